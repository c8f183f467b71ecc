"""One-sided hits on a closed convex mesh found by walking its surface, the BVH
(`core.shared.triangle_bvh`) only for the rays whose walk does not arrive.

On a closed convex mesh a ray has at most one way in (a face turned toward it) and one
way out (a face it leaves by), so a triangle on the asked side that the ray meets
within its bounds (the BVH's own Möller–Trumbore test, `triangle_bvh.hit_slots`, the
same arithmetic and tolerances) is *the* hit: accepting it needs no search for a
nearer one. A walk starts near the hit: where the ray's line meets the ellipsoid
inscribed in the mesh's bounding box, looked up in a cube map of the triangles around
its centre (each texel the triangle whose centre is nearest in direction: exact for
an ellipsoid pebble, a few triangles off for a lens, a rod or a cube); from there it
steps across the edge the line passes beyond (the most negative barycentric of the
line's point on the triangle's plane), a few steps at most. The
same ellipsoid grown to hold every vertex holds the mesh: a line that misses it surely
misses; so does a line that a walk carries across a silhouette edge (one face turned
toward it, the other away) and that passes beyond that edge's plane along the line (a
supporting plane of the convex mesh) by more than `SILHOUETTE_MARGIN`: the rays beside
the glass within that ellipsoid stop there. A ray whose walk leaves the mesh, turns to
the wrong side, cycles or runs out of steps is cast against the BVH: the walk only
ever skips a traversal. The hits
therefore equal the BVH's (with one side asked, the BVH also stops at its first hit
found); where a ray passes exactly through an edge or a vertex (both triangles within
the tolerance) either triangle may be the one reported, as in the BVH.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from . import parallel
from .triangle_bvh import (
    Hits,
    TriangleBvh,
    hit_slots,
    intersect,
    no_hits,
    ray_arrays,
)
from .vectors import column_bounds, corner_mean, cross, dot, norm

#: Steps a walk may take before its ray is handed to the BVH.
STEPS = 12
#: A line farther than this (times the mesh's size) beyond a silhouette edge's plane
#: surely misses (`_beyond_silhouette`): the rays that pass beside the glass within its
#: bounding ellipsoid stop there instead of walking all their steps, twice, and then
#: traversing the BVH. And the least |cos| between a face and the line (times its
#: edges' lengths) for the face to count as turned toward or away from it.
SILHOUETTE_MARGIN = 1e-6
SILHOUETTE_COS = 1e-6
#: The cube map's texels per triangle, and its side at most (texels per face side).
#: A texel holds the triangle whose centre's direction is nearest its own among the
#: centres in its 3 × 3 texels (`SEED_REACH`), then among its neighbours' choices
#: (`_fill`). Before, the last centre to fall in a texel, the empty texels filled from
#: the first neighbour found, at 12 a triangle: the speed bench's 2 000-triangle
#: Generate walked 576 steps (hit tests of a few rays each, Python between them);
#: with the nearest centres at 4 a triangle 149 (19 800 triangles: 611 -> 226).
MAP_PER_TRIANGLE = 4.0
MAP_SIDE = 256
SEED_REACH = 1
#: Rays from which the walks are split over threads: a walk's steps are short numpy
#: calls on the rays still walking, the Python between them holding the GIL (as
#: `core.lens.mesh.WALK_ROWS`, which calls this with the whole first wave: ~17 000 rays
#: in a Generate, where two threads cost more CPU and no less wall time).
THREAD_ROWS = 1 << 17


@dataclass(frozen=True)
class SurfaceWalk:
    """A BVH and its mesh's edge neighbours: ``across`` (T, 3) the triangle across the
    edge opposite each corner (−1: an open or non-manifold edge), ``slot`` (T,) each
    triangle's slot in the BVH; and where walks start: the ellipsoid inscribed in a
    bounding box (``center``, ``half`` axes along the columns of ``axes``: the world's,
    or the mesh's own where its box is smaller) and a cube map (6, M, M) of a triangle
    (−1: none) in each direction from the centre of that ellipsoid. That ellipsoid
    grown ``reach`` times holds every vertex, so the whole mesh (convex, or not: each
    triangle is in the hull of its corners): a line that misses it misses the mesh."""

    bvh: TriangleBvh
    across: np.ndarray
    slot: np.ndarray
    center: np.ndarray
    half: np.ndarray
    cube: np.ndarray
    reach: float
    axes: np.ndarray

    def local(self, points, directions):
        """Points and directions in the box's frame, its half axes 1."""
        return ((points - self.center) @ self.axes) / self.half, (
            directions @ self.axes
        ) / self.half


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
    v = bvh.vertices[tris.reshape(-1)] if t else np.zeros((1, 3))
    axes = _box_axes(v)
    loc = v @ axes
    lo, hi = column_bounds(loc)
    center, half = axes @ (0.5 * (lo + hi)), np.maximum(0.5 * (hi - lo), 1e-300)
    walk = SurfaceWalk(bvh, across.reshape(t, 3), slot, center, half, None, 0.0, axes)
    # a hair more than the farthest vertex: rounding never makes a hit a miss
    reach = float(np.linalg.norm(walk.local(v, v)[0], axis=1).max()) * (1.0 + 1e-7) + 1e-12
    m = int(np.clip(np.sqrt(t * MAP_PER_TRIANGLE / 6.0), 1, MAP_SIDE))
    cube = np.zeros((6, m, m), dtype=np.int64)
    if t:
        cen = corner_mean(bvh.vertices[tris])
        cube = np.full((6, m, m), -1, dtype=np.int64)
        loc_c = walk.local(cen, cen)[0]
        unit = loc_c / np.maximum(norm(loc_c), 1e-300)[:, None]
        cube = _fill(_nearest_centres(_texel(loc_c, m), unit, m), unit)
    return dataclasses.replace(walk, cube=cube, reach=reach)


def _box_axes(v) -> np.ndarray:
    """(3, 3) the axes (columns) of the box the walks' ellipsoid is inscribed in: the
    vertices' principal axes where their box is smaller than the world-aligned box (a
    tilted pebble, lens or rod: the ellipsoid then fits it, and the walks' first
    guesses land near their hits), else the world's (a sphere's principal axes are
    any; a cube's too, and an axis-aligned one's box is the world's)."""
    c = v - v.mean(axis=0)
    _, vecs = np.linalg.eigh(c.T @ c)

    def volume(axes):
        lo, hi = column_bounds(v @ axes)
        return float(np.prod(hi - lo + 1e-12 * span))

    lo, hi = column_bounds(v)
    span = (hi - lo).max()
    return vecs if volume(vecs) < 0.99 * volume(np.eye(3)) else np.eye(3)


def _texel(q, m):
    """Cube-map texel (face, row, column) of the directions q (N, 3)."""
    a = np.abs(q)
    major = np.argmax(a, axis=1)
    n = np.arange(len(q))
    big = np.maximum(a[n, major], 1e-300)
    face = 2 * major + (q[n, major] < 0)
    i = np.clip(((q[n, (major + 1) % 3] / big + 1.0) * 0.5 * m).astype(np.int64), 0, m - 1)
    j = np.clip(((q[n, (major + 2) % 3] / big + 1.0) * 0.5 * m).astype(np.int64), 0, m - 1)
    return face, i, j


def _texel_directions(m: int) -> np.ndarray:
    """(6, m, m, 3) the unit direction through each cube-map texel's centre (as
    `_texel` reads them), float32."""
    g = (np.arange(m) + 0.5) / m * 2.0 - 1.0
    dirs = np.zeros((6, m, m, 3))
    for f in range(6):
        major = f // 2
        dirs[f, ..., major] = -1.0 if f % 2 else 1.0
        dirs[f, ..., (major + 1) % 3] = g[:, None]
        dirs[f, ..., (major + 2) % 3] = g[None, :]
    return (dirs / norm(dirs)[..., None]).astype(np.float32)


def _nearest_centres(texels, centers, m: int) -> np.ndarray:
    """(6, m, m) cube map: each texel within `SEED_REACH` texels of some triangle's
    centre (its direction ``centers``, unit; in the texels ``texels``) holds the one
    whose centre is nearest its own direction (not the last that fell in it: a UV
    sphere's pole crowds a fan of thin triangles into a few texels), the others −1."""
    face, i, j = texels
    tri = np.arange(len(face), dtype=np.int64)
    dirs = _texel_directions(m).reshape(-1, 3)
    c32 = centers.astype(np.float32)
    best = np.full(6 * m * m, -1, dtype=np.int64)
    r = SEED_REACH
    for di in range(-r, r + 1):
        for dj in range(-r, r + 1):
            ii, jj = i + di, j + dj
            ok = (ii >= 0) & (ii < m) & (jj >= 0) & (jj < m)
            to = ((face * m + ii) * m + jj)[ok]
            cos = np.einsum("ij,ij->i", dirs[to], c32[ok])
            # the nearest as the largest key: cos in the high bits, the triangle below
            key = ((cos.astype(np.float64) + 1.0) * (1 << 30)).astype(np.int64) << 31
            np.maximum.at(best, to, key | tri[ok])
    return np.where(best >= 0, best & ((1 << 31) - 1), -1).reshape(6, m, m)


def _fill(cube, centers):
    """Each texel the nearest centre (direction, ``centers``) among its own and its 8
    neighbours' (within a face), one neighbour direction after the other (so a centre
    travels on along each pass: jump flooding's last step); texels still empty
    from a neighbour, and a face with none at all triangle 0 (a start far off: the
    walk or the BVH still finds the hit)."""
    m = cube.shape[1]
    dirs = _texel_directions(m)
    none = len(centers)
    c32 = np.concatenate([centers, np.zeros((1, 3))]).astype(np.float32)
    cur = np.where(cube >= 0, cube, none)
    cos = np.where(cur < none, np.einsum("fijk,fijk->fij", dirs, c32[cur]), -np.inf)
    for di in (-1, 0, 1):
        for dj in (-1, 0, 1):
            if di == 0 and dj == 0:
                continue
            pad = np.pad(cur, ((0, 0), (1, 1), (1, 1)), constant_values=none)
            tri = pad[:, 1 + di : 1 + di + m, 1 + dj : 1 + dj + m]
            c = np.einsum("fijk,fijk->fij", dirs, c32[tri])
            better = (c > cos) & (tri < none)
            cur = np.where(better, tri, cur)
            cos = np.where(better, c, cos)
    for _ in range(2 * m):
        if not (cur == none).any():
            break
        for ax in (1, 2):
            for sh in (1, -1):
                nb = np.roll(cur, sh, axis=ax)
                cur = np.where((cur == none) & (nb < none), nb, cur)
    return np.where(cur < none, cur, 0)


def aim(walk: SurfaceWalk, o, d, side, t_min, t_max):
    """Where each ray's walk starts: the triangle in the cube map where its line meets
    the inscribed ellipsoid (entering for side +1, leaving for −1; its closest approach
    where it misses), and a function giving a second guess for some of the rays
    (their indices), where they meet the bounding box (a box-like mesh): asked only
    for the rays whose first walk did not arrive. And which rays surely miss: their
    line misses the grown ellipsoid, or meets it only outside (t_min, t_max]."""
    p, q = walk.local(o, d)
    ia = 1.0 / np.maximum(dot(q, q), 1e-300)
    # the line's closest approach to the centre (stable however far the origin is)
    tc = -dot(p, q) * ia
    h2 = dot(p + tc[:, None] * q, p + tc[:, None] * q)
    half_chord = np.sqrt(np.maximum(1.0 - h2, 0.0) * ia)
    t = tc + np.where(side < 0, half_chord, -half_chord)
    m = walk.cube.shape[1]
    start = walk.cube[_texel(p + t[:, None] * q, m)]

    def second(rows):
        pr, qr = p[rows], q[rows]
        with np.errstate(divide="ignore", invalid="ignore"):
            t1, t2 = (-1.0 - pr) / qr, (1.0 - pr) / qr
            near = np.fmax.reduce(np.minimum(t1, t2), axis=1)
            far = np.fmin.reduce(np.maximum(t1, t2), axis=1)
        t_box = np.where(side[rows] < 0, far, near)
        t_box = np.where(np.isfinite(t_box), t_box, t[rows])
        return walk.cube[_texel(pr + t_box[:, None] * qr, m)]

    wide = np.sqrt(np.maximum(walk.reach**2 - h2, 0.0) * ia)
    miss = (h2 > walk.reach**2) | (tc + wide <= t_min) | (tc - wide > t_max)
    return start, second, miss & ((d[:, 0] != 0.0) | (d[:, 1] != 0.0) | (d[:, 2] != 0.0))


def _walk_from(walk, o, d, side, t_min, t_max, start):
    """(triangle, t, u, v) of the rays' walks from the triangles ``start``; triangle
    −1 where a walk did not arrive. And which of those surely miss the mesh: their
    line passed beyond a silhouette edge (`_beyond_silhouette`), so no second walk
    and no BVH cast is needed (a BVH miss: the same columns)."""
    tri, tt, uu, vv = no_hits(len(o))
    missed = np.zeros(len(o), dtype=bool)
    ray = np.arange(len(o))
    cur = start
    dn = norm(d)
    prev = np.full(len(ray), -1, dtype=np.int64)
    margin = SILHOUETTE_MARGIN * float(np.max(walk.half)) * walk.reach
    # a line from inside meets the mesh: only rays from outside may pass beside it
    outside = bool(np.any(side > 0))
    for _ in range(STEPS):
        if len(ray) == 0:
            break
        t, u, v, ok, det = hit_slots(walk.bvh, o[ray], d[ray], dn[ray], walk.slot[cur])
        good = ok & (t > t_min[ray]) & (t <= t_max[ray]) & (det * side[ray] >= 0.0)
        r = ray[good]
        tri[r], tt[r], uu[r], vv[r] = cur[good], t[good], u[good], v[good]
        # beyond which edge the line meets the plane: the most negative barycentric
        # (the first of equals, as argmin over (1 − u − v, u, v), without the stack)
        w = 1.0 - u - v
        corner = np.where((w <= u) & (w <= v), 0, np.where(u <= v, 1, 2))
        step = walk.across.reshape(-1)[cur * 3 + corner]
        # no way on: parallel plane, inside but rejected, an open edge, back and forth
        stuck = (det == 0.0) | (np.minimum(np.minimum(w, u), v) >= -1e-12)
        stuck |= (step < 0) | (step == prev)
        go = ~good & ~stuck
        if outside:
            gone = _beyond_silhouette(walk, (o, d, dn, ray), cur, corner, step, det, go, margin)
            missed[ray[gone]] = True
            go &= ~gone
        ray, prev, cur = ray[go], cur[go], step[go]
    return tri, tt, uu, vv, missed


def _beyond_silhouette(walk, rays, cur, corner, step, det, go, margin) -> np.ndarray:
    """Which of the rows ``go`` (stepping from triangle ``cur`` across the edge opposite
    ``corner`` to ``step``) surely miss the mesh. Where one of the edge's faces turns
    toward the line and the other away (a silhouette edge: both clearly, not grazing),
    the plane through the edge along the line supports the convex mesh (its normal is
    in the edge's cone of face normals): the whole mesh lies on the side of the
    current face's third corner. A line beyond that plane by more than ``margin``
    (far above the triangle test's tolerances and a 'convex' mesh's float32 folds)
    meets no triangle: the BVH would find none."""
    out = np.zeros(len(go), dtype=bool)
    rows = np.flatnonzero(go)
    if len(rows) == 0:
        return out
    o, d, dn, ray = rays  # all the walk's rays, and which are walking (``go`` of these)
    row_c = walk.bvh.packed[walk.slot[cur[rows]]]
    row_n = walk.bvh.packed[walk.slot[step[rows]]]
    dr = d[ray[rows]]
    det_n = -dot(dr, row_n[:, 0:3])
    det_c = det[rows]
    tol = SILHOUETTE_COS * dn[ray[rows]]
    sil = ((det_c > tol * row_c[:, 12]) & (det_n < -tol * row_n[:, 12])) | (
        (det_c < -tol * row_c[:, 12]) & (det_n > tol * row_n[:, 12])
    )
    rows, row_c, dr = rows[sil], row_c[sil], dr[sil]
    if len(rows) == 0:
        return out
    # the current face's corners: v0, v0 + e1, v0 + e2 (corner k: w, u, v's)
    v0 = row_c[:, 3:6]
    corners = np.stack([v0, v0 + row_c[:, 6:9], v0 + row_c[:, 9:12]], axis=1)
    k = corner[rows]
    n = np.arange(len(rows))
    a, b, inner = corners[n, (k + 1) % 3], corners[n, (k + 2) % 3], corners[n, k]
    m = cross(b - a, dr)
    lim = margin * norm(m)
    s_in = dot(m, inner - a)
    s_line = dot(m, o[ray[rows]] - a)
    beyond = ((s_in > lim) & (s_line < -lim)) | ((s_in < -lim) & (s_line > lim))
    out[rows[beyond]] = True
    return out


def intersect_convex(walk: SurfaceWalk, origins, dirs, facing, t_min=0.0, t_max=np.inf) -> Hits:
    """As ``triangle_bvh.intersect(walk.bvh, origins, dirs, t_min, t_max, facing=facing)``
    on a closed convex mesh, ``facing`` (per ray or scalar) ±1 for every ray."""
    o, d, t_min, t_max = ray_arrays(origins, dirs, t_min, t_max)
    n = len(o)
    side = np.broadcast_to(np.asarray(facing, dtype=np.int8), (n,))
    if np.any(side == 0):
        raise ValueError("intersect_convex needs a side for every ray")
    tri, tt, uu, vv = no_hits(n)

    def run(block: slice):  # a block of rays in one thread: each ray's hit is its own
        o_, d_, s_, lo, hi = o[block], d[block], side[block], t_min[block], t_max[block]
        start, second, miss = aim(walk, o_, d_, s_, lo, hi)
        ray = np.nonzero(~miss)[0]
        out = (tri[block], tt[block], uu[block], vv[block])  # views: written in place
        guess = start[ray]
        for _ in range(2):  # rays whose first walk did not arrive: from the second guess
            *found, missed = _walk_from(walk, o_[ray], d_[ray], s_[ray], lo[ray], hi[ray], guess)
            for col, val in zip(out, found, strict=True):
                col[ray] = val
            ray = ray[(out[0][ray] < 0) & ~missed]
            if len(ray) == 0:
                break
            guess = second(ray)
        if len(ray):  # neither walk arrived: the BVH decides
            hb = intersect(walk.bvh, o_[ray], d_[ray], lo[ray], hi[ray], facing=s_[ray])
            for col, val in zip(out, (hb.triangle, hb.t, hb.u, hb.v), strict=True):
                col[ray] = val

    parallel.map_slices(run, n, min_rows=THREAD_ROWS)
    point = o + np.where(np.isfinite(tt), tt, 0.0)[:, None] * d
    return Hits(triangle=tri, t=tt, u=uu, v=vv, point=point)
