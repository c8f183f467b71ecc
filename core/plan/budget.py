"""Model only what a scene needs: contribution estimates, cut-off, cap, merging.

A scene of droplets or beads can yield tens of thousands of secondary sources; most
carry a negligible share of their light's power, and EEVEE slows down with every
light. Each source's contribution is estimated from the flux its lens catches:

    flux = P · Ω_fraction · brightness_factor · unblocked_fraction

with P the primary's power and Ω_fraction the share of an isotropic light's flux
that the lens's disc subtends (SPEC §4.2's cancellation-free form). The budget then

1. drops sources whose flux is below `min_flux_fraction` of their light's power,
2. optionally merges sources of the same light that nearly coincide (positions in
   the same cell of size `merge_distance`, axes within `merge_angle_deg`): one
   light carrying their summed flux at their flux-weighted mean position,
3. keeps at most `max_lights` sources, the strongest by flux.

The report says how many were dropped at each step, and how much flux that was.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..phase1.point_lights import SourceTable, take
from ..shared.words import share_text


def caught_fraction(radius, distance):
    """Share of an isotropic light's flux falling on a sphere: (1 − cos α)/2,
    written as (R/D)² / (2(1 + sqrt((1 − R/D)(1 + R/D)))) so it does not underflow."""
    x = np.asarray(radius, dtype=float) / np.asarray(distance, dtype=float)
    return x * x / (2.0 * (1.0 + np.sqrt((1.0 - x) * (1.0 + x))))


def source_flux(table: SourceTable, light_power) -> np.ndarray:
    """Estimated flux (W, or the light's brightness unit) each source carries."""
    power = np.asarray(light_power, dtype=float)[table.light]
    return (
        power
        * caught_fraction(table.lens_radius, table.distance)
        * table.brightness_factor
        * table.unblocked_fraction
        * table.emission
    )


@dataclass
class BudgetReport:
    total: int = 0
    below_cutoff: int = 0
    merged: int = 0  # sources absorbed into another (not lost: their flux stays)
    over_cap: int = 0
    kept: int = 0
    flux_total: float = 0.0
    flux_dropped: float = 0.0  # by the cut-off and the cap
    notes: list[str] = field(default_factory=list)

    def summary(self) -> str:
        parts = [f"{self.kept} of {self.total} lens lights kept"]
        if self.below_cutoff:
            parts.append(f"{self.below_cutoff} below the brightness cut-off")
        if self.merged:
            parts.append(f"{self.merged} merged into nearby ones")
        if self.over_cap:
            parts.append(f"{self.over_cap} over the maximum number")
        share = share_text(self.flux_dropped, self.flux_total)
        if share:
            parts.append(f"{share} of the lens flux left out")
        return "; ".join(parts)


def apply_budget(
    table: SourceTable,
    light_power,
    min_flux_fraction: float = 0.0,
    max_lights: int | None = None,
    merge_distance: float | None = None,
    merge_angle_deg: float = 5.0,
):
    """Returns (kept table, energy scale per kept source, BudgetReport).

    The energy scale is 1 except for merged sources, where it is the group's
    flux over its leading member's: the Blender side multiplies the energy of the
    light it builds from the (leading) source by it.
    """
    flux = source_flux(table, light_power)
    power = np.asarray(light_power, dtype=float)[table.light]
    report = BudgetReport(total=len(table), flux_total=float(flux.sum()))

    keep = flux >= min_flux_fraction * power
    report.below_cutoff = int((~keep).sum())
    report.flux_dropped += float(flux[~keep].sum())
    table, flux = take(table, np.flatnonzero(keep)), flux[keep]

    scale = np.ones(len(table))
    if merge_distance and len(table):
        table, merged_flux, report.merged = merge_nearby(
            table, flux, merge_distance, merge_angle_deg
        )
        lead_flux = source_flux(table, light_power)
        scale = np.where(lead_flux > 0, merged_flux / np.where(lead_flux > 0, lead_flux, 1.0), 1.0)
        flux = merged_flux

    if max_lights is not None and len(table) > max_lights:
        order = np.argsort(-flux, kind="stable")
        chosen = np.sort(order[: max(max_lights, 0)])
        report.over_cap = len(table) - chosen.size
        report.flux_dropped += float(flux.sum() - flux[chosen].sum())
        table, flux, scale = take(table, chosen), flux[chosen], scale[chosen]
    report.kept = len(table)
    return table, scale, report


def merge_nearby(table: SourceTable, flux: np.ndarray, distance: float, angle_deg: float):
    """Merge sources of one light in the same position cell with nearly equal axes.

    Cells of size `distance` (so sources up to √3·distance apart can merge, and
    two close ones straddling a cell face do not: a cheap, documented rule). The
    merged source takes the flux-weighted mean position and axis, the summed
    intensity, the widest spread, and the strongest member's other data; returns
    (merged table, summed flux per merged source, number of sources absorbed).
    """
    cell = np.floor(table.position / distance).astype(np.int64)
    # Axis bucket: the axis direction quantised to the angle tolerance.
    axis_bin = np.round(table.axis / np.radians(angle_deg)).astype(np.int64)
    key = np.column_stack([table.light, cell, axis_bin])
    _, group, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    group = group.ravel()
    if counts.max(initial=1) == 1:
        return table, flux, 0
    n_groups = counts.size
    weight = np.zeros(n_groups)
    np.add.at(weight, group, flux)
    w = flux / np.where(weight[group] > 0, weight[group], 1.0)
    # The strongest member of each group carries the non-summed columns.
    order = np.lexsort((-flux, group))
    lead = order[np.r_[True, group[order][1:] != group[order][:-1]]]
    merged = take(table, lead)
    pos = np.zeros((n_groups, 3))
    axis = np.zeros((n_groups, 3))
    np.add.at(pos, group, w[:, None] * table.position)
    np.add.at(axis, group, flux[:, None] * table.axis)
    norm = np.linalg.norm(axis, axis=1, keepdims=True)
    lead_group = group[lead]
    merged.position = pos[lead_group]
    merged.axis = np.where(norm > 0, axis / np.where(norm > 0, norm, 1.0), table.axis[lead])[
        lead_group
    ]
    intensity = np.zeros(n_groups)
    np.add.at(intensity, group, table.intensity)
    merged.intensity = intensity[lead_group]
    spread = np.zeros(n_groups)
    np.maximum.at(spread, group, table.spread)
    merged.spread = spread[lead_group]
    return merged, weight[lead_group], len(table) - n_groups
