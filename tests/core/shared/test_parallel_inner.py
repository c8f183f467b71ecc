"""Threads inside one light (`core/shared/parallel.py`, issue 16): the threaded maps give the
same arrays as inline, bit for bit, and run inline inside phase 1's light threads.

The threshold is lowered and more cores claimed than the machine may have, so that
small scenes take the threaded path on any machine."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from core.lens.sphere_caps import _segment_area, _segments, cap_overlap_fraction
from core.phase1.point_lights import compute_phase1
from core.phase1.shadow_mask import glass_passed
from core.scene.arrays import SceneArrays
from core.shared import parallel


@pytest.fixture
def threaded(monkeypatch):
    """Every map above 64 rows split over 3 threads."""
    monkeypatch.setattr(parallel, "MIN_ROWS", 64)
    monkeypatch.setattr(parallel, "cores", lambda: 3)


def grid_scene(n_lights=1, side=14, layers=4):
    """Glass balls (radius 0.3, n 1.5, kt 0.9) on a grid, lights above it: crowded
    views with many partial glass blockers."""
    g = np.arange(float(side))
    x, y, z = np.meshgrid(g, g, np.arange(float(layers)), indexing="ij")
    c = np.column_stack([x.ravel(), y.ravel(), z.ravel()])
    n = len(c)
    lights = np.array([[side / 2 - 0.3, side / 2 - 0.7, layers + 1.0]] * n_lights)
    lights[:, 0] += 1.3 * np.arange(n_lights)
    return SceneArrays(
        lights,
        np.ones(n_lights),
        np.ones((n_lights, 3)),
        c,
        np.full(n, 0.3),
        np.full(n, 1.5),
        np.full(n, 0.9),
    )


def table_arrays(result):
    t = result.table
    return {k: v for k, v in vars(t).items() if isinstance(v, np.ndarray)}


def test_slices_cover_the_rows_in_order():
    for n, parts in [(0, 1), (1, 1), (10, 3), (1001, 2), (7, 7)]:
        cut = parallel.split(n, parts)
        assert len(cut) == parts
        assert np.array_equal(np.concatenate([np.arange(n)[s] for s in cut]), np.arange(n))


def test_map_runs_inline_below_the_threshold_and_inside_inline(threaded):
    seen = []

    def who(s):
        seen.append(threading.get_ident())
        return s

    assert parallel.map_slices(who, 63) == [slice(0, 63)]
    with parallel.inline():
        assert parallel.map_slices(who, 10_000) == [slice(0, 10_000)]
        assert parallel.workers(10_000) == 1
    assert set(seen) == {threading.get_ident()}
    assert len(parallel.map_slices(who, 10_000)) == 3
    assert parallel.workers(10_000) == 3


def test_cap_overlap_and_glass_share_threaded_equal_inline(threaded):
    rng = np.random.default_rng(7)
    n = 60_000  # several chunks of glass_passed, threaded and inline
    alpha = rng.uniform(1e-4, 0.5, n)
    beta = rng.uniform(1e-4, 0.5, n)
    gamma = rng.uniform(0.0, 1.0, n) * (alpha + beta)
    ior = rng.choice([1.5, 1.33, 0.8, 1.0], n)
    kt = rng.uniform(0.5, 1.0, n)
    cover = cap_overlap_fraction(alpha, beta, gamma)
    passed = glass_passed(alpha, beta, gamma, ior, kt)
    with parallel.inline():
        assert np.array_equal(cover, cap_overlap_fraction(alpha, beta, gamma))
        assert np.array_equal(passed, glass_passed(alpha, beta, gamma, ior, kt))
    # the two segments sharing their sines: the two separate calls, bit for bit
    both = _segment_area(alpha, beta, gamma) + _segment_area(beta, alpha, gamma)
    assert np.array_equal(_segments(alpha, beta, gamma), both)


def test_phase1_threaded_inside_a_light_equals_inline(threaded):
    scene = grid_scene()
    got = compute_phase1(scene)
    with parallel.inline():
        ref = compute_phase1(scene)
    assert got.table.shadow_spheres.size > 1000  # crowded: the threaded paths ran
    a, b = table_arrays(got), table_arrays(ref)
    assert a.keys() == b.keys()
    for k in a:
        assert np.array_equal(a[k], b[k], equal_nan=a[k].dtype.kind == "f"), k
    for k in ("light", "lens", "code", "other"):
        assert np.array_equal(getattr(got.skip_table, k), getattr(ref.skip_table, k)), k


def test_light_threads_run_every_light_inline(threaded, monkeypatch):
    """Lights side by side in threads: no map inside them starts threads."""
    calls = []
    real = parallel.map_slices

    def spy(fn, n_rows, min_rows=None, threads=None):
        calls.append(parallel.workers(n_rows, min_rows) if threads is None else threads)
        return real(fn, n_rows, min_rows, threads)

    for mod in ("core.lens.sphere_caps", "core.phase1.shadow_mask", "core.phase1.obstruction"):
        monkeypatch.setattr(f"{mod}.map_slices", spy)
    scene = grid_scene(n_lights=3, side=10, layers=3)
    got = compute_phase1(scene, workers=2)
    assert calls and set(calls) == {1}
    one = compute_phase1(scene, workers=1)  # lights one after another: threads inside
    assert max(calls) == 3
    a, b = table_arrays(got), table_arrays(one)
    for k in a:
        assert np.array_equal(a[k], b[k], equal_nan=a[k].dtype.kind == "f"), k
