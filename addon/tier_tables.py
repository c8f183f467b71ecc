"""Blender lights of a whole phase-1 source table at once, as columns.

`light_models.make_blender_light` (THESIS, PHYSICAL) and `lens_tiers`
(FITTED, EXACT_PROFILE) make one `BlenderLight` per source in Python: about 60 µs
each, the bulk of `phase1 --json` on large scenes. `make_light_table` does the
same arithmetic on arrays over all sources of a `phase1.SourceTable`: the same
numbers (to floating-point rounding: numpy's transcendental functions may differ
from `math`'s in the last bit) and, on demand, the same notes (`LightTable.note`,
`LightTable.light`). The per-source makers stay the reference
(tests/test_tier_tables.py compares every field).

EXACT_PROFILE still traces the exact beam once per distinct `(D/R, n)`
(`lens_tiers._beam_summary`, cached): that part is not vectorisable here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from . import lens_tiers as lt
from .light_models import (
    COLLIMATED_DISTANCE_FACTOR,
    CUTOFF_FACTOR,
    DEFAULT_SPOT_BLEND,
    MIN_HALF_ANGLE_DEG,
    SPOT,
    SPOT_SIZE_MAX_DEG,
    SPOT_SIZE_MIN_DEG,
    BlenderLight,
    head_on_transmission,
)
from .phase1 import SourceTable

THESIS, PHYSICAL, FITTED, EXACT_PROFILE = "THESIS", "PHYSICAL", "FITTED", "EXACT_PROFILE"
KINDS = SourceTable.KINDS
REAL, VIRTUAL, COLLIMATED = range(3)
#: Why a THESIS/PHYSICAL light is a far-away beam spot (0: it is a cone at the image).
CONE, BEAM_COLLIMATED, BEAM_REAL_BEYOND, BEAM_VIRTUAL_FAR = range(4)


@dataclass
class Primaries:
    """Per source: its primary light and its lens's material (`PrimaryLight`,
    `LensOptics` as columns)."""

    power_w: np.ndarray  # (N,)
    radius: np.ndarray  # (N,)
    color: np.ndarray  # (N, 3)
    transmission_weight: np.ndarray  # (N,)
    tint: np.ndarray | None = None  # (N, 3); None: clear (1, 1, 1)
    absorption: np.ndarray | None = None  # (N, 3); None: none

    @property
    def intensity(self) -> np.ndarray:
        return self.power_w / (4.0 * math.pi)


@dataclass
class ConeShapes:
    """`light_models.cone_shape` over arrays; `code` says which note applies."""

    spot_size_deg: np.ndarray
    scale_xy: np.ndarray
    half_angle_deg: np.ndarray
    asked_deg: np.ndarray  # the half-angle asked for (for the note)
    widened: np.ndarray  # bool: below MIN_HALF_ANGLE_DEG or not finite
    clamped: np.ndarray  # bool: wider than 180°
    narrowed: np.ndarray  # bool: spot_size 1° plus object scale

    def note(self, t: int) -> str:
        theta = float(self.asked_deg[t])
        note = (
            f"cone half-angle {theta:.3g}° widened to {MIN_HALF_ANGLE_DEG:g}°"
            if self.widened[t]
            else ""
        )
        if self.clamped[t]:
            full = 2.0 * max(theta, MIN_HALF_ANGLE_DEG)
            return f"cone {full:.4g}° clamped to Blender's maximum 180°"
        if self.narrowed[t]:
            full = 2.0 * float(self.half_angle_deg[t])
            extra = (
                f"cone {full:.3g}° < 1°: spot_size 1°, narrowed by object scale "
                f"{float(self.scale_xy[t]):.4g}"
            )
            return f"{note}; {extra}" if note else extra
        return note


def cone_shapes(half_angle_deg: np.ndarray) -> ConeShapes:
    asked = np.asarray(half_angle_deg, dtype=float)
    with np.errstate(invalid="ignore"):
        widened = ~np.isfinite(asked) | (asked < MIN_HALF_ANGLE_DEG)
    theta = np.where(widened, MIN_HALF_ANGLE_DEG, asked)
    full = 2.0 * theta
    clamped = full > SPOT_SIZE_MAX_DEG
    narrowed = ~clamped & (full < SPOT_SIZE_MIN_DEG)
    k = np.tan(np.radians(theta)) / math.tan(math.radians(0.5 * SPOT_SIZE_MIN_DEG))
    return ConeShapes(
        spot_size_deg=np.where(
            clamped, SPOT_SIZE_MAX_DEG, np.where(narrowed, SPOT_SIZE_MIN_DEG, full)
        ),
        scale_xy=np.where(narrowed, k, 1.0),
        half_angle_deg=np.where(clamped, 90.0, theta),
        asked_deg=asked,
        widened=widened,
        clamped=clamped,
        narrowed=narrowed,
    )


@dataclass
class LightTable:
    """One Blender light per source (columns); `light(t)` is the `BlenderLight`."""

    model: str
    kind: np.ndarray  # source kind codes (phase1.SourceTable.kind)
    energy_w: np.ndarray
    spot_size_deg: np.ndarray
    spot_blend: np.ndarray
    radius: np.ndarray
    location: np.ndarray  # (N, 3)
    direction: np.ndarray  # (N, 3)
    color: np.ndarray  # (N, 3)
    scale_xy: np.ndarray
    cone_half_angle_deg: np.ndarray
    cutoff_distance: np.ndarray
    reference_irradiance: np.ndarray
    relative_brightness: np.ndarray
    _note_parts: list  # callables t → str ("" when none), in note order
    profile_info: dict | None = None  # EXACT_PROFILE: columns of `profile_info`

    def __len__(self) -> int:
        return int(self.energy_w.size)

    def note(self, t: int) -> str:
        return "; ".join(p for p in (part(t) for part in self._note_parts) if p)

    def light(self, t: int) -> BlenderLight:
        common = dict(
            type=SPOT,
            energy_w=float(self.energy_w[t]),
            spot_size_deg=float(self.spot_size_deg[t]),
            spot_blend=float(self.spot_blend[t]),
            radius=float(self.radius[t]),
            location=tuple(self.location[t].tolist()),
            direction=tuple(self.direction[t].tolist()),
            note=self.note(t),
            color=tuple(self.color[t].tolist()),
            scale_xy=float(self.scale_xy[t]),
            cone_half_angle_deg=float(self.cone_half_angle_deg[t]),
            cutoff_distance=float(self.cutoff_distance[t]),
            kind=KINDS[int(self.kind[t])],
            model=self.model,
            reference_irradiance=float(self.reference_irradiance[t]),
            relative_brightness=float(self.relative_brightness[t]),
        )
        if self.profile_info is None:
            return BlenderLight(**common)
        info = {
            k: (v[t].item() if isinstance(v, np.ndarray) else v)
            for k, v in self.profile_info.items()
        }
        return lt.ProfileLight(**common, profile_info=info)

    def json_columns(self) -> dict[str, list]:
        """`BlenderLight.to_json` of every light, as columns of lists (for JSON)."""
        n = len(self)
        cols = {
            "type": [SPOT] * n,
            "energy_w": self.energy_w.tolist(),
            "spot_size_deg": self.spot_size_deg.tolist(),
            "spot_blend": self.spot_blend.tolist(),
            "radius": self.radius.tolist(),
        }
        if self.profile_info is not None:
            info = {
                k: (v.tolist() if isinstance(v, np.ndarray) else [v] * n)
                for k, v in self.profile_info.items()
            }
            cols["profile"] = [
                dict(zip(info, row, strict=True)) for row in zip(*info.values(), strict=True)
            ]
        return cols


# --------------------------------------------------------------------------- helpers


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.sqrt(np.sum(v * v, axis=1))[:, None]


def _downstream_reach(origin, axis, scene_bounds, fallback):
    """`light_models._downstream_reach` over rows."""
    if scene_bounds is None:
        return np.broadcast_to(np.asarray(fallback, dtype=float), origin.shape[:1])
    lo, hi = (np.asarray(b, dtype=float) for b in scene_bounds)
    return np.sum(np.maximum((lo - origin) * axis, (hi - origin) * axis), axis=1)


def _physical_color(table: SourceTable, p: Primaries) -> np.ndarray:
    tint = np.ones_like(p.color) if p.tint is None else np.clip(p.tint, 0.0, 1.0)
    absorption = np.zeros_like(p.color) if p.absorption is None else np.maximum(p.absorption, 0.0)
    return p.color * tint * np.exp(-absorption * (2.0 * table.lens_radius)[:, None])


def _unblocked(table: SourceTable) -> tuple[np.ndarray, np.ndarray]:
    full = np.diff(table.shadow_offsets) == 0
    return np.clip(table.unblocked_fraction, 0.0, 1.0), full


def _nonfull_note(unblocked, full):
    return lambda t: (
        ""
        if full[t]
        else f"non-full: energy × {float(unblocked[t]):.4g} (unblocked share of the lit cap)"
    )


def _relative(irradiance, primary_irradiance):
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(primary_irradiance > 0, irradiance / primary_irradiance, 0.0)


def _safe_size(scene_size) -> float:
    ok = scene_size and math.isfinite(scene_size) and scene_size > 0
    return float(scene_size) if ok else 1.0


# --------------------------------------------------------------------------- makers


def make_light_table(
    table: SourceTable,
    primaries: Primaries,
    model: str,
    *,
    scene_size: float = 1.0,
    scene_bounds=None,
    collimated_distance: float | None = None,
    spot_blend: float = DEFAULT_SPOT_BLEND,
) -> LightTable:
    """What `make_blender_light(source, primary, model, optics=…, scene_size=…,
    scene_bounds=…, collimated_distance=…)` gives for every source of `table`."""
    size = _safe_size(scene_size)
    if model in (FITTED, EXACT_PROFILE):
        far = collimated_distance or COLLIMATED_DISTANCE_FACTOR * size
        if model == FITTED:
            return fitted_table(table, primaries, scene_size=size, collimated_distance=far)
        return profile_table(table, primaries, scene_size=size)
    if model not in (THESIS, PHYSICAL):
        raise ValueError(f"unknown tier {model!r}")
    return paraxial_table(
        table,
        primaries,
        model,
        scene_size=size,
        scene_bounds=scene_bounds,
        collimated_distance=collimated_distance,
        spot_blend=spot_blend,
    )


def paraxial_table(
    table: SourceTable,
    p: Primaries,
    model: str,
    *,
    scene_size: float,
    scene_bounds=None,
    collimated_distance: float | None = None,
    spot_blend: float = DEFAULT_SPOT_BLEND,
) -> LightTable:
    """THESIS and PHYSICAL (`light_models.make_blender_light`'s own branch)."""
    axis = _unit(table.axis)
    R, D, kind = table.lens_radius, table.distance, table.kind
    center, position = table.lens_center, table.position
    unblocked, full = _unblocked(table)
    I0 = p.intensity
    color = p.color.copy() if model == THESIS else _physical_color(table, p)
    primary_irradiance = I0 / D**2
    s_far = (
        float(collimated_distance)
        if collimated_distance
        else COLLIMATED_DISTANCE_FACTOR * scene_size
    )
    s_far = max(s_far, 1e-6 * scene_size)
    back_vertex = center + R[:, None] * axis
    col = kind == COLLIMATED
    with np.errstate(divide="ignore", invalid="ignore"):
        z_img = np.where(col, np.nan, 1.0 / table.vergence)  # signed, from the centre
        m = np.where(col, np.nan, -1.0 / (table.vergence * D))
    spread_deg = np.degrees(table.spread)

    # Model quantities (ThesisModel / PhysicalModel).
    if model == THESIS:
        cone_intensity = I0 * table.brightness_factor
    else:
        w = np.clip(p.transmission_weight, 0.0, 1.0)
        throughput = head_on_transmission(table.ior) * w * w
        cone_intensity = I0 * throughput * m * m

    real_far = _downstream_reach(position, axis, scene_bounds, scene_size - (z_img - R)) <= 0.0
    why = np.where(
        col,
        BEAM_COLLIMATED,
        np.where(
            (kind == REAL) & real_far,
            BEAM_REAL_BEYOND,
            np.where((kind == VIRTUAL) & (np.abs(z_img) > s_far), BEAM_VIRTUAL_FAR, CONE),
        ),
    )
    beam = why != CONE

    # Beam spots, far behind the back vertex.
    reach = _downstream_reach(back_vertex, axis, scene_bounds, scene_size)
    l_ref = (
        0.5 * np.minimum(np.maximum(reach, 0.0), scene_size)
        if scene_bounds is not None
        else np.full(len(table), 0.5 * scene_size)
    )
    ref = np.maximum(l_ref, 1e-9 * scene_size)
    if model == THESIS:
        beam_irradiance = I0 * table.brightness_factor / ref**2
    else:
        beam_irradiance = I0 * throughput / D**2
    with np.errstate(divide="ignore", invalid="ignore"):
        width = np.where(
            col,
            np.nan_to_num(table.cylinder_radius),
            np.tan(np.radians(spread_deg)) * np.abs(z_img - R),
        )
        b_irr = (
            np.where(col, beam_irradiance, cone_intensity / (z_img - (R + l_ref)) ** 2) * unblocked
        )
        b_light_radius = np.where(col, p.radius / D, np.abs(m) * p.radius / np.abs(z_img))
    b_shape = cone_shapes(np.degrees(np.arctan2(width, s_far)))
    b_intensity = b_irr * (s_far + l_ref) ** 2

    # Cones at the image point.
    c_shape = cone_shapes(spread_deg)
    c_intensity = cone_intensity * unblocked
    z_ref = np.abs(z_img)
    with np.errstate(divide="ignore", invalid="ignore"):
        c_irr = np.where(z_ref > 0, c_intensity / z_ref**2, np.inf)

    shape = ConeShapes(
        *(
            np.where(beam, getattr(b_shape, f), getattr(c_shape, f))
            for f in ConeShapes.__dataclass_fields__
        )
    )
    intensity = np.where(beam, b_intensity, c_intensity)
    irradiance = np.where(beam, b_irr, c_irr)
    location = np.where(beam[:, None], back_vertex - s_far * axis, position)
    radius = np.where(beam, s_far * b_light_radius, np.abs(m) * p.radius)
    reach_total = np.where(
        beam, s_far + scene_size, np.sqrt(np.sum((position - center) ** 2, axis=1)) + scene_size
    )

    def beam_note(t):
        w_ = float(width[t])
        return {
            CONE: "",
            BEAM_COLLIMATED: f"collimated beam R_C={w_:.4g}",
            BEAM_REAL_BEYOND: f"real image beyond the scene: beam of radius {w_:.4g}",
            BEAM_VIRTUAL_FAR: f"virtual image far behind: beam of radius {w_:.4g}",
        }[int(why[t])]

    def spot_note(t):
        return f"spot {s_far:.4g} behind the back vertex" if beam[t] else ""

    return LightTable(
        model=model,
        kind=kind,
        energy_w=4.0 * math.pi * intensity,
        spot_size_deg=shape.spot_size_deg,
        spot_blend=np.full(len(table), float(min(max(spot_blend, 0.0), 1.0))),
        radius=radius,
        location=location,
        direction=axis,
        color=color,
        scale_xy=shape.scale_xy,
        cone_half_angle_deg=shape.half_angle_deg,
        cutoff_distance=CUTOFF_FACTOR * reach_total,
        reference_irradiance=irradiance,
        relative_brightness=_relative(irradiance, primary_irradiance),
        _note_parts=[beam_note, spot_note, shape.note, _nonfull_note(unblocked, full)],
    )


def fitted_spots(D_over_R: np.ndarray, n: np.ndarray):
    """`lens_tiers.fitted_spot` over arrays: (apex, intensity, half_angle_deg,
    blend, x_clamped, n_clamped)."""
    t = lt._table()
    xs, ns = np.asarray(t.X), np.asarray(t.N)
    with np.errstate(divide="ignore"):
        x = np.where(np.isfinite(D_over_R), 1.0 / D_over_R, 0.0)
    DR = np.where(x == 0.0, lt.SUN_DISTANCE, D_over_R)
    x_clamped = x > xs[-1]
    x = np.where(x_clamped, xs[-1], x)
    n_clamped = ~((ns[0] <= n) & (n <= ns[-1]))
    n = np.clip(n, ns[0], ns[-1])
    i = np.clip(np.searchsorted(xs, x, side="right") - 1, 0, xs.size - 2)
    j = np.clip(np.searchsorted(ns, n, side="right") - 1, 0, ns.size - 2)
    u = (x - xs[i]) / (xs[i + 1] - xs[i])
    v = (n - ns[j]) / (ns[j + 1] - ns[j])

    def lerp(A):
        return (
            (1 - u) * (1 - v) * A[i, j]
            + u * (1 - v) * A[i + 1, j]
            + (1 - u) * v * A[i, j + 1]
            + u * v * A[i + 1, j + 1]
        )

    w = lerp(np.asarray(t.W))
    e = np.exp(lerp(np.log(np.asarray(t.E))))
    r = np.exp(lerp(np.log(np.asarray(t.RCONE))))
    b = lerp(np.asarray(t.BLEND))
    d = 1.0 / w  # SpotFit.from_invariants
    apex = 1.0 + lt.FIRST_RECEIVER - d
    intensity = e * (d / DR) ** 2
    half = np.degrees(np.arctan2(r, d))
    return apex, intensity, half, b, x_clamped, n_clamped


def fitted_table(
    table: SourceTable, p: Primaries, *, scene_size: float, collimated_distance: float | None
) -> LightTable:
    """FITTED (`lens_tiers.make_fitted_light`, table lookup)."""
    axis = _unit(table.axis)
    R, D, n = table.lens_radius, table.distance, table.ior
    unblocked, full = _unblocked(table)
    scale = np.clip(p.transmission_weight, 0.0, 1.0) ** 2 * unblocked
    DR = D / R
    apex, intensity, half, blend, x_clamped, n_clamped = fitted_spots(DR, n)
    xs, ns = lt._table().X, lt._table().N

    def table_note(t):
        parts = []
        if x_clamped[t]:
            parts.append(
                f"light at {float(DR[t]):.4g} R: nearer than the table's "
                f"{1 / xs[-1]:.4g} R, clamped"
            )
        if n_clamped[t]:
            parts.append(f"n = {float(n[t]):.4g} outside the table's {ns[0]:g}–{ns[-1]:g}, clamped")
        return "; ".join(parts)

    pulled = np.zeros(len(table), dtype=bool)
    old_behind = (1.0 - apex) * R
    if collimated_distance:  # lens_tiers.pull_in
        max_behind = float(collimated_distance) / R
        pulled = ((1.0 - apex) > max_behind) & (max_behind > 0.0)
        new_apex = 1.0 - max_behind
        d_old, d_new = 1.0 + lt.FIRST_RECEIVER - apex, 1.0 + lt.FIRST_RECEIVER - new_apex
        r_cone = d_old * np.tan(np.radians(half))
        z_ref = 1.0 + lt.FIT_RECEIVERS[len(lt.FIT_RECEIVERS) // 2]
        k = intensity * ((z_ref - new_apex) / (z_ref - apex)) ** 2
        half = np.where(pulled, np.degrees(np.arctan2(r_cone, d_new)), half)
        intensity = np.where(pulled, k, intensity)
        apex = np.where(pulled, new_apex, apex)

    def pull_note(t):
        return (
            ""
            if not pulled[t]
            else f"spot pulled in from {float(old_behind[t]):.4g} to "
            f"{float((1.0 - apex[t]) * R[t]):.4g} behind the back vertex "
            "(geometry behind the lens)"
        )

    shape = cone_shapes(half)
    I0 = p.intensity
    d_ref = (1.0 + lt.FIRST_RECEIVER - apex) * R
    irradiance = I0 * intensity * scale / d_ref**2
    return LightTable(
        model=FITTED,
        kind=table.kind,
        energy_w=p.power_w * intensity * scale,
        spot_size_deg=shape.spot_size_deg,
        spot_blend=np.clip(blend, 0.0, 1.0),
        radius=p.radius * np.abs(apex * R + D) / D,
        location=table.lens_center + (apex * R)[:, None] * axis,
        direction=axis,
        color=_physical_color(table, p),
        scale_xy=shape.scale_xy,
        cone_half_angle_deg=shape.half_angle_deg,
        cutoff_distance=CUTOFF_FACTOR * (np.abs(apex) * R + scene_size),
        reference_irradiance=irradiance,
        relative_brightness=_relative(irradiance, I0 / D**2),
        _note_parts=[_nonfull_note(unblocked, full), table_note, pull_note, shape.note],
    )


def profile_table(table: SourceTable, p: Primaries, *, scene_size: float) -> LightTable:
    """EXACT_PROFILE (`lens_tiers.make_profile_light`, the shipped table's sizes)."""
    axis = _unit(table.axis)
    R, D = table.lens_radius, table.distance
    unblocked, full = _unblocked(table)
    scale = np.clip(p.transmission_weight, 0.0, 1.0) ** 2 * unblocked
    # The beam's flux and reference irradiance per distinct (D/R, n), as lens_tiers keys them.
    keys = list(
        zip(
            [round(x, 9) for x in (D / R).tolist()],
            [round(x, 9) for x in table.ior.tolist()],
            strict=True,
        )
    )
    summary = {k: lt._beam_summary(*k) for k in dict.fromkeys(keys)}
    flux = np.array([summary[k][0] for k in keys], dtype=float).reshape(-1)
    e_ref = np.array([summary[k][1] for k in keys], dtype=float).reshape(-1)
    I0 = p.intensity
    t_ref = np.where(flux > 0, flux / (2.0 * math.pi), 1.0)
    I_ref = np.where(flux > 0, I0 * t_ref * scale, 0.0)
    apex = 1.0 + lt.PROFILE_OFFSET
    irradiance = I0 * scale * e_ref / R**2
    nsrc = len(table)
    info = {
        "gamma_max_deg": lt.PROFILE_GAMMA_MAX_DEG,
        "h_min": lt.PROFILE_H_MIN * R,
        "h_max": lt.PROFILE_H_MAX * R,
        "width": lt.PROFILE_ANGLES,
        "height": lt.PROFILE_DISTANCES,
        "strength_scale": 1.0,
    }
    cycles = "Cycles only: intensity from the light node tree (EEVEE ignores it)"
    return LightTable(
        model=EXACT_PROFILE,
        kind=table.kind,
        energy_w=4.0 * math.pi * I_ref,
        spot_size_deg=np.full(nsrc, 180.0),
        spot_blend=np.zeros(nsrc),
        radius=p.radius * (apex * R + D) / D,
        location=table.lens_center + (apex * R)[:, None] * axis,
        direction=axis,
        color=_physical_color(table, p),
        scale_xy=np.ones(nsrc),
        cone_half_angle_deg=np.full(nsrc, 90.0),
        cutoff_distance=CUTOFF_FACTOR * (R + scene_size),
        reference_irradiance=irradiance,
        relative_brightness=_relative(irradiance, I0 / D**2),
        _note_parts=[_nonfull_note(unblocked, full), lambda t: cycles],
        profile_info=info,
    )


# --------------------------------------------------------------------------- .bi scenes


def bi_scene_light_table(
    arrays, table: SourceTable, model: str, light_radius: np.ndarray | None = None
) -> LightTable:
    """The lights `./lens-lights phase1` reports for a `.bi` scene (`arrays`: its
    `phase1.SceneArrays`), with the import's conventions (`scripts/cli.py`'s
    `blender_lights`): a light of brightness b is b × 10 000 W of the file's
    colour, a lens's transmission weight is its kt, the scene's bounds are those
    of its lights and spheres (radius taken as |r|)."""
    from .bi_conversions import watts_from_brightness

    j, i = table.light, table.lens
    radius = np.zeros(len(arrays.light_brightness)) if light_radius is None else light_radius
    primaries = Primaries(
        power_w=arrays.light_brightness[j] * watts_from_brightness(1.0),
        radius=np.asarray(radius, dtype=float)[j],
        color=arrays.light_color[j],
        transmission_weight=arrays.kt[i],
    )
    r = np.abs(arrays.radius)[:, None]
    pts = np.concatenate([arrays.light_position, arrays.center - r, arrays.center + r])
    bounds, size = None, 1.0
    if pts.size:
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        if np.all(np.isfinite(lo)) and np.all(np.isfinite(hi)):
            bounds = (tuple(lo.tolist()), tuple(hi.tolist()))
            size = float(np.linalg.norm(hi - lo)) or 1.0
    return make_light_table(table, primaries, model.upper(), scene_size=size, scene_bounds=bounds)
