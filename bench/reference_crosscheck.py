"""The reference light tracer (reference) against mitsuba 3 on the same scenes.

    ./lens-lights bench reference_crosscheck          # a few minutes, one core
    ./lens-lights bench reference_crosscheck --quick  # fewer paths, to try it out

One glass sphere (R = 1, n = 1.5) lit from -z, a white Lambertian receiving plane
behind it; per emitter (point, spot covering half the lens, directional, area) the
irradiance on a grid of cells of the plane from mitsuba 3 (variant scalar_rgb,
integrator ptracer, max_depth 4: light -> entry -> exit -> plane -> camera) and
from the reference tracer.  Compared over the lens's umbra on the plane (where the
emitter's direct light, which mitsuba adds and the reference leaves out, is zero).
Writes reports/reference_crosscheck.md and reports/reference_crosscheck.png.
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

from reference import (
    AreaLight,
    GlassSphere,
    PointLight,
    ReceiverPlane,
    SpotLight,
    SunLight,
    lens_shadow,
    trace_irradiance,
)

REPORTS = ROOT / "reports"
R, N = 1.0, 1.5
LENS = GlassSphere((0.0, 0.0, 0.0), R, N)
CELLS = 24
UMBRA_MARGIN = 0.04  # of the half-width: a few pixels
WIDTH = 1024  # pixels: many across a cell even at a grazing camera angle


def cases():
    """(name, description, reference emitter, mitsuba emitter dict, plane Z, half-width
    of the measured square, mitsuba samples per pixel)."""
    D = 4.0
    alpha = math.degrees(math.asin(R / D))
    shadow = (D + 3.0) * R / math.sqrt(D * D - R * R)
    H = 20.0
    axis = (math.sin(math.radians(H)), 0.0, math.cos(math.radians(H)))
    sx, sy, P_area = 0.6, 0.3, 10.0
    return [
        (
            "point",
            f"point light r = 0 on the axis, D = {D:g} R, plane 3 R behind the centre",
            PointLight((0.0, 0.0, -D), 4.0 * math.pi),
            # 1 W/sr in a cone just wider than the sphere: the point light, no paths wasted
            {
                "type": "spot",
                "intensity": {"type": "rgb", "value": [1.0, 1.0, 1.0]},
                "beam_width": alpha * 1.002,
                "cutoff_angle": alpha * 1.004,
                "to_world": ("look_at", [0, 0, -D], [0, 0, 0]),
            },
            3.0,
            1.05 * shadow,
            4,
        ),
        (
            "spot",
            f"hard-edged spot (half-angle {H:g} deg, mitsuba: beam_width {H - 0.02:g} deg) "
            "whose edge passes through the lens centre, D = 4 R, plane 3 R behind",
            SpotLight((0.0, 0.0, -D), axis, 4.0 * math.pi, math.radians(2 * H), 0.0),
            {
                "type": "spot",
                "intensity": {"type": "rgb", "value": [1.0, 1.0, 1.0]},
                "beam_width": H - 0.02,
                "cutoff_angle": H,
                "to_world": ("look_at", [0, 0, -D], [axis[0] * 10, 0, -D + axis[2] * 10]),
            },
            3.0,
            1.05 * shadow,
            6,
        ),
        (
            "sun",
            "directional light (angle 0), strength 1 W/m^2, plane 2 R behind the centre",
            SunLight((0.0, 0.0, 1.0), 1.0),
            {
                "type": "directional",
                "direction": [0.0, 0.0, 1.0],
                "irradiance": {"type": "rgb", "value": [1.0, 1.0, 1.0]},
            },
            2.0,
            1.3 * R,
            10,
        ),
        (
            "area",
            f"rectangle area light {sx:g} x {sy:g} R, {P_area:g} W, facing the lens from "
            f"D = {D:g} R, plane 3 R behind",
            AreaLight((0.0, 0.0, -D), (0.0, 0.0, 1.0), P_area, sx, sy, "RECTANGLE"),
            {
                "type": "rectangle",
                "to_world": ("rect", [0, 0, -D], [0.5 * sx, 0.5 * sy, 1.0]),
                "emitter": {
                    "type": "area",
                    "radiance": {"type": "rgb", "value": [P_area / (math.pi * sx * sy)] * 3},
                },
            },
            3.0,
            1.05 * shadow * 1.1,
            20,
        ),
    ]


def camera_tilt(Z, w, margin=1.03):
    """Smallest tilt (from the plane's normal, toward +x) of a far camera whose lines of
    sight to every point of the square |u|, |v| <= w on z = Z miss the sphere."""
    g = np.linspace(-w, w, 41)
    p = np.stack(np.broadcast_arrays(g[:, None], g[None, :], Z), axis=-1).reshape(-1, 3)
    for beta in np.radians(np.arange(10.0, 88.0, 0.5)):
        d = np.array([math.sin(beta), 0.0, -math.cos(beta)])
        pd = p @ d
        if np.all((pd >= 0.0) | (np.sum(p * p, axis=1) - pd * pd >= (margin * R) ** 2)):
            return beta
    raise RuntimeError("no camera tilt sees the whole square")


def mitsuba_render(emitter, Z, w, spp, width, log):
    import drjit as dr
    import mitsuba as mi

    mi.set_variant("scalar_rgb")
    dr.set_thread_count(1)
    logger = mi.logger() if hasattr(mi, "logger") else mi.Thread.thread().logger()
    logger.set_log_level(mi.LogLevel.Warn)
    logger.clear_appenders()  # no progress bars in the log
    T = mi.ScalarTransform4f
    emitter = dict(emitter)
    tw = emitter.pop("to_world", None)
    if tw is not None and tw[0] == "look_at":
        emitter["to_world"] = T().look_at(origin=tw[1], target=tw[2], up=[0, 1, 0])
    elif tw is not None:
        emitter["to_world"] = T().translate(tw[1]) @ T().scale(tw[2])
    beta = camera_tilt(Z, w)
    L = 60.0
    d = np.array([math.sin(beta), 0.0, -math.cos(beta)])
    tgt = np.array([0.0, 0.0, Z])
    base = {
        "type": "scene",
        "sensor": {
            "type": "perspective",
            "fov": 2 * math.degrees(math.atan(1.1 * w / L)),
            "fov_axis": "y",
            "to_world": T().look_at(
                origin=(tgt + L * d).tolist(), target=tgt.tolist(), up=[0, 1, 0]
            ),
            "film": {
                "type": "hdrfilm",
                "width": width,
                "height": width,
                "rfilter": {"type": "box"},
                "pixel_format": "rgb",
            },
            "sampler": {"type": "independent", "sample_count": spp},
        },
        "light": emitter,
        "sphere": {
            "type": "sphere",
            "center": [0, 0, 0],
            "radius": R,
            "bsdf": {"type": "dielectric", "int_ior": N, "ext_ior": 1.0},
        },
        "plane": {
            "type": "rectangle",
            "to_world": T().translate([0, 0, Z])
            @ T().rotate([1, 0, 0], 180)
            @ T().scale([1.25 * w, 1.25 * w, 1]),
            "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [1, 1, 1]}},
        },
    }
    t0 = time.perf_counter()
    scene = mi.load_dict(
        dict(base, integrator={"type": "ptracer", "max_depth": 4, "hide_emitters": True})
    )
    halves = [np.array(mi.render(scene, spp=spp // 2, seed=seed)) for seed in (1, 2)]
    seconds = time.perf_counter() - t0
    pos = np.array(
        mi.render(
            mi.load_dict(dict(base, integrator={"type": "aov", "aovs": "pp:position"})), spp=4
        )
    )
    E = [math.pi * h[..., :3].mean(axis=2) for h in halves]  # white Lambertian: E = pi L
    return E, pos[..., :3], seconds, width * width * spp, math.degrees(beta)


def bin_pixels(E_halves, pos, Z, edges):
    """Irradiance per cell from the pixels: the flux each pixel collects (ptracer splats
    every light path into the one pixel its plane point projects to, so a pixel's E
    is the flux over its footprint / the footprint's area) summed over the pixels
    whose plane point falls in the cell, divided by the cell's area.  Weighting by the
    footprint (from the position render's finite differences) keeps the sum over
    cells the flux, whatever the number of pixels a cell happens to get (an
    unweighted pixel mean is biased by that count, by percents on a sharp caustic
    seen at a grazing camera angle).  Standard error from the two independent half
    renders."""
    on = np.abs(pos[..., 2] - Z) < 1e-3
    di, dj = np.gradient(pos, axis=0), np.gradient(pos, axis=1)
    foot = np.linalg.norm(np.cross(di, dj), axis=2)
    x, y = pos[..., 0][on], -pos[..., 1][on]  # plane coordinates (u = x, v = -y)
    cnt = np.histogram2d(x, y, bins=(edges, edges))[0]
    cell = np.diff(edges)[0] ** 2
    means = [
        np.histogram2d(x, y, bins=(edges, edges), weights=(e * foot)[on])[0] / cell
        for e in E_halves
    ]
    return 0.5 * (means[0] + means[1]), 0.5 * np.abs(means[0] - means[1]), cnt


def run_case(case, quick, log):
    name, desc, emitter, mit_emitter, Z, w, spp = case
    if quick:
        spp = 2
    plane = ReceiverPlane((0.0, 0.0, Z), (0.0, 0.0, -1.0), (1.0, 0.0, 0.0))
    edges = np.linspace(-w, w, CELLS + 1)
    n_rays = 300_000 if quick else 2_000_000
    ref = trace_irradiance(
        emitter, LENS, plane, n_rays, seed=1, grid=(edges, edges), fresnel="per_surface"
    )
    tracked = trace_irradiance(emitter, LENS, plane, n_rays // 4, seed=2, grid=(edges, edges))
    log(
        f"{name}: reference {ref.n_rays} rays in {ref.seconds:.1f} s "
        f"({ref.rays_per_second / 1e3:.0f} k rays/s)"
    )
    # umbra cells: the cell grown by a margin of a few pixels (a pixel whose centre is
    # in the cell collects light over its whole footprint) hidden from the whole emitter
    c = 0.5 * (edges[1:] + edges[:-1])
    h = 0.5 * (edges[1] - edges[0])
    g = h + UMBRA_MARGIN * w
    uu, vv = np.meshgrid(c, c, indexing="ij")
    umbra = np.ones(uu.shape, bool)
    for du, dv in ((0, 0), (-g, -g), (-g, g), (g, -g), (g, g)):
        umbra &= lens_shadow(emitter, LENS, plane, uu + du, vv + dv, n_samples=96) >= 1.0
    E_halves, pos, seconds, paths, beta = mitsuba_render(mit_emitter, Z, w, spp, WIDTH, log)
    mit, mit_se, cnt = bin_pixels(E_halves, pos, Z, edges)
    region = umbra & (cnt >= 4)
    area = (2 * h) ** 2
    f_ref = float(np.sum(ref.irradiance[region]) * area)
    f_mit = float(np.sum(mit[region]) * area)
    f_trk = float(np.sum(tracked.irradiance[region]) * area)
    l1 = float(np.sum(np.abs(mit - ref.irradiance)[region]) / np.sum(ref.irradiance[region]))
    noise = float(
        np.sum(np.hypot(mit_se, ref.irradiance_se)[region]) / np.sum(ref.irradiance[region])
    )
    res = dict(
        name=name,
        desc=desc,
        Z=Z,
        w=w,
        edges=edges,
        ref=ref,
        mit=mit,
        mit_se=mit_se,
        region=region,
        flux_ratio=f_mit / f_ref,
        tracked_ratio=f_trk / f_ref,
        l1=l1,
        noise=noise,
        paths=paths,
        seconds=seconds,
        beta=beta,
        in_region=f_ref / ref.flux_on_plane,
        cells=int(region.sum()),
    )
    log(
        f"{name}: mitsuba {paths / 1e6:.1f} M paths in {seconds:.0f} s; flux ratio "
        f"mitsuba/reference {res['flux_ratio']:.4f}, L1 {l1:.4f} (noise {noise:.4f}), "
        f"{res['in_region']:.3f} of the beam in the {res['cells']} umbra cells"
    )
    return res


def figure(results):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(3, len(results), figsize=(4.2 * len(results), 11), squeeze=False)
    for k, r in enumerate(results):
        e = r["edges"]
        vmax = max(r["ref"].irradiance[r["region"]].max(), 1e-12)
        ext = (e[0], e[-1], e[0], e[-1])
        for row, (img, label) in enumerate(
            ((r["mit"], "mitsuba ptracer"), (r["ref"].irradiance, "reference tracer"))
        ):
            ax = axes[row, k]
            ax.imshow(
                np.where(r["region"], img, np.nan).T,
                origin="lower",
                extent=ext,
                cmap="inferno",
                vmin=0,
                vmax=vmax,
            )
            ax.set_title(f"{r['name']}: {label}", fontsize=9)
            ax.set_xlabel("u / R")
        ax = axes[2, k]
        mid = 0.5 * (e[1:] + e[:-1])
        j = len(mid) // 2
        rows = slice(j - 1, j + 1)  # the two cell rows around v = 0
        sel = r["region"][:, rows].all(axis=1)
        m = r["mit"][:, rows].mean(axis=1)
        ms = np.hypot(*r["mit_se"][:, rows].T) / 2
        f = r["ref"].irradiance[:, rows].mean(axis=1)
        fs = np.hypot(*r["ref"].irradiance_se[:, rows].T) / 2
        ax.errorbar(
            mid[sel],
            m[sel],
            yerr=2 * ms[sel],
            fmt="o",
            ms=3,
            color="tab:red",
            label="mitsuba (±2 s.e.)",
        )
        ax.errorbar(
            mid[sel],
            f[sel],
            yerr=2 * fs[sel],
            fmt="-",
            color="k",
            lw=1,
            label="reference (±2 s.e.)",
        )
        ax.set_yscale("log")
        ax.set_title(f"{r['name']}: profile at v = 0 (umbra cells)", fontsize=9)
        ax.set_xlabel("u / R")
        ax.legend(fontsize=7)
    axes[0, 0].set_ylabel("v / R")
    axes[1, 0].set_ylabel("v / R")
    axes[2, 0].set_ylabel("irradiance (W / R^2)")
    fig.tight_layout()
    fig.savefig(REPORTS / "reference_crosscheck.png", dpi=100)
    plt.close(fig)


def report(results, wall, quick):
    L = [
        "# The reference light tracer against mitsuba 3\n",
        "Generated by `./lens-lights bench reference_crosscheck`"
        + (" --quick" if quick else "")
        + f" in {wall:.0f} s (one core).\n",
        "Scenes: a glass sphere R = 1, n = 1.5 at the origin, lit from −z; a white Lambertian "
        "plane z = Z facing the lens. mitsuba 3.9.1, variant `scalar_rgb`, integrator `ptracer` "
        "(light tracing, `max_depth` 4: light → entry → exit → plane → camera, the direct beam "
        "as the reference traces it), analytic sphere with the `dielectric` BSDF, a far camera "
        "tilted so that no line of sight to the measured square crosses the sphere; its pixels "
        "are placed on the plane by an `aov` position render; per cell, the flux of its pixels "
        f"(E = π L times the pixel's footprint) over the cell's area ({CELLS} × {CELLS} cells, "
        f"{WIDTH} × {WIDTH} pixels: a pixel straddling two cells counts in one of them, so "
        "pixels must be much smaller than cells). The reference tracer "
        '(`reference`) traces the same scene with `fresnel="per_surface"`, mitsuba\'s '
        "convention (each surface depolarises: ((t_s + t_p)/2)² instead of the "
        "polarisation-tracking (t_s² + t_p²)/2 of SPEC 6; the column 'tracked/per-surface' "
        "gives the size of that choice).\n",
        "Compared over the lens's **umbra** on the plane (cells whose centre and corners, "
        "the cell grown by a few pixels, the lens hides from the whole emitter, "
        "`reference.lens_shadow`): there mitsuba's image "
        "holds the lens's light only, while outside it mitsuba adds the emitter's direct light, "
        "which the reference leaves out by design. L1 = Σ|E_mitsuba − E_ref| / Σ E_ref over "
        "those cells; noise = the same sum of the two standard errors (mitsuba's from two "
        "independent half renders, the reference's from its own estimate), the floor L1 "
        "cannot go below.\n",
        "| emitter | scene | mitsuba paths / time | reference rays / time (rays/s) | "
        "share of the beam in the umbra | flux ratio mitsuba/ref | L1 | noise | "
        "tracked/per-surface |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in results:
        ref = r["ref"]
        L.append(
            f"| {r['name']} | {r['desc']} | {r['paths'] / 1e6:.1f} M / {r['seconds']:.0f} s | "
            f"{ref.n_rays / 1e6:.1f} M / {ref.seconds:.1f} s "
            f"({ref.rays_per_second / 1e3:.0f} k) | {r['in_region']:.3f} | "
            f"{r['flux_ratio']:.4f} | {r['l1']:.4f} | {r['noise']:.4f} | "
            f"{r['tracked_ratio']:.4f} |"
        )
    L.append("")
    L.append("![mitsuba and the reference tracer](reference_crosscheck.png)\n")
    L.append(
        "Top: mitsuba's irradiance per cell (umbra cells only); middle: the reference's, on "
        "the same colour scale; bottom: the profile through the two cell rows at v = 0.\n"
    )
    L.append("## Notes\n")
    L.append(
        "- mitsuba's `spot` falls off linearly in angle between `beam_width` and "
        "`cutoff_angle`, not with Blender's smoothstep in the cosine (SPEC 10); the spot "
        "case uses a 0.02° band, i.e. a hard cone on both sides (the reference's blend 0). "
        "The point case is a mitsuba spot whose cone just contains the sphere (the same "
        "light for the lens, no paths wasted)."
    )
    L.append(
        "- mitsuba's `directional` emitter has no angular size: the sun case has angle 0 "
        "(the reference's angular blur is tested against the exact optics in "
        "tests/reference/test_reference_emitters.py)."
    )
    L.append(
        "- mitsuba's `ptracer` also counts light reflected off the sphere's outside (depth "
        "3), which the reference drops; it lands mostly outside the umbra."
    )
    L.append(
        "- On the spot's dark side mitsuba shows ~1e-5 of the peak where the reference has "
        "exactly 0 (light of its 0.02° falloff band, paths that leave the lens near the "
        "cone's edge); invisible in the sums."
    )
    L.append(
        "- Runtimes are on a shared 2-core machine (other jobs running): the reference's "
        "rays/s vary by 2x between runs."
    )
    L.append(
        "- mitsuba's `area` emitter has no `spread`; neither has the reference (Cycles' "
        "default 180° is the Lambertian emitter both model)."
    )
    (REPORTS / "reference_crosscheck.md").write_text("\n".join(L) + "\n")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--quick", action="store_true", help="fewer paths (a trial run)")
    ap.add_argument("--only", help="comma-separated cases (point, spot, sun, area)")
    args = ap.parse_args(argv)
    REPORTS.mkdir(exist_ok=True)
    t0 = time.perf_counter()

    def log(msg):
        print(f"[{time.perf_counter() - t0:6.1f} s] {msg}", flush=True)

    todo = [c for c in cases() if not args.only or c[0] in args.only.split(",")]
    results = [run_case(c, args.quick, log) for c in todo]
    figure(results)
    report(results, time.perf_counter() - t0, args.quick)
    log(f"wrote {REPORTS / 'reference_crosscheck.md'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
