"""Read a Blender scene as the renderer sees it, into the bpy-free scene model.

**Which depsgraph.** A final render (F12) evaluates the scene in a *render*
depsgraph (``Depsgraph.mode == 'RENDER'``): render visibility (the object's and
the collections' camera icon, view-layer exclusion), modifiers' render settings
(Subdivision's render levels, ``show_render``), geometry nodes' "Is Viewport",
instancers' ``show_instancer_for_render``.  The depsgraph Python gets from
``context.evaluated_depsgraph_get()`` is the *viewport* one: objects disabled in
the viewport (monitor icon, also on a collection) or hidden (eye icon) are not in
it at all, objects disabled for rendering are, and modifiers use their viewport
settings.  Python cannot create a render depsgraph; only a render engine is handed
one.  So :func:`rendered_depsgraph` runs a function on the depsgraph of a real,
tiny render:

1. it copies the context scene (``Scene.copy()``: a shallow copy with the same
   objects and child collections, copies of the view layers with their
   exclusions, and of the render settings), sets the copy's engine to a probe
   engine registered only for this (so it never shows in the engine menu), turns
   compositing and the sequencer off in the copy, keeps only the context's view
   layer, shrinks the resolution, and renders the copy
   (``bpy.ops.render.render(scene=copy, layer=view layer)``);
2. the probe's ``render(depsgraph)`` calls the function with the render
   depsgraph (Blender evaluates it exactly as for F12) and keeps its result;
3. the copy (and a temporary camera, added to the copy only when the scene has
   none: a render needs one), the probe engine and, if the probe created it, the
   "Render Result" image are removed.

The user's scene is never changed, and their last render is kept (the copy
renders into its own render result).  The render handlers
(``bpy.app.handlers.render_*``) do run, with the copy as their scene.  When the
probe cannot run (a render is in progress, the render is refused), the viewport
depsgraph is read instead with the render-visibility rules applied by hand, and
the read says so (``BlenderSceneRead.how``).

**Reading.** `read_depsgraph(depsgraph)` walks the depsgraph's object instances
(modifiers, geometry nodes and instancing applied, world space).  The per-instance
work is only to note which evaluated object/data/original it is and to copy its
matrix; everything else is done once per *group* of instances that share these
(an instanced sphere is fitted and its material evaluated once, however many
instances there are), then in numpy over all instances (world centres and radii,
the uniform-scale test, bounding boxes, names).  It returns a
:class:`BlenderSceneRead`:

* ``arrays`` — `addon.phase1.SceneArrays`: the POINT lights (position, power in W,
  colour) and the spheres (centre, radius, IOR, kt) for phase 1; ``scene`` — the
  same as an `addon.scene.Scene` (made on first use; the `.bi` exporter's);
* ``sphere_sources`` / ``light_sources`` — the object (or instance: "instancer/
  object", "#k" for repeats) names, parallel to the spheres / lights;
* ``left_out`` — (name, reason) for every render-enabled light or geometry that is
  not in the model (not a point light, not a sphere, non-uniform or zero scale …);
  the instances of one instancer left out for one reason are one entry
  ("Grid/Cube (250 instances)");
* for the generator: ``sphere_objects`` / ``light_objects`` (original objects: for
  geometry-nodes instances the instancer), ``primaries`` (`PrimaryLight`),
  ``lens_optics`` (`LensOptics`), ``lens_candidates`` (a numpy bool array: could the
  user expect a lens there), ``bounds`` of everything rendered, and ``occluders``
  (`occluders.Occluders`: the spheres and the other meshes, for the rays that keep
  a beam's spot clear of the geometry behind its lens; it reads the evaluated
  meshes lazily, so it is usable only while the depsgraph is, and is released
  after a probe).

Rules:

* Lens mode (``object.lens_lights.lens_mode``, of the original object; for
  geometry-nodes instances the instancer's): AUTO: the material decides; ALWAYS:
  a lens even if the material is opaque (transmission 1, IOR 1.5 unless known);
  NEVER: an opaque sphere. The IOR override replaces the material's IOR.
* A light's power is ``energy × 2^exposure`` (× the sphere's area 4πr² if its power
  is not normalised); its colour includes the blackbody colour when temperature is used.
* A sphere's transform may rotate, mirror (negative scale) and scale uniformly;
  a non-uniform scale (an ellipsoid) or a zero scale is left out and named.
  Meshes without vertices (e.g. an instancer's own empty mesh) are ignored.
* Lights the extension created are skipped entirely.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import bpy
import numpy as np

from ..addon.tiers import LensOptics, PrimaryLight
from ..addon.material_model import (GLASS, OTHER, PRINCIPLED, REFRACTION, Absorption, Add, Bsdf,
                                    MaterialOptics, Mix, evaluate_material)
from ..addon.phase1 import SceneArrays
from ..addon.scene import Camera, Light, Scene, Sphere, Surface
from ..addon.sphere_fit import BOX_RATIO, SphereFit, fit_sphere, uniform_scales
from .occluders import MeshSource, Occluders

#: IOR used for a lens forced with "Always" when neither the material nor the
#: override gives one.
DEFAULT_LENS_IOR = 1.5
GEOMETRY_TYPES = {"MESH", "CURVE", "SURFACE", "META", "FONT", "CURVES", "POINTCLOUD", "VOLUME",
                  "GREASEPENCIL"}
#: Geometry that blocks rays (`occluders`) through its evaluated mesh.
MESHABLE_TYPES = {"CURVE", "SURFACE", "META", "FONT"}
READ_TYPES = GEOMETRY_TYPES | {"LIGHT"}
#: `BlenderSceneRead.how` when the render depsgraph was read.
RENDER = "render"
#: The probe render's smaller image side, in pixels (the resolution is scaled down
#: to about this; nothing is drawn, but the render result is allocated).
PROBE_PIXELS = 16


class _Seq(Sequence):
    """Read-only sequence with list equality (what tests and callers compare)."""

    def __eq__(self, other):
        return list(self) == list(other)

    def __repr__(self):
        return repr(list(self))


class Indexed(_Seq):
    """``values[index[i]]``: one value per group, looked up per item."""

    def __init__(self, values, index):
        self.values, self.index = list(values), np.asarray(index, dtype=np.int64)

    def __len__(self):
        return int(self.index.size)

    def __getitem__(self, i):
        if isinstance(i, slice):
            return [self.values[k] for k in self.index[i]]
        return self.values[self.index[i]]


class InstanceNames(_Seq):
    """Names made on demand: ``bases[base[i]]``, with ``#k`` for the k-th repeat."""

    def __init__(self, bases, base, occurrence):
        self.bases = list(bases)
        self.base = np.asarray(base, dtype=np.int64)
        self.occurrence = np.asarray(occurrence, dtype=np.int64)

    def __len__(self):
        return int(self.base.size)

    def __getitem__(self, i):
        if isinstance(i, slice):
            return [self[k] for k in range(*i.indices(len(self)))]
        b, k = self.bases[self.base[i]], int(self.occurrence[i])
        return b if k == 0 else f"{b}#{k}"


@dataclass
class BlenderSceneRead:
    arrays: SceneArrays
    width: int = 0
    height: int = 0
    camera: Camera = field(default_factory=Camera)
    sphere_sources: Sequence = field(default_factory=list)
    light_sources: list[str] = field(default_factory=list)
    left_out: list[tuple[str, str]] = field(default_factory=list)
    # For the generator (parallel to the spheres / lights):
    sphere_objects: Sequence = field(default_factory=list)      # original bpy Objects
    light_objects: list = field(default_factory=list)
    lens_optics: Sequence = field(default_factory=list)
    lens_candidates: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))
    material_notes: Sequence = field(default_factory=list)
    primaries: list[PrimaryLight] = field(default_factory=list)
    #: (name, reason) of left-out objects that looked like lenses (refracting
    #: material or lens mode Always): the ones worth reporting to the user.
    left_out_lenses: list[tuple[str, str]] = field(default_factory=list)
    bounds: tuple[np.ndarray, np.ndarray] | None = None
    #: What blocks rays (`occluders.Occluders`): valid while the depsgraph read is.
    occluders: Occluders | None = None
    #: RENDER, or "viewport (why the render depsgraph was not read)".
    how: str = RENDER
    lights: list[Light] = field(default_factory=list)
    surfaces: Sequence = field(default_factory=list)   # `Surface` per sphere
    _scene: Scene | None = field(default=None, repr=False)

    @property
    def scene(self) -> Scene:
        """The read as an `addon.scene.Scene` (made on first use)."""
        if self._scene is None:
            a = self.arrays
            spheres = [Sphere(center=tuple(float(x) for x in a.center[i]),
                              radius=float(a.radius[i]), surface=self.surfaces[i],
                              name=self.sphere_sources[i]) for i in range(len(a.radius))]
            self._scene = Scene(width=self.width, height=self.height, camera=self.camera,
                                lights=list(self.lights), objects=spheres)
        return self._scene

    @property
    def scene_size(self) -> float:
        """Diagonal of everything rendered (≥ a tiny positive number)."""
        if self.bounds is None:
            return 1.0
        size = float(np.linalg.norm(self.bounds[1] - self.bounds[0]))
        return size if size > 0 and math.isfinite(size) else 1.0


# --------------------------------------------------------------------------- render depsgraph

class ProbeUnavailable(RuntimeError):
    """The render depsgraph could not be had (the reason is the message)."""


class _ProbeRun:
    def __init__(self, fn):
        self.fn, self.done, self.value, self.error = fn, False, None, None

    def __call__(self, depsgraph):
        if self.done:               # multi-view: one call is enough
            return
        self.done = True
        try:
            self.value = self.fn(depsgraph)
        except BaseException as exc:        # re-raised outside the render
            self.error = exc


_ACTIVE_RUN: _ProbeRun | None = None


class LENS_LIGHTS_RE_probe(bpy.types.RenderEngine):
    """Registered only while `rendered_depsgraph` renders: hands over the render
    depsgraph and draws nothing."""
    bl_idname = "LENS_LIGHTS_PROBE"
    bl_label = "Lens Lights scene probe"
    bl_use_preview = False

    def render(self, depsgraph):
        if _ACTIVE_RUN is not None:
            _ACTIVE_RUN(depsgraph)


def _render_results():
    return {img.as_pointer() for img in bpy.data.images if img.type == "RENDER_RESULT"}


def _probe(scene, view_layer, fn):
    global _ACTIVE_RUN
    if bpy.app.is_job_running("RENDER"):
        raise ProbeUnavailable("a render is in progress")
    run = _ProbeRun(fn)
    results_before = _render_results()
    copy = camera = None
    registered = False
    try:
        if not LENS_LIGHTS_RE_probe.is_registered:
            bpy.utils.register_class(LENS_LIGHTS_RE_probe)
            registered = True
        copy = scene.copy()
        copy.name = f"{scene.name} (Lens Lights probe)"
        r = copy.render
        r.engine = LENS_LIGHTS_RE_probe.bl_idname
        r.use_compositing = False
        r.use_sequencer = False
        side = max(1, min(r.resolution_x, r.resolution_y))
        r.resolution_percentage = int(min(100, max(1, math.ceil(100.0 * PROBE_PIXELS / side))))
        for layer in copy.view_layers:
            layer.use = layer.name == view_layer.name
        if copy.camera is None:
            camera = bpy.data.objects.new("Lens Lights probe camera",
                                          bpy.data.cameras.new("Lens Lights probe camera"))
            copy.collection.objects.link(camera)
            copy.camera = camera
        _ACTIVE_RUN = run
        bpy.ops.render.render(scene=copy.name, layer=view_layer.name)
    except Exception as exc:                    # noqa: BLE001  (the caller falls back)
        if run.error is None:
            raise ProbeUnavailable(f"the probe render failed: {str(exc).strip()}") from None
    finally:
        _ACTIVE_RUN = None
        # Each step on its own: one failing must not keep the others from running.
        steps = []
        if copy is not None:
            steps.append(lambda: bpy.data.scenes.remove(copy))
        if camera is not None:
            data = camera.data
            steps += [lambda: bpy.data.objects.remove(camera),
                      lambda: bpy.data.cameras.remove(data)]
        if registered:
            steps.append(lambda: bpy.utils.unregister_class(LENS_LIGHTS_RE_probe))
        steps.append(lambda: [bpy.data.images.remove(img) for img in list(bpy.data.images)
                              if img.type == "RENDER_RESULT"
                              and img.as_pointer() not in results_before])
        for step in steps:
            try:
                step()
            except Exception:                   # noqa: BLE001
                import traceback
                traceback.print_exc()
    if run.error is not None:
        raise run.error
    if not run.done:
        raise ProbeUnavailable("the render did not reach the scene")
    return run.value


def rendered_depsgraph(context, fn):
    """``(fn(depsgraph), how)`` with the render depsgraph of the context's scene and
    view layer (see the module's docstring); when that cannot be had, with the
    viewport depsgraph, and `how` says why. Exceptions of `fn` propagate."""
    try:
        return _probe(context.scene, context.view_layer, fn), RENDER
    except ProbeUnavailable as exc:
        why = str(exc)
    return fn(context.evaluated_depsgraph_get()), f"viewport ({why})"


# --------------------------------------------------------------------------- visibility

def _render_visible_objects(view_layer) -> set:
    """Original objects in at least one collection enabled for rendering (used
    only when reading a viewport depsgraph)."""
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


def _local_fit(mesh, corners, cache):
    """Sphere fit of an evaluated mesh in its local space (cached per mesh)."""
    key = mesh.as_pointer()
    if key in cache:
        return cache[key]
    if corners is None:
        corners = _mesh_arrays(mesh)[0]
    extent = corners.max(axis=0) - corners.min(axis=0)
    if not np.all(np.isfinite(extent)):
        fit = SphereFit(False, np.zeros(3), 0.0, "not a sphere: non-finite vertex coordinates")
    elif not extent.max() > 0:
        fit = SphereFit(False, np.zeros(3), 0.0, "zero size: all its vertices are at one point")
    elif extent.min() < BOX_RATIO * extent.max():
        dims = " × ".join(f"{e:.3g}" for e in extent)
        fit = SphereFit(False, np.zeros(3), 0.0, f"not a sphere: its bounding box ({dims}) is not a cube")
    else:
        fit = fit_sphere(*_mesh_arrays(mesh))
    cache[key] = fit
    return fit


def _corners(ob):
    try:
        corners = np.array([tuple(c) for c in ob.bound_box], dtype=float)
    except (AttributeError, TypeError):
        return None
    return corners if corners.shape == (8, 3) else None


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


# --------------------------------------------------------------------------- groups

LIGHT_GROUP, SPHERE_GROUP, OTHER_GROUP = range(3)


@dataclass
class _Group:
    """What all instances of one evaluated object / data / original share."""
    kind: int
    name: str
    orig: object
    corners: np.ndarray | None = None          # local bounding box (8 × 3)
    reason: str = ""                           # OTHER_GROUP: why it is no sphere
    looks_like_lens: bool = False
    # SPHERE_GROUP
    center: np.ndarray | None = None           # local
    radius: float = 0.0
    ior: float = 1.0
    kt: float = 0.0
    lens_like: bool = False
    optics: LensOptics | None = None
    surface: Surface | None = None
    notes: list = field(default_factory=list)
    # LIGHT_GROUP
    light_type: str = ""
    power: float = 0.0
    light_radius: float = 0.0
    color: tuple = (1.0, 1.0, 1.0)
    mesh_source: MeshSource | None = None      # what blocks rays (`occluders`)


def _light_group(ob, orig) -> _Group:
    ld = ob.data
    power = float(ld.energy) * 2.0 ** float(getattr(ld, "exposure", 0.0))
    radius = float(ld.shadow_soft_size)
    if not getattr(ld, "normalize", True) and radius > 0:
        power *= 4.0 * math.pi * radius * radius
    color = np.array(ld.color[:3], dtype=float)
    if getattr(ld, "use_temperature", False):
        color = color * np.array(ld.temperature_color[:3], dtype=float)
    return _Group(LIGHT_GROUP, ob.name, orig, light_type=ld.type, power=power,
                  light_radius=radius, color=tuple(float(c) for c in color))


def _geometry_group(ob, orig, fit_cache, optics_cache) -> _Group | None:
    settings = getattr(orig, "lens_lights", None)
    mode = settings.lens_mode if settings else "AUTO"
    corners = _corners(ob)
    if ob.type != "MESH":
        return _Group(OTHER_GROUP, ob.name, orig, corners, f"not a mesh ({ob.type.lower()})",
                      looks_like_lens=mode == "ALWAYS",
                      mesh_source=MeshSource.from_object(ob) if ob.type in MESHABLE_TYPES else None)
    mesh = ob.data
    if len(mesh.vertices) == 0:
        return None                          # nothing rendered (e.g. an instancer's own mesh)
    source = MeshSource(mesh)
    material = _main_material(ob, mesh)
    key = material.as_pointer() if material is not None else 0
    optics = optics_cache.get(key)
    if optics is None:
        optics = optics_cache[key] = material_optics(material)
    looks_like_lens = mode == "ALWAYS" or (mode == "AUTO" and optics.is_transmissive)
    fit = _local_fit(mesh, corners, fit_cache)
    if not fit.ok:
        return _Group(OTHER_GROUP, ob.name, orig, corners, fit.reason, looks_like_lens,
                      mesh_source=source)
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
    surface_optics = MaterialOptics(ior=ior, transmission=kt, tint=optics.tint,
                                    absorption=optics.absorption)
    color = optics.color if material is not None and material.node_tree is not None \
        else (tuple(material.diffuse_color[:3]) if material is not None else (0.8, 0.8, 0.8))
    return _Group(SPHERE_GROUP, ob.name, orig, corners, "", looks_like_lens, mesh_source=source,
                  center=np.asarray(fit.center, dtype=float), radius=float(fit.radius),
                  ior=float(ior), kt=float(kt), lens_like=kt > 0.0 and ior > 1.0,
                  optics=LensOptics(transmission_weight=weight, tint=tuple(optics.tint),
                                    absorption=tuple(optics.absorption)),
                  surface=_surface(surface_optics, color), notes=list(optics.notes))


def _classify(ob, orig, groups, fit_cache, optics_cache) -> int:
    if ob.type == "LIGHT":
        if _is_lens_light(orig):
            return -1
        group = _light_group(ob, orig)
    else:
        group = _geometry_group(ob, orig, fit_cache, optics_cache)
        if group is None:
            return -1
    groups.append(group)
    return len(groups) - 1


def _occurrences(keys: np.ndarray) -> np.ndarray:
    """For each item, how many earlier items have the same key (0, 1, 2 …)."""
    if keys.size == 0:
        return np.zeros(0, dtype=np.int64)
    order = np.argsort(keys, kind="stable")
    sk = keys[order]
    run_start = np.r_[True, sk[1:] != sk[:-1]]
    first = np.maximum.accumulate(np.where(run_start, np.arange(sk.size), 0))
    occ = np.empty(keys.size, dtype=np.int64)
    occ[order] = np.arange(sk.size) - first
    return occ


def _scale_codes(m: np.ndarray) -> np.ndarray:
    """Which of `_scale_reason`'s cases each matrix (K × 4 × 4) is, as a number."""
    axes = np.linalg.norm(m[:, :3, :3], axis=1)
    with np.errstate(invalid="ignore"):
        code = np.where(axes.max(axis=1) > 0, np.where(axes.min(axis=1) > 0, 3, 2), 1)
        uniform = np.all(np.abs(axes - axes[:, :1]) <= 1e-3 * np.abs(axes[:, :1]), axis=1)
    code = np.where((code == 3) & uniform, 4, code)
    return np.where(np.all(np.isfinite(m), axis=(1, 2)), code, 0).astype(np.int64)


def _scale_reason(m: np.ndarray) -> str:
    axes = np.linalg.norm(m[:3, :3], axis=0)
    if not np.all(np.isfinite(m)):
        return "invalid transform (non-finite numbers)"
    if not axes.max() > 0:
        return "zero scale: nothing is rendered"
    if not axes.min() > 0:
        return "zero scale on an axis (" + ", ".join(f"{s:.4g}" for s in axes) + "): flat, not a sphere"
    if np.allclose(axes, axes[0], rtol=1e-3):
        return "sheared transform: not a sphere"
    return "non-uniform scale (" + ", ".join(f"{s:.4g}" for s in axes) + "): an ellipsoid, not a sphere"


# --------------------------------------------------------------------------- main

def read_blender_scene(context_or_depsgraph) -> BlenderSceneRead:
    """The scene as the renderer sees it (see the module's docstring): from a
    context, the render depsgraph of its scene and view layer; from a depsgraph,
    that depsgraph (a viewport one with the render-visibility rules applied)."""
    if isinstance(context_or_depsgraph, bpy.types.Depsgraph):
        read = read_depsgraph(context_or_depsgraph)
    else:
        context = context_or_depsgraph
        read, how = rendered_depsgraph(context, lambda dg: read_depsgraph(dg, context.scene))
        read.how = how
    # The evaluated meshes may be freed (the probe's depsgraph) or replaced (the
    # viewport's, at its next update) after this: the occluders keep only the
    # spheres. (`read_depsgraph` keeps them all, for use while its depsgraph lives.)
    read.occluders.release()
    return read


def read_depsgraph(depsgraph, scene=None) -> BlenderSceneRead:
    """Read `depsgraph` (render or viewport); `scene`: the original scene whose
    camera and resolution the read reports (default: the depsgraph's)."""
    scene = scene if scene is not None else depsgraph.scene
    viewport = depsgraph.mode != "RENDER"
    visible = _render_visible_objects(depsgraph.view_layer) if viewport else None

    # 1. One pass over the instances: group key, matrix, instancer.
    keys: dict = {}
    groups: list[_Group] = []
    fit_cache: dict = {}
    optics_cache: dict = {}
    parent_ids: dict = {}
    parent_names: list[str] = []
    gid_list, mats, pids = [], [], []
    for inst in depsgraph.object_instances:
        ob = inst.object
        if ob.type not in READ_TYPES:
            continue
        orig = ob.original
        if inst.is_instance:
            parent = inst.parent
            if viewport:
                porig = parent.original
                if porig.hide_render or porig not in visible or orig.hide_render:
                    continue
            pk = parent.as_pointer()
            pid = parent_ids.get(pk)
            if pid is None:
                pid = parent_ids[pk] = len(parent_names)
                parent_names.append(parent.name)
        else:
            if viewport and (orig.hide_render or orig not in visible):
                continue
            pid = -1
        data = ob.data
        key = (ob.as_pointer(), orig.as_pointer(), data.as_pointer() if data is not None else 0)
        gid = keys.get(key)
        if gid is None:
            gid = keys[key] = _classify(ob, orig, groups, fit_cache, optics_cache)
        if gid < 0:
            continue
        gid_list.append(gid)
        mats.append(np.array(inst.matrix_world))      # copied now: the iterator reuses it
        pids.append(pid)
    return _assemble(scene, groups, np.asarray(gid_list, dtype=np.int64),
                     np.array(mats).reshape(-1, 4, 4), np.asarray(pids, dtype=np.int64),
                     parent_names, RENDER if not viewport else "viewport")


def _assemble(scene, groups, gid, M, pid, parent_names, how) -> BlenderSceneRead:
    """Everything after the pass over the instances, vectorised over them."""
    n, n_groups = gid.size, len(groups)
    r = scene.render
    width = r.resolution_x * r.resolution_percentage // 100
    height = r.resolution_y * r.resolution_percentage // 100
    kind = np.array([g.kind for g in groups], dtype=np.int64)[gid] if n else np.zeros(0, np.int64)

    # Names: "instancer/object" for instances, "#k" for the k-th repeat of a name.
    pair = pid * max(n_groups, 1) + gid
    pairs, pair_of = np.unique(pair, return_inverse=True)
    base_ids: dict[str, int] = {}
    pair_base = np.empty(pairs.size, dtype=np.int64)
    for k, p in enumerate(pairs):
        parent, g = divmod(int(p), max(n_groups, 1))
        text = groups[g].name if parent < 0 else f"{parent_names[parent]}/{groups[g].name}"
        pair_base[k] = base_ids.setdefault(text, len(base_ids))
    bases = list(base_ids)
    base = pair_base[pair_of.ravel()] if n else np.zeros(0, np.int64)
    occurrence = _occurrences(base)
    names = InstanceNames(bases, base, occurrence)

    # Bounds of everything rendered: the boxes of the geometry, the lights' positions.
    corners = np.array([g.corners if g.corners is not None else np.full((8, 3), np.nan)
                        for g in groups]).reshape(-1, 8, 3)
    lo, hi = [], []
    box_lo = np.full((n, 3), np.nan)
    box_hi = np.full((n, 3), np.nan)
    geo = np.flatnonzero(kind != LIGHT_GROUP)
    if geo.size:
        w = np.einsum("nij,nkj->nki", M[geo, :3, :3], corners[gid[geo]]) + M[geo, None, :3, 3]
        with np.errstate(invalid="ignore"):
            finite = np.all(np.isfinite(w), axis=(1, 2))
        if finite.any():
            box_lo[geo] = w.min(axis=1)
            box_hi[geo] = w.max(axis=1)
            lo.append(w[finite].min(axis=(0, 1)))
            hi.append(w[finite].max(axis=(0, 1)))

    out = BlenderSceneRead(arrays=None, width=width, height=height, camera=_camera(scene), how=how)
    left: dict[tuple[str, str], list] = {}      # (base name, reason) → [count, first, lens?]

    def leave_out(i, reason, lens, count=1):
        entry = left.get((bases[base[i]], reason))
        if entry is None:
            left[(bases[base[i]], reason)] = [count, int(i), lens]
        else:
            entry[0] += count
            entry[1] = min(entry[1], int(i))

    def leave_out_grouped(idx, code, reason_of):
        """`leave_out` for instances `idx`, one call per (name, reason code)."""
        if idx.size == 0:
            return
        keys = base[idx] * (int(code.max()) + 1) + code
        _, first, counts = np.unique(keys, return_index=True, return_counts=True)
        for f, c in zip(first, counts):
            i = idx[f]
            leave_out(i, reason_of(i), groups[gid[i]].looks_like_lens, int(c))

    # Lights (few: a Python loop).
    light_pos, light_power, light_color = [], [], []
    for i in np.flatnonzero(kind == LIGHT_GROUP):
        g = groups[gid[i]]
        pos = M[i, :3, 3]
        if g.light_type != "POINT":
            leave_out(i, f"{g.light_type.lower()} light: only point lights make lens lights", False)
            continue
        if not g.power > 0 or not math.isfinite(g.power):
            leave_out(i, f"point light without power ({g.power:g} W)", False)
            continue
        if not np.all(np.isfinite(pos)):
            leave_out(i, "invalid transform (non-finite numbers)", False)
            continue
        lo.append(pos)
        hi.append(pos)
        name = names[i]
        out.lights.append(Light(position=tuple(float(x) for x in pos), color=g.color,
                                brightness=g.power, radius=g.light_radius, name=name))
        out.primaries.append(PrimaryLight(power_w=g.power, radius=g.light_radius, color=g.color))
        out.light_sources.append(name)
        out.light_objects.append(g.orig)
        light_pos.append(pos)
        light_power.append(g.power)
        light_color.append(g.color)

    # Geometry that is no sphere: one entry per instancer, object and reason.
    other = np.flatnonzero(kind == OTHER_GROUP)
    leave_out_grouped(other, gid[other], lambda i: groups[gid[i]].reason)

    # Spheres: world centre and radius of every instance at once.
    sph = np.flatnonzero(kind == SPHERE_GROUP)
    sg = gid[sph]
    local_c = np.array([g.center if g.kind == SPHERE_GROUP else np.zeros(3) for g in groups]
                       ).reshape(-1, 3)
    local_r = np.array([g.radius for g in groups], dtype=float)
    scale = uniform_scales(M[sph])
    ok = np.isfinite(scale)
    # What blocks rays besides the spheres: every other geometry instance with a
    # mesh, and the spheres that are none here (ellipsoids).
    blocking = np.concatenate([np.flatnonzero(kind == OTHER_GROUP), sph[~ok]])
    has_mesh = np.array([groups[g].mesh_source is not None for g in gid[blocking]], dtype=bool)
    blocking = blocking[has_mesh & np.all(np.isfinite(box_lo[blocking]), axis=1)
                        & np.all(np.isfinite(box_hi[blocking]), axis=1)]
    source_of = {g: k for k, g in enumerate(np.unique(gid[blocking]))}
    bad = sph[~ok]
    leave_out_grouped(bad, _scale_codes(M[bad]), lambda i: _scale_reason(M[i]))
    sph, sg, scale = sph[ok], sg[ok], scale[ok]
    center = np.einsum("nij,nj->ni", M[sph, :3, :3], local_c[sg]) + M[sph, :3, 3]
    radius = local_r[sg] * scale

    out.arrays = SceneArrays(
        light_position=np.asarray(light_pos, dtype=float).reshape(-1, 3),
        light_brightness=np.asarray(light_power, dtype=float),
        light_color=np.asarray(light_color, dtype=float).reshape(-1, 3),
        center=center.reshape(-1, 3), radius=radius,
        ior=np.array([g.ior for g in groups], dtype=float)[sg] if sg.size else np.zeros(0),
        kt=np.array([g.kt for g in groups], dtype=float)[sg] if sg.size else np.zeros(0))
    out.sphere_sources = InstanceNames(bases, base[sph], occurrence[sph])
    out.sphere_objects = Indexed([g.orig for g in groups], sg)
    out.lens_optics = Indexed([g.optics for g in groups], sg)
    out.surfaces = Indexed([g.surface for g in groups], sg)
    out.material_notes = Indexed([g.notes for g in groups], sg)
    out.lens_candidates = np.array([g.lens_like for g in groups], dtype=bool)[sg] \
        if sg.size else np.zeros(0, dtype=bool)

    for (b, reason), (count, first, lens) in sorted(left.items(), key=lambda kv: kv[1][1]):
        name = names[first] if count == 1 else f"{b} ({count} instances)"
        out.left_out.append((name, reason))
        if lens:
            out.left_out_lenses.append((name, reason))
    if lo:
        out.bounds = (np.min(lo, axis=0), np.max(hi, axis=0))
    out.occluders = Occluders(
        out.arrays.center, out.arrays.radius, M[blocking], box_lo[blocking], box_hi[blocking],
        [source_of[g] for g in gid[blocking]],
        [groups[g].mesh_source for g in source_of])
    return out
