"""First hits of a bundle of rays (close-together origins, one direction) against
spheres and axis-aligned boxes, vectorised in numpy.

Pure (numpy only). `operators/occluders.py` uses these for the exact spheres and
as the boxes' pre-test, before it casts against the meshes inside the boxes.
"""

from __future__ import annotations

import numpy as np


def sphere_hits(
    centers: np.ndarray, radii: np.ndarray, origins: np.ndarray, d: np.ndarray
) -> np.ndarray:
    """Nearest t > 0 per origin (k × 3) along the unit `d` against all spheres
    (inf: none). A ray starting inside a sphere hits its far side."""
    if radii.size == 0:
        return np.full(len(origins), np.inf)
    # Relative to the first origin (the origins are close together), so that
    # |oc|² = |C'|² − 2 C'·o + |o|² keeps its precision far from the world origin.
    ref = origins[0]
    o = origins - ref  # (k, 3), small
    c = centers - ref  # (S, 3)
    cd = c @ d  # (S,)
    r2 = radii**2
    # Only spheres ahead of the origins and near the rays' line can be hit.
    reach = float(np.linalg.norm(o, axis=1).max())
    perp2 = np.einsum("sj,sj->s", c, c) - cd * cd
    near_line = (cd + radii + reach > 0) & (perp2 <= (radii + reach) ** 2)
    idx = np.flatnonzero(near_line)
    out = np.full(len(origins), np.inf)
    if idx.size == 0:
        return out
    c, cd, r2 = c[idx], cd[idx], r2[idx]
    b = cd[None, :] - (o @ d)[:, None]  # (k, S')
    oc2 = (
        np.einsum("sj,sj->s", c, c)[None, :]
        - 2.0 * (o @ c.T)
        + np.einsum("kj,kj->k", o, o)[:, None]
    )
    disc = b * b - (oc2 - r2[None, :])
    with np.errstate(invalid="ignore"):
        root = np.sqrt(disc)
        near, far = b - root, b + root
        t = np.where(near > 0, near, np.where(far > 0, far, np.inf))
    t = np.where(disc >= 0, t, np.inf)
    return np.minimum(out, t.min(axis=1))


def box_entries(
    box_lo: np.ndarray, box_hi: np.ndarray, origins: np.ndarray, d: np.ndarray, limit: float
) -> tuple[np.ndarray, np.ndarray]:
    """Slab test of every ray (k origins, direction `d`) against every box (N):
    (enter: k × N distance where the ray enters the box, hit: k × N whether it
    meets the box ahead of its origin, entering within `limit`)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = np.where(d != 0, 1.0 / d, np.inf)
        t0 = (box_lo[None] - origins[:, None]) * inv  # (k, N, 3)
        t1 = (box_hi[None] - origins[:, None]) * inv
        t0 = np.where(np.isnan(t0), -np.inf, t0)
        t1 = np.where(np.isnan(t1), np.inf, t1)
    enter = np.minimum(t0, t1).max(axis=2)
    leave = np.maximum(t0, t1).min(axis=2)
    hit = (leave >= np.maximum(enter, 0.0)) & (enter <= limit)
    return enter, hit
