"""Operators "Generate lens lights" (`lens_lights.generate`) and "Clear lens lights"
(`lens_lights.clear`), both undoable.

Generate: remove the lights a previous run created (only those), read the scene
(`scene_reader`), run phase 1, choose the lights (`addon.light_models.plan_lights`:
energy model, brightness cut-off, maximum number) and create them
(`light_builder`). Reports how many lights were made and which pairs were skipped
and why (the first few by name); the figures are kept in `scene.lens_lights.last_*`
for the panel. A progress bar runs in the window (no-op without one).
"""
from __future__ import annotations

import time

import bpy

from ..addon.light_models import plan_lights
from ..addon.phase1 import compute_phase1
from . import light_builder
from .scene_reader import read_blender_scene

#: How many skipped pairs / left-out objects a report names.
REPORT_FIRST = 3
#: A beam's spot stays this share of the free distance behind the lens.
FREE_MARGIN = 0.9


def free_distance_behind(context, source, scene_size):
    """How far behind its lens (from the back vertex, against the beam) a beam's
    spot can sit without geometry between it and the lens: rays cast from the
    front vertex's plane backwards, on the axis and on four points of the beam's
    rim. Objects there must not block a beam that really starts at the lens.
    Returns None when nothing is hit within the default distance."""
    from mathutils import Vector
    from ..addon.light_models import COLLIMATED_DISTANCE_FACTOR
    u = Vector(tuple(float(x) for x in source.axis)).normalized()
    c = Vector(tuple(float(x) for x in source.lens_center))
    r = float(source.lens_radius)
    depsgraph = context.evaluated_depsgraph_get()
    limit = COLLIMATED_DISTANCE_FACTOR * scene_size
    side = u.orthogonal().normalized()
    other = u.cross(side)
    front = c - u * (r * 1.0001)
    nearest = None
    for offset in (Vector((0, 0, 0)), side, -side, other, -other):
        origin = front + offset * (0.9 * r)
        hit, location, *_ = context.scene.ray_cast(depsgraph, origin, -u, distance=limit)
        if hit:
            d = (location - origin).length
            nearest = d if nearest is None else min(nearest, d)
    if nearest is None:
        return None
    return FREE_MARGIN * nearest + 2.0 * r


class _Progress:
    """`window_manager.progress_*` in percent; harmless without a window."""

    def __init__(self, context):
        self.wm = context.window_manager if context.window else None

    def __enter__(self):
        if self.wm:
            self.wm.progress_begin(0, 100)
        return self

    def __call__(self, percent):
        if self.wm:
            self.wm.progress_update(int(percent))

    def __exit__(self, *exc):
        if self.wm:
            self.wm.progress_end()


def generate(context):
    """Do the work of the generate operator; returns (level, message, figures)."""
    scene = context.scene
    settings = scene.lens_lights
    t0 = time.perf_counter()
    with _Progress(context) as progress:
        light_builder.clear(scene)
        progress(5)
        read = read_blender_scene(context)
        progress(35)
        result = compute_phase1(read.scene)
        progress(50)
        plan = plan_lights(
            result, read.primaries, settings.energy_model, optics=read.lens_optics,
            light_names=read.light_sources, lens_names=read.sphere_sources,
            lens_candidates=read.lens_candidates, min_brightness=settings.min_brightness,
            max_lights=settings.max_lights, spot_blend=settings.spot_blend,
            scene_size=read.scene_size, scene_bounds=read.bounds,
            far_limit=lambda src: free_distance_behind(context, src, read.scene_size))
        progress(60)
        total = max(len(plan.lights), 1)
        made = light_builder.build(scene, plan, read.sphere_objects,
                                   progress=lambda k: progress(60 + 40 * k / total))
        progress(100)

    lenses = sum(1 for c in read.lens_candidates if c)
    figures = dict(created=len(made), sources=len(result.sources), skipped=len(plan.skipped),
                   primaries=len(read.scene.lights), lenses=lenses,
                   left_out=len(read.left_out_lenses), seconds=time.perf_counter() - t0)
    level = "INFO"
    parts = [f"Created {len(made)} lens light{'s' if len(made) != 1 else ''} "
             f"({len(read.scene.lights)} point light{'s' if len(read.scene.lights) != 1 else ''}"
             f" × {lenses} lens{'es' if lenses != 1 else ''})"]
    if not read.scene.lights:
        level = "WARNING"
        parts.append("no point light is enabled for rendering")
    elif lenses == 0:
        level = "WARNING"
        parts.append("no glass sphere found")
    if plan.skipped:
        parts.append(f"skipped {len(plan.skipped)} pair{'s' if len(plan.skipped) != 1 else ''}: "
                     + plan.skipped_summary(REPORT_FIRST))
    if read.left_out_lenses:
        shown = "; ".join(f"{n}: {why}" for n, why in read.left_out_lenses[:REPORT_FIRST])
        more = len(read.left_out_lenses) - REPORT_FIRST
        parts.append(f"left out {len(read.left_out_lenses)} object"
                     f"{'s' if len(read.left_out_lenses) != 1 else ''}: {shown}"
                     + (f"; and {more} more" if more > 0 else ""))
    message = "; ".join(parts)

    settings.last_run = True
    settings.last_created = figures["created"]
    settings.last_sources = figures["sources"]
    settings.last_skipped = figures["skipped"]
    settings.last_primaries = figures["primaries"]
    settings.last_lenses = figures["lenses"]
    settings.last_left_out = figures["left_out"]
    settings.last_seconds = figures["seconds"]
    settings.last_report = message
    return level, message, figures


class LENS_LIGHTS_OT_generate(bpy.types.Operator):
    """Turn every point light × glass sphere into a spot light that paints its caustic"""
    bl_idname = "lens_lights.generate"
    bl_label = "Generate lens lights"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return context.scene is not None

    def execute(self, context):
        level, message, _ = generate(context)
        self.report({level}, message)
        return {"FINISHED"}


class LENS_LIGHTS_OT_clear(bpy.types.Operator):
    """Remove the lens lights this extension created (and nothing else)"""
    bl_idname = "lens_lights.clear"
    bl_label = "Clear lens lights"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return context.scene is not None

    def execute(self, context):
        removed = light_builder.clear(context.scene)
        settings = context.scene.lens_lights
        settings.last_created = 0
        settings.last_report = f"Removed {removed} lens light{'s' if removed != 1 else ''}"
        self.report({"INFO"}, settings.last_report)
        return {"FINISHED"}


_CLASSES = (LENS_LIGHTS_OT_generate, LENS_LIGHTS_OT_clear)


def register():
    for cls in _CLASSES:
        bpy.utils.register_class(cls)


def unregister():
    for cls in reversed(_CLASSES):
        bpy.utils.unregister_class(cls)
