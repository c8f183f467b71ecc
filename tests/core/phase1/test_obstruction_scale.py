"""The culled obstruction (grid broad phase) gives exactly the thesis' full loop.

The reference here is the thesis' algorithm 5.7.1 written out plainly: every lens
against every other sphere, with `math` only.
"""

import math

import numpy as np
import pytest

from core.phase1.point_lights import compute_phase1
from core.scene.arrays import SceneArrays


def thesis_obstruction(a: SceneArrays, j: int):
    """{lens: ("total", k) | ("partial", [k…]) } for light j, by the full O(S²) loop."""
    light = a.light_position[j]
    S = len(a.radius)
    dist = [math.dist(a.center[k], light) for k in range(S)]
    if any(dist[k] <= a.radius[k] for k in range(S)):
        return None  # light inside a sphere: not compared
    tangent = [math.sqrt(dist[k] ** 2 - a.radius[k] ** 2) for k in range(S)]
    radial = [math.asin(a.radius[k] / dist[k]) for k in range(S)]
    unit = [(a.center[k] - light) / dist[k] for k in range(S)]
    out = {}
    for i in range(S):
        if not (a.kt[i] > 0 and a.ior[i] > 1):
            continue
        totals, partial = [], []
        for k in range(S):
            if k == i or not tangent[k] < tangent[i]:
                continue
            cos_g = max(-1.0, min(1.0, float(unit[i] @ unit[k])))
            gamma = math.acos(cos_g)
            if radial[i] + radial[k] >= gamma:
                if radial[k] >= gamma + radial[i]:
                    totals.append((tangent[k], k))
                else:
                    partial.append(k)
        out[i] = ("total", min(totals)[1]) if totals else ("partial", partial)
    return out


def random_scene(rng, n_spheres, n_lights, outliers=False):
    c = rng.uniform(-10, 10, (n_spheres, 3))
    r = rng.uniform(0.1, 0.8, n_spheres)
    if outliers:  # a few spheres far bigger than the rest
        big = rng.choice(n_spheres, size=max(1, n_spheres // 50), replace=False)
        r[big] *= rng.uniform(5, 12, big.size)
    lights = rng.uniform(-25, 25, (n_lights, 3))
    return SceneArrays(
        lights,
        np.ones(n_lights),
        np.ones((n_lights, 3)),
        c,
        r,
        rng.choice([1.0, 1.5], n_spheres),
        rng.choice([0.0, 0.6, 1.0], n_spheres),
    )


@pytest.mark.parametrize("seed", range(12))
def test_culled_obstruction_equals_thesis_loop(seed):
    rng = np.random.default_rng(seed)
    a = random_scene(rng, int(rng.integers(20, 160)), 2, outliers=seed % 2 == 1)
    result = compute_phase1(a)
    compared = 0
    for j in range(2):
        ref = thesis_obstruction(a, j)
        if ref is None:
            continue
        got = {s.lens: ("partial", s.shadow_list) for s in result.sources if s.light == j}
        got.update(
            {
                k.lens: ("total", int(k.reason.rsplit(" ", 1)[1]))
                for k in result.skipped
                if k.light == j and k.reason.startswith("totally blocked")
            }
        )
        assert got == ref
        compared += len(ref)
    assert compared > 0


def test_dense_row_of_lenses_along_a_line_of_sight():
    """Ten lenses in a row on one line of sight, each seen a little bigger than the
    one before: each is partly blocked by every nearer one (all share the same
    direction, the worst case for a spatial search)."""
    n = 10
    dist = 3.0 * (np.arange(n) + 1)
    radii = dist * np.sin(0.1 + 0.01 * np.arange(n))  # radial angle grows
    centers = np.stack([np.zeros(n), np.zeros(n), dist], axis=1)
    a = SceneArrays(
        np.zeros((1, 3)),
        np.ones(1),
        np.ones((1, 3)),
        centers,
        radii,
        np.full(n, 1.5),
        np.full(n, 1.0),
    )
    result = compute_phase1(a)
    assert [s.lens for s in result.sources] == list(range(n))
    assert [s.shadow_list for s in result.sources] == [list(range(i)) for i in range(n)]
    ref = thesis_obstruction(a, 0)
    assert all(ref[i] == ("partial", list(range(i))) for i in range(n))


def dense_grid(nx, ny, nz, light, radius=0.3):
    g = np.meshgrid(np.arange(float(nx)), np.arange(float(ny)), np.arange(float(nz)), indexing="ij")
    c = np.column_stack([x.ravel() for x in g])
    n = len(c)
    return SceneArrays(
        np.array([light], dtype=float),
        np.ones(1),
        np.ones((1, 3)),
        c,
        np.full(n, radius),
        np.full(n, 1.5),
        np.full(n, 0.9),
    )


@pytest.mark.parametrize("light", [(4.7, 4.3, 3.0), (0.5, -1.0, 0.4), (4.5, 4.5, 1.5)])
def test_dense_grid_with_a_close_light_equals_thesis_loop(light):
    """Spheres on a grid, the light just above or beside it (discs of very different
    sizes, heavily overlapping at grazing angles): the crowded case the broad phase
    is tuned for."""
    a = dense_grid(10, 10, 3, light)
    result = compute_phase1(a)
    ref = thesis_obstruction(a, 0)
    got = {s.lens: ("partial", s.shadow_list) for s in result.sources}
    got.update(
        {
            k.lens: ("total", int(k.reason.rsplit(" ", 1)[1]))
            for k in result.skipped
            if k.reason.startswith("totally blocked")
        }
    )
    assert got == ref
    assert sum(v[0] == "total" for v in ref.values()) > 10
    assert sum(len(v[1]) for v in ref.values() if v[0] == "partial") > 100


@pytest.mark.parametrize("seed", range(6))
def test_candidate_pairs_are_each_overlapping_pair_once(seed):
    from core.lens.sphere_caps import angle_between, radial_angle
    from core.phase1.obstruction import _candidate_pairs

    rng = np.random.default_rng(seed)
    a = random_scene(rng, 300, 1, outliers=seed % 2 == 1)
    v = a.center - a.light_position[0]
    d = np.linalg.norm(v, axis=1)
    keep = d > a.radius
    w, rho = v / d[:, None], np.where(keep, radial_angle(d, a.radius), 0.0)
    p, q = _candidate_pairs(w, rho, keep, keep)
    pairs = list(zip(np.minimum(p, q).tolist(), np.maximum(p, q).tolist(), strict=True))
    assert len(pairs) == len(set(pairs))  # each once
    i, k = np.triu_indices(len(d), 1)
    both = keep[i] & keep[k]
    i, k = i[both], k[both]
    overlap = rho[i] + rho[k] >= angle_between(w[i], w[k])
    assert set(zip(i[overlap].tolist(), k[overlap].tolist(), strict=True)) <= set(pairs)


def test_angle_from_columns_is_geometry_angle_between_bit_for_bit():
    from core.lens.sphere_caps import angle_between
    from core.phase1.obstruction import _angle_between_rows

    rng = np.random.default_rng(3)
    v = rng.normal(size=(5000, 3)) * 10.0 ** rng.integers(-8, 8, (5000, 1))
    w = v / np.linalg.norm(v, axis=1)[:, None]
    w[:50] = w[50:100] * (1 + 1e-15)  # nearly parallel pairs
    i, k = rng.integers(0, 5000, 20000), rng.integers(0, 5000, 20000)
    i[:50], k[:50] = np.arange(50), np.arange(50, 100)
    assert np.array_equal(_angle_between_rows(w, i, k), angle_between(w[i], w[k]))


def brute_force_blockers(lens_rows, direction, ang, tlen, obstacle):
    """`find_blockers`' answer by every lens against every sphere, with the same
    floating-point tests (angles by `geometry.angle_between`, which the column
    version equals bit for bit); the partial blockers' shares are combined by
    `shadow_mask.union_unblocked` (tested on its own in tests/core/phase1/test_blockers_union.py)
    from these pairs, so that what is compared here is the broad phase."""
    from core.lens.sphere_caps import angle_between, cap_overlap_fraction
    from core.phase1.shadow_mask import union_unblocked

    total, lists = [], []
    pair_rows, pair_obst, pair_cover = [], [], []
    for row, i in enumerate(lens_rows.tolist()):
        k = np.flatnonzero(obstacle & (tlen < tlen[i]))
        k = k[k != i]
        alpha, beta = ang[i], ang[k]
        gamma = angle_between(np.broadcast_to(direction[i], (k.size, 3)), direction[k])
        blocks = alpha + beta >= gamma
        full = blocks & (beta >= gamma + alpha)
        if full.any():
            kk = k[full]
            near = kk[tlen[kk] == tlen[kk].min()].min()
            total.append(int(near))
            lists.append([])
        else:
            total.append(-1)
            lists.append(k[blocks].tolist())
            cover = cap_overlap_fraction(np.full(blocks.sum(), alpha), beta[blocks], gamma[blocks])
            pair_rows += [row] * int(blocks.sum())
            pair_obst += k[blocks].tolist()
            pair_cover += cover.tolist()
    unblocked = union_unblocked(
        np.array(pair_rows, dtype=np.int64),
        np.array(pair_obst, dtype=np.int64),
        np.array(pair_cover, dtype=float),
        lens_rows,
        direction,
        ang,
    )
    unblocked[np.array(total) >= 0] = 0.0
    return total, lists, unblocked.tolist()


def light_view(a: SceneArrays, j=0):
    """The per-light columns `find_blockers` takes, as phase 1 makes them."""
    from core.lens.sphere_caps import radial_angle

    v = a.center - a.light_position[j]
    d = np.linalg.norm(v, axis=1)
    outside = d > a.radius
    ang = np.where(outside, radial_angle(d, a.radius), 0.0)
    tlen = np.where(outside, np.sqrt(np.maximum(d * d - a.radius**2, 0.0)), 0.0)
    lenses = np.flatnonzero(outside & (a.kt > 0) & (a.ior > 1))
    return lenses, v / d[:, None], ang, tlen, outside


@pytest.mark.parametrize(
    "light, seed",
    [((4.7, 4.3, 4.2), 0), ((-0.5, 3.0, 1.0), 1), ((2.2, 2.6, 5.5), 2), ((9.0, -3.0, 0.3), 3)],
)
def test_dense_grid_blockers_equal_every_pair_bit_for_bit(light, seed):
    """A crowded grid seen from close, radii and materials mixed (spheres that are
    no lens still block): the total blockers, the partial blockers of the others
    and the unblocked share are exactly every-pair's, and lenses totally blocked
    still block part of the lenses behind them."""
    from core.phase1.obstruction import find_blockers

    rng = np.random.default_rng(seed)
    a = dense_grid(9, 8, 5, light)
    n = len(a.radius)
    a.radius = rng.uniform(0.15, 0.49, n)
    a.kt = rng.choice([0.0, 0.9, 1.0], n)
    a.ior = rng.choice([1.0, 1.5], n)
    lenses, w, ang, tlen, outside = light_view(a)
    got = find_blockers(lenses, w, ang, tlen, outside)
    total, lists, unblocked = brute_force_blockers(lenses, w, ang, tlen, outside)
    assert got.total_blocker.tolist() == total
    offsets = got.shadow_offsets.tolist()
    got_lists = [
        got.shadow_spheres[a:b].tolist() for a, b in zip(offsets, offsets[1:], strict=False)
    ]
    assert got_lists == lists
    np.testing.assert_allclose(got.unblocked_fraction, unblocked, rtol=1e-12, atol=0)
    hidden = set(lenses[np.array(total) >= 0].tolist())
    assert len(hidden) >= 10
    # Lenses totally blocked still block part of the lenses behind them.
    assert any(k in hidden for blockers in lists for k in blockers)
    assert sum(map(len, lists)) > 50


@pytest.mark.parametrize("seed", range(4))
def test_blockers_of_discs_of_every_size_equal_every_pair(seed):
    """Random spheres with a few huge ones and some tiny ones (discs of sizes far
    apart: boxes at every level of the grids)."""
    from core.phase1.obstruction import find_blockers

    rng = np.random.default_rng(seed)
    a = random_scene(rng, 400, 1, outliers=True)
    tiny = rng.choice(400, 40, replace=False)
    a.radius[tiny] *= 1e-3
    lenses, w, ang, tlen, outside = light_view(a)
    got = find_blockers(lenses, w, ang, tlen, outside)
    total, lists, unblocked = brute_force_blockers(lenses, w, ang, tlen, outside)
    assert got.total_blocker.tolist() == total
    offsets = got.shadow_offsets.tolist()
    assert [
        got.shadow_spheres[a:b].tolist() for a, b in zip(offsets, offsets[1:], strict=False)
    ] == lists
    np.testing.assert_allclose(got.unblocked_fraction, unblocked, rtol=1e-12, atol=0)
    assert any(t >= 0 for t in total)
