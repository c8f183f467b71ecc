"""The reference the columns path of `core.plan.planning.plan_result` is tested
against (tests/core/plan/test_planning_speed_equivalence.py): the same pre-selection and plan,
source by source."""

from __future__ import annotations

import time
from types import SimpleNamespace

import numpy as np

from core.phase1.point_lights import Phase1Result
from core.phase1.skip_reasons import Reason, SkippedPair
from core.plan.planning import (
    PRESELECT_FACTOR,
    Work,
    free_distance_behind,
    may_be_beam,
    plan_lights,
    receiver_distance,
    select_sources,
    sunk_lenses,
)
from core.scene.ray_hits import sphere_hits, sphere_hits_bundles
from core.tiers import PHYSICAL, THESIS


def plan_result_per_source(
    read,
    result: Phase1Result,
    options: dict,
    timings: dict | None = None,
    *,
    preselect_factor: int = PRESELECT_FACTOR,
) -> Work:
    """`planning.plan_result` source by source: the tier's per-source maker
    (`plan_lights`), the rays one source at a time (`free_distance_behind`,
    `receiver_distance`)."""
    timings = {} if timings is None else timings
    t = time.perf_counter()
    selection = select_sources(
        result,
        read.arrays.light_brightness,
        max_lights=options["max_lights"],
        merge_distance=options["merge_distance"],
        preselect_factor=preselect_factor,
    )
    timings["budget"] = time.perf_counter() - t
    t = time.perf_counter()
    model = options["energy_model"]
    common = dict(
        optics=read.lens_optics,
        light_names=read.light_sources,
        lens_names=read.sphere_sources,
        min_brightness=options["min_brightness"],
        max_lights=options["max_lights"],
        spot_blend=options["spot_blend"],
        scene_size=read.scene_size,
        scene_bounds=read.bounds,
    )
    first = plan_lights(
        SimpleNamespace(sources=selection.sources, skipped=[]),
        read.primaries,
        model,
        energy_scale=selection.scale,
        **common,
    )
    rows = {id(src): k for k, src in enumerate(selection.sources)}
    # the same rule as the columns path: a lens another surface cuts into gets no light
    sunk = sunk_lenses(
        read.occluders,
        [p.source.lens_center for p in first.lights],
        [p.source.lens_radius for p in first.lights],
    )
    sunk_pairs = [
        SkippedPair(p.light_name, p.lens_name, Reason.SUNK)
        for p, s in zip(first.lights, sunk, strict=True)
        if s
    ]
    chosen = [p.source for p, s in zip(first.lights, sunk, strict=True) if not s]
    size = read.scene_size

    def far_limit(src):
        if model in (THESIS, PHYSICAL) and not may_be_beam(src, read.bounds, size):
            return None
        return free_distance_behind(read.occluders, src, size)

    def receiver_limit(src):
        return receiver_distance(read.occluders, src, size)

    plan = plan_lights(
        SimpleNamespace(sources=chosen, skipped=[]),
        read.primaries,
        model,
        far_limit=far_limit,
        receiver_limit=receiver_limit,
        energy_scale=[selection.scale[rows[id(s)]] for s in chosen],
        **common,
    )
    plan.skipped[:0] = first.skipped + sunk_pairs
    timings["plan"] = time.perf_counter() - t
    read.occluders.release()  # the depsgraph may go away after this
    return Work(read, result, selection, plan, timings)


class PlanesAndSpheres:
    """Exact first hits against spheres and planes {x : n·x = d} (hit from either
    side), bundle by bundle (`first_hit` only: planning loops over the bundles)."""

    def __init__(self, centers, radii, planes):
        self.centers = np.asarray(centers, dtype=float).reshape(-1, 3)
        self.radii = np.asarray(radii, dtype=float)
        self.planes = [(np.asarray(n, dtype=float), float(d)) for n, d in planes]
        self.released = False

    def first_hit(self, origins, direction, limit):
        origins = np.asarray(origins, dtype=float).reshape(-1, 3)
        d = np.asarray(direction, dtype=float)
        d = d / np.linalg.norm(d)
        best = sphere_hits(self.centers, self.radii, origins, d)
        for n, off in self.planes:
            dn = float(n @ d)
            if dn == 0.0:
                continue
            t = (off - origins @ n) / dn
            best = np.minimum(best, np.where(t > 1e-12, t, np.inf))
        return np.where(best <= limit, best, np.inf)

    def release(self):
        self.released = True


class Batched(PlanesAndSpheres):
    """The same geometry with a batched `first_hits` (spheres by
    `sphere_hits_bundles`): planning casts every kept source's rays at once."""

    def first_hits(self, origins, directions, limit):
        origins = np.asarray(origins, dtype=float)
        d = np.asarray(directions, dtype=float)
        d = d / np.linalg.norm(d, axis=1)[:, None]
        best = sphere_hits_bundles(self.centers, self.radii, origins, d)
        for n, off in self.planes:
            dn = d @ n
            with np.errstate(divide="ignore", invalid="ignore"):
                t = (off - origins @ n) / dn[:, None]
            best = np.minimum(best, np.where((dn[:, None] != 0) & (t > 1e-12), t, np.inf))
        return np.where(best <= limit, best, np.inf)
