"""The shared triangle BVH against brute force: every ray against every triangle by
solving o + t d = v0 + u e1 + v e2 (numpy's linear solver, not the code under test)."""

import numpy as np
import pytest

from core.shared.triangle_bvh import build_bvh, intersect
from reference.meshes import uv_sphere


def _brute(verts, tris, o, d, t_min, t_max):
    v0 = verts[tris[:, 0]]
    e1, e2 = verts[tris[:, 1]] - v0, verts[tris[:, 2]] - v0
    best_t = np.full(len(o), np.inf)
    best_k = np.full(len(o), -1)
    for i in range(len(o)):
        m = np.stack([-np.broadcast_to(d[i], e1.shape), e1, e2], axis=-1)  # (T, 3, 3)
        ok = np.abs(np.linalg.det(m)) > 1e-12
        sol = np.linalg.solve(m[ok], (o[i] - v0[ok])[..., None])[..., 0]
        t, u, v = sol.T
        inside = (u >= 0) & (v >= 0) & (u + v <= 1) & (t > t_min[i]) & (t <= t_max[i])
        if inside.any():
            j = np.argmin(np.where(inside, t, np.inf))
            best_t[i], best_k[i] = t[j], np.nonzero(ok)[0][j]
    return best_k, best_t


@pytest.mark.parametrize("leaf", [1, 3, 4, 8])
def test_nearest_hit_of_a_triangle_soup_equals_brute_force(leaf):
    rng = np.random.default_rng(11)
    cen = rng.uniform(-3, 3, (250, 3))
    verts = np.repeat(cen, 3, axis=0) + rng.normal(0, 0.5, (750, 3))
    tris = np.arange(750).reshape(250, 3)
    o = rng.uniform(-4, 4, (300, 3))
    d = rng.normal(size=(300, 3))
    t_min = rng.uniform(0, 1, 300)
    t_max = rng.uniform(2, 8, 300)
    hits = intersect(build_bvh(verts, tris, leaf_size=leaf), o, d, t_min, t_max, chunk=97)
    k, t = _brute(verts, tris, o, d, t_min, t_max)
    np.testing.assert_array_equal(hits.triangle, k)
    hit = k >= 0
    assert hit.sum() > 50
    np.testing.assert_allclose(hits.t[hit], t[hit], rtol=1e-9)
    assert np.all(np.isinf(hits.t[~hit]))
    # the barycentrics give the hit point
    p = (
        verts[tris[k[hit], 0]]
        + hits.u[hit, None] * (verts[tris[k[hit], 1]] - verts[tris[k[hit], 0]])
        + hits.v[hit, None] * (verts[tris[k[hit], 2]] - verts[tris[k[hit], 0]])
    )
    np.testing.assert_allclose(p, hits.point[hit], atol=1e-9)


def test_rays_from_inside_a_closed_sphere_all_hit_it_once_ahead():
    m = uv_sphere((0.5, -0.2, 0.1), 2.0, 24, 48)
    verts, tris = np.asarray(m.vertices), np.asarray(m.triangles)
    rng = np.random.default_rng(3)
    o = np.array([0.5, -0.2, 0.1]) + rng.uniform(-1, 1, (200, 3))
    d = rng.normal(size=(200, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    hits = intersect(build_bvh(verts, tris), o, d)
    k, t = _brute(verts, tris, o, d, np.zeros(200), np.full(200, np.inf))
    assert np.all(hits.triangle >= 0)
    np.testing.assert_allclose(hits.t, t, rtol=1e-9)
    np.testing.assert_array_equal(hits.triangle, k)


def _brute_side(verts, tris, o, d, side):
    """The nearest hit among the triangles on ``side`` (+1: facing the ray)."""
    v0 = verts[tris[:, 0]]
    n = np.cross(verts[tris[:, 1]] - v0, verts[tris[:, 2]] - v0)
    out = []
    for i in range(len(o)):
        keep = side * (d[i] @ n.T) < 0
        k, t = _brute(verts, tris[keep], o[i : i + 1], d[i : i + 1], [0.0], [np.inf])
        out.append(np.nonzero(keep)[0][k[0]] if k[0] >= 0 else -1)
    return np.array(out)


@pytest.mark.parametrize("shape", ["ellipsoid", "box"])
def test_one_side_of_a_convex_mesh_is_its_one_way_in_or_out(shape):
    if shape == "box":  # leaves holding opposite faces: normals that cancel
        from glass_meshes import box

        verts, tris = box((-1.3, -0.8, -1.1), (1.7, 1.0, 0.5))
    else:
        m = uv_sphere((0.2, 0.1, -0.3), 1.5, 20, 40)
        verts, tris = np.asarray(m.vertices) * [1.0, 0.6, 0.8], np.asarray(m.triangles)
    bvh = build_bvh(verts, tris)
    rng = np.random.default_rng(7)
    outside = rng.normal(size=(150, 3))
    outside = 5 * outside / np.linalg.norm(outside, axis=1)[:, None]
    d_in = rng.uniform(-0.8, 0.8, (150, 3)) - outside
    inside = rng.uniform(-0.4, 0.4, (150, 3)) + [0.2, 0.1, -0.3]
    d_out = rng.normal(size=(150, 3))
    for o, d, side in ((outside, d_in, 1), (inside, d_out, -1)):
        got = intersect(bvh, o, d, facing=side)
        want = _brute_side(verts, tris, o, d, side)
        np.testing.assert_array_equal(got.triangle, want)
        assert (want >= 0).sum() > 100
        two_sided = intersect(bvh, o, d)  # the same face: the nearest either way
        np.testing.assert_array_equal(two_sided.triangle, want)
