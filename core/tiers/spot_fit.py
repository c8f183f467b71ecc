"""One Blender spot fitted to the exact beam of a ball lens (the FITTED tier's
optimum, :mod:`.fitted`).

The spot on the lens's axis whose position, energy, cone and blend minimise the
relative L1 error of the irradiance (:mod:`core.tiers.beam_error`) against the exact
optics, averaged over receivers 0.5 R to 10 R behind the sphere
(``FIT_RECEIVERS``). The optimum depends only on ``D/R`` and ``n``.
:func:`fit_spot` is the direct fit (about 0.3 s); ``bench/make_fitted_table.py``
runs it over a grid and writes the table :mod:`.fitted` interpolates.

A point-like light can only make a beam that widens with distance; the true beam
converges to a focus first (and has a bright core in a wide halo). No spot can
reproduce that: the error is what the fit trades for working in EEVEE.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..scene.blender_spot import one_minus_cos_of_radius, spot_mask_integral
from . import beam_error as acc

#: Receivers the fit averages over, in R behind the back pole.
FIT_RECEIVERS = tuple(float(x) for x in np.geomspace(0.5, 10.0, 9))
#: The first receiver (R behind the back pole): the fitted apex stays before it.
FIRST_RECEIVER = 0.5
#: The sun (x = 0) is fitted with the light this far away (in R).
SUN_DISTANCE = 1e6
#: Bounds of the fitted spot: its apex at most this far (R) before the first
#: receiver, its half-angle at least this (degrees).
FIT_MAX_DISTANCE = 1e3
FIT_MIN_HALF_ANGLE_DEG = 0.01


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
        return (
            1.0 / d,
            self.intensity * (D_over_R / d) ** 2,
            d * math.tan(math.radians(self.half_angle_deg)),
            self.blend,
        )

    @classmethod
    def from_invariants(cls, D_over_R, w, e, r, b, l1=float("nan")) -> SpotFit:
        apex, intensity, half = (float(v) for v in from_invariants(D_over_R, w, e, r))
        return cls(apex=apex, intensity=intensity, half_angle_deg=half, blend=b, l1=l1)

    def model(self, R=1.0, I0=1.0) -> acc.AxialSpot:
        return acc.AxialSpot(
            apex=self.apex * R,
            intensity=self.intensity * I0,
            half_angle=math.radians(self.half_angle_deg),
            blend=self.blend,
        )


def from_invariants(D_over_R, w, e, r):
    """(apex, intensity, half_angle_deg) of the spot with the invariants ``w, e, r``
    (:meth:`SpotFit.invariants`), on numbers or columns."""
    d = 1.0 / w
    return (1.0 + FIRST_RECEIVER - d, e * (d / D_over_R) ** 2, np.degrees(np.arctan2(r, d)))


class SpotObjective:
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
            q = one_minus_cos_of_radius(h, self.edges[j])
            f = 2.0 * math.pi * k * spot_mask_integral(q, H, b)
            out[j] = np.sum(np.abs(np.diff(f) - self.true[j])) / self.total[j]
        return out

    @staticmethod
    def unpack(x):
        """Optimiser coordinates → (apex, k, H rad, blend): ``x = (log d, log e,
        log r, blend)`` with the invariants of :class:`SpotFit` (``e`` here
        without the factor ``D^2``).  ``d`` is kept within ``[1e-3, FIT_MAX_DISTANCE]``
        R and ``H`` within ``[FIT_MIN_HALF_ANGLE, 90°]``: a nearly collimated beam
        is as well served by a spot 1000 R away as by one farther, and the cone
        must stay one Blender can make (see :func:`.base.cone_shape`)."""
        d = min(max(math.exp(x[0]), 1e-3), FIT_MAX_DISTANCE)
        e, r = math.exp(x[1]), math.exp(x[2])
        H = min(max(math.atan2(r, d), math.radians(FIT_MIN_HALF_ANGLE_DEG)), 0.5 * math.pi)
        return 1.0 + FIRST_RECEIVER - d, e * d * d, H, min(max(x[3], 0.0), 1.0)

    def __call__(self, x) -> float:
        self.evaluations += 1
        if (
            not all(math.isfinite(v) for v in x)
            or abs(x[0]) > 40
            or abs(x[1]) > 80
            or abs(x[2]) > 40
        ):
            return 10.0
        return float(np.mean(self.l1(*self.unpack(x))))


def nelder_mead(f, x0, step, max_iter=500, ftol=1e-5):
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
    ob = SpotObjective(beam, receivers)
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
        x, fx = nelder_mead(ob, x0, [0.3, 0.3, 0.3, 0.2])
        if fx < best_f:
            best_x, best_f = x, fx
    apex, k, H, b = ob.unpack(best_x)
    return SpotFit(apex=apex, intensity=k, half_angle_deg=math.degrees(H), blend=b, l1=best_f)
