"""A triangle BVH built in numpy and vectorised ray casting (nearest hit, barycentrics).

The BVH is a linear one: triangles sorted by the Morton code of their centroids, cut
into leaves of ``leaf_size`` consecutive triangles, and an implicit complete binary tree
over the leaves (level ℓ has 2^ℓ nodes; node i's children are 2i and 2i + 1), its boxes
reduced bottom-up. No pointers and no Python loop over triangles: building is a sort and
a few reductions. Traversal is breadth-first over (ray, node) pairs: at each level every
pair's box is slab-tested at once and the survivors expand into their two children; at
the leaves the pairs become (ray, triangle) Möller–Trumbore tests and the nearest hit
beyond ``t_min`` wins. Rays are processed in chunks to bound memory. Used by the caustic
layer's receivers and by the glass meshes of `core.lens.mesh`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class TriangleBvh:
    vertices: np.ndarray  # (V, 3) as given
    triangles: np.ndarray  # (T, 3) as given
    leaf_size: int
    tri_index: np.ndarray  # (n_leaves · leaf_size,) triangle of each slot, −1 = padding
    v0: np.ndarray  # (slots, 3) first vertex of each slot's triangle
    e1: np.ndarray  # (slots, 3) edge v1 − v0
    e2: np.ndarray  # (slots, 3) edge v2 − v0
    lo: list[np.ndarray]  # per level (2^ℓ, 3) box minima (NaN: empty)
    hi: list[np.ndarray]  # per level (2^ℓ, 3) box maxima (NaN: empty)
    lo_t: list[np.ndarray]  # the same, transposed (3, 2^ℓ) for the traversal
    hi_t: list[np.ndarray]


@dataclass(frozen=True)
class Hits:
    """Nearest hit of each ray: ``triangle`` (−1 = miss), distance ``t`` (inf on a miss),
    barycentrics ``u``, ``v`` (point = v0 + u e1 + v e2) and the hit ``point``."""

    triangle: np.ndarray
    t: np.ndarray
    u: np.ndarray
    v: np.ndarray
    point: np.ndarray


def morton(cells: np.ndarray) -> np.ndarray:
    """Interleave three 10-bit integer coordinates into a 30-bit Morton code."""

    def spread(x):
        x = x.astype(np.uint64) & 0x3FF
        x = (x | (x << 16)) & 0x030000FF
        x = (x | (x << 8)) & 0x0300F00F
        x = (x | (x << 4)) & 0x030C30C3
        return (x | (x << 2)) & 0x09249249

    return (spread(cells[:, 0]) << 2) | (spread(cells[:, 1]) << 1) | spread(cells[:, 2])


def build_bvh(vertices, triangles, leaf_size: int = 4) -> TriangleBvh:
    """Linear BVH of the triangles (see the module docstring)."""
    v = np.asarray(vertices, dtype=float)
    tris = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    corners = v[tris]  # (T, 3, 3)
    cen = corners.mean(axis=1)
    if len(tris):
        lo_c, hi_c = cen.min(axis=0), cen.max(axis=0)
    else:
        lo_c = hi_c = np.zeros(3)
    cells = ((cen - lo_c) / np.maximum(hi_c - lo_c, 1e-300) * 1023.0).astype(np.int64)
    order = np.argsort(morton(np.clip(cells, 0, 1023)), kind="stable")
    n_leaves = max(1, -(-len(tris) // leaf_size))
    depth = int(np.ceil(np.log2(n_leaves))) if n_leaves > 1 else 0
    slots = (1 << depth) * leaf_size
    tri_index = np.full(slots, -1, dtype=np.int64)
    tri_index[: len(order)] = order
    c = np.zeros((slots, 3, 3))
    c[: len(order)] = corners[order]
    pad = tri_index < 0
    # Empty boxes are NaN: every slab comparison with them is false (±inf would let
    # every ray through), and fmin/fmax skip them in the reductions.
    tlo = np.where(pad[:, None], np.nan, c.min(axis=1)).reshape(-1, leaf_size, 3)
    thi = np.where(pad[:, None], np.nan, c.max(axis=1)).reshape(-1, leaf_size, 3)
    with np.errstate(invalid="ignore"):
        lo = [np.fmin.reduce(tlo, axis=1)]
        hi = [np.fmax.reduce(thi, axis=1)]
        while len(lo[0]) > 1:
            lo.insert(0, np.fmin(lo[0][0::2], lo[0][1::2]))
            hi.insert(0, np.fmax(hi[0][0::2], hi[0][1::2]))
    return TriangleBvh(
        vertices=v,
        triangles=tris,
        leaf_size=leaf_size,
        tri_index=tri_index,
        v0=c[:, 0],
        e1=c[:, 1] - c[:, 0],
        e2=c[:, 2] - c[:, 0],
        lo=lo,
        hi=hi,
        lo_t=[np.ascontiguousarray(x.T) for x in lo],
        hi_t=[np.ascontiguousarray(x.T) for x in hi],
    )


def ray_arrays(origins, dirs, t_min, t_max):
    """Rays as (N, 3) origins and directions with per-ray ``t`` bounds."""
    o = np.asarray(origins, dtype=float).reshape(-1, 3)
    d = np.asarray(dirs, dtype=float).reshape(-1, 3)
    n = len(o)
    t_min = np.broadcast_to(np.asarray(t_min, dtype=float), (n,))
    t_max = np.broadcast_to(np.asarray(t_max, dtype=float), (n,))
    return o, d, t_min, t_max


def no_hits(n: int):
    """(triangle, t, u, v) columns of `n` rays that hit nothing yet."""
    return np.full(n, -1, dtype=np.int64), np.full(n, np.inf), np.zeros(n), np.zeros(n)


def intersect(bvh: TriangleBvh, origins, dirs, t_min=0.0, t_max=np.inf, chunk: int = 16384) -> Hits:
    """Nearest hit with ``t_min < t ≤ t_max`` (per ray or scalar) of the rays
    ``origins + t · dirs`` ((N, 3) each; ``dirs`` need not be unit, ``t`` is in its
    units). Triangles are two-sided."""
    o, d, t_min, t_max = ray_arrays(origins, dirs, t_min, t_max)
    n = len(o)
    tri, tt, uu, vv = no_hits(n)
    for s in range(0, n, chunk):
        sl = slice(s, min(n, s + chunk))
        tri[sl], tt[sl], uu[sl], vv[sl] = _intersect_chunk(bvh, o[sl], d[sl], t_min[sl], t_max[sl])
    point = o + np.where(np.isfinite(tt), tt, 0.0)[:, None] * d
    return Hits(triangle=tri, t=tt, u=uu, v=vv, point=point)


def _intersect_chunk(bvh, o, d, t_min, t_max):
    n = len(o)
    # 1/d with zero components replaced by a tiny signed number: slabs stay finite.
    safe = np.where(np.abs(d) < 1e-300, np.where(d < 0.0, -1e-300, 1e-300), d)
    inv = np.ascontiguousarray((1.0 / safe).T)  # (3, n): rows gather fastest
    oinv = np.ascontiguousarray((o / safe).T)
    ray = np.arange(n)
    node = np.zeros(n, dtype=np.int64)
    with np.errstate(invalid="ignore"):
        for level in range(len(bvh.lo)):
            ir, oi = inv[:, ray], oinv[:, ray]
            t1 = bvh.lo_t[level][:, node] * ir - oi
            t2 = bvh.hi_t[level][:, node] * ir - oi
            a, b = np.minimum(t1, t2), np.maximum(t1, t2)
            near = np.maximum(np.maximum(a[0], a[1]), a[2])
            far = np.minimum(np.minimum(b[0], b[1]), b[2])
            keep = (near <= far) & (far >= t_min[ray]) & (near <= t_max[ray])
            ray, node = ray[keep], node[keep]
            if level + 1 < len(bvh.lo):
                ray = np.repeat(ray, 2)
                node = (np.repeat(node, 2) << 1) | np.tile([0, 1], len(node))
    ls = bvh.leaf_size
    ray = np.repeat(ray, ls)
    slot = (np.repeat(node, ls) * ls) + np.tile(np.arange(ls), len(node))
    live = bvh.tri_index[slot] >= 0
    ray, slot = ray[live], slot[live]
    t, u, v, ok = moller_trumbore(o[ray], d[ray], bvh.v0[slot], bvh.e1[slot], bvh.e2[slot])
    ok &= (t > t_min[ray]) & (t <= t_max[ray])
    ray, slot, t, u, v = ray[ok], slot[ok], t[ok], u[ok], v[ok]
    first = np.lexsort((t, ray))
    ray, slot, t, u, v = ray[first], slot[first], t[first], u[first], v[first]
    head = np.ones(len(ray), dtype=bool)
    head[1:] = ray[1:] != ray[:-1]
    tri = np.full(n, -1, dtype=np.int64)
    tt = np.full(n, np.inf)
    uu = np.zeros(n)
    vv = np.zeros(n)
    r = ray[head]
    tri[r], tt[r], uu[r], vv[r] = bvh.tri_index[slot[head]], t[head], u[head], v[head]
    return tri, tt, uu, vv


def moller_trumbore(o, d, v0, e1, e2):
    """Two-sided Möller–Trumbore; returns (t, u, v, hit mask)."""
    p = np.cross(d, e2)
    det = np.einsum("ij,ij->i", e1, p)
    scale = np.linalg.norm(e1, axis=1) * np.linalg.norm(e2, axis=1) * np.linalg.norm(d, axis=1)
    ok = np.abs(det) > 1e-14 * scale
    inv = 1.0 / np.where(ok, det, 1.0)
    s = o - v0
    u = np.einsum("ij,ij->i", s, p) * inv
    q = np.cross(s, e1)
    v = np.einsum("ij,ij->i", d, q) * inv
    t = np.einsum("ij,ij->i", e2, q) * inv
    eps = 1e-12
    ok &= (u >= -eps) & (v >= -eps) & (u + v <= 1.0 + eps)
    return t, u, v, ok
