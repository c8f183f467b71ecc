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
"""

from __future__ import annotations

import math

import bpy

from ..addon.scene_read import RENDER

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
