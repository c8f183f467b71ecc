"""Error measure, Blender spot model and the FITTED / EXACT_PROFILE tiers (pure).

core/scene/blender_spot.py, core/tiers/beam_error.py, core/tiers/spot_fit.py, fitted.py
(and its table, fitted_table.json), exact_profile.py. Lengths in units of the lens
radius unless said.
"""

import math

import numpy as np
import pytest

from core.lens import ball_optics as xo
from core.lens.glass import LensOptics
from core.phase1.point_lights import compute_phase1
from core.scene.blender_spot import (
    profile_flux_within_angle,
    smoothstep01,
    spot_flux_within_radius,
    spot_irradiance,
    spot_mask,
    spot_mask_integral,
    spot_ring_irradiance,
    spot_solid_angle,
)
from core.scene.model import Light, Scene, Sphere, Surface
from core.scene.primaries import PrimaryLight
from core.tiers import exact_profile as xp
from core.tiers import fitted as ft
from core.tiers import make_blender_light
from core.tiers import spot_fit as sf
from core.tiers.beam_error import (
    AxialSpot,
    ExactBeam,
    axial_peak,
    evaluate_case,
    l1_error,
    model_from_light,
    ring_edges,
)


def source_for(D, n, R=1.0, center=(0.0, 0.0, 0.0), direction=(0.0, 0.0, 1.0), brightness=1.0):
    c = np.asarray(center, float)
    u = np.asarray(direction, float) / np.linalg.norm(direction)
    scene = Scene(
        lights=[Light(position=tuple(c - D * u), brightness=brightness)],
        objects=[Sphere(center=tuple(c), radius=R, surface=Surface(transmission=1.0, ior=n))],
    )
    result = compute_phase1(scene)
    assert len(result.sources) == 1
    return result.sources[0]


# --------------------------------------------------------------------------- spot model


def test_spot_mask_is_blenders_smoothstep_in_cosine():
    H = math.radians(30.0)
    cos_h = math.cos(H)
    # blend 0: hard edge
    assert spot_mask(math.cos(math.radians(29.9)), H, 0.0) == 1.0
    assert spot_mask(math.cos(math.radians(30.1)), H, 0.0) == 0.0
    # blend 0.5: f = (c − cos H)/((1 − cos H)·0.5); at c halfway, f = 0.5 → 0.5
    c = cos_h + 0.25 * (1.0 - cos_h)
    assert spot_mask(c, H, 0.5) == pytest.approx(0.5)
    c = cos_h + 0.1 * (1.0 - cos_h)  # f = 0.2 → 3·0.04 − 2·0.008 = 0.104
    assert spot_mask(c, H, 0.5) == pytest.approx(0.104)
    assert spot_mask(1.0, H, 1.0) == pytest.approx(1.0)
    assert smoothstep01([-1.0, 0.0, 1.0, 2.0]).tolist() == [0.0, 0.0, 1.0, 1.0]


@pytest.mark.parametrize("H_deg,blend", [(30.0, 0.0), (30.0, 0.3), (5.0, 1.0), (90.0, 0.7)])
def test_mask_integral_is_the_integral_of_the_mask(H_deg, blend):
    H = math.radians(H_deg)
    q = np.linspace(0.0, 1.2, 200_001)
    m = spot_mask(1.0 - q, H, blend)
    num = np.concatenate([[0.0], np.cumsum(0.5 * (m[1:] + m[:-1]) * np.diff(q))])
    assert np.max(np.abs(spot_mask_integral(q, H, blend) - num)) < 1e-5  # step: one grid cell
    assert 2 * math.pi * spot_mask_integral(2.0, H, blend) == pytest.approx(
        spot_solid_angle(H, blend)
    )


def test_spot_on_axis_irradiance_is_intensity_over_distance_squared():
    # 100 W spot → I0 = 100/(4π) W/sr; 2 m in front: E = I0/4 = 1.98944 W/m².
    I0 = 100.0 / (4 * math.pi)
    assert spot_irradiance(I0, 2.0, math.radians(20), 0.2, 0.0) == pytest.approx(1.989437, rel=1e-6)
    # off axis, inside the full-intensity core: I0 h / r³ (cos γ / r²)
    r = math.hypot(2.0, 0.3)
    assert spot_irradiance(I0, 2.0, math.radians(20), 0.2, 0.3) == pytest.approx(I0 * 2.0 / r**3)
    # outside the cone, and behind the spot: nothing
    assert spot_irradiance(I0, 2.0, math.radians(20), 0.2, 2.0) == 0.0
    assert spot_irradiance(I0, -1.0, math.radians(20), 0.2, 0.0) == 0.0


def test_spot_ring_flux_matches_quadrature_of_the_irradiance():
    I0, h, H, b = 3.0, 1.7, math.radians(25.0), 0.6
    rho = np.linspace(0.0, 1.5, 300_001)
    E = spot_irradiance(I0, h, H, b, rho)
    f = 2 * math.pi * rho * E
    num = np.sum(0.5 * (f[1:] + f[:-1]) * np.diff(rho))
    assert spot_flux_within_radius(I0, h, H, b, [1.5])[0] == pytest.approx(num, rel=1e-7)
    # a whole spot: I0 × its weighted solid angle
    assert spot_flux_within_radius(I0, h, H, b, [1e9])[0] == pytest.approx(
        I0 * spot_solid_angle(H, b)
    )
    edges = np.array([0.0, 0.2, 0.5])
    ring = spot_ring_irradiance(I0, h, H, b, edges)
    assert ring[0] * math.pi * 0.04 == pytest.approx(spot_flux_within_radius(I0, h, H, b, [0.2])[0])


def test_profile_flux_exact_for_constant_and_linear_profiles():
    g = np.array([0.0, 0.3, 0.8])
    # constant 2 W/sr up to 0.8 rad: 2π · 2 · (1 − cos γ)
    assert profile_flux_within_angle(g, [2.0, 2.0, 2.0], 0.5) == pytest.approx(
        4 * math.pi * (1 - math.cos(0.5))
    )
    assert profile_flux_within_angle(g, [2.0, 2.0, 2.0], 2.0) == pytest.approx(
        4 * math.pi * (1 - math.cos(0.8))
    )
    # piecewise linear: quadrature
    I0 = np.array([5.0, 1.0, 0.0])
    x = np.linspace(0.0, 0.7, 100_001)
    f = np.interp(x, g, I0) * np.sin(x)
    num = 2 * math.pi * np.sum(0.5 * (f[1:] + f[:-1]) * np.diff(x))
    assert profile_flux_within_angle(g, I0, 0.7) == pytest.approx(num, rel=1e-8)
    assert profile_flux_within_angle(g, I0, 1e-5) == pytest.approx(
        2 * math.pi * 5.0 * 0.5e-10, rel=1e-4
    )


# --------------------------------------------------------------------------- the truth


@pytest.mark.parametrize(
    "D,n,Z", [(2.0, 1.5, 1.5), (2.0, 1.5, 11.0), (1.2, 1.33, 3.0), (50.0, 1.7, 2.0)]
)
def test_exact_beam_matches_exact_optics(D, n, Z):
    beam = ExactBeam(1.0, D, 1.0, n, n_fan=20_000)
    radii = np.linspace(0.0, xo.lens_shadow_radius(D, 1.0, Z), 97)
    ref = xo.flux_within_radius(1.0, D, 1.0, n, Z, radii, n_psi=20_000)
    got = beam.flux_within_radius(Z, radii)
    assert np.max(np.abs(got - ref)) <= 1e-6 * ref[-1]
    assert beam.receiver(Z).total <= beam.lens_flux * (1 + 1e-9)


class _Truth:
    def __init__(self, beam):
        self.beam = beam

    def flux_within_radius(self, Z, radii):
        return self.beam.flux_within_radius(Z, radii)


def test_exact_model_against_itself_has_zero_error():
    beam = ExactBeam(1.0, 3.0, 1.0, 1.5)
    ce = evaluate_case(_Truth(beam), beam, receivers=(0.5, 2.0, 8.0))
    assert np.all(ce.l1 < 1e-12)
    assert ce.peak_error == 0.0
    assert np.allclose(ce.flux_ratio, 1.0)


def test_l1_is_converged_in_the_rings():
    beam = ExactBeam(1.0, 3.0, 1.0, 1.5)
    spot = AxialSpot(apex=1.0, intensity=0.3, half_angle=math.radians(30.0), blend=0.8)
    Z = beam.plane(2.0)
    rs = beam.shadow_radius(Z)
    coarse = l1_error(spot, beam, Z)
    fine = l1_error(spot, beam, Z, ring_edges(rs, 3200, 400))
    assert coarse <= fine + 1e-12  # averaging can only lower it
    assert fine - coarse < 5e-3


def test_axial_peak_of_the_truth_lies_between_marginal_and_paraxial_focus():
    # D = 2, n = 1.5: paraxial image 6 R behind the centre (5 R behind the back pole)
    beam = ExactBeam(1.0, 2.0, 1.0, 1.5)
    peak = axial_peak(beam.flux_within_radius, 1.0, 0.5, 10.0)
    assert 1.0 < peak < 5.0
    # a spot's brightest point is the nearest receiver
    spot = AxialSpot(apex=0.0, intensity=1.0, half_angle=math.radians(20.0))
    assert axial_peak(spot.flux_within_radius, 1.0, 0.5, 10.0) == pytest.approx(0.5)


def test_model_from_blender_light_in_world_space():
    # sphere of radius 0.5 at (1, 2, 3), light along −y: PHYSICAL light on the axis.
    src = source_for(4.0, 1.5, R=0.5, center=(1.0, 2.0, 3.0), direction=(0.0, -1.0, 0.0))
    bl = make_blender_light(src, PrimaryLight(100.0), "PHYSICAL", scene_size=10.0)
    m = model_from_light(bl, src)
    assert m.apex == pytest.approx(src.image_distance)
    assert m.intensity == pytest.approx(bl.energy_w / (4 * math.pi))
    assert m.half_angle == pytest.approx(math.radians(bl.cone_half_angle_deg))
    assert m.facing == 1.0
    m2 = model_from_light(bl.to_json() | {"location": bl.location, "direction": bl.direction}, src)
    assert m2.apex == pytest.approx(m.apex)
    # a cone narrower than 1°: spot_size stays 1°, the model uses the cone made
    narrow = ft.make_fitted_light(source_for(1.5, 1.5), PrimaryLight(100.0))  # collimated
    assert narrow.spot_size_deg == 1.0 and 0.0 < narrow.scale_xy < 1.0
    assert model_from_light(narrow, source_for(1.5, 1.5)).half_angle == pytest.approx(
        math.radians(narrow.cone_half_angle_deg)
    )


# --------------------------------------------------------------------------- tiers


def test_spot_fit_invariants_round_trip():
    fit = sf.SpotFit(apex=-3.0, intensity=12.5, half_angle_deg=4.0, blend=0.7)
    back = sf.SpotFit.from_invariants(7.0, *fit.invariants(7.0))
    assert back.apex == pytest.approx(fit.apex)
    assert back.intensity == pytest.approx(fit.intensity)
    assert back.half_angle_deg == pytest.approx(fit.half_angle_deg)
    assert back.blend == fit.blend


def test_fitted_table_round_trips_at_its_nodes():
    t = ft.fitted_table()
    assert list(t.X) == list(ft.TABLE_X) and list(t.N) == list(ft.TABLE_N)
    for i, j in [(3, 3), (10, 5), (19, 0), (1, 8)]:
        x, n = t.X[i], t.N[j]
        fit, note = ft.fitted_spot(1.0 / x, n)
        assert note == ""
        w, e, r, b = fit.invariants(1.0 / x)
        assert w == pytest.approx(t.W[i][j], rel=1e-5)
        assert e == pytest.approx(t.E[i][j], rel=1e-5)
        assert r == pytest.approx(t.RCONE[i][j], rel=1e-5)
        assert b == pytest.approx(t.BLEND[i][j], abs=1e-6)
    # outside the table: clamped, and said so
    fit, note = ft.fitted_spot(1.01, 2.4)
    assert "clamped" in note and math.isfinite(fit.apex)


def test_fitted_table_is_the_one_the_code_held():
    """The table, now data (fitted_table.json), holds the numbers the generated
    module addon/fitted_table.py held (first and last rows copied from it)."""
    t = ft.fitted_table()
    assert t is ft.fitted_table()  # read once
    assert t.X.shape == (21,) and t.N.shape == (9,)
    assert t.X[0] == 0.0 and t.X[-1] == 0.95 and list(t.N) == list(ft.TABLE_N)
    old = {
        "W": (
            [0.917578, 2.67966, 9.53276, 2.10967, 1.97655, 1.82505, 1.73157, 1.65936, 1.60256],
            [0.2833, 0.251078, 0.188562, 0.142803, 0.0945803, 0.0387643, 0.001, 0.001, 0.001],
        ),
        "E": (
            [12.1773, 39.2446, 271.226, 10.0776, 6.61319, 4.47529, 3.31195, 2.57143, 2.06897],
            [0.319373, 0.466785, 0.624991, 0.88067, 1.16878, 1.45713, 1.94467, 3.58509, 3.72717],
        ),
        "RCONE": (
            [
                0.255438,
                0.153149,
                0.0612782,
                0.342788,
                0.476377,
                0.638644,
                0.834458,
                1.03929,
                1.25162,
            ],
            [1.85424, 1.44429, 1.22601, 1.03755, 0.896618, 0.782463, 0.660917, 0.627438, 0.496692],
        ),
        "BLEND": ([1, 1, 1, 1, 1, 1, 1, 1, 1], [0, 0.000147958, 0, 0, 0, 0, 0, 1, 1]),
        "L1": (
            [
                0.531079,
                0.402901,
                0.321669,
                0.241173,
                0.177819,
                0.133568,
                0.100372,
                0.0760041,
                0.058294,
            ],
            [
                0.432792,
                0.475447,
                0.465203,
                0.440125,
                0.423019,
                0.378215,
                0.446221,
                0.660592,
                0.777574,
            ],
        ),
    }
    for k, (first, last) in old.items():
        a = getattr(t, k)
        assert a.shape == (21, 9), k
        assert a[0].tolist() == first and a[-1].tolist() == last, k


@pytest.mark.parametrize("D,n", [(3.0, 1.5), (10.0, 1.5), (2.0, 1.7), (5.0, 1.33)])
def test_fitted_tier_beats_physical(D, n):
    src = source_for(D, n)
    primary = PrimaryLight(4 * math.pi)  # I0 = 1 W/sr
    beam = ExactBeam(1.0, D, 1.0, n)
    rec = (0.5, 1.0, 2.0, 4.0, 8.0)
    phys = evaluate_case(
        model_from_light(make_blender_light(src, primary, "PHYSICAL", scene_size=20.0), src),
        beam,
        rec,
        peak_true=0.5,
    )
    fitted = ft.make_fitted_light(src, primary, scene_size=20.0)
    fit = evaluate_case(model_from_light(fitted, src), beam, rec, peak_true=0.5)
    assert fit.l1_mean < phys.l1_mean
    assert fit.l1_mean < 0.8


def test_fitted_light_geometry_and_energy():
    src = source_for(5.0, 1.5, R=0.5, center=(0.0, 0.0, 1.0), direction=(0.0, 0.0, -1.0))
    a = ft.make_fitted_light(src, PrimaryLight(100.0), scene_size=5.0)
    b = ft.make_fitted_light(src, PrimaryLight(200.0), scene_size=5.0)
    assert b.energy_w == pytest.approx(2 * a.energy_w)
    fit, _ = ft.fitted_spot(10.0, 1.5)  # D/R = 5/0.5
    assert a.location == pytest.approx((0.0, 0.0, 1.0 - 0.5 * fit.apex))
    assert a.direction == pytest.approx((0.0, 0.0, -1.0))
    assert a.energy_w == pytest.approx(100.0 * fit.intensity)
    assert a.spot_size_deg == pytest.approx(2 * fit.half_angle_deg)
    assert a.model == "FITTED" and a.type == "SPOT"
    c = ft.make_fitted_light(src, PrimaryLight(100.0), optics=LensOptics(transmission_weight=0.5))
    assert c.energy_w == pytest.approx(0.25 * a.energy_w)


def test_direct_fit_is_at_least_as_good_as_the_table():
    D, n = 3.0, 1.6
    beam = ExactBeam(1.0, D, 1.0, n)
    direct = sf.fit_spot(D, n)
    table, _ = ft.fitted_spot(D, n)
    ob = sf.SpotObjective(beam)
    d = float(
        np.mean(
            ob.l1(direct.apex, direct.intensity, math.radians(direct.half_angle_deg), direct.blend)
        )
    )
    t = float(
        np.mean(ob.l1(table.apex, table.intensity, math.radians(table.half_angle_deg), table.blend))
    )
    assert d == pytest.approx(direct.l1, abs=1e-5)  # fit used an 8000-ray fan
    assert d <= t + 1e-3


def test_exact_profile_is_accurate_and_conserves_flux():
    D, n = 10.0, 1.5
    prof = xp.exact_profile(D, n, K=128, M=128)
    beam = ExactBeam(1.0, D, 1.0, n)
    ce = evaluate_case(xp.profile_model(prof), beam, receivers=(0.5, 1.0, 3.0, 9.0), peak_true=0.5)
    assert ce.l1_mean < 0.1
    # each row carries the beam's flux reaching that plane (to the table's resolution)
    j = 100
    h = prof.distances[j]
    g = np.concatenate([[0.0], np.radians(prof.angles_deg)])
    I0 = np.concatenate([[prof.table[j, 0]], prof.table[j]])
    flux = profile_flux_within_angle(g, I0, math.pi / 2)
    assert flux == pytest.approx(beam.receiver(prof.apex + h).total, rel=0.02)


def test_profile_light_world_units_and_json():
    src = source_for(4.0, 1.5, R=2.0, center=(0.0, 0.0, 0.0), direction=(1.0, 0.0, 0.0))
    prof = xp.exact_profile(2.0, 1.5, K=64, M=32)
    light = xp.make_profile_light(src, PrimaryLight(50.0), profile=prof)
    assert light.location == pytest.approx((2.0 * prof.apex, 0.0, 0.0))
    assert light.spot_size_deg == 180.0 and light.spot_blend == 0.0
    p = light.profile
    assert p["pixels"].shape == (32, 64) and p["pixels"].dtype == np.float32
    assert p["h_min"] == pytest.approx(2.0 * prof.h_min)
    # energy/(4π) × pixel = the table's intensity × the primary's intensity
    I0 = 50.0 / (4 * math.pi)
    assert light.energy_w / (4 * math.pi) * float(p["pixels"].max()) == pytest.approx(
        prof.table.max() * I0, rel=1e-6
    )
    # a 180° spot emits energy/2: the beam's flux
    assert light.energy_w / 2 == pytest.approx(prof.flux * I0)
    assert prof.flux == pytest.approx(ExactBeam(1.0, 2.0, 1.0, 1.5).lens_flux, rel=1e-4)
    js = light.to_json()
    assert set(js) >= {"type", "energy_w", "spot_size_deg", "spot_blend", "radius", "profile"}
    assert "pixels" not in js["profile"]
