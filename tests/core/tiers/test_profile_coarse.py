"""The coarse Exact profile table live update shows while the user works
(`exact_profile.fan_profiles(coarse=True)`: fewer rays, and every fourth row beyond the
caustic) against the row-by-row exact table (`exact_profile.exact_profile`, from
`beam_error.ExactBeam`'s flux within a radius, 8000 rays: not the code under test),
over a sweep of D/R and n, far and near field: on every row the flux within 1 % of
the beam's; on the rows that carry the beam (a tenth of it or more) the peak (the
brightest ring of width PEAK_DISC R on the row's plane) within 5 % and the L1
difference within 5 % of the row's flux (the exact table's: 1 %). Then: tables made
in one batch are the tables made alone, and `prepare_tables` gives coarse tables
only where the exact one is not made."""

import math

import numpy as np
import pytest
from profile_measures import D_OMEGA, compare

from core.phase1.point_lights import compute_phase1
from core.scene.model import Light, Scene, Sphere, Surface
from core.scene.primaries import PrimaryLight
from core.tiers import exact_profile as xp
from core.tiers.beam_error import PEAK_DISC, ExactBeam
from core.tiers.near_field import ReceiverDistance
from core.tiers.spot_fit import FIRST_RECEIVER

RESTING = 1.0 / math.cos(math.radians(30.0))  # a marble on a table lit from 30°
CASES = [
    (d, n, where)
    for d in (1.1, 1.5, 3.0, 40.0, 1000.0)
    for n in (1.33, 1.9)
    for where in ("far", "resting", "near")
]


def _spec(d_over_r, n, where):
    if where == "resting":
        return (d_over_r, n, True, RESTING, xp.NEAR_DISTANCES, True)
    if where == "near":  # a wall 0.1 R behind the lens, square to the axis
        return (d_over_r, n, True, 1.1, xp.NEAR_DISTANCES, False)
    return (d_over_r, n, False, None, xp.PROFILE_DISTANCES, False)


@pytest.mark.parametrize("d_over_r,n,where", CASES)
def test_coarse_table_within_a_percent_of_the_flux_and_five_of_the_peak(d_over_r, n, where):
    spec = _spec(d_over_r, n, where)
    kw = {}
    if spec[3] is not None:
        kw = dict(receiver=spec[3], M=spec[4], slope=spec[5])
    exact = xp.exact_profile(d_over_r, n, **kw)
    (coarse,) = xp.fan_profiles([spec], coarse=True)
    assert coarse.table.shape == exact.table.shape
    assert (coarse.apex, coarse.h_min, coarse.h_max) == (exact.apex, exact.h_min, exact.h_max)
    l1, f_exact, p_exact, f_coarse, p_coarse = compare(exact, coarse)
    beam = exact.flux
    assert np.max(np.abs(f_coarse - f_exact)) <= 0.01 * beam
    lit = f_exact >= 0.1 * beam
    assert lit.sum() > 0.5 * len(lit)
    assert np.max(np.abs(p_coarse[lit] / p_exact[lit] - 1.0)) <= 0.05
    assert np.max(l1[lit] / f_exact[lit]) <= 0.05
    if exact.slope is not None:  # the tilt correction's channel: table × mean slope
        s_exact = exact.table * exact.slope
        diff = np.sum(np.abs(coarse.table * coarse.slope - s_exact) * D_OMEGA)
        assert diff <= 0.05 * np.sum(np.abs(s_exact) * D_OMEGA)


@pytest.mark.parametrize("coarse", [False, True])
def test_tables_in_one_batch_are_the_tables_made_alone(coarse):
    specs = [_spec(39.5, 1.5, "resting"), _spec(3.0, 1.33, "far"), _spec(12.0, 1.9, "near")]
    specs.append((40.0, 1.5, True, 1.02, xp.NEAR_DISTANCES, True))
    together = xp.fan_profiles(specs, coarse=coarse)
    for spec, prof in zip(specs, together, strict=True):
        (alone,) = xp.fan_profiles([spec], coarse=coarse)
        np.testing.assert_array_equal(prof.table, alone.table)
        if alone.slope is not None:
            np.testing.assert_array_equal(prof.slope, alone.slope)
        assert prof.flux == alone.flux


def _light(distance):
    """An Exact profile light of a ball (R 0.5, n 1.5) at the origin lit from
    `distance` straight above, resting on a table 0.5005 below its centre (the near
    field, a row on the table)."""
    scene = Scene(
        lights=[Light(position=(0.0, 0.0, distance), brightness=100.0)],
        objects=[
            Sphere(center=(0.0, 0.0, 0.0), radius=0.5, surface=Surface(transmission=1.0, ior=1.5))
        ],
    )
    (src,) = compute_phase1(scene).sources
    receiver = ReceiverDistance(0.5005, (0.0, 0.0, 1.0), ())
    return xp.make_profile_light(src, PrimaryLight(100.0), receiver_distance=receiver)


def test_prepare_tables_coarse_only_where_the_exact_table_is_not_made():
    xp.cached_profile.cache_clear()
    known, new = _light(3.0), _light(3.1)
    xp.prepare_tables([known])  # its exact table, made before
    assert xp.cached_profile.cache_info().currsize == 1
    assert xp.prepare_tables([known, new], coarse=True) == 1
    assert not known.coarse and new.coarse
    assert new.profile["key"].endswith(" coarse") and not known.profile["key"].endswith("coarse")
    # the coarse table, normalised as the exact one is (the beam's flux / 2π)
    d_over_r, n, near, receiver, slope = new.table_key
    (coarse,) = xp.fan_profiles(
        [(d_over_r, n, near, receiver, xp.NEAR_DISTANCES, slope)], coarse=True
    )
    t_ref = xp.cached_profile(d_over_r, n).flux / (2.0 * math.pi)
    np.testing.assert_allclose(new.profile["pixels"], coarse.table / t_ref, rtol=1e-6)
    # planned again without coarse: the exact table, under its own key
    assert xp.prepare_tables([new]) == 0
    assert not new.coarse and not new.profile["key"].endswith("coarse")
    exact = xp.cached_profile(*new.table_key)
    np.testing.assert_allclose(new.profile["pixels"], exact.table / t_ref, rtol=1e-6)


def test_live_updates_coarse_table_leaves_its_rows_between_to_the_image():
    """Live update's coarse table (`fan_profiles(lazy=True)`, what `prepare_tables`
    makes) computes the rows the eager one computes and leaves the rows between
    them pending: its light's pixels (red: intensity, green: intensity × slope, over
    the normalisation) are the eager table's to float32's rounding, and the table
    completed is the eager one bit for bit."""
    spec = (39.5, 1.5, True, RESTING, xp.NEAR_DISTANCES, True)
    (eager,) = xp.fan_profiles([spec], coarse=True)
    (lazy,) = xp.fan_profiles([spec], coarse=True, lazy=True)
    kept, todo = lazy.pending
    assert todo.size > 100 and kept[0] < todo[0] and todo[-1] < kept[-1]
    done = np.setdiff1d(np.arange(xp.NEAR_DISTANCES), todo)
    np.testing.assert_array_equal(lazy.table[done], eager.table[done])
    np.testing.assert_array_equal(lazy.slope[done], eager.slope[done])
    t_ref = eager.flux / (2.0 * math.pi)
    profile = xp.profile_dict(lazy, t_ref, 0.5, np.zeros(3), np.array([0.0, 0.0, -1.0]), "k")
    red, green = profile["pixels"], profile["slope_pixels"]
    assert red.dtype == np.float32 and green.dtype == np.float32
    want_red = (eager.table / t_ref).astype(np.float32)
    want_green = (eager.table * eager.slope / t_ref).astype(np.float32)
    np.testing.assert_array_equal(red[done], want_red[done])
    np.testing.assert_array_equal(green[done], want_green[done])
    np.testing.assert_allclose(red, want_red, rtol=2e-6, atol=1e-6 * float(want_red.max()))
    scale = float(np.abs(want_green).max())
    np.testing.assert_allclose(green, want_green, rtol=0, atol=2e-6 * scale)
    lazy.complete()
    assert lazy.pending is None
    np.testing.assert_array_equal(lazy.table, eager.table)
    np.testing.assert_array_equal(lazy.slope, eager.slope)


@pytest.mark.parametrize("d_over_r", [1.1, 1.5, 3.0, 40.0, 1000.0])
@pytest.mark.parametrize("n", [1.33, 1.9])
def test_coarse_summary_within_its_bounds_of_the_exact_beam(d_over_r, n):
    """Within `coarse_summaries` (live update while the user works) a light's flux and
    reference irradiance come from `COARSE_SUMMARY_FAN` rays: the flux within 1e-5 and
    the mean irradiance on the disc of PEAK_DISC R at the first receiver within 1.2 %
    of a 20 000-ray `ExactBeam`'s; outside it the summary Generate plans with."""
    beam = ExactBeam(1.0, d_over_r, 1.0, n, n_fan=20000)
    z = beam.plane(FIRST_RECEIVER)
    e = float(beam.flux_within_radius(z, np.array([PEAK_DISC]))[0]) / (math.pi * PEAK_DISC**2)
    with xp.coarse_summaries():
        flux, e_ref, coarse = xp.beam_summary(d_over_r, n)
    assert coarse
    assert abs(flux / beam.lens_flux - 1.0) <= 1e-5
    assert abs(e_ref / e - 1.0) <= 0.012
    assert xp.beam_summary(d_over_r, n) == (*xp._beam_summary(d_over_r, n), False)
