"""The Caustic layer tier's plain-data side (no bpy): planned lens lights →
caustic-sheet sources (`core.caustic_layer.pipeline.SheetSource`), the camera
estimate of the ray budget, which receivers a layer cannot show, and the report.

Every primary reaches the layer as the point light that stands for it toward the
lens (`tiers.base.effective_primary`: a spot's cone share, an area light's
Lambertian intensity, a sun as a far point light at its equivalent distance), at
``lens centre − D·axis``. Its power carries the lens material's transmission
weight² and the unblocked share of the lit cap, as the spot tiers do; the lens
tint and the axial Beer–Lambert colour (`tiers.base.glass_color`) are its colour.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..lens.glass import LensOptics
from ..shared.words import share_text
from ..tiers.base import effective_primary, glass_color, unblocked_share
from .emitters import Lens, PointLight
from .pipeline import Camera, SheetSource
from .ray_budget import layer_resolution, pixel_size
from .shadow import ShadowList

#: Node rays for all sources together, and per source (the ray budget's caps); rays
#: per pixel² of a caustic's extent on screen (the sub-cells interpolate between them).
TOTAL_RAYS = 400_000
MAX_RAYS_PER_SOURCE = 16_384
MIN_RAYS_PER_SOURCE = 256
RAYS_PER_PIXEL = 0.5
#: With a camera: rays per texel the caustic covers in view (all samples of an extended
#: light together), up to this many per source. Fewer leave the faint halo's landed
#: cells tens of texels long, drawn as dashes (a close-up's lit table of 0.47: up to
#: +0.62 at 4 608 rays, +0.27 at 16 384, none at 51 968–65 536; bench/layer_mirror.py).
RAYS_PER_TEXEL = 1.0
VIEW_MAX_RAYS_PER_SOURCE = 65_536
#: Texels per side of a layer raster at most without a camera (every raster alike) and
#: with one (each raster spans what it sees of its caustic, about a texel per pixel),
#: and the texels of all layers together (many lenses: coarser rasters, a fast build).
MAX_RESOLUTION = 128
VIEW_MAX_RESOLUTION = 256
FACE_BUDGET = 65_536
#: With a camera, no texel finer than this share of a pixel at its lens (the drawn
#: irradiance is interpolated, so finer texels sharpen a small focus instead of
#: aliasing; without a camera, half a pixel).
VIEW_TEXEL_FRACTION = 0.25
#: Samples of an extended primary's disc (they share its ray budget).
SOURCE_SAMPLES = 16
#: A receiver this metallic or transmissive is no diffuse surface: a Fitted spot.
GLOSSY_METALLIC = 0.5
TRANSPARENT_TRANSMISSION = 0.5


def sheet_source(planned, primary, optics: LensOptics | None = None, arrays=None) -> SheetSource:
    """The caustic-sheet source of one `planning.PlannedLight` (`arrays`: phase 1's
    `SceneArrays`, for the shadow list drawn in the beam)."""
    src = planned.source
    optics = optics or LensOptics()
    eff = effective_primary(src, primary)
    axis = np.asarray(src.axis, dtype=float)
    axis = axis / np.linalg.norm(axis)
    center = np.asarray(src.lens_center, dtype=float)
    wgt = min(max(float(optics.transmission_weight), 0.0), 1.0)
    power = eff.power_w * wgt * wgt * unblocked_share(src)
    color = glass_color(src, eff, optics)
    emitter = PointLight(
        position=center - float(src.distance) * axis,
        power=float(power),
        radius=float(eff.radius),
        color=tuple(float(c) for c in color),
    )
    lens = Lens(center=center, radius=float(src.lens_radius), ior=float(src.ior))
    # An extended primary blurs the caustic (SPEC §10): samples of its disc, each
    # image spread over its share (`caustic_layer._splat_cells`).
    n_source = 1 if eff.radius <= 0.0 else SOURCE_SAMPLES
    return SheetSource(emitter, lens, n_source=n_source, blockers=ShadowList.of(src, arrays))


def sheet_sources(planned_lights, primaries, lens_optics=None, arrays=None) -> list[SheetSource]:
    return [
        sheet_source(
            p,
            primaries[p.source.light],
            lens_optics[p.source.lens] if lens_optics else None,
            arrays,
        )
        for p in planned_lights
    ]


def sheet_camera(camera, width_px: int, ortho_scale: float | None = None, targets=None) -> Camera:
    """The ray budget's camera from the read's `core.scene.model.Camera` (horizontal fov).
    An orthographic camera (`ortho_scale`: the width it sees) has the same pixel
    everywhere: the perspective camera whose pixel matches it at the mean distance
    of `targets` (the lens centres) stands for it."""
    pos = np.asarray(camera.position, dtype=float)
    fov = math.radians(float(camera.fov_deg[0])) if camera.fov_deg else math.radians(45.0)
    if ortho_scale and targets is not None and len(targets):
        dist = float(np.mean(np.linalg.norm(np.asarray(targets, float) - pos, axis=1)))
        if dist > 0:
            fov = 2.0 * math.atan(0.5 * float(ortho_scale) / dist)
    return Camera(pos, fov, max(int(width_px), 16))


def raster_resolution(sources, camera: Camera, extents=None) -> int:
    """Without a view of the scene (no camera): one texel per pixel of the largest
    caustic (`ray_budget.layer_resolution`; its extent per source, by default the lens'
    diameter), at most `MAX_RESOLUTION` and so that all layers keep within
    `FACE_BUDGET` texels."""
    if extents is None:
        extents = [2.0 * s.lens.radius for s in sources]
    res = max(
        layer_resolution(e, pixel_size(camera.position, s.lens.center, camera.fov, camera.width_px))
        for s, e in zip(sources, extents, strict=True)
    )
    share = math.isqrt(FACE_BUDGET // max(len(sources), 1))
    return int(min(res, MAX_RESOLUTION, max(share, 16)))


def fallback_reason(metallic: float, transmission: float, glossy_only: bool) -> str:
    """Why a receiver cannot take a layer ("" if it can): the layer is a diffuse
    radiance (irradiance × albedo / π); a mirror or glass shows no such thing."""
    if glossy_only or metallic >= GLOSSY_METALLIC:
        return "glossy"
    if transmission >= TRANSPARENT_TRANSMISSION:
        return "transparent"
    return ""


@dataclass
class LayerFigures:
    """What a bake made, for the report."""

    layers: int = 0
    faces: int = 0
    rays: int = 0  # traced from the lights (`SheetBake.rays_traced`)
    flux_emitted: float = 0.0
    flux_in_layers: float = 0.0
    flux_lost: float = 0.0  # missed every receiver
    flux_outside: float = 0.0  # on a receiver, outside every layer (beyond a raster's edge)
    fallback_lights: int = 0
    fallback_receivers: tuple = ()
    coarse: int = 0  # layers of a caustic out of the camera's view (drawn coarsely)
    #: "Rod on Mirror (glossy)": a glass mesh's light on a receiver the layer cannot
    #: draw on, where no lens light stands in for it (`undrawn_glass`)
    undrawn: tuple = ()

    def text(self) -> str:
        shares = (
            (share_text(self.flux_lost, self.flux_emitted), "missed every receiver"),
            (
                share_text(self.flux_outside, self.flux_emitted),
                "landed outside the layers (past their edge)",
            ),
        )
        parts = [f"{share} {what}" for share, what in shares if share]
        # (the report's first words count the layers and fallback spots: not said again)
        out = f"{self.faces} texels and {self.rays} rays traced from the lights" + (
            f"; of the flux, {' and '.join(parts)}" if parts else ""
        )
        if self.coarse:  # drawn: a mirror may show them
            out += (
                f"; {self.coarse} of the layers coarse, where the camera does not see the "
                "caustic (for reflections) or for a glass's faint light far from its caustic"
            )
        if self.undrawn:
            out += (
                f"; not drawn: the light through {', '.join(self.undrawn)} (a glass mesh's "
                "caustic on a glossy or transparent receiver has no lens light to stand in)"
            )
        return out


def undrawn_glass(patches, receiver_of, first_mesh: int, glass_names) -> tuple:
    """ "Rod on Mirror (glossy)" for each glass mesh (its sources from `first_mesh` on,
    named by `glass_names`) whose light lands on a receiver the layer cannot draw on
    (``receiver_of(patch)``: its name and "glossy", "transparent" or "")."""
    out = set()
    for patch in patches:
        name, why = receiver_of(patch)
        for s in (int(x) for x in patch.sources):
            if why and first_mesh <= s < first_mesh + len(glass_names):
                out.add(f"{glass_names[s - first_mesh]} on {name} ({why})")
    return tuple(sorted(out))


def figures_of(bake, fallback_lights: int = 0, fallback_receivers=(), undrawn=()) -> LayerFigures:
    layer = bake.layer
    return LayerFigures(
        layers=len(layer.patches),
        faces=sum(p.resolution**2 for p in layer.patches),  # texels
        rays=int(layer.n_rays if bake.rays_traced is None else bake.rays_traced),
        flux_emitted=float(layer.flux_emitted),
        flux_in_layers=float(layer.flux_in_rasters),
        flux_lost=float(layer.flux_lost),
        flux_outside=float(layer.flux_outside),
        fallback_lights=fallback_lights,
        fallback_receivers=tuple(fallback_receivers),
        coarse=sum(1 for p in layer.patches if p.coarse),
        undrawn=tuple(undrawn),
    )
