"""Generate's wall time on a glass pebble, before and after → reports/glass_generate_speed.md.

The scene (issue 25's speed case): a floor (8 m plane), a glass pebble — a UV sphere of
radius 0.5 scaled (1, 1, 0.5), shaded smooth, 1 m above the floor — one point light
(radius 0, as `bpy.data.lights.new` makes it) 3 m above it, a 1920 × 1080 camera looking down at it
from 5 m. 2 000 triangles (32 × 32 segments: 1 984) and 20 000 (100 × 100: 19 800),
EEVEE and Cycles. ``bpy.ops``-free: `blender.commands.generate.generate` on the
context, ``--repeat`` times per case after one Generate that warms the process up
(imports, numpy's first calls: a user's first Generate of a session pays them once);
the median and the best wall and CPU time and the median of each step's time
(`generate.LAST_FIGURES["timings"]`), the node and refinement rays traced. Each timed
Generate is of a glass the process has not built yet (`beam_trace.clear_built` first,
where the tree has it); *again*: Generate pressed once more right after, nothing changed
(a tree that keeps built glass by content reuses its BVH then).

    ./lens-lights bench glass_generate_speed [--before TREE] [--repeat 3] [--rounds 1]

``--before TREE``: a checkout of the code to compare with (e.g. ``git archive main |
tar -x -C /tmp/before``); each tree runs in its own processes (``--tree``,
``--json``). ``--rounds N``: the trees take turns N times (before, after, before, …),
each turn ``--repeat`` Generates per case, so that both see the same load on a shared
machine.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
REPORT = ROOT / "reports" / "glass_generate_speed.md"
CASES = [(2000, 32, 32), (20000, 100, 100)]
ENGINES = ["BLENDER_EEVEE_NEXT", "CYCLES"]


def load(tree: Path):
    """The extension of ``tree`` as the package `lens_lights` (as dev_extension)."""
    sys.path.insert(0, str(tree / "scripts"))
    spec = importlib.util.spec_from_file_location(
        "lens_lights", tree / "__init__.py", submodule_search_locations=[str(tree)]
    )
    module = importlib.util.module_from_spec(spec)
    sys.modules["lens_lights"] = module
    spec.loader.exec_module(module)
    module.register()
    return module


def scene(segments, rings, engine):
    import bpy

    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    try:
        sc.render.engine = engine
    except TypeError:  # Blender 5: EEVEE's name
        sc.render.engine = "BLENDER_EEVEE"
    sc.render.resolution_x, sc.render.resolution_y = 1920, 1080
    bpy.ops.mesh.primitive_plane_add(size=8.0, location=(0.0, 0.0, 0.0))
    bpy.ops.mesh.primitive_uv_sphere_add(
        radius=0.5, segments=segments, ring_count=rings, location=(0.0, 0.0, 1.0)
    )
    peb = bpy.context.object
    peb.name = "Pebble"
    peb.scale = (1.0, 1.0, 0.5)
    bpy.ops.object.shade_smooth()
    mat = bpy.data.materials.new("Glass")
    mat.use_nodes = True
    bsdf = mat.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Transmission Weight"].default_value = 1.0
    bsdf.inputs["IOR"].default_value = 1.5
    peb.data.materials.append(mat)
    lamp = bpy.data.lights.new("Lamp", "POINT")
    lamp.energy = 1000.0
    ob = bpy.data.objects.new("Lamp", lamp)
    sc.collection.objects.link(ob)
    ob.location = (0.3, 0.2, 4.0)
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    sc.collection.objects.link(cam)
    cam.location = (0.0, -3.0, 4.0)
    cam.rotation_euler = (0.6435, 0.0, 0.0)  # toward (0, 0, 0)
    sc.camera = cam
    tris = sum(len(p.vertices) - 2 for p in peb.data.polygons)
    return tris


def run_tree(tree: Path, repeat: int) -> list[dict]:
    import bpy

    load(tree)
    from lens_lights.blender.commands import generate as gen
    from lens_lights.core.lens.mesh import MeshLens

    # the CPU time (all threads) inside the glass mesh's tracer, summed per Generate
    traced = [0.0]
    plain = MeshLens.trace_branches

    def timed(self, *args, **kwargs):
        c = time.process_time()
        try:
            return plain(self, *args, **kwargs)
        finally:
            traced[0] += time.process_time() - c

    MeshLens.trace_branches = timed
    # a tree that keeps built glass by content (`beam_trace.clear_built`): each timed
    # Generate is of a glass seen for the first time, "again" of the same glass
    from lens_lights.core.caustic_layer import beam_trace

    forget = getattr(beam_trace, "clear_built", lambda: None)

    scene(*CASES[0][1:], ENGINES[0])  # the warm-up, untimed
    gen.generate(bpy.context)
    rows = []
    for label, seg, rings in CASES:
        for engine in ENGINES:
            walls, cpus, traces, parts, rays, again = [], [], [], [], None, []
            for _ in range(repeat):
                tris = scene(seg, rings, engine)
                forget()
                t, c = time.perf_counter(), time.process_time()
                traced[0] = 0.0
                gen.generate(bpy.context)
                traces.append(traced[0])
                walls.append(time.perf_counter() - t)
                cpus.append(time.process_time() - c)
                fig = gen.LAST_FIGURES
                parts.append(dict(fig.get("timings", {})))
                lb = getattr(bpy.context.scene.lens_lights, "last_report", "")
                rays = rays or lb
                t = time.perf_counter()  # Generate again, nothing changed
                gen.generate(bpy.context)
                again.append(time.perf_counter() - t)
            rows.append(
                dict(
                    label=label,
                    triangles=tris,
                    engine=engine,
                    walls=walls,
                    cpus=cpus,
                    traces=traces,
                    parts=parts,
                    report=rays,
                    again=again,
                )
            )
            print(f"{label} {engine}: {statistics.median(walls):.3f} s", flush=True)
    return rows


def summary(runs) -> list[dict]:
    """The rows of several runs of one tree (lists of `run_tree`'s rows) merged per
    case: medians and bests over all their Generates."""
    out = []
    for group in zip(*runs, strict=True):
        walls = [w for r in group for w in r["walls"]]
        cpus = [c for r in group for c in r["cpus"]]
        parts = [p for r in group for p in r["parts"]]
        keys = sorted({k for p in parts for k in p})
        out.append(
            dict(
                group[0],
                wall=statistics.median(walls),
                wall_best=min(walls),
                walls=walls,
                cpu=statistics.median(cpus),
                cpu_best=min(cpus),
                trace_cpu=statistics.median(t for r in group for t in r["traces"]),
                again=statistics.median(a for r in group for a in r.get("again", [])),
                parts={k: statistics.median(p.get(k, 0.0) for p in parts) for k in keys},
            )
        )
    return out


def uptime() -> str:
    return " ".join(f"{x:.2f}" for x in os.getloadavg())


SHOWN = ["read", "phase1", "mesh sources", "receivers", "bake", "build"]


def table(rows) -> list[str]:
    out = [
        "| triangles | engine | Generate (median) | best | CPU (median) | best | trace CPU | "
        + " | ".join(SHOWN)
        + " | runs | again |"
    ]
    out.append("|---:|---|---:|---:|---:|---:|---:|" + "---:|" * len(SHOWN) + "---|---:|")
    for r in rows:
        p = r["parts"]
        cells = [f"{p[k]:.3f}" if k in p else "–" for k in SHOWN]
        eng = "EEVEE" if "EEVEE" in r["engine"] else "Cycles"
        runs = ", ".join(f"{w:.2f}" for w in r["walls"])
        out.append(
            f"| {r['triangles']} | {eng} | **{r['wall']:.3f}** | {r['wall_best']:.3f} | "
            f"{r['cpu']:.3f} | {r['cpu_best']:.3f} | {r['trace_cpu']:.3f} | "
            + " | ".join(cells)
            + f" | {runs} | {r['again']:.3f} |"
        )
    return out


def bake_parts(rows) -> list[str]:
    keys = sorted({k for r in rows for k in r["parts"] if k.startswith("bake ")})
    if not keys:
        return []
    out = ["| triangles | engine | " + " | ".join(k[5:] for k in keys) + " |"]
    out.append("|---:|---|" + "---:|" * len(keys))
    for r in rows:
        eng = "EEVEE" if "EEVEE" in r["engine"] else "Cycles"
        cells = [f"{r['parts'].get(k, 0.0):.3f}" for k in keys]
        out.append(f"| {r['triangles']} | {eng} | " + " | ".join(cells) + " |")
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tree", type=Path, default=None, help="run this tree, write --json")
    ap.add_argument("--json", type=Path, default=None)
    ap.add_argument("--before", type=Path, default=None, help="a checkout to compare with")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--rounds", type=int, default=1, help="turns each tree takes")
    args = ap.parse_args(argv)
    if args.tree is not None:
        rows = run_tree(args.tree.resolve(), args.repeat)
        args.json.write_text(json.dumps(rows, indent=1))
        return 0
    trees = [(n, t) for n, t in [("before", args.before), ("after", ROOT)] if t is not None]
    runs = {name: [] for name, _ in trees}
    loads = {name: [] for name, _ in trees}
    for _ in range(args.rounds):
        for name, tree in trees:
            out = Path(f"/tmp/glass_generate_speed_{name}_{os.getpid()}.json")
            load0 = uptime()
            cmd = [sys.executable, __file__, "--tree", str(tree), "--json", str(out)]
            subprocess.run(cmd + ["--repeat", str(args.repeat)], check=True)
            runs[name].append(json.loads(out.read_text()))
            loads[name] += [load0, uptime()]
    results = {name: (summary(runs[name]), loads[name][0], loads[name][-1]) for name, _ in trees}
    lines = [
        "# Generate on a glass pebble: wall and CPU time",
        "",
        f"`./lens-lights bench glass_generate_speed --repeat {args.repeat} --rounds {args.rounds}"
        + (" --before <main at the start>`" if args.before else "`")
        + ": the scene of the bench's docstring (pebble r 0.5 × (1, 1, 0.5), one point"
        " light of radius 0, floor, 1920 × 1080 camera), Generate run"
        f" {args.repeat} times per case in each of {args.rounds} turns per tree (the trees"
        " taking turns), after a warm-up Generate per process; median and best wall time,"
        " median and best CPU time of the process"
        " (all its threads: on a shared machine the wall time waits for the cores), the"
        " CPU time inside the glass mesh's tracer (`MeshLens.trace_branches`: the coarse"
        " and the final trace, node rays and refinements), and the median of each step"
        " (wall), s. Each timed Generate is of a glass new to the process (a tree that"
        " keeps built glass by content forgets it first: `beam_trace.clear_built`);"
        " *again*: the median wall time of Generate pressed once more right after,"
        " nothing changed (the same glass: its BVH kept where the tree keeps it).",
        "",
    ]
    for name, (rows, l0, l1) in results.items():
        lines += [
            f"## {name}",
            "",
            f"Load average (1, 5, 15 min) at the start: {l0}; at the end: {l1} (2 cores, shared).",
            "",
        ]
        lines += table(rows) + [""] + ["The layer bake's parts:", ""] + bake_parts(rows) + [""]
        lines += (
            ["Reports:", ""]
            + [f"- {r['triangles']} {r['engine']}: {r['report']}" for r in rows]
            + [""]
        )
    REPORT.write_text("\n".join(lines))
    print(f"wrote {REPORT}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
