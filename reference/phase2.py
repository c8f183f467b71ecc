"""Phase 2 of the thesis as a reference: the irradiance a non-full secondary source
puts on a plane, by exact rays light → blockers → lens → plane.

Deterministic, not Monte-Carlo: a grid of rays over the lens' lit cap, parametrised by
where they enter the sphere (angle of incidence ι × azimuth φ about the light–lens
axis, cell midpoints), each carrying the flux of its patch

    I · dΩ · T(ι),   dΩ = (R/D)² sin ι cos ι / cos ψ dι dφ   (sin ψ = (R/D) sin ι)

times the share its blockers pass (:func:`.tracer.blocker_transmission`: 0 through an
opaque one, the two-surface Fresnel share through a glass one, undeflected). Each ray
is refracted into and out of the lens by the vector Snell law with its own 3-D
cosines and followed to the plane, where its flux is binned. The lens' own shadow, the
direct light and internal reflections are left out, as in :mod:`.tracer`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .emitters import PointLight
from .scene import GlassSphere, ReceiverPlane
from .tracer import blocker_transmission
from .vectors import frame, fresnel_sp, refract, sphere_hits, unit

__all__ = ["Phase2Rays", "Phase2Irradiance", "phase2_rays", "phase2_irradiance"]


@dataclass(frozen=True)
class Phase2Rays:
    """The traced grid (``n_radial × n_azimuth`` rays, flattened): where each lands on
    the plane (``u, v``; NaN if it never does), the flux it carries with no blocker
    (``flux``, W, after the lens' Fresnel) and the share its blockers pass (``passed``),
    and its exit point and direction from the lens."""

    u: np.ndarray
    v: np.ndarray
    flux: np.ndarray
    passed: np.ndarray
    exit_points: np.ndarray
    exit_dirs: np.ndarray

    @property
    def landed(self) -> np.ndarray:
        return np.isfinite(self.u)


@dataclass(frozen=True)
class Phase2Irradiance:
    """Irradiance (W/length²) on the cells ``(len(u_edges)-1, len(v_edges)-1)`` and
    the flux landing anywhere on the plane, with and without the blockers."""

    u_edges: np.ndarray
    v_edges: np.ndarray
    irradiance: np.ndarray
    flux_on_plane: float
    flux_unblocked: float
    n_rays: int


def phase2_rays(
    light: PointLight,
    lens: GlassSphere,
    plane: ReceiverPlane,
    blockers=(),
    n_radial: int = 512,
    n_azimuth: int = 1024,
) -> Phase2Rays:
    """Trace the ray grid of a point light (radius 0) through ``blockers`` and ``lens``
    onto ``plane`` (which must not cut the lens)."""
    if not isinstance(light, PointLight) or light.radius != 0.0:
        raise ValueError("phase 2's reference takes a point light of radius 0")
    c, R, n = lens.c, float(lens.radius), float(lens.ior)
    p = np.asarray(light.position, float)
    D = float(np.linalg.norm(c - p))
    if not D > R:
        raise ValueError("the light must lie outside the lens")
    if abs(plane.signed_distance(c[None, :])[0]) <= R:
        raise ValueError("the plane cuts the lens: phase 2's reference needs it clear")
    nr, na = int(n_radial), int(n_azimuth)
    d_iota, d_phi = 0.5 * math.pi / nr, 2.0 * math.pi / na
    iota = (np.arange(nr) + 0.5) * d_iota
    phi = (np.arange(na) + 0.5) * d_phi
    w = unit(c - p)
    s_ax, t_ax = (x[0] for x in frame(w))
    sin_psi = (R / D) * np.sin(iota)
    cos_psi = np.sqrt((1.0 - sin_psi) * (1.0 + sin_psi))
    radial = np.cos(phi)[:, None] * s_ax + np.sin(phi)[:, None] * t_ax  # (na, 3)
    d = (cos_psi[:, None, None] * w + sin_psi[:, None, None] * radial[None]).reshape(-1, 3)
    o = np.broadcast_to(p, d.shape)
    intensity = light.power / (4.0 * math.pi)
    d_omega = (R / D) ** 2 * np.sin(iota) * np.cos(iota) / cos_psi * d_iota * d_phi
    flux0 = np.repeat(intensity * d_omega, na)

    t1, _, hit = sphere_hits(o, d, c, R)
    t1 = np.where(hit, t1, 0.0)
    p1 = o + t1[:, None] * d
    d2, ci1, ct1, tir1 = refract(d, (p1 - c) / R, 1.0 / n)
    ts1, tp1 = fresnel_sp(ci1, ct1, 1.0, n)
    _, t_far, _ = sphere_hits(p1, d2, c, R)
    chord = np.maximum(np.nan_to_num(t_far), 0.0)
    p2 = p1 + chord[:, None] * d2
    d3, ci2, ct2, tir2 = refract(d2, -(p2 - c) / R, n)
    ts2, tp2 = fresnel_sp(ci2, ct2, n, 1.0)
    trans = 0.5 * (ts1 * ts2 + tp1 * tp2) * np.exp(-lens.absorption * chord)
    flux = np.where(hit & ~tir1 & ~tir2, flux0 * trans, 0.0)
    passed = blocker_transmission(o, d, 0.0, t1, tuple(blockers))

    eu, ev, nrm = plane.axes()
    p0 = np.asarray(plane.origin, float)
    dn = d3 @ nrm
    s2 = (p2 - p0) @ nrm
    lands = (dn < 0.0) & (s2 > 0.0)
    t3 = np.where(lands, -s2 / np.where(lands, dn, -1.0), np.nan)
    x = p2 + t3[:, None] * d3
    u, v = (x - p0) @ eu, (x - p0) @ ev
    return Phase2Rays(u, v, np.where(lands, flux, 0.0), passed, p2, d3)


def phase2_irradiance(
    light: PointLight,
    lens: GlassSphere,
    plane: ReceiverPlane,
    grid,
    blockers=(),
    n_radial: int = 512,
    n_azimuth: int = 1024,
) -> Phase2Irradiance:
    """Irradiance on the cells ``grid = (u_edges, v_edges)`` of ``plane`` of the light
    that goes ``light`` → ``blockers`` → ``lens`` → plane (:func:`phase2_rays`)."""
    rays = phase2_rays(light, lens, plane, blockers, n_radial, n_azimuth)
    u_edges, v_edges = (np.asarray(e, float) for e in grid)
    ok = rays.landed
    w = (rays.flux * rays.passed)[ok]
    hist = np.histogram2d(rays.u[ok], rays.v[ok], bins=(u_edges, v_edges), weights=w)[0]
    area = np.outer(np.diff(u_edges), np.diff(v_edges))
    return Phase2Irradiance(
        u_edges=u_edges,
        v_edges=v_edges,
        irradiance=hist / area,
        flux_on_plane=float(w.sum()),
        flux_unblocked=float(rays.flux[ok].sum()),
        n_rays=int(rays.u.size),
    )
