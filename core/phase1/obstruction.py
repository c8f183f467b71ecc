"""Obstruction tests of the thesis (§5.5 / SPEC §3.5) for one light, at scale.

The thesis tests every lens against every sphere: O(spheres²) per light. Here a
broad phase finds the pairs whose angular discs (as seen from the light) can
overlap, and the thesis' exact tests run only on those, vectorised. Results are
identical to the full loop: the broad phase is conservative (see `_candidate_pairs`).
"""

from __future__ import annotations

import math
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from ..lens.sphere_caps import cap_halves, cap_overlap_fraction
from ..shared import parallel
from ..shared.parallel import map_slices
from ..shared.ranges import expand_ranges
from .shadow_mask import union_unblocked

#: Smallest grid cell (in units of direction-vector length): keeps cell keys in int64.
_MIN_CELL = 1e-6

#: Owner keys per occupied cell and corner from which a level is searched on the
#: half-size grid (fewer far pairs share a cell there).
_CROWDED = 4

#: Meetings tested at once (a few MB of temporaries).
_PIECE = 1 << 16


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

    def window(s):
        """Per sphere, the depth it blocks at (its tangent length if an obstacle, else
        ∞) and the depth up to which a blocker can still matter to it (the nearer of
        its tangent length and what hides it, if a lens, else −∞): a useful pair has
        one's first no deeper than the other's second."""
        near = np.where(obstacle[s], tlen[s], np.inf)
        return near, np.where(row_of[s] >= 0, np.minimum(tlen[s], hidden_at[s]), -np.inf)

    found = []
    batches = _candidate_batches(direction, ang, obstacle, row_of >= 0, useful, window)
    cols = tuple(np.ascontiguousarray(direction[:, c]) for c in range(3))

    def exact(a, b):
        """The pairs (a, b) that overlap, as (lens, obst, α, β, γ); row by row."""
        # Only the farther sphere of a pair (longer tangent) can be blocked by the other.
        far_a = tlen[a] > tlen[b]
        lens, obst = np.where(far_a, a, b), np.where(far_a, b, a)
        alpha, beta = ang[lens], ang[obst]
        gamma = _angle_between_rows(direction, lens, obst, cols)
        blocks = alpha + beta >= gamma
        return tuple(x[blocks] for x in (lens, obst, alpha, beta, gamma))

    for a, b in batches:
        parts = map_slices(lambda s, a=a, b=b: exact(a[s], b[s]), a.size)
        if len(parts) == 1:
            lens, obst, alpha, beta, gamma = parts[0]
        else:
            lens, obst, alpha, beta, gamma = (np.concatenate(x) for x in zip(*parts, strict=True))
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
        # per lens the nearest (hidden_at holds its tangent length), then lowest index
        tl, to = lens[total], obst[total]
        nearest = tlen[to] == hidden_at[tl]
        tl, to = tl[nearest], to[nearest]
        pick = np.full(direction.shape[0], np.iinfo(np.int64).max)
        np.minimum.at(pick, tl, to)
        total_blocker[row_of[tl]] = pick[tl]

    partial = total_blocker[row_of[lens]] < 0
    rows = row_of[lens[partial]]
    obst, alpha, beta, gamma = obst[partial], alpha[partial], beta[partial], gamma[partial]
    # by row, then sphere (one sort of a unique integer key, as lexsort((obst, rows)))
    order = np.argsort(rows * direction.shape[0] + obst, kind="stable")
    rows, obst, gamma = rows[order], obst[order], gamma[order]
    s2, t2 = cap_halves(ang)  # once per sphere, not per pair
    lens_o = lens_rows[rows]
    halves = (s2[lens_o], t2[lens_o], s2[obst], t2[obst])
    cover = cap_overlap_fraction(alpha[order], beta[order], gamma, halves)
    unblocked = union_unblocked(rows, obst, cover, lens_rows, direction, ang, ior, kt, gamma=gamma)
    unblocked[total_blocker >= 0] = 0.0
    offsets = np.zeros(n_rows + 1, dtype=np.int64)
    offsets[1:] = np.cumsum(np.bincount(rows, minlength=n_rows))
    return Blockers(total_blocker, offsets, obst, unblocked)


def _angle_between_rows(direction, i, k, cols=None):
    """`geometry.angle_between(direction[i], direction[k])`, bit for bit, from the
    columns (no (N, 3) gathers and no `np.cross` overhead: it is most of the
    exact test's cost in a crowded view). `cols`: direction's columns, if made."""
    if cols is None:
        cols = tuple(np.ascontiguousarray(direction[:, c]) for c in range(3))
    x, y, z = cols
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


def _candidate_batches(direction, ang, obstacle, lens_mask, useful=None, window=None):
    """Unordered pairs (a, b), each once, of spheres whose angular discs may overlap,
    one batch per level, coarsest first; `useful(a, b)` (a mask), if given, is
    asked for each batch's pairs just before they are yielded, so a caller may drop
    the pairs the coarser batches made pointless. `window(s)`, if given, is asked
    before each level for two depths per sphere (n, f) such that a useful pair
    (a, b) has n_a ≤ f_b or n_b ≤ f_a: a finer box that can make no such pair with
    any of the level's boxes is not looked up there, nor, where the level is
    crowded, is any box in a cell where it can make none.

    Conservative: overlapping discs (γ ≤ ρ_a + ρ_b) have unit vectors at chord
    distance 2 sin(γ/2) ≤ γ ≤ ρ_a + ρ_b (ρ is widened by a few ulps for rounding);
    pairs met are kept if that chord test holds.
    The directions are seen on the six faces of a cube (a face per axis and sign,
    each direction at home on the face of its largest coordinate): a face keeps two
    of the three coordinates, which brings points no farther apart, so two
    overlapping discs' squares [w − ρ, w + ρ] there intersect on every face.
    A hierarchy of levels (sizes c₀·2^ℓ) holds each box in the level whose size is
    at least its width. Each level's boxes (the owners) are met by their own and
    every finer level's boxes on a uniform 2-D grid per face, of the level's size
    or, where that is crowded, of half of it (fewer far pairs share a cell). A finer
    box is looked up on its home face only; an owner is put on every face near
    enough that a box at home there can overlap it (see `_faces_near`), and a pair
    of owners is kept on the home face of the one that comes first.
    Within a face, a pair is met only in the cell holding the lower corner of the
    two squares' overlap: the cell where, on both axes, one of the two squares is
    in its first cell (`_face_keys`' corner bits: `bits_a & bits_b == 0`); two owners
    meet from the one with the lower corner bits (or, both in their first cells,
    the one sorted first). So each pair comes out once, without sorting the
    candidates to drop repeats.
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
    # np.argmax(|w|, axis=1), column by column (reductions along rows of 3 are slow)
    ax, ay, az = np.abs(wx), np.abs(wy), np.abs(wz)
    axis = np.where(az > np.maximum(ax, ay), 2, np.where(ay > ax, 1, 0))
    home = 2 * axis + (w[np.arange(w.shape[0]), axis] >= 0)
    pa, pb = [], []

    def meet(q, e, lo, count, faces=None, corners=None):
        """The near pairs of query q.ids[i] with owners e.ids[lo[i] … lo[i] + count[i]
        − 1]; faces (those of q's keys), if given: kept on the home face of the pair's
        first box only; corners (the query keys' and the owners' corner bits), if
        given: q's keys counted all owners of their cell, and only those at corners
        sharing no bit with the query's are kept (q is e: the owners among
        themselves, each pair from the lower corner or, both at corner 0, from the
        one sorted first). The owners' columns are read in their own order, the
        query's repeated: no scattered reads per meeting."""
        has = np.flatnonzero(count)
        if not has.size:
            return
        lo, count = lo[has], count[has]
        total = np.cumsum(count)
        # In pieces of about _PIECE meetings: their temporaries stay in cache.
        cuts = np.searchsorted(total, np.arange(_PIECE, int(total[-1]), _PIECE))
        for s, t in zip(np.r_[0, cuts], np.r_[cuts, count.size], strict=True):
            if t > s:
                a, b = meet_piece(q, e, has[s:t], lo[s:t], count[s:t], faces, corners)
                pa.append(a)
                pb.append(b)

    def meet_piece(q, e, rows, lo, count, faces, corners):
        which, at = expand_ranges(lo, count)
        row = rows[which]
        if corners is not None:
            # A few owners per cell: all of a cell's met, those of the wrong corners
            # dropped here, before the columns are read.
            bq, be = corners[0][row], corners[1][at]
            keep = (bq & be) == 0
            if q is e:
                keep &= (bq < be) | ((bq == be) & (row < at))
            keep = np.flatnonzero(keep)
            row, at = row[keep], at[keep]
        chord2 = q.x[row]
        chord2 -= e.x[at]
        chord2 *= chord2
        for qc, ec in ((q.y, e.y), (q.z, e.z)):
            d = qc[row]
            d -= ec[at]
            d *= d
            chord2 += d
        r = q.r[row]
        r += e.r[at]
        r *= r
        near = np.flatnonzero(chord2 <= r)
        row = row[near]
        qi, ei = q.ids[row], e.ids[at[near]]
        if faces is not None:
            ok = faces[row] == home[np.minimum(qi, ei)]
            qi, ei = qi[ok], ei[ok]
        a, b = active[qi], active[ei]
        if useful is not None:
            ok = useful(a, b)
            a, b = a[ok], b[ok]
        return a, b

    def side(keys, ids):
        return _Side(keys, ids, wx[ids], wy[ids], wz[ids], rho[ids])

    box_lo = [wx - rho, wy - rho, wz - rho]
    box_hi = [wx + rho, wy + rho, wz + rho]

    def owner_side(lvl):
        """A level's owners on their grid (what does not depend on what is hidden)."""
        cell = c0 * 2.0**lvl
        end = int(ends[lvl])
        start = int(ends[lvl - 1]) if lvl else 0
        # Only boxes that meet the owners' bounding box can meet an owner's box (a
        # level of a few near spheres is not searched with every far one's keys).
        meets = np.ones(start, dtype=bool)
        for lo, hi in zip(box_lo, box_hi, strict=True):
            meets &= hi[:start] >= lo[start:end].min()
            meets &= lo[:start] <= hi[start:end].max()
        on_faces = np.nonzero(_faces_near(w[start:end], rho[start:end] + 0.5 * cell))
        on_faces = (on_faces[0] + start, on_faces[1])
        grid = cell
        while True:
            e_keys, e_idx, e_bits, e_face = _face_keys(w, rho, grid, *on_faces)
            code = e_keys * 4 + e_bits
            order = np.argsort(code, kind="stable")
            code = code[order]
            # Crowded (many owners per cell): the half-size grid meets fewer far pairs.
            occupied = 1 + np.count_nonzero(code[1:] != code[:-1])
            if grid < cell or grid / 2.0 < _MIN_CELL or code.size < _CROWDED * occupied:
                break
            grid = cell / 2.0
        own = side(code, e_idx[order])
        cells = None
        if grid < cell:
            cells = _Cells(code, 6 * (int(math.ceil(2.5 / grid)) + 2) ** 2)
        finer = np.flatnonzero(meets)
        # In the second thread, the finer boxes' keys too (the hidden ones dropped after)
        asked = query_side(finer, grid, cells) if ahead is not None else None
        return start, end, cell, grid, finer, own, e_bits[order], e_face[order], cells, asked

    def query_side(finer, grid, cells):
        """The finer boxes' keys on the level's grid, with their cells' owner runs."""
        q_keys, q_idx, q_bits, _ = _face_keys(w, rho, grid, finer, home[finer])
        ask = side(q_keys * 4, q_idx)
        q_runs, q_cell = cells.runs(ask.keys) if cells is not None else (None, None)
        return ask, q_bits, q_runs, q_cell

    levels = np.unique(level)[::-1].tolist()
    # With a core to spare, a second thread lays out the next levels' owners (sorts
    # and searches of whole arrays: they let go of the GIL) while this one meets.
    ahead = ThreadPoolExecutor(1) if parallel.workers(active.size) > 1 else None
    try:
        laid = [ahead.submit(owner_side, lvl) for lvl in levels] if ahead else None
        for k, lvl in enumerate(levels):
            pa.clear()
            pb.clear()
            start, end, cell, grid, finer, own, own_bits, own_face, cells, asked = (
                laid[k].result() if ahead else owner_side(lvl)
            )
            all_finer = finer.size
            if window is not None:
                depth_n, depth_f = window(active)
                lvl_n, lvl_f = depth_n[start:end].min(), depth_f[start:end].max()
                finer = finer[(depth_n[finer] <= lvl_f) | (depth_f[finer] >= lvl_n)]
            if asked is None:
                asked = query_side(finer, grid, cells)
            elif finer.size < all_finer:  # keys of the boxes dropped above: out
                kept = np.zeros(active.size, dtype=bool)
                kept[finer] = True
                asked = _kept_keys(asked, np.flatnonzero(kept[asked[0].ids]))
            ask, q_bits, q_runs, q_cell = asked
            if cells is None:
                # Not crowded: each key meets its cell's owners of every corner; those
                # whose corners share a bit are dropped before the chord test.
                for q, corners, faces in ((ask, q_bits, None), (own, own_bits, own_face)):
                    cell_of = q.keys - (corners if q is own else 0)
                    lo = np.searchsorted(own.keys, cell_of)
                    count = np.searchsorted(own.keys, cell_of + 4) - lo
                    meet(q, own, lo, count, faces, (corners, own_bits))
                if pa:
                    yield np.concatenate(pa), np.concatenate(pb)
                continue
            own_runs = cells.own_runs
            if window is not None:
                # A key whose box can make no useful pair with any owner of its cell
                # meets none of them.
                first_of = cells.bounds[:, 0]
                cell_n = np.minimum.reduceat(depth_n[own.ids], first_of)
                cell_f = np.maximum.reduceat(depth_f[own.ids], first_of)
                for runs, ids, at in (
                    (q_runs, ask.ids, q_cell),
                    (own_runs, own.ids, cells.of_code),
                ):
                    idle = (depth_n[ids] > cell_f[at]) & (depth_f[ids] < cell_n[at])
                    runs[idle] = runs[idle, :1]
            # Crowded: each key meets only the owners at corners it shares no bit with.
            for be in range(4):
                lo = q_runs[:, be]
                count = q_runs[:, be + 1] - lo
                count[(q_bits & be) != 0] = 0
                meet(ask, own, lo, count)
                # The owners among themselves: from the lower corner bits only.
                lo = own_runs[:, be]
                count = own_runs[:, be + 1] - lo
                count[((own_bits & be) != 0) | (own_bits >= be)] = 0
                meet(own, own, lo, count, own_face)
            # Both in their first cells: each with the ones sorted after it.
            first = np.flatnonzero(own_bits == 0)
            head = _Side(*(x[first] for x in (own.keys, own.ids, own.x, own.y, own.z, own.r)))
            count = np.maximum(own_runs[first, 1] - first - 1, 0)
            meet(head, own, first + 1, count, own_face[first])
            if pa:
                yield np.concatenate(pa), np.concatenate(pb)
    finally:
        if ahead is not None:
            ahead.shutdown(cancel_futures=True)


def _kept_keys(asked, k):
    """`query_side`'s output for its keys `k` only."""
    ask, q_bits, q_runs, q_cell = asked
    ask = _Side(*(x[k] for x in (ask.keys, ask.ids, ask.x, ask.y, ask.z, ask.r)))
    if q_runs is not None:
        q_runs, q_cell = q_runs[k], q_cell[k]
    return ask, q_bits[k], q_runs, q_cell


@dataclass
class _Side:
    """Cell codes (sorted, for owners) and, per code, its box's row and columns."""

    keys: np.ndarray
    ids: np.ndarray
    x: np.ndarray
    y: np.ndarray
    z: np.ndarray
    r: np.ndarray


#: The two coordinates a cube face keeps (faces 2k, 2k + 1: axis k, − and +).
_FACE_AXES = ((1, 2), (0, 2), (0, 1))


def _faces_near(w, reach):
    """(n, 6) mask of the faces on which a direction within chord `reach` of w can be
    at home: one there has s·v_k ≥ |v_j| for all j, and each coordinate moves by at
    most the chord, so s·w_k ≥ max_j |w_j| − 2·reach (with a margin for rounding)."""
    biggest = np.maximum(np.maximum(np.abs(w[:, 0]), np.abs(w[:, 1])), np.abs(w[:, 2]))
    top = biggest - 2.0 * reach * (1.0 + 1e-9) - 1e-12
    out = np.empty((w.shape[0], 6), dtype=bool)
    for k in range(3):
        out[:, 2 * k] = -w[:, k] >= top
        out[:, 2 * k + 1] = w[:, k] >= top
    return out


def _face_keys(w, rho, cell, rows, face):
    """Keys of the cells of a 2-D grid of size `cell` on face face[k] that the square
    [w − ρ, w + ρ] of box rows[k] (its two coordinates kept by the face) touches,
    2ρ ≤ 2·cell (up to 3 per axis); with the index of the box each key is for,
    which of the box's cells it is by corner bits (2: the first axis, 1: the second
    not the box's first cell on it), and the face.
    The grid is fixed in space (origin below −1, since |w| = 1), so keys of
    different box sets on the same grid agree."""
    dims = int(math.ceil(2.5 / cell)) + 2
    axes = np.array(_FACE_AXES)[face // 2]
    r = rho[rows]
    # Cells from −1 (a box up to a cell past −1) to dims − 2, shifted by one so
    # keys are ≥ 0 and each (face, cell) has its own.
    lo_i = np.floor((w[rows, axes[:, 0]] - r + 1.25) / cell).astype(np.int64)
    lo_j = np.floor((w[rows, axes[:, 1]] - r + 1.25) / cell).astype(np.int64)
    span_i = np.floor((w[rows, axes[:, 0]] + r + 1.25) / cell).astype(np.int64) - lo_i
    span_j = np.floor((w[rows, axes[:, 1]] + r + 1.25) / cell).astype(np.int64) - lo_j
    base = (face * dims + lo_i + 1) * dims + lo_j + 1
    keys, idx, bits = [], [], []
    for di in range(int(span_i.max(initial=0)) + 1):
        oi = np.flatnonzero(span_i >= di)
        for dj in range(int(span_j[oi].max(initial=0)) + 1):
            ok = oi[span_j[oi] >= dj]
            keys.append(base[ok] + di * dims + dj)
            idx.append(ok)
            bits.append(np.full(ok.size, 2 * (di > 0) + (dj > 0), dtype=np.int64))
    ok = np.concatenate(idx)
    return np.concatenate(keys), rows[ok], np.concatenate(bits), face[ok]


class _Cells:
    """The occupied cells of a crowded level's sorted owner codes (cell key × 4 +
    corner bits): per cell, where each corner's run of owners starts and where the
    cell ends (`bounds`, (cells, 5)), the cell of each code (`of_code`) and its bounds
    (`own_runs`).
    `runs(codes)` gives the bounds for query codes of corner 0 (all equal for an
    empty cell) and their cells (0 for an empty one), through a table of all `keys`
    cells where it is small beside the codes, else by binary search among the
    occupied cells."""

    def __init__(self, codes, keys):
        new = np.r_[True, (codes[1:] >> 2) != (codes[:-1] >> 2)]
        self.of_code = np.cumsum(new) - 1
        self.cell = codes[new] & ~np.int64(3)
        self.bounds = np.searchsorted(codes, self.cell[:, None] + np.arange(5))
        self.own_runs = self.bounds[self.of_code]  # the bounds of each code's cell
        self.table = None
        if keys <= 16 * codes.size:
            self.table = np.full(keys, -1, dtype=np.int64)
            self.table[self.cell >> 2] = np.arange(self.cell.size)

    def runs(self, codes):
        if self.table is not None:
            at = self.table[codes >> 2]
            found = at >= 0
        else:
            at = np.minimum(np.searchsorted(self.cell, codes), self.cell.size - 1)
            found = self.cell[at] == codes
        out = self.bounds[at]
        out[~found] = 0
        return out, np.where(found, at, 0)
