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
edges as wide as the cell along each rim's normal; a direction inside several
blockers' caps counts once, for the widest of them), each direction passed by the
product of its blockers' shares (0 behind an opaque one; a glass one's averaged over
the cell's width, from a table of ∫ T). Each grid's resolution follows from its size
against the lens' cap (its error a share of the lens' flux), not from a budget. The glass
blocker's own focusing (it deflects what it passes: a tertiary source) is out of scope:
what passes is counted as if undeflected.

`ray_passes` tells what blockers pass of given rays (the Exact profile's mask,
`exact_profile_mask.py`, and the caustic layer's beam, `core/caustic_layer/shadow.py`).

Each grid's azimuth starts toward the other cap, and blockers are ranked by their
size, so the result does not depend on how the scene is turned or in which order its
spheres come (but for ties).
"""

from __future__ import annotations

import functools

import numpy as np

from ..lens.refraction import fresnel_transmittance
from ..lens.sphere import intersect_sphere
from ..shared import parallel
from ..shared.parallel import map_slices
from ..shared.ranges import concat_ranges

#: Rings of a sampled term's grid (× 2·rings azimuths): the fewest of these ≥
#: `_TERM_FULL` × the grid's radius against the lens' cap (its edge error, a share
#: ∝ (ρ/α)²/rings² of the lens' flux: a resolution per term, not a budget per call).
#: On the 16 × 10 000 droplets' 161 rows with three overlapping blockers, against this
#: code at 256 rings (itself within 1e-5 of an independent 1-D integration): 24 → at
#: most 1.2e-3, half within 2e-4 (16: 1.5e-3, twice as fast; the former sampler at its
#: budget: 8e-3). What is left is mostly slivers thinner than a cell.
TERM_RINGS = (4, 6, 8, 12, 16, 24, 32, 48, 64, 96, 128)
_TERM_FULL = 24
#: Sample × blocker evaluations per block of terms (memory).
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


def _cell_sides(a, nr, na):
    """Per sample of the grids over caps of angular radius ``a`` (P,): its cell's width
    along the ring (dθ = dv / sin θ) and along the azimuth (sin θ dφ), (P, N) each."""
    omc = 2.0 * np.sin(0.5 * a) ** 2
    v = ((np.arange(nr) + 0.5) / nr)[None, :] * omc[:, None]
    sin_t = np.sqrt(v * (2.0 - v))
    ring = (omc / nr)[:, None] / np.maximum(sin_t, 1e-300)
    return np.repeat(ring, na, axis=1), np.repeat(sin_t * (2.0 * np.pi / na), na, axis=1)


def _ramp_along(off, off_len, to_rim, ring, arc):
    """A ramp's width for an edge whose normal at each sample points along ``to_rim``
    (the sample less the edge's cap centre, (P, N, 3)): the cell's width along that
    normal, ``ring`` |cos ψ| + ``arc`` |sin ψ| (ψ off the grid's radial direction
    ``off``, of length ``off_len``). A width matched to the cell keeps each edge's error
    second order in the cell (a thin ring's width alone is not: an edge across the
    rings saw point samples as long as the ring's cells)."""
    dot = np.einsum("pni,pni->pn", off, to_rim)
    norm = off_len * np.sqrt(np.einsum("pni,pni->pn", to_rim, to_rim))  # |to_rim| = chord
    cos = np.minimum(np.abs(dot) / np.maximum(norm, 1e-300), 1.0)
    return ring * cos + arc * np.sqrt((1.0 - cos) * (1.0 + cos))


def coverage(chord2, radius, h) -> np.ndarray:
    """How much of a sample's cell (angular size ``h`` (…, N)) lies in a cap of angular
    ``radius`` (…,) whose centre is at chord² ``chord2`` (…, N): a linear ramp over the
    signed angular distance to the rim. Anti-aliased: the estimate is continuous in
    the geometry (no sample flips in or out on rounding) and its edge error is
    second order in h."""
    chord = np.sqrt(np.minimum(chord2, 4.0))
    return _rim_ramp(chord, np.sqrt(np.maximum(1.0 - 0.25 * chord2, 0.0)), radius, h)


def _rim_ramp(chord, cos_half, radius, h):
    """`coverage` from the chord 2 sin(θ/2) and cos(θ/2): β − θ as the chords'
    difference over cos(θ/2) (d chord / dθ; off by a share θ h / 4 of itself within
    the ramp, the sign exact beyond it: no angle needed)."""
    gap = 2.0 * np.sin(0.5 * radius)[..., None] - chord
    return np.clip(0.5 + gap / np.maximum(cos_half * h, 1e-300), 0.0, 1.0)


def passed_share(chord2, beta, glass, ior, kt, h):
    """What each blocker passes of the directions at chord² ``chord2`` (B, N) from its
    centre direction that go through it (radial angle ``beta``, glass or not, index, kt
    per blocker (B,)), and how much of each sample's cell its cap covers
    (:func:`coverage`)."""
    share = np.zeros(chord2.shape)
    g = np.flatnonzero(glass)  # Fresnel only for the glass ones' rows
    if g.size:
        half = 0.5 * np.sqrt(np.minimum(chord2[g], 4.0))
        cos_half = np.sqrt(np.maximum(1.0 - half * half, 0.0))
        share[g] = _cell_share(half, cos_half, np.sin(beta[g]), h[g], ior[g], kt[g])
    return share, coverage(chord2, beta, h)


#: Points of the tables of T(x) and its integral ∫₀ˣ T, uniform in x = sin ι (looked up
#: by index, not searched); interpolated linearly, within ~1e-8.
_TABLE_POINTS = 4097


@functools.lru_cache(maxsize=64)
def _fresnel_table(ior: float):
    """T(x) (two surfaces, kt = 1) and G(x) = ∫₀ˣ T dx' at x uniform on [0, 1] for one
    index, and their steps to the next point (G by Simpson on a grid 64 × as fine: T's
    (1 − x²)^(3/2) at grazing costs it ~1e-12)."""
    fine = 64 * (_TABLE_POINTS - 1)
    f = glass_share(np.linspace(0.0, 1.0, fine + 1), ior, 1.0)
    simpson = (f[:-2:2] + 4.0 * f[1:-1:2] + f[2::2]) * (1.0 / (3.0 * fine))
    g = np.concatenate([[0.0], np.cumsum(simpson)])[::32]
    t = f[::64]
    return t, np.diff(t), g, np.diff(g)


def _lookup(x, table, step):
    """Linear interpolation in a table uniform on [0, 1] (x in [0, 1])."""
    pos = x * (table.size - 1)
    i = np.minimum(pos.astype(np.int64), table.size - 2)
    return table[i] + (pos - i) * step[i]


def _cell_share(half, cos_half, sin_beta, h, ior, kt):
    """kt² T(ι) averaged over the part inside the blocker of each sample's cell (its
    width ``h`` along the blocker's radius; the sample at sin(θ/2) = ``half``): T falls
    from T(0) to 0 within a few % of β of the rim, a layer that one value per cell
    misses (a first-order error); the mean over [θ − h/2, θ + h/2] ∩ [0, β] of T in
    x = sin θ / sin β from the tabulated ∫ T dx. Rows (B, N); per row ``sin_beta``,
    ``ior``, ``kt`` (B,)."""
    sin_t = 2.0 * half * cos_half
    cos_t = 1.0 - 2.0 * half * half
    sh = 0.5 * h  # sin, cos of h/2 (h ≪ 1)
    mid = sin_t * (1.0 - 0.125 * h * h)
    arm = cos_t * sh
    inv = 1.0 / sin_beta[:, None]
    x_lo = np.clip((mid - arm) * inv, 0.0, 1.0)
    x_hi = np.clip((mid + arm) * inv, 0.0, 1.0)
    wide = x_hi - x_lo
    out = np.empty(half.shape)
    for n in np.unique(ior):
        r = slice(None) if n == ior[0] and (ior == n).all() else np.flatnonzero(ior == n)
        t, dt, g, dg = _fresnel_table(float(n))
        lo, hi, dx = x_lo[r], x_hi[r], wide[r]
        mean = (_lookup(hi, g, dg) - _lookup(lo, g, dg)) / np.maximum(dx, 1e-300)
        thin = dx <= 1e-9  # too thin to difference (or wholly outside): its middle's T
        if thin.any():
            mean[thin] = _lookup(0.5 * (lo[thin] + hi[thin]), t, dt)
        out[r] = mean
    return out * np.clip(kt, 0.0, 1.0)[:, None] ** 2


def union_unblocked(
    rows,
    obst,
    cover,
    lens_rows,
    direction,
    ang,
    ior=None,
    kt=None,
    gamma=None,
) -> np.ndarray:
    """The unblocked share of every lens row (``len(lens_rows)``), from its partial
    blockers: pairs (``rows``, ``obst``) sorted by row, ``cover`` each pair's closed-form
    cap overlap (share of the lens' cap), ``ior``, ``kt`` per sphere (None: all opaque).

    Where the blockers' caps do not overlap one another the union is the sum:
    1 − Σ cover_k (1 − ⟨passed⟩_k), ⟨passed⟩ 0 for an opaque blocker and, for a glass
    one, its Fresnel share averaged over what it covers of the lens' cap
    (:func:`glass_passed`, 1-D). Rows whose blockers overlap are sampled
    (:func:`_sampled_blocked`). ``gamma``: each pair's angle lens–blocker, if known."""
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
    crowded = hard.any() and int((count[hard] ** 2).sum()) > MAX_INTERACTIONS
    passed = np.zeros(rows.size)  # the glass blockers' share of their blocked directions
    if g.any():
        if gamma is None:
            gamma_g = _angle(direction[lens[g]], direction[obst[g]])
        else:
            gamma_g = np.asarray(gamma, dtype=float)[g]
        # Rows taken as a product are off by ~5e-3–1e-2 (the overlaps counted twice):
        # their glass shares need be no closer than the coarse rule's 3e-4.
        coarse = hard[rows[g]] if crowded else np.zeros(gamma_g.size, dtype=bool)
        o = obst[g]
        for sel, rule in ((~coarse, _END_RULE), (coarse, _CROWDED_RULE)):
            if sel.any():
                k = np.flatnonzero(g)[sel]
                passed[k] = glass_passed(
                    alpha[k], beta[k], gamma_g[sel], ior_a[o[sel]], kt_a[o[sel]], rule
                )
    blocked = np.zeros(n_rows)
    np.add.at(blocked, rows, cover * (1.0 - passed))  # disjoint: the union is the sum
    unblocked = np.clip(1.0 - blocked, 0.0, 1.0)
    if crowded:
        # a crowded view: overlapping blockers as independent (the product), not sampled
        prod = np.ones(n_rows)
        np.multiply.at(prod, rows, 1.0 - cover * (1.0 - passed))
        unblocked[hard] = prod[hard]
    elif hard.any():
        # overlapping only in pairs: the sum less each pair's overlap (sampled alone)
        pairs, p, q = _pair_only_overlaps(rows, obst, count, hard, direction, ang)
        if p.size:
            twice = _pair_overlap_blocked(
                p, q, rows, obst, lens_rows, direction, ang, glass, ior_a, kt_a
            )
            blocked -= np.bincount(rows[p], twice, minlength=n_rows)
            unblocked[pairs] = np.clip(1.0 - blocked[pairs], 0.0, 1.0)
        rest = hard & ~pairs
        if rest.any():
            sampled = _sampled_blocked(
                rows, obst, count, rest, lens_rows, direction, ang, glass, ior_a, kt_a
            )
            unblocked[rest] = np.clip(1.0 - sampled[rest], 0.0, 1.0)
    return unblocked


def _angle(a, b):
    """Angles between unit rows (atan2 of |a × b| and a · b: no acos)."""
    return np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1), np.einsum("...i,...i->...", a, b))


def _overlapping_rows(rows, obst, count, direction, ang, n_rows):
    """Rows with two blockers whose caps overlap (their union is no sum). Each
    blocker is first tried against the next of its row (in a crowded view most rows
    are found so); every pair of the rows still open after that."""
    out = np.zeros(n_rows, dtype=bool)
    multi = count[rows] > 1
    if not multi.any():
        return out
    p = np.flatnonzero(rows[1:] == rows[:-1])
    _mark_overlaps(out, rows, obst, p, p + 1, direction, ang)
    sel = np.flatnonzero(multi & ~out[rows])
    if sel.size:
        r, o = rows[sel], obst[sel]
        cnt = np.bincount(r, minlength=n_rows)
        starts = np.concatenate([[0], np.cumsum(cnt)])
        p = np.arange(r.size)  # each pair with every pair of its row after it
        after = starts[r + 1] - p - 1
        q = concat_ranges(p + 1, after)
        _mark_overlaps(out, r, o, np.repeat(p, after), q, direction, ang)
    return out


def _caps_overlap(i, k, direction, ang):
    """Whether the caps of spheres i and k (angular radii ``ang``, unit ``direction``)
    overlap, γ < ρ_i + ρ_k, as chords: |u_i − u_k| < 2 sin((ρ_i + ρ_k)/2) (no angle
    to take: one sine, not an atan2 and a cross product; as exact for tiny caps)."""
    d = direction[i] - direction[k]
    chord2 = np.einsum("ij,ij->i", d, d)
    reach = ang[i] + ang[k]
    lim = 2.0 * np.sin(0.5 * np.minimum(reach, np.pi))
    return (chord2 < lim * lim) | (reach > np.pi)


def _mark_overlaps(out, rows, obst, p, q, direction, ang):
    """out[row] = True where the caps of the pairs (p, q) of its blockers overlap."""

    def mark(s):  # only ever sets True: slices may write side by side
        out[rows[p[s][_caps_overlap(obst[p[s]], obst[q[s]], direction, ang)]]] = True

    map_slices(mark, p.size)


def _end_rule(m):
    """Gauss–Legendre in φ ∈ [0, π] with t = (1 − cos φ)/2: nodes t ∈ (0, 1) and
    weights on [0, 1], crowded at both ends so that √-type end points (a circle
    tangent to the lens' rim, grazing incidence at the blocker's rim) integrate
    like smooth functions."""
    x, w = np.polynomial.legendre.leggauss(m)
    phi = 0.5 * np.pi * (1.0 + x)
    return 0.5 * (1.0 - np.cos(phi)), 0.25 * np.pi * w * np.sin(phi)


#: 8 nodes: on the dense grid's 0.5 M glass blockers within 1.7e-5 (× their cover: the
#: error in the unblocked share) of a 128-node reference, 10 within 5e-6, 16 within 8e-7.
#: README Limits: a glass blocker's share within 2e-5 of the lens' share.
_END_RULE = _end_rule(8)
#: Glass shares of rows taken as a product in a crowded view (`MAX_INTERACTIONS`): 6
#: nodes, a row's product within 1.6e-4 of 8 nodes' on the dense grid (mean 8e-5) and
#: 2.7e-4 on the 1 × 100 000 droplets, where the product itself is off by 1.1e-2 and
#: 1.1e-3 (medians; up to 7e-2 and 1.7e-2) against the sampled union (`bench
#: union_error`). 4 nodes: 1.1e-3 and 2.1e-3.
_CROWDED_RULE = _end_rule(6)
#: Blockers per block of the quadrature ((nodes, rows) arrays of a few hundred kB).
#: 494 k dense grid blockers, wall: inline 0.27 s at 1024, 0.23 at 2048, 0.19 at 8192;
#: in 2 threads 0.24 s at 2048, 0.15 at 8192, 0.13 at 16384.
_CHUNK = 8192
#: The same in threads: fewer, longer numpy steps hold the GIL less often.
_THREADED_CHUNK = 16384


def glass_passed(alpha, beta, gamma, ior, kt, rule=None) -> np.ndarray:
    """What a glass blocker (angular radius ``beta``, ``gamma`` off the lens' axis, cap
    ``alpha``) passes of the lens' directions it covers: kt² T(ι) (sin ι = sin θ /
    sin β at θ from its centre) averaged over its cap ∩ the lens' cap. 1-D in
    v = 1 − cos θ (the solid angle per azimuth: no sin θ weight, no θ itself needed):
    the share of the circle θ inside the lens' cap is an arc (cos φ ≥ c, c from the
    half-angle forms, no cancellation); where γ < α the circles θ < α − γ lie inside
    the cap (share 1), the circles from |α − γ| to min(α + γ, β) cross its rim, and
    beyond neither piece there is nothing of the lens' cap. Each piece by `rule`
    (`_end_rule`'s nodes and weights; None: `_END_RULE`)."""
    rule = _END_RULE if rule is None else rule
    alpha, beta, gamma, ior, kt = (
        np.asarray(x, dtype=float) for x in (alpha, beta, gamma, ior, kt)
    )
    out = np.zeros(beta.size)
    # an index above 1 (the common glass): one fused pass; any other by the general one
    usual = np.isfinite(ior) & (ior > 1.0)
    threads = parallel.workers(beta.size)
    chunk = _CHUNK if threads == 1 else _THREADED_CHUNK
    jobs = []
    for sel, block in ((usual, _glass_usual_block), (~usual, _glass_passed_block)):
        idx = np.flatnonzero(sel)
        jobs.extend((block, idx[s : s + chunk]) for s in range(0, idx.size, chunk))

    def run(part):  # the blocks are row by row: any thread computes its rows alike
        for block, k in jobs[part]:
            out[k] = block(alpha[k], beta[k], gamma[k], ior[k], kt[k], rule)

    map_slices(run, len(jobs), threads=threads)
    return out


def _glass_usual_block(alpha, beta, gamma, n, kt, rule):
    """`_glass_passed_block` for indices above 1 (no total reflection): both pieces in
    one array (piece A's rows after piece B's, without an arc), rows of no width left
    out, T(ι) from sin²ι = v (2 − v) / sin²β (no square root for sin θ).
    Arrays are (nodes, rows), steps in place: a row's sum adds whole rows of memory.
    (Single precision for the roots and Fresnel's products was 20 % faster and within
    2e-7 of double, but a turn of the scene, moving the inputs in their last bits, can
    flip its roundings by more than the 1e-9 tests/core/phase1/test_stability.py allows.)"""
    v0 = _v(np.minimum(np.abs(alpha - gamma), beta))
    v1 = _v(np.minimum(alpha + gamma, beta))
    b_rows = np.flatnonzero(v1 > v0)  # piece B: circles crossing the lens' rim
    a_rows = np.flatnonzero((gamma < alpha) & (v0 > 0.0))  # piece A: wholly inside
    nb = b_rows.size
    rows = np.concatenate([b_rows, a_rows])
    lo = np.concatenate([v0[b_rows], np.zeros(a_rows.size)])
    width = np.concatenate([v1[b_rows] - v0[b_rows], v0[a_rows]])
    end_t, end_w = rule
    v = width * end_t[:, None]
    v += lo
    sin2 = 2.0 - v
    sin2 *= v  # sin²θ
    wts = np.empty(v.shape)
    if nb:
        # cos φ ≥ c on the circle θ: c = (v cos γ − 2 sin((α−γ)/2) sin((α+γ)/2)) /
        # (sin θ sin γ), the cosine law with cos α − cos γ as a product; γ = 0 leaves no
        # piece B. The arc's half-angle acos c as atan √((1 − c)/(1 + c)) (SPEC §4.2).
        ab, gb = alpha[b_rows], gamma[b_rows]
        c = v[:, :nb] * np.cos(gb)
        c -= 2.0 * np.sin(0.5 * (ab - gb)) * np.sin(0.5 * (ab + gb))
        c /= np.sqrt(sin2[:, :nb]) * np.sin(gb)
        np.clip(c, -1.0, 1.0, out=c)
        ratio = (1.0 - c) / np.maximum(1.0 + c, 1e-300)
        np.sqrt(ratio, out=ratio)
        wts[:, :nb] = np.arctan(ratio, out=ratio)
        wts[:, :nb] *= 2.0
    wts[:, nb:] = np.pi  # piece A: the whole circle (the arc's π)
    wts *= end_w[:, None]
    n_r = n[rows]
    s2 = sin2
    s2 *= 1.0 / np.sin(beta[rows]) ** 2  # sin²ι
    c_i = 1.0 - s2
    np.maximum(c_i, 0.0, out=c_i)
    np.sqrt(c_i, out=c_i)
    s2 *= -1.0 / (n_r * n_r)
    s2 += 1.0
    c_t = np.sqrt(s2, out=s2)
    nc_t, nc_i = c_t * n_r, c_i * n_r
    tsp = nc_t * c_i
    tsp *= 4.0  # t_s (c_i + n c_t)² = t_p (c_t + n c_i)²
    nc_t += c_i
    nc_t *= nc_t
    t_s = tsp / nc_t
    nc_i += c_t
    nc_i *= nc_i
    tsp /= nc_i  # t_p
    t_s *= t_s
    tsp *= tsp
    t_s += tsp  # 2 T
    t_s *= wts
    # node by node sums, in node order (not a matrix product nor numpy's sum, whose
    # order changes with the shape: one blocker's share must not depend on how many
    # are computed with it)
    num_r, den_r = t_s[0].copy(), wts[0].copy()
    for k in range(1, t_s.shape[0]):
        num_r += t_s[k]
        den_r += wts[k]
    num_r *= width
    den_r *= width
    num, den = np.zeros(alpha.size), np.zeros(alpha.size)
    num[b_rows], den[b_rows] = num_r[:nb], den_r[:nb]
    num[a_rows] += num_r[nb:]
    den[a_rows] += den_r[nb:]
    ok = den > 0.0
    return np.where(ok, 0.5 * np.clip(kt, 0.0, 1.0) ** 2 * num / np.where(ok, den, 1.0), 0.0)


def _v(theta):
    return 2.0 * np.sin(0.5 * theta) ** 2  # 1 − cos θ, no cancellation


def _glass_passed_block(alpha, beta, gamma, ior, kt, rule):
    sb, n, kt = np.sin(beta)[:, None], ior[:, None], kt[:, None]
    lo_b = np.minimum(np.abs(alpha - gamma), beta)
    v0, v1 = _v(lo_b)[:, None], _v(np.minimum(alpha + gamma, beta))[:, None]
    p, q = 0.5 * (alpha - gamma)[:, None], 0.5 * (alpha + gamma)[:, None]
    sg = np.sin(gamma)[:, None]
    arc = (np.cos(p), np.sin(p), np.sin(q), np.cos(q), np.where(sg > 0.0, sg, 1.0))
    # piece B: the circles crossing the lens' rim; piece A (γ < α): circles wholly in it
    num, den = _pieces(v0, v1, sb, n, kt, arc, rule)
    inside = np.flatnonzero(gamma < alpha)
    if inside.size:
        na, da = _pieces(
            0.0 * v0[inside], v0[inside], sb[inside], n[inside], kt[inside], None, rule
        )
        num[inside] += na
        den[inside] += da
    return np.where(den > 0.0, num / np.where(den > 0.0, den, 1.0), 0.0)


def _pieces(v0, v1, sb, n, kt, arc, rule):
    """∫ share · (arc share) dv and ∫ (arc share) dv over [v0, v1] (per row), split
    where an index below 1 starts total reflection (its T has a √-type kink there)."""
    num, den = _piece(v0, v1, sb, n, kt, arc, rule)
    odd = np.flatnonzero(np.isfinite(n[:, 0]) & (n[:, 0] < 1.0))
    if odd.size:
        s_crit = np.clip(n[odd] * sb[odd], 0.0, 1.0)  # sin θ where sin ι = n
        v_crit = s_crit * s_crit / (1.0 + np.sqrt((1.0 - s_crit) * (1.0 + s_crit)))
        mid = np.clip(v_crit, v0[odd], v1[odd])
        sub = None if arc is None else tuple(x[odd] for x in arc)
        n1, d1 = _piece(v0[odd], mid, sb[odd], n[odd], kt[odd], sub, rule)
        n2, d2 = _piece(mid, v1[odd], sb[odd], n[odd], kt[odd], sub, rule)
        num[odd], den[odd] = n1 + n2, d1 + d2
    return num, den


def _piece(v0, v1, sb, n, kt, arc, rule):
    v = v0 + (v1 - v0) * rule[0]
    wts = (v1 - v0) * rule[1]
    sh, ch = np.sqrt(0.5 * v), np.sqrt(1.0 - 0.5 * v)  # sin, cos of θ/2
    sin_t = 2.0 * sh * ch
    if arc is not None:
        # c = 1 − 2 sin((α + θ − γ)/2) sin((α − θ + γ)/2) / (sin θ sin γ); γ = 0 leaves
        # no piece B (zero width), its c is then anything finite.
        cp, sp, sq, cq, sg = arc
        c = 1.0 - 2.0 * (sh * cp + ch * sp) * (sq * ch - cq * sh) / (sin_t * sg)
        c = np.clip(c, -1.0, 1.0)  # the arc's half-angle, acos c by atan2 (SPEC §4.2)
        wts = 2.0 * np.arctan2(np.sqrt(1.0 - c), np.sqrt(1.0 + c)) * (1.0 / np.pi) * wts
    share = _share(sin_t / sb, n, kt)
    return (share * wts).sum(axis=1), wts.sum(axis=1)


def _share(sin_iota, n, kt):
    """kt² T(ι) as `glass_share`, written out for n > 1 (no total reflection, no
    zero denominator: the common glass), `glass_share` for any other index."""
    s = np.clip(sin_iota, 0.0, 1.0)
    usual = np.isfinite(n[:, 0]) & (n[:, 0] > 1.0)
    if not usual.all():
        out = np.empty(s.shape)
        odd = ~usual
        out[odd] = glass_share(s[odd], n[odd], kt[odd])
        if usual.any():
            out[usual] = _share(s[usual], n[usual], kt[usual])
        return out
    c_i = np.sqrt((1.0 - s) * (1.0 + s))
    r = s / n
    c_t = np.sqrt((1.0 - r) * (1.0 + r))
    num = 4.0 * n * c_i * c_t
    t_s = num / (c_i + n * c_t) ** 2
    t_p = num / (c_t + n * c_i) ** 2
    return np.clip(kt, 0.0, 1.0) ** 2 * 0.5 * (t_s * t_s + t_p * t_p)


def _sampled_blocked(rows, obst, count, sampled, lens_rows, direction, ang, glass, ior, kt):
    """Blocked share of the rows ``sampled``: 1 − Σ_k ∫ over blocker k's cap ∩ the
    lens' cap, outside the caps of the blockers before k (widest first), of
    (1 − ∏_j passed_j), over the lens' solid angle. Each term (row, k) on a grid over
    the smaller of the two caps (a small blocker's own disc is covered exactly, a lens
    inside a big blocker's disc is resolved: only the union's edges are sampled), its
    rings by its size against the lens' cap (`TERM_RINGS`), meeting only the row's
    blockers whose caps reach that grid; vectorised over the terms of each level."""
    starts = np.concatenate([[0], np.cumsum(count)])
    t_pair = np.flatnonzero(sampled[rows])  # one term per pair of a sampled row
    bk, alpha = ang[obst[t_pair]], ang[lens_rows[rows[t_pair]]]
    # rings by the grid's radius against the lens' cap (the edge error ∝ (ρ/α)²/rings²)
    size = np.sin(0.5 * np.minimum(bk, alpha)) / np.sin(0.5 * alpha)
    levels = np.asarray(TERM_RINGS)
    lv = np.minimum(np.searchsorted(levels, _TERM_FULL * size), levels.size - 1)
    by_level = np.argsort(lv, kind="stable")
    t_pair, lv = t_pair[by_level], lv[by_level]
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
    # each direction is counted by the first blocker of its row holding it, widest first
    # (then by index: neither the scene's turn nor its order moves it)
    pos = np.empty(rows.size, dtype=np.int64)
    pos[np.lexsort((obst, -ang[obst], rows))] = np.arange(rows.size)
    rank = np.sign(pos[it_pair] - pos[t_pair[it_term]]).astype(np.int8)  # −1 before, 0 self
    keep = (rank == 0) | (gamma < (ad[it_term] + ang[it_blk]) * (1.0 + 1e-9) + 1e-12)
    it_term, it_blk, rank, gamma = it_term[keep], it_blk[keep], rank[keep], gamma[keep]
    ref = _azimuth_ref(ref, wd, it_term, it_blk, gamma, direction, ang)
    first = np.searchsorted(it_term, np.arange(t_pair.size + 1))  # each term's interactions
    value = np.zeros(t_pair.size)
    lo = 0
    while lo < t_pair.size:  # chunks of one level's terms: interactions × samples bounded
        nr = int(levels[lv[lo]])
        na = 2 * nr
        end = int(np.searchsorted(lv, lv[lo], side="right"))
        hi = int(np.searchsorted(first, first[lo] + BUDGET // (nr * na), side="right")) - 1
        hi = min(max(hi, lo + 1), end)
        value[lo:hi] = _terms(
            slice(lo, hi),
            slice(first[lo], first[hi]),
            it_term,
            it_blk,
            rank,
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
    rank,
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
    ring, arc = _cell_sides(ad, nr, na)
    off_len = np.sqrt(np.einsum("pni,pni->pn", off, off))
    d_lens = (wd - w)[:, None, :] + off
    h = _ramp_along(off, off_len, d_lens, ring, arc)
    in_lens = np.where(
        own[:, None], coverage(np.einsum("pni,pni->pn", d_lens, d_lens), alpha, h), 1.0
    )
    lt = it_term[its] - ts.start  # each interaction's term, local
    blk, rk = it_blk[its], rank[its]
    me = rk == 0
    diff = (wd[lt] - direction[blk])[:, None, :] + off[lt]
    chord2 = np.einsum("pni,pni->pn", diff, diff)
    h = _ramp_along(off[lt], off_len[lt], diff, ring[lt], arc[lt])
    share, cover = passed_share(
        chord2, np.maximum(ang[blk], 1e-300), glass[blk], ior[blk], kt[blk], h
    )
    cover = np.where((me & own[lt])[:, None], 1.0, cover)  # its own grid lies inside it
    # term k = in_k (1 − share_k ∏_{j after k} passed_j) ∏_{j before k} (1 − in_j): linear
    # in each blocker's coverage, so each ramp's error stays second order in the cell
    # (dividing by the number of holders was not linear: first order at the rims)
    before = (rk < 0)[:, None]
    passed = np.where(me[:, None], share, 1.0 - cover * (1.0 - share))
    starts = np.flatnonzero(np.r_[True, lt[1:] != lt[:-1]])
    outside = np.multiply.reduceat(np.where(before, 1.0 - cover, 1.0), starts, axis=0)
    through = np.multiply.reduceat(np.where(before, 1.0, passed), starts, axis=0)
    in_k = cover[me]  # one self interaction per term, in term order
    term = in_lens * in_k * outside * (1.0 - through)
    ratio = (np.sin(0.5 * ad) / np.sin(0.5 * alpha)) ** 2
    return ratio * term.mean(axis=1)


def _off_axis(ref, alt, axis):
    """``ref``, or ``alt`` where ``ref`` lies along the unit ``axis`` (within 1e-9)."""
    perp = ref - np.einsum("pi,pi->p", ref, axis)[:, None] * axis
    on = np.linalg.norm(perp, axis=1) <= 1e-9
    return np.where(on[:, None], alt, ref)


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
        h = intersect_sphere(o, d, centers[b], radii[b])
        b2, r = h.perp2, radii[b]  # impact parameter²
        hit = (b2 < r * r) & (h.far > 0.0) & (h.near < t_end)
        if glass[b]:
            n_b, kt_b = (float(np.asarray(x, dtype=float).reshape(-1)[b]) for x in (ior, kt))
            share = glass_share(np.sqrt(b2) / r, n_b, kt_b)
        else:
            share = 0.0
        out = np.where(hit, out * share, out)
    return out


#: Rings of the cap grids over one overlap of two blockers (× 2·rings azimuths): the
#: fewest of these ≥ `_FULL_RINGS` × the grid's radius against the lens' (a grid spans
#: that overlap only, so its edge error, ∝ (ρ / α)² / rings², is a share of it).
PAIR_RINGS = (6, 8, 12, 16, 24, 32, 48, 64)
#: Rings (and `_FULL_BOX`: box cells along) for a grid as wide as the lens' cap. On the
#: 16 × 10 000 droplets' 1 772 rows overlapping in pairs, against this code at 192
#: rings and cells: at most 5.7e-4, 99 % within 2.8e-4 (the former: 9.6e-4, 5.7e-4).
_FULL_RINGS = 24
#: Blockers per row beyond which the row's overlaps are not told apart (sampled whole).
_MAX_ROW = 16
#: Samples × pairs per block of the pairs' grids (memory stays bounded).
_PAIR_BLOCK = 200_000


def _pair_only_overlaps(rows, obst, count, hard, direction, ang):
    """The overlapping blocker pairs (p, q) (indices into rows/obst) of the rows of
    ``hard`` where no three blockers' caps overlap one another (no direction lies behind
    three: the union is the sum less each pair's overlap), and those rows (a mask)."""
    n_rows = count.size
    sel = np.flatnonzero(hard[rows] & (count[rows] <= _MAX_ROW))
    ok = np.zeros(n_rows, dtype=bool)
    empty = np.zeros(0, dtype=np.int64)
    if sel.size == 0:
        return ok, empty, empty
    starts = np.concatenate([[0], np.cumsum(count)])
    after = starts[rows[sel] + 1] - sel - 1  # each blocker with every one after it
    q = concat_ranges(sel + 1, after)
    p = np.repeat(sel, after)
    over = _caps_overlap(obst[p], obst[q], direction, ang)
    p, q = p[over], q[over]
    local = np.arange(rows.size) - starts[rows]  # place in its row (< _MAX_ROW)
    adj = np.zeros(rows.size, dtype=np.int64)  # per blocker: bit set of its overlaps
    np.bitwise_or.at(adj, p, np.left_shift(1, local[q]))
    np.bitwise_or.at(adj, q, np.left_shift(1, local[p]))
    ok[rows[sel]] = True
    ok[rows[p[(adj[p] & adj[q]) != 0]]] = False  # a triangle: three may overlap
    keep = ok[rows[p]]
    return ok & hard, p[keep], q[keep]


def _hav(x):
    return np.sin(0.5 * x) ** 2


def _pair_overlap_blocked(p, q, rows, obst, lens_rows, direction, ang, glass, ior, kt):
    """Per overlapping pair (p, q): ∫ over blocker p's cap ∩ blocker q's cap ∩ the
    lens' cap of (1 − passed_p)(1 − passed_q), over the lens' solid angle (what the
    plain sum counts twice). A lens-shaped overlap is sampled on a box around it in
    the gnomonic plane at its axis' middle (a thin sliver is as many cells across as a
    round overlap); the smaller blocker if nested, or the lens' cap if smaller, on its
    cap's grid (`cap_offsets`)."""
    bi, bj = obst[p], obst[q]
    swap = ang[bj] > ang[bi]  # i the wider
    bi, bj = np.where(swap, bj, bi), np.where(swap, bi, bj)
    lens = lens_rows[rows[p]]
    ci, cj, w = direction[bi], direction[bj], direction[lens]
    a, b, alpha = ang[bi], ang[bj], ang[lens]
    d_ij = cj - ci
    g = _angle(ci, cj)
    nested = g + b <= a
    # the lens-shaped overlap: axis from ci toward cj, points t ∈ [g − b, a] on it,
    # the rims crossing at φ off the axis (haversine law: no cancellation when small)
    sa, sg = np.sin(a), np.where(g > 0.0, np.sin(g), 1.0)
    hav_phi = np.clip((_hav(b) - _hav(a - g)) / np.maximum(sa * sg, 1e-300), 0.0, 1.0)
    t_c = 0.5 * (a + g - b)
    half_u = np.maximum(0.5 * (a - g + b), 0.0)  # the overlap's half-length on the axis
    hav_d = _hav(a - t_c) + sa * np.sin(t_c) * hav_phi
    hav_d = np.clip(hav_d, 0.0, 1.0)
    reach = np.maximum(half_u, 2.0 * np.arctan2(np.sqrt(hav_d), np.sqrt(1.0 - hav_d)))
    e = (d_ij + 2.0 * _hav(g)[:, None] * ci) / sg[:, None]  # unit, ⟂ ci, toward cj
    m_off = -2.0 * _hav(t_c)[:, None] * ci + np.sin(t_c)[:, None] * e  # centre − ci
    # gnomonic box: caps map to ellipses symmetric about the axis, so the overlap lies
    # within tan(half_u) along it and tan(reach) across (a cell's margin for the ramps)
    box_u, box_v = np.tan(np.minimum(half_u, 1.2)), np.tan(np.minimum(reach, 1.2))
    small = nested | (4.0 * box_u * box_v >= 4.0 * np.pi * _hav(alpha))
    on_lens = small & (alpha <= np.where(nested, b, np.inf))
    out = np.zeros(p.size)
    boxed = np.flatnonzero(~small)
    # cells along × across by the box's size against the lens' cap (error ∝ its area)
    scale = np.sqrt(box_u * box_v / (np.pi * _hav(alpha)))
    levels = np.asarray(BOX_LEVELS)
    lv = np.minimum(np.searchsorted(levels, scale[boxed] * _FULL_BOX), levels.size - 1)
    for j, nu in enumerate(BOX_LEVELS):
        idx = boxed[lv == j]
        step = max(1, _PAIR_BLOCK // (nu * nu * 4 // 3))
        for s in range(0, idx.size, step):
            k = idx[s : s + step]
            e1 = -np.sin(t_c[k])[:, None] * ci[k] + np.cos(t_c[k])[:, None] * e[k]
            e2 = np.cross(ci[k], e[k])
            m = ci[k] + m_off[k]
            out[k] = _box_block(
                m,
                m_off[k],
                e1,
                e2,
                box_u[k],
                box_v[k],
                bi[k],
                bj[k],
                d_ij[k],
                ci[k] - w[k],
                alpha[k],
                ang,
                glass,
                ior,
                kt,
                nu,
                nu * 4 // 3,
            )
    round_ = np.flatnonzero(small)
    if round_.size:
        # the lens' cap, or the smaller blocker (nested: its own rim is the grid's)
        rho = np.where(on_lens, alpha, b)[round_]
        m_off_r = np.where(on_lens[:, None], w - ci, d_ij)[round_]
        ref = np.where(on_lens[:, None], 0.5 * (ci + cj) - w, w - cj)[round_]
        # a reference centred on the grid sets no azimuth (cap_offsets would fall back on
        # the world's axes, which turn with the scene): toward a cap that is not centred
        axis = np.where(on_lens[:, None], w, cj)[round_]
        for alt in (np.where(on_lens[:, None], ci - w, ci - cj), cj - w):
            ref = _off_axis(ref, alt[round_], axis)
        own_j = (nested & ~on_lens)[round_]
        size = np.sin(0.5 * rho) / np.sin(0.5 * alpha[round_])  # against the lens' cap
        r = round_
        geo = (bi[r], bj[r], ci[r], w[r], d_ij[r], m_off_r, ref, rho, alpha[r], own_j)
        geo += (on_lens[r], size)
        levels = np.asarray(PAIR_RINGS)
        nr_of = levels[np.minimum(np.searchsorted(levels, _FULL_RINGS * size), levels.size - 1)]
        for nr in PAIR_RINGS:
            idx = np.flatnonzero(nr_of == nr)
            step = max(1, _PAIR_BLOCK // (2 * nr * nr))
            for s in range(0, idx.size, step):
                k = idx[s : s + step]
                out[round_[k]] = _pair_block(tuple(x[k] for x in geo), ang, glass, ior, kt, nr)
    return out


#: Cells along the axis of the box over a lens-shaped overlap (4/3 as many across), the
#: fewest for which ``_FULL_BOX`` × the box's size against the lens' cap.
BOX_LEVELS = (6, 9, 12, 18, 24, 36, 48)
_FULL_BOX = 16


def _box_block(
    m, m_off, e1, e2, box_u, box_v, bi, bj, d_ij, ci_w, alpha, ang, glass, ior, kt, n_u, n_v
):
    """The pair term on a midpoint grid over the gnomonic box (±box_u along e1, ±box_v
    along e2 about m), each sample weighted by its solid angle du dv / (1 + r²)^{3/2}."""
    # a cell more on every side: the edges' ramps reach half a cell beyond the overlap
    box_u, box_v = box_u * (1.0 + 2.0 / (n_u - 2)), box_v * (1.0 + 2.0 / (n_v - 2))
    fu = (np.arange(n_u) + 0.5) / n_u * 2.0 - 1.0
    fv = (np.arange(n_v) + 0.5) / n_v * 2.0 - 1.0
    u = (box_u[:, None] * fu)[:, :, None]  # (P, U, 1)
    v = (box_v[:, None] * fv)[:, None, :]  # (P, 1, V)
    r2 = (u * u + v * v).reshape(m.shape[0], -1)
    root = np.sqrt(1.0 + r2)
    k = 1.0 / root
    km1 = -r2 / (root * (1.0 + root))  # k − 1, no cancellation
    plane = u[..., None] * e1[:, None, None, :] + v[..., None] * e2[:, None, None, :]
    off = km1[..., None] * m[:, None, :] + k[..., None] * plane.reshape(m.shape[0], -1, 3)
    du, dv = 2.0 * box_u / n_u, 2.0 * box_v / n_v
    h = np.sqrt(du * dv)[:, None] * k * k  # a cell's angular size (the projection shrinks)
    value = k**3
    parts = [
        _passes_not(to_c, off, ang[blk], glass[blk], ior[blk], kt[blk], h, None)
        for blk, to_c in ((bi, m_off), (bj, m_off - d_ij))
    ]
    value = value * parts[0][0] * parts[0][1] * parts[1][0] * parts[1][1]
    d = (m_off + ci_w)[:, None, :] + off
    value *= coverage(np.einsum("pni,pni->pn", d, d), alpha, h)
    return value.sum(axis=1) * du * dv / (4.0 * np.pi * _hav(alpha))


def _pair_block(geo, ang, glass, ior, kt, nr):
    """The pair term on a cap's grid (`cap_offsets`, nr rings)."""
    bi, bj, ci, w, d_ij, m_off, ref, rho, alpha, own_j, on_lens, size = geo
    na = 2 * nr
    m = ci + m_off
    m /= np.linalg.norm(m, axis=1)[:, None]
    off = cap_offsets(m, rho, ref, nr, na)
    ring, arc = _cell_sides(rho, nr, na)
    off_len = np.sqrt(np.einsum("pni,pni->pn", off, off))
    parts = []
    for blk, to_c, mine in ((bi, m_off, None), (bj, m_off - d_ij, own_j)):
        h = _ramp_along(off, off_len, to_c[:, None, :] + off, ring, arc)
        parts.append(_passes_not(to_c, off, ang[blk], glass[blk], ior[blk], kt[blk], h, mine))
    value = _meet(*parts)
    d = (m_off + ci - w)[:, None, :] + off
    h = _ramp_along(off, off_len, d, ring, arc)
    in_lens = coverage(np.einsum("pni,pni->pn", d, d), alpha, h)
    value *= np.where(on_lens[:, None], 1.0, in_lens)
    return size * size * value.mean(axis=1)


def _meet(first, second):
    """∫ over a cell of (1 − passed_i)(1 − passed_j) from `_passes_not`'s parts: the
    share of the cell inside both caps, from each one's (ramps r_i, r_j) and the angle
    of their rims' outward normals (cos ψ): r_i r_j where the rims cross at a right
    angle, max(0, r_i + r_j − 1) where they face each other (a sliver thinner than the
    cell: the product of the two ramps counts a sliver of no width h/6 deep), min(r_i,
    r_j) where they run alike, linear in cos ψ between; equal where a ramp is 0 or 1."""
    (ri, wi, ti), (rj, wj, tj) = first, second
    dot = np.einsum("pni,pni->pn", ti, tj)
    cos = dot / np.maximum(
        np.sqrt(np.einsum("pni,pni->pn", ti, ti) * np.einsum("pni,pni->pn", tj, tj)), 1e-300
    )
    prod = ri * rj
    bound = np.where(cos < 0.0, np.maximum(ri + rj - 1.0, 0.0), np.minimum(ri, rj))
    return (prod + np.abs(cos) * (bound - prod)) * wi * wj


def _passes_not(to_c, off, beta, glass, ior, kt, h, mine):
    """How much of each sample's cell a blocker's cap covers, 1 − what it passes there
    (1 if opaque) and the direction from its centre to the sample (its rim's outward
    normal there), at the grid's samples ``off`` from a centre ``to_c`` away from the
    blocker's."""
    d = to_c[:, None, :] + off
    chord2 = np.einsum("pni,pni->pn", d, d)
    half = 0.5 * np.sqrt(np.minimum(chord2, 4.0))
    cos_half = np.sqrt(np.maximum(1.0 - half * half, 0.0))
    cov = _rim_ramp(2.0 * half, cos_half, beta, h)
    if mine is not None:
        cov[mine] = 1.0
    stop = np.ones(cov.shape)
    g = np.flatnonzero(glass)
    if g.size:
        sb = np.sin(np.maximum(beta[g], 1e-300))
        stop[g] = 1.0 - _cell_share(half[g], cos_half[g], sb, h[g], ior[g], kt[g])
    return cov, stop, d
