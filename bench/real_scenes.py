"""Real scenes (issue 12): lens lights of every light type, rendered in Cycles and
EEVEE (tier AUTO), against the reference tracer (`reference`).

    ./lens-lights bench real_scenes [--quick] [--only NAME,...]

Scenes: a 2 cm glass marble resting on a table under a point light 1 m away, from
above and at 60° elevation (and a sweep 90°…20° unless --quick), a point light of
radius 0.1 m, a sun overhead and at 70°, a spot and a disk area light over it, and the floating ball
of `bench/render_compare.py` (R 5 cm, 10 cm over the table, the light 25 cm above
its centre). Each is the measuring scene of `scripts/measuring_scene.py` (white
Lambertian table, orthographic top camera over the lens's shadow, linear EXR, no
world), with the ball visible to every ray but the camera (as an artist's would be).

**What is measured.** The caustic is the render with lens lights minus the render
of the same scene without them (same samples and seed), Cycles' refractive
caustics off in both (Generate's "Replace Cycles' Caustics" turns them off; the
baseline sets the same); a pixel is ``albedo · E / π``, so ``E = π · pixel /
albedo``. The truth is the tracer's irradiance of the light through the lens on
the same pixel grid (Fresnel at both surfaces), the camera's square fitted to the
caustic (every cell above 0.5 % of a quick trace's peak, 30 % wider). Per scene:
the relative L1 over the caustic region (reference above 1 % of its peak, or the render above 5 % of
it), the flux ratio over that region, the peak ratio (brightest pixel).

"Cycles, default paths" rows: the same scene generated with Replace Cycles'
Caustics off, so Cycles' own path-traced caustic (refractive caustics on, Filter
Glossy 1) is rendered besides the lens lights' — the double light SPEC §9 warns of.

Writes reports/real_scenes.md and reports/real_scenes.png (rows: scenes; columns:
truth | Cycles | EEVEE, one colour scale per row).
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "scripts"))

from measuring_scene import (  # noqa: E402
    build_measuring_scene,
    measured_render_settings,
    render_irradiance,
)

import reference as ref  # noqa: E402

REPORTS = ROOT / "reports"
IOR = 1.5
ALBEDO = 0.8
MARBLE = 0.01  # 2 cm marble (radius, m)
#: Issue 24's targets: relative L1 and |flux ratio − 1| in every real scene.
L1_TARGET, FLUX_TARGET = 0.10, 0.05


@dataclass
class Case:
    name: str
    label: str
    radius: float  # ball radius; its centre at height `height`
    height: float
    light: dict  # kind, and the light's numbers
    variants: tuple = ()  # extra Cycles runs: "default_paths"
    notes: list = field(default_factory=list)
    ior: float = IOR


def point_at(elevation_deg, distance, center):
    e = math.radians(elevation_deg)
    return (center[0] - distance * math.cos(e), center[1], center[2] + distance * math.sin(e))


def sun_toward(elevation_deg):
    """A sun's direction of travel at `elevation_deg`, coming from −x (as `point_at`)."""
    e = math.radians(elevation_deg)
    return (math.cos(e), 0.0, -math.sin(e))


def cases(quick):
    c = (0.0, 0.0, MARBLE)
    out = [
        Case(
            "rest_90",
            "marble resting, point light 1 m above",
            MARBLE,
            MARBLE,
            dict(kind="POINT", position=point_at(90, 1.0, c), power=100.0),
        ),
        Case(
            "rest_60",
            "marble resting, point light at 60°",
            MARBLE,
            MARBLE,
            dict(kind="POINT", position=point_at(60, 1.0, c), power=100.0),
        ),
        Case(
            "rest_r01",
            "marble resting, point light r = 0.1 m above",
            MARBLE,
            MARBLE,
            dict(kind="POINT", position=point_at(90, 1.0, c), power=100.0, radius=0.1),
            variants=("default_paths",),
        ),
        Case(
            "sun",
            "marble resting, sun (0.5°) overhead",
            MARBLE,
            MARBLE,
            dict(kind="SUN", direction=(0.0, 0.0, -1.0), strength=10.0, angle=math.radians(0.5)),
        ),
        Case(
            "sun_70",
            "marble resting, sun (0.5°) at 70°",
            MARBLE,
            MARBLE,
            dict(kind="SUN", direction=sun_toward(70), strength=10.0, angle=math.radians(0.5)),
        ),
        Case(
            "spot",
            "marble resting, spot 30° 1 m above",
            MARBLE,
            MARBLE,
            dict(
                kind="SPOT",
                position=point_at(90, 1.0, c),
                direction=(0.0, 0.0, -1.0),
                power=100.0,
                spot_size=math.radians(30.0),
                blend=0.15,
            ),
        ),
        Case(
            "area",
            "marble resting, disk area light Ø 0.2 m, 1 m above",
            MARBLE,
            MARBLE,
            dict(
                kind="AREA",
                position=point_at(90, 1.0, c),
                direction=(0.0, 0.0, -1.0),
                power=100.0,
                size=0.2,
                shape="DISK",
            ),
        ),
        Case(
            "floating",
            "floating ball (render_compare): R 5 cm, 10 cm over the table",
            0.05,
            0.15,
            dict(kind="POINT", position=(0.0, 0.0, 0.40), power=10.0),
        ),
    ]
    if not quick:
        out[2:2] = [
            Case(
                f"rest_{e}",
                f"marble resting, point light at {e}°",
                MARBLE,
                MARBLE,
                dict(kind="POINT", position=point_at(e, 1.0, c), power=100.0),
            )
            for e in (45, 30, 20)
        ]
    return out


def issue14_cases():
    """Issue 14's own table: a ball (R 5 cm, 10 cm over the table) with a point light
    at D = 9 R overhead, the same at 45°, and at D = 4 R with n = 1.7 (the resting
    marble under an oblique light is `rest_60`/`rest_45` of `cases`)."""
    c = (0.0, 0.0, 0.15)
    return [
        Case(
            "float_9",
            "floating ball, point light D = 9 R overhead",
            0.05,
            0.15,
            dict(kind="POINT", position=point_at(90, 0.45, c), power=10.0),
        ),
        Case(
            "float_9_45",
            "floating ball, point light D = 9 R at 45°",
            0.05,
            0.15,
            dict(kind="POINT", position=point_at(45, 0.45, c), power=10.0),
        ),
        Case(
            "float_4_n17",
            "floating ball n = 1.7, point light D = 4 R overhead",
            0.05,
            0.15,
            dict(kind="POINT", position=point_at(90, 0.20, c), power=10.0),
            ior=1.7,
        ),
    ]


# --------------------------------------------------------------------------- geometry


def footprint(case):
    """(centre x, y, view width) of the camera: the lens's shadow on the table,
    from the ray through the lens centre and the shadow's size."""
    C = np.array([0.0, 0.0, case.height])
    L = case.light
    if L["kind"] == "SUN":
        u = np.asarray(L["direction"], float)
        k = 1.0
    else:
        P = np.asarray(L["position"], float)
        u = (C - P) / np.linalg.norm(C - P)
        k = P[2] / (P[2] - C[2])  # shadow magnification
    t = C[2] / -u[2]
    hit = C + t * u
    sin_e = -u[2]
    view = 2.0 * 1.6 * case.radius * k / sin_e
    return hit[0], hit[1], view


def emitter(case):
    L = case.light
    if L["kind"] == "POINT":
        return ref.PointLight(L["position"], L["power"], L.get("radius", 0.0))
    if L["kind"] == "SPOT":
        return ref.SpotLight(
            L["position"],
            L["direction"],
            L["power"],
            L["spot_size"],
            L["blend"],
            L.get("radius", 0.0),
        )
    if L["kind"] == "SUN":
        return ref.SunLight(L["direction"], L["strength"], L["angle"])
    return ref.AreaLight(L["position"], L["direction"], L["power"], L["size"], shape=L["shape"])


def trace(case, frame, px, n_rays, seed=7):
    """Reference irradiance (rows y bottom → top, columns x) on the grid of `frame`
    (centre x, y, width)."""
    cx, cy, view = frame
    xe = cx + (np.arange(px + 1) / px - 0.5) * view
    ye = cy + (np.arange(px + 1) / px - 0.5) * view
    res = ref.trace_irradiance(
        emitter(case),
        ref.GlassSphere((0.0, 0.0, case.height), case.radius, case.ior),
        ref.ReceiverPlane((0.0, 0.0, 0.0), (0.0, 0.0, 1.0)),
        n_rays,
        seed=seed,
        grid=(xe, ye),
    )
    return res.irradiance.T.copy()


def fit_frame(case, px):
    """The camera's frame fitted to the caustic: a quick trace over twice the
    shadow's `footprint`, then the square around every cell above 0.5 % of its
    peak, 30 % wider (small pixels where the caustic is)."""
    cx, cy, view = footprint(case)
    wide = (cx, cy, 2.0 * view)
    E = trace(case, wide, px, 400_000, seed=3)
    rows, cols = np.nonzero(E > 0.005 * E.max())
    step = wide[2] / px
    x0, x1 = cx - wide[2] / 2 + step * cols.min(), cx - wide[2] / 2 + step * (cols.max() + 1)
    y0, y1 = cy - wide[2] / 2 + step * rows.min(), cy - wide[2] / 2 + step * (rows.max() + 1)
    return 0.5 * (x0 + x1), 0.5 * (y0 + y1), 1.3 * max(x1 - x0, y1 - y0)


# --------------------------------------------------------------------------- Blender


def load_extension():
    from dev_extension import PACKAGE
    from dev_extension import load_extension as load

    registered = PACKAGE in sys.modules
    module = load()
    if not registered:
        module.register()
    return module


def eevee_id():
    import bpy

    return "BLENDER_EEVEE" if bpy.app.version >= (5, 0, 0) else "BLENDER_EEVEE_NEXT"


def add_light(case):
    import bpy
    from mathutils import Vector

    L = case.light
    data = bpy.data.lights.new("Light", L["kind"])
    ob = bpy.data.objects.new("Light", data)
    bpy.context.scene.collection.objects.link(ob)
    if L["kind"] == "SUN":
        data.energy, data.angle = L["strength"], L["angle"]
    else:
        data.energy = L["power"]
        ob.location = L["position"]
    if L["kind"] in ("POINT", "SPOT"):
        data.shadow_soft_size = L.get("radius", 0.0)
    if L["kind"] == "SPOT":
        data.spot_size, data.spot_blend = L["spot_size"], L["blend"]
    if L["kind"] == "AREA":
        data.shape, data.size = L["shape"], L["size"]
    if "direction" in L:
        ob.rotation_mode = "QUATERNION"
        ob.rotation_quaternion = Vector(L["direction"]).to_track_quat("-Z", "Y")
    return ob


def build(case, frame, engine, px, samples):
    cx, cy, view = frame
    built = build_measuring_scene(
        engine,
        resolution=px,
        floor_size=4.0,
        albedo=ALBEDO,
        view=view,
        camera_xy=(cx, cy),
        camera_height=case.height + 2.0 * case.radius + 0.5,
        clip_end=10.0,
        ball=dict(
            radius=case.radius,
            location=(0.0, 0.0, case.height),
            ior=case.ior,
            segments=64,
            rings=32,
        ),
    )
    sc = built.scene
    add_light(case)
    measured_render_settings(sc, engine, samples)
    if engine == "CYCLES":
        c = sc.cycles
        c.caustics_refractive = False  # the baseline: no caustic at all
    return sc


def render(sc, path):
    """(irradiance on the floor per pixel, W/m², the render's seconds)."""
    return render_irradiance(sc, path, ALBEDO)


def generate(replace=True):
    import bpy
    from lens_lights.blender.commands.generate import generate as run

    sc = bpy.context.scene
    sc.lens_lights.energy_model = "AUTO"
    sc.lens_lights.replace_cycles_caustics = replace
    level, message, figures = run(bpy.context)
    if level == "ERROR":
        raise RuntimeError(message)
    return message, figures


def caustic(case, frame, engine, px, samples, tmp, replace=True):
    """(caustic irradiance, seconds of rendering, the generate report)."""
    sc = build(case, frame, engine, px, samples)
    base, t1 = render(sc, Path(tmp) / "base.exr")
    if not replace:
        sc.cycles.caustics_refractive = True  # Blender's default light paths
    message, _ = generate(replace)
    img, t2 = render(sc, Path(tmp) / "lit.exr")
    return img - base, t1 + t2, message


# --------------------------------------------------------------------------- metrics


def metrics(img, truth_map):
    peak = float(truth_map.max())
    region = (truth_map > 0.01 * peak) | (img > 0.05 * peak)
    ref_sum = float(truth_map[region].sum())
    return dict(
        l1=float(np.abs(img - truth_map)[region].sum()) / ref_sum,
        flux=float(img[region].sum()) / ref_sum,
        peak=float(img.max()) / peak,
    )


# --------------------------------------------------------------------------- report


def strip(rows, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = len(rows)
    fig, axes = plt.subplots(n, 3, figsize=(6.0, 2.0 * n), squeeze=False)
    for r, (label, maps) in enumerate(rows):
        vmax = float(maps[0].max())
        for k, (title, m) in enumerate(zip(("truth", "Cycles", "EEVEE"), maps, strict=True)):
            ax = axes[r, k]
            ax.set_xticks([])
            ax.set_yticks([])
            if m is None:
                continue
            ax.imshow(m, origin="lower", cmap="inferno", vmin=0.0, vmax=vmax)
            if r == 0:
                ax.set_title(title, fontsize=9)
        axes[r, 0].set_ylabel(label, fontsize=6)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="no elevation sweep")
    ap.add_argument("--only", default="", help="comma-separated scene names")
    ap.add_argument("--px", type=int, default=48)
    ap.add_argument("--cycles-samples", type=int, default=128)
    ap.add_argument("--eevee-samples", type=int, default=16)
    ap.add_argument("--rays", type=float, default=2e6)
    ap.add_argument("--no-eevee", action="store_true")
    ap.add_argument("--no-cycles", action="store_true")
    ap.add_argument("--issue14", action="store_true", help="issue 14's floating-ball table")
    ap.add_argument("--report", default="real_scenes", help="report name in reports/")
    args = ap.parse_args()
    import bpy

    load_extension()
    pool = issue14_cases() if args.issue14 else cases(args.quick)
    chosen = [c for c in pool if not args.only or c.name in args.only.split(",")]
    table, pictures = [], []
    t_start = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        for case in chosen:
            t0 = time.perf_counter()
            frame = fit_frame(case, args.px)
            E = trace(case, frame, args.px, int(args.rays))
            print(
                f"{case.name}: truth {time.perf_counter() - t0:.1f} s, view "
                f"{1000 * frame[2]:.1f} mm",
                flush=True,
            )
            maps = [E, None, None]
            runs = [] if args.no_cycles else [("CYCLES", "Cycles AUTO", True)]
            runs += (
                []
                if args.no_cycles
                else [
                    ("CYCLES", "Cycles AUTO, default paths", False)
                    for v in case.variants
                    if v == "default_paths"
                ]
            )
            if not args.no_eevee:
                runs.append((eevee_id(), "EEVEE AUTO", True))
            for engine, label, replace in runs:
                samples = args.cycles_samples if engine == "CYCLES" else args.eevee_samples
                img, dt, message = caustic(case, frame, engine, args.px, samples, tmp, replace)
                m = metrics(img, E)
                tiers = {
                    o.lens_lights.energy_model
                    for o in bpy.data.objects
                    if o.type == "LIGHT" and o.lens_lights.is_lens_light
                }
                # Caustic layers are meshes, not lights (their data carry the mark).
                if any(m.get("lens_lights_created") == "layer" for m in bpy.data.meshes):
                    tiers.add("CAUSTIC_LAYER")
                tier = ", ".join(sorted(tiers))
                table.append(
                    dict(
                        scene=case.name,
                        label=case.label,
                        run=label,
                        tier=tier,
                        seconds=dt,
                        view=frame[2],
                        **m,
                    )
                )
                print(
                    f"  {label:28s} {tier:14s} L1 {m['l1']:.3f}  flux {m['flux']:.3f}  "
                    f"peak {m['peak']:.3f}  ({dt:.1f} s)",
                    flush=True,
                )
                if replace:
                    maps[1 if engine == "CYCLES" else 2] = img
            pictures.append((case.name, maps))
    total = time.perf_counter() - t_start
    REPORTS.mkdir(exist_ok=True)
    strip(pictures, REPORTS / f"{args.report}.png")
    write_report(table, args, total, bpy.app.version_string)


def write_report(table, args, total, version):
    lines = [
        "# Real scenes: every light type, Cycles and EEVEE (AUTO) vs the reference tracer",
        "",
        f"`./lens-lights bench real_scenes{' --quick' if args.quick else ''}"
        f"{' --issue14' if args.issue14 else ''}"
        f"{' --report ' + args.report if args.report != 'real_scenes' else ''}` — Blender "
        f"{version}, {args.px}×{args.px} px, Cycles {args.cycles_samples} spp (CPU), EEVEE "
        f"{args.eevee_samples} samples (software GL), reference {args.rays:.3g} rays per "
        f"scene; {total / 60:.1f} min in all on 2 shared cores.",
        "",
        "Caustic = render with lens lights − the same render without them (Cycles' "
        "refractive caustics off in both: Replace Cycles' Caustics); truth = "
        "`reference.trace_irradiance` on the same pixel grid, the camera's square "
        "fitted to the caustic (view). L1: relative L1 over "
        "the caustic region (truth > 1 % of its peak, or the render > 5 % of it); flux: "
        "render / truth over that region; peak: brightest pixel / the truth's. Targets "
        "(issue 24): L1 ≤ 0.10 and flux within ±5 % in Cycles and in EEVEE.",
        "",
        "| scene | view (mm) | run | tier | L1 | flux | peak | target met |",
        "| --- | ---: | --- | --- | ---: | ---: | ---: | :---: |",
    ]
    for r in table:
        if "default paths" in r["run"]:
            met = "(double light)"
        else:
            met = "yes" if r["l1"] <= L1_TARGET and abs(r["flux"] - 1) <= FLUX_TARGET else "no"
        lines.append(
            f"| {r['label']} | {1000 * r['view']:.0f} | {r['run']} | {r['tier']} | "
            f"{r['l1']:.3f} | {r['flux']:.3f} | {r['peak']:.2f} | {met} |"
        )
    lines += ["", f"![truth | Cycles | EEVEE per scene]({args.report}.png)", ""]
    (REPORTS / f"{args.report}.md").write_text("\n".join(lines))


if __name__ == "__main__":
    main()
