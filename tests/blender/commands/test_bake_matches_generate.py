"""Bake = Generate at every frame (issue 24, item 4): a baked frame renders as Generate
renders that frame, with everything Generate's Exact profile light holds on it: the
near field's own table, the tilt correction of a receiver tilted against the lens
axis, and the shadow mask of a blocker on the caustic.

The scene: a glass marble (R = 0.5, n = 1.5) resting on a white floor, a 1000 W point
light 4 from its centre moving over frames 1–3 (elevation 62°, 65°, 68°; azimuth 0°,
6°, 12°: the floor is tilted 28°–22° against the lens axis, the receiver 1.06–1.13 R
from the centre: the near field), and an opaque ball (r = 0.15) moving with the light,
0.4 of the way to the marble and 0.25 aside, so that it shades part of the lens' cap
(the shadow list: a shadow mask). Cycles, direct light only, 32 px, 16 samples, seed 1,
an orthographic camera straight down on the caustic (the marble and the blocker
hidden from it).

Bake frames 1–3, save the .blend, and render its frame 2 in a fresh Blender process
that never loads the extension (the keys alone). Then Generate on frame 2 in this
process and render with the same seed. The two renders' lens-light parts (render minus
the render without the "Lens Lights" collection) must agree: the L1 difference at most
`L1_TOL` of the caustic's light and the total within `TOTAL_TOL` (0.1 %). Both run the
same samples (same seed, same scene) through trees that compute the same numbers in
another order (the texture read at the same texel of a tile of a stacked image, the
tilt's normal from keyed Value nodes instead of constants): what is left is float
rounding (measured: L1 4e-6, total 1 − 2e-6 on 5.2). Before this change the bake left
out the tilt correction and the mask: L1 0.26, total 1.066.

The second case (issue 24 items 2 and 4 merged): the marble lit from 44°–46°
elevation with, on frames 2–3, a wall 1.05 R from its centre across the beam (frame
1: far away): frame 2's light has two receiver planes, the table and the wall, each
corrected by its own normal where the shading point lies on it (`lights._tilted`);
the baked light's tree has two planes keyed per frame (frame 1's second: never on
the shading point, `lights.NO_PLANE`) and the green channel (intensity × slope) in
its tiles. An oblique camera sees the table and the wall. Frame 2 baked, rendered
without the extension, against Generate: the same tolerances. With the planes'
Value nodes left unkeyed (the tree's defaults: no plane matches) L1 0.21, total
1.047; with the wall's plane alone unkeyed L1 0.088, total 0.988 (measured on 5.2;
keyed: L1 3e-6, total 1 − 1e-6).
"""

import math

import bpy
import numpy as np
import pytest
from mathutils import Vector
from measuring_scene import build_measuring_scene, direct_light_only, new_material, render_grey
from stock_render import stock_render

pytestmark = pytest.mark.blender

R, N, POWER, DIST = 0.5, 1.5, 1000.0, 4.0
ELEVATIONS, AZIMUTHS = (62.0, 65.0, 68.0), (0.0, 6.0, 12.0)
BLOCKER_R, BLOCKER_AT, BLOCKER_ASIDE = 0.15, 0.4, 0.25
PX, VIEW, SAMPLES = 32, 1.6, 16
L1_TOL, TOTAL_TOL = 1e-3, 1e-3
#: The wall case: lamp elevations on frames 1–3, the wall's distance from the
#: marble's centre (R) on them (20: out of the beam's reach).
WALL_ELEVATIONS, WALL_AT = (44.0, 45.0, 46.0), (20.0, 1.05, 1.05)


def lamp_and_blocker(frame):
    """World positions of the lamp and the blocker on `frame` (1–3)."""
    e, a = (math.radians(x[frame - 1]) for x in (ELEVATIONS, AZIMUTHS))
    c = np.array([0.0, 0.0, R])
    lamp = c + DIST * np.array(
        [-math.cos(e) * math.cos(a), -math.cos(e) * math.sin(a), math.sin(e)]
    )
    aside = np.array([math.sin(a), -math.cos(a), 0.0])  # horizontal, square to the light
    return lamp, lamp + BLOCKER_AT * (c - lamp) + BLOCKER_ASIDE * aside


def build():
    built = build_measuring_scene(
        "CYCLES",
        resolution=PX,
        floor_size=8.0,
        view=VIEW,
        camera_xy=(0.35, 0.0),
        camera_height=6.0,
        ball=dict(radius=R, location=(0.0, 0.0, R), ior=N, segments=64, rings=32, name="Marble"),
        lamp=dict(location=tuple(lamp_and_blocker(1)[0]), power=POWER),
    )
    bpy.ops.mesh.primitive_uv_sphere_add(radius=BLOCKER_R, segments=32, ring_count=16)
    blocker = bpy.context.object
    blocker.name = "Blocker"
    blocker.data.materials.append(new_material("Opaque"))
    blocker.visible_camera = False
    for f in (1, 2, 3):
        lamp, block = lamp_and_blocker(f)
        built.lamp.location, blocker.location = tuple(lamp), tuple(block)
        built.lamp.keyframe_insert("location", frame=f)
        blocker.keyframe_insert("location", frame=f)
    sc = built.scene
    direct_light_only(sc, SAMPLES)
    sc.frame_start, sc.frame_end = 1, 3
    sc.lens_lights.energy_model = "EXACT_PROFILE"
    sc.frame_set(1)
    return sc


def _baked_against_generated(sc, tmp_path, frame):
    """Bake, render `frame` of the saved file without the extension, then Generate
    that frame here: (L1 of the difference over the caustic, total ratio, Generate's
    lens light, the names of the baked light's nodes)."""
    from lens_lights.blender.commands import bake
    from lens_lights.blender.commands.generate import generate

    assert bpy.ops.lens_lights.bake() == {"FINISHED"}
    assert bake.LAST_BAKE["frames"] == 3
    (ob,) = [
        o
        for o in bpy.data.objects
        if o.lens_lights.is_lens_light and not o.get("lens_lights_reflection")
    ]
    baked = {n.name for n in ob.data.node_tree.nodes}
    blend = tmp_path / "baked.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend), copy=True)
    facts, baked_img, without = stock_render(blend, tmp_path, frame)
    assert facts == dict(registered=False, operators=False)
    bpy.ops.lens_lights.clear()
    sc.frame_set(frame)
    level, message, _ = generate(bpy.context)
    assert level != "ERROR", message
    (light,) = [
        o
        for o in bpy.data.objects
        if o.lens_lights.is_lens_light and not o.get("lens_lights_reflection")
    ]
    generated = render_grey(sc, tmp_path / "generated.exr")
    caustic = generated - without
    assert caustic.sum() > 0.0
    l1 = float(np.abs(baked_img - generated).sum() / np.abs(caustic).sum())
    total = float((baked_img - without).sum() / caustic.sum())
    return l1, total, light, baked


def test_a_baked_frame_renders_as_generate_renders_it(extension, tmp_path):
    from lens_lights.blender.build.lights import TILT_NODE

    sc = build()
    l1, total, light, baked = _baked_against_generated(sc, tmp_path, 2)
    # what makes frame 2 Generate's: its tilt and its mask, keyed
    assert {TILT_NODE.format(0, "nx"), "Lens bake mask slice"} <= baked
    nt = light.data.node_tree
    # Generate's light on frame 2 has a tilt correction and a mask (else the test
    # would not test them)
    assert TILT_NODE.format(0, "nx") in nt.nodes
    assert any(n.bl_idname == "ShaderNodeTexImage" and "mask" in n.image.name for n in nt.nodes)
    assert "near field" in light.lens_lights.note
    print(f"\nbaked frame 2 against Generate: L1 {l1:.2e} of the caustic, total {total:.6f}")
    assert l1 <= L1_TOL
    assert abs(total - 1.0) <= TOTAL_TOL


def build_with_wall():
    """The marble on the floor, the lamp at `WALL_ELEVATIONS`, the wall (normal ∓x) at
    `WALL_AT` R from the marble's centre, keyed per frame; an orthographic camera
    looking down at 45° toward +x at the corner the caustic lights."""
    xw = [a * R for a in WALL_AT]
    built = build_measuring_scene(
        "CYCLES",
        resolution=PX,
        floor_size=8.0,
        view=0.8,
        camera_height=6.0,
        ball=dict(radius=R, location=(0.0, 0.0, R), ior=N, segments=64, rings=32, name="Marble"),
        lamp=dict(location=(0.0, 0.0, 4.0), power=POWER),
    )
    bpy.ops.mesh.primitive_plane_add(size=4.0, location=(xw[0], 0.0, 1.0))
    wall = bpy.context.object
    wall.name = "Wall"
    wall.rotation_euler = (0.0, math.pi / 2, 0.0)
    wall.data.materials.append(built.floor.data.materials[0])
    for f, (e, x) in enumerate(zip(WALL_ELEVATIONS, xw, strict=True), start=1):
        er = math.radians(e)
        built.lamp.location = (-DIST * math.cos(er), 0.0, R + DIST * math.sin(er))
        built.lamp.keyframe_insert("location", frame=f)
        wall.location.x = x
        wall.keyframe_insert("location", index=0, frame=f)
    target = np.array([0.4, 0.0, 0.12])
    d = np.array([1.0, 0.0, -1.0]) / math.sqrt(2.0)
    cam = built.camera
    cam.location = tuple(target - 4.0 * d)
    cam.rotation_mode = "QUATERNION"
    cam.rotation_quaternion = Vector(tuple(d)).to_track_quat("-Z", "Y")
    sc = built.scene
    direct_light_only(sc, SAMPLES)
    sc.frame_start, sc.frame_end = 1, 3
    sc.lens_lights.energy_model = "EXACT_PROFILE"
    sc.frame_set(1)
    return sc


def test_a_baked_frame_with_a_table_and_a_wall_renders_as_generate(extension, tmp_path):
    from lens_lights.blender.build.lights import TILT_NODE

    sc = build_with_wall()
    l1, total, light, baked = _baked_against_generated(sc, tmp_path, 2)
    assert TILT_NODE.format(1, "offset") in baked
    nodes = light.data.node_tree.nodes
    # Generate's light on frame 2: the near field, two planes (table and wall)
    assert "near field" in light.lens_lights.note
    assert TILT_NODE.format(1, "nx") in nodes and TILT_NODE.format(2, "nx") not in nodes
    print(f"\nwall: baked frame 2 against Generate: L1 {l1:.2e} of the caustic, total {total:.6f}")
    assert l1 <= L1_TOL
    assert abs(total - 1.0) <= TOTAL_TOL
