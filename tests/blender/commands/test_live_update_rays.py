"""Live update's planner rays remembered per pair (issue 27, bpy module;
`core.plan.ray_memo`): a marble resting on a table, one lamp keyed to move and one
resting. A frame change casts the rays of the moving lamp's pair only (counted), yet
every change that can move a lens light refreshes the resting lamp's too: the state
after it equals a fresh Generate's (lights' numbers, Value nodes, table pixels) when
the table (receiver) is moved, a wall beside the marble is moved, the resting lamp's
power is changed, and when a shape key reshapes the table inside the same box on a
frame change (what the memo's own check of transforms and boxes cannot see)."""

import bpy
import numpy as np
import pytest
from blender_scene_helpers import (
    assert_profile_lights_are_generates,
    profile_light_states,
    resting_marble,
)

pytestmark = pytest.mark.blender

R = 0.5
MOVING = {1: (1.0, 0.4, 5.0), 3: (-0.6, -0.9, 4.2)}
TILT = 0.02  # the table's slope along x, flipped by its shape key


def _scene(shape_key=False):
    from lens_lights.blender.commands import live_update
    from lens_lights.core.tiers import exact_profile

    sc, lamp = resting_marble((-1.5, 1.2, 4.0), radius=R)
    lamp.name = "Resting"
    floor = bpy.data.objects["Plane"]
    if shape_key:  # tilted one way, the key the other: the same box
        for v in floor.data.vertices:
            v.co.z = TILT * v.co.x
        floor.shape_key_add(name="Basis")
        key = floor.shape_key_add(name="Flip")
        for p in key.data:
            p.co.z = -TILT * p.co.x
        for frame, value in ((1, 0.0), (3, 1.0)):
            key.value = value
            key.keyframe_insert("value", frame=frame)
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=(0.0, 1.3, 0.5))
    bpy.context.object.name = "Wall"  # beside the marble: a side plane of its lights
    data = bpy.data.lights.new("Moving", "POINT")
    data.energy = 1000.0
    moving = bpy.data.objects.new("Moving", data)
    sc.collection.objects.link(moving)
    for frame, loc in MOVING.items():
        moving.location = loc
        moving.keyframe_insert("location", frame=frame)
    sc.frame_start, sc.frame_end = 1, 3
    sc.frame_set(1)
    exact_profile.cached_profile.cache_clear()
    sc.lens_lights.live_update = True
    assert "error" not in live_update.LAST_FIGURES
    return sc, live_update._RAYS[sc.as_pointer()]


def _equal_to_generate(state):
    assert set(state) == {"Resting", "Moving"}
    assert_profile_lights_are_generates(state)


def test_a_frame_casts_the_moving_lamps_pair_only(empty_blend):
    from lens_lights.core.plan.planning import SUNK_PROBES
    from lens_lights.core.tiers.near_field import SIDE_AZIMUTHS, SIDE_POLAR_DEG

    sc, rays = _scene()
    # turned on: both pairs' bundles and the sunk probes of the marble, all cast
    probes, side = len(SUNK_PROBES), len(SIDE_POLAR_DEG) * SIDE_AZIMUTHS
    pairs = rays.cast - probes
    assert rays.reused == 0 and pairs > 0 and pairs % 2 == 0
    # the moving lamp's pair cast; the resting one's receiver and free distance
    # bundles and the probes looked up, its side planes not even that
    sc.frame_set(2)
    assert rays.cast == pairs // 2 and rays.reused == pairs // 2 - side + probes
    _equal_to_generate(profile_light_states())


def _drag(ob, dz=0.0, dy=0.0):
    ob.location.z += dz
    ob.location.y += dy
    bpy.context.view_layer.update()


@pytest.mark.parametrize("change", ["table", "wall", "power"])
def test_a_change_near_the_resting_lamps_pair_refreshes_it(empty_blend, change):
    from lens_lights.blender.commands import live_update

    sc, rays = _scene()
    sc.frame_set(2)
    before = profile_light_states()
    figures = live_update.LAST_FIGURES
    if change == "table":
        _drag(bpy.data.objects["Plane"], dz=-0.05)  # the marble floats a little above it
    elif change == "wall":
        _drag(bpy.data.objects["Wall"], dy=-0.15)
    else:
        bpy.data.objects["Resting"].data.energy = 400.0
        bpy.context.view_layer.update()
    assert live_update.LAST_FIGURES is not figures and "error" not in live_update.LAST_FIGURES
    after = profile_light_states()
    assert not np.array_equal(after["Resting"][1], before["Resting"][1]) or (
        after["Resting"][2] != before["Resting"][2]
    )
    _equal_to_generate(after)


def test_a_shape_key_reshaping_the_table_in_its_box_refreshes_every_pair(empty_blend):
    sc, rays = _scene(shape_key=True)
    floor = bpy.data.objects["Plane"]
    box = np.array(floor.evaluated_get(bpy.context.evaluated_depsgraph_get()).bound_box)
    sc.frame_set(3)  # the lamp moved and the table's tilt flipped, in the same box
    after = np.array(floor.evaluated_get(bpy.context.evaluated_depsgraph_get()).bound_box)
    np.testing.assert_allclose(after, box, atol=1e-6)
    assert rays.reused == 0  # every bundle cast again
    _equal_to_generate(profile_light_states())
