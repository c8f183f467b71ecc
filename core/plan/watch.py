"""Where a plan's light goes, for live update's filter (`blender/commands/live_update.py`):
an edit of an object that touches none of it cannot change the plan, so it costs
nothing.

A plan is made from (1) the light from every primary light to every lens (phase
1's obstruction: a blocker there changes a source), (2) the rays the planner casts
along each lit lens' axis to find the receiver, its distance and tilt, and the free
distance behind the lens (`planning.receiver_rays`, `planning.free_distances`), and
(3) for the Caustic layer, the traced beam from each lens to the receiver patches
it landed on. Each is covered by `Capsules` (segments with a radius, conservative:
a box near one is taken to touch it).
Not covered: rays of the layer's beam that missed every receiver, and the faintest
texels holding ``FAINT_SHARE`` of each raster's flux (a marble's rim rays reach
whatever stands around it; moving such an object leaves that invisible light where
it was until the next update that counts).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..scene.primaries import AREA, KINDS, SUN

#: The capsule along a lens' axis, in lens radii: the planner's rays run
#: ``RIM_OFFSET`` (1.02) R from the axis at most.
AXIS_MARGIN = 1.05
#: The faintest texels of a raster holding this share of its flux are not followed.
FAINT_SHARE = 1e-3
#: A raster's lit texels are followed in about this many cells along its longest side.
CLUSTER_CELLS = 8
#: Box × capsule pairs tested in one numpy pass (a few tens of MB of temporaries).
PAIRS_AT_ONCE = 1 << 18


@dataclass
class Capsules:
    """Segments ``a[k]`` → ``b[k]``, each with the radius ``radius[k]``."""

    a: np.ndarray  # (K, 3)
    b: np.ndarray  # (K, 3)
    radius: np.ndarray  # (K,)

    @classmethod
    def empty(cls) -> Capsules:
        return cls(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0))

    @classmethod
    def join(cls, parts) -> Capsules:
        parts = [p for p in parts if len(p.radius)]
        if not parts:
            return cls.empty()
        return cls(
            np.concatenate([p.a for p in parts]),
            np.concatenate([p.b for p in parts]),
            np.concatenate([p.radius for p in parts]),
        )

    def __len__(self) -> int:
        return len(self.radius)

    def touches(self, lo, hi) -> bool:
        """Does any capsule come within its radius of the box [lo, hi] (axis-aligned;
        tested as the segment against the box grown by the radius on every side: a
        little more than the capsule, never less)?"""
        lo, hi = np.asarray(lo, float).reshape(1, 3), np.asarray(hi, float).reshape(1, 3)
        return bool(self.touching(lo, hi)[0])

    def touching(self, lo, hi) -> np.ndarray:
        """`touches` for many boxes (N, 3) at once: (N,) bool."""
        lo, hi = np.asarray(lo, float).reshape(-1, 3), np.asarray(hi, float).reshape(-1, 3)
        out = np.zeros(len(lo), bool)
        if not len(self.radius):
            return out
        step = max(1, PAIRS_AT_ONCE // len(self.radius))
        for k in range(0, len(lo), step):
            out[k : k + step] = self._touching(lo[k : k + step], hi[k : k + step])
        return out

    def _touching(self, lo, hi) -> np.ndarray:
        r = self.radius[None, :, None]
        lo, hi = lo[:, None, :] - r, hi[:, None, :] + r  # (N, K, 3)
        a, d = self.a[None], (self.b - self.a)[None]
        with np.errstate(divide="ignore", invalid="ignore"):
            t1 = (lo - a) / d
            t2 = (hi - a) / d
        flat = np.abs(d) < 1e-300
        inside = (a >= lo) & (a <= hi)
        # An axis the segment runs across: its slab's entry and exit; one it runs
        # along: all or nothing, by where it lies.
        t_in = np.where(flat, np.where(inside, -np.inf, np.inf), np.minimum(t1, t2))
        t_out = np.where(flat, np.where(inside, np.inf, -np.inf), np.maximum(t1, t2))
        enter = np.maximum(t_in.max(axis=2), 0.0)
        leave = np.minimum(t_out.min(axis=2), 1.0)
        return np.any(enter <= leave, axis=1)


def light_to_lens(origins, sizes, suns, centers, radii, reach) -> Capsules:
    """Every light × every lens: from the light (a sun: from ``reach`` back along its
    direction) to the lens, as wide as the wider of the light and the lens.
    `origins` (L, 3): positions, or a sun's direction of travel; `sizes` (L,): the
    light's radius (an area light's half diagonal); `suns` (L,) bool."""
    origins = np.asarray(origins, float).reshape(-1, 3)
    centers = np.asarray(centers, float).reshape(-1, 3)
    n_l, n_s = len(origins), len(centers)
    if not n_l or not n_s:
        return Capsules.empty()
    suns = np.asarray(suns, bool)
    start = np.where(
        suns[:, None, None],
        centers[None, :, :] - reach * origins[:, None, :],
        origins[:, None, :],
    )
    width = np.maximum(np.asarray(sizes, float)[:, None], np.asarray(radii, float)[None, :])
    return Capsules(
        start.reshape(-1, 3),
        np.broadcast_to(centers[None], (n_l, n_s, 3)).reshape(-1, 3).copy(),
        width.reshape(-1),
    )


def along_axes(centers, radii, axes, reach) -> Capsules:
    """Through each lit lens (one row per source), along its beam's axis, ``reach``
    both ways: the planner's rays beyond the lens (the receiver, its distance and
    tilt: `planning.receiver_rays`) and before it (the free distance behind it:
    `planning.free_distances`) start within ``RIM_OFFSET`` R of the axis and run
    along it, so a capsule ``AXIS_MARGIN`` R wide holds them."""
    centers = np.asarray(centers, float).reshape(-1, 3)
    axes = np.asarray(axes, float).reshape(-1, 3)
    axes = reach * axes / np.linalg.norm(axes, axis=1)[:, None]
    return Capsules(centers - axes, centers + axes, AXIS_MARGIN * np.asarray(radii, float))


def light_extents(primaries) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Of `primaries` (`core.scene.primaries.PrimaryArrays`): (origins, sizes, suns)
    for `light_to_lens`: a sun's origin is its direction of travel; a light's size is
    its radius (an area light's half diagonal)."""
    suns = primaries.kind == KINDS.index(SUN)
    area = primaries.kind == KINDS.index(AREA)
    half_diagonal = 0.5 * np.hypot(primaries.size[:, 0], primaries.size[:, 1])
    sizes = np.where(area, half_diagonal, np.where(suns, 0.0, primaries.radius))
    origins = np.where(suns[:, None], primaries.direction, primaries.position)
    return origins, sizes, suns


def landings(centers, radii, spots, spot_radii) -> Capsules:
    """From each lens (`centers`, `radii`: L rows) to each spot its beam lit
    (`spots`, `spot_radii`: S rows): L × S capsules, each as wide as the wider end."""
    centers = np.asarray(centers, float).reshape(-1, 1, 3)
    spots = np.asarray(spots, float).reshape(1, -1, 3)
    n_l, n_s = centers.shape[0], spots.shape[1]
    width = np.maximum(
        np.asarray(radii, float).reshape(-1, 1), np.asarray(spot_radii, float).reshape(1, -1)
    )
    return Capsules(
        np.broadcast_to(centers, (n_l, n_s, 3)).reshape(-1, 3).copy(),
        np.broadcast_to(spots, (n_l, n_s, 3)).reshape(-1, 3).copy(),
        width.reshape(-1),
    )


def lit_texels(flux, rows, share=FAINT_SHARE) -> np.ndarray:
    """The rows of the brightest texels holding all but `share` of the `flux` (per
    texel, `rows` parallel to it): the rest, faint, is not followed."""
    flux = np.asarray(flux, float).reshape(-1)
    total = flux.sum()
    if total <= 0:
        return np.zeros(0, dtype=np.asarray(rows).dtype)
    order = np.argsort(flux)[::-1]
    count = int(np.searchsorted(np.cumsum(flux[order]), (1.0 - share) * total)) + 1
    return np.asarray(rows)[np.sort(order[:count])]


def clusters(points, radii, cells=CLUSTER_CELLS) -> tuple[np.ndarray, np.ndarray]:
    """Spheres (`points`, `radii`) gathered on a grid of about `cells` cells along
    the longest side of their box: per occupied cell, one sphere holding all of its
    own (centre: the middle of their centres' box)."""
    points = np.asarray(points, float).reshape(-1, 3)
    radii = np.asarray(radii, float).reshape(-1)
    if not len(points):
        return points, radii
    lo, hi = points.min(axis=0), points.max(axis=0)
    size = float((hi - lo).max()) / cells
    if size <= 0:
        return points[:1], np.array([radii.max()])
    keys = np.floor((points - lo) / size).astype(np.int64)
    _, group = np.unique(keys, axis=0, return_inverse=True)
    group = group.reshape(-1)
    n = int(group.max()) + 1
    g_lo = np.full((n, 3), np.inf)
    g_hi = np.full((n, 3), -np.inf)
    np.minimum.at(g_lo, group, points)
    np.maximum.at(g_hi, group, points)
    centers = 0.5 * (g_lo + g_hi)
    reach = np.linalg.norm(points - centers[group], axis=1) + radii
    out = np.zeros(n)
    np.maximum.at(out, group, reach)
    return centers, out


def bounding_sphere(points) -> tuple[np.ndarray, float]:
    """A sphere around `points` (N, 3): the box's centre and the farthest point."""
    points = np.asarray(points, float).reshape(-1, 3)
    c = 0.5 * (points.min(axis=0) + points.max(axis=0))
    return c, float(np.sqrt(((points - c) ** 2).sum(axis=1).max()))
