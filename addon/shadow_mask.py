"""What a source's shadow list lets through: the exact union of the blockers' shadows
over the lens' lit cap, and a glass blocker's Fresnel transmission.

Phase 1 finds the partial blockers of a lens (spheres nearer the light whose angular
disc overlaps the lens'). An opaque blocker's share is exact in closed form
(`geometry.cap_overlap_fraction`). Shares of several cannot be multiplied: blockers whose
caps are disjoint block the sum of their shares, and where caps overlap a direction
behind two blockers must count once. A glass blocker passes kt² T(ι), T the unpolarised
two-surface Fresnel transmission at the ray's actual angle of incidence ι (sin ι =
sin θ_k / sin β_k for a direction θ_k from the blocker's centre, β_k its radial angle),
averaged over what it covers of the lens' cap by a 1-D quadrature (`glass_passed`).
Rows whose blockers' caps overlap are sampled (`_sampled_blocked`): each blocker's
meeting with the lens' cap on a deterministic grid of directions equal in solid angle
over the smaller of the two caps (rings uniform in 1 − cos θ × azimuths, anti-aliased
edges; a direction inside several blockers' caps counts once in all), each direction
passed by the product of its blockers' shares (0 behind an opaque one). The glass
blocker's own focusing (it deflects what it passes: a tertiary source) is out of scope:
what passes is counted as if undeflected.

`ray_passes` tells what blockers pass of given rays (the Exact profile's mask,
`emission_mask.py`, and the caustic layer's beam, `caustic_sheet/shadow.py`).

Each grid's azimuth starts toward the other cap, so the result does not depend on how
the scene is turned or in which order its spheres come.
"""

from __future__ import annotations

import numpy as np

from .exact_optics import fresnel_transmittance
from .ranges import concat_ranges

#: Directions per lens cap (rings × 2·rings): at most, and at least for crowded views.
MAX_SAMPLES, MIN_SAMPLES = 192 * 384, 16 * 32
#: Sample × blocker evaluations per call before the grid gets coarser (memory, time).
BUDGET = 250_000
#: Blocker pairs (of rows with overlapping blockers) per call beyond which the overlaps
#: are not sampled but taken as independent (a crowded view: time, see README Limits).
MAX_INTERACTIONS = 4_000


def is_glass(ior, kt) -> np.ndarray:
    """Spheres that pass light (kt > 0 and a finite index > 0); the rest are opaque."""
    ior, kt = np.asarray(ior, dtype=float), np.asarray(kt, dtype=float)
    with np.errstate(invalid="ignore"):
        return (kt > 0.0) & np.isfinite(ior) & (ior > 0.0)


def glass_share(sin_iota, ior, kt) -> np.ndarray:
    """kt² T(ι): the share a glass sphere passes straight through (both surfaces; s and
    p keep their plane of incidence, so T = (t_s² + t_p²)/2)."""
    s = np.clip(sin_iota, 0.0, 1.0)
    t_s, t_p = fresnel_transmittance(np.sqrt((1.0 - s) * (1.0 + s)), 1.0, ior)
    return np.clip(kt, 0.0, 1.0) ** 2 * 0.5 * (t_s * t_s + t_p * t_p)


def _rings(n_samples: int) -> tuple[int, int]:
    nr = max(int(np.sqrt(n_samples / 2.0)), 1)
    return nr, 2 * nr


def cap_offsets(w, alpha, ref, n_rings: int, n_azimuth: int) -> np.ndarray:
    """Directions s over the caps (unit axes ``w`` (P, 3), half-angles ``alpha`` (P,)),
    equal in solid angle, as offsets ``s − w`` (P, n_rings·n_azimuth, 3) (small and
    precise for tiny caps); azimuth 0 toward ``ref`` (P, 3) projected off ``w``."""
    e1 = ref - np.einsum("pi,pi->p", ref, w)[:, None] * w
    norm = np.linalg.norm(e1, axis=1)
    fallback = np.where(np.abs(w[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    fallback = fallback - np.einsum("pi,pi->p", fallback, w)[:, None] * w
    e1 = np.where((norm > 1e-12)[:, None], e1, fallback)
    e1 /= np.linalg.norm(e1, axis=1)[:, None]
    e2 = np.cross(w, e1)
    omc = 2.0 * np.sin(0.5 * alpha) ** 2  # 1 − cos α
    v = ((np.arange(n_rings) + 0.5) / n_rings)[None, :] * omc[:, None]  # 1 − cos θ
    sin_t = np.sqrt(v * (2.0 - v))
    phi = 2.0 * np.pi * (np.arange(n_azimuth) + 0.5) / n_azimuth
    cp, sp = np.cos(phi), np.sin(phi)
    radial = cp[None, :, None] * e1[:, None, :] + sp[None, :, None] * e2[:, None, :]  # (P, A, 3)
    off = sin_t[:, :, None, None] * radial[:, None] - v[:, :, None, None] * w[:, None, None]
    return off.reshape(w.shape[0], n_rings * n_azimuth, 3)


def _ramp_width(a, nr, na):
    """Per sample of the grids over caps of angular radius ``a`` (P,): the width of its
    cell, the smaller of the mean (square) one and its ring's (rings get thin toward
    the rim, where two touching caps meet: a sliver of overlap stays a sliver)."""
    omc = 2.0 * np.sin(0.5 * a) ** 2
    v = ((np.arange(nr) + 0.5) / nr)[None, :] * omc[:, None]
    ring = (omc / nr)[:, None] / np.maximum(np.sqrt(v * (2.0 - v)), 1e-300)  # dθ = dv/sin θ
    mean = (2.0 * np.sqrt(np.pi / (nr * na)) * np.sin(0.5 * a))[:, None]
    return np.repeat(np.minimum(ring, mean), na, axis=1)


def coverage(chord2, radius, h) -> np.ndarray:
    """How much of a sample's cell (angular size ``h`` (…, N)) lies in a cap of angular
    ``radius`` (…,) whose centre is at chord² ``chord2`` (…, N): a linear ramp over the
    signed angular distance to the rim. Anti-aliased: the estimate is continuous in
    the geometry (no sample flips in or out on rounding) and its edge error is
    second order in h."""
    half = 0.5 * np.sqrt(np.minimum(chord2, 4.0))
    theta = 2.0 * np.arctan2(half, np.sqrt(np.maximum(1.0 - half * half, 0.0)))
    return np.clip(0.5 + (radius[..., None] - theta) / np.maximum(h, 1e-300), 0.0, 1.0)


def passed_share(chord2, beta, glass, ior, kt, h):
    """What each blocker passes of the directions at chord² ``chord2`` (B, N) from its
    centre direction that go through it (radial angle ``beta``, glass or not, index, kt
    per blocker (B,)), and how much of each sample's cell its cap covers
    (:func:`coverage`)."""
    share = np.zeros(chord2.shape)
    g = np.flatnonzero(glass)  # Fresnel only for the glass ones' rows
    if g.size:
        half = 0.5 * np.sqrt(np.minimum(chord2[g], 4.0))
        sin_theta = 2.0 * half * np.sqrt(np.maximum(1.0 - half * half, 0.0))  # sin 2asin(c/2)
        sin_iota = sin_theta / np.sin(beta[g])[:, None]
        share[g] = glass_share(sin_iota, ior[g][:, None], kt[g][:, None])
    return share, coverage(chord2, beta, h)


def union_unblocked(
    rows, obst, cover, lens_rows, direction, ang, ior=None, kt=None, n_samples=MAX_SAMPLES
) -> np.ndarray:
    """The unblocked share of every lens row (``len(lens_rows)``), from its partial
    blockers: pairs (``rows``, ``obst``) sorted by row, ``cover`` each pair's closed-form
    cap overlap (share of the lens' cap), ``ior``, ``kt`` per sphere (None: all opaque).

    Where the blockers' caps do not overlap one another the union is the sum:
    1 − Σ cover_k (1 − ⟨passed⟩_k), ⟨passed⟩ 0 for an opaque blocker and, for a glass
    one, its Fresnel share averaged over what it covers of the lens' cap
    (:func:`glass_passed`, 1-D). Rows whose blockers overlap are sampled
    (:func:`_sampled_blocked`)."""
    n_rows = len(lens_rows)
    unblocked = np.ones(n_rows)
    rows, obst = np.asarray(rows, dtype=np.int64), np.asarray(obst, dtype=np.int64)
    if rows.size == 0:
        return unblocked
    count = np.bincount(rows, minlength=n_rows)
    if ior is None or kt is None:
        glass = np.zeros(direction.shape[0], dtype=bool)
        ior_a, kt_a = np.ones(direction.shape[0]), np.zeros(direction.shape[0])
    else:
        glass = is_glass(ior, kt)
        ior_a, kt_a = np.asarray(ior, dtype=float), np.asarray(kt, dtype=float)
    lens = lens_rows[rows]
    beta, alpha = ang[obst], ang[lens]
    g = glass[obst]
    hard = _overlapping_rows(rows, obst, count, direction, ang, n_rows)
    passed = np.zeros(rows.size)  # the glass blockers' share of their blocked directions
    if g.any():
        gamma = _angle(direction[lens[g]], direction[obst[g]])
        passed[g] = glass_passed(alpha[g], beta[g], gamma, ior_a[obst[g]], kt_a[obst[g]])
    blocked = np.zeros(n_rows)
    np.add.at(blocked, rows, cover * (1.0 - passed))  # disjoint: the union is the sum
    unblocked = np.clip(1.0 - blocked, 0.0, 1.0)
    if hard.any() and int((count[hard] ** 2).sum()) > MAX_INTERACTIONS:
        # a crowded view: overlapping blockers as independent (the product), not sampled
        prod = np.ones(n_rows)
        np.multiply.at(prod, rows, 1.0 - cover * (1.0 - passed))
        unblocked[hard] = prod[hard]
    elif hard.any():
        sampled = _sampled_blocked(
            rows, obst, count, hard, lens_rows, direction, ang, glass, ior_a, kt_a, n_samples
        )
        unblocked[hard] = np.clip(1.0 - sampled[hard], 0.0, 1.0)
    return unblocked


def _angle(a, b):
    """Angles between unit rows (atan2 of |a × b| and a · b: no acos)."""
    return np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1), np.einsum("...i,...i->...", a, b))


def _overlapping_rows(rows, obst, count, direction, ang, n_rows):
    """Rows with two blockers whose caps overlap (their union is no sum)."""
    out = np.zeros(n_rows, dtype=bool)
    multi = count[rows] > 1
    if not multi.any():
        return out
    starts = np.concatenate([[0], np.cumsum(count)])
    p = np.flatnonzero(multi)  # each pair with every pair of its row after it
    after = starts[rows[p] + 1] - p - 1
    q = concat_ranges(p + 1, after)
    p = np.repeat(p, after)
    gap = _angle(direction[obst[p]], direction[obst[q]])
    out[rows[p[gap < ang[obst[p]] + ang[obst[q]]]]] = True
    return out


_GL_X, _GL_W = np.polynomial.legendre.leggauss(32)


def glass_passed(alpha, beta, gamma, ior, kt) -> np.ndarray:
    """What a glass blocker (angular radius ``beta``, ``gamma`` off the lens' axis, cap
    ``alpha``) passes of the lens' directions it covers: kt² T(ι) (sin ι = sin θ /
    sin β at θ from its centre) averaged over its cap ∩ the lens' cap. 1-D in θ: the
    share of the circle θ inside the lens' cap is an arc (cos φ ≥ c, c from the
    half-angle forms, no cancellation), Gauss–Legendre between the kinks |α − γ|, α + γ."""
    cuts = np.sort(
        np.stack(
            [
                np.zeros_like(beta),
                np.minimum(np.abs(alpha - gamma), beta),
                np.minimum(alpha + gamma, beta),
                beta,
            ],
            axis=1,
        ),
        axis=1,
    )
    lo, hi = cuts[:, :-1, None], cuts[:, 1:, None]  # (G, 3, 1): three pieces
    theta = (0.5 * (lo + hi) + 0.5 * (hi - lo) * _GL_X).reshape(beta.size, -1)
    wts = (0.5 * (hi - lo) * _GL_W).reshape(beta.size, -1) * np.sin(theta)
    a, gm = alpha[:, None], gamma[:, None]
    sg = np.sin(gm)
    with np.errstate(divide="ignore", invalid="ignore"):
        c = 1.0 - 2.0 * np.sin(0.5 * (a + theta - gm)) * np.sin(0.5 * (a - theta + gm)) / (
            np.sin(theta) * sg
        )
    c = np.where(sg > 0.0, c, np.where(theta <= a, -1.0, 1.0))
    c = np.clip(np.nan_to_num(c, nan=1.0), -1.0, 1.0)
    frac = np.arctan2(np.sqrt((1.0 - c) * (1.0 + c)), c) / np.pi  # arccos(c)/π
    share = glass_share(np.sin(theta) / np.sin(beta)[:, None], ior[:, None], kt[:, None])
    num, den = (share * frac * wts).sum(axis=1), (frac * wts).sum(axis=1)
    return np.where(den > 0.0, num / np.where(den > 0.0, den, 1.0), 0.0)


def _sampled_blocked(rows, obst, count, sampled, lens_rows, direction, ang, glass, ior, kt, n_max):
    """Blocked share of the rows ``sampled``: 1 − Σ_k ∫ over blocker k's cap ∩ the
    lens' cap of (1 − ∏_j passed_j) / (how many blockers' caps hold the direction),
    over the lens' solid angle. Each term (row, k) on a grid over the smaller of the two
    caps (a small blocker's own disc is covered exactly, a lens inside a big blocker's
    disc is resolved: only the union's edges are sampled), meeting only the row's
    blockers whose caps reach that grid; vectorised over all terms at once."""
    starts = np.concatenate([[0], np.cumsum(count)])
    t_pair = np.flatnonzero(sampled[rows])  # one term per pair of a sampled row
    t_row, t_blk = rows[t_pair], obst[t_pair]
    lens = lens_rows[t_row]
    w, alpha = direction[lens], ang[lens]
    bk = ang[t_blk]
    own = bk <= alpha
    wd = np.where(own[:, None], direction[t_blk], w)
    ad = np.where(own, bk, alpha)
    ref = np.where(own[:, None], w, direction[t_blk])
    # interactions: (term, a blocker of its row whose cap reaches the term's grid)
    it_term = np.repeat(np.arange(t_pair.size), count[t_row])
    it_pair = concat_ranges(starts[t_row], count[t_row])
    it_blk = obst[it_pair]
    wj = direction[it_blk]
    cross = np.cross(wd[it_term], wj)
    gamma = np.arctan2(np.linalg.norm(cross, axis=1), np.einsum("ij,ij->i", wd[it_term], wj))
    is_self = it_pair == t_pair[it_term]
    keep = is_self | (gamma < (ad[it_term] + ang[it_blk]) * (1.0 + 1e-9) + 1e-12)
    it_term, it_blk, is_self, gamma = it_term[keep], it_blk[keep], is_self[keep], gamma[keep]
    ref = _azimuth_ref(ref, wd, it_term, it_blk, gamma, direction, ang)
    n = int(np.clip(BUDGET // max(it_term.size, 1), MIN_SAMPLES, n_max))
    nr, na = _rings(n)
    n = nr * na
    first = np.searchsorted(it_term, np.arange(t_pair.size + 1))  # each term's interactions
    value = np.zeros(t_pair.size)
    lo = 0
    while lo < t_pair.size:  # chunks of terms: interactions × samples within the budget
        hi = int(np.searchsorted(first, first[lo] + BUDGET // n, side="right")) - 1
        hi = min(max(hi, lo + 1), t_pair.size)
        value[lo:hi] = _terms(
            slice(lo, hi),
            slice(first[lo], first[hi]),
            it_term,
            it_blk,
            is_self,
            wd,
            ad,
            ref,
            own,
            w,
            alpha,
            direction,
            ang,
            glass,
            ior,
            kt,
            nr,
            na,
        )
        lo = hi
    blocked = np.zeros(len(lens_rows))
    np.add.at(blocked, t_row, value)
    return blocked


def _terms(
    ts,
    its,
    it_term,
    it_blk,
    is_self,
    wd,
    ad,
    ref,
    own,
    w,
    alpha,
    direction,
    ang,
    glass,
    ior,
    kt,
    nr,
    na,
):
    """The blocked share (over the lens' cap) of the terms ``ts`` with their
    interactions ``its`` (sorted by term)."""
    wd, ad, own, w, alpha = wd[ts], ad[ts], own[ts], w[ts], alpha[ts]
    off = cap_offsets(wd, ad, ref[ts], nr, na)  # s − wd, (T, N, 3)
    h = _ramp_width(ad, nr, na)
    d_lens = (wd - w)[:, None, :] + off
    in_lens = np.where(
        own[:, None], coverage(np.einsum("pni,pni->pn", d_lens, d_lens), alpha, h), 1.0
    )
    lt = it_term[its] - ts.start  # each interaction's term, local
    blk, me = it_blk[its], is_self[its]
    diff = (wd[lt] - direction[blk])[:, None, :] + off[lt]
    chord2 = np.einsum("pni,pni->pn", diff, diff)
    share, cover = passed_share(
        chord2, np.maximum(ang[blk], 1e-300), glass[blk], ior[blk], kt[blk], h[lt]
    )
    cover = np.where((me & own[lt])[:, None], 1.0, cover)  # its own grid lies inside it
    passed = 1.0 - cover * (1.0 - share)
    starts = np.flatnonzero(np.r_[True, lt[1:] != lt[:-1]])
    with np.errstate(divide="ignore"):
        log_passed = np.add.reduceat(np.log(passed), starts, axis=0)
    holders = np.add.reduceat(cover, starts, axis=0)
    in_k = cover[me]  # one self interaction per term, in term order
    term = in_lens * in_k * (1.0 - np.exp(log_passed)) / np.maximum(holders, 1e-12)
    ratio = (np.sin(0.5 * ad) / np.sin(0.5 * alpha)) ** 2
    return ratio * term.mean(axis=1)


def _azimuth_ref(ref, wd, it_term, it_blk, gamma, direction, ang):
    """Where each grid's azimuth starts: toward the other cap (the lens', or blocker k's);
    if that one is centred on the grid, toward the widest blocker that is not (every
    cap centred: anything will do, the whole is symmetric). Never the world's axes, so
    turning the scene does not move the grid against the caps."""
    perp = ref - np.einsum("pi,pi->p", ref, wd)[:, None] * wd
    bad = np.flatnonzero(np.linalg.norm(perp, axis=1) <= 1e-9)
    if bad.size == 0:
        return ref
    ref = ref.copy()
    for t in bad:
        mine = (it_term == t) & (gamma > 1e-9)
        if mine.any():
            k = np.flatnonzero(mine)
            ref[t] = direction[it_blk[k[np.argmax(ang[it_blk[k]])]]]
    return ref


def ray_passes(origins, dirs, t_end, centers, radii, ior=None, kt=None) -> np.ndarray:
    """What the spheres (``centers`` (B, 3), ``radii`` (B,); glass where ``is_glass``)
    pass of each ray ``origins + t dirs`` (…, 3), unit ``dirs``, on ``0 < t < t_end``:
    0 through an opaque one, kt² T(ι) through a glass one (ι from the impact
    parameter, the same at both surfaces), the product over the spheres it crosses."""
    o = np.asarray(origins, dtype=float)
    d = np.asarray(dirs, dtype=float)
    o, d = np.broadcast_arrays(o, d)
    out = np.ones(d.shape[:-1])
    centers = np.asarray(centers, dtype=float).reshape(-1, 3)
    radii = np.asarray(radii, dtype=float).reshape(-1)
    glass = np.zeros(radii.size, dtype=bool) if ior is None or kt is None else is_glass(ior, kt)
    for b in range(radii.size):
        f = o - centers[b]
        beta = np.einsum("...i,...i->...", f, d)
        perp = f - beta[..., None] * d
        b2 = np.einsum("...i,...i->...", perp, perp)  # impact parameter²
        r = radii[b]
        half = np.sqrt(np.maximum(r * r - b2, 0.0))
        hit = (b2 < r * r) & (-beta + half > 0.0) & (-beta - half < t_end)
        if glass[b]:
            n_b, kt_b = (float(np.asarray(x, dtype=float).reshape(-1)[b]) for x in (ior, kt))
            share = glass_share(np.sqrt(b2) / r, n_b, kt_b)
        else:
            share = 0.0
        out = np.where(hit, out * share, out)
    return out
