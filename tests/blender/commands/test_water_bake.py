"""Issue 26: the water's caustic baked over frames. A pool whose surface moves (an
Ocean modifier on a 16 × 16 grid, its time keyed) under a sun, floor below: Bake
writes the water's layer with a fixed topology and each frame's irradiance, keyed;
the saved file rendered by a Blender that never loads the extension (as
`blender -b file.blend -a` on a farm node) shows at frame 2 what Generate makes at
frame 2, and another net at frame 3 (the waves moved). Clear removes what the bake
made and nothing else: the user's scene is as it was.

Measured (Cycles, 32 px, direct light only): each render minus the same render with
the "Lens Lights" collection hidden, as the caustic; relative L1 over the lit pixels.
The bound is set from the renders themselves: the baked frame against Generate's
must be far closer than two frames of the bake are to each other (the nets moved).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

pytestmark = pytest.mark.blender

bpy = pytest.importorskip("bpy")

from blender_scene_helpers import (  # noqa: E402
    add_point_light,
    generate,
    glass_material,
    set_engine,
    snapshot,
    snapshot_diff,
)
from stock_render import stock_render  # noqa: E402

N, STRENGTH, ZENITH, PX = 1.333, 3.0, math.radians(30.0), 32


def moving_pool():
    """Floor, a 2 m water grid (16 × 16) 0.6 m above it with an Ocean modifier whose
    time runs 1 → 3 over frames 1 → 3, a sun 30° off the zenith, a camera
    straight down over the lit floor, the water hidden from the camera (it sees the
    floor as it lies in the water, as the water bench does)."""
    sc = bpy.context.scene
    bpy.ops.mesh.primitive_plane_add(size=8.0, location=(0.0, 0.0, 0.0))
    bpy.context.object.name = "Floor"
    bpy.ops.mesh.primitive_grid_add(
        x_subdivisions=16, y_subdivisions=16, size=2.0, location=(0.0, 0.0, 0.6)
    )
    water = bpy.context.object
    water.name = "Water"
    water.data.materials.append(glass_material("Water", ior=N))
    water.visible_camera = False
    ocean = water.modifiers.new("Ocean", "OCEAN")
    ocean.geometry_mode = "DISPLACE"
    ocean.resolution = ocean.viewport_resolution = 4
    ocean.spatial_size = 2
    ocean.size = 1.0
    ocean.wave_scale = 0.3
    ocean.choppiness = 0.0
    for f, t in ((1, 1.0), (3, 3.0)):  # (frame 2: time 2, Bézier or linear alike)
        ocean.time = t
        water.keyframe_insert('modifiers["Ocean"].time', frame=f)
    sun = add_point_light("Sun", (0.0, 0.0, 5.0), energy=STRENGTH, kind="SUN")
    sun.rotation_euler = (0.0, -ZENITH, 0.0)
    shift = 0.6 * math.tan(math.asin(math.sin(ZENITH) / N))
    bpy.ops.object.camera_add(location=(shift, 0.0, 4.0), rotation=(0.0, 0.0, 0.0))
    cam = bpy.context.object
    cam.data.type = "ORTHO"
    cam.data.ortho_scale = 1.6
    sc.camera = cam
    sc.render.resolution_x = sc.render.resolution_y = PX
    sc.frame_start, sc.frame_end = 1, 3
    sc.frame_set(1)
    set_engine("CYCLES")
    sc.cycles.samples = 16
    sc.cycles.max_bounces = sc.cycles.diffuse_bounces = 0
    sc.render.image_settings.file_format = "OPEN_EXR"
    return water


def caustic(blend, tmp, frame):
    facts, lit, without = stock_render(blend, tmp, frame)
    assert facts["registered"] is False and facts["operators"] is False
    return lit - without


def l1(a, b):
    lit = (a > 0.05 * a.max()) | (b > 0.05 * b.max())
    return float(np.abs(a - b)[lit].sum() / b[lit].sum())


def water_layers():
    from lens_lights.blender.build.marks import WATER_MARK

    return [o for o in bpy.data.objects if o.get(WATER_MARK)]


def test_baked_water_renders_without_the_extension_as_generate_and_clear_removes_it(
    empty_blend, tmp_path
):
    moving_pool()
    sc = bpy.context.scene
    before = snapshot()
    assert bpy.ops.lens_lights.bake() == {"FINISHED"}
    report = sc.lens_lights.last_report
    assert "water caustic layer object" in report, report
    baked = water_layers()
    assert baked and sc.frame_current == 1
    # one fixed mesh per layer: the same vertices on every frame, the light in its image
    verts = {o.name: len(o.data.vertices) for o in baked}
    sc.frame_set(3)
    assert {o.name: len(o.data.vertices) for o in baked} == verts
    sc.frame_set(1)
    blend = tmp_path / "baked.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend), copy=True)
    b2 = caustic(blend, tmp_path / "b2", 2)
    b3 = caustic(blend, tmp_path / "b3", 3)

    # Clear: only what the bake made goes; the user's scene is as it was
    assert bpy.ops.lens_lights.clear() == {"FINISHED"}
    assert water_layers() == []
    assert not [i for i in bpy.data.images if i.get("lens_lights_created") == "bake"]
    after = snapshot()
    assert after == before, snapshot_diff(before, after)

    sc.frame_set(2)
    level, message, _ = generate()
    assert level in ("INFO", "WARNING") and "water: Water" in message, message
    blend2 = tmp_path / "generated.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend2), copy=True)
    g2 = caustic(blend2, tmp_path / "g2", 2)

    same, moved = l1(b2, g2), l1(b3, g2)
    flux = b2.sum() / g2.sum()
    print(f"\nbaked frame 2 vs Generate at 2: L1 {same:.3f}, flux {flux:.3f}; "
          f"baked frame 3 vs Generate at 2: L1 {moved:.3f}")  # fmt: skip
    assert g2.max() > 0 and b2.max() > 0
    assert same < 0.5 * moved  # the frame's own net, not another's
    assert same < 0.2
    assert flux == pytest.approx(1.0, abs=0.05)
