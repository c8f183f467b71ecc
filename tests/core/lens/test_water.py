"""The water surface (`core.lens.water`) against Snell and Fresnel worked out by hand
(the amplitude coefficients, not the code's power forms) on a flat and a tilted patch,
and its rest plane."""

import math

import numpy as np
import pytest
from glass_meshes import unpolarised_t

from core.lens.water import WaterSurface, rest_plane

N = 1.333


def _flat(z=0.0, size=1.0, tilt=0.0):
    """A square of two triangles at height z, turned by ``tilt`` about the x axis."""
    s = 0.5 * size
    v = np.array([[-s, -s, 0.0], [s, -s, 0.0], [s, s, 0.0], [-s, s, 0.0]])
    c, sn = math.cos(tilt), math.sin(tilt)
    rot = np.array([[1, 0, 0], [0, c, -sn], [0, sn, c]])
    v = v @ rot.T + [0.0, 0.0, z]
    return WaterSurface(v, np.array([[0, 1, 2], [0, 2, 3]]), ior=N)


def _unpolarised_t(theta):
    """1 − (r_s² + r_p²)/2 with the amplitude coefficients, air → water."""
    return unpolarised_t(theta, 1.0, N)


@pytest.mark.parametrize("theta_deg", [0.0, 30.0, 60.0, 80.0])
def test_flat_water_refracts_by_snell_with_fresnel(theta_deg):
    th = math.radians(theta_deg)
    w = _flat(z=0.2)
    d = np.array([[math.sin(th), 0.0, -math.cos(th)]])
    o = np.array([[0.1 - 2.0 * d[0, 0], 0.05, 0.2 + 2.0 * math.cos(th)]])
    h = w.enter(o, d)
    assert h.hit[0]
    np.testing.assert_allclose(h.points[0], [0.1, 0.05, 0.2], atol=1e-12)
    sin_t = math.sin(th) / N
    np.testing.assert_allclose(h.directions[0], [sin_t, 0.0, -math.sqrt(1 - sin_t**2)], atol=1e-12)
    assert h.transmittance[0] == pytest.approx(_unpolarised_t(th), rel=1e-12)
    if theta_deg == 0.0:  # 1 − ((n − 1)/(n + 1))²
        assert h.transmittance[0] == pytest.approx(1 - (0.333 / 2.333) ** 2, rel=1e-12)


def test_shading_normals_bend_the_ray_on_a_flat_triangle():
    """Corner normals tilted by 10° about y: the ray sees a 10° slope, as Blender
    shades (the smooth normal, not the flat face)."""
    v = np.array([[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [1.0, 1.0, 0.0], [-1.0, 1.0, 0.0]])
    a = math.radians(10.0)
    n = np.array([math.sin(a), 0.0, math.cos(a)])
    w = WaterSurface(v, np.array([[0, 1, 2], [0, 2, 3]]), np.broadcast_to(n, (2, 3, 3)), N)
    h = w.enter([[0.2, 0.1, 1.0]], [[0.0, 0.0, -1.0]])
    # incidence 10° on the tilted normal: refracted at asin(sin 10° / n) from −n, in
    # the plane of the ray and the normal
    st = math.sin(a) / N
    t = math.asin(st)
    expect = -math.cos(t) * n + math.sin(t) * np.array([math.cos(a), 0.0, -math.sin(a)])
    np.testing.assert_allclose(h.directions[0], expect, atol=1e-12)
    assert h.transmittance[0] == pytest.approx(_unpolarised_t(a), rel=1e-12)


def test_a_ray_beside_the_water_misses_it():
    w = _flat(size=1.0)
    h = w.enter([[2.0, 0.0, 1.0]], [[0.0, 0.0, -1.0]])
    assert not h.hit[0] and h.transmittance[0] == 0.0
    np.testing.assert_allclose(h.directions[0], [0.0, 0.0, -1.0])


def test_rest_plane_of_a_tilted_wavy_sheet():
    tilt = math.radians(20.0)
    xs, ys = np.meshgrid(np.linspace(-1, 1, 21), np.linspace(-0.5, 0.5, 11))
    z = 0.01 * np.sin(7.0 * xs) * np.cos(5.0 * ys)
    p = np.stack([xs, ys, z], -1).reshape(-1, 3)
    c, s = math.cos(tilt), math.sin(tilt)
    p = p @ np.array([[1, 0, 0], [0, c, -s], [0, s, c]]).T + [0.3, 0.0, 2.0]
    pl = rest_plane(p)
    np.testing.assert_allclose(abs(pl.normal @ [0.0, -s, c]), 1.0, atol=1e-3)
    assert pl.normal[2] > 0.0
    assert pl.u_range[1] - pl.u_range[0] == pytest.approx(2.0, rel=0.02)
    assert pl.v_range[1] - pl.v_range[0] == pytest.approx(1.0, rel=0.02)
    assert 0.005 < pl.top < 0.02 and -0.02 < pl.bottom < -0.005
    np.testing.assert_allclose(np.cross(pl.axis_u, pl.axis_v), pl.normal, atol=1e-12)


def test_rest_plane_axes_follow_a_square_grid():
    """A square grid turned 20° about z: its principal axes are undetermined (a square),
    the rest plane's axes follow its rows and columns and its extent is the square's."""
    xs = np.linspace(-1.0, 1.0, 11)
    gx, gy = np.meshgrid(xs, xs)
    p = np.stack([gx, gy, np.zeros_like(gx)], -1).reshape(-1, 3)
    a = math.radians(20.0)
    p = p @ np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]]).T
    i, j = np.meshgrid(np.arange(10), np.arange(10), indexing="ij")
    q = (i * 11 + j).reshape(-1)
    t = np.concatenate([np.stack([q, q + 1, q + 12], 1), np.stack([q, q + 12, q + 11], 1)])
    pl = rest_plane(p, t)
    row = np.array([math.cos(a), math.sin(a), 0.0])
    assert min(abs(pl.axis_u @ row), abs(pl.axis_v @ row)) < 1e-9
    assert (pl.u_range[1] - pl.u_range[0]) == pytest.approx(2.0, rel=1e-9)
    assert (pl.v_range[1] - pl.v_range[0]) == pytest.approx(2.0, rel=1e-9)
