"""Snell and Fresnel of `core.lens.refraction` against values by hand."""

import math

import numpy as np
import pytest

from core.lens.refraction import (
    fresnel_reflectance,
    fresnel_transmittance,
    refract,
)


def _ray(angle):
    """Unit direction at ``angle`` to the normal (0, 0, 1), going down into z < 0."""
    return np.array([math.sin(angle), 0.0, -math.cos(angle)])


@pytest.mark.parametrize("n1, n2", [(1.0, 1.5), (1.5, 1.0), (1.0, 2.4), (1.33, 1.0)])
def test_refraction_obeys_snell_by_angles(n1, n2):
    up = np.array([0.0, 0.0, 1.0])
    crit = math.asin(n2 / n1) if n1 > n2 else math.pi / 2
    for angle in np.linspace(0.0, 0.999 * crit, 13):
        out = refract(_ray(angle), up, n1 / n2)
        t = out.directions
        assert np.linalg.norm(t) == pytest.approx(1.0, abs=1e-15)
        want = math.asin(n1 * math.sin(angle) / n2)
        assert math.atan2(t[0], -t[2]) == pytest.approx(want, abs=1e-13)
        assert float(out.cos_i) == pytest.approx(math.cos(angle), abs=1e-15)
        assert float(out.cos_t) == pytest.approx(math.cos(want), abs=1e-13)
        assert not out.tir and t[1] == 0.0


def test_total_internal_reflection_is_flagged_beyond_the_critical_angle():
    n1, n2 = 1.5, 1.0
    crit = math.asin(n2 / n1)
    d = np.stack([_ray(a) for a in (crit - 1e-6, crit + 1e-6, 1.2)])
    out = refract(d, np.array([0.0, 0.0, 1.0]), n1 / n2)
    np.testing.assert_array_equal(out.tir, [False, True, True])
    assert np.all(out.cos_t[1:] == 0.0)  # the grazing direction, still a unit vector
    np.testing.assert_allclose(np.linalg.norm(out.directions, axis=1), 1.0, rtol=1e-15)
    t_s, t_p = fresnel_transmittance(out.cos_i, n1, n2)
    assert t_s[0] > 0 and t_p[0] > 0 and np.all(t_s[1:] == 0.0) and np.all(t_p[1:] == 0.0)
    r_s, r_p = fresnel_reflectance(out.cos_i[1:], n1, n2)
    assert np.all(r_s == 1.0) and np.all(r_p == 1.0)


@pytest.mark.parametrize("n", [1.33, 1.5, 1.9, 2.42])
def test_fresnel_at_normal_incidence(n):
    r0 = ((n - 1.0) / (n + 1.0)) ** 2
    for n1, n2 in ((1.0, n), (n, 1.0)):
        r_s, r_p = fresnel_reflectance(1.0, n1, n2)
        assert float(r_s) == pytest.approx(r0, rel=1e-14)
        assert float(r_p) == pytest.approx(r0, rel=1e-14)
        t_s, t_p = fresnel_transmittance(1.0, n1, n2)
        assert float(0.5 * (t_s + t_p)) == pytest.approx(1 - r0, rel=1e-14)


@pytest.mark.parametrize("n1, n2", [(1.0, 1.5), (1.5, 1.0), (1.0, 1.33)])
def test_brewster_angle_reflects_no_p_light(n1, n2):
    brewster = math.atan(n2 / n1)
    r_s, r_p = fresnel_reflectance(math.cos(brewster), n1, n2)
    assert float(r_p) == pytest.approx(0.0, abs=1e-30)
    assert float(r_s) > 0.01
    t_s, t_p = fresnel_transmittance(math.cos(brewster), n1, n2)
    assert float(t_p) == pytest.approx(1.0, abs=1e-15)


def test_energy_is_conserved_and_matches_the_angle_forms():
    """t + r = 1, and Fresnel's sine/tangent forms (by hand) at a few angles."""
    n1, n2 = 1.0, 1.5
    for a in np.linspace(0.05, 1.5, 9):
        b = math.asin(n1 * math.sin(a) / n2)
        r_s_hand = (math.sin(a - b) / math.sin(a + b)) ** 2
        r_p_hand = (math.tan(a - b) / math.tan(a + b)) ** 2
        r_s, r_p = fresnel_reflectance(math.cos(a), n1, n2)
        t_s, t_p = fresnel_transmittance(math.cos(a), n1, n2)
        assert float(r_s) == pytest.approx(r_s_hand, rel=1e-12, abs=1e-15)
        assert float(r_p) == pytest.approx(r_p_hand, rel=1e-10, abs=1e-15)
        assert float(t_s + r_s) == pytest.approx(1.0, abs=1e-15)
        assert float(t_p + r_p) == pytest.approx(1.0, abs=1e-15)


def test_grazing_and_index_matched():
    t_s, t_p = fresnel_transmittance(0.0, 1.0, 1.5)
    assert t_s == 0.0 and t_p == 0.0
    np.testing.assert_array_equal(fresnel_transmittance(np.linspace(0, 1, 5), 1.2, 1.2), 1.0)
    d = _ray(0.7)
    np.testing.assert_allclose(refract(d, np.array([0.0, 0.0, 1.0]), 1.0).directions, d)
