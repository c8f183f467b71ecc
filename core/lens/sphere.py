"""Ray–sphere intersection in the numerically stable form of SPEC §4.3 (Haines, Günther,
Akenine-Möller, "Precision Improvements for Ray/Sphere Intersection", Ray Tracing Gems,
2019): the one copy every core site uses.

For a unit direction ``d`` and ``f = origin − centre`` the distances solve
``t² + 2βt + c = 0`` with ``β = f·d`` and ``c = |f|² − R²``. The discriminant is taken as
``R² − |f − βd|²`` (the squared impact parameter is exact where ``β² − c`` cancels), the
root of larger magnitude as ``q = −β − sign(β)·√disc`` and the other as ``c/q``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["SphereHit", "sphere_roots", "intersect_sphere"]


def _dot(a, b):
    return np.einsum("...i,...i->...", a, b)


def sphere_roots(beta, disc, c):
    """Both roots ``(near, far)`` of ``t² + 2βt + c = 0`` given the discriminant
    ``disc = β² − c`` in whatever accurate form the caller has (clamped at 0: a grazing
    ray meets the tangent point). ``near <= far``; both 0 where ``β = disc = 0``."""
    beta = np.asarray(beta, dtype=float)
    sq = np.sqrt(np.maximum(disc, 0.0))
    q = -beta - np.where(beta >= 0.0, 1.0, -1.0) * sq
    nz = q != 0.0
    other = np.where(nz, c / np.where(nz, q, 1.0), 0.0)
    # β < 0: q is the far root (> 0), c/q the near one; β ≥ 0: q is the near (≤ 0)
    ahead = beta < 0.0
    return np.where(ahead, other, q), np.where(ahead, q, other)


@dataclass(frozen=True)
class SphereHit:
    """Where the lines ``origin + t·d`` meet a sphere (all arrays (…)).

    ``near <= far``: the two distances (from the clamped discriminant, so a ray missing
    by rounding still gets the tangent point; check ``hit``); ``beta = f·d``;
    ``perp2``: squared distance of the line from the centre (the impact parameter²);
    ``disc = R² − perp2`` (unclamped); ``hit``: ``disc >= 0``."""

    near: np.ndarray
    far: np.ndarray
    beta: np.ndarray
    perp2: np.ndarray
    disc: np.ndarray

    @property
    def hit(self) -> np.ndarray:
        return self.disc >= 0.0


def intersect_sphere(origins, dirs, center, radius) -> SphereHit:
    """Both intersections of the rays ``origins + t·dirs`` (…, 3; unit ``dirs``) with the
    sphere(s) ``center`` (…, 3), ``radius`` (…), broadcast against the rays.

    ``c = (|f| − R)(|f| + R)`` keeps its precision for an origin near the surface; an
    origin inside the sphere has ``near < 0 < far``."""
    c0 = np.asarray(center, dtype=float)
    radius = np.asarray(radius, dtype=float)
    f = origins - c0
    beta = _dot(f, dirs)
    perp = f - beta[..., None] * dirs
    perp2 = _dot(perp, perp)
    disc = radius * radius - perp2
    ff = np.sqrt(_dot(f, f))
    near, far = sphere_roots(beta, disc, (ff - radius) * (ff + radius))
    return SphereHit(near, far, beta, perp2, disc)
