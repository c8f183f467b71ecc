"""How many rays a caustic sheet gets: from its flux share and its size on screen.

The layer resolves the caustic to the rays' landed cells (and sub-cells between them),
so what matters is the number of rays per *pixel* the caustic covers; and a dim caustic
tolerates a coarser grid, because the error of a piecewise representation is a fraction
of the irradiance: to keep the absolute error even across sources the count scales with
the source's flux relative to the brightest one. The count is capped per source and in
total; the grid is Nr × Na cells with Na = 4 Nr (square cells in (ι, φ) at the rim).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class RayBudget:
    n_radial: int
    n_azimuth: int

    @property
    def n_rays(self) -> int:
        """Node rays per source sample: (Nr + 1) × Na."""
        return (self.n_radial + 1) * self.n_azimuth


def pixel_size(camera_position, target, fov: float, width_px: int) -> float:
    """Length one pixel covers at ``target`` for a perspective camera of horizontal
    field of view ``fov`` (rad) and ``width_px`` pixels across."""
    dist = float(np.linalg.norm(np.asarray(target, float) - np.asarray(camera_position, float)))
    return 2.0 * dist * math.tan(0.5 * fov) / max(1, int(width_px))


def ray_budget(
    flux_share: float,
    extent: float,
    pixel: float,
    rays_per_pixel: float = 1.0,
    min_rays: int = 1024,
    max_rays: int = 65536,
    samples: int = 1,
    min_rays_per_sample: int = 256,
    texels: float | None = None,
    rays_per_texel: float = 1.0,
) -> RayBudget:
    """Grid for one source. ``flux_share``: its flux over the brightest source's (0..1];
    ``extent``: the caustic's size on the receiver (e.g. the lens' diameter, or the last
    layer's core); ``pixel``: :func:`pixel_size` there. ``texels``: the texels its
    caustic covers (a layer following the camera: :func:`view_texels`), if known: then
    ``rays_per_texel`` per texel instead (a ray's landed cell spread over many texels
    shows as dashes of sub-cells on the faint halo). An extended source's ``samples``
    share the budget (each one's image is blurred by its share of the source, so a
    coarser grid per sample suffices), down to ``min_rays_per_sample``."""
    px = max(extent, 0.0) / max(pixel, 1e-300)
    share = min(max(flux_share, 0.0), 1.0)
    want = rays_per_pixel * px * px * share
    if texels is not None:
        want = rays_per_texel * max(float(texels), 0.0) * share
    n = float(np.clip(want, min_rays, max_rays)) / max(int(samples), 1)
    n = max(n, float(min_rays_per_sample) if samples > 1 else n)
    nr = max(2, int(round(math.sqrt(n / 4.0))))
    return RayBudget(nr, 4 * nr)


def allocate(
    fluxes, extents, pixels, total_rays: int = 1_000_000, samples=None, texels=None, **kwargs
) -> list[RayBudget]:
    """Budgets for many sources: :func:`ray_budget` each (``samples``: per source, the
    samples of an extended emitter sharing it; ``texels``: per source, the texels its
    caustic covers; ``min_rays`` one number or one per source: a glass mesh's grows
    with its triangles; ``rays_per_texel`` one number or one per source: a glass
    mesh's are fewer, `mesh_sources.MESH_TEXEL_SHARE`), then scaled down together if
    the sum of all samples' rays exceeds ``total_rays``."""
    fluxes = np.asarray(fluxes, dtype=float)
    top = fluxes.max() if len(fluxes) and fluxes.max() > 0 else 1.0
    ks = [1] * len(fluxes) if samples is None else [max(int(k), 1) for k in samples]
    ts = [None] * len(fluxes) if texels is None else list(texels)
    mins = kwargs.pop("min_rays", None)
    mins = [mins] * len(fluxes) if mins is None or np.isscalar(mins) else list(mins)
    rpt = kwargs.pop("rays_per_texel", 1.0)
    rpt = [rpt] * len(fluxes) if np.isscalar(rpt) else list(rpt)
    out = [
        ray_budget(
            f / top,
            e,
            p,
            samples=k,
            texels=t,
            rays_per_texel=r,
            **kwargs,
            **({} if m is None else {"min_rays": m}),
        )
        for f, e, p, k, t, m, r in zip(fluxes, extents, pixels, ks, ts, mins, rpt, strict=True)
    ]
    total = sum(b.n_rays * k for b, k in zip(out, ks, strict=True))
    if total > total_rays:
        k = math.sqrt(total_rays / total)
        out = [RayBudget(max(2, int(b.n_radial * k)), 4 * max(2, int(b.n_radial * k))) for b in out]
    return out


def layer_resolution(extent: float, pixel: float, min_res: int = 16, max_res: int = 256) -> int:
    """Texels per side of a layer raster: about one texel per pixel of the caustic's
    extent (the warp makes the core's texels finer still), capped."""
    return int(np.clip(math.ceil(max(extent, 0.0) / max(pixel, 1e-300)), min_res, max_res))


def view_texels(span: float, pixel: float, texels_per_pixel: float, max_side: int) -> float:
    """The texels a caustic of size ``span`` covers in a raster that follows the camera:
    ``texels_per_pixel`` per ``pixel`` across, at most ``max_side`` per side, squared."""
    side = min(texels_per_pixel * max(span, 0.0) / max(pixel, 1e-300), float(max_side))
    return side * side
