"""The Exact profile's shadow mask: which of a lens light's emission directions carry
light its source's shadow list blocks, from exact ray paths light → blockers → lens
(`blender/build/mask_nodes.py` puts it in the light's node tree)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..lens.refraction import fresnel_transmittance, refract
from ..phase1.shadow_mask import ray_passes


@dataclass
class EmissionMask:
    """What share of a lens light's beam its shadow list lets through, over the
    directions the light emits in: ``pixels[j, i]`` at the light's local direction
    components ``x = −s_max + (2i + 1) s_max / size`` (its local X) and ``y`` likewise
    (row j, its local Y); 1 where no ray goes. ``passed``: the share of the beam's
    flux that passes (the tiers' `unblocked_fraction` weighs the cap by solid angle,
    this by the flux through the lens)."""

    pixels: np.ndarray  # (size, size) float32, row 0 = most negative y
    s_max: float
    passed: float

    @property
    def size(self) -> int:
        return int(self.pixels.shape[0])


def emission_mask(
    light_position,
    lens_center,
    lens_radius: float,
    ior: float,
    blockers,
    apex,
    ex,
    ey,
    receiver: float | None = None,
    size: int = 128,
    n_radial: int = 384,
    n_azimuth: int = 768,
) -> EmissionMask:
    """The mask of a point light's beam through a lens (centre, radius, index) behind
    ``blockers`` = (centres (B, 3), radii (B,), indices (B,), kt (B,)), for a lens
    light at ``apex`` whose local X and Y axes are ``ex``, ``ey`` (world).

    Exact ray paths: a grid over where the rays enter the lens (ι × φ, as in the
    caustic layer's beam), each weighted by its flux through the lens (solid angle ×
    two-surface Fresnel) and by what the blockers pass of it on its way there
    (:func:`ray_passes`), landed on the plane across the axis ``receiver`` from the
    lens' centre (None: far away, the exit directions), and binned by the direction
    from ``apex`` to where it lands. The mask is exact on that plane (to its texels)
    and a fair guess elsewhere beyond the focus."""
    P = np.asarray(light_position, dtype=float)
    C = np.asarray(lens_center, dtype=float)
    A = np.asarray(apex, dtype=float)
    ex, ey = np.asarray(ex, dtype=float), np.asarray(ey, dtype=float)
    R, n = float(lens_radius), float(ior)
    to_c = C - P
    D = float(np.linalg.norm(to_c))
    if not (D > R and R > 0 and n > 0):
        raise ValueError("the light must lie outside the lens (radius > 0, index > 0)")
    u = to_c / D
    e1 = np.cross(u, [1.0, 0.0, 0.0] if abs(u[0]) < 0.9 else [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(u, e1)
    d_iota = 0.5 * np.pi / n_radial
    iota = (np.arange(n_radial) + 0.5) * d_iota
    phi = 2.0 * np.pi * (np.arange(n_azimuth) + 0.5) / n_azimuth
    sin_i, cos_i = np.sin(iota), np.cos(iota)
    sin_psi = (R / D) * sin_i
    cos_psi = np.sqrt((1.0 - sin_psi) * (1.0 + sin_psi))
    radial = np.cos(phi)[:, None] * e1 + np.sin(phi)[:, None] * e2
    d = cos_psi[:, None, None] * u + sin_psi[:, None, None] * radial[None]  # (I, P, 3)
    t1 = D * cos_psi - R * cos_i  # to the entry point
    p1 = P + t1[:, None, None] * d
    d2 = refract(d, (p1 - C) / R, 1.0 / n).directions
    cos_r = np.sqrt(np.maximum(1.0 - (sin_i / n) ** 2, 0.0))
    p2 = p1 + (2.0 * R * cos_r)[:, None, None] * d2
    d3 = refract(d2, -(p2 - C) / R, n).directions
    t_s, t_p = fresnel_transmittance(cos_i, 1.0, n)
    flux = sin_i * cos_i / cos_psi * 0.5 * (t_s * t_s + t_p * t_p)
    w = np.broadcast_to(flux[:, None], d.shape[:2])
    centers, radii, b_ior, b_kt = blockers
    passed = ray_passes(P, d, t1[:, None], centers, radii, b_ior, b_kt)
    if receiver is None:
        to = d3
    else:
        plane = C + float(receiver) * u
        along = np.einsum("...i,i->...", d3, u)
        t = np.einsum("...i,i->...", plane - p2, u) / np.where(along > 0, along, 1.0)
        to = p2 + np.maximum(t, 0.0)[..., None] * d3 - A
        w = np.where(along > 0, w, 0.0)
    to = to / np.linalg.norm(to, axis=-1)[..., None]
    x, y = to @ ex, to @ ey
    w = np.where(np.einsum("...i,i->...", to, u) > 0, w, 0.0)
    # the texels span the directions of 99 % of the flux (beyond: the edge texels)
    rho = np.hypot(x, y).ravel()
    order = np.argsort(rho)
    cum = np.cumsum(w.ravel()[order])
    reach = rho[order][min(np.searchsorted(cum, 0.99 * cum[-1]), rho.size - 1)] if cum[-1] else 1
    s_max = float(min(1.05 * reach, 1.0)) or 1.0
    edges = np.linspace(-s_max, s_max, int(size) + 1)
    both = np.histogram2d(y.ravel(), x.ravel(), bins=(edges, edges), weights=(w * passed).ravel())
    total = np.histogram2d(y.ravel(), x.ravel(), bins=(edges, edges), weights=w.ravel())[0]
    pixels = np.where(total > 0, both[0] / np.where(total > 0, total, 1.0), 1.0)
    share = float((w * passed).sum() / w.sum()) if w.sum() > 0 else 1.0
    return EmissionMask(pixels.astype(np.float32), s_max, share)
