"""Issue 24, item 6: a sun's partial blockers are combined as the union of their
shadows over the lens's disc, a glass blocker passing its Fresnel share (as for
point lights), not as a product that counts glass opaque. The expected share is
brute force: parallel rays on a fine grid over the lens's disc, each through the
reference tracer's `blocker_transmission` (independent of the code under test)."""

from __future__ import annotations

import numpy as np
import pytest

from core.phase1.all_lights import compute_phase1_primaries
from core.scene.arrays import SceneArrays
from core.scene.primaries import SunPrimary
from reference import Blocker, blocker_transmission

R = 0.5  # the lens, at the origin; the sun shines along −z
N_GRID = 801  # grid points across the lens's disc (≈ 5e5 rays)


def _scene(blockers):
    c = np.array([(0.0, 0.0, 0.0)] + [b.center for b in blockers], dtype=float)
    radius = np.array([R] + [b.radius for b in blockers])
    ior = np.array([1.5] + [b.ior if b.ior is not None else 1.0 for b in blockers])
    kt = np.array([1.0] + [1.0 if b.ior is not None else 0.0 for b in blockers])
    return SceneArrays(np.zeros((0, 3)), np.zeros(0), np.zeros((0, 3)), c, radius, ior, kt)


def _brute_force(blockers, u=(0.0, 0.0, -1.0)):
    """Mean transmission of parallel rays along `u` over the lens's disc (a grid)."""
    x = np.linspace(-R, R, N_GRID)
    gx, gy = np.meshgrid(x, x)
    inside = gx**2 + gy**2 < R * R
    start = np.column_stack([gx[inside], gy[inside], np.full(inside.sum(), 20.0)])
    d = np.broadcast_to(np.asarray(u, dtype=float), start.shape)
    t_end = 20.0  # at the lens's centre plane: every blocker lies upstream of it
    return float(blocker_transmission(start, d, 0.0, t_end, blockers).mean())


def _unblocked(blockers):
    r = compute_phase1_primaries(_scene(blockers), [SunPrimary((0, 0, -1), 1.0)])
    (src,) = [s for s in r.sources if s.lens == 0]
    return src, src.unblocked_fraction


CASES = {
    # two opaque blockers whose shadows overlap on the lens (a product counts the
    # overlap's complement twice)
    "opaque pair": [Blocker((0.35, 0.0, 2.0), 0.3), Blocker((0.25, 0.15, 4.0), 0.3)],
    # one glass blocker: the old product counted it opaque
    "glass": [Blocker((0.3, 0.1, 2.0), 0.35, ior=1.5)],
    # glass and opaque, overlapping one another over the lens
    "glass and opaque": [
        Blocker((0.3, 0.0, 2.0), 0.35, ior=1.5),
        Blocker((0.1, 0.3, 3.0), 0.25),
        Blocker((-0.45, -0.2, 5.0), 0.2, ior=1.33),
    ],
}


@pytest.mark.parametrize("name", list(CASES))
def test_sun_blockers_are_the_union_of_their_shadows(name):
    blockers = CASES[name]
    src, got = _unblocked(blockers)
    truth = _brute_force(blockers)
    assert sorted(src.shadow_list) == list(range(1, len(blockers) + 1))
    # the grid's own error on the rims: ~1e-3 of the disc at 801 points across
    assert got == pytest.approx(truth, abs=2.5e-3)
    # the product with glass counted opaque (the former rule) is far off here
    product = 1.0
    for b in blockers:
        product *= _brute_force([Blocker(b.center, b.radius)])
    assert abs(product - truth) > 0.02


def test_sun_union_keeps_the_single_opaque_blocker_exact():
    """One opaque blocker: the closed-form disc overlap (half-overlapping discs of
    equal radius: 1 − (2π/3 − √3/2)/π)."""
    blockers = [Blocker((R, 0.0, 2.0), R)]
    _src, got = _unblocked(blockers)
    assert got == pytest.approx(1.0 - (2.0 * np.pi / 3.0 - np.sqrt(3.0) / 2.0) / np.pi, rel=1e-9)
