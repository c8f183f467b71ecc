"""Measures of an Exact profile table computed from the table alone (tests of the
fan tables, exact and coarse): per row its flux and the peak irradiance on the row's
plane, and the L1 difference of two tables per row."""

import math

import numpy as np

from core.tiers import exact_profile as xp
from core.tiers.beam_error import PEAK_DISC, ExactBeam

# ring solid angles of the tables' angular bins (u = sqrt(gamma/90°), K uniform)
K = xp.PROFILE_ANGLES
G_EDGES = math.radians(xp.PROFILE_GAMMA_MAX_DEG) * (np.arange(K + 1) / K) ** 2
OMEGA_EDGES = 4.0 * math.pi * np.sin(0.5 * G_EDGES) ** 2
D_OMEGA = np.diff(OMEGA_EDGES)


def row_measures(table, distances):
    """Per row: flux (W per W/sr) and peak irradiance on its plane, from rings of
    width PEAK_DISC R (the flux within a radius read from the cumulative over the
    bins, linear in solid angle within a bin, as the table holds a mean per bin)."""
    cum = np.concatenate([np.zeros((table.shape[0], 1)), np.cumsum(table * D_OMEGA, 1)], 1)
    flux = cum[:, -1]
    peaks = np.zeros(table.shape[0])
    for j, h in enumerate(distances):
        rho = np.arange(0.0, 4.0 * h, PEAK_DISC)  # to 76° from the apex
        omega = 4.0 * math.pi * np.sin(0.5 * np.arctan2(rho, h)) ** 2
        within = np.interp(omega, OMEGA_EDGES, cum[j])
        area = math.pi * np.diff(rho**2)
        peaks[j] = np.max(np.diff(within) / area)
    return flux, peaks


def outside_lens(prof):
    """The texels outside the lens (near field: the apex at the centre; texels
    reaching inside hold no receiver's light)."""
    h = prof.distances[:, None]
    return (prof.apex + h) ** 2 + (h * np.tan(G_EDGES[:-1])) ** 2 >= 1.0


def compare(exact, other):
    """(per-row L1 difference, rows' flux, their peaks, the other's fluxes and
    peaks), outside the lens."""
    outside = outside_lens(exact)
    t_exact, t_other = exact.table * outside, other.table * outside
    f_exact, p_exact = row_measures(t_exact, exact.distances)
    f_other, p_other = row_measures(t_other, other.distances)
    l1 = np.sum(np.abs(t_other - t_exact) * D_OMEGA, 1)
    return l1, f_exact, p_exact, f_other, p_other


def exact_near_table(centre, radius, n, lamp_at):
    """The exact near-field table (`exact_profile.exact_profile`, slopes too) of a lens
    at `centre` lit from `lamp_at` over the table z = 0, the geometry by hand (D/R; the
    table met along the axis, in R from the centre), and the factor that turns a
    light's image (red: the table over the energy's normalisation) into it."""
    d = np.asarray(centre, float) - np.asarray(lamp_at, float)
    D = float(np.linalg.norm(d))
    d_over_r, z = D / radius, float(centre[2]) / (-d[2] / D) / radius
    exact = xp.exact_profile(d_over_r, n, receiver=z, M=xp.NEAR_DISTANCES, slope=True)
    t_ref = ExactBeam(1.0, d_over_r, 1.0, n, n_fan=8000).lens_flux / (2.0 * math.pi)
    return exact, t_ref
