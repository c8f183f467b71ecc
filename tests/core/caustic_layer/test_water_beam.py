"""The water beam landed under water (`core.caustic_layer.water_beam` + the layer's
rasters) against irradiance worked out by hand on flat water (sun and point light,
Fresnel, Beer per channel, the 1/n² Cycles renders) and against the Monte-Carlo
height-field reference (`reference/water_tracer.py`) for a sine-wave surface."""

import math

import numpy as np
import pytest
from glass_meshes import unpolarised_t

from core.caustic_layer.emitters import PointLight, SunLight
from core.caustic_layer.rasters import build_layer
from core.caustic_layer.receiver_bvh import ReceiverMesh
from core.caustic_layer.receiver_index import build_index
from core.caustic_layer.water_beam import WaterSource, grid_shape, trace_water_beams
from core.caustic_layer.water_sources import WATER_SUBCELLS_PER_TEXEL as SUB
from core.lens.water import WaterSurface
from reference.layer_metrics import radial_flux, relative_l1
from reference.water_tracer import SineWaves, height_field_mesh, layer_on_bins, trace_floor

N = 1.333


def _t(theta):
    """Unpolarised Fresnel transmittance air → water from the amplitude coefficients."""
    return unpolarised_t(theta, 1.0, N)


def _floor(z, half=4.0):
    v = np.array([[-half, -half, z], [half, -half, z], [half, half, z], [-half, half, z]])
    return build_index(ReceiverMesh(v, np.array([[0, 1, 2], [0, 2, 3]])))


def _flat_water(half=0.5, n=8, absorption=0.0):
    xs = np.linspace(-half, half, n + 1)
    gx, gy = np.meshgrid(xs, xs)
    v = np.stack([gx, gy, np.zeros_like(gx)], -1).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    a = (i * (n + 1) + j).reshape(-1)
    t = np.concatenate([np.stack([a, a + 1, a + n + 2], 1), np.stack([a, a + n + 2, a + n + 1], 1)])
    return WaterSurface(v, t, ior=N, absorption=absorption)


def _mean_in_box(patch, box, channel=0):
    """Mean irradiance of the layer's texels whose centres lie in ``box``."""
    c = patch.texel_centers()
    x0, x1, y0, y1 = box
    inside = (c[..., 0] > x0) & (c[..., 0] < x1) & (c[..., 1] > y0) & (c[..., 1] < y1)
    return float(patch.irradiance[..., channel][inside].mean())


def test_flat_water_under_the_sun_is_fresnel_beer_over_n_squared():
    """A sun 60° high over flat water with a tinted absorption, floor 0.8 m down: the
    floor under the middle gets S·cos θ·T(θ)·exp(−α_c·D/cos θ_t)/n² per channel."""
    alpha = (0.5, 0.1, 0.02)
    zen = math.radians(30.0)
    sun = SunLight(np.array([math.sin(zen), 0.0, -math.cos(zen)]), 2.0)
    water = _flat_water(absorption=alpha)
    idx = _floor(-0.8)
    beams = trace_water_beams(WaterSource(sun, water), idx, (64, 64))
    assert len(beams) == 3  # a coloured absorption: one beam per channel
    layer = build_layer(beams, idx, resolution=64, warp=False, subcells_per_texel=SUB)
    (patch,) = layer.patches
    ct = math.sqrt(1.0 - (math.sin(zen) / N) ** 2)
    shift = 0.8 * math.sin(zen) / N / ct  # where the middle of the water lands
    box = (shift - 0.2, shift + 0.2, -0.2, 0.2)
    for c in range(3):
        expect = 2.0 * math.cos(zen) * _t(zen) * math.exp(-alpha[c] * 0.8 / ct) / N**2
        assert _mean_in_box(patch, box, c) == pytest.approx(expect, rel=2e-3)
    # all of the light into the water reaches the floor (channel 0's Beer aside)
    into = 2.0 * math.cos(zen) * _t(zen) * 1.0 / N**2
    assert layer.flux_lost == pytest.approx(0.0, abs=1e-12)
    assert beams[1].total_flux == pytest.approx(into * math.exp(-alpha[1] * 0.8 / ct), rel=1e-3)


def _landing_radius(theta, h, depth):
    """Where the ray leaving the lamp at θ from the vertical meets the floor."""
    return h * math.tan(theta) + depth * math.tan(math.asin(math.sin(theta) / N))


def test_point_light_over_flat_water_flux_within_radii():
    """An isotropic point light h above flat water, floor D below: the flux landing
    within ρ of the nadir is I·∫ T(θ) 2π sin θ dθ up to the θ that lands at ρ (by
    bisection and a fine midpoint sum here), over n²."""
    h, depth, power = 1.2, 0.6, 100.0
    lamp = PointLight(np.array([0.0, 0.0, h]), power)
    water = _flat_water(half=1.0)
    idx = _floor(-depth)
    (beam,) = trace_water_beams(WaterSource(lamp, water), idx, (96, 96))
    layer = build_layer([beam], idx, resolution=256, warp=False, subcells_per_texel=SUB)
    (patch,) = layer.patches
    intensity = power / (4.0 * math.pi)
    radii = [0.1, 0.3, 0.6, 1.0]
    got = radial_flux(patch, [0.0, 0.0, -depth], radii)
    for rho, g in zip(radii, got, strict=True):
        lo, hi = 0.0, 0.5 * math.pi
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if _landing_radius(mid, h, depth) < rho else (lo, mid)
        th = (np.arange(20_000) + 0.5) / 20_000 * lo
        flux = sum(_t(a) * math.sin(a) for a in th) * 2.0 * math.pi * lo / 20_000
        assert g == pytest.approx(intensity * flux / N**2, rel=0.01)


def test_grid_shape_follows_the_surface():
    water = _flat_water()
    assert grid_shape(water, 10_000) == (100, 100)


WAVES = SineWaves(
    0.0,
    (0.006, 0.004),
    ((2 * math.pi / 0.3, 0.0), (2 * math.pi / 0.21 * 0.6, 2 * math.pi / 0.21 * 0.8)),
    (0.3, 1.1),
    (-0.5, 0.5, -0.5, 0.5),
)


def test_sine_waves_under_the_sun_match_the_reference():
    """The caustic net of two sine waves, sun 60° high, floor 0.7 m down: L1 and flux
    against the Monte-Carlo reference on 1.5 cm bins of the lit floor."""
    zen = math.radians(30.0)
    d = np.array([math.sin(zen), 0.0, -math.cos(zen)])
    ex, ey = np.linspace(-0.02, 0.58, 41), np.linspace(-0.3, 0.3, 41)
    ref = trace_floor(WAVES, -0.7, ex, ey, ior=N, sun_direction=d, n_rays=600_000, seed=3)
    v, t, cn = height_field_mesh(WAVES, 160, 160)
    water = WaterSurface(v, t, cn, ior=N)
    idx = _floor(-0.7)
    (beam,) = trace_water_beams(WaterSource(SunLight(d, 1.0), water), idx, (240, 240))
    layer = build_layer([beam], idx, resolution=200, warp=False, subcells_per_texel=SUB)
    (patch,) = layer.patches
    e = layer_on_bins(patch, ex, ey)
    area = np.diff(ey)[:, None] * np.diff(ex)[None, :]
    l1 = relative_l1(e, ref.irradiance, area)
    assert l1 < 0.1
    assert (e * area).sum() / (ref.irradiance * area).sum() == pytest.approx(1.0, abs=0.02)
    assert beam.total_flux == pytest.approx(ref.flux, rel=0.01)
    # a net, not a flat sheet: the reference's contrast is there in the layer
    assert e.max() / e.mean() > 1.5 and ref.irradiance.max() / ref.irradiance.mean() > 1.5


def test_a_round_pond_keeps_the_light_at_its_rim():
    """A flat round pond (a 64-gon, radius 0.5) under a sun 30° off the zenith: every
    ray that meets it lands, S·cos θ·A·T(θ)/n² with A the polygon's area, though its
    rim cuts the ray grid's cells (their sub-rays carry it: without them about 3 % of
    a 40 × 40 grid's flux is lost or misplaced along the rim)."""
    n_seg, r = 64, 0.5
    ang = 2 * np.pi * np.arange(n_seg) / n_seg
    v = np.concatenate(
        [[[0.0, 0.0, 0.0]], np.stack([r * np.cos(ang), r * np.sin(ang), 0 * ang], 1)]
    )
    t = np.array([[0, 1 + i, 1 + (i + 1) % n_seg] for i in range(n_seg)])
    pond = WaterSurface(v, t, ior=N)
    zen = math.radians(30.0)
    sun = SunLight(np.array([math.sin(zen), 0.0, -math.cos(zen)]), 1.0)
    idx = _floor(-0.5)
    area = 0.5 * n_seg * r * r * math.sin(2 * math.pi / n_seg)
    expect = math.cos(zen) * area * _t(zen) / N**2
    (beam,) = trace_water_beams(WaterSource(sun, pond), idx, (40, 40))
    assert beam.parts and beam.total_flux == pytest.approx(expect, rel=2e-3)
    layer = build_layer([beam], idx, resolution=64, subcells_per_texel=SUB)
    assert layer.flux_in_rasters + layer.flux_outside == pytest.approx(expect, rel=2e-3)
    (bare,) = trace_water_beams(WaterSource(sun, pond), idx, (40, 40), rim=0)
    assert abs(bare.total_flux / expect - 1.0) > 0.01  # what the rim's sub-rays mend
