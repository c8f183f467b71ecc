"""Linking groups (core/plan/linking.py): hand-built scenes, and every beam checked
by brute force (points sampled inside each sphere, tested against the beam's
directions by their own angle and distance) against the groups."""

import math
import time

import numpy as np

from core.plan.linking import (
    Beams,
    merge_bands,
    plan_linking,
    profile_bands,
    reach_pairs,
    sets_used,
)

R = 0.01  # 2 cm marbles


def _grid(k, spacing=3 * R, z=R):
    x = (np.arange(k) - (k - 1) / 2) * spacing
    X, Y = np.meshgrid(x, x, indexing="ij")
    return np.stack([X.ravel(), Y.ravel(), np.full(k * k, z)], axis=1)


def _beams(apex, axis, half_angle_deg, radius=0.0, lens=None, bands=None):
    n = len(apex)
    axis = np.broadcast_to(np.asarray(axis, float), (n, 3))
    axis = axis / np.linalg.norm(axis, axis=1, keepdims=True)
    if bands is None:
        edges = np.tile([-np.inf, np.inf], (n, 1))
        angle = np.full((n, 1), math.radians(half_angle_deg))
    else:
        edges = np.tile(bands[0], (n, 1))
        angle = np.tile(bands[1], (n, 1))
    return Beams(
        apex=np.asarray(apex, float),
        axis=axis,
        radius=np.full(n, radius),
        lens=np.arange(n) if lens is None else np.asarray(lens),
        band_edges=edges,
        band_angle=angle,
    )


def _brute_reached(beams, center, radius, samples=4000, seed=1):
    """(light, sphere) pairs some sampled point of the (light-radius inflated) sphere
    lies in the beam: h along the axis in a band whose half-angle exceeds its angle."""
    rng = np.random.default_rng(seed)
    d = rng.normal(size=(samples, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    r = rng.random(samples) ** (1 / 3)
    d = np.concatenate([d, -d, [[0, 0, 0]]]) * np.concatenate([r, r, [0]])[:, None]
    out = set()
    for i in range(len(beams.lens)):
        for s in range(len(center)):
            p = center[s] + d * (radius[s] + beams.radius[i]) - beams.apex[i]
            dist = np.linalg.norm(p, axis=1)
            h = p @ beams.axis[i]
            ang = np.arccos(np.clip(h / np.maximum(dist, 1e-300), -1, 1))
            e, a = beams.band_edges[i], beams.band_angle[i]
            band = np.clip(np.searchsorted(e, h, side="right") - 1, 0, len(a) - 1)
            if np.any((dist < 1e-12) | ((a[band] >= 0) & (ang < a[band]))):
                out.add((i, s))
    return out


def _check(beams, center, radius, owner, plan):
    """Every pair the brute force finds is found; no linked light reaches another
    lens of its group unless listed as a conflict; every light reaching its own lens
    is linked (with a group)."""
    rows, spheres = reach_pairs(beams, center, radius)
    found = set(zip(rows.tolist(), spheres.tolist(), strict=True))
    brute = _brute_reached(beams, center, radius)
    assert brute <= found, sorted(brute - found)[:5]
    listed = set(plan.conflicts)
    for i, s in brute:
        mine = beams.lens[i]
        if s == mine:
            assert plan.linked[i] and plan.group[owner[mine]] >= 0
        elif plan.linked[i] and plan.group[owner[s]] == plan.group[owner[mine]]:
            assert (i, s) in listed or (i, s) in plan.instances, (i, s)


def test_81_resting_marbles_lights_at_their_centres_pointing_down_share_one_group():
    # the near field: each light at its marble's centre, a 60° cone downward; a
    # neighbour 3 R away is 90° off the axis and subtends asin(1/3) = 19.5°: unreached
    c = _grid(9)
    beams = _beams(c, (0, 0, -1), 60.0)
    owner = np.arange(81)
    plan = plan_linking(beams, c, np.full(81, R), owner)
    assert plan.linked.all()
    assert plan.groups == 1 and (plan.group == 0).all()
    assert plan.conflicts == []
    _check(beams, c, np.full(81, R), owner, plan)


def test_lights_reaching_their_row_get_distinct_groups():
    # each light at its centre, aimed along +x with a 10° cone: it reaches every
    # marble further along its row (9 in a row: a 9-clique), none of the other rows
    # (3 R aside at ≥ 3 R: the cone 10° + asin(1/3)… only ahead, angle ≥ 45° − …)
    c = _grid(9)
    beams = _beams(c, (1, 0, 0), 10.0)
    owner = np.arange(81)
    radius = np.full(81, R)
    plan = plan_linking(beams, c, radius, owner)
    assert plan.linked.all() and plan.conflicts == []
    rows = plan.group.reshape(9, 9)  # [i (x), j (y)]
    for j in range(9):  # a row along x: all different
        assert len(set(rows[:, j].tolist())) == 9
    assert plan.groups == 9
    _check(beams, c, radius, owner, plan)


def test_a_floating_ball_whose_image_is_far_below_needs_no_linking():
    # the ball at z = 1 (R = 0.05), its light 0.3 below the centre, cone 20° down:
    # the ball is behind the apex (outside its cone): nothing to link
    c = np.array([[0.0, 0.0, 1.0]])
    beams = _beams(np.array([[0.0, 0.0, 0.7]]), (0, 0, -1), 20.0)
    plan = plan_linking(beams, c, np.array([0.05]), np.array([0]))
    assert not plan.linked.any() and plan.groups == 0 and plan.group[0] == -1
    # aimed away, even just behind the back pole (0.06 below, 80°) it cannot reach
    # the ball; with a radius of 0.02 (rays from up to 0.02 around it) it can
    beams = _beams(np.array([[0.0, 0.0, 0.94]]), (0, 0, -1), 80.0)
    assert not plan_linking(beams, c, np.array([0.05]), np.array([0])).linked.any()
    beams = _beams(np.array([[0.0, 0.0, 0.94]]), (0, 0, -1), 80.0, radius=0.02)
    plan = plan_linking(beams, c, np.array([0.05]), np.array([0]))
    assert plan.linked.all() and plan.groups == 1


def test_the_lights_radius_widens_its_reach():
    # a light 0.012 below a marble's bottom … aimed down: unreached with r = 0,
    # reached once its radius (0.02) lets rays leave from beside the marble's bottom
    c = np.array([[0.0, 0.0, R]])
    apex = np.array([[0.0, 0.0, -0.012]])
    assert not plan_linking(_beams(apex, (0, 0, -1), 30.0), c, [R], [0]).linked.any()
    assert plan_linking(_beams(apex, (0, 0, -1), 30.0, radius=0.02), c, [R], [0]).linked.all()


def test_short_budget_still_excludes_every_lens_and_lists_the_conflicts():
    # a row of 10 lights aimed along it: a 10-clique; 4 groups: every light keeps its
    # own lens out, the lenses sharing a group that a light reaches are listed
    c = _grid(1)[:0]
    c = np.stack([np.arange(10) * 3 * R, np.zeros(10), np.full(10, R)], axis=1)
    beams = _beams(c, (1, 0, 0), 10.0)
    owner = np.arange(10)
    radius = np.full(10, R)
    plan = plan_linking(beams, c, radius, owner, budget=4)
    assert plan.linked.all() and plan.groups == 4 and (plan.group >= 0).all()
    assert len(plan.conflicts) > 0
    for i, s in plan.conflicts:
        assert s > i and plan.group[s] == plan.group[i]  # ahead of it, same group
    _check(beams, c, radius, owner, plan)
    # budget 0: nothing linked, all listed as ungrouped
    plan = plan_linking(beams, c, radius, owner, budget=0)
    assert not plan.linked.any() and plan.ungrouped == list(range(10))


def test_instances_of_one_object_share_its_group():
    # spheres 0, 1 are instances of object 0; sphere 2 is object 1. Light of sphere 0
    # aimed at sphere 1 (its own object: an unavoidable conflict), light of sphere 2
    # aimed away from everything
    c = np.array([[0.0, 0, R], [3 * R, 0, R], [0, 9 * R, R]])
    beams = _beams(c[[0, 2]], [[1, 0, 0], [0, 1, 0]], 10.0, lens=[0, 2])
    owner = np.array([0, 0, 1])
    plan = plan_linking(beams, c, np.full(3, R), owner)
    assert plan.linked.all()
    assert plan.instances == [(0, 1)] and plan.conflicts == []
    assert plan.groups == 1  # objects 0 and 1 never meet: one group


def test_random_scenes_against_brute_force():
    rng = np.random.default_rng(5)
    for trial in range(6):
        n = 25
        c = rng.uniform(-0.1, 0.1, size=(n, 3))
        c[:, 2] = rng.uniform(0, 0.05, n)
        radius = rng.uniform(0.004, 0.012, n)
        apex = c + rng.normal(scale=0.01, size=(n, 3))
        axis = rng.normal(size=(n, 3))
        beams = _beams(apex, axis, 0.0, radius=rng.uniform(0, 0.004))
        beams.radius = rng.uniform(0, 0.004, n)
        beams.band_angle[:] = np.radians(rng.uniform(2, 60, (n, 1)))
        if trial % 2:  # two bands: narrow near the apex, wide beyond 0.05
            beams.band_edges = np.tile([-np.inf, 0.05, np.inf], (n, 1))
            beams.band_angle = np.radians(
                np.stack([rng.uniform(2, 20, n), rng.uniform(30, 80, n)], 1)
            )
        owner = np.arange(n) // 2  # pairs of instances
        plan = plan_linking(beams, c, radius, owner, budget=3 + trial)
        _check(beams, c, radius, owner, plan)


def test_profile_bands_follow_the_table_as_the_node_tree_reads_it():
    # 4 rows, 8 columns, γ_max 90°: rows 0–1 lit up to column 1, rows 2–3 to column 7
    px = np.zeros((4, 8))
    px[:2, :2] = 1.0
    px[2:, :] = 1.0
    px[:, -1] = 0.0  # the last column is always 0
    px[2:, 6] = 1.0
    profile = dict(pixels=px, gamma_max_deg=90.0, h_min=0.01, h_max=0.16)
    e, a = profile_bands(profile)
    # row centres h = 0.01·16^((j+.5)/4): 0.01414, 0.02828, 0.05657, 0.1131
    # rows 0–1: up to column 2's centre, u = 2.5/8, γ = 90·u² = 8.789°
    # row 1 → 2 interpolates into row 2's reach: u = 7.5/8, γ = 79.10°
    assert np.allclose(np.degrees(a), [90 * (2.5 / 8) ** 2, 90 * (7.5 / 8) ** 2])
    assert e[0] == -np.inf and e[-1] == np.inf
    assert math.isclose(e[1], 0.01 * 16 ** (1.5 / 4), rel_tol=1e-12)


def test_profile_bands_ignore_the_faint_tails():
    # the same table with a tail of 1e-9 of the peak out to column 6 in rows 0–1:
    # dark (below 1e-6 of the peak), the reach stays at column 2's centre
    px = np.zeros((4, 8))
    px[:2, :2] = 1.0
    px[:2, 2:7] = 1e-9
    px[2:, :7] = 1.0
    profile = dict(pixels=px, gamma_max_deg=90.0, h_min=0.01, h_max=0.16)
    e, a = profile_bands(profile)
    assert np.allclose(np.degrees(a), [90 * (2.5 / 8) ** 2, 90 * (7.5 / 8) ** 2])
    e, a = profile_bands(profile, faint=0.0)  # every non-zero texel
    assert np.allclose(np.degrees(a), [90 * (7.5 / 8) ** 2])


def test_merge_bands_keeps_the_widest():
    e, a = merge_bands([-np.inf, 1, 2, 3, np.inf], [0.1, 0.5, 0.2, 0.9], 2)
    assert len(a) == 2 and a.max() == 0.9 and e[0] == -np.inf and e[-1] == np.inf
    assert (np.diff(e) > 0).all()
    # every original band's angle is covered by its merged band
    for lo, ang in zip([-np.inf, 1, 2, 3], [0.1, 0.5, 0.2, 0.9], strict=True):
        k = np.searchsorted(e, lo, side="right") - 1
        assert a[k] >= ang


def test_sets_used_counts_distinct_memberships():
    # groups 0, 0, 1, none; the user's collection on objects 1 and 3: (0,−1), (0,0),
    # (1,−1), (−1,0) → 4, plus 2 of the user's sets elsewhere
    assert sets_used([0, 0, 1, -1], [-1, 0, -1, 0], 2) == 6


def test_5000_marbles_plan_in_seconds():
    c = _grid(71)[:5000]
    beams = _beams(c, (0.5, 0, -1), 45.0)  # oblique: reaches its +x neighbours' bottoms?
    t = time.perf_counter()
    plan = plan_linking(beams, c, np.full(len(c), R), np.arange(len(c)))
    dt = time.perf_counter() - t
    assert plan.linked.all() and plan.conflicts == [] and plan.groups <= 63
    assert dt < 20.0
