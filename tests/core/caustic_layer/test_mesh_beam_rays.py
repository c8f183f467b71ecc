"""What a glass mesh's beam traces and how it lands it (`mesh_beam`, `core.lens.mesh`;
issue 25's speed): each refinement ray traced once (neighbouring refined cells share
their edge's rays, a sub-grid's corners are node rays), blocks of rays walked in
threads giving the one walk's branches bit for bit, and the path with the most flux
drawn as the main sheet on the node grid."""

import numpy as np
from glass_meshes import box

from core.caustic_layer import mesh_beam
from core.caustic_layer.beam_trace import trace_beam
from core.caustic_layer.emitters import Lens, PointLight
from core.lens import mesh as mesh_lens
from core.lens.mesh import MeshLens
from core.shared import parallel
from reference.glass_meshes import ellipsoid_mesh

N = 1.5


def _cube_lens():
    v, t = box((-0.5, -0.5, 0.0), (0.5, 0.5, 1.0))
    return MeshLens((0.0, 0.0, 0.5), 0.9, N, 0.0, v, t)


def _beam_rays(iota, phi):
    """A parallel beam tilted 20° from the vertical over the cube, entering a disc
    of radius 0.85 at (ι, φ) as `beam_trace` parametrises a sun's: origin 4 radii
    up the axis, off it by r sin ι along (cos φ, sin φ) in the frame."""
    u = np.array([np.sin(0.35), 0.0, -np.cos(0.35)])
    e1 = np.cross(u, [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(u, e1)
    iota, phi = np.broadcast_arrays(iota, phi)
    radial = np.cos(phi)[..., None] * e1 + np.sin(phi)[..., None] * e2
    origins = np.array([0.0, 0.0, 0.5]) - 3.4 * u + (0.85 * np.sin(iota))[..., None] * radial
    return origins, np.broadcast_to(u, origins.shape).copy()


def test_refinement_traces_each_sub_grid_ray_once():
    """Cells (2, 3), (2, 4), (3, 3), (3, 4) side by side and (5, 11) on the azimuth's
    wrap of a 6 × 12 grid, each refined 3 × 3 (m = 2): the block's 5 × 5 lattice
    has 9 node points, so 16 rays; the lone cell 9 less its 4 corners (the two on
    φ = 2π being column 0's nodes), 5: 21 traced, against 45 when every cell traced
    its own 9. Each sub-ray's branches are what a trace of that very ray gives."""
    lens = _cube_lens()
    nr, na, m = 6, 12, 2
    iota = 0.5 * np.pi * np.arange(nr + 1) / nr
    phi = 2.0 * np.pi * (np.arange(na) + 0.5) / na
    dp = 2.0 * np.pi / na
    node_o, node_d = _beam_rays(iota[:, None], phi[None, :])
    node_br = lens.trace_branches(node_o[None], node_d[None], 8, 5e-3)
    ic = np.array([2, 2, 3, 3, 5])
    jc = np.array([3, 4, 3, 4, 11])
    a = np.arange(m + 1) / m
    si = iota[ic][:, None, None] + (iota[ic + 1] - iota[ic])[:, None, None] * a[None, :, None]
    sp = phi[jc][:, None, None] + dp * a[None, None, :]
    o, d = _beam_rays(si, sp)
    kc = np.zeros(len(ic), dtype=np.int64)
    br, n = mesh_beam._sub_branches(lens, node_br, (1, nr, na), kc, ic, jc, m, o, d, 8, 5e-3)
    assert n == 21
    want = lens.trace_branches(o, d, 8, 5e-3)
    for c in range(len(ic)):
        for i in range(m + 1):
            for j in range(m + 1):
                got_w = br.weight[:, c, i, j]
                ref_w = want.weight[:, c, i, j]
                got_s = br.signature[:, c, i, j][got_w > 0]
                ref_s = want.signature[:, c, i, j][ref_w > 0]
                assert sorted(got_s.tolist()) == sorted(ref_s.tolist())
                # the same paths: weights and exit points (the node's (ι, φ) may differ
                # from the cell's own sum in its last bit)
                gk, rk = np.argsort(got_s), np.argsort(ref_s)
                np.testing.assert_allclose(got_w[got_w > 0][gk], ref_w[ref_w > 0][rk], atol=1e-9)
                gp = br.points[:, c, i, j][got_w > 0][gk]
                rp = want.points[:, c, i, j][ref_w > 0][rk]
                np.testing.assert_allclose(gp, rp, atol=1e-9)


def _rays_into_cube(n, seed):
    """`n` rays from above the cube (random origins) toward random points about its
    centre (unit directions)."""
    rng = np.random.default_rng(seed)
    o = rng.uniform(-0.4, 0.4, (n, 3)) + [0.0, 0.0, 2.5]
    d = np.array([0.0, 0.0, 0.5]) + rng.uniform(-0.4, 0.4, (n, 3)) - o
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return o, d


def test_threaded_walk_gives_the_one_walks_branches(monkeypatch):
    """5 000 rays through a cube (internal reflections, TIR) in blocks over 3 threads:
    every field of every branch equal, bit for bit, to the walk in one thread."""
    lens = _cube_lens()
    o, d = _rays_into_cube(5000, seed=4)
    monkeypatch.setattr(parallel, "cores", lambda: 1)
    one = lens.trace_branches(o, d)
    monkeypatch.setattr(parallel, "cores", lambda: 3)
    monkeypatch.setattr(mesh_lens, "WALK_ROWS", 256)
    assert parallel.workers(len(o), mesh_lens.WALK_ROWS) == 3
    three = lens.trace_branches(o, d)
    for f in ("points", "directions", "weight", "hit", "path", "crossings", "signature"):
        np.testing.assert_array_equal(getattr(three, f), getattr(one, f), err_msg=f)
    for f in ("exit_face", "absorbed", "dropped", "leaked"):
        np.testing.assert_array_equal(getattr(three, f), getattr(one, f), err_msg=f)


def test_a_generate_sized_walk_runs_in_one_thread(monkeypatch):
    """Generate's glass trace walks ~17 000 rays (the speed bench's pebble: 16 640):
    split over two threads, its short numpy steps waited for the GIL (the walk's wall
    time the same, its CPU up to 25 % more: issue 25), so it walks in the calling
    thread, on two cores too."""
    lens = _cube_lens()
    o, d = _rays_into_cube(16_640, seed=5)
    monkeypatch.setattr(parallel, "cores", lambda: 2)
    pools = []
    plain = parallel.map_slices

    def counted(fn, n_rows, min_rows=None, threads=None):
        pools.append(threads if threads is not None else parallel.workers(n_rows, min_rows))
        return plain(fn, n_rows, min_rows, threads)

    monkeypatch.setattr(parallel, "map_slices", counted)
    out = lens.trace_branches(o, d)
    assert out.points.shape[1] == 16_640
    assert all(n == 1 for n in pools)


def test_the_main_sheet_of_a_pebble_is_its_direct_path():
    """An oblate pebble (semi-axes 0.5, 0.5, 0.25, smooth) 1 m up, a point light 3 m
    above it: the light going straight through (transmitted twice, ~0.92 of what
    enters) is the main sheet on the node grid, not the partial internal reflection
    (~4 %), which reaches more cells (every cell the direct path does, and the rim's
    total reflections) and was the main sheet when counted by cells; the direct path
    then went as thousands of separate quads."""
    c, axes = (0.0, 0.0, 1.0), (0.5, 0.5, 0.25)
    v, t, nrm = ellipsoid_mesh(c, axes, None, 24, 48)
    ctr = 0.5 * (v.min(axis=0) + v.max(axis=0))
    r = float(np.linalg.norm(v - ctr, axis=1).max()) * (1 + 1e-9)
    rec = Lens(ctr, r, N, kind="mesh", params=(v, t, nrm[t]))
    beam = trace_beam(PointLight(np.array([0.3, 0.2, 4.0]), 1000.0), rec, 32, 128)
    main = beam.cell_flux.sum()
    drawn = main + sum(p.cell_flux.sum() for p in beam.parts)
    assert all(p.cell_flux.sum() < main for p in beam.parts)
    # 0.77 of all that came through: the rest is the rim's refined cells (any path)
    # and the internal reflections; the reflection as main sheet carried ~0.13
    assert main > 0.6 * drawn, main / drawn
