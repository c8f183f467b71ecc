"""Live update follows the water (issue 26): the waves move every frame (an Ocean
modifier's time keyed); after `frame_set(k)` with live update on, the water's layer
is written into the same objects and meshes in place and equals a fresh Generate
at k, in the lens-light tier (Cycles' AUTO) and the Caustic layer tier (EEVEE)."""

import bpy
import numpy as np
import pytest
from blender_scene_helpers import generate, layer_states
from water_scenes import moving_pool, water_layers

pytestmark = pytest.mark.blender


def _live():
    from lens_lights.blender.commands import live_update

    return live_update


def _state():
    """The water's layer meshes (not the reflection copies): name → (positions,
    irradiance, object and mesh pointers)."""
    return layer_states(water_layers())


@pytest.mark.parametrize("engine, model", [("CYCLES", "AUTO"), ("BLENDER_EEVEE", "CAUSTIC_LAYER")])
def test_live_update_rewrites_the_water_layer_on_every_frame(empty_blend, engine, model):
    live = _live()
    moving_pool(engine)
    scene = bpy.context.scene
    scene.lens_lights.energy_model = model
    scene.lens_lights.live_update = True  # the layer at frame 1, at once
    first = _state()
    assert first, live.LAST_FIGURES
    scene.frame_set(2)
    f = live.LAST_FIGURES
    assert f.get("water_layers") == "refilled", f
    state = _state()
    # the same objects and meshes, another net
    assert {k: v[2:] for k, v in state.items()} == {k: v[2:] for k, v in first.items()}
    assert any(not np.array_equal(state[k][1], first[k][1]) for k in state)
    switch = scene.cycles.caustics_refractive  # Cycles' own caustics, as live update left it
    scene.lens_lights.live_update = False
    level, message, _ = generate()
    assert scene.cycles.caustics_refractive == switch  # as Generate leaves it
    assert "water: Water" in message, message
    fresh = _state()
    assert sorted(fresh) == sorted(state)
    for name, (co, irr, *_p) in fresh.items():
        np.testing.assert_array_equal(state[name][0], co)
        np.testing.assert_array_equal(state[name][1], irr)
