"""Labelled side-by-side images for `./lens-lights render --compare` and `demo`: a
built-in 5×7 bitmap font, the composition (pure numpy), and reading / writing
images through Blender's image datablocks (bpy).

Images are float RGB arrays, rows top to bottom. The image formats are those of
`IMAGE_FORMATS` (by file extension): 8-bit PNG, JPEG, TIFF and WebP hold
display-referred values (the view transform applied); OpenEXR holds linear scene
values as 32-bit floats.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

LABEL_WITHOUT, LABEL_WITH = "WITHOUT LENS LIGHTS", "WITH LENS LIGHTS"
SHORT_WITHOUT, SHORT_WITH = "WITHOUT", "WITH"

#: File extension → Blender's `ImageFormatSettings.file_format`.
IMAGE_FORMATS = {
    ".png": "PNG",
    ".jpg": "JPEG",
    ".jpeg": "JPEG",
    ".exr": "OPEN_EXR",
    ".tif": "TIFF",
    ".tiff": "TIFF",
    ".webp": "WEBP",
}
#: Formats written as floats (linear); the others as 8-bit display values.
FLOAT_FORMATS = {"OPEN_EXR"}


def image_format(path: str | os.PathLike) -> str | None:
    """Blender's file format for `path`'s extension (None: not one we write)."""
    return IMAGE_FORMATS.get(Path(path).suffix.lower())


def allowed_extensions() -> str:
    return ", ".join(IMAGE_FORMATS)


def apply_format(settings, file_format: str, alpha: bool = False) -> None:
    """Set an `ImageFormatSettings` (a scene's render output or an image's save
    settings) to `file_format`: 8-bit for the display formats, 32-bit float
    for OpenEXR; RGBA only where the format has alpha and `alpha` is asked for."""
    settings.file_format = file_format
    settings.color_mode = "RGBA" if alpha and file_format != "JPEG" else "RGB"
    settings.color_depth = "32" if file_format in FLOAT_FORMATS else "8"
    if file_format == "JPEG":
        settings.quality = 90


# --------------------------------------------------------------------------- reading, writing


def read_image(path: str) -> np.ndarray:
    """An image file as a float RGB array (rows top to bottom): 8-bit formats as
    byte/255, OpenEXR as stored. A transparent film is composed over black."""
    import bpy

    image = bpy.data.images.load(os.path.abspath(path), check_existing=False)
    try:
        w, h = image.size
        pixels = np.empty(w * h * 4, dtype=np.float32)
        image.pixels.foreach_get(pixels)
    finally:
        bpy.data.images.remove(image)
    rgba = pixels.reshape(h, w, 4)[::-1]
    rgb, alpha = rgba[..., :3], rgba[..., 3:]
    return rgb * alpha


#: The name kept for callers of the PNG-only version.
read_png = read_image


def write_image(rgb: np.ndarray, path: str, file_format: str | None = None) -> None:
    """Write a float RGB array (rows top to bottom) in `file_format` (default: by
    the extension, see `IMAGE_FORMATS`): 8-bit formats get the values clipped to
    0–1 and rounded to bytes here, so a PNG holds exactly these bytes; OpenEXR
    gets the floats as they are."""
    import bpy

    file_format = file_format or image_format(path)
    if file_format is None:
        raise ValueError(f"{path}: not an image type we write ({allowed_extensions()})")
    is_float = file_format in FLOAT_FORMATS
    h, w, _ = rgb.shape
    rgb = np.asarray(rgb, dtype=np.float64)
    if not is_float:
        rgb = np.round(np.clip(rgb, 0.0, 1.0) * 255.0) / 255.0
    rgba = np.concatenate([rgb, np.ones((h, w, 1))], axis=2)[::-1]
    image = bpy.data.images.new("lens-lights compare", w, h, alpha=False, float_buffer=is_float)
    try:
        image.pixels.foreach_set(rgba.astype(np.float32).ravel())
        image.filepath_raw = os.path.abspath(path)
        image.file_format = file_format
        Path(path).parent.mkdir(parents=True, exist_ok=True)
        if is_float:
            # `Image.save` writes a float buffer's own depth; a scene's settings say 32.
            scene = bpy.context.scene
            settings = scene.render.image_settings
            saved = (settings.file_format, settings.color_mode, settings.color_depth)
            apply_format(settings, file_format)
            try:
                image.save_render(os.path.abspath(path), scene=scene)
            finally:
                settings.file_format, settings.color_mode, settings.color_depth = saved
        else:
            image.save()
    finally:
        bpy.data.images.remove(image)


def write_png(rgb: np.ndarray, path: str) -> None:
    """Write a float RGB array (rows top to bottom, 0–1) as an 8-bit PNG, as is."""
    write_image(rgb, path, "PNG")


# --------------------------------------------------------------------------- font

# 5×7 bitmap font: each glyph is 7 rows of 5 columns ("#" = ink).
_FONT_ROWS = {
    "A": ".###.|#...#|#...#|#####|#...#|#...#|#...#",
    "B": "####.|#...#|#...#|####.|#...#|#...#|####.",
    "C": ".###.|#...#|#....|#....|#....|#...#|.###.",
    "D": "####.|#...#|#...#|#...#|#...#|#...#|####.",
    "E": "#####|#....|#....|####.|#....|#....|#####",
    "F": "#####|#....|#....|####.|#....|#....|#....",
    "G": ".###.|#...#|#....|#.###|#...#|#...#|.###.",
    "H": "#...#|#...#|#...#|#####|#...#|#...#|#...#",
    "I": ".###.|..#..|..#..|..#..|..#..|..#..|.###.",
    "J": "..###|...#.|...#.|...#.|...#.|#..#.|.##..",
    "K": "#...#|#..#.|#.#..|##...|#.#..|#..#.|#...#",
    "L": "#....|#....|#....|#....|#....|#....|#####",
    "M": "#...#|##.##|#.#.#|#.#.#|#...#|#...#|#...#",
    "N": "#...#|#...#|##..#|#.#.#|#..##|#...#|#...#",
    "O": ".###.|#...#|#...#|#...#|#...#|#...#|.###.",
    "P": "####.|#...#|#...#|####.|#....|#....|#....",
    "Q": ".###.|#...#|#...#|#...#|#.#.#|#..#.|.##.#",
    "R": "####.|#...#|#...#|####.|#.#..|#..#.|#...#",
    "S": ".####|#....|#....|.###.|....#|....#|####.",
    "T": "#####|..#..|..#..|..#..|..#..|..#..|..#..",
    "U": "#...#|#...#|#...#|#...#|#...#|#...#|.###.",
    "V": "#...#|#...#|#...#|#...#|#...#|.#.#.|..#..",
    "W": "#...#|#...#|#...#|#.#.#|#.#.#|#.#.#|.#.#.",
    "X": "#...#|#...#|.#.#.|..#..|.#.#.|#...#|#...#",
    "Y": "#...#|#...#|.#.#.|..#..|..#..|..#..|..#..",
    "Z": "#####|....#|...#.|..#..|.#...|#....|#####",
    "0": ".###.|#...#|#..##|#.#.#|##..#|#...#|.###.",
    "1": "..#..|.##..|..#..|..#..|..#..|..#..|.###.",
    "2": ".###.|#...#|....#|...#.|..#..|.#...|#####",
    "3": "#####|...#.|..#..|...#.|....#|#...#|.###.",
    "4": "...#.|..##.|.#.#.|#..#.|#####|...#.|...#.",
    "5": "#####|#....|####.|....#|....#|#...#|.###.",
    "6": "..##.|.#...|#....|####.|#...#|#...#|.###.",
    "7": "#####|....#|...#.|..#..|.#...|.#...|.#...",
    "8": ".###.|#...#|#...#|.###.|#...#|#...#|.###.",
    "9": ".###.|#...#|#...#|.####|....#|...#.|.##..",
    " ": ".....|.....|.....|.....|.....|.....|.....",
    ".": ".....|.....|.....|.....|.....|.##..|.##..",
    ",": ".....|.....|.....|.....|.##..|..#..|.#...",
    ":": ".....|.##..|.##..|.....|.##..|.##..|.....",
    "-": ".....|.....|.....|#####|.....|.....|.....",
    "/": "....#|....#|...#.|..#..|.#...|#....|#....",
    "(": "...#.|..#..|.#...|.#...|.#...|..#..|...#.",
    ")": ".#...|..#..|...#.|...#.|...#.|..#..|.#...",
    "|": "..#..|..#..|..#..|..#..|..#..|..#..|..#..",
    "?": ".###.|#...#|....#|...#.|..#..|.....|..#..",
}
FONT = {
    ch: np.array([[c == "#" for c in row] for row in rows.split("|")], dtype=bool)
    for ch, rows in _FONT_ROWS.items()
}
GLYPH_W, GLYPH_H, GLYPH_GAP = 5, 7, 1


def text_width(text: str, scale: int) -> int:
    return max(0, len(text) * (GLYPH_W + GLYPH_GAP) - GLYPH_GAP) * scale


def text_mask(text: str, scale: int) -> np.ndarray:
    """A boolean bitmap (rows top to bottom) of `text` in the built-in font;
    characters it lacks are drawn as '?'; lower case as upper case."""
    width = text_width(text, 1)
    mask = np.zeros((GLYPH_H, max(width, 1)), dtype=bool)
    for i, ch in enumerate(text.upper()):
        glyph = FONT.get(ch, FONT["?"])
        x = i * (GLYPH_W + GLYPH_GAP)
        mask[:, x : x + GLYPH_W] = glyph
    return np.kron(mask, np.ones((scale, scale), dtype=bool))


def label_scale(width: int) -> int:
    """Glyph scale (1–4) for a label over a panel `width` pixels wide."""
    return max(1, min(4, width // 240 + 1))


def _fit_label(labels: tuple[str, ...], width: int, scale: int) -> tuple[str, int] | None:
    """The first label that fits `width` pixels at `scale` or, failing that, at a
    smaller scale; None if even the shortest label does not fit at scale 1."""
    for s in range(scale, 0, -1):
        for label in labels:
            if text_width(label, s) <= width - 2:
                return label, s
    return None


def compose_side_by_side(
    left: np.ndarray,
    right: np.ndarray,
    labels=((LABEL_WITHOUT, SHORT_WITHOUT), (LABEL_WITH, SHORT_WITH)),
    gap: int = 4,
) -> np.ndarray:
    """One image: `left | right` (RGB float arrays, top row first, same height),
    each under a dark band with its label in white."""
    h = max(left.shape[0], right.shape[0])
    panels = []
    for image, names in zip((left, right), labels, strict=True):
        pad = np.zeros((h, image.shape[1], 3), dtype=np.float32)
        pad[: image.shape[0]] = image
        panels.append((pad, names))
    scale = label_scale(min(image.shape[1] for image, _ in panels))
    fits = [_fit_label(names, image.shape[1], scale) for image, names in panels]
    scale = min([f[1] for f in fits if f] or [1])
    margin = max(2, 2 * scale)
    band_h = GLYPH_H * scale + 2 * margin
    band_color, ink = np.float32(0.08), np.float32(1.0)
    columns = []
    for (image, _names), fit in zip(panels, fits, strict=True):
        band = np.full((band_h, image.shape[1], 3), band_color, dtype=np.float32)
        if fit:
            mask = text_mask(fit[0], scale)
            x0 = max(0, (image.shape[1] - mask.shape[1]) // 2)
            band[margin : margin + mask.shape[0], x0 : x0 + mask.shape[1]][mask] = ink
        columns.append(np.concatenate([band, image.astype(np.float32)], axis=0))
    separator = np.full((h + band_h, gap, 3), band_color, dtype=np.float32)
    return np.concatenate([columns[0], separator, columns[1]], axis=1)


def compare_images(without_path: str, with_path: str, out_path: str) -> None:
    """`out_path` (its format by extension): the two images side by side, labelled."""
    write_image(compose_side_by_side(read_image(without_path), read_image(with_path)), out_path)


#: The name kept for callers of the PNG-only version.
compare_png = compare_images
