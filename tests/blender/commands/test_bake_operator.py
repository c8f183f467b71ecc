"""`lens_lights.bake` in Blender (bpy module, no renders): on every frame the baked
lights are what Generate makes on that frame; a light that exists on some frames
only is keyed hidden on the others; Exact profile lights share one image over the
frames; the Caustic layer keeps one object per receiver and lamps; Clear removes the
baked lights, their actions and images; bad ranges change nothing; one undo step
puts the scene back; the user's data is untouched."""

import math

import bpy
import numpy as np
import pytest
from blender_scene_helpers import (
    add_point_light,
    add_sphere,
    caustic_layers,
    draw_panel,
    glass_material,
    lens_lights,
    set_engine,
    snapshot,
    snapshot_diff,
)

pytestmark = pytest.mark.blender


def linear(ob, path, values, index=-1):
    """Key `ob.path` to values[k] on frame k + 1."""
    bpy.context.preferences.edit.keyframe_new_interpolation_type = "LINEAR"
    for k, v in enumerate(values):
        setattr(ob, path, v)
        ob.keyframe_insert(path, index=index, frame=k + 1)


def constant(ob, path, values):
    bpy.context.preferences.edit.keyframe_new_interpolation_type = "CONSTANT"
    for k, v in enumerate(values):
        setattr(ob, path, v)
        ob.keyframe_insert(path, frame=k + 1)


def two_lamps_scene(engine="CYCLES", model="FITTED"):
    """A glass ball, a floor, lamp A moving over frames 1–3, lamp B hidden for the
    render on frame 2 only."""
    sc = bpy.context.scene
    set_engine(engine)
    sc.lens_lights.energy_model = model
    sc.frame_start, sc.frame_end = 1, 3
    add_sphere("Marble", (0.0, 0.0, 1.0), material=glass_material())
    bpy.ops.mesh.primitive_plane_add(size=20)
    a = add_point_light("A", (0.0, 0.0, 4.0))
    b = add_point_light("B", (1.0, 0.0, 4.0))
    linear(a, "location", [(0.0, 0.0, 4.0), (-0.5, 0.0, 4.5), (-1.0, 0.0, 5.0)])
    constant(b, "hide_render", [False, True, False])
    sc.frame_set(1)
    return sc


def state(ob):
    """The keyed values (the rotation as a matrix: q and −q are one rotation)."""
    d = ob.data
    rot = ob.rotation_quaternion.normalized().to_matrix()
    return [
        *ob.location,
        *(x for row in rot for x in row),
        *ob.scale,
        d.energy,
        *d.color,
        d.spot_size,
        d.spot_blend,
        d.shadow_soft_size,
    ]


def generated_on(frame):
    """{(primary, lens): state} of Generate's lights on `frame` (then cleared)."""
    from lens_lights.blender.commands.generate import generate

    bpy.context.scene.frame_set(frame)
    generate(bpy.context)
    out = {(o.lens_lights.source_light, o.lens_lights.source_lens): state(o) for o in lens_lights()}
    bpy.ops.lens_lights.clear()
    return out


def baked_on(frame):
    bpy.context.scene.frame_set(frame)
    return {
        (o.lens_lights.source_light, o.lens_lights.source_lens): state(o)
        for o in lens_lights()
        if not o.hide_render
    }


def test_bake_equals_generate_on_every_frame(empty_blend):
    sc = two_lamps_scene()
    expected = {f: generated_on(f) for f in (1, 2, 3)}
    assert set(expected[1]) == {("A", "Marble"), ("B", "Marble")}
    assert set(expected[2]) == {("A", "Marble")}  # B is not rendered on frame 2
    sc.frame_set(2)
    assert bpy.ops.lens_lights.bake() == {"FINISHED"}
    assert sc.frame_current == 2  # put back
    baked = lens_lights()
    assert len(baked) == 2  # one object per key, not per frame
    for f in (1, 2, 3):
        got = baked_on(f)
        assert set(got) == set(expected[f]), f
        for key, values in expected[f].items():
            assert got[key] == pytest.approx(values, rel=1e-5, abs=1e-6), (f, key)
    b = next(o for o in baked if o.lens_lights.source_light == "B")
    for f, hidden in ((1, False), (2, True), (3, False)):
        sc.frame_set(f)
        assert (b.hide_render, b.hide_viewport) == (hidden, hidden)
    # stock data only: actions, no drivers
    for o in baked:
        assert o.animation_data.action is not None and not o.animation_data.drivers
        assert o.data.animation_data.action is not None


def test_panel_has_the_bake_button(empty_blend):
    from types import SimpleNamespace

    from lens_lights.blender.commands.bake import LENS_LIGHTS_OT_bake
    from lens_lights.blender.ui.panel import VIEW3D_PT_lens_lights

    log = draw_panel(VIEW3D_PT_lens_lights, SimpleNamespace(scene=bpy.context.scene, object=None))
    assert ("operator", "lens_lights.bake") in log
    assert "UNDO" in LENS_LIGHTS_OT_bake.bl_options


def test_bad_range_changes_nothing(empty_blend):
    two_lamps_scene()
    before = snapshot()
    with pytest.raises(RuntimeError, match="ends before it starts"):
        bpy.ops.lens_lights.bake(frame_start=5, frame_end=2)
    with pytest.raises(RuntimeError, match="ends before it starts"):  # no window: at once
        bpy.ops.lens_lights.bake("INVOKE_DEFAULT", frame_start=5, frame_end=2)
    assert lens_lights() == [] and snapshot_diff(before, snapshot()) == []


def test_cancel_after_some_frames_changes_nothing(empty_blend):
    """What Esc does in the modal bake: frames planned, then cancelled."""
    from lens_lights.blender.commands.bake import Baker

    sc = two_lamps_scene()
    sc.frame_set(3)
    before = snapshot()
    baker = Baker(bpy.context, 1, 3)
    baker.plan_next()
    baker.plan_next()
    assert not baker.done and sc.frame_current == 2  # (frame 2 planned last)
    baker.cancel()
    assert sc.frame_current == 3
    assert lens_lights() == [] and snapshot_diff(before, snapshot()) == []


def test_exact_profile_bake_one_image_clear_and_undo(empty_blend):
    sc = two_lamps_scene(model="EXACT_PROFILE")
    sc.frame_end = 6
    # D/R of A: 6.0 … 7.2 (D = 3 … 3.6, R = 0.5); B's 6.32 is within
    linear(bpy.data.objects["A"], "location", [(0, 0, 4.0 + 0.12 * k) for k in range(6)])
    sc.frame_set(1)
    actions_before = set(bpy.data.actions)
    bpy.ops.ed.undo_push(message="scene")
    before = snapshot()
    assert bpy.ops.lens_lights.bake("EXEC_DEFAULT", True) == {"FINISHED"}
    profiles = [i for i in bpy.data.images if i.name.startswith("Lens profile")]
    assert len(profiles) == 1  # two lights, six frames: one stacked table for the lens
    (img,) = profiles
    assert img.packed_file is not None
    # the slices 1.04^45 … 1.04^51, stacked, kept bit for bit (one-channel float EXR)
    from lens_lights.core.animation.light_tracks import profile_slice_table

    tables = [profile_slice_table(1.04**k, 1.5, False) for k in range(45, 52)]
    w, h = img.size
    assert (w, h) == (tables[0].shape[1], 7 * tables[0].shape[0])
    px = np.empty(w * h * 4, dtype=np.float32)
    img.pixels.foreach_get(px)
    assert np.array_equal(px.reshape(h, w, 4)[..., 0], np.concatenate(tables))
    a = next(o for o in lens_lights() if o.lens_lights.source_light == "A")
    nodes = a.data.node_tree.nodes
    assert "Lens bake slice" in nodes and a.data.node_tree.animation_data.action is not None
    # on the grid 1.04^k (k = 45 … 51: 5.84 … 7.39) the slice coordinate is
    # log_1.04(D/R) − 45
    sc.frame_set(1)
    s1 = nodes["Lens bake slice"].outputs[0].default_value
    sc.frame_set(6)
    s6 = nodes["Lens bake slice"].outputs[0].default_value
    assert s1 == pytest.approx(math.log(6.0) / math.log(1.04) - 45, abs=1e-4)
    assert s6 == pytest.approx(math.log(7.2) / math.log(1.04) - 45, abs=1e-4)
    sc.frame_set(1)
    assert set(bpy.data.actions) > actions_before
    assert bpy.ops.lens_lights.clear("EXEC_DEFAULT", True) == {"FINISHED"}
    assert lens_lights() == []
    assert set(bpy.data.actions) == actions_before  # the user's actions stay
    assert not [i for i in bpy.data.images if i.name.startswith("Lens profile")]
    assert snapshot_diff(before, snapshot()) == []
    # bake again, then one undo step puts the scene back
    bpy.ops.lens_lights.bake("EXEC_DEFAULT", True)
    assert len(lens_lights()) == 2
    bpy.ops.ed.undo()
    assert lens_lights() == [] and snapshot_diff(before, snapshot()) == []


def test_caustic_layer_bake_keeps_one_mesh_per_receiver_and_lamps_over_the_frames(empty_blend):
    """Lamps A and B light the floor on frames 1 and 3 (one raster: their caustics
    overlap), A alone on frame 2: two layer objects, not one per frame; the one of
    A and B shows on frames 1 and 3 with the same mesh, the other on frame 2."""
    sc = two_lamps_scene(engine="BLENDER_EEVEE", model="CAUSTIC_LAYER")
    bpy.ops.object.camera_add(location=(0.0, 0.0, 8.0))
    sc.camera = bpy.context.object
    assert bpy.ops.lens_lights.bake() == {"FINISHED"}
    # (and a coarse one of each for the halo out of the camera's view)
    layers = [o for o in caustic_layers() if "coarse" not in o.lens_lights.note]
    assert len(layers) == 2
    shown = {}
    for f in (1, 2, 3):
        sc.frame_set(f)
        (shown[f],) = [o for o in layers if not o.hide_render]
        assert not shown[f].hide_viewport
    assert shown[1] == shown[3] != shown[2]
    assert bpy.ops.lens_lights.clear() == {"FINISHED"}
    assert lens_lights() == []


def test_marble_rolling_on_a_table_bakes_the_near_field_profile(empty_blend):
    """A marble resting on the table (the receiver nearer than the profile's first
    row): Generate puts the Exact-profile light at the lens centre with the near
    field's table; the bake keys that light (its own key variant, its own image)
    and equals Generate on each frame."""
    sc = bpy.context.scene
    set_engine("CYCLES")
    sc.lens_lights.energy_model = "EXACT_PROFILE"
    sc.frame_start, sc.frame_end = 1, 2
    bpy.ops.mesh.primitive_plane_add(size=20)
    marble = add_sphere("Marble", (0.0, 0.0, 0.5), material=glass_material())
    add_point_light("Lamp", (0.0, 0.0, 3.0))
    linear(marble, "location", [(0.0, 0.0, 0.5), (0.4, 0.0, 0.5)])
    sc.frame_set(1)
    expected = {f: generated_on(f) for f in (1, 2)}
    assert bpy.ops.lens_lights.bake() == {"FINISHED"}
    (light,) = lens_lights()
    (img,) = [i for i in bpy.data.images if i.name.startswith("Lens profile")]
    assert " near " in img.name
    for f in (1, 2):
        got = baked_on(f)
        for key, values in expected[f].items():
            assert got[key] == pytest.approx(values, rel=1e-5, abs=1e-6), (f, key)
    # the light sits at the lens centre on each frame
    sc.frame_set(2)
    assert tuple(light.location) == pytest.approx((0.4, 0.0, 0.5), abs=1e-6)


def test_bake_turns_live_update_off(empty_blend):
    """Live update would rebuild the lights on every frame the bake visits and then
    overwrite its keys: the bake turns it off (and says so); a cancel turns it back on."""
    from lens_lights.blender.commands.bake import Baker

    sc = two_lamps_scene()
    sc.lens_lights.live_update = True
    baker = Baker(bpy.context, 1, 2)
    assert not sc.lens_lights.live_update
    baker.cancel()
    assert sc.lens_lights.live_update
    assert bpy.ops.lens_lights.bake() == {"FINISHED"}
    assert not sc.lens_lights.live_update
    assert "Live update turned off" in sc.lens_lights.last_report
    assert len(lens_lights()) == 2
    sc.frame_set(2)  # no live update: the keys drive the lights
    b = next(o for o in lens_lights() if o.lens_lights.source_light == "B")
    assert b.hide_render
