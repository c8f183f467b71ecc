"""The camera's view of the caustic layer (`core/caustic_layer/view.py`) and the rasters
fitted to it (`rasters.build_layer(view=…)`): texels a third of a pixel where the camera
sees the caustic, finer when it is nearer, none out of view. Expectations by hand
(a pixel at depth z spans 2 z tan(fov/2) / width) and from the exact optics' flux."""

import math

import numpy as np
import pytest

from core.caustic_layer.beam_trace import trace_beam
from core.caustic_layer.emitters import Lens, PointLight
from core.caustic_layer.rasters import build_layer
from core.caustic_layer.receiver_index import build_index
from core.caustic_layer.view import view_of
from core.lens import ball_optics as eo
from core.scene.model import Camera as ModelCamera
from reference.meshes import rectangle

R, N_IOR, D, Z = 1.0, 1.5, 10.0, 5.0  # the ball at the origin, the floor at z = 5
I0 = 1.0


def _down(height, x=0.0, fov_deg=90.0, width=200, height_px=200):
    """A camera at (x, 0, height) looking down −… along +z toward the floor (z = 5 is
    below it: the light comes from z = −10, the floor is at z = +5, so 'down' is +z)."""
    cam = ModelCamera(
        position=(x, 0.0, Z - height),
        target=(x, 0.0, Z),
        up=(0.0, 1.0, 0.0),
        fov_deg=(fov_deg, fov_deg),
    )
    return view_of(cam, width, height_px)


def test_a_pixel_and_the_frame_by_hand():
    v = _down(2.0, fov_deg=90.0, width=100, height_px=50)
    # horizontal 90°: tan 45° = 1; the vertical opening given as 90° too (a square
    # sensor, as the read computes it for the render's aspect)
    assert v.half_x == pytest.approx(1.0) and v.half_y == pytest.approx(1.0)
    # a point on the floor, depth 2: a pixel spans 2 · 2 · 1 / 100 = 0.04
    assert v.pixel([[0.3, 0.2, Z]])[0] == pytest.approx(0.04)
    # the frame at depth 2 spans x, y in [−2, 2] (+5 % margin per side: 2.2)
    inside = v.in_view([[1.9, -1.9, Z], [2.1, 0.0, Z], [2.3, 0.0, Z], [0.0, 0.0, Z - 3.0]])
    assert inside.tolist() == [True, True, False, False]  # the last one behind it
    ortho = view_of(ModelCamera((0, 0, 0), (0, 0, 1), (0, 1, 0)), 64, 32, ortho_scale=6.4)
    assert ortho.pixel([[0.0, 0.0, 9.0]])[0] == pytest.approx(0.1)  # 6.4 / 64 anywhere
    assert ortho.in_view([[3.1, 1.5, 1.0], [0.0, 1.8, 1.0]]).tolist() == [True, False]


def _layer(view, **kw):
    lens = Lens(np.zeros(3), R, N_IOR)
    light = PointLight(np.array([0.0, 0.0, -D]), 4.0 * math.pi * I0)
    floor = rectangle([0, 0, Z], [0, 0, 1], 200.0, 200.0, 4, 4)
    return build_layer(
        [trace_beam(light, lens, 32, 128)],
        build_index(floor),
        resolution=256,
        view=view,
        **kw,
    )


def test_resolution_follows_the_cameras_distance():
    # from 10 and from 20 above the floor: a pixel there spans 2 · 10 · tan 45° / 60
    # = 1/3, and 2/3; the texels along the raster's longer side, on average, a third
    for height, pixel in ((10.0, 1 / 3), (20.0, 2 / 3)):
        (p,) = _layer(_down(height, width=60)).patches
        span = max(p.edges_u[-1] - p.edges_u[0], p.edges_v[-1] - p.edges_v[0])
        assert span / p.resolution == pytest.approx(pixel / 3, rel=0.05)
    # the whole caustic in view from 40 above: the exact optics' flux in the raster
    flux = eo.lens_flux(I0, D, R, N_IOR)
    assert _layer(_down(40.0)).flux_in_rasters == pytest.approx(flux, rel=0.01)
    # within the budget of texels: every raster scaled down alike
    capped = _layer(_down(10.0, width=200), max_texels=32 * 32)
    assert capped.patches[0].resolution == 32


def test_no_raster_out_of_view_and_only_the_part_in_view():
    layer = _layer(_down(10.0, x=60.0))  # sees x in [50, 70]: far from the caustic
    assert layer.patches == []
    assert layer.flux_in_rasters == 0.0
    assert layer.flux_outside + layer.flux_lost == pytest.approx(layer.flux_emitted, rel=1e-9)
    # a camera seeing x in [1, 3] (from 1 above, fov 90°): the raster starts there
    half = _layer(_down(1.0, x=2.0, width=100))
    (p,) = half.patches
    x = p.vertices[:, 0]
    assert x.min() > 1.0 - 0.1 * 2.0 - 0.05  # the frame, its margin, a texel
    assert x.max() < 3.0 + 0.1 * 2.0 + 0.05
    assert 0.0 < half.flux_in_rasters < 0.5 * layer.flux_emitted
