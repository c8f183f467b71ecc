"""Batch renders: `./lens-lights render …` and `./lens-lights demo …` (needs bpy).

Run by the launcher with the pinned environment's python (bpy 5.0.1 as a module),
or inside a Blender binary:

    blender -b --python scripts/render.py -- SCENE.blend|SCENE.bi -o OUT.png [--compare]

If the extension is not installed (the bpy module, a fresh Blender), it is loaded
from this checkout and registered for the run.

render SCENE -o OUT.png   render a `.blend` or `.bi` scene with lens lights; the
                          extension of OUT picks the format (.png, .jpg/.jpeg, .exr,
                          .tif/.tiff, .webp); a missing folder is created
  --engine cycles|eevee   render engine (default: the file's for a .blend, else cycles)
  --samples N             samples per pixel (default: the file's; 64 for a .bi)
  --resolution WxH        image size in pixels (default: the file's / the .bi viewport)
  --no-lens-lights        render without lens lights (removes any generated ones)
  --compare               one image: without | with lens lights, side by side, labelled
                          (scripts/image_strip.py)
  --frame N               render frame N (lens lights generated on that frame)
  --frames A-B            render frames A to B: the lens lights are baked over the range
                          first (`lens_lights.bake`), then each frame is rendered to OUT
                          with its last run of '#' replaced by the frame number
                          (OUT_####.png → OUT_0001.png …; several frames need a '#')
  --bake OUT.blend        save the baked file (frames: --frames, --frame, else the
                          scene's range) for a render farm: stock Blender renders it
                          (`blender -b OUT.blend -a`); -o is optional then; never the
                          input file

demo [--out DIR]          build the showcase scene, render it without and with lens
                          lights; writes DIR/showcase.blend, showcase_without.png,
                          showcase_with.png, showcase_compare.png (default DIR: out/)
"""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import os
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT / "scripts") not in sys.path:
    sys.path.insert(0, str(ROOT / "scripts"))
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

import image_strip
from image_strip import allowed_extensions, apply_format, image_format

from core.animation.light_tracks import frame_path, parse_frames

PACKAGE = "lens_lights"
EXIT_BAD_INPUT = 2
EXIT_FAILED = 1
DEFAULT_BI_SAMPLES = 64
DEFAULT_OUT = ROOT / "out"
DEMO_ENGINE, DEMO_SAMPLES = "cycles", 64


class RenderError(Exception):
    """A failure with a message for the terminal (no traceback)."""

    def __init__(self, message: str, code: int = EXIT_FAILED):
        super().__init__(message)
        self.code = code


_t0 = time.monotonic()


def say(message: str) -> None:
    """Progress on the terminal (stderr, so stdout carries only results)."""
    print(f"lens-lights [{time.monotonic() - _t0:6.1f} s] {message}", file=sys.stderr, flush=True)


# --------------------------------------------------------------------------- arguments


def resolution(text: str) -> tuple[int, int]:
    try:
        w, h = (int(v) for v in text.lower().replace("×", "x").split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected WIDTHxHEIGHT, e.g. 640x480, got '{text}'"
        ) from None
    if not (4 <= w <= 65536 and 4 <= h <= 65536):
        raise argparse.ArgumentTypeError(f"width and height must be 4–65536 pixels, got '{text}'")
    return w, h


def positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got '{text}'")
    return value


def add_engine_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--engine",
        choices=("cycles", "eevee"),
        help="render engine (default: the .blend's own; cycles for a .bi)",
    )
    p.add_argument(
        "--samples",
        type=positive_int,
        metavar="N",
        help=f"samples per pixel (default: the .blend's own; {DEFAULT_BI_SAMPLES} for a .bi)",
    )
    p.add_argument(
        "--resolution",
        type=resolution,
        metavar="WxH",
        help="image size in pixels (default: the scene's)",
    )


def frame_range(text: str) -> tuple[int, int]:
    try:
        return parse_frames(text)
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


def frame_number(text: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a frame number, got '{text}'") from None


def add_render_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("scene", help="a .blend or .bi scene")
    p.add_argument(
        "-o",
        "--output",
        metavar="OUT.png",
        help=(
            "the image to write; its extension picks the format: "
            f"{allowed_extensions()} (a missing folder is created)"
        ),
    )
    add_engine_arguments(p)
    group = p.add_mutually_exclusive_group()
    group.add_argument(
        "--no-lens-lights",
        action="store_true",
        help="render without lens lights (removes generated ones)",
    )
    group.add_argument(
        "--compare", action="store_true", help="one image: without | with lens lights, labelled"
    )
    frames = p.add_mutually_exclusive_group()
    frames.add_argument(
        "--frame", type=frame_number, metavar="N", help="render frame N (default: the current)"
    )
    frames.add_argument(
        "--frames",
        type=frame_range,
        metavar="A-B",
        help="render frames A to B (lens lights baked over the range); OUT needs a '#' "
        "run for the frame number, e.g. OUT_####.png",
    )
    p.add_argument(
        "--bake",
        metavar="OUT.blend",
        help="save the file with the lens lights baked over the frames (default: the "
        "scene's range) for a render farm; renders without the extension",
    )


def add_demo_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--out",
        default=str(DEFAULT_OUT),
        metavar="DIR",
        help=f"output directory (default: {DEFAULT_OUT})",
    )
    p.add_argument(
        "--engine", choices=("cycles", "eevee"), help=f"render engine (default: {DEMO_ENGINE})"
    )
    p.add_argument(
        "--samples",
        type=positive_int,
        metavar="N",
        help=f"samples per pixel (default: {DEMO_SAMPLES})",
    )
    p.add_argument(
        "--resolution",
        type=resolution,
        metavar="WxH",
        help="image size in pixels (default: the showcase's 480x270)",
    )


# --------------------------------------------------------------------------- extension


def _has_operator(module: str, name: str) -> bool:
    import bpy

    try:
        getattr(getattr(bpy.ops, module), name).get_rna_type()
        return True
    except (KeyError, AttributeError):
        return False


def ensure_extension():
    """The Lens Lights package, registering it from this checkout unless Blender
    already has it (an installed extension). Returns the package module or None."""
    if _has_operator("import_scene", "bi") and _has_operator("lens_lights", "generate"):
        return None
    sys.path.insert(0, str(ROOT / "scripts"))
    from dev_extension import load_extension

    module = load_extension()
    if not _has_operator("import_scene", "bi"):
        module.register()
    return module


def _run_operator(op, what: str) -> None:
    """Call an operator; its error report becomes a RenderError (no traceback)."""
    try:
        result = op()
    except RuntimeError as e:
        message = str(e).strip()
        if message.startswith("Error: "):
            message = message[len("Error: ") :]
        raise RenderError(f"{what}: {message}") from None
    if "FINISHED" not in result:
        raise RenderError(f"{what}: cancelled ({', '.join(sorted(result))})")


# --------------------------------------------------------------------------- scenes


def new_empty_file() -> None:
    import bpy

    # Factory startup but the user's preferences (keeps installed extensions).
    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)


def check_scene_path(path: str) -> None:
    """A scene argument that names a readable file (before anything is loaded)."""
    if os.path.isdir(path):
        raise RenderError(f"{path}: is a directory (expected a .blend or .bi file)", EXIT_BAD_INPUT)
    if not os.path.isfile(path):
        raise RenderError(f"{path}: no such file", EXIT_BAD_INPUT)


def _make_folder(folder: Path, what: str) -> None:
    """Create `folder` (and its parents) unless it exists; a clear error otherwise."""
    if folder.is_dir():
        return
    for parent in (folder, *folder.parents):
        if parent.exists() and not parent.is_dir():
            raise RenderError(
                f"{parent}: is not a directory (in the {what} {folder})", EXIT_BAD_INPUT
            )
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise RenderError(
            f"{folder}: cannot create the {what} ({e.strerror or e})", EXIT_BAD_INPUT
        ) from None


def check_output(path: str) -> str:
    """The absolute path of an image to write, checked before anything is rendered:
    not a directory, an extension of `image_strip.IMAGE_FORMATS`; a missing parent
    folder is created (a parent that is a file is an error)."""
    out = Path(os.path.abspath(path))
    if out.is_dir() or path.endswith(("/", os.sep)):
        raise RenderError(
            f"{path}: is a directory (expected an image file, e.g. {Path(path) / 'render.png'})",
            EXIT_BAD_INPUT,
        )
    if image_format(out) is None:
        kind = f"'{out.suffix}'" if out.suffix else "no extension"
        raise RenderError(
            f"{path}: unknown image type ({kind}); use one of {allowed_extensions()}",
            EXIT_BAD_INPUT,
        )
    _make_folder(out.parent, "output folder")
    if not os.access(out.parent, os.W_OK):
        raise RenderError(f"{out.parent}: not writable", EXIT_BAD_INPUT)
    return str(out)


def check_output_dir(path: str) -> Path:
    """`demo --out DIR`: a folder (created if missing), checked before rendering."""
    out = Path(os.path.abspath(path))
    if out.exists() and not out.is_dir():
        raise RenderError(f"{path}: is not a directory (--out takes a folder)", EXIT_BAD_INPUT)
    _make_folder(out, "output folder")
    if not os.access(out, os.W_OK):
        raise RenderError(f"{out}: not writable", EXIT_BAD_INPUT)
    return out


def load_scene(path: str) -> bool:
    """Open a .blend or import a .bi into an empty file. Returns True for .bi."""
    import bpy

    check_scene_path(path)
    suffix = Path(path).suffix.lower()
    if suffix == ".blend":
        try:
            bpy.ops.wm.open_mainfile(filepath=os.path.abspath(path), load_ui=False)
        except RuntimeError as e:
            raise RenderError(f"{path}: cannot open ({str(e).strip()})", EXIT_BAD_INPUT) from None
        ensure_extension()
        return False
    if suffix == ".bi":
        new_empty_file()
        ensure_extension()
        try:
            _run_operator(lambda: bpy.ops.import_scene.bi(filepath=os.path.abspath(path)), "import")
        except RenderError as e:
            raise RenderError(str(e).removeprefix("import: "), EXIT_BAD_INPUT) from None
        return True
    raise RenderError(f"{path}: expected a .blend or .bi file", EXIT_BAD_INPUT)


def eevee_engine() -> str:
    import bpy

    return "BLENDER_EEVEE_NEXT" if bpy.app.version < (5, 0, 0) else "BLENDER_EEVEE"


def configure(
    scene, engine: str | None, samples: int | None, size: tuple[int, int] | None, is_bi: bool
) -> None:
    """Engine, samples and size; a .bi scene gets Cycles and 64 samples by default."""
    if engine is None and is_bi:
        engine = "cycles"
    if engine == "cycles":
        scene.render.engine = "CYCLES"
    elif engine == "eevee":
        scene.render.engine = eevee_engine()
    if scene.render.engine == "CYCLES":
        scene.cycles.device = "CPU"
    if samples is None and is_bi:
        samples = DEFAULT_BI_SAMPLES
    if samples is not None:
        if scene.render.engine == "CYCLES":
            scene.cycles.samples = samples
            scene.cycles.preview_samples = samples
        else:
            scene.eevee.taa_render_samples = samples
    if size is not None:
        scene.render.resolution_x, scene.render.resolution_y = size
        scene.render.resolution_percentage = 100
    if scene.camera is None:
        raise RenderError("the scene has no camera", EXIT_BAD_INPUT)


def describe(scene) -> str:
    r = scene.render
    w = r.resolution_x * r.resolution_percentage // 100
    h = r.resolution_y * r.resolution_percentage // 100
    if r.engine == "CYCLES":
        return f"Cycles, {w}×{h}, {scene.cycles.samples} samples"
    return f"EEVEE, {w}×{h}, {scene.eevee.taa_render_samples} samples"


def set_lens_lights(on: bool) -> str:
    """Generate (on) or clear (off) the scene's lens lights; a short report."""
    import bpy

    if not on:
        # Clear's poll refuses a scene without lens lights: nothing to remove then.
        if _has_operator("lens_lights", "clear") and bpy.ops.lens_lights.clear.poll():
            _run_operator(bpy.ops.lens_lights.clear, "removing lens lights")
        return "no lens lights"
    if not _has_operator("lens_lights", "generate"):
        raise RenderError(
            "the Lens Lights generator (bpy.ops.lens_lights.generate) is not available"
        )
    before = {o.name for o in bpy.data.objects}
    _run_operator(bpy.ops.lens_lights.generate, "generating lens lights")
    lights = [o for o in bpy.context.scene.objects if o.type == "LIGHT" and o.name not in before]
    return f"{len(lights)} lens light(s)"


class _SampleProgress:
    """Blender's render statistics ("Remaining: … | Sample 8/64") on the terminal,
    at most every `interval` seconds (a `render_stats` handler)."""

    def __init__(self, interval: float = 3.0):
        self.interval = interval
        self.last = 0.0

    def __call__(self, stats, *_):
        text = str(stats)
        if "Sample" not in text:
            return
        now = time.monotonic()
        final = (
            "Sample" in text
            and text.split("Sample")[-1].strip().split("/")[0] == text.split("/")[-1].strip()
        )
        if now - self.last < self.interval and not final:
            return
        self.last = now
        parts = [p.strip() for p in text.split("|")]
        keep = [p for p in parts if p.startswith(("Sample", "Remaining"))]
        say("  " + ", ".join(keep).lower())


def render_to(scene, path: str, label: str) -> float:
    """Render the scene's camera view to `path`, in the format its extension names
    (`image_strip.IMAGE_FORMATS`); returns seconds taken."""
    import bpy

    apply_format(
        scene.render.image_settings, image_format(path), alpha=scene.render.film_transparent
    )
    scene.render.use_file_extension = False
    scene.render.filepath = os.path.abspath(path)
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    say(f"rendering {label} ({describe(scene)}) ...")
    start = time.monotonic()
    progress = _SampleProgress()
    bpy.app.handlers.render_stats.append(progress)
    try:
        bpy.ops.render.render(write_still=True)
    except RuntimeError as e:
        raise RenderError(f"render failed: {str(e).strip()}") from None
    finally:
        bpy.app.handlers.render_stats.remove(progress)
    seconds = time.monotonic() - start
    if not os.path.isfile(path):
        raise RenderError(f"render failed: {path} was not written")
    say(f"rendered {label} in {seconds:.1f} s → {path}")
    return seconds


def check_bake_path(path: str, scene_path: str) -> str:
    """`--bake OUT.blend`: a .blend path that is not the input scene; its folder is
    created."""
    out = Path(os.path.abspath(path))
    if out.suffix.lower() != ".blend":
        raise RenderError(
            f"{path}: --bake writes a .blend file (got '{out.suffix}')", EXIT_BAD_INPUT
        )
    if out.is_dir():
        raise RenderError(f"{path}: is a directory (expected a .blend file)", EXIT_BAD_INPUT)
    src = Path(os.path.abspath(scene_path))
    if out == src or (out.exists() and os.path.samefile(out, src)):
        raise RenderError(
            f"{path}: is the input scene; --bake never overwrites it (choose another name)",
            EXIT_BAD_INPUT,
        )
    _make_folder(out.parent, "folder of the baked file")
    return str(out)


def check_frame_arguments(args) -> None:
    """The frame options against the others (before anything is loaded)."""
    several = args.frames is not None and args.frames[0] != args.frames[1]
    if args.output is None and args.bake is None:
        raise RenderError(
            "nothing to do: give -o OUT.png, --bake OUT.blend or both", EXIT_BAD_INPUT
        )
    if (args.frames or args.frame is not None or args.bake) and args.compare:
        raise RenderError(
            "--compare renders one still: not with --frame, --frames or --bake", EXIT_BAD_INPUT
        )
    if args.bake and args.no_lens_lights:
        raise RenderError("--bake bakes the lens lights: not with --no-lens-lights", EXIT_BAD_INPUT)
    if several and args.output is not None and "#" not in args.output:
        raise RenderError(
            f"{args.output}: {args.frames[1] - args.frames[0] + 1} frames need a '#' run "
            "for the frame number in the output name, e.g. OUT_####.png",
            EXIT_BAD_INPUT,
        )


def bake_lens_lights(start: int, end: int) -> str:
    """Bake the lens lights over start…end (`lens_lights.bake`); a short report."""
    import bpy

    if not _has_operator("lens_lights", "bake"):
        raise RenderError("the Lens Lights bake (bpy.ops.lens_lights.bake) is not available")
    _run_operator(
        lambda: bpy.ops.lens_lights.bake(frame_start=start, frame_end=end), "baking lens lights"
    )
    return bpy.context.scene.lens_lights.last_report


def render_frames_baked(scene, out: str, start: int, end: int) -> list[str]:
    """Render each frame of an already baked scene; returns the paths written."""
    paths = []
    count = end - start + 1
    for k, frame in enumerate(range(start, end + 1)):
        scene.frame_set(frame)
        path = frame_path(out, frame)
        render_to(scene, path, f"frame {frame} ({k + 1}/{count})")
        paths.append(path)
    return paths


def render_frames(scene, out: str, start: int, end: int, on: bool) -> list[str]:
    """Bake (on) or clear the lens lights, then render each frame; the paths written."""
    if on:
        say(f"baking lens lights over frames {start}–{end} ...")
        say(bake_lens_lights(start, end))
    else:
        say(set_lens_lights(False))
    return render_frames_baked(scene, out, start, end)


# --------------------------------------------------------------------------- commands


def cmd_render(args) -> int:
    check_scene_path(args.scene)  # all before anything is loaded or rendered
    check_frame_arguments(args)
    out = check_output(args.output) if args.output is not None else None
    bake_out = check_bake_path(args.bake, args.scene) if args.bake else None
    import bpy

    say(f"loading {args.scene}")
    is_bi = load_scene(args.scene)
    scene = bpy.context.scene
    configure(scene, args.engine, args.samples, args.resolution, is_bi)
    if args.frames is not None or bake_out is not None:
        start, end = args.frames or (
            (args.frame, args.frame)
            if args.frame is not None
            else (scene.frame_start, scene.frame_end)
        )
        if end < start:
            raise RenderError(f"the scene's frame range {start}–{end} is empty", EXIT_BAD_INPUT)
        on = not args.no_lens_lights
        if bake_out is not None:
            say(f"baking lens lights over frames {start}–{end} ...")
            say(bake_lens_lights(start, end))
            bpy.ops.wm.save_as_mainfile(filepath=bake_out, copy=True)
            say(f"wrote the baked file → {bake_out}")
            print(bake_out)
            if out is None:
                return 0
            for path in render_frames_baked(scene, out, start, end):
                print(path)
            return 0
        for path in render_frames(scene, out, start, end, on):
            print(path)
        return 0
    if args.frame is not None:
        scene.frame_set(args.frame)
    out = frame_path(out, scene.frame_current)  # a '#' run in a still's name: its frame
    if not args.compare:
        on = not args.no_lens_lights
        say(f"{'generating' if on else 'removing'} lens lights ...")
        say(set_lens_lights(on))
        render_to(scene, out, "with lens lights" if on else "without lens lights")
        print(out)
        return 0
    with tempfile.TemporaryDirectory(prefix="lens-lights-") as tmp:
        # The halves as 8-bit PNG (display values), or as EXR for an EXR comparison.
        ext = ".exr" if image_format(out) in image_strip.FLOAT_FORMATS else ".png"
        without, with_ = os.path.join(tmp, "without" + ext), os.path.join(tmp, "with" + ext)
        say(set_lens_lights(False))
        render_to(scene, without, "without lens lights")
        say("generating lens lights ...")
        say(set_lens_lights(True))
        render_to(scene, with_, "with lens lights")
        image_strip.compare_images(without, with_, out)
    say(f"wrote the comparison → {out}")
    print(out)
    return 0


def load_showcase():
    """`build_showcase(scene)` from examples/showcase.py."""
    package = sys.modules.get(PACKAGE)
    if package is not None:
        try:
            return importlib.import_module(f"{PACKAGE}.examples.showcase").build_showcase
        except ModuleNotFoundError as e:
            if e.name not in (f"{PACKAGE}.examples", f"{PACKAGE}.examples.showcase"):
                raise
    path = ROOT / "examples" / "showcase.py"
    if not path.is_file():
        raise RenderError(f"{path}: the showcase scene is missing")
    spec = importlib.util.spec_from_file_location(f"{PACKAGE}.examples.showcase", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module.build_showcase


def cmd_demo(args) -> int:
    out_dir = check_output_dir(args.out)
    import bpy

    say(f"building the showcase scene (output: {out_dir})")
    new_empty_file()
    ensure_extension()
    build_showcase = load_showcase()
    build_showcase(bpy.context.scene)
    scene = bpy.context.scene
    configure(
        scene,
        args.engine or DEMO_ENGINE,
        args.samples or DEMO_SAMPLES,
        args.resolution,
        is_bi=False,
    )
    if scene.render.engine == "CYCLES":
        scene.cycles.use_denoising = True
    paths = {k: str(out_dir / f"showcase_{k}.png") for k in ("without", "with", "compare")}
    blend = str(out_dir / "showcase.blend")
    say(set_lens_lights(False))
    bpy.ops.wm.save_as_mainfile(filepath=blend, copy=True)
    render_to(scene, paths["without"], "without lens lights")
    say("generating lens lights ...")
    say(set_lens_lights(True))
    render_to(scene, paths["with"], "with lens lights")
    image_strip.compare_images(paths["without"], paths["with"], paths["compare"])
    say("done")
    print(f"showcase scene:       {blend}")
    print(f"without lens lights:  {paths['without']}")
    print(f"with lens lights:     {paths['with']}")
    print(f"side by side:         {paths['compare']}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="render.py", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    sub = parser.add_subparsers(dest="command", required=True)
    add_render_arguments(sub.add_parser("render", help="render a .blend or .bi scene"))
    add_demo_arguments(sub.add_parser("demo", help="render the showcase scene"))
    return parser


def run(args) -> int:
    """Run a parsed `render` or `demo` command; errors become a message and an exit code."""
    try:
        return {"render": cmd_render, "demo": cmd_demo}[args.command](args)
    except RenderError as e:
        print(f"lens-lights: {e}", file=sys.stderr)
        return e.code


def main(argv=None) -> int:
    if argv is None:
        # Inside Blender: `blender -b --python render.py -- ARGS`.
        argv = sys.argv[sys.argv.index("--") + 1 :] if "--" in sys.argv else sys.argv[1:]
        if argv and argv[0] not in ("render", "demo", "-h", "--help"):
            argv = ["render", *argv]
    return run(build_parser().parse_args(argv))


if __name__ == "__main__":
    sys.exit(main())
