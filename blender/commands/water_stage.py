"""Water's part of Generate (issue 26): after the plan (`pipeline.plan_scene`), the
open glass meshes that are water (`read.water`) are taken out of the glass left out,
the receivers read without them, every (light, water) pair traced through its
surface and landed under it in one layer (`core.caustic_layer.water_sources`), and
built with the other layers (`build.layers`) in Generate's undo step, in every tier
and both engines. Its objects are marked (`marks.WATER_MARK`).

Bake: each frame's stage as the layer's bake takes it (`frame_layers`: the pairs
keyed by (light, water) names, the re-landing of the same rays on the bake's fixed
rasters). Live update: the stage run again on every update, its layers written into
the water's layer objects in place where the patches are the same (`refill`), else
those alone made again (`replace`); the glass layers and lens lights are not
touched.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from ...core.animation.layer_segments import FrameLayers, plan_segments
from ...core.caustic_layer.plan import (
    FACE_BUDGET,
    SOURCE_SAMPLES,
    VIEW_MAX_RESOLUTION,
    figures_of,
    sheet_camera,
)
from ...core.caustic_layer.rasters import RasterFrame
from ...core.caustic_layer.ray_budget import pixel_size
from ...core.caustic_layer.view import view_of
from ...core.caustic_layer.water_beam import WaterSource
from ...core.caustic_layer.water_sources import WATER_RAYS, rays_for, water_bake, water_sources
from ...core.lens.water import WaterSurface
from ...core.scene.water import water_text
from ..build import layers as layer_builder
from ..build.marks import WATER_MARK
from ..build.ownership import created_objects
from ..read.receivers import read_receivers
from ..read.water import read_water, take_water
from .layer_stage import EEVEE_ENGINES, receivers_key


@dataclass
class WaterStage:
    """What the stage read and baked: the water surfaces, the pairs ((light, water)
    indices per source), the receivers under water and the layer's bake (None:
    nothing to bake), the figures for the report."""

    waters: list = field(default_factory=list)
    pairs: list = field(default_factory=list)
    receivers: object = None
    bake: object = None
    figures: object = None
    sources: list = field(default_factory=list)  # `water_beam.WaterSource` per pair
    rays: list = field(default_factory=list)  # node rays per pair (the bake's re-landing)


@dataclass
class FixedRasters:
    """A bake's water rasters, fixed from its first frame with water (`fixed_rasters`):
    the later frames land on them at once when their pairs (``keys``), receivers
    (``receivers``: `layer_stage.receivers_key`) and camera (``view``: the texels
    follow it) are that frame's."""

    keys: list
    receivers: bytes
    view: str
    given: list  # `rasters.RasterFrame` per baked layer
    resolution: int


def prepare(depsgraph, work, fixed: FixedRasters | None = None):
    """Read and bake the water of ``work``'s scene (changes nothing); returns `work`
    with ``work.water`` set. ``fixed`` (a bake's): its rasters filled instead of
    rasters fitted to this frame's landings, where this frame's pairs and receivers
    are theirs."""
    stage = work.water = WaterStage()
    read = work.read
    t = time.perf_counter()
    waters, _not_water = read_water(depsgraph, read)  # not water: left out as before
    if not waters:
        return work
    take_water(read, waters)
    stage.waters = waters
    lenses = [
        ob for ob, lens in zip(read.sphere_objects, read.lens_candidates, strict=False) if lens
    ]
    lenses += [m.orig for m in getattr(read, "mesh_lenses", [])]
    stage.receivers = read_receivers(depsgraph, exclude=lenses + [w.orig for w in waters])
    work.timings["water read"] = time.perf_counter() - t
    if not len(stage.receivers.mesh.triangles):
        return work
    t = time.perf_counter()
    # an extended light (a radius, a sun's angle): its samples' images blur the net
    sources, stage.pairs, _left = water_sources(
        read.primary_lights, waters, n_source=SOURCE_SAMPLES
    )
    if not sources:
        return work
    cam = depsgraph.scene.camera
    has_camera = cam is not None and cam.type == "CAMERA"
    ortho = cam.data.ortho_scale if has_camera and cam.data.type == "ORTHO" else None
    view = view_of(read.camera, read.width, read.height, ortho) if has_camera else None
    # about two rays per pixel's length on the water, as the camera sees it
    centers = [s.surface.center for s in sources]
    cam_est = sheet_camera(read.camera, read.width, ortho, centers)
    rays = [
        rays_for(s.surface, pixel_size(cam_est.position, c, cam_est.fov, cam_est.width_px))
        if has_camera
        else WATER_RAYS
        for s, c in zip(sources, centers, strict=True)
    ]
    stage.sources, stage.rays = sources, rays
    if fixed is not None and land_on(work, fixed):
        work.timings["water bake"] = time.perf_counter() - t
        return work
    stage.bake = water_bake(
        sources,
        stage.receivers.mesh,
        n_rays=rays,
        resolution=VIEW_MAX_RESOLUTION,
        view=view,
        max_texels=FACE_BUDGET,
    )
    work.timings["water bake"] = time.perf_counter() - t
    return work


def build(scene, work) -> list:
    """The water's layers (and their reflection copies in EEVEE): every object made."""
    stage = work.water
    if stage is None or stage.bake is None:
        return []
    names = pair_names(work)
    made, _lights, fallback = layer_builder.build(
        scene,
        stage.bake,
        stage.receivers,
        [],
        [],
        None,
        names,
        reflections=scene.render.engine in EEVEE_ENGINES,
    )
    stage.figures = figures_of(stage.bake, 0, fallback)
    for ob in made:
        ob[WATER_MARK] = True
    return made


def is_water_layer(ob) -> bool:
    """Is `ob` (the extension's) a water surface's layer or its reflection copy?"""
    return bool(ob.get(WATER_MARK))


def water_layers(scene) -> list:
    """The extension's water layer objects in `scene`."""
    return [ob for ob in created_objects(scene) if is_water_layer(ob)]


def pair_names(work) -> list:
    """(light, water) names per pair: the layers' words and the bake's keys."""
    stage = work.water
    return [(work.read.light_sources[j], stage.waters[k].name) for j, k in stage.pairs]


def frame_layers(work, light: bool = False):
    """``work``'s water as one frame of a bake (`layer_segments.FrameLayers`: keys
    ("water", light, water) per pair; its re-landing traces the same rays, Generate's,
    onto the bake's rasters), or None when the frame has no water layer. Receivers
    drawn by a fallback (glossy, transparent) get no layer, as in Generate. ``light``:
    keep only the surfaces' arrays (not their BVH and grid, rebuilt if a re-landing
    is needed): a bake holds every frame."""
    stage = work.water
    if stage is None or stage.bake is None:
        return None
    infos = stage.receivers.objects
    rays, index = stage.rays, stage.bake.index
    sources = [_Kept.of(s) for s in stage.sources] if light else stage.sources

    def reland(given, res):
        traced = [s.source() for s in sources] if light else sources
        return water_bake(
            traced, index, n_rays=rays, resolution=res, raster_frames=given
        ).layer.patches

    return FrameLayers(
        sources,
        stage.bake,
        [("water", light, water) for light, water in pair_names(work)],
        [info.name for info in infos],
        frozenset(k for k, info in enumerate(infos) if info.fallback),
        reland=reland,
    )


@dataclass
class _Kept:
    """A `WaterSource` without its surface's search structures (the bake's frames)."""

    emitter: object
    arrays: tuple  # vertices, triangles, corner normals, ior, absorption
    n_source: int
    own_object: int

    @classmethod
    def of(cls, source):
        w = source.surface
        arrays = (w.vertices, w.triangles.astype(np.int32), w.corner_normals, w.ior, w.absorption)
        return cls(source.emitter, arrays, source.n_source, source.own_object)

    def source(self):
        return WaterSource(self.emitter, WaterSurface(*self.arrays), self.n_source, self.own_object)


def note(work) -> str:
    """The report's words: each water surface taken, with the receivers its caustic
    lies on, and the water no light reaches ("" when there is no water)."""
    stage = work.water
    if stage is None or not stage.waters:
        return ""
    under: dict[int, set] = {}
    if stage.bake is not None:
        for p in stage.bake.layer.patches:
            name = stage.receivers.objects[p.object_id].name
            for s in p.sources:
                under.setdefault(stage.pairs[int(s)][1], set()).add(name)
    lit = sorted({k for _j, k in stage.pairs})
    taken = [
        (stage.waters[k].name, stage.waters[k].n_triangles, sorted(under.get(k, ()))) for k in lit
    ]
    unlit = [w.name for k, w in enumerate(stage.waters) if k not in set(lit)]
    text = water_text(taken, unlit)
    if stage.figures is not None:
        text += f" ({stage.figures.text()})"
    return text


def refill(scene, work, existing) -> bool:
    """The stage's layers written into the water's layer objects `existing` (and
    through their shared meshes their reflection copies) in place, when they are
    the layers of the same patches on the same receivers, in order; False: nothing
    written (`replace` them)."""
    stage = work.water
    if stage is None or stage.bake is None:
        return False
    infos = stage.receivers.objects
    patches = [p for p in stage.bake.layer.patches if not infos[p.object_id].fallback]
    obs = [ob for ob in existing if not layer_builder.is_reflection(ob)]
    copies = len(existing) - len(obs)
    reflections = scene.render.engine in EEVEE_ENGINES
    if len(obs) != len(patches) or copies != (len(obs) if reflections else 0):
        return False
    for ob, p in zip(obs, patches, strict=True):
        if ob.data is None or ob.lens_lights.receiver != infos[p.object_id].name:
            return False
    names = pair_names(work)
    for ob, p in zip(obs, patches, strict=True):
        layer_builder.refill_layer(ob, p, names)
    return True


def fixed_rasters(work) -> FixedRasters | None:
    """The rasters a bake fixes from ``work``'s water (this frame's layer as one
    frame of `layer_segments`: every raster of the bake's one resolution), or None
    without a water layer."""
    fl = frame_layers(work)
    if fl is None:
        return None
    segs, res = plan_segments([fl])
    given = [RasterFrame(*s.members[0], *s.plane, s.axes, s.key[-1]) for s in segs]
    return FixedRasters(
        fl.source_keys, receivers_key(work.water.receivers), _view_key(work.read), given, res
    )


def _view_key(read) -> str:
    """What the rasters' texels follow: the camera and the render's size."""
    return repr((read.camera, read.width, read.height))


def land_on(work, fixed: FixedRasters) -> bool:
    """``work``'s water traced and landed on the ``fixed`` rasters (its bake replaced)
    when its pairs, receivers and camera are theirs: a bake's frames then share one
    topology and need no second landing (`layer_segments.bake_frames` keeps a frame
    whose rasters are the bake's). False: nothing done (the pairs, receivers or
    camera differ)."""
    stage = work.water
    if not stage.sources or stage.receivers is None:
        return False
    keys = [("water", light, water) for light, water in pair_names(work)]
    if keys != fixed.keys or receivers_key(stage.receivers) != fixed.receivers:
        return False
    if _view_key(work.read) != fixed.view:  # the camera moved: its own texels
        return False
    index = stage.bake.index if stage.bake is not None else stage.receivers.mesh
    stage.bake = water_bake(
        stage.sources,
        index,
        n_rays=stage.rays,
        resolution=fixed.resolution,
        raster_frames=fixed.given,
    )
    return True
