"""`lens-lights render` and `lens-lights demo` on tiny images, and their checks of
the command line (scene and output paths, image formats). The labelled
side-by-side composition: tests/scripts/test_image_strip.py."""

import struct
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from image_strip import read_image  # scripts/ (tests/conftest.py)

pytestmark = pytest.mark.blender

ROOT = Path(__file__).resolve().parents[2]
CLI = ROOT / "scripts" / "cli.py"
FIG1 = ROOT / "examples" / "fig1.bi"
FIG3 = ROOT / "examples" / "fig3.bi"
TINY = ["--resolution", "48x48", "--samples", "2"]

#: A glass sphere above a white floor (a sphere of radius 1000): without lens
#: lights it casts a plain shadow; with them its caustic lights a disc inside it.
CAUSTIC_BI = """V 48 36
C 0 3 10
A 0 1 0
U 0 1 0
B 50 38.5
L 1
C 1 1 1
P 0 10 0
I 1
O 2
T 0
C 0 6 0
R 1
S
#C 1 1 1
#A 0.1
#D 0
#S 0.1
#T 0.9
#E 80
#N 1.5
T 0
C 0 -1000 0
R 1000
S
#C 0.9 0.9 0.9
#A 0.1
#D 0.9
#S 0
#T 0
#E 10
#N 1
"""


def run_cli(*args, timeout=600):
    return subprocess.run(
        [sys.executable, str(CLI), *map(str, args)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=timeout,
    )


def png_size(path) -> tuple[int, int]:
    data = Path(path).read_bytes()[:24]
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    return struct.unpack(">II", data[16:24])


def png_pixels(path) -> np.ndarray:
    """RGB rows top to bottom (the test process has bpy too)."""
    return read_image(str(path))


# --------------------------------------------------------------------------- render


def test_render_bi_without_lens_lights(tmp_path):
    out = tmp_path / "fig3.png"
    result = run_cli("render", FIG3, "-o", out, *TINY, "--no-lens-lights")
    assert result.returncode == 0, result.stderr
    assert png_size(out) == (48, 48)
    assert result.stdout.strip().splitlines()[-1] == str(out)
    assert "rendering without lens lights (Cycles, 48×48, 2 samples)" in result.stderr
    assert png_pixels(out).max() > 0.1  # something is lit


def test_render_bi_with_lens_lights_and_compare(tmp_path):
    """The default renders with lens lights; --compare puts both side by side,
    and the lens light lights up the glass sphere's shadow."""
    scene = tmp_path / "caustic.bi"
    scene.write_text(CAUSTIC_BI)
    with_png, cmp_png = tmp_path / "with.png", tmp_path / "compare.png"
    result = run_cli("render", scene, "-o", with_png, "--samples", "2")
    assert result.returncode == 0, result.stderr
    assert "1 lens light(s)" in result.stderr and png_size(with_png) == (48, 36)

    result = run_cli("render", scene, "-o", cmp_png, "--samples", "2", "--compare")
    assert result.returncode == 0, result.stderr
    w, h = png_size(cmp_png)
    assert w == 48 + 4 + 48 and h > 36
    image = png_pixels(cmp_png)
    without, with_ = image[h - 36 :, :48], image[h - 36 :, 52:]
    # Same scene, same seed: the same image (Cycles 4.2 differs by a level or two of
    # 8 bits between processes; 5.x is bit-identical).
    assert np.abs(with_ - png_pixels(with_png)).max() <= 3 / 255
    gain = with_ - without
    assert gain.max() > 0.05 and gain.sum() > 5.0 and gain.min() > -0.05


def test_render_blend_with_eevee(tmp_path):
    """A .blend (saved from an import) through EEVEE, at its own resolution."""
    blend = tmp_path / "fig3.blend"
    script = (
        f"import bpy; bpy.ops.wm.read_factory_settings(use_empty=True); "
        f"import sys; sys.path.insert(0, {str(ROOT / 'scripts')!r}); "
        f"import render; render.ensure_extension(); "
        f"bpy.ops.import_scene.bi(filepath={str(FIG3)!r}); "
        f"s = bpy.context.scene; s.render.resolution_x = 40; s.render.resolution_y = 32; "
        f"bpy.ops.wm.save_as_mainfile(filepath={str(blend)!r}); "
        # Blender 4.2's bpy crashes in its destructors at exit, after the work.
        f"import os; sys.stdout.flush(); os._exit(0)"
    )
    made = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=600
    )
    assert made.returncode == 0, made.stderr
    out = tmp_path / "eevee.png"
    result = run_cli(
        "render", blend, "-o", out, "--engine", "eevee", "--samples", "1", "--no-lens-lights"
    )
    assert result.returncode == 0, result.stderr
    assert "EEVEE, 40×32, 1 samples" in result.stderr
    assert png_size(out) == (40, 32)


@pytest.mark.parametrize(
    "content,expect",
    [
        (None, ": no such file"),
        ("V 200 200\nC 0 0 10\nA 0 0 0\nU 0 1 0\nB 45 45\nL 1\nC 1 1 1\nP 1 2\n", ":8: "),
        ("V 200 200\nC 0 0 10\nA 0 0 0\nU 0 0 0\n", ":4: "),
        ("V 2 2\nC 0 0 10\nA 0 0 0\nU 0 1 0\nB 45 45\nL 0\nO 0\n", ":1: viewport"),
    ],
    ids=["missing", "short record", "zero up", "tiny viewport"],
)
def test_render_bad_file(tmp_path, content, expect):
    path = tmp_path / "bad.bi"
    if content is not None:
        path.write_text(content)
    result = run_cli("render", path, "-o", tmp_path / "x.png", *TINY)
    assert result.returncode == 2
    assert f"lens-lights: {path}{expect}" in result.stderr
    assert "Traceback" not in result.stderr
    assert not (tmp_path / "x.png").exists()


def test_render_bad_arguments(tmp_path):
    txt = tmp_path / "scene.txt"
    txt.write_text("")
    result = run_cli("render", txt, "-o", tmp_path / "x.png")
    assert result.returncode == 2 and "expected a .blend or .bi file" in result.stderr
    for bad in (
        ["--resolution", "48"],
        ["--resolution", "2x2"],
        ["--samples", "0"],
        ["--engine", "povray"],
        ["--compare", "--no-lens-lights"],
    ):
        result = run_cli("render", FIG1, "-o", tmp_path / "x.png", *bad)
        assert result.returncode == 2, bad
        assert "Traceback" not in result.stderr


# --------------------------------------------------------------------------- paths, formats


def assert_refused_before_rendering(result, message):
    assert result.returncode == 2, result.stderr
    assert message in result.stderr, result.stderr
    assert "Traceback" not in result.stderr
    assert "rendering" not in result.stderr and "loading" not in result.stderr


def test_render_output_is_a_directory(tmp_path):
    """Checked before loading and rendering (it used to render, then fail, exit 1)."""
    result = run_cli("render", FIG1, "-o", tmp_path)
    assert_refused_before_rendering(result, f"lens-lights: {tmp_path}: is a directory")
    result = run_cli("render", FIG1, "-o", f"{tmp_path}/new/")
    assert_refused_before_rendering(result, "is a directory")


@pytest.mark.parametrize("name,kind", [("x.gif", "'.gif'"), ("x", "no extension")])
def test_render_output_unknown_image_type(tmp_path, name, kind):
    result = run_cli("render", FIG1, "-o", tmp_path / name)
    assert_refused_before_rendering(result, f"unknown image type ({kind})")
    assert ".png, .jpg, .jpeg, .exr" in result.stderr
    assert not (tmp_path / name).exists()


def test_render_output_folder_is_a_file(tmp_path):
    (tmp_path / "file").write_text("")
    result = run_cli("render", FIG1, "-o", tmp_path / "file" / "x.png")
    assert_refused_before_rendering(result, f"{tmp_path / 'file'}: is not a directory")


def test_render_scene_is_a_directory(tmp_path):
    result = run_cli("render", tmp_path, "-o", tmp_path / "x.png")
    assert_refused_before_rendering(result, f"lens-lights: {tmp_path}: is a directory")
    assert "no such file" not in result.stderr


def test_render_jpeg_into_a_new_folder(tmp_path):
    """The extension picks the format (JPEG bytes in x.jpg); a missing folder is made."""
    out = tmp_path / "new" / "sub" / "x.jpg"
    result = run_cli("render", FIG3, "-o", out, *TINY, "--no-lens-lights")
    assert result.returncode == 0, result.stderr
    assert out.read_bytes()[:3] == b"\xff\xd8\xff"
    assert read_image(str(out)).shape == (48, 48, 3)


def test_render_compare_as_exr(tmp_path):
    """An OpenEXR comparison: float halves, composed as floats."""
    out = tmp_path / "cmp.exr"
    result = run_cli("render", FIG3, "-o", out, *TINY, "--compare")
    assert result.returncode == 0, result.stderr
    assert out.read_bytes()[:4] == b"v/1\x01"
    image = read_image(str(out))
    assert image.shape[1] == 48 + 4 + 48 and image.shape[0] > 48


def test_demo_out_is_not_a_directory(tmp_path):
    (tmp_path / "file").write_text("")
    for out in (tmp_path / "file", tmp_path / "file" / "demo"):
        result = run_cli("demo", "--out", out, "--resolution", "48x36", "--samples", "1")
        assert result.returncode == 2, result.stderr
        assert f"{tmp_path / 'file'}: is not a directory" in result.stderr
        assert "Traceback" not in result.stderr and "rendering" not in result.stderr


# --------------------------------------------------------------------------- demo


def test_demo_tiny(tmp_path):
    out = tmp_path / "demo"
    result = run_cli("demo", "--out", out, "--resolution", "48x36", "--samples", "2")
    assert result.returncode == 0, result.stderr
    for name in (
        "showcase_without.png",
        "showcase_with.png",
        "showcase_compare.png",
        "showcase.blend",
    ):
        assert (out / name).is_file(), name
        assert str(out / name) in result.stdout
    assert png_size(out / "showcase_with.png") == (48, 36)
    assert png_size(out / "showcase_compare.png")[0] == 100
    without, with_ = png_pixels(out / "showcase_without.png"), png_pixels(out / "showcase_with.png")
    assert with_.sum() > without.sum()
