"""Phase 1 on every hard case of SPEC §5: a correct result or a clear, reported skip,
and never a NaN or an infinity in the output.

Expected values are computed independently of core/phase1/point_lights.py: the thesis' formulas
(SPEC §3) and the vergence form (SPEC §4.1) written out with `math`, a plain Snell's
law ray trace, and hand arithmetic.
"""

from __future__ import annotations

import json
import math

import pytest
from plain_vectors import vadd, vdot, vnorm, vscale, vsub, vunit

from core.phase1.point_lights import compute_phase1
from core.scene.model import Light, Scene, Sphere, Surface

# ------------------------------------------------------------ plain-Python references


def thesis_image_distance(p, R, n):
    """Eqs. 2.11, 5.8: image distance from the back vertex V2."""
    a, e = n - 1.0, 2.0 * R
    p1 = R * p * n / (p * a - R) - e
    return R * p1 / (p1 * a + n * R)


def thesis_focal(R, n):
    """Eq. 2.13."""
    a, e = n - 1.0, 2.0 * R
    p1f = -e + n * R / a
    return R * p1f / (p1f * a + n * R)


def vergence_image_from_center(D, R, n):
    """SPEC §4.1: 1/V, V = 2(n − 1)/(n R) − 1/D."""
    return 1.0 / (2.0 * (n - 1.0) / (n * R) - 1.0 / D)


def thesis_phi(alpha, n):
    return 2.0 * math.asin(1.0 / n) + alpha - math.pi / 2.0


def thesis_tan_theta(i, R, alpha, n, kind):
    """Eqs. 5.14 (real) and 5.21 (virtual) in their tangent form:
    cos θ = 1/sqrt(1 + x²) ⟺ tan θ = |x| (the cos form loses all digits for tiny θ)."""
    if kind == "real":
        phi = thesis_phi(alpha, n)
        return abs(R * math.sin(phi) / (i + R - R * math.cos(phi)))
    sigma = 1.5 * math.pi - alpha - 2.0 * math.asin(1.0 / n)
    return abs(R * math.sin(sigma) / (abs(i) - R - R * math.cos(sigma)))


def thesis_brightness(I0, R, n, kt):
    delta = math.asin(1.0 / n)
    return I0 * math.exp(-(1.0 - kt) * (2.0 * R + 2.0 * R * math.cos(delta)) / 2.0)


def _refract(d, N, eta):
    cos_i = -vdot(N, d)
    k = 1.0 - eta * eta * (1.0 - cos_i * cos_i)
    return vadd(vscale(d, eta), vscale(N, eta * cos_i - math.sqrt(k)))


def trace_axis_crossing(D, R, n, impact=1e-5):
    """Plain Snell's-law trace of a near-axis ray (2-D: z along the axis, y up);
    the exit line's axis crossing, from the centre."""
    o = (-D, 0.0)
    s = impact * R / D
    d = (math.sqrt(1.0 - s * s), s)
    t_mid = -vdot(o, d)
    foot = vadd(o, vscale(d, t_mid))
    p1 = vadd(o, vscale(d, t_mid - math.sqrt(R * R - vdot(foot, foot))))
    d1 = _refract(d, vscale(p1, 1.0 / R), 1.0 / n)
    p2 = vadd(p1, vscale(d1, -2.0 * vdot(p1, d1)))
    d2 = _refract(d1, vscale(p2, -1.0 / R), n)
    return p2[0] - p2[1] * d2[0] / d2[1]


# ------------------------------------------------------------ scenes and checks


def lens(center, radius, n=1.5, kt=1.0):
    return Sphere(
        center=tuple(float(c) for c in center),
        radius=radius,
        surface=Surface(transmission=kt, ior=n),
    )


def opaque(center, radius):
    return Sphere(
        center=tuple(float(c) for c in center),
        radius=radius,
        surface=Surface(transmission=0.0, ior=1.0),
    )


def scene(lights, objects):
    return Scene(
        lights=[lt if isinstance(lt, Light) else Light(position=tuple(lt)) for lt in lights],
        objects=list(objects),
    )


def run(sc, **kw):
    """compute_phase1 + the invariants every result must satisfy."""
    result = compute_phase1(sc, **kw)
    data = result.to_json()
    # allow_nan=False refuses NaN and ±inf anywhere, and non-JSON types raise too
    json.dumps(data, allow_nan=False)
    for s in result.sources:  # the extra fields, too
        for name in (
            "spread_deg",
            "intensity",
            "brightness_factor",
            "distance",
            "lens_radius",
            "ior",
            "vergence",
            "alpha_deg",
            "unblocked_fraction",
        ):
            assert math.isfinite(getattr(s, name)), (name, s)
        for name in ("image_distance", "magnification", "cylinder_radius"):
            v = getattr(s, name)
            assert v is None or math.isfinite(v), (name, s)
        assert s.kind in ("real", "virtual", "collimated")
        assert (s.cylinder_radius is not None) == (s.kind == "collimated")
        assert s.full == (s.shadow_list == [])
        assert vnorm(tuple(s.axis)) == pytest.approx(1.0, rel=1e-12)
    for k in result.skipped:
        assert isinstance(k.reason, str) and k.reason
    pairs = [(s.light, s.lens) for s in result.sources] + [
        (k.light, k.lens) for k in result.skipped
    ]
    assert len(pairs) == len(set(pairs)), "a pair reported twice"
    assert set(pairs) == {(j, i) for j in range(len(sc.lights)) for i in range(len(sc.objects))}
    return result


def source(result, light=0, lens_index=0):
    found = [s for s in result.sources if s.light == light and s.lens == lens_index]
    assert len(found) == 1, (result.sources, result.skipped)
    return found[0]


def reasons(result):
    return {(k.light, k.lens): k.reason for k in result.skipped}


def close_vec(actual, expected, tol):
    assert all(abs(float(a) - e) <= tol for a, e in zip(actual, expected, strict=False)), (
        list(actual),
        expected,
    )


# ============================================================ the focal point

# Lens: R = 1, n = 1.5 → front focal point at D0 = nR/(2(n − 1)) = 1.5 from the centre
# (p = f = 0.5 R). The light sits at D0 + ε R along an oblique axis.
FC = (0.3, -0.2, 0.7)
FU = vunit((1.0, 2.0, 2.0))
FR, FN, FKT = 1.0, 1.5, 0.8
D0 = FN * FR / (2 * (FN - 1))
EPSILONS = [s * 10.0**-k for k in range(1, 13) for s in (+1, -1)]


def focal_scene(eps):
    return scene([vsub(FC, vscale(FU, D0 + eps * FR))], [lens(FC, FR, FN, FKT)])


def test_focal_point_of_eq_2_13_is_where_the_vergence_vanishes():
    assert thesis_focal(FR, FN) == pytest.approx(D0 - FR, rel=1e-15)  # p = f


def test_light_exactly_at_the_focal_point_gives_a_collimated_beam():
    sc = focal_scene(0.0)
    s = source(run(sc))
    assert s.kind == "collimated"
    assert s.spread_deg == 0.0
    close_vec(s.position, vadd(FC, vscale(FU, FR)), 1e-12)  # back vertex V2
    close_vec(s.axis, FU, 1e-12)
    # eq. 5.10: R_C = |d| = R |sin φ|, α at D = D0
    alpha = math.acos(math.sqrt(D0**2 - FR**2) / D0)
    assert s.cylinder_radius == pytest.approx(abs(FR * math.sin(thesis_phi(alpha, FN))), rel=1e-9)
    assert s.intensity == pytest.approx(thesis_brightness(1.0, FR, FN, FKT), rel=1e-12)
    assert s.image_distance is None and s.magnification is None


@pytest.mark.parametrize("eps", EPSILONS)
def test_near_the_focal_point(eps):
    sc = focal_scene(eps)
    s = source(run(sc))
    L = sc.lights[0].position
    D = vnorm(vsub(FC, L))  # the distance as actually placed
    p = D - FR
    alpha = math.asin(FR / D)
    kind = "real" if eps > 0 else "virtual"
    if abs(eps) >= 1e-3:
        assert s.kind == kind  # no premature switch
    if abs(eps) <= 1e-9:
        assert s.kind == "collimated"  # the image is ≥ 1e9 R away
    if s.kind == "collimated":
        assert s.spread_deg == 0.0
        close_vec(s.position, vadd(FC, vscale(FU, FR)), 1e-12)
        assert s.cylinder_radius == pytest.approx(
            FR * abs(math.sin(thesis_phi(alpha, FN))), rel=1e-9
        )
    else:
        assert s.kind == kind
        i = thesis_image_distance(p, FR, FN)
        # the thesis' formula loses about 1e-16/|ε| relative near the focus
        rel = max(1e-9, 1e-14 / abs(eps))
        assert s.image_distance == pytest.approx(FR + i, rel=rel)
        assert s.image_distance == pytest.approx(vergence_image_from_center(D, FR, FN), rel=rel)
        close_vec(s.position, vadd(vadd(FC, vscale(FU, FR)), vscale(FU, i)), rel * abs(i) + 1e-12)
        theta = math.degrees(math.atan(thesis_tan_theta(i, FR, alpha, FN, kind)))
        assert s.spread_deg == pytest.approx(theta, rel=rel)
    assert s.intensity == pytest.approx(thesis_brightness(1.0, FR, FN, FKT), rel=1e-12)


@pytest.mark.parametrize("side", [+1, -1])
def test_spread_goes_to_zero_continuously_at_the_focal_point(side):
    spreads = [source(run(focal_scene(side * 10.0**-k))).spread_deg for k in range(1, 13)]
    kinds = [source(run(focal_scene(side * 10.0**-k))).kind for k in range(1, 13)]
    # never increases as the light approaches the focal point
    assert all(b <= a for a, b in zip(spreads, spreads[1:], strict=False)), spreads
    # once collimated, stays collimated (a single switch)
    first = kinds.index("collimated")
    assert all(k == "collimated" for k in kinds[first:])
    assert all(k != "collimated" for k in kinds[:first])
    # θ ∝ |ε| as ε → 0: at 1e-3 it is a tenth of that at 1e-2 within a few per cent,
    # and the last cone before the switch is already nearly a cylinder
    assert spreads[2] / spreads[1] == pytest.approx(0.1, rel=0.05)
    assert spreads[first - 1] < 0.01 and spreads[first] == 0.0
    assert 0.0 < spreads[first - 1]


def test_cylinder_radius_continues_the_cone_at_the_switch():
    """The last cone's radius at the exit circle equals the first cylinder's R_C
    (up to the change of α between the two light positions, ~1e-4 relative)."""
    for side in (+1, -1):
        srcs = [source(run(focal_scene(side * 10.0**-k))) for k in range(1, 13)]
        first = [s.kind for s in srcs].index("collimated")
        cone, cyl = srcs[first - 1], srcs[first]
        alpha = math.asin(FR / cone.distance)
        exit_axial = FR * math.cos(thesis_phi(alpha, FN))
        radius = abs(cone.image_distance - exit_axial) * math.tan(math.radians(cone.spread_deg))
        assert radius == pytest.approx(cyl.cylinder_radius, rel=1e-3)


# ============================================================ p·a = R


@pytest.mark.parametrize("n,R", [(1.5, 1.0), (1.5171, 0.7), (1.33, 2.0), (1.9, 0.05)])
def test_p_times_a_equals_R_gives_the_finite_image(n, R):
    """The thesis' p1 divides by zero; the image is finite: i → R/a (limit of 2.11),
    i.e. the mirror point of the light, D behind the centre (vergence 1/V = D)."""
    a = n - 1.0
    p = R / a
    D = p + R
    C = (1.0, 2.0, -3.0)
    u = vunit((-1.0, 0.5, 0.25))
    L = vsub(C, vscale(u, D))
    s = source(run(scene([L], [lens(C, R, n)])))
    Dact = vnorm(vsub(C, L))
    assert s.kind == "real"
    assert s.image_distance == pytest.approx(R + R / a, rel=1e-9)  # limit of the thesis
    assert s.image_distance == pytest.approx(vergence_image_from_center(Dact, R, n), rel=1e-12)
    assert s.image_distance == pytest.approx(D, rel=1e-9)  # the mirror point
    assert s.image_distance == pytest.approx(trace_axis_crossing(Dact, R, n), rel=1e-7)
    close_vec(s.position, vadd(C, vscale(u, D)), 1e-9 * D)
    assert s.magnification == pytest.approx(-1.0, rel=1e-9)
    # the thesis' formula on either side tends to the same point
    for side in (+1, -1):
        near = thesis_image_distance(p * (1 + side * 1e-7), R, n) + R
        assert near == pytest.approx(D, rel=1e-5)


# ============================================================ light on / in the sphere


LC, LR = (2.0, -1.0, 0.5), 1.3
LU = vunit((0.2, -1.0, 0.7))


@pytest.mark.parametrize(
    "D_over_R,reason",
    [
        (1.0, "light on the sphere's surface"),
        (1.0 + 1e-12, "light on the sphere's surface"),
        (1.0 - 1e-12, "light on the sphere's surface"),
        (0.5, "light inside the sphere"),
        (0.0, "light inside the sphere"),  # at the centre
    ],
)
def test_light_on_or_inside_the_sphere_is_skipped(D_over_R, reason):
    L = vsub(LC, vscale(LU, D_over_R * LR)) if D_over_R else LC
    result = run(scene([L], [lens(LC, LR)]))
    assert result.sources == []
    assert reasons(result) == {(0, 0): reason}


def test_light_just_outside_the_surface_is_a_virtual_source():
    D = LR * (1 + 1e-6)
    L = vsub(LC, vscale(LU, D))
    s = source(run(scene([L], [lens(LC, LR)])))
    Dact = vnorm(vsub(LC, L))
    assert s.kind == "virtual"
    assert s.image_distance == pytest.approx(vergence_image_from_center(Dact, LR, 1.5), rel=1e-8)
    assert s.image_distance == pytest.approx(
        thesis_image_distance(Dact - LR, LR, 1.5) + LR, rel=1e-8
    )


def test_light_inside_another_sphere_skips_the_lens_with_that_sphere_named():
    # light inside opaque sphere 1; lens 0 elsewhere gets no light
    result = run(scene([(0.0, 0.0, 0.0)], [lens((10, 0, 0), 1.0), opaque((0.2, 0, 0), 1.0)]))
    assert result.sources == []
    r = reasons(result)
    assert r[(0, 1)] == "opaque (kt = 0)"
    assert r[(0, 0)] == "light inside sphere 1"


def test_light_on_another_sphere_is_reported_or_finite():
    result = run(scene([(-1.0, 0.0, 0.0)], [lens((10, 0, 0), 1.0), opaque((0, 0, 0), 1.0)]))
    r = reasons(result)
    if (0, 0) in r:
        assert r[(0, 0)] == "light on the surface of sphere 1"


# ============================================================ index of refraction


@pytest.mark.parametrize("n,text", [(1.0, "n = 1 ≤ 1"), (0.75, "n = 0.75 ≤ 1"), (0.0, "n = 0 ≤ 1")])
def test_not_a_converging_lens(n, text):
    result = run(scene([(0, 0, 0)], [lens((5, 0, 0), 1.0, n=n, kt=0.9)]))
    assert result.sources == []
    reason = reasons(result)[(0, 0)]
    assert reason.startswith("not a converging lens")
    assert text in reason


def test_bubble_still_blocks_as_an_obstacle():
    # a diverging bubble (n < 1) is no lens, but it is a sphere in the way
    result = run(scene([(0, 0, 0)], [lens((10, 0, 0), 1.0), lens((4, 0.1, 0), 0.2, n=0.8, kt=1.0)]))
    assert source(result).shadow_list == [1]
    assert reasons(result)[(0, 1)].startswith("not a converging lens")


@pytest.mark.parametrize("D", [1.0001, 1.5, 5.0, 1e3])
def test_very_large_index_of_refraction(D):
    n, R = 1e6, 1.0
    C = (0.0, 1.0, 2.0)
    u = vunit((1.0, -1.0, 0.5))
    L = vsub(C, vscale(u, D))
    s = source(run(scene([L], [lens(C, R, n, kt=0.9)])))
    Dact = vnorm(vsub(C, L))
    # f = R(2 − n)/(2(n − 1)) < 0: every outside light is beyond the focal point
    assert s.kind == "real"
    assert s.image_distance == pytest.approx(vergence_image_from_center(Dact, R, n), rel=1e-9)
    assert s.image_distance == pytest.approx(thesis_image_distance(Dact - R, R, n) + R, rel=1e-6)
    close_vec(s.position, vadd(C, vscale(u, s.image_distance)), 1e-12)
    i = thesis_image_distance(Dact - R, R, n)
    theta = math.degrees(math.atan(thesis_tan_theta(i, R, math.asin(R / Dact), n, "real")))
    assert s.spread_deg == pytest.approx(theta, rel=1e-6, abs=1e-12)
    assert s.intensity == pytest.approx(thesis_brightness(1.0, R, n, 0.9), rel=1e-12)


# ============================================================ transmission


def test_kt_zero_is_opaque():
    result = run(scene([(0, 0, 0)], [lens((5, 0, 0), 1.0, kt=0.0)]))
    assert result.sources == []
    assert reasons(result) == {(0, 0): "opaque (kt = 0)"}


@pytest.mark.parametrize("n", [1.0001, 1.5, 3.0, 1e6])
def test_kt_one_has_no_absorption(n):
    result = run(
        Scene(
            lights=[Light(position=(0, 0, 0), brightness=2.75, color=(0.1, 0.2, 0.3))],
            objects=[lens((50, 0, 0), 3.0, n=n, kt=1.0)],
        )
    )
    s = source(result)
    assert s.brightness_factor == 1.0
    assert s.intensity == 2.75
    assert tuple(s.color) == pytest.approx((0.1, 0.2, 0.3), rel=1e-15)


def test_kt_above_one_is_reported():
    result = run(scene([(0, 0, 0)], [lens((5, 0, 0), 1.0, kt=1.5)]))
    assert result.sources == []
    assert reasons(result)[(0, 0)].startswith("invalid transmission")


# ============================================================ scale


def scaled_scene(s):
    """Light at the origin; lens 0 collimated (light at its focal point), lens 1 real
    and partly blocked by opaque sphere 3, lens 2 virtual. kt = 1 everywhere."""
    objects = [
        lens((0, 1.5 * s, 0), 1.0 * s),
        lens((10 * s, 0, 0), 1.0 * s, n=1.5171),
        lens((0, -1.2 * s, 0), 1.0 * s),
        opaque((5 * s, 0.35 * s, 0), 0.1 * s),
    ]
    return Scene(lights=[Light(position=(0.0, 0.0, 0.0), brightness=1.5)], objects=objects)


SCALES = [1e-4, 1e-2, 1.0, 1e2, 1e4]


@pytest.mark.parametrize("s", SCALES)
def test_scene_scaled_by_radius_1e_minus_4_to_1e4(s):
    ref = run(scaled_scene(1.0))
    got = run(scaled_scene(s))
    assert reasons(got) == reasons(ref)
    kinds = {(x.light, x.lens): x.kind for x in got.sources}
    assert kinds == {(x.light, x.lens): x.kind for x in ref.sources}
    assert kinds == {(0, 0): "collimated", (0, 1): "real", (0, 2): "virtual"}
    for key in kinds:
        g, r = source(got, *key), source(ref, *key)
        close_vec(g.position, vscale(tuple(r.position), s), 1e-9 * s * 20)
        close_vec(g.axis, tuple(r.axis), 1e-12)
        assert g.spread_deg == pytest.approx(r.spread_deg, rel=1e-9, abs=1e-12)
        assert g.alpha_deg == pytest.approx(r.alpha_deg, rel=1e-9)
        assert g.intensity == r.intensity == 1.5
        assert g.shadow_list == r.shadow_list
        assert g.unblocked_fraction == pytest.approx(r.unblocked_fraction, rel=1e-9)
        if r.cylinder_radius is None:
            assert g.cylinder_radius is None
            assert g.image_distance == pytest.approx(r.image_distance * s, rel=1e-9)
            assert g.magnification == pytest.approx(r.magnification, rel=1e-9)
        else:
            assert g.cylinder_radius == pytest.approx(r.cylinder_radius * s, rel=1e-9)
    # and the reference itself, by hand
    real = source(ref, 0, 1)
    assert real.shadow_list == [3]
    i = thesis_image_distance(9.0, 1.0, 1.5171)
    assert real.image_distance == pytest.approx(1.0 + i, rel=1e-10)
    virt = source(ref, 0, 2)
    assert virt.image_distance == pytest.approx(
        thesis_image_distance(0.2, 1.0, 1.5) + 1.0, rel=1e-10
    )


# ============================================================ very far lights


@pytest.mark.parametrize("n", [1.2, 1.5, 1.5171, 1.9])
@pytest.mark.parametrize("R", [1e-3, 1.0, 1e3])
def test_very_far_light_images_at_the_back_focal_point(n, R):
    C = (3.0 * R, -2.0 * R, 1.0 * R)
    u = vunit((0.3, 0.4, -1.0))
    D = 1e8 * R
    L = vsub(C, vscale(u, D))
    s = source(run(scene([L], [lens(C, R, n, kt=1.0)])))
    f = R * (2 - n) / (2 * (n - 1))  # from the back vertex
    assert s.kind == "real"
    # the true image is EFL²/D = (nR/(2(n−1)))²/D beyond the focal point: ~1e-8 R
    close_vec(s.position, vadd(C, vscale(u, R + f)), 1e-6 * R)
    close_vec(s.axis, u, 1e-12)
    # spreading angle of eq. 5.14 with α = asin(R/D) ≈ 1e-8 (cos α = R_T/D is 1 in floats)
    i = thesis_image_distance(D - R, R, n)
    assert i == pytest.approx(f, rel=1e-6)
    theta = math.degrees(math.atan(thesis_tan_theta(i, R, math.asin(R / D), n, "real")))
    assert s.spread_deg == pytest.approx(theta, rel=1e-7)
    assert s.alpha_deg == pytest.approx(math.degrees(R / D), rel=1e-7)


# ============================================================ obstacles


def test_obstacle_on_the_axis_bigger_than_the_lens_in_front_blocks_totally():
    result = run(scene([(0, 0, 0)], [lens((10, 0, 0), 1.0), opaque((5, 0, 0), 1.5)]))
    assert result.sources == []
    assert reasons(result)[(0, 0)] == "totally blocked by sphere 1"


def test_obstacle_on_the_axis_bigger_than_the_lens_behind_it_does_not_block():
    result = run(scene([(0, 0, 0)], [lens((10, 0, 0), 1.0), opaque((20, 0, 0), 3.0)]))
    s = source(result)
    assert s.full and s.shadow_list == [] and s.unblocked_fraction == 1.0


def test_obstacle_on_the_axis_smaller_than_the_lens_disc_is_partial():
    # β = asin(0.2/4) < α = asin(1/10): the prototype's |β − α| ≥ γ would drop it (§7)
    result = run(scene([(0, 0, 0)], [lens((10, 0, 0), 1.0), opaque((4, 0, 0), 0.2)]))
    s = source(result)
    assert s.shadow_list == [1] and not s.full
    alpha, beta = math.asin(0.1), math.asin(0.05)
    assert s.unblocked_fraction == pytest.approx(
        1 - (1 - math.cos(beta)) / (1 - math.cos(alpha)), rel=1e-10
    )


def test_overlapping_lenses():
    # intersecting spheres, the light outside both: the nearer one shades the other
    result = run(scene([(0, 0, 0)], [lens((6.5, 0.8, 0), 1.0), lens((5, 0, 0), 1.0)]))
    near, far = source(result, 0, 1), source(result, 0, 0)
    assert near.full and near.shadow_list == []
    assert far.shadow_list == [1] and 0 < far.unblocked_fraction < 1
    for s, C in ((near, (5, 0, 0)), (far, (6.5, 0.8, 0))):
        D = vnorm(C)
        assert s.image_distance == pytest.approx(
            thesis_image_distance(D - 1, 1.0, 1.5) + 1, rel=1e-10
        )


def test_light_inside_the_overlap_of_two_spheres():
    result = run(scene([(5.8, 0.4, 0)], [lens((6.5, 0.8, 0), 1.0), lens((5, 0, 0), 1.0)]))
    assert result.sources == []
    assert set(reasons(result).values()) == {"light inside the sphere"}


def test_nested_lenses_light_outside():
    # a lens inside a bigger lens: the outer one hides the inner one entirely
    result = run(scene([(0, 0, 0)], [lens((10, 0, 0), 0.5), lens((10, 0, 0), 2.0)]))
    outer = source(result, 0, 1)
    assert outer.full
    assert reasons(result) == {(0, 0): "totally blocked by sphere 1"}


def test_nested_lenses_light_between_them():
    result = run(scene([(10, 1.5, 0)], [lens((10, 0, 0), 0.5), lens((10, 0, 0), 2.0)]))
    assert result.sources == []
    assert reasons(result) == {(0, 0): "light inside sphere 1", (0, 1): "light inside the sphere"}


def test_two_lenses_blocking_each_other():
    # light 0 on the left sees A in front of B; light 1 on the right sees B in front of A
    result = run(scene([(-10, 2, 0), (10, 2, 0)], [lens((-2, 0, 0), 1.0), lens((2, 0, 0), 1.0)]))
    assert result.skipped == []
    assert source(result, 0, 0).full and source(result, 0, 1).shadow_list == [0]
    assert source(result, 1, 1).full and source(result, 1, 0).shadow_list == [1]


def test_many_lenses_in_a_row_along_the_light():
    # equal lenses on one line through the light: the nearest hides all the others
    objects = [lens((3.0 * (k + 2), 0, 0), 1.0) for k in range(12)]
    order = [7, 3, 11, 0, 5, 9, 1, 10, 2, 8, 6, 4]  # nearest is index 3
    objects = [objects[k] for k in order]
    result = run(scene([(0, 0, 0)], objects))
    assert len(result.sources) == 1
    s = result.sources[0]
    assert s.lens == 3 and s.full
    assert reasons(result) == {(0, k): "totally blocked by sphere 3" for k in range(12) if k != 3}


def test_many_lenses_in_a_row_growing():
    # each farther lens is seen under a slightly larger angle: every nearer one lies
    # inside its disc, so it is partly shaded by all the nearer ones; only the nearest is full
    objects = []
    for k in range(10):
        D = 10.0 * 2.0**k
        objects.append(lens((D, 0.0, 0.0), D * math.sin(0.05 * (1 + 0.1 * k))))
    result = run(scene([(0, 0, 0)], objects))
    assert result.skipped == []
    for k in range(10):
        s = source(result, 0, k)
        assert s.shadow_list == list(range(k))
        assert s.full == (k == 0)


# ============================================================ degenerate input


NAN, INF = float("nan"), float("inf")


@pytest.mark.parametrize(
    "bad,reason",
    [
        (
            Sphere(center=(5.0, 0.0, 0.0), radius=0.0, surface=Surface(transmission=0.9, ior=1.5)),
            "invalid sphere (radius 0 ≤ 0)",
        ),
        (
            Sphere(center=(5.0, 0.0, 0.0), radius=-1.0, surface=Surface(transmission=0.9, ior=1.5)),
            "invalid sphere (radius -1 ≤ 0)",
        ),
        (
            Sphere(center=(NAN, 0.0, 0.0), radius=1.0, surface=Surface(transmission=0.9, ior=1.5)),
            "invalid sphere (non-finite number)",
        ),
        (
            Sphere(center=(5.0, INF, 0.0), radius=1.0, surface=Surface(transmission=0.9, ior=1.5)),
            "invalid sphere (non-finite number)",
        ),
        (
            Sphere(center=(5.0, 0.0, 0.0), radius=INF, surface=Surface(transmission=0.9, ior=1.5)),
            "invalid sphere (non-finite number)",
        ),
        (
            Sphere(center=(5.0, 0.0, 0.0), radius=NAN, surface=Surface(transmission=0.9, ior=1.5)),
            "invalid sphere (non-finite number)",
        ),
        (
            Sphere(center=(5.0, 0.0, 0.0), radius=1.0, surface=Surface(transmission=0.9, ior=NAN)),
            "invalid sphere (non-finite number)",
        ),
        (
            Sphere(center=(5.0, 0.0, 0.0), radius=1.0, surface=Surface(transmission=0.9, ior=INF)),
            "invalid sphere (non-finite number)",
        ),
        (
            Sphere(center=(5.0, 0.0, 0.0), radius=1.0, surface=Surface(transmission=NAN, ior=1.5)),
            "invalid sphere (non-finite number)",
        ),
        (
            Sphere(center=(5.0, 0.0, 0.0), radius=0.0, surface=Surface(transmission=0.0, ior=1.0)),
            "invalid sphere (radius 0 ≤ 0)",
        ),
    ],
)
def test_invalid_sphere_is_reported_and_harmless(bad, reason):
    good = lens((20, 0, 0), 1.0, kt=0.9)
    alone = run(scene([(0, 0, 0)], [good]))
    result = run(scene([(0, 0, 0)], [bad, good]))
    assert reasons(result) == {(0, 0): reason}
    s, ref = source(result, 0, 1), source(alone, 0, 0)
    # the bad sphere (on the good lens's axis) neither blocks nor disturbs it
    assert s.full and s.unblocked_fraction == 1.0
    assert tuple(s.position) == tuple(ref.position) and s.spread_deg == ref.spread_deg
    assert s.kind == ref.kind and s.intensity == ref.intensity


@pytest.mark.parametrize(
    "light",
    [
        Light(position=(NAN, 0.0, 0.0)),
        Light(position=(0.0, INF, 0.0)),
        Light(position=(0.0, 0.0, -INF)),
        Light(position=(0.0, 0.0, 0.0), brightness=NAN),
        Light(position=(0.0, 0.0, 0.0), brightness=INF),
        Light(position=(0.0, 0.0, 0.0), color=(1.0, NAN, 0.0)),
    ],
)
def test_invalid_light_is_reported_per_sphere(light):
    objects = [lens((5, 0, 0), 1.0), opaque((0, 5, 0), 1.0)]
    result = run(Scene(lights=[light, Light(position=(-5.0, 0.0, 0.0))], objects=objects))
    r = reasons(result)
    assert r[(0, 0)] == r[(0, 1)] == "invalid light (non-finite number)"
    assert source(result, 1, 0).full  # the valid light is unaffected


def test_no_lights():
    result = run(scene([], [lens((5, 0, 0), 1.0), opaque((0, 5, 0), 1.0)]))
    assert result.sources == [] and result.skipped == []
    assert result.to_json() == {"sources": [], "skipped": []}


def test_no_spheres():
    result = run(scene([(0, 0, 0), (1, 2, 3)], []))
    assert result.sources == [] and result.skipped == []


def test_empty_scene():
    result = run(Scene())
    assert result.to_json() == {"sources": [], "skipped": []}


def test_only_invalid_things():
    objects = [
        Sphere(center=(NAN, NAN, NAN), radius=NAN),
        Sphere(center=(0.0, 0.0, 0.0), radius=-3.0),
        opaque((4, 0, 0), 1.0),
    ]
    result = run(
        Scene(
            lights=[Light(position=(INF, 0.0, 0.0)), Light(position=(0.0, 0.0, 0.0))],
            objects=objects,
        )
    )
    assert result.sources == []
    r = reasons(result)
    assert all(r[(0, k)] == "invalid light (non-finite number)" for k in range(3))
    assert r[(1, 0)] == "invalid sphere (non-finite number)"
    assert r[(1, 1)].startswith("invalid sphere (radius")
    assert r[(1, 2)] == "opaque (kt = 0)"
