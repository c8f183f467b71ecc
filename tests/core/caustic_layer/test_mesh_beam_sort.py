"""The glass beam's cells sorted out (`mesh_beam._corner_paths`): the kept paths at every
cell's corners in the order of one lexsort by (cell, signature, corner, −weight), the
simple computation it replaces, on grids with repeated signatures at a node and equal
weights (the rare cases its shortcut handles apart); and its rays (`mesh_beam.rays_at`)
with each sample's sphere half-angle taken once, against the per-ray gathers."""

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


@pytest.mark.parametrize("radius", [0.0, 0.3])
def test_rays_at_are_the_per_ray_gathers_of_each_sample(radius):
    # `rays_at` takes each sample's sphere half-angle once and gathers it per ray: the
    # same values as computing it from each ray's gathered sample (the simple form)
    from core.caustic_layer.beam_trace import _batch, frames_of
    from core.caustic_layer.emitters import Lens, PointLight
    from core.caustic_layer.mesh_beam import rays_at

    light = PointLight(np.array([0.3, -0.2, 5.0]), 100.0, radius=radius)
    bt = _batch([(light, Lens(np.zeros(3), 1.0, 1.5))], 16 if radius else 1)
    k = len(bt.weights)
    rows = np.broadcast_to(np.arange(k)[:, None, None], (k, 5, 8))
    iota = np.broadcast_to(np.linspace(0.0, 1.4, 5)[None, :, None], rows.shape)
    phi = np.broadcast_to(np.linspace(0.0, 6.0, 8)[None, None, :], rows.shape)
    frames = frames_of(bt.axes)
    o, d, g = rays_at(bt, rows, iota, phi, frames, light, False)
    _, _, g_only = rays_at(bt, rows, iota, phi, frames, light, False, rays=False)
    r = bt.radius[rows]
    s = r / np.maximum(np.linalg.norm(bt.center[rows] - bt.points[rows], axis=-1), r)
    sin_psi = s * np.sin(iota)
    cos_psi = np.sqrt((1.0 - sin_psi) * (1.0 + sin_psi))
    f = frames[rows]
    radial = np.cos(phi)[..., None] * f[..., 0, :] + np.sin(phi)[..., None] * f[..., 1, :]
    want_d = cos_psi[..., None] * bt.axes[rows] + sin_psi[..., None] * radial
    assert k == (16 if radius else 1)
    assert np.array_equal(d, want_d)
    assert np.array_equal(o, np.broadcast_to(bt.points[rows], want_d.shape))
    assert np.array_equal(g, g_only)
