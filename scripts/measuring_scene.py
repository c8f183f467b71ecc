"""The measuring scene of the render checks (bpy): a white Lambertian floor seen
straight down by an orthographic camera, optionally a clear glass ball and a point
light above it; no world light, Standard view transform, exposure 0, linear
32-bit OpenEXR output, so that a pixel is the floor's radiance
``albedo · E / π`` (E the irradiance in W/m²).

Used by the render tests and benches (tests/blender/build/test_blender_render.py,
tests/blender/build/test_blockers_render.py, bench/render_compare.py, bench/blockers.py,
bench/blender_light_check.py …; import it with `scripts/` on `sys.path`, as
tests/conftest.py puts it). The samplers (Cycles' bounces, samples, pixel filter,
EEVEE's options) differ between them and stay with each caller, but for
`direct_light_only`, which most Cycles checks share.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any


@dataclass
class MeasuringScene:
    scene: Any
    floor: Any
    ball: Any = None  # None: no ball
    lamp: Any = None  # None: no point light
    camera: Any = None


def new_measuring_scene(engine: str, resolution: int | tuple[int, int]):
    """An empty file whose scene renders `resolution` pixels (an int: square)
    with `engine` ('CYCLES', 'BLENDER_EEVEE', …), in linear 32-bit OpenEXR,
    Standard view transform, no look, exposure 0, gamma 1, an opaque film and
    no world (black: `bpy.data.worlds.new()` would bring a 0.05 grey)."""
    import bpy

    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    if engine == "BLENDER_EEVEE" and bpy.app.version < (5, 0, 0):
        engine = "BLENDER_EEVEE_NEXT"  # EEVEE's identifier in 4.2–4.5
    sc.render.engine = engine
    w, h = (resolution, resolution) if isinstance(resolution, int) else resolution
    sc.render.resolution_x, sc.render.resolution_y = w, h
    sc.render.resolution_percentage = 100
    sc.render.film_transparent = False
    sc.view_settings.view_transform = "Standard"
    sc.view_settings.look = "None"
    sc.view_settings.exposure = 0.0
    sc.view_settings.gamma = 1.0
    sc.render.image_settings.file_format = "OPEN_EXR"
    sc.render.image_settings.color_depth = "32"
    sc.world = None
    if engine == "CYCLES":
        sc.cycles.device = "CPU"
    return sc


def new_material(name: str):
    """A material with its node tree (Principled BSDF → Material Output); before
    Blender 5.0 a new material has no nodes until `use_nodes` is set."""
    import bpy

    mat = bpy.data.materials.new(name)
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    return mat


def add_diffuse_floor(size: float, albedo: float = 0.8, name: str = "Floor"):
    """A square plane of `size` at z = 0 with a grey Diffuse BSDF of `albedo`."""
    import bpy

    mat = new_material(name)
    nt = mat.node_tree
    nt.nodes.remove(nt.nodes["Principled BSDF"])
    diffuse = nt.nodes.new("ShaderNodeBsdfDiffuse")
    diffuse.inputs["Color"].default_value = (albedo, albedo, albedo, 1.0)
    nt.links.new(diffuse.outputs[0], nt.nodes["Material Output"].inputs["Surface"])
    bpy.ops.mesh.primitive_plane_add(size=size)
    floor = bpy.context.object
    floor.name = name
    floor.data.materials.append(mat)
    return floor


def add_glass_ball(
    radius: float,
    location,
    ior: float = 1.5,
    segments: int = 48,
    rings: int = 24,
    name: str = "Ball",
    material=None,
    hide_from_indirect: bool = False,
):
    """A smooth-shaded UV sphere of clear glass (Principled BSDF: transmission 1,
    roughness 0, white) hidden from the camera (the floor under it shows through;
    it still casts its shadow and caustic); `hide_from_indirect` also hides it
    from diffuse and glossy rays. `material`: reuse that glass."""
    import bpy

    if material is None:
        material = new_material("Glass")
        bsdf = material.node_tree.nodes["Principled BSDF"]
        bsdf.inputs["Transmission Weight"].default_value = 1.0
        bsdf.inputs["IOR"].default_value = ior
        bsdf.inputs["Roughness"].default_value = 0.0
        bsdf.inputs["Base Color"].default_value = (1.0, 1.0, 1.0, 1.0)  # clear glass
    bpy.ops.mesh.primitive_uv_sphere_add(
        radius=radius, location=tuple(location), segments=segments, ring_count=rings
    )
    ball = bpy.context.object
    ball.name = name
    ball.data.materials.append(material)
    bpy.ops.object.shade_smooth()
    ball.visible_camera = False
    if hide_from_indirect:
        ball.visible_diffuse = False
        ball.visible_glossy = False
    return ball


def add_point_light(location, power: float, radius: float = 0.0, name: str = "Lamp"):
    """A point light of `power` W and `radius` (0: a true point)."""
    import bpy

    data = bpy.data.lights.new(name, "POINT")
    data.energy = power
    data.shadow_soft_size = radius
    lamp = bpy.data.objects.new(name, data)
    bpy.context.scene.collection.objects.link(lamp)
    lamp.location = tuple(location)
    return lamp


def add_top_camera(
    x: float,
    y: float,
    height: float,
    view: float,
    clip_end: float | None = None,
    name: str = "Camera",
):
    """An orthographic camera at (x, y, height) looking straight down (unrotated:
    image x is world x, image y world y), `view` metres wide; the scene's camera."""
    import bpy

    cam = bpy.data.objects.new(name, bpy.data.cameras.new(name))
    bpy.context.scene.collection.objects.link(cam)
    cam.data.type = "ORTHO"
    cam.data.ortho_scale = view
    if clip_end is not None:
        cam.data.clip_end = clip_end
    cam.location = (x, y, height)
    bpy.context.scene.camera = cam
    return cam


def build_measuring_scene(
    engine: str,
    *,
    resolution,
    floor_size: float,
    albedo: float = 0.8,
    view: float,
    camera_xy=(0.0, 0.0),
    camera_height: float,
    clip_end: float | None = None,
    ball: dict | None = None,
    lamp: dict | None = None,
) -> MeasuringScene:
    """The whole scene: `new_measuring_scene`, the floor, then the ball
    (`ball`: keyword arguments of `add_glass_ball`, None: no ball), the point
    light (`lamp`: of `add_point_light`, None: none) and the camera, in this
    order."""
    sc = new_measuring_scene(engine, resolution)
    floor = add_diffuse_floor(floor_size, albedo)
    ball_ob = add_glass_ball(**ball) if ball is not None else None
    lamp_ob = add_point_light(**lamp) if lamp is not None else None
    camera = add_top_camera(camera_xy[0], camera_xy[1], camera_height, view, clip_end)
    return MeasuringScene(sc, floor, ball_ob, lamp_ob, camera)


def direct_light_only(sc, samples: int) -> None:
    """Cycles renders direct light alone: no bounce, no caustic of its own, no
    denoiser, a fixed seed (what the analytic references model)."""
    c = sc.cycles
    c.samples = samples
    c.max_bounces = 0
    c.use_denoising = False
    c.caustics_refractive = False
    c.caustics_reflective = False
    c.seed = 1


def measured_render_settings(sc, engine: str, samples: int) -> None:
    """The benches' plain render settings: `samples`, no denoiser or adaptive sampling,
    a one-pixel box filter and a fixed seed in Cycles; in EEVEE no ray tracing,
    shadows on, a one-pixel filter (what a pixel-by-pixel comparison needs)."""
    if engine == "CYCLES":
        c = sc.cycles
        c.samples = samples
        c.use_denoising = False
        c.use_adaptive_sampling = False
        c.pixel_filter_type = "BOX"
        c.filter_width = 1.0
        c.seed = 1
        return
    sc.eevee.taa_render_samples = samples
    for attr, value in (("use_raytracing", False), ("use_shadows", True)):
        if hasattr(sc.eevee, attr):
            setattr(sc.eevee, attr, value)
    if hasattr(sc.render, "filter_size"):
        sc.render.filter_size = 1.0


def render_irradiance(sc, path, albedo: float):
    """(the irradiance a white-ish Lambertian floor of `albedo` shows per pixel,
    ``π · grey / albedo`` (W/m², rows from the bottom), the render's seconds)."""
    import math
    import time

    t0 = time.perf_counter()
    grey = render_grey(sc, path)
    return grey * math.pi / albedo, time.perf_counter() - t0


def render_grey(sc, path):
    """Renders `sc` to `path` and returns the mean of the RGB channels per pixel
    (rows from the bottom, as Blender's images store them)."""
    import bpy
    import numpy as np

    sc.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)
    img = bpy.data.images.load(str(path))
    px = np.array(img.pixels[:], dtype=float).reshape(img.size[1], img.size[0], 4)
    bpy.data.images.remove(img)
    return px[..., :3].mean(axis=2)
