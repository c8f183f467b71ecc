"""Energy models: a secondary light source → the parameters of one Blender light.

Pure (numpy + standard library). The Blender side (`operators/light_builder.py`)
only copies the fields of :class:`BlenderLight` onto a light object.

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

Energy models (``ENERGY_MODELS``; a model is an :class:`EnergyModel`):

``THESIS``    eq. 5.22: the secondary source is a point light of intensity
              ``I0 · exp(−(1 − kt)(2R + TR)/2)`` (``I0 = P/(4π)``), primary's colour.
``PHYSICAL``  flux-conserving paraxial optics (SPEC §6): on-axis intensity
              ``I0 · T(0) · m²`` seen from the image point, with the head-on Fresnel
              transmission of both surfaces ``T(0) = (4n/(n + 1)²)²``, the square of
              the material's transmission weight (it applies at entry and at exit)
              and, in the colour, the tint of a path through the sphere
              (`material_model`) and Beer–Lambert absorption over the axial chord
              ``2R``.

Every model also says what irradiance a collimated beam has; the geometry (cone or
far-away spot) and the non-full scaling by the unblocked share of the lit cap are
common to both.

Two more tiers are made by :mod:`.lens_tiers` (:func:`make_blender_light` hands
them over; their registry entries, :class:`TierModel`, only name and describe them):

``FITTED``         one spot fitted to the exact beam (EEVEE and Cycles); its own
                   position, cone and blend (the ``spot_blend`` setting does not apply).
``EXACT_PROFILE``  the exact beam tabulated over angle and distance, read by the
                   light's node tree (Cycles only: EEVEE ignores light nodes).

``AUTO`` (the panel's default) is not a tier: :func:`resolve_energy_model` turns it
into the most accurate tier the render engine can show — ``EXACT_PROFILE`` in
Cycles, ``FITTED`` otherwise — as measured in reports/accuracy.md (relative L1 error
of the irradiance over the lens's shadow disc, mean over 15 cases with D ≥ 2R:
THESIS 187 (median 1.1), PHYSICAL 0.87, FITTED 0.50, EXACT_PROFILE 0.024).

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

The reference irradiance of a light (for the brightness cut-off): a cone's
on-axis irradiance at ``|1/V|`` beyond its apex (for PHYSICAL ``T(0)`` times the
primary's irradiance at the lens), a beam's at ``L_ref``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

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


# --------------------------------------------------------------------------- inputs

@dataclass(frozen=True)
class PrimaryLight:
    """What the energy models need of the primary (point) light."""
    power_w: float                   # Blender energy (× 2^exposure), W
    radius: float = 0.0              # shadow_soft_size
    color: tuple[float, float, float] = (1.0, 1.0, 1.0)

    @property
    def intensity(self) -> float:
        """Radiant intensity, W/sr: ``P/(4π)`` (SPEC §9)."""
        return self.power_w / (4.0 * math.pi)


@dataclass(frozen=True)
class LensOptics:
    """What the material adds to the sphere's geometry (see `material_model`)."""
    transmission_weight: float = 1.0                       # w (Principled's Transmission Weight …)
    tint: tuple[float, float, float] = (1.0, 1.0, 1.0)     # colour of a path through the sphere
    absorption: tuple[float, float, float] = (0.0, 0.0, 0.0)  # σ per unit length (Volume Absorption)


def head_on_transmission(ior: float) -> float:
    """Fresnel transmission through both surfaces at normal incidence:
    ``T(0) = (4n/(n + 1)²)²`` (0.9216 for n = 1.5)."""
    t = 4.0 * ior / (ior + 1.0) ** 2
    return t * t


# --------------------------------------------------------------------------- models

class EnergyModel(Protocol):
    name: str
    label: str
    description: str

    def cone_intensity(self, source, primary: PrimaryLight, optics: LensOptics) -> float:
        """On-axis radiant intensity (W/sr) of a cone seen from its apex."""

    def beam_irradiance(self, source, primary: PrimaryLight, optics: LensOptics,
                        reference_distance: float) -> float:
        """On-axis irradiance (W/length²) of a collimated beam, at
        `reference_distance` beyond the back vertex (on a plane across the beam)."""

    def color(self, source, primary: PrimaryLight,
              optics: LensOptics) -> tuple[float, float, float]:
        """Colour of the Blender light (0–1 per channel)."""


@dataclass(frozen=True)
class ThesisModel:
    name: str = "THESIS"
    label: str = "Thesis"
    description: str = ("Eq. 5.22: the primary's power × the absorption factor, "
                        "no concentration of flux")

    def cone_intensity(self, source, primary, optics):
        return primary.intensity * source.brightness_factor

    def beam_irradiance(self, source, primary, optics, reference_distance):
        # The thesis uses the cylinder like a point light at the back vertex.
        return primary.intensity * source.brightness_factor / reference_distance ** 2

    def color(self, source, primary, optics):
        return tuple(float(c) for c in primary.color)


@dataclass(frozen=True)
class PhysicalModel:
    name: str = "PHYSICAL"
    label: str = "Physical"
    description: str = ("Flux-conserving: on-axis intensity I0·T(0)·m², "
                        "tint and absorption of the glass")

    def _throughput(self, source, optics):
        w = min(max(optics.transmission_weight, 0.0), 1.0)
        return head_on_transmission(source.ior) * w * w

    def cone_intensity(self, source, primary, optics):
        m = source.magnification
        return primary.intensity * self._throughput(source, optics) * m * m

    def beam_irradiance(self, source, primary, optics, reference_distance):
        # Paraxial rays leave parallel: dA = D² dΩ, so E = I0 T(0) / D²
        # (the limit of I0 T(0) m² / z² at the image's distance z = 1/V).
        return primary.intensity * self._throughput(source, optics) / source.distance ** 2

    def color(self, source, primary, optics):
        chord = 2.0 * source.lens_radius
        out = []
        for c, t, a in zip(primary.color, optics.tint, optics.absorption):
            t = min(max(float(t), 0.0), 1.0)
            out.append(float(c) * t * math.exp(-max(float(a), 0.0) * chord))
        return tuple(out)


@dataclass(frozen=True)
class TierModel:
    """Registry entry of a tier made by :mod:`.lens_tiers` (FITTED, EXACT_PROFILE):
    a name, a label, a description and the engines that render it;
    :func:`make_blender_light` hands such a tier to
    :func:`.lens_tiers.make_tier_light`."""
    name: str
    label: str
    description: str
    engines: tuple[str, ...] = ("CYCLES", "BLENDER_EEVEE")


THESIS, PHYSICAL, FITTED, EXACT_PROFILE = "THESIS", "PHYSICAL", "FITTED", "EXACT_PROFILE"
#: Not a tier: the most accurate tier for the render engine (`resolve_energy_model`).
AUTO = "AUTO"
AUTO_LABEL = "Auto — most accurate for the engine"
AUTO_DESCRIPTION = ("Exact profile in Cycles, Fitted in EEVEE (and any other engine): "
                    "the most accurate tier the engine renders")

ENERGY_MODELS: dict[str, EnergyModel] = {}


def register_energy_model(model: EnergyModel) -> None:
    """Make a model available under `model.name`."""
    ENERGY_MODELS[model.name] = model


register_energy_model(ThesisModel())
register_energy_model(PhysicalModel())
register_energy_model(TierModel(
    FITTED, "Fitted",
    "One spot fitted to the exact beam: EEVEE and Cycles; its own cone and blend "
    "(relative L1 error 0.50 for D ≥ 2R)"))
register_energy_model(TierModel(
    EXACT_PROFILE, "Exact profile (Cycles)",
    "The exact beam tabulated over angle and distance in a light node tree: Cycles only, "
    "EEVEE gets Fitted lights instead (relative L1 error 0.024 for D ≥ 2R)",
    engines=("CYCLES",)))
#: The generator's default setting (`properties`): the best tier for the engine.
DEFAULT_ENERGY_MODEL = AUTO


#: Fixed enum numbers: a .blend stores an enum setting as its number, and files
#: saved when the items were THESIS (0) and PHYSICAL (1) must keep their choice.
ENUM_NUMBERS = {THESIS: 0, PHYSICAL: 1, FITTED: 2, EXACT_PROFILE: 3, AUTO: 4}


def energy_model_items(include_auto: bool = False) -> list[tuple[str, str, str, int]]:
    """(identifier, label, description, number) for an enum property: the tiers,
    and with `include_auto` first the AUTO choice."""
    items = [(m.name, m.label, m.description,
              ENUM_NUMBERS.get(m.name, 100 + k)) for k, m in enumerate(ENERGY_MODELS.values())]
    auto = [(AUTO, AUTO_LABEL, AUTO_DESCRIPTION, ENUM_NUMBERS[AUTO])] if include_auto else []
    return auto + items


def resolve_energy_model(model: str, engine: str | None = None) -> tuple[str, str]:
    """The tier to build for the setting `model` with the render engine `engine`
    (`scene.render.engine`; None: not known), and a warning ("" if none).

    AUTO: EXACT_PROFILE in Cycles, FITTED otherwise (also without an engine: the
    most accurate tier that renders in both). EXACT_PROFILE with an engine other
    than Cycles: FITTED, with a warning (light node trees are Cycles only)."""
    engine = (engine or "").upper()
    if model == AUTO:
        return (EXACT_PROFILE if engine == "CYCLES" else FITTED), ""
    if model == EXACT_PROFILE and engine and engine != "CYCLES":
        shown = {"BLENDER_EEVEE": "EEVEE", "BLENDER_EEVEE_NEXT": "EEVEE",
                 "BLENDER_WORKBENCH": "Workbench"}.get(engine, engine)
        return FITTED, (f"Exact profile needs Cycles (light node trees); the engine is "
                        f"{shown}: made Fitted lights instead")
    return model, ""


# --------------------------------------------------------------------------- output

@dataclass
class BlenderLight:
    """One Blender light object, in world space."""
    type: str                          # "SPOT"
    energy_w: float                    # Light.energy
    spot_size_deg: float               # Light.spot_size (full angle, within 1°–180°)
    spot_blend: float                  # Light.spot_blend
    radius: float                      # Light.shadow_soft_size
    location: tuple[float, float, float]
    direction: tuple[float, float, float]   # unit; the light's local −Z
    note: str = ""                     # what was approximated, for people
    color: tuple[float, float, float] = (1.0, 1.0, 1.0)
    scale_xy: float = 1.0              # object scale in local x, y (narrows the cone)
    cone_half_angle_deg: float = 0.0   # the cone actually made (after scale_xy)
    cutoff_distance: float = 0.0       # EEVEE custom influence distance
    kind: str = ""                     # "real" | "virtual" | "collimated"
    model: str = ""
    reference_irradiance: float = 0.0  # W/length², on the axis at the reference distance
    relative_brightness: float = 0.0   # reference irradiance / primary's irradiance at the lens

    def to_json(self) -> dict:
        return {"type": self.type, "energy_w": self.energy_w,
                "spot_size_deg": self.spot_size_deg, "spot_blend": self.spot_blend,
                "radius": self.radius}


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
        return ConeShape(SPOT_SIZE_MAX_DEG, 1.0, 90.0,
                         f"cone {full:.4g}° clamped to Blender's maximum 180°")
    if full >= SPOT_SIZE_MIN_DEG:
        return ConeShape(full, 1.0, theta, note)
    k = math.tan(math.radians(theta)) / math.tan(math.radians(0.5 * SPOT_SIZE_MIN_DEG))
    extra = f"cone {full:.3g}° < 1°: spot_size 1°, narrowed by object scale {k:.4g}"
    return ConeShape(SPOT_SIZE_MIN_DEG, k, theta, f"{note}; {extra}" if note else extra)


def _vec(v) -> tuple[float, float, float]:
    return tuple(float(x) for x in v)


def _downstream_reach(origin, axis, scene_bounds, fallback):
    """How far the scene reaches beyond `origin` along `axis` (the largest
    `(corner − origin)·axis` over the bounding box, may be negative); `fallback`
    without bounds."""
    if scene_bounds is None:
        return fallback
    lo, hi = ([float(x) for x in b] for b in scene_bounds)
    return sum(max((l - o) * a, (h - o) * a) for l, h, o, a in zip(lo, hi, origin, axis))


def make_blender_light(source, primary: PrimaryLight, model: str = DEFAULT_ENERGY_MODEL,
                       *, optics: LensOptics | None = None,
                       spot_blend: float = DEFAULT_SPOT_BLEND,
                       scene_size: float = 1.0,
                       scene_bounds=None,
                       collimated_distance: float | None = None) -> BlenderLight:
    """The Blender light for one `phase1.SecondarySource`.

    `primary`: the primary light's power (W), radius and colour. `model`: a key of
    `ENERGY_MODELS` (FITTED and EXACT_PROFILE are made by
    `lens_tiers.make_tier_light`, which ignores `spot_blend` and `scene_bounds`) or
    AUTO (without an engine: FITTED; see `resolve_energy_model`). `optics`: the lens material's transmission weight, tint and
    absorption (default: clear glass, weight 1). `scene_size`: the size (diagonal)
    of everything the light may reach; `scene_bounds`: its bounding box (lo, hi),
    if known. `collimated_distance`: how far behind the back vertex a beam's spot
    may go (default `COLLIMATED_DISTANCE_FACTOR × scene_size`; the caller lowers it
    when geometry behind the lens would block the spot). A non-full source's
    energy is scaled by `source.unblocked_fraction`.

    Which representation (`BlenderLight.note` says):

    * **cone** — a spot at the image point (real or virtual) with half-angle θ;
    * **beam** — the far-away spot of the module's docstring, for a collimated
      source, for a real image beyond everything in the scene (the whole scene lies
      in the converging part of the beam, which a spot at the image cannot light:
      e.g. a marble resting on a table under a high lamp focuses below the table),
      and for a virtual image farther behind than the beam's spot would be. Its
      footprint at the back vertex is the beam's (``tan θ·|1/V − R|``, ``R_C`` when
      collimated) and its irradiance at the reference distance (half the scene's
      reach beyond the back vertex) the model's: ``I/(1/V − z)²`` for an image at
      ``1/V``, the beam irradiance when collimated — so it is continuous across
      the switch to collimated.
    """
    if model == AUTO:
        model = resolve_energy_model(model)[0]
    try:
        energy_model = ENERGY_MODELS[model]
    except KeyError:
        raise ValueError(f"unknown energy model {model!r}; "
                         f"known: {', '.join([AUTO, *ENERGY_MODELS])}") from None
    scene_size = float(scene_size) if scene_size and math.isfinite(scene_size) and scene_size > 0 else 1.0
    if isinstance(energy_model, TierModel):
        from . import lens_tiers        # it imports this module
        # A fitted spot stays within the beams' distance behind the lens.
        return lens_tiers.make_tier_light(
            source, primary, model, optics=optics, scene_size=scene_size,
            collimated_distance=collimated_distance or COLLIMATED_DISTANCE_FACTOR * scene_size)
    optics = optics or LensOptics()
    axis = [float(x) for x in source.axis]
    norm = math.sqrt(sum(x * x for x in axis))
    axis = [x / norm for x in axis]
    position = [float(x) for x in source.position]
    center = [float(x) for x in source.lens_center]
    radius_lens = float(source.lens_radius)
    unblocked = min(max(float(source.unblocked_fraction), 0.0), 1.0)
    color = energy_model.color(source, primary, optics)
    notes = []
    primary_irradiance = primary.intensity / source.distance ** 2   # at the lens centre
    s_far = float(collimated_distance) if collimated_distance else COLLIMATED_DISTANCE_FACTOR * scene_size
    s_far = max(s_far, 1e-6 * scene_size)
    back_vertex = [c + radius_lens * a for c, a in zip(center, axis)]

    if source.kind == "collimated":
        beam = True
    else:
        z_img = float(source.image_distance)             # signed, from the centre
        if source.kind == "real":
            beyond = _downstream_reach(position, axis, scene_bounds,
                                       scene_size - (z_img - radius_lens)) <= 0.0
            beam = beyond
            why = "real image beyond the scene"
        else:
            beam = abs(z_img) > s_far
            why = "virtual image far behind"

    if beam:
        # Reference: half-way along the scene's reach beyond the back vertex.
        reach = _downstream_reach(back_vertex, axis, scene_bounds, scene_size)
        l_ref = 0.5 * min(max(reach, 0.0), scene_size) if scene_bounds is not None else 0.5 * scene_size
        if source.kind == "collimated":
            width = float(source.cylinder_radius or 0.0)
            irradiance = energy_model.beam_irradiance(source, primary, optics, max(l_ref, 1e-9 * scene_size))
            notes.append(f"collimated beam R_C={width:.4g}")
            light_radius = primary.radius / source.distance      # divergence r/D, × s below
        else:
            width = math.tan(math.radians(source.spread_deg)) * abs(z_img - radius_lens)
            irradiance = (energy_model.cone_intensity(source, primary, optics)
                          / (z_img - (radius_lens + l_ref)) ** 2)
            notes.append(f"{why}: beam of radius {width:.4g}")
            light_radius = abs(source.magnification) * primary.radius / abs(z_img)
        irradiance *= unblocked
        shape = cone_shape(math.degrees(math.atan2(width, s_far)))
        intensity = irradiance * (s_far + l_ref) ** 2
        location = [p - s_far * a for p, a in zip(back_vertex, axis)]
        radius = s_far * light_radius
        reach_total = s_far + scene_size
        notes.append(f"spot {s_far:.4g} behind the back vertex")
    else:
        shape = cone_shape(source.spread_deg)
        intensity = energy_model.cone_intensity(source, primary, optics) * unblocked
        z_ref = abs(z_img)
        irradiance = intensity / z_ref ** 2 if z_ref > 0 else math.inf
        location = position
        radius = abs(source.magnification) * primary.radius
        reach_total = math.dist(position, center) + scene_size
    if shape.note:
        notes.append(shape.note)
    if not source.full:
        notes.append(f"non-full: energy × {unblocked:.4g} (unblocked share of the lit cap)")

    energy = 4.0 * math.pi * intensity
    return BlenderLight(
        type=SPOT, energy_w=float(energy), spot_size_deg=float(shape.spot_size_deg),
        spot_blend=float(min(max(spot_blend, 0.0), 1.0)), radius=float(radius),
        location=_vec(location), direction=_vec(axis), note="; ".join(notes),
        color=color, scale_xy=float(shape.scale_xy),
        cone_half_angle_deg=float(shape.half_angle_deg),
        cutoff_distance=float(CUTOFF_FACTOR * reach_total), kind=source.kind, model=model,
        reference_irradiance=float(irradiance),
        relative_brightness=float(irradiance / primary_irradiance) if primary_irradiance > 0 else 0.0,
    )


# --------------------------------------------------------------------------- planning

@dataclass
class PlannedLight:
    source: object                     # phase1.SecondarySource
    light: BlenderLight
    light_name: str
    lens_name: str


@dataclass
class Plan:
    lights: list[PlannedLight]
    #: (primary light's name, lens's name, reason) of every pair without a light,
    #: lenses only (a pair whose sphere is no lens, e.g. opaque, is not listed).
    skipped: list[tuple[str, str, str]]
    not_lenses: int = 0                # pairs whose sphere is no lens (not reported)

    def skipped_summary(self, first: int = 3) -> str:
        """'A × B: reason; …' for the first few skipped pairs (and how many more)."""
        parts = [f"{a} × {b}: {why}" for a, b, why in self.skipped[:first]]
        more = len(self.skipped) - first
        if more > 0:
            parts.append(f"and {more} more")
        return "; ".join(parts)


def plan_lights(result, primaries, model: str = DEFAULT_ENERGY_MODEL, *,
                optics=None, light_names=None, lens_names=None, lens_candidates=None,
                min_brightness: float = 0.0, max_lights: int | None = None,
                spot_blend: float = DEFAULT_SPOT_BLEND, scene_size: float = 1.0,
                scene_bounds=None, far_limit=None, energy_scale=None) -> Plan:
    """The Blender lights for a phase-1 result, brightest first.

    `primaries[j]`: `PrimaryLight` of light j; `optics[i]`: `LensOptics` of sphere i
    (default clear glass); names for the report (default "light j", "sphere i");
    `lens_candidates[i]`: False for spheres that are no lens (their skipped pairs are
    counted in `not_lenses`, not listed). A light whose relative brightness (its
    reference irradiance over the primary's irradiance at the lens) is below
    `min_brightness` is skipped, and so is every light beyond the `max_lights`
    brightest (by reference irradiance). `scene_bounds`: see `make_blender_light`;
    `far_limit(source)`: how far behind the lens a beam's spot may go (None: as far
    as the default), e.g. up to the first geometry behind the lens.
    `energy_scale[t]` (parallel to `result.sources`): a factor on the energy of
    source t's light, applied before the cut-off and the cap (a merged source
    carries the flux of its group: `addon.budget.apply_budget`).
    """
    light_name = (lambda j: light_names[j]) if light_names else (lambda j: f"light {j}")
    lens_name = (lambda i: lens_names[i]) if lens_names else (lambda i: f"sphere {i}")
    plan = Plan(lights=[], skipped=[])
    for k in result.skipped:
        if lens_candidates is not None and not lens_candidates[k.lens]:
            plan.not_lenses += 1
        else:
            plan.skipped.append((light_name(k.light), lens_name(k.lens), k.reason))
    candidates = []
    for t, src in enumerate(result.sources):
        limit = far_limit(src) if far_limit is not None else None
        bl = make_blender_light(src, primaries[src.light], model,
                                optics=optics[src.lens] if optics else None,
                                spot_blend=spot_blend, scene_size=scene_size,
                                scene_bounds=scene_bounds, collimated_distance=limit)
        f = 1.0 if energy_scale is None else float(energy_scale[t])
        if f != 1.0:
            bl.energy_w *= f
            bl.reference_irradiance *= f
            bl.relative_brightness *= f
            bl.note = "; ".join(x for x in (bl.note, f"merged: energy × {f:.4g}") if x)
        names = (light_name(src.light), lens_name(src.lens))
        if not (bl.energy_w > 0 and math.isfinite(bl.energy_w)):
            plan.skipped.append((*names, "no light gets through"))
        elif bl.relative_brightness < min_brightness:
            plan.skipped.append((*names, f"dimmer than the cut-off "
                                         f"({bl.relative_brightness:.3g} < {min_brightness:g})"))
        else:
            candidates.append(PlannedLight(src, bl, *names))
    candidates.sort(key=lambda p: -p.light.reference_irradiance)
    limit = len(candidates) if max_lights is None else max(int(max_lights), 0)
    plan.lights = candidates[:limit]
    for p in candidates[limit:]:
        plan.skipped.append((p.light_name, p.lens_name,
                             f"beyond the maximum of {limit} lens lights"))
    return plan
