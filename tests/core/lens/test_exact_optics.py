"""Tests of the exact ball-lens optics (SPEC section 6)."""

import math

import numpy as np
import pytest

from core.lens.ball_optics import (
    cone_half_angle,
    cone_one_minus_cos,
    flux_within_radius,
    irradiance_on_plane,
    landing_radius,
    lens_flux,
    lens_shadow_radius,
    monte_carlo_irradiance,
    on_axis_intensity,
    paraxial_image_distance,
    trace_rays,
    two_surface_transmission,
)
from core.lens.refraction import fresnel_transmittance

# --------------------------------------------------------------------------- Fresnel


def test_head_on_transmission_hand_value():
    # single surface 4n/(n+1)^2 = 6/6.25 = 0.96, two surfaces 0.96^2
    assert float(two_surface_transmission(0.0, 1.5)) == pytest.approx(0.9216, abs=1e-12)
    for n in (1.2, 1.5171, 2.0, 3.0):
        assert float(two_surface_transmission(0.0, n)) == pytest.approx(
            (4 * n / (n + 1) ** 2) ** 2, rel=1e-12
        )


def test_grazing_transmission_is_zero():
    assert float(two_surface_transmission(math.pi / 2, 1.5)) == pytest.approx(0.0, abs=1e-12)
    t_s, t_p = fresnel_transmittance(0.0, 1.0, 1.5)
    assert float(t_s) == 0.0 and float(t_p) == 0.0
    t_s, t_p = fresnel_transmittance(0.0, 1.5, 1.0)  # beyond the critical angle
    assert float(t_s) == 0.0 and float(t_p) == 0.0


def test_fresnel_single_surface_properties():
    n = 1.5
    # Brewster angle: p fully transmitted
    c_b = math.cos(math.atan(n))
    t_s, t_p = fresnel_transmittance(c_b, 1.0, n)
    assert float(t_p) == pytest.approx(1.0, abs=1e-12)
    assert 0.0 < float(t_s) < 1.0
    # reciprocity: air->glass at iota equals glass->air at r
    iota = np.linspace(0.0, 1.5, 50)
    r = np.arcsin(np.sin(iota) / n)
    a = fresnel_transmittance(np.cos(iota), 1.0, n)
    b = fresnel_transmittance(np.cos(r), n, 1.0)
    np.testing.assert_allclose(a[0], b[0], rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(a[1], b[1], rtol=1e-12, atol=1e-15)
    # total internal reflection and index match
    assert float(fresnel_transmittance(math.cos(0.8), n, 1.0)[0]) == 0.0
    np.testing.assert_array_equal(fresnel_transmittance(np.cos(iota), 1.3, 1.3)[0], 1.0)
    # T is (t_s^2 + t_p^2)/2
    np.testing.assert_allclose(two_surface_transmission(iota, n), 0.5 * (a[0] ** 2 + a[1] ** 2))


def test_cap_averaged_transmission_about_084():
    # distant source: flux weight 2 pi b db, uniform in u = (b/R)^2 = sin^2(iota)
    m = 400_000
    u = (np.arange(m) + 0.5) / m
    avg = float(np.mean(two_surface_transmission(np.arcsin(np.sqrt(u)), 1.5)))
    assert avg == pytest.approx(0.84, abs=0.003)
    # the same through the 1-D flux integral of a far light
    D, R = 1e4, 1.0
    avg2 = lens_flux(1.0, D, R, 1.5) / (2 * math.pi * cone_one_minus_cos(D, R))
    assert avg2 == pytest.approx(avg, rel=1e-4)


# --------------------------------------------------------------------------- rays


def test_paraxial_hand_numbers():
    D, R, n = 10.0, 1.0, 1.5
    P = 2 * 0.5 / 1.5
    assert P == pytest.approx(0.6667, abs=1e-4)
    V = P - 1 / D
    assert V == pytest.approx(0.5667, abs=1e-4)
    assert paraxial_image_distance(D, R, n) == pytest.approx(1.7647, abs=1e-4)
    assert paraxial_image_distance(D, R, n) == pytest.approx(1 / V, rel=1e-12)
    # the paraxial rays cross there
    fan = trace_rays(np.array([0.0, 1e-7, 1e-5]), D, R, n)
    np.testing.assert_allclose(fan.crossing, 1 / V, rtol=1e-6)
    assert fan.crossing[0] == pytest.approx(1 / V, rel=1e-15)  # psi = 0: the limit
    # collimated: source at the front focal point nR/(2(n-1)) = 1.5
    assert paraxial_image_distance(1.5, R, n) == math.inf


def test_hand_computed_ray():
    D, R, n, psi = 10.0, 1.0, 1.5, 0.05
    iota = math.asin(D / R * math.sin(psi))
    r = math.asin(math.sin(iota) / n)
    theta = 2 * (iota - r) - psi
    fan = trace_rays(np.array([psi]), D, R, n, absorption=0.2)
    assert fan.iota[0] == pytest.approx(iota, rel=1e-13)
    assert fan.r[0] == pytest.approx(r, rel=1e-13)
    assert fan.b[0] == pytest.approx(R * math.sin(iota), rel=1e-13)
    assert fan.b[0] == pytest.approx(D * math.sin(psi), rel=1e-13)
    assert fan.theta_exit[0] == pytest.approx(theta, rel=1e-12)
    assert fan.crossing[0] == pytest.approx(R * math.sin(iota) / math.sin(theta), rel=1e-12)
    assert fan.entry_polar[0] == pytest.approx(iota - psi, rel=1e-12)
    assert fan.exit_polar[0] == pytest.approx(math.pi + iota - psi - 2 * r, rel=1e-12)
    assert fan.chord[0] == pytest.approx(2 * R * math.cos(r), rel=1e-13)
    assert fan.transmission[0] == pytest.approx(
        float(two_surface_transmission(iota, n)) * math.exp(-0.2 * 2 * R * math.cos(r)), rel=1e-12
    )
    # by hand: sin(iota) = 10 sin(0.05) = 0.499792, iota = 29.986 deg; sin(r) = 0.333195,
    # r = 19.463 deg; theta = 2 (10.523 deg) - 2.865 deg = 18.182 deg;
    # crossing = 0.499792 / sin(18.182 deg) = 1.6017 (paraxial: 1.7647)
    assert math.degrees(fan.iota[0]) == pytest.approx(29.986, abs=1e-3)
    assert math.degrees(fan.r[0]) == pytest.approx(19.463, abs=1e-3)
    assert math.degrees(fan.theta_exit[0]) == pytest.approx(18.182, abs=1e-3)
    assert fan.crossing[0] == pytest.approx(1.6017, abs=1e-4)


def test_exit_point_lies_on_exit_ray_and_sphere_geometry():
    D, R, n = 4.0, 1.0, 1.5
    psi = np.linspace(0.01, 0.99, 40) * cone_half_angle(D, R)
    fan = trace_rays(psi, D, R, n)
    # entry point on the source's ray: (R sin e, -R cos e) seen at angle psi from (0, -D)
    y1, z1 = R * np.sin(fan.entry_polar), -R * np.cos(fan.entry_polar)
    np.testing.assert_allclose(np.arctan2(y1, z1 + D), psi, rtol=1e-12)
    # chord length from the two polar angles
    y2, z2 = R * np.sin(fan.exit_polar), -R * np.cos(fan.exit_polar)
    np.testing.assert_allclose(np.hypot(y2 - y1, z2 - z1), fan.chord, rtol=1e-12)
    # the exit ray passes through the exit point: landing height on z = z_exit is y_exit
    for k in (0, 17, 39):
        h = landing_radius(psi[k : k + 1], D, R, n, z2[k])
        assert h[0] == pytest.approx(y2[k], abs=1e-12)


def test_spherical_aberration_marginal_rays_cross_near_the_back():
    D, R, n = 10.0, 1.0, 1.5
    alpha = cone_half_angle(D, R)
    psi = np.linspace(1e-4, 0.99, 200) * alpha
    c = trace_rays(psi, D, R, n).crossing
    assert np.all(np.diff(c) < 0)  # positive spherical aberration
    assert np.all(c < paraxial_image_distance(D, R, n))
    assert c[-1] < 1.05 * R  # marginal: at the back of the sphere
    assert paraxial_image_distance(D, R, n) - c[-1] > 0.7 * R


def test_landing_sign_and_misses():
    D, R, n = 10.0, 1.0, 1.5
    alpha = cone_half_angle(D, R)
    psi = np.linspace(0.05, 0.9, 20) * alpha
    assert np.all(landing_radius(psi, D, R, n, 5.0) < 0)  # all crossed before z = 5
    h = landing_radius(psi, D, R, n, 1.2)
    assert h[0] > 0 and h[-1] < 0  # paraxial not yet, marginal already
    fan = trace_rays(np.array([1.01 * alpha]), D, R, n)  # misses the sphere
    assert np.isnan(fan.iota[0]) and fan.transmission[0] == 0.0
    with pytest.raises(ValueError):
        trace_rays([0.0], 0.5, 1.0, 1.5)  # source inside the sphere


def test_no_lens_n_equal_one():
    D, R, Z = 3.0, 1.0, 3.0
    alpha = cone_half_angle(D, R)
    fan = trace_rays(np.array([0.1, 0.2, alpha]), D, R, 1.0)
    np.testing.assert_allclose(fan.crossing, -D)  # straight lines through the source
    np.testing.assert_allclose(fan.transmission, [1, 1, 1])
    h = landing_radius(np.array([alpha]), D, R, 1.0, Z)
    assert h[0] == pytest.approx(lens_shadow_radius(D, R, Z), rel=1e-12)


# --------------------------------------------------------------------------- radiometry


def test_on_axis_intensity_hand_value():
    # m = 1.7647/10, T(0) = 0.9216
    assert on_axis_intensity(1.0, 10.0, 1.0, 1.5) == pytest.approx(
        0.9216 * (1 / 0.56667 / 10) ** 2, rel=1e-4
    )
    assert on_axis_intensity(2.0, 10.0, 1.0, 1.5, absorption=0.1) == pytest.approx(
        2 * 0.9216 * (1 / (2 / 3 - 0.1) / 10) ** 2 * math.exp(-0.2), rel=1e-12
    )


def test_central_irradiance_beyond_paraxial_image_matches_on_axis_intensity():
    D, R, n = 10.0, 1.0, 1.5
    for Z in (3.0, 6.0):
        E = irradiance_on_plane(1.0, D, R, n, Z, [0.0, 1e-3], n_psi=20_000)[0]
        ref = on_axis_intensity(1.0, D, R, n) / (Z - paraxial_image_distance(D, R, n)) ** 2
        assert E == pytest.approx(ref, rel=1e-4)


def test_energy_conservation_on_huge_plane():
    I0, D, R, n, Z = 2.0, 3.0, 1.0, 1.5, 5.0
    # independent reference: I0 * 2 pi * integral of T over cos(psi) (midpoint rule)
    omc = cone_one_minus_cos(D, R)
    m = 400_000
    v = (np.arange(m) + 0.5) / m * omc  # 1 - cos(psi)
    sin_psi = np.sqrt(v * (2 - v))
    iota = np.arcsin(np.minimum(D / R * sin_psi, 1.0))
    ref = I0 * 2 * math.pi * omc * float(np.mean(two_surface_transmission(iota, n)))
    edges = np.linspace(0.0, 100.0, 51)
    E = irradiance_on_plane(I0, D, R, n, Z, edges, n_psi=50_000)
    total = float(np.sum(E * math.pi * np.diff(edges**2)))
    assert total == pytest.approx(ref, rel=1e-5)
    assert lens_flux(I0, D, R, n) == pytest.approx(ref, rel=1e-5)
    # without a lens the cone carries I0 * 4 pi * (fraction of SPEC 4.2)
    fraction = (R / D) ** 2 / (2 * (1 + math.sqrt((1 - R / D) * (1 + R / D))))
    assert flux_within_radius(I0, D, R, 1.0, Z, [np.inf], n_psi=20_000)[0] == pytest.approx(
        I0 * 4 * math.pi * fraction, rel=1e-7
    )


def _compare_with_monte_carlo(D, R, n, Z, edges, absorption, n_rays, seed):
    E = irradiance_on_plane(1.0, D, R, n, Z, edges, absorption=absorption, n_psi=50_000)
    mc = monte_carlo_irradiance(
        1.0, D, R, n, Z, edges, n_rays, np.random.default_rng(seed), absorption=absorption
    )
    bright = E > 0.1 * E.max()
    assert bright.sum() >= 5
    np.testing.assert_allclose(mc[bright], E[bright], rtol=0.03)
    area = math.pi * np.diff(edges**2)
    assert float(np.sum(mc * area)) == pytest.approx(float(np.sum(E * area)), rel=0.01)


def test_closed_form_matches_monte_carlo_beyond_focus():
    _compare_with_monte_carlo(5.0, 1.0, 1.5, 4.0, np.linspace(0.0, 3.0, 16), 0.0, 600_000, 12345)


def test_closed_form_matches_monte_carlo_at_caustic_with_absorption():
    # plane through the ring caustic (h = 0.0475 R) and the axial caustic
    _compare_with_monte_carlo(10.0, 1.0, 1.5, 1.47, np.linspace(0.0, 0.1, 11), 0.3, 600_000, 2024)
