"""From phase 1's sources to the lens lights to build (pure; the operator,
`operators/generate.py`, reads the scene and builds what this plans).

* `select_sources`: merge nearby sources (if asked) and keep the
  ``PRESELECT_FACTOR × max_lights`` strongest by estimated flux, vectorised in
  `budget.apply_budget`, so that 100 000 sources never become 100 000 Python
  objects;
* `plan_lights`: the tier's light for each source, the merged sources' energy
  scale, the brightness cut-off and the maximum number, brightest first;
* `may_be_beam` / `free_distance_behind`: whether a spot may sit behind its lens,
  and how far it can without geometry in the way; `receiver_distance`: where the
  surface the caustic falls on lies (no lens light at or behind it);
* `plan_result`: all of it for phase 1's result on a scene read.

Every pair left without a light is a `skip_reasons.SkippedPair` (code + details).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from types import SimpleNamespace

import numpy as np

from .budget import BudgetReport, apply_budget, source_flux
from .phase1 import Phase1Result
from .skip_reasons import Reason, SkippedPair
from .tiers import (
    COLLIMATED_DISTANCE_FACTOR,
    DEFAULT_ENERGY_MODEL,
    DEFAULT_SPOT_BLEND,
    PHYSICAL,
    THESIS,
    BlenderLight,
    make_blender_light,
)
from .tiers.near_field import ReceiverDistance, rim_plane_normal
from .tiers.paraxial import is_beyond_scene

#: A beam's spot stays this share of the free distance behind the lens.
FREE_MARGIN = 0.9
#: The receiver's rays start this many lens radii from the axis (just outside it).
RIM_OFFSET = 1.02
#: The pre-selection keeps this many times `max_lights` sources (the strongest by
#: estimated flux) for the final choice by `plan_lights`.
PRESELECT_FACTOR = 4
#: Sources merged when "Merge nearby lens lights" is on must also point within
#: this angle of each other.
MERGE_ANGLE_DEG = 5.0


# --------------------------------------------------------------------------- selection


@dataclass
class Selection:
    """The pre-selected sources (`select_sources`)."""

    table: object  # phase1.SourceTable of the kept (possibly merged) sources
    scale: np.ndarray  # energy scale per kept source (merged: group flux / lead's)
    sources: list  # SecondarySource per kept row
    budget: BudgetReport
    flux_total: float  # estimated flux of all sources
    flux_kept: np.ndarray  # estimated flux per kept row (merged: the group's)
    preselect: int | None  # how many were allowed through (None: no limit)


def select_sources(
    result: Phase1Result,
    light_power,
    *,
    max_lights: int | None,
    merge_distance: float | None = None,
    merge_angle_deg: float = MERGE_ANGLE_DEG,
    preselect_factor: int = PRESELECT_FACTOR,
) -> Selection:
    """Merge nearby sources (if `merge_distance`) and keep the
    ``preselect_factor × max_lights`` strongest by estimated flux, vectorised;
    only those become `SecondarySource` objects."""
    table = result.table
    power = np.asarray(light_power, dtype=float).reshape(-1)
    flux_total = float(np.sum(source_flux(table, power))) if len(table) else 0.0
    pre = None if max_lights is None else preselect_factor * max(int(max_lights), 1)
    kept, scale, report = apply_budget(
        table, power, 0.0, pre, merge_distance or None, merge_angle_deg
    )
    flux_kept = source_flux(kept, power) * scale if len(kept) else np.zeros(0)
    return Selection(
        kept,
        np.asarray(scale, dtype=float),
        [kept.source(t) for t in range(len(kept))],
        report,
        flux_total,
        flux_kept,
        pre,
    )


# --------------------------------------------------------------------------- beams


def may_be_beam(source, scene_bounds, scene_size) -> bool:
    """Whether `make_blender_light` may draw `source` as a beam (a spot behind the
    lens) in the THESIS and PHYSICAL tiers, the only case where the free distance
    behind the lens matters to them: collimated sources; real images beyond
    everything in the scene (`tiers.paraxial.is_beyond_scene`); virtual images
    farther behind than 2R (the free distance is never shorter). (The FITTED tier
    may put any spot behind the lens: it always gets the rays.)"""
    if source.kind == "collimated":
        return True
    if source.kind == "real":
        return is_beyond_scene(source, scene_bounds, scene_size)
    return abs(float(source.image_distance)) > 2.0 * float(source.lens_radius)


def free_distance_behind(occluders, source, scene_size):
    """How far behind its lens (from the back vertex, against the beam) a beam's
    spot can sit without geometry between it and the lens: rays cast from the
    front vertex's plane backwards, on the axis and on four points of the beam's
    rim, against `occluders` (`first_hit(origins, direction, limit)`: the
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


def receiver_distance(occluders, source, scene_size):
    """How far from the lens centre along the beam's axis the first surface behind
    the lens lies (None: nothing within the scene's reach): the surface the
    caustic falls on, before which every lens light must sit
    (`tiers.near_field`). Rays along the axis from four points just outside the
    lens's rim (a table the lens rests on, a wall beside it) and from just past
    the back vertex; a pair of rim rays on opposite sides gives the plane's
    distance on the axis by its mean (exact for a plane, tilted or not). A
    `near_field.ReceiverDistance`: a float, with the plane's `normal` where the
    four rim rays found one plane at that distance (else None)."""
    u = np.asarray(source.axis, dtype=float)
    u = u / np.linalg.norm(u)
    c = np.asarray(source.lens_center, dtype=float)
    r = float(source.lens_radius)
    limit = COLLIMATED_DISTANCE_FACTOR * scene_size
    side = np.cross(u, (1.0, 0.0, 0.0) if abs(u[0]) < 0.9 else (0.0, 1.0, 0.0))
    side /= np.linalg.norm(side)
    other = np.cross(u, side)
    rim = RIM_OFFSET * r
    origins = np.array(
        [
            c + rim * side,
            c - rim * side,
            c + rim * other,
            c - rim * other,
            c + u * (r * (1.0 + 1e-6)),
        ]
    )
    hits = np.asarray(occluders.first_hit(origins, u, limit), dtype=float)
    found = []
    for a, b in ((0, 1), (2, 3)):
        ha, hb = hits[a], hits[b]
        if np.isfinite(ha) and np.isfinite(hb):
            found.append(0.5 * (ha + hb))
        elif np.isfinite(ha) or np.isfinite(hb):
            found.append(min(ha, hb))
    if np.isfinite(hits[4]):
        found.append(r * (1.0 + 1e-6) + float(hits[4]))
    if not found:
        return None
    # with the plane's normal where the four rim rays found one (a tilted table)
    z = max(min(found), r)
    return ReceiverDistance(z, rim_plane_normal(origins, u, hits, r, distance=z))


# --------------------------------------------------------------------------- lights


@dataclass
class PlannedLight:
    source: object  # phase1.SecondarySource
    light: BlenderLight
    light_name: str
    lens_name: str


@dataclass
class Plan:
    lights: list[PlannedLight]
    #: every pair without a light (light's name, lens's name, reason text; with
    #: `.code` and `.details`), lenses only (a pair whose sphere is no lens, e.g.
    #: opaque, is not listed).
    skipped: list[SkippedPair]
    not_lenses: int = 0  # pairs whose sphere is no lens (not reported)

    def skipped_summary(self, first: int = 3) -> str:
        """'A × B: reason; …' for the first few skipped pairs (and how many more)."""
        parts = [f"{a} × {b}: {why}" for a, b, why in self.skipped[:first]]
        more = len(self.skipped) - first
        if more > 0:
            parts.append(f"and {more} more")
        return "; ".join(parts)


def plan_lights(
    result,
    primaries,
    model: str = DEFAULT_ENERGY_MODEL,
    *,
    optics=None,
    light_names=None,
    lens_names=None,
    lens_candidates=None,
    min_brightness: float = 0.0,
    max_lights: int | None = None,
    spot_blend: float = DEFAULT_SPOT_BLEND,
    scene_size: float = 1.0,
    scene_bounds=None,
    far_limit=None,
    energy_scale=None,
    receiver_limit=None,
) -> Plan:
    """The Blender lights for a phase-1 result, brightest first.

    `primaries[j]`: `PrimaryLight` of light j; `optics[i]`: `LensOptics` of sphere i
    (default clear glass); names for the report (default "light j", "sphere i");
    `lens_candidates[i]`: False for spheres that are no lens (their skipped pairs are
    counted in `not_lenses`, not listed). A light whose relative brightness (its
    reference irradiance over the primary's irradiance at the lens) is below
    `min_brightness` is skipped, and so is every light beyond the `max_lights`
    brightest (by reference irradiance). `scene_bounds`: see `make_blender_light`;
    `far_limit(source)`: how far behind the lens a beam's spot may go (None: as far
    as the default), e.g. up to the first geometry behind the lens.
    `energy_scale[t]` (parallel to `result.sources`): a factor on the energy of
    source t's light, applied before the cut-off and the cap (a merged source
    carries the flux of its group: `addon.budget.apply_budget`).
    `receiver_limit(source)`: how far from the lens centre the surface behind the
    lens lies (None: unknown; `receiver_distance`): no light sits at or behind it.
    """
    light_name = (lambda j: light_names[j]) if light_names else (lambda j: f"light {j}")
    lens_name = (lambda i: lens_names[i]) if lens_names else (lambda i: f"sphere {i}")
    plan = Plan(lights=[], skipped=[])
    for k in result.skipped:
        if lens_candidates is not None and not lens_candidates[k.lens]:
            plan.not_lenses += 1
        else:
            plan.skipped.append(
                SkippedPair(light_name(k.light), lens_name(k.lens), k.code, text=k.reason)
            )
    candidates = []
    for t, src in enumerate(result.sources):
        limit = far_limit(src) if far_limit is not None else None
        near = receiver_limit(src) if receiver_limit is not None else None
        bl = make_blender_light(
            src,
            primaries[src.light],
            model,
            optics=optics[src.lens] if optics else None,
            spot_blend=spot_blend,
            scene_size=scene_size,
            scene_bounds=scene_bounds,
            collimated_distance=limit,
            receiver_distance=near,
        )
        f = 1.0 if energy_scale is None else float(energy_scale[t])
        if f != 1.0:
            bl.energy_w *= f
            bl.reference_irradiance *= f
            bl.relative_brightness *= f
            bl.note = "; ".join(x for x in (bl.note, f"merged: energy × {f:.4g}") if x)
        names = (light_name(src.light), lens_name(src.lens))
        if not (bl.energy_w > 0 and math.isfinite(bl.energy_w)):
            plan.skipped.append(SkippedPair(*names, Reason.NO_LIGHT_THROUGH))
        elif bl.relative_brightness < min_brightness:
            plan.skipped.append(
                SkippedPair(
                    *names,
                    Reason.DIMMER_THAN_CUTOFF,
                    dict(relative=bl.relative_brightness, cutoff=min_brightness),
                )
            )
        else:
            candidates.append(PlannedLight(src, bl, *names))
    candidates.sort(key=lambda p: -p.light.reference_irradiance)
    limit = len(candidates) if max_lights is None else max(int(max_lights), 0)
    plan.lights = candidates[:limit]
    for p in candidates[limit:]:
        plan.skipped.append(
            SkippedPair(p.light_name, p.lens_name, Reason.BEYOND_MAXIMUM, dict(limit=limit))
        )
    return plan


# --------------------------------------------------------------------------- a scene


@dataclass
class Work:
    read: object  # scene_reader.BlenderSceneRead
    result: Phase1Result
    selection: Selection
    plan: Plan
    timings: dict = field(default_factory=dict)


def plan_result(
    read,
    result: Phase1Result,
    options: dict,
    timings: dict | None = None,
    *,
    preselect_factor: int = PRESELECT_FACTOR,
) -> Work:
    """The pre-selection and the plan for phase 1's `result` on a scene read
    (`read.arrays`, `primaries`, `lens_optics`, names, `scene_size`, `bounds`,
    `occluders`: `scene_reader.read_depsgraph`); `options`: energy_model,
    min_brightness, max_lights, spot_blend, merge_distance.

    The lights are planned twice: first every pre-selected source without the rays
    that keep a beam's spot clear of the geometry behind its lens (they hardly
    change which lights are kept: a beam's brightness does not depend on how far
    behind the lens its spot sits, a Fitted spot pulled in keeps its irradiance in
    the middle of its receivers), then only the kept ones with the rays and the
    same cut-off (a light the rays make dimmer than it is dropped and reported), for
    the sources whose spot may sit behind the lens (THESIS and PHYSICAL:
    `may_be_beam`; the other tiers: all), against the geometry that was read
    (`occluders`: spheres analytically, other meshes by box then BVH), and for
    every kept source the receiver behind its lens (`receiver_distance`): no lens
    light sits at or behind the surface its caustic falls on."""
    timings = {} if timings is None else timings
    t = time.perf_counter()
    selection = select_sources(
        result,
        read.arrays.light_brightness,
        max_lights=options["max_lights"],
        merge_distance=options["merge_distance"],
        preselect_factor=preselect_factor,
    )
    timings["budget"] = time.perf_counter() - t
    t = time.perf_counter()
    model = options["energy_model"]
    common = dict(
        optics=read.lens_optics,
        light_names=read.light_sources,
        lens_names=read.sphere_sources,
        min_brightness=options["min_brightness"],
        max_lights=options["max_lights"],
        spot_blend=options["spot_blend"],
        scene_size=read.scene_size,
        scene_bounds=read.bounds,
    )
    first = plan_lights(
        SimpleNamespace(sources=selection.sources, skipped=[]),
        read.primaries,
        model,
        energy_scale=selection.scale,
        **common,
    )
    rows = {id(src): k for k, src in enumerate(selection.sources)}
    chosen = [p.source for p in first.lights]
    size = read.scene_size

    def far_limit(src):
        if model in (THESIS, PHYSICAL) and not may_be_beam(src, read.bounds, size):
            return None
        return free_distance_behind(read.occluders, src, size)

    def receiver_limit(src):
        return receiver_distance(read.occluders, src, size)

    plan = plan_lights(
        SimpleNamespace(sources=chosen, skipped=[]),
        read.primaries,
        model,
        far_limit=far_limit,
        receiver_limit=receiver_limit,
        energy_scale=[selection.scale[rows[id(s)]] for s in chosen],
        **common,
    )
    plan.skipped[:0] = first.skipped
    timings["plan"] = time.perf_counter() - t
    read.occluders.release()  # the depsgraph may go away after this
    return Work(read, result, selection, plan, timings)
