"""Live update reacts to what changes a caustic and to nothing else (issue 28, item 3):
an object away from every path of the light costs no update; a blocker put in, moved
out or deleted, the glass's colour, the receiver's colour and a receiver turned
metallic each bring the lens lights to what a fresh Generate makes."""

import bpy
import pytest
from blender_scene_helpers import (
    add_point_light,
    add_sphere,
    caustic_layers,
    generate,
    glass_material,
    lens_lights,
    node_material,
    set_engine,
)

pytestmark = [pytest.mark.blender, pytest.mark.usefixtures("auto_builds_lights")]

STONE_AWAY = (3.0, -3.0, 0.5)
#: Between the lamp and the glass ball: it hides the whole ball from the lamp.
STONE_BLOCKING = (0.0, 0.0, 3.6)


def _scene(extras=True):
    """Floor (white Principled) at z 0, glass ball R 0.5 at z 2.5, point lamp 2 above
    it, a cube of 1 at (3, 3, 0.5), 3 m off the lamp → ball → floor line, and an
    opaque ball R 0.5 (a blocker phase 1 models) at (3, −3, 0.5)."""
    bpy.ops.mesh.primitive_plane_add(size=8)
    floor = bpy.context.object
    floor.name = "Floor"
    floor.data.materials.append(
        node_material("Table", "ShaderNodeBsdfPrincipled", **{"Base Color": (0.8, 0.8, 0.8, 1)})
    )
    marble = add_sphere("Marble", (0.0, 0.0, 2.5), material=glass_material())
    lamp = add_point_light("Lamp", (0.0, 0.0, 4.5), energy=1000.0)
    if not extras:
        return floor, marble, lamp, None
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=(3.0, 3.0, 0.5))
    cube = bpy.context.object
    cube.name = "Cube"
    add_sphere("Stone", STONE_AWAY)
    return floor, marble, lamp, cube


def _figures():
    from lens_lights.blender.commands import live_update

    return live_update.LAST_FIGURES


def _lights_state():
    return sorted(
        (
            o.name,
            tuple(round(x, 6) for x in o.location),
            round(o.data.energy, 4),
            tuple(round(x, 5) for x in o.data.color),
        )
        for o in lens_lights()
        if o.type == "LIGHT"
    )


def _fresh():
    """What Generate makes of the scene as it is now (live update off for it)."""
    scene = bpy.context.scene
    scene.lens_lights.live_update = False
    generate()
    return _lights_state()


def test_an_edit_away_from_the_light_costs_no_update(empty_blend):
    _, _, _, cube = _scene()
    scene = bpy.context.scene
    scene.lens_lights.live_update = True
    (light,) = lens_lights()
    before = _figures()
    for k in range(5):  # dragging the cube about, 3 m from the beam
        cube.location.x = 3.0 + 0.1 * k
        bpy.context.view_layer.update()
    assert _figures() is before
    stone = bpy.data.objects["Stone"]
    stone.location = STONE_BLOCKING
    bpy.context.view_layer.update()
    assert _figures() is not before and _figures()["why"] == "edit"
    assert lens_lights() == []
    stone.location = STONE_AWAY  # out again: the light comes back
    bpy.context.view_layer.update()
    assert len(lens_lights()) == 1


def test_a_cube_moved_into_the_shadow_is_seen(empty_blend):
    _, _, _, cube = _scene()
    scene = bpy.context.scene
    scene.lens_lights.energy_model = "FITTED"
    scene.lens_lights.live_update = True
    before = _lights_state()
    cube.location = (0.0, 0.0, 1.0)  # under the ball: the caustic now falls on it
    bpy.context.view_layer.update()
    after = _lights_state()
    assert after != before
    assert after == _fresh()


def test_deleting_a_blocker_brings_the_light_back(empty_blend):
    _scene()
    stone = bpy.data.objects["Stone"]
    stone.location = STONE_BLOCKING
    scene = bpy.context.scene
    scene.lens_lights.live_update = True
    assert lens_lights() == []
    bpy.data.objects.remove(stone)
    bpy.context.view_layer.update()
    assert len(lens_lights()) == 1


def test_hiding_a_blocker_in_the_viewport_is_seen(empty_blend):
    _scene()
    stone = bpy.data.objects["Stone"]
    stone.location = STONE_BLOCKING
    scene = bpy.context.scene
    scene.lens_lights.live_update = True
    assert lens_lights() == []
    stone.hide_viewport = True  # gone from the viewport depsgraph live update reads
    bpy.context.view_layer.update()
    assert len(lens_lights()) == 1


def test_the_glass_colour_is_followed(empty_blend):
    _, marble, _, _ = _scene()
    scene = bpy.context.scene
    scene.lens_lights.live_update = True
    white = _lights_state()
    bsdf = marble.active_material.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (1.0, 0.5, 0.25, 1.0)
    bpy.context.view_layer.update()
    tinted = _lights_state()
    (light,) = lens_lights()
    r, g, b = light.data.color
    assert tinted != white and g < r and b < g
    assert tinted == _fresh()


def _layer_scene():
    floor, _, _, _ = _scene(extras=False)
    set_engine("BLENDER_EEVEE")
    scene = bpy.context.scene
    scene.lens_lights.energy_model = "CAUSTIC_LAYER"
    return floor


def _layer_colour():
    (layer,) = [o for o in caustic_layers() if "Floor" in o.name]
    nodes = layer.active_material.node_tree.nodes
    (mix,) = [n for n in nodes if n.type == "MIX" and n.data_type == "RGBA"]
    return tuple(round(x, 5) for x in mix.inputs["B"].default_value)


def test_the_receivers_colour_and_metal_are_followed_by_the_layer(empty_blend):
    floor = _layer_scene()
    scene = bpy.context.scene
    scene.lens_lights.live_update = True
    assert _layer_colour() == pytest.approx((0.8, 0.8, 0.8, 1.0))
    bsdf = floor.active_material.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (0.2, 0.4, 0.6, 1.0)
    bpy.context.view_layer.update()
    assert _layer_colour() == pytest.approx((0.2, 0.4, 0.6, 1.0))
    bsdf.inputs["Metallic"].default_value = 1.0  # a metal table: no diffuse layer on it
    bpy.context.view_layer.update()
    made = sorted((o.type, o.name) for o in lens_lights())
    assert not [n for t, n in made if t == "MESH" and "Floor" in n]
    assert [n for t, n in made if t == "LIGHT"]  # the glossy fallback's spot
    scene.lens_lights.live_update = False
    generate()
    assert sorted((o.type, o.name) for o in lens_lights()) == made


def test_the_lamps_colour_is_followed(empty_blend):
    _, _, lamp, _ = _scene()
    scene = bpy.context.scene
    scene.lens_lights.live_update = True
    lamp.data.color = (1.0, 0.6, 0.3)  # the light's data only (a PointLight datablock)
    bpy.context.view_layer.update()
    (light,) = lens_lights()
    r, g, b = light.data.color
    assert g / r == pytest.approx(0.6, rel=1e-4) and b / r == pytest.approx(0.3, rel=1e-4)
    assert _lights_state() == _fresh()


def test_an_edit_away_from_the_light_costs_no_update_beside_a_coarse_layer(empty_blend):
    """EEVEE, the caustic layer, a camera that does not see the floor: the caustic is
    drawn by a coarse raster out of view (for mirrors), whose big texels once watched
    the cube 3 m away and rebuilt the layer on every drag (seconds each)."""
    import math

    _, _, _, cube = _scene()
    scene = bpy.context.scene
    set_engine("BLENDER_EEVEE")
    scene.lens_lights.energy_model = "CAUSTIC_LAYER"
    bpy.ops.object.camera_add(location=(0.0, -6.0, 2.5), rotation=(math.pi / 2, 0.0, 0.0))
    scene.camera = bpy.context.object
    scene.lens_lights.live_update = True
    assert any("coarse" in o.lens_lights.note for o in caustic_layers())
    bpy.context.view_layer.update()  # the echo of its own build
    before = _figures()
    for k in range(5):  # dragging the cube about, 3 m from the beam
        cube.location.x = 3.0 + 0.1 * k
        bpy.context.view_layer.update()
    assert _figures() is before
