"""Obstruction (SPEC §3.5) as properties over random geometry (hypothesis).

Every scene is built from angles, so the tests' boundaries are exact up to
rounding: a light L anywhere, the lens at distance D_l along a random direction
w with radius D_l·sin α (the light sees it under the radial angle α), and the
obstacle at distance d along the direction γ away from w (in a random plane)
with radius d·sin β. "Nearer" means a shorter tangent length (d·cos β < D_l·cos α,
the thesis' distance test).

Expected values come from spherical geometry by hand: the blocked share of the
lens's flux is the obstacle's share of the lens's cap of directions (an
isotropic light's flux is uniform in solid angle), and a cap of angular radius
a has the solid angle 2π(1 − cos a) = 4π sin²(a/2).
"""

from __future__ import annotations

import json
import math

import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from plain_vectors import vadd, vcross, vscale, vunit

from core.phase1.point_lights import compute_phase1
from core.scene.model import Light, Scene, Sphere, Surface

EXAMPLES = 120
REL = 1e-9


# ------------------------------------------------------------ geometry by hand


def fresnel_two_surfaces(sin_i, n):
    """Unpolarised transmittance of a glass sphere's direct path at incidence asin(sin_i):
    the Fresnel equations by hand, s and p through both surfaces alike."""
    cos_i = math.sqrt(max(0.0, 1.0 - sin_i * sin_i))
    cos_t = math.sqrt(max(0.0, 1.0 - (sin_i / n) ** 2))
    ts = 1.0 - ((cos_i - n * cos_t) / (cos_i + n * cos_t)) ** 2
    tp = 1.0 - ((cos_t - n * cos_i) / (cos_t + n * cos_i)) ** 2
    return 0.5 * (ts * ts + tp * tp)


def glass_cap_mean(beta, n=1.5, steps=4000):
    """Mean over a glass sphere's cap of directions (angular radius β) of what it passes:
    a direction θ off its centre enters at sin ι = sin θ / sin β (midpoint rule in θ)."""
    h = beta / steps
    num = den = 0.0
    for k in range(steps):
        t = (k + 0.5) * h
        num += fresnel_two_surfaces(math.sin(t) / math.sin(beta), n) * math.sin(t)
        den += math.sin(t)
    return num / den


def cap_area(a):
    """Solid angle of a cap of angular radius a (cancellation-free)."""
    return 4.0 * math.pi * math.sin(0.5 * a) ** 2


class Frame:
    """A light and two orthonormal directions (w: to the lens, e: ⟂ w)."""

    def __init__(self, light, az, cz, twist):
        s = math.sqrt(max(0.0, 1.0 - cz * cz))
        self.light = light
        self.w = (s * math.cos(az), s * math.sin(az), cz)
        p1 = vunit(vcross(self.w, (0.0, 0.0, 1.0) if abs(cz) < 0.9 else (1.0, 0.0, 0.0)))
        p2 = vcross(self.w, p1)
        self.e = vadd(vscale(p1, math.cos(twist)), vscale(p2, math.sin(twist)))

    def sphere(self, distance, radial, gamma=0.0, glass=False):
        """A sphere seen under `radial` from the light, its centre `gamma` off w."""
        direction = (
            self.w
            if gamma == 0.0
            else vadd(vscale(self.w, math.cos(gamma)), vscale(self.e, math.sin(gamma)))
        )
        center = vadd(self.light, vscale(direction, distance))
        surface = (
            Surface(transmission=1.0, ior=1.5) if glass else Surface(transmission=0.0, ior=1.0)
        )
        return Sphere(center=center, radius=distance * math.sin(radial), surface=surface)

    def scene(self, lens_distance, alpha, obstacle):
        lens = self.sphere(lens_distance, alpha, glass=True)
        return Scene(lights=[Light(position=self.light)], objects=[lens, obstacle])


frames = st.builds(
    Frame,
    light=st.tuples(*[st.floats(-20.0, 20.0)] * 3),
    az=st.floats(0.0, 2 * math.pi),
    cz=st.floats(-1.0, 1.0),
    twist=st.floats(0.0, 2 * math.pi),
)
lens_distances = st.floats(5.0, 50.0)
glass = st.booleans()


def nearer(lens_distance, alpha, beta, fraction):
    """Obstacle distance whose tangent length is `fraction` of the lens's."""
    return lens_distance * math.cos(alpha) / math.cos(beta) * fraction


def run(sc):
    result = compute_phase1(sc)
    json.dumps(result.to_json(), allow_nan=False)
    for s in result.sources:
        assert math.isfinite(s.unblocked_fraction) and 0.0 <= s.unblocked_fraction <= 1.0
        assert s.full == (s.shadow_list == [])
    return result


def lens_source(result):
    found = [s for s in result.sources if (s.light, s.lens) == (0, 0)]
    return found[0] if found else None


def lens_skip(result):
    return {(k.light, k.lens): k.reason for k in result.skipped}.get((0, 0))


# ============================================================ partial, total, ignored


@settings(max_examples=EXAMPLES, deadline=None)
@given(
    frame=frames,
    Dl=lens_distances,
    alpha=st.floats(0.01, 0.6),
    beta_frac=st.floats(0.05, 0.9),
    gamma_frac=st.floats(0.0, 0.95),
    d_frac=st.floats(0.1, 0.9),
    is_glass=glass,
)
def test_obstacle_inside_the_lens_disc_is_partial_by_the_cap_ratio(
    frame, Dl, alpha, beta_frac, gamma_frac, d_frac, is_glass
):
    """Nearer, its disc wholly inside the lens's (γ + β < α): a non-full source with
    the obstacle in its shadow list, blocking exactly its own cap's share (a glass one
    passing its Fresnel share of it)."""
    beta = alpha * beta_frac
    gamma = (alpha - beta) * gamma_frac
    d = nearer(Dl, alpha, beta, d_frac)
    result = run(frame.scene(Dl, alpha, frame.sphere(d, beta, gamma, glass=is_glass)))
    src = lens_source(result)
    assert src is not None, result.skipped
    assert src.full is False and src.shadow_list == [1]
    expected = 1.0 - cap_area(beta) / cap_area(alpha)
    assert 0.0 < src.unblocked_fraction < 1.0
    if is_glass:
        expected = 1.0 - cap_area(beta) / cap_area(alpha) * (1.0 - glass_cap_mean(beta))
        assert src.unblocked_fraction == pytest.approx(expected, abs=2e-4)
    else:
        assert src.unblocked_fraction == pytest.approx(expected, rel=REL)
    if is_glass:  # the glass obstacle is a lens too, and nothing blocks it
        other = [s for s in result.sources if s.lens == 1]
        assert len(other) == 1 and other[0].full


@settings(max_examples=EXAMPLES, deadline=None)
@given(
    frame=frames,
    Dl=lens_distances,
    alpha=st.floats(0.01, 0.5),
    beta_extra=st.floats(0.01, 0.9),
    gamma_frac=st.one_of(st.just(0.0), st.floats(0.0, 0.95)),
    d_frac=st.floats(0.1, 0.9),
    is_glass=glass,
)
def test_bigger_nearer_obstacle_on_the_axis_blocks_totally(
    frame, Dl, alpha, beta_extra, gamma_frac, d_frac, is_glass
):
    """Nearer, its disc covering the lens's (β ≥ γ + α, γ = 0 included): no source,
    the pair reported as totally blocked by that sphere."""
    beta = min(alpha + beta_extra, 1.4)
    gamma = (beta - alpha) * gamma_frac
    d = nearer(Dl, alpha, beta, d_frac)
    result = run(frame.scene(Dl, alpha, frame.sphere(d, beta, gamma, glass=is_glass)))
    assert lens_source(result) is None
    assert lens_skip(result) == "totally blocked by sphere 1"


@settings(max_examples=EXAMPLES, deadline=None)
@given(
    frame=frames,
    Dl=lens_distances,
    alpha=st.floats(0.01, 0.5),
    beta=st.floats(0.01, 1.2),
    gamma_frac=st.floats(0.0, 1.5),
    d_frac=st.floats(1.05, 5.0),
    is_glass=glass,
)
def test_obstacle_behind_the_lens_is_ignored(frame, Dl, alpha, beta, gamma_frac, d_frac, is_glass):
    """Farther tangent length: never blocks, however big its disc (γ from 0 to well
    past α + β): a full source with nothing blocked."""
    gamma = (alpha + beta) * gamma_frac
    d = nearer(Dl, alpha, beta, d_frac)
    result = run(frame.scene(Dl, alpha, frame.sphere(d, beta, gamma, glass=is_glass)))
    src = lens_source(result)
    assert src is not None, result.skipped
    assert src.full is True and src.shadow_list == [] and src.unblocked_fraction == 1.0


@settings(max_examples=EXAMPLES, deadline=None)
@given(
    frame=frames,
    Dl=lens_distances,
    alpha=st.floats(0.01, 0.5),
    beta=st.floats(0.01, 0.5),
    t1=st.floats(0.001, 0.999),
    t2=st.floats(0.001, 0.999),
    d_frac=st.floats(0.1, 0.9),
)
def test_rim_crossing_obstacle_blocks_less_the_farther_off_axis(
    frame, Dl, alpha, beta, t1, t2, d_frac
):
    """Disc crossing the lens's rim (|α − β| < γ < α + β, no total cover): partial,
    0 < unblocked < 1, the blocked share at most the obstacle's cap ratio, and it
    shrinks as the obstacle moves off the axis."""
    lo, hi = abs(alpha - beta), alpha + beta
    shares = []
    for t in sorted((t1, t2)):
        gamma = lo + (hi - lo) * t
        d = nearer(Dl, alpha, beta, d_frac)
        src = lens_source(run(frame.scene(Dl, alpha, frame.sphere(d, beta, gamma))))
        assert src is not None
        assert src.full is False and src.shadow_list == [1]
        assert 0.0 < src.unblocked_fraction < 1.0
        blocked = 1.0 - src.unblocked_fraction
        assert blocked <= min(1.0, cap_area(beta) / cap_area(alpha)) * (1 + 1e-12)
        shares.append(blocked)
    # equal up to the overlap formula's rounding (≈ 1e-15 sr absolute) when γ hardly moves
    assert shares[1] <= shares[0] + 1e-14 / cap_area(alpha)


@settings(max_examples=EXAMPLES, deadline=None)
@given(
    frame=frames,
    Dl=lens_distances,
    alpha=st.floats(0.01, 0.5),
    beta=st.floats(0.01, 0.5),
    t=st.floats(0.001, 0.999),
    d_frac=st.floats(0.1, 0.9),
)
def test_overlap_is_the_same_seen_from_either_disc(frame, Dl, alpha, beta, t, d_frac):
    """The overlap of two caps is symmetric: swapping the lens's and the obstacle's
    apparent sizes (same γ) blocks the same solid angle,
    (1 − u₁)·cap(α) = (1 − u₂)·cap(β)."""
    gamma = abs(alpha - beta) + (alpha + beta - abs(alpha - beta)) * t
    overlap = []
    for a, b in ((alpha, beta), (beta, alpha)):
        d = nearer(Dl, a, b, d_frac)
        src = lens_source(run(frame.scene(Dl, a, frame.sphere(d, b, gamma))))
        assert src is not None and src.shadow_list == [1]
        overlap.append((1.0 - src.unblocked_fraction) * cap_area(a))
    # to 1e-8, or the overlap formula's absolute rounding (≈ 1e-15 sr) for slivers
    assert overlap[0] == pytest.approx(overlap[1], rel=1e-8, abs=1e-14)


# ============================================================ the two tangent boundaries


@settings(max_examples=EXAMPLES, deadline=None)
@given(
    frame=frames,
    Dl=lens_distances,
    alpha=st.floats(1e-3, 0.5),
    beta=st.floats(1e-3, 0.5),
    d_frac=st.floats(0.2, 0.9),
    side=st.sampled_from([-1, +1]),
    is_glass=glass,
)
def test_discs_touching_alpha_plus_beta_equals_gamma(
    frame, Dl, alpha, beta, d_frac, side, is_glass
):
    """γ = (α + β)(1 ∓ 1e-9): a sliver of overlap → partial (blocked < 1e-6);
    a sliver of gap → not blocked at all."""
    gamma = (alpha + beta) * (1.0 + side * REL)
    d = nearer(Dl, alpha, beta, d_frac)
    src = lens_source(run(frame.scene(Dl, alpha, frame.sphere(d, beta, gamma, glass=is_glass))))
    assert src is not None
    if side < 0:
        assert src.full is False and src.shadow_list == [1]
        assert 0.0 <= 1.0 - src.unblocked_fraction < 1e-6
    else:
        assert src.full is True and src.shadow_list == [] and src.unblocked_fraction == 1.0


@settings(max_examples=EXAMPLES, deadline=None)
@given(
    frame=frames,
    Dl=lens_distances,
    alpha=st.floats(1e-3, 0.5),
    gamma=st.floats(1e-3, 0.5),
    d_frac=st.floats(0.2, 0.9),
    side=st.sampled_from([-1, +1]),
    is_glass=glass,
)
def test_disc_just_covering_beta_equals_gamma_plus_alpha(
    frame, Dl, alpha, gamma, d_frac, side, is_glass
):
    """β = (γ + α)(1 ± 1e-9): just covering → totally blocked (no source: a glass one
    too, what it passes is a tertiary source); just short of it → partial with almost
    nothing left (unblocked < 1e-6), or, glass, its Fresnel share: at most T(0) =
    (4n/(n + 1)²)²."""
    beta = (gamma + alpha) * (1.0 + side * REL)
    d = nearer(Dl, alpha, beta, d_frac)
    result = run(frame.scene(Dl, alpha, frame.sphere(d, beta, gamma, glass=is_glass)))
    src = lens_source(result)
    if side > 0:
        assert src is None and lens_skip(result) == "totally blocked by sphere 1"
    else:
        assert src is not None, result.skipped
        assert src.full is False and src.shadow_list == [1]
        if is_glass:
            assert 0.0 < src.unblocked_fraction < (4 * 1.5 / 2.5**2) ** 2
        else:
            assert 0.0 <= src.unblocked_fraction < 1e-6


# ============================================================ small discs (far lenses)


def planar_overlap_fraction(a, b, g):
    """Share of a disc of radius a covered by a disc of radius b whose centre is g
    away (plane geometry): the small-angle limit of the caps' overlap, to a
    relative O(a²). Half-angles at the centres by the half-angle formula (no acos)."""
    if g >= a + b:
        return 0.0
    if g <= abs(a - b):
        return min(1.0, (b / a) ** 2)
    s = 0.5 * (a + b + g)
    half_a = 2.0 * math.atan2(math.sqrt((s - a) * (s - g)), math.sqrt(s * (s - b)))  # at a's centre
    half_b = 2.0 * math.atan2(math.sqrt((s - b) * (s - g)), math.sqrt(s * (s - a)))  # at b's centre
    seg = a * a * (half_a - 0.5 * math.sin(2 * half_a)) + b * b * (
        half_b - 0.5 * math.sin(2 * half_b)
    )
    return seg / (math.pi * a * a)


def test_planar_overlap_reference_is_sound():
    a = 1.0
    assert planar_overlap_fraction(a, 0.5, 0.2) == pytest.approx(0.25, rel=1e-15)
    assert planar_overlap_fraction(a, 1.0, 2.0) == 0.0
    # two equal discs at distance a: 2/3 − √3/(2π) of either (the lens shape)
    assert planar_overlap_fraction(a, 1.0, 1.0) == pytest.approx(
        2 / 3 - math.sqrt(3) / (2 * math.pi), rel=1e-13
    )
    # half-plane limit: a huge disc whose rim passes through the small one's centre
    assert planar_overlap_fraction(a, 1e6, 1e6) == pytest.approx(0.5, rel=1e-5)


@settings(max_examples=EXAMPLES, deadline=None)
@example(frame=Frame((0.0, 0.0, 0.0), 0.0, 0.0, 0.0), log_D=8.0, beta_ratio=2.0, t=0.5, d_frac=0.5)
@given(
    frame=frames,
    log_D=st.floats(3.0, 9.0),
    beta_ratio=st.floats(0.1, 3.0),
    t=st.floats(0.02, 0.98),
    d_frac=st.floats(0.2, 0.9),
)
def test_far_lens_partly_blocked_keeps_its_blocked_share(frame, log_D, beta_ratio, t, d_frac):
    """A lens of radius 1 at 1e3 … 1e9 from the light (α = 1e-3 … 1e-9 rad) and an
    obstacle crossing its rim: the blocked share depends only on the discs' shape
    (α : β : γ), not on how far away they are, and equals the planar overlap to a
    relative 1e-6. (SPEC §5: "lights very far away".)"""
    Dl = 10.0**log_D
    alpha = math.asin(1.0 / Dl)
    beta = alpha * beta_ratio
    lo, hi = abs(alpha - beta), alpha + beta
    gamma = lo + (hi - lo) * t
    sc = Scene(
        lights=[Light(position=frame.light)],
        objects=[
            frame.sphere(Dl, alpha, glass=True),
            frame.sphere(nearer(Dl, alpha, beta, d_frac), beta, gamma),
        ],
    )
    src = lens_source(run(sc))
    assert src is not None and src.shadow_list == [1] and src.full is False
    expected = planar_overlap_fraction(alpha, beta, gamma)
    # floats place the directions only to ~1e-16 rad: allow the share's change over that
    step = 1e-3 * (hi - lo) * min(t, 1 - t)
    slope = abs(
        planar_overlap_fraction(alpha, beta, gamma + step)
        - planar_overlap_fraction(alpha, beta, gamma - step)
    ) / (2 * step)
    assert 1.0 - src.unblocked_fraction == pytest.approx(expected, rel=1e-6, abs=slope * 1e-15), (
        f"α = {alpha:.3g} rad (lens {Dl:.3g} radii away): blocked "
        f"{1.0 - src.unblocked_fraction!r}, the discs' overlap is {expected!r}"
    )
