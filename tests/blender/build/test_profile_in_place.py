"""Live update writes an Exact profile light in place (issue 27): a marble resting on a
table, the lamp moved (another D/R, another receiver distance, another tilt): the
same light, the same node tree (its nodes not rebuilt), the same image with the new
table's pixels — the exact table of the new geometry (the row-by-row trace of
`exact_profile`, not the code under test) within the tier's 1 % — and no new image;
the state equals a fresh Generate's (pixels, Value nodes); saving the file packs the
rewritten image, and the saved file holds the new pixels."""

import math

import bpy
import numpy as np
import pytest
from blender_scene_helpers import (
    lens_lights,
    resting_marble,
)
from profile_measures import exact_near_table

from core.tiers import exact_profile as xp

pytestmark = pytest.mark.blender

R, N = 0.5, 1.5
CENTRE = np.array([0.0, 0.0, R])  # resting on the table z = 0


def _scene():
    return resting_marble((1.0, 0.4, 5.0), radius=R, ior=N)


def _light():
    (ob,) = [o for o in lens_lights() if o.type == "LIGHT"]
    return ob


def _pixels(img):
    px = np.empty(len(img.pixels), dtype=np.float32)
    img.pixels.foreach_get(px)
    return px.reshape(img.size[1], img.size[0], 4)


def _geometry(lamp_at):
    """D/R and the table's distance along the axis (R) from the lens centre, for the
    lamp at `lamp_at`: the exact geometry, by hand."""
    d = CENTRE - np.asarray(lamp_at, float)
    D = float(np.linalg.norm(d))
    axis = d / D
    return D / R, R / (-axis[2]) / R  # the table z = 0 met along the axis


def _check_against_exact(img, lamp_at):
    """The image's red channel × energy/(4π) normalisation is the exact near-field
    table of this geometry, within 1 % of each lit row's flux (outside the lens)."""
    exact, t_ref = exact_near_table(CENTRE, R, N, lamp_at)
    table = _pixels(img)[..., 0].astype(float) * t_ref
    assert table.shape == exact.table.shape
    K = table.shape[1]
    g = math.radians(xp.PROFILE_GAMMA_MAX_DEG) * (np.arange(K + 1) / K) ** 2
    d_omega = np.diff(4.0 * math.pi * np.sin(0.5 * g) ** 2)
    h = exact.distances[:, None]
    outside = (exact.apex + h) ** 2 + (h * np.tan(g[:-1])) ** 2 >= 1.0
    flux = np.sum(exact.table * outside * d_omega, 1)
    l1 = np.sum(np.abs(table - exact.table) * outside * d_omega, 1)
    lit = flux >= 0.1 * exact.flux
    assert lit.sum() > 100
    assert np.max(l1[lit] / flux[lit]) <= 0.01


def test_a_moved_lamp_rewrites_the_profile_light_in_place(empty_blend, tmp_path):
    from lens_lights.blender.build import lights
    from lens_lights.blender.commands import live_update
    from lens_lights.blender.commands.generate import generate

    sc, lamp = _scene()
    live_update.update(sc, bpy.context.evaluated_depsgraph_get(), force=True)
    ob = _light()
    nt = ob.data.node_tree
    nodes = {n.name: n.as_pointer() for n in nt.nodes}
    img = nt.nodes[lights.PROFILE_TEX_NODE].image
    image_ptr, images = img.as_pointer(), {i.as_pointer() for i in bpy.data.images}
    before = _pixels(img).copy()
    h_min = nt.nodes[lights.H_MIN_NODE].outputs[0].default_value

    lamp.location = (-0.6, -0.9, 4.2)  # another D/R, receiver distance and tilt
    live_update.update(sc, bpy.context.evaluated_depsgraph_get(), force=True)
    assert _light() == ob
    nt = ob.data.node_tree
    assert {n.name: n.as_pointer() for n in nt.nodes} == nodes  # not rebuilt
    img = nt.nodes[lights.PROFILE_TEX_NODE].image
    assert img.as_pointer() == image_ptr  # its own image, rewritten
    assert {i.as_pointer() for i in bpy.data.images} == images  # nothing new
    after = _pixels(img).copy()
    assert np.abs(after - before).max() > 1e-3 * np.abs(before).max()
    _check_against_exact(img, lamp.location)
    # the new table's first distance: its rows shifted onto the new receiver
    _, z = _geometry(lamp.location)
    want_h_min = xp.table_geometry(z, xp.NEAR_DISTANCES, on_row=True)[1] * R
    assert nt.nodes[lights.H_MIN_NODE].outputs[0].default_value == pytest.approx(
        want_h_min, rel=1e-6
    )
    assert want_h_min != pytest.approx(h_min, rel=1e-6)
    live = {
        n.name: n.outputs[0].default_value for n in nt.nodes if n.bl_idname == "ShaderNodeValue"
    }
    location = tuple(ob.location)

    # a fresh Generate on the same scene makes the same light
    sc.lens_lights.live_update = False
    generate(bpy.context)
    fresh = _light()
    fnt = fresh.data.node_tree
    assert tuple(fresh.location) == pytest.approx(location, abs=1e-6)
    fresh_values = {
        n.name: n.outputs[0].default_value for n in fnt.nodes if n.bl_idname == "ShaderNodeValue"
    }
    assert fresh_values.keys() == live.keys()
    for name, value in live.items():
        assert fresh_values[name] == pytest.approx(value, rel=1e-6, abs=1e-9), name
    np.testing.assert_array_equal(_pixels(fnt.nodes[lights.PROFILE_TEX_NODE].image), after)


def test_saving_packs_the_rewritten_table(empty_blend, tmp_path):
    from lens_lights.blender.build import lights
    from lens_lights.blender.commands import live_update

    sc, lamp = _scene()
    live_update.update(sc, bpy.context.evaluated_depsgraph_get(), force=True)
    lamp.location = (-0.6, -0.9, 4.2)
    live_update.update(sc, bpy.context.evaluated_depsgraph_get(), force=True)
    img = _light().data.node_tree.nodes[lights.PROFILE_TEX_NODE].image
    assert img.is_dirty  # rewritten in memory, not yet packed
    want = _pixels(img).copy()
    path = str(tmp_path / "saved.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    assert not img.is_dirty and img.packed_file is not None
    bpy.ops.wm.open_mainfile(filepath=path)
    img = _light().data.node_tree.nodes[lights.PROFILE_TEX_NODE].image
    np.testing.assert_array_equal(_pixels(img)[..., :3], want[..., :3])


def test_the_values_written_in_place_reach_the_evaluated_light(empty_blend):
    """The Value nodes are written raw and the tree updated once
    (`_update_profile_in_place`): the next depsgraph update reports the light's
    shading changed, as a socket's own write does (what Cycles' viewport follows),
    and the evaluated light's tree holds the new values."""
    from lens_lights.blender.build import lights
    from lens_lights.blender.commands import live_update

    sc, lamp = _scene()
    live_update.update(sc, bpy.context.evaluated_depsgraph_get(), force=True)
    bpy.context.view_layer.update()
    ob = _light()
    old = ob.data.node_tree.nodes[lights.H_MIN_NODE].outputs[0].default_value
    lamp.location = (-0.6, -0.9, 4.2)
    live_update.update(sc, bpy.context.evaluated_depsgraph_get(), force=True)
    seen = []

    def record(_scene, depsgraph):
        seen.extend((u.id.name, u.is_updated_shading) for u in depsgraph.updates)

    bpy.app.handlers.depsgraph_update_post.append(record)
    try:
        bpy.context.view_layer.update()
    finally:
        bpy.app.handlers.depsgraph_update_post.remove(record)
    assert (ob.data.name, True) in seen
    nt = ob.data.node_tree
    assert nt.nodes[lights.H_MIN_NODE].outputs[0].default_value != old
    evaluated = ob.evaluated_get(bpy.context.evaluated_depsgraph_get()).data.node_tree
    for node in nt.nodes:
        if node.bl_idname == "ShaderNodeValue":
            got = evaluated.nodes[node.name].outputs[0].default_value
            assert got == node.outputs[0].default_value, node.name


def test_a_new_image_made_in_place_is_packed_when_saved(empty_blend, tmp_path):
    """A light whose image something else uses too (here the user's fake user) gets a
    new image when its table changes; live update leaves it unpacked (packing takes
    milliseconds an image) and saving packs it: the saved file holds its pixels."""
    from lens_lights.blender.build import lights
    from lens_lights.blender.commands import live_update

    sc, lamp = _scene()
    live_update.update(sc, bpy.context.evaluated_depsgraph_get(), force=True)
    old = _light().data.node_tree.nodes[lights.PROFILE_TEX_NODE].image
    old.use_fake_user = True  # not the light's alone: kept as it is
    kept = _pixels(old).copy()
    lamp.location = (-0.6, -0.9, 4.2)
    live_update.update(sc, bpy.context.evaluated_depsgraph_get(), force=True)
    img = _light().data.node_tree.nodes[lights.PROFILE_TEX_NODE].image
    assert img != old and img.packed_file is None and img.is_dirty
    np.testing.assert_array_equal(_pixels(old), kept)
    _check_against_exact(img, lamp.location)
    want = _pixels(img).copy()
    path = str(tmp_path / "saved.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    assert img.packed_file is not None and not img.is_dirty
    bpy.ops.wm.open_mainfile(filepath=path)
    img = _light().data.node_tree.nodes[lights.PROFILE_TEX_NODE].image
    np.testing.assert_array_equal(_pixels(img)[..., :3], want[..., :3])
