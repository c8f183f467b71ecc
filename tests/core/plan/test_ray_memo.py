"""Live update's planner rays remembered (`ray_memo.RayMemo`, issue 27): a plan made
with the memo is the plan made without it (every light's fields equal), a pair whose
lens and axis did not change is not cast again (the rays the geometry is asked for,
counted), also when the scene's size (the casts' limit) moves with the lamp, and a
moved floor, wall or sphere casts every pair again."""

import math
from types import SimpleNamespace

import numpy as np
import pytest
from planning_reference import Batched

from core.phase1.point_lights import compute_phase1
from core.plan.planning import SUNK_PROBES, plan_result
from core.plan.ray_memo import RayMemo
from core.scene.arrays import SceneArrays
from core.scene.model import Light, Scene, Sphere, Surface
from core.scene.primaries import PrimaryLight
from core.tiers.near_field import SIDE_AZIMUTHS, SIDE_POLAR_DEG

R = 0.5
OPTIONS = dict(
    energy_model="EXACT_PROFILE",
    min_brightness=0.0,
    max_lights=64,
    spot_blend=0.0,
    merge_distance=None,
)


class CountingGeometry(Batched):
    """Spheres and planes {x : n·x = d} with the arrays `RayMemo.start` compares (a
    plane's offset stands in as its instance matrix), first hits by hand
    (`planning_reference.Batched`), the rays asked for counted."""

    def __init__(self, centers, radii, planes):
        super().__init__(centers, radii, planes)
        self.matrices = np.array([np.eye(4) * d for _, d in self.planes]).reshape(-1, 4, 4)
        self.box_lo = np.array([-10 * np.ones(3)] * len(self.planes)).reshape(-1, 3)
        self.box_hi = -self.box_lo
        self.source_index = np.arange(len(self.planes))
        self.rays = 0

    def first_hits(self, origins, directions, limit):
        origins = np.asarray(origins, float)
        self.rays += origins.shape[0] * origins.shape[1]
        return super().first_hits(origins, directions, limit)


def _read(lamps, floor=0.0, wall=3.0, blocker=(5.0, 5.0, 0.5), size=None):
    """Four marbles resting on the floor z = `floor` (a wall x = `wall` beside them,
    a fifth sphere at `blocker`), lit by the point lights `lamps` (the scene's size
    grows with the lamps' reach, as a read's)."""
    centres = [(x, y, floor + R) for x in (0.0, 1.5) for y in (0.0, 1.5)]
    glass = Surface(transmission=1.0, ior=1.5)
    scene = Scene(
        lights=[Light(position=p, brightness=100.0) for p in lamps],
        objects=[Sphere(center=c, radius=R, surface=glass) for c in centres]
        + [Sphere(center=blocker, radius=R, surface=Surface(transmission=0.0))],
    )
    arrays = SceneArrays.from_scene(scene)
    spheres = np.array([*centres, blocker])
    occ = CountingGeometry(
        spheres, np.full(len(spheres), R), [((0, 0, 1), floor), ((1, 0, 0), wall)]
    )
    read = SimpleNamespace(
        arrays=arrays,
        primaries=[PrimaryLight(100.0) for _ in lamps],
        lens_optics=None,
        light_sources=[f"lamp {j}" for j in range(len(lamps))],
        sphere_sources=[f"marble {i}" for i in range(len(spheres))],
        lens_candidates=None,
        scene_size=size or float(np.max(np.abs(np.array(lamps)))) + 10.0,
        bounds=(np.full(3, -10.0), np.full(3, 10.0)),
        occluders=occ,
    )
    return read, compute_phase1(scene)


def _plan(read, result, rays=None):
    work = plan_result(read, result, OPTIONS, rays=rays)
    return {(p.light_name, p.lens_name): p.light for p in work.plan.lights}


def _same_lights(a, b):
    assert a.keys() == b.keys()
    for k, la in a.items():
        lb = b[k]
        for name in ("energy_w", "location", "direction", "radius", "receiver_distance"):
            assert getattr(la, name) == pytest.approx(getattr(lb, name), rel=1e-12), (k, name)
        assert la.table_key == lb.table_key
        pa, pb = la.profile, lb.profile
        ra, rb = pa.get("receivers", ()), pb.get("receivers", ())
        for (na, oa), (nb, ob) in zip(ra, rb, strict=True):
            np.testing.assert_allclose(na, nb, rtol=1e-12)
            assert oa == pytest.approx(ob, rel=1e-12)


LAMP_A = [(4.0, 1.0, 6.0), (3.2, 0.4, 5.5)]  # the lamp moving (two frames)
LAMP_B = (-2.0, -1.0, 4.0)  # the one resting


def test_an_unchanged_pair_is_not_cast_again_and_the_plan_is_the_one_without_memo():
    memo = RayMemo()
    read, result = _read([LAMP_A[0], LAMP_B])
    first = _plan(read, result, memo)
    assert read.occluders.rays > 0 and len(first) == 8  # two lamps × four marbles
    _same_lights(first, _plan(*_read([LAMP_A[0], LAMP_B])))
    # the next frame: lamp A moved, lamp B's four pairs the same
    read, result = _read([LAMP_A[1], LAMP_B])
    cast_before = memo.cast
    got = _plan(read, result, memo)
    fresh_read, fresh_result = _read([LAMP_A[1], LAMP_B])
    _same_lights(got, _plan(fresh_read, fresh_result))
    # only lamp A's pairs cast: half of the pairs' bundles (none of the sunk lens
    # probes: the marbles did not move); lamp B's receiver and free distance bundles
    # looked up, its side planes (derived from their hits alone) not even that
    probes, side = len(SUNK_PROBES), len(SIDE_POLAR_DEG) * SIDE_AZIMUTHS
    pairs = cast_before - probes  # the first plan: every pair's bundles and the probes
    assert memo.cast == pairs // 2
    assert memo.reused == 4 * (pairs // 8 - side) + probes
    assert read.occluders.rays < 0.5 * fresh_read.occluders.rays
    # the same inputs again: nothing cast at all
    read, result = _read([LAMP_A[1], LAMP_B])
    _same_lights(_plan(read, result, memo), got)
    assert read.occluders.rays == 0


@pytest.mark.parametrize(
    "moved",
    [dict(floor=-0.2), dict(wall=2.4), dict(blocker=(5.0, 4.0, 0.5))],
    ids=["floor", "wall", "sphere"],
)
def test_moved_geometry_casts_every_pair_again(moved):
    memo = RayMemo()
    _plan(*_read([LAMP_A[0], LAMP_B]), memo)
    read, result = _read([LAMP_A[0], LAMP_B], **moved)
    got = _plan(read, result, memo)
    fresh_read, fresh_result = _read([LAMP_A[0], LAMP_B], **moved)
    expected = _plan(fresh_read, fresh_result)
    _same_lights(got, expected)
    assert read.occluders.rays == fresh_read.occluders.rays  # all of it cast again
    if "floor" in moved:  # the receivers moved with it: the lights changed
        key = ("lamp 1", "marble 0")
        assert not math.isclose(
            got[key].receiver_distance, _plan(*_read([LAMP_A[0], LAMP_B]))[key].receiver_distance
        )


def test_a_longer_limit_than_a_bundle_was_cast_with_casts_it_again():
    """The receivers' and free distances' casts reach as far as the scene's size
    (which grows with a lamp dragged away): a bundle asked within more than the
    headroom it was cast with is cast again; the side planes' and the probes' reach
    (the lens' radius) is the same."""
    memo = RayMemo()
    _plan(*_read([LAMP_A[0], LAMP_B], size=10.0), memo)
    read, result = _read([LAMP_A[0], LAMP_B], size=10.0 * 2.5)
    got = _plan(read, result, memo)
    fresh_read, fresh_result = _read([LAMP_A[0], LAMP_B], size=10.0 * 2.5)
    _same_lights(got, _plan(fresh_read, fresh_result))
    assert memo.cast == 2 * 8  # every pair's receiver and free distance bundle


def test_clear_forgets_what_start_cannot_see():
    memo = RayMemo()
    _plan(*_read([LAMP_A[0], LAMP_B]), memo)
    assert len(memo)
    memo.clear()  # (live update: a mesh reshaped within its box)
    read, result = _read([LAMP_A[0], LAMP_B])
    _plan(read, result, memo)
    fresh_read, fresh_result = _read([LAMP_A[0], LAMP_B])
    _plan(fresh_read, fresh_result)
    assert read.occluders.rays == fresh_read.occluders.rays


def test_occluders_without_geometry_arrays_are_never_remembered():
    class Bare:
        def first_hits(self, origins, directions, limit):
            return np.full(np.asarray(origins).shape[:2], np.inf)

    memo = RayMemo()
    for _ in range(2):
        memo.start(Bare())
        got = memo.view(Bare()).first_hits(np.zeros((2, 3, 3)), np.eye(3)[:2], 10.0)
        assert got.shape == (2, 3) and memo.cast == 2 and memo.reused == 0
    assert len(memo) == 0
