"""Issue 24, items 3 and 6, in Blender: a thin-walled glass sphere is no lens (and
says so); glass that is no sphere is named by its shape; Generate says what it made
(lens lights or caustic layers); Replace Cycles' Caustics leaves the scene's
refractive caustics on while glass Lens Lights does not model is there, and names it.

The expected facts are those of the scene built here: which objects, their shapes,
what was made (counted in the file, not taken from the report)."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

bpy = pytest.importorskip("bpy")

from blender_scene_helpers import (  # noqa: E402
    add_point_light,
    add_sphere,
    basic_scene,
    generate,
    glass_material,
    lens_lights,
    node_material,
    set_engine,
)

pytestmark = pytest.mark.blender

THIN_WALL = "thin-walled glass (Thin Wall): a shell, which focuses nothing"


def _thin_glass(name="Bubble glass"):
    mat = glass_material(name)
    bsdf = mat.node_tree.nodes["Principled BSDF"]
    if bpy.app.version >= (5, 0, 0):
        bsdf.inputs["Thin Wall"].default_value = True
    return mat


def _glass_object(name, make, location, **kw):
    make(location=location, **kw)
    ob = bpy.context.object
    ob.name = name
    ob.data.materials.append(glass_material(f"{name} glass"))
    return ob


# --------------------------------------------------------------------------- Thin Wall


def test_a_thin_walled_sphere_makes_no_solid_ball_caustic(empty_blend, auto_builds_lights):
    """5.x: Thin Wall on → no lens, left out with its reason; the solid ball beside it
    still gets its lens light. 4.5 has no Thin Wall input: the same material is solid
    glass there and both are lenses."""
    from lens_lights.blender.read.scene import read_blender_scene

    set_engine("CYCLES")
    bpy.ops.mesh.primitive_plane_add(size=20)
    add_sphere("Ball", (-2.0, 0.0, 1.0), material=glass_material())
    add_sphere("Bubble", (2.0, 0.0, 1.0), material=_thin_glass())
    add_point_light("Lamp", (0.0, 0.0, 5.0))
    read = read_blender_scene(bpy.context)
    bsdf = bpy.data.materials["Bubble glass"].node_tree.nodes["Principled BSDF"]
    if bpy.app.version >= (5, 0, 0):
        assert bsdf.inputs["Thin Wall"].type == "BOOLEAN"
        assert list(read.sphere_sources) == ["Ball"]
        assert read.left_out_lenses == [("Bubble", THIN_WALL)]
        assert ("Bubble", THIN_WALL) in read.unmodelled_glass
        level, message, figures = generate()
        made = [ob.lens_lights.source_lens for ob in lens_lights()]
        assert figures["created"] == 1 == len(made) and made == ["Ball"]
        assert f"Bubble ({THIN_WALL})" in message
    else:
        assert "Thin Wall" not in bsdf.inputs  # nothing to read before 5.0
        assert sorted(read.sphere_sources) == ["Ball", "Bubble"]
        assert read.left_out_lenses == []
        level, message, figures = generate()
        assert figures["created"] == 2 == len(lens_lights())


# --------------------------------------------------------------------------- shapes


def test_glass_that_is_no_sphere_is_named_by_its_shape(empty_blend, auto_builds_lights):
    from lens_lights.blender.read.scene import read_blender_scene

    set_engine("CYCLES")
    add_sphere("Ball", (0.0, 0.0, 1.0), material=glass_material())
    _glass_object("Cylinder", bpy.ops.mesh.primitive_cylinder_add, (3.0, 0.0, 1.0))
    _glass_object("Cube", bpy.ops.mesh.primitive_cube_add, (-3.0, 0.0, 1.0))
    _glass_object(
        "Tube", bpy.ops.mesh.primitive_cylinder_add, (0.0, 3.0, 1.0), end_fill_type="NOTHING"
    )
    egg = add_sphere("Egg", (0.0, -3.0, 1.0), material=glass_material("Egg glass"))
    egg.scale = (1.0, 1.0, 1.4)
    bpy.ops.object.select_all(action="DESELECT")
    egg.select_set(True)
    bpy.context.view_layer.objects.active = egg
    bpy.ops.object.transform_apply(scale=True)  # a stretched mesh, not a scaled object
    stretched = add_sphere("Stretched", (3.0, 3.0, 1.0), material=glass_material("S glass"))
    stretched.scale = (1.0, 2.0, 1.0)  # a scaled object: the transform says it
    add_point_light("Lamp", (0.0, 0.0, 6.0))

    read = read_blender_scene(bpy.context)
    reasons = dict(read.left_out_lenses)
    # issue 25: closed glass is a mesh lens of its own; open glass is named
    assert sorted(m.name for m in read.mesh_lenses) == ["Cube", "Cylinder", "Egg", "Stretched"]
    assert reasons == {
        "Tube": "open mesh: a surface, not a glass volume "
        "(open glass is water only with water's index, 1.30–1.36)",
    }
    assert dict(read.unmodelled_glass) == reasons
    level, message, figures = generate()
    assert figures["created"] == 1 and figures["left_out"] == 1
    assert (
        "left out 1 object (Lens Lights models solid glass spheres and closed glass meshes): "
        "Tube (open mesh: a surface, not a glass volume "
        "(open glass is water only with water's index, 1.30–1.36))"
    ) in message
    # no floor here: nothing receives the meshes' caustics, and the report says so
    assert "no caustic layer for the glass of Cylinder, Cube, Egg, Stretched" in message
    assert "too coarse" not in message


# --------------------------------------------------------------------------- what was made


def test_eevee_says_it_made_a_caustic_layer_not_a_lens_light(empty_blend):
    basic_scene()
    set_engine("BLENDER_EEVEE")
    level, message, figures = generate()
    made = lens_lights()
    assert [ob.type for ob in made] == ["MESH"]  # one caustic layer, no light
    assert message.startswith("Created 1 caustic layer on Floor (1 light × 1 lens)"), message
    assert "lens light" not in message.split(";")[0]
    assert figures["created"] == 0 and figures["layers"] == 1
    settings = bpy.context.scene.lens_lights
    assert settings.last_created == 0 and settings.last_layers == 1
    assert bpy.ops.lens_lights.clear() == {"FINISHED"}
    assert settings.last_report.startswith("Removed 1 caustic layer")


def test_cycles_says_it_made_lens_lights(empty_blend, auto_builds_lights):
    basic_scene()
    set_engine("CYCLES")
    level, message, figures = generate()
    assert [ob.type for ob in lens_lights()] == ["LIGHT"]
    assert message.startswith("Created 1 lens light (1 light × 1 lens)"), message
    assert figures["created"] == 1 and figures["layers"] == 0


# --------------------------------------------------------------------------- Cycles' caustics


def test_refractive_caustics_stay_on_while_unmodelled_glass_is_there(
    empty_blend, auto_builds_lights
):
    set_engine("CYCLES")
    scene = bpy.context.scene
    ball = add_sphere("Ball", (0.0, 0.0, 1.0), material=glass_material())
    ball.cycles.is_caustics_caster = True
    # open glass (issue 25: a closed cube is a mesh lens now, with its own layer)
    cube = _glass_object("Glass cube", bpy.ops.mesh.primitive_plane_add, (3.0, 0.0, 1.0))
    add_point_light("Lamp", (0.0, 0.0, 4.0))
    assert scene.cycles.caustics_refractive is True
    level, message, figures = generate()
    assert figures["created"] == 1
    assert scene.cycles.caustics_refractive is True  # the cube keeps its caustic
    assert ball.cycles.is_caustics_caster is False  # per lens: nobody else's
    assert level == "WARNING"
    assert (
        "Cycles' refractive caustics left on: Lens Lights does not model the glass of "
        "Glass cube, whose caustics only Cycles renders"
    ) in message
    assert "its own caustic of Ball on top of the lens lights'" in message
    assert "refractive caustics (scene)" not in message  # not turned off: not said so

    # without the cube the scene-wide switch is turned off again
    bpy.data.objects.remove(cube)
    level, message, figures = generate()
    assert scene.cycles.caustics_refractive is False
    assert "refractive caustics (scene)" in message and "left on" not in message
    assert bpy.ops.lens_lights.clear() == {"FINISHED"}
    assert scene.cycles.caustics_refractive is True


def test_the_bake_too_keeps_refractive_caustics_for_unmodelled_glass(empty_blend):
    set_engine("CYCLES")
    scene = bpy.context.scene
    scene.lens_lights.energy_model = "FITTED"
    scene.frame_start, scene.frame_end = 1, 2
    add_sphere("Ball", (0.0, 0.0, 1.0), material=glass_material())
    cube = _glass_object("Glass cube", bpy.ops.mesh.primitive_cube_add, (3.0, 0.0, 1.0))
    add_point_light("Lamp", (0.0, 0.0, 4.0))
    assert bpy.ops.lens_lights.bake() == {"FINISHED"}
    assert len(lens_lights()) == 1
    assert scene.cycles.caustics_refractive is True
    report = scene.lens_lights.last_report
    assert "Cycles' refractive caustics left on" in report and "Glass cube" in report
    bpy.data.objects.remove(cube)
    assert bpy.ops.lens_lights.bake() == {"FINISHED"}
    assert scene.cycles.caustics_refractive is False
    assert "left on" not in scene.lens_lights.last_report


def test_in_eevee_the_caustic_layers_replace_cycles_caustics(empty_blend):
    basic_scene()
    set_engine("BLENDER_EEVEE")
    level, message, figures = generate()
    assert figures["layers"] == 1
    assert (
        "Cycles' own caustics turned off (the caustic layers replace them): "
        "refractive caustics (scene)"
    ) in message


def test_glass_text_keeps_refractive_caustics_too(empty_blend, auto_builds_lights):
    """Text (like curves and metaballs) renders as its evaluated mesh, an instance of
    the text object in the depsgraph: that mesh, flat, is the glass named."""
    from lens_lights.blender.read.scene import read_blender_scene
    from lens_lights.core.lens.closed_mesh import OPEN_REASON

    set_engine("CYCLES")
    scene = bpy.context.scene
    add_sphere("Ball", (0.0, 0.0, 1.0), material=glass_material())
    bpy.ops.object.text_add(location=(3.0, 0.0, 1.0))
    text = bpy.context.object
    text.name = "Glass text"
    text.data.materials.append(glass_material("Text glass"))
    add_point_light("Lamp", (0.0, 0.0, 4.0))
    assert read_blender_scene(bpy.context).unmodelled_glass == [
        ("Glass text/Glass text", OPEN_REASON)
    ]
    level, message, figures = generate()
    assert scene.cycles.caustics_refractive is True
    assert "does not model the glass of Glass text/Glass text," in message


def test_refractive_caustics_stay_on_for_lenses_beyond_the_maximum(empty_blend, auto_builds_lights):
    set_engine("CYCLES")
    scene = bpy.context.scene
    add_sphere("Near ball", (0.0, 0.0, 1.0), material=glass_material())
    add_sphere("Far ball", (3.0, 0.0, 1.0), material=glass_material())
    add_point_light("Lamp", (0.0, 0.0, 4.0))
    scene.lens_lights.max_lights = 1  # one ball only
    level, message, figures = generate()
    assert figures["created"] == 1
    ((lit,),) = [[ob.lens_lights.source_lens for ob in lens_lights()]]
    unlit = ({"Near ball", "Far ball"} - {lit}).pop()
    assert scene.cycles.caustics_refractive is True  # the other keeps Cycles' caustic
    assert level == "WARNING"
    assert f"left on: Maximum Lens Lights left {unlit} without a lens light," in message
    scene.lens_lights.max_lights = 2
    level, message, figures = generate()
    assert figures["created"] == 2 and scene.cycles.caustics_refractive is False


def test_a_library_linked_lens_keeps_its_caster_flag_and_the_report_says_so(
    empty_blend, auto_builds_lights, tmp_path
):
    # The library: a glass marble with Cycles' shadow caustics caster on.
    add_sphere("Marble", (0.0, 0.0, 1.0), material=glass_material())
    bpy.data.objects["Marble"].cycles.is_caustics_caster = True
    library = tmp_path / "marbles.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(library))
    # The shot: the marble linked from it, a local floor and lamp.
    bpy.ops.wm.read_factory_settings(use_empty=True)
    with bpy.data.libraries.load(str(library), link=True) as (_, into):
        into.objects = ["Marble"]
    marble = into.objects[0]
    bpy.context.scene.collection.objects.link(marble)
    assert marble.library is not None and marble.cycles.is_caustics_caster is True
    bpy.ops.mesh.primitive_plane_add(size=8)
    add_point_light("Lamp", (0.0, 0.0, 4.0))
    set_engine("CYCLES")
    level, message, figures = generate()
    assert figures["created"] == 1
    # Not turned off in memory only (it would be on again in the saved file): left on, said.
    assert marble.cycles.is_caustics_caster is True
    assert level == "WARNING"
    assert "Shadow caustics caster left on for Marble: linked from a library" in message
    assert "shadow caustics caster of Marble" not in message  # not claimed off
    shot = tmp_path / "shot.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(shot))
    bpy.ops.wm.open_mainfile(filepath=str(shot))
    assert bpy.data.objects["Marble"].cycles.is_caustics_caster is True
    assert "left on for Marble" in bpy.context.scene.lens_lights.last_report


def test_a_marble_sunk_into_the_table_gets_no_lens_light_and_keeps_cycles_caustic(
    empty_blend, auto_builds_lights
):
    set_engine("CYCLES")
    scene = bpy.context.scene
    bpy.ops.mesh.primitive_plane_add(size=8)
    bpy.context.object.name = "Table"
    add_sphere("Sunk", (0.0, 0.0, 0.0), material=glass_material())  # centre on the table
    add_point_light("Lamp", (-2.0, 0.0, 2.0))  # 45°
    level, message, figures = generate()
    assert lens_lights() == [] and figures["created"] == 0
    assert "sunk into another surface" in message
    assert scene.cycles.caustics_refractive is True  # Cycles' own caustic stays
    # beside a resting marble that does get its lens light: the switch stays on, said
    add_sphere("Resting", (3.0, 0.0, 0.5), material=glass_material())
    level, message, figures = generate()
    assert [ob.lens_lights.source_lens for ob in lens_lights()] == ["Resting"]
    assert scene.cycles.caustics_refractive is True
    assert "does not model the glass of Sunk," in message and level == "WARNING"


# --------------------------------------------------------------------------- issue 28 item 7


def _object_panel(ob):
    from blender_scene_helpers import draw_panel
    from lens_lights.blender.ui.panel import VIEW3D_PT_lens_lights_object

    context = SimpleNamespace(object=ob, region=None, preferences=None)
    return [text for kind, text in draw_panel(VIEW3D_PT_lens_lights_object, context)]


def test_a_layer_and_its_fallback_spot_are_said_in_the_layers_terms(empty_blend):
    """One spot through one marble over a table with a small mirror on it (metallic:
    no layer can show a caustic there): Generate makes one layer mesh on the table
    and one fallback spot lighting the mirror, and says so; the Object panel says of
    each what it is (never "Lens: Table"); Clear says what it removed and put back."""
    set_engine("BLENDER_EEVEE")
    bpy.ops.mesh.primitive_plane_add(size=8)
    bpy.context.object.name = "Table"
    bpy.ops.mesh.primitive_plane_add(size=1, location=(0.0, 0.0, 0.01))
    mirror = bpy.context.object
    mirror.name = "Mirror"
    mirror.data.materials.append(node_material("Metal", "ShaderNodeBsdfPrincipled", Metallic=1.0))
    add_sphere("Marble", (0.0, 0.0, 1.0), material=glass_material())
    add_point_light("Lamp", (0.0, 0.0, 4.0), kind="SPOT")
    scene = bpy.context.scene
    scene.cycles.caustics_refractive = True
    level, message, figures = generate()
    made = lens_lights()
    layer = [ob for ob in made if ob.type == "MESH"]
    spot = [ob for ob in made if ob.type == "LIGHT"]
    assert len(layer) == 1 == len(spot), [ob.name for ob in made]
    assert message.startswith(
        "Created 1 caustic layer on Table and 1 fallback spot on glossy or transparent "
        "Mirror (1 light × 1 lens)"
    ), message
    assert "Fitted spot" not in message  # said once, at the start
    assert figures["created"] == 0 and figures["layers"] == 1 and figures["fallback"] == 1
    from blender_scene_helpers import draw_panel
    from lens_lights.blender.ui.panel import VIEW3D_PT_lens_lights

    main = draw_panel(VIEW3D_PT_lens_lights, SimpleNamespace(scene=bpy.context.scene, object=None))
    shown = [text for kind, text in main if kind == "label"]
    assert "Caustic layers: 1" in shown and "Fallback spots: 1" in shown
    assert "Lens lights: 0" in shown
    (layer,), (spot,) = layer, spot
    flux = layer.lens_lights.relative_brightness
    text = _object_panel(layer)
    assert text[:5] == [
        layer.name,
        "Caustic layer on: Table",
        "Lenses: Marble",
        "Lights: Lamp",
        f"Flux drawn: {flux:.3g} W",
    ], text
    assert not any(t.startswith(("Lens: ", "From: ", "Unblocked", "Model: ")) for t in text)
    text = _object_panel(spot)
    assert text[1] == "Fallback spot on: Mirror", text
    assert "Light: Lamp" in text and "Lens: Marble" in text
    assert "glossy or transparent" in " ".join(text)
    assert bpy.ops.lens_lights.clear() == {"FINISHED"}
    assert scene.lens_lights.last_report == (
        "Removed 1 caustic layer on Table and 1 fallback spot on glossy or transparent "
        "Mirror; Cycles' own caustics back as they were: refractive caustics (scene) on"
    )
    assert scene.cycles.caustics_refractive is True


def test_a_lens_lights_panel_names_its_model_by_its_label(empty_blend):
    basic_scene()
    set_engine("CYCLES")
    generate()
    (ll,) = lens_lights()
    text = _object_panel(ll)
    assert "From: Lamp" in text and "Lens: Marble" in text
    model = next(t for t in text if t.startswith("Model: "))
    assert model.startswith("Model: Exact profile (Cycles), brightness "), text


def test_the_operators_tooltips_are_true_for_both_engines(extension):
    generate_tip = bpy.ops.lens_lights.generate.get_rna_type().description
    assert "spot light" in generate_tip and "emissive meshes" in generate_tip
    assert "\n" not in generate_tip
    clear_tip = bpy.ops.lens_lights.clear.get_rna_type().description
    assert "caustic layers" in clear_tip
