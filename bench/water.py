"""Water (issue 26): the caustic net of a sine-wave surface, Cycles and EEVEE Generate
against the height-field reference.

    ./lens-lights bench water [--px 96] [--rays 4e6] [--grid 200] [--depths 0.5,0.7,1.0]
                              [--no-eevee] [--no-cycles] [--cycles-samples 64]

Scene (metres): a 1 × 1 m water surface z = Σ a_k sin(k_k·(x, y) + φ_k) (three waves:
6/5/3 mm high, 30/22/17 cm long, in three directions) meshed as a ``--grid`` ×
``--grid`` plane (Principled BSDF, transmission 1, roughness 0, IOR 1.333, smooth),
its rest plane ``--depths`` above a white Lambertian floor (one row each) (albedo 0.8), a sun 60°
above the horizon (strength 3, angle 0); an orthographic camera straight down over
the lit floor, the water hidden from the camera (so the camera sees the floor as it
lies in the water: the layer's E/n², Cycles' own convention, SPEC §9), linear EXR,
no world.

Truth: `reference.water_tracer.trace_floor` — the analytic height field (exact
normals), Snell and unpolarised Fresnel, binned on the camera's pixels, divided by n².

A second reference with another seed, measured against the first, shows the
reference's own noise in the metric (about √2 × one reference's).

Columns: Cycles Generate, EEVEE Generate (tier AUTO, Replace Cycles' Caustics): the
render with Generate's layer minus the render without it, as irradiance (pixel × π /
albedo). Metrics as bench/real_scenes.py: relative L1 over the region (truth > 1 % of
its peak, or the render > 5 % of it), flux ratio, peak ratio; times of Generate and of
the render. Targets (issue 26): L1 ≤ 0.15, flux within ±10 %. Writes reports/water.md
and reports/water.png.
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "scripts"))
sys.path.insert(0, str(ROOT / "bench"))

from measuring_scene import (  # noqa: E402
    add_diffuse_floor,
    add_top_camera,
    measured_render_settings,
    new_measuring_scene,
    render_irradiance,
)
from real_scenes import ALBEDO, eevee_id, load_extension, metrics  # noqa: E402

from reference.water_tracer import SineWaves, height_field_mesh, trace_floor  # noqa: E402

REPORTS = ROOT / "reports"
IOR = 1.333
STRENGTH = 3.0
ELEVATION = 60.0
L1_TARGET, FLUX_TARGET = 0.15, 0.10

WAVES = SineWaves(
    0.0,
    (0.006, 0.005, 0.003),
    (
        (2 * math.pi / 0.30, 0.0),
        (2 * math.pi / 0.22 * math.cos(math.radians(60)), 2 * math.pi / 0.22 * math.sin(math.radians(60))),
        (2 * math.pi / 0.17 * math.cos(math.radians(-50)), 2 * math.pi / 0.17 * math.sin(math.radians(-50))),
    ),
    (0.3, 1.1, 2.0),
    (-0.5, 0.5, -0.5, 0.5),
)  # fmt: skip


def sun_direction():
    e = math.radians(ELEVATION)
    return np.array([math.cos(e), 0.0, -math.sin(e)])


def frame(depth, view):
    """(cx, cy, view): the camera's square over the middle of the lit floor (the
    water's middle moved along the refracted sun)."""
    d = sun_direction()
    st = math.hypot(d[0], d[1]) / IOR
    shift = depth * st / math.sqrt(1.0 - st * st)
    return shift, 0.0, view


def add_water(depth, grid):
    """The waves as a smooth glass-of-water mesh whose rest plane is ``depth`` above
    the floor."""
    import bpy
    from measuring_scene import new_material

    v, t, _cn = height_field_mesh(WAVES, grid, grid)
    v = v + [0.0, 0.0, depth]
    me = bpy.data.meshes.new("Water")
    me.from_pydata([tuple(map(float, p)) for p in v], [], [tuple(map(int, f)) for f in t])
    me.validate()
    me.shade_smooth()
    mat = new_material("Water")
    bsdf = mat.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Transmission Weight"].default_value = 1.0
    bsdf.inputs["IOR"].default_value = IOR
    bsdf.inputs["Roughness"].default_value = 0.0
    bsdf.inputs["Base Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    me.materials.append(mat)
    ob = bpy.data.objects.new("Water", me)
    bpy.context.scene.collection.objects.link(ob)
    ob.visible_camera = False
    return ob


def build(engine, px, samples, depth, grid, fr):
    import bpy
    from mathutils import Vector

    sc = new_measuring_scene(engine, px)
    add_diffuse_floor(6.0, ALBEDO)
    add_water(depth, grid)
    data = bpy.data.lights.new("Sun", "SUN")
    data.energy, data.angle = STRENGTH, 0.0
    sun = bpy.data.objects.new("Sun", data)
    bpy.context.scene.collection.objects.link(sun)
    sun.rotation_mode = "QUATERNION"
    sun.rotation_quaternion = Vector(tuple(sun_direction())).to_track_quat("-Z", "Y")
    add_top_camera(fr[0], fr[1], depth + 0.5, fr[2], clip_end=10.0)
    measured_render_settings(sc, engine, samples)
    if engine == "CYCLES":
        c = sc.cycles
        c.diffuse_bounces = 1
        c.sample_clamp_direct = c.sample_clamp_indirect = 0.0
    return sc


def render(sc, path):
    """(irradiance on the floor per pixel, W/m², the render's seconds)."""
    return render_irradiance(sc, path, ALBEDO)


def generated(engine, px, samples, depth, grid, fr, tmp):
    """(the layer's irradiance, render s, Generate s, its report)."""
    import bpy
    from lens_lights.blender.commands.generate import generate as run

    sc = build(engine, px, samples, depth, grid, fr)
    before = {o.name for o in bpy.data.objects}
    sc.lens_lights.energy_model = "AUTO"
    sc.lens_lights.replace_cycles_caustics = True
    t0 = time.perf_counter()
    level, message, _ = run(bpy.context)
    t_gen = time.perf_counter() - t0
    made = [o for o in bpy.data.objects if o.name not in before]
    if level == "ERROR" or not made:
        return None, 0.0, t_gen, message
    img, dt = render(sc, Path(tmp) / "lit.exr")
    for o in made:
        o.hide_render = True
    base, _ = render(sc, Path(tmp) / "base.exr")
    return img - base, dt, t_gen, message


def truth(px, n_rays, depth, fr, seed=11):
    cx, cy, view = fr
    ex = cx + (np.arange(px + 1) / px - 0.5) * view
    ey = cy + (np.arange(px + 1) / px - 0.5) * view
    shifted = SineWaves(WAVES.z0 + depth, WAVES.amplitudes, WAVES.wavevectors, WAVES.phases,
                        WAVES.bounds)  # fmt: skip
    t = trace_floor(
        shifted, 0.0, ex, ey, ior=IOR, sun_direction=sun_direction(), sun_strength=STRENGTH,
        n_rays=n_rays, seed=seed,
    )  # fmt: skip
    return t.irradiance


def strip(rows, titles, path):
    """One row of maps per depth (label, maps), the reference's scale in each."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n, k = len(rows), len(titles)
    fig, axes = plt.subplots(n, k, figsize=(2.6 * k, 2.7 * n), squeeze=False)
    for r, (label, maps) in enumerate(rows):
        vmax = float(maps[0].max())
        for c, (m, title) in enumerate(zip(maps, titles, strict=True)):
            ax = axes[r, c]
            ax.set_xticks([])
            ax.set_yticks([])
            if r == 0:
                ax.set_title(title, fontsize=8)
            if m is not None:
                ax.imshow(m, origin="lower", cmap="inferno", vmin=0.0, vmax=vmax)
        axes[r, 0].set_ylabel(label, fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def main():
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--px", type=int, default=96)
    ap.add_argument("--view", type=float, default=0.6, help="camera's square (m)")
    ap.add_argument("--depths", default="0.5,0.7,1.0", help="floor below the rest plane (m)")
    ap.add_argument("--grid", type=int, default=200, help="water mesh quads per side")
    ap.add_argument("--rays", type=float, default=4e6, help="reference rays")
    ap.add_argument("--cycles-samples", type=int, default=64)
    ap.add_argument("--eevee-samples", type=int, default=16)
    ap.add_argument("--no-cycles", action="store_true")
    ap.add_argument("--no-eevee", action="store_true")
    ap.add_argument("--report", default="water")
    args = ap.parse_args()
    import bpy

    load_extension()
    runs = [] if args.no_cycles else [("CYCLES", "Cycles Generate", args.cycles_samples)]
    if not args.no_eevee:
        runs.append((eevee_id(), "EEVEE Generate", args.eevee_samples))
    titles = ["reference"] + [label for _e, label, _s in runs]
    table, pictures, messages, t_truths = [], [], [], []
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        for depth in (float(x) for x in args.depths.split(",")):
            fr = frame(depth, args.view)
            t1 = time.perf_counter()
            E = truth(args.px, int(args.rays), depth, fr)
            t_truths.append(time.perf_counter() - t1)
            m = metrics(truth(args.px, int(args.rays), depth, fr, seed=12), E)
            table.append(dict(depth=depth, run="reference, another seed", **m))
            print(
                f"depth {depth:g}: reference {t_truths[-1]:.1f} s, mean {E.mean():.4f} W/m², "
                f"peak {E.max():.3f}; another seed: L1 {m['l1']:.3f} flux {m['flux']:.3f}",
                flush=True,
            )
            maps = [E]
            for engine, label, samples in runs:
                img, dt, t_gen, message = generated(
                    engine, args.px, samples, depth, args.grid, fr, tmp
                )
                messages.append((f"{depth:g} m, {label}", message))
                maps.append(img)
                if img is None:
                    table.append(dict(depth=depth, run=label, gen=t_gen, l1=None))
                    print(f"  {label}: nothing made ({message})", flush=True)
                    continue
                m = metrics(img, E)
                table.append(dict(depth=depth, run=label, seconds=dt, gen=t_gen, **m))
                print(
                    f"  {label}: L1 {m['l1']:.3f} flux {m['flux']:.3f} peak {m['peak']:.2f} "
                    f"(Generate {t_gen:.2f} s, render {dt:.1f} s)",
                    flush=True,
                )
            pictures.append((f"floor {depth:g} m down", maps))
    total = time.perf_counter() - t0
    REPORTS.mkdir(exist_ok=True)
    strip(pictures, titles, REPORTS / f"{args.report}.png")
    cmd = "./lens-lights bench water" + "".join(f" {a}" for a in sys.argv[1:])
    lines = [
        "# Water: a sine-wave pool's caustic net in Cycles and EEVEE vs the reference (issue 26)",
        "",
        f"`{cmd}` — Blender {bpy.app.version_string}, {args.px}×{args.px} px over "
        f"{args.view:g} m of floor, water 1 × 1 m as {args.grid}×{args.grid} quads "
        f"({2 * args.grid**2} triangles), sun {ELEVATION:g}° high (strength {STRENGTH:g}); "
        f"reference {args.rays:.3g} rays per depth (about {np.mean(t_truths):.0f} s each); "
        f"{total / 60:.1f} min in all on 2 shared cores (other jobs running beside).",
        "",
        "Reference: `reference/water_tracer.py` (analytic height field, exact normals, Snell, "
        "unpolarised Fresnel), binned on the camera's pixels, over n² (the brightness "
        "Cycles renders under water, SPEC §9). Generate rows: the render with the layer "
        "minus the render without, as irradiance. L1 over the region (reference > 1 % of "
        "its peak or the render > 5 % of it); flux: render / reference there; peak: "
        "brightest pixel / the reference's. 'Reference, another seed': a second reference "
        "against the first (the metric's noise floor from the reference alone). Targets: "
        f"L1 ≤ {L1_TARGET}, flux ±{FLUX_TARGET:.0%}.",
        "",
        "| floor depth | run | L1 | flux | peak | Generate s | render s | target met |",
        "| ---: | --- | ---: | ---: | ---: | ---: | ---: | :---: |",
    ]
    for r in table:
        head = f"| {r['depth']:g} m | {r['run']} |"
        if r["run"].startswith("reference"):
            lines.append(
                f"{head} {r['l1']:.3f} | {r['flux']:.3f} | {r['peak']:.2f} | — | — | (noise) |"
            )
        elif r.get("l1") is None:
            lines.append(f"{head} — | — | — | {r['gen']:.2f} | — | nothing made |")
        else:
            met = "yes" if r["l1"] <= L1_TARGET and abs(r["flux"] - 1) <= FLUX_TARGET else "no"
            lines.append(
                f"{head} {r['l1']:.3f} | {r['flux']:.3f} | {r['peak']:.2f} | "
                f"{r['gen']:.2f} | {r['seconds']:.1f} | {met} |"
            )
    lines += ["", f"![{' | '.join(titles)}]({args.report}.png)", ""]
    lines += ["## Generate's reports", ""] + [f"- {label}: {msg}" for label, msg in messages]
    lines.append("")
    (REPORTS / f"{args.report}.md").write_text("\n".join(lines))
    print(f"wrote {REPORTS / (args.report + '.md')}", flush=True)


if __name__ == "__main__":
    main()
