"""Is a mesh a sphere? Fit centre and radius to its vertices, vectorised numpy.

The renderer sees the mesh itself, so the test is on the mesh (in the object's
local space; `to_world` then applies the object's matrix):

1. **vertices** — algebraic least-squares fit ``|p|² = 2 c·p + (r² − |c|²)`` (linear
   in ``c`` and ``k = r² − |c|²``), on coordinates centred and scaled for
   conditioning. Every vertex must lie within ``VERTEX_TOLERANCE`` (1 %) of the
   radius from the fitted sphere.
2. **faces** — the flat faces lie inside the sphere of their vertices; a face's
   centre may be at most ``FACE_TOLERANCE`` (7 % of the radius) inside it. This
   rejects polyhedra whose corners lie on a sphere (a cube: 42 %, an icosahedron:
   21 %) and accepts Blender's default UV sphere (32 × 16: 1.0 %), its default
   icosphere (subdivisions 2: 6.6 %), a UV sphere of 12 × 6 (6.5 %) and anything
   finer. (A subdivided cube is not a sphere: its vertices deviate by 2 %.)
3. **closed** — the area-weighted face normals of a closed surface add up to zero;
   ``|Σ n A| ≤ CLOSURE_TOLERANCE`` (1 %) of the total area rejects caps and
   hemispheres, whose vertices also lie on a sphere.

A cheap first test rejects meshes whose bounding box is far from a cube (floors,
walls) before any fit. `to_world` accepts rotations, reflections, translations
and a uniform scale: the three axes of the matrix must have the same length
within ``SCALE_TOLERANCE`` (0.1 %) and be perpendicular to that precision.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

VERTEX_TOLERANCE = 0.01
FACE_TOLERANCE = 0.07
CLOSURE_TOLERANCE = 0.01
SCALE_TOLERANCE = 1e-3
#: Bounding-box extents of a sphere mesh are all about 2r (≥ 2r cos(π/n) for n
#: segments); a box whose smallest side is under this share of its largest is
#: not a sphere.
BOX_RATIO = 0.7
MIN_VERTICES = 6


@dataclass
class SphereFit:
    ok: bool
    center: np.ndarray  # (3,), local space
    radius: float
    reason: str = ""  # why it is not a sphere (empty when ok)
    vertex_deviation: float = 0.0  # max |dist − r| / r over the vertices
    face_depth: float = 0.0  # max (r − |face centre − c|) / r over the faces


def _fail(reason, center=None, radius=0.0, **kw) -> SphereFit:
    c = np.zeros(3) if center is None else np.asarray(center, dtype=float)
    return SphereFit(False, c, float(radius), reason, **kw)


def least_squares_sphere(points) -> tuple[np.ndarray, float] | None:
    """Centre and radius of the least-squares (algebraic) sphere through `points`
    (N × 3), or None when the points do not determine one (fewer than 4, or all in
    a plane or on a line)."""
    p = np.asarray(points, dtype=float).reshape(-1, 3)
    if len(p) < 4 or not np.all(np.isfinite(p)):
        return None
    mean = p.mean(axis=0)
    q = p - mean
    scale = np.abs(q).max()
    if not scale > 0:
        return None
    q = q / scale
    a = np.column_stack([2.0 * q, np.ones(len(q))])
    b = np.einsum("ij,ij->i", q, q)
    sol, _, rank, sv = np.linalg.lstsq(a, b, rcond=None)
    if rank < 4 or sv[-1] < 1e-9 * sv[0]:
        return None
    c = sol[:3]
    r2 = sol[3] + c @ c
    if not r2 > 0:
        return None
    return mean + scale * c, float(scale * np.sqrt(r2))


def fit_sphere(
    vertices,
    face_centers=None,
    face_normals=None,
    face_areas=None,
    vertex_tolerance=VERTEX_TOLERANCE,
    face_tolerance=FACE_TOLERANCE,
    closure_tolerance=CLOSURE_TOLERANCE,
) -> SphereFit:
    """Decide whether a mesh is a sphere and fit it (local space).

    `vertices` (N × 3); optional face data of the same mesh: `face_centers` (F × 3),
    `face_normals` (F × 3, unit) and `face_areas` (F,). Without face data only the
    vertex test runs.
    """
    v = np.asarray(vertices, dtype=float).reshape(-1, 3)
    if len(v) < MIN_VERTICES:
        return _fail(f"not a sphere: only {len(v)} vertices")
    if not np.all(np.isfinite(v)):
        return _fail("not a sphere: non-finite vertex coordinates")
    extent = v.max(axis=0) - v.min(axis=0)
    if not extent.max() > 0 or extent.min() < BOX_RATIO * extent.max():
        dims = " × ".join(f"{e:.3g}" for e in extent)
        return _fail(f"not a sphere: its bounding box ({dims}) is not a cube")
    fit = least_squares_sphere(v)
    if fit is None:
        return _fail("not a sphere: its vertices do not determine one")
    center, radius = fit
    dev = float(np.max(np.abs(np.linalg.norm(v - center, axis=1) - radius)) / radius)
    if dev > vertex_tolerance:
        return _fail(
            f"not a sphere: vertices deviate up to {100 * dev:.3g} % of the "
            f"radius (tolerance {100 * vertex_tolerance:g} %)",
            center,
            radius,
            vertex_deviation=dev,
        )
    depth = 0.0
    if face_centers is not None:
        fc = np.asarray(face_centers, dtype=float).reshape(-1, 3)
        if len(fc) == 0:
            return _fail("not a sphere: no faces", center, radius, vertex_deviation=dev)
        depth = float(np.max(radius - np.linalg.norm(fc - center, axis=1)) / radius)
        if depth > face_tolerance:
            return _fail(
                f"too coarse for a sphere: faces lie up to {100 * depth:.3g} % "
                f"of the radius inside it (tolerance {100 * face_tolerance:g} %)",
                center,
                radius,
                vertex_deviation=dev,
                face_depth=depth,
            )
    if face_normals is not None and face_areas is not None:
        n = np.asarray(face_normals, dtype=float).reshape(-1, 3)
        a = np.asarray(face_areas, dtype=float).reshape(-1)
        total = a.sum()
        open_share = (
            float(np.linalg.norm((n * a[:, None]).sum(axis=0)) / total) if total > 0 else 1.0
        )
        if open_share > closure_tolerance:
            return _fail(
                f"not a sphere: the surface is not closed (area-weighted normals "
                f"add up to {100 * open_share:.3g} % of its area)",
                center,
                radius,
                vertex_deviation=dev,
                face_depth=depth,
            )
    return SphereFit(True, center, radius, "", dev, depth)


def uniform_scales(matrices) -> np.ndarray:
    """Vectorised `uniform_scale` over a stack of affine matrices (K × 4 × 4 or
    K × 3 × 3): the uniform scale factor of each, NaN where it scales non-uniformly,
    shears or has a zero or non-finite scale."""
    m3 = np.asarray(matrices, dtype=float)[..., :3, :3]
    with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
        gram = np.einsum("...ji,...jk->...ik", m3, m3)  # s² I for a similarity
        s2 = np.trace(gram, axis1=-2, axis2=-1) / 3.0
        ok = np.all(np.isfinite(m3), axis=(-2, -1)) & (s2 > 0) & np.isfinite(s2)
        dev = np.max(
            np.abs(gram / np.where(ok, s2, 1.0)[..., None, None] - np.eye(3)), axis=(-2, -1)
        )
        ok &= dev <= 2 * SCALE_TOLERANCE
        return np.where(ok, np.sqrt(np.where(ok, s2, 1.0)), np.nan)


def uniform_scale(matrix) -> float | None:
    """The uniform scale factor of a 4 × 4 (or 3 × 3) affine matrix, or None when it
    scales non-uniformly or shears (beyond `SCALE_TOLERANCE`)."""
    s = float(uniform_scales(np.asarray(matrix, dtype=float)[None])[0])
    return s if math.isfinite(s) else None


def to_world(center, radius, matrix) -> tuple[np.ndarray, float] | None:
    """A local-space sphere through the object's matrix (4 × 4, column vectors as in
    Blender), or None when the matrix is not a similarity (non-uniform scale)."""
    s = uniform_scale(matrix)
    if s is None:
        return None
    m = np.asarray(matrix, dtype=float)
    c = m[:3, :3] @ np.asarray(center, dtype=float) + m[:3, 3]
    return c, float(radius) * s
