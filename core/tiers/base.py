"""What every tier shares: its inputs, its output, the cone a Blender spot can
make, and the registry entry (:class:`Tier`) each tier module fills in.

Pure (numpy + standard library); imports nothing of the tiers, so each tier
module imports it and the registry (:mod:`.` — ``addon/tiers/__init__.py``)
imports the tiers.

Blender's conventions (SPEC §9), checked against the renderers' source and by
measurement (tests/blender/build/test_blender_render.py):

* A point or spot light of power ``P`` W has the radiant intensity ``P/(4π)`` W/sr.
  Cycles (``intern/cycles/scene/light.cpp``) gives point *and* spot lights the same
  ``eval_fac = 1/(π · area)`` with ``area = 4π r²`` (``4`` for ``r = 0``), and EEVEE
  (``draw/engines/eevee/eevee_light.cc``, ``point_radiance_get``/``shape_radiance_get``)
  the same ``1/(4π)``: there is **no extra factor for spot lights** — narrowing the
  cone does not concentrate power.
* Inside the cone the spot's only attenuation is ``smoothstep((cos ψ − cos ½size) /
  ((1 − cos ½size) · blend))`` (Cycles ``kernel/light/spot.h``; EEVEE's ``spot_mul``/
  ``spot_bias``): full intensity wherever ``1 − cos ψ ≤ (1 − blend)(1 − cos ½size)``.
  Older Cycles (≤ 3.x) also multiplied by ``cos ψ``; 4.x/5.x do not.
* ``spot_size`` (full cone angle) is clamped by RNA to 1°–180°. Both engines shape
  the cone with the light object's scale (Cycles ``spot_light_to_local`` divides by
  the scaled axes, EEVEE ``spot_size_inv = scale.z/scale.xy``) and neither scales
  intensity or radius with it. So a cone narrower than 1° is made exactly: spot_size
  1° and the object scaled by ``k = tan θ / tan 0.5°`` in its local x and y
  (:attr:`BlenderLight.scale_xy`). A cone wider than 180° cannot be made; it is
  clamped to 180° (a hemisphere) with unchanged intensity, and noted.
* A spot emits along its local −Z axis (`direction` here is that axis in world space).
* EEVEE fades every local light out towards its influence distance (by default
  ``sqrt(P/100/light_threshold)``, which cuts dim lights off within a metre or so);
  :attr:`BlenderLight.cutoff_distance` is a custom distance five times the farthest
  the light has to reach, which keeps that fade below 0.5 %.

The lens light's radius (:func:`lens_light_radius`, FITTED and EXACT_PROFILE,
whose lights do not sit at the image): a primary of radius ``r`` images to a
source of radius ``|m|·r`` with ``m = −(1/V)/D`` (SPEC §4.1), and seen from
beyond the image a lens light that large looks as large as the image. As
``V → 0`` (collimated) ``|m| → ∞``: the image then subtends ``r/D`` from the lens
(the chief ray through a ball lens's centre is undeviated), so the radius is
capped at ``r·S/D``, the size that shows that divergence across the scene's size
``S``. (A THESIS/PHYSICAL cone sits at the image and gets ``|m|·r`` exactly.)
Where the receiver's distance ``z`` from the lens centre is known (the operator
casts rays, `planning.receiver_distance`), every lens light gets ``z·r/D``: the
blur the physics gives that receiver (SPEC §10), at the image ``|m|·r`` again.
Other primaries (spot, sun, area: `core.scene.primaries`) reach the tiers as the point
light that stands for them toward the lens (:func:`effective_primary`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..lens.glass import LensOptics
from ..scene.primaries import PrimaryLight

#: Blender's range for `spot_size` (full cone angle, degrees).
SPOT_SIZE_MIN_DEG = 1.0
SPOT_SIZE_MAX_DEG = 180.0
#: Narrowest cone made (half-angle, degrees): below it the cone is widened to it
#: (only reached by a degenerate spreading angle, e.g. θ = 0 at φ = 0).
MIN_HALF_ANGLE_DEG = 1e-3
#: A collimated beam's spot sits this many scene sizes behind the back vertex.
COLLIMATED_DISTANCE_FACTOR = 20.0
#: EEVEE's custom influence distance is this many times the farthest reach.
CUTOFF_FACTOR = 5.0
DEFAULT_SPOT_BLEND = 0.15

SPOT, POINT = "SPOT", "POINT"

#: Render engines (`scene.render.engine`) as the panel and the README name them.
CYCLES, EEVEE = "CYCLES", "BLENDER_EEVEE"
ENGINE_NAMES = {
    CYCLES: "Cycles",
    EEVEE: "EEVEE",
    "BLENDER_EEVEE_NEXT": "EEVEE",
    "BLENDER_WORKBENCH": "Workbench",
}


# --------------------------------------------------------------------------- inputs


def effective_primary(source, primary: PrimaryLight) -> PrimaryLight:
    """The point light that stands for `primary` toward `source`'s lens: its power
    times the source's ``emission`` (a spot's cone share, an area light's
    Lambertian intensity, a sun's equivalent distance², see `core.scene.primaries`),
    its radius the source's ``source_radius`` where phase 1 gave one
    (:func:`effective_columns`)."""
    e = float(getattr(source, "emission", 1.0))
    r = float(getattr(source, "source_radius", math.nan))
    if e == 1.0 and not math.isfinite(r):
        return primary
    power, radius = effective_columns(primary.power_w, primary.radius, e, r)
    return PrimaryLight(power_w=float(power), radius=float(radius), color=primary.color)


def effective_columns(power_w, radius, emission, source_radius):
    """`effective_primary` on columns (or scalars): (power × emission, the source's
    radius where finite, else the primary's)."""
    source_radius = np.asarray(source_radius, dtype=float)
    return (
        np.multiply(power_w, emission),
        np.where(np.isfinite(source_radius), source_radius, radius),
    )


def glass_color(source, primary: PrimaryLight, optics: LensOptics) -> tuple[float, float, float]:
    """The primary's colour through the glass: × tint, × Beer–Lambert over the
    axial chord ``2R`` (PHYSICAL, FITTED, EXACT_PROFILE; :func:`glass_colors`)."""
    c = glass_colors(
        np.atleast_1d(source.lens_radius), primary.color, optics.tint, optics.absorption
    )
    return tuple(c[0].tolist())


def glass_colors(lens_radius, color, tint=None, absorption=None) -> np.ndarray:
    """:func:`glass_color` over rows: `color`, `tint`, `absorption` (N, 3) or one
    row of 3 (None: clear, none), `lens_radius` (N,)."""
    color = np.asarray(color, dtype=float).reshape(-1, 3)
    tint = (
        np.ones_like(color)
        if tint is None
        else np.clip(np.asarray(tint, dtype=float).reshape(-1, 3), 0.0, 1.0)
    )
    absorption = (
        np.zeros_like(color)
        if absorption is None
        else np.maximum(np.asarray(absorption, dtype=float).reshape(-1, 3), 0.0)
    )
    chord = 2.0 * np.asarray(lens_radius, dtype=float)[:, None]
    return color * tint * np.exp(-absorption * chord)


def unblocked_share(source) -> float:
    """The share of the lens's lit cap no other sphere covers, within 0…1."""
    return min(max(float(source.unblocked_fraction), 0.0), 1.0)


def non_full_note(source) -> list[str]:
    return (
        []
        if source.full
        else [f"non-full: energy × {unblocked_share(source):.4g} (unblocked share of the lit cap)"]
    )


def axial_light_common(source, primary: PrimaryLight, optics: LensOptics | None):
    """What FITTED and EXACT_PROFILE lights share: axis, R, D, the energy factor
    (transmission weight² × unblocked share), colour (as PHYSICAL), notes."""
    optics = optics or LensOptics()
    axis = np.asarray(source.axis, dtype=float)
    axis = axis / np.linalg.norm(axis)
    R, D = float(source.lens_radius), float(source.distance)
    wgt = min(max(optics.transmission_weight, 0.0), 1.0)
    color = glass_color(source, primary, optics)
    return axis, R, D, wgt * wgt * unblocked_share(source), color, non_full_note(source)


def safe_scene_size(scene_size) -> float:
    """`scene_size` if a positive finite number, else 1."""
    ok = scene_size and math.isfinite(scene_size) and scene_size > 0
    return float(scene_size) if ok else 1.0


def lens_light_radius(
    source, primary: PrimaryLight, scene_size: float, receiver_distance: float | None = None
) -> float:
    """The radius of a lens light standing for `source`'s image (module docstring,
    :func:`lens_light_radii`)."""
    z = math.nan if receiver_distance is None else float(receiver_distance)
    return float(lens_light_radii(primary.radius, source.distance, source.vergence, scene_size, z))


def lens_light_radii(radius, distance, vergence, scene_size, receiver_distance=math.nan):
    """:func:`lens_light_radius` on columns (or scalars): ``r·z/D``, the blur
    ``z·r/D`` the physics gives a receiver ``z`` behind the lens centre (SPEC §10),
    with ``z`` the `receiver_distance` where known (> 0; NaN: unknown), else the
    image's distance ``min(|1/V|, S)`` (= ``min(|m|·r, r·S/D)``, the image's own
    radius); finite for a collimated source; 0 without a radius or distance."""
    r, D, V = (np.asarray(x, dtype=float) for x in (radius, distance, vergence))
    z_r = np.asarray(receiver_distance, dtype=float)
    S = safe_scene_size(scene_size)
    with np.errstate(divide="ignore", invalid="ignore"):
        reach = np.where(V == 0.0, S, np.minimum(np.abs(1.0 / V), S))
        z = np.where(z_r > 0, np.minimum(z_r, S), reach)
        return np.where((r > 0.0) & (D > 0.0), r * z / D, 0.0)


def downstream_reach(origin, axis, scene_bounds, fallback):
    """How far the scene reaches beyond `origin` along `axis` (the largest
    `(corner − origin)·axis` over the bounding box, may be negative); `fallback`
    without bounds (:func:`downstream_reaches`)."""
    if scene_bounds is None:
        return fallback
    return float(
        downstream_reaches(
            np.asarray([origin], dtype=float),
            np.asarray([axis], dtype=float),
            scene_bounds,
            fallback,
        )[0]
    )


def downstream_reaches(origin, axis, scene_bounds, fallback) -> np.ndarray:
    """:func:`downstream_reach` over rows (`origin`, `axis`: (N, 3); `fallback`: a
    number or (N,))."""
    if scene_bounds is None:
        return np.broadcast_to(np.asarray(fallback, dtype=float), origin.shape[:1])
    lo, hi = (np.asarray(b, dtype=float) for b in scene_bounds)
    return np.sum(np.maximum((lo - origin) * axis, (hi - origin) * axis), axis=1)


# --------------------------------------------------------------------------- output


@dataclass
class BlenderLight:
    """One Blender light object, in world space."""

    type: str  # "SPOT"
    energy_w: float  # Light.energy
    spot_size_deg: float  # Light.spot_size (full angle, within 1°–180°)
    spot_blend: float  # Light.spot_blend
    radius: float  # Light.shadow_soft_size
    location: tuple[float, float, float]
    direction: tuple[float, float, float]  # unit; the light's local −Z
    note: str = ""  # what was approximated, for people
    color: tuple[float, float, float] = (1.0, 1.0, 1.0)
    scale_xy: float = 1.0  # object scale in local x, y (narrows the cone)
    cone_half_angle_deg: float = 0.0  # the cone actually made (after scale_xy)
    cutoff_distance: float = 0.0  # EEVEE custom influence distance
    kind: str = ""  # "real" | "virtual" | "collimated"
    model: str = ""
    reference_irradiance: float = 0.0  # W/length², on the axis at the reference distance
    relative_brightness: float = 0.0  # reference irradiance / primary's irradiance at the lens
    #: The light sits inside its lens: the lens must be out of its light and shadow
    #: linking (the builder always excludes it), else the lens swallows the light.
    inside_lens: bool = False

    def to_json(self) -> dict:
        return {
            "type": self.type,
            "energy_w": self.energy_w,
            "spot_size_deg": self.spot_size_deg,
            "spot_blend": self.spot_blend,
            "radius": self.radius,
        }


@dataclass
class ConeShape:
    spot_size_deg: float
    scale_xy: float
    half_angle_deg: float
    note: str = ""


def cone_shape(half_angle_deg: float) -> ConeShape:
    """Blender spot parameters for a cone of half-angle θ (degrees).

    1° ≤ 2θ ≤ 180°: `spot_size = 2θ`, no scale. 2θ < 1°: `spot_size = 1°` and the
    object scaled by `tan θ / tan 0.5°` in x and y (both engines narrow the cone by
    that scale without changing intensity), so the cone is exact. 2θ > 180°: 180°
    (a spot cannot emit backward), noted. θ below `MIN_HALF_ANGLE_DEG` (or not a
    finite number) is widened to it, noted. (One row of :func:`cone_shapes`.)
    """
    s = cone_shapes(np.asarray([half_angle_deg], dtype=float))
    return ConeShape(
        float(s.spot_size_deg[0]), float(s.scale_xy[0]), float(s.half_angle_deg[0]), s.note(0)
    )


@dataclass
class ConeShapes:
    """:func:`cone_shape` over rows; the flags say which note applies."""

    spot_size_deg: np.ndarray
    scale_xy: np.ndarray
    half_angle_deg: np.ndarray
    asked_deg: np.ndarray  # the half-angle asked for (for the note)
    widened: np.ndarray  # bool: below MIN_HALF_ANGLE_DEG or not finite
    clamped: np.ndarray  # bool: wider than 180°
    narrowed: np.ndarray  # bool: spot_size 1° plus object scale

    def note(self, t: int) -> str:
        theta = float(self.asked_deg[t])
        note = (
            f"cone half-angle {theta:.3g}° widened to {MIN_HALF_ANGLE_DEG:g}°"
            if self.widened[t]
            else ""
        )
        if self.clamped[t]:
            full = 2.0 * float(self.half_angle_deg[t] if self.widened[t] else theta)
            return f"cone {full:.4g}° clamped to Blender's maximum 180°"
        if self.narrowed[t]:
            full = 2.0 * float(self.half_angle_deg[t])
            extra = (
                f"cone {full:.3g}° < 1°: spot_size 1°, narrowed by object scale "
                f"{float(self.scale_xy[t]):.4g}"
            )
            return f"{note}; {extra}" if note else extra
        return note

    def where(self, mask: np.ndarray, other: ConeShapes) -> ConeShapes:
        """Rows of `self` where `mask`, of `other` elsewhere."""
        return ConeShapes(
            *(
                np.where(mask, getattr(self, f), getattr(other, f))
                for f in ConeShapes.__dataclass_fields__
            )
        )


def cone_shapes(half_angle_deg) -> ConeShapes:
    """:func:`cone_shape` of every half-angle (degrees) of an array."""
    asked = np.asarray(half_angle_deg, dtype=float)
    with np.errstate(invalid="ignore"):
        widened = ~np.isfinite(asked) | (asked < MIN_HALF_ANGLE_DEG)
    theta = np.where(widened, MIN_HALF_ANGLE_DEG, asked)
    full = 2.0 * theta
    clamped = full > SPOT_SIZE_MAX_DEG
    narrowed = ~clamped & (full < SPOT_SIZE_MIN_DEG)
    k = np.tan(np.radians(theta)) / math.tan(math.radians(0.5 * SPOT_SIZE_MIN_DEG))
    return ConeShapes(
        spot_size_deg=np.where(
            clamped, SPOT_SIZE_MAX_DEG, np.where(narrowed, SPOT_SIZE_MIN_DEG, full)
        ),
        scale_xy=np.where(narrowed, k, 1.0),
        half_angle_deg=np.where(clamped, 90.0, theta),
        asked_deg=asked,
        widened=widened,
        clamped=clamped,
        narrowed=narrowed,
    )


# --------------------------------------------------------------------------- columns

#: Source kinds in the order of `phase1.SourceTable.kind`'s codes.
KINDS = ("real", "virtual", "collimated")
REAL, VIRTUAL, COLLIMATED = range(3)


@dataclass
class Primaries:
    """Per source (rows of a `phase1.SourceTable`): its primary light and its
    lens's material, as columns (`PrimaryLight`, `LensOptics`)."""

    power_w: np.ndarray  # (N,)
    radius: np.ndarray  # (N,)
    color: np.ndarray  # (N, 3)
    transmission_weight: np.ndarray  # (N,)
    tint: np.ndarray | None = None  # (N, 3); None: clear (1, 1, 1)
    absorption: np.ndarray | None = None  # (N, 3); None: none

    @property
    def intensity(self) -> np.ndarray:
        return self.power_w / (4.0 * math.pi)

    def effective(self, table) -> Primaries:
        """`effective_primary` for every source of `table` (its ``emission`` and
        ``source_radius`` columns)."""
        power, radius = effective_columns(
            self.power_w, self.radius, table.emission, table.source_radius
        )
        return dataclasses.replace(self, power_w=power, radius=radius)


def unblocked_columns(table) -> tuple[np.ndarray, np.ndarray]:
    """(`unblocked_share`, full) of every source of a `phase1.SourceTable`."""
    return np.clip(table.unblocked_fraction, 0.0, 1.0), np.diff(table.shadow_offsets) == 0


def non_full_notes(unblocked: np.ndarray, full: np.ndarray) -> Callable[[int], str]:
    """`non_full_note` of row t (a `LightTable` note part)."""
    return lambda t: (
        ""
        if full[t]
        else f"non-full: energy × {float(unblocked[t]):.4g} (unblocked share of the lit cap)"
    )


def unit_rows(v: np.ndarray) -> np.ndarray:
    return v / np.sqrt(np.sum(v * v, axis=1))[:, None]


def relative_brightness(irradiance, primary_irradiance) -> np.ndarray:
    """irradiance / the primary's irradiance at the lens (0 where that is not > 0)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(primary_irradiance > 0, irradiance / primary_irradiance, 0.0)


@dataclass
class LightTable:
    """One Blender light per source of a `phase1.SourceTable`, as columns (what a
    tier's table maker gives); `light(t)` is the `BlenderLight` its per-source
    maker makes."""

    model: str
    kind: np.ndarray  # source kind codes (`KINDS`)
    energy_w: np.ndarray
    spot_size_deg: np.ndarray
    spot_blend: np.ndarray
    radius: np.ndarray
    location: np.ndarray  # (N, 3)
    direction: np.ndarray  # (N, 3)
    color: np.ndarray  # (N, 3)
    scale_xy: np.ndarray
    cone_half_angle_deg: np.ndarray
    cutoff_distance: np.ndarray
    reference_irradiance: np.ndarray
    relative_brightness: np.ndarray
    inside_lens: np.ndarray  # bool
    note_parts: list  # callables t → str ("" when none), in note order
    profile_info: dict | None = None  # EXACT_PROFILE: `ProfileLight.profile_info` columns
    light_class: type | None = None  # the per-source maker's class (None: BlenderLight)

    def __len__(self) -> int:
        return int(self.energy_w.size)

    def note(self, t: int) -> str:
        return "; ".join(p for p in (part(t) for part in self.note_parts) if p)

    def light(self, t: int) -> BlenderLight:
        common = dict(
            type=SPOT,
            energy_w=float(self.energy_w[t]),
            spot_size_deg=float(self.spot_size_deg[t]),
            spot_blend=float(self.spot_blend[t]),
            radius=float(self.radius[t]),
            location=tuple(self.location[t].tolist()),
            direction=tuple(self.direction[t].tolist()),
            note=self.note(t),
            color=tuple(self.color[t].tolist()),
            scale_xy=float(self.scale_xy[t]),
            cone_half_angle_deg=float(self.cone_half_angle_deg[t]),
            cutoff_distance=float(self.cutoff_distance[t]),
            kind=KINDS[int(self.kind[t])],
            model=self.model,
            reference_irradiance=float(self.reference_irradiance[t]),
            relative_brightness=float(self.relative_brightness[t]),
            inside_lens=bool(self.inside_lens[t]),
        )
        if self.profile_info is None:
            return (self.light_class or BlenderLight)(**common)
        info = {
            k: (v[t].item() if isinstance(v, np.ndarray) else v)
            for k, v in self.profile_info.items()
        }
        return self.light_class(**common, profile_info=info)

    def json_columns(self) -> dict[str, list]:
        """`BlenderLight.to_json` of every light, as columns of lists (for JSON)."""
        n = len(self)
        cols = {
            "type": [SPOT] * n,
            "energy_w": self.energy_w.tolist(),
            "spot_size_deg": self.spot_size_deg.tolist(),
            "spot_blend": self.spot_blend.tolist(),
            "radius": self.radius.tolist(),
        }
        if self.profile_info is not None:
            info = {
                k: (v.tolist() if isinstance(v, np.ndarray) else [v] * n)
                for k, v in self.profile_info.items()
            }
            cols["profile"] = [
                dict(zip(info, row, strict=True)) for row in zip(*info.values(), strict=True)
            ]
        return cols


# --------------------------------------------------------------------------- registry entry


@dataclass(frozen=True)
class Accuracy:
    """A tier's figures in reports/accuracy.md: the relative L1 error of the
    irradiance over the lens's shadow disc against the exact optics, mean over
    receivers 0.5–10 R behind the lens, over the 15 cases with D ≥ 2R."""

    l1_mean: float
    l1_worst: float
    l1_median: float | None = None  # given where the mean is dominated by a few cases


#: ``make(source, primary, *, optics, spot_blend, scene_size, scene_bounds,
#: collimated_distance, receiver_distance) -> BlenderLight`` (see
#: `tiers.make_blender_light`).
LightMaker = Callable[..., BlenderLight]
#: ``make_table(table, primaries, *, spot_blend, scene_size, scene_bounds,
#: collimated_distance) -> LightTable``: the same lights for every source of a
#: `phase1.SourceTable` with no receiver known (see `tiers.make_light_table`).
TableMaker = Callable[..., LightTable]


@dataclass(frozen=True)
class Tier:
    """One energy model: how to make its light and how to describe it.

    ``description``: the setting's tooltip; ``trades``: one line on what it trades
    (the panel, the README's table); ``engines``: where it renders; ``number``: the
    enum number a .blend stores (fixed: files must keep their choice)."""

    name: str
    label: str
    description: str
    trades: str
    engines: tuple[str, ...]
    accuracy: Accuracy
    number: int
    make: LightMaker
    make_table: TableMaker

    @property
    def short_label(self) -> str:
        """The label without its parenthesis ("Exact profile (Cycles)" → "Exact profile")."""
        return self.label.split(" (")[0]
