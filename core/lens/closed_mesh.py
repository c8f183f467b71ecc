"""Is a glass mesh a closed volume the mesh lens (`core.lens.mesh`) can trace, and the
mesh as that lens takes it, in world space (pure numpy).

A refracting mesh is a lens here when light that enters it must leave it: every edge
is in exactly two triangles, the two walk it in opposite directions (consistently
oriented), and the normals point outward (positive enclosed volume). Vertices at the
same position are one vertex for this test (a mesh split along sharp edges or seams is
still closed). What fails says why, in the words of `problem`:

* an edge of one triangle only: an open mesh (a water surface, a pane: planned);
* an edge of three or more: non-manifold (faces fanned on one edge, inner faces);
* an edge walked twice the same way: faces flipped against their neighbours;
* a negative volume: the normals point inward (Cycles renders it as a bubble of air
  in glass); Recalculate Outside fixes it.

`world_mesh` places a local mesh with an object's matrix: vertices by the matrix,
shading normals by its inverse transpose (renormalised), and a mirroring matrix
reverses each triangle's order so that the faces stay outward.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .glass import WATER_IOR_RANGE

OPEN_REASON = (
    "open mesh: a surface, not a glass volume (open glass is water only with water's "
    f"index, {WATER_IOR_RANGE[0]:.2f}–{WATER_IOR_RANGE[1]:.2f})"
)
INWARD_REASON = (
    "its normals point inward (Cycles renders it as air inside glass): "
    "Mesh › Normals › Recalculate Outside"
)
NO_FACES_REASON = "no faces"
ZERO_SIZE_REASON = "zero size: nothing is rendered"


def non_manifold_reason(edges: int) -> str:
    return (
        f"non-manifold mesh ({edges} edge{'s' if edges != 1 else ''} in more than two "
        "faces): not one closed glass volume"
    )


def flipped_reason(edges: int) -> str:
    return (
        f"faces flipped against their neighbours ({edges} edge{'s' if edges != 1 else ''}): "
        "Mesh › Normals › Recalculate Outside"
    )


@dataclass(frozen=True)
class LocalMesh:
    """A mesh as Blender renders it, in its object's space: vertices (V, 3), loop
    triangles (T, 3) into them, the shading normal at each triangle corner (T, 3, 3:
    smooth, flat, Smooth by Angle, custom normals alike)."""

    vertices: np.ndarray
    triangles: np.ndarray
    corner_normals: np.ndarray

    @property
    def n_triangles(self) -> int:
        return len(self.triangles)


@dataclass(frozen=True)
class WorldMesh:
    """A mesh lens in world space: `LocalMesh`'s arrays placed, and its bounding
    sphere (centre of the box, radius to the farthest vertex)."""

    vertices: np.ndarray
    triangles: np.ndarray
    corner_normals: np.ndarray
    center: np.ndarray
    radius: float

    @property
    def n_triangles(self) -> int:
        return len(self.triangles)


def welded(vertices, triangles) -> np.ndarray:
    """`triangles` with vertices at one position given one index (the first)."""
    v = np.ascontiguousarray(np.asarray(vertices, dtype=float).reshape(-1, 3) + 0.0)  # −0 → 0
    _u, first, inverse = np.unique(v, axis=0, return_index=True, return_inverse=True)
    return first[inverse.reshape(-1)][np.asarray(triangles, dtype=np.int64)]


def problem(vertices, triangles) -> str:
    """Why the mesh is no closed, outward glass volume ("" when it is one; module
    docstring). Degenerate triangles (two corners at one position) are ignored."""
    t = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    if not len(t):
        return NO_FACES_REASON
    v = np.asarray(vertices, dtype=float).reshape(-1, 3)
    if not np.ptp(v[t.reshape(-1)], axis=0).max() > 0.0:
        return ZERO_SIZE_REASON
    w = welded(vertices, t)
    w = w[(w[:, 0] != w[:, 1]) & (w[:, 1] != w[:, 2]) & (w[:, 2] != w[:, 0])]
    if len(w) < 4:
        return OPEN_REASON
    a, b = w.reshape(-1), w[:, [1, 2, 0]].reshape(-1)
    n = int(max(a.max(), b.max())) + 1
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    _keys, uses = np.unique(lo * n + hi, return_counts=True)
    if np.any(uses == 1):
        return OPEN_REASON
    many = int(np.count_nonzero(uses > 2))
    if many:
        return non_manifold_reason(many)
    _directed, twice = np.unique(a * n + b, return_counts=True)
    same_way = int(np.count_nonzero(twice > 1))
    if same_way:
        return flipped_reason(same_way)
    if signed_volume(vertices, t) <= 0.0:
        return INWARD_REASON
    return ""


def signed_volume(vertices, triangles) -> float:
    """The enclosed volume (positive for outward faces), by the divergence theorem."""
    v = np.asarray(vertices, dtype=float).reshape(-1, 3)
    p = v[np.asarray(triangles, dtype=np.int64)]
    p = p - v.mean(axis=0)  # about the middle: no cancellation far from the origin
    return float(np.einsum("ti,ti->t", p[:, 0], np.cross(p[:, 1], p[:, 2])).sum() / 6.0)


def mean_chord(vertices, triangles) -> float:
    """The mean chord of a convex body, 4 V / S (Cauchy): the path inside the glass
    that its colour's absorption is taken over when it is not traced per ray."""
    v = np.asarray(vertices, dtype=float).reshape(-1, 3)
    p = v[np.asarray(triangles, dtype=np.int64)]
    area = 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1).sum()
    return 4.0 * abs(signed_volume(v, triangles)) / area if area > 0 else 0.0


def world_mesh(local: LocalMesh, matrix) -> WorldMesh:
    """`local` placed by the 4 × 4 `matrix` (module docstring)."""
    m = np.asarray(matrix, dtype=float).reshape(4, 4)
    lin = m[:3, :3]
    v = np.asarray(local.vertices, dtype=float) @ lin.T + m[:3, 3]
    normal_map = np.linalg.inv(lin).T
    n = np.asarray(local.corner_normals, dtype=float) @ normal_map.T
    n /= np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-300)
    t = np.asarray(local.triangles, dtype=np.int64)
    if np.linalg.det(lin) < 0.0:  # a mirror turns the faces inside out: reverse them
        t = t[:, ::-1]
        n = n[:, ::-1]
    lo, hi = v.min(axis=0), v.max(axis=0)
    center = 0.5 * (lo + hi)
    radius = float(np.sqrt(((v - center) ** 2).sum(axis=1).max()))
    return WorldMesh(v, np.ascontiguousarray(t), np.ascontiguousarray(n), center, radius)
