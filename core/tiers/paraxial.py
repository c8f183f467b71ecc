"""The paraxial lens light shared by THESIS and PHYSICAL: a cone at the image
point, or a far-away spot (a *beam*); the tiers differ only in how bright it is
(an :class:`EnergyModel`).

Beams. A collimated source (a cylinder of radius ``R_C`` from the back vertex)
becomes a spot pushed back by ``s`` (default ``COLLIMATED_DISTANCE_FACTOR`` × the
scene's size, less when geometry behind the lens is nearer: the operator casts rays
and passes ``collimated_distance``) along −axis, with half-angle ``atan(R_C/s)``:
at the back vertex its footprint is exactly ``R_C`` and it widens by ``1 + L/s`` at
``L`` beyond it. Its intensity is chosen so that the irradiance at the reference
distance ``L_ref`` (half the scene's reach beyond the back vertex) is the model's
beam irradiance; across the scene it then varies by ``(s + L_ref)²/(s + L)²``,
within ±5 % for ``s = 20 S``. The same representation serves a real image that
lies beyond everything in the scene (the scene sits in the converging part of the
beam, which a spot at the image point cannot light — a marble resting on a table
under a high lamp focuses under the table) and a virtual image farther behind than
``s``; their irradiance at ``L_ref`` is the cone's ``I/(1/V − z)²``, which tends to
the collimated value as ``V → 0``: no jump at the switch. Shadow linking keeps the
lens from blocking the spot; the spot's distance keeps other geometry behind the
lens out of the way.

Radius: a cone sits at the image point and gets the image's radius ``|m|·r``
(SPEC §4.1); a beam's far-away spot (and a cone pulled in before its receiver)
gets the blur ``z·r/D`` the physics gives a receiver ``z`` from the lens centre
(SPEC §10): the receiver's distance when known, else the reference distance.

The reference irradiance of a light (for the brightness cut-off): a cone's
on-axis irradiance at ``|1/V|`` beyond its apex (for PHYSICAL ``T(0)`` times the
primary's irradiance at the lens), a beam's at ``L_ref``.
"""

from __future__ import annotations

import math
from types import SimpleNamespace
from typing import Protocol

import numpy as np

from ..lens.glass import LensOptics
from ..scene.primaries import PrimaryLight
from .base import (
    COLLIMATED,
    COLLIMATED_DISTANCE_FACTOR,
    CUTOFF_FACTOR,
    DEFAULT_SPOT_BLEND,
    REAL,
    SPOT,
    VIRTUAL,
    BlenderLight,
    LightTable,
    Primaries,
    cone_shape,
    cone_shapes,
    downstream_reach,
    downstream_reaches,
    non_full_note,
    non_full_notes,
    relative_brightness,
    unblocked_columns,
    unblocked_share,
    unit_rows,
)
from .near_field import APEX_CLEARANCE, flux_keeping_factor, pulled_in_cone


class EnergyModel(Protocol):
    """Each method takes one source, primary and material (a `SecondarySource`,
    `PrimaryLight`, `LensOptics`) or columns of many (:func:`paraxial_table`: the
    sources' columns, `Primaries` for both primary and material) and returns a
    number or a column."""

    def cone_intensity(self, source, primary: PrimaryLight, optics: LensOptics) -> float:
        """On-axis radiant intensity (W/sr) of a cone seen from its apex."""

    def beam_irradiance(
        self, source, primary: PrimaryLight, optics: LensOptics, reference_distance: float
    ) -> float:
        """On-axis irradiance (W/length²) of a collimated beam, at
        `reference_distance` beyond the back vertex (on a plane across the beam)."""

    def color(self, source, primary: PrimaryLight, optics: LensOptics) -> np.ndarray:
        """Colour of the Blender light (0–1 per channel), one row per source."""


def _vec(v) -> tuple[float, float, float]:
    return tuple(float(x) for x in v)


def is_beyond_scene(source, scene_bounds, scene_size) -> bool:
    """A real image beyond everything in the scene: drawn as a beam (the rule of
    `make_paraxial_light`)."""
    z = float(source.image_distance)
    return (
        downstream_reach(
            source.position, source.axis, scene_bounds, scene_size - (z - float(source.lens_radius))
        )
        <= 0.0
    )


def make_paraxial_light(
    source,
    primary: PrimaryLight,
    energy_model: EnergyModel,
    name: str,
    *,
    optics: LensOptics | None = None,
    spot_blend: float = DEFAULT_SPOT_BLEND,
    scene_size: float = 1.0,
    scene_bounds=None,
    collimated_distance: float | None = None,
    receiver_distance: float | None = None,
) -> BlenderLight:
    """The light of tier `name` whose brightness is `energy_model`'s.

    Which representation (`BlenderLight.note` says):

    * **cone** — a spot at the image point (real or virtual) with half-angle θ;
    * **beam** — the far-away spot of the module's docstring, for a collimated
      source, for a real image beyond everything in the scene, and for a virtual
      image farther behind than the beam's spot would be. Its footprint at the
      back vertex is the beam's (``tan θ·|1/V − R|``, ``R_C`` when collimated) and
      its irradiance at the reference distance (half the scene's reach beyond the
      back vertex) the model's: ``I/(1/V − z)²`` for an image at ``1/V``, the beam
      irradiance when collimated — so it is continuous across the switch;
    * **pulled-in cone** — a real image at or beyond the receiver
      (`receiver_distance`, from the lens centre; `near_field.pulled_in_cone`):
      a spot at the lens centre aimed at the beam's cross-section on the
      receiver, with the cone's flux.

    The radius: the primary's radius times ``z/D`` (``z`` the receiver's distance
    when known, else the image's — the image's size ``|m|·r`` for a cone — or,
    for a beam, the reference distance): the blur the physics gives there (SPEC §10).
    """
    optics = optics or LensOptics()
    axis = [float(x) for x in source.axis]
    norm = math.sqrt(sum(x * x for x in axis))
    axis = [x / norm for x in axis]
    position = [float(x) for x in source.position]
    center = [float(x) for x in source.lens_center]
    radius_lens = float(source.lens_radius)
    unblocked = unblocked_share(source)
    color = _vec(energy_model.color(source, primary, optics)[0])
    notes = []
    primary_irradiance = primary.intensity / source.distance**2  # at the lens centre
    s_far = (
        float(collimated_distance)
        if collimated_distance
        else COLLIMATED_DISTANCE_FACTOR * scene_size
    )
    s_far = max(s_far, 1e-6 * scene_size)
    back_vertex = [c + radius_lens * a for c, a in zip(center, axis, strict=True)]

    if source.kind == "collimated":
        beam = True
    else:
        z_img = float(source.image_distance)  # signed, from the centre
        if source.kind == "real":
            beam = (
                downstream_reach(position, axis, scene_bounds, scene_size - (z_img - radius_lens))
                <= 0.0
            )
            why = "real image beyond the scene"
        else:
            beam = abs(z_img) > s_far
            why = "virtual image far behind"

    # Knowing the receiver, a real image beyond it is a cone pulled in before it
    # (the beam stands for the same converging light when the receiver is not known).
    near = (
        source.kind == "real"
        and receiver_distance is not None
        and z_img > float(receiver_distance) - APEX_CLEARANCE * radius_lens
    )
    inside = False
    if near:
        z_r = float(receiver_distance)
        half, factor = pulled_in_cone(z_img, math.radians(source.spread_deg), z_r)
        shape = cone_shape(math.degrees(half))
        intensity = (
            energy_model.cone_intensity(source, primary, optics)
            * unblocked
            * flux_keeping_factor(
                math.radians(source.spread_deg), math.radians(shape.half_angle_deg)
            )
        )
        irradiance = intensity / z_r**2
        location = center
        radius = primary.radius * z_r / source.distance
        reach_total = scene_size
        inside = True
        notes.append(
            f"near field: image {z_img:.4g} beyond the receiver {z_r:.4g} from the "
            "centre; cone pulled in to the lens centre, flux kept"
        )
    elif beam:
        # Reference: half-way along the scene's reach beyond the back vertex.
        reach = downstream_reach(back_vertex, axis, scene_bounds, scene_size)
        l_ref = (
            0.5 * min(max(reach, 0.0), scene_size) if scene_bounds is not None else 0.5 * scene_size
        )
        if source.kind == "collimated":
            width = float(source.cylinder_radius or 0.0)
            irradiance = energy_model.beam_irradiance(
                source, primary, optics, max(l_ref, 1e-9 * scene_size)
            )
            notes.append(f"collimated beam R_C={width:.4g}")
        else:
            width = math.tan(math.radians(source.spread_deg)) * abs(z_img - radius_lens)
            irradiance = (
                energy_model.cone_intensity(source, primary, optics)
                / (z_img - (radius_lens + l_ref)) ** 2
            )
            notes.append(f"{why}: beam of radius {width:.4g}")
        irradiance *= unblocked
        shape = cone_shape(math.degrees(math.atan2(width, s_far)))
        intensity = irradiance * (s_far + l_ref) ** 2
        location = [p - s_far * a for p, a in zip(back_vertex, axis, strict=True)]
        z_blur = float(receiver_distance) if receiver_distance else radius_lens + max(l_ref, 0.0)
        radius = z_blur * primary.radius / source.distance
        reach_total = s_far + scene_size
        notes.append(f"spot {s_far:.4g} behind the back vertex")
    else:
        shape = cone_shape(source.spread_deg)
        intensity = energy_model.cone_intensity(source, primary, optics) * unblocked
        z_ref = abs(z_img)
        irradiance = intensity / z_ref**2 if z_ref > 0 else math.inf
        location = position
        radius = abs(source.magnification) * primary.radius
        reach_total = math.dist(position, center) + scene_size
    if shape.note:
        notes.append(shape.note)
    notes += non_full_note(source)

    energy = 4.0 * math.pi * intensity
    return BlenderLight(
        type=SPOT,
        energy_w=float(energy),
        spot_size_deg=float(shape.spot_size_deg),
        spot_blend=float(min(max(spot_blend, 0.0), 1.0)),
        radius=float(radius),
        location=_vec(location),
        direction=_vec(axis),
        note="; ".join(notes),
        color=color,
        scale_xy=float(shape.scale_xy),
        cone_half_angle_deg=float(shape.half_angle_deg),
        cutoff_distance=float(CUTOFF_FACTOR * reach_total),
        kind=source.kind,
        model=name,
        reference_irradiance=float(irradiance),
        relative_brightness=(
            float(irradiance / primary_irradiance) if primary_irradiance > 0 else 0.0
        ),
        inside_lens=inside,
    )


#: Why a table's light is a beam (`paraxial_table`; CONE: a cone at the image).
CONE, BEAM_COLLIMATED, BEAM_REAL_BEYOND, BEAM_VIRTUAL_FAR = range(4)


def paraxial_table(
    table,
    p: Primaries,
    energy_model: EnergyModel,
    name: str,
    *,
    spot_blend: float = DEFAULT_SPOT_BLEND,
    scene_size: float = 1.0,
    scene_bounds=None,
    collimated_distance: float | None = None,
    **_ignored,
) -> LightTable:
    """`make_paraxial_light` for every source of a `phase1.SourceTable` at once,
    no receiver known (so no pulled-in cones): cones and beams as there."""
    axis = unit_rows(table.axis)
    R, D, kind = table.lens_radius, table.distance, table.kind
    center, position = table.lens_center, table.position
    unblocked, full = unblocked_columns(table)
    col = kind == COLLIMATED
    with np.errstate(divide="ignore", invalid="ignore"):
        z_img = np.where(col, np.nan, 1.0 / table.vergence)  # signed, from the centre
        m = np.where(col, np.nan, -1.0 / (table.vergence * D))
    columns = SimpleNamespace(
        brightness_factor=table.brightness_factor,
        magnification=m,
        ior=table.ior,
        distance=D,
        lens_radius=R,
    )
    color = energy_model.color(columns, p, p)
    primary_irradiance = p.intensity / D**2
    s_far = (
        float(collimated_distance)
        if collimated_distance
        else COLLIMATED_DISTANCE_FACTOR * scene_size
    )
    s_far = max(s_far, 1e-6 * scene_size)
    back_vertex = center + R[:, None] * axis
    spread_deg = np.degrees(table.spread)
    cone_intensity = energy_model.cone_intensity(columns, p, p)

    real_far = downstream_reaches(position, axis, scene_bounds, scene_size - (z_img - R)) <= 0.0
    why = np.where(
        col,
        BEAM_COLLIMATED,
        np.where(
            (kind == REAL) & real_far,
            BEAM_REAL_BEYOND,
            np.where((kind == VIRTUAL) & (np.abs(z_img) > s_far), BEAM_VIRTUAL_FAR, CONE),
        ),
    )
    beam = why != CONE

    # Beams: far-away spots behind the back vertex.
    reach = downstream_reaches(back_vertex, axis, scene_bounds, scene_size)
    l_ref = (
        0.5 * np.minimum(np.maximum(reach, 0.0), scene_size)
        if scene_bounds is not None
        else np.full(len(table), 0.5 * scene_size)
    )
    with np.errstate(divide="ignore", invalid="ignore"):
        beam_irradiance = energy_model.beam_irradiance(
            columns, p, p, np.maximum(l_ref, 1e-9 * scene_size)
        )
        width = np.where(
            col,
            np.nan_to_num(table.cylinder_radius),
            np.tan(np.radians(spread_deg)) * np.abs(z_img - R),
        )
        b_irr = (
            np.where(col, beam_irradiance, cone_intensity / (z_img - (R + l_ref)) ** 2) * unblocked
        )
    b_shape = cone_shapes(np.degrees(np.arctan2(width, s_far)))
    b_intensity = b_irr * (s_far + l_ref) ** 2
    b_radius = (R + np.maximum(l_ref, 0.0)) * p.radius / D

    # Cones at the image point.
    c_shape = cone_shapes(spread_deg)
    c_intensity = cone_intensity * unblocked
    z_ref = np.abs(z_img)
    with np.errstate(divide="ignore", invalid="ignore"):
        c_irr = np.where(z_ref > 0, c_intensity / z_ref**2, np.inf)

    shape = b_shape.where(beam, c_shape)
    irradiance = np.where(beam, b_irr, c_irr)
    reach_total = np.where(
        beam, s_far + scene_size, np.sqrt(np.sum((position - center) ** 2, axis=1)) + scene_size
    )

    def beam_note(t):
        w = float(width[t])
        return {
            CONE: "",
            BEAM_COLLIMATED: f"collimated beam R_C={w:.4g}",
            BEAM_REAL_BEYOND: f"real image beyond the scene: beam of radius {w:.4g}",
            BEAM_VIRTUAL_FAR: f"virtual image far behind: beam of radius {w:.4g}",
        }[int(why[t])]

    def spot_note(t):
        return f"spot {s_far:.4g} behind the back vertex" if beam[t] else ""

    n = len(table)
    return LightTable(
        model=name,
        kind=kind,
        energy_w=4.0 * math.pi * np.where(beam, b_intensity, c_intensity),
        spot_size_deg=shape.spot_size_deg,
        spot_blend=np.full(n, float(min(max(spot_blend, 0.0), 1.0))),
        radius=np.where(beam, b_radius, np.abs(m) * p.radius),
        location=np.where(beam[:, None], back_vertex - s_far * axis, position),
        direction=axis,
        color=np.broadcast_to(color, (n, 3)),
        scale_xy=shape.scale_xy,
        cone_half_angle_deg=shape.half_angle_deg,
        cutoff_distance=CUTOFF_FACTOR * reach_total,
        reference_irradiance=irradiance,
        relative_brightness=relative_brightness(irradiance, primary_irradiance),
        inside_lens=np.zeros(n, dtype=bool),
        note_parts=[beam_note, spot_note, shape.note, non_full_notes(unblocked, full)],
    )
