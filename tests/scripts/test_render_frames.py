"""`lens-lights render --frame N | --frames A-B | --bake OUT.blend` on a tiny animated
scene (a point light moving over a glass ball): one file per frame, named by the
output's '#' run; the baked file written (never over the input); clear errors for
bad ranges and names before anything is loaded."""

import subprocess
import sys
from pathlib import Path

import bpy
import pytest
from measuring_scene import build_measuring_scene

pytestmark = pytest.mark.blender

ROOT = Path(__file__).resolve().parents[2]
CLI = ROOT / "scripts" / "cli.py"
TINY = ["--resolution", "16x16", "--samples", "1", "--engine", "cycles"]


def run_cli(*args, timeout=600):
    return subprocess.run(
        [sys.executable, str(CLI), "render", *map(str, args)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=timeout,
    )


def printed(run, folder):
    """The paths the command printed (stdout also carries Blender's own log)."""
    return [ln for ln in run.stdout.splitlines() if ln.startswith(str(folder))]


@pytest.fixture(scope="module")
def animated_blend(extension, tmp_path_factory):
    """A saved .blend: glass ball, floor, a lamp keyed from x = −0.5 (frame 1) to
    x = 0.5 (frame 3)."""
    built = build_measuring_scene(
        "CYCLES",
        resolution=16,
        floor_size=6.0,
        view=2.0,
        camera_height=5.0,
        ball=dict(radius=0.5, location=(0.0, 0.0, 2.0), name="Marble"),
        lamp=dict(location=(-0.5, 0.0, 4.0), power=1000.0),
    )
    sc = built.scene
    sc.frame_start, sc.frame_end = 1, 3
    lamp = built.lamp
    lamp.keyframe_insert("location", frame=1)
    lamp.location.x = 0.5
    lamp.keyframe_insert("location", frame=3)
    path = tmp_path_factory.mktemp("scene") / "animated.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path), copy=True)
    return path


def test_frames_write_one_file_each(animated_blend, tmp_path):
    run = run_cli(animated_blend, "-o", tmp_path / "shot_####.png", "--frames", "2-3", *TINY)
    assert run.returncode == 0, run.stderr[-3000:]
    written = sorted(p.name for p in tmp_path.iterdir())
    assert written == ["shot_0002.png", "shot_0003.png"]
    assert "frame 2 (1/2)" in run.stderr and "frame 3 (2/2)" in run.stderr
    assert "Baked 1 lens light over frames 2–3" in run.stderr
    assert printed(run, tmp_path) == [str(tmp_path / n) for n in written]


def test_one_frame_and_bake_file(animated_blend, tmp_path):
    baked = tmp_path / "farm" / "baked.blend"
    run = run_cli(animated_blend, "--bake", baked, "--frames", "1-3", *TINY)
    assert run.returncode == 0, run.stderr[-3000:]
    assert baked.is_file() and printed(run, tmp_path) == [str(baked)]
    with bpy.data.libraries.load(str(baked)) as (src, _):
        names = list(src.objects)
        actions = list(src.actions)
    assert "Lens light Lamp > Marble" in names
    # the lamp's own and the lens light's (from 4.4 one action may hold the object's
    # and its light data's slots)
    assert "LampAction" in actions and len(actions) >= 2
    run = run_cli(animated_blend, "-o", tmp_path / "still_##.png", "--frame", "2", *TINY)
    assert run.returncode == 0, run.stderr[-3000:]
    assert (tmp_path / "still_02.png").is_file()


@pytest.mark.parametrize(
    "args, message",
    [
        (["-o", "OUT/x_####.png", "--frames", "5-2"], "ends before it starts"),
        (["-o", "OUT/x.png", "--frames", "1-3"], "3 frames need a '#' run"),
        (["-o", "OUT/x_#.png", "--frames", "a-b"], "expected a frame range"),
        (["--frames", "1-2"], "nothing to do"),
        (["-o", "OUT/x.png", "--compare", "--frame", "2"], "--compare renders one still"),
        (["--bake", "OUT/x.blend", "--no-lens-lights"], "not with --no-lens-lights"),
        (["--bake", "OUT/x.png"], "--bake writes a .blend file"),
    ],
)
def test_bad_frame_arguments(animated_blend, tmp_path, args, message):
    args = [str(a).replace("OUT", str(tmp_path)) for a in args]
    run = run_cli(animated_blend, *args)
    assert run.returncode == 2, run.stderr[-2000:]
    assert message in run.stderr
    assert "Traceback" not in run.stderr
    assert not any(tmp_path.iterdir())  # nothing loaded, nothing written


def test_bake_never_overwrites_the_input(animated_blend):
    before = animated_blend.read_bytes()
    run = run_cli(animated_blend, "--bake", animated_blend)
    assert run.returncode == 2 and "never overwrites it" in run.stderr
    assert animated_blend.read_bytes() == before
