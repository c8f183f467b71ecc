"""Caustic layer benchmark → reports/caustic_layer.md and reports/caustic_layer.png.

The caustic layer (addon/caustic_sheet) against the exact one-dimensional integral of
SPEC §6 (addon.exact_optics.irradiance_on_plane) for a glass ball floating above a
plane and a marble resting on it: the layer's irradiance image beside the exact one,
the relative L1 over the lens' shadow disc (rings) and the flux ratio; then the time to
build the layers of 64 lens lights on a table scene of 10 000 triangles.

    ./lens-lights bench caustic_layer [--quick]
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from addon import exact_optics as eo
from addon.caustic_sheet.beam_trace import trace_beam
from addon.caustic_sheet.caustic_layer import build_layer
from addon.caustic_sheet.emitters import Lens, PointLight
from addon.caustic_sheet.layer_metrics import relative_l1, ring_irradiance
from addon.caustic_sheet.meshes import merge, rectangle
from addon.caustic_sheet.receiver_index import build_index

REPORTS = ROOT / "reports"
R, N_IOR, D = 1.0, 1.5, 10.0
I0 = 1.0  # W/sr (a 4π W point light)


def accuracy_case(name, Z, nr, na, res, rings=40):
    """The lens at the origin, the light on the axis at z = −D, the plane z = Z (for the
    resting marble Z = R: the plane touches the sphere)."""
    lens = Lens(np.zeros(3), R, N_IOR)
    index = build_index(rectangle([0, 0, Z], [0, 0, 1], 400.0, 400.0, 8, 8))
    t = time.perf_counter()
    beam = trace_beam(PointLight(np.array([0.0, 0.0, -D]), 4 * math.pi * I0), lens, nr, na)
    layer = build_layer([beam], index, resolution=res)
    seconds = time.perf_counter() - t
    patch = layer.patches[0]
    r_max = eo.lens_shadow_radius(D, R, Z) if Z > R * 1.01 else 0.5 * R
    edges = np.linspace(0.0, r_max, rings + 1)
    got = ring_irradiance(patch, [0, 0, Z], edges)
    exact = eo.irradiance_on_plane(I0, D, R, N_IOR, Z, edges)
    flux = eo.lens_flux(I0, D, R, N_IOR)
    return {
        "name": name,
        "Z": Z,
        "grid": f"{nr} × {na}",
        "rays": beam.n_rays,
        "res": res,
        "l1": relative_l1(got, exact, np.diff(edges**2)),
        "flux_ratio": layer.flux_in_rasters / flux,
        "outside": layer.flux_outside / flux,
        "lost": layer.flux_lost / flux,
        "seconds": seconds,
        "patch": patch,
        "r_max": r_max,
    }


def table_scene(n_lenses=64):
    """A 2 m × 1.2 m table top meshed into 9 800 triangles, a floor and a wall; marbles
    (R = 2 cm) resting on the table in an 8 × 8 array under one point light."""
    x_axis = [1.0, 0.0, 0.0]
    table = rectangle([0, 0, 0], [0, 0, 1], 2.0, 1.2, 70, 70, x_axis, object_id=1)
    floor = rectangle([0, 0, -0.75], [0, 0, 1], 10.0, 10.0, 1, 1, x_axis, object_id=2)
    wall = rectangle([0, 1.5, 0.5], [0, -1, 0], 10.0, 3.0, 10, 10, x_axis, object_id=3)
    mesh = merge(table, floor, wall)
    r = 0.02
    side = int(round(math.sqrt(n_lenses)))
    xs, ys = np.meshgrid(np.linspace(-0.8, 0.8, side), np.linspace(-0.45, 0.45, side))
    lenses = [
        Lens(np.array([x, y, r]), r, N_IOR) for x, y in zip(xs.ravel(), ys.ravel(), strict=True)
    ]
    return mesh, lenses, PointLight(np.array([0.3, -0.2, 1.5]), 100.0)


def timing_case(nr, na, res, repeats=3):
    mesh, lenses, light = table_scene()
    best = None
    for _ in range(repeats):  # best of a few: the machine is shared
        t0, c0 = time.perf_counter(), time.process_time()
        index = build_index(mesh)
        t1 = time.perf_counter()
        beams = [trace_beam(light, lens, nr, na) for lens in lenses]
        t2 = time.perf_counter()
        layer = build_layer(beams, index, resolution=res)
        t3, c3 = time.perf_counter(), time.process_time()
        row = {
            "cpu": c3 - c0,
            "grid": f"{nr} × {na}",
            "res": res,
            "sources": len(lenses),
            "triangles": len(mesh.triangles),
            "rays": layer.n_rays,
            "index": t1 - t0,
            "trace": t2 - t1,
            "land": layer.timings["land"],
            "splat": layer.timings["splat"],
            "mesh": layer.timings["mesh"],
            "total": t3 - t0,
            "rasters": len(layer.patches),
            "flux_ratio": layer.flux_in_rasters / layer.flux_emitted,
            "lost": layer.flux_lost / layer.flux_emitted,
        }
        if best is None or row["total"] < best["total"]:
            best = row
    best["rays_per_s_land"] = best["rays"] / best["land"]
    best["rays_per_s_total"] = best["rays"] / best["total"]
    return best


def exact_image(patch, Z):
    """The exact irradiance at each texel centre (from fine rings)."""
    c = patch.texel_centers()
    rho = np.hypot(c[..., 0], c[..., 1])
    edges = np.linspace(0.0, rho.max() * 1.001, 4001)
    ring = eo.irradiance_on_plane(I0, D, R, N_IOR, Z, edges)
    k = np.clip(np.searchsorted(edges, rho) - 1, 0, len(ring) - 1)
    return ring[k]


def picture(cases, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import LogNorm

    fig, axes = plt.subplots(len(cases), 3, figsize=(13.5, 4.2 * len(cases)))
    for row, case in zip(np.atleast_2d(axes), cases, strict=True):
        p = case["patch"]
        layer_img = p.irradiance[..., 0]
        exact_img = exact_image(p, case["Z"])
        hi = max(layer_img.max(), exact_img.max())
        norm = LogNorm(vmin=hi * 1e-4, vmax=hi)
        lim = case["r_max"]
        for ax, img, title in (
            (row[0], layer_img, "caustic layer"),
            (row[1], exact_img, "exact (SPEC §6 integral)"),
        ):
            ax.pcolormesh(
                p.edges_u, p.edges_v, np.maximum(img, hi * 1e-5), norm=norm, cmap="inferno"
            )
            ax.set_xlim(-lim, lim)
            ax.set_ylim(-lim, lim)
            ax.set_aspect("equal")
            ax.set_title(f"{case['name']}: {title}")
        edges = np.linspace(0.0, lim, 81)
        mid = 0.5 * (edges[1:] + edges[:-1])
        row[2].semilogy(
            mid, eo.irradiance_on_plane(I0, D, R, N_IOR, case["Z"], edges), "k-", label="exact"
        )
        row[2].semilogy(mid, ring_irradiance(p, [0, 0, case["Z"]], edges), "r--", label="layer")
        row[2].set_xlabel("radius / R")
        row[2].set_ylabel("ring irradiance (W/R²)")
        row[2].set_title(f"L1 {case['l1']:.3f}, flux ratio {case['flux_ratio']:.4f}")
        row[2].legend()
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def write_report(cases, timings, path):
    lines = [
        "# Caustic layer: accuracy and speed",
        "",
        "Generated by `./lens-lights bench caustic_layer` (bench/caustic_layer.py).",
        "",
        "The caustic layer (`addon/caustic_sheet/`) traces each lens light's beam exactly as",
        "a grid of rays over the lens' lit disc, lands it on the receivers' triangles and",
        "accumulates the landed cells' flux into an irradiance raster per planar receiver",
        "patch (folds add). Reference: the exact one-dimensional integral of SPEC §6",
        "(`exact_optics.irradiance_on_plane`, `lens_flux`). Glass n = 1.5, R = 1, a point",
        "light (I = 1 W/sr) on the axis at D = 10 R, a plane perpendicular to the axis at",
        "Z from the centre. L1: relative L1 of the ring irradiance over the lens' shadow",
        "disc (the resting marble: over r < R/2; 40 rings), flux ratio: flux in the",
        "layer / `lens_flux`.",
        "",
        "| case | Z / R | grid (rings × azimuths) | rays | raster | L1 | flux ratio "
        "| outside | lost | time (s) |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for c in cases:
        lines.append(
            f"| {c['name']} | {c['Z']:g} | {c['grid']} | {c['rays']} | "
            f"{c['res']}² | {c['l1']:.4f} | {c['flux_ratio']:.4f} | "
            f"{c['outside']:.1e} | {c['lost']:.1e} | {c['seconds']:.3f} |"
        )
    lines += [
        "",
        "EEVEE's best spot-light tier today (Fitted) has L1 0.50 on the same measure;",
        "Lightsheet (hand-aimed) about 0.03.",
        "",
        "![layer vs exact](caustic_layer.png)",
        "",
        "Rows: the floating ball (Z = 5 R), the same ball's plane near the focus",
        "(Z = 1.5 R, where the landed grid folds), the resting marble (Z = R). Columns: the",
        "layer's raster (its texels, sinh-spaced: finer in the core), the exact irradiance",
        "at the same texels, and the ring averages (log scale).",
        "",
        "## 64 lens lights on a table (10 000 triangles)",
        "",
        "Marbles (R = 2 cm) resting on a table top meshed into 9 800 triangles, plus a floor",
        "and a wall; one point light above. Best of 3 runs on a shared 2-core machine",
        "(wall-clock seconds; CPU: the process' CPU time, less sensitive to the other",
        "users of the machine). *index*: planar patches + BVH of the scene (once per",
        "scene); *trace*: 64 exact beams; *land*: all rays onto the receivers; *splat*:",
        "the folds-adding rasters; *mesh*: vertices, faces, UVs.",
        "",
        "| grid | raster | rays | index | trace | land | splat | mesh | total | CPU | "
        "rays/s (landing) | rays/s (all) | rasters | flux in rasters | lost |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- "
        "| --- |",
    ]
    for t in timings:
        lines.append(
            f"| {t['grid']} | {t['res']}² | {t['rays']} | {t['index']:.3f} | "
            f"{t['trace']:.3f} | {t['land']:.3f} | {t['splat']:.3f} | {t['mesh']:.3f} | "
            f"**{t['total']:.3f}** | {t['cpu']:.3f} | {t['rays_per_s_land']:.0f} | "
            f"{t['rays_per_s_total']:.0f} | {t['rasters']} | {t['flux_ratio']:.4f} | "
            f"{t['lost']:.1e} |"
        )
    lines += [
        "",
        "The issue's goal is < 0.5 s for 64 lens lights of a table scene. Lost: flux that",
        "misses every receiver (exactly, 1e-4 of a marble's beam leaves it upward).",
        "",
    ]
    path.write_text("\n".join(lines))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--quick", action="store_true", help="fewer timing repeats")
    args = ap.parse_args(argv)
    cases = [
        accuracy_case("floating ball", 5.0, 32, 128, 128),
        accuracy_case("floating ball (fine)", 5.0, 64, 256, 256),
        accuracy_case("resting marble", 1.0, 32, 128, 128),
        accuracy_case("near the focus (folds)", 1.5, 32, 128, 128),
    ]
    for c in cases:
        print(
            f"{c['name']:>24}: L1 {c['l1']:.4f} flux ratio {c['flux_ratio']:.4f} "
            f"({c['seconds']:.3f} s)"
        )
    repeats = 1 if args.quick else 3
    timings = [
        timing_case(8, 32, 32, repeats),
        timing_case(16, 64, 64, repeats),
        timing_case(32, 128, 64, repeats),
    ]
    for t in timings:
        print(
            f"64 sources, {t['grid']}: {t['total']:.3f} s, "
            f"{t['rays_per_s_land']:.0f} rays/s landing"
        )
    REPORTS.mkdir(exist_ok=True)
    picture([cases[0], cases[3], cases[2]], REPORTS / "caustic_layer.png")
    write_report(cases, timings, REPORTS / "caustic_layer.md")
    print(f"wrote {REPORTS / 'caustic_layer.md'}")


if __name__ == "__main__":
    main()
