"""One call from lens lights to caustic layers: budget, trace, land, accumulate.

What the Blender side calls once per bake (or per frame): the (light, lens) pairs of
phase 1 as :mod:`.emitters` data, the receivers as a :class:`.ReceiverMesh` (or an index
built once per scene), and a camera estimate for the ray budget.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .beam_trace import BeamGrid, trace_beam
from .caustic_layer import CausticLayer, build_layer, land_beams
from .emitters import Lens
from .ray_budget import RayBudget, allocate, layer_resolution, pixel_size
from .receiver_bvh import ReceiverMesh
from .receiver_index import ReceiverIndex, build_index


@dataclass(frozen=True)
class SheetSource:
    """One secondary source: a primary (PointLight, SpotLight, SunLight or AreaLight),
    its lens, how many samples of an extended emitter, and the object id of the lens'
    own mesh among the receivers (−1: not there)."""

    emitter: object
    lens: Lens
    n_source: int = 1
    own_object: int = -1


@dataclass(frozen=True)
class Camera:
    """A perspective camera estimate: position, horizontal field of view (rad), width in
    pixels."""

    position: np.ndarray
    fov: float
    width_px: int


@dataclass
class SheetBake:
    layer: CausticLayer
    budgets: list[RayBudget]  # per source, (Nr, Na) and its node-ray count
    resolution: int


def bake(
    sources: list[SheetSource],
    receivers: ReceiverMesh | ReceiverIndex,
    camera: Camera | None = None,
    rays_per_pixel: float = 1.0,
    max_rays: int = 65536,
    total_rays: int = 1_000_000,
    grid: tuple[int, int] | None = None,
    resolution: int | Callable[[list[float], list[float]], int] | None = None,
) -> SheetBake:
    """Caustic layers of ``sources`` on ``receivers``. The grid per source comes from
    :func:`.ray_budget.allocate` (flux share and caustic extent from a coarse 4 × 16
    trace landed on the receivers, pixel size at the lens from ``camera``) unless
    ``grid`` = (Nr, Na) is given; the raster resolution from :func:`.layer_resolution`
    of the largest extent, or ``resolution(extents, pixels)`` if a callable."""
    index = receivers if isinstance(receivers, ReceiverIndex) else build_index(receivers)
    extents = [2.0 * s.lens.radius for s in sources]
    if grid is not None:
        budgets = [RayBudget(int(grid[0]), int(grid[1])) for _ in sources]
        pixels = [math.inf] * len(sources)
    else:
        coarse = [trace_beam(s.emitter, s.lens, 4, 16) for s in sources]
        extents = caustic_extents(coarse, index, [s.own_object for s in sources], extents)
        pixels = [
            pixel_size(camera.position, s.lens.center, camera.fov, camera.width_px)
            if camera is not None
            else 2.0 * s.lens.radius / 64.0
            for s in sources
        ]
        budgets = allocate(
            [b.total_flux for b in coarse],
            extents,
            pixels,
            total_rays=total_rays,
            rays_per_pixel=rays_per_pixel,
            max_rays=max_rays,
            samples=[s.n_source for s in sources],
        )
    if callable(resolution):
        resolution = resolution(extents, pixels)
    elif resolution is None:
        resolution = max(
            (layer_resolution(e, p) for e, p in zip(extents, pixels, strict=True)), default=16
        )
    beams = [
        trace_beam(s.emitter, s.lens, b.n_radial, b.n_azimuth, s.n_source)
        for s, b in zip(sources, budgets, strict=True)
    ]
    own = [s.own_object for s in sources]
    layer = build_layer(
        beams, index, resolution=resolution, own_objects=own if any(o >= 0 for o in own) else None
    )
    return SheetBake(layer, budgets, int(resolution))


def caustic_extents(
    coarse: list[BeamGrid], index: ReceiverIndex, own_objects, diameters
) -> list[float]:
    """Per coarse beam, the size of its caustic on the receivers: the lens' diameter,
    or the span of the landed rays if larger (a grazing receiver stretches the caustic
    far beyond it). The rim's rays (ι = 90°, grazing the sphere) are left out."""
    if not coarse:
        return []
    own = list(own_objects)
    landed = land_beams(coarse, index, own if any(o >= 0 for o in own) else None)
    out = []
    for b, lb, diameter in zip(coarse, landed, diameters, strict=True):
        rings = b.exit_points.shape[1]
        keep = (lb.patch >= 0).reshape(b.exit_points.shape[:3])
        keep[:, rings - 1] = False
        pts = lb.point[keep.reshape(-1)]
        span = float(np.ptp(pts, axis=0).max()) if len(pts) > 1 else 0.0
        out.append(max(span, diameter))
    return out
