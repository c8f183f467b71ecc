"""What a mesh that is no sphere is, in plain words, for the report (pure numpy).

`core.lens.sphere_fit` says *whether* a mesh is a sphere, with numbers a user cannot
act on for a glass cylinder ("too coarse for a sphere: faces lie 29 % inside it").
`mesh_shape` names the shape from the same mesh (local space), in this order:

1. **a flat sheet** — its vertices span no volume (smallest bounding-box side under
   `FLAT` of the largest): a pane, a plane;
2. **an open mesh** — not a closed surface: it has edges of one face only (when
   the caller counts them), or its area-weighted face normals do not add up to
   zero (`sphere_fit.CLOSURE_TOLERANCE`);
3. **a box** — `ALIGNED` (99 %) of its area faces along three perpendicular
   directions (the largest face's normal, the largest face's at right angles to it,
   and their cross product), within `ANGLE` (cos 0.999: 2.6°);
4. **a cylinder** (or a prism of more than four sides) — an axis along or across
   which 99 % of its area faces, with more than four directions across it (the
   axis tried: the largest face's normal, and the principal axes of Σ A n nᵀ);
5. **an ellipsoid** (a stretched or squashed sphere; the words give its axes, the
   longest 1: "an ellipsoid (axes 1 : 0.71 : 0.71)") — its bounding box along the
   vertices' principal axes is not a cube (sides differ by more than `STRETCH`, 2 %),
   and scaled to a cube along those axes it passes `sphere_fit.fit_sphere` (vertices
   and faces);
6. otherwise "" (the fit's own reason stands: a coarse sphere, another shape).
"""

from __future__ import annotations

import numpy as np

from .sphere_fit import CLOSURE_TOLERANCE, fit_sphere

FLAT = 1e-4
ANGLE = 1e-3  # 1 − cos of the largest angle between a face and its direction
ALIGNED = 0.99
STRETCH = 0.02
#: Directions across a cylinder's axis: more than a box's four.
MIN_SIDES = 5

FLAT_SHEET = "a flat sheet"
OPEN_MESH = "an open mesh"
BOX = "a box"
CYLINDER = "a cylinder"
ELLIPSOID = "an ellipsoid"


def mesh_shape(vertices, face_centers, face_normals, face_areas, open_edges=0) -> str:
    """The plain word for a mesh's shape (module docstring), or ""; `open_edges`:
    how many of its edges border one face only (0: none, or not counted)."""
    v = np.asarray(vertices, dtype=float).reshape(-1, 3)
    if len(v) < 3 or not np.all(np.isfinite(v)):
        return ""
    extent = v.max(axis=0) - v.min(axis=0)
    if extent.max() > 0 and extent.min() <= FLAT * extent.max():
        return FLAT_SHEET
    n = np.asarray(face_normals, dtype=float).reshape(-1, 3)
    a = np.asarray(face_areas, dtype=float).reshape(-1)
    keep = (a > 0) & np.all(np.isfinite(n), axis=1)
    n, a = n[keep], a[keep]
    total = a.sum()
    if not total > 0:
        return ""
    if open_edges or np.linalg.norm((n * a[:, None]).sum(axis=0)) > CLOSURE_TOLERANCE * total:
        return OPEN_MESH
    if _is_box(n, a, total):
        return BOX
    if _is_cylinder(n, a, total):
        return CYLINDER
    axes = _ellipsoid_axes(v, face_centers)
    if axes is not None:
        return f"{ELLIPSOID} (axes {' : '.join(f'{x:.2g}' for x in axes)})"
    return ""


def shape_reason(shape: str) -> str:
    """Why a mesh of `shape` is no lens, for the report."""
    if shape in (FLAT_SHEET, OPEN_MESH):
        return f"{shape}, not a closed surface"
    return f"{shape}, not a sphere"


def _aligned(n, axis):
    """|cos| of each normal against the unit `axis`."""
    return np.abs(n @ axis)


def _is_box(n, a, total) -> bool:
    a1 = n[np.argmax(a)]
    across = _aligned(n, a1) < ANGLE
    if not across.any():
        return False
    a2 = n[across][np.argmax(a[across])]
    a3 = np.cross(a1, a2)
    a3 /= np.linalg.norm(a3)
    best = np.max(np.column_stack([_aligned(n, x) for x in (a1, a2, a3)]), axis=1)
    return a[best > 1.0 - ANGLE].sum() >= ALIGNED * total


def _is_cylinder(n, a, total) -> bool:
    m = np.einsum("f,fi,fj->ij", a, n, n)
    _w, vecs = np.linalg.eigh(m)
    for axis in (n[np.argmax(a)], *vecs.T):
        c = _aligned(n, axis)
        along, across = c > 1.0 - ANGLE, c < ANGLE
        if a[along | across].sum() < ALIGNED * total or not across.any():
            continue
        e1 = np.cross(axis, (1.0, 0.0, 0.0) if abs(axis[0]) < 0.9 else (0.0, 1.0, 0.0))
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(axis, e1)
        side = n[across]
        azimuth = np.arctan2(side @ e2, side @ e1)
        if np.unique(np.round(azimuth / ANGLE)).size >= MIN_SIDES:
            return True
    return False


def _ellipsoid_axes(v, face_centers):
    """The axes of the ellipsoid the mesh is, longest first as shares of the longest
    (None: it is none, or a sphere)."""
    mean = v.mean(axis=0)
    _w, axes = np.linalg.eigh(np.cov((v - mean).T))
    q = (v - mean) @ axes
    lo, hi = q.min(axis=0), q.max(axis=0)
    half = 0.5 * (hi - lo)
    if not half.min() > 0 or half.max() <= (1.0 + STRETCH) * half.min():
        return None
    mid = 0.5 * (hi + lo)
    unit = (q - mid) / half
    fc = None
    if face_centers is not None:
        fc = ((np.asarray(face_centers, dtype=float).reshape(-1, 3) - mean) @ axes - mid) / half
    if not fit_sphere(unit, fc).ok:
        return None
    return np.sort(half)[::-1] / half.max()
