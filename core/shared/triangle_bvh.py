"""A triangle BVH built in numpy and vectorised ray casting (nearest hit, barycentrics).

The BVH is a linear one: triangles sorted by the Morton code of their centroids, cut
into leaves of ``leaf_size`` consecutive triangles, and an implicit complete binary tree
over the leaves (level ℓ has 2^ℓ nodes; node i's children are 2i and 2i + 1), its boxes
reduced bottom-up. No pointers and no Python loop over triangles: building is a sort and
a few reductions. Traversal is breadth-first over (ray, node) pairs: at each level every
pair's box is slab-tested at once and the survivors expand into their two children; at
the leaves the pairs become (ray, triangle) Möller–Trumbore tests and the nearest hit
beyond ``t_min`` wins. Rays are processed in chunks to bound memory, blocks of them in
threads (`core.shared.parallel`: numpy's loops let go of the GIL). Used by the caustic
layer's receivers and by the glass meshes of `core.lens.mesh` (a convex one's waves walk
its surface first, `core.shared.surface_walk`, with this module's triangle test).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import parallel
from .vectors import column_bounds, corner_bounds, corner_mean, cross, dot, norm

#: Rays below which a cast runs in the calling thread alone.
THREAD_ROWS = 8192


@dataclass(frozen=True)
class TriangleBvh:
    vertices: np.ndarray  # (V, 3) as given
    triangles: np.ndarray  # (T, 3) as given
    leaf_size: int
    tri_index: np.ndarray  # (n_leaves · leaf_size,) triangle of each slot, −1 = padding
    v0: np.ndarray  # (slots, 3) first vertex of each slot's triangle
    e1: np.ndarray  # (slots, 3) edge v1 − v0
    e2: np.ndarray  # (slots, 3) edge v2 − v0
    normal: np.ndarray  # (slots, 3) e1 × e2 (not unit)
    edge_scale: np.ndarray  # (slots,) |e1| |e2| (the degenerate-triangle test's scale)
    lo: list[np.ndarray]  # per level (2^ℓ, 3) box minima (NaN: empty)
    hi: list[np.ndarray]  # per level (2^ℓ, 3) box maxima (NaN: empty)
    boxes: list[np.ndarray]  # per level (6, 2^ℓ): minima then maxima, for the traversal
    cones: list[np.ndarray]  # per level (4, 2^ℓ): a cone holding the faces' normals:
    #                          unit axis, then sin of its half-angle (2: 90° or more)
    # (slots, 13): normal, v0, e1, e2, edge_scale side by side, so that a test of many
    # small batches (a surface walk's steps) gathers each slot's row once, not five times
    packed: np.ndarray | None = None


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
    cen = corner_mean(corners)
    if len(tris):
        lo_c, hi_c = column_bounds(cen)
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
    c_lo, c_hi = corner_bounds(c)
    tlo = np.where(pad[:, None], np.nan, c_lo).reshape(-1, leaf_size, 3)
    thi = np.where(pad[:, None], np.nan, c_hi).reshape(-1, leaf_size, 3)
    with np.errstate(invalid="ignore"):
        lo = [np.fmin.reduce(tlo, axis=1)]
        hi = [np.fmax.reduce(thi, axis=1)]
        while len(lo[0]) > 1:
            lo.insert(0, np.fmin(lo[0][0::2], lo[0][1::2]))
            hi.insert(0, np.fmax(hi[0][0::2], hi[0][1::2]))
    e1, e2 = c[:, 1] - c[:, 0], c[:, 2] - c[:, 0]
    normal = cross(e1, e2)
    edge_scale = np.linalg.norm(e1, axis=1) * np.linalg.norm(e2, axis=1)
    return TriangleBvh(
        cones=_normal_cones(c, pad, leaf_size, len(lo)),
        vertices=v,
        triangles=tris,
        leaf_size=leaf_size,
        tri_index=tri_index,
        v0=c[:, 0],
        e1=e1,
        e2=e2,
        normal=normal,
        edge_scale=edge_scale,
        packed=np.concatenate([normal, c[:, 0], e1, e2, edge_scale[:, None]], axis=1),
        lo=lo,
        hi=hi,
        boxes=[
            np.ascontiguousarray(np.concatenate([a, b], axis=1).T)
            for a, b in zip(lo, hi, strict=True)
        ],
    )


def _normal_cones(c, pad, leaf_size, levels):
    """Per level (4, 2^ℓ): the axis (unit) and sin of the half-angle of a cone holding
    the unit winding normals of every triangle below each node; a cone of 90° or more
    (or an empty node) gets 2, never culling."""
    n = cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0])
    n /= np.maximum(np.linalg.norm(n, axis=1), 1e-300)[:, None]
    n = np.where(pad[:, None], np.nan, n).reshape(-1, leaf_size, 3)
    with np.errstate(invalid="ignore"):
        axis = np.nansum(n, axis=1)
        axis /= np.maximum(np.linalg.norm(axis, axis=1), 1e-300)[:, None]
        ang = np.fmax.reduce(_angle(n, axis[:, None, :]), axis=1)
        ang = np.where(np.isnan(ang), np.pi, ang)
        axes, angs = [axis], [ang]
        while len(axes[0]) > 1:
            a, b = axes[0][0::2], axes[0][1::2]
            m = a + b
            m /= np.maximum(np.linalg.norm(m, axis=1), 1e-300)[:, None]
            spread = [_angle(m, x) + g for x, g in ((a, angs[0][0::2]), (b, angs[0][1::2]))]
            axes.insert(0, m)
            angs.insert(0, np.minimum(np.maximum(*spread), np.pi))
    out = []
    for a, g in zip(axes, angs, strict=True):
        sin = np.where(g < 0.5 * np.pi, np.sin(g), 2.0)
        out.append(np.ascontiguousarray(np.concatenate([a.T, sin[None]], axis=0)))
    assert len(out) == levels
    return out


def _angle(a, b):
    """Angle between unit vectors (…, 3), by atan2 (exact near 0 and π); π where one
    is zero (an axis of normals that cancel: no cone narrower than all directions)."""
    ang = np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1), np.sum(a * b, axis=-1))
    zero = (np.sum(a * a, axis=-1) < 0.25) | (np.sum(b * b, axis=-1) < 0.25)
    return np.where(zero, np.pi, ang)


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


def intersect(
    bvh: TriangleBvh, origins, dirs, t_min=0.0, t_max=np.inf, chunk: int = 16384, facing=None
) -> Hits:
    """Nearest hit with ``t_min < t ≤ t_max`` (per ray or scalar) of the rays
    ``origins + t · dirs`` ((N, 3) each; ``dirs`` need not be unit, ``t`` is in its
    units). Triangles are two-sided, unless ``facing`` (per ray or scalar) says which
    side counts: +1 only triangles whose winding normal faces the ray (``d · n < 0``),
    −1 only those it leaves by, 0 both. A ray with a side stops at its first hit
    found: for a convex mesh that is the only one (one way in, one way out)."""
    o, d, t_min, t_max = ray_arrays(origins, dirs, t_min, t_max)
    n = len(o)
    tri, tt, uu, vv = no_hits(n)
    side = np.broadcast_to(np.asarray(0 if facing is None else facing, dtype=np.int8), (n,))

    def run(block: slice):  # chunks of one block, in one thread
        for s in range(block.start, block.stop, chunk):
            sl = slice(s, min(block.stop, s + chunk))
            tri[sl], tt[sl], uu[sl], vv[sl] = _intersect_chunk(
                bvh, o[sl], d[sl], t_min[sl], t_max[sl], side[sl]
            )

    # each ray's hit is its own: blocks of rays in threads give the same hits
    parallel.map_slices(run, n, min_rows=THREAD_ROWS)
    point = o + np.where(np.isfinite(tt), tt, 0.0)[:, None] * d
    return Hits(triangle=tri, t=tt, u=uu, v=vv, point=point)


#: The traversal goes breadth-first down to this level, then subtree by subtree in the
#: order each ray enters them, a subtree starting beyond the best hit so far skipped.
SPLIT_LEVEL = 6


def _intersect_chunk(bvh, o, d, t_min, t_max, side):
    n = len(o)
    # 1/d with zero components replaced by a tiny signed number: slabs stay finite.
    safe = np.where(np.abs(d) < 1e-300, np.where(d < 0.0, -1e-300, 1e-300), d)
    inv = 1.0 / safe
    unit = d / np.maximum(norm(d), 1e-300)[:, None]
    rays = np.ascontiguousarray(np.concatenate([inv, o * inv, unit], axis=1).T)  # (9, n)
    depth = len(bvh.lo) - 1
    split = min(depth, SPLIT_LEVEL)
    sided = side if np.any(side) else None
    ray, node, near = _descend(
        bvh, rays, t_min, t_max, np.arange(n), np.zeros(n, np.int64), -1, split, sided
    )
    tri = np.full(n, -1, dtype=np.int64)
    best = t_max.copy()
    uu = np.zeros(n)
    vv = np.zeros(n)
    dn = norm(d)
    done = np.zeros(n, dtype=bool)  # rays with a side are done at their first hit
    for r, nd in _nearest_first(ray, node, near, n, best, done):
        r, nd, nr_ = _descend(bvh, rays, t_min, best, r, nd, split, depth, sided)
        _test_leaves(bvh, o, d, dn, t_min, best, tri, uu, vv, r, nd, nr_, side, done)
    tt = np.where(tri >= 0, best, np.inf)
    return tri, tt, uu, vv


def _descend(bvh, rays, t_min, t_max, ray, node, level, depth, side=None):
    """The (ray, node) pairs at ``level`` (−1: before the root) down to the pairs at
    ``depth`` whose boxes the rays cross within (t_min, t_max]; two levels (four
    boxes) a step. A ray with a ``side`` skips a node whose normal cone has no face on
    that side of it. Returns (ray, node, key): the near distance, the order in which
    the ray's boxes are opened; −far for a ray leaving a convex mesh (the one face it
    leaves by is where it leaves the boxes last, not in those around its origin)."""
    near = np.zeros(len(ray))
    far = np.zeros(len(ray))
    with np.errstate(invalid="ignore"):
        while level < depth:
            step = 1 if level < 0 or level + 2 > depth else 2
            fan = 1 << step if level >= 0 else 1
            child = (node[:, None] << step) | np.arange(fan) if level >= 0 else node[:, None]
            boxes = bvh.boxes[level + step]  # (6, 2^ℓ)
            near = far = None
            for axis in range(3):
                ir = rays[axis, ray][:, None]
                oi = rays[3 + axis, ray][:, None]
                t1 = boxes[axis][child] * ir - oi
                t2 = boxes[3 + axis][child] * ir - oi
                lo_t, hi_t = np.minimum(t1, t2), np.maximum(t1, t2)
                near = lo_t if near is None else np.maximum(near, lo_t)
                far = hi_t if far is None else np.minimum(far, hi_t)
            keep = (near <= far) & (far >= t_min[ray][:, None]) & (near <= t_max[ray][:, None])
            if side is not None:  # d·n over the cone spans d·a ± sin(half-angle)
                cone = bvh.cones[level + step]
                da = sum(cone[i][child] * rays[6 + i, ray][:, None] for i in range(3))
                sd = side[ray][:, None]
                sn = cone[3][child]
                keep &= ~(((sd < 0) & (da <= -sn)) | ((sd > 0) & (da >= sn)))
            ray = np.broadcast_to(ray[:, None], keep.shape)[keep]
            node = child[keep]
            near, far = near[keep], far[keep]
            level += step
    if side is None:
        return ray, node, near
    return ray, node, np.where(side[ray] < 0, -far, near)


def _nearest_first(ray, node, near, n, best, done=None):
    """Rounds of (ray, node) pairs: each ray's nearest box, its next, then the next 2,
    4 …, a box that starts beyond the ray's ``best`` hit so far (read at each round)
    left out."""
    order = np.lexsort((near, ray))
    ray, node, near = ray[order], node[order], near[order]
    rank = np.arange(len(ray)) - np.searchsorted(ray, np.arange(n))[ray]
    lo, width = 0, 1
    while len(ray):
        now = rank < lo + width
        r, nd, nr_ = ray[now], node[now], near[now]
        go = nr_ <= best[r]  # a key −far ≤ 0 < best: never pruned, ended by `done`
        if done is not None:
            go &= ~done[r]
        yield r[go], nd[go]
        ray, node, near, rank = ray[~now], node[~now], near[~now], rank[~now]
        lo += width
        width = width if lo < 2 else 2 * width


def _test_leaves(bvh, o, d, dn, t_min, best, tri, uu, vv, ray, node, near, side, done):
    """The leaves' triangles against their rays, nearest box first; the nearest hit
    beyond ``t_min`` and before ``best`` updates (best, tri, uu, vv) in place (a ray
    with a ``side`` only by triangles on that side, and its first)."""
    ls = bvh.leaf_size
    for r, nd in _nearest_first(ray, node, near, len(o), best, done):
        r = np.repeat(r, ls)
        slot = np.repeat(nd, ls) * ls + np.tile(np.arange(ls), len(nd))
        live = bvh.tri_index[slot] >= 0
        r, slot = r[live], slot[live]
        t, u, v, ok, det = hit_slots(bvh, o[r], d[r], dn[r], slot)
        ok &= (t > t_min[r]) & (t <= best[r]) & (det * side[r] >= 0.0)
        r, slot, t, u, v = r[ok], slot[ok], t[ok], u[ok], v[ok]
        if len(r) == 0:
            continue
        first = np.lexsort((t, r))
        r, slot, t, u, v = r[first], slot[first], t[first], u[first], v[first]
        head = np.ones(len(r), dtype=bool)
        head[1:] = r[1:] != r[:-1]
        r, slot, t, u, v = r[head], slot[head], t[head], u[head], v[head]
        better = t < best[r]
        r, slot, t, u, v = r[better], slot[better], t[better], u[better], v[better]
        tri[r], best[r], uu[r], vv[r] = bvh.tri_index[slot], t, u, v
        done[r] = side[r] != 0


def hit_slots(bvh, o, d, dn, slot):
    """Möller–Trumbore against the slots' triangles with their normals precomputed
    (one cross product per pair): ``det = −d·n``, ``u = e2·(s×d)/det``,
    ``v = −e1·(s×d)/det``, ``t = s·n/det`` with ``s = o − v0``; the same tolerances
    as :func:`moller_trumbore`."""
    row = bvh.packed[slot]
    nrm = row[:, 0:3]
    det = -dot(d, nrm)
    ok = np.abs(det) > 1e-14 * row[:, 12] * dn
    inv = 1.0 / np.where(ok, det, 1.0)
    s = o - row[:, 3:6]
    sx, sy, sz = s[:, 0], s[:, 1], s[:, 2]
    dx, dy, dz = d[:, 0], d[:, 1], d[:, 2]
    c = np.empty_like(s)
    c[:, 0] = sy * dz - sz * dy
    c[:, 1] = sz * dx - sx * dz
    c[:, 2] = sx * dy - sy * dx
    u = dot(row[:, 9:12], c) * inv
    v = -dot(row[:, 6:9], c) * inv
    t = dot(s, nrm) * inv
    eps = 1e-12
    ok &= (u >= -eps) & (v >= -eps) & (u + v <= 1.0 + eps)
    return t, u, v, ok, det


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
