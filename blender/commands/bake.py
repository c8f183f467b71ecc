"""Operator "Bake lens lights" (`lens_lights.bake`): lens lights keyed over a frame
range, so that the .blend renders the animation with stock Blender (no extension:
render-farm nodes). One undo step; from the UI it runs modal (a frame per timer
tick, progress bar, Esc cancels and changes nothing); from Python or in the
background it runs at once.

Two stages, as Generate (`generate.py`), so that a failure or a cancel leaves the
scene as it was:

1. **Plan** every frame (nothing changes but the current frame, put back at the
   end): `scene.frame_set(f)`, then the pipeline Generate and Live update share
   (`pipeline.plan_scene`: read, phase 1, plan, the Caustic layer's bake) on the
   render depsgraph of a probe render where the render can differ from the
   viewport, else the viewport's (`render_probe.as_rendered`, as Generate;
   `use_viewport=True`: always the viewport depsgraph with the render rules). Each
   frame's lights become
   `core.animation.light_tracks.FrameLight`s keyed by live update's
   `core.animation.light_keys.LightKey` (primary, lens, kind, tier, occurrence;
   variant "near" for the Exact profile's near field).
2. **Build**: Clear (`cleanup.clear`: the previous lens lights, baked or not), then
   * light tiers: one Blender object per key (`lights.create_light` from the
     key's first frame), its transform (object action), energy, colour, cone,
     blend and radius (light data action) keyed on every frame, LINEAR; on frames
     without the key it is keyed hidden (`hide_render`, `hide_viewport`, CONSTANT);
   * Exact profile: Generate's node tree on every frame
     (`lights.build_profile_nodes(slices=)` + `mask_nodes.add_baked_mask`), every
     number of it that changes with the frame a keyed Value node, every table a
     slice of one image read through a keyed slice index
     (`core.animation.frame_tables`: tiles within a GPU's 16 384² texture):
     - far field: per (lens, n) one image of stacked D/R slices
       (`light_tracks.slice_grid`), "Lens bake slice" (fractional: two slices
       blended) and "Lens bake h_min" keyed LINEAR;
     - near field: the frame's own table, Generate's (its rows on the frame's
       receiver; red the intensity, green intensity × the rays' mean slope when a
       frame has tilted receiver planes, Generate's ``slope_pixels``), one slice per
       distinct table of the track, "Lens bake slice" and "Lens bake h_min" keyed
       CONSTANT; the tilt correction (`lights._tilted`, Generate's: each receiver
       plane its own normal, applied where the shading point lies on it): per plane
       k "Lens tilt k nx/ny/nz/offset" and "Lens tilt tolerance" (CONSTANT), the tree
       built with the most planes any frame has, a frame with fewer keying the rest
       `lights.NO_PLANE` (a zero normal: never on the shading point, exactly E);
     - shadow mask (a frame whose source has a shadow list): the frames' masks as
       slices of one image ("Lens mask bake …"; a frame without one reads ones),
       "Lens bake mask slice" and "Lens bake mask scale" (0.5 / s_max) CONSTANT;
   * Caustic layer: one mesh per receiver plane × lens lights whose topology is
     fixed over the frames (`core.animation.layer_segments`: the union of the frames' rasters,
     cut in time only where it would coarsen a frame's caustic core more than
     `layer_segments.COARSEN_LIMIT` times; each frame's rays landed again on it), the
     frames' irradiance as slices of one packed half-float image, read through
     the mesh's raster UVs with a keyed slice index (`baked_layers`).
   * Water (in every tier, as Generate; `water_stage`): each frame's water layer
     read and traced as Generate's; the first frame with water fixes its rasters
     (`water_stage.fixed_rasters`) and the later frames land on them at once
     (`water_stage.land_on`: same pairs, same receivers; else the frame keeps its own
     and `layer_segments` makes the union), then keyed as the Caustic layer's (one
     mesh per track, the frames' irradiance as slices of one atlas; marked
     `marks.WATER_MARK`).

Live update (where the extension has it) is turned off for the bake and stays off
after it (the keys drive the lights; a cancel or a failed plan puts it back); while
the bake exists it does nothing even when turned on (`live_update._on`).

What each frame was read from is kept as prints (`bake_check.prints_of`, stored by
`bake_check.record` in ``scene.lens_lights.baked_from``), so that the panel and
renders can say when the scene changed under the bake (`bake_check`).

Every action made is marked (`marks.COLLECTION_MARK` = "bake") and removed by
Clear once unused (`cleanup.remove_unused_bake_actions`, called by `cleanup.clear`).
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
import time
import traceback
from types import SimpleNamespace

import bpy
import numpy as np
from mathutils import Vector

from ...core.animation import frame_tables, layer_segments, light_tracks
from ...core.animation.light_keys import keys_of
from ...core.caustic_layer.mesh_sources import members_of
from ...core.plan.cycles_caustics import kept_on_warning, linked_caster_warning
from ...core.report.message import error_text, linking_groups_note
from ...core.tiers import EXACT_PROFILE, builds_layer
from ..build import baked_layers, cleanup, cycles_caustics, layers, lights, mask_nodes, ownership
from ..build.marks import (
    BAKE_MARK,
    COLLECTION_MARK,
    MASK_PREFIX,
    PROFILE_KEY,
    PROFILE_MARK,
    PROFILE_PREFIX,
    WATER_MARK,
)
from ..read.render_probe import VIEWPORT_AS_RENDER, as_rendered
from . import bake_check, layer_stage, pipeline, water_stage

#: Why a glass mesh traced as a lens gets nothing from a bake outside the layer tier.
MESH_NOT_BAKED = "a glass mesh: its caustic layer is baked in the Caustic layer tier only"

SLICE_NODE, H_MIN_NODE = lights.SLICE_NODE, lights.H_MIN_NODE
MASK_SLICE_NODE, MASK_SCALE_NODE = mask_nodes.MASK_SLICE_NODE, mask_nodes.MASK_SCALE_NODE
#: Recorded per frame (not keyed): how many receiver planes the frame's tilt has.
TILT_PLANES = "tilt planes"
#: The figures of the last bake (seconds per stage, counts).
LAST_BAKE: dict = {}


# --------------------------------------------------------------------------- keyframes


def _fcurves(idb):
    """The F-curves of `idb`'s action (its slot's channel bag from 4.4 on)."""
    ad = idb.animation_data
    slot = getattr(ad, "action_slot", None)
    if slot is not None:
        from bpy_extras.anim_utils import action_get_channelbag_for_slot

        return action_get_channelbag_for_slot(ad.action, slot).fcurves
    return ad.action.fcurves


def key_column(idb, data_path, index, frames, values, interpolation="LINEAR"):
    """Key `idb`'s `data_path[index]` to `values` on `frames` in one go:
    `keyframe_insert` once (the action, slot and F-curve, on every release), then
    all the points at once."""
    frames = [float(f) for f in frames]
    values = [float(v) for v in values]
    idb.keyframe_insert(data_path, index=index, frame=frames[0])
    ad = idb.animation_data
    if ad.action.get(COLLECTION_MARK) is None:
        ad.action[COLLECTION_MARK] = BAKE_MARK
    fc = _fcurves(idb).find(data_path, index=max(index, 0))
    points = fc.keyframe_points
    points.add(len(frames) - len(points))
    co = [x for pair in zip(frames, values, strict=True) for x in pair]
    points.foreach_set("co", co)
    for p in points:
        p.interpolation = interpolation
    fc.update()
    return fc


def key_visibility(ob, keys):
    """`ob` hidden / shown at (frame, hidden) `keys` (render and viewport), CONSTANT."""
    frames = [f for f, _ in keys]
    hidden = [1.0 if h else 0.0 for _, h in keys]
    for path in ("hide_render", "hide_viewport"):
        key_column(ob, path, -1, frames, hidden, "CONSTANT")


# --------------------------------------------------------------------------- profile


def compact_profile_image(key: str, pixels):
    """A marked profile image (as `lights.profile_image` makes, reused by
    key) holding `pixels` (H, K) as a one-channel (or (H, K, 3): RGB) 32-bit float
    OpenEXR, ZIP, packed: bit for bit the same values (`lights.packed_exr`)."""
    H, K = pixels.shape[:2]
    for img in bpy.data.images:
        if (
            img.get(COLLECTION_MARK) == PROFILE_MARK
            and img.get(PROFILE_KEY) == key
            and tuple(img.size) == (K, H)
            and img.packed_file is not None
        ):
            return img
    img = lights.packed_exr(PROFILE_PREFIX + key, pixels, "32", "lens_profile.exr")
    img[COLLECTION_MARK] = PROFILE_MARK
    img[PROFILE_KEY] = key
    return img


def _profile_images(tracks, ratio) -> dict:
    """Per Exact profile track key: (image, layout, slice coordinate per frame, h_min
    per frame in world units, interpolation). Far field: the image stacks its group's
    D/R slices (`light_tracks.profile_groups`), read between two (LINEAR); near
    field: the track's own image of its frames' own tables, Generate's (red: the
    intensity; green: intensity × the rays' mean slope where a frame has tilted
    receivers), each frame reading its own (CONSTANT; `frame_tables`)."""
    out = {}
    far = [t for t in tracks if t.profile_group is not None and not t.profile_group[2]]
    groups = light_tracks.profile_groups(far, ratio)
    by_key = {t.key: t for t in tracks}
    for group, (keys, grid) in groups.items():
        lens, n = group[:2]
        tables = [light_tracks.profile_slice_table(g, n, False) for g in grid]
        key = f"bake {lens} n {n:.9g} D/R " + " ".join(f"{g:.9g}" for g in grid)
        image = compact_profile_image(key, light_tracks.stack_slices(tables))
        layout = frame_tables.SliceLayout(len(grid), *tables[0].shape)
        for k in keys:
            t = by_key[k]
            s = light_tracks.slice_coordinate(t.d_over_r, grid)
            out[k] = (image, layout, s, t.values["h_min"][:, 0], "LINEAR")
    for t in tracks:
        if t.profile_group is None or not t.profile_group[2]:
            continue
        frames = t.tables["near"]
        keys, s = frame_tables.frame_slices([key for key, _ in frames])
        first = {}
        for key, px in frames:
            first.setdefault(key, px)
        tilted = any(px.ndim == 3 for px in first.values())
        tables = [_near_pixels(first[key], tilted) for key in keys]
        layout = frame_tables.slice_layout(len(tables), *tables[0].shape[:2])
        # the key lists the frames' tables (Generate's keys, in slice order)
        key = f"bake {t.profile_group[0]} near: " + "; ".join(map(str, keys))
        image = compact_profile_image(key, frame_tables.tile_slices(tables, layout))
        out[t.key] = (image, layout, s.astype(float), t.values["h_min"][:, 0], "CONSTANT")
    return out


def _near_pixels(pixels, tilted: bool):
    """A near table as the bake's image holds it: (M, K), or with `tilted` (M, K, 3)
    RGB, green intensity × the rays' mean slope (0 for a frame without tilted
    receivers: its planes are `lights.NO_PLANE`, the green is never used)."""
    px = np.asarray(pixels, dtype=np.float32)
    if not tilted:
        return px
    rgb = np.zeros((*px.shape[:2], 3), dtype=np.float32)
    rgb[..., : px.shape[2] if px.ndim == 3 else 1] = px if px.ndim == 3 else px[..., None]
    return rgb


def _slice_image(track, role: str, name: str):
    """(image, layout, slice per frame) of the track's frames' `role` tables (None:
    no frame has one), one slice per distinct table (`frame_tables`); a frame
    without one reads a slice of ones. The image: a packed 32-bit float OpenEXR
    named `name`, marked like the profile images (Clear removes it once unused)."""
    frames = track.tables.get(role)
    if not frames or all(m is None for m in frames):
        return None
    keys, s = frame_tables.frame_slices([None if m is None else m[0] for m in frames])
    pixels = {m[0]: m[1] for m in frames if m is not None}
    shape = next(iter(pixels.values())).shape
    tables = [pixels[k] if k is not None else np.ones(shape, np.float32) for k in keys]
    layout = frame_tables.slice_layout(len(tables), *shape[:2])
    image = lights.packed_exr(
        name, frame_tables.tile_slices(tables, layout), "32", f"lens_{role}.exr"
    )
    image[COLLECTION_MARK] = PROFILE_MARK
    return image, layout, s.astype(float)


# --------------------------------------------------------------------------- the bake


def _frame_lights(work, firsts: dict, tables: dict) -> list:
    """The `FrameLight`s of one frame's plan; `firsts` gets each new key's
    (PlannedLight, lens object, its user light's own linking); `tables` (key →
    pixels) shares equal tables over the frames. An Exact profile light records
    what Generate's node tree reads on this frame: its near field's own table (its
    key, intensity and intensity × slope), its receiver planes' tilt numbers
    (`lights.tilt_values`; their count under `TILT_PLANES`), its shadow mask
    (`mask_nodes.shadow_mask`)."""
    out = []
    nears = [
        bool(
            p.light.model == EXACT_PROFILE
            and getattr(p.light, "profile_info", None) is not None
            and p.light.inside_lens
        )
        for p in work.plan.lights
    ]
    keys = keys_of(
        (p.light_name, p.lens_name, p.light.kind, p.light.model, "near" if near else "")
        for p, near in zip(work.plan.lights, nears, strict=True)
    )
    for p, near, key in zip(work.plan.lights, nears, keys, strict=True):
        bl = p.light
        profile = bl.model == EXACT_PROFILE and getattr(bl, "profile_info", None) is not None
        q = Vector(bl.direction).to_track_quat("-Z", "Y")
        values = dict(
            location=bl.location,
            rotation_quaternion=tuple(q),
            scale_xy=bl.scale_xy,
            energy=bl.energy_w,
            color=bl.color,
            spot_size=math.radians(bl.spot_size_deg),
            spot_blend=bl.spot_blend,
            radius=bl.radius,
        )
        fl = light_tracks.FrameLight(key, values)
        if profile:
            src = p.source
            fl.profile_group = (p.lens_name, round(float(src.ior), 9), near)
            fl.d_over_r = float(src.distance) / float(src.lens_radius)
            values["h_min"] = float(bl.profile_info["h_min"])
            values["lens_radius"] = float(src.lens_radius)
            if near:  # the frame's own table, Generate's
                prof = bl.profile
                values["receiver"] = float(bl.receiver_distance) / float(src.lens_radius)
                values["h_min"] = float(prof["h_min"])
                # the tree's numbers, under the names of the Value nodes keyed with them
                values.update(lights.tilt_values(prof))
                values[TILT_PLANES] = len(prof.get("receivers") or ())
                tkey = prof["key"] if prof.get("key") is not None else f"frame {id(prof)}"
                if tkey not in tables:
                    px = np.asarray(prof["pixels"], dtype=np.float32)
                    if prof.get("slope_pixels") is not None:  # Generate's green channel
                        green = np.asarray(prof["slope_pixels"], np.float32)
                        px = np.stack([px, green], axis=-1)
                    tables[tkey] = px
                fl.tables["near"] = (tkey, tables[tkey])
            mask = mask_nodes.shadow_mask(p, work.read.arrays)
            if mask is not None:
                px, s_max = mask
                fl.tables["mask"] = (hashlib.sha1(px.tobytes()).hexdigest(), px)
                values[MASK_SCALE_NODE] = 0.5 / s_max
        if key not in firsts:  # (its user light's own linking: `lights.user_link`)
            firsts[key] = (
                p,
                work.read.sphere_objects[p.source.lens],
                lights.user_link(work.read.light_objects[p.source.light]),
            )
        out.append(fl)
    return out


class Baker:
    """One bake: `plan_next()` per frame, then `build()` (or `cancel()`)."""

    def __init__(
        self,
        context,
        frame_start: int,
        frame_end: int,
        use_viewport=False,
        profile_step=light_tracks.SLICE_RATIO - 1.0,
    ):
        if frame_end < frame_start:
            raise ValueError(f"the frame range {frame_start}–{frame_end} ends before it starts")
        self.context, self.scene = context, context.scene
        self.frames = list(range(int(frame_start), int(frame_end) + 1))
        self.use_viewport = use_viewport
        self.profile_step = float(profile_step)
        self.options = pipeline.options_from(self.scene.lens_lights)
        self.layer = builds_layer(self.options["energy_model"])
        self.frame_before = (self.scene.frame_current, self.scene.frame_subframe)
        # Live update (where the extension has it) would rebuild the lens lights on
        # every frame the bake visits, and later overwrite the baked keys: off while
        # baking, and after (the keys drive the lights); a cancel puts it back.
        settings = self.scene.lens_lights
        self.live_before = bool(getattr(settings, "live_update", False))
        if self.live_before:
            settings.live_update = False
        self.per_frame, self.works, self.firsts, self.tables = [], [], {}, {}
        # the water's layer per frame (`water_stage.frame_layers`; None: none) and its
        # receivers (in every tier, as Generate builds the water's layers); the rasters
        # its first frame fixes, the later frames' landed on them at once
        self.water, self.water_receivers, self.water_fixed = [], [], None
        # what each frame was baked from (`bake_check`), and whether read as rendered
        self.prints: list = []
        self.read_as_render = True
        self.lens_objects: set = set()
        self.unmodelled_glass: dict = {}  # name → why: keeps Cycles' refractive caustics on
        self.timings = dict(plan=0.0, build=0.0)
        self.t0 = time.perf_counter()

    @property
    def done(self) -> bool:
        return len(self.per_frame) == len(self.frames)

    def plan_next(self):
        """Plan the next frame (changes nothing but the current frame)."""
        t = time.perf_counter()
        f = self.frames[len(self.per_frame)]
        scene, options = self.scene, self.options

        def plan(dg):
            work = pipeline.plan_scene(dg, scene, options)
            return water_stage.prepare(dg, work, self.water_fixed)

        scene.frame_set(f)
        if self.use_viewport:
            work = plan(self.context.evaluated_depsgraph_get())
            work.read.occluders.release()
        else:  # the probe only where the render can differ from the viewport
            work, how = as_rendered(self.context, plan)
            if how == VIEWPORT_AS_RENDER:
                work.read.occluders.release()
        self.per_frame.append(_frame_lights(work, self.firsts, self.tables))
        if self.water_fixed is None:  # the first frame with water fixes the rasters
            self.water_fixed = water_stage.fixed_rasters(work)
            if self.water_fixed is not None:
                water_stage.land_on(work, self.water_fixed)
        self.water.append(water_stage.frame_layers(work, light=True))
        self.water_receivers.append(work.water.receivers)
        work.water = None  # (the frame's surfaces and their search structures: freed)
        self.prints.append(bake_check.prints_of(work.read, options))
        self.read_as_render &= bake_check.read_as_render(work.read.how)
        self.lens_objects.update(work.read.sphere_objects[p.source.lens] for p in work.plan.lights)
        self.unmodelled_glass.update(getattr(work.read, "unmodelled_glass", []))
        if self.layer:  # the glass meshes traced: their layers replace Cycles' caustics
            meshes = work.read.mesh_lenses
            self.lens_objects.update(
                meshes[k].orig for _j, key in work.read.mesh_pairs for k in members_of(key)
            )
        else:  # the glass meshes' layers are baked in the layer's tier only
            self.unmodelled_glass.update((m.name, MESH_NOT_BAKED) for m in work.read.mesh_lenses)
        if self.layer:
            self.works.append(work)  # built per frame (its meshes)
        self.timings["plan"] += time.perf_counter() - t

    def restore_frame(self):
        self.scene.frame_set(self.frame_before[0], subframe=self.frame_before[1])

    def cancel(self):
        """Nothing changed: the frame and Live update as they were."""
        self.restore_frame()
        if self.live_before:
            self.scene.lens_lights.live_update = True

    def build(self) -> dict:
        """Clear, then make the keyed lights (stage 2); figures for the report."""
        t = time.perf_counter()
        scene = self.scene
        self.restore_frame()
        cleanup.clear(scene)
        cycles_caustics.restore(scene)
        try:
            figures = self._build_layers() if self.layer else self._build_lights()
            figures.update(self._build_water())
            figures["objects"] += figures["water_objects"]
            if scene.lens_lights.replace_cycles_caustics and figures["objects"]:
                lenses = sorted(self.lens_objects, key=lambda o: o.name)
                values = cycles_caustics.scene_values(scene)
                glass = sorted(self.unmodelled_glass)
                cycles_caustics.replace(scene, lenses, keep_scene=bool(glass))
                by = "the caustic layers" if self.layer else "the lens lights"
                engine = scene.render.engine
                figures["caustics_warning"] = "; ".join(
                    x
                    for x in (
                        kept_on_warning(engine, values, glass, [ob.name for ob in lenses], by),
                        linked_caster_warning(engine, cycles_caustics.linked_casters(lenses), by),
                    )
                    if x
                )
        except Exception:
            cleanup.clear(scene)
            cycles_caustics.restore(scene)
            raise
        self.timings["build"] = time.perf_counter() - t
        figures.update(
            frames=len(self.frames),
            frame_start=self.frames[0],
            frame_end=self.frames[-1],
            energy_model=self.options["energy_model"],
            seconds=time.perf_counter() - self.t0,
            timings=dict(self.timings),
        )
        return figures

    def _build_lights(self) -> dict:
        scene = self.scene
        tracks = light_tracks.build_tracks(self.frames, self.per_frame)
        images = _profile_images(tracks, 1.0 + self.profile_step)
        collection = lights.lights_collection(scene)
        made, firsts = [], []
        masks: set = set()
        for track in tracks:
            planned, lens_ob, _ = self.firsts[track.key]
            bl = planned.light
            if track.profile_group is not None:  # no per-frame image: the nodes come below
                bl = dataclasses.replace(bl, _profile=None, _profile_maker=None)
            ob = lights.create_light(
                scene, dataclasses.replace(planned, light=bl), lens_ob, collection, None
            )
            masks |= self._key_track(ob, track, images)
            made.append(ob)
            firsts.append(bl)
        # the lights move: every beam taken as reaching every lens (each lens its own
        # group while Blender's sets last, then shared: the report lists them)
        lens_objects = [self.firsts[t.key][1] for t in tracks]
        index = {o.as_pointer(): k for k, o in enumerate(dict.fromkeys(lens_objects))}
        spheres = list(dict.fromkeys(lens_objects))
        firsts = [
            SimpleNamespace(light=bl, source=SimpleNamespace(lens=index[o.as_pointer()]))
            for bl, o in zip(firsts, lens_objects, strict=True)
        ]
        self.linking = lights.link_lights(
            scene,
            made,
            firsts,
            np.zeros((len(spheres), 3)),
            np.zeros(len(spheres)),
            spheres,
            everywhere=True,
            user_links=[self.firsts[t.key][2] for t in tracks],
        )
        profiles = len({v[0].name for v in images.values()})
        return dict(objects=len(tracks), images=profiles, mask_images=len(masks))

    def _key_track(self, ob, track, images):
        frames, v = track.frames, track.values
        for i in range(3):
            key_column(ob, "location", i, frames, v["location"][:, i])
        for i in range(4):
            key_column(ob, "rotation_quaternion", i, frames, v["rotation_quaternion"][:, i])
        for i in range(2):
            key_column(ob, "scale", i, frames, v["scale_xy"][:, 0])
        data = ob.data
        key_column(data, "energy", -1, frames, v["energy"][:, 0])
        for i in range(3):
            key_column(data, "color", i, frames, v["color"][:, i])
        key_column(data, "spot_size", -1, frames, v["spot_size"][:, 0])
        key_column(data, "spot_blend", -1, frames, v["spot_blend"][:, 0])
        key_column(data, "shadow_soft_size", -1, frames, v["radius"][:, 0])
        masks = set()
        if track.profile_group is not None:
            image, layout, s, h_min, how = images[track.key]
            info = dict(self.firsts[track.key][0].light.profile_info)
            info["tilt_planes"] = planes = int(v[TILT_PLANES].max()) if TILT_PLANES in v else 0
            nt = lights.build_profile_nodes(data, info, image, slices=layout)
            path = 'nodes["{}"].outputs[0].default_value'
            key_column(nt, path.format(SLICE_NODE), -1, frames, s, how)
            key_column(nt, path.format(H_MIN_NODE), -1, frames, h_min, how)
            mask = _slice_image(track, "mask", MASK_PREFIX + f"bake {ob.name}")
            if mask is not None:
                m_image, m_layout, m_s = mask
                mask_nodes.add_baked_mask(nt, m_image, m_layout)
                key_column(nt, path.format(MASK_SLICE_NODE), -1, frames, m_s, "CONSTANT")
                masks.add(m_image.name)
            # every number the frames recorded under a Value node's name of the tree;
            # the planes a frame lacks: `lights.NO_PLANE` (never on the shading point)
            v = dict(v)
            for k in range(planes):
                unused = v[TILT_PLANES][:, 0] <= k
                for part, x in zip(lights.TILT_PARTS, lights.NO_PLANE, strict=True):
                    name = lights.TILT_NODE.format(k, part)
                    col = v.get(name, np.zeros((len(frames), 1))).copy()
                    col[unused] = x
                    v[name] = col
            for name, col in v.items():
                node = nt.nodes.get(name)
                if node is not None and node.bl_idname == "ShaderNodeValue":
                    if name not in (SLICE_NODE, H_MIN_NODE, MASK_SLICE_NODE):
                        key_column(nt, path.format(name), -1, frames, col[:, 0], "CONSTANT")
        key_visibility(ob, light_tracks.visibility_keys(frames, track.present))
        return masks

    def _build_layers(self) -> dict:
        """Fixed-topology layers (`core.animation.layer_segments`): per segment one mesh, its
        slice, scale and colour keyed per frame (CONSTANT) and its visibility; the
        frames' fallback spots (no receiver at all, or glossy / transparent ones)
        are made per frame and shown on their frame only, as Generate makes them."""
        scene = self.scene
        first, last = self.frames[0], self.frames[-1]
        inputs, spots = [], 0
        for i, (f, work) in enumerate(zip(self.frames, self.works, strict=True)):
            made = []
            if work.layer_bake is None:  # no receiver: the Fitted spots stand in
                made = layer_stage.build(scene, work)
                inputs.append(layer_segments.FrameLayers([], None, [], []))
            else:
                infos = work.receivers.objects
                skip = frozenset(k for k, info in enumerate(infos) if info.fallback)
                keys = [fl.key for fl in self.per_frame[i]] + layer_stage.mesh_keys(work.read)
                names = [info.name for info in infos]
                inputs.append(
                    layer_segments.FrameLayers(
                        work.layer_sources, work.layer_bake, keys, names, skip
                    )
                )
                if skip:
                    patches = [p for p in work.layer_bake.layer.patches if p.object_id in skip]
                    only = dataclasses.replace(
                        work.layer_bake,
                        layer=dataclasses.replace(work.layer_bake.layer, patches=patches),
                    )
                    _l, made, _n = layers.build(
                        scene, only, work.receivers, work.plan.lights, work.read.sphere_objects
                    )
            for ob in made:
                key_visibility(ob, light_tracks.single_frame_visibility(f, first, last))
            spots += len(made)
        t = time.perf_counter()
        segments, res = layer_segments.bake_frames(inputs)
        self.timings["layer re-landing"] = time.perf_counter() - t
        infos = [self.works[s.frames[0]].receivers.objects[s.object_id] for s in segments]
        objects, _copies, images = self._key_segments(segments, res, infos)
        return dict(
            objects=len(objects) + spots,
            images=images,
            layer_resolution=res,
            layer_segments=[(len(s.frames), s.coarsening) for s in segments],
        )

    def _build_water(self) -> dict:
        """The water's layers over the frames (in every tier, as Generate's): one fixed
        topology per (receiver plane, pairs) track (`layer_segments`, each frame's
        rays landed again on it: `water_stage.frame_layers`), keyed as the layer's."""
        empty = layer_segments.FrameLayers([], None, [], [])
        inputs = [empty if w is None else w for w in self.water]
        if all(w is None for w in self.water):
            return dict(water_objects=0)
        t = time.perf_counter()
        segments, res = layer_segments.bake_frames(inputs)
        self.timings["water re-landing"] = time.perf_counter() - t
        infos = [self.water_receivers[s.frames[0]].objects[s.object_id] for s in segments]
        objects, copies, images = self._key_segments(segments, res, infos)
        for ob in objects + copies:
            ob[WATER_MARK] = True
        return dict(
            water_objects=len(objects),
            water_images=images,
            water_resolution=res,
            water_segments=[(len(s.frames), s.coarsening) for s in segments],
        )

    def _key_segments(self, segments, res: int, infos) -> tuple[list, list, int]:
        """The baked layers of `segments` (`baked_layers.build`), each one's slice, scale
        and colour keyed per frame (CONSTANT) and its visibility. Returns (the layer
        objects, their EEVEE reflection copies, the atlas images made)."""
        scene = self.scene
        collection = lights.lights_collection(scene)
        objects, keyed, images, copies = baked_layers.build(
            scene,
            segments,
            res,
            infos,
            collection,
            reflections=scene.render.engine in layer_stage.EEVEE_ENGINES,
        )
        frames = np.asarray(self.frames)
        path = 'nodes["{}"].outputs[0].default_value'
        for seg, ob, (mat, slices, scales, colours), copy in zip(
            segments, objects, keyed, copies, strict=True
        ):
            at = frames[seg.frames]
            present = np.zeros(len(frames), dtype=bool)
            present[seg.frames] = True
            for o, m in [(ob, mat)] + ([copy] if copy is not None else []):
                nt = m.node_tree
                key_column(nt, path.format(baked_layers.SLICE_NODE), -1, at, slices, "CONSTANT")
                key_column(nt, path.format(baked_layers.SCALE_NODE), -1, at, scales, "CONSTANT")
                for c in range(3):
                    col = [x[c] for x in colours]
                    key_column(nt, path.format(baked_layers.COLOUR_NODE), c, at, col, "CONSTANT")
                key_visibility(o, light_tracks.visibility_keys(frames, present))
        return objects, [c[0] for c in copies if c is not None], images


def bake(
    context,
    frame_start=None,
    frame_end=None,
    use_viewport=False,
    progress=None,
    profile_step=light_tracks.SLICE_RATIO - 1.0,
):
    """Plan and build at once; returns (level, message, figures). Never raises."""
    global LAST_BAKE
    scene = context.scene
    a = scene.frame_start if frame_start is None else frame_start
    b = scene.frame_end if frame_end is None else frame_end
    try:
        baker = Baker(context, a, b, use_viewport, profile_step)
    except ValueError as exc:
        return "ERROR", str(exc), dict(changed=False)
    try:
        while not baker.done:
            baker.plan_next()
            if progress is not None:
                progress(len(baker.per_frame) / len(baker.frames))
    except Exception as exc:
        traceback.print_exc()
        baker.cancel()
        return "ERROR", error_text("read the scene", exc), dict(changed=False)
    return finish(baker)


def finish(baker):
    global LAST_BAKE
    try:
        figures = baker.build()
    except Exception as exc:
        traceback.print_exc()
        message = error_text("bake the lens lights", exc) + " (the lens lights were removed)"
        return "ERROR", message, dict(changed=True)
    figures["changed"] = True
    LAST_BAKE = figures
    settings = baker.scene.lens_lights
    if figures["objects"]:
        bake_check.record(baker.scene, baker.frames, baker.prints, baker.read_as_render)
    settings.last_run = True
    settings.last_created = figures["objects"]
    settings.last_seconds = figures["seconds"]
    settings.last_report = light_tracks.bake_message(figures)
    level = "INFO"
    if figures.get("caustics_warning"):
        settings.last_report += "; " + figures["caustics_warning"]
        level = "WARNING"
    linking = getattr(baker, "linking", None)
    note = linking and linking_groups_note(
        linking.ungrouped, linking.conflicts, (), linking.user_sets
    )
    if note:
        settings.last_report += "; " + note
        level = "WARNING"
    kept, doubled = ownership.kept_note(baker.scene, ownership.created_objects(baker.scene))
    if kept:  # the user's copies, renamed and moved lens lights: kept beside the baked
        settings.last_report += "; " + kept
        level = "WARNING" if doubled else level
    unbaked = sorted(n for n, why in baker.unmodelled_glass.items() if why == MESH_NOT_BAKED)
    if unbaked:
        settings.last_report += (
            f"; not baked: the caustics of the glass meshes {', '.join(unbaked)} (their "
            "caustic layers are baked in the Caustic layer tier; Cycles renders their own)"
        )
        level = "WARNING"
    if baker.live_before:
        settings.last_report += "; Live update turned off (the keys drive the lens lights)"
    return level, settings.last_report, figures


class LENS_LIGHTS_OT_bake(bpy.types.Operator):
    """Key the lens lights on every frame of a range, so that the file renders the
    animation without the extension (render farms). Esc cancels"""

    bl_idname = "lens_lights.bake"
    bl_label = "Bake Lens Lights"
    bl_options = {"REGISTER", "UNDO"}

    frame_start: bpy.props.IntProperty(
        name="Start", description="First frame (default: the scene's)", default=0
    )
    frame_end: bpy.props.IntProperty(
        name="End", description="Last frame (default: the scene's)", default=-1
    )
    use_viewport: bpy.props.BoolProperty(
        name="Viewport Depsgraph",
        description=(
            "Read each frame from the viewport's evaluation with the render rules "
            "instead of a probe render (faster; differs where the render settings do)"
        ),
        default=False,
    )
    profile_step: bpy.props.FloatProperty(
        name="Profile Step",
        description=(
            "Exact profile: relative D/R step between the baked tables (smaller: closer "
            "to the exact beam near the focus between tables; more tables, larger file)"
        ),
        default=100.0 * (light_tracks.SLICE_RATIO - 1.0),
        min=0.5,
        max=25.0,
        subtype="PERCENTAGE",
    )

    @classmethod
    def poll(cls, context):
        return context.scene is not None

    def _range(self, context):
        scene = context.scene
        a = self.frame_start if self.properties.is_property_set("frame_start") else None
        b = self.frame_end if self.properties.is_property_set("frame_end") else None
        return (scene.frame_start if a is None else a), (scene.frame_end if b is None else b)

    def execute(self, context):
        a, b = self._range(context)
        self.frame_start, self.frame_end = a, b  # the redo panel shows what was baked
        level, message, figures = bake(
            context, a, b, self.use_viewport, profile_step=self.profile_step / 100.0
        )
        self.report({level}, message)
        if level == "ERROR" and not figures.get("changed", True):
            return {"CANCELLED"}
        return {"FINISHED"}

    def invoke(self, context, event):
        if context.window is None:
            return self.execute(context)
        a, b = self._range(context)
        try:
            self._baker = Baker(context, a, b, self.use_viewport, self.profile_step / 100.0)
        except ValueError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        wm = context.window_manager
        wm.progress_begin(0, len(self._baker.frames))
        self._timer = wm.event_timer_add(0.001, window=context.window)
        wm.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def _end(self, context):
        wm = context.window_manager
        wm.event_timer_remove(self._timer)
        wm.progress_end()

    def modal(self, context, event):
        baker = self._baker
        if event.type == "ESC":
            self._end(context)
            baker.cancel()
            self.report({"WARNING"}, "Bake cancelled: nothing changed")
            return {"CANCELLED"}
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        try:
            baker.plan_next()
        except Exception as exc:
            traceback.print_exc()
            self._end(context)
            baker.cancel()
            self.report({"ERROR"}, error_text("read the scene", exc))
            return {"CANCELLED"}
        context.window_manager.progress_update(len(baker.per_frame))
        if not baker.done:
            return {"RUNNING_MODAL"}
        self._end(context)
        level, message, _figures = finish(baker)
        self.report({level}, message)
        return {"FINISHED"}


_CLASSES = (LENS_LIGHTS_OT_bake,)


register, unregister = bpy.utils.register_classes_factory(_CLASSES)
