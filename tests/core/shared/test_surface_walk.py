"""Walked one-sided hits on closed convex meshes against brute force: every ray against
every triangle of the asked side by solving o + t d = v0 + u e1 + v e2 (numpy's linear
solver, not the code under test); and the walk really doing the work on coherent rays."""

import numpy as np
import pytest

from core.shared import surface_walk
from core.shared.surface_walk import build_walk, intersect_convex
from core.shared.triangle_bvh import build_bvh
from reference.glass_meshes import biconvex_mesh, box_mesh, ellipsoid_mesh, rod_mesh
from reference.shapes import Biconvex, Box, Rod, rotation_to


def _brute(verts, tris, o, d, side, t_min=None, t_max=None):
    """(triangle, t) of the nearest hit among the triangles on ``side`` (+1: facing
    the ray) within (t_min, t_max]."""
    v0 = verts[tris[:, 0]]
    e1, e2 = verts[tris[:, 1]] - v0, verts[tris[:, 2]] - v0
    n = np.cross(e1, e2)
    k_out = np.full(len(o), -1)
    t_out = np.full(len(o), np.inf)
    for i in range(len(o)):
        m = np.stack([-np.broadcast_to(d[i], e1.shape), e1, e2], axis=-1)
        ok = (np.abs(np.linalg.det(m)) > 1e-12) & (side[i] * (n @ d[i]) < 0)
        sol = np.linalg.solve(m[ok], (o[i] - v0[ok])[..., None])[..., 0]
        t, u, v = sol.T
        lo = 0.0 if t_min is None else t_min[i]
        hi = np.inf if t_max is None else t_max[i]
        inside = (u >= 0) & (v >= 0) & (u + v <= 1) & (t > lo) & (t <= hi)
        if inside.any():
            j = np.argmin(np.where(inside, t, np.inf))
            k_out[i], t_out[i] = np.nonzero(ok)[0][j], t[j]
    return k_out, t_out


MESHES = {
    "ellipsoid": lambda: ellipsoid_mesh(
        (0.3, -0.2, 1.0), (1.0, 0.6, 0.35), rotation_to((1, 2, 3)), 24, 48
    ),
    "rod": lambda: rod_mesh(Rod((0.0, 0.5, 0.2), (1.0, 0.3, 0.0), 0.25, 2.0), 48, 3),
    "box": lambda: box_mesh(Box((1.0, 0.0, 0.0), (1.0, 2.0, 0.7), rotation_to((1, 1, 1)))),
    "lens": lambda: biconvex_mesh(Biconvex((0, 0, 0), (0, 0.3, 1.0), 1.5, 2.5, 0.5), 8, 40),
}


def _scatter(verts, rng, n):
    """Rays from outside aimed near the mesh (side +1) and rays from inside (−1)."""
    c = verts.mean(axis=0)
    size = np.ptp(verts, axis=0).max()
    far = rng.normal(size=(n, 3))
    far = c + 2.0 * size * far / np.linalg.norm(far, axis=1)[:, None]
    aim = c + 0.3 * size * rng.uniform(-1, 1, (n, 3)) - far
    # inside: convex combinations of the vertices
    w = rng.dirichlet(np.ones(len(verts)), n)
    inner = w @ verts
    return (far, aim, np.ones(n, np.int8)), (inner, rng.normal(size=(n, 3)), -np.ones(n, np.int8))


@pytest.mark.parametrize("name", sorted(MESHES))
def test_walked_hits_equal_brute_force_on_convex_meshes(name):
    verts, tris, _ = MESHES[name]()
    walk = build_walk(build_bvh(verts, tris))
    rng = np.random.default_rng(4)
    for o, d, side in _scatter(verts, rng, 300):
        got = intersect_convex(walk, o, d, side)
        k, t = _brute(verts, tris, o, d, side)
        np.testing.assert_array_equal(got.triangle, k)
        hit = k >= 0
        assert hit.sum() > 100
        np.testing.assert_allclose(got.t[hit], t[hit], rtol=1e-9)
        assert np.all(np.isinf(got.t[~hit]))
        p = verts[tris[k[hit], 0]]
        p = p + got.u[hit, None] * (verts[tris[k[hit], 1]] - p)
        p = p + got.v[hit, None] * (verts[tris[k[hit], 2]] - verts[tris[k[hit], 0]])
        np.testing.assert_allclose(got.point[hit], p, atol=1e-9)


def test_ray_bounds_are_kept():
    verts, tris, _ = MESHES["ellipsoid"]()
    walk = build_walk(build_bvh(verts, tris))
    rng = np.random.default_rng(9)
    (o, d, side), _ = _scatter(verts, rng, 300)
    d = d / np.linalg.norm(d, axis=1)[:, None]
    k_all, t_all = _brute(verts, tris, o, d, side)
    # half the rays end before their hit, the others start beyond it
    t_min = np.where(np.arange(300) % 2 == 0, 0.0, np.where(k_all >= 0, t_all + 1e-6, 0.0))
    t_max = np.where(np.arange(300) % 2 == 0, np.where(k_all >= 0, t_all - 1e-6, np.inf), np.inf)
    got = intersect_convex(walk, o, d, side, t_min, t_max)
    k, _ = _brute(verts, tris, o, d, side, t_min, t_max)
    np.testing.assert_array_equal(got.triangle, k)
    assert np.all(got.triangle[k_all >= 0] < 0)  # the one hit each had is out of bounds


def _counted_casts(monkeypatch):
    """From now on, the rays of each BVH cast the walk falls back to (its
    `surface_walk.intersect`), in a list; and the plain function, to put back."""
    cast = []
    real = surface_walk.intersect

    def counting(bvh, o, *args, **kw):
        cast.append(len(o))
        return real(bvh, o, *args, **kw)

    monkeypatch.setattr(surface_walk, "intersect", counting)
    return cast, real


def test_a_light_bundle_is_walked_not_traversed(monkeypatch):
    """A point light's grid of rays over a 20 000-triangle pebble, the entering and
    the leaving wave: the walk finds almost every hit (the BVH casts the rays that
    miss and a few at the silhouette), the same hits as brute force on a sample."""
    verts, tris, _ = ellipsoid_mesh((0.0, 0.0, 1.0), (0.5, 0.5, 0.25), None, 100, 100)
    walk = build_walk(build_bvh(verts, tris))
    cast, real = _counted_casts(monkeypatch)
    light = np.array([0.3, 0.2, 4.0])
    ii, pp = np.meshgrid(np.linspace(0.0, 0.2, 65), np.linspace(0, 2 * np.pi, 256), indexing="ij")
    axis = np.array([-0.3, -0.2, -3.0]) / np.linalg.norm([-0.3, -0.2, -3.0])
    e1 = np.cross(axis, [0, 0, 1.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(axis, e1)
    d = (
        np.cos(ii)[..., None] * axis
        + np.sin(ii)[..., None] * (np.cos(pp)[..., None] * e1 + np.sin(pp)[..., None] * e2)
    ).reshape(-1, 3)
    o = np.broadcast_to(light, d.shape)
    h1 = intersect_convex(walk, o, d, 1)
    hit = h1.triangle >= 0
    # the leaving wave: straight on from a hair inside the entry points
    o2, d2 = h1.point[hit] + 1e-7 * d[hit], d[hit]
    h2 = intersect_convex(walk, o2, d2, -1)
    assert hit.sum() > 8000 and np.all(h2.triangle >= 0)
    n_rays = len(d) + len(d2)
    assert sum(cast) < 0.25 * n_rays  # rays the BVH traversed (the misses: ~7 000)
    assert sum(cast) > 0  # the misses cannot be walked
    monkeypatch.setattr(surface_walk, "intersect", real)
    pick = np.random.default_rng(2).choice(len(d), 60, replace=False)
    k, t = _brute(verts, tris, o[pick], d[pick], np.ones(60))
    np.testing.assert_array_equal(h1.triangle[pick], k)
    pick2 = np.random.default_rng(3).choice(len(d2), 60, replace=False)
    k2, _ = _brute(verts, tris, o2[pick2], d2[pick2], -np.ones(60))
    np.testing.assert_array_equal(h2.triangle[pick2], k2)


def test_edge_neighbours_and_open_edges():
    verts, tris, _ = MESHES["box"]()
    walk = build_walk(build_bvh(verts, tris))
    for f in range(len(tris)):
        for k in range(3):
            edge = {tris[f][(k + 1) % 3], tris[f][(k + 2) % 3]}
            others = [g for g in range(len(tris)) if g != f and edge <= set(tris[g])]
            assert walk.across[f, k] == others[0]
    # an open mesh (the box without its last face): the walk stops at the hole, the
    # BVH answers those rays; hits still equal brute force
    open_tris = tris[:-2]
    walk = build_walk(build_bvh(verts, open_tris))
    assert (walk.across < 0).sum() == 4
    rng = np.random.default_rng(5)
    for o, d, side in _scatter(verts, rng, 200):
        got = intersect_convex(walk, o, d, side)
        k, _ = _brute(verts, open_tris, o, d, side)
        np.testing.assert_array_equal(got.triangle, k)


def test_blocks_in_threads_give_the_same_hits(monkeypatch):
    from core.shared import parallel, surface_walk

    verts, tris, _ = MESHES["lens"]()
    walk = build_walk(build_bvh(verts, tris))
    rng = np.random.default_rng(6)
    for o, d, side in _scatter(verts, rng, 3000):
        one = intersect_convex(walk, o, d, side)
        monkeypatch.setattr(surface_walk, "THREAD_ROWS", 500)
        monkeypatch.setattr(parallel, "cores", lambda: 4)
        assert parallel.workers(len(o), surface_walk.THREAD_ROWS) > 1
        split = intersect_convex(walk, o, d, side)
        monkeypatch.undo()
        np.testing.assert_array_equal(split.triangle, one.triangle)
        np.testing.assert_array_equal(split.t, one.t)
        np.testing.assert_array_equal(split.u, one.u)
        assert (one.triangle >= 0).sum() > 1000


def test_a_far_light_grazing_the_silhouette_is_not_taken_for_a_miss():
    """A 1 cm pebble lit from 1 km: rays aimed at its rim, just inside and just
    outside; the sure-miss test (the grown ellipsoid) must not drop a grazing hit."""
    verts, tris, _ = ellipsoid_mesh((0.0, 0.0, 0.0), (0.01, 0.007, 0.005), None, 12, 24)
    walk = build_walk(build_bvh(verts, tris))
    light = np.array([1000.0, 300.0, 200.0])
    rng = np.random.default_rng(12)
    # points on the rim seen from the light: vertices, a hair in or out from the centre
    rim = verts[rng.choice(len(verts), 300)] * rng.uniform(0.999, 1.001, (300, 1))
    d = rim - light
    o = np.broadcast_to(light, d.shape)
    got = intersect_convex(walk, o, d, 1)
    k, t = _brute(verts, tris, o, d, np.ones(300))
    np.testing.assert_array_equal(got.triangle, k)
    assert 30 < (k >= 0).sum() < 290


def test_a_tilted_pebble_is_walked_in_its_own_frame(monkeypatch):
    """An oblate pebble (semi-axes 0.5, 0.4, 0.2) tilted 15° about a slanted axis:
    the walks' ellipsoid is inscribed in the pebble's own box (its principal axes are
    the rotation's columns, up to order and sign), so a point light's bundle is
    walked: the BVH casts 2 of its 6 161 rays (entering and leaving; in the
    world-aligned box 738), and the hits are brute force's."""
    ang = np.radians(15.0)
    k = np.array([1.0, 2.0, 0.5]) / np.linalg.norm([1.0, 2.0, 0.5])
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    rot = np.eye(3) + np.sin(ang) * kx + (1 - np.cos(ang)) * kx @ kx  # Rodrigues
    verts, tris, _ = ellipsoid_mesh((0.0, 0.0, 1.0), (0.5, 0.4, 0.2), rot, 32, 64)
    walk = build_walk(build_bvh(verts, tris))
    # each of the walk's axes is one of the pebble's (|cos| 1 with exactly one)
    np.testing.assert_allclose(np.sort(np.abs(walk.axes.T @ rot), axis=1)[:, -1], 1.0, atol=1e-6)
    cast, real = _counted_casts(monkeypatch)
    rng = np.random.default_rng(5)
    light = np.array([0.4, -0.3, 3.0])
    target = rng.uniform(-0.55, 0.55, (4000, 3)) * [1, 1, 0.3] + [0, 0, 1.0]
    d = target - light
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    o = np.broadcast_to(light, d.shape)
    h1 = intersect_convex(walk, o, d, 1)
    hit = h1.triangle >= 0
    o2, d2 = h1.point[hit] + 1e-7 * d[hit], d[hit]
    h2 = intersect_convex(walk, o2, d2, -1)
    assert hit.sum() > 2000 and np.all(h2.triangle >= 0)
    assert sum(cast) < 0.01 * (len(d) + len(d2)), sum(cast)
    monkeypatch.setattr(surface_walk, "intersect", real)
    pick = rng.choice(len(d2), 60, replace=False)
    k2, _ = _brute(verts, tris, o2[pick], d2[pick], -np.ones(60))
    np.testing.assert_array_equal(h2.triangle[pick], k2)
    k1, _ = _brute(verts, tris, o[pick], d[pick], np.ones(60))
    np.testing.assert_array_equal(h1.triangle[pick], k1)


@pytest.mark.parametrize("name", sorted(MESHES))
def test_rays_beside_the_glass_stop_at_its_silhouette(name, monkeypatch):
    """Rays passing beside a convex mesh but within the bounding ellipsoid the walks
    start on (the band between its faces and that ellipsoid): each walk reaches a
    silhouette edge, the line is beyond its plane, so it is a miss, with no BVH cast
    (before: 24 walk steps and then the BVH for each); rays a hair inside the rim
    still hit. All as brute force."""
    verts, tris, _ = MESHES[name]()
    walk = build_walk(build_bvh(verts, tris))
    rng = np.random.default_rng(8)
    # in the walk's frame (that ellipsoid the unit sphere): lines at a distance from 1
    # (inscribed) to the grown ellipsoid's reach, every direction
    q = rng.normal(size=(400, 3))
    q /= np.linalg.norm(q, axis=1)[:, None]
    off = np.cross(q, rng.normal(size=(400, 3)))
    off /= np.linalg.norm(off, axis=1)[:, None]
    off *= rng.uniform(1.0, walk.reach, (400, 1))
    o = walk.center + ((off - 3.0 * q) * walk.half) @ walk.axes.T
    d = (q * walk.half) @ walk.axes.T
    cast, real = _counted_casts(monkeypatch)
    got = intersect_convex(walk, o, d, 1)
    monkeypatch.setattr(surface_walk, "intersect", real)
    k, _ = _brute(verts, tris, o, d, np.ones(400))
    np.testing.assert_array_equal(got.triangle, k)
    assert (k < 0).sum() > 50
    assert sum(cast) < 0.2 * (k < 0).sum(), (sum(cast), (k < 0).sum())


def test_the_cube_map_holds_the_nearest_centre_and_walks_are_short(monkeypatch):
    """The speed bench's pebble (1 984 triangles: a latitude-longitude ellipsoid 0.5 ×
    0.5 × 0.25, smooth) under a point light 3 m above, a 121 × 121 grid of rays over
    it traced through (`MeshLens.trace_branches`: in, out, the internal reflections):
    with each cube-map texel holding the triangle whose centre's direction is nearest
    its own (most texels: brute force over all centres), the walks take 42 steps in
    all (triangle tests of a batch of rays; with the last centre to fall in a texel
    and the empty texels filled from the first neighbour found: 186). The exit rays as
    BVH's own (the walk only guesses where to start)."""
    from core.lens.mesh import MeshLens
    from core.shared import triangle_bvh

    verts, tris, nrm = ellipsoid_mesh((0.0, 0.0, 1.0), (0.5, 0.5, 0.25), None, 32, 32)
    lens = MeshLens((0.0, 0.0, 1.0), 0.5, 1.5, 0.0, verts, tris, nrm[tris])
    walk = lens.walker
    # the map against brute force: each texel's nearest centre (directions in the
    # walk's frame, through the texel's centre as `_texel` reads it)
    cen = verts[lens.triangles].mean(axis=1)
    c = walk.local(cen, cen)[0]
    c /= np.linalg.norm(c, axis=1)[:, None]
    m = walk.cube.shape[1]
    g = (np.arange(m) + 0.5) / m * 2.0 - 1.0
    agree = 0
    for f in range(6):
        q = np.zeros((m, m, 3))
        q[..., f // 2] = -1.0 if f % 2 else 1.0
        q[..., (f // 2 + 1) % 3] = g[:, None]
        q[..., (f // 2 + 2) % 3] = g[None, :]
        q = q.reshape(-1, 3) / np.linalg.norm(q.reshape(-1, 3), axis=1)[:, None]
        best = np.argmax(q @ c.T, axis=1)
        agree += int(np.sum(walk.slot[best] == walk.slot[walk.cube[f].reshape(-1)]))
    assert agree > 0.95 * walk.cube.size, agree / walk.cube.size
    light = np.array([0.0, 0.0, 4.0])
    g = np.linspace(-0.55, 0.55, 121)
    x, y = np.meshgrid(g, g)
    d = np.stack([x.ravel(), y.ravel(), np.full(x.size, 1.0)], 1) - light
    d /= np.linalg.norm(d, axis=1)[:, None]
    o = np.broadcast_to(light, d.shape)
    steps = []
    real = surface_walk.hit_slots

    def counting(bvh, o_, *args):
        steps.append(len(o_))
        return real(bvh, o_, *args)

    monkeypatch.setattr(surface_walk, "hit_slots", counting)
    walked = lens.trace_branches(o, d)
    monkeypatch.undo()
    assert len(steps) < 80, len(steps)
    # the same paths with every cast the BVH's (no walk)
    monkeypatch.setattr(
        type(lens),
        "_cast",
        lambda self, seg: triangle_bvh.intersect(self.bvh, seg.origin, seg.direction),
    )
    lens2 = MeshLens((0.0, 0.0, 1.0), 0.5, 1.5, 0.0, verts, tris, nrm[tris])
    cast = lens2.trace_branches(o, d)
    # (a ray through an edge may be given either triangle: the same point and way on)
    np.testing.assert_allclose(walked.points, cast.points, rtol=0, atol=1e-9)
    np.testing.assert_allclose(walked.directions, cast.directions, rtol=0, atol=1e-9)
    np.testing.assert_allclose(walked.weight, cast.weight, rtol=0, atol=1e-9)
