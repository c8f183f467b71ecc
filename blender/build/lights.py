"""Create and remove the lens lights (bpy).

Every lens light is a SPOT light object in the collection "Lens Lights" (created on
demand, under the scene's collection), placed, turned and shaped from a
`BlenderLight` (`core/tiers/base.py`):

* location and rotation: the light's local −Z along `direction`;
* scale (k, k, 1) when the cone is narrower than Blender's 1° minimum;
* energy, colour, spot_size, spot_blend, radius (`shadow_soft_size`), and EEVEE's
  custom influence distance;
* light linking and shadow linking (`link_lights`, after the lights are made): a
  light whose beam reaches its own lens has as receiver and blocker collection its
  lens's group, "Lens link: group k", which holds the group's lenses with state
  EXCLUDE, so the light neither lights nor is blocked by its own lens (nor by the
  other lenses of the group, which its beam does not reach: `core/plan/linking.py`
  groups them, at most 63 groups less what the user's own linking takes). Objects
  instanced from one original share its linking: all instances of that original
  are excluded (Blender links objects, not instances). A caustic layer's fallback
  light keeps a collection "Lens link: <lens>" of its own (`link_collection`).
* `object.lens_lights` records the origin: primary light, lens, kind, full,
  unblocked share, the tier it was made with (`energy_model`), relative
  brightness, notes.
* EXACT_PROFILE lights (`tiers.exact_profile.ProfileLight`, Cycles only) also get
  the light node tree of `build_profile_nodes` (this module is its one description;
  `bench/blender_light_check.py` renders it): a SPOT of 180°, blend 0, whose emission
  strength is read from a 32-bit float, Non-Color, packed image of the profile.
  The node tree is the light's own (embedded in the light data, removed with it);
  the image is named "Lens profile <key>", marked with the custom property
  `marks.COLLECTION_MARK` = "profile" and its cache key, and shared by every
  light with the same key (same D/R and n: same pixels).

The values (all but the name, linking and origin) are put by `apply_light`, on a new
light or on one live update keeps (`live_update`): only what differs is written.

Everything created is listed in `scene.lens_lights.created_*` (objects under their
name: `ownership.register`) and marked (`object.lens_lights.is_lens_light`,
collection custom property `marks.COLLECTION_MARK`); Clear (`cleanup.clear`, above
every builder) removes only what is still exactly the extension's (`ownership`: a
copy, a renamed or moved lens light is the user's, kept), and then the marked
profile images nothing uses any more (`remove_unused_profile_images`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import bpy
import numpy as np
from mathutils import Vector

from ...core.plan.linking import MAX_COLLECTIONS, MAX_SETS, beams_of, plan_linking, sets_used
from ...core.tiers import exact_profile
from . import mask_nodes
from .marks import (
    COLLECTION_MARK,
    COLLECTION_NAME,
    LIGHTS_MARK,
    LINK_GROUP,
    LINK_MARK,
    LINK_PREFIX,
    PROFILE_KEY,
    PROFILE_MARK,
    PROFILE_PREFIX,
    USER_LINK,
)
from .node_maths import shader_math, slice_coordinates, value_node
from .ownership import register


def _register_collection(settings, coll):
    item = settings.created_collections.add()
    item.collection = coll


def lights_collection(scene):
    """The extension's "Lens Lights" collection in `scene`, created if needed."""
    settings = scene.lens_lights
    for item in settings.created_collections:
        coll = item.collection
        if coll is not None and coll.get(COLLECTION_MARK) == LIGHTS_MARK:
            if coll.name not in scene.collection.children:
                scene.collection.children.link(coll)
            return coll
    coll = bpy.data.collections.new(COLLECTION_NAME)
    coll[COLLECTION_MARK] = LIGHTS_MARK
    scene.collection.children.link(coll)
    _register_collection(settings, coll)
    return coll


def link_collection(scene, lens_object, cache):
    """The linking collection that excludes `lens_object` (one per lens, per run)."""
    coll = cache.get(lens_object.name)
    if coll is None:
        coll = bpy.data.collections.new(LINK_PREFIX + lens_object.name)
        coll[COLLECTION_MARK] = LINK_MARK
        coll.objects.link(lens_object)
        for member in coll.collection_objects:
            member.light_linking.link_state = "EXCLUDE"
        _register_collection(scene.lens_lights, coll)
        cache[lens_object.name] = coll
    return coll


def packed_exr(name: str, pixels, depth: str, file_name: str):
    """A packed Non-Color image named `name` of `pixels` ((H, W) one channel or
    (H, W, 3) RGB, row 0 at the bottom) as an OpenEXR of `depth` ("16" half, "32"
    float), ZIP: written through a throw-away scene's output settings (the user's are
    not touched) into a temporary folder, loaded and packed. A third of the size of
    the RGBA image packed from memory."""
    import os
    import tempfile

    import numpy as np

    px = np.asarray(pixels, dtype=np.float32)
    h, w = px.shape[:2]
    tmp_scene = bpy.data.scenes.new("Lens Lights bake (temporary)")
    src = bpy.data.images.new(name + " (temporary)", w, h, float_buffer=True, alpha=False)
    try:
        src.colorspace_settings.name = "Non-Color"  # before the pixels (see profile_image)
        src.use_half_precision = False
        rgba = np.ones((h, w, 4), dtype=np.float32)
        rgba[..., :3] = px[..., None] if px.ndim == 2 else px
        src.pixels.foreach_set(rgba.ravel())
        src.update()
        settings = tmp_scene.render.image_settings
        settings.file_format = "OPEN_EXR"
        settings.color_mode = "BW" if px.ndim == 2 else "RGB"
        settings.color_depth = depth
        settings.exr_codec = "ZIP"
        with tempfile.TemporaryDirectory(prefix="lens-lights-") as folder:
            path = os.path.join(folder, file_name)
            src.save_render(path, scene=tmp_scene)
            img = bpy.data.images.load(path)
            img.colorspace_settings.name = "Non-Color"
            img.pack()
    finally:
        bpy.data.images.remove(src)
        bpy.data.scenes.remove(tmp_scene)
    img.name = name
    return img


def _is_profile_image(img) -> bool:
    return img.get(COLLECTION_MARK) == PROFILE_MARK


def profile_image(profile: dict, image_cache: dict | None = None, pack: bool = True):
    """The float image of an EXACT_PROFILE table (`ProfileLight.profile`), reusing
    a marked image with the same key and size (from `image_cache`, then from
    `bpy.data`); a table without a key gets an image of its own. A new image is
    packed at once unless `pack` is False (live update: packed when the file is
    saved, as its rewrites are, `pack_dirty_profile_images`; packing one as OpenEXR
    takes about 5 ms)."""
    key = profile.get("key")
    H, K = int(profile["height"]), int(profile["width"])
    if key is not None:
        found = _keyed_image(key, K, H, image_cache)
        if found is not None:
            return found
    img = bpy.data.images.new(
        PROFILE_PREFIX + (key or "table"), width=K, height=H, float_buffer=True, alpha=False
    )
    img[COLLECTION_MARK] = PROFILE_MARK
    # Traps: the colour space first (changing it
    # later regenerates the generated image and loses the pixels), and full float
    # precision (the table spans about 20 decades, up to ~1e7).
    img.colorspace_settings.name = "Non-Color"
    img.use_half_precision = False
    write_profile_pixels(img, profile)
    if pack:
        img.pack()  # kept in the .blend (as OpenEXR)
    if image_cache is not None and key is not None:
        image_cache[key] = img
    return img


def _keyed_image(key, K: int, H: int, image_cache: dict | None):
    """A marked profile image holding the table `key` at size K × H, or None."""
    if image_cache is not None and key in image_cache:
        return image_cache[key]
    for img in bpy.data.images:
        if (
            _is_profile_image(img)
            and img.get(PROFILE_KEY) == key
            and tuple(img.size) == (K, H)
            and (img.packed_file is not None or img.has_data)
        ):
            if image_cache is not None:
                image_cache[key] = img
            return img
    return None


def write_profile_pixels(img, profile: dict) -> None:
    """`profile`'s table into `img` (its size): red and blue the intensity, green the
    near field's intensity × mean slope (else the intensity), and its key. Not
    packed: a live update's rewrite is packed when the file is saved
    (`pack_dirty_profile_images`)."""
    H, K = int(profile["height"]), int(profile["width"])
    rgba = _RGBA.get((H, K))
    if rgba is None:  # one buffer per size (alpha 1), rewritten for every table
        rgba = _RGBA[(H, K)] = np.ones((H, K, 4), dtype=np.float32)
    px = np.asarray(profile["pixels"], dtype=np.float32)
    rgba[..., 0] = px
    rgba[..., 2] = px
    if profile.get("slope_pixels") is not None:  # near field: intensity × mean slope
        rgba[..., 1] = np.asarray(profile["slope_pixels"], dtype=np.float32)
    else:
        rgba[..., 1] = px
    img.pixels.foreach_set(rgba.ravel())
    img.update()
    if profile.get("key") is not None:
        img[PROFILE_KEY] = profile["key"]


#: `write_profile_pixels`' RGBA buffers by (height, width).
_RGBA: dict = {}


def pack_dirty_profile_images() -> int:
    """Pack the profile images live update rewrote in place since they were packed
    (before the .blend is saved: the packed copy is what the file keeps)."""
    dirty = [img for img in bpy.data.images if _is_profile_image(img) and img.is_dirty]
    for img in dirty:
        img.pack()
    return len(dirty)


#: A baked profile light's keyed Value nodes (`blender/commands/bake.py`): the slice
#: coordinate and the table's first distance (also Generate's tree: live update
#: writes it, with the log of the distances' range, in place).
SLICE_NODE, H_MIN_NODE = "Lens bake slice", "Lens bake h_min"
LOG_RANGE_NODE = "Lens table log range"
#: The Image Texture node of a (not baked) profile tree: its image is the table.
PROFILE_TEX_NODE = "Lens profile table"
#: The tilt correction's Value nodes (`_tilted`), Generate's and the bake's: plane k's
#: normal in the light's frame ("nx", "ny", "nz") and its offset from the apex
#: ("offset", world units), and the tolerance within which a shading point is on a
#: plane (world units).
TILT_NODE = "Lens tilt {} {}"
TILT_PARTS = ("nx", "ny", "nz", "offset")
TOLERANCE_NODE = "Lens tilt tolerance"
#: (nx, ny, nz, offset) of a plane that never matches: a baked frame with fewer
#: planes than its light's tree keys the others so. With a zero normal L n·ω is 0
#: for every shading point (finite L), so |L n·ω − offset| = 1e30, never within a
#: tolerance (R/50): `on` is 0, and the plane's step out + 0 × (tilted − out) gives
#: `out` bit for bit (tilted is 0 there, finite: beam 0 over the 1e-4 floor).
NO_PLANE = (0.0, 0.0, 0.0, 1.0e30)


def tilt_values(profile: dict) -> dict:
    """The tilt correction's numbers of `profile` under its Value nodes' names: per
    plane of ``receivers`` its normal turned into the light's frame (as
    `create_light` turns the light: its −Z along ``axis``) and its offset, and the
    tolerance; empty without receivers. What Generate's tree holds, and what the bake
    records per frame."""
    receivers = profile.get("receivers") or ()
    if not receivers:
        return {}
    q = Vector(profile["axis"]).to_track_quat("-Z", "Y").inverted()
    out = {TOLERANCE_NODE: float(profile.get("plane_tolerance", 0.0))}
    for k, (normal, offset) in enumerate(receivers):
        local = (*(q @ Vector(normal)), offset)
        out.update(
            (TILT_NODE.format(k, p), float(x)) for p, x in zip(TILT_PARTS, local, strict=True)
        )
    return out


def build_profile_nodes(data, profile: dict, image, slices=None):
    """The EXACT_PROFILE light node tree on the light data `data` (Cycles; EEVEE
    ignores light nodes), the one description Generate, live update and the bake
    share: emission strength = red(texture(u, v)) [tilted] × strength_scale,
    with u = sqrt(γ / γ_max) (γ from the spot's −Z axis, the Texture Coordinate's
    Normal, as atan2(√(x² + y²), −z)) and v = ln(h / h_min) / ln(h_max / h_min) (h:
    distance along the axis, Light Path ▸ Ray Length × cos γ); the image
    (`profile_image`) read with linear interpolation, EXTEND. With the light's
    energy twice the beam's flux, the intensity toward (γ, h) is energy/(4π) ×
    texture. Tilted receivers (`_tilted`, green: intensity × slope) when the
    profile has ``receivers`` (or, for the bake, ``tilt_planes`` > 0); the shadow
    mask is added after (`mask_nodes`).

    `slices`: the baked light's image of stacked tables, a
    `core.animation.frame_tables.SliceLayout`: (u, v) read in slice s of it
    (`slice_coordinates`), two neighbouring slices blended by the fractional part of
    s (red and green alike); s and h_min are Value nodes (`SLICE_NODE`,
    `H_MIN_NODE`) the bake keys per frame, as it keys the tilt's (`TILT_NODE`,
    `TOLERANCE_NODE`: ``tilt_planes`` planes, default `NO_PLANE`)."""
    if bpy.app.version < (5, 0, 0) or data.node_tree is None:
        data.use_nodes = True  # (deprecated from 5.0, where every light has its tree)
    nt = data.node_tree
    nt.nodes.clear()

    def math_node(op, a, b=None, c=None):
        return shader_math(nt, op, a, b, c)

    tc = nt.nodes.new("ShaderNodeTexCoord")
    sep = nt.nodes.new("ShaderNodeSeparateXYZ")
    nt.links.new(tc.outputs["Normal"], sep.inputs[0])
    cosg = math_node("MULTIPLY", sep.outputs["Z"], -1.0)
    # γ = atan2(sin γ, cos γ), not acos(cos γ): in 32-bit floats acos quantises the
    # angles below ~0.02° (cos γ = 1 − γ²/2 rounds), which read the axial caustic's
    # first texels far out from the axis (a 4× hot pixel at a sun's caustic centre)
    x2 = math_node("MULTIPLY", sep.outputs["X"], sep.outputs["X"])
    sin_g = math_node("SQRT", math_node("MULTIPLY_ADD", sep.outputs["Y"], sep.outputs["Y"], x2))
    gam = math_node("ARCTAN2", sin_g, math_node("MAXIMUM", cosg, 0.0))
    u = math_node("SQRT", math_node("DIVIDE", gam, math.radians(profile["gamma_max_deg"])))
    lp = nt.nodes.new("ShaderNodeLightPath")
    h = math_node("MULTIPLY", lp.outputs["Ray Length"], cosg)
    h_min, h_max = float(profile["h_min"]), float(profile["h_max"])
    log_range = math.log(h_max / h_min)
    h_min = value_node(nt, H_MIN_NODE, h_min)  # live update's and the bake's to write
    if slices is None:
        log_range = value_node(nt, LOG_RANGE_NODE, log_range)
    ratio = math_node("DIVIDE", math_node("MAXIMUM", h, h_min), h_min)
    v = math_node("DIVIDE", math_node("LOGARITHM", ratio, math.e), log_range)

    def lookup(vector):
        tex = nt.nodes.new("ShaderNodeTexImage")
        tex.image = image
        tex.interpolation = "Linear"
        tex.extension = "EXTEND"
        nt.links.new(vector, tex.inputs["Vector"])
        rgb = nt.nodes.new("ShaderNodeSeparateColor")  # red: the intensity
        nt.links.new(tex.outputs["Color"], rgb.inputs[0])
        return rgb

    if slices is None:
        comb = nt.nodes.new("ShaderNodeCombineXYZ")
        nt.links.new(u, comb.inputs["X"])
        nt.links.new(v, comb.inputs["Y"])
        rgb = lookup(comb.outputs[0])
        rgb.inputs[0].links[0].from_node.name = PROFILE_TEX_NODE
        texel, slope = rgb.outputs[0], rgb.outputs[1]
    else:
        count = int(slices.count)
        s = value_node(nt, SLICE_NODE, 0.0)
        base = math_node("MINIMUM", math_node("FLOOR", s), max(count - 2, 0))
        rgb = lookup(slice_coordinates(nt, u, v, slices, base))
        texel, slope = rgb.outputs[0], rgb.outputs[1]
        if count > 1:
            frac = math_node("SUBTRACT", s, base)
            second = lookup(slice_coordinates(nt, u, v, slices, math_node("ADD", base, 1.0)))

            def blend(a, b):
                return math_node("MULTIPLY_ADD", math_node("SUBTRACT", b, a), frac, a)

            texel = blend(texel, second.outputs[0])
            slope = blend(slope, second.outputs[1])
    planes = int(profile.get("tilt_planes", len(profile.get("receivers") or ())))
    if planes:
        values = tilt_values(profile)
        texel = _tilted(
            nt, planes, values, sep, sin_g, cosg, texel, slope, lp.outputs["Ray Length"]
        )
    strength = math_node("MULTIPLY", texel, float(profile.get("strength_scale", 1.0)))
    em = nt.nodes.new("ShaderNodeEmission")
    em.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    nt.links.new(strength, em.inputs["Strength"])
    out = nt.nodes.new("ShaderNodeOutputLight")
    nt.links.new(em.outputs[0], out.inputs["Surface"])
    return nt


def _tilted(nt, planes: int, values: dict, sep, sin_g, cos_g, red, green, ray_length):
    """Near field, receivers tilted against the axis (per plane its unit normal n in
    the light's frame and offset o from the apex, world units: `tilt_values`): the
    light's rays come from its apex (slope tan γ), the beam's from the lens, and a
    plane takes E_perp (n·a + tan α ρ̂·n) of each ray (α its slope), so on plane k
    the texel E (`red`) becomes cos γ (E n·a + S ρ̂·n) / (n·ω), clamped to [0, 8 E]
    (S: the image's green channel `green`, E × the rays' mean slope,
    `tiers.exact_profile._slope_table`; ω: the Normal coordinate, a = −Z). The
    shading point apex + L ω (L: Ray Length) is on plane k where |L n·ω − o| is
    within the tolerance (`profile["plane_tolerance"]`); elsewhere (another surface)
    E as it is. Per plane about 14 math nodes and four Value nodes, `TILT_NODE` (k,
    "nx" | "ny" | "nz" | "offset"), and one `TOLERANCE_NODE`: what the bake keys per
    frame (`planes` of them; a number missing from `values`: `NO_PLANE`'s)."""

    def op(kind, *args):
        return shader_math(nt, kind, *args)

    x, y, z = sep.outputs["X"], sep.outputs["Y"], sep.outputs["Z"]
    tol = value_node(nt, TOLERANCE_NODE, values.get(TOLERANCE_NODE, 0.0))
    inv_sin = op("DIVIDE", 1.0, op("MAXIMUM", sin_g, 1e-6))
    cap = op("MULTIPLY", red, 8.0)
    out = red
    for k in range(planes):
        nx, ny, nz, o = (
            value_node(nt, TILT_NODE.format(k, p), values.get(TILT_NODE.format(k, p), d))
            for p, d in zip(TILT_PARTS, NO_PLANE, strict=True)
        )
        q_xy = op("MULTIPLY_ADD", x, nx, op("MULTIPLY", y, ny))  # sin γ (ρ̂·n)
        n_dot_w = op("MULTIPLY_ADD", z, nz, q_xy)
        n_dot_a = op("MULTIPLY", nz, -1.0)  # a = −Z
        beam = op(
            "MULTIPLY_ADD", green, op("MULTIPLY", q_xy, inv_sin), op("MULTIPLY", red, n_dot_a)
        )
        tilted = op("DIVIDE", op("MULTIPLY", beam, cos_g), op("MAXIMUM", n_dot_w, 1e-4))
        tilted = op("MINIMUM", op("MAXIMUM", tilted, 0.0), cap)
        miss = op("ABSOLUTE", op("SUBTRACT", op("MULTIPLY", ray_length, n_dot_w), o))
        on = op("LESS_THAN", miss, tol)
        out = op("MULTIPLY_ADD", on, op("SUBTRACT", tilted, out), out)
    return out


def create_light(
    scene,
    planned,
    lens_object,
    collection,
    link_cache,
    model_name="",
    image_cache=None,
    arrays=None,
):
    """One lens light object from a `PlannedLight` (EXACT_PROFILE: with its node
    tree, and its shadow mask given phase 1's `arrays`; `image_cache` shares
    profile images within a run). `link_cache` a dict: linked now to a collection of
    its lens alone (a layer's fallback light); None: by `link_lights` afterwards."""
    name = f"Lens light {planned.light_name} > {planned.lens_name}"
    data = bpy.data.lights.new(name, "SPOT")
    ob = bpy.data.objects.new(name, data)
    try:
        apply_light(ob, planned, image_cache, arrays)
    except Exception:
        bpy.data.objects.remove(ob)  # not registered yet: clear would miss them
        bpy.data.lights.remove(data)
        raise
    collection.objects.link(ob)
    if lens_object is not None and link_cache is not None:  # else `link_lights` links
        link = link_collection(scene, lens_object, link_cache)
        ob.light_linking.receiver_collection = link
        ob.light_linking.blocker_collection = link
    meta = ob.lens_lights
    meta.is_lens_light = True
    meta.source_light = planned.light_name
    meta.source_lens = planned.lens_name
    meta.kind = planned.light.kind
    meta.energy_model = model_name or planned.light.model
    register(scene, ob)
    return ob


def _put(owner, attr, value):
    """Set `owner.attr` only if it differs (float32 storage: a relative tolerance),
    so that an unchanged lens light is not tagged for re-evaluation (live update)."""
    old = getattr(owner, attr)
    if isinstance(value, str) or isinstance(old, (bool, str)):
        same = old == value
    else:
        olds = tuple(old) if hasattr(old, "__len__") else (old,)
        news = tuple(value) if hasattr(value, "__len__") else (value,)
        same = len(olds) == len(news) and all(
            abs(a - b) <= 1e-6 * max(1.0, abs(b)) for a, b in zip(olds, news, strict=True)
        )
    if not same:
        setattr(owner, attr, value)


#: Custom properties of a profile light's data: what its node tree was built from
#: (its shape: sizes, planes), the values in it (table key, distances, tilts), and
#: whether it ends with a shadow mask (then what the mask was drawn from).
PROFILE_SIGNATURE = "lens_lights_profile_signature"
PROFILE_VALUES = "lens_lights_profile_values"
MASKED = "lens_lights_masked"
MASK_SIGNATURE = "lens_lights_mask_signature"
#: A light's data whose energy live update wrote from the coarse beam summary
#: (`exact_profile.coarse_summaries`): the refine writes the exact energy however
#: close it is (`_put`'s tolerance would keep the coarse one).
COARSE_ENERGY = "lens_lights_coarse_energy"


def _profile_signatures(profile: dict) -> tuple[str, str]:
    """(shape, values) of a profile's node tree: a tree of the same shape takes new
    values in place (`_update_profile_in_place`)."""
    shape = repr(
        [profile.get(k) for k in ("height", "width", "gamma_max_deg", "strength_scale")]
        + [len(profile.get("receivers") or ()), profile.get("key") is None]
    )
    values = repr(
        [profile.get(k) for k in ("key", "h_min", "h_max")]
        # the tilt correction's planes, in the light's frame
        + [profile.get(k) for k in ("axis", "receivers", "plane_tolerance")]
    )
    return shape, values


def _mask_signature(planned, arrays) -> str:
    """What a shadow mask is drawn from (`mask_nodes.shadow_mask`): the light and its
    lens, where the light sits, and the blockers of its shadow list."""
    src, bl = planned.source, planned.light
    k = np.asarray(src.shadow_list, dtype=np.int64)
    parts = [
        np.asarray(src.lens_center, float),
        np.asarray(src.axis, float),
        np.array([src.distance, src.lens_radius, src.ior, src.unblocked_fraction], float),
        np.asarray(bl.location, float),
        np.asarray(bl.direction, float),
        np.array([getattr(bl, "receiver_distance", None) or -1.0], float),
        k.astype(float),
        arrays.center[k].ravel(),
        arrays.radius[k],
        arrays.ior[k],
        arrays.kt[k],
    ]
    return np.concatenate([np.ravel(x) for x in parts]).astype(np.float64).tobytes().hex()


def _update_profile_in_place(data, profile: dict, image_cache) -> bool:
    """Write a profile's values into the light's existing tree of the same shape (the
    distances and tilts into its Value nodes, the table into its image: a shared
    one with that key, else its own image rewritten where nothing else uses it);
    False where the tree lacks a node (an older file's: rebuild)."""
    nt = data.node_tree
    tex = nt.nodes.get(PROFILE_TEX_NODE) if nt is not None else None
    h_min, log_range = (
        nt.nodes.get(n) if nt is not None else None for n in (H_MIN_NODE, LOG_RANGE_NODE)
    )
    tilts = tilt_values(profile)
    if (
        tex is None
        or h_min is None
        or log_range is None
        or any(nt.nodes.get(n) is None for n in tilts)
    ):
        return False
    h0, h1 = float(profile["h_min"]), float(profile["h_max"])
    values = {H_MIN_NODE: h0, LOG_RANGE_NODE: math.log(h1 / h0), **tilts}
    changed = False
    for name, value in values.items():  # only changes
        outputs = nt.nodes[name].outputs
        if outputs[0].default_value != float(np.float32(value)):  # (a float socket)
            # written raw, the tree updated once below: each `default_value =` updates
            # the whole tree (0.1-0.2 ms; a moved light writes five or more)
            outputs.foreach_set("default_value", [value])
            changed = True
    if changed:  # (tags the light for the depsgraph as a socket's write does)
        nt.update_tag()
    key = profile["key"]
    H, K = int(profile["height"]), int(profile["width"])
    img = _keyed_image(key, K, H, image_cache)
    if img is None:
        old = tex.image
        if (
            old is not None
            and _is_profile_image(old)
            and old.users == 1
            and tuple(old.size) == (K, H)
        ):
            write_profile_pixels(old, profile)  # ours alone: rewritten, not remade
            old.name = PROFILE_PREFIX + key
            img = old
            if image_cache is not None:
                image_cache[key] = img
        else:  # (shared: a new image, packed when the file is saved)
            img = profile_image(profile, image_cache, pack=False)
    if tex.image != img:
        tex.image = img
    return True


def apply_light(ob, planned, image_cache=None, arrays=None) -> bool:
    """Put a `PlannedLight`'s values on the lens light `ob` (new, or kept by live
    update): transform, energy, colour, cone, blend, radius, distance, the origin
    notes, and for EXACT_PROFILE its node tree: built when new or of another shape
    (table size, tilted planes), else its values written in place (distances, tilts,
    the table's pixels: `_update_profile_in_place`); a source with a shadow list
    ends with a shadow mask (`mask_nodes.add_shadow_mask`; `arrays`: phase 1's
    `SceneArrays`), its tree rebuilt only when what the mask is drawn from changed
    (the light, its lens, the blockers). Writes only what changed; True if the tree
    was built or rewritten."""
    bl = planned.light
    data = ob.data
    coarse_energy = bool(getattr(bl, "coarse_energy", False))
    if data.get(COARSE_ENERGY) and not coarse_energy:
        data.energy = bl.energy_w  # the exact energy, however close the coarse one
        del data[COARSE_ENERGY]
    else:
        _put(data, "energy", bl.energy_w)
        if coarse_energy and not data.get(COARSE_ENERGY):
            data[COARSE_ENERGY] = True
    _put(data, "color", bl.color)
    _put(data, "spot_size", math.radians(bl.spot_size_deg))
    _put(data, "spot_blend", bl.spot_blend)
    _put(data, "shadow_soft_size", bl.radius)
    _put(data, "use_custom_distance", True)
    _put(data, "cutoff_distance", bl.cutoff_distance)
    changed = False
    profile = getattr(bl, "profile", None)
    if profile is not None:
        changed = _apply_profile(data, ob, planned, profile, image_cache, arrays)
    _put(ob, "location", bl.location)
    _put(ob, "rotation_mode", "QUATERNION")
    _put(ob, "rotation_quaternion", Vector(bl.direction).to_track_quat("-Z", "Y"))
    _put(ob, "scale", (bl.scale_xy, bl.scale_xy, 1.0))
    meta = ob.lens_lights
    _put(meta, "full", bool(planned.source.full))
    _put(meta, "unblocked_fraction", float(planned.source.unblocked_fraction))
    _put(meta, "relative_brightness", bl.relative_brightness)
    _put(meta, "note", bl.note)
    return changed


def _apply_profile(data, ob, planned, profile, image_cache, arrays) -> bool:
    """The profile part of `apply_light`: True if the tree was built or rewritten."""
    shape, values = _profile_signatures(profile)
    masked = arrays is not None and len(planned.source.shadow_list) > 0
    mask_sig = _mask_signature(planned, arrays) if masked else ""
    same_shape = (
        data.get(PROFILE_SIGNATURE) == shape
        and profile.get("key") is not None
        and data.get(MASK_SIGNATURE, "") == mask_sig
    )
    if same_shape and data.get(PROFILE_VALUES) == values:
        return False  # the same tree, the same numbers
    if (
        same_shape
        and not data.get(MASKED, False)
        and _update_profile_in_place(data, profile, image_cache)
    ):
        data[PROFILE_VALUES] = values
        return True
    build_profile_nodes(data, profile, profile_image(profile, image_cache))
    data[PROFILE_SIGNATURE] = shape
    data[PROFILE_VALUES] = values
    data[MASKED] = bool(masked and mask_nodes.add_shadow_mask(ob, planned, arrays))
    data[MASK_SIGNATURE] = mask_sig
    return True


def build(scene, plan, lens_objects, progress=None, arrays=None):
    """Create the planned lights (unlinked: `link_lights` next); `lens_objects[i]`:
    original object of sphere i. `progress(k)` is called with the number of lights
    made so far. `arrays`: phase 1's `SceneArrays` (a profile light of a non-full
    source gets its shadow mask)."""
    collection = lights_collection(scene)
    images: dict = {}
    made = []
    exact_profile.prepare_tables([p.light for p in plan.lights])  # their tables at once
    for k, planned in enumerate(plan.lights):
        made.append(
            create_light(
                scene,
                planned,
                lens_objects[planned.source.lens],
                collection,
                None,
                image_cache=images,
                arrays=arrays,
            )
        )
        if progress is not None and k % 16 == 15:
            progress(k + 1)
    return made


def remove_unused_profile_images() -> int:
    """Remove the extension's profile images (marked) that nothing uses; an image
    still used (by another scene's lens lights, or by something of the user's) is
    kept. Returns how many were removed."""
    unused = [img for img in bpy.data.images if _is_profile_image(img) and img.users == 0]
    if unused:
        bpy.data.batch_remove(unused)
    return len(unused)


# --------------------------------------------------------------------------- linking


@dataclass
class LinkReport:
    """What `link_lights` did: the plan, and for the report the names of the lenses
    left unlinked and of the (light, lens) pairs sharing a group in spite of a beam."""

    groups: int = 0
    budget: int = MAX_SETS
    linked: int = 0
    lights: int = 0
    ungrouped: list = field(default_factory=list)  # lens object names
    conflicts: list = field(default_factory=list)  # (light name, lens name)
    instances: int = 0  # lights reaching another instance of their lens's object
    user_sets: int = 0
    user_collections: int = 0
    user_linked: int = 0  # lights keeping their user's light's own linking
    blender_says: list = field(default_factory=list)  # Blender's own console lines


def _is_ours(coll) -> bool:
    return coll is not None and coll.get(COLLECTION_MARK) is not None


def _members(coll, state=None, seen=None):
    """(object, link state) of a linking collection, as Blender reads it: its own
    objects with their state, a child collection's objects with the child's state."""
    seen = set() if seen is None else seen
    if coll.as_pointer() in seen:
        return
    seen.add(coll.as_pointer())
    # (a CollectionObject / CollectionChild names no object: same order as the lists)
    for ob, member in zip(coll.objects, coll.collection_objects, strict=True):
        yield ob, state or member.light_linking.link_state
    for child, link in zip(coll.children, coll.collection_children, strict=True):
        yield from _members(child, state or link.light_linking.link_state, seen)


def user_linking(scene):
    """The user's own light and shadow linking in `scene`: per kind, the collections
    its emitters use and each object's membership (signature) in them. Returns
    (collections, sets, signature per object pointer) with the larger count of the
    two kinds (ours left out)."""
    counts = []
    signatures: dict = {}
    for attr in ("receiver_collection", "blocker_collection"):
        colls = {}
        for ob in scene.objects:
            ll = getattr(ob, "light_linking", None)
            coll = getattr(ll, attr, None) if ll is not None else None
            if coll is not None and not _is_ours(coll):
                colls[coll.as_pointer()] = coll
        sig: dict = {}
        for ptr, coll in colls.items():
            for ob, state in _members(coll):
                sig.setdefault(ob.as_pointer(), set()).add((ptr, state))
        kinds = {frozenset(v) for v in sig.values()}
        counts.append((len(colls), len(kinds)))
        for k, v in sig.items():
            signatures.setdefault(k, set()).update((attr, *x) for x in v)
    colls = max(c for c, _ in counts)
    sets = max(s for _, s in counts)
    return colls, sets, {k: frozenset(v) for k, v in signatures.items()}


def _group_collections(scene) -> dict:
    out = {}
    for item in scene.lens_lights.created_collections:
        coll = item.collection
        if coll is not None and coll.get(COLLECTION_MARK) == LINK_MARK and LINK_GROUP in coll:
            out.setdefault(int(coll[LINK_GROUP]), coll)
    return out


def _group_collection(scene, g, existing):
    coll = existing.get(g)
    if coll is None:
        coll = bpy.data.collections.new(f"{LINK_PREFIX}group {g + 1}")
        coll[COLLECTION_MARK] = LINK_MARK
        coll[LINK_GROUP] = g
        _register_collection(scene.lens_lights, coll)
        existing[g] = coll
    return coll


def user_link(light_object):
    """(receiver, blocker) collections of a user's light's own linking (None each
    where it has none; None for a light without any)."""
    ll = getattr(light_object, "light_linking", None)
    if ll is None:
        return None
    rc, bc = ll.receiver_collection, ll.blocker_collection
    rc = None if rc is None or _is_ours(rc) else rc
    bc = None if bc is None or _is_ours(bc) else bc
    return (rc, bc) if rc is not None or bc is not None else None


def user_links_of(planned, light_objects) -> list:
    """`user_link` of each planned light's user light (`light_objects`: the read's,
    indexed by the source's light)."""
    return [user_link(light_objects[p.source.light]) for p in planned]


def _with_lenses_out(scene, user_coll, group_coll, made: dict):
    """A linking collection of ours that is `user_coll` (each object in it with its
    link state, as Blender reads it) with the lenses of `group_coll` excluded: a user
    light's linking for its lens lights. None for no group: the user's own collection
    serves as it is. Made once per (user collection, group) and run; an existing one
    is refilled only where it differs (live update)."""
    if group_coll is None:
        return user_coll
    key = f"{user_coll.name_full} + group {int(group_coll.get(LINK_GROUP, 0)) + 1}"
    coll = made.get(key)
    if coll is not None:
        return coll
    coll = next(
        (
            item.collection
            for item in scene.lens_lights.created_collections
            if item.collection is not None and item.collection.get(USER_LINK) == key
        ),
        None,
    )
    if coll is None:
        coll = bpy.data.collections.new(f"{LINK_PREFIX}{key}")
        coll[COLLECTION_MARK] = LINK_MARK
        coll[USER_LINK] = key
        _register_collection(scene.lens_lights, coll)
    want = {ob.as_pointer(): (ob, state) for ob, state in _members(user_coll)}
    for ob in group_coll.objects:  # the lens out, whatever the user said of it
        want[ob.as_pointer()] = (ob, "EXCLUDE")
    for ob in list(coll.objects):
        if ob.as_pointer() not in want:
            coll.objects.unlink(ob)
    have = {ob.as_pointer() for ob in coll.objects}
    for ptr, (ob, _) in want.items():
        if ptr not in have:
            coll.objects.link(ob)
    for ob, member in zip(coll.objects, coll.collection_objects, strict=True):
        state = want[ob.as_pointer()][1]
        if member.light_linking.link_state != state:
            member.light_linking.link_state = state
    made[key] = coll
    return coll


def link_lights(
    scene, objects, planned, centers, radii, sphere_objects, everywhere=False, user_links=None
) -> LinkReport:
    """Light and shadow linking for the lens lights `objects` (made from `planned`,
    row for row): which need their lens out and each lens's group (`core/plan/linking`),
    within the budget left by the user's own linking; the group collections made,
    filled and emptied to match (only what differs is written, for live update), and
    those no light uses removed. `centers`, `radii`, `sphere_objects`: every sphere of
    the read (lenses a beam may reach). `everywhere`: every beam taken as reaching
    every lens (a bake's lights move). `user_links`: per light, its user's light's own
    linking (`user_link`, None: none), which its lens light keeps: the user's
    collections with its lens group excluded (`_with_lenses_out`)."""
    report = LinkReport(lights=len(objects))
    ptrs: dict = {}
    owner = np.array([ptrs.setdefault(o.as_pointer(), len(ptrs)) for o in sphere_objects])
    by_id = {ptrs[o.as_pointer()]: o for o in sphere_objects}
    user_colls, user_sets, user_sig = user_linking(scene)
    report.user_sets, report.user_collections = user_sets, user_colls
    budget = max(0, min(MAX_SETS - user_sets, MAX_COLLECTIONS - user_colls))
    lights = [p.light for p in planned]
    beams = beams_of(lights, [p.source.lens for p in planned])
    lens_sig = {}
    for i, ob in by_id.items():  # the user's membership of each lens object, as an id
        s = user_sig.get(ob.as_pointer())
        if s:
            lens_sig[i] = lens_sig.setdefault(s, len(lens_sig))
    others = len(
        {v for k, v in user_sig.items() if k not in {o.as_pointer() for o in by_id.values()}}
    )
    for _ in range(4):  # the user's collections on lenses split our sets: fit them
        plan = plan_linking(beams, centers, radii, owner, budget=budget, everywhere=everywhere)
        sig = np.array([lens_sig.get(i, -1) for i in range(len(by_id))], dtype=int)
        excess = sets_used(plan.group, sig, others) - MAX_SETS
        if excess <= 0 or budget == 0:
            break
        budget = max(0, budget - excess)
    report.groups, report.budget, report.linked = plan.groups, budget, int(plan.linked.sum())
    report.ungrouped = sorted(by_id[o].name for o in plan.ungrouped)
    report.conflicts = [(objects[r].name, sphere_objects[s].name) for r, s in plan.conflicts]
    report.instances = len({r for r, _ in plan.instances})
    existing = _group_collections(scene)
    colls = {
        g: _group_collection(scene, g, existing) for g in sorted(set(plan.group.tolist())) if g >= 0
    }
    want = {
        g: {by_id[o].as_pointer(): by_id[o] for o in np.nonzero(plan.group == g)[0]} for g in colls
    }
    for g, coll in colls.items():
        have = {ob.as_pointer(): ob for ob in coll.objects}
        for ptr, ob in have.items():
            if ptr not in want[g]:
                coll.objects.unlink(ob)
        for ptr, ob in want[g].items():
            if ptr not in have:
                coll.objects.link(ob)
        for member in coll.collection_objects:
            if member.light_linking.link_state != "EXCLUDE":
                member.light_linking.link_state = "EXCLUDE"
    users = user_links if user_links is not None else [None] * len(objects)
    combined: dict = {}
    for ob, p, on, user in zip(objects, planned, plan.linked.tolist(), users, strict=True):
        g = int(plan.group[owner[p.source.lens]])
        coll = colls[g] if on else None
        receivers = blockers = coll
        if user is not None:  # the user's light's own linking, its lens still out
            if user[0] is not None:
                receivers = _with_lenses_out(scene, user[0], coll, combined)
            if user[1] is not None:
                blockers = _with_lenses_out(scene, user[1], coll, combined)
        ll = ob.light_linking
        if ll.receiver_collection != receivers:
            ll.receiver_collection = receivers
        if ll.blocker_collection != blockers:
            ll.blocker_collection = blockers
    report.user_linked = sum(1 for u in users if u is not None)
    settings = scene.lens_lights
    kept = {c.as_pointer() for c in combined.values()}
    for k in reversed(range(len(settings.created_collections))):
        coll = settings.created_collections[k].collection
        stale = coll is not None and (
            (LINK_GROUP in coll and int(coll[LINK_GROUP]) not in colls)
            or (USER_LINK in coll and coll.as_pointer() not in kept and user_links is not None)
        )
        if stale:
            settings.created_collections.remove(k)
            bpy.data.collections.remove(coll)
    return report


#: What Blender prints when a linking limit is passed (depsgraph_light_linking.cc).
BLENDER_LIMIT_TEXT = "Maximum number of light linking"


def linking_messages(context) -> list[str]:
    """Blender's own console lines about its linking limits: the view layer's
    depsgraph evaluated with the process's standard output caught (Blender prints
    them from C, at the relations' rebuild). Empty where it cannot be caught."""
    import ctypes
    import os
    import sys
    import tempfile

    try:
        libc = ctypes.CDLL(None)
    except OSError:
        return []
    sys.stdout.flush()
    with tempfile.TemporaryFile(mode="w+b") as tmp:
        saved = os.dup(1)
        try:
            libc.fflush(None)
            os.dup2(tmp.fileno(), 1)
            context.evaluated_depsgraph_get().update()
            context.view_layer.update()
            libc.fflush(None)
        finally:
            os.dup2(saved, 1)
            os.close(saved)
        tmp.seek(0)
        text = tmp.read().decode("utf-8", "replace")
    lines = text.splitlines()
    for line in lines:  # what is not ours goes on to the console as it would have
        if BLENDER_LIMIT_TEXT not in line:
            print(line)
    return [line.strip() for line in lines if BLENDER_LIMIT_TEXT in line]
