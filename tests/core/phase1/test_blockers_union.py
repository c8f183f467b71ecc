"""The unblocked share of a lens behind several blockers (core/phase1/shadow_mask.py through
core/phase1/obstruction.find_blockers): the union of their shadows, not the product of their
shares, and a glass blocker's Fresnel transmission.

Expected values by hand: cap solid angles 4π sin²(a/2), inclusion–exclusion with the
closed-form overlap of two caps (`geometry.cap_overlap_fraction`, itself pinned against
quadrature in test_phase1), the Fresnel equations written out below and a 1-D
quadrature over a glass blocker's disc."""

from __future__ import annotations

import math

import numpy as np
import pytest

from core.lens.sphere_caps import cap_overlap_fraction
from core.phase1.obstruction import find_blockers
from core.phase1.point_lights import compute_phase1
from core.phase1.shadow_mask import ray_passes
from core.scene.model import Light, Scene, Sphere, Surface

N_GLASS = 1.5


def cap(a):
    return 4.0 * math.pi * math.sin(0.5 * a) ** 2


def fresnel_two_surfaces(sin_i, n=N_GLASS):
    """Unpolarised two-surface transmittance by the Fresnel equations."""
    cos_i = math.sqrt(max(0.0, 1.0 - sin_i * sin_i))
    cos_t = math.sqrt(max(0.0, 1.0 - (sin_i / n) ** 2))
    ts = 1.0 - ((cos_i - n * cos_t) / (cos_i + n * cos_t)) ** 2
    tp = 1.0 - ((cos_t - n * cos_i) / (cos_t + n * cos_i)) ** 2
    return 0.5 * (ts * ts + tp * tp)


def glass_cap_mean(beta, steps=4000):
    """Mean over a glass blocker's cap of what it passes (sin ι = sin θ / sin β)."""
    t = (np.arange(steps) + 0.5) * beta / steps
    T = np.array([fresnel_two_surfaces(math.sin(x) / math.sin(beta)) for x in t])
    return float((T * np.sin(t)).sum() / np.sin(t).sum())


def direction(gamma, azimuth):
    """Unit vector γ off the +z axis (the lens' direction) at `azimuth`."""
    return np.array(
        [
            math.sin(gamma) * math.cos(azimuth),
            math.sin(gamma) * math.sin(azimuth),
            math.cos(gamma),
        ]
    )


def share(alpha, blockers, glass=None, kt=1.0):
    """find_blockers' unblocked share of a lens seen under α on +z (10 away) behind
    blockers (β, γ, azimuth) 4 away from the light."""
    dirs = [direction(0.0, 0.0)] + [direction(g, az) for _, g, az in blockers]
    ang = np.array([alpha] + [b for b, _, _ in blockers])
    dist = np.array([10.0] + [4.0] * len(blockers))
    tlen = dist * np.cos(ang)
    n = len(dirs)
    ior = np.full(n, N_GLASS)
    kts = np.array([1.0] + [kt if (glass and glass[k]) else 0.0 for k in range(n - 1)])
    blk = find_blockers(np.array([0]), np.array(dirs), ang, tlen, np.ones(n, bool), ior, kts)
    assert blk.total_blocker[0] == -1
    assert list(blk.shadow_spheres) == list(range(1, n))
    return float(blk.unblocked_fraction[0])


def test_half_the_lens_blocked_by_a_big_disc_and_one_inside_it():
    """A wide disc whose rim runs through the lens' centre covers about half of it;
    a small disc inside that shadow adds nothing (union), the product counts it."""
    alpha = 0.05
    big, small = 0.5, 0.01
    got = share(alpha, [(big, big, 0.0), (small, 0.02, 0.0)])
    cover = float(cap_overlap_fraction(alpha, big, big))
    assert 0.45 < cover < 0.55
    assert got == pytest.approx(1.0 - cover, abs=5e-4)
    product = (1.0 - cover) * (1.0 - cap(small) / cap(alpha))
    assert got - product > 0.01


def test_a_centred_blocker_with_a_smaller_one_in_its_shadow():
    alpha = 0.1
    got = share(alpha, [(0.05, 0.0, 0.0), (0.03, 0.01, 1.0)])
    assert got == pytest.approx(1.0 - cap(0.05) / cap(alpha), abs=2e-4)


@pytest.mark.parametrize("gap", [0.01, 0.03, 0.05])
def test_two_overlapping_blockers_block_their_union(gap):
    """Both inside the lens' disc, γ = gap apart: blocked = cap₁ + cap₂ − overlap."""
    alpha, b1, b2 = 0.1, 0.03, 0.025
    got = share(alpha, [(b1, 0.02, 0.0), (b2, 0.02 + gap, 0.0)])
    overlap = float(cap_overlap_fraction(b1, b2, gap)) * cap(b1)
    union = cap(b1) + cap(b2) - overlap
    assert got == pytest.approx(1.0 - union / cap(alpha), abs=3e-4)
    if overlap > 0:
        product = (1.0 - cap(b1) / cap(alpha)) * (1.0 - cap(b2) / cap(alpha))
        assert abs(got - product) > 1e-3


@pytest.mark.parametrize("kt", [1.0, 0.8])
def test_a_glass_blocker_passes_its_fresnel_share(kt):
    """A glass disc inside the lens' disc blocks its cap × (1 − kt² ⟨T⟩), ⟨T⟩ the
    Fresnel transmission averaged over the disc (at the rays' own incidence)."""
    alpha, beta = 0.1, 0.04
    got = share(alpha, [(beta, 0.03, 0.5)], glass=[True], kt=kt)
    passed = kt * kt * glass_cap_mean(beta)
    assert 0.8 < glass_cap_mean(beta) < (4 * N_GLASS / (N_GLASS + 1) ** 2) ** 2
    assert got == pytest.approx(1.0 - cap(beta) / cap(alpha) * (1.0 - passed), abs=2e-4)
    # the old rule, glass as opaque, blocks the whole cap
    assert got > 1.0 - cap(beta) / cap(alpha) + 0.5 * cap(beta) / cap(alpha)


def test_glass_and_opaque_overlapping():
    """An opaque disc inside a glass one: blocked = opaque cap + the glass ring's
    (1 − T) — the glass' mean over its whole disc minus over the opaque part."""
    alpha, bg, bo = 0.1, 0.04, 0.01
    got = share(alpha, [(bg, 0.0, 0.0), (bo, 0.0, 0.0)], glass=[True, False])
    t = (np.arange(4000) + 0.5) * bg / 4000
    T = np.array([fresnel_two_surfaces(math.sin(x) / math.sin(bg)) for x in t])
    w = np.sin(t) * (bg / 4000) * 2 * math.pi
    blocked = cap(bo) + float(((1.0 - T) * w)[t >= bo].sum())
    assert got == pytest.approx(1.0 - blocked / cap(alpha), abs=3e-4)


def test_rays_through_a_glass_sphere_pass_fresnel_at_their_incidence():
    b = np.array([0.0, 0.3, 0.6, 0.9, 1.2])  # impact parameters, sphere radius 1
    o = np.stack([b, np.zeros(5), np.full(5, -5.0)], axis=1)
    d = np.tile([0.0, 0.0, 1.0], (5, 1))
    got = ray_passes(o, d, 10.0, [(0.0, 0.0, 0.0)], [1.0], [N_GLASS], [1.0])
    want = [fresnel_two_surfaces(x) for x in b[:4]] + [1.0]
    assert got == pytest.approx(want, rel=1e-12)
    assert ray_passes(o, d, 10.0, [(0.0, 0.0, 0.0)], [1.0]).tolist() == [0, 0, 0, 0, 1]
    # a sphere beyond the segment's end does not block it
    assert ray_passes(o, d, 3.0, [(0.0, 0.0, 0.0)], [1.0]).tolist() == [1, 1, 1, 1, 1]


def _scene(spheres, light=(0.0, 0.0, 0.0)):
    objs = [
        Sphere(center=c, radius=r, surface=Surface(transmission=kt, ior=N_GLASS))
        for c, r, kt in spheres
    ]
    return Scene(lights=[Light(position=light)], objects=objs)


def test_phase1_uses_the_union_and_is_unchanged_by_turning_and_reordering():
    lens = ((0.0, 0.0, 10.0), 1.0, 1.0)
    b1 = ((0.1, 0.0, 4.0), 0.12, 0.0)
    b2 = ((0.2, 0.05, 4.5), 0.12, 0.0)
    src = [s for s in compute_phase1(_scene([lens, b1, b2])).sources if s.lens == 0][0]
    assert src.shadow_list == [1, 2]
    # by hand: the caps seen from the light, inclusion–exclusion
    alpha = math.asin(0.1)
    d1, d2 = np.array(b1[0]), np.array(b2[0])
    be1, be2 = math.asin(0.12 / np.linalg.norm(d1)), math.asin(0.12 / np.linalg.norm(d2))
    g12 = math.acos(d1 @ d2 / np.linalg.norm(d1) / np.linalg.norm(d2))
    g1, g2 = (math.acos(d[2] / np.linalg.norm(d)) for d in (d1, d2))
    assert g1 + be1 < alpha and g2 + be2 < alpha  # both inside the lens' disc
    union = cap(be1) + cap(be2) - float(cap_overlap_fraction(be1, be2, g12)) * cap(be1)
    assert src.unblocked_fraction == pytest.approx(1.0 - union / cap(alpha), abs=3e-4)
    # turned about an axis and with the spheres in another order: the same share
    rot = np.array([[0.6, -0.8, 0.0], [0.8, 0.6, 0.0], [0.0, 0.0, 1.0]]) @ np.array(
        [[1.0, 0.0, 0.0], [0.0, 0.8, -0.6], [0.0, 0.6, 0.8]]
    )
    turned = [(tuple(rot @ np.array(c)), r, kt) for c, r, kt in (b2, lens, b1)]
    other = [s for s in compute_phase1(_scene(turned)).sources if s.lens == 1][0]
    assert other.unblocked_fraction == pytest.approx(src.unblocked_fraction, rel=1e-9)


def test_a_glass_blocker_across_the_rim_passes_its_fresnel_share_of_what_it_covers():
    """Blocked = ∫ over the glass cap ∩ the lens' cap of (1 − T), by a brute-force
    midpoint grid over the glass cap in its own polar angles (hand Fresnel)."""
    alpha, beta, gamma = 0.1, 0.05, 0.09
    got = share(alpha, [(beta, gamma, 0.0)], glass=[True])
    n = 1500
    t = (np.arange(n) + 0.5) * beta / n
    p = (np.arange(2 * n) + 0.5) * math.pi / n
    T, P = np.meshgrid(t, p, indexing="ij")
    # direction θ from the blocker's centre (at γ on the x side), azimuth φ about it
    cos_d = np.cos(T) * math.cos(gamma) - np.sin(T) * math.sin(gamma) * np.cos(P)
    in_lens = cos_d >= math.cos(alpha)
    x = np.sin(T) / math.sin(beta)
    c_i = np.sqrt(1 - x * x)
    c_t = np.sqrt(1 - (x / N_GLASS) ** 2)
    ts = 1 - ((c_i - N_GLASS * c_t) / (c_i + N_GLASS * c_t)) ** 2
    tp = 1 - ((c_t - N_GLASS * c_i) / (c_t + N_GLASS * c_i)) ** 2
    trans = 0.5 * (ts * ts + tp * tp)
    d_omega = np.sin(T) * (beta / n) * (math.pi / n)
    blocked = float(((1 - trans) * in_lens * d_omega).sum())
    assert got == pytest.approx(1.0 - blocked / cap(alpha), abs=2e-4)
