"""The animation bake (`lens_lights.bake`): its time and the .blend it leaves →
reports/bake.md.

Scenes (bpy module): a floor, a camera, N glass spheres (R = 0.3, in a row 1.5
apart, 1 m up) and L point lights moving over the frames (linear keys: each light
travels 2 m sideways and 1 m up, so every lens' D/R changes on every frame).

* time: the bake of F frames, split into planning (per frame: `frame_set`, the
  probe render or the viewport depsgraph, Generate's planning) and building
  (keyed objects, profile slices, F-curves), for 1 lens × 1 light and 10 lenses ×
  2 lights, Cycles (Exact profile), with the probe render and with
  ``use_viewport``; EEVEE (Caustic layer) for 1 lens over fewer frames;
* size: the saved .blend after baking 1 frame and F frames (Exact profile: one
  stacked image per lens);
* the Exact profile read between two D/R slices against the table of that D/R;
* the Caustic layer (EEVEE, 1 lens × 1 light) → reports/bake_layer.md: time (CPU
  seconds of this process) and .blend size of the fixed-topology bake against the
  earlier one mesh per frame (rebuilt here from the same plans: Generate's layers
  per frame, each keyed visible on its frame), for each of `--layer-frames`; and a
  baked middle frame rendered in EEVEE by a Blender process without the extension
  against Generate's layer of that frame and the exact optics.

    ./lens-lights bench bake [--frames 100] [--layer-frames 10 100] [--quick]
    ./lens-lights bench bake --layer-only [--layer-frames 10 100] [--render-px 64]
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "scripts"))
sys.path.insert(0, str(ROOT))

import bpy
from dev_extension import load_extension

REPORT = ROOT / "reports" / "bake.md"


def build_scene(lenses: int, lights: int, frames: int, engine: str):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    sc.render.engine = engine
    sc.render.resolution_x, sc.render.resolution_y = 320, 180
    sc.frame_start, sc.frame_end = 1, frames
    bpy.ops.mesh.primitive_plane_add(size=40)
    glass = bpy.data.materials.new("Glass")
    if bpy.app.version < (5, 0, 0):
        glass.use_nodes = True
    bsdf = glass.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Transmission Weight"].default_value = 1.0
    bsdf.inputs["IOR"].default_value = 1.5
    for k in range(lenses):
        bpy.ops.mesh.primitive_uv_sphere_add(radius=0.3, location=(1.5 * k, 0.0, 1.0))
        bpy.context.object.data.materials.append(glass)
    bpy.context.preferences.edit.keyframe_new_interpolation_type = "LINEAR"
    for j in range(lights):
        data = bpy.data.lights.new(f"Lamp {j}", "POINT")
        data.energy = 1000.0
        ob = bpy.data.objects.new(f"Lamp {j}", data)
        sc.collection.objects.link(ob)
        x0 = 1.5 * (lenses - 1) / 2 + (j - (lights - 1) / 2)
        ob.location = (x0 - 1.0, 0.5 * j, 4.0)
        ob.keyframe_insert("location", frame=1)
        ob.location = (x0 + 1.0, 0.5 * j, 5.0)
        ob.keyframe_insert("location", frame=max(frames, 2))
    bpy.ops.object.camera_add(location=(1.5 * (lenses - 1) / 2, -8.0, 6.0))
    cam = bpy.context.object
    cam.rotation_euler = (1.0, 0.0, 0.0)
    sc.camera = cam
    sc.frame_set(1)
    return sc


def run_bake(frames: int, use_viewport: bool):
    from lens_lights.blender.commands import bake

    t = time.perf_counter()
    result = bpy.ops.lens_lights.bake(frame_start=1, frame_end=frames, use_viewport=use_viewport)
    seconds = time.perf_counter() - t
    assert result == {"FINISHED"}, result
    return seconds, dict(bake.LAST_BAKE)


def blend_size(tmp: str, name: str) -> int:
    path = os.path.join(tmp, name)
    bpy.ops.wm.save_as_mainfile(filepath=path, copy=True, compress=False)
    return os.path.getsize(path)


def timing_rows(frames: int):
    rows = []
    cases = [
        ("1 lens × 1 light", 1, 1, "CYCLES", frames, False),
        ("1 lens × 1 light", 1, 1, "CYCLES", frames, True),
        ("10 lenses × 2 lights", 10, 2, "CYCLES", frames, False),
        ("10 lenses × 2 lights", 10, 2, "CYCLES", frames, True),
    ]
    for label, n_lens, n_light, engine, f, viewport in cases:
        build_scene(n_lens, n_light, f, engine)
        seconds, fig = run_bake(f, viewport)
        t = fig["timings"]
        rows.append(
            dict(
                case=label,
                tier=fig["energy_model"],
                read="viewport" if viewport else "probe render",
                frames=f,
                objects=fig["objects"],
                images=fig["images"],
                seconds=seconds,
                plan=t["plan"],
                build=t["build"],
            )
        )
        print(rows[-1], flush=True)
    return rows


def size_rows(frames: int):
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for engine, f in (("CYCLES", frames),):
            sizes = {}
            for n in (1, f):
                build_scene(1, 1, f, engine)
                sizes["none"] = blend_size(tmp, "none.blend")
                _, fig = run_bake(n, True)
                sizes[n] = blend_size(tmp, f"baked_{n}.blend")
                tier, images = fig["energy_model"], fig["images"]
                if n == 1:
                    images_1 = images
            rows.append(dict(tier=tier, frames=f, none=sizes["none"], one=sizes[1], many=sizes[f]))
            rows[-1]["images"] = (images_1, images)
            print(rows[-1], flush=True)
    return rows


#: Bands of distance h from the light (in R) for the slice error.
H_BANDS = ((0.2, 1.0), (1.0, 3.0), (3.0, 10.0), (10.0, 30.0))


def slice_error_rows(d_over_r_values=(3.0, 4.5, 8.0), n=1.5):
    """The Exact profile read between two D/R slices against the table made for the
    D/R itself, at the geometric midpoint between two nodes (the worst place), for
    the grid ratio 1.04 and its square (what a wide range falls back to): per
    distance row the relative L1 difference of the intensity (weighted by solid
    angle), its mean and maximum over the rows of each band of distance h from the
    light (`H_BANDS`)."""
    import math

    import numpy as np
    from lens_lights.core.animation import light_tracks
    from lens_lights.core.tiers.exact_profile import (
        PROFILE_ANGLES,
        PROFILE_DISTANCES,
        PROFILE_GAMMA_MAX_DEG,
        table_geometry,
    )

    gmax = math.radians(PROFILE_GAMMA_MAX_DEG)
    edges = gmax * (np.arange(PROFILE_ANGLES + 1) / PROFILE_ANGLES) ** 2
    omega = np.diff(2 * math.pi * (1 - np.cos(edges)))
    _, h_min, h_max = table_geometry(None)  # the rows' distances (R), as BeamProfile's
    h = h_min * (h_max / h_min) ** ((np.arange(PROFILE_DISTANCES) + 0.5) / PROFILE_DISTANCES)
    rows = []
    for ratio in (light_tracks.SLICE_RATIO, light_tracks.SLICE_RATIO**2):
        for dr in d_over_r_values:
            k = math.floor(math.log(dr) / math.log(ratio))
            lo, hi = ratio**k, ratio ** (k + 1)
            mid = math.sqrt(lo * hi)
            a, b, exact = (light_tracks.profile_slice_table(x, n, False) for x in (lo, hi, mid))
            blend = 0.5 * (a.astype(float) + b.astype(float))
            diff = (np.abs(blend - exact) * omega).sum(axis=1)
            norm = (np.abs(exact) * omega).sum(axis=1)
            rel = diff / np.where(norm > 0, norm, 1.0)
            bands = [rel[(h >= b0) & (h < b1)] for b0, b1 in H_BANDS]
            rows.append(
                dict(
                    ratio=ratio,
                    d_over_r=mid,
                    bands=[(float(x.mean()), float(x.max())) for x in bands],
                )
            )
            print(rows[-1], flush=True)
    return rows


def mb(n: int) -> str:
    return f"{n / 1e6:.2f} MB"


def write_report(timing, sizes, errors, args):
    lines = [
        "# Bake: time and file size",
        "",
        "Written by `./lens-lights bench bake" + f" --frames {args.frames}" + "` (bench/bake.py), "
        f"Blender {bpy.app.version_string}, {platform.machine()}, "
        f"{os.cpu_count()} CPU(s) shared with other work: times are indicative.",
        "",
        "Scenes: N glass spheres (R = 0.3) over a floor, L point lights moving 2 m "
        "sideways and 1 m up over the frames (every D/R changes every frame). "
        "Cycles gets the Exact profile tier (AUTO); the Caustic layer (EEVEE) is in "
        "reports/bake_layer.md.",
        "",
        "## Time",
        "",
        "Times vary by up to 2.5× between runs with the other work on these CPUs.",
        "",
        "| scene | tier | frames read by | frames | objects | profile images "
        "| bake (s) | planning (s) | building (s) | per frame (s) |",
        "| --- | --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |",
    ]
    for r in timing:
        lines.append(
            f"| {r['case']} | {r['tier']} | {r['read']} | {r['frames']} | {r['objects']} "
            f"| {r['images']} | {r['seconds']:.1f} | {r['plan']:.1f} | {r['build']:.1f} "
            f"| {r['seconds'] / r['frames']:.3f} |"
        )
    lines += [
        "",
        "Planning is Generate's planning once per frame (with the probe render: a tiny "
        "render of a copy of the scene per frame, for the render depsgraph). Building "
        "includes the Exact profile's slices (the exact trace, about 0.3–2 s per new "
        "D/R slice, remembered for the session; at most 12 per image). "
        "One image per lens, or one per lens light where a lens' lights together span "
        "more D/R than 12 slices cover (the profile images column).",
        "",
        "## File size",
        "",
        "One lens × one light, the saved .blend (uncompressed) before baking, after "
        "baking frame 1 only, and after baking every frame:",
        "",
        "| tier | frames | not baked | 1 frame | all frames | profile images (1 / all) |",
        "| --- | ---: | ---: | ---: | ---: | --- |",
    ]
    for r in sizes:
        lines.append(
            f"| {r['tier']} | {r['frames']} | {mb(r['none'])} | {mb(r['one'])} "
            f"| {mb(r['many'])} | {r['images'][0]} / {r['images'][1]} |"
        )
    lines += [
        "",
        "## Between two slices",
        "",
        "The Exact profile of a baked light blends the two D/R slices around its D/R "
        "(linear in log D/R). At the geometric midpoint between two nodes (the worst "
        "place), against the table made for that D/R (n = 1.5): per distance row the "
        "relative L1 difference of the intensity (solid-angle weighted; the L1 error "
        "of the irradiance on a plane at that distance), mean / maximum over the rows "
        "whose distance h from the light (≈ from the lens' back) lies in each band. "
        "For comparison, the Exact profile tier's own mean L1 error against the exact "
        "optics is 0.024 (reports/accuracy.md).",
        "",
        "| grid ratio | D/R | " + " | ".join(f"h {b0:g}–{b1:g} R" for b0, b1 in H_BANDS) + " |",
        "| ---: | ---: |" + " ---: |" * len(H_BANDS),
        *(
            f"| {e['ratio']:.4f} | {e['d_over_r']:.3f} | "
            + " | ".join(f"{m:.4f} / {x:.4f}" for m, x in e["bands"])
            + " |"
            for e in errors
        ),
        "",
        "Receivers more than about 3 R behind the lens see the tables of the grid "
        "nodes blended to better than 0.1 %; nearer, around the focus (where the "
        "converging beam changes fastest with D/R), the blend of two slices differs "
        "from the exact table by up to the figures above: there, on frames between "
        "two nodes, the caustic's core is a blend of two nearby cores.",
        "",
        "## File size notes",
        "",
        "Exact profile: the image holds one 256 × 256 table per D/R slice (packed as a "
        "one-channel 32-bit float OpenEXR, ZIP: about 0.25 MB a slice); the slices "
        "cover the D/R range the lens takes, not the frames, so the size grows with the range (at most 12 slices), not with the number of "
        "frames. The Caustic layer (EEVEE): reports/bake_layer.md.",
        "",
    ]
    REPORT.write_text("\n".join(lines))
    print(f"wrote {REPORT}")


# --------------------------------------------------------------------------- Caustic layer

LAYER_REPORT = ROOT / "reports" / "bake_layer.md"


def per_frame_layer_bake(frames: int):
    """The bake as it was before the fixed topology (main at ca817e7): the same
    plans (`Baker.plan_next`), then each frame's Generate layers, keyed visible on
    their frame only. Returns LAST_BAKE-like figures."""
    from lens_lights.blender.build import cleanup
    from lens_lights.blender.commands import bake, layer_stage
    from lens_lights.core.animation import light_tracks

    scene = bpy.context.scene
    t0 = time.perf_counter()
    baker = bake.Baker(bpy.context, 1, frames, True)
    while not baker.done:
        baker.plan_next()
    t1 = time.perf_counter()
    baker.restore_frame()
    cleanup.clear(scene)
    objects = 0
    for f, work in zip(baker.frames, baker.works, strict=True):
        for ob in layer_stage.build(scene, work):
            bake.key_visibility(ob, light_tracks.single_frame_visibility(f, 1, frames))
            objects += 1
    t2 = time.perf_counter()
    return dict(objects=objects, images=0, timings=dict(plan=t1 - t0, build=t2 - t1))


def layer_rows(frame_counts):
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for f in frame_counts:
            for mode in ("one mesh per frame (before)", "fixed topology"):
                build_scene(1, 1, f, "BLENDER_EEVEE")
                none = blend_size(tmp, "none.blend")
                cpu, wall = time.process_time(), time.perf_counter()
                if mode.startswith("fixed"):
                    _s, fig = run_bake(f, True)
                else:
                    fig = per_frame_layer_bake(f)
                cpu, wall = time.process_time() - cpu, time.perf_counter() - wall
                meshes = [
                    o for o in bpy.data.objects if o.type == "MESH" and o.lens_lights.is_lens_light
                ]
                faces = sum(len(o.data.polygons) for o in meshes)
                size = blend_size(tmp, "baked.blend")
                rows.append(
                    dict(
                        frames=f,
                        mode=mode,
                        objects=fig["objects"],
                        faces=faces,
                        images=fig["images"],
                        cpu=cpu,
                        wall=wall,
                        plan=fig["timings"]["plan"],
                        build=fig["timings"]["build"],
                        reland=fig["timings"].get("layer re-landing", 0.0),
                        none=none,
                        size=size,
                        res=fig.get("layer_resolution"),
                        segments=len(fig.get("layer_segments", [])),
                        coarsening=max(
                            (c for _n, c in fig.get("layer_segments", [])), default=None
                        ),
                    )
                )
                print(rows[-1], flush=True)
    return rows


LAYER_STOCK_RENDER = """
import json, os, sys
import bpy
path, out, frame, engine = sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4]
bpy.ops.wm.open_mainfile(filepath=path)
scene = bpy.context.scene
facts = dict(registered=scene.bl_rna.properties.get("lens_lights") is not None)
scene.render.engine = engine
if engine == "CYCLES":
    scene.cycles.samples = 64
    scene.cycles.max_bounces = 0
    scene.cycles.caustics_refractive = scene.cycles.caustics_reflective = False
    scene.cycles.use_denoising = False
scene.frame_set(frame)
scene.render.filepath = os.path.join(out, "baked.exr")
bpy.ops.render.render(write_still=True)
bpy.data.collections["Lens Lights"].hide_render = True
scene.render.filepath = os.path.join(out, "without.exr")
bpy.ops.render.render(write_still=True)
print("FACTS " + json.dumps(facts), flush=True)
sys.stdout.flush()
os._exit(0)
"""


def _load_luma(path):
    import numpy as np

    img = bpy.data.images.load(str(path))
    px = np.array(img.pixels[:], dtype=float).reshape(img.size[1], img.size[0], 4)
    bpy.data.images.remove(img)
    return px[..., :3].mean(axis=2)


def layer_accuracy(px: int, frames: int = 9):
    """The measuring scene (glass ball R = 0.5, n = 1.5, 2.5 above a white floor,
    albedo 0.8; a 1000 W point light moving from (−0.45, 0, 4.45) to (−1.1, 0, 4.6)
    over `frames` frames, linear keys; orthographic camera 1 m wide straight down on
    the middle frame's axis point): the middle frame rendered in EEVEE (`px`²) from
    the baked file by a process without the extension, and with Generate's layer of
    that frame; each against the exact optics (`ball_optics.irradiance_on_plane`
    around the axis point, and the axis point itself) and against each other."""
    import math
    import subprocess

    import numpy as np
    from measuring_scene import build_measuring_scene

    from core.lens import ball_optics

    R, N, P, A, VIEW = 0.5, 1.5, 1000.0, 0.8, 1.0
    center = np.array([0.0, 0.0, 2.5])
    first, last = np.array([-0.45, 0.0, 4.45]), np.array([-1.1, 0.0, 4.6])
    mid_f = (frames + 1) // 2
    light = first + (mid_f - 1) / (frames - 1) * (last - first)
    u = (center - light) / np.linalg.norm(center - light)
    hit = center + (center[2] / -u[2]) * u
    built = build_measuring_scene(
        "BLENDER_EEVEE",
        resolution=px,
        floor_size=60.0,
        albedo=A,
        view=VIEW,
        camera_xy=(hit[0], hit[1]),
        camera_height=6.0,
        ball=dict(radius=R, location=tuple(center), ior=N, segments=48, rings=24, name="Marble"),
        lamp=dict(location=tuple(first), power=P),
    )
    sc = built.scene
    sc.lens_lights.energy_model = "CAUSTIC_LAYER"
    sc.eevee.taa_render_samples = 16
    sc.frame_start, sc.frame_end = 1, frames
    bpy.context.preferences.edit.keyframe_new_interpolation_type = "LINEAR"
    built.lamp.location = first
    built.lamp.keyframe_insert("location", frame=1)
    built.lamp.location = last
    built.lamp.keyframe_insert("location", frame=frames)
    sc.frame_set(1)
    out = {}
    with tempfile.TemporaryDirectory() as tmp:
        assert bpy.ops.lens_lights.bake() == {"FINISHED"}
        blend = os.path.join(tmp, "baked.blend")
        bpy.ops.wm.save_as_mainfile(filepath=blend, copy=True)
        env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
        for engine in ("BLENDER_EEVEE", "CYCLES"):
            run = subprocess.run(
                [sys.executable, "-c", LAYER_STOCK_RENDER, blend, tmp, str(mid_f), engine],
                capture_output=True,
                text=True,
                env=env,
                timeout=1800,
            )
            facts = [ln for ln in run.stdout.splitlines() if ln.startswith("FACTS ")]
            assert facts, run.stdout[-2000:] + run.stderr[-2000:]
            assert '"registered": false' in facts[0]
            label = "baked, EEVEE" if engine == "BLENDER_EEVEE" else "baked, Cycles (64 samples)"
            out[label] = _load_luma(os.path.join(tmp, "baked.exr")) - _load_luma(
                os.path.join(tmp, "without.exr")
            )
        # Generate's layer of that frame, rendered here
        bpy.ops.lens_lights.clear()
        sc.frame_set(mid_f)
        assert bpy.ops.lens_lights.generate() == {"FINISHED"}
        for name, hidden in (("gen.exr", False), ("gen_without.exr", True)):
            bpy.data.collections["Lens Lights"].hide_render = hidden
            sc.render.filepath = os.path.join(tmp, name)
            bpy.ops.render.render(write_still=True)
        out["Generate, EEVEE"] = _load_luma(os.path.join(tmp, "gen.exr")) - _load_luma(
            os.path.join(tmp, "gen_without.exr")
        )
    coords = (np.arange(px) + 0.5) * (VIEW / px) - VIEW / 2
    x = np.broadcast_to(hit[0] + coords[None, :], (px, px))
    y = np.broadcast_to(hit[1] + coords[:, None], (px, px))
    patch_r = 1.5 * VIEW / 32  # the test's measuring disc (1.5 px at 32 px)
    d = float(np.linalg.norm(center - light))
    e = ball_optics.irradiance_on_plane(P / (4 * math.pi), d, R, N, center[2] / -u[2], [0, patch_r])
    radiance = A * float(e[0]) * -u[2] / math.pi
    patch = np.hypot(x - hit[0], y - hit[1]) <= patch_r
    rows = []
    for name, img in out.items():
        cx, cy = float((img * x).sum() / img.sum()), float((img * y).sum() / img.sum())
        rows.append(
            dict(
                render=name,
                centroid=math.hypot(cx - hit[0], cy - hit[1]),
                brightness=float(img[patch].mean()) / radiance,
                total=float(img.sum()),
            )
        )
    g, b = out["Generate, EEVEE"], out["baked, EEVEE"]
    l1 = float(np.abs(b - g).sum() / g.sum())
    return dict(rows=rows, l1=l1, px=px, frame=mid_f, frames=frames, light=light, hit=hit)


def write_layer_report(rows, acc, args, _t):
    by = {(r["frames"], r["mode"].startswith("fixed")): r for r in rows}
    lines = [
        "# Bake: the Caustic layer with a fixed topology",
        "",
        "Written by `./lens-lights bench bake --layer-only --layer-frames "
        + " ".join(str(f) for f in args.layer_frames)
        + f" --render-px {args.render_px}` (bench/bake.py), Blender {bpy.app.version_string}, "
        f"{platform.machine()}, {os.cpu_count()} CPU(s) shared with other work "
        f"(load average {os.getloadavg()[0]:.1f} at the end): times are indicative; "
        "CPU seconds of this process.",
        "",
        "Scene: one glass sphere (R = 0.3, 1 m up) over a 40 m floor, one 1000 W point "
        "light moving 2 m sideways and 1 m up over the frames, EEVEE, Caustic layer, "
        "frames read from the viewport depsgraph (`use_viewport`). *Before*: each "
        "frame's Generate layers kept as their own meshes, keyed visible on their frame "
        "only (the bake up to ca817e7, rebuilt here from the same plans). *Fixed "
        "topology*: one mesh per receiver plane × lens lights over the frames "
        "(cut in time where one raster would coarsen a frame's caustic core more than "
        "2×), the irradiance of every frame a slice of one packed half-float image.",
        "",
        "| frames | bake | layer objects | faces | images | raster | worst core texel "
        "| CPU (s) | wall (s) | planning (s) | building (s) | of which re-landing (s) "
        "| .blend not baked | .blend baked | baked − not baked |",
        "| ---: | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: "
        "| ---: | ---: | ---: | ---: |",
    ]
    for r in rows:
        lines.append(
            f"| {r['frames']} | {r['mode']} | {r['objects']} | {r['faces']} | {r['images']} "
            f"| {r['res'] or '–'} | "
            + (f"{r['coarsening']:.2f}×" if r["coarsening"] is not None else "1×")
            + f" | {r['cpu']:.1f} | {r['wall']:.1f} | {r['plan']:.1f} | {r['build']:.1f} "
            f"| {r['reland']:.1f} | {mb(r['none'])} | {mb(r['size'])} "
            f"| {mb(r['size'] - r['none'])} |"
        )
    for f in args.layer_frames:
        old, new = by.get((f, False)), by.get((f, True))
        if old and new:
            lines.append("")
            lines.append(
                f"{f} frames: the bake adds {mb(new['size'] - new['none'])} to the file instead "
                f"of {mb(old['size'] - old['none'])} "
                f"({(old['size'] - old['none']) / max(new['size'] - new['none'], 1):.1f}× less), "
                f"in {new['cpu']:.1f} CPU s instead of {old['cpu']:.1f}."
            )
    lines += [
        "",
        "## Accuracy of a baked frame",
        "",
        f"The measuring scene (glass ball R = 0.5, n = 1.5, 2.5 above a white floor of "
        f"albedo 0.8, a 1000 W point light moving from (−0.45, 0, 4.45) to (−1.1, 0, 4.6) "
        f"over {acc['frames']} frames), frame {acc['frame']} at {acc['px']}² px "
        "(orthographic, 1 m wide, on that frame's axis point): the caustic (render minus "
        "the render without the lens lights) from the baked file rendered by a Blender "
        "process **without the extension** (EEVEE, and Cycles with no bounces), and from "
        "Generate's layer of that frame (EEVEE). The axis point is not the exact "
        "caustic's centroid (the beam is tilted 21° on that frame): compare the rows. "
        "Centroid: distance of the radiance-weighted centroid over the view from the "
        "axis point. Brightness: mean radiance within 0.047 m of the axis point over "
        "the exact optics' there (`ball_optics.irradiance_on_plane` × albedo × "
        "cos tilt / π).",
        "",
        "| render | centroid from the axis point (m) | brightness / exact |",
        "| --- | ---: | ---: |",
        *(f"| {r['render']} | {r['centroid']:.4f} | {r['brightness']:.3f} |" for r in acc["rows"]),
        "",
        f"Baked against Generate's render, pixel by pixel: relative L1 {acc['l1']:.3f} "
        f"(one pixel is {1.0 / acc['px']:.4f} m).",
        "",
    ]
    LAYER_REPORT.write_text("\n".join(lines))
    print(f"wrote {LAYER_REPORT}")


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--frames", type=int, default=100)
    p.add_argument("--layer-frames", type=int, nargs="+", default=[10, 100])
    p.add_argument("--render-px", type=int, default=64, help="the layer's accuracy render")
    p.add_argument("--layer-only", action="store_true", help="only reports/bake_layer.md")
    p.add_argument("--quick", action="store_true", help="5 frames, 2 layer frames")
    p.add_argument("--errors-only", action="store_true", help="only the slice errors (printed)")
    args = p.parse_args(argv)
    if args.quick:
        args.frames, args.layer_frames, args.render_px = 5, [2], 32
    load_extension().register()
    write_layer_report(
        layer_rows(args.layer_frames), layer_accuracy(args.render_px), args, time.perf_counter()
    )
    if args.layer_only:
        return 0
    if args.errors_only:
        slice_error_rows()
        return 0
    timing = timing_rows(args.frames)
    sizes = size_rows(args.frames)
    errors = slice_error_rows()
    write_report(timing, sizes, errors, args)
    return 0


if __name__ == "__main__":
    code = main()
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)
