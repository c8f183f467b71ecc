"""Exact beam of one secondary source as a structured ray grid over the lens' lit disc.

The rays are parametrised by where they enter the sphere: the angle of incidence ι
(uniform in [0, π/2], so the impact parameter b = R sin ι is denser toward the rim, where
the caustic concentrates) × the azimuth φ about the light–lens axis. Node (i, j) of the
grid is the ray with ι_i = (π/2)·i/Nr and φ_j = 2π(j + ½)/Na; ring 0 is the axial ray
(repeated, so the topology stays a plain Nr × Na grid of cells, the first ring of cells
degenerate quads = triangles). Each cell carries the flux of its patch of (ι, φ):

    point sample:    I · A(dir) · T(ι) · exp(−a·2R cos r) · dΩ,  dΩ = (R/D)² sinι cosι/cosψ dι dφ
    parallel sample: S · T(ι) · exp(−a·2R cos r) · dA,          dA = R² sinι cosι dι dφ

(T: unpolarised two-surface Fresnel transmission, which depends only on ι for a sphere;
A: the spot mask or the area light's cosine), integrated by 3 × 3 Gauss–Legendre points
per cell. The rays themselves are traced in 3-D world coordinates through the sphere with
the robust intersection of SPEC §4.3 and the vector form of Snell's law. The topology
(K source samples × (Nr + 1) × Na rays, K × Nr × Na cells) depends only on the
parameters, never on the geometry, so an animation bake can key it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..exact_optics import two_surface_transmission
from . import shadow
from .emitters import (
    Lens,
    SourceSamples,
    angular_factor,
    is_isotropic,
    perpendicular_frame,
    source_samples,
)

_GL_X, _GL_W = np.polynomial.legendre.leggauss(3)


@dataclass
class BeamGrid:
    """The traced beam of one (light, lens) pair. Shapes: K samples, Nr + 1 rings of
    nodes, Na azimuths. Positions and directions in world coordinates."""

    exit_points: np.ndarray  # (K, Nr+1, Na, 3) where each node ray leaves the sphere
    exit_dirs: np.ndarray  # (K, Nr+1, Na, 3) unit direction after the exit
    node_density: np.ndarray  # (K, Nr+1, Na) flux per unit (ι, φ) at the nodes (W/rad²)
    cell_flux: np.ndarray  # (K, Nr, Na) flux (W) of each grid cell
    valid: np.ndarray  # (K,) False: sample inside the sphere (no beam, zero flux)
    color: np.ndarray  # (3,) light colour × lens tint

    @property
    def shape(self) -> tuple[int, int, int]:
        return self.cell_flux.shape

    @property
    def total_flux(self) -> float:
        return float(self.cell_flux.sum())

    @property
    def n_rays(self) -> int:
        return int(np.prod(self.exit_points.shape[:3]))

    @property
    def n_cells(self) -> int:
        return int(self.cell_flux.size)


def _dot(a, b):
    return np.einsum("...i,...i->...", a, b)


def refract(d, nrm, eta):
    """Unit directions ``d`` refracted at unit normals ``nrm`` facing against them,
    ``eta = n_from/n_to``; rounding past total reflection is clamped to grazing."""
    cos_i = np.clip(-_dot(d, nrm), 0.0, 1.0)
    k = np.maximum(1.0 - eta * eta * (1.0 - cos_i) * (1.0 + cos_i), 0.0)
    t = eta * d + (eta * cos_i - np.sqrt(k))[..., None] * nrm
    return t / np.linalg.norm(t, axis=-1)[..., None]


def trace_through_sphere(origins, dirs, center, radius, ior):
    """Exit points and directions of rays (…, 3) that enter the sphere from outside.

    Entry: the near root ``c/q`` of the robust form (SPEC §4.3, Haines et al. 2019) with
    the discriminant ``R² − |f − (f·d)d|²`` clamped at 0 (grazing rays of the grid's rim);
    inside: the far root ``q`` from the entry point. Returns (exit point, exit direction,
    chord length)."""
    c = np.asarray(center, dtype=float)
    f = origins - c
    beta = _dot(f, dirs)
    perp = f - beta[..., None] * dirs
    sq = np.sqrt(np.maximum(radius * radius - _dot(perp, perp), 0.0))
    q = -beta - np.where(beta >= 0.0, 1.0, -1.0) * sq
    cc = (np.sqrt(_dot(f, f)) - radius) * (np.sqrt(_dot(f, f)) + radius)
    t1 = cc / np.where(q != 0.0, q, 1.0)
    p1 = origins + t1[..., None] * dirs
    d2 = refract(dirs, (p1 - c) / radius, 1.0 / ior)
    f2 = p1 - c
    beta2 = _dot(f2, d2)
    perp2 = f2 - beta2[..., None] * d2
    chord = -beta2 + np.sqrt(np.maximum(radius * radius - _dot(perp2, perp2), 0.0))
    p2 = p1 + chord[..., None] * d2
    d3 = refract(d2, -(p2 - c) / radius, ior)
    return p2, d3, chord


def _transmission(iota, lens: Lens):
    """T(ι) · exp(−a · 2R cos r): the fraction of a ray's power on the direct path."""
    cos_r = np.sqrt(np.maximum(1.0 - (np.sin(iota) / lens.ior) ** 2, 0.0))
    fres = two_surface_transmission(iota, lens.ior)
    return fres * np.exp(-lens.absorption * 2.0 * lens.radius * cos_r)


def _incoming(samples: SourceSamples, lens: Lens, iota, phi):
    """Origins and unit directions of the rays entering at (ι, φ) for every sample, and
    the Jacobian of their flux measure per unit (ι, φ) (sr or m² per rad²).
    ``iota``: (K, I) or (I,), ``phi``: (P,); outputs (K, I, P, …)."""
    c = np.asarray(lens.center, dtype=float)
    R = lens.radius
    k = len(samples.weights)
    axes = samples.directions  # (K, 3) from the sample to the lens
    frames = np.array([perpendicular_frame(a) for a in axes])  # (K, 2, 3)
    iota = np.broadcast_to(np.asarray(iota, dtype=float), (k, np.shape(iota)[-1]))
    sin_i, cos_i = np.sin(iota), np.cos(iota)
    radial = (
        np.cos(phi)[None, None, :, None] * frames[:, None, None, 0, :]
        + np.sin(phi)[None, None, :, None] * frames[:, None, None, 1, :]
    )  # (K, 1, P, 3)
    u = axes[:, None, None, :]
    if samples.parallel:
        b = (R * sin_i)[:, :, None, None]
        origins = c - 4.0 * R * u + b * radial
        dirs = np.broadcast_to(u, origins.shape)
        jac = R * R * sin_i * cos_i
        return origins, dirs, jac[:, :, None]
    dist = np.linalg.norm(c - samples.points, axis=1)  # (K,)
    s = (R / np.maximum(dist, R))[:, None]
    sin_psi = s * sin_i
    cos_psi = np.sqrt((1.0 - sin_psi) * (1.0 + sin_psi))
    dirs = cos_psi[:, :, None, None] * u + sin_psi[:, :, None, None] * radial
    origins = np.broadcast_to(samples.points[:, None, None, :], dirs.shape)
    # cos ψ = 0 only for a light on the sphere (an invalid sample, zeroed by the caller)
    jac = np.divide(s * s * sin_i * cos_i, cos_psi, out=np.zeros_like(cos_psi), where=cos_psi > 0.0)
    return origins, dirs, jac[:, :, None]


def _density(samples, lens, iota, phi):
    """Flux per unit (ι, φ), shape (K, I, P)."""
    _, dirs, jac = _incoming(samples, lens, iota, phi)
    ang = 1.0 if samples.parallel else angular_factor(samples.emitter, dirs)
    w = samples.weights[:, None, None]
    dens = w * ang * _transmission(np.asarray(iota), lens)[..., None] * jac
    return np.broadcast_to(dens, (len(samples.weights), np.shape(iota)[-1], len(phi)))


def trace_beam(
    emitter,
    lens: Lens,
    n_radial: int = 64,
    n_azimuth: int = 256,
    n_source: int = 1,
    blockers=None,
) -> BeamGrid:
    """Trace the beam of ``emitter`` (a :mod:`.emitters` light) through ``lens``.

    ``n_radial`` × ``n_azimuth`` cells per source sample, ``n_source`` samples of an
    extended emitter (ignored for a point light of radius 0 or a sun of angle 0).
    ``blockers``: the source's `shadow.ShadowList` (its shadow drawn in the beam)."""
    samples = source_samples(emitter, lens, n_source)
    R = lens.radius
    nr, na = int(n_radial), int(n_azimuth)
    iota = 0.5 * math.pi * np.arange(nr + 1) / nr
    phi = 2.0 * math.pi * (np.arange(na) + 0.5) / na
    valid = np.ones(len(samples.weights), dtype=bool)
    if not samples.parallel:
        valid = np.linalg.norm(samples.points - lens.center, axis=1) > R * (1.0 + 1e-9)
    origins, dirs, _ = _incoming(samples, lens, iota, phi)
    origins = np.ascontiguousarray(np.broadcast_to(origins, dirs.shape))
    exit_p, exit_d, _ = trace_through_sphere(origins, dirs, lens.center, R, lens.ior)
    dens = _density(samples, lens, iota, phi)

    # 3 × 3 Gauss–Legendre points per cell.
    di, dp = iota[1] - iota[0], phi[1] - phi[0]
    qi = (iota[:-1, None] + 0.5 * di * (1.0 + _GL_X)).reshape(-1)  # (Nr·3,)
    qp = (phi[:, None] - 0.5 * dp + 0.5 * dp * (1.0 + _GL_X)).reshape(-1)  # (Na·3,)
    if samples.parallel or is_isotropic(samples.emitter):  # separable: 1-D in ι
        radial = _density(samples, lens, qi, np.zeros(1))[:, :, 0]  # (K, Nr·3)
        radial = (radial.reshape(len(valid), nr, 3) * _GL_W).sum(-1) * 0.5 * di
        cell = radial[:, :, None] * np.full(na, dp)
    else:
        q = _density(samples, lens, qi, qp).reshape(len(valid), nr, 3, na, 3)
        cell = np.einsum("kijab,j,b->kia", q, _GL_W, _GL_W) * 0.25 * di * dp
    cell, dens = shadow.apply(cell, dens, origins, dirs, lens, blockers, samples.parallel)
    cell = np.where(valid[:, None, None], cell, 0.0)
    dens = np.where(valid[:, None, None], dens, 0.0)
    color = np.asarray(getattr(emitter, "color", (1.0, 1.0, 1.0)), dtype=float) * np.asarray(
        lens.tint, dtype=float
    )
    return BeamGrid(
        exit_points=exit_p,
        exit_dirs=exit_d,
        node_density=dens,
        cell_flux=cell,
        valid=valid,
        color=color,
    )
