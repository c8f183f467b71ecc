"""The EEVEE caustic layer in a mirror and in a close-up (issue 28 item 6), before and
after → reports/layer_mirror.md and reports/layer_mirror.png.

The scene: a glass marble (R = 0.5, n = 1.5) resting on a white table (albedo 0.8), a
point light (1000 W, radius 0.1) at 45°, EEVEE (Raytracing on, Screen-Trace), 4 TAA
samples, no world.

1. **Mirror.** A vertical mirror (metallic 1, roughness 0, white) beside the marble
   with a Light Probe Plane on it; camera C1 frames the mirror so that it sees the
   caustic only in the mirror. Generate from C1, render C1 with and without the lens
   lights: the caustic's excess radiance in the mirror. Its reference: camera C2, C1
   reflected in the mirror's plane (the mirror hidden), which sees the same table
   directly, mirrored: Generate from C2, render C2, flip. Figures: the excess summed
   over the frame (C1 / C2) and the mean |C1 − flipped C2| over the caustic. EEVEE's
   Clamping > Surface Indirect is 0 (off); C1 is rendered again with its default, 10,
   which clips the caustic's radiance in the mirror.
2. **Close-up.** A camera 1.7 m from the caustic. Generate from a far camera, then
   from the close one; each rendered from the close one. The dashes: pixels of the lit
   table (without lens lights > 0.3, 3 px from the shadow's edge) brighter by more
   than 0.02, and the largest excess there; the ray count of each Generate.

"Before" runs the same script on another checkout's code (``--before REV``: a `git
archive` of it, main by default), in a subprocess; "after" on this one.

    ./lens-lights bench layer_mirror [--before main] [--px 96]
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
ALBEDO = 0.8
MIRROR_Y = 1.2  # the mirror's plane (facing −y)


def _setup(code: Path):
    sys.path.insert(0, str(code / "scripts"))
    sys.path.insert(0, str(code))
    from dev_extension import load_extension

    load_extension().register()


def _camera(name, loc, target, fov_deg):
    import bpy
    from mathutils import Matrix, Vector

    cam = bpy.data.objects.new(name, bpy.data.cameras.new(name))
    bpy.context.scene.collection.objects.link(cam)
    d = Vector(target) - Vector(loc)
    rot = d.to_track_quat("-Z", "Y").to_matrix().to_4x4()
    cam.matrix_world = Matrix.Translation(Vector(loc)) @ rot
    cam.data.angle = math.radians(fov_deg)
    cam.data.sensor_fit = "HORIZONTAL"
    return cam


def _scene(px):
    from measuring_scene import (
        add_diffuse_floor,
        add_glass_ball,
        add_point_light,
        new_measuring_scene,
    )

    sc = new_measuring_scene("BLENDER_EEVEE", px)
    add_diffuse_floor(20.0, ALBEDO, "Table")
    add_glass_ball(0.5, (0.0, 0.0, 0.5), 1.5, 64, 32, "Marble", hide_from_indirect=True)
    add_point_light((-3.0, 0.0, 3.5), 1000.0, 0.1)
    e = sc.eevee
    e.taa_render_samples = 4
    if hasattr(e, "use_raytracing"):
        e.use_raytracing = True
    if hasattr(e, "clamp_surface_indirect"):
        e.clamp_surface_indirect = 0.0  # (its default 10 clips the caustic in a mirror)
    sc.render.filter_size = 1.0
    return sc


def _add_mirror():
    import bpy
    from measuring_scene import new_material

    m = new_material("Mirror")
    b = m.node_tree.nodes["Principled BSDF"]
    b.inputs["Metallic"].default_value = 1.0
    b.inputs["Roughness"].default_value = 0.0
    b.inputs["Base Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    bpy.ops.mesh.primitive_plane_add(size=1.0)
    mirror = bpy.context.object
    mirror.name = "Mirror"
    mirror.scale = (6.0, 2.5, 1.0)
    mirror.rotation_euler = (math.radians(90), 0.0, 0.0)  # faces −y
    mirror.location = (0.5, MIRROR_Y, 1.25)
    mirror.data.materials.append(m)
    kind = "PLANE" if bpy.app.version >= (4, 1, 0) else "PLANAR"
    bpy.ops.object.lightprobe_add(type=kind, location=(0.5, MIRROR_Y - 0.001, 1.25))
    probe = bpy.context.object
    probe.rotation_euler = (math.radians(90), 0.0, 0.0)
    probe.scale = (3.0, 1.25, 1.0)
    return mirror, probe


def _render(sc, path):
    import bpy
    import numpy as np

    sc.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)
    img = bpy.data.images.load(str(path))
    pix = np.array(img.pixels[:], dtype=float).reshape(img.size[1], img.size[0], 4)
    bpy.data.images.remove(img)
    return pix[..., :3].mean(axis=2)


def _generate():
    import bpy
    from lens_lights.blender.commands.generate import generate

    sc = bpy.context.scene
    sc.lens_lights.energy_model = "AUTO"
    level, message, figures = generate(bpy.context)
    layer = figures.get("layer") or {}
    return message, int(layer.get("rays", 0)) if isinstance(layer, dict) else 0


def _clear():
    import bpy
    from lens_lights.blender.build import cleanup, cycles_caustics

    cleanup.clear(bpy.context.scene)
    cycles_caustics.restore(bpy.context.scene)


def measure(code: Path, out: Path, px: int):
    """Both scenes with the code of `code`: images (npz) and figures (json) in `out`."""
    import numpy as np

    _setup(code)
    import bpy

    res, figs = {}, {}
    # 1. the mirror
    sc = _scene((px, px * 2 // 3))
    mirror, probe = _add_mirror()
    c1_loc, target = (-1.0, -5.0, 1.6), (0.5, MIRROR_Y, 0.55)
    c1 = _camera("C1", c1_loc, target, 14.0)
    c2_loc = (c1_loc[0], 2 * MIRROR_Y - c1_loc[1], c1_loc[2])  # C1 reflected
    c2 = _camera("C2", c2_loc, target, 14.0)
    sc.camera = c1
    res["c1_without"] = _render(sc, out / "c1_without.exr")
    figs["c1_report"], figs["c1_rays"] = _generate()
    res["c1_with"] = _render(sc, out / "c1_with.exr")
    if hasattr(sc.eevee, "clamp_surface_indirect"):  # EEVEE's default clamp
        sc.eevee.clamp_surface_indirect = 10.0
        res["c1_with_clamp10"] = _render(sc, out / "c1_with_clamp10.exr")
        sc.eevee.clamp_surface_indirect = 0.0
    _clear()
    mirror.hide_render = True
    probe.hide_render = True
    sc.camera = c2
    res["c2_without"] = _render(sc, out / "c2_without.exr")
    figs["c2_report"], figs["c2_rays"] = _generate()
    res["c2_with"] = _render(sc, out / "c2_with.exr")
    _clear()
    # 2. the close-up
    sc = _scene((px * 4 // 3, px))
    far = _camera("Far", (-1.0, -5.0, 3.0), (0.5, 0.0, 0.0), 40.0)
    close = _camera("Close", (1.4, -1.3, 1.1), (0.8, 0.0, 0.0), 50.0)
    sc.camera = close
    res["close_without"] = _render(sc, out / "close_without.exr")
    for name, cam in (("far", far), ("close", close)):
        sc.camera = cam
        figs[f"{name}_report"], figs[f"{name}_rays"] = _generate()
        sc.camera = close
        res[f"close_from_{name}"] = _render(sc, out / f"close_from_{name}.exr")
        _clear()
    np.savez(out / "images.npz", **res)
    (out / "figures.json").write_text(json.dumps(figs, indent=1))
    bpy.ops.wm.read_factory_settings(use_empty=True)


def _lit_mask(base, margin=3):
    """The lit table: radiance > 0.3, at least `margin` pixels from anything darker."""
    import numpy as np

    lit = base > 0.3
    out = lit.copy()
    for dy in range(-margin, margin + 1):
        for dx in range(-margin, margin + 1):
            out &= np.roll(np.roll(lit, dy, 0), dx, 1)
    out[:margin], out[-margin:], out[:, :margin], out[:, -margin:] = False, False, False, False
    return out


def figures_of(d, figs):
    import numpy as np

    m1 = d["c1_with"] - d["c1_without"]
    ref = (d["c2_with"] - d["c2_without"])[:, ::-1]  # C2 sees the mirror image of C1's
    region = ref > 0.05 * max(ref.max(), 1e-9)
    out = {
        "mirror_sum": float(m1.sum()),
        "direct_sum": float(ref.sum()),
        "mirror_ratio": float(m1.sum() / max(ref.sum(), 1e-12)),
        "mirror_ratio_clamp10": float(
            (d.get("c1_with_clamp10", d["c1_with"]) - d["c1_without"]).sum() / max(ref.sum(), 1e-12)
        ),
        "mirror_l1": float(np.abs(m1 - ref)[region].mean() / max(ref[region].mean(), 1e-12)),
        "c1_rays": figs["c1_rays"],
    }
    base = d["close_without"]
    lit = _lit_mask(base)
    for name in ("far", "close"):
        ex = d[f"close_from_{name}"] - base
        out[f"{name}_dashes"] = int((lit & (ex > 0.02)).sum())
        out[f"{name}_max"] = float(ex[lit].max())
        out[f"{name}_rays"] = figs[f"{name}_rays"]
    out["lit_px"] = int(lit.sum())
    out["lit_median"] = float(np.median(base[lit]))
    return out


def report(runs: dict, path_md: Path, path_png: Path, command: str):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    names = list(runs)
    fig, axes = plt.subplots(len(names), 5, figsize=(19, 3.3 * len(names)))
    rows = []
    for r, name in enumerate(names):
        d, f = runs[name]
        g = figures_of(d, f)
        rows.append((name, g))
        panels = [
            (d["c1_with"], "C1 (mirror) with lens lights", "gray", 1.2),
            (d["c1_with"] - d["c1_without"], "C1 excess (caustic in the mirror)", "magma", 0.5),
            (
                (d["c2_with"] - d["c2_without"])[:, ::-1],
                "C2 excess, flipped (direct view)",
                "magma",
                0.5,
            ),
            (d["close_from_close"], "close-up, generated from it", "gray", 1.5),
            (
                np.where(
                    _lit_mask(d["close_without"]), d["close_from_close"] - d["close_without"], 0
                ),
                "close-up excess on the lit table",
                "magma",
                0.1,
            ),
        ]
        for ax, (img, title, cmap, vmax) in zip(axes[r], panels, strict=True):
            shown = np.clip(img, 0, vmax) ** (1 / 2.2) if cmap == "gray" else img
            ax.imshow(
                shown,
                origin="lower",
                cmap=cmap,
                vmin=0,
                vmax=vmax ** (1 / 2.2) if cmap == "gray" else vmax,
            )
            ax.set_title(f"{name}: {title}", fontsize=9)
            ax.set_xticks([])
            ax.set_yticks([])
    plt.tight_layout()
    fig.savefig(path_png, dpi=80)
    lines = [
        "# The EEVEE caustic layer in a mirror and in a close-up (issue 28 item 6)",
        "",
        f"`{command}` (bench/layer_mirror.py; the scene is in its docstring).",
        "",
        "| code | mirror: excess C1 / C2 (clamp 10) | mirror: mean abs(C1 − C2) / mean C2 "
        "over the caustic | C1's rays | close-up from far: dashes, max excess, rays | from "
        "close: dashes, max excess, rays |",
        "|---|---|---|---|---|---|",
    ]
    for name, g in rows:
        lines.append(
            f"| {name} | {g['mirror_ratio']:.3f} ({g['mirror_ratio_clamp10']:.3f}) "
            f"| {g['mirror_l1']:.3f} | {g['c1_rays']} "
            f"| {g['far_dashes']} px, +{g['far_max']:.3f}, {g['far_rays']} "
            f"| {g['close_dashes']} px, +{g['close_max']:.3f}, {g['close_rays']} |"
        )
    g = rows[-1][1]
    lines += [
        "",
        f"Dashes: pixels of the lit table ({g['lit_px']} px, median radiance "
        f"{g['lit_median']:.2f}, 3 px from the shadow's edge) brighter by more than 0.02 "
        "with the lens lights. Excess: radiance with − without lens lights.",
        "",
        "![before and after](layer_mirror.png)",
        "",
    ]
    for name in names:
        f = runs[name][1]
        lines += [f"- {name}, Generate from C1: {f['c1_report']}"]
    path_md.write_text("\n".join(lines) + "\n")
    return rows


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--before", default="main", help="git revision of the 'before' code")
    ap.add_argument("--px", type=int, default=96)
    ap.add_argument("--measure", help=argparse.SUPPRESS)  # (subprocess) code dir
    ap.add_argument("--out", help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.measure:
        measure(Path(a.measure), Path(a.out), a.px)
        return
    import numpy as np

    runs = {}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        before = tmp / "before_code"
        before.mkdir()
        tar = subprocess.run(
            ["git", "-C", str(ROOT), "archive", a.before], check=True, capture_output=True
        ).stdout
        subprocess.run(["tar", "-x", "-C", str(before)], input=tar, check=True)
        for name, code in ((f"before ({a.before})", before), ("after", ROOT)):
            out = tmp / name.split()[0]
            out.mkdir()
            t = time.perf_counter()
            subprocess.run(
                [
                    sys.executable,
                    __file__,
                    "--measure",
                    str(code),
                    "--out",
                    str(out),
                    "--px",
                    str(a.px),
                ],
                check=True,
            )
            print(f"{name}: {time.perf_counter() - t:.0f} s")
            d = dict(np.load(out / "images.npz"))
            runs[name] = (d, json.loads((out / "figures.json").read_text()))
    command = (
        "./lens-lights bench layer_mirror"
        + (f" --before {a.before}" if a.before != "main" else "")
        + (f" --px {a.px}" if a.px != 96 else "")
    )
    rows = report(
        runs, ROOT / "reports/layer_mirror.md", ROOT / "reports/layer_mirror.png", command
    )
    for name, g in rows:
        print(name, json.dumps(g))


if __name__ == "__main__":
    main()
