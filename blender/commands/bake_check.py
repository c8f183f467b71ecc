"""Is the bake still what the scene would give? (issue 28: a bake knows what it was
baked from.)

The bake keeps, per baked frame, the prints of what the pipeline read
(`core.animation.bake_inputs`; `record`, stored in ``scene.lens_lights.baked_from``).
`check` reads the scene again at the current frame (the read only: no phase 1, no
plan) and compares. It runs

* when the panel draws (`status`: cached until the next depsgraph update or frame
  change, so a redraw costs nothing);
* on every frame a render evaluates (``frame_change_post`` with the render's own
  depsgraph: F12, animations, ``blender -b``): an out-of-date frame prints
  "Lens Lights: The bake (frames 1–10) is out of date at frame 5: Marble moved
  since it was baked; Bake again" (`LAST_RENDER_WARNING`). The frame renders as
  baked: the warning is all it does.

A viewport read against a bake read as the render evaluates (or the other way
round) compares where each object is and what it is made of, not shapes nor who is
there (modifiers' viewport levels, objects hidden in the viewport differ between
the two); the render's check compares everything.

A render farm without the extension cannot check: it renders the bake as baked.
"""

from __future__ import annotations

import time
import traceback
from dataclasses import dataclass, field

import bpy

from ...core.animation.bake_inputs import (
    AWAY,
    CAMERA,
    SETTINGS,
    BakeInputs,
    Change,
    away,
    changes,
    differing,
    frame_prints,
    light_paths,
    stale_text,
)
from ...core.tiers import builds_layer
from ..build.ownership import created_objects
from ..read.render_probe import viewport_differs
from ..read.scene import read_depsgraph
from . import handlers, pipeline

#: The last warning a render printed (None: none since the extension loaded).
LAST_RENDER_WARNING: str | None = None
#: Bumped on every depsgraph update: the panel's cached status is then old.
_GENERATION = 0
#: Per scene pointer: (cache key, `BakeStatus`, when it was computed).
_STATUS: dict = {}
#: A check that cost more than this (seconds) is run again at most every
#: `RECHECK_FACTOR` × its cost (dragging in a big scene: the panel keeps its last
#: status meanwhile and redraws when the wait is over).
RECHECK_ABOVE = 0.02
RECHECK_FACTOR = 10.0
#: The pending redraw's timer function (None: none pending).
_REDRAW = None


def extras(read, options: dict) -> dict:
    """The pseudo-objects of a frame's prints: the settings the plan used, and for
    the Caustic layer (fitted to the camera's view) the camera and image size."""
    out = {SETTINGS: options}
    if builds_layer(options["energy_model"]):
        out[CAMERA] = (read.camera, read.width, read.height)
    return out


def prints_of(read, options: dict, paths=True) -> dict:
    """The prints of one read (`core.animation.bake_inputs.frame_prints`); `paths`:
    surfaces away from every path of the light marked so (`light_paths`; not for the
    Caustic layer, whose beam lands wherever it lands: every object counts)."""
    if paths and not builds_layer(options["energy_model"]):
        paths = light_paths(read)
    else:
        paths = None
    return frame_prints(read.inputs, extras(read, options), paths)


def read_as_render(how: str) -> bool:
    """Whether a read's ``how`` is the render's evaluation (a probe render, or the
    viewport's depsgraph where nothing renders differently)."""
    return how != "viewport"


def record(scene, frames, prints, render: bool) -> BakeInputs:
    """Store the bake's prints in `scene` (``lens_lights.baked_from``)."""
    rec = BakeInputs.of_frames(frames, prints, render)
    scene.lens_lights.baked_from = rec.to_text()
    return rec


def baked_inputs(scene) -> BakeInputs | None:
    """What `scene`'s bake was baked from; None: no bake (none made, cleared, replaced
    by Generate, or all its lights deleted)."""
    settings = getattr(scene, "lens_lights", None)
    if settings is None or not settings.baked_from:
        return None
    if not created_objects(scene):
        return None
    return BakeInputs.from_text(settings.baked_from)


def has_bake(scene) -> bool:
    """Whether `scene` holds a bake (cheap: live update asks on every update)."""
    settings = getattr(scene, "lens_lights", None)
    return bool(settings is not None and settings.baked_from and len(settings.created_objects))


@dataclass
class BakeStatus:
    first: int
    last: int
    frame: int
    changes: list[Change] = field(default_factory=list)
    seconds: float = 0.0

    @property
    def stale(self) -> bool:
        return bool(self.changes)

    @property
    def text(self) -> str:
        return stale_text(self.first, self.last, self.frame, self.changes) if self.stale else ""


def check(scene, depsgraph, frame: int | None = None, *, render: bool | None = None):
    """The bake's status at `frame` (default: the scene's) against `depsgraph` read
    now (`render`: whether that depsgraph evaluates as the render does; default: a
    render depsgraph does); None without a bake or outside its frames."""
    rec = baked_inputs(scene)
    frame = scene.frame_current if frame is None else int(frame)
    if rec is None or not rec.covers(frame):
        return None
    t = time.perf_counter()
    read = read_depsgraph(depsgraph, scene)
    read.occluders.release()
    options = pipeline.options_from(scene.lens_lights)
    now = prints_of(read, options, paths=False)  # the paths only where something differs
    names = differing(rec.at(frame), now)
    if names and not builds_layer(options["energy_model"]):
        for name in away(read.inputs, [n for n in names if n in now], light_paths(read)):
            now[name] = AWAY + now[name][1:]
    if render is None:
        render = depsgraph.mode == "RENDER"
    same_kind = render == rec.render
    baked = rec.at(frame)
    if not same_kind:  # who is there and shapes differ between the two evaluations
        common = baked.keys() & now.keys()
        baked = {k: baked[k] for k in common}
        now = {k: now[k] for k in common}
    found = changes(baked, now, shapes=same_kind)
    return BakeStatus(rec.first, rec.last, frame, found, time.perf_counter() - t)


def status(context):
    """`check` of the context's scene at its frame on the view layer's depsgraph,
    cached until the next depsgraph update or frame change (for the panel)."""
    scene = context.scene
    settings = scene.lens_lights
    if not settings.baked_from:
        return None
    key = (_GENERATION, scene.frame_current, hash(settings.baked_from))
    cached = _STATUS.get(scene.as_pointer())
    if cached is not None:
        if cached[0] == key:
            return cached[1]
        cost = cached[1].seconds if cached[1] is not None else 0.0
        wait = RECHECK_FACTOR * cost - (time.perf_counter() - cached[2])
        if cost > RECHECK_ABOVE and wait > 0:
            _redraw_later(wait)
            return cached[1]
    try:
        render = viewport_differs(context) is None
    except Exception:
        render = False
    depsgraph = context.view_layer.depsgraph
    try:
        result = check(scene, depsgraph, render=render)
    except Exception:  # the panel draws on: the render's check still runs
        traceback.print_exc()
        result = None
    _STATUS[scene.as_pointer()] = (key, result, time.perf_counter())
    return result


def _redraw_later(seconds: float):
    """Redraw the 3D views' sidebars in `seconds` (once, however often asked)."""
    global _REDRAW
    if _REDRAW is not None:
        return

    def redraw():
        global _REDRAW
        _REDRAW = None
        for window in bpy.context.window_manager.windows:
            for area in window.screen.areas:
                if area.type == "VIEW_3D":
                    area.tag_redraw()
        return None  # once

    _REDRAW = redraw
    bpy.app.timers.register(redraw, first_interval=seconds)


def cancel_redraw():
    """Drop a pending redraw (unregistering, loading a file: Blender 4.5's bpy module
    waits for a pending timer when Python exits)."""
    global _REDRAW
    if _REDRAW is not None and bpy.app.timers.is_registered(_REDRAW):
        bpy.app.timers.unregister(_REDRAW)
    _REDRAW = None


def render_warning(scene, depsgraph) -> str | None:
    """The warning of a frame a render evaluates (`depsgraph`: the render's), printed
    and kept in `LAST_RENDER_WARNING`; None when the bake is up to date there."""
    global LAST_RENDER_WARNING
    result = check(scene, depsgraph)
    if result is None or not result.stale:
        return None
    LAST_RENDER_WARNING = "Lens Lights: " + result.text
    print(LAST_RENDER_WARNING)
    return LAST_RENDER_WARNING


@bpy.app.handlers.persistent
def on_depsgraph_update(scene, depsgraph=None):
    global _GENERATION
    _GENERATION += 1


@bpy.app.handlers.persistent
def on_frame_change(scene, depsgraph=None):
    global _GENERATION
    _GENERATION += 1
    if depsgraph is None or depsgraph.mode != "RENDER":
        return
    settings = getattr(scene, "lens_lights", None)
    if settings is None or not settings.baked_from:
        return
    try:
        render_warning(scene, depsgraph)
    except Exception:  # a handler must never raise into Blender
        traceback.print_exc()


@bpy.app.handlers.persistent
def on_load(*args):
    _STATUS.clear()
    cancel_redraw()


_HANDLERS = (
    ("depsgraph_update_post", on_depsgraph_update),
    ("frame_change_post", on_frame_change),
    ("load_post", on_load),
)


def register():
    handlers.install(_HANDLERS)


def unregister():
    cancel_redraw()
    handlers.remove(_HANDLERS)
