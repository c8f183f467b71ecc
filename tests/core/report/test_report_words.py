"""Issue 24 item 6: the report's words say what is true (pure): what was made by
its name, the left-out glass with its shape, and Cycles' caustics left on for the
glass Lens Lights does not model (naming it)."""

from types import SimpleNamespace

from core.plan.cycles_caustics import (
    SCENE,
    Change,
    describe_restored,
    kept_on_warning,
    linked_caster_warning,
    planned_changes,
)
from core.report.message import left_out_text, made_text, report_message


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


# --------------------------------------------------------------------------- issue 28 item 7


def test_a_layer_run_counts_layers_and_fallback_spots_by_their_names():
    """One layer mesh on the table and one fallback spot for a mirror read as that,
    not as "2 lens lights … 2 caustic layers"."""
    assert made_text(0, 1, 1, ["Table"], ["Mirror"]) == (
        "1 caustic layer on Table and 1 fallback spot on glossy or transparent Mirror"
    )
    assert made_text(0, 2, 0, ["Table", "Wall"]) == "2 caustic layers on Table, Wall"
    assert made_text(0, 0, 2) == "2 fallback spots on glossy or transparent receivers"
    assert made_text(3, 0, 0) == "3 lens lights"


def test_clear_says_what_it_put_back():
    """Clear said "Cycles' own caustics restored (the lens lights replace them)": the
    lens lights are gone; it put the user's values back."""
    put_back = [
        Change(SCENE, "caustics_refractive", True, False),
        Change("Ball", "is_caustics_caster", True, False),
    ]
    assert describe_restored(put_back) == (
        "Cycles' own caustics back as they were: refractive caustics (scene) on, "
        "shadow caustics caster of Ball on"
    )
    assert describe_restored([]) == ""


def _work(flux_kept, flux_total):
    """The parts of a `planning.Work` the report reads: one light, two lenses, a
    source per lens, both built."""
    import numpy as np

    from core.phase1.point_lights import SkipTable

    sources = [SimpleNamespace(name="a"), SimpleNamespace(name="b")]
    none = np.zeros(0, dtype=np.int64)
    return SimpleNamespace(
        read=SimpleNamespace(
            light_sources=["Lamp"],
            sphere_sources=["A", "B"],
            lens_candidates=np.array([True, True]),
            arrays=None,
            left_out_lenses=[],
            light_notes=[],
            how="render",
        ),
        result=SimpleNamespace(table=[0, 1], skip_table=SkipTable(none, none, none, none)),
        selection=SimpleNamespace(
            sources=sources,
            flux_kept=np.array(flux_kept),
            flux_total=flux_total,
            budget=SimpleNamespace(over_cap=0, merged=0, preselect=0),
        ),
        plan=SimpleNamespace(lights=[SimpleNamespace(source=s) for s in sources], skipped=[]),
    )


def test_the_flux_without_a_light_is_never_rounding_dust():
    """Both sources built: 1 − (0.1 + 0.7)/0.8 is 1.1e-16 in floating point, which
    read "1.11e-14% of the lenses' flux has no lens light"."""
    level, message, figures = report_message(_work([0.1, 0.7], 0.8), 2)
    assert message == "Created 2 lens lights (1 light × 2 lenses)"
    level, message, figures = report_message(_work([0.1, 0.3], 0.8), 2)
    assert (
        message
        == "Created 2 lens lights (1 light × 2 lenses); 50 % of the lenses' flux has no lens light"
    )


def test_a_lens_with_the_users_lens_lights_beside_the_new_ones_is_counted_and_named():
    """Issue 28 item 4: a lens light the user duplicated, renamed or moved is kept; the
    report says how many the lens now has, and which are whose."""
    from core.report.message import kept_text

    made = [("Lens light Lamp > Marble", "Marble"), ("Lens light Lamp > Other", "Other")]
    assert kept_text(made, []) == ""
    assert kept_text(made, [("My copy", "Marble")]) == (
        "Marble has 2 lens lights: 'Lens light Lamp > Marble' (made now) and "
        "'My copy' (yours, kept)"
    )
    # after Clear nothing is made now; three copies of two lenses
    assert kept_text([], [("A", "Marble"), ("B", "Ball"), ("C", "Marble")]) == (
        "Ball has 1 lens light: 'B' (yours, kept); "
        "Marble has 2 lens lights: 'A' (yours, kept) and 'C' (yours, kept)"
    )
    many = [(f"Copy {k}", f"Lens {k}") for k in range(5)]
    text = kept_text([], many, "caustic layer")
    assert text.startswith("Lens 0 has 1 caustic layer: 'Copy 0' (yours, kept); ")
    assert text.endswith("; and 2 more lenses with caustic layers of yours")
