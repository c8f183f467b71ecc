"""Issue 28 item 4: a lens light the user duplicated (Shift+D: object and data copied;
Alt+D: data shared), renamed or moved into a collection of theirs is the user's: Generate,
Clear and live update keep it, working (its lens still out of its light and shadow
linking, its caustic unchanged in a render), and the report says the lens now has two.
(blender/build/ownership.py)"""

import bpy
import numpy as np
import pytest
from blender_scene_helpers import (
    add_point_light,
    add_sphere,
    generate,
    glass_material,
    lens_lights,
    set_engine,
)

pytestmark = [pytest.mark.blender, pytest.mark.usefixtures("auto_builds_lights")]

ORIGINAL = "Lens light Lamp > Marble"


def resting_marble():
    """A marble resting on a table, a lamp above to the side: in Cycles its lens light
    (Exact profile, near field) sits at the marble's centre, so the marble must be out
    of its light and shadow linking (else the glass shadows it)."""
    set_engine("CYCLES")
    bpy.ops.mesh.primitive_plane_add(size=8)
    bpy.context.object.name = "Table"
    ball = add_sphere("Marble", (0.0, 0.0, 0.5), material=glass_material())
    lamp = add_point_light("Lamp", (1.0, 0.0, 4.0), energy=1000.0, radius=0.1)
    return ball, lamp


def members(coll) -> dict:
    """A linking collection's objects and their link states."""
    return {
        o.name: m.light_linking.link_state
        for o, m in zip(coll.objects, coll.collection_objects, strict=True)
    }


def linking(ob):
    ll = ob.light_linking
    return ll.receiver_collection, ll.blocker_collection


def kept(ob) -> bool:
    """Flagged the user's (getattr: the same test runs on the code before the flag)."""
    return bool(getattr(ob.lens_lights, "kept", False))


def made_now():
    return [o for o in lens_lights() if not kept(o)]


def images_of(data) -> list:
    return [n.image for n in data.node_tree.nodes if n.type == "TEX_IMAGE" and n.image]


def duplicate(ob, name, linked_data=False):
    """What Shift+D (`linked_data`: Alt+D) does to a lens light: a copy of the object
    (custom properties and linking included) in the original's collections, with a
    copy of its data (or the same data)."""
    dup = ob.copy()
    if not linked_data:
        dup.data = ob.data.copy()
    dup.name = name
    for coll in ob.users_collection:
        coll.objects.link(dup)
    return dup


@pytest.mark.parametrize("linked_data", [False, True], ids=["shift_d", "alt_d"])
def test_a_duplicated_lens_light_keeps_its_linking_through_generate_and_clear(
    empty_blend, linked_data
):
    from lens_lights.blender.build.marks import COLLECTION_MARK

    resting_marble()
    generate()
    (ours,) = lens_lights()
    rc, bc = linking(ours)
    assert rc is not None and bc is rc and members(rc) == {"Marble": "EXCLUDE"}
    dup = duplicate(ours, "My copy", linked_data)
    data, energy = dup.data, dup.data.energy
    images = images_of(data)
    assert images  # the Exact profile's table

    level, message, figures = generate()
    assert bpy.data.objects.get("My copy") is dup
    # the copy is no primary: one light, one lens, one lens light
    (new,) = [o for o in lens_lights() if o is not dup]
    assert new.name == ORIGINAL and figures["created"] == 1 and figures["primaries"] == 1
    assert new.data is not data  # (Alt+D: the shared data stays with the user's light)
    assert dup.data is data and data.energy == energy
    # its lens still out of its light and shadow linking, in a collection of the user's
    rc, bc = linking(dup)
    assert rc is not None and bc is rc and members(rc) == {"Marble": "EXCLUDE"}
    assert rc.get(COLLECTION_MARK) is None and kept(dup)
    assert members(linking(new)[0]) == {"Marble": "EXCLUDE"}  # ours: linked as before
    assert level == "WARNING"
    assert (
        f"Marble has 2 lens lights: '{ORIGINAL}' (made now) and 'My copy' (yours, kept)" in message
    )

    assert bpy.ops.lens_lights.clear() == {"FINISHED"}
    assert lens_lights() == [dup] and dup.data is data and data.energy == energy
    assert linking(dup) == (rc, rc) and members(rc) == {"Marble": "EXCLUDE"}
    # the profile image its node tree reads is still there (not removed as unused)
    assert images_of(dup.data) == images and all(i.name in bpy.data.images for i in images)
    report = bpy.context.scene.lens_lights.last_report
    assert "Removed 1 lens light" in report
    assert "Marble has 1 lens light: 'My copy' (yours, kept)" in report
    # and the next Generate still makes the extension's own, the copy untouched
    generate()
    assert [o.name for o in made_now()] == [ORIGINAL] and linking(dup) == (rc, rc)


def test_the_copys_caustic_does_not_change(empty_blend, tmp_path):
    """Rendered (Cycles, direct light, 24 px): the copy alone lights the table through
    the marble as before Generate and after Clear (before the fix it lost its linking:
    the marble shadowed it)."""
    from measuring_scene import (
        add_diffuse_floor,
        add_glass_ball,
        add_top_camera,
        direct_light_only,
        new_measuring_scene,
        render_grey,
    )
    from measuring_scene import add_point_light as measuring_lamp

    sc = new_measuring_scene("CYCLES", 24)
    direct_light_only(sc, 16)
    add_diffuse_floor(6.0)
    add_glass_ball(0.5, (0.0, 0.0, 0.5), name="Marble")
    lamp = measuring_lamp((1.0, 0.0, 4.0), 1000.0, radius=0.1)
    add_top_camera(-0.3, 0.0, 5.0, view=2.0)
    generate()
    (ours,) = lens_lights()
    dup = duplicate(ours, "My copy")

    def copy_alone(name):
        others = [lamp] + [o for o in lens_lights() if o is not dup]
        for o in others:
            o.hide_render = True
        try:
            return render_grey(sc, tmp_path / f"{name}.exr")
        finally:
            for o in others:
                o.hide_render = False

    before = copy_alone("before")
    assert before.mean() > 0.02  # the copy's caustic is there
    generate()
    after_generate = copy_alone("generate")
    bpy.ops.lens_lights.clear()
    after_clear = copy_alone("clear")
    for img in (after_generate, after_clear):
        assert np.abs(img - before).max() <= 1e-6 * max(float(before.max()), 1.0)


def test_a_renamed_lens_light_is_kept_and_a_new_one_made(empty_blend):
    resting_marble()
    generate()
    (ours,) = lens_lights()
    ours.name = "My marble light"
    level, message, figures = generate()
    kept_one = bpy.data.objects.get("My marble light")
    assert kept_one is ours and kept(kept_one)
    (new,) = made_now()
    assert new.name == ORIGINAL and new is not kept_one
    assert members(linking(kept_one)[0]) == {"Marble": "EXCLUDE"}
    assert (
        f"Marble has 2 lens lights: '{ORIGINAL}' (made now) and 'My marble light' "
        "(yours, kept)" in message
    )
    assert figures["kept"] == ["My marble light"]
    # the Object panel says whose it is (the extension's own: not)
    from types import SimpleNamespace

    from blender_scene_helpers import draw_panel
    from lens_lights.blender.ui.panel import VIEW3D_PT_lens_lights_object

    def says_yours(ob):
        ctx = SimpleNamespace(scene=bpy.context.scene, object=ob, region=None)
        log = draw_panel(VIEW3D_PT_lens_lights_object, ctx)
        return any(kind == "label" and text.startswith("Yours:") for kind, text in log)

    assert says_yours(kept_one) and not says_yours(new)


@pytest.mark.parametrize("also", [False, True], ids=["moved", "linked_too"])
def test_a_lens_light_moved_into_a_users_collection_is_kept(empty_blend, also):
    resting_marble()
    generate()
    (ours,) = lens_lights()
    mine = bpy.data.collections.new("My lights")
    bpy.context.scene.collection.children.link(mine)
    mine.objects.link(ours)
    if not also:  # M: moved; Ctrl+L: linked into the user's as well
        bpy.data.collections["Lens Lights"].objects.unlink(ours)
    level, message, figures = generate()
    assert bpy.data.objects.get(ORIGINAL) is ours and kept(ours)
    assert ours.name in mine.objects
    (new,) = made_now()
    assert [c.name for c in new.users_collection] == ["Lens Lights"]
    assert f"'{new.name}' (made now) and '{ORIGINAL}' (yours, kept)" in message
    bpy.ops.lens_lights.clear()
    assert lens_lights() == [ours] and ours.name in mine.objects
    assert members(linking(ours)[0]) == {"Marble": "EXCLUDE"}


def test_live_update_leaves_the_users_copy_alone(empty_blend):
    """A linked duplicate (Alt+D) shares the light data: live update moving the
    extension's light must not write the user's (its power, its node tree)."""
    _, lamp = resting_marble()
    scene = bpy.context.scene
    lamp.location = (1.0, 0.0, 4.0)
    lamp.keyframe_insert("location", frame=1)
    lamp.location = (-0.5, 0.8, 3.0)
    lamp.keyframe_insert("location", frame=5)
    scene.frame_set(1)
    scene.lens_lights.live_update = True  # the lights are made at once
    (ours,) = lens_lights()
    dup = duplicate(ours, "My copy", linked_data=True)
    data = dup.data
    energy = data.energy
    nodes = [(n.name, n.bl_idname) for n in data.node_tree.nodes]
    where = (tuple(dup.location), tuple(dup.rotation_quaternion))
    scene.frame_set(5)
    (now,) = [o for o in lens_lights() if o is not dup]
    # ours followed the lamp (at the marble's centre: it turned), in place
    assert now is ours and tuple(ours.rotation_quaternion) != pytest.approx(where[1], abs=1e-3)
    assert ours.data is not data and ours.data.energy != pytest.approx(energy, rel=1e-4)
    assert dup.data is data and data.energy == energy
    assert [(n.name, n.bl_idname) for n in data.node_tree.nodes] == nodes
    assert (tuple(dup.location), tuple(dup.rotation_quaternion)) == where
    assert members(linking(dup)[0]) == {"Marble": "EXCLUDE"}
    scene.lens_lights.live_update = False


def test_bake_keeps_the_users_copy_and_says_so(empty_blend):
    resting_marble()
    scene = bpy.context.scene
    scene.lens_lights.energy_model = "PHYSICAL"  # (a cheap bake: no profile tables)
    scene.frame_start, scene.frame_end = 1, 2
    generate()
    (ours,) = lens_lights()
    assert members(linking(ours)[0]) == {"Marble": "EXCLUDE"}
    dup = duplicate(ours, "My copy")
    energy = dup.data.energy
    assert bpy.ops.lens_lights.bake() == {"FINISHED"}
    assert bpy.data.objects.get("My copy") is dup and dup.data.energy == energy
    assert members(linking(dup)[0]) == {"Marble": "EXCLUDE"} and kept(dup)
    assert dup.animation_data is None or dup.animation_data.action is None  # not keyed
    assert "'My copy' (yours, kept)" in scene.lens_lights.last_report


def test_a_duplicated_or_renamed_caustic_layer_is_kept(empty_blend):
    """EEVEE's caustic layer (a mesh on the receiver): a copy of it (Shift+D: its mesh
    copied) and a renamed one are the user's too: kept with their mesh and material,
    named in the report; the layer made now is the only one listed."""
    from blender_scene_helpers import basic_scene

    basic_scene()
    set_engine("BLENDER_EEVEE")
    bpy.context.scene.lens_lights.energy_model = "CAUSTIC_LAYER"
    generate()
    (layer,) = lens_lights()
    assert layer.type == "MESH"
    made_name = layer.name
    dup = duplicate(layer, "My layer")
    material = dup.data.materials[0]
    layer.name = "My renamed layer"
    level, message, figures = generate()
    (new,) = [o for o in lens_lights() if o not in (dup, layer)]
    assert new.name == made_name
    assert bpy.data.objects.get("My layer") is dup and dup.data.materials[0] is material
    assert bpy.data.objects.get("My renamed layer") is layer
    assert (
        f"Floor has 3 caustic layers: '{made_name}' (made now), 'My layer' (yours, kept) "
        "and 'My renamed layer' (yours, kept)" in message
    )
    bpy.ops.lens_lights.clear()
    assert lens_lights() == sorted([dup, layer], key=lambda o: o.name)
    assert material.name in bpy.data.materials and dup.data.materials[0] is material


def test_a_lens_light_linked_from_another_file_is_kept_unchanged(empty_blend, tmp_path):
    """A lens light linked from a library (another shot's file) carries the mark but
    is read-only: kept, not written (not flagged, linking untouched), named in the
    report, and no primary light."""
    resting_marble()
    generate()
    (ours,) = lens_lights()
    path = tmp_path / "shot.blend"
    bpy.data.libraries.write(str(path), {ours}, fake_user=True)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    resting_marble()
    with bpy.data.libraries.load(str(path), link=True) as (_, into):
        into.objects = [ORIGINAL]
    linked = bpy.data.objects[ORIGINAL]
    assert linked.library is not None
    bpy.context.scene.collection.objects.link(linked)
    before = linking(linked)
    level, message, figures = generate()
    assert figures["created"] == 1 and figures["primaries"] == 1, message
    assert linking(linked) == before and not kept(linked)
    assert f"'{ORIGINAL}' (yours, kept)" in message
    assert bpy.ops.lens_lights.clear() == {"FINISHED"}
    assert lens_lights() == [linked]
