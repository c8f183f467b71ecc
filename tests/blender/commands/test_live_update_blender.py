"""Live update and the quiet probe (bpy module): lens lights follow an animated light
on frame_set, objects are kept, an animation render completes, and Generate fires
none of the user's render / frame-change handlers."""

import math

import bpy
import pytest
from blender_scene_helpers import basic_scene, caustic_layers, generate, lens_lights, set_engine
from mathutils import Vector

from core.lens import ball_optics

pytestmark = [pytest.mark.blender, pytest.mark.usefixtures("auto_builds_lights")]

R, N = 0.5, 1.5
CENTRE = (0.0, 0.0, 2.5)
#: The lamp's keyed positions (frames 1 and 5; linear in between).
KEYS = {1: (0.0, 0.0, 4.5), 5: (0.8, 0.4, 4.3)}
HANDLER_LISTS = (
    "render_init",
    "render_pre",
    "render_post",
    "render_stats",
    "render_write",
    "render_complete",
    "render_cancel",
    "frame_change_pre",
    "frame_change_post",
)


def _animated_scene():
    sphere, lamp = basic_scene()
    lamp.data.shadow_soft_size = 0.0
    for frame, loc in KEYS.items():
        lamp.location = loc
        lamp.keyframe_insert("location", frame=frame)
    scene = bpy.context.scene
    scene.lens_lights.energy_model = "PHYSICAL"
    scene.frame_start, scene.frame_end = 1, 5
    return sphere, lamp


def _lamp_at(lamp, frame):
    bpy.context.scene.frame_set(frame)
    return tuple(lamp.matrix_world.translation)


def _exact(lamp_pos):
    """The paraxial image point and the spot's power for a point lamp of 1000 W,
    from the exact optics (SPEC §6), independently of the tiers."""
    d = [c - p for c, p in zip(CENTRE, lamp_pos, strict=True)]
    D = math.sqrt(sum(x * x for x in d))
    axis = [x / D for x in d]
    s = ball_optics.paraxial_image_distance(D, R, N)
    image = tuple(c + a * s for c, a in zip(CENTRE, axis, strict=True))
    power = 4 * math.pi * ball_optics.on_axis_intensity(1000.0 / (4 * math.pi), D, R, N)
    return image, power


def _state():
    (ll,) = lens_lights()
    return ll.as_pointer(), ll.name, tuple(ll.location), ll.data.energy


def test_frame_set_follows_an_animated_light_in_place(empty_blend):
    _, lamp = _animated_scene()
    scene = bpy.context.scene
    scene.frame_set(1)
    scene.lens_lights.live_update = True  # turned on: the lights are made at once
    live = {}
    for k in (1, 3, 5, 2):
        scene.frame_set(k)
        live[k] = _state()
    pointers = {v[0] for v in live.values()}
    names = {v[1] for v in live.values()}
    assert len(pointers) == 1 and len(names) == 1  # one object, kept across frames
    assert live[1][2] != pytest.approx(live[5][2], abs=1e-3)  # it did move
    scene.lens_lights.live_update = False
    for k, (_, _, loc, energy) in live.items():
        image, power = _exact(_lamp_at(lamp, k))
        assert loc == pytest.approx(image, abs=1e-4)
        assert energy == pytest.approx(power, rel=1e-4)
        level, message, _ = generate()  # a fresh Generate at frame k: the same light
        assert level == "INFO", message
        _, _, g_loc, g_energy = _state()
        assert loc == pytest.approx(g_loc, abs=1e-5)
        assert energy == pytest.approx(g_energy, rel=1e-5)


def _profile_images():
    return sorted(i.name for i in bpy.data.images if i.get("lens_lights_created") == "profile")


def test_exact_profile_follows_with_one_image_per_frame_at_most(empty_blend):
    _, lamp = _animated_scene()
    scene = bpy.context.scene
    set_engine("CYCLES")
    scene.lens_lights.energy_model = "EXACT_PROFILE"
    scene.frame_set(1)
    scene.lens_lights.live_update = True
    (ll,) = lens_lights()
    pointer, images_1 = ll.as_pointer(), _profile_images()
    scene.frame_set(5)
    (ll5,) = lens_lights()
    live = (tuple(ll5.location), ll5.data.energy, _profile_images())
    assert ll5.as_pointer() == pointer and ll5.lens_lights.energy_model == "EXACT_PROFILE"
    assert len(live[2]) == 1 and live[2] != images_1  # D/R changed: the old image is gone
    tex = [n for n in ll5.data.node_tree.nodes if n.type == "TEX_IMAGE"]
    assert [n.image.name for n in tex] == live[2]
    scene.lens_lights.live_update = False
    generate()  # a fresh Generate at frame 5
    (g,) = lens_lights()
    assert live[0] == pytest.approx(tuple(g.location), abs=1e-5)
    assert live[1] == pytest.approx(g.data.energy, rel=1e-5)
    assert live[2] == _profile_images()


def test_caustic_layer_is_rebuilt_on_frame_change(empty_blend):
    _, lamp = _animated_scene()
    scene = bpy.context.scene
    set_engine("BLENDER_EEVEE")
    scene.lens_lights.energy_model = "CAUSTIC_LAYER"
    scene.frame_set(1)
    scene.lens_lights.live_update = True

    def centroid():
        (ob,) = caustic_layers()
        xs = [v.co.x for v in ob.data.vertices]
        return sum(xs) / len(xs)

    x1 = centroid()
    scene.frame_set(5)
    x5 = centroid()
    # The lamp moved +0.8 in x: the caustic under the ball moves the other way.
    assert x1 == pytest.approx(0.0, abs=0.02) and x5 < x1 - 0.1
    assert len(lens_lights()) == 1


def test_unchanged_frames_are_not_replanned_and_clear_stops_live_update(empty_blend):
    _animated_scene()
    from lens_lights.blender.commands import live_update

    scene = bpy.context.scene
    scene.frame_set(5)
    scene.lens_lights.live_update = True
    state = _state()
    scene.frame_set(7)  # past the last key: the same scene
    assert live_update.LAST_FIGURES.get("skipped") is True
    assert _state() == state
    scene.frame_set(3)
    assert not live_update.LAST_FIGURES.get("skipped") and _state()[2] != state[2]
    assert bpy.ops.lens_lights.clear() == {"FINISHED"}
    assert not scene.lens_lights.live_update and lens_lights() == []
    scene.frame_set(4)
    assert lens_lights() == []


def test_generate_with_live_update_on_then_frames_reuse_its_lights(empty_blend):
    _, lamp = _animated_scene()
    scene = bpy.context.scene
    scene.frame_set(2)
    scene.lens_lights.live_update = True
    level, message, _ = generate()  # probe render with our handlers detached
    assert level == "INFO", message
    assert [s.name for s in bpy.data.scenes] == ["Scene"]  # the probe's copy is gone
    pointer = _state()[0]
    scene.frame_set(4)
    (ll,) = lens_lights()
    assert ll.as_pointer() == pointer
    assert tuple(ll.location) == pytest.approx(_exact(_lamp_at(lamp, 4))[0], abs=1e-4)


def test_updates_of_its_own_lights_do_not_run_live_update(empty_blend):
    _animated_scene()
    from lens_lights.blender.commands import live_update

    scene = bpy.context.scene
    scene.lens_lights.live_update = True
    (ll,) = lens_lights()
    before = live_update.LAST_FIGURES
    ll.location.x += 1.0  # only ours changed: ignored (no feedback loop)
    ll.data.energy *= 2.0
    bpy.context.view_layer.update()
    assert live_update.LAST_FIGURES is before
    bpy.data.objects["Floor"].location.z = 0.1  # a receiver moved: an update
    bpy.context.view_layer.update()
    assert live_update.LAST_FIGURES is not before
    assert live_update.LAST_FIGURES["why"] == "edit"


def test_moving_the_lamp_updates_on_depsgraph_update(empty_blend):
    _, lamp = _animated_scene()
    lamp.animation_data_clear()
    lamp.location = (0.3, 0.0, 4.5)
    scene = bpy.context.scene
    scene.lens_lights.live_update = True
    before = _state()
    lamp.location = (-0.4, 0.2, 4.4)
    bpy.context.view_layer.update()  # runs depsgraph_update_post
    after = _state()
    assert after[0] == before[0]
    image, power = _exact((-0.4, 0.2, 4.4))
    assert after[2] == pytest.approx(image, abs=1e-4)
    assert after[3] == pytest.approx(power, rel=1e-4)


def test_a_light_that_stops_reaching_the_lens_is_removed_and_comes_back(empty_blend):
    _, lamp = _animated_scene()
    lamp.animation_data_clear()
    scene = bpy.context.scene
    scene.lens_lights.live_update = True
    assert len(lens_lights()) == 1
    lamp.data.energy = 0.0  # no power: no lens light
    bpy.context.view_layer.update()
    assert lens_lights() == []
    assert not [c for c in bpy.data.collections if c.name.startswith("Lens link: ")]
    lamp.data.energy = 1000.0
    bpy.context.view_layer.update()
    (ll,) = lens_lights()
    # its image point lies beyond the marble's back pole and the spot aims away from
    # the marble (wholly behind the cone's apex): the light cannot reach its lens, so
    # it needs no linking (core/plan/linking.py), and no linking collection is left
    marble = bpy.data.objects["Marble"]
    to_centre = marble.matrix_world.translation - ll.matrix_world.translation
    axis = ll.matrix_world.to_quaternion() @ Vector((0.0, 0.0, -1.0))
    assert to_centre.length > R + ll.data.shadow_soft_size
    assert to_centre.dot(axis) < -(R + ll.data.shadow_soft_size)
    assert ll.light_linking.receiver_collection is None
    assert not [c for c in bpy.data.collections if c.name.startswith("Lens link: ")]


def test_animation_render_completes_with_live_update(empty_blend, tmp_path):
    _, lamp = _animated_scene()
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.samples = 1
    scene.cycles.device = "CPU"
    scene.render.resolution_x = scene.render.resolution_y = 8
    scene.frame_start, scene.frame_end = 3, 5
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    scene.collection.objects.link(cam)
    scene.camera = cam
    cam.location = (0.0, -8.0, 2.0)
    cam.rotation_euler = (math.radians(90), 0.0, 0.0)
    scene.render.filepath = str(tmp_path / "frame_")
    scene.frame_set(1)
    scene.lens_lights.live_update = True
    seen = []

    def engine_view(scene, depsgraph):  # after ours (appended later): what the frame renders
        if depsgraph.mode == "RENDER":
            (ll,) = lens_lights()
            seen.append((scene.frame_current, ll.as_pointer(), tuple(ll.location)))

    bpy.app.handlers.frame_change_post.append(engine_view)
    try:
        bpy.ops.render.render(animation=True)
    finally:
        bpy.app.handlers.frame_change_post.remove(engine_view)
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "frame_0003.png",
        "frame_0004.png",
        "frame_0005.png",
    ]
    assert [f for f, _, _ in seen] == [3, 4, 5]
    assert len({p for _, p, _ in seen}) == 1
    for frame, _, loc in seen:
        image, _ = _exact(_lamp_at(lamp, frame))
        assert loc == pytest.approx(image, abs=1e-4)


def test_a_users_frame_change_handler_that_generates_does_not_recurse(empty_blend, tmp_path):
    _animated_scene()
    scene = bpy.context.scene
    calls = []

    def regenerate(scene, *args):
        level, message, _ = generate()
        calls.append((scene.frame_current, level, "read as the viewport" in message))

    bpy.app.handlers.frame_change_pre.append(regenerate)
    try:
        scene.frame_set(2)
        scene.frame_set(4)
        assert calls == [(2, "INFO", False), (4, "INFO", False)]  # once each: no recursion
        # Inside an animation render the probe refuses (a render inside a render
        # crashes Blender): Generate reads the viewport, and the render completes.
        scene.render.engine = "CYCLES"
        scene.cycles.samples = 1
        scene.render.resolution_x = scene.render.resolution_y = 8
        cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
        scene.collection.objects.link(cam)
        scene.camera = cam
        scene.frame_start, scene.frame_end = 2, 3
        scene.render.filepath = str(tmp_path / "frame_")
        del calls[:]
        bpy.ops.render.render(animation=True)
    finally:
        bpy.app.handlers.frame_change_pre.remove(regenerate)
    assert [c for c in calls if c[0] in (2, 3)][:2] == [(2, "INFO", True), (3, "INFO", True)]
    assert len(list(tmp_path.iterdir())) == 2
    assert len(lens_lights()) == 1


def test_generate_fires_no_user_render_or_frame_handler(empty_blend):
    basic_scene()
    calls = []

    def make(name):
        def handler(*args):
            calls.append(name)

        handler.__name__ = f"user_{name}"
        return handler

    @bpy.app.handlers.persistent
    def persistent_pre(*args):
        calls.append("persistent render_pre")

    added = {name: make(name) for name in HANDLER_LISTS}
    before = {name: list(getattr(bpy.app.handlers, name)) for name in HANDLER_LISTS}
    for name, fn in added.items():
        getattr(bpy.app.handlers, name).append(fn)
    bpy.app.handlers.render_pre.insert(0, persistent_pre)
    try:
        from lens_lights.blender.read.render_probe import rendered_depsgraph

        mode, how = rendered_depsgraph(bpy.context, lambda dg: dg.mode)
        assert (mode, how) == ("RENDER", "render")  # the probe did render
        level, message, _ = generate()
        assert level == "INFO", message
        with pytest.raises(ZeroDivisionError):  # an error inside: still put back
            rendered_depsgraph(bpy.context, lambda dg: 1 / 0)
        assert calls == []
        for name in HANDLER_LISTS:
            expected = before[name] + [added[name]]
            if name == "render_pre":
                expected = [persistent_pre] + expected
            assert list(getattr(bpy.app.handlers, name)) == expected, name
    finally:
        for name, fn in added.items():
            getattr(bpy.app.handlers, name).remove(fn)
        bpy.app.handlers.render_pre.remove(persistent_pre)


def test_lights_made_and_removed_during_an_animation_render(empty_blend, tmp_path):
    _, lamp = _animated_scene()
    lamp.animation_data_clear()
    lamp.location = KEYS[1]
    for frame, energy in ((3, 0.0), (4, 1000.0), (6, 0.0)):
        lamp.data.energy = energy
        lamp.data.keyframe_insert("energy", frame=frame)
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.samples = 1
    scene.render.resolution_x = scene.render.resolution_y = 8
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    scene.collection.objects.link(cam)
    scene.camera = cam
    scene.frame_start, scene.frame_end = 3, 6
    scene.render.filepath = str(tmp_path / "frame_")
    scene.frame_set(3)
    scene.lens_lights.live_update = True
    seen = []

    def engine_view(scene, depsgraph):
        if depsgraph.mode == "RENDER":
            watts = lamp.data.evaluated_get(depsgraph).energy
            seen.append((scene.frame_current, watts, [o.data.energy for o in lens_lights()]))

    bpy.app.handlers.frame_change_post.append(engine_view)
    try:
        bpy.ops.render.render(animation=True)
    finally:
        bpy.app.handlers.frame_change_post.remove(engine_view)
    assert [f for f, _, _ in seen] == [3, 4, 5, 6]
    _, per_watt = _exact(KEYS[1])  # lamp 2 above the centre: power per 1000 W
    for frame, watts, energies in seen:
        if frame in (3, 6):
            assert energies == []  # no power: no lens light
        else:
            assert energies == [pytest.approx(per_watt * watts / 1000.0, rel=1e-4)]
    assert len(list(tmp_path.iterdir())) == 4
