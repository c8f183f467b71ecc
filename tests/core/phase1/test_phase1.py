"""Tests of phase 1 (core/phase1/point_lights.py): values, JSON shape and obstruction.

Every expected value here is computed independently of the code under test:

* the thesis' own formulas (SPEC §3: eqs. 2.11/2.13/5.8 for the image, 5.9–5.14 and
  5.21 for the spreading angle with the thesis' ``cos θ`` forms, 5.22 for the
  brightness, ``cos α = R_T / D`` for the radial angle), written out with ``math``;
* the vergence form of SPEC §4.1, written out again with ``math`` (the two are
  checked against each other, too);
* a plain-Python Snell's-law ray trace through the sphere (the paraxial limit of
  the exact optics of SPEC §6);
* spherical-cap areas by hand, a Monte-Carlo estimate and a 1-D quadrature for the
  obstruction fractions.

No helper of core/phase1/point_lights.py is used to compute an expectation; the ones that are
public API (``cap_overlap_fraction``) are only *tested* here.
"""

from __future__ import annotations

import json
import math
import re

import numpy as np
import pytest
from plain_vectors import vadd, vcross, vdot, vnorm, vscale, vsub, vunit

from core.lens.sphere_caps import cap_overlap_fraction
from core.phase1.point_lights import compute_phase1
from core.scene.model import Light, Scene, Sphere, Surface

# --------------------------------------------------------------------------- vectors
# (plain Python on purpose: the expectations must not share the code's numpy path)


def angle(a, b):
    """Angle between two directions, by hand (atan2 of |a×b| and a·b)."""
    return math.atan2(vnorm(vcross(a, b)), vdot(a, b))


def perpendicular(u):
    """A unit vector perpendicular to u."""
    other = (0.0, 0.0, 1.0) if abs(u[2]) < 0.9 else (1.0, 0.0, 0.0)
    return vunit(vcross(u, other))


# --------------------------------------------------------------------------- the thesis' formulas


def thesis_focal(R, n):
    """Eq. 2.13: back focal distance, from a vertex."""
    a, e = n - 1.0, 2.0 * R
    p1f = -e + n * R / a
    return R * p1f / (p1f * a + n * R)


def thesis_image_distance(p, R, n):
    """Eqs. 2.11 and 5.8: image distance i, measured from the back vertex V2."""
    a, e = n - 1.0, 2.0 * R
    p1 = R * p * n / (p * a - R) - e
    return R * p1 / (p1 * a + n * R)


def thesis_alpha(D, R):
    """Radial angle from the thesis' tangent construction: cos α = R_T / D."""
    R_T = math.sqrt(D * D - R * R)
    return math.acos(R_T / D)


def thesis_phi(alpha, n):
    """Eq. 5.9ff: angle of the exit point R from the back axis, φ = 2δ + α − 90°."""
    delta = math.asin(1.0 / n)
    return 2.0 * delta + alpha - math.pi / 2.0


def thesis_cos_theta_real(i, R, alpha, n):
    """Eq. 5.14: cos θ = 1 / sqrt(1 + (d / (i + R − R cos φ))²), d = R sin φ."""
    phi = thesis_phi(alpha, n)
    d = R * math.sin(phi)
    return 1.0 / math.sqrt(1.0 + (d / (i + R - R * math.cos(phi))) ** 2)


def thesis_cos_theta_virtual(i, R, alpha, n):
    """Eq. 5.21: σ = 270° − α − 2δ; cos θ = 1/sqrt(1 + (R sin σ/(|i| − R − R cos σ))²)."""
    delta = math.asin(1.0 / n)
    sigma = 1.5 * math.pi - alpha - 2.0 * delta
    return 1.0 / math.sqrt(1.0 + (R * math.sin(sigma) / (abs(i) - R - R * math.cos(sigma))) ** 2)


def thesis_brightness(I0, R, n, kt):
    """Eq. 5.22: I0 · exp(−(1 − kt)(2R + TR)/2), TR = 2R cos δ."""
    delta = math.asin(1.0 / n)
    TR = 2.0 * R * math.cos(delta)
    return I0 * math.exp(-(1.0 - kt) * (2.0 * R + TR) / 2.0)


def vergence_image_from_center(D, R, n):
    """SPEC §4.1: 1/V with V = P − 1/D, P = 2(n − 1)/(n R); signed, from the centre."""
    P = 2.0 * (n - 1.0) / (n * R)
    return 1.0 / (P - 1.0 / D)


def expected_source(light_pos, center, R, n, kt, brightness=1.0):
    """The secondary source as the thesis' text defines it (real or virtual only)."""
    D = vnorm(vsub(center, light_pos))
    u = vunit(vsub(center, light_pos))
    p = D - R
    f = thesis_focal(R, n)
    i = thesis_image_distance(p, R, n)
    V2 = vadd(center, vscale(u, R))
    alpha = thesis_alpha(D, R)
    kind = "real" if p > f else "virtual"
    if kind == "real":
        cos_t = thesis_cos_theta_real(i, R, alpha, n)
    else:
        cos_t = thesis_cos_theta_virtual(i, R, alpha, n)
    return {
        "kind": kind,
        "position": vadd(V2, vscale(u, i)),
        "axis": u,
        "spread_deg": math.degrees(math.acos(cos_t)),
        "intensity": thesis_brightness(brightness, R, n, kt),
        "image_distance": i + R,  # from the centre
        "distance": D,
        "alpha": alpha,
    }


# --------------------------------------------------------------------------- plain ray trace


def _refract(d, N, eta):
    """Snell's law in vector form; N faces the incident side (N·d < 0)."""
    cos_i = -vdot(N, d)
    k = 1.0 - eta * eta * (1.0 - cos_i * cos_i)
    assert k >= 0.0, "total internal reflection cannot happen in a ball lens"
    return vadd(vscale(d, eta), vscale(N, eta * cos_i - math.sqrt(k)))


def trace_axis_crossing(D, R, n, impact=1e-5):
    """Meridional ray from a point on the axis at distance D from the centre, with
    impact parameter `impact`·R, through the sphere by Snell's law; returns where
    its exit line crosses the axis (signed, from the centre, + away from the light)."""
    o = (-D, 0.0)  # (z along the axis, y height)
    sin_psi = impact * R / D
    d = (math.sqrt(1.0 - sin_psi * sin_psi), sin_psi)
    # entry: near root of |o + t d| = R (robust form: perpendicular distance)
    t_mid = -vdot(o, d)
    foot = vadd(o, vscale(d, t_mid))
    half_chord = math.sqrt(R * R - vdot(foot, foot))
    p1 = vadd(o, vscale(d, t_mid - half_chord))
    d1 = _refract(d, vscale(p1, 1.0 / R), 1.0 / n)
    # inside: the ray starts on the sphere, its other intersection is at t = −2 p1·d1
    p2 = vadd(p1, vscale(d1, -2.0 * vdot(p1, d1)))
    d2 = _refract(d1, vscale(p2, -1.0 / R), n)
    # the exit line z = p2.z + s d2.z, y = p2.y + s d2.y meets y = 0
    return p2[0] - p2[1] * d2[0] / d2[1]


# --------------------------------------------------------------------------- scenes


def rgb255(r, g, b):
    return (r / 255.0, g / 255.0, b / 255.0)


def lens(center, radius, n=1.5, kt=1.0, name=""):
    return Sphere(
        center=tuple(float(c) for c in center),
        radius=float(radius),
        surface=Surface(transmission=kt, ior=n),
        name=name,
    )


def opaque(center, radius, name=""):
    return Sphere(
        center=tuple(float(c) for c in center),
        radius=float(radius),
        surface=Surface(transmission=0.0, ior=1.0),
        name=name,
    )


def sphere(center, radius, color, ka, kd, ks, kt, E, n):
    return Sphere(
        center=center,
        radius=radius,
        surface=Surface(
            color=rgb255(*color),
            ambient=ka,
            diffuse=kd,
            specular=ks,
            transmission=kt,
            exponent=E,
            ior=n,
        ),
    )


def fig1():
    return Scene(
        lights=[Light(position=(10.0, 10.0, 10.0), color=rgb255(100, 100, 100), brightness=1.0)],
        objects=[
            sphere((3.0, 3.0, 3.0), 1.0, (100, 10, 10), 0.1, 0.2, 0, 0.7, 80, 1.5171),
            sphere((1.0, 1.0, -1.0), 2.0, (250, 0, 0), 0.1, 0.9, 0, 0, 70, 1.0),
        ],
        color_scale=255.0,
    )


def fig2():
    return Scene(
        lights=[Light(position=(-12.0, 12.0, 2.0), color=rgb255(100, 0, 0), brightness=1.0)],
        objects=[
            sphere((-4.5, 4.5, 1.5), 1.0, (10, 0, 100), 0.03, 0.02, 0.35, 0.6, 80, 1.5),
            sphere((0.0, 0.0, 0.0), 2.0, (0, 0, 100), 0.2, 0, 0.8, 0, 70, 1.0),
        ],
        color_scale=255.0,
    )


def fig3():
    return Scene(
        lights=[Light(position=(4.0, 13.0, 4.0), color=rgb255(100, 0, 0), brightness=1.0)],
        objects=[
            sphere((1.5, 7.0, 2.0), 0.25, (0, 0, 0), 0.2, 0.4, 0.4, 0, 80, 1.0),
            sphere((1.0, 6.0, 2.0), 1.0, (100, 100, 100), 0.1, 0, 0.4, 0.6, 80, 1.5),
            sphere((-1.0, 0.0, 0.0), 2.0, (100, 100, 100), 0.2, 0, 0.8, 0, 70, 1.0),
        ],
        color_scale=255.0,
    )


def one_lens_scene(light_pos, center, R, n, kt=1.0, brightness=1.0, color=(1.0, 1.0, 1.0)):
    return Scene(
        lights=[Light(position=tuple(light_pos), color=color, brightness=brightness)],
        objects=[lens(center, R, n, kt)],
    )


# --------------------------------------------------------------------------- checks


def all_numbers(obj):
    if isinstance(obj, bool) or obj is None or isinstance(obj, str):
        return
    if isinstance(obj, (int, float)):
        yield float(obj)
    elif isinstance(obj, dict):
        for v in obj.values():
            yield from all_numbers(v)
    elif isinstance(obj, (list, tuple)):
        for v in obj:
            yield from all_numbers(v)
    else:
        raise AssertionError(f"to_json() holds a non-JSON value {obj!r} ({type(obj)})")


def assert_finite_json(result):
    data = result.to_json()
    json.dumps(data, allow_nan=False)  # raises on NaN / inf
    assert all(math.isfinite(x) for x in all_numbers(data))
    return data


def assert_close_vec(actual, expected, rel=1e-9, abs_=1e-12):
    assert len(actual) == 3
    scale = max(1.0, max(abs(x) for x in expected))
    for a, e in zip(actual, expected, strict=False):
        assert float(a) == pytest.approx(e, rel=rel, abs=abs_ * scale), (actual, expected)


def only_source(result, light=0, lens=0):
    found = [s for s in result.sources if s.light == light and s.lens == lens]
    assert len(found) == 1, (result.sources, result.skipped)
    return found[0]


def skipped_pairs(result):
    return {(s.light, s.lens): s.reason for s in result.skipped}


def check_against_thesis(src, exp, rel=1e-9):
    assert src.kind == exp["kind"]
    assert_close_vec(src.position, exp["position"], rel=rel, abs_=rel)
    assert_close_vec(src.axis, exp["axis"], rel=1e-12, abs_=1e-12)
    assert src.spread_deg == pytest.approx(exp["spread_deg"], rel=rel, abs=1e-12)
    assert src.intensity == pytest.approx(exp["intensity"], rel=1e-12)
    assert src.cylinder_radius is None


# =========================================================================== the thesis' scenes


def test_fig1_one_real_full_source_by_the_thesis_formulas():
    result = compute_phase1(fig1())
    assert_finite_json(result)
    assert len(result.sources) == 1
    src = only_source(result, 0, 0)
    exp = expected_source((10, 10, 10), (3, 3, 3), 1.0, 1.5171, 0.7)
    check_against_thesis(src, exp)
    assert exp["kind"] == "real"
    assert src.full is True and src.shadow_list == []
    assert src.color == pytest.approx(rgb255(100, 100, 100), rel=1e-15)
    # hand values: D = 7√3, p = D − 1, α = asin(1/D)
    D = 7.0 * math.sqrt(3.0)
    assert src.distance == pytest.approx(D, rel=1e-14)
    assert src.alpha_deg == pytest.approx(math.degrees(math.asin(1.0 / D)), rel=1e-12)
    assert skipped_pairs(result) == {(0, 1): "opaque (kt = 0)"}


def test_fig2_one_real_full_source_by_the_thesis_formulas():
    result = compute_phase1(fig2())
    assert_finite_json(result)
    assert len(result.sources) == 1
    src = only_source(result, 0, 0)
    exp = expected_source((-12, 12, 2), (-4.5, 4.5, 1.5), 1.0, 1.5, 0.6)
    check_against_thesis(src, exp)
    assert exp["kind"] == "real"
    # the sphere behind it (farther tangent length) does not block
    assert src.full is True and src.shadow_list == []
    assert src.color == pytest.approx(rgb255(100, 0, 0), rel=1e-15)
    assert skipped_pairs(result) == {(0, 1): "opaque (kt = 0)"}


def test_fig3_one_real_non_full_source_shadowed_by_sphere_1():
    result = compute_phase1(fig3())
    assert_finite_json(result)
    assert len(result.sources) == 1
    src = only_source(result, 0, 1)
    exp = expected_source((4, 13, 4), (1, 6, 2), 1.0, 1.5, 0.6)
    check_against_thesis(src, exp)
    assert src.kind == "real"
    assert src.full is False and src.shadow_list == [0]
    # the thesis' rounded numbers
    assert src.spread_deg == pytest.approx(1.07, abs=0.006)
    assert src.intensity == pytest.approx(0.498, abs=6e-4)
    # hand arithmetic: D = √62, cos δ = √5/3, I = exp(−0.4·(1 + √5/3))
    assert src.intensity == pytest.approx(math.exp(-0.4 * (1.0 + math.sqrt(5.0) / 3.0)), rel=1e-13)
    assert src.brightness_factor == pytest.approx(src.intensity, rel=1e-15)
    assert src.distance == pytest.approx(math.sqrt(62.0), rel=1e-14)
    # the small opaque sphere lies wholly inside the lens's disc: blocked share = caps' ratio
    beta = math.asin(0.25 / math.sqrt(46.25))
    alpha = math.asin(1.0 / math.sqrt(62.0))
    blocked = math.sin(beta / 2) ** 2 / math.sin(alpha / 2) ** 2
    assert src.unblocked_fraction == pytest.approx(1.0 - blocked, rel=1e-10)
    assert skipped_pairs(result) == {(0, 0): "opaque (kt = 0)", (0, 2): "opaque (kt = 0)"}


def test_fig3_json_shape():
    data = json.loads(json.dumps(compute_phase1(fig3()).to_json(), allow_nan=False))
    assert set(data) >= {"sources", "skipped"}
    assert len(data["sources"]) == 1
    s = data["sources"][0]
    required = {
        "light",
        "lens",
        "kind",
        "position",
        "axis",
        "spread_deg",
        "cylinder_radius",
        "intensity",
        "color",
        "full",
        "shadow_list",
    }
    assert required <= set(s), required - set(s)
    assert s["light"] == 0 and type(s["light"]) is int
    assert s["lens"] == 1 and type(s["lens"]) is int
    assert s["kind"] == "real"
    for key in ("position", "axis", "color"):
        assert isinstance(s[key], list) and len(s[key]) == 3
        assert all(type(x) is float for x in s[key]), key
    assert type(s["spread_deg"]) is float and round(s["spread_deg"], 2) == 1.07
    assert s["cylinder_radius"] is None
    assert type(s["intensity"]) is float and round(s["intensity"], 3) == 0.498
    assert s["color"] == pytest.approx([100 / 255, 0.0, 0.0], rel=1e-15)
    assert s["full"] is False
    assert s["shadow_list"] == [0] and all(type(k) is int for k in s["shadow_list"])
    assert {"light": 0, "lens": 0, "reason": "opaque (kt = 0)"} in data["skipped"]
    for k in data["skipped"]:
        assert {"light", "lens", "reason"} <= set(k)
        assert type(k["light"]) is int and type(k["lens"]) is int and isinstance(k["reason"], str)


# =========================================================================== formulas cross-checked


SWEEP_N = [1.2, 1.5, 1.5171, 1.9, 2.5]
SWEEP_P = [0.05, 0.2, 0.4, 0.7, 1.3, 2.5, 10.0, 100.0]  # p / R; none at p·a = R or p = f


@pytest.mark.parametrize("n", SWEEP_N)
@pytest.mark.parametrize("p", SWEEP_P)
def test_thesis_two_surface_formula_equals_vergence_form(n, p):
    """The two independent expectations agree with each other (SPEC §4.1)."""
    R = 0.8
    i = thesis_image_distance(p * R, R, n)
    assert R + i == pytest.approx(vergence_image_from_center(p * R + R, R, n), rel=1e-11)
    # and the focal distance of eq. 2.13 is the closed form of §3.1
    assert thesis_focal(R, n) == pytest.approx(R * (2 - n) / (2 * (n - 1)), rel=1e-12)


@pytest.mark.parametrize("n", SWEEP_N)
@pytest.mark.parametrize("p", SWEEP_P)
def test_single_lens_matches_thesis_formulas(n, p):
    R = 0.8
    C = (0.3, -1.2, 2.0)
    u = vunit((2.0, -1.0, 2.0))
    L = vsub(C, vscale(u, p * R + R))
    result = compute_phase1(
        one_lens_scene(L, C, R, n, kt=0.75, brightness=2.5, color=(0.2, 0.4, 0.6))
    )
    assert_finite_json(result)
    assert result.skipped == []
    src = only_source(result)
    exp = expected_source(L, C, R, n, 0.75, brightness=2.5)
    check_against_thesis(src, exp, rel=1e-8)
    assert src.full and src.shadow_list == []
    assert src.color == pytest.approx((0.2, 0.4, 0.6), rel=1e-15)
    assert src.image_distance == pytest.approx(exp["image_distance"], rel=1e-8)
    assert src.magnification == pytest.approx(-exp["image_distance"] / exp["distance"], rel=1e-8)
    assert src.alpha_deg == pytest.approx(math.degrees(exp["alpha"]), rel=1e-10)
    assert src.brightness_factor == pytest.approx(thesis_brightness(1.0, R, n, 0.75), rel=1e-12)


def test_virtual_image_checked_against_eq_5_21():
    """Light nearer than the front focal point: p = 0.3 R < f = 0.5 R (n = 1.5)."""
    R, n = 1.0, 1.5
    C, L = (0.0, 0.0, 0.0), (-1.3, 0.0, 0.0)
    src = only_source(compute_phase1(one_lens_scene(L, C, R, n)))
    # by hand: p1 = 0.45/(0.15 − 1) − 2, i = p1/(0.5 p1 + 1.5)
    p1 = 0.45 / (0.15 - 1.0) - 2.0
    i = p1 / (0.5 * p1 + 1.5)
    assert i < -R  # virtual, on the light's side
    assert src.kind == "virtual"
    assert_close_vec(src.position, (R + i, 0.0, 0.0))
    assert src.position[0] == pytest.approx(vergence_image_from_center(1.3, R, n), rel=1e-12)
    alpha = math.acos(math.sqrt(1.3**2 - 1.0) / 1.3)
    delta = math.asin(1 / 1.5)
    sigma = math.radians(270.0) - alpha - 2 * delta
    cos_t = 1.0 / math.sqrt(1.0 + (R * math.sin(sigma) / (abs(i) - R - R * math.cos(sigma))) ** 2)
    assert src.spread_deg == pytest.approx(math.degrees(math.acos(cos_t)), rel=1e-10)
    assert 3.7 < src.spread_deg < 3.9  # ≈ 3.79°, hand arithmetic
    assert src.magnification > 0  # virtual: upright


def test_real_and_virtual_spread_formulas_are_the_cone_through_the_exit_circle():
    """θ is the half-angle of the cone with apex I through the exit circle (§3.3)."""
    R, n = 1.0, 1.5
    for D in (1.2, 1.45, 1.55, 2.0, 3.0, 7.0):
        L, C = (0.0, 0.0, -D), (0.0, 0.0, 0.0)
        src = only_source(compute_phase1(one_lens_scene(L, C, R, n)))
        alpha = math.asin(R / D)
        phi = 2 * math.asin(1 / n) + alpha - math.pi / 2
        exit_z, exit_h = R * math.cos(phi), R * math.sin(phi)  # exit circle
        apex_z = src.position[2]
        assert math.degrees(math.atan2(abs(exit_h), abs(apex_z - exit_z))) == pytest.approx(
            src.spread_deg, rel=1e-9
        )


# =========================================================================== paraxial limit


PARAXIAL_CASES = [
    (1.5171, 1.0, 12.124355652982141),  # fig1's lens and distance
    (1.5, 1.0, math.sqrt(62.0)),  # fig3's
    (1.5, 1.0, 3.0),  # p·a = R
    (1.5, 1.0, 1.3),  # virtual
    (1.5, 1.0, 1.05),  # virtual, light close to the surface
    (1.3, 2.0, 25.0),
    (1.8, 0.5, 0.9),
    (2.5, 1.0, 4.0),  # n > 2: image inside the sphere
]


@pytest.mark.parametrize("n,R,D", PARAXIAL_CASES)
def test_source_is_the_paraxial_limit_of_a_traced_ray(n, R, D):
    crossing = trace_axis_crossing(D, R, n, impact=1e-5)
    C = (1.0, -2.0, 0.5)
    u = vunit((1.0, 1.0, -1.0))
    L = vsub(C, vscale(u, D))
    src = only_source(compute_phase1(one_lens_scene(L, C, R, n)))
    assert_close_vec(src.position, vadd(C, vscale(u, crossing)), rel=1e-7, abs_=1e-7)
    # and the ray is converging (real) iff the crossing is ahead of the light
    assert (src.kind == "real") == (crossing > 0)


def test_ray_trace_reference_is_sound():
    """The plain trace itself: at larger impact it shows the spherical aberration
    the SPEC describes (marginal rays cross nearer), paraxially it converges."""
    near = trace_axis_crossing(10.0, 1.0, 1.5, impact=1e-5)
    mid = trace_axis_crossing(10.0, 1.0, 1.5, impact=0.3)
    far = trace_axis_crossing(10.0, 1.0, 1.5, impact=0.9)
    assert far < mid < near
    assert near == pytest.approx(vergence_image_from_center(10.0, 1.0, 1.5), rel=1e-8)


# =========================================================================== obstruction


LIGHT = (0.5, -0.25, 1.0)
E1 = vunit((1.0, 0.3, -0.2))
E2 = perpendicular(E1)


def placed(distance, radial, gamma=0.0, kind="opaque", n=1.5):
    """A sphere seen from LIGHT at `distance` (centre), under radial angle `radial`,
    its centre `gamma` away from the axis E1 (in the plane of E1, E2)."""
    direction = vadd(vscale(E1, math.cos(gamma)), vscale(E2, math.sin(gamma)))
    center = vadd(LIGHT, vscale(direction, distance))
    radius = distance * math.sin(radial)
    return lens(center, radius, n=n) if kind == "lens" else opaque(center, radius)


def obstruction_scene(*obstacles, lens_distance=10.0, alpha=0.1):
    return Scene(
        lights=[Light(position=LIGHT)],
        objects=[placed(lens_distance, alpha, kind="lens"), *obstacles],
    )


def test_partial_obstruction_puts_the_obstacle_in_the_shadow_list():
    result = compute_phase1(obstruction_scene(placed(4.0, 0.05, gamma=0.12)))
    assert_finite_json(result)
    src = only_source(result)
    assert src.full is False and src.shadow_list == [1]
    assert 0.0 < src.unblocked_fraction < 1.0


def test_total_obstruction_skips_the_source():
    result = compute_phase1(obstruction_scene(placed(3.0, 0.2, gamma=0.05)))
    assert_finite_json(result)
    assert result.sources == []
    assert skipped_pairs(result) == {
        (0, 0): "totally blocked by sphere 1",
        (0, 1): "opaque (kt = 0)",
    }


def test_obstacle_behind_the_lens_is_ignored():
    # a far bigger disc around the lens, but farther than its lit cap
    result = compute_phase1(obstruction_scene(placed(40.0, 0.3, gamma=0.02)))
    src = only_source(result)
    assert src.full is True and src.shadow_list == []
    assert src.unblocked_fraction == 1.0


def test_obstacle_off_axis_is_ignored():
    result = compute_phase1(obstruction_scene(placed(4.0, 0.05, gamma=0.16)))
    src = only_source(result)
    assert src.full is True and src.shadow_list == []


REL = 1e-9


@pytest.mark.parametrize("side", [-1, +1])
def test_boundary_alpha_plus_beta_equals_gamma(side):
    """α + β = γ: the discs touch. γ slightly smaller → partial; larger → ignored."""
    alpha, beta = 0.1, 0.05
    gamma = (alpha + beta) * (1.0 + side * REL)
    result = compute_phase1(obstruction_scene(placed(4.0, beta, gamma=gamma), alpha=alpha))
    assert_finite_json(result)
    src = only_source(result)
    if side < 0:
        assert src.full is False and src.shadow_list == [1]
        assert 0.0 <= 1.0 - src.unblocked_fraction < 1e-6  # a sliver
    else:
        assert src.full is True and src.shadow_list == []
        assert src.unblocked_fraction == 1.0


@pytest.mark.parametrize("side", [-1, +1])
def test_boundary_beta_equals_gamma_plus_alpha(side):
    """β = γ + α: the obstacle's disc just covers the lens's. β slightly larger →
    total (no source); slightly smaller → partial (non-full source)."""
    alpha, gamma = 0.1, 0.05
    beta = (gamma + alpha) * (1.0 + side * REL)
    result = compute_phase1(obstruction_scene(placed(3.0, beta, gamma=gamma), alpha=alpha))
    assert_finite_json(result)
    if side > 0:
        assert result.sources == []
        assert skipped_pairs(result)[(0, 0)] == "totally blocked by sphere 1"
    else:
        src = only_source(result)
        assert src.full is False and src.shadow_list == [1]
        assert 0.0 <= src.unblocked_fraction < 1e-6  # almost all blocked


@pytest.mark.parametrize("side", [-1, +1])
def test_boundary_of_the_distance_test(side):
    """R_T,k = R_T,i: only an obstacle strictly nearer to the light can block."""
    alpha, beta, gamma, Di = 0.1, 0.05, 0.1, 10.0
    RT_lens = Di * math.cos(alpha)
    RT_obst = RT_lens * (1.0 + side * REL)
    Dk = RT_obst / math.cos(beta)
    result = compute_phase1(
        obstruction_scene(placed(Dk, beta, gamma=gamma), lens_distance=Di, alpha=alpha)
    )
    src = only_source(result)
    if side < 0:
        assert src.shadow_list == [1] and src.full is False
    else:
        assert src.shadow_list == [] and src.full is True


def test_nearest_total_blocker_is_reported():
    # indices: 0 lens (D 10), 1 total blocker at D 6, 2 total blocker at D 3 (nearest),
    # 3 a partial one; 2 must be named
    result = compute_phase1(
        obstruction_scene(placed(6.0, 0.3), placed(3.0, 0.25), placed(8.0, 0.02, gamma=0.1))
    )
    assert result.sources == []
    assert skipped_pairs(result)[(0, 0)] == "totally blocked by sphere 2"
    # and with the order of the two blockers swapped, still the nearest
    result = compute_phase1(
        obstruction_scene(placed(3.0, 0.25), placed(6.0, 0.3), placed(8.0, 0.02, gamma=0.1))
    )
    assert skipped_pairs(result)[(0, 0)] == "totally blocked by sphere 1"


@pytest.mark.parametrize("gamma", [0.0, 0.02, 0.05])
def test_small_obstacle_inside_the_lens_disc_is_partial_not_total(gamma):
    """SPEC §7: the prototype's |β − α| ≥ γ fires here; the text's β ≥ γ + α does not."""
    alpha, beta = 0.1, 0.03
    assert abs(beta - alpha) >= gamma  # the prototype would drop it
    result = compute_phase1(obstruction_scene(placed(4.0, beta, gamma=gamma), alpha=alpha))
    src = only_source(result)
    assert src.full is False and src.shadow_list == [1]
    # wholly inside: the blocked share is the ratio of the caps' solid angles
    blocked = (1 - math.cos(beta)) / (1 - math.cos(alpha))
    assert src.unblocked_fraction == pytest.approx(1.0 - blocked, rel=1e-9)


def test_fig3_is_itself_a_prototype_bug_case():
    """In fig3 the small sphere 1 lies inside the glass sphere's disc."""
    L, C1, C2 = (4, 13, 4), (1.5, 7, 2), (1, 6, 2)
    alpha = math.asin(1.0 / vnorm(vsub(C2, L)))
    beta = math.asin(0.25 / vnorm(vsub(C1, L)))
    gamma = angle(vsub(C1, L), vsub(C2, L))
    assert abs(beta - alpha) >= gamma and not beta >= gamma + alpha
    assert only_source(compute_phase1(fig3()), 0, 1).shadow_list == [0]


@pytest.mark.parametrize("side", [-1, +1])
def test_grazing_pairs_in_every_direction_and_size(side):
    """Discs that just touch (α + β = γ ∓ 1e-9 relative), the obstacle displaced along
    a coordinate axis (where a box-based search is tightest), at many azimuths and
    apparent sizes: every touching pair is found, no separated one is."""
    rng = np.random.default_rng(5)
    objects, pairs = [], []
    for m in range(40):
        az = 2 * math.pi * m / 40
        alpha = float(rng.uniform(0.002, 0.04))
        beta = float(rng.uniform(0.001, 0.03))
        gamma = (alpha + beta) * (1 + side * REL)
        Dl, Do = float(rng.uniform(20, 60)), float(rng.uniform(3, 15))
        wl = (math.cos(az), math.sin(az), 0.0)
        sign = 1.0 if m % 2 else -1.0
        wo = (
            math.cos(az) * math.cos(gamma),
            math.sin(az) * math.cos(gamma),
            sign * math.sin(gamma),
        )
        objects.append(lens(vscale(wl, Dl), Dl * math.sin(alpha)))
        objects.append(opaque(vscale(wo, Do), Do * math.sin(beta)))
        pairs.append((2 * m, 2 * m + 1))
    result = compute_phase1(Scene(lights=[Light(position=(0.0, 0.0, 0.0))], objects=objects))
    for i, k in pairs:
        src = only_source(result, 0, i)
        assert src.shadow_list == ([k] if side < 0 else []), (i, src.shadow_list)


def plain_obstruction(light, spheres):
    """The thesis' §3.5 tests as a plain double loop (no broad phase, no numpy).

    spheres: list of (center, radius, is_lens). Returns {lens: ("total", set of
    nearest total blockers) | ("partial", sorted shadow list) | None (near a boundary:
    not compared)}, for the lenses the light is outside of, or None when the light
    is inside / on some sphere."""
    geo = []
    for c, r, _ in spheres:
        w = vsub(c, light)
        D = vnorm(w)
        if D <= r * (1 + 1e-6):
            return None
        geo.append((w, math.asin(r / D), math.sqrt(D * D - r * r)))
    out = {}
    for i, (_, _, is_lens) in enumerate(spheres):
        if not is_lens:
            continue
        wi, alpha, ti = geo[i]
        totals, shadow, doubtful = [], [], False
        for k, (wk, beta, tk) in enumerate(geo):
            if k == i:
                continue
            gamma = angle(wi, wk)
            near_edge = (
                abs(tk - ti) <= 1e-9 * ti
                or abs(alpha + beta - gamma) <= 1e-9
                or abs(beta - gamma - alpha) <= 1e-9
            )
            doubtful |= near_edge
            if tk < ti and alpha + beta >= gamma:
                (totals if beta >= gamma + alpha else shadow).append((tk, k))
        if doubtful:
            out[i] = None
        elif totals:
            nearest = min(t for t, _ in totals)
            out[i] = ("total", {k for t, k in totals if t == nearest})
        else:
            out[i] = ("partial", sorted(k for _, k in shadow))
    return out


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_obstruction_matches_a_plain_loop_on_a_random_scene(seed):
    """Many spheres of very different apparent sizes (tiny far ones, a few huge near
    ones): the code's result equals the thesis' double loop written out here."""
    rng = np.random.default_rng(seed)
    spheres = []
    for _ in range(150):
        c = tuple(float(x) for x in rng.uniform(-30, 30, 3))
        spheres.append((c, float(rng.uniform(0.05, 1.5)), bool(rng.random() < 0.5)))
    for _ in range(4):  # big spheres
        c = tuple(float(x) for x in rng.uniform(-20, 20, 3))
        spheres.append((c, float(rng.uniform(3.0, 6.0)), bool(rng.random() < 0.5)))
    lights = [tuple(float(x) for x in rng.uniform(-25, 25, 3)) for _ in range(5)]
    # a light close to a big sphere sees it under a huge angle
    c, r, _ = spheres[-1]
    lights.append(vadd(c, (r * 1.05, 0.0, 0.0)))
    sc = Scene(
        lights=[Light(position=p) for p in lights],
        objects=[
            lens(c, r, n=1.5, kt=0.9) if is_lens else opaque(c, r) for c, r, is_lens in spheres
        ],
    )
    result = compute_phase1(sc)
    assert_finite_json(result)
    compared = 0
    for j, L in enumerate(lights):
        expected = plain_obstruction(L, spheres)
        if expected is None:
            continue
        got_sources = {s.lens: s for s in result.sources if s.light == j}
        got_skips = {k.lens: k.reason for k in result.skipped if k.light == j}
        for i, exp in expected.items():
            if exp is None:
                continue
            compared += 1
            if exp[0] == "total":
                m = re.fullmatch(r"totally blocked by sphere (\d+)", got_skips.get(i, ""))
                assert m and int(m.group(1)) in exp[1], (j, i, got_skips.get(i), exp)
            else:
                assert i in got_sources, (j, i, got_skips.get(i), exp)
                assert sorted(got_sources[i].shadow_list) == exp[1], (j, i)
                assert got_sources[i].full == (exp[1] == [])
    assert compared > 300
    # the scene does exercise all three outcomes
    assert any(s.full for s in result.sources) and any(not s.full for s in result.sources)
    assert any(k.reason.startswith("totally blocked") for k in result.skipped)


# --------------------------------------------------------------------------- cap overlap


def cap_overlap_quadrature(alpha, beta, gamma, m=200_000):
    """Share of cap α (about z) inside cap β (centre γ from z): midpoint rule over
    the polar angle θ about the lens's centre, the azimuth range by hand."""
    h = alpha / m
    th = (np.arange(m) + 0.5) * h
    if gamma == 0.0:
        width = np.where(th <= beta, 2 * np.pi, 0.0)
    else:
        c = (math.cos(beta) - np.cos(th) * math.cos(gamma)) / (np.sin(th) * math.sin(gamma))
        width = 2.0 * np.arccos(np.clip(c, -1.0, 1.0))
    covered = float(np.sum(np.sin(th) * width) * h)
    return covered / (4 * math.pi * math.sin(alpha / 2) ** 2)


def cap_overlap_monte_carlo(alpha, beta, gamma, n=400_000, seed=20240607):
    rng = np.random.default_rng(seed)
    cos_t = 1.0 - rng.random(n) * 2.0 * math.sin(alpha / 2) ** 2  # uniform in solid angle
    sin_t = np.sqrt(np.maximum(0.0, 1.0 - cos_t * cos_t))
    phi = rng.random(n) * 2 * np.pi
    dots = sin_t * np.cos(phi) * math.sin(gamma) + cos_t * math.cos(gamma)
    return float(np.mean(dots >= math.cos(beta))), n


CAP_CASES = [
    (0.3, 0.2, 0.4),  # partial
    (0.3, 0.1, 0.1),  # obstacle inside the lens's disc
    (0.2, 0.5, 0.25),  # lens covered
    (0.2, 0.1, 0.35),  # disjoint
    (0.5, 0.3, 0.4),  # obstacle centre inside, disc sticking out
    (0.3, 0.8, 0.6),  # big obstacle, most of the lens covered
    (0.5, 0.5, 0.9),  # equal radii
    (1.2, 0.9, 1.6),  # large caps (spherical, not planar, geometry)
    (1.0, 1.4, 0.5),  # near-hemispherical obstacle
    (0.01, 0.008, 0.012),  # tiny caps
    (0.1, 0.03, 0.0),  # concentric, contained
]


@pytest.mark.parametrize("alpha,beta,gamma", CAP_CASES)
def test_cap_overlap_fraction_against_monte_carlo(alpha, beta, gamma):
    got = float(cap_overlap_fraction(alpha, beta, gamma))
    mc, n = cap_overlap_monte_carlo(alpha, beta, gamma)
    sigma = math.sqrt(max(mc * (1 - mc), 1.0 / n) / n)
    assert got == pytest.approx(mc, abs=5 * sigma + 1e-12)
    assert got == pytest.approx(cap_overlap_quadrature(alpha, beta, gamma), abs=2e-6)
    assert 0.0 <= got <= 1.0


def test_cap_overlap_fraction_broadcasts():
    a = np.array([c[0] for c in CAP_CASES])
    b = np.array([c[1] for c in CAP_CASES])
    g = np.array([c[2] for c in CAP_CASES])
    got = cap_overlap_fraction(a, b, g)
    assert got.shape == a.shape
    for k, case in enumerate(CAP_CASES):
        assert got[k] == pytest.approx(cap_overlap_quadrature(*case), abs=2e-6)


def test_unblocked_fraction_of_a_partly_blocked_source():
    alpha, beta, gamma = 0.1, 0.05, 0.12
    src = only_source(
        compute_phase1(obstruction_scene(placed(4.0, beta, gamma=gamma), alpha=alpha))
    )
    expected = 1.0 - cap_overlap_quadrature(alpha, beta, gamma)
    assert src.unblocked_fraction == pytest.approx(expected, abs=2e-6)


# --------------------------------------------------------------------------- order independence


def rich_scene():
    lights = [
        Light(position=(0.0, 0.0, 0.0), color=(1.0, 0.9, 0.8), brightness=1.0),
        Light(position=(0.0, 20.0, 0.0), color=(0.5, 0.5, 1.0), brightness=3.0),
        Light(position=(-6.0, -6.0, 1.0), brightness=0.5),
    ]
    objects = [
        lens((10, 0, 0), 1.0, n=1.5, kt=0.9),  # 0
        opaque((4, 0.3, 0), 0.2),  # 1: partial for 0
        lens((20, 0, 0), 1.5, n=1.6, kt=0.8),  # 2: behind 0 (total)
        lens((0, 10, 5), 1.0, n=1.5171, kt=0.7),  # 3
        opaque((-5, -5, 0), 2.0),  # 4: light 2 sits inside
        lens((10, 3, 0), 1.0, n=1.4, kt=0.5),  # 5
        lens((2.5, 1.0, 0), 1.0, n=1.2, kt=1.0),  # 6: near the light
        lens((6, 0.2, 0.1), 0.4, n=1.5, kt=0.95),  # 7: partial for 0
        opaque((0, 15, 2.5), 0.5),  # 8: between light 1 and lens 3
        lens((0, 30, 0), 1.0, n=1.5, kt=0.6),  # 9
        Sphere(
            center=(50.0, 50.0, 50.0), radius=-1.0, surface=Surface(transmission=0.5, ior=1.5)
        ),  # 10
        lens((0, 0, 1.5), 1.0, n=1.5, kt=1.0),  # 11: collimated for light 0
    ]
    rng = np.random.default_rng(7)
    for _ in range(14):
        c = tuple(float(x) for x in rng.uniform(-25, 25, 3))
        r = float(rng.uniform(0.2, 2.0))
        if rng.random() < 0.6:
            objects.append(
                lens(c, r, n=float(rng.uniform(1.1, 2.4)), kt=float(rng.uniform(0.3, 1)))
            )
        else:
            objects.append(opaque(c, r))
    return Scene(lights=lights, objects=objects)


def _canonical(result, to_original):
    """Sources and skips keyed by original sphere indices."""

    def remap_reason(reason):
        return re.sub(r"sphere (\d+)$", lambda m: f"sphere {to_original[int(m.group(1))]}", reason)

    sources = {}
    for s in result.sources:
        sources[(s.light, to_original[s.lens])] = s
    skipped = {(k.light, to_original[k.lens]): remap_reason(k.reason) for k in result.skipped}
    return sources, skipped


def test_shuffling_the_spheres_gives_the_same_sources():
    base = rich_scene()
    ref_sources, ref_skipped = _canonical(compute_phase1(base), list(range(len(base.objects))))
    # the scene is rich enough to exercise everything
    kinds = {s.kind for s in ref_sources.values()}
    assert {"real", "virtual", "collimated"} <= kinds
    assert any(not s.full for s in ref_sources.values())
    assert any(r.startswith("totally blocked") for r in ref_skipped.values())
    assert any(r.startswith("light inside sphere") for r in ref_skipped.values())
    rng = np.random.default_rng(11)
    for _ in range(6):
        perm = [int(x) for x in rng.permutation(len(base.objects))]
        shuffled = Scene(lights=base.lights, objects=[base.objects[k] for k in perm])
        result = compute_phase1(shuffled)
        sources, skipped = _canonical(result, perm)
        assert skipped == ref_skipped
        assert sources.keys() == ref_sources.keys()
        for key, s in sources.items():
            r = ref_sources[key]
            assert s.kind == r.kind and s.full == r.full
            assert sorted(perm[k] for k in s.shadow_list) == sorted(r.shadow_list)
            assert_close_vec(s.position, r.position, rel=1e-12, abs_=1e-12)
            assert_close_vec(s.axis, r.axis, rel=1e-12, abs_=1e-12)
            assert s.spread_deg == pytest.approx(r.spread_deg, rel=1e-12, abs=1e-15)
            assert s.intensity == pytest.approx(r.intensity, rel=1e-12)
            assert s.unblocked_fraction == pytest.approx(r.unblocked_fraction, rel=1e-12, abs=1e-15)
            if r.cylinder_radius is None:
                assert s.cylinder_radius is None
            else:
                assert s.cylinder_radius == pytest.approx(r.cylinder_radius, rel=1e-12)


def test_every_pair_is_either_a_source_or_skipped():
    scene = rich_scene()
    result = compute_phase1(scene)
    assert_finite_json(result)
    pairs = [(s.light, s.lens) for s in result.sources] + [
        (k.light, k.lens) for k in result.skipped
    ]
    assert len(pairs) == len(set(pairs))
    assert set(pairs) == {
        (j, i) for j in range(len(scene.lights)) for i in range(len(scene.objects))
    }
