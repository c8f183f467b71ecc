"""The rendered comparison (issue "Accuracy", item 4): one table-top scene, the
caustic of a glass ball on the table, rendered by

(a) Cycles with its own shadow caustics (MNEE) at increasing samples,
(b) Cycles with lens lights, per tier (THESIS, PHYSICAL, FITTED, EXACT_PROFILE),
(c) EEVEE with lens lights (FITTED, PHYSICAL),

each against (d) the exact irradiance of SPEC §6 (the converged reference).
Writes reports/render_compare.md and reports/render_compare_*.png.

    ./lens-lights bench render_compare            # about 6–10 minutes on 2 cores
    ./lens-lights bench render_compare --quick    # fewer sample counts (a smoke run)
    ./lens-lights bench render_compare --tiers THESIS PHYSICAL --no-eevee

The scene (all lengths in metres): a white Lambertian table (albedo 0.8) at z = 0;
a clear glass ball (R = 5 cm, n = 1.5, smooth-shaded UV sphere 64 × 32) with its
centre 15 cm above the table (its bottom 2R above it, as on a clear stand); a
point light (10 W, radius 0) straight above the ball, D = 5R = 25 cm from its
centre. No world light. An orthographic camera looks straight down at the ball's
shadow; the ball is invisible to the camera (`visible_camera = False`), so the
table under it shows through (it still casts its shadow and its caustic).
96 × 96 pixels, box pixel filter one pixel wide (a pixel is the mean over its
square), Standard view transform, exposure 0, no denoising, float EXR.

Reference (d): the light's axis is perpendicular to the table, so the beam is
rotationally symmetric and its exact irradiance on the table is the 1-D integral
of SPEC §6 (`core.accuracy.ExactBeam`: Fresnel at both surfaces, internal
reflections ignored), plus the direct light outside the ball's shadow; a pixel
is albedo/π × its mean irradiance (16 × 16 sub-samples over fine rings).
Caustic region: the pixels entirely inside the ball's shadow disc. Error:
relative L1 over the region, Σ|pixel − reference| / Σ reference.

Wall time: the render call (`bpy.ops.render.render`, scene sync included) on
the machine's cores; for lens lights plus the time to generate them (the
operator, once per scene). EEVEE's first render of a scene compiles its shaders;
that warm-up is reported separately and not counted.
"""

from __future__ import annotations

import argparse
import math
import re
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from core.lens import ball_optics as xo
from core.phase1.point_lights import compute_phase1
from core.scene.model import Light, Scene, Sphere, Surface
from core.scene.primaries import PrimaryLight
from core.tiers import exact_profile as lt
from core.tiers import make_blender_light
from core.tiers.beam_error import ExactBeam, model_from_light

sys.path.insert(0, str(ROOT / "scripts"))
from measuring_scene import build_measuring_scene

REPORTS = ROOT / "reports"

# --------------------------------------------------------------------------- the scene
R = 0.05  # ball radius (m)
IOR = 1.5
D = 5.0 * R  # light to ball centre
BEHIND = 2.0 * R  # table below the ball's bottom
Z = R + BEHIND  # ball centre above the table (= distance centre → table)
POWER = 10.0  # W (Blender energy of the point light)
I0 = POWER / (4.0 * math.pi)
ALBEDO = 0.8
PX = 96
RS = xo.lens_shadow_radius(D, R, Z)  # radius of the ball's shadow on the table
VIEW = 2.0 * 1.25 * RS  # the camera's field (m), centred on the axis
STEP = VIEW / PX
SUPER = 16  # sub-samples per pixel side for the reference

CYCLES_MNEE = "CYCLES_MNEE"
CYCLES_MNEE_X10 = "CYCLES_MNEE_X10"  # the same scene × 10 (MNEE depends on the scale)
ALL_TIERS = ("THESIS", "PHYSICAL", "FITTED", "EXACT_PROFILE")
EEVEE_TIERS = ("FITTED", "PHYSICAL")
SAMPLES_MNEE = (1, 4, 16, 64, 256, 1024)
SAMPLES_CYCLES_LL = (1, 4, 16, 64, 256, 1024)
SAMPLES_EEVEE = (1, 4, 16, 64)
QUICK = dict(mnee=(4, 64), cycles=(4, 64), eevee=(1, 4))
#: MNEE side experiment: the same scene scaled (lengths × s, power × s², so every
#: irradiance is the same): an exact renderer gives the same image.
SCALES = (0.2, 1.0, 10.0)
SCALE_SAMPLES = 256
#: MNEE side experiment: the ball's tessellation (segments, rings).
MESHES = ((32, 16), (64, 32), (128, 64))
MESH_SAMPLES = 64

LABEL = {
    CYCLES_MNEE: "Cycles MNEE (shadow caustics)",
    CYCLES_MNEE_X10: "Cycles MNEE, the scene × 10 (R = 50 cm)",
    ("CYCLES", "THESIS"): "Cycles + lens lights THESIS",
    ("CYCLES", "PHYSICAL"): "Cycles + lens lights PHYSICAL",
    ("CYCLES", "FITTED"): "Cycles + lens lights FITTED",
    ("CYCLES", "EXACT_PROFILE"): "Cycles + lens lights EXACT_PROFILE",
    ("BLENDER_EEVEE", "FITTED"): "EEVEE + lens lights FITTED",
    ("BLENDER_EEVEE", "PHYSICAL"): "EEVEE + lens lights PHYSICAL",
}
SHORT = {
    CYCLES_MNEE: "Cycles MNEE",
    CYCLES_MNEE_X10: "Cycles MNEE, scene × 10",
    ("CYCLES", "THESIS"): "Cycles LL THESIS",
    ("CYCLES", "PHYSICAL"): "Cycles LL PHYSICAL",
    ("CYCLES", "FITTED"): "Cycles LL FITTED",
    ("CYCLES", "EXACT_PROFILE"): "Cycles LL EXACT_PROFILE",
    ("BLENDER_EEVEE", "FITTED"): "EEVEE LL FITTED",
    ("BLENDER_EEVEE", "PHYSICAL"): "EEVEE LL PHYSICAL",
}
COLOR = {
    CYCLES_MNEE: "black",
    CYCLES_MNEE_X10: "tab:red",
    ("CYCLES", "THESIS"): "tab:gray",
    ("CYCLES", "PHYSICAL"): "tab:orange",
    ("CYCLES", "FITTED"): "tab:blue",
    ("CYCLES", "EXACT_PROFILE"): "tab:green",
    ("BLENDER_EEVEE", "FITTED"): "tab:purple",
    ("BLENDER_EEVEE", "PHYSICAL"): "tab:brown",
}


# --------------------------------------------------------------------------- reference


def pixel_grid(view=VIEW, px=PX):
    """World x, y of the pixel centres (row 0 is the bottom row, as Blender stores
    images; the camera is unrotated: x to the right, y up)."""
    c = (np.arange(px) + 0.5) * view / px - view / 2.0
    return np.meshgrid(c, c)


def region_mask(view=VIEW, px=PX, rs=RS):
    """Pixels entirely inside the ball's shadow disc."""
    x, y = pixel_grid(view, px)
    return np.hypot(x, y) + (view / px) / math.sqrt(2.0) <= rs


def pixel_average(flux_within, r_max, view=VIEW, px=PX, ss=SUPER):
    """Per-pixel mean irradiance of a rotationally symmetric beam about the
    camera's centre, from its flux within a radius (`flux_within(radii)`):
    ring means over fine rings (uniform plus geometric toward the axis, where the
    exact beam has its 1/ρ caustic), looked up at ss × ss sub-samples a pixel."""
    edges = np.unique(
        np.concatenate([np.linspace(0.0, r_max, 20001), r_max * np.geomspace(1e-7, 1.0, 400)])
    )
    F = np.asarray(flux_within(edges), dtype=float)
    ring = np.diff(F) / (math.pi * np.diff(edges**2))
    step = view / px
    sub = (np.arange(ss) + 0.5) / ss * step
    c = np.arange(px) * step - view / 2.0
    x = (c[:, None] + sub[None, :]).ravel()
    out = np.empty((px, px))
    for i in range(px):  # one row of pixels at a time
        ys = x[i * ss : (i + 1) * ss]
        r = np.hypot(x[None, :], ys[:, None])
        k = np.clip(np.searchsorted(edges, r, side="right") - 1, 0, ring.size - 1)
        out[i] = ring[k].reshape(ss, px, ss).mean(axis=(0, 2))
    return out


def direct_average(view=VIEW, px=PX, ss=SUPER, rs=RS, h=Z + D, i0=I0):
    """Per-pixel mean direct irradiance of the point light (zero in the shadow)."""
    step = view / px
    sub = (np.arange(ss) + 0.5) / ss * step
    c = np.arange(px) * step - view / 2.0
    x = (c[:, None] + sub[None, :]).ravel()
    out = np.empty((px, px))
    for i in range(px):
        ys = x[i * ss : (i + 1) * ss]
        r = np.hypot(x[None, :], ys[:, None])
        e = np.where(r >= rs, i0 * h / (h * h + r * r) ** 1.5, 0.0)
        out[i] = e.reshape(ss, px, ss).mean(axis=(0, 2))
    return out


def to_pixel(E):
    """Radiance of the white Lambertian table: albedo/π × irradiance."""
    return ALBEDO / math.pi * E


def reference_maps():
    """(beam, direct) pixel maps (radiance) of the exact optics."""
    beam = ExactBeam(I0, D, R, IOR)
    r_max = VIEW * 0.75
    beam_px = to_pixel(pixel_average(lambda e: beam.flux_within_radius(Z, e), r_max))
    return beam_px, to_pixel(direct_average()), beam


def pure_source():
    """The phase-1 source of the scene, in world coordinates (as the operator sees it)."""
    scene = Scene(
        lights=[Light(position=(0.0, 0.0, Z + D), brightness=1.0)],
        objects=[
            Sphere(center=(0.0, 0.0, Z), radius=R, surface=Surface(transmission=1.0, ior=IOR))
        ],
    )
    return compute_phase1(scene).sources[0]


def tier_model_map(tier):
    """The pixel map (radiance, region only: the beam) of the tier's *pure* model,
    the light the add-on's code makes for this source, as Blender renders it
    (`core.spot_irradiance` / the profile): what the renders converge to."""
    src = pure_source()
    primary = PrimaryLight(POWER)
    if tier == "EXACT_PROFILE":
        prof = lt.exact_profile(D / R, IOR)
        light = lt.make_profile_light(src, primary, scene_size=2.0, profile=prof)
        # the light's energy/(4π) × texture is primary intensity × the table (see
        # make_profile_light), so the model is the table at scale (R, I0)
        model = lt.profile_model(prof, R, I0)
    else:
        light = make_blender_light(src, primary, tier, scene_size=2.0)
        model = model_from_light(light, src)
    return to_pixel(pixel_average(lambda e: model.flux_within_radius(Z, e), VIEW * 0.75)), light


def l1(img, ref, mask):
    return float(np.abs(img - ref)[mask].sum() / ref[mask].sum())


def flux_ratio(img, ref, mask):
    return float(img[mask].sum() / ref[mask].sum())


# --------------------------------------------------------------------------- Blender


def load_extension():
    """The checkout as the package `lens_lights`, registered once."""
    sys.path.insert(0, str(ROOT / "scripts"))
    from dev_extension import PACKAGE
    from dev_extension import load_extension as load

    registered = PACKAGE in sys.modules
    module = load()
    if not registered:
        module.register()
    return module


def available_tiers():
    """The energy models the operator's enum offers now."""
    import bpy

    settings = bpy.context.scene.lens_lights
    return [item.identifier for item in settings.bl_rna.properties["energy_model"].enum_items]


def build_scene(engine, scale=1.0, segments=64, rings=32):
    """The table-top scene (see the module docstring; the measuring scene of
    scripts/measuring_scene.py), lengths × `scale`, power × scale² (same
    irradiance), the ball a `segments` × `rings` UV sphere. Returns (scene,
    table, ball, lamp)."""
    built = build_measuring_scene(
        engine,
        resolution=PX,
        floor_size=2.0 * scale,
        albedo=ALBEDO,
        view=VIEW * scale,
        camera_height=2.0 * scale,
        clip_end=100.0 * scale,
        ball=dict(
            radius=R * scale,
            location=(0.0, 0.0, Z * scale),
            ior=IOR,
            segments=segments,
            rings=rings,
            hide_from_indirect=True,
        ),
        lamp=dict(location=(0.0, 0.0, (Z + D) * scale), power=POWER * scale * scale),
    )
    sc = built.scene
    built.floor.name = "Table"
    sc.render.threads_mode = "AUTO"
    if engine == "CYCLES":
        c = sc.cycles
        c.use_denoising = False
        c.use_adaptive_sampling = False
        c.pixel_filter_type = "BOX"
        c.filter_width = 1.0
        c.seed = 1
        # MNEE runs only with a diffuse bounce left (diffuse_bounces 0 switches it
        # off); the ball is hidden from diffuse and glossy rays, so no other
        # indirect light is rendered: direct light + the caustic, as the reference.
        # Every Cycles render here uses these settings (MNEE on or off).
        c.max_bounces = 4
        c.diffuse_bounces = 1
        c.glossy_bounces = 0
        c.transmission_bounces = 4
        c.volume_bounces = 0
        c.transparent_max_bounces = 0
        c.caustics_refractive = False
        c.caustics_reflective = False
        c.sample_clamp_direct = 0.0
        c.sample_clamp_indirect = 0.0
    else:
        e = sc.eevee
        for attr, value in (
            ("use_raytracing", False),
            ("use_shadows", True),
            ("use_volumetric_shadows", False),
            ("use_gtao", False),
            ("use_bloom", False),
            ("use_ssr", False),
        ):
            if hasattr(e, attr):
                setattr(e, attr, value)
        if hasattr(sc.render, "filter_size"):
            sc.render.filter_size = 1.0
    return sc, built.floor, built.ball, built.lamp


def bpy_scene():
    import bpy

    return bpy.context.scene


def enable_mnee(sc, table, ball, lamp):
    sc.cycles.caustics_refractive = True
    ball.cycles.is_caustics_caster = True
    table.cycles.is_caustics_receiver = True
    lamp.data.cycles.is_caustics_light = True


#: CPU time (all threads of this process) of the last render.
LAST_CPU = [0.0]


def render(sc, path, samples):
    """(pixels, seconds): one render of `samples` samples (wall time; its CPU time
    in LAST_CPU[0]); pixels are the mean of the RGB channels (the scene is grey)."""
    import bpy

    if sc.render.engine == "CYCLES":
        sc.cycles.samples = samples
    else:
        sc.eevee.taa_render_samples = samples
    sc.render.filepath = str(path)
    c0 = time.process_time()
    t0 = time.perf_counter()
    bpy.ops.render.render(write_still=True)
    dt = time.perf_counter() - t0
    LAST_CPU[0] = time.process_time() - c0
    img = bpy.data.images.load(str(path))
    px = np.array(img.pixels[:], dtype=np.float64).reshape(img.size[1], img.size[0], 4)
    bpy.data.images.remove(img)
    return px[..., :3].mean(axis=2), dt


def generate_lens_lights(tier):
    """Run the operator's work with the given tier; (seconds, the lens light's
    parameters, message)."""
    import bpy
    from lens_lights.blender.commands.generate import generate

    sc = bpy.context.scene
    sc.lens_lights.energy_model = tier
    t0 = time.perf_counter()
    level, message, figures = generate(bpy.context)
    dt = time.perf_counter() - t0
    if level == "ERROR":
        raise RuntimeError(message)
    lights = [o for o in bpy.data.objects if o.type == "LIGHT" and o.lens_lights.is_lens_light]
    info = [
        dict(
            energy=o.data.energy,
            spot_size=math.degrees(o.data.spot_size),
            blend=o.data.spot_blend,
            z=o.location.z,
            scale=o.scale.x,
            nodes=bool(o.data.use_nodes),
            model=o.lens_lights.energy_model,
        )
        for o in lights
    ]
    return dt, info, message


# --------------------------------------------------------------------------- the runs


class Runner:
    def __init__(self, args, log):
        self.args, self.log = args, log
        self.tmp = Path(tempfile.mkdtemp(prefix="render_compare_"))
        self.rows = []  # dicts: method, samples, gen, render, total, l1, flux
        self.images = {}  # (method, samples) -> pixels
        self.notes = {}

    def measure(self, method, samples, img, dt, gen=0.0):
        row = dict(
            method=method,
            samples=samples,
            gen=gen,
            render=dt,
            total=gen + dt,
            cpu=LAST_CPU[0],
            l1=l1(img, self.ref, self.mask),
            flux=flux_ratio(img, self.ref, self.mask),
        )
        self.rows.append(row)
        self.images[method, samples] = img
        self.log(
            f"  {SHORT[method]:<24s} {samples:5d} spp  render {dt:7.2f} s"
            f"  (+ gen {gen:5.2f} s, CPU {LAST_CPU[0]:6.2f} s)  L1 {row['l1']:.4f}  flux ratio {row['flux']:.4f}"
        )
        return row

    def warm_up(self):
        """Load Cycles' kernels once (not counted anywhere)."""
        sc, *_ = build_scene("CYCLES")
        render(sc, self.tmp / "warm.exr", 1)

    def mnee(self, samples, scale=1.0):
        method = CYCLES_MNEE if scale == 1.0 else CYCLES_MNEE_X10
        self.log(f"(a) {LABEL[method]}, samples {samples}")
        sc, table, ball, lamp = build_scene("CYCLES", scale=scale)
        enable_mnee(sc, table, ball, lamp)
        for s in samples:
            img, dt = render(sc, self.tmp / f"mnee_{scale:g}_{s}.exr", s)
            self.measure(method, s, img, dt)

    def lens_lights(self, engine, tier, samples):
        method = (engine, tier)
        self.log(f"({'b' if engine == 'CYCLES' else 'c'}) {LABEL[method]}, samples {samples}")
        sc, *_ = build_scene(engine)
        gen, info, message = generate_lens_lights(tier)
        self.notes[method] = dict(info=info, message=message, gen=gen)
        self.log(f"  generated in {gen:.2f} s: {message}")
        for d in info:
            self.log(
                "  light: "
                + ", ".join(
                    f"{k} {v:.5g}" if isinstance(v, float) else f"{k} {v}" for k, v in d.items()
                )
            )
        if engine != "CYCLES":
            img, dt = render(sc, self.tmp / f"{engine}_{tier}_warm.exr", 1)
            self.notes[method]["warm_up"] = dt
            self.log(f"  warm-up render (shader compilation), not counted: {dt:.1f} s")
        for s in samples:
            img, dt = render(sc, self.tmp / f"{engine}_{tier}_{s}.exr", s)
            self.measure(method, s, img, dt, gen)

    def direct_check(self):
        """The camera, pixel footprint and radiometry: the table without the ball
        (Cycles, direct light only) against the analytic direct light."""
        import bpy

        sc, table, ball, lamp = build_scene("CYCLES")
        bpy.data.objects.remove(ball)
        img, _ = render(sc, self.tmp / "no_ball.exr", 16)
        ref = to_pixel(direct_average(rs=0.0))
        dev = np.abs(img / ref - 1.0)
        self.direct = dict(
            max_rel=float(dev.max()),
            p999=float(np.quantile(dev, 0.999)),
            n_out=int((dev > 1e-3).sum()),
            mean_ratio=float(img.sum() / ref.sum()),
        )
        self.log(
            f"check: no ball, direct light: rendered / analytic = {self.direct['mean_ratio']:.5f}, "
            f"99.9 % of pixels within {self.direct['p999']:.1e}, {self.direct['n_out']} pixel(s) "
            f"off by more than 1e-3 (largest {self.direct['max_rel']:.2e})"
        )

    def mnee_scales(self, tier):
        """MNEE on the same scene at other scales (lengths × s, power × s²), and
        lens lights of `tier` (None: none) for comparison."""
        self.scales = []
        for s in SCALES:
            ll = {}
            if tier:
                build_scene("CYCLES", scale=s)
                generate_lens_lights(tier)
                img, _ = render(bpy_scene(), self.tmp / f"ll_scale_{s}.exr", SCALE_SAMPLES)
                ll = dict(
                    ll_l1=l1(img, self.ref, self.mask), ll_flux=flux_ratio(img, self.ref, self.mask)
                )
            sc, table, ball, lamp = build_scene("CYCLES", scale=s)
            enable_mnee(sc, table, ball, lamp)
            img, dt = render(sc, self.tmp / f"mnee_scale_{s}.exr", SCALE_SAMPLES)
            self.scales.append(
                dict(
                    scale=s,
                    img=img,
                    tier=tier,
                    **ll,
                    dark=int(((img < 1e-6) & self.mask).sum()),
                    l1=l1(img, self.ref, self.mask),
                    flux=flux_ratio(img, self.ref, self.mask),
                    seconds=dt,
                    centre=float(img[PX // 2 - 2 : PX // 2 + 2, PX // 2 - 2 : PX // 2 + 2].mean()),
                )
            )
            self.log(
                f"  MNEE at scale {s:g} (R = {R * s * 100:g} cm), {SCALE_SAMPLES} spp: "
                f"L1 {self.scales[-1]['l1']:.4f}, flux ratio {self.scales[-1]['flux']:.4f}"
                + (
                    f"; lens lights {tier}: L1 {ll['ll_l1']:.4f}, flux ratio {ll['ll_flux']:.4f}"
                    if ll
                    else ""
                )
            )

    def mnee_meshes(self):
        """MNEE with the ball tessellated more and less finely."""
        self.meshes = []
        for seg, ring in MESHES:
            sc, table, ball, lamp = build_scene("CYCLES", segments=seg, rings=ring)
            enable_mnee(sc, table, ball, lamp)
            img, dt = render(sc, self.tmp / f"mnee_mesh_{seg}.exr", MESH_SAMPLES)
            dark = int(((img < 1e-6) & self.mask).sum())
            self.meshes.append(
                dict(
                    seg=seg,
                    ring=ring,
                    l1=l1(img, self.ref, self.mask),
                    flux=flux_ratio(img, self.ref, self.mask),
                    dark=dark,
                    img=img,
                )
            )
            self.log(
                f"  MNEE, ball {seg} × {ring}, {MESH_SAMPLES} spp: L1 {self.meshes[-1]['l1']:.4f}, "
                f"flux ratio {self.meshes[-1]['flux']:.4f}, {dark} black pixels in the region"
            )


def mitsuba_reference_check(log):
    """The reference against mitsuba in this very geometry (D = 5R, n = 1.5, the
    table 2R behind the ball), with bench/accuracy.py's light-tracing check."""
    sys.path.insert(0, str(ROOT / "bench"))
    import accuracy as bench_acc

    bench_acc.MITSUBA_CASES = ((D / R, IOR, BEHIND / R),)
    return bench_acc.mitsuba_check(log, width=160, spp=256)[0]


# --------------------------------------------------------------------------- output


def fmt_s(t):
    return f"{t:.2f} s" if t < 10 else f"{t:.1f} s"


def methods_in(rows):
    seen = []
    for r in rows:
        if r["method"] not in seen:
            seen.append(r["method"])
    return seen


def interp_error_at(rows, method, t):
    """The method's L1 at wall time t (log-log interpolation between its runs; None
    outside their range)."""
    pts = sorted((r["total"], r["l1"]) for r in rows if r["method"] == method)
    ts = np.array([p[0] for p in pts])
    es = np.array([p[1] for p in pts])
    if t < ts[0] or t > ts[-1]:
        return None
    return float(np.exp(np.interp(np.log(t), np.log(ts), np.log(es))))


def plots(run, models, files):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import LogNorm

    rows = run.rows
    methods = methods_in(rows)
    # 1. error against wall time
    fig, ax = plt.subplots(figsize=(8.5, 5.5))
    for m in methods:
        rs_ = sorted((r for r in rows if r["method"] == m), key=lambda r: r["total"])
        ax.plot(
            [r["total"] for r in rs_],
            [r["l1"] for r in rs_],
            marker="o",
            color=COLOR[m],
            label=SHORT[m],
            ls="--" if isinstance(m, tuple) and m[0] != "CYCLES" else "-",
        )
        for r in rs_:
            ax.annotate(
                str(r["samples"]),
                (r["total"], r["l1"]),
                fontsize=6,
                xytext=(2, 3),
                textcoords="offset points",
                color=COLOR[m],
            )
    floor = 0.5 * min(r["l1"] for r in rows)
    for m in methods:
        if isinstance(m, tuple) and m[1] in models and models[m[1]]["l1"] > floor:
            ax.axhline(models[m[1]]["l1"], color=COLOR[m], lw=0.6, ls=":")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_ylim(floor, None)
    ax.set_xlabel("wall time (s): render (+ generating the lens lights); 2 shared cores")
    ax.set_ylabel("relative L1 error in the caustic region")
    ax.set_title(
        "Glass ball on a table (R = 5 cm, n = 1.5, light 5R above): error against time\n"
        "(numbers: samples; dotted: each tier's model error, the limit of its curve)",
        fontsize=9,
    )
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, loc="best")
    fig.tight_layout()
    fig.savefig(files["error_time"], dpi=130)
    plt.close(fig)

    # 2. picture strip: rows = methods, columns = samples (+ the reference)
    ref_full = run.ref_full
    lo = float(np.percentile(run.ref[run.mask], 5)) * 0.3
    hi = float(ref_full.max())
    norm = LogNorm(vmin=lo, vmax=hi)
    cols = sorted({r["samples"] for r in rows})
    fig, axes = plt.subplots(
        len(methods) + 1,
        len(cols) + 1,
        figsize=(1.45 * (len(cols) + 1) + 0.4, 1.45 * (len(methods) + 1) + 0.5),
    )
    for a in axes.ravel():
        a.set_xticks([])
        a.set_yticks([])
        for s in a.spines.values():
            s.set_visible(False)
    theta = np.linspace(0, 2 * np.pi, 200)
    circle = (PX / 2 - 0.5 + RS / STEP * np.cos(theta), PX / 2 - 0.5 + RS / STEP * np.sin(theta))
    axes[0, 0].imshow(np.maximum(ref_full, lo), origin="lower", norm=norm, cmap="inferno")
    axes[0, 0].plot(*circle, color="cyan", lw=0.4)
    axes[0, 0].set_title("reference\n(exact optics)", fontsize=7)
    for j, s in enumerate(cols):
        axes[0, j + 1].set_title(f"{s} spp", fontsize=7)
    for i, m in enumerate(methods):
        axes[i + 1, 0].text(
            0.95,
            0.5,
            SHORT[m].replace(" LL ", "\nlens lights "),
            ha="right",
            va="center",
            fontsize=7,
            transform=axes[i + 1, 0].transAxes,
        )
        for j, s in enumerate(cols):
            img = run.images.get((m, s))
            if img is None:
                continue
            a = axes[i + 1, j + 1]
            a.imshow(np.maximum(img, lo), origin="lower", norm=norm, cmap="inferno")
            r = next(r for r in rows if r["method"] == m and r["samples"] == s)
            a.text(
                0.03,
                0.03,
                f"L1 {r['l1']:.2f}\n{fmt_s(r['total'])}",
                color="white",
                fontsize=5.5,
                transform=a.transAxes,
                va="bottom",
            )
    fig.suptitle(
        "The table from above (log colour scale, common to all; cyan: the ball's shadow;\n"
        "L1 in the caustic region, wall time)",
        fontsize=8,
    )
    fig.tight_layout(rect=(0, 0, 1, 0.97))
    fig.savefig(files["strip"], dpi=140)
    plt.close(fig)

    # 3. radial profiles of the most converged image of each method
    fig, ax = plt.subplots(figsize=(8.5, 5))
    x, y = pixel_grid()
    rr = np.hypot(x, y) / R
    edges = np.linspace(0, RS / R * 1.2, 37)
    mid = 0.5 * (edges[1:] + edges[:-1])

    def prof(img):
        return np.array(
            [img[(rr >= a) & (rr < b)].mean() for a, b in zip(edges[:-1], edges[1:], strict=False)]
        )

    ax.plot(mid, prof(ref_full), "k-", lw=2.5, label="reference (exact optics)")
    for m in methods:
        best = max((r for r in rows if r["method"] == m), key=lambda r: r["samples"])
        ax.plot(
            mid,
            prof(run.images[m, best["samples"]]),
            color=COLOR[m],
            ls="--" if isinstance(m, str) else "-",
            label=f"{SHORT[m]} ({best['samples']} spp)",
        )
    ax.set_yscale("log")
    ax.set_ylim(max(1e-3, float(prof(ref_full).min()) * 0.01), None)
    ax.axvline(RS / R, color="c", lw=0.8)
    ax.text(RS / R, ax.get_ylim()[1], " shadow edge", color="c", fontsize=7, va="top")
    ax.set_xlabel("distance from the axis on the table (R)")
    ax.set_ylabel("pixel value (radiance, albedo/π × E)")
    ax.set_title("Mean over rings of pixels (most samples of each method)", fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(files["profiles"], dpi=130)
    plt.close(fig)


def plot_mnee(run, path):
    """MNEE at the three scales and the three tessellations."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import LogNorm

    lo = float(np.percentile(run.ref[run.mask], 5)) * 0.3
    norm = LogNorm(vmin=lo, vmax=float(run.ref_full.max()))
    rows = [("scale", run.scales), ("mesh", run.meshes)]
    fig, axes = plt.subplots(2, 4, figsize=(8.6, 5.6))
    for a in axes.ravel():
        a.set_xticks([])
        a.set_yticks([])
    for i, (kind, items) in enumerate(rows):
        axes[i, 0].imshow(np.maximum(run.ref_full, lo), origin="lower", norm=norm, cmap="inferno")
        axes[i, 0].set_title("reference", fontsize=7)
        for j, it in enumerate(items[:3]):
            a = axes[i, j + 1]
            a.imshow(np.maximum(it["img"], lo), origin="lower", norm=norm, cmap="inferno")
            title = (
                f"MNEE, scale {it['scale']:g} (R {R * it['scale'] * 100:g} cm)"
                if kind == "scale"
                else f"MNEE, ball {it['seg']} × {it['ring']}"
            )
            a.set_title(title, fontsize=7)
            a.text(
                0.03,
                0.03,
                f"L1 {it['l1']:.2f}, flux {it['flux']:.2f}",
                color="white",
                fontsize=6,
                transform=a.transAxes,
            )
    fig.suptitle(
        f"Cycles MNEE: the same scene scaled (power × scale², {SCALE_SAMPLES} spp; top) and "
        f"tessellated differently ({MESH_SAMPLES} spp; bottom). Log colour scale as the strip.",
        fontsize=8,
    )
    fig.tight_layout(rect=(0, 0, 1, 0.95), h_pad=3.0)
    fig.savefig(path, dpi=130)
    plt.close(fig)


def headline(run, mnee=CYCLES_MNEE):
    """Equal-time comparison of each lens-light method against MNEE (`mnee`: which
    MNEE curve)."""
    rows = run.rows
    if not any(r["method"] == mnee for r in rows):
        return [], None
    out = []
    for m in methods_in(rows):
        if isinstance(m, str):
            continue
        for r in sorted((r for r in rows if r["method"] == m), key=lambda r: r["total"]):
            e_m = interp_error_at(rows, mnee, r["total"])
            if e_m is None:
                continue
            out.append(
                dict(
                    method=m,
                    samples=r["samples"],
                    total=r["total"],
                    l1=r["l1"],
                    mnee=e_m,
                    factor=e_m / r["l1"],
                )
            )
    mnee_best = min(r["l1"] for r in rows if r["method"] == mnee)
    return out, mnee_best


def _factor_range(cs):
    f = [c["factor"] for c in cs]
    lo, hi = min(f), max(f)
    fmt = (
        (lambda x: f"{x:.0f}")
        if lo >= 10
        else (lambda x: f"{x:.1f}")
        if lo >= 1
        else (lambda x: f"{x:.2f}")
    )
    return lo, hi, (f"{fmt(lo)} ×" if abs(hi - lo) < 0.05 * hi else f"{fmt(lo)}–{fmt(hi)} ×")


def headline_lines(run, comps, mnee_best):
    """The headline, from the numbers (which tiers beat MNEE at equal time, by how much)."""
    by = {}
    for c in comps:
        by.setdefault(c["method"], []).append(c)
    mnee_rows = [r for r in run.rows if r["method"] == CYCLES_MNEE]
    mnee_flux = max(mnee_rows, key=lambda r: r["samples"])["flux"]
    t_lo, t_hi = min(r["total"] for r in mnee_rows), max(r["total"] for r in mnee_rows)
    out = []
    order = [("CYCLES", "EXACT_PROFILE"), ("CYCLES", "FITTED"), ("BLENDER_EEVEE", "FITTED")]
    lead = next((m for m in order if m in by), None)
    if lead is None:
        lead = max(by, key=lambda m: float(np.median([c["factor"] for c in by[m]])))
    cs = sorted(by[lead], key=lambda c: c["total"])
    top = max(cs, key=lambda c: c["factor"])
    # from which render on is every later one better than MNEE?
    k = len(cs)
    while k > 0 and cs[k - 1]["factor"] > 1.0:
        k -= 1
    wins, loses = cs[k:], cs[:k]
    lose_spp = ", ".join(str(c["samples"]) for c in loses)
    lose_f = ", ".join(f"{c['factor']:.2f} ×" for c in loses)
    name = SHORT[lead] + (
        ", the tier AUTO picks in Cycles" if lead == ("CYCLES", "EXACT_PROFILE") else ""
    )
    if wins:
        mid = [c for c in wins if c is not top]
        out.append(
            f"**At equal render time, lens lights beat Cycles' own caustics in the caustic region "
            f"by a factor of {top['factor']:.0f} in relative L1 error** ({name}: L1 {top['l1']:.4f} "
            f"at {top['samples']} spp in {fmt_s(top['total'])}, MNEE {top['mnee']:.3f} in the same "
            f"time) — and by {wins[0]['factor']:.1f} × already at {wins[0]['samples']} spp "
            f"({fmt_s(wins[0]['total'])})"
            + (
                ", "
                + ", ".join(
                    f"{c['factor']:.0f} × at {c['samples']} spp ({fmt_s(c['total'])})"
                    for c in mid[1:]
                )
                if len(mid) > 1
                else ""
            )
            + f"; every render of it from {wins[0]['samples']} spp on beats MNEE at the same time"
            + (
                f", while its {lose_spp}-spp render{'s are' if len(loses) > 1 else ' is'} still "
                f"too noisy ({lose_f})"
                if loses
                else ""
            )
            + f". Times between {fmt_s(t_lo)} and {fmt_s(t_hi)}, where both were run. This is at "
            f"table-top scale; made 10 × larger, the same scene is rendered nearly right by MNEE "
            f"(below)."
        )
    else:
        lo, hi, txt = _factor_range(cs)
        out.append(
            f"**At equal render time, lens lights do not beat Cycles' own caustics here** "
            f"with {name}: MNEE / lens lights = {txt}."
        )
    out.append("")
    for m, cs in by.items():
        if m == lead:
            continue
        lo, hi, txt = _factor_range(cs)
        if lo > 1.0:
            verdict = f"beats MNEE by {txt}"
        elif hi < 1.0:
            verdict = f"does **not** beat MNEE: MNEE / lens lights = {txt}"
        else:
            good = [c for c in cs if c["factor"] > 1.0]
            verdict = (
                f"beats MNEE from {min(c['samples'] for c in good)} spp on "
                f"({_factor_range(good)[2]}), not below ({txt} over all its renders)"
            )
        extra = ""
        note = run.notes.get(m)
        if m[1] in ("THESIS", "PHYSICAL") and note and note["info"]:
            d = note["info"][0]
            foot = d["z"] * math.tan(math.radians(0.5 * d["spot_size"])) * d["scale"]
            f_in, f_all = run.beam.flux_within_radius(Z, [foot, RS])
            extra = (
                f" — its cone (apex at the paraxial image, {d['z'] * 100:.1f} cm above the "
                f"table, {d['spot_size']:.3g}° wide) lights a disc of {foot * 1000:.1f} mm "
                f"radius ({foot / STEP:.1f} pixels) and leaves the rest of the shadow "
                f"({RS * 1000:.0f} mm) dark, where {1 - f_in / f_all:.0%} of the true "
                f"caustic's flux lands"
            )
        out.append(f"* {LABEL[m]} {verdict}{extra}.")
    out.append(
        f"* Cycles' MNEE never gets below L1 {mnee_best:.3f}, whatever the samples: it is "
        f"biased, not noisy — its caustic carries {mnee_flux:.0%} of the true flux in the "
        f"region, and it has black rings (see the strip and the MNEE sections below)."
    )
    return out


TEMPLATE = Path(__file__).resolve().parent / "templates" / "render_compare.md"


def report_sections(path=TEMPLATE) -> dict[str, str]:
    """The report's prose: {name: text} of the template's `<!-- section: NAME -->`
    parts (each to be filled by `str.format`)."""
    sections, name, lines = {}, None, []
    for line in path.read_text().splitlines(keepends=True):
        m = re.fullmatch(r"<!-- section: (\w+) -->\n?", line)
        if m:
            if name:
                sections[name] = "".join(lines)
            name, lines = m[1], []
        elif name:
            lines.append(line)
    if name:
        sections[name] = "".join(lines)
    return sections


def write_report(run, models, files, args, wall, mitsuba, tiers_missing, out=None):
    """reports/render_compare.md (or `out`): the numbers of `run` in the prose of
    bench/templates/render_compare.md."""
    rows = run.rows
    t = report_sections()
    parts = []

    def w(section, **values):
        parts.append(t[section].format(**values))

    def inline(section, **values):
        return t[section].format(**values).rstrip("\n")

    w(
        "header",
        minutes=wall / 60,
        bpy_version=run.bpy_version,
        argv=(" " + " ".join(args.argv)) if args.argv else "",
        strip=files["strip"].name,
        error_time=files["error_time"].name,
        profiles=files["profiles"].name,
        mnee_picture=inline("mnee_picture", mnee=files["mnee"].name) if "mnee" in files else "",
    )
    w(
        "scene",
        R_cm=R * 100,
        IOR=IOR,
        behind_cm=BEHIND * 100,
        ALBEDO=ALBEDO,
        POWER=POWER,
        D_cm=D * 100,
        D_R=D / R,
        view_cm=VIEW * 100,
        PX=PX,
        step_mm=STEP * 1000,
        region_px=int(run.mask.sum()),
        RS_R=RS / R,
        RS_cm=RS * 100,
        gen_times=gen_times(run),
        warm_times=warm_times(run),
    )
    if mitsuba:
        mitsuba_result = inline(
            "mitsuba_done",
            paths_M=mitsuba["paths"] / 1e6,
            **{k: mitsuba[k] for k in ("flux_ratio", "ring_l1", "ring_l1_mf", "noise", "seconds")},
        )
    else:
        mitsuba_result = inline("mitsuba_skipped")
    w(
        "reference",
        D_R=D / R,
        IOR=IOR,
        behind_R=BEHIND / R,
        mitsuba_result=mitsuba_result,
        direct_ratio=run.direct["mean_ratio"],
        direct_p999=run.direct["p999"],
        direct_n_out=run.direct["n_out"],
        direct_max=run.direct["max_rel"],
    )
    x10 = [r for r in rows if r["method"] == CYCLES_MNEE_X10]
    if x10:
        b = max(x10, key=lambda r: r["samples"])
        w("check_x10", l1=b["l1"], flux=b["flux"], samples=b["samples"])
    w("check_mesh", mesh_dev=1 - math.cos(math.pi / 64))
    w("results")
    for r in rows:
        w(
            "results_row",
            label=LABEL[r["method"]],
            samples=r["samples"],
            gen=fmt_s(r["gen"]) if r["gen"] else "–",
            render=fmt_s(r["render"]),
            total=fmt_s(r["total"]),
            cpu=fmt_s(r["cpu"]),
            l1=r["l1"],
            flux=r["flux"],
        )
    w("models", behind_R=BEHIND / R)
    for m in methods_in(rows):
        if isinstance(m, str) or m[1] not in models:
            continue
        best = max((r for r in rows if r["method"] == m), key=lambda r: r["samples"])
        w(
            "models_row",
            short=SHORT[m],
            model_l1=models[m[1]]["l1"],
            best_l1=best["l1"],
            best_samples=best["samples"],
            diff=best["l1"] - models[m[1]]["l1"],
        )
    comps, mnee_best = headline(run)
    w("headline")
    if comps:
        parts.extend(line + "\n" for line in headline_lines(run, comps, mnee_best))
        w("equal_time")
        for c in comps:
            w(
                "equal_time_row",
                short=SHORT[c["method"]],
                samples=c["samples"],
                total=fmt_s(c["total"]),
                l1=c["l1"],
                mnee=c["mnee"],
                factor=c["factor"],
            )
        parts.append("\n")
    else:
        w("no_mnee")
    comps10, best10 = headline(run, CYCLES_MNEE_X10)
    if comps10:
        w("x10", best10=best10)
        by = {}
        for c in comps10:
            by.setdefault(c["method"], []).append(c)
        for m, cs in by.items():
            f = [c["factor"] for c in cs]
            rng = (
                f"{min(f):.2f} ×"
                if max(f) - min(f) < 0.01
                else f"{min(f):.2f}–{max(f):.2f} × ({len(f)} renders)"
            )
            w("x10_row", short=SHORT[m], range=rng, median=float(np.median(f)))
        ex = by.get(("CYCLES", "EXACT_PROFILE"))
        if ex:
            w("x10_exact")
            for c in ex:
                w(
                    "x10_exact_row",
                    samples=c["samples"],
                    total=fmt_s(c["total"]),
                    l1=c["l1"],
                    mnee=c["mnee"],
                    factor=c["factor"],
                )
            b10 = max(
                (r for r in rows if r["method"] == CYCLES_MNEE_X10), key=lambda r: r["samples"]
            )
            w("x10_exact_end", l1=b10["l1"], dark=1 - b10["flux"], samples=b10["samples"])
        else:
            parts.append("\n")
    if getattr(run, "scales", None):
        tier = run.scales[0].get("tier")
        centre = run.ref[PX // 2 - 2 : PX // 2 + 2, PX // 2 - 2 : PX // 2 + 2].mean()
        w(
            "scales",
            samples=SCALE_SAMPLES,
            centre_ref=centre,
            tier_head=f" lens lights {tier}: L1 / flux ratio |" if tier else "",
            tier_rule="---|" if tier else "",
        )
        for sc in run.scales:
            w(
                "scales_row",
                scale=sc["scale"],
                radius_cm=R * sc["scale"] * 100,
                l1=sc["l1"],
                flux=sc["flux"],
                centre=sc["centre"],
                dark=sc["dark"],
                tier_cells=f" {sc['ll_l1']:.4f} / {sc['ll_flux']:.3f} |" if tier else "",
            )
        w("scales_end")
    if getattr(run, "meshes", None):
        w("meshes", samples=MESH_SAMPLES)
        for m in run.meshes:
            w("meshes_row", **{k: m[k] for k in ("seg", "ring", "l1", "flux", "dark")})
        w("meshes_end")
    obs = observations(run, models)
    if obs:
        w("observations")
        parts.extend(line + "\n" for line in obs)
        parts.append("\n")
    w("notes")
    parts.extend(line + "\n" for line in notes_lines(run, models, tiers_missing))
    parts.append("\n")
    (out or REPORTS / "render_compare.md").write_text("".join(parts))


def observations(run, models):
    """Things the numbers show that are worth saying (each computed here)."""
    out = []
    rows = run.rows
    ex = run.images.get((("CYCLES", "EXACT_PROFILE"), 1))
    fi = [r for r in rows if r["method"] == ("CYCLES", "FITTED")]
    exr = [r for r in rows if r["method"] == ("CYCLES", "EXACT_PROFILE")]
    if ex is not None and exr:
        zero = float((ex[run.mask] == 0).mean())
        r1 = next(r for r in exr if r["samples"] == 1)
        out.append(
            f"* EXACT_PROFILE is noisy at few samples, although it is unbiased (flux ratio "
            f"{r1['flux']:.2f} at 1 spp): at 1 spp {zero:.0%} of the region's pixels are black, "
            f"the rest about {1 / max(1 - zero, 1e-9):.1f} × too bright (L1 {r1['l1']:.2f} ≈ "
            f"2 × {zero:.2f}). Cycles' light selection picks the lens light for only about "
            f"{1 - zero:.0%} of the samples in the shadow, where the primary light's samples are "
            f"wasted (it is shadowed, but the light tree does not know): the profile light's "
            f"nominal energy is small (twice the beam's flux, "
            f"{run.notes[('CYCLES', 'EXACT_PROFILE')]['info'][0]['energy']:.3g} W against the "
            f"primary's {POWER:g} W). It needs about 64 spp to get below L1 0.05"
            + (
                f"; FITTED (energy {run.notes[('CYCLES', 'FITTED')]['info'][0]['energy']:.3g} W) "
                f"reaches its model error by 16 spp"
                if fi and ("CYCLES", "FITTED") in run.notes
                else ""
            )
            + ". Raising the profile light's sampling weight (e.g. a larger energy with the "
            "texture scaled down) might cut this noise; not tried here."
        )
    ee = [r for r in rows if r["method"] == ("BLENDER_EEVEE", "FITTED")]
    if ee and fi:
        e1 = min(ee, key=lambda r: r["samples"])
        c16 = min(
            (r for r in fi if r["l1"] <= e1["l1"] * 1.01), key=lambda r: r["total"], default=None
        )
        if c16:
            out.append(
                f"* EEVEE is the slowest engine here: its FITTED render at {e1['samples']} spp takes "
                f"{fmt_s(e1['total'])} (L1 {e1['l1']:.3f}) where Cycles reaches the same error in "
                f"{fmt_s(c16['total'])} ({c16['samples']} spp). This is EEVEE on software OpenGL "
                f"(the bpy module, no GPU); on a GPU it is normally far faster (not measured "
                f"here). EEVEE converges to the same image as Cycles for the same tier (FITTED: "
                f"L1 {min(ee, key=lambda r: -r['samples'])['l1']:.4f} against "
                f"{min(fi, key=lambda r: -r['samples'])['l1']:.4f}; the same spot model in both "
                f"engines)."
            )
    mb = [r for r in rows if r["method"] == CYCLES_MNEE]
    if mb:
        best = max(mb, key=lambda r: r["samples"])
        img = run.images[CYCLES_MNEE, best["samples"]]
        x, y = pixel_grid()
        rr = np.hypot(x, y) / R
        inner = rr < 0.25
        outer = (rr > 1.1) & run.mask
        out.append(
            f"* Where MNEE goes wrong at table-top scale: within 0.25 R of the axis its pixels are "
            f"{img[inner].mean() / run.ref[inner].mean():.3f} × the truth (about "
            f"{run.ref[inner].mean() / img[inner].mean():.0f} × too dark: it has no bright core "
            f"at all, a flat {img[inner].mean():.2f} instead of a peak), while in the outer part "
            f"of the shadow (1.1 R to its edge: light that passed near the ball's rim, strongly "
            f"refracted) it is {img[outer].mean() / run.ref[outer].mean():.2f} × the truth "
            f"({best['samples']} spp; render_compare_profiles.png)."
        )
    m1 = run.images.get((CYCLES_MNEE, 1))
    if m1 is not None:
        i = np.arange(PX)
        on = run.mask[i, i]
        zeros = int((m1[i, i][on] == 0).sum())
        j = PX - 1 - i
        anti = int((m1[i, j][run.mask[i, j]] == 0).sum())
        if zeros > 0.5 * on.sum():
            out.append(
                f"* At 1 spp MNEE leaves {zeros} of the {int(on.sum())} pixels on the table's "
                f"diagonal inside the shadow black (the edge the plane's two triangles share; the "
                f"direct light there is fine; on the other diagonal {anti} are black): a black "
                f"line in the 1-spp picture that fades with samples."
            )
    return out


def gen_times(run):
    parts = [f"{SHORT[m]} {fmt_s(v['gen'])}" for m, v in run.notes.items()]
    return ", ".join(parts) if parts else "none"


def warm_times(run):
    parts = [f"{SHORT[m]} {fmt_s(v['warm_up'])}" for m, v in run.notes.items() if "warm_up" in v]
    return ", ".join(parts) if parts else "no EEVEE renders"


def notes_lines(run, models, tiers_missing):
    out = []
    if tiers_missing:
        out.append(
            f"* Not rendered: {', '.join(tiers_missing)} (not offered by the operator's "
            f"energy-model setting when this ran)."
        )
    for m, v in run.notes.items():
        lights = "; ".join(
            f"{d['model'] or '?'} spot {d['spot_size']:.3g}°, blend {d['blend']:.3g}, "
            f"energy {d['energy']:.4g} W, {d['z'] * 100:.2f} cm above the table"
            + (f", scale {d['scale']:.3g}" if abs(d["scale"] - 1) > 1e-6 else "")
            + (", node tree" if d["nodes"] else "")
            for d in v["info"]
        )
        out.append(
            f"* {LABEL[m]}: {len(v['info'])} lens light(s): {lights}. Operator: {v['message']}"
        )
    for tier, mm in models.items():
        lt_ = mm["light"]
        out.append(
            f"* Pure {tier} light for comparison (addon code): energy {lt_.energy_w:.4g} W, "
            f"spot {lt_.spot_size_deg:.3g}°, blend {lt_.spot_blend:.3g}, "
            f"{lt_.location[2] * 100:.2f} cm above the table."
        )
    return out


# --------------------------------------------------------------------------- main


def _rescale_profile_lights(k):
    """Energy × k, the node tree's strength_scale ÷ k, on every EXACT_PROFILE lens
    light of the scene (the image's expectation is unchanged)."""
    import bpy

    for o in bpy.data.objects:
        if o.type != "LIGHT" or not o.lens_lights.is_lens_light or not o.data.use_nodes:
            continue
        o.data.energy *= k
        for n in o.data.node_tree.nodes:
            if (
                n.bl_idname == "ShaderNodeMath"
                and n.operation == "MULTIPLY"
                and n.outputs[0].links
                and n.outputs[0].links[0].to_node.bl_idname == "ShaderNodeEmission"
            ):
                n.inputs[1].default_value /= k


def quick_look(args) -> int:
    """`--only`: L1 and flux ratio of a few Cycles lens-light tiers, printed only."""
    import bpy

    t0 = time.perf_counter()

    def log(msg):
        print(f"[{time.perf_counter() - t0:6.1f} s] {msg}", flush=True)

    load_extension()
    run = Runner(args, log)
    beam_px, direct_px, run.beam = reference_maps()
    run.ref, run.mask = beam_px, region_mask()
    # pixels entirely outside the shadow: the primary's direct light (and the rim of the beam)
    x, y = pixel_grid()
    outside = np.hypot(x, y) - STEP / math.sqrt(2.0) >= RS
    ref_full = beam_px + direct_px
    run.warm_up()
    samples = args.samples or SAMPLES_CYCLES_LL
    table = []
    for tier in args.only:
        for k in args.energy_factor if tier == "EXACT_PROFILE" else [1.0]:
            sc, *_ = build_scene("CYCLES")
            gen, info, message = generate_lens_lights(tier)
            if k != 1.0:
                _rescale_profile_lights(k)
            energies = [o.data.energy for o in bpy.data.objects if o.type == "LIGHT"]
            log(f"{tier} k = {k:g}: light energies {', '.join(f'{e:.4g}' for e in energies)} W")
            for s in samples:
                res = []
                for seed in args.seeds:
                    sc.cycles.seed = seed
                    img, dt = render(sc, run.tmp / f"quick_{tier}_{k:g}_{s}_{seed}.exr", s)
                    res.append(
                        (
                            l1(img, run.ref, run.mask),
                            flux_ratio(img, run.ref, run.mask),
                            l1(img, ref_full, outside),
                            l1(img, ref_full, np.ones_like(outside)),
                            dt,
                        )
                    )
                e, f, o, a, dt = np.mean(res, axis=0)
                table.append((tier, k, s, e, f, o, a, dt))
                log(
                    f"  {s:5d} spp  L1 {e:.4f}  flux ratio {f:.4f}  L1 outside the shadow {o:.4f}  "
                    f"L1 whole image {a:.4f}  render {dt:.2f} s"
                )
    print(
        f"\nmeans over seeds {args.seeds}\n| tier | k | samples | L1 (caustic region) | flux ratio | "
        "L1 outside the shadow | L1 whole image | render |\n|---|---|---|---|---|---|---|---|"
    )
    for tier, k, s, e, f, o, a, dt in table:
        print(f"| {tier} | {k:g} | {s} | {e:.4f} | {f:.4f} | {o:.4f} | {a:.4f} | {dt:.2f} s |")
    shutil.rmtree(run.tmp, ignore_errors=True)
    return 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--quick", action="store_true", help="two sample counts per method")
    ap.add_argument("--tiers", nargs="+", default=list(ALL_TIERS), help="Cycles lens-light tiers")
    ap.add_argument("--no-mnee", action="store_true")
    ap.add_argument("--no-eevee", action="store_true")
    ap.add_argument(
        "--no-mitsuba", action="store_true", help="skip the mitsuba check of the reference"
    )
    ap.add_argument("--no-scales", action="store_true", help="skip MNEE at other scales")
    ap.add_argument(
        "--only",
        nargs="+",
        metavar="TIER",
        help="quick look: render only these Cycles lens-light tiers (no MNEE, EEVEE, "
        "mitsuba or side experiments) and print their L1; writes no report",
    )
    ap.add_argument("--samples", nargs="+", type=int, help="sample counts (with --only)")
    ap.add_argument(
        "--seeds",
        nargs="+",
        type=int,
        default=[1],
        help="Cycles seeds (with --only; the errors printed are means over them)",
    )
    ap.add_argument(
        "--energy-factor",
        nargs="+",
        type=float,
        default=[1.0],
        metavar="K",
        help="with --only: also render each EXACT_PROFILE light with its energy × K "
        "and its node tree's strength_scale ÷ K (same expectation)",
    )
    args = ap.parse_args(argv)
    if args.only:
        return quick_look(args)
    args.argv = list(argv if argv is not None else sys.argv[1:])
    REPORTS.mkdir(exist_ok=True)
    t0 = time.perf_counter()

    def log(msg):
        print(f"[{time.perf_counter() - t0:6.1f} s] {msg}", flush=True)

    import bpy

    load_extension()
    offered = available_tiers()
    tiers = [t for t in args.tiers if t in offered]
    missing = [t for t in args.tiers if t not in offered]
    eevee_tiers = [t for t in EEVEE_TIERS if t in offered] if not args.no_eevee else []
    missing += [f"EEVEE {t}" for t in EEVEE_TIERS if t not in offered and not args.no_eevee]
    log(
        f"bpy {bpy.app.version_string}; operator tiers {offered}; rendering Cycles {tiers}, "
        f"EEVEE {eevee_tiers}" + (f"; missing {missing}" if missing else "")
    )

    run = Runner(args, log)
    run.bpy_version = bpy.app.version_string
    log(
        f"reference: exact optics on {PX} × {PX} pixels (D = {D / R:g} R, n = {IOR}, table "
        f"{BEHIND / R:g} R behind the ball, shadow radius {RS / R:.3f} R)"
    )
    beam_px, direct_px, run.beam = reference_maps()
    run.ref = beam_px  # in the region the direct light is 0
    run.ref_full = beam_px + direct_px
    run.mask = region_mask()
    log(
        f"  {int(run.mask.sum())} pixels in the caustic region; reference beam flux there "
        f"{run.ref[run.mask].sum():.4g} (pixel units)"
    )
    models = {}
    for tier in dict.fromkeys(tiers + eevee_tiers):
        img, light = tier_model_map(tier)
        models[tier] = dict(
            l1=l1(img, run.ref, run.mask),
            flux=flux_ratio(img, run.ref, run.mask),
            light=light,
            img=img,
        )
        log(
            f"  model limit {tier:<14s}: L1 {models[tier]['l1']:.4f}, flux ratio {models[tier]['flux']:.4f}"
        )
    mitsuba = None
    if not args.no_mitsuba:
        log("mitsuba check of the exact optics in this geometry")
        mitsuba = mitsuba_reference_check(log)

    run.warm_up()
    run.direct_check()
    samples_m = QUICK["mnee"] if args.quick else SAMPLES_MNEE
    samples_c = QUICK["cycles"] if args.quick else SAMPLES_CYCLES_LL
    samples_e = QUICK["eevee"] if args.quick else SAMPLES_EEVEE
    if not args.no_mnee:
        run.mnee(samples_m)
        if not args.no_scales:
            run.mnee(samples_m, scale=10.0)
    for tier in tiers:
        run.lens_lights("CYCLES", tier, samples_c)
    for tier in eevee_tiers:
        try:
            run.lens_lights("BLENDER_EEVEE", tier, samples_e)
        except Exception as exc:  # EEVEE needs a GL context
            log(f"  EEVEE {tier} failed: {type(exc).__name__}: {exc}")
            missing.append(f"EEVEE {tier} ({type(exc).__name__}: {exc})")
    if not args.no_mnee and not args.no_scales:
        log("MNEE at other scales")
        ll_tier = next((t for t in ("EXACT_PROFILE", "FITTED", "PHYSICAL") if t in tiers), None)
        run.mnee_scales(ll_tier)
        log("MNEE with other tessellations of the ball")
        run.mnee_meshes()

    files = {k: REPORTS / f"render_compare_{k}.png" for k in ("error_time", "strip", "profiles")}
    plots(run, models, files)
    if getattr(run, "scales", None) and getattr(run, "meshes", None):
        files["mnee"] = REPORTS / "render_compare_mnee.png"
        plot_mnee(run, files["mnee"])
    write_report(run, models, files, args, time.perf_counter() - t0, mitsuba, missing)
    log(f"wrote {REPORTS / 'render_compare.md'} and {', '.join(f.name for f in files.values())}")
    shutil.rmtree(run.tmp, ignore_errors=True)  # the EXR renders
    return 0


if __name__ == "__main__":
    sys.exit(main())
