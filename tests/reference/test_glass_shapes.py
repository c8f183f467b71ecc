"""The glass shapes (reference/shapes.py) and their meshes (reference/glass_meshes.py)
against hand geometry: hit points on the surface, normals, volumes, closed meshes."""

from __future__ import annotations

import math

import numpy as np
import pytest

from reference.glass_meshes import biconvex_mesh, box_mesh, ellipsoid_mesh, rod_mesh
from reference.shapes import Biconvex, Box, Ellipsoid, Rod, TriangleMesh, rotation_to


def _rays(n, center, r, seed=0):
    rng = np.random.default_rng(seed)
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    o = np.asarray(center) - 3.0 * r * d + rng.normal(size=(n, 3)) * 0.4 * r
    return o, d


def _closed(f):
    e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    return np.all(np.unique(e, axis=0, return_counts=True)[1] == 2)


def test_ellipsoid_hits_lie_on_its_surface_with_the_gradient_normal():
    rot = rotation_to((1.0, 2.0, 0.5))
    e = Ellipsoid((0.1, -0.2, 0.3), (1.0, 0.6, 0.3), rot)
    o, d = _rays(500, e.center, 1.0)
    for inside in (False, True):
        h = e.hit(o, d, False, 0.0)
        ok = np.isfinite(h.t)
        if inside:  # from the entry point: the exit
            o, d = (o + h.t[:, None] * d)[ok], d[ok]
            h = e.hit(o, d, True, 1e-9)
            ok = np.isfinite(h.t)
            assert ok.all()
        p = o[ok] + h.t[ok, None] * d[ok]
        q = ((p - e.center) @ rot) / e.axes  # local unit-sphere coordinates
        assert np.linalg.norm(q, axis=1) == pytest.approx(1.0, abs=1e-12)
        grad = ((p - e.center) @ rot / np.square(e.axes)) @ rot.T
        grad /= np.linalg.norm(grad, axis=1, keepdims=True)
        assert np.allclose(h.normal[ok], grad, atol=1e-12)
        assert np.all((np.sum(h.normal[ok] * d[ok], axis=1) > 0) == inside)


def test_box_from_inside_exits_through_the_face_it_heads_to():
    b = Box((0.0, 0.0, 0.0), (2.0, 4.0, 6.0))
    o = np.zeros((3, 3))
    h = b.hit(o, np.eye(3), True, 0.0)
    assert h.t == pytest.approx([1.0, 2.0, 3.0])
    assert np.allclose(h.normal, np.eye(3))


def test_biconvex_rim_and_a_ray_along_the_axis():
    """Radii 2 and 3, thickness 0.5: the sags s1 + s2 = 0.5 with s = R - sqrt(R^2 - r^2)
    at the rim; along the axis the ray enters at +t/2 and leaves at -t/2."""
    lens = Biconvex((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 2.0, 3.0, 0.5)
    r = lens.edge_radius()
    sag = sum(R - math.sqrt(R * R - r * r) for R in (2.0, 3.0))
    assert sag == pytest.approx(0.5, abs=1e-12)
    o, d = np.array([[0.0, 0.0, 5.0]]), np.array([[0.0, 0.0, -1.0]])
    assert lens.hit(o, d, False).t == pytest.approx([4.75])
    assert lens.hit(np.array([[0.0, 0.0, 0.25]]), d, True, 1e-9).t == pytest.approx([0.5])
    plano = Biconvex((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 2.0, math.inf, 0.4)
    assert plano.edge_radius() == pytest.approx(math.sqrt(2.0**2 - 1.6**2))
    assert plano.hit(np.array([[0.3, 0.0, -1.0]]), -d, False).normal == pytest.approx(
        np.array([[0.0, 0.0, -1.0]])
    )


@pytest.mark.parametrize(
    "shape,build,volume",
    [
        (
            Ellipsoid((0.0, 0.0, 0.0), (1.0, 0.5, 0.25)),
            lambda s: ellipsoid_mesh(s.center, s.axes, n_lat=96, n_lon=192),
            4.0 / 3.0 * math.pi * 0.125,
        ),
        (
            Rod((0.0, 0.0, 0.0), (1.0, 0.0, 0.0), 0.2, 2.0),
            lambda s: rod_mesh(s, 256),
            math.pi * 0.04 * 2.0,
        ),
        (Box((1.0, 0.0, 0.0), (1.0, 2.0, 3.0), rotation_to((1, 1, 1))), box_mesh, 6.0),
        (
            # two caps of height h = R - sqrt(R^2 - a^2): pi h^2 (3R - h) / 3 each
            Biconvex((0.0, 0.0, 0.0), (0.0, 1.0, 0.0), 2.0, 2.0, 0.4),
            lambda s: biconvex_mesh(s, 64, 256),
            2.0 * math.pi * 0.2**2 * (6.0 - 0.2) / 3.0,
        ),
    ],
)
def test_meshes_are_closed_with_the_shape_volume_and_hits(shape, build, volume):
    v, f, _ = build(shape)
    assert _closed(f)
    mesh = TriangleMesh(v, f)
    assert mesh.volume() == pytest.approx(volume, rel=2e-3)  # inscribed: a hair smaller
    c, r = shape.bounding_sphere()
    o, d = _rays(2000, c, r, seed=1)
    ha, hm = shape.hit(o, d, False), mesh.hit(o, d, False)
    both = np.isfinite(ha.t) & np.isfinite(hm.t)
    assert both.sum() >= 0.98 * np.isfinite(ha.t).sum()
    assert np.median(np.abs(ha.t[both] - hm.t[both])) < 2e-3 * r
