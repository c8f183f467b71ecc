"""The one pipeline Generate, Bake and Live update share: the options from the scene's
settings (`options_from`) and the plan of one depsgraph (`plan_scene`: read → phase 1 →
plan → the Caustic layer's stage). Nothing here changes the file; what each command
does around it (which depsgraph it reads, a probe render or not, how it builds) is
its own:

* Generate (`generate.py`): the render depsgraph of the context scene and view layer
  (`render_probe.as_rendered`), then Clear and build;
* Bake (`bake.py`): the same on every frame of the range (or always the viewport's
  with the render rules), then the keyed lights;
* Live update (`live_update.py`): the depsgraph its handler is handed, planned only
  when the read differs from the last update's (`plan_scene`'s ``unless``), then
  applied to the existing lens lights in place.
"""

from __future__ import annotations

import time

from ...core.phase1.all_lights import compute_phase1_primaries
from ...core.plan.planning import PRESELECT_FACTOR, plan_result
from ...core.tiers import resolve_energy_model
from ..read.scene import read_depsgraph
from . import layer_stage


def options_from(settings) -> dict:
    """The planning options of `settings` (``scene.lens_lights``): the tier to build
    (AUTO → the most accurate for the scene's engine; Exact profile outside Cycles →
    Fitted, with ``model_warning`` for the report), the cut-off, the maximum number of
    lights, the spot blend, the merge distance (None: no merging)."""
    merge = bool(getattr(settings, "use_merge", False))
    model, model_warning = resolve_energy_model(
        settings.energy_model, settings.id_data.render.engine
    )
    return dict(
        energy_model=model,
        model_warning=model_warning,
        min_brightness=float(settings.min_brightness),
        max_lights=int(settings.max_lights),
        spot_blend=float(settings.spot_blend),
        merge_distance=float(settings.merge_distance) if merge else None,
    )


def plan_scene(
    depsgraph,
    scene,
    options: dict,
    *,
    timings: dict | None = None,
    unless=None,
    layer_live=None,
    rays=None,
):
    """Plan `scene` as `depsgraph` shows it; changes nothing. Read it
    (`read.scene.read_depsgraph`: the rays that keep a beam's spot clear of the geometry
    behind its lens are cast against the geometry read from the same depsgraph), run
    phase 1 for every light type (`compute_phase1_primaries`), then
    `planning.plan_result` (pre-select the ``PRESELECT_FACTOR × max_lights`` strongest
    sources, merging nearby ones if asked, and plan their lights), and the Caustic
    layer's stage (`layer_stage.prepare`: the receivers and the layer's bake when the
    tier is the layer's). Returns a `planning.Work`; seconds per step in its timings
    (`timings`, filled in place when given).

    `unless(read)`, when given, is asked right after the read: True stops there (the
    read's occluders released) and None is returned. ``layer_live``: live update's
    coarse layer state (`layer_stage.prepare`; with it, the Fitted spots standing for
    the layer's sources skip their near-field fits while the layer is the coarse
    one); ``rays``: its planner rays of the
    last updates (`core.plan.ray_memo.RayMemo`)."""
    timings = {} if timings is None else timings
    t = time.perf_counter()
    read = read_depsgraph(depsgraph, scene)
    timings["read"] = time.perf_counter() - t
    if unless is not None and unless(read):
        read.occluders.release()
        return None
    t = time.perf_counter()
    result = compute_phase1_primaries(read.arrays, read.primary_lights)
    timings["phase1"] = time.perf_counter() - t

    def plan(near_fits=True, release=True):
        return plan_result(
            read,
            result,
            options,
            timings,
            preselect_factor=PRESELECT_FACTOR,
            rays=rays,
            near_fits=near_fits,
            release=release,
        )

    if layer_live is None:
        return layer_stage.prepare(depsgraph, plan(), options)
    # A coarse layer's spots only rank its sources: no near-field fits (the full
    # plan when the coarse layer cannot stand for the full one after all).
    work = plan(near_fits=False, release=False)
    try:
        return layer_stage.prepare(depsgraph, work, options, layer_live, plan)
    finally:
        read.occluders.release()
