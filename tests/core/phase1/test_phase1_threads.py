"""Phase 1 with its lights computed side by side in threads gives exactly what one
thread gives: the same sources in the same order, the same skipped pairs."""

import dataclasses
import math

import numpy as np
import pytest
from random_scenes import random_scene

from core.phase1.point_lights import compute_phase1
from core.scene.arrays import SceneArrays
from core.scene.model import Light, Sphere, Surface


def _same(a, b):
    for f in dataclasses.fields(a):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if isinstance(x, np.ndarray):
            np.testing.assert_array_equal(x, y, err_msg=f.name)


def _crowded(seed):
    """Many lights, spheres close together (partial and total blockers, glass and
    opaque), a light inside a sphere and one with a NaN position (skipped pairs of
    every kind from every thread)."""
    scene = random_scene(seed, n_lights=9, n_spheres=400, spread=5.0)
    scene.lights.append(Light(position=(0.0, 0.0, 0.0), brightness=1.0))
    scene.objects.append(Sphere(center=(0.0, 0.0, 0.0), radius=0.5, surface=Surface(1.0, 1.5)))
    a = SceneArrays.from_scene(scene)
    a.light_position[3] = math.nan
    return a


@pytest.mark.parametrize("seed", [1, 2])
@pytest.mark.parametrize("workers", [2, 3, 16])
def test_threads_give_what_one_thread_gives(seed, workers):
    a = _crowded(seed)
    one = compute_phase1(a, workers=1)
    many = compute_phase1(a, workers=workers)
    assert len(one.table) > 100 and (one.table.shadow_offsets[-1] > 50)
    codes = set(one.skip_table.code.tolist())
    assert {0, 3, 8, 10} <= codes  # invalid light, opaque, light inside another, blocked
    _same(one.table, many.table)
    _same(one.skip_table, many.skip_table)


def test_the_default_threads_only_big_scenes():
    from core.phase1.point_lights import THREADED_SPHERES, _default_workers

    assert _default_workers(1, 10**6) == 1
    assert _default_workers(8, THREADED_SPHERES - 1) == 1
    assert 1 <= _default_workers(8, THREADED_SPHERES) <= 8
