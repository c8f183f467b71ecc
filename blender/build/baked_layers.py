"""The baked Caustic layer's Blender data (`core/animation/layer_segments.py` plans it,
`blender/commands/bake.py` keys it): per segment one mesh object whose topology is fixed
over its frames, and per bake one atlas image of every frame's irradiance.

* **Mesh.** `layers.create_layer`'s mesh (lifted off the receiver, the
  receiver's UVs in "UVMap") of `layer_segments.baked_mesh`: one quad over the
  segment's raster where the receiver's UVs are affine (a floor, a wall), else
  Generate's vertex grid; no irradiance attribute. Its size does not
  depend on the raster's resolution.
* **Image.** The slices as tiles of one packed half-float OpenEXR (ZIP; one channel
  when every slice is one colour times a scalar), each normalised to its maximum,
  Non-Color; marked (`marks.COLLECTION_MARK` = "bake") and removed by Clear
  once unused. It renders in a Blender without the extension.
* **Reflection copy** (EEVEE): Generate's copy of the layer for mirrors and probes
  (`layers.create_reflection`), its material reading the same atlas, keyed alike.
* **Material.** Generate's layer material for that receiver (`layers.
  layer_material`: irradiance × the receiver's colour or texture / π, added to a
  transparent BSDF), its irradiance read from the image instead of the face
  attribute: each point's texel from its object coordinates through the inverse of
  the raster's warp (`layer_segments.raster_coordinate`), in the tile of the keyed slice
  index (`SLICE_NODE`), clamped inside the tile's texel centres, interpolated
  bilinearly between the four nearest texel centres (four Closest reads: EEVEE
  mipmaps a Linear image; continuous, as Generate's layer; each texel's value scaled
  so its flux is kept: `core/caustic_layer/smooth.image_texels`), times the keyed scale
  (`SCALE_NODE`) and colour (`COLOUR_NODE`). EEVEE and Cycles read it alike. The
  object keeps its raster (`RASTER_PROP`).
"""

from __future__ import annotations

import bpy

from ...core.animation import layer_segments
from ...core.caustic_layer.smooth import DrawnMesh, image_texels
from . import layers, lights
from .marks import BAKE_IMAGE_PREFIX, BAKE_MARK, COLLECTION_MARK

SLICE_NODE, SCALE_NODE, COLOUR_NODE = "Lens layer slice", "Lens layer scale", "Lens layer colour"
#: Object property: (c, s, ξ0, dξ) along u, along v, then axis_u, axis_v (world).
RASTER_PROP = "lens_lights_raster"


def packed_exr(name: str, pixels) -> object:
    """A packed half-float OpenEXR of `pixels` (`lights.packed_exr`), marked
    "bake"."""
    img = lights.packed_exr(name, pixels, "16", "lens_caustic_bake.exr")
    img[COLLECTION_MARK] = BAKE_MARK
    return img


_math = lights.shader_math


def _raster_coordinate(nt, position, axis, direction, res: int):
    """Nodes of `layer_segments.raster_coordinate` along one axis: t = (asinh((p·a −
    c)/s) − ξ0) / (res·dξ), asinh as sign · ln(|x| + √(x² + 1))."""
    c, s, xi0, dxi = (float(x) for x in axis)
    dot = nt.nodes.new("ShaderNodeVectorMath")
    dot.operation = "DOT_PRODUCT"
    nt.links.new(position, dot.inputs[0])
    dot.inputs[1].default_value = tuple(float(x) for x in direction)
    x = _math(nt, "DIVIDE", _math(nt, "SUBTRACT", dot.outputs["Value"], c), s)
    root = _math(nt, "SQRT", _math(nt, "MULTIPLY_ADD", x, x, 1.0))
    ln = _math(nt, "LOGARITHM", _math(nt, "ADD", _math(nt, "ABSOLUTE", x), root), 2.718281828459045)
    xi = _math(nt, "MULTIPLY", _math(nt, "SIGN", x), ln)
    return _math(nt, "DIVIDE", _math(nt, "SUBTRACT", xi, xi0), res * dxi)


def _image_reader(nt, image, cols: int, rows: int, seg):
    """Nodes reading slice `SLICE_NODE` of the atlas at each point (from its object
    coordinates: the layer's vertices are in world space at the identity), bilinear
    between the four nearest texel centres, each read Closest (a Linear image node
    would do it, but EEVEE mipmaps it: a sharp caustic would blur and a tile bleed
    into its neighbours); beyond the first or last centre the texel extends. Returns
    the socket of irradiance / (scale × colour)."""
    res = seg.layer.resolution
    s = nt.nodes.new("ShaderNodeValue")
    s.name = s.label = SLICE_NODE
    row = _math(nt, "FLOOR", _math(nt, "DIVIDE", _math(nt, "ADD", s.outputs[0], 0.5), cols))
    col = _math(nt, "SUBTRACT", s.outputs[0], _math(nt, "MULTIPLY", row, cols))
    coords = nt.nodes.new("ShaderNodeTexCoord")
    half = 0.5 / res  # the tile's first and last texel centres: never a neighbour tile

    def texels(axis, direction, tile, count):
        """The image coordinates of the two texel centres about each point along one
        axis, and the point's share of the way from the first to the second."""
        t = _raster_coordinate(nt, coords.outputs["Object"], axis, direction, res)
        inside = _math(nt, "MINIMUM", _math(nt, "MAXIMUM", t, half), 1.0 - half)
        p = _math(nt, "MULTIPLY_ADD", inside, res, -0.5)  # texel centres at integers
        first = _math(nt, "FLOOR", p)
        second = _math(nt, "MINIMUM", _math(nt, "ADD", first, 1.0), res - 1.0)

        def image(i):
            return _math(
                nt,
                "DIVIDE",
                _math(nt, "ADD", tile, _math(nt, "MULTIPLY_ADD", i, 1.0 / res, half)),
                count,
            )

        return image(first), image(second), _math(nt, "SUBTRACT", p, first)

    _n, axis_u, axis_v = seg.plane
    u0, u1, fu = texels(seg.axes[0], axis_u, col, cols)
    v0, v1, fv = texels(seg.axes[1], axis_v, row, rows)

    def sample(u, v):
        comb = nt.nodes.new("ShaderNodeCombineXYZ")
        nt.links.new(u, comb.inputs["X"])
        nt.links.new(v, comb.inputs["Y"])
        tex = nt.nodes.new("ShaderNodeTexImage")
        tex.image = image
        tex.interpolation = "Closest"
        tex.extension = "EXTEND"
        nt.links.new(comb.outputs[0], tex.inputs["Vector"])
        return tex.outputs["Color"]

    def mix(a, b, f):
        m = nt.nodes.new("ShaderNodeMix")
        m.data_type = "RGBA"
        m.blend_type = "MIX"
        nt.links.new(f, m.inputs["Factor"])
        nt.links.new(a, m.inputs["A"])
        nt.links.new(b, m.inputs["B"])
        return m.outputs["Result"]

    low = mix(sample(u0, v0), sample(u1, v0), fu)
    high = mix(sample(u0, v1), sample(u1, v1), fu)
    return mix(low, high, fv)


def baked_material(info, image, cols: int, rows: int, seg, reflection=False):
    """Generate's layer material for receiver `info` (or, with `reflection`, its
    EEVEE reflection copy's: `layers.reflection_material`), reading the atlas."""
    if reflection:
        mat = layers.reflection_material(info, {})
    else:
        mat = layers.layer_material(info, {})
    nt = mat.node_tree
    attr = next(n for n in nt.nodes if n.bl_idname == "ShaderNodeAttribute")
    targets = [link.to_socket for out in attr.outputs for link in out.links]
    nt.nodes.remove(attr)
    texel = _image_reader(nt, image, cols, rows, seg)
    colour = nt.nodes.new("ShaderNodeRGB")
    colour.name = colour.label = COLOUR_NODE
    scale = nt.nodes.new("ShaderNodeValue")
    scale.name = scale.label = SCALE_NODE
    tinted = nt.nodes.new("ShaderNodeVectorMath")
    tinted.operation = "MULTIPLY"
    nt.links.new(texel, tinted.inputs[0])
    nt.links.new(colour.outputs[0], tinted.inputs[1])
    scaled = nt.nodes.new("ShaderNodeVectorMath")
    scaled.operation = "SCALE"
    nt.links.new(tinted.outputs[0], scaled.inputs[0])
    nt.links.new(scale.outputs[0], scaled.inputs["Scale"])
    for target in targets:  # (the reflection copy's "lit" test reads it as a float)
        nt.links.new(scaled.outputs[0], target)
    return mat


def baked_layer(scene, seg, info, collection, material, k: int):
    """The segment's layer object: `layer_segments.baked_mesh` of its raster (one quad
    where the receiver's UVs are affine), without the irradiance attribute, with
    `material` instead of Generate's."""
    key = (info.name, info.image.name if info.image is not None else None)
    mesh = layer_segments.baked_mesh(seg.layer)
    drawn = DrawnMesh(mesh.vertices, mesh.faces, mesh.uvs, None)  # the image holds the light
    ob = layers.create_layer(scene, mesh, info, collection, {key: material}, k, drawn=drawn)
    res = seg.layer.resolution
    # the raster, for whoever reads the image back: texel lines x = c + s·sinh(ξ0 + i·dξ)
    # along axis_u (u) and axis_v (v), i = 0…res
    ob[RASTER_PROP] = [float(x) for x in (*seg.axes[0], *seg.axes[1], *seg.plane[1], *seg.plane[2])]
    ob.lens_lights.note = (
        f"baked caustic layer: a {res}² raster over {len(seg.frames)} "
        f"frame{'s' if len(seg.frames) != 1 else ''} "
        f"(texels at most {seg.coarsening:.2f}× Generate's at the caustic's core)"
        + (" (coarse: out of the camera's view, for reflections)" if seg.key[-1] else "")
    )
    return ob


def build(
    scene, segments, res: int, infos, collection, reflections=False
) -> tuple[list, list, int, list]:
    """Every segment's object, material and the atlas images. `infos[i]`: the
    segment's receiver (`blender.read.receivers.ReceiverInfo`). Returns (objects, per
    segment (material, slice index per frame, scale per frame, colour per frame),
    image count, per segment its EEVEE reflection copy (object, material) with
    `reflections`, else None: keyed like the layer)."""
    # the texels an image drawn bilinearly between texel centres needs for each texel's flux
    all_slices = [image_texels(sl, s.axes, s.layer.resolution) for s in segments for sl in s.slices]
    images, scales, colours, _mono = layer_segments.split_colour(all_slices)
    cap = layer_segments.atlas_capacity(res)
    # segments into images of at most `cap` slices, in order
    groups, count = [[]], 0
    for i, s in enumerate(segments):
        if count + len(s.slices) > cap:
            groups.append([])
            count = 0
        groups[-1].append(i)
        count += len(s.slices)
    objects, keyed, made_images, start, copies = [], [], 0, 0, []
    for g in groups:
        n = sum(len(segments[i].slices) for i in g)
        if not n:
            continue
        cols, rows = layer_segments.atlas_layout(n, res)
        atlas = layer_segments.stack_atlas(images[start : start + n], cols, rows)
        image = packed_exr(f"{BAKE_IMAGE_PREFIX}{made_images + 1}", atlas)
        made_images += 1
        k = 0
        for i in g:
            s, info = segments[i], infos[i]
            mat = baked_material(info, image, cols, rows, s)
            ob = baked_layer(scene, s, info, collection, mat, len(objects))
            objects.append(ob)
            copies.append(
                _reflection(scene, ob, info, collection, image, cols, rows, s)
                if reflections
                else None
            )
            m = len(s.slices)
            sl = slice(start + k, start + k + m)
            keyed.append((mat, list(range(k, k + m)), scales[sl], colours[sl]))
            k += m
        start += n
    return objects, keyed, made_images, copies


def _reflection(scene, ob, info, collection, image, cols, rows, seg):
    """(the layer object `ob`'s reflection copy, its material reading the atlas)."""
    mat = baked_material(info, image, cols, rows, seg, reflection=True)
    key = ("reflected", info.name, info.image.name if info.image is not None else None)
    return layers.create_reflection(scene, ob, info, collection, {key: mat}), mat


def remove_unused_bake_images() -> int:
    """Remove the baked layer's images (marked) that nothing uses (`cleanup`)."""
    unused = [i for i in bpy.data.images if i.get(COLLECTION_MARK) == BAKE_MARK and i.users == 0]
    if unused:
        bpy.data.batch_remove(unused)
    return len(unused)
