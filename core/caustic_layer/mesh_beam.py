"""The beam of one light through a glass mesh (`core.lens.mesh`): sheets, refined cells
and splats, so that no cell whose corners took different paths is drawn stretched.

The node rays are the (ι, φ) grid of `beam_trace` over the mesh's bounding sphere,
traced with every branch (`Lens.trace_branches`: internal reflections up to a budget). A
branch belongs to the beam when it went into the glass (two crossings or more; what the
outside reflects and what misses the glass is not the caustic). Each node's branches are
sorted by their path signature (the events and smooth face groups on the way), so that
slot b of neighbouring nodes that took the same paths is the same path. A cell is
*coherent* when its four corners carry the same set of paths: then slot b is one smooth
piece of sheet b over it, drawn by the layer as a quad (bilinear sub-cells); the path
with the most flux, and any path over more cells than a quarter of the grid's nodes, is
drawn on the node grid itself (neighbouring cells share their nodes: a quad of its own
lands four). A cell whose corners differ (a cube's edge, a rod's cap, the rim of what
reaches a face) is refined: an m × m sub-grid of rays is traced in it (each ray once:
refined cells side by side share their edge's rays, and its corners are node rays), its
coherent sub-cells drawn as quads; a sub-cell a path crosses in part, where its image
abuts the next path's (a cube's edge), as quads of the part up to where the path ends
(found by bisecting the sub-cell's sides, `EDGE_STEPS`); the rest landed as splats
(each sub-corner's branches as points carrying their share). Every such cell is
refined (the budget in proportion to their number); cells beyond its cap are splatted
at their own corners (``cut_cells``).

Flux: the emitter's density without the glass, g = I·A·dΩ/d(ι, φ) (or S·dA/d(ι, φ)),
is integrated over each cell by Gauss–Legendre points (no tracing: it is analytic), as
four corner-weighted integrals G_c = ∫ g · bilinear_c; a path's flux over the cell is
Σ_c G_c w_c with w_c its weight (Fresnel × Beer) at corner c. A splat of corner c carries
G_c w_c, so sheets, refinements and splats add up to the same integral: the traced flux
through the glass.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ..shared.vectors import norm
from . import shadow
from .emitters import angular_factor, is_isotropic

_GL_X, _GL_W = np.polynomial.legendre.leggauss(3)
_GL2_X, _GL2_W = np.polynomial.legendre.leggauss(2)
#: A path's signature is this where a node has no path in that slot.
_NONE = np.iinfo(np.uint64).max

#: Default budget of the branches in the layer: crossings per path, and the weight
#: below which a branch is dropped (a second partial internal reflection, ~0.2 %).
MAX_DEPTH = 8
MIN_WEIGHT = 5e-3
#: The refinement's sub-grid per side in each cell it refines (9 rays a cell): a cell
#: on an edge of the beam (a cube's edge, a rod's cap, the rim of what reaches a face)
#: is drawn from its sub-cells, so every such cell is refined, the budget in proportion
#: to how many there are (a flat 32 768-ray floor cut 6 889 of the real_glass ice
#: cube's 10 529 edge cells into their corners' points). The sub-cells still on the
#: edge land as points: at 2 × 2 a gap between them shows as a dark line along the ice
#: cube's bright face (L1 0.114); 5 × 5 closes it (0.080) for 2.4× the rays and 3.7×
#: the layer's sub-cells; 3 × 3 gave the pebble nothing for twice its CPU, and
#: refining the edge's sub-cells again (3 levels) cost the pebble 2.6× the rays.
REFINE_SUB = 2
#: ... at most this many times the node rays, or `REFINE_FLOOR` rays if more (then
#: the brightest cells first, at least 2 × 2 sub-cells each): a grid so coarse that
#: most of its cells straddle an edge is better served by more node rays
#: (`ray_budget`). Few cells share `REFINE_FLOOR` rays, up to 6 × 6 sub-cells each:
#: a few thousand rays cost milliseconds, and a cube under a point light (one image,
#: whose jags no other sample averages) needs its edges sharp.
REFINE_MAX_SHARE = 4.0
REFINE_FLOOR = 8192
#: A path of this weight that some corners of a cell have and others not: an edge in
#: the beam, the cell is refined (a first internal reflection, ~4 %, counts).
STRONG = 0.02
#: A sub-cell that a path crosses only in part (some of its corners carry the path,
#: the others the next face's: a cube's edge) is drawn to where the path ends
#: (`_clip_partial`): the end is found on each sub-cell edge by this many bisections
#: (that many rays an edge, within 2^-steps of the edge). Landed at its corners'
#: points instead, a strip along the edge's image got nothing: the ice cube's dark
#: line (`tests/core/caustic_layer/test_cube_edge.py`: the layer's least across the
#: edge 0.52 of the truth, L1 0.16, 11 793 rays; one step 0.55 / 0.11 / 13 949; two
#: 0.68 / 0.06 / 16 105; three 0.80 / 0.07 / 18 261).
EDGE_STEPS = 2
#: ... for a path of at least this weight at one of its corners (a direct
#: transmission; an internal reflection's strip is faint: its corners' points, no rays)
CLIP_WEIGHT = 0.1
#: ... and only where the next path's exit point at the edge's far corner lies within
#: this share of the glass's bounding radius of this path's (their images abut, as
#: across a cube's edge; where they do not, as where a smooth pebble's total
#: reflection sets in, nothing is dark between them: no rays spent, the pebble's
#: count unchanged).
ABUT = 0.1


@dataclass
class MeshPart:
    """One drawable part: rows (C,) are the source samples each row belongs to;
    nodes (C, Nr+1, Na) and cells (C, Nr, Na) as a `BeamGrid` (azimuth wraps)."""

    rows: np.ndarray
    exit_points: np.ndarray
    exit_dirs: np.ndarray
    node_density: np.ndarray
    cell_flux: np.ndarray


@dataclass
class MeshBeam:
    """The parts of one (light, mesh) pair, the first the main sheet (the node grid's
    slot 0), and the budget figures: cells refined, cells splatted unrefined (the
    budget cut), rays traced."""

    parts: list[MeshPart] = field(default_factory=list)
    refined_cells: int = 0
    cut_cells: int = 0
    n_rays: int = 0


def rays_at(bt, rows, iota, phi, frames, emitter, parallel: bool, rays: bool = True):
    """Origins, unit directions and flux density without the glass (per unit (ι, φ))
    of the rays entering the bounding sphere at (ι, φ) for the samples ``rows``; all
    arrays of one shape (elementwise `beam_trace._incoming` × the sample's weight and
    angular factor). ``rays`` False: the density alone (origins and directions None)
    where it needs no direction (a sun, an isotropic emitter: the corner integrals'
    nine points per cell)."""
    rows = np.asarray(rows)
    iota = np.asarray(iota, dtype=float)
    phi = np.asarray(phi, dtype=float)
    sin_i, cos_i = np.sin(iota), np.cos(iota)
    # sin of the sphere's half-angle from each sample, per sample once (then by row):
    # the same values as gathered per ray first
    reach = None
    if not parallel:
        reach = bt.radius / np.maximum(norm(bt.center - bt.points), bt.radius)
    if not rays and (parallel or is_isotropic(emitter)):
        r = bt.radius[rows]
        if parallel:
            jac = r * r * sin_i * cos_i
        else:
            s = reach[rows]
            sin_psi = s * sin_i
            cos_psi = np.sqrt((1.0 - sin_psi) * (1.0 + sin_psi))
            jac = np.divide(
                s * s * sin_i * cos_i, cos_psi, out=np.zeros_like(cos_psi), where=cos_psi > 0.0
            )
        jac = np.broadcast_to(jac, np.broadcast_shapes(np.shape(jac), np.shape(phi)))
        return None, None, np.where(bt.valid[rows], bt.weights[rows] * jac, 0.0)
    f = frames[rows]  # (…, 2, 3)
    radial = np.cos(phi)[..., None] * f[..., 0, :] + np.sin(phi)[..., None] * f[..., 1, :]
    u = bt.axes[rows]
    r = bt.radius[rows]
    c = bt.center[rows]
    if parallel:
        dirs = np.broadcast_to(u, radial.shape).copy()
        origins = c - 4.0 * r[..., None] * u + (r * sin_i)[..., None] * radial
        jac = r * r * sin_i * cos_i
    else:
        pts = bt.points[rows]
        s = reach[rows]
        sin_psi = s * sin_i
        cos_psi = np.sqrt((1.0 - sin_psi) * (1.0 + sin_psi))
        dirs = cos_psi[..., None] * u + sin_psi[..., None] * radial
        origins = np.broadcast_to(pts, dirs.shape).copy()
        jac = np.divide(
            s * s * sin_i * cos_i, cos_psi, out=np.zeros_like(cos_psi), where=cos_psi > 0.0
        )
    ang = 1.0 if parallel or is_isotropic(emitter) else angular_factor(emitter, dirs)
    valid = bt.valid[rows]
    return origins, dirs, np.where(valid, bt.weights[rows] * ang * jac, 0.0)


def corner_integrals(bt, rows, i0, di, p0, dp, frames, emitter, parallel, gl=(_GL_X, _GL_W)):
    """(…, 4) integrals of g × each corner's bilinear weight over the cells
    [i0, i0 + di] × [p0, p0 + dp] (arrays of one shape), corners in the layer's order
    (ι, φ), (ι + dι, φ), (ι + dι, φ + dφ), (ι, φ + dφ); Gauss–Legendre points ``gl``."""
    x, w = gl
    s = 0.5 * (1.0 + x)
    out = np.zeros((*np.shape(i0), 4))
    for a in range(len(x)):
        for b in range(len(x)):
            _, _, g = rays_at(
                bt, rows, i0 + di * s[a], p0 + dp * s[b], frames, emitter, parallel, rays=False
            )
            g = g * (0.25 * w[a] * w[b]) * di * dp
            bil = ((1 - s[a]) * (1 - s[b]), s[a] * (1 - s[b]), s[a] * s[b], (1 - s[a]) * s[b])
            for k in range(4):
                out[..., k] += g * bil[k]
    return out


#: Roberts' R2 sequence (the plastic number): the samples' grid offsets, well spread.
_R2 = (0.7548776662466927, 0.5698402909980532)


def staggered_grids(iota, phi, k: int) -> tuple[np.ndarray, np.ndarray]:
    """(K, Nr+1) and (K, Na): each of the ``k`` samples' node grid, the given one
    shifted by its own fraction of a cell (the R2 sequence, within ±½ a cell; sample 0
    unshifted): its ring edges inside (ι = 0 and the rim stay) and its azimuths. A
    bilinear quad cannot follow a fold (a rod's focal line) inside a cell, and on one
    grid every sample would make the same error in the same places: the rod's line in
    steps one cell long. Staggered, the samples' errors fall in different places and
    average out (the showcase rod on its 8 × 32 grid, 16 sun samples: its along-line
    variation 0.22 → 0.08, L1 0.58 → 0.26 against the glass tracer at 1 mm)."""
    iota = np.asarray(iota, dtype=float)
    phi = np.asarray(phi, dtype=float)
    i = np.arange(k, dtype=float)
    fi = np.modf(0.5 + i * _R2[0])[0] - 0.5
    fp = np.modf(0.5 + i * _R2[1])[0] - 0.5
    iota_k = np.tile(iota, (k, 1))
    iota_k[:, 1:-1] += fi[:, None] * 0.5 * (np.diff(iota)[None, :-1] + np.diff(iota)[None, 1:])
    dp = 2.0 * np.pi / max(len(phi), 1)
    return iota_k, phi[None, :] + fp[:, None] * dp


def _grid_corners(k, nr, na, wrap: bool):
    """Flat node indices (k·nr·na, 4) of each cell's corners on a (k, nr+1, na) node
    grid, in the layer's order; ``wrap``: the last column's cells close onto column 0
    (else there is one more node column than cells)."""
    cols = na if wrap else na + 1
    kk, ii, jj = np.meshgrid(np.arange(k), np.arange(nr), np.arange(na), indexing="ij")
    jn = (jj + 1) % cols

    def flat(i, j):
        return ((kk * (nr + 1) + i) * cols + j).reshape(-1)

    return np.stack([flat(ii, jj), flat(ii + 1, jj), flat(ii + 1, jn), flat(ii, jn)], axis=1)


@dataclass
class _Sorted:
    """A grid's cells sorted out: ``quads`` — each (cell, path) whose four corners all
    carry that path: cell index, path signature, the corners' node slots (Q, 4) —;
    ``splat`` — (cell, corner, slot) entries landed as points —; ``mixed`` (cells,):
    a path of weight ≥ ``strong`` at some corners only (refine it)."""

    q_cell: np.ndarray
    q_sig: np.ndarray
    q_slot: np.ndarray
    s_cell: np.ndarray
    s_corner: np.ndarray
    s_slot: np.ndarray
    mixed: np.ndarray


def _sort_cells(keep, sig, w, corners, strong: float) -> _Sorted:
    """Every cell's corner paths grouped by (cell, signature) (one sort)."""
    n_cells = len(corners)
    b, c, q, sg, wt = _corner_paths(keep, sig, w, corners)
    # a second path with one signature at one corner (rare): a splat
    first = np.ones(len(c), dtype=bool)
    first[1:] = (c[1:] != c[:-1]) | (sg[1:] != sg[:-1]) | (q[1:] != q[:-1])
    dup = ~first
    b1, c1, q1, sg1, wt1 = b[first], c[first], q[first], sg[first], wt[first]
    head = np.ones(len(c1), dtype=bool)
    head[1:] = (c1[1:] != c1[:-1]) | (sg1[1:] != sg1[:-1])
    gid = np.cumsum(head) - 1
    n_in = np.bincount(gid)
    full = n_in[gid] == 4
    top = np.zeros(len(n_in))
    np.maximum.at(top, gid, wt1)
    partial = ~full
    mixed = np.zeros(n_cells, dtype=bool)
    mixed[c1[partial & (top[gid] >= strong)]] = True
    # the full groups: 4 entries each, in corner order (sorted by q within a group)
    fh = np.nonzero(head & full)[0]
    q_slot = b1[fh[:, None] + np.arange(4)]
    return _Sorted(
        q_cell=c1[fh],
        q_sig=sg1[fh],
        q_slot=q_slot,
        s_cell=np.concatenate([c1[partial], c[dup]]),
        s_corner=np.concatenate([q1[partial], q[dup]]),
        s_slot=np.concatenate([b1[partial], b[dup]]),
        mixed=mixed,
    )


def _corner_paths(keep, sig, w, corners):
    """The kept (slot b, cell c, corner q) of every cell's corners with their path's
    signature and weight, ordered by (c, signature, q, −weight, b) (as one lexsort of
    those keys). Taken in (c, q, b) order, one stable sort by (c, signature) leaves
    (q, b) in order; only a signature twice at one corner (rare) needs its weights."""
    nb = keep.shape[0]
    kf = keep.reshape(nb, -1).T[corners]  # (C, 4, nb)
    c, q, b = np.nonzero(kf)
    node = corners[c, q]
    sg = sig.reshape(nb, -1)[b, node]
    wt = w.reshape(nb, -1)[b, node]
    order = np.lexsort((sg, c))
    b, c, q, sg, wt = b[order], c[order], q[order], sg[order], wt[order]
    same = (c[1:] == c[:-1]) & (sg[1:] == sg[:-1]) & (q[1:] == q[:-1])
    if np.any(same):  # those runs by weight, heaviest first, then by slot
        rows = np.nonzero(np.concatenate([[False], same]) | np.concatenate([same, [False]]))[0]
        run = np.cumsum(np.concatenate([[True], ~same]))[rows]
        sub = rows[np.lexsort((b[rows], -wt[rows], run))]
        for a in (b, c, q, sg, wt):
            a[rows] = a[sub]
    return b, c, q, sg, wt


def _quad_part(rows, slots, node, pts, dirs, g, w, flux) -> MeshPart:
    """Quads (Q cells of their own): nodes (Q, 2, 2) as corners (ι, φ), (ι, φ+),
    (ι+, φ), (ι+, φ+), cells (Q, 1, 2) of which the second (the azimuth's wrap) is
    empty. ``slots``, ``node``: (Q, 4) corner slots and flat nodes, layer order."""
    nb = pts.shape[0]
    p = pts.reshape(nb, -1, 3)[slots, node]  # (Q, 4, 3)
    d = dirs.reshape(nb, -1, 3)[slots, node]
    dens = g.reshape(-1)[node] * w.reshape(nb, -1)[slots, node]
    grid = [0, 3, 1, 2]  # layer order (00, 10, 11, 01) → node grid (00, 01, 10, 11)
    q = len(rows)
    cell = np.zeros((q, 1, 2))
    cell[:, 0, 0] = flux
    return MeshPart(
        rows=rows,
        exit_points=p[:, grid].reshape(q, 2, 2, 3),
        exit_dirs=d[:, grid].reshape(q, 2, 2, 3),
        node_density=dens[:, grid].reshape(q, 2, 2),
        cell_flux=cell,
    )


def _splat_part(rows, pts, dirs, flux) -> MeshPart:
    """Points as cells whose four corners are one point (nodes (S, 2, 1))."""
    two = lambda a: np.stack([a, a], axis=1)[:, :, None]  # noqa: E731
    return MeshPart(rows, two(pts), two(dirs), np.ones((len(rows), 2, 1)), flux[:, None, None])


def _draw(st: _Sorted, cells_ok, rows_of_cell, corners, pts, dirs, g, w, cg):
    """The quads and splats of the cells ``cells_ok`` (bool per cell)."""
    nb = pts.shape[0]
    wf = w.reshape(nb, -1)
    qk = cells_ok[st.q_cell]
    qc, qs = st.q_cell[qk], st.q_slot[qk]
    node = corners[qc]
    flux = np.einsum("qk,qk->q", cg[qc], wf[qs, node])
    quads = _quad_part(rows_of_cell[qc], qs, node, pts, dirs, g, w, flux)
    sk = cells_ok[st.s_cell]
    sc, sq, sb = st.s_cell[sk], st.s_corner[sk], st.s_slot[sk]
    sn = corners[sc, sq]
    sflux = cg[sc, sq] * wf[sb, sn]
    on = sflux > 0.0
    splat = (
        rows_of_cell[sc][on],
        pts.reshape(nb, -1, 3)[sb, sn][on],
        dirs.reshape(nb, -1, 3)[sb, sn][on],
        sflux[on],
    )
    return quads, st.q_sig[qk], qc, qs, splat


def trace_mesh_beam(
    bt,
    optics,
    iota,
    phi,
    frames,
    emitter,
    parallel: bool,
    lens,
    blockers=None,
    refine_rays: int | None = None,
    max_depth: int = MAX_DEPTH,
    min_weight: float = MIN_WEIGHT,
    strong: float = STRONG,
) -> MeshBeam:
    """The :class:`MeshBeam` of one (light, mesh) pair. ``bt``: the pair's samples (a
    `beam_trace` batch); ``iota`` (Nr+1,), ``phi`` (Na,): the node grid (φ_j the
    centres of Na equal sectors); ``frames`` (K, 2, 3); ``lens``: its scene record
    (the shadow's centre); ``refine_rays``: sub-grid rays at most (None:
    `REFINE_SUB` per side in every cell to refine, within `REFINE_MAX_SHARE` and
    `REFINE_FLOOR`); ``strong``: a path appearing at some corners of a cell with
    this weight makes the cell refined (weaker ones are splatted where they are)."""
    k = len(bt.weights)
    nr, na = len(iota) - 1, len(phi)
    dp = float(2.0 * np.pi / na)
    iota_k, phi_k = staggered_grids(iota, phi, k)
    di_k = np.diff(iota_k, axis=1)  # (K, Nr): each sample's ring widths
    rows = np.broadcast_to(np.arange(k)[:, None, None], (k, nr + 1, na))
    ii = np.broadcast_to(iota_k[:, :, None], rows.shape)
    pp = np.broadcast_to(phi_k[:, None, :], rows.shape)
    origins, dirs, g = rays_at(bt, rows, ii, pp, frames, emitter, parallel)
    br = optics.trace_branches(origins, dirs, max_depth, min_weight)
    keep = (br.crossings >= 2) & (br.weight > 0.0)  # through the glass: the caustic
    w = np.where(keep, br.weight, 0.0)
    ci0 = np.broadcast_to(np.arange(k)[:, None, None], (k, nr, na))
    c_i0 = np.broadcast_to(iota_k[:, :-1, None], ci0.shape)
    c_di = np.broadcast_to(di_k[:, :, None], ci0.shape)
    c_p0 = np.broadcast_to(phi_k[:, None, :], ci0.shape)
    cg = corner_integrals(bt, ci0, c_i0, c_di, c_p0, dp, frames, emitter, parallel)
    # the blockers' shadow: each cell × the mean of its corners' passing share
    per_cell, per_node = shadow.apply(
        np.ones((k, nr, na)), np.ones((k, nr + 1, na)), origins, dirs, lens, blockers, parallel
    )
    cg = (cg * per_cell[..., None]).reshape(-1, 4)
    g = g * per_node
    corners = _grid_corners(k, nr, na, wrap=True)
    st = _sort_cells(keep, br.signature, w, corners, strong)
    out = MeshBeam(n_rays=int(origins.size // 3))
    lit = np.einsum("ck,bck->c", cg, w.reshape(w.shape[0], -1)[:, corners])
    mixed = np.nonzero(st.mixed & (lit > 0.0))[0]
    n_mixed = max(len(mixed), 1)
    cap = max(int(REFINE_MAX_SHARE * out.n_rays), REFINE_FLOOR)
    budget = (
        min(max(n_mixed * (REFINE_SUB + 1) ** 2, REFINE_FLOOR), cap)
        if refine_rays is None
        else int(refine_rays)
    )
    m = int(np.clip(np.sqrt(budget / n_mixed) - 1.0, 2, 6))
    n_fit = budget // ((m + 1) ** 2)
    if len(mixed) > n_fit:  # the brightest cells refined; the rest drawn as they are
        mixed = np.sort(mixed[np.argsort(-lit[mixed], kind="stable")][:n_fit])
    out.refined_cells = int(len(mixed))
    out.cut_cells = int(np.count_nonzero(st.mixed & (lit > 0.0))) - out.refined_cells
    ok = np.ones(len(corners), dtype=bool)
    ok[mixed] = False
    cell_row = np.repeat(np.arange(k), nr * na)
    quads, q_sig, q_cell, q_slot, splat = _draw(
        st, ok, cell_row, corners, br.points, br.directions, g, w, cg
    )
    # The path with the most flux is the main sheet, on the node grid itself, and so is
    # any other path whose quads would land more nodes than the grid has (cells side by
    # side share their nodes on the grid; a quad of its own lands 4): the pebble's
    # partial internal reflection covers more cells than its direct path, and was the
    # main sheet when counted by cells, the direct path 16 748 quads.
    flux = quads.cell_flux[:, 0, 0]
    sheets = [np.zeros(len(q_sig), dtype=bool)]
    if len(q_sig):
        u, inv = np.unique(q_sig, return_inverse=True)
        cnt, fl = np.bincount(inv), np.bincount(inv, weights=flux)
        top = int(np.argmax(fl))
        wide = [j for j in np.argsort(-fl, kind="stable") if j != top and 4 * cnt[j] > g.size]
        sheets = [inv == j for j in [top, *wide]]
    out.parts = [
        _main_sheet(br, w, g, q_cell[s], corners[q_cell[s]], q_slot[s], flux[s]) for s in sheets
    ]
    rest = ~np.logical_or.reduce(sheets)
    if np.any(rest):
        out.parts.append(_take_rows(quads, rest))
    splats = [splat]
    if len(mixed):
        sub, sub_splat, n_sub = _refine(
            bt, optics, mixed, (k, nr, na), iota_k, phi_k, di_k, dp, m, frames, emitter, parallel,
            per_cell, max_depth, min_weight, br,
        )  # fmt: skip
        out.parts.append(sub)
        splats.append(sub_splat)
        out.n_rays += n_sub
    r = np.concatenate([s[0] for s in splats])
    if len(r):
        out.parts.append(
            _splat_part(
                r,
                np.concatenate([s[1] for s in splats]),
                np.concatenate([s[2] for s in splats]),
                np.concatenate([s[3] for s in splats]),
            )
        )
    out.parts = [p for i, p in enumerate(out.parts) if i == 0 or len(p.rows)]
    return out


def _take_rows(part: MeshPart, sel) -> MeshPart:
    return MeshPart(*(getattr(part, f)[sel] for f in MeshPart.__dataclass_fields__))


def _main_sheet(br, w, g, cells, nodes, slots, flux) -> MeshPart:
    """One path's quads back on the node grid (K, Nr+1, Na): ``cells`` (Q,) their
    flat cell indices, ``nodes``/``slots`` (Q, 4) their corners' nodes and slots,
    ``flux`` (Q,); every other node its first slot and no density (no cell of the
    sheet uses it: it carries none of the path's flux)."""
    k, nn, na = g.shape
    nb = w.shape[0]
    slot = np.zeros(k * nn * na, dtype=np.int64)
    slot[nodes.reshape(-1)] = slots.reshape(-1)
    used = np.zeros(k * nn * na, dtype=bool)
    used[nodes.reshape(-1)] = True
    cell = np.zeros(k * (nn - 1) * na)
    cell[cells] = flux
    node = np.arange(k * nn * na)
    pts = br.points.reshape(nb, -1, 3)[slot, node].reshape(k, nn, na, 3)
    dirs = br.directions.reshape(nb, -1, 3)[slot, node].reshape(k, nn, na, 3)
    dens = np.where(used, g.reshape(-1) * w.reshape(nb, -1)[slot, node], 0.0)
    dens = dens.reshape(k, nn, na)
    return MeshPart(np.arange(k), pts, dirs, dens, cell.reshape(k, nn - 1, na))


def _refine(
    bt, optics, cells, shape, iota, phi, di, dp, m, frames, emitter, parallel, per_cell,
    max_depth, min_weight, node_br,
):  # fmt: skip
    """Trace an m × m sub-grid in each of ``cells`` (flat indices of the (K, Nr, Na)
    grid; ``iota`` (K, Nr+1), ``di`` (K, Nr), ``phi`` (K, Na): each sample's grid):
    quads of its coherent sub-cells, splats for the rest. ``node_br``: the node grid's
    branches (B, K, Nr+1, Na), whose rays the sub-grids' corners are. Returns the
    parts and the rays traced here."""
    kc, ic, jc = np.unravel_index(cells, shape)
    c = len(cells)
    a = np.arange(m + 1) / m
    rows = np.broadcast_to(kc[:, None, None], (c, m + 1, m + 1))
    i_c, di_c, p_c = iota[kc, ic], di[kc, ic], phi[kc, jc]
    si = i_c[:, None, None] + di_c[:, None, None] * a[None, :, None]
    sp = p_c[:, None, None] + dp * a[None, None, :]
    si, sp = np.broadcast_arrays(si, sp)
    origins, dirs, g = rays_at(bt, rows, si, sp, frames, emitter, parallel)
    br, n_traced = _sub_branches(optics, node_br, shape, kc, ic, jc, m, origins, dirs,
                                 max_depth, min_weight)  # fmt: skip
    keep = (br.crossings >= 2) & (br.weight > 0.0)
    w = np.where(keep, br.weight, 0.0)
    sub_rows = np.broadcast_to(kc[:, None, None], (c, m, m))
    i0 = i_c[:, None, None] + di_c[:, None, None] * a[None, :-1, None]
    p0 = p_c[:, None, None] + dp * a[None, None, :-1]
    i0, p0 = np.broadcast_arrays(i0, p0)
    sub_di = np.broadcast_to(di_c[:, None, None] / m, i0.shape)
    cg = corner_integrals(
        bt, sub_rows, i0, sub_di, p0, dp / m, frames, emitter, parallel, (_GL2_X, _GL2_W)
    )
    cg = (cg * per_cell.reshape(-1)[cells][:, None, None, None]).reshape(-1, 4)
    g = g * per_cell.reshape(-1)[cells][:, None, None]
    corners = _grid_corners(c, m, m, wrap=False)
    st = _sort_cells(keep, br.signature, w, corners, np.inf)
    shade = per_cell.reshape(-1)[cells]

    def trace_at(cell, i_, p_):  # new rays in refined cells
        o, d, gg = rays_at(bt, kc[cell], i_, p_, frames, emitter, parallel)
        return optics.trace_branches(o, d, max_depth, min_weight), gg * shade[cell]

    sn = corners[st.s_cell, st.s_corner]
    entry_flux = cg[st.s_cell, st.s_corner] * w.reshape(w.shape[0], -1)[st.s_slot, sn]
    clipped, todo, n_edge = _clip_partial(
        st, entry_flux, br, g.reshape(-1), corners, np.stack([si, sp], axis=-1).reshape(-1, 2),
        np.arange(len(corners)) // (m * m), trace_at, ABUT * float(np.max(bt.radius)),
    )  # fmt: skip
    st = replace(st, s_cell=st.s_cell[todo], s_corner=st.s_corner[todo], s_slot=st.s_slot[todo])
    ok = np.ones(len(corners), dtype=bool)
    quads, _, _, _, splat = _draw(
        st, ok, sub_rows.reshape(-1), corners, br.points, br.directions, g, w, cg
    )
    if clipped is not None:
        clipped.rows = kc[clipped.rows]  # the refined cell's sample
        quads = MeshPart(*(np.concatenate([getattr(quads, f), getattr(clipped, f)])
                           for f in MeshPart.__dataclass_fields__))  # fmt: skip
    return quads, splat, n_traced + n_edge


def _carries(b, cols, sig):
    """Whether the traced rays ``cols`` of branches ``b`` (B, N) carry path ``sig``."""
    return np.any(
        (b.signature[:, cols] == sig) & (b.crossings[:, cols] >= 2) & (b.weight[:, cols] > 0.0),
        axis=0,
    )


def _slot_of(b, cols, sig):
    """The slot (per column) of the rays ``cols`` that carries path ``sig``."""
    hit = (b.signature[:, cols] == sig) & (b.crossings[:, cols] >= 2) & (b.weight[:, cols] > 0.0)
    return np.argmax(hit, axis=0)


@dataclass
class _Flat:
    """Branches (B, N) over N rays, flat (what `_clip_partial` reads)."""

    points: np.ndarray
    directions: np.ndarray
    weight: np.ndarray
    crossings: np.ndarray
    signature: np.ndarray

    @classmethod
    def of(cls, br):
        nb = br.weight.shape[0]
        keep = (br.crossings >= 2) & (br.weight > 0.0)
        return cls(
            br.points.reshape(nb, -1, 3),
            br.directions.reshape(nb, -1, 3),
            np.where(keep, br.weight, 0.0).reshape(nb, -1),
            br.crossings.reshape(nb, -1),
            br.signature.reshape(nb, -1),
        )


def _partial_groups(st, b: _Flat, corners, strong):
    """The (sub-cell, path) groups of a sort's splat entries whose corners are one run
    of 1–3 neighbours (cyclic) and whose path has ``strong`` weight at one of them:
    (entry order, group of each ordered entry, the groups' ids, sub-cells, paths, first
    corner of the run, run length)."""
    node = corners[st.s_cell, st.s_corner]
    sig = b.signature[st.s_slot, node]
    order = np.lexsort((st.s_corner, sig, st.s_cell))
    cell, psig, corner = st.s_cell[order], sig[order], st.s_corner[order]
    head = np.ones(len(cell), dtype=bool)
    head[1:] = (cell[1:] != cell[:-1]) | (psig[1:] != psig[:-1])
    gid = np.cumsum(head) - 1
    n_g = int(gid[-1]) + 1 if len(gid) else 0
    bits = np.zeros(n_g, dtype=np.int64)
    np.bitwise_or.at(bits, gid, np.left_shift(1, corner))
    count = np.bincount(gid, minlength=n_g)
    top = np.zeros(n_g)
    np.maximum.at(top, gid, b.weight[st.s_slot[order], node[order]])
    pop = np.array([bin(x).count("1") for x in range(16)])[bits]
    # a corner twice (two rays of one path) or two opposite corners: landed as points
    ok = (pop == count) & (bits != 0b0101) & (bits != 0b1010) & (top >= strong)
    present = (bits[:, None] >> np.arange(4)) & 1
    first = np.argmax(present & (1 - np.roll(present, 1, axis=1)), axis=1)
    sel = np.nonzero(ok)[0]
    return order, gid, sel, cell[head][sel], psig[head][sel], first[sel], count[sel]


def _edge_ends(ends, sig, own_slot, aim, b: _Flat, g_nodes, params, cell_of, trace, steps):
    """Where each group's path ends along the sub-cell edge ``ends`` (E, 2: its own
    corner, the corner without it): the end's (ι, φ) and the landing, direction and
    density g·w there. Edges with ``aim`` are bisected ``steps`` times (once per edge,
    aimed at its strongest path ending there); the vertex is midway between the last
    ray that carries the path and the first that does not (the flux reaches the edge)
    and lands where that last ray does. Elsewhere: mid-edge, at the own corner's
    landing (the corners' bilinear shares as before). Returns them and the rays."""
    own = ends[:, 0]
    vp = b.points[own_slot, own]
    vd = b.directions[own_slot, own]
    dens = g_nodes[own] * b.weight[own_slot, own]
    u_mid = np.full(len(ends), 0.5)
    idx = np.nonzero(aim)[0]
    if len(idx) == 0 or steps == 0:
        return _lerp(params, ends, u_mid), vp, vd, dens, 0
    a, z = ends[idx, 0], ends[idx, 1]
    key = np.minimum(a, z) * (len(params) + 1) + np.maximum(a, z)
    _, e_of = np.unique(key, return_inverse=True)
    wt = b.weight[own_slot[idx], a]
    best = np.lexsort((-wt, e_of))
    head = np.ones(len(best), dtype=bool)
    head[1:] = e_of[best][1:] != e_of[best][:-1]
    tgt = best[head]  # per edge, its strongest ending path's entry
    e_in, e_out, e_sig = a[tgt], z[tgt], sig[idx][tgt]
    p_in, p_out, e_cell = params[e_in], params[e_out], cell_of[idx][tgt]
    lo, hi = np.zeros(len(tgt)), np.ones(len(tgt))
    ts, rays = [], []
    for _ in range(steps):
        t = 0.5 * (lo + hi)
        par = p_in + t[:, None] * (p_out - p_in)
        br, gg = trace(e_cell, par[:, 0], par[:, 1])
        has = _carries(br, slice(None), e_sig)
        lo, hi = np.where(has, t, lo), np.where(has, hi, t)
        ts.append(t)
        rays.append((br, gg))
    # each entry along its edge from its own corner (u = 0) to the other (u = 1)
    flip = a != e_in[e_of]
    u_s = np.stack([np.where(flip, 1.0 - t[e_of], t[e_of]) for t in ts], axis=1)
    carry = np.stack([_carries(br, e_of, sig[idx]) for br, _ in rays], axis=1)
    u_next = np.min(np.where(carry, 1.0, u_s), axis=1)
    before = carry & (u_s < u_next[:, None])
    u_last = np.max(np.where(before, u_s, 0.0), axis=1)
    pick = np.argmax(np.where(before, u_s, -1.0), axis=1)
    u_mid[idx] = 0.5 * (u_last + u_next)
    for s, (br, gg) in enumerate(rays):
        j = np.nonzero((u_last > 0.0) & (pick == s))[0]
        if len(j) == 0:
            continue
        col = e_of[j]
        slot = _slot_of(br, col, sig[idx][j])
        vp[idx[j]] = br.points[slot, col]
        vd[idx[j]] = br.directions[slot, col]
        dens[idx[j]] = gg[col] * br.weight[slot, col]
    return _lerp(params, ends, u_mid), vp, vd, dens, steps * len(tgt)


def _lerp(params, ends, u):
    a, z = params[ends[:, 0]], params[ends[:, 1]]
    return a + u[:, None] * (z - a)


def _clip_partial(st, entry_flux, br, g_nodes, corners, params, cell_of, trace, abut,
                  steps=EDGE_STEPS, strong=CLIP_WEIGHT):  # fmt: skip
    """Sub-cells straddling an edge of the beam, drawn to the edge: each (sub-cell,
    path) the path reaches at a run of 1–3 neighbouring corners only, one of whose ends
    abuts the next path's (`ABUT`), becomes a polygon — those corners and, on the two
    sub-cell edges the path ends on, its end (`_edge_ends`) — drawn as quads (a 5-gon:
    a quad and a triangle; a triangle: a quad with a repeated corner). Each sub-cell's
    polygons carry what their corners' points carried (``entry_flux``, the traced flux
    unchanged), shared in proportion to their own ∫ g·w (a fan, g·w linear): where
    three paths or more meet in one sub-cell their polygons leave part of it
    uncovered.

    ``st``: the sub-grid's sort (`_sort_cells`); ``br``: its branches (B, N…) over its
    N nodes, ``g_nodes`` (N,); ``corners`` (S, 4) each sub-cell's nodes; ``params``
    (N, 2) each node's (ι, φ); ``cell_of`` (S,) each sub-cell's refined cell;
    ``trace(cells, iota, phi)`` → (branches, g) of new rays in those refined cells;
    ``abut``: `ABUT` as a length. Returns (the quads as a `MeshPart` with ``rows`` the
    refined cells, or None; per splat entry of ``st`` whether it is still a point;
    rays traced)."""
    b = _Flat.of(br)
    todo = np.ones(len(st.s_cell), dtype=bool)
    order, gid, sel, gc, gs, f0, n_run = _partial_groups(st, b, corners, strong)
    if len(sel) == 0:
        return None, todo, 0
    ar = np.arange(len(sel))
    c4 = corners[gc]
    last = (f0 + n_run - 1) % 4
    ends = np.concatenate(
        [
            np.stack([c4[ar, f0], c4[ar, (f0 - 1) % 4]], axis=1),  # where the run enters
            np.stack([c4[ar, last], c4[ar, (last + 1) % 4]], axis=1),  # where it leaves
        ]
    )
    sig2 = np.concatenate([gs, gs])
    own_slot = _slot_of(b, ends[:, 0], sig2)
    far_slot = np.argmax(b.weight[:, ends[:, 1]], axis=0)
    gap = np.linalg.norm(b.points[own_slot, ends[:, 0]] - b.points[far_slot, ends[:, 1]], axis=-1)
    aim = (b.weight[far_slot, ends[:, 1]] > 0.0) & (gap < abut)
    n = len(sel)
    take = aim[:n] | aim[n:]
    if not np.any(take):
        return None, todo, 0
    both = np.concatenate([take, take])
    sel, gc, f0, n_run, c4, ar = (
        sel[take],
        gc[take],
        f0[take],
        n_run[take],
        c4[take],
        ar[: take.sum()],
    )
    ends, sig2, own_slot, aim = ends[both], sig2[both], own_slot[both], aim[both]
    n = len(sel)
    vpar, vp, vd, vdens, n_traced = _edge_ends(
        ends, sig2, own_slot, aim, b, g_nodes, params, np.concatenate([cell_of[gc]] * 2), trace,
        steps,
    )  # fmt: skip
    # polygon vertices (G, 5): the entering end, the run (padded by the leaving end),
    # the leaving end
    run = c4[ar[:, None], (f0[:, None] + np.arange(3)) % 4]
    rslot = _slot_of(b, run.reshape(-1), np.repeat(sig2[:n], 3)).reshape(n, 3)
    pad = np.arange(3)[None, :] >= n_run[:, None]

    def vertices(at_end, at_run):
        out = np.concatenate([at_end[:n, None], at_run, at_end[n:, None]], axis=1)
        out[:, 1:4][pad] = np.broadcast_to(at_end[n:, None], at_run.shape)[pad]
        return out

    poly = [
        vertices(vpar, params[run]),
        vertices(vp, b.points[rslot, run]),
        vertices(vd, b.directions[rslot, run]),
        vertices(vdens, g_nodes[run] * b.weight[rslot, run]),
    ]
    tri = np.nonzero(n_run == 3)[0]  # a 5-gon: the quad 0–3 and the triangle 0, 3, 4
    pick = [(np.arange(n), [0, 1, 2, 3]), (tri, [0, 3, 4, 4])]
    par, pts, dirs, dens = (np.concatenate([v[g][:, k] for g, k in pick]) for v in poly)
    sub = np.concatenate([gc[g] for g, _ in pick])
    flux = _fan_integral(par, dens)
    n_s = len(corners)
    picked = np.isin(gid, sel)
    was = np.bincount(st.s_cell[order][picked], entry_flux[order][picked], n_s)
    now = np.bincount(sub, flux, n_s)
    good = now > 0.0
    flux = flux * np.divide(was, now, out=np.zeros(n_s), where=good)[sub]
    keep = good[sub]
    todo[order] = ~(picked & good[st.s_cell[order]])
    q = int(np.count_nonzero(keep))
    grid = [0, 3, 1, 2]  # cyclic (the layer's order) → node grid (00, 01, 10, 11)
    cell = np.zeros((q, 1, 2))
    cell[:, 0, 0] = flux[keep]
    part = MeshPart(
        rows=cell_of[sub[keep]],
        exit_points=pts[keep][:, grid].reshape(q, 2, 2, 3),
        exit_dirs=dirs[keep][:, grid].reshape(q, 2, 2, 3),
        node_density=dens[keep][:, grid].reshape(q, 2, 2),
        cell_flux=cell,
    )
    return part, todo, n_traced


def _fan_integral(par, dens):
    """∫ of a density over quads (Q, 4) in (ι, φ): vertices ``par`` (Q, 4, 2) in
    cyclic order (one may repeat), ``dens`` (Q, 4) at them, linear over the fan's two
    triangles (0, 1, 2) and (0, 2, 3)."""

    def tri(a, b, c):
        u, v = par[:, b] - par[:, a], par[:, c] - par[:, a]
        area = 0.5 * np.abs(u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0])
        return area * (dens[:, a] + dens[:, b] + dens[:, c]) / 3.0

    return tri(0, 1, 2) + tri(0, 2, 3)


def _sub_branches(optics, node_br, shape, kc, ic, jc, m, origins, dirs, max_depth, min_weight):
    """The branches (B, C, m+1, m+1) of the refined cells' sub-grid rays, each ray
    traced once: cells side by side share the rays of their common edge, and a
    sub-grid's corners are rays of the node grid (``node_br``), traced already (the
    same (ι, φ) but for the last bit of a far edge's sum). Returns them and the
    number of rays traced (about half of 9 per cell in a band of refined cells)."""
    k, nr, na = shape
    c = len(kc)
    s = np.arange(m + 1)
    big_i = np.broadcast_to(ic[:, None, None] * m + s[None, :, None], (c, m + 1, m + 1))
    big_j = (jc[:, None, None] * m + s[None, None, :]) % (na * m)  # φ wraps
    big_j = np.broadcast_to(big_j, big_i.shape)
    key = (kc[:, None, None] * (nr * m + 1) + big_i) * (na * m) + big_j
    _, first, inverse = np.unique(key.reshape(-1), return_index=True, return_inverse=True)
    fi, fj = big_i.reshape(-1)[first], big_j.reshape(-1)[first]
    on_node = (fi % m == 0) & (fj % m == 0)
    node = (kc[first // (m + 1) ** 2] * (nr + 1) + fi // m) * na + fj // m
    new = first[~on_node]
    traced = optics.trace_branches(
        origins.reshape(-1, 3)[new], dirs.reshape(-1, 3)[new], max_depth, min_weight
    )
    nb = max(node_br.weight.shape[0], traced.weight.shape[0])
    out = {}
    for f in ("points", "directions", "weight", "crossings", "signature"):
        a, b = getattr(node_br, f), getattr(traced, f)
        tail = a.shape[1 + len(shape) :]
        col = np.zeros((nb, len(first), *tail), dtype=a.dtype)
        col[: a.shape[0], on_node] = a.reshape(a.shape[0], -1, *tail)[:, node[on_node]]
        col[: b.shape[0], ~on_node] = b
        out[f] = col[:, inverse].reshape(nb, c, m + 1, m + 1, *tail)
    return _SubBranches(**out), len(new)


@dataclass
class _SubBranches:
    """The `BranchRays` fields a refinement reads."""

    points: np.ndarray
    directions: np.ndarray
    weight: np.ndarray
    crossings: np.ndarray
    signature: np.ndarray
