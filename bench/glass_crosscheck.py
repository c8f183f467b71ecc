"""The glass tracer (reference.glass_tracer) against mitsuba 3 on glass meshes.

    ./lens-lights bench glass_crosscheck          # a few minutes
    ./lens-lights bench glass_crosscheck --quick  # fewer paths, to try it out

Four glass shapes (n = 1.5) as the same flat-shaded triangle meshes
(reference.glass_meshes) in both: an oblate ellipsoid under a point light, a
biconvex lens in a parallel beam, a rod lying just above the table under an
oblique point light, a cube under a point light at 45°.  mitsuba renders the
scene with its particle tracer (`ptracer`, variant scalar_rgb: every Fresnel
branch by roulette, TIR) onto a white-ish Lambertian plane seen by a far tilted
camera; its pixels are binned into cells of the plane as in
bench/reference_crosscheck.py.  The reference traces the same mesh
(`trace_glass`, every branch, outer reflection kept) and, for the tessellation's
size, the analytic shape too.  Compared over the mesh's umbra on the plane (no
direct light there in mitsuba's image).  Writes reports/glass_crosscheck.md + .png.
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

from reference import PointLight, ReceiverPlane, SunLight  # noqa: E402
from reference.glass_meshes import biconvex_mesh, box_mesh, ellipsoid_mesh, rod_mesh  # noqa: E402
from reference.glass_tracer import Glass, Receiver, trace_glass  # noqa: E402
from reference.shapes import Biconvex, Box, Ellipsoid, Rod, TriangleMesh  # noqa: E402
from reference.vectors import unit  # noqa: E402

REPORTS = ROOT / "reports"
N = 1.5
CELLS = 24
ALBEDO = 0.2  # a dim plane: little of its light comes back through the glass
UMBRA_MARGIN = 0.03  # of the half-width: a few pixels
WIDTH = 640
MAX_DEPTH = 12  # glass interactions in the reference; mitsuba's counts the plane and camera too


def _rot_y(deg):
    a = math.radians(deg)
    return np.array([[math.cos(a), 0, math.sin(a)], [0, 1, 0], [-math.sin(a), 0, math.cos(a)]])


def _rot_z(deg):
    a = math.radians(deg)
    return np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])


def cases():
    """(name, description, analytic shape, mesh (v, f), light, plane z, grid centre,
    half-width, mitsuba samples per pixel)."""
    out = []
    e = Ellipsoid((0.0, 0.0, 0.0), (1.0, 0.75, 0.45), _rot_y(20.0))
    out.append(
        (
            "ellipsoid",
            "oblate ellipsoid 1 × 0.75 × 0.45 tilted 20°, point light 4 above, plane 2.5 below",
            e,
            ellipsoid_mesh(e.center, e.axes, e.rotation, 48, 96)[:2],
            ("point", (0.8, 0.3, 4.0), 4.0 * math.pi),
            -2.5,
            None,
            1.7,
            24,
        )
    )
    b = Biconvex((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 3.0, 3.0, 0.45)
    out.append(
        (
            "biconvex",
            "biconvex lens R 3/3, 0.45 thick (f ≈ 3), parallel beam 8° off its axis, plane 2 below",
            b,
            biconvex_mesh(b, 24, 96)[:2],
            (
                "sun",
                unit(np.array([math.sin(math.radians(8)), 0.0, -math.cos(math.radians(8))])),
                1.0,
            ),
            -2.0,
            None,
            1.0,
            32,
        )
    )
    r = Rod((0.0, 0.0, 0.9), (1.0, 0.0, 0.0), 0.3, 2.4)
    out.append(
        (
            "rod",
            "rod r 0.3, length 2.4, axis 0.9 above the plane, point light at 50° from −y",
            r,
            rod_mesh(r, 96)[:2],
            ("point", (0.3, -2.2, 3.5), 4.0 * math.pi),
            0.0,
            None,
            1.3,
            24,
        )
    )
    c = Box((0.0, 0.0, 1.0), (0.8, 0.8, 0.8), _rot_z(20.0))
    out.append(
        (
            "cube",
            "cube 0.8 turned 20°, centre 1 above the plane, point light at 45°",
            c,
            box_mesh(c)[:2],
            ("point", (-2.5, 0.3, 3.5), 4.0 * math.pi),
            0.0,
            None,
            1.2,
            24,
        )
    )
    return out


def ref_emitter(light):
    kind, a, b = light
    return PointLight(tuple(a), b) if kind == "point" else SunLight(tuple(a), b)


def mitsuba_emitter(light, center, radius):
    kind, a, b = light
    if kind == "sun":
        return {
            "type": "directional",
            "direction": list(map(float, a)),
            "irradiance": {"type": "rgb", "value": [b] * 3},
        }
    # a point light as a spot whose cone just holds the glass (no paths wasted)
    dist = float(np.linalg.norm(np.asarray(a) - center))
    alpha = math.degrees(math.asin(radius / dist))
    return {
        "type": "spot",
        "intensity": {"type": "rgb", "value": [b / (4 * math.pi)] * 3},
        "beam_width": alpha * 1.002,
        "cutoff_angle": alpha * 1.004,
        "to_world": ("look_at", list(map(float, a)), center.tolist()),
    }


def umbra_cells(mesh, light, Z, edges, margin):
    """Cells whose centre and corners (grown by ``margin``) the mesh hides from the
    light (a point, or the sun's direction)."""
    pts, shape = _cell_points(Z, edges, margin)
    hidden = np.ones(shape, bool)
    for p in pts:
        if light[0] == "sun":
            d = np.tile(-unit(np.asarray(light[1], float)), (p.shape[0], 1))
            far = np.full(p.shape[0], np.inf)
        else:
            vec = np.asarray(light[1], float) - p
            far = np.linalg.norm(vec, axis=1)
            d = vec / far[:, None]
        hidden &= (mesh.hit(p, d, False, 1e-9).t < far).reshape(shape)
    return hidden


def _cell_points(Z, edges, margin):
    """Each cell's centre and corners grown by ``margin``: (5, cells, 3)."""
    ue, ve = edges
    h = 0.5 * (ue[1] - ue[0]) + margin
    cu, cv = np.meshgrid(0.5 * (ue[1:] + ue[:-1]), 0.5 * (ve[1:] + ve[:-1]), indexing="ij")
    return [
        np.stack([cu + du, cv + dv, np.full(cu.shape, Z)], -1).reshape(-1, 3)
        for du, dv in ((0, 0), (-h, -h), (-h, h), (h, -h), (h, h))
    ], cu.shape


def visible_cells(mesh, Z, edges, margin, d):
    """Cells whose centre and grown corners a far camera in direction ``d`` sees."""
    pts, shape = _cell_points(Z, edges, margin)
    ok = np.ones(shape, bool)
    for p in pts:
        ok &= ~np.isfinite(mesh.hit(p, np.tile(d, (p.shape[0], 1)), False, 1e-9).t).reshape(shape)
    return ok


def camera_direction(mesh, Z, edges, margin, umbra):
    """The far camera's direction (from the plane toward it) that sees the most
    umbra cells whole, the least tilted among equals; and its visible cells."""
    best = None
    for beta in np.radians(np.arange(0.0, 70.0, 5.0)):
        for az in np.radians(np.arange(0.0, 360.0, 45.0 if beta > 0 else 360.0)):
            d = np.array(
                [math.sin(beta) * math.cos(az), math.sin(beta) * math.sin(az), math.cos(beta)]
            )
            vis = visible_cells(mesh, Z, edges, margin, d)
            score = int(np.sum(vis & umbra))
            if best is None or score > best[0]:
                best = (score, d, math.degrees(beta), vis)
    return best[1], best[2], best[3]


def write_obj(path, v, f):
    with open(path, "w") as fh:
        for p in v:
            fh.write(f"v {p[0]:.17g} {p[1]:.17g} {p[2]:.17g}\n")
        for t in f:
            fh.write(f"f {t[0] + 1} {t[1] + 1} {t[2] + 1}\n")


def mitsuba_render(obj, emitter, Z, c0, w, cam_dir, spp, width):
    import drjit as dr
    import mitsuba as mi

    mi.set_variant("scalar_rgb")
    dr.set_thread_count(1)
    logger = mi.logger() if hasattr(mi, "logger") else mi.Thread.thread().logger()
    logger.set_log_level(mi.LogLevel.Warn)
    logger.clear_appenders()
    T = mi.ScalarTransform4f
    emitter = dict(emitter)
    tw = emitter.pop("to_world", None)
    if tw is not None:
        axis = unit(np.asarray(tw[2]) - np.asarray(tw[1]))
        up_l = [0, 0, 1] if abs(axis[2]) < 0.9 else [1, 0, 0]
        emitter["to_world"] = T().look_at(origin=tw[1], target=tw[2], up=up_l)
    L = 80.0 * w
    tgt = np.array([c0[0], c0[1], Z])
    up = [0, 1, 0] if abs(cam_dir[1]) < 0.9 else [1, 0, 0]
    base = {
        "type": "scene",
        "sensor": {
            "type": "perspective",
            "fov": 2 * math.degrees(math.atan(1.08 * w / L)),
            "fov_axis": "smaller",
            "to_world": T().look_at(
                origin=(tgt + L * cam_dir).tolist(), target=tgt.tolist(), up=up
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
        "glass": {
            "type": "obj",
            "filename": str(obj),
            "face_normals": True,
            "bsdf": {"type": "dielectric", "int_ior": N, "ext_ior": 1.0},
        },
        "plane": {
            "type": "rectangle",
            "to_world": T().translate([c0[0], c0[1], Z]) @ T().scale([1.6 * w, 1.6 * w, 1]),
            "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [ALBEDO] * 3}},
        },
    }
    t0 = time.perf_counter()
    scene = mi.load_dict(
        dict(
            base, integrator={"type": "ptracer", "max_depth": MAX_DEPTH + 2, "hide_emitters": True}
        )
    )
    halves = [np.array(mi.render(scene, spp=spp // 2, seed=s)) for s in (1, 2)]
    seconds = time.perf_counter() - t0
    pos = np.array(
        mi.render(
            mi.load_dict(dict(base, integrator={"type": "aov", "aovs": "pp:position"})), spp=4
        )
    )
    E = [
        math.pi * h[..., :3].mean(axis=2) / ALBEDO for h in halves
    ]  # Lambertian: E = pi L / albedo
    return E, pos[..., :3], seconds, width * width * spp


def bin_pixels(E_halves, pos, Z, edges, scale):
    """Per cell: the flux of the pixels whose plane point falls in it (E times the
    pixel's footprint) over the cell's area; the standard error from the two halves."""
    on = np.abs(pos[..., 2] - Z) < 1e-4 * scale
    di, dj = np.gradient(pos, axis=0), np.gradient(pos, axis=1)
    foot = np.linalg.norm(np.cross(di, dj), axis=2)
    x, y = pos[..., 0][on], pos[..., 1][on]
    cnt = np.histogram2d(x, y, bins=edges)[0]
    cell = np.diff(edges[0])[0] * np.diff(edges[1])[0]
    means = [np.histogram2d(x, y, bins=edges, weights=(e * foot)[on])[0] / cell for e in E_halves]
    return 0.5 * (means[0] + means[1]), 0.5 * np.abs(means[0] - means[1]), cnt


def run_case(case, quick, tmp, log):
    name, desc, shape, (v, f), light, Z, c0, w, spp = case
    if quick:
        spp = 4
    n_rays = 150_000 if quick else 1_000_000
    mesh = TriangleMesh(v, f)
    em = ref_emitter(light)
    plane = ReceiverPlane((0.0, 0.0, Z), (0.0, 0.0, 1.0))
    if c0 is None:  # centre the square on where the beam lands
        probe = trace_glass(
            em,
            [Glass(shape, N)],
            [Receiver(plane, (np.linspace(-4, 4, 161),) * 2)],
            20_000,
            seed=9,
            max_depth=2,
        )
        cf = probe.receivers[0].cell_flux()
        mid = 0.5 * (probe.receivers[0].u_edges[1:] + probe.receivers[0].u_edges[:-1])
        c0 = (float(np.sum(cf.sum(1) * mid) / cf.sum()), float(np.sum(cf.sum(0) * mid) / cf.sum()))
    edges = (
        np.linspace(c0[0] - w, c0[0] + w, CELLS + 1),
        np.linspace(c0[1] - w, c0[1] + w, CELLS + 1),
    )
    rec = [Receiver(plane, edges)]
    kw = dict(max_depth=MAX_DEPTH, outer_reflection=True)
    ref = trace_glass(em, [Glass(mesh, N)], rec, n_rays, seed=1, **kw)
    ana = trace_glass(em, [Glass(shape, N)], rec, n_rays, seed=2, **kw)
    log(
        f"{name}: reference {n_rays} rays on {len(f)} triangles in {ref.seconds:.0f} s, "
        f"analytic in {ana.seconds:.0f} s"
    )
    umbra = umbra_cells(mesh, light, Z, edges, UMBRA_MARGIN * w)
    c_mesh, r_mesh = mesh.bounding_sphere()
    cam_dir, beta, visible = camera_direction(mesh, Z, edges, UMBRA_MARGIN * w, umbra)
    obj = Path(tmp) / f"{name}.obj"
    write_obj(obj, v, f)
    E, pos, seconds, paths = mitsuba_render(
        obj, mitsuba_emitter(light, c_mesh, r_mesh), Z, c0, w, cam_dir, spp, WIDTH
    )
    mit, mit_se, cnt = bin_pixels(E, pos, Z, edges, w)
    region = umbra & visible & (cnt >= 4)
    R, A = ref.receivers[0], ana.receivers[0]
    area = (2 * w / CELLS) ** 2
    f_ref = float(np.sum(R.irradiance[region]) * area)
    res = dict(
        name=name,
        desc=desc,
        tris=len(f),
        c0=c0,
        w=w,
        edges=edges,
        ref=R,
        ana=A,
        mit=mit,
        region=region,
        flux_ratio=float(np.sum(mit[region]) * area) / f_ref,
        l1=float(np.sum(np.abs(mit - R.irradiance)[region]) / np.sum(R.irradiance[region])),
        noise=float(
            np.sum(np.hypot(mit_se, R.irradiance_se)[region]) / np.sum(R.irradiance[region])
        ),
        ana_ratio=float(np.sum(A.irradiance[region]) * area) / f_ref,
        ana_l1=float(
            np.sum(np.abs(A.irradiance - R.irradiance)[region]) / np.sum(R.irradiance[region])
        ),
        in_region=f_ref / R.flux,
        cells=int(region.sum()),
        paths=paths,
        seconds=seconds,
        ref_seconds=ref.seconds,
        n_rays=n_rays,
        beta=beta,
        balance=ref.balance() / ref.tally["into_glass"],
        tally=ref.tally,
    )
    log(
        f"{name}: mitsuba {paths / 1e6:.1f} M paths in {seconds:.0f} s (camera tilt {beta:.0f}°); "
        f"flux ratio {res['flux_ratio']:.4f}, L1 {res['l1']:.4f} (noise {res['noise']:.4f}); "
        f"analytic/mesh flux {res['ana_ratio']:.4f}, L1 {res['ana_l1']:.4f}; "
        f"{res['in_region']:.3f} of the landed flux in {res['cells']} umbra cells"
    )
    return res


def figure(results):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(3, len(results), figsize=(4.2 * len(results), 11), squeeze=False)
    for k, r in enumerate(results):
        eu, ev = r["edges"]
        vmax = max(r["ref"].irradiance[r["region"]].max(), 1e-12)
        ext = (eu[0], eu[-1], ev[0], ev[-1])
        for row, (img, label) in enumerate(
            ((r["mit"], "mitsuba ptracer"), (r["ref"].irradiance, "reference (mesh)"))
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
        ax = axes[2, k]
        mid = 0.5 * (eu[1:] + eu[:-1])
        j = int(np.argmax(r["ref"].cell_flux()[:, :].sum(axis=0)))  # the brightest row
        sel = r["region"][:, j]
        ax.plot(mid[sel], r["mit"][sel, j], "o", ms=3, color="tab:red", label="mitsuba")
        ax.plot(
            mid[sel], r["ref"].irradiance[sel, j], "-", color="k", lw=1, label="reference (mesh)"
        )
        ax.plot(
            mid[sel],
            r["ana"].irradiance[sel, j],
            "--",
            color="tab:blue",
            lw=1,
            label="reference (analytic)",
        )
        ax.set_title(
            f"{r['name']}: profile along u at v = {0.5 * (ev[j] + ev[j + 1]):.2f}", fontsize=9
        )
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(REPORTS / "glass_crosscheck.png", dpi=90)
    plt.close(fig)


def report(results, wall, quick):
    L = [
        "# The glass tracer against mitsuba 3 on glass meshes\n",
        "Generated by `./lens-lights bench glass_crosscheck`"
        + (" --quick" if quick else "")
        + f" in {wall:.0f} s (one core for mitsuba; a shared 2-core machine).\n",
        "Each shape is the same flat-shaded triangle mesh (`reference/glass_meshes.py`) in "
        "mitsuba 3 (variant `scalar_rgb`, `obj` with `face_normals`, `dielectric` n = 1.5, "
        f"integrator `ptracer`, `max_depth` {MAX_DEPTH + 2}) and in the reference "
        f"(`reference.glass_tracer.trace_glass`, every Fresnel branch, TIR, up to {MAX_DEPTH} "
        "glass interactions, the light reflected off the outside kept, as mitsuba keeps it). "
        f"The plane is Lambertian with albedo {ALBEDO} (its light that comes back through the "
        "glass, which mitsuba follows and the reference does not, is then small); mitsuba's "
        "pixels are binned into the plane's cells by their footprint as in "
        "`bench/reference_crosscheck.py` (E = π L / albedo). Compared over the mesh's "
        "**umbra** on the plane (cells whose centre and grown corners the mesh hides from the "
        "light: there mitsuba's image holds only light that went through or off the glass). "
        "L1 = Σ|E_mitsuba − E_ref| / Σ E_ref; noise = Σ of both standard errors / Σ E_ref, the "
        "floor of L1. The 'analytic' columns trace the exact shape instead of its mesh (the "
        "tessellation's own effect).\n",
        "| shape | scene | triangles | mitsuba paths / time | reference rays / time | share of the "
        "landed flux in the umbra cells | flux ratio mitsuba/ref | L1 | noise | analytic/mesh flux | "
        "analytic vs mesh L1 | energy balance |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in results:
        L.append(
            f"| {r['name']} | {r['desc']} | {r['tris']} | {r['paths'] / 1e6:.1f} M / {r['seconds']:.0f} s | "
            f"{r['n_rays'] / 1e6:.2f} M / {r['ref_seconds']:.0f} s | {r['in_region']:.3f} "
            f"({r['cells']} cells) | {r['flux_ratio']:.4f} | {r['l1']:.4f} | {r['noise']:.4f} | "
            f"{r['ana_ratio']:.4f} | {r['ana_l1']:.4f} | {r['balance']:.1e} |"
        )
    L.append("")
    L.append("![mitsuba and the reference](glass_crosscheck.png)\n")
    L.append(
        "Top: mitsuba's irradiance per cell (umbra cells only); middle: the reference's on the "
        "same scale; bottom: both along the brightest row (and the analytic shape's).\n"
    )
    L.append("## Notes\n")
    L.append(
        "- Energy balance: (flux into the glass − landed − escaped − absorbed − blocked − cut) / "
        "flux into the glass, the reference's own bookkeeping (zero up to its Russian roulette)."
    )
    L.append(
        "- The point lights are mitsuba spots whose cone just holds the mesh's bounding sphere "
        "(the same light for the glass); the sun is mitsuba's `directional` (no angular size)."
    )
    L.append(
        "- Outside the umbra mitsuba adds the light's direct illumination, which the reference "
        "leaves out by design: light refracted out of the shadow (the cube's side faces, the "
        "rod's edge) is not compared here; the 'share' column says how much of it is."
    )
    (REPORTS / "glass_crosscheck.md").write_text("\n".join(L) + "\n")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--quick", action="store_true", help="fewer paths (a trial run)")
    ap.add_argument("--only", help="comma-separated cases (ellipsoid, biconvex, rod, cube)")
    args = ap.parse_args(argv)
    REPORTS.mkdir(exist_ok=True)
    t0 = time.perf_counter()

    def log(msg):
        print(f"[{time.perf_counter() - t0:6.1f} s] {msg}", flush=True)

    todo = [c for c in cases() if not args.only or c[0] in args.only.split(",")]
    with tempfile.TemporaryDirectory() as tmp:
        results = [run_case(c, args.quick, tmp, log) for c in todo]
    figure(results)
    report(results, time.perf_counter() - t0, args.quick)
    log(f"wrote {REPORTS / 'glass_crosscheck.md'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
