"""`core.shared.vectors.cross` against numpy's own cross product."""

import numpy as np

from core.shared.vectors import cross


def test_cross_of_rows_and_of_two_vectors_is_numpys():
    rng = np.random.default_rng(3)
    a, b = rng.normal(size=(7, 3)), rng.normal(size=(7, 3))
    np.testing.assert_allclose(cross(a, b), np.cross(a, b), rtol=0, atol=1e-15)
    np.testing.assert_allclose(cross(a[2], b[5]), np.cross(a[2], b[5]), rtol=0, atol=1e-15)
    np.testing.assert_array_equal(cross(np.array([1.0, 0, 0]), np.array([0, 1.0, 0])), [0, 0, 1])
    # (…, 3) stacks too, and a broadcast partner
    c = rng.normal(size=(2, 4, 3))
    np.testing.assert_allclose(cross(c, b[0]), np.cross(c, b[0]), rtol=0, atol=1e-15)
