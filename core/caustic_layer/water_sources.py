"""The water surfaces' (light, water) pairs and their layer, in one call (issue 26).

Every light above a water surface (`core.scene.water.WaterRead`) lights the receivers
under it through the surface: each pair is a `water_beam.WaterSource` (the light as
`emitters` data, exactly its type — a sun stays parallel — with its colour times the
water's tint of one crossing and its power times the transmission weight), and all
pairs' beams land in one `rasters.build_layer` on the receivers (the water surfaces
themselves not among them). Phase 1's obstruction is not run for water: what stands
between a light and the water (a diving board) does not shadow the net yet.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..lens.water import WaterSurface
from ..scene.primaries import AreaPrimary, PointPrimary, SpotPrimary, SunPrimary
from .emitters import AreaLight, PointLight, SpotLight, SunLight
from .pipeline import SheetBake
from .rasters import RasterFrame, build_layer
from .ray_budget import RayBudget
from .receiver_bvh import ReceiverMesh
from .receiver_index import ReceiverIndex, build_index
from .water_beam import WaterSource, grid_shape, trace_water_beams

#: Node rays per (light, water) pair without a camera: a 512² grid.
WATER_RAYS = 512 * 512
#: With a camera: rays this many per pixel's length on the water (2: 4 rays per
#: pixel²), within these bounds per pair.
RAYS_PER_PIXEL_SIDE = 2.0
MIN_WATER_RAYS, MAX_WATER_RAYS = 128 * 128, 1024 * 1024
#: Bilinear sub-cells per texel side when a cell lands (the layer's default is 2): a
#: net's cells are about a texel each, and their sub-cells deposited as points alias
#: (a flat-lit floor's texels: ±15–25 % at 2, ±10–15 % at 4, ±5–7 % at 8).
WATER_SUBCELLS_PER_TEXEL = 8.0


def emitter_of(primary, tint=(1.0, 1.0, 1.0), weight: float = 1.0):
    """The `emitters` light of a `core.scene.primaries` light, its power (or a sun's
    strength) × ``weight`` and colour × ``tint``; None for a type it does not know."""
    color = tuple(float(c) * float(t) for c, t in zip(primary.color, tint, strict=True))
    w = float(weight)
    if isinstance(primary, SunPrimary):
        return SunLight(np.asarray(primary.direction, float), primary.strength * w,
                        float(primary.angle), color)  # fmt: skip
    if isinstance(primary, SpotPrimary):
        return SpotLight(
            np.asarray(primary.position, float), np.asarray(primary.direction, float),
            primary.power_w * w, float(primary.spot_size), float(primary.blend),
            float(primary.radius), color,
        )  # fmt: skip
    if isinstance(primary, PointPrimary):
        return PointLight(np.asarray(primary.position, float), primary.power_w * w,
                          float(primary.radius), color)  # fmt: skip
    if isinstance(primary, AreaPrimary):
        return AreaLight(
            np.asarray(primary.position, float), np.asarray(primary.direction, float),
            np.asarray(primary.axis_x, float), primary.power_w * w, float(primary.size_x),
            float(primary.size_y), str(primary.shape), color,
        )  # fmt: skip
    return None


def surface_of(water) -> WaterSurface:
    """The `core.lens.water` surface of a `WaterRead`."""
    return WaterSurface(
        water.vertices, water.triangles, water.corner_normals, water.ior, water.absorption
    )


def rays_for(surface: WaterSurface, pixel: float) -> int:
    """Node rays for a water surface seen with pixels of ``pixel`` length there:
    `RAYS_PER_PIXEL_SIDE` per pixel along each side of its extent, within
    `MIN_WATER_RAYS` … `MAX_WATER_RAYS`."""
    pl = surface.plane
    area = (pl.u_range[1] - pl.u_range[0]) * (pl.v_range[1] - pl.v_range[0])
    if not (pixel > 0.0 and math.isfinite(pixel)):
        return WATER_RAYS
    n = area * (RAYS_PER_PIXEL_SIDE / pixel) ** 2
    return int(min(max(n, MIN_WATER_RAYS), MAX_WATER_RAYS))


def _above(primary, surface: WaterSurface) -> bool:
    """Whether the light reaches the water from above (a sun shining down on it, a
    lamp above its highest wave)."""
    pl = surface.plane
    if isinstance(primary, SunPrimary):
        return float(np.asarray(primary.direction, float) @ pl.normal) < 0.0
    pos = np.asarray(primary.position, float)
    return float((pos - pl.origin) @ pl.normal) > pl.top


def water_sources(primary_lights, waters, own_objects=None, n_source: int = 1):
    """(the `WaterSource` of every (light, water) pair whose light is above the water,
    the pair of each as (light index, water index), the pairs left out as (light
    index, water index, why)). ``own_objects``: per water its object id among the
    receivers (−1: not there)."""
    surfaces = [surface_of(w) for w in waters]
    sources, pairs, left = [], [], []
    for k, (w, surf) in enumerate(zip(waters, surfaces, strict=True)):
        own = -1 if own_objects is None else int(own_objects[k])
        for j, prim in enumerate(primary_lights):
            if not _above(prim, surf):
                left.append((j, k, "the light is not above the water"))
                continue
            e = emitter_of(prim, w.tint, w.transmission_weight)
            if e is None:
                left.append((j, k, "a light type the water layer does not know"))
                continue
            extended = getattr(prim, "radius", 0.0) > 0.0 or getattr(prim, "angle", 0.0) > 0.0
            sources.append(WaterSource(e, surf, n_source if extended else 1, own))
            pairs.append((j, k))
    return sources, pairs, left


def water_bake(
    sources,
    receivers: ReceiverMesh | ReceiverIndex,
    n_rays: int | list[int] = WATER_RAYS,
    resolution: int = 256,
    view=None,
    max_texels: int | None = None,
    raster_frames: list[RasterFrame] | None = None,
) -> SheetBake:
    """The caustic layer of every water source on ``receivers`` (a `SheetBake`, as
    `pipeline.bake` gives; ``budgets`` (ny, nx) per source as `RayBudget`s);
    ``n_rays``: node rays per source (one number for all, or one each).
    ``raster_frames`` (their ``beams``: source indices, as the layer's patches name
    them): the rasters to fill instead of those fitted to the landings (the bake's
    fixed topology, `core.animation.layer_segments`); the same ``n_rays`` trace the
    same rays, so a frame's beams land again exactly as Generate's did."""
    index = receivers if isinstance(receivers, ReceiverIndex) else build_index(receivers)
    beams, owner, budgets = [], [], []
    rays = [n_rays] * len(sources) if np.ndim(n_rays) == 0 else list(n_rays)
    for i, s in enumerate(sources):
        shape = grid_shape(s.surface, max(int(rays[i]) // max(s.n_source, 1), 4))
        made = trace_water_beams(s, index, shape)
        beams += made
        owner += [i] * len(made)
        budgets.append(RayBudget(shape[0], shape[1] + 1))
    own = [sources[i].own_object for i in owner]
    if raster_frames is not None:  # sources → their beams (a tint's three channels)
        of = np.asarray(owner, dtype=np.int64)
        raster_frames = [
            dataclasses.replace(rf, beams=tuple(np.nonzero(np.isin(of, rf.beams))[0].tolist()))
            for rf in raster_frames
        ]
    layer = build_layer(
        beams,
        index,
        resolution=resolution,
        own_objects=own if any(o >= 0 for o in own) else None,
        view=view,
        max_texels=max_texels,
        subcells_per_texel=WATER_SUBCELLS_PER_TEXEL,
        raster_frames=raster_frames,
    )
    # a coloured absorption makes a beam per channel: the layer's sources are beams
    for p in layer.patches:
        p.sources = np.unique(np.asarray(owner, dtype=np.int64)[np.asarray(p.sources, int)])
    res = max((p.resolution for p in layer.patches), default=int(resolution))
    refinement = [(0, 0, b.n_rays * s.n_source) for b, s in zip(budgets, sources, strict=True)]
    return SheetBake(layer, budgets, int(res), index, refinement)
