"""From phase 1's sources to the lens lights to build (pure; the operator,
`blender/commands/generate.py`, reads the scene and builds what this plans).

* `select_sources`: merge nearby sources (if asked) and keep the
  ``PRESELECT_FACTOR × max_lights`` strongest by estimated flux, vectorised in
  `budget.apply_budget`, so that 100 000 sources never become 100 000 Python
  objects;
* `plan_lights`: the tier's light for each source, the merged sources' energy
  scale, the brightness cut-off and the maximum number, brightest first;
* `may_be_beam` / `free_distance_behind`: whether a spot may sit behind its lens,
  and how far it can without geometry in the way; `receiver_distance`: where the
  surface the caustic falls on lies (no lens light at or behind it);
* `plan_result`: all of it for phase 1's result on a scene read, on columns (the
  tiers' table makers; every kept source's rays in one batched cast:
  `free_distances`, `receiver_rays`); tests/helpers/planning_reference.py does the same
  source by source (`plan_lights`, `free_distance_behind`, `receiver_distance`), the
  reference the columns path is tested against.

Every pair left without a light is a `skip_reasons.SkippedPair` (code + details).
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from types import SimpleNamespace

import numpy as np

from ..lens.glass import LensOptics
from ..phase1.point_lights import Phase1Result, take
from ..phase1.skip_reasons import Reason, SkippedPair
from ..scene.ray_hits import sphere_hits_bundles
from ..shared.vectors import cross
from ..tiers import (
    AUTO,
    CAUSTIC_LAYER,
    COLLIMATED_DISTANCE_FACTOR,
    DEFAULT_ENERGY_MODEL,
    DEFAULT_SPOT_BLEND,
    EXACT_PROFILE,
    FITTED,
    PHYSICAL,
    THESIS,
    TIERS,
    BlenderLight,
    LightTable,
    Primaries,
    make_blender_light,
    make_light_table,
    resolve_energy_model,
)
from ..tiers.base import safe_scene_size
from ..tiers.near_field import (
    SIDE_REACH,
    ReceiverDistance,
    rim_plane_normal,
    side_plane_rays,
    side_planes,
)
from ..tiers.paraxial import is_beyond_scene
from .budget import BudgetReport, apply_budget, source_flux
from .ray_memo import RayMemo

#: A lens another surface cuts into by more than this share of its radius is sunk
#: into it (`sunk_lenses`): its light would focus inside that surface.
SUNK_MARGIN = 0.02
#: A beam's spot stays this share of the free distance behind the lens.
FREE_MARGIN = 0.9
#: The receiver's rays start this many lens radii from the axis (just outside it).
RIM_OFFSET = 1.02
#: The pre-selection keeps this many times `max_lights` sources (the strongest by
#: estimated flux) for the final choice by `plan_lights`.
PRESELECT_FACTOR = 4
#: Tiers whose table maker takes each source's free distance and receiver (the
#: kept lights made as columns); the others' kept lights are made source by source.
RECEIVER_TABLES = (FITTED, CAUSTIC_LAYER)
#: Sources merged when "Merge nearby lens lights" is on must also point within
#: this angle of each other.
MERGE_ANGLE_DEG = 5.0


# --------------------------------------------------------------------------- selection


class LazySources(Sequence):
    """``table.source(t)`` for every row, each made on first use and then kept (the
    same object every time: the report matches planned lights to rows by identity)."""

    def __init__(self, table):
        self.table, self._made = table, {}

    def __len__(self) -> int:
        return len(self.table)

    def __getitem__(self, t):
        if isinstance(t, slice):
            return [self[k] for k in range(*t.indices(len(self)))]
        t = int(t)
        if t < 0:
            t += len(self)
        if not 0 <= t < len(self):
            raise IndexError(t)
        src = self._made.get(t)
        if src is None:
            src = self._made[t] = self.table.source(t)
        return src


@dataclass
class Selection:
    """The pre-selected sources (`select_sources`)."""

    table: object  # phase1.SourceTable of the kept (possibly merged) sources
    scale: np.ndarray  # energy scale per kept source (merged: group flux / lead's)
    sources: Sequence  # SecondarySource per kept row (`LazySources`: made on first use)
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
        LazySources(kept),
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
    side = cross(u, (1.0, 0.0, 0.0) if abs(u[0]) < 0.9 else (0.0, 1.0, 0.0))
    side /= np.linalg.norm(side)
    other = cross(u, side)
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
    side = cross(u, (1.0, 0.0, 0.0) if abs(u[0]) < 0.9 else (0.0, 1.0, 0.0))
    side /= np.linalg.norm(side)
    other = cross(u, side)
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
    # with the plane's normal where the four rim rays found one (a tilted table),
    # and the other planes the beam meets near the lens (a wall beside it)
    z = max(min(found), r)
    normal = rim_plane_normal(origins, u, hits, r, distance=z)
    return ReceiverDistance(z, normal, other_planes(occluders, u, c, r, z, normal))


def other_planes(occluders, axis, center, radius, z, normal) -> list:
    """The planes besides the receiver on the axis (`z` from the centre, its
    `normal` or None) that the beam meets within ``near_field.SIDE_REACH`` R of the
    lens (`near_field.side_planes`: one batched cast of the side bundles)."""
    origins, dirs = side_plane_rays(axis, center, radius)
    hits = cast_bundles(occluders, origins, dirs, SIDE_REACH * radius)
    u = np.asarray(axis, dtype=float)
    known = [] if normal is None else [(normal, np.asarray(center, float) + z * u)]
    return side_planes(origins, dirs, hits, radius, known)


def all_other_planes(occluders, axis, center, radius, z, normals) -> dict:
    """`other_planes` of the sources `normals` holds (row → the receiver's normal or
    None; their receivers `z[row]` from the centre), every bundle in one cast. With
    occluders seen through a `RayMemo` (``ray_memo``), a row whose inputs were
    planned before on this geometry is not cast or derived again."""
    memo = getattr(occluders, "ray_memo", None)
    out, keys = {}, {}
    if memo is not None:
        for k in normals:
            nrm = np.full(3, np.nan) if normals[k] is None else normals[k]
            keys[k] = memo.key(axis[k], center[k], radius[k], z[k], nrm)
            found = memo.derived("planes", keys[k])
            if found is not None:
                out[k] = found
    rows = [k for k in normals if k not in out]
    if not rows:
        return out
    rays = [side_plane_rays(axis[k], center[k], float(radius[k])) for k in rows]
    origins = np.concatenate([o for o, _ in rays])
    dirs = np.concatenate([d for _, d in rays])
    reach = SIDE_REACH * np.asarray(radius, dtype=float)[rows]
    hits = cast_bundles(occluders, origins, dirs, float(reach.max()))
    start = 0
    for k, (o, d) in zip(rows, rays, strict=True):
        part = slice(start, start + len(o))
        start += len(o)
        u = np.asarray(axis[k], dtype=float)
        c = np.asarray(center[k], dtype=float)
        known = [] if normals[k] is None else [(normals[k], c + float(z[k]) * u)]
        out[k] = side_planes(o, d, hits[part], float(radius[k]), known)
        if memo is not None:  # (side_planes keeps a hit within the pair's own reach)
            memo.remember("planes", keys[k], out[k])
    return out


def _frames(axis, center, radius):
    """Unit axes, the two unit vectors square to them (as `free_distance_behind`),
    centres and radii, per row."""
    u = np.asarray(axis, dtype=float).reshape(-1, 3)
    u = u / np.sqrt(np.sum(u * u, axis=1))[:, None]
    ref = np.where((np.abs(u[:, 0]) < 0.9)[:, None], (1.0, 0.0, 0.0), (0.0, 1.0, 0.0))
    side = cross(u, ref)
    side /= np.sqrt(np.sum(side * side, axis=1))[:, None]
    other = cross(u, side)
    c = np.asarray(center, dtype=float).reshape(-1, 3)
    return u, side, other, c, np.asarray(radius, dtype=float).reshape(-1)


def cast_bundles(occluders, origins, directions, limit) -> np.ndarray:
    """First hits of bundles of rays (`origins` B × k × 3, one direction per bundle):
    `occluders.first_hits` in one call where it has it, else `first_hit` per bundle."""
    if len(origins) == 0:
        return np.zeros((0, origins.shape[1]))
    if hasattr(occluders, "first_hits"):
        return np.asarray(occluders.first_hits(origins, directions, limit), dtype=float)
    return np.array(
        [occluders.first_hit(o, d, limit) for o, d in zip(origins, directions, strict=True)],
        dtype=float,
    )


#: Probe directions of `sunk_lenses`: the axes and the cube's diagonals, both ways.
_PROBES = np.array(
    [(1, 0, 0), (0, 1, 0), (0, 0, 1)] + [(1, 1, 1), (1, 1, -1), (1, -1, 1), (-1, 1, 1)],
    dtype=float,
)
SUNK_PROBES = (
    np.concatenate([_PROBES, -_PROBES])
    / np.linalg.norm(np.concatenate([_PROBES, -_PROBES]), axis=1)[:, None]
)


def sunk_lenses(occluders, center, radius) -> np.ndarray:
    """Which lenses (rows) another surface cuts into by more than ``SUNK_MARGIN`` of
    their radius (a marble sunk into the table; one resting on it only touches it):
    along each of `SUNK_PROBES` a ray from half a radius behind the centre through
    it, a hit within the lens' own ball short of its far surface (the lens itself
    is hit there, at 1.5 R) means a surface inside the glass (another sphere's does
    not count: marbles in a pile may overlap a little). A surface crossing the
    ball nearer its centre than about 0.8 (1 − margin) R is always met (the nearest
    probe is within 35° of its normal)."""
    c = np.asarray(center, dtype=float).reshape(-1, 3)
    r = np.asarray(radius, dtype=float).reshape(-1)
    if not len(r):
        return np.zeros(0, dtype=bool)
    origins = c[None, :, :] - 0.5 * r[None, :, None] * SUNK_PROBES[:, None, :]
    reach = (1.5 - SUNK_MARGIN) * r
    hits = cast_bundles(occluders, origins, SUNK_PROBES, float(reach.max()))
    # Another sphere's surface does not count (balls in a pile may overlap a little,
    # each still a lens): a hit counts only nearer than the spheres' own.
    centers = np.asarray(getattr(occluders, "centers", np.zeros((0, 3))), dtype=float)
    if len(centers):
        radii = np.asarray(occluders.radii, dtype=float)
        spheres = sphere_hits_bundles(centers, radii, origins, SUNK_PROBES)
        with np.errstate(invalid="ignore"):
            nearer = spheres - 1e-9 * (spheres + r[None, :])
        hits = np.where(hits < np.where(np.isfinite(spheres), nearer, np.inf), hits, np.inf)
    return np.any(hits <= reach[None, :], axis=0)


def free_distances(occluders, axis, center, radius, scene_size) -> np.ndarray:
    """`free_distance_behind` of many sources at once (columns; NaN: None), all
    their rays in one batched cast."""
    u, side, other, c, r = _frames(axis, center, radius)
    front = c - u * (r * 1.0001)[:, None]
    offsets = np.stack([np.zeros_like(side), side, -side, other, -other], axis=1)
    origins = front[:, None] + (0.9 * r)[:, None, None] * offsets
    hits = cast_bundles(occluders, origins, -u, COLLIMATED_DISTANCE_FACTOR * scene_size)
    near = np.min(hits, axis=1) if hits.size else np.zeros(0)
    return np.where(np.isfinite(near), FREE_MARGIN * near + 2.0 * r, np.nan)


def receiver_rays(occluders, axis, center, radius, scene_size):
    """The rays of `receiver_distance` for many sources in one batched cast:
    (origins N × 5 × 3, unit axes N × 3, hits N × 5, distances N: NaN where none)."""
    u, side, other, c, r = _frames(axis, center, radius)
    rim = (RIM_OFFSET * r)[:, None]
    origins = np.stack(
        [
            c + rim * side,
            c - rim * side,
            c + rim * other,
            c - rim * other,
            c + u * (r * (1.0 + 1e-6))[:, None],
        ],
        axis=1,
    )
    hits = cast_bundles(occluders, origins, u, COLLIMATED_DISTANCE_FACTOR * scene_size)
    found = np.full((len(r), 3), np.inf)
    for col, (a, b) in enumerate(((0, 1), (2, 3))):
        ha, hb = hits[:, a], hits[:, b]
        both = np.isfinite(ha) & np.isfinite(hb)
        found[:, col] = np.where(both, 0.5 * (ha + hb), np.minimum(ha, hb))
    found[:, 2] = r * (1.0 + 1e-6) + hits[:, 4]
    best = found.min(axis=1) if len(r) else np.zeros(0)
    return origins, u, hits, np.where(np.isfinite(best), np.maximum(best, r), np.nan)


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
    carries the flux of its group: `core.plan.budget.apply_budget`).
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


@dataclass(slots=True)
class Work:
    """One scene's plan: the read, phase 1's result, the selection, the plan, seconds
    per step; and the Caustic layer's part, set by the Blender side's layer stage
    (`blender/commands/layer_stage.py`; None when the tier is not the layer's): the
    receivers read, the layer's bake, its sources (`caustic_layer.plan.sheet_sources`)
    and the report's figures. Slots: a field not declared here cannot be attached."""

    read: object  # core.scene.assembly.BlenderSceneRead
    result: Phase1Result
    selection: Selection
    plan: Plan
    timings: dict = field(default_factory=dict)
    receivers: object = None  # blender.read.receivers.Receivers
    layer_bake: object = None  # caustic_layer.pipeline.SheetBake
    layer_sources: list | None = None
    layer_figures: object = None  # caustic_layer.plan.LayerFigures
    layer_floors: list | None = None  # per layer source, its ray budget's floor
    water: object = None  # blender.commands.water_stage.WaterStage (issue 26, Generate)


def _primary_columns(read, table) -> Primaries:
    """`read.primaries` and `read.lens_optics` per source of `table`, as columns
    (each light and lens looked up once)."""
    lights, light_row = np.unique(np.asarray(table.light, dtype=np.int64), return_inverse=True)
    lenses, lens_row = np.unique(np.asarray(table.lens, dtype=np.int64), return_inverse=True)
    prims = [read.primaries[j] for j in lights.tolist()]
    optics = read.lens_optics
    opts = [(optics[i] if optics else None) or LensOptics() for i in lenses.tolist()]

    def col(values, rows, width=None):
        a = np.asarray(values, dtype=float).reshape(-1, *(() if width is None else (width,)))
        return a[rows]

    return Primaries(
        power_w=col([q.power_w for q in prims], light_row),
        radius=col([q.radius for q in prims], light_row),
        color=col([q.color for q in prims], light_row, 3),
        transmission_weight=col([o.transmission_weight for o in opts], lens_row),
        tint=col([o.tint for o in opts], lens_row, 3),
        absorption=col([o.absorption for o in opts], lens_row, 3),
    )


def _scaled(lights: LightTable, f: np.ndarray) -> LightTable:
    """`lights` with the merged sources' energy scale `f` (as `plan_lights`)."""
    return dataclasses.replace(
        lights,
        energy_w=lights.energy_w * f,
        reference_irradiance=lights.reference_irradiance * f,
        relative_brightness=lights.relative_brightness * f,
    )


def _rank(lights: LightTable, names, min_brightness, max_lights, skipped):
    """`plan_lights`' choice on columns: rows with light, at or above the cut-off,
    brightest first (stable), at most `max_lights`; the others appended to
    `skipped` in `plan_lights`' order. Returns the kept rows, in order."""
    e, rel = lights.energy_w, lights.relative_brightness
    ok = (e > 0) & np.isfinite(e)
    dim = ok & (rel < min_brightness)
    for t in np.flatnonzero(~ok | dim).tolist():
        if not ok[t]:
            skipped.append(SkippedPair(*names(t), Reason.NO_LIGHT_THROUGH))
        else:
            details = dict(relative=float(rel[t]), cutoff=min_brightness)
            skipped.append(SkippedPair(*names(t), Reason.DIMMER_THAN_CUTOFF, details))
    cand = np.flatnonzero(ok & ~dim)
    cand = cand[np.argsort(-lights.reference_irradiance[cand], kind="stable")]
    limit = cand.size if max_lights is None else max(int(max_lights), 0)
    for t in cand[limit:].tolist():
        skipped.append(SkippedPair(*names(t), Reason.BEYOND_MAXIMUM, dict(limit=limit)))
    return cand[:limit]


def plan_result(
    read,
    result: Phase1Result,
    options: dict,
    timings: dict | None = None,
    *,
    preselect_factor: int = PRESELECT_FACTOR,
    rays: RayMemo | None = None,
    near_fits: bool = True,
    release: bool = True,
) -> Work:
    """The pre-selection and the plan for phase 1's `result` on a scene read
    (`read.arrays`, `primaries`, `lens_optics`, names, `scene_size`, `bounds`,
    `occluders`: `read.scene.read_depsgraph`); `options`: energy_model,
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
    light sits at or behind the surface its caustic falls on.

    On columns: the first pass is the tier's table maker (`make_light_table`) over
    the pre-selection, the rays of every kept source go in two batched casts
    (`free_distances`, `receiver_rays`), and the kept lights are the table maker's
    where it takes receivers (`RECEIVER_TABLES`), else the per-source maker's; the
    same lights as tests/helpers/planning_reference.py's source by source
    (tests/core/plan/test_planning_speed_equivalence.py).

    `rays` (live update): the bundles cast before on the same geometry are not cast
    again (`ray_memo.RayMemo`: the pairs whose lens and axis did not change).
    ``near_fits=False`` (live update's coarse Caustic layer): the table makers that
    take receivers skip their near-field fits (`fitted.make_table`). ``release=False``:
    the read's occluders stay for a second plan of the same read (the caller releases
    them)."""
    timings = {} if timings is None else timings
    occ = read.occluders
    if rays is not None:
        rays.start(occ)
        occ = rays.view(occ)
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
    tier = TIERS.get(resolve_energy_model(model)[0] if model == AUTO else model)
    if tier is None:
        raise ValueError(f"unknown energy model {model!r}; known: {', '.join([AUTO, *TIERS])}")
    size = safe_scene_size(read.scene_size)
    table, scale = selection.table, selection.scale
    min_b, max_lights = options["min_brightness"], options["max_lights"]
    light_names, lens_names = read.light_sources, read.sphere_sources

    def names_of(rows):
        def names(t):
            r = int(rows[t])
            j, i = int(table.light[r]), int(table.lens[r])
            return (
                light_names[j] if light_names else f"light {j}",
                lens_names[i] if lens_names else f"sphere {i}",
            )

        return names

    plan = Plan(lights=[], skipped=[])
    if len(table):
        cols = _primary_columns(read, table)
        common = dict(spot_blend=options["spot_blend"], scene_size=size, scene_bounds=read.bounds)
        first = _scaled(make_light_table(table, cols, model, **common), scale)
        everything = np.arange(len(table))
        kept = _rank(first, names_of(everything), min_b, max_lights, plan.skipped)
        kept = _without_sunk(read, occ, table, kept, names_of(kept), plan.skipped)
        timings["plan first"] = time.perf_counter() - t
        lights = _final_lights(read, occ, selection, cols, kept, tier, model, common, near_fits)
        names = names_of(kept)
        for k in _rank(lights, names, min_b, max_lights, plan.skipped).tolist():
            src = selection.sources[int(kept[k])]
            plan.lights.append(PlannedLight(src, lights.get(k), *names(k)))
    timings["plan"] = time.perf_counter() - t
    if release:
        read.occluders.release()  # the depsgraph may go away after this
    return Work(read, result, selection, plan, timings)


def _without_sunk(read, occ, table, kept, names, skipped) -> np.ndarray:
    """`kept` less the rows whose lens another surface cuts into (`sunk_lenses`),
    each listed in `skipped` (`Reason.SUNK`)."""
    if not len(kept):
        return kept
    lenses, row_lens = np.unique(np.asarray(table.lens)[kept], return_inverse=True)
    a = read.arrays
    sunk = sunk_lenses(occ, a.center[lenses], a.radius[lenses])[row_lens]
    for k in np.flatnonzero(sunk).tolist():
        skipped.append(SkippedPair(*names(k), Reason.SUNK))
    return kept[~sunk]


class _KeptLights:
    """The kept sources' lights, energy-scaled, with the columns `_rank` reads
    (`energy_w`, `reference_irradiance`, `relative_brightness`); ``get(k)`` is the
    `BlenderLight` of row k with the merged note, as `plan_lights` makes it."""

    def __init__(self, table: LightTable | None, rows: list | None, f: np.ndarray):
        self.f, self.table, self.rows = f, table, rows
        if table is not None:
            self.table = _scaled(table, f)
            src = self.table
        else:
            for bl, fk in zip(rows, f.tolist(), strict=True):
                if fk != 1.0:
                    bl.energy_w *= fk
                    bl.reference_irradiance *= fk
                    bl.relative_brightness *= fk
            src = SimpleNamespace(
                **{
                    k: np.array([getattr(bl, k) for bl in rows], dtype=float)
                    for k in ("energy_w", "reference_irradiance", "relative_brightness")
                }
            )
        self.energy_w = src.energy_w
        self.reference_irradiance = src.reference_irradiance
        self.relative_brightness = src.relative_brightness

    def get(self, k: int) -> BlenderLight:
        bl = self.table.light(k) if self.table is not None else self.rows[k]
        fk = float(self.f[k])
        if fk != 1.0:
            bl.note = "; ".join(x for x in (bl.note, f"merged: energy × {fk:.4g}") if x)
        return bl


def _final_lights(
    read, occ, selection, cols, rows, tier, model, common, near_fits=True
) -> _KeptLights:
    """The lights of the selection's `rows` with their rays against `occ` (the read's
    occluders, or their `RayMemo` view) (`plan_result`): the tier's table maker for
    `RECEIVER_TABLES`, else its per-source maker."""
    sub = take(selection.table, rows)
    size = common["scene_size"]
    f = selection.scale[rows]
    origins, axis, hits, recv = receiver_rays(occ, sub.axis, sub.lens_center, sub.lens_radius, size)
    if tier.name in RECEIVER_TABLES:
        free = free_distances(occ, sub.axis, sub.lens_center, sub.lens_radius, size)
        far = np.where(np.isfinite(free), free, COLLIMATED_DISTANCE_FACTOR * size)
        picked = dataclasses.replace(
            cols,
            **{
                k: getattr(cols, k)[rows]
                for k in ("power_w", "radius", "color", "transmission_weight", "tint", "absorption")
                if getattr(cols, k) is not None
            },
        )
        lights = tier.make_table(
            sub,
            picked.effective(sub),
            **common,
            collimated_distance=far,
            receiver_distance=recv,
            near_fits=near_fits,
        )
        return _KeptLights(lights, None, f)
    sources = [selection.sources[r] for r in rows.tolist()]
    beams = np.array(
        [model not in (THESIS, PHYSICAL) or may_be_beam(s, read.bounds, size) for s in sources],
        dtype=bool,
    )
    free = np.full(len(rows), np.nan)
    if beams.any():
        free[beams] = free_distances(
            occ, sub.axis[beams], sub.lens_center[beams], sub.lens_radius[beams], size
        )
    optics = read.lens_optics
    normals = {}
    for k in np.flatnonzero(np.isfinite(recv)).tolist():
        r = float(sub.lens_radius[k])
        normals[k] = rim_plane_normal(origins[k], axis[k], hits[k], r, distance=float(recv[k]))
    found = {}
    if tier.name == EXACT_PROFILE and normals:  # the only tier that reads them
        found = all_other_planes(occ, axis, sub.lens_center, sub.lens_radius, recv, normals)
    out = []
    for k, src in enumerate(sources):
        near = None
        if k in normals:
            near = ReceiverDistance(float(recv[k]), normals[k], found.get(k, ()))
        out.append(
            make_blender_light(
                src,
                read.primaries[src.light],
                model,
                optics=optics[src.lens] if optics else None,
                collimated_distance=float(free[k]) if np.isfinite(free[k]) else None,
                receiver_distance=near,
                **common,
            )
        )
    return _KeptLights(None, out, f)
