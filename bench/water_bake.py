"""Water baked (issue 26): an Ocean-modifier pool's caustic net over many frames, its
bake time and .blend growth, and frames of the baked file rendered by a Blender
without the extension (`blender -b file.blend -a`) against Generate at those frames.

    ./lens-lights bench water_bake [--grid 256] [--frames 100] [--size 4] [--depth 1]
                                   [--px 96] [--samples 16] [--check 1,50,100]
                                   [--report water_bake]

Scene (metres): a ``--size`` square water surface, a grid of ``--grid`` × ``--grid``
quads displaced by an Ocean modifier (DISPLACE, wind 2 m/s: ripples of tens of cm,
heights of about a centimetre) whose ``time`` is keyed linearly from 0 s on frame 1
to (frames − 1)/24 s on the last, ``--depth`` above a white Lambertian floor (albedo
0.8), the water's material Principled BSDF (transmission 1, roughness 0, IOR 1.333),
hidden from the camera (the camera sees the floor as it lies in the water: the
layer's E/n², SPEC §9); a sun 60° above the horizon (strength 3); an orthographic
camera straight down over the middle of the lit floor, 1 m across, ``--px``²
pixels; Cycles, ``--samples`` samples, direct light only.

Steps: the file saved before the bake; `bake.bake(...)` over all frames (Caustic
layer tier: the water's layers only; timings per stage); the file saved again (the
growth: after − before, bytes); a fresh process of the same Python that never loads
the extension opens the baked file and renders each ``--check`` frame as an
animation of one frame (what ``-a`` runs), then again with the "Lens Lights"
collection hidden; here, per checked frame, Clear, Generate at that frame, the same
two renders. Metric (bench/real_scenes.py's): relative L1 of the baked caustic
(render − render without) against Generate's over the region, flux and peak ratios.
Writes reports/<report>.md and a strip reports/<report>.png (Generate | baked per
checked frame).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
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
    new_material,
    new_measuring_scene,
    render_grey,
)
from real_scenes import ALBEDO, load_extension, metrics  # noqa: E402

REPORTS = ROOT / "reports"
IOR, STRENGTH, ELEVATION = 1.333, 3.0, 60.0

#: Renders the given frames of a saved file in a process that never loads the
#: extension: each frame as an animation of one frame (what `blender -b file -a`
#: runs), then each again with the "Lens Lights" collection hidden.
STOCK = """
import json, os, sys, time
import bpy
path, out, frames = sys.argv[1], sys.argv[2], [int(f) for f in sys.argv[3].split(",")]
bpy.ops.wm.open_mainfile(filepath=path)
scene = bpy.context.scene
facts = dict(registered=scene.bl_rna.properties.get("lens_lights") is not None,
             operators=hasattr(bpy.types, "LENS_LIGHTS_OT_bake"))
for hidden in (False, True):
    bpy.data.collections["Lens Lights"].hide_render = hidden
    for f in frames:
        scene.frame_start = scene.frame_end = f
        scene.render.filepath = os.path.join(out, ("without_" if hidden else "baked_") + "####")
        bpy.ops.render.render(animation=True)
if len(sys.argv) > 4:  # then the whole range at once, as `blender -b file -a` does
    bpy.data.collections["Lens Lights"].hide_render = False
    scene.frame_start, scene.frame_end = 1, int(sys.argv[4])
    scene.render.filepath = os.path.join(out, "anim_####")
    t = time.perf_counter()
    bpy.ops.render.render(animation=True)
    facts["animation_s"] = time.perf_counter() - t
print("FACTS " + json.dumps(facts), flush=True)
sys.stdout.flush()
os._exit(0)
"""


def sun_direction():
    e = math.radians(ELEVATION)
    return np.array([math.cos(e), 0.0, -math.sin(e)])


def build(args):
    """The pool (see the module's text); returns the scene."""
    import bpy
    from mathutils import Vector

    sc = new_measuring_scene("CYCLES", args.px)
    add_diffuse_floor(4.0 * args.size, ALBEDO)
    bpy.ops.mesh.primitive_grid_add(
        x_subdivisions=args.grid, y_subdivisions=args.grid, size=args.size,
        location=(0.0, 0.0, args.depth),
    )  # fmt: skip
    water = bpy.context.object
    water.name = "Pool"
    mat = new_material("Water")
    bsdf = mat.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Transmission Weight"].default_value = 1.0
    bsdf.inputs["IOR"].default_value = IOR
    bsdf.inputs["Roughness"].default_value = 0.0
    water.data.materials.append(mat)
    water.data.shade_smooth()
    water.visible_camera = False
    ocean = water.modifiers.new("Ocean", "OCEAN")
    ocean.geometry_mode = "DISPLACE"
    ocean.resolution = ocean.viewport_resolution = 12
    ocean.spatial_size = int(args.size)
    ocean.wind_velocity = 2.0
    ocean.wave_scale = 1.0
    ocean.choppiness = 0.0
    bpy.context.preferences.edit.keyframe_new_interpolation_type = "LINEAR"
    for f, t in ((1, 0.0), (args.frames, (args.frames - 1) / 24.0)):
        ocean.time = t
        water.keyframe_insert('modifiers["Ocean"].time', frame=f)
    data = bpy.data.lights.new("Sun", "SUN")
    data.energy, data.angle = STRENGTH, 0.0
    sun = bpy.data.objects.new("Sun", data)
    sc.collection.objects.link(sun)
    sun.rotation_mode = "QUATERNION"
    sun.rotation_quaternion = Vector(tuple(sun_direction())).to_track_quat("-Z", "Y")
    d = sun_direction()
    st = math.hypot(d[0], d[1]) / IOR
    shift = args.depth * st / math.sqrt(1.0 - st * st)  # the middle of the lit floor
    add_top_camera(shift, 0.0, args.depth + 0.5, args.view, clip_end=10.0)
    measured_render_settings(sc, "CYCLES", args.samples)
    sc.cycles.max_bounces = sc.cycles.diffuse_bounces = 0
    sc.frame_start, sc.frame_end = 1, args.frames
    sc.lens_lights.energy_model = "CAUSTIC_LAYER"
    sc.lens_lights.replace_cycles_caustics = True
    sc.frame_set(1)
    return sc, water


def grey(path):
    import bpy

    img = bpy.data.images.load(str(path))
    px = np.array(img.pixels[:], dtype=float).reshape(img.size[1], img.size[0], 4)
    bpy.data.images.remove(img)
    return px[..., :3].mean(axis=2)


def strip(rows, path):
    """Per checked frame: Generate's caustic | the baked one (Generate's scale)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, len(rows), figsize=(2.6 * len(rows), 5.4), squeeze=False)
    for c, (f, gen, baked) in enumerate(rows):
        vmax = float(gen.max())
        for r, (m, what) in enumerate(((gen, "Generate"), (baked, "baked, no extension"))):
            ax = axes[r, c]
            ax.set_xticks([])
            ax.set_yticks([])
            ax.imshow(m, origin="lower", cmap="inferno", vmin=0.0, vmax=vmax)
            ax.set_title(f"frame {f}: {what}", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def main():
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--grid", type=int, default=256, help="water quads per side")
    ap.add_argument("--frames", type=int, default=100)
    ap.add_argument("--size", type=float, default=2.0, help="the water's side (m)")
    ap.add_argument("--depth", type=float, default=1.0, help="floor below the water (m)")
    ap.add_argument("--view", type=float, default=1.6, help="camera's square (m)")
    ap.add_argument("--px", type=int, default=128)
    ap.add_argument("--samples", type=int, default=16)
    ap.add_argument("--check", default="1,50,100", help="frames rendered and compared")
    ap.add_argument(
        "--viewport",
        action="store_true",
        help="bake from the viewport depsgraph with the render rules (no probe)",
    )
    ap.add_argument("--report", default="water_bake")
    args = ap.parse_args()
    import bpy

    load_extension()
    from lens_lights.blender.commands import bake as bake_mod
    from lens_lights.blender.commands.generate import generate

    checks = [f for f in (int(x) for x in args.check.split(",")) if 1 <= f <= args.frames]
    out: dict = dict(args=vars(args))
    t_all = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        sc, _water = build(args)
        before = tmp / "before.blend"
        bpy.ops.wm.save_as_mainfile(filepath=str(before), copy=True, compress=False)
        t0 = time.perf_counter()
        level, message, figures = bake_mod.bake(bpy.context, use_viewport=args.viewport)
        out["bake_s"] = time.perf_counter() - t0
        out["bake_message"] = message
        out["timings"] = figures.get("timings", {})
        out["water_resolution"] = figures.get("water_resolution")
        out["water_segments"] = figures.get("water_segments")
        print(f"bake: {out['bake_s']:.1f} s: {message}", flush=True)
        if level == "ERROR":
            raise SystemExit(message)
        baked = tmp / "baked.blend"
        bpy.ops.wm.save_as_mainfile(filepath=str(baked), copy=True, compress=False)
        out["bytes_before"], out["bytes_after"] = before.stat().st_size, baked.stat().st_size
        print(f"file: {out['bytes_before']} → {out['bytes_after']} bytes", flush=True)
        # the baked frames, rendered where the extension never loads
        env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
        t1 = time.perf_counter()
        run = subprocess.run(
            [sys.executable, "-c", STOCK, str(baked), str(tmp), ",".join(map(str, checks)),
             str(args.frames)],
            capture_output=True, text=True, env=env, timeout=7200,
        )  # fmt: skip
        out["stock_render_s"] = time.perf_counter() - t1
        facts = [ln for ln in run.stdout.splitlines() if ln.startswith("FACTS ")]
        assert facts, run.stdout[-2000:] + run.stderr[-2000:]
        out["facts"] = json.loads(facts[0][6:])
        # the whole animation: every frame written, the checked ones as rendered alone
        anim = sorted(tmp.glob("anim_*.exr"))
        out["animation_frames"] = len(anim)
        out["animation_same"] = max(
            float(np.abs(grey(tmp / f"anim_{f:04d}.exr") - grey(tmp / f"baked_{f:04d}.exr")).max())
            for f in checks
        )
        factor = math.pi / ALBEDO  # grey → irradiance
        rows, table = [], []
        bpy.ops.lens_lights.clear()
        for f in checks:
            b = (grey(tmp / f"baked_{f:04d}.exr") - grey(tmp / f"without_{f:04d}.exr")) * factor
            sc.frame_set(f)
            t2 = time.perf_counter()
            glevel, gmessage, _ = generate(bpy.context)
            t_gen = time.perf_counter() - t2
            g = render_grey(sc, tmp / "gen.exr")
            bpy.data.collections["Lens Lights"].hide_render = True
            g = (g - render_grey(sc, tmp / "gen_without.exr")) * factor
            bpy.data.collections["Lens Lights"].hide_render = False
            m = metrics(b, g)
            table.append(dict(frame=f, gen_s=t_gen, **m))
            rows.append((f, g, b))
            print(f"frame {f}: baked vs Generate L1 {m['l1']:.3f} flux {m['flux']:.3f} "
                  f"peak {m['peak']:.2f} (Generate {t_gen:.1f} s: {gmessage})", flush=True)  # fmt: skip
        # the nets move: frame-to-frame difference of Generate's (how much a wrong
        # frame would cost in the metric)
        moved = [metrics(rows[i + 1][1], rows[i][1])["l1"] for i in range(len(rows) - 1)]
    out["table"], out["moved"] = table, moved
    total = time.perf_counter() - t_all
    REPORTS.mkdir(exist_ok=True)
    strip(rows, REPORTS / f"{args.report}.png")
    grow = out["bytes_after"] - out["bytes_before"]
    tm = out["timings"]
    cmd = "./lens-lights bench water_bake" + "".join(f" {a}" for a in sys.argv[1:])
    lines = [
        "# Water baked: an Ocean pool over many frames, rendered without the extension (issue 26)",
        "",
        f"`{cmd}` — Blender {bpy.app.version_string}; {total / 60:.1f} min in all on 2 "
        "shared cores (other jobs running beside).",
        "",
        f"Scene: a {args.size:g} × {args.size:g} m pool, {args.grid} × {args.grid} quads "
        f"({2 * args.grid**2} triangles) displaced by an Ocean modifier (time keyed over "
        f"{args.frames} frames), a white floor {args.depth:g} m below, a sun "
        f"{ELEVATION:g}° high; Cycles, {args.px}² px over {args.view:g} m of floor, "
        f"{args.samples} samples, direct light only. Bake: Caustic layer tier, "
        + (
            "the viewport depsgraph with the render rules (`--viewport`)."
            if args.viewport
            else "a probe render per frame (as Generate reads)."
        ),
        "",
        "| frames | bake s | s per frame | plan s | re-landing s | build s | .blend before | "
        ".blend after | growth |",
        "| ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |",
        f"| {args.frames} | {out['bake_s']:.1f} | {out['bake_s'] / args.frames:.2f} | "
        f"{tm.get('plan', 0.0):.1f} | {tm.get('water re-landing', 0.0):.1f} | "
        f"{tm.get('build', 0.0):.1f} | {out['bytes_before'] / 1e6:.2f} MB | "
        f"{out['bytes_after'] / 1e6:.2f} MB | {grow / 1e6:.2f} MB |",
        "",
        f"Bake's report: {out['bake_message']}",
        "",
        f"Layer: {out['water_resolution']}² texels per raster; segments (frames, worst "
        f"coarsening of a frame's core texel): {out['water_segments']}.",
        "",
        "Rendered by a process that never loaded the extension (registered: "
        f"{out['facts']['registered']}, operators: {out['facts']['operators']}), each "
        f"frame as `-a` renders it ({out['stock_render_s']:.0f} s for "
        f"{2 * len(checks)} renders and the animation below, with its start-up), against "
        "Generate at that frame "
        "rendered here (render − render without the layers, as irradiance; L1 over "
        "the region as bench/real_scenes.py):",
        "",
        f"The whole range rendered the same way as one animation (`-a`): "
        f"{out['animation_frames']} of {args.frames} frames written in "
        f"{out['facts'].get('animation_s', 0.0):.0f} s; at the checked frames its images "
        f"differ from the frames rendered alone by at most {out['animation_same']:.1e} "
        "(grey).",
        "",
        "| frame | L1 baked vs Generate | flux | peak | Generate s |",
        "| ---: | ---: | ---: | ---: | ---: |",
    ]
    for r in table:
        lines.append(
            f"| {r['frame']} | {r['l1']:.3f} | {r['flux']:.3f} | {r['peak']:.2f} | "
            f"{r['gen_s']:.1f} |"
        )
    if moved:
        lines += [
            "",
            "For scale: Generate at one checked frame against Generate at the next, L1 "
            + ", ".join(f"{x:.2f}" for x in moved)
            + " (the nets move).",
        ]
    lines += ["", f"![Generate and baked per frame]({args.report}.png)", ""]
    (REPORTS / f"{args.report}.md").write_text("\n".join(lines))
    print(f"wrote {REPORTS / (args.report + '.md')}", flush=True)


if __name__ == "__main__":
    main()
