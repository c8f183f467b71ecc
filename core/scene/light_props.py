"""A Blender light's properties → a primary (`core.scene.primaries`), and what of it
Lens Lights does not model (pure; `blender.read.scene` copies the properties into a
`LightRecord`).

`LightProps` is what the reader copies of one light data block (Blender 4.2–5.2:
``exposure`` and ``normalize`` exist from 4.3 on, 4.2 reads them as 0 and True).
`primary_of` places it with the instance's world matrix. Power (SPEC §9, §10):

* point, spot: ``energy × 2^exposure``, × the sphere's area ``4πr²`` when not
  normalised (Blender's point and spot lights with a radius are spheres);
* sun: the strength ``energy × 2^exposure`` in W/m² (no normalisation);
* area: ``energy × 2^exposure``, × its area (object scale included) when not normalised.

`LightRecord` (with `LightNodes`) is what the walk copies of one light, as Blender
holds it; `light_props` makes its `LightProps` (the colour × the blackbody colour,
what its node tree does: `node_emission`), once per light in the assembly. A node
tree is read when it is one Emission (constant colour) whose Strength is a constant
or an IES Texture's Fac (`ies`: then the primary carries a `ies.LightProfile` and
phase 1's emission toward each lens is scaled by it); any other tree leaves the
light out (`UNREAD_NODES`), never lit as if it had none.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .ies import IesError, IesProfile, LightProfile, light_frame, parse_ies
from .primaries import (
    AREA,
    ELLIPSE,
    POINT,
    RECTANGLE,
    SHAPES,
    SPOT,
    SQUARE,
    SUN,
    AreaPrimary,
    PointPrimary,
    SpotPrimary,
    SunPrimary,
    area_of,
    from_matrix,
)


@dataclass(frozen=True)
class LightProps:
    """The properties of one Blender light data block (and its object) that matter."""

    type: str  # light.type
    energy: float  # light.energy (W; a sun: W/m²)
    color: tuple = (1.0, 1.0, 1.0)  # colour × blackbody colour
    exposure: float = 0.0  # light.exposure (4.3+)
    normalize: bool = True  # light.normalize (4.3+)
    radius: float = 0.0  # shadow_soft_size (point, spot)
    spot_size: float = math.pi / 4  # radians, full cone
    spot_blend: float = 0.15
    angle: float = 0.0  # sun: angular diameter, radians
    shape: str = SQUARE  # area
    size: float = 1.0
    size_y: float = 1.0
    spread: float = math.pi  # area: Cycles' spread (π: Lambertian)
    uses_nodes: bool = False  # a light node tree drives its emission (Cycles)
    nodes_scale: float = 1.0  # what its nodes multiply its power by (`node_emission`)
    nodes_color: tuple = (1.0, 1.0, 1.0)  # … and its colour
    ies: IesProfile | None = None  # the IES profile its nodes read, if any
    ies_key: str = ""  # where that profile came from
    nodes_unread: str = ""  # why its nodes cannot be read ("" : they can)
    nodes_ignored: bool = False  # the render engine does not evaluate its nodes (EEVEE)
    linked: bool = False  # the light has light or shadow linking of its own


@dataclass(frozen=True)
class LightNodes:
    """A light's node tree as read (when it has one and uses it): its nodes' kinds,
    and of its one Emission node (if it has one) the colour, strength and how many
    of its inputs are linked."""

    kinds: tuple  # bl_idname of each node
    emissions: int  # how many Emission nodes
    color: tuple = (1.0, 1.0, 1.0)  # the Emission's Color (one Emission)
    strength: float = 1.0
    linked_inputs: int = 0
    #: What feeds the Emission's Strength: "" (nothing), IES_FAC (an IES Texture's
    #: Fac), or the bl_idname and output of another node.
    strength_from: str = ""
    ies_text: str = ""  # that IES Texture's file, as text
    ies_key: str = ""  # where it came from (the Text's or file's name)
    ies_strength: float = 1.0  # its Strength input
    ies_linked: int = 0  # how many of its inputs are linked
    ies_error: str = ""  # why its file could not be read


@dataclass
class LightRecord:
    """One light as the walk reads it (shared by all instances of its evaluated
    object / data / original): Blender's values, copied, nothing derived."""

    name: str  # the evaluated object's name
    orig: object  # the original object (carried through, not looked at)
    type: str  # light.type
    energy: float
    color: tuple = (1.0, 1.0, 1.0)  # light.color
    temperature_color: tuple | None = None  # its blackbody colour, when it uses one
    exposure: float = 0.0
    normalize: bool = True
    radius: float = 0.0  # point, spot
    spot_size: float = math.pi / 4
    spot_blend: float = 0.15
    angle: float = 0.0  # sun
    shape: str = SQUARE  # area
    size: float = 1.0
    size_y: float = 1.0
    spread: float = math.pi
    nodes: LightNodes | None = None  # its node tree, if it has and uses one
    linked: bool = False  # the object's own light or shadow linking
    nodes_ignored: bool = False  # it has nodes the render engine does not evaluate


#: The node tree every new light has from Blender 5.0 on (and `use_nodes` makes
#: in 4.x): Emission (white, strength 1) → Light Output. It changes nothing.
PLAIN_LIGHT_NODES = ("ShaderNodeEmission", "ShaderNodeOutputLight")


def plain_light_nodes(kinds, color, strength, linked_inputs: int) -> bool:
    """Whether a light's node tree is the plain one (`PLAIN_LIGHT_NODES`, nothing
    linked into the Emission, its colour white and strength 1): then the light's
    own power and colour are all there is."""
    return (
        sorted(kinds) == sorted(PLAIN_LIGHT_NODES)
        and linked_inputs == 0
        and tuple(color[:3]) == (1.0, 1.0, 1.0)
        and strength == 1.0
    )


def uses_light_nodes(nodes: LightNodes | None) -> bool:
    """Whether a light's node tree (None: none, or not used) changes the light."""
    if nodes is None:
        return False
    if nodes.emissions != 1:
        return True
    return not plain_light_nodes(nodes.kinds, nodes.color, nodes.strength, nodes.linked_inputs)


#: `LightNodes.strength_from` for an IES Texture's Fac.
IES_FAC = "ShaderNodeTexIES.Fac"
IES_NODE = "ShaderNodeTexIES"
#: Why a light is left out whose node tree Lens Lights cannot follow.
UNREAD_NODES = "its emission uses nodes Lens Lights cannot read"


def node_emission(nodes: LightNodes | None) -> tuple[float, tuple, IesProfile | None, str]:
    """What a light's node tree does to its emission, as (scale of its power, colour,
    IES profile or None, why it cannot be read — "" when it can). Read: one Emission
    node (constant colour) into the Light Output, its Strength a constant or an IES
    Texture's Fac (constant Strength, its Vector the default: the light's own
    frame); anything else is not read."""
    if nodes is None:
        return 1.0, (1.0, 1.0, 1.0), None, ""
    known = set(PLAIN_LIGHT_NODES) | {IES_NODE}
    if nodes.emissions != 1 or not set(nodes.kinds) <= known:
        return 1.0, (1.0, 1.0, 1.0), None, UNREAD_NODES
    color = tuple(float(c) for c in nodes.color[:3])
    if nodes.strength_from == "":
        if nodes.linked_inputs:  # its Color is fed by a node
            return 1.0, (1.0, 1.0, 1.0), None, UNREAD_NODES
        return float(nodes.strength), color, None, ""
    if nodes.strength_from != IES_FAC or nodes.linked_inputs != 1 or nodes.ies_linked:
        return 1.0, (1.0, 1.0, 1.0), None, UNREAD_NODES
    if nodes.ies_error:
        return 1.0, (1.0, 1.0, 1.0), None, f"its IES file cannot be read ({nodes.ies_error})"
    try:
        profile = parse_ies(nodes.ies_text)
    except IesError as exc:
        return 1.0, (1.0, 1.0, 1.0), None, f"its IES profile cannot be read: {exc}"
    return float(nodes.ies_strength), color, profile, ""


def light_props(record: LightRecord, color: tuple) -> LightProps:
    """The `LightProps` of a light read as `record`, with its `color` (the light's
    colour × its blackbody colour: `light_colors`)."""
    scale, nodes_color, ies, unread = node_emission(record.nodes)
    return LightProps(
        type=record.type,
        energy=record.energy,
        color=color,
        exposure=record.exposure,
        normalize=record.normalize,
        radius=record.radius,
        spot_size=record.spot_size,
        spot_blend=record.spot_blend,
        angle=record.angle,
        shape=record.shape,
        size=record.size,
        size_y=record.size_y,
        spread=record.spread,
        uses_nodes=uses_light_nodes(record.nodes),
        nodes_scale=scale,
        nodes_color=nodes_color,
        ies=ies,
        ies_key=record.nodes.ies_key if ies is not None else "",
        nodes_unread=unread,
        nodes_ignored=record.nodes_ignored,
        linked=record.linked,
    )


def light_colors(records) -> list[tuple]:
    """Each light's colour × its blackbody colour when it uses one (all at once)."""
    if not records:
        return []
    c = np.array([r.color[:3] for r in records], dtype=float).reshape(-1, 3)
    t = [r.temperature_color for r in records]
    if any(x is not None for x in t):
        ones = (1.0, 1.0, 1.0)
        c = c * np.array([ones if x is None else x[:3] for x in t], dtype=float)
    return [tuple(row) for row in c.tolist()]


def light_power(energy: float, exposure: float, normalize: bool, radius: float) -> float:
    """A point or spot light's power in W: ``energy × 2^exposure``, × the sphere's
    area 4πr² when its power is not normalised."""
    power = float(energy) * 2.0 ** float(exposure)
    if not normalize and radius > 0:
        power *= 4.0 * math.pi * radius * radius
    return power


def primary_of(props: LightProps, matrix, name: str = ""):
    """(primary or None, why it is left out, notes on what is not modelled) of a
    light with the world `matrix` (4 × 4)."""
    m = np.asarray(matrix, dtype=float).reshape(4, 4)
    if not np.all(np.isfinite(m)):
        return None, "invalid transform (non-finite numbers)", []
    if props.type not in (POINT, SPOT, SUN, AREA):
        return None, f"{props.type.lower()} light: not a Blender light type Lens Lights knows", []
    position, direction, axis_x, sx, sy = from_matrix(m)
    if props.nodes_unread:
        return None, props.nodes_unread, []
    # its nodes' constant strength and colour scale it; an IES profile, per direction
    scale = 2.0 ** float(props.exposure) * float(props.nodes_scale)
    profile = None
    if props.ies is not None:
        frame = light_frame(m)
        if props.type == SUN:  # one direction: a constant
            local = np.asarray(frame).reshape(3, 3) @ np.asarray(direction)
            scale *= float(props.ies.fac(local))
        else:
            profile = LightProfile(props.ies, frame, props.ies_key)
    notes = []  # (its own light linking: kept by its lens lights, `blender.build.lights`)
    if props.nodes_ignored:
        notes.append(
            "its light nodes: the render engine (EEVEE) does not evaluate them, so its "
            "caustic follows the light as rendered, without them"
        )
    color = tuple(float(c) * float(n) for c, n in zip(props.color, props.nodes_color, strict=True))
    if props.type == SUN:
        strength = float(props.energy) * scale
        if not strength > 0 or not math.isfinite(strength):
            return None, f"sun without strength ({strength:g} W/m²)", notes
        return (
            SunPrimary(
                direction=direction,
                strength=strength,
                angle=float(props.angle),
                color=color,
                name=name,
            ),
            "",
            notes,
        )
    if props.type == AREA:
        shape = props.shape if props.shape in SHAPES else SQUARE
        size_x = float(props.size) * sx
        size_y = float(props.size_y if shape in (RECTANGLE, ELLIPSE) else props.size) * sy
        power = float(props.energy) * scale
        if not props.normalize:
            power *= float(area_of(shape, size_x, size_y))
        if not (power > 0 and math.isfinite(power)) or not size_x * size_y > 0:
            return None, f"area light without power or size ({power:g} W)", notes
        if props.spread < math.pi - 1e-6:
            notes.append(
                f"its spread ({math.degrees(props.spread):.3g}°, Cycles only) is not "
                "modelled: lit as a plain (Lambertian) area light"
            )
        return (
            AreaPrimary(
                position=position,
                direction=direction,
                axis_x=axis_x,
                power_w=power,
                shape=shape,
                size_x=size_x,
                size_y=size_y,
                color=color,
                name=name,
                profile=profile,
            ),
            "",
            notes,
        )
    power = light_power(props.energy, props.exposure, props.normalize, props.radius)
    power *= float(props.nodes_scale)
    kind = props.type.lower()
    if not power > 0 or not math.isfinite(power):
        return None, f"{kind} light without power ({power:g} W)", notes
    if props.type == SPOT:
        return (
            SpotPrimary(
                position=position,
                direction=direction,
                power_w=power,
                spot_size=float(props.spot_size),
                blend=float(props.spot_blend),
                radius=float(props.radius),
                color=color,
                name=name,
                profile=profile,
            ),
            "",
            notes,
        )
    return (
        PointPrimary(
            position=position,
            power_w=power,
            radius=float(props.radius),
            color=color,
            name=name,
            profile=profile,
        ),
        "",
        notes,
    )
