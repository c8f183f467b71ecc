"""What every tier shares: its inputs, its output, the cone a Blender spot can
make, and the registry entry (:class:`Tier`) each tier module fills in.

Pure (numpy + standard library); imports nothing of the tiers, so each tier
module imports it and the registry (:mod:`.` — ``addon/tiers/__init__.py``)
imports the tiers.

Blender's conventions (SPEC §9), checked against the renderers' source and by
measurement (tests/test_blender_render.py):

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
Other primaries (spot, sun, area: `addon.primaries`) reach the tiers as the point
light that stands for them toward the lens (:func:`effective_primary`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

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


@dataclass(frozen=True)
class PrimaryLight:
    """What the energy models need of the primary (point) light."""

    power_w: float  # Blender energy (× 2^exposure), W
    radius: float = 0.0  # shadow_soft_size
    color: tuple[float, float, float] = (1.0, 1.0, 1.0)

    @property
    def intensity(self) -> float:
        """Radiant intensity, W/sr: ``P/(4π)`` (SPEC §9)."""
        return self.power_w / (4.0 * math.pi)


def effective_primary(source, primary: PrimaryLight) -> PrimaryLight:
    """The point light that stands for `primary` toward `source`'s lens: its power
    times the source's ``emission`` (a spot's cone share, an area light's
    Lambertian intensity, a sun's equivalent distance², see `addon.primaries`),
    its radius the source's ``source_radius`` where phase 1 gave one."""
    e = float(getattr(source, "emission", 1.0))
    r = float(getattr(source, "source_radius", math.nan))
    if e == 1.0 and not math.isfinite(r):
        return primary
    return PrimaryLight(
        power_w=primary.power_w * e,
        radius=r if math.isfinite(r) else primary.radius,
        color=primary.color,
    )


@dataclass(frozen=True)
class LensOptics:
    """What the material adds to the sphere's geometry (see `material_model`)."""

    transmission_weight: float = 1.0  # w (Principled's Transmission Weight …)
    tint: tuple[float, float, float] = (1.0, 1.0, 1.0)  # colour of a path through the sphere
    absorption: tuple[float, float, float] = (0.0, 0.0, 0.0)  # σ per length (Volume Absorption)


def head_on_transmission(ior: float) -> float:
    """Fresnel transmission through both surfaces at normal incidence:
    ``T(0) = (4n/(n + 1)²)²`` (0.9216 for n = 1.5)."""
    t = 4.0 * ior / (ior + 1.0) ** 2
    return t * t


def glass_color(source, primary: PrimaryLight, optics: LensOptics) -> tuple[float, float, float]:
    """The primary's colour through the glass: × tint, × Beer–Lambert over the
    axial chord ``2R`` (PHYSICAL, FITTED, EXACT_PROFILE)."""
    chord = 2.0 * source.lens_radius
    out = []
    for c, t, a in zip(primary.color, optics.tint, optics.absorption, strict=False):
        t = min(max(float(t), 0.0), 1.0)
        out.append(float(c) * t * math.exp(-max(float(a), 0.0) * chord))
    return tuple(out)


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


def lens_light_radius(
    source, primary: PrimaryLight, scene_size: float, receiver_distance: float | None = None
) -> float:
    """The radius of a lens light standing for `source`'s image (module docstring):
    ``r·z/D``, the blur ``z·r/D`` the physics gives a receiver ``z`` behind the lens
    centre (SPEC §10), with ``z`` the `receiver_distance` when known, else the
    image's distance ``min(|1/V|, S)`` (= ``min(|m|·r, r·S/D)``, the image's own
    radius); finite for a collimated source."""
    r, D = float(primary.radius), float(source.distance)
    if not (r > 0.0 and D > 0.0):
        return 0.0
    S = float(scene_size) if scene_size and math.isfinite(scene_size) and scene_size > 0 else 1.0
    if receiver_distance is not None and receiver_distance > 0:
        return r * min(float(receiver_distance), S) / D
    V = float(source.vergence)
    reach = S if V == 0.0 else min(abs(1.0 / V), S)
    return r * reach / D


def downstream_reach(origin, axis, scene_bounds, fallback):
    """How far the scene reaches beyond `origin` along `axis` (the largest
    `(corner − origin)·axis` over the bounding box, may be negative); `fallback`
    without bounds."""
    if scene_bounds is None:
        return fallback
    lo, hi = ([float(x) for x in b] for b in scene_bounds)
    return sum(
        max((lo_k - o) * a, (hi_k - o) * a)
        for lo_k, hi_k, o, a in zip(lo, hi, origin, axis, strict=False)
    )


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
    finite number) is widened to it, noted.
    """
    note = ""
    theta = float(half_angle_deg)
    if not math.isfinite(theta) or theta < MIN_HALF_ANGLE_DEG:
        note = f"cone half-angle {theta:.3g}° widened to {MIN_HALF_ANGLE_DEG:g}°"
        theta = MIN_HALF_ANGLE_DEG
    full = 2.0 * theta
    if full > SPOT_SIZE_MAX_DEG:
        return ConeShape(
            SPOT_SIZE_MAX_DEG, 1.0, 90.0, f"cone {full:.4g}° clamped to Blender's maximum 180°"
        )
    if full >= SPOT_SIZE_MIN_DEG:
        return ConeShape(full, 1.0, theta, note)
    k = math.tan(math.radians(theta)) / math.tan(math.radians(0.5 * SPOT_SIZE_MIN_DEG))
    extra = f"cone {full:.3g}° < 1°: spot_size 1°, narrowed by object scale {k:.4g}"
    return ConeShape(SPOT_SIZE_MIN_DEG, k, theta, f"{note}; {extra}" if note else extra)


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

    @property
    def short_label(self) -> str:
        """The label without its parenthesis ("Exact profile (Cycles)" → "Exact profile")."""
        return self.label.split(" (")[0]
