"""The camera's view of the caustic layer (`core/caustic_layer/view.py`) and the rasters
fitted to it (`rasters.build_layer(view=…)`): texels a third of a pixel where the camera
sees the caustic, finer when it is nearer, a coarse raster for what lands out of view
(a mirror sees it), and the ray budget that follows the texels the caustic covers.
Expectations by hand (a pixel at depth z spans 2 z tan(fov/2) / width) and from the
exact optics' flux."""

import math

import numpy as np
import pytest

from core.caustic_layer.beam_trace import trace_beam
from core.caustic_layer.emitters import Lens, PointLight
from core.caustic_layer.pipeline import SheetSource, bake
from core.caustic_layer.rasters import COARSE_RESOLUTION, build_layer
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
        (p,) = [q for q in _layer(_down(height, width=60)).patches if not q.coarse]
        span = max(p.edges_u[-1] - p.edges_u[0], p.edges_v[-1] - p.edges_v[0])
        assert span / p.resolution == pytest.approx(pixel / 3, rel=0.05)
    # the whole caustic in view from 40 above: the exact optics' flux in the raster
    flux = eo.lens_flux(I0, D, R, N_IOR)
    assert _layer(_down(40.0)).flux_in_rasters == pytest.approx(flux, rel=0.01)
    # within the budget of texels: the coarse raster (out of view) at most a quarter of
    # it (48 → 16 per side), the raster in view the rest: 32² − 16² = 768 → 27 per side
    capped = _layer(_down(10.0, width=200), max_texels=32 * 32)
    assert sorted((p.coarse, p.resolution) for p in capped.patches) == [(False, 27), (True, 16)]


def _flux_within(layer, radius):
    """The flux drawn within ``radius`` of the axis (texel centres), all rasters."""
    out = 0.0
    for p in layer.patches:
        c = p.texel_centers()
        inside = np.hypot(c[..., 0], c[..., 1]) < radius
        out += float(p.texel_flux()[..., 0][inside].sum())
    return out


def test_out_of_view_a_coarse_raster_not_nothing():
    # A camera that sees x in [50, 70]: the caustic is all out of its view, but a mirror
    # may show it: one coarse raster holds it all (main: no raster, the flux "outside").
    layer = _layer(_down(10.0, x=60.0))
    (p,) = layer.patches
    assert p.coarse and p.resolution == COARSE_RESOLUTION
    exact = eo.lens_flux(I0, D, R, N_IOR)
    assert layer.flux_in_rasters == pytest.approx(exact, rel=0.01)
    assert layer.flux_in_rasters + layer.flux_outside + layer.flux_lost == pytest.approx(
        layer.flux_emitted, rel=1e-9
    )
    # its flux where it lands, against the exact optics (landing radii by the exact
    # trace): within a coarse texel (0.16 at the core to 3 in the far halo; counted by
    # their centres) of the exact flux within each radius
    for r in (1.0, 2.0, 3.0):
        want = float(eo.flux_within_radius(I0, D, R, N_IOR, Z, [r])[0])
        assert _flux_within(layer, r) == pytest.approx(want, rel=0.1)


def test_the_part_in_view_fine_the_rest_coarse_the_flux_whole():
    # a camera seeing x in [1, 3] (from 1 above, fov 90°): the fine raster starts there,
    # the caustic's core (r < 0.8, out of that view) is drawn by the coarse raster
    half = _layer(_down(1.0, x=2.0, width=100))
    fine = [p for p in half.patches if not p.coarse]
    coarse = [p for p in half.patches if p.coarse]
    assert len(fine) == 1 and len(coarse) == 1
    x = fine[0].vertices[:, 0]
    assert x.min() > 1.0 - 0.1 * 2.0 - 0.05  # the frame, its margin, a texel
    assert x.max() < 3.0 + 0.1 * 2.0 + 0.05
    exact = eo.lens_flux(I0, D, R, N_IOR)
    assert 0.0 < fine[0].flux < 0.5 * exact
    # nothing drawn twice, nothing left out: the exact flux in all, and where it lands
    assert half.flux_in_rasters == pytest.approx(exact, rel=0.01)
    for r in (0.5, 0.8):  # out of view: the coarse raster's (texels ≈ 0.16 there)
        want = float(eo.flux_within_radius(I0, D, R, N_IOR, Z, [r])[0])
        assert _flux_within(half, r) == pytest.approx(want, rel=0.2)
    # the fine raster keeps the camera's density: a third of a pixel (0.02) per texel
    # at its finest, as without the coarse one
    assert np.diff(fine[0].edges_u).min() <= 0.02 / 3 * 1.05


def _source(radius=0.0):
    lens = Lens(np.zeros(3), R, N_IOR)
    light = PointLight(np.array([0.0, 0.0, -D]), 4.0 * math.pi * I0, radius=radius)
    return SheetSource(light, lens, n_source=16 if radius > 0 else 1)


@pytest.mark.parametrize("radius", [0.0, 0.3])
def test_rays_follow_the_texels_a_closer_camera_covers(radius):
    # The caustic's 99 % span on the floor, s (≈ 10 with its halo): from 40 above the
    # floor with 200 px over 80 (a pixel 0.4 there) it covers 3 · s / 0.4 ≈ 75 texels a
    # side, from 4 above (a pixel 0.04) beyond the cap of 256. One ray per texel, all
    # samples of an extended light together: about 10× more rays near (main: the same count,
    # the pixel taken at the lens and the span of 90 % of the flux, 256 per sample).
    floor = rectangle([0, 0, Z], [0, 0, 1], 200.0, 200.0, 4, 4)
    rays = {}
    for h in (40.0, 4.0):
        sb = bake(
            [_source(radius)],
            floor,
            max_rays=65_536,
            min_rays=256,
            resolution=256,
            view=_down(h),
            rays_per_texel=1.0,
        )
        rays[h] = sb.layer.n_rays
    assert rays[4.0] > 8 * rays[40.0]
    # near: ≈ 256² rays; (Nr + 1)·4Nr per sample with Nr = round(√(n / 4))
    k = 16 if radius > 0 else 1
    nr = round(math.sqrt(65_536 / k / 4))
    assert rays[4.0] == k * (nr + 1) * 4 * nr
