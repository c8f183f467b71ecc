"""The render depsgraph of a scene, which Python cannot create: a tiny render of
a copy of the scene with a probe engine hands it over (`rendered_depsgraph`).

**Which depsgraph.** A final render (F12) evaluates the scene in a *render*
depsgraph (``Depsgraph.mode == 'RENDER'``): render visibility (the object's and
the collections' camera icon, view-layer exclusion), modifiers' render settings
(Subdivision's render levels, ``show_render``), geometry nodes' "Is Viewport",
instancers' ``show_instancer_for_render``.  The depsgraph Python gets from
``context.evaluated_depsgraph_get()`` is the *viewport* one: objects disabled in
the viewport (monitor icon, also on a collection) or hidden (eye icon) are not in
it at all, objects disabled for rendering are, and modifiers use their viewport
settings.  Python cannot create a render depsgraph; only a render engine is handed
one.  So :func:`rendered_depsgraph` runs a function on the depsgraph of a real,
tiny render:

1. it copies the context scene (``Scene.copy()``: a shallow copy with the same
   objects and child collections, copies of the view layers with their
   exclusions, and of the render settings), sets the copy's engine to a probe
   engine registered only for this (so it never shows in the engine menu), turns
   compositing and the sequencer off in the copy, keeps only the context's view
   layer, shrinks the resolution, and renders the copy
   (``bpy.ops.render.render(scene=copy, layer=view layer)``);
2. the probe's ``render(depsgraph)`` calls the function with the render
   depsgraph (Blender evaluates it exactly as for F12) and keeps its result;
3. the copy (and a temporary camera, added to the copy only when the scene has
   none: a render needs one), the probe engine and, if the probe created it, the
   "Render Result" image are removed.

The user's scene is never changed, and their last render is kept (the copy
renders into its own render result).  **No handler runs**: for the probe's
duration every function in ``bpy.app.handlers`` ``render_init``, ``render_pre``,
``render_post``, ``render_stats``, ``render_write``, ``render_complete``,
``render_cancel``, ``frame_change_pre`` and ``frame_change_post`` (the user's, a
render farm's, persistent or not, and the extension's own) is detached, and each
list is put back in its order afterwards, also when the render fails (a handler
something appends meanwhile is kept, after them).  So Generate neither runs a
farm's render hooks nor recurses through a user's ``frame_change_pre`` handler
that calls Generate.  When the probe cannot run (a render is in progress — a
render job, or a render of the user's that calls Generate from one of its
handlers: a render started inside a render crashes Blender; the extension's own
render handlers count those, `note_render` — or the render is refused), the
viewport depsgraph is read instead with the render-visibility rules applied by
hand, and the read says so (``BlenderSceneRead.how``).

**When the viewport's depsgraph is the render's** (`as_rendered`). The probe
builds and evaluates a whole second depsgraph (16 CPU s on 100 000
collection-instance empties), so it is skipped when nothing in the file can make
the render depsgraph differ from the viewport one (`viewport_differs`:
vectorised over ``bpy.data.objects`` and collections, the modifier stacks read
only for objects that can have one): every object and collection has the same
viewport and render visibility (``hide_viewport`` == ``hide_render``,
``show_instancer_for_viewport`` == ``…_for_render``), every object the render
shows at the top level is visible in the view layer (no eye, no local view),
every modifier is on or off in both and is of a type that evaluates alike in both
(Subdivision and Multires with equal levels — Subdivision only with GPU
subdivision off in the preferences —, Screw with equal steps, geometry nodes
without an "Is Viewport" node in their trees), curves and metaballs have equal
resolutions, Simplify is off, no background scene, Object Mode, and no render is
under way.  Then the viewport depsgraph is read as it is
(`reads_viewport_as_render`: no rule applied by hand, none is needed) and
``BlenderSceneRead.how`` is `VIEWPORT_AS_RENDER`; anything else is probed.
"""

from __future__ import annotations

import math

import bpy
import numpy as np

from ...core.scene.assembly import RENDER

#: `BlenderSceneRead.how` when the viewport depsgraph was read because nothing in
#: the file renders differently (`as_rendered`).
VIEWPORT_AS_RENDER = "render (the viewport depsgraph: nothing renders differently)"

#: The probe render's smaller image side, in pixels (the resolution is scaled down
#: to about this; nothing is drawn, but the render result is allocated).
PROBE_PIXELS = 16


#: The handler lists a render fires (`render.render` on the copy): detached while
#: the probe renders (see the module's docstring).
QUIET_HANDLERS = (
    "render_init",
    "render_pre",
    "render_post",
    "render_stats",
    "render_write",
    "render_complete",
    "render_cancel",
    "frame_change_pre",
    "frame_change_post",
)


class ProbeUnavailable(RuntimeError):
    """The render depsgraph could not be had (the reason is the message)."""


class _ProbeRun:
    def __init__(self, fn):
        self.fn, self.done, self.value, self.error = fn, False, None, None

    def __call__(self, depsgraph):
        if self.done:  # multi-view: one call is enough
            return
        self.done = True
        try:
            self.value = self.fn(depsgraph)
        except BaseException as exc:  # re-raised outside the render
            self.error = exc


_ACTIVE_RUN: _ProbeRun | None = None
#: Renders of the user's under way (`note_render`, from the extension's own
#: render_init / render_complete / render_cancel handlers in `live_update`): a
#: render started inside one crashes Blender, so the probe refuses then.
_RENDERS_RUNNING = 0


def note_render(started: bool | None):
    """Count a render of the user's starting (True) or ending (False); None: forget
    them all (a file was loaded)."""
    global _RENDERS_RUNNING
    if started is None:
        _RENDERS_RUNNING = 0
    else:
        _RENDERS_RUNNING = _RENDERS_RUNNING + 1 if started else max(0, _RENDERS_RUNNING - 1)


class LENS_LIGHTS_RE_probe(bpy.types.RenderEngine):
    """Registered only while `rendered_depsgraph` renders: hands over the render
    depsgraph and draws nothing."""

    bl_idname = "LENS_LIGHTS_PROBE"
    bl_label = "Lens Lights scene probe"
    bl_use_preview = False

    def render(self, depsgraph):
        if _ACTIVE_RUN is not None:
            _ACTIVE_RUN(depsgraph)


class _HandlersDetached:
    """Empties the `QUIET_HANDLERS` lists and puts them back, in order, on exit."""

    def __enter__(self):
        self.saved = {}
        for name in QUIET_HANDLERS:
            handlers = getattr(bpy.app.handlers, name, None)
            if handlers is not None:
                self.saved[name] = list(handlers)
                handlers.clear()
        return self

    def __exit__(self, *exc):
        for name, saved in self.saved.items():
            handlers = getattr(bpy.app.handlers, name)
            added = [f for f in handlers if f not in saved]  # appended meanwhile: kept
            handlers.clear()
            handlers.extend(saved + added)


def _render_results():
    return {img.as_pointer() for img in bpy.data.images if img.type == "RENDER_RESULT"}


def _probe(scene, view_layer, fn):
    global _ACTIVE_RUN
    if bpy.app.is_job_running("RENDER") or _RENDERS_RUNNING:
        raise ProbeUnavailable("a render is in progress")
    run = _ProbeRun(fn)
    results_before = _render_results()
    copy = camera = None
    registered = False
    try:
        if not LENS_LIGHTS_RE_probe.is_registered:
            bpy.utils.register_class(LENS_LIGHTS_RE_probe)
            registered = True
        copy = scene.copy()
        copy.name = f"{scene.name} (Lens Lights probe)"
        r = copy.render
        r.engine = LENS_LIGHTS_RE_probe.bl_idname
        r.use_compositing = False
        r.use_sequencer = False
        side = max(1, min(r.resolution_x, r.resolution_y))
        r.resolution_percentage = int(min(100, max(1, math.ceil(100.0 * PROBE_PIXELS / side))))
        for layer in copy.view_layers:
            layer.use = layer.name == view_layer.name
        if copy.camera is None:
            camera = bpy.data.objects.new(
                "Lens Lights probe camera", bpy.data.cameras.new("Lens Lights probe camera")
            )
            copy.collection.objects.link(camera)
            copy.camera = camera
        _ACTIVE_RUN = run
        with _HandlersDetached():
            bpy.ops.render.render(scene=copy.name, layer=view_layer.name)
    except Exception as exc:  # the caller falls back
        if run.error is None:
            raise ProbeUnavailable(f"the probe render failed: {str(exc).strip()}") from None
    finally:
        _ACTIVE_RUN = None
        # Each step on its own: one failing must not keep the others from running.
        steps = []
        if copy is not None:
            steps.append(lambda: bpy.data.scenes.remove(copy))
        if camera is not None:
            data = camera.data
            steps += [
                lambda: bpy.data.objects.remove(camera),
                lambda: bpy.data.cameras.remove(data),
            ]
        if registered:
            steps.append(lambda: bpy.utils.unregister_class(LENS_LIGHTS_RE_probe))
        steps.append(
            lambda: [
                bpy.data.images.remove(img)
                for img in list(bpy.data.images)
                if img.type == "RENDER_RESULT" and img.as_pointer() not in results_before
            ]
        )
        for step in steps:
            try:
                step()
            except Exception:
                import traceback

                traceback.print_exc()
    if run.error is not None:
        raise run.error
    if not run.done:
        raise ProbeUnavailable("the render did not reach the scene")
    return run.value


def rendered_depsgraph(context, fn):
    """``(fn(depsgraph), how)`` with the render depsgraph of the context's scene and
    view layer (see the module's docstring); when that cannot be had, with the
    viewport depsgraph, and `how` says why. Exceptions of `fn` propagate."""
    try:
        return _probe(context.scene, context.view_layer, fn), RENDER
    except ProbeUnavailable as exc:
        why = str(exc)
    return fn(context.evaluated_depsgraph_get()), f"viewport ({why})"


# --------------------------------------------------------------------------- viewport = render

#: Modifier types whose result does not depend on the evaluation mode (the others
#: are checked one by one in `_modifier_differs`, or make the probe run).
SAME_MODIFIERS = frozenset(
    {
        "ARMATURE", "CAST", "CURVE", "DISPLACE", "HOOK", "LAPLACIANDEFORM", "LATTICE",
        "MESH_DEFORM", "SHRINKWRAP", "SIMPLE_DEFORM", "SMOOTH", "CORRECTIVE_SMOOTH",
        "LAPLACIANSMOOTH", "SURFACE_DEFORM", "WARP", "WAVE", "ARRAY", "BEVEL", "BOOLEAN",
        "BUILD", "DECIMATE", "EDGE_SPLIT", "MASK", "MIRROR", "REMESH", "SKIN", "SOLIDIFY",
        "TRIANGULATE", "WELD", "WIREFRAME", "WEIGHTED_NORMAL", "NORMAL_EDIT",
        "DATA_TRANSFER", "UV_PROJECT", "UV_WARP", "VERTEX_WEIGHT_EDIT",
        "VERTEX_WEIGHT_MIX", "VERTEX_WEIGHT_PROXIMITY", "MESH_CACHE",
    }
)  # fmt: skip
#: Object types that carry no modifier stack (their objects are not looped over).
_NO_MODIFIERS = frozenset({"EMPTY", "LIGHT", "CAMERA", "SPEAKER", "LIGHT_PROBE", "ARMATURE"})

#: The pointer of the depsgraph `as_rendered` is handing over as the render one.
_VIEWPORT_AS_RENDER: int | None = None


def reads_viewport_as_render(depsgraph) -> bool:
    """Whether `depsgraph` is a viewport depsgraph `as_rendered` hands over as the
    render one (readers then apply no render rule by hand)."""
    return _VIEWPORT_AS_RENDER is not None and depsgraph.as_pointer() == _VIEWPORT_AS_RENDER


def render_visible_objects(view_layer) -> set:
    """Original objects in at least one collection of `view_layer` enabled for
    rendering (not excluded, not ``hide_render``, nor a parent of it)."""
    visible = set()
    evaluated = view_layer.id_data.is_evaluated  # an original scene holds originals

    def walk(layer_coll, parent_hidden):
        coll = layer_coll.collection
        hidden = parent_hidden or layer_coll.exclude or coll.hide_render
        if not hidden:
            visible.update((ob.original for ob in coll.objects) if evaluated else coll.objects)
        for child in layer_coll.children:
            walk(child, hidden)

    walk(view_layer.layer_collection, False)
    return visible


def _flags(items, name) -> np.ndarray:
    out = np.zeros(len(items), dtype=bool)
    if len(items):
        items.foreach_get(name, out)
    return out


def _tree_uses_viewport(tree, seen: dict) -> bool:
    """Whether a node tree (or a group in it) has an "Is Viewport" node (or any node
    named for the viewport)."""
    key = tree.as_pointer()
    if key in seen:
        return seen[key]
    seen[key] = False  # (a group inside itself: not possible, but never loop)
    found = False
    for node in tree.nodes:
        if "Viewport" in node.bl_idname:
            found = True
            break
        sub = getattr(node, "node_tree", None)
        if sub is not None and _tree_uses_viewport(sub, seen):
            found = True
            break
    seen[key] = found
    return found


def _modifier_differs(md, gpu_subdivision: bool, trees: dict) -> bool:
    if md.show_viewport != md.show_render:
        return True
    if not md.show_render:
        return False  # off in both
    kind = md.type
    if kind in SAME_MODIFIERS:
        return False
    if kind == "SUBSURF":
        # The viewport may leave a Subdivision (the last of the stack) to the GPU:
        # its evaluated mesh is then the cage.
        return md.levels != md.render_levels or gpu_subdivision
    if kind == "MULTIRES":
        return md.levels != md.render_levels
    if kind == "SCREW":
        return md.steps != md.render_steps
    if kind == "NODES":
        return md.node_group is not None and _tree_uses_viewport(md.node_group, trees)
    return True  # particles, ocean, fluid, unknown: the probe decides


def _data_differs(ob) -> bool:
    """Curves and metaballs with a render resolution of their own."""
    data = ob.data
    if ob.type in ("CURVE", "SURFACE", "FONT"):
        if data.render_resolution_u not in (0, data.resolution_u):
            return True
        return ob.type == "SURFACE" and data.render_resolution_v not in (0, data.resolution_v)
    if ob.type == "META":
        return data.render_resolution != data.resolution
    return False


def viewport_differs(context) -> str | None:
    """Why the render depsgraph of the context's scene and view layer could differ
    from its viewport depsgraph (the first reason found), or None when it cannot
    (see the module's docstring). Cheap: flags read with ``foreach_get``; modifier
    stacks only of the objects that can have one."""
    scene = context.scene
    mode = getattr(context, "mode", None)
    if mode != "OBJECT":
        return f"{str(mode).lower().replace('_', ' ')} mode"
    shown = getattr(context, "visible_objects", None)
    if shown is None:
        return "the context has no visible objects"
    if scene.render.use_simplify:
        return "Simplify is on"
    if scene.background_set is not None:
        return "a background scene is set"
    objects = bpy.data.objects
    pairs = (
        ("hide_viewport", "hide_render"),
        ("show_instancer_for_viewport", "show_instancer_for_render"),
    )
    for a, b in pairs:
        diff = np.flatnonzero(_flags(objects, a) != _flags(objects, b))
        if len(diff):
            return f"{objects[int(diff[0])].name}: {a} differs from {b}"
    collections = bpy.data.collections
    diff = np.flatnonzero(
        _flags(collections, "hide_viewport") != _flags(collections, "hide_render")
    )
    if len(diff):
        return (
            f"collection {collections[int(diff[0])].name}: hide_viewport differs from hide_render"
        )
    # Object types as enum values: which values carry modifiers, named from one object each.
    codes = np.zeros(len(objects), dtype=np.int32)
    if len(objects):
        objects.foreach_get("type", codes)
    values, first = np.unique(codes, return_index=True)
    stacked = [
        v for v, k in zip(values, first, strict=True) if objects[int(k)].type not in _NO_MODIFIERS
    ]
    gpu = bool(getattr(context.preferences.system, "use_gpu_subdivision", False))
    trees: dict = {}
    for k in np.flatnonzero(np.isin(codes, stacked)):
        ob = objects[int(k)]
        if _data_differs(ob):
            return f"{ob.name}: its render resolution differs"
        for md in ob.modifiers:
            if _modifier_differs(md, gpu, trees):
                return f"{ob.name}: modifier {md.name} ({md.type.lower()})"
    # What the render shows at the top level must be visible in the view layer (the
    # eye, local view: flags the depsgraph has but `hide_*` do not say).
    expected = render_visible_objects(context.view_layer)
    hidden = np.flatnonzero(_flags(objects, "hide_render"))
    if len(hidden):  # (few: read one by one)
        listed = objects.values()
        expected -= {listed[int(k)] for k in hidden}
    missing = expected - set(shown)
    if missing:
        return f"{min(ob.name for ob in missing)} is hidden in the viewport"
    return None


def as_rendered(context, fn):
    """``(fn(depsgraph), how)`` with a depsgraph that is the render one: the viewport
    depsgraph when nothing in the file renders differently (`viewport_differs`; `how`
    is `VIEWPORT_AS_RENDER`) and no render is under way, else `rendered_depsgraph`'s
    (the probe, or its fallback). Exceptions of `fn` propagate."""
    global _VIEWPORT_AS_RENDER
    # During a render of the user's (Generate from one of its handlers) the probe's
    # fallback reads the viewport and says so, as it always did.
    rendering = bpy.app.is_job_running("RENDER") or _RENDERS_RUNNING
    try:
        differs = rendering or viewport_differs(context) is not None
    except Exception:  # something the check does not know: the probe decides
        differs = True
    if differs:
        return rendered_depsgraph(context, fn)
    depsgraph = context.evaluated_depsgraph_get()
    _VIEWPORT_AS_RENDER = depsgraph.as_pointer()
    try:
        return fn(depsgraph), VIEWPORT_AS_RENDER
    finally:
        _VIEWPORT_AS_RENDER = None
