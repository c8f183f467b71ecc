"""Independent expected values for the reference tracer's tests: deterministic
quadratures over the cone of directions from an on-axis point light to the lens,
built on the 1-D exact optics of :mod:`core.lens.ball_optics` (SPEC 6), never on the
tracer under test."""

from __future__ import annotations

import numpy as np

from core.lens import ball_optics as xo


def cone_grid(D, R, n, n_iota=1500, n_phi=720, absorption=0.0):
    """Midpoint grid over the directions from a point at ``(0, 0, -D)`` that hit the
    sphere of radius ``R`` at the origin, in the incidence angle ``iota`` (fine near
    grazing) and the azimuth ``phi``.  Returns unit directions ``(k, 3)`` and the
    flux weights ``T(iota) exp(-a chord) dOmega`` (the lens's transmission times the
    solid angle of each cell), so that ``I0 * sum(weights * f(directions))`` is the
    flux the lens passes of a light of intensity ``I0 f(direction)``."""
    h = 0.5 * np.pi / n_iota
    iota = (np.arange(n_iota) + 0.5) * h
    fan = xo.trace_rays_iota(iota, D, R, n, absorption)
    k = R / D
    d_omega_dphi = k * k * np.sin(iota) * np.cos(iota) / np.cos(fan.psi) * h
    phi = (np.arange(n_phi) + 0.5) * (2.0 * np.pi / n_phi)
    psi = fan.psi[:, None]
    dirs = np.stack(
        np.broadcast_arrays(np.sin(psi) * np.cos(phi), np.sin(psi) * np.sin(phi), np.cos(psi)),
        axis=-1,
    ).reshape(-1, 3)
    w = np.repeat(fan.transmission * d_omega_dphi, n_phi) * (2.0 * np.pi / n_phi)
    return dirs, w


def angle_to(dirs, axis):
    """Angle of each direction to the unit ``axis`` (atan2 form, SPEC 4.2)."""
    axis = np.asarray(axis, float)
    return np.arctan2(np.linalg.norm(np.cross(dirs, axis), axis=1), dirs @ axis)


def disc_mean_transmission(n, n_iota=200_000):
    """Mean two-surface transmission of a parallel beam over a sphere's
    cross-section disc: ``integral 2 sin(iota) cos(iota) T(iota) d iota`` (the impact
    parameter ``b = R sin iota`` is uniform over the disc's area)."""
    h = 0.5 * np.pi / n_iota
    iota = (np.arange(n_iota) + 0.5) * h
    return float(
        np.sum(2.0 * np.sin(iota) * np.cos(iota) * xo.two_surface_transmission(iota, n)) * h
    )
