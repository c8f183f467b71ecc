"""The coarse probe of a glass mesh's beam (`pipeline.bake` places the rays and texels
from it, issue 25's Generate speed): its cells on an edge of the beam refined at
`mesh_beam.REFINE_SUB` per side only (not 6 × 6 within `REFINE_FLOOR`: ~1 200 rays of
the pebble's Generate spent on a 4 × 16 look), its flux still the beam's."""

import numpy as np

from core.caustic_layer import mesh_beam
from core.caustic_layer.beam_trace import trace_beams
from core.caustic_layer.emitters import Lens, PointLight
from reference.glass_meshes import ellipsoid_mesh


def _pebble():
    v, t, nrm = ellipsoid_mesh((0.0, 0.0, 1.0), (0.5, 0.5, 0.25), None, 32, 32)
    c = 0.5 * (v.min(axis=0) + v.max(axis=0))
    r = float(np.linalg.norm(v - c, axis=1).max()) * (1 + 1e-9)
    return Lens(c, r, 1.5, kind="mesh", params=(v, t, nrm[t]))


def test_the_probe_refines_its_edge_cells_three_by_three_and_keeps_the_flux():
    light = PointLight(np.array([0.3, 0.2, 4.0]), 1000.0)
    pair = [(light, _pebble())]
    probe = trace_beams(pair, 4, 16, probe=True)[0]
    full = trace_beams(pair, 4, 16)[0]
    fine = trace_beams(pair, 64, 256)[0]
    assert probe.refined_cells == full.refined_cells > 0  # the same cells refined
    # 5 × 16 node rays, then at most (REFINE_SUB + 1)² new rays a refined cell
    sub = (mesh_beam.REFINE_SUB + 1) ** 2
    assert 5 * 16 < probe.traced_rays <= 5 * 16 + sub * probe.refined_cells
    assert full.traced_rays > 4 * probe.traced_rays
    # the flux through the glass: the fine grid's within 0.5 % (the full probe's too)
    assert abs(probe.total_flux / fine.total_flux - 1.0) < 5e-3
    assert abs(full.total_flux / fine.total_flux - 1.0) < 5e-3
