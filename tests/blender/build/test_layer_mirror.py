"""The EEVEE caustic layer seen in a mirror (issue 28 item 6): a marble on a table, a
point light at 45°, a vertical mirror beside them with a Light Probe Plane (Raytracing
on, Clamping > Surface Indirect off); camera C1 sees the caustic only in the mirror.
Its reference: camera C2, C1 reflected in the mirror's plane (the mirror hidden),
which sees the same table directly, mirrored, with a layer generated for it (the
direct view's layer, checked against the exact optics in test_blender_render.py).
The caustic's excess radiance summed over C1's frame must match C2's: on main the
mirror showed the shadow without the caustic (0 %). The same scene in the bench:
reports/layer_mirror.md (0.93). A bake of the layer shows in the mirror as Generate's."""

import math

import bpy
import numpy as np
import pytest
from blender_scene_helpers import generate, set_engine
from mathutils import Matrix, Vector
from measuring_scene import (
    add_diffuse_floor,
    add_glass_ball,
    add_point_light,
    new_material,
    new_measuring_scene,
)

pytestmark = pytest.mark.blender

MIRROR_Y = 1.2
#: The mirror's total over the direct view's: the coarse raster, the probe's
#: capture and 4 TAA samples (0.93 in the bench, the same scene; 0.76 at 64 px).
RATIO_TOL = 0.2
#: Blender 4.5 (the minimum): the mirror shows the caustic, but at 0.33 of the direct
#: view's, with Surface Indirect clamped or not (its probe capture of the Dithered
#: copy; not understood): within these bounds.
BLENDER_4_RATIO = (0.2, 0.5)


def _camera(name, loc, target):
    cam = bpy.data.objects.new(name, bpy.data.cameras.new(name))
    bpy.context.scene.collection.objects.link(cam)
    rot = (Vector(target) - Vector(loc)).to_track_quat("-Z", "Y").to_matrix().to_4x4()
    cam.matrix_world = Matrix.Translation(Vector(loc)) @ rot
    cam.data.angle = math.radians(14.0)
    cam.data.sensor_fit = "HORIZONTAL"
    return cam


def _render(sc, path):
    sc.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)
    img = bpy.data.images.load(str(path))
    px = np.array(img.pixels[:], dtype=float).reshape(img.size[1], img.size[0], 4)
    bpy.data.images.remove(img)
    return px[..., :3].mean(axis=2)


def test_a_mirror_shows_the_caustic_the_camera_does_not_see(extension, tmp_path):
    sc = new_measuring_scene("BLENDER_EEVEE", (96, 64))
    set_engine("BLENDER_EEVEE")
    add_diffuse_floor(20.0, 0.8, "Table")
    add_glass_ball(0.5, (0.0, 0.0, 0.5), 1.5, 64, 32, "Marble", hide_from_indirect=True)
    add_point_light((-3.0, 0.0, 3.5), 1000.0, 0.1)
    e = sc.eevee
    e.taa_render_samples = 4
    e.use_raytracing = True
    e.clamp_surface_indirect = 0.0
    mat = new_material("Mirror")
    bsdf = mat.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Metallic"].default_value = 1.0
    bsdf.inputs["Roughness"].default_value = 0.0
    bsdf.inputs["Base Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    bpy.ops.mesh.primitive_plane_add(size=1.0)
    mirror = bpy.context.object
    mirror.scale = (6.0, 2.5, 1.0)
    mirror.rotation_euler = (math.radians(90), 0.0, 0.0)  # faces −y
    mirror.location = (0.5, MIRROR_Y, 1.25)
    mirror.data.materials.append(mat)
    kind = "PLANE" if bpy.app.version >= (4, 1, 0) else "PLANAR"
    bpy.ops.object.lightprobe_add(type=kind, location=(0.5, MIRROR_Y - 0.001, 1.25))
    probe = bpy.context.object
    probe.rotation_euler = (math.radians(90), 0.0, 0.0)
    probe.scale = (3.0, 1.25, 1.0)
    c1_loc, target = (-1.0, -5.0, 1.6), (0.5, MIRROR_Y, 0.55)
    c1 = _camera("C1", c1_loc, target)
    c2 = _camera("C2", (c1_loc[0], 2 * MIRROR_Y - c1_loc[1], c1_loc[2]), target)

    mirror.hide_render = probe.hide_render = True  # C2 sees the table directly
    sc.camera = c2
    c2_without = _render(sc, tmp_path / "c2_without.exr")
    mirror.hide_render = probe.hide_render = False
    sc.camera = c1
    c1_without = _render(sc, tmp_path / "c1_without.exr")
    level, message, figures = generate()
    assert figures["energy_model"] == "CAUSTIC_LAYER", message
    c1_with = _render(sc, tmp_path / "c1_with.exr")
    mirror.hide_render = probe.hide_render = True
    sc.camera = c2
    generate()
    c2_with = _render(sc, tmp_path / "c2_with.exr")

    direct = (c2_with - c2_without)[:, ::-1]
    seen = c1_with - c1_without
    assert direct.sum() > 10.0  # the caustic is in C2's view (and bright)
    if bpy.app.version >= (5, 0, 0):
        assert seen.sum() == pytest.approx(direct.sum(), rel=RATIO_TOL)
    else:  # Blender 4.5's EEVEE shows it at a third (0.33), the clamp is not why
        assert BLENDER_4_RATIO[0] < seen.sum() / direct.sum() < BLENDER_4_RATIO[1]
    # and where it is: the brightest pixel of each within 3 px of the other's
    peak_seen = np.unravel_index(np.argmax(seen), seen.shape)
    peak_direct = np.unravel_index(np.argmax(direct), direct.shape)
    assert np.hypot(*np.subtract(peak_seen, peak_direct)) <= 3.0
    # a bake's layer has its reflection copy too, keyed as the layer: the mirror shows
    # the baked caustic as it shows Generate's (before: none, 0 %)
    mirror.hide_render = probe.hide_render = False
    sc.camera = c1
    sc.frame_start = sc.frame_end = 1
    assert bpy.ops.lens_lights.bake() == {"FINISHED"}
    copies = [o for o in sc.objects if o.get("lens_lights_reflection")]
    assert copies and all(not o.visible_camera for o in copies)
    assert all(o.material_slots[0].material.node_tree.animation_data for o in copies)
    baked = _render(sc, tmp_path / "c1_baked.exr") - c1_without
    assert baked.sum() == pytest.approx(seen.sum(), rel=0.1)
