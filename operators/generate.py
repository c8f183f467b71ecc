"""Operators "Generate lens lights" (`lens_lights.generate`) and "Clear lens lights"
(`lens_lights.clear`), both undoable.

Generate works in two stages, so that a failure never leaves the scene half-done:

1. **Plan** (nothing in the file changes): read the scene as the renderer sees it
   (`scene_reader.rendered_depsgraph`: the render depsgraph of the context scene
   and view layer), run phase 1, pre-select the sources (`select_sources`:
   merging nearby ones if the scene's settings ask for it, then the
   ``PRESELECT_FACTOR × max_lights`` strongest by estimated flux, both vectorised
   in `addon.budget.apply_budget`, so that 100 000 sources never become 100 000
   Python objects), and plan the lights (`addon.light_models.plan_lights`: energy
   model, merged sources' energy scale, brightness cut-off, maximum number). The
   rays that keep a beam's spot clear of the geometry behind its lens are cast
   against the geometry read from the same render depsgraph (`occluders`).
2. **Build**: remove the lights a previous run created (only those) and create the
   planned ones (`light_builder`).

A failure in stage 1 is reported and changes nothing (the operator is cancelled);
one in stage 2 removes what was made and is reported. Generate never raises.

The report says how many lights were made, which pairs got none and why (the
first few by name, then counts per reason), how many sources were merged, and
which share of the lenses' estimated flux has no light. The figures are kept in
`scene.lens_lights.last_*` for the panel and, with the time of each step, in
`LAST_FIGURES`. A progress bar runs in the window (no-op without one).
"""
from __future__ import annotations

import time
import traceback
from dataclasses import dataclass, field
from types import SimpleNamespace

import bpy
import numpy as np

from ..addon.budget import BudgetReport, apply_budget, source_flux
from ..addon.light_models import (COLLIMATED_DISTANCE_FACTOR, PHYSICAL, THESIS, _downstream_reach,
                                  plan_lights, resolve_energy_model)
from ..addon.phase1 import Phase1Result, SkipTable, compute_phase1, reason_text
from . import light_builder
from .scene_reader import RENDER, read_depsgraph, rendered_depsgraph

#: How many skipped pairs / left-out objects a report names.
REPORT_FIRST = 3
#: A beam's spot stays this share of the free distance behind the lens.
FREE_MARGIN = 0.9
#: The pre-selection keeps this many times `max_lights` sources (the strongest by
#: estimated flux) for the final choice by `plan_lights`.
PRESELECT_FACTOR = 4
#: Sources merged when "Merge nearby lens lights" is on must also point within
#: this angle of each other.
MERGE_ANGLE_DEG = 5.0

#: The figures of the last run of `generate` (with "timings": seconds per step).
LAST_FIGURES: dict = {}


def free_distance_behind(occluders, source, scene_size):
    """How far behind its lens (from the back vertex, against the beam) a beam's
    spot can sit without geometry between it and the lens: rays cast from the
    front vertex's plane backwards, on the axis and on four points of the beam's
    rim, against `occluders` (`scene_reader.BlenderSceneRead.occluders`: the
    geometry the scene was read with). Objects there must not block a beam that
    really starts at the lens. Returns None when nothing is hit within the
    default distance."""
    u = np.asarray(source.axis, dtype=float)
    u = u / np.linalg.norm(u)
    c = np.asarray(source.lens_center, dtype=float)
    r = float(source.lens_radius)
    limit = COLLIMATED_DISTANCE_FACTOR * scene_size
    side = np.cross(u, (1.0, 0.0, 0.0) if abs(u[0]) < 0.9 else (0.0, 1.0, 0.0))
    side /= np.linalg.norm(side)
    other = np.cross(u, side)
    front = c - u * (r * 1.0001)
    origins = front + 0.9 * r * np.array([np.zeros(3), side, -side, other, -other])
    hits = occluders.first_hit(origins, -u, limit)
    if not np.isfinite(hits).any():
        return None
    return FREE_MARGIN * float(hits[np.isfinite(hits)].min()) + 2.0 * r


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


# --------------------------------------------------------------------------- selection

@dataclass
class Selection:
    """The pre-selected sources (`select_sources`)."""
    table: object                   # phase1.SourceTable of the kept (possibly merged) sources
    scale: np.ndarray               # energy scale per kept source (merged: group flux / lead's)
    sources: list                   # SecondarySource per kept row
    budget: BudgetReport
    flux_total: float               # estimated flux of all sources
    flux_kept: np.ndarray           # estimated flux per kept row (merged: the group's)
    preselect: int | None           # how many were allowed through (None: no limit)


def select_sources(result: Phase1Result, light_power, *, max_lights: int | None,
                   merge_distance: float | None = None,
                   merge_angle_deg: float = MERGE_ANGLE_DEG) -> Selection:
    """Merge nearby sources (if `merge_distance`) and keep the
    ``PRESELECT_FACTOR × max_lights`` strongest by estimated flux, vectorised;
    only those become `SecondarySource` objects."""
    table = result.table
    power = np.asarray(light_power, dtype=float).reshape(-1)
    flux_total = float(np.sum(source_flux(table, power))) if len(table) else 0.0
    pre = None if max_lights is None else PRESELECT_FACTOR * max(int(max_lights), 1)
    kept, scale, report = apply_budget(table, power, 0.0, pre, merge_distance or None,
                                       merge_angle_deg)
    flux_kept = source_flux(kept, power) * scale if len(kept) else np.zeros(0)
    return Selection(kept, np.asarray(scale, dtype=float), [kept.source(t) for t in range(len(kept))],
                     report, flux_total, flux_kept, pre)


# --------------------------------------------------------------------------- planning

@dataclass
class Work:
    read: object
    result: Phase1Result
    selection: Selection
    plan: object
    timings: dict = field(default_factory=dict)


def may_be_beam(source, scene_bounds, scene_size) -> bool:
    """Whether `make_blender_light` may draw `source` as a beam (a spot behind the
    lens) in the THESIS and PHYSICAL tiers, the only case where the free distance
    behind the lens matters to them: collimated sources; real images beyond
    everything in the scene (its rule, `_downstream_reach(image, axis) ≤ 0`);
    virtual images farther behind than 2R (the free distance is never shorter).
    (The FITTED tier may put any spot behind the lens: it always gets the rays.)"""
    if source.kind == "collimated":
        return True
    z = float(source.image_distance)
    if source.kind == "real":
        return _downstream_reach(source.position, source.axis, scene_bounds,
                                 scene_size - (z - source.lens_radius)) <= 0.0
    return abs(z) > 2.0 * float(source.lens_radius)


def plan_scene(depsgraph, scene, options: dict) -> Work:
    """Stage 1 on `depsgraph` (see the module's docstring); changes nothing.

    The lights are planned twice: first every pre-selected source without the rays
    that keep a beam's spot clear of the geometry behind its lens (they hardly
    change which lights are kept: a beam's brightness does not depend on how far
    behind the lens its spot sits, a Fitted spot pulled in keeps its irradiance in
    the middle of its receivers), then only the kept ones with the rays and the
    same cut-off (a light the rays make dimmer than it is dropped and reported), for
    the sources whose spot may sit behind the lens (THESIS and PHYSICAL:
    `may_be_beam`; the other tiers: all), against the geometry that was read
    (`occluders`: spheres analytically, other meshes by box then BVH)."""
    timings = {}
    t = time.perf_counter()
    read = read_depsgraph(depsgraph, scene)
    timings["read"] = time.perf_counter() - t
    t = time.perf_counter()
    result = compute_phase1(read.arrays)
    timings["phase1"] = time.perf_counter() - t
    t = time.perf_counter()
    selection = select_sources(result, read.arrays.light_brightness,
                               max_lights=options["max_lights"],
                               merge_distance=options["merge_distance"])
    timings["budget"] = time.perf_counter() - t
    t = time.perf_counter()
    common = dict(optics=read.lens_optics, light_names=read.light_sources,
                  lens_names=read.sphere_sources, min_brightness=options["min_brightness"],
                  max_lights=options["max_lights"], spot_blend=options["spot_blend"],
                  scene_size=read.scene_size, scene_bounds=read.bounds)
    first = plan_lights(SimpleNamespace(sources=selection.sources, skipped=[]), read.primaries,
                        options["energy_model"], energy_scale=selection.scale, **common)
    rows = {id(src): k for k, src in enumerate(selection.sources)}
    chosen = [p.source for p in first.lights]
    size = read.scene_size

    def far_limit(src):
        if options["energy_model"] in (THESIS, PHYSICAL) and not may_be_beam(src, read.bounds, size):
            return None
        return free_distance_behind(read.occluders, src, size)

    plan = plan_lights(SimpleNamespace(sources=chosen, skipped=[]), read.primaries,
                       options["energy_model"], far_limit=far_limit,
                       energy_scale=[selection.scale[rows[id(s)]] for s in chosen], **common)
    plan.skipped[:0] = first.skipped
    timings["plan"] = time.perf_counter() - t
    read.occluders.release()                # the depsgraph may go away after this
    return Work(read, result, selection, plan, timings)


def _options(settings) -> dict:
    merge = bool(getattr(settings, "use_merge", False))
    # The tier to build: AUTO → the most accurate for the scene's engine; Exact
    # profile outside Cycles → Fitted, with a warning in the report.
    model, model_warning = resolve_energy_model(settings.energy_model,
                                                settings.id_data.render.engine)
    return dict(energy_model=model, model_warning=model_warning,
                min_brightness=float(settings.min_brightness),
                max_lights=int(settings.max_lights), spot_blend=float(settings.spot_blend),
                merge_distance=float(settings.merge_distance) if merge else None)


# --------------------------------------------------------------------------- report

def _reason_kind(reason: str) -> str:
    """A plan's reason without its numbers ("dimmer than the cut-off (0.1 < 0.2)" →
    "dimmer than the cut-off")."""
    return reason.split(" (")[0]


def skip_report(work: Work):
    """(skipped count, first few "light × lens: reason", counts per reason)."""
    read, result, sel, plan = work.read, work.result, work.selection, work.plan
    s = result.skip_table
    cand = read.lens_candidates[s.lens] if len(s) else np.zeros(0, dtype=bool)
    first, counts = [], {}
    a = read.arrays
    for k in np.flatnonzero(cand)[:REPORT_FIRST]:
        i = int(s.lens[k])
        first.append(f"{read.light_sources[int(s.light[k])]} × {read.sphere_sources[i]}: "
                     + reason_text(int(s.code[k]), float(a.radius[i]), float(a.ior[i]),
                                   float(a.kt[i]), int(s.other[k])))
    if cand.any():
        sub = SkipTable(s.light[cand], s.lens[cand], s.code[cand], s.other[cand])
        counts.update(Phase1Result(result.table, sub, a).skip_counts())
    for light, lens, why in plan.skipped:
        if len(first) < REPORT_FIRST:
            first.append(f"{light} × {lens}: {why}")
        kind = _reason_kind(why)
        counts[kind] = counts.get(kind, 0) + 1
    if sel.budget.over_cap:
        counts[f"not among the {sel.preselect} strongest by flux"] = sel.budget.over_cap
    total = sum(counts.values())
    return total, first, counts


def _plural(n, word, many=None):
    return f"{n} {word if n == 1 else (many or word + 's')}"


def report_message(work: Work, made: int) -> tuple[str, str, dict]:
    read, result, sel, plan = work.read, work.result, work.selection, work.plan
    lights = len(read.light_sources)
    lenses = int(np.count_nonzero(read.lens_candidates))
    skipped, first, counts = skip_report(work)
    # Flux without a light: every source's estimated flux minus the built lights'.
    rows = {id(src): t for t, src in enumerate(sel.sources)}
    built = sum(float(sel.flux_kept[rows[id(p.source)]]) for p in plan.lights
                if id(p.source) in rows)
    left_share = (1.0 - built / sel.flux_total) if sel.flux_total > 0 else 0.0
    left_share = min(max(left_share, 0.0), 1.0) if made else (1.0 if sel.flux_total > 0 else 0.0)

    level = "INFO"
    parts = [f"Created {_plural(made, 'lens light')} ({_plural(lights, 'point light')}"
             f" × {_plural(lenses, 'lens', 'lenses')})"]
    if not lights:
        level = "WARNING"
        parts.append("no point light is enabled for rendering")
    elif lenses == 0:
        level = "WARNING"
        parts.append("no glass sphere found")
    if skipped:
        text = f"skipped {_plural(skipped, 'pair')}: " + "; ".join(first)
        if skipped > len(first):
            text += f"; and {skipped - len(first)} more"
        parts.append(text)
        if len(counts) > 1 or skipped > len(first):
            parts.append("by reason: " + ", ".join(
                f"{n} {kind}" for kind, n in sorted(counts.items(), key=lambda kv: -kv[1])))
    if sel.budget.merged:
        parts.append(f"merged {_plural(sel.budget.merged, 'source')} into nearby lens lights")
    if left_share > 0 and len(result.table):
        parts.append(f"{100.0 * left_share:.3g}% of the lenses' flux has no lens light")
    if read.left_out_lenses:
        shown = "; ".join(f"{n}: {why}" for n, why in read.left_out_lenses[:REPORT_FIRST])
        more = len(read.left_out_lenses) - REPORT_FIRST
        parts.append(f"left out {_plural(len(read.left_out_lenses), 'object')}: {shown}"
                     + (f"; and {more} more" if more > 0 else ""))
    if read.how != RENDER:
        parts.append(f"scene read as the {read.how}")
    figures = dict(created=made, sources=len(result.table), skipped=skipped,
                   skipped_by_reason=counts, merged=sel.budget.merged,
                   primaries=lights, lenses=lenses, left_out=len(read.left_out_lenses),
                   flux_left_out=left_share, how=read.how)
    return level, "; ".join(parts), figures


def _store(settings, message, figures):
    settings.last_run = True
    settings.last_created = figures.get("created", 0)
    settings.last_sources = figures.get("sources", 0)
    settings.last_skipped = figures.get("skipped", 0)
    settings.last_primaries = figures.get("primaries", 0)
    settings.last_lenses = figures.get("lenses", 0)
    settings.last_left_out = figures.get("left_out", 0)
    settings.last_seconds = figures.get("seconds", 0.0)
    settings.last_report = message


def _error_text(stage, exc):
    where = traceback.extract_tb(exc.__traceback__)[-1] if exc.__traceback__ else None
    at = f" ({where.filename.rsplit('/', 1)[-1]}:{where.lineno})" if where else ""
    return f"Lens Lights could not {stage}: {type(exc).__name__}: {exc}{at}"


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
            options = _options(settings)
            t = time.perf_counter()
            work, how = rendered_depsgraph(context, lambda dg: plan_scene(dg, scene, options))
            work.read.how = how
            work.timings["probe_total"] = time.perf_counter() - t
        except Exception as exc:            # noqa: BLE001  (reported, never raised)
            message = _error_text("read the scene", exc)
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
        total = max(len(plan.lights), 1)
        try:
            light_builder.clear(scene)
            made = light_builder.build(scene, plan, work.read.sphere_objects,
                                       progress=lambda k: progress(60 + 40 * k / total))
        except Exception as exc:            # noqa: BLE001
            traceback.print_exc()
            try:
                light_builder.clear(scene)
            except Exception:               # noqa: BLE001
                traceback.print_exc()
            message = _error_text("create the lens lights", exc) + " (the lens lights were removed)"
            figures = dict(changed=True, created=0, seconds=time.perf_counter() - t0)
            LAST_FIGURES = figures
            _store(settings, message, figures)
            return "ERROR", message, figures
        work.timings["build"] = time.perf_counter() - t
        progress(100)

    try:
        level, message, figures = report_message(work, len(made))
    except Exception as exc:                # noqa: BLE001  (the lights are made: say so)
        traceback.print_exc()
        level, figures = "WARNING", dict(created=len(made))
        message = f"Created {len(made)} lens lights; " + _error_text("write the report", exc)
    if options["model_warning"]:
        level = "WARNING" if level == "INFO" else level
        message = f"{message}; {options['model_warning']}"
    figures["energy_model"] = options["energy_model"]
    figures.update(changed=True, seconds=time.perf_counter() - t0, timings=dict(work.timings))
    LAST_FIGURES = figures
    _store(settings, message, figures)
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
        level, message, figures = generate(context)
        self.report({level}, message)
        if level == "ERROR" and not figures.get("changed", True):
            return {"CANCELLED"}
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


register, unregister = bpy.utils.register_classes_factory(_CLASSES)
