"""The Caustic layer's bake in Blender (bpy module): one mesh of fixed topology per
receiver plane over the frames, one packed image of slices, keyed slice index;
each frame's slice carries Generate's layer of that frame (flux and centroid, and
the exact optics' flux); Clear and one undo step remove the objects, materials,
image and actions; a glossy receiver's Fitted spots stay one per frame;
a floor with warped UVs bakes as a vertex grid carrying its UVs; a baked frame renders
in EEVEE in a Blender process without the extension, its
caustic where and as bright as the exact optics says.

Scene: the measuring scene (white floor albedo 0.8, glass ball R = 0.5, n = 1.5 at
2.5 above the floor, a 1000 W point light moving over frames 1–3, orthographic
camera straight down on the middle frame's axis point)."""

import math

import bpy
import numpy as np
import pytest
from blender_scene_helpers import basic_scene, caustic_layers, lens_lights, set_engine
from measuring_scene import build_measuring_scene, new_material
from stock_render import stock_render

from core.lens import ball_optics

pytestmark = pytest.mark.blender

R, N, POWER, ALBEDO = 0.5, 1.5, 1000.0, 0.8
CENTER = np.array([0.0, 0.0, 2.5])
FIRST, LAST = np.array([-0.45, 0.0, 4.45]), np.array([-1.1, 0.0, 4.6])
MID = 0.5 * (FIRST + LAST)
PX, VIEW = 32, 1.0


def axis_hit(light):
    u = (CENTER - light) / np.linalg.norm(CENTER - light)
    return CENTER + (CENTER[2] / -u[2]) * u


def make_scene():
    hit = axis_hit(MID)
    built = build_measuring_scene(
        "BLENDER_EEVEE",
        resolution=PX,
        floor_size=60.0,  # (wide: the beam's steepest rays land too)
        albedo=ALBEDO,
        view=VIEW,
        camera_xy=(hit[0], hit[1]),
        camera_height=6.0,
        ball=dict(radius=R, location=tuple(CENTER), ior=N, segments=48, rings=24, name="Marble"),
        lamp=dict(location=tuple(FIRST), power=POWER),
    )
    sc = built.scene
    sc.lens_lights.energy_model = "CAUSTIC_LAYER"
    sc.eevee.taa_render_samples = 4
    sc.frame_start, sc.frame_end = 1, 3
    bpy.context.preferences.edit.keyframe_new_interpolation_type = "LINEAR"
    for k, p in enumerate((FIRST, MID, LAST)):
        built.lamp.location = p
        built.lamp.keyframe_insert("location", frame=k + 1)
    sc.frame_set(1)
    return built


def layer_objects():
    """The layers in the camera's view (not the coarse ones of the halo out of it)."""
    return [o for o in caustic_layers() if "coarse" not in o.lens_lights.note]


def face_areas_centres(me):
    n = len(me.polygons)
    area, centre = np.empty(n), np.empty(3 * n)
    me.polygons.foreach_get("area", area)
    me.polygons.foreach_get("center", centre)
    return area, centre.reshape(-1, 3)


def summary(flux, centre, frame):
    """(total flux, flux-weighted centroid of the faces within 2 R of the frame's axis
    point: the core the camera sees; the wide halo's coarse texels would blur it)."""
    light = FIRST + (frame - 1) * 0.5 * (LAST - FIRST)
    near = np.linalg.norm(centre - axis_hit(light), axis=1) <= 2 * R
    return float(flux.sum()), flux[near] @ centre[near] / flux[near].sum()


def generated_layer(frame):
    """(flux, core centroid) of Generate's layer on `frame` (then cleared)."""
    from lens_lights.blender.commands.generate import generate

    bpy.context.scene.frame_set(frame)
    generate(bpy.context)
    (ob,) = layer_objects()
    me = ob.data
    rgba = np.empty(len(me.vertices) * 4)
    me.attributes["lens_irradiance"].data.foreach_get("color", rgba)
    corners = np.empty(len(me.loops), dtype=np.int32)
    me.loops.foreach_get("vertex_index", corners)
    area, centre = face_areas_centres(me)
    # per triangle: area × the mean of its corners' irradiance (drawn linear over it)
    flux = rgba.reshape(-1, 4)[corners.reshape(-1, 3), 1].mean(axis=1) * area
    bpy.ops.lens_lights.clear()
    return summary(flux, centre, frame)


def traced_flux_on_raster(ob, light):
    """The reference tracer's flux of the lens' beam on the floor over the baked
    layer's raster (its extent from the object's raster property: the layer spans only
    what the camera sees of the caustic, `core/caustic_layer/view.py`)."""
    from lens_lights.blender.build import baked_layers as lbb

    import reference as ref

    raster = list(ob[lbb.RASTER_PROP])
    nt = ob.active_material.node_tree
    clamp = next(
        n for n in nt.nodes if n.bl_idname == "ShaderNodeMath" and n.operation == "MAXIMUM"
    )
    res = round(0.5 / clamp.inputs[1].default_value)
    lo_hi = [
        c + s * np.sinh(np.array([x0, x0 + res * d])) for c, s, x0, d in (raster[0:4], raster[4:8])
    ]
    traced = ref.trace_irradiance(
        ref.PointLight(tuple(light), POWER, 0.0),
        ref.GlassSphere(tuple(CENTER), R, N),
        ref.ReceiverPlane((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), tuple(raster[8:11])),
        400_000,
        seed=3,
        grid=tuple(lo_hi),
    )
    return float(traced.irradiance[0, 0]) * float(np.ptp(lo_hi[0]) * np.ptp(lo_hi[1]))


def mathutils_vector(v):
    from mathutils import Vector

    return Vector(tuple(float(x) for x in v))


def baked_layer(ob, frame):
    """(flux, core centroid) of the baked layer on `frame`, read in numpy from its image's
    tile of the keyed slice × the keyed scale and colour (green)."""
    from lens_lights.blender.build import baked_layers as lbb

    bpy.context.scene.frame_set(frame)
    nt = ob.active_material.node_tree
    k = int(round(nt.nodes[lbb.SLICE_NODE].outputs[0].default_value))
    scale = nt.nodes[lbb.SCALE_NODE].outputs[0].default_value
    green = nt.nodes[lbb.COLOUR_NODE].outputs[0].default_value[1]
    tex = next(
        n
        for n in nt.nodes
        if n.bl_idname == "ShaderNodeTexImage"
        and n.image is not None
        and n.image.get("lens_lights_created") == "bake"
    )
    img = tex.image
    w, h = img.size
    px = np.array(img.pixels[:], dtype=float).reshape(h, w, 4)[..., 1]
    raster = list(ob[lbb.RASTER_PROP])
    au, av = np.array(raster[8:11]), np.array(raster[11:14])
    res = next(n for n in nt.nodes if n.bl_idname == "ShaderNodeMath" and n.operation == "MAXIMUM")
    res = round(0.5 / res.inputs[1].default_value)  # the clamp at half a texel
    cols = w // res
    row = math.floor((k + 0.5) / cols)
    col = k - row * cols
    tile = px[row * res : (row + 1) * res, col * res : (col + 1) * res]
    # the texel lines (documented warp) → texel areas and centres on the plane
    eu, ev = (
        c + s * np.sinh(x0 + d * np.arange(res + 1)) for c, s, x0, d in (raster[0:4], raster[4:8])
    )
    area = (np.diff(ev)[:, None] * np.diff(eu)[None, :]).reshape(-1)
    cu, cv = 0.5 * (eu[1:] + eu[:-1]), 0.5 * (ev[1:] + ev[:-1])
    normal = np.cross(au, av)
    height = float(ob.data.vertices[0].co @ mathutils_vector(normal))
    centre = (cu[None, :, None] * au + cv[:, None, None] * av + height * normal).reshape(-1, 3)
    flux = tile.reshape(-1) * scale * green * area
    return summary(flux, centre, frame)


def test_baked_layer_is_one_fixed_mesh_and_one_image_and_each_slice_is_that_frames_layer(
    extension,
):
    from lens_lights.blender.commands import bake

    make_scene()
    generated = {f: generated_layer(f) for f in (1, 2, 3)}
    bpy.context.scene.frame_set(1)
    assert bpy.ops.lens_lights.bake() == {"FINISHED"}
    assert bake.LAST_BAKE["images"] == 1
    (ob,) = layer_objects()  # one object for the floor over the three frames
    assert len(ob.data.polygons) == 1  # a floor's UVs are affine: one quad
    marked = [i for i in bpy.data.images if i.get("lens_lights_created") == "bake"]
    assert len(marked) == 1 and marked[0].packed_file is not None
    counts = set()
    for f in (1, 2, 3):
        bpy.context.scene.frame_set(f)
        assert not ob.hide_render and not ob.hide_viewport
        counts.add((len(ob.data.vertices), len(ob.data.polygons)))
        flux, c = baked_layer(ob, f)
        g_flux, g_c = generated[f]
        assert flux == pytest.approx(g_flux, rel=0.005)  # half floats, the 0.1 % clip
        assert np.linalg.norm(c - g_c) <= 0.01 * R
        light = FIRST + (f - 1) * 0.5 * (LAST - FIRST)
        assert flux == pytest.approx(traced_flux_on_raster(ob, light), rel=0.02)
    assert len(counts) == 1
    assert "layer image" in bpy.context.scene.lens_lights.last_report
    assert bpy.ops.lens_lights.clear() == {"FINISHED"}
    assert lens_lights() == []
    assert not [i for i in bpy.data.images if i.get("lens_lights_created") == "bake"]
    assert not [m for m in bpy.data.materials if m.get("lens_lights_created") == "layer"]
    assert not [a for a in bpy.data.actions if a.get("lens_lights_created") == "bake"]
    # bake again, then one undo step puts the scene back
    bpy.ops.ed.undo_push(message="cleared")
    bpy.ops.lens_lights.bake("EXEC_DEFAULT", True)
    assert len(layer_objects()) == 1
    bpy.ops.ed.undo()
    assert lens_lights() == []
    assert not [i for i in bpy.data.images if i.get("lens_lights_created") == "bake"]


def test_a_glossy_receiver_keeps_its_fitted_spot_per_frame(empty_blend):
    """A mirror floor takes no layer: its caustic is a Fitted spot per frame (as
    Generate makes it), each shown on its own frame only, lighting the mirror only;
    no layer object, no image."""
    sc = bpy.context.scene
    _ball, lamp = basic_scene()
    floor = bpy.data.objects["Floor"]
    mirror = new_material("Mirror")
    mirror.node_tree.nodes["Principled BSDF"].inputs["Metallic"].default_value = 1.0
    floor.data.materials.append(mirror)
    set_engine("BLENDER_EEVEE")
    sc.lens_lights.energy_model = "CAUSTIC_LAYER"
    bpy.ops.object.camera_add(location=(0.0, -8.0, 3.0), rotation=(1.4, 0.0, 0.0))
    sc.camera = bpy.context.object
    sc.frame_start, sc.frame_end = 1, 2
    bpy.context.preferences.edit.keyframe_new_interpolation_type = "LINEAR"
    for f, x in ((1, 0.0), (2, 0.2)):
        lamp.location = (x, 0.0, 4.5)
        lamp.keyframe_insert("location", frame=f)
    sc.frame_set(1)
    assert bpy.ops.lens_lights.bake() == {"FINISHED"}
    assert layer_objects() == []
    spots = [o for o in lens_lights() if o.type == "LIGHT"]
    assert len(spots) == 2
    for f in (1, 2):
        sc.frame_set(f)
        (shown,) = [o for o in spots if not o.hide_render]
        assert shown.data.type == "SPOT"
        assert list(shown.light_linking.receiver_collection.objects) == [floor]
    assert not [i for i in bpy.data.images if i.get("lens_lights_created") == "bake"]


def caustic_figures(diff, hit, light):
    """(centroid's distance from the axis point, brightness at the axis point over
    the exact optics' there) of a caustic image `diff` (radiance)."""
    coords = (np.arange(PX) + 0.5) * (VIEW / PX) - VIEW / 2
    x = np.broadcast_to(hit[0] + coords[None, :], (PX, PX))
    y = np.broadcast_to(hit[1] + coords[:, None], (PX, PX))
    cx, cy = float((diff * x).sum() / diff.sum()), float((diff * y).sum() / diff.sum())
    u = (CENTER - light) / np.linalg.norm(CENTER - light)
    z = CENTER[2] / -u[2]
    patch_r = 1.5 * VIEW / PX
    e = ball_optics.irradiance_on_plane(
        POWER / (4 * math.pi), float(np.linalg.norm(CENTER - light)), R, N, z, [0.0, patch_r]
    )[0]
    radiance = ALBEDO * float(e) * -u[2] / math.pi
    patch = np.hypot(x - hit[0], y - hit[1]) <= patch_r
    return math.hypot(cx - hit[0], cy - hit[1]), float(diff[patch].mean()) / radiance


def test_baked_layer_frame_renders_in_eevee_without_the_extension(extension, tmp_path):
    make_scene()
    assert bpy.ops.lens_lights.bake() == {"FINISHED"}
    blend = tmp_path / "baked.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend), copy=True)
    facts, baked, without = stock_render(blend, tmp_path, 2, timeout=900)
    assert facts["registered"] is False
    diff = baked - without
    off, ratio = caustic_figures(diff, axis_hit(MID), MID)
    print(
        f"\nbaked layer, frame 2 (EEVEE {PX} px): centroid {off:.4f} from the axis point, "
        f"brightness {ratio:.3f} of the exact optics"
    )
    assert off <= VIEW / PX  # one pixel
    assert abs(ratio - 1.0) <= 0.15


def warped_u(x):
    return (x + 30.0) ** 2 / 60.0


def warp_floor_uvs(floor, cuts=119):
    """The floor cut into (cuts + 1)² quads (0.5 m: a few across the camera's view,
    which the layer spans), u = (x + 30)²/60 at its vertices (not affine in the plane:
    the bake's vertex-grid path), v = (y + 30)/60."""
    import bmesh

    me = floor.data
    bm = bmesh.new()
    bm.from_mesh(me)
    bmesh.ops.subdivide_edges(bm, edges=bm.edges[:], cuts=cuts, use_grid_fill=True)
    bm.to_mesh(me)
    bm.free()
    n = len(me.loops)
    vi = np.empty(n, dtype=np.int64)
    me.loops.foreach_get("vertex_index", vi)
    co = np.empty(3 * len(me.vertices))
    me.vertices.foreach_get("co", co)
    xy = co.reshape(-1, 3)[vi, :2] * floor.scale[0]
    uv = np.stack([warped_u(xy[:, 0]), (xy[:, 1] + 30.0) / 60.0], axis=1)
    me.uv_layers.active.data.foreach_set("uv", uv.astype(np.float32).ravel())
    me.update()
    return np.unique(np.round(xy[:, 0], 9))  # the grid's lines along x


def test_a_floor_with_warped_uvs_bakes_one_vertex_grid_with_its_uvs(extension):
    """Where the receiver's UVs are not affine, the baked layer is Generate's vertex grid
    (one topology for all frames), its UVs the floor's UVs interpolated on the floor's
    faces (u = x² is linear between the grid lines), and each frame's slice is that
    frame's layer."""
    built = make_scene()
    lines_x = warp_floor_uvs(built.floor)
    generated = {f: generated_layer(f) for f in (1, 3)}
    bpy.context.scene.frame_set(1)
    assert bpy.ops.lens_lights.bake() == {"FINISHED"}
    (ob,) = layer_objects()
    me = ob.data
    counts = set()
    for f in (1, 3):
        bpy.context.scene.frame_set(f)
        counts.add((len(me.vertices), len(me.polygons)))
        flux, c = baked_layer(ob, f)
        g_flux, g_c = generated[f]
        assert flux == pytest.approx(g_flux, rel=0.005)
        assert np.linalg.norm(c - g_c) <= 0.01 * R
    ((n_verts, n_faces),) = counts
    res = round(math.sqrt(n_faces))
    assert n_faces == res * res > 1 and n_verts == (res + 1) ** 2  # the vertex grid
    # its UVs: the floor's, interpolated linearly between the grid lines
    vi = np.empty(len(me.loops), dtype=np.int64)
    me.loops.foreach_get("vertex_index", vi)
    co = np.empty(3 * n_verts)
    me.vertices.foreach_get("co", co)
    world = np.array(ob.matrix_world)
    xy = (co.reshape(-1, 3) @ world[:3, :3].T + world[:3, 3])[vi, :2]
    uv = np.empty(2 * len(me.loops), dtype=np.float32)
    me.uv_layers["UVMap"].data.foreach_get("uv", uv)
    uv = uv.reshape(-1, 2)
    u_lines = warped_u(lines_x)
    expected_u = np.interp(xy[:, 0], lines_x, u_lines)
    assert np.abs(uv[:, 0] - expected_u).max() < 2e-5
    assert np.abs(uv[:, 1] - (xy[:, 1] + 30.0) / 60.0).max() < 2e-5
    # and not the affine fit: somewhere the piecewise-linear u departs from a line
    fit = np.polyval(np.polyfit(xy[:, 0], uv[:, 0], 1), xy[:, 0])
    assert np.abs(uv[:, 0] - fit).max() > 1e-4
