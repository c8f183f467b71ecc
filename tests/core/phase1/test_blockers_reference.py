"""Phase 2's reference (reference/phase2.py) against independent values: the
Monte-Carlo tracer of reference on the issue's scene (an opaque sphere between a
point light and a glass ball), and the 1-D exact integral of SPEC 6 for the flux."""

from __future__ import annotations

import math

import numpy as np
import pytest

from core.lens import ball_optics as xo
from reference import Blocker, GlassSphere, PointLight, ReceiverPlane, trace_irradiance
from reference.phase2 import phase2_irradiance, phase2_rays

LIGHT = PointLight((0.0, 0.0, 3.0), 100.0)
LENS = GlassSphere((0.0, 0.0, 0.0), 0.5, 1.5)
PLANE = ReceiverPlane((0.0, 0.0, -1.5), (0.0, 0.0, 1.0))
EDGES = np.linspace(-0.4, 0.4, 25)


def test_without_blockers_the_flux_is_the_exact_integral():
    rays = phase2_rays(LIGHT, LENS, PLANE, n_radial=1024, n_azimuth=64)
    exact = xo.lens_flux(LIGHT.power / (4.0 * math.pi), 3.0, 0.5, 1.5)
    assert rays.flux.sum() == pytest.approx(exact, rel=1e-5)
    assert np.all(rays.passed == 1.0)


@pytest.mark.parametrize(
    "blockers",
    [
        [Blocker((0.158, 0.0, 1.5), 0.12)],  # the scene: one side blocked
        [Blocker((0.0, 0.0, 1.5), 0.1, ior=1.5)],  # a glass blocker on the axis
    ],
)
def test_phase2_matches_the_monte_carlo_tracer(blockers):
    grid = (EDGES, EDGES)
    ref = phase2_irradiance(LIGHT, LENS, PLANE, grid, blockers)
    mc = trace_irradiance(LIGHT, LENS, PLANE, 1_000_000, seed=3, blockers=blockers, grid=grid)
    assert ref.flux_on_plane == pytest.approx(mc.flux_on_plane, abs=4.0 * mc.flux_on_plane_se)
    assert ref.flux_on_plane < ref.flux_unblocked
    l1 = np.abs(ref.irradiance - mc.irradiance).sum() / mc.irradiance.sum()
    assert l1 < 0.04
    half = EDGES.size // 2
    lr_ref = ref.irradiance[:half].sum() / ref.irradiance[half:].sum()
    lr_mc = mc.irradiance[:half].sum() / mc.irradiance[half:].sum()
    assert lr_ref == pytest.approx(lr_mc, rel=0.02)


def test_the_shadow_falls_on_the_far_side_beyond_the_focus():
    """V = P − 1/D = 2(n − 1)/(nR) − 1/D = 1: the image lies 1.0 behind the centre, so
    the plane 1.5 behind it sees the beam inverted: a blocker on +x darkens −x."""
    ref = phase2_irradiance(LIGHT, LENS, PLANE, (EDGES, EDGES), [Blocker((0.158, 0, 1.5), 0.12)])
    half = EDGES.size // 2
    assert ref.irradiance[:half].sum() < 0.7 * ref.irradiance[half:].sum()


def test_bad_input_is_refused():
    with pytest.raises(ValueError, match="radius 0"):
        phase2_rays(PointLight((0.0, 0.0, 3.0), 1.0, radius=0.1), LENS, PLANE)
    with pytest.raises(ValueError, match="cuts the lens"):
        phase2_rays(LIGHT, LENS, ReceiverPlane((0.0, 0.0, -0.2), (0.0, 0.0, 1.0)))
