"""Light linking within Blender's limits (issue 24): more than 63 resting marbles,
each lens light inside its marble, still excluded from its own lens, in at most 63
linking collections; Blender's own console line about its limits is caught; and in
Cycles every marble's caustic is there (before, the lenses beyond Blender's 64 sets
shadowed their lights: no caustic at all)."""

import math

import bpy
import numpy as np
import pytest
from blender_scene_helpers import add_point_light, add_sphere, generate, glass_material, lens_lights

pytestmark = [pytest.mark.blender, pytest.mark.usefixtures("auto_builds_lights")]

R = 0.01  # 2 cm marbles
SPACING = 0.03
COLS, ROWS = 9, 8  # 72 marbles


def marbles():
    glass = glass_material()
    out = []
    for k in range(COLS * ROWS):
        x = (k % COLS - (COLS - 1) / 2) * SPACING
        y = (k // COLS - (ROWS - 1) / 2) * SPACING
        out.append(add_sphere(f"Marble {k:02d}", (x, y, R), radius=R, material=glass))
    bpy.ops.mesh.primitive_plane_add(size=2.0)
    bpy.context.object.name = "Table"
    sun = add_point_light("Sun", (0, 0, 1), energy=3.0, kind="SUN")  # straight down
    sun.data.angle = math.radians(0.5)
    bpy.context.scene.lens_lights.max_lights = 1000
    return out


def test_72_resting_marbles_each_light_excludes_its_lens_within_blenders_limits(empty_blend):
    from lens_lights.blender.build.lights import linking_messages
    from lens_lights.blender.build.marks import COLLECTION_MARK, LINK_MARK

    balls = marbles()
    level, message, figures = generate()
    made = lens_lights()
    assert len(made) == len(balls)
    links = {
        c.name
        for c in bpy.data.collections
        if c.get(COLLECTION_MARK) == LINK_MARK and c.name.startswith("Lens link")
    }
    assert 1 <= len(links) <= 63
    for ob in made:
        lens = bpy.data.objects[ob.lens_lights.source_lens]
        # the light sits inside its marble (its centre: the near field)
        assert (ob.location - lens.location).length < R
        coll = ob.light_linking.receiver_collection
        assert coll is not None and ob.light_linking.blocker_collection == coll
        states = {
            o.name: m.light_linking.link_state
            for o, m in zip(coll.objects, coll.collection_objects, strict=True)
        }
        assert states.get(lens.name) == "EXCLUDE"
    assert figures["linking"]["ungrouped"] == [] and figures["linking"]["conflicts"] == []
    assert figures["linking"]["blender_says"] == []
    assert "light-linking" not in message and "Blender says" not in message
    # what Blender prints past its limit is caught: one collection per lens, the old way
    for k, ball in enumerate(balls):
        coll = bpy.data.collections.new(f"per lens {k}")
        coll.objects.link(ball)
        made[k].light_linking.receiver_collection = coll
    said = linking_messages(bpy.context)
    assert any("Maximum number of light linking" in line for line in said), said


def test_the_users_own_linking_counts_against_the_budget(empty_blend):
    from lens_lights.blender.build.lights import user_linking

    balls = marbles()
    lamp = add_point_light("Rim", (0.5, 0, 0.5), energy=10.0)
    mine = bpy.data.collections.new("My linking")
    mine.objects.link(balls[0])
    lamp.light_linking.receiver_collection = mine
    lamp.light_linking.blocker_collection = mine
    colls, sets, signature = user_linking(bpy.context.scene)
    assert (colls, sets) == (1, 1) and balls[0].as_pointer() in signature
    level, message, figures = generate()
    assert figures["linking"]["user_sets"] == 1
    assert figures["linking"]["budget"] <= 62
    assert lamp.light_linking.receiver_collection == mine  # the user's untouched


def _render(scene, path):
    scene.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)
    img = bpy.data.images.load(str(path))
    w, h = img.size
    px = np.array(img.pixels[:], dtype=float).reshape(h, w, 4)[..., :3].mean(axis=2)
    bpy.data.images.remove(img)
    return px


def test_cycles_every_marble_beyond_the_64th_throws_its_caustic(empty_blend, tmp_path):
    """72 marbles, Cycles 96 px, 64 samples of direct light: the caustic (render with
    lens lights minus without; the sun 20° wide, so that pixels see the caustic)
    summed over each marble's footprint (within R of its contact point) is there for
    every marble, the median near the flux a marble catches (before: the lenses past
    Blender's 64 sets shadowed their lights: exactly none)."""
    from measuring_scene import direct_light_only  # (scripts/ on the path)

    balls = marbles()
    sc = bpy.context.scene
    sc.render.engine = "CYCLES"
    direct_light_only(sc, 64)
    bpy.data.objects["Sun"].data.angle = math.radians(20.0)  # a caustic pixels can see
    sc.render.resolution_x = sc.render.resolution_y = 96
    sc.render.image_settings.file_format = "OPEN_EXR"
    sc.view_settings.view_transform = "Standard"
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    sc.collection.objects.link(cam)
    cam.data.type = "ORTHO"
    cam.data.ortho_scale = COLS * SPACING
    cam.location = (0, 0, 0.5)
    sc.camera = cam
    for ball in balls:  # the camera sees the table through them
        ball.visible_camera = False
    base = _render(sc, tmp_path / "base.exr")
    level, message, figures = generate()
    assert figures["created"] == len(balls)
    lit = _render(sc, tmp_path / "lit.exr")
    caustic = lit - base
    size = COLS * SPACING / 96  # metres per pixel
    ys, xs = np.mgrid[0:96, 0:96]
    x = (xs + 0.5) * size - COLS * SPACING / 2
    y = (ys + 0.5) * size - COLS * SPACING / 2
    # (row 0 is the bottom: world −y; the camera's up is +y)
    flux = []
    for ball in balls:
        near = (x - ball.location.x) ** 2 + (y - ball.location.y) ** 2 < R * R
        flux.append(float(caustic[near].sum()))
    # in watts: a pixel is albedo·E/π (the plane's default albedo 0.8)
    flux = np.array(flux) * size * size * math.pi / 0.8
    # the sun's 3 W/m² on a marble's disc, less ~8 % Fresnel loss: 0.87 mW
    expected = 3.0 * math.pi * R * R * 0.92
    ratio = flux / expected
    # 64 samples leave the tiny caustics noisy (0.1–3 of the truth per marble, the
    # median near 1); a lens shadowing its own light gives exactly 0
    assert ratio.min() > 0.05, np.round(ratio, 2)
    assert 0.5 < float(np.median(ratio)) < 2.0, np.round(ratio, 2)
