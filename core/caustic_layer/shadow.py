"""A source's shadow list in the caustic layer: the traced beam's rays that a blocker
stops get weight 0 (opaque) or its Fresnel share (glass), so the blocker's shadow is
drawn inside the caustic instead of the whole layer being dimmed.

The rays are the beam grid's node rays (`beam_trace`), from the source sample to the
lens; what the blockers pass of each is `core.phase1.shadow_mask.ray_passes` (0 through an
opaque sphere, kt² T(ι) through a glass one, undeflected: its focusing is a tertiary
source, out of scope). A cell gets the mean of its four corners (a soft edge one cell
wide). The emitter's power already carries phase 1's unblocked share (over the lens'
cap), so the weights are divided by it: the layer's flux becomes what passes.

The add-on hands every primary to the layer as a point light (a sun at its equivalent
distance, `caustic_layer.plan`); a sun given as parallel rays keeps the dimming (its rays start
just before the lens).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..phase1.shadow_mask import ray_passes


@dataclass(frozen=True)
class ShadowList:
    """The blockers of one source: centres (B, 3), radii (B,), indices and kt (B,) (glass
    where kt > 0), and the unblocked share the emitter's power already carries."""

    centers: np.ndarray
    radii: np.ndarray
    ior: np.ndarray
    kt: np.ndarray
    unblocked: float

    @classmethod
    def of(cls, source, arrays) -> ShadowList | None:
        """The shadow list of a phase-1 `SecondarySource` over the `SceneArrays` it
        indexes (None: a full source)."""
        if arrays is None:
            return None
        k = np.asarray(list(getattr(source, "shadow_list", ())), dtype=np.int64)
        if k.size == 0:
            return None
        return cls(
            np.asarray(arrays.center, dtype=float)[k],
            np.asarray(arrays.radius, dtype=float)[k],
            np.asarray(arrays.ior, dtype=float)[k],
            np.asarray(arrays.kt, dtype=float)[k],
            float(source.unblocked_fraction),
        )


def apply(cell, dens, origins, dirs, lens, blockers: ShadowList | None, parallel: bool):
    """``cell`` (K, Nr, Na) and ``dens`` (K, Nr+1, Na) weighed by what ``blockers`` pass
    of the node rays ``origins + t dirs`` (K, Nr+1, Na, 3) before the lens; unchanged
    without blockers or for parallel rays."""
    if blockers is None or parallel or not blockers.unblocked > 0.0:
        return cell, dens
    c = np.asarray(lens.center, dtype=float)
    t_end = np.einsum("...i,...i->...", c - origins, dirs)  # up to the lens' centre plane
    node = ray_passes(
        origins, dirs, t_end, blockers.centers, blockers.radii, blockers.ior, blockers.kt
    )
    node = node / blockers.unblocked
    corners = node[:, :-1, :] + node[:, 1:, :]
    per_cell = 0.25 * (corners + np.roll(corners, -1, axis=2))
    return cell * per_cell, dens * node
