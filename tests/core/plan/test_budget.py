"""Budgets: cut-off, cap, merging, with expectations worked out by hand."""

import math

import numpy as np

from core.phase1.point_lights import compute_phase1
from core.plan.budget import apply_budget, caught_fraction, source_flux
from core.scene.arrays import SceneArrays


def test_caught_fraction_matches_cap_solid_angle_and_survives_far_lights():
    # (1 − cos α)/2 with sin α = R/D, by hand for R/D = 1/2: (1 − √3/2)/2
    assert math.isclose(caught_fraction(1.0, 2.0), (1 - math.sqrt(3) / 2) / 2, rel_tol=1e-14)
    # Far away it tends to (R/D)²/4 without underflow: R/D = 1e-12 → 2.5e-25
    assert math.isclose(caught_fraction(1.0, 1e12), 0.25e-24, rel_tol=1e-12)


def _row_scene(distances, radius=0.5):
    """Lenses at the given distances from the light, 25° apart in direction so
    that none blocks another (α + β < γ for every pair)."""
    d = np.asarray(distances, float)
    ang = np.radians(25.0) * np.arange(d.size)
    centers = np.stack([d * np.cos(ang), d * np.sin(ang), np.zeros(d.size)], 1)
    return SceneArrays(
        np.zeros((1, 3)),
        np.ones(1),
        np.ones((1, 3)),
        centers,
        np.full(d.size, radius),
        np.full(d.size, 1.5),
        np.full(d.size, 1.0),
    )


def test_cutoff_and_cap_keep_the_strongest():
    a = _row_scene([3.0, 6.0, 12.0, 24.0])
    table = compute_phase1(a).table
    power = [100.0]
    flux = source_flux(table, power)
    # kt = 1 and nothing blocked: flux = P · caught fraction
    D = np.array([3.0, 6.0, 12.0, 24.0])
    expected = 100.0 * np.array([caught_fraction(0.5, d) for d in D])
    np.testing.assert_allclose(flux, expected, rtol=1e-12)
    cut = expected[1] / 100.0  # keeps sources 0 and 1 (flux decreases with D)
    kept, scale, report = apply_budget(table, power, min_flux_fraction=cut * 0.999)
    assert kept.lens.tolist() == [0, 1] and report.below_cutoff == 2
    assert math.isclose(report.flux_dropped, expected[2:].sum(), rel_tol=1e-12)
    kept, scale, report = apply_budget(table, power, max_lights=3)
    assert kept.lens.tolist() == [0, 1, 2] and report.over_cap == 1
    assert "3 of 4 lens lights kept" in report.summary()


def test_merging_nearly_coincident_sources_keeps_their_flux():
    # Two equal lenses side by side, 0.01 apart in the middle of a merge cell:
    # their images nearly coincide; merged, the energy scale doubles.
    centers = np.array([[10.0, 0.505, 0.505], [10.0, 0.5, 0.5]])
    a = SceneArrays(
        np.array([[0.0, 0.5, 0.5]]),
        np.ones(1),
        np.ones((1, 3)),
        centers,
        np.full(2, 0.001),
        np.full(2, 1.5),
        np.full(2, 1.0),
    )
    table = compute_phase1(a).table
    assert len(table) == 2
    kept, scale, report = apply_budget(table, [1.0], merge_distance=1.0)
    assert len(kept) == 1 and report.merged == 1
    # Equal flux within 1e-5: scale = (f0 + f1) / f_lead ≈ 2
    assert math.isclose(scale[0], 2.0, rel_tol=1e-4)
    np.testing.assert_allclose(kept.position[0], table.position.mean(axis=0), rtol=1e-5)
