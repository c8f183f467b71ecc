"""One-sided hits on a closed convex mesh found by walking its surface from a neighbour's
hit, the BVH (`core.shared.triangle_bvh`) only for a sparse subset of the rays and for
the rays whose walk does not arrive.

On a closed convex mesh a ray has at most one way in (a face turned toward it) and one
way out (a face it leaves by), so a triangle on the asked side that the ray meets
within its bounds (the BVH's own Möller–Trumbore test, `triangle_bvh.hit_slots`, the
same tolerances) is *the* hit: accepting it needs no search for a nearer one. Rays come
in coherent bundles (a light's ray grid, the waves of `core.lens.mesh`), so a ray's
neighbour in the array hits near it: every ``stride``-th ray is cast against the BVH,
the others start at the triangle their sample hit and step across the edge their line
passes beyond (the most negative barycentric of the line's point on the triangle's
plane), a few steps at most. A ray whose walk leaves the mesh, turns to the wrong side,
cycles or runs out of steps, and a ray whose samples both missed, is cast against the
BVH: the walk only ever skips a traversal, never decides a miss. The hits therefore
equal the BVH's (with one side asked, the BVH also stops at its first hit found); where
a ray passes exactly through an edge or a vertex (both triangles within the tolerance)
either triangle may be the one reported, as in the BVH.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .triangle_bvh import Hits, TriangleBvh, hit_slots, intersect, no_hits, ray_arrays

#: Every this many rays one is cast against the BVH: the others' walks start there.
STRIDE = 8
#: Steps a walk may take before its ray is handed to the BVH.
STEPS = 12
#: Samples below which they are cast against the BVH (above: found by a walk themselves,
#: from every ``stride``-th of them).
MIN_SAMPLES = 2048


@dataclass(frozen=True)
class SurfaceWalk:
    """A BVH and its mesh's edge neighbours: ``across`` (T, 3) the triangle across the
    edge opposite each corner (−1: an open or non-manifold edge), ``slot`` (T,) each
    triangle's slot in the BVH."""

    bvh: TriangleBvh
    across: np.ndarray
    slot: np.ndarray


def build_walk(bvh: TriangleBvh) -> SurfaceWalk:
    tris = bvh.triangles
    t = len(tris)
    # the edge opposite corner k runs from corner k+1 to k+2
    a = tris[:, [1, 2, 0]].reshape(-1)
    b = tris[:, [2, 0, 1]].reshape(-1)
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    order = np.lexsort((hi, lo))
    lo, hi = lo[order], hi[order]
    same = (lo[1:] == lo[:-1]) & (hi[1:] == hi[:-1])
    # an edge of exactly two faces: a pair not part of a longer run
    before = np.concatenate([[False], same[:-1]]) if len(same) else same
    after = np.concatenate([same[1:], [False]]) if len(same) else same
    pair = np.nonzero(same & ~before & ~after)[0]
    across = np.full(3 * t, -1, dtype=np.int64)
    ea, eb = order[pair], order[pair + 1]
    across[ea], across[eb] = eb // 3, ea // 3
    slot = np.empty(t, dtype=np.int64)
    live = bvh.tri_index >= 0
    slot[bvh.tri_index[live]] = np.nonzero(live)[0]
    return SurfaceWalk(bvh=bvh, across=across.reshape(t, 3), slot=slot)


def intersect_convex(
    walk: SurfaceWalk, origins, dirs, facing, t_min=0.0, t_max=np.inf, stride=STRIDE
) -> Hits:
    """As ``triangle_bvh.intersect(walk.bvh, origins, dirs, t_min, t_max, facing=facing)``
    on a closed convex mesh, ``facing`` (per ray or scalar) ±1 for every ray."""
    o, d, t_min, t_max = ray_arrays(origins, dirs, t_min, t_max)
    n = len(o)
    side = np.broadcast_to(np.asarray(facing, dtype=np.int8), (n,))
    if np.any(side == 0):
        raise ValueError("intersect_convex needs a side for every ray")
    tri, tt, uu, vv = no_hits(n)
    if n == 0:
        return Hits(tri, tt, uu, vv, o.copy())
    samp = np.arange(0, n, stride)
    if len(samp) > MIN_SAMPLES:  # the samples themselves from sparser samples
        hs = intersect_convex(walk, o[samp], d[samp], side[samp], t_min[samp], t_max[samp], stride)
    else:
        hs = intersect(walk.bvh, o[samp], d[samp], t_min[samp], t_max[samp], facing=side[samp])
    tri[samp], tt[samp], uu[samp], vv[samp] = hs.triangle, hs.t, hs.u, hs.v
    # each other ray starts where its sample hit (else the next sample)
    rest = np.ones(n, dtype=bool)
    rest[samp] = False
    ray = np.nonzero(rest)[0]
    k = ray // stride
    start = hs.triangle[k]
    nxt = hs.triangle[np.minimum(k + 1, len(samp) - 1)]
    start = np.where(start >= 0, start, nxt)
    cast = [ray[start < 0]]  # both samples missed: the BVH decides
    ray, cur = ray[start >= 0], start[start >= 0]
    dn = np.linalg.norm(d, axis=1)
    prev = np.full(len(ray), -1, dtype=np.int64)
    for _ in range(STEPS):
        if len(ray) == 0:
            break
        t, u, v, ok, det = hit_slots(walk.bvh, o[ray], d[ray], dn[ray], walk.slot[cur])
        good = ok & (t > t_min[ray]) & (t <= t_max[ray]) & (det * side[ray] >= 0.0)
        r = ray[good]
        tri[r], tt[r], uu[r], vv[r] = cur[good], t[good], u[good], v[good]
        # beyond which edge the line meets the plane: the most negative barycentric
        bary = np.stack([1.0 - u - v, u, v], axis=1)
        corner = np.argmin(bary, axis=1)
        step = walk.across[cur, corner]
        # no way on: parallel plane, inside but rejected, an open edge, back and forth
        stuck = (det == 0.0) | (bary[np.arange(len(cur)), corner] >= -1e-12)
        stuck |= (step < 0) | (step == prev)
        lost = ~good & stuck
        cast.append(ray[lost])
        go = ~good & ~stuck
        ray, prev, cur = ray[go], cur[go], step[go]
    cast.append(ray)
    c = np.concatenate(cast)
    if len(c):
        hb = intersect(walk.bvh, o[c], d[c], t_min[c], t_max[c], facing=side[c])
        tri[c], tt[c], uu[c], vv[c] = hb.triangle, hb.t, hb.u, hb.v
    point = o + np.where(np.isfinite(tt), tt, 0.0)[:, None] * d
    return Hits(triangle=tri, t=tt, u=uu, v=vv, point=point)
