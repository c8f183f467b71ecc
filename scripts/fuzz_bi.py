"""Fuzz the `.bi` reader and `lens-lights phase1` with generated input.

    ./lens-lights fuzz [--count 100000] [--seed 0]

Inputs: mutations of the example files (lines dropped, duplicated, swapped or
truncated; numbers replaced by huge, tiny, negative, NaN-like or non-numeric
tokens; comments opened and not closed; bytes flipped) and random text/bytes.
For every input the reader either returns a scene or raises `BiFormatError` with
a line number (None only when the file could not be opened); anything else is a
failure. Every 50th input also goes through the CLI's `phase1` in-process: exit
0 with output, or exit 2 with a one-line message and no traceback. Every 200th
goes through Blender's `import_scene.bi` operator (the bpy module): it imports,
or it fails with a report naming the file and line, creates nothing and shows no
traceback. Parsed scenes go through phase 1, whose JSON must contain only finite
numbers.

Inputs that are refused as they should be print nothing (Blender's own "Error: …"
line of a refused import is captured); the run ends with a summary: inputs,
parsed, refused as expected, failures (the first 5 failures are shown in full).
Exit status 0 without failures, 1 with, 2 for bad arguments.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import math
import os
import random
import sys
import tempfile
import time
import traceback
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "scripts"))

from core.bi.format import BiFormatError, parse_bi
from core.phase1.point_lights import compute_phase1

TOKENS = [
    "0",
    "-1",
    "1e308",
    "1e-320",
    "nan",
    "inf",
    "-inf",
    "1e999",
    "x",
    "",
    "1.5.2",
    "0x10",
    "+3",
    "  ",
    "/*",
    "*/",
    "#T",
    "T",
    "S",
    "L",
    "O",
    "2",
    "-0",
    "99999999999",
]


def mutate(text: str, rng: random.Random) -> str:
    lines = text.split("\n")
    for _ in range(rng.randint(1, 4)):
        op = rng.randrange(8)
        i = rng.randrange(len(lines)) if lines else 0
        if not lines:
            lines = [""]
        if op == 0:
            del lines[i]
        elif op == 1:
            lines.insert(i, lines[rng.randrange(len(lines))])
        elif op == 2:
            j = rng.randrange(len(lines))
            lines[i], lines[j] = lines[j], lines[i]
        elif op == 3:
            words = lines[i].split(" ")
            words[rng.randrange(len(words))] = rng.choice(TOKENS)
            lines[i] = " ".join(words)
        elif op == 4:
            lines[i] = lines[i][: rng.randrange(len(lines[i]) + 1)]
        elif op == 5:
            lines = lines[:i]
        elif op == 6:
            lines[i] = lines[i] + " " + rng.choice(TOKENS)
        else:
            s = lines[i]
            if s:
                k = rng.randrange(len(s))
                lines[i] = s[:k] + chr(rng.randrange(1, 0x3000)) + s[k + 1 :]
    return "\n".join(lines)


def random_text(rng: random.Random) -> str:
    alphabet = "VCAUBLPIOTRS#DENx0123456789.-+e /*\n\t"
    return "".join(rng.choice(alphabet) for _ in range(rng.randrange(0, 400)))


def check_phase1_json(scene) -> None:
    def finite(x):
        if isinstance(x, float) and not math.isfinite(x):
            raise AssertionError(f"non-finite number {x} in phase-1 JSON")
        if isinstance(x, dict):
            for v in x.values():
                finite(v)
        if isinstance(x, list):
            for v in x:
                finite(v)

    finite(compute_phase1(scene).to_json())


def check_cli(text: str, tmp: Path) -> None:
    import cli

    path = tmp / "fuzz.bi"
    path.write_bytes(text.encode("utf-8", "surrogatepass"))
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = cli.main(["phase1", str(path), "--json"])
    if code == 0:
        json.loads(out.getvalue())
    elif code == 2:
        msg = err.getvalue().strip()
        if "Traceback" in msg or "\n" in msg or f"{path}:" not in msg:
            raise AssertionError(f"bad CLI error message: {msg!r}")
    else:
        raise AssertionError(f"CLI exit status {code}")


@contextlib.contextmanager
def captured_output(into: list):
    """Everything written to the process' stdout and stderr (file descriptors 1
    and 2: Blender's C code prints operator reports there) is appended to `into`
    as one string instead of reaching the terminal."""
    sys.stdout.flush()
    sys.stderr.flush()
    saved = os.dup(1), os.dup(2)
    with tempfile.TemporaryFile() as sink:
        os.dup2(sink.fileno(), 1)
        os.dup2(sink.fileno(), 2)
        try:
            yield
        finally:
            sys.stdout.flush()
            sys.stderr.flush()
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            os.close(saved[0])
            os.close(saved[1])
            sink.seek(0)
            into.append(sink.read().decode("utf-8", "replace"))


def check_import_operator(text: str, tmp: Path) -> None:
    path = tmp / "fuzz_import.bi"
    path.write_bytes(text.encode("utf-8", "surrogatepass"))
    printed = []
    try:
        # Blender's start-up log lines and the report of a refused import are captured.
        with captured_output(printed):
            import bpy
            from dev_extension import PACKAGE, load_extension

            if PACKAGE not in sys.modules:
                load_extension().register()
            bpy.ops.wm.read_factory_settings(use_empty=True)
            bpy.ops.import_scene.bi(filepath=str(path))
    except RuntimeError as e:  # the operator's ERROR report, as bpy.ops raises it
        msg = str(e)
        if "Traceback" in msg or f"{path}:" not in msg:
            raise AssertionError(f"bad import report: {msg!r}") from e
        if "Traceback" in printed[0]:
            raise AssertionError(f"a refused import printed a traceback: {printed[0]!r}") from e
        if len(bpy.data.objects) or len(bpy.data.collections):
            raise AssertionError("a failed import left objects behind") from e


def positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got '{text}'")
    return value


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(
        prog="lens-lights fuzz",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    ap.add_argument(
        "--count",
        type=positive_int,
        default=100_000,
        metavar="N",
        help="number of generated inputs (default: 100000)",
    )
    ap.add_argument(
        "--seed",
        type=int,
        default=0,
        help="seed of the generator (default: 0); the same seed, the same inputs",
    )
    return ap


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    rng = random.Random(args.seed)
    seeds = [p.read_text() for p in sorted((ROOT / "examples").glob("*.bi"))]
    t0 = time.perf_counter()
    failures, parsed, errors = 0, 0, 0
    with tempfile.TemporaryDirectory() as tmp:
        for n in range(args.count):
            text = random_text(rng) if n % 10 == 0 else mutate(rng.choice(seeds), rng)
            try:
                try:
                    scene = parse_bi(text, "fuzz.bi")
                    parsed += 1
                    check_phase1_json(scene)
                except BiFormatError as e:
                    errors += 1
                    if e.line is None or not str(e).startswith(f"fuzz.bi:{e.line}:"):
                        raise AssertionError(f"error without a line number: {e}") from e
                if n % 50 == 0:
                    check_cli(text, Path(tmp))
                if n % 200 == 0:
                    check_import_operator(text, Path(tmp))
            except Exception:  # the point of a fuzzer
                failures += 1
                if failures <= 5:
                    print(f"--- failure on input {n}:\n{text!r}\n{traceback.format_exc()}")
            if (n + 1) % 10_000 == 0:
                print(f"{n + 1} inputs, {failures} failures", flush=True)
    dt = time.perf_counter() - t0
    print(
        f"fuzz: {args.count} inputs in {dt:.1f} s: {parsed} parsed, {errors} refused as "
        f"expected (an error with a line number), {failures} failure(s)"
    )
    return 1 if failures else 0


if __name__ == "__main__":
    code = main()
    # Blender 4.2's bpy module (imported for the import operator) crashes in its static
    # destructors at exit, after the work: leave without running them.
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code or 0)
