"""Scene builders and a datablock snapshot for the Blender tests (bpy module)."""

from __future__ import annotations

import hashlib
import math
from types import SimpleNamespace

import bpy
import numpy as np
from measuring_scene import new_material  # (scripts/): Blender 4.x needs use_nodes


def glass_material(name="Glass", ior=1.5, transmission=1.0, color=(1, 1, 1)):
    mat = new_material(name)
    bsdf = mat.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Transmission Weight"].default_value = transmission
    bsdf.inputs["IOR"].default_value = ior
    bsdf.inputs["Base Color"].default_value = (*color, 1.0)
    return mat


def node_material(name, kind, **inputs):
    """A material whose surface is one shader node of type `kind` (bl_idname)."""
    mat = new_material(name)
    nt = mat.node_tree
    for node in list(nt.nodes):
        if node.type != "OUTPUT_MATERIAL":
            nt.nodes.remove(node)
    node = nt.nodes.new(kind)
    for key, value in inputs.items():
        node.inputs[key].default_value = value
    nt.links.new(node.outputs[0], nt.nodes["Material Output"].inputs["Surface"])
    return mat


def add_sphere(name, location, radius=0.5, material=None, segments=32, rings=16):
    bpy.ops.mesh.primitive_uv_sphere_add(
        radius=radius, location=location, segments=segments, ring_count=rings
    )
    ob = bpy.context.object
    ob.name = name
    if material is not None:
        ob.data.materials.append(material)
    return ob


def add_point_light(name, location, energy=1000.0, radius=0.0, kind="POINT"):
    data = bpy.data.lights.new(name, kind)
    data.energy = energy
    data.shadow_soft_size = radius
    ob = bpy.data.objects.new(name, data)
    bpy.context.scene.collection.objects.link(ob)
    ob.location = location
    return ob


def lens_lights(copies=False):
    """The extension's objects, by name; without the caustic layers' copies for EEVEE's
    reflections (`blender/build/layers.py`) unless ``copies``."""
    return sorted(
        (
            o
            for o in bpy.data.objects
            if o.lens_lights.is_lens_light and (copies or not o.get("lens_lights_reflection"))
        ),
        key=lambda o: o.name,
    )


def caustic_layers():
    """The caustic layers among `lens_lights()`: their meshes, without the copies made
    for EEVEE's reflections (`blender/build/layers.py`)."""
    return [o for o in lens_lights() if o.type == "MESH" and not o.get("lens_lights_reflection")]


def layer_triangle_flux(ob):
    """(T, 3): per triangle of a caustic layer mesh, the R, G, B of the irradiance the
    renderer draws integrated over it: its area × the mean of its corners' values
    (the attribute is linear over each triangle)."""
    me = ob.data
    rgba = np.empty(len(me.vertices) * 4)
    me.attributes["lens_irradiance"].data.foreach_get("color", rgba)
    corners = np.empty(len(me.loops), dtype=np.int32)
    me.loops.foreach_get("vertex_index", corners)
    area = np.empty(len(me.polygons))
    me.polygons.foreach_get("area", area)
    rgb = rgba.reshape(-1, 4)[:, :3]
    return rgb[corners.reshape(-1, 3)].mean(axis=1) * area[:, None]


def layer_flux(ob) -> float:
    """What a caustic layer mesh draws, integrated over it (green: a white light)."""
    return float(layer_triangle_flux(ob)[:, 1].sum())


def layer_states(objects) -> dict:
    """The layer meshes among `objects` (not their reflection copies): name →
    (positions, irradiance, object and mesh pointers), to compare two states."""
    out = {}
    for ob in objects:
        if ob.type != "MESH" or not ob.lens_lights.is_lens_light:
            continue
        if ob.get("lens_lights_reflection"):
            continue
        me = ob.data
        co = np.zeros(3 * len(me.vertices), np.float32)
        me.vertices.foreach_get("co", co)
        irr = np.zeros(4 * len(me.vertices), np.float32)
        me.attributes["lens_irradiance"].data.foreach_get("color", irr)
        out[ob.name] = (co, irr, ob.as_pointer(), me.as_pointer())
    return out


def profile_light_states() -> dict:
    """Each Exact-profile lens light by its source light: (object, tree and image
    pointers), its numbers (location, rotation, energy, radius), its Value nodes, its
    table's pixels (rows × columns × RGBA)."""
    from lens_lights.blender.build import lights

    out = {}
    for ob in bpy.data.objects:
        if not ob.lens_lights.is_lens_light or ob.type != "LIGHT":
            continue
        d = ob.data
        nt = d.node_tree
        img = nt.nodes[lights.PROFILE_TEX_NODE].image
        px = np.empty(len(img.pixels), dtype=np.float32)
        img.pixels.foreach_get(px)
        nums = np.array([*ob.location, *ob.rotation_quaternion, d.energy, d.shadow_soft_size])
        values = {n.name: n.outputs[0].default_value for n in nt.nodes if n.type == "VALUE"}
        pointers = (ob.as_pointer(), nt.as_pointer(), img.as_pointer())
        px = px.reshape(img.size[1], img.size[0], 4)
        out[ob.lens_lights.source_light] = (pointers, nums, values, px)
    return out


def assert_profile_lights_are_generates(state):
    """`state` (`profile_light_states`) equals what a fresh Generate makes now (live
    update turned off first): the same lights, numbers, Value nodes and pixels."""
    import pytest
    from lens_lights.blender.commands.generate import generate

    bpy.context.scene.lens_lights.live_update = False
    generate(bpy.context)
    fresh = profile_light_states()
    assert state.keys() == fresh.keys()
    for k, (_p, nums, values, px) in fresh.items():
        np.testing.assert_allclose(state[k][1], nums, rtol=1e-6, atol=1e-9)
        assert state[k][2].keys() == values.keys()
        for name, v in values.items():
            assert state[k][2][name] == pytest.approx(v, rel=1e-6, abs=1e-9), (k, name)
        np.testing.assert_array_equal(state[k][3], px)


def resting_marble(lamp_at, radius=0.5, ior=1.5):
    """Cycles, the Exact profile tier: a glass marble resting on a 20 m plane at the
    origin (its centre `radius` above it) and a point light "Lamp" at `lamp_at`.
    Returns (scene, lamp)."""
    sc = bpy.context.scene
    set_engine("CYCLES")
    sc.lens_lights.energy_model = "EXACT_PROFILE"
    add_sphere(
        "Marble",
        (0.0, 0.0, radius),
        radius=radius,
        material=glass_material(ior=ior),
        segments=64,
        rings=32,
    )
    bpy.ops.mesh.primitive_plane_add(size=20)
    return sc, add_point_light("Lamp", lamp_at)


def generate():
    from lens_lights.blender.commands.generate import generate as run

    return run(bpy.context)


def gn_instances(
    name,
    points,
    radius=0.25,
    material=None,
    instance_object=None,
    scale=None,
    location=(0.0, 0.0, 0.0),
):
    """A mesh object whose geometry nodes put an instance on each of `points`
    (a list of (x, y, z) in its local space): a UV sphere geometry with `material`
    (geometry instances), or `instance_object` (object instances, Object Info "As
    Instance"). `scale`: the instances' scale (a 3-tuple)."""
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([tuple(p) for p in points], [], [])
    host = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(host)
    host.location = location
    tree = bpy.data.node_groups.new(name, "GeometryNodeTree")
    tree.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    tree.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    nodes, links = tree.nodes, tree.links
    inp, out = nodes.new("NodeGroupInput"), nodes.new("NodeGroupOutput")
    inst = nodes.new("GeometryNodeInstanceOnPoints")
    links.new(inp.outputs[0], inst.inputs["Points"])
    if instance_object is not None:
        info = nodes.new("GeometryNodeObjectInfo")
        info.inputs["As Instance"].default_value = True
        info.inputs["Object"].default_value = instance_object
        links.new(info.outputs["Geometry"], inst.inputs["Instance"])
    else:
        uv = nodes.new("GeometryNodeMeshUVSphere")
        uv.inputs["Radius"].default_value = radius
        setm = nodes.new("GeometryNodeSetMaterial")
        setm.inputs["Material"].default_value = material
        links.new(uv.outputs["Mesh"], setm.inputs["Geometry"])
        links.new(setm.outputs["Geometry"], inst.inputs["Instance"])
    if scale is not None:
        inst.inputs["Scale"].default_value = scale
    links.new(inst.outputs["Instances"], out.inputs[0])
    host.modifiers.new("Instances", "NODES").node_group = tree
    return host


def collection_of(name, *objects):
    """A collection (not linked to the scene) holding `objects` (unlinked from
    the scene's collection)."""
    coll = bpy.data.collections.new(name)
    for ob in objects:
        coll.objects.link(ob)
        for c in list(ob.users_collection):
            if c != coll:
                c.objects.unlink(ob)
    return coll


def collection_instance(name, collection, location=(0, 0, 0), scale=(1, 1, 1), parent_coll=None):
    e = bpy.data.objects.new(name, None)
    e.instance_type = "COLLECTION"
    e.instance_collection = collection
    e.location = location
    e.scale = scale
    (parent_coll or bpy.context.scene.collection).objects.link(e)
    return e


def grid(n, spacing=1.0, z=0.0):
    side = int(math.ceil(math.sqrt(n)))
    return [(spacing * (k % side), spacing * (k // side), z) for k in range(n)]


# --------------------------------------------------------------------------- snapshot

#: RNA properties that are bookkeeping, not content (or change by merely being
#: looked at / evaluated).
SKIP_PROPS = {
    "rna_type",
    "users",
    "session_uid",
    "is_evaluated",
    "original",
    "tag",
    "is_runtime_data",
    "preview",
    "bl_rna",
    "id_data",
    "is_editmode",
    "bindcode",
    "is_dirty",
    "has_data",
    "is_missing",
    "use_extra_user",
    "is_library_indirect",
    "library_weak_reference",
    "depsgraph",
    "statistics",
    "frame_current_final",
    "is_embedded_data",
    "name_full",
    "is_editable",
    "is_linked_packed",
    "use_nodes",  # deprecated (always on in 5.0; warns when read)
    "particle_edit",  # runtime state of particle edit mode (undo resets it)
    # Blender 5.2 keeps a constant attribute as one value ('SINGLE') and expands
    # it to an 'ARRAY' when its `data` is read: the snapshot's own reading
    # changes it, nothing of the extension's does (tests/blender/commands/test_blender_generate.py
    # pins that the snapshot is stable).
    "storage_type",
    "uv_sculpt",  # Blender 4.2: reading ToolSettings.uv_sculpt.brush crashes
    "lens_lights",
}  # the extension's own settings (checked separately)
MAX_ITEMS = 64


def _ours(value) -> bool:
    """A datablock the extension created (its lights, collections, images)."""
    from lens_lights.blender.build.marks import COLLECTION_MARK

    if isinstance(value, bpy.types.Object):
        return bool(value.lens_lights.is_lens_light)
    if isinstance(value, bpy.types.ID) and value.get(COLLECTION_MARK) is not None:
        return True  # its collections and profile images
    if isinstance(value, bpy.types.LayerCollection):
        return _ours(value.collection)
    if isinstance(value, bpy.types.Light):
        return any(_ours(o) for o in bpy.data.objects if o.data == value)
    return False


def _value(v):
    if isinstance(v, float):
        return "nan" if v != v else repr(round(v, 9))
    if isinstance(v, (str, int, bool)) or v is None:
        return v
    try:
        return tuple(_value(x) for x in v)
    except TypeError:
        return repr(v)


def _idprop(v):
    for method in ("to_dict", "to_list"):
        if hasattr(v, method):
            return getattr(v, method)()
    return v


def _struct(s, depth):
    out = []
    for prop in s.bl_rna.properties:
        pid = prop.identifier
        if pid in SKIP_PROPS:
            continue
        try:
            value = getattr(s, pid)
        except (AttributeError, RuntimeError, TypeError):
            continue
        if prop.type == "POINTER":
            if value is None:
                out.append((pid, None))
            elif isinstance(value, bpy.types.ID):
                out.append((pid, "ID " + value.name_full))
            elif depth > 0:
                out.append((pid, _struct(value, depth - 1)))
        elif prop.type == "COLLECTION":
            if depth > 0:
                items = [x for x in list(value)[: MAX_ITEMS * 4] if not _ours(x)][:MAX_ITEMS]
                out.append(
                    (
                        pid,
                        tuple(
                            "ID " + x.name_full
                            if isinstance(x, bpy.types.ID)
                            else _struct(x, depth - 1)
                            for x in items
                        ),
                    )
                )
        else:
            out.append((pid, _value(value)))
    try:
        # Before 5.0 `keys()` also lists properties registered from Python
        # (`scene.lens_lights`): only the custom ones count here.
        out.append(
            (
                "custom",
                tuple(
                    sorted(
                        (k, repr(_idprop(s[k]))) for k in s.keys() if k not in s.bl_rna.properties
                    )
                ),
            )
        )
    except (TypeError, AttributeError):
        pass
    return tuple(out)


def _mesh_digest(mesh):
    v = np.empty(len(mesh.vertices) * 3)
    mesh.vertices.foreach_get("co", v)
    return hashlib.sha1(np.round(v, 7).tobytes()).hexdigest()


DATA = (
    "objects",
    "meshes",
    "materials",
    "lights",
    "collections",
    "worlds",
    "cameras",
    "node_groups",
    "images",
    "libraries",
    "scenes",
    "textures",
    "curves",
    "actions",
    "particles",
    "volumes",
    "pointclouds",
)


def snapshot(depth=3) -> dict:
    """{(collection, name_full): structure} of every datablock that is not the
    extension's own: names, RNA properties (three levels deep, nested collections
    capped), custom properties, transforms, mesh vertices. Every view layer is
    evaluated first (Blender writes evaluated matrices back to the objects lazily)."""
    for scene in bpy.data.scenes:
        for layer in scene.view_layers:
            layer.update()
    snap = {}
    for attr in DATA:
        for idb in getattr(bpy.data, attr):
            if _ours(idb):
                continue
            entry = _struct(idb, depth)
            if isinstance(idb, bpy.types.Mesh):
                entry += (("vertices", _mesh_digest(idb)),)
            if isinstance(idb, bpy.types.Object):
                entry += (("matrix_world", _value([tuple(r) for r in idb.matrix_world])),)
            snap[(attr, idb.name_full)] = entry
    return snap


def snapshot_diff(a: dict, b: dict, limit=8) -> list[str]:
    """What differs between two snapshots (for assertion messages)."""
    out = [f"only before: {k}" for k in a.keys() - b.keys()]
    out += [f"only after: {k}" for k in b.keys() - a.keys()]
    for k in sorted(a.keys() & b.keys()):
        if a[k] != b[k]:
            da, db = dict(a[k]), dict(b[k])
            keys = [p for p in set(da) | set(db) if da.get(p) != db.get(p)]
            out.append(
                f"{k}: "
                + ", ".join(
                    f"{p}: {str(da.get(p))[:120]} → {str(db.get(p))[:120]}"
                    for p in sorted(keys)[:4]
                )
            )
    return out[:limit]


# --------------------------------------------------------------------------- scenes and panels


def basic_scene():
    """Floor, glass sphere R 0.5 at height 2.5, point light 2 above its centre."""
    bpy.ops.mesh.primitive_plane_add(size=8)
    bpy.context.object.name = "Floor"
    sphere = add_sphere("Marble", (0.0, 0.0, 2.5), material=glass_material())
    light = add_point_light("Lamp", (0.0, 0.0, 4.5), energy=1000.0, radius=0.1)
    return sphere, light


class OperatorProps:
    """What a panel sets on an operator button (hashable: logs go into sets)."""

    def __init__(self, idname, text):
        self.idname, self.text = idname, text


class FakeLayout:
    """Records what a panel draws; checks that every property drawn exists."""

    def __init__(self, log):
        self.log = log
        self.scale_y = 1.0
        self.active = True
        self.use_property_split = False
        self.use_property_decorate = True

    def _sub(self, *a, **k):
        return FakeLayout(self.log)

    row = column = box = grid_flow = split = _sub

    def prop(self, data, name, **kw):
        assert name in data.bl_rna.properties, name
        self.log.append(("prop", name))

    def operator(self, idname, **kw):
        module, op = idname.split(".")
        getattr(getattr(bpy.ops, module), op).get_rna_type()  # KeyError if it is missing
        self.log.append(("operator", idname))
        props = OperatorProps(idname, kw.get("text"))
        self.log.append(("operator props", props))  # the button's settings, as set
        return props

    def label(self, text="", **kw):
        self.log.append(("label", text))

    def separator(self, **kw):
        pass


def draw_panel(cls, context):
    log = []
    panel = SimpleNamespace(layout=FakeLayout(log))
    cls.draw(panel, context)
    return log


def set_engine(engine):
    """Set the render engine; EEVEE's identifier was BLENDER_EEVEE_NEXT before 5.0."""
    if engine == "BLENDER_EEVEE" and bpy.app.version < (5, 0, 0):
        engine = "BLENDER_EEVEE_NEXT"
    bpy.context.scene.render.engine = engine
