"""Blender's lights (SPEC sections 9 and 10) as samplers of rays toward a sphere.

Every emitter draws only rays that can reach the lens (a sphere of centre ``c`` and
radius ``R``): a point on the emitter, then a direction uniform within the cone from
that point to the sphere (or, for the sun, a point on the sphere's cross-section
disc).  Each ray carries the *single-sample estimate* of the flux: the flux the
emitter would send toward the lens if this ray were its only sample, so that the
mean over ``m`` rays estimates the flux and each ray's share is ``flux / m``.

Radiometry (W, m, sr; any length unit works):

- point, power P, radius r: r = 0 is isotropic, ``P / (4 pi)`` W/sr; r > 0 a sphere
  of uniform radiance ``P / (4 pi^2 r^2)``.  A ray from a surface point ``x`` with
  outward normal ``N`` toward the lens cone of solid angle ``Omega(x)`` carries
  ``L cos(N, d) * 4 pi r^2 * Omega(x) = (P / pi) cos(N, d) Omega(x)``.
- spot: the point light times Blender's mask of the emission direction.  With a
  radius it is the point light's uniform sphere times the mask (Cycles 4+ treats
  spot lights as spheres; seen from the lens, SPEC 10's "uniform disc").
- sun, strength S, angular diameter a: uniform radiance within the cone of half-angle
  ``h = a/2``, scaled so that a plane facing the sun receives S:
  ``L = S / (pi sin^2 h)``.  The sphere catches ``L Omega pi R^2 = S pi R^2 * 2/(1 + cos h)``.
- area, power P: Lambertian from its -Z side, radiance ``P / (pi A)``; a ray carries
  ``(P / pi) cos(theta) Omega(x)``.  Cycles' ``spread`` is not modelled (the default,
  180 degrees, is the Lambertian emitter).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .vectors import cone_one_minus_cos, dot, frame, sample_cone, unit

__all__ = [
    "RayBatch",
    "PointLight",
    "SpotLight",
    "SunLight",
    "AreaLight",
    "spot_mask",
    "smoothstep",
]


@dataclass(frozen=True)
class RayBatch:
    """Rays toward the lens: ``origin`` and unit ``direction`` ``(m, 3)``, ``flux``
    ``(m,)`` the single-sample flux estimates (W; 0 for a ray the emitter does not
    send), ``t_min`` where each ray's free path starts (0, or ``-inf`` for a sun:
    nothing upstream of the scene blocks its light except the blockers)."""

    origin: np.ndarray
    direction: np.ndarray
    flux: np.ndarray
    t_min: float = 0.0


def smoothstep(f):
    """0 for f <= 0, 1 for f >= 1, ``3 f^2 - 2 f^3`` between."""
    f = np.clip(np.asarray(f, dtype=float), 0.0, 1.0)
    return f * f * (3.0 - 2.0 * f)


def spot_mask(cos_gamma, spot_size, blend):
    """Blender's spot mask (SPEC 10) for emission directions at cosine ``cos_gamma``
    to the spot's axis: 0 outside the half-angle ``spot_size / 2``, a smoothstep over
    the band of width ``blend * (1 - cos(spot_size / 2))`` in the cosine inside it,
    1 beyond the band; ``blend = 0`` is a hard edge."""
    c = np.asarray(cos_gamma, dtype=float)
    one_minus_cos_h = 2.0 * math.sin(0.25 * spot_size) ** 2
    cos_h = 1.0 - one_minus_cos_h
    width = one_minus_cos_h * blend
    if width <= 0.0:
        return np.where(c > cos_h, 1.0, 0.0)
    return smoothstep((c - cos_h) / width)


def _toward_sphere(points, normals, center, radius, rng, power):
    """Rays from surface points of an emitter of power ``power`` whose radiance is
    ``P / (pi * area)`` (outward normals ``normals``; ``None``: a point, isotropic)
    into the cones toward the sphere, with their single-sample flux."""
    m = points.shape[0]
    to_c = center - points
    dist = np.linalg.norm(to_c, axis=1)
    w = to_c / dist[:, None]
    omc = cone_one_minus_cos(dist, radius)
    d = sample_cone(w, omc, rng.random(m), rng.random(m))
    omega = 2.0 * np.pi * omc
    if normals is None:
        return d, power / (4.0 * np.pi) * omega
    cos_e = np.maximum(dot(d, normals), 0.0)
    return d, power / np.pi * cos_e * omega


def _check_outside(position, radius, center, lens_radius):
    gap = float(np.linalg.norm(np.asarray(position, float) - center)) - lens_radius - radius
    if not gap > 0.0:
        raise ValueError("the light must lie outside the lens (and not touch it)")


def _sphere_points(position, radius, m, rng):
    """Uniform points on a sphere and their outward normals."""
    z = 1.0 - 2.0 * rng.random(m)
    phi = 2.0 * np.pi * rng.random(m)
    s = np.sqrt(np.maximum(0.0, (1.0 - z) * (1.0 + z)))
    nrm = np.stack([s * np.cos(phi), s * np.sin(phi), z], axis=1)
    return np.asarray(position, float) + radius * nrm, nrm


@dataclass(frozen=True)
class PointLight:
    """Blender point light: ``power`` P (W), ``position``, ``radius`` r
    (``shadow_soft_size``)."""

    position: tuple
    power: float
    radius: float = 0.0

    def sample(self, center, lens_radius, m, rng) -> RayBatch:
        _check_outside(self.position, self.radius, center, lens_radius)
        if self.radius > 0.0:
            pts, nrm = _sphere_points(self.position, self.radius, m, rng)
        else:
            pts, nrm = np.tile(np.asarray(self.position, float), (m, 1)), None
        d, flux = _toward_sphere(pts, nrm, center, lens_radius, rng, self.power)
        return RayBatch(pts, d, flux)


@dataclass(frozen=True)
class SpotLight:
    """Blender spot light: a point light (``power``, ``position``, ``radius``) times
    the spot mask of ``spot_size`` (full cone angle, radians) and ``blend``,
    emitting around the unit ``direction`` (the light's local -Z)."""

    position: tuple
    direction: tuple
    power: float
    spot_size: float
    blend: float = 0.0
    radius: float = 0.0

    def sample(self, center, lens_radius, m, rng) -> RayBatch:
        rays = PointLight(self.position, self.power, self.radius).sample(
            center, lens_radius, m, rng
        )
        mask = spot_mask(rays.direction @ unit(self.direction), self.spot_size, self.blend)
        return RayBatch(rays.origin, rays.direction, rays.flux * mask)


@dataclass(frozen=True)
class SunLight:
    """Blender sun: ``strength`` S (W/m^2 on a plane facing it), unit ``direction``
    the light travels in (the sun's local -Z), ``angle`` its angular diameter
    (radians): directions uniform within the cone of half-angle ``angle / 2``."""

    direction: tuple
    strength: float
    angle: float = 0.0

    def sample(self, center, lens_radius, m, rng) -> RayBatch:
        half = 0.5 * self.angle
        omc = 2.0 * math.sin(0.5 * half) ** 2
        w = np.tile(unit(self.direction), (m, 1))
        u1, u2 = rng.random(m), rng.random(m)  # drawn even for angle 0 (same stream)
        d = sample_cone(w, omc, u1, u2) if omc > 0.0 else w
        rho = lens_radius * np.sqrt(rng.random(m))
        phi = 2.0 * np.pi * rng.random(m)
        s, t = frame(d)
        disc = (rho * np.cos(phi))[:, None] * s + (rho * np.sin(phi))[:, None] * t
        origin = np.asarray(center, float) + disc - 2.0 * lens_radius * d
        flux = self.strength * np.pi * lens_radius**2 * 2.0 / (1.0 + math.cos(half))
        return RayBatch(origin, d, np.full(m, flux), t_min=-np.inf)


@dataclass(frozen=True)
class AreaLight:
    """Blender area light: ``power`` P (W), ``position`` (centre), ``direction`` the
    unit normal it emits along (local -Z), ``x_axis`` its local X (made orthogonal
    to ``direction``), ``shape`` one of SQUARE, RECTANGLE, DISK, ELLIPSE, ``size_x``
    and ``size_y`` (edge lengths; diameters for DISK/ELLIPSE; SQUARE and DISK use
    ``size_x`` for both)."""

    position: tuple
    direction: tuple
    power: float
    size_x: float
    size_y: float | None = None
    shape: str = "SQUARE"
    x_axis: tuple = (1.0, 0.0, 0.0)

    def axes(self):
        nrm = unit(self.direction)
        x = np.asarray(self.x_axis, float)
        x = x - (x @ nrm) * nrm
        if np.linalg.norm(x) < 1e-9:
            x = frame(nrm)[0][0]
        x = unit(x)
        return x, np.cross(nrm, x), nrm

    def extent(self):
        sy = self.size_x if self.shape in ("SQUARE", "DISK") or self.size_y is None else self.size_y
        return self.size_x, sy

    def area(self):
        sx, sy = self.extent()
        return sx * sy * (0.25 * np.pi if self.shape in ("DISK", "ELLIPSE") else 1.0)

    def sample(self, center, lens_radius, m, rng) -> RayBatch:
        if self.shape not in ("SQUARE", "RECTANGLE", "DISK", "ELLIPSE"):
            raise ValueError(f"unknown area light shape {self.shape!r}")
        sx, sy = self.extent()
        u1, u2 = rng.random(m), rng.random(m)
        if self.shape in ("DISK", "ELLIPSE"):
            rho, phi = np.sqrt(u1), 2.0 * np.pi * u2
            a, b = 0.5 * sx * rho * np.cos(phi), 0.5 * sy * rho * np.sin(phi)
        else:
            a, b = (u1 - 0.5) * sx, (u2 - 0.5) * sy
        ex, ey, nrm = self.axes()
        pts = np.asarray(self.position, float) + a[:, None] * ex + b[:, None] * ey
        reach = np.linalg.norm(pts - center, axis=1) - lens_radius
        if np.any(reach <= 0.0):
            raise ValueError("the area light must lie outside the lens")
        d, flux = _toward_sphere(pts, np.tile(nrm, (m, 1)), center, lens_radius, rng, self.power)
        return RayBatch(pts, d, flux)
