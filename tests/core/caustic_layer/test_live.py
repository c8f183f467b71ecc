"""Live update's incremental caustic layer (`core.caustic_layer.live`): only the pairs
whose inputs changed are traced again, the beams splatted alone into fixed rasters
add up to the joint splat of `build_layer` (the reference here), the flux is kept,
and the coarse layer of a lens carries its exact flux (`ball_optics.lens_flux`)."""

import math

import numpy as np
import pytest

from core.caustic_layer.beam_trace import trace_beam
from core.caustic_layer.emitters import Lens, PointLight
from core.caustic_layer.live import LiveLayer
from core.caustic_layer.pipeline import SheetSource, bake
from core.caustic_layer.rasters import (
    RasterFrame,
    beam_fluxes,
    blur_flux,
    build_layer,
    fixed_layer,
    fixed_rasters,
)
from core.lens import ball_optics as eo
from reference.meshes import rectangle

R, N_IOR = 0.3, 1.5
CENTRES = [(-1.0, 0.0, 1.0), (0.0, 0.0, 1.0), (1.0, 0.0, 1.0)]
LAMPS = {"A": (0.5, 0.3, 8.0), "B": (-0.6, -0.2, 6.0)}
POWER = 1000.0
KEY = b"floor"


def _sources(lamps=LAMPS):
    out, names = [], []
    for light, pos in lamps.items():
        for k, c in enumerate(CENTRES):
            out.append(
                SheetSource(PointLight(np.array(pos, float), POWER), Lens(np.array(c), R, N_IOR))
            )
            names.append((light, f"Marble {k}"))
    return out, names


def _floor():
    return rectangle((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 12.0, 12.0, 2, 2)


@pytest.fixture(scope="module")
def full():
    sources, names = _sources()
    return bake(sources, _floor(), grid=(8, 32), resolution=64), sources, names


def test_only_the_pairs_whose_inputs_changed_are_traced_again(full):
    sheet, sources, names = full
    live = LiveLayer(sheet, names, KEY)
    assert live.coarse(sources, names, KEY) is not None
    assert (live.traced, live.reused) == (6, 0)  # the first coarse layer: every pair
    live.coarse(sources, names, KEY)
    assert (live.traced, live.reused) == (6, 6)  # nothing changed: nothing traced
    moved, _ = _sources({"A": (0.7, 0.3, 8.0), "B": LAMPS["B"]})
    live.coarse(moved, names, KEY)
    assert (live.traced, live.reused) == (9, 9)  # lamp A's three pairs
    # the pairs come in another order (the plan sorts them by brightness): by name
    live.coarse(moved[::-1], names[::-1], KEY)
    assert (live.traced, live.reused) == (9, 15)
    # other pairs or other receivers: the full bake is needed
    assert live.coarse(moved[:5], names[:5], KEY) is None
    assert live.coarse(moved, names, b"another floor") is None


def test_reused_beams_give_the_layer_traced_afresh(full):
    sheet, sources, names = full
    moved, _ = _sources({"A": (0.7, 0.3, 8.0), "B": LAMPS["B"]})
    live = LiveLayer(sheet, names, KEY)
    live.coarse(sources, names, KEY)
    reused = live.coarse(moved[::-1], names[::-1], KEY)
    fresh = LiveLayer(sheet, names, KEY).coarse(moved[::-1], names[::-1], KEY)
    for a, b in zip(reused.patches, fresh.patches, strict=True):
        np.testing.assert_allclose(a.irradiance, b.irradiance, rtol=1e-12, atol=0.0)
        assert sorted(a.sources.tolist()) == sorted(b.sources.tolist())
    # the full bake's rasters, unchanged: the meshes keep their topology and positions
    for a, b in zip(reused.patches, sheet.layer.patches, strict=True):
        assert a.vertices is b.vertices and a.resolution == b.resolution


def test_beams_splatted_alone_add_up_to_the_joint_splat(full):
    sheet, sources, names = full
    moved, _ = _sources({"A": (0.9, 0.1, 7.0), "B": LAMPS["B"]})
    beams = [trace_beam(s.emitter, s.lens, 8, 32) for s in moved]
    index = sheet.index
    frames = [
        RasterFrame(p.patch, tuple(p.sources), p.normal, p.axis_u, p.axis_v, p.axes, p.coarse)
        for p in sheet.layer.patches
    ]
    joint = build_layer(beams, index, resolution=64, raster_frames=frames, max_subdivision=4)
    rasters = fixed_rasters(sheet.layer.patches, len(beams), len(index.patches))
    alone = beam_fluxes(beams, list(range(len(beams))), index, rasters, max_subdivision=4)
    layer = fixed_layer(rasters, alone, sum(b.total_flux for b in beams))
    for a, b in zip(layer.patches, joint.patches, strict=True):
        np.testing.assert_allclose(a.irradiance, b.irradiance, rtol=1e-9, atol=1e-12)
    assert layer.flux_in_rasters == pytest.approx(joint.flux_in_rasters, rel=1e-12)
    assert layer.flux_in_rasters + layer.flux_outside + layer.flux_lost == pytest.approx(
        layer.flux_emitted, rel=1e-9
    )


def test_the_coarse_layer_carries_each_lens_flux():
    # one lens, one lamp: what lands is the exact flux through the ball (SPEC §6)
    lens = Lens(np.array([0.0, 0.0, 1.0]), R, N_IOR)
    d = 7.0
    src = [SheetSource(PointLight(np.array([0.0, 0.0, 1.0 + d]), POWER), lens)]
    names = [("A", "Marble")]
    sheet = bake(src, _floor(), grid=(16, 64), resolution=64)
    coarse = LiveLayer(sheet, names, KEY).coarse(src, names, KEY)
    exact = eo.lens_flux(POWER / (4.0 * math.pi), d, R, N_IOR)
    assert coarse.flux_in_rasters + coarse.flux_outside == pytest.approx(exact, rel=0.01)
    assert coarse.flux_in_rasters == pytest.approx(sheet.layer.flux_in_rasters, rel=0.02)


def test_blur_keeps_the_flux_and_spreads_by_the_binomial_weights():
    f = np.zeros((5, 5))
    f[2, 2] = 1.0
    g = blur_flux(f, 1)
    w = np.array([0.25, 0.5, 0.25])  # one [1 2 1]/4 pass per axis
    np.testing.assert_allclose(g[1:4, 1:4], np.outer(w, w), rtol=1e-15)
    assert g.sum() == pytest.approx(1.0, rel=1e-15)
    corner = np.zeros((4, 4, 3))
    corner[0, 0] = (1.0, 2.0, 3.0)
    h = blur_flux(corner, 2)  # what would leave stays in the border texel
    np.testing.assert_allclose(h.sum(axis=(0, 1)), (1.0, 2.0, 3.0), rtol=1e-14)
    # from the edge, by hand: one pass keeps 1/2 + 1/4 (what would leave), a second
    # [3/4, 1/4] → [3/4·3/4 + 1/4·1/4, 3/4·1/4 + 1/4·1/2, 1/4·1/4, 0]; separable
    one = np.array([0.75, 0.25, 0.0, 0.0])
    two = np.array([0.75 * 0.75 + 0.25 * 0.25, 0.75 * 0.25 + 0.25 * 0.5, 0.25 * 0.25, 0.0])
    assert np.allclose(blur_flux(np.eye(1, 4).reshape(1, 4), 1)[0], one)
    np.testing.assert_allclose(h[:, 0, 0], two * two[0], rtol=1e-14)
