"""The reference tracer's emitters and blockers (reference) against hand
values: conservation of flux, 1-D and 2-D deterministic quadratures over the lens's
cone built on core/lens/ball_optics (tests/helpers/reference_quadrature.py), and the geometry
of a sun's caustic."""

from __future__ import annotations

import math

import numpy as np
import pytest
from reference_quadrature import angle_to, cone_grid, disc_mean_transmission

from core.lens import ball_optics as xo
from core.scene import blender_spot
from reference import (
    AreaLight,
    Blocker,
    GlassSphere,
    PointLight,
    ReceiverPlane,
    SpotLight,
    SunLight,
    spot_mask,
    trace_irradiance,
)

R, N = 1.0, 1.5
LENS = GlassSphere((0.0, 0.0, 0.0), R, N)
BEHIND = ReceiverPlane((0.0, 0.0, 4.0), (0.0, 0.0, -1.0))
I0 = 1.0
POWER = 4.0 * math.pi * I0


def _close(res, expected, k=4.0, rel=0.0):
    return abs(res.flux_on_plane - expected) < k * res.flux_on_plane_se + rel * expected


# --------------------------------------------------------------------------- sun


def test_sun_flux_is_strength_times_the_disc_times_the_mean_transmission():
    S = 2.0
    res = trace_irradiance(SunLight((0.0, 0.0, 1.0), S), LENS, BEHIND, 200_000, seed=1)
    assert res.flux_into_lens == pytest.approx(S * math.pi * R * R, rel=1e-12)
    assert _close(res, S * math.pi * R * R * disc_mean_transmission(N))


def test_sun_rings_match_a_very_far_point_light():
    """A sun is the limit D -> inf of a point light (SPEC 10): the exact 1-D integral
    for D = 1e6 R with intensity S D^2 (the same irradiance on the lens)."""
    S, D, Z = 1.0, 1e6, 2.0
    edges = np.linspace(0.0, 1.0, 11)
    res = trace_irradiance(
        SunLight((0.0, 0.0, 1.0), S),
        LENS,
        ReceiverPlane((0.0, 0.0, Z), (0.0, 0.0, -1.0)),
        300_000,
        seed=2,
        rings=((0.0, 0.0), edges),
    )
    exact = xo.irradiance_on_plane(S * D * D, D, R, N, Z, edges)
    z = (res.ring_irradiance - exact) / res.ring_se
    assert np.all(np.abs(z) < 4.5), z


@pytest.mark.parametrize("beta_deg", [0.0, 10.0])
def test_sun_caustic_peak_sits_on_the_line_through_the_centre(beta_deg):
    """The chief ray through the centre is not deviated, and by symmetry the axial
    caustic of a tilted sun lies on the line through the centre along its
    direction: on the plane z = Z the peak cell holds the point at Z tan(beta)."""
    b = math.radians(beta_deg)
    Z = 1.4  # between the marginal and the paraxial focus (1.5 R)
    e = np.linspace(-0.6, 0.6, 61)
    res = trace_irradiance(
        SunLight((math.sin(b), 0.0, math.cos(b)), 1.0),
        LENS,
        ReceiverPlane((0.0, 0.0, Z), (0.0, 0.0, -1.0)),
        200_000,
        seed=3,
        grid=(e, e),
    )
    i, j = np.unravel_index(np.argmax(res.irradiance), res.irradiance.shape)
    x = Z * math.tan(b)
    assert e[i] - 1e-9 <= x <= e[i + 1] + 1e-9 or abs(x - e[i]) < 1e-9
    assert abs(0.5 * (e[j] + e[j + 1])) <= 0.02


def _lens_area(d, a, b):
    """Area of the intersection of discs of radii ``a`` and ``b`` at distance ``d``."""
    d = np.asarray(d, float)
    out = np.where(d <= abs(a - b), math.pi * min(a, b) ** 2, 0.0)
    part = (d > abs(a - b)) & (d < a + b)
    dd = np.where(part, d, 0.5 * (a + b))
    ca = np.clip((dd * dd + a * a - b * b) / (2 * dd * a), -1, 1)
    cb = np.clip((dd * dd + b * b - a * a) / (2 * dd * b), -1, 1)
    k = np.sqrt(np.maximum((-dd + a + b) * (dd + a - b) * (dd - a + b) * (dd + a + b), 0.0))
    return np.where(part, a * a * np.arccos(ca) + b * b * np.arccos(cb) - 0.5 * k, out)


def test_sun_blur_grows_with_its_angular_diameter():
    """Each direction of a sun of angular diameter a makes the point-sun caustic
    displaced by Z tan(angle) (the line through the centre): near the axis the
    pattern is the sharp one convolved with a uniform disc of radius s = Z tan(a/2)
    (the blur ~ f a of SPEC 10 at the focal plane).  Expected flux within rho0 of
    the axis: the exact sharp profile's ring fluxes times the chance that a uniform
    shift within s brings each ring point inside rho0."""
    Z, a = 1.5, math.radians(3.0)  # the paraxial focal plane of n = 1.5
    s = Z * math.tan(0.5 * a)
    rho0 = np.array([0.0, 0.5, 1.0, 2.0]) * s
    D = 1e6
    fine = np.linspace(0.0, rho0[-1] + s, 401)
    ring = np.diff(xo.flux_within_radius(D * D, D, R, N, Z, fine, n_psi=50_000))
    mid = 0.5 * (fine[1:] + fine[:-1])
    within = np.array([np.sum(ring * _lens_area(mid, r0, s)) for r0 in rho0[1:]])
    expected = np.diff(np.concatenate([[0.0], within / (math.pi * s * s)]))
    sharp = np.diff(xo.flux_within_radius(D * D, D, R, N, Z, rho0, n_psi=50_000))
    plane = ReceiverPlane((0.0, 0.0, Z), (0.0, 0.0, -1.0))
    res = trace_irradiance(
        SunLight((0.0, 0.0, 1.0), 1.0, a), LENS, plane, 300_000, seed=4, rings=((0.0, 0.0), rho0)
    )
    got, se = res.ring_flux(), res.ring_se * math.pi * np.diff(rho0**2)
    assert np.all(np.abs(got - expected) < 4.0 * se + 0.02 * expected), (got, expected, sharp)
    assert sharp[0] - got[0] > 8.0 * se[0]  # the blur is there, and measurable


# --------------------------------------------------------------------------- spot


def test_spot_mask_is_the_projects_model():
    c = np.linspace(0.5, 1.0, 1001)
    for size, blend in (
        (math.radians(40.0), 0.3),
        (math.radians(120.0), 1.0),
        (math.radians(10.0), 0.0),
    ):
        assert np.allclose(
            spot_mask(c, size, blend), blender_spot.spot_mask(c, 0.5 * size, blend), atol=1e-12
        )


def test_spot_covering_half_the_lens_passes_about_half():
    """A hard-edged spot whose cone edge goes through the lens's centre: expected flux
    from the cone quadrature of T(iota) x mask."""
    D, H = 4.0, math.radians(20.0)
    axis = np.array([math.sin(H), 0.0, math.cos(H)])  # the lens centre on the edge
    spot = SpotLight((0.0, 0.0, -D), tuple(axis), POWER, 2.0 * H, 0.0)
    res = trace_irradiance(spot, LENS, BEHIND, 200_000, seed=5)
    dirs, w = cone_grid(D, R, N)
    expected = I0 * np.sum(w * (angle_to(dirs, axis) < H))
    full = I0 * np.sum(w)
    assert 0.4 < expected / full < 0.6
    assert _close(res, expected)


def test_spot_blend_toward_the_lens():
    """Spot aimed at the lens, cone just the lens's, blend 1: the smoothstep in the
    cosine weights the rings of the cone (a 1-D integral)."""
    D = 3.0
    alpha = xo.cone_half_angle(D, R)
    spot = SpotLight((0.0, 0.0, -D), (0.0, 0.0, 1.0), POWER, 2.0 * alpha, 1.0)
    res = trace_irradiance(spot, LENS, BEHIND, 200_000, seed=6)
    dirs, w = cone_grid(D, R, N, n_phi=1)
    expected = I0 * np.sum(w * blender_spot.spot_mask(dirs[:, 2], alpha, 1.0))
    assert expected < 0.6 * I0 * np.sum(w)
    assert _close(res, expected)


# --------------------------------------------------------------------------- area


@pytest.mark.parametrize(
    "shape,size_y", [("SQUARE", None), ("RECTANGLE", 0.05), ("DISK", None), ("ELLIPSE", 0.2)]
)
def test_small_far_area_light_sends_p_over_pi_cos_times_the_cone(shape, size_y):
    """A small Lambertian emitter far away, tilted by 40 degrees from the lens: it
    sends ``(P/pi) cos(theta) * pi sin^2(alpha)`` (the cosine-weighted solid angle of
    the lens's cone) into the lens; the lens passes the point light's mean
    transmission of that (its cone is the same)."""
    D, P, th = 20.0, 10.0, math.radians(40.0)
    light = AreaLight((0.0, 0.0, -D), (math.sin(th), 0.0, math.cos(th)), P, 0.1, size_y, shape)
    res = trace_irradiance(light, LENS, BEHIND, 60_000, seed=7)
    sin_a = R / D
    into = P * math.cos(th) * sin_a * sin_a
    assert res.flux_into_lens == pytest.approx(into, rel=2e-3)
    mean_t = xo.lens_flux(1.0, D, R, N) / (2 * math.pi * xo.cone_one_minus_cos(D, R))
    assert _close(res, into * mean_t, rel=2e-3)


def test_area_light_facing_away_sends_nothing():
    light = AreaLight((0.0, 0.0, -5.0), (0.0, 0.0, -1.0), 10.0, 0.5)
    res = trace_irradiance(light, LENS, BEHIND, 5_000, seed=1)
    assert res.flux_into_lens == 0.0


# --------------------------------------------------------------------------- blockers

D_B = 4.0  # the light at (0, 0, -4); blockers 1.5 from it


def _blocker_at(angle, azimuth, dist=1.5, radius=None):
    """A sphere seen from the light under the angular radius ``angle`` whose edge goes
    through the lens's centre direction (centre ``angle`` off the axis)."""
    radius = dist * math.sin(angle) if radius is None else radius
    d = np.array(
        [math.sin(angle) * math.cos(azimuth), math.sin(angle) * math.sin(azimuth), math.cos(angle)]
    )
    return Blocker(tuple(np.array([0.0, 0.0, -D_B]) + dist * d), radius), d


def test_opaque_blocker_covering_half_the_lens_halves_the_flux():
    beta = math.radians(11.0)
    blocker, axis = _blocker_at(beta, 0.0)
    res = trace_irradiance(
        PointLight((0.0, 0.0, -D_B), POWER), LENS, BEHIND, 200_000, seed=8, blockers=[blocker]
    )
    dirs, w = cone_grid(D_B, R, N)
    free = angle_to(dirs, axis) > beta
    expected = I0 * np.sum(w * free)
    assert 0.35 < expected / (I0 * np.sum(w)) < 0.65
    assert _close(res, expected)


def test_two_overlapping_blockers_block_the_union():
    beta = math.radians(11.0)
    (b1, a1), (b2, a2) = _blocker_at(beta, 0.0), _blocker_at(beta, 0.5 * math.pi)
    res = trace_irradiance(
        PointLight((0.0, 0.0, -D_B), POWER), LENS, BEHIND, 200_000, seed=9, blockers=[b1, b2]
    )
    dirs, w = cone_grid(D_B, R, N)
    in1, in2 = angle_to(dirs, a1) < beta, angle_to(dirs, a2) < beta
    full = np.sum(w)
    union = I0 * np.sum(w * ~(in1 | in2))
    product = I0 * full * (np.sum(w * ~in1) / full) * (np.sum(w * ~in2) / full)
    assert np.sum(w * (in1 & in2)) > 0.05 * full  # they do overlap
    assert _close(res, union)
    assert abs(res.flux_on_plane - product) > 10.0 * res.flux_on_plane_se


def test_glass_blocker_passes_its_fresnel_share_undeflected():
    """A glass sphere on the axis, wider than the lens's cone: each ray keeps the
    blocker's two-surface transmission at its own incidence angle (sin i_b = (d_b /
    r_b) sin psi) and its absorption along 2 r_b cos r_b, and goes on undeflected."""
    n_b, a_b, d_b, r_b = 1.33, 0.5, 1.5, 0.6
    glass = Blocker((0.0, 0.0, -D_B + d_b), r_b, n_b, a_b)
    res = trace_irradiance(
        PointLight((0.0, 0.0, -D_B), POWER), LENS, BEHIND, 200_000, seed=10, blockers=[glass]
    )
    dirs, w = cone_grid(D_B, R, N, n_phi=1)
    iota_b = np.arcsin(np.clip(d_b / r_b * np.sqrt(1.0 - dirs[:, 2] ** 2), 0.0, 1.0))
    r_in = np.arcsin(np.sin(iota_b) / n_b)
    share = xo.two_surface_transmission(iota_b, n_b) * np.exp(-a_b * 2 * r_b * np.cos(r_in))
    expected = I0 * np.sum(w * share)
    assert expected < 0.8 * I0 * np.sum(w)
    assert _close(res, expected)
