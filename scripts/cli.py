"""`./lens-lights SUBCOMMAND …`: the project's command line (run by the launcher
with the pinned environment's python).

Subcommands:
  phase1 SCENE.bi [--json] [--model TIER]
                             secondary light sources of a `.bi` scene and the
                             Blender light of each for a lens-light tier
                             (thesis|physical|fitted|exact_profile; default
                             fitted: the most accurate tier that renders in both
                             EEVEE and Cycles)
  test [PYTEST ARGS]         the whole test suite on Blender 5.2, then the Blender
                             tests on 4.2 (`--blender X.Y`: on that release only;
                             paths: those tests only)
  render SCENE -o OUT.png    render a .blend or .bi scene with lens lights
                             [--engine cycles|eevee] [--samples N] [--resolution WxH]
                             [--no-lens-lights | --compare]; OUT's extension picks
                             the format (.png .jpg/.jpeg .exr .tif/.tiff .webp)
  demo [--out DIR]           render the showcase scene without and with lens lights
  build [ARGS]               build the extension's zip (scripts/build_extension.py)
  bench NAME [ARGS]          a benchmark of bench/ (e.g. `bench scale`), report in reports/
  fuzz [--count N] [--seed S]
                             fuzz the .bi reader and `phase1` (100 000 inputs by default)
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

EXIT_BAD_INPUT = 2


def _fail(message: str) -> int:
    print(f"lens-lights: {message}", file=sys.stderr)
    return EXIT_BAD_INPUT


# --------------------------------------------------------------------------- phase1

def _fmt_vec(v) -> str:
    return "(" + ", ".join(f"{x:.4g}" for x in v) + ")"


#: `--model` values (lower case) → tiers of `addon.tiers`.
PHASE1_MODELS = ("thesis", "physical", "fitted", "exact_profile")
#: The default: the most accurate tier that renders in both EEVEE and Cycles
#: (reports/accuracy.md); EXACT_PROFILE is more accurate but Cycles only.
PHASE1_DEFAULT_MODEL = "fitted"


def blender_lights(scene, result, model: str) -> list:
    """The Blender light (`tiers.BlenderLight`) of each source of `result`
    for the tier `model`, as the add-on makes it for this scene once imported
    (`File › Import › Bitracer scene`): a light of brightness b is a point light
    of b × 10 000 W (`bi_conversions.watts_from_brightness`) with the file's
    colour, a sphere's transmission weight is its kt (clear: Base Color white),
    the scene's bounds are those of its lights and spheres."""
    import numpy as np
    from addon.bi_conversions import watts_from_brightness
    from addon.tiers import LensOptics, PrimaryLight, make_blender_light
    pts = [np.asarray(l.position, dtype=float) for l in scene.lights]
    for o in scene.objects:
        c, r = np.asarray(o.center, dtype=float), abs(float(o.radius))
        pts += [c - r, c + r]
    bounds, size = None, 1.0
    if pts:
        lo, hi = np.min(pts, axis=0), np.max(pts, axis=0)
        if np.all(np.isfinite(lo)) and np.all(np.isfinite(hi)):
            bounds = (tuple(lo), tuple(hi))
            size = float(np.linalg.norm(hi - lo)) or 1.0
    out = []
    for s in result.sources:
        light = scene.lights[s.light]
        primary = PrimaryLight(power_w=watts_from_brightness(light.brightness),
                               radius=float(light.radius), color=tuple(light.color))
        optics = LensOptics(transmission_weight=float(scene.objects[s.lens].surface.transmission))
        out.append(make_blender_light(s, primary, model.upper(), optics=optics,
                                      scene_size=size, scene_bounds=bounds))
    return out


def format_phase1_table(result, lights=None, model: str = "") -> str:
    """A readable report of phase 1: one row per source (with `lights`, the energy
    of its Blender light for the tier `model`), then the skipped pairs."""
    lines = [f"{len(result.sources)} secondary light source(s), "
             f"{len(result.skipped)} light × sphere pair(s) skipped", ""]
    if result.sources:
        energy = f"{'energy W':>10} " if lights is not None else ""
        header = (f"{'light':>5} {'lens':>4}  {'kind':<10} {'position':<28} "
                  f"{'spread°':>8} {'R_C':>8} {'intensity':>9} {energy} shadow")
        if lights is not None:
            lines.insert(1, f"energy: Blender light power (W) with the {model.lower()} tier")
        lines += [header, "-" * len(header)]
        for k, s in enumerate(result.sources):
            rc = f"{s.cylinder_radius:.4g}" if s.cylinder_radius is not None else "-"
            shadow = "full" if s.full else "non-full, blocked by " + ", ".join(
                f"sphere {k}" for k in s.shadow_list)
            e = f"{lights[k].energy_w:>10.4g} " if lights is not None else ""
            lines.append(f"{s.light:>5} {s.lens:>4}  {s.kind:<10} "
                         f"{_fmt_vec(s.position):<28} {s.spread_deg:>8.4g} {rc:>8} "
                         f"{s.intensity:>9.4g} {e} {shadow}")
    if result.skipped:
        lines += ["", "skipped:"]
        lines += [f"  light {k.light} × sphere {k.lens}: {k.reason}" for k in result.skipped]
    return "\n".join(lines)


def cmd_phase1(args) -> int:
    from addon.bi_format import BiFormatError, read_bi
    from addon.phase1 import compute_phase1
    try:
        scene = read_bi(args.scene)
    except BiFormatError as e:
        return _fail(str(e))
    except OSError as e:
        return _fail(f"{args.scene}: {e.strerror or e}")
    result = compute_phase1(scene)
    lights = blender_lights(scene, result, args.model)
    if args.json:
        out = result.to_json()
        for src, bl in zip(out["sources"], lights):
            src["blender_light"] = bl.to_json()
        json.dump({"model": args.model.upper(), **out}, sys.stdout, indent=2)
        print()
    else:
        print(format_phase1_table(result, lights, args.model))
    return 0


# --------------------------------------------------------------------------- test

#: The release whose environment the launcher picks without `--blender`.
DEFAULT_BLENDER = "5.2"
#: The manifest's `blender_version_min`: plain `test` also runs the Blender tests there.
MINIMUM_BLENDER = "4.2"


def cmd_test(args, extra) -> int:
    """Plain `test`: the whole suite on the default release, then the Blender-side
    tests on the minimum release (its own environment, made on first use). Paths or
    `--blender X.Y` narrow it to one pytest run."""
    # Paths given on the command line replace the default (the whole suite).
    targets = [] if any(not a.startswith("-") for a in extra) else [str(ROOT / "tests")]
    chosen = os.environ.get("LENS_LIGHTS_BLENDER") or ""
    release = chosen or DEFAULT_BLENDER
    # Another release than the default: the Blender-side tests only; the pure core
    # is the same code on every release.
    marks = ["-m", "blender"] if release != DEFAULT_BLENDER and "-m" not in extra else []
    cmd = [sys.executable, "-m", "pytest", *targets, "-q", *marks, *extra]
    code = subprocess.call(cmd, cwd=ROOT)
    if code != 0 or chosen or not targets:
        return code
    print(f"lens-lights: the Blender tests on Blender {MINIMUM_BLENDER} "
          "(the manifest's minimum)", flush=True)
    return subprocess.call([str(ROOT / "lens-lights"), "test", "--blender", MINIMUM_BLENDER,
                            *extra], cwd=ROOT)


# --------------------------------------------------------------------------- bench

def cmd_bench(args, extra) -> int:
    script = ROOT / "bench" / f"{args.name}.py"
    if not script.is_file():
        names = sorted(p.stem for p in (ROOT / "bench").glob("*.py") if not p.stem.startswith("_"))
        return _fail(f"no benchmark {args.name!r}; there are: {', '.join(names)}")
    return subprocess.call([sys.executable, str(script), *extra], cwd=ROOT)


# --------------------------------------------------------------------------- render, demo, build

def _load_script(name: str):
    """A module of scripts/ by file (cli.py may run from anywhere)."""
    import importlib.util
    path = ROOT / "scripts" / f"{name}.py"
    spec = importlib.util.spec_from_file_location(f"lens_lights_scripts_{name}", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def cmd_render(args) -> int:
    """`render` and `demo`: scripts/render.py, in this process (bpy is imported there)."""
    return _load_script("render").run(args)


def cmd_build(args, extra) -> int:
    if not (ROOT / "scripts" / "build_extension.py").is_file():
        return _fail("scripts/build_extension.py is missing")
    return _load_script("build_extension").main(extra) or 0


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="lens-lights", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("phase1", help="secondary light sources of a .bi scene")
    p.add_argument("scene", help="a .bi scene file")
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")
    p.add_argument("--model", choices=PHASE1_MODELS, default=PHASE1_DEFAULT_MODEL,
                   type=str.lower,
                   help=("lens-light tier of each source's Blender light (default: "
                         f"{PHASE1_DEFAULT_MODEL}, the most accurate that renders in both "
                         "EEVEE and Cycles; exact_profile is Cycles only)"))

    sub.add_parser("test", help="run the whole test suite (extra args go to pytest)")

    # Its options (--count, --seed) and --help are scripts/fuzz_bi.py's own.
    sub.add_parser("fuzz", add_help=False,
                   help="fuzz the .bi reader and phase1 (`fuzz --help`: its options)")

    p = sub.add_parser("bench", help="run a benchmark of bench/ (extra args go to it)")
    p.add_argument("name", help="benchmark name, e.g. scale or accuracy")

    render = _load_script("render")
    render.add_render_arguments(sub.add_parser(
        "render", help="render a .blend or .bi scene (with lens lights by default)"))
    render.add_demo_arguments(sub.add_parser(
        "demo", help="render the showcase scene without and with lens lights"))
    sub.add_parser("build", add_help=False,
                   help="build the extension's zip (args go to scripts/build_extension.py)")

    args, extra = parser.parse_known_args(argv)
    if args.command == "build":
        return cmd_build(args, extra)
    if args.command == "test":
        return cmd_test(args, extra)
    if args.command == "bench":
        return cmd_bench(args, extra)
    if args.command == "fuzz":
        return subprocess.call([sys.executable, str(ROOT / "scripts" / "fuzz_bi.py"), *extra])
    if extra:
        parser.error(f"unrecognized arguments: {' '.join(extra)}")
    return {"phase1": cmd_phase1, "render": cmd_render,
            "demo": cmd_render}[args.command](args)


if __name__ == "__main__":
    try:
        sys.exit(main())
    except BrokenPipeError:          # `… | head` closed the pipe: not an error
        sys.stderr.close()
        sys.exit(0)
