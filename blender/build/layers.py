"""The Caustic layer tier's Blender objects: one emissive mesh per `PatchLayer`.

Each layer is a mesh object "Lens caustic <receiver> <k>" in the "Lens Lights"
collection, at the identity transform (the core's vertices are in world space,
already lifted off the receiver along its normal: no z-fighting), marked and
listed like a lens light (`object.lens_lights.is_lens_light`, the scene's
`created_objects`), so Clear removes it and its mesh; its material is marked
(`marks.COLLECTION_MARK` = "layer") and removed by Clear once unused
(`remove_unused_layer_materials`). No images: the irradiance is a point attribute of
a mesh over the texel centres (`core/caustic_layer/smooth.py`), interpolated linearly
over its triangles (no texel shows as a block; the flux of every texel is kept).

Material (one per receiver object): radiance = irradiance × the receiver's diffuse
colour / π, the colour being the receiver's own (a constant, or its image texture
sampled through the layer's UV map, which holds the receiver's UVs); emission added
to a white Transparent BSDF, so where the irradiance is 0 the layer is invisible
and elsewhere it only adds light over the receiver (EEVEE: blended render method,
sorted). Ray visibility: the camera, glossy and transmission rays (a mirror shows
the caustic on the floor it reflects in Cycles; no spot light paints it any more); no
shadow (the layer sits between the receiver and its lights), no diffuse (it must not
light other objects).

EEVEE's reflections (screen-traced, and its plane and sphere light probes) hold only
its deferred surfaces, never blended ones: a mirror there shows the receiver without
the layer. So in EEVEE each layer has a **reflection copy** ("… reflected"): the same
mesh, hidden from the camera and from every ray (Cycles never sees it) and from
volume probes, with a Dithered material that is the receiver's diffuse colour lit
as a diffuse surface plus the layer's emission where the irradiance is not 0, and
fully transparent elsewhere. Plane and sphere probes capture it, so a mirror with a
Light Probe Plane (Raytracing on) shows the caustic; over the caustic the mirror
then shows the receiver as a plain diffuse surface of its colour (its gloss is not
copied).
"""

from __future__ import annotations

import math

import bpy
import numpy as np

from ...core.caustic_layer.smooth import drawn_mesh
from .lights import create_light, lights_collection
from .marks import (
    COLLECTION_MARK,
    INCLUDE_PREFIX,
    LAYER_MARK,
    LAYER_PREFIX,
    LINK_MARK,
    MATERIAL_PREFIX,
    REFLECTION_MARK,
    WATER_MARK,
)
from .ownership import created_objects, register

#: The point attribute holding the irradiance (W per unit², RGB), interpolated per triangle.
IRRADIANCE = "lens_irradiance"
REFLECTED_SUFFIX = " reflected"
UV_NAME = "UVMap"


def _is_layer_material(mat) -> bool:
    return mat.get(COLLECTION_MARK) == LAYER_MARK


def layer_material(info, cache: dict):
    """The layer material for receiver `info` (`blender.read.receivers.ReceiverInfo`)."""
    key = (info.name, info.image.name if info.image is not None else None)
    mat = cache.get(key)
    if mat is not None:
        return mat
    mat = bpy.data.materials.new(MATERIAL_PREFIX + info.name)
    mat[COLLECTION_MARK] = LAYER_MARK
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    if hasattr(mat, "surface_render_method"):
        mat.surface_render_method = "BLENDED"
    else:  # EEVEE Legacy
        mat.blend_method = "BLEND"
    if hasattr(mat, "use_transparent_shadow"):
        mat.use_transparent_shadow = True
    nt = mat.node_tree
    nt.nodes.clear()
    attr = nt.nodes.new("ShaderNodeAttribute")
    attr.attribute_type = "GEOMETRY"
    attr.attribute_name = IRRADIANCE
    mix = nt.nodes.new("ShaderNodeMix")
    mix.data_type = "RGBA"
    mix.blend_type = "MULTIPLY"
    mix.inputs["Factor"].default_value = 1.0
    nt.links.new(attr.outputs["Color"], mix.inputs["A"])
    if info.image is not None:
        nt.links.new(_receiver_texture(nt, info), mix.inputs["B"])
    else:
        mix.inputs["B"].default_value = (*info.color[:3], 1.0)
    em = nt.nodes.new("ShaderNodeEmission")
    em.inputs["Strength"].default_value = 1.0 / math.pi  # Lambertian: L = ρE/π
    nt.links.new(mix.outputs["Result"], em.inputs["Color"])
    tr = nt.nodes.new("ShaderNodeBsdfTransparent")
    tr.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    add = nt.nodes.new("ShaderNodeAddShader")
    nt.links.new(em.outputs[0], add.inputs[0])
    nt.links.new(tr.outputs[0], add.inputs[1])
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    nt.links.new(add.outputs[0], out.inputs["Surface"])
    cache[key] = mat
    return mat


def _receiver_texture(nt, info):
    """In node tree `nt`: receiver `info`'s image read through the layer's UVs (as the
    receiver reads it); its colour output."""
    uv = nt.nodes.new("ShaderNodeUVMap")
    uv.uv_map = UV_NAME
    tex = nt.nodes.new("ShaderNodeTexImage")
    tex.image = info.image
    tex.interpolation = info.interpolation
    tex.extension = info.extension
    nt.links.new(uv.outputs["UV"], tex.inputs["Vector"])
    return tex.outputs["Color"]


def reflection_material(info, cache: dict):
    """The reflection copy's material for receiver `info` (see the module's text):
    Dithered; where the layer's irradiance is above 0 the receiver's diffuse colour as a
    Diffuse BSDF plus the layer's emission, elsewhere a Transparent BSDF."""
    key = ("reflected", info.name, info.image.name if info.image is not None else None)
    mat = cache.get(key)
    if mat is not None:
        return mat
    mat = bpy.data.materials.new(MATERIAL_PREFIX + info.name + REFLECTED_SUFFIX)
    mat[COLLECTION_MARK] = LAYER_MARK
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    if hasattr(mat, "surface_render_method"):
        mat.surface_render_method = "DITHERED"
    nt = mat.node_tree
    nt.nodes.clear()
    attr = nt.nodes.new("ShaderNodeAttribute")
    attr.attribute_type = "GEOMETRY"
    attr.attribute_name = IRRADIANCE
    if info.image is not None:
        colour = _receiver_texture(nt, info)
    else:
        rgb = nt.nodes.new("ShaderNodeRGB")
        rgb.outputs[0].default_value = (*info.color[:3], 1.0)
        colour = rgb.outputs[0]
    mix = nt.nodes.new("ShaderNodeMix")
    mix.data_type = "RGBA"
    mix.blend_type = "MULTIPLY"
    mix.inputs["Factor"].default_value = 1.0
    nt.links.new(attr.outputs["Color"], mix.inputs["A"])
    nt.links.new(colour, mix.inputs["B"])
    em = nt.nodes.new("ShaderNodeEmission")
    em.inputs["Strength"].default_value = 1.0 / math.pi
    nt.links.new(mix.outputs["Result"], em.inputs["Color"])
    diffuse = nt.nodes.new("ShaderNodeBsdfDiffuse")
    nt.links.new(colour, diffuse.inputs["Color"])
    add = nt.nodes.new("ShaderNodeAddShader")
    nt.links.new(em.outputs[0], add.inputs[0])
    nt.links.new(diffuse.outputs[0], add.inputs[1])
    # opaque (the receiver's look + the caustic) only where there is a caustic
    lit = nt.nodes.new("ShaderNodeMath")
    lit.operation = "GREATER_THAN"
    lit.inputs[1].default_value = 0.0
    nt.links.new(attr.outputs["Fac"], lit.inputs[0])
    tr = nt.nodes.new("ShaderNodeBsdfTransparent")
    pick = nt.nodes.new("ShaderNodeMixShader")
    nt.links.new(lit.outputs[0], pick.inputs[0])
    nt.links.new(tr.outputs[0], pick.inputs[1])
    nt.links.new(add.outputs[0], pick.inputs[2])
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    nt.links.new(pick.outputs[0], out.inputs["Surface"])
    cache[key] = mat
    return mat


def is_reflection(ob) -> bool:
    """Whether `ob` is a layer's reflection copy (`create_reflection`)."""
    return bool(ob.get(REFLECTION_MARK, False))


def create_reflection(scene, layer_ob, info, collection, materials):
    """The EEVEE reflection copy of `layer_ob` (see the module's text), registered
    and marked like it (Clear removes it)."""
    ob = bpy.data.objects.new(layer_ob.name + REFLECTED_SUFFIX, layer_ob.data)
    ob[REFLECTION_MARK] = True
    ob.material_slots[0].link = "OBJECT"
    ob.material_slots[0].material = reflection_material(info, materials)
    collection.objects.link(ob)
    for attr in ("camera", "diffuse", "glossy", "transmission", "shadow", "volume_scatter"):
        setattr(ob, "visible_" + attr, False)
    if hasattr(ob, "hide_probe_volume"):  # it must not light anything either
        ob.hide_probe_volume = True
    meta = ob.lens_lights
    meta.is_lens_light = True
    meta.energy_model = "CAUSTIC_LAYER"
    meta.receiver = info.name
    meta.source_light = layer_ob.lens_lights.source_light
    meta.source_lens = layer_ob.lens_lights.source_lens
    meta.relative_brightness = layer_ob.lens_lights.relative_brightness
    meta.note = "reflection copy of the caustic layer (EEVEE's mirrors and probes)"
    register(scene, ob)
    return ob


def layer_mesh(name, drawn, shapes: dict | None = None):
    """A mesh of `drawn` (`core.caustic_layer.smooth.DrawnMesh`: Generate's triangles
    over the texel centres, or the bake's quad): its faces, its UVs (per corner), and
    the irradiance as a point attribute, which the renderer interpolates over each
    triangle (none if ``drawn.irradiance`` is None). ``shapes``: meshes made before by
    topology; a mesh of the same faces starts as a copy of one (Blender copies a
    mesh's topology at memory speed, which is 5–6× faster than setting it) and only
    its positions, UVs and irradiance are set."""
    faces = np.asarray(drawn.triangles, dtype=np.int32)
    n_f, corners = faces.shape
    key = (len(drawn.vertices), n_f, corners, drawn.uvs is not None, drawn.irradiance is not None)
    like = shapes.get(key) if shapes is not None else None
    if like is not None and np.array_equal(like[1], faces):
        me = like[0].copy()
        me.name = name
        me.materials.clear()
        _set_positions_uvs(me, drawn, faces)
        if drawn.irradiance is not None:
            me.attributes[IRRADIANCE].data.foreach_set("color", _rgba(drawn).ravel())
        me.update()
        return me
    me = bpy.data.meshes.new(name)
    me[COLLECTION_MARK] = LAYER_MARK
    _fill(me, drawn, faces)
    if shapes is not None:
        shapes[key] = (me, faces)
    return me


def _fill(me, drawn, faces):
    """`me` (empty) given the faces, UVs, positions and irradiance of `drawn`."""
    n_f, corners = faces.shape
    me.vertices.add(len(drawn.vertices))
    me.loops.add(corners * n_f)
    # the corners' vertices as one attribute array (MeshLoop.vertex_index goes corner
    # by corner: 30–100 ms for a 256² raster's 390 000 corners, the attribute < 1 ms)
    corner_vert = me.attributes.get(".corner_vert")
    if corner_vert is not None and corner_vert.data_type == "INT":
        corner_vert.data.foreach_set("value", faces.ravel())
    else:
        me.loops.foreach_set("vertex_index", faces.ravel())
    me.polygons.add(n_f)
    me.polygons.foreach_set("loop_start", np.arange(0, corners * n_f, corners, dtype=np.int32))
    _set_edges(me, drawn)
    if drawn.uvs is not None:
        me.uv_layers.new(name=UV_NAME)
    _set_positions_uvs(me, drawn, faces)
    if drawn.irradiance is not None:
        me.attributes.new(IRRADIANCE, "FLOAT_COLOR", "POINT").data.foreach_set(
            "color", _rgba(drawn).ravel()
        )
    me.update()


def _set_edges(me, drawn) -> bool:
    """The edges `drawn` gives (`smooth.grid_edges`: in closed form) written whole, so
    that `me.update()` need not find them (a hash of every corner pair: 45 ms of a
    251² raster's build); False (Blender finds them) without them or where the mesh
    has no such attributes."""
    if drawn.edges is None or drawn.corner_edges is None:
        return False
    corner_edge = me.attributes.get(".corner_edge")
    if corner_edge is None or corner_edge.data_type != "INT":
        return False
    me.edges.add(len(drawn.edges))
    verts = me.attributes.get(".edge_verts")
    edges = np.asarray(drawn.edges, dtype=np.int32).ravel()
    if verts is not None and verts.data_type == "INT32_2D":
        verts.data.foreach_set("value", edges)
    else:
        me.edges.foreach_set("vertices", edges)
    corner_edge.data.foreach_set("value", np.asarray(drawn.corner_edges, dtype=np.int32))
    return True


def refill_mesh(me, drawn):
    """`me` (a layer's mesh) made to draw `drawn` in place: the same datablock (the
    objects using it, their selection and undo keep it). Same topology (a raster of
    the same resolution): only its positions, UVs and irradiance are written;
    otherwise its geometry is replaced."""
    faces = np.asarray(drawn.triangles, dtype=np.int32)
    same = len(me.vertices) == len(drawn.vertices) and len(me.polygons) == len(faces)
    if same and (drawn.uvs is None) == (UV_NAME not in me.uv_layers):
        _set_positions_uvs(me, drawn, faces)
        write_irradiance(me, drawn.irradiance)
        return
    me.clear_geometry()
    for layer in list(me.uv_layers):
        me.uv_layers.remove(layer)
    if me.attributes.get(IRRADIANCE) is not None:
        me.attributes.remove(me.attributes[IRRADIANCE])
    _fill(me, drawn, faces)


def write_irradiance(me, irradiance) -> bool:
    """The irradiance point attribute of `me` set to ``irradiance`` (V, 3) in place;
    False when the mesh has not that many vertices (another raster)."""
    attr = me.attributes.get(IRRADIANCE)
    if attr is None or len(attr.data) != len(irradiance):
        return False
    rgba = np.ones((len(irradiance), 4), dtype=np.float32)
    rgba[:, :3] = irradiance
    attr.data.foreach_set("color", rgba.ravel())
    me.update()  # (tags it for the viewport and the render)
    return True


def _set_positions_uvs(me, drawn, faces):
    """The vertices' positions and the corners' UVs through the generic attributes:
    their arrays are set whole (MeshVertex.co and MeshUVLoop.uv go element by element,
    15–50× slower)."""
    co = np.asarray(drawn.vertices, dtype=np.float32).ravel()
    pos = me.attributes.get("position")
    if pos is not None and pos.data_type == "FLOAT_VECTOR":
        pos.data.foreach_set("vector", co)
    else:
        me.vertices.foreach_set("co", co)
    if drawn.uvs is not None:
        # each corner's (u, v) gathered as one 8-byte word: 4× faster than by pairs
        uv32 = np.ascontiguousarray(drawn.uvs, dtype=np.float32)
        uv = uv32.view(np.uint64).reshape(-1)[faces.reshape(-1)].view(np.float32)
        attr = me.attributes.get(UV_NAME)
        if attr is not None and attr.data_type == "FLOAT2" and attr.domain == "CORNER":
            attr.data.foreach_set("vector", uv)
        else:
            me.uv_layers[UV_NAME].data.foreach_set("uv", uv)


def _rgba(drawn) -> np.ndarray:
    rgba = np.ones((len(drawn.vertices), 4), dtype=np.float32)
    rgba[:, :3] = drawn.irradiance
    return rgba


def _visibility(ob):
    ob.visible_camera = True
    ob.visible_glossy = True
    ob.visible_transmission = True
    ob.visible_diffuse = False
    ob.visible_shadow = False
    ob.visible_volume_scatter = False


def layer_name(info, k) -> str:
    """The name of the layer object of patch `k` of a bake, on receiver `info`."""
    return f"{LAYER_PREFIX}{info.name} {k}"


def _describe(ob, patch, beams):
    """The panel's words on layer object `ob` drawing `patch` (`beams`: the (light,
    lens) names of its sources)."""
    meta = ob.lens_lights
    lights = ", ".join(dict.fromkeys(light for light, _lens in beams))
    lenses = ", ".join(dict.fromkeys(lens for _light, lens in beams))
    if meta.source_light != lights:
        meta.source_light = lights
    if meta.source_lens != lenses:
        meta.source_lens = lenses
    meta.relative_brightness = float(patch.flux)  # the flux it draws, W
    note = f"{patch.resolution}² texels" + (
        " (coarse: out of the camera's view, for reflections)" if patch.coarse else ""
    )
    if meta.note != note:
        meta.note = note


def create_layer(
    scene, patch, info, collection, materials, k, shapes=None, drawn=None, lights=(), lenses=()
):
    """One layer object (registered and marked like a lens light) drawing `patch`
    (`drawn`: its mesh, by default `smooth.drawn_mesh(patch)`); ``shapes``: see
    `layer_mesh`; `lights`, `lenses`: the names of the lights and lenses whose caustic
    it draws (the panel says them)."""
    name = layer_name(info, k)
    drawn = drawn_mesh(patch) if drawn is None else drawn
    ob = bpy.data.objects.new(name, layer_mesh(name, drawn, shapes))
    ob.data.materials.append(layer_material(info, materials))
    collection.objects.link(ob)
    _visibility(ob)
    meta = ob.lens_lights
    meta.is_lens_light = True
    meta.energy_model = "CAUSTIC_LAYER"
    meta.receiver = info.name  # the object it lies on
    _describe(ob, patch, list(zip(lights, lenses, strict=True)))
    register(scene, ob)
    return ob


def _include_collection(scene, objects, tag):
    """A linking collection that lights only `objects` (the fallback receivers)."""
    coll = bpy.data.collections.new(INCLUDE_PREFIX + tag)
    coll[COLLECTION_MARK] = LINK_MARK
    for ob in objects:
        coll.objects.link(ob)
    for member in coll.collection_objects:
        member.light_linking.link_state = "INCLUDE"
    scene.lens_lights.created_collections.add().collection = coll
    return coll


def build(
    scene, bake, receivers, planned, lens_objects, progress=None, mesh_names=(), reflections=False
):
    """The layers of `bake` (`core.caustic_layer.pipeline.SheetBake`) on `receivers`
    (`blender.read.receivers.Receivers`), each with its reflection copy if
    ``reflections`` (EEVEE); for the sources whose caustic lands on a receiver a layer
    cannot show, their Fitted spot (`planned[i]`), lighting only those receivers. The
    sources after the planned ones are glass meshes', named by `mesh_names` ((light,
    lens) each). Returns (layer objects and copies, fallback lights, fallback receiver
    names)."""
    names = [(p.light_name, p.lens_name) for p in planned] + list(mesh_names)
    collection = lights_collection(scene)
    materials: dict = {}
    shapes: dict = {}  # one topology per raster resolution: later meshes copy it
    layers, fallback_sources, fallback_objects = [], set(), {}
    patches = bake.layer.patches
    for k, patch in enumerate(patches):
        info = receivers.objects[patch.object_id]
        if info.fallback:
            fallback_sources.update(int(s) for s in patch.sources)
            fallback_objects[info.name] = info.original
            continue
        beams = [names[int(s)] for s in patch.sources if int(s) < len(names)]
        layers.append(
            create_layer(
                scene,
                patch,
                info,
                collection,
                materials,
                k,
                shapes,
                lights=[light for light, _lens in beams],
                lenses=[lens for _light, lens in beams],
            )
        )
        if reflections:
            layers.append(create_reflection(scene, layers[-1], info, collection, materials))
        if progress is not None and k % 8 == 7:
            progress((k + 1) / max(len(patches), 1))
    lights = []
    if any(s < len(planned) for s in fallback_sources):
        include = _include_collection(scene, list(fallback_objects.values()), "receivers")
        links: dict = {}
        for s in sorted(fallback_sources):
            if s >= len(planned):  # a mesh lens' source: no spot stands for it
                continue
            p = planned[s]
            ob = create_light(
                scene, p, lens_objects[p.source.lens], collection, links, model_name="CAUSTIC_LAYER"
            )
            ob.light_linking.receiver_collection = include
            ob.lens_lights.receiver = ", ".join(sorted(fallback_objects))
            lights.append(ob)
    return layers, lights, sorted(fallback_objects)


def _existing_layers(scene, patches, receivers, reflections) -> list | None:
    """The extension's layer object of each of `patches` (by `layer_name`), when the
    scene's objects are exactly those (and their reflection copies if
    ``reflections``: no fallback spot, none missing or extra); else None."""
    # (the water's layers are the water stage's: `water_stage.refill`)
    objects = [ob for ob in created_objects(scene) if not ob.get(WATER_MARK)]
    existing = {ob.name: ob for ob in objects if ob.type == "MESH"}
    if len(existing) != len(objects):  # a light: a fallback spot, or another tier's
        return None
    out = []
    for k, patch in enumerate(patches):
        info = receivers.objects[patch.object_id]
        ob = existing.get(layer_name(info, k))
        if info.fallback or ob is None or ob.data is None:
            return None
        out.append(ob)
    expected = {ob.name for ob in out}
    if reflections:
        expected |= {ob.name + REFLECTED_SUFFIX for ob in out}
    return out if set(existing) == expected else None


def refill(scene, bake, receivers, names, reflections, drawn=None, anchors=None) -> list | None:
    """The layers of `bake` written into the scene's layer objects in place (the same
    objects and meshes: `refill_mesh`), when they are the layers of the same patches
    on the same receivers (`_existing_layers`); None otherwise (nothing written: build
    anew). ``names``: (light, lens) per source; ``drawn``: per patch its irradiance at
    the drawn mesh's vertices (a coarse layer in the full one's rasters: positions and
    UVs are left as they are; ``anchors``: per patch the first and last vertex its
    mesh must have, else it is another raster's: an undo brought it back), else the
    drawn meshes are made here. ``reflections``: the layers have their EEVEE
    reflection copies (`build`)."""
    patches = bake.layer.patches
    objects = _existing_layers(scene, patches, receivers, reflections)
    if objects is None:
        return None
    if drawn is not None and not all(
        _holds(ob.data, v, a) for ob, v, a in zip(objects, drawn, anchors, strict=True)
    ):
        return None
    for k, (ob, patch) in enumerate(zip(objects, patches, strict=True)):
        if drawn is not None:
            write_irradiance(ob.data, drawn[k])
            beams = [names[int(s)] for s in patch.sources if int(s) < len(names)]
            _describe(ob, patch, beams)
        else:
            refill_layer(ob, patch, names)
    return objects


def refill_layer(ob, patch, names):
    """Layer object `ob` made to draw `patch` in place (its mesh: `refill_mesh`; its
    reflection copy shares it), its words updated; ``names``: (light, lens) per
    source."""
    refill_mesh(ob.data, drawn_mesh(patch))
    _describe(ob, patch, [names[int(s)] for s in patch.sources if int(s) < len(names)])


def _holds(me, values, anchors) -> bool:
    """Is `me` the mesh `values` (per vertex) and ``anchors`` (its first and last
    vertex, float32 as stored) were computed for?"""
    if len(me.vertices) != len(values) or not len(values):
        return False
    got = np.array([me.vertices[0].co, me.vertices[-1].co], dtype=np.float32)
    return bool(np.array_equal(got, np.asarray(anchors, dtype=np.float32)))


def made_counts(objects) -> dict:
    """What `objects` (the extension's, made or about to be removed) are, for
    `made_text`: lens lights (``made``), caustic layers (meshes) and the receivers
    they lie on, the layer's fallback spots and the receivers they light."""
    # (a layer's reflection copy for EEVEE is part of that layer: not counted)
    layers = [ob for ob in objects if ob.type != "LIGHT" and not is_reflection(ob)]
    fallback = [ob for ob in objects if ob.type == "LIGHT" and ob.lens_lights.receiver]
    return dict(
        made=sum(1 for ob in objects if ob.type == "LIGHT") - len(fallback),
        layers=len(layers),
        fallback=len(fallback),
        on=sorted({ob.lens_lights.receiver for ob in layers if ob.lens_lights.receiver}),
        fallback_on=sorted(
            {n for ob in fallback for n in ob.lens_lights.receiver.split(", ") if n}
        ),
    )


def remove_unused_layer_materials() -> int:
    """Remove the extension's layer materials (marked) that nothing uses."""
    unused = [m for m in bpy.data.materials if _is_layer_material(m) and m.users == 0]
    if unused:
        bpy.data.batch_remove(unused)
    return len(unused)
