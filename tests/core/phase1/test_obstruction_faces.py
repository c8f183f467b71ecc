"""The broad phase on the cube's faces (issue 16, third round) against every pair.

`obstruction._candidate_pairs` sees the directions on the six faces of a cube (two of
the three coordinates each), owners on every face near enough, each pair kept once,
on a grid of each level's size or, where crowded, of half of it, looked up through a
table or by binary search. Here, against every pair of discs (γ ≤ ρ_a + ρ_b by
`geometry.angle_between`): discs on the axes, the cube's edges and corners (where a
direction's home face changes), huge discs reaching over several faces, tangent discs
on lattices (boxes ending on cell borders), crowded stacks of two sizes beside a
sparse view; and `_faces_near` against the definition of a home face.
"""

from __future__ import annotations

import numpy as np
import pytest

from core.lens.sphere_caps import angle_between
from core.phase1.obstruction import _candidate_pairs, _faces_near


def every_overlapping_pair(direction, ang):
    i, k = np.triu_indices(len(ang), 1)
    overlap = ang[i] + ang[k] >= angle_between(direction[i], direction[k])
    return set(zip(i[overlap].tolist(), k[overlap].tolist(), strict=True))


def broad_pairs(direction, ang):
    keep = np.ones(len(ang), dtype=bool)
    p, q = _candidate_pairs(direction, ang, keep, keep)
    pairs = list(zip(np.minimum(p, q).tolist(), np.maximum(p, q).tolist(), strict=True))
    assert len(pairs) == len(set(pairs))  # each once
    return set(pairs)


def unit(v):
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def home_face(v):
    """Face 2k + 1 (k: the axis of the largest |coordinate|) if it is positive, else 2k."""
    k = int(np.argmax(np.abs(v)))
    return 2 * k + int(v[k] >= 0)


def special_directions():
    """The 6 axes, the 12 edge midpoints and the 8 corners of the cube, exactly."""
    axes = np.vstack([np.eye(3), -np.eye(3)])
    edges = [
        s1 * np.eye(3)[a] + s2 * np.eye(3)[b]
        for a in range(3)
        for b in range(a + 1, 3)
        for s1 in (-1, 1)
        for s2 in (-1, 1)
    ]
    corners = [[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]
    return np.vstack([axes, unit(edges), unit(corners)])


def test_faces_near_holds_the_home_face_of_every_direction_within_reach():
    rng = np.random.default_rng(11)
    base = special_directions()
    a = unit(base[rng.integers(0, len(base), 20_000)] + rng.normal(scale=0.02, size=(20_000, 3)))
    reach = rng.uniform(1e-4, 0.2, 20_000)
    step = unit(rng.normal(size=(20_000, 3))) * (reach * rng.uniform(0, 1, 20_000))[:, None]
    b = unit(a + step)
    inside = np.linalg.norm(a - b, axis=1) <= reach
    near = _faces_near(b, reach)
    got = near[np.arange(len(a)), [home_face(v) for v in a]]
    assert inside.sum() > 15_000
    assert got[inside].all()
    # and it does choose: small reaches away from edges are on one face only
    assert near[reach < 1e-3].sum(axis=1).min() == 1


def test_broad_phase_at_the_axes_edges_and_corners_of_the_cube():
    rng = np.random.default_rng(12)
    base = special_directions()
    exact = np.repeat(base, 3, axis=0)  # each special direction thrice, exactly
    jitter = base[rng.integers(0, len(base), 1500)]
    jitter = unit(jitter + rng.normal(size=(1500, 3)) * rng.choice([1e-4, 1e-3, 1e-2], (1500, 1)))
    direction = np.vstack([exact, jitter])
    ang = rng.choice([1e-4, 5e-4, 2e-3, 1e-2, 0.05], len(direction))
    ang *= rng.uniform(0.5, 1.0, len(direction))
    want = every_overlapping_pair(direction, ang)
    assert len(want) > 1000
    assert want <= broad_pairs(direction, ang)


def test_broad_phase_with_huge_discs_reaching_over_several_faces():
    rng = np.random.default_rng(13)
    direction = unit(rng.normal(size=(1500, 3)))
    ang = rng.uniform(1e-3, 0.03, 1500)
    ang[:12] = [1.5, 1.2, 0.9, 0.7, 0.5, 0.4, 0.3, 0.25, 0.2, 0.15, 1.55, 1.0]
    direction[:4] = special_directions()[[0, 10, 20, 25]]  # an axis, an edge, corners
    want = every_overlapping_pair(direction, ang)
    assert any(i < 12 and k < 12 for i, k in want)
    assert want <= broad_pairs(direction, ang)


@pytest.mark.parametrize("rho", [1e-3, 0.01, 0.07])
def test_broad_phase_keeps_tangent_discs_on_a_lattice(rho):
    """Equal discs 2ρ apart along rows (tangent, γ = ρ_a + ρ_b up to rounding) across the
    edge between two faces and over the +z axis, with smaller discs between them."""
    n = int(0.6 / (2 * rho)) if rho > 0.005 else 40
    steps = np.arange(-n, n + 1) * 2 * rho
    # rows of directions at angles t from +z towards x (through the pole) and, across
    # the x = y edge, around z at the height of that edge
    t = steps[:, None]
    pole = np.column_stack([np.sin(t), np.zeros_like(t), np.cos(t)])
    phi = np.pi / 4 + steps
    edge = np.column_stack([np.cos(phi), np.sin(phi), np.full_like(phi, 0.2)])
    edge = unit(edge)
    small = unit(pole[:-1] + pole[1:])  # between two tangent discs
    direction = np.vstack([pole, edge, small])
    ang = np.r_[np.full(len(pole) + len(edge), rho), np.full(len(small), rho / 8)]
    want = every_overlapping_pair(direction, ang)
    assert len(want) >= len(pole) - 1
    assert want <= broad_pairs(direction, ang)


@pytest.mark.parametrize("rho", [0.1, 0.01])
def test_broad_phase_keeps_every_pair_of_a_crowded_stack(rho):
    """Hundreds of discs on top of each other (many to a cell: the half-size grid), some
    much smaller among them and a few larger, beside a sparse scatter elsewhere."""
    rng = np.random.default_rng(14)
    centre = unit([0.3, -0.8, 0.5])
    stack = unit(centre + rng.normal(scale=2 * rho, size=(1200, 3)))
    sparse = unit(rng.normal(size=(800, 3)))
    direction = np.vstack([stack, sparse])
    ang = np.r_[
        rho * rng.uniform(0.5, 1.0, 1000),
        rho * rng.uniform(0.01, 0.1, 150),
        rho * rng.uniform(2, 8, 50),
        rng.uniform(1e-3, 0.05, 800),
    ]
    want = every_overlapping_pair(direction, ang)
    assert len(want) > 50_000
    assert want <= broad_pairs(direction, ang)
