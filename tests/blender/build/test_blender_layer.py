"""The Caustic layer tier on the Blender side, without rendering (the EEVEE render
of the layer against the exact optics: tests/blender/build/test_blender_render.py): AUTO in EEVEE
builds layers and no spot, the layer's flux against `core.lens.ball_optics`, a textured
receiver's image sampled through the receiver's UVs, a glossy receiver falls back to
a Fitted spot lighting only it, and Clear removes the layers and nothing else.
"""

import math

import bpy
import numpy as np
import pytest
from blender_scene_helpers import (
    basic_scene,
    caustic_layers,
    generate,
    layer_flux,
    lens_lights,
    set_engine,
    snapshot,
    snapshot_diff,
)
from measuring_scene import new_material

from core.lens import ball_optics

pytestmark = pytest.mark.blender

MARK = "lens_lights_created"
#: The layer's flux against the exact beam's flux (reports/caustic_layer.md: 0.9988
#: for the floating ball; the floor catches all but the grazing rays).
FLUX_TOL = 0.02


def layers():
    return caustic_layers()


def test_auto_in_eevee_builds_layers_not_lights(empty_blend):
    basic_scene()
    set_engine("BLENDER_EEVEE")
    level, message, figures = generate()
    assert level == "INFO", message
    assert figures["energy_model"] == "CAUSTIC_LAYER"
    assert "caustic layer" in message
    assert not [o for o in lens_lights() if o.type == "LIGHT"]  # no double light
    (ob,) = layers()
    assert ob.lens_lights.energy_model == "CAUSTIC_LAYER"
    assert ob.visible_camera and not ob.visible_shadow and not ob.visible_diffuse
    assert ob.users_collection[0].name == "Lens Lights"
    mat = ob.data.materials[0]
    assert mat.get(MARK) == "layer"
    types = {n.type for n in mat.node_tree.nodes}
    assert {"ATTRIBUTE", "EMISSION", "BSDF_TRANSPARENT", "ADD_SHADER"} <= types
    # Lifted above the floor (z = 0), toward the light.
    z = np.empty(len(ob.data.vertices) * 3)
    ob.data.vertices.foreach_get("co", z)
    assert 0.0 < z[2::3].min() < 1e-2
    # Flux on the floor against the exact optics (R 0.5, n 1.5, D 2, 1000 W).
    exact = ball_optics.lens_flux(1000.0 / (4 * math.pi), 2.0, 0.5, 1.5)
    assert layer_flux(ob) == pytest.approx(exact, rel=FLUX_TOL)
    # Read back, the layer is neither a lens, a receiver nor an occluder: same result.
    level, message, figures = generate()
    (ob2,) = layers()
    assert layer_flux(ob2) == pytest.approx(layer_flux_value := layer_flux(ob2))
    assert layer_flux_value == pytest.approx(exact, rel=FLUX_TOL)


def test_eevee_layers_have_a_reflection_copy_only_probes_see(empty_blend):
    # EEVEE's reflections hold no blended surface (issue 28 item 6): each layer gets a
    # copy on the same mesh, Dithered, hidden from the camera and from every ray (so
    # Cycles never draws it twice) and from volume probes (it lights nothing).
    basic_scene()
    set_engine("BLENDER_EEVEE")
    level, message, figures = generate()
    made = [o for o in lens_lights(copies=True) if o.type == "MESH"]
    copies = [o for o in made if o.get("lens_lights_reflection")]
    assert len(copies) == len(layers()) >= 1
    assert figures["layers"] == len(layers())  # the report counts layers, not copies
    for copy in copies:
        (ob,) = [o for o in layers() if o.data == copy.data]
        assert copy.name == ob.name + " reflected"
        for ray in ("camera", "diffuse", "glossy", "transmission", "shadow", "volume_scatter"):
            assert not getattr(copy, "visible_" + ray), ray
        if hasattr(copy, "hide_probe_volume"):
            assert copy.hide_probe_volume and not copy.hide_probe_plane
        mat = copy.material_slots[0].material
        assert copy.material_slots[0].link == "OBJECT" and mat is not ob.data.materials[0]
        assert mat.get(MARK) == "layer"
        if hasattr(mat, "surface_render_method"):
            assert mat.surface_render_method == "DITHERED"
        types = {n.type for n in mat.node_tree.nodes}
        assert {"ATTRIBUTE", "EMISSION", "BSDF_DIFFUSE", "BSDF_TRANSPARENT", "MIX_SHADER"} <= types
    # Cycles sees the layer itself in mirrors (glossy rays): no copy there
    set_engine("CYCLES")
    bpy.context.scene.lens_lights.energy_model = "CAUSTIC_LAYER"
    generate()
    assert layers() and not [o for o in lens_lights(copies=True) if o.get("lens_lights_reflection")]


def test_auto_in_cycles_keeps_the_exact_profile(empty_blend):
    basic_scene()
    set_engine("CYCLES")
    level, message, figures = generate()
    assert figures["energy_model"] == "EXACT_PROFILE" and not layers()


def checker_image(n=8):
    img = bpy.data.images.new("Checker", n, n, float_buffer=True)
    ij = np.indices((n, n)).sum(axis=0) % 2
    px = np.ones((n, n, 4), dtype=np.float32)
    px[..., :3] = ij[..., None]
    img.pixels.foreach_set(px.ravel())
    return img


def test_textured_receiver_layer_samples_the_receivers_texture(empty_blend):
    basic_scene()
    floor = bpy.data.objects["Floor"]
    mat = new_material("Checker floor")
    nt = mat.node_tree
    tex = nt.nodes.new("ShaderNodeTexImage")
    tex.image = checker_image()
    tex.interpolation = "Closest"
    nt.links.new(tex.outputs["Color"], nt.nodes["Principled BSDF"].inputs["Base Color"])
    floor.data.materials.append(mat)
    set_engine("BLENDER_EEVEE")
    generate()
    (ob,) = layers()
    lm = ob.data.materials[0]
    (tnode,) = [n for n in lm.node_tree.nodes if n.type == "TEX_IMAGE"]
    assert tnode.image == tex.image and tnode.interpolation == "Closest"
    (uvnode,) = [n for n in lm.node_tree.nodes if n.type == "UVMAP"]
    assert uvnode.uv_map in ob.data.uv_layers
    # The layer's UVs are the floor's at the same points (plane of size 8: u = x/8 + ½).
    me = ob.data
    uv = np.empty(len(me.loops) * 2)
    me.uv_layers[uvnode.uv_map].data.foreach_get("uv", uv)
    vi = np.empty(len(me.loops), dtype=np.int64)
    me.loops.foreach_get("vertex_index", vi)
    co = np.empty(len(me.vertices) * 3)
    me.vertices.foreach_get("co", co)
    xy = co.reshape(-1, 3)[vi, :2]
    assert uv.reshape(-1, 2) == pytest.approx(xy / 8.0 + 0.5, abs=1e-5)
    # The texture is what multiplies the irradiance (a white and a black square give
    # 1 : 0): the image feeds the multiply's B, the irradiance its A.
    (mix,) = [n for n in lm.node_tree.nodes if n.type == "MIX"]
    assert mix.inputs["B"].links[0].from_node == tnode
    assert mix.inputs["A"].links[0].from_node.type == "ATTRIBUTE"


#: The checker's two colours (linear RGB): the caustic on each cell is tinted by it.
LIGHT_CELL = (0.9, 0.6, 0.3)
DARK_CELL = (0.1, 0.25, 0.05)


def _render_rgb(sc, path):
    sc.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)
    img = bpy.data.images.load(str(path))
    px = np.array(img.pixels[:], dtype=float).reshape(img.size[1], img.size[0], 4)
    bpy.data.images.remove(img)
    return px[..., :3]


def test_textured_receiver_renders_the_caustic_tinted_by_the_texture_under_it(
    empty_blend, tmp_path
):
    """EEVEE, 32 px: the lamp hidden from the render, so the picture is the layer
    alone. Rendered once with a two-colour checker on the floor and once with the
    same image made white: on every pixel well inside a cell the ratio of the two is
    that cell's colour, per channel (the texture's values, read by Blender)."""
    from measuring_scene import add_top_camera, new_measuring_scene

    sc = new_measuring_scene("BLENDER_EEVEE", 32)
    sc.eevee.taa_render_samples = 4
    basic_scene()
    cells = 16  # on the floor of size 8: 0.5 m cells, 8 px each in the view below
    img = bpy.data.images.new("Checker", cells, cells, float_buffer=True)
    parity = np.indices((cells, cells)).sum(axis=0) % 2  # (row = v, column = u)
    px = np.ones((cells, cells, 4), dtype=np.float32)
    px[..., :3] = np.where(parity[..., None] == 1, LIGHT_CELL, DARK_CELL)
    img.pixels.foreach_set(px.ravel())
    mat = new_material("Checker floor")
    nt = mat.node_tree
    tex = nt.nodes.new("ShaderNodeTexImage")
    tex.image, tex.interpolation = img, "Closest"
    nt.links.new(tex.outputs["Color"], nt.nodes["Principled BSDF"].inputs["Base Color"])
    bpy.data.objects["Floor"].data.materials.append(mat)
    add_top_camera(0.0, 0.0, 6.0, 2.0)
    level, message, _ = generate()
    assert level == "INFO" and layers(), message
    bpy.data.objects["Lamp"].hide_render = True  # the layer alone
    bpy.data.objects["Marble"].visible_camera = False  # the floor, not its refraction
    tinted = _render_rgb(sc, tmp_path / "checker.exr")
    img.pixels.foreach_set(np.ones(cells * cells * 4, dtype=np.float32))
    white = _render_rgb(sc, tmp_path / "white.exr")

    # Pixel centres → floor UV (u = x/8 + ½) → the cell and the distance to its edges.
    c = (np.arange(32) + 0.5) / 32 * 2.0 - 1.0
    u = c[None, :] / 8.0 + 0.5
    v = c[:, None] / 8.0 + 0.5
    fu, fv = u * cells % 1.0, v * cells % 1.0
    edge = np.minimum(np.minimum(fu, 1 - fu), np.minimum(fv, 1 - fv))  # (32, 32)
    inside = edge > 2.5 / 8.0  # more than 2.5 px from a cell's edge (the pixel filter)
    lit = white.mean(axis=2) > 0.05 * white.mean(axis=2).max()
    light = (np.floor(u * cells) + np.floor(v * cells)) % 2 == 1
    for mask, colour in ((light, LIGHT_CELL), (~light, DARK_CELL)):
        sel = inside & lit & mask
        assert sel.sum() >= 8
        ratio = tinted[sel] / white[sel]
        assert np.median(ratio, axis=0) == pytest.approx(colour, rel=0.03)
        assert np.abs(ratio - colour).max() < 0.1


def test_glossy_receiver_gets_a_fitted_spot_for_itself(empty_blend):
    basic_scene()
    floor = bpy.data.objects["Floor"]
    mat = new_material("Mirror")
    mat.node_tree.nodes["Principled BSDF"].inputs["Metallic"].default_value = 1.0
    floor.data.materials.append(mat)
    set_engine("BLENDER_EEVEE")
    level, message, figures = generate()
    assert not layers()
    (ll,) = [o for o in lens_lights() if o.type == "LIGHT"]
    assert ll.data.type == "SPOT" and "glossy or transparent" in message
    include = ll.light_linking.receiver_collection
    assert list(include.objects) == [floor]


def test_clear_removes_the_layers_and_nothing_else(empty_blend):
    basic_scene()
    set_engine("BLENDER_EEVEE")
    before = snapshot()
    n_mesh, n_mat = len(bpy.data.meshes), len(bpy.data.materials)
    generate()
    assert layers() and len(bpy.data.materials) > n_mat
    assert bpy.ops.lens_lights.clear() == {"FINISHED"}
    assert not lens_lights()
    assert len(bpy.data.meshes) == n_mesh and len(bpy.data.materials) == n_mat
    assert not [m for m in bpy.data.materials if m.get(MARK)]
    assert not [c for c in bpy.data.collections if c.get(MARK)]
    after = snapshot()
    assert before == after, snapshot_diff(before, after)


def test_generate_with_layers_is_one_undo_step(empty_blend):
    basic_scene()
    set_engine("BLENDER_EEVEE")
    bpy.ops.ed.undo_push(message="scene")
    empty = snapshot()
    bpy.ops.lens_lights.generate("EXEC_DEFAULT", True)
    assert len(layers()) == 1
    bpy.ops.ed.undo()
    assert lens_lights() == [] and not [m for m in bpy.data.meshes if m.get(MARK)]
    assert snapshot_diff(empty, snapshot()) == []
    bpy.ops.ed.redo()
    assert len(layers()) == 1 and layers()[0].data.attributes.get("lens_irradiance")


def test_layers_of_one_topology_each_keep_their_own_values(empty_blend):
    """A layer mesh of faces made before starts as a copy of that mesh (the speed
    round): each keeps its own positions, UVs and irradiance (per vertex, what the
    renderer interpolates), the first is unchanged, and neither carries the other's
    material."""
    from lens_lights.blender.build.layers import IRRADIANCE, UV_NAME, layer_mesh
    from lens_lights.core.caustic_layer.smooth import DrawnMesh

    res = 3
    i = np.arange(res + 1, dtype=float)
    grid = np.stack(np.meshgrid(i, i, indexing="xy"), axis=-1).reshape(-1, 2)
    a = (np.arange(res)[:, None] * (res + 1) + np.arange(res)[None, :]).reshape(-1)
    tris = np.concatenate(
        [np.stack([a, a + 1, a + res + 2], 1), np.stack([a, a + res + 2, a + res + 1], 1)]
    )

    def drawn(k):
        z = np.full((len(grid), 1), 0.1 * k)
        return DrawnMesh(
            vertices=np.hstack([grid + 10 * k, z]), triangles=tris,
            uvs=grid / res + 0.25 * k,
            irradiance=np.outer(np.arange(len(grid)) + k, [1.0, 2.0, 3.0]),
        )  # fmt: skip

    shapes: dict = {}
    first = layer_mesh("first", drawn(0), shapes)
    first.materials.append(bpy.data.materials.new("m"))
    second = layer_mesh("second", drawn(1), shapes)
    assert second.name == "second" and len(second.materials) == 0
    for me, k in ((first, 0), (second, 1)):
        d = drawn(k)
        co = np.empty(3 * len(me.vertices))
        me.vertices.foreach_get("co", co)
        np.testing.assert_allclose(co.reshape(-1, 3), d.vertices, atol=1e-6)
        uv = np.empty(2 * len(me.loops))
        me.uv_layers[UV_NAME].data.foreach_get("uv", uv)
        np.testing.assert_allclose(uv.reshape(-1, 2), d.uvs[tris].reshape(-1, 2), atol=1e-6)
        attr = me.attributes[IRRADIANCE]
        assert attr.domain == "POINT"
        rgba = np.empty(4 * len(me.vertices))
        attr.data.foreach_get("color", rgba)
        np.testing.assert_allclose(rgba.reshape(-1, 4)[:, :3], d.irradiance, rtol=1e-6)
        loops = np.empty(len(me.loops), dtype=np.int32)
        me.loops.foreach_get("vertex_index", loops)
        np.testing.assert_array_equal(loops.reshape(-1, 3), tris)


def test_a_drawn_layers_edges_are_the_ones_blender_finds(empty_blend):
    """The drawn mesh's edges written with its faces (`smooth.grid_edges`, so that
    `mesh.update()` need not hash ~380 000 corner pairs) are the edges Blender finds
    itself for the same faces, and the mesh is valid as built (`validate` changes
    nothing)."""
    from lens_lights.blender.build.layers import layer_mesh
    from lens_lights.core.caustic_layer.smooth import DrawnMesh, grid_edges, grid_triangles

    n = 6
    tris, _ = grid_triangles(n)
    v = n * n + (n - 1) ** 2
    rng = np.random.default_rng(2)
    verts, uvs, irr = rng.random((v, 3)), rng.random((v, 2)), rng.random((v, 3))
    ours = layer_mesh("ours", DrawnMesh(verts, tris, uvs, irr, *grid_edges(n)))
    found = layer_mesh("found", DrawnMesh(verts, tris, uvs, irr))

    def edge_set(me):
        e = np.empty(2 * len(me.edges), dtype=np.int32)
        me.edges.foreach_get("vertices", e)
        return {tuple(sorted(p)) for p in e.reshape(-1, 2).tolist()}

    assert len(ours.edges) == len(found.edges) == 4 * (n - 1) ** 2 + 2 * n * (n - 1)
    assert edge_set(ours) == edge_set(found)
    # each corner's edge joins it to its triangle's next corner
    ce = np.empty(len(ours.loops), dtype=np.int32)
    ours.loops.foreach_get("edge_index", ce)
    e = np.empty(2 * len(ours.edges), dtype=np.int32)
    ours.edges.foreach_get("vertices", e)
    want = np.sort(np.stack([tris.ravel(), np.roll(tris, -1, axis=1).ravel()], 1), axis=1)
    np.testing.assert_array_equal(np.sort(e.reshape(-1, 2)[ce], axis=1), want)
    assert not ours.validate(verbose=False)
