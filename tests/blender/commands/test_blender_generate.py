"""The Blender side without rendering: scene reading, generate, regenerate, clear,
undo, skipped objects, the panel's drawing (bpy module, no images)."""

import math
from types import SimpleNamespace

import bpy
import pytest

# --------------------------------------------------------------------------- helpers
from blender_scene_helpers import (
    add_point_light,
    add_sphere,
    basic_scene,
    draw_panel,
    generate,
    glass_material,
    lens_lights,
    new_material,
    node_material,
)

# The light pipeline: AUTO builds lights here (the Caustic layer: test_blender_layer.py).
pytestmark = [pytest.mark.blender, pytest.mark.usefixtures("auto_builds_lights")]


# --------------------------------------------------------------------------- generate


def test_generate_creates_the_physical_spot_light(empty_blend):
    sphere, light = basic_scene()
    bpy.context.scene.lens_lights.energy_model = "PHYSICAL"  # (the default is AUTO)
    assert bpy.ops.lens_lights.generate() == {"FINISHED"}
    (ll,) = lens_lights()
    # R 0.5, n 1.5, D 2: V = 4/3 − 1/2, image 1.2 below the centre (z = 1.3);
    # m = 0.6: energy = 1000 · 0.9216 · 0.36, radius = 0.6 · 0.1; 2θ = 11.41°.
    assert ll.type == "LIGHT" and ll.data.type == "SPOT"
    assert tuple(ll.location) == pytest.approx((0.0, 0.0, 1.3), abs=1e-6)
    down = -ll.matrix_world.to_3x3().col[2]  # a spot emits along its local −Z
    assert tuple(down.normalized()) == pytest.approx((0.0, 0.0, -1.0), abs=1e-6)
    assert ll.data.energy == pytest.approx(1000 * 0.9216 * 0.36, rel=1e-5)
    assert math.degrees(ll.data.spot_size) == pytest.approx(11.4104, abs=2e-3)
    assert ll.data.shadow_soft_size == pytest.approx(0.06, rel=1e-5)
    assert ll.data.spot_blend == pytest.approx(0.15)
    assert ll.data.use_custom_distance and ll.data.cutoff_distance > 10
    assert tuple(ll.scale) == (1.0, 1.0, 1.0)
    assert [c.name for c in ll.users_collection] == ["Lens Lights"]
    meta = ll.lens_lights
    assert (meta.source_light, meta.source_lens, meta.kind, meta.full) == (
        "Lamp",
        "Marble",
        "real",
        True,
    )
    assert meta.energy_model == "PHYSICAL" and meta.unblocked_fraction == pytest.approx(1.0)
    # light and shadow linking: none needed, the light 0.2 below the back pole (z 1.5)
    # with radius 0.06 aims down, away from the marble: it cannot reach its lens
    # (lights inside their lens: tests/blender/build/test_linking_groups.py)
    assert ll.light_linking.receiver_collection is None
    assert ll.light_linking.blocker_collection is None
    s = bpy.context.scene.lens_lights
    assert (s.last_created, s.last_sources, s.last_primaries, s.last_lenses, s.last_skipped) == (
        1,
        1,
        1,
        1,
        0,
    )
    assert s.last_report.startswith("Created 1 lens light (1 light × 1 lens)")


def test_thesis_model_and_settings(empty_blend):
    basic_scene()
    s = bpy.context.scene.lens_lights
    s.energy_model = "THESIS"
    s.spot_blend = 0.5
    generate()
    (ll,) = lens_lights()
    assert ll.data.energy == pytest.approx(1000.0)  # kt = 1: brightness factor 1
    assert ll.data.spot_blend == pytest.approx(0.5)
    assert ll.lens_lights.energy_model == "THESIS"


def test_regenerate_replaces_only_the_extensions_lights(empty_blend):
    basic_scene()
    mine = add_point_light("My spot", (3.0, 0.0, 3.0), energy=50.0, kind="SPOT")
    generate()
    first = lens_lights()
    assert len(first) == 1
    # the user puts an object of theirs into "Lens Lights", and duplicates a lens light
    coll = bpy.data.collections["Lens Lights"]
    keep = add_point_light("Kept", (0, 3, 3), energy=10.0, kind="AREA")
    coll.objects.link(keep)
    dup = first[0].copy()
    dup.name = "My copy of a lens light"
    bpy.context.scene.collection.objects.link(dup)
    level, message, figures = generate()
    assert figures["created"] == 2  # the user's area light is a primary too
    ours = [o for o in bpy.data.objects if o.name.startswith("Lens light")]
    assert len(ours) == 2
    assert bpy.data.objects.get("My spot") is mine and mine.data.energy == 50.0
    assert bpy.data.objects.get("Kept") is keep and keep.name in coll.objects
    assert bpy.data.objects.get("My copy of a lens light") is dup
    assert len([c for c in bpy.data.collections if c.name.startswith("Lens link")]) == 1


def test_clear_removes_everything_created_and_nothing_else(empty_blend):
    basic_scene()
    n_lights, n_colls = len(bpy.data.lights), len(bpy.data.collections)
    generate()
    assert len(bpy.data.lights) == n_lights + 1
    assert bpy.ops.lens_lights.clear() == {"FINISHED"}
    assert lens_lights() == []
    assert len(bpy.data.lights) == n_lights and len(bpy.data.collections) == n_colls
    assert {o.name for o in bpy.data.objects} == {"Floor", "Marble", "Lamp"}
    assert [c.name for c in bpy.data.objects["Marble"].users_collection] == ["Scene Collection"]
    assert "Removed 1 lens light" in bpy.context.scene.lens_lights.last_report
    # nothing left to clear: Clear's poll says no (blender.ui.scene_state)
    from lens_lights.blender.ui.scene_state import has_lens_lights

    assert not has_lens_lights(bpy.context.scene)


def test_clear_keeps_a_lens_lights_data_the_user_also_uses(empty_blend):
    """Clear removes its lights' data with them, but not a light data the user gave
    to an object of theirs (it has a user left)."""
    basic_scene()
    generate()
    (ll,) = lens_lights()
    data = ll.data
    mine = bpy.data.objects.new("My lamp", data)
    bpy.context.scene.collection.objects.link(mine)
    n_lights = len(bpy.data.lights)
    assert bpy.ops.lens_lights.clear() == {"FINISHED"}
    assert lens_lights() == [] and bpy.data.objects.get("My lamp") is mine
    assert mine.data is data and len(bpy.data.lights) == n_lights


def test_there_is_something_to_clear_only_after_generate(empty_blend):
    from lens_lights.blender.ui.scene_state import has_lens_lights

    basic_scene()
    assert not has_lens_lights(bpy.context.scene)
    generate()
    assert has_lens_lights(bpy.context.scene)
    # another scene has nothing of the extension's
    assert not has_lens_lights(bpy.data.scenes.new("Other"))
    bpy.ops.lens_lights.clear()
    assert not has_lens_lights(bpy.context.scene)


def test_undo_and_redo(empty_blend):
    basic_scene()
    bpy.ops.ed.undo_push(message="before")
    bpy.ops.lens_lights.generate("EXEC_DEFAULT", True)  # True: push an undo step
    assert len(lens_lights()) == 1
    bpy.ops.ed.undo()
    assert lens_lights() == []
    bpy.ops.ed.redo()
    assert len(lens_lights()) == 1
    bpy.ops.lens_lights.clear("EXEC_DEFAULT", True)
    assert lens_lights() == []
    bpy.ops.ed.undo()
    assert len(lens_lights()) == 1


# --------------------------------------------------------------------------- skipped


def test_skipped_and_left_out_objects_are_reported(empty_blend):
    from lens_lights.blender.read.scene import read_blender_scene
    from lens_lights.core.lens.closed_mesh import OPEN_REASON

    glass = glass_material()
    basic_scene()
    bpy.ops.mesh.primitive_cube_add(location=(3, 3, 1))
    bpy.context.object.name = "Glass cube"
    bpy.context.object.data.materials.append(glass)
    egg = add_sphere("Egg", (-3, 3, 1), material=glass)
    egg.scale = (1.0, 1.0, 1.3)
    add_sphere("Red ball", (-3, -3, 1), material=node_material("Red", "ShaderNodeBsdfDiffuse"))
    hidden = add_sphere("Hidden", (3, -3, 1), material=glass)
    hidden.hide_render = True
    off = add_point_light("Off", (0, 0, 9))
    off.hide_render = True
    add_point_light("Sun", (0, 0, 9), energy=0.0, kind="SUN")
    add_sphere("Coarse", (0, 3, 1), material=glass, segments=8, rings=4)
    bpy.ops.mesh.primitive_plane_add(size=1.0, location=(-3, 0, 1))
    bpy.context.object.name = "Pane"
    bpy.context.object.data.materials.append(glass)
    off_coll = bpy.data.collections.new("Render off")
    bpy.context.scene.collection.children.link(off_coll)
    off_coll.hide_render = True
    in_off = add_sphere("In a render-disabled collection", (3, 0, 1), material=glass)
    off_coll.objects.link(in_off)
    bpy.context.scene.collection.objects.unlink(in_off)

    read = read_blender_scene(bpy.context)
    assert read.light_sources == ["Lamp"]
    assert sorted(read.sphere_sources) == ["Marble", "Red ball"]
    reasons = dict(read.left_out)
    assert "Hidden" not in reasons and "Off" not in reasons  # disabled for rendering
    assert "In a render-disabled collection" not in reasons
    # issue 25: closed glass that is no sphere is a mesh lens (a box, an unevenly
    # scaled sphere, a sphere too coarse for the fit), open glass is left out
    assert sorted(m.name for m in read.mesh_lenses) == ["Coarse", "Egg", "Glass cube"]
    assert reasons["Pane"] == OPEN_REASON
    assert reasons["Sun"].startswith("sun without strength")  # a sun of 0 W/m²
    assert reasons["Floor"].startswith("not a sphere: its bounding box")
    assert [n for n, _ in read.left_out_lenses] == ["Pane"]

    level, message, figures = generate()
    assert figures["created"] == 1 and figures["left_out"] == 1
    assert (
        "left out 1 object (Lens Lights models solid glass spheres and closed glass meshes): "
        f"Pane ({OPEN_REASON})" in message
    )
    assert "caustic layers for 3 glass objects" in message
    assert "Red ball" not in message  # an opaque ball is no lens, not "skipped"


def test_blocked_pairs_are_skipped_by_name(empty_blend):
    basic_scene()
    add_sphere(
        "Blocker",
        (0.0, 0.0, 3.6),
        radius=0.45,
        material=node_material("Grey", "ShaderNodeBsdfDiffuse"),
    )
    level, message, figures = generate()
    assert figures["created"] == 0 and figures["skipped"] == 1
    assert "skipped 1 pair: Lamp × Marble: totally blocked by sphere" in message


def test_lens_mode_and_ior_override(empty_blend):
    sphere, _ = basic_scene()
    bpy.context.scene.lens_lights.energy_model = "PHYSICAL"  # (the default is AUTO)
    sphere.lens_lights.lens_mode = "NEVER"
    assert generate()[2]["created"] == 0
    sphere.lens_lights.lens_mode = "AUTO"
    sphere.lens_lights.use_ior_override = True
    sphere.lens_lights.ior_override = 2.0
    generate()
    # n = 2: P = 2(n−1)/(nR) = 2, V = 2 − 1/2 = 1.5, image 2/3 below the centre
    (ll,) = lens_lights()
    assert ll.location.z == pytest.approx(2.5 - 2 / 3, abs=1e-6)
    # "Always" makes a lens of an opaque sphere, IOR 1.5 by default
    sphere.lens_lights.use_ior_override = False
    sphere.lens_lights.lens_mode = "ALWAYS"
    sphere.data.materials[0] = node_material("Grey", "ShaderNodeBsdfDiffuse")
    generate()
    (ll,) = lens_lights()
    assert ll.location.z == pytest.approx(1.3, abs=1e-6)


@pytest.mark.parametrize(
    "kind,weight", [("ShaderNodeBsdfGlass", 1.0), ("ShaderNodeBsdfRefraction", 1.0)]
)
def test_glass_and_refraction_bsdfs(empty_blend, kind, weight):
    from lens_lights.blender.read.scene import read_blender_scene

    add_sphere("S", (0, 0, 0), material=node_material("M", kind, IOR=1.33, Color=(1, 0.5, 0.25, 1)))
    add_point_light("L", (0, 0, 3))
    read = read_blender_scene(bpy.context)
    surf = read.scene.objects[0].surface
    assert surf.ior == pytest.approx(1.33) and surf.transmission == weight
    assert read.lens_optics[0].tint == pytest.approx((1, 0.25, 0.0625))  # Color² (two surfaces)


def test_mix_shader_and_volume_absorption(empty_blend):
    from lens_lights.blender.read.scene import read_blender_scene

    mat = new_material("Mixed")
    nt = mat.node_tree
    nt.nodes.remove(nt.nodes["Principled BSDF"])
    out = nt.nodes["Material Output"]
    glass = nt.nodes.new("ShaderNodeBsdfGlass")
    glass.inputs["IOR"].default_value = 1.6
    diffuse = nt.nodes.new("ShaderNodeBsdfDiffuse")
    mix = nt.nodes.new("ShaderNodeMixShader")
    mix.inputs["Fac"].default_value = 0.25  # 0.75 glass, 0.25 diffuse
    nt.links.new(glass.outputs[0], mix.inputs[1])
    nt.links.new(diffuse.outputs[0], mix.inputs[2])
    nt.links.new(mix.outputs[0], out.inputs["Surface"])
    absorb = nt.nodes.new("ShaderNodeVolumeAbsorption")
    absorb.inputs["Density"].default_value = 2.0
    absorb.inputs["Color"].default_value = (1.0, 0.5, 0.0, 1.0)
    nt.links.new(absorb.outputs[0], out.inputs["Volume"])
    add_sphere("S", (0, 0, 0), material=mat)
    add_point_light("L", (0, 0, 3))
    read = read_blender_scene(bpy.context)
    surf = read.scene.objects[0].surface
    assert surf.transmission == pytest.approx(0.75) and surf.ior == pytest.approx(1.6)
    assert read.lens_optics[0].absorption == pytest.approx((0.0, 1.0, 2.0))


# --------------------------------------------------------------------------- reading


def test_scene_reader_contract_world_space_and_instances(empty_blend):
    from lens_lights.blender.read.scene import read_blender_scene

    glass = glass_material()
    src = add_sphere("Bead", (0, 0, 0), radius=0.25, material=glass)
    coll = bpy.data.collections.new("Beads")
    coll.objects.link(src)
    bpy.context.scene.collection.objects.unlink(src)
    for k, loc in enumerate([(1, 0, 1), (-1, 0, 1)]):
        inst = bpy.data.objects.new(f"Inst{k}", None)
        inst.instance_type = "COLLECTION"
        inst.instance_collection = coll
        inst.location = loc
        inst.rotation_euler = (0.3, 0.2, 0.1)
        inst.scale = (2, 2, 2)
        bpy.context.scene.collection.objects.link(inst)
    add_point_light("L", (0, 0, 5), energy=100.0, radius=0.2)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    read = read_blender_scene(depsgraph)  # a depsgraph works too
    assert sorted(read.sphere_sources) == ["Inst0/Bead", "Inst1/Bead"]
    assert len(read.scene.objects) == len(read.sphere_sources) == len(read.lens_optics)
    centers = sorted(tuple(round(c, 6) for c in s.center) for s in read.scene.objects)
    assert centers == [(-1, 0, 1), (1, 0, 1)]
    assert all(s.radius == pytest.approx(0.5) for s in read.scene.objects)  # 0.25 × 2
    light = read.scene.lights[0]
    assert (light.position, light.brightness, light.radius, light.name) == (
        (0, 0, 5),
        100.0,
        pytest.approx(0.2),
        "L",
    )
    assert read.light_sources == ["L"] and read.sphere_objects[0].name == "Bead"
    assert read.scene_size > 2
    generate()
    assert len(lens_lights()) == 2


def test_exposure_temperature_and_unnormalized_power(empty_blend):
    from lens_lights.blender.read.scene import read_blender_scene

    light = add_point_light("L", (0, 0, 3), energy=10.0, radius=0.5)
    if not hasattr(light.data, "exposure"):
        # Blender 4.2 lights have no exposure, normalize or temperature (4.5 added
        # them): the power is the energy.
        assert read_blender_scene(bpy.context).scene.lights[0].brightness == 10.0
        pytest.skip("this Blender's lights have no exposure, normalize or temperature")
    light.data.exposure = 1.0
    read = read_blender_scene(bpy.context)
    assert read.scene.lights[0].brightness == pytest.approx(20.0)
    light.data.normalize = False
    read = read_blender_scene(bpy.context)
    assert read.scene.lights[0].brightness == pytest.approx(20.0 * 4 * math.pi * 0.25)
    light.data.use_temperature = True
    light.data.temperature = 3000
    read = read_blender_scene(bpy.context)
    r, g, b = read.scene.lights[0].color
    assert r > g > b  # warm


@pytest.mark.skipif(bpy.app.version >= (5, 0, 0), reason="from 5.0 every material uses its nodes")
def test_a_material_with_use_nodes_off_is_no_lens(empty_blend):
    """Before 5.0 a material keeps its node tree with "Use Nodes" off and renders
    its plain colours: opaque."""
    from lens_lights.blender.read.scene import read_blender_scene

    glass = glass_material()
    glass.use_nodes = False
    add_sphere("Marble", (0.0, 0.0, 1.0), material=glass)
    add_point_light("Lamp", (0.0, 0.0, 5.0))
    read = read_blender_scene(bpy.context)
    assert read.arrays.kt.tolist() == [0.0]
    assert "material without nodes" in read.material_notes[0]


def test_collimated_source_becomes_a_narrow_far_spot(empty_blend):
    bpy.context.scene.lens_lights.energy_model = "PHYSICAL"  # (the default is AUTO)
    # Light at the front focal point (D = nR/(2(n−1)) = 0.75 for R 0.5, n 1.5).
    add_sphere("Marble", (0.0, 0.0, 2.5), material=glass_material())
    add_point_light("Lamp", (0.0, 0.0, 3.25), energy=100.0)
    bpy.ops.mesh.primitive_plane_add(size=8)
    generate()
    (ll,) = lens_lights()
    assert ll.lens_lights.kind == "collimated"
    assert ll.location.z > 10 and ll.location.x == pytest.approx(0, abs=1e-3)
    assert math.degrees(ll.data.spot_size) == pytest.approx(1.0)
    assert ll.scale.x == pytest.approx(ll.scale.y) and ll.scale.x < 1
    # Footprint at the back vertex (z = 2) equals R_C: tan(0.5°) · k · (z_light − 2).
    from lens_lights.blender.read.scene import read_blender_scene
    from lens_lights.core.phase1.point_lights import compute_phase1

    src = compute_phase1(read_blender_scene(bpy.context).scene).sources[0]
    footprint = math.tan(math.radians(0.5)) * ll.scale.x * (ll.location.z - 2.0)
    assert footprint == pytest.approx(src.cylinder_radius, rel=1e-4)


def test_blender_clamps_spot_size_to_1_to_180_degrees(empty_blend):
    # What Blender itself does outside the range (the reason for the scale trick).
    data = bpy.data.lights.new("s", "SPOT")
    data.spot_size = math.radians(0.5)
    assert math.degrees(data.spot_size) == pytest.approx(1.0)
    data.spot_size = math.radians(200.0)
    assert math.degrees(data.spot_size) == pytest.approx(180.0)


def test_max_lights_and_brightness_cut_off(empty_blend):
    bpy.context.scene.lens_lights.energy_model = "PHYSICAL"  # (the default is AUTO)
    glass = glass_material()
    bpy.ops.mesh.primitive_plane_add(size=20, location=(3, 0, -2))  # images above it: cones
    for k in range(4):
        add_sphere(f"M{k}", (2.0 * k, 0.0, 1.0), radius=0.2 + 0.1 * k, material=glass)
    add_point_light("Lamp", (3.0, 0.0, 6.0))
    s = bpy.context.scene.lens_lights
    s.max_lights = 2
    level, message, figures = generate()
    assert figures["created"] == 2 and figures["skipped"] == 2
    assert "beyond the maximum of 2 lens lights" in message
    s.max_lights = 64
    s.min_brightness = 0.95  # PHYSICAL: T(0) = 0.92 < 0.95
    assert generate()[2]["created"] == 0
    assert "dimmer than the cut-off" in bpy.context.scene.lens_lights.last_report


def test_no_lights_and_no_lenses_warn(empty_blend):
    assert generate()[0] == "WARNING"
    add_point_light("L", (0, 0, 3))
    level, message, _ = generate()
    assert level == "WARNING" and "no glass sphere" in message


# --------------------------------------------------------------------------- panel


def test_panel_draws_buttons_settings_and_figures(empty_blend):
    from lens_lights.blender.ui.panel import VIEW3D_PT_lens_lights, VIEW3D_PT_lens_lights_object

    assert VIEW3D_PT_lens_lights.bl_category == "Lens Lights"
    assert VIEW3D_PT_lens_lights.bl_region_type == "UI"
    sphere, _ = basic_scene()
    ctx = SimpleNamespace(scene=bpy.context.scene, object=sphere)
    log = draw_panel(VIEW3D_PT_lens_lights, ctx)
    assert ("operator", "lens_lights.generate") in log and ("operator", "lens_lights.clear") in log
    assert {("prop", p) for p in ("energy_model", "min_brightness", "max_lights")} <= set(log)
    assert ("label", "Not run yet") in log
    generate()
    log = draw_panel(VIEW3D_PT_lens_lights, ctx)
    assert ("label", "Lens lights: 1") in log
    assert VIEW3D_PT_lens_lights_object.poll(ctx)
    log = draw_panel(VIEW3D_PT_lens_lights_object, ctx)
    assert ("prop", "lens_mode") in log and ("prop", "ior_override") in log
    ctx.object = lens_lights()[0]
    log = draw_panel(VIEW3D_PT_lens_lights_object, ctx)
    assert ("label", "From: Lamp") in log and ("label", "Lens: Marble") in log
    assert bpy.types.VIEW3D_PT_lens_lights.bl_label == "Lens Lights"
    # (lower(): the label is in Title Case, "Generate Lens Lights", once generate.py has it)
    assert bpy.ops.lens_lights.generate.get_rna_type().name.lower() == "generate lens lights"


def test_marble_on_a_table_under_a_high_lamp_and_a_ceiling(empty_blend):
    bpy.context.scene.lens_lights.energy_model = "PHYSICAL"  # (the default is AUTO)
    # The image (1.2 below the centre) lies under the table the marble rests on:
    # the receiver (the table, R below the centre) cuts the converging beam, so the
    # cone is pulled in to the lens centre (issue 12), never under the table; a
    # ceiling above changes nothing.
    bpy.ops.mesh.primitive_plane_add(size=8)
    add_sphere("Marble", (0.0, 0.0, 0.5), material=glass_material())
    add_point_light("Lamp", (0.0, 0.0, 2.5))
    generate()
    (ll,) = lens_lights()
    assert "near field" in ll.lens_lights.note
    assert tuple(ll.location) == pytest.approx((0.0, 0.0, 0.5), abs=1e-6)
    bpy.ops.mesh.primitive_plane_add(size=8, location=(0, 0, 4))
    bpy.context.object.name = "Ceiling"
    generate()
    (ll,) = lens_lights()
    assert tuple(ll.location) == pytest.approx((0.0, 0.0, 0.5), abs=1e-6)
    assert ll.data.energy > 0
