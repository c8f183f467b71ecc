"""`core.shared.vectors.cross` (the planner's and the tracers' cross product): numpy's own
`np.cross` bit for bit (the same products in the same order), for the shapes the
planner passes (one vector, rows of vectors, rows against one vector)."""

import numpy as np
import pytest

from core.shared.vectors import column_bounds, corner_bounds, corner_mean, cross, dot, norm


@pytest.mark.parametrize(
    "shape_a,shape_b", [((3,), (3,)), ((24, 3), (24, 3)), ((24, 3), (3,)), ((3,), (7, 3))]
)
def test_cross_is_numpys_cross_bit_for_bit(shape_a, shape_b):
    rng = np.random.default_rng(7)
    for _ in range(100):
        a = rng.normal(size=shape_a) * 10.0 ** rng.uniform(-3, 3)
        b = rng.normal(size=shape_b) * 10.0 ** rng.uniform(-3, 3)
        want = np.cross(a, b)
        got = cross(a, b)
        assert got.shape == want.shape and got.dtype == want.dtype
        np.testing.assert_array_equal(got, want)
    u = rng.normal(size=3)
    np.testing.assert_array_equal(cross(u, (1.0, 0.0, 0.0)), np.cross(u, (1.0, 0.0, 0.0)))


@pytest.mark.parametrize("shape", [(3,), (1, 3), (50, 3), (15_000, 3), (4, 6, 3)])
def test_norm_is_numpys_norm_bit_for_bit(shape):
    """The walk's and the refraction's row lengths: np.linalg.norm(v, axis=-1) exactly
    (rows of every scale, zeros, one huge component)."""
    rng = np.random.default_rng(11)
    v = rng.normal(size=shape) * 10.0 ** rng.uniform(-150, 150, size=(*shape[:-1], 1))
    v.reshape(-1, 3)[0] = 0.0
    v.reshape(-1, 3)[-1] = (1e-300, 3.0, 1e300) if v.size > 3 else v.reshape(-1, 3)[-1]
    with np.errstate(over="ignore", under="ignore"):  # inf where a square overflows: both
        want = np.linalg.norm(v, axis=-1)
        got = norm(v)
    assert got.shape == want.shape and got.dtype == want.dtype
    np.testing.assert_array_equal(got, want)


def test_column_and_corner_reductions_are_numpys():
    """The BVH's and the walk's bounds and centroids without numpy's slow reductions
    over a short axis: its min, max and mean bit for bit (ties, signed zeros, NaN)."""
    rng = np.random.default_rng(13)
    c = rng.normal(size=(5000, 3, 3)) * 10.0 ** rng.uniform(-6, 6, size=(5000, 1, 1))
    c[:50] = np.round(c[:50])
    c[50] = -0.0
    c[51, 1] = np.nan
    np.testing.assert_array_equal(corner_mean(c), c.mean(axis=1))
    lo, hi = corner_bounds(c)
    np.testing.assert_array_equal(lo, c.min(axis=1))
    np.testing.assert_array_equal(hi, c.max(axis=1))
    a = c[:, 0][52:]
    lo, hi = column_bounds(a)
    np.testing.assert_array_equal(lo, a.min(axis=0))
    np.testing.assert_array_equal(hi, a.max(axis=0))


@pytest.mark.parametrize(
    "shape_a,shape_b",
    [((20_000, 3), (20_000, 3)), ((7, 3), (7, 3)), ((500, 3, 3), (500, 1, 3)), ((100, 3), (3,))],
)
def test_dot_is_numpys_einsum_bit_for_bit(shape_a, shape_b):
    """The walk's and the refraction's row dot products: np.einsum("...i,...i->...")
    exactly (numpy 1.26 and 2.x add the three products as (x + z) + y), also on
    strided rows (a packed BVH row's columns) and broadcast."""
    rng = np.random.default_rng(17)
    a = rng.normal(size=shape_a) * 10.0 ** rng.uniform(-5, 5, size=(*shape_a[:-1], 1))
    b = rng.normal(size=shape_b)
    np.testing.assert_array_equal(dot(a, b), np.einsum("...i,...i->...", a, b))
    packed = rng.normal(size=(300, 13))
    rows = rng.normal(size=(300, 3)) * 10.0 ** rng.uniform(-5, 5, size=(300, 1))
    np.testing.assert_array_equal(
        dot(packed[:, 9:12], rows), np.einsum("ij,ij->i", packed[:, 9:12], rows)
    )
