"""Closed, outward-wound glass meshes built by hand for the mesh lens' tests: a UV sphere
(smooth corner normals: the exact sphere normals), a box, a triangular prism; and the
Fresnel formulas written out (the tests' own copy, not core's)."""

from __future__ import annotations

import math

import numpy as np

from reference.meshes import uv_sphere as _sphere_mesh


def sphere(radius=1.0, n_lat=32, n_lon=64, center=(0.0, 0.0, 0.0)):
    """(vertices, triangles, smooth corner normals) of a latitude–longitude sphere."""
    m = _sphere_mesh(center, radius, n_lat, n_lon)
    v, t = np.asarray(m.vertices), np.asarray(m.triangles)
    normals = (v[t] - np.asarray(center, float)) / radius
    return v, t, normals


def box(lo, hi):
    """(vertices, triangles) of the axis-aligned box [lo, hi], two triangles a face."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    v = np.array(
        [
            [(lo, hi)[i][0], (lo, hi)[j][1], (lo, hi)[k][2]]
            for i in (0, 1)
            for j in (0, 1)
            for k in (0, 1)
        ]
    )
    idx = lambda i, j, k: 4 * i + 2 * j + k  # noqa: E731
    quads = [
        (idx(0, 0, 0), idx(0, 0, 1), idx(0, 1, 1), idx(0, 1, 0)),  # −x
        (idx(1, 0, 0), idx(1, 1, 0), idx(1, 1, 1), idx(1, 0, 1)),  # +x
        (idx(0, 0, 0), idx(1, 0, 0), idx(1, 0, 1), idx(0, 0, 1)),  # −y
        (idx(0, 1, 0), idx(0, 1, 1), idx(1, 1, 1), idx(1, 1, 0)),  # +y
        (idx(0, 0, 0), idx(0, 1, 0), idx(1, 1, 0), idx(1, 0, 0)),  # −z
        (idx(0, 0, 1), idx(1, 0, 1), idx(1, 1, 1), idx(0, 1, 1)),  # +z
    ]
    tris = [t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))]
    return v, np.array(tris)


def prism(apex_deg=60.0, side=1.0, length=4.0):
    """(vertices, triangles) of a prism along y: its cross-section in the x–z plane an
    isosceles triangle with the apex angle at the top (z > 0), the base on z = 0."""
    half = math.radians(apex_deg) / 2.0
    h = side * math.cos(half)
    w = side * math.sin(half)
    tri2 = [(-w, 0.0), (w, 0.0), (0.0, h)]
    v = np.array([(x, y, z) for y in (-length / 2, length / 2) for x, z in tri2])
    tris = [(0, 2, 1), (3, 4, 5)]  # end caps
    for a in range(3):
        b = (a + 1) % 3
        tris += [(a, b, b + 3), (a, b + 3, a + 3)]
    v_t = np.array(tris)
    # wind every face outward (the centroid behind it)
    c = v.mean(axis=0)
    p = v[v_t]
    n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    flip = np.einsum("ij,ij->i", n, p.mean(axis=1) - c) < 0
    v_t[flip] = v_t[flip][:, ::-1]
    return v, v_t


def fresnel_t(cos_i, n1, n2):
    """(t_s, t_p) power transmittances by the textbook amplitude formulas."""
    sin_t = n1 / n2 * math.sqrt(max(0.0, 1.0 - cos_i * cos_i))
    if sin_t >= 1.0:
        return 0.0, 0.0
    cos_t = math.sqrt(1.0 - sin_t * sin_t)
    rs = (n1 * cos_i - n2 * cos_t) / (n1 * cos_i + n2 * cos_t)
    rp = (n2 * cos_i - n1 * cos_t) / (n2 * cos_i + n1 * cos_t)
    return 1.0 - rs * rs, 1.0 - rp * rp


def unpolarised_t(theta, n1, n2):
    """Unpolarised power transmittance at incidence `theta` from n1 into n2, the mean
    of `fresnel_t`'s s and p parts."""
    ts, tp = fresnel_t(math.cos(theta), n1, n2)
    return 0.5 * (ts + tp)
