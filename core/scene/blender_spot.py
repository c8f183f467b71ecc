"""What a Blender spot light puts on a receiving plane perpendicular to its axis.

A pure (numpy-only) model of Blender's spot light, used to measure lens-light
models against the exact optics (:mod:`core.lens.ball_optics`) and to fit them.

How Blender's spot light emits (checked in the sources, Blender 4.x/5.0)
----------------------------------------------------------------------------

* Cycles, ``intern/cycles/scene/light.cpp`` (``LightManager::device_update_lights``):
  for a spot light it stores ``cos_half_spot_angle = cos(spot_angle / 2)`` and
  ``spot_smooth = 1 / ((1 - cos_half_spot_angle) * spot_blend)`` (``spot_angle`` is
  Blender's ``spot_size``, the *full* cone angle; ``spot_smooth`` is ``spot_blend``).
* Cycles, ``intern/cycles/kernel/light/spot.h`` (``spot_light_attenuation``): the
  emission toward a direction whose cosine to the spot's axis is ``z`` is scaled by
  ``smoothstepf((z - cos_half_spot_angle) * spot_smooth)``, with
  ``smoothstepf(f) = 0`` for ``f <= 0``, ``1`` for ``f >= 1`` and ``3f^2 - 2f^3``
  between.  Since Cycles 4.0 there is no extra ``cos`` factor in the attenuation
  (Cycles 3.x multiplied the smoothstep by the cosine ``z`` itself; that older form
  is *not* what Blender 4.2+ does).
* EEVEE, ``source/blender/draw/engines/eevee(_next)/eevee_light.cc``: ``spot_mul =
  1 / max(1e-8, (1 - cos(spotsize / 2)) * spotblend)`` and ``spot_bias =
  -cos(spotsize / 2) * spot_mul``; the shader's spot mask is
  ``smoothstep(0, 1, z * spot_mul + spot_bias)`` with ``z`` the cosine to the axis
  (for an unscaled light).  That is the same function as Cycles'.
* The intensity of a point or spot light of power ``energy`` (W) is
  ``energy / (4 pi)`` W/sr before the spot mask (SPEC section 9): narrowing the cone
  does not concentrate power.

So, with ``c = cos(gamma)`` the cosine of the angle ``gamma`` between the emission
direction and the spot's axis, ``c_H = cos(H)`` (``H = spot_size / 2``) and
``w = (1 - c_H) * spot_blend`` (the width of the blend band *in cosine*):

    I(gamma) = energy / (4 pi) * smoothstep((c - c_H) / w)

The blend band is therefore linear in the cosine, not in the angle: with
``spot_blend = 1`` the mask rises from 0 at the rim to 1 only on the axis.

Irradiance on a plane perpendicular to the axis at distance ``h`` in front of the
apex, at radius ``rho`` from the axis (``r^2 = h^2 + rho^2``, ``c = h / r``):

    E(rho) = I(gamma) * c / r^2 = I(gamma) * h / r^3

and the flux landing within radius ``rho`` is ``2 pi I0 * A(1 - c)``, where
``A(q) = integral_0^q mask dq'`` has a closed form (the smoothstep integrates to a
quartic).  Ring averages are computed from that, exactly.

The light's ``radius`` (``shadow_soft_size``) is ignored: from a receiver that sees
the whole (small) emitting sphere, a uniformly emitting sphere gives the same
irradiance as a point at its centre; lens lights keep it small.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = [
    "smoothstep01",
    "spot_mask",
    "spot_mask_integral",
    "spot_solid_angle",
    "spot_flux_within_radius",
    "spot_irradiance",
    "spot_ring_irradiance",
    "profile_flux_within_angle",
    "profile_flux_within_radius",
    "one_minus_cos_of_radius",
]

FOUR_PI = 4.0 * math.pi


def smoothstep01(f):
    """``0`` for ``f <= 0``, ``1`` for ``f >= 1``, ``3f^2 - 2f^3`` between (array-like)."""
    f = np.clip(np.asarray(f, dtype=float), 0.0, 1.0)
    return f * f * (3.0 - 2.0 * f)


def _band(half_angle, blend):
    """``(q_H, w)``: ``1 - cos H`` (without cancellation) and the blend band width
    in cosine ``w = (1 - cos H) * blend``."""
    q_h = 2.0 * math.sin(0.5 * half_angle) ** 2
    return q_h, q_h * max(0.0, float(blend))


def spot_mask(cos_gamma, half_angle, blend):
    """Blender's spot mask (0..1) for directions with cosine ``cos_gamma`` to the
    axis.  ``half_angle``: ``spot_size / 2`` (radians, in ``(0, pi/2]``);
    ``blend``: ``spot_blend`` (0..1).  ``blend == 0`` is a hard edge (1 strictly
    inside the cone, 0 outside)."""
    c = np.asarray(cos_gamma, dtype=float)
    q_h, w = _band(half_angle, blend)
    cos_h = 1.0 - q_h
    if w <= 0.0:
        return np.where(c > cos_h, 1.0, 0.0)
    return smoothstep01((c - cos_h) / w)


def _F(u):
    """Antiderivative of ``smoothstep01`` on ``[0, 1]``: ``u^3 - u^4/2``."""
    u = np.clip(u, 0.0, 1.0)
    return u * u * u * (1.0 - 0.5 * u)


def spot_mask_integral(q, half_angle, blend):
    """``A(q) = integral over c' from 1 - q to 1 of mask(c') dc'`` for ``q = 1 - c``
    in ``[0, 2]`` (array-like): the mask-weighted solid angle within angle
    ``gamma`` of the axis is ``2 pi A(1 - cos gamma)``.  Exact:

        A(q) = max(0, min(q, q_H - w)) + w (1/2 - F(clip((q_H - q)/w, 0, 1)))

    with ``F(u) = u^3 - u^4/2`` the antiderivative of the smoothstep."""
    q = np.asarray(q, dtype=float)
    q_h, w = _band(half_angle, blend)
    if w <= 0.0:
        return np.clip(q, 0.0, q_h)
    core = np.clip(q, 0.0, q_h - w)
    u = (q_h - q) / w
    return core + w * (0.5 - _F(u))


def spot_solid_angle(half_angle, blend):
    """Mask-weighted solid angle of the whole spot (sr): ``2 pi (q_H - w/2)``.
    A spot of intensity ``I0`` emits ``I0`` times this (W)."""
    q_h, w = _band(half_angle, blend)
    return 2.0 * math.pi * (q_h - 0.5 * w)


def one_minus_cos_of_radius(h, rho):
    """``1 - cos(gamma)`` for the point at radius ``rho`` on the plane at distance
    ``h > 0`` (``tan gamma = rho / h``), without cancellation:
    ``rho^2 / (r (r + h))``."""
    rho = np.asarray(rho, dtype=float)
    r = np.hypot(h, rho)
    return rho * rho / (r * (r + h))


def spot_flux_within_radius(intensity, h, half_angle, blend, radii):
    """Flux (W) that a spot of on-axis intensity ``intensity`` (W/sr, i.e.
    ``energy / (4 pi)``) puts within radius ``rho`` (each of ``radii``) of the axis
    on the plane perpendicular to its axis at distance ``h`` in front of its apex.
    ``h <= 0`` (the plane behind the spot, which emits away from it) gives 0."""
    radii = np.asarray(radii, dtype=float)
    if not h > 0.0:
        return np.zeros(radii.shape)
    q = one_minus_cos_of_radius(h, radii)
    return 2.0 * math.pi * intensity * spot_mask_integral(q, half_angle, blend)


def spot_irradiance(intensity, h, half_angle, blend, rho):
    """Point irradiance (W/length^2) at radius ``rho`` on the plane at distance
    ``h`` in front of the apex: ``I(gamma) h / r^3``; 0 for ``h <= 0``."""
    rho = np.asarray(rho, dtype=float)
    if not h > 0.0:
        return np.zeros(rho.shape)
    r = np.hypot(h, rho)
    c = h / r
    return intensity * spot_mask(c, half_angle, blend) * h / (r * r * r)


def spot_ring_irradiance(intensity, h, half_angle, blend, edges):
    """Ring averages of :func:`spot_irradiance` over rings with the given increasing
    ``edges`` (the convention of :func:`.exact_optics.irradiance_on_plane`)."""
    edges = np.asarray(edges, dtype=float)
    cum = spot_flux_within_radius(intensity, h, half_angle, blend, edges)
    return np.diff(cum) / (math.pi * np.diff(edges * edges))


# ---------------------------------------------------------------------------
# Tabulated angular profile (the exact-profile tier)
# ---------------------------------------------------------------------------


def profile_flux_within_angle(gammas, intensities, gamma):
    """Flux (W) within angle ``gamma`` (array-like, radians) of the axis of a light
    whose radiant intensity (W/sr) is linear in the angle between the table's nodes
    ``gammas`` (increasing, from 0) with values ``intensities``, and 0 beyond the
    last node.  Exact: on a segment ``I0 = a + b g``,
    ``integral (a + b g) sin g dg = -a cos g + b (sin g - g cos g)``, both written
    without cancellation for small angles."""
    g = np.asarray(gammas, dtype=float)
    I0 = np.asarray(intensities, dtype=float)
    if g.ndim != 1 or g.size < 2 or g[0] != 0.0 or np.any(np.diff(g) <= 0.0):
        raise ValueError("gammas must be increasing and start at 0")
    slope = np.diff(I0) / np.diff(g)
    a = I0[:-1] - slope * g[:-1]

    def prim(x, k):
        # -a cos x + b (sin x - x cos x), shifted by its value at 0 (= -a), using
        # 1 - cos x = 2 sin^2(x/2) and sin x - x cos x computed by series near 0.
        omc = 2.0 * np.sin(0.5 * x) ** 2
        small = np.abs(x) < 1e-3
        xs = np.where(small, x, 0.0)
        s_minus = np.where(small, xs**3 / 3.0 - xs**5 / 30.0, np.sin(x) - x * np.cos(x))
        return a[k] * omc + slope[k] * s_minus

    seg_full = prim(g[1:], np.arange(g.size - 1)) - prim(g[:-1], np.arange(g.size - 1))
    cum_nodes = np.concatenate([[0.0], np.cumsum(seg_full)])
    x = np.clip(np.asarray(gamma, dtype=float), 0.0, g[-1])
    k = np.clip(np.searchsorted(g, x, side="right") - 1, 0, g.size - 2)
    part = prim(x, k) - prim(g[k], k)
    return 2.0 * math.pi * (cum_nodes[k] + part)


def profile_flux_within_radius(gammas, intensities, h, radii):
    """Flux (W) within radius ``rho`` on the plane at distance ``h`` in front of the
    apex of a tabulated profile (see :func:`profile_flux_within_angle`); 0 for
    ``h <= 0``."""
    radii = np.asarray(radii, dtype=float)
    if not h > 0.0:
        return np.zeros(radii.shape)
    return profile_flux_within_angle(gammas, intensities, np.arctan2(radii, h))
