"""The Exact profile's table binned straight from the exact ray fan, every row at
once: what live update and Generate read (`exact_profile.cached_profile`).

`exact_profile.exact_profile` builds each row from `beam_error.ExactBeam`'s flux
within a radius (one sort of the 8000-ray fan per row: 0.3 s for the far table,
0.9 s with the near field's 512 rows and its slopes). Here the fan is traced once
(`ball_optics.trace_rays_iota`, a few hundred microseconds) and every row's landing
heights are linear in the plane's distance, so the table is one pass over a
rows × rays array: each piece of the fan between two rays (split where it crosses
the axis) puts its flux (trapezoid in the incidence angle, as `ExactBeam`) on the
rings it spans, spread evenly over its radius range (the partial rings at its ends
by their share, the rings inside it through one cumulative sum), and the near
field's slope channel the same flux times the piece's mean slope. No sorting: about
a hundred times faster than the row-by-row table for the same fan. `fan_tables`
does many tables at once (live update's tables of one frame, Generate's): their
rows in chunks small enough for the CPU's cache, the rows no ray has reached yet
left dark.

Its error against `exact_profile` (the truth at 8000 rays) is the fan's
discretisation: `FAN` rays keep it within 1 % of the flux per receiver row and the
peak within 5 % (`tests/core/tiers/test_profile_fan.py`, a sweep of D/R and n;
`bench live_update` reports it per scene).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..lens import ball_optics as xo

#: Intervals of the ray fan over the incidence angle [0, π/2]: the near field's
#: (planes through the lens's back, where the rays leave it, need the most: 1.8 %
#: of such a row's flux at 600 rays, 0.8 % at 1200) and the far table's (every
#: row behind the lens: within 0.2 % at 600).
FAN = 1200
FAN_FAR = 600
#: Rows per chunk of `fan_tables` (rows × rays temporaries within the cache).
CHUNK_ROWS = 64


def fan_angles(n_fan: int = FAN) -> np.ndarray:
    """The fan's incidence angles: uniform over [0, π/2] (rays crowded toward grazing
    incidence did no better per ray)."""
    return np.linspace(0.0, 0.5 * np.pi, int(n_fan) + 1)


def fan_table(
    D_over_R: float,
    n: float,
    absorption: float,
    apex: float,
    distances: np.ndarray,
    gamma_edges: np.ndarray,
    *,
    n_fan: int = FAN,
    slope: bool = False,
) -> tuple[np.ndarray, np.ndarray | None, float]:
    """``(table, mean_slope, flux)`` of a lens (R = 1, primary intensity 1) for a
    light at `apex` (R from the centre on the axis) and points at `distances` (R,
    along the axis from it) in the angular bins `gamma_edges` (K + 1 radians):
    ``table[j, i]`` the mean intensity (flux on the ring / its solid angle) toward
    bin ``i`` for points at ``distances[j]``; with `slope` also the flux-weighted
    mean ``tan α`` (the rays' angle to the axis, positive outward) per texel, ``tan``
    of the bin's middle where no ray lands; ``flux`` the beam's. One job of
    `fan_tables`."""
    job = (D_over_R, n, absorption, apex, distances)
    return fan_tables([job], gamma_edges, n_fan=n_fan, slope=slope)[0]


def fan_tables(
    jobs,
    gamma_edges: np.ndarray,
    *,
    n_fan: int = FAN,
    slope: bool = False,
) -> list:
    """`fan_table` for many tables at once (one pass over all their rows: what live
    update's tables of one frame cost together is a few large numpy calls, not a
    Python loop per pair). `jobs`: ``(D_over_R, n, absorption, apex, distances)``
    per table, every one traced with `n_fan` rays; returns ``(table, mean_slope,
    flux)`` per job."""
    K = gamma_edges.size - 1
    outs = []
    for job in jobs:
        M = np.asarray(job[4]).size
        outs.append((np.empty((M, K)), np.empty((M, K)) if slope else None, np.arange(M)))
    fluxes = fan_fill(jobs, gamma_edges, outs, n_fan=n_fan)
    return [(t, s, f) for (t, s, _), f in zip(outs, fluxes, strict=True)]


def fan_fill(jobs, gamma_edges: np.ndarray, outs, *, n_fan: int = FAN, fans=None) -> list:
    """`fan_tables` written straight into the callers' tables (no batch table copied
    out): `outs` per job ``(table, mean_slope or None, rows)``, the job's distances
    going to those rows of its arrays (every job with or every one without slopes);
    `fans` per job its `ray_fan` if already traced (with `n_fan` rays). Returns the
    beams' fluxes."""
    iota = fan_angles(n_fan)
    dx = np.diff(iota)  # per piece
    gmax = float(gamma_edges[-1])
    slope = outs[0][1] is not None if outs else False
    if fans is None:
        fans = [ray_fan(*job[:3], n_fan=n_fan) for job in jobs]
    dists = [np.asarray(job[4], dtype=float).reshape(-1) for job in jobs]
    h = np.concatenate(dists)
    Z = np.concatenate([float(job[3]) + d for job, d in zip(jobs, dists, strict=True)])
    sizes = [d.size for d in dists]
    job_of_row = np.repeat(np.arange(len(jobs)), sizes)
    starts = np.cumsum([0] + sizes)
    tan_g = np.tan(np.minimum(gamma_edges, 0.5 * np.pi - 1e-9))
    # per-ray values of every job's fan, read at (row, ray): [job of the row, ray]
    w_all = np.stack([f.w for f in fans])
    seg_all = dx[None, :] * 0.5 * (w_all[:, :-1] + w_all[:, 1:])  # the trapezoid, as `ExactBeam`
    ctx = _Context(fans, w_all, np.stack([f.z_exit for f in fans]), seg_all, dx, tan_g, gmax, slope)
    mid = np.tan(0.5 * (gamma_edges[:-1] + gamma_edges[1:]))
    omega = np.diff(4.0 * np.pi * np.sin(0.5 * gamma_edges) ** 2)
    # the rows no ray has reached yet (planes through the lens nearer than every
    # exit point) stay dark: not computed
    first_exit = np.array([np.min(f.z_exit[f.good], initial=np.inf) for f in fans])
    dark = Z < first_exit[job_of_row]
    for j, (table, mean_slope, rows) in enumerate(outs):
        off = np.flatnonzero(dark[starts[j] : starts[j + 1]])
        if off.size:
            table[rows[off]] = 0.0
            if slope:
                mean_slope[rows[off]] = mid
    lit = np.flatnonzero(~dark)
    # rows in chunks: each chunk's temporaries stay in the CPU's cache (the whole
    # rows × rays arrays at once: twice the time, most of it in fresh pages)
    for start in range(0, lit.size, CHUNK_ROWS):
        rows = lit[start : start + CHUNK_ROWS]
        t, s = _chunk(ctx, h[rows], Z[rows], job_of_row[rows])
        if slope:  # the flux-weighted mean; the bin's middle where no ray lands
            lit_texel = t > 0.0
            s = np.divide(s, t, out=np.broadcast_to(mid, t.shape).copy(), where=lit_texel)
        t /= omega
        # each job's part of the chunk into its own table
        jobs_here = job_of_row[rows]
        cut = np.flatnonzero(np.diff(jobs_here)) + 1
        for a, b in zip(np.r_[0, cut], np.r_[cut, rows.size], strict=True):
            j = int(jobs_here[a])
            table, mean_slope, dest = outs[j]
            at = dest[rows[a:b] - starts[j]]
            table[at] = t[a:b]
            if slope:
                mean_slope[at] = s[a:b]
    return [f.flux for f in fans]


def caustic_end(D_over_R: float, n: float, absorption: float = 0.0, n_fan: int = FAN) -> float:
    """How far (R, from the lens centre along the axis) the beam's rays still cross:
    one another (the caustic) or the axis. Beyond, every ray keeps its side and its
    order, and the table changes smoothly from row to row."""
    return fan_caustic_end(ray_fan(D_over_R, n, absorption, n_fan=n_fan))


def fan_caustic_end(f) -> float:
    """`caustic_end` of a traced `ray_fan` (the coarse table's rows, from the fan its
    rows are binned from: traced once)."""
    both = f.good[:-1] & f.good[1:] & (f.w[:-1] > 0.0) & (f.w[1:] > 0.0)
    boc, tan = f.b_over_c.astype(float), f.tan_exit.astype(float)
    with np.errstate(divide="ignore", invalid="ignore"):
        axis = boc / tan  # where each ray's line meets the axis
        pair = (boc[:-1] - boc[1:]) / (tan[:-1] - tan[1:])  # where neighbours meet
    found = np.concatenate([axis[f.good & (f.w > 0.0)], pair[both]])
    found = found[np.isfinite(found)]
    return float(np.max(found, initial=0.0))


class _Context(NamedTuple):
    """What every chunk of rows reads: the fans, their per-ray weights, exit heights
    and piece fluxes stacked by job, the pieces' widths, the bins' tangents."""

    fans: list
    w_all: np.ndarray
    z_all: np.ndarray
    seg_all: np.ndarray
    dx: np.ndarray
    tan_g: np.ndarray
    gmax: float
    slope: bool


def _chunk(ctx, h, Z, job_of_row):
    """The rows at distances `h` (apex + `h` = `Z`, each of job `job_of_row`) of
    `fan_tables`: the flux per texel (rows × K) and, with slopes, the flux × slope."""
    fans, w_all, z_all, seg_all, dx, tan_g, gmax, slope = ctx
    K = tan_g.size - 1
    N = dx.size
    M = h.size
    change = np.flatnonzero(np.diff(job_of_row)) + 1
    bounds = np.concatenate([[0], change, [M]])
    blocks = [
        (slice(int(i), int(j)), fans[int(job_of_row[i])])
        for i, j in zip(bounds[:-1], bounds[1:], strict=True)
    ]
    f32 = np.float32
    Z32, h32 = Z.astype(f32), h.astype(f32)
    # landing heights (rows × rays, float32: the rings are ~1e-3 wide in u); a ray
    # counts once it has left the sphere; each job's rows from its own fan
    height = np.empty((M, N + 1), dtype=f32)
    valid = np.empty((M, N + 1), dtype=bool)
    for blk, f in blocks:
        height[blk] = f.b_over_c[None, :] - Z32[blk, None] * f.tan_exit[None, :]
        valid[blk] = f.good[None, :] & (Z[blk, None] >= f.z_exit[None, :])
    rho = np.abs(height)
    # each landing's ring: u = √(γ/γ_max), K rings uniform in u
    with np.errstate(invalid="ignore"):
        u = np.sqrt(np.arctan(rho / h32[:, None]) * f32(1.0 / gmax))
    ring = np.minimum(np.where(valid, u * f32(K), 0.0), K - 1).astype(np.int32)
    ok = valid[:, :-1] & valid[:, 1:]
    ha, hb = height[:, :-1], height[:, 1:]
    cross = ok & (ha * hb < 0.0)  # the two rays on either side of the axis
    plain = ok & ~cross
    ia, ib = ring[:, :-1], ring[:, 1:]
    same = plain & (ia == ib)
    row_base = np.arange(M, dtype=np.int64)[:, None] * K
    same_flux = np.empty((M, N))
    ray_slope = np.empty((M, N + 1), dtype=f32) if slope else None
    for blk, f in blocks:
        j = int(job_of_row[blk.start])
        same_flux[blk] = np.where(same[blk], seg_all[j][None, :], 0.0)
        if slope:  # a ray's outward slope: −sign(height) tan θ_exit
            ray_slope[blk] = -np.sign(height[blk]) * f.tan_exit[None, :]
    flat_slope = None if ray_slope is None else ray_slope.ravel()
    # what lands in a texel: (index, flux, slope) parts, one bincount at the end
    idx, val, sls = [], [], []
    # the plain pieces within one ring: all their flux there
    idx.append((row_base + ia).ravel())
    val.append(same_flux.ravel())
    if slope:
        sls.append((0.5 * (ray_slope[:, :-1] + ray_slope[:, 1:])).ravel())
    # the pieces that span rings, spread over them (below); a piece: (row, its two
    # ends' radii and rings, the flux weights there, its flux, slope)
    span = np.flatnonzero(plain & (ia != ib))
    r_s = span // N
    k_s = span - r_s * N
    ray_a = span + r_s  # the piece's first ray in the (rows, rays) arrays
    flat_rho, flat_ring, flat_h = rho.ravel(), ring.ravel(), height.ravel()
    j_s = job_of_row[r_s]
    pieces = [
        (
            r_s,
            flat_rho[ray_a].astype(float),
            flat_rho[ray_a + 1].astype(float),
            flat_ring[ray_a],
            flat_ring[ray_a + 1],
            w_all[j_s, k_s],
            w_all[j_s, k_s + 1],
            seg_all[j_s, k_s],
            None if not slope else 0.5 * (flat_slope[ray_a] + flat_slope[ray_a + 1]),
        )
    ]
    # the pieces that cross the axis: split there (ray a → axis, axis → ray b)
    crossing = np.flatnonzero(cross)
    if crossing.size:
        r_c = crossing // N
        k_c = crossing - r_c * N
        ray_c = crossing + r_c
        ha_c = flat_h[ray_c].astype(float)
        hb_c = flat_h[ray_c + 1].astype(float)
        s0 = ha_c / (ha_c - hb_c)
        j_c = job_of_row[r_c]
        wa, wb = w_all[j_c, k_c], w_all[j_c, k_c + 1]
        wz = wa + s0 * (wb - wa)
        zero = np.zeros(r_c.size)
        for ray, w_end, fl in (
            (ray_c, wa, dx[k_c] * s0 * 0.5 * (wa + wz)),
            (ray_c + 1, wb, dx[k_c] * (1.0 - s0) * 0.5 * (wz + wb)),
        ):
            sl = None if flat_slope is None else flat_slope[ray]
            pieces.append(
                (r_c, zero, flat_rho[ray].astype(float), 0 * ray, flat_ring[ray], wz, w_end, fl, sl)
            )
    # the pieces the plane cuts where their rays leave the sphere (one ray out, the
    # next still inside: planes through the lens, the near field's first rows): the
    # part already out, to where the exit point (linear along the piece) meets the
    # plane (`ExactBeam` drops the whole piece: an error of one piece's flux)
    edge = valid[:, :-1] != valid[:, 1:]
    for blk, f in blocks:
        edge[blk] &= (f.good[:-1] & f.good[1:])[None, :]
    cut = np.flatnonzero(edge)
    if cut.size:
        r_e = cut // N
        k_e = cut - r_e * N
        j_e = job_of_row[r_e]
        base = cut + r_e  # ray a in the (rows, rays) arrays
        out_a = valid.ravel()[base]  # ray a out (else ray b)
        za, zb = z_all[j_e, k_e], z_all[j_e, k_e + 1]
        t = np.clip((Z[r_e] - za) / (zb - za), 0.0, 1.0)  # ray a at 0, b at 1
        t_out = np.where(out_a, t, 1.0 - t)  # the part out, from the ray out
        ray_out = np.where(out_a, base, base + 1)
        ray_in = np.where(out_a, base + 1, base)
        k_out, k_in = np.where(out_a, k_e, k_e + 1), np.where(out_a, k_e + 1, k_e)
        h_out = flat_h[ray_out].astype(float)
        h_mid = h_out + t_out * (flat_h[ray_in].astype(float) - h_out)
        w_out = w_all[j_e, k_out]
        w_mid = w_out + t_out * (w_all[j_e, k_in] - w_out)
        fl = dx[k_e] * t_out * 0.5 * (w_out + w_mid)
        rho_mid = np.abs(h_mid)
        ring_mid = np.minimum(
            (K * np.sqrt(np.arctan(rho_mid / h[r_e]) / gmax)).astype(np.int64), K - 1
        )
        sl = None if flat_slope is None else flat_slope[ray_out]
        pieces.append(
            (r_e, np.abs(h_out), rho_mid, flat_ring[ray_out], ring_mid, w_out, w_mid, fl, sl)
        )
    # the main group alone (no copy into one array with the few others)
    marks, coef_a, coef_c, mark_sl = [], [], [], []
    small = pieces[1:]
    groups = [pieces[0]]
    if small:
        groups.append(
            tuple(
                None if small[0][i] is None else np.concatenate([p[i] for p in small])
                for i in range(9)
            )
        )
    for group in groups:
        _spread(K, h, tan_g, group, idx, val, sls, marks, coef_a, coef_c, mark_sl)
    all_idx = np.concatenate(idx)
    all_val = np.concatenate(val)
    size = M * K
    flux_w = np.bincount(all_idx, all_val, size).reshape(M, K)
    marks = np.concatenate(marks)
    coef_a = np.concatenate(coef_a)
    coef_c = np.concatenate(coef_c)
    dtan = np.diff(tan_g)
    width = h[:, None] * dtan[None, :]
    half_sq = 0.5 * (h * h)[:, None] * np.diff(tan_g * tan_g)[None, :]
    half_sq[:, -1] = 0.0  # the last ring (to 90°) is never inside a piece
    width[:, -1] = 0.0

    def inside(ca, cc):
        run_a = np.cumsum(np.bincount(marks, ca, size).reshape(M, K), axis=1)
        run_c = np.cumsum(np.bincount(marks, cc, size).reshape(M, K), axis=1)
        return run_a * width + run_c * half_sq

    table = flux_w + inside(coef_a, coef_c)
    if not slope:
        return table, None
    S = np.bincount(all_idx, all_val * np.concatenate(sls), size).reshape(M, K)
    sl2 = np.concatenate(mark_sl)
    return table, S + inside(coef_a * sl2, coef_c * sl2)


def _spread(K, h, tan_g, piece, idx, val, sls, marks, coef_a, coef_c, mark_sl):
    """Lay a group of pieces ``(row, radii, rings, flux weights at both ends, flux,
    slope)`` on the texels: onto the lists of (index, flux, slope) and of the inner
    rings' marks (index, coefficients, slope).

    Along a piece the radius and the flux weight are both linear in the incidence
    angle, so its flux per unit radius is linear too (d_lo at its near end, d_hi at
    its far end): the partial rings at its ends take their share of that, the rings
    inside it a running sum of both coefficients (`_chunk`'s ``inside``)."""
    r, rho0, rho1, ring0, ring1, w0, w1, fl, sl = piece
    if sl is not None:
        sl = sl.astype(float)
    near_first = rho0 <= rho1
    lo, hi = np.where(near_first, rho0, rho1), np.where(near_first, rho1, rho0)
    w_lo, w_hi = np.where(near_first, w0, w1), np.where(near_first, w1, w0)
    j0, j1 = np.minimum(ring0, ring1).astype(np.int64), np.maximum(ring0, ring1).astype(np.int64)
    b = r * K
    spread = (j0 != j1) & (fl > 0.0)
    if not spread.all():
        # a piece within one ring (or without flux): all of it there
        one = ~spread
        idx.append(b[one] + j0[one])
        val.append(fl[one])
        if sl is not None:
            sls.append(sl[one])
            sl = sl[spread]
        r, lo, hi, w_lo, w_hi, fl, j0, j1, b = (
            x[spread] for x in (r, lo, hi, w_lo, w_hi, fl, j0, j1, b)
        )
    length = hi - lo
    total_w = w_lo + w_hi
    d_lo = 2.0 * fl * w_lo / (total_w * length)
    slope_d = 2.0 * fl * (w_hi - w_lo) / (total_w * length * length)
    first = _below(h[r] * tan_g[j0 + 1], lo, length, d_lo, slope_d, fl)
    last = fl - _below(h[r] * tan_g[j1], lo, length, d_lo, slope_d, fl)
    idx += [b + j0, b + j1]
    val += [first, last]
    if sl is not None:
        sls += [sl, sl]
        mark_sl += [sl, sl]
    # inside: flux per unit radius a + c ρ with a = d_lo − c lo, c = slope_d, from
    # ring j0 + 1 up to ring j1 (exclusive): marks at both ends, running sums per row
    # (a piece's two marks cancel within its row)
    marks += [b + j0 + 1, b + j1]
    a = d_lo - slope_d * lo
    coef_a += [a, -a]
    coef_c += [slope_d, -slope_d]


class RayFan(NamedTuple):
    """One lens' ray fan, per ray: its flux weight, where it lands (b/c and tan θ_exit
    of its exit line), the height of its exit point, whether it leaves the lens."""

    w: np.ndarray
    b_over_c: np.ndarray  # float32
    tan_exit: np.ndarray  # float32
    z_exit: np.ndarray
    good: np.ndarray
    flux: float


def ray_fan(D_over_R, n, absorption=0.0, *, n_fan: int = FAN) -> RayFan:
    """The fan of `n_fan` rays (`fan_angles`): its per-ray arrays (flux weight, b/c,
    tan θ_exit, exit height, good) and the beam's flux."""
    iota = fan_angles(n_fan)
    dx = np.diff(iota)
    fan = xo.trace_rays_iota(iota, float(D_over_R), 1.0, float(n), float(absorption))
    k = 1.0 / float(D_over_R)
    w = fan.transmission * 2.0 * np.pi * k * k * np.sin(iota) * np.cos(iota) / np.cos(fan.psi)
    flux = float(np.sum(0.5 * (w[1:] + w[:-1]) * dx))
    c = np.cos(fan.theta_exit)
    with np.errstate(divide="ignore", invalid="ignore"):
        b_over_c = fan.b / c
        tan_exit = fan.sin_theta_exit / c
    z_exit = -np.cos(fan.exit_polar)
    # the axial ray (no flux of its own) bounds the first piece: kept, unlike
    # `ExactBeam`, which drops that piece (at 1200 rays the caustic's first texels)
    good = (c > 0.0) & np.isfinite(b_over_c) & np.isfinite(w)
    f32 = np.float32
    return RayFan(w, b_over_c.astype(f32), tan_exit.astype(f32), z_exit, good, flux)


def thinned(fan: RayFan, n_fan: int) -> RayFan:
    """`ray_fan` of `n_fan` rays from the same lens's `fan` of ``2 n_fan`` (every other
    ray: `fan_angles` gives the same angles bit for bit, and every per-ray value is a
    function of its own angle): the far rows' fan without tracing it again."""
    w = np.ascontiguousarray(fan.w[::2])
    dx = np.diff(fan_angles(n_fan))
    flux = float(np.sum(0.5 * (w[1:] + w[:-1]) * dx))
    b_over_c, tan_exit, z_exit, good = (
        np.ascontiguousarray(x[::2]) for x in (fan.b_over_c, fan.tan_exit, fan.z_exit, fan.good)
    )
    return RayFan(w, b_over_c, tan_exit, z_exit, good, flux)


def _below(e, lo, length, d_lo, slope_d, flux):
    """A piece's flux at radii below `e` (its flux per unit radius d_lo at its near
    end `lo`, growing by slope_d per unit radius over its `length`)."""
    t = np.clip(e - lo, 0.0, length)
    return np.minimum(t * (d_lo + 0.5 * slope_d * t), flux)
