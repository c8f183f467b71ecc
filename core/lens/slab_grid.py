"""Nearest hits of rays on a thin sheet of triangles (a water surface) through a 2-D
grid over its rest plane: every triangle lies in the slab between the plane's
``bottom`` and ``top`` heights, so a ray can only meet the triangles binned in the
cells its stretch across that slab passes over — a few cells for any ray that is
not grazing. Each such (ray, triangle) pair is tested at once (Möller–Trumbore),
and the nearest hit kept. For a sheet this is many times faster than descending a
BVH (`core.shared.triangle_bvh`), which stays the path for the rays that cross the
slab so obliquely that they pass over more than `MAX_CELLS` cells.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..shared.triangle_bvh import Hits, TriangleBvh
from ..shared.triangle_bvh import intersect as bvh_intersect
from ..shared.vectors import cross

#: Cells a ray's stretch across the slab may pass over before the BVH takes it.
MAX_CELLS = 64
#: Rays per block (bounds the (ray, triangle) pairs held at once).
BLOCK = 16384


@dataclass(frozen=True)
class SlabGrid:
    """Triangles binned by their extent over the plane (origin, axes u, v, normal):
    cell (i, j) of ``shape`` (nv, nu), side ``cell``, from (u0, v0); ``start`` (cells
    + 1) and ``tris``: the triangles of each cell (CSR); ``bottom``/``top``: the slab."""

    origin: np.ndarray
    axis_u: np.ndarray
    axis_v: np.ndarray
    normal: np.ndarray
    u0: float
    v0: float
    cell: float
    shape: tuple[int, int]
    start: np.ndarray
    tris: np.ndarray
    bottom: float
    top: float
    v0s: np.ndarray  # (T, 3) first corners
    e1: np.ndarray  # (T, 3) edges
    e2: np.ndarray
    scale: np.ndarray  # (T,) |e1| |e2|: the degenerate-triangle test's scale


def build_slab_grid(vertices, triangles, plane, per_cell: float = 2.0) -> SlabGrid:
    """The grid of ``triangles`` over ``plane`` (`water.RestPlane`), about
    ``per_cell`` triangles per cell."""
    v = np.asarray(vertices, dtype=float)
    t = np.asarray(triangles, dtype=np.int64)
    rel = v - plane.origin
    pu, pv = rel @ plane.axis_u, rel @ plane.axis_v
    u0, v0 = float(pu.min()), float(pv.min())
    lu, lv = max(float(pu.max()) - u0, 1e-12), max(float(pv.max()) - v0, 1e-12)
    cell = max(np.sqrt(lu * lv * per_cell / max(len(t), 1)), 1e-12)
    nu, nv = int(np.ceil(lu / cell)) + 1, int(np.ceil(lv / cell)) + 1
    tu, tv = pu[t], pv[t]
    iu0 = np.clip(((tu.min(1) - u0) / cell).astype(np.int64), 0, nu - 1)
    iu1 = np.clip(((tu.max(1) - u0) / cell).astype(np.int64), 0, nu - 1)
    iv0 = np.clip(((tv.min(1) - v0) / cell).astype(np.int64), 0, nv - 1)
    iv1 = np.clip(((tv.max(1) - v0) / cell).astype(np.int64), 0, nv - 1)
    tri, cells = _boxes(iu0, iu1, iv0, iv1, nu)
    order = np.argsort(cells, kind="stable")
    start = np.searchsorted(cells[order], np.arange(nu * nv + 1))
    corners = v[t]
    e1, e2 = corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]
    h = rel @ plane.normal
    pad = 1e-9 * max(lu, lv)
    return SlabGrid(
        plane.origin, plane.axis_u, plane.axis_v, plane.normal, u0, v0, float(cell), (nv, nu),
        start, tri[order], float(h.min()) - pad, float(h.max()) + pad,
        corners[:, 0], e1, e2, np.linalg.norm(e1, axis=1) * np.linalg.norm(e2, axis=1),
    )  # fmt: skip


def _boxes(i0, i1, j0, j1, nu):
    """(item, flat cell) of every cell in each item's box [i0, i1] × [j0, j1]."""
    wi, wj = i1 - i0 + 1, j1 - j0 + 1
    n = wi * wj
    item = np.repeat(np.arange(len(i0)), n)
    k = np.arange(int(n.sum())) - np.repeat(np.cumsum(n) - n, n)
    i = i0[item] + k % wi[item]
    j = j0[item] + k // wi[item]
    return item, j * nu + i


def intersect(grid: SlabGrid, bvh: TriangleBvh, origins, dirs) -> Hits:
    """Nearest hit (t > 0) of each ray (N, 3) with the triangles, as the BVH's
    `Hits` (triangle −1 and t inf on a miss)."""
    o = np.asarray(origins, dtype=float).reshape(-1, 3)
    d = np.asarray(dirs, dtype=float).reshape(-1, 3)
    n = len(o)
    tri = np.full(n, -1, dtype=np.int64)
    tt = np.full(n, np.inf)
    uu, vv = np.zeros(n), np.zeros(n)
    oblique = np.zeros(n, dtype=bool)
    for a in range(0, n, BLOCK):
        b = min(n, a + BLOCK)
        r = _block(grid, o[a:b], d[a:b])
        tri[a:b], tt[a:b], uu[a:b], vv[a:b], oblique[a:b] = r
    if oblique.any():
        h = bvh_intersect(bvh, o[oblique], d[oblique])
        tri[oblique], tt[oblique], uu[oblique], vv[oblique] = h.triangle, h.t, h.u, h.v
    point = o + np.where(np.isfinite(tt), tt, 0.0)[:, None] * d
    return Hits(triangle=tri, t=tt, u=uu, v=vv, point=point)


def _block(g: SlabGrid, o, d):
    n = len(o)
    rel = o - g.origin
    h0, dh = rel @ g.normal, d @ g.normal
    # the stretch of each ray inside the slab (t from where it enters to where it leaves)
    with np.errstate(divide="ignore", invalid="ignore"):
        ta, tb = (g.top - h0) / dh, (g.bottom - h0) / dh
    inside = (h0 >= g.bottom) & (h0 <= g.top)
    flat = np.abs(dh) < 1e-12
    t_in = np.where(flat, np.where(inside, 0.0, np.inf), np.minimum(ta, tb))
    t_out = np.where(flat, np.where(inside, np.inf, -np.inf), np.maximum(ta, tb))
    t_in = np.maximum(t_in, 0.0)
    crosses = t_out >= t_in
    tri = np.full(n, -1, dtype=np.int64)
    tt = np.full(n, np.inf)
    uu, vv = np.zeros(n), np.zeros(n)
    oblique = np.zeros(n, dtype=bool)
    if not crosses.any():
        return tri, tt, uu, vv, oblique
    nv, nu = g.shape
    ru, rv = rel @ g.axis_u, rel @ g.axis_v
    du, dv = d @ g.axis_u, d @ g.axis_v
    t_end = np.where(np.isfinite(t_out), t_out, t_in)
    ua, ub = ru + t_in * du, ru + t_end * du
    va, vb = rv + t_in * dv, rv + t_end * dv
    i0 = np.floor((np.minimum(ua, ub) - g.u0) / g.cell)
    i1 = np.floor((np.maximum(ua, ub) - g.u0) / g.cell)
    j0 = np.floor((np.minimum(va, vb) - g.v0) / g.cell)
    j1 = np.floor((np.maximum(va, vb) - g.v0) / g.cell)
    off = crosses & ((i1 < 0) | (i0 > nu - 1) | (j1 < 0) | (j0 > nv - 1) | ~np.isfinite(t_out))
    with np.errstate(invalid="ignore"):  # a ray in the slab's plane: inf − inf, the BVH's
        span = (i1 - i0 + 1) * (j1 - j0 + 1)
    oblique = crosses & ~off & ~(span <= MAX_CELLS)
    oblique |= crosses & ~np.isfinite(t_out)  # travelling inside the slab's plane
    go = np.nonzero(crosses & ~off & ~oblique)[0]
    if not len(go):
        return tri, tt, uu, vv, oblique
    clip = lambda x, m: np.clip(x[go], 0, m - 1).astype(np.int64)  # noqa: E731
    ray, cells = _boxes(clip(i0, nu), clip(i1, nu), clip(j0, nv), clip(j1, nv), nu)
    ray = go[ray]
    cnt = g.start[cells + 1] - g.start[cells]
    pr = np.repeat(ray, cnt)
    k = np.arange(int(cnt.sum())) - np.repeat(np.cumsum(cnt) - cnt, cnt)
    pt = g.tris[np.repeat(g.start[cells], cnt) + k]
    t, u, v = _moller_trumbore(o[pr], d[pr], g.v0s[pt], g.e1[pt], g.e2[pt], g.scale[pt])
    ok = np.isfinite(t) & (t > 0.0)
    pr, pt, t, u, v = pr[ok], pt[ok], t[ok], u[ok], v[ok]
    order = np.lexsort((t, pr))
    first = np.ones(len(order), dtype=bool)
    first[1:] = pr[order][1:] != pr[order][:-1]
    sel = order[first]
    tri[pr[sel]], tt[pr[sel]], uu[pr[sel]], vv[pr[sel]] = pt[sel], t[sel], u[sel], v[sel]
    return tri, tt, uu, vv, oblique


def _moller_trumbore(o, d, v0, e1, e2, scale):
    """(t, u, v) of each ray–triangle pair, two-sided; t NaN where it misses."""
    p = cross(d, e2)
    det = np.einsum("ij,ij->i", e1, p)
    good = np.abs(det) > 1e-14 * scale
    inv = 1.0 / np.where(good, det, 1.0)
    s = o - v0
    u = np.einsum("ij,ij->i", s, p) * inv
    q = cross(s, e1)
    v = np.einsum("ij,ij->i", d, q) * inv
    t = np.einsum("ij,ij->i", e2, q) * inv
    hit = good & (u >= 0.0) & (v >= 0.0) & (u + v <= 1.0)
    return np.where(hit, t, np.nan), u, v
