"""Issue 25: the caustic layer's sources of glass meshes (core/caustic_layer/mesh_sources.py):
one per light that reaches the mesh, the light where it is with its power, the
sphere in its way as its blocker, a spot turned away giving none, Maximum Lens
Lights keeping the pairs with the most flux. Expected values by hand from the scene
built here (positions, powers, which light points where)."""

from __future__ import annotations

import math

import numpy as np

from core.caustic_layer.emitters import Lens
from core.caustic_layer.mesh_sources import (
    cap_flux,
    mesh_color,
    mesh_facets,
    mesh_min_rays,
    mesh_sheet_sources,
)
from core.lens.closed_mesh import LocalMesh, world_mesh
from core.lens.glass import LensOptics
from core.phase1.skip_reasons import Reason
from core.scene.arrays import SceneArrays
from core.scene.mesh_lenses import MeshLensRead
from core.scene.primaries import PointPrimary, SpotPrimary, tier_primaries

CUBE_V = np.array([[x, y, z] for x in (0.0, 1.0) for y in (0.0, 1.0) for z in (0.0, 1.0)]) - 0.5
CUBE_T = np.array(
    [
        [0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
        [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3],
    ]
)  # fmt: skip


def cube_at(center, optics=None):
    fn = np.cross(
        CUBE_V[CUBE_T[:, 1]] - CUBE_V[CUBE_T[:, 0]], CUBE_V[CUBE_T[:, 2]] - CUBE_V[CUBE_T[:, 0]]
    )
    fn /= np.linalg.norm(fn, axis=1)[:, None]
    m = np.eye(4)
    m[:3, 3] = center
    local = LocalMesh(CUBE_V, CUBE_T, np.repeat(fn[:, None], 3, axis=1))
    return MeshLensRead("Ice", None, world_mesh(local, m), 1.5, 1.0, optics or LensOptics())


def spheres(centers=(), radii=()):
    c = np.asarray(centers, dtype=float).reshape(-1, 3)
    return SceneArrays(
        light_position=np.zeros((0, 3)),
        light_brightness=np.zeros(0),
        light_color=np.zeros((0, 3)),
        center=c,
        radius=np.asarray(radii, dtype=float),
        ior=np.full(len(c), 1.5),
        kt=np.zeros(len(c)),  # opaque balls
    )


def test_a_point_light_above_a_cube_is_one_source_and_a_spot_turned_away_none():
    lights = [
        PointPrimary((0.0, 0.0, 5.0), 1000.0),
        SpotPrimary((3.0, 0.0, 1.0), (1.0, 0.0, 0.0), 500.0, math.radians(30.0)),  # away
    ]
    cube = cube_at((0.0, 0.0, 1.0))
    sources, pairs, skipped = mesh_sheet_sources(spheres(), lights, tier_primaries(lights), [cube])
    assert pairs == [(0, 0)]
    (s,) = sources
    assert np.allclose(s.emitter.position, (0.0, 0.0, 5.0))
    assert s.emitter.power == 1000.0
    assert s.lens.kind == "mesh" and s.lens.ior == 1.5
    assert s.lens.radius == math.sqrt(3.0) / 2.0
    assert len(s.lens.params[1]) == 12
    assert s.blockers is None
    assert [(j, k) for j, k, _code in skipped] == [(1, 0)]
    assert skipped[0][2] == int(Reason.OUTSIDE_EMISSION)


def test_a_ball_between_the_light_and_the_cube_is_its_blocker():
    lights = [PointPrimary((0.0, 0.0, 5.0), 1000.0)]
    cube = cube_at((0.0, 0.0, 1.0))
    # a ball of radius 0.2 on the axis at z = 3: part of the cube's bounding sphere's
    # cone (half-angle asin(0.866 / 4) = 12.5°) against the ball's (asin(0.2 / 2) = 5.7°)
    sources, pairs, _ = mesh_sheet_sources(
        spheres([(0.0, 0.0, 3.0)], [0.2]), lights, tier_primaries(lights), [cube]
    )
    (s,) = sources
    assert s.blockers is not None and np.allclose(s.blockers.centers, [(0.0, 0.0, 3.0)])
    share = s.blockers.unblocked
    # the shadowed share of the cap: (1 − cos 5.74°) / (1 − cos 12.5°) of it
    lost = (1 - math.cos(math.asin(0.1))) / (1 - math.cos(math.asin(math.sqrt(3) / 2 / 4)))
    assert abs(share - (1.0 - lost)) < 0.01
    assert abs(s.emitter.power - 1000.0 * share) < 1e-6


def test_maximum_lens_lights_keeps_the_pairs_with_the_most_flux():
    lights = [PointPrimary((0.0, 0.0, 5.0), 1000.0), PointPrimary((0.0, 0.0, 20.0), 1000.0)]
    cube = cube_at((0.0, 0.0, 1.0))
    sources, pairs, skipped = mesh_sheet_sources(
        spheres(), lights, tier_primaries(lights), [cube], max_pairs=1
    )
    assert pairs == [(0, 0)]  # the nearer light sends more into the cube
    assert skipped == [(1, 0, int(Reason.BEYOND_MAXIMUM))]
    r = math.sqrt(3.0) / 2.0
    assert abs(cap_flux(1000.0, 4.0, r) - 500.0 * (1 - math.sqrt(1 - (r / 4.0) ** 2))) < 1e-9


def test_the_colour_carries_the_tint_and_the_absorption_beyond_its_mean():
    optics = LensOptics(tint=(1.0, 0.5, 0.25), absorption=(0.0, 1.0, 2.0))
    cube = cube_at((0.0, 0.0, 1.0), optics)
    # mean chord of the unit cube: 4 V / S = 2/3; absorption beyond the mean (1): −1, 0, 1
    expect = np.array([1.0, 0.5, 0.25]) * np.exp(-np.array([-1.0, 0.0, 1.0]) * 2.0 / 3.0)
    assert np.allclose(mesh_color(cube, (1.0, 1.0, 1.0)), expect)


def _sphere_record(n_lat, n_lon, smooth):
    """A UV sphere (`reference.meshes.uv_sphere`) as a mesh lens record: smooth
    (the sphere's own normals at the corners) or flat-shaded (no corner normals)."""
    from reference.meshes import uv_sphere

    m = uv_sphere((0.0, 0.0, 1.0), 0.5, n_lat, n_lon)
    v, t = np.asarray(m.vertices), np.asarray(m.triangles)
    nrm = (v[t] - [0.0, 0.0, 1.0]) / 0.5 if smooth else None
    return Lens(np.array([0.0, 0.0, 1.0]), 0.5 * (1 + 1e-9), 1.5, kind="mesh", params=(v, t, nrm))


def test_a_smooth_pebble_is_one_facet_and_a_flat_one_a_facet_per_face():
    """A smooth sphere of 1 984 triangles shows one facet, and its ray floor is the
    screen's, not 4 per triangle; flat-shaded, each of its planar quads (two
    triangles) is a facet (30 rows of 32), and each polar fan one (its neighbouring
    triangles' normals, tilted 2.8° from the pole 11.25° apart in azimuth, differ by
    0.55°: under the 0.81° of `SMOOTH_COS`, one smooth group)."""
    smooth, flat = _sphere_record(32, 32, True), _sphere_record(32, 32, False)
    assert len(smooth.params[1]) == 2 * 32 * 31 == 1984
    assert mesh_facets(smooth) == 1
    assert mesh_facets(flat) == 30 * 32 + 2
    assert mesh_min_rays(mesh_facets(smooth), 256, pixels=500.0) == 256
    assert mesh_min_rays(mesh_facets(flat), 256, pixels=500.0) == 4 * 962
    assert mesh_min_rays(mesh_facets(flat), 256, pixels=10.0) == 400  # 4 per pixel²
