"""`blender.read.occluders.Occluders.first_hits` (every kept source's rays in one call,
`planning.plan_result`) against `first_hit` bundle by bundle: random spheres and
mesh instances (rotated, scaled planes and boxes, shared meshes, overlapping
boxes), hits to the BVH's single precision; the plane's hits by hand."""

import math

import bpy  # noqa: F401  (mathutils comes with it)
import numpy as np
import pytest

pytestmark = [pytest.mark.blender, pytest.mark.usefixtures("extension")]


def box_mesh():
    v = np.array([(x, y, z) for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    tris = [t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))]
    return v, np.array(tris)


def test_batched_first_hits_equal_the_per_bundle_ones():
    from lens_lights.blender.read.occluders import MeshSource, Occluders
    from mathutils import Euler, Matrix

    rng = np.random.default_rng(11)
    C = rng.uniform(-10, 10, (300, 3))
    R = rng.uniform(0.05, 0.8, 300)
    plane = (
        np.array([(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], float),
        np.array([(0, 1, 2), (0, 2, 3)]),
    )
    sources = [MeshSource(arrays=plane), MeshSource(arrays=box_mesh())]
    mats, index = [], []
    for k in range(25):
        m = (
            Matrix.Translation(tuple(rng.uniform(-10, 10, 3)))
            @ Euler(tuple(rng.uniform(0, math.pi, 3))).to_matrix().to_4x4()
            @ Matrix.Diagonal((*rng.uniform(0.5, 4, 3), 1.0))
        )
        mats.append(np.array(m))
        index.append(k % 2)
    lo, hi = [], []
    for m, s in zip(mats, index, strict=True):
        w = sources[s]._arrays[0] @ m[:3, :3].T + m[:3, 3]
        lo.append(w.min(0))
        hi.append(w.max(0))
    occ = Occluders(C, R, np.array(mats), np.array(lo), np.array(hi), index, sources)
    B = 80
    o0 = rng.uniform(-12, 12, (B, 3))
    origins = o0[:, None] + rng.uniform(-0.4, 0.4, (B, 5, 3))
    d = rng.normal(size=(B, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    got = occ.first_hits(origins, d, 15.0)
    want = np.array([occ.first_hit(origins[b], d[b], 15.0) for b in range(B)])
    np.testing.assert_array_equal(np.isfinite(got), np.isfinite(want))
    np.testing.assert_allclose(got[np.isfinite(want)], want[np.isfinite(want)], rtol=1e-6)
    assert 100 < np.isfinite(want).sum() < 5 * B
    # one plane by hand: 2 × 2 turned 30° about x, scaled 3, centred at (0, 0, 5)
    m = np.array(
        Matrix.Translation((0, 0, 5))
        @ Matrix.Rotation(math.radians(30), 4, "X")
        @ Matrix.Scale(3, 4)
    )
    w = plane[0] @ m[:3, :3].T + m[:3, 3]
    one = Occluders(
        np.zeros((0, 3)),
        np.zeros(0),
        m[None],
        w.min(0)[None],
        w.max(0)[None],
        [0],
        [MeshSource(arrays=plane)],
    )
    hits = one.first_hits(
        np.array([[(0, 0, 0), (0.5, 0.2, 0), (10, 0, 0)]], float), np.array([(0, 0, 2.0)]), 100.0
    )[0]
    assert hits[0] == pytest.approx(5.0, rel=1e-6)  # the BVH is single precision
    assert hits[1] == pytest.approx(5.0 + 0.2 * math.tan(math.radians(30)), rel=1e-6)
    assert hits[2] == math.inf
