"""One call from lens lights to caustic layers: budget, trace, land, accumulate.

What the Blender side calls once per bake (or per frame): the (light, lens) pairs of
phase 1 as :mod:`.emitters` data, the receivers as a :class:`.ReceiverMesh` (or an index
built once per scene), and a camera estimate for the ray budget.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .beam_trace import trace_beam
from .caustic_layer import CausticLayer, build_layer
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
    blockers: object = None  # shadow.ShadowList: the shadow list drawn in the beam


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
    resolution: int | None = None,
) -> SheetBake:
    """Caustic layers of ``sources`` on ``receivers``. The grid per source comes from
    :func:`.ray_budget.allocate` (flux share from a coarse 4 × 16 trace, extent the lens'
    diameter, pixel size at the lens from ``camera``) unless ``grid`` = (Nr, Na) is given;
    the raster resolution from :func:`.layer_resolution` unless given."""
    index = receivers if isinstance(receivers, ReceiverIndex) else build_index(receivers)
    if grid is not None:
        budgets = [RayBudget(int(grid[0]), int(grid[1])) for _ in sources]
        pixels = [math.inf]
    else:
        coarse = [trace_beam(s.emitter, s.lens, 4, 16, s.n_source).total_flux for s in sources]
        pixels = [
            pixel_size(camera.position, s.lens.center, camera.fov, camera.width_px)
            if camera is not None
            else 2.0 * s.lens.radius / 64.0
            for s in sources
        ]
        budgets = allocate(
            coarse,
            [2.0 * s.lens.radius for s in sources],
            pixels,
            total_rays=total_rays,
            rays_per_pixel=rays_per_pixel,
            max_rays=max_rays,
        )
    if resolution is None:
        resolution = max(
            (
                layer_resolution(2.0 * s.lens.radius, p)
                for s, p in zip(sources, pixels, strict=False)
            ),
            default=16,
        )
    beams = [
        trace_beam(s.emitter, s.lens, b.n_radial, b.n_azimuth, s.n_source, s.blockers)
        for s, b in zip(sources, budgets, strict=True)
    ]
    own = [s.own_object for s in sources]
    layer = build_layer(
        beams, index, resolution=resolution, own_objects=own if any(o >= 0 for o in own) else None
    )
    return SheetBake(layer, budgets, int(resolution))
