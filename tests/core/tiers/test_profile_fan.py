"""The Exact profile's fast table (`profile_fan`, what `cached_profile` gives Generate,
the bake and live update) against the row-by-row exact table (`exact_profile`, built
from `beam_error.ExactBeam`'s flux within a radius, 8000 rays): over a sweep of D/R
and n, far and near field: on every receiver row (outside the lens) the L1 difference
and the row's flux within 1 % of the beam's flux; on the rows that carry the beam
(a tenth of its flux or more) the L1 difference within 1 % of the row's own flux and
its peak (the brightest ring of width PEAK_DISC R on the row's plane) within 5 %.
The measures are computed here from the tables alone."""

import math

import numpy as np
import pytest
from profile_measures import D_OMEGA, compare

from core.tiers import exact_profile as xp
from core.tiers import profile_fan as pf
from core.tiers.beam_error import ExactBeam

CASES = [
    (d, n, where)
    for d in (1.1, 1.5, 3.0, 10.0, 40.0, 1000.0)
    for n in (1.33, 1.5, 1.9)
    for where in ("far", "resting", "near")
]


@pytest.mark.parametrize("d_over_r,n,where", CASES)
def test_fast_table_matches_the_exact_table(d_over_r, n, where):
    kw = {}
    if where == "resting":  # a marble on a table lit from 30°: the table 1/cos 30° R away
        kw = dict(receiver=1.0 / math.cos(math.radians(30.0)), M=xp.NEAR_DISTANCES, slope=True)
    elif where == "near":  # a wall 0.1 R behind the lens, square to the axis
        kw = dict(receiver=1.1, M=xp.NEAR_DISTANCES)
    exact = xp.exact_profile(d_over_r, n, **kw)
    fast = xp.fan_profile(d_over_r, n, **kw)
    assert fast.table.shape == exact.table.shape
    assert (fast.apex, fast.h_min, fast.h_max) == (exact.apex, exact.h_min, exact.h_max)
    # texels reaching inside the lens (near field: apex at the centre) hold no
    # receiver's light: compared outside it only
    l1, f_exact, p_exact, f_fast, p_fast = compare(exact, fast)
    beam = exact.flux
    # every row: the L1 difference and the flux within 1 % of the beam's flux
    assert l1.max() <= 0.01 * beam, (l1.max() / beam, int(np.argmax(l1)))
    assert np.max(np.abs(f_fast - f_exact)) <= 0.01 * beam
    # the rows that carry the beam (a tenth of it or more: not the planes inside the
    # lens that only grazing rays have left): within 1 % of their own flux, the peak 5 %
    lit = f_exact >= 0.1 * beam
    assert lit.sum() > 0.5 * len(lit)
    assert np.max(l1[lit] / f_exact[lit]) <= 0.01
    assert np.max(np.abs(p_fast[lit] / p_exact[lit] - 1.0)) <= 0.05
    if exact.slope is not None:  # the tilt correction's channel: table × mean slope
        s_exact = exact.table * exact.slope
        diff = np.sum(np.abs(fast.table * fast.slope - s_exact) * D_OMEGA)
        assert diff <= 0.02 * np.sum(np.abs(s_exact) * D_OMEGA)


def test_cached_profile_is_the_fast_table_with_the_planned_flux():
    prof = xp.cached_profile(4.69, 1.5)
    fast = xp.fan_profile(4.69, 1.5)
    np.testing.assert_array_equal(prof.table, fast.table)
    # the light's energy is made of the beam's flux (`SUMMARY_FAN` rays): the same number
    assert prof.flux == ExactBeam(1.0, 4.69, 1.0, 1.5, n_fan=xp.SUMMARY_FAN).lens_flux
    assert prof.flux == pytest.approx(fast.flux, rel=1e-5)


@pytest.mark.parametrize("d_over_r", [1.1, 1.5, 3.0, 38.37, 1000.0])
@pytest.mark.parametrize("n", [1.33, 1.9])
@pytest.mark.parametrize("rays", [xp.COARSE_FAN_FAR, pf.FAN_FAR])
def test_the_far_rows_fan_thinned_from_the_near_rows_is_the_fan_traced(d_over_r, n, rays):
    """`profile_fan.thinned`: every other ray of the fan of twice the rays is the fan
    traced with `rays` bit for bit (the same angles, per-ray values of their own
    angle), its flux too: the far rows' fan need not be traced again."""
    traced = pf.ray_fan(d_over_r, n, 0.0, n_fan=rays)
    thin = pf.thinned(pf.ray_fan(d_over_r, n, 0.0, n_fan=2 * rays), rays)
    for name in traced._fields:
        np.testing.assert_array_equal(getattr(thin, name), getattr(traced, name))
