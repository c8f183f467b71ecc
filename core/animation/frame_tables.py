"""The tables a baked lens light's node tree reads per frame (`blender/commands/bake.py`):
whatever Generate's tree reads from an image that changes with the frame (the Exact
profile's near-field table, the shadow mask) becomes one slice of one image per
distinct table, and the frame reads its own slice through a keyed slice index.

* `frame_slices`: each frame's table key → the distinct keys (first appearance
  first) and each frame's slice index (equal keys, equal pixels: one slice).
* `SliceLayout` (`slice_layout`): slices of `rows` × `width` texels laid out as tiles,
  `columns` side by side and as many tile rows as needed, so that neither side of
  the image exceeds `MAX_SIDE` (a GPU's texture limit; Metal's is 16 384): slice k
  at tile column k mod columns, tile row k // columns. `texture_coordinates` is what
  the node tree computes (`lights.build_profile_nodes`, `mask_nodes`): the table's
  (u, v) clamped to the tile's first and last texel centres, so that the linear
  filter never reads a neighbouring tile (as EXTEND does at the image's edge).
* `tile_slices`: the tables laid out so (unused tiles 0).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: Largest side of a baked image (texels): Metal's 2-D texture limit (CUDA's is larger).
MAX_SIDE = 16384


def frame_slices(keys) -> tuple[list, np.ndarray]:
    """(distinct keys in order of first appearance, each frame's index among them)."""
    order: dict = {}
    index = np.zeros(len(keys), dtype=np.int64)
    for i, key in enumerate(keys):
        index[i] = order.setdefault(key, len(order))
    return list(order), index


@dataclass(frozen=True)
class SliceLayout:
    """`count` slices of `rows` × `width` texels, `columns` tiles side by side."""

    count: int
    rows: int
    width: int
    columns: int = 1

    @property
    def tile_rows(self) -> int:
        return math.ceil(self.count / self.columns)

    @property
    def shape(self) -> tuple[int, int]:
        """(height, width) of the image in texels."""
        return self.tile_rows * self.rows, self.columns * self.width

    def tile(self, k: int) -> tuple[int, int]:
        """(tile column, tile row) of slice k."""
        return k % self.columns, k // self.columns

    def texture_coordinates(self, k: int, u: float, v: float) -> tuple[float, float]:
        """The image's texture coordinates of the table's (u, v) in slice k."""
        col, row = self.tile(k)
        hu, hv = 0.5 / self.width, 0.5 / self.rows
        x = (col + min(max(u, hu), 1.0 - hu)) / self.columns
        y = (row + min(max(v, hv), 1.0 - hv)) / self.tile_rows
        return x, y


def slice_layout(count: int, rows: int, width: int, max_side: int = MAX_SIDE) -> SliceLayout:
    """The fewest columns that keep the image's height within `max_side`; a ValueError
    when even its width would not fit."""
    if count < 1 or rows < 1 or width < 1:
        raise ValueError(f"no slices to lay out ({count} of {rows} × {width})")
    if rows > max_side or width > max_side:
        raise ValueError(f"a {rows} × {width} table exceeds {max_side} texels")
    per_column = max_side // rows
    columns = math.ceil(count / per_column)
    if columns * width > max_side:
        raise ValueError(
            f"{count} tables of {rows} × {width} texels do not fit one {max_side}² image"
        )
    return SliceLayout(int(count), int(rows), int(width), int(columns))


def tile_slices(tables, layout: SliceLayout) -> np.ndarray:
    """The tables (each (rows, width) or (rows, width, C)) as the layout's image, row 0
    at the bottom (Blender's); unused tiles 0."""
    tables = [np.asarray(t, dtype=np.float32) for t in tables]
    if len(tables) != layout.count:
        raise ValueError(f"{len(tables)} tables for a layout of {layout.count}")
    shapes = {t.shape for t in tables}
    if len(shapes) != 1 or next(iter(shapes))[:2] != (layout.rows, layout.width):
        raise ValueError(f"tables of sizes {sorted(shapes)} for {layout.rows} × {layout.width}")
    h, w = layout.shape
    out = np.zeros((h, w, *tables[0].shape[2:]), dtype=np.float32)
    for k, t in enumerate(tables):
        col, row = layout.tile(k)
        y0, x0 = row * layout.rows, col * layout.width
        out[y0 : y0 + layout.rows, x0 : x0 + layout.width] = t
    return out
