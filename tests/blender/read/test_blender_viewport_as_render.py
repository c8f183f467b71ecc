"""Generate reads the viewport depsgraph instead of probing a render when nothing
in the file renders differently (`render_probe.as_rendered`, `viewport_differs`):
a plain scene takes that path and reads what the probe's render depsgraph reads;
every scene where viewport and render differ is still read as rendered (probe)."""

import bpy
import numpy as np
import pytest
from blender_scene_helpers import (
    add_point_light,
    add_sphere,
    collection_instance,
    collection_of,
    generate,
    glass_material,
    gn_instances,
    lens_lights,
)

pytestmark = [pytest.mark.blender, pytest.mark.usefixtures("auto_builds_lights")]


def probe():
    from lens_lights.blender.read import render_probe

    return render_probe


def read():
    from lens_lights.blender.read.scene import read_blender_scene

    return read_blender_scene(bpy.context)


def read_probed():
    """The render depsgraph's read, always through the probe render."""
    from lens_lights.blender.read.scene import read_depsgraph

    read, how = probe().rendered_depsgraph(
        bpy.context, lambda dg: read_depsgraph(dg, bpy.context.scene)
    )
    assert how == "render"
    read.occluders.release()
    return read


def spheres(r) -> dict:
    """name → (centre rounded to 1e-4, radius rounded to 1e-3)."""
    return {
        name: (tuple(np.round(c, 4)), round(float(rad), 3))
        for name, c, rad in zip(r.sphere_sources, r.arrays.center, r.arrays.radius, strict=True)
    }


def plain_scene():
    glass = glass_material()
    add_sphere("Ball", (0.0, 0.0, 1.0), radius=0.5, material=glass)
    bead = add_sphere("Bead", (0.0, 0.0, 0.0), radius=0.25, material=glass)
    beads = collection_of("Beads", bead)
    collection_instance("Beads.A", beads, location=(2.0, 0.0, 1.0))
    collection_instance("Beads.B", beads, location=(-2.0, 0.0, 1.0))
    add_point_light("Lamp", (0.0, 0.0, 8.0))


def test_plain_scene_reads_the_viewport_as_the_render(empty_blend):
    plain_scene()
    assert probe().viewport_differs(bpy.context) is None
    r = read()
    assert r.how == probe().VIEWPORT_AS_RENDER
    # the placed spheres (UV spheres: the fit's radius within the facets' 0.5 %)
    got = spheres(r)
    assert sorted(got) == ["Ball", "Beads.A/Bead", "Beads.B/Bead"]
    assert got["Ball"][0] == (0.0, 0.0, 1.0) and got["Beads.A/Bead"][0] == (2.0, 0.0, 1.0)
    assert got["Beads.B/Bead"][0] == (-2.0, 0.0, 1.0)
    np.testing.assert_allclose([got[k][1] for k in sorted(got)], [0.5, 0.25, 0.25], rtol=5e-3)
    assert spheres(read_probed()) == got and r.light_sources == ["Lamp"]


def test_generate_takes_the_fast_path_and_builds_what_the_probe_builds(empty_blend, monkeypatch):
    plain_scene()
    level, message, figures = generate()
    assert level == "INFO", message
    assert figures["how"] == probe().VIEWPORT_AS_RENDER
    assert "scene read as" not in message
    fast = [
        (o.name, round(o.data.energy, 6), tuple(np.round(o.location, 6))) for o in lens_lights()
    ]
    assert len(fast) == 3
    monkeypatch.setattr(probe(), "viewport_differs", lambda context: "forced")
    level, message, figures = generate()
    assert figures["how"] == "render"
    probed = [
        (o.name, round(o.data.energy, 6), tuple(np.round(o.location, 6))) for o in lens_lights()
    ]
    assert probed == fast


def test_instances_of_a_hidden_source_are_read_as_rendered(empty_blend):
    """A source object hidden in both the viewport and the render, instanced by
    geometry nodes: both depsgraphs show the instances (no rule applied by hand)."""
    src = add_sphere("Source", (0.0, 0.0, -30.0), radius=0.3, material=glass_material())
    src.hide_viewport = src.hide_render = True
    gn_instances("Beads", [(0, 0, 0), (2, 0, 0)], instance_object=src, location=(0, 0, 1))
    add_point_light("Lamp", (0.0, 0.0, 8.0))
    assert probe().viewport_differs(bpy.context) is None
    r = read()
    assert r.how == probe().VIEWPORT_AS_RENDER
    assert sorted(spheres(r)) == ["Beads/Source", "Beads/Source#1"]
    assert spheres(r) == spheres(read_probed())


def _render_only_hidden():
    ob = bpy.data.objects["Ball"]
    ob.hide_render = True
    return dict(absent=["Ball"])


def _viewport_only_hidden():
    bpy.data.objects["Ball"].hide_viewport = True
    return dict(present=["Ball"])


def _eye_hidden():
    bpy.data.objects["Ball"].hide_set(True)
    return dict(present=["Ball"])


def _collection_render_off():
    coll = bpy.data.collections.new("Render off")
    bpy.context.scene.collection.children.link(coll)
    extra = add_sphere("Extra", (4.0, 0.0, 1.0), radius=0.5, material=bpy.data.materials[0])
    for c in list(extra.users_collection):
        c.objects.unlink(extra)
    coll.objects.link(extra)
    coll.hide_render = True
    return dict(absent=["Extra"])


def _instanced_object_render_off():
    bpy.data.objects["Bead"].hide_render = True
    return dict(absent=["Beads.A/Bead", "Beads.B/Bead"])


def _modifier_render_only():
    # A Cast to a cuboid only in the render: the ball is no sphere there.
    m = bpy.data.objects["Ball"].modifiers.new("Cast", "CAST")
    m.cast_type, m.factor = "CUBOID", 1.0
    m.show_viewport = False
    return dict(absent=["Ball"])


def _simplify():
    bpy.context.scene.render.use_simplify = True
    return dict(present=["Ball"])


@pytest.mark.parametrize(
    "change",
    [
        _render_only_hidden,
        _viewport_only_hidden,
        _eye_hidden,
        _collection_render_off,
        _instanced_object_render_off,
        _modifier_render_only,
        _simplify,
    ],
    ids=lambda f: f.__name__.strip("_"),
)
def test_any_difference_keeps_the_probe(empty_blend, change):
    plain_scene()
    expect = change()
    assert probe().viewport_differs(bpy.context) is not None
    r = read()
    assert r.how == "render"
    names = set(r.sphere_sources)
    assert not names & set(expect.get("absent", [])), names
    assert names >= set(expect.get("present", [])), names


def _coarse_ball():
    """A 12 × 6 UV sphere (radius 1): a sphere as it is, none once subdivided (the
    poles: 3 % off)."""
    return add_sphere(
        "Coarse", (0.0, 0.0, 3.0), radius=1.0, material=glass_material(), segments=12, rings=6
    )


def test_subdivision_render_levels_are_read_as_rendered(empty_blend):
    ob = _coarse_ball()
    add_point_light("Lamp", (0.0, 0.0, 9.0))
    sub = ob.modifiers.new("Subdivision", "SUBSURF")
    sub.levels, sub.render_levels = 0, 2
    system = bpy.context.preferences.system
    gpu_before = system.use_gpu_subdivision
    try:
        system.use_gpu_subdivision = False
        why = probe().viewport_differs(bpy.context)
        assert why == "Coarse: modifier Subdivision (subsurf)"
        probed = read()
        # as rendered: subdivided, no sphere (the viewport's level 0 is one)
        assert probed.how == "render" and probed.sphere_sources == []
        # (its poles ~3 % in: no sphere, but closed glass: a mesh lens, issue 25)
        assert [m.name for m in probed.mesh_lenses] == ["Coarse"]
        rendered = probed.mesh_lenses[0].n_triangles
        # Independently: the viewport at the render's level (nothing differs then) ...
        sub.levels = 2
        assert probe().viewport_differs(bpy.context) is None
        viewport = read()
        assert viewport.how == probe().VIEWPORT_AS_RENDER
        assert viewport.left_out == probed.left_out and viewport.sphere_sources == []
        assert [m.n_triangles for m in viewport.mesh_lenses] == [rendered]
        # ... unless the viewport may leave the last Subdivision to the GPU
        system.use_gpu_subdivision = True
        assert probe().viewport_differs(bpy.context) == why
    finally:
        system.use_gpu_subdivision = gpu_before
    # the level 0 of both: a sphere of radius 1
    sub.levels = sub.render_levels = 0
    level0 = read()
    assert spheres(level0) == {"Coarse": ((0.0, 0.0, 3.0), 1.0)} and not level0.mesh_lenses
    # level 2 makes 16 quads (32 triangles) of a quad (2 triangles), 12 of a triangle
    n0 = sum(len(p.vertices) - 2 for p in ob.data.polygons)  # level 0's triangles
    assert 16 * n0 <= rendered <= 24 * n0


def _is_viewport_tree(radius_viewport, radius_render, material):
    tree = bpy.data.node_groups.new("Ball by mode", "GeometryNodeTree")
    tree.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    tree.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    nodes, links = tree.nodes, tree.links
    out = nodes.new("NodeGroupOutput")
    switch = nodes.new("GeometryNodeSwitch")
    switch.input_type = "GEOMETRY"
    links.new(nodes.new("GeometryNodeIsViewport").outputs[0], switch.inputs["Switch"])
    for key, radius in (("True", radius_viewport), ("False", radius_render)):
        uv = nodes.new("GeometryNodeMeshUVSphere")
        uv.inputs["Radius"].default_value = radius
        setm = nodes.new("GeometryNodeSetMaterial")
        setm.inputs["Material"].default_value = material
        links.new(uv.outputs["Mesh"], setm.inputs["Geometry"])
        links.new(setm.outputs["Geometry"], switch.inputs[key])
    links.new(switch.outputs[0], out.inputs[0])
    return tree


def test_geometry_nodes_is_viewport_is_read_as_rendered(empty_blend):
    """Is Viewport → a sphere of radius 0.3 in the viewport, 0.7 in the render,
    also when the switch sits in a nested group."""
    glass = glass_material()
    inner = _is_viewport_tree(0.3, 0.7, glass)
    outer = bpy.data.node_groups.new("Outer", "GeometryNodeTree")
    outer.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    outer.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    group = outer.nodes.new("GeometryNodeGroup")
    group.node_tree = inner
    outer.links.new(group.outputs[0], outer.nodes.new("NodeGroupOutput").inputs[0])
    mesh = bpy.data.meshes.new("Host")
    host = bpy.data.objects.new("Host", mesh)
    bpy.context.scene.collection.objects.link(host)
    host.location = (0.0, 0.0, 2.0)
    host.modifiers.new("Ball", "NODES").node_group = outer
    add_point_light("Lamp", (0.0, 0.0, 9.0))
    why = probe().viewport_differs(bpy.context)
    assert why is not None and "Ball" in why
    r = read()
    assert r.how == "render"
    (name, (center, radius)), *_ = spheres(r).items()
    assert name == "Host" and center == (0.0, 0.0, 2.0)
    assert radius == pytest.approx(0.7, rel=5e-3)


def test_a_failing_check_or_a_render_under_way_keeps_the_probe_path(empty_blend, monkeypatch):
    plain_scene()

    def broken(context):
        raise AttributeError("a property this Blender lacks")

    with monkeypatch.context() as m:
        m.setattr(probe(), "viewport_differs", broken)
        assert read().how == "render"  # the probe rendered
    # A render of the user's under way: the probe's fallback, which says so.
    monkeypatch.setattr(probe(), "_RENDERS_RUNNING", 1)
    assert read().how == "viewport (a render is in progress)"
