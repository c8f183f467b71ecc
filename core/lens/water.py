"""Water as a lens: an open refracting surface (a displaced plane's triangles) with the
water below it, the light arriving from the air above.

Unlike a glass mesh (`mesh`), the light does not leave the medium again: the receivers
(a pool's floor and walls, the sea bed) lie inside it. So one crossing is traced: the
first hit from above through the triangle BVH, Snell with the shading normal (Blender's
corner normals interpolated, as `mesh` does) and the unpolarised Fresnel transmittance
(the mean of the s and p parts). What happens further down (the depth travelled, its
Beer absorption, the landing) is the caustic layer's (`caustic_layer.water_beam`).

The first hits are found through a grid over the rest plane (`slab_grid`), the
triangle BVH taking the rays that graze the sheet. The surface's rest plane (its
least-squares plane, normal up toward +Z) parametrises
the rays: a ray is named by where it crosses that plane, so a regular grid over the
plane is a regular grid of rays however the waves move.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..shared.triangle_bvh import build_bvh
from ..shared.triangle_bvh import intersect as bvh_intersect
from .base import ExitRays, Lens
from .refraction import fresnel_from_cosines, refract
from .slab_grid import build_slab_grid
from .slab_grid import intersect as slab_intersect

#: The index Blender users give water (Blender's own IOR preset for water).
WATER_IOR = 1.333


def _dot(a, b):
    return np.einsum("...i,...i->...", a, b)


def _unit(v):
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.where(n > 0.0, n, 1.0)


@dataclass(frozen=True)
class RestPlane:
    """The surface's rest plane: ``origin`` (the vertices' centroid), unit ``normal``
    (up: toward +Z, or the side the light comes from when the plane is vertical),
    in-plane unit axes ``axis_u`` × ``axis_v`` = ``normal``, the vertices' extent along
    them (``u_range``, ``v_range``) and their heights above and below (``top``,
    ``bottom``: the most a wave rises or sinks along the normal)."""

    origin: np.ndarray
    normal: np.ndarray
    axis_u: np.ndarray
    axis_v: np.ndarray
    u_range: tuple[float, float]
    v_range: tuple[float, float]
    top: float
    bottom: float

    def point(self, u, v) -> np.ndarray:
        """World points (…, 3) at plane coordinates (u, v)."""
        u, v = np.asarray(u, dtype=float), np.asarray(v, dtype=float)
        return self.origin + u[..., None] * self.axis_u + v[..., None] * self.axis_v


def rest_plane(vertices, triangles=None) -> RestPlane:
    """The least-squares plane of ``vertices`` (V, 3) (its normal: the smallest
    principal axis, turned toward +Z) and the vertices' extent in it. The in-plane
    axes follow the mesh's edges (``triangles`` given: the length-weighted mean of
    their directions modulo 90°, so a grid's rows and columns; else the principal
    axes), so a rectangle's ray grid is not turned across its corners."""
    v = np.asarray(vertices, dtype=float).reshape(-1, 3)
    c = v.mean(axis=0)
    _, _, vt = np.linalg.svd(v - c, full_matrices=False)
    n = vt[2] / np.linalg.norm(vt[2])
    if n[2] < 0.0 or (n[2] == 0.0 and n.sum() < 0.0):
        n = -n
    au = vt[0] - (vt[0] @ n) * n
    au /= np.linalg.norm(au)
    av = np.cross(n, au)
    if triangles is not None and len(triangles):
        t = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
        e = (v[t[:, [1, 2, 0]]] - v[t]).reshape(-1, 3)
        x, y = e @ au, e @ av
        w = np.hypot(x, y)
        a4 = 4.0 * np.arctan2(y, x)
        turn = 0.25 * np.arctan2((w * np.sin(a4)).sum(), (w * np.cos(a4)).sum())
        au, av = (
            np.cos(turn) * au + np.sin(turn) * av,
            np.cross(n, np.cos(turn) * au + np.sin(turn) * av),
        )
    rel = v - c
    pu, pv, h = rel @ au, rel @ av, rel @ n
    return RestPlane(
        c, n, au, av, (float(pu.min()), float(pu.max())), (float(pv.min()), float(pv.max())),
        float(h.max()), float(h.min()),
    )  # fmt: skip


@dataclass(frozen=True)
class WaterHits:
    """Rays (N) at the water surface: ``hit`` (met it from above), the hit ``points``
    (N, 3), the refracted unit ``directions`` into the water, the Fresnel
    ``transmittance`` (s/p mean; 0 where missed) and the cosine of incidence."""

    hit: np.ndarray
    points: np.ndarray
    directions: np.ndarray
    transmittance: np.ndarray
    cos_i: np.ndarray


class WaterSurface(Lens):
    """An open triangle mesh with water (index ``ior``) below it: ``vertices`` (V, 3)
    world coordinates, ``triangles`` (T, 3), ``corner_normals`` (T, 3, 3) as Blender
    shades (None: flat); ``absorption``: Beer per unit length in the water, RGB (a
    scalar for grey). The BVH, the rest plane and the grid over it (`slab_grid`: the
    first hits of a sheet, the BVH for grazing rays) are built once, here."""

    def __init__(self, vertices, triangles, corner_normals=None, ior=WATER_IOR, absorption=0.0):
        self.vertices = np.asarray(vertices, dtype=float).reshape(-1, 3)
        self.triangles = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
        self.ior = float(ior)
        self.absorption = np.broadcast_to(np.asarray(absorption, dtype=float), (3,)).copy()
        corners = self.vertices[self.triangles]
        cross = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
        self.face_normals = _unit(cross)
        if corner_normals is None:
            cn = np.repeat(self.face_normals[:, None, :], 3, axis=1)
        else:
            cn = _unit(np.asarray(corner_normals, dtype=float).reshape(-1, 3, 3))
        self.corner_normals = cn
        self.plane = rest_plane(self.vertices, self.triangles)
        self.center = self.vertices.mean(axis=0)
        self.radius = float(np.linalg.norm(self.vertices - self.center, axis=1).max(initial=0.0))
        self.eps = 1e-7 * max(self.radius, 1e-9)
        self.bvh = build_bvh(self.vertices, self.triangles)
        self.grid = build_slab_grid(self.vertices, self.triangles, self.plane)

    # ------------------------------------------------------------------ the Lens interface

    def bounding_sphere(self):
        return self.center, np.asarray(self.radius)

    def intersect(self, origins, directions):
        o, d = _flat(origins, directions)
        h = bvh_intersect(self.bvh, o, d)
        hit = h.triangle >= 0
        nrm = np.where(hit[:, None], self.face_normals[np.maximum(h.triangle, 0)], 0.0)
        shape = np.shape(directions)[:-1]
        return h.t.reshape(shape), nrm.reshape((*shape, 3))

    def trace(self, origins, directions, aimed: bool = False) -> ExitRays:
        """Into the water: the points on the surface, the refracted directions, the
        Fresnel transmittance (the light stays in the water: no second crossing)."""
        shape = np.shape(directions)[:-1]
        w = self.enter(origins, directions)
        return ExitRays(
            w.points.reshape((*shape, 3)),
            w.directions.reshape((*shape, 3)),
            w.transmittance.reshape(shape),
            w.hit.reshape(shape),
            np.zeros(shape),
        )

    # ------------------------------------------------------------------ the crossing

    def enter(self, origins, directions) -> WaterHits:
        """The first crossing of each ray (N, 3) from the air into the water."""
        o, d = _flat(origins, directions)
        d = _unit(d)
        h = slab_intersect(self.grid, self.bvh, o, d)
        hit = h.triangle >= 0
        tri = np.maximum(h.triangle, 0)
        ng = self.face_normals[tri]
        facing = np.where((_dot(d, ng) > 0.0)[:, None], -ng, ng)  # toward the air side
        bary = np.stack([1.0 - h.u - h.v, h.u, h.v], axis=1)
        ns = _unit(np.einsum("nk,nki->ni", bary, self.corner_normals[tri]))
        ns = np.where((_dot(ns, facing) < 0.0)[:, None], -ns, ns)
        # a shading normal the ray meets from behind, or that bends it back up: the
        # geometric one there (as `mesh` does; continuous where both agree)
        nrm = np.where((_dot(d, ns) >= 0.0)[:, None], facing, ns)
        rf = refract(d, nrm, 1.0 / self.ior)
        bad = _dot(rf.directions, facing) >= 0.0
        if bad.any():
            nrm = np.where(bad[:, None], facing, nrm)
            rf = refract(d, nrm, 1.0 / self.ior)
        ts, tp = fresnel_from_cosines(rf.cos_i, rf.cos_t, 1.0, self.ior)
        trans = np.where(hit, 0.5 * (ts + tp), 0.0)
        pts = np.where(hit[:, None], h.point, o)
        dirs = np.where(hit[:, None], rf.directions, d)
        return WaterHits(hit, pts, dirs, trans, np.where(hit, rf.cos_i, 0.0))


def _flat(origins, directions):
    o, d = np.broadcast_arrays(
        np.asarray(origins, dtype=float), np.asarray(directions, dtype=float)
    )
    return o.reshape(-1, 3), d.reshape(-1, 3)
