"""What a Blender material does to light, read from its node tree: the shader
nodes feeding the active output become the plain-data tree of
`core.lens.glass` (Principled, Glass, Refraction, Mix, Add, Volume
Absorption; other nodes are opaque), which `evaluate_material` turns into lens
optics (`material_optics`; the Principled BSDF's Thin Wall, 5.x, is read too: a
shell, no lens). Unlinked input values are read; a Value or RGB node
feeding an input gives its value; anything else driving an input is noted and the
socket's own value used. Muted nodes and links are skipped, reroutes followed.
"""

from __future__ import annotations

import bpy
import numpy as np

from ...core.lens.glass import (
    GLASS,
    OTHER,
    PRINCIPLED,
    REFRACTION,
    Absorption,
    Add,
    Bsdf,
    MaterialOptics,
    Mix,
    evaluate_material,
)


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


def _thin_wall(node, notes) -> bool:
    """Principled BSDF's Thin Wall (a boolean input from Blender 5.0; 4.5 has none)."""
    value = _input_value(node, "Thin Wall", False, notes)
    return bool(value) if isinstance(value, (bool, float, int)) else False


def _shader(socket, notes, depth=0):
    """Plain-data shader tree (`core.lens.glass`) of what feeds `socket`."""
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
        return Bsdf(
            PRINCIPLED,
            ior=_input_value(node, "IOR", 1.5, notes),
            color=_input_value(node, "Base Color", (0.8, 0.8, 0.8), notes),
            transmission=_input_value(node, "Transmission Weight", 0.0, notes),
            metallic=_input_value(node, "Metallic", 0.0, notes),
            alpha=_input_value(node, "Alpha", 1.0, notes),
            name=node.name,
            thin_wall=_thin_wall(node, notes),
        )
    if t in ("BSDF_GLASS", "BSDF_REFRACTION"):
        return Bsdf(
            GLASS if t == "BSDF_GLASS" else REFRACTION,
            ior=_input_value(node, "IOR", 1.5, notes),
            color=_input_value(node, "Color", (1.0, 1.0, 1.0), notes),
            name=node.name,
        )
    if t == "MIX_SHADER":
        fac = _input_value(node, "Fac", 0.5, notes)
        return Mix(
            fac if isinstance(fac, float) else 0.5,
            _shader(node.inputs[1], notes, depth + 1),
            _shader(node.inputs[2], notes, depth + 1),
        )
    if t == "ADD_SHADER":
        return Add(
            _shader(node.inputs[0], notes, depth + 1), _shader(node.inputs[1], notes, depth + 1)
        )
    if t == "VOLUME_ABSORPTION":
        return Absorption(
            _input_value(node, "Density", 1.0, notes),
            _input_value(node, "Color", (0.8, 0.8, 0.8), notes),
        )
    color = _input_value(node, "Color", None, notes) if "Color" in node.inputs else None
    if color is None and "Base Color" in node.inputs:
        color = _input_value(node, "Base Color", None, notes)
    if t in ("GROUP", "CUSTOM"):
        notes.append(f"node '{node.name}' ({node.bl_idname}) not looked into: treated as opaque")
    return Bsdf(
        OTHER, color=tuple(color) if isinstance(color, tuple) else (0.8, 0.8, 0.8), name=node.name
    )


def node_tree(material):
    """The node tree a material renders with, or None (before Blender 5.0 a material
    may keep a node tree with "Use Nodes" off: it renders its plain colours then;
    from 5.0 every material uses its nodes and `use_nodes` is deprecated)."""
    nt = material.node_tree
    if nt is not None and bpy.app.version < (5, 0, 0) and not material.use_nodes:
        return None
    return nt


def material_optics(material) -> MaterialOptics:
    """Lens optics of a Blender material (None: Blender's default grey, opaque)."""
    if material is None:
        return MaterialOptics(notes=["no material"])
    nt = node_tree(material)
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


def main_material(ob, mesh):
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
        k = int(
            np.argmax(
                np.bincount(np.clip(idx, 0, len(slots) - 1), weights=area, minlength=len(slots))
            )
        )
    else:
        k = 0
    return slots[k].material
