"""The primaries and the lens as plain data, and their deterministic source samples.

An extended source blurs the caustic (SPEC §10). It is modelled by supersampling the
emitter: K points on a point/spot light's disc, K directions within a sun's cone, K
points on an area light. Each sample makes its own exact ray grid and the caustic layer
adds them up. Supersampling is chosen over convolving with the image of the source
because the shift of the caustic is not the same everywhere (near-field and tilted
receivers), and an accumulation raster adds the samples for free. The sample patterns
are deterministic (Vogel spiral, stratified grid), so an animation does not flicker.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..blender_spot import spot_mask

GOLDEN_ANGLE = math.pi * (3.0 - math.sqrt(5.0))


def _vec(v) -> np.ndarray:
    return np.asarray(v, dtype=float).reshape(3)


def _unit(v) -> np.ndarray:
    v = _vec(v)
    return v / np.linalg.norm(v)


@dataclass(frozen=True)
class Lens:
    """A glass sphere: centre, radius, relative index, Beer–Lambert absorption per
    unit length (SPEC §3.4: ``1 − kt``) and a transmission tint (RGB multiplier)."""

    center: np.ndarray
    radius: float
    ior: float
    absorption: float = 0.0
    tint: tuple[float, float, float] = (1.0, 1.0, 1.0)


@dataclass(frozen=True)
class PointLight:
    """Blender point light: power P (W), radius r (a uniform sphere; 0 = a point)."""

    position: np.ndarray
    power: float
    radius: float = 0.0
    color: tuple[float, float, float] = (1.0, 1.0, 1.0)


@dataclass(frozen=True)
class SpotLight:
    """Blender spot: a point light of power P times the spot mask around ``direction``
    (the emission axis, Blender's local −Z); ``spot_size`` the full cone angle (rad)."""

    position: np.ndarray
    direction: np.ndarray
    power: float
    spot_size: float
    blend: float = 0.15
    radius: float = 0.0
    color: tuple[float, float, float] = (1.0, 1.0, 1.0)


@dataclass(frozen=True)
class SunLight:
    """Blender sun: ``direction`` the light travels in, strength S (W/m²), ``angle`` the
    full angular diameter (rad)."""

    direction: np.ndarray
    strength: float
    angle: float = 0.0
    color: tuple[float, float, float] = (1.0, 1.0, 1.0)


@dataclass(frozen=True)
class AreaLight:
    """Blender area light: Lambertian on the side of ``normal`` (local −Z), radiance
    P/(π A). ``axis_x`` is the local X axis; shape 'SQUARE'/'RECTANGLE' (size_x ×
    size_y) or 'DISK'/'ELLIPSE' (diameters size_x, size_y)."""

    position: np.ndarray
    normal: np.ndarray
    axis_x: np.ndarray
    power: float
    size_x: float
    size_y: float
    shape: str = "RECTANGLE"
    color: tuple[float, float, float] = (1.0, 1.0, 1.0)


@dataclass(frozen=True)
class SourceSamples:
    """K samples of one emitter. ``parallel``: each sample is a parallel beam
    travelling along ``directions[k]`` with irradiance ``weights[k]`` (W/m²); otherwise
    a point at ``points[k]`` with radiant intensity ``weights[k]`` (W/sr) times
    :func:`angular_factor` toward each direction."""

    parallel: bool
    points: np.ndarray  # (K, 3)
    directions: np.ndarray  # (K, 3) unit
    weights: np.ndarray  # (K,)
    emitter: object = field(repr=False, default=None)
    # What each sample stands for: its share of the emitter, spanned by two vectors
    # (K, 2, 3) about it (point samples: displacements of the point; parallel: changes
    # of the direction), a disc (``share_disc``) or a square of that span (zero: none).
    shares: np.ndarray | None = None
    share_disc: bool = True


def perpendicular_frame(axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors completing ``axis`` (unit) to a right-handed frame, continuous
    in the axis except near −x (Frisvad-style branch on the largest helper)."""
    a = np.asarray(axis, dtype=float)
    helper = np.array([1.0, 0.0, 0.0]) if abs(a[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = np.cross(helper, a)
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(a, e1)


def vogel_disc(k: int) -> np.ndarray:
    """``k`` points of equal area in the unit disc (Vogel's golden-angle spiral); one
    sample is the centre."""
    i = np.arange(k, dtype=float)
    rad = np.sqrt((i + 0.5) / k) if k > 1 else np.zeros(1)
    ang = i * GOLDEN_ANGLE
    return np.column_stack([rad * np.cos(ang), rad * np.sin(ang)])


def source_samples(emitter, lens: Lens, k: int = 1) -> SourceSamples:
    """Deterministic samples of ``emitter`` as seen from ``lens`` (k ≥ 1)."""
    k = max(1, int(k))
    c = _vec(lens.center)
    if isinstance(emitter, SunLight):
        d = _unit(emitter.direction)
        e1, e2 = perpendicular_frame(d)
        disc = vogel_disc(k) if emitter.angle > 0.0 else np.zeros((1, 2))
        t = math.tan(0.5 * emitter.angle)
        dirs = d + t * (disc[:, :1] * e1 + disc[:, 1:] * e2)
        dirs /= np.linalg.norm(dirs, axis=1)[:, None]
        w = np.full(len(dirs), emitter.strength / len(dirs))
        shares = _disc_shares(t * (1.0 if emitter.angle > 0.0 else 0.0), e1, e2, len(dirs))
        return SourceSamples(True, c - 4.0 * lens.radius * dirs, dirs, w, emitter, shares)
    if isinstance(emitter, (PointLight, SpotLight)):
        p = _vec(emitter.position)
        # The disc faces the lens (a sphere light) or the spot's axis (a disk spot).
        facing = _unit(c - p) if isinstance(emitter, PointLight) else _unit(emitter.direction)
        e1, e2 = perpendicular_frame(facing)
        disc = vogel_disc(k) if emitter.radius > 0.0 else np.zeros((1, 2))
        pts = p + emitter.radius * (disc[:, :1] * e1 + disc[:, 1:] * e2)
        w = np.full(len(pts), emitter.power / (4.0 * math.pi) / len(pts))
        shares = _disc_shares(emitter.radius, e1, e2, len(pts))
        return SourceSamples(False, pts, _dirs_to(pts, c), w, emitter, shares)
    if isinstance(emitter, AreaLight):
        nrm = _unit(emitter.normal)
        ax = _vec(emitter.axis_x)
        ax = ax - (ax @ nrm) * nrm
        ax /= np.linalg.norm(ax)
        ay = np.cross(nrm, ax)
        disc = emitter.shape in ("DISK", "ELLIPSE")
        if disc:
            uv = 0.5 * vogel_disc(k)
            span = 0.5 / math.sqrt(len(uv))  # the radius of a disc of 1/K of the area
        else:
            m = max(1, int(round(math.sqrt(k))))
            g = (np.arange(m) + 0.5) / m - 0.5
            uv = np.stack(np.meshgrid(g, g, indexing="ij"), axis=-1).reshape(-1, 2)
            span = 1.0 / m  # the side of a grid cell
        pts = (
            _vec(emitter.position)
            + uv[:, :1] * emitter.size_x * ax
            + uv[:, 1:] * emitter.size_y * ay
        )
        # radiance P/(πA) × (A/K) per sample: intensity P/(πK) × cos θ (angular_factor)
        w = np.full(len(pts), emitter.power / (math.pi * len(pts)))
        axes = np.stack([span * emitter.size_x * ax, span * emitter.size_y * ay])
        shares = np.broadcast_to(axes, (len(pts), 2, 3)).copy()
        return SourceSamples(False, pts, _dirs_to(pts, c), w, emitter, shares, disc)
    raise TypeError(f"unknown emitter {type(emitter).__name__}")


def _disc_shares(radius: float, e1, e2, k: int) -> np.ndarray:
    """(k, 2, 3): each of k equal-area samples of a disc of ``radius`` (axes e1, e2)
    stands for a disc of 1/k of its area: radius ``radius/√k``."""
    r = radius / math.sqrt(k)
    return np.broadcast_to(np.stack([r * e1, r * e2]), (k, 2, 3)).copy()


def _dirs_to(pts: np.ndarray, c: np.ndarray) -> np.ndarray:
    d = c - pts
    return d / np.linalg.norm(d, axis=1)[:, None]


def is_isotropic(emitter) -> bool:
    """True when a sample sends the same intensity toward every point of the lens."""
    return isinstance(emitter, (PointLight, SunLight))


def angular_factor(emitter, dirs: np.ndarray) -> np.ndarray | float:
    """Multiplier of a sample's weight toward unit directions ``dirs`` (…, 3): 1 for a
    point light or a sun, Blender's spot mask for a spot, cos θ⁺ for an area light."""
    if isinstance(emitter, SpotLight):
        cosg = dirs @ _unit(emitter.direction)
        return spot_mask(cosg, 0.5 * emitter.spot_size, emitter.blend)
    if isinstance(emitter, AreaLight):
        return np.maximum(dirs @ _unit(emitter.normal), 0.0)
    return 1.0
