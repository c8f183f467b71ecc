"""The pure `.bi` ↔ Blender conversions (no bpy): camera, lights, materials."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from core.bi import conversions as conv
from core.scene.model import Camera, Surface

# --------------------------------------------------------------------------- lights


def test_brightness_watts_rule():
    assert conv.WATTS_PER_BRIGHTNESS == 10_000.0
    assert conv.watts_from_brightness(1) == 10_000.0
    assert conv.watts_from_brightness(0.25) == 2_500.0
    assert conv.brightness_from_watts(10_000.0) == 1.0
    for b in (0.0, 1e-6, 0.7, 3.0, 1e6):
        assert conv.brightness_from_watts(conv.watts_from_brightness(b)) == pytest.approx(
            b, rel=1e-15
        )


def test_brightness_rule_exposure():
    """The documented meaning: brightness 1 lights a white matte surface facing it
    to pixel value 1 at sqrt(W)/(2π) ≈ 15.9 units (Blender: P / (4π² d²))."""
    d = math.sqrt(conv.WATTS_PER_BRIGHTNESS) / (2 * math.pi)
    assert d == pytest.approx(15.915, abs=1e-3)
    assert conv.watts_from_brightness(1) / (4 * math.pi**2 * d**2) == pytest.approx(1.0)


# --------------------------------------------------------------------------- camera


def test_lens_from_fov():
    lens, sensor = conv.lens_from_fov(90.0)
    assert sensor == 36.0 and lens == pytest.approx(18.0)
    lens, sensor = conv.lens_from_fov(45.0)
    assert lens == pytest.approx(18.0 / math.tan(math.radians(22.5)))
    # very wide: Blender's 1 mm minimum focal length, a wider sensor instead
    lens, sensor = conv.lens_from_fov(179.0)
    assert lens == 1.0
    assert sensor == pytest.approx(2 * math.tan(math.radians(89.5)))


def test_pixel_aspect_square_and_matching():
    assert conv.pixel_aspect_from_fov(45, 45, 200, 200) == (1.0, 1.0)
    # angles that match a 2:1 image need square pixels
    v = math.degrees(2 * math.atan(math.tan(math.radians(30)) / 2))
    assert conv.pixel_aspect_from_fov(60, v, 400, 200) == pytest.approx((1.0, 1.0))
    # a square image spanning 60° × 30°: pixels wider than high
    pax, pay = conv.pixel_aspect_from_fov(60, 30, 200, 200)
    assert pay == 1.0 and pax == pytest.approx(
        math.tan(math.radians(30)) / math.tan(math.radians(15))
    )


def test_pixel_aspect_out_of_blender_range():
    with pytest.raises(conv.BlenderLimitError) as info:
        conv.pixel_aspect_from_fov(179, 1, 200, 200)
    assert info.value.record == "B" and "pixel aspect" in str(info.value)


def test_resolution_out_of_blender_range():
    cam = Camera()
    for w, h in ((3, 200), (200, 2), (70000, 10)):
        with pytest.raises(conv.BlenderLimitError) as info:
            conv.camera_to_blender(cam, w, h)
        assert info.value.record == "V"


@settings(max_examples=200, deadline=None)
@given(
    h=st.floats(0.5, 175), v=st.floats(0.5, 175), w=st.integers(4, 4000), hh=st.integers(4, 4000)
)
def test_fov_round_trip(h, v, w, hh):
    """Opening angles → lens, sensor, pixel aspect → Blender's own sensor-fit rule
    gives the angles back."""
    try:
        pax, pay = conv.pixel_aspect_from_fov(h, v, w, hh)
    except conv.BlenderLimitError:
        return
    lens, sensor = conv.lens_from_fov(h)
    got = conv.fov_from_blender(lens, sensor, 24.0, "HORIZONTAL", w, hh, pax, pay)
    assert got == pytest.approx((h, v), rel=1e-9, abs=1e-9)


def test_fov_from_blender_sensor_fits():
    t = 36.0 / (2 * 50.0)
    # AUTO, landscape: sensor_width spans the width
    h, v = conv.fov_from_blender(50, 36, 24, "AUTO", 400, 200)
    assert math.tan(math.radians(h) / 2) == pytest.approx(t)
    assert math.tan(math.radians(v) / 2) == pytest.approx(t / 2)
    # AUTO, portrait: sensor_width spans the height
    h, v = conv.fov_from_blender(50, 36, 24, "AUTO", 200, 400)
    assert math.tan(math.radians(v) / 2) == pytest.approx(t)
    assert math.tan(math.radians(h) / 2) == pytest.approx(t / 2)
    # VERTICAL: sensor_height spans the height
    h, v = conv.fov_from_blender(50, 36, 24, "VERTICAL", 400, 200)
    assert math.tan(math.radians(v) / 2) == pytest.approx(24 / 100)
    assert math.tan(math.radians(h) / 2) == pytest.approx(2 * 24 / 100)
    # pixel aspect: pixels twice as high as wide make the same image taller
    h, v = conv.fov_from_blender(50, 36, 24, "HORIZONTAL", 200, 200, 1.0, 2.0)
    assert math.tan(math.radians(v) / 2) == pytest.approx(2 * t)


def test_look_at_basis():
    rot, parallel = conv.look_at((0, 0, 10), (1, 1, -1), (0, 1, 0))
    assert not parallel
    assert np.allclose(rot.T @ rot, np.eye(3)) and np.linalg.det(rot) == pytest.approx(1)
    forward = np.subtract((1, 1, -1), (0, 0, 10))
    forward = forward / np.linalg.norm(forward)
    assert np.allclose(-rot[:, 2], forward)  # looks along −Z
    up = rot[:, 1]
    assert up @ (0, 1, 0) > 0
    # up lies in the plane of U and the view direction
    assert abs(np.linalg.det(np.column_stack([up, forward, (0, 1, 0)]))) < 1e-12
    assert rot[:, 0] @ (0, 1, 0) == pytest.approx(0, abs=1e-12)  # no roll


def test_look_at_parallel_up_falls_back():
    rot, parallel = conv.look_at((0, 0, 0), (0, 5, 0), (0, 1, 0))
    assert parallel
    assert np.allclose(-rot[:, 2], (0, 1, 0))
    assert np.allclose(rot.T @ rot, np.eye(3))
    with pytest.raises(ValueError):
        conv.look_at((1, 2, 3), (1, 2, 3), (0, 1, 0))


@settings(max_examples=100, deadline=None)
@given(st.lists(st.floats(-100, 100), min_size=9, max_size=9))
def test_camera_round_trip_same_view(values):
    pos, target, up = np.array(values).reshape(3, 3)
    d = np.linalg.norm(target - pos)
    if d < 1e-3 or np.linalg.norm(up) < 1e-3:
        return
    forward = (target - pos) / d
    if np.linalg.norm(np.cross(up / np.linalg.norm(up), forward)) < 1e-3:
        return
    cam = Camera(position=tuple(pos), target=tuple(target), up=tuple(up), fov_deg=(40, 30))
    bc = conv.camera_to_blender(cam, 320, 240)
    back = conv.camera_from_blender(pos, bc.rotation, bc.focus_distance, cam.fov_deg)
    assert np.allclose(back.target, target, atol=1e-9 * max(1, d))
    assert conv.same_view(cam, back, 1e-9)
    # the effective up is the file's up made perpendicular to the view
    u = up - forward * (up @ forward)
    assert np.allclose(back.up, u / np.linalg.norm(u), atol=1e-9)


def test_same_view_detects_changes():
    a = Camera(position=(0, 0, 10), target=(1, 1, -1), up=(0, 1, 0))
    b = Camera(position=(0, 0, 10), target=(2, 2, -12), up=(0.7, 3.7, -7.7))  # 3U + 0.7 view: same
    assert conv.same_view(a, b)
    assert not conv.same_view(a, Camera(position=(0, 0, 10.01), target=(1, 1, -1)))
    assert not conv.same_view(a, Camera(position=(0, 0, 10), target=(1, 1.01, -1)))
    assert not conv.same_view(a, Camera(position=(0, 0, 10), target=(1, 1, -1), up=(1, 1, 0)))


# --------------------------------------------------------------------------- materials


def is_lens(surface):
    return surface.transmission > 0 and surface.ior > 1


THESIS_SURFACES = [
    # fig1 lens, fig1 red sphere, fig2 lens, fig2 mirror, fig3 obstacle, fig3 lens
    Surface((100 / 255, 10 / 255, 10 / 255), 0.1, 0.2, 0.0, 0.7, 80, 1.5171),
    Surface((250 / 255, 0, 0), 0.1, 0.9, 0.0, 0.0, 70, 1.0),
    Surface((10 / 255, 0, 100 / 255), 0.03, 0.02, 0.35, 0.6, 80, 1.5),
    Surface((0, 0, 100 / 255), 0.2, 0.0, 0.8, 0.0, 70, 1.0),
    Surface((0, 0, 0), 0.2, 0.4, 0.4, 0.0, 80, 1.0),
    Surface((100 / 255,) * 3, 0.1, 0.0, 0.4, 0.6, 80, 1.5),
]


def test_principled_mapping_table():
    glass = conv.principled_from_surface(THESIS_SURFACES[0])
    # glass refracts untinted (white Base Color); its colour is the viewport colour
    assert glass == {
        "Base Color": (1.0, 1.0, 1.0, 1.0),
        "Metallic": 0.0,
        "Roughness": 0.0,
        "IOR": 1.5171,
        "Transmission Weight": 0.7,
    }
    assert conv.viewport_color(THESIS_SURFACES[0]) == (100 / 255, 10 / 255, 10 / 255, 1.0)
    red = conv.principled_from_surface(THESIS_SURFACES[1])
    assert red["Metallic"] == 0.0 and red["Transmission Weight"] == 0.0
    assert red["Base Color"] == (250 / 255, 0, 0, 1.0)
    assert red["Roughness"] == pytest.approx(math.sqrt(2 / 72))
    assert red["IOR"] == conv.OPAQUE_IOR
    mirror = conv.principled_from_surface(THESIS_SURFACES[3])
    assert mirror["Metallic"] == 1.0  # kd 0, ks 0.8: a metal
    half = conv.principled_from_surface(THESIS_SURFACES[4])
    assert half["Metallic"] == 0.5
    dull = conv.principled_from_surface(Surface(diffuse=0, specular=0, exponent=0))
    assert dull["Metallic"] == 0.0 and dull["Roughness"] == 1.0


@pytest.mark.parametrize("surface", THESIS_SURFACES)
def test_principled_inverse_keeps_what_phase1_uses(surface):
    back = conv.surface_from_principled(
        conv.principled_from_surface(surface), conv.viewport_color(surface)
    )
    assert back.transmission == surface.transmission
    assert back.color == pytest.approx(surface.color)
    if surface.transmission > 0:
        assert back.ior == surface.ior
        assert back.diffuse + back.specular == pytest.approx(1 - surface.transmission)
    else:
        assert back.ior == 1.0
        assert back.exponent == pytest.approx(surface.exponent)
        if surface.diffuse + surface.specular > 0:
            ratio = surface.specular / (surface.diffuse + surface.specular)
            assert back.specular / (back.diffuse + back.specular) == pytest.approx(ratio)
    assert is_lens(back) == is_lens(surface)


def test_surface_from_foreign_principled():
    """A material not made by the importer: Blender's default, a glass."""
    default = conv.surface_from_principled({})
    assert default.transmission == 0.0 and default.color == pytest.approx((0.8,) * 3)
    assert default.exponent == pytest.approx(2 / 0.25 - 2)
    glass = conv.surface_from_principled(
        {"Transmission Weight": 1.0, "IOR": 1.45, "Roughness": 0.0, "Metallic": 0.3}
    )
    assert is_lens(glass) and glass.ior == 1.45 and glass.exponent == conv.GLASS_EXPONENT
    mirror = conv.surface_from_principled({"Roughness": 0.0, "Metallic": 1.0})
    assert mirror.exponent == conv.MAX_EXPONENT and mirror.specular == 1.0
    clamped = conv.surface_from_principled({"Transmission Weight": 1.7}, (-1, 2, 0.5, 1))
    assert clamped.transmission == 1.0 and min(clamped.color) == 0.0
    # a transmitting sphere's colour is the viewport colour; without one, Base Color
    tinted = {"Transmission Weight": 1.0, "Base Color": (0.2, 0.3, 0.4, 1)}
    assert conv.surface_from_principled(tinted, (0.5, 0.6, 0.7, 1)).color == (0.5, 0.6, 0.7)
    assert conv.surface_from_principled(tinted).color == (0.2, 0.3, 0.4)
    opaque = {"Base Color": (0.2, 0.3, 0.4, 1)}
    assert conv.surface_from_principled(opaque, (0.5, 0.6, 0.7, 1)).color == (0.2, 0.3, 0.4)


def test_principled_matches_float32():
    values = conv.principled_from_surface(THESIS_SURFACES[0])
    f32 = {
        k: tuple(float(np.float32(x)) for x in v) if isinstance(v, tuple) else float(np.float32(v))
        for k, v in values.items()
    }
    assert conv.principled_matches(values, f32)
    f32["IOR"] = 1.52
    assert not conv.principled_matches(values, f32)


# --------------------------------------------------------------------------- stored numbers


def test_prefer_stored():
    stored = (3.0, 3.0, 3.0)
    f32 = tuple(float(np.float32(x)) for x in (0.1, 0.2, 0.3))
    assert conv.prefer_stored(f32, (0.1, 0.2, 0.3)) == (0.1, 0.2, 0.3)
    assert conv.prefer_stored((3.0, 3.0, 3.0001), stored) == (3.0, 3.0, 3.0001)
    assert conv.prefer_stored((1.0, 2.0), None) == (1.0, 2.0)
    assert conv.prefer_stored(float(np.float32(100 / 255)), 100 / 255) == 100 / 255
    assert conv.prefer_stored(0.5, 0.6) == 0.5
    # a component near 0 is judged against `scale`
    assert conv.prefer_stored((1e-8, 1.0, 2.0), (0.0, 1.0, 2.0), scale=1.0) == (0.0, 1.0, 2.0)
    assert conv.prefer_stored((1e-8, 1.0, 2.0), (0.0, 1.0, 2.0), scale=1e-6) == (1e-8, 1.0, 2.0)
    assert conv.prefer_stored((1.0, 2.0), (1.0, 2.0, 3.0)) == (1.0, 2.0)  # shape mismatch


def test_header_line():
    text = (
        "/* a comment\n over two lines */\nV 200 200\nC 0 0 10 /* pos */\nA 1 1 -1\n"
        "U 0 1 0\n\n  B 45 45\nL 0\nO 0\n"
    )
    assert conv.header_line(text, "V") == 3
    assert conv.header_line(text, "B") == 8
    assert conv.header_line(text, "X") is None
    assert conv.header_line("/* V 1 1 */\nV 2 2\n", "V") == 2
