"""The beam of a light through a water surface, landed on the receivers under water.

A regular grid of rays over the surface's rest plane (`core.lens.water.RestPlane`):
node (i, j) is the ray crossing the plane at (u_j, v_i) — from the light's sample point
(a point, spot or area light) or along the sun's direction. Each node ray enters the
water (`WaterSurface.enter`: first hit, Snell, Fresnel) and runs down to the first
receiver (Beer over that depth). The flux density per unit plane area at a node is

    sun:    S · |d·n| · T · exp(−α·depth) / n²
    point:  I · A(d) · |d·n| / r² · T · exp(−α·depth) / n²

(S the sun's irradiance, I the intensity, A the spot or area light's pattern, r the
distance to the plane point, n the plane's normal). The 1/n²: Cycles applies no n²
radiance scaling at a refraction, so its own caustic on a floor in water is E/n² of the
physical irradiance, and the layer carries what Cycles would render (SPEC §9). Each
cell carries its area times the mean of its corners' densities; the layer
(`rasters.build_layer`) spreads it over the landed quad, where quads fold past a focus
their flux adds.

The grids are `BeamGrid`s whose last column of cells (a `BeamGrid`'s azimuth wraps
from the last node column to the first; a plane grid does not) is empty. An absorption
that differs per colour channel makes three beams, one per channel, each with its own
Beer.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..lens.water import WaterSurface
from .beam_trace import BeamGrid
from .emitters import Lens, angular_factor, is_isotropic, source_samples
from .receiver_index import ReceiverIndex, intersect

#: Node rays per grid side at most (a 10 m pool at 2 cm: 500).
MAX_SIDE = 1024
#: Sub-rays per side of a cell the water's rim cuts.
RIM_SPLIT = 4


@dataclass(frozen=True)
class WaterSource:
    """A primary light over a water surface: the emitter (`emitters` data), the
    surface, samples of an extended emitter, and the object id of the surface's own
    mesh among the receivers (−1: not there)."""

    emitter: object
    surface: WaterSurface
    n_source: int = 1
    own_object: int = -1


def grid_shape(surface: WaterSurface, n_rays: int) -> tuple[int, int]:
    """(cells along v, cells along u) of about ``n_rays`` square cells over the
    surface's extent, each side at most `MAX_SIDE`."""
    p = surface.plane
    lu = max(p.u_range[1] - p.u_range[0], 1e-12)
    lv = max(p.v_range[1] - p.v_range[0], 1e-12)
    h = math.sqrt(lu * lv / max(n_rays, 1))
    return (
        int(np.clip(round(lv / h), 2, MAX_SIDE)),
        int(np.clip(round(lu / h), 2, MAX_SIDE)),
    )


def _lens_record(surface: WaterSurface) -> Lens:
    """The `emitters.Lens` that `source_samples` aims at: the surface's bounding
    sphere (the samples of an extended light face it)."""
    return Lens(center=surface.center, radius=max(surface.radius, 1e-9), ior=surface.ior)


def _depths(index: ReceiverIndex, points, dirs, own_object: int) -> tuple[np.ndarray, np.ndarray]:
    """(distance, hit) of each ray to its first receiver, skipping the surface's own
    object (a few times: a wave seen from below)."""
    h = intersect(index, points, dirs, t_min=0.0)
    t, tri = h.t.copy(), h.triangle.copy()
    if own_object >= 0:
        ids = index.mesh.ids
        for _ in range(4):
            again = np.nonzero((tri >= 0) & (ids[np.maximum(tri, 0)] == own_object))[0]
            if not len(again):
                break
            h2 = intersect(index, points[again], dirs[again], t_min=t[again] * (1 + 1e-9) + 1e-12)
            t[again], tri[again] = h2.t, h2.triangle
    return np.where(tri >= 0, t, 0.0), tri >= 0


def _rays(sm, pl, plane_pts, lift):
    """Origins, unit directions and flux density per unit plane area (before the
    water) of the rays of every sample of ``sm`` through the plane points
    ``plane_pts`` (…, 3): arrays (K, …); and per sample whether it lights the water
    from above."""
    k = len(sm.weights)
    extra = (1,) * (plane_pts.ndim - 1)
    if sm.parallel:
        dirs = np.broadcast_to(sm.directions.reshape(k, *extra, 3), (k, *plane_pts.shape))
        cos = np.abs(dirs @ pl.normal)
        back = lift / np.maximum(cos, 1e-6)
        origins = plane_pts[None] - back[..., None] * dirs
        dens = sm.weights.reshape(k, *extra) * cos
        valid = sm.directions @ pl.normal < 0.0  # the sun above the water
        return origins, dirs, dens, valid
    rel = plane_pts[None] - sm.points.reshape(k, *extra, 3)
    r = np.linalg.norm(rel, axis=-1)
    dirs = rel / np.maximum(r, 1e-300)[..., None]
    origins = np.broadcast_to(sm.points.reshape(k, *extra, 3), dirs.shape)
    cos = np.abs(dirs @ pl.normal)
    ang = 1.0 if is_isotropic(sm.emitter) else angular_factor(sm.emitter, dirs)
    dens = sm.weights.reshape(k, *extra) * ang * cos / np.maximum(r * r, 1e-300)
    # a light above every wave (one under or among them is not modelled)
    valid = (sm.points - pl.origin) @ pl.normal > pl.top
    return origins, dirs, dens, valid


def _through(source, index, origins, dirs, dens, valid):
    """Every ray into the water and down to its receiver: (points on the surface,
    directions in the water, depth to the receiver, density in the water before
    Beer — Fresnel and 1/n² in, 0 where the ray misses the water or lands nowhere —,
    whether it met the water)."""
    surf = source.surface
    shape = dens.shape
    wh = surf.enter(origins.reshape(-1, 3), dirs.reshape(-1, 3))
    depth, landed = _depths(index, wh.points, wh.directions, source.own_object)
    base = dens.reshape(-1) * wh.transmittance / (surf.ior * surf.ior)
    on = np.broadcast_to(valid.reshape(-1, *(1,) * (len(shape) - 1)), shape).reshape(-1)
    base = np.where(wh.hit & landed & on, base, 0.0)
    return wh.points, wh.directions, depth, base, wh.hit


def trace_water_beams(
    source: WaterSource, index: ReceiverIndex, shape: tuple[int, int], rim: int = RIM_SPLIT
) -> list[BeamGrid]:
    """The beams of one light through one water surface: a (K, ny+1, nx+1) node grid
    (``shape`` = (ny, nx) cells; K samples of the emitter), one beam, or three (R, G,
    B) where the water's absorption differs per channel. A cell the water's rim cuts
    (some corners meet the water, some not) is traced again by ``rim`` × ``rim``
    sub-rays, each landed as a point with its share of the cell (the beam's
    ``parts``): the rim's light is neither lost nor drawn in the wrong shape."""
    surf = source.surface
    pl = surf.plane
    ny, nx = int(shape[0]), int(shape[1])
    # the outer nodes a hair inside the rim, so that they meet the water
    eu = 1e-7 * (pl.u_range[1] - pl.u_range[0])
    ev = 1e-7 * (pl.v_range[1] - pl.v_range[0])
    u = np.linspace(pl.u_range[0] + eu, pl.u_range[1] - eu, nx + 1)
    v = np.linspace(pl.v_range[0] + ev, pl.v_range[1] - ev, ny + 1)
    du, dv = u[1] - u[0], v[1] - v[0]
    plane_pts = pl.point(u[None, :], v[:, None])  # (ny+1, nx+1, 3)
    sm = source_samples(source.emitter, _lens_record(surf), source.n_source)
    k = len(sm.weights)
    lift = (pl.top + 1e-3 * max(surf.radius, 1e-9)) * 2.0 + 1e-6  # above every wave
    origins, dirs, dens, valid = _rays(sm, pl, plane_pts, lift)
    pts, dr, depth, base, met = _through(source, index, origins, dirs, dens, valid)
    met = met.reshape(k, ny + 1, nx + 1)
    corners = (met[:, :-1, :-1], met[:, 1:, :-1], met[:, 1:, 1:], met[:, :-1, 1:])
    n_met = sum(c.astype(np.int64) for c in corners)
    cut = (n_met > 0) & (n_met < 4) & valid[:, None, None]
    sub = _rim_rays(source, index, sm, pl, u, v, cut, rim, lift) if cut.any() and rim > 0 else None
    color = np.asarray(getattr(source.emitter, "color", (1.0, 1.0, 1.0)), dtype=float)
    a = surf.absorption
    channels = (
        [(color, a[0])]
        if np.all(a == a[0])
        else [(color * e, a[c]) for c, e in enumerate(np.eye(3))]
    )
    out = []
    pts = pts.reshape(k, ny + 1, nx + 1, 3)
    dr = dr.reshape(k, ny + 1, nx + 1, 3)
    n_sub = 0 if sub is None else len(sub[0])
    for col, alpha in channels:
        g = (base * np.exp(-alpha * depth)).reshape(k, ny + 1, nx + 1)
        cells = 0.25 * du * dv * (g[:, :-1, :-1] + g[:, 1:, :-1] + g[:, 1:, 1:] + g[:, :-1, 1:])
        cells = np.where(cut, 0.0, cells)  # drawn by the rim's sub-rays instead
        beam = BeamGrid(
            exit_points=pts,
            exit_dirs=dr,
            node_density=g,
            # the cells closing column nx onto column 0 (the azimuth's wrap): empty
            cell_flux=np.concatenate([cells, np.zeros((k, ny, 1))], axis=2),
            valid=valid,
            color=col,
            rotations=np.zeros((k, 2, 3)),
            center=surf.center,
            share_disc=sm.share_disc,
            share_cells=None,
            share_grid=1,
            traced_rays=int(k * (ny + 1) * (nx + 1)) + n_sub,
        )
        if sub is not None and n_sub:
            sp, sd, s_depth, s_flux = sub
            f = s_flux * np.exp(-alpha * s_depth) * (du * dv / rim**2)
            beam.parts = [_splats(sp, sd, f, col, surf.center)]
        out.append(beam)
    return out


def _rim_rays(source, index, sm, pl, u, v, cut, m, lift):
    """The m × m sub-rays of every cell ``cut`` (K, ny, nx) by the rim: (points on
    the water, directions, depths, density in the water before Beer), those that
    met the water."""
    kk, ii, jj = np.nonzero(cut)
    a = (np.arange(m) + 0.5) / m
    su = u[jj][:, None, None] + (u[1] - u[0]) * a[None, None, :]
    sv = v[ii][:, None, None] + (v[1] - v[0]) * a[None, :, None]
    su, sv = np.broadcast_arrays(su, sv)
    pts = pl.point(su, sv)  # (C, m, m, 3)
    origins, dirs, dens, valid = _rays(sm, pl, pts, lift)
    # each cut cell's own sample: (C, m, m) out of (K, C, m, m)
    c = np.arange(len(kk))
    origins, dirs, dens = origins[kk, c], dirs[kk, c], dens[kk, c]
    p, d, depth, base, met = _through(source, index, origins, dirs, dens, valid[kk])
    keep = met & (base > 0.0)
    return p[keep], d[keep], depth[keep], base[keep]


def _splats(points, dirs, flux, color, center) -> BeamGrid:
    """Points landed with their flux: cells whose four corners are one ray (nodes
    (S, 2, 1), as `mesh_beam`'s splats)."""
    n = len(flux)
    two = lambda x: np.stack([x, x], axis=1)[:, :, None]  # noqa: E731
    return BeamGrid(
        exit_points=two(points),
        exit_dirs=two(dirs),
        node_density=np.ones((n, 2, 1)),
        cell_flux=np.asarray(flux, dtype=float)[:, None, None],
        valid=np.ones(n, dtype=bool),
        color=color,
        rotations=np.zeros((n, 2, 3)),
        center=center,
    )
