"""Where rays land on the receivers: planar patches by plane + 2-D grid, the rest by BVH.

Caustics land mostly on a few large planes (a table top, a floor, a wall), each possibly
meshed into thousands of triangles. For those, a ray is intersected with the patch's
*plane* (one dot product per ray and plane) and the hit point is located among the
patch's triangles through a uniform 2-D grid in the plane (each cell lists the triangles
whose bounding box touches it): a handful of 2-D barycentric tests per ray, whatever the
triangle count. Triangles of small or curved patches (one patch per facet) go to the
numpy BVH of :mod:`.receiver_bvh`. The nearest of both hits wins.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .emitters import perpendicular_frame
from .receiver_bvh import Hits, ReceiverMesh, TriangleBvh, build_bvh, no_hits, ray_arrays
from .receiver_bvh import intersect as bvh_intersect
from .receiver_patches import ReceiverPatch, find_patches


@dataclass(frozen=True)
class PlaneGrids:
    """The planar fast path: P planes, their grids in one CSR table."""

    patch: np.ndarray  # (P,) patch index of each plane
    normal: np.ndarray  # (P, 3)
    offset: np.ndarray  # (P,)
    au: np.ndarray  # (P, 3) in-plane axes
    av: np.ndarray
    lo: np.ndarray  # (P, 2) grid origin in (au, av) coordinates
    cell: np.ndarray  # (P, 2) cell size
    dims: np.ndarray  # (P, 2) cells along u, v
    base: np.ndarray  # (P,) first cell of each plane in the CSR table
    cell_start: np.ndarray  # (cells + 1,)
    cell_tris: np.ndarray  # (entries,) triangle indices
    tri_a: np.ndarray  # (T, 2) first vertex in its plane's coordinates
    tri_inv: np.ndarray  # (T, 2, 2) inverse of [e1 e2] in the plane: (u, v) barycentrics


@dataclass(frozen=True)
class ReceiverIndex:
    mesh: ReceiverMesh
    patch_of: np.ndarray  # (T,) patch of each triangle (−1 degenerate)
    patches: list[ReceiverPatch]
    planes: PlaneGrids | None
    bvh: TriangleBvh | None  # over the other triangles
    bvh_tris: np.ndarray  # (T_bvh,) their indices in the mesh


def build_index(
    mesh: ReceiverMesh,
    min_plane_triangles: int = 2,
    max_planes: int = 64,
    cells_per_triangle: float = 2.0,
) -> ReceiverIndex:
    """Index ``mesh`` for landing rays: the up to ``max_planes`` patches with at least
    ``min_plane_triangles`` triangles take the planar fast path, the rest a BVH."""
    patch_of, patches = find_patches(mesh)
    counts = np.array([len(p.triangles) for p in patches], dtype=np.int64)
    big = np.nonzero(counts >= min_plane_triangles)[0]
    big = big[np.argsort(-counts[big], kind="stable")][:max_planes]
    planes = _plane_grids(mesh, patches, big, cells_per_triangle) if len(big) else None
    in_plane = np.zeros(len(mesh.triangles), dtype=bool)
    for p in big:
        in_plane[patches[p].triangles] = True
    rest = np.nonzero(~in_plane & (patch_of >= 0))[0]
    bvh = None
    if len(rest):
        bvh = build_bvh(ReceiverMesh(mesh.vertices, np.asarray(mesh.triangles)[rest]))
    return ReceiverIndex(mesh, patch_of, patches, planes, bvh, rest)


def _plane_grids(mesh, patches, big, cells_per_triangle) -> PlaneGrids:
    v = np.asarray(mesh.vertices, dtype=float)
    tris = np.asarray(mesh.triangles, dtype=np.int64)
    n_t = len(tris)
    tri_a = np.zeros((n_t, 2))
    tri_inv = np.zeros((n_t, 2, 2))
    normal, offset, au_l, av_l, lo_l, cell_l, dims_l, base_l = ([] for _ in range(8))
    entries_cell, entries_tri = [], []
    base = 0
    for p in big:  # loop over planes, not triangles
        pt = patches[p]
        au, av = perpendicular_frame(pt.normal)
        c = v[tris[pt.triangles]]  # (m, 3, 3)
        xy = np.stack([c @ au, c @ av], axis=-1)  # (m, 3, 2)
        a = xy[:, 0]
        m2 = np.stack([xy[:, 1] - a, xy[:, 2] - a], axis=-1)  # columns e1, e2
        tri_a[pt.triangles] = a
        tri_inv[pt.triangles] = _inv2(m2)
        lo, hi = xy.reshape(-1, 2).min(axis=0), xy.reshape(-1, 2).max(axis=0)
        span = np.maximum(hi - lo, 1e-12 * (1.0 + np.abs(lo).max()))
        n_cells = max(1.0, cells_per_triangle * len(pt.triangles))
        g = np.sqrt(n_cells * span / span[::-1])  # square-ish cells
        dims = np.clip(np.ceil(g), 1, 4096).astype(np.int64)
        cell = span / dims * (1.0 + 1e-9)
        i0 = np.clip(((xy.min(axis=1) - lo) / cell).astype(np.int64), 0, dims - 1)
        i1 = np.clip(((xy.max(axis=1) - lo) / cell).astype(np.int64), 0, dims - 1)
        nu, nv = i1[:, 0] - i0[:, 0] + 1, i1[:, 1] - i0[:, 1] + 1
        cnt = nu * nv
        tri_rep = np.repeat(pt.triangles, cnt)
        k = np.arange(cnt.sum()) - np.repeat(np.cumsum(cnt) - cnt, cnt)
        iu = np.repeat(i0[:, 0], cnt) + k // np.repeat(nv, cnt)
        iv = np.repeat(i0[:, 1], cnt) + k % np.repeat(nv, cnt)
        entries_cell.append(base + iu * dims[1] + iv)
        entries_tri.append(tri_rep)
        normal.append(pt.normal)
        offset.append(pt.offset)
        au_l.append(au)
        av_l.append(av)
        lo_l.append(lo)
        cell_l.append(cell)
        dims_l.append(dims)
        base_l.append(base)
        base += int(dims[0] * dims[1])
    ec, et = np.concatenate(entries_cell), np.concatenate(entries_tri)
    o = np.argsort(ec, kind="stable")
    start = np.searchsorted(ec[o], np.arange(base + 1))
    return PlaneGrids(
        np.asarray(big),
        np.array(normal),
        np.array(offset),
        np.array(au_l),
        np.array(av_l),
        np.array(lo_l),
        np.array(cell_l),
        np.array(dims_l),
        np.array(base_l),
        start,
        et[o],
        tri_a,
        tri_inv,
    )


def _inv2(m: np.ndarray) -> np.ndarray:
    """Inverses of 2 × 2 matrices (k, 2, 2) in closed form (np.linalg.inv calls LAPACK
    once per matrix: ~40× slower for 10 000 triangles)."""
    a, b, c, d = m[:, 0, 0], m[:, 0, 1], m[:, 1, 0], m[:, 1, 1]
    det = a * d - b * c
    if np.any(det == 0.0):  # a degenerate triangle: LAPACK's error, as before
        raise np.linalg.LinAlgError("Singular matrix")
    return (
        np.stack([np.stack([d, -b], axis=-1), np.stack([-c, a], axis=-1)], axis=1)
        / det[:, None, None]
    )


def intersect(index: ReceiverIndex, origins, dirs, t_min=0.0, t_max=np.inf) -> Hits:
    """Nearest hit with ``t_min < t ≤ t_max`` of rays ``origins + t·dirs`` ((N, 3)) on the
    indexed mesh; triangles two-sided. Same result as a BVH over the whole mesh."""
    o, d, t_min, t_max = ray_arrays(origins, dirs, t_min, t_max)
    tri, tt, uu, vv = no_hits(len(o))
    if index.planes is not None:
        tri, tt, uu, vv = _intersect_planes(index.planes, o, d, t_min, t_max)
    if index.bvh is not None:
        h = bvh_intersect(index.bvh, o, d, t_min, np.minimum(t_max, tt))
        better = (h.triangle >= 0) & (h.t < tt)
        tri = np.where(better, index.bvh_tris[np.maximum(h.triangle, 0)], tri)
        tt = np.where(better, h.t, tt)
        uu = np.where(better, h.u, uu)
        vv = np.where(better, h.v, vv)
    point = o + np.where(np.isfinite(tt), tt, 0.0)[:, None] * d
    return Hits(triangle=tri, t=tt, u=uu, v=vv, point=point)


def _intersect_planes(g: PlaneGrids, o, d, t_min, t_max):
    n = len(o)
    nd = d @ g.normal.T  # (N, P)
    gap = g.offset[None, :] - o @ g.normal.T
    with np.errstate(divide="ignore", invalid="ignore"):
        t = gap / nd
    ok = (nd != 0.0) & (t > t_min[:, None]) & (t <= t_max[:, None])
    t = np.where(ok, t, np.inf)
    out_tri, out_t, out_u, out_v = no_hits(n)
    # Nearest plane first: most rays stop on their first plane (a table above a floor),
    # only the misses (a hole, the table's edge) try the next one.
    order = np.argsort(t, axis=1) if t.shape[1] > 1 else np.zeros((n, 1), dtype=np.int64)
    todo = np.arange(n)
    for rank in range(t.shape[1]):
        pl = order[todo, rank]
        tt = t[todo, pl]
        keep = np.isfinite(tt)
        todo, pl, tt = todo[keep], pl[keep], tt[keep]
        if not len(todo):
            break
        tri, u, v = _locate(g, o[todo], d[todo], pl, tt)
        hit = tri >= 0
        r = todo[hit]
        out_tri[r], out_t[r], out_u[r], out_v[r] = tri[hit], tt[hit], u[hit], v[hit]
        todo = todo[~hit]
    return out_tri, out_t, out_u, out_v


def _locate(g: PlaneGrids, o, d, pl, t):
    """The triangle of plane ``pl`` (per ray) under each ray's hit at ``t`` (−1: none)
    and its barycentric (u, v), through the plane's 2-D grid. (Per coordinate, not
    (N, 2) pairs: numpy's reductions and gathers along a short axis are slow.)"""
    m = len(o)
    tri_out = np.full(m, -1, dtype=np.int64)
    u_out, v_out = np.zeros(m), np.zeros(m)
    p = o + t[:, None] * d
    x, y = np.einsum("ij,ij->i", p, g.au[pl]), np.einsum("ij,ij->i", p, g.av[pl])
    ci = np.floor((x - g.lo[pl, 0]) / g.cell[pl, 0]).astype(np.int64)
    cj = np.floor((y - g.lo[pl, 1]) / g.cell[pl, 1]).astype(np.int64)
    di, dj = g.dims[pl, 0], g.dims[pl, 1]
    inside = (ci >= 0) & (ci < di) & (cj >= 0) & (cj < dj)
    ray = np.nonzero(inside)[0]
    x, y = x[ray], y[ray]
    cid = g.base[pl[ray]] + ci[ray] * dj[ray] + cj[ray]
    s0, s1 = g.cell_start[cid], g.cell_start[cid + 1]
    cnt = s1 - s0
    k = np.arange(cnt.sum()) - np.repeat(np.cumsum(cnt) - cnt, cnt)
    q = np.repeat(np.arange(len(ray)), cnt)
    tri = g.cell_tris[np.repeat(s0, cnt) + k]
    a, inv = g.tri_a[tri], g.tri_inv[tri]
    rx, ry = x[q] - a[:, 0], y[q] - a[:, 1]
    u = inv[:, 0, 0] * rx + inv[:, 0, 1] * ry  # the 2 × 2 products written out: no einsum
    v = inv[:, 1, 0] * rx + inv[:, 1, 1] * ry
    eps = 1e-12
    hit = np.nonzero((u >= -eps) & (v >= -eps) & (u + v <= 1.0 + eps))[0]
    # a point on a shared edge lies in two triangles: either will do (same plane, same t)
    r = ray[q[hit]]
    tri_out[r], u_out[r], v_out[r] = tri[hit], u[hit], v[hit]
    return tri_out, u_out, v_out
