"""Phase 1 of the Bitracer method: one secondary light source per point light × lens.

SPEC.md §3 gives the thesis' formulas, §4 the stable forms used here:

* image position by vergence about the centre (`V = P − 1/D`), so there is no
  singular point at `p·a = R` and the focal point is just `V = 0`;
* radial angles by `atan2`, angles between directions by `atan2(|a×b|, a·b)`;
* the spreading angle of eqs. 5.14 and 5.21 rewritten in terms of `V` (the two
  branches are one formula: `tan θ = |R sin φ · V| / |R cos φ · V − 1|`), which
  tends to 0 smoothly as the image runs off to infinity.

Everything is vectorised over lights × lenses (and × obstacles for the obstruction
tests); the only Python loop is over lights, each handling all spheres at once.
No inf or NaN leaves this module: invalid input becomes a skipped pair with a reason.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .scene import Scene

REAL, VIRTUAL, COLLIMATED = "real", "virtual", "collimated"

#: A light within this relative distance of a sphere's surface is "on" it.
SURFACE_TOLERANCE = 1e-9
#: Default switch to the collimated representation: when the image lies farther
#: from the lens than this many times the scene's size.
COLLIMATION_RATIO = 1e4
#: Obstruction is evaluated in blocks of lenses × spheres of about this many cells.
_BLOCK_CELLS = 1 << 21


@dataclass
class SecondarySource:
    light: int                      # index among the scene's lights
    lens: int                       # index among the scene's objects
    kind: str                       # "real" | "virtual" | "collimated"
    position: np.ndarray            # image point (back vertex when collimated)
    axis: np.ndarray                # unit beam direction, from the light through the lens
    spread_deg: float               # θ, half-angle of the cone (0 when collimated)
    cylinder_radius: float | None   # R_C for collimated sources
    intensity: float                # I_j × brightness factor (eq. 5.22)
    color: tuple[float, float, float]
    full: bool
    shadow_list: list[int]
    # Quantities later stages need (energy models, Blender lights, reports):
    brightness_factor: float        # exp(−(1 − kt)(2R + TR)/2)
    distance: float                 # D, light to lens centre
    lens_center: np.ndarray
    lens_radius: float
    ior: float
    vergence: float                 # V = P − 1/D (1/length)
    image_distance: float | None    # 1/V, signed, from the lens centre along the axis
    magnification: float | None     # m = −(1/V)/D; None when collimated
    alpha_deg: float                # half-angle under which the light sees the lens
    unblocked_fraction: float       # share of the lit cap's flux no obstacle blocks

    def to_json(self) -> dict:
        return {
            "light": self.light,
            "lens": self.lens,
            "kind": self.kind,
            "position": [float(x) for x in self.position],
            "axis": [float(x) for x in self.axis],
            "spread_deg": self.spread_deg,
            "cylinder_radius": self.cylinder_radius,
            "intensity": self.intensity,
            "color": [float(c) for c in self.color],
            "full": self.full,
            "shadow_list": list(self.shadow_list),
            "image_distance": self.image_distance,
            "magnification": self.magnification,
            "brightness_factor": self.brightness_factor,
            "unblocked_fraction": self.unblocked_fraction,
        }


@dataclass
class Skipped:
    light: int
    lens: int
    reason: str

    def to_json(self) -> dict:
        return {"light": self.light, "lens": self.lens, "reason": self.reason}


@dataclass
class Phase1Result:
    sources: list[SecondarySource] = field(default_factory=list)
    skipped: list[Skipped] = field(default_factory=list)

    def to_json(self) -> dict:
        return {"sources": [s.to_json() for s in self.sources],
                "skipped": [s.to_json() for s in self.skipped]}


# --------------------------------------------------------------------------- helpers

def radial_angle(distance, radius):
    """Half-angle under which a point at `distance` from a centre sees a sphere.

    `atan2(R, sqrt((D − R)(D + R)))`: exact far away and near grazing, where
    `acos(R_T / D)` loses every digit (SPEC §4.2). NaN where D < R (caller masks).
    """
    with np.errstate(invalid="ignore"):
        return np.arctan2(radius, np.sqrt((distance - radius) * (distance + radius)))


def tangent_length(distance, radius):
    """`R_T = sqrt(D² − R²)`, in the cancellation-free product form."""
    with np.errstate(invalid="ignore"):
        return np.sqrt((distance - radius) * (distance + radius))


def angle_between(a, b):
    """Angle between direction arrays `a`, `b` (…, 3): `atan2(|a×b|, a·b)`."""
    return np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1), np.sum(a * b, axis=-1))


def ball_lens_power(radius, ior):
    """Power of a ball lens, both principal planes at its centre: `2(n − 1)/(n R)`."""
    return 2.0 * (ior - 1.0) / (ior * radius)


def critical_angle(ior):
    """`δ = asin(1/n)` for n ≥ 1, via atan2 so n → 1 (δ → 90°) stays exact."""
    return np.arctan2(1.0, np.sqrt((ior - 1.0) * (ior + 1.0)))


def brightness_factor(radius, ior, kt):
    """Thesis eq. 5.22: Beer–Lambert over the mean of the axial (2R) and edge chords.

    The edge ray's chord is `TR = 2R cos δ`, `cos δ = sqrt(n² − 1)/n`.
    """
    cos_delta = np.sqrt((ior - 1.0) * (ior + 1.0)) / ior
    return np.exp(-(1.0 - kt) * radius * (1.0 + cos_delta))


def cap_overlap_fraction(alpha, beta, gamma):
    """Share of a spherical cap (angular radius α) covered by another (β) at γ apart.

    Both caps live on the unit sphere of directions around the light; because an
    isotropic light's flux is uniform in solid angle, this is the share of the
    lens's flux that the obstacle blocks. Exact spherical geometry, written with
    atan2 of stable quantities (no acos of numbers near 1): the overlap is the
    sum of two "cap segments" cut by the plane through both circles' intersection.
    Works elementwise on broadcastable arrays; caps must have radius < π/2.
    """
    alpha, beta, gamma = np.broadcast_arrays(*(np.asarray(x, dtype=float)
                                               for x in (alpha, beta, gamma)))
    out = np.zeros(alpha.shape)
    cap_a = _cap_area(alpha)
    inside = beta >= gamma + alpha                      # obstacle covers the lens
    contained = (alpha >= gamma + beta) & ~inside       # obstacle within the lens
    partial = (alpha + beta > gamma) & ~inside & ~contained
    out[inside] = 1.0
    out[contained] = _cap_area(beta[contained]) / cap_a[contained]
    if np.any(partial):
        a, b, g = alpha[partial], beta[partial], gamma[partial]
        out[partial] = (_segment_area(a, b, g) + _segment_area(b, a, g)) / cap_a[partial]
    return np.clip(out, 0.0, 1.0)


def _cap_area(a):
    """Solid angle of a cap of angular radius a: `2π(1 − cos a) = 4π sin²(a/2)`."""
    return 4.0 * np.pi * np.sin(0.5 * a) ** 2


def _segment_area(a, b, g):
    """Solid angle of the part of cap `a` beyond the great circle through the two
    points where the rims of caps `a` and `b` (centres γ apart) cross.

    With ω the angle at a's centre between the arc to b's centre and the arc to a
    crossing point (spherical half-angle formula, stable for thin triangles), the
    segment is the sector `2ω(1 − cos a)` minus the isosceles triangle, which
    simplifies to `π − 2ρ − 2ω cos a` with the base angle `ρ = atan2(cos ω,
    cos a sin ω)` (Napier's rule); it also holds for ω > π/2.
    """
    s = 0.5 * (a + b + g)
    sin_half = np.sqrt(np.maximum(np.sin(s - a) * np.sin(s - g), 0.0))
    cos_half = np.sqrt(np.maximum(np.sin(s) * np.sin(s - b), 0.0))
    omega = 2.0 * np.arctan2(sin_half, cos_half)
    cos_a = np.cos(a)
    rho = np.arctan2(np.cos(omega), cos_a * np.sin(omega))
    return np.pi - 2.0 * rho - 2.0 * omega * cos_a


# --------------------------------------------------------------------------- phase 1

@dataclass
class SceneArrays:
    """The numbers phase 1 needs, as arrays (lights L, spheres S)."""
    light_position: np.ndarray      # (L, 3)
    light_brightness: np.ndarray    # (L,)
    light_color: np.ndarray         # (L, 3)
    center: np.ndarray              # (S, 3)
    radius: np.ndarray              # (S,)
    ior: np.ndarray                 # (S,)
    kt: np.ndarray                  # (S,)

    @classmethod
    def from_scene(cls, scene: Scene) -> "SceneArrays":
        def arr(values, shape):
            return np.asarray(values, dtype=float).reshape(shape)
        nl, ns = len(scene.lights), len(scene.objects)
        return cls(
            light_position=arr([l.position for l in scene.lights], (nl, 3)),
            light_brightness=arr([l.brightness for l in scene.lights], (nl,)),
            light_color=arr([l.color for l in scene.lights], (nl, 3)),
            center=arr([s.center for s in scene.objects], (ns, 3)),
            radius=arr([s.radius for s in scene.objects], (ns,)),
            ior=arr([s.surface.ior for s in scene.objects], (ns,)),
            kt=arr([s.surface.transmission for s in scene.objects], (ns,)),
        )


def scene_size(arrays: SceneArrays, valid_lights, valid_spheres) -> float:
    """Diagonal of the box around the valid lights and spheres (at least one radius)."""
    lo, hi = [], []
    if np.any(valid_lights):
        p = arrays.light_position[valid_lights]
        lo.append(p.min(axis=0)); hi.append(p.max(axis=0))
    if np.any(valid_spheres):
        c, r = arrays.center[valid_spheres], arrays.radius[valid_spheres, None]
        lo.append((c - r).min(axis=0)); hi.append((c + r).max(axis=0))
    if not lo:
        return 1.0
    size = float(np.linalg.norm(np.max(hi, axis=0) - np.min(lo, axis=0)))
    if np.any(valid_spheres):
        size = max(size, float(arrays.radius[valid_spheres].max()))
    return size if size > 0 and math.isfinite(size) else 1.0


def _sphere_problem(center, radius, ior, kt) -> str | None:
    """Why a sphere cannot be a lens, or None (the reasons reported per pair)."""
    if not (np.all(np.isfinite(center)) and math.isfinite(radius)
            and math.isfinite(ior) and math.isfinite(kt)):
        return "invalid sphere (non-finite number)"
    if radius <= 0:
        return f"invalid sphere (radius {radius:g} ≤ 0)"
    if kt <= 0:
        return "opaque (kt = 0)"
    if kt > 1:
        return f"invalid transmission (kt = {kt:g} > 1)"
    if ior <= 1:
        return f"not a converging lens (n = {ior:g} ≤ 1)"
    return None


def compute_phase1(scene: Scene | SceneArrays,
                   collimation_ratio: float = COLLIMATION_RATIO) -> Phase1Result:
    """All secondary light sources of a scene, and every pair that yields none.

    `collimation_ratio`: an image farther from its lens than this many times the
    scene's size is represented as a collimated beam (a cylinder of radius R_C from
    the back vertex). Across the switch the light a receiver in the scene gets
    changes by about 1/collimation_ratio: the cone's apex is that far away and its
    half-angle that small, so its footprint is R_C to that precision.
    """
    a = scene if isinstance(scene, SceneArrays) else SceneArrays.from_scene(scene)
    n_lights, n_spheres = len(a.light_brightness), len(a.radius)

    valid_light = (np.all(np.isfinite(a.light_position), axis=1)
                   & np.isfinite(a.light_brightness)
                   & np.all(np.isfinite(a.light_color), axis=1))
    sphere_problem = [_sphere_problem(a.center[i], a.radius[i], a.ior[i], a.kt[i])
                      for i in range(n_spheres)]
    valid_sphere = np.array([p is None or not p.startswith("invalid sphere")
                             for p in sphere_problem], dtype=bool)
    lens_ids = np.array([i for i, p in enumerate(sphere_problem) if p is None], dtype=int)
    far = collimation_ratio * scene_size(a, valid_light, valid_sphere)

    result = Phase1Result()
    for j in range(n_lights):
        if not valid_light[j]:
            result.skipped += [Skipped(j, i, "invalid light (non-finite number)")
                               for i in range(n_spheres)]
            continue
        result.skipped += [Skipped(j, i, p) for i, p in enumerate(sphere_problem)
                           if p is not None]
        _light_sources(a, j, lens_ids, valid_sphere, far, result)
    result.skipped.sort(key=lambda s: (s.light, s.lens))
    return result


def _light_sources(a: SceneArrays, j: int, lens_ids: np.ndarray, valid_sphere,
                   far: float, result: Phase1Result) -> None:
    """Secondary sources of light j through every lens, appended to `result`."""
    light = a.light_position[j]
    # Geometry of every sphere as seen from the light (obstacles need it too).
    to_center = a.center - light                                   # (S, 3)
    dist = np.linalg.norm(to_center, axis=1)
    rad = a.radius
    surface = np.abs(dist - rad) <= SURFACE_TOLERANCE * rad
    inside = (dist < rad) & ~surface
    outside = valid_sphere & ~inside & ~surface
    with np.errstate(invalid="ignore", divide="ignore"):
        direction = to_center / dist[:, None]
    ang = np.where(outside, radial_angle(dist, rad), 0.0)          # α or β
    tlen = np.where(outside, tangent_length(dist, rad), 0.0)       # R_T

    # The light inside or on another sphere: the tangent construction is void.
    enclosing = np.flatnonzero(valid_sphere & (inside | surface))
    ok = []
    for i in lens_ids:
        if inside[i]:
            result.skipped.append(Skipped(j, int(i), "light inside the sphere"))
        elif surface[i]:
            result.skipped.append(Skipped(j, int(i), "light on the sphere's surface"))
        elif enclosing.size:
            k = int(enclosing[0])
            where = "inside" if inside[k] else "on the surface of"
            result.skipped.append(Skipped(j, int(i), f"light {where} sphere {k}"))
        else:
            ok.append(i)
    lenses = np.asarray(ok, dtype=int)
    if lenses.size == 0:
        return

    blocked_by, shadows, unblocked = _obstruction(lenses, direction, ang, tlen, outside)

    # Optics, vectorised over this light's lenses.
    D, R, n = dist[lenses], rad[lenses], a.ior[lenses]
    u = direction[lenses]
    C = a.center[lenses]
    V = ball_lens_power(R, n) - 1.0 / D
    collimated = np.abs(V) * far <= 1.0
    alpha = ang[lenses]
    phi = 2.0 * critical_angle(n) + alpha - 0.5 * np.pi     # exit point, from the back axis
    height = R * np.sin(phi)                                 # d of eq. 5.10 (signed)
    theta = np.where(collimated, 0.0,
                     np.arctan2(np.abs(height * V), np.abs(R * np.cos(phi) * V - 1.0)))
    with np.errstate(divide="ignore"):
        image = np.where(collimated, 0.0, 1.0 / np.where(collimated, 1.0, V))
    position = np.where(collimated[:, None], C + R[:, None] * u, C + image[:, None] * u)
    factor = brightness_factor(R, n, a.kt[lenses])
    intensity = a.light_brightness[j] * factor
    color = tuple(float(c) for c in a.light_color[j])

    for t, i in enumerate(lenses):
        if blocked_by[t] >= 0:
            result.skipped.append(
                Skipped(j, int(i), f"totally blocked by sphere {int(blocked_by[t])}"))
            continue
        is_col = bool(collimated[t])
        kind = COLLIMATED if is_col else (REAL if V[t] > 0 else VIRTUAL)
        result.sources.append(SecondarySource(
            light=j, lens=int(i), kind=kind,
            position=position[t].copy(), axis=u[t].copy(),
            spread_deg=float(np.degrees(theta[t])),
            cylinder_radius=float(abs(height[t])) if is_col else None,
            intensity=float(intensity[t]), color=color,
            full=not shadows[t], shadow_list=shadows[t],
            brightness_factor=float(factor[t]), distance=float(D[t]),
            lens_center=C[t].copy(), lens_radius=float(R[t]), ior=float(n[t]),
            vergence=float(V[t]),
            image_distance=None if is_col else float(image[t]),
            magnification=None if is_col else float(-image[t] / D[t]),
            alpha_deg=float(np.degrees(alpha[t])),
            unblocked_fraction=float(unblocked[t]),
        ))


def _obstruction(lenses, direction, ang, tlen, outside):
    """Thesis §5.5 for one light: blockers of each lens, vectorised lens × sphere.

    Sphere k blocks (part of) lens i iff it is nearer the light (R_T,k < R_T,i) and
    their angular discs overlap (α + β ≥ γ); it blocks all of it iff β ≥ γ + α.
    Returns (index of the nearest total blocker or −1, sorted shadow list, share
    of the lens's flux left unblocked) per lens. The unblocked share treats
    blockers as independent (product of their single coverings).
    """
    n_lens, n_sph = lenses.size, direction.shape[0]
    blocked_by = np.full(n_lens, -1, dtype=int)
    shadows: list[list[int]] = [[] for _ in range(n_lens)]
    unblocked = np.ones(n_lens)
    obstacles = np.flatnonzero(outside)
    if obstacles.size <= 1:
        return blocked_by, shadows, unblocked
    step = max(1, _BLOCK_CELLS // obstacles.size)
    w_k, beta, t_k = direction[obstacles], ang[obstacles], tlen[obstacles]
    for start in range(0, n_lens, step):
        rows = lenses[start:start + step]
        alpha = ang[rows][:, None]
        gamma = angle_between(direction[rows][:, None, :], w_k[None, :, :])
        nearer = (t_k[None, :] < tlen[rows][:, None]) & (obstacles[None, :] != rows[:, None])
        blocks = nearer & (alpha + beta[None, :] >= gamma)
        total = blocks & (beta[None, :] >= gamma + alpha)
        for r in np.flatnonzero(blocks.any(axis=1)):
            t = start + r
            ks = np.flatnonzero(blocks[r])
            tk = np.flatnonzero(total[r])
            if tk.size:
                blocked_by[t] = int(obstacles[tk[np.argmin(t_k[tk])]])
                unblocked[t] = 0.0
                continue
            shadows[t] = [int(k) for k in obstacles[ks]]
            cover = cap_overlap_fraction(alpha[r, 0], beta[ks], gamma[r, ks])
            unblocked[t] = float(np.prod(1.0 - cover))
    return blocked_by, shadows, unblocked
