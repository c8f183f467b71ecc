"""Issue 25: several glass objects on one path (core/caustic_layer/glass_groups.py).

A magnifier held over a glass pebble under a point light: the pebble lies wholly in
the lens' shadow, so all its light comes through the lens. Traced together (one mesh lens
over both, `glass_groups.join`), the layer on the floor matches the independent
Monte-Carlo tracer given both solids (`reference.glass_tracer`, analytic shapes); traced
apart (each its own lens, as before), the layer is far off. Which pieces join is checked
by hand-built geometry: pieces in one another's light join, pieces side by side under a
light from above do not, and the pieces' indices travel per triangle."""

from __future__ import annotations

import numpy as np
import pytest
from glass_meshes import box

from core.caustic_layer.beam_trace import trace_beam
from core.caustic_layer.emitters import Lens, PointLight
from core.caustic_layer.glass_groups import glass_groups, join, reaches
from core.caustic_layer.mesh_sources import mesh_sheet_sources
from core.caustic_layer.rasters import RasterFrame, build_layer
from core.caustic_layer.receiver_index import build_index
from core.lens.closed_mesh import LocalMesh, world_mesh
from core.lens.glass import LensOptics
from core.lens.mesh import MeshLens
from core.scene.arrays import SceneArrays
from core.scene.mesh_lenses import MeshLensRead
from core.scene.primaries import PointPrimary, tier_primaries
from reference import glass_tracer as gt
from reference.emitters import PointLight as RefPoint
from reference.glass_meshes import biconvex_mesh, corner_normals, ellipsoid_mesh, rod_mesh
from reference.meshes import rectangle
from reference.scene import ReceiverPlane
from reference.shapes import Biconvex, Ellipsoid, Rod

LIGHT = np.array([0.3, 0.2, 8.0])
LENS = Biconvex(
    center=(0.0, 0.0, 3.0), axis=(0.0, 0.0, 1.0), r_front=4.0, r_back=4.0, thickness=0.5
)
PEBBLE = Ellipsoid(center=(0.05, -0.05, 1.3), axes=(0.8, 0.7, 0.4))


def _lens(v, f, nrm=None, ior=1.5):
    c = 0.5 * (v.min(axis=0) + v.max(axis=0))
    r = float(np.linalg.norm(v - c, axis=1).max()) * (1 + 1e-9)
    return MeshLens(c, r, ior, 0.0, v, f, nrm)


def _pieces(pebble_ior=1.5):
    v, f, vn = biconvex_mesh(LENS, n_rings=48, n_seg=192)
    lens = _lens(v, f, corner_normals(f, vn))
    pv, pf, pn = ellipsoid_mesh(PEBBLE.center, PEBBLE.axes, n_lat=48, n_lon=96)
    return lens, _lens(pv, pf, corner_normals(pf, pn), pebble_ior)


def _record(m: MeshLens) -> Lens:
    return Lens(
        m.center,
        m.radius,
        m.ior,
        kind="mesh",
        params=(m.vertices, m.triangles, m.corner_normals, m.triangle_ior, m.triangle_absorption),
    )


def _joined_record(pieces) -> Lens:
    j = join(pieces)
    params = (j.vertices, j.triangles, j.corner_normals, j.triangle_ior, j.triangle_absorption)
    return Lens(j.center, j.radius, 1.5, kind="mesh", params=params)


def _floor_layer(records, light, floor, frames=None):
    beams = [trace_beam(light, rec, 32, 128) for rec in records]
    return build_layer(beams, floor, 40, raster_frames=frames)


def _frames(layer):
    return [
        RasterFrame(p.patch, tuple(int(s) for s in p.sources), p.normal, p.axis_u, p.axis_v, p.axes)
        for p in layer.patches
    ]


def _truth(layer, pebble_ior, n=300_000):
    """The reference tracer's irradiance on the layer's texels (both solids)."""
    pl = layer.patches[0]
    plane = ReceiverPlane(origin=tuple(pl.origin), normal=(0.0, 0.0, 1.0), u_axis=tuple(pl.axis_u))
    rec = gt.Receiver(plane, grid=(pl.edges_u, pl.edges_v))
    glass = [gt.Glass(LENS, 1.5), gt.Glass(PEBBLE, pebble_ior)]
    res = gt.trace_glass(RefPoint(tuple(LIGHT), 1000.0), glass, [rec], n, seed=3)
    return res.receivers[0].irradiance.T, res.receivers[0].flux


def test_light_through_a_magnifier_then_a_pebble_lands_like_the_reference():
    """The pebble of another index (1.33) than the lens (1.5): each piece refracts with
    its own. Measured: L1 0.070, flux 0.975 (apart: L1 0.91)."""
    pebble_ior = 1.33
    lens, pebble = _pieces(pebble_ior)
    floor = build_index(rectangle([0.0, 0.0, 0.0], [0, 0, 1], 8.0, 8.0))
    light = PointLight(LIGHT, 1000.0)
    layer = _floor_layer([_joined_record([lens, pebble])], light, floor)
    truth, flux = _truth(layer, pebble_ior)
    got = layer.patches[0].irradiance[..., 0]
    l1 = float(np.abs(got - truth).sum() / truth.sum())
    assert l1 < 0.12, l1
    assert layer.patches[0].flux == pytest.approx(flux, rel=0.04)
    # apart (each piece its own lens: the pebble lit as if the lens were not there, the
    # lens' beam landing through no pebble), on the same texels: far from the truth
    apart = _floor_layer([_record(lens), _record(pebble)], light, floor, _frames(layer))
    l1_apart = float(np.abs(apart.patches[0].irradiance[..., 0] - truth).sum() / truth.sum())
    assert l1_apart > 3 * l1, (l1_apart, l1)


def test_pieces_in_one_anothers_light_join_and_pieces_side_by_side_do_not():
    lens, pebble = _pieces()
    # the pebble below the lens: the lens' light reaches it
    assert reaches(LIGHT, lens, [pebble]).tolist() == [True]
    # seen from the pebble, the lens stands between it and the light
    assert reaches(LIGHT, pebble, [lens]).tolist() == [True]
    assert glass_groups([LIGHT, LIGHT], [lens, pebble]) == [[0, 1]]
    # two cubes 3 apart under a light straight above the middle: neither's light
    # (refracted down) reaches the other
    v, t = box((-0.5, -0.5, 0.0), (0.5, 0.5, 1.0))
    a, b = _lens(v - [1.5, 0, 0], t), _lens(v + [1.5, 0, 0], t)
    top = np.array([0.0, 0.0, 6.0])
    assert glass_groups([top, top], [a, b]) == [[0], [1]]
    # ... but a light low on the side sends one's light into the other
    low = np.array([-9.0, 0.0, 1.2])
    assert glass_groups([low, low], [a, b]) == [[0, 1]]
    # a long rod beside the cube: its bounding sphere (radius 3) holds the cube's
    # beam, its triangles do not meet it
    rv, rf, rn = rod_mesh(Rod(center=(0.0, 1.5, 0.3), axis=(1.0, 0.0, 0.0), radius=0.3, length=6.0))
    rod = _lens(rv, rf, corner_normals(rf, rn))
    assert np.linalg.norm(rod.center - a.center) < rod.radius
    assert glass_groups([top, top], [a, rod]) == [[0], [1]]


def test_a_joined_mesh_keeps_each_pieces_index_and_normals():
    lens, pebble = _pieces(1.33)
    j = join([lens, pebble])
    nl = len(lens.triangles)
    assert np.all(j.triangle_ior[:nl] == 1.5) and np.all(j.triangle_ior[nl:] == 1.33)
    assert np.array_equal(j.triangles[nl:], pebble.triangles + len(lens.vertices))
    assert np.array_equal(j.corner_normals[:nl], lens.corner_normals)
    assert np.all(np.linalg.norm(j.vertices - j.center, axis=1) <= j.radius)


def _cube_read(name, center):
    v, t = box((-0.5, -0.5, -0.5), (0.5, 0.5, 0.5))
    fn = np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]])
    fn /= np.linalg.norm(fn, axis=1)[:, None]
    m = np.eye(4)
    m[:3, 3] = center
    local = LocalMesh(v, t, np.repeat(fn[:, None], 3, axis=1))
    return MeshLensRead(name, None, world_mesh(local, m), 1.5, 1.0, LensOptics())


def test_the_sources_trace_stacked_glass_once_and_side_by_side_apart():
    no_spheres = SceneArrays(
        light_position=np.zeros((0, 3)),
        light_brightness=np.zeros(0),
        light_color=np.zeros((0, 3)),
        center=np.zeros((0, 3)),
        radius=np.zeros(0),
        ior=np.zeros(0),
        kt=np.zeros(0),
    )
    lights = [PointPrimary((0.0, 0.0, 8.0), 1000.0)]
    # stacked: the upper cube stands in the lower one's light
    stacked = [_cube_read("Upper", (0.0, 0.0, 2.5)), _cube_read("Lower", (0.0, 0.0, 0.8))]
    sources, pairs, skipped = mesh_sheet_sources(
        no_spheres, lights, tier_primaries(lights), stacked
    )
    assert pairs == [(0, (0, 1))] and not skipped
    (s,) = sources
    assert len(s.lens.params[1]) == 24  # both cubes' triangles
    assert s.blockers is None  # neither blocks the other: both are traced
    assert np.allclose(s.emitter.position, (0.0, 0.0, 8.0))
    # power: the light's, not dimmed by the upper cube's bounding sphere as a blocker
    assert s.emitter.power == pytest.approx(1000.0)
    # side by side far apart: a source each
    apart = [_cube_read("Left", (-3.0, 0.0, 0.8)), _cube_read("Right", (3.0, 0.0, 0.8))]
    sources, pairs, _ = mesh_sheet_sources(no_spheres, lights, tier_primaries(lights), apart)
    assert pairs == [(0, 0), (0, 1)]
