"""The primaries and the lens as plain data, and their deterministic source samples.

An extended source blurs the caustic (SPEC §10). It is modelled by supersampling the
emitter: K points on a point/spot light's disc, K directions within a sun's cone, K
points on an area light, each the centre of an equal share of the emitter (a cell of an
m × m grid, mapped onto a disc by Shirley and Chiu's concentric map). Each sample makes
its own exact ray grid; the caustic layer spreads each sample's image over its share.
Supersampling is chosen over convolving with the image of the source because the shift
of the caustic is not the same everywhere (near-field and tilted receivers), and an
accumulation raster adds the samples for free. The sample patterns are deterministic
(grids), so an animation does not flicker.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..scene.blender_spot import spot_mask
from ..shared.vectors import cross


def _vec(v) -> np.ndarray:
    return np.asarray(v, dtype=float).reshape(3)


def _unit(v) -> np.ndarray:
    v = _vec(v)
    return v / np.linalg.norm(v)


@dataclass(frozen=True)
class Lens:
    """A lens: centre, radius, relative index, Beer–Lambert absorption per unit length
    (SPEC §3.4: ``1 − kt``), a transmission tint (RGB multiplier), and its ``kind`` (a
    key of `core.lens.kinds.LENS_KINDS`; a glass sphere by default) with the kind's
    own ``params``."""

    center: np.ndarray
    radius: float
    ior: float
    absorption: float = 0.0
    tint: tuple[float, float, float] = (1.0, 1.0, 1.0)
    kind: str = "ball"
    params: tuple = ()


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
    # What each sample stands for: its share of the emitter. ``shares`` (K, 2, 3): the
    # emitter's two axes (point samples: displacements of the point; parallel: changes
    # of the direction) per unit of its shape's coordinates (the unit disc if
    # ``share_disc``, else the square [−½, ½]²; zero: a point); the share is cell
    # ``share_cells[k]`` of the m × m grid (``share_grid``) on that shape.
    shares: np.ndarray | None = None
    share_disc: bool = True
    share_cells: np.ndarray | None = None
    share_grid: int = 1


def perpendicular_frame(axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors completing ``axis`` (unit) to a right-handed frame, continuous
    in the axis except near −x (Frisvad-style branch on the largest helper)."""
    a = np.asarray(axis, dtype=float)
    helper = np.array([1.0, 0.0, 0.0]) if abs(a[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = cross(helper, a)
    e1 /= np.linalg.norm(e1)
    return e1, cross(a, e1)


def concentric_disc(s, t):
    """Shirley and Chiu's concentric map of the unit square [0, 1]² onto the unit disc:
    equal areas to equal areas, cells of a grid to compact cells (arrays)."""
    a, b = 2.0 * np.asarray(s, dtype=float) - 1.0, 2.0 * np.asarray(t, dtype=float) - 1.0
    first = np.abs(a) > np.abs(b)
    safe_a = np.where(a != 0.0, a, 1.0)
    safe_b = np.where(b != 0.0, b, 1.0)
    r = np.where(first, a, b)
    phi = np.where(first, 0.25 * np.pi * b / safe_a, 0.5 * np.pi - 0.25 * np.pi * a / safe_b)
    r = np.where((a == 0.0) & (b == 0.0), 0.0, r)
    return r * np.cos(phi), r * np.sin(phi)


def disc_grid(k: int) -> tuple[np.ndarray, np.ndarray, int]:
    """About ``k`` equal-area samples of the unit disc: the centres of an m × m grid
    (m = round √k) mapped by :func:`concentric_disc`; returns the points (m², 2), each
    one's grid cell (m², 2) and m."""
    m = max(1, int(round(math.sqrt(k))))
    i, j = (a.reshape(-1) for a in np.meshgrid(np.arange(m), np.arange(m), indexing="ij"))
    x, y = concentric_disc((i + 0.5) / m, (j + 0.5) / m)
    return np.column_stack([x, y]), np.column_stack([i, j]), m


def _one_point():
    return np.zeros((1, 2)), np.zeros((1, 2), dtype=np.int64), 1


def source_samples(emitter, lens: Lens, k: int = 1) -> SourceSamples:
    """Deterministic samples of ``emitter`` as seen from ``lens`` (k ≥ 1; an extended
    emitter gets m² ≈ k of them, m = round √k)."""
    k = max(1, int(k))
    c = _vec(lens.center)
    if isinstance(emitter, SunLight):
        d = _unit(emitter.direction)
        e1, e2 = perpendicular_frame(d)
        disc, cells, m = disc_grid(k) if emitter.angle > 0.0 else _one_point()
        t = math.tan(0.5 * emitter.angle)
        dirs = d + t * (disc[:, :1] * e1 + disc[:, 1:] * e2)
        dirs /= np.linalg.norm(dirs, axis=1)[:, None]
        w = np.full(len(dirs), emitter.strength / len(dirs))
        shares = _axes(t * e1, t * e2, len(dirs))
        return SourceSamples(
            True, c - 4.0 * lens.radius * dirs, dirs, w, emitter, shares, True, cells, m
        )
    if isinstance(emitter, (PointLight, SpotLight)):
        p = _vec(emitter.position)
        # The disc faces the lens (a sphere light) or the spot's axis (a disk spot).
        facing = _unit(c - p) if isinstance(emitter, PointLight) else _unit(emitter.direction)
        e1, e2 = perpendicular_frame(facing)
        disc, cells, m = disc_grid(k) if emitter.radius > 0.0 else _one_point()
        pts = p + emitter.radius * (disc[:, :1] * e1 + disc[:, 1:] * e2)
        w = np.full(len(pts), emitter.power / (4.0 * math.pi) / len(pts))
        shares = _axes(emitter.radius * e1, emitter.radius * e2, len(pts))
        return SourceSamples(False, pts, _dirs_to(pts, c), w, emitter, shares, True, cells, m)
    if isinstance(emitter, AreaLight):
        nrm = _unit(emitter.normal)
        ax = _vec(emitter.axis_x)
        ax = ax - (ax @ nrm) * nrm
        ax /= np.linalg.norm(ax)
        ay = np.cross(nrm, ax)
        disc = emitter.shape in ("DISK", "ELLIPSE")
        if disc:
            uv, cells, m = disc_grid(k)
            uv = 0.5 * uv  # the shape's coordinates: diameters size_x, size_y
            half = 0.5
        else:
            m = max(1, int(round(math.sqrt(k))))
            i, j = (a.reshape(-1) for a in np.meshgrid(np.arange(m), np.arange(m), indexing="ij"))
            cells = np.column_stack([i, j])
            uv = (cells + 0.5) / m - 0.5
            half = 1.0
        pts = (
            _vec(emitter.position)
            + uv[:, :1] * emitter.size_x * ax
            + uv[:, 1:] * emitter.size_y * ay
        )
        # radiance P/(πA) × (A/K) per sample: intensity P/(πK) × cos θ (angular_factor)
        w = np.full(len(pts), emitter.power / (math.pi * len(pts)))
        shares = _axes(half * emitter.size_x * ax, half * emitter.size_y * ay, len(pts))
        return SourceSamples(False, pts, _dirs_to(pts, c), w, emitter, shares, disc, cells, m)
    raise TypeError(f"unknown emitter {type(emitter).__name__}")


def point_samples(pairs) -> list:
    """:func:`source_samples` of the (emitter, lens) pairs whose emitter is a point (a
    point or spot light of radius 0: one sample whatever k), all at once (many lenses
    under one lamp cost one set of array operations); None for the other pairs. Their
    ``shares`` is None: a point has no extent to blur over."""
    out = [None] * len(pairs)
    idx = [
        i
        for i, (e, _) in enumerate(pairs)
        if isinstance(e, (PointLight, SpotLight)) and not e.radius > 0.0
    ]
    if not idx:
        return out
    p = np.array([pairs[i][0].position for i in idx], dtype=float).reshape(-1, 3)
    c = np.array([pairs[i][1].center for i in idx], dtype=float).reshape(-1, 3)
    d = c - p
    d /= np.linalg.norm(d, axis=1)[:, None]
    w = np.array([pairs[i][0].power for i in idx], dtype=float) / (4.0 * math.pi)
    cells = np.zeros((1, 2), dtype=np.int64)
    for k, i in enumerate(idx):
        out[i] = SourceSamples(
            False, p[k : k + 1], d[k : k + 1], w[k : k + 1], pairs[i][0], None, True, cells, 1
        )
    return out


def _axes(a1, a2, k: int) -> np.ndarray:
    return np.broadcast_to(np.stack([a1, a2]), (k, 2, 3)).copy()


def share_offsets(cells, m, disc, s, t):
    """Offsets, in the emitter's shape coordinates, from each sample to points (s, t) ∈
    [0, 1]² of its share (cell ``cells`` of the m × m grid; ``disc``: through the
    concentric map). ``cells`` (N, 2), ``m`` and ``disc`` (N,), ``s``, ``t`` (N, Q)."""
    i, j = cells[:, :1].astype(float), cells[:, 1:].astype(float)
    mm = np.asarray(m, dtype=float)[:, None]
    d = np.asarray(disc, dtype=bool)[:, None]
    x, y = concentric_disc((i + s) / mm, (j + t) / mm)
    x0, y0 = concentric_disc((i + 0.5) / mm, (j + 0.5) / mm)
    return np.where(d, x - x0, (s - 0.5) / mm), np.where(d, y - y0, (t - 0.5) / mm)


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
