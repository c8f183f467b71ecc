"""The splat's per-cell reductions written out over the four corner columns
(`rasters._corner_sum`, `rasters._corner_ptp`): numpy's ``sum(axis=1)``, ``mean(1)``
and ``np.ptp(axis=1)`` bit for bit, on rows of every scale, ties and signed zeros."""

import numpy as np

from core.caustic_layer import rasters


def test_corner_sums_and_spans_are_numpys():
    rng = np.random.default_rng(5)
    a = rng.normal(size=(25_000, 4)) * 10.0 ** rng.uniform(-8, 8, size=(25_000, 1))
    a[:100] = np.round(a[:100])  # ties
    a[100] = (-0.0, 0.0, -0.0, 0.0)
    a[101] = (1e300, -1e300, 1e-300, 3.0)
    np.testing.assert_array_equal(rasters._corner_sum(a), a.sum(axis=1))
    np.testing.assert_array_equal(rasters._corner_sum(a) / 4.0, a.mean(1))
    np.testing.assert_array_equal(rasters._corner_ptp(a), np.ptp(a, axis=1))
