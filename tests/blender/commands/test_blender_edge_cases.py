"""Hard cases and bad input on the Blender side (bpy module, no images): the scene
as the renderer sees it, transforms, instancing, linked libraries, several scenes,
lights inside glass, overlapping spheres, many lights, failures, undo, and that
generate / regenerate / clear never change anything of the user's."""

import math
from types import SimpleNamespace

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
    node_material,
    snapshot,
    snapshot_diff,
)

# The light pipeline: AUTO builds lights here (the Caustic layer: test_blender_layer.py).
pytestmark = [pytest.mark.blender, pytest.mark.usefixtures("auto_builds_lights")]


def read():
    from lens_lights.blender.read.scene import read_blender_scene

    return read_blender_scene(bpy.context)


def add_camera():
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    bpy.context.scene.collection.objects.link(cam)
    cam.location = (0.0, -10.0, 5.0)
    cam.rotation_euler = (math.radians(65), 0.0, 0.0)
    bpy.context.scene.camera = cam
    return cam


def floor():
    bpy.ops.mesh.primitive_plane_add(size=30)
    bpy.context.object.name = "Floor"
    return bpy.context.object


def lit_row(names, glass, z=1.0):
    """Glass spheres R 0.5 in a row (x = 0, 2, 4 …) under a lamp at z = 6."""
    return [add_sphere(n, (2.0 * k, 0.0, z), material=glass) for k, n in enumerate(names)]


# --------------------------------------------------------------------------- visibility


def test_reads_the_scene_as_the_renderer_sees_it(empty_blend):
    """Render visibility, not the viewport's: objects and collections disabled in
    the viewport (monitor) or hidden (eye) count, those disabled for rendering
    (camera) do not; modifiers count with their render settings."""
    glass = glass_material()
    floor()
    add_point_light("Lamp", (4.0, 0.0, 6.0))
    names = [
        "Plain",
        "Viewport off",
        "Eye hidden",
        "Render off",
        "In viewport-off coll",
        "In render-off coll",
        "In excluded coll",
        "In eye-hidden coll",
        "Cuboid in render",
        "Cuboid in viewport",
    ]
    s = {n: ob for n, ob in zip(names, lit_row(names, glass), strict=False)}
    s["Viewport off"].hide_viewport = True
    s["Eye hidden"].hide_set(True)
    s["Render off"].hide_render = True
    layers = bpy.context.view_layer.layer_collection
    for n, setup in (
        ("In viewport-off coll", lambda c, lc: setattr(c, "hide_viewport", True)),
        ("In render-off coll", lambda c, lc: setattr(c, "hide_render", True)),
        ("In excluded coll", lambda c, lc: setattr(lc, "exclude", True)),
        ("In eye-hidden coll", lambda c, lc: setattr(lc, "hide_viewport", True)),
    ):
        coll = collection_of(n, s[n])
        bpy.context.scene.collection.children.link(coll)
        setup(coll, layers.children[coll.name])
    # A Cast modifier turns the sphere into a box only in the render / only in the viewport.
    for n, render in (("Cuboid in render", True), ("Cuboid in viewport", False)):
        m = s[n].modifiers.new("Cast", "CAST")
        m.cast_type, m.factor = "CUBOID", 1.0
        m.show_render, m.show_viewport = render, not render
    hidden_lamp = add_point_light("Viewport-off lamp", (0.0, 3.0, 6.0))
    hidden_lamp.hide_viewport = True
    add_point_light("Render-off lamp", (0.0, -3.0, 6.0)).hide_render = True

    r = read()
    assert r.how == "render"
    assert sorted(r.sphere_sources) == sorted(
        [
            "Plain",
            "Viewport off",
            "Eye hidden",
            "In viewport-off coll",
            "In eye-hidden coll",
            "Cuboid in viewport",
        ]
    )
    assert sorted(r.light_sources) == ["Lamp", "Viewport-off lamp"]
    left = dict(r.left_out)
    # the render's box is closed glass: a mesh lens (issue 25), not left out
    assert [m.name for m in r.mesh_lenses] == ["Cuboid in render"]
    assert "Render off" not in left and "In excluded coll" not in left
    # The viewport depsgraph, read directly, is what the viewport shows (minus the
    # render-disabled objects): the monitor- and eye-hidden ones are missing.
    from lens_lights.blender.read.scene import read_blender_scene

    v = read_blender_scene(bpy.context.evaluated_depsgraph_get())
    assert v.how == "viewport"
    assert "Viewport off" not in v.sphere_sources and "Viewport-off lamp" not in v.light_sources
    assert [m.name for m in v.mesh_lenses] == ["Cuboid in viewport"]
    assert "Cuboid in render" in v.sphere_sources
    # Generate uses the render view: 2 lamps × 6 lenses (some pairs may be blocked),
    # and the render's glass box, traced as a mesh lens (7 lenses in all)
    level, message, figures = generate()
    assert figures["how"] == "render" and figures["primaries"] == 2 and figures["lenses"] == 7
    assert figures["created"] + figures["skipped"] == 12
    assert {ll.lens_lights.source_lens for ll in lens_lights()} >= {"Viewport off", "Eye hidden"}


def test_instancer_visibility_in_the_render(empty_blend):
    glass = glass_material()
    bead = add_sphere("Bead", (0, 0, 0), radius=0.25, material=glass)
    hidden_bead = add_sphere("Hidden bead", (0, 1, 0), radius=0.25, material=glass)
    hidden_bead.hide_render = True
    coll = collection_of("Beads", bead, hidden_bead)
    collection_instance("Shown", coll, location=(0, 0, 1))
    collection_instance("Render-off instancer", coll, location=(5, 0, 1)).hide_render = True
    collection_instance("Viewport-off instancer", coll, location=(-5, 0, 1)).hide_viewport = True
    add_point_light("Lamp", (0, 0, 8))
    r = read()
    # the render-disabled bead is not instanced; the render-off instancer shows nothing
    assert sorted(r.sphere_sources) == ["Shown/Bead", "Viewport-off instancer/Bead"]


def test_falls_back_to_the_viewport_and_says_so(empty_blend, monkeypatch):
    from lens_lights.blender.read import render_probe

    basic = lit_row(["Marble"], glass_material())
    add_point_light("Lamp", (0, 0, 6))
    basic[0].hide_viewport = True  # only the render sees it

    def refuse(*a, **k):
        raise render_probe.ProbeUnavailable("a render is in progress")

    monkeypatch.setattr(render_probe, "_probe", refuse)
    level, message, figures = generate()
    assert figures["how"] == "viewport (a render is in progress)"
    assert "scene read as the viewport (a render is in progress)" in message
    assert figures["lenses"] == 0  # the viewport does not have it


def test_the_probe_leaves_no_trace_and_keeps_the_last_render(empty_blend, tmp_path):
    """No scene, camera, image or engine is left behind; the user's Render Result
    (a 4 × 4 Workbench render) is the same before and after."""
    lit_row(["Marble"], glass_material())
    add_point_light("Lamp", (0, 0, 6))
    scene = bpy.context.scene
    before = {
        a: sorted(x.name_full for x in getattr(bpy.data, a))
        for a in ("scenes", "objects", "cameras", "images", "collections")
    }
    generate()  # no camera, no render result yet
    bpy.ops.lens_lights.clear()
    after = {a: sorted(x.name_full for x in getattr(bpy.data, a)) for a in before}
    assert after == before
    engines = [
        e.identifier for e in bpy.types.RenderSettings.bl_rna.properties["engine"].enum_items
    ]
    assert "LENS_LIGHTS_PROBE" not in engines

    add_camera()
    scene.render.engine = "BLENDER_WORKBENCH"
    scene.render.resolution_x = scene.render.resolution_y = 4
    bpy.ops.render.render()
    image = bpy.data.images["Render Result"]
    image.save_render(str(tmp_path / "before.png"))
    generate()
    image.save_render(str(tmp_path / "after.png"))
    assert (tmp_path / "before.png").read_bytes() == (tmp_path / "after.png").read_bytes()
    assert scene.render.engine == "BLENDER_WORKBENCH"
    assert [i.name for i in bpy.data.images] == ["Render Result"]


# --------------------------------------------------------------------------- transforms


def test_scales_zero_sizes_and_parents(empty_blend):
    from mathutils import Matrix

    glass = glass_material()
    add_point_light("Lamp", (0.0, 0.0, 20.0))
    mirrored = add_sphere("Mirrored", (0, 0, 1), material=glass)
    mirrored.scale = (1.0, -1.0, 1.0)
    negative = add_sphere("Negative", (3, 0, 1), material=glass)
    negative.scale = (-2.0, -2.0, -2.0)
    squashed = add_sphere("Negative ellipsoid", (6, 0, 1), material=glass)
    squashed.scale = (-1.0, 2.0, 2.0)
    add_sphere("Zero scale", (9, 0, 1), material=glass).scale = (0.0, 0.0, 0.0)
    add_sphere("Flat", (12, 0, 1), material=glass).scale = (1.0, 1.0, 0.0)
    point = add_sphere("Collapsed mesh", (15, 0, 1), material=glass)
    point.data.transform(Matrix.Scale(0.0, 4))
    empty_mesh = bpy.data.objects.new("Empty mesh", bpy.data.meshes.new("Empty mesh"))
    bpy.context.scene.collection.objects.link(empty_mesh)
    parent = bpy.data.objects.new("Parent", None)
    bpy.context.scene.collection.objects.link(parent)
    parent.location = (0.0, 5.0, 1.0)
    parent.rotation_euler = (0.4, 0.3, 0.2)
    parent.scale = (1.5, 1.5, 1.5)
    child = add_sphere("Child", (0, 0, 0), material=glass)
    child.parent = parent
    child.location = (2.0, 0.0, 0.0)
    stretched_parent = bpy.data.objects.new("Stretched parent", None)
    bpy.context.scene.collection.objects.link(stretched_parent)
    stretched_parent.scale = (1.0, 1.0, 3.0)
    stretched_parent.location = (0.0, -5.0, 1.0)
    add_sphere("Child of stretched", (0, 0, 0), material=glass).parent = stretched_parent

    r = read()
    spheres = {
        n: (tuple(r.arrays.center[i]), float(r.arrays.radius[i]))
        for i, n in enumerate(r.sphere_sources)
    }
    assert set(spheres) == {"Mirrored", "Negative", "Child"}
    assert spheres["Mirrored"][1] == pytest.approx(0.5, rel=1e-4)
    assert spheres["Negative"][0] == pytest.approx((3, 0, 1), abs=1e-5)
    assert spheres["Negative"][1] == pytest.approx(1.0, rel=1e-4)
    want = parent.matrix_world @ child.matrix_parent_inverse @ child.matrix_basis
    assert spheres["Child"][0] == pytest.approx(tuple(want.translation), abs=1e-5)
    assert spheres["Child"][1] == pytest.approx(0.75, rel=1e-4)
    left = dict(r.left_out)
    # glass ellipsoids (one mirrored) are mesh lenses (issue 25), outward in the world
    meshes = {m.name: m.mesh for m in r.mesh_lenses}
    assert sorted(meshes) == ["Child of stretched", "Negative ellipsoid"]
    from lens_lights.core.lens.closed_mesh import problem

    assert all(problem(m.vertices, m.triangles) == "" for m in meshes.values())
    assert left["Zero scale"].startswith("zero scale: nothing is rendered")
    assert left["Flat"].startswith("zero scale on an axis")
    assert left["Collapsed mesh"].startswith("zero size")
    assert "Empty mesh" not in left  # nothing to render, nothing to say
    level, message, figures = generate()
    assert figures["created"] == 3 and figures["left_out"] == 3  # zero, flat, collapsed
    assert "left out 3 objects" in message


def test_nan_and_huge_transforms_do_not_break_generate(empty_blend):
    glass = glass_material()
    add_point_light("Lamp", (0.0, 0.0, 6.0))
    add_sphere("Good", (0, 0, 1), material=glass)
    huge = add_sphere("Huge", (0, 0, 1), material=glass)
    huge.location = (1e30, 0.0, 1.0)
    huge.scale = (1e29, 1e29, 1e29)
    nan_lamp = add_point_light("NaN lamp", (0.0, 0.0, 6.0))
    nan_lamp.location = (float("nan"), 0.0, 6.0)
    level, message, figures = generate()
    assert level in ("INFO", "WARNING") and figures["created"] >= 1, message
    assert "NaN lamp" in dict(read().left_out)


# --------------------------------------------------------------------------- instances


def test_collection_and_geometry_nodes_instances(empty_blend):
    glass = glass_material()
    add_point_light("Lamp", (0.0, 0.0, 12.0))
    bead = add_sphere("Bead", (0, 0, 0), radius=0.25, material=glass)
    beads = collection_of("Beads", bead)
    # nested: a collection instance inside an instanced collection
    collection_instance(
        "Inner",
        beads,
        location=(0.5, 0, 0),
        scale=(2, 2, 2),
        parent_coll=bpy.data.collections.new("Outer"),
    )
    outer = bpy.data.collections["Outer"]
    collection_instance("Nest", outer, location=(0, 4, 1))
    collection_instance("Plain", beads, location=(0, -4, 1))
    gn_instances(
        "Geo", [(x, 0, 0) for x in (-3, 0, 3)], radius=0.2, material=glass, location=(0, 0, 1)
    )
    gn_instances("ObjInst", [(x, 0, 0) for x in (-3, 3)], instance_object=bead, location=(0, 8, 1))
    gn_instances(
        "Stretched",
        [(0, 0, 0), (2, 0, 0)],
        radius=0.2,
        material=glass,
        scale=(1, 1, 2),
        location=(0, -8, 1),
    )
    r = read()
    names = list(r.sphere_sources)
    centers = {
        n: tuple(round(float(c), 5) for c in r.arrays.center[i]) for i, n in enumerate(names)
    }
    radii = {n: float(r.arrays.radius[i]) for i, n in enumerate(names)}
    # the bead itself lives only in the (unlinked) collection: not rendered
    assert "Bead" not in names
    assert centers["Nest/Bead"] == (0.5, 4.0, 1.0) and radii["Nest/Bead"] == pytest.approx(0.5)
    assert centers["Plain/Bead"] == (0.0, -4.0, 1.0) and radii["Plain/Bead"] == pytest.approx(0.25)
    geo = sorted(v for n, v in centers.items() if n.startswith("Geo/"))
    assert geo == [(-3.0, 0.0, 1.0), (0.0, 0.0, 1.0), (3.0, 0.0, 1.0)]
    assert [n for n in names if n.startswith("Geo/")] == ["Geo/Geo", "Geo/Geo#1", "Geo/Geo#2"]
    assert sorted(v for n, v in centers.items() if n.startswith("ObjInst/")) == [
        (-3.0, 8.0, 1.0),
        (3.0, 8.0, 1.0),
    ]
    # the instances' original objects: the bead for collection and object
    # instances, the instancer for geometry instances (linking excludes those)
    objects = {n: r.sphere_objects[i].name for i, n in enumerate(names)}
    assert objects["Nest/Bead"] == "Bead" and objects["ObjInst/Bead"] == "Bead"
    assert objects["Geo/Geo"] == "Geo"
    # glass spheres stretched by their instance transform: mesh lenses (issue 25),
    # each placed by its own matrix
    stretched = {m.name: m.mesh for m in r.mesh_lenses if m.name.startswith("Stretched")}
    assert sorted(stretched) == ["Stretched/Stretched", "Stretched/Stretched#1"]
    extents = sorted(tuple(np.ptp(m.vertices, axis=0).round(3)) for m in stretched.values())
    assert extents == [(0.4, 0.4, 0.8)] * 2  # radius 0.2, z doubled
    assert not [n for n, _why in r.left_out_lenses if n.startswith("Stretched")]
    assert "Geo" not in dict(r.left_out)  # the instancer's own (empty) mesh
    level, message, figures = generate()
    # 7 spheres and the 2 stretched glass instances traced as mesh lenses
    assert figures["lenses"] == 9 and figures["created"] + figures["skipped"] == 7
    links = {
        ll.lens_lights.source_lens: ll.light_linking.blocker_collection for ll in lens_lights()
    }
    # a linked light of a geometry instance excludes the instancer (its original)
    coll = links.get("Geo/Geo#1")
    assert coll is None or "Geo" in [o.name for o in coll.objects]


def test_snapshot_is_stable_and_generate_keeps_attribute_storage(empty_blend):
    """Blender 5.2 stores a constant mesh attribute as one value and expands it when
    its `data` is read. The snapshot reads `data`, so it must not compare that storage
    detail (two snapshots in a row are equal); Generate itself expands nothing."""
    floor()
    add_sphere("Ball", (0.0, 0.0, 1.0), material=glass_material())
    add_point_light("Lamp", (0.0, 0.0, 8.0))
    mesh = bpy.data.objects["Floor"].data

    def storage():
        return [(a.name, getattr(a, "storage_type", "n/a")) for a in mesh.attributes]

    untouched = storage()
    level, message, figures = generate()
    assert figures["created"] == 1, message
    assert storage() == untouched
    assert snapshot_diff(snapshot(), snapshot()) == []


def test_linked_library_data(empty_blend, tmp_path):
    """Spheres linked from a library (.blend written with `libraries.write`):
    directly and through an instanced collection. They become lenses; nothing of
    the library's data changes, and clear leaves the file as it was."""
    glass = glass_material("Library glass")
    ball = add_sphere("Library ball", (0, 0, 0), material=glass)
    coll = collection_of("Library beads", ball)
    path = tmp_path / "library.blend"
    bpy.data.libraries.write(str(path), {coll, ball}, fake_user=True)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    with bpy.data.libraries.load(str(path), link=True) as (src, dst):
        dst.collections = ["Library beads"]
    linked = bpy.data.collections["Library beads"]
    assert linked.library is not None
    collection_instance("Beads here", linked, location=(0, 0, 1))
    ball = bpy.data.objects["Library ball"]
    bpy.context.scene.collection.objects.link(ball)  # the linked object itself, at the origin
    add_point_light("Lamp", (3.0, 0.0, 8.0))
    floor().location.z = -0.5  # under the linked ball (at the origin), not through it
    before, replaced = snapshot(), replaced_snapshot()
    level, message, figures = generate()
    assert figures["created"] == 2, message
    assert sorted(ll.lens_lights.source_lens for ll in lens_lights()) == [
        "Beads here/Library ball",
        "Library ball",
    ]
    assert ball.library is not None and ball.is_editable is False
    assert snapshot_diff(replaced, snapshot()) == []
    bpy.ops.lens_lights.clear()
    assert snapshot_diff(before, snapshot()) == []
    assert len(bpy.data.libraries) == 1


def replaced_snapshot():
    """The snapshot of the context scene as Generate leaves it: the user's data as it
    was but for the scene's Cycles refractive caustics, off (Replace Cycles'
    Caustics; the lenses here are no MNEE casters). Clear puts it back."""
    cycles = bpy.context.scene.cycles
    cycles.caustics_refractive = False
    try:
        return snapshot()
    finally:
        cycles.caustics_refractive = True


# --------------------------------------------------------------------------- scenes


def test_generate_acts_on_the_context_scene_only(empty_blend):
    glass = glass_material()
    first = bpy.context.scene
    lit_row(["A ball"], glass)
    add_point_light("A lamp", (0, 0, 6))
    other = bpy.data.scenes.new("Other")
    ball = add_sphere("B ball", (0, 0, 1), material=glass)
    lamp = add_point_light("B lamp", (0, 0, 6))
    for ob in (ball, lamp):
        other.collection.objects.link(ob)
        first.collection.objects.unlink(ob)
    assert ball.name in other.collection.objects and ball.name not in first.collection.objects
    replaced = replaced_snapshot()
    generate()
    (ll,) = lens_lights()
    assert ll.lens_lights.source_lens == "A ball" and ll.name in first.collection.all_objects
    assert ll.name not in other.collection.all_objects
    assert other.lens_lights.last_run is False
    assert snapshot_diff(replaced, snapshot()) == []
    with bpy.context.temp_override(scene=other, view_layer=other.view_layers[0]):
        level, message, figures = generate()
    assert figures["created"] == 1
    assert {o.lens_lights.source_lens for o in lens_lights()} == {"A ball", "B ball"}
    bpy.ops.lens_lights.clear()  # the context scene's only
    assert [o.lens_lights.source_lens for o in lens_lights()] == ["B ball"]


# --------------------------------------------------------------------------- optics cases


def test_light_inside_glass(empty_blend):
    glass = glass_material()
    add_sphere("Lantern", (0, 0, 3), radius=1.0, material=glass)
    add_sphere("Marble", (3, 0, 1), material=glass)
    add_point_light("Candle", (0, 0, 3.2))
    floor()
    level, message, figures = generate()
    assert figures["created"] == 0 and figures["skipped"] == 2
    assert "Candle × Lantern: light inside the sphere" in message
    assert "Candle × Marble: light inside sphere" in message


def test_overlapping_and_nested_spheres(empty_blend):
    glass = glass_material()
    add_sphere("Outer", (0, 0, 2), radius=1.0, material=glass)
    add_sphere("Inner", (0, 0, 2), radius=0.4, material=glass)
    add_sphere("Left", (4.0, 0, 2), radius=0.6, material=glass)
    add_sphere("Right", (4.6, 0, 2), radius=0.6, material=glass)  # overlaps Left
    add_point_light("Lamp", (2, 0, 8))
    floor()
    level, message, figures = generate()
    assert level == "INFO"
    assert figures["created"] + figures["skipped"] == 4
    # the inner sphere is entirely behind the outer one as seen from the lamp
    assert "Lamp × Inner: totally blocked" in message


def test_hundreds_of_lights(empty_blend):
    glass = glass_material()
    add_sphere("Left", (-1.5, 0, 1), material=glass)
    add_sphere("Right", (1.5, 0, 1), material=glass)
    floor()
    for k in range(300):
        a = 2 * math.pi * k / 300
        add_point_light(
            f"Lamp {k:03d}", (6 * math.cos(a), 6 * math.sin(a), 8 + (k % 7)), energy=100.0 + k
        )
    bpy.context.scene.lens_lights.max_lights = 64
    level, message, figures = generate()
    assert figures["primaries"] == 300 and figures["sources"] >= 590
    assert figures["created"] == 64
    assert figures["skipped_by_reason"]["beyond the maximum of 64 lens lights"] == 192
    assert (
        figures["skipped_by_reason"][f"not among the {4 * 64} strongest by flux"]
        == figures["sources"] - 256
    )
    # (Its time is a benchmark's business, not a test's: bench/operator_scale.py.)


def test_more_lenses_than_light_linking_sets_fit(empty_blend):
    """66 lit lenses: Blender keeps 63 light sets and 64 linking collections per scene;
    the lenses share collections (none of these beams reaches another lens)."""
    glass = glass_material()
    for k in range(66):
        add_sphere(
            f"Ball {k:02d}", (1.2 * (k % 11), 1.2 * (k // 11), 1), radius=0.3, material=glass
        )
    floor()
    add_point_light("Lamp", (6, 3, 12), energy=1000.0)
    bpy.context.scene.lens_lights.max_lights = 100
    level, message, figures = generate()
    assert figures["created"] == 66
    assert level == "INFO", message
    link = figures["linking"]
    assert link["groups"] <= 63 and link["ungrouped"] == [] and link["conflicts"] == []
    assert link["blender_says"] == []


# --------------------------------------------------------------------------- failures


def test_generate_never_raises(empty_blend, monkeypatch):
    from lens_lights.blender.build import lights
    from lens_lights.blender.commands import generate as gen
    from lens_lights.blender.commands import pipeline

    lit_row(["M0", "M1", "M2"], glass_material())
    add_point_light("Lamp", (2, 0, 6))
    bpy.ops.lens_lights.generate()
    assert len(lens_lights()) == 3
    before = snapshot()
    names_before = sorted(o.name for o in lens_lights())

    def boom(*a, **k):
        raise ValueError("boom")

    # A failure while planning: reported, nothing changed, the operator cancelled
    # (called from Python, an operator's error report becomes a RuntimeError).
    monkeypatch.setattr(pipeline, "compute_phase1_primaries", boom)
    level, message, figures = gen.generate(bpy.context)
    assert level == "ERROR" and figures["changed"] is False
    assert message.startswith("Lens Lights could not read the scene: ValueError: boom")
    reports = []
    op = SimpleNamespace(report=lambda kind, text: reports.append((kind, text)))
    assert gen.LENS_LIGHTS_OT_generate.execute(op, bpy.context) == {"CANCELLED"}
    assert reports[0][0] == {"ERROR"}
    with pytest.raises(RuntimeError, match="could not read the scene: ValueError: boom"):
        bpy.ops.lens_lights.generate()
    s = bpy.context.scene.lens_lights
    assert s.last_report.startswith("Lens Lights could not read the scene: ValueError: boom")
    assert sorted(o.name for o in lens_lights()) == names_before
    assert snapshot_diff(before, snapshot()) == []
    monkeypatch.undo()
    # A failure while building: what was made is removed, reported, undoable.
    calls = []
    real = lights.create_light

    def fail_on_second(*a, **k):
        calls.append(1)
        if len(calls) == 2:
            raise RuntimeError("no more lights")
        return real(*a, **k)

    monkeypatch.setattr(lights, "create_light", fail_on_second)
    reports.clear()
    assert gen.LENS_LIGHTS_OT_generate.execute(op, bpy.context) == {"FINISHED"}
    assert reports[0][0] == {"ERROR"}
    assert "could not create the lens lights: RuntimeError: no more lights" in s.last_report
    assert lens_lights() == []
    # the lens lights removed, Cycles' refractive caustics are back on (as before Generate)
    assert bpy.context.scene.cycles.caustics_refractive is True
    bpy.context.scene.cycles.caustics_refractive = False
    assert snapshot_diff(before, snapshot()) == []


def test_operators_are_undoable_and_undo_restores_exactly(empty_blend):
    from lens_lights.blender.commands.generate import LENS_LIGHTS_OT_clear, LENS_LIGHTS_OT_generate

    assert (
        "UNDO" in LENS_LIGHTS_OT_generate.bl_options and "UNDO" in LENS_LIGHTS_OT_clear.bl_options
    )
    glass = glass_material()
    lit_row(["M0", "M1"], glass)
    add_point_light("Lamp", (1, 0, 6))
    floor()
    bpy.ops.ed.undo_push(message="scene")
    empty = snapshot()
    bpy.ops.lens_lights.generate("EXEC_DEFAULT", True)
    assert len(lens_lights()) == 2
    generated = snapshot()
    bpy.ops.lens_lights.generate("EXEC_DEFAULT", True)  # regenerate
    bpy.ops.lens_lights.clear("EXEC_DEFAULT", True)
    assert lens_lights() == []
    bpy.ops.ed.undo()  # back to the regenerated
    assert len(lens_lights()) == 2
    bpy.ops.ed.undo()
    bpy.ops.ed.undo()  # back to before any
    assert lens_lights() == [] and not bpy.data.collections.get("Lens Lights")
    assert snapshot_diff(empty, snapshot()) == []
    assert bpy.context.scene.lens_lights.last_run is False
    bpy.ops.ed.redo()
    assert len(lens_lights()) == 2 and snapshot_diff(generated, snapshot()) == []


def test_generate_regenerate_and_clear_touch_nothing_of_the_users(empty_blend):
    """Every datablock that is not the extension's own is the same (names, RNA
    properties, custom properties, transforms, mesh vertices) after generate,
    regenerate and clear; after clear nothing of the extension's is left."""
    glass = glass_material()
    glass["my prop"] = 7
    floor()["note"] = "mine"
    balls = lit_row(["M0", "M1", "M2"], glass)
    balls[1].lens_lights.lens_mode = "ALWAYS"
    add_sphere("Grey", (0, 3, 1), material=node_material("Grey", "ShaderNodeBsdfDiffuse"))
    gn_instances("Geo", [(x, 4, 1) for x in (0, 2)], material=glass)
    add_point_light("Lamp", (2, 0, 6))
    add_point_light("Sun", (0, 0, 20), kind="SUN")
    add_camera()
    names = {
        a: sorted(x.name_full for x in getattr(bpy.data, a))
        for a in ("objects", "collections", "lights", "images", "scenes")
    }
    before, replaced = snapshot(), replaced_snapshot()
    generate()
    assert len(lens_lights()) >= 3
    assert snapshot_diff(replaced, snapshot()) == []
    generate()
    assert snapshot_diff(replaced, snapshot()) == []
    bpy.ops.lens_lights.clear()
    assert snapshot_diff(before, snapshot()) == []
    assert {a: sorted(x.name_full for x in getattr(bpy.data, a)) for a in names} == names


def test_a_lens_mesh_edited_between_reads_is_fitted_again(empty_blend):
    """Sphere fits are remembered by the mesh's content across runs (scene_reader's
    `_FITS`): an edited mesh is fitted again — scaled 2× it reads as radius 1.0,
    with its top cap cut open it is no lens."""
    import bmesh
    from mathutils import Matrix

    ball = add_sphere("Ball", (0.0, 0.0, 2.0), radius=0.5, material=glass_material())
    r = read()
    assert r.sphere_sources == ["Ball"]
    assert float(r.arrays.radius[0]) == pytest.approx(0.5, rel=2e-3)
    assert read().sphere_sources == ["Ball"]  # the same mesh: the remembered fit

    ball.data.transform(Matrix.Scale(2.0, 4))
    ball.data.update()
    r = read()
    assert float(r.arrays.radius[0]) == pytest.approx(1.0, rel=2e-3)

    bm = bmesh.new()
    bm.from_mesh(ball.data)
    cap = [f for f in bm.faces if f.calc_center_median().z > 0.9]
    assert cap
    bmesh.ops.delete(bm, geom=cap, context="FACES_ONLY")
    bm.to_mesh(ball.data)
    bm.free()
    ball.data.update()
    assert read().sphere_sources == []
