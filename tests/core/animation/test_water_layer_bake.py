"""The water's bake (issue 26): moving waves' frames landed again on one raster fixed
over the frames (`layer_segments.bake_frames` with `water_sources.water_bake`'s
re-landing), each slice against the Monte-Carlo height-field reference of its own
frame (`reference/water_tracer.py`), and against Generate's layer of that frame."""

import dataclasses
import math

import numpy as np
import pytest

from core.animation import layer_segments
from core.caustic_layer.emitters import SunLight
from core.caustic_layer.receiver_bvh import ReceiverMesh
from core.caustic_layer.water_beam import WaterSource
from core.caustic_layer.water_sources import water_bake
from core.lens.water import WaterSurface
from reference.layer_metrics import relative_l1
from reference.water_tracer import SineWaves, height_field_mesh, layer_on_bins, trace_floor

N = 1.333
RAYS = 200 * 200
ZEN = math.radians(30.0)
SUN = np.array([math.sin(ZEN), 0.0, -math.cos(ZEN)])


def waves(t):
    """Two sine waves travelling (phase 2.2 rad per frame along the first)."""
    return SineWaves(
        0.0,
        (0.006, 0.004),
        ((2 * math.pi / 0.3, 0.0), (2 * math.pi / 0.21 * 0.6, 2 * math.pi / 0.21 * 0.8)),
        (0.3 + 2.2 * t, 1.1 - 1.3 * t),
        (-0.5, 0.5, -0.5, 0.5),
    )


def floor(z=-0.7, half=4.0):
    v = np.array([[-half, -half, z], [half, -half, z], [half, half, z], [-half, half, z]])
    return ReceiverMesh(v, np.array([[0, 1, 2], [0, 2, 3]]))


def frame_input(t, receivers):
    v, tri, cn = height_field_mesh(waves(t), 120, 120)
    sources = [WaterSource(SunLight(SUN, 1.0), WaterSurface(v, tri, cn, ior=N))]
    sheet = water_bake(sources, receivers, n_rays=RAYS, resolution=96)

    def reland(given, res):
        return water_bake(
            sources, sheet.index, n_rays=RAYS, resolution=res, raster_frames=given
        ).layer.patches

    return layer_segments.FrameLayers(sources, sheet, [("water", "Sun", "Pool")], ["Floor"],
                                      reland=reland)  # fmt: skip


def test_moving_waves_bake_on_one_raster_each_slice_its_frames_net():
    receivers = floor()
    frames = [frame_input(t, receivers) for t in (0.0, 1.0)]
    segs, res = layer_segments.bake_frames(frames)
    (seg,) = segs  # one fixed topology over both frames
    assert seg.frames == [0, 1] and len(seg.slices) == 2
    ex, ey = np.linspace(-0.02, 0.58, 31), np.linspace(-0.3, 0.3, 31)
    area = np.diff(ey)[:, None] * np.diff(ex)[None, :]
    for k, t in enumerate((0.0, 1.0)):
        ref = trace_floor(waves(t), -0.7, ex, ey, ior=N, sun_direction=SUN, n_rays=400_000,
                          seed=5 + k)  # fmt: skip
        baked = layer_on_bins(dataclasses.replace(seg.layer, irradiance=seg.slices[k]), ex, ey)
        (own,) = frames[k].sheet.layer.patches  # Generate's layer of that frame
        generated = layer_on_bins(own, ex, ey)
        l1 = relative_l1(baked, ref.irradiance, area)
        print(f"frame {k}: baked vs reference L1 {l1:.3f}; vs Generate "
              f"{relative_l1(baked, generated, area):.3f}")  # fmt: skip
        assert l1 < 0.12
        assert relative_l1(baked, generated, area) < 0.08
        # every landed watt is in the slice: the flux through the water, as the reference's
        assert seg.flux[k] == pytest.approx(ref.flux, rel=0.01)
        # the two frames' nets differ (the waves moved): the slices are the frames' own
        assert baked.max() / baked.mean() > 1.5
    other = layer_on_bins(dataclasses.replace(seg.layer, irradiance=seg.slices[1]), ex, ey)
    first = layer_on_bins(dataclasses.replace(seg.layer, irradiance=seg.slices[0]), ex, ey)
    assert relative_l1(first, other, area) > 0.2


def test_the_bake_report_counts_the_water_layers_apart():
    from core.animation.light_tracks import bake_message

    fig = dict(objects=3, water_objects=2, water_images=1, energy_model="AUTO", frame_start=1,
               frame_end=100, frames=100, seconds=60.0)  # fmt: skip
    assert bake_message(fig) == (
        "Baked 1 lens light and 2 water caustic layer objects over frames 1–100 (100 frames, "
        "60.0 s); 1 water layer image"
    )
    fig.update(objects=2, energy_model="CAUSTIC_LAYER")
    assert bake_message(fig).startswith("Baked 2 water caustic layer objects over frames 1–100")
