"""A `.bi` scene ↔ Blender data: what the importer builds and the exporter reads.

The numeric rules (opening angles → focal length, brightness → watts, surface →
Principled BSDF) live in the bpy-free `core/bi/conversions.py`; this module only
creates and reads Blender data with them.

The importer stores each record's numbers as a custom property `lens_lights_bi` on
the object (camera, light, sphere) and on the sphere's material, and the file's
colour scale on the scene (`lens_lights_bi_color_scale`). The exporter writes the
stored numbers back while Blender's values still match them (Blender keeps float32;
an edit of more than 1e-5 relative wins), so import → export reproduces the file.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import bmesh
import bpy
from mathutils import Matrix, Vector

from ...core.bi import conversions as conv
from ...core.bi.records import (
    as_tuple,
    f32,
    f32v,
    light_name,
    order_key,
    scene_extent,
    sphere_name,
    surface_dict,
    surface_from_dict,
)
from ...core.scene.model import Camera, Light, Scene, Sphere, Surface
from ..read.materials import node_tree
from ..read.scene import read_blender_scene

#: Custom property with the `.bi` numbers of an imported object or material.
PROP = "lens_lights_bi"
#: Scene custom property: the colour scale (1 or 255) of the imported file.
COLOR_SCALE_PROP = "lens_lights_bi_color_scale"
#: UV sphere resolution of imported spheres (smooth shaded).
SPHERE_SEGMENTS, SPHERE_RINGS = 64, 32
#: Relative tolerance under which Blender's value is "still the file's number".
STORED_TOLERANCE = 1e-5


# --------------------------------------------------------------------------- import


@dataclass
class BuiltScene:
    collection: bpy.types.Collection
    camera: bpy.types.Object
    lights: list = field(default_factory=list)
    spheres: list = field(default_factory=list)
    warnings: list = field(default_factory=list)


def _principled(material) -> bpy.types.Node:
    """The Principled BSDF of a material, creating the node tree if needed."""
    if material.node_tree is None or (bpy.app.version < (5, 0, 0) and not material.use_nodes):
        material.use_nodes = True  # Blender 4.x; always on from 5.0
    tree = material.node_tree
    node = next((n for n in tree.nodes if n.type == "BSDF_PRINCIPLED"), None)
    if node is None:
        node = tree.nodes.new("ShaderNodeBsdfPrincipled")
        out = next((n for n in tree.nodes if n.type == "OUTPUT_MATERIAL"), None) or tree.nodes.new(
            "ShaderNodeOutputMaterial"
        )
        tree.links.new(node.outputs["BSDF"], out.inputs["Surface"])
    return node


def make_material(name: str, surface: Surface) -> bpy.types.Material:
    material = bpy.data.materials.new(name)
    node = _principled(material)
    values = conv.principled_from_surface(surface)
    for key, value in values.items():
        node.inputs[key].default_value = value
    material.diffuse_color = conv.viewport_color(surface)
    material.metallic = values["Metallic"]
    material.roughness = values["Roughness"]
    material[PROP] = surface_dict(surface)
    return material


def _sphere_mesh(name: str) -> bpy.types.Mesh:
    mesh = bpy.data.meshes.new(name)
    bm = bmesh.new()
    try:
        bmesh.ops.create_uvsphere(
            bm, u_segments=SPHERE_SEGMENTS, v_segments=SPHERE_RINGS, radius=1.0
        )
        for face in bm.faces:
            face.smooth = True
        bm.to_mesh(mesh)
    finally:
        bm.free()
    return mesh


def build_camera(scene: Scene, context, collection, name: str = "Camera"):
    """The scene camera and render settings; returns (object, warnings)."""
    bc = conv.camera_to_blender(scene.camera, scene.width, scene.height)
    data = bpy.data.cameras.new(name)
    data.type = "PERSP"
    data.sensor_fit = bc.sensor_fit
    data.sensor_width = bc.sensor_width
    data.sensor_height = bc.sensor_height
    data.lens_unit = "MILLIMETERS"
    data.lens = bc.lens
    data.dof.focus_distance = bc.focus_distance
    extent = scene_extent(scene)
    data.clip_end = max(100.0, 2.0 * extent)
    data.clip_start = max(1e-6, min(0.1, extent * 1e-4))
    obj = bpy.data.objects.new(name, data)
    collection.objects.link(obj)
    obj.location = scene.camera.position
    obj.rotation_mode = "XYZ"
    obj.rotation_euler = Matrix([list(row) for row in bc.rotation]).to_euler("XYZ")
    cam = scene.camera
    obj[PROP] = {
        "position": list(cam.position),
        "target": list(cam.target),
        "up": list(cam.up),
        "fov": list(cam.fov_deg),
        "viewport": [scene.width, scene.height],
    }
    render = context.scene.render
    render.resolution_x, render.resolution_y = bc.resolution_x, bc.resolution_y
    render.resolution_percentage = 100
    render.pixel_aspect_x, render.pixel_aspect_y = bc.pixel_aspect_x, bc.pixel_aspect_y
    context.scene.camera = obj
    warnings = []
    if bc.up_was_parallel:
        warnings.append("the camera's up vector is parallel to its view; another up was used")
    return obj, warnings


def build_light(light: Light, index: int, collection) -> bpy.types.Object:
    name = light.name or light_name(index)
    data = bpy.data.lights.new(name, "POINT")
    data.energy = conv.watts_from_brightness(light.brightness)
    data.color = light.color
    data.shadow_soft_size = light.radius
    obj = bpy.data.objects.new(name, data)
    collection.objects.link(obj)
    obj.location = light.position
    obj[PROP] = {
        "index": index,
        "position": list(light.position),
        "color": list(light.color),
        "brightness": light.brightness,
    }
    return obj


def build_sphere(sphere: Sphere, index: int, collection) -> bpy.types.Object:
    name = sphere.name or sphere_name(index)
    mesh = _sphere_mesh(name)
    mesh.materials.append(make_material(name, sphere.surface))
    obj = bpy.data.objects.new(name, mesh)
    collection.objects.link(obj)
    obj.location = sphere.center
    obj.scale = (sphere.radius,) * 3
    obj[PROP] = {"index": index, "center": list(sphere.center), "radius": sphere.radius}
    return obj


WORLD_NAME = "Bitracer ambient"


def build_world(context) -> bpy.types.World:
    """The thesis' ambient light (0.1 grey) as the world's light, seen black by the
    camera (the thesis' black background): a new world for the scene."""
    world = bpy.data.worlds.get(WORLD_NAME) or bpy.data.worlds.new(WORLD_NAME)
    world.color = conv.AMBIENT_COLOR
    if world.node_tree is None or (bpy.app.version < (5, 0, 0) and not world.use_nodes):
        world.use_nodes = True
    tree = world.node_tree
    tree.nodes.clear()
    out = tree.nodes.new("ShaderNodeOutputWorld")
    ambient = tree.nodes.new("ShaderNodeBackground")
    ambient.inputs["Color"].default_value = (*conv.AMBIENT_COLOR, 1.0)
    ambient.inputs["Strength"].default_value = 1.0
    black = tree.nodes.new("ShaderNodeBackground")
    black.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
    black.inputs["Strength"].default_value = 0.0
    path = tree.nodes.new("ShaderNodeLightPath")
    mix = tree.nodes.new("ShaderNodeMixShader")
    tree.links.new(path.outputs["Is Camera Ray"], mix.inputs["Fac"])
    tree.links.new(ambient.outputs["Background"], mix.inputs[1])
    tree.links.new(black.outputs["Background"], mix.inputs[2])
    tree.links.new(mix.outputs["Shader"], out.inputs["Surface"])
    for node, x in ((path, -400), (ambient, -400), (black, -400), (mix, -150), (out, 100)):
        node.location.x = x
    path.location.y, ambient.location.y, black.location.y = 300, 0, -150
    context.scene.world = world
    return world


def build_scene(scene: Scene, context, name: str = "bi scene", progress=None) -> BuiltScene:
    """Create the camera, lights, spheres (with materials) and world of `scene`
    in a new collection `name` of the current Blender scene. Raises ValueError
    for what Blender cannot represent (checked before anything is created)."""
    conv.camera_to_blender(scene.camera, scene.width, scene.height)  # validate first
    collection = bpy.data.collections.new(name)
    context.scene.collection.children.link(collection)
    camera, warnings = build_camera(scene, context, collection)
    built = BuiltScene(collection=collection, camera=camera, warnings=warnings)
    total = len(scene.lights) + len(scene.objects)
    for i, light in enumerate(scene.lights):
        built.lights.append(build_light(light, i, collection))
        if progress:
            progress(i + 1, total)
    for i, sphere in enumerate(scene.objects):
        built.spheres.append(build_sphere(sphere, i, collection))
        if progress:
            progress(len(scene.lights) + i + 1, total)
    build_world(context)
    context.scene[COLOR_SCALE_PROP] = scene.color_scale
    return built


# --------------------------------------------------------------------------- export


@dataclass
class ExportRead:
    scene: Scene
    left_out: list = field(default_factory=list)  # (name, reason)
    warnings: list = field(default_factory=list)


def _stored(idblock):
    value = idblock.get(PROP) if idblock is not None else None
    if value is None:
        return None
    try:
        return value.to_dict()
    except AttributeError:
        return None


def principled_inputs(material) -> dict | None:
    """Values of the inputs of a material's Principled BSDF (the one feeding the
    output, or the first), or None without one."""
    tree = node_tree(material) if material is not None else None
    if tree is None:
        return None
    nodes = [n for n in tree.nodes if n.type == "BSDF_PRINCIPLED"]
    if not nodes:
        return None
    node = nodes[0]
    out = {}
    for key in ("Base Color", "Metallic", "Roughness", "IOR", "Transmission Weight"):
        socket = node.inputs.get(key)
        if socket is not None:
            value = socket.default_value
            out[key] = tuple(value) if hasattr(value, "__len__") else float(value)
    return out


def surface_of_material(material, fallback: Surface | None = None) -> Surface:
    """The `.bi` surface of a material: the imported numbers while its Principled
    BSDF still shows them, else read from the Principled BSDF, else `fallback`."""
    inputs = principled_inputs(material)
    stored = _stored(material)
    if inputs is not None and stored is not None:
        try:
            surface = surface_from_dict(stored)
            if conv.principled_matches(conv.principled_from_surface(surface), inputs):
                return surface
        except (KeyError, TypeError, ValueError):
            pass
    if inputs is not None:
        s = conv.surface_from_principled(inputs, tuple(material.diffuse_color))
        return Surface(
            color=f32v(s.color),
            ambient=s.ambient,
            diffuse=f32(s.diffuse),
            specular=f32(s.specular),
            transmission=f32(s.transmission),
            exponent=f32(s.exponent),
            ior=f32(s.ior),
        )
    return fallback if fallback is not None else Surface()


def read_camera(context, warnings: list) -> tuple[Camera, int, int]:
    """The `.bi` camera and viewport size of the scene's active camera."""
    bscene = context.scene
    render = bscene.render
    width, height = int(render.resolution_x), int(render.resolution_y)
    obj = bscene.camera
    if obj is None or obj.type != "CAMERA":
        warnings.append("the scene has no camera: a default camera was written")
        return Camera(), width, height
    data = obj.data
    if data.type != "PERSP":
        warnings.append(
            f"camera '{obj.name}' is {data.type.lower()}, not perspective: "
            "written as a perspective camera with its focal length"
        )
    if data.shift_x or data.shift_y:
        warnings.append(f"camera '{obj.name}': lens shift cannot be written in .bi; ignored")
    depsgraph = context.evaluated_depsgraph_get()
    matrix = obj.evaluated_get(depsgraph).matrix_world
    position = matrix.translation
    rotation = matrix.to_3x3().normalized()
    forward = -Vector(rotation.col[2])
    distance = data.dof.focus_distance
    if data.dof.focus_object is not None:
        along = (data.dof.focus_object.matrix_world.translation - position).dot(forward)
        if along > 0:
            distance = along
    fov = conv.fov_from_blender(
        data.lens,
        data.sensor_width,
        data.sensor_height,
        data.sensor_fit,
        width,
        height,
        render.pixel_aspect_x,
        render.pixel_aspect_y,
    )
    camera = conv.camera_from_blender(
        [f32(c) for c in position],
        [list(r) for r in rotation],
        distance,
        (f32(fov[0]), f32(fov[1])),
    )
    camera = Camera(
        position=camera.position,
        target=f32v(camera.target),
        up=f32v(camera.up),
        fov_deg=camera.fov_deg,
    )
    stored = _stored(obj)
    if stored is not None:
        try:
            file_cam = Camera(
                position=tuple(stored["position"]),
                target=tuple(stored["target"]),
                up=tuple(stored["up"]),
                fov_deg=tuple(stored["fov"]),
            )
            if conv.same_view(camera, file_cam, STORED_TOLERANCE) and conv.close(
                camera.fov_deg, file_cam.fov_deg, STORED_TOLERANCE
            ):
                camera = file_cam
        except (KeyError, TypeError, ValueError):
            pass
    return camera, width, height


def read_for_export(context) -> ExportRead:
    """The Blender scene as a `.bi` scene: the active camera, the point lights and
    the objects phase 1 recognises as spheres (blender/read/scene.py); every
    other object is listed in `left_out` with the reason."""
    read = read_blender_scene(context)
    warnings: list = []
    camera, width, height = read_camera(context, warnings)

    lights = []
    for name, light in zip(read.point_light_sources, read.scene.lights, strict=True):
        obj = bpy.data.objects.get(name)
        stored = _stored(obj) or {}
        position = conv.prefer_stored(
            f32v(light.position), as_tuple(stored.get("position")), STORED_TOLERANCE
        )
        color = conv.prefer_stored(
            f32v(light.color), as_tuple(stored.get("color")), STORED_TOLERANCE
        )
        brightness = conv.prefer_stored(
            f32(conv.brightness_from_watts(light.brightness)),
            stored.get("brightness"),
            STORED_TOLERANCE,
        )
        lights.append(
            (
                order_key(stored, name),
                Light(position=position, color=color, brightness=brightness, name=name),
            )
        )

    spheres = []
    for name, sphere in zip(read.sphere_sources, read.scene.objects, strict=True):
        obj = bpy.data.objects.get(name)
        stored = _stored(obj) or {}
        radius = conv.prefer_stored(f32(sphere.radius), stored.get("radius"), STORED_TOLERANCE)
        center = conv.prefer_stored(
            f32v(sphere.center), as_tuple(stored.get("center")), STORED_TOLERANCE, scale=radius
        )
        material = obj.active_material if obj is not None else None
        surface = surface_of_material(material, fallback=sphere.surface)
        spheres.append(
            (
                order_key(stored, name),
                Sphere(center=center, radius=radius, surface=surface, name=name),
            )
        )

    lights.sort(key=lambda t: t[0])
    spheres.sort(key=lambda t: t[0])
    scale = float(context.scene.get(COLOR_SCALE_PROP, 1.0))
    scene = Scene(
        width=width,
        height=height,
        camera=camera,
        lights=[light for _, light in lights],
        objects=[s for _, s in spheres],
        color_scale=255.0 if scale == 255.0 else 1.0,
    )
    # The `.bi` model has point lights only: the other types are named.
    others = [
        (
            name,
            f"{type(p).__name__.removesuffix('Primary').lower()} light: the .bi "
            "format has point lights only",
        )
        for name, p in zip(read.light_sources, read.primary_lights, strict=True)
        if name not in read.point_light_sources
    ]
    return ExportRead(scene=scene, left_out=others + list(read.left_out), warnings=warnings)
