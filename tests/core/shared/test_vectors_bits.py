"""`core.shared.vectors.cross` (the planner's and the tracers' cross product): numpy's own
`np.cross` bit for bit (the same products in the same order), for the shapes the
planner passes (one vector, rows of vectors, rows against one vector)."""

import numpy as np
import pytest

from core.shared.vectors import cross


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
