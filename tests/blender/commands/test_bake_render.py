"""A baked animation renders with stock Blender: bake a few frames where the light
(one test) or the lens (another) moves, save the .blend, and render its middle
frame in a fresh Blender process that never loads the extension (as a render-farm
node running `blender -b file.blend -a` does). The caustic there must match the
exact optics of *that* frame's geometry.

The scene is the measuring scene of tests/blender/build/test_blender_render.py (white floor,
glass ball R = 0.5, n = 1.5, a 1000 W point light, no bounces, orthographic camera
straight down) in Cycles with the default tier (AUTO: Exact profile, whose D/R
changes every frame: the bake's stacked profile slices are read between two of
them). The camera looks at the middle frame's axis point.

Expected, computed by hand from the keyed inputs (linear keys: the middle frame's
positions are the mean of the first and last): the axis point where the line from
the light through the ball's centre meets the floor; the irradiance there from
`core.lens.ball_optics.irradiance_on_plane` (perpendicular plane at that distance
along the axis, averaged over the measuring disc) × cos(tilt). Measured: the
render minus the same render with the baked "Lens Lights" collection disabled.
Position: its radiance-weighted centroid over the view against that of the exact
optics on the floor itself (`exact_floor_image`, as the render tests' AUTO tier
check). Tolerances as the render tests: position within `POSITION_TOL` (one
pixel), brightness within `BRIGHTNESS_TOL` (10 %).
"""

import math

import bpy
import numpy as np
import pytest
from measuring_scene import build_measuring_scene, direct_light_only
from stock_render import load, stock_render

from core.lens import ball_optics

pytestmark = pytest.mark.blender

R, N, POWER, ALBEDO = 0.5, 1.5, 1000.0, 0.8
PX, VIEW = 48, 1.0
PATCH_PX = 2.0
POSITION_TOL = 0.02
BRIGHTNESS_TOL = 0.10


def linear_keys():
    bpy.context.preferences.edit.keyframe_new_interpolation_type = "LINEAR"


def animate(ob, positions):
    """`ob` at `positions[k]` on frame k + 1 (linear keys)."""
    linear_keys()
    for k, p in enumerate(positions):
        ob.location = p
        ob.keyframe_insert("location", frame=k + 1)


def make_scene(center_mid, light_mid):
    """The measuring scene with the camera on the middle frame's axis point."""
    c, p = np.asarray(center_mid, float), np.asarray(light_mid, float)
    u = (c - p) / np.linalg.norm(c - p)
    hit = c + (c[2] / -u[2]) * u
    built = build_measuring_scene(
        "CYCLES",
        resolution=PX,
        floor_size=8.0,
        albedo=ALBEDO,
        view=VIEW,
        camera_xy=(hit[0], hit[1]),
        camera_height=6.0,
        ball=dict(radius=R, location=tuple(c), ior=N, segments=48, rings=24, name="Marble"),
        lamp=dict(location=tuple(p), power=POWER),
    )
    sc = built.scene
    direct_light_only(sc, 64)
    sc.frame_start, sc.frame_end = 1, 3
    return built, hit


def expected(center, light):
    """(axis point on the floor, exact radiance of the floor there)."""
    c, p = np.asarray(center, float), np.asarray(light, float)
    D = float(np.linalg.norm(c - p))
    u = (c - p) / D
    z = c[2] / -u[2]  # along the axis from the centre to the floor
    cos_tilt = -u[2]
    patch = PATCH_PX * VIEW / PX
    e = ball_optics.irradiance_on_plane(POWER / (4 * math.pi), D, R, N, z, [0.0, patch])[0]
    return c + z * u, ALBEDO * float(e) * cos_tilt / math.pi


def exact_floor_image(center, light, n_iota=2000, n_phi=2048, seed=1):
    """The exact optics (SPEC §6, `ball_optics.trace_rays_iota`, Fresnel at both
    surfaces) on the floor z = 0, binned into the camera's pixels (as in
    tests/blender/build/test_blender_render.py, for a lens anywhere on the x–z plane): a jittered
    fan of 4 M exact rays, each with its share of the flux I0 T dΩ."""
    rng = np.random.default_rng(seed)
    c, p = np.asarray(center, float), np.asarray(light, float)
    D = float(np.linalg.norm(c - p))
    u = (c - p) / D
    t = math.atan2(u[0], -u[2])
    e1, e2 = np.array([math.cos(t), 0.0, math.sin(t)]), np.array([0.0, 1.0, 0.0])
    d_iota, d_phi = 0.5 * math.pi / n_iota, 2 * math.pi / n_phi
    iota = (np.arange(n_iota) + rng.random(n_iota)) * d_iota
    fan = ball_optics.trace_rays_iota(iota, D, R, N)
    k = R / D
    flux = (
        ((POWER / (4 * math.pi)) * fan.transmission * k * k * np.sin(iota) * np.cos(iota))
        / np.cos(fan.psi)
        * d_iota
        * d_phi
    )
    phi = (np.arange(n_phi)[None, :] + rng.random((n_iota, n_phi))) * d_phi
    cos_t = np.cos(fan.theta_exit)[:, None]
    a, b = fan.b[:, None] / cos_t, np.tan(fan.theta_exit)[:, None]  # h(Z) = a − b Z
    sz = np.cos(phi) * e1[2] + np.sin(phi) * e2[2]
    Z = -(c[2] + a * sz) / (u[2] - b * sz)  # along the axis, to z = 0
    h = a - Z * b
    x = c[0] + h * (np.cos(phi) * e1[0] + np.sin(phi) * e2[0]) + Z * u[0]
    y = c[1] + h * (np.cos(phi) * e1[1] + np.sin(phi) * e2[1]) + Z * u[1]
    ok = (cos_t > 0) & (Z >= (-R * np.cos(fan.exit_polar))[:, None])
    ok &= np.isfinite(x) & np.isfinite(y)
    hit = c + (c[2] / -u[2]) * u
    ex = hit[0] + (np.arange(PX + 1) / PX - 0.5) * VIEW
    ey = hit[1] + (np.arange(PX + 1) / PX - 0.5) * VIEW
    E, _, _ = np.histogram2d(
        y[ok], x[ok], bins=[ey, ex], weights=np.broadcast_to(flux[:, None], x.shape)[ok]
    )
    return ALBEDO * (E / (VIEW / PX) ** 2) / math.pi


def pixel_xy(hit):
    coords = (np.arange(PX) + 0.5) * (VIEW / PX) - VIEW / 2
    return (
        np.broadcast_to(hit[0] + coords[None, :], (PX, PX)),
        np.broadcast_to(hit[1] + coords[:, None], (PX, PX)),
    )


def bake_and_check(tmp, center_mid, light_mid):
    from lens_lights.blender.commands import bake

    result = bpy.ops.lens_lights.bake()
    assert result == {"FINISHED"}
    LAST_BAKE = bake.LAST_BAKE
    assert LAST_BAKE["frames"] == 3 and LAST_BAKE["energy_model"] == "EXACT_PROFILE"
    assert LAST_BAKE["images"] == 1  # one stacked table for the lens, not one per frame
    blend = tmp / "baked.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend), copy=True)
    facts, with_, without = stock_render(blend, tmp, 2)
    assert facts == dict(registered=False, operators=False)
    check_caustic(with_, without, center_mid, light_mid, "baked frame 2")


def check_caustic(with_, without, center_mid, light_mid, label):
    """The caustic (`with_` − `without`) against the exact optics of that geometry."""
    hit, radiance = expected(center_mid, light_mid)
    diff = with_ - without
    x, y = pixel_xy(hit)
    exact = exact_floor_image(center_mid, light_mid)
    assert diff.sum() > 0.5 * exact.sum(), "no caustic"

    def centroid(img):
        return float((img * x).sum() / img.sum()), float((img * y).sum() / img.sum())

    (cx, cy), (ex, ey) = centroid(diff), centroid(exact)
    error = math.hypot(cx - ex, cy - ey)
    patch = np.hypot(x - hit[0], y - hit[1]) <= PATCH_PX * VIEW / PX
    ratio = float(diff[patch].mean()) / radiance
    print(f"\n{label}: centroid {error:.4f} from the exact one, brightness ratio {ratio:.4f}")
    assert error <= POSITION_TOL
    assert abs(ratio - 1) <= BRIGHTNESS_TOL


def test_baked_moving_light_renders_without_extension(extension, tmp_path):
    center = (0.0, 0.0, 2.5)
    first, last = np.array([-0.45, 0.0, 4.45]), np.array([-1.1, 0.0, 4.6])
    mid = 0.5 * (first + last)
    built, _ = make_scene(center, mid)
    animate(built.lamp, [first, mid, last])
    bake_and_check(tmp_path, center, mid)


def test_baked_moving_lens_renders_without_extension(extension, tmp_path):
    light = (0.0, 0.0, 4.6)
    first, last = np.array([0.3, 0.0, 2.4]), np.array([0.7, 0.0, 2.6])
    mid = 0.5 * (first + last)
    built, _ = make_scene(mid, light)
    animate(built.ball, [first, mid, last])
    bake_and_check(tmp_path, mid, light)


def test_live_update_still_render_matches_the_frame(extension, tmp_path):
    """Live update on, `frame_set(2)`, then a still render (F12): the caustic is frame
    2's, by the same measure as the baked frame."""
    center = (0.0, 0.0, 2.5)
    first, last = np.array([-0.45, 0.0, 4.45]), np.array([-1.1, 0.0, 4.6])
    mid = 0.5 * (first + last)
    built, _ = make_scene(center, mid)
    animate(built.lamp, [first, mid, last])
    scene = built.scene
    scene.frame_set(1)
    scene.lens_lights.live_update = True
    scene.frame_set(2)

    def render(name):
        scene.render.filepath = str(tmp_path / name)
        scene.render.image_settings.file_format = "OPEN_EXR"
        bpy.ops.render.render(write_still=True)
        return load(tmp_path / name)

    with_ = render("live.exr")
    scene.lens_lights.live_update = False
    bpy.data.collections["Lens Lights"].hide_render = True
    without = render("without.exr")
    check_caustic(with_, without, center, mid, "live update, frame 2")
