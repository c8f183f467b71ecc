"""Irradiance on receiving planes of the light that goes emitter -> one or several
glass solids (:mod:`.shapes`) -> receivers, by Monte-Carlo light tracing with every
branch: Fresnel (unpolarised, per surface) at every crossing, the reflected and the
transmitted branch both followed, total internal reflection, Beer absorption inside
the glass, up to a depth.  Independent of ``core``: only :mod:`.emitters`,
:mod:`.vectors`, :mod:`.scene` and :mod:`.shapes`.

The emitters aim their rays at the bounding sphere of all the glass, so the
emitter's direct light is not traced: only light that touched glass is binned (the
caustic, and with ``outer_reflection`` the light reflected off the glass's outside).
Receivers and blockers are opaque; a receiver takes light on its front only.
Solids must not overlap or touch one another (a ray leaving one enters air).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from .scene import ReceiverPlane
from .vectors import dot

__all__ = ["Glass", "Receiver", "ReceiverResult", "GlassTrace", "trace_glass", "glass_bounds"]

#: tallies per primary ray (flux, W)
TALLIES = (
    "into_glass",
    "landed",
    "escaped",
    "absorbed",
    "blocked",
    "outer_reflection",
    "cut",
    "lost",
)


@dataclass(frozen=True)
class Glass:
    """A glass solid: a shape of :mod:`.shapes`, its index ``ior`` and Beer
    ``absorption`` (1/length)."""

    shape: object
    ior: float = 1.5
    absorption: float = 0.0


@dataclass(frozen=True)
class Receiver:
    """An opaque receiving plane (a table, a wall): ``plane`` (light lands on its
    front), ``grid`` ``(u_edges, v_edges)`` in its coordinates (None: totals only),
    ``extent`` ``(u0, u1, v0, v1)`` its finite rectangle (None: infinite)."""

    plane: ReceiverPlane
    grid: tuple | None = None
    extent: tuple | None = None


@dataclass(frozen=True)
class ReceiverResult:
    """What landed on one receiver: total ``flux`` (W) and its standard error; the
    grid's ``irradiance`` (W/length^2, ``(nu, nv)``) and its standard error."""

    flux: float
    flux_se: float
    u_edges: np.ndarray | None = None
    v_edges: np.ndarray | None = None
    irradiance: np.ndarray | None = None
    irradiance_se: np.ndarray | None = None

    def cell_flux(self):
        return self.irradiance * np.outer(np.diff(self.u_edges), np.diff(self.v_edges))


@dataclass(frozen=True)
class GlassTrace:
    """The trace: ``receivers`` (one :class:`ReceiverResult` each), ``tally`` and
    ``tally_se`` (dicts over :data:`TALLIES`, W: the flux whose first hit is glass;
    landed on any receiver; escaped to infinity; absorbed in the glass; stopped by a
    blocker or a receiver's back; reflected off the outside and dropped; cut at the
    depth budget; lost to numerical trouble), ``n_rays``, ``seconds``, ``segments``
    (ray segments traced)."""

    n_rays: int
    seconds: float
    segments: int
    receivers: list
    tally: dict
    tally_se: dict

    def balance(self):
        """``into_glass`` minus everything it became (0 up to roulette noise)."""
        t = self.tally
        return t["into_glass"] - sum(t[k] for k in TALLIES[1:])


def glass_bounds(glass):
    """A sphere ``(centre, radius)`` holding every solid."""
    spheres = [g.shape.bounding_sphere() for g in glass]
    c = np.mean([s[0] for s in spheres], axis=0)
    r = max(float(np.linalg.norm(s[0] - c)) + s[1] for s in spheres)
    return c, r


def _receiver_t(rec, o, d, t_min):
    """Where each ray crosses the receiver (within its extent), inf elsewhere; and
    whether it meets the front."""
    eu, ev, nrm = rec.plane.axes()
    p0 = np.asarray(rec.plane.origin, float)
    dn = d @ nrm
    with np.errstate(divide="ignore", invalid="ignore"):
        t = ((p0 - o) @ nrm) / dn
    ok = (dn != 0.0) & (t > t_min)
    if rec.extent is not None:
        x = o + np.where(ok, t, 0.0)[:, None] * d - p0
        u, v = x @ eu, x @ ev
        u0, u1, v0, v1 = rec.extent
        ok &= (u >= u0) & (u <= u1) & (v >= v0) & (v <= v1)
    return np.where(ok, t, np.inf), dn < 0.0


def trace_glass(
    emitter,
    glass,
    receivers,
    n_rays,
    seed=0,
    blockers=(),
    max_depth=16,
    outer_reflection=False,
    branching="split",
    rr_weight=0.02,
    chunk=100_000,
) -> GlassTrace:
    """Trace ``n_rays`` primary rays from ``emitter`` (:mod:`.emitters`) through the
    ``glass`` solids (:class:`Glass`, a list) onto the ``receivers``
    (:class:`Receiver`, a list); ``blockers``: opaque shapes.

    ``branching``: ``"split"`` follows both Fresnel branches with their weights
    (a branch whose weight falls below ``rr_weight`` of its primary's flux plays
    Russian roulette: it survives with probability weight / threshold at the
    threshold's weight; ``rr_weight = 0`` keeps everything: exact energy
    balance); ``"roulette"`` picks one branch with the Fresnel probability (as
    mitsuba does).  ``max_depth``: glass crossings (or reflections) per path;
    beyond it the flux is tallied as ``cut``.  ``outer_reflection``: keep the
    light the glass's outside reflects before it has been inside any glass (the
    emitter's mirror image, a reflective caustic: True) or drop it (False, tallied);
    light that has been through glass is followed off every surface either way.
    The result is a deterministic function of ``seed`` (and ``chunk``).
    """
    if branching not in ("split", "roulette"):
        raise ValueError(f"branching must be 'split' or 'roulette', got {branching!r}")
    glass, receivers, blockers = list(glass), list(receivers), list(blockers)
    rng = np.random.default_rng(seed)
    center, radius = glass_bounds(glass)
    eps = 1e-9 * radius
    convex = [not hasattr(g.shape, "triangles") for g in glass]
    grids = []
    for rec in receivers:
        if rec.grid is None:
            grids.append(None)
        else:
            ue, ve = (np.asarray(e, float) for e in rec.grid)
            grids.append(
                (
                    ue,
                    ve,
                    np.zeros((ue.size - 1) * (ve.size - 1)),
                    np.zeros((ue.size - 1) * (ve.size - 1)),
                )
            )
    sums = np.zeros((len(TALLIES), 2))  # sum and sum of squares over primaries
    rec_sums = np.zeros((len(receivers), 2))
    segments = 0
    t0 = time.perf_counter()
    done = 0
    while done < n_rays:
        m = min(chunk, n_rays - done)
        done += m
        rays = emitter.sample(center, radius, m, rng)
        o, d = rays.origin.copy(), rays.direction.copy()
        g0 = rays.flux.astype(float)
        w = g0.copy()
        if np.isinf(rays.t_min):  # a sun: anything upstream of the start blocks it
            back = -d
            for rec in receivers:
                w = np.where(np.isfinite(_receiver_t(rec, o, back, 0.0)[0]), 0.0, w)
            for b in blockers:
                w = np.where(np.isfinite(b.hit(o, back, False, 0.0).t), 0.0, w)
        root = np.arange(m)
        medium = np.full(m, -1)
        depth = np.zeros(m, np.int64)
        touched = np.zeros(m, bool)
        entered = np.zeros(m, bool)  # has been inside glass (its reflections are kept)
        last_solid = np.full(m, -1)
        last_prim = np.full(m, -1)
        tal = np.zeros((len(TALLIES), m))
        rec_tal = np.zeros((len(receivers), m))
        events = [[] for _ in receivers]  # (root, cell, weight) per receiver
        alive = w > 0.0
        o, d, w, g0, root = o[alive], d[alive], w[alive], g0[alive], root[alive]
        medium, depth, touched = medium[alive], depth[alive], touched[alive]
        last_solid, last_prim, entered = last_solid[alive], last_prim[alive], entered[alive]
        while o.shape[0]:
            n = o.shape[0]
            segments += n
            best = np.full(n, np.inf)
            kind = np.zeros(n, np.int64)  # 0 nothing, 1 glass, 2 receiver, 3 blocker
            which = np.full(n, -1)
            nrm = np.zeros((n, 3))
            geo = np.zeros((n, 3))
            prim = np.full(n, -1)
            front = np.zeros(n, bool)
            for k, gl in enumerate(glass):
                sel = (medium == -1) | (medium == k)
                if convex[k]:  # a convex solid is never re-entered by the ray leaving it
                    sel &= ~((medium == -1) & (last_solid == k))
                if not np.any(sel):
                    continue
                idx = np.flatnonzero(sel)
                skip = np.where(last_solid[idx] == k, last_prim[idx], -1)
                h = gl.shape.hit(o[idx], d[idx], medium[idx] == k, eps, skip)
                closer = h.t < best[idx]
                j = idx[closer]
                best[j], kind[j], which[j] = h.t[closer], 1, k
                nrm[j], geo[j], prim[j] = h.normal[closer], h.geo_normal[closer], h.prim[closer]
            for k, rec in enumerate(receivers):
                t, fr = _receiver_t(rec, o, d, eps)
                closer = t < best
                best[closer], kind[closer], which[closer], front[closer] = (
                    t[closer],
                    2,
                    k,
                    fr[closer],
                )
            air = medium == -1
            for k, b in enumerate(blockers):
                idx = np.flatnonzero(air)
                h = b.hit(o[idx], d[idx], False, eps)
                closer = h.t < best[idx]
                j = idx[closer]
                best[j], kind[j], which[j] = h.t[closer], 3, k
            # Beer absorption along the segment inside glass
            inside = medium >= 0
            if np.any(inside):
                mu = np.array([g.absorption for g in glass])[np.maximum(medium, 0)]
                seg = np.where(np.isfinite(best), best, 0.0)
                w_new = np.where(inside, w * np.exp(-mu * seg), w)
                np.add.at(tal[3], root, w - w_new)
                w = w_new
            # nothing ahead
            gone = kind == 0
            esc = gone & ~inside & touched
            np.add.at(tal[2], root[esc], w[esc])  # escaped
            np.add.at(tal[7], root[gone & inside], w[gone & inside])  # no exit found: lost
            # receivers
            hit_rec = kind == 2
            land = hit_rec & touched & front
            np.add.at(tal[4], root[hit_rec & touched & ~front], w[hit_rec & touched & ~front])
            np.add.at(tal[1], root[land], w[land])
            if np.any(land):
                x = o[land] + best[land][:, None] * d[land]
                for k, rec in enumerate(receivers):
                    on = which[land] == k
                    if not np.any(on):
                        continue
                    np.add.at(rec_tal[k], root[land][on], w[land][on])
                    if grids[k] is None:
                        continue
                    ue, ve = grids[k][0], grids[k][1]
                    u, v = rec.plane.to_plane(x[on])
                    iu = np.searchsorted(ue, u, side="right") - 1
                    iv = np.searchsorted(ve, v, side="right") - 1
                    ing = (iu >= 0) & (iu < ue.size - 1) & (iv >= 0) & (iv < ve.size - 1)
                    cell = iu[ing] * (ve.size - 1) + iv[ing]
                    events[k].append((root[land][on][ing], cell, w[land][on][ing]))
            # blockers
            blk = (kind == 3) & touched
            np.add.at(tal[4], root[blk], w[blk])
            # glass interfaces
            gi = np.flatnonzero(kind == 1)
            if gi.size == 0:
                break
            first = ~touched[gi]
            np.add.at(tal[0], root[gi[first]], w[gi[first]])
            k = which[gi]
            ior = np.array([g.ior for g in glass])[k]
            from_in = medium[gi] == k
            n1 = np.where(from_in, ior, 1.0)
            n2 = np.where(from_in, 1.0, ior)
            dd = d[gi]
            nn = nrm[gi]
            nf = np.where((dot(dd, nn) < 0.0)[:, None], nn, -nn)  # facing the ray
            p = o[gi] + best[gi][:, None] * dd
            eta = n1 / n2
            cos_i = np.clip(-dot(dd, nf), 0.0, 1.0)
            kk = 1.0 - eta * eta * (1.0 - cos_i) * (1.0 + cos_i)
            tir = kk < 0.0
            cos_t = np.sqrt(np.where(tir, 0.0, kk))
            t_dir = eta[:, None] * dd + (eta * cos_i - cos_t)[:, None] * nf
            t_dir /= np.linalg.norm(t_dir, axis=1, keepdims=True)
            r_dir = dd + (2.0 * cos_i)[:, None] * nf
            ts, tp = _fresnel(cos_i, cos_t, n1, n2)
            refl = np.where(tir, 1.0, 1.0 - 0.5 * (ts + tp))
            wg = w[gi]
            dep = depth[gi] + 1
            cut = dep > max_depth
            np.add.at(tal[6], root[gi[cut]], wg[cut])
            go = ~cut
            if branching == "split":
                w_t, w_r = wg * (1.0 - refl), wg * refl
                keep_t, keep_r = go & (w_t > 0.0), go & (w_r > 0.0)
            else:
                pick_r = rng.random(gi.size) < refl
                w_t = w_r = wg
                keep_t, keep_r = go & ~pick_r, go & pick_r
            if not outer_reflection:
                outer = keep_r & ~from_in & ~entered[gi]
                np.add.at(tal[5], root[gi[outer]], w_r[outer])
                keep_r &= ~outer
            new_medium_t = np.where(from_in, -1, k)
            parts = []
            for keep, dirs, ww, med, ent in (
                (keep_t, t_dir, w_t, new_medium_t, np.ones(gi.size, bool)),
                (keep_r, r_dir, w_r, medium[gi], entered[gi]),
            ):
                sel = np.flatnonzero(keep)
                parts.append(
                    (
                        p[sel],
                        dirs[sel],
                        ww[sel],
                        g0[gi[sel]],
                        root[gi[sel]],
                        med[sel],
                        dep[sel],
                        k[sel],
                        prim[gi[sel]],
                        ent[sel],
                    )
                )
            o, d, w, g0, root, medium, depth, last_solid, last_prim, entered = (
                np.concatenate(x) for x in zip(*parts, strict=True)
            )
            touched = np.ones(o.shape[0], bool)
            if branching == "split" and rr_weight > 0.0:
                thr = rr_weight * g0
                low = w < thr
                if np.any(low):
                    u = rng.random(o.shape[0])
                    survive = ~low | (u * thr < w)
                    w = np.where(low, thr, w)
                    o, d, w, g0, root = (
                        o[survive],
                        d[survive],
                        w[survive],
                        g0[survive],
                        root[survive],
                    )
                    medium, depth, touched = medium[survive], depth[survive], touched[survive]
                    last_solid, last_prim = last_solid[survive], last_prim[survive]
                    entered = entered[survive]
        # per-primary sums -> means and standard errors
        sums[:, 0] += tal.sum(axis=1)
        sums[:, 1] += (tal * tal).sum(axis=1)
        rec_sums[:, 0] += rec_tal.sum(axis=1)
        rec_sums[:, 1] += (rec_tal * rec_tal).sum(axis=1)
        for k, ev in enumerate(events):
            if grids[k] is None or not ev:
                continue
            r = np.concatenate([e[0] for e in ev])
            c = np.concatenate([e[1] for e in ev])
            ww = np.concatenate([e[2] for e in ev])
            ncell = grids[k][2].size
            keys, inv = np.unique(r * ncell + c, return_inverse=True)
            per = np.bincount(inv, weights=ww)
            cells = keys % ncell
            grids[k][2][:] += np.bincount(cells, weights=per, minlength=ncell)
            grids[k][3][:] += np.bincount(cells, weights=per * per, minlength=ncell)
    seconds = time.perf_counter() - t0

    def mean_se(s, sq):
        mean = s / n_rays
        return mean, np.sqrt(np.maximum(sq / n_rays - mean * mean, 0.0) / n_rays)

    tally, tally_se = {}, {}
    for i, name in enumerate(TALLIES):
        mean, se = mean_se(sums[i, 0], sums[i, 1])
        tally[name], tally_se[name] = float(mean), float(se)
    results = []
    for k in range(len(receivers)):
        f, fse = mean_se(rec_sums[k, 0], rec_sums[k, 1])
        if grids[k] is None:
            results.append(ReceiverResult(float(f), float(fse)))
            continue
        ue, ve, s, sq = grids[k]
        area = np.outer(np.diff(ue), np.diff(ve))
        mean, se = mean_se(s.reshape(area.shape), sq.reshape(area.shape))
        results.append(ReceiverResult(float(f), float(fse), ue, ve, mean / area, se / area))
    return GlassTrace(n_rays, seconds, segments, results, tally, tally_se)


def _fresnel(cos_i, cos_t, n1, n2):
    """Per-ray s and p transmittances (``n1``, ``n2`` arrays; :func:`fresnel_sp` per
    index pair would need a loop)."""
    num = 4.0 * n1 * cos_i * n2 * cos_t
    den_s = (n1 * cos_i + n2 * cos_t) ** 2
    den_p = (n1 * cos_t + n2 * cos_i) ** 2
    t_s = np.where(den_s > 0.0, num / np.where(den_s > 0.0, den_s, 1.0), 0.0)
    t_p = np.where(den_p > 0.0, num / np.where(den_p > 0.0, den_p, 1.0), 0.0)
    return t_s, t_p
