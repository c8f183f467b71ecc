"""A glass mesh's built lens (BVH, surface walk, face groups) reused by content
(`beam_trace.optics_of`): Generate pressed again on an unchanged glass reads new arrays
of the same values and gets the lens already built; any change (a vertex, a normal, the
index) builds a new one; `clear_built` forgets them all."""

import numpy as np
from glass_meshes import sphere

from core.caustic_layer.beam_trace import clear_built, optics_of
from core.caustic_layer.emitters import Lens


def _record(v, t, nrm, ior=1.5):
    return Lens(np.zeros(3), 1.0, ior, kind="mesh", params=(v.copy(), t.copy(), nrm.copy()))


def test_the_same_glass_read_again_reuses_its_built_lens():
    clear_built()
    v, t, nrm = sphere(1.0, 8, 16)
    first = optics_of(_record(v, t, nrm))
    assert optics_of(_record(v, t, nrm)) is first  # new arrays, the same values
    moved = v.copy()
    moved[3, 0] += 1e-9
    assert optics_of(_record(moved, t, nrm)) is not first
    bent = nrm.copy()
    bent[5, 1] *= 1.0 + 1e-12
    assert optics_of(_record(v, t, bent)) is not first
    assert optics_of(_record(v, t, nrm, ior=1.33)) is not first
    clear_built()
    again = optics_of(_record(v, t, nrm))
    assert again is not first
    # what was built is the same lens
    assert np.array_equal(again.triangles, first.triangles)
    assert np.array_equal(again.corner_normals, first.corner_normals)


def test_a_ball_is_made_each_time():
    ball = Lens(np.zeros(3), 1.0, 1.5)
    assert optics_of(ball) is not optics_of(ball)
