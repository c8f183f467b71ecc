"""The sheet's grid (`core.lens.slab_grid`) finds the same nearest hits as the
triangle BVH (`core.shared.triangle_bvh`, independent code) on a wavy sheet, for
steep, oblique, grazing (the BVH's share), upward and in-sheet rays."""

import math

import numpy as np

from core.lens.slab_grid import build_slab_grid, intersect
from core.lens.water import rest_plane
from core.shared.triangle_bvh import build_bvh
from core.shared.triangle_bvh import intersect as bvh_intersect


def _sheet(n=40, tilt=0.3):
    xs = np.linspace(-1.0, 1.0, n + 1)
    gx, gy = np.meshgrid(xs, 0.7 * xs)
    gz = 0.03 * np.sin(9.0 * gx + 1.0) * np.cos(7.0 * gy) + 0.02 * np.sin(5.0 * gy)
    v = np.stack([gx, gy, gz], -1).reshape(-1, 3)
    c, s = math.cos(tilt), math.sin(tilt)
    v = v @ np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]]).T + [0.2, -0.1, 1.0]
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    a = (i * (n + 1) + j).reshape(-1)
    t = np.concatenate([np.stack([a, a + 1, a + n + 2], 1), np.stack([a, a + n + 2, a + n + 1], 1)])
    return v, t


def test_same_hits_as_the_bvh():
    v, t = _sheet()
    pl = rest_plane(v)
    grid = build_slab_grid(v, t, pl)
    bvh = build_bvh(v, t)
    rng = np.random.default_rng(4)
    n = 6000
    targets = v[rng.integers(len(v), size=n)] + rng.normal(0, 0.05, (n, 3))
    d = rng.normal(size=(n, 3))
    d[: n // 2, 2] = -np.abs(d[: n // 2, 2]) - 2.0  # steep, down
    d[n // 2 : 3 * n // 4, 2] *= 0.02  # grazing
    d /= np.linalg.norm(d, axis=1)[:, None]
    o = targets - 3.0 * d
    o[-50:] = targets[-50:]  # starting inside the slab
    d[-10:] = np.cross(pl.normal, rng.normal(size=(10, 3)))  # travelling in its plane
    d[-10:] /= np.linalg.norm(d[-10:], axis=1)[:, None]
    h = intersect(grid, bvh, o, d)
    ref = bvh_intersect(bvh, o, d)
    hit = ref.triangle >= 0
    assert hit.sum() > n // 3
    np.testing.assert_array_equal(h.triangle >= 0, hit)
    np.testing.assert_allclose(h.t[hit], ref.t[hit], rtol=1e-9, atol=1e-12)
    # the same triangle, or one sharing the hit point (a ray through an edge)
    same = h.triangle[hit] == ref.triangle[hit]
    np.testing.assert_allclose(h.point[hit][~same], ref.point[hit][~same], atol=1e-9)
    assert same.mean() > 0.999
