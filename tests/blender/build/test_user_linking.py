"""Issue 28 item 7: a user light's own light and shadow linking is kept by its lens
lights. A lamp whose linking leaves the table out lights no table, and neither does
its lens light: the lens light's receiver collection is the user's (each object in
it with the user's state) with its lens excluded as before; shadow linking alike.
The user's own collections are never changed, Clear removes what was made, and a
caustic layer, which cannot keep a light's linking, leaves such a light out by name.

Expected: the memberships of the collections the test builds (by hand)."""

import bpy
import pytest
from blender_scene_helpers import (
    add_point_light,
    add_sphere,
    generate,
    glass_material,
    lens_lights,
    set_engine,
)

pytestmark = [pytest.mark.blender]


def _states(coll) -> dict:
    return {
        o.name: m.light_linking.link_state
        for o, m in zip(coll.objects, coll.collection_objects, strict=True)
    }


def _resting_marble_scene():
    """A 2 cm marble resting on a table (its lens light sits inside it: linked to
    leave it out), a wall beside, and the user's lamp above."""
    set_engine("CYCLES")  # AUTO: Exact profile
    bpy.ops.mesh.primitive_plane_add(size=2.0)
    bpy.context.object.name = "Table"
    bpy.ops.mesh.primitive_plane_add(size=2.0, location=(1.0, 0.0, 1.0), rotation=(0, 1.5708, 0))
    bpy.context.object.name = "Wall"
    add_sphere("Marble", (0.0, 0.0, 0.01), radius=0.01, material=glass_material())
    return add_point_light("Lamp", (0.0, 0.0, 1.0), energy=100.0)


def _user_collection(name, **states):
    coll = bpy.data.collections.new(name)
    for ob_name in states:
        coll.objects.link(bpy.data.objects[ob_name])
    for ob, member in zip(coll.objects, coll.collection_objects, strict=True):
        member.light_linking.link_state = states[ob.name]
    return coll


def test_a_lamp_that_leaves_the_table_out_makes_a_lens_light_that_does_too(empty_blend):
    lamp = _resting_marble_scene()
    lights_out = _user_collection("No table", Table="EXCLUDE")
    shadows_in = _user_collection("Wall shadows", Wall="INCLUDE")
    lamp.light_linking.receiver_collection = lights_out
    lamp.light_linking.blocker_collection = shadows_in
    level, message, figures = generate()
    (ll,) = lens_lights()
    receivers = ll.light_linking.receiver_collection
    blockers = ll.light_linking.blocker_collection
    # the user's exclusion and the lens' own, together
    assert _states(receivers) == {"Table": "EXCLUDE", "Marble": "EXCLUDE"}, message
    assert _states(blockers) == {"Wall": "INCLUDE", "Marble": "EXCLUDE"}
    assert "linking is not copied" not in message
    assert figures["linking"]["user_linked"] == 1
    # the user's collections are as they were, and Clear leaves them
    assert _states(lights_out) == {"Table": "EXCLUDE"}
    assert _states(shadows_in) == {"Wall": "INCLUDE"}
    made = {receivers.name, blockers.name}
    assert bpy.ops.lens_lights.clear() == {"FINISHED"}
    assert not made & {c.name for c in bpy.data.collections}
    assert lamp.light_linking.receiver_collection == lights_out
    assert _states(lights_out) == {"Table": "EXCLUDE"}


def test_regenerating_after_the_user_changes_the_linking_follows_it(empty_blend):
    lamp = _resting_marble_scene()
    coll = _user_collection("Lit", Table="INCLUDE")
    lamp.light_linking.receiver_collection = coll
    generate()
    (ll,) = lens_lights()
    assert _states(ll.light_linking.receiver_collection) == {
        "Table": "INCLUDE",
        "Marble": "EXCLUDE",
    }
    assert ll.light_linking.blocker_collection is not coll  # the user set none: the lens'
    assert _states(ll.light_linking.blocker_collection) == {"Marble": "EXCLUDE"}
    lamp.light_linking.receiver_collection = None  # the user drops it
    generate()
    (ll,) = lens_lights()
    assert _states(ll.light_linking.receiver_collection) == {"Marble": "EXCLUDE"}
    left = [c.name for c in bpy.data.collections if c.name.startswith("Lens link: Lit")]
    assert left == []  # the combined collection went with it


def test_a_caustic_layer_leaves_a_linked_lamp_out_by_name(empty_blend):
    """EEVEE's caustic layer lies on every receiver the beam reaches: it cannot keep
    the lamp's linking, so the pair is skipped with that reason (it drew the caustic
    on the excluded table)."""
    lamp = _resting_marble_scene()
    set_engine("BLENDER_EEVEE")
    bpy.context.scene.lens_lights.energy_model = "CAUSTIC_LAYER"
    lamp.light_linking.receiver_collection = _user_collection("No table", Table="EXCLUDE")
    level, message, figures = generate()
    assert lens_lights() == []
    assert "Lamp × Marble: the light has light or shadow linking of its own" in message
    assert figures["skipped_by_reason"] == {
        "the light's own linking (no caustic layer keeps it)": 1
    }


def test_in_cycles_the_excluded_table_gets_no_caustic(empty_blend, tmp_path):
    """A render (Cycles, direct light only: the lens light is the only caustic): the
    lamp leaves the floor out, so the floor under the marble is black, caustic
    included; without the user's linking the same render shows the caustic."""
    from measuring_scene import (
        add_glass_ball,
        build_measuring_scene,
        direct_light_only,
        render_grey,
    )

    ms = build_measuring_scene(
        "CYCLES",
        resolution=32,
        floor_size=2.0,
        view=0.1,
        camera_height=1.0,
        lamp=dict(location=(0.0, 0.0, 1.0), power=100.0),
    )
    add_glass_ball(0.01, (0.0, 0.0, 0.01), name="Marble")
    direct_light_only(ms.scene, 16)
    ms.lamp.light_linking.receiver_collection = _user_collection("No floor", Floor="EXCLUDE")
    generate()
    assert len(lens_lights()) == 1
    dark = render_grey(ms.scene, str(tmp_path / "linked.exr"))
    assert float(dark.max()) == 0.0
    ms.lamp.light_linking.receiver_collection = None
    generate()
    lit = render_grey(ms.scene, str(tmp_path / "plain.exr"))
    assert float(lit.max()) > 1.0  # the caustic (and the lamp's own light) are there
