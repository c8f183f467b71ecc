"""CAUSTIC_LAYER (EEVEE and Cycles): the lens' caustic as an emissive mesh on its
receivers (`core.caustic_layer`), not as a light.

Planning still needs a light per source to rank and cut sources by brightness, so
this maker returns the FITTED spot (`fitted.make_light`) marked with this tier. The
operator builds no light for it: it bakes the caustic layer of every planned
source in one call and keeps the spot only for receivers a layer cannot show
(glossy or transparent ones, where the caustic is not a diffuse radiance).
"""

from __future__ import annotations

import dataclasses

from . import fitted
from .base import CYCLES, EEVEE, Accuracy, BlenderLight, Tier

NAME = "CAUSTIC_LAYER"


def make_light(source, primary, **kwargs) -> BlenderLight:
    """The FITTED spot standing for the layer (ranking, cut-off, fallback)."""
    light = fitted.make_light(source, primary, **kwargs)
    light.model = NAME
    return light


def make_table(table, primaries, **kwargs):
    """:func:`make_light` for a whole source table: the FITTED spots, named for
    this tier (the layer itself needs receivers, which a table does not have)."""
    lights = fitted.make_table(table, primaries, **kwargs)
    return dataclasses.replace(lights, model=NAME)


#: reports/caustic_layer.md (relative L1 over the shadow disc against the exact
#: optics: floating ball 0.0085, near the focus 0.0105, resting marble 0.026).
ACCURACY = Accuracy(0.015, 0.026)
TIER = Tier(
    name=NAME,
    label="Caustic layer",
    description=(
        "The caustic traced exactly and shown as an emissive layer on the "
        f"receivers: EEVEE and Cycles (relative L1 error {ACCURACY.l1_mean:.3f}); "
        "glossy or transparent receivers get a Fitted spot"
    ),
    trades=(
        "Exact beam as an emissive mesh on diffuse receivers (sharp core, folds); "
        "a bake per frame, no light on glossy or transparent receivers"
    ),
    engines=(EEVEE, CYCLES),
    accuracy=ACCURACY,
    number=5,
    make=make_light,
    make_table=make_table,
)
