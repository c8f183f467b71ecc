"""The Exact profile's near field built in Blender: a marble resting on a table lit
from 60° elevation (bench real_scenes rest_60) gets the tilt correction, its normal
in the light's own frame (`blender/build/lights._tilted`)."""

import math

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

pytestmark = pytest.mark.blender

R = 0.01


def _resting_marble(elevation_deg):
    add_sphere("Marble", (0.0, 0.0, R), radius=R, material=glass_material(), segments=64, rings=32)
    bpy.ops.mesh.primitive_plane_add(size=1.0)
    e = math.radians(elevation_deg)
    add_point_light("Lamp", (-math.cos(e), 0.0, R + math.sin(e)), energy=100.0)
    set_engine("CYCLES")
    bpy.context.scene.lens_lights.energy_model = "EXACT_PROFILE"
    generate()
    (ll,) = lens_lights()
    return ll


def test_a_tilted_table_gets_the_tilt_correction_in_the_lights_frame(empty_blend):
    """The table's normal, turned along the beam, is (0, 0, −1) in the world; the
    node tree holds it in the light's frame: the light's rotation takes it back.
    The image's green channel holds intensity × the rays' mean slope, red the
    intensity."""
    from lens_lights.blender.build.lights import TILT_NODE

    ll = _resting_marble(60.0)
    assert "near field" in ll.lens_lights.note
    nt = ll.data.node_tree
    assert any(n.type == "SEPARATE_COLOR" for n in nt.nodes)
    local = tuple(nt.nodes[TILT_NODE.format(0, "n" + c)].outputs[0].default_value for c in "xyz")
    # its offset from the light (at the lens centre): R along the normal
    assert nt.nodes[TILT_NODE.format(0, "offset")].outputs[0].default_value == pytest.approx(R)
    assert TILT_NODE.format(1, "nx") not in nt.nodes  # one plane: the table
    bpy.context.view_layer.update()  # matrix_world from the rotation set by the builder
    rot = np.array(ll.matrix_world.to_3x3().normalized())
    world = rot @ np.array(local)
    assert world == pytest.approx((0.0, 0.0, -1.0), abs=1e-5)
    (tex,) = [n for n in nt.nodes if n.type == "TEX_IMAGE"]
    img = tex.image
    w, h = img.size
    px = np.array(img.pixels[:], dtype=np.float32).reshape(h, w, 4)
    assert not np.array_equal(px[..., 1], px[..., 0]) and np.all(np.isfinite(px[..., 1]))


def test_a_square_table_gets_no_tilt_correction(empty_blend):
    """Light straight above: the table is square to the axis, the tree as before."""
    ll = _resting_marble(90.0)
    assert "near field" in ll.lens_lights.note
    nt = ll.data.node_tree
    (sep,) = [n for n in nt.nodes if n.type == "SEPXYZ"]
    fed_by_z = [link.to_node for link in sep.outputs["Z"].links]
    assert [n.operation for n in fed_by_z] == ["MULTIPLY"]  # cos γ only
