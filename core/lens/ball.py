"""The ball lens: a glass sphere, traced exactly (SPEC §4.3 intersection, §6 optics)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from .ball_optics import two_surface_transmission
from .base import ExitRays, Lens
from .refraction import fresnel_from_cosines, refract
from .sphere import intersect_sphere


@dataclass(frozen=True, eq=False)  # array fields: compare by identity
class BallLens(Lens):
    """Sphere of ``radius`` at ``center``, relative index ``ior``, Beer–Lambert
    ``absorption`` per unit length. Fields may be arrays ((…, 3) and (…)) that broadcast
    against the rays: many balls traced in one call."""

    center: np.ndarray
    radius: float | np.ndarray
    ior: float | np.ndarray
    absorption: float | np.ndarray = 0.0

    point_image: ClassVar[bool] = True

    def bounding_sphere(self):
        return np.asarray(self.center, dtype=float), np.asarray(self.radius, dtype=float)

    def intersect(self, origins, directions):
        c, r = self.bounding_sphere()
        h = intersect_sphere(origins, directions, c, r)
        t = np.where(h.near > 0.0, h.near, h.far)
        t = np.where(h.hit & (t > 0.0), t, np.inf)
        p = origins + np.where(np.isfinite(t), t, 0.0)[..., None] * directions
        nrm = np.where(np.isfinite(t)[..., None], (p - c) / r[..., None], 0.0)
        return t, nrm

    def trace(self, origins, directions, aimed: bool = False) -> ExitRays:
        """Entry at the near root, the chord to the far root from the entry point (the
        discriminant clamped at 0: a ray missing by rounding, within 1e-12 R², goes in at
        the tangent point; every ray ahead of the ball when ``aimed``, as the tracers'
        grids' rim rays must, whatever the rounding of their frames);
        Fresnel from the actual 3-D cosines at both surfaces, s and p separately (both
        planes of incidence hold the centre and the ray)."""
        c, radius = self.bounding_sphere()
        ior = np.asarray(self.ior, dtype=float)
        r3 = radius[..., None]
        entry = intersect_sphere(origins, directions, c, radius)
        grazing = True if aimed else entry.disc >= -1e-12 * radius * radius
        hit = grazing & (entry.far > 0.0)
        p1 = origins + entry.near[..., None] * directions
        inner = refract(directions, (p1 - c) / r3, 1.0 / ior)
        chord = intersect_sphere(p1, inner.directions, c, radius).far
        p2 = p1 + chord[..., None] * inner.directions
        outer = refract(inner.directions, -(p2 - c) / r3, ior)
        ts1, tp1 = fresnel_from_cosines(inner.cos_i, inner.cos_t, 1.0, ior)
        ts2, tp2 = fresnel_from_cosines(outer.cos_i, outer.cos_t, ior, 1.0)
        w = 0.5 * (ts1 * ts2 + tp1 * tp2) * np.exp(-self.absorption * chord)
        w = np.where(inner.tir | outer.tir, 0.0, w)
        return ExitRays(
            points=np.where(hit[..., None], p2, origins),
            directions=np.where(hit[..., None], outer.directions, directions),
            weight=np.where(hit, w, 1.0),
            hit=hit,
            path=np.where(hit, chord, 0.0),
        )

    def incidence_transmission(self, iota):
        """``T(ι) · exp(−a · 2R cos r)`` (SPEC §6): two-surface Fresnel of the isosceles
        chord (the exit's transmittances equal the entry's by reciprocity)."""
        iota = np.asarray(iota, dtype=float)
        ior = np.asarray(self.ior, dtype=float)
        cos_r = np.sqrt(np.maximum(1.0 - (np.sin(iota) / ior) ** 2, 0.0))
        fres = two_surface_transmission(iota, ior)
        return fres * np.exp(-self.absorption * 2.0 * np.asarray(self.radius) * cos_r)

    @classmethod
    def stack(cls, lenses, counts, extra_dims: int = 0):
        ones = (1,) * extra_dims

        def rep(values, tail=()):
            v = np.repeat(np.asarray(values, dtype=float), counts, axis=0)
            return v.reshape((-1, *ones, *tail))

        return cls(
            center=rep([np.asarray(ln.center, dtype=float).reshape(3) for ln in lenses], (3,)),
            radius=rep([ln.radius for ln in lenses]),
            ior=rep([ln.ior for ln in lenses]),
            absorption=rep([ln.absorption for ln in lenses]),
        )
