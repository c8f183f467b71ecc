"""Receivers as plain triangle arrays over the generic numpy BVH of
`core.shared.triangle_bvh` (built and cast there; this module names the receivers' mesh).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..shared import triangle_bvh
from ..shared.triangle_bvh import Hits, TriangleBvh, intersect, moller_trumbore, no_hits, ray_arrays

__all__ = ["Hits", "ReceiverMesh", "TriangleBvh", "build_bvh", "intersect", "no_hits", "ray_arrays"]


@dataclass(frozen=True)
class ReceiverMesh:
    """Triangles that receive caustics: ``vertices`` (V, 3), ``triangles`` (T, 3) vertex
    indices, optional ``uvs`` (V, 2) per vertex, optional ``object_ids`` (T,) telling
    which object each triangle belongs to (the lens' own sphere must not be in it)."""

    vertices: np.ndarray
    triangles: np.ndarray
    uvs: np.ndarray | None = None
    object_ids: np.ndarray | None = None

    @property
    def ids(self) -> np.ndarray:
        if self.object_ids is None:
            return np.zeros(len(self.triangles), dtype=np.int64)
        return np.asarray(self.object_ids, dtype=np.int64)


def build_bvh(mesh: ReceiverMesh, leaf_size: int = 4) -> TriangleBvh:
    """Linear BVH of the receivers' triangles (`core.shared.triangle_bvh`)."""
    return triangle_bvh.build_bvh(mesh.vertices, mesh.triangles, leaf_size)


#: The two-sided ray–triangle test, under its old name here (the tests' brute force).
_moller_trumbore = moller_trumbore
