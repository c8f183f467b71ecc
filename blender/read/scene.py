"""Read a Blender scene as the renderer sees it, into the bpy-free scene model.

**Which depsgraph.** See `render_probe`: the render depsgraph, as a final render
(F12) evaluates the scene: the viewport one when nothing in the file renders
differently (`render_probe.as_rendered`), else had from a tiny render of a copy of
the scene; when that cannot run, the viewport depsgraph with the render-visibility
rules applied by hand (``BlenderSceneRead.how`` says which).

**Reading.** `read_depsgraph(depsgraph)` walks the depsgraph's object instances
once (modifiers, geometry nodes and instancing applied, world space). Per instance
it only notes which evaluated object/data/original it is, its instancer, and copies
its matrix (in one ``foreach_get``; `_bulk_walk` reads scenes of collection
instances without a Python step per instance). Per *group* of instances sharing
these it copies what Blender holds into one plain record, nothing decided yet
(`core.scene.assembly.GeometryRecord`: type, local box, lens mode, material optics
and colour; `core.scene.light_props.LightRecord`: a light's properties); materials
are read by `materials`. After the walk each mesh is fitted once (`fit_meshes`: the
boxes tested at once, a fit remembered by content across reads), and
`core.scene.assembly.assemble` makes the read of all records and instances at once
(what each record is, its lens material and surface; world centres and radii, the
uniform-scale test, bounding boxes, names: `core.scene.instances`). It returns a
:class:`BlenderSceneRead`:

* ``arrays`` — `core.scene.arrays.SceneArrays`: the lights (position, a sun's NaN;
  nominal power in W; colour) and the spheres (centre, radius, IOR, kt) for phase 1; ``scene`` — the
  same as an `core.scene.model.Scene` (made on first use; the `.bi` exporter's);
* ``sphere_sources`` / ``light_sources`` — the object (or instance: "instancer/
  object", "#k" for repeats) names, parallel to the spheres / lights;
* ``primary_lights`` — every light as an `core.scene.primaries` dataclass (point, spot,
  sun, area: `core.scene.light_props`), ``light_notes`` — (name, reason) of the lights
  left out or only partly modelled (light nodes, an area light's spread, …);
* ``left_out`` — (name, reason) for every render-enabled light or geometry that is
  not in the model (a light without power, not a sphere, non-uniform or zero scale …);
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
* A light's power is ``energy × 2^exposure`` (× its area — a point or spot light's
  sphere 4πr², an area light's surface — if its power is not normalised; a sun's
  strength in W/m²); its colour includes the blackbody colour when temperature is used.
* A sphere's transform may rotate, mirror (negative scale) and scale uniformly;
  a non-uniform scale (an ellipsoid) or a zero scale is left out and named, unless
  it is glass (below). Meshes without vertices (e.g. an instancer's own empty mesh)
  are ignored.
* Glass that is no sphere (or a glass sphere scaled unevenly) is a *mesh lens*
  (``mesh_lenses``, `core.scene.mesh_lenses`) when its evaluated mesh is closed and
  outward (`core.lens.closed_mesh`; read by `read_local_mesh` only when asked),
  else left out with why ("open mesh: …", or its shape: "a flat sheet"); a sphere
  of thin-walled glass (Principled's Thin Wall, 5.x) is a shell, no lens
  (`core.scene.assembly.THIN_WALL_REASON`). Both, and glass spheres set to Never, are
  ``unmodelled_glass``: Generate then keeps Cycles' refractive caustics.
* Lights the extension created are skipped entirely.
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
import warnings

import bpy
import mathutils
import numpy as np

from ...core.lens.closed_mesh import LocalMesh
from ...core.lens.glass import MaterialOptics
from ...core.lens.mesh_shape import mesh_shape, shape_reason
from ...core.lens.sphere_fit import fit_sphere
from ...core.scene.assembly import (
    RENDER,
    BlenderSceneRead,
    GeometryRecord,
    assemble,
    box_fit_failure,
    box_fit_failures,
    camera_from_matrix,
    perspective_fov,
    render_size,
)
from ...core.scene.light_props import IES_FAC, LightNodes, LightRecord, uses_light_nodes
from ...core.scene.model import Camera
from .materials import main_material, material_optics, node_tree
from .occluders import MeshSource, Occluders
from .render_probe import as_rendered, reads_viewport_as_render, render_visible_objects

GEOMETRY_TYPES = {
    "MESH",
    "CURVE",
    "SURFACE",
    "META",
    "FONT",
    "CURVES",
    "POINTCLOUD",
    "VOLUME",
    "GREASEPENCIL",
}
#: Geometry that blocks rays (`occluders`) through its evaluated mesh.
MESHABLE_TYPES = {"CURVE", "SURFACE", "META", "FONT"}
READ_TYPES = GEOMETRY_TYPES | {"LIGHT"}


# --------------------------------------------------------------------------- visibility


def is_lens_light(ob) -> bool:
    """Whether `ob` (an original object) is one the extension made (a lens light or
    a caustic layer), or the user's copy of one (kept, `build.ownership`): the reads
    skip it (a lens light is its lens' image: never a primary, nor a receiver)."""
    settings = getattr(ob, "lens_lights", None)
    return bool(settings and settings.is_lens_light)


# --------------------------------------------------------------------------- geometry


#: Sphere fits of the meshes read before, by content (`_fingerprint`): the next
#: Generate, live-update frame or bake frame fits only the meshes that changed.
_FITS: dict[bytes, object] = {}
_FITS_MAX = 4096


def _fingerprint(mesh):
    """(digest, vertices, face normals) of an evaluated mesh: its counts, vertex
    positions and face normals, which decide its sphere fit (face centres and areas
    follow from them for a given topology; a change of topology changes a count or a
    normal)."""
    nv, nf = len(mesh.vertices), len(mesh.polygons)
    v = np.empty(nv * 3)
    mesh.vertices.foreach_get("co", v)
    nr = np.empty(nf * 3)
    mesh.polygons.foreach_get("normal", nr)
    h = hashlib.blake2b(np.array([nv, nf, len(mesh.loops)], dtype=np.int64).tobytes())
    h.update(v.tobytes())
    h.update(nr.tobytes())
    return h.digest(), v.reshape(-1, 3), nr.reshape(-1, 3)


def _face_centres_areas(mesh):
    nf = len(mesh.polygons)
    c = np.empty(nf * 3)
    mesh.polygons.foreach_get("center", c)
    a = np.empty(nf)
    mesh.polygons.foreach_get("area", a)
    return c.reshape(-1, 3), a


def _content_fit(mesh):
    """Sphere fit of an evaluated mesh in its local space, remembered by content
    across reads (`_FITS`)."""
    digest, v, normals = _fingerprint(mesh)
    fit = _FITS.get(digest)
    if fit is None:
        fit = box_fit_failure(v.max(axis=0) - v.min(axis=0)) if len(v) else None
        if fit is None:
            centres, areas = _face_centres_areas(mesh)
            fit = fit_sphere(v, centres, normals, areas)
        if len(_FITS) >= _FITS_MAX:
            _FITS.clear()
        _FITS[digest] = fit
    return fit


#: Shape words (`core.lens.mesh_shape`) of the glass meshes read before, by content.
_SHAPES: dict[bytes, str] = {}


def _content_shape(mesh) -> str:
    """`mesh_shape` of an evaluated mesh (its edges of one face counted from its
    loops), remembered by content across reads (`_SHAPES`)."""
    digest, v, normals = _fingerprint(mesh)
    shape = _SHAPES.get(digest)
    if shape is None:
        edges = np.empty(len(mesh.loops), dtype=np.int32)
        mesh.loops.foreach_get("edge_index", edges)
        uses = np.bincount(edges, minlength=len(mesh.edges))
        centres, areas = _face_centres_areas(mesh)
        shape = mesh_shape(v, centres, normals, areas, int(np.count_nonzero(uses == 1)))
        if len(_SHAPES) >= _FITS_MAX:
            _SHAPES.clear()
        _SHAPES[digest] = shape
    return shape


def _is_glass(record) -> bool:
    """Whether a record's material passes light (or it is forced a lens): its
    shape is worth naming when it is no sphere."""
    o = record.optics
    return record.mode == "ALWAYS" or (o is not None and (o.is_transmissive or o.thin_wall > 0))


def read_local_mesh(mesh) -> LocalMesh:
    """An evaluated mesh as Blender renders it (`core.lens.closed_mesh.LocalMesh`):
    its loop triangles, vertices and the shading normal of each triangle corner
    (``corner_normals``: smooth, flat, Smooth by Angle and custom normals as shaded),
    in bulk."""
    tris = mesh.loop_triangles
    nt = len(tris)
    v = np.empty(len(mesh.vertices) * 3)
    mesh.vertices.foreach_get("co", v)
    t = np.empty(nt * 3, dtype=np.int32)
    tris.foreach_get("vertices", t)
    loops = np.empty(nt * 3, dtype=np.int32)
    tris.foreach_get("loops", loops)
    cn = np.empty(len(mesh.corner_normals) * 3)
    mesh.corner_normals.foreach_get("vector", cn)
    normals = cn.reshape(-1, 3)[loops].reshape(nt, 3, 3)
    return LocalMesh(v.reshape(-1, 3), t.reshape(nt, 3).astype(np.int64), normals)


class _LensMesh:
    """`GeometryRecord.lens_mesh` of a glass mesh: its `read_local_mesh`, read when
    the assembly asks (only for glass that is no sphere, or a sphere scaled unevenly)
    and while the depsgraph is valid, once."""

    __slots__ = ("mesh", "local")

    def __init__(self, mesh):
        self.mesh, self.local = mesh, None

    def __call__(self):
        if self.local is None:
            self.local = read_local_mesh(self.mesh)
        return self.local


def fit_meshes(records, meshes) -> None:
    """Fill in each mesh record's local sphere fit (`GeometryRecord.fit`; `meshes`:
    the evaluated mesh of each record, None for the others), after the walk: the
    bounding boxes are tested at once (`box_fit_failures`), then each mesh not ruled
    out by the box of its first record is fitted once (`_content_fit`). A glass
    mesh that is no sphere gets the reason in its shape's words (`_content_shape`:
    "a cylinder, not a sphere")."""
    rows = [k for k, mesh in enumerate(meshes) if mesh is not None]
    boxed = [k for k in rows if records[k].corners is not None]
    corners = np.array([records[k].corners for k in boxed], dtype=float).reshape(-1, 8, 3)
    extents = corners.max(axis=1) - corners.min(axis=1)
    failed = dict(zip(boxed, box_fit_failures(extents), strict=True))
    by_mesh: dict = {}
    readers: dict = {}
    for k in rows:
        glass = _is_glass(records[k])
        if glass:
            reader = readers.get(meshes[k].as_pointer())
            if reader is None:
                reader = readers[meshes[k].as_pointer()] = _LensMesh(meshes[k])
            records[k].lens_mesh = reader
        key = (meshes[k].as_pointer(), glass)
        fit = by_mesh.get(key)
        if fit is None:
            fit = failed.get(k)
            if fit is None:
                fit = _content_fit(meshes[k])
            if not fit.ok and glass:
                shape = _content_shape(meshes[k])
                if shape:
                    fit = dataclasses.replace(fit, reason=shape_reason(shape))
            by_mesh[key] = fit
        records[k].fit = fit


def _corners(ob):
    try:
        corners = np.array([tuple(c) for c in ob.bound_box], dtype=float)
    except (AttributeError, TypeError):
        return None
    return corners if corners.shape == (8, 3) else None


def _render_size(scene) -> tuple[int, int]:
    r = scene.render
    return render_size(r.resolution_x, r.resolution_y, r.resolution_percentage)


def _camera(scene) -> Camera:
    cam = scene.camera
    if cam is None or cam.type != "CAMERA":
        return Camera()
    data = cam.data
    fov = (45.0, 45.0)
    if data.type == "PERSP":
        fov = perspective_fov(
            data.angle_x, data.angle_y, data.angle, data.sensor_fit, *_render_size(scene)
        )
    return camera_from_matrix(np.array([list(row) for row in cam.matrix_world], dtype=float), fov)


# --------------------------------------------------------------------------- records


def _linked(ob) -> bool:
    ll = getattr(ob, "light_linking", None)
    return bool(ll and (ll.receiver_collection or ll.blocker_collection))


def _light_nodes(ld) -> LightNodes | None:
    """A light's node tree, if it has one and uses it (every light has a plain one
    from 5.0 on: `core.scene.light_props.plain_light_nodes`; `use_nodes` is
    deprecated)."""
    nt = getattr(ld, "node_tree", None)
    if nt is None:
        return None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        if not getattr(ld, "use_nodes", True):
            return None
    kinds = tuple(n.bl_idname for n in nt.nodes)
    emission = [n for n in nt.nodes if n.bl_idname == "ShaderNodeEmission"]
    if len(emission) != 1:
        return LightNodes(kinds, len(emission))
    e = emission[0].inputs
    nodes = LightNodes(
        kinds,
        1,
        tuple(e["Color"].default_value),
        float(e["Strength"].default_value),
        sum(1 for i in e if i.is_linked),
    )
    if not e["Strength"].is_linked:
        return nodes
    link = e["Strength"].links[0]
    node = link.from_node
    source = f"{node.bl_idname}.{link.from_socket.identifier}"
    if source != IES_FAC:
        return dataclasses.replace(nodes, strength_from=source)
    text, key, error = _ies_text(node)
    return dataclasses.replace(
        nodes,
        strength_from=source,
        ies_text=text,
        ies_key=key,
        ies_strength=float(node.inputs["Strength"].default_value),
        ies_linked=sum(1 for i in node.inputs if i.is_linked),
        ies_error=error,
    )


def _ies_text(node) -> tuple[str, str, str]:
    """(the IES file's text, where it is, why it could not be read) of an IES
    Texture node: its internal Text, or its external file."""
    if node.mode == "INTERNAL":
        if node.ies is None:
            return "", "", "no Text chosen"
        text, where = node.ies.as_string(), node.ies.name_full
    else:
        where = bpy.path.abspath(node.filepath, library=node.id_data.library)
        try:
            with open(where, encoding="latin-1") as f:
                text = f.read()
        except OSError as exc:
            return "", "", f"{node.filepath}: {exc.strerror or exc}"
    # the key changes with the text (an edited profile is another profile)
    return text, f"{where}:{hashlib.sha1(text.encode()).hexdigest()[:16]}", ""


def _light_record(ob, orig) -> LightRecord:
    """What a light holds (`core.scene.light_props.LightRecord`); ``exposure`` and
    ``normalize`` are 4.3+ (4.2: 0, True)."""
    ld = ob.data
    kind = ld.type
    props = dict(
        type=kind,
        energy=float(ld.energy),
        color=tuple(ld.color[:3]),
        temperature_color=(
            tuple(ld.temperature_color[:3]) if getattr(ld, "use_temperature", False) else None
        ),
        exposure=float(getattr(ld, "exposure", 0.0)),
        normalize=bool(getattr(ld, "normalize", True)),
        nodes=_light_nodes(ld),
        linked=_linked(orig),
    )
    if kind in ("POINT", "SPOT"):
        props["radius"] = float(ld.shadow_soft_size)
    if kind == "SPOT":
        props.update(spot_size=float(ld.spot_size), spot_blend=float(ld.spot_blend))
    elif kind == "SUN":
        props["angle"] = float(ld.angle)
    elif kind == "AREA":
        props.update(
            shape=ld.shape,
            size=float(ld.size),
            size_y=float(ld.size_y),
            spread=float(getattr(ld, "spread", math.pi)),
        )
    return LightRecord(ob.name, orig, **props)


def _material_optics_cached(material, cache) -> MaterialOptics:
    key = material.as_pointer() if material is not None else 0
    optics = cache.get(key)
    if optics is None:
        optics = cache[key] = material_optics(material)
    return optics


def _geometry_record(ob, orig, optics_cache) -> tuple[GeometryRecord | None, object]:
    """(what a geometry object holds, its evaluated mesh to fit, or None): no record
    for a mesh without vertices (nothing rendered, e.g. an instancer's own mesh)."""
    settings = getattr(orig, "lens_lights", None)
    mode = settings.lens_mode if settings else "AUTO"
    override = settings.ior_override if settings and settings.use_ior_override else None
    corners = _corners(ob)
    if ob.type != "MESH":
        source = MeshSource.from_object(ob) if ob.type in MESHABLE_TYPES else None
        return GeometryRecord(
            ob.name, orig, ob.type, corners, mode, override, mesh_source=source
        ), None
    mesh = ob.data
    if len(mesh.vertices) == 0:
        return None, None
    material = main_material(ob, mesh)
    optics = _material_optics_cached(material, optics_cache)
    if material is None:
        color = (0.8, 0.8, 0.8)
    elif node_tree(material) is None:
        color = tuple(material.diffuse_color[:3])
    else:
        color = optics.color
    record = GeometryRecord(
        ob.name, orig, ob.type, corners, mode, override, optics, color, mesh_source=MeshSource(mesh)
    )
    return record, mesh


# --------------------------------------------------------------------------- main


def read_blender_scene(context_or_depsgraph) -> BlenderSceneRead:
    """The scene as the renderer sees it (see the module's docstring): from a
    context, the render depsgraph of its scene and view layer; from a depsgraph,
    that depsgraph (a viewport one with the render-visibility rules applied)."""
    if isinstance(context_or_depsgraph, bpy.types.Depsgraph):
        read = read_depsgraph(context_or_depsgraph)
    else:
        context = context_or_depsgraph
        read, how = as_rendered(context, lambda dg: read_depsgraph(dg, context.scene))
        read.how = how
    # The evaluated meshes may be freed (the probe's depsgraph) or replaced (the
    # viewport's, at its next update) after this: the occluders keep only the
    # spheres. (`read_depsgraph` keeps them all, for use while its depsgraph lives.)
    read.occluders.release()
    return read


class _InstanceWalk:
    """One pass over a depsgraph's instances: per instance its group (a record read
    on first sight: `record`), world matrix and instancer. `walk` is the pass (the matrices read
    in one go); `add`, one instance at a time, is the reference it falls back on."""

    def __init__(self, viewport, visible):
        self.viewport, self.visible = viewport, visible
        self.keys: dict = {}
        #: One record per group (`GeometryRecord`, `LightRecord`), and its evaluated
        #: mesh to fit (`fit_meshes`) or None.
        self.records: list = []
        self.meshes: list = []
        self.optics_cache: dict = {}
        self.parent_ids: dict = {}
        self.parent_names: list[str] = []
        self.gid, self.mats, self.pid = [], [], []

    def _hidden(self, orig) -> bool:
        return self.viewport and (orig.hide_render or orig not in self.visible)

    def _parent_id(self, inst, orig) -> int | None:
        """The instancer's index (−1: not an instance; None: not rendered)."""
        if not inst.is_instance:
            return None if self._hidden(orig) else -1
        parent = inst.parent
        if self.viewport and (self._hidden(parent.original) or orig.hide_render):
            return None
        pk = parent.as_pointer()
        pid = self.parent_ids.get(pk)
        if pid is None:
            pid = self.parent_ids[pk] = len(self.parent_names)
            self.parent_names.append(parent.name)
        return pid

    def _group(self, ob, orig, data) -> int:
        key = (ob.as_pointer(), orig.as_pointer(), data.as_pointer() if data is not None else 0)
        gid = self.keys.get(key)
        if gid is None:
            gid = self.keys[key] = self.record(ob, orig)
        return gid

    def record(self, ob, orig) -> int:
        """The group of a new evaluated object: its record's index (−1: not read, as
        the extension's own objects and meshes without vertices)."""
        if is_lens_light(orig):  # lens lights and caustic layers
            return -1
        if ob.type == "LIGHT":
            record, mesh = _light_record(ob, orig), None
        else:
            record, mesh = _geometry_record(ob, orig, self.optics_cache)
            if record is None:
                return -1
        self.records.append(record)
        self.meshes.append(mesh)
        return len(self.records) - 1

    def add(self, inst):
        ob = inst.object
        if ob.type not in READ_TYPES:
            return
        orig = ob.original
        pid = self._parent_id(inst, orig)
        if pid is None:
            return
        gid = self._group(ob, orig, ob.data)
        if gid < 0:
            return
        self.gid.append(gid)
        self.mats.append(np.array(inst.matrix_world))  # copied now: the iterator reuses it
        self.pid.append(pid)

    def walk(self, instances) -> bool:
        """`add` for every instance of `instances` (a depsgraph's ``object_instances``),
        the same result for less Python per instance (about 20 → 6 µs: Blender's RNA
        reads dominate): what `add` decides per instance is cached per evaluated
        object (not an instance) or per (evaluated object, original, data) and per
        instancer — the RNA structs are dict keys (hashed and compared by pointer,
        as `add`'s ``as_pointer`` keys) —, and the matrices are copied afterwards in
        one ``foreach_get`` over the same iterator. False (and nothing kept) when
        that second pass does not give the first's instances (its count, or the
        matrix of each group's first instance, read in the first pass, differs)."""
        viewport, hidden = self.viewport, self._hidden
        parent_names, group = self.parent_names, self._group
        objects: dict = {}  # not an instance: evaluated object → [read?, hidden?, gid]
        keyed: dict = {}  # instance: (object, original, data) → [read?, hide_render, gid]
        parents: dict = {}  # instancer → [hidden?, index]
        gids, pids, rows, checks = [], [], [], []
        i = -1
        for inst in instances:
            i += 1
            ob = inst.object
            if inst.is_instance:
                orig, data = ob.original, ob.data
                k = (ob, orig, data)
                e = keyed.get(k)
                if e is None:
                    read = ob.type in READ_TYPES
                    e = keyed[k] = [read, read and viewport and orig.hide_render, None]
                if not e[0]:
                    continue
                parent = inst.parent
                pe = parents.get(parent)
                if pe is None:
                    pe = parents[parent] = [viewport and hidden(parent.original), None]
                if pe[0] or e[1]:
                    continue
                pid = pe[1]
                if pid is None:
                    pid = pe[1] = len(parent_names)
                    parent_names.append(parent.name)
            else:
                e = objects.get(ob)
                if e is None:
                    read = ob.type in READ_TYPES
                    e = objects[ob] = [read, read and hidden(ob.original), None]
                if not e[0] or e[1]:
                    continue
                pid = -1
            gid = e[2]
            if gid is None:
                gid = e[2] = group(ob, ob.original, ob.data)
                if gid >= 0:
                    checks.append((len(rows), np.array(inst.matrix_world)))
            if gid < 0:
                continue
            gids.append(gid)
            pids.append(pid)
            rows.append(i)
        n = i + 1
        flat = np.empty(n * 16, dtype=np.float32)  # Blender's matrices are float32
        try:
            instances.foreach_get("matrix_world", flat)
        except (RuntimeError, TypeError, AttributeError):
            return False
        # Blender stores a matrix by columns: transposed into numpy's rows.
        mats = flat.reshape(n, 4, 4).transpose(0, 2, 1)[np.asarray(rows, dtype=np.int64)]
        # The reference's dtype (float32 where mathutils hands numpy its buffer, 5.x).
        mats = mats.astype(checks[0][1].dtype if checks else float)
        if any(not np.array_equal(mats[r], m) for r, m in checks):
            return False
        self.gid, self.pid, self.mats = gids, pids, mats
        return True


# --------------------------------------------------------------------------- bulk

#: Object types an instanced collection read in bulk may hold (others: the walk).
_BULK_CHILD_TYPES = frozenset({"MESH", "LIGHT", "EMPTY"})
#: Objects other than empties beyond which the bulk read is not tried (it saves
#: nothing when most objects are plain ones).
_BULK_MAX_OTHERS = 2000
#: Instances of the bulk read compared with the depsgraph's iterator's.
_BULK_CHECK = 64


def _enum_code(prop: str, name: str) -> int:
    return bpy.types.Object.bl_rna.properties[prop].enum_items[name].value


def _values(items, name, dtype, size=1, count=None) -> np.ndarray:
    out = np.zeros((len(items) if count is None else count) * size, dtype=dtype)
    if len(out):
        items.foreach_get(name, out)
    return out


def _may_instance(ob) -> bool:
    """Whether an object instances anything (its instance type, geometry nodes,
    particles)."""
    if ob.instance_type != "NONE":
        return True
    return any(md.type in ("NODES", "PARTICLE_SYSTEM") for md in getattr(ob, "modifiers", ()))


def _mul(a, b):
    """Blender's ``mul_m4_m4m4`` (SSE2) on float32 stacks (K × 4 × 4), in numpy's row
    convention: ``a @ b``, each element summed as (a0 b0 + a1 b1) + (a2 b2 + a3 b3)."""
    a = np.ascontiguousarray(a.transpose(0, 2, 1))  # a's columns, each contiguous
    b = np.ascontiguousarray(b)
    return (a[:, 0, :, None] * b[:, None, 0] + a[:, 1, :, None] * b[:, None, 1]) + (
        a[:, 2, :, None] * b[:, None, 2] + a[:, 3, :, None] * b[:, None, 3]
    )


def _bulk_collections(instancers, names):
    """The collections the empties `instancers` (named `names`) instance, if each
    can be read in bulk: (instancer name → collection index, per collection its
    offset matrix and objects), else None."""
    of: dict[str, int] = {}
    index: dict = {}
    kids: list = []
    for empty, name in zip(instancers, names, strict=True):
        coll = empty.instance_collection
        if coll is None:
            continue
        c = index.get(coll)
        if c is None:
            if coll.hide_viewport or coll.hide_render:
                return None
            if any(sub.hide_viewport or sub.hide_render for sub in coll.children_recursive):
                return None
            obs = list(coll.all_objects)
            for ob in obs:
                if ob.type not in _BULK_CHILD_TYPES or ob.hide_viewport or ob.hide_render:
                    return None
                if _may_instance(ob):
                    return None
            offset = np.zeros((4, 4), dtype=np.float32)
            offset[range(4), range(4)] = 1.0
            offset[:3, 3] = -np.array(coll.instance_offset, dtype=np.float32)
            c = index[coll] = len(kids)
            kids.append((offset, obs))
        of[name] = c
    return of, kids


def _bulk_walk(depsgraph) -> _InstanceWalk | None:
    """The walk's result without a Python step per instance, for a viewport
    depsgraph read as the render one (`reads_viewport_as_render`) whose only
    instancers are empties instancing collections of plain objects (meshes, lights,
    empties; nothing nested, hidden or instancing inside; every instancer shown;
    no linked library, so that names name objects): the depsgraph's objects (in
    the iterator's order) are read with ``foreach_get``, and each instance's
    matrix is composed in numpy as Blender composes it (instancer @
    translation(−instance offset) @ object, float32, its order of sums). None when
    the scene is not such a one, or when its first instances are not the
    iterator's (then the walk reads it)."""
    objects = bpy.data.objects
    if len(bpy.data.libraries) or not len(objects):
        return None
    empty, coll_code = _enum_code("type", "EMPTY"), _enum_code("instance_type", "COLLECTION")
    n = len(objects)
    types = _values(objects, "type", np.int32, count=n)
    inst_types = _values(objects, "instance_type", np.int32, count=n)
    if not np.any(inst_types == coll_code):
        return None  # nothing to gain
    if not np.all(_values(objects, "show_instancer_for_viewport", bool, count=n)):
        return None  # an instancer missing from the depsgraph's objects
    if np.any((inst_types == coll_code) & (types != empty)):
        return None
    others = np.flatnonzero(types != empty)
    if len(others) > _BULK_MAX_OTHERS:
        return None
    listed = objects.values()
    by_name = {ob.name: ob for ob in (listed[k] for k in others.tolist())}
    if any(_may_instance(ob) for ob in by_name.values()):
        return None
    rows_of = np.flatnonzero(inst_types == coll_code).tolist()
    all_names = objects.keys()
    found = _bulk_collections([listed[k] for k in rows_of], [all_names[k] for k in rows_of])
    if found is None:
        return None
    coll_of, kids = found

    dobs = depsgraph.objects
    names = dobs.keys()
    rows = len(names)
    row_type = _values(dobs, "type", np.int32, count=rows)
    row_mat = _values(dobs, "matrix_world", np.float32, 16, rows).reshape(-1, 4, 4)
    row_mat = row_mat.transpose(0, 2, 1)  # Blender's matrices are stored by columns
    row_coll = np.array([coll_of.get(name, -1) for name in names], dtype=np.int64)
    read_codes = [_enum_code("type", t) for t in READ_TYPES]
    read_rows = np.flatnonzero(np.isin(row_type, read_codes))

    # Groups in order of first sight, as the walk makes them: a read object at its
    # row, an instanced object at the first row instancing its collection.
    walk = _InstanceWalk(False, None)
    events = [(int(r), -1, None) for r in read_rows]
    first_row = np.full(len(kids), rows, dtype=np.int64)
    np.minimum.at(first_row, row_coll[row_coll >= 0], np.flatnonzero(row_coll >= 0))
    kid_read = []  # per collection instanced here: [(original, evaluated)] of those read
    for c, (_offset, obs) in enumerate(kids):
        used = first_row[c] < rows
        read = [(ob, ob.evaluated_get(depsgraph)) for ob in obs if used and ob.type in READ_TYPES]
        kid_read.append(read)
        events += [(int(first_row[c]), k, c) for k in range(len(read))]
    row_gid = {}
    kid_gid: dict = {}
    for r, k, c in sorted(events, key=lambda e: (e[0], e[1])):
        if c is None:
            orig = by_name[names[r]]
            ob = orig.evaluated_get(depsgraph)
            row_gid[r] = walk._group(ob, orig, ob.data)
        else:
            orig, ob = kid_read[c][k]
            if orig not in kid_gid:
                kid_gid[orig] = walk.record(ob, orig)

    # Per collection: the groups and local matrices of its instanced objects kept.
    kept_gid, kept_mat, n_read = [], [], []
    for read in kid_read:
        g = np.array([kid_gid.get(orig, -1) for orig, _ob in read], dtype=np.int64)
        m = np.array([np.array(ob.matrix_world) for _orig, ob in read], dtype=np.float32)
        keep = g >= 0
        kept_gid.append(g[keep])
        kept_mat.append(m.reshape(-1, 4, 4)[keep])
        n_read.append(len(read))
    n_read = np.array(n_read, dtype=np.int64)
    # Instancers with an object read in their collection, in row order, get an index.
    inst_rows = np.flatnonzero((row_coll >= 0) & (n_read[np.maximum(row_coll, 0)] > 0))
    walk.parent_names = [names[r] for r in inst_rows.tolist()]
    c_of = row_coll[inst_rows]
    count = np.array([len(g) for g in kept_gid], dtype=np.int64)[c_of]
    item_row = np.repeat(inst_rows, count)
    item_pid = np.repeat(np.arange(len(inst_rows)), count)
    item_c = np.repeat(c_of, count)
    local = np.arange(int(count.sum())) - np.repeat(np.cumsum(count) - count, count)
    starts = np.cumsum([0] + [len(g) for g in kept_gid])
    flat_gid = np.concatenate(kept_gid + [np.zeros(0, np.int64)])
    flat_mat = np.concatenate(kept_mat + [np.zeros((0, 4, 4), np.float32)])
    kid = starts[item_c] + local
    offsets = np.array([o for o, _obs in kids], dtype=np.float32).reshape(-1, 4, 4)
    item_mat = _mul(_mul(row_mat[item_row], offsets[item_c]), flat_mat[kid])

    self_rows = np.array([r for r in sorted(row_gid) if row_gid[r] >= 0], dtype=np.int64)
    self_gid = np.array([row_gid[r] for r in self_rows.tolist()], dtype=np.int64)
    all_row = np.concatenate([self_rows, item_row])
    order = np.argsort(all_row, kind="stable")  # a row's own item before its instances
    gid = np.concatenate([self_gid, flat_gid[kid]])[order]
    pid = np.concatenate([np.full(len(self_rows), -1, np.int64), item_pid])[order]
    mats = np.concatenate([row_mat[self_rows], item_mat])[order]
    dtype = np.array(mathutils.Matrix.Identity(4)).dtype  # the walk's (float32 in 5.x)
    walk.gid, walk.pid, walk.mats = gid.tolist(), pid.tolist(), mats.astype(dtype)
    return walk if _bulk_agrees(depsgraph, walk) else None


def _bulk_agrees(depsgraph, walk) -> bool:
    """Whether the first `_BULK_CHECK` instances the reference walk reads off the
    depsgraph's iterator are the bulk read's (objects, instancers, matrices)."""
    ref = _InstanceWalk(False, None)
    ref.optics_cache = walk.optics_cache
    for inst in depsgraph.object_instances:
        ref.add(inst)
        if len(ref.gid) >= _BULK_CHECK:
            break
    m = len(ref.gid)
    if m > len(walk.gid) or (m < _BULK_CHECK and m != len(walk.gid)):
        return False

    def items(w, k):
        r = w.records[w.gid[k]]
        p = w.pid[k]
        return r.orig, r.name, type(r), w.parent_names[p] if p >= 0 else None

    if any(items(ref, k) != items(walk, k) for k in range(m)):
        return False
    return np.array_equal(np.array(ref.mats).reshape(-1, 4, 4), walk.mats[:m])


def _walk(depsgraph, viewport) -> _InstanceWalk:
    if not viewport and reads_viewport_as_render(depsgraph):
        try:
            walk = _bulk_walk(depsgraph)
        except Exception:  # anything it did not foresee: the walk reads (and says) it
            walk = None
        if walk is not None:
            return walk
    visible = render_visible_objects(depsgraph.view_layer) if viewport else None
    walk = _InstanceWalk(viewport, visible)
    if walk.walk(depsgraph.object_instances):
        return walk
    walk = _InstanceWalk(viewport, visible)
    for inst in depsgraph.object_instances:
        walk.add(inst)
    return walk


def read_depsgraph(depsgraph, scene=None) -> BlenderSceneRead:
    """Read `depsgraph` (render or viewport); `scene`: the original scene whose
    camera and resolution the read reports (default: the depsgraph's)."""
    scene = scene if scene is not None else depsgraph.scene
    viewport = depsgraph.mode != "RENDER" and not reads_viewport_as_render(depsgraph)
    walk = _walk(depsgraph, viewport)
    return _assemble(scene, walk, RENDER if not viewport else "viewport")


def _assemble(scene, walk: _InstanceWalk, how) -> BlenderSceneRead:
    """Everything after the pass over the instances: the meshes' sphere fits
    (`fit_meshes`), the read (`core.scene.assembly.assemble`), and the occluders made
    of the instances' meshes."""
    fit_meshes(walk.records, walk.meshes)
    if scene.render.engine != "CYCLES":  # only Cycles evaluates a light's node tree
        for r in walk.records:
            if isinstance(r, LightRecord) and uses_light_nodes(r.nodes):
                r.nodes, r.nodes_ignored = None, True
    width, height = _render_size(scene)
    read, blocking = assemble(
        walk.records,
        np.asarray(walk.gid, dtype=np.int64),
        np.array(walk.mats).reshape(-1, 4, 4),
        np.asarray(walk.pid, dtype=np.int64),
        walk.parent_names,
        how,
        width,
        height,
        _camera(scene),
    )
    read.occluders = Occluders(
        read.arrays.center,
        read.arrays.radius,
        blocking.matrices,
        blocking.box_lo,
        blocking.box_hi,
        blocking.source_index,
        blocking.sources,
    )
    return read
