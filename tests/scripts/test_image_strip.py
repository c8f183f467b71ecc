"""The labelled side-by-side composition of `render --compare` and `demo`
(scripts/image_strip.py: pure numpy) and its image writing (bpy)."""

import image_strip  # scripts/ (tests/conftest.py)
import numpy as np
import pytest

# --------------------------------------------------------------------------- composition


def test_text_mask_has_every_label_glyph():
    for label in (image_strip.LABEL_WITHOUT, image_strip.LABEL_WITH, image_strip.SHORT_WITHOUT):
        assert all(ch in image_strip.FONT for ch in label)
    mask = image_strip.text_mask("Ab", 2)
    assert mask.shape == (14, image_strip.text_width("Ab", 2)) == (14, 22)
    assert np.array_equal(image_strip.text_mask("~", 1), image_strip.FONT["?"])
    for ch, glyph in image_strip.FONT.items():
        assert glyph.shape == (7, 5), ch
        assert ch == " " or glyph.any(), ch


@pytest.mark.parametrize("w,h", [(48, 48), (200, 150), (960, 540)])
def test_compose_side_by_side(w, h):
    rng = np.random.default_rng(1)
    left = rng.random((h, w, 3)).astype(np.float32)
    right = rng.random((h, w, 3)).astype(np.float32)
    out = image_strip.compose_side_by_side(left, right)
    band = out.shape[0] - h
    assert out.shape == (h + band, 2 * w + 4, 3) and band >= 11
    # the images are kept exactly, under their labels
    assert np.array_equal(out[band:, :w], left)
    assert np.array_equal(out[band:, w + 4 :], right)
    # each band holds white text
    assert (out[:band, :w] == 1.0).any() and (out[:band, w + 4 :] == 1.0).any()
    assert not (out[:band, w : w + 4] == 1.0).any()
    if w >= 200:  # the full labels fit: "WITHOUT LENS LIGHTS" is wider than "WITH …"
        ink_l = np.flatnonzero((out[:band, :w] == 1.0).any(axis=(0, 2)))
        ink_r = np.flatnonzero((out[:band, w + 4 :] == 1.0).any(axis=(0, 2)))
        assert np.ptp(ink_l) > np.ptp(ink_r) > 0.5 * np.ptp(ink_l)


def test_compose_too_narrow_for_any_label():
    img = np.zeros((20, 8, 3), dtype=np.float32)
    out = image_strip.compose_side_by_side(img, img)
    assert out.shape[1] == 20 and not (out == 1.0).any()


# --------------------------------------------------------------------------- files

MAGIC = {
    ".png": b"\x89PNG\r\n\x1a\n",
    ".jpg": b"\xff\xd8\xff",
    ".exr": b"v/1\x01",
    ".tif": b"II*\x00",
    ".webp": b"RIFF",
}


@pytest.mark.blender
@pytest.mark.parametrize("ext", sorted(MAGIC))
def test_write_image_in_the_format_of_the_extension(tmp_path, ext):
    pytest.importorskip("bpy")
    rgb = np.random.default_rng(2).random((6, 10, 3)) * 2.0
    path = tmp_path / f"x{ext}"
    image_strip.write_image(rgb, str(path))
    assert path.read_bytes()[: len(MAGIC[ext])] == MAGIC[ext]
    back = image_strip.read_image(str(path))
    assert back.shape == (6, 10, 3)
    if ext == ".exr":  # linear floats, kept as they are
        assert np.allclose(back, rgb, atol=1e-6)
    elif ext in (".png", ".tif"):  # lossless 8 bit: clipped, rounded to bytes
        assert np.allclose(back, np.round(np.clip(rgb, 0, 1) * 255) / 255, atol=1e-6)


def test_image_formats_by_extension():
    assert image_strip.image_format("a/b.PNG") == "PNG"
    assert image_strip.image_format("x.jpeg") == image_strip.image_format("x.jpg") == "JPEG"
    assert image_strip.image_format("x.exr") == "OPEN_EXR"
    assert image_strip.image_format("x.gif") is None
    assert image_strip.image_format("x") is None
