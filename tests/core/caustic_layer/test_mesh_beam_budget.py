"""The glass mesh beam's budget (`mesh_beam`, issue 25): the cells on an edge of the
beam are refined with rays in proportion to their number (no flat 32 768-ray floor), an
extended light's coarse grids per sample still draw a cube's caustic as the independent
glass tracer (`reference.glass_tracer`) sees it; `ray_budget.allocate` takes rays per
texel per source (a glass mesh's are fewer)."""

import math

import numpy as np
from glass_meshes import box

from core.caustic_layer import mesh_beam
from core.caustic_layer.beam_trace import trace_beam
from core.caustic_layer.emitters import Lens, PointLight
from core.caustic_layer.rasters import build_layer
from core.caustic_layer.ray_budget import allocate
from core.caustic_layer.receiver_index import build_index
from reference import ReceiverPlane
from reference.emitters import PointLight as RefPointLight
from reference.glass_tracer import Glass, Receiver, trace_glass
from reference.meshes import rectangle
from reference.shapes import TriangleMesh

N = 1.5
FLOOR_Z = -0.001


def _cube():
    v, t = box((-0.5, -0.5, 0.0), (0.5, 0.5, 1.0))
    c = 0.5 * (v.min(axis=0) + v.max(axis=0))
    r = float(np.linalg.norm(v - c, axis=1).max()) * (1 + 1e-9)
    return v, t, Lens(c, r, N, kind="mesh", params=(v, t, None))


def _on_grid(layer, xe, ye, ss=6):
    """The layer's irradiance on the floor averaged over each cell of the world grid
    (x edges ``xe``, y edges ``ye``; rows y), its texels sampled ss × ss per cell."""
    nx, ny = len(xe) - 1, len(ye) - 1
    gx = xe[0] + (np.arange(nx * ss) + 0.5) * (xe[-1] - xe[0]) / (nx * ss)
    gy = ye[0] + (np.arange(ny * ss) + 0.5) * (ye[-1] - ye[0]) / (ny * ss)
    x, y = np.meshgrid(gx, gy)
    pts = np.stack([x, y, np.full_like(x, FLOOR_Z)], axis=-1)
    img = np.zeros_like(x)
    for p in layer.patches:
        d = pts - p.origin
        iu = np.searchsorted(p.edges_u, d @ p.axis_u) - 1
        iv = np.searchsorted(p.edges_v, d @ p.axis_v) - 1
        ok = (iu >= 0) & (iu < p.resolution) & (iv >= 0) & (iv < p.resolution)
        img[ok] += p.irradiance[iv[ok], iu[ok], 0]
    return img.reshape(ny, ss, nx, ss).mean(axis=(1, 3))


def test_an_extended_light_through_a_cube_on_a_coarse_grid_per_sample():
    """A sphere light (radius 0.5 at 4.6 from a unit cube) in 16 samples of 6 × 24 node
    cells each: most cells of each sample straddle an edge of the beam. Against the
    glass tracer's 600 000 rays on a 24 × 24 grid over the caustic (its own noise
    0.04 L1): 0.107 with 13 434 rays (203 edge cells beyond the cap landed as points);
    the flat floor gave 0.060 with 25 040. A guard on the cap, not a fault's test."""
    v, t, rec = _cube()
    pos = np.array([2.5, 0.7, 3.0])
    light = PointLight(pos, 1000.0, radius=0.5)
    floor = build_index(rectangle([0, 0, FLOOR_Z], [0, 0, 1], 16.0, 16.0))
    beam = trace_beam(light, rec, 6, 24, n_source=16)
    layer = build_layer([beam], floor, 48)
    xe = np.linspace(-2.4, 0.6, 25)
    ye = np.linspace(-1.8, 1.2, 25)
    truth = trace_glass(
        RefPointLight(tuple(pos), 1000.0, 0.5),
        [Glass(TriangleMesh(v, t), N)],
        [Receiver(ReceiverPlane((0.0, 0.0, FLOOR_Z), (0.0, 0.0, 1.0)), (xe, ye))],
        600_000,
        seed=3,
    )
    want = truth.receivers[0].irradiance.T  # rows y
    got = _on_grid(layer, xe, ye)
    region = want > 0.01 * want.max()
    # the grid holds the caustic: nearly all the traced flux that lands
    cell = np.diff(xe)[0] * np.diff(ye)[0]
    assert want.sum() * cell > 0.95 * truth.receivers[0].flux
    l1 = np.abs(got - want)[region].sum() / want[region].sum()
    assert l1 < 0.2, l1


def test_every_edge_cell_refined_in_proportion():
    """A point light on the cube, 24 × 96 node cells: the 545 cells on an edge of the
    beam are all refined, (`REFINE_SUB` + 1)² = 9 rays each, 4 905 in all (before:
    the flat 32 768-ray floor gave them 7 × 7 = 49 each, 26 705 rays, five times as
    many for the same edges; and cut cells into points where there were more)."""
    v, t, rec = _cube()
    light = PointLight(np.array([2.5, 0.7, 3.0]), 1000.0)
    beam = trace_beam(light, rec, 24, 96)
    node = 25 * 96
    assert 400 < beam.refined_cells < 700 and beam.cut_cells == 0
    refine = beam.traced_rays - node
    # 9 rays a cell, or the floor shared by fewer cells (before: 26 705)
    per_cell = (mesh_beam.REFINE_SUB + 1) ** 2
    assert refine <= max(beam.refined_cells * per_cell, mesh_beam.REFINE_FLOOR)


def test_allocate_takes_rays_per_texel_per_source():
    """Two sources alike but for their rays per texel: the second's grid has a quarter
    of the rays (half the rings), as `ray_budget` gives for that figure alone."""
    b = allocate(
        [1.0, 1.0], [0.1, 0.1], [0.001, 0.001], texels=[16_384, 16_384], rays_per_texel=[1.0, 0.25]
    )
    assert b[0].n_radial == round(math.sqrt(16_384 / 4.0))
    assert b[1].n_radial == round(math.sqrt(4_096 / 4.0))


def test_what_an_oblate_pebble_sends_upward_misses_every_receiver():
    """Issue 25's unexplained loss ("18 % of the pebble's flux missed every
    receiver"): an oblate glass pebble (semi-axes 0.5, 0.5, 0.25, 1 m over the floor)
    under a point light 3 m above it sends light that totally reflects inside its flat
    rim back up through its top. The layer's lost share is the glass tracer's escaped
    share of what went through the glass (0.174 and 0.179: physics, not a fault; the
    test pins the explanation, it is not a fix)."""
    from reference.glass_meshes import ellipsoid_mesh
    from reference.shapes import Ellipsoid

    c, axes = (0.0, 0.0, 1.0), (0.5, 0.5, 0.25)
    v, t, nrm = ellipsoid_mesh(c, axes, None, 24, 48)
    ctr = 0.5 * (v.min(axis=0) + v.max(axis=0))
    r = float(np.linalg.norm(v - ctr, axis=1).max()) * (1 + 1e-9)
    rec = Lens(ctr, r, N, kind="mesh", params=(v, t, nrm[t]))
    pos = np.array([0.0, 0.0, 4.0])
    floor = build_index(rectangle([0, 0, 0], [0, 0, 1], 8.0, 8.0))
    layer = build_layer([trace_beam(PointLight(pos, 1000.0), rec, 24, 96)], floor, 32)
    lost = layer.flux_lost / layer.flux_emitted
    ref = trace_glass(
        RefPointLight(tuple(pos), 1000.0),
        [Glass(Ellipsoid(c, axes), N)],
        [Receiver(ReceiverPlane((0.0, 0.0, 0.0), (0.0, 0.0, 1.0)), None, (-4, 4, -4, 4))],
        200_000,
        seed=5,
        rr_weight=0.0,
    ).tally
    escaped = ref["escaped"] / (ref["landed"] + ref["escaped"])
    assert 0.15 < escaped < 0.21
    assert abs(lost - escaped) < 0.02, (lost, escaped)
