"""A bake knows what it was baked from (issue 28 item 2): move the marble after
baking and the panel says the bake is out of date, names the marble and offers Bake
Again over the baked frames; a render of such a frame prints the warning; live
update turned on after a bake leaves the baked lights, node trees and images
exactly as baked; Clear and Generate end the bake (nothing to warn about)."""

import bpy
import numpy as np
import pytest
from blender_scene_helpers import basic_scene, draw_panel, lens_lights, set_engine

pytestmark = pytest.mark.blender


def baked_scene():
    """Floor, marble, lamp in Cycles (AUTO: the Exact profile), frames 1–3 baked;
    the lamp moves over the frames (so each frame has its own print)."""
    sc = bpy.context.scene
    set_engine("CYCLES")
    sc.frame_start, sc.frame_end = 1, 3
    marble, lamp = basic_scene()
    for f, x in ((1, 0.0), (3, 0.2)):
        lamp.location.x = x
        lamp.keyframe_insert("location", index=0, frame=f)
    sc.frame_set(2)
    assert bpy.ops.lens_lights.bake() == {"FINISHED"}
    assert lens_lights()
    return sc, marble, lamp


@pytest.fixture(autouse=True)
def check_every_draw(monkeypatch, extension):
    """The panel checks again on every update here (on a busy machine a tiny scene's
    check can exceed `RECHECK_ABOVE`, and the panel would keep its last status for a
    moment: a UI nicety, tested on its own below)."""
    from lens_lights.blender.commands import bake_check

    monkeypatch.setattr(bake_check, "RECHECK_ABOVE", float("inf"))


def panel_labels(context):
    from lens_lights.blender.ui.panel import VIEW3D_PT_lens_lights

    log = draw_panel(VIEW3D_PT_lens_lights, context)
    labels = " ".join(text for kind, text in log if kind == "label")
    ops = [p for kind, p in log if kind == "operator props"]
    return labels, ops


def test_the_panel_says_when_the_marble_moved_since_the_bake(empty_blend):
    sc, marble, _lamp = baked_scene()
    labels, ops = panel_labels(bpy.context)
    assert "Baked 1 lens light over frames 1–3" in labels
    assert "out of date" not in labels  # up to date on every frame
    for f in (1, 3):
        sc.frame_set(f)
        assert "out of date" not in panel_labels(bpy.context)[0], f
    marble.location.x += 0.3
    bpy.context.view_layer.update()
    sc.frame_set(2)
    labels, ops = panel_labels(bpy.context)
    # wrapped to the sidebar's width: compare the words
    expected = (
        "The bake (frames 1–3) is out of date at frame 2: Marble moved since it was "
        "baked; Bake again"
    )
    assert " ".join(labels.split()).find(expected) >= 0, labels
    (again,) = [p for p in ops if p.text == "Bake Again"]
    assert (again.idname, again.frame_start, again.frame_end) == ("lens_lights.bake", 1, 3)
    # the marble put back: up to date again
    marble.location.x -= 0.3
    bpy.context.view_layer.update()
    assert "out of date" not in panel_labels(bpy.context)[0]
    # moved again and baked again over the button's frames: up to date
    marble.location.x += 0.3
    bpy.context.view_layer.update()
    assert "out of date" in panel_labels(bpy.context)[0]
    assert bpy.ops.lens_lights.bake(frame_start=1, frame_end=3) == {"FINISHED"}
    for f in (1, 2, 3):
        sc.frame_set(f)
        assert "out of date" not in panel_labels(bpy.context)[0], f


def test_a_lamp_edit_and_an_object_in_the_light_are_named_and_nothing_else(empty_blend):
    from lens_lights.blender.commands import bake_check

    sc, _marble, lamp = baked_scene()
    sc.frame_set(1)
    dg = bpy.context.evaluated_depsgraph_get()
    assert bake_check.check(sc, dg, render=True).changes == []
    # a box 3 m to the side (its near side 2 m from the lamp → marble → floor line):
    # nothing a plan reads changes, nothing is said
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=(3.0, 3.0, 0.5))
    box = bpy.context.object
    box.name = "Box"
    dg = bpy.context.evaluated_depsgraph_get()
    assert bake_check.check(sc, dg, render=True).changes == []
    box.location = (-3.0, 2.0, 0.5)  # moved, still away
    dg = bpy.context.evaluated_depsgraph_get()
    assert bake_check.check(sc, dg, render=True).changes == []
    # the lamp's power, and the box under the marble (in its beam): both named
    lamp.data.energy = 500.0
    box.location = (0.0, 0.0, 1.0)
    dg = bpy.context.evaluated_depsgraph_get()
    status = bake_check.check(sc, dg, render=True)
    assert [(c.name, c.what) for c in status.changes] == [("Box", "added"), ("Lamp", "changed")]
    assert status.text == (
        "The bake (frames 1–3) is out of date at frame 1: Box is new (or shown), Lamp's "
        "light settings changed since it was baked; Bake again"
    )
    assert bake_check.check(sc, dg, frame=4) is None  # outside the bake


def test_a_render_of_an_out_of_date_frame_warns(empty_blend, capfd):
    sc, marble, _lamp = baked_scene()
    sc.render.resolution_x = sc.render.resolution_y = 16
    sc.render.resolution_percentage = 100
    sc.cycles.samples = 1
    bpy.ops.object.camera_add(location=(0.0, -6.0, 3.0), rotation=(1.2, 0.0, 0.0))
    sc.camera = bpy.context.object
    sc.frame_set(2)
    capfd.readouterr()
    bpy.ops.render.render()
    assert "out of date" not in capfd.readouterr().out  # the camera is no input of lights
    marble.location.x += 0.3
    bpy.ops.render.render()
    expected = (
        "Lens Lights: The bake (frames 1–3) is out of date at frame 2: Marble moved since "
        "it was baked; Bake again"
    )
    assert expected in capfd.readouterr().out.splitlines()
    from lens_lights.blender.commands import bake_check

    assert bake_check.LAST_RENDER_WARNING == expected


def baked_state():
    """Every lens light's node tree (each node's input values, the keyed curves'
    points), its data's curves, and the pixels of every image the trees read."""
    out = {}
    for ob in lens_lights():
        nt = ob.data.node_tree
        nodes = {}
        for node in nt.nodes:
            values = []
            for s in node.inputs:
                v = getattr(s, "default_value", None)
                values.append(tuple(v) if hasattr(v, "__len__") else v)
            if node.bl_idname == "ShaderNodeValue":
                values.append(node.outputs[0].default_value)
            image = getattr(node, "image", None)
            if image is not None:
                px = np.empty(len(image.pixels), np.float32)
                image.pixels.foreach_get(px)
                values.append((image.name, px.tobytes()))
            nodes[node.name] = values
        curves = {}
        for idb in (ob, ob.data, nt):
            ad = idb.animation_data
            if ad is not None and ad.action is not None:
                for fc in ad.action.fcurves if hasattr(ad.action, "fcurves") else []:
                    pts = np.empty(2 * len(fc.keyframe_points))
                    fc.keyframe_points.foreach_get("co", pts)
                    curves[(idb.name, fc.data_path, fc.array_index)] = pts.tobytes()
        out[ob.name] = (nodes, curves, tuple(ob.location), ob.data.energy)
    return out


def test_live_update_turned_on_after_a_bake_leaves_it_as_baked(empty_blend):
    sc, _marble, _lamp = baked_scene()
    images = {i.name for i in bpy.data.images}
    before = {}
    for f in (1, 2, 3):
        sc.frame_set(f)
        before[f] = baked_state()
    sc.lens_lights.live_update = True  # the switch's update: would rebuild at once
    for f in (3, 1, 2, 3):
        sc.frame_set(f)
        assert baked_state() == before[f], f
    assert {i.name for i in bpy.data.images} == images
    from lens_lights.blender.ui.panel import VIEW3D_PT_lens_lights

    log = draw_panel(VIEW3D_PT_lens_lights, bpy.context)
    words = " ".join(" ".join(t for k, t in log if k == "label").split())
    assert "Live update is off while a bake exists" in words


def test_clear_and_generate_end_the_bake(empty_blend):
    from lens_lights.blender.commands import bake_check

    sc, marble, _lamp = baked_scene()
    assert bake_check.has_bake(sc)
    marble.location.x += 0.3
    bpy.context.view_layer.update()
    assert bpy.ops.lens_lights.generate() == {"FINISHED"}
    assert not bake_check.has_bake(sc) and sc.lens_lights.baked_from == ""
    assert "out of date" not in panel_labels(bpy.context)[0]
    assert bpy.ops.lens_lights.bake() == {"FINISHED"}
    assert bake_check.has_bake(sc)
    assert bpy.ops.lens_lights.clear() == {"FINISHED"}
    assert not bake_check.has_bake(sc) and sc.lens_lights.baked_from == ""


def test_a_costly_check_is_run_again_only_after_a_wait(empty_blend, monkeypatch):
    """While the user drags in a big scene the panel keeps its last status for ten
    times the last check's cost, then checks again."""
    from lens_lights.blender.commands import bake_check

    sc, marble, _lamp = baked_scene()
    first = bake_check.status(bpy.context)
    assert first is not None and not first.stale
    monkeypatch.setattr(bake_check, "RECHECK_ABOVE", 0.0)
    monkeypatch.setattr(bake_check, "RECHECK_FACTOR", 1e6)  # a long wait
    marble.location.x += 0.3
    bpy.context.view_layer.update()
    assert bake_check.status(bpy.context) is first  # kept meanwhile
    assert bpy.app.timers.is_registered(bake_check._REDRAW)  # a redraw after the wait
    monkeypatch.setattr(bake_check, "RECHECK_FACTOR", 0.0)  # the wait is over
    assert bake_check.status(bpy.context).stale
    bake_check.cancel_redraw()  # (a pending timer delays the bpy module's exit)
    assert bake_check._REDRAW is None
