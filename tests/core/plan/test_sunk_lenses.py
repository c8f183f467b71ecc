"""A lens another surface cuts into (a marble sunk into the table) is found by
`planning.sunk_lenses`; one resting on the table, or overlapping another ball, is not
(issue 28, item 1). The geometry is exact: a plane and spheres hit analytically."""

import numpy as np

from core.plan.planning import SUNK_MARGIN, sunk_lenses
from core.scene.ray_hits import sphere_hits


class TableAndBalls:
    """The plane z = 0 (hit from either side) and spheres."""

    def __init__(self, centers, radii):
        self.centers = np.asarray(centers, float).reshape(-1, 3)
        self.radii = np.asarray(radii, float)

    def first_hit(self, origins, direction, limit):
        origins = np.asarray(origins, float).reshape(-1, 3)
        d = np.asarray(direction, float) / np.linalg.norm(direction)
        best = sphere_hits(self.centers, self.radii, origins, d)
        if d[2] != 0.0:
            t = -origins[:, 2] / d[2]
            best = np.minimum(best, np.where(t > 1e-12, t, np.inf))
        return np.where(best <= limit, best, np.inf)


def _sunk(heights, radius=1.0):
    centers = [(3.0 * k, 0.0, h) for k, h in enumerate(heights)]
    occ = TableAndBalls(centers, [radius] * len(heights))
    return sunk_lenses(occ, centers, [radius] * len(heights)).tolist()


def test_sunk_balls_are_found_and_resting_ones_are_not():
    # centre on the table, half sunk, 10 % sunk; resting (touching), 1 % in (within
    # the margin), floating
    assert _sunk([0.0, 0.5, 0.9]) == [True, True, True]
    assert _sunk([1.0, 1.0 - 0.5 * SUNK_MARGIN, 1.5]) == [False, False, False]
    assert _sunk([-0.3]) == [True]  # centre below the table's plane


def test_a_ball_overlapping_another_is_no_sunk_lens():
    centers = [(0.0, 0.0, 5.0), (1.8, 0.0, 5.0)]  # two balls R 1 overlapping by 0.2
    occ = TableAndBalls(centers, [1.0, 1.0])
    assert sunk_lenses(occ, centers, [1.0, 1.0]).tolist() == [False, False]


def test_scale_does_not_matter():
    for r in (1e-3, 1.0, 50.0):
        assert _sunk([0.0, r * 1.0], radius=r) == [True, False]
