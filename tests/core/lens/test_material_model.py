"""Material → lens optics rules (core/lens/glass.py); pure, no Blender."""

import pytest

from core.lens.glass import (
    GLASS,
    OTHER,
    PRINCIPLED,
    REFRACTION,
    Absorption,
    Add,
    Bsdf,
    Mix,
    evaluate_material,
)


def principled(t=1.0, ior=1.5, color=(1, 1, 1), metallic=0.0, alpha=1.0):
    return Bsdf(PRINCIPLED, ior=ior, color=color, transmission=t, metallic=metallic, alpha=alpha)


def test_principled_glass_tints_once():
    o = evaluate_material(principled(ior=1.5, color=(0.9, 0.8, 0.7)))
    assert (o.ior, o.transmission, o.tint) == (1.5, 1.0, (0.9, 0.8, 0.7))
    assert o.is_transmissive and o.absorption == (0.0, 0.0, 0.0) and not o.notes


def test_principled_without_transmission_is_opaque():
    o = evaluate_material(principled(t=0.0))
    assert o.transmission == 0.0 and o.ior == 1.0 and not o.is_transmissive


def test_principled_partial_transmission_metallic_and_alpha():
    # refracting share = 0.8 · (1 − 0.5) · 0.5 = 0.2
    o = evaluate_material(principled(t=0.8, metallic=0.5, alpha=0.5))
    assert o.transmission == pytest.approx(0.2) and o.ior == pytest.approx(1.5)


@pytest.mark.parametrize("kind", [GLASS, REFRACTION])
def test_glass_and_refraction_tint_at_both_surfaces(kind):
    o = evaluate_material(Bsdf(kind, ior=1.33, color=(0.5, 1.0, 1.0)))
    assert (o.ior, o.transmission, o.tint) == (1.33, 1.0, (0.25, 1.0, 1.0))


def test_mix_weights_first_by_one_minus_factor():
    # Mix(0.25, glass, diffuse): 0.75 refracts.
    o = evaluate_material(Mix(0.25, Bsdf(GLASS, ior=1.6), Bsdf(OTHER)))
    assert o.transmission == pytest.approx(0.75) and o.ior == pytest.approx(1.6)
    o = evaluate_material(Mix(0.25, Bsdf(GLASS, color=(1, 1, 1)), Bsdf(OTHER, color=(0, 0, 0))))
    assert o.color == pytest.approx((0.75, 0.75, 0.75))
    o = evaluate_material(Mix(1.0, Bsdf(GLASS, ior=1.6), Bsdf(OTHER)))
    assert o.transmission == 0.0


def test_mixed_iors_and_tints_are_averaged_with_a_note():
    o = evaluate_material(
        Mix(0.5, Bsdf(GLASS, ior=1.4, color=(1, 0, 0)), Bsdf(REFRACTION, ior=1.6, color=(0, 0, 1)))
    )
    assert o.transmission == pytest.approx(1.0)
    assert o.ior == pytest.approx(1.5) and o.tint == pytest.approx((0.5, 0.0, 0.5))  # 1² and 1²
    assert any("averaged" in n for n in o.notes)


def test_add_sums_and_clamps():
    o = evaluate_material(Add(Bsdf(GLASS, ior=1.5), Bsdf(REFRACTION, ior=1.5)))
    assert o.transmission == 1.0 and o.ior == 1.5
    o = evaluate_material(Add(Mix(0.5, Bsdf(GLASS), None), Bsdf(OTHER)))
    assert o.transmission == pytest.approx(0.5)


def test_nothing_connected_and_unknown_nodes():
    assert evaluate_material(None).transmission == 0.0
    o = evaluate_material("a group node")
    assert o.transmission == 0.0 and "unknown shader" in o.notes[0]


def test_volume_absorption():
    # σ = density · (1 − colour) per channel; a mix halves it.
    o = evaluate_material(principled(), Absorption(2.0, (1.0, 0.5, 0.0)))
    assert o.absorption == pytest.approx((0.0, 1.0, 2.0))
    o = evaluate_material(principled(), Mix(0.5, Absorption(2.0, (0.0, 0.0, 0.0)), None))
    assert o.absorption == pytest.approx((1.0, 1.0, 1.0))
    o = evaluate_material(principled(), Add(Absorption(1.0, (0, 0, 0)), Absorption(1.0, (0, 0, 0))))
    assert o.absorption == pytest.approx((2.0, 2.0, 2.0))
    o = evaluate_material(principled(), "Principled Volume")
    assert o.absorption == (0.0, 0.0, 0.0) and "ignored" in o.notes[0]


def test_thin_wall_refracts_nothing_and_says_so():
    """Issue 24 item 3: Principled's Thin Wall (5.x) is a shell: what it transmits
    passes straight, so nothing refracts; the share it passes is kept apart."""
    thin = Bsdf(PRINCIPLED, ior=1.5, transmission=1.0, name="Bubble", thin_wall=True)
    o = evaluate_material(thin)
    assert o.transmission == 0.0 and o.ior == 1.0 and not o.is_transmissive
    assert o.thin_wall == 1.0
    assert o.notes == ["Thin Wall on in 'Bubble': a thin shell passes light without focusing it"]
    # half solid glass, half a thin wall passing 0.8 · (1 − 0.5) = 0.4 of its half
    half = Bsdf(PRINCIPLED, transmission=0.8, metallic=0.5, thin_wall=True)
    o = evaluate_material(Mix(0.5, principled(ior=1.4), half))
    assert o.transmission == pytest.approx(0.5) and o.ior == pytest.approx(1.4)
    assert o.thin_wall == pytest.approx(0.2)
    # off, it is the solid glass it always was
    assert evaluate_material(principled()).thin_wall == 0.0
