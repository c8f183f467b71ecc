"""One Exact-profile node tree (`lights.build_profile_nodes`) for Generate,
live update and the bake: a baked profile light and the light Generate makes on the
same frame give the same emission toward the same directions, far field and near
field (a marble resting on a table, then the table lowered: the baked near field
reads each frame's own table, its row on the frame's receiver). The trees are
evaluated node by node in numpy (the image texture as Blender reads it: texels at
(i + ½)/K, bilinear, EXTEND), from the images' pixels; the lens' D/R sits on the
bake's slice grid (1.04^k) on each frame, so the baked slices are Generate's
tables; with tilted receivers (a table and a wall beside the marble) the baked
tree's tilt, read from the slices' green channel and keyed per plane, is Generate's
at shading points on each plane. And live update keeps a non-full source's shadow
mask when it rebuilds a profile light's tree."""

import math

import bpy
import numpy as np
import pytest
from blender_scene_helpers import (
    add_point_light,
    add_sphere,
    glass_material,
    lens_lights,
    set_engine,
)

pytestmark = pytest.mark.blender

R = 0.5


def _texture(pixels, x, y):
    """Blender's Linear, EXTEND image texture at (x, y) of `pixels` (H, W, C)."""
    H, W = pixels.shape[:2]

    def corners(c, n):
        t = float(c) * n - 0.5
        i = math.floor(t)
        return min(max(i, 0), n - 1), min(max(i + 1, 0), n - 1), t - i

    i0, i1, s = corners(x, W)
    j0, j1, t = corners(y, H)
    row0 = (1 - s) * pixels[j0, i0] + s * pixels[j0, i1]
    row1 = (1 - s) * pixels[j1, i0] + s * pixels[j1, i1]
    return (1 - t) * row0 + t * row1


_MATH = {
    "ADD": lambda a, b, c: a + b,
    "SUBTRACT": lambda a, b, c: a - b,
    "MULTIPLY": lambda a, b, c: a * b,
    "MULTIPLY_ADD": lambda a, b, c: a * b + c,
    "DIVIDE": lambda a, b, c: a / b if b != 0.0 else 0.0,
    "MAXIMUM": lambda a, b, c: max(a, b),
    "MINIMUM": lambda a, b, c: min(a, b),
    "SQRT": lambda a, b, c: math.sqrt(a) if a > 0.0 else 0.0,
    "FLOOR": lambda a, b, c: float(math.floor(a)),
    "ARCTAN2": lambda a, b, c: math.atan2(a, b),
    "LOGARITHM": lambda a, b, c: math.log(a) / math.log(b) if a > 0.0 and b > 0.0 else 0.0,
    "ABSOLUTE": lambda a, b, c: abs(a),
    "LESS_THAN": lambda a, b, c: 1.0 if a < b else 0.0,
}


def emission(nt, omega, ray_length):
    """The light tree `nt`'s emission strength toward `omega` (the Texture
    Coordinate's Normal) at the ray length `ray_length`."""
    pixels: dict = {}

    def image_pixels(img):
        if img.name not in pixels:
            w, h = img.size
            px = np.empty(w * h * 4, dtype=np.float32)
            img.pixels.foreach_get(px)
            pixels[img.name] = px.reshape(h, w, 4).astype(float)
        return pixels[img.name]

    def value_in(socket):
        if socket.is_linked:
            link = socket.links[0]
            return out(link.from_node, link.from_socket.name)
        v = socket.default_value
        return tuple(v) if hasattr(v, "__len__") else float(v)

    def out(node, name):
        kind = node.bl_idname
        if kind == "ShaderNodeTexCoord":
            assert name == "Normal", name
            return tuple(omega)
        if kind == "ShaderNodeLightPath":
            assert name == "Ray Length", name
            return float(ray_length)
        if kind == "ShaderNodeValue":
            return float(node.outputs[0].default_value)
        if kind == "ShaderNodeSeparateXYZ":
            return value_in(node.inputs[0])["XYZ".index(name)]
        if kind == "ShaderNodeCombineXYZ":
            return tuple(value_in(node.inputs[k]) for k in "XYZ")
        if kind == "ShaderNodeSeparateColor":
            assert node.mode == "RGB"
            return value_in(node.inputs[0])[("Red", "Green", "Blue").index(name)]
        if kind == "ShaderNodeTexImage":
            assert (node.interpolation, node.extension) == ("Linear", "EXTEND")
            x, y = value_in(node.inputs["Vector"])[:2]
            return tuple(_texture(image_pixels(node.image), x, y)[:3])
        if kind == "ShaderNodeMath":
            # a colour into a number: its grey (the masks are grey: r = g = b)
            a, b, c = (value_in(node.inputs[k]) for k in range(3))
            a, b, c = (sum(x) / len(x) if isinstance(x, tuple) else x for x in (a, b, c))
            return float(_MATH[node.operation](a, b, c))
        raise AssertionError(f"node {kind} not evaluated by this test")

    em = next(n for n in nt.nodes if n.bl_idname == "ShaderNodeEmission")
    return value_in(em.inputs["Strength"])


#: Emission directions (γ, φ) and distances along the axis h (in R): the axis
#: (0.001°: the 32-bit acos used to read it far out), the caustic's core and ring.
PROBES = [(0.001, 0.0, 3.0), (0.3, 1.0, 3.0), (2.0, 2.0, 5.0), (6.0, 0.5, 8.0), (15.0, 4.0, 2.0)]


def _probe(ob):
    """{probe: energy × emission} of the light object `ob` (the intensity over 1/(4π))."""
    out = []
    for g, phi, h in PROBES:
        gr = math.radians(g)
        omega = (math.sin(gr) * math.cos(phi), math.sin(gr) * math.sin(phi), -math.cos(gr))
        out.append(ob.data.energy * emission(ob.data.node_tree, omega, h * R / math.cos(gr)))
    return np.array(out)


def _generated_on(frame):
    from lens_lights.blender.commands.generate import generate

    bpy.context.scene.frame_set(frame)
    generate(bpy.context)
    (ob,) = [o for o in lens_lights() if o.data.node_tree is not None]
    got = (_probe(ob), tuple(ob.location))
    assert bpy.ops.lens_lights.clear() == {"FINISHED"}
    return got


def _lamp_keys(lamp, z0, ks):
    """Key the lamp straight above the lens (centre height `z0`) at D/R = 1.04^k on
    frame 1, 2, …: the bake's slice grid nodes."""
    bpy.context.preferences.edit.keyframe_new_interpolation_type = "LINEAR"
    for f, k in enumerate(ks, start=1):
        lamp.location = (0.0, 0.0, z0 + R * 1.04**k)
        lamp.keyframe_insert("location", frame=f)


def _bake_agrees_with_generate(ks):
    sc = bpy.context.scene
    sc.frame_start, sc.frame_end = 1, len(ks)
    expected = {f: _generated_on(f) for f in range(1, len(ks) + 1)}
    assert bpy.ops.lens_lights.bake() == {"FINISHED"}
    (baked,) = lens_lights()
    nodes = baked.data.node_tree.nodes
    assert "Lens bake slice" in nodes  # Generate's tree in its slices mode
    for f, (want, location) in expected.items():
        sc.frame_set(f)
        assert tuple(baked.location) == pytest.approx(location, abs=1e-6)
        got = _probe(baked)
        assert np.all(want > 0.0)
        np.testing.assert_allclose(got, want, rtol=2e-3, err_msg=f"frame {f}")
    return baked


def test_baked_profile_tree_agrees_with_generate_far_field(empty_blend):
    sc = bpy.context.scene
    set_engine("CYCLES")
    sc.lens_lights.energy_model = "EXACT_PROFILE"
    add_sphere("Marble", (0.0, 0.0, 1.0), radius=R, material=glass_material())
    bpy.ops.mesh.primitive_plane_add(size=20)  # 2 R below the centre: the far field
    lamp = add_point_light("Lamp", (0.0, 0.0, 4.0))
    _lamp_keys(lamp, 1.0, [45.0, 46.0, 47.0])
    baked = _bake_agrees_with_generate([45.0, 46.0, 47.0])
    (img,) = [i for i in bpy.data.images if i.name.startswith("Lens profile")]
    assert " near " not in img.name and baked.location.z < 1.0 - R  # past the back pole


def test_baked_near_field_tree_agrees_with_generate(empty_blend):
    """A marble resting on the table (receiver 1 R from the centre): the baked slices
    carry the row on the receiver, as Generate's table (before: the receiver-less
    near table, a dark disc at the caustic's centre)."""
    sc = bpy.context.scene
    set_engine("CYCLES")
    sc.lens_lights.energy_model = "EXACT_PROFILE"
    add_sphere("Marble", (0.0, 0.0, R), radius=R, material=glass_material())
    bpy.ops.mesh.primitive_plane_add(size=20)
    floor = bpy.context.object
    lamp = add_point_light("Lamp", (0.0, 0.0, 4.0))
    _lamp_keys(lamp, R, [60.0, 61.0, 62.0])
    # the table resting, then 2 % of R lower on frame 3 (still the near field): the
    # near field's rows lie on each frame's receiver
    bpy.context.preferences.edit.keyframe_new_interpolation_type = "CONSTANT"
    for f, z in ((1, 0.0), (2, 0.0), (3, -0.02 * R)):
        floor.location.z = z
        floor.keyframe_insert("location", index=2, frame=f)
    baked = _bake_agrees_with_generate([60.0, 61.0, 62.0])
    (img,) = [i for i in bpy.data.images if i.name.startswith("Lens profile")]
    # each frame its own table (Generate's), its rows on its receiver, 1 R and 1.02 R
    from lens_lights.blender.build.marks import PROFILE_KEY

    key = img[PROFILE_KEY]  # (the name is cut at 63 characters before Blender 5)
    tables = key.split(": ", 1)[1].split("; ")
    assert len(tables) == 3
    assert [t.split(" near ")[1] for t in tables] == ["1", "1", "1.02"]
    assert tuple(baked.location) == pytest.approx((0.0, 0.0, R), abs=1e-6)  # the centre


def test_live_update_keeps_the_shadow_mask_of_a_non_full_source(empty_blend):
    """An opaque ball shading one side of the lens (the scene of
    tests/blender/build/test_blockers_render.py): the profile light ends with a mask (a second
    image texture); a live update that rebuilds its tree (the lamp moved: another
    D/R, another table) keeps it; with the blocker gone it goes."""
    from lens_lights.blender.commands import live_update

    sc = bpy.context.scene
    set_engine("CYCLES")
    sc.lens_lights.energy_model = "EXACT_PROFILE"
    add_sphere("Lens", (0.0, 0.0, 1.5), radius=R, material=glass_material())
    blocker = add_sphere("Blocker", (0.158, 0.0, 3.0), radius=0.12)  # no material: opaque
    bpy.ops.mesh.primitive_plane_add(size=20)
    lamp = add_point_light("Lamp", (0.0, 0.0, 4.5))

    def masks(ob):
        return [
            n.image.name
            for n in ob.data.node_tree.nodes
            if n.bl_idname == "ShaderNodeTexImage" and n.image.name.startswith("Lens mask ")
        ]

    def lens_light():
        (ob,) = [
            o
            for o in lens_lights()
            if o.lens_lights.source_light == "Lamp" and o.lens_lights.source_lens == "Lens"
        ]
        return ob

    dg = bpy.context.evaluated_depsgraph_get()
    live_update.update(sc, dg, force=True)
    first = lens_light()
    assert not first.lens_lights.full and len(masks(first)) == 1
    lamp.location = (0.0, 0.0, 4.8)  # another D/R: the tree is rebuilt
    sig = first.data.get("lens_lights_profile_values")  # the table's key, distances
    live_update.update(sc, bpy.context.evaluated_depsgraph_get(), force=True)
    ob = lens_light()
    assert ob == first  # updated in place
    assert ob.data.get("lens_lights_profile_values") != sig
    assert not ob.lens_lights.full and len(masks(ob)) == 1
    # the previous mask removed once unused
    assert all(i.users > 0 for i in bpy.data.images if i.name.startswith("Lens mask "))
    blocker.location = (10.0, 10.0, 3.0)  # out of the way: a full source, no mask
    live_update.update(sc, bpy.context.evaluated_depsgraph_get(), force=True)
    ob = lens_light()
    assert ob.lens_lights.full and masks(ob) == []


def test_a_tiled_slice_image_reads_the_keyed_slice(empty_blend):
    """The bake's slices laid out as tiles (`frame_tables.SliceLayout`, two columns):
    slice k holds the constant k + 1, so the tree's emission at slice coordinate s is
    the blend of slices ⌊s⌋ and ⌊s⌋ + 1 (the last slice read whole)."""
    from lens_lights.blender.build import lights
    from lens_lights.core.animation.frame_tables import SliceLayout, tile_slices

    layout = SliceLayout(count=3, rows=4, width=8, columns=2)
    px = tile_slices([np.full((4, 8), k + 1.0) for k in range(3)], layout)  # (8, 16)
    img = bpy.data.images.new("tiles", 16, 8, float_buffer=True, alpha=False)
    img.colorspace_settings.name = "Non-Color"
    rgba = np.ones((8, 16, 4), dtype=np.float32)
    rgba[..., :3] = px[..., None]
    img.pixels.foreach_set(rgba.ravel())
    data = bpy.data.lights.new("tiled", "SPOT")
    profile = dict(gamma_max_deg=90.0, h_min=0.1, h_max=10.0, strength_scale=1.0)
    nt = lights.build_profile_nodes(data, profile, img, slices=layout)
    omega = (math.sin(0.3), 0.0, -math.cos(0.3))
    for s, want in ((0.0, 1.0), (1.0, 2.0), (2.0, 3.0), (0.5, 1.5), (1.25, 2.25)):
        nt.nodes[lights.SLICE_NODE].outputs[0].default_value = s
        # far out along the table (v clamped to the tile's last row) and near (first)
        for h in (0.01, 1.0, 100.0):
            assert emission(nt, omega, h) == pytest.approx(want, rel=1e-6), (s, h)


def test_baked_shadow_mask_agrees_with_generate(empty_blend):
    """An opaque ball shading one side of the lens (the scene of
    tests/blender/build/test_blockers_render.py), the lamp moving: the baked tree
    multiplies by the frame's own mask (a tile of the bake's mask image at the keyed
    slice, its keyed scale) and so emits what Generate's does on every frame."""
    sc = bpy.context.scene
    set_engine("CYCLES")
    sc.lens_lights.energy_model = "EXACT_PROFILE"
    add_sphere("Lens", (0.0, 0.0, 1.5), radius=R, material=glass_material())
    add_sphere("Blocker", (0.158, 0.0, 3.0), radius=0.12)  # no material: opaque
    bpy.ops.mesh.primitive_plane_add(size=20)
    lamp = add_point_light("Lamp", (0.0, 0.0, 4.5))
    _lamp_keys(lamp, 1.5, [45.0, 46.0, 47.0])
    baked = _bake_agrees_with_generate([45.0, 46.0, 47.0])
    nodes = baked.data.node_tree.nodes
    (mask,) = [n for n in nodes if n.bl_idname == "ShaderNodeTexImage" and "mask" in n.image.name]
    assert mask.image.size[1] == 3 * mask.image.size[0]  # one 128² tile per frame


def _world_emission(ob, point):
    """energy × emission of the light object `ob` toward the world `point` (the
    Normal coordinate: the direction in the light's frame; Ray Length: the distance)."""
    bpy.context.view_layer.update()  # matrix_world from the rotation the builder set
    loc = np.array(ob.matrix_world.translation)
    rot = np.array(ob.matrix_world.to_3x3().normalized())
    d = np.asarray(point, dtype=float) - loc
    dist = float(np.linalg.norm(d))
    return ob.data.energy * emission(ob.data.node_tree, rot.T @ (d / dist), dist)


def test_baked_tilt_of_two_receiver_planes_agrees_with_generate(empty_blend):
    """A marble resting on a table lit from 44°–46° elevation (the near field, the
    table tilted against the axis), and on frames 2–3 a wall 1.05 R from its centre
    across the beam (frame 1: far away). Generate's tree has one plane on frame 1 and
    two on frames 2–3 (`lights._tilted`, each applied where the shading point lies
    on it); the baked tree has two, the second keyed `lights.NO_PLANE` on frame 1.
    At points on the table and on the wall, where the tilt changes the emission by
    tens of per cent, the baked tree emits what Generate's does on every frame."""
    from lens_lights.blender.build import lights

    sc = bpy.context.scene
    set_engine("CYCLES")
    sc.lens_lights.energy_model = "EXACT_PROFILE"
    add_sphere("Marble", (0.0, 0.0, R), radius=R, material=glass_material())
    bpy.ops.mesh.primitive_plane_add(size=20)
    xw = 1.05 * R
    bpy.ops.mesh.primitive_plane_add(size=4, location=(xw, 0.0, 1.0), rotation=(0, math.pi / 2, 0))
    wall = bpy.context.object
    lamp = add_point_light("Lamp", (0.0, 0.0, 4.0))
    bpy.context.preferences.edit.keyframe_new_interpolation_type = "CONSTANT"
    for f, e, x in ((1, 44.0, 20.0), (2, 45.0, xw), (3, 46.0, xw)):
        er = math.radians(e)
        lamp.location = (-8 * R * math.cos(er), 0.0, R + 8 * R * math.sin(er))
        lamp.keyframe_insert("location", frame=f)
        wall.location.x = x
        wall.keyframe_insert("location", index=0, frame=f)
    sc.frame_start, sc.frame_end = 1, 3
    on_table = [(x, y, 0.0) for x in (0.34, 0.43, 0.5) for y in (-0.06, 0.0, 0.05)]
    on_wall = [(xw, y, z) for z in (0.03, 0.1, 0.18) for y in (-0.05, 0.0, 0.06)]
    points = on_table + on_wall
    expected, planes = {}, {}
    for f in (1, 2, 3):
        from lens_lights.blender.commands.generate import generate

        sc.frame_set(f)
        generate(bpy.context)
        (ob,) = [o for o in lens_lights() if o.data.node_tree is not None]
        assert "near field" in ob.lens_lights.note
        nodes = ob.data.node_tree.nodes
        planes[f] = sum(lights.TILT_NODE.format(k, "nx") in nodes for k in range(3))
        expected[f] = np.array([_world_emission(ob, p) for p in points])
        # the tilt matters here: the same tree without it (its planes never matching)
        for k in range(planes[f]):
            nodes[lights.TILT_NODE.format(k, "offset")].outputs[0].default_value = 1e30
        untilted = np.array([_world_emission(ob, p) for p in points])
        assert np.max(np.abs(untilted / expected[f] - 1.0)) > 0.1, f
        assert bpy.ops.lens_lights.clear() == {"FINISHED"}
    assert planes == {1: 1, 2: 2, 3: 2}
    assert bpy.ops.lens_lights.bake() == {"FINISHED"}
    (baked,) = lens_lights()
    nodes = baked.data.node_tree.nodes
    assert "Lens bake slice" in nodes and lights.TILT_NODE.format(1, "nx") in nodes
    assert lights.TILT_NODE.format(2, "nx") not in nodes
    for f in (1, 2, 3):
        sc.frame_set(f)
        offset = nodes[lights.TILT_NODE.format(1, "offset")].outputs[0].default_value
        assert (offset > 1e29) == (f == 1)  # (a float32 of NO_PLANE's 1e30)
        got = np.array([_world_emission(baked, p) for p in points])
        assert np.all(expected[f] > 0.0)
        np.testing.assert_allclose(got, expected[f], rtol=2e-3, err_msg=f"frame {f}")
