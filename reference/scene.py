"""The lens, the blockers and the receiving plane of the reference tracer."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .vectors import frame, unit

__all__ = ["GlassSphere", "Blocker", "ReceiverPlane"]


def _check_sphere(center, radius):
    if not (
        np.all(np.isfinite(np.asarray(center, float))) and np.isfinite(radius) and radius > 0.0
    ):
        raise ValueError(f"a sphere needs a finite centre and radius > 0, got {radius!r}")


@dataclass(frozen=True)
class GlassSphere:
    """The lens: ``center``, ``radius`` R, index ``ior`` n (relative to air) and the
    Beer-Lambert ``absorption`` coefficient (1/length) along the chord."""

    center: tuple
    radius: float
    ior: float
    absorption: float = 0.0

    def __post_init__(self):
        _check_sphere(self.center, self.radius)
        if not (np.isfinite(self.ior) and self.ior > 0.0):
            raise ValueError(f"index of refraction must be > 0, got {self.ior!r}")

    @property
    def c(self):
        return np.asarray(self.center, dtype=float)


@dataclass(frozen=True)
class Blocker:
    """A sphere between the light and the lens.  ``ior=None``: opaque.  Otherwise
    glass (index ``ior``, ``absorption``) that passes its two-surface Fresnel share
    times ``exp(-absorption * chord)`` *without deflecting the ray* (a stated
    simplification: a deflected ray may miss the lens, and rays aimed elsewhere may
    be bent into it, which a sampler aimed at the lens cannot see)."""

    center: tuple
    radius: float
    ior: float | None = None
    absorption: float = 0.0

    def __post_init__(self):
        _check_sphere(self.center, self.radius)

    @property
    def c(self):
        return np.asarray(self.center, dtype=float)


@dataclass(frozen=True)
class ReceiverPlane:
    """An infinite opaque plane through ``origin`` whose unit ``normal`` points to the
    side the light arrives on (its front).  Plane coordinates ``(u, v)``: along
    ``u_axis`` (made orthogonal to the normal) and ``normal x u_axis``, from
    ``origin``.  Light reaches it only from the front; the plane also blocks the
    light's path toward the lens if that path crosses it."""

    origin: tuple
    normal: tuple
    u_axis: tuple = (1.0, 0.0, 0.0)

    def axes(self):
        """``(e_u, e_v, normal)``, unit and right-handed."""
        nrm = unit(self.normal)
        u = np.asarray(self.u_axis, float)
        u = u - (u @ nrm) * nrm
        if np.linalg.norm(u) < 1e-9:
            u = frame(nrm)[0][0]
        u = unit(u)
        return u, np.cross(nrm, u), nrm

    def signed_distance(self, points):
        return (points - np.asarray(self.origin, float)) @ self.axes()[2]

    def to_plane(self, points):
        """``(u, v)`` coordinates of 3-D points (projected onto the plane)."""
        eu, ev, _ = self.axes()
        rel = points - np.asarray(self.origin, float)
        return rel @ eu, rel @ ev

    def to_world(self, u, v):
        eu, ev, _ = self.axes()
        u, v = np.asarray(u, float), np.asarray(v, float)
        return np.asarray(self.origin, float) + u[..., None] * eu + v[..., None] * ev
