"""Small node-building helpers shared by the profile node tree (`lights`), the shadow
mask (`mask_nodes`) and the baked layers (bpy): a Math node, a named Value node (a
number the bake keys per frame), a table's texture coordinates in a slice of a
stacked image."""

from __future__ import annotations


def shader_math(nt, op, *inputs):
    """A Math node of `nt` doing `op` on `inputs` (numbers become its default values,
    sockets are linked; None leaves an input as it is); its output socket."""
    n = nt.nodes.new("ShaderNodeMath")
    n.operation = op
    for k, v in enumerate(inputs):
        if v is None:
            continue
        if isinstance(v, (int, float)):
            n.inputs[k].default_value = float(v)
        else:
            nt.links.new(v, n.inputs[k])
    return n.outputs[0]


def value_node(nt, name: str, value: float):
    """A Value node of `nt` named (and labelled) `name`, holding `value`: a number the
    bake keys per frame. Its output socket."""
    node = nt.nodes.new("ShaderNodeValue")
    node.name = node.label = name
    node.outputs[0].default_value = float(value)
    return node.outputs[0]


def slice_coordinates(nt, u, v, layout, k):
    """The texture coordinates (a Combine XYZ's output) of the table's (u, v) in slice
    `k` (a socket holding a whole number) of `layout` (a
    `core.animation.frame_tables.SliceLayout`), as its `texture_coordinates`: u and v
    clamped to the tile's first and last texel centres (EXTEND within the tile)."""

    def op(kind, *args):
        return shader_math(nt, kind, *args)

    hu, hv = 0.5 / layout.width, 0.5 / layout.rows
    u = op("MAXIMUM", op("MINIMUM", u, 1.0 - hu), hu)
    v = op("MAXIMUM", op("MINIMUM", v, 1.0 - hv), hv)
    if layout.columns > 1:
        row = op("FLOOR", op("DIVIDE", op("ADD", k, 0.5), float(layout.columns)))
        col = op("MULTIPLY_ADD", row, -float(layout.columns), k)
        u = op("DIVIDE", op("ADD", col, u), float(layout.columns))
    else:
        row = k
    v = op("DIVIDE", op("ADD", row, v), float(layout.tile_rows))
    comb = nt.nodes.new("ShaderNodeCombineXYZ")
    nt.links.new(u, comb.inputs["X"])
    nt.links.new(v, comb.inputs["Y"])
    return comb.outputs[0]
