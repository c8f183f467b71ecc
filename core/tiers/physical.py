"""PHYSICAL: flux-conserving paraxial optics (SPEC §6), as a paraxial cone (or
beam, :mod:`.paraxial`). On-axis intensity ``I0 · T(0) · m²`` seen from the image
point, with the head-on Fresnel transmission of both surfaces
``T(0) = (4n/(n + 1)²)²``, the square of the material's transmission weight (it
applies at entry and at exit) and, in the colour, the tint of a path through the
sphere (`core.lens.glass`) and Beer–Lambert absorption over the axial chord ``2R``."""

from __future__ import annotations

import numpy as np

from ..lens.glass import head_on_transmission
from .base import CYCLES, EEVEE, Accuracy, Tier, glass_colors
from .paraxial import make_paraxial_light, paraxial_table

NAME = "PHYSICAL"


class PhysicalModel:
    def _throughput(self, source, optics):
        w = np.clip(optics.transmission_weight, 0.0, 1.0)
        return head_on_transmission(source.ior) * w * w

    def cone_intensity(self, source, primary, optics):
        m = source.magnification
        return primary.intensity * self._throughput(source, optics) * m * m

    def beam_irradiance(self, source, primary, optics, reference_distance):
        # Paraxial rays leave parallel: dA = D² dΩ, so E = I0 T(0) / D²
        # (the limit of I0 T(0) m² / z² at the image's distance z = 1/V).
        return primary.intensity * self._throughput(source, optics) / source.distance**2

    def color(self, source, primary, optics):
        return glass_colors(
            np.atleast_1d(source.lens_radius), primary.color, optics.tint, optics.absorption
        )


MODEL = PhysicalModel()


def make_light(source, primary, **kwargs):
    return make_paraxial_light(source, primary, MODEL, NAME, **kwargs)


def make_table(table, primaries, **kwargs):
    return paraxial_table(table, primaries, MODEL, NAME, **kwargs)


TIER = Tier(
    name=NAME,
    label="Physical",
    description="Flux-conserving: on-axis intensity I0·T(0)·m², tint and absorption of the glass",
    trades="Paraxial cone with the exact on-axis intensity; misses the halo and the near beam",
    engines=(EEVEE, CYCLES),
    accuracy=Accuracy(0.87, 1.02),
    number=1,
    make=make_light,
    make_table=make_table,
)
