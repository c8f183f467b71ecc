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
per cell. The rays themselves are traced in 3-D world coordinates through the lens by its
`core.lens.base.Lens` interface (a ball: the robust intersection of SPEC §4.3 and the
vector form of Snell's law); the grid covers the lens' bounding sphere, and a kind whose
transmission is not a function of ι alone is weighted by tracing the quadrature rays
(2-D quadrature over ι × φ). The topology
(K source samples × (Nr + 1) × Na rays, K × Nr × Na cells) depends only on the
parameters, never on the geometry, so an animation bake can key it.
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
from dataclasses import dataclass

import numpy as np

from ..lens import base as lens_base
from ..lens import kinds
from ..lens.base import ExitRays
from ..shared.vectors import cross
from . import mesh_beam, shadow
from .emitters import (
    Lens,
    SourceSamples,
    angular_factor,
    is_isotropic,
    point_samples,
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
    # Per sample, how a move across the extended emitter turns the beam about the lens
    # centre: rotation vectors (K, 2, 3) per unit of the emitter's shape coordinates (a
    # landing point q, relative to the centre, moves by α × q); each sample's share of
    # the emitter (`emitters.SourceSamples`): its cell of an m × m grid on the shape.
    rotations: np.ndarray | None = None
    center: np.ndarray | None = None
    share_disc: bool = True
    share_cells: np.ndarray | None = None
    share_grid: int = 1
    # A glass mesh's beam (`mesh_beam`) is several grids: this one (the main sheet) and
    # its ``parts`` (the other paths' sheets, refined cells, splats), landed alike;
    # ``refined_cells`` / ``cut_cells``: cells refined, and splatted unrefined (the
    # refinement budget cut); ``traced_rays``: rays traced for it (sub-grids included).
    parts: list = dataclasses.field(default_factory=list)
    refined_cells: int = 0
    cut_cells: int = 0
    traced_rays: int = 0

    @property
    def shape(self) -> tuple[int, int, int]:
        return self.cell_flux.shape

    @property
    def total_flux(self) -> float:
        return float(self.cell_flux.sum()) + sum(p.total_flux for p in self.parts)

    @property
    def n_rays(self) -> int:
        return int(np.prod(self.exit_points.shape[:3])) + sum(p.n_rays for p in self.parts)

    @property
    def n_cells(self) -> int:
        return int(self.cell_flux.size) + sum(p.n_cells for p in self.parts)


def flatten_parts(beams: list[BeamGrid]) -> tuple[list[BeamGrid], np.ndarray]:
    """Every grid of ``beams`` as its own beam (the parts after their beam, each without
    parts) and, per grid, the index of the beam it belongs to."""
    flat, owner = [], []
    for i, b in enumerate(beams):
        for g in (b, *b.parts):
            flat.append(dataclasses.replace(g, parts=[]) if g.parts else g)
            owner.append(i)
    return flat, np.asarray(owner, dtype=np.int64)


#: The last few built lenses of kinds other than the ball, by record (kept with it, so
#: its id is not reused): a glass mesh's BVH is built once per Generate, not per trace.
_BUILT: dict[int, tuple] = {}
_BUILT_MAX = 16
#: ... and the last few glass meshes by their content (what was read from Blender):
#: Generate pressed again on an unchanged glass (a light moved, the camera) reuses its
#: BVH, surface walk and face groups (at 19 800 triangles 0.1–0.2 s of building).
_BY_CONTENT: dict[bytes, object] = {}
_CONTENT_MAX = 4


def clear_built() -> None:
    """Forget every built lens (the next trace builds its lens afresh)."""
    _BUILT.clear()
    _BY_CONTENT.clear()


def _content_key(lens: Lens) -> bytes | None:
    """A digest of a glass mesh record's kind, optics and arrays (None: not hashable)."""
    h = hashlib.blake2b(digest_size=16)
    h.update(
        repr((lens.kind, float(lens.radius), float(lens.ior), float(lens.absorption))).encode()
    )
    try:
        for a in (lens.center, *lens.params):
            if a is None:
                h.update(b"-")
                continue
            a = np.ascontiguousarray(a)
            h.update(repr((a.dtype.str, a.shape)).encode())
            h.update(a)
    except (TypeError, ValueError, BufferError):
        return None
    return h.digest()


def optics_of(lens: Lens):
    """The `core.lens` lens of a scene record: its ``kind`` from `kinds.LENS_KINDS`
    with its centre, radius, index, absorption and ``params`` (a kind other than the
    ball built once per record: the coarse and the final trace share it)."""
    if lens.kind == "ball":
        return kinds.make_lens(
            lens.kind, lens.center, lens.radius, lens.ior, lens.absorption, lens.params
        )
    hit = _BUILT.get(id(lens))
    if hit is not None and hit[0] is lens:
        return hit[1]
    key = _content_key(lens)
    optics = _BY_CONTENT.get(key) if key is not None else None
    if optics is None:
        optics = kinds.make_lens(
            lens.kind, lens.center, lens.radius, lens.ior, lens.absorption, lens.params
        )
        if key is not None:
            if len(_BY_CONTENT) >= _CONTENT_MAX:
                _BY_CONTENT.pop(next(iter(_BY_CONTENT)))
            _BY_CONTENT[key] = optics
    if len(_BUILT) >= _BUILT_MAX:
        _BUILT.pop(next(iter(_BUILT)))
    _BUILT[id(lens)] = (lens, optics)
    return optics


def frames_of(axes: np.ndarray) -> np.ndarray:
    """(K, 2, 3): :func:`.emitters.perpendicular_frame` of each unit axis (K, 3),
    vectorised (the same branch, so the same frames)."""
    a = np.asarray(axes, dtype=float)
    helper = np.where(np.abs(a[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    e1 = cross(helper, a)
    e1 /= np.linalg.norm(e1, axis=1)[:, None]
    return np.stack([e1, cross(a, e1)], axis=1)


@dataclass
class _Batch:
    """The samples of many (emitter, lens) pairs stacked along one axis of S samples,
    each with its own lens."""

    samples: list  # SourceSamples per pair
    lenses: list
    starts: np.ndarray  # (pairs + 1,) sample ranges
    points: np.ndarray  # (S, 3)
    axes: np.ndarray  # (S, 3) unit, from the sample toward the lens
    weights: np.ndarray  # (S,)
    parallel: np.ndarray  # (S,) bool
    center: np.ndarray  # (S, 3) of the lens' bounding sphere
    radius: np.ndarray  # (S,)
    valid: np.ndarray  # (S,) False: a point sample inside its sphere
    optics: list  # `core.lens` Lens per pair

    def counts(self) -> np.ndarray:
        return np.diff(self.starts)

    def stacked(self, extra_dims: int):
        """One lens over all S samples (then ``extra_dims`` axes of 1), or None when
        the pairs' kinds differ or the kind traces lens by lens."""
        kind = type(self.optics[0])
        if any(type(o) is not kind for o in self.optics):
            return None
        return kind.stack(self.optics, self.counts(), extra_dims)

    def part(self, k: int) -> _Batch:
        """The samples of pair ``k`` alone."""
        a, b = self.starts[k], self.starts[k + 1]
        sub = dataclasses.replace(
            self, samples=[self.samples[k]], lenses=[self.lenses[k]], optics=[self.optics[k]]
        )
        sub.starts = np.array([0, b - a])
        for name in ("points", "axes", "weights", "parallel", "center", "radius", "valid"):
            setattr(sub, name, getattr(self, name)[a:b])
        return sub


def _batch(pairs, n_source: int) -> _Batch:
    points = point_samples(pairs)
    samples = [
        sm if sm is not None else source_samples(e, lens, n_source)
        for sm, (e, lens) in zip(points, pairs, strict=True)
    ]
    lenses = [lens for _, lens in pairs]
    optics = [optics_of(lens) for lens in lenses]
    counts = [len(sm.weights) for sm in samples]
    rep = lambda v: np.repeat(np.asarray(v, dtype=float), counts, axis=0)  # noqa: E731
    spheres = [o.bounding_sphere() for o in optics]
    center = rep([np.asarray(c, dtype=float).reshape(3) for c, _ in spheres]).reshape(-1, 3)
    radius = rep([float(r) for _, r in spheres])
    points = np.concatenate([sm.points for sm in samples])
    parallel = np.repeat([sm.parallel for sm in samples], counts)
    dist = np.linalg.norm(points - center, axis=1)
    return _Batch(
        samples=samples,
        lenses=lenses,
        starts=np.concatenate([[0], np.cumsum(counts)]),
        points=points,
        axes=np.concatenate([sm.directions for sm in samples]),
        weights=np.concatenate([sm.weights for sm in samples]),
        parallel=parallel,
        center=center,
        radius=radius,
        valid=parallel | (dist > radius * (1.0 + 1e-9)),
        optics=optics,
    )


def _incoming(bt: _Batch, iota, phi, frames=None):
    """Origins and unit directions of the rays entering at (ι, φ) for every sample, and
    the Jacobian of their flux measure per unit (ι, φ) (sr or m² per rad²).
    ``iota``: (I,), ``phi``: (P,); outputs (S, I, P, …)."""
    frames = frames_of(bt.axes) if frames is None else frames  # (S, 2, 3)
    iota = np.asarray(iota, dtype=float)[None, :]
    sin_i, cos_i = np.sin(iota), np.cos(iota)
    radial = (
        np.cos(phi)[None, None, :, None] * frames[:, None, None, 0, :]
        + np.sin(phi)[None, None, :, None] * frames[:, None, None, 1, :]
    )  # (S, 1, P, 3)
    u = bt.axes[:, None, None, :]
    R = bt.radius[:, None]
    c = bt.center[:, None, None, :]
    par = bt.parallel[:, None]
    # a point sample: the cone of rays toward its sphere, ψ off the axis
    s = R / np.maximum(np.linalg.norm(bt.center - bt.points, axis=1)[:, None], R)
    sin_psi = np.where(par, 0.0, s * sin_i)
    cos_psi = np.sqrt((1.0 - sin_psi) * (1.0 + sin_psi))
    dirs = cos_psi[..., None, None] * u + sin_psi[..., None, None] * radial
    # a parallel sample: the rays at impact parameter b = R sin ι, from 4R before
    b = (R * sin_i)[..., None, None]
    par_origins = c - 4.0 * R[..., None, None] * u + b * radial
    origins = np.where(
        par[..., None, None], par_origins, np.broadcast_to(bt.points[:, None, None, :], dirs.shape)
    )
    # cos ψ = 0 only for a light on the sphere (an invalid sample, zeroed by the caller)
    point_jac = np.divide(
        s * s * sin_i * cos_i, cos_psi, out=np.zeros_like(cos_psi), where=cos_psi > 0.0
    )
    jac = np.where(par, R * R * sin_i * cos_i, point_jac)
    return origins, dirs, jac[:, :, None]


def _density(bt: _Batch, iota, phi, frames=None, dirs=None):
    """Flux per unit (ι, φ), shape (S, I, P)."""
    origins, d, jac = _incoming(bt, iota, phi, frames)
    dirs = d if dirs is None else dirs
    ang = np.ones(dirs.shape[:3])
    for k, sm in enumerate(bt.samples):  # only spots and area lights have a pattern
        if not sm.parallel and not is_isotropic(sm.emitter):
            a, b = bt.starts[k], bt.starts[k + 1]
            ang[a:b] = angular_factor(sm.emitter, dirs[a:b])
    iota = np.asarray(iota, dtype=float)
    lens = bt.stacked(2)  # (S, 1, 1) against ι (1, I, 1)
    closed = None if lens is None else lens.incidence_transmission(iota[None, :, None])
    if closed is not None:  # a function of ι alone (a ball): the same for every φ
        trans = closed[..., 0][..., None]
    else:
        origins = np.broadcast_to(origins, d.shape)
        trans = np.empty(d.shape[:3])
        for k in range(len(bt.optics)):
            a, b = bt.starts[k], bt.starts[k + 1]
            rays = _exit_rays(bt.part(k), origins[a:b], d[a:b])
            trans[a:b] = np.where(rays.hit, rays.weight, 0.0)  # a miss is not the beam
    return bt.weights[:, None, None] * ang * (trans * jac)


def _exit_rays(bt: _Batch, origins, dirs) -> ExitRays:
    """The rays (S, …, 3) through each sample's lens: in one call when the kind stacks."""
    lens = bt.stacked(dirs.ndim - 2)
    if lens is not None:
        return lens.trace(origins, dirs, aimed=True)
    parts = []
    for k, o in enumerate(bt.optics):
        a, b = bt.starts[k], bt.starts[k + 1]
        parts.append(o.trace(origins[a:b], dirs[a:b], aimed=True))
    return ExitRays(
        *(np.concatenate([getattr(p, f.name) for p in parts]) for f in dataclasses.fields(ExitRays))
    )


def _symmetric(bt: _Batch, k: int) -> bool:
    """Whether pair ``k``'s lens transmits as a function of ι alone (1-D quadrature)."""
    return bt.optics[k].incidence_transmission(np.zeros(1)) is not None


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
    return trace_beams([(emitter, lens)], n_radial, n_azimuth, n_source, [blockers])[0]


def trace_beams(pairs, n_radial: int = 64, n_azimuth: int = 256, n_source: int = 1, blockers=None):
    """:func:`trace_beam` of many (emitter, lens) pairs sharing one grid, in one
    vectorised pass (many lenses cost one set of array operations, not one each).
    ``blockers``: one `shadow.ShadowList` (or None) per pair."""
    if not pairs:
        return []
    blockers = list(blockers) if blockers is not None else [None] * len(pairs)
    meshes = [i for i, (_, lens) in enumerate(pairs) if _branching(lens.kind)]
    if meshes:
        out = [None] * len(pairs)
        rest = [i for i in range(len(pairs)) if i not in set(meshes)]
        traced = trace_beams(
            [pairs[i] for i in rest], n_radial, n_azimuth, n_source, [blockers[i] for i in rest]
        )
        for i, beam in zip(rest, traced, strict=True):
            out[i] = beam
        for i in meshes:
            out[i] = _mesh_beam(pairs[i], n_radial, n_azimuth, n_source, blockers[i])
        return out
    bt = _batch(pairs, n_source)
    nr, na = int(n_radial), int(n_azimuth)
    iota = 0.5 * math.pi * np.arange(nr + 1) / nr
    phi = 2.0 * math.pi * (np.arange(na) + 0.5) / na
    frames = frames_of(bt.axes)
    origins, dirs, _ = _incoming(bt, iota, phi, frames)
    origins = np.ascontiguousarray(np.broadcast_to(origins, dirs.shape))
    rays = _exit_rays(bt, origins, dirs)
    exit_p, exit_d = rays.points, rays.directions
    dens = _density(bt, iota, phi, frames, dirs)

    # 3 × 3 Gauss–Legendre points per cell; 1-D in ι where the sample is isotropic.
    n = len(bt.weights)
    di, dp = iota[1] - iota[0], phi[1] - phi[0]
    qi = (iota[:-1, None] + 0.5 * di * (1.0 + _GL_X)).reshape(-1)  # (Nr·3,)
    qp = (phi[:, None] - 0.5 * dp + 0.5 * dp * (1.0 + _GL_X)).reshape(-1)  # (Na·3,)
    radial = _density(bt, qi, np.zeros(1), frames)[:, :, 0]  # (S, Nr·3), no pattern at φ
    radial = (radial.reshape(n, nr, 3) * _GL_W).sum(-1) * 0.5 * di
    cell = np.repeat((radial * dp)[:, :, None], na, axis=2)
    for k, sm in enumerate(bt.samples):
        if (not sm.parallel and not is_isotropic(sm.emitter)) or not _symmetric(bt, k):
            a, b = bt.starts[k], bt.starts[k + 1]
            q = _density(bt.part(k), qi, qp, frames[a:b]).reshape(b - a, nr, 3, na, 3)
            cell[a:b] = np.einsum("kijab,j,b->kia", q, _GL_W, _GL_W) * 0.25 * di * dp
    for k, (sl, sm) in enumerate(zip(blockers or [None] * len(pairs), bt.samples, strict=True)):
        if sl is not None:
            a, b = bt.starts[k], bt.starts[k + 1]
            cell[a:b], dens[a:b] = shadow.apply(
                cell[a:b], dens[a:b], origins[a:b], dirs[a:b], pairs[k][1], sl, sm.parallel
            )
    cell = np.where(bt.valid[:, None, None], cell, 0.0)
    dens = np.where(bt.valid[:, None, None], dens, 0.0)
    out = []
    for k, ((emitter, lens), sm) in enumerate(zip(pairs, bt.samples, strict=True)):
        a, b = bt.starts[k], bt.starts[k + 1]
        color = np.asarray(getattr(emitter, "color", (1.0, 1.0, 1.0)), dtype=float)
        out.append(
            BeamGrid(
                exit_points=exit_p[a:b],
                exit_dirs=exit_d[a:b],
                node_density=dens[a:b],
                cell_flux=cell[a:b],
                valid=bt.valid[a:b],
                color=color * np.asarray(lens.tint, dtype=float),
                rotations=_share_rotations(sm, lens),
                center=np.asarray(lens.center, dtype=float),
                share_disc=sm.share_disc,
                share_cells=sm.share_cells,
                share_grid=sm.share_grid,
            )
        )
    return out


def _branching(kind: str) -> bool:
    """Whether lenses of ``kind`` follow several paths per ray (a glass mesh)."""
    cls = kinds.LENS_KINDS.get(kind)
    return cls is not None and cls.trace_branches is not lens_base.Lens.trace_branches


def _mesh_beam(pair, n_radial: int, n_azimuth: int, n_source: int, blockers) -> BeamGrid:
    """The beam of one (light, glass mesh) pair (`mesh_beam`): the main sheet with the
    other parts as its ``parts``."""
    emitter, lens = pair
    bt = _batch([pair], n_source)
    nr, na = int(n_radial), int(n_azimuth)
    iota = 0.5 * math.pi * np.arange(nr + 1) / nr
    phi = 2.0 * math.pi * (np.arange(na) + 0.5) / na
    frames = frames_of(bt.axes)
    sm = bt.samples[0]
    mb = mesh_beam.trace_mesh_beam(
        bt, bt.optics[0], iota, phi, frames, sm.emitter, sm.parallel, lens, blockers
    )
    color = np.asarray(getattr(emitter, "color", (1.0, 1.0, 1.0)), dtype=float)
    color = color * np.asarray(lens.tint, dtype=float)
    rot = _share_rotations(sm, lens)
    cells = sm.share_cells

    def grid(part) -> BeamGrid:
        r = part.rows
        return BeamGrid(
            exit_points=part.exit_points,
            exit_dirs=part.exit_dirs,
            node_density=part.node_density,
            cell_flux=part.cell_flux,
            valid=bt.valid[r],
            color=color,
            rotations=rot[r],
            center=np.asarray(lens.center, dtype=float),
            share_disc=sm.share_disc,
            share_cells=None if cells is None else np.asarray(cells)[r],
            share_grid=sm.share_grid,
        )

    main = grid(mb.parts[0])
    main.parts = [grid(p) for p in mb.parts[1:]]
    main.refined_cells, main.cut_cells, main.traced_rays = (
        mb.refined_cells,
        mb.cut_cells,
        mb.n_rays,
    )
    return main


def _share_rotations(samples: SourceSamples, lens: Lens) -> np.ndarray:
    """(K, 2, 3) rotation vectors of the beam about the lens centre per unit of the
    emitter's shape coordinates: the axis u turns by δu (−w/L for a point moved by w at distance L;
    the direction change itself for a parallel beam), so α = u × δu."""
    k = len(samples.weights)
    if samples.shares is None:
        return np.zeros((k, 2, 3))
    u = samples.directions[:, None, :]
    if samples.parallel:
        du = samples.shares
    else:
        dist = np.linalg.norm(np.asarray(lens.center, float) - samples.points, axis=1)
        du = -samples.shares / np.maximum(dist, lens.radius)[:, None, None]
    return cross(np.broadcast_to(u, du.shape), du)
