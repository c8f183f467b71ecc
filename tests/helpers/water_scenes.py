"""Water scenes for the Blender tests (issue 26): a pool whose surface moves."""

import math

import bpy
from blender_scene_helpers import add_point_light, glass_material, set_engine

N, STRENGTH, ZENITH, PX = 1.333, 3.0, math.radians(30.0), 32


def moving_pool(engine="CYCLES"):
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
    set_engine(engine)
    sc.cycles.samples = 16
    sc.cycles.max_bounces = sc.cycles.diffuse_bounces = 0
    sc.render.image_settings.file_format = "OPEN_EXR"
    return water


def water_layers():
    from lens_lights.blender.build.marks import WATER_MARK

    return [o for o in bpy.data.objects if o.get(WATER_MARK)]
