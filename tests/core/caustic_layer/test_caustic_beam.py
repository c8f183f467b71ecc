"""The caustic layer's beam tracing: flux per ray grid and exact exit rays, every emitter.

Expected values come from core.lens.ball_optics (the meridional closed forms of SPEC §6)
and from one-dimensional quadratures written here, not from the grid code."""

import math

import numpy as np
import pytest

from core.caustic_layer.beam_trace import trace_beam
from core.caustic_layer.emitters import AreaLight, Lens, PointLight, SpotLight, SunLight
from core.lens import ball_optics as eo
from core.scene.blender_spot import spot_mask

R, N_IOR = 1.0, 1.5


def _rotation(seed):
    q, _ = np.linalg.qr(np.random.default_rng(seed).normal(size=(3, 3)))
    return q * np.sign(np.linalg.det(q))


def _iota_quadrature(f, n=200_001):
    iota = np.linspace(0.0, 0.5 * np.pi, n)
    return np.trapezoid(f(iota), iota)


@pytest.mark.parametrize("absorption", [0.0, 0.3])
@pytest.mark.parametrize("D", [1.5, 10.0, 1e4])
def test_point_beam_carries_the_lens_flux(D, absorption):
    lens = Lens(np.zeros(3), R, N_IOR, absorption)
    beam = trace_beam(PointLight(np.array([0.0, 0.0, -D]), 4.0 * math.pi), lens, 32, 128)
    assert beam.total_flux == pytest.approx(eo.lens_flux(1.0, D, R, N_IOR, absorption), rel=1e-5)


def test_exit_rays_are_the_exact_trace_anywhere_in_any_orientation():
    D, nr = 4.0, 16
    rot = _rotation(3)
    center = np.array([2.0, -7.0, 0.5])
    light = center + rot @ np.array([0.0, 0.0, -D])
    beam = trace_beam(PointLight(light, 1.0), Lens(center, R, N_IOR), nr, 32)
    fan = eo.trace_rays_iota(0.5 * np.pi * np.arange(nr + 1) / nr, D, R, N_IOR)
    axis = rot @ np.array([0.0, 0.0, 1.0])
    d = beam.exit_dirs[0]  # (Nr+1, Na, 3)
    p = beam.exit_points[0] - center
    # angle of the exit ray to the axis, and the exit point's polar angle from the back
    ang = np.arctan2(np.linalg.norm(np.cross(d, axis), axis=-1), d @ axis)
    np.testing.assert_allclose(
        ang, np.broadcast_to(np.abs(fan.theta_exit)[:, None], ang.shape), atol=1e-9
    )
    polar = np.arctan2(np.linalg.norm(np.cross(p, axis), axis=-1), p @ axis)
    want = np.broadcast_to(np.abs(fan.exit_polar - np.pi)[:, None], polar.shape)
    np.testing.assert_allclose(polar[:-1], want[:-1], atol=1e-9)
    # the grazing ring (ι = π/2, zero flux) through a discriminant of 0: sqrt-sensitive
    np.testing.assert_allclose(polar[-1], want[-1], atol=1e-6)
    np.testing.assert_allclose(np.linalg.norm(p, axis=-1), R, rtol=1e-12)


def test_sun_flux_is_strength_times_disc_times_mean_transmission():
    S = 1000.0
    expected = (
        S
        * 2.0
        * np.pi
        * R
        * R
        * _iota_quadrature(lambda i: eo.two_surface_transmission(i, N_IOR) * np.sin(i) * np.cos(i))
    )
    for angle, k in ((0.0, 1), (math.radians(0.53), 16)):
        beam = trace_beam(
            SunLight(np.array([0.3, -0.2, -1.0]), S, angle),
            Lens(np.array([1.0, 2.0, 3.0]), R, N_IOR),
            32,
            128,
            k,
        )
        assert beam.total_flux == pytest.approx(expected, rel=1e-5)
        assert beam.shape == (k, 32, 128)


def test_spot_mask_cuts_the_flux_like_the_exact_integral():
    D, P = 8.0, 100.0
    half, blend = math.radians(4.0), 0.4  # the cone edge crosses the lens
    beam = trace_beam(
        SpotLight(np.array([0.0, 0.0, -D]), np.array([0.0, 0.0, 1.0]), P, 2.0 * half, blend),
        Lens(np.zeros(3), R, N_IOR),
        48,
        192,
    )

    def integrand(iota):
        fan = eo.trace_rays_iota(iota, D, R, N_IOR)
        domega = 2 * np.pi * (R / D) ** 2 * np.sin(iota) * np.cos(iota) / np.cos(fan.psi)
        return spot_mask(np.cos(fan.psi), half, blend) * fan.transmission * domega

    expected = P / (4 * math.pi) * _iota_quadrature(integrand)
    assert beam.total_flux == pytest.approx(expected, rel=2e-3)
    assert beam.total_flux < eo.lens_flux(P / (4 * math.pi), D, R, N_IOR)


def test_small_area_light_is_a_lambertian_point():
    D, P = 30.0, 50.0
    lens = Lens(np.zeros(3), R, N_IOR)
    area = AreaLight(
        np.array([0.0, 0.0, -D]), np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0]), P, 0.2, 0.1
    )
    beam = trace_beam(area, lens, 32, 128, n_source=9)
    # intensity (P/π) cos θ; over the lens' tiny cone cos θ ≈ 1 - θ²/2
    assert beam.total_flux == pytest.approx(eo.lens_flux(P / math.pi, D, R, N_IOR), rel=2e-3)
    tilted = AreaLight(
        area.position, np.array([math.sin(0.5), 0.0, math.cos(0.5)]), area.axis_x, P, 0.2, 0.1
    )
    assert trace_beam(tilted, lens, 32, 128, 9).total_flux == pytest.approx(
        math.cos(0.5) * beam.total_flux, rel=2e-3
    )


def test_sphere_light_keeps_flux_and_topology_and_samples_its_disc():
    D = 6.0
    lens = Lens(np.zeros(3), R, N_IOR)
    point = trace_beam(PointLight(np.array([0.0, 0.0, -D]), 10.0), lens, 24, 96)
    sphere = trace_beam(
        PointLight(np.array([0.0, 0.0, -D]), 10.0, radius=0.3), lens, 24, 96, n_source=16
    )
    assert sphere.shape == (16, 24, 96)  # a 4 × 4 grid of equal shares of the disc
    # each disc sample sees the lens from a slightly different distance
    assert sphere.total_flux == pytest.approx(point.total_flux, rel=5e-3)
    spread = np.ptp(sphere.exit_dirs[:, 0, 0], axis=0)  # axial rays differ per sample
    assert spread.max() > 1e-3


def test_topology_is_fixed_and_a_light_inside_gives_an_empty_beam():
    lens = Lens(np.zeros(3), R, N_IOR)
    shapes = set()
    for pos in ([0.0, 0.0, -5.0], [3.0, 1.0, 2.0], [0.0, 0.2, 0.1]):
        b = trace_beam(PointLight(np.array(pos), 1.0), lens, 12, 40)
        shapes.add((b.exit_points.shape, b.cell_flux.shape))
        if np.linalg.norm(pos) < R:
            assert not b.valid.any() and b.total_flux == 0.0
    assert len(shapes) == 1


def test_many_lenses_in_one_batch_each_carry_their_exact_flux():
    from core.caustic_layer.beam_trace import trace_beams

    lenses = [
        Lens(np.array([0.0, 0.0, 0.0]), 1.0, 1.5),
        Lens(np.array([5.0, 1.0, -2.0]), 0.5, 1.7, absorption=0.2),
        Lens(np.array([-3.0, 4.0, 1.0]), 2.0, 1.4),
    ]
    D = (10.0, 3.0, 7.0)
    pairs = [
        (PointLight(lens.center + np.array([0.0, 0.0, d]), 4.0 * math.pi), lens)
        for lens, d in zip(lenses, D, strict=True)
    ]
    S = 100.0
    pairs.append((SunLight(np.array([0.0, 1.0, -1.0]), S), lenses[0]))
    beams = trace_beams(pairs, 24, 96)
    for (_, lens), d, beam in zip(pairs, D, beams, strict=False):
        expected = eo.lens_flux(1.0, d, lens.radius, lens.ior, lens.absorption)
        assert beam.total_flux == pytest.approx(expected, rel=1e-5)
    sun = (
        S
        * 2
        * np.pi
        * _iota_quadrature(lambda i: eo.two_surface_transmission(i, 1.5) * np.sin(i) * np.cos(i))
    )
    assert beams[-1].total_flux == pytest.approx(sun, rel=1e-5)
    # each beam leaves its own sphere
    for (_, lens), beam in zip(pairs, beams, strict=True):
        r = np.linalg.norm(beam.exit_points - lens.center, axis=-1)
        np.testing.assert_allclose(r, lens.radius, rtol=1e-9)
