"""What a source's shadow list lets through: the exact union of the blockers' shadows
over the lens' lit cap, and a glass blocker's Fresnel transmission.

Phase 1 finds the partial blockers of a lens (spheres nearer the light whose angular
disc overlaps the lens'). One opaque blocker is exact in closed form
(`geometry.cap_overlap_fraction`); several overlap, so their shares cannot be multiplied
(a direction behind two blockers would count twice), and a glass blocker passes part of
the light. Here each blocker's meeting with the lens' cap is sampled by a deterministic
grid of directions equal in solid angle over the smaller of the two caps (rings uniform
in 1 − cos θ × azimuths; a direction inside several blockers' caps counts once in all),
and each direction is passed by the product of its blockers' shares: 0 behind an opaque
one (so opaque blockers block the union of their shadows), kt² T(ι) behind a glass one,
where T is the unpolarised two-surface Fresnel transmission at the ray's actual angle of
incidence ι (sin ι = sin θ_k / sin β_k for a direction θ_k from the blocker's centre,
β_k its radial angle). The glass blocker's own focusing (it deflects what it passes: a
tertiary source) is out of scope: what passes is counted as if undeflected.

Each grid's azimuth starts toward the other cap, so the result does not depend on how
the scene is turned or in which order its spheres come.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .exact_optics import fresnel_transmittance

#: Directions per lens cap (rings × 2·rings): at most, and at least for crowded views.
MAX_SAMPLES, MIN_SAMPLES = 192 * 384, 24 * 48
#: Sample × blocker evaluations per call before the grid gets coarser (memory, time).
BUDGET = 4_000_000


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
    ring = (omc / nr)[:, None] / np.sqrt(v * (2.0 - v))  # dθ = dv / sin θ
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
    """What one blocker passes of the directions at chord² ``chord2`` (…, N) from its
    centre direction that go through it (radial angle ``beta``, glass or not, index, kt
    per blocker (…,)), and how much of each sample's cell its cap covers
    (:func:`coverage`)."""
    half = 0.5 * np.sqrt(np.minimum(chord2, 4.0))
    sin_theta = 2.0 * half * np.sqrt(np.maximum(1.0 - half * half, 0.0))  # sin(2 asin(c/2))
    sin_iota = sin_theta / np.sin(beta)[..., None]
    share = np.where(glass[..., None], glass_share(sin_iota, ior[..., None], kt[..., None]), 0.0)
    return share, coverage(chord2, beta, h)


def union_unblocked(
    rows, obst, cover, lens_rows, direction, ang, ior=None, kt=None, n_samples=MAX_SAMPLES
) -> np.ndarray:
    """The unblocked share of every lens row (``len(lens_rows)``), from its partial
    blockers: pairs (``rows``, ``obst``) sorted by row, ``cover`` each pair's closed-form
    cap overlap. A row with one opaque blocker keeps 1 − cover (exact); a row with
    several, or with a glass one (``ior``, ``kt`` per sphere; None: all opaque), gets
    the union (and glass transmission) over its sampled cap."""
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
    any_glass = np.zeros(n_rows, dtype=bool)
    np.logical_or.at(any_glass, rows, glass[obst])
    simple = (count[rows] == 1) & ~any_glass[rows]
    unblocked[rows[simple]] = 1.0 - cover[simple]
    sampled = np.flatnonzero((count > 1) | any_glass)
    if sampled.size == 0:
        return unblocked
    work = int((count[sampled] ** 2).sum())  # each cap's samples meet every blocker
    n = int(np.clip(BUDGET // max(work, 1), MIN_SAMPLES, n_samples))
    nr, na = _rings(n)
    starts = np.concatenate([[0], np.cumsum(count)])
    per_chunk = max(BUDGET // (nr * na * max(int(count[sampled].max()), 1) ** 2), 1)
    for lo in range(0, sampled.size, per_chunk):
        chunk = sampled[lo : lo + per_chunk]
        unblocked[chunk] = _sampled_rows(
            chunk, starts, obst, lens_rows, direction, ang, glass, ior_a, kt_a, nr, na
        )
    return unblocked


def _sampled_rows(chunk, starts, obst, lens_rows, direction, ang, glass, ior, kt, nr, na):
    """Unblocked shares of the rows ``chunk``: 1 − Σ_k ∫ over blocker k's cap ∩ the
    lens' cap of (1 − ∏_j passed_j) / (how many blockers' caps hold the direction),
    over the lens' solid angle; each term on a grid over the smaller of the two caps
    (a small blocker's own disc is covered exactly, a lens inside a big blocker's disc
    is resolved: only the union's edges are sampled)."""
    lens = lens_rows[chunk]
    first, last = starts[chunk], starts[chunk + 1]
    k_max = int((last - first).max())
    # pad every row's blockers to k_max (padding: flagged off by `real`)
    idx = first[:, None] + np.arange(k_max)[None, :]
    real = idx < last[:, None]
    blk = obst[np.where(real, idx, first[:, None])]
    beta = np.where(real, ang[blk], 0.0)
    w = direction[lens]
    alpha = ang[lens]
    blocked = np.zeros(chunk.size)
    for k in range(k_max):
        bk = blk[:, k]
        # sample the smaller of the two caps (blocker k's, the lens'): their meeting
        # is all that counts, and the smaller one's grid resolves it
        own = (beta[:, k] <= alpha)[:, None]
        wd = np.where(own, direction[bk], w)
        ad = np.where(own[:, 0], beta[:, k], alpha)
        off = cap_offsets(
            wd, ad, _azimuth_ref(wd, own, w, direction[bk], blk, real, beta, direction), nr, na
        )  # s − wd
        h = _ramp_width(ad, nr, na)
        d_lens = (wd - w)[:, None, :] + off
        in_lens = np.where(own, coverage(np.einsum("pni,pni->pn", d_lens, d_lens), alpha, h), 1.0)
        passed = np.ones(off.shape[:2])
        holders = np.zeros(off.shape[:2])
        in_k = np.ones(off.shape[:2])
        for j in range(k_max):
            bj = blk[:, j]
            diff = (wd - direction[bj])[:, None, :] + off
            chord2 = np.einsum("pni,pni->pn", diff, diff)
            bj_beta = np.maximum(beta[:, j], 1e-300)
            share, cover = passed_share(chord2, bj_beta, glass[bj], ior[bj], kt[bj], h)
            if j == k:  # its own grid lies wholly inside it
                cover = np.where(own, 1.0, cover)
                in_k = cover
            passed *= np.where(real[:, j, None], 1.0 - cover * (1.0 - share), 1.0)
            holders += np.where(real[:, j, None], cover, 0.0)
        term = in_lens * in_k * (1.0 - passed) / np.maximum(holders, 1e-12)
        ratio = (np.sin(0.5 * ad) / np.sin(0.5 * alpha)) ** 2
        blocked += np.where(real[:, k], ratio * term.mean(axis=1), 0.0)
    return np.clip(1.0 - blocked, 0.0, 1.0)


def _azimuth_ref(wd, own, w, wk, blk, real, beta, direction):
    """Where each grid's azimuth starts: toward the other cap (the lens', or blocker k's);
    if that one is centred on the grid, toward the widest blocker that is not (every
    cap centred: anything will do, the whole is symmetric). Never the world's axes, so
    turning the scene does not move the grid against the caps."""
    ref = np.where(own, w, wk)

    def off_axis(v):
        perp = v - np.einsum("pi,pi->p", v, wd)[:, None] * wd
        return np.linalg.norm(perp, axis=1) > 1e-9

    bad = ~off_axis(ref)
    if not bad.any():
        return ref
    best, score = ref.copy(), np.full(wd.shape[0], -1.0)
    for j in range(blk.shape[1]):
        dj = direction[blk[:, j]]
        better = bad & real[:, j] & off_axis(dj) & (beta[:, j] > score)
        best = np.where(better[:, None], dj, best)
        score = np.where(better, beta[:, j], score)
    return best


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


# --------------------------------------------------------------------------- the mask


@dataclass
class EmissionMask:
    """What share of a lens light's beam its shadow list lets through, over the
    directions the light emits in: ``pixels[j, i]`` at the light's local direction
    components ``x = −s_max + (2i + 1) s_max / size`` (its local X) and ``y`` likewise
    (row j, its local Y); 1 where no ray goes. ``passed``: the share of the beam's
    flux that passes (the tiers' `unblocked_fraction` weighs the cap by solid angle,
    this by the flux through the lens)."""

    pixels: np.ndarray  # (size, size) float32, row 0 = most negative y
    s_max: float
    passed: float

    @property
    def size(self) -> int:
        return int(self.pixels.shape[0])


def _refract(d, nrm, eta):
    cos_i = np.clip(-np.einsum("...i,...i->...", d, nrm), 0.0, 1.0)
    k = np.maximum(1.0 - eta * eta * (1.0 - cos_i) * (1.0 + cos_i), 0.0)
    t = eta * d + (eta * cos_i - np.sqrt(k))[..., None] * nrm
    return t / np.linalg.norm(t, axis=-1)[..., None]


def emission_mask(
    light_position,
    lens_center,
    lens_radius: float,
    ior: float,
    blockers,
    apex,
    ex,
    ey,
    receiver: float | None = None,
    size: int = 128,
    n_radial: int = 384,
    n_azimuth: int = 768,
) -> EmissionMask:
    """The mask of a point light's beam through a lens (centre, radius, index) behind
    ``blockers`` = (centres (B, 3), radii (B,), indices (B,), kt (B,)), for a lens
    light at ``apex`` whose local X and Y axes are ``ex``, ``ey`` (world).

    Exact ray paths: a grid over where the rays enter the lens (ι × φ, as in the
    caustic layer's beam), each weighted by its flux through the lens (solid angle ×
    two-surface Fresnel) and by what the blockers pass of it on its way there
    (:func:`ray_passes`), landed on the plane across the axis ``receiver`` from the
    lens' centre (None: far away, the exit directions), and binned by the direction
    from ``apex`` to where it lands. The mask is exact on that plane (to its texels)
    and a fair guess elsewhere beyond the focus."""
    P = np.asarray(light_position, dtype=float)
    C = np.asarray(lens_center, dtype=float)
    A = np.asarray(apex, dtype=float)
    ex, ey = np.asarray(ex, dtype=float), np.asarray(ey, dtype=float)
    R, n = float(lens_radius), float(ior)
    to_c = C - P
    D = float(np.linalg.norm(to_c))
    if not (D > R and R > 0 and n > 0):
        raise ValueError("the light must lie outside the lens (radius > 0, index > 0)")
    u = to_c / D
    e1 = np.cross(u, [1.0, 0.0, 0.0] if abs(u[0]) < 0.9 else [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(u, e1)
    d_iota = 0.5 * np.pi / n_radial
    iota = (np.arange(n_radial) + 0.5) * d_iota
    phi = 2.0 * np.pi * (np.arange(n_azimuth) + 0.5) / n_azimuth
    sin_i, cos_i = np.sin(iota), np.cos(iota)
    sin_psi = (R / D) * sin_i
    cos_psi = np.sqrt((1.0 - sin_psi) * (1.0 + sin_psi))
    radial = np.cos(phi)[:, None] * e1 + np.sin(phi)[:, None] * e2
    d = cos_psi[:, None, None] * u + sin_psi[:, None, None] * radial[None]  # (I, P, 3)
    t1 = D * cos_psi - R * cos_i  # to the entry point
    p1 = P + t1[:, None, None] * d
    d2 = _refract(d, (p1 - C) / R, 1.0 / n)
    cos_r = np.sqrt(np.maximum(1.0 - (sin_i / n) ** 2, 0.0))
    p2 = p1 + (2.0 * R * cos_r)[:, None, None] * d2
    d3 = _refract(d2, -(p2 - C) / R, n)
    t_s, t_p = fresnel_transmittance(cos_i, 1.0, n)
    flux = sin_i * cos_i / cos_psi * 0.5 * (t_s * t_s + t_p * t_p)
    w = np.broadcast_to(flux[:, None], d.shape[:2])
    centers, radii, b_ior, b_kt = blockers
    passed = ray_passes(P, d, t1[:, None], centers, radii, b_ior, b_kt)
    if receiver is None:
        to = d3
    else:
        plane = C + float(receiver) * u
        along = np.einsum("...i,i->...", d3, u)
        t = np.einsum("...i,i->...", plane - p2, u) / np.where(along > 0, along, 1.0)
        to = p2 + np.maximum(t, 0.0)[..., None] * d3 - A
        w = np.where(along > 0, w, 0.0)
    to = to / np.linalg.norm(to, axis=-1)[..., None]
    x, y = to @ ex, to @ ey
    w = np.where(np.einsum("...i,i->...", to, u) > 0, w, 0.0)
    # the texels span the directions of 99 % of the flux (beyond: the edge texels)
    rho = np.hypot(x, y).ravel()
    order = np.argsort(rho)
    cum = np.cumsum(w.ravel()[order])
    reach = rho[order][min(np.searchsorted(cum, 0.99 * cum[-1]), rho.size - 1)] if cum[-1] else 1
    s_max = float(min(1.05 * reach, 1.0)) or 1.0
    edges = np.linspace(-s_max, s_max, int(size) + 1)
    both = np.histogram2d(y.ravel(), x.ravel(), bins=(edges, edges), weights=(w * passed).ravel())
    total = np.histogram2d(y.ravel(), x.ravel(), bins=(edges, edges), weights=w.ravel())[0]
    pixels = np.where(total > 0, both[0] / np.where(total > 0, total, 1.0), 1.0)
    share = float((w * passed).sum() / w.sum()) if w.sum() > 0 else 1.0
    return EmissionMask(pixels.astype(np.float32), s_max, share)
