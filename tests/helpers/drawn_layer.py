"""What a caustic layer shows at given points: its drawn meshes (`smooth.drawn_mesh`,
what Blender renders: the irradiance linear over each triangle) evaluated there, summed
over the rasters (the coarse ones too: a renderer draws them all).

The drawn mesh of a raster is a grid of (res + 2)² vertices (rows along the raster's
v axis) and one vertex at the centre of each grid cell, each cell cut into four
triangles about it; a point is located by the grid's lines (read back from the mesh's
own vertices) and interpolated barycentrically in its triangle, as a rasteriser does."""

from __future__ import annotations

import numpy as np

from core.caustic_layer.smooth import drawn_mesh


def _barycentric(p, a, b, c):
    """Weights of a, b, c at p (arrays of 2-vectors as (x, y) tuples)."""
    v0 = (b[0] - a[0], b[1] - a[1])
    v1 = (c[0] - a[0], c[1] - a[1])
    v2 = (p[0] - a[0], p[1] - a[1])
    den = v0[0] * v1[1] - v1[0] * v0[1]
    wb = (v2[0] * v1[1] - v1[0] * v2[1]) / den
    wc = (v0[0] * v2[1] - v2[0] * v0[1]) / den
    return 1.0 - wb - wc, wb, wc


def patch_at(patch, points) -> np.ndarray:
    """The drawn irradiance (first channel) of one raster (`rasters.PatchLayer`) at
    world ``points`` (…, 3) on its plane; 0 beyond it."""
    mesh = drawn_mesh(patch)
    n = int(patch.resolution) + 2
    rel = mesh.vertices - patch.origin
    gu = (rel[:n] @ patch.axis_u).reshape(-1)  # the first row: the grid's u lines
    gv = (rel[: n * n : n] @ patch.axis_v).reshape(-1)  # the first column: its v lines
    grid = mesh.irradiance[: n * n, 0].reshape(n, n)
    centre = mesh.irradiance[n * n :, 0].reshape(n - 1, n - 1)
    p = np.asarray(points, dtype=float) - patch.origin
    x, y = p @ patch.axis_u, p @ patch.axis_v
    inside = (x >= gu[0]) & (x <= gu[-1]) & (y >= gv[0]) & (y <= gv[-1])
    i = np.clip(np.searchsorted(gu, x, side="right") - 1, 0, n - 2)
    j = np.clip(np.searchsorted(gv, y, side="right") - 1, 0, n - 2)
    s = (x - gu[i]) / (gu[i + 1] - gu[i])
    t = (y - gv[j]) / (gv[j + 1] - gv[j])
    c00, c10, c11, c01, cc = (
        grid[j, i],
        grid[j, i + 1],
        grid[j + 1, i + 1],
        grid[j + 1, i],
        centre[j, i],
    )
    ds, dt = s - 0.5, t - 0.5
    bottom = (dt <= 0.0) & (np.abs(ds) <= -dt)
    top = (dt >= 0.0) & (np.abs(ds) <= dt)
    right = ~bottom & ~top & (ds > 0.0)
    left = ~bottom & ~top & ~right
    out = np.zeros(np.shape(x))
    for mask, (a, va), (b, vb) in (
        (bottom, ((0.0, 0.0), c00), ((1.0, 0.0), c10)),
        (right, ((1.0, 0.0), c10), ((1.0, 1.0), c11)),
        (top, ((1.0, 1.0), c11), ((0.0, 1.0), c01)),
        (left, ((0.0, 1.0), c01), ((0.0, 0.0), c00)),
    ):
        wa, wb, wc = _barycentric((s, t), a, b, (0.5, 0.5))
        out = np.where(mask, wa * va + wb * vb + wc * cc, out)
    return np.where(inside, out, 0.0)


def layer_at(layer, points) -> np.ndarray:
    """The whole layer's drawn irradiance at ``points``: every raster's, summed."""
    return sum((patch_at(p, points) for p in layer.patches), np.zeros(np.shape(points)[:-1]))


def bin_means(layer, u_edges, v_edges, origin, axis_u, axis_v, sub: int = 4) -> np.ndarray:
    """(nu, nv): the layer's drawn irradiance averaged over each bin of the grid
    ``u_edges`` × ``v_edges`` along ``axis_u``, ``axis_v`` from ``origin`` on the
    plane (``sub`` × ``sub`` points per bin), as a Monte-Carlo tally bins it."""
    f = (np.arange(sub) + 0.5) / sub
    uu = (u_edges[:-1, None] + np.diff(u_edges)[:, None] * f[None, :]).reshape(-1)
    vv = (v_edges[:-1, None] + np.diff(v_edges)[:, None] * f[None, :]).reshape(-1)
    gu, gv = np.meshgrid(uu, vv, indexing="ij")
    pts = origin + gu[..., None] * axis_u + gv[..., None] * axis_v
    val = layer_at(layer, pts)
    nu, nv = len(u_edges) - 1, len(v_edges) - 1
    return val.reshape(nu, sub, nv, sub).mean(axis=(1, 3))
