"""Rows whose blockers' caps overlap only in pairs (core/phase1/shadow_mask.py: the plain sum
less each pair's overlap, sampled on a grid over that overlap alone) and rows with three
overlapping (sampled whole), through core/phase1/obstruction.find_blockers.

Expected values by hand: inclusion–exclusion with the closed-form overlap of two caps
(`geometry.cap_overlap_fraction`) for opaque blockers inside the lens' disc, and
otherwise a brute-force midpoint grid over the lens' cap in its own polar angles, each
direction passed by the product of what the blockers it is behind pass (the Fresnel
equations written out below)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from core.lens.sphere_caps import cap_overlap_fraction
from core.phase1.obstruction import find_blockers

N_GLASS, KT = 1.33, 0.95


def cap(a):
    return 4.0 * math.pi * math.sin(0.5 * a) ** 2


def direction(gamma, azimuth):
    return np.array(
        [
            math.sin(gamma) * math.cos(azimuth),
            math.sin(gamma) * math.sin(azimuth),
            math.cos(gamma),
        ]
    )


def share(alpha, blockers):
    """find_blockers' unblocked share of a lens seen under α on +z behind blockers
    (β, γ, azimuth, glass)."""
    dirs = [direction(0.0, 0.0)] + [direction(g, az) for _, g, az, _ in blockers]
    ang = np.array([alpha] + [b[0] for b in blockers])
    n = len(dirs)
    tlen = np.array([10.0] + [4.0] * (n - 1)) * np.cos(ang)
    ior = np.full(n, N_GLASS)
    kt = np.array([0.0] + [KT if b[3] else 0.0 for b in blockers])
    blk = find_blockers(np.array([0]), np.array(dirs), ang, tlen, np.ones(n, bool), ior, kt)
    assert blk.total_blocker[0] == -1
    assert sorted(blk.shadow_spheres) == list(range(1, n))
    return float(blk.unblocked_fraction[0])


def fresnel_two_surfaces(sin_i):
    cos_i = np.sqrt(np.maximum(0.0, 1.0 - sin_i * sin_i))
    cos_t = np.sqrt(np.maximum(0.0, 1.0 - (sin_i / N_GLASS) ** 2))
    ts = 1.0 - ((cos_i - N_GLASS * cos_t) / (cos_i + N_GLASS * cos_t)) ** 2
    tp = 1.0 - ((cos_t - N_GLASS * cos_i) / (cos_t + N_GLASS * cos_i)) ** 2
    return 0.5 * (ts * ts + tp * tp)


def brute_force(alpha, blockers, n=1200):
    """Unblocked share by a midpoint grid in (θ, φ) over the lens' cap."""
    t = (np.arange(n) + 0.5) * alpha / n
    p = (np.arange(2 * n) + 0.5) * math.pi / n
    th, ph = np.meshgrid(t, p, indexing="ij")
    s = np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)], axis=-1)
    passed = np.ones(th.shape)
    for beta, gamma, az, glass in blockers:
        c = direction(gamma, az)
        off = np.arctan2(np.linalg.norm(np.cross(s, c), axis=-1), s @ c)
        sin_i = np.minimum(np.sin(off) / math.sin(beta), 1.0)  # outside: not used
        through = KT * KT * fresnel_two_surfaces(sin_i) if glass else 0.0
        passed = np.where(off < beta, passed * through, passed)
    w = np.sin(th)
    return float((passed * w).sum() / w.sum())


def overlap(b1, b2, gap):
    return float(cap_overlap_fraction(b1, b2, gap)) * cap(b1)


@pytest.mark.parametrize("gap", [0.02, 0.04, 0.052])
def test_two_opaque_discs_in_the_lens_by_inclusion_exclusion(gap):
    """Lens-shaped overlaps from wide to a thin sliver (0.003 across)."""
    alpha, b1, b2 = 0.1, 0.03, 0.025
    got = share(alpha, [(b1, 0.01, 0.0, False), (b2, 0.01 + gap, 0.0, False)])
    union = cap(b1) + cap(b2) - overlap(b1, b2, gap)
    assert got == pytest.approx(1.0 - union / cap(alpha), abs=3e-4)


def test_a_chain_of_three_discs_overlapping_in_pairs_only():
    """1–2 and 2–3 overlap, 1–3 do not: union = Σ caps − both pair overlaps."""
    alpha, b = 0.1, 0.02
    got = share(alpha, [(b, 0.035, math.pi, False), (b, 0.0, 0.0, False), (b, 0.035, 0.0, False)])
    union = 3.0 * cap(b) - 2.0 * overlap(b, b, 0.035)
    assert got == pytest.approx(1.0 - union / cap(alpha), abs=3e-4)


@pytest.mark.parametrize(
    "alpha, blockers",
    [
        # two glass discs overlapping across the lens' rim
        (0.05, [(0.03, 0.055, 0.2, True), (0.025, 0.06, 0.9, True)]),
        # a glass disc nested in an opaque one, the lens' rim through both
        (0.05, [(0.04, 0.06, 0.0, False), (0.015, 0.05, 0.1, True)]),
        # the lens smaller than the two glass discs' overlap
        (0.012, [(0.05, 0.04, 0.0, True), (0.05, 0.045, 2.0, True)]),
        # three glass discs overlapping one another (sampled whole)
        (0.05, [(0.03, 0.01, 0.0, True), (0.03, 0.02, 2.0, True), (0.02, 0.03, 4.0, True)]),
    ],
)
def test_overlapping_glass_and_opaque_discs_against_a_brute_force_grid(alpha, blockers):
    got = share(alpha, blockers)
    want = brute_force(alpha, blockers)
    assert 0.0 < want < 0.999
    assert got == pytest.approx(want, abs=3e-4)
