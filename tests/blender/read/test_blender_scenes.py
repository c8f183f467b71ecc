"""Issue 12 in Blender: every light type makes lens lights, what is not modelled is
named, the resting marble, and Cycles' own caustics replaced (and restored).

Expected values come from the physics by hand: the back focal point
f = nR/(2(n − 1)) of a ball lens (SPEC §3.1), a half-space cut of a cap through its
centre (half of it, by symmetry), a Lambertian disc's on-axis intensity P/π (SPEC §10:
4× a point light's P/(4π)).
"""

from __future__ import annotations

import math

import pytest

# The light pipeline: AUTO builds lights here (the Caustic layer: test_blender_layer.py).
pytestmark = [pytest.mark.blender, pytest.mark.usefixtures("auto_builds_lights")]

bpy = pytest.importorskip("bpy")

from blender_scene_helpers import (  # noqa: E402
    add_point_light,
    add_sphere,
    generate,
    glass_material,
    lens_lights,
)


def set_engine(engine):
    """EEVEE's identifier was BLENDER_EEVEE_NEXT before 5.0 (SPEC §9)."""
    if engine == "BLENDER_EEVEE" and bpy.app.version < (5, 0, 0):
        engine = "BLENDER_EEVEE_NEXT"
    bpy.context.scene.render.engine = engine


def floor(z):
    """A floor (a receiver in the scene: a real image above it is drawn at the image,
    not as a far-away beam)."""
    bpy.ops.mesh.primitive_plane_add(size=20, location=(0.0, 0.0, z))


def ball(location=(0.0, 0.0, 0.0), radius=0.5):
    return add_sphere("Ball", location, radius=radius, material=glass_material(ior=1.5))


def energy_of(lights):
    return sum(ll.data.energy for ll in lights)


# --------------------------------------------------------------------------- light types


def test_a_sun_over_a_ball_makes_one_lens_light_at_the_back_focal_point(empty_blend):
    bpy.context.scene.lens_lights.energy_model = "PHYSICAL"  # drawn from the paraxial image
    floor(0.0)
    ball((0.0, 0.0, 2.0), 0.5)
    sun = add_point_light("Sun", (5.0, 5.0, 9.0), energy=3.0, kind="SUN")  # −Z: straight down
    sun.data.angle = 0.0
    level, message, figures = generate()
    (ll,) = lens_lights()
    f = 1.5 * 0.5 / (2 * (1.5 - 1))  # 0.75 from the centre, along the sun
    assert tuple(ll.location) == pytest.approx((0.0, 0.0, 2.0 - f), abs=1e-4)
    assert ll.lens_lights.source_light == "Sun" and ll.data.energy > 0
    assert "1 light × 1 lens" in message


def test_a_spot_whose_cone_edge_cuts_the_lens_in_half_gives_half_the_power(empty_blend):
    bpy.context.scene.lens_lights.energy_model = "PHYSICAL"
    ball()
    add_point_light("Point", (0.0, 0.0, 5.0), energy=1000.0)
    generate()
    point_energy = energy_of(lens_lights())
    bpy.data.objects.remove(bpy.data.objects["Point"])
    # A 180° spot aimed sideways: its edge is the horizontal great circle through
    # the lens's centre direction, which halves the lens's cap exactly.
    spot = add_point_light("Spot", (0.0, 0.0, 5.0), energy=1000.0, kind="SPOT")
    spot.data.spot_size, spot.data.spot_blend = math.pi, 0.0
    spot.rotation_euler = (0.0, math.pi / 2, 0.0)  # −Z → −X
    generate()
    (ll,) = lens_lights()
    assert energy_of([ll]) == pytest.approx(0.5 * point_energy, rel=0.02)
    # turned away from the lens: nothing
    spot.rotation_euler = (0.0, math.pi, 0.0)  # −Z → +Z
    level, message, figures = generate()
    assert figures["created"] == 0 and "outside" in message


def test_a_disk_area_light_makes_a_lens_light_four_times_a_point_light(empty_blend):
    bpy.context.scene.lens_lights.energy_model = "PHYSICAL"
    floor(-3.0)
    ball()
    add_point_light("Point", (0.0, 0.0, 4.0), energy=100.0)
    generate()
    (point_ll,) = lens_lights()
    point_energy = point_ll.data.energy
    bpy.data.objects.remove(bpy.data.objects["Point"])
    area = add_point_light("Panel", (0.0, 0.0, 4.0), energy=100.0, kind="AREA")
    area.data.shape, area.data.size = "DISK", 0.2
    generate()
    (ll,) = lens_lights()
    assert ll.location.z < 0 and abs(ll.location.x) < 1e-6  # a real image below
    # Lambertian on its axis: P/π = 4 × P/(4π); the disc's 0.1 radius at 4 m: < 0.1 %
    assert ll.data.energy == pytest.approx(4 * point_energy, rel=0.01)


def test_what_is_not_modelled_is_named(empty_blend):
    ball()
    area = add_point_light("Narrow panel", (0.0, 0.0, 4.0), energy=100.0, kind="AREA")
    area.data.spread = math.radians(30.0)
    add_point_light("Dark spot", (0.0, 0.0, 4.0), energy=0.0, kind="SPOT")
    gobo = add_point_light("Gobo", (1.0, 0.0, 4.0), energy=100.0)
    _give_nodes(gobo.data)
    level, message, figures = generate()
    notes = dict(figures["light_notes"])
    assert notes["Narrow panel"].startswith("its spread (30°")
    assert notes["Dark spot"] == "spot light without power (0 W)"
    # EEVEE (this scene's engine) does not evaluate the gobo's node tree: named; in
    # Cycles its constant strength is read (×3), no note (issue 28)
    assert notes["Gobo"].startswith("its light nodes: the render engine (EEVEE)")
    assert "not modelled: " in message and "Narrow panel: its spread" in message
    assert "Ball" not in notes and len(notes) == 3
    assert figures["created"] == 2  # the panel and the gobo light
    set_engine("CYCLES")
    level, message, figures = generate()
    assert "Gobo" not in dict(figures["light_notes"])


def _give_nodes(light_data):
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        light_data.use_nodes = True  # (deprecated in 5.x, still what makes the tree)
    # a plain tree (every 5.x light has one) changes nothing; a stronger emission is read
    light_data.node_tree.nodes["Emission"].inputs["Strength"].default_value = 3.0


# --------------------------------------------------------------------------- near field


@pytest.mark.parametrize("engine", ["CYCLES", "BLENDER_EEVEE"])
def test_the_resting_marble_gets_a_lens_light_above_the_floor(empty_blend, engine):
    set_engine(engine)  # AUTO: Exact profile / Fitted
    bpy.ops.mesh.primitive_plane_add(size=2)
    marble = ball((0.0, 0.0, 0.01), 0.01)  # a 2 cm marble resting on the table
    add_point_light("Lamp", (0.0, 0.0, 1.0), energy=100.0)
    generate()
    (ll,) = lens_lights()
    # the paraxial image (1.5 cm below the centre for D = 0.99) lies under the
    # table: the light stays above it
    assert 0.0 < ll.location.z < 0.02  # above the table, in the marble
    assert abs(ll.location.x) < 1e-6 and abs(ll.location.y) < 1e-6
    # light and shadow linking exclude the marble (it sits inside it)
    for coll in (ll.light_linking.receiver_collection, ll.light_linking.blocker_collection):
        assert list(coll.objects) == [marble]
        assert [m.light_linking.link_state for m in coll.collection_objects] == ["EXCLUDE"]


# --------------------------------------------------------------------------- no double light


def test_cycles_caustics_are_replaced_and_restored_by_clear(empty_blend):
    set_engine("CYCLES")
    scene = bpy.context.scene
    lens = ball((0.0, 0.0, 1.0))
    other = add_sphere("Opaque", (3.0, 0.0, 1.0))
    lens.cycles.is_caustics_caster = other.cycles.is_caustics_caster = True
    add_point_light("Lamp", (0.0, 0.0, 4.0))
    assert scene.cycles.caustics_refractive is True  # Blender's default
    for _ in range(2):  # a second Generate keeps the record
        level, message, _ = generate()
        assert scene.cycles.caustics_refractive is False
        assert lens.cycles.is_caustics_caster is False
        assert other.cycles.is_caustics_caster is True  # no lens light: untouched
        assert "refractive caustics (scene), shadow caustics caster of Ball" in message
    assert bpy.ops.lens_lights.clear() == {"FINISHED"}
    assert scene.cycles.caustics_refractive is True and lens.cycles.is_caustics_caster is True
    assert scene.lens_lights.last_report.endswith(
        "Cycles' own caustics back as they were: refractive caustics (scene) on, "
        "shadow caustics caster of Ball on"
    )
    assert len(scene.lens_lights.replaced) == 0

    # a value the user changes after Generate is theirs: Clear leaves it
    generate()
    lens.cycles.is_caustics_caster = True
    scene.cycles.caustics_refractive = False
    generate()  # restores (refractive: True again), then replaces (the caster too)
    assert scene.cycles.caustics_refractive is False and lens.cycles.is_caustics_caster is False
    bpy.ops.lens_lights.clear()
    assert scene.cycles.caustics_refractive is True and lens.cycles.is_caustics_caster is True


def test_with_replace_off_nothing_changes_and_the_double_light_is_named(empty_blend):
    set_engine("CYCLES")
    scene = bpy.context.scene
    scene.lens_lights.replace_cycles_caustics = False
    ball((0.0, 0.0, 1.0))
    add_point_light("Lamp", (0.0, 0.0, 4.0))
    level, message, _ = generate()
    assert scene.cycles.caustics_refractive is True
    assert level == "WARNING" and "rendered twice" in message


def test_undo_restores_the_cycles_settings(empty_blend):
    set_engine("CYCLES")
    ball((0.0, 0.0, 1.0))
    add_point_light("Lamp", (0.0, 0.0, 4.0))
    bpy.ops.ed.undo_push(message="before")
    bpy.ops.lens_lights.generate("EXEC_DEFAULT", True)  # True: push an undo step
    assert bpy.context.scene.cycles.caustics_refractive is False
    bpy.ops.ed.undo()
    assert bpy.context.scene.cycles.caustics_refractive is True
    bpy.ops.ed.redo()
    bpy.ops.lens_lights.clear("EXEC_DEFAULT", True)
    assert bpy.context.scene.cycles.caustics_refractive is True
    bpy.ops.ed.undo()
    assert bpy.context.scene.cycles.caustics_refractive is False


def test_eevee_before_4_3_names_the_lens_lights_inside_their_lens():
    from lens_lights.core.report.message import linking_note

    assert "ignores light and shadow linking" in linking_note((4, 2, 23), "BLENDER_EEVEE_NEXT", 1)
    assert linking_note((4, 3, 0), "BLENDER_EEVEE_NEXT", 1) == ""
    assert linking_note((4, 2, 23), "CYCLES", 1) == ""
    assert linking_note((4, 2, 23), "BLENDER_EEVEE_NEXT", 0) == ""


def test_linking_report_names_the_lenses_and_pairs():
    """Lenses left unlinked and lenses sharing a group with a beam that reaches them
    are named; Blender's own console line is passed on."""
    from lens_lights.core.report.message import linking_groups_note

    assert linking_groups_note([], []) == ""
    note = linking_groups_note(["Ball 1", "Ball 2"], [("Lens light L > A", "B")], ["Maximum x"], 3)
    assert note.startswith("2 lenses (Ball 1, Ball 2): lens lights not excluded")
    assert "(3 by your own linking)" in note
    assert "1 lens light share a linking group with a lens their beam reaches" in note
    assert "Lens light L > A → B" in note and note.endswith("Blender says: Maximum x")
