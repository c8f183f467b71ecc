"""The stale-bake check's cost and the record it keeps → reports/bake_check.md.

Scenes: live update's bench scene (`bench/live_update.py`'s `build_scene`: a floor,
N glass spheres on a grid, two point lights, one moving over the frames), baked over
F frames (Fitted, EEVEE: the check reads the same whatever the tier). Then:

* the record: bytes of ``scene.lens_lights.baked_from`` (per frame and object);
* the check at the middle frame, as the panel runs it on a cache miss
  (`bake_check.status`: the viewport depsgraph read, the prints, the compare; its
  throttle off): median of ``--repeats`` runs, and the read alone, and a cached
  call (a redraw without an update in between);
* that a sphere moved after the bake is named, and a cube moved beside the floor
  (away from every path of the light) is not (and what that check costs: the
  paths are built only when something differs).

    ./lens-lights bench bake_check [--counts 20 100 1000] [--frames 10] [--repeats 9]
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "scripts"))
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

import bpy
from dev_extension import load_extension
from live_update import build_scene, set_engine

REPORTS = ROOT / "reports"


def run(n, frames, repeats):
    from lens_lights.blender.commands import bake_check
    from lens_lights.blender.read.scene import read_depsgraph

    bake_check.RECHECK_ABOVE = float("inf")  # the check itself, never its throttle
    build_scene(n, frames)
    scene = bpy.context.scene
    side = max(1.0, n**0.5)
    bpy.ops.mesh.primitive_cube_add(size=0.5, location=(1.5 * side, 1.5 * side, 0.25))
    cube = bpy.context.object  # beside the floor, away from every beam
    cube.name = "Unrelated cube"
    set_engine("BLENDER_EEVEE")
    scene.lens_lights.energy_model = "FITTED"
    scene.frame_start, scene.frame_end = 1, frames
    t = time.perf_counter()
    assert bpy.ops.lens_lights.bake() == {"FINISHED"}
    bake_s = time.perf_counter() - t
    size = len(scene.lens_lights.baked_from.encode())
    middle = (1 + frames) // 2
    scene.frame_set(middle)
    dg = bpy.context.evaluated_depsgraph_get()
    checks, reads = [], []
    for _ in range(repeats):
        bake_check.on_depsgraph_update(scene)  # what an update does: the cache is old
        t = time.perf_counter()
        status = bake_check.status(bpy.context)
        checks.append(time.perf_counter() - t)
        t = time.perf_counter()
        read_depsgraph(dg, scene).occluders.release()
        reads.append(time.perf_counter() - t)
    assert status is not None and not status.stale, status and status.text
    t = time.perf_counter()
    bake_check.status(bpy.context)
    cached = time.perf_counter() - t
    cube.location.x += 0.5
    bpy.context.view_layer.update()
    t = time.perf_counter()
    aside = bake_check.status(bpy.context)
    aside_s = time.perf_counter() - t
    cube_named = aside is None or aside.stale
    bead = bpy.data.objects["Bead.00001"] if n > 1 else bpy.data.objects["Sphere"]
    bead.location.x += 0.01
    bpy.context.view_layer.update()
    moved = bake_check.status(bpy.context)
    named = moved is not None and [c.name for c in moved.changes] == [bead.name]
    return dict(
        n=n,
        frames=frames,
        objects=n + 3,
        bake=bake_s,
        bytes=size,
        check=statistics.median(checks),
        read=statistics.median(reads),
        cached=cached,
        named=named,
        cube_named=cube_named,
        aside=aside_s,
        text=moved.text if moved is not None else "",
    )


def ms(x):
    return f"{1000.0 * x:.2f}"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--counts", type=int, nargs="+", default=[20, 100, 1000])
    ap.add_argument("--frames", type=int, default=10)
    ap.add_argument("--repeats", type=int, default=9)
    args = ap.parse_args(argv)
    load_extension().register()
    load = os.getloadavg()[0]
    rows = []
    for n in args.counts:
        r = run(n, args.frames, args.repeats)
        rows.append(r)
        print(
            f"{n} lenses, {args.frames} frames: record {r['bytes']} B, check {ms(r['check'])} ms "
            f"(read {ms(r['read'])} ms), cached {ms(r['cached'])} ms, moved named: {r['named']}, "
            f"cube named: {r['cube_named']} ({ms(r['aside'])} ms)",
            flush=True,
        )
    lines = [
        "# The stale-bake check (issue 28 item 2)",
        "",
        f"`./lens-lights bench bake_check --counts {' '.join(map(str, args.counts))} "
        f"--frames {args.frames} --repeats {args.repeats}`; Blender "
        f"{bpy.app.version_string}, {platform.machine()}, {os.cpu_count()} cores "
        f"(load {load:.1f} at the start: the machine is shared, times are indicative).",
        "",
        "Scene: `bench/live_update.py`'s (floor, N glass spheres, two point lights, one "
        "moving every frame), baked (Fitted, EEVEE) over the frames. *check*: the panel's "
        "`bake_check.status` on a cache miss (the viewport depsgraph read, the prints, the "
        "compare), median; *read*: `read_depsgraph` alone, the share of it that any read "
        "costs (live update pays it on every update); *cached*: a redraw with no update in "
        "between. *record*: bytes of `scene.lens_lights.baked_from` in the .blend.",
        "",
        "| lenses | objects | frames | bake s | record B | B / object | check ms | read ms "
        "| cached ms | a moved sphere named | a cube moved away from the light named "
        "(check ms) |",
        "| ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- | --- |",
    ]
    for r in rows:
        lines.append(
            f"| {r['n']} | {r['objects']} | {r['frames']} | {r['bake']:.1f} | {r['bytes']} "
            f"| {r['bytes'] / r['objects']:.0f} | {ms(r['check'])} | {ms(r['read'])} "
            f"| {ms(r['cached'])} | {'yes' if r['named'] else 'NO'} "
            f"| {'YES' if r['cube_named'] else 'no'} ({ms(r['aside'])}) |"
        )
    lines += ["", f"The message for the last: “{rows[-1]['text']}”."]
    REPORTS.mkdir(exist_ok=True)
    report = REPORTS / "bake_check.md"
    report.write_text("\n".join(lines) + "\n")
    print(f"wrote {report.relative_to(ROOT)}")


if __name__ == "__main__":
    main(sys.argv[1:])
    sys.stdout.flush()
    os._exit(0)  # bpy 4.x crashes at exit
