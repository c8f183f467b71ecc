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


def trace_water_beams(
    source: WaterSource, index: ReceiverIndex, shape: tuple[int, int]
) -> list[BeamGrid]:
    """The beams of one light through one water surface: a (K, ny+1, nx+1) node grid
    (``shape`` = (ny, nx) cells; K samples of the emitter), one beam, or three (R, G,
    B) where the water's absorption differs per channel."""
    surf = source.surface
    pl = surf.plane
    ny, nx = int(shape[0]), int(shape[1])
    # the outer nodes a hair inside the rim, so that they meet the water (a node
    # missing it would take half its cells' flux away along the edge)
    eu = 1e-7 * (pl.u_range[1] - pl.u_range[0])
    ev = 1e-7 * (pl.v_range[1] - pl.v_range[0])
    u = np.linspace(pl.u_range[0] + eu, pl.u_range[1] - eu, nx + 1)
    v = np.linspace(pl.v_range[0] + ev, pl.v_range[1] - ev, ny + 1)
    cell_area = (u[1] - u[0]) * (v[1] - v[0])
    plane_pts = pl.point(u[None, :], v[:, None])  # (ny+1, nx+1, 3)
    sm = source_samples(source.emitter, _lens_record(surf), source.n_source)
    k = len(sm.weights)
    lift = (pl.top + 1e-3 * max(surf.radius, 1e-9)) * 2.0 + 1e-6  # above every wave
    if sm.parallel:
        dirs = np.broadcast_to(sm.directions[:, None, None, :], (k, ny + 1, nx + 1, 3))
        cos = np.abs(dirs @ pl.normal)
        back = lift / np.maximum(cos, 1e-6)
        origins = plane_pts[None] - back[..., None] * dirs
        dens = sm.weights[:, None, None] * cos
        valid = sm.directions @ pl.normal < 0.0  # the sun above the water
    else:
        rel = plane_pts[None] - sm.points[:, None, None, :]
        r = np.linalg.norm(rel, axis=-1)
        dirs = rel / np.maximum(r, 1e-300)[..., None]
        origins = np.broadcast_to(sm.points[:, None, None, :], dirs.shape)
        cos = np.abs(dirs @ pl.normal)
        ang = 1.0 if is_isotropic(sm.emitter) else angular_factor(sm.emitter, dirs)
        dens = sm.weights[:, None, None] * ang * cos / np.maximum(r * r, 1e-300)
        # a light above every wave (one under or among them is not modelled)
        valid = (sm.points - pl.origin) @ pl.normal > pl.top
    wh = surf.enter(origins.reshape(-1, 3), dirs.reshape(-1, 3))
    depth, landed = _depths(index, wh.points, wh.directions, source.own_object)
    base = dens.reshape(-1) * wh.transmittance / (surf.ior * surf.ior)
    base = np.where(wh.hit & landed, base, 0.0) * np.repeat(valid, (ny + 1) * (nx + 1))
    color = np.asarray(getattr(source.emitter, "color", (1.0, 1.0, 1.0)), dtype=float)
    a = surf.absorption
    channels = (
        [(color, a[0])]
        if np.all(a == a[0])
        else [(color * e, a[c]) for c, e in enumerate(np.eye(3))]
    )
    out = []
    pts = wh.points.reshape(k, ny + 1, nx + 1, 3)
    dr = wh.directions.reshape(k, ny + 1, nx + 1, 3)
    for col, alpha in channels:
        g = (base * np.exp(-alpha * depth)).reshape(k, ny + 1, nx + 1)
        cells = 0.25 * cell_area * (g[:, :-1, :-1] + g[:, 1:, :-1] + g[:, 1:, 1:] + g[:, :-1, 1:])
        out.append(
            BeamGrid(
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
                traced_rays=int(k * (ny + 1) * (nx + 1)),
            )
        )
    return out
