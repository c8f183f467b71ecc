"""The Caustic layer's part of the pipeline (`pipeline.plan_scene` calls `prepare`) and
its build: when the resolved tier is CAUSTIC_LAYER, read the receivers from the
depsgraph the plan was read from (`read.receivers`), bake every planned source's layer
in one pipeline call (`core.caustic_layer.pipeline`, the ray budget from each lens' flux
and screen size, capped: `core.caustic_layer.plan`), and build the layers instead of the
lens lights (`build.layers`; with no receiver at all, the planned Fitted spots:
`build.lights`). The bake is part of the plan (a failure changes nothing); the build is
one undo step with the rest of Generate. What it adds to the plan is in the fields
`planning.Work` declares for it (``receivers``, ``layer_bake``, ``layer_sources``,
``layer_figures``).
"""

from __future__ import annotations

import time

from ...core.caustic_layer.pipeline import bake
from ...core.caustic_layer.plan import (
    FACE_BUDGET,
    MAX_RAYS_PER_SOURCE,
    MIN_RAYS_PER_SOURCE,
    RAYS_PER_PIXEL,
    RAYS_PER_TEXEL,
    TOTAL_RAYS,
    VIEW_MAX_RAYS_PER_SOURCE,
    VIEW_MAX_RESOLUTION,
    VIEW_TEXEL_FRACTION,
    figures_of,
    raster_resolution,
    sheet_camera,
    sheet_sources,
)
from ...core.caustic_layer.view import view_of
from ...core.tiers import builds_layer
from ...core.tiers.base import ENGINE_NAMES
from ..build import layers as layer_builder
from ..build import lights as light_builder
from ..read.receivers import read_receivers

#: Render engines that are EEVEE (its identifier before and since Blender 5.0).
EEVEE_ENGINES = frozenset(k for k, v in ENGINE_NAMES.items() if v == "EEVEE")


def prepare(depsgraph, work, options: dict):
    """Stage 1's layer part (changes nothing); returns `work` with ``receivers`` and
    ``layer_bake`` (None: no layer tier or nothing to bake)."""
    work.receivers = work.layer_bake = None
    if not builds_layer(options.get("energy_model")) or not work.plan.lights:
        return work
    read = work.read
    t = time.perf_counter()
    lenses = [
        ob for ob, lens in zip(read.sphere_objects, read.lens_candidates, strict=False) if lens
    ]
    work.receivers = read_receivers(depsgraph, exclude=lenses)
    work.timings["receivers"] = time.perf_counter() - t
    if not len(work.receivers.mesh.triangles):
        return work  # nothing to lay a caustic on
    t = time.perf_counter()
    sources = sheet_sources(work.plan.lights, read.primaries, read.lens_optics, read.arrays)
    cam = depsgraph.scene.camera
    ortho = (
        cam.data.ortho_scale
        if cam is not None and cam.type == "CAMERA" and cam.data.type == "ORTHO"
        else None
    )
    camera = sheet_camera(read.camera, read.width, ortho, [s.lens.center for s in sources])
    has_camera = cam is not None and cam.type == "CAMERA"
    # the rasters follow what the camera sees (without one: the budget's one resolution)
    view = view_of(read.camera, read.width, read.height, ortho) if has_camera else None
    work.layer_sources = sources  # the bake lands them again (core/animation/layer_segments.py)
    work.layer_bake = bake(
        sources,
        work.receivers.mesh,
        camera,
        total_rays=TOTAL_RAYS,
        max_rays=MAX_RAYS_PER_SOURCE if view is None else VIEW_MAX_RAYS_PER_SOURCE,
        min_rays=MIN_RAYS_PER_SOURCE,
        rays_per_pixel=RAYS_PER_PIXEL,
        resolution=VIEW_MAX_RESOLUTION
        if view is not None
        else lambda extents, _pixels: raster_resolution(sources, camera, extents),
        view=view,
        max_texels=FACE_BUDGET,
        texel_fraction=VIEW_TEXEL_FRACTION if view is not None else 0.5,
        rays_per_texel=RAYS_PER_TEXEL if view is not None else None,
    )
    work.timings["bake"] = time.perf_counter() - t
    work.timings.update({f"bake {k}": v for k, v in work.layer_bake.layer.timings.items()})
    return work


def build(scene, work, progress=None) -> list:
    """Stage 2: the layers (and fallback spots); returns every object made and sets
    ``work.layer_figures`` for the report."""
    work.layer_figures = None
    if work.layer_bake is None:  # no receivers: the Fitted spots stand in
        return light_builder.build(scene, work.plan, work.read.sphere_objects)
    layers, lights, fallback = layer_builder.build(
        scene,
        work.layer_bake,
        work.receivers,
        work.plan.lights,
        work.read.sphere_objects,
        progress=progress,
        # EEVEE's reflections do not show blended surfaces: a copy for them
        reflections=scene.render.engine in EEVEE_ENGINES,
    )
    work.layer_figures = figures_of(work.layer_bake, len(lights), fallback)
    return layers + lights
