"""Phase 1 of the Bitracer method: one secondary light source per point light × lens.

SPEC.md §3 gives the thesis' formulas, §4 the stable forms used here:

* image position by vergence about the centre (`V = P − 1/D`), so there is no
  singular point at `p·a = R` and the focal point is just `V = 0`;
* radial angles by `atan2`, angles between directions by `atan2(|a×b|, a·b)`;
* the spreading angle of eqs. 5.14 and 5.21 rewritten in terms of `V` (the two
  branches are one formula: `tan θ = |R sin φ · V| / |R cos φ · V − 1|`), which
  tends to 0 smoothly as the image runs off to infinity.

Everything is vectorised over lights × lenses (and × obstacles for the obstruction
tests); the only Python loop is over lights, each handling all spheres at once (on
several cores, lights side by side in threads, for scenes of 50 000 spheres or more).
No inf or NaN leaves this module: invalid input becomes a skipped pair with a reason.
"""

from __future__ import annotations

import math
import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, fields

import numpy as np

from ..lens.sphere_caps import radial_angle, tangent_length
from ..scene.arrays import SceneArrays
from ..scene.model import Scene
from ..shared import parallel
from ..shared.ranges import concat_ranges
from . import skip_reasons
from .obstruction import find_blockers

REAL, VIRTUAL, COLLIMATED = "real", "virtual", "collimated"

#: A light within this relative distance of a sphere's surface is "on" it.
SURFACE_TOLERANCE = 1e-9
#: Default switch to the collimated representation: when the image lies farther
#: from the lens than this many times the scene's size.
COLLIMATION_RATIO = 1e4


@dataclass
class SecondarySource:
    light: int  # index among the scene's lights
    lens: int  # index among the scene's objects
    kind: str  # "real" | "virtual" | "collimated"
    position: np.ndarray  # image point (back vertex when collimated)
    axis: np.ndarray  # unit beam direction, from the light through the lens
    spread_deg: float  # θ, half-angle of the cone (0 when collimated)
    cylinder_radius: float | None  # R_C for collimated sources
    intensity: float  # I_j × brightness factor (eq. 5.22)
    color: tuple[float, float, float]
    full: bool
    shadow_list: list[int]
    # Quantities later stages need (energy models, Blender lights, reports):
    brightness_factor: float  # exp(−(1 − kt)(2R + TR)/2)
    distance: float  # D, light to lens centre
    lens_center: np.ndarray
    lens_radius: float
    ior: float
    vergence: float  # V = P − 1/D (1/length)
    image_distance: float | None  # 1/V, signed, from the lens centre along the axis
    magnification: float | None  # m = −(1/V)/D; None when collimated
    alpha_deg: float  # half-angle under which the light sees the lens
    unblocked_fraction: float  # share of the lit cap's flux no obstacle blocks
    # Primaries other than point lights (`all_lights`): the intensity toward
    # the lens in units of the primary's P/(4π), and the radius of the disc the
    # primary looks like from the lens (NaN: the primary's own radius).
    emission: float = 1.0
    source_radius: float = math.nan

    def to_json(self) -> dict:
        return {
            "light": self.light,
            "lens": self.lens,
            "kind": self.kind,
            "position": [float(x) for x in self.position],
            "axis": [float(x) for x in self.axis],
            "spread_deg": self.spread_deg,
            "cylinder_radius": self.cylinder_radius,
            "intensity": self.intensity,
            "color": [float(c) for c in self.color],
            "full": self.full,
            "shadow_list": list(self.shadow_list),
            "image_distance": self.image_distance,
            "magnification": self.magnification,
            "brightness_factor": self.brightness_factor,
            "unblocked_fraction": self.unblocked_fraction,
        }


@dataclass
class Skipped:
    light: int
    lens: int
    reason: str
    code: int = -1  # skip_reasons.Reason

    def to_json(self) -> dict:
        return {"light": self.light, "lens": self.lens, "reason": self.reason}


# --------------------------------------------------------------------------- optics


def ball_lens_power(radius, ior):
    """Power of a ball lens, both principal planes at its centre: `2(n − 1)/(n R)`."""
    return 2.0 * (ior - 1.0) / (ior * radius)


def critical_angle(ior):
    """`δ = asin(1/n)` for n ≥ 1, via atan2 so n → 1 (δ → 90°) stays exact."""
    return np.arctan2(1.0, np.sqrt((ior - 1.0) * (ior + 1.0)))


def brightness_factor(radius, ior, kt):
    """Thesis eq. 5.22: Beer–Lambert over the mean of the axial (2R) and edge chords.

    The edge ray's chord is `TR = 2R cos δ`, `cos δ = sqrt(n² − 1)/n`.
    """
    cos_delta = np.sqrt((ior - 1.0) * (ior + 1.0)) / ior
    return np.exp(-(1.0 - kt) * radius * (1.0 + cos_delta))


# --------------------------------------------------------------------------- input


def scene_size(arrays: SceneArrays, valid_lights, valid_spheres) -> float:
    """Diagonal of the box around the valid lights and spheres (at least one radius)."""
    lo, hi = [], []
    if np.any(valid_lights):
        p = arrays.light_position[valid_lights]
        lo.append(p.min(axis=0))
        hi.append(p.max(axis=0))
    if np.any(valid_spheres):
        # column by column: numpy's reductions over an (N, 3) array's rows are slow
        c, r = arrays.center, arrays.radius
        if not np.all(valid_spheres):
            c, r = c[valid_spheres], r[valid_spheres]
        lo.append(np.array([(c[:, k] - r).min() for k in range(3)]))
        hi.append(np.array([(c[:, k] + r).max() for k in range(3)]))
    if not lo:
        return 1.0
    with np.errstate(over="ignore", invalid="ignore"):
        size = float(_norm((np.max(hi, axis=0) - np.min(lo, axis=0))[None, :])[0])
    if np.any(valid_spheres):
        size = max(size, float(arrays.radius[valid_spheres].max()))
    return size if size > 0 and math.isfinite(size) else 1.0


# --------------------------------------------------------------------------- reasons

# Why a light × sphere pair yields no source. Codes keep the skip table columnar
# (a scene of 100 000 opaque spheres skips 100 000 pairs per light); the text is
# made only when asked for.
(
    INVALID_LIGHT,
    INVALID_SPHERE_NONFINITE,
    INVALID_SPHERE_RADIUS,
    OPAQUE,
    INVALID_KT,
    NOT_CONVERGING,
    LIGHT_INSIDE,
    LIGHT_ON_SURFACE,
    LIGHT_INSIDE_OTHER,
    LIGHT_ON_OTHER,
    TOTALLY_BLOCKED,
    OUT_OF_RANGE,
) = range(12)  # = skip_reasons.Reason


def reason_text(code: int, radius: float, ior: float, kt: float, other: int) -> str:
    return skip_reasons.reason_text(code, dict(radius=radius, ior=ior, kt=kt, other=other))


def sphere_problems(a: SceneArrays) -> np.ndarray:
    """Per sphere: the reason code that keeps it from being a lens, or −1."""
    code = np.full(a.radius.shape, -1, dtype=np.int64)
    # Later assignments win only where nothing earlier applied: go from least to
    # most fundamental and overwrite.
    code[a.ior <= 1] = NOT_CONVERGING
    code[(a.kt > 1) | (a.kt < 0)] = INVALID_KT
    code[a.kt == 0] = OPAQUE
    code[a.radius <= 0] = INVALID_SPHERE_RADIUS
    finite = _finite_rows(a.center) & np.isfinite(a.radius) & np.isfinite(a.ior) & np.isfinite(a.kt)
    code[~finite] = INVALID_SPHERE_NONFINITE
    return code


# --------------------------------------------------------------------------- output


@dataclass
class SourceTable:
    """All secondary sources as columns (N sources), ordered by (light, lens)."""

    light: np.ndarray  # (N,) int
    lens: np.ndarray  # (N,) int
    kind: np.ndarray  # (N,) 0 real, 1 virtual, 2 collimated
    position: np.ndarray  # (N, 3)
    axis: np.ndarray  # (N, 3)
    spread: np.ndarray  # (N,) θ in radians
    cylinder_radius: np.ndarray  # (N,) R_C, NaN unless collimated
    intensity: np.ndarray
    color: np.ndarray  # (N, 3)
    brightness_factor: np.ndarray
    distance: np.ndarray
    lens_center: np.ndarray  # (N, 3)
    lens_radius: np.ndarray
    ior: np.ndarray
    vergence: np.ndarray
    alpha: np.ndarray  # radians
    unblocked_fraction: np.ndarray
    emission: np.ndarray  # (N,) see SecondarySource.emission
    source_radius: np.ndarray  # (N,) NaN: the primary's own radius
    shadow_offsets: np.ndarray  # (N + 1,) CSR into shadow_spheres
    shadow_spheres: np.ndarray

    KINDS = (REAL, VIRTUAL, COLLIMATED)

    def __len__(self) -> int:
        return int(self.light.size)

    def shadow_list(self, t: int) -> list[int]:
        return self.shadow_spheres[self.shadow_offsets[t] : self.shadow_offsets[t + 1]].tolist()

    def source(self, t: int) -> SecondarySource:
        kind = self.KINDS[self.kind[t]]
        col = kind == COLLIMATED
        V, D = float(self.vergence[t]), float(self.distance[t])
        shadow = self.shadow_list(t)
        return SecondarySource(
            light=int(self.light[t]),
            lens=int(self.lens[t]),
            kind=kind,
            position=self.position[t].copy(),
            axis=self.axis[t].copy(),
            spread_deg=float(np.degrees(self.spread[t])),
            cylinder_radius=float(self.cylinder_radius[t]) if col else None,
            intensity=float(self.intensity[t]),
            color=tuple(float(c) for c in self.color[t]),
            full=not shadow,
            shadow_list=shadow,
            brightness_factor=float(self.brightness_factor[t]),
            distance=D,
            lens_center=self.lens_center[t].copy(),
            lens_radius=float(self.lens_radius[t]),
            ior=float(self.ior[t]),
            vergence=V,
            image_distance=None if col else 1.0 / V,
            magnification=None if col else -1.0 / (V * D),
            alpha_deg=float(np.degrees(self.alpha[t])),
            unblocked_fraction=float(self.unblocked_fraction[t]),
            emission=float(self.emission[t]),
            source_radius=float(self.source_radius[t]),
        )


@dataclass
class SkipTable:
    """Every light × sphere pair without a source, as columns, by (light, lens)."""

    light: np.ndarray
    lens: np.ndarray
    code: np.ndarray
    other: np.ndarray  # the other sphere a reason names, or −1

    def __len__(self) -> int:
        return int(self.light.size)


class Phase1Result:
    """Phase 1's answer: `table` and `skip_table` (columns, for code that scales),
    `sources` and `skipped` (lists of dataclasses, made on first use)."""

    def __init__(self, table: SourceTable, skip_table: SkipTable, arrays: SceneArrays):
        self.table = table
        self.skip_table = skip_table
        self._arrays = arrays
        self._sources: list[SecondarySource] | None = None
        self._skipped: list[Skipped] | None = None

    @property
    def sources(self) -> list[SecondarySource]:
        if self._sources is None:
            self._sources = [self.table.source(t) for t in range(len(self.table))]
        return self._sources

    @property
    def skipped(self) -> list[Skipped]:
        if self._skipped is None:
            a, s = self._arrays, self.skip_table
            self._skipped = [
                Skipped(
                    int(j),
                    int(i),
                    reason_text(
                        int(c), float(a.radius[i]), float(a.ior[i]), float(a.kt[i]), int(k)
                    ),
                    int(c),
                )
                for j, i, c, k in zip(s.light, s.lens, s.code, s.other, strict=False)
            ]
        return self._skipped

    def skip_counts(self) -> dict[str, int]:
        """How many pairs were skipped for each kind of reason (numbers left out)."""
        counts: dict[str, int] = {}
        codes, n = np.unique(self.skip_table.code, return_counts=True)
        for c, k in zip(codes, n, strict=False):
            kind = skip_reasons.reason_kind(c)
            counts[kind] = counts.get(kind, 0) + int(k)
        return counts

    def to_json(self) -> dict:
        return {
            "sources": [s.to_json() for s in self.sources],
            "skipped": [s.to_json() for s in self.skipped],
        }


# --------------------------------------------------------------------------- phase 1


def compute_phase1(
    scene: Scene | SceneArrays,
    collimation_ratio: float = COLLIMATION_RATIO,
    workers: int | None = None,
) -> Phase1Result:
    """All secondary light sources of a scene, and every pair that yields none.

    `collimation_ratio`: an image farther from its lens than this many times the
    scene's size is represented as a collimated beam (a cylinder of radius R_C from
    the back vertex). Across the switch the light a receiver in the scene gets
    changes by about 1/collimation_ratio: the cone's apex is that far away and its
    half-angle that small, so its footprint is R_C to that precision.

    `workers`: threads computing lights side by side (None: one per core, up to the
    number of lights, when the scene is big enough to gain). The lights are
    independent and numpy lets go of the GIL in its loops; the result is the same
    for any number.
    """
    a = scene if isinstance(scene, SceneArrays) else SceneArrays.from_scene(scene)
    n_lights, n_spheres = len(a.light_brightness), len(a.radius)
    valid_light = (
        np.all(np.isfinite(a.light_position), axis=1)
        & np.isfinite(a.light_brightness)
        & np.all(np.isfinite(a.light_color), axis=1)
    )
    problem = sphere_problems(a)
    valid_sphere = (problem != INVALID_SPHERE_NONFINITE) & (problem != INVALID_SPHERE_RADIUS)
    far = collimation_ratio * scene_size(a, valid_light, valid_sphere)

    all_spheres = np.arange(n_spheres)
    not_lens = problem >= 0
    lit = np.flatnonzero(valid_light)

    def one_light(j):
        own = [(j, all_spheres[not_lens], problem[not_lens], -1)]
        return _light_sources(a, j, problem, valid_sphere, far, own), own

    if workers is None:
        workers = _default_workers(lit.size, n_spheres)
    if workers > 1 and lit.size > 1:

        def one_light_inline(j):  # lights in threads: no threads inside a light
            with parallel.inline():
                return one_light(j)

        with ThreadPoolExecutor(min(workers, lit.size)) as pool:
            lights = pool.map(one_light_inline, lit.tolist())
            done = dict(zip(lit.tolist(), lights, strict=True))
    else:
        done = {j: one_light(j) for j in lit.tolist()}
    parts, skips = [], []
    for j in range(n_lights):  # in the lights' order, whichever thread finished first
        if not valid_light[j]:
            skips.append((j, all_spheres, np.full(n_spheres, INVALID_LIGHT), -1))
            continue
        part, own = done[j]
        parts.append(part)
        skips.extend(own)
    return Phase1Result(_concat_sources(parts), _skip_table(skips), a)


#: Spheres below which one thread does all lights: a light's numpy steps are then too
#: short for the GIL to be let go long. Droplets, wall best of 5, one thread → two:
#: 16 × 10 000 1.37 → 1.05 s, 16 × 7 000 1.03 → 0.82 s, 2 × 20 000 0.20 → 0.16 s,
#: 16 × 5 000 0.53 → 0.51 s, 10 × 3 000 0.22 → 0.30 s (slower); 2 × 100 489 glass
#: balls 3.4–3.8 → 2.1–2.3 s.
THREADED_SPHERES = 7_000


def _default_workers(n_lights: int, n_spheres: int) -> int:
    if n_lights < 2 or n_spheres < THREADED_SPHERES:
        return 1
    try:
        cores = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        cores = os.cpu_count() or 1
    return max(1, min(cores, n_lights))


def _light_sources(a: SceneArrays, j: int, problem, valid_sphere, far, skips) -> dict:
    """Columns of the secondary sources of light j through every lens."""
    light = a.light_position[j]
    with np.errstate(over="ignore", invalid="ignore"):
        to_center = a.center - light  # (S, 3)
        dist = _norm(to_center)
    rad = a.radius
    overflow = valid_sphere & ~(np.isfinite(dist) & _finite_rows(to_center))
    if overflow.any():
        skips.append(
            (
                j,
                np.flatnonzero(overflow & (problem < 0)),
                np.full(int((overflow & (problem < 0)).sum()), OUT_OF_RANGE),
                -1,
            )
        )
        valid_sphere = valid_sphere & ~overflow
    with np.errstate(invalid="ignore"):
        surface = valid_sphere & (np.abs(dist - rad) <= SURFACE_TOLERANCE * rad)
        inside = valid_sphere & (dist < rad) & ~surface
    outside = valid_sphere & ~inside & ~surface
    with np.errstate(invalid="ignore", divide="ignore"):
        direction = to_center / dist[:, None]
    ang = np.where(outside, radial_angle(dist, rad), 0.0)  # α or β
    tlen = np.where(outside, tangent_length(dist, rad), 0.0)  # R_T

    lens = problem < 0
    for mask, code in ((lens & inside, LIGHT_INSIDE), (lens & surface, LIGHT_ON_SURFACE)):
        if mask.any():
            skips.append((j, np.flatnonzero(mask), np.full(mask.sum(), code), -1))
    lens &= outside
    # The light inside (or on) some other sphere: the tangent construction is void.
    enclosing = np.flatnonzero(inside | surface)
    if enclosing.size and lens.any():
        k = int(enclosing[0])
        ids = np.flatnonzero(lens)
        code = LIGHT_INSIDE_OTHER if inside[k] else LIGHT_ON_OTHER
        skips.append((j, ids, np.full(ids.size, code), k))
        lens[:] = False
    lenses = np.flatnonzero(lens)

    blk = find_blockers(lenses, direction, ang, tlen, outside, a.ior, a.kt)
    total = blk.total_blocker >= 0
    if total.any():
        skips.append(
            (j, lenses[total], np.full(total.sum(), TOTALLY_BLOCKED), blk.total_blocker[total])
        )
    keep = ~total
    rows = np.flatnonzero(keep)
    lenses = lenses[keep]

    # Optics, vectorised over this light's lenses.
    D, R, n = dist[lenses], rad[lenses], a.ior[lenses]
    u, C = direction[lenses], a.center[lenses]
    V = ball_lens_power(R, n) - 1.0 / D
    collimated = np.abs(V) * far <= 1.0
    alpha = ang[lenses]
    phi = 2.0 * critical_angle(n) + alpha - 0.5 * np.pi  # exit point, from the back axis
    height = R * np.sin(phi)  # d of eq. 5.10 (signed)
    theta = np.where(
        collimated, 0.0, np.arctan2(np.abs(height * V), np.abs(R * np.cos(phi) * V - 1.0))
    )
    image = np.where(collimated, R, 1.0 / np.where(collimated, 1.0, V))
    factor = brightness_factor(R, n, a.kt[lenses])
    starts = blk.shadow_offsets[rows]
    counts = blk.shadow_offsets[rows + 1] - starts
    shadow = blk.shadow_spheres[concat_ranges(starts, counts)]
    m = lenses.size
    return dict(
        light=np.full(m, j),
        lens=lenses,
        kind=np.where(collimated, 2, np.where(V > 0, 0, 1)),
        position=C + image[:, None] * u,
        axis=u,
        spread=theta,
        cylinder_radius=np.where(collimated, np.abs(height), np.nan),
        intensity=a.light_brightness[j] * factor,
        color=np.broadcast_to(a.light_color[j], (m, 3)),
        brightness_factor=factor,
        distance=D,
        lens_center=C,
        lens_radius=R,
        ior=n,
        vergence=V,
        alpha=alpha,
        unblocked_fraction=blk.unblocked_fraction[rows],
        emission=np.ones(m),
        source_radius=np.full(m, np.nan),
        shadow_counts=counts,
        shadow_spheres=shadow,
    )


def _norm(v: np.ndarray) -> np.ndarray:
    """Row norms that do not overflow before the result does (huge coordinates)."""
    # column by column (numpy's reductions along rows of 3 are slow), summed in the
    # order np.linalg.norm sums them
    x, y, z = (np.abs(v[:, k]) for k in range(3))
    scale = np.maximum(np.maximum(x, y), z)
    safe = np.where(scale > 0, scale, 1.0)
    x, y, z = x / safe, y / safe, z / safe
    return scale * np.sqrt(x * x + y * y + z * z)


def _finite_rows(v: np.ndarray) -> np.ndarray:
    """Rows of an (N, 3) array whose three numbers are all finite."""
    return np.isfinite(v[:, 0]) & np.isfinite(v[:, 1]) & np.isfinite(v[:, 2])


def _concat_sources(parts: list[dict]) -> SourceTable:
    names = [f for f in SourceTable.__dataclass_fields__ if not f.startswith("shadow")]
    if not parts:
        parts = [
            dict(
                {
                    k: np.zeros((0, 3) if k in ("position", "axis", "color", "lens_center") else 0)
                    for k in names
                },
                shadow_counts=np.zeros(0, dtype=np.int64),
                shadow_spheres=np.zeros(0, dtype=np.int64),
            )
        ]
    cols = {k: np.concatenate([np.asarray(p[k]) for p in parts]) for k in names}
    counts = np.concatenate([p["shadow_counts"] for p in parts]).astype(np.int64)
    offsets = np.concatenate([[0], np.cumsum(counts)])
    cols["light"] = cols["light"].astype(np.int64)
    cols["lens"] = cols["lens"].astype(np.int64)
    cols["kind"] = cols["kind"].astype(np.int64)
    return SourceTable(
        **cols,
        shadow_offsets=offsets,
        shadow_spheres=np.concatenate([p["shadow_spheres"] for p in parts]).astype(np.int64),
    )


def _skip_table(skips) -> SkipTable:
    if not skips:
        z = np.zeros(0, dtype=np.int64)
        return SkipTable(z, z, z, z)
    light = np.concatenate([np.full(np.size(ids), j) for j, ids, _, _ in skips])
    lens = np.concatenate([np.asarray(ids) for _, ids, _, _ in skips])
    code = np.concatenate([np.asarray(c) for _, _, c, _ in skips])
    other = np.concatenate([np.broadcast_to(k, np.size(ids)) for _, ids, _, k in skips])
    order = np.lexsort((lens, light))
    return SkipTable(*(x[order].astype(np.int64) for x in (light, lens, code, other)))


def take(table: SourceTable, rows: np.ndarray) -> SourceTable:
    """The sources `rows` of a table (shadow lists carried along)."""
    rows = np.asarray(rows, dtype=np.int64)
    cols = {
        f.name: getattr(table, f.name)[rows]
        for f in fields(table)
        if not f.name.startswith("shadow")
    }
    starts = table.shadow_offsets[rows]
    counts = table.shadow_offsets[rows + 1] - starts
    spheres = table.shadow_spheres[concat_ranges(starts, counts)]
    return SourceTable(
        **cols, shadow_offsets=np.concatenate([[0], np.cumsum(counts)]), shadow_spheres=spheres
    )
