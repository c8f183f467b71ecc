"""The Caustic layer's fixed-topology bake (core/animation/layer_segments.py), without Blender.

A glass ball (R = 1, n = 1.5) over a floor 5 R below its centre, a point light
above it moving sideways over the frames. Generate's layer of a frame is
`pipeline.bake` of that frame alone; the bake re-lands the same rays on rasters
fixed over the frames. Checked against Generate's layer of each frame (flux in the
raster, flux-weighted centroid, the exact optics' ring irradiance
`ball_optics.irradiance_on_plane` around the frame's axis point) and, for a still
caustic, texel for texel."""

import math

import numpy as np
import pytest

from core.animation import layer_segments as lb
from core.caustic_layer.emitters import Lens, PointLight
from core.caustic_layer.pipeline import SheetSource, bake
from core.caustic_layer.rasters import RasterFrame
from core.caustic_layer.receiver_index import build_index
from core.lens import ball_optics as eo
from reference.layer_metrics import relative_l1, ring_irradiance
from reference.meshes import rectangle

R, N_IOR, D, Z = 1.0, 1.5, 9.0, 5.0
I0 = 1.0  # W/sr
RES, GRID = 64, (32, 128)
FLOOR = rectangle(np.array([0.0, 0.0, -Z]), np.array([0.0, 0.0, 1.0]), 200.0, 200.0, 4, 4)
INDEX = build_index(FLOOR)
LENS = Lens(np.zeros(3), R, N_IOR)


def light_at(x):
    return np.array([x, 0.0, D])


def frame(x, color=(1.0, 1.0, 1.0)):
    """Generate's layer with the light at `light_at(x)` as the bake's input."""
    src = [SheetSource(PointLight(light_at(x), 4.0 * math.pi * I0, color=color), LENS)]
    sheet = bake(src, INDEX, grid=GRID, resolution=RES)
    return lb.FrameLayers(src, sheet, ["lamp ∘ ball"], ["Floor"])


def axis_point(x):
    """Where the line from the light through the ball's centre meets the floor."""
    light = light_at(x)
    t = (-Z - light[2]) / (0.0 - light[2])
    return light + t * (np.zeros(3) - light)


def centroid(pl, irr):
    flux = irr.sum(axis=2) * pl.texel_areas()
    return np.einsum("ij,ijk->k", flux, pl.texel_centers()) / flux.sum()


def test_a_still_caustic_bakes_generates_layer_texel_for_texel():
    frames = [frame(0.0) for _ in range(3)]
    segs, res = lb.bake_frames(frames)
    assert res == RES and len(segs) == 1
    (seg,) = segs
    assert seg.frames == [0, 1, 2] and seg.coarsening == 1.0
    own = frames[0].sheet.layer.patches[0]
    for sl in seg.slices:
        assert np.array_equal(sl, own.irradiance.astype(np.float32))
    assert np.array_equal(seg.layer.vertices, own.vertices)
    # (the bake keeps Generate's layer there; landing the same rays again on the
    # same raster, as the bake does for a moving caustic, gives the same values)
    f0 = frames[0]
    given = RasterFrame(own.patch, tuple(own.sources), own.normal, own.axis_u, own.axis_v, own.axes)
    again = bake(
        f0.sources, f0.sheet.index, budgets=f0.sheet.budgets, resolution=RES, raster_frames=[given]
    ).layer.patches
    assert len(again) == 1
    assert np.array_equal(again[0].irradiance, own.irradiance)
    assert np.array_equal(again[0].vertices, own.vertices)


def test_a_moving_caustic_keeps_one_mesh_and_each_slice_is_that_frames_layer():
    xs = [0.0, 0.1, 0.2, 0.3]
    frames = [frame(x) for x in xs]
    segs, res = lb.bake_frames(frames)
    assert len(segs) == 1
    (seg,) = segs
    assert seg.frames == [0, 1, 2, 3] and 1.0 <= seg.coarsening <= lb.COARSEN_LIMIT
    pl = seg.layer
    assert pl.vertices.shape == ((res + 1) ** 2, 3) and pl.faces.shape == (res * res, 4)
    exact_flux = eo.lens_flux(I0, D, R, N_IOR)
    for k, x in enumerate(xs):
        own = frames[k].sheet.layer.patches[0]
        sl = seg.slices[k]
        # the union raster holds what Generate's holds (and the 0.1 % it clips)
        assert seg.flux[k] >= own.flux * (1 - 1e-9)
        assert seg.flux[k] <= (own.flux + own.flux_outside) * (1 + 1e-9)
        assert seg.flux[k] == pytest.approx(exact_flux, rel=0.01)
        got_c, own_c = centroid(pl, sl), centroid(own, own.irradiance)
        assert np.linalg.norm(got_c - own_c) <= 0.01 * R
        # the rings about the frame's axis point against the exact optics (the tilt
        # of 2° at most changes the irradiance by < 0.1 %)
        c = axis_point(x)
        dist = float(np.linalg.norm(c - light_at(x))) - D
        edges = np.linspace(0.0, eo.lens_shadow_radius(D, R, dist), 17)
        exact = eo.irradiance_on_plane(I0, D, R, N_IOR, dist, edges)
        baked = dict(pl.__dict__, irradiance=sl)
        got = ring_irradiance(type(pl)(**baked), c, edges)
        own_rings = ring_irradiance(own, c, edges)
        w = np.diff(edges**2)
        assert relative_l1(got, exact, w) <= relative_l1(own_rings, exact, w) + 0.03
        assert relative_l1(got, exact, w) <= 0.08


def test_a_caustic_travelling_far_is_cut_into_segments_each_within_the_limit():
    xs = np.linspace(0.0, 6.0, 7)
    frames = [frame(x) for x in xs]
    segs, _ = lb.plan_segments(frames)
    assert len(segs) > 1
    assert sorted(i for s in segs for i in s.frames) == list(range(len(xs)))
    for s in segs:
        assert s.coarsening <= lb.COARSEN_LIMIT
        assert s.frames == list(range(s.frames[0], s.frames[-1] + 1))  # consecutive
    # one raster over all frames would coarsen some frame's core beyond the limit
    (one,) = lb.plan_segments(frames, limit=math.inf)[0]
    assert one.coarsening > lb.COARSEN_LIMIT


def test_union_axis_ratio_is_the_texel_at_each_core_over_its_own():
    # two frames: cores at 0 and 1, own texel 0.01 at the core, extents ±0.5 about it
    facts = [(0.0, 0.05, -0.5, 0.5, 0.01), (1.0, 0.05, 0.5, 1.5, 0.01)]
    (c, s, xi0, dxi), ratio = lb.union_axis(facts, 64)
    assert c == pytest.approx(0.5)
    edges = c + s * np.sinh(xi0 + dxi * np.arange(65))
    assert edges[0] == pytest.approx(-0.5) and edges[-1] == pytest.approx(1.5)
    for core, r in zip((0.0, 1.0), ratio, strict=True):
        k = np.searchsorted(edges, core) - 1
        assert r == pytest.approx((edges[k + 1] - edges[k]) / 0.01, rel=0.02)


def test_atlas_tiles_round_trip_and_stay_within_the_image_limit():
    rng = np.random.default_rng(3)
    slices = [rng.random((8, 8)).astype(np.float32) for _ in range(11)]
    cols, rows = lb.atlas_layout(11, 8)
    assert (cols, rows) == (4, 3)
    img = lb.stack_atlas(slices, cols, rows)
    assert img.shape == (24, 32)
    for k, sl in enumerate(slices):
        assert np.array_equal(lb.read_atlas(img, k, cols, 8), sl)
        col, row = lb.tile_of(k, cols)
        assert (col, row) == (k % 4, k // 4)
    assert lb.atlas_layout(128 * 128, 128) == (128, 128)
    with pytest.raises(ValueError, match="do not fit"):
        lb.atlas_layout(128 * 128 + 1, 128)


def test_one_colour_slices_need_one_channel_and_mixed_ones_keep_rgb():
    e = np.random.default_rng(4).random((6, 6))
    warm = np.array([1.0, 0.8, 0.5])
    mono = [e[..., None] * warm * 7.0, e[..., None] * np.array([0.2, 0.4, 1.0]) * 0.5]
    images, scales, colours, one = lb.split_colour(mono)
    assert one
    for img, sc, col, want in zip(images, scales, colours, mono, strict=True):
        assert img.shape == (6, 6) and float(img.max()) == pytest.approx(1.0)
        np.testing.assert_allclose(img[..., None] * sc * np.array(col), want, rtol=1e-6)
    mixed = [mono[0] + np.stack([e.T, 0 * e, 0 * e], axis=-1)]
    images, scales, colours, one = lb.split_colour(mixed)
    assert not one and images[0].shape == (6, 6, 3) and colours == [(1.0, 1.0, 1.0)]
    np.testing.assert_allclose(images[0] * scales[0], mixed[0], rtol=1e-6)


def test_raster_coordinate_finds_each_texel_of_a_warped_raster_from_its_position():
    frames = [frame(0.0), frame(0.3)]
    segs, res = lb.plan_segments(frames)
    (seg,) = segs
    pl = lb.bake_frames(frames)[0][0].layer
    t = lb.raster_coordinate(pl.texel_centers().reshape(-1, 3), seg.axes, *seg.plane[1:], res)
    iy, ix = np.divmod(np.arange(res * res), res)
    # each texel's centre (mid-way between its lines) lies inside that texel
    assert np.array_equal(np.floor(t * res).astype(int), np.stack([ix, iy], axis=1))
    # the vertices (lifted off the plane) at the texel corners
    corners = lb.raster_coordinate(pl.vertices, seg.axes, *seg.plane[1:], res)
    g = np.arange(res + 1) / res
    np.testing.assert_allclose(corners[:, 0], np.tile(g, res + 1), atol=1e-9)
    np.testing.assert_allclose(corners[:, 1], np.repeat(g, res + 1), atol=1e-9)


def test_an_affine_uv_receiver_needs_one_quad_with_the_uvs_at_its_corners():
    pl = lb.bake_frames([frame(0.0)])[0][0].layer
    assert pl.uv_inside is None and pl.uvs is not None
    quad = lb.baked_mesh(pl)
    assert quad.vertices.shape == (4, 3) and quad.faces.tolist() == [[0, 1, 3, 2]]
    for k, v in enumerate((0, RES, (RES + 1) * RES, (RES + 1) ** 2 - 1)):
        assert np.array_equal(quad.vertices[k], pl.vertices[v])
        assert np.array_equal(quad.uvs[k], pl.uvs[v])
