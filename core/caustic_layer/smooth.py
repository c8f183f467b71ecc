"""The layer as it is drawn: irradiance continuous across texels, the flux exact.

A raster's texels hold the flux each received (`rasters.PatchLayer.irradiance`); drawn
flat, each texel shows as a block. Drawn here instead: a mesh whose vertices are the
texel centres (plus the raster's border, where the nearest texel's value extends),
each cell cut into four triangles about its centre (there the mean of its corners),
with the irradiance at each vertex, which the renderer interpolates linearly over
each triangle (a point attribute; Blender splits nothing: the triangles are given).
A texel's value at its centre vertex is scaled by its area over the measure of the
vertices that carry it (each vertex's share of its triangles, a third of each), so
the interpolated irradiance integrates to the texels' flux exactly, a uniform raster
is drawn uniform, and a texel's flux spreads at most to its neighbours' centres (one
texel).

The baked layer reads an image instead (`image_texels`): the same texel values
interpolated bilinearly between texel centres in the raster's warped coordinate
(four Closest reads in `blender/build/baked_layers.py`: EEVEE would mipmap a Linear
image), each scaled by its area over the measure of its tent there.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np


@dataclass
class DrawnMesh:
    """A triangle mesh over one raster: vertices (V, 3) in world space (lifted as the
    raster's), triangles (T, 3) counter-clockwise about its normal, the receiver's UV
    per vertex (or None) and the irradiance per vertex (V, 3). ``edges`` (E, 2) and
    ``corner_edges`` (3 T,): its edges and each corner's edge (to the next corner), or
    None (Blender then finds them itself, as a hash of ~380 000 edges: 45 ms)."""

    vertices: np.ndarray
    triangles: np.ndarray
    uvs: np.ndarray | None
    irradiance: np.ndarray
    edges: np.ndarray | None = None
    corner_edges: np.ndarray | None = None


def dual_lines(res: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For the res + 2 lines of the drawn grid along one axis (the raster's first edge,
    the res texel centres, its last edge): the texel lines each lies between (lo, hi:
    the mean of the two) and the texel whose value it carries."""
    i = np.arange(res + 2)
    lo = np.clip(i - 1, 0, res)
    hi = np.clip(i, 0, res)
    return lo, hi, np.clip(i - 1, 0, res - 1)


@lru_cache(maxsize=8)
def grid_triangles(n: int) -> tuple[np.ndarray, np.ndarray]:
    """The triangles of an n × n vertex grid (row-major, rows along v) whose every cell
    is cut into four about an extra vertex at its centre (n² + k, k the cell's index):
    (4 (n−1)², 3), counter-clockwise about u × v, and the cells' corners ((n−1)², 4).
    Four, not two along a diagonal: a diagonal would favour two corners of each cell
    (a third of its area each against a sixth), so a uniform raster would not be drawn
    uniform at the raster's corners. Read-only (cached per n)."""
    a = (np.arange(n - 1)[:, None] * n + np.arange(n - 1)[None, :]).reshape(-1)
    corners = np.stack([a, a + 1, a + n + 1, a + n], 1)
    m = n * n + np.arange(len(a))
    tris = np.stack([np.stack([corners[:, k], corners[:, (k + 1) % 4], m], 1) for k in range(4)], 1)
    tris = tris.reshape(-1, 3)
    tris.flags.writeable = False  # cached per n: shared
    corners.flags.writeable = False
    return tris, corners


@lru_cache(maxsize=8)
def grid_edges(n: int) -> tuple[np.ndarray, np.ndarray]:
    """The edges of `grid_triangles` (n) in closed form, (E, 2) int32, and each
    triangle corner's edge (the one to the triangle's next corner), (12 (n−1)²,):
    per cell its 4 spokes to the centre (4k + j from corner j), then the grid's lines
    along u (row r, column c: (r n + c, r n + c + 1)), then along v ((r n + c,
    (r + 1) n + c)). Read-only (cached per n)."""
    m = n - 1
    r, c = np.divmod(np.arange(m * m), m)
    a = r * n + c
    corners = np.stack([a, a + 1, a + n + 1, a + n], 1)
    centre = n * n + np.arange(m * m)
    spokes = np.stack([corners.reshape(-1), np.repeat(centre, 4)], 1)
    ru, cu = np.divmod(np.arange(n * m), m)
    along_u = np.stack([ru * n + cu, ru * n + cu + 1], 1)
    rv, cv = np.divmod(np.arange(m * n), n)
    along_v = np.stack([rv * n + cv, (rv + 1) * n + cv], 1)
    edges = np.concatenate([spokes, along_u, along_v]).astype(np.int32)
    u0, v0 = 4 * m * m, 4 * m * m + n * m
    # a cell's sides, from corner j to j + 1: its row's u line, its right v line, the
    # next row's u line, its own v line
    sides = np.stack([u0 + r * m + c, v0 + r * n + c + 1, u0 + (r + 1) * m + c, v0 + a], 1)
    spoke = 4 * np.arange(m * m)[:, None] + np.arange(4)[None, :]
    # triangle (k, j): corners j, j + 1, centre; its corners' edges: side j, spoke
    # j + 1 (to the centre), spoke j (back to corner j)
    per = np.stack([sides, np.roll(spoke, -1, axis=1), spoke], 2).reshape(-1).astype(np.int32)
    edges.flags.writeable = False
    per.flags.writeable = False
    return edges, per


@dataclass
class DrawnWeights:
    """What `drawn_mesh` computes from a raster's geometry alone (its texel lines):
    each texel's measure (of the vertices carrying it); a raster refilled in place
    (live update) reuses it."""

    measure: np.ndarray  # (res²,)


def drawn_geometry(patch) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, DrawnWeights]:
    """The drawn mesh's vertices, triangles, UVs (or None) and weights (`DrawnWeights`)
    of `patch` (`rasters.PatchLayer`): see the module's text. By slices of the grid
    (the cells' corners j = 0..3 and their four triangles), not gathers over the
    triangles: the same sums, 3× faster on a 251² raster."""
    res = int(patch.resolution)
    lo, hi, _ = dual_lines(res)
    n = res + 2

    def dual(values):  # the corner grid's values at the drawn grid's points (bilinear)
        g = np.asarray(values, dtype=float).reshape(res + 1, res + 1, -1)
        return 0.25 * (g[lo][:, lo] + g[lo][:, hi] + g[hi][:, lo] + g[hi][:, hi])

    def with_centres(g):  # (n, n, k) → the n² grid vertices, then the cells' centres
        c = (g[:-1, :-1] + g[:-1, 1:] + g[1:, 1:] + g[1:, :-1]) * 0.25
        return np.concatenate([g.reshape(n * n, -1), c.reshape(-1, g.shape[-1])])

    grid = dual(patch.vertices)
    tris, _ = grid_triangles(n)
    verts = with_centres(grid)
    # the cells' corners as grid_triangles orders them, and each triangle's area
    # (corner j, corner j + 1, centre): a third of it to each of its vertices
    corner = [grid[:-1, :-1], grid[:-1, 1:], grid[1:, 1:], grid[1:, :-1]]
    centre = verts[n * n :].reshape(n - 1, n - 1, 3)
    area = [_area(corner[j], corner[(j + 1) % 4], centre) / 3.0 for j in range(4)]
    # a centre's value is its cell's corners' mean: its measure goes a quarter to each
    to_corner = 0.25 * (area[0] + area[1] + area[2] + area[3])
    d = np.zeros((n, n))
    for j, (rs, cs) in enumerate(_CORNER_SLICES):
        d[rs, cs] += area[j] + area[j - 1] + to_corner
    # the border's lines carry the first and last texels (`dual_lines`)
    d[1] += d[0]
    d[-2] += d[-1]
    d[:, 1] += d[:, 0]
    d[:, -2] += d[:, -1]
    measure = d[1:-1, 1:-1].reshape(-1)
    uvs = None if patch.uvs is None else with_centres(dual(patch.uvs))
    return verts, tris, uvs, DrawnWeights(measure)


#: the grid's slices holding each cell's corner j (0..3, as `grid_triangles`)
_CORNER_SLICES = (
    (slice(None, -1), slice(None, -1)),
    (slice(None, -1), slice(1, None)),
    (slice(1, None), slice(1, None)),
    (slice(1, None), slice(None, -1)),
)


def _area(a, b, c):
    """The areas of the triangles (a, b, c) (arrays of points, ..., 3)."""
    u, v = b - a, c - a
    x = u[..., 1] * v[..., 2] - u[..., 2] * v[..., 1]
    y = u[..., 2] * v[..., 0] - u[..., 0] * v[..., 2]
    z = u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]
    return 0.5 * np.sqrt(x * x + y * y + z * z)


def drawn_irradiance(patch, weights: DrawnWeights) -> np.ndarray:
    """(V, 3) the irradiance at the drawn mesh's vertices of `patch` (its texel
    values), from its geometry's `weights` (`drawn_geometry`). The grid's vertices
    carry the texels edge-padded (`dual_lines`), the centres their cell's mean: by
    slices, not gathers (live update draws every coarse layer this way)."""
    res = int(patch.resolution)
    flux = np.asarray(patch.irradiance, dtype=float).reshape(-1, 3) * patch.texel_areas().reshape(
        -1, 1
    )
    m = weights.measure
    value = (flux / np.where(m > 0.0, m, 1.0)[:, None]).reshape(res, res, 3)
    g = np.pad(value, ((1, 1), (1, 1), (0, 0)), mode="edge")  # (res + 2)² grid vertices
    centres = 0.25 * (g[:-1, :-1] + g[:-1, 1:] + g[1:, 1:] + g[1:, :-1])
    return np.concatenate([g.reshape(-1, 3), centres.reshape(-1, 3)])


def drawn_mesh(patch) -> DrawnMesh:
    """The drawn mesh of `patch` (`rasters.PatchLayer`): see the module's text."""
    verts, tris, uvs, weights = drawn_geometry(patch)
    edges, corner_edges = grid_edges(int(patch.resolution) + 2)
    return DrawnMesh(verts, tris, uvs, drawn_irradiance(patch, weights), edges, corner_edges)


def tent_measures(axis, res: int) -> np.ndarray:
    """(res,) the world length of each texel's tent along one raster axis whose texel
    lines are x(ξ) = c + s·sinh(ξ), ξ = ξ0 + i·dξ (`rasters.PatchLayer.axes`): the
    integral of the function that is 1 at the texel's centre and falls linearly in ξ
    to 0 at its neighbours' centres (the first and last stay 1 out to the raster's
    edge, as an image sampled with Extend). In closed form from X(ξ) = c ξ + s cosh ξ,
    the antiderivative of x."""
    c, s, xi0, dxi = (float(v) for v in axis)
    m = xi0 + dxi * (np.arange(res) + 0.5)  # texel centres

    def x(xi):
        return c + s * np.sinh(xi)

    def big_x(xi):
        return c * xi + s * np.cosh(xi)

    right = (big_x(m + dxi) - big_x(m)) / dxi - x(m)  # ∫ over [m, m + dξ] of the falling half
    left = x(m) - (big_x(m) - big_x(m - dxi)) / dxi
    right[-1] = x(m[-1] + 0.5 * dxi) - x(m[-1])  # the last: flat to the edge
    left[0] = x(m[0]) - x(m[0] - 0.5 * dxi)
    return left + right


def image_texels(irradiance, axes, res: int) -> np.ndarray:
    """(res, res, k) the values an image sampled with Linear interpolation between its
    texel centres (in the raster's warped coordinate) must hold for the irradiance it
    draws to carry each texel's flux: the texel's irradiance × its area / its tent's
    measure (rows along v, columns along u, as `PatchLayer.irradiance`)."""
    edges = [
        float(a[0]) + float(a[1]) * np.sinh(float(a[2]) + float(a[3]) * np.arange(res + 1))
        for a in axes
    ]
    area = np.diff(edges[1])[:, None] * np.diff(edges[0])[None, :]
    tent = tent_measures(axes[1], res)[:, None] * tent_measures(axes[0], res)[None, :]
    irr = np.asarray(irradiance, dtype=float)
    return irr * (area / tent).reshape(res, res, *([1] * (irr.ndim - 2)))
