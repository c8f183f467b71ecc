"""Sphere detection and fit (core/lens/sphere_fit.py); pure numpy, no Blender."""

import math

import numpy as np
import pytest

from core.lens.sphere_fit import (
    CLOSURE_TOLERANCE,
    FACE_TOLERANCE,
    VERTEX_TOLERANCE,
    fit_sphere,
    least_squares_sphere,
    to_world,
    uniform_scale,
)


def uv_sphere(segments=32, rings=16, center=(0.0, 0.0, 0.0), radius=1.0, drop_top_rings=0):
    """A UV sphere like Blender's: vertices, and per face its centre (vertex mean),
    unit normal and area (triangulated fan). `drop_top_rings` removes faces of the
    top rings (an open surface)."""
    c = np.asarray(center, dtype=float)
    lat = np.pi * np.arange(1, rings) / rings  # ring polar angles
    lon = 2 * np.pi * np.arange(segments) / segments
    ring = np.stack(
        [
            np.outer(np.sin(lat), np.cos(lon)),
            np.outer(np.sin(lat), np.sin(lon)),
            np.repeat(np.cos(lat)[:, None], segments, axis=1),
        ],
        axis=-1,
    )
    verts = np.concatenate([[[0, 0, 1]], ring.reshape(-1, 3), [[0, 0, -1]]]) * radius + c
    idx = lambda i, j: 1 + i * segments + (j % segments)  # noqa: E731
    faces = []
    for j in range(segments):
        faces.append([0, idx(0, j), idx(0, j + 1)])
        faces.append([len(verts) - 1, idx(rings - 2, j + 1), idx(rings - 2, j)])
    for i in range(rings - 2):
        for j in range(segments):
            faces.append([idx(i, j), idx(i + 1, j), idx(i + 1, j + 1), idx(i, j + 1)])
    if drop_top_rings:
        faces = (
            faces[2 * segments :]
            if drop_top_rings == 1
            else [
                f
                for f in faces
                if min(verts[k][2] for k in f) - c[2]
                < radius * math.cos(np.pi * drop_top_rings / rings) - 1e-9
            ]
        )
    return verts, *face_data(verts, faces)


def face_data(verts, faces):
    centers, normals, areas = [], [], []
    for f in faces:
        p = verts[f]
        centers.append(p.mean(axis=0))
        cross = sum(np.cross(p[0] - p[k], p[0] - p[k + 1]) for k in range(1, len(p) - 1))
        area = np.linalg.norm(cross) / 2
        n = cross / (2 * area)
        if n @ (p.mean(axis=0) - verts.mean(axis=0)) < 0:  # outward
            n = -n
        normals.append(n)
        areas.append(area)
    return np.array(centers), np.array(normals), np.array(areas)


def test_uv_sphere_is_fitted_exactly():
    fit = fit_sphere(*uv_sphere(center=(1.0, -2.0, 3.0), radius=0.5))
    assert fit.ok, fit.reason
    assert fit.center == pytest.approx([1.0, -2.0, 3.0], abs=1e-12)
    assert fit.radius == pytest.approx(0.5, rel=1e-12)
    assert fit.vertex_deviation < 1e-12
    assert 0.009 < fit.face_depth < 0.011  # 32 × 16: faces 1 % inside


@pytest.mark.parametrize(
    "center,radius", [((1e4, -1e4, 5e3), 1e-2), ((0, 0, 0), 1e-4), ((3e6, 0, 0), 1e4)]
)
def test_fit_is_well_conditioned_far_from_origin_and_at_any_size(center, radius):
    verts = uv_sphere(center=center, radius=radius)[0]
    fit = fit_sphere(verts)
    assert fit.ok, fit.reason
    assert fit.radius == pytest.approx(radius, rel=1e-8)
    assert np.max(np.abs(fit.center - center)) < 1e-8 * max(radius, 1.0) * 1e3


def test_noise_within_tolerance_is_accepted_beyond_it_rejected():
    verts, *faces = uv_sphere()
    rng = np.random.default_rng(1)
    d = verts / np.linalg.norm(verts, axis=1)[:, None]
    small = verts + d * rng.uniform(-0.5, 0.5, len(verts))[:, None] * VERTEX_TOLERANCE
    assert fit_sphere(small, *faces).ok
    big = verts + d * rng.uniform(-3, 3, len(verts))[:, None] * VERTEX_TOLERANCE
    fit = fit_sphere(big, *faces)
    assert not fit.ok and "vertices deviate" in fit.reason and "tolerance 1 %" in fit.reason


def test_ellipsoid_is_not_a_sphere():
    verts, *faces = uv_sphere()
    fit = fit_sphere(verts * [1.0, 1.0, 1.05], *faces)
    assert not fit.ok and "deviate" in fit.reason


def test_cube_corners_lie_on_a_sphere_but_its_faces_do_not():
    verts = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    quads = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]]
    fit = fit_sphere(verts, *face_data(verts, quads))
    assert not fit.ok and fit.reason.startswith("too coarse for a sphere")
    assert fit.face_depth == pytest.approx(1 - 1 / math.sqrt(3))
    assert fit.radius == pytest.approx(math.sqrt(3))


def test_coarse_and_fine_uv_spheres():
    assert not fit_sphere(*uv_sphere(8, 4)).ok  # faces 19 % inside
    assert fit_sphere(*uv_sphere(16, 8)).ok  # 3.7 %
    assert fit_sphere(*uv_sphere(12, 6)).face_depth < FACE_TOLERANCE


def test_open_surfaces_are_rejected():
    # A hemisphere fails the bounding-box test; a sphere without its top two
    # rings of faces (vertices all still there) fails the closure test.
    verts, *faces = uv_sphere()
    half = verts[:, 2] >= -1e-9
    assert "bounding box" in fit_sphere(verts[half]).reason
    fit = fit_sphere(*uv_sphere(drop_top_rings=2))
    assert not fit.ok and "not closed" in fit.reason
    assert fit.face_depth < FACE_TOLERANCE  # it failed on closure only
    assert CLOSURE_TOLERANCE == 0.01


def test_flat_and_degenerate_meshes():
    plane = np.array([[x, y, 0.0] for x in np.linspace(-1, 1, 5) for y in np.linspace(-1, 1, 5)])
    assert "bounding box" in fit_sphere(plane).reason
    assert "only 4 vertices" in fit_sphere(plane[:4]).reason
    assert "non-finite" in fit_sphere(np.full((8, 3), np.nan)).reason
    assert least_squares_sphere(plane) is None  # coplanar
    assert least_squares_sphere(np.outer(np.arange(10), [1, 2, 3])) is None  # a line
    assert least_squares_sphere(np.zeros((10, 3))) is None


def test_a_million_vertices_is_fast():
    import time

    rng = np.random.default_rng(0)
    v = rng.normal(size=(1_000_000, 3))
    v = 2.0 * v / np.linalg.norm(v, axis=1)[:, None] + [5, 6, 7]
    t = time.perf_counter()
    fit = fit_sphere(v)
    assert time.perf_counter() - t < 2.0
    assert fit.ok and fit.radius == pytest.approx(2.0)


def rotation(axis, angle):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * k @ k


def affine(m3, t):
    m = np.eye(4)
    m[:3, :3], m[:3, 3] = m3, t
    return m


def test_to_world_with_rotation_uniform_scale_and_translation():
    m = affine(2.5 * rotation([1, 2, 3], 0.7), [1, 2, 3])
    c, r = to_world([0.1, 0.2, 0.3], 0.4, m)
    assert c == pytest.approx(m[:3, :3] @ [0.1, 0.2, 0.3] + [1, 2, 3])
    assert r == pytest.approx(1.0)
    mirror = affine(np.diag([-1.0, 1.0, 1.0]) * 3, [0, 0, 0])  # reflections are similarities
    assert to_world([0, 0, 0], 1.0, mirror)[1] == pytest.approx(3.0)


def test_to_world_refuses_non_uniform_scale_and_shear():
    assert to_world([0, 0, 0], 1.0, affine(np.diag([1.0, 1.0, 1.01]), [0, 0, 0])) is None
    shear = np.eye(3)
    shear[0, 1] = 0.05
    assert to_world([0, 0, 0], 1.0, affine(shear, [0, 0, 0])) is None
    assert uniform_scale(affine(np.diag([1.0, 1.0, 1.0005]), [0, 0, 0])) is not None  # within 0.1 %
    assert uniform_scale(np.zeros((4, 4))) is None
