"""Live update's filter: where a plan's light goes (`core.plan.watch`), checked against
distances computed point by point along the segments."""

import math

import numpy as np

from core.plan import watch
from core.plan.planning import RIM_OFFSET
from core.plan.watch import Capsules
from core.scene.primaries import AreaPrimary, PointPrimary, PrimaryArrays, SunPrimary


def _box_distance(points, lo, hi):
    """Distance of each point to the box [lo, hi]."""
    return np.linalg.norm(np.maximum(np.maximum(lo - points, points - hi), 0.0), axis=-1)


def _sampled(a, b, n=4001):
    t = np.linspace(0.0, 1.0, n)[:, None]
    return a + t * (b - a)


def test_touches_never_misses_a_box_within_the_radius_and_finds_none_far_beyond():
    rng = np.random.default_rng(3)
    checked_near = checked_far = 0
    for _ in range(1500):
        a, b = rng.uniform(-2, 2, 3), rng.uniform(-2, 2, 3)
        if rng.random() < 0.2:  # along an axis: the slab test's flat case
            b = a.copy()
            b[rng.integers(3)] += rng.uniform(-3, 3)
        r = rng.uniform(0.01, 0.5)
        c, half = rng.uniform(-2, 2, 3), rng.uniform(0.05, 0.6, 3)
        lo, hi = c - half, c + half
        step = np.linalg.norm(b - a) / 4000
        d = _box_distance(_sampled(a, b), lo, hi).min()
        got = Capsules(a[None], b[None], np.array([r])).touches(lo, hi)
        if d <= r:  # the capsule reaches the box: always seen
            assert got
            checked_near += 1
        # Beyond the box grown by r on every side (and its corners' √3): never seen.
        if d > math.sqrt(3.0) * r + step:
            assert not got
            checked_far += 1
    assert checked_near > 60 and checked_far > 60


def test_empty_capsules_touch_nothing_and_join_skips_empties():
    e = Capsules.empty()
    assert not e.touches((-1, -1, -1), (1, 1, 1))
    one = Capsules(np.zeros((1, 3)), np.ones((1, 3)), np.array([0.1]))
    assert len(Capsules.join([e, one, e])) == 1


def test_a_light_to_lens_capsule_holds_the_cone_to_the_lens_and_a_sun_comes_from_afar():
    # A point light of radius 0.2 at the origin, a lens R 0.5 at 3 along z; a sun
    # travelling −z over the same lens.
    origins = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
    caps = watch.light_to_lens(
        origins, np.array([0.2, 0.0]), np.array([False, True]), [[0, 0, 3.0]], [0.5], 100.0
    )
    assert len(caps) == 2
    point = Capsules(caps.a[:1], caps.b[:1], caps.radius[:1])
    # The cone of lines from the light's disc to the lens: at z = 1.5 within 0.35 of the axis.
    assert point.touches((0.34, 0.0, 1.5), (0.34, 0.0, 1.5))
    assert not point.touches((0.0, 0.0, 3.8), (0.1, 0.1, 4.0))  # beyond the lens
    sun = Capsules(caps.a[1:], caps.b[1:], caps.radius[1:])
    assert sun.touches((0.4, 0.0, 50.0), (0.4, 0.0, 50.0))  # high above, in the sun's way
    assert not sun.touches((0.0, 0.0, 1.0), (0.1, 0.1, 2.0))  # under the lens


def test_along_axes_holds_the_planners_rim_rays_both_ways_and_nothing_wider():
    center, radius, axis = np.array([1.0, 2.0, 3.0]), 0.25, np.array([0.0, 0.6, -0.8])
    caps = watch.along_axes([center], [radius], [axis], 40.0)
    side = np.cross(axis, (1.0, 0.0, 0.0))
    side /= np.linalg.norm(side)
    for s in (-30.0, -1.0, 0.5, 10.0, 39.0):  # a rim ray's point before and beyond
        p = center + s * axis + RIM_OFFSET * radius * side
        assert caps.touches(p, p)
    far = center + 5.0 * axis + 3.0 * radius * side  # 3 R off the axis
    assert not caps.touches(far, far)


def test_light_extents_of_each_kind():
    prim = PrimaryArrays.from_primaries(
        [
            PointPrimary(position=(1.0, 2.0, 3.0), power_w=10.0, radius=0.1),
            SunPrimary(direction=(0.0, 0.0, -1.0), strength=3.0, angle=0.01),
            AreaPrimary(
                position=(0.0, 0.0, 2.0),
                direction=(0.0, 0.0, -1.0),
                axis_x=(1.0, 0.0, 0.0),
                power_w=5.0,
                shape="RECTANGLE",
                size_x=0.6,
                size_y=0.8,
            ),
        ]
    )
    origins, sizes, suns = watch.light_extents(prim)
    assert suns.tolist() == [False, True, False]
    np.testing.assert_allclose(origins, [[1, 2, 3], [0, 0, -1], [0, 0, 2]])
    np.testing.assert_allclose(sizes, [0.1, 0.0, 0.5])  # the rectangle's half diagonal


def test_landings_and_bounding_sphere():
    pts = np.array([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 2.0, 0.0], [2.0, 2.0, 0.0]])
    c, r = watch.bounding_sphere(pts)
    np.testing.assert_allclose(c, [1, 1, 0])
    assert r == math.sqrt(2.0)
    caps = watch.landings([[1.0, 1.0, 3.0]], [0.5], [c], [r])
    assert caps.touches((1.9, 1.9, 0.05), (1.9, 1.9, 0.05))  # on the patch's corner
    assert not caps.touches((5.0, 5.0, 0.0), (5.0, 5.0, 0.0))


def test_touching_many_boxes_in_pieces_is_touches_box_by_box(monkeypatch):
    rng = np.random.default_rng(5)
    caps = Capsules(
        rng.uniform(-2, 2, (37, 3)), rng.uniform(-2, 2, (37, 3)), rng.uniform(0, 0.2, 37)
    )
    c, half = rng.uniform(-3, 3, (200, 3)), rng.uniform(0.01, 0.3, (200, 3))
    one_by_one = [caps.touches(lo, hi) for lo, hi in zip(c - half, c + half, strict=True)]
    monkeypatch.setattr(watch, "PAIRS_AT_ONCE", 100)  # a few boxes per pass
    got = caps.touching(c - half, c + half)
    assert got.tolist() == one_by_one and 20 < sum(one_by_one) < 180
