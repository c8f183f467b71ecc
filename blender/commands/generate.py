"""Operators "Generate lens lights" (`lens_lights.generate`) and "Clear lens lights"
(`lens_lights.clear`), both undoable. Only what needs Blender is here; the
planning (`core/plan/planning.py`) and the report (`core/report/message.py`) are pure.

Generate works in two stages, so that a failure never leaves the scene half-done:

1. **Plan** (nothing in the file changes): the pipeline Bake and Live update share
   (`pipeline.plan_scene`: read, phase 1, plan, the Caustic layer's stage) on the
   scene as the renderer sees it (`render_probe.as_rendered`: the render depsgraph of
   the context scene and view layer — the viewport one when nothing renders
   differently, else a probe render's), with the options of the scene's settings
   (`pipeline.options_from`).
2. **Build**: remove what a previous run created (only that: `cleanup.clear`) and put
   back the Cycles settings it changed, create the planned lights (`lights`) or the
   Caustic layers (`layer_stage.build`), and with "Replace Cycles' Caustics" on turn
   Cycles' own caustics of their lenses off (`cycles_caustics`: recorded, restored by
   Clear and by the next Generate).

A failure in stage 1 is reported and changes nothing (the operator is cancelled);
one in stage 2 removes what was made and is reported. Generate never raises.

The report (`report.report_message`) says how many lens lights and caustic layers
were made (each by its name), which pairs
got none and why (the first few by name, then counts per reason), how many
sources were merged, and which share of the lenses' estimated flux has no light.
The figures are kept in `scene.lens_lights.last_*` for the panel and, with the
time of each step, in `LAST_FIGURES`. A progress bar runs in the window (no-op
without one).
"""

from __future__ import annotations

import time
import traceback

import bpy

from ...core.plan.cycles_caustics import describe_restored
from ...core.report.message import (
    error_text,
    linking_groups_note,
    linking_note,
    made_text,
    report_message,
)
from ...core.scene.assembly import RENDER
from ...core.tiers import builds_layer
from ..build import cleanup, cycles_caustics, layers, lights, ownership
from ..read.render_probe import VIEWPORT_AS_RENDER, as_rendered
from ..ui.scene_state import has_lens_lights
from . import layer_stage, pipeline, water_stage

#: The figures of the last run of `generate` (with "timings": seconds per step).
LAST_FIGURES: dict = {}


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


def _store(settings, message, figures):
    settings.last_run = True
    settings.last_created = figures.get("created", 0)
    settings.last_layers = figures.get("layers", 0)
    settings.last_fallback = figures.get("fallback", 0)
    settings.last_sources = figures.get("sources", 0)
    settings.last_skipped = figures.get("skipped", 0)
    settings.last_primaries = figures.get("primaries", 0)
    settings.last_lenses = figures.get("lenses", 0)
    settings.last_left_out = figures.get("left_out", 0)
    settings.last_seconds = figures.get("seconds", 0.0)
    settings.last_report = message


def generate(context):
    """Do the work of the generate operator; returns (level, message, figures).
    Never raises: an error is returned as level "ERROR" (figures["changed"] says
    whether the file was changed)."""
    global LAST_FIGURES
    scene = context.scene
    settings = scene.lens_lights
    t0 = time.perf_counter()
    with _Progress(context) as progress:
        # 1. Plan (nothing changes).
        try:
            options = pipeline.options_from(settings)
            t = time.perf_counter()
            work, how = as_rendered(
                context,
                lambda dg: water_stage.prepare(dg, pipeline.plan_scene(dg, scene, options)),
            )
            work.read.how = how
            work.timings["probe_total"] = time.perf_counter() - t
        except Exception as exc:  # reported, never raised
            message = error_text("read the scene", exc)
            traceback.print_exc()
            figures = dict(changed=False, seconds=time.perf_counter() - t0)
            LAST_FIGURES = figures
            settings.last_run = True
            settings.last_report = message
            return "ERROR", message, figures
        progress(60)
        # 2. Build.
        t = time.perf_counter()
        plan = work.plan
        linking = None
        total = max(len(plan.lights), 1)
        try:
            cleanup.clear(scene)
            cycles_caustics.restore(scene)
            if builds_layer(options["energy_model"]):  # the layers replace the lights
                made = layer_stage.build(scene, work, lambda f: progress(60 + 40 * f))
            else:
                made = lights.build(
                    scene,
                    plan,
                    work.read.sphere_objects,
                    progress=lambda k: progress(60 + 40 * k / total),
                    arrays=work.read.arrays,
                )
                a, tl = work.read.arrays, time.perf_counter()
                linking = lights.link_lights(
                    scene,
                    made,
                    plan.lights,
                    a.center,
                    a.radius,
                    work.read.sphere_objects,
                    user_links=lights.user_links_of(plan.lights, work.read.light_objects),
                )
                work.timings["linking"] = time.perf_counter() - tl
                # the glass meshes' caustic layers beside the spheres' lens lights
                made += layer_stage.build_mesh_layers(scene, work)
            made += water_stage.build(scene, work)  # the water's layers, in every tier
            counted = layers.made_counts(made)
            caustics_note, caustics_warn = cycles_caustics.after_build(
                scene, plan, work.read, len(made), layers=counted["layers"] > 0
            )
        except Exception as exc:  # whatever failed: remove what was made, report it
            traceback.print_exc()
            try:
                cleanup.clear(scene)
                cycles_caustics.restore(scene)
            except Exception:
                traceback.print_exc()
            message = error_text("create the lens lights", exc) + " (the lens lights were removed)"
            figures = dict(changed=True, created=0, seconds=time.perf_counter() - t0)
            LAST_FIGURES = figures
            _store(settings, message, figures)
            return "ERROR", message, figures
        work.timings["build"] = time.perf_counter() - t
        progress(100)

    try:
        level, message, figures = report_message(
            work, **counted, read_as_rendered=work.read.how in (RENDER, VIEWPORT_AS_RENDER)
        )
    except Exception as exc:  # the lights are made: say so
        traceback.print_exc()
        level = "WARNING"
        figures = dict(created=counted["made"], layers=counted["layers"])
        message = f"Created {made_text(*counted.values())}; " + error_text("write the report", exc)
    meshes = layer_stage.mesh_lenses_note(work, counted["layers"])
    if meshes:
        message = f"{message}; {meshes}"
    water = water_stage.note(work)
    if water:
        message = f"{message}; {water}"
    if work.layer_figures is not None:
        message = f"{message}; {work.layer_figures.text()}"
        figures["layer"] = vars(work.layer_figures)
    if options["model_warning"]:
        level = "WARNING" if level == "INFO" else level
        message = f"{message}; {options['model_warning']}"
    inside = sum(1 for p in work.plan.lights if getattr(p.light, "inside_lens", False))
    eevee_note = linking_note(bpy.app.version, scene.render.engine, inside)
    if eevee_note:
        level = "WARNING" if level == "INFO" else level
        message = f"{message}; {eevee_note}"
    if linking is not None:
        linking.blender_says = lights.linking_messages(context)
        figures["linking"] = vars(linking)
        sets_note = linking_groups_note(
            linking.ungrouped, linking.conflicts, linking.blender_says, linking.user_sets
        )
        if sets_note:
            level = "WARNING" if level == "INFO" else level
            message = f"{message}; {sets_note}"
    if caustics_note:
        message = f"{message}; {caustics_note}"
        if caustics_warn:
            level = "WARNING" if level == "INFO" else level
    kept_note, doubled = ownership.kept_note(scene, made)
    if kept_note:  # the user's lens lights, kept: a lens may now have two
        message = f"{message}; {kept_note}"
        figures["kept"] = [ob.name for ob in ownership.kept_objects(scene)]
        if doubled:
            level = "WARNING" if level == "INFO" else level
    figures["energy_model"] = options["energy_model"]
    figures.update(changed=True, seconds=time.perf_counter() - t0, timings=dict(work.timings))
    LAST_FIGURES = figures
    _store(settings, message, figures)
    return level, message, figures


class LENS_LIGHTS_OT_generate(bpy.types.Operator):
    bl_description = (
        "Precompute the caustic every light casts through each glass sphere: lens lights "
        "(spot lights that paint it; Cycles' default) or, with the Caustic layer model "
        "(EEVEE's default), emissive meshes on the surfaces it lands on"
    )
    bl_idname = "lens_lights.generate"
    bl_label = "Generate Lens Lights"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return context.scene is not None

    def execute(self, context):
        level, message, figures = generate(context)
        self.report({level}, message)
        if level == "ERROR" and not figures.get("changed", True):
            return {"CANCELLED"}
        return {"FINISHED"}


class LENS_LIGHTS_OT_clear(bpy.types.Operator):
    bl_description = (
        "Remove the lens lights and caustic layers this extension created (nothing "
        "else) and put back the Cycles caustics settings it changed"
    )
    bl_idname = "lens_lights.clear"
    bl_label = "Clear Lens Lights"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        if context.scene is None or not has_lens_lights(context.scene):
            cls.poll_message_set("Nothing to clear: this scene has no lens lights")
            return False
        return True

    def execute(self, context):
        context.scene.lens_lights.live_update = False  # else the lights come back at once
        counted = layers.made_counts(list(ownership.created_objects(context.scene)))
        cleanup.clear(context.scene)
        restored = cycles_caustics.restore(context.scene)
        settings = context.scene.lens_lights
        settings.last_created = settings.last_layers = settings.last_fallback = 0
        settings.last_report = f"Removed {made_text(*counted.values())}"
        if restored:
            settings.last_report += "; " + describe_restored(restored)
        kept_note, _ = ownership.kept_note(context.scene)
        if kept_note:  # the user's copies, renamed and moved lens lights stay
            settings.last_report += "; " + kept_note
        self.report({"INFO"}, settings.last_report)
        return {"FINISHED"}


_CLASSES = (LENS_LIGHTS_OT_generate, LENS_LIGHTS_OT_clear)


register, unregister = bpy.utils.register_classes_factory(_CLASSES)
