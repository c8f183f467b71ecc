"""`lens-lights render` and `lens-lights demo` on tiny images, and the labelled
side-by-side composition (pure numpy)."""
import importlib.util
import struct
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.blender

ROOT = Path(__file__).resolve().parent.parent
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


def load_render():
    spec = importlib.util.spec_from_file_location("lens_lights_render_under_test",
                                                  ROOT / "scripts" / "render.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


render = load_render()


def run_cli(*args, timeout=600):
    return subprocess.run([sys.executable, str(CLI), *map(str, args)], cwd=ROOT,
                          capture_output=True, text=True, timeout=timeout)


def png_size(path) -> tuple[int, int]:
    data = Path(path).read_bytes()[:24]
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    return struct.unpack(">II", data[16:24])


def png_pixels(path) -> np.ndarray:
    """RGB rows top to bottom (the test process has bpy too)."""
    return render.read_png(str(path))


# --------------------------------------------------------------------------- composition

def test_text_mask_has_every_label_glyph():
    for label in (render.LABEL_WITHOUT, render.LABEL_WITH, render.SHORT_WITHOUT):
        assert all(ch in render.FONT for ch in label)
    mask = render.text_mask("Ab", 2)
    assert mask.shape == (14, render.text_width("Ab", 2)) == (14, 22)
    assert np.array_equal(render.text_mask("~", 1), render.FONT["?"])
    for ch, glyph in render.FONT.items():
        assert glyph.shape == (7, 5), ch
        assert ch == " " or glyph.any(), ch


@pytest.mark.parametrize("w,h", [(48, 48), (200, 150), (960, 540)])
def test_compose_side_by_side(w, h):
    rng = np.random.default_rng(1)
    left = rng.random((h, w, 3)).astype(np.float32)
    right = rng.random((h, w, 3)).astype(np.float32)
    out = render.compose_side_by_side(left, right)
    band = out.shape[0] - h
    assert out.shape == (h + band, 2 * w + 4, 3) and band >= 11
    # the images are kept exactly, under their labels
    assert np.array_equal(out[band:, :w], left)
    assert np.array_equal(out[band:, w + 4:], right)
    # each band holds white text
    assert (out[:band, :w] == 1.0).any() and (out[:band, w + 4:] == 1.0).any()
    assert not (out[:band, w:w + 4] == 1.0).any()
    if w >= 200:     # the full labels fit: "WITHOUT LENS LIGHTS" is wider than "WITH …"
        ink_l = np.flatnonzero((out[:band, :w] == 1.0).any(axis=(0, 2)))
        ink_r = np.flatnonzero((out[:band, w + 4:] == 1.0).any(axis=(0, 2)))
        assert np.ptp(ink_l) > np.ptp(ink_r) > 0.5 * np.ptp(ink_l)


def test_compose_too_narrow_for_any_label():
    img = np.zeros((20, 8, 3), dtype=np.float32)
    out = render.compose_side_by_side(img, img)
    assert out.shape[1] == 20 and not (out == 1.0).any()


# --------------------------------------------------------------------------- render

def test_render_bi_without_lens_lights(tmp_path):
    out = tmp_path / "fig3.png"
    result = run_cli("render", FIG3, "-o", out, *TINY, "--no-lens-lights")
    assert result.returncode == 0, result.stderr
    assert png_size(out) == (48, 48)
    assert result.stdout.strip().splitlines()[-1] == str(out)
    assert "rendering without lens lights (Cycles, 48×48, 2 samples)" in result.stderr
    assert png_pixels(out).max() > 0.1          # something is lit


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
    without, with_ = image[h - 36:, :48], image[h - 36:, 52:]
    assert np.array_equal(with_, png_pixels(with_png))       # same scene, same seed
    gain = with_ - without
    assert gain.max() > 0.05 and gain.sum() > 5.0 and gain.min() > -0.05


def test_render_blend_with_eevee(tmp_path):
    """A .blend (saved from an import) through EEVEE, at its own resolution."""
    blend = tmp_path / "fig3.blend"
    script = (f"import bpy; bpy.ops.wm.read_factory_settings(use_empty=True); "
              f"import sys; sys.path.insert(0, {str(ROOT / 'scripts')!r}); "
              f"import render; render.ensure_extension(); "
              f"bpy.ops.import_scene.bi(filepath={str(FIG3)!r}); "
              f"s = bpy.context.scene; s.render.resolution_x = 40; s.render.resolution_y = 32; "
              f"bpy.ops.wm.save_as_mainfile(filepath={str(blend)!r})")
    made = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          timeout=600)
    assert made.returncode == 0, made.stderr
    out = tmp_path / "eevee.png"
    result = run_cli("render", blend, "-o", out, "--engine", "eevee", "--samples", "1",
                     "--no-lens-lights")
    assert result.returncode == 0, result.stderr
    assert "EEVEE, 40×32, 1 samples" in result.stderr
    assert png_size(out) == (40, 32)


@pytest.mark.parametrize("content,expect", [
    (None, ": no such file"),
    ("V 200 200\nC 0 0 10\nA 0 0 0\nU 0 1 0\nB 45 45\nL 1\nC 1 1 1\nP 1 2\n", ":8: "),
    ("V 200 200\nC 0 0 10\nA 0 0 0\nU 0 0 0\n", ":4: "),
    ("V 2 2\nC 0 0 10\nA 0 0 0\nU 0 1 0\nB 45 45\nL 0\nO 0\n", ":1: viewport"),
], ids=["missing", "short record", "zero up", "tiny viewport"])
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
    for bad in (["--resolution", "48"], ["--resolution", "2x2"], ["--samples", "0"],
                ["--engine", "povray"], ["--compare", "--no-lens-lights"]):
        result = run_cli("render", FIG1, "-o", tmp_path / "x.png", *bad)
        assert result.returncode == 2, bad
        assert "Traceback" not in result.stderr


# --------------------------------------------------------------------------- demo

def test_demo_tiny(tmp_path):
    out = tmp_path / "demo"
    result = run_cli("demo", "--out", out, "--resolution", "48x36", "--samples", "2")
    assert result.returncode == 0, result.stderr
    for name in ("showcase_without.png", "showcase_with.png", "showcase_compare.png",
                 "showcase.blend"):
        assert (out / name).is_file(), name
        assert str(out / name) in result.stdout
    assert png_size(out / "showcase_with.png") == (48, 36)
    assert png_size(out / "showcase_compare.png")[0] == 100
    without, with_ = png_pixels(out / "showcase_without.png"), png_pixels(out / "showcase_with.png")
    assert with_.sum() > without.sum()
