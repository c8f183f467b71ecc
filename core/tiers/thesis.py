"""THESIS: the thesis' eq. 5.22. The secondary source is a paraxial cone (or
beam, :mod:`.paraxial`) of intensity ``I0 · exp(−(1 − kt)(2R + TR)/2)``
(``I0 = P/(4π)``) in the primary's colour: no concentration of flux."""

from __future__ import annotations

import numpy as np

from .base import CYCLES, EEVEE, Accuracy, Tier
from .paraxial import make_paraxial_light, paraxial_table

NAME = "THESIS"


class ThesisModel:
    def cone_intensity(self, source, primary, optics):
        return primary.intensity * source.brightness_factor

    def beam_irradiance(self, source, primary, optics, reference_distance):
        # The thesis uses the cylinder like a point light at the back vertex.
        return primary.intensity * source.brightness_factor / reference_distance**2

    def color(self, source, primary, optics):
        return np.array(primary.color, dtype=float).reshape(-1, 3)


MODEL = ThesisModel()


def make_light(source, primary, **kwargs):
    return make_paraxial_light(source, primary, MODEL, NAME, **kwargs)


def make_table(table, primaries, **kwargs):
    return paraxial_table(table, primaries, MODEL, NAME, **kwargs)


TIER = Tier(
    name=NAME,
    label="Thesis",
    description="Eq. 5.22: the primary's power × the absorption factor, no concentration of flux",
    trades="Thesis eq. 5.22: paraxial cone, no flux concentration; far off for distant lights",
    engines=(EEVEE, CYCLES),
    accuracy=Accuracy(187.0, 2243.0, l1_median=1.1),
    number=0,
    make=make_light,
    make_table=make_table,
)
