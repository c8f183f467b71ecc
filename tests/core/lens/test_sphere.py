"""The stable ray–sphere intersection (SPEC §4.3) against values by hand."""

import math

import numpy as np
import pytest

from core.lens.sphere import intersect_sphere, sphere_roots


def test_straight_through_the_centre():
    h = intersect_sphere(np.array([0.0, 0.0, -5.0]), np.array([0.0, 0.0, 1.0]), np.zeros(3), 2.0)
    assert (float(h.near), float(h.far)) == (3.0, 7.0)
    assert bool(h.hit) and float(h.perp2) == 0.0


def test_off_axis_by_hand():
    # line y = 1 along z from z = -10; sphere R = 2 at (0, 0, 1): |dz| = sqrt(3)
    h = intersect_sphere(np.array([0.0, 1.0, -10.0]), np.array([0.0, 0.0, 1.0]), [0, 0, 1.0], 2.0)
    assert float(h.near) == pytest.approx(11.0 - math.sqrt(3.0), rel=1e-15)
    assert float(h.far) == pytest.approx(11.0 + math.sqrt(3.0), rel=1e-15)
    assert float(h.perp2) == 1.0


def test_tangent_ray_meets_the_tangent_point_once():
    h = intersect_sphere(np.array([1.0, 0.0, -4.0]), np.array([0.0, 0.0, 1.0]), np.zeros(3), 1.0)
    assert bool(h.hit) and float(h.disc) == 0.0
    assert float(h.near) == float(h.far) == 4.0


def test_miss_is_flagged():
    h = intersect_sphere(np.array([1.5, 0.0, -4.0]), np.array([0.0, 0.0, 1.0]), np.zeros(3), 1.0)
    assert not bool(h.hit) and float(h.disc) == pytest.approx(-1.25)


def test_origin_inside_gives_roots_on_both_sides():
    d = np.array([0.6, 0.8, 0.0])
    h = intersect_sphere(np.zeros(3) + [0.0, 0.0, 0.5], d, np.zeros(3), 1.0)
    s = math.sqrt(0.75)
    assert float(h.near) == pytest.approx(-s, rel=1e-15)
    assert float(h.far) == pytest.approx(s, rel=1e-15)
    # from the centre
    h = intersect_sphere(np.zeros(3), d, np.zeros(3), 3.0)
    assert (float(h.near), float(h.far)) == (-3.0, 3.0)


def test_sphere_behind_the_origin_has_negative_roots():
    h = intersect_sphere(np.array([0.0, 0.0, 5.0]), np.array([0.0, 0.0, 1.0]), np.zeros(3), 1.0)
    assert (float(h.near), float(h.far)) == (-6.0, -4.0)


@pytest.mark.parametrize("radius", [1e-4, 1.0, 1e4])
def test_far_origin_small_sphere_keeps_the_near_root_precise(radius):
    """An origin 1e6 R away: the textbook −β − √disc loses the near root's last digits to
    cancellation in β² − c; the stable form keeps the entry on the surface."""
    dist = 1e6 * radius
    b = 0.3 * radius  # impact parameter
    o = np.array([b, 0.0, -dist])
    d = np.array([0.0, 0.0, 1.0])
    h = intersect_sphere(o, d, np.zeros(3), radius)
    half = math.sqrt((radius - b) * (radius + b))
    assert float(h.near) == pytest.approx(dist - half, rel=1e-15)
    assert float(h.far) == pytest.approx(dist + half, rel=1e-15)
    p = o + float(h.near) * d
    assert np.linalg.norm(p) == pytest.approx(radius, rel=1e-9)


def test_vectorised_with_broadcast_spheres():
    o = np.zeros((2, 4, 3)) + [0.0, 0.0, -3.0]
    d = np.broadcast_to([0.0, 0.0, 1.0], o.shape)
    centers = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 1.0]])[:, None, :]
    radii = np.array([1.0, 2.0])[:, None]
    h = intersect_sphere(o, d, centers, radii)
    assert h.near.shape == (2, 4)
    np.testing.assert_array_equal(h.near, [[2.0] * 4, [2.0] * 4])
    np.testing.assert_array_equal(h.far, [[4.0] * 4, [6.0] * 4])


def test_roots_of_the_quadratic():
    # t² + 2βt + c = 0 with β = −5, c = 9: roots 1 and 9
    near, far = sphere_roots(-5.0, 16.0, 9.0)
    assert (float(near), float(far)) == (1.0, 9.0)
    near, far = sphere_roots(5.0, 16.0, 9.0)
    assert (float(near), float(far)) == (-9.0, -1.0)
    near, far = sphere_roots(0.0, 0.0, 0.0)
    assert (float(near), float(far)) == (0.0, 0.0)
