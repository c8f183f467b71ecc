"""Obstruction tests of the thesis (§5.5 / SPEC §3.5) for one light, at scale.

The thesis tests every lens against every sphere: O(spheres²) per light. Here a
broad phase finds the pairs whose angular discs (as seen from the light) can
overlap, and the thesis' exact tests run only on those, vectorised. Results are
identical to the full loop: the broad phase is conservative (see `_candidate_pairs`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .geometry import angle_between, cap_overlap_fraction

#: Smallest grid cell (in units of direction-vector length): keeps cell keys in int64.
_MIN_CELL = 1e-6
#: A disc more than this many times the 99th-percentile disc is an outlier and is
#: tested against every sphere instead of being put into the grid.
_OUTLIER_FACTOR = 4.0


@dataclass
class Blockers:
    """Per lens row (index into the `lens_rows` given to `find_blockers`)."""
    total_blocker: np.ndarray        # sphere index of the nearest total blocker, or −1
    shadow_offsets: np.ndarray       # CSR offsets into shadow_spheres (len rows + 1)
    shadow_spheres: np.ndarray       # partial blockers, ascending per row
    unblocked_fraction: np.ndarray   # share of the lens's flux no partial blocker covers


def find_blockers(lens_rows: np.ndarray, direction: np.ndarray, ang: np.ndarray,
                  tlen: np.ndarray, obstacle: np.ndarray) -> Blockers:
    """The thesis' obstruction tests for the lenses `lens_rows` of one light.

    direction (S, 3): unit vectors light → sphere centre; ang (S,): radial angle
    (α of a lens, β of an obstacle); tlen (S,): tangent length R_T; obstacle (S,):
    spheres that can block (valid, light outside them). Sphere k blocks (part of)
    lens i iff R_T,k < R_T,i and α_i + β_k ≥ γ_ik; all of it iff β_k ≥ γ_ik + α_i.
    The unblocked fraction treats partial blockers as independent: ∏(1 − cover_k).
    """
    n_rows = lens_rows.size
    row_of = np.full(direction.shape[0], -1, dtype=np.int64)
    row_of[lens_rows] = np.arange(n_rows)

    a, b = _candidate_pairs(direction, ang, obstacle, row_of >= 0)
    # Orient every unordered pair both ways: (lens, obstacle).
    lens = np.concatenate([a, b])
    obst = np.concatenate([b, a])
    keep = (row_of[lens] >= 0) & obstacle[obst] & (tlen[obst] < tlen[lens])
    lens, obst = lens[keep], obst[keep]
    alpha, beta = ang[lens], ang[obst]
    gamma = angle_between(direction[lens], direction[obst])
    blocks = alpha + beta >= gamma
    lens, obst, alpha, beta, gamma = (x[blocks] for x in (lens, obst, alpha, beta, gamma))
    total = beta >= gamma + alpha

    total_blocker = np.full(n_rows, -1, dtype=np.int64)
    if np.any(total):
        tl, to = lens[total], obst[total]
        order = np.lexsort((to, tlen[to], tl))          # per lens: nearest, then lowest index
        tl, to = tl[order], to[order]
        first = np.r_[True, tl[1:] != tl[:-1]]
        total_blocker[row_of[tl[first]]] = to[first]

    partial = total_blocker[row_of[lens]] < 0
    rows = row_of[lens[partial]]
    obst, alpha, beta, gamma = obst[partial], alpha[partial], beta[partial], gamma[partial]
    order = np.lexsort((obst, rows))
    rows, obst = rows[order], obst[order]
    cover = cap_overlap_fraction(alpha[order], beta[order], gamma[order])
    unblocked = np.ones(n_rows)
    np.multiply.at(unblocked, rows, 1.0 - cover)
    unblocked[total_blocker >= 0] = 0.0
    offsets = np.zeros(n_rows + 1, dtype=np.int64)
    np.add.at(offsets, rows + 1, 1)
    return Blockers(total_blocker, np.cumsum(offsets), obst, unblocked)


def _candidate_pairs(direction, ang, obstacle, lens_mask):
    """Unordered pairs (a, b) of spheres whose angular discs may overlap.

    Conservative: overlapping discs (γ ≤ ρ_a + ρ_b) have unit vectors at chord
    distance 2 sin(γ/2) ≤ γ ≤ ρ_a + ρ_b, so their boxes [w − ρ, w + ρ] intersect,
    and two intersecting boxes share a grid cell when both are at most one cell
    wide. Outliers (discs much bigger than the rest) are paired with everything.
    """
    active = np.flatnonzero(obstacle | lens_mask)
    if active.size < 2:
        empty = np.zeros(0, dtype=np.int64)
        return empty, empty
    rho = ang[active]
    q99 = float(np.quantile(rho, 0.99))
    limit = _OUTLIER_FACTOR * q99
    outlier = rho > limit
    cell = max(2.0 * float(rho[~outlier].max(initial=0.0)), _MIN_CELL)

    in_grid = active[~outlier]
    pa, pb = _grid_pairs(direction[in_grid], ang[in_grid], cell)
    pairs_a, pairs_b = [in_grid[pa]], [in_grid[pb]]

    big = active[outlier]
    for k in big:      # few by construction
        others = active[active != k]
        pairs_a.append(np.full(others.size, k, dtype=np.int64))
        pairs_b.append(others)
    a = np.concatenate(pairs_a)
    b = np.concatenate(pairs_b)
    # pairs of two outliers appear twice; the grid gives each pair once per cell
    key = np.unique(np.minimum(a, b) * direction.shape[0] + np.maximum(a, b))
    return key // direction.shape[0], key % direction.shape[0]


def _grid_pairs(w, rho, cell):
    """Index pairs (i < j) of boxes [w − ρ, w + ρ] sharing a cell of a uniform grid."""
    n = w.shape[0]
    lo = np.floor((w - rho[:, None]) / cell).astype(np.int64)
    hi = np.floor((w + rho[:, None]) / cell).astype(np.int64)
    base = lo.min(axis=0)
    lo -= base
    hi -= base
    dims = hi.max(axis=0) + 1
    keys, owners = [], []
    for dx in (0, 1):
        for dy in (0, 1):
            for dz in (0, 1):
                c = lo + (dx, dy, dz)
                ok = np.all(c <= hi, axis=1)
                keys.append((c[ok, 0] * dims[1] + c[ok, 1]) * dims[2] + c[ok, 2])
                owners.append(np.flatnonzero(ok))
    keys = np.concatenate(keys)
    owners = np.concatenate(owners)
    order = np.argsort(keys, kind="stable")
    keys, owners = keys[order], owners[order]
    # For the entry at position p in a cell [start, end): pair it with p+1 … end−1.
    starts = np.flatnonzero(np.r_[True, keys[1:] != keys[:-1]])
    ends = np.r_[starts[1:], keys.size]
    size = ends - starts
    end_of = np.repeat(ends, size)
    pos = np.arange(keys.size)
    count = end_of - pos - 1
    total = int(count.sum())
    if total == 0:
        empty = np.zeros(0, dtype=np.int64)
        return empty, empty
    first = np.repeat(pos, count)
    offset = np.arange(total) - np.repeat(np.cumsum(count) - count, count)
    second = first + 1 + offset
    i, j = owners[first], owners[second]
    key = np.unique(np.minimum(i, j) * n + np.maximum(i, j))
    return key // n, key % n
