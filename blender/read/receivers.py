"""The receivers of the caustic layer (Caustic layer tier), read from the same
evaluated depsgraph the scene reader walks: every rendered mesh instance except the
lenses and the extension's own objects, as one `ReceiverMesh` in world space.

Vertices are taken per face corner (loop), so a UV seam keeps both UVs and the
layer's UV map samples the receiver's textures exactly; all through `foreach_get`,
once per evaluated mesh, then numpy per instance. Per receiver object it also reads
what the layer's material needs: the diffuse colour of its main material (a
constant, or the image texture feeding it) and whether a layer can show a caustic
on it (`core.caustic_layer.plan.fallback_reason`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ...core.caustic_layer.plan import fallback_reason
from ...core.caustic_layer.receiver_bvh import ReceiverMesh
from .materials import main_material, node_tree
from .render_probe import reads_viewport_as_render, render_visible_objects
from .scene import is_lens_light

DEFAULT_COLOR = (0.8, 0.8, 0.8)


@dataclass
class ReceiverInfo:
    """One receiver object (its id in `ReceiverMesh.object_ids`)."""

    name: str
    original: object
    color: tuple = DEFAULT_COLOR  # constant diffuse colour
    image: object = None  # the image texture feeding it, if any
    interpolation: str = "Linear"
    extension: str = "REPEAT"
    fallback: str = ""  # "glossy" / "transparent": no layer here


@dataclass
class Receivers:
    mesh: ReceiverMesh
    objects: list[ReceiverInfo] = field(default_factory=list)


def _linked_node(socket, depth=0):
    if socket is None or not socket.is_linked or depth > 32:
        return None
    node = socket.links[0].from_node
    return _linked_node(node.inputs[0], depth + 1) if node.type == "REROUTE" else node


def _value(node, name, default):
    sock = node.inputs.get(name)
    if sock is None:
        return default
    v = sock.default_value
    try:
        return tuple(float(x) for x in v)[:3]
    except TypeError:
        return float(v)


def surface_of(material, info: ReceiverInfo) -> ReceiverInfo:
    """Fill `info`'s colour, image and fallback from the shader feeding the output."""
    if material is None:
        return info
    nt = node_tree(material)
    if nt is None:
        info.color = tuple(material.diffuse_color[:3])
        return info
    out = nt.get_output_node("EEVEE") or nt.get_output_node("ALL")
    node = _linked_node(out.inputs.get("Surface")) if out is not None else None
    if node is None:
        return info
    t = node.type
    if t in (
        "BSDF_GLOSSY",
        "BSDF_ANISOTROPIC",
        "BSDF_GLASS",
        "BSDF_REFRACTION",
        "BSDF_TRANSPARENT",
    ):
        info.fallback = fallback_reason(
            0.0,
            0.0 if t in ("BSDF_GLOSSY", "BSDF_ANISOTROPIC") else 1.0,
            t in ("BSDF_GLOSSY", "BSDF_ANISOTROPIC"),
        )
        return info
    name = "Base Color" if t == "BSDF_PRINCIPLED" else "Color"
    if t == "BSDF_PRINCIPLED":
        info.fallback = fallback_reason(
            _value(node, "Metallic", 0.0), _value(node, "Transmission Weight", 0.0), False
        )
    if name not in node.inputs:
        return info
    src = _linked_node(node.inputs[name])
    if src is not None and src.type == "TEX_IMAGE" and src.image is not None:
        info.image, info.interpolation, info.extension = src.image, src.interpolation, src.extension
    elif src is not None and src.type == "RGB":
        info.color = tuple(src.outputs[0].default_value)[:3]
    else:
        info.color = _value(node, name, DEFAULT_COLOR)
    return info


def _mesh_corners(mesh):
    """(corner positions L × 3, triangles T × 3 of corner indices, UVs L × 2 or None)."""
    v = np.empty(len(mesh.vertices) * 3)
    mesh.vertices.foreach_get("co", v)
    vi = np.empty(len(mesh.loops), dtype=np.int64)
    mesh.loops.foreach_get("vertex_index", vi)
    tris = mesh.loop_triangles
    t = np.empty(len(tris) * 3, dtype=np.int64)
    tris.foreach_get("loops", t)
    uv = None
    layer = next((u for u in mesh.uv_layers if u.active_render), None) or mesh.uv_layers.active
    if layer is not None:
        uv = np.empty(len(mesh.loops) * 2)
        layer.data.foreach_get("uv", uv)
        uv = uv.reshape(-1, 2)
    return v.reshape(-1, 3)[vi], t.reshape(-1, 3), uv


def read_receivers(depsgraph, exclude=()) -> Receivers:
    """The receivers in `depsgraph` (see the module's docstring); `exclude`: original
    objects that are no receivers (the lenses)."""
    excluded = {ob.as_pointer() for ob in exclude if ob is not None}
    viewport = depsgraph.mode != "RENDER" and not reads_viewport_as_render(depsgraph)
    visible = render_visible_objects(depsgraph.view_layer) if viewport else None
    meshes: dict = {}
    ids: dict = {}
    infos: list[ReceiverInfo] = []
    parts = []
    for inst in depsgraph.object_instances:
        ob = inst.object
        if ob.type != "MESH":
            continue
        orig = ob.original
        if orig.as_pointer() in excluded or is_lens_light(orig):
            continue
        if inst.is_instance and inst.parent.original.as_pointer() in excluded:
            continue
        if viewport and (orig.hide_render or (not inst.is_instance and orig not in visible)):
            continue
        key = ob.data.as_pointer()
        if key not in meshes:
            meshes[key] = _mesh_corners(ob.data)
        corners, tris, uv = meshes[key]
        if not len(tris):
            continue
        oid = ids.get(orig.as_pointer())
        if oid is None:
            oid = ids[orig.as_pointer()] = len(infos)
            infos.append(surface_of(main_material(ob, ob.data), ReceiverInfo(orig.name, orig)))
        m = np.array(inst.matrix_world)
        parts.append((corners @ m[:3, :3].T + m[:3, 3], tris, uv, oid))
    if not parts:
        empty = ReceiverMesh(
            np.zeros((0, 3)),
            np.zeros((0, 3), dtype=np.int64),
            np.zeros((0, 2)),
            np.zeros(0, dtype=np.int64),
        )
        return Receivers(empty, infos)
    offsets = np.cumsum([0] + [len(p[0]) for p in parts[:-1]])
    verts = np.concatenate([p[0] for p in parts])
    tris = np.concatenate([p[1] + o for p, o in zip(parts, offsets, strict=True)])
    uvs = np.concatenate([p[2] if p[2] is not None else np.zeros((len(p[0]), 2)) for p in parts])
    oids = np.concatenate([np.full(len(p[1]), p[3], dtype=np.int64) for p in parts])
    return Receivers(ReceiverMesh(verts, tris, uvs, oids), infos)
