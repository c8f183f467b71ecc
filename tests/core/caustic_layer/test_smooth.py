"""The layer as drawn (`core/caustic_layer/smooth.py`): irradiance continuous across
texels, each texel's flux kept.

References: hand-computed rasters (one bright texel, a step), the exact optics of a
ball lens (core.lens.ball_optics: lens_flux, irradiance_on_plane), and integrals of
the drawn piecewise-linear irradiance evaluated here from its corner values at points
inside each triangle (a linear function over a triangle: its barycentric mix)."""

import math

import numpy as np
import pytest

from core.caustic_layer.beam_trace import trace_beam
from core.caustic_layer.emitters import Lens, PointLight
from core.caustic_layer.rasters import PatchLayer, build_layer
from core.caustic_layer.receiver_index import build_index
from core.caustic_layer.smooth import drawn_mesh, image_texels, tent_measures
from core.lens import ball_optics as eo
from reference.layer_metrics import relative_l1
from reference.meshes import rectangle

R, N_IOR, D = 1.0, 1.5, 10.0
I0 = 1.0  # W/sr


def _patch(edges_u, edges_v, irradiance):
    """A raster on the plane z = 0 (u = x, v = y) with the given texel lines."""
    eu, ev = np.asarray(edges_u, float), np.asarray(edges_v, float)
    res = len(eu) - 1
    verts = np.stack([*np.meshgrid(eu, ev, indexing="xy"), np.zeros((res + 1, res + 1))], -1)
    return PatchLayer(
        patch=0,
        sources=np.array([0]),
        object_id=0,
        normal=np.array([0.0, 0.0, 1.0]),
        axis_u=np.array([1.0, 0.0, 0.0]),
        axis_v=np.array([0.0, 1.0, 0.0]),
        origin=np.zeros(3),
        edges_u=eu,
        edges_v=ev,
        resolution=res,
        irradiance=np.asarray(irradiance, float),
        flux=0.0,
        flux_outside=0.0,
        vertices=verts.reshape(-1, 3),
        faces=np.zeros((0, 4), dtype=int),
        uvs=None,
        uv_inside=None,
    )


#: Barycentric sample points filling a triangle evenly (the centroids of its 4ⁿ
#: sub-triangles, n = 3): their mean of a linear function is its mean over the triangle.
def _bary(levels=3):
    tris = [np.eye(3)]
    for _ in range(levels):
        nxt = []
        for t in tris:
            m01, m12, m20 = (t[0] + t[1]) / 2, (t[1] + t[2]) / 2, (t[2] + t[0]) / 2
            nxt += [
                np.array([t[0], m01, m20]),
                np.array([m01, t[1], m12]),
                np.array([m20, m12, t[2]]),
                np.array([m01, m12, m20]),
            ]
        tris = nxt
    return np.array([t.mean(axis=0) for t in tris])


def _samples(drawn):
    """Points (T·k, 3), the drawn irradiance there (T·k, 3) and each point's area."""
    b = _bary()
    p = drawn.vertices[drawn.triangles]  # (T, 3, 3)
    e = drawn.irradiance[drawn.triangles]
    area = 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)
    pts = np.einsum("kj,tjc->tkc", b, p).reshape(-1, 3)
    val = np.einsum("kj,tjc->tkc", b, e).reshape(-1, 3)
    return pts, val, np.repeat(area / len(b), len(b))


def test_one_bright_texel_stays_within_its_neighbours_centres():
    res, h = 6, 0.5
    edges = h * np.arange(res + 1)
    irr = np.zeros((res, res, 3))
    irr[2, 3] = (4.0, 2.0, 1.0)  # row v = 2, column u = 3
    drawn = drawn_mesh(_patch(edges, edges, irr))
    pts, val, w = _samples(drawn)
    # all of its flux, E·h², and nothing else
    np.testing.assert_allclose(np.sum(val * w[:, None], axis=0), irr[2, 3] * h * h, rtol=1e-12)
    # at its centre (3.5 h, 2.5 h): its value; nothing beyond its neighbours' centres
    at = np.nonzero(np.all(np.isclose(drawn.vertices[:, :2], [3.5 * h, 2.5 * h]), axis=1))[0]
    np.testing.assert_allclose(drawn.irradiance[at[0]], irr[2, 3], rtol=1e-12)
    far = (np.abs(pts[:, 0] - 3.5 * h) > h) | (np.abs(pts[:, 1] - 2.5 * h) > h)
    assert np.all(val[far] == 0.0)


def test_a_uniform_raster_is_drawn_uniform_and_a_step_blurs_one_texel():
    res, h = 8, 0.25
    edges = h * np.arange(res + 1)
    drawn = drawn_mesh(_patch(edges, edges, np.full((res, res, 3), 3.0)))
    np.testing.assert_allclose(drawn.irradiance, 3.0, rtol=1e-12)
    # a step at u = 4 h: 2 on the left, 0 on the right; drawn: 2 up to the last left
    # centre (3.5 h), 0 from the first right one (4.5 h), linear between
    irr = np.zeros((res, res, 3))
    irr[:, :4] = 2.0
    drawn = drawn_mesh(_patch(edges, edges, irr))
    pts, val, w = _samples(drawn)
    u = pts[:, 0]
    assert np.allclose(val[u < 3.5 * h], 2.0) and np.all(val[u > 4.5 * h] == 0.0)
    mid = (u > 3.5 * h) & (u < 4.5 * h)
    np.testing.assert_allclose(val[mid, 0], 2.0 * (4.5 * h - u[mid]) / h, atol=1e-12)
    assert np.sum(val[:, 0] * w) == pytest.approx(2.0 * 4 * h * res * h, rel=1e-12)


def test_warped_texels_keep_every_texels_flux_in_all():
    rng = np.random.default_rng(3)
    eu = np.cumsum(np.r_[0.0, rng.uniform(0.05, 1.0, 12)])  # unequal texels
    ev = np.cumsum(np.r_[-2.0, rng.uniform(0.1, 0.6, 12)])
    irr = rng.uniform(0.0, 5.0, (12, 12, 3))
    drawn = drawn_mesh(_patch(eu, ev, irr))
    _pts, val, w = _samples(drawn)
    flux = np.sum(irr * (np.diff(ev)[:, None] * np.diff(eu)[None, :])[..., None], axis=(0, 1))
    np.testing.assert_allclose(np.sum(val * w[:, None], axis=0), flux, rtol=1e-10)
    assert np.all(drawn.irradiance >= 0.0)


def test_drawn_floating_ball_caustic_matches_the_exact_optics():
    lens = Lens(np.zeros(3), R, N_IOR)
    z = 5.0
    light = PointLight(np.array([0.0, 0.0, -D]), 4.0 * math.pi * I0)
    floor = rectangle([0, 0, z], [0, 0, 1], 200.0, 200.0, 4, 4)
    layer = build_layer([trace_beam(light, lens, 32, 128)], build_index(floor), resolution=96)
    (patch,) = layer.patches
    drawn = drawn_mesh(patch)
    pts, val, w = _samples(drawn)
    # the drawn flux is the raster's, to rounding, and the exact optics' to 1 %
    assert float(np.sum(val[:, 0] * w)) == pytest.approx(patch.flux, rel=1e-9)
    assert patch.flux == pytest.approx(eo.lens_flux(I0, D, R, N_IOR), rel=0.01)
    # its irradiance over rings about the axis, against the exact integral
    edges = np.linspace(0.0, eo.lens_shadow_radius(D, R, z), 25)
    rho = np.hypot(pts[:, 0], pts[:, 1])
    ring = np.digitize(rho, edges) - 1
    ok = (ring >= 0) & (ring < len(edges) - 1)
    got = np.bincount(ring[ok], val[ok, 0] * w[ok], len(edges) - 1) / (np.pi * np.diff(edges**2))
    exact = eo.irradiance_on_plane(I0, D, R, N_IOR, z, edges)
    assert relative_l1(got, exact, np.diff(edges**2)) <= 0.05


def _linear_in_xi(values, axis, res, n=200_001):
    """Per texel, the world integral along one warped axis of the function linear in ξ
    between texel centres (flat beyond the first and last), each texel alone 1: by
    the trapezoid rule on a fine grid of ξ."""
    c, s, xi0, dxi = axis
    xi = np.linspace(xi0, xi0 + res * dxi, n)
    dx = s * np.cosh(xi)
    centres = xi0 + dxi * (np.arange(res) + 0.5)
    out = []
    for i in range(res):
        e = np.zeros(res)
        e[i] = 1.0
        out.append(np.trapezoid(np.interp(xi, centres, e) * dx, xi))
    return np.array(out) * values


def test_image_texels_keep_the_flux_of_a_linear_image_on_a_warped_raster():
    axes = ((0.2, 0.03, -3.5, 0.11), (-0.1, 0.05, -2.0, 0.09))
    res = 40
    tent_u = _linear_in_xi(np.ones(res), axes[0], res)
    tent_v = _linear_in_xi(np.ones(res), axes[1], res)
    np.testing.assert_allclose(tent_measures(axes[0], res), tent_u, rtol=1e-8)
    irr = np.random.default_rng(5).uniform(0.0, 2.0, (res, res))
    stored = image_texels(irr, axes, res)
    edges = [a[0] + a[1] * np.sinh(a[2] + a[3] * np.arange(res + 1)) for a in axes]
    area = np.diff(edges[1])[:, None] * np.diff(edges[0])[None, :]
    drawn_flux = np.sum(stored * tent_v[:, None] * tent_u[None, :])
    assert drawn_flux == pytest.approx(np.sum(irr * area), rel=1e-8)


@pytest.mark.parametrize("n", [2, 3, 7])
def test_the_drawn_grids_edges_are_its_triangles_sides(n):
    """`grid_edges` (closed form, for the build to hand Blender) against the sides of
    `grid_triangles`' triangles found by sorting their corner pairs: every side once,
    and each corner's edge the one to its triangle's next corner."""
    from core.caustic_layer.smooth import grid_edges, grid_triangles

    tris, _ = grid_triangles(n)
    edges, corner_edges = grid_edges(n)
    pairs = np.sort(np.stack([tris.ravel(), np.roll(tris, -1, axis=1).ravel()], 1), axis=1)
    sides = np.unique(pairs, axis=0)
    # (n − 1)² cells: 4 spokes each, and the grid's 2 n (n − 1) lines
    assert len(edges) == len(sides) == 4 * (n - 1) ** 2 + 2 * n * (n - 1)
    np.testing.assert_array_equal(np.unique(np.sort(edges, axis=1), axis=0), sides)
    np.testing.assert_array_equal(np.sort(edges[corner_edges], axis=1), pairs)
