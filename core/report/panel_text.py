"""Text for the extension's panel: wrapping to the width of the sidebar.

Pure. Blender's `UILayout.label` does not wrap: `blender/ui/panel.py` splits long
texts into lines of about as many characters as fit the region's width.
"""

from __future__ import annotations

#: Characters per line when the region's width is unknown (a sidebar of the
#: default width at UI scale 1).
DEFAULT_CHARS = 42
#: Average width of a character of the interface font at UI scale 1, in pixels
#: (Blender's default interface font, 11 pt, over ordinary English text).
CHAR_PIXELS = 6.5
#: Pixels of a sidebar panel's width taken by its margins and the label's indent.
MARGIN_PIXELS = 30.0
#: Never wrap narrower than this (a very narrow sidebar still gets words).
MIN_CHARS = 12


def chars_per_line(region_width: float | None, ui_scale: float = 1.0) -> int:
    """How many characters of label text fit a region `region_width` pixels wide
    (None: `DEFAULT_CHARS`)."""
    if not region_width or region_width <= 0:
        return DEFAULT_CHARS
    scale = ui_scale if ui_scale and ui_scale > 0 else 1.0
    return max(MIN_CHARS, int((region_width - MARGIN_PIXELS * scale) / (CHAR_PIXELS * scale)))


def wrap(text: str, width: int = DEFAULT_CHARS) -> list[str]:
    """`text` in lines of at most `width` characters, broken between words (a
    longer word gets a line of its own)."""
    lines, line = [], ""
    for word in text.split():
        if line and len(line) + 1 + len(word) > width:
            lines.append(line)
            line = word
        else:
            line = f"{line} {word}" if line else word
    if line:
        lines.append(line)
    return lines
