"""Issue 12: primary lights of every Blender type, phase 1 for them, extended
sources and the near field (pure). Expected values by hand or by quadratures
written here, never taken from the code under test."""

import math

import numpy as np
import pytest

from core.phase1.all_lights import compute_phase1_primaries, disc_overlap
from core.phase1.point_lights import compute_phase1
from core.phase1.skip_reasons import Reason
from core.plan.budget import source_flux
from core.plan.planning import receiver_distance
from core.scene.arrays import SceneArrays
from core.scene.primaries import (
    AreaPrimary,
    PointPrimary,
    PrimaryArrays,
    PrimaryLight,
    SpotPrimary,
    SunPrimary,
    emission_toward,
    lens_flux,
    source_radius,
    tier_primaries,
)
from core.tiers import TIERS, make_blender_light
from core.tiers import beam_error as acc
from core.tiers import exact_profile as xp
from core.tiers.near_field import APEX_CLEARANCE


def spheres(centers, radii, ior=1.5, kt=1.0):
    c = np.asarray(centers, float).reshape(-1, 3)
    n = len(c)
    return SceneArrays(
        np.zeros((0, 3)),
        np.zeros(0),
        np.zeros((0, 3)),
        c,
        np.asarray(radii, float).reshape(n),
        np.full(n, ior),
        np.broadcast_to(np.asarray(kt, float), (n,)).copy(),
    )


def smoothstep(x):
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3 - 2 * x)


def disc_mean_of_mask(pos, axis, half, blend, center, R, n=400):
    """The spot's mask averaged over the lens's disc seen from `pos` (a fine grid
    on the disc across the line of sight; for R ≪ D every point has the same
    solid angle)."""
    w = np.subtract(center, pos) / np.linalg.norm(np.subtract(center, pos))
    e1 = np.cross(w, (1.0, 0.0, 0.0))
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(w, e1)
    g = (np.arange(n) + 0.5) / n * 2 - 1
    x, y = np.meshgrid(g, g)
    inside = x * x + y * y <= 1
    pts = np.asarray(center) + R * (x[inside, None] * e1 + y[inside, None] * e2)
    d = pts - pos
    c = d @ np.asarray(axis) / np.linalg.norm(d, axis=1)
    q = 1 - math.cos(half)
    mask = (c > 1 - q) * 1.0 if blend == 0 else smoothstep((c - (1 - q)) / (q * blend))
    return float(mask.mean())


# --------------------------------------------------------------------------- emitters


@pytest.mark.parametrize("blend", [0.0, 0.5])
def test_a_spot_cone_through_the_lens_centre_gives_about_half_the_flux(blend):
    H = math.radians(20.0)
    D, R = 2.0, 0.02
    center = (D * math.sin(H), 0.0, -D * math.cos(H))  # the cone's rim through the centre
    spot = SpotPrimary((0.0, 0.0, 0.0), (0.0, 0.0, -1.0), 100.0, 2 * H, blend)
    a = PrimaryArrays.from_primaries([spot])
    e = float(emission_toward(a, [0], [center], [R])[0])
    expected = disc_mean_of_mask((0, 0, 0), (0, 0, -1), H, blend, center, R)
    assert e == pytest.approx(expected, abs=0.01)
    if blend == 0.0:
        assert e == pytest.approx(0.5, abs=0.02)  # half the lens inside the cone
    omega = 2 * math.pi * (1 - math.sqrt(1 - (R / D) ** 2))
    assert lens_flux(a, [0], [center], [R])[0] == pytest.approx(100 / (4 * math.pi) * omega * e)


def test_a_spot_covering_the_lens_gives_all_and_one_missing_it_nothing():
    spot = SpotPrimary((0.0, 0.0, 1.0), (0.0, 0.0, -1.0), 10.0, math.radians(40), 0.3)
    s = spheres([(0, 0, 0), (2, 0, 0)], [0.05, 0.05])
    r = compute_phase1_primaries(s, [spot])
    assert [(x.lens, x.emission) for x in r.sources] == [(0, 1.0)]
    (skip,) = r.skipped
    assert skip.lens == 1 and skip.code == Reason.OUTSIDE_EMISSION


def test_area_light_intensity_is_lambertian():
    x = 0.01  # a small square: (P/π) cos θ
    area = AreaPrimary((0.0, 0.0, 0.0), (0.0, 0.0, -1.0), (1.0, 0.0, 0.0), 50.0, "SQUARE", x, x)
    a = PrimaryArrays.from_primaries([area])
    th = math.radians(60.0)
    c = (10 * math.sin(th), 0.0, -10 * math.cos(th))
    e = emission_toward(a, [0, 0], [c, (0, 0, 10.0)], [0.1, 0.1])
    assert e[0] * 50 / (4 * math.pi) == pytest.approx(50 / math.pi * math.cos(th), rel=1e-3)
    assert e[1] == 0.0  # behind its emitting side


def test_area_light_near_a_lens_is_the_exact_disc_integral():
    # A small sphere on the axis of a Lambertian disc of radius a at height h:
    # Φ = L ∫ cos θ π R²/d² dA = 2π² L R² (1 − h/sqrt(h² + a²)), L = P/(π · π a²).
    P, a_, h, R = 20.0, 0.5, 0.3, 0.003
    disk = AreaPrimary(
        (0.0, 0.0, 0.0), (0.0, 0.0, -1.0), (1.0, 0.0, 0.0), P, "DISK", 2 * a_, 2 * a_
    )
    pa = PrimaryArrays.from_primaries([disk])
    L = P / (math.pi * math.pi * a_ * a_)
    exact = 2 * math.pi**2 * L * R * R * (1 - h / math.hypot(h, a_))
    assert lens_flux(pa, [0], [(0, 0, -h)], [R])[0] == pytest.approx(exact, rel=0.02)


def test_source_radius_of_each_primary():
    x = 0.3
    prims = [
        PointPrimary((0, 0, 0), 1.0, 0.1),
        AreaPrimary((0, 0, 0), (0, 0, -1), (1, 0, 0), 1.0, "SQUARE", x, x),
        AreaPrimary((0, 0, 0), (0, 0, -1), (1, 0, 0), 1.0, "DISK", x, x),
        SunPrimary((0, 0, -1), 1.0, math.radians(0.5)),
    ]
    a = PrimaryArrays.from_primaries(prims)
    r = source_radius(a, [0, 1, 2, 3], [(0, 0, -5.0)] * 4, [1.0, 1.0, 1.0, 1e4])
    # square: the disc of the same second moment, sqrt(2 (x²/12 + x²/12)) = x/√3
    assert r == pytest.approx([0.1, x / math.sqrt(3), x / 2, 1e4 * math.tan(math.radians(0.25))])


# --------------------------------------------------------------------------- phase 1


def test_point_lights_give_phase1s_sources_unchanged():
    s = spheres([(0, 0, 0), (3, 1, 0), (1.5, 0.5, 0)], [1.0, 0.5, 0.2])
    prims = [PointPrimary((6.0, 2.0, 0.5), 3.0), PointPrimary((-5.0, 0.0, 1.0), 2.0)]
    got = compute_phase1_primaries(s, prims)
    scene = SceneArrays(
        np.array([p.position for p in prims]),
        np.array([3.0, 2.0]),
        np.ones((2, 3)),
        s.center,
        s.radius,
        s.ior,
        s.kt,
    )
    want = compute_phase1(scene)
    assert len(got.table) == len(want.table) > 0
    for name in (
        "light",
        "lens",
        "kind",
        "position",
        "axis",
        "spread",
        "intensity",
        "vergence",
        "unblocked_fraction",
        "shadow_spheres",
    ):
        assert np.array_equal(getattr(got.table, name), getattr(want.table, name)), name
    assert [k.code for k in got.skipped] == [k.code for k in want.skipped]
    assert np.all(got.table.emission == 1.0)


def test_sun_image_is_the_back_focal_point_and_its_flux_s_pi_r2():
    n, R, S = 1.5, 0.5, 3.0
    C = np.array([1.0, 2.0, 3.0])
    r = compute_phase1_primaries(spheres([C], [R], ior=n), [SunPrimary((0, 0, -1), S)])
    (src,) = r.sources
    f = n * R / (2 * (n - 1))  # effective focal length, from C
    assert src.kind == "real"
    assert src.position == pytest.approx(C + np.array([0, 0, -f]), abs=1e-12)
    # irradiance S at the lens: intensity toward it over D²
    assert src.emission * 4 * math.pi * S / (4 * math.pi) / src.distance**2 == pytest.approx(S)
    flux = source_flux(r.table, r._arrays.light_brightness)[0] / src.brightness_factor
    assert flux == pytest.approx(S * math.pi * R * R, rel=1e-6)


def test_sun_obstruction_is_a_cylinder_test():
    R = 1.0
    # lens at the origin; a blocker upstream (the sun shines along −z) shifted by R:
    # half-overlapping discs, overlap = R²(2π/3 − √3/2)
    s = spheres(
        [(0, 0, 0), (R, 0, 10.0), (0.0, 30.0, -10.0), (0, 30.0, 0)],
        [R, R, 5.0, R],
        kt=[1.0, 0.0, 0.0, 1.0],
    )
    r = compute_phase1_primaries(s, [SunPrimary((0, 0, -1), 1.0)])
    src = {x.lens: x for x in r.sources}
    share = 1 - R * R * (2 * math.pi / 3 - math.sqrt(3) / 2) / (math.pi * R * R)
    assert src[0].shadow_list == [1] and src[0].unblocked_fraction == pytest.approx(share)
    assert src[3].full  # its big neighbour lies downstream
    assert disc_overlap(1.0, 1.0, 1.0) == pytest.approx(2 * math.pi / 3 - math.sqrt(3) / 2)
    # a big blocker upstream covers the lens's whole disc (R_k ≥ ρ + R_i)
    s2 = spheres([(0, 0, 0), (0.5, 0, 10.0)], [R, 3.0], kt=[1.0, 0.0])
    r2 = compute_phase1_primaries(s2, [SunPrimary((0, 0, -1), 1.0)])
    assert not r2.sources
    assert [(k.lens, k.code) for k in r2.skipped] == [
        (0, Reason.TOTALLY_BLOCKED),
        (1, Reason.OPAQUE),
    ]


# --------------------------------------------------------------------------- extended sources


def _marble(D=1.0, R=0.01, n=1.5, radius=0.0):
    s = spheres([(0, 0, 0)], [R], ior=n)
    return compute_phase1_primaries(s, [PointPrimary((0, 0, D), 4 * math.pi, radius)]).sources[0]


def test_blur_is_the_image_of_the_source():
    D, R, n, r = 1.0, 0.01, 1.5, 0.1
    src = _marble(D, R, n, r)
    V = 2 * (n - 1) / (n * R) - 1 / D  # SPEC §4.1
    m = (1 / V) / D
    bounds = ((-1, -1, -0.5), (1, 1, 1.0))  # the image lies within the scene
    light = make_blender_light(
        src, PrimaryLight(4 * math.pi, r), "PHYSICAL", scene_size=3.0, scene_bounds=bounds
    )
    assert light.radius == pytest.approx(abs(m) * r)
    # a receiver z from the centre sees the blur z·r/D (SPEC §10)
    for tier in ("FITTED", "EXACT_PROFILE"):
        light = make_blender_light(
            src, PrimaryLight(4 * math.pi, r), tier, scene_size=3.0, receiver_distance=0.05
        )
        assert light.radius == pytest.approx(0.05 * r / D)


def test_a_suns_blur_is_f_tan_half_its_angle():
    n, R, a = 1.5, 0.01, math.radians(2.0)
    r = compute_phase1_primaries(spheres([(0, 0, 0)], [R], ior=n), [SunPrimary((0, 0, -1), 1.0, a)])
    (src,) = r.sources
    light = make_blender_light(
        src,
        PrimaryLight(4 * math.pi),
        "PHYSICAL",
        scene_size=1.0,
        scene_bounds=((-1, -1, -1), (1, 1, 1)),
    )
    f = n * R / (2 * (n - 1))
    assert light.radius == pytest.approx(f * math.tan(a / 2), rel=1e-5)
    assert light.location == pytest.approx((0, 0, -f), abs=1e-9)


# --------------------------------------------------------------------------- near field


class PlaneOccluder:
    """`occluders.first_hit` against one plane {x : n·x = d} (hit from either side)."""

    def __init__(self, normal, d):
        self.n, self.d = np.asarray(normal, float), float(d)

    def first_hit(self, origins, direction, limit):
        denom = self.n @ np.asarray(direction, float)
        t = (self.d - np.asarray(origins) @ self.n) / denom if denom else np.full(len(origins), -1)
        return np.where((t > 1e-12) & (t <= limit), t, np.inf)


def test_receiver_distance_finds_the_table_under_a_resting_marble():
    R = 0.01
    src = _marble(1.0, R)  # axis (0, 0, −1)
    assert receiver_distance(PlaneOccluder((0, 0, 1), -R), src, 3.0) == pytest.approx(R)
    assert receiver_distance(PlaneOccluder((0, 0, 1), -2 * R), src, 3.0) == pytest.approx(2 * R)
    # a table tilted 30° to the axis, touching the sphere: R / cos 30° along the axis
    nrm = (math.sin(math.radians(30)), 0.0, math.cos(math.radians(30)))
    assert receiver_distance(PlaneOccluder(nrm, -R), src, 3.0) == pytest.approx(
        R / math.cos(math.radians(30))
    )


@pytest.mark.parametrize("tier", list(TIERS))
@pytest.mark.parametrize("Z", [1.0, 1.5, 2.0])
def test_no_lens_light_sits_at_or_behind_its_receiver(tier, Z):
    R = 0.01
    src = _marble(1.0, R)
    bounds = ((-0.5, -0.5, -Z * R), (0.5, 0.5, 1.0))
    light = make_blender_light(
        src,
        PrimaryLight(4 * math.pi),
        tier,
        scene_size=1.5,
        scene_bounds=bounds,
        receiver_distance=Z * R,
    )
    apex = float(np.dot(np.subtract(light.location, src.lens_center), src.axis))
    assert apex <= Z * R - APEX_CLEARANCE * R * 0.999
    assert light.inside_lens == (abs(apex) < R)


def test_pulled_in_cone_keeps_the_paraxial_flux():
    R, Z = 0.01, 0.01
    src = _marble(1.0, R)
    bounds = ((-0.5, -0.5, -0.05), (0.5, 0.5, 1.0))  # the image lies inside the scene
    far = make_blender_light(
        src, PrimaryLight(4 * math.pi), "PHYSICAL", scene_size=1.5, scene_bounds=bounds
    )
    near = make_blender_light(
        src,
        PrimaryLight(4 * math.pi),
        "PHYSICAL",
        scene_size=1.5,
        scene_bounds=bounds,
        receiver_distance=Z,
    )
    theta = math.radians(src.spread_deg)
    rho = (src.image_distance - Z) * math.tan(theta)  # the beam's section on the table
    H = math.radians(near.cone_half_angle_deg)
    assert math.tan(H) == pytest.approx(rho / Z, rel=1e-9)
    assert near.location == pytest.approx(tuple(src.lens_center))

    def omega(x):
        return 2 * math.pi * (1 - math.cos(x))

    assert near.energy_w * omega(H) == pytest.approx(far.energy_w * omega(theta), rel=1e-9)


def _flux_on(light, src, Z, radii):
    if light.model == "EXACT_PROFILE":
        apex = np.dot(np.subtract(light.location, src.lens_center), src.axis)
        prof = xp.cached_profile(
            round(src.distance / src.lens_radius, 9),
            round(src.ior, 9),
            bool(apex < src.lens_radius),
        )
        I0 = light.energy_w / (4 * math.pi) / (prof.flux / (2 * math.pi))
        return xp._Profile2D(prof, src.lens_radius, I0).flux_within_radius(Z, radii)
    return acc.model_from_light(light, src).flux_within_radius(Z, radii)


@pytest.mark.parametrize("tier,l1_max", [("FITTED", 0.65), ("EXACT_PROFILE", 0.4)])
def test_a_resting_marble_gets_its_caustic(tier, l1_max):
    """Light 1 m above a 2 cm marble on a table: the flux on the table around the
    contact point (the shadow disc, and the inner 0.3 R) within 10 % of the exact
    optics', and the relative L1 error over the shadow disc below `l1_max`
    (before: nothing, L1 = 1)."""
    R, D = 0.01, 1.0
    src = _marble(D, R)
    light = make_blender_light(
        src, PrimaryLight(4 * math.pi), tier, scene_size=1.5, receiver_distance=R
    )
    beam = acc.ExactBeam(1.0, D, R, 1.5, n_fan=8000)
    edges = acc.ring_edges(beam.shadow_radius(R))
    true = beam.flux_within_radius(R, edges)
    mod = np.asarray(_flux_on(light, src, R, edges))
    assert mod[-1] == pytest.approx(true[-1], rel=0.1)
    inner = [0.0, 0.3 * R]
    assert np.diff(_flux_on(light, src, R, inner))[0] == pytest.approx(
        np.diff(beam.flux_within_radius(R, inner))[0], rel=0.1
    )
    l1 = np.sum(np.abs(np.diff(mod) - np.diff(true))) / (true[-1] - true[0])
    assert l1 < l1_max


# --------------------------------------------------------------------------- through the tiers


def test_every_primary_reaches_every_tier_as_its_equivalent_point_light():
    """A sun's PHYSICAL cone has the on-axis intensity S·T(0)·f² (the limit of
    I·T(0)·m² with I = S·D², m = f/D); a spot covering half the lens gives half a
    point light's energy; an area light 4 cos θ times its P/(4π)."""
    n, R, S = 1.5, 0.01, 2.0
    s = spheres([(0, 0, 0)], [R], ior=n)
    bounds = ((-1, -1, -1), (1, 1, 1))
    f = n * R / (2 * (n - 1))
    T0 = (4 * n / (n + 1) ** 2) ** 2
    (sun,) = compute_phase1_primaries(s, [SunPrimary((0, 0, -1), S)]).sources
    light = make_blender_light(
        sun, PrimaryLight(4 * math.pi * S), "PHYSICAL", scene_size=2.0, scene_bounds=bounds
    )
    assert light.energy_w / (4 * math.pi) == pytest.approx(S * T0 * f * f, rel=1e-5)

    H = math.radians(20.0)
    pos = (-math.sin(H), 0.0, math.cos(H))  # the cone's rim through the centre
    spot = SpotPrimary(pos, (0.0, 0.0, -1.0), 100.0, 2 * H, 0.0)
    point = PointPrimary(pos, 100.0)
    th = math.radians(50.0)
    area = AreaPrimary(
        (math.sin(th), 0.0, math.cos(th)),
        (0.0, 0.0, -1.0),
        (1.0, 0.0, 0.0),
        100.0,
        "SQUARE",
        1e-3,
        1e-3,
    )
    got = compute_phase1_primaries(s, [spot, point, area]).sources
    for tier in TIERS:
        e = [
            make_blender_light(
                x, PrimaryLight(100.0), tier, scene_size=2.0, scene_bounds=bounds
            ).energy_w
            for x in got
        ]
        assert e[0] / e[1] == pytest.approx(0.5, abs=0.02), tier
        assert got[2].emission == pytest.approx(4 * math.cos(th), rel=1e-4)


def test_tier_primaries_carry_nominal_power_radius_and_colour():
    got = tier_primaries(
        [PointPrimary((0, 0, 0), 5.0, 0.2, (1, 0.5, 0)), SunPrimary((0, 0, -1), 3.0, 0.01)]
    )
    assert (got[0].power_w, got[0].radius, got[0].color) == (5.0, 0.2, (1.0, 0.5, 0.0))
    assert got[1].power_w == pytest.approx(4 * math.pi * 3.0) and got[1].radius == 0.0
