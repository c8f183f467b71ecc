"""Energy models → Blender light parameters (core/tiers/, core/plan/planning.py); pure, no Blender.

Expectations are worked out by hand in the comments (R = 0.5, n = 1.5, D = 2,
P = 100 W unless said otherwise).
"""

import math

import numpy as np
import pytest

from core.lens.glass import LensOptics, head_on_transmission
from core.phase1.point_lights import SecondarySource, compute_phase1
from core.scene.model import Light, Scene, Sphere, Surface
from core.scene.primaries import PrimaryLight
from core.tiers import (
    COLLIMATED_DISTANCE_FACTOR,
    CUTOFF_FACTOR,
    cone_shape,
    energy_model_items,
    make_blender_light,
)
from core.tiers import TIERS as ENERGY_MODELS

P = 100.0


def ball_scene(distance=2.0, kt=1.0, ior=1.5, radius=0.5, light_radius=0.0):
    """Light straight above a sphere at the origin: the axis is −z."""
    return Scene(
        lights=[Light(position=(0.0, 0.0, distance), brightness=P, radius=light_radius)],
        objects=[
            Sphere(center=(0.0, 0.0, 0.0), radius=radius, surface=Surface(transmission=kt, ior=ior))
        ],
    )


def only_source(scene):
    result = compute_phase1(scene)
    assert len(result.sources) == 1, result.skipped
    return result.sources[0]


def test_head_on_transmission():
    # (4n/(n+1)²)² = (6/6.25)² = 0.9216 for n = 1.5; no interface for n = 1.
    assert head_on_transmission(1.5) == pytest.approx(0.9216, abs=1e-12)
    assert head_on_transmission(1.0) == pytest.approx(1.0)


def test_physical_real_image_by_hand():
    # V = 2(n−1)/(nR) − 1/D = 4/3 − 1/2 = 5/6 → image 1.2 below the centre,
    # m = −1.2/2 = −0.6, m² = 0.36; energy = P·T(0)·m² = 100 · 0.9216 · 0.36.
    src = only_source(ball_scene(light_radius=0.1))
    bl = make_blender_light(src, PrimaryLight(P, radius=0.1), "PHYSICAL", scene_size=4.0)
    assert bl.type == "SPOT"
    assert bl.energy_w == pytest.approx(100 * 0.9216 * 0.36, rel=1e-9)
    assert bl.location == pytest.approx((0.0, 0.0, -1.2), abs=1e-12)
    assert bl.direction == pytest.approx((0.0, 0.0, -1.0), abs=1e-12)
    # θ: α = asin(1/4), δ = asin(2/3), φ = 2δ + α − 90° = 8.0981°, d = R sin φ,
    # tan θ = |dV| / |R cos φ V − 1| = 0.099905 → θ = 5.7052°, spot_size = 2θ.
    assert bl.spot_size_deg == pytest.approx(11.4104, abs=2e-3)
    assert bl.scale_xy == 1.0
    assert bl.radius == pytest.approx(0.6 * 0.1)  # |m| · r
    assert bl.kind == "real" and bl.note == ""
    assert bl.cutoff_distance == pytest.approx(CUTOFF_FACTOR * (1.2 + 4.0))
    # Reference irradiance at |1/V| beyond the image: I0 T m² V² = I0 T / D².
    assert bl.relative_brightness == pytest.approx(0.9216, rel=1e-9)
    assert bl.to_json() == {
        "type": "SPOT",
        "energy_w": bl.energy_w,
        "spot_size_deg": bl.spot_size_deg,
        "spot_blend": 0.15,
        "radius": bl.radius,
    }


def test_thesis_is_primary_power_times_eq_5_22():
    # kt = 1: factor 1, energy = P. kt = 0.6: exp(−0.4 · R (1 + cos δ)),
    # cos δ = sqrt(n² − 1)/n = 0.745356 → exp(−0.4 · 0.5 · 1.745356) = exp(−0.349071) = 0.705343.
    bl = make_blender_light(only_source(ball_scene()), PrimaryLight(P), "THESIS")
    assert bl.energy_w == pytest.approx(P)
    src = only_source(ball_scene(kt=0.6))
    bl = make_blender_light(src, PrimaryLight(P, color=(1.0, 0.5, 0.25)), "THESIS")
    assert bl.energy_w == pytest.approx(P * 0.705343, rel=1e-5)
    assert bl.color == (1.0, 0.5, 0.25)  # the primary's colour only


def test_physical_virtual_image_by_hand():
    # D = 0.7 < front focal distance 0.75: V = 4/3 − 1/0.7 = −0.095238,
    # image at 1/V = −10.5 (on the light's side), m = 10.5/0.7 = 15, m² = 225.
    src = only_source(ball_scene(distance=0.7, light_radius=0.01))
    assert src.kind == "virtual"
    bl = make_blender_light(src, PrimaryLight(P, radius=0.01), "PHYSICAL", scene_size=30.0)
    assert bl.energy_w == pytest.approx(P * 0.9216 * 225, rel=1e-9)
    assert bl.location == pytest.approx((0.0, 0.0, 10.5), rel=1e-9)
    assert bl.direction == pytest.approx((0.0, 0.0, -1.0))
    assert bl.radius == pytest.approx(15 * 0.01)


def test_physical_tint_absorption_and_weight():
    # w = 0.5 → × 0.25 on energy; tint (of the whole path) as is; σ over 2R = 1.
    src = only_source(ball_scene())
    optics = LensOptics(transmission_weight=0.5, tint=(1.0, 0.5, 0.0), absorption=(0.0, 1.0, 2.0))
    bl = make_blender_light(src, PrimaryLight(P, color=(1.0, 1.0, 0.5)), "PHYSICAL", optics=optics)
    assert bl.energy_w == pytest.approx(100 * 0.9216 * 0.36 * 0.25)
    assert bl.color == pytest.approx((1.0, 0.5 * math.exp(-1.0), 0.0))


def test_non_full_scales_energy_by_unblocked_share():
    # An opaque ball (radius 0.25) half-way, beside the axis: the lens is non-full.
    scene = ball_scene(distance=4.0)
    scene.objects.append(Sphere(center=(0.3, 0.0, 2.0), radius=0.25))
    src = [s for s in compute_phase1(scene).sources if s.lens == 0][0]
    assert not src.full and 0.0 < src.unblocked_fraction < 1.0
    full = make_blender_light(src, PrimaryLight(P), "PHYSICAL")
    src.full, f = True, src.unblocked_fraction
    src.unblocked_fraction = 1.0
    unscaled = make_blender_light(src, PrimaryLight(P), "PHYSICAL")
    assert full.energy_w == pytest.approx(unscaled.energy_w * f)
    assert "non-full" in full.note


def test_cone_shape_within_blender_range():
    s = cone_shape(30.0)
    assert (s.spot_size_deg, s.scale_xy, s.half_angle_deg, s.note) == (60.0, 1.0, 30.0, "")
    assert cone_shape(0.5).spot_size_deg == 1.0 and cone_shape(0.5).scale_xy == 1.0
    assert cone_shape(90.0).spot_size_deg == 180.0


def test_cone_narrower_than_one_degree_uses_object_scale():
    # 2θ = 0.5°: spot_size 1°, scale tan(0.25°)/tan(0.5°) = 0.49996; the cone made
    # through the scaled object has tan = tan(0.5°) · k = tan(0.25°) exactly.
    s = cone_shape(0.25)
    assert s.spot_size_deg == 1.0
    assert s.scale_xy == pytest.approx(math.tan(math.radians(0.25)) / math.tan(math.radians(0.5)))
    assert math.tan(math.radians(0.5)) * s.scale_xy == pytest.approx(math.tan(math.radians(0.25)))
    assert "1°" in s.note


def test_cone_wider_than_180_degrees_is_clamped():
    s = cone_shape(100.0)
    assert s.spot_size_deg == 180.0 and s.scale_xy == 1.0 and "180" in s.note


def test_degenerate_cone_is_widened_not_zero():
    for theta in (0.0, -1.0, float("nan")):
        s = cone_shape(theta)
        assert s.scale_xy > 0 and s.half_angle_deg > 0 and "widened" in s.note


def collimated_source(rc=0.1, distance=0.75, ior=1.5, radius=0.5):
    """A hand-made collimated source: light at the focal point D = 0.75 above the
    sphere at the origin, beam down the −z axis from the back vertex (0, 0, −0.5)."""
    return SecondarySource(
        light=0,
        lens=0,
        kind="collimated",
        position=np.array([0.0, 0.0, -radius]),
        axis=np.array([0.0, 0.0, -1.0]),
        spread_deg=0.0,
        cylinder_radius=rc,
        intensity=P,
        color=(1.0, 1.0, 1.0),
        full=True,
        shadow_list=[],
        brightness_factor=1.0,
        distance=distance,
        lens_center=np.zeros(3),
        lens_radius=radius,
        ior=ior,
        vergence=0.0,
        image_distance=None,
        magnification=None,
        alpha_deg=math.degrees(math.asin(radius / distance)),
        unblocked_fraction=1.0,
    )


def test_collimated_beam_is_a_far_spot_by_hand():
    # scene size 2: s = 40 behind the back vertex, L_ref = 1, half-angle
    # atan(0.1/40) = 0.14324° → 1° spot narrowed by k = tan(0.14324°)/tan(0.5°).
    # PHYSICAL: E = I0 T(0) / D² at every distance (paraxial rays are parallel);
    # intensity E · (s + L_ref)², energy 4π × that = P T(0) 41² / 0.75².
    src = collimated_source()
    bl = make_blender_light(src, PrimaryLight(P, radius=0.05), "PHYSICAL", scene_size=2.0)
    s = COLLIMATED_DISTANCE_FACTOR * 2.0
    assert s == 40.0
    assert bl.location == pytest.approx((0.0, 0.0, 40.0 - 0.5))
    assert bl.direction == pytest.approx((0.0, 0.0, -1.0))
    assert bl.spot_size_deg == 1.0
    assert bl.scale_xy == pytest.approx((0.1 / 40) / math.tan(math.radians(0.5)), rel=1e-9)
    assert bl.energy_w == pytest.approx(P * 0.9216 * 41**2 / 0.75**2, rel=1e-9)
    # footprint at the back vertex is R_C: tan(half-angle) · s
    assert math.tan(math.radians(0.5)) * bl.scale_xy * s == pytest.approx(0.1)
    # the blur z·r/D at the reference receiver (R + L_ref = 1.5 from the centre)
    assert bl.radius == pytest.approx(1.5 * 0.05 / 0.75)
    assert bl.kind == "collimated" and "collimated" in bl.note
    # irradiance at the reference distance: intensity / (s + L_ref)²
    assert bl.energy_w / (4 * math.pi) / 41**2 == pytest.approx(bl.reference_irradiance)
    assert bl.relative_brightness == pytest.approx(0.9216)


def test_collimated_thesis_matches_point_light_at_reference():
    # THESIS: intensity I0 · factor at the back vertex → E = I0 / L_ref² at L_ref = 1.
    bl = make_blender_light(collimated_source(), PrimaryLight(P), "THESIS", scene_size=2.0)
    assert bl.reference_irradiance == pytest.approx(P / (4 * math.pi) / 1.0)


def test_collimated_is_continuous_with_a_far_real_image():
    # Just before collimation the cone's irradiance far beyond the image tends to
    # the beam's I0 T / D²: compare at the image distance itself.
    src = only_source(ball_scene(distance=0.75 * (1 + 1e-4)))
    assert src.kind == "real"
    bl = make_blender_light(src, PrimaryLight(P), "PHYSICAL", scene_size=4.0)
    beam = make_blender_light(
        collimated_source(distance=src.distance), PrimaryLight(P), "PHYSICAL", scene_size=4.0
    )
    assert bl.reference_irradiance == pytest.approx(beam.reference_irradiance, rel=1e-3)


def test_unknown_model_and_registry():
    # (FITTED was the unknown name here before the tiers were registered.)
    with pytest.raises(ValueError, match="unknown energy model"):
        make_blender_light(only_source(ball_scene()), PrimaryLight(P), "BOGUS")
    assert list(ENERGY_MODELS)[:2] == ["THESIS", "PHYSICAL"]
    assert [i[0] for i in energy_model_items()][:2] == ["THESIS", "PHYSICAL"]


# --------------------------------------------------------------------------- tiers


def test_all_five_tiers_and_auto_are_registered():
    from core.tiers import AUTO, DEFAULT_ENERGY_MODEL

    assert list(ENERGY_MODELS) == ["THESIS", "PHYSICAL", "FITTED", "EXACT_PROFILE", "CAUSTIC_LAYER"]
    items = energy_model_items(include_auto=True)
    assert [i[0] for i in items] == [
        "AUTO",
        "THESIS",
        "PHYSICAL",
        "FITTED",
        "EXACT_PROFILE",
        "CAUSTIC_LAYER",
    ]
    assert DEFAULT_ENERGY_MODEL == AUTO
    assert items[0][1] == "Auto — most accurate for the engine"
    assert all(len(i) == 4 and all(isinstance(x, str) and x for x in i[:3]) for i in items)
    # numbers as stored in .blend files: THESIS 0 and PHYSICAL 1 as before the tiers
    assert [i[3] for i in items] == [4, 0, 1, 2, 3, 5]


@pytest.mark.parametrize(
    "model, engine, tier, warns",
    [
        ("AUTO", "CYCLES", "EXACT_PROFILE", False),
        ("AUTO", "BLENDER_EEVEE", "CAUSTIC_LAYER", False),
        ("AUTO", "BLENDER_EEVEE_NEXT", "CAUSTIC_LAYER", False),
        ("CAUSTIC_LAYER", "CYCLES", "CAUSTIC_LAYER", False),
        ("AUTO", "BLENDER_WORKBENCH", "FITTED", False),
        ("AUTO", None, "FITTED", False),
        ("EXACT_PROFILE", "CYCLES", "EXACT_PROFILE", False),
        ("EXACT_PROFILE", "BLENDER_EEVEE", "FITTED", True),
        ("EXACT_PROFILE", None, "EXACT_PROFILE", False),
        ("FITTED", "CYCLES", "FITTED", False),
        ("THESIS", "BLENDER_EEVEE", "THESIS", False),
        ("PHYSICAL", "CYCLES", "PHYSICAL", False),
    ],
)
def test_resolve_energy_model(model, engine, tier, warns):
    from core.tiers import resolve_energy_model

    got, warning = resolve_energy_model(model, engine)
    assert got == tier
    assert bool(warning) == warns
    if warns:
        assert "EEVEE" in warning and "Fitted" in warning


@pytest.mark.parametrize("tier", ["FITTED", "EXACT_PROFILE"])
def test_lens_light_radius_is_the_images(tier):
    """Issue 10: a primary of radius r images to a source of radius |m|·r (SPEC §4.1),
    whatever tier; for a collimated beam (|m| → ∞) at most r·S/D. By hand, R = 0.5,
    n = 1.5: P = 2(n − 1)/(nR) = 4/3."""
    r = 0.1
    # D = 2: V = 4/3 − 1/2 = 5/6, 1/V = 1.2, m = −(1/V)/D = −0.6 → |m|·r = 0.06
    # (cap r·S/D = 0.1 · 4/2 = 0.2 does not apply)
    src = only_source(ball_scene(light_radius=r))
    bl = make_blender_light(src, PrimaryLight(P, radius=r), tier, scene_size=4.0)
    assert bl.radius == pytest.approx(0.06, rel=1e-12)
    # scene size S = 1 < |1/V| = 1.2: the cap r·S/D = 0.1 · 1/2 = 0.05
    bl = make_blender_light(src, PrimaryLight(P, radius=r), tier, scene_size=1.0)
    assert bl.radius == pytest.approx(0.05, rel=1e-12)
    # D = 4: V = 4/3 − 1/4 = 13/12, 1/V = 12/13, m = −(12/13)/4 = −3/13 → 0.3/13
    src = only_source(ball_scene(distance=4.0, light_radius=r))
    bl = make_blender_light(src, PrimaryLight(P, radius=r), tier, scene_size=4.0)
    assert bl.radius == pytest.approx(0.3 / 13, rel=1e-12)
    # collimated (light at the focal point D = nR/(2(n − 1)) = 0.75, V = 0): r·S/D
    bl = make_blender_light(collimated_source(), PrimaryLight(P, radius=r), tier, scene_size=2.0)
    assert bl.radius == pytest.approx(0.1 * 2.0 / 0.75, rel=1e-12)
    # a point primary stays a point
    assert make_blender_light(src, PrimaryLight(P), tier, scene_size=4.0).radius == 0.0


def test_make_blender_light_dispatches_the_tiers():
    from core.tiers import exact_profile
    from core.tiers import fitted as fitted_tier

    src = only_source(ball_scene(light_radius=0.1))
    prim = PrimaryLight(P, radius=0.1)
    fitted = make_blender_light(src, prim, "FITTED", scene_size=4.0, spot_blend=0.3)
    assert fitted == fitted_tier.make_fitted_light(src, prim, scene_size=4.0)
    assert fitted.model == "FITTED" and fitted.type == "SPOT"
    assert make_blender_light(src, prim, "AUTO", scene_size=4.0) == fitted  # no engine: FITTED
    exact = make_blender_light(src, prim, "EXACT_PROFILE", scene_size=4.0)
    assert isinstance(exact, exact_profile.ProfileLight) and exact.model == "EXACT_PROFILE"
    assert (exact.spot_size_deg, exact.spot_blend) == (180.0, 0.0)
    # planning needs a brightness for every tier (cut-off and ordering)
    for bl in (fitted, exact):
        assert bl.reference_irradiance > 0 and bl.relative_brightness > 0
        assert set(bl.to_json()) >= {"type", "energy_w", "spot_size_deg", "spot_blend", "radius"}


def test_profile_light_reference_brightness_is_the_exact_beams():
    # D/R = 4, n = 1.5: the exact mean irradiance on a disc of 0.05 R at 0.5 R
    # behind the lens, over the primary's irradiance at the lens centre.
    from core.tiers.beam_error import ExactBeam

    src = only_source(ball_scene())
    bl = make_blender_light(src, PrimaryLight(P), "EXACT_PROFILE", scene_size=4.0)
    beam = ExactBeam(P / (4 * math.pi), 2.0, 0.5, 1.5)
    e = beam.flux_within_radius(beam.plane(0.5), [0.025])[0] / (math.pi * 0.025**2)
    assert bl.reference_irradiance == pytest.approx(e, rel=1e-3)
    assert bl.relative_brightness == pytest.approx(e / (P / (4 * math.pi) / 4.0), rel=1e-3)


def test_profile_table_is_made_only_when_used():
    from core.tiers import exact_profile as lt

    src = only_source(ball_scene(distance=2.345))
    lt.cached_profile.cache_clear()
    bl = make_blender_light(src, PrimaryLight(P), "EXACT_PROFILE")
    assert lt.cached_profile.cache_info().currsize == 0  # planning: no table
    js = bl.to_json()
    assert (
        js["profile"]["width"] == lt.PROFILE_ANGLES and lt.cached_profile.cache_info().currsize == 0
    )
    p = bl.profile
    assert p["pixels"].shape == (lt.PROFILE_DISTANCES, lt.PROFILE_ANGLES)
    assert p["key"] == f"D/R {2.345 / 0.5:.9g} n 1.5"
    assert lt.cached_profile.cache_info().currsize == 1
    # the energy: twice the beam's flux (a 180° spot emits half its energy)
    prof = lt.cached_profile(round(2.345 / 0.5, 9), 1.5)
    assert bl.energy_w / 2 == pytest.approx(prof.flux * P / (4 * math.pi), rel=1e-9)


def test_plan_lights_with_every_tier_keeps_brightness_order_and_scale():
    from core.plan.planning import plan_lights

    result = compute_phase1(two_lens_scene())
    for tier in ("THESIS", "PHYSICAL", "FITTED", "EXACT_PROFILE"):
        plan = plan_lights(
            result,
            [PrimaryLight(P)],
            tier,
            scene_size=6.0,
            energy_scale=[2.0] * len(result.sources),
        )
        assert len(plan.lights) == 2, tier
        assert all(p.light.model == tier for p in plan.lights)
        irr = [p.light.reference_irradiance for p in plan.lights]
        assert irr == sorted(irr, reverse=True)
        single = make_blender_light(plan.lights[0].source, PrimaryLight(P), tier, scene_size=6.0)
        assert plan.lights[0].light.energy_w == pytest.approx(2.0 * single.energy_w)


def test_fitted_spot_is_pulled_in_before_geometry_behind_the_lens():
    # Near the front focal distance (0.75 for R 0.5, n 1.5) the fitted spot sits
    # far behind the lens; a free distance of 1 brings it to 1 behind the back vertex.
    src = only_source(ball_scene(distance=0.76))
    free = make_blender_light(src, PrimaryLight(P), "FITTED", scene_size=4.0)
    behind = free.location[2] + 0.5  # the axis is −z, back vertex z = −0.5
    # the fit's own spot is 1000 R behind; as the other tiers' beams, at most
    # COLLIMATED_DISTANCE_FACTOR × the scene's size
    assert behind == pytest.approx(COLLIMATED_DISTANCE_FACTOR * 4.0)
    near = make_blender_light(
        src, PrimaryLight(P), "FITTED", scene_size=4.0, collimated_distance=1.0
    )
    assert near.location[2] + 0.5 == pytest.approx(1.0)
    assert "pulled in" in near.note
    # the cone keeps its radius at the first receiver (0.25 behind the back vertex)
    r_free = math.tan(math.radians(free.cone_half_angle_deg)) * (behind + 0.25)
    r_near = math.tan(math.radians(near.cone_half_angle_deg)) * (1.0 + 0.25)
    assert r_near == pytest.approx(r_free, rel=1e-6)


def test_axis_is_normalised_and_oblique_geometry():
    # Light at (3, 0, 4) from a sphere at the origin: axis −(0.6, 0, 0.8), D = 5.
    scene = ball_scene()
    scene.lights[0].position = (3.0, 0.0, 4.0)
    src = only_source(scene)
    bl = make_blender_light(src, PrimaryLight(P), "PHYSICAL")
    assert bl.direction == pytest.approx((-0.6, 0.0, -0.8))
    v = 4 / 3 - 1 / 5
    assert bl.location == pytest.approx(tuple(-0.6 / v * np.array([1, 0, 4 / 3])), rel=1e-9)
    assert bl.energy_w == pytest.approx(P * 0.9216 * (1 / v / 5) ** 2)


def two_lens_scene():
    """Two clear lenses under one light, and an opaque ball (no lens) beside them."""
    return Scene(
        lights=[Light(position=(0.0, 0.0, 3.0), brightness=P)],
        objects=[
            Sphere(center=(-1.0, 0.0, 0.0), radius=0.5, surface=Surface(transmission=1.0, ior=1.5)),
            Sphere(center=(1.0, 0.0, 0.0), radius=0.25, surface=Surface(transmission=0.5, ior=1.5)),
            Sphere(center=(0.0, 3.0, 0.0), radius=0.5, surface=Surface(transmission=0.0)),
        ],
    )


def test_plan_orders_by_brightness_and_limits():
    from core.plan.planning import plan_lights

    scene = two_lens_scene()
    result = compute_phase1(scene)
    prim = [PrimaryLight(P)]
    plan = plan_lights(
        result,
        prim,
        "PHYSICAL",
        light_names=["Lamp"],
        lens_names=["Big", "Small", "Ball"],
        lens_candidates=[True, True, False],
        scene_size=6.0,
    )
    assert plan.not_lenses == 1 and plan.skipped == []  # the opaque ball is not listed
    assert [p.lens_name for p in plan.lights] == ["Big", "Small"] or [
        p.lens_name for p in plan.lights
    ] == ["Small", "Big"]
    irr = [p.light.reference_irradiance for p in plan.lights]
    assert irr == sorted(irr, reverse=True)
    one = plan_lights(
        result,
        prim,
        "PHYSICAL",
        light_names=["Lamp"],
        lens_names=["Big", "Small", "Ball"],
        lens_candidates=[True, True, False],
        max_lights=1,
    )
    assert len(one.lights) == 1 and one.lights[0].lens_name == plan.lights[0].lens_name
    assert one.skipped == [
        ("Lamp", plan.lights[1].lens_name, "beyond the maximum of 1 lens lights")
    ]


def test_plan_brightness_cut_off_and_summary():
    from core.plan.planning import plan_lights

    result = compute_phase1(two_lens_scene())
    # PHYSICAL relative brightness = T(0) · w²: 0.9216 (w = 1) and 0.2304 (w = 0.5).
    optics = [LensOptics(1.0), LensOptics(0.5), LensOptics(0.0)]
    plan = plan_lights(result, [PrimaryLight(P)], "PHYSICAL", optics=optics, min_brightness=0.5)
    assert [p.source.lens for p in plan.lights] == [0]
    assert plan.skipped[-1][:2] == ("light 0", "sphere 1")
    assert plan.skipped[-1][2].startswith("dimmer than the cut-off (0.23 < 0.5)")
    # the opaque ball, without lens_candidates, is listed with phase 1's reason
    assert ("light 0", "sphere 2", "opaque (kt = 0)") in plan.skipped
    assert plan.skipped_summary(first=1).endswith("and 1 more")


def test_real_image_beyond_the_scene_becomes_a_converging_beam():
    # A marble resting on a table (z = 0) under a lamp 2 above its centre: the image
    # (1.2 below the centre, z = −0.7) lies under the table, beyond everything. A spot
    # there would light nothing; the beam representation lights the table.
    src = only_source(ball_scene())  # centre (0, 0, 0), image at z = −1.2
    bounds = ((-3.0, -3.0, -0.5), (3.0, 3.0, 2.0))  # the table top at z = −0.5
    bl = make_blender_light(src, PrimaryLight(P), "PHYSICAL", scene_size=8.0, scene_bounds=bounds)
    assert "real image beyond the scene" in bl.note
    assert bl.location[2] > 100 and bl.direction == pytest.approx((0, 0, -1))
    # Reference: half the scene's reach beyond the back vertex (z = −0.5): reach 0,
    # so L_ref = 0; E = I0 T m² / (1/V − R)² = 1000/(4π) · 0.9216 · 0.36 / 0.7².
    e = P / (4 * math.pi) * 0.9216 * 0.36 / 0.7**2
    assert bl.reference_irradiance == pytest.approx(e, rel=1e-9)
    s = COLLIMATED_DISTANCE_FACTOR * 8.0
    assert bl.energy_w == pytest.approx(4 * math.pi * e * s**2, rel=1e-9)
    # footprint at the back vertex = the converging beam's radius tan θ (1/V − R)
    width = math.tan(math.radians(src.spread_deg)) * 0.7
    assert math.tan(math.radians(bl.cone_half_angle_deg)) * s == pytest.approx(width, rel=1e-9)
    # With the table lower (z = −1.5) the image (z = −1.2) is inside the scene: a cone.
    bl = make_blender_light(
        src,
        PrimaryLight(P),
        "PHYSICAL",
        scene_size=8.0,
        scene_bounds=((-3.0, -3.0, -1.5), (3.0, 3.0, 2.0)),
    )
    assert bl.location == pytest.approx((0.0, 0.0, -1.2)) and "beam" not in bl.note


def test_far_virtual_image_becomes_a_beam_and_the_spot_distance_can_be_limited():
    # D = 0.7499: V = 4/3 − 1/0.7499 < 0, image ~5600 behind: farther than the
    # beam's spot (20 × scene size 2 = 40) would be.
    src = only_source(ball_scene(distance=0.7499))
    assert src.kind == "virtual" and src.image_distance < -1000
    bl = make_blender_light(src, PrimaryLight(P), "PHYSICAL", scene_size=2.0)
    assert "virtual image far behind" in bl.note
    assert bl.location == pytest.approx((0.0, 0.0, -0.5 + 40.0))  # back vertex z = −0.5
    # geometry 3 behind the lens: the caller limits the distance; the irradiance at
    # the reference stays the model's.
    near = make_blender_light(
        src, PrimaryLight(P), "PHYSICAL", scene_size=2.0, collimated_distance=3.0
    )
    assert near.location == pytest.approx((0.0, 0.0, 2.5))
    assert near.reference_irradiance == pytest.approx(bl.reference_irradiance)
    assert near.energy_w < bl.energy_w
