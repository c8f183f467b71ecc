"""The lens-light tiers beyond THESIS and PHYSICAL: FITTED and EXACT_PROFILE.

Both take what :func:`.light_models.make_blender_light` takes (a
:class:`.phase1.SecondarySource`, a :class:`.light_models.PrimaryLight`, the
lens's :class:`.light_models.LensOptics`, the scene's size) and return a
:class:`.light_models.BlenderLight` (EXACT_PROFILE: a :class:`ProfileLight`, the
same plus the profile table).  Pure numpy.

FITTED (EEVEE and Cycles)
    One spot light on the lens's axis whose position, energy, cone and blend
    minimise the relative L1 error of the irradiance (:mod:`.accuracy`) against
    the exact optics, averaged over receivers 0.5 R to 10 R behind the sphere
    (``FIT_RECEIVERS``).  The optimum depends only on ``D/R`` and ``n``, so it is
    precomputed (``bench/make_fitted_table.py`` → ``addon/fitted_table.py``) on a
    grid over ``x = R/D`` (0 = a sun … 0.95) and ``n`` (1.2 … 2.0) and looked up by
    bilinear interpolation (microseconds per source).  The table stores
    dimensionless quantities that stay finite for a sun and across collimation
    (:meth:`SpotFit.invariants`): ``w = R/d`` with ``d`` the apex's distance
    before the first receiver (``1.5 R`` behind the centre), the spot's on-axis
    irradiance there relative to the primary's at the lens, the cone's radius
    there, and the blend.
    :func:`fit_spot` is the direct fit (about 0.3 s), used to make the table.

    A point-like light can only make a beam that widens with distance; the true
    beam converges to a focus first (and has a bright core in a wide halo).  No
    spot can reproduce that: the error is what the fit trades for working in
    EEVEE.

EXACT_PROFILE (Cycles only: it needs a light node tree)
    The exact beam, tabulated.  A spot light (``spot_size`` 180°, blend 0) just
    behind the back pole whose intensity is a table over the angle ``gamma`` from
    the axis *and* the distance ``h`` along the axis from the light, read in the
    light's node tree (Cycles gives a light shader the distance to the shading
    point: Light Path ▸ Ray Length).  With ``I(gamma, h) = E(h tan gamma; h) h^2 /
    cos^3 gamma`` the light puts on every plane perpendicular to the axis the exact
    irradiance (to the table's resolution), including the converging part and the
    focus.  Beyond the table's last distance the intensity tends to the beam's
    far-field profile, which is exact for a far receiver whatever the apex.  The
    table is computed per source from the exact trace (about 0.25 s; remembered
    per ``(D/R, n)``).

    It also carries a one-dimensional angular profile (``angular``): the best
    distance-independent profile about its own apex (a per-angle weighted median
    over the receivers, which minimises the L1 error averaged over them): usable
    as an IES file or a Float Curve where a 2-D table is not wanted; it cannot
    converge either, and the report measures it too.

What the Blender side builds for a :class:`ProfileLight` is described in
:data:`NODE_TREE_RECIPE` (and in the bench report).
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np

from . import accuracy as acc
from .light_models import (CUTOFF_FACTOR, SPOT, BlenderLight, LensOptics, PhysicalModel,
                           PrimaryLight, cone_shape)
from .spot_irradiance import one_minus_cos_of_radius, spot_mask_integral

__all__ = [
    "FITTED", "EXACT_PROFILE", "TIER_LINES", "FIT_RECEIVERS", "FIRST_RECEIVER",
    "SpotFit", "fit_spot", "fitted_spot", "make_fitted_light",
    "BeamProfile", "exact_profile", "ProfileLight", "make_profile_light",
    "make_tier_light", "profile_model", "pull_in", "NODE_TREE_RECIPE",
]

FITTED, EXACT_PROFILE = "FITTED", "EXACT_PROFILE"

#: One line per tier on what it trades (for the panel).
TIER_LINES = {
    "THESIS": "Thesis eq. 5.22: paraxial cone, no flux concentration; far off for distant lights",
    "PHYSICAL": "Paraxial cone with the exact on-axis intensity; misses the halo and the near beam",
    FITTED: "One spot fitted to the exact beam; cannot converge to the focus (EEVEE-safe)",
    EXACT_PROFILE: "Exact beam tabulated over angle and distance; Cycles only (light nodes)",
}

#: Receivers the fit averages over, in R behind the back pole.
FIT_RECEIVERS = tuple(float(x) for x in np.geomspace(0.5, 10.0, 9))
#: The first receiver (R behind the back pole): the fitted apex stays before it.
FIRST_RECEIVER = 0.5
#: Range of the fitted table and of the index of refraction it covers.
TABLE_X = tuple(float(x) for x in np.round(np.concatenate([[0.0, 0.02], np.arange(0.05, 0.951, 0.05)]), 4))
TABLE_N = (1.2, 1.3, 1.4, 1.5, 1.6, 1.7, 1.8, 1.9, 2.0)
#: The sun (x = 0) is fitted with the light this far away (in R).
SUN_DISTANCE = 1e6
#: Bounds of the fitted spot: its apex at most this far (R) before the first
#: receiver, its half-angle at least this (degrees).
FIT_MAX_DISTANCE = 1e3
FIT_MIN_HALF_ANGLE_DEG = 0.01


# ---------------------------------------------------------------------------
# FITTED: one spot
# ---------------------------------------------------------------------------

@dataclass(frozen=True)
class SpotFit:
    """A spot light on the axis, dimensionless (lens radius 1, primary intensity 1).

    ``apex``: position from the lens centre along the axis (R); ``intensity``:
    spot intensity / primary intensity (the spot's energy is this times the
    primary's power); ``half_angle_deg``: half the spot size; ``blend``;
    ``l1``: the fit's objective (mean L1 over ``FIT_RECEIVERS``; NaN when
    interpolated from the table).
    """

    apex: float
    intensity: float
    half_angle_deg: float
    blend: float
    l1: float = float("nan")

    # The table's collimation-proof coordinates (see the module docstring).
    def invariants(self, D_over_R: float) -> tuple[float, float, float, float]:
        """``(w, e, r, blend)``: ``w = R/d`` (``d``: apex to the first receiver),
        ``e``: the spot's on-axis irradiance at the first receiver relative to
        the primary's irradiance at the lens centre, ``k (D/d)^2``; ``r``: the
        cone's radius there, ``d tan H`` (R).  All finite for a sun and for a
        collimated beam."""
        d = 1.0 + FIRST_RECEIVER - self.apex
        return (1.0 / d, self.intensity * (D_over_R / d) ** 2,
                d * math.tan(math.radians(self.half_angle_deg)), self.blend)

    @classmethod
    def from_invariants(cls, D_over_R, w, e, r, b, l1=float("nan")) -> "SpotFit":
        d = 1.0 / w
        return cls(apex=1.0 + FIRST_RECEIVER - d, intensity=e * (d / D_over_R) ** 2,
                   half_angle_deg=math.degrees(math.atan2(r, d)), blend=b, l1=l1)

    def model(self, R=1.0, I0=1.0) -> acc.AxialSpot:
        return acc.AxialSpot(apex=self.apex * R, intensity=self.intensity * I0,
                             half_angle=math.radians(self.half_angle_deg), blend=self.blend)


class _SpotObjective:
    """Mean L1 over receivers of a spot against the exact beam (R = 1, I0 = 1),
    with the truth's ring fluxes computed once."""

    def __init__(self, beam: acc.ExactBeam, receivers=FIT_RECEIVERS, n_uniform=150, n_log=40):
        self.Z = np.array([beam.plane(s) for s in receivers])
        self.edges, self.true, self.total = [], [], []
        for Z in self.Z:
            e = acc.ring_edges(beam.shadow_radius(Z), n_uniform, n_log)
            f = beam.flux_within_radius(Z, e)
            self.edges.append(e)
            self.true.append(np.diff(f))
            self.total.append(f[-1] - f[0])
        self.evaluations = 0

    def l1(self, apex, k, H, b) -> np.ndarray:
        out = np.empty(self.Z.size)
        for j, Z in enumerate(self.Z):
            h = Z - apex
            if not h > 0.0:
                out[j] = 1.0
                continue
            f = 2.0 * math.pi * k * spot_mask_integral(one_minus_cos_of_radius(h, self.edges[j]), H, b)
            out[j] = np.sum(np.abs(np.diff(f) - self.true[j])) / self.total[j]
        return out

    @staticmethod
    def unpack(x):
        """Optimiser coordinates → (apex, k, H rad, blend): ``x = (log d, log e,
        log r, blend)`` with the invariants of :class:`SpotFit` (``e`` here
        without the factor ``D^2``).  ``d`` is kept within ``[1e-3, FIT_MAX_DISTANCE]``
        R and ``H`` within ``[FIT_MIN_HALF_ANGLE, 90°]``: a nearly collimated beam
        is as well served by a spot 1000 R away as by one farther, and the cone
        must stay one Blender can make (see :func:`.light_models.cone_shape`)."""
        d = min(max(math.exp(x[0]), 1e-3), FIT_MAX_DISTANCE)
        e, r = math.exp(x[1]), math.exp(x[2])
        H = min(max(math.atan2(r, d), math.radians(FIT_MIN_HALF_ANGLE_DEG)), 0.5 * math.pi)
        return 1.0 + FIRST_RECEIVER - d, e * d * d, H, min(max(x[3], 0.0), 1.0)

    def __call__(self, x) -> float:
        self.evaluations += 1
        if not all(math.isfinite(v) for v in x) or abs(x[0]) > 40 or abs(x[1]) > 80 or abs(x[2]) > 40:
            return 10.0
        return float(np.mean(self.l1(*self.unpack(x))))


def _nelder_mead(f, x0, step, max_iter=500, ftol=1e-5):
    """Plain Nelder–Mead (standard coefficients), minimising ``f`` from ``x0``."""
    n = len(x0)
    X = [np.asarray(x0, dtype=float)]
    for i in range(n):
        x = np.array(x0, dtype=float)
        x[i] += step[i]
        X.append(x)
    F = [f(x) for x in X]
    for _ in range(max_iter):
        order = np.argsort(F)
        X = [X[i] for i in order]
        F = [F[i] for i in order]
        if F[-1] - F[0] <= ftol * max(1.0, abs(F[0])):
            break
        c = np.mean(X[:-1], axis=0)
        xr = c + (c - X[-1])
        fr = f(xr)
        if fr < F[0]:
            xe = c + 2.0 * (c - X[-1])
            fe = f(xe)
            X[-1], F[-1] = (xe, fe) if fe < fr else (xr, fr)
        elif fr < F[-2]:
            X[-1], F[-1] = xr, fr
        else:
            xc = c + 0.5 * ((xr if fr < F[-1] else X[-1]) - c)
            fc = f(xc)
            if fc < min(fr, F[-1]):
                X[-1], F[-1] = xc, fc
            else:
                for i in range(1, n + 1):
                    X[i] = X[0] + 0.5 * (X[i] - X[0])
                    F[i] = f(X[i])
    i = int(np.argmin(F))
    return X[i], F[i]


def fit_spot(D_over_R: float, n: float, receivers=FIT_RECEIVERS, n_fan: int = 8000) -> SpotFit:
    """The direct fit of one spot to the exact beam (R = 1, primary intensity 1).

    A coarse search over the apex (17 distances before the first receiver, up
    to 1000 R for nearly collimated beams), the cone (7 half-angles) and the blend
    (3 values), with the energy that matches the flux in the middle receiver's
    shadow disc, then Nelder–Mead from the eight best starts in the coordinates
    of :class:`SpotFit`'s invariants.
    """
    D = float(D_over_R)
    beam = acc.ExactBeam(1.0, D, 1.0, n, n_fan=n_fan)
    ob = _SpotObjective(beam, receivers)
    mid = len(ob.Z) // 2
    starts = []
    z0 = 1.0 + FIRST_RECEIVER
    for d in np.concatenate([np.geomspace(0.03, z0 + min(D, 30.0), 14), [1e2, 3e2, 1e3]]):
        h = ob.Z[mid] - (z0 - d)
        q = one_minus_cos_of_radius(h, ob.edges[mid][-1])
        for H_deg in (2.0, 5.0, 10.0, 20.0, 35.0, 55.0, 80.0):
            H = math.radians(H_deg)
            for b in (0.2, 0.6, 1.0):
                A = float(spot_mask_integral(q, H, b))
                if not A > 0.0:
                    continue
                k = ob.total[mid] / (2.0 * math.pi * A)
                x = np.array([math.log(d), math.log(k / (d * d)), math.log(d * math.tan(H)), b])
                starts.append((ob(x), x))
    starts.sort(key=lambda s: s[0])
    best_x, best_f = None, math.inf
    for _, x0 in starts[:8]:
        x, fx = _nelder_mead(ob, x0, [0.3, 0.3, 0.3, 0.2])
        if fx < best_f:
            best_x, best_f = x, fx
    apex, k, H, b = ob.unpack(best_x)
    return SpotFit(apex=apex, intensity=k, half_angle_deg=math.degrees(H), blend=b, l1=best_f)


def _table():
    from . import fitted_table as t          # generated by bench/make_fitted_table.py
    return t


def fitted_spot(D_over_R: float, n: float) -> tuple[SpotFit, str]:
    """The fitted spot for a lens seen from ``D/R`` with index ``n``, interpolated
    from the shipped table (bilinear in ``x = R/D`` and ``n``, on the invariants
    ``w``, ``log e``, ``log r``, ``blend``).  Returns the fit and a note ("" or
    what was clamped)."""
    t = _table()
    xs, ns = np.asarray(t.X), np.asarray(t.N)
    x = 0.0 if not math.isfinite(D_over_R) else 1.0 / float(D_over_R)
    D_over_R = math.inf if x == 0.0 else float(D_over_R)
    note = []
    if x > xs[-1]:
        note.append(f"light at {D_over_R:.4g} R: nearer than the table's {1 / xs[-1]:.4g} R, clamped")
        x = xs[-1]
    if not ns[0] <= n <= ns[-1]:
        note.append(f"n = {n:.4g} outside the table's {ns[0]:g}–{ns[-1]:g}, clamped")
        n = min(max(n, ns[0]), ns[-1])
    i = int(np.clip(np.searchsorted(xs, x, side="right") - 1, 0, xs.size - 2))
    j = int(np.clip(np.searchsorted(ns, n, side="right") - 1, 0, ns.size - 2))
    u = (x - xs[i]) / (xs[i + 1] - xs[i])
    v = (n - ns[j]) / (ns[j + 1] - ns[j])
    W = np.asarray(t.W)
    LE, LR, B = np.log(np.asarray(t.E)), np.log(np.asarray(t.RCONE)), np.asarray(t.BLEND)

    def lerp(A):
        return ((1 - u) * (1 - v) * A[i, j] + u * (1 - v) * A[i + 1, j]
                + (1 - u) * v * A[i, j + 1] + u * v * A[i + 1, j + 1])
    fit = SpotFit.from_invariants(D_over_R if math.isfinite(D_over_R) else SUN_DISTANCE, lerp(W),
                                  math.exp(lerp(LE)), math.exp(lerp(LR)), lerp(B))
    return fit, "; ".join(note)


def _common(source, primary: PrimaryLight, optics: LensOptics | None):
    optics = optics or LensOptics()
    axis = np.asarray(source.axis, dtype=float)
    axis = axis / np.linalg.norm(axis)
    R, D = float(source.lens_radius), float(source.distance)
    wgt = min(max(optics.transmission_weight, 0.0), 1.0)
    unblocked = min(max(float(source.unblocked_fraction), 0.0), 1.0)
    color = PhysicalModel().color(source, primary, optics)
    notes = [] if source.full else [f"non-full: energy × {unblocked:.4g} (unblocked share of the lit cap)"]
    return axis, R, D, wgt * wgt * unblocked, color, notes


def pull_in(fit: SpotFit, max_behind: float) -> SpotFit:
    """``fit`` with its apex at most ``max_behind`` (in R) behind the back pole
    (a nearly collimated beam's fitted spot may sit up to 1000 R behind the lens,
    where other geometry could block it): the cone keeps its radius at the first
    receiver and the on-axis irradiance at the middle fit receiver is kept."""
    if not (1.0 - fit.apex) > max_behind or not max_behind > 0.0:
        return fit
    apex = 1.0 - max_behind
    d_old, d_new = 1.0 + FIRST_RECEIVER - fit.apex, 1.0 + FIRST_RECEIVER - apex
    r = d_old * math.tan(math.radians(fit.half_angle_deg))
    z_ref = 1.0 + FIT_RECEIVERS[len(FIT_RECEIVERS) // 2]
    k = fit.intensity * ((z_ref - apex) / (z_ref - fit.apex)) ** 2
    return SpotFit(apex=apex, intensity=k, half_angle_deg=math.degrees(math.atan2(r, d_new)),
                   blend=fit.blend, l1=float("nan"))


def make_fitted_light(source, primary: PrimaryLight, *, optics: LensOptics | None = None,
                      scene_size: float = 1.0, direct: bool = False,
                      collimated_distance: float | None = None, **_ignored) -> BlenderLight:
    """The FITTED tier's Blender light for ``source``: a spot on the lens's axis at
    ``lens_center + apex R axis``, shining along the axis.  ``direct``: fit now
    (about 0.3 s) instead of interpolating the shipped table.  Energy: the fit's
    intensity ratio × the primary's power × the material's transmission weight²
    × the unblocked share; colour as PHYSICAL (tint², absorption over 2R).
    ``collimated_distance``: how far behind the back vertex a spot may sit (None:
    no limit; :func:`.light_models.make_blender_light` passes the operator's free
    distance, else ``COLLIMATED_DISTANCE_FACTOR`` × the scene's size, as for the
    other tiers' beams); a fitted apex farther behind (up to 1000 R for a nearly
    collimated beam) is pulled in (:func:`pull_in`), noted."""
    axis, R, D, scale, color, notes = _common(source, primary, optics)
    if direct:
        fit = fit_spot(D / R, float(source.ior))
    else:
        fit, note = fitted_spot(D / R, float(source.ior))
        if note:
            notes.append(note)
    if collimated_distance:
        pulled = pull_in(fit, float(collimated_distance) / R)
        if pulled is not fit:
            notes.append(f"spot pulled in from {(1.0 - fit.apex) * R:.4g} to "
                         f"{(1.0 - pulled.apex) * R:.4g} behind the back vertex (geometry behind the lens)")
            fit = pulled
    shape = cone_shape(fit.half_angle_deg)
    if shape.note:
        notes.append(shape.note)
    center = np.asarray(source.lens_center, dtype=float)
    location = center + fit.apex * R * axis
    reach = abs(fit.apex) * R + float(scene_size or 1.0)
    energy = primary.power_w * fit.intensity * scale
    d_ref = (1.0 + FIRST_RECEIVER - fit.apex) * R
    irradiance = primary.intensity * fit.intensity * scale / d_ref ** 2
    primary_irr = primary.intensity / D ** 2
    return BlenderLight(
        type=SPOT, energy_w=float(energy), spot_size_deg=float(shape.spot_size_deg),
        spot_blend=float(min(max(fit.blend, 0.0), 1.0)),
        radius=float(primary.radius * abs(fit.apex * R + D) / D),
        location=tuple(float(v) for v in location), direction=tuple(float(v) for v in axis),
        note="; ".join(notes), color=color, scale_xy=float(shape.scale_xy),
        cone_half_angle_deg=float(shape.half_angle_deg),
        cutoff_distance=float(CUTOFF_FACTOR * reach), kind=source.kind, model=FITTED,
        reference_irradiance=float(irradiance),
        relative_brightness=float(irradiance / primary_irr) if primary_irr > 0 else 0.0,
    )


# ---------------------------------------------------------------------------
# EXACT_PROFILE: the beam tabulated over angle and distance
# ---------------------------------------------------------------------------

#: Table size: angle columns, distance rows.
PROFILE_ANGLES = 256
PROFILE_DISTANCES = 256
#: The light sits this far (in R) behind the back pole; rows span these distances
#: (in R) from it, log-spaced.
PROFILE_OFFSET = 1e-3
PROFILE_H_MIN, PROFILE_H_MAX = 0.2, 30.0
#: Largest angle from the axis the table covers (degrees).
PROFILE_GAMMA_MAX_DEG = 90.0


@dataclass
class BeamProfile:
    """The exact beam as a light's intensity table (dimensionless: R = 1,
    primary intensity 1).

    ``apex``: the light's position from the lens centre (R).  Texel ``(i, j)``
    (angle column ``i`` of ``K``, distance row ``j`` of ``M``) sits at the texture
    coordinates ``u = (i + 0.5)/K``, ``v = (j + 0.5)/M``, i.e. at the angle
    ``gamma = gamma_max u^2`` and the distance along the axis
    ``h = h_min (h_max/h_min)^v`` from the light.  ``table[j, i]``: intensity
    (W/sr per W/sr of the primary) toward ``gamma`` for points at ``h``; the last
    column is 0 (so that clamping beyond ``gamma_max`` gives 0).
    ``angular``: the 1-D profile over the same angles about ``angular_apex``.
    """

    apex: float
    gamma_max_deg: float
    h_min: float
    h_max: float
    table: np.ndarray = field(repr=False)          # (M, K)
    flux: float = 0.0                              # the beam's flux (W per W/sr of the primary)
    angular_apex: float = 0.0
    angular: np.ndarray = field(default=None, repr=False)   # (K,)

    @property
    def angles_deg(self) -> np.ndarray:
        K = self.table.shape[1]
        u = (np.arange(K) + 0.5) / K
        return self.gamma_max_deg * u * u

    @property
    def distances(self) -> np.ndarray:
        M = self.table.shape[0]
        v = (np.arange(M) + 0.5) / M
        return self.h_min * (self.h_max / self.h_min) ** v

    def intensity_at(self, h: float) -> np.ndarray:
        """The angular profile (K values) the light has for points at distance
        ``h`` along the axis: linear in ``v`` between rows, clamped at the ends,
        as the image texture (linear interpolation, EXTEND) does."""
        M = self.table.shape[0]
        v = math.log(max(h, 1e-300) / self.h_min) / math.log(self.h_max / self.h_min)
        y = min(max(v * M - 0.5, 0.0), M - 1.0)
        j = min(int(y), M - 2)
        t = y - j
        return (1.0 - t) * self.table[j] + t * self.table[j + 1]


def _bin_intensity(rf: acc.ReceiverFlux, h: float, gamma_edges: np.ndarray) -> np.ndarray:
    """Mean intensity (flux / solid angle) in each angular bin about a point at
    distance ``h`` before the receiver."""
    flux = rf.flux_within_radius(h * np.tan(np.minimum(gamma_edges, 0.5 * np.pi - 1e-9)))
    omega = 2.0 * np.pi * 2.0 * np.sin(0.5 * gamma_edges) ** 2
    return np.diff(flux) / np.diff(omega)


def _profile_nodes(intensity_bins: np.ndarray) -> np.ndarray:
    """Bin means → node values at the bin centres (``angles_deg``); last node 0."""
    out = np.array(intensity_bins, dtype=float)
    out[-1] = 0.0
    return out


def exact_profile(D_over_R: float, n: float, absorption: float = 0.0, *, n_fan: int = 8000,
                  K: int = PROFILE_ANGLES, M: int = PROFILE_DISTANCES,
                  receivers=FIT_RECEIVERS) -> BeamProfile:
    """The EXACT_PROFILE table of a lens (R = 1, primary intensity 1)."""
    beam = acc.ExactBeam(1.0, float(D_over_R), 1.0, n, absorption, n_fan=n_fan)
    gmax = math.radians(PROFILE_GAMMA_MAX_DEG)
    u_edges = np.arange(K + 1) / K
    g_edges = gmax * u_edges * u_edges
    apex = 1.0 + PROFILE_OFFSET
    prof = BeamProfile(apex, PROFILE_GAMMA_MAX_DEG, PROFILE_H_MIN, PROFILE_H_MAX,
                       np.zeros((M, K)), flux=beam.lens_flux)
    for j, h in enumerate(prof.distances):
        rf = beam.receiver(apex + h)
        prof.table[j] = _profile_nodes(_bin_intensity(rf, h, g_edges))
    # 1-D profile: best apex among candidates, per-bin weighted median over receivers
    best = None
    z0 = 1.0 + FIRST_RECEIVER
    for d in np.geomspace(0.05, z0 + min(float(D_over_R), 30.0), 16):
        a = z0 - d
        rows, wts = [], []
        for s in receivers:
            Z = beam.plane(s)
            rf = beam.receiver(Z)
            h = Z - a
            rows.append(_bin_intensity(rf, h, g_edges))
            inside = np.arctan2(beam.shadow_radius(Z), h)
            tot = rf.flux_within_radius([beam.shadow_radius(Z)])[0]
            wts.append(np.where(g_edges[1:] <= inside + 1e-12, 1.0 / tot, 0.0))
        rows, wts = np.array(rows), np.array(wts)
        med = _weighted_median(rows, wts)
        omega = np.diff(2.0 * np.pi * 2.0 * np.sin(0.5 * g_edges) ** 2)
        cost = float(np.sum(wts * np.abs(rows - med[None, :]) * omega[None, :]))
        if best is None or cost < best[0]:
            best = (cost, a, med)
    prof.angular_apex = best[1]
    prof.angular = _profile_nodes(best[2])
    return prof


@functools.lru_cache(maxsize=128)
def _cached_profile(D_over_R: float, n: float) -> BeamProfile:
    """:func:`exact_profile`, remembered: a scene re-evaluated with unchanged
    lenses and lights (frame changes, re-runs) pays once.  Do not modify the
    returned table."""
    return exact_profile(D_over_R, n)


def _weighted_median(values: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """Column-wise weighted median of ``values`` (R, K) with ``weights`` (R, K);
    columns without weight get 0."""
    order = np.argsort(values, axis=0)
    v = np.take_along_axis(values, order, axis=0)
    w = np.take_along_axis(weights, order, axis=0)
    cw = np.cumsum(w, axis=0)
    half = 0.5 * cw[-1]
    idx = np.argmax(cw >= half[None, :], axis=0)
    out = v[idx, np.arange(values.shape[1])]
    return np.where(cw[-1] > 0.0, out, 0.0)


class _Profile2D:
    """Accuracy model of a :class:`BeamProfile` (the 2-D table) at scale ``R``,
    primary intensity ``I0``."""

    def __init__(self, prof: BeamProfile, R=1.0, I0=1.0):
        self.p, self.R, self.I0 = prof, R, I0
        self.g = np.concatenate([[0.0], np.radians(prof.angles_deg)])

    def flux_within_radius(self, Z, radii):
        h = Z / self.R - self.p.apex
        I = self.p.intensity_at(h)
        I = np.concatenate([[I[0]], I]) * self.I0
        return acc.AxialProfile(self.p.apex * self.R, self.g, I).flux_within_radius(Z, radii)


def profile_model(prof: BeamProfile, R=1.0, I0=1.0, angular: bool = False):
    """The :mod:`.accuracy` model of a profile: the 2-D table, or with
    ``angular`` the 1-D angular profile about its own apex."""
    if angular:
        g = np.concatenate([[0.0], np.radians(prof.angles_deg)])
        I = np.concatenate([[prof.angular[0]], prof.angular]) * I0
        return acc.AxialProfile(prof.angular_apex * R, g, I)
    return _Profile2D(prof, R, I0)


@dataclass
class ProfileLight(BlenderLight):
    """A :class:`.light_models.BlenderLight` plus the EXACT_PROFILE table (world
    units) for the light node tree; see :data:`NODE_TREE_RECIPE`.

    ``profile`` (the table, ``pixels`` and all) is made on first use (about 0.25 s
    per new ``(D/R, n)``, then remembered), so that planning many candidate lights
    (energy, brightness, ordering) costs only the exact trace (milliseconds);
    ``profile_info`` (its sizes and distances) is known at once."""

    profile_info: dict | None = None
    _profile: dict | None = field(default=None, repr=False)
    _profile_maker: object = field(default=None, repr=False, compare=False)

    @property
    def profile(self) -> dict | None:
        if self._profile is None and self._profile_maker is not None:
            self._profile = self._profile_maker()
        return self._profile

    def to_json(self) -> dict:
        out = super().to_json()
        if self.profile_info is not None:
            out["profile"] = dict(self.profile_info)
        return out


@functools.lru_cache(maxsize=1024)
def _beam_summary(D_over_R: float, n: float) -> tuple[float, float]:
    """(the beam's flux, its exact mean irradiance on the disc of ``PEAK_DISC`` R
    around the axis at the first receiver), per unit primary intensity, R = 1.
    The flux is the one :func:`exact_profile` records (same trace)."""
    beam = acc.ExactBeam(1.0, D_over_R, 1.0, n, n_fan=8000)
    Z = beam.plane(FIRST_RECEIVER)
    disc = acc.PEAK_DISC
    e = float(beam.flux_within_radius(Z, np.array([disc]))[0]) / (math.pi * disc * disc)
    return beam.lens_flux, e


def _profile_dict(prof: BeamProfile, t_ref: float, R: float, center, axis, key) -> dict:
    ang = prof.angular / t_ref
    return {
        "pixels": (prof.table / t_ref).astype(np.float32),   # (height, width), row 0 = v at the bottom
        "width": prof.table.shape[1], "height": prof.table.shape[0],
        "gamma_max_deg": prof.gamma_max_deg,
        "h_min": prof.h_min * R, "h_max": prof.h_max * R,    # world units
        "strength_scale": 1.0,
        "angles_deg": prof.angles_deg.tolist(),
        "angular_relative": ang.tolist(),                    # 1-D profile / (energy/4π), about angular_apex
        "angular_apex_location": tuple(float(v) for v in center + prof.angular_apex * R * axis),
        # Lights with equal keys have equal pixels (one image may serve them all);
        # None for a table passed in.
        "key": key,
    }


def make_profile_light(source, primary: PrimaryLight, *, optics: LensOptics | None = None,
                       scene_size: float = 1.0, profile: BeamProfile | None = None,
                       **_ignored) -> ProfileLight:
    """The EXACT_PROFILE tier's light: a 180° spot (blend 0) just behind the
    back pole, whose emission is ``energy/(4π) × texture(u, v)``
    (``profile["pixels"]``: float32, values from 0 to about 1e7 — the image must
    be a 32-bit float image, ``use_half_precision = False``).  ``energy_w`` is
    twice the beam's flux, so the light's nominal power (a 180° spot emits half
    its energy) is the beam's.  Distances in ``profile`` are in world units.
    ``reference_irradiance``: the exact mean irradiance on a disc of
    ``PEAK_DISC`` R around the axis at the first receiver (0.5 R behind the
    lens); ``relative_brightness`` that over the primary's at the lens."""
    axis, R, D, scale, color, notes = _common(source, primary, optics)
    n = float(source.ior)
    key = (round(D / R, 9), round(n, 9))
    flux, e_ref = _beam_summary(*key)
    if profile is not None:
        flux = profile.flux
    # Normalise so that the light's nominal power is the beam's: a 180° spot of
    # energy P emits P/2, so energy = 2 × beam flux and the texture holds the
    # intensity in units of energy/(4π) (values above 1 where the beam is
    # concentrated).  Cycles' light sampling then weighs this light by its real
    # power, not by the peak of its caustic.
    t_ref = flux / (2.0 * math.pi) if flux > 0 else 1.0
    I_ref = primary.intensity * t_ref * scale if flux > 0 else 0.0
    apex = profile.apex if profile is not None else 1.0 + PROFILE_OFFSET
    center = np.asarray(source.lens_center, dtype=float)
    location = center + apex * R * axis
    notes.append("Cycles only: intensity from the light node tree (EEVEE ignores it)")
    irradiance = primary.intensity * scale * e_ref / R ** 2
    primary_irr = primary.intensity / D ** 2
    if profile is not None:
        maker = functools.partial(_profile_dict, profile, t_ref, R, center, axis, None)
        shape = profile.table.shape
        info = (profile.gamma_max_deg, profile.h_min, profile.h_max)
    else:
        def maker():
            return _profile_dict(_cached_profile(*key), t_ref, R, center, axis,
                                 f"D/R {key[0]:.9g} n {key[1]:.9g}")
        shape = (PROFILE_DISTANCES, PROFILE_ANGLES)
        info = (PROFILE_GAMMA_MAX_DEG, PROFILE_H_MIN, PROFILE_H_MAX)
    profile_info = {"gamma_max_deg": info[0], "h_min": info[1] * R, "h_max": info[2] * R,
                    "width": shape[1], "height": shape[0], "strength_scale": 1.0}
    return ProfileLight(
        type=SPOT, energy_w=float(4.0 * math.pi * I_ref), spot_size_deg=180.0, spot_blend=0.0,
        radius=float(primary.radius * (apex * R + D) / D),
        location=tuple(float(v) for v in location), direction=tuple(float(v) for v in axis),
        note="; ".join(notes), color=color, scale_xy=1.0, cone_half_angle_deg=90.0,
        cutoff_distance=float(CUTOFF_FACTOR * (R + float(scene_size or 1.0))), kind=source.kind,
        model=EXACT_PROFILE, reference_irradiance=float(irradiance),
        relative_brightness=float(irradiance / primary_irr) if primary_irr > 0 else 0.0,
        profile_info=profile_info, _profile_maker=maker,
    )


def make_tier_light(source, primary: PrimaryLight, tier: str, **kwargs) -> BlenderLight:
    """FITTED or EXACT_PROFILE (the others are :func:`.light_models.make_blender_light`)."""
    if tier == FITTED:
        return make_fitted_light(source, primary, **kwargs)
    if tier == EXACT_PROFILE:
        return make_profile_light(source, primary, **kwargs)
    raise ValueError(f"unknown tier {tier!r}")


NODE_TREE_RECIPE = """\
EXACT_PROFILE light node tree (Cycles; light.use_nodes = True). The light is a SPOT
(spot_size 180°, blend 0, radius as given) at `location`, local −Z along `direction`.
Image: bpy.data.images.new(name, width, height, float_buffer=True, alpha=False);
set colorspace_settings.name = 'Non-Color' FIRST (changing it afterwards regenerates
the generated image and loses the pixels) and use_half_precision = False (values
reach ~1e7 and span ~20 decades), then pixels.foreach_set(profile["pixels"] in
R=G=B, A = 1, row j = bottom-up), image.update(), image.pack() (packs as OpenEXR).
Nodes (Math nodes unless said):
  TexCoord = Texture Coordinate            # .outputs['Normal']: object-space direction
  Sep      = Separate XYZ(TexCoord.Normal)  #   from the light to the shaded point
  cosg     = MULTIPLY(Sep.Z, -1)            # cos(gamma), spot axis is local −Z
  gam      = ARCCOSINE(MAXIMUM(MINIMUM(cosg, 1), 0))
  u        = SQRT(gam / radians(gamma_max_deg))
  t        = Light Path .outputs['Ray Length']      # distance light → shaded point
  h        = t * cosg                               # distance along the axis
  v        = LOGARITHM(MAXIMUM(h, h_min) / h_min, base e) / ln(h_max / h_min)
  Img      = Image Texture(Vector = Combine XYZ(u, v, 0)), interpolation 'Linear',
             extension 'EXTEND', the image above
  Emission(Color = white, Strength = Img.Color (R channel) × strength_scale)
           → Light Output.Surface
energy_w is twice the beam's flux (the spot's nominal power is the beam's), and
intensity(γ, h) = energy/(4π) × texture. Reference implementation, checked by
rendering with Cycles: bench/blender_light_check.py, build_profile_light().
EEVEE ignores light nodes: with EEVEE use the FITTED light instead. The lens must not shadow this light (it sits R/1000 behind
the back pole, so rays to receivers behind the lens do not cross the sphere, but
exclude the lens from its blockers anyway, as for every lens light).
"""
