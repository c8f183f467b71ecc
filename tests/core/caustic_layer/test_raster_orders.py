"""The rasters' shared sorts (`rasters.regroup`, `rasters.sub_order`): a patch's landings
sorted once per axis, and the orders the quantiles need (by beam, by glass, by raster,
of a subset) derived from it, equal the plain one (np.lexsort by group then x) on data
with ties; the bulk boxes are the same given the orders or not."""

import numpy as np
import pytest

from core.caustic_layer.rasters import bulk_boxes, grouped_interp_quantiles, regroup, sub_order


def _data(seed, n=3000, n_groups=7):
    rng = np.random.default_rng(seed)
    # coarse values: many exact ties (a glass's quads share their corners)
    x = np.round(rng.normal(size=n), 2)
    groups = rng.integers(0, n_groups, n)
    return x, groups, rng


@pytest.mark.parametrize("seed", [0, 1])
def test_regroup_is_the_lexsort_by_group_then_x(seed):
    x, groups, _ = _data(seed)
    o = regroup(np.argsort(x, kind="stable"), groups, 7)
    assert np.array_equal(o, np.lexsort((x, groups)))


@pytest.mark.parametrize("seed", [0, 1])
def test_a_subsets_order_from_the_whole(seed):
    x, groups, rng = _data(seed)
    rows = np.nonzero(rng.random(len(x)) < 0.4)[0]
    got = sub_order(np.argsort(x, kind="stable"), rows, len(x))
    assert np.array_equal(got, np.argsort(x[rows], kind="stable"))
    assert np.array_equal(regroup(got, groups[rows], 7), np.lexsort((x[rows], groups[rows])))
    # rows out of order: no order (the caller sorts)
    assert sub_order(np.argsort(x, kind="stable"), rows[::-1], len(x)) is None


def test_quantiles_with_the_order_given_are_the_same():
    x, groups, rng = _data(2)
    w = rng.random(len(x))
    o = regroup(np.argsort(x, kind="stable"), groups, 7)
    qs = (0.0005, 0.5, 0.9995)
    a = grouped_interp_quantiles(x, w, groups, 7, qs)
    b = grouped_interp_quantiles(x, w, groups, 7, qs, o)
    assert np.array_equal(a, b)


@pytest.mark.parametrize("every", [True, False])
def test_bulk_boxes_given_the_orders_are_the_same(every):
    x, beam, rng = _data(3, n_groups=4)
    y = np.round(rng.normal(size=len(x)) * 3.0, 2)
    order = np.argsort(beam, kind="stable")  # landings by beam, as a patch has them
    x, y, beam = x[order], y[order], beam[order]
    w = rng.random(len(x))
    glass = beam // 2
    in_view = np.ones(len(x), dtype=bool) if every else rng.random(len(x)) < 0.7
    pixel = rng.uniform(0.001, 0.002, len(x))
    boxes = np.array([[-1.0, 1.0, -1.0, 1.0]] * 4)
    args = ((x, y, w, glass, beam), in_view, pixel, boxes, 1e-3, 16)
    plain = bulk_boxes(*args)
    given = bulk_boxes(*args, (np.argsort(x, kind="stable"), np.argsort(y, kind="stable")))
    for a, b in zip(plain, given, strict=True):
        assert np.array_equal(a, b)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_warps_median_distance_from_the_x_order(seed):
    """The warp's scale (the weighted median of |x − c| per raster) sorted from x's
    order (two runs merged) gives the texel lines of the plain sort, bit for bit, on
    data with many ties in x (a glass's quads share their corners) and medians that
    fall on one of them."""
    from core.caustic_layer import rasters

    x, groups, rng = _data(seed)
    groups = np.sort(groups)  # the rasters' landings come raster by raster
    w = rng.random(len(x))
    w[::5] = 1.0  # equal weights too
    order = np.lexsort((x, groups))
    quant = grouped_interp_quantiles(x, w, groups, 7, (0.0005, 0.9995, 0.5), order)
    res = np.full(7, 64)
    floors = np.zeros(7)
    plain = rasters._warp_axes(x, w, groups, 7, quant, res, True, floors)
    fast = rasters._warp_axes(x, w, groups, 7, quant, res, True, floors, order)
    for a, b in zip(plain, fast, strict=True):
        np.testing.assert_array_equal(a, b)
