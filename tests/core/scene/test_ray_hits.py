"""Rays against spheres for the occluders (`core.scene.ray_hits`): hand values, and the
hard case of SPEC §4.3, a small sphere far along the ray, where the textbook near root
``b − √disc`` cancels."""

import numpy as np
import pytest

from core.scene.ray_hits import sphere_hits, sphere_hits_bundles


def test_first_hits_by_hand():
    centers = np.array([[0.0, 0.0, 5.0], [0.0, 0.0, 20.0], [3.0, 0.0, 5.0]])
    radii = np.array([1.0, 2.0, 0.5])
    origins = np.array([[0.0, 0.0, 0.0], [0.0, 0.6, 0.0], [0.0, 0.0, 5.0], [0.0, 9.0, 0.0]])
    d = np.array([0.0, 0.0, 1.0])
    t = sphere_hits(centers, radii, origins, d)
    # on the axis: the near surface at 4; 0.6 off it: 5 − √(1 − 0.36) = 4.2; from the
    # first sphere's centre: its far side at 1; far off the line: nothing
    assert t == pytest.approx([4.0, 4.2, 1.0, np.inf], rel=1e-15)
    both = sphere_hits_bundles(centers, radii, origins[None], d[None])
    assert both[0] == pytest.approx(t, rel=1e-15)


@pytest.mark.parametrize("distance", [1e3, 1e6])
def test_small_far_sphere_keeps_its_digits(distance):
    """R = 1e-4 at D along the ray, 0.5 R off it: t = D − √(R² − (R/2)²) to the last
    digits (the cancelling form loses about log10(D²/R²) of them)."""
    R = 1e-4
    centers = np.array([[0.0, 0.5 * R, distance]])
    origins = np.zeros((1, 3))
    d = np.array([0.0, 0.0, 1.0])
    exact = distance - np.sqrt(0.75) * R
    t = sphere_hits(centers, np.array([R]), origins, d)
    assert abs(t[0] - exact) <= 4 * np.spacing(distance)
    tb = sphere_hits_bundles(centers, np.array([R]), origins[None], d[None])
    assert abs(tb[0, 0] - exact) <= 4 * np.spacing(distance)
