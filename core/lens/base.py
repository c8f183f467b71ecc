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


@dataclass(frozen=True)
class BranchRays(ExitRays):
    """Every way a ray leaves the glass, internal reflections followed
    (:meth:`Lens.trace_branches`): the `ExitRays` fields with a leading branch axis
    (B, …), strongest branch first, padded with ``weight`` 0 (and ``hit`` False) where a
    ray has fewer than B. ``crossings`` (B, …): surface crossings on the branch's path
    (0: the ray missed; 1: reflected off the outside); ``signature`` (B, …) uint64: a hash
    of the path's events (reflected or transmitted, and the smooth face group crossed at
    each), equal on neighbouring rays that took the same path; ``exit_face`` (B, …): the
    triangle (or −1) it last left by. Per ray (…): ``absorbed`` inside the glass and
    ``dropped`` by the budget (depth, minimum weight) or lost through a crack, so that
    ``weight.sum(0) + absorbed + dropped == 1``; ``leaked`` (…) bool, None when the
    kind cannot leak: part of the ray was lost through a crack (a path inside the glass
    that met no surface)."""

    crossings: np.ndarray
    signature: np.ndarray
    exit_face: np.ndarray
    absorbed: np.ndarray
    dropped: np.ndarray
    leaked: np.ndarray | None = None


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

    def trace_branches(
        self, origins, directions, max_depth: int = 8, min_weight: float = 1e-3
    ) -> BranchRays:
        """All the paths out of the glass (:class:`BranchRays`): at each crossing both
        the transmitted and the reflected part, up to ``max_depth`` crossings per path,
        parts under ``min_weight`` of the ray's power dropped. The default: the one
        branch of :meth:`trace` (a ball's internal reflections are not followed; what
        the glass reflects or absorbs counts as dropped)."""
        r = self.trace(origins, directions, aimed=True)
        w = np.where(r.hit, r.weight, 1.0)
        face = np.full(w.shape, -1, dtype=np.int64)
        return BranchRays(
            points=r.points[None],
            directions=r.directions[None],
            weight=w[None],
            hit=r.hit[None],
            path=r.path[None],
            crossings=np.where(r.hit, 2, 0)[None],
            signature=np.where(r.hit, 1, 0).astype(np.uint64)[None],
            exit_face=face[None],
            absorbed=np.zeros(w.shape),
            dropped=1.0 - w,
        )

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
