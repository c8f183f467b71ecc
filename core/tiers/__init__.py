"""The energy models ("tiers"): a secondary light source → one Blender light.

May import core.shared, core.lens, core.scene and core.phase1.

One module per tier, each holding its maker, its description and its accuracy
figures (a :class:`.base.Tier`); this registry lists them (``TIERS``, the one
table the panel, the CLI and the README's table read) and resolves AUTO.

``THESIS``         :mod:`.thesis` — eq. 5.22, paraxial cone, no flux concentration
``PHYSICAL``       :mod:`.physical` — paraxial cone, exact on-axis intensity
``FITTED``         :mod:`.fitted` — one spot fitted to the exact beam (EEVEE, Cycles)
``EXACT_PROFILE``  :mod:`.exact_profile` — the exact beam in a light node tree (Cycles)
``CAUSTIC_LAYER``  :mod:`.caustic_layer` — the exact caustic as an emissive mesh (EEVEE, Cycles)

Shared pieces (inputs, the Blender light, the cone a spot can make) are in
:mod:`.base`; the cone/beam geometry of THESIS and PHYSICAL in :mod:`.paraxial`.

``AUTO`` (the panel's default) is not a tier: :func:`resolve_energy_model` turns it
into the most accurate tier the render engine can show (``AUTO_RESOLUTION``) —
``EXACT_PROFILE`` in Cycles, ``CAUSTIC_LAYER`` in EEVEE, ``FITTED`` otherwise — as
measured in reports/accuracy.md and reports/caustic_layer.md (each tier's ``accuracy``).
"""

from __future__ import annotations

from ..lens.glass import LensOptics, head_on_transmission
from ..scene.primaries import PrimaryLight
from . import caustic_layer, exact_profile, fitted, physical, thesis
from .base import (
    COLLIMATED_DISTANCE_FACTOR,
    CUTOFF_FACTOR,
    CYCLES,
    DEFAULT_SPOT_BLEND,
    EEVEE,
    ENGINE_NAMES,
    BlenderLight,
    LightTable,
    Primaries,
    Tier,
    cone_shape,
    effective_primary,
    safe_scene_size,
)

__all__ = [
    "TIERS",
    "builds_layer",
    "TIER_LINES",
    "THESIS",
    "PHYSICAL",
    "FITTED",
    "EXACT_PROFILE",
    "CAUSTIC_LAYER",
    "AUTO",
    "AUTO_LABEL",
    "AUTO_DESCRIPTION",
    "AUTO_RESOLUTION",
    "DEFAULT_ENERGY_MODEL",
    "ENUM_NUMBERS",
    "energy_model_items",
    "resolve_energy_model",
    "make_blender_light",
    "make_light_table",
    "LightTable",
    "Primaries",
    "BlenderLight",
    "LensOptics",
    "PrimaryLight",
    "Tier",
    "cone_shape",
    "head_on_transmission",
    "COLLIMATED_DISTANCE_FACTOR",
    "CUTOFF_FACTOR",
    "DEFAULT_SPOT_BLEND",
]

#: Every tier, in the order the setting lists them.
TIERS: dict[str, Tier] = {
    t.name: t
    for t in (thesis.TIER, physical.TIER, fitted.TIER, exact_profile.TIER, caustic_layer.TIER)
}
THESIS, PHYSICAL, FITTED, EXACT_PROFILE, CAUSTIC_LAYER = TIERS
#: One line per tier on what it trades (the panel).
TIER_LINES = {name: t.trades for name, t in TIERS.items()}

#: Not a tier: the most accurate tier for the render engine (`resolve_energy_model`).
AUTO = "AUTO"
AUTO_LABEL = "Auto — most accurate for the engine"
AUTO_DESCRIPTION = (
    "Exact profile in Cycles, Caustic layer in EEVEE, Fitted in any other "
    "engine: the most accurate tier the engine renders"
)
#: AUTO per engine; any other engine (or none known): ``None``'s.
AUTO_RESOLUTION = {
    CYCLES: EXACT_PROFILE,
    EEVEE: CAUSTIC_LAYER,
    "BLENDER_EEVEE_NEXT": CAUSTIC_LAYER,
    None: FITTED,
}
AUTO_NUMBER = 4
#: The generator's default setting (`properties`): the best tier for the engine.
DEFAULT_ENERGY_MODEL = AUTO

#: Fixed enum numbers: a .blend stores an enum setting as its number, and files
#: saved when the items were THESIS (0) and PHYSICAL (1) must keep their choice.
ENUM_NUMBERS = {**{name: t.number for name, t in TIERS.items()}, AUTO: AUTO_NUMBER}


def energy_model_items(include_auto: bool = False) -> list[tuple[str, str, str, int]]:
    """(identifier, label, description, number) for an enum property: the tiers,
    and with `include_auto` first the AUTO choice."""
    items = [(t.name, t.label, t.description, t.number) for t in TIERS.values()]
    auto = [(AUTO, AUTO_LABEL, AUTO_DESCRIPTION, AUTO_NUMBER)] if include_auto else []
    return auto + items


def resolve_energy_model(model: str, engine: str | None = None) -> tuple[str, str]:
    """The tier to build for the setting `model` with the render engine `engine`
    (`scene.render.engine`; None: not known), and a warning ("" if none).

    AUTO: ``AUTO_RESOLUTION`` (also without an engine: the most accurate tier
    that renders in both). A Cycles-only tier (EXACT_PROFILE: light node trees)
    with another engine: FITTED, with a warning."""
    engine = (engine or "").upper()
    if model == AUTO:
        return AUTO_RESOLUTION.get(engine, AUTO_RESOLUTION[None]), ""
    tier = TIERS.get(model)
    if tier is not None and tier.engines == (CYCLES,) and engine and engine != CYCLES:
        shown = ENGINE_NAMES.get(engine, engine)
        return FITTED, (
            f"{tier.short_label} needs Cycles (light node trees); the engine "
            f"is {shown}: made Fitted lights instead"
        )
    return model, ""


def make_blender_light(
    source,
    primary: PrimaryLight,
    model: str = DEFAULT_ENERGY_MODEL,
    *,
    optics: LensOptics | None = None,
    spot_blend: float = DEFAULT_SPOT_BLEND,
    scene_size: float = 1.0,
    scene_bounds=None,
    collimated_distance: float | None = None,
    receiver_distance: float | None = None,
) -> BlenderLight:
    """The Blender light for one `phase1.SecondarySource`.

    `primary`: the primary light's power (W), radius and colour. `model`: a key of
    `TIERS` or AUTO (without an engine: FITTED; see `resolve_energy_model`).
    `optics`: the lens material's transmission weight, tint and absorption
    (default: clear glass, weight 1). `scene_size`: the size (diagonal) of
    everything the light may reach; `scene_bounds`: its bounding box (lo, hi), if
    known. `collimated_distance`: how far behind the back vertex a spot may go
    (default `COLLIMATED_DISTANCE_FACTOR × scene_size`; the caller lowers it when
    geometry behind the lens would block the spot). A non-full source's energy is
    scaled by `source.unblocked_fraction`. FITTED and EXACT_PROFILE ignore
    `spot_blend` and `scene_bounds`. `receiver_distance`: how far from the lens
    centre along the axis the first surface behind the lens lies (None: unknown;
    `planning.receiver_distance`): no light is placed at or behind it, and the
    spot tiers aim at it (`tiers.near_field`). The source's `emission` and
    `source_radius` (primaries other than point lights) turn `primary` into the
    point light that stands for it toward this lens (`base.effective_primary`).
    """
    tier = _tier(model)
    scene_size = safe_scene_size(scene_size)
    primary = effective_primary(source, primary)
    return tier.make(
        source,
        primary,
        optics=optics,
        spot_blend=spot_blend,
        scene_size=scene_size,
        scene_bounds=scene_bounds,
        collimated_distance=collimated_distance,
        receiver_distance=receiver_distance,
    )


def make_light_table(
    table,
    primaries: Primaries,
    model: str = DEFAULT_ENERGY_MODEL,
    *,
    spot_blend: float = DEFAULT_SPOT_BLEND,
    scene_size: float = 1.0,
    scene_bounds=None,
    collimated_distance: float | None = None,
) -> LightTable:
    """`make_blender_light` for every source of a `phase1.SourceTable` at once, as
    columns (the tier's ``make_table``), with no receiver known: `primaries` per
    source (their effective primary from the table's ``emission`` and
    ``source_radius``, as `make_blender_light`); ``light(t)`` is source t's light."""
    tier = _tier(model)
    return tier.make_table(
        table,
        primaries.effective(table),
        spot_blend=spot_blend,
        scene_size=safe_scene_size(scene_size),
        scene_bounds=scene_bounds,
        collimated_distance=collimated_distance,
    )


def _tier(model: str) -> Tier:
    if model == AUTO:
        model = resolve_energy_model(model)[0]
    try:
        return TIERS[model]
    except KeyError:
        raise ValueError(
            f"unknown energy model {model!r}; known: {', '.join([AUTO, *TIERS])}"
        ) from None


def builds_layer(model: str) -> bool:
    """Does the (resolved) tier `model` build caustic layers instead of lights?"""
    return model == CAUSTIC_LAYER
