"""Live update's Exact profile while the user works (issue 27, bpy module): in
Blender's window a marble resting on a table, the lamp keyed to move: frame changes
show coarse tables (written into the same light, tree and image; the table within
1 % of the beam's flux and 5 % of the peak of the exact table of that geometry, the
row-by-row trace of `exact_profile`, not the code under test), the refine timer
once they stop makes the state a fresh Generate's; a render starting after a burst
of frame changes, and every frame it renders, sees the exact state."""

import time

import bpy
import numpy as np
import pytest
from blender_scene_helpers import (
    assert_profile_lights_are_generates,
    profile_light_states,
    resting_marble,
)
from profile_measures import compare, exact_near_table

from core.tiers import exact_profile as xp

pytestmark = pytest.mark.blender

R, N = 0.5, 1.5
CENTRE = np.array([0.0, 0.0, R])  # resting on the table z = 0
LAMP = {1: (1.0, 0.4, 5.0), 5: (-0.6, -0.9, 4.2)}


def _scene():
    sc, lamp = resting_marble(LAMP[1], radius=R, ior=N)
    for frame, loc in LAMP.items():
        lamp.location = loc
        lamp.keyframe_insert("location", frame=frame)
    sc.frame_start, sc.frame_end = 1, 5
    sc.frame_set(1)
    from lens_lights.core.tiers import exact_profile  # the extension's own tables

    exact_profile.cached_profile.cache_clear()  # (a former test's would be exact already)
    sc.lens_lights.live_update = True  # turned on: the exact state at once
    return sc, lamp


def _check_coarse_table(pixels, lamp_at):
    """The image's table (red × the energy's normalisation) against the exact
    near-field table of this geometry (D/R, the table met along the axis, by hand):
    every row's flux within 1 % of the beam's, the lit rows' peaks within 5 %."""
    exact, t_ref = exact_near_table(CENTRE, R, N, lamp_at)
    shown = xp.BeamProfile(
        exact.apex, exact.gamma_max_deg, exact.h_min, exact.h_max, pixels[..., 0] * t_ref
    )
    _l1, f_exact, p_exact, f_shown, p_shown = compare(exact, shown)
    assert np.max(np.abs(f_shown - f_exact)) <= 0.01 * exact.flux
    lit = f_exact >= 0.1 * exact.flux
    assert lit.sum() > 100
    assert np.max(np.abs(p_shown[lit] / p_exact[lit] - 1.0)) <= 0.05


def test_coarse_tables_while_working_then_the_timer_gives_generates_lights(
    empty_blend, interactive, monkeypatch
):
    live = interactive
    monkeypatch.setattr(live, "BURST_SECONDS", 1.0)  # (a busy machine: no early refine)
    sc, lamp = _scene()
    exact = profile_light_states()
    sc.frame_set(3)
    f = live.LAST_FIGURES
    assert "error" not in f and f["coarse"] == 1  # one light, its table not made yet
    assert bpy.app.timers.is_registered(live.refine)
    coarse = profile_light_states()
    (key,) = coarse
    assert coarse[key][0] == exact[key][0]  # the same light, tree and image: in place
    _check_coarse_table(coarse[key][3], lamp.location)
    sc.frame_set(3)  # the same inputs: nothing planned
    assert live.LAST_FIGURES.get("skipped") is True
    wait = live.refine()  # the burst is not over: the timer comes back later
    assert wait is not None and 0.0 < wait <= live.BURST_SECONDS
    time.sleep(live.BURST_SECONDS)
    assert live.refine() is None  # done: the timer stops
    f = live.LAST_FIGURES
    assert f["why"] == "refined" and f["coarse"] == 0
    refined = profile_light_states()
    assert refined[key][0] == exact[key][0]
    assert not np.array_equal(refined[key][3], coarse[key][3])
    assert_profile_lights_are_generates(refined)


def test_a_render_after_a_burst_of_frames_sees_the_exact_state(empty_blend, interactive):
    live = interactive
    sc, _lamp = _scene()
    for frame in (2, 3, 4):
        sc.frame_set(frame)
        assert live.LAST_FIGURES["coarse"] == 1
    live.on_render_start(sc)  # render_init: the exact tables before the first frame
    try:
        f = live.LAST_FIGURES
        assert f["why"] == "refined" and f["coarse"] == 0
        sc.frame_set(2)  # a frame the render changes to: never coarse
        assert live.LAST_FIGURES["coarse"] == 0
        rendered = profile_light_states()
    finally:
        live.on_render_end(sc)
    assert_profile_lights_are_generates(rendered)


def test_turning_live_update_off_or_saving_never_leaves_coarse_tables(
    empty_blend, interactive, tmp_path
):
    live = interactive
    sc, _lamp = _scene()
    sc.frame_set(3)
    assert live.LAST_FIGURES["coarse"] == 1
    sc.lens_lights.live_update = False  # off while the coarse state shows: refined first
    assert live.LAST_FIGURES["why"] == "refined" and live.LAST_FIGURES["coarse"] == 0
    assert_profile_lights_are_generates(profile_light_states())
    sc.lens_lights.live_update = True
    sc.frame_set(4)
    assert live.LAST_FIGURES["coarse"] == 1
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "saved.blend"))  # refined first
    assert live.LAST_FIGURES["why"] == "refined" and live.LAST_FIGURES["coarse"] == 0
    assert_profile_lights_are_generates(profile_light_states())


def test_a_light_planned_while_working_waits_for_the_refine_even_with_its_exact_table(
    empty_blend, interactive, monkeypatch
):
    """While the user works the lights' energies come from the coarse beam summary
    (`exact_profile.coarse_summaries`): back on frame 1, whose exact table was made
    when live update was turned on, the light reads that table, yet its energy is the
    coarse summary's (its flux within 1e-5 of the exact one's, the pixels normalised
    by it), so the refine still comes and makes the state a fresh Generate's, bit for
    bit in its energy."""
    live = interactive
    monkeypatch.setattr(live, "BURST_SECONDS", 0.0)
    sc, lamp = _scene()
    # a dim lamp: its lens light's energy below 1 W, where a write within 1e-6 W is
    # skipped as unchanged (`lights._put`): the refine must write it all the same
    lamp.data.energy = 5.0
    bpy.context.view_layer.update()
    assert live.refine() is None
    exact = profile_light_states()
    (key,) = exact
    assert exact[key][1][7] < 1.0
    sc.frame_set(3)
    sc.frame_set(1)  # the exact table of frame 1 is remembered
    f = live.LAST_FIGURES
    assert "error" not in f and f["coarse"] == 0 and f["coarse_energy"] is True
    assert bpy.app.timers.is_registered(live.refine)
    rough = profile_light_states()
    # the exact table, over the coarse summary's normalisation (as the energy is)
    np.testing.assert_allclose(rough[key][3], exact[key][3], rtol=1e-5)
    assert abs(rough[key][1][7] / exact[key][1][7] - 1.0) <= 1e-5
    assert live.refine() is None
    f = live.LAST_FIGURES
    assert f["why"] == "refined" and f["coarse"] == 0 and f["coarse_energy"] is False
    refined = profile_light_states()
    assert_profile_lights_are_generates(refined)
    fresh = profile_light_states()  # Generate's
    assert refined[key][1][7] == fresh[key][1][7] == exact[key][1][7]  # bit for bit


def _linking():
    """Each lens light's receiver and blocker collections: their names and members
    (object name, link state)."""
    out = {}
    for ob in bpy.data.objects:
        if not ob.lens_lights.is_lens_light or ob.type != "LIGHT":
            continue
        parts = []
        for coll in (ob.light_linking.receiver_collection, ob.light_linking.blocker_collection):
            # (a CollectionObject names no object: the same order as `objects`)
            members = (
                [] if coll is None else zip(coll.objects, coll.collection_objects, strict=True)
            )
            parts.append(
                (
                    None if coll is None else coll.name,
                    sorted((o.name, m.light_linking.link_state) for o, m in members),
                )
            )
        out[ob.lens_lights.source_light] = parts
    return out


def test_while_working_the_lights_keep_their_groups_until_the_refine(
    empty_blend, interactive, monkeypatch
):
    """A coarse update of the same lights leaves their linking as the last update
    made it (`figures["linking"] == "kept"`: no beams or groups planned while the
    user works); the refine links them again, as a fresh Generate does."""
    live = interactive
    monkeypatch.setattr(live, "BURST_SECONDS", 0.0)
    sc, _lamp = _scene()
    assert live.LAST_FIGURES["linking"] == "linked"  # turned on: exact, linked
    linked = _linking()
    assert linked and all(parts[0][0] is not None for parts in linked.values())
    for frame in (2, 3):
        sc.frame_set(frame)
        f = live.LAST_FIGURES
        assert f["coarse"] == 1 and f["linking"] == "kept"
        assert _linking() == linked
    assert live.refine() is None
    f = live.LAST_FIGURES
    assert f["why"] == "refined" and f["linking"] == "linked"
    refined = _linking()
    from lens_lights.blender.commands.generate import generate

    sc.lens_lights.live_update = False
    generate(bpy.context)
    assert _linking() == refined
