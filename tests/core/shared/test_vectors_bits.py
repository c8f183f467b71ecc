"""`core.shared.vectors.cross` (the planner's and the tracers' cross product): numpy's own
`np.cross` bit for bit (the same products in the same order), for the shapes the
planner passes (one vector, rows of vectors, rows against one vector)."""

import numpy as np
import pytest

from core.shared.vectors import cross, norm


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
