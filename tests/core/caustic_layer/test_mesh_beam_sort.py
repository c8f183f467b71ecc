"""The glass beam's cells sorted out (`mesh_beam._corner_paths`): the kept paths at every
cell's corners in the order of one lexsort by (cell, signature, corner, −weight), the
simple computation it replaces, on grids with repeated signatures at a node and equal
weights (the rare cases its shortcut handles apart)."""

import numpy as np
import pytest

from core.caustic_layer.mesh_beam import _corner_paths, _grid_corners


def _lexsorted(keep, sig, w, corners):
    nb = keep.shape[0]
    b, c, q = np.nonzero(keep.reshape(nb, -1)[:, corners])
    node = corners[c, q]
    sg, wt = sig.reshape(nb, -1)[b, node], w.reshape(nb, -1)[b, node]
    o = np.lexsort((-wt, q, sg, c))
    return b[o], c[o], q[o], sg[o], wt[o]


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_corner_paths_are_the_lexsort_of_cell_signature_corner_and_weight(seed):
    rng = np.random.default_rng(seed)
    nb, k, nr, na = 5, 2, 7, 9
    keep = rng.random((nb, k, nr + 1, na)) < 0.6
    # few signatures (paths shared by neighbours), some twice at one node, and weights
    # rounded so that some tie
    sig = rng.integers(0, 4, (nb, k, nr + 1, na)).astype(np.uint64) * np.uint64(2**61)
    w = np.round(rng.random((nb, k, nr + 1, na)), 1)
    corners = _grid_corners(k, nr, na, wrap=True)
    got, want = _corner_paths(keep, sig, w, corners), _lexsorted(keep, sig, w, corners)
    for a, b in zip(got, want, strict=True):
        assert np.array_equal(a, b)
    n = np.count_nonzero(keep.reshape(nb, -1)[:, corners])
    assert len(got[0]) == n > 100
    # the rare case is there: one signature twice at a corner
    _, c, q, sg, _ = got
    assert np.any((c[1:] == c[:-1]) & (q[1:] == q[:-1]) & (sg[1:] == sg[:-1]))
