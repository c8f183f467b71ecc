"""The report's ray count (`plan.figures_of`, issue 25): the rays traced from the
lights — a ball's node rays, a glass mesh's node and refinement rays as its tracer
is given them — not the nodes the layer lands (a mesh's quads land their own corners,
its refined cells land as splats)."""

import numpy as np
from glass_meshes import box

from core.caustic_layer.emitters import Lens, PointLight
from core.caustic_layer.pipeline import SheetSource, bake
from core.caustic_layer.plan import figures_of
from core.caustic_layer.receiver_index import build_index
from core.lens.mesh import MeshLens
from reference.meshes import rectangle

N = 1.5


def _scene():
    """A point light, a glass ball and a glass cube (a mesh lens) over a floor."""
    v, t = box((-0.5, -0.5, 0.0), (0.5, 0.5, 1.0))
    c = 0.5 * (v.min(axis=0) + v.max(axis=0))
    r = float(np.linalg.norm(v - c, axis=1).max()) * (1 + 1e-9)
    cube = Lens(c, r, N, kind="mesh", params=(v, t, None))
    ball = Lens(np.array([-2.0, 0.0, 0.5]), 0.5, N)
    floor = build_index(rectangle([0, 0, -0.001], [0, 0, 1], 16.0, 16.0))
    return PointLight(np.array([2.5, 0.7, 3.0]), 1000.0), ball, cube, floor


def _count_handed(monkeypatch) -> list:
    """The rays the glass mesh's tracer is handed, one entry per call."""
    handed = []
    plain = MeshLens.trace_branches

    def counted(self, origins, *args, **kwargs):
        handed.append(int(np.asarray(origins).size // 3))
        return plain(self, origins, *args, **kwargs)

    monkeypatch.setattr(MeshLens, "trace_branches", counted)
    return handed


def test_the_report_counts_the_rays_traced(monkeypatch):
    light, ball, cube, floor = _scene()
    handed = _count_handed(monkeypatch)
    out = bake([SheetSource(light, ball), SheetSource(light, cube)], floor, grid=(24, 96))
    # the ball: one point-light sample, (24 + 1) × 96 node rays
    ball_rays = 25 * 96
    assert out.refinement[1][0] > 0  # the cube's refinement traced rays too
    assert len(handed) >= 2
    assert figures_of(out).rays == ball_rays + sum(handed)
    # (the nodes the layer lands are another number: the old count)
    assert out.layer.n_rays != ball_rays + sum(handed)


def test_the_count_includes_the_coarse_probe(monkeypatch):
    """Without a given grid a coarse 4 × 16 trace places the rays first: its rays are
    traced too (the ball's (4 + 1) × 16, the cube's as its tracer is handed them)."""
    light, ball, cube, floor = _scene()
    handed = _count_handed(monkeypatch)
    out = bake(
        [SheetSource(light, ball), SheetSource(light, cube)], floor, max_rays=4096, min_rays=1024
    )
    b = out.budgets[0]
    ball_rays = (4 + 1) * 16 + (b.n_radial + 1) * b.n_azimuth  # one point-light sample
    assert figures_of(out).rays == ball_rays + sum(handed)
