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

from .beam_trace import BeamGrid, flatten_parts, trace_beams
from .emitters import Lens
from .rasters import (
    NEAR_PIXEL_SHARE,
    TEXELS_PER_PIXEL,
    CausticLayer,
    RasterFrame,
    build_layer,
    grouped_quantiles,
    land_beams,
)
from .ray_budget import RayBudget, allocate, layer_resolution, pixel_size, view_texels
from .receiver_bvh import ReceiverMesh
from .receiver_index import ReceiverIndex, build_index
from .view import View


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
    index: ReceiverIndex | None = None  # the receivers' index it landed on
    # per source, for a glass mesh (`mesh_beam`): (cells refined, cells the refinement
    # budget cut, rays traced); (0, 0, 0) for a ball
    refinement: list[tuple[int, int, int]] | None = None
    # live update's coarse layer (`live.LiveLayer`): the full bake's rasters refilled
    # by coarse beams; the full one follows
    coarse: bool = False
    names: list | None = None  # per source (light, lens) names (the layer stage's)
    receivers_key: bytes = b""  # what it landed on (`layer_stage.receivers_key`)
    # rays traced from the lights (a ball's node rays; a glass mesh's node rays and its
    # refinements' sub-grid rays, not the nodes its parts land; the coarse probe's
    # too): None, the layer's nodes
    rays_traced: int | None = None


def bake(
    sources: list[SheetSource],
    receivers: ReceiverMesh | ReceiverIndex,
    camera: Camera | None = None,
    rays_per_pixel: float = 1.0,
    max_rays: int = 65536,
    total_rays: int = 1_000_000,
    min_rays: int | list[int] = 1024,
    texel_fraction: float = 0.5,
    grid: tuple[int, int] | None = None,
    blur_shares: bool = True,
    resolution: int | Callable[[list[float], list[float]], int] | None = None,
    budgets: list[RayBudget] | None = None,
    raster_frames: list[RasterFrame] | None = None,
    view: View | None = None,
    max_texels: int | None = None,
    rays_per_texel: float | None = None,
) -> SheetBake:
    """Caustic layers of ``sources`` on ``receivers``. The grid per source comes from
    :func:`.ray_budget.allocate` (flux share and caustic extent from a coarse 4 × 16
    trace landed on the receivers, pixel size at the lens from ``camera``) unless
    ``grid`` = (Nr, Na) is given; the raster resolution from :func:`.layer_resolution`
    of the largest extent, or ``resolution(extents, pixels)`` if a callable; no texel
    finer than ``texel_fraction`` of a pixel (a renderer would only alias it).
    ``budgets`` (per source, e.g. an earlier bake's) replace the allocation, and
    ``raster_frames`` the rasters fitted to the landings (`build_layer`): the bake of
    an animation re-lands each frame's beams on rasters fixed over the frames.
    ``view`` (`view.View`, the scene's camera): each raster spans what it sees of its
    caustic, about a texel per pixel there, at most the resolution above per side and
    ``max_texels`` in all (`build_layer`); the bake's ``resolution`` is then the
    largest raster's. With a view and ``rays_per_texel``, a source's rays follow the
    texels its caustic covers there (the span of 99 % of its flux, `TEXELS_PER_PIXEL`
    per pixel where it lands, at most ``resolution`` per side, all sources' at most
    ``max_texels`` together, as their rasters): a closer camera, more rays (within
    ``max_rays`` and ``total_rays``)."""
    index = receivers if isinstance(receivers, ReceiverIndex) else build_index(receivers)
    extents = spans = [2.0 * s.lens.radius for s in sources]
    coarse = []
    if budgets is not None:
        pixels = [math.inf] * len(sources)
    elif grid is not None:
        budgets = [RayBudget(int(grid[0]), int(grid[1])) for _ in sources]
        pixels = [math.inf] * len(sources)
    else:
        coarse = trace_beams([(s.emitter, s.lens) for s in sources], 4, 16)
        own = [s.own_object for s in sources]
        # the rays go where the bulk of the flux is; the texels span nearly all of it
        extents, spans, near = caustic_extents(
            coarse, index, own, extents, bulks=(0.9, 0.99), view=view
        )
        pixels = [
            pixel_size(camera.position, s.lens.center, camera.fov, camera.width_px)
            if camera is not None
            else 2.0 * s.lens.radius / 64.0
            for s in sources
        ]
        texels = None
        if view is not None and rays_per_texel is not None:
            side = resolution if isinstance(resolution, int) else 1 << 30
            texels = [
                view_texels(sp, px, TEXELS_PER_PIXEL, side)
                for sp, px in zip(spans, near, strict=True)
            ]
            # the rasters share ``max_texels``: so do the rays that fill them
            total = float(sum(texels))
            if max_texels is not None and total > max_texels:
                texels = [t * max_texels / total for t in texels]
        budgets = allocate(
            [b.total_flux for b in coarse],
            extents,
            pixels,
            total_rays=total_rays,
            rays_per_pixel=rays_per_pixel,
            max_rays=max_rays,
            min_rays=min_rays,
            samples=[s.n_source for s in sources],
            texels=texels,
            rays_per_texel=rays_per_texel or 1.0,
        )
    if callable(resolution):
        resolution = resolution(spans, pixels)
    elif resolution is None:
        resolution = max(
            (layer_resolution(e, p) for e, p in zip(spans, pixels, strict=True)), default=16
        )
    # one vectorised trace per grid shared by several sources
    beams = [None] * len(sources)
    groups: dict[tuple[int, int, int], list[int]] = {}
    for i, (s, b) in enumerate(zip(sources, budgets, strict=True)):
        groups.setdefault((b.n_radial, b.n_azimuth, s.n_source), []).append(i)
    for (nr, na, k), ids in groups.items():
        traced = trace_beams(
            [(sources[i].emitter, sources[i].lens) for i in ids],
            nr,
            na,
            k,
            [sources[i].blockers for i in ids],
        )
        for i, beam in zip(ids, traced, strict=True):
            beams[i] = beam
    own = [s.own_object for s in sources]
    layer = build_layer(
        beams,
        index,
        resolution=resolution,
        own_objects=own if any(o >= 0 for o in own) else None,
        min_texel=[texel_fraction * p if math.isfinite(p) else 0.0 for p in pixels],
        blur_shares=blur_shares,
        raster_frames=raster_frames,
        view=view,
        max_texels=max_texels,
    )
    if view is not None and layer.patches:
        resolution = max(p.resolution for p in layer.patches)
    refinement = [(b.refined_cells, b.cut_cells, b.traced_rays) for b in beams]
    out = SheetBake(layer, budgets, int(resolution), index, refinement)
    # a glass mesh lands more nodes than it traces (each quad's own corners) and traces
    # refinement rays it lands as splats: its own count; a ball's nodes are its rays
    # (the coarse probe's rays, which placed them, are traced too)
    out.rays_traced = sum(b.traced_rays or b.n_rays for b in [*coarse, *beams])
    return out


def caustic_extents(
    coarse: list[BeamGrid],
    index: ReceiverIndex,
    own_objects,
    diameters,
    bulks=(0.9,),
    view: View | None = None,
) -> list[list[float]]:
    """Per share in ``bulks``, per coarse beam, the size of its caustic on the
    receivers: the lens' diameter, or the span of that central share of its landed
    flux if larger (per world axis; a grazing receiver stretches the caustic far beyond
    the lens). Then, per beam, the pixel of ``view`` where it lands in view (the
    `NEAR_PIXEL_SHARE` quantile of its flux there, as the rasters take it; inf: none in
    view; all inf without a view)."""
    if not coarse:
        return [[] for _ in bulks] + [[]]
    flat, owner = flatten_parts(coarse)  # a glass mesh's parts count for its beam
    own = [int(o) for o in np.asarray(list(own_objects), dtype=np.int64)[owner]]
    landed = land_beams(flat, index, own if any(o >= 0 for o in own) else None)
    beam = np.concatenate([np.full(len(lb.patch), owner[i]) for i, lb in enumerate(landed)])
    on = np.concatenate([lb.patch >= 0 for lb in landed])
    pts = np.concatenate([lb.point for lb in landed])[on]
    w = np.concatenate([lb.node_flux for lb in landed])[on] + 1e-300
    beam = beam[on]
    hit = np.bincount(beam, minlength=len(coarse)) > 1
    # beams with fewer than two landings keep their diameter (a dummy landing each)
    missing = np.nonzero(~hit)[0]
    beam = np.concatenate([beam, missing])
    pts = np.concatenate([pts, np.zeros((len(missing), 3))])
    w = np.concatenate([w, np.ones(len(missing))])
    near = [math.inf] * len(coarse)
    if view is not None:
        seen = view.in_view(pts) & (np.arange(len(pts)) < len(pts) - len(missing))
        if np.any(seen):  # one sort for all beams seen
            ids, group = np.unique(beam[seen], return_inverse=True)
            q = grouped_quantiles(
                view.pixel(pts[seen]), w[seen], group, len(ids), [NEAR_PIXEL_SHARE]
            )
            for i, v in zip(ids.tolist(), q[:, 0].tolist(), strict=True):
                near[i] = v
    qs = [q for b in bulks for q in (0.5 * (1.0 - b), 0.5 * (1.0 + b))]
    per_axis = [grouped_quantiles(pts[:, a], w, beam, len(coarse), qs) for a in range(3)]
    diam = np.asarray(diameters, dtype=float)
    out = []
    for k in range(len(bulks)):
        span = np.max([q[:, 2 * k + 1] - q[:, 2 * k] for q in per_axis], axis=0)
        out.append([float(v) for v in np.maximum(np.where(hit, span, 0.0), diam)])
    return out + [[float(p) for p in near]]
