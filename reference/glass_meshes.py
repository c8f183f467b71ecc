"""Closed triangle meshes of the analytic glass shapes (:mod:`.shapes`), the same
geometry handed to Blender and mitsuba and traced as :class:`.shapes.TriangleMesh`.

Each builder returns ``(vertices, triangles, vertex_normals)``: outward winding,
vertices on the analytic surface (curved surfaces are inscribed), and the analytic
surface's normal at each vertex (for smooth shading; a vertex on a sharp edge gets
one copy per face it borders, so its normals stay the face's own).
"""

from __future__ import annotations

import math

import numpy as np

from .shapes import rotation_to
from .vectors import unit

__all__ = ["ellipsoid_mesh", "biconvex_mesh", "rod_mesh", "box_mesh", "corner_normals"]


def corner_normals(triangles, vertex_normals):
    """Per-corner normals ``(f, 3, 3)`` of :class:`.shapes.TriangleMesh`."""
    return np.asarray(vertex_normals, float)[np.asarray(triangles)]


def _grid_tris(rows, cols, wrap=True):
    """Quads between ``rows`` rings of ``cols`` vertices (ring-major indices)."""
    tris = []
    for i in range(rows - 1):
        for j in range(cols if wrap else cols - 1):
            a, b = i * cols + j, i * cols + (j + 1) % cols
            c, d = a + cols, b + cols
            tris += [(a, c, d), (a, d, b)]
    return np.array(tris, np.int64)


def _orient(v, f):
    """Flip the winding if the signed volume is negative (outward faces)."""
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    if np.einsum("ij,ij->i", a, np.cross(b - a, c - a)).sum() < 0.0:
        return f[:, ::-1].copy()
    return f


def ellipsoid_mesh(center, axes, rotation=None, n_lat=32, n_lon=64):
    """A latitude–longitude ellipsoid (poles shared)."""
    rot = np.eye(3) if rotation is None else np.asarray(rotation, float)
    ax = np.asarray(axes, float)
    lat = np.linspace(0.0, math.pi, n_lat + 1)[1:-1]
    lon = np.linspace(0.0, 2 * math.pi, n_lon, endpoint=False)
    la, lo = np.meshgrid(lat, lon, indexing="ij")
    s = np.stack([np.sin(la) * np.cos(lo), np.sin(la) * np.sin(lo), np.cos(la)], -1).reshape(-1, 3)
    s = np.concatenate([[[0, 0, 1.0]], s, [[0, 0, -1.0]]])
    v = (s * ax) @ rot.T + np.asarray(center, float)
    nrm = unit((s / ax) @ rot.T)
    ring = 1 + _grid_tris(n_lat - 1, n_lon)
    top = np.array([(0, 1 + j, 1 + (j + 1) % n_lon) for j in range(n_lon)])
    last = len(v) - 1
    base = 1 + (n_lat - 2) * n_lon
    bottom = np.array([(last, base + (j + 1) % n_lon, base + j) for j in range(n_lon)])
    f = _orient(v, np.concatenate([top, ring, bottom]))
    return v, f, nrm


def _revolve(profile, normals, axis_rot, center, n_seg, sharp):
    """A solid of revolution from a profile of ``(r, z)`` points from the +z pole to
    the -z pole (both on the axis, r = 0) and their ``(nr, nz)`` normals; ``sharp``:
    profile indices where a crease is (each gets two rings: one per side)."""
    pr, pn = [], []
    for i, (p, n) in enumerate(zip(profile, normals, strict=True)):
        pr.append(p)
        pn.append(n[0])
        if i in sharp:
            pr.append(p)
            pn.append(n[1])
    pr, pn = np.array(pr, float), np.array(pn, float)
    phi = np.linspace(0.0, 2 * math.pi, n_seg, endpoint=False)
    inner = pr[1:-1]
    ring_v = np.stack(
        [
            inner[:, None, 0] * np.cos(phi),
            inner[:, None, 0] * np.sin(phi),
            np.broadcast_to(inner[:, None, 1], (len(inner), n_seg)),
        ],
        -1,
    ).reshape(-1, 3)
    inn = pn[1:-1]
    ring_n = np.stack(
        [
            inn[:, None, 0] * np.cos(phi),
            inn[:, None, 0] * np.sin(phi),
            np.broadcast_to(inn[:, None, 1], (len(inn), n_seg)),
        ],
        -1,
    ).reshape(-1, 3)
    v = np.concatenate([[[0, 0, pr[0, 1]]], ring_v, [[0, 0, pr[-1, 1]]]])
    nrm = np.concatenate([[[0, 0, pn[0, 1]]], ring_n, [[0, 0, pn[-1, 1]]]])
    rows = len(inner)
    tris = [1 + _grid_tris(rows, n_seg)]
    tris.append(np.array([(0, 1 + j, 1 + (j + 1) % n_seg) for j in range(n_seg)]))
    last, base = len(v) - 1, 1 + (rows - 1) * n_seg
    tris.append(np.array([(last, base + (j + 1) % n_seg, base + j) for j in range(n_seg)]))
    f = np.concatenate(tris)
    # drop the degenerate quads between the two rings of a crease (same positions)
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    f = f[np.linalg.norm(np.cross(b - a, c - a), axis=1) > 1e-14]
    v = v @ axis_rot.T + np.asarray(center, float)
    nrm = unit(nrm @ axis_rot.T)
    return v, _orient(v, f), nrm


def _weld(v, f):
    """Merge coincident vertices (a crease's two rings) so that the mesh is closed;
    returns ``(v, f, first)``, ``first`` the kept copy of each old vertex."""
    key = np.round(v / (1e-9 * (np.abs(v).max() + 1.0))).astype(np.int64)
    _, first, inv = np.unique(key, axis=0, return_index=True, return_inverse=True)
    return v[first], inv.reshape(-1)[f], first


def biconvex_mesh(shape, n_rings=24, n_seg=96):
    """:class:`.shapes.Biconvex` as a mesh: each cap a spherical (or flat) cap of
    ``n_rings`` rings, a rim band where ``diameter`` cuts one.  Creases at the rim:
    its vertices are shared (closed mesh); ``vertex_normals`` holds a cap's normal
    there (use flat shading or :func:`corner_normals` per face for the crease)."""
    h = 0.5 * shape.thickness
    rim = shape.edge_radius()
    prof, nrms = [], []
    z_rim = []
    for sgn, r in ((1.0, shape.r_front), (-1.0, shape.r_back)):
        if math.isfinite(r):
            zc = sgn * (h - r)  # the ball's centre on the axis
            z_rim.append(zc + sgn * math.sqrt(max(r * r - rim * rim, 0.0)))
        else:
            z_rim.append(sgn * h)
    pts_f, pts_b = [], []
    for sgn, r, pts in (
        (1.0, shape.r_front, pts_f),
        (-1.0, shape.r_back, pts_b),
    ):
        for i in range(n_rings + 1):
            rho = rim * i / n_rings
            if math.isfinite(r):
                zc = sgn * (h - r)
                z = zc + sgn * math.sqrt(max(r * r - rho * rho, 0.0))
                n = ((rho) / r, (z - zc) / r)
            else:
                z, n = sgn * h, (0.0, sgn)
            pts.append(((rho, z), n))
    prof = [p for p, _ in pts_f] + [p for p, _ in pts_b[::-1]]
    nrms = [(n, n) for _, n in pts_f] + [(n, n) for _, n in pts_b[::-1]]
    if z_rim[0] - z_rim[1] > 1e-9 * rim:  # a cylindrical rim band: its own normals
        k = n_rings
        nrms[k] = (nrms[k][0], (1.0, 0.0))
        nrms[k + 1] = ((1.0, 0.0), nrms[k + 1][1])
        sharp = {k, k + 1}
    else:
        prof.pop(n_rings + 1)
        nrms.pop(n_rings + 1)
        sharp = set()
    v, f, nrm = _revolve(prof, nrms, rotation_to(shape.axis), shape.center, n_seg, sharp)
    v, f, first = _weld(v, f)
    return v, f, nrm[first]


def rod_mesh(shape, n_seg=96, n_len=1):
    """:class:`.shapes.Rod`: side quads and flat caps (fans), sharp rims."""
    h = 0.5 * shape.length
    r = shape.radius
    prof = (
        [(0.0, h), (r, h)]
        + [(r, h - 2 * h * i / n_len) for i in range(1, n_len)]
        + [(r, -h), (0.0, -h)]
    )
    nrms = (
        [((0, 1), (0, 1)), ((0, 1), (1, 0))]
        + [((1, 0), (1, 0))] * (n_len - 1)
        + [((1, 0), (0, -1)), ((0, -1), (0, -1))]
    )
    sharp = {1, len(prof) - 2}
    v, f, nrm = _revolve(prof, nrms, rotation_to(shape.axis), shape.center, n_seg, sharp)
    v, f, first = _weld(v, f)
    return v, f, nrm[first]


def box_mesh(shape):
    """:class:`.shapes.Box`: 12 triangles."""
    rot = np.eye(3) if shape.rotation is None else np.asarray(shape.rotation, float)
    s = 0.5 * np.asarray(shape.size, float)
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float) * s
    v = corners @ rot.T + np.asarray(shape.center, float)
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    f = np.array([t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))], np.int64)
    f = _orient(v, f)
    return v, f, unit(v - np.asarray(shape.center, float))


def revolved_mesh(profile, center=(0.0, 0.0, 0.0), axis=(0.0, 0.0, 1.0), n_seg=64):
    """A closed solid of revolution of a profile of ``(r, z)`` points running from a
    point on the axis (r = 0) to another; vertex normals from the profile's
    neighbouring segments (smooth everywhere: let the renderer crease it)."""
    p = np.asarray(profile, float)
    seg = np.diff(p, axis=0)
    # outward normal of each segment: the tangent turned toward +r for a profile
    # that goes from the top pole down the outside
    sn = unit(np.column_stack([-seg[:, 1], seg[:, 0]]))
    vn = np.zeros_like(p)
    vn[:-1] += sn
    vn[1:] += sn
    vn = unit(vn)
    nrms = [(tuple(n), tuple(n)) for n in vn]
    v, f, nrm = _revolve([tuple(q) for q in p], nrms, rotation_to(axis), center, n_seg, set())
    return v, f, nrm


def wine_glass_profile(
    height=0.15,
    bowl_radius=0.038,
    wall=0.0022,
    stem_radius=0.0035,
    foot_radius=0.032,
    foot=0.004,
    n=14,
):
    """A wine glass's profile from the bowl's inner bottom (on the axis) up the inside,
    over the rim, down the outside, the stem and the foot to the foot's bottom centre
    (z = 0 at the foot's bottom)."""
    z_bowl = 0.45 * height  # where the bowl meets the stem
    bowl_h = height - z_bowl
    t = np.linspace(0.0, 1.0, n)
    # outer bowl: r grows as sin of a quarter turn and a little inward at the rim
    r_out = bowl_radius * np.sin(0.5 * math.pi * np.minimum(1.0, 1.25 * t)) * (1.0 - 0.12 * t**3)
    r_out[0] = stem_radius
    z_out = z_bowl + bowl_h * t
    r_in = np.maximum(r_out - wall, 0.0)
    z_in = z_out + wall * (1 - t)
    inner = [(0.0, z_bowl + 1.5 * wall)] + [(r, z) for r, z in zip(r_in[1:], z_in[1:], strict=True)]
    outer = [(r, z) for r, z in zip(r_out[::-1], z_out[::-1], strict=True)]
    stem = [
        (stem_radius, z_bowl - 0.2 * z_bowl),
        (stem_radius, foot + 0.15 * z_bowl),
        (0.6 * foot_radius, foot),
    ]
    foot_p = [(foot_radius, 0.6 * foot), (foot_radius, 0.0), (0.0, 0.0)]
    return inner + outer + stem + foot_p
