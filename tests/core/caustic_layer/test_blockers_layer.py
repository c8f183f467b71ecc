"""The caustic layer's beam with a shadow list (core/caustic_layer/shadow.py through
`beam_trace.trace_beam`) against phase 2's reference (reference/phase2.py): the
flux that passes and on which side of the caustic it lands, on the issue's scene."""

from __future__ import annotations

import numpy as np
import pytest

from core.caustic_layer.beam_trace import trace_beam
from core.caustic_layer.emitters import Lens, PointLight
from core.caustic_layer.shadow import ShadowList
from reference import Blocker, GlassSphere, ReceiverPlane
from reference import PointLight as RefPoint
from reference.phase2 import phase2_rays

LIGHT, POWER = np.array([0.0, 0.0, 3.0]), 100.0
LENS = Lens(center=np.zeros(3), radius=0.5, ior=1.5)
Z_PLANE = -1.5


def landed_x(beam):
    """x where each cell's first-corner ray meets the plane z = Z_PLANE (the cells' own
    footprint is the layer's business; the side is all this test needs)."""
    p, d = beam.exit_points[:, :-1], beam.exit_dirs[:, :-1]
    t = (Z_PLANE - p[..., 2]) / d[..., 2]
    return p[..., 0] + t * d[..., 0]


def reference(blockers):
    rays = phase2_rays(
        RefPoint(tuple(LIGHT), POWER),
        GlassSphere((0.0, 0.0, 0.0), 0.5, 1.5),
        ReceiverPlane((0.0, 0.0, Z_PLANE), (0.0, 0.0, 1.0)),
        blockers,
    )
    w = rays.flux * rays.passed
    ok = rays.landed
    return w[ok].sum(), w[ok & (rays.u < 0)].sum() / w[ok & (rays.u > 0)].sum()


@pytest.mark.parametrize(
    "blocker",
    [
        Blocker((0.158, 0.0, 1.5), 0.12),  # the issue's: one side
        Blocker((0.0, 0.0, 1.5), 0.1),  # over the lens' centre
        Blocker((0.1, 0.05, 1.5), 0.1, ior=1.5),  # glass
    ],
)
def test_the_beam_draws_the_shadow_as_the_reference(blocker):
    glass = blocker.ior is not None
    shadow = ShadowList(
        np.array([blocker.center], float),
        np.array([blocker.radius]),
        np.array([1.5 if glass else 1.0]),
        np.array([1.0 if glass else 0.0]),
        unblocked=1.0,  # the emitter's power carries no dimming here
    )
    emitter = PointLight(position=LIGHT, power=POWER)
    free = trace_beam(emitter, LENS, 128, 512)
    beam = trace_beam(emitter, LENS, 128, 512, blockers=shadow)
    flux, lr = reference([blocker])
    free_flux, _ = reference([])
    assert free.total_flux == pytest.approx(free_flux, rel=2e-3)
    assert beam.total_flux == pytest.approx(flux, rel=1e-2)
    x = landed_x(beam)
    got_lr = beam.cell_flux[x < 0].sum() / beam.cell_flux[x > 0].sum()
    assert got_lr == pytest.approx(lr, rel=0.03)


def test_the_unblocked_share_in_the_power_is_not_counted_twice():
    blocker = ShadowList(
        np.array([[0.158, 0.0, 1.5]]), np.array([0.12]), np.ones(1), np.zeros(1), 0.8
    )
    emitter = PointLight(position=LIGHT, power=POWER * 0.8)
    beam = trace_beam(emitter, LENS, 64, 256, blockers=blocker)
    flux, _ = reference([Blocker((0.158, 0.0, 1.5), 0.12)])
    assert beam.total_flux == pytest.approx(flux, rel=1e-2)
