"""Headless renders (Cycles on the CPU, EEVEE through software GL): the caustic a
lens light paints on the floor is where the physics puts it and as bright as the
exact optics of SPEC §6 predict.

The scene: a white diffuse floor (albedo 0.8) at z = 0, a glass sphere (Principled
BSDF, transmission 1, IOR 1.5, R = 0.5) centred 2.5 above it, hidden from the camera
(`visible_camera = False`: the floor under it stays visible; it still casts its
shadow), a point light (1000 W) D = 2 from the centre, tilted 20° from the
vertical, so the axis meets the floor at x = 2.5 tan 20° = 0.910. An orthographic
camera looks straight down at that point; no world light, no bounces: a pixel
is the floor's radiance ``0.8 · E / π`` with E the irradiance (W/m²).

Expected irradiance at the axis point: the exact ball-lens optics
(`core.lens.ball_optics.irradiance_on_plane`, on the plane perpendicular to the axis
at the floor's distance, averaged over a disc as wide as the measuring patch),
times cos 20° for the floor's tilt. The measured value is the mean of the pixels
within `PATCH_PX` of the axis point, "with lens lights" minus "without".

Tolerances (stated, and asserted): caustic position within `POSITION_TOL` (0.02,
one pixel) of the axis point; brightness within `BRIGHTNESS_TOL` (10 %) of the
exact optics. The measured figures are printed (`-s` shows them).

A second scene puts the light at the sphere's front focal point: a collimated beam,
rendered in both engines as the far-away narrow spot of `addon/light_models.py`.

The tiers (the panel's default AUTO, one more render per engine on the basic
scene): EXACT_PROFILE in Cycles, CAUSTIC_LAYER in EEVEE, against the exact optics on the
tilted floor itself (`exact_floor_image`: 4 M exact rays binned into the pixels).
The caustic's centroid (radiance-weighted, over the view) must lie within
`POSITION_TOL` of the exact one. Brightness at the axis patch and the light in
the whole view, as ratios to the exact optics:

* EXACT_PROFILE (Cycles): both within `BRIGHTNESS_TOL` (10 %) of 1 (measured:
  patch 1.035, view 1.000, centroid 0.004 off).
* CAUSTIC_LAYER (EEVEE): the layer mesh on the floor; both within
  `BRIGHTNESS_TOL` (10 %) of 1 too (measured: see the printed figures and
  reports/caustic_layer.md).
* FITTED (EEVEE, no longer AUTO's there; bench/render_compare.py): one spot
  cannot make the converged core of the real beam (here 4.3 R behind the lens,
  past the focus; D = 4 R); the fit minimises the L1 error
  over the whole shadow disc (0.54 for this lens, reports/accuracy.md), so at the
  axis it is darker and its halo is cut short. Asserted: patch ratio within
  `FITTED_RATIO`, view ratio within `FITTED_VIEW_RATIO` (measured 0.332 and
  0.662, centroid 0.010 off; the pure spot model of the same light gives 0.333).
"""

import math

import bpy
import numpy as np
import pytest
from measuring_scene import (
    add_top_camera,
    build_measuring_scene,
    direct_light_only,
    new_material,
    new_measuring_scene,
    render_grey,
)

from core.lens import ball_optics
from core.lens.glass import head_on_transmission

pytestmark = pytest.mark.blender

R, N, D, HEIGHT, TILT_DEG, POWER, ALBEDO = 0.5, 1.5, 2.0, 2.5, 20.0, 1000.0, 0.8
D_FOCAL = N * R / (2 * (N - 1))  # 0.75: front focal distance
PX, VIEW = 48, 1.0  # 48 × 48 px over 1 m: ~2 cm a pixel
PATCH_PX = 2.0
POSITION_TOL = 0.02
BRIGHTNESS_TOL = 0.10
ENGINES = ("CYCLES", "BLENDER_EEVEE")
#: The tier AUTO builds per engine.
AUTO_TIER = {"CYCLES": "EXACT_PROFILE", "BLENDER_EEVEE": "CAUSTIC_LAYER"}
FITTED_RATIO = (0.25, 0.45)
FITTED_VIEW_RATIO = (0.5, 0.85)
FIGURES = {}


def axis_dir():
    t = math.radians(TILT_DEG)
    return np.array([math.sin(t), 0.0, -math.cos(t)])


def axis_hit():
    """Where the axis (from the sphere's centre along axis_dir) meets z = 0."""
    u = axis_dir()
    c = np.array([0.0, 0.0, HEIGHT])
    return c + (HEIGHT / -u[2]) * u, HEIGHT / -u[2]


def build_scene(engine, tmp, light_distance=D):
    """The measuring scene (scripts/measuring_scene.py) of the module docstring."""
    center = np.array([0.0, 0.0, HEIGHT])
    hit, _ = axis_hit()
    built = build_measuring_scene(
        engine,
        resolution=PX,
        floor_size=6.0,
        albedo=ALBEDO,
        view=VIEW,
        camera_xy=(hit[0], hit[1]),
        camera_height=5.0,
        ball=dict(
            radius=R, location=(0.0, 0.0, HEIGHT), ior=N, segments=48, rings=24, name="Marble"
        ),
        lamp=dict(location=center - light_distance * axis_dir(), power=POWER),
    )
    sc = built.scene
    if engine == "CYCLES":
        direct_light_only(sc, 64)
    else:
        sc.eevee.taa_render_samples = 4
    return sc, built.lamp


def render(sc, path):
    return render_grey(sc, path)  # grey floor: channels agree


def pixel_xy():
    """World x, y of each pixel centre (row 0 is the bottom row in Blender images)."""
    hit, _ = axis_hit()
    step = VIEW / PX
    coords = (np.arange(PX) + 0.5) * step - VIEW / 2
    x = hit[0] + coords[None, :]
    y = hit[1] + coords[:, None]
    return np.broadcast_to(x, (PX, PX)), np.broadcast_to(y, (PX, PX))


def patch_mean(img, point, radius_px=PATCH_PX):
    x, y = pixel_xy()
    mask = np.hypot(x - point[0], y - point[1]) <= radius_px * VIEW / PX
    return float(img[mask].mean()), mask


def exact_floor_irradiance(light_distance, z_along_axis, patch_radius):
    """Exact optics (SPEC §6): irradiance on the floor at the axis point, averaged
    over a disc of `patch_radius` on the perpendicular plane, × cos(tilt)."""
    i0 = POWER / (4 * math.pi)
    e = ball_optics.irradiance_on_plane(
        i0, light_distance, R, N, z_along_axis, [0.0, patch_radius], n_psi=100_000
    )[0]
    return float(e) * math.cos(math.radians(TILT_DEG))


def to_radiance(e):
    return ALBEDO * e / math.pi


@pytest.fixture(scope="module")
def renders(extension, tmp_path_factory):
    """All renders, once: per engine, the basic scene without and with lens lights,
    and the collimated scene with lens lights only (primary hidden)."""
    from lens_lights.blender.commands.generate import generate

    tmp = tmp_path_factory.mktemp("renders")
    out = {}
    for engine in ENGINES:
        sc, lamp = build_scene(engine, tmp)
        out[engine, "without"] = render(sc, tmp / f"{engine}_without.exr")
        sc.lens_lights.energy_model = "PHYSICAL"
        generate(bpy.context)
        (ll,) = [
            o
            for o in bpy.data.objects
            if o.lens_lights.is_lens_light and not o.get("lens_lights_reflection")
        ]
        out[engine, "light"] = dict(
            energy=ll.data.energy,
            location=tuple(ll.location),
            spot_size=math.degrees(ll.data.spot_size),
        )
        out[engine, "with"] = render(sc, tmp / f"{engine}_with.exr")
        sc.lens_lights.energy_model = "AUTO"
        generate(bpy.context)
        # one light, or the layers (in view, and a coarse one for the halo out of view)
        made = [
            o
            for o in bpy.data.objects
            if o.lens_lights.is_lens_light and not o.get("lens_lights_reflection")
        ]
        ll = max(made, key=lambda o: len(o.data.polygons) if o.type == "MESH" else 0)
        assert len({o.lens_lights.energy_model for o in made}) == 1
        out[engine, "tier"] = ll.lens_lights.energy_model
        out[engine, "tier_light"] = (
            dict(layer=ll.name, faces=len(ll.data.polygons))
            if ll.type == "MESH"
            else dict(
                energy=ll.data.energy,
                location=tuple(ll.location),
                spot_size=math.degrees(ll.data.spot_size),
                blend=ll.data.spot_blend,
            )
        )
        out[engine, "tier_render"] = render(sc, tmp / f"{engine}_tier.exr")

        sc, lamp = build_scene(engine, tmp, light_distance=D_FOCAL)
        sc.lens_lights.energy_model = "PHYSICAL"  # (the default is AUTO)
        generate(bpy.context)
        (ll,) = [
            o
            for o in bpy.data.objects
            if o.lens_lights.is_lens_light and not o.get("lens_lights_reflection")
        ]
        assert ll.lens_lights.kind == "collimated"
        out[engine, "beam"] = dict(
            energy=ll.data.energy, location=tuple(ll.location), scale=ll.scale.x
        )
        lamp.hide_render = True
        out[engine, "collimated"] = render(sc, tmp / f"{engine}_collimated.exr")
    return out


@pytest.mark.parametrize("engine", ENGINES)
def test_caustic_is_where_the_axis_meets_the_floor(renders, engine):
    diff = renders[engine, "with"] - renders[engine, "without"]
    x, y = pixel_xy()
    lit = diff > 0.5 * diff.max()
    assert lit.sum() >= 20, "no caustic"
    cx, cy = float(x[lit].mean()), float(y[lit].mean())
    hit, _ = axis_hit()
    error = math.hypot(cx - hit[0], cy - hit[1])
    FIGURES[engine, "position_error"] = error
    print(
        f"\n{engine}: caustic centre ({cx:.4f}, {cy:.4f}), axis meets the floor at "
        f"({hit[0]:.4f}, {hit[1]:.4f}): error {error:.4f} (pixel {VIEW / PX:.4f})"
    )
    assert error <= POSITION_TOL


@pytest.mark.parametrize("engine", ENGINES)
def test_caustic_brightness_matches_exact_optics(renders, engine):
    hit, t_hit = axis_hit()
    without, _ = patch_mean(renders[engine, "without"], hit)
    with_, _ = patch_mean(renders[engine, "with"], hit)
    measured = with_ - without
    radius = PATCH_PX * VIEW / PX
    expected = to_radiance(exact_floor_irradiance(D, t_hit, radius))
    ratio = measured / expected
    # What THESIS would give here: its energy over PHYSICAL's, same geometry.
    v = 2 * (N - 1) / (N * R) - 1 / D
    thesis_ratio = ratio / (head_on_transmission(N) * (1 / (v * D)) ** 2)
    FIGURES[engine, "ratio"] = ratio
    print(
        f"\n{engine}: caustic {measured:.4f} vs exact optics {expected:.4f}: "
        f"PHYSICAL ratio {ratio:.4f} (THESIS would give {thesis_ratio:.3f}); "
        f"without lens lights {without:.4f}"
    )
    assert without < 0.05 * expected  # no caustic without lens lights
    assert abs(ratio - 1) <= BRIGHTNESS_TOL


def exact_floor_image(light_distance=D, n_iota=2000, n_phi=2048, seed=1):
    """The exact optics (SPEC §6: `ball_optics.trace_rays_iota`, Fresnel at both
    surfaces) on the tilted floor itself, per pixel: the floor's radiance
    ``0.8 E / π`` of the direct beam. A jittered fan of 4 M exact rays (incidence
    angle × azimuth), each carrying its share of the flux ``I0 T dΩ``, is
    intersected with the floor z = 0 and binned into the camera's pixels."""
    rng = np.random.default_rng(seed)
    t = math.radians(TILT_DEG)
    u = axis_dir()
    e1, e2 = np.array([math.cos(t), 0.0, math.sin(t)]), np.array([0.0, 1.0, 0.0])
    c = np.array([0.0, 0.0, HEIGHT])
    d_iota, d_phi = 0.5 * math.pi / n_iota, 2 * math.pi / n_phi
    iota = (np.arange(n_iota) + rng.random(n_iota)) * d_iota
    fan = ball_optics.trace_rays_iota(iota, light_distance, R, N)
    k = R / light_distance
    # flux per ray: I0 T(ι) dΩ, dΩ = k² sin ι cos ι / cos ψ dι dφ
    flux = (
        (POWER / (4 * math.pi))
        * fan.transmission
        * k
        * k
        * np.sin(iota)
        * np.cos(iota)
        / np.cos(fan.psi)
        * d_iota
        * d_phi
    )
    phi = (np.arange(n_phi)[None, :] + rng.random((n_iota, n_phi))) * d_phi
    cos_t = np.cos(fan.theta_exit)[:, None]
    a, b = fan.b[:, None] / cos_t, np.tan(fan.theta_exit)[:, None]  # h(Z) = a − b Z (meridional)
    sz = np.cos(phi) * e1[2] + np.sin(phi) * e2[2]
    Z = -(c[2] + a * sz) / (u[2] - b * sz)  # along the axis, to z = 0
    h = a - Z * b
    x = c[0] + h * (np.cos(phi) * e1[0] + np.sin(phi) * e2[0]) + Z * u[0]
    y = c[1] + h * (np.cos(phi) * e1[1] + np.sin(phi) * e2[1]) + Z * u[1]
    ok = (
        (cos_t > 0)
        & (Z >= (-R * np.cos(fan.exit_polar))[:, None])
        & np.isfinite(x)
        & np.isfinite(y)
    )
    hit, _ = axis_hit()
    ex = hit[0] + (np.arange(PX + 1) / PX - 0.5) * VIEW
    ey = hit[1] + (np.arange(PX + 1) / PX - 0.5) * VIEW
    E, _, _ = np.histogram2d(
        y[ok], x[ok], bins=[ey, ex], weights=np.broadcast_to(flux[:, None], x.shape)[ok]
    )
    return to_radiance(E / (VIEW / PX) ** 2)


@pytest.mark.parametrize("engine", ENGINES)
def test_auto_tier_caustic_against_exact_optics(renders, engine):
    """AUTO's tier per engine (EXACT_PROFILE in Cycles, CAUSTIC_LAYER in EEVEE) against
    the exact optics on the floor itself (`exact_floor_image`): where the caustic is
    (its centroid, the radiance-weighted mean position over the view), how bright
    it is at the axis point (the patch of the PHYSICAL test) and how much of the
    exact light falls into the view."""
    tier = renders[engine, "tier"]
    assert tier == AUTO_TIER[engine]
    diff = renders[engine, "tier_render"] - renders[engine, "without"]
    exact = exact_floor_image()
    x, y = pixel_xy()
    hit, t_hit = axis_hit()

    def centroid(img):
        return float((img * x).sum() / img.sum()), float((img * y).sum() / img.sum())

    (cx, cy), (ex, ey) = centroid(diff), centroid(exact)
    error = math.hypot(cx - ex, cy - ey)
    _, patch = patch_mean(diff, hit)
    ratio = float(diff[patch].mean() / exact[patch].mean())
    view_ratio = float(diff.sum() / exact.sum())
    # The perpendicular-plane estimate of the PHYSICAL test, for comparison.
    approx = to_radiance(exact_floor_irradiance(D, t_hit, PATCH_PX * VIEW / PX))
    FIGURES[engine, "tier_ratio"] = ratio
    print(
        f"\n{engine} {tier}: centroid ({cx:.4f}, {cy:.4f}) vs exact ({ex:.4f}, {ey:.4f}): "
        f"error {error:.4f}; axis patch {diff[patch].mean():.4f} "
        f"vs exact {exact[patch].mean():.4f} "
        f"(perpendicular-plane estimate {approx:.4f}): ratio {ratio:.4f}; light in the view "
        f"{view_ratio:.4f} of the exact; light {renders[engine, 'tier_light']}"
    )
    assert error <= POSITION_TOL
    if tier in ("EXACT_PROFILE", "CAUSTIC_LAYER"):
        assert abs(ratio - 1) <= BRIGHTNESS_TOL
        assert abs(view_ratio - 1) <= BRIGHTNESS_TOL
    else:
        assert FITTED_RATIO[0] <= ratio <= FITTED_RATIO[1]
        assert FITTED_VIEW_RATIO[0] <= view_ratio <= FITTED_VIEW_RATIO[1]


@pytest.mark.parametrize("engine", ENGINES)
def test_collimated_beam_renders_as_modelled(renders, engine):
    """The beam is R_C wide and carries PHYSICAL's paraxial irradiance I0 T(0)/D²
    (to the far spot's (s + L_ref)²/(s + L)² across the scene, × cos tilt). The
    exact near-axis irradiance is printed too: at the focal point spherical
    aberration makes every marginal ray cross the axis before the floor, so the
    true axial caustic (∝ 1/ρ) is far brighter than any cylinder; not asserted."""
    img = renders[engine, "collimated"]
    beam = renders[engine, "beam"]
    hit, t_hit = axis_hit()
    measured, _ = patch_mean(img, hit)
    radius = PATCH_PX * VIEW / PX
    i0 = POWER / (4 * math.pi)
    back_vertex = np.array([0.0, 0.0, HEIGHT]) + R * axis_dir()
    s = float(np.linalg.norm(np.array(beam["location"]) - back_vertex))
    # The far spot at s behind the back vertex, the floor L = t_hit − R beyond it:
    # irradiance energy/(4π)/(s + L)² across the beam, × cos tilt on the floor.
    model = beam["energy"] / (4 * math.pi) / (s + t_hit - R) ** 2
    expected = to_radiance(model * math.cos(math.radians(TILT_DEG)))
    paraxial = i0 * head_on_transmission(N) / D_FOCAL**2  # PHYSICAL's beam, any L
    exact = to_radiance(exact_floor_irradiance(D_FOCAL, t_hit, radius))
    ratio = measured / expected
    FIGURES[engine, "beam_ratio"] = ratio
    # Width across the beam (y is perpendicular to the tilt): the profile's
    # equivalent width ∫ profile / peak along the two columns through the axis point.
    profile = img[:, PX // 2 - 1 : PX // 2 + 1].mean(axis=1)
    width = float(profile.sum() / profile[PX // 2 - 2 : PX // 2 + 2].mean()) * VIEW / PX
    # R_C of the beam at the focal point: R sin(2δ + α − 90°), α = asin(R/D_f),
    # widened by the far spot's (1 + L/s) at the floor; the spot blend b fades the
    # edge over the outer share b of 1 − cos ψ ∝ ψ² (a smoothstep, half-way at
    # 1 − b/2): the equivalent width is × sqrt(1 − b/2) (0.962 for b = 0.15).
    delta, alpha = math.asin(1 / N), math.asin(R / D_FOCAL)
    rc = R * math.sin(2 * delta + alpha - math.pi / 2) * (1 + (t_hit - R) / s)
    blend = math.sqrt(1 - 0.15 / 2)
    print(
        f"\n{engine}: collimated beam {measured:.4f} vs the far spot {expected:.4f}: "
        f"ratio {ratio:.4f} (the spot is {model / paraxial:.3f} × I0 T(0)/D² at the floor); "
        f"width {width:.3f} vs 2 R_C {2 * rc:.3f} (× blend "
        f"{2 * rc * blend:.3f}); exact optics near "
        f"the axis {exact:.1f} ({exact / measured:.1f} × the beam: axial caustic)"
    )
    assert abs(ratio - 1) <= BRIGHTNESS_TOL
    assert width == pytest.approx(2 * rc * blend, rel=0.03)


def test_cycles_glass_path_transmittance(extension, tmp_path):
    """What PHYSICAL assumes of Cycles' glass, measured through a sphere seen
    against an emitter (strength 1) along the axis: T(0) = 0.9216 for n = 1.5, the
    Principled BSDF tints a path once by Base Color, the Glass BSDF at each surface."""
    sc = new_measuring_scene("CYCLES", 8)  # linear EXR, Standard, no world
    sc.cycles.samples = 8
    sc.cycles.use_denoising = False
    bpy.ops.mesh.primitive_plane_add(size=20, location=(0, 0, -5))
    em = new_material("Emitter")
    nt = em.node_tree
    nt.nodes.remove(nt.nodes["Principled BSDF"])
    e = nt.nodes.new("ShaderNodeEmission")
    nt.links.new(e.outputs[0], nt.nodes["Material Output"].inputs["Surface"])
    bpy.context.object.data.materials.append(em)
    bpy.ops.mesh.primitive_uv_sphere_add(radius=1, segments=64, ring_count=32)
    sphere = bpy.context.object
    bpy.ops.object.shade_smooth()
    add_top_camera(0.0, 0.0, 5.0, view=0.05)

    def through(kind, color):
        mat = new_material(kind)
        nt = mat.node_tree
        if kind == "principled":
            b = nt.nodes["Principled BSDF"]
            b.inputs["Transmission Weight"].default_value = 1.0
            b.inputs["Roughness"].default_value = 0.0
            b.inputs["Base Color"].default_value = (color, color, color, 1)
        else:
            nt.nodes.remove(nt.nodes["Principled BSDF"])
            b = nt.nodes.new("ShaderNodeBsdfGlass")
            b.inputs["Roughness"].default_value = 0.0
            b.inputs["Color"].default_value = (color, color, color, 1)
            nt.links.new(b.outputs[0], nt.nodes["Material Output"].inputs["Surface"])
        b.inputs["IOR"].default_value = 1.5
        sphere.data.materials.clear()
        sphere.data.materials.append(mat)
        return float(np.mean(render(sc, tmp_path / f"{kind}{color}.exr")))

    t0 = head_on_transmission(1.5)
    clear = through("principled", 1.0)
    print(
        f"\nCycles through a sphere (n 1.5): {clear:.4f} (T(0) = {t0:.4f}); "
        f"Principled base 0.5: {through('principled', 0.5) / clear:.3f} of it, "
        f"Glass colour 0.5: {through('glass', 0.5) / clear:.3f}"
    )
    assert clear == pytest.approx(t0, rel=0.01)  # (+0.4 %: internal reflections)
    assert through("principled", 0.5) / clear == pytest.approx(0.5, rel=0.01)
    assert through("glass", 0.5) / clear == pytest.approx(0.25, rel=0.01)
