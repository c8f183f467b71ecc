"""Small, numerically stable geometry of spheres seen from a point (SPEC §4.2).

No `acos` of numbers near 1 anywhere: every angle is an `atan2` of quantities
computed without cancellation.
"""

from __future__ import annotations

import numpy as np

from ..shared.parallel import map_slices


def radial_angle(distance, radius):
    """Half-angle under which a point at `distance` from a centre sees a sphere.

    `atan2(R, sqrt(D − R)·sqrt(D + R))`: exact far away and near grazing, where
    `acos(R_T / D)` loses every digit (SPEC §4.2). NaN where D < R (caller masks).
    """
    with np.errstate(invalid="ignore"):
        return np.arctan2(radius, np.sqrt(distance - radius) * np.sqrt(distance + radius))


def tangent_length(distance, radius):
    """`R_T = sqrt(D² − R²)`, in the cancellation-free product form."""
    with np.errstate(invalid="ignore"):
        return np.sqrt(distance - radius) * np.sqrt(distance + radius)


def angle_between(a, b):
    """Angle between direction arrays `a`, `b` (…, 3): `atan2(|a×b|, a·b)`."""
    return np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1), np.sum(a * b, axis=-1))


def cap_overlap_fraction(alpha, beta, gamma, halves=None):
    """Share of a spherical cap (angular radius α) covered by another (β) at γ apart.

    Both caps live on the unit sphere of directions around the light; because an
    isotropic light's flux is uniform in solid angle, this is the share of the
    lens's flux that the obstacle blocks. Exact spherical geometry, written with
    atan2 of stable quantities (no acos of numbers near 1): the overlap is the
    sum of two "cap segments" cut by the plane through both circles' intersection.
    Works elementwise on broadcastable arrays; caps must have radius < π/2.
    `halves`, if given: each pair's `cap_halves(alpha)` and `cap_halves(beta)`, the
    same values made once per sphere by a caller with many pairs of each (they are
    a third of the sines and tangents).
    """
    alpha, beta, gamma = np.broadcast_arrays(
        *(np.asarray(x, dtype=float) for x in (alpha, beta, gamma))
    )
    if halves is None:
        halves = (*cap_halves(alpha), *cap_halves(beta))
    s2_a, t2_a, s2_b, t2_b = np.broadcast_arrays(*halves)
    out = np.zeros(alpha.shape)
    cap_a = 4.0 * np.pi * s2_a
    inside = beta >= gamma + alpha  # obstacle covers the lens
    contained = (alpha >= gamma + beta) & ~inside  # obstacle within the lens
    partial = (alpha + beta > gamma) & ~inside & ~contained
    out[inside] = 1.0
    out[contained] = 4.0 * np.pi * s2_b[contained] / cap_a[contained]
    if np.any(partial):
        a, b, g, ca = alpha[partial], beta[partial], gamma[partial], cap_a[partial]
        h = tuple(x[partial] for x in (s2_a, t2_a, s2_b, t2_b))

        def overlap(s):  # elementwise: a slice's rows are bit for bit the whole's
            return _segments(a[s], b[s], g[s], *(x[s] for x in h)) / ca[s]

        out[partial] = np.concatenate(map_slices(overlap, a.size))
    return np.clip(out, 0.0, 1.0)


def cap_halves(a):
    """sin²(a/2) and tan²(a/2) of caps of angular radius a (a cap's area is 4π sin²(a/2))."""
    return np.sin(0.5 * a) ** 2, np.tan(0.5 * a) ** 2


def _segments(a, b, g, s2_a=None, t2_a=None, s2_b=None, t2_b=None):
    """`_segment_area(a, b, g) + _segment_area(b, a, g)`, bit for bit: both share the
    half-perimeter's four sines (b's s_a is a's s_b and the reverse); the caps'
    `cap_halves`, if given, are not computed again."""
    if s2_a is None:
        (s2_a, t2_a), (s2_b, t2_b) = cap_halves(a), cap_halves(b)
    s = 0.5 * (a + b + g)
    s_a, s_b, s_g = 0.5 * (b + g - a), 0.5 * (a + g - b), 0.5 * (a + b - g)
    sin_s, sin_a, sin_b, sin_g = np.sin(s), np.sin(s_a), np.sin(s_b), np.sin(s_g)
    return _segment(sin_s, sin_a, sin_b, sin_g, s2_a, t2_a) + _segment(
        sin_s, sin_b, sin_a, sin_g, s2_b, t2_b
    )


def _segment_area(a, b, g):
    """Solid angle of the part of cap `a` beyond the great circle through the two
    points where the rims of caps `a` and `b` (centres γ apart) cross.

    ω, the angle at a's centre between the arc to b's centre and the arc to a
    crossing point, comes from the spherical half-angle formula (stable for thin
    triangles, with the half-perimeter differences formed directly). The segment
    is the sector `4ω sin²(a/2)` minus the isosceles triangle of legs a and apex
    angle 2ω, whose excess is `E = 2 atan2(t² sin 2ω, 1 + t² cos 2ω)`, t = tan(a/2).
    Both terms scale as a², so tiny caps (far lenses) keep their relative
    precision; for ω > π/2 the excess turns negative and the sum still holds.
    """
    s = 0.5 * (a + b + g)
    s_a, s_b, s_g = 0.5 * (b + g - a), 0.5 * (a + g - b), 0.5 * (a + b - g)
    return _segment(np.sin(s), np.sin(s_a), np.sin(s_b), np.sin(s_g), *cap_halves(a))


def _segment(sin_s, sin_sa, sin_sb, sin_sg, s2, t2):
    """`_segment_area` of cap `a` from the sines of s, s − a, s − b, s − γ and its
    `cap_halves` s2 = sin²(a/2), t2 = tan²(a/2)."""
    sin_half = np.sqrt(np.maximum(sin_sa * sin_sg, 0.0))
    cos_half = np.sqrt(np.maximum(sin_s * sin_sb, 0.0))
    omega = 2.0 * np.arctan2(sin_half, cos_half)
    excess = 2.0 * np.arctan2(t2 * np.sin(2.0 * omega), 1.0 + t2 * np.cos(2.0 * omega))
    return 4.0 * omega * s2 - excess
