"""Issue 28 item 7 in Blender: a light whose emission uses nodes. An IES Texture
feeding the Emission's Strength is read (what the light sends toward each lens is
its profile there), constant node strength and colour scale the light, and a node
tree Lens Lights cannot follow leaves the light out by name, never with the full
caustic.

Expected values: the IES files are written here, their candela values known; the
Fac Cycles makes of them is candela × 4π/177.83 (its `util/ies.cpp`); the first
test checks that convention, and the light's frame, against a Cycles render of
the direct light on a floor (E = P/(4π)·Fac·cos θ/d², radiance 0.8·E/π)."""

from __future__ import annotations

import math

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from blender_scene_helpers import (  # noqa: E402
    add_point_light,
    add_sphere,
    generate,
    glass_material,
    lens_lights,
    set_engine,
)

pytestmark = [pytest.mark.blender, pytest.mark.usefixtures("auto_builds_lights")]

CANDELA_TO_FAC = 4.0 * math.pi / 177.83
V1 = math.degrees(math.atan(0.5))  # the floor point 0.5 m aside, 1 m below


def ies_text(v_angles, h_angles, candela, multiplier=1.0):
    """An LM-63 file, type C, of `candela` rows per horizontal angle."""
    rows = "\n".join(" ".join(f"{c:g}" for c in row) for row in candela)
    return (
        "IESNA:LM-63-2002\n[TEST] Lens Lights\nTILT=NONE\n"
        f"1 1000 {multiplier:g} {len(v_angles)} {len(h_angles)} 1 2 0 0 0\n"
        "1 1 100\n"
        + " ".join(f"{v:.9f}" for v in v_angles)
        + "\n"
        + " ".join(f"{h:g}" for h in h_angles)
        + f"\n{rows}\n"
    )


def light_tree(ob):
    data = ob.data
    if bpy.app.version < (5, 0, 0):
        data.use_nodes = True
    nt = data.node_tree
    return nt, next(n for n in nt.nodes if n.bl_idname == "ShaderNodeEmission")


def with_ies(ob, text, strength=1.0):
    """`ob`'s light emits through an IES Texture (an internal Text holding `text`)."""
    nt, emission = light_tree(ob)
    ies = nt.nodes.new("ShaderNodeTexIES")
    ies.mode = "INTERNAL"
    ies.ies = bpy.data.texts.new(f"{ob.name}.ies")
    ies.ies.write(text)
    ies.inputs["Strength"].default_value = strength
    nt.links.new(ies.outputs["Fac"], emission.inputs["Strength"])
    return ies


STEEP = ies_text(
    [0.0, V1, 45.0, 90.0, 180.0],
    [0.0, 90.0, 180.0, 270.0],
    [[100, 200, 50, 0, 0], [100, 400, 50, 0, 0], [100, 600, 50, 0, 0], [100, 800, 50, 0, 0]],
)


@pytest.mark.parametrize("turn", [0.0, 90.0])
def test_the_ies_profile_is_read_as_cycles_renders_it(empty_blend, turn, tmp_path):
    """A point light 1 m over a floor through an IES profile that differs in every
    horizontal plane, the light turned `turn`° about Z: the floor's radiance under
    it, at the tabulated directions and one between them, is what the profile read
    by Lens Lights says (so its units, its angles and the light's frame are
    Cycles')."""
    from lens_lights.core.scene.ies import LightProfile, light_frame, parse_ies
    from measuring_scene import build_measuring_scene, direct_light_only, render_grey

    lamp_at = np.array([0.125, 0.125, 1.0])  # the floor points below are pixel centres
    ms = build_measuring_scene(
        "CYCLES",
        resolution=32,
        floor_size=20,
        view=8.0,
        camera_height=5.0,
        lamp=dict(location=tuple(lamp_at), power=1000.0),
    )
    direct_light_only(ms.scene, 4)
    ms.scene.cycles.filter_width = 0.01  # each pixel its centre
    with_ies(ms.lamp, STEEP)
    ms.lamp.rotation_euler = (0.0, 0.0, math.radians(turn))
    bpy.context.view_layer.update()
    image = render_grey(ms.scene, str(tmp_path / "ies.exr"))
    profile = LightProfile(parse_ies(STEEP), light_frame(list(map(list, ms.lamp.matrix_world))))
    # the three planes off the 0°/360° seam at V1 and 45°, and between planes (not
    # straight down: at the pole, where h is undefined, 4.5 renders 2.6 % more)
    steps = [(2, 0), (-2, 0), (0, 2), (4, 0), (0, 4)]
    steps += [(-1, 1)] if turn else [(1, 1)]
    for k in steps:
        p = np.array([lamp_at[0] + 0.25 * k[0], lamp_at[1] + 0.25 * k[1], 0.0])
        col, row = (int(round((c + 4.0) / 0.25 - 0.5)) for c in p[:2])
        d = p - lamp_at
        dist = float(np.linalg.norm(d))
        fac = float(profile.fac_world(d))
        want = 0.8 / math.pi * 1000.0 / (4 * math.pi) * fac * (-d[2] / dist) / dist**2
        assert image[row, col] == pytest.approx(want, rel=0.01), (k, fac)
    # the values by hand at two tabulated directions (unturned: +x is the 270° plane)
    if not turn:
        assert float(profile.fac_world([0.0, 0.0, -1.0])) == pytest.approx(100 * CANDELA_TO_FAC)
        assert float(profile.fac_world([0.5, 0.0, -1.0])) == pytest.approx(800 * CANDELA_TO_FAC)


def _marble_under(lamp_kind="POINT"):
    set_engine("CYCLES")
    bpy.context.scene.lens_lights.energy_model = "FITTED"
    bpy.ops.mesh.primitive_plane_add(size=20)
    add_sphere("Marble", (0.0, 0.0, 1.0), material=glass_material())
    return add_point_light("Lamp", (0.0, 0.0, 4.0), energy=1000.0, kind=lamp_kind)


def test_an_ies_dark_downward_gives_the_marble_below_no_caustic(empty_blend):
    """The profile sends nothing within 30° of straight down, where the marble is: no
    lens light, the pair skipped as outside the light's emission (it had the full
    caustic)."""
    lamp = _marble_under()
    with_ies(lamp, ies_text([0.0, 30.0, 31.0, 90.0], [0.0], [[0, 0, 500, 500]]))
    level, message, figures = generate()
    assert lens_lights() == []
    assert figures["skipped_by_reason"] == {"outside the light's emission": 1}, message
    assert "Lamp × Marble: outside the light's emission" in message


def test_an_ies_scales_the_lens_light_by_what_it_sends_toward_the_lens(empty_blend):
    """A profile of 300 cd in every direction down to 60° (the marble is straight
    below), Strength 0.5: the lens light is the plain lamp's × 300 · 4π/177.83 · 0.5
    in energy, everything else alike."""
    lamp = _marble_under()
    generate()
    (plain,) = lens_lights()
    energy, size = plain.data.energy, plain.data.spot_size
    flat = ies_text([0.0, 45.0, 60.0, 90.0], [0.0], [[300, 300, 300, 0]])  # 300 to 60°
    with_ies(lamp, flat, strength=0.5)
    level, message, figures = generate()
    (ll,) = lens_lights()
    assert ll.data.energy == pytest.approx(energy * 300 * CANDELA_TO_FAC * 0.5, rel=1e-6)
    assert ll.data.spot_size == pytest.approx(size, rel=1e-9)
    assert "light nodes" not in message


def test_constant_node_strength_and_colour_scale_the_lens_light(empty_blend):
    lamp = _marble_under()
    generate()
    (plain,) = lens_lights()
    energy, color = plain.data.energy, tuple(plain.data.color)
    nt, emission = light_tree(lamp)
    emission.inputs["Strength"].default_value = 2.0
    emission.inputs["Color"].default_value = (1.0, 0.5, 0.25, 1.0)
    level, message, figures = generate()
    (ll,) = lens_lights()
    # the colour's brightness goes into the colour, its strength into the energy
    got = np.array(ll.data.color) * ll.data.energy
    want = np.array(color) * np.array([1.0, 0.5, 0.25]) * energy * 2.0
    assert got == pytest.approx(want, rel=1e-5)


def test_light_nodes_it_cannot_read_leave_the_light_out_by_name(empty_blend):
    """A Noise Texture drives the Emission's strength: Lens Lights cannot know what
    it sends toward the marble, so it leaves the lamp out and says so by name."""
    lamp = _marble_under()
    nt, emission = light_tree(lamp)
    noise = nt.nodes.new("ShaderNodeTexNoise")
    nt.links.new(noise.outputs["Fac"], emission.inputs["Strength"])
    level, message, figures = generate()
    assert lens_lights() == []
    assert "Lamp: its emission uses nodes Lens Lights cannot read" in message
    assert figures["light_notes"] == [("Lamp", "its emission uses nodes Lens Lights cannot read")]


def test_an_ies_file_that_cannot_be_read_leaves_the_light_out(empty_blend):
    lamp = _marble_under()
    ies = with_ies(lamp, STEEP)
    ies.mode = "EXTERNAL"
    ies.filepath = "//no such profile.ies"
    level, message, figures = generate()
    assert lens_lights() == []
    ((name, why),) = figures["light_notes"]
    assert name == "Lamp" and why.startswith("its IES file cannot be read (//no such profile.ies")


def test_eevee_renders_the_lamp_without_its_nodes_and_the_caustic_follows_it(empty_blend):
    """EEVEE does not evaluate light node trees (its lamp with an IES dark downward
    still lights the floor below): the caustic follows the lamp as EEVEE renders it,
    and the report says why (a Fitted lens light, as the plain lamp's)."""
    lamp = _marble_under()
    generate()
    (plain,) = lens_lights()
    energy = plain.data.energy
    set_engine("BLENDER_EEVEE")
    with_ies(lamp, ies_text([0.0, 30.0, 31.0, 90.0], [0.0], [[0, 0, 500, 500]]))
    level, message, figures = generate()
    (ll,) = lens_lights()
    assert ll.data.energy == pytest.approx(energy, rel=1e-6)
    ((name, why),) = figures["light_notes"]
    assert name == "Lamp" and why.startswith("its light nodes: the render engine (EEVEE)")
