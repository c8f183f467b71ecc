"""Obstruction tests of the thesis (§5.5 / SPEC §3.5) for one light, at scale.

The thesis tests every lens against every sphere: O(spheres²) per light. Here a
broad phase finds the pairs whose angular discs (as seen from the light) can
overlap, and the thesis' exact tests run only on those, vectorised. Results are
identical to the full loop: the broad phase is conservative (see `_candidate_pairs`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .geometry import cap_overlap_fraction
from .ranges import concat_ranges
from .shadow_mask import union_unblocked

#: Smallest grid cell (in units of direction-vector length): keeps cell keys in int64.
_MIN_CELL = 1e-6


@dataclass
class Blockers:
    """Per lens row (index into the `lens_rows` given to `find_blockers`)."""

    total_blocker: np.ndarray  # sphere index of the nearest total blocker, or −1
    shadow_offsets: np.ndarray  # CSR offsets into shadow_spheres (len rows + 1)
    shadow_spheres: np.ndarray  # partial blockers, ascending per row
    unblocked_fraction: np.ndarray  # share of the lens's flux no partial blocker covers


def find_blockers(
    lens_rows: np.ndarray,
    direction: np.ndarray,
    ang: np.ndarray,
    tlen: np.ndarray,
    obstacle: np.ndarray,
    ior: np.ndarray | None = None,
    kt: np.ndarray | None = None,
) -> Blockers:
    """The thesis' obstruction tests for the lenses `lens_rows` of one light.

    direction (S, 3): unit vectors light → sphere centre; ang (S,): radial angle
    (α of a lens, β of an obstacle); tlen (S,): tangent length R_T; obstacle (S,):
    spheres that can block (valid, light outside them). Sphere k blocks (part of)
    lens i iff R_T,k < R_T,i and α_i + β_k ≥ γ_ik; all of it iff β_k ≥ γ_ik + α_i.
    The unblocked fraction is the union of the partial blockers' shadows over the
    lens' cap, a glass one (`ior`, `kt` per sphere) passing its Fresnel share
    (`shadow_mask.union_unblocked`).
    """
    n_rows = lens_rows.size
    row_of = np.full(direction.shape[0], -1, dtype=np.int64)
    row_of[lens_rows] = np.arange(n_rows)
    # tlen of the nearest total blocker found so far per sphere (coarse levels first):
    # a pair whose farther sphere is already hidden behind something nearer than the
    # other sphere can change nothing (that one is no nearest total blocker, and a
    # hidden lens has no shadow list), so it is dropped before its exact test.
    hidden_at = np.full(direction.shape[0], np.inf)

    def useful(q, e):
        """Pairs that can change the answer; farther sphere a lens, nearer an obstacle."""
        tq, te = tlen[q], tlen[e]
        far_q = tq > te
        far, near = np.where(far_q, q, e), np.where(far_q, e, q)
        tf, tn = np.where(far_q, tq, te), np.where(far_q, te, tq)
        return (row_of[far] >= 0) & obstacle[near] & (tn < tf) & (hidden_at[far] >= tn)

    found = []
    for a, b in _candidate_batches(direction, ang, obstacle, row_of >= 0, useful):
        # Only the farther sphere of a pair (longer tangent) can be blocked by the other.
        far_a = tlen[a] > tlen[b]
        lens, obst = np.where(far_a, a, b), np.where(far_a, b, a)
        alpha, beta = ang[lens], ang[obst]
        gamma = _angle_between_rows(direction, lens, obst)
        blocks = alpha + beta >= gamma
        lens, obst, alpha, beta, gamma = (x[blocks] for x in (lens, obst, alpha, beta, gamma))
        total = beta >= gamma + alpha
        np.minimum.at(hidden_at, lens[total], tlen[obst[total]])
        found.append((lens, obst, alpha, beta, gamma, total))
    if found:
        cols = (np.concatenate(x) for x in zip(*found, strict=True))
        lens, obst, alpha, beta, gamma, total = cols
    else:
        lens = obst = np.zeros(0, dtype=np.int64)
        alpha = beta = gamma = np.zeros(0)
        total = np.zeros(0, dtype=bool)

    total_blocker = np.full(n_rows, -1, dtype=np.int64)
    if np.any(total):
        tl, to = lens[total], obst[total]
        order = np.lexsort((to, tlen[to], tl))  # per lens: nearest, then lowest index
        tl, to = tl[order], to[order]
        first = np.r_[True, tl[1:] != tl[:-1]]
        total_blocker[row_of[tl[first]]] = to[first]

    partial = total_blocker[row_of[lens]] < 0
    rows = row_of[lens[partial]]
    obst, alpha, beta, gamma = obst[partial], alpha[partial], beta[partial], gamma[partial]
    # by row, then sphere (one sort of a unique integer key, as lexsort((obst, rows)))
    order = np.argsort(rows * direction.shape[0] + obst, kind="stable")
    rows, obst, gamma = rows[order], obst[order], gamma[order]
    cover = cap_overlap_fraction(alpha[order], beta[order], gamma)
    unblocked = union_unblocked(rows, obst, cover, lens_rows, direction, ang, ior, kt, gamma=gamma)
    unblocked[total_blocker >= 0] = 0.0
    offsets = np.zeros(n_rows + 1, dtype=np.int64)
    offsets[1:] = np.cumsum(np.bincount(rows, minlength=n_rows))
    return Blockers(total_blocker, offsets, obst, unblocked)


def _angle_between_rows(direction, i, k):
    """`geometry.angle_between(direction[i], direction[k])`, bit for bit, from the
    columns (no (N, 3) gathers and no `np.cross` overhead: it is most of the
    exact test's cost in a crowded view)."""
    x, y, z = (np.ascontiguousarray(direction[:, c]) for c in range(3))
    ax, ay, az, bx, by, bz = x[i], y[i], z[i], x[k], y[k], z[k]
    cx, cy, cz = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
    return np.arctan2(np.sqrt(cx * cx + cy * cy + cz * cz), ax * bx + ay * by + az * bz)


def _candidate_pairs(direction, ang, obstacle, lens_mask):
    """Unordered pairs (a, b), each once, of spheres whose angular discs may overlap
    (`_candidate_batches`, all levels joined)."""
    batches = list(_candidate_batches(direction, ang, obstacle, lens_mask))
    if not batches:
        empty = np.zeros(0, dtype=np.int64)
        return empty, empty
    return tuple(np.concatenate(x) for x in zip(*batches, strict=True))


def _candidate_batches(direction, ang, obstacle, lens_mask, useful=None):
    """Unordered pairs (a, b), each once, of spheres whose angular discs may overlap,
    one batch per grid level, coarsest first; `useful(a, b)` (a mask), if given, is
    asked for each batch's pairs just before they are yielded, so a caller may drop
    the pairs the coarser batches made pointless.

    Conservative: overlapping discs (γ ≤ ρ_a + ρ_b) have unit vectors at chord
    distance 2 sin(γ/2) ≤ γ ≤ ρ_a + ρ_b, so their boxes [w − ρ, w + ρ] intersect
    (ρ is widened by a few ulps for rounding); pairs sharing a cell are kept if
    that chord test holds.
    A hierarchy of uniform grids (cell sizes c₀·2^ℓ) holds each box in the level
    whose cells are at least twice its width, so a box touches at most 8 cells of
    its own level and of every coarser one. Each box is looked up in its own and
    all coarser levels: two intersecting boxes always share a cell of the coarser
    one's level. Near and far spheres (discs of very different sizes) thus cost
    no more than uniform ones.
    A pair is kept only in the cell holding the lower corner of the two boxes'
    overlap (and, within one level, with a < b): so each pair comes out once,
    without sorting all candidates to drop repeats. A box spans at most two
    cells per axis; that cell is the one where, on every axis, one of the two
    boxes is in its lower cell (`_cell_keys`' corner bits: `bits_a & bits_b == 0`).
    """
    active = np.flatnonzero(obstacle | lens_mask)
    if active.size < 2:
        return
    w = direction[active]
    rho = ang[active] * (1.0 + 1e-12) + 1e-15
    c0 = max(2.0 * float(np.quantile(rho, 0.05)), _MIN_CELL)
    level = np.maximum(0, np.ceil(np.log2(np.maximum(2.0 * rho / c0, 1.0)))).astype(np.int64)
    # Boxes by level: a level's owners and queries (it and the finer ones) are slices.
    by_level = np.argsort(level, kind="stable")
    active, w, rho, level = active[by_level], w[by_level], rho[by_level], level[by_level]
    ends = np.searchsorted(level, np.arange(level[-1] + 1), side="right")
    wx, wy, wz = (np.ascontiguousarray(w[:, k]) for k in range(3))

    def meet(qk, qi, cross, qb, ek, eo, eb, lo=None, count=None):
        """Pairs (query, owner) sharing a cell, in their home cell only, near."""
        if lo is None:
            lo = np.searchsorted(ek, qk, side="left")
            count = np.searchsorted(ek, qk, side="right") - lo
        if not count.any():
            return
        at = concat_ranges(lo, count)
        q, e = np.repeat(qi, count), eo[at]
        ok = np.repeat(cross, count) | (q < e)  # within a level both orders come up
        if qb is not None:
            ok &= (np.repeat(qb, count) & eb[at]) == 0
        q, e = q[ok], e[ok]
        # The boxes only bound the discs: keep pairs within chord ρ_a + ρ_b (≤ γ).
        chord2 = (wx[q] - wx[e]) ** 2 + (wy[q] - wy[e]) ** 2 + (wz[q] - wz[e]) ** 2
        near = chord2 <= (rho[q] + rho[e]) ** 2
        q, e = active[q[near]], active[e[near]]
        if useful is not None:
            ok = useful(q, e)
            q, e = q[ok], e[ok]
        pa.append(q)
        pb.append(e)

    box_lo, box_hi = w - rho[:, None], w + rho[:, None]
    for lvl in np.unique(level)[::-1]:
        pa, pb = [], []
        cell = c0 * 2.0**lvl
        end = int(ends[lvl])
        owners = np.arange(int(ends[lvl - 1]) if lvl else 0, end)
        # Only boxes that meet the owners' bounding box can meet an owner's box (a
        # level of a few near spheres is not searched with every far one's keys).
        lo, hi = box_lo[owners].min(axis=0), box_hi[owners].max(axis=0)
        queries = np.flatnonzero(np.all((box_hi[:end] >= lo) & (box_lo[:end] <= hi), axis=1))
        e_keys, e_idx, e_bits = _cell_keys(w[owners], rho[owners], cell)
        q_keys, q_idx, q_bits = _cell_keys(w[queries], rho[queries], cell)
        order = np.argsort(e_keys, kind="stable")
        ek, eo, eb = e_keys[order], owners[e_idx[order]], e_bits[order]
        qi = queries[q_idx]
        cross = level[qi] < lvl
        # Crowded or not (which way is faster; both give the same pairs): judged on
        # every 16th query key first, so that a crowded level is searched only once.
        sample = q_keys[::16]
        hits = np.searchsorted(ek, sample, side="right") - np.searchsorted(ek, sample)
        if int(hits.sum()) <= 4 * sample.size:
            lo = np.searchsorted(ek, q_keys, side="left")
            count = np.searchsorted(ek, q_keys, side="right") - lo
            if int(count.sum()) <= 4 * q_keys.size:
                meet(q_keys, qi, cross, q_bits, ek, eo, eb, lo, count)
                if pa:
                    yield np.concatenate(pa), np.concatenate(pb)
                continue
        # Crowded: split the owners by corner, so that a query's cell at corner bq
        # is searched only among owners at corners be with bq & be == 0 (above),
        # and a pair's other meetings are never expanded.
        by_corner = []
        for be in range(8):
            k = np.flatnonzero(eb == be)
            by_corner.append((ek[k], eo[k]))
        for bq in range(8):
            sel = np.flatnonzero(q_bits == bq)
            if not sel.size:
                continue
            qk, qs, cs = q_keys[sel], qi[sel], cross[sel]
            for be in range(8):
                if not bq & be and by_corner[be][0].size:
                    meet(qk, qs, cs, None, *by_corner[be], None)
        if pa:
            yield np.concatenate(pa), np.concatenate(pb)


def _cell_keys(w, rho, cell):
    """Keys of the (at most 8) cells of a grid of size `cell` that each box
    [w − ρ, w + ρ] touches (2ρ ≤ cell), with the index of the box each key is for
    and which corner of the box's cells it is (bit 4: x, 2: y, 1: z upper).
    The grid is fixed in space (origin below −1, since |w| = 1), so keys of
    different box sets on the same level agree."""
    dims = int(math.ceil(2.5 / cell)) + 2
    lo = np.floor((w - rho[:, None] + 1.25) / cell).astype(np.int64)
    hi = np.floor((w + rho[:, None] + 1.25) / cell).astype(np.int64)
    base = (lo[:, 0] * dims + lo[:, 1]) * dims + lo[:, 2]
    # Which axes the box spans two cells on (bits as the corners'): corner d is
    # touched iff its bits are among them.
    spans = (hi > lo).astype(np.uint8) @ np.array([4, 2, 1], dtype=np.uint8)
    keys, idx, bits = [], [], []
    for d in range(8):
        ok = np.flatnonzero((spans & d) == d)
        keys.append(base[ok] + ((d >> 2) * dims + ((d >> 1) & 1)) * dims + (d & 1))
        idx.append(ok)
        bits.append(np.full(ok.size, d, dtype=np.uint8))
    return np.concatenate(keys), np.concatenate(idx), np.concatenate(bits)
