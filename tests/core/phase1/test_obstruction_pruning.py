"""The broad phase's coarse-first pruning (`obstruction.find_blockers`): levels of the
grid are searched coarsest first, and a pair whose farther lens a coarser level has
already shown hidden behind a sphere nearer than the other sphere is dropped.

What could go wrong is the edge of that rule: a nearer total blocker met only on a
finer level, blockers tied in tangent length (the lower index wins), and hidden lenses
that still block lenses behind them. Expected answers are worked out by hand from the
thesis' tests (SPEC §3.5: k blocks i iff R_T,k < R_T,i and α_i + β_k ≥ γ; totally iff
β_k ≥ γ + α_i; the nearest total blocker, then the lowest index), or by every lens
against every sphere written out plainly here.
"""

import math

import numpy as np
import pytest

from core.phase1.obstruction import find_blockers


def _unit(theta_x, theta_y=0.0):
    """Unit vector about +z, tilted by small angles (radians) toward x and y."""
    v = np.array([math.tan(theta_x), math.tan(theta_y), 1.0])
    return v / np.linalg.norm(v)


def _find(dirs, ang, tlen, lenses=None):
    n = len(ang)
    lenses = np.arange(n) if lenses is None else np.asarray(lenses)
    return find_blockers(
        lenses, np.array(dirs), np.array(ang, float), np.array(tlen, float), np.ones(n, bool)
    )


def test_nearer_total_blocker_on_a_finer_level_wins():
    """Lens 0 (α 0.002, far) lies inside both a big disc (β 0.4, tangent 8) and a
    much smaller one (β 0.01, tangent 3, all on the same axis): the big disc's level is
    searched first and hides lens 0, yet the nearest total blocker is the small one."""
    dirs = [_unit(0.0), _unit(0.0), _unit(0.0)]
    got = _find(dirs, [0.002, 0.4, 0.01], [50.0, 8.0, 3.0], lenses=[0])
    assert got.total_blocker.tolist() == [2]
    assert got.unblocked_fraction.tolist() == [0.0]


def test_total_blockers_tied_in_tangent_length_lowest_index_wins():
    """Two total blockers of lens 2 at the same tangent length 5, of very different
    sizes (levels): the coarse one (index 1) hides the lens first, the fine one
    (index 0, lower) must still be met, and it is the answer."""
    dirs = [_unit(0.0), _unit(0.001), _unit(0.0005)]
    # γ(2, 0) = γ(2, 1) ≈ 5e-4; α_2 = 1e-4: both β ≥ γ + α.
    got = _find(dirs, [0.003, 0.5, 1e-4], [5.0, 5.0, 40.0], lenses=[2])
    assert got.total_blocker.tolist() == [0]


def test_hidden_lens_still_blocks_the_lens_behind_it():
    """Lens 1 hides behind sphere 0 (β 0.3, lens 1 0.2 off its axis with α 0.09);
    lens 2 (α 0.02, 0.3 off the axis, far) overlaps both discs without lying inside
    either, so its shadow list holds the hidden lens 1 beside sphere 0."""
    dirs = [_unit(0.0), _unit(0.2), _unit(0.3)]
    d = np.array(dirs)
    gamma = {(i, k): math.acos(min(1.0, float(d[i] @ d[k]))) for i, k in ((1, 0), (2, 0), (2, 1))}
    ang, tlen = [0.3, 0.09, 0.02], [2.0, 10.0, 80.0]
    # By hand: 1 inside 0's disc; 2 overlaps 0 and 1, inside neither.
    assert ang[0] >= gamma[1, 0] + ang[1]
    assert ang[2] + ang[0] >= gamma[2, 0] and ang[0] < gamma[2, 0] + ang[2]
    assert ang[2] + ang[1] >= gamma[2, 1] and ang[1] < gamma[2, 1] + ang[2]
    got = _find(dirs, ang, tlen)
    assert got.total_blocker.tolist() == [-1, 0, -1]
    assert got.shadow_offsets.tolist() == [0, 0, 0, 2]
    assert got.shadow_spheres.tolist() == [0, 1]
    assert 0.0 < got.unblocked_fraction[2] < 1.0


def test_hidden_finer_spheres_still_meet_the_levels_that_matter():
    """Before a level's boxes are met, the finer ones that can make no useful pair
    with them are dropped (`open_to`). Sphere 0 (β 0.3, tangent 1, coarsest) hides
    lenses 1 and 3 first; yet lens 1's nearest total blocker is sphere 2 (β 0.05,
    tangent 0.5, a level between), and the hidden sphere 3 still partly blocks
    lens 4 (β 0.12, tangent 20, a level between, 0.10 from sphere 3): both hidden
    ones must still meet those levels."""
    dirs = [_unit(0.0), _unit(0.05), _unit(0.06), _unit(-0.15), _unit(-0.25)]
    ang, tlen = [0.3, 0.01, 0.05, 0.01, 0.12], [1.0, 10.0, 0.5, 5.0, 20.0]
    got = _find(dirs, ang, tlen)
    # By hand (γ is the difference of the tilts): 0 covers 1 (0.3 ≥ 0.05 + 0.01) and 3
    # (0.3 ≥ 0.15 + 0.01); 2 covers 1 (0.05 ≥ 0.01 + 0.01) and is nearer; 0 and 3
    # overlap 4 (0.25 ≤ 0.42, 0.10 ≤ 0.13), neither covers it; 2 overlaps 0 only.
    assert got.total_blocker.tolist() == [-1, 2, -1, 0, -1]
    assert got.shadow_offsets.tolist() == [0, 1, 1, 1, 1, 3]
    assert got.shadow_spheres.tolist() == [2, 0, 3]


def _every_pair(dirs, ang, tlen):
    """Total blocker and partial list per lens by every lens against every sphere, with
    `math` angles; the tests' floating point differs from the columns' only in γ, so
    the scenes below keep every γ away from the thresholds (checked)."""
    n = len(ang)
    total, lists, margin = [], [], math.inf
    for i in range(n):
        totals, partial = [], []
        for k in range(n):
            if k == i or not tlen[k] < tlen[i]:
                continue
            g = math.acos(max(-1.0, min(1.0, float(dirs[i] @ dirs[k]))))
            margin = min(margin, abs(ang[i] + ang[k] - g), abs(ang[k] - g - ang[i]))
            if ang[i] + ang[k] >= g:
                (totals if ang[k] >= g + ang[i] else partial).append(k)
        if totals:
            near = min(tlen[k] for k in totals)
            total.append(min(k for k in totals if tlen[k] == near))
            lists.append([])
        else:
            total.append(-1)
            lists.append(partial)
    return total, lists, margin


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_crowded_view_with_tied_depths_equals_every_pair(seed):
    """300 discs packed in a small patch of the view, sizes over four octaves (many
    levels) and tangent lengths drawn from only 12 values (many ties): the total
    blockers and shadow lists equal the every-pair loop's."""
    rng = np.random.default_rng(seed)
    n = 300
    dirs = np.array([_unit(x, y) for x, y in rng.uniform(-0.05, 0.05, (n, 2))])
    ang = 0.003 * 2.0 ** rng.uniform(0, 4, n)
    tlen = rng.integers(1, 13, n).astype(float)
    total, lists, margin = _every_pair(dirs, ang, tlen)
    assert margin > 1e-12  # no pair within rounding of a threshold
    assert sum(t >= 0 for t in total) > 30 and sum(map(len, lists)) > 100
    got = _find(dirs, ang, tlen)
    assert got.total_blocker.tolist() == total
    offs = got.shadow_offsets.tolist()
    got_lists = [got.shadow_spheres[a:b].tolist() for a, b in zip(offs, offs[1:], strict=False)]
    assert got_lists == lists
