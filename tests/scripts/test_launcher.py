"""The launcher (`./lens-lights`, `scripts/ensure_env.sh`) as a new user meets it:
which Python it picks for a release, the one line it prints when there is none, and
no environment built for a benchmark that does not exist. Each run gets its own
`LENS_LIGHTS_HOME` and a fake pyenv, so nothing here touches the real environments."""

import os
import shutil
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def fake_python(path: Path, version: str) -> Path:
    """An executable that answers the launcher's version check like Python `version`
    and fails at anything else (so creating the environment stops right after the
    choice, which the launcher prints)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(
        "#!/bin/sh\n"
        f"""case "$2" in *"'{version}'"*) exit 0 ;; *"import sys"*) exit 1 ;; esac\n"""
        "exit 3\n"
    )
    path.chmod(0o755)
    return path


def staged(tmp_path: Path, pins: str) -> Path:
    """A copy of the launcher with one extra release, 9.9, whose pins need `pins`."""
    root = tmp_path / "clone"
    (root / "scripts" / "envs").mkdir(parents=True)
    shutil.copy(ROOT / "scripts" / "ensure_env.sh", root / "scripts" / "ensure_env.sh")
    (root / "scripts" / "envs" / "blender-9.9.txt").write_text(pins)
    return root


def run_env(root: Path, tmp_path: Path, *args, **env):
    base = {
        "PATH": "/usr/bin:/bin",
        "HOME": str(tmp_path / "home"),
        "LENS_LIGHTS_HOME": str(tmp_path / "envs"),
        "PYENV_ROOT": str(tmp_path / "pyenv"),
    }
    return subprocess.run(
        ["bash", str(root / "scripts" / "ensure_env.sh"), *args],
        capture_output=True,
        text=True,
        env={**base, **env},
        timeout=60,
    )


def test_unknown_release_names_the_known_ones(tmp_path):
    res = run_env(ROOT, tmp_path, "--blender", "3.6")
    assert res.returncode == 2 and res.stdout == ""
    assert "no environment for Blender '3.6'" in res.stderr
    for known in ("4.2", "4.5", "5.2"):
        assert known in res.stderr


def test_no_python_of_that_version_says_how_to_get_one(tmp_path):
    root = staged(tmp_path, "# python 3.99\nbpy==9.9.0\n")
    res = run_env(root, tmp_path, "--blender", "9.9")
    assert res.returncode == 1 and res.stdout == ""
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1, res.stderr
    assert "Blender 9.9 needs Python 3.99" in lines[0]
    assert "pyenv install 3.99" in lines[0] and "LENS_LIGHTS_PYTHON" in lines[0]
    assert not list((tmp_path / "envs").glob("venv-*"))


def test_finds_pyenvs_python_and_prefers_lens_lights_python(tmp_path):
    root = staged(tmp_path, "# python 3.99\nbpy==9.9.0\n")
    in_pyenv = fake_python(
        tmp_path / "pyenv" / "versions" / "3.99.1" / "bin" / "python3.99", "3.99"
    )
    res = run_env(root, tmp_path, "--blender", "9.9")
    assert f"with {in_pyenv} " in res.stderr, res.stderr
    assert res.returncode != 0  # the fake cannot make a venv: stops after choosing

    chosen = fake_python(tmp_path / "elsewhere" / "python", "3.99")
    res = run_env(root, tmp_path, "--blender", "9.9", LENS_LIGHTS_PYTHON=str(chosen))
    assert f"with {chosen} " in res.stderr, res.stderr

    wrong = fake_python(tmp_path / "wrong" / "python", "3.98")
    res = run_env(root, tmp_path, "--blender", "9.9", LENS_LIGHTS_PYTHON=str(wrong))
    assert f"with {in_pyenv} " in res.stderr, res.stderr  # a wrong version is passed over


def test_bench_that_does_not_exist_builds_nothing(tmp_path):
    env = {**os.environ, "LENS_LIGHTS_HOME": str(tmp_path / "envs")}
    res = subprocess.run(
        [str(ROOT / "lens-lights"), "bench", "nosuch"],
        capture_output=True,
        text=True,
        env=env,
        timeout=60,
    )
    assert res.returncode == 2
    assert "no benchmark 'nosuch'; there are:" in res.stderr and "scale" in res.stderr
    assert not (tmp_path / "envs").exists()
