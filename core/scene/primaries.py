"""The primary lights: one plain dataclass per Blender light type, and what each
sends toward a lens (SPEC §10), vectorised over primaries × lenses.

The Blender side fills the dataclasses (one line per property, see each class);
:class:`PrimaryArrays` holds them as columns for phase 1
(:mod:`core.phase1.all_lights`), which turns every pair into a point-like source at
the primary's position (a sun: the limit ``D → ∞``) with two numbers per pair:

* ``emission``: the mean radiant intensity the primary sends over the lens's
  disc, in units of its nominal ``P/(4π)`` (a point light: 1; a spot: the share
  of the lens inside its cone, blend included; an area light ``4 cos θ`` far
  away, the exact form-factor integral near it; a sun: see ``SUN_DISTANCE``),
  times its IES profile's value toward the lens when its light nodes hold one
  (``profile``: `ies.LightProfile`);
* ``source_radius``: the radius of the disc the primary looks like from the
  lens (a sun's at the equivalent distance), which the tiers image to the lens
  light's blur (``tiers.base.lens_light_radius``).

Blender's emission (SPEC §9, §10; Cycles ``kernel/light/*.h``): a point or spot
light of power ``P`` has the intensity ``P/(4π)``; a spot multiplies it by
``smoothstep((cos γ − cos H)/((1 − cos H)·blend))``, ``H = spot_size/2``; a sun
gives the irradiance ``S`` on a plane facing it; an area light is a Lambertian
emitter on its local −Z side of radiance ``P/(π A)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .blender_spot import smoothstep01
from .ies import LightProfile

Vec3 = tuple[float, float, float]

POINT, SPOT, SUN, AREA = "POINT", "SPOT", "SUN", "AREA"
KINDS = (POINT, SPOT, SUN, AREA)
SQUARE, RECTANGLE, DISK, ELLIPSE = "SQUARE", "RECTANGLE", "DISK", "ELLIPSE"
SHAPES = (SQUARE, RECTANGLE, DISK, ELLIPSE)

#: A sun is represented, per lens, as a point light this many lens radii away
#: whose intensity ``S·D²`` gives the sun's irradiance at the lens: every
#: formula written for a point light then gives the sun's limit to ~1/SUN_DISTANCE
#: (its vergence is set to the exact limit ``V = P``).
SUN_DISTANCE = 1e6
#: Quadrature of a spot's mask over the lens's disc (rings × sectors, equal
#: solid angle) and of an area light over its surface (n × n points).
SPOT_RINGS, SPOT_SECTORS = 12, 24
AREA_POINTS = 8


# --------------------------------------------------------------------------- the lights


@dataclass(frozen=True)
class PointPrimary:
    """``light.type == 'POINT'``."""

    position: Vec3  # matrix_world.translation
    power_w: float  # light.energy (× 2^exposure)
    radius: float = 0.0  # light.shadow_soft_size
    color: Vec3 = (1.0, 1.0, 1.0)  # light.color
    name: str = ""
    profile: LightProfile | None = None  # its IES profile (light nodes), if any


@dataclass(frozen=True)
class SpotPrimary:
    """``light.type == 'SPOT'``."""

    position: Vec3  # matrix_world.translation
    direction: Vec3  # the object's local −Z in world space
    power_w: float  # light.energy
    spot_size: float  # light.spot_size (full cone angle, radians)
    blend: float = 0.15  # light.spot_blend
    radius: float = 0.0  # light.shadow_soft_size
    color: Vec3 = (1.0, 1.0, 1.0)
    name: str = ""
    profile: LightProfile | None = None  # its IES profile (light nodes), if any


@dataclass(frozen=True)
class SunPrimary:
    """``light.type == 'SUN'``."""

    direction: Vec3  # local −Z in world space: where the light travels
    strength: float  # light.energy (W/m² on a plane facing the sun)
    angle: float = 0.0  # light.angle (angular diameter, radians)
    color: Vec3 = (1.0, 1.0, 1.0)
    name: str = ""


@dataclass(frozen=True)
class AreaPrimary:
    """``light.type == 'AREA'``: Lambertian on its local −Z side."""

    position: Vec3  # matrix_world.translation (the centre)
    direction: Vec3  # local −Z in world space (the emitting side)
    axis_x: Vec3  # local +X in world space (size_x runs along it)
    power_w: float  # light.energy
    shape: str = SQUARE  # light.shape
    size_x: float = 1.0  # light.size × the object's x scale
    size_y: float = 1.0  # light.size_y × y scale (SQUARE, DISK: = size_x)
    color: Vec3 = (1.0, 1.0, 1.0)
    name: str = ""
    profile: LightProfile | None = None  # its IES profile (light nodes), if any

    @property
    def area(self) -> float:
        return float(area_of(self.shape, self.size_x, self.size_y))


Primary = PointPrimary | SpotPrimary | SunPrimary | AreaPrimary


def area_of(shape, size_x, size_y):
    """Area of an area light: ``x·y`` (square, rectangle), ``π x y/4`` (disk, ellipse)."""
    round_ = np.isin(np.asarray(shape), (DISK, ELLIPSE))
    return np.where(round_, 0.25 * math.pi, 1.0) * np.asarray(size_x) * np.asarray(size_y)


def from_matrix(matrix) -> tuple[Vec3, Vec3, Vec3, float, float]:
    """(position, direction −Z, unit axis x, scale x, scale y) of a 4 × 4 world matrix
    (`Object.matrix_world`, as nested rows)."""
    m = np.asarray(matrix, dtype=float).reshape(4, 4)
    x, y, z = m[:3, 0], m[:3, 1], m[:3, 2]
    sx, sy = float(np.linalg.norm(x)), float(np.linalg.norm(y))
    d = -z / np.linalg.norm(z)
    return (tuple(m[:3, 3]), tuple(d), tuple(x / sx), sx, sy)


# --------------------------------------------------------------------------- columns


@dataclass
class PrimaryArrays:
    """The primaries as columns (L lights)."""

    kind: np.ndarray  # (L,) index into KINDS
    position: np.ndarray  # (L, 3); a sun's is NaN
    direction: np.ndarray  # (L, 3) unit: spot axis, sun's travel, area's −Z
    axis_x: np.ndarray  # (L, 3) unit (area lights; else 0)
    power: np.ndarray  # (L,) W; a sun: its nominal 4π·S (see `nominal_power`)
    radius: np.ndarray  # (L,) point / spot radius
    half_angle: np.ndarray  # (L,) spot: spot_size/2 (π otherwise)
    blend: np.ndarray  # (L,)
    strength: np.ndarray  # (L,) sun: S (W/m²)
    angle: np.ndarray  # (L,) sun: angular diameter
    shape: np.ndarray  # (L,) area: shape name ("" otherwise)
    size: np.ndarray  # (L, 2) area: size_x, size_y
    color: np.ndarray  # (L, 3)
    profiles: tuple = ()  # (L,) each light's `ies.LightProfile`, or None (none: all None)

    def __len__(self) -> int:
        return int(self.kind.size)

    @classmethod
    def from_primaries(cls, primaries) -> PrimaryArrays:
        n = len(primaries)
        a = cls(
            kind=np.zeros(n, dtype=np.int64),
            position=np.full((n, 3), np.nan),
            direction=np.zeros((n, 3)),
            axis_x=np.zeros((n, 3)),
            power=np.zeros(n),
            radius=np.zeros(n),
            half_angle=np.full(n, math.pi),
            blend=np.zeros(n),
            strength=np.zeros(n),
            angle=np.zeros(n),
            shape=np.full(n, "", dtype=object),
            size=np.zeros((n, 2)),
            color=np.ones((n, 3)),
        )
        for j, p in enumerate(primaries):
            a.color[j] = p.color
            if isinstance(p, SunPrimary):
                a.kind[j] = KINDS.index(SUN)
                a.direction[j] = _unit(p.direction)
                a.strength[j], a.angle[j] = p.strength, p.angle
                a.power[j] = nominal_power(p)
                continue
            a.position[j] = p.position
            a.power[j] = p.power_w
            if isinstance(p, PointPrimary):
                a.kind[j], a.radius[j] = KINDS.index(POINT), p.radius
            elif isinstance(p, SpotPrimary):
                a.kind[j] = KINDS.index(SPOT)
                a.direction[j] = _unit(p.direction)
                a.half_angle[j] = 0.5 * min(max(p.spot_size, 0.0), math.pi)
                a.blend[j], a.radius[j] = min(max(p.blend, 0.0), 1.0), p.radius
            elif isinstance(p, AreaPrimary):
                a.kind[j] = KINDS.index(AREA)
                a.direction[j] = _unit(p.direction)
                x = np.asarray(p.axis_x, dtype=float)
                x = x - np.dot(x, a.direction[j]) * a.direction[j]  # keep it in the plane
                a.axis_x[j] = x / np.linalg.norm(x)
                a.shape[j] = p.shape if p.shape in SHAPES else SQUARE
                square = a.shape[j] in (SQUARE, DISK)
                a.size[j] = (p.size_x, p.size_x if square else p.size_y)
            else:
                raise TypeError(f"not a primary light: {p!r}")
        a.profiles = tuple(getattr(p, "profile", None) for p in primaries)
        return a

    def is_(self, kind: str) -> np.ndarray:
        return self.kind == KINDS.index(kind)


def nominal_power(p) -> float:
    """The power the tiers scale (`tiers.base.PrimaryLight.power_w`): a light's
    energy; a sun's ``4π·S`` (an intensity of ``S`` W/sr at unit distance, which
    phase 1 scales by ``D²`` at the equivalent distance ``D``)."""
    if isinstance(p, SunPrimary):
        return 4.0 * math.pi * float(p.strength)
    return float(p.power_w)


def tier_primaries(primaries) -> list:
    """The `tiers.PrimaryLight` of each primary (power: `nominal_power`; radius: a
    point or spot light's; colour): what `planning.plan_lights` takes as
    ``primaries``; each source's ``emission`` and ``source_radius`` do the rest."""

    return [
        PrimaryLight(
            power_w=nominal_power(p),
            radius=float(getattr(p, "radius", 0.0)),
            color=tuple(float(c) for c in p.color),
        )
        for p in primaries
    ]


def _unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)


def _basis(w):
    """Two unit vectors (…, 3) perpendicular to the unit vectors `w` and to each other."""
    helper = np.where(np.abs(w[..., :1]) < 0.9, [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    e1 = np.cross(w, helper)
    e1 /= np.linalg.norm(e1, axis=-1, keepdims=True)
    return e1, np.cross(w, e1)


def cap_one_minus_cos(D, R):
    """``1 − cos α`` of the cap a lens of radius R subtends at distance D (SPEC §4.2)."""
    s = np.clip(R / D, 0.0, 1.0)
    return s * s / (1.0 + np.sqrt((1.0 - s) * (1.0 + s)))


# --------------------------------------------------------------------------- toward a lens


def spot_share(
    position,
    direction,
    half_angle,
    blend,
    centers,
    radii,
    rings: int = SPOT_RINGS,
    sectors: int = SPOT_SECTORS,
) -> np.ndarray:
    """Mean of a spot's mask over the cap a lens subtends (N pairs): 1 when the lens
    lies inside the full-intensity cone, 0 outside the cone, else a quadrature of
    equal solid-angle cells (a cone covering part of the lens gives that part's light)."""
    to = np.asarray(centers, float) - position
    D = np.linalg.norm(to, axis=-1)
    w = to / D[:, None]
    alpha = np.arctan2(radii, np.sqrt(np.maximum((D - radii) * (D + radii), 0.0)))
    gamma = np.arctan2(
        np.linalg.norm(np.cross(w, direction), axis=-1), np.sum(w * direction, axis=-1)
    )
    # the full-intensity cone: 1 − cos ψ ≤ (1 − blend)(1 − cos H), i.e.
    # sin(ψ/2) ≤ sqrt(1 − blend)·sin(H/2) (atan2, no acos: SPEC §4.2)
    s = np.sqrt(np.clip(1.0 - blend, 0.0, 1.0)) * np.sin(0.5 * np.asarray(half_angle, float))
    full = 2.0 * np.arctan2(s, np.sqrt((1.0 - s) * (1.0 + s)))
    out = np.where(gamma + alpha <= full, 1.0, 0.0)
    edge = np.flatnonzero((gamma + alpha > full) & (gamma - alpha < half_angle))
    if edge.size:
        w_e = w[edge]
        e1, e2 = _basis(w_e)
        t = (np.arange(rings) + 0.5) / rings  # equal solid angle rings
        one_m = cap_one_minus_cos(D[edge], np.asarray(radii, float)[edge])[:, None] * t
        cos_p, sin_p = 1.0 - one_m, np.sqrt(one_m * (2.0 - one_m))
        phi = 2.0 * math.pi * (np.arange(sectors) + 0.5) / sectors
        d = cos_p[..., None, None] * w_e[:, None, None, :] + sin_p[..., None, None] * (
            np.cos(phi)[:, None] * e1[:, None, None, :]
            + np.sin(phi)[:, None] * e2[:, None, None, :]
        )
        dirs = direction[edge] if np.ndim(direction) == 2 else direction
        dirs = np.broadcast_to(dirs, (edge.size, 3))
        c = np.einsum("nrsk,nk->nrs", d, dirs)
        h = np.broadcast_to(np.asarray(half_angle, float), D.shape)[edge]
        b = np.broadcast_to(np.asarray(blend, float), D.shape)[edge]
        out[edge] = spot_mask(c, h[:, None, None], b[:, None, None]).mean(axis=(1, 2))
    return out


def spot_mask(cos_gamma, half_angle, blend):
    """Blender's spot mask, elementwise over arrays (`blender_spot.spot_mask` takes
    one cone): ``smoothstep((c − cos H)/((1 − cos H)·blend))``, a hard edge at blend 0."""
    q_h = 2.0 * np.sin(0.5 * np.asarray(half_angle, float)) ** 2
    w = q_h * np.maximum(np.asarray(blend, float), 0.0)
    x = np.asarray(cos_gamma, float) - (1.0 - q_h)
    with np.errstate(divide="ignore", invalid="ignore"):
        soft = smoothstep01(x / np.where(w > 0, w, 1.0))
    return np.where(w > 0, soft, (x > 0).astype(float))


def _area_points(shape, sx, sy, n: int = AREA_POINTS):
    """Quadrature points (n², 2) in the light's plane (local x, y) and their weight
    (share of the area): a midpoint grid on a rectangle, equal-area rings on a disc."""
    i = (np.arange(n) + 0.5) / n
    if shape in (DISK, ELLIPSE):
        r = np.sqrt(i)[:, None]
        phi = 2.0 * math.pi * i[None, :]
        uv = np.stack([0.5 * sx * r * np.cos(phi), 0.5 * sy * r * np.sin(phi)], -1)
    else:
        u, v = np.meshgrid((i - 0.5) * sx, (i - 0.5) * sy, indexing="ij")
        uv = np.stack([u, v], -1)
    return uv.reshape(-1, 2), 1.0 / (n * n)


def area_flux(
    position, direction, axis_x, power, shape, sx, sy, centers, radii, n: int = AREA_POINTS
) -> np.ndarray:
    """Flux (W) an area light sends into a sphere (N pairs): radiance ``P/(πA)`` times
    ``∫_A cos θ · π sin²α dA`` (the form factor of a sphere fully above a surface
    element: ``cos θ (R/d)²``), by quadrature over the light's surface; a sphere
    below the light's plane gets nothing (a partly-below sphere: its centre's
    ``cos θ`` clamped at 0, an approximation)."""
    uv, weight = _area_points(shape, sx, sy, n)
    ey = np.cross(direction, axis_x)
    pts = position + uv[:, :1] * axis_x + uv[:, 1:] * ey  # (K, 3)
    to = np.asarray(centers, float)[:, None, :] - pts[None]  # (N, K, 3)
    d2 = np.einsum("nki,nki->nk", to, to)
    cos_t = np.maximum(np.einsum("nki,i->nk", to, direction) / np.sqrt(d2), 0.0)
    sin2 = np.minimum(np.asarray(radii, float)[:, None] ** 2 / d2, 1.0)
    # radiance × area = P/π; π sin²α cos θ per point, weighted by its share of A
    return power * np.sum(cos_t * sin2, axis=1) * weight


def emission_toward(arrays: PrimaryArrays, light, centers, radii) -> np.ndarray:
    """Per pair (light index `light`, lens centre, radius; N pairs): the mean radiant
    intensity over the lens's disc in units of the nominal ``power/(4π)`` — the
    factor the tiers put on the primary's power (module docstring). Suns: 1 (their
    equivalent distance is applied by phase 1)."""
    light = np.asarray(light, dtype=np.int64)
    centers = np.asarray(centers, float).reshape(-1, 3)
    radii = np.asarray(radii, float).reshape(-1)
    out = np.ones(light.size)
    kind = arrays.kind[light]
    spot = np.flatnonzero(kind == KINDS.index(SPOT))
    if spot.size:
        j = light[spot]
        out[spot] = spot_share(
            arrays.position[j],
            arrays.direction[j],
            arrays.half_angle[j],
            arrays.blend[j],
            centers[spot],
            radii[spot],
        )
    area = np.flatnonzero(kind == KINDS.index(AREA))
    for j in np.unique(light[area]):
        rows = area[light[area] == j]
        c, r = centers[rows], radii[rows]
        flux = area_flux(
            arrays.position[j],
            arrays.direction[j],
            arrays.axis_x[j],
            arrays.power[j],
            arrays.shape[j],
            *arrays.size[j],
            c,
            r,
        )
        D = np.linalg.norm(c - arrays.position[j], axis=-1)
        omega = 2.0 * math.pi * cap_one_minus_cos(D, r)
        with np.errstate(divide="ignore", invalid="ignore"):
            out[rows] = np.where(
                arrays.power[j] > 0, flux / (arrays.power[j] / (4.0 * math.pi) * omega), 0.0
            )
    # an IES profile (light nodes) scales what the light sends toward each lens
    if any(p is not None for p in arrays.profiles):
        for j in np.unique(light):
            profile = arrays.profiles[int(j)]
            if profile is not None:
                rows = np.flatnonzero(light == j)
                out[rows] *= profile.toward(arrays.position[j], centers[rows], radii[rows])
    return out


def lens_flux(arrays: PrimaryArrays, light, centers, radii) -> np.ndarray:
    """Flux (W) each primary sends into each lens (N pairs; obstruction not
    included): a sun ``S·πR²``, the others ``emission × P/(4π) × 2π(1 − cos α)``."""
    light = np.asarray(light, dtype=np.int64)
    centers = np.asarray(centers, float).reshape(-1, 3)
    radii = np.asarray(radii, float).reshape(-1)
    sun = arrays.kind[light] == KINDS.index(SUN)
    with np.errstate(invalid="ignore"):
        D = np.linalg.norm(centers - arrays.position[light], axis=-1)
    omega = 2.0 * math.pi * cap_one_minus_cos(np.where(sun, 1.0, D), radii)
    point = (
        arrays.power[light]
        / (4.0 * math.pi)
        * omega
        * emission_toward(arrays, light, centers, radii)
    )
    return np.where(sun, arrays.strength[light] * math.pi * radii**2, point)


def source_radius(arrays: PrimaryArrays, light, centers, equivalent_distance=None):
    """Radius of the disc each primary looks like from each lens (N pairs): a point
    or spot light its radius; an area light the disc with the second moment of its
    outline projected across the line of sight (Blender's lens lights are discs:
    ``sqrt(2 (σx² |x⊥|² + σy² |y⊥|²))``, σ² = s²/12 for a side s, d²/16 for a
    diameter d); a sun ``D tan(a/2)`` at its `equivalent_distance` D (N,)."""
    light = np.asarray(light, dtype=np.int64)
    centers = np.asarray(centers, float).reshape(-1, 3)
    out = arrays.radius[light].astype(float).copy()
    kind = arrays.kind[light]
    area = kind == KINDS.index(AREA)
    if area.any():
        j = light[area]
        w = centers[area] - arrays.position[j]
        w /= np.linalg.norm(w, axis=-1, keepdims=True)
        ex = arrays.axis_x[j]
        ey = np.cross(arrays.direction[j], ex)

        def perp2(e):
            return 1.0 - np.sum(e * w, axis=-1) ** 2

        round_ = np.isin(arrays.shape[j], (DISK, ELLIPSE))
        k = np.where(round_, 1.0 / 16.0, 1.0 / 12.0)
        sx, sy = arrays.size[j, 0], arrays.size[j, 1]
        out[area] = np.sqrt(2.0 * k * (sx * sx * perp2(ex) + sy * sy * perp2(ey)))
    sun = kind == KINDS.index(SUN)
    if sun.any():
        D = np.asarray(equivalent_distance, float).reshape(-1)[sun]
        out[sun] = D * np.tan(0.5 * arrays.angle[light[sun]])
    return out


@dataclass(frozen=True)
class PrimaryLight:
    """What the energy models need of the primary (point) light."""

    power_w: float  # Blender energy (× 2^exposure), W
    radius: float = 0.0  # shadow_soft_size
    color: tuple[float, float, float] = (1.0, 1.0, 1.0)

    @property
    def intensity(self) -> float:
        """Radiant intensity, W/sr: ``P/(4π)`` (SPEC §9)."""
        return self.power_w / (4.0 * math.pi)
