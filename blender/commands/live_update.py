"""Live update: while ``scene.lens_lights.live_update`` is on, the lens lights follow
the scene (bpy handlers).

**When.** Persistent handlers, registered with the extension (cheap no-ops for a scene
with live update off):

* ``frame_change_post`` — playback, scrubbing, ``frame_set``, and every frame of a
  render: F12, ``render(animation=True)`` and ``blender -b -a`` run it with the
  *render* depsgraph of the frame (measured in Blender 5.2), and Blender evaluates
  what a handler changed before the engine reads the frame, so the frame renders
  with its own lens lights;
* ``depsgraph_update_post`` — when something that is not ours changed and can
  change a lens light (`relevant`): a light, a camera, a lens or other glass, any
  material (colours and receivers' shaders are not in the read's signature: planned
  again), an object that touches a path of the last plan's light (`_Watch`,
  `core.plan.watch`: lamp → lens, the lens' axis, the layer's landings) now or did
  at the last update, an object added, removed, hidden or shown, or given other
  data or materials. An edit of anything else (a cube moved away from every beam)
  costs a box test (`bench live_update`, ``--unrelated``). Updates made only of the
  extension's lights, their data, its collections, images and layer materials (our
  own edits come back this way) are ignored, so live update does not feed itself;
* ``render_init`` / ``render_complete`` / ``render_cancel`` — tell the render probe
  that a render of the user's is running (`render_probe.note_render`): Generate
  called from a user's handler then reads the viewport instead of rendering inside
  the render (which crashes Blender); ``load_post`` forgets both.

A module flag guards against re-entry: what an update changes never runs another
update from inside it.

**How.** No probe render in a handler: the depsgraph the handler is handed is read
and planned by the pipeline Generate and Bake share (`pipeline.plan_scene`; a
viewport depsgraph with the render-visibility rules applied by hand, as Generate's
fallback), and applied to the existing lens lights in place (only the extension's:
one the user duplicated, renamed or moved is theirs, left alone:
`ownership.keep_users`): each light is matched to its planned source by a stable key
(`core.animation.light_keys`: primary light, lens, kind, tier), updated with only the values
that changed (`lights.apply_light`: transform, power, colour, cone, blend,
radius; an Exact profile's table written into its tree's Value nodes and its own
image in place, `image.pixels.foreach_set`, the tree rebuilt only when its shape
changes or the blockers of its shadow mask move; the rewritten images are packed
when the file is saved, ``save_pre``), new
keys get new lights, vanished keys' lights are removed. So the objects stay the
same from frame to frame (selection, undo). When the read's inputs (lights, spheres,
primaries, the other geometry's transforms and boxes, camera, settings) are those of
the last update, nothing is planned (a camera-only animation costs the read).
Cycles' own caustics are re-replaced when the set of lights changes.

**The Caustic layer** (EEVEE's AUTO; issue 27). A full layer (Generate's bake) is
written into the scene's layer objects in place when they are the layers of the same
patches on the same receivers (`layers.refill`: positions, UVs, irradiance set whole;
a raster of another resolution replaces its mesh's geometry, the mesh stays), else
rebuilt. In Blender's window (`INTERACTIVE`; not in background, where no timer runs)
an update shows the *coarse* layer instead (`core.caustic_layer.live.LiveLayer`:
each pair's beam on a coarse grid, remembered by its inputs so only the pairs whose
light or lens changed are traced, splatted alone into the last full layer's rasters;
only the meshes' irradiance is written), and `refine`, a `bpy.app.timers` timer,
makes the full one `BURST_SECONDS` after the last update (a drag's or a playback's
burst is over), as Blender's viewport refines. A render never sees a coarse layer:
render_init refines at once, and an update with the render's depsgraph (or during a
render) is always full. Other pairs, other receivers (moved, recoloured) or a glass
mesh's beam need the full layer at once.

**The Exact profile** (Cycles' AUTO) follows the same way: every table the plan's
lights read is made in one batch (`exact_profile.prepare_tables`); in Blender's
window a light whose exact table is not made yet reads a *coarse* one (fewer rays:
within 1 % of the flux and 5 % of the peak; its image keyed apart), and `refine`
writes the exact tables once the burst is over, or at once when a render starts.
The planner's rays are remembered per scene (`core.plan.ray_memo.RayMemo`, by their
own rays, while the occluders' transforms and boxes are the same; forgotten on a
forced update and when the depsgraph changed an object's shape): the pairs of a lamp
that did not move are not cast again.

**Water** (issue 26): every update runs the water stage (`water_stage.prepare`, as
Generate) and writes its layers into the water's layer objects in place where the
patches are the same (`water_stage.refill`), else makes those alone again; the lens
lights and glass layers are matched without them. The water surfaces' evaluated
vertices are in the inputs' signature (an Ocean's waves move every frame inside one
bounding box) and the surfaces are watched. Always the full water layer (no coarse
one).

**The switch.** Turning ``live_update`` on brings the lights up to date at once
(`live_update_changed`, forced): `register` installs it as the switch's update hook
(`properties.set_live_update_hook`), so that the settings never import this module.
Clear turns live update off (else the lights would come back at the next update).
While a bake exists (`bake_check.has_bake`) live update does nothing, switch on or
not: the bake's keys drive its lights, node trees and images (the panel says so).
In a viewport depsgraph, objects hidden in the viewport (eye or monitor icon) are
not there at all, so their lights and lenses are missed until a render (whose
depsgraph has them) or Generate. Figures of the last update: `LAST_FIGURES`.
"""

from __future__ import annotations

import contextlib
import hashlib
import time
import traceback
from dataclasses import dataclass

import bpy
import numpy as np

from ...core.animation.light_keys import keys_of, match
from ...core.caustic_layer.live import LiveLayer
from ...core.plan import watch
from ...core.plan.ray_memo import RayMemo
from ...core.plan.watch import Capsules
from ...core.scene.primaries import PrimaryArrays
from ...core.tiers import builds_layer, exact_profile
from ...core.tiers.base import COLLIMATED_DISTANCE_FACTOR
from ..build import cleanup, cycles_caustics, lights, ownership
from ..build import layers as layer_builder
from ..build.marks import COLLECTION_MARK, LINK_MARK
from ..read import render_probe
from ..ui.properties import set_live_update_hook
from . import bake_check, handlers, layer_stage, pipeline, water_stage

#: The last update's figures: seconds per step, lights updated/created/removed.
LAST_FIGURES: dict = {}
_BUSY = False
#: Per scene: (signature of the last update's inputs, how many objects it left).
_LAST_INPUTS: dict = {}

#: Datablock types whose change (when not ours) can move a lens light (a Collection:
#: objects added, removed, hidden or shown).
_WATCHED = ("Object", "Light", "Mesh", "Material", "Camera", "Collection")
#: Per scene: where the last update's light goes (`_Watch`).
_WATCHES: dict = {}
#: Per scene: the names of the last update's water surfaces (their evaluated vertices
#: are in the inputs' signature: a wave moves inside the same bounding box).
_WATERS: dict = {}
#: Caustic layer: per scene its last full layer (`core.caustic_layer.live.LiveLayer`),
#: when its last update ended (perf_counter), and the scenes showing a coarse one.
_LAYERS: dict = {}
#: Per scene: the planner's rays of the last updates (`core.plan.ray_memo.RayMemo`):
#: a pair whose lens, axis and surroundings did not change is not cast again.
_RAYS: dict = {}
_LAST_RUN: dict = {}
_PENDING: set = set()
#: The full layer follows this long (s) after the last update of a burst.
BURST_SECONDS = 0.3
#: Coarse layers while the user works: None, in Blender's window (not in background,
#: where no timer runs and no one drags: every update is full); the bench and the
#: tests set it to take the window's path.
INTERACTIVE: bool | None = None
_RENDERING = 0
#: Objects that can be anywhere they make geometry: always watched.
_INSTANCING_MODIFIERS = ("NODES", "PARTICLE_SYSTEM")
#: Beyond this many objects × capsules (or objects), no filter: every edit counts.
WATCH_PAIRS = 5_000_000
WATCH_OBJECTS = 20_000
#: Object types with no surface of their own to block or receive light.
_NO_GEOMETRY = ("EMPTY", "LIGHT", "CAMERA", "SPEAKER", "LIGHT_PROBE", "ARMATURE", "LATTICE")


def _existing_key(ob):
    if ob.type != "LIGHT" or ob.data is None:
        return None  # a caustic layer: never matched, rebuilt
    m = ob.lens_lights
    return (m.source_light, m.source_lens, m.kind, m.energy_model)


def _ours(scene) -> set:
    """Pointers of the extension's objects in `scene` and their data."""
    out = set()
    for ob in ownership.created_objects(scene):
        out.add(ob.as_pointer())
        if ob.data is not None:
            out.add(ob.data.as_pointer())
    return out


def _world_box(ob) -> tuple[np.ndarray, np.ndarray]:
    """`ob`'s axis-aligned box in the world (evaluated: with its modifiers)."""
    m = np.array(ob.matrix_world)
    corners = np.array(ob.bound_box) @ m[:3, :3].T + m[:3, 3]
    return corners.min(axis=0), corners.max(axis=0)


def _slots(ob) -> tuple:
    """What `ob` is made of: its data's name and its materials' names."""
    data = ob.data.name if ob.data is not None else ""
    return data, tuple(s.material.name if s.material else "" for s in ob.material_slots)


def _always(ob) -> bool:
    """Is `ob` watched wherever it is: a light, a camera, or an object that makes
    geometry away from its own box (instances, particles, geometry nodes)?"""
    return (
        ob.type in ("LIGHT", "CAMERA")
        or ob.instance_type != "NONE"
        or any(m.type in _INSTANCING_MODIFIERS for m in ob.modifiers)
    )


@dataclass
class _Watch:
    """Where the last update's light goes (`core.plan.watch`) and what it was read
    from: what an edit must touch to change a lens light."""

    capsules: Capsules
    watched: frozenset  # objects whose edits always count (lenses, glass, in the light)
    meshes: frozenset  # their data
    known: dict  # every object the depsgraph held: name → `_slots`

    def says(self, kind, orig, evaluated, depsgraph, ours) -> str:
        """ "" / "edit" / "force" for one update (see `relevant`)."""
        if kind in ("Light", "Camera"):
            return "edit"
        if kind == "Material":
            return "force"  # the read's signature holds no colours, no receivers
        if kind == "Mesh":
            return "force" if orig.name in self.meshes else ""
        if kind == "Collection":  # added, removed, hidden, shown?
            held = frozenset(
                o.original.name for o in depsgraph.objects if o.original.as_pointer() not in ours
            )
            return "" if held == self.known.keys() else "edit"
        name = orig.name
        if name in self.watched or _always(orig) or self.known.get(name) != _slots(orig):
            return "edit"
        return "edit" if self.capsules.touches(*_world_box(evaluated)) else ""


def _landings(patches, sources) -> Capsules:
    """Each layer patch's lenses to its lit texels (`watch.lit_texels` over every
    patch: the faintest, holding `watch.FAINT_SHARE` of all, are left out)."""
    flux, middles, radii, owner = [], [], [], []
    for k, patch in enumerate(patches):
        if getattr(patch, "coarse", False):
            # drawn out of the camera's view for mirrors only: its big texels would
            # watch half the scene (an edit there waits for the next followed one)
            continue
        corners = patch.vertices[patch.faces]  # (texels, 4, 3)
        middle = corners.mean(axis=1)
        flux.append(patch.face_irradiance.sum(axis=1) * patch.texel_areas().reshape(-1))
        middles.append(middle)
        radii.append(np.linalg.norm(corners - middle[:, None], axis=2).max(axis=1))
        owner.append(np.full(len(middle), k))
    if not flux:
        return Capsules.empty()
    owner = np.concatenate(owner)
    kept = watch.lit_texels(np.concatenate(flux), np.arange(len(owner)))
    parts = []
    for k in np.unique(owner[kept]):
        texels = kept[owner[kept] == k]
        lenses = [sources[int(s)].lens for s in patches[k].sources]  # centre and size:
        spots, spot_radii = watch.clusters(
            np.concatenate(middles)[texels], np.concatenate(radii)[texels]
        )
        parts.append(  # a sphere holding the lens
            watch.landings(
                [x.center for x in lenses], [x.radius for x in lenses], spots, spot_radii
            )
        )
    return Capsules.join(parts)


def _watch_of(scene, depsgraph, work) -> _Watch | None:
    """The `_Watch` of an update's plan (`work`) on `depsgraph` (`scene`'s: its lens
    lights and layers are no inputs); None where testing every object against every
    path of the light would cost more than planning again (`WATCH_PAIRS`)."""
    read, a = work.read, work.read.arrays
    reach = COLLIMATED_DISTANCE_FACTOR * read.scene_size  # as far as the planner casts
    origins, sizes, suns = watch.light_extents(PrimaryArrays.from_primaries(read.primary_lights))
    lenses = np.flatnonzero(np.asarray(read.lens_candidates, bool))
    parts = [watch.light_to_lens(origins, sizes, suns, a.center[lenses], a.radius[lenses], reach)]
    sources = [p.source for p in work.plan.lights]
    if sources:
        lens = np.array([s.lens for s in sources])
        axes = np.array([s.axis for s in sources], float)
        parts.append(watch.along_axes(a.center[lens], a.radius[lens], axes, reach))
    if work.layer_bake is not None:
        parts.append(_landings(work.layer_bake.layer.patches, work.layer_sources))
    capsules = Capsules.join(parts)
    ours = _ours(scene)
    objects = [ob for ob in depsgraph.objects if ob.original.as_pointer() not in ours]
    if len(objects) * len(capsules) > WATCH_PAIRS or len(objects) > WATCH_OBJECTS:
        return None  # costlier than it saves: every edit counts
    watched = {read.sphere_objects[i].name for i in lenses}
    watched.update(name for name, _ in read.left_out_lenses)
    watched.update(m.orig.name for m in read.mesh_lenses)  # the glass meshes traced
    water = getattr(work, "water", None)
    if water is not None:  # the water surfaces: an edit of theirs changes the net
        watched.update(w.name for w in water.waters)
    known = {ob.original.name: _slots(ob.original) for ob in objects}
    solid = [
        ob for ob in objects if ob.type not in _NO_GEOMETRY and ob.original.name not in watched
    ]
    if solid:
        boxes = np.array([_world_box(ob) for ob in solid])
        hit = capsules.touching(boxes[:, 0], boxes[:, 1])
        watched.update(ob.original.name for ob, h in zip(solid, hit, strict=True) if h)
    meshes = set()
    for name in watched:
        ob = bpy.data.objects.get(name)
        if ob is not None and ob.data is not None:
            meshes.add(ob.data.name)
    return _Watch(capsules, frozenset(watched), frozenset(meshes), known)


def relevant(scene, depsgraph) -> str:
    """What `depsgraph.updates` holds that can change a lens light: "" nothing (ours,
    or objects away from every path of the light: `_Watch`), "edit" (the read's
    inputs may have changed: planned unless they are the last update's), "force"
    (a material, or the mesh of a lens, receiver or blocker: what the read's
    signature does not hold; planned again)."""
    ours = None
    watching = _WATCHES.get(scene.as_pointer())
    why = ""
    for update in depsgraph.updates:
        idb = update.id
        # A light's data is a PointLight, SpotLight, SunLight or AreaLight.
        kind = "Light" if isinstance(idb, bpy.types.Light) else type(idb).__name__
        if kind not in _WATCHED:
            continue
        orig = getattr(idb, "original", idb)
        if isinstance(orig, bpy.types.Object) and orig.lens_lights.is_lens_light:
            continue
        if isinstance(orig, bpy.types.Material) and orig.get(COLLECTION_MARK) is not None:
            continue  # a caustic layer's material
        if isinstance(orig, bpy.types.Collection) and orig.get(COLLECTION_MARK) is not None:
            continue
        if ours is None:
            ours = _ours(scene)
        if orig.as_pointer() in ours:
            continue
        if watching is None:
            return "edit"
        said = watching.says(kind, orig, idb, depsgraph, ours)
        if said == "force":
            return said
        why = why or said
    return why


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
        for ob in ownership.created_objects(scene)
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


def _unchanged(scene, signature, coarse_ok=False) -> bool:
    last = _LAST_INPUTS.get(scene.as_pointer())
    if last is None or last[0] != signature or (last[2] and not coarse_ok):
        return False  # changed, or a coarse layer where the full one is due
    items = scene.lens_lights.created_objects
    return len(items) == last[1] and all(item.object is not None for item in items)


def update(scene, depsgraph, force=False, coarse=False) -> dict:
    """Bring `scene`'s lens lights to what `depsgraph` shows (see the module's
    docstring); returns the figures. Nothing is planned when the inputs are those
    of the last update (unless `force`). ``coarse``: a Caustic layer may be the
    coarse one (`_layer_update`). Raises on failure (the handlers catch)."""
    t0 = time.perf_counter()
    options = pipeline.options_from(scene.lens_lights)
    timings: dict = {}
    seen: dict = {}
    layered = builds_layer(options["energy_model"])
    live = _LAYERS.get(scene.as_pointer()) if coarse and layered else None

    def unchanged(read) -> bool:
        signature = _signature(read, options, scene) + _water_print(scene, depsgraph)
        seen.update(signature=signature, how=read.how)
        return not force and _unchanged(scene, seen["signature"], coarse)

    rays = _RAYS.setdefault(scene.as_pointer(), RayMemo())
    if force or _geometry_changed(scene, depsgraph):
        rays.clear()  # (its own check sees transforms and boxes, not a mesh's shape)
    # while the user works the Exact profile's lights take the coarse beam summary
    # (their energies: refined with the tables)
    rough = exact_profile.coarse_summaries() if coarse else contextlib.nullcontext()
    with rough:
        work = pipeline.plan_scene(
            depsgraph, scene, options, timings=timings, unless=unchanged, layer_live=live, rays=rays
        )
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
    is_coarse = work.layer_bake is not None and work.layer_bake.coarse
    t_water = time.perf_counter()
    water_stage.prepare(depsgraph, work)  # the water's layer of this frame (built below)
    _WATERS[scene.as_pointer()] = [w.name for w in work.water.waters]
    work.timings["water"] = time.perf_counter() - t_water
    # Before the build: the handler's depsgraph still holds what it evaluated. (A
    # coarse layer keeps the last full one's watch: the full one follows.)
    t_watch = time.perf_counter()
    if not is_coarse:
        _WATCHES[scene.as_pointer()] = _watch_of(scene, depsgraph, work)
    work.timings["watch"] = time.perf_counter() - t_watch
    t_plan = time.perf_counter()
    plan, read = work.plan, work.read
    figures = dict(planned=len(plan.lights), updated=0, created=0, removed=0)
    # the user's copies, renamed and moved lens lights: theirs, never updated or removed
    figures["kept"] = len(ownership.keep_users(scene))
    if layered:
        if not _no_glass(scene, work) and not _layer_update(scene, work, figures):
            # not in place: rebuilt whole
            cleanup.clear(scene)
            cycles_caustics.restore(scene)
            made = layer_stage.build(scene, work)
            cycles_caustics.after_build(scene, plan, read, len(made))
            figures.update(created=len(made), rebuilt=True, coarse=is_coarse)
        elif figures.pop("other_pairs", False):  # other lenses lit: Cycles' switches
            cycles_caustics.restore(scene)
            cycles_caustics.after_build(scene, plan, read, figures["updated"])
        _remember_layer(scene, work.layer_bake)
    else:
        existing = [
            ob for ob in ownership.created_objects(scene) if not water_stage.is_water_layer(ob)
        ]
        old_keys = keys_of([_existing_key(ob) for ob in existing])
        new_keys = keys_of(
            (p.light_name, p.lens_name, p.light.kind, p.light.model) for p in plan.lights
        )
        m = match(old_keys, new_keys)
        images: dict = {}
        # every table the lights read, at once (coarse ones while the user works)
        t_tables = time.perf_counter()
        figures["coarse"] = exact_profile.prepare_tables([p.light for p in plan.lights], coarse)
        # a light planned with the coarse summary waits for the refine too, its table
        # exact or not
        rough = any(getattr(p.light, "coarse_energy", False) for p in plan.lights)
        work.timings["tables"] = time.perf_counter() - t_tables
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
        # while the user works, the same lights keep the groups the last update gave
        # them (a beam moved a little reaches the same lenses) where the refine is
        # due anyway (a coarse table or energy): it links them again
        keep_groups = coarse and (figures["coarse"] > 0 or rough) and m.same_set
        figures["linking"] = "kept" if keep_groups else "linked"
        if pairs and not keep_groups:  # the groups follow the beams (only changes written)
            lights.link_lights(
                scene,
                [ob for ob, _ in pairs],
                [p for _, p in pairs],
                read.arrays.center,
                read.arrays.radius,
                read.sphere_objects,
                user_links=lights.user_links_of([p for _, p in pairs], read.light_objects),
            )
        if images:  # a profile's node tree was rebuilt: its old image may be unused
            lights.remove_unused_profile_images()
        # the glass meshes' layers (the old ones were removed above: a layer never matches)
        meshes = layer_stage.build_mesh_layers(scene, work)
        figures["mesh_layers"] = len(meshes)
        if not m.same_set:
            cycles_caustics.restore(scene)
            cycles_caustics.after_build(scene, plan, read, len(plan.lights))
        figures.update(updated=len(m.update), created=len(m.create), removed=len(m.remove))
        _remember_coarse(scene, figures["coarse"] > 0 or rough)
        figures["coarse_energy"] = rough
    figures["water_layers"] = _water_update(scene, work)
    _LAST_INPUTS[scene.as_pointer()] = (
        signature,
        len(scene.lens_lights.created_objects),
        is_coarse or figures.get("coarse", 0) > 0 or figures.get("coarse_energy", False),
    )
    t1 = time.perf_counter()
    figures.update(
        plan_seconds=t_plan - t0, apply_seconds=t1 - t_plan, seconds=t1 - t0, how=read.how
    )
    figures["timings"] = dict(work.timings)
    if layered and work.layer_bake is not None:
        figures["layer"] = work.layer_bake.layer  # (the bench compares it)
    return figures


def _geometry_changed(scene, depsgraph) -> bool:
    """Did `depsgraph` change the shape of an object not ours (an edited mesh, a
    shape key or modifier animated over frames: what the planner's rays may meet,
    inside the same box)? A frame change's depsgraph lists them as an edit's does
    (the object, its geometry updated; the scene, node trees and images say
    "geometry" too and are no shapes)."""
    ours = None
    for u in depsgraph.updates:
        if not u.is_updated_geometry or not isinstance(u.id, bpy.types.Object):
            continue
        orig = u.id.original
        if orig.type in _NO_GEOMETRY or orig.lens_lights.is_lens_light:
            continue
        if ours is None:
            ours = _ours(scene)
        if orig.as_pointer() not in ours:
            return True
    return False


def _no_glass(scene, work) -> bool:
    """Nothing but water, before and now: no lens light or glass layer planned, none
    in the scene (the water's layers are `_water_update`'s alone)."""
    if work.plan.lights or work.layer_bake is not None:
        return False
    return all(water_stage.is_water_layer(ob) for ob in ownership.created_objects(scene))


def _water_print(scene, depsgraph) -> str:
    """A digest of the last update's water surfaces as evaluated now (their vertices:
    an Ocean modifier's waves move every frame within one bounding box)."""
    names = _WATERS.get(scene.as_pointer())
    if not names:
        return ""
    h = hashlib.blake2b(digest_size=16)
    for name in names:
        ob = bpy.data.objects.get(name)
        if ob is None or ob.type != "MESH":
            h.update(b"-")
            continue
        me = ob.evaluated_get(depsgraph).data
        co = np.empty(len(me.vertices) * 3, dtype=np.float32)
        me.vertices.foreach_get("co", co)
        h.update(co.tobytes())
        h.update(np.asarray(ob.evaluated_get(depsgraph).matrix_world, np.float32).tobytes())
    return h.hexdigest()


def _water_update(scene, work) -> str:
    """The water's layers of this update (`water_stage`): written into the existing
    ones in place where the patches are the same (the frame's waves: only positions,
    UVs and irradiance), else those alone removed and made again (the glass layers and
    lens lights are not touched; after a whole rebuild none are left). Returns what
    was done: "refilled", "rebuilt", "removed" or ""."""
    existing = water_stage.water_layers(scene)
    if water_stage.refill(scene, work, existing):
        done, made = "refilled", existing
    else:
        if existing:
            _remove(scene, existing)
        made = water_stage.build(scene, work)
        done = "rebuilt" if made else ("removed" if existing else "")
    if made:  # Cycles' own caustics off for them (again where the lights' rebuild put
        # them back; a switch already off is left as it is)
        cycles_caustics.after_build(scene, work.plan, work.read, len(made), layers=True)
    return done


def _layer_update(scene, work, figures) -> bool:
    """The Caustic layer written into the scene's layer objects in place (`layers.refill`:
    the same objects and meshes, only positions, UVs and irradiance written; a coarse
    layer, its irradiance only) when they are the layers of the same patches on the
    same receivers; False: nothing written (build anew)."""
    bake = work.layer_bake
    last = _LAYERS.get(scene.as_pointer())
    if bake is None or last is None or last.bake.receivers_key != bake.receivers_key:
        return False
    reflections = scene.render.engine in layer_stage.EEVEE_ENGINES
    drawn = last.drawn(bake.layer) if bake.coarse else None
    anchors = last.anchors() if bake.coarse else None
    t = time.perf_counter()
    done = layer_builder.refill(
        scene, bake, work.receivers, bake.names, reflections, drawn, anchors
    )
    work.timings["layer write"] = time.perf_counter() - t
    if done is None:
        return False
    figures.update(updated=len(done), coarse=bake.coarse)
    figures["other_pairs"] = set(bake.names) != set(last.names)
    if bake.coarse:
        figures.update(traced=last.traced, reused=last.reused)
    return True


def _remember_layer(scene, bake):
    """After a layer update: a full layer is the next coarse ones' rasters (its
    `LiveLayer`), a coarse one waits for the full one (`refine`, a timer)."""
    ptr = scene.as_pointer()
    if bake is not None and bake.coarse:
        _PENDING.add(ptr)
        if not bpy.app.timers.is_registered(refine):
            bpy.app.timers.register(refine, first_interval=BURST_SECONDS)
        return
    _PENDING.discard(ptr)
    if bake is None or bake.names is None:
        _LAYERS.pop(ptr, None)
    else:
        _LAYERS[ptr] = LiveLayer(bake, bake.names, bake.receivers_key)


def _remember_coarse(scene, coarse: bool):
    """After an Exact profile update: coarse tables wait for the exact ones (`refine`,
    a timer)."""
    ptr = scene.as_pointer()
    if not coarse:
        _PENDING.discard(ptr)
    else:
        _PENDING.add(ptr)
        if not bpy.app.timers.is_registered(refine):
            bpy.app.timers.register(refine, first_interval=BURST_SECONDS)


def _coarse_allowed(depsgraph) -> bool:
    """May this update show a coarse layer or coarse Exact profile tables? Never for
    a render (its depsgraph, or while one runs: every frame renders the full layer
    and the exact tables), and only in Blender's window (`INTERACTIVE`)."""
    if _RENDERING or getattr(depsgraph, "mode", "VIEWPORT") == "RENDER":
        return False
    return (not bpy.app.background) if INTERACTIVE is None else INTERACTIVE


def refine(scene=None, wait=True) -> float | None:
    """The full layer (the exact tables) for the scenes showing a coarse one (all, or
    `scene`), each once its burst is over (``wait``: `BURST_SECONDS` after its last
    update; False: now). The timer's function: returns the seconds until it runs
    again, None when done."""
    now = time.perf_counter()
    again = 0.0
    for ptr in list(_PENDING):
        if scene is not None and ptr != scene.as_pointer():
            continue
        quiet = now - _LAST_RUN.get(ptr, 0.0)
        if wait and quiet < BURST_SECONDS:
            again = max(again, BURST_SECONDS - quiet)
            continue
        target = next((s for s in bpy.data.scenes if s.as_pointer() == ptr), None)
        context_scene = getattr(bpy.context, "scene", None)
        if target is None or not _on(target):
            _PENDING.discard(ptr)
            continue
        if context_scene is None or context_scene.as_pointer() != ptr:
            again = max(again, BURST_SECONDS)  # not the window's scene now: later
            continue
        _PENDING.discard(ptr)
        _run(target, bpy.context.evaluated_depsgraph_get(), "refined", coarse=False)
    return again or None


def _run(scene, depsgraph, why, force=False, coarse=None):
    global _BUSY, LAST_FIGURES
    if _BUSY:
        return
    _BUSY = True
    try:
        if coarse is None:
            coarse = _coarse_allowed(depsgraph)
        figures = update(scene, depsgraph, force, coarse)
        figures["why"] = why
        LAST_FIGURES = figures
    except Exception:  # a handler must never raise into Blender
        traceback.print_exc()
        LAST_FIGURES = dict(why=why, error=traceback.format_exc(limit=1))
    finally:
        _LAST_RUN[scene.as_pointer()] = time.perf_counter()
        _BUSY = False


def _on(scene) -> bool:
    settings = getattr(scene, "lens_lights", None)
    # The probe's scene copy carries the setting too: never update it.
    probe = scene.render.engine == render_probe.LENS_LIGHTS_RE_probe.bl_idname
    if settings is None or not settings.live_update or probe:
        return False
    # A bake's keys drive its lights, trees and images: never rebuilt under it (the
    # panel says live update waits; Clear or Generate ends the bake).
    return not bake_check.has_bake(scene)


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
    if _BUSY or depsgraph is None or not _on(scene):
        return
    why = relevant(scene, depsgraph)
    if why:
        _run(scene, depsgraph, "edit", force=why == "force")


@bpy.app.handlers.persistent
def on_render_start(scene, *args):
    global _RENDERING
    render_probe.note_render(True)
    _RENDERING += 1
    if scene.as_pointer() in _PENDING and _on(scene):  # never a coarse layer rendered
        refine(scene, wait=False)


@bpy.app.handlers.persistent
def on_render_end(scene, *args):
    global _RENDERING
    render_probe.note_render(False)
    _RENDERING = max(0, _RENDERING - 1)


@bpy.app.handlers.persistent
def on_save(*args):
    if _PENDING:  # a coarse state is never saved: the full one first
        refine(wait=False)
    # the Exact profile's images live update rewrote in place: packed as they are now
    lights.pack_dirty_profile_images()


@bpy.app.handlers.persistent
def on_load(*args):
    global _RENDERING
    _LAST_INPUTS.clear()  # another file: other objects
    _WATCHES.clear()
    _WATERS.clear()
    _LAYERS.clear()
    _RAYS.clear()
    _PENDING.clear()
    _RENDERING = 0
    render_probe.note_render(None)


def live_update_changed(settings, context):
    """The checkbox's update: turned on, bring the lights up to date at once; turned
    off while a coarse state shows, the full one first (never left coarse)."""
    scene = settings.id_data
    if not _on(scene):
        if scene.as_pointer() in _PENDING and context is not None and context.view_layer:
            _PENDING.discard(scene.as_pointer())
            _run(scene, context.evaluated_depsgraph_get(), "refined", coarse=False)
        return  # off, or a bake exists: left alone
    if context is not None and context.view_layer is not None:
        _run(scene, context.evaluated_depsgraph_get(), "turned on", force=True, coarse=False)


_HANDLERS = (
    ("frame_change_post", on_frame_change),
    ("depsgraph_update_post", on_depsgraph_update),
    ("render_init", on_render_start),
    ("render_complete", on_render_end),
    ("render_cancel", on_render_end),
    ("load_post", on_load),
    ("save_pre", on_save),
)


def register():
    handlers.install(_HANDLERS)
    set_live_update_hook(live_update_changed)


def unregister():
    set_live_update_hook(None)
    handlers.remove(_HANDLERS)
    if bpy.app.timers.is_registered(refine):
        bpy.app.timers.unregister(refine)
