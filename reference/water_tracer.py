"""A Monte-Carlo reference for light through a wavy water surface onto a floor in the
water: the oracle for `core.caustic_layer.water_beam` (shares no code with it).

The surface is an analytic height field z = z0 + Σ a_k sin(k_k·(x, y) + φ_k) over a
rectangle, its normals exact (from the gradient); rays are found on it by marching
and bisection, refracted by Snell's law with the unpolarised Fresnel transmittance
(from the amplitude coefficients), absorbed by Beer over the path in the water, and
binned where they reach the horizontal floor z = floor_z. Rays are sampled uniformly
by where they cross the rest plane z = z0 over a rectangle larger than the surface;
each carries the flux through its share of that rectangle (a sun: S·cos θ·A/N; a
point light: I·cos θ/r²·A/N). The binned irradiance is divided by n² (Cycles' own
convention under water, SPEC §9), as the layer's is.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class SineWaves:
    """z = z0 + Σ_k amplitude_k · sin(wavevector_k · (x, y) + phase_k) over
    ``bounds`` = (x0, x1, y0, y1)."""

    z0: float
    amplitudes: tuple
    wavevectors: tuple  # ((kx, ky), …) rad per unit length
    phases: tuple
    bounds: tuple

    def _args(self, x, y):
        k = np.asarray(self.wavevectors, dtype=float)
        return x[..., None] * k[:, 0] + y[..., None] * k[:, 1] + np.asarray(self.phases)

    def height(self, x, y):
        x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
        return self.z0 + np.sin(self._args(x, y)) @ np.asarray(self.amplitudes, dtype=float)

    def gradient(self, x, y):
        x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
        c = np.cos(self._args(x, y)) * np.asarray(self.amplitudes, dtype=float)
        k = np.asarray(self.wavevectors, dtype=float)
        return c @ k[:, 0], c @ k[:, 1]

    def normal(self, x, y):
        """Unit upward normals (…, 3)."""
        hx, hy = self.gradient(x, y)
        n = np.stack([-hx, -hy, np.ones_like(hx)], axis=-1)
        return n / np.linalg.norm(n, axis=-1, keepdims=True)

    @property
    def reach(self) -> float:
        return float(np.sum(np.abs(self.amplitudes)))


def height_field_mesh(waves: SineWaves, nx: int, ny: int):
    """The surface as the code under test takes it: vertices on an (ny+1) × (nx+1)
    grid over the bounds, two triangles per square (counter-clockwise seen from above),
    corner normals exact."""
    x0, x1, y0, y1 = waves.bounds
    xs, ys = np.linspace(x0, x1, nx + 1), np.linspace(y0, y1, ny + 1)
    gx, gy = np.meshgrid(xs, ys)
    verts = np.stack([gx, gy, waves.height(gx, gy)], axis=-1).reshape(-1, 3)
    normals = waves.normal(gx, gy).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(ny), np.arange(nx), indexing="ij")
    a = (i * (nx + 1) + j).reshape(-1)
    b, c, d = a + 1, a + nx + 2, a + nx + 1
    tris = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    return verts, tris, normals[tris]


def _hit(waves: SineWaves, o, d, steps: int = 16, iters: int = 24):
    """Parameter t of each ray's first crossing of the height field (NaN: none in
    the band the waves span), by marching through that band and bisection."""
    top, bottom = waves.z0 + waves.reach * 1.001 + 1e-9, waves.z0 - waves.reach * 1.001 - 1e-9
    t0 = (top - o[:, 2]) / d[:, 2]
    t1 = (bottom - o[:, 2]) / d[:, 2]

    def f(t):
        p = o + t[:, None] * d
        return p[:, 2] - waves.height(p[:, 0], p[:, 1])

    lo = t0.copy()
    flo = f(lo)
    found = np.zeros(len(o), dtype=bool)
    hi = np.full(len(o), np.nan)
    for s in range(1, steps + 1):
        t = t0 + (t1 - t0) * s / steps
        ft = f(t)
        cross = ~found & (ft <= 0.0)
        hi[cross] = t[cross]
        found |= cross
        keep = ~found
        lo[keep], flo[keep] = t[keep], ft[keep]
    a, b = lo[found], hi[found]
    oo, dd = o[found], d[found]
    for _ in range(iters):
        m = 0.5 * (a + b)
        p = oo + m[:, None] * dd
        up = p[:, 2] - waves.height(p[:, 0], p[:, 1]) > 0.0
        a, b = np.where(up, m, a), np.where(up, b, m)
    out = np.full(len(o), np.nan)
    out[found] = 0.5 * (a + b)
    return out


def _fresnel_t(cos_i, n1, n2):
    """Unpolarised transmittance 1 − (r_s² + r_p²)/2 from the amplitude coefficients."""
    sin_t = n1 / n2 * np.sqrt(np.maximum(0.0, 1.0 - cos_i**2))
    cos_t = np.sqrt(np.maximum(0.0, 1.0 - sin_t**2))
    rs = (n1 * cos_i - n2 * cos_t) / (n1 * cos_i + n2 * cos_t)
    rp = (n2 * cos_i - n1 * cos_t) / (n2 * cos_i + n1 * cos_t)
    return 1.0 - 0.5 * (rs * rs + rp * rp), cos_t


@dataclass
class FloorTally:
    """Irradiance (ny, nx) (×1/n², first channel's absorption) binned over the floor
    cells ``edges_x`` × ``edges_y``, and the flux reaching the floor (all of it, binned
    or not)."""

    irradiance: np.ndarray
    edges_x: np.ndarray
    edges_y: np.ndarray
    flux: float
    rays: int


def trace_floor(
    waves: SineWaves,
    floor_z: float,
    edges_x,
    edges_y,
    ior: float = 1.333,
    absorption: float = 0.0,
    sun_direction=None,
    sun_strength: float = 1.0,
    point=None,
    intensity: float = 1.0,
    n_rays: int = 1_000_000,
    seed: int = 1,
    batch: int = 250_000,
) -> FloorTally:
    """Trace a sun (``sun_direction``, irradiance ``sun_strength``) or an isotropic
    point light (``point``, ``intensity`` W/sr) through ``waves`` onto the floor."""
    rng = np.random.default_rng(seed)
    ex, ey = np.asarray(edges_x, dtype=float), np.asarray(edges_y, dtype=float)
    acc = np.zeros((len(ey) - 1, len(ex) - 1))
    x0, x1, y0, y1 = waves.bounds
    pad = 4.0 * waves.reach + 1e-6  # rays crossing the rest plane near the rim may hit inside
    lx0, lx1, ly0, ly1 = x0 - pad, x1 + pad, y0 - pad, y1 + pad
    area = (lx1 - lx0) * (ly1 - ly0)
    flux = 0.0
    done = 0
    while done < n_rays:
        m = min(batch, n_rays - done)
        done += m
        p = np.stack(
            [rng.uniform(lx0, lx1, m), rng.uniform(ly0, ly1, m), np.full(m, waves.z0)], axis=1
        )
        if point is None:
            d = np.broadcast_to(np.asarray(sun_direction, float), p.shape)
            d = d / np.linalg.norm(d, axis=1, keepdims=True)
            w = sun_strength * np.abs(d[:, 2]) * area / n_rays
            o = p - d * (2.0 * waves.reach + 1.0) / np.abs(d[:, 2:3])
        else:
            rel = p - np.asarray(point, float)
            r = np.linalg.norm(rel, axis=1)
            d = rel / r[:, None]
            w = intensity * np.abs(d[:, 2]) / (r * r) * area / n_rays
            o = np.broadcast_to(np.asarray(point, float), p.shape)
        t = _hit(waves, o, d)
        ok = np.isfinite(t)
        h = o + np.where(ok, t, 0.0)[:, None] * d
        ok &= (h[:, 0] >= x0) & (h[:, 0] <= x1) & (h[:, 1] >= y0) & (h[:, 1] <= y1)
        h, d, w = h[ok], d[ok], w[ok]
        n = waves.normal(h[:, 0], h[:, 1])
        cos_i = -np.sum(d * n, axis=1)
        tr, cos_t = _fresnel_t(cos_i, 1.0, ior)
        eta = 1.0 / ior
        dt = eta * d + (eta * cos_i - cos_t)[:, None] * n
        dt /= np.linalg.norm(dt, axis=1, keepdims=True)
        s = (floor_z - h[:, 2]) / dt[:, 2]
        f = h + s[:, None] * dt
        w = w * tr * np.exp(-absorption * s)
        flux += float(w.sum())
        ix = np.searchsorted(ex, f[:, 0], side="right") - 1
        iy = np.searchsorted(ey, f[:, 1], side="right") - 1
        inb = (ix >= 0) & (ix < len(ex) - 1) & (iy >= 0) & (iy < len(ey) - 1)
        np.add.at(acc, (iy[inb], ix[inb]), w[inb])
    bin_area = np.diff(ey)[:, None] * np.diff(ex)[None, :]
    return FloorTally(acc / bin_area / ior**2, ex, ey, flux / ior**2, n_rays)


def layer_on_bins(patch, edges_x, edges_y, supersample: int = 8) -> np.ndarray:
    """A caustic layer raster (`PatchLayer` on a horizontal floor) averaged over the
    reference's bins (ny, nx), first channel: each texel's flux spread over
    s × s points, summed per bin, over the bin's area."""
    g = (np.arange(supersample) + 0.5) / supersample
    du, dv = np.diff(patch.edges_u), np.diff(patch.edges_v)
    pu = (patch.edges_u[:-1, None] + du[:, None] * g).reshape(-1)
    pv = (patch.edges_v[:-1, None] + dv[:, None] * g).reshape(-1)
    flux = np.repeat(np.repeat(patch.texel_flux()[..., 0], supersample, 0), supersample, 1)
    flux = flux / supersample**2
    world = (
        patch.origin + pu[None, :, None] * patch.axis_u + pv[:, None, None] * patch.axis_v
    )  # (v, u, 3)
    ex, ey = np.asarray(edges_x, float), np.asarray(edges_y, float)
    ix = np.searchsorted(ex, world[..., 0], side="right") - 1
    iy = np.searchsorted(ey, world[..., 1], side="right") - 1
    inb = (ix >= 0) & (ix < len(ex) - 1) & (iy >= 0) & (iy < len(ey) - 1)
    acc = np.zeros((len(ey) - 1, len(ex) - 1))
    np.add.at(acc, (iy[inb], ix[inb]), flux[inb])
    return acc / (np.diff(ey)[:, None] * np.diff(ex)[None, :])
