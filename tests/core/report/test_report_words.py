"""Issue 24 item 6: the report's words say what is true (pure): what was made by
its name, the left-out glass with its shape, and Cycles' caustics left on for the
glass Lens Lights does not model (naming it)."""

from core.plan.cycles_caustics import (
    SCENE,
    Change,
    kept_on_warning,
    linked_caster_warning,
    planned_changes,
)
from core.report.message import left_out_text, made_text


def test_what_was_made_is_counted_by_its_name():
    assert made_text(1) == "1 lens light"
    assert made_text(0) == "0 lens lights"
    assert made_text(0, 1) == "1 caustic layer"
    assert made_text(0, 3) == "3 caustic layers"
    assert made_text(2, 1) == "1 caustic layer and 2 lens lights"


def test_left_out_glass_is_named_with_its_shape():
    left = [
        ("Cylinder", "a cylinder, not a sphere"),
        ("Cube", "a box, not a sphere"),
        ("Egg", "an ellipsoid (axes 1 : 0.71 : 0.71), not a sphere"),
        ("Pane", "a flat sheet, not a closed surface"),
    ]
    assert left_out_text([]) == ""
    assert left_out_text(left[:1]) == (
        "left out 1 object (Lens Lights models solid glass spheres and closed glass meshes): "
        "Cylinder (a cylinder, not a sphere)"
    )
    assert left_out_text(left) == (
        "left out 4 objects (Lens Lights models solid glass spheres and closed glass meshes): "
        "Cylinder (a cylinder, not a sphere); Cube (a box, not a sphere); "
        "Egg (an ellipsoid (axes 1 : 0.71 : 0.71), not a sphere); and 1 more"
    )


def test_the_scene_switch_is_kept_for_unmodelled_glass():
    scene = {"caustics_refractive": True}
    lenses = {"Ball": {"is_caustics_caster": True}}
    assert planned_changes(scene, lenses) == [
        Change(SCENE, "caustics_refractive", True, False),
        Change("Ball", "is_caustics_caster", True, False),
    ]
    assert planned_changes(scene, lenses, keep_scene=True) == [
        Change("Ball", "is_caustics_caster", True, False)
    ]


def test_the_warning_names_the_glass_and_the_lenses():
    on = {"caustics_refractive": True}
    text = kept_on_warning("CYCLES", on, ["Cube", "Cylinder"], ["Ball"])
    assert text.startswith(
        "Cycles' refractive caustics left on: Lens Lights does not model the glass of "
        "Cube, Cylinder, whose caustics only Cycles renders"
    )
    assert "its own caustic of Ball on top of the lens lights'" in text
    many = kept_on_warning("CYCLES", on, ["A", "B", "C", "D", "E"], ["Ball"])
    assert "the glass of A, B, C and 2 more," in many
    # nothing to say: no such glass, the switch already off, or not Cycles
    assert kept_on_warning("CYCLES", on, [], ["Ball"]) == ""
    assert kept_on_warning("CYCLES", {"caustics_refractive": False}, ["Cube"], ["Ball"]) == ""
    assert kept_on_warning("BLENDER_EEVEE", on, ["Cube"], ["Ball"]) == ""


def test_the_warning_names_the_lenses_left_without_a_lens_light():
    on = {"caustics_refractive": True}
    text = kept_on_warning("CYCLES", on, [], ["Ball"], unlit=["Ball.001"])
    assert text.startswith(
        "Cycles' refractive caustics left on: Maximum Lens Lights left Ball.001 without a "
        "lens light, whose caustics only Cycles renders"
    )
    both = kept_on_warning("CYCLES", on, ["Cube"], ["Ball"], unlit=["Ball.001"])
    assert "the glass of Cube and Maximum Lens Lights left Ball.001 without" in both


def test_the_warning_for_linked_casters():
    text = linked_caster_warning("CYCLES", ["Marble", "Pebble"])
    assert text.startswith("Shadow caustics caster left on for Marble, Pebble: linked from a")
    assert "on top of the lens lights'" in text and "Library Override" in text
    assert linked_caster_warning("CYCLES", []) == ""
    assert linked_caster_warning("BLENDER_EEVEE", ["Marble"]) == ""
