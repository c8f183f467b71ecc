"""Planar receiver patches: the triangles of one object that share one plane.

A caustic layer is a raster over a plane, so the receivers' triangles are grouped by
(object, plane): the unit normal (sign made canonical, so both windings group together)
rounded to ``angle_tol`` and the plane's offset rounded to ``dist_tol``. A table top, a
floor or a wall is one patch however finely it is meshed; a curved object falls apart into
one patch per facet.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .receiver_bvh import ReceiverMesh


@dataclass(frozen=True)
class ReceiverPatch:
    """One planar patch: its ``object_id``, canonical unit ``normal``, plane offset
    ``offset`` (normal · x for x on the plane) and its ``triangles`` (indices)."""

    object_id: int
    normal: np.ndarray
    offset: float
    triangles: np.ndarray


def find_patches(
    mesh: ReceiverMesh, angle_tol: float = 1e-4, dist_tol: float | None = None
) -> tuple[np.ndarray, list[ReceiverPatch]]:
    """Group ``mesh``'s triangles into planar patches.

    Returns ``patch_of_triangle`` ((T,) int, −1 for a degenerate triangle) and the
    patches. ``dist_tol`` defaults to 1e-6 × the mesh's bounding-box diagonal."""
    v = np.asarray(mesh.vertices, dtype=float)
    t = np.asarray(mesh.triangles, dtype=np.int64)
    c = v[t]
    nrm = np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0])
    length = np.linalg.norm(nrm, axis=1)
    ok = length > 0.0
    nrm = nrm / np.where(ok, length, 1.0)[:, None]
    big = np.argmax(np.abs(nrm), axis=1)
    nrm *= np.where(nrm[np.arange(len(nrm)), big] < 0.0, -1.0, 1.0)[:, None]
    off = np.einsum("ij,ij->i", nrm, c.mean(axis=1))
    if dist_tol is None:
        dist_tol = 1e-6 * max(float(np.linalg.norm(np.ptp(v, axis=0))), 1e-300)
    keys = np.column_stack(
        [
            mesh.ids,
            np.round(nrm / angle_tol).astype(np.int64),
            np.round(off / dist_tol).astype(np.int64),
        ]
    )
    patch_of = np.full(len(t), -1, dtype=np.int64)
    if not ok.any():
        return patch_of, []
    # the distinct keys in lexicographic order (np.unique(axis=0)'s, by one lexsort:
    # many times faster than its sort of row records); triangles in index order
    kept = np.nonzero(ok)[0]
    o = kept[np.lexsort(keys[kept].T[::-1])]
    ks = keys[o]
    first = np.ones(len(o), dtype=bool)
    first[1:] = np.any(ks[1:] != ks[:-1], axis=1)
    patch_of[o] = np.cumsum(first) - 1
    uniq = ks[first]
    starts = np.nonzero(first)[0]
    ends = np.append(starts[1:], len(o))
    patches = []
    for p in range(len(uniq)):  # loop over patches, not triangles
        tri = o[starts[p] : ends[p]]
        n = nrm[tri].mean(axis=0)
        n /= np.linalg.norm(n)
        patches.append(ReceiverPatch(int(uniq[p, 0]), n, float(np.mean(off[tri])), tri))
    return patch_of, patches
