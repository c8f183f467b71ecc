"""Live update's Caustic layer (issue 27, bpy module): in Blender's window a coarse
layer while frames follow each other, written into the same objects and meshes, and
the full one once they stop (the timer's `refine`) or before a render, equal to a
fresh Generate; in background every update is the full layer, also in place."""

import time

import bpy
import numpy as np
import pytest
from blender_scene_helpers import (
    add_point_light,
    add_sphere,
    basic_scene,
    generate,
    glass_material,
    layer_states,
    lens_lights,
    set_engine,
)
from measuring_scene import new_material

pytestmark = [pytest.mark.blender, pytest.mark.usefixtures("auto_builds_lights")]


def _live():
    from lens_lights.blender.commands import live_update

    return live_update


def _scene(lamp=None, keys=None):
    """The Caustic layer in EEVEE, live update on at frame 1 (the full layer); the
    lamp (default: `basic_scene`'s) keyed at frames 1 and 5 (`keys`)."""
    if lamp is None:
        _, lamp = basic_scene()
    keys = keys or {1: (0.0, 0.0, 4.5), 5: (0.8, 0.4, 4.3)}
    for frame, loc in keys.items():
        lamp.location = loc
        lamp.keyframe_insert("location", frame=frame)
    scene = bpy.context.scene
    set_engine("BLENDER_EEVEE")
    scene.lens_lights.energy_model = "CAUSTIC_LAYER"
    scene.frame_start, scene.frame_end = 1, 5
    scene.frame_set(1)
    scene.lens_lights.live_update = True  # the full layer, at once
    return scene


def _layers():
    """Layer meshes (not the reflection copies): name → (positions, irradiance,
    object and mesh pointers)."""
    return layer_states(bpy.data.objects)


def _pointers(state):
    return {k: v[2:] for k, v in state.items()}


def _equal_to_generate(state):
    bpy.context.scene.lens_lights.live_update = False
    level, _message, _ = generate()
    assert level == "INFO"
    fresh = _layers()
    assert sorted(state) == sorted(fresh)
    for name, (co, irr, *_p) in fresh.items():
        assert np.array_equal(state[name][0], co) and np.array_equal(state[name][1], irr)


def test_coarse_while_working_then_the_timer_gives_generates_layer(
    empty_blend, interactive, monkeypatch
):
    live = interactive
    monkeypatch.setattr(live, "BURST_SECONDS", 1.0)  # (a busy machine: no early refine)
    scene = _scene()
    full = _layers()
    scene.frame_set(3)
    f = live.LAST_FIGURES
    assert f["coarse"] is True and "error" not in f
    assert f["traced"] == 1  # one pair, traced on the coarse grid
    assert bpy.app.timers.is_registered(live.refine)
    coarse = _layers()
    assert _pointers(coarse) == _pointers(full)  # the same objects and meshes
    for name, (co, irr, *_p) in coarse.items():  # the full layer's rasters: irradiance only
        assert np.array_equal(co, full[name][0]) and not np.array_equal(irr, full[name][1])
    scene.frame_set(3)  # the same inputs: nothing planned, nothing traced
    assert live.LAST_FIGURES.get("skipped") is True
    # the burst is not over: the timer comes back later, the layer stays coarse
    wait = live.refine()
    assert wait is not None and 0.0 < wait <= live.BURST_SECONDS
    assert live.LAST_FIGURES.get("skipped") is True
    time.sleep(live.BURST_SECONDS)
    assert live.refine() is None  # done: the timer stops
    f = live.LAST_FIGURES
    assert f["why"] == "refined" and not f.get("coarse") and not f.get("rebuilt")
    refined = _layers()
    assert _pointers(refined) == _pointers(full)
    _equal_to_generate(refined)


def test_a_render_never_starts_on_a_coarse_layer(empty_blend, interactive):
    live = interactive
    scene = _scene()
    scene.frame_set(4)
    assert live.LAST_FIGURES["coarse"] is True
    live.on_render_start(scene)  # render_init: the full layer before the first frame
    try:
        f = live.LAST_FIGURES
        assert f["why"] == "refined" and not f.get("coarse")
        scene.frame_set(4)  # frame_change_post of the render's frame: never coarse
        assert not live.LAST_FIGURES.get("coarse")
    finally:
        live.on_render_end(scene)
    _equal_to_generate(_layers())


def test_in_background_every_frame_gets_the_full_layer_in_place(empty_blend):
    live = _live()
    scene = _scene()
    first = _layers()
    scene.frame_set(5)
    f = live.LAST_FIGURES
    assert not f.get("coarse") and not f.get("rebuilt") and f["updated"] == len(first)
    state = _layers()
    assert _pointers(state) == _pointers(first)  # no new objects or meshes
    _equal_to_generate(state)


def test_a_mesh_of_other_rasters_is_rebuilt_not_written(empty_blend, interactive):
    # (an undo can bring back the meshes of an earlier full layer: the coarse
    # irradiance, computed for the last full layer's rasters, would land wrong)
    live = interactive
    scene = _scene()
    (name,) = [n for n in _layers() if n.endswith(" 0")]
    me = bpy.data.objects[name].data
    me.vertices[0].co.x += 0.25  # no longer the raster the coarse layer is computed on
    scene.frame_set(2)
    f = live.LAST_FIGURES
    assert f.get("rebuilt") is True  # built anew, not written into the wrong mesh


def _fallback_spots():
    """The layer's fallback spots (glossy receivers): name → their settings."""
    return {
        o.name: (tuple(o.location), o.data.energy, o.data.spot_size, o.data.spot_blend)
        for o in lens_lights()
        if o.type == "LIGHT"
    }


def test_a_coarse_layer_skips_the_near_field_fits_and_the_refine_makes_them(
    empty_blend, interactive, monkeypatch
):
    # A marble resting on a metal table: its caustic lands where no layer can be drawn,
    # so the layer's Fitted spot lights the table, fitted to it (near field: a fit of
    # ~60 ms per new light distance). While frames follow each other the coarse layer
    # does without those fits; the refine makes them, as Generate does.
    from lens_lights.core.tiers import fitted

    live = interactive
    monkeypatch.setattr(live, "BURST_SECONDS", 60.0)  # (only the explicit refine below)
    bpy.ops.mesh.primitive_plane_add(size=8)
    floor = bpy.context.object
    metal = new_material("Metal")
    metal.node_tree.nodes["Principled BSDF"].inputs["Metallic"].default_value = 1.0
    floor.data.materials.append(metal)
    add_sphere("Marble", (0.0, 0.0, 0.5), material=glass_material())
    lamp = add_point_light("Lamp", (0.3, 0.0, 3.0), radius=0.05)
    scene = _scene(lamp, {1: (0.3, 0.0, 3.0), 5: (0.9, 0.4, 2.6)})
    assert len(_fallback_spots()) == 1
    fits = []
    plain = fitted.receiver_fit

    def counted(*args):
        fits.append(args)
        return plain(*args)

    monkeypatch.setattr(fitted, "receiver_fit", counted)
    scene.frame_set(3)
    assert live.LAST_FIGURES.get("coarse") is True and "error" not in live.LAST_FIGURES
    assert fits == []  # the coarse state: no near-field fit
    coarse = _fallback_spots()
    live.refine(scene, wait=False)
    f = live.LAST_FIGURES
    assert f["why"] == "refined" and not f.get("coarse") and "error" not in f
    assert len(fits) == 1  # the spot's fit to the metal table at frame 3
    refined = _fallback_spots()
    assert refined.keys() == coarse.keys() and refined != coarse  # the fit moved it
    scene.lens_lights.live_update = False
    level, _message, _ = generate()
    assert level == "INFO"
    assert _fallback_spots() == refined  # Generate at frame 3: the same spot
