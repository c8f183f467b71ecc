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

The glass meshes read as lenses (`read.mesh_lenses`, issue 25) have no lens light:
their (light, lens) pairs (`core.caustic_layer.mesh_sources`) are baked here in every
tier and both engines, after the spheres' sources when the spheres' tier is the
layer's, alone otherwise (`build_mesh_layers` then builds their layers beside the
spheres' lens lights). Without the mesh lens kind (`core.lens.kinds`) they are
reported as glass it cannot model, and Cycles keeps its own caustics for them.
"""

from __future__ import annotations

import hashlib
import time

import numpy as np

from ...core.animation.light_keys import keys_of
from ...core.caustic_layer.mesh_sources import (
    MESH_KIND,
    MESH_TEXEL_SHARE,
    budget_cuts,
    members_of,
    mesh_facets,
    mesh_min_rays,
    mesh_sheet_sources,
)
from ...core.caustic_layer.pipeline import SheetBake, bake
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
    undrawn_glass,
)
from ...core.caustic_layer.ray_budget import pixel_size
from ...core.caustic_layer.view import view_of
from ...core.lens.kinds import LENS_KINDS
from ...core.phase1.skip_reasons import Reason, SkippedPair
from ...core.report.message import mesh_lenses_text
from ...core.tiers import builds_layer
from ...core.tiers.base import ENGINE_NAMES
from ..build import layers as layer_builder
from ..build import lights as light_builder
from ..read.receivers import read_receivers

#: Render engines that are EEVEE (its identifier before and since Blender 5.0).
EEVEE_ENGINES = frozenset(k for k, v in ENGINE_NAMES.items() if v == "EEVEE")


def prepare(depsgraph, work, options: dict, live=None, full_plan=None):
    """Stage 1's layer part (changes nothing); returns `work` with ``receivers`` and
    ``layer_bake`` (None: no layer tier or nothing to bake). ``live``
    (`core.caustic_layer.live.LiveLayer`, live update while the user drags): the
    coarse layer in the last full bake's rasters when it can stand for it
    (``layer_bake.coarse``), else the full bake, of the plan ``full_plan()`` when
    given (`work`'s was made for a coarse layer: `pipeline.plan_scene`)."""
    work.receivers = work.layer_bake = None
    read = work.read
    spheres = builds_layer(options.get("energy_model")) and bool(work.plan.lights)
    if spheres:  # a light with its own linking: no layer (lens lights keep it)
        _leave_out_linked(work)
        spheres = bool(work.plan.lights)
    meshes = mesh_sources_of(read, work.timings, options.get("max_lights"))
    if not spheres and not meshes:
        return work
    t = time.perf_counter()
    lenses = [
        ob for ob, lens in zip(read.sphere_objects, read.lens_candidates, strict=False) if lens
    ]
    lenses += [m.orig for m in read.mesh_lenses]  # no glass receives its own caustic
    work.receivers = read_receivers(depsgraph, exclude=lenses)
    work.timings["receivers"] = time.perf_counter() - t
    if not len(work.receivers.mesh.triangles):
        return work  # nothing to lay a caustic on
    t = time.perf_counter()
    sources = (
        sheet_sources(work.plan.lights, read.primaries, read.lens_optics, read.arrays)
        if spheres
        else []
    ) + meshes
    cam = depsgraph.scene.camera
    ortho = (
        cam.data.ortho_scale
        if cam is not None and cam.type == "CAMERA" and cam.data.type == "ORTHO"
        else None
    )
    camera = sheet_camera(read.camera, read.width, ortho, [s.lens.center for s in sources])
    has_camera = cam is not None and cam.type == "CAMERA"
    # a glass mesh's floor of rays grows with its flat facets and its size on screen
    work.layer_floors = floors = [MIN_RAYS_PER_SOURCE] * (len(sources) - len(meshes)) + [
        mesh_min_rays(
            mesh_facets(s.lens),
            MIN_RAYS_PER_SOURCE,
            2.0
            * s.lens.radius
            / pixel_size(camera.position, s.lens.center, camera.fov, camera.width_px),
        )
        for s in meshes
    ]
    # the rasters follow what the camera sees (without one: the budget's one resolution)
    view = view_of(read.camera, read.width, read.height, ortho) if has_camera else None
    work.layer_sources = sources  # the bake lands them again (core/animation/layer_segments.py)
    names = [(p.light_name, p.lens_name) for p in work.plan.lights] if spheres else []
    names += mesh_names(read)
    receivers = receivers_key(work.receivers)
    if live is not None:
        layer = live.coarse(sources, names, receivers)
        if layer is not None:
            full = live.bake
            work.layer_bake = SheetBake(
                layer, full.budgets, full.resolution, full.index, coarse=True
            )
            work.layer_bake.names, work.layer_bake.receivers_key = names, receivers
            work.timings["coarse layer"] = time.perf_counter() - t
            return work
        if full_plan is not None:
            return prepare(depsgraph, full_plan(), options)
    work.layer_bake = bake(
        sources,
        work.receivers.mesh,
        camera,
        total_rays=TOTAL_RAYS,
        max_rays=MAX_RAYS_PER_SOURCE if view is None else VIEW_MAX_RAYS_PER_SOURCE,
        min_rays=floors,
        rays_per_pixel=RAYS_PER_PIXEL,
        resolution=VIEW_MAX_RESOLUTION
        if view is not None
        else lambda extents, _pixels: raster_resolution(sources, camera, extents),
        view=view,
        max_texels=FACE_BUDGET,
        texel_fraction=VIEW_TEXEL_FRACTION if view is not None else 0.5,
        # a glass mesh's beam needs fewer node rays (`mesh_sources.MESH_TEXEL_SHARE`)
        rays_per_texel=[RAYS_PER_TEXEL] * (len(sources) - len(meshes))
        + [RAYS_PER_TEXEL * MESH_TEXEL_SHARE] * len(meshes)
        if view is not None
        else None,
    )
    work.layer_bake.names, work.layer_bake.receivers_key = names, receivers
    work.timings["bake"] = time.perf_counter() - t
    work.timings.update({f"bake {k}": v for k, v in work.layer_bake.layer.timings.items()})
    return work


def receivers_key(receivers) -> bytes:
    """A digest of what the layer lands on and how it is drawn there: the receivers'
    triangles (and UVs, object ids) and each receiver's name, colour, image and
    fallback. Equal keys: a layer's rasters and materials still fit."""
    h = hashlib.blake2b(digest_size=16)
    mesh = receivers.mesh
    for arr in (mesh.vertices, mesh.triangles, mesh.uvs, mesh.object_ids):
        h.update(b"-" if arr is None else np.ascontiguousarray(arr).tobytes())
    for info in receivers.objects:
        image = info.image.name if info.image is not None else ""
        h.update(
            repr(
                (
                    info.name,
                    tuple(info.color),
                    image,
                    info.interpolation,
                    info.extension,
                    info.fallback,
                )
            ).encode()
        )
    return h.digest()


def _leave_out_linked(work):
    """The planned lights of a light with light or shadow linking of its own leave the
    plan, each pair skipped by name: a layer lies on every receiver its beam lands on,
    whatever the light's linking says (lens lights keep it: `lights.link_lights`)."""
    objects = work.read.light_objects
    keep = []
    for p in work.plan.lights:
        if light_builder.user_link(objects[p.source.light]) is None:
            keep.append(p)
        else:
            work.plan.skipped.append(
                SkippedPair(p.light_name, p.lens_name, Reason.LINKED_LIGHT_IN_LAYER)
            )
    work.plan.lights = keep


def mesh_sources_of(read, timings=None, max_pairs=None) -> list:
    """The sheet sources of the read's mesh lenses (`mesh_sheet_sources`), with their
    pairs in ``read.mesh_pairs`` ((light, mesh lens) indices per source);
    without the mesh lens kind none, and the meshes are named as glass left out."""
    read.mesh_pairs = []
    if not read.mesh_lenses:
        return []
    if MESH_KIND not in LENS_KINDS:  # the tracer is not there: Cycles keeps its caustics
        why = "a glass mesh: this build of Lens Lights cannot trace meshes"
        for m in read.mesh_lenses:
            read.left_out.append((m.name, why))
            read.left_out_lenses.append((m.name, why))
            read.unmodelled_glass.append((m.name, why))
        read.mesh_lenses = []
        return []
    t = time.perf_counter()
    sources, lens_of, skipped = mesh_sheet_sources(
        read.arrays, read.primary_lights, read.primaries, read.mesh_lenses, max_pairs
    )
    read.mesh_pairs = lens_of
    read.mesh_beyond = sum(1 for *_pair, code in skipped if code == int(Reason.BEYOND_MAXIMUM))
    if timings is not None:
        timings["mesh sources"] = time.perf_counter() - t
    return sources


def glass_name(read, key) -> str:
    """The name of a source's glass: a mesh lens's, or the pieces traced together
    ("Magnifier + Pebble")."""
    return " + ".join(read.mesh_lenses[k].name for k in members_of(key))


def mesh_keys(read) -> list:
    """The bake's keys of the mesh lenses' sources (`light_keys.keys_of`: light and
    lens names, kind "mesh"), after the planned lights' in a frame's layer sources."""
    return keys_of(
        (read.light_sources[j], glass_name(read, key), MESH_KIND, "CAUSTIC_LAYER")
        for j, key in read.mesh_pairs
    )


def mesh_names(read) -> list:
    """(light, glass mesh) names of the mesh lenses' sources, in their order."""
    pairs = getattr(read, "mesh_pairs", [])
    return [(read.light_sources[j], glass_name(read, key)) for j, key in pairs]


def build_mesh_layers(scene, work, progress=None) -> list:
    """The mesh lenses' layers when the spheres got lens lights (any tier but the
    layer's): every object made."""
    if work.layer_bake is None:
        work.layer_figures = None
        return []
    layers, _lights, fallback = layer_builder.build(
        scene,
        work.layer_bake,
        work.receivers,
        [],
        [],
        progress,
        mesh_names(work.read),
        reflections=scene.render.engine in EEVEE_ENGINES,
    )
    work.layer_figures = figures_of(work.layer_bake, 0, fallback, _undrawn(work))
    return layers


def mesh_lenses_note(work, layers_made: int) -> str:
    """The report's words on the glass meshes traced as lenses (`mesh_lenses_text`):
    those with a caustic layer (by name, with their triangle counts), those no light
    reaches, and those whose layer could not be made (no receiver)."""
    read = work.read
    if not read.mesh_lenses:
        return ""
    traced = sorted({k for _light, key in read.mesh_pairs for k in members_of(key)})
    lit = [(read.mesh_lenses[k].name, read.mesh_lenses[k].n_triangles) for k in traced]
    unlit = [m.name for k, m in enumerate(read.mesh_lenses) if k not in set(traced)]
    if lit and not (layers_made and work.layer_bake is not None):
        names = ", ".join(n for n, _t in lit)
        why = (
            "nothing receives its caustic"
            if work.layer_bake is None
            else "it lands only where a layer cannot be drawn (glossy or transparent receivers)"
        )
        return f"no caustic layer for the glass of {names}: {why}"
    text = mesh_lenses_text(lit, unlit)
    together = sorted(
        {glass_name(read, key) for _j, key in read.mesh_pairs if len(members_of(key)) > 1}
    )
    if together:
        text += "; traced together (light through one reaches the other): " + ", ".join(together)
    if read.mesh_beyond:
        text += (
            f"; {read.mesh_beyond} dimmer light × glass mesh pair"
            f"{'s' if read.mesh_beyond != 1 else ''} left out (beyond Maximum Lens Lights)"
        )
    bake = work.layer_bake
    first = len(bake.budgets) - len(read.mesh_pairs)
    names, wanted, got = [], [], []
    for j, (_light, key) in enumerate(read.mesh_pairs):
        src = work.layer_sources[first + j]
        names.append(glass_name(read, key))
        wanted.append(work.layer_floors[first + j])
        got.append(bake.budgets[first + j].n_rays * src.n_source)
    cuts = budget_cuts(names, wanted, got)
    return f"{text}; {cuts}" if cuts else text


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
        progress,
        mesh_names(work.read),
        # EEVEE's reflections do not show blended surfaces: a copy for them
        reflections=scene.render.engine in EEVEE_ENGINES,
    )
    work.layer_figures = figures_of(work.layer_bake, len(lights), fallback, _undrawn(work))
    return layers + lights


def _undrawn(work) -> tuple:
    """The glass meshes whose light lands on glossy or transparent receivers
    (`plan.undrawn_glass`): the mesh sources come last in the layer's sources."""
    names = [lens for _light, lens in mesh_names(work.read)]
    objects = work.receivers.objects

    def receiver_of(patch):
        info = objects[patch.object_id]
        return info.name, info.fallback

    first = len(work.layer_sources) - len(names)
    return undrawn_glass(work.layer_bake.layer.patches, receiver_of, first, names)
