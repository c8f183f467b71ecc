"""Read a Blender scene as the renderer sees it, into the bpy-free scene model.

`read_blender_scene(context_or_depsgraph)` walks the evaluated depsgraph's object
instances (modifiers, geometry nodes and instancing applied, world space) and
returns a :class:`BlenderSceneRead`:

* ``scene`` — an `addon.scene.Scene`: ``lights`` are the POINT lights (position,
  colour, brightness = power in W, radius); ``objects`` are the meshes whose
  evaluated geometry is a sphere (see `addon/sphere_fit.py` for the tests and
  tolerances), each with a `Surface` from its material (`addon/material_model.py`):
  ``ior``, ``transmission`` (the thesis' kt), ``color``. Opaque spheres are kept:
  they block light (phase 1's obstruction).
* ``sphere_sources`` / ``light_sources`` — the object (or instance) names, parallel
  to ``scene.objects`` / ``scene.lights``;
* ``left_out`` — (name, reason) for every render-enabled light or geometry that is
  not in the model (not a point light, not a sphere, non-uniform scale …);
* for the generator: the original objects (``sphere_objects``, ``light_objects``),
  ``primaries`` (`PrimaryLight`), ``lens_optics`` (`LensOptics`), ``lens_candidates``
  (whether the user could expect a lens there), ``bounds`` of everything rendered.

Rules:

* Objects and lights disabled for rendering (the object's camera-icon
  ``hide_render``, or only in render-disabled collections, or instanced by such an
  object) are ignored. The depsgraph is the view layer's; collections excluded
  from it are not seen.
* Lens mode (``object.lens_lights.lens_mode``): AUTO: the material decides; ALWAYS:
  a lens even if the material is opaque (transmission 1, IOR 1.5 unless known);
  NEVER: an opaque sphere. The IOR override replaces the material's IOR.
* A light's power is ``energy × 2^exposure`` (× the sphere's area 4πr² if its power
  is not normalised); its colour includes the blackbody colour when temperature is used.
* Lights the extension created are skipped entirely.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import bpy
import numpy as np

from ..addon.light_models import LensOptics, PrimaryLight
from ..addon.material_model import (GLASS, OTHER, PRINCIPLED, REFRACTION, Absorption, Add, Bsdf,
                                    MaterialOptics, Mix, evaluate_material)
from ..addon.scene import Camera, Light, Scene, Sphere, Surface
from ..addon.sphere_fit import BOX_RATIO, SphereFit, fit_sphere, to_world

#: IOR used for a lens forced with "Always" when neither the material nor the
#: override gives one.
DEFAULT_LENS_IOR = 1.5
GEOMETRY_TYPES = {"MESH", "CURVE", "SURFACE", "META", "FONT", "CURVES", "POINTCLOUD", "VOLUME",
                  "GREASEPENCIL"}


@dataclass
class BlenderSceneRead:
    scene: Scene
    sphere_sources: list[str] = field(default_factory=list)
    light_sources: list[str] = field(default_factory=list)
    left_out: list[tuple[str, str]] = field(default_factory=list)
    # For the generator (parallel to scene.objects / scene.lights):
    sphere_objects: list = field(default_factory=list)      # original bpy Objects
    light_objects: list = field(default_factory=list)
    lens_optics: list[LensOptics] = field(default_factory=list)
    lens_candidates: list[bool] = field(default_factory=list)
    material_notes: list[list[str]] = field(default_factory=list)
    primaries: list[PrimaryLight] = field(default_factory=list)
    #: (name, reason) of left-out objects that looked like lenses (refracting
    #: material or lens mode Always): the ones worth reporting to the user.
    left_out_lenses: list[tuple[str, str]] = field(default_factory=list)
    bounds: tuple[np.ndarray, np.ndarray] | None = None

    @property
    def scene_size(self) -> float:
        """Diagonal of everything rendered (≥ a tiny positive number)."""
        if self.bounds is None:
            return 1.0
        size = float(np.linalg.norm(self.bounds[1] - self.bounds[0]))
        return size if size > 0 and math.isfinite(size) else 1.0


# --------------------------------------------------------------------------- visibility

def _render_visible_objects(view_layer) -> set:
    """Original objects in at least one collection enabled for rendering."""
    visible = set()

    def walk(layer_coll, parent_hidden):
        coll = layer_coll.collection
        hidden = parent_hidden or layer_coll.exclude or coll.hide_render
        if not hidden:
            visible.update(ob.original for ob in coll.objects)
        for child in layer_coll.children:
            walk(child, hidden)

    walk(view_layer.layer_collection, False)
    return visible


def _is_lens_light(ob) -> bool:
    settings = getattr(ob, "lens_lights", None)
    return bool(settings and settings.is_lens_light)


# --------------------------------------------------------------------------- materials

def _input_value(node, name, default, notes):
    sock = node.inputs.get(name)
    if sock is None:
        return default
    if sock.is_linked:
        src = sock.links[0].from_node
        if src.type == "VALUE":
            return float(src.outputs[0].default_value)
        if src.type == "RGB":
            return tuple(src.outputs[0].default_value)[:3]
        notes.append(f"'{node.name}' {name} is driven by '{src.name}': its own value used")
    value = sock.default_value
    try:
        return tuple(float(x) for x in value)[:3]
    except TypeError:
        return float(value)


def _shader(socket, notes, depth=0):
    """Plain-data shader tree (`addon.material_model`) of what feeds `socket`."""
    if socket is None or not socket.is_linked or depth > 64:
        return None
    link = socket.links[0]
    if not link.is_valid or link.is_muted:
        return None
    node = link.from_node
    if node.type == "REROUTE":
        return _shader(node.inputs[0], notes, depth + 1)
    if node.mute:
        notes.append(f"muted node '{node.name}' ignored")
        return None
    t = node.type
    if t == "BSDF_PRINCIPLED":
        return Bsdf(PRINCIPLED, ior=_input_value(node, "IOR", 1.5, notes),
                    color=_input_value(node, "Base Color", (0.8, 0.8, 0.8), notes),
                    transmission=_input_value(node, "Transmission Weight", 0.0, notes),
                    metallic=_input_value(node, "Metallic", 0.0, notes),
                    alpha=_input_value(node, "Alpha", 1.0, notes), name=node.name)
    if t in ("BSDF_GLASS", "BSDF_REFRACTION"):
        return Bsdf(GLASS if t == "BSDF_GLASS" else REFRACTION,
                    ior=_input_value(node, "IOR", 1.5, notes),
                    color=_input_value(node, "Color", (1.0, 1.0, 1.0), notes), name=node.name)
    if t == "MIX_SHADER":
        fac = _input_value(node, "Fac", 0.5, notes)
        return Mix(fac if isinstance(fac, float) else 0.5,
                   _shader(node.inputs[1], notes, depth + 1), _shader(node.inputs[2], notes, depth + 1))
    if t == "ADD_SHADER":
        return Add(_shader(node.inputs[0], notes, depth + 1), _shader(node.inputs[1], notes, depth + 1))
    if t == "VOLUME_ABSORPTION":
        return Absorption(_input_value(node, "Density", 1.0, notes),
                          _input_value(node, "Color", (0.8, 0.8, 0.8), notes))
    color = _input_value(node, "Color", None, notes) if "Color" in node.inputs else None
    if color is None and "Base Color" in node.inputs:
        color = _input_value(node, "Base Color", None, notes)
    if t in ("GROUP", "CUSTOM"):
        notes.append(f"node '{node.name}' ({node.bl_idname}) not looked into: treated as opaque")
    return Bsdf(OTHER, color=tuple(color) if isinstance(color, tuple) else (0.8, 0.8, 0.8),
                name=node.name)


def material_optics(material) -> MaterialOptics:
    """Lens optics of a Blender material (None: Blender's default grey, opaque)."""
    if material is None:
        return MaterialOptics(notes=["no material"])
    nt = material.node_tree
    if nt is None:
        return MaterialOptics(notes=["material without nodes"])
    out = nt.get_output_node("CYCLES") or nt.get_output_node("ALL")
    if out is None:
        return MaterialOptics(notes=["material without an active output"])
    notes: list[str] = []
    surface = _shader(out.inputs.get("Surface"), notes)
    volume = _shader(out.inputs.get("Volume"), notes)
    optics = evaluate_material(surface, volume)
    optics.notes[:0] = notes
    return optics


def _main_material(ob, mesh):
    """The material of most of the mesh's area (evaluated object: slots resolved)."""
    slots = ob.material_slots
    if not slots:
        return None
    n = len(mesh.polygons)
    if len(slots) > 1 and n:
        idx = np.empty(n, dtype=np.int32)
        mesh.polygons.foreach_get("material_index", idx)
        area = np.empty(n)
        mesh.polygons.foreach_get("area", area)
        k = int(np.argmax(np.bincount(np.clip(idx, 0, len(slots) - 1), weights=area,
                                      minlength=len(slots))))
    else:
        k = 0
    return slots[k].material


# --------------------------------------------------------------------------- geometry

def _mesh_arrays(mesh):
    nv, nf = len(mesh.vertices), len(mesh.polygons)
    v = np.empty(nv * 3)
    mesh.vertices.foreach_get("co", v)
    c = np.empty(nf * 3)
    mesh.polygons.foreach_get("center", c)
    nr = np.empty(nf * 3)
    mesh.polygons.foreach_get("normal", nr)
    a = np.empty(nf)
    mesh.polygons.foreach_get("area", a)
    return v.reshape(-1, 3), c.reshape(-1, 3), nr.reshape(-1, 3), a


def _local_fit(ob, cache):
    """Sphere fit of an evaluated mesh object in its local space (cached per mesh)."""
    mesh = ob.data
    key = mesh.as_pointer()
    if key in cache:
        return cache[key]
    box = np.array([tuple(c) for c in ob.bound_box])
    extent = box.max(axis=0) - box.min(axis=0)
    if not extent.max() > 0 or extent.min() < BOX_RATIO * extent.max():
        dims = " × ".join(f"{e:.3g}" for e in extent)
        fit = SphereFit(False, np.zeros(3), 0.0, f"not a sphere: its bounding box ({dims}) is not a cube")
    else:
        fit = fit_sphere(*_mesh_arrays(mesh))
    cache[key] = fit
    return fit


def _world_box(ob, matrix):
    try:
        corners = np.array([tuple(c) for c in ob.bound_box])
    except (AttributeError, TypeError):
        return None
    if corners.size == 0:
        return None
    w = corners @ matrix[:3, :3].T + matrix[:3, 3]
    return w.min(axis=0), w.max(axis=0)


def _matrix(m) -> np.ndarray:
    return np.array([list(row) for row in m], dtype=float)


def _surface(optics: MaterialOptics, color) -> Surface:
    """Thesis surface block for a sphere (the Phong numbers are approximations for
    the `.bi` exporter: ka 0.1, kd 0.8(1 − kt), ks 0.2 for glass else 0.1, E 80)."""
    kt = float(optics.transmission)
    return Surface(color=tuple(float(c) for c in color), ambient=0.1,
                   diffuse=round(0.8 * (1.0 - kt), 6), specular=0.2 if kt > 0 else 0.1,
                   transmission=kt, exponent=80.0, ior=float(optics.ior) if kt > 0 else 1.0)


def _camera(scene) -> Camera:
    cam = scene.camera
    if cam is None or cam.type != "CAMERA":
        return Camera()
    m = _matrix(cam.matrix_world)
    pos = m[:3, 3]
    fwd = -m[:3, 2] / np.linalg.norm(m[:3, 2])
    up = m[:3, 1] / np.linalg.norm(m[:3, 1])
    data = cam.data
    r = scene.render
    w, h = r.resolution_x * r.resolution_percentage // 100, r.resolution_y * r.resolution_percentage // 100
    if data.type == "PERSP":
        fov = (math.degrees(data.angle_x), math.degrees(data.angle_y))
        if data.sensor_fit == "AUTO":   # the sensor spans the larger image side
            big = data.angle
            half_tan = math.tan(big / 2)
            if w >= h:
                fov = (math.degrees(big), math.degrees(2 * math.atan(half_tan * h / w)))
            else:
                fov = (math.degrees(2 * math.atan(half_tan * w / h)), math.degrees(big))
    else:
        fov = (45.0, 45.0)
    target = pos + fwd * 10.0
    return Camera(position=tuple(pos), target=tuple(target), up=tuple(up),
                  fov_deg=(float(fov[0]), float(fov[1])))


# --------------------------------------------------------------------------- main

def read_blender_scene(context_or_depsgraph) -> BlenderSceneRead:
    """The scene as the renderer sees it (see the module's docstring)."""
    if isinstance(context_or_depsgraph, bpy.types.Depsgraph):
        depsgraph = context_or_depsgraph
    else:
        depsgraph = context_or_depsgraph.evaluated_depsgraph_get()
    scene = depsgraph.scene          # originals (the depsgraph's own, not evaluated copies)
    view_layer = depsgraph.view_layer
    visible = _render_visible_objects(view_layer)
    r = scene.render
    model = Scene(width=r.resolution_x * r.resolution_percentage // 100,
                  height=r.resolution_y * r.resolution_percentage // 100,
                  camera=_camera(scene))
    out = BlenderSceneRead(scene=model)
    fit_cache: dict = {}
    optics_cache: dict = {}
    lo, hi = [], []
    names_seen: dict[str, int] = {}

    for inst in depsgraph.object_instances:
        ob = inst.object
        orig = ob.original
        if _is_lens_light(orig):
            continue
        if inst.is_instance:
            parent = inst.parent.original
            if parent.hide_render or parent not in visible or orig.hide_render:
                continue
            base = f"{parent.name}/{ob.name}"
        else:
            if orig.hide_render or orig not in visible:
                continue
            base = ob.name
        count = names_seen.get(base, 0)
        names_seen[base] = count + 1
        name = base if count == 0 else f"{base}#{count}"
        matrix = _matrix(inst.matrix_world)

        if ob.type == "LIGHT":
            _read_light(out, ob, orig, name, matrix)
            lo.append(matrix[:3, 3])
            hi.append(matrix[:3, 3])
            continue
        if ob.type not in GEOMETRY_TYPES:
            continue
        box = _world_box(ob, matrix)
        if box is not None:
            lo.append(box[0])
            hi.append(box[1])
        _read_geometry(out, ob, orig, name, matrix, fit_cache, optics_cache)

    if lo:
        out.bounds = (np.min(lo, axis=0), np.max(hi, axis=0))
    return out


def _read_light(out: BlenderSceneRead, ob, orig, name, matrix):
    ld = ob.data
    if ld.type != "POINT":
        out.left_out.append((name, f"{ld.type.lower()} light: only point lights make lens lights"))
        return
    power = float(ld.energy) * 2.0 ** float(getattr(ld, "exposure", 0.0))
    radius = float(ld.shadow_soft_size)
    if not getattr(ld, "normalize", True) and radius > 0:
        power *= 4.0 * math.pi * radius * radius
    color = np.array(ld.color[:3], dtype=float)
    if getattr(ld, "use_temperature", False):
        color = color * np.array(ld.temperature_color[:3], dtype=float)
    if not power > 0 or not math.isfinite(power):
        out.left_out.append((name, f"point light without power ({power:g} W)"))
        return
    pos = tuple(float(x) for x in matrix[:3, 3])
    out.scene.lights.append(Light(position=pos, color=tuple(color), brightness=power,
                                  radius=radius, name=name))
    out.primaries.append(PrimaryLight(power_w=power, radius=radius, color=tuple(color)))
    out.light_sources.append(name)
    out.light_objects.append(orig)


def _read_geometry(out: BlenderSceneRead, ob, orig, name, matrix, fit_cache, optics_cache):
    settings = getattr(orig, "lens_lights", None)
    mode = settings.lens_mode if settings else "AUTO"
    if ob.type != "MESH":
        if mode == "ALWAYS":
            out.left_out_lenses.append((name, f"not a mesh ({ob.type.lower()})"))
        out.left_out.append((name, f"not a mesh ({ob.type.lower()})"))
        return
    mesh = ob.data
    material = _main_material(ob, mesh)
    key = material.as_pointer() if material is not None else 0
    optics = optics_cache.get(key)
    if optics is None:
        optics = optics_cache[key] = material_optics(material)
    looks_like_lens = mode == "ALWAYS" or (mode == "AUTO" and optics.is_transmissive)

    fit = _local_fit(ob, fit_cache)
    reason = None
    if not fit.ok:
        reason = fit.reason
    else:
        world = to_world(fit.center, fit.radius, matrix)
        if world is None:
            scale = np.linalg.norm(matrix[:3, :3], axis=0)
            reason = ("non-uniform scale (" + ", ".join(f"{s:.4g}" for s in scale)
                      + "): an ellipsoid, not a sphere")
    if reason is not None:
        out.left_out.append((name, reason))
        if looks_like_lens:
            out.left_out_lenses.append((name, reason))
        return
    center, radius = world

    ior = optics.ior
    kt = optics.transmission
    weight = kt
    if mode == "NEVER":
        kt = weight = 0.0
    elif mode == "ALWAYS" and not optics.is_transmissive:
        kt = weight = 1.0
        ior = DEFAULT_LENS_IOR
    if settings and settings.use_ior_override and mode != "NEVER":
        ior = float(settings.ior_override)
    lens_like = kt > 0.0 and ior > 1.0
    surface_optics = MaterialOptics(ior=ior, transmission=kt, tint=optics.tint,
                                    absorption=optics.absorption)
    color = optics.color if material is not None and material.node_tree is not None \
        else (tuple(material.diffuse_color[:3]) if material is not None else (0.8, 0.8, 0.8))
    out.scene.objects.append(Sphere(center=tuple(float(x) for x in center), radius=radius,
                                    surface=_surface(surface_optics, color), name=name))
    out.sphere_sources.append(name)
    out.sphere_objects.append(orig)
    out.lens_optics.append(LensOptics(transmission_weight=weight, tint=tuple(optics.tint),
                                      absorption=tuple(optics.absorption)))
    out.lens_candidates.append(lens_like)
    out.material_notes.append(list(optics.notes))

