"""How fast a glass mesh is traced into the caustic layer → reports/mesh_lens_speed.md.

One point light above a smooth glass pebble (an ellipsoid 1 : 0.7 : 0.5, smooth corner
normals) of about 2 000, 20 000 and 100 000 triangles, and an ice cube (12 triangles),
over a floor; the default grid of the layer's budget (64 × 256 cells, 16 640 node
rays). Times, best of ``--repeat`` runs (the machine is shared: the load average at
the start is in the report):

* ``build`` — the MeshLens: its BVH, its face groups and convexity;
* ``trace`` — `trace_beam`: node rays with every branch, the cells sorted, refined
  cells' sub-grids, analytic flux;
* ``land`` — `build_layer` on the floor (the landing and the rasters);
* ``rays`` — rays traced (nodes + sub-grids), cells refined, cells cut by the budget;
* ``one wave`` — a single cast of the 16 640 node rays against the BVH;
* ``walked`` — the same rays' one-sided hits on the convex glass by surface walks
  (`core.shared.surface_walk`, what the waves use on a convex mesh).

And what the refinement buys: the off-axis ice cube's layer (48 × 192 cells, 40² texels)
against 400 000 Monte-Carlo rays through the same glass binned on its texels (L1 of the
irradiance, the MC's own noise included), for refinement budgets of 0, the default
(a quarter of the node rays, `mesh_beam.REFINE_SHARE`), half of them and 100 000 rays.

    ./lens-lights bench mesh_lens_speed [--repeat 3] [--threads 0|1]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import functools  # noqa: E402

from core.caustic_layer import mesh_beam  # noqa: E402
from core.caustic_layer.beam_trace import trace_beam  # noqa: E402
from core.caustic_layer.emitters import Lens, PointLight  # noqa: E402
from core.caustic_layer.rasters import build_layer  # noqa: E402
from core.caustic_layer.receiver_index import build_index  # noqa: E402
from core.lens.mesh import MeshLens  # noqa: E402
from core.shared import surface_walk, triangle_bvh  # noqa: E402
from reference.meshes import rectangle, uv_sphere  # noqa: E402

REPORT = ROOT / "reports" / "mesh_lens_speed.md"
AXES = np.array([1.0, 0.7, 0.5])
GRID = (64, 256)


def pebble(n_side: int):
    """(vertices, triangles, smooth corner normals) of the ellipsoid pebble."""
    m = uv_sphere((0.0, 0.0, 0.0), 1.0, n_side, n_side)
    v = np.asarray(m.vertices) * AXES
    t = np.asarray(m.triangles)
    nrm = v[t] / AXES**2
    nrm /= np.linalg.norm(nrm, axis=-1, keepdims=True)
    return v + [0.0, 0.0, 0.6], t, nrm


def cube():
    lo, hi = np.array([-0.5, -0.5, 0.0]), np.array([0.5, 0.5, 1.0])
    v = np.array(
        [
            [(lo, hi)[i][0], (lo, hi)[j][1], (lo, hi)[k][2]]
            for i in (0, 1)
            for j in (0, 1)
            for k in (0, 1)
        ]
    )
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    return v, np.array([t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))]), None


def record(v, t, nrm):
    c = 0.5 * (v.min(axis=0) + v.max(axis=0))
    r = float(np.linalg.norm(v - c, axis=1).max()) * (1 + 1e-9)
    return Lens(c, r, 1.5, kind="mesh", params=(v, t, nrm))


CPU = {}


def best(fn, repeat, key=None):
    """Best wall time of ``repeat`` runs (and its process CPU time, all threads, under
    ``key`` in CPU) and the last result."""
    times, out = [], None
    for _ in range(repeat):
        t0, c0 = time.perf_counter(), time.process_time()
        out = fn()
        times.append((time.perf_counter() - t0, time.process_time() - c0))
    wall, cpu = min(times)
    if key is not None:
        CPU[key] = cpu
    return wall, out


def case(name, mesh, floor, light, repeat):
    v, t, nrm = mesh
    rec = record(v, t, nrm)
    build, lens = best(lambda: _built(rec, v, t, nrm), repeat)
    tr, beam = best(lambda: trace_beam(light, rec, *GRID), repeat, (name, len(t)))
    land, layer = best(lambda: build_layer([beam], floor, 128), repeat)
    k = np.arange((GRID[0] + 1) * GRID[1])
    rng = np.random.default_rng(0)
    tgt = rec.center + rec.radius * 0.9 * rng.uniform(-1, 1, (len(k), 3))
    d = tgt - light.position
    d /= np.linalg.norm(d, axis=1)[:, None]
    o = np.broadcast_to(light.position, d.shape)
    wave, _ = best(lambda: triangle_bvh.intersect(lens.bvh, o, d), repeat)
    walked = float("nan")
    if lens.convex:
        walk = lens.walker
        walked, _ = best(lambda: surface_walk.intersect_convex(walk, o, d, 1), repeat)
    return {
        "name": name,
        "tris": len(t),
        "build": build,
        "trace": tr,
        "land": land,
        "total": build + tr + land,
        "cpu": CPU[(name, len(t))],
        "wave": wave,
        "walked": walked,
        "rays": beam.traced_rays,
        "refined": beam.refined_cells,
        "cut": beam.cut_cells,
        "parts": len(beam.parts),
        "flux": beam.total_flux,
        "landed": layer.flux_in_rasters + layer.flux_outside,
    }


def refinement_l1(budgets=(0, None, 48 * 193 // 2, 100_000), n=400_000):
    """L1 of the off-axis cube's layer against binned Monte-Carlo rays, per budget."""
    v, t, _ = cube()
    rec = record(v, t, None)
    floor = build_index(rectangle([0, 0, -0.001], [0, 0, 1], 16.0, 16.0))
    light = PointLight(np.array([2.5, 0.7, 3.0]), 1000.0)
    rng = np.random.default_rng(1)
    c, r = rec.center, rec.radius
    axis = (c - light.position) / np.linalg.norm(c - light.position)
    cos_max = np.sqrt(1 - (r / np.linalg.norm(c - light.position)) ** 2)
    cos_p = rng.uniform(cos_max, 1.0, n)
    sin_p = np.sqrt(1 - cos_p**2)
    ph = rng.uniform(0, 2 * np.pi, n)
    e1 = np.cross(axis, [0.0, 0.0, 1.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(axis, e1)
    d = cos_p[:, None] * axis + sin_p[:, None] * (
        np.cos(ph)[:, None] * e1 + np.sin(ph)[:, None] * e2
    )
    br = MeshLens(c, r, 1.5, 0.0, v, t).trace_branches(
        np.broadcast_to(light.position, d.shape), d, mesh_beam.MAX_DEPTH, mesh_beam.MIN_WEIGHT
    )
    ok = (br.crossings >= 2) & (br.weight > 0) & (br.directions[..., 2] < 0)
    p, dd = br.points[ok], br.directions[ok]
    w = br.weight[ok] * light.power / (4 * np.pi) * 2 * np.pi * (1 - cos_max) / n
    hit = p - (p[:, 2] / dd[:, 2])[:, None] * dd
    out = []
    orig = mesh_beam.trace_mesh_beam
    try:
        for b in budgets:
            mesh_beam.trace_mesh_beam = functools.partial(orig, refine_rays=b)
            beam = trace_beam(light, rec, 48, 192)
            pl = build_layer([beam], floor, 40).patches[0]
            x, y = (hit - pl.origin) @ pl.axis_u, (hit - pl.origin) @ pl.axis_v
            hist, _, _ = np.histogram2d(y, x, bins=[pl.edges_v, pl.edges_u], weights=w)
            mc = hist / (np.diff(pl.edges_v)[:, None] * np.diff(pl.edges_u)[None, :])
            l1 = np.abs(pl.irradiance[..., 0] - mc).sum() / mc.sum()
            out.append(("default" if b is None else str(b), beam.refined_cells, beam.cut_cells, l1))
    finally:
        mesh_beam.trace_mesh_beam = orig
    return out


def _built(rec, v, t, nrm):
    lens = MeshLens(rec.center, rec.radius, 1.5, 0.0, v, t, nrm)
    _ = lens.face_groups, lens.convex
    return lens


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--threads", type=int, default=1, help="0: one thread (no blocks in threads)")
    args = ap.parse_args(argv)
    if not args.threads:
        triangle_bvh.THREAD_ROWS = 1 << 62
    load = os.getloadavg()
    floor = build_index(rectangle([0, 0, 0], [0, 0, 1], 20.0, 20.0))
    light = PointLight(np.array([1.0, 0.5, 5.0]), 1000.0)
    rows = [case("ice cube", cube(), floor, light, args.repeat)]
    for n_side in (32, 100, 224):
        m = pebble(n_side)
        rows.append(case("pebble", m, floor, light, args.repeat))
    lines = [
        "# Glass mesh lens: trace speed",
        "",
        "`./lens-lights bench mesh_lens_speed "
        + f"--repeat {args.repeat} --threads {args.threads}` — one point light, the "
        + f"layer's default grid {GRID[0]} × {GRID[1]} cells ({(GRID[0] + 1) * GRID[1]} node "
        + "rays), best of the repeats, seconds. Load average at the start: "
        + f"{load[0]:.2f} on {os.cpu_count()} cores (a shared machine: figures vary).",
        "",
        "| object | triangles | build | trace | trace CPU | land | total | one wave | walked | rays traced | cells refined | cut | parts | flux W | landed W |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for r in rows:
        lines.append(
            f"| {r['name']} | {r['tris']} | {r['build']:.3f} | {r['trace']:.3f} | {r['cpu']:.3f} | {r['land']:.3f} | "
            f"**{r['total']:.3f}** | {r['wave']:.3f} | {r['walked']:.3f} | {r['rays']} | {r['refined']} | {r['cut']} | "
            f"{r['parts']} | {r['flux']:.3f} | {r['landed']:.3f} |"
        )
    lines += [
        "",
        "| refinement budget (rays) | cells refined | cut | L1 vs Monte Carlo |",
        "|---|---:|---:|---:|",
    ]
    for name, refined, cut, l1 in refinement_l1():
        lines.append(f"| {name} | {refined} | {cut} | {l1:.3f} |")
    lines += [
        "",
        "`trace CPU`: the process's CPU time for the trace (both threads' when the BVH",
        "casts blocks of rays in threads; on a busy machine the wall time is longer).",
        "`trace` includes every wave of the node rays (entry, exit, internal reflections",
        "above the layer's minimum weight) and the refined cells' sub-grids; `one wave` is a",
        "single cast of as many rays, the unit of the tracer's cost.",
        "",
    ]
    REPORT.parent.mkdir(exist_ok=True)
    REPORT.write_text("\n".join(lines), encoding="utf-8")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
