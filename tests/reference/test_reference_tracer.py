"""The reference light tracer (reference) against independent values: the 1-D
exact integral of SPEC 6 (core/lens/ball_optics), hand geometry and conservation laws.

Monte-Carlo results are compared within a few standard errors (the tracer's own
estimate of them); every case uses a fixed seed, so the tests are deterministic.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from core.lens import ball_optics as xo
from reference import (
    GlassSphere,
    PointLight,
    ReceiverPlane,
    SunLight,
    lens_shadow,
    trace_irradiance,
)

R, N = 1.0, 1.5
LENS = GlassSphere((0.0, 0.0, 0.0), R, N)
I0 = 1.0  # W/sr: power 4 pi
POWER = 4.0 * math.pi * I0


def _behind(Z):
    """Plane z = Z behind the lens, facing the light at -z."""
    return ReceiverPlane((0.0, 0.0, Z), (0.0, 0.0, -1.0))


@pytest.mark.parametrize("D,Z,absorption", [(3.0, 3.0, 0.0), (1.5, 5.0, 0.4)])
def test_point_on_axis_rings_match_the_exact_integral(D, Z, absorption):
    lens = GlassSphere((0.0, 0.0, 0.0), R, N, absorption)
    edges = np.linspace(0.0, xo.lens_shadow_radius(D, R, Z), 13)
    res = trace_irradiance(
        PointLight((0.0, 0.0, -D), POWER),
        lens,
        _behind(Z),
        300_000,
        seed=1,
        rings=((0.0, 0.0), edges),
    )
    exact = xo.irradiance_on_plane(I0, D, R, N, Z, edges, absorption)
    lit = res.ring_se > 0.0
    assert np.all(exact[~lit] < 1e-9 * exact.max())  # rings the beam does not reach
    z = (res.ring_irradiance - exact)[lit] / res.ring_se[lit]
    assert np.all(np.abs(z) < 4.5), z
    assert np.sqrt(np.mean(z * z)) < 1.6  # the standard errors are honest, not inflated
    flux = xo.lens_flux(I0, D, R, N, absorption)
    assert abs(res.flux_on_plane - flux) < 4.0 * res.flux_on_plane_se
    # every sample carries the same flux into the lens: the cone's, exactly (SPEC 4.2)
    assert res.flux_into_lens == pytest.approx(
        2 * math.pi * I0 * xo.cone_one_minus_cos(D, R), rel=1e-12
    )


def test_deterministic_given_the_seed():
    args = (PointLight((0.0, 0.0, -3.0), POWER, 0.1), LENS, _behind(4.0), 20_000)
    kw = dict(rings=((0.0, 0.0), np.linspace(0.0, 2.0, 9)), chunk=7_000)
    a, b = trace_irradiance(*args, seed=5, **kw), trace_irradiance(*args, seed=5, **kw)
    c = trace_irradiance(*args, seed=6, **kw)
    assert np.array_equal(a.ring_irradiance, b.ring_irradiance)
    assert a.flux_on_plane == b.flux_on_plane
    assert not np.array_equal(a.ring_irradiance, c.ring_irradiance)


def test_resting_marble_lands_near_the_contact_point():
    """Light straight above, the table tangent to the sphere's bottom: the exact
    meridional landing map on the plane z = R (ball_optics. frame) gives the flux
    within each radius of the contact point."""
    D = 10.0
    plane = ReceiverPlane((0.0, 0.0, -R), (0.0, 0.0, 1.0))
    edges = np.array([0.0, 0.05, 0.1, 0.15, 0.2, 0.25, 0.3, 0.5, 100.0])
    res = trace_irradiance(
        PointLight((0.0, 0.0, D), POWER), LENS, plane, 300_000, seed=2, rings=((0.0, 0.0), edges)
    )
    exact = np.diff(xo.flux_within_radius(I0, D, R, N, R, edges))
    se = res.ring_se * np.pi * np.diff(edges**2)
    got = res.ring_flux()
    assert np.all(np.abs(got - exact) < 4.5 * se + 1e-9 * exact.sum()), (got, exact)
    total = xo.lens_flux(I0, D, R, N)
    # the exact map puts all the beam within 0.3 R of the contact point
    assert exact[:7].sum() / total > 0.999
    assert got[:7].sum() / res.flux_on_plane > 0.999
    assert abs(res.flux_on_plane - total) < 4.0 * res.flux_on_plane_se


def test_plane_cutting_the_sphere_gets_the_light_inside_the_glass():
    """A plane through the centre: rays whose chord crosses it land inside the glass
    (with the entry's transmittance), the others after the exit; all the entering
    light lands (nothing can go back up through the table)."""
    D = 10.0
    light = PointLight((0.0, 0.0, D), POWER)
    half = trace_irradiance(
        light,
        LENS,
        ReceiverPlane((0.0, 0.0, 0.0), (0.0, 0.0, 1.0)),
        100_000,
        seed=3,
        rings=((0.0, 0.0), np.array([0.0, R, 10.0])),
    )
    tangent = trace_irradiance(
        light, LENS, ReceiverPlane((0.0, 0.0, -R), (0.0, 0.0, 1.0)), 100_000, seed=3
    )
    # a single surface passes more than two: more flux, all of it under the sphere
    assert half.flux_on_plane > tangent.flux_on_plane
    assert half.ring_flux()[1] < 1e-12 * half.flux_on_plane
    # the entry's mean Fresnel transmittance is between T(two surfaces) and 1
    ratio = half.flux_on_plane / half.flux_into_lens
    assert tangent.flux_on_plane / tangent.flux_into_lens < ratio < 1.0


def test_tilted_plane_catches_the_same_flux():
    """Same seed, same rays: a plane tilted by 12 degrees still catches the whole
    beam, so its flux equals the perpendicular plane's and the exact total."""
    D, Z = 3.0, 6.0
    light = PointLight((0.0, 0.0, -D), POWER)
    b = math.radians(12.0)
    tilted = ReceiverPlane((0.0, 0.0, Z), (0.0, math.sin(b), -math.cos(b)))
    a = trace_irradiance(light, LENS, _behind(Z), 200_000, seed=4)
    t = trace_irradiance(
        light,
        LENS,
        tilted,
        200_000,
        seed=4,
        grid=(np.linspace(-40, 40, 81), np.linspace(-40, 40, 81)),
    )
    assert t.flux_on_plane == pytest.approx(a.flux_on_plane, rel=2e-4)
    assert abs(t.flux_on_plane - xo.lens_flux(I0, D, R, N)) < 4.0 * t.flux_on_plane_se
    assert t.cell_flux().sum() == pytest.approx(t.flux_on_plane, rel=1e-3)


def test_sphere_light_sends_what_a_point_light_sends():
    """A uniform-radiance sphere of radius r sends the lens the point light's flux
    (exactly where the whole emitter stays above each lens point's horizon; here the
    difference is of order (r/D)^2) and blurs the caustic."""
    D, r, Z = 5.0, 0.1, 3.0
    point = trace_irradiance(PointLight((0.0, 0.0, -D), POWER), LENS, _behind(Z), 100_000, seed=7)
    ball = trace_irradiance(PointLight((0.0, 0.0, -D), POWER, r), LENS, _behind(Z), 200_000, seed=7)
    assert (
        abs(ball.flux_into_lens - point.flux_into_lens)
        < 4.0 * ball.flux_into_lens_se + 2e-3 * point.flux_into_lens
    )
    flux = xo.lens_flux(I0, D, R, N)
    assert abs(ball.flux_on_plane - flux) < 4.0 * ball.flux_on_plane_se + 2e-3 * flux


def test_light_behind_the_plane_sends_nothing():
    plane = ReceiverPlane((0.0, 0.0, -2.0), (0.0, 0.0, 1.0))  # floor under the lens
    res = trace_irradiance(PointLight((0.0, 0.0, -4.0), POWER), LENS, plane, 10_000, seed=1)
    assert res.flux_on_plane == 0.0 and res.flux_into_lens == 0.0


def test_rejects_a_light_inside_the_lens():
    with pytest.raises(ValueError):
        trace_irradiance(PointLight((0.0, 0.0, 0.5), POWER), LENS, _behind(3.0), 100)


def test_lens_shadow_is_the_tangent_cone_disc():
    """A point light's shadow on a perpendicular plane is the disc of
    ball_optics.lens_shadow_radius; a sun's, the disc of radius R; a sphere light
    has a penumbra around it."""
    D, Z = 3.0, 4.0
    rs = xo.lens_shadow_radius(D, R, Z)
    u = np.array([0.0, 0.5 * rs, 0.999 * rs, 1.001 * rs, 2.0 * rs])
    v = np.zeros_like(u)
    point = lens_shadow(PointLight((0.0, 0.0, -D), POWER), LENS, _behind(Z), u, v)
    assert np.array_equal(point, [1.0, 1.0, 1.0, 0.0, 0.0])
    sun = lens_shadow(SunLight((0.0, 0.0, 1.0), 1.0), LENS, _behind(Z), u * R / rs, v)
    assert np.array_equal(sun, [1.0, 1.0, 1.0, 0.0, 0.0])
    ball = lens_shadow(
        PointLight((0.0, 0.0, -D), POWER, 0.3),
        LENS,
        _behind(Z),
        np.array([0.0, rs, 3.0 * rs]),
        np.zeros(3),
        n_samples=400,
    )
    assert ball[0] == 1.0 and 0.2 < ball[1] < 0.8 and ball[2] == 0.0
