"""The dense-grid speed-ups checked against plain references (issue 16):

- a glass blocker's Fresnel share over what it covers of the lens' cap
  (`shadow_mask.glass_passed`, a 1-D quadrature in 1 − cos θ over the pieces that hold
  any of the cap) against a brute-force midpoint grid over the blocker's disc in its
  own polar angles, with the Fresnel equations written out here;
- in a crowded view (`shadow_mask.MAX_INTERACTIONS`), rows whose blockers overlap
  as the product of what each leaves, their glass shares by the coarse 6-node rule
  (`shadow_mask._CROWDED_RULE`), rows whose blockers are apart as the sum with the
  8-node rule, against the same brute-force grid;
- the rows whose blockers' caps overlap (`shadow_mask._overlapping_rows`, consecutive
  blockers first) against every pair of every row;
- the broad phase (`obstruction._candidate_pairs`, boxes sorted by level, queries cut
  to the owners' bounding box) against every pair of spheres, on views the dense grid
  does not have: coincident spheres, a few huge near discs off to one side of many
  tiny ones, lenses behind the light.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from core.lens.sphere_caps import angle_between, cap_overlap_fraction, radial_angle
from core.phase1.obstruction import _candidate_pairs
from core.phase1.shadow_mask import (
    _CROWDED_RULE,
    MAX_INTERACTIONS,
    _overlapping_rows,
    glass_passed,
    union_unblocked,
)


def fresnel_two_surfaces(sin_i, n):
    """Unpolarised two-surface power transmittance (s and p each through both
    surfaces), 0 beyond total reflection; numpy arrays."""
    cos_i = np.sqrt(np.maximum(0.0, 1.0 - sin_i * sin_i))
    k = 1.0 - (sin_i / n) ** 2
    cos_t = np.sqrt(np.maximum(0.0, k))
    ts = 1.0 - ((cos_i - n * cos_t) / (cos_i + n * cos_t)) ** 2
    tp = 1.0 - ((cos_t - n * cos_i) / (cos_t + n * cos_i)) ** 2
    return np.where(k > 0.0, 0.5 * (ts * ts + tp * tp), 0.0)


def brute_passed(alpha, beta, gamma, n, kt, steps=1500):
    """Mean of kt² T(ι) over the blocker's cap ∩ the lens' cap: midpoints in the
    blocker's polar angles (θ from its centre, φ about it), the lens' axis γ away."""
    t = (np.arange(steps) + 0.5) * beta / steps
    p = (np.arange(2 * steps) + 0.5) * math.pi / steps
    T, P = np.meshgrid(t, p, indexing="ij")
    cos_d = np.cos(T) * math.cos(gamma) - np.sin(T) * math.sin(gamma) * np.cos(P)
    inside = cos_d >= math.cos(alpha)
    trans = kt * kt * fresnel_two_surfaces(np.sin(T) / math.sin(beta), n)
    w = np.sin(T) * inside
    return float((trans * w).sum() / w.sum())


@pytest.mark.parametrize(
    "alpha, beta, gamma, n, kt",
    [
        (0.1, 0.05, 0.09, 1.5, 1.0),  # across the lens' rim, its centre outside the cap
        (0.1, 0.06, 0.05, 1.5, 0.9),  # centre inside the cap, disc across the rim
        (0.1, 0.03, 0.02, 1.5, 1.0),  # wholly inside the cap (grazing rim included)
        (0.1, 0.05, 0.0, 1.33, 1.0),  # centred on the lens' axis
        (0.1, 0.06, 0.09, 0.8, 1.0),  # index below 1: total reflection near its rim
        (0.1, 0.06, 0.03, 0.8, 0.7),
        (3e-3, 4e-3, 5e-3, 1.5, 1.0),  # a far, tiny pair (the dense grid's horizon)
        (0.2, 0.25, 0.3, 2.4, 1.0),  # a bigger blocker than the lens
    ],
)
def test_glass_share_equals_a_brute_force_grid_over_the_blocker(alpha, beta, gamma, n, kt):
    got = glass_passed(
        np.array([alpha]), np.array([beta]), np.array([gamma]), np.array([n]), np.array([kt])
    )[0]
    assert got == pytest.approx(brute_passed(alpha, beta, gamma, n, kt), abs=3e-4)


def test_glass_share_of_index_one_is_kt_squared_and_many_at_once_equal_one_by_one():
    rng = np.random.default_rng(5)
    m = 10_000  # more than one block of the quadrature
    alpha = rng.uniform(1e-3, 0.2, m)
    beta = alpha * rng.uniform(0.3, 3.0, m)
    gamma = rng.uniform(0.0, 1.0, m) * (alpha + beta)
    n = rng.choice([0.8, 1.0, 1.33, 1.5], m)
    kt = rng.uniform(0.0, 1.0, m)
    all_at_once = glass_passed(alpha, beta, gamma, n, kt)
    one = n == 1.0
    assert np.allclose(all_at_once[one], kt[one] ** 2, rtol=1e-12, atol=0)
    pick = rng.choice(m, 40, replace=False)
    for i in pick:
        single = glass_passed(
            alpha[i : i + 1], beta[i : i + 1], gamma[i : i + 1], n[i : i + 1], kt[i : i + 1]
        )
        assert single[0] == all_at_once[i]
    assert np.all((all_at_once >= 0.0) & (all_at_once <= kt * kt + 1e-15))


def axis_at(gamma, phi):
    return np.array([np.sin(gamma) * np.cos(phi), np.sin(gamma) * np.sin(phi), np.cos(gamma)])


def crowded_view(n_blockers=70, seed=3):
    """Sphere 0: a lens on the z axis (α = 0.1) behind `n_blockers` glass blockers
    scattered over its cap (overlapping one another); sphere 1: a lens far off with
    one blocker (sphere 2) across its rim, alone in its row."""
    rng = np.random.default_rng(seed)
    alpha = 0.1
    beta = rng.uniform(0.01, 0.04, n_blockers)
    gamma = rng.uniform(0.0, 1.0, n_blockers) * (alpha + beta) * 0.95
    phi = rng.uniform(0.0, 2.0 * np.pi, n_blockers)
    blockers = np.array([axis_at(g, p) for g, p in zip(gamma, phi, strict=True)])
    far = axis_at(1.0, 0.3)
    lone = np.cross(far, [0.0, 0.0, 1.0])
    lone = np.cos(0.07) * far + np.sin(0.07) * lone / np.linalg.norm(lone)
    direction = np.vstack([[0.0, 0.0, 1.0], far, lone, blockers])
    ang = np.concatenate([[alpha, 0.05, 0.04], beta])
    ior = np.concatenate([[1.5, 1.5, 1.33], rng.choice([1.33, 1.5, 1.9], n_blockers)])
    kt = np.concatenate([[1.0, 1.0, 0.9], rng.uniform(0.5, 1.0, n_blockers)])
    rows = np.r_[np.zeros(n_blockers, dtype=np.int64), 1]
    obst = np.r_[np.arange(3, 3 + n_blockers), 2]
    return rows, obst, np.array([0, 1]), direction, ang, ior, kt


def shares(rows, obst, lens_rows, direction, ang, ior, kt):
    lens = lens_rows[rows]
    gamma = np.array(
        [angle_between(direction[i], direction[k]) for i, k in zip(lens, obst, strict=True)]
    )
    cover = cap_overlap_fraction(ang[lens], ang[obst], gamma)
    return lens, gamma, cover


def test_crowded_rows_are_the_product_with_coarse_shares_and_apart_rows_the_sum():
    rows, obst, lens_rows, direction, ang, ior, kt = crowded_view()
    assert np.bincount(rows)[0] ** 2 > MAX_INTERACTIONS  # a crowded view
    lens, gamma, cover = shares(rows, obst, lens_rows, direction, ang, ior, kt)
    got = union_unblocked(rows, obst, cover, lens_rows, direction, ang, ior, kt, gamma=gamma)
    crowd = rows == 0
    # a coarse grid suffices for the product's 3e-4 (each share to ~1e-5 of its cover)
    brute = np.array(
        [
            brute_passed(ang[i], ang[k], g, ior[k], kt[k], steps=300 if c else 1500)
            for i, k, g, c in zip(lens, obst, gamma, crowd, strict=True)
        ]
    )
    product = np.prod(1.0 - cover[crowd] * (1.0 - brute[crowd]))
    # 70 coarse shares (each within ~3e-5 × its cover): the product within 3e-4, as
    # README Limits says of a crowded view's rows (here 6e-5)
    assert got[0] == pytest.approx(product, abs=3e-4)
    coarse = glass_passed(
        *(x[crowd] for x in (ang[lens], ang[obst], gamma, ior[obst], kt[obst])), rule=_CROWDED_RULE
    )
    assert got[0] == pytest.approx(np.prod(1.0 - cover[crowd] * (1.0 - coarse)), rel=1e-12)
    # the row alone keeps the sum and the 8-node rule: within 2e-5 (README Limits)
    assert got[1] == pytest.approx(1.0 - cover[~crowd][0] * (1.0 - brute[~crowd][0]), abs=2e-5)


@pytest.mark.parametrize(
    "alpha, beta, gamma, n, kt",
    [
        (0.1, 0.05, 0.09, 1.5, 1.0),
        (0.1, 0.06, 0.05, 1.5, 0.9),
        (0.1, 0.03, 0.02, 1.5, 1.0),
        (3e-3, 4e-3, 5e-3, 1.5, 1.0),
        (0.1, 0.06, 0.09, 0.8, 1.0),
    ],
)
def test_coarse_rule_share_is_within_its_stated_error(alpha, beta, gamma, n, kt):
    args = (np.array([x]) for x in (alpha, beta, gamma, n, kt))
    got = glass_passed(*args, rule=_CROWDED_RULE)[0]
    cover = float(cap_overlap_fraction(alpha, beta, gamma))
    assert abs(got - brute_passed(alpha, beta, gamma, n, kt)) * cover < 1e-4  # 8e-7–3e-5


def test_overlapping_rows_equal_every_pair_of_every_row():
    """Rows of blockers scattered so that some overlap only with a blocker that is not
    their neighbour in the row, some with none, some with several."""
    rng = np.random.default_rng(11)
    s = 400
    v = rng.normal(size=(s, 3)) * [0.05, 0.05, 1.0] + [0.0, 0.0, 3.0]
    direction = v / np.linalg.norm(v, axis=1)[:, None]
    ang = rng.uniform(0.001, 0.02, s)
    rows, obst = [], []
    n_rows = 300
    for r in range(n_rows):
        k = np.sort(rng.choice(s, rng.integers(0, 7), replace=False))
        rows += [r] * k.size
        obst += k.tolist()
    rows, obst = np.array(rows, dtype=np.int64), np.array(obst, dtype=np.int64)
    count = np.bincount(rows, minlength=n_rows)
    got = _overlapping_rows(rows, obst, count, direction, ang, n_rows)
    want = np.zeros(n_rows, dtype=bool)
    for r in range(n_rows):
        k = obst[rows == r]
        for i in range(k.size):
            for j in range(i + 1, k.size):
                gap = angle_between(direction[k[i]], direction[k[j]])
                want[r] |= bool(gap < ang[k[i]] + ang[k[j]])
    assert 0 < want.sum() < n_rows
    assert np.array_equal(got, want)


def every_overlapping_pair(direction, ang, keep):
    i, k = np.triu_indices(len(ang), 1)
    both = keep[i] & keep[k]
    i, k = i[both], k[both]
    overlap = ang[i] + ang[k] >= angle_between(direction[i], direction[k])
    return set(zip(i[overlap].tolist(), k[overlap].tolist(), strict=True))


def broad_pairs(direction, ang, keep):
    p, q = _candidate_pairs(direction, ang, keep, keep)
    pairs = list(zip(np.minimum(p, q).tolist(), np.maximum(p, q).tolist(), strict=True))
    assert len(pairs) == len(set(pairs))  # each once
    return set(pairs)


def view(centers, radii, light):
    v = centers - np.asarray(light, dtype=float)
    d = np.linalg.norm(v, axis=1)
    keep = d > radii
    return v / d[:, None], np.where(keep, radial_angle(d, radii), 0.0), keep


def test_broad_phase_keeps_every_overlap_of_coincident_spheres():
    rng = np.random.default_rng(2)
    c = rng.uniform(-3, 3, (200, 3))
    r = rng.uniform(0.05, 0.4, 200)
    c[100:150], r[100:150] = c[:50], r[:50]  # 50 exact duplicates
    c[150:175] = c[:25]  # same centre, another radius
    direction, ang, keep = view(c, r, (0.3, -0.2, 8.0))
    assert every_overlapping_pair(direction, ang, keep) <= broad_pairs(direction, ang, keep)


def test_broad_phase_keeps_every_overlap_of_huge_near_discs_off_to_one_side():
    """A few spheres close to the light on one side (discs of many levels, owners'
    bounding boxes small), thousands of far small ones all around, some spheres
    behind the light: the queries cut to each level's owners must lose no pair."""
    rng = np.random.default_rng(4)
    far = rng.normal(size=(3000, 3))
    far = far / np.linalg.norm(far, axis=1)[:, None] * rng.uniform(20, 60, (3000, 1))
    near = np.array([1.0, 0.0, 0.0]) + rng.normal(scale=0.3, size=(12, 3))
    c = np.vstack([far, near])
    r = np.r_[rng.uniform(0.05, 0.3, 3000), rng.uniform(0.05, 0.5, 12)]
    direction, ang, keep = view(c, r, (0.0, 0.0, 0.0))
    assert ang[3000:].max() > 50 * np.median(ang[:3000])
    want = every_overlapping_pair(direction, ang, keep)
    assert any(i >= 3000 or k >= 3000 for i, k in want)
    assert want <= broad_pairs(direction, ang, keep)
