"""The columns planning path (`planning.plan_result`: the tiers' table makers, the
rays of every kept source in one batched cast) against the per-source path
(tests/helpers/planning_reference.py's `plan_result_per_source`: every source's light and
rays one at a time, as planning was before): the same lights, fields to float tolerance, and the
same skipped pairs, on random scenes with every tier, cut-offs, caps, merging,
other primaries' emission and radius, tinted glass, and a floor and a wall near
the lenses (near-field fits, spots pulled in); plus the batched sphere and box
ray tests against the per-bundle ones."""

import dataclasses
import math
from types import SimpleNamespace

import numpy as np
import pytest
from planning_reference import Batched, PlanesAndSpheres, plan_result_per_source
from random_scenes import random_scene

from core.lens.glass import LensOptics
from core.phase1.point_lights import Phase1Result, compute_phase1, take
from core.phase1.skip_reasons import Reason
from core.plan.planning import plan_result
from core.scene.arrays import SceneArrays
from core.scene.primaries import PrimaryLight
from core.scene.ray_hits import box_entries, box_entries_bundles, sphere_hits, sphere_hits_bundles

MODELS = ("THESIS", "PHYSICAL", "FITTED", "EXACT_PROFILE", "CAUSTIC_LAYER")
#: numpy's vectorised arithmetic may differ from the per-source path in the last bits.
RTOL = 1e-9


def make_read(seed, occluder_class, *, other_primaries=False):
    """A scene read (`read.scene.read_depsgraph`'s fields) of a random scene with
    a floor below the lowest sphere's centre and walls, random primaries'
    powers, radii and colours, and tinted, absorbing, partly transmitting glass."""
    scene = random_scene(seed, n_lights=3, n_spheres=30, spread=5.0)
    arrays = SceneArrays.from_scene(scene)
    result = compute_phase1(scene)
    rng = np.random.default_rng(seed + 100)
    if other_primaries:  # spot, sun and area lights: emission and radius per source
        n = len(result.table)
        table = dataclasses.replace(
            result.table,
            emission=rng.uniform(0.0, 3.0, n),
            source_radius=np.where(rng.uniform(size=n) < 0.5, np.nan, rng.uniform(0.0, 0.3, n)),
        )
        result = Phase1Result(table, result.skip_table, arrays)
    nl, ns = len(arrays.light_position), len(arrays.center)
    primaries = [
        PrimaryLight(
            float(rng.uniform(50, 2000)),
            float(rng.uniform(0, 0.2)),
            tuple(rng.uniform(0.2, 1, 3).tolist()),
        )
        for _ in range(nl)
    ]
    optics = [
        LensOptics(
            float(rng.choice([1.0, 0.8, 0.3])),
            tuple(rng.uniform(0.5, 1, 3).tolist()),
            tuple(rng.uniform(0, 0.3, 3).tolist()),
        )
        for _ in range(ns)
    ]
    c, r = arrays.center, np.abs(arrays.radius)
    low = float(np.min(c[:, 2] - 1.5 * r))
    pts = np.concatenate([arrays.light_position, c - r[:, None], c + r[:, None]])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    # a floor, a far wall, and a wall just behind the collimated lens's front vertex
    # (random_scene's light at x = 100, lens at x = 101.5): its spot is pulled in
    planes = [((0.0, 0.0, 1.0), low), ((1.0, 0.0, 0.0), float(hi[0]) + 0.5)]
    occ = occluder_class(c, r, planes + [((1.0, 0.0, 0.0), 100.3)])
    read = SimpleNamespace(
        arrays=arrays,
        primaries=primaries,
        lens_optics=optics,
        light_sources=[f"Lamp {j}" for j in range(nl)],
        sphere_sources=[f"Ball {i}" for i in range(ns)],
        scene_size=float(np.linalg.norm(hi - lo)),
        bounds=(tuple(lo.tolist()), tuple(hi.tolist())),
        occluders=occ,
    )
    return read, result


def assert_same_light(got, want, where):
    assert type(got) is type(want), where
    for f in dataclasses.fields(want):
        if f.name.startswith("_"):  # the Exact profile's table maker (a closure)
            continue
        a, b = getattr(got, f.name), getattr(want, f.name)
        if isinstance(b, float):
            assert a == pytest.approx(b, rel=RTOL, abs=1e-300, nan_ok=True), (where, f.name)
        elif isinstance(b, tuple):
            assert a == pytest.approx(b, rel=RTOL, abs=1e-12), (where, f.name)
        elif isinstance(b, dict):
            assert a == pytest.approx(b, rel=RTOL), (where, f.name)
        else:
            assert a == b, (where, f.name)


def assert_same_work(got, want, where):
    g, w = got.plan, want.plan
    assert len(g.lights) == len(w.lights), where
    for k, (p, q) in enumerate(zip(g.lights, w.lights, strict=True)):
        at = f"{where} light {k}"
        assert (p.light_name, p.lens_name) == (q.light_name, q.lens_name), at
        assert (p.source.light, p.source.lens) == (q.source.light, q.source.lens), at
        assert_same_light(p.light, q.light, at)
    assert len(g.skipped) == len(w.skipped), where
    for a, b in zip(g.skipped, w.skipped, strict=True):
        assert (a[0], a[1], a.code) == (b[0], b[1], b.code), where
        assert a.details == pytest.approx(b.details, rel=RTOL), where
    assert got.read.occluders.released


OPTIONS = [
    dict(min_brightness=0.0, max_lights=64, merge_distance=None),
    dict(min_brightness=0.05, max_lights=7, merge_distance=None),
    dict(min_brightness=0.0, max_lights=12, merge_distance=0.8),
]


@pytest.mark.parametrize("model", MODELS)
@pytest.mark.parametrize("occluder_class", [PlanesAndSpheres, Batched])
def test_columns_plan_equals_the_per_source_plan(model, occluder_class):
    near = pulled = 0
    for seed in range(3):
        for k, opts in enumerate(OPTIONS):
            options = dict(opts, energy_model=model, spot_blend=0.3)
            read, result = make_read(seed, occluder_class, other_primaries=seed == 2)
            want = plan_result_per_source(read, result, options)
            read, result = make_read(seed, occluder_class, other_primaries=seed == 2)
            got = plan_result(read, result, options)
            assert_same_work(got, want, f"{model} seed {seed} options {k}")
            assert got.plan.lights, (seed, k)
            near += sum("near field" in p.light.note for p in want.plan.lights)
            pulled += sum("pulled in" in p.light.note for p in want.plan.lights)
    if model in ("FITTED", "CAUSTIC_LAYER"):
        assert near > 0 and pulled > 0  # the receiver fits and the free distance ran


def test_merged_cut_off_and_beyond_maximum_are_reported_alike():
    seen_codes, merged = set(), 0
    for max_lights, min_brightness in ((200, 0.0), (3, 0.0), (200, 0.2)):
        options = dict(
            energy_model="FITTED",
            spot_blend=0.3,
            min_brightness=min_brightness,
            max_lights=max_lights,
            merge_distance=6.0,
        )
        read, result = make_read(1, Batched)
        want = plan_result_per_source(read, result, options)
        read, result = make_read(1, Batched)
        got = plan_result(read, result, options)
        assert_same_work(got, want, f"merged, max {max_lights}, cut-off {min_brightness}")
        seen_codes |= {p.code for p in want.plan.skipped}
        merged += sum("merged: energy" in p.light.note for p in want.plan.lights)
    assert merged > 0
    assert {Reason.BEYOND_MAXIMUM, Reason.DIMMER_THAN_CUTOFF} <= seen_codes


def test_batched_sphere_and_box_hits_equal_the_per_bundle_ones():
    rng = np.random.default_rng(5)
    C = rng.uniform(-20, 20, (500, 3)) + 1e4  # far from the world origin
    R = rng.uniform(0.05, 1.5, 500)
    lo = rng.uniform(-20, 15, (30, 3)) + 1e4
    hi = lo + rng.uniform(0.1, 5, (30, 3))
    B = 60
    o0 = rng.uniform(-20, 20, (B, 3)) + 1e4
    origins = o0[:, None] + rng.uniform(-0.5, 0.5, (B, 5, 3))
    d = rng.normal(size=(B, 3))
    d[:5, 1:] = 0.0  # along an axis: the slab test's divisions by zero
    d /= np.linalg.norm(d, axis=1)[:, None]
    got = sphere_hits_bundles(C, R, origins, d)
    enter, hit = box_entries_bundles(lo, hi, origins, d, 30.0)
    assert np.isfinite(got).sum() > 20 and hit.sum() > 20
    for b in range(B):
        np.testing.assert_allclose(got[b], sphere_hits(C, R, origins[b], d[b]), rtol=1e-12)
        e, h = box_entries(lo, hi, origins[b], d[b], 30.0)
        np.testing.assert_array_equal(hit[b], h)
        np.testing.assert_allclose(enter[b][h], e[h], rtol=1e-12)
    assert sphere_hits_bundles(C, R, np.zeros((0, 5, 3)), np.zeros((0, 3))).shape == (0, 5)
    assert math.isinf(sphere_hits_bundles(C[:0], R[:0], origins[:1], d[:1]).min())


@pytest.mark.parametrize("layout", ["cloud", "plane", "line", "stacked"])
def test_grouped_sphere_hits_equal_the_per_bundle_ones(layout, monkeypatch):
    """From `CLUSTER_FROM` spheres on the bundles meet groups of spheres first: the
    hits are those of `sphere_hits` bundle by bundle (every sphere a ray can hit is
    in a group the line test keeps), in a cloud, a flat grid, a line and with many
    spheres at one centre, far from the world origin."""
    from core.scene import ray_hits

    rng = np.random.default_rng(11)
    n = ray_hits.CLUSTER_FROM + 900
    if layout == "cloud":
        C = rng.uniform(-30, 30, (n, 3))
    elif layout == "plane":
        g = np.stack(np.meshgrid(np.arange(70), np.arange(72), indexing="ij"), -1)
        C = np.column_stack([g.reshape(-1, 2)[:n] * 0.8, np.zeros(n)])
    elif layout == "line":
        C = np.column_stack([np.linspace(-50, 50, n), np.zeros(n), np.zeros(n)])
    else:
        C = np.repeat(rng.uniform(-5, 5, (n // 100 + 1, 3)), 100, axis=0)[:n]
    C = C + 1e4
    R = rng.uniform(0.05, 0.6, n)
    B = 40
    pick = rng.choice(n, B)
    d = rng.normal(size=(B, 3))
    d[:4, 1:] = 0.0
    d /= np.linalg.norm(d, axis=1)[:, None]
    # bundles starting just outside a sphere (as planning's), and some from afar
    o0 = C[pick] + (R[pick] * 1.01)[:, None] * d
    o0[::5] -= 40.0 * d[::5]
    origins = o0[:, None] + rng.uniform(-0.2, 0.2, (B, 5, 3))
    got = ray_hits.sphere_hits_bundles(C, R, origins, d)
    assert np.isfinite(got).sum() > 20
    for b in range(B):
        want = sphere_hits(C, R, origins[b], d[b])
        np.testing.assert_allclose(got[b], want, rtol=1e-12, atol=1e-12)
    monkeypatch.setattr(ray_hits, "CLUSTER_FROM", n + 1)  # every pair: the same numbers
    np.testing.assert_array_equal(got, ray_hits.sphere_hits_bundles(C, R, origins, d))
    order, starts, mid, rad = ray_hits.sphere_clusters(C, R)
    assert np.array_equal(np.sort(order), np.arange(n))
    cell = np.repeat(np.arange(len(starts)), np.diff(np.append(starts, n)))
    assert np.all(
        np.linalg.norm(C[order] - mid[cell], axis=1) + R[order] <= rad[cell] * (1 + 1e-12)
    )


@pytest.mark.parametrize("model", MODELS)
def test_nothing_kept_is_planned_alike(model):
    """Every source under the cut-off, a maximum of 0 lights, no source at all."""
    for seed, min_brightness, max_lights in ((0, 1e9, 5), (1, 0.0, 0)):
        options = dict(
            energy_model=model,
            spot_blend=0.3,
            min_brightness=min_brightness,
            max_lights=max_lights,
            merge_distance=None,
        )
        read, result = make_read(seed, Batched)
        want = plan_result_per_source(read, result, options)
        read, result = make_read(seed, Batched)
        got = plan_result(read, result, options)
        assert_same_work(got, want, f"{model} cut-off {min_brightness} max {max_lights}")
        assert got.plan.skipped
    read, result = make_read(0, Batched)
    none = Phase1Result(take(result.table, np.zeros(0, dtype=np.int64)), result.skip_table, None)
    got = plan_result(read, none, options)
    assert got.plan.lights == [] and got.plan.skipped == [] and read.occluders.released
