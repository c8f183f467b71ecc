"""Build the extension zip and validate it, with the `blender_ext.py` that the bpy
wheel ships (no `blender` binary needed).

    python scripts/build_extension.py [--output-dir DIR]      (default: ROOT/dist)

Copies the work tree without hidden files and folders (``.git``, ``.pytest_cache``,
``.hypothesis`` …), ``__pycache__`` and ``dist`` to a temporary folder, runs
``blender_ext.py build --source-dir THAT --output-dir DIR`` there (the manifest's
``[build] paths_exclude_pattern`` keeps tests, examples, docs and tooling out),
then ``blender_ext.py validate ZIP``, and prints the zip's path. Exit status 0 on
success; the tool's own output goes to stderr.
"""

from __future__ import annotations

import argparse
import importlib.util
import re
import shutil
import subprocess
import sys
import tempfile
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
DEFAULT_OUTPUT = ROOT / "dist"


def blender_ext_path() -> Path:
    """`<site-packages>/bpy/<major.minor>/scripts/addons_core/bl_pkg/cli/blender_ext.py`,
    found without importing bpy (which takes seconds)."""
    spec = importlib.util.find_spec("bpy")
    if spec is None or not spec.submodule_search_locations:
        raise FileNotFoundError("the bpy module is not installed in this Python")
    base = Path(next(iter(spec.submodule_search_locations)))
    found = sorted(base.glob("[0-9]*.[0-9]*/scripts/addons_core/bl_pkg/cli/blender_ext.py"))
    if not found:
        raise FileNotFoundError(f"blender_ext.py not found under {base}")
    return found[-1]


def manifest() -> dict:
    with open(ROOT / "blender_manifest.toml", "rb") as f:
        return tomllib.load(f)


def run_tool(*args) -> subprocess.CompletedProcess:
    cmd = [sys.executable, str(blender_ext_path()), *map(str, args)]
    return subprocess.run(cmd, capture_output=True, text=True)


def _ignore(folder, names):
    """Leave out hidden entries, caches and earlier builds when staging the tree."""
    top = Path(folder).resolve() == ROOT
    return {
        n
        for n in names
        if n.startswith(".")
        or n == "__pycache__"
        or n.endswith((".pyc", ".zip"))
        or (top and n == DEFAULT_OUTPUT.name)
    }


def build(output_dir: Path = DEFAULT_OUTPUT) -> Path:
    """Build and validate; returns the zip's path. Raises RuntimeError on failure."""
    output_dir = Path(output_dir).resolve()
    output_dir.mkdir(parents=True, exist_ok=True)
    m = manifest()
    zip_path = output_dir / f"{m['id']}-{m['version']}.zip"
    if zip_path.exists():
        zip_path.unlink()
    with tempfile.TemporaryDirectory(prefix="lens-lights-build-") as tmp:
        source = Path(tmp) / m["id"]
        shutil.copytree(ROOT, source, ignore=_ignore)
        res = run_tool("build", "--source-dir", source, "--output-dir", output_dir)
    sys.stderr.write(res.stdout + res.stderr)
    if res.returncode != 0 or not zip_path.exists():
        raise RuntimeError(f"blender_ext.py build failed (exit {res.returncode})")
    res = run_tool("validate", zip_path)
    sys.stderr.write(res.stdout + res.stderr)
    if res.returncode != 0 or re.search(r"\berror\b", res.stdout + res.stderr, re.I):
        raise RuntimeError(f"blender_ext.py validate failed (exit {res.returncode})")
    return zip_path


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(
        prog="build_extension",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument(
        "--output-dir",
        type=Path,
        default=DEFAULT_OUTPUT,
        help=f"where the zip goes (default: {DEFAULT_OUTPUT})",
    )
    args = parser.parse_args(argv)
    try:
        path = build(args.output_dir)
    except (RuntimeError, FileNotFoundError) as e:
        print(f"build_extension: {e}", file=sys.stderr)
        return 1
    print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
