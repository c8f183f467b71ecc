"""FITTED (EEVEE and Cycles): one spot on the lens's axis fitted to the exact
beam (:mod:`.spot_fit`), its own position, energy, cone and blend (the
``spot_blend`` setting does not apply).

The optimum depends only on ``D/R`` and ``n``, so it is precomputed
(``bench/make_fitted_table.py`` → ``fitted_table.json`` beside this module, read
once on first use) on a grid over ``x = R/D`` (0 = a sun … 0.95) and ``n``
(1.2 … 2.0) and looked up by bilinear interpolation (microseconds per source).
The table stores dimensionless quantities that stay finite for a sun and across
collimation (:meth:`.spot_fit.SpotFit.invariants`): ``w = R/d`` with ``d`` the
apex's distance before the first receiver (``1.5 R`` behind the centre), the
spot's on-axis irradiance there relative to the primary's at the lens, the
cone's radius there, and the blend.
"""

from __future__ import annotations

import functools
import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..lens.glass import LensOptics
from ..scene.primaries import PrimaryLight
from .base import (
    COLLIMATED_DISTANCE_FACTOR,
    CUTOFF_FACTOR,
    CYCLES,
    EEVEE,
    SPOT,
    Accuracy,
    BlenderLight,
    LightTable,
    Primaries,
    Tier,
    axial_light_common,
    cone_shape,
    cone_shapes,
    glass_colors,
    lens_light_radii,
    lens_light_radius,
    non_full_notes,
    relative_brightness,
    unblocked_columns,
    unit_rows,
)
from .near_field import APEX_CLEARANCE, NEAR_FIELD, is_near, receiver_fit
from .spot_fit import (
    FIRST_RECEIVER,
    FIT_RECEIVERS,
    SUN_DISTANCE,
    SpotFit,
    fit_spot,
    from_invariants,
)

NAME = "FITTED"

#: The grid of the table: x = R/D (rows) and the index of refraction (columns).
TABLE_X = tuple(
    float(x) for x in np.round(np.concatenate([[0.0, 0.02], np.arange(0.05, 0.951, 0.05)]), 4)
)
TABLE_N = (1.2, 1.3, 1.4, 1.5, 1.6, 1.7, 1.8, 1.9, 2.0)
#: Written by bench/make_fitted_table.py: {"x", "n", and per quantity a row per x}.
TABLE_FILE = Path(__file__).with_name("fitted_table.json")
TABLE_COLUMNS = ("W", "E", "RCONE", "BLEND", "L1")


@dataclass(frozen=True)
class FittedTable:
    """Rows: x = R/D (``X``), columns: n (``N``). ``W = R/d``, ``E`` = on-axis
    irradiance at the first receiver / the primary's irradiance at the lens
    centre, ``RCONE`` = cone radius there (R), ``BLEND`` = spot_blend, ``L1`` =
    the fit's mean L1 error over ``FIT_RECEIVERS``."""

    X: np.ndarray
    N: np.ndarray
    W: np.ndarray
    E: np.ndarray
    RCONE: np.ndarray
    BLEND: np.ndarray
    L1: np.ndarray


@functools.cache
def fitted_table() -> FittedTable:
    """The shipped table (read once)."""
    data = json.loads(TABLE_FILE.read_text(encoding="utf-8"))
    return FittedTable(*(np.asarray(data[k], dtype=float) for k in ("X", "N", *TABLE_COLUMNS)))


def fitted_spot(D_over_R: float, n: float) -> tuple[SpotFit, str]:
    """The fitted spot for a lens seen from ``D/R`` with index ``n``, interpolated
    from the shipped table (bilinear in ``x = R/D`` and ``n``, on the invariants
    ``w``, ``log e``, ``log r``, ``blend``; one row of :func:`fitted_spots`).
    Returns the fit and a note ("" or what was clamped)."""
    s = fitted_spots(np.asarray([D_over_R], dtype=float), np.asarray([n], dtype=float))
    fit = SpotFit(
        apex=float(s.apex[0]),
        intensity=float(s.intensity[0]),
        half_angle_deg=float(s.half_angle_deg[0]),
        blend=float(s.blend[0]),
    )
    return fit, s.note(0)


@dataclass
class FittedSpots:
    """:class:`.spot_fit.SpotFit` columns (R = 1, primary intensity 1) from the
    shipped table, with what was clamped (`note`)."""

    apex: np.ndarray
    intensity: np.ndarray
    half_angle_deg: np.ndarray
    blend: np.ndarray
    D_over_R: np.ndarray  # as looked up (inf: a sun)
    n: np.ndarray  # as asked
    x_clamped: np.ndarray  # bool: nearer than the table's last row
    n_clamped: np.ndarray  # bool: index outside the table's columns

    def note(self, t: int) -> str:
        xs, ns = fitted_table().X, fitted_table().N
        parts = []
        if self.x_clamped[t]:
            parts.append(
                f"light at {float(self.D_over_R[t]):.4g} R: nearer than the table's "
                f"{1 / xs[-1]:.4g} R, clamped"
            )
        if self.n_clamped[t]:
            parts.append(
                f"n = {float(self.n[t]):.4g} outside the table's {ns[0]:g}–{ns[-1]:g}, clamped"
            )
        return "; ".join(parts)


def fitted_spots(D_over_R: np.ndarray, n: np.ndarray) -> FittedSpots:
    """:func:`fitted_spot` of every ``(D/R, n)`` of two arrays."""
    t = fitted_table()
    xs, ns = np.asarray(t.X), np.asarray(t.N)
    n_asked = np.asarray(n, dtype=float)
    with np.errstate(divide="ignore"):
        x = np.where(np.isfinite(D_over_R), 1.0 / D_over_R, 0.0)
    DR = np.where(x == 0.0, math.inf, D_over_R)
    x_clamped = x > xs[-1]
    x = np.where(x_clamped, xs[-1], x)
    n_clamped = ~((ns[0] <= n_asked) & (n_asked <= ns[-1]))
    n = np.clip(n_asked, ns[0], ns[-1])
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

    apex, intensity, half = from_invariants(
        np.where(np.isfinite(DR), DR, SUN_DISTANCE),
        lerp(np.asarray(t.W)),
        np.exp(lerp(np.log(np.asarray(t.E)))),
        np.exp(lerp(np.log(np.asarray(t.RCONE)))),
    )
    return FittedSpots(
        apex, intensity, half, lerp(np.asarray(t.BLEND)), DR, n_asked, x_clamped, n_clamped
    )


def pull_in(fit: SpotFit, max_behind: float) -> SpotFit:
    """``fit`` with its apex at most ``max_behind`` (in R) behind the back pole
    (a nearly collimated beam's fitted spot may sit up to 1000 R behind the lens,
    where other geometry could block it): the cone keeps its radius at the first
    receiver and the on-axis irradiance at the middle fit receiver is kept
    (one row of :func:`pull_in_columns`)."""
    pulled, apex, intensity, half = pull_in_columns(
        np.asarray([fit.apex]),
        np.asarray([fit.intensity]),
        np.asarray([fit.half_angle_deg]),
        np.asarray([max_behind], dtype=float),
    )
    if not pulled[0]:
        return fit
    return SpotFit(
        apex=float(apex[0]),
        intensity=float(intensity[0]),
        half_angle_deg=float(half[0]),
        blend=fit.blend,
        l1=float("nan"),
    )


def pull_in_columns(apex, intensity, half_angle_deg, max_behind):
    """:func:`pull_in` on columns: (pulled, apex, intensity, half_angle_deg)."""
    pulled = ((1.0 - apex) > max_behind) & (max_behind > 0.0)
    new_apex = 1.0 - max_behind
    d_old, d_new = 1.0 + FIRST_RECEIVER - apex, 1.0 + FIRST_RECEIVER - new_apex
    r = d_old * np.tan(np.radians(half_angle_deg))
    z_ref = 1.0 + FIT_RECEIVERS[len(FIT_RECEIVERS) // 2]
    k = intensity * ((z_ref - new_apex) / (z_ref - apex)) ** 2
    return (
        pulled,
        np.where(pulled, new_apex, apex),
        np.where(pulled, k, intensity),
        np.where(pulled, np.degrees(np.arctan2(r, d_new)), half_angle_deg),
    )


def make_fitted_light(
    source,
    primary: PrimaryLight,
    *,
    optics: LensOptics | None = None,
    scene_size: float = 1.0,
    direct: bool = False,
    collimated_distance: float | None = None,
    receiver_distance: float | None = None,
    **_ignored,
) -> BlenderLight:
    """The FITTED tier's Blender light for ``source``: a spot on the lens's axis at
    ``lens_center + apex R axis``, shining along the axis.  ``direct``: fit now
    (about 0.3 s) instead of interpolating the shipped table.  Energy: the fit's
    intensity ratio × the primary's power × the material's transmission weight²
    × the unblocked share; colour as PHYSICAL (tint², absorption over 2R).
    ``collimated_distance``: how far behind the back vertex a spot may sit (None:
    no limit; :func:`make_light` passes the operator's free
    distance, else ``COLLIMATED_DISTANCE_FACTOR`` × the scene's size, as for the
    other tiers' beams); a fitted apex farther behind (up to 1000 R for a nearly
    collimated beam) is pulled in (:func:`pull_in`), noted.
    ``receiver_distance``: how far from the lens centre along the axis the first
    surface behind the lens lies (None: unknown); a near one (or one the fitted
    apex would sit behind) gets a spot fitted to that receiver, its apex before
    it, often inside the lens (:mod:`.near_field`)."""
    axis, R, D, scale, color, notes = axial_light_common(source, primary, optics)
    if direct:
        fit = fit_spot(D / R, float(source.ior))
    else:
        fit, note = fitted_spot(D / R, float(source.ior))
        if note:
            notes.append(note)
    if collimated_distance:
        pulled = pull_in(fit, float(collimated_distance) / R)
        if pulled is not fit:
            notes.append(
                f"spot pulled in from {(1.0 - fit.apex) * R:.4g} to "
                f"{(1.0 - pulled.apex) * R:.4g} behind the back vertex "
                "(geometry behind the lens)"
            )
            fit = pulled
    z_recv = float(receiver_distance) / R if receiver_distance else None
    if is_near(z_recv, fit.apex):
        fit = receiver_fit(round(D / R, 6), round(float(source.ior), 6), round(z_recv, 3))
        notes.append(f"near field: fitted to the receiver {z_recv:.4g} R from the lens centre")
    shape = cone_shape(fit.half_angle_deg)
    if shape.note:
        notes.append(shape.note)
    center = np.asarray(source.lens_center, dtype=float)
    location = center + fit.apex * R * axis
    reach = abs(fit.apex) * R + float(scene_size or 1.0)
    energy = primary.power_w * fit.intensity * scale
    d_ref = (1.0 + FIRST_RECEIVER - fit.apex) * R
    irradiance = primary.intensity * fit.intensity * scale / d_ref**2
    primary_irr = primary.intensity / D**2
    return BlenderLight(
        type=SPOT,
        energy_w=float(energy),
        spot_size_deg=float(shape.spot_size_deg),
        spot_blend=float(min(max(fit.blend, 0.0), 1.0)),
        radius=float(lens_light_radius(source, primary, scene_size, receiver_distance)),
        location=tuple(float(v) for v in location),
        direction=tuple(float(v) for v in axis),
        note="; ".join(notes),
        color=color,
        scale_xy=float(shape.scale_xy),
        cone_half_angle_deg=float(shape.half_angle_deg),
        cutoff_distance=float(CUTOFF_FACTOR * reach),
        kind=source.kind,
        model=NAME,
        reference_irradiance=float(irradiance),
        relative_brightness=float(irradiance / primary_irr) if primary_irr > 0 else 0.0,
        inside_lens=bool(fit.apex < 1.0),
    )


def make_light(
    source,
    primary,
    *,
    optics=None,
    scene_size=1.0,
    collimated_distance=None,
    receiver_distance=None,
    **_ignored,
):
    """The registry's maker: a fitted spot stays within the beams' distance
    behind the lens (the operator's free distance, else the default) and before
    the receiver (`receiver_distance`)."""
    return make_fitted_light(
        source,
        primary,
        optics=optics,
        scene_size=scene_size,
        collimated_distance=collimated_distance or COLLIMATED_DISTANCE_FACTOR * scene_size,
        receiver_distance=receiver_distance,
    )


def make_table(
    table,
    p: Primaries,
    *,
    scene_size: float = 1.0,
    collimated_distance=None,
    receiver_distance=None,
    near_fits: bool = True,
    **_ignored,
) -> LightTable:
    """:func:`make_light` for every source of a `phase1.SourceTable` at once.
    `collimated_distance`: a number or one per source (None or 0: the default);
    `receiver_distance`: None (no receiver known: no near-field fits) or one per
    source (NaN: unknown), the near-field rows fitted one distinct geometry at a
    time (:func:`.near_field.receiver_fit`, remembered). ``near_fits=False``: the
    receivers' distances without those fits (live update's coarse Caustic layer,
    whose spots only rank its sources: the fits cost ~60 ms per new geometry)."""
    axis = unit_rows(table.axis)
    R, D = table.lens_radius, table.distance
    unblocked, full = unblocked_columns(table)
    scale = np.clip(p.transmission_weight, 0.0, 1.0) ** 2 * unblocked
    spots = fitted_spots(D / R, table.ior)
    default = COLLIMATED_DISTANCE_FACTOR * scene_size
    far = (
        default
        if collimated_distance is None
        else np.where(
            np.asarray(collimated_distance, dtype=float) == 0.0, default, collimated_distance
        )
    )
    pulled, apex, intensity, half = pull_in_columns(
        spots.apex, spots.intensity, spots.half_angle_deg, far / R
    )
    pulled_apex, blend = apex, spots.blend
    z_recv = np.full(len(table), np.nan)
    near = np.zeros(len(table), dtype=bool)
    if receiver_distance is not None:
        rd = np.asarray(receiver_distance, dtype=float)
        z_recv = np.where(rd != 0.0, rd / R, np.nan)
        with np.errstate(invalid="ignore"):
            near = np.isfinite(z_recv) & ((z_recv <= NEAR_FIELD) | (apex > z_recv - APEX_CLEARANCE))
        near &= near_fits
        if near.any():
            apex, intensity, half, blend = (
                np.array(x, dtype=float) for x in (apex, intensity, half, blend)
            )
            DR, n = D / R, table.ior
            for t in np.flatnonzero(near).tolist():
                fit = receiver_fit(
                    round(float(DR[t]), 6), round(float(n[t]), 6), round(float(z_recv[t]), 3)
                )
                apex[t], intensity[t] = fit.apex, fit.intensity
                half[t], blend[t] = fit.half_angle_deg, fit.blend

    def pull_note(t):
        return (
            ""
            if not pulled[t]
            else f"spot pulled in from {float((1.0 - spots.apex[t]) * R[t]):.4g} to "
            f"{float((1.0 - pulled_apex[t]) * R[t]):.4g} behind the back vertex "
            "(geometry behind the lens)"
        )

    def near_note(t):
        return (
            f"near field: fitted to the receiver {float(z_recv[t]):.4g} R from the lens centre"
            if near[t]
            else ""
        )

    shape = cone_shapes(half)
    d_ref = (1.0 + FIRST_RECEIVER - apex) * R
    irradiance = p.intensity * intensity * scale / d_ref**2
    return LightTable(
        model=NAME,
        kind=table.kind,
        energy_w=p.power_w * intensity * scale,
        spot_size_deg=shape.spot_size_deg,
        spot_blend=np.clip(blend, 0.0, 1.0),
        radius=lens_light_radii(
            p.radius,
            D,
            table.vergence,
            scene_size,
            math.nan if receiver_distance is None else receiver_distance,
        ),
        location=table.lens_center + (apex * R)[:, None] * axis,
        direction=axis,
        color=glass_colors(R, p.color, p.tint, p.absorption),
        scale_xy=shape.scale_xy,
        cone_half_angle_deg=shape.half_angle_deg,
        cutoff_distance=CUTOFF_FACTOR * (np.abs(apex) * R + float(scene_size or 1.0)),
        reference_irradiance=irradiance,
        relative_brightness=relative_brightness(irradiance, p.intensity / D**2),
        inside_lens=apex < 1.0,
        note_parts=[non_full_notes(unblocked, full), spots.note, pull_note, near_note, shape.note],
    )


ACCURACY = Accuracy(0.50, 0.79)
TIER = Tier(
    name=NAME,
    label="Fitted",
    description=(
        "One spot fitted to the exact beam: EEVEE and Cycles; its own cone and blend "
        f"(relative L1 error {ACCURACY.l1_mean:.2f} for D ≥ 2R)"
    ),
    trades="One spot fitted to the exact beam; cannot converge to the focus (EEVEE-safe)",
    engines=(EEVEE, CYCLES),
    accuracy=ACCURACY,
    number=2,
    make=make_light,
    make_table=make_table,
)
