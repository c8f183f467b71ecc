"""First hits of a bundle of rays (close-together origins, one direction) against
spheres and axis-aligned boxes, vectorised in numpy.

Pure (numpy only). `blender/read/occluders.py` uses these for the exact spheres and
as the boxes' pre-test, before it casts against the meshes inside the boxes.
"""

from __future__ import annotations

import math

import numpy as np

from ..lens.sphere import sphere_roots


def sphere_hits(
    centers: np.ndarray, radii: np.ndarray, origins: np.ndarray, d: np.ndarray
) -> np.ndarray:
    """Nearest t > 0 per origin (k × 3) along the unit `d` against all spheres
    (inf: none). A ray starting inside a sphere hits its far side."""
    if radii.size == 0:
        return np.full(len(origins), np.inf)
    # Relative to the first origin (the origins are close together), so that
    # |oc|² = |C'|² − 2 C'·o + |o|² keeps its precision far from the world origin.
    ref = origins[0]
    o = origins - ref  # (k, 3), small
    c = centers - ref  # (S, 3)
    cd = c @ d  # (S,)
    r2 = radii**2
    # Only spheres ahead of the origins and near the rays' line can be hit.
    reach = float(np.linalg.norm(o, axis=1).max())
    # the centres' offsets across `d` (|c|² − (c·d)² cancels for a far, small sphere)
    c_x = c - cd[:, None] * d
    near_line = (cd + radii + reach > 0) & (np.einsum("sj,sj->s", c_x, c_x) <= (radii + reach) ** 2)
    idx = np.flatnonzero(near_line)
    out = np.full(len(origins), np.inf)
    if idx.size == 0:
        return out
    c, cd, r2, c_x = c[idx], cd[idx], r2[idx], c_x[idx]
    b = cd[None, :] - (o @ d)[:, None]  # (k, S')
    oc2 = (
        np.einsum("sj,sj->s", c, c)[None, :]
        - 2.0 * (o @ c.T)
        + np.einsum("kj,kj->k", o, o)[:, None]
    )
    # the rays' distance² from each centre, from the parts across `d` (each ≲ R + reach)
    o_x = o - (o @ d)[:, None] * d
    perp2 = (
        np.einsum("sj,sj->s", c_x, c_x)[None, :]
        - 2.0 * (o_x @ c_x.T)
        + np.einsum("kj,kj->k", o_x, o_x)[:, None]
    )
    t = _first_hit(b, oc2 - r2[None, :], r2[None, :] - perp2)
    return np.minimum(out, t.min(axis=1))


def _first_hit(b, c, disc):
    """Nearest t > 0 (inf: none) of ``t² − 2bt + c = 0`` (``b``: the centre's distance
    along the ray, ``c = |origin − centre|² − R²``) given its discriminant as
    ``R² − perp²`` (SPEC §4.3: ``b² − c`` cancels for a small, far sphere), with the
    one stable root pair (`core.lens.sphere.sphere_roots`)."""
    near, far = sphere_roots(-b, disc, c)
    t = np.where(near > 0, near, np.where(far > 0, far, np.inf))
    return np.where(disc >= 0, t, np.inf)


def box_entries(
    box_lo: np.ndarray, box_hi: np.ndarray, origins: np.ndarray, d: np.ndarray, limit: float
) -> tuple[np.ndarray, np.ndarray]:
    """Slab test of every ray (k origins, direction `d`) against every box (N):
    (enter: k × N distance where the ray enters the box, hit: k × N whether it
    meets the box ahead of its origin, entering within `limit`)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = np.where(d != 0, 1.0 / d, np.inf)
        t0 = (box_lo[None] - origins[:, None]) * inv  # (k, N, 3)
        t1 = (box_hi[None] - origins[:, None]) * inv
        t0 = np.where(np.isnan(t0), -np.inf, t0)
        t1 = np.where(np.isnan(t1), np.inf, t1)
    enter = np.minimum(t0, t1).max(axis=2)
    leave = np.maximum(t0, t1).min(axis=2)
    hit = (leave >= np.maximum(enter, 0.0)) & (enter <= limit)
    return enter, hit


#: Bundles × spheres (or boxes) tested at once in the batched forms (memory bound).
BATCH_CELLS = 1 << 20


#: From this many spheres on, `sphere_hits_bundles` first tests the bundles against
#: groups of spheres (about `CLUSTER_SIZE` each) and only then against the members of
#: the groups they pass near.
CLUSTER_FROM = 4096
CLUSTER_SIZE = 32


def sphere_clusters(centers: np.ndarray, radii: np.ndarray):
    """Spheres grouped by the cells of a uniform grid (about `CLUSTER_SIZE` spheres a
    cell): (order, starts, centre, radius) — the spheres' indices cell by cell, each
    cell's first position in `order`, and a ball per cell holding all its spheres
    (centre: the middle of its centres' box; radius: the farthest sphere's reach)."""
    lo, hi = centers.min(axis=0), centers.max(axis=0)
    ext = np.maximum(hi - lo, 0.0)
    want = max(1.0, len(centers) / CLUSTER_SIZE)
    # the cell side h with about `want` cells over the centres' box (flat boxes too):
    # the number of cells falls as h grows; bisection in log h
    top = float(ext.max())
    h = 1.0
    if top > 0:
        lo_h, hi_h = top / want, top
        for _ in range(30):
            mid_h = math.sqrt(lo_h * hi_h)
            if np.prod(np.floor(ext / mid_h) + 1.0) >= want:
                lo_h = mid_h
            else:
                hi_h = mid_h
        h = lo_h
    ijk = np.floor((centers - lo) / h).astype(np.int64)
    dims = ijk.max(axis=0) + 1
    key = (ijk[:, 0] * dims[1] + ijk[:, 1]) * dims[2] + ijk[:, 2]
    order = np.argsort(key, kind="stable")
    ks = key[order]
    starts = np.flatnonzero(np.concatenate([[True], ks[1:] != ks[:-1]]))
    c = centers[order]
    mid = 0.5 * (np.minimum.reduceat(c, starts, axis=0) + np.maximum.reduceat(c, starts, axis=0))
    cell = np.repeat(np.arange(len(starts)), np.diff(np.append(starts, len(order))))
    reach = np.sqrt(np.sum((c - mid[cell]) ** 2, axis=1)) + radii[order]
    return order, starts, mid, np.maximum.reduceat(reach, starts)


def _near_line(centers, radii, ref, d, reach):
    """(S, b) whether each sphere (centre, radius) may be hit by a bundle (first
    origin `ref`, direction `d`, origins within `reach` of it): ahead of it and
    near its line, in world coordinates by matrix products, widened by far more than
    their rounding."""
    dw = np.einsum("bj,bj->b", ref, d)
    c2, r2w = np.einsum("sj,sj->s", centers, centers), np.einsum("bj,bj->b", ref, ref)
    cd = centers @ d.T - dw[None]  # (S, b): (centre − ref)·d
    cc = c2[:, None] - 2.0 * (centers @ ref.T) + r2w[None]  # |centre − ref|²
    rr = radii[:, None] + reach[None]
    scale = np.sqrt(c2)[:, None] + np.sqrt(r2w)[None]
    tol = 1e-9 * scale
    return (cd + rr + tol > 0) & (cc - cd * cd <= rr**2 + tol * (scale + rr))


def sphere_hits_bundles(
    centers: np.ndarray, radii: np.ndarray, origins: np.ndarray, d: np.ndarray
) -> np.ndarray:
    """`sphere_hits` of many bundles at once: `origins` (B × k × 3), one unit
    direction per bundle `d` (B × 3) → (B × k). The same arithmetic per bundle
    (relative to its first origin, spheres off its line skipped), vectorised over
    the (bundle, sphere) pairs the line test keeps. Many spheres: the line test
    first on groups of them (`sphere_clusters`, balls holding their members, so no
    sphere a bundle can hit is missed), then on the members of the groups kept."""
    origins = np.asarray(origins, dtype=float)
    d = np.asarray(d, dtype=float).reshape(-1, 3)
    B, k = origins.shape[:2]
    out = np.full((B, k), np.inf)
    if radii.size == 0 or B == 0:
        return out
    ref = origins[:, 0]  # (B, 3)
    o = origins - ref[:, None]  # (B, k, 3), small
    reach = np.sqrt(np.einsum("bkj,bkj->bk", o, o)).max(axis=1)  # (B,)
    clusters = sphere_clusters(centers, radii) if radii.size >= CLUSTER_FROM else None
    groups = radii.size if clusters is None else len(clusters[1])
    step = max(1, BATCH_CELLS // max(groups, 1))
    for b0 in range(0, B, step):
        b1 = min(B, b0 + step)
        sl = slice(b0, b1)
        if clusters is None:
            si, bi = np.nonzero(_near_line(centers, radii, ref[sl], d[sl], reach[sl]))
        else:
            order, starts, mid, rad = clusters
            gi, bi = np.nonzero(_near_line(mid, rad, ref[sl], d[sl], reach[sl]))
            size = np.diff(np.append(starts, len(order)))[gi]
            first = np.repeat(starts[gi] - np.cumsum(size) + size, size)
            si = order[first + np.arange(int(size.sum()))]
            bi = np.repeat(bi, size)
        if bi.size == 0:
            continue
        c = centers[si] - ref[b0 + bi]  # (P, 3), relative as in `sphere_hits`
        dp = d[b0 + bi]
        cdp = np.einsum("pj,pj->p", c, dp)
        ccp = np.einsum("pj,pj->p", c, c)
        c_x = c - cdp[:, None] * dp  # across the ray, as in `sphere_hits`
        keep = (cdp + radii[si] + reach[b0 + bi] > 0) & (
            np.einsum("pj,pj->p", c_x, c_x) <= (radii[si] + reach[b0 + bi]) ** 2
        )
        si, bi, cp, cdp, ccp = si[keep], bi[keep], c[keep], cdp[keep], ccp[keep]
        dp, c_x = dp[keep], c_x[keep]
        op = o[b0 + bi]  # (P, k, 3)
        b = cdp[:, None] - np.einsum("pkj,pj->pk", op, d[b0 + bi])
        oc2 = (
            ccp[:, None] - 2.0 * np.einsum("pkj,pj->pk", op, cp) + np.einsum("pkj,pkj->pk", op, op)
        )
        o_x = op - np.einsum("pkj,pj->pk", op, dp)[..., None] * dp[:, None, :]
        perp2 = (
            np.einsum("pj,pj->p", c_x, c_x)[:, None]
            - 2.0 * np.einsum("pkj,pj->pk", o_x, c_x)
            + np.einsum("pkj,pkj->pk", o_x, o_x)
        )
        r2 = (radii[si] ** 2)[:, None]
        np.minimum.at(out, b0 + bi, _first_hit(b, oc2 - r2, r2 - perp2))
    return out


def box_entries_bundles(
    box_lo: np.ndarray, box_hi: np.ndarray, origins: np.ndarray, d: np.ndarray, limit: float
) -> tuple[np.ndarray, np.ndarray]:
    """`box_entries` of many bundles at once (`origins` B × k × 3, `d` B × 3):
    (enter, hit), each B × k × N."""
    origins = np.asarray(origins, dtype=float)
    d = np.asarray(d, dtype=float).reshape(-1, 3)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = np.where(d != 0, 1.0 / d, np.inf)[:, None, None, :]  # (B, 1, 1, 3)
        t0 = (box_lo[None, None] - origins[:, :, None]) * inv  # (B, k, N, 3)
        t1 = (box_hi[None, None] - origins[:, :, None]) * inv
        t0 = np.where(np.isnan(t0), -np.inf, t0)
        t1 = np.where(np.isnan(t1), np.inf, t1)
    enter = np.minimum(t0, t1).max(axis=3)
    leave = np.maximum(t0, t1).min(axis=3)
    hit = (leave >= np.maximum(enter, 0.0)) & (enter <= limit)
    return enter, hit
