"""What the tracers, the obstruction and the tiers ask of a lens: the `Lens` interface.

A kind of lens (a ball, later a slab, a plano-convex…) is one file with a subclass, and
one line in `kinds.LENS_KINDS`. Every kind's constructor takes
``(center, radius, ior, absorption, *params)`` (``radius``: its size; ``params``: what
else it needs), so a scene record names a kind and its numbers and nothing else changes.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import ClassVar

import numpy as np


@dataclass(frozen=True)
class ExitRays:
    """Rays (…) after the glass. ``points`` (…, 3): where each leaves it (the origin for
    a ray that misses); ``directions`` (…, 3): unit, after the last refraction;
    ``weight``: the share of the ray's power on this straight transmitted path (Fresnel
    at each crossing × absorption along the path; 0 where a crossing totally reflects);
    ``hit``: the ray met the glass (a miss goes on unchanged with weight 1); ``path``:
    length inside the glass."""

    points: np.ndarray
    directions: np.ndarray
    weight: np.ndarray
    hit: np.ndarray
    path: np.ndarray


class Lens(ABC):
    """A piece of glass in air. Vectorised: rays are (…, 3) arrays, unit directions."""

    #: Whether the beam from a point source has a point-like image, so that phase 1's
    #: paraxial secondary source (a lens light) applies; False: only the caustic layer.
    point_image: ClassVar[bool] = False

    @abstractmethod
    def bounding_sphere(self) -> tuple[np.ndarray, np.ndarray]:
        """(centre (…, 3), radius (…)): a sphere holding all the glass (the tracer's ray
        grids cover it, the obstruction tests against it)."""

    @abstractmethod
    def intersect(self, origins, directions) -> tuple[np.ndarray, np.ndarray]:
        """(distance (…), outward unit normal (…, 3)) of each ray's first hit ahead of
        its origin (from inside the glass too); ``inf`` (normal 0) where it misses."""

    @abstractmethod
    def trace(self, origins, directions, aimed: bool = False) -> ExitRays:
        """The rays through the glass along their straight transmitted path: refraction
        and Fresnel transmission at each crossing, absorption inside. Internally reflected
        light is dropped (not followed yet). ``aimed``: the rays were aimed at the glass
        (a tracer's grid over its lit disc, rim rays tangent by construction), so one
        that misses only by rounding enters at the tangent point."""

    def incidence_transmission(self, iota) -> np.ndarray | None:
        """The ``weight`` of :meth:`trace` as a function of the angle of incidence ``iota``
        on the bounding sphere alone, when the lens is symmetric enough for that (a ball);
        None (the default): the tracer traces the rays it needs."""
        return None

    @classmethod
    def stack(cls, lenses, counts, extra_dims: int = 0) -> Lens | None:
        """One lens of this kind holding ``lenses[k]`` repeated ``counts[k]`` times along
        a first axis (then ``extra_dims`` axes of 1), so that one call traces many lenses'
        rays at once; None (the default): trace lens by lens."""
        return None
