"""Measures of a caustic layer against radial references (tests and benchmarks).

The layer is piecewise constant per texel, so its average over a ring is computed by
supersampling each texel uniformly (s × s points sharing the texel's flux): the value
the layer itself shows, not a binning artefact of texels straddling a ring's edge.
"""

from __future__ import annotations

import numpy as np

from core.caustic_layer.rasters import PatchLayer


def _subpoints(layer: PatchLayer, s: int):
    g = (np.arange(s) + 0.5) / s
    du, dv = np.diff(layer.edges_u), np.diff(layer.edges_v)
    pu = (layer.edges_u[:-1, None] + du[:, None] * g).reshape(-1)  # (res·s,)
    pv = (layer.edges_v[:-1, None] + dv[:, None] * g).reshape(-1)
    flux = np.repeat(np.repeat(layer.texel_flux()[..., 0], s, 0), s, 1) / (s * s)
    return pu, pv, flux  # flux (v, u)


def radial_flux(layer: PatchLayer, center, radii, supersample: int = 8) -> np.ndarray:
    """Flux (W, first colour channel) of the layer within distance ``radii`` of the
    world point ``center`` (measured in the layer's plane)."""
    pu, pv, flux = _subpoints(layer, supersample)
    c = np.asarray(center, dtype=float) - layer.origin
    cu, cv = c @ layer.axis_u, c @ layer.axis_v
    rho = np.hypot(pu[None, :] - cu, pv[:, None] - cv).reshape(-1)
    o = np.argsort(rho)
    cum = np.concatenate([[0.0], np.cumsum(flux.reshape(-1)[o])])
    return cum[np.searchsorted(rho[o], np.asarray(radii, dtype=float), side="right")]


def ring_irradiance(layer: PatchLayer, center, edges, supersample: int = 8) -> np.ndarray:
    """Average irradiance of the layer over the rings between consecutive ``edges``."""
    edges = np.asarray(edges, dtype=float)
    return np.diff(radial_flux(layer, center, edges, supersample)) / (np.pi * np.diff(edges**2))


def relative_l1(values, reference, weights) -> float:
    """∫|E − E_ref| dA / ∫E_ref dA over bins of area ``weights``."""
    values, reference, weights = (np.asarray(a, dtype=float) for a in (values, reference, weights))
    return float(np.sum(np.abs(values - reference) * weights) / np.sum(reference * weights))


def radius_containing(layer: PatchLayer, center, fraction: float, supersample: int = 8) -> float:
    """Smallest radius about ``center`` within which the layer holds ``fraction`` of its
    flux."""
    pu, pv, flux = _subpoints(layer, supersample)
    c = np.asarray(center, dtype=float) - layer.origin
    rho = np.hypot(pu[None, :] - c @ layer.axis_u, pv[:, None] - c @ layer.axis_v).reshape(-1)
    o = np.argsort(rho)
    cum = np.cumsum(flux.reshape(-1)[o])
    return float(np.interp(fraction * cum[-1], cum, rho[o]))
