"""The shadow mask of an EXACT_PROFILE lens light (bpy): the blocker's shadow drawn
inside the caustic, not only the light dimmed.

A lens light whose source has a shadow list (phase 1's partial blockers) gets a mask
over its emission directions (`core.tiers.exact_profile_mask.emission_mask`: exact rays light →
blockers → lens, landed on the receiver behind the lens), stored as a small 32-bit
float, Non-Color, packed image "Lens mask <light>" (marked like the profile images, so
`cleanup.clear` removes it once unused) and multiplied into the emission strength
of the light's node tree (`lights.build_profile_nodes`): texture coordinates
``0.5 + 0.5 (X, Y)/s_max`` from the emission direction in the light's frame (the
Texture Coordinate's Normal), linear interpolation, EXTEND.

The light's energy already carries the unblocked share (phase 1's, over the lens' cap):
the mask is divided by it, so that what the light emits toward each direction is the
unblocked beam's times the share of it the blockers pass (its total: the flux that
passes, exactly, rather than the cap's share).
"""

from __future__ import annotations

import math

import bpy
import numpy as np
from mathutils import Vector

from ...core.tiers.exact_profile_mask import emission_mask
from .marks import COLLECTION_MARK, MASK_PREFIX, PROFILE_MARK
from .node_maths import shader_math, slice_coordinates, value_node


def shadow_mask(planned, arrays):
    """(pixels, s_max) of the shadow mask of the EXACT_PROFILE light made from `planned`
    (a `planning.PlannedLight`): the emission mask over the cap's unblocked share; None
    for a light without a profile, a full source, or a source without a finite light
    position. `arrays`: the phase-1 `SceneArrays` the shadow list indexes."""
    bl, src = planned.light, planned.source
    if arrays is None or not list(src.shadow_list) or getattr(bl, "profile_info", None) is None:
        return None
    D = float(src.distance)
    axis = np.asarray(src.axis, dtype=float)
    if not (math.isfinite(D) and np.all(np.isfinite(axis))):
        return None
    # the energy already holds the cap's unblocked share: the mask replaces it
    unblocked = float(src.unblocked_fraction)
    if not unblocked > 0.0:
        return None
    light_position = np.asarray(src.lens_center, dtype=float) - D * axis
    k = np.asarray(src.shadow_list, dtype=np.int64)
    blockers = (arrays.center[k], arrays.radius[k], arrays.ior[k], arrays.kt[k])
    rot = Vector(bl.direction).to_track_quat("-Z", "Y").to_matrix()
    ex, ey = (tuple(rot.col[i]) for i in (0, 1))
    mask = emission_mask(
        light_position,
        src.lens_center,
        float(src.lens_radius),
        float(src.ior),
        blockers,
        bl.location,
        ex,
        ey,
        receiver=getattr(bl, "receiver_distance", None),
    )
    return mask.pixels / np.float32(unblocked), float(mask.s_max)


def add_shadow_mask(ob, planned, arrays) -> bool:
    """Mask the EXACT_PROFILE light object `ob` made from `planned` by its source's
    shadow list (`shadow_mask`); False (nothing done) without a profile node tree or
    a mask."""
    nt = ob.data.node_tree if ob.data is not None else None
    if nt is None or not any(n.bl_idname == "ShaderNodeEmission" for n in nt.nodes):
        return False
    mask = shadow_mask(planned, arrays)
    if mask is None:
        return False
    pixels, s_max = mask
    _insert(nt, _mask_image(ob.name, pixels), 0.5 / s_max)
    return True


#: A baked light's keyed Value nodes (`blender/commands/bake.py`): the frame's slice
#: of the stacked masks, and 0.5 / s_max (its directions' scale).
MASK_SLICE_NODE, MASK_SCALE_NODE = "Lens bake mask slice", "Lens bake mask scale"


def add_baked_mask(nt, image, layout) -> None:
    """The bake's shadow mask: `image` holds the frames' masks as slices (`layout`, a
    `core.animation.frame_tables.SliceLayout`), read at the keyed slice
    `MASK_SLICE_NODE` with the keyed scale `MASK_SCALE_NODE`."""
    scale = value_node(nt, MASK_SCALE_NODE, 0.5)
    k = value_node(nt, MASK_SLICE_NODE, 0.0)
    _insert(nt, image, scale, layout, k)


def _mask_image(name, pixels):
    size = int(pixels.shape[0])
    img = bpy.data.images.new(
        MASK_PREFIX + name, width=size, height=size, float_buffer=True, alpha=False
    )
    img[COLLECTION_MARK] = PROFILE_MARK  # removed with the profile images once unused
    img.colorspace_settings.name = "Non-Color"  # first: changing it later loses pixels
    img.use_half_precision = False
    rgba = np.ones((size, size, 4), dtype=np.float32)
    rgba[..., :3] = pixels[..., None]
    img.pixels.foreach_set(rgba.ravel())
    img.update()
    img.pack()
    return img


def _insert(nt, image, scale, layout=None, k=None):
    """Strength ← strength × mask(0.5 + X scale, 0.5 + Y scale) (scale = 0.5 / s_max, a
    number or a socket); with `layout`, read in slice `k` of it
    (`lights.slice_coordinates`)."""
    em = next(n for n in nt.nodes if n.bl_idname == "ShaderNodeEmission")
    strength = em.inputs["Strength"]
    tc = next((n for n in nt.nodes if n.bl_idname == "ShaderNodeTexCoord"), None)
    if tc is None:
        tc = nt.nodes.new("ShaderNodeTexCoord")
    sep = nt.nodes.new("ShaderNodeSeparateXYZ")
    nt.links.new(tc.outputs["Normal"], sep.inputs[0])
    u, v = (shader_math(nt, "MULTIPLY_ADD", sep.outputs[a], scale, 0.5) for a in ("X", "Y"))
    if layout is None:
        comb = nt.nodes.new("ShaderNodeCombineXYZ")
        nt.links.new(u, comb.inputs["X"])
        nt.links.new(v, comb.inputs["Y"])
        vector = comb.outputs[0]
    else:
        vector = slice_coordinates(nt, u, v, layout, k)
    tex = nt.nodes.new("ShaderNodeTexImage")
    tex.image = image
    tex.interpolation = "Linear"
    tex.extension = "EXTEND"
    nt.links.new(vector, tex.inputs["Vector"])
    mul = nt.nodes.new("ShaderNodeMath")
    mul.operation = "MULTIPLY"
    if strength.is_linked:
        nt.links.new(strength.links[0].from_socket, mul.inputs[0])
    else:
        mul.inputs[0].default_value = strength.default_value
    nt.links.new(tex.outputs["Color"], mul.inputs[1])
    nt.links.new(mul.outputs[0], strength)
