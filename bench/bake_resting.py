"""The bake of a marble resting on a table (the Exact profile's near field) with a lamp
moving around it and a blocker moving with the lamp: what "Bake = Generate at every
frame" costs (issue 24, item 4) → reports/bake_resting.md.

The scene of tests/blender/commands/test_bake_matches_generate.py over F frames: a
glass marble (R = 0.5) on a floor, a 1000 W lamp 4 from its centre whose elevation
goes 62° → 68° and azimuth 0° → 60° (linear keys), an opaque ball (r = 0.15) 0.4 of
the way to the marble and 0.25 aside (a shadow mask on every frame). The receiver
(the floor, tilted 22°–28° against the lens axis) is 1.06–1.13 R from the centre along
the axis: a distinct distance on every frame, so every frame gets its own near-field
table (Generate's) and its own mask. Measured: the bake's time (planning: per frame
the probe render and Generate's planning, the near table, the mask; building), the
saved .blend's size after 1 and F frames, the images and their sizes.

    ./lens-lights bench bake_resting [--frames 30]
"""

from __future__ import annotations

import argparse
import math
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
import numpy as np
from dev_extension import load_extension
from measuring_scene import build_measuring_scene, new_material

REPORT = ROOT / "reports" / "bake_resting.md"
R, DIST = 0.5, 4.0


def build(frames: int):
    built = build_measuring_scene(
        "CYCLES",
        resolution=64,
        floor_size=8.0,
        view=1.6,
        camera_xy=(0.35, 0.0),
        camera_height=6.0,
        ball=dict(radius=R, location=(0.0, 0.0, R), ior=1.5, segments=64, rings=32, name="Marble"),
        lamp=dict(location=(0.0, 0.0, 5.0), power=1000.0),
    )
    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.15, segments=32, ring_count=16)
    blocker = bpy.context.object
    blocker.name = "Blocker"
    blocker.data.materials.append(new_material("Opaque"))
    c = np.array([0.0, 0.0, R])
    for f in range(1, frames + 1):
        t = (f - 1) / max(frames - 1, 1)
        e, a = math.radians(62.0 + 6.0 * t), math.radians(60.0 * t)
        lamp = c + DIST * np.array(
            [-math.cos(e) * math.cos(a), -math.cos(e) * math.sin(a), math.sin(e)]
        )
        aside = np.array([math.sin(a), -math.cos(a), 0.0])
        built.lamp.location = tuple(lamp)
        blocker.location = tuple(lamp + 0.4 * (c - lamp) + 0.25 * aside)
        built.lamp.keyframe_insert("location", frame=f)
        blocker.keyframe_insert("location", frame=f)
    sc = built.scene
    sc.frame_start, sc.frame_end = 1, frames
    sc.lens_lights.energy_model = "EXACT_PROFILE"
    sc.frame_set(1)
    return sc


def blend_size(tmp: str, name: str) -> int:
    path = os.path.join(tmp, name)
    bpy.ops.wm.save_as_mainfile(filepath=path, copy=True, compress=False)
    return os.path.getsize(path)


def bake(frames: int):
    from lens_lights.blender.commands import bake as bake_module

    t = time.perf_counter()
    assert bpy.ops.lens_lights.bake(frame_start=1, frame_end=frames) == {"FINISHED"}
    seconds = time.perf_counter() - t
    figures = dict(bake_module.LAST_BAKE)
    images = [
        (img.name, tuple(img.size), img.packed_file.size if img.packed_file else 0)
        for img in bpy.data.images
        if img.name.startswith(("Lens profile", "Lens mask"))
    ]
    return seconds, figures, images


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--frames", type=int, default=30)
    args = p.parse_args(argv)
    load_extension().register()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for frames in (1, args.frames):
            build(frames)
            unbaked = blend_size(tmp, "unbaked.blend")
            seconds, figures, images = bake(frames)
            size = blend_size(tmp, f"baked_{frames}.blend")
            rows.append((frames, seconds, figures, images, unbaked, size))
            print(frames, f"{seconds:.1f} s", figures["timings"], size, images, flush=True)
    lines = [
        "# Bake of a resting marble (near field, tilted receiver, shadow mask)",
        "",
        f"{platform.node()}, Blender {bpy.app.version_string}, 2 shared CPUs. "
        "Reproduce: `./lens-lights bench bake_resting --frames "
        f"{args.frames}`.",
        "",
        "Every frame has its own receiver distance: its own near table (Generate's, "
        "512 × 256, intensity and intensity × slope) and its own mask (128 × 128).",
        "",
        "| frames | bake (s) | plan (s) | build (s) | .blend unbaked (MB) | baked (MB) "
        "| per frame (MB) | images (texels, packed MB) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    base = rows[0]
    for frames, seconds, figures, images, unbaked, size in rows:
        per = f"{(size - base[5]) / (frames - 1) / 1e6:.2f}" if frames > 1 else "–"
        imgs = "; ".join(f"{w}×{h}, {b / 1e6:.1f}" for _n, (w, h), b in images)
        t = figures["timings"]
        lines.append(
            f"| {frames} | {seconds:.1f} | {t['plan']:.1f} | {t['build']:.1f} | "
            f"{unbaked / 1e6:.1f} | {size / 1e6:.1f} | {per} | {imgs} |"
        )
    REPORT.write_text("\n".join(lines) + "\n")
    print("wrote", REPORT)
    return 0


if __name__ == "__main__":
    code = main()
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)
