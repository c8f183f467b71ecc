"""The glass tracer (reference/glass_tracer.py) against independent values: the
sphere tracer (reference/tracer.py), Fresnel's formulas by hand for a slab, the
paraxial focal line of a cylinder, energy conservation, and a tessellated sphere.

Monte-Carlo values are compared within a few of the tracer's own standard errors;
every case has a fixed seed (deterministic)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from reference import GlassSphere, PointLight, ReceiverPlane, SunLight, trace_irradiance
from reference.glass_meshes import box_mesh, corner_normals, ellipsoid_mesh
from reference.glass_tracer import Glass, Receiver, trace_glass
from reference.shapes import Box, Ellipsoid, Rod, TriangleMesh

N = 1.5


def _below(z, grid=None):
    """The plane z = z, its front facing +z (light from above)."""
    return Receiver(ReceiverPlane((0.0, 0.0, z), (0.0, 0.0, 1.0)), grid)


def _fresnel_r(cos_i, n1, n2):
    """Unpolarised reflectance from the amplitude coefficients (Hecht, 4.42-4.43)."""
    sin_t = n1 / n2 * math.sqrt(1.0 - cos_i * cos_i)
    cos_t = math.sqrt(1.0 - sin_t * sin_t)
    rs = (n1 * cos_i - n2 * cos_t) / (n1 * cos_i + n2 * cos_t)
    rp = (n2 * cos_i - n1 * cos_t) / (n2 * cos_i + n1 * cos_t)
    return 0.5 * (rs * rs + rp * rp)


@pytest.mark.parametrize(
    "emitter,z",
    [
        (PointLight((0.0, 0.0, 3.0), 4.0 * math.pi), -3.0),
        (SunLight((0.3, 0.0, -1.0), 1.0, math.radians(2.0)), -2.0),
    ],
)
def test_ellipsoid_with_equal_axes_is_the_sphere_tracer(emitter, z):
    """The direct beam (entry, exit: max_depth 2, no outside reflection) of an
    ellipsoid of equal axes is the sphere tracer's beam with per-surface Fresnel."""
    edges = np.linspace(-2.0, 2.0, 13)
    plane = ReceiverPlane((0.0, 0.0, z), (0.0, 0.0, 1.0))
    sphere = trace_irradiance(
        emitter,
        GlassSphere((0.0, 0.0, 0.0), 1.0, N),
        plane,
        150_000,
        seed=1,
        grid=(edges, edges),
        fresnel="per_surface",
    )
    glass = trace_glass(
        emitter,
        [Glass(Ellipsoid((0.0, 0.0, 0.0), (1.0, 1.0, 1.0)), N)],
        [Receiver(plane, (edges, edges))],
        150_000,
        seed=2,
        max_depth=2,
    )
    got = glass.receivers[0]
    lit = sphere.irradiance_se > 0.0
    z_score = (got.irradiance - sphere.irradiance)[lit] / np.hypot(
        got.irradiance_se, sphere.irradiance_se
    )[lit]
    assert np.all(np.abs(z_score) < 4.5), z_score
    assert np.sqrt(np.mean(z_score**2)) < 1.6
    assert abs(got.flux - sphere.flux_on_plane) < 4.0 * math.hypot(
        got.flux_se, sphere.flux_on_plane_se
    )
    assert np.all(got.irradiance[~lit] == 0.0)


@pytest.mark.parametrize("theta_deg,absorption", [(0.0, 0.0), (35.0, 0.0), (0.0, 2.0)])
def test_slab_under_a_parallel_beam_transmits_the_fresnel_series(theta_deg, absorption):
    """A thin slab (thickness L) under a sun at theta: below it E = S cos(theta) T^2 a
    / (1 - R^2 a^2), the sum over the internal reflections, T = 1 - R the
    unpolarised per-surface transmittance (the same at both faces), a = exp(-mu L /
    cos(theta_t)).  Every ray gives the same series (splitting, no roulette): exact."""
    L, S = 0.1, 2.0
    th = math.radians(theta_deg)
    sun = SunLight((math.sin(th), 0.0, -math.cos(th)), S)
    slab = Glass(Box((0.0, 0.0, 0.0), (1.6, 1.6, L)), N, absorption)
    edges = np.linspace(-0.4, 0.4, 3)
    res = trace_glass(
        sun, [slab], [_below(-0.3, (edges, edges))], 200_000, seed=3, rr_weight=0.0, max_depth=12
    )
    R = _fresnel_r(math.cos(th), 1.0, N)
    cos_t = math.sqrt(1.0 - (math.sin(th) / N) ** 2)
    a = math.exp(-absorption * L / cos_t)
    share = (1 - R) ** 2 * a / (1 - R * R * a * a)
    rec = res.receivers[0]
    # cells inside the lit region: where rays land is random, what each carries is not
    z = (rec.irradiance - S * math.cos(th) * share) / rec.irradiance_se
    assert np.all(np.abs(z) < 4.5), z
    assert abs(res.balance()) < 1e-9 * res.tally["into_glass"]
    if theta_deg == 0.0:  # every ray enters the top face: each one's share is exact
        assert rec.flux / res.tally["into_glass"] == pytest.approx(share, rel=1e-9)


def _beam_width(res):
    """RMS of the landing u over the grid (cell centres, flux weights)."""
    rec = res.receivers[0]
    f = rec.cell_flux().sum(axis=1)
    u = 0.5 * (rec.u_edges[1:] + rec.u_edges[:-1])
    mean = np.sum(f * u) / f.sum()
    return math.sqrt(np.sum(f * (u - mean) ** 2) / f.sum())


def test_cylinder_focuses_a_parallel_beam_at_the_2d_ball_lens_focus():
    """A sun perpendicular to a rod's axis, through a slit |x| < h (two opaque boxes):
    paraxially the rays cross the plane z at x = x0 (1 - z/f) from the axis, f =
    n R / (2 (n - 1)) (the 2-D ball lens, principal planes at the centre), so the
    beam's width is |1 - z/f| times the slit's: equal at z = f -/+ 0.3 R."""
    R, h = 1.0, 0.05
    f = N * R / (2.0 * (N - 1.0))
    rod = Glass(Rod((0.0, 0.0, 0.0), (0.0, 1.0, 0.0), R, 0.6), N)
    slit = [
        Box((1.5 + h, 0.0, 1.5), (3.0, 4.0, 0.1)),
        Box((-1.5 - h, 0.0, 1.5), (3.0, 4.0, 0.1)),
    ]
    sun = SunLight((0.0, 0.0, -1.0), 1.0)
    ue, ve = np.linspace(-0.1, 0.1, 801), np.array([-1.0, 1.0])
    widths = []
    for z in (f - 0.3, f + 0.3, f):
        res = trace_glass(
            sun, [rod], [_below(-z, (ue, ve))], 200_000, seed=4, blockers=slit, max_depth=2
        )
        widths.append(_beam_width(res))
    w1, w2, w_f = widths
    expected = h / math.sqrt(3.0) * 0.3 / f  # uniform slit: RMS h / sqrt 3
    assert w1 == pytest.approx(expected, rel=0.03)
    assert w2 == pytest.approx(expected, rel=0.03)
    # the focus from the two widths (linear in |z - f|), and the waist at f
    z_focus = ((f - 0.3) * w2 + (f + 0.3) * w1) / (w1 + w2)
    assert z_focus == pytest.approx(f, rel=0.005)
    assert w_f < 0.1 * w1


def test_energy_is_conserved_over_every_branch():
    """Everything that enters the glass lands, escapes, is absorbed, blocked or cut
    (splitting without roulette: exactly; roulette: within its noise)."""
    em = PointLight((0.5, 0.2, 3.0), 10.0, 0.1)
    glass = [
        Glass(Ellipsoid((0.0, 0.0, 0.0), (1.0, 0.6, 0.4)), N, 0.3),
        Glass(Box((0.0, 0.0, -1.2), (0.8, 0.8, 0.8)), 1.33, 0.1),
    ]
    recs = [_below(-2.0), Receiver(ReceiverPlane((3.0, 0.0, 0.0), (-1.0, 0.0, 0.0)))]
    blockers = [Box((1.5, 0.0, -1.0), (0.2, 2.0, 0.2))]
    exact = trace_glass(
        em, glass, recs, 20_000, seed=5, blockers=blockers, rr_weight=0.0, outer_reflection=True
    )
    t = exact.tally
    assert abs(exact.balance()) < 1e-9 * t["into_glass"]
    for k in ("landed", "escaped", "absorbed", "blocked", "cut"):
        assert t[k] > 0.0, k
    assert t["lost"] == 0.0 and t["outer_reflection"] == 0.0
    assert t["landed"] == pytest.approx(sum(r.flux for r in exact.receivers), rel=1e-12)
    rr = trace_glass(
        em,
        glass,
        recs,
        20_000,
        seed=6,
        blockers=blockers,
        branching="roulette",
        outer_reflection=True,
    )
    assert abs(rr.balance()) < 4.0 * rr.tally_se["into_glass"]
    assert rr.tally["landed"] == pytest.approx(
        t["landed"], abs=4.0 * rr.tally_se["landed"] + 4.0 * exact.tally_se["landed"]
    )
    # without the outer reflection: the dropped part is tallied, the balance holds
    drop = trace_glass(em, glass, recs, 20_000, seed=5, blockers=blockers, rr_weight=0.0)
    assert drop.tally["outer_reflection"] > 0.0
    assert abs(drop.balance()) < 1e-9 * drop.tally["into_glass"]


def test_a_finely_tessellated_sphere_is_the_analytic_sphere():
    """The mesh shape with the smooth normals of a 64 x 128 latitude-longitude sphere
    lands its light as the analytic sphere does (within the noise and 1 % of flux)."""
    em = PointLight((0.3, 0.0, 3.0), 4.0 * math.pi, 0.05)
    edges = np.linspace(-1.6, 1.6, 9)
    rec = [_below(-2.5, (edges, edges))]
    v, f, vn = ellipsoid_mesh((0.0, 0.0, 0.0), (1.0, 1.0, 1.0), n_lat=64, n_lon=128)
    mesh = TriangleMesh(v, f, corner_normals(f, vn))
    a = trace_glass(em, [Glass(Ellipsoid((0.0, 0.0, 0.0), (1.0, 1.0, 1.0)))], rec, 60_000, seed=7)
    b = trace_glass(em, [Glass(mesh)], rec, 60_000, seed=8)
    ga, gb = a.receivers[0], b.receivers[0]
    lit = (ga.irradiance_se > 0) & (gb.irradiance_se > 0)
    z = (ga.irradiance - gb.irradiance)[lit] / np.hypot(ga.irradiance_se, gb.irradiance_se)[lit]
    assert np.sqrt(np.mean(z * z)) < 2.0 and np.all(np.abs(z) < 5.0), z
    assert gb.flux == pytest.approx(ga.flux, rel=0.01)


def test_deterministic_given_the_seed():
    em = PointLight((0.0, 0.0, 3.0), 1.0)
    args = (
        em,
        [Glass(Rod((0.0, 0.0, 0.0), (1.0, 0.0, 0.0), 0.3, 1.0))],
        [_below(-1.0, (np.linspace(-1, 1, 5),) * 2)],
        5_000,
    )
    a, b, c = trace_glass(*args, seed=1), trace_glass(*args, seed=1), trace_glass(*args, seed=2)
    assert np.array_equal(a.receivers[0].irradiance, b.receivers[0].irradiance)
    assert not np.array_equal(a.receivers[0].irradiance, c.receivers[0].irradiance)


@pytest.mark.parametrize("as_one_mesh,outer", [(False, False), (True, True)])
def test_two_stacked_plates_transmit_the_incoherent_series(as_one_mesh, outer):
    """Two plates under a parallel beam at normal incidence, as two glass solids or as
    one non-convex mesh (a ray leaves it and enters it again): each plate passes
    Ts = (1 - R)/(1 + R) and reflects Rs = 1 - Ts, and the pair passes Ts^2 / (1 - Rs^2)
    (the light bouncing between them summed), within the roulette's noise (splitting
    every branch without it grows exponentially with the depth here).  Dropping the
    outer reflection drops only the first surface's (R), which goes up and away."""
    plates = [Box((0.0, 0.0, 0.0), (1.2, 1.2, 0.1)), Box((0.0, 0.0, -0.3), (1.2, 1.2, 0.1))]
    if as_one_mesh:
        (v1, f1, _), (v2, f2, _) = (box_mesh(p) for p in plates)
        glass = [
            Glass(TriangleMesh(np.concatenate([v1, v2]), np.concatenate([f1, f2 + len(v1)])), N)
        ]
    else:
        glass = [Glass(p, N) for p in plates]
    res = trace_glass(
        SunLight((0.0, 0.0, -1.0), 1.0),
        glass,
        [_below(-0.6)],
        100_000,
        seed=9,
        max_depth=40,
        outer_reflection=outer,
    )
    R = _fresnel_r(1.0, 1.0, N)
    ts = (1 - R) / (1 + R)
    expected = ts * ts / (1 - (1 - ts) ** 2)
    rec, into = res.receivers[0], res.tally["into_glass"]
    # the share passed: mean over the rays that entered, the noise only the roulette's
    assert rec.flux == pytest.approx(expected * into, abs=4.0 * rec.flux_se)
    assert rec.flux / into == pytest.approx(expected, rel=2e-3)
    assert abs(res.balance()) < 4.0 * res.tally_se["into_glass"]
    dropped = res.tally["outer_reflection"]
    assert dropped == (0.0 if outer else pytest.approx(R * into, rel=1e-12))


def test_a_finite_receiver_passes_what_misses_it_to_the_next():
    """A receiver covering x > 0 only, a plane below it: under a slab in a vertical
    beam each takes half of what passes the slab (the flux through the slab's two
    halves), the total that of one infinite plane."""
    sun = SunLight((0.0, 0.0, -1.0), 1.0)
    slab = [Glass(Box((0.0, 0.0, 0.0), (1.0, 1.0, 0.1)), N)]
    half = Receiver(ReceiverPlane((0.0, 0.0, -0.3), (0.0, 0.0, 1.0)), extent=(0.0, 5.0, -5.0, 5.0))
    res = trace_glass(sun, slab, [half, _below(-0.6)], 100_000, seed=10)
    whole = trace_glass(sun, slab, [_below(-0.6)], 100_000, seed=10)
    a, b = res.receivers
    assert a.flux + b.flux == pytest.approx(whole.receivers[0].flux, rel=1e-12)
    assert a.flux == pytest.approx(b.flux, abs=4.0 * math.hypot(a.flux_se, b.flux_se))
