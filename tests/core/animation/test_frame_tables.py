"""The bake's per-frame tables (core/animation/frame_tables.py): distinct tables and each
frame's slice, the tiles' layout and the texture coordinates the node tree reads, the
tiled image. Expected values worked out by hand."""

import numpy as np
import pytest

from core.animation import frame_tables as ft


def test_equal_keys_share_a_slice_in_order_of_first_appearance():
    keys, index = ft.frame_slices(["b", "a", "b", None, "c", "a"])
    assert keys == ["b", "a", None, "c"]
    assert index.tolist() == [0, 1, 0, 2, 3, 1]


def test_the_layout_adds_columns_only_past_the_side_limit():
    # 512-row tables, at most 16 384 rows: 32 slices per column
    one = ft.slice_layout(32, 512, 256)
    assert (one.columns, one.tile_rows, one.shape) == (1, 32, (16384, 256))
    two = ft.slice_layout(33, 512, 256)
    assert (two.columns, two.tile_rows, two.shape) == (2, 17, (8704, 512))
    assert two.tile(0) == (0, 0) and two.tile(1) == (1, 0) and two.tile(32) == (0, 16)
    with pytest.raises(ValueError, match="do not fit"):
        ft.slice_layout(3000, 512, 256)  # 94 columns of 256 texels > 16 384
    with pytest.raises(ValueError):
        ft.slice_layout(0, 512, 256)


def test_texture_coordinates_stay_inside_the_tile():
    lay = ft.SliceLayout(count=3, rows=4, width=8, columns=2)  # tiles 2 × 2, one unused
    # slice 2: tile column 0, tile row 1; (u, v) = (0.5, 0.5): the tile's middle
    assert lay.texture_coordinates(2, 0.5, 0.5) == pytest.approx((0.25, 0.75))
    # v beyond the table clamps to the tile's last row centre (3.5 / 4), u below 0 to
    # its first column centre (0.5 / 8): EXTEND inside the tile
    x, y = lay.texture_coordinates(1, -1.0, 2.0)
    assert x == pytest.approx((1 + 0.5 / 8) / 2) and y == pytest.approx((0 + 3.5 / 4) / 2)


def test_tiles_hold_the_tables_bottom_up():
    lay = ft.SliceLayout(count=3, rows=2, width=3, columns=2)
    tables = [np.full((2, 3), k + 1.0) for k in range(3)]
    tables[0][1, 2] = 9.0
    img = ft.tile_slices(tables, lay)
    assert img.shape == (4, 6)
    assert img[:2, :3].tolist() == [[1, 1, 1], [1, 1, 9]]  # slice 0: bottom left
    assert (img[:2, 3:] == 2).all() and (img[2:, :3] == 3).all()
    assert (img[2:, 3:] == 0).all()  # the unused tile
    # channels carry through (the near table's slopes)
    rgb = ft.tile_slices([np.ones((2, 3, 3))] * 3, lay)
    assert rgb.shape == (4, 6, 3)
    with pytest.raises(ValueError):
        ft.tile_slices([np.ones((3, 3))] * 3, lay)
