"""The layer's splat in threads (`rasters._splat_cells`: its subdivision levels side by
side, `core.shared.parallel.map_items`) draws the same layer as one level after the
other, bit for bit: a glass pebble under a sphere light (its samples' shares jitter
the sub-cells) seen by a camera that sees part of the caustic (a fine raster and a
coarse one that takes what lands beyond it)."""

import math

import numpy as np
import pytest
from glass_meshes import sphere

from core.caustic_layer.beam_trace import trace_beam
from core.caustic_layer.emitters import Lens, PointLight
from core.caustic_layer.rasters import build_layer
from core.caustic_layer.receiver_index import build_index
from core.caustic_layer.view import view_of
from core.scene.model import Camera as ModelCamera
from core.shared import parallel
from reference.meshes import rectangle


def _layer():
    v, t, nrm = sphere(1.0, 12, 24)
    v = v * [1.0, 1.0, 0.5]
    c = 0.5 * (v.min(axis=0) + v.max(axis=0))
    r = float(np.linalg.norm(v - c, axis=1).max()) * (1 + 1e-9)
    lens = Lens(c, r, 1.5, kind="mesh", params=(v, t, nrm))
    light = PointLight(np.array([0.0, 0.0, -8.0]), 4.0 * math.pi, radius=0.4)
    floor = build_index(rectangle([0, 0, 3.0], [0, 0, 1], 60.0, 60.0, 4, 4))
    cam = ModelCamera(
        position=(1.5, 0.0, 2.0), target=(1.5, 0.0, 3.0), up=(0.0, 1.0, 0.0), fov_deg=(90, 90)
    )
    beam = trace_beam(light, lens, 16, 64, n_source=4)
    return build_layer([beam], floor, resolution=128, view=view_of(cam, 120, 120))


def test_the_splat_in_threads_draws_the_same_layer_bit_for_bit(monkeypatch):
    inline = _layer()
    levels = []
    plain = parallel.map_items

    def threaded(fn, items, work=None):
        items = list(items)
        levels.append(len(items))
        return plain(fn, items)  # no work figure: threads however small

    monkeypatch.setattr(parallel, "cores", lambda: 3)
    monkeypatch.setattr(parallel, "map_items", threaded)
    both = _layer()
    # several levels, a fine and a coarse raster, the shares' jitter: all on the path
    assert levels and max(levels) >= 3
    assert sorted(p.coarse for p in inline.patches) == [False, True]
    assert inline.n_subcells == both.n_subcells > 0
    _assert_same_layer(inline, both)


def _assert_same_layer(a, b):
    """Two layers' irradiance and fluxes, bit for bit."""
    for p, q in zip(a.patches, b.patches, strict=True):
        assert np.array_equal(p.irradiance, q.irradiance)
        assert p.flux == q.flux and p.flux_outside == q.flux_outside
    assert a.flux_in_rasters == b.flux_in_rasters
    assert a.flux_outside == b.flux_outside


@pytest.mark.parametrize("n", [0, 1, 5])
def test_map_items_keeps_the_order_and_runs_inline_inside_inline(monkeypatch, n):
    monkeypatch.setattr(parallel, "cores", lambda: 3)
    names = []

    def job(x):
        import threading

        names.append(threading.current_thread().name)
        return x * x

    assert parallel.map_items(job, range(n)) == [x * x for x in range(n)]
    names.clear()
    with parallel.inline():
        assert parallel.map_items(job, range(n)) == [x * x for x in range(n)]
    assert set(names) <= {"MainThread"}
    # below the work threshold: inline too
    names.clear()
    assert parallel.map_items(job, range(n), work=10) == [x * x for x in range(n)]
    assert set(names) <= {"MainThread"}


def test_the_splat_in_blocks_draws_the_same_layer_bit_for_bit(monkeypatch):
    """Each level's sub-cells worked out in blocks of cells (`rasters.SPLAT_BLOCK`, its
    scratch arrays reused) and summed as one: small blocks (cut anywhere, also through
    the shares' low-discrepancy sequence and the coarse raster's sub-cells) draw the
    layer of one block per level, bit for bit."""
    from core.caustic_layer import rasters

    monkeypatch.setattr(rasters, "SPLAT_BLOCK", 1 << 40)
    whole = _layer()
    monkeypatch.setattr(rasters, "SPLAT_BLOCK", 1000)
    blocks = _layer()
    assert whole.n_subcells == blocks.n_subcells > 100_000
    _assert_same_layer(whole, blocks)
