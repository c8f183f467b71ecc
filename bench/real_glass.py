"""Real glass (issue 25): lenses, rods, blocks — Cycles and EEVEE against the glass tracer.

    ./lens-lights bench real_glass [--only pebble,rod] [--px 48] [--pt-samples 1024]
                                   [--no-pt] [--no-generate] [--no-eevee] [--rays 1e6]
                                   [--truth-cache DIR]

``--truth-cache DIR``: keep each truth (case, pixels, rays, with or without the outer
reflection, seed) in DIR as .npy and reuse it: a second run of the same cases then
costs only Generate and the renders (the magnifier's truth is minutes).

Cases (metres; n = 1.5, Principled BSDF transmission 1, roughness 0, white; a white
Lambertian table (albedo 0.8) at z = 0; an orthographic camera straight down over
the caustic, the glass hidden from the camera, linear EXR, no world):

- ``pebble``: an oblate glass ellipsoid (6 × 5 × 2.4 cm) 4 cm above the table,
  tilted 15°, a point light (radius 5 cm) 60 cm away at 70° elevation;
- ``magnifier``: a biconvex magnifying glass (R 10 cm both sides, 1.2 cm thick,
  7 cm across, f ≈ 10 cm) 9 cm above the table in the sun (angle 1°, 20° from the
  zenith): its focal spot, just before focus;
- ``rod``: a glass rod (r 1 cm, 8 cm long) lying on the table, a point light
  (radius 5 cm) at 40° elevation: a line caustic;
- ``ice_cube``: a 3 cm cube turned 15°, resting on the table, a spot (40°, blend
  0.2, radius 5 cm) at 45° elevation 50 cm away;
- ``wine_glass``: a 15 cm wine glass (a closed solid of revolution, 2.2 mm walls,
  smooth by angle) under a point light (radius 3 cm) at 55°: the stress case.

Objects "lying on" the table rest 0.2 mm above it: a glass face exactly on the
table renders wrongly in Cycles itself (SPEC §9); the truth is traced with the same
gap. Every glass mesh is handed to Blender and its evaluated triangles and corner
normals (what Cycles shades with) read back for the truth: the same geometry.

Truth: `reference.glass_tracer.trace_glass` on the camera's pixel grid (every
Fresnel branch, TIR, up to 16 crossings). Two of them: with the light reflected off
the glass's outside (what Cycles' own path tracing renders) and without (the
transmitted caustic, what lens lights model).

Columns per case:

- **Cycles path tracing** (``--pt-samples``, on the cases of ``--pt``): Blender's own
  caustics (refractive and reflective caustics on, Filter Glossy 0, no clamping
  (Cycles' default Clamp Indirect 10 cuts a caustic's samples: 5.7× too dark here),
  many bounces)
  minus the same render with both caustics off: the light that came through or off
  the glass; compared to the truth with the outer reflection.
- **Cycles / EEVEE Generate**: the extension's Generate (Replace Cycles' Caustics,
  tier AUTO) minus the render without it; while the extension cannot model glass
  meshes (they are left out as 'not a sphere') the report says "not modelled yet"
  with Generate's own words.

Metrics as bench/real_scenes.py (region: truth > 1 % of its peak or the render >
5 % of it): relative L1, flux ratio, peak ratio; times of each render and of
Generate. Writes reports/real_glass.md and reports/real_glass.png.
"""

from __future__ import annotations

import argparse
import math
import shlex
import sys
import tempfile
import time
from dataclasses import dataclass, field
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
    render_irradiance,
)
from real_scenes import ALBEDO, add_light, eevee_id, emitter, load_extension, metrics  # noqa: E402

from reference import ReceiverPlane  # noqa: E402
from reference.glass_meshes import (  # noqa: E402
    biconvex_mesh,
    box_mesh,
    ellipsoid_mesh,
    revolved_mesh,
    rod_mesh,
    wine_glass_profile,
)
from reference.glass_tracer import Glass, Receiver, trace_glass  # noqa: E402
from reference.shapes import Biconvex, Box, Ellipsoid, Rod, TriangleMesh  # noqa: E402

REPORTS = ROOT / "reports"
IOR = 1.5
GAP = 0.0002  # objects "on" the table rest this far above it (SPEC §9)
#: Issue 25's targets: relative L1 and |flux ratio − 1| in every case and engine.
L1_TARGET, FLUX_TARGET = 0.15, 0.10


@dataclass
class Case:
    name: str
    label: str
    mesh: tuple  # (vertices, triangles) in world coordinates
    light: dict  # as bench/real_scenes.py's Case.light
    shading: str = "SMOOTH"  # FLAT, SMOOTH, or an angle in degrees (smooth by angle)
    notes: list = field(default_factory=list)


def _rot(axis, deg):
    a = math.radians(deg)
    k = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(a) * K + (1 - math.cos(a)) * K @ K


def _at(elevation_deg, distance, target, azimuth_deg=180.0):
    """A point ``distance`` from ``target`` at ``elevation`` (azimuth 180°: from −x)."""
    e, a = math.radians(elevation_deg), math.radians(azimuth_deg)
    t = np.asarray(target, float)
    return tuple(
        t + distance * np.array([math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e)])
    )


def _toward(p, target):
    d = np.asarray(target, float) - np.asarray(p, float)
    return tuple(d / np.linalg.norm(d))


def cases():
    out = []
    c = (0.0, 0.0, 0.04)
    e = Ellipsoid(c, (0.03, 0.025, 0.012), _rot((0, 1, 0), 15.0))
    out.append(
        Case(
            "pebble",
            "oblate glass pebble 6×5×2.4 cm, 4 cm up, point light r 5 cm at 70°",
            ellipsoid_mesh(e.center, e.axes, e.rotation, 32, 64)[:2],
            dict(kind="POINT", position=_at(70, 0.6, c), power=200.0, radius=0.05),
        )
    )
    c = (0.0, 0.0, 0.09)
    b = Biconvex(c, (0.0, 0.0, 1.0), 0.10, 0.10, 0.012, diameter=0.07)
    sun = (math.sin(math.radians(20)), 0.0, -math.cos(math.radians(20)))
    out.append(
        Case(
            "magnifier",
            "biconvex magnifier R 10 cm, 7 cm across, 9 cm up, sun (1°) at 20° from the zenith",
            biconvex_mesh(b, 16, 64)[:2],
            dict(kind="SUN", direction=sun, strength=5.0, angle=math.radians(1.0)),
            shading="30",
        )
    )
    c = (0.0, 0.0, 0.01 + GAP)
    r = Rod(c, (1.0, 0.0, 0.0), 0.01, 0.08)
    p = _at(40, 0.5, c, azimuth_deg=-100.0)
    out.append(
        Case(
            "rod",
            "glass rod r 1 cm × 8 cm lying on the table, point light r 5 cm at 40°",
            rod_mesh(r, 64)[:2],
            dict(kind="POINT", position=p, power=200.0, radius=0.05),
            shading="30",
        )
    )
    c = (0.0, 0.0, 0.015 + GAP)
    x = Box(c, (0.03, 0.03, 0.03), _rot((0, 0, 1), 15.0))
    p = _at(45, 0.5, c)
    out.append(
        Case(
            "ice_cube",
            "3 cm ice-clear cube resting on the table, spot 40° (blend 0.2, r 5 cm) at 45°",
            box_mesh(x)[:2],
            dict(
                kind="SPOT",
                position=p,
                direction=_toward(p, c),
                power=300.0,
                spot_size=math.radians(40.0),
                blend=0.2,
                radius=0.05,
            ),
            shading="FLAT",
        )
    )
    v, f, _ = revolved_mesh(wine_glass_profile(), center=(0.0, 0.0, GAP), n_seg=48)
    c = (0.0, 0.0, 0.08)
    out.append(
        Case(
            "wine_glass",
            "wine glass 15 cm (2.2 mm walls) standing on the table, point light r 3 cm at 55°",
            (v, f),
            dict(kind="POINT", position=_at(55, 0.6, c), power=300.0, radius=0.03),
            shading="40",
        )
    )
    return out


# --------------------------------------------------------------------------- Blender


def add_glass(case, name="Glass"):
    """The case's mesh as a glass object (Principled: transmission 1, roughness 0,
    white, IOR 1.5) hidden from the camera, shaded as the case says."""
    import bpy

    v, f = case.mesh
    me = bpy.data.meshes.new(name)
    me.from_pydata([tuple(map(float, p)) for p in v], [], [tuple(map(int, t)) for t in f])
    me.validate()
    mat = new_material(name)
    bsdf = mat.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Transmission Weight"].default_value = 1.0
    bsdf.inputs["IOR"].default_value = IOR
    bsdf.inputs["Roughness"].default_value = 0.0
    bsdf.inputs["Base Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    me.materials.append(mat)
    if case.shading == "FLAT":
        me.shade_flat()
    elif case.shading == "SMOOTH":
        me.shade_smooth()
    else:
        me.shade_smooth()
        me.set_sharp_from_angle(angle=math.radians(float(case.shading)))
    ob = bpy.data.objects.new(name, me)
    bpy.context.scene.collection.objects.link(ob)
    ob.visible_camera = False
    return ob


def blender_geometry(case):
    """The glass as Blender shades it: world-space vertices, triangles and corner
    normals ``(f, 3, 3)`` of the evaluated mesh."""
    import bpy

    new_measuring_scene("CYCLES", 8)
    ob = add_glass(case)
    dg = bpy.context.evaluated_depsgraph_get()
    ev = ob.evaluated_get(dg)
    me = ev.to_mesh()
    me.calc_loop_triangles()
    n_v, n_t = len(me.vertices), len(me.loop_triangles)
    co = np.zeros(3 * n_v)
    me.vertices.foreach_get("co", co)
    tri = np.zeros(3 * n_t, np.int64)
    me.loop_triangles.foreach_get("vertices", tri)
    loops = np.zeros(3 * n_t, np.int64)
    me.loop_triangles.foreach_get("loops", loops)
    cn = np.zeros(3 * len(me.loops))
    me.corner_normals.foreach_get("vector", cn)
    mw = np.array(ob.matrix_world)
    v = co.reshape(-1, 3) @ mw[:3, :3].T + mw[:3, 3]
    normals = cn.reshape(-1, 3)[loops].reshape(-1, 3, 3) @ mw[:3, :3].T  # no scale: a rotation
    ev.to_mesh_clear()
    return v, tri.reshape(-1, 3), normals


def build(case, frame, engine, px, samples):
    cx, cy, view = frame
    sc = new_measuring_scene(engine, px)
    add_diffuse_floor(4.0, ALBEDO)
    add_glass(case)
    add_light(case)
    top = float(np.max(case.mesh[0][:, 2]))
    add_top_camera(cx, cy, top + 0.5, view, clip_end=10.0)
    measured_render_settings(sc, engine, samples)
    if engine == "CYCLES":
        c = sc.cycles
        c.caustics_refractive = False
        c.caustics_reflective = False
        c.max_bounces, c.transmission_bounces, c.glossy_bounces = 24, 16, 16
        c.diffuse_bounces = 1
        c.blur_glossy = 0.0  # "Filter Glossy": no roughening of the glass
        c.sample_clamp_direct = c.sample_clamp_indirect = 0.0  # no clamp (default 10)
    return sc


def render(sc, path):
    """(irradiance on the floor per pixel, W/m², the render's seconds)."""
    return render_irradiance(sc, path, ALBEDO)


def cycles_path_traced(case, frame, px, samples, tmp):
    """Cycles' own caustic: caustics on minus caustics off (same samples, seed)."""
    sc = build(case, frame, "CYCLES", px, samples)
    base, t1 = render(sc, Path(tmp) / "pt_base.exr")
    sc.cycles.caustics_refractive = True
    sc.cycles.caustics_reflective = True
    lit, t2 = render(sc, Path(tmp) / "pt_lit.exr")
    return lit - base, t2


def generated(case, frame, engine, px, samples, tmp):
    """(caustic or None, render seconds, Generate's seconds, its report): the render
    with Generate's output minus the render without; None when Generate made nothing
    for the glass (not modelled yet)."""
    import bpy
    from lens_lights.blender.commands.generate import generate as run

    sc = build(case, frame, engine, px, samples)
    before = {o.name for o in bpy.data.objects}
    sc.lens_lights.energy_model = "AUTO"
    sc.lens_lights.replace_cycles_caustics = True
    t0 = time.perf_counter()
    level, message, _ = run(bpy.context)
    t_gen = time.perf_counter() - t0
    made = [o for o in bpy.data.objects if o.name not in before]
    if level == "ERROR" or not made:
        return None, 0.0, t_gen, message
    img, t2 = render(sc, Path(tmp) / "gen_lit.exr")
    for o in made:  # the same scene without what Generate made
        o.hide_render = True
    base, _ = render(sc, Path(tmp) / "gen_base.exr")
    return img - base, t2, t_gen, message


# --------------------------------------------------------------------------- truth


#: Where `truth` keeps its results (``--truth-cache``; None: nowhere).
TRUTH_CACHE: Path | None = None


def truth(case, geometry, frame, px, n_rays, outer, seed=7):
    """Irradiance of the light through the glass on the pixel grid of ``frame``
    (rows y bottom → top, columns x), W/m²; and the trace (None when read from
    `TRUTH_CACHE`)."""
    key = None
    if TRUTH_CACHE is not None:
        key = TRUTH_CACHE / f"{case.name}_{px}_{n_rays}_{int(outer)}_{seed}_{frame[2]:.6f}.npy"
        if key.exists():
            return np.load(key), None
    E, res = _truth(case, geometry, frame, px, n_rays, outer, seed)
    if key is not None:
        key.parent.mkdir(parents=True, exist_ok=True)
        np.save(key, E)
    return E, res


def _truth(case, geometry, frame, px, n_rays, outer, seed):
    v, f, cn = geometry
    cx, cy, view = frame
    xe = cx + (np.arange(px + 1) / px - 0.5) * view
    ye = cy + (np.arange(px + 1) / px - 0.5) * view
    res = trace_glass(
        emitter(case),
        [Glass(TriangleMesh(v, f, cn), IOR)],
        [Receiver(ReceiverPlane((0.0, 0.0, 0.0), (0.0, 0.0, 1.0)), (xe, ye))],
        n_rays,
        seed=seed,
        outer_reflection=outer,
    )
    return res.receivers[0].irradiance.T.copy(), res


def fit_frame(case, geometry, px):
    """The camera's square fitted to the transmitted caustic: a quick trace over a
    wide square around the glass's shadow, then the square around every cell above
    3 % of its peak, 40 % wider (a lower threshold takes in faint wide wings, light
    reflected around inside the glass, and makes the caustic a few coarse pixels)."""
    v = geometry[0]
    c = v.mean(axis=0)
    size = float(np.max(np.ptp(v, axis=0)))
    L = case.light
    if L["kind"] == "SUN":
        d = np.asarray(L["direction"], float)
    else:
        d = c - np.asarray(L["position"], float)
        d /= np.linalg.norm(d)
    hit = c + (c[2] / -d[2]) * d
    n = 2 * px
    wide = (float(hit[0]), float(hit[1]), 4.0 * size / max(-d[2], 0.3))
    E, _ = truth(case, geometry, wide, n, 150_000, False, seed=3)
    rows, cols = np.nonzero(E > 0.03 * E.max())
    step = wide[2] / n
    x0, x1 = (
        wide[0] - wide[2] / 2 + step * cols.min(),
        wide[0] - wide[2] / 2 + step * (cols.max() + 1),
    )
    y0, y1 = (
        wide[1] - wide[2] / 2 + step * rows.min(),
        wide[1] - wide[2] / 2 + step * (rows.max() + 1),
    )
    return 0.5 * (x0 + x1), 0.5 * (y0 + y1), 1.4 * max(x1 - x0, y1 - y0)


# --------------------------------------------------------------------------- report


COLUMNS = ("truth", "Cycles path tracing", "Cycles Generate", "EEVEE Generate")


def strip(rows, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = len(rows)
    fig, axes = plt.subplots(n, len(COLUMNS), figsize=(2.1 * len(COLUMNS), 2.1 * n), squeeze=False)
    for r, (label, maps) in enumerate(rows):
        vmax = float(maps[0].max())
        for k, (title, m) in enumerate(zip(COLUMNS, maps, strict=True)):
            ax = axes[r, k]
            ax.set_xticks([])
            ax.set_yticks([])
            if r == 0:
                ax.set_title(title, fontsize=8)
            if m is None:
                ax.text(
                    0.5, 0.5, "not run /\nnot modelled yet", ha="center", va="center", fontsize=7
                )
                continue
            ax.imshow(m, origin="lower", cmap="inferno", vmin=0.0, vmax=vmax)
        axes[r, 0].set_ylabel(label, fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def write_report(table, notes, args, total, version):
    cmd = "./lens-lights bench real_glass" + "".join(f" {shlex.quote(a)}" for a in sys.argv[1:])
    pt = f"Cycles path tracing {args.pt_samples} spp" if args.pt else "no Cycles path tracing run"
    lines = [
        "# Real glass: lenses, rods, blocks in Cycles and EEVEE vs the glass tracer (issue 25)",
        "",
        f"`{cmd}` — Blender {version}, {args.px}×{args.px} px, {pt}, "
        f"Generate: Cycles {args.cycles_samples} spp, EEVEE "
        f"{args.eevee_samples} samples; truth {args.rays:.3g} rays per case "
        f"(`reference.glass_tracer`); {total / 60:.1f} min in all on 2 shared cores.",
        "",
        "Truth: the light through the glass (every Fresnel branch, TIR) on the camera's "
        "pixel grid, from Blender's own evaluated triangles and corner normals. 'Cycles path "
        "tracing' is Blender's own caustic (caustics on − off, Filter Glossy 0) against the "
        "truth *with* the light reflected off the glass's outside; 'Generate' rows against the "
        "truth without it (the transmitted caustic). L1: relative L1 over the caustic region "
        "(truth > 1 % of its peak, or the render > 5 % of it); flux: render / truth there; "
        "peak: brightest pixel / the truth's. Targets (issue 25): L1 ≤ 0.15 and flux within "
        "±10 % in Cycles and EEVEE (Generate rows).",
        "",
        "| case | view (mm) | run | L1 | flux | peak | render s | Generate s | target met |",
        "| --- | ---: | --- | ---: | ---: | ---: | ---: | ---: | :---: |",
    ]
    for r in table:
        if r.get("l1") is None:
            lines.append(
                f"| {r['label']} | {1000 * r['view']:.0f} | {r['run']} | — | — | — | — | "
                f"{r.get('gen', 0):.2f} | {r['status']} |"
            )
            continue
        if r["run"].startswith("Cycles path"):
            met = "(sanity)"
        else:
            met = "yes" if r["l1"] <= L1_TARGET and abs(r["flux"] - 1) <= FLUX_TARGET else "no"
        gen = f"{r['gen']:.2f}" if "gen" in r else "—"
        lines.append(
            f"| {r['label']} | {1000 * r['view']:.0f} | {r['run']} | {r['l1']:.3f} | "
            f"{r['flux']:.3f} | {r['peak']:.2f} | {r['seconds']:.1f} | {gen} | {met} |"
        )
    lines += [
        "",
        f"![truth | Cycles path tracing | Cycles Generate | EEVEE Generate]({args.report}.png)",
        "",
    ]
    lines += ["## Notes", ""] + [f"- {n}" for n in notes] + [""]
    (REPORTS / f"{args.report}.md").write_text("\n".join(lines))


def main():
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--only", default="", help="comma-separated cases")
    ap.add_argument("--px", type=int, default=48)
    ap.add_argument("--pt-samples", type=int, default=1024, help="Cycles' own path tracing")
    ap.add_argument("--cycles-samples", type=int, default=128, help="Cycles with Generate")
    ap.add_argument("--eevee-samples", type=int, default=16)
    ap.add_argument("--rays", type=float, default=1e6, help="truth rays per case")
    ap.add_argument(
        "--pt",
        default="pebble,rod,ice_cube",
        help="cases with Cycles' own path tracing ('' none, 'all'); a 1° sun is hopeless for it",
    )
    ap.add_argument("--no-generate", action="store_true", help="skip the extension's runs")
    ap.add_argument("--no-cycles", action="store_true", help="no Cycles Generate run")
    ap.add_argument("--no-eevee", action="store_true")
    ap.add_argument("--report", default="real_glass", help="report name in reports/")
    ap.add_argument("--truth-cache", default="", help="keep and reuse the truths in this folder")
    args = ap.parse_args()
    global TRUTH_CACHE
    TRUTH_CACHE = Path(args.truth_cache) if args.truth_cache else None
    import bpy

    load_extension()
    chosen = [c for c in cases() if not args.only or c.name in args.only.split(",")]
    table, pictures, notes = [], [], []
    t_start = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        for case in chosen:
            t0 = time.perf_counter()
            geometry = blender_geometry(case)
            frame = fit_frame(case, geometry, args.px)
            E, res = truth(case, geometry, frame, args.px, int(args.rays), False)
            t_truth = time.perf_counter() - t0
            base = dict(scene=case.name, label=case.label, view=frame[2])
            traced = (
                f"{res.n_rays} rays, balance {res.balance() / res.tally['into_glass']:.1e}"
                if res is not None
                else "cached"
            )
            print(
                f"{case.name}: {len(geometry[1])} triangles, truth {t_truth:.1f} s "
                f"({traced}), view {1000 * frame[2]:.1f} mm",
                flush=True,
            )
            maps = [E, None, None, None]
            if args.pt == "all" or case.name in args.pt.split(","):
                E_all, _ = truth(case, geometry, frame, args.px, int(args.rays), True, seed=8)
                img, dt = cycles_path_traced(case, frame, args.px, args.pt_samples, tmp)
                m = metrics(img, E_all)
                table.append(
                    dict(base, run=f"Cycles path tracing {args.pt_samples} spp", seconds=dt, **m)
                )
                maps[1] = img
                print(
                    f"  Cycles path tracing  L1 {m['l1']:.3f} flux {m['flux']:.3f} peak {m['peak']:.2f} ({dt:.1f} s)",
                    flush=True,
                )
            if not args.no_generate:
                runs = (
                    []
                    if args.no_cycles
                    else [("CYCLES", "Cycles Generate", args.cycles_samples, 2)]
                )
                if not args.no_eevee:
                    runs.append((eevee_id(), "EEVEE Generate", args.eevee_samples, 3))
                for engine, label, samples, col in runs:
                    img, dt, t_gen, message = generated(case, frame, engine, args.px, samples, tmp)
                    if img is None:
                        table.append(
                            dict(base, run=label, gen=t_gen, status="not modelled yet", l1=None)
                        )
                        notes.append(
                            f"{case.name}, {label}: not modelled yet — Generate said: {message.strip()!r}"
                        )
                        print(f"  {label}: not modelled yet ({message.strip()[:120]})", flush=True)
                        continue
                    m = metrics(img, E)
                    table.append(dict(base, run=label, seconds=dt, gen=t_gen, **m))
                    maps[col] = img
                    print(
                        f"  {label}  L1 {m['l1']:.3f} flux {m['flux']:.3f} peak {m['peak']:.2f} "
                        f"(render {dt:.1f} s, Generate {t_gen:.2f} s)",
                        flush=True,
                    )
            pictures.append((case.name, maps))
    total = time.perf_counter() - t_start
    notes.append(
        "Cycles' path tracing also carries light that bounces table → glass → table (the "
        "table's own light through the glass), which the truth leaves out: a small excess."
    )
    REPORTS.mkdir(exist_ok=True)
    strip(pictures, REPORTS / f"{args.report}.png")
    write_report(table, notes, args, total, bpy.app.version_string)
    print(f"wrote {REPORTS / (args.report + '.md')}", flush=True)


if __name__ == "__main__":
    main()
