"""The unblocked share's precision (README Limits: a few 1e-4 of the share where
blockers overlap) on hard cases for `shadow_mask`'s samplers: glass blockers whose caps
overlap in thin slivers, three mutually (a row sampled whole; 1.0e-4 off when this was
written) or two (a pair's overlap sampled alone; 7e-7). The aim of 5e-5 everywhere is
not met on the three (README Limits).

The expected share is integrated here, independently of `shadow_mask`: ring by ring
about the lens' axis (Gauss–Legendre in 1 − cos θ, crowded at both ends of each
interval between the rings that touch a rim or pass where two rims cross), each ring
split in φ where it crosses a blocker's rim (the cosine law, by atan2) and each arc
integrated by Gauss–Legendre crowded at both ends (the Fresnel share's √ at grazing),
each direction passed by the product of what the blockers holding it pass (the Fresnel
equations written out below)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from core.phase1.obstruction import find_blockers

N_GLASS, KT = 1.33, 0.95
TARGET = 2e-4


def direction(gamma, azimuth):
    return np.array(
        [
            math.sin(gamma) * math.cos(azimuth),
            math.sin(gamma) * math.sin(azimuth),
            math.cos(gamma),
        ]
    )


def share(alpha, blockers):
    """find_blockers' unblocked share of a lens seen under α on +z behind glass blockers
    (β, γ, azimuth)."""
    dirs = [direction(0.0, 0.0)] + [direction(g, az) for _, g, az in blockers]
    ang = np.array([alpha] + [b[0] for b in blockers])
    n = len(dirs)
    tlen = np.array([10.0] + [4.0] * (n - 1)) * np.cos(ang)
    ior = np.full(n, N_GLASS)
    kt = np.array([0.0] + [KT] * (n - 1))
    blk = find_blockers(np.array([0]), np.array(dirs), ang, tlen, np.ones(n, bool), ior, kt)
    assert blk.total_blocker[0] == -1
    assert sorted(blk.shadow_spheres) == list(range(1, n))
    return float(blk.unblocked_fraction[0])


def passed_by(blockers, s):
    """What the blockers pass of unit directions s (…, 3): kt² (t_s² + t_p²)/2 at the
    ray's incidence (sin ι = sin θ_k / sin β_k) behind each blocker holding it."""
    out = np.ones(s.shape[:-1])
    for beta, gamma, az in blockers:
        c = direction(gamma, az)
        off = np.arctan2(np.linalg.norm(np.cross(s, c), axis=-1), s @ c)
        sin_i = np.minimum(np.sin(off) / math.sin(beta), 1.0)
        cos_i = np.sqrt(np.maximum(0.0, 1.0 - sin_i * sin_i))
        cos_t = np.sqrt(np.maximum(0.0, 1.0 - (sin_i / N_GLASS) ** 2))
        ts = 1.0 - ((cos_i - N_GLASS * cos_t) / (cos_i + N_GLASS * cos_t)) ** 2
        tp = 1.0 - ((cos_t - N_GLASS * cos_i) / (cos_t + N_GLASS * cos_i)) ** 2
        out = np.where(off < beta, out * KT * KT * 0.5 * (ts * ts + tp * tp), out)
    return out


def rims_meet(bi, bj):
    """The unit directions where the rims of caps bi and bj (β, γ, azimuth) cross."""
    ci, cj = direction(*bi[1:]), direction(*bj[1:])
    d = ci @ cj
    # p = x ci + y cj + z (ci × cj) with p·ci = cos βi, p·cj = cos βj, |p| = 1
    x = (math.cos(bi[0]) - d * math.cos(bj[0])) / (1.0 - d * d)
    y = (math.cos(bj[0]) - d * math.cos(bi[0])) / (1.0 - d * d)
    base = x * ci + y * cj
    n = np.cross(ci, cj)
    z2 = (1.0 - base @ base) / (n @ n)
    return [] if z2 < 0.0 else [base + math.sqrt(z2) * n, base - math.sqrt(z2) * n]


def integrated(alpha, blockers, nodes=48):
    """Unblocked share: rings in v = 1 − cos θ, each ring's arcs between the blockers'
    rims by Gauss in φ crowded at both ends; the rings by Gauss crowded at both ends of
    each interval between the θ where a ring touches a rim or passes where two rims
    cross (the ring integrand is smooth between them, √-like at them)."""
    x, w = np.polynomial.legendre.leggauss(nodes)
    t = 0.5 * (1.0 + x)  # Gauss on [0, 1], crowded at both ends: (1 − cos πt)/2
    u, du = 0.5 * (1.0 - np.cos(math.pi * t)), 0.25 * math.pi * np.sin(math.pi * t) * w
    breaks = [0.0, alpha]
    for k, (beta, gamma, _) in enumerate(blockers):
        breaks += [abs(gamma - beta), gamma + beta]
        for other in blockers[k + 1 :]:
            breaks += [
                math.atan2(math.hypot(p[0], p[1]), p[2]) for p in rims_meet(blockers[k], other)
            ]
    breaks = np.unique([2.0 * math.sin(0.5 * b) ** 2 for b in breaks if 0.0 <= b <= alpha])
    total = 0.0
    for a, b in zip(breaks[:-1], breaks[1:], strict=True):
        for v, wv in zip(a + (b - a) * u, (b - a) * du, strict=True):
            sin_t = math.sqrt(v * (2.0 - v))
            cuts = [0.0, 2.0 * math.pi]
            for beta, gamma, az in blockers:
                # cos of the rim's half-arc on this ring: (cos β − cos θ cos γ)/(sin θ sin γ)
                c = (math.cos(beta) - (1.0 - v) * math.cos(gamma)) / (sin_t * math.sin(gamma))
                if -1.0 < c < 1.0:
                    half = math.atan2(math.sqrt(1.0 - c * c), c)
                    cuts += [(az - half) % (2.0 * math.pi), (az + half) % (2.0 * math.pi)]
            cuts = np.sort(cuts)
            lo, hi = cuts[:-1], cuts[1:]
            phi = lo[:, None] + (hi - lo)[:, None] * u
            wphi = (hi - lo)[:, None] * du
            s = np.stack(
                [sin_t * np.cos(phi), sin_t * np.sin(phi), np.full(phi.shape, 1.0 - v)], axis=-1
            )
            total += wv * float((passed_by(blockers, s) * wphi).sum())
    return total / (2.0 * math.pi * breaks[-1])


# Three glass blockers, each pair overlapping (the first two in a sliver 2e-3 wide, the
# first across the lens' rim), all three over one patch: a row sampled whole.
THREE = [(0.04, 0.075, 0.0), (0.035, 0.05, 1.18935), (0.03, 0.02, 0.6)]
# Two glass blockers overlapping in a sliver 1e-3 wide, one across the rim: a pair's
# overlap sampled alone.
TWO = [(0.045, 0.06, 0.0), (0.04, 0.04, 1.96818)]


def gap(blockers, i, j):
    """How far the caps i and j overlap (β_i + β_j − their centres' angle)."""
    ci, cj = direction(*blockers[i][1:]), direction(*blockers[j][1:])
    g = math.atan2(np.linalg.norm(np.cross(ci, cj)), ci @ cj)
    return blockers[i][0] + blockers[j][0] - g


def test_the_crafted_cases_are_as_described():
    over = sorted(gap(THREE, i, j) for i, j in ((0, 1), (0, 2), (1, 2)))
    assert 1.9e-3 < over[0] < 2.1e-3 and over[1] > 5e-3
    assert 0.9e-3 < gap(TWO, 0, 1) < 1.1e-3


@pytest.mark.parametrize("blockers", [THREE, TWO], ids=["three", "two"])
def test_overlapping_glass_blockers_meet_the_error_target(blockers):
    alpha = 0.1
    expected = integrated(alpha, blockers)
    # the integration itself: two thirds of the nodes, within a tenth of the target
    assert integrated(alpha, blockers, nodes=32) == pytest.approx(expected, abs=0.1 * TARGET)
    assert 0.85 < expected < 0.97  # glass: a real share of the lens blocked
    assert share(alpha, blockers) == pytest.approx(expected, abs=TARGET)
