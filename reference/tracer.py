"""Irradiance on a receiving plane of the light that goes emitter -> (blockers) ->
glass sphere -> plane, by Monte-Carlo light tracing (vectorised over rays).

The direct beam only (as SPEC 6): internally reflected light is dropped, and so is
the light reflected off the sphere's outside.  The emitter's direct light on the
plane is not included either; :func:`lens_shadow` gives the region the lens shades.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from .emitters import PointLight, SpotLight, SunLight
from .scene import Blocker, GlassSphere, ReceiverPlane
from .vectors import fresnel_sp, refract, sphere_hits, unit

__all__ = ["PlaneIrradiance", "trace_irradiance", "lens_shadow", "blocker_transmission"]


@dataclass(frozen=True)
class PlaneIrradiance:
    """What :func:`trace_irradiance` measured (flux in W, lengths in the scene's unit).

    - ``flux_into_lens``: flux arriving at the lens's surface (after the blockers,
      before Fresnel); ``flux_on_plane``: flux of the beam landing anywhere on the
      (infinite) plane; each with its standard error ``*_se``
    - ``u_edges, v_edges, irradiance, irradiance_se``: the grid of cells in the
      plane's coordinates, irradiance ``(len(u_edges)-1, len(v_edges)-1)`` in W/length^2
      (flux landing in the cell / its area) and its standard error (None without a grid)
    - ``ring_center, ring_edges, ring_irradiance, ring_se``: the same over rings
      around ``ring_center`` (plane coordinates) (None without rings)
    - ``centroid``: flux-weighted mean landing point ``(u, v)``
    - ``n_rays``, ``seconds``: the work done
    """

    n_rays: int
    seconds: float
    flux_into_lens: float
    flux_into_lens_se: float
    flux_on_plane: float
    flux_on_plane_se: float
    centroid: tuple
    u_edges: np.ndarray | None = None
    v_edges: np.ndarray | None = None
    irradiance: np.ndarray | None = None
    irradiance_se: np.ndarray | None = None
    ring_center: tuple | None = None
    ring_edges: np.ndarray | None = None
    ring_irradiance: np.ndarray | None = None
    ring_se: np.ndarray | None = None

    @property
    def peak(self):
        """The largest cell mean of the grid (of the rings without a grid)."""
        values = self.irradiance if self.irradiance is not None else self.ring_irradiance
        return float(np.max(values))

    @property
    def rays_per_second(self):
        return self.n_rays / self.seconds if self.seconds > 0.0 else math.inf

    def ring_flux(self):
        """Flux (W) landing in each ring."""
        return self.ring_irradiance * np.pi * np.diff(self.ring_edges**2)

    def cell_flux(self):
        """Flux (W) landing in each cell of the grid."""
        return self.irradiance * np.outer(np.diff(self.u_edges), np.diff(self.v_edges))


def _two_surfaces(ts1, tp1, ts2, tp2, fresnel):
    """Unpolarised transmittance of two surfaces.  ``"tracked"``: both surfaces share
    the ray's plane of incidence (the plane through the ray and the centre), so s and
    p go through separately, ``(ts1 ts2 + tp1 tp2)/2`` (SPEC 6).  ``"per_surface"``:
    each surface depolarises, ``((ts1 + tp1)/2)((ts2 + tp2)/2)`` (mitsuba's
    ``scalar_rgb`` dielectric)."""
    if fresnel == "tracked":
        return 0.5 * (ts1 * ts2 + tp1 * tp2)
    if fresnel == "per_surface":
        return 0.25 * (ts1 + tp1) * (ts2 + tp2)
    raise ValueError(f"fresnel must be 'tracked' or 'per_surface', got {fresnel!r}")


def blocker_transmission(origin, direction, t_min, t_end, blockers, fresnel="tracked"):
    """Fraction of each ray's power that passes all ``blockers`` on its free path
    ``t_min < t < t_end``: 0 if an opaque one is in the way (so several opaque
    blockers block the union of their shadows), the product of the glass ones'
    shares (two-surface Fresnel at the 3-D incidence angle x absorption along the
    chord; no deflection, see :class:`.Blocker`)."""
    trans = np.ones(origin.shape[0])
    for b in blockers:
        tn, tf, hit = sphere_hits(origin, direction, b.c, b.radius)
        on_path = hit & (tf > t_min) & (tn < t_end)
        if b.ior is None:
            trans = np.where(on_path, 0.0, trans)
            continue
        # incidence angle from the impact parameter: the same at both surfaces
        half_chord = np.where(hit, 0.5 * (tf - tn), 0.0)
        cos_i = np.clip(half_chord / b.radius, 0.0, 1.0)
        eta = 1.0 / b.ior
        k = 1.0 - eta * eta * (1.0 - cos_i) * (1.0 + cos_i)
        cos_t = np.sqrt(np.maximum(k, 0.0))
        ts1, tp1 = fresnel_sp(cos_i, cos_t, 1.0, b.ior)
        ts2, tp2 = fresnel_sp(cos_t, cos_i, b.ior, 1.0)
        share = _two_surfaces(ts1, tp1, ts2, tp2, fresnel)
        # the chord inside the glass of the refracted ray, 2 R cos(t)
        share = np.where(k < 0.0, 0.0, share * np.exp(-b.absorption * 2.0 * b.radius * cos_t))
        trans = np.where(on_path, trans * share, trans)
    return trans


def _check(lens, plane, blockers):
    if not isinstance(lens, GlassSphere) or not isinstance(plane, ReceiverPlane):
        raise TypeError("lens must be a GlassSphere and plane a ReceiverPlane")
    if not all(isinstance(b, Blocker) for b in blockers):
        raise TypeError("blockers must be Blocker spheres")
    if plane.signed_distance(lens.c[None, :])[0] < -lens.radius:
        raise ValueError("the lens lies behind the receiving plane")


def trace_irradiance(
    emitter,
    lens,
    plane,
    n_rays,
    seed=0,
    blockers=(),
    grid=None,
    rings=None,
    fresnel="tracked",
    chunk=200_000,
) -> PlaneIrradiance:
    """Trace ``n_rays`` rays from ``emitter`` (a light of :mod:`.emitters`) through the
    ``blockers`` and the ``lens`` onto ``plane`` and bin where they land.

    ``grid``: ``(u_edges, v_edges)`` cell edges in the plane's coordinates; ``rings``:
    ``((u0, v0), edges)`` ring edges around a point of the plane.  ``seed``: the
    result is a deterministic function of it (and of ``chunk``).  ``fresnel``: see
    :func:`_two_surfaces`.

    Each ray is intersected with the lens (robust form, SPEC 4.3), refracted by the
    vector Snell law with its own 3-D cosines, weighted by the s/p Fresnel
    transmittances of both surfaces and ``exp(-absorption * chord)``, refracted out
    and followed forward from its exit point to the plane.  Near field: where the
    plane cuts the sphere, a ray whose chord crosses the plane lands there (entry
    Fresnel and the absorption so far); rays that leave the lens heading away from
    the plane's front never land.
    """
    _check(lens, plane, blockers)
    n_rays = int(n_rays)
    rng = np.random.default_rng(seed)
    c, R, n, absorption = lens.c, float(lens.radius), float(lens.ior), float(lens.absorption)
    eu, ev, nrm = plane.axes()
    p0 = np.asarray(plane.origin, float)
    if grid is not None:
        u_edges, v_edges = (np.asarray(e, float) for e in grid)
        g_sum = np.zeros((u_edges.size - 1, v_edges.size - 1))
        g_sq = np.zeros_like(g_sum)
    if rings is not None:
        r_center, r_edges = tuple(map(float, rings[0])), np.asarray(rings[1], float)
        r_sum = np.zeros(r_edges.size - 1)
        r_sq = np.zeros_like(r_sum)
    tot = np.zeros(6)  # sums of g and g^2 into the lens, on the plane; g u, g v
    t0 = time.perf_counter()
    done = 0
    while done < n_rays:  # chunks of rays keep the memory bounded
        m = min(chunk, n_rays - done)
        done += m
        rays = emitter.sample(c, R, m, rng)
        o, d, g = rays.origin, rays.direction, rays.flux
        t_near, _, hit = sphere_hits(o, d, c, R)
        hit &= t_near > rays.t_min
        t1 = np.where(hit, t_near, 0.0)
        p1 = o + t1[:, None] * d
        g = np.where(hit, g, 0.0)
        g = g * blocker_transmission(o, d, rays.t_min, t1, blockers, fresnel)
        # the opaque plane blocks a path that reaches the lens from behind it
        dn = d @ nrm
        s1 = (p1 - p0) @ nrm
        if np.isinf(rays.t_min):
            front = (dn < 0.0) | ((dn == 0.0) & (s1 >= 0.0))
        else:
            front = (o - p0) @ nrm >= 0.0
        g = np.where(front & (s1 >= -1e-12 * R), g, 0.0)
        tot[0] += g.sum()
        tot[1] += (g * g).sum()

        n1 = (p1 - c) / R
        d2, ci1, ct1, tir1 = refract(d, n1, 1.0 / n)
        ts1, tp1 = fresnel_sp(ci1, ct1, 1.0, n)
        chord = 2.0 * R * ct1  # isosceles chord, no re-intersection
        p2 = p1 + chord[:, None] * d2
        n2 = (p2 - c) / R
        d3, ci2, ct2, tir2 = refract(d2, -n2, n)
        ts2, tp2 = fresnel_sp(ci2, ct2, n, 1.0)
        w_out = _two_surfaces(ts1, tp1, ts2, tp2, fresnel) * np.exp(-absorption * chord)
        w_out = np.where(tir1 | tir2, 0.0, w_out)

        # a chord that crosses the plane (the plane cuts the sphere) lands inside
        s2 = (p2 - p0) @ nrm
        d2n = d2 @ nrm
        inside = (s2 < 0.0) & ~tir1
        t_in = np.where(inside, s1 / np.where(inside, -d2n, 1.0), 0.0)
        w_in = 0.5 * (ts1 + tp1) * np.exp(-absorption * t_in)
        x_in = p1 + t_in[:, None] * d2
        # the exit ray, forward from the exit point
        d3n = d3 @ nrm
        out = ~inside & (d3n < 0.0)
        t3 = np.where(out, -s2 / np.where(out, d3n, -1.0), 0.0)
        x_out = p2 + np.maximum(t3, 0.0)[:, None] * d3
        x = np.where(inside[:, None], x_in, x_out)
        w = g * np.where(inside, w_in, np.where(out, w_out, 0.0))
        u, v = (x - p0) @ eu, (x - p0) @ ev
        tot[2] += w.sum()
        tot[3] += (w * w).sum()
        tot[4] += (w * u).sum()
        tot[5] += (w * v).sum()
        if grid is not None:
            g_sum += np.histogram2d(u, v, bins=(u_edges, v_edges), weights=w)[0]
            g_sq += np.histogram2d(u, v, bins=(u_edges, v_edges), weights=w * w)[0]
        if rings is not None:
            rho = np.hypot(u - r_center[0], v - r_center[1])
            r_sum += np.histogram(rho, bins=r_edges, weights=w)[0]
            r_sq += np.histogram(rho, bins=r_edges, weights=w * w)[0]
    seconds = time.perf_counter() - t0

    def mean_se(s, sq):
        mean = s / n_rays
        return mean, np.sqrt(np.maximum(sq / n_rays - mean * mean, 0.0) / n_rays)

    f_in, f_in_se = mean_se(tot[0], tot[1])
    f_pl, f_pl_se = mean_se(tot[2], tot[3])
    centroid = (tot[4] / tot[2], tot[5] / tot[2]) if tot[2] > 0.0 else (math.nan, math.nan)
    out = dict(
        n_rays=n_rays,
        seconds=seconds,
        flux_into_lens=float(f_in),
        flux_into_lens_se=float(f_in_se),
        flux_on_plane=float(f_pl),
        flux_on_plane_se=float(f_pl_se),
        centroid=centroid,
    )
    if grid is not None:
        area = np.outer(np.diff(u_edges), np.diff(v_edges))
        mean, se = mean_se(g_sum, g_sq)
        out.update(
            u_edges=u_edges, v_edges=v_edges, irradiance=mean / area, irradiance_se=se / area
        )
    if rings is not None:
        area = np.pi * np.diff(r_edges**2)
        mean, se = mean_se(r_sum, r_sq)
        out.update(
            ring_center=r_center, ring_edges=r_edges, ring_irradiance=mean / area, ring_se=se / area
        )
    return PlaneIrradiance(**out)


def lens_shadow(emitter, lens, plane, u, v, n_samples=64, seed=0):
    """Fraction (0..1) of the emitter that the lens hides from each plane point
    ``(u, v)`` (arrays of one shape): 1 in the umbra, 0 where the lens casts no
    shadow.  Samples of the emitter: its position (a point light), its disc as seen
    from the point (a sphere light, which looks like a uniform disc), directions in
    its cone (a sun), points of its surface (an area light; unweighted by cosines,
    a region mask rather than an irradiance).  Blockers are not considered."""
    q = plane.to_world(u, v).reshape(-1, 3)
    rng = np.random.default_rng(seed)
    c, R = lens.c, lens.radius
    k = int(n_samples)
    if isinstance(emitter, SunLight):
        rays = emitter.sample(c, R, k, rng)
        dirs = np.broadcast_to(-rays.direction[None], (q.shape[0], k, 3))
        starts = np.broadcast_to(q[:, None], dirs.shape)
        t_end = np.full(dirs.shape[:2], np.inf)
    else:
        if isinstance(emitter, (PointLight, SpotLight)):
            pos = np.asarray(emitter.position, float)
            r = emitter.radius
            rho, phi = np.sqrt(rng.random(k)), 2.0 * np.pi * rng.random(k)
            to_l = unit(pos[None] - q)
            a = unit(
                np.cross(to_l, np.where(np.abs(to_l[:, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]]))
            )
            b = np.cross(to_l, a)
            off = (r * rho * np.cos(phi))[None, :, None] * a[:, None] + (r * rho * np.sin(phi))[
                None, :, None
            ] * b[:, None]
            pts = pos + off
        else:
            pts = np.broadcast_to(emitter.sample(c, R, k, rng).origin[None], (q.shape[0], k, 3))
        vec = pts - q[:, None]
        t_end = np.linalg.norm(vec, axis=2)
        dirs = vec / t_end[..., None]
        starts = np.broadcast_to(q[:, None], dirs.shape)
    tn, tf, hit = sphere_hits(
        starts.reshape(-1, 3), np.ascontiguousarray(dirs).reshape(-1, 3), c, R
    )
    blocked = hit & (tf > 0.0) & (tn < t_end.reshape(-1))
    return blocked.reshape(q.shape[0], k).mean(axis=1).reshape(np.shape(u))
