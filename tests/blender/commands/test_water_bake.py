"""Issue 26: the water's caustic baked over frames. A pool whose surface moves (an
Ocean modifier on a 16 × 16 grid, its time keyed) under a sun, floor below: Bake
writes the water's layer with a fixed topology and each frame's irradiance, keyed;
the saved file rendered by a Blender that never loads the extension (as
`blender -b file.blend -a` on a farm node) shows at frame 2 what Generate makes at
frame 2, and another net at frame 3 (the waves moved). Clear removes what the bake
made and nothing else: the user's scene is as it was.

Measured (Cycles, 32 px, direct light only): each render minus the same render with
the "Lens Lights" collection hidden, as the caustic; relative L1 over the lit pixels.
The bound is set from the renders themselves: the baked frame against Generate's
must be far closer than two frames of the bake are to each other (the nets moved).
"""

from __future__ import annotations

import numpy as np
import pytest

pytestmark = pytest.mark.blender

bpy = pytest.importorskip("bpy")

from blender_scene_helpers import generate, snapshot, snapshot_diff  # noqa: E402
from stock_render import stock_render  # noqa: E402
from water_scenes import moving_pool, water_layers  # noqa: E402


def caustic(blend, tmp, frame):
    facts, lit, without = stock_render(blend, tmp, frame)
    assert facts["registered"] is False and facts["operators"] is False
    return lit - without


def l1(a, b):
    lit = (a > 0.05 * a.max()) | (b > 0.05 * b.max())
    return float(np.abs(a - b)[lit].sum() / b[lit].sum())


def test_baked_water_renders_without_the_extension_as_generate_and_clear_removes_it(
    empty_blend, tmp_path
):
    moving_pool()
    sc = bpy.context.scene
    before = snapshot()
    assert bpy.ops.lens_lights.bake() == {"FINISHED"}
    report = sc.lens_lights.last_report
    assert "water caustic layer object" in report, report
    baked = water_layers()
    assert baked and sc.frame_current == 1
    # one fixed mesh per layer: the same vertices on every frame, the light in its image
    verts = {o.name: len(o.data.vertices) for o in baked}
    sc.frame_set(3)
    assert {o.name: len(o.data.vertices) for o in baked} == verts
    sc.frame_set(1)
    blend = tmp_path / "baked.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend), copy=True)
    b2 = caustic(blend, tmp_path / "b2", 2)
    b3 = caustic(blend, tmp_path / "b3", 3)

    # Clear: only what the bake made goes; the user's scene is as it was
    assert bpy.ops.lens_lights.clear() == {"FINISHED"}
    assert water_layers() == []
    assert not [i for i in bpy.data.images if i.get("lens_lights_created") == "bake"]
    after = snapshot()
    assert after == before, snapshot_diff(before, after)

    sc.frame_set(2)
    level, message, _ = generate()
    assert level in ("INFO", "WARNING") and "water: Water" in message, message
    blend2 = tmp_path / "generated.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend2), copy=True)
    g2 = caustic(blend2, tmp_path / "g2", 2)

    same, moved = l1(b2, g2), l1(b3, g2)
    flux = b2.sum() / g2.sum()
    print(f"\nbaked frame 2 vs Generate at 2: L1 {same:.3f}, flux {flux:.3f}; "
          f"baked frame 3 vs Generate at 2: L1 {moved:.3f}")  # fmt: skip
    assert g2.max() > 0 and b2.max() > 0
    assert same < 0.5 * moved  # the frame's own net, not another's
    assert same < 0.2
    assert flux == pytest.approx(1.0, abs=0.05)


def test_frames_whose_receivers_change_are_landed_again_on_one_raster(
    empty_blend, tmp_path, monkeypatch
):
    """A box appears on the floor (away from the net) on frame 3: that frame's
    receivers differ, so it is fitted alone and the bake's union raster re-lands every
    frame from the surfaces it kept (`water_stage._Kept`); frame 2 still renders as
    Generate's."""
    from lens_lights.blender.commands import water_stage

    moving_pool()
    sc = bpy.context.scene
    bpy.ops.mesh.primitive_cube_add(size=0.2, location=(3.0, 3.0, 0.1))
    box = bpy.context.object
    for f, hidden in ((1, True), (2, True), (3, False)):
        box.hide_render = box.hide_viewport = hidden
        box.keyframe_insert("hide_render", frame=f)
        box.keyframe_insert("hide_viewport", frame=f)
    sc.frame_set(1)
    rebuilt = []
    kept_source = water_stage._Kept.source
    monkeypatch.setattr(
        water_stage._Kept, "source", lambda self: rebuilt.append(1) or kept_source(self)
    )
    assert bpy.ops.lens_lights.bake() == {"FINISHED"}
    assert len(rebuilt) >= 2  # frames 1 and 2 landed again from what was kept
    blend = tmp_path / "baked.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend), copy=True)
    b2 = caustic(blend, tmp_path / "b2", 2)
    assert bpy.ops.lens_lights.clear() == {"FINISHED"}
    sc.frame_set(2)
    level, message, _ = generate()
    blend2 = tmp_path / "generated.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend2), copy=True)
    g2 = caustic(blend2, tmp_path / "g2", 2)
    same = l1(b2, g2)
    print(f"\nre-landed frame 2 vs Generate at 2: L1 {same:.3f}, flux {b2.sum() / g2.sum():.3f}")
    assert same < 0.2
    assert b2.sum() / g2.sum() == pytest.approx(1.0, abs=0.05)
