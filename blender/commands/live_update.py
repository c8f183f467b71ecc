"""Live update: while ``scene.lens_lights.live_update`` is on, the lens lights follow
the scene (bpy handlers).

**When.** Persistent handlers, registered with the extension (cheap no-ops for a scene
with live update off):

* ``frame_change_post`` — playback, scrubbing, ``frame_set``, and every frame of a
  render: F12, ``render(animation=True)`` and ``blender -b -a`` run it with the
  *render* depsgraph of the frame (measured in Blender 5.2), and Blender evaluates
  what a handler changed before the engine reads the frame, so the frame renders
  with its own lens lights;
* ``depsgraph_update_post`` — when something that is not ours changed: an object
  (a light, a lens, a receiver, a blocker, a camera) or a light, mesh, material or
  camera datablock. Updates made only of the extension's lights, their data, its
  collections, images and layer materials (our own edits come back this way) are
  ignored, so live update does not feed itself;
* ``render_init`` / ``render_complete`` / ``render_cancel`` — tell the render probe
  that a render of the user's is running (`render_probe.note_render`): Generate
  called from a user's handler then reads the viewport instead of rendering inside
  the render (which crashes Blender); ``load_post`` forgets both.

A module flag guards against re-entry: what an update changes never runs another
update from inside it.

**How.** No probe render in a handler: the depsgraph the handler is handed is read
and planned by the pipeline Generate and Bake share (`pipeline.plan_scene`; a
viewport depsgraph with the render-visibility rules applied by hand, as Generate's
fallback), and applied to the existing lens
lights in place: each light is matched to its planned source by a stable key
(`core.animation.light_keys`: primary light, lens, kind, tier), updated with only the values
that changed (`lights.apply_light`: transform, power, colour, cone, blend,
radius; an Exact profile's node tree and image only when its profile changed), new
keys get new lights, vanished keys' lights are removed. So the objects stay the
same from frame to frame (selection, undo). When the read's inputs (lights, spheres,
primaries, the other geometry's transforms and boxes, camera, settings) are those of
the last update, nothing is planned (a camera-only animation costs the read). The
Caustic layer tier (EEVEE's AUTO) is rebuilt whole on every update (its meshes depend
on the traced beam): correct but slow. Cycles' own caustics are re-replaced when the
set of lights changes.

**The switch.** Turning ``live_update`` on brings the lights up to date at once
(`live_update_changed`, forced): `register` installs it as the switch's update hook
(`properties.set_live_update_hook`), so that the settings never import this module.
Clear turns live update off (else the lights would come back at the next update).
In a viewport depsgraph, objects hidden in the viewport (eye or monitor icon) are
not there at all, so their lights and lenses are missed until a render (whose
depsgraph has them) or Generate. Figures of the last update: `LAST_FIGURES`.
"""

from __future__ import annotations

import hashlib
import time
import traceback

import bpy
import numpy as np

from ...core.animation.light_keys import keys_of, match
from ...core.tiers import builds_layer
from ..build import cleanup, cycles_caustics, lights
from ..build.marks import COLLECTION_MARK, LINK_MARK
from ..read import render_probe
from ..ui.properties import set_live_update_hook
from . import layer_stage, pipeline

#: The last update's figures: seconds per step, lights updated/created/removed.
LAST_FIGURES: dict = {}
_BUSY = False
#: Per scene: (signature of the last update's inputs, how many objects it left).
_LAST_INPUTS: dict = {}

#: Datablock types whose change (when not ours) can move a lens light.
_WATCHED = ("Object", "Light", "Mesh", "Material", "Camera")


def _existing_key(ob):
    if ob.type != "LIGHT" or ob.data is None:
        return None  # a caustic layer: never matched, rebuilt
    m = ob.lens_lights
    return (m.source_light, m.source_lens, m.kind, m.energy_model)


def _ours(scene) -> set:
    """Pointers of the extension's objects in `scene` and their data."""
    out = set()
    for ob in lights.created_objects(scene):
        out.add(ob.as_pointer())
        if ob.data is not None:
            out.add(ob.data.as_pointer())
    return out


def relevant(scene, depsgraph) -> bool:
    """Does `depsgraph.updates` hold a change that can move a lens light (see the
    module's docstring)?"""
    ours = None
    for update in depsgraph.updates:
        idb = update.id
        if type(idb).__name__ not in _WATCHED:
            continue
        orig = getattr(idb, "original", idb)
        if isinstance(orig, bpy.types.Object) and orig.lens_lights.is_lens_light:
            continue
        if isinstance(orig, bpy.types.Material) and orig.get(COLLECTION_MARK) is not None:
            continue  # a caustic layer's material
        if ours is None:
            ours = _ours(scene)
        if orig.as_pointer() not in ours:
            return True
    return False


def _remove(scene, objects):
    """Remove `objects` (ours), their orphaned data, their registry entries, and the
    linking collections no lens light uses any more."""
    datas = {ob.data for ob in objects if ob.data is not None}
    bpy.data.batch_remove(objects)
    orphans = [d for d in datas if d.users == 0]
    if orphans:
        bpy.data.batch_remove(orphans)
    settings = scene.lens_lights
    for k in reversed(range(len(settings.created_objects))):
        if settings.created_objects[k].object is None:
            settings.created_objects.remove(k)
    used = {
        c.as_pointer()
        for ob in lights.created_objects(scene)
        if ob.type == "LIGHT"
        for c in (ob.light_linking.receiver_collection, ob.light_linking.blocker_collection)
        if c is not None
    }
    for k in reversed(range(len(settings.created_collections))):
        coll = settings.created_collections[k].collection
        if coll is None:
            settings.created_collections.remove(k)
        elif coll.get(COLLECTION_MARK) == LINK_MARK and coll.as_pointer() not in used:
            settings.created_collections.remove(k)
            bpy.data.collections.remove(coll)
    lights.remove_unused_profile_images()


def _signature(read, options, scene) -> str:
    """A digest of everything the plan is made from (lights, spheres, primaries, the
    other geometry's transforms and boxes, camera, settings): equal digests, equal
    plans. (A mesh deformed within the same bounding box is not seen.)"""
    h = hashlib.blake2b(digest_size=16)
    a, occ = read.arrays, read.occluders
    for arr in (
        a.light_position,
        a.light_brightness,
        a.light_color,
        a.center,
        a.radius,
        a.ior,
        a.kt,
        occ.matrices,
        occ.box_lo,
        occ.box_hi,
    ):
        h.update(np.ascontiguousarray(arr, dtype=float).tobytes())
    h.update(
        repr(
            (
                read.primaries,
                read.light_sources,
                read.sphere_sources,
                read.camera,
                read.width,
                read.height,
                sorted(options.items()),
                scene.render.engine,
            )
        ).encode()
    )
    return h.hexdigest()


def _unchanged(scene, signature) -> bool:
    last = _LAST_INPUTS.get(scene.as_pointer())
    if last is None or last[0] != signature:
        return False
    items = scene.lens_lights.created_objects
    return len(items) == last[1] and all(item.object is not None for item in items)


def update(scene, depsgraph, force=False) -> dict:
    """Bring `scene`'s lens lights to what `depsgraph` shows (see the module's
    docstring); returns the figures. Nothing is planned when the inputs are those
    of the last update (unless `force`). Raises on failure (the handlers catch)."""
    t0 = time.perf_counter()
    options = pipeline.options_from(scene.lens_lights)
    timings: dict = {}
    seen: dict = {}

    def unchanged(read) -> bool:
        seen.update(signature=_signature(read, options, scene), how=read.how)
        return not force and _unchanged(scene, seen["signature"])

    work = pipeline.plan_scene(depsgraph, scene, options, timings=timings, unless=unchanged)
    if work is None:  # the inputs of the last update: nothing planned
        t1 = time.perf_counter()
        return dict(
            skipped=True,
            seconds=t1 - t0,
            plan_seconds=t1 - t0,
            apply_seconds=0.0,
            how=seen["how"],
            timings=timings,
        )
    signature = seen["signature"]
    t_plan = time.perf_counter()
    plan, read = work.plan, work.read
    figures = dict(planned=len(plan.lights), updated=0, created=0, removed=0)
    if builds_layer(options["energy_model"]):
        cleanup.clear(scene)  # the layer's meshes: rebuilt whole
        cycles_caustics.restore(scene)
        made = layer_stage.build(scene, work)
        cycles_caustics.after_build(scene, plan, read, len(made))
        figures.update(created=len(made), rebuilt=True)
    else:
        existing = lights.created_objects(scene)
        old_keys = keys_of([_existing_key(ob) for ob in existing])
        new_keys = keys_of(
            (p.light_name, p.lens_name, p.light.kind, p.light.model) for p in plan.lights
        )
        m = match(old_keys, new_keys)
        images: dict = {}
        for i, j in m.update:
            # with phase 1's arrays: a non-full source's profile light keeps its mask
            lights.apply_light(existing[i], plan.lights[j], images, read.arrays)
        if m.remove:
            _remove(scene, [existing[i] for i in m.remove])
        pairs = [(existing[i], plan.lights[j]) for i, j in m.update]
        if m.create:
            collection = lights.lights_collection(scene)
            for j in m.create:
                p = plan.lights[j]
                ob = lights.create_light(
                    scene,
                    p,
                    read.sphere_objects[p.source.lens],
                    collection,
                    None,
                    image_cache=images,
                    arrays=read.arrays,
                )
                pairs.append((ob, p))
        if pairs:  # the groups follow the beams (only what differs is written)
            lights.link_lights(
                scene,
                [ob for ob, _ in pairs],
                [p for _, p in pairs],
                read.arrays.center,
                read.arrays.radius,
                read.sphere_objects,
            )
        if images:  # a profile's node tree was rebuilt: its old image may be unused
            lights.remove_unused_profile_images()
        if not m.same_set:
            cycles_caustics.restore(scene)
            cycles_caustics.after_build(scene, plan, read, len(plan.lights))
        figures.update(updated=len(m.update), created=len(m.create), removed=len(m.remove))
    _LAST_INPUTS[scene.as_pointer()] = (signature, len(scene.lens_lights.created_objects))
    t1 = time.perf_counter()
    figures.update(
        plan_seconds=t_plan - t0, apply_seconds=t1 - t_plan, seconds=t1 - t0, how=read.how
    )
    figures["timings"] = dict(work.timings)
    return figures


def _run(scene, depsgraph, why, force=False):
    global _BUSY, LAST_FIGURES
    if _BUSY:
        return
    _BUSY = True
    try:
        figures = update(scene, depsgraph, force)
        figures["why"] = why
        LAST_FIGURES = figures
    except Exception:  # a handler must never raise into Blender
        traceback.print_exc()
        LAST_FIGURES = dict(why=why, error=traceback.format_exc(limit=1))
    finally:
        _BUSY = False


def _on(scene) -> bool:
    settings = getattr(scene, "lens_lights", None)
    # The probe's scene copy carries the setting too: never update it.
    probe = scene.render.engine == render_probe.LENS_LIGHTS_RE_probe.bl_idname
    return settings is not None and settings.live_update and not probe


@bpy.app.handlers.persistent
def on_frame_change(scene, depsgraph=None):
    if _BUSY or not _on(scene):
        return
    _run(
        scene,
        depsgraph if depsgraph is not None else bpy.context.evaluated_depsgraph_get(),
        "frame",
    )


@bpy.app.handlers.persistent
def on_depsgraph_update(scene, depsgraph=None):
    if _BUSY or depsgraph is None or not _on(scene) or not relevant(scene, depsgraph):
        return
    _run(scene, depsgraph, "edit")


@bpy.app.handlers.persistent
def on_render_start(scene, *args):
    render_probe.note_render(True)


@bpy.app.handlers.persistent
def on_render_end(scene, *args):
    render_probe.note_render(False)


@bpy.app.handlers.persistent
def on_load(*args):
    _LAST_INPUTS.clear()  # another file: other objects
    render_probe.note_render(None)


def live_update_changed(settings, context):
    """The checkbox's update: turned on, bring the lights up to date at once."""
    scene = settings.id_data
    if settings.live_update and context is not None and context.view_layer is not None:
        _run(scene, context.evaluated_depsgraph_get(), "turned on", force=True)


_HANDLERS = (
    ("frame_change_post", on_frame_change),
    ("depsgraph_update_post", on_depsgraph_update),
    ("render_init", on_render_start),
    ("render_complete", on_render_end),
    ("render_cancel", on_render_end),
    ("load_post", on_load),
)


def _remove_ours(handlers, fn):
    # By name as well: a reloaded extension's old functions are other objects.
    for h in list(handlers):
        if h is fn or (
            getattr(h, "__module__", None) == fn.__module__ and h.__name__ == fn.__name__
        ):
            handlers.remove(h)


def register():
    for name, fn in _HANDLERS:
        handlers = getattr(bpy.app.handlers, name)
        _remove_ours(handlers, fn)
        handlers.append(fn)
    set_live_update_hook(live_update_changed)


def unregister():
    set_live_update_hook(None)
    for name, fn in _HANDLERS:
        _remove_ours(getattr(bpy.app.handlers, name), fn)
