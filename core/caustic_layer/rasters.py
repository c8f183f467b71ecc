"""The caustic layer: the landed ray grids accumulated into irradiance rasters.

Each beam's node rays are landed on the receivers (nearest hit beyond the exit point).
A grid cell whose four corners land on the same planar patch spreads its flux over the
landed quad: it is cut into m × m sub-cells (m from the quad's landed size, 2 per
texel, up to 8 per side freely and beyond that as its share of the flux allows), each
placed by bilinear interpolation of the four landed corners and weighted by
the bilinear interpolation of the corners' flux densities, normalised to the cell's
flux. Sub-cells are deposited into a regular raster in the patch's plane, so where the
landed quads overlap (past the focus, at the caustic's folds) their flux adds instead of
z-fighting. A cell whose corners land on different patches (an edge between receivers)
gives each corner its density-weighted share; corners that miss every receiver carry
their share into ``flux_lost``. Flux that lands on a patch beyond its raster is
``flux_outside``. So emitted = rasters + outside + lost.

One raster per patch that any ray reaches, or per cluster of beams whose footprints
overlap on it (so rasters never overlap and each resolves its own caustics):
``resolution`` × ``resolution`` texels over the flux-weighted extent of the landings
(the quantiles ``clip_fraction/2`` and ``1 − clip_fraction/2``: a few grazing rays land
very far away). A lens beam is a small
bright core in a wide faint halo, so the texel lines are spaced by a separable sinh warp,
``x = c + s·sinh(ξ)`` with ξ uniform, centred on the flux's median ``c`` with ``s`` its
median distance from it: texels are fine in the core and grow in the halo, and the faces
stay rectangles that do not overlap. The resolution is a parameter, so the layer's
topology is fixed while a light moves; with the camera's ``view`` each raster spans
only the landings in view and has its own resolution (texels per pixel there), and a
coarse raster over the whole caustic takes what lands out of view. With a view the
beams are clustered by their glass's bulk where a faint tail spreads far beyond it
(`bulk_boxes`: a rod's light reflected out of its side), the tail drawn by the coarse
raster: a caustic keeps a raster of its own instead of one spanning the table. Per
patch the output is plain data for one emissive mesh: a grid of vertices lifted by
``offset`` along the normal toward the light (no z-fighting), quad faces, the
irradiance per texel (W/m², RGB = flux × light colour × lens tint) and the receiver's
UV at each vertex (emission = irradiance × albedo / π); `smooth.drawn_mesh` turns it
into the mesh drawn, continuous across texels.
"""

from __future__ import annotations

import dataclasses
import functools
import time
from dataclasses import dataclass, field

import numpy as np

from ..shared import parallel
from .beam_trace import BeamGrid, flatten_parts
from .emitters import perpendicular_frame, share_offsets
from .receiver_index import ReceiverIndex, intersect
from .receiver_patches import ReceiverPatch
from .view import View


@dataclass
class PatchLayer:
    """The caustic on one planar receiver patch (texel (iy, ix) = face iy·res + ix)."""

    patch: int  # index into the patch list
    sources: np.ndarray  # indices of the beams whose caustic this raster holds
    object_id: int
    normal: np.ndarray  # (3,) unit, toward the side the light arrives from
    axis_u: np.ndarray  # (3,) in-plane; axis_u × axis_v = normal
    axis_v: np.ndarray
    origin: np.ndarray  # (3,) the plane's point at (u, v) = (0, 0)
    edges_u: np.ndarray  # (res+1,) texel lines: world = origin + u·axis_u + v·axis_v
    edges_v: np.ndarray  # (res+1,)
    resolution: int
    irradiance: np.ndarray  # (res, res, 3) W/length² per texel (rows: v, columns: u)
    flux: float  # W (uncoloured) deposited in the raster
    flux_outside: float  # W landed on the patch beyond the raster
    vertices: np.ndarray  # ((res+1)², 3) lifted by the offset along ``normal``
    faces: np.ndarray  # (res², 4) vertex indices, counter-clockwise about normal
    uvs: np.ndarray | None  # ((res+1)², 2) the receiver's UV at each vertex
    uv_inside: np.ndarray | None  # ((res+1)²,) False: beyond the patch (UV extrapolated);
    #                               None: the patch's UV is affine, valid everywhere
    axes: tuple | None = None  # ((c, s, ξ0, dξ) along u, along v): the texel lines' warp
    coarse: bool = False  # the coarse raster of a caustic out of the camera's view

    @property
    def face_irradiance(self) -> np.ndarray:
        return self.irradiance.reshape(-1, 3)

    def texel_areas(self) -> np.ndarray:
        """(res, res) areas of the faces (length²)."""
        return np.diff(self.edges_v)[:, None] * np.diff(self.edges_u)[None, :]

    def texel_centers(self) -> np.ndarray:
        """World positions (res, res, 3) of the texel centres, on the plane."""
        cu = 0.5 * (self.edges_u[1:] + self.edges_u[:-1])
        cv = 0.5 * (self.edges_v[1:] + self.edges_v[:-1])
        return self.origin + cu[None, :, None] * self.axis_u + cv[:, None, None] * self.axis_v

    def texel_flux(self) -> np.ndarray:
        """(res, res, 3) flux (W) of each texel."""
        return self.irradiance * self.texel_areas()[..., None]


#: The fields of a raster axis's texel lines c + s·sinh(ξ0 + i·dξ), in `PatchLayer.axes`.
AXIS_FIELDS = ("c", "s", "xi0", "dxi")


@dataclass(frozen=True)
class RasterFrame:
    """A raster given to :func:`build_layer` instead of the one it would fit to this
    frame's landings (the bake's fixed topology, ``core/animation/layer_segments.py``): on patch
    ``patch`` of the index, for the beams ``beams``, in the plane frame (``normal``,
    ``axis_u``, ``axis_v``) with the texel lines ``axes`` (as ``PatchLayer.axes``)."""

    patch: int
    beams: tuple
    normal: np.ndarray
    axis_u: np.ndarray
    axis_v: np.ndarray
    axes: tuple
    coarse: bool = False  # a coarse raster: it takes what lands beyond the other one


@dataclass
class CausticLayer:
    patches: list[PatchLayer]
    flux_emitted: float  # W leaving the lenses (all beams)
    flux_in_rasters: float
    flux_outside: float  # landed on a patch, beyond its raster
    flux_lost: float  # missed every receiver
    n_rays: int
    n_cells: int
    n_subcells: int
    timings: dict = field(default_factory=dict)


@dataclass
class _Landed:
    beam: BeamGrid
    patch: np.ndarray  # (N,) patch of each node ray, −1 = miss
    point: np.ndarray  # (N, 3)
    dirs: np.ndarray  # (N, 3)
    node_flux: np.ndarray  # (N,) a quarter of each adjacent cell's flux


def cell_corners(shape) -> np.ndarray:
    """Flat node indices (K·Nr·Na, 4) of each cell's corners, in the order
    (i, j), (i+1, j), (i+1, j+1), (i, j+1), for a beam of cell shape (K, Nr, Na).
    Read-only, shared between beams of one shape."""
    return _cell_corners(tuple(int(n) for n in shape))


@functools.lru_cache(maxsize=32)
def _cell_corners(shape) -> np.ndarray:
    k, nr, na = shape
    kk, ii, jj = np.meshgrid(np.arange(k), np.arange(nr), np.arange(na), indexing="ij")
    jn = (jj + 1) % na

    def flat(i, j):
        return ((kk * (nr + 1) + i) * na + j).reshape(-1)

    out = np.stack([flat(ii, jj), flat(ii + 1, jj), flat(ii + 1, jn), flat(ii, jn)], axis=1)
    out.setflags(write=False)
    return out


def weighted_quantile(x, w, q):
    o = np.argsort(x)
    cw = np.cumsum(w[o])
    return float(np.interp(q * cw[-1], cw, x[o]))


def _group_order(x, groups, n_groups: int) -> np.ndarray:
    """np.lexsort((x, groups)): the order by group, then by x (stable). Groups already
    in order (contiguous runs, as the rasters' and beams' landings are) and long are
    sorted run by run: twice as fast as one two-key lexsort."""
    groups = np.asarray(groups)
    # short runs: one lexsort is cheaper than a sort call per run
    if len(groups) < 64 * max(n_groups, 1) or not np.all(groups[1:] >= groups[:-1]):
        return np.lexsort((x, groups))
    bounds = np.searchsorted(groups, np.arange(n_groups + 1)).tolist()
    return np.concatenate(
        [np.zeros(0, dtype=np.intp)]
        + [
            a + np.argsort(x[a:b], kind="stable")
            for a, b in zip(bounds[:-1], bounds[1:], strict=True)
        ]
    )


def regroup(order_x, groups, n_groups: int) -> np.ndarray:
    """`_group_order` (by group, then x, then index) from ``order_x``, a stable order
    of x (``np.argsort(x, kind="stable")``): one stable sort of the small group ids
    along it (a radix sort), not a sort of x again."""
    g = groups[order_x]
    if n_groups < 1 << 15:
        g = g.astype(np.int16)
    return order_x[np.argsort(g, kind="stable")]


def sub_order(order_x, rows, n: int) -> np.ndarray | None:
    """The stable order of x[rows] from ``order_x`` (that of all ``n`` of x), ``rows``
    increasing (then ties keep their order); None when they are not."""
    rows = np.asarray(rows)
    if len(rows) > 1 and not np.all(rows[1:] > rows[:-1]):
        return None
    pos = np.full(n, -1, dtype=np.int64)
    pos[rows] = np.arange(len(rows))
    p = pos[order_x]
    return p[p >= 0]


def grouped_quantiles(x, w, groups, n_groups: int, qs, order=None) -> np.ndarray:
    """Weighted quantiles ``qs`` of ``x`` within each group (ids 0..n_groups−1, every
    group non-empty): (n_groups, len(qs)), the values where the group's cumulative
    weight first reaches each share (one sort for all groups; ``order``: that sort,
    `_group_order`'s, if known)."""
    o = _group_order(x, groups, n_groups) if order is None else order
    g, xs, ws = groups[o], x[o], w[o]
    cw = np.cumsum(ws)
    total = np.bincount(g, weights=ws, minlength=n_groups)
    start = np.concatenate([[0.0], np.cumsum(total)[:-1]])
    share = (cw - start[g]) / np.where(total > 0, total, 1.0)[g]  # (0, 1] per group
    key = g + np.minimum(share, 1.0 - 1e-12)
    ends = np.cumsum(np.bincount(g, minlength=n_groups))
    out = np.empty((n_groups, len(qs)))
    for j, q in enumerate(qs):
        i = np.searchsorted(key, np.arange(n_groups) + q * (1.0 - 1e-12))
        out[:, j] = xs[np.minimum(i, ends - 1)]
    return out


def land_beams(
    beams: list[BeamGrid], index: ReceiverIndex, own_objects=None, t_min_rel: float = 1e-7
) -> list[_Landed]:
    """Land every node ray of every beam (all beams in one vectorised cast): nearest hit
    with t > −t_min_rel × the exit points' spread, so a receiver touching the sphere (a
    resting marble) still counts. ``own_objects``: per beam the object id of its lens'
    own mesh if the receivers include it (or −1): hits on it are skipped, the ray goes
    on from there (a lens is not its own receiver; other lenses may be receivers)."""
    o = np.concatenate([b.exit_points.reshape(-1, 3) for b in beams])
    d = np.concatenate([b.exit_dirs.reshape(-1, 3) for b in beams])
    sizes = [len(b.exit_points.reshape(-1, 3)) for b in beams]
    # each beam's spread of exit points, all beams by one reduceat per bound
    first = np.concatenate([[0], np.cumsum(sizes)[:-1]])
    spread = np.maximum.reduceat(o, first) - np.minimum.reduceat(o, first)
    scale = np.repeat(np.maximum(spread.max(axis=1), 1e-300), sizes)
    h = intersect(index, o, d, t_min=-t_min_rel * scale)
    tri, point = h.triangle, h.point
    if own_objects is not None:
        own = np.repeat(np.asarray(own_objects, dtype=np.int64), sizes)
        ids = index.mesh.ids
        for _ in range(4):  # a convex lens mesh: at most a few hits
            again = np.nonzero((tri >= 0) & (ids[np.maximum(tri, 0)] == own))[0]
            if not len(again):
                break
            h2 = intersect(index, o[again], d[again], t_min=h.t[again] * (1 + 1e-9) + 1e-12)
            tri[again], point[again] = h2.triangle, h2.point
            h.t[again] = h2.t
    patch = np.where(tri >= 0, index.patch_of[np.maximum(tri, 0)], -1)
    # a sample with no beam (its light inside the sphere) lands nowhere
    valid = np.repeat(
        np.concatenate([b.valid for b in beams]),
        np.concatenate(
            [np.full(len(b.valid), n // len(b.valid)) for b, n in zip(beams, sizes, strict=True)]
        ),
    )
    patch = np.where(valid, patch, -1)
    # each node a quarter of its cells' flux: one bincount over all beams' corners
    starts = np.concatenate([[0], np.cumsum(sizes)])
    corners = np.concatenate(
        [cell_corners(b.shape) + s for b, s in zip(beams, starts[:-1].tolist(), strict=True)]
    )
    quarter = np.concatenate([0.25 * b.cell_flux.reshape(-1) for b in beams])
    node_flux = np.bincount(
        corners.reshape(-1), weights=np.repeat(quarter, 4), minlength=int(starts[-1])
    )
    out = []
    for b, a, e in zip(beams, starts[:-1].tolist(), starts[1:].tolist(), strict=True):
        out.append(_Landed(b, patch[a:e], point[a:e], d[a:e], node_flux[a:e]))
    return out


def build_layer(
    beams: list[BeamGrid],
    index: ReceiverIndex,
    resolution: int = 128,
    clip_fraction: float = 1e-3,
    warp: bool = True,
    subcells_per_texel: float = 2.0,
    max_subdivision: int = 16,
    max_subcells: int = 8_000_000,
    flux_subcells_per_texel: float = 8.0,
    offset: float | None = None,
    merge_footprints: bool = True,
    own_objects=None,
    min_texel=None,
    blur_shares: bool = True,
    raster_frames: list[RasterFrame] | None = None,
    view: View | None = None,
    max_texels: int | None = None,
) -> CausticLayer:
    """Accumulate ``beams`` landed on the receivers of ``index`` (:func:`.build_index`)
    into per-patch irradiance rasters. ``offset``:
    lift of the layer along the normal (default 0.1 of the smallest texel). ``warp``:
    sinh-spaced texel lines (else uniform). ``merge_footprints``: one raster per cluster
    of beams with overlapping footprints on a patch (disjoint rasters, each resolving its
    own caustics); False: one raster per patch for all beams. ``own_objects``: per beam
    the object id of its own lens among the receivers (see :func:`land_beams`).
    ``min_texel``: per beam the smallest texel its raster may have (e.g. half a pixel
    on screen there): a renderer point-samples the layer a few times per pixel, so
    texels far below a pixel show as noise, not detail. ``blur_shares``: spread each
    sample of an extended source over its share (False: K sharp images, for
    comparison). ``raster_frames``: the rasters to fill (one each, in that order; a
    beam's flux on a patch without one is lost), instead of fitting them here.
    ``view`` (`view.View`): each raster spans only the landings in view and has its
    own resolution, `TEXELS_PER_PIXEL` per pixel there (the pixel at its nearest
    landings), at most ``resolution``; where more than ``clip_fraction`` of its flux
    lands out of view, a coarse raster (`PatchLayer.coarse`, `COARSE_RESOLUTION` per
    side) spans all its landings and takes what lands beyond the fine one (a mirror
    may show it: drawn, not outside). All rasters together at most ``max_texels``
    texels (the coarse ones `COARSE_SHARE` of them). Without a view every raster has
    ``resolution`` texels per side. A given ``RasterFrame`` that is ``coarse`` takes
    what lands beyond the other given raster of its (patch, beams)."""
    t0 = time.perf_counter()
    plist = index.patches
    if not beams:
        return CausticLayer([], 0.0, 0.0, 0.0, 0.0, 0, 0, 0, {"total": 0.0})
    # a glass mesh's beam is several grids: each landed as a beam of its own, the
    # rasters' sources named by the beams given
    n_given = len(beams)
    beams, owner = flatten_parts(beams)
    flat_same = len(beams) == n_given
    if not flat_same:
        if own_objects is not None:
            own_objects = np.asarray(own_objects)[owner]
        if min_texel is not None and np.ndim(min_texel):
            min_texel = np.asarray(min_texel)[owner]
        if raster_frames is not None:
            raster_frames = [
                dataclasses.replace(rf, beams=tuple(np.nonzero(np.isin(owner, rf.beams))[0]))
                for rf in raster_frames
            ]
    landed = land_beams(beams, index, own_objects)
    t1 = time.perf_counter()
    res = int(resolution)

    if flat_same:
        owner = np.arange(len(beams))
    # Which patches receive anything, their light side, and per patch the clusters of
    # beams whose footprints overlap: one raster per (patch, cluster).
    bid = np.concatenate([np.full(len(x.patch), i) for i, x in enumerate(landed)])
    pid = np.concatenate([x.patch for x in landed])
    pts = np.concatenate([x.point for x in landed])
    dirs = np.concatenate([x.dirs for x in landed])
    wts = np.concatenate([x.node_flux for x in landed]) + 1e-300
    slot_of = np.full((len(beams), len(plist)), -1, dtype=np.int64)
    frames, members, slot_pts, floors, pixels = [], [], [], [], []
    slot_orders = []  # per raster, the stable order of its landings' x and y (or None)
    outer_of, coarse_of = [], []  # per raster: its coarse raster (−1: none); coarse or not
    on = np.nonzero(pid >= 0)[0]
    on = on[np.argsort(pid[on], kind="stable")]  # by patch, then beam (bid is in order)
    p_starts = np.nonzero(np.diff(np.concatenate([[-1], pid[on]])))[0]
    for k, start in enumerate(p_starts if raster_frames is None else []):  # per patch
        idx = on[start : p_starts[k + 1] if k + 1 < len(p_starts) else len(on)]
        p = int(pid[idx[0]])
        n = plist[p].normal
        side = -np.sign(np.sum(wts[idx] * (dirs[idx] @ n))) or 1.0
        n_out = n * side
        au, av = perpendicular_frame(n_out)
        x, y = pts[idx] @ au, pts[idx] @ av
        b_starts = np.nonzero(np.diff(np.concatenate([[-1], bid[idx]])))[0]
        b_ends = np.append(b_starts[1:], len(idx))
        w_here = wts[idx]
        local = np.repeat(np.arange(len(b_starts)), b_ends - b_starts)
        qs = (0.5 * clip_fraction, 1.0 - 0.5 * clip_fraction)
        # one sort per axis of the patch's landings: the beams' boxes, the glasses'
        # bulks and the rasters' texel lines take their orders from it
        ox, oy = (np.argsort(c, kind="stable") for c in (x, y))
        boxes = np.concatenate(
            [
                grouped_quantiles(
                    c, w_here, local, len(b_starts), qs, regroup(o, local, len(b_starts))
                )
                for c, o in ((x, ox), (y, oy))
            ],
            axis=1,
        )  # (beams here, 4): u_lo, u_hi, v_lo, v_hi
        in_view = view.in_view(pts[idx]) if view is not None else None
        if view is not None:  # a faint tail far out: the bulk decides (`bulk_boxes`)
            boxes, tail = bulk_boxes(
                (x, y, w_here, owner[bid[idx]], local),
                in_view,
                view.pixel(pts[idx]),
                boxes,
                clip_fraction,
                res,
                (ox, oy),
            )
        comps = _disjoint_clusters(boxes) if merge_footprints else [np.arange(len(b_starts))]
        for comp in comps:
            sel = np.concatenate([np.arange(b_starts[c], b_ends[c]) for c in comp])
            beams_here = bid[idx[b_starts[comp]]]
            floor = 0.0 if min_texel is None else float(np.min(np.asarray(min_texel)[beams_here]))
            parts = [(sel, False)]
            if view is not None:  # the raster spans what the camera sees of the caustic
                # a glass's tail beyond its bulk: to the coarse raster
                box = boxes[local[sel]]
                seen = in_view[sel] & (
                    ~tail[local[sel]]
                    | (
                        (x[sel] >= box[:, 0])
                        & (x[sel] <= box[:, 1])
                        & (y[sel] >= box[:, 2])
                        & (y[sel] <= box[:, 3])
                    )
                )
                w_sel = w_here[sel]
                # and a coarse one all of it, for what lands out of view (a mirror sees it)
                unseen = float(w_sel[~seen].sum()) > clip_fraction * float(w_sel.sum())
                parts = [(sel[seen], False)] if np.any(seen) else []
                parts += [(sel, True)] if unseen else []
            inner = -1
            for part, coarse in parts:
                if view is not None and not coarse:
                    pix = view.pixel(pts[idx[part]])
                    pixels.append(weighted_quantile(pix, w_here[part], NEAR_PIXEL_SHARE))
                elif view is not None:
                    pixels.append(np.inf)  # (its resolution: `_with_coarse`)
                if inner >= 0:
                    outer_of[inner] = len(frames)
                else:
                    slot_of[beams_here, p] = len(frames)
                inner = len(frames)
                outer_of.append(-1)
                coarse_of.append(coarse)
                frames.append((p, n_out, au, av))
                members.append(beams_here)
                slot_pts.append((x[part], y[part], w_here[part]))
                slot_orders.append([sub_order(o, part, len(x)) for o in (ox, oy)])
                floors.append(floor)
    given = raster_frames or []
    base = len(frames)
    for rf in given:  # the bake's fixed rasters (in their order: the caller's)
        frames.append((rf.patch, rf.normal, rf.axis_u, rf.axis_v))
        members.append(np.asarray(rf.beams, dtype=np.int64))
        outer_of.append(-1)
        coarse_of.append(bool(rf.coarse))
        if not rf.coarse:
            slot_of[members[-1], rf.patch] = len(frames) - 1
    for k, rf in enumerate(given):  # a coarse one takes what lands beyond the other
        first = slot_of[members[base + k][0], rf.patch] if len(rf.beams) else -1
        if rf.coarse and first >= 0:
            outer_of[first] = base + k
        elif rf.coarse:
            slot_of[members[base + k], rf.patch] = base + k
    fr = {
        "au": np.array([f[2] for f in frames]).reshape(-1, 3),
        "av": np.array([f[3] for f in frames]).reshape(-1, 3),
    }
    for k, key in enumerate(("u", "v") if given else ()):  # the given texel lines
        for j, name in enumerate(AXIS_FIELDS):
            fr[key + name] = np.array([float(rf.axes[k][j]) for rf in given])
    fr["res"] = np.full(len(frames), res, dtype=np.int64)
    fr["outer"] = np.asarray(outer_of, dtype=np.int64).reshape(-1)
    coarse_of = np.asarray(coarse_of, dtype=bool).reshape(-1)
    if not given:  # every raster's texel lines at once (one sort per axis for all)
        gid = np.repeat(np.arange(len(frames)), [len(t[0]) for t in slot_pts])
        w_all = np.concatenate([t[2] for t in slot_pts]) if slot_pts else np.zeros(0)
        c_all = [
            np.concatenate([t[k] for t in slot_pts]) if slot_pts else np.zeros(0) for k in (0, 1)
        ]
        # per axis the footprint's quantiles and median: the view's spans and the warp's
        qs = (0.5 * clip_fraction, 1.0 - 0.5 * clip_fraction, 0.5)
        orders = [_joined(slot_orders, k) for k in (0, 1)]
        quant = [
            grouped_interp_quantiles(c, w_all, gid, len(frames), qs, orders[k])
            for k, c in enumerate(c_all)
        ]
        if view is not None and len(frames):
            fr["res"] = _view_resolutions(quant, pixels, res)
            fr["res"] = _with_coarse(fr["res"], coarse_of, res, max_texels)
    for key, k in (("u", 0), ("v", 1)) if not given else ():
        axis = _warp_axes(
            c_all[k], w_all, gid, len(frames), quant[k], fr["res"], warp, floors, orders[k]
        )
        for name, val in zip(AXIS_FIELDS, axis, strict=True):
            fr[key + name] = val
    # every raster's texels in blocks of side × side (a raster of fewer uses a corner)
    side = int(fr["res"].max(initial=1))
    fr["side"] = side

    n_slots = len(frames)
    rgb = np.zeros((n_slots * side * side, 3))
    flux_in = np.zeros(n_slots)
    flux_out = np.zeros(n_slots)
    lost = unseen = 0.0
    n_sub = 0
    # One vectorised pass per light colour (beams of one colour share the arithmetic).
    colors = np.array([lb.beam.color for lb in landed]).reshape(-1, 3)
    uniq, group = np.unique(colors, axis=0, return_inverse=True)
    for gi, color in enumerate(uniq):  # loop over colours, usually one or two
        ids = [i for i in np.nonzero(group.reshape(-1) == gi)[0]]
        acc, out_acc, g_lost, g_unseen, g_sub = _accumulate_beams(
            [landed[i] for i in ids],
            ids,
            slot_of,
            fr,
            blur_shares,
            (subcells_per_texel, max_subdivision, max_subcells, flux_subcells_per_texel),
        )
        lost += float(g_lost.sum())
        unseen += float(g_unseen.sum())
        n_sub += g_sub
        flux_in += acc.reshape(n_slots, side * side).sum(axis=1)
        flux_out += out_acc
        rgb += acc[:, None] * color
    t2 = time.perf_counter()

    layers = []
    uv_fits = {}
    rgb = rgb.reshape(n_slots, side, side, 3)
    for slot, (p, n_out, au, av) in enumerate(frames):
        r = int(fr["res"][slot])
        eu, ev = (_edges(tuple(fr[k + n][slot] for n in AXIS_FIELDS), r) for k in ("u", "v"))
        du, dv = np.diff(eu), np.diff(ev)
        irr = rgb[slot, :r, :r] / (dv[:, None] * du[None, :])[..., None]
        off = 0.1 * min(du.min(), dv.min()) if offset is None else offset
        origin = n_out * (plist[p].offset * (n_out @ plist[p].normal))
        verts = (origin + eu[None, :, None] * au + ev[:, None, None] * av).reshape((r + 1) ** 2, 3)
        if p not in uv_fits:  # one fit per patch, shared by its rasters
            uv_fits[p] = _affine_uv_fit(index, plist[p], n_out)
        uvs, inside = _vertex_uvs(index, uv_fits[p], p, verts, n_out)
        layers.append(
            PatchLayer(
                patch=int(p),
                sources=members[slot] if flat_same else np.unique(owner[members[slot]]),
                object_id=plist[p].object_id,
                normal=n_out,
                axis_u=au,
                axis_v=av,
                origin=origin,
                edges_u=eu,
                edges_v=ev,
                resolution=r,
                irradiance=irr,
                flux=float(flux_in[slot]),
                flux_outside=float(flux_out[slot]),
                vertices=verts + off * n_out,
                faces=_grid_faces(r),
                uvs=uvs,
                uv_inside=inside,
                axes=tuple(tuple(float(fr[k + n][slot]) for n in AXIS_FIELDS) for k in ("u", "v")),
                coarse=bool(coarse_of[slot]),
            )
        )
    t3 = time.perf_counter()
    return CausticLayer(
        patches=layers,
        flux_emitted=float(sum(b.total_flux for b in beams)),
        flux_in_rasters=float(flux_in.sum()),
        flux_outside=float(flux_out.sum()) + unseen,
        flux_lost=lost,
        n_rays=sum(b.n_rays for b in beams),
        n_cells=sum(b.n_cells for b in beams),
        n_subcells=n_sub,
        timings={"land": t1 - t0, "splat": t2 - t1, "mesh": t3 - t2, "total": t3 - t0},
    )


def _accumulate_beams(members_g, ids, slot_of, fr, blur_shares, splat):
    """The landed beams ``members_g`` (beam indices ``ids``, one light colour) added to
    the rasters ``fr`` (``slot_of``: each beam's raster per patch): (texel flux of
    every raster's block, flux beyond each raster, flux lost and flux landed out of
    view per beam, sub-cells); ``splat``: (sub-cells per texel, the most per side, the most in all,
    sub-cells per texel by flux) for `_splat_cells`."""
    subcells_per_texel, max_subdivision, max_subcells, flux_subcells_per_texel = splat
    n_slots, side = len(fr["res"]), fr["side"]
    n_sub = 0
    base = np.cumsum([0] + [len(lb.patch) for lb in members_g])
    point = np.concatenate([lb.point for lb in members_g])
    slot = np.concatenate(
        [
            np.where(lb.patch >= 0, slot_of[i][np.maximum(lb.patch, 0)], -1)
            for i, lb in zip(ids, members_g, strict=True)
        ]
    )
    corners = np.concatenate(
        [cell_corners(lb.beam.shape) + base[k] for k, lb in enumerate(members_g)]
    )
    cflux = np.concatenate([lb.beam.cell_flux.reshape(-1) for lb in members_g])
    # the samples' shares matter only to blur an extended source's images
    blurred = blur_shares and any(
        lb.beam.rotations is not None and np.any(lb.beam.rotations) for lb in members_g
    )
    if blurred:
        rot, ctr, disc, share_cells, share_grid = _cell_shares(members_g)
    dens = np.concatenate([lb.beam.node_density.reshape(-1) for lb in members_g])[corners]
    acc = np.zeros(n_slots * side * side)
    out_acc = np.zeros(n_slots)
    cs = slot[corners]
    c0 = cs[:, 0]  # (columns compared: numpy's reductions along a short axis are slow)
    same = (c0 >= 0) & (cs[:, 1] == c0) & (cs[:, 2] == c0) & (cs[:, 3] == c0) & (cflux > 0.0)
    # cells across receivers (or missing): each corner its density-weighted share
    mixed = ~same & (cflux > 0.0)
    dsum = _corner_sum(dens[mixed])[:, None]
    share = np.where(dsum > 0.0, dens[mixed] / np.where(dsum > 0.0, dsum, 1.0), 0.25)
    share = (share * cflux[mixed, None]).reshape(-1)
    cm = corners[mixed].reshape(-1)
    sm = cs[mixed].reshape(-1)
    landed_g = np.concatenate([lb.patch for lb in members_g])[cm] >= 0
    # per member (a beam's cells are contiguous: its member from the cell's index)
    cell_member = np.repeat(np.arange(len(members_g)), [lb.beam.cell_flux.size for lb in members_g])
    member = np.repeat(cell_member[mixed], 4)
    miss = sm < 0
    lost = np.bincount(member[miss & ~landed_g], share[miss & ~landed_g], len(members_g))
    # on a receiver, out of view
    unseen = np.bincount(member[miss & landed_g], share[miss & landed_g], len(members_g))
    on = sm >= 0
    _deposit(acc, out_acc, point[cm[on]], sm[on], share[on], fr)
    # cells on one patch: m × m bilinear sub-cells
    cidx = np.nonzero(same)[0]
    if len(cidx):
        jitter = shares = None
        if blurred and np.any(rot[cidx]):
            direction = np.concatenate([lb.dirs for lb in members_g])[corners[cidx]]
            jitter = _share_offsets(
                point[corners[cidx]], direction, rot[cidx], ctr[cidx], cs[cidx, 0], fr
            )
            shares = (disc[cidx], share_cells[cidx], share_grid[cidx])
        # each node in its raster's plane coordinates once, then per cell corner
        ns = np.maximum(slot, 0)
        node_x = np.einsum("ij,ij->i", point, fr["au"][ns])
        node_y = np.einsum("ij,ij->i", point, fr["av"][ns])
        n_sub += _splat_cells(
            acc,
            out_acc,
            (node_x[corners[cidx]], node_y[corners[cidx]]),
            cs[cidx, 0],
            dens[cidx],
            cflux[cidx],
            fr,
            subcells_per_texel,
            max_subdivision,
            max_subcells,
            flux_subcells_per_texel,
            jitter=jitter,
            shares=shares,
        )
    return acc, out_acc, lost, unseen, n_sub


@functools.lru_cache(maxsize=8)
def _grid_faces(res: int) -> np.ndarray:
    """(res², 4) quads of a (res+1)² vertex grid, counter-clockwise; read-only, shared
    by every raster of that resolution."""
    a = (np.arange(res)[:, None] * (res + 1) + np.arange(res)[None, :]).reshape(-1)
    out = np.stack([a, a + 1, a + res + 2, a + res + 1], axis=1)
    out.setflags(write=False)
    return out


#: The central share of a beam's flux in view that is its bulk, and how many times
#: wider its whole footprint (the ``clip_fraction`` quantiles) must be, along either
#: axis, for the bulk to stand for it (`bulk_boxes`).
BULK_SHARE = 0.99
TAIL_SPREAD = 2.0


def _joined(orders, k: int) -> np.ndarray | None:
    """The rasters' stable orders along axis ``k`` as one order of their landings
    concatenated (by raster, then x: `_group_order`'s), or None if one is unknown."""
    parts = [o[k] for o in orders]
    if any(p is None for p in parts):
        return None
    starts = np.cumsum([0] + [len(p) for p in parts])
    return np.concatenate(
        [np.zeros(0, dtype=np.int64)] + [p + a for p, a in zip(parts, starts[:-1], strict=True)]
    )


def bulk_boxes(landings, in_view, pixel, boxes, clip_fraction, res_max, orders=None):
    """The boxes (beams here, 4) the rasters are clustered by, and per beam whether
    its box is its glass's bulk (then its fine raster spans only that; what lands
    beyond goes to the coarse raster): each beam's footprint ``boxes`` (its
    ``clip_fraction`` quantiles), or its glass's bulk (the `BULK_SHARE` of its flux
    in view) where its whole footprint is more than `TAIL_SPREAD` times wider along
    either axis and its part in view needs more than ``res_max`` texels a side at
    `TEXELS_PER_PIXEL` per pixel (so spanning it all would coarsen the bulk's
    texels). A glass mesh sends a few % of its light far (internal reflections out of
    a rod's side, a lens's rim): without this, that faint tail joined every caustic
    on the table into one raster, whose texels, fine only about the middle of all,
    were 1.4–2.9 mm at the showcase rod's line for a 0.6 mm pixel. ``landings``:
    (x, y, flux, glass, beam) per landing (the glass: of the beams given to
    `build_layer`; the beam: its index into ``boxes``); ``in_view``, ``pixel``: per
    landing, whether the camera sees it and its pixel there; ``orders``: the stable
    orders of x and y (np.argsort(…, kind="stable")), if known."""
    x, y, w, owner, local = landings
    owners, group = np.unique(owner, return_inverse=True)
    n = len(owners)
    seen = in_view & (w > 1e-300)
    # per glass: its bulk and extent in view (all its landings if none is), its pixel
    # there, and its whole footprint
    has = np.bincount(group[seen], minlength=n) > 0
    use = seen | ~has[group]
    half = 0.5 * (1.0 - BULK_SHARE)
    whole_q = (0.5 * clip_fraction, 1.0 - 0.5 * clip_fraction)
    bulk, whole, span = [], [], np.zeros(n)
    every = bool(np.all(use))
    rows = None if every else np.nonzero(use)[0]
    for k, c in enumerate((x, y)):
        cu, wu, gu = (c, w, group) if every else (c[use], w[use], group[use])
        o = None if orders is None else orders[k]
        o_all = None if o is None else regroup(o, group, n)
        o_use = o_all if every or o is None else sub_order(o, rows, len(c))
        if not every and o_use is not None:
            o_use = regroup(o_use, gu, n)
        # one sort per axis for the bulk and the span in view (and the whole footprint
        # when every landing is used: the same landings)
        q = grouped_interp_quantiles(cu, wu, gu, n, (half, 1.0 - half, *whole_q), o_use)
        bulk.append(q[:, :2])
        whole.append(
            q[:, 2:] if every else grouped_interp_quantiles(c, w, group, n, whole_q, o_all)
        )
        span = np.maximum(span, q[:, 3] - q[:, 2])
    pix = grouped_quantiles(
        pixel if every else pixel[use], w if every else w[use], gu, n, (NEAR_PIXEL_SHARE,)
    )[:, 0]
    starved = TEXELS_PER_PIXEL * span > res_max * np.where(np.isfinite(pix), pix, np.inf)
    bulk = np.concatenate(bulk, axis=1)  # (glasses, 4)
    whole = np.concatenate(whole, axis=1)
    width_b = np.stack([bulk[:, 1] - bulk[:, 0], bulk[:, 3] - bulk[:, 2]], axis=1)
    width_w = np.stack([whole[:, 1] - whole[:, 0], whole[:, 3] - whole[:, 2]], axis=1)
    tail = starved & np.any(width_w > TAIL_SPREAD * np.maximum(width_b, 1e-300), axis=1)
    beam_glass = group[np.searchsorted(local, np.arange(len(boxes)))]
    return np.where(tail[beam_glass][:, None], bulk[beam_glass], boxes), tail[beam_glass]


def _disjoint_clusters(boxes: np.ndarray) -> list[np.ndarray]:
    """Group boxes (m, 4: u_lo, u_hi, v_lo, v_hi) into clusters whose merged boxes do
    not overlap: connected components of the overlap graph, repeated on the merged
    boxes until they are disjoint (m is the number of beams on one patch: small)."""
    groups = [np.array([i]) for i in range(len(boxes))]
    cur = boxes.copy()
    while True:
        over = (
            (cur[:, None, 0] <= cur[None, :, 1])
            & (cur[None, :, 0] <= cur[:, None, 1])
            & (cur[:, None, 2] <= cur[None, :, 3])
            & (cur[None, :, 2] <= cur[:, None, 3])
        )
        label = np.arange(len(cur))
        while True:  # label propagation to the smallest index
            new = np.where(over, label[None, :], len(cur)).min(axis=1)
            if np.array_equal(new, label):
                break
            label = new
        if len(np.unique(label)) == len(cur):
            return groups
        keys = np.unique(label)
        groups = [np.concatenate([groups[i] for i in np.nonzero(label == k)[0]]) for k in keys]
        cur = np.array(
            [
                [
                    cur[label == k, 0].min(),
                    cur[label == k, 1].max(),
                    cur[label == k, 2].min(),
                    cur[label == k, 3].max(),
                ]
                for k in keys
            ]
        )


def grouped_interp_quantiles(x, w, groups, n_groups: int, qs, order=None) -> np.ndarray:
    """:func:`weighted_quantile` (interpolated in the cumulative weight, as np.interp)
    of ``x`` within each group (ids 0..n_groups−1, every group non-empty), for each
    share in ``qs``: (n_groups, len(qs)), one sort for all groups (``order``: that
    sort, `_group_order`'s, if known)."""
    o = _group_order(x, groups, n_groups) if order is None else order
    g, xs = groups[o], x[o]
    cw = np.cumsum(w[o])
    ends = np.cumsum(np.bincount(g, minlength=n_groups))
    starts = ends - np.bincount(g, minlength=n_groups)
    base = np.where(starts > 0, cw[np.maximum(starts - 1, 0)], 0.0)
    total = cw[ends - 1] - base
    out = np.empty((n_groups, len(qs)))
    for k, q in enumerate(qs):
        target = base + q * total
        j = np.searchsorted(cw, target, side="right") - 1  # cw[j] ≤ target < cw[j+1]
        j = np.clip(j, starts - 1, ends - 1)
        lo = np.maximum(j, starts)
        hi = np.minimum(j + 1, ends - 1)
        c0 = np.where(j >= starts, cw[lo], base)
        gap = cw[hi] - c0
        frac = np.where(
            (j >= starts) & (j < ends - 1) & (gap > 0),
            (target - c0) / np.where(gap > 0, gap, 1.0),
            0.0,
        )
        out[:, k] = np.where(j < starts, xs[starts], xs[lo] + frac * (xs[hi] - xs[lo]))
    return out


#: The share of a raster's flux in view whose pixel is finer than the one its texels
#: follow: the near part of the caustic sets the resolution.
NEAR_PIXEL_SHARE = 0.1
#: Texels per pixel across a raster (before its warp refines the core): the drawn
#: irradiance is linear between texel centres, so a sharp fold (a resting marble's
#: rim) keeps its width within a third of a pixel (2 per pixel: L1 0.058 against 0.043
#: for the 60° marble of bench/real_scenes.py).
TEXELS_PER_PIXEL = 3.0
MIN_RESOLUTION = 16
#: Texels per side of the coarse raster that holds a caustic where the camera does not
#: see it (a mirror or glossy surface may: drawn coarsely, not missing), and the share
#: of the texel budget those rasters may take at most.
COARSE_RESOLUTION = 48
COARSE_SHARE = 0.25


def _view_resolutions(quantiles, pixels, res_max) -> np.ndarray:
    """Per raster, texels per side for `TEXELS_PER_PIXEL` per pixel over the span of its
    landings in view (the larger of its two axes: ``quantiles`` per axis, (rasters, ≥2)
    their ``clip_fraction`` quantiles), within [`MIN_RESOLUTION`, ``res_max``]."""
    span = np.maximum(*(q[:, 1] - q[:, 0] for q in quantiles))
    pix = np.maximum(np.asarray(pixels, dtype=float), 1e-300)
    want = np.ceil(TEXELS_PER_PIXEL * span / pix)
    return np.clip(want, MIN_RESOLUTION, max(int(res_max), MIN_RESOLUTION)).astype(np.int64)


def _within_texels(res: np.ndarray, max_texels: int | None) -> np.ndarray:
    """The resolutions scaled down together (not below `MIN_RESOLUTION`) so that all
    rasters hold at most ``max_texels`` texels."""
    total = float(np.sum(res.astype(float) ** 2))
    if max_texels is None or total <= max_texels:
        return res
    k = np.sqrt(max_texels / total)
    return np.maximum(np.floor(res * k), MIN_RESOLUTION).astype(np.int64)


def _with_coarse(res: np.ndarray, coarse: np.ndarray, res_max: int, max_texels) -> np.ndarray:
    """The view rasters' resolutions with the coarse ones (out of view) at
    `COARSE_RESOLUTION` per side: those together at most `COARSE_SHARE` of
    ``max_texels``, the rasters in view within the rest (`_within_texels`)."""
    res = res.copy()
    res[coarse] = min(COARSE_RESOLUTION, max(int(res_max), MIN_RESOLUTION))
    if max_texels is None:
        return res
    res[coarse] = _within_texels(res[coarse], int(COARSE_SHARE * max_texels))
    rest = max(int(max_texels) - int(np.sum(res[coarse].astype(float) ** 2)), 0)
    res[~coarse] = _within_texels(res[~coarse], rest)
    return res


def _warp_axes(x, w, groups, n_groups, quantiles, res, warp, min_texel, order=None):
    """(c, s, ξ0, dξ) of one raster axis per group, each (n_groups,): texel lines at
    ``c + s·sinh(ξ0 + i·dξ)`` over the weighted quantiles ``clip_fraction/2`` and
    ``1 − clip_fraction/2`` of ``x`` (a texel of margin), centred on its median
    (``quantiles`` (n_groups, 3): those three, `grouped_interp_quantiles`); the
    warp is flattened (s grown) until the finest texel, s·dξ, is the group's
    ``min_texel`` (or the texels are uniform). ``order``: `_group_order`'s of x, if
    known: |x − c| along it falls then rises, two runs a stable sort merges in one
    pass (the median distance's sort ~14× faster at 64 000 landings)."""
    lo, hi, c = quantiles[:, 0], quantiles[:, 1], quantiles[:, 2]
    span = np.maximum(hi - lo, 1e-12 * (1.0 + np.abs(lo) + np.abs(hi)))
    lo, hi = lo - span / res, hi + span / res  # a texel of margin
    if warp:
        dist = np.abs(x - c[groups])
        o = None
        if order is not None:  # by group, then distance (stable: ties in x's order)
            o = order[_group_order(dist[order], groups[order], n_groups)]
        mad = grouped_interp_quantiles(dist, w, groups, n_groups, (0.5,), o)[:, 0]
        s = np.maximum(mad, 1e-3 * span)
    else:
        s = 1e3 * span
    min_texel = np.asarray(min_texel, dtype=float).reshape(-1)

    def finest(s):
        return s * (np.arcsinh((hi - c) / s) - np.arcsinh((lo - c) / s)) / res

    need = finest(s) < min_texel  # grows with s, toward the uniform texel (hi − lo)/res
    flat = need & ((hi - lo) / res <= min_texel)
    s = np.where(flat, 1e3 * span, s)
    bis = need & ~flat
    if np.any(bis):
        a, b = s.copy(), 1e3 * span
        for _ in range(60):  # bisection in log s
            m = np.sqrt(a * b)
            low = finest(m) < min_texel
            a, b = np.where(low, m, a), np.where(low, b, m)
        s = np.where(bis, b, s)
    xi0, xi1 = np.arcsinh((lo - c) / s), np.arcsinh((hi - c) / s)
    return c, s, xi0, (xi1 - xi0) / res


def _edges(axis, res):
    c, s, xi0, dxi = axis
    return c + s * np.sinh(xi0 + dxi * np.arange(res + 1))


def _asinh(u, out=None, scratch=None):
    """arcsinh by its logarithm, odd by construction (twice numpy's speed; the same to
    a few ulps); into ``out`` with ``scratch`` (arrays of u's shape) if given."""
    a = np.abs(u, out=scratch)
    t = np.multiply(a, a, out=out)  # in place from here: the same arithmetic
    t += 1.0
    np.sqrt(t, out=t)
    t += a
    np.log(t, out=t)
    return np.copysign(t, u, out=t)


class _SplatBuffers:
    """A splat level's scratch arrays for one block of ``n`` sub-cells: four float,
    two integer and two boolean (reused block after block: no fresh pages)."""

    def __init__(self, n: int):
        self.floats = [np.empty(n) for _ in range(4)]
        self.ints = [np.empty(n, dtype=np.int64) for _ in range(2)]
        self.bools = [np.empty(n, dtype=bool) for _ in range(2)]


def _texel_index(x, fr, key, slots):
    xi = _asinh((x - fr[key + "c"][slots]) / fr[key + "s"][slots])
    return np.floor((xi - fr[key + "xi0"][slots]) / fr[key + "dxi"][slots]).astype(np.int64)


def _local_texel(x, fr, key, slots):
    """Texel width at ``x``: dx/dξ · dξ = sqrt(s² + (x − c)²) · dξ."""
    return np.hypot(fr[key + "s"][slots], x - fr[key + "c"][slots]) * fr[key + "dxi"][slots]


def _deposit(acc, out_acc, points, slots, flux, fr):
    """Add ``flux`` at world ``points`` into the rasters of ``slots`` (their texel)."""
    if len(points) == 0:
        return
    x = np.einsum("ij,ij->i", points, fr["au"][slots])
    y = np.einsum("ij,ij->i", points, fr["av"][slots])
    ix = _texel_index(x, fr, "u", slots)
    iy = _texel_index(y, fr, "v", slots)
    _accumulate(acc, out_acc, ix, iy, slots, flux, fr, (x, y))


def _accumulate(acc, out_acc, ix, iy, slots, flux, fr, xy=None):
    """Add ``flux`` at texels (ix, iy) of rasters ``slots`` (broadcast against them;
    raster k has ``fr["res"][k]`` texels per side, stored in a block of ``fr["side"]``²);
    beyond a raster, into its coarse raster (``fr["outer"]``, found from the plane
    coordinates ``xy``, which all rasters of a patch share) or, without one, to its
    ``out_acc``."""
    n = len(acc)
    for both in _texel_sums(n, len(out_acc), ix, iy, slots, flux, fr, xy):
        acc += both[:n]
        out_acc += both[n:]


def _texel_sums(n, n_out, ix, iy, slots, flux, fr, xy=None) -> list[np.ndarray]:
    """What `_accumulate` adds, as the arrays (n + n_out,) it adds in turn (the texels
    of all rasters' blocks, then the flux beyond each raster): what lands beyond a
    raster into its coarse one first, then the rest."""
    sums = []
    inside = _inside(ix, iy, slots, fr)
    if xy is not None and np.any(fr["outer"] >= 0):
        outer = fr["outer"][slots]
        move = ~inside & (outer >= 0)
        if np.any(move):  # ``xy``: the plane coordinates
            x, y = (np.broadcast_to(a, inside.shape)[move] for a in xy)
            to = np.broadcast_to(outer, inside.shape)[move]
            flux = np.broadcast_to(flux, inside.shape)
            sums += _texel_sums(
                n,
                n_out,
                _texel_index(x, fr, "u", to),
                _texel_index(y, fr, "v", to),
                to,
                flux[move],
                fr,
            )
            flux = np.where(move, 0.0, flux)
    idx = _bins(ix, iy, slots, ~inside, fr, n)
    sums.append(np.bincount(idx.reshape(-1), weights=flux.reshape(-1), minlength=n + n_out))
    return sums


def _inside(ix, iy, slots, fr, out=None, scratch=None) -> np.ndarray:
    """Whether texel (ix, iy) lies within raster ``slots`` (broadcast; into ``out``,
    with ``scratch`` of its shape, if given). Unsigned: a negative index compares as
    huge, one test per side."""
    res = fr["res"].astype(np.uint64)[slots]
    inside = np.less(ix.view(np.uint64), res, out=out)
    inside &= np.less(iy.view(np.uint64), res, out=scratch)
    return inside


def _bins(ix, iy, slots, beyond, fr, n, out=None) -> np.ndarray:
    """Each texel's bin for one bincount of all rasters: (ix, iy) in raster ``slots``'s
    block of ``fr["side"]``², or ``n + slot`` where ``beyond`` it (into ``out`` if given)."""
    side = fr["side"]
    if out is None:
        out = np.empty(np.broadcast_shapes(ix.shape, np.shape(slots)), dtype=np.int64)
    np.multiply(slots, side, out=out)
    out += iy
    out *= side
    out += ix
    np.copyto(out, n + slots, where=beyond)
    return out


def _splat_cells(
    acc,
    out_acc,
    corner_xy,
    slots,
    dens,
    flux,
    fr,
    per_texel,
    m_max,
    max_subcells,
    flux_subcells_per_texel,
    m_free=8,
    jitter=None,
    shares=None,
):
    """Spread each cell's flux over its landed quad by m × m bilinear sub-cells;
    ``corner_xy``: the corners' plane coordinates (x, y), each (C, 4), along the axes of
    the cell's raster ``slots``.

    ``jitter`` (C, 2, 2): per cell the plane offsets (u, v) of a unit step along each
    axis of the emitter's shape (:func:`_share_offsets`); ``shares``: per cell (disc,
    grid cell, grid size) of its sample's share. Each sub-cell is moved by a point of
    that share from a low-discrepancy sequence, so the K images of an extended source
    blend into its continuous blur instead of K separate copies."""
    x, y = corner_xy  # (C, 4)
    # sub-cells per side: the quad's extent in local texels at its centre
    tx = _local_texel(_corner_sum(x) / 4.0, fr, "u", slots)
    ty = _local_texel(_corner_sum(y) / 4.0, fr, "v", slots)
    size = np.maximum(_corner_ptp(x) / tx, _corner_ptp(y) / ty)
    m = np.clip(np.ceil(per_texel * size), 1, m_max).astype(np.int64)
    # A dim cell's sampling error is a small share of the image: the cells that need
    # more than ``m_free`` sub-cells per side (the wide faint halo, past the folds) get
    # them by flux too, about ``flux_subcells_per_texel`` per texel of the rasters in all.
    budget = flux_subcells_per_texel * max(float(np.sum(fr["res"].astype(float) ** 2)), 1.0)
    m_flux = np.ceil(np.sqrt(budget * flux / max(float(flux.sum()), 1e-300))).astype(np.int64)
    m = np.where(m <= m_free, m, np.maximum(m_free, np.minimum(m, m_flux)))
    total = int(np.sum(m * m))
    if total > max_subcells:  # keep memory bounded: coarser sub-cells
        m = np.maximum(1, (m * np.sqrt(max_subcells / total)).astype(np.int64))
    dsum = _corner_sum(dens)
    dens = np.where(dsum[:, None] > 0.0, dens, 1.0)
    dsum = _corner_sum(dens)
    # The warp's argument (x − c)/s at the corners: the bilinear sub-cells commute with
    # that affine map, so they are placed in it directly (per raster constants gathered
    # once per cell, not per sub-cell).
    su, sv = fr["us"][slots], fr["vs"][slots]
    xn = (x - fr["uc"][slots][:, None]) / su[:, None]
    yn = (y - fr["vc"][slots][:, None]) / sv[:, None]
    xi0u, dxiu = fr["uxi0"][slots], fr["udxi"][slots]
    xi0v, dxiv = fr["vxi0"][slots], fr["vdxi"][slots]
    levels = [int(mm) for mm in np.unique(m)]
    sels = [np.nonzero(m == mm)[0] for mm in levels]
    # each level's first sub-cell (along the share points' sequence)
    first = np.cumsum([0] + [len(sel) * mm * mm for sel, mm in zip(sels, levels, strict=True)])

    def level(k):  # one subdivision level's texel sums
        mm, sel, n_sub = levels[k], sels[k], int(first[k])
        g = (np.arange(mm) + 0.5) / mm
        s, t = (a.reshape(-1) for a in np.meshgrid(g, g, indexing="ij"))
        bw = np.stack([(1 - s) * (1 - t), s * (1 - t), s * t, (1 - s) * t], axis=1)  # (q, 4)
        q = len(s)
        n, n_out = len(acc), len(out_acc)
        outer_any = bool(np.any(fr["outer"] >= 0))
        idx_all = np.empty(len(sel) * q, dtype=np.int64)
        w_all = np.empty(len(sel) * q)
        moved = []  # per block: (x, y, raster, flux) of the sub-cells beyond a fine raster
        # in blocks of cells whose sub-cells' temporaries stay small (cache-sized, reused
        # by the allocator: a level's whole arrays, ~6 MB each, cost their page faults
        # every time), written into the level's arrays in order: the same elements
        per = max(1, SPLAT_BLOCK // q)
        buf = _SplatBuffers(min(per, len(sel)) * q)
        for a0 in range(0, len(sel), per):
            rs = sel[a0 : a0 + per]
            shape = (len(rs), q)
            px, py, t, tmp = (b[: len(rs) * q].reshape(shape) for b in buf.floats)
            ix, iy = (b[: len(rs) * q].reshape(shape) for b in buf.ints)
            inside, out_ = (b[: len(rs) * q].reshape(shape) for b in buf.bools)
            span = slice(a0 * q, a0 * q + len(rs) * q)
            w = w_all[span].reshape(shape)
            np.matmul(xn[rs], bw.T, out=px)  # (c, q)
            np.matmul(yn[rs], bw.T, out=py)
            if jitter is not None:
                a, b = _share_points(n_sub + a0 * q, shape, *(x[rs] for x in shares))
                j = jitter[rs]
                px += (a * j[:, None, 0, 0] + b * j[:, None, 1, 0]) / su[rs, None]
                py += (a * j[:, None, 0, 1] + b * j[:, None, 1, 1]) / sv[rs, None]
            # the m × m midpoints weigh each corner q/4 in all: the cell's flux exactly
            np.matmul(dens[rs] * (flux[rs] / (0.25 * q * dsum[rs]))[:, None], bw.T, out=w)
            for p, x0, dx, i in ((px, xi0u, dxiu, ix), (py, xi0v, dxiv, iy)):
                _asinh(p, out=t, scratch=tmp)
                t -= x0[rs, None]
                t /= dx[rs, None]
                np.floor(t, out=t)
                np.copyto(i, t, casting="unsafe")  # (as astype(np.int64))
            sl = slots[rs][:, None]
            _inside(ix, iy, sl, fr, out=inside, scratch=out_)
            np.logical_not(inside, out=out_)
            if outer_any:  # beyond a fine raster: into its coarse one (`_texel_sums`)
                move = out_ & (fr["outer"][sl] >= 0)
                if np.any(move):
                    moved.append(
                        (
                            px[move] * np.broadcast_to(su[rs, None], shape)[move]
                            + np.broadcast_to(fr["uc"][sl], shape)[move],
                            py[move] * np.broadcast_to(sv[rs, None], shape)[move]
                            + np.broadcast_to(fr["vc"][sl], shape)[move],
                            np.broadcast_to(fr["outer"][sl], shape)[move],
                            w[move],
                        )
                    )
                    np.copyto(w, 0.0, where=move)
            _bins(ix, iy, sl, out_, fr, n, out=idx_all[span].reshape(shape))
        sums = []
        if moved:  # as `_texel_sums`: the moved sub-cells' sums first, in their order
            mx, my, to, mf = (np.concatenate(c) for c in zip(*moved, strict=True))
            ix, iy = _texel_index(mx, fr, "u", to), _texel_index(my, fr, "v", to)
            sums += _texel_sums(n, n_out, ix, iy, to, mf, fr)
        sums.append(np.bincount(idx_all, weights=w_all, minlength=n + n_out))
        return sums

    # the levels side by side in threads, their sums added in the levels' order: the
    # same additions as one level after the other
    n = len(acc)
    for sums in parallel.map_items(level, range(len(levels)), work=int(first[-1])):
        for both in sums:
            acc += both[:n]
            out_acc += both[n:]
    return int(first[-1])


#: Sub-cells a splat level handles at once (`_splat_cells`): its temporaries 256 KB;
#: and its products of cells × 4 corners by the sub-cells' weights small enough that
#: OpenBLAS runs each on one thread (its threads cost far more than they save on a
#: product 4 deep: 8.9 ms wall against 0.22 ms for (4145, 4) @ (4, 64)).
SPLAT_BLOCK = 1 << 15


def _corner_sum(a) -> np.ndarray:
    """``a.sum(axis=1)`` of (C, 4) corner values, bit for bit (numpy adds a row of four
    in turn), without numpy's slow reduction along a short axis (as `_corner_ptp`)."""
    s = a[:, 0] + a[:, 1]
    s += a[:, 2]
    s += a[:, 3]
    return s


def _corner_ptp(a) -> np.ndarray:
    """``np.ptp(a, axis=1)`` of (C, 4) corner values (exact: maxima and minima), four
    columns compared instead of a short-axis reduction (~10× faster at 25 000 cells)."""
    c0, c1, c2, c3 = a[:, 0], a[:, 1], a[:, 2], a[:, 3]
    return np.maximum(np.maximum(c0, c1), np.maximum(c2, c3)) - np.minimum(
        np.minimum(c0, c1), np.minimum(c2, c3)
    )


#: Roberts' R2 sequence (the plastic number): well spread points in the unit square.
_R2 = 1.0 / np.array([1.32471795724474602596, 1.32471795724474602596**2])


def _share_points(start: int, shape, disc, cells, grid) -> tuple[np.ndarray, np.ndarray]:
    """Offsets (shape coordinates of the emitter) to points of each cell's sample's
    share for ``shape`` = (cells, sub-cells), the sub-cells numbered from ``start`` along
    a low-discrepancy sequence. Deterministic, so an animation does not flicker."""
    i = start + np.arange(shape[0] * shape[1], dtype=float).reshape(shape)
    s = np.modf(0.5 + i * _R2[0])[0]
    t = np.modf(0.5 + i * _R2[1])[0]
    return share_offsets(cells, grid, disc, s, t)


def _cell_shares(landed: list[_Landed]):
    """Per cell of the landed beams: its sample's rotation vectors (C, 2, 3), its lens
    centre (C, 3), whether the emitter is a disc (C,), its share's grid cell (C, 2) and
    the grid's size (C,)."""
    rot, ctr, disc, cells, grid = [], [], [], [], []
    for lb in landed:
        b = lb.beam
        k, nr, na = b.shape
        n = nr * na
        r = b.rotations if b.rotations is not None else np.zeros((k, 2, 3))
        rot.append(np.repeat(r, n, axis=0))
        c = b.center if b.center is not None else np.zeros(3)
        ctr.append(np.broadcast_to(c, (k * n, 3)))
        disc.append(np.full(k * n, bool(b.share_disc)))
        sc = b.share_cells if b.share_cells is not None else np.zeros((k, 2), dtype=np.int64)
        cells.append(np.repeat(sc, n, axis=0))
        grid.append(np.full(k * n, int(b.share_grid)))
    return (
        np.concatenate(rot),
        np.concatenate(ctr),
        np.concatenate(disc),
        np.concatenate(cells),
        np.concatenate(grid),
    )


def _share_offsets(corner_pts, corner_dirs, rot, centers, slots, fr):
    """(C, 2, 2): per cell, the plane offsets (u, v) of its landing for a unit step along
    each axis of its sample's share. The beam turns about the lens centre by α, so the
    landing q moves by α × q; that move is carried back onto the receiver's plane along
    the cell's ray direction (a grazing receiver stretches it, at most 20×)."""
    au, av = fr["au"][slots], fr["av"][slots]
    nrm = np.cross(au, av)
    q = corner_pts.mean(axis=1) - centers
    d = corner_dirs.mean(axis=1)
    d /= np.maximum(np.linalg.norm(d, axis=1), 1e-300)[:, None]
    delta = np.cross(rot, q[:, None, :])  # (C, 2, 3)
    dn = np.einsum("ci,ci->c", d, nrm)
    dn = np.where(dn >= 0.0, 1.0, -1.0) * np.maximum(np.abs(dn), 0.05)
    delta = delta - d[:, None, :] * (np.einsum("cki,ci->ck", delta, nrm) / dn[:, None])[..., None]
    return np.stack(
        [np.einsum("cki,ci->ck", delta, au), np.einsum("cki,ci->ck", delta, av)], axis=-1
    )


def _affine_uv_fit(index: ReceiverIndex, patch: ReceiverPatch, n_out):
    """Least-squares affine map (plane coordinates → UV) over the patch's vertices and
    whether it is exact; None without UVs."""
    mesh = index.mesh
    if mesh.uvs is None:
        return None
    used = np.zeros(len(mesh.vertices), dtype=bool)
    used[np.asarray(mesh.triangles)[patch.triangles].reshape(-1)] = True
    vi = np.nonzero(used)[0]  # the patch's vertices, sorted (a mask: no sort needed)
    uv = np.asarray(mesh.uvs, dtype=float)
    pv = np.asarray(mesh.vertices, dtype=float)[vi]
    au, av = perpendicular_frame(n_out)
    a = np.column_stack([pv @ au, pv @ av, np.ones(len(pv))])
    coef = np.linalg.lstsq(a, uv[vi], rcond=None)[0]
    scale = max(float(np.ptp(uv[vi], axis=0).max()), 1e-300)
    # Blender stores UVs in float32: affine to its precision counts as affine
    return coef, bool(np.abs(a @ coef - uv[vi]).max() <= 1e-6 * scale)


def _vertex_uvs(index: ReceiverIndex, uv_fit, p, verts, n_out):
    """The receiver's UV at each layer vertex. A plane's UVs are usually affine in the
    plane: then the least-squares affine fit is exact and used everywhere (``inside`` is
    None). Otherwise barycentric interpolation on the patch's triangle under each vertex,
    the affine fit beyond the patch (``inside`` False there)."""
    if uv_fit is None:
        return None, None
    coef, exact = uv_fit
    au, av = perpendicular_frame(n_out)
    fit = np.column_stack([verts @ au, verts @ av, np.ones(len(verts))]) @ coef
    if exact:
        return fit, None
    mesh = index.mesh
    uv = np.asarray(mesh.uvs, dtype=float)
    h = 1e-6 * max(float(np.ptp(verts, axis=0).max()), 1e-300)
    hits = intersect(
        index, verts + h * n_out, np.broadcast_to(-n_out, verts.shape), t_min=0.0, t_max=2.0 * h
    )
    tri = hits.triangle
    inside = (tri >= 0) & (index.patch_of[np.maximum(tri, 0)] == p)
    tv = np.asarray(mesh.triangles)[np.maximum(tri, 0)]
    bary = np.stack([1.0 - hits.u - hits.v, hits.u, hits.v], axis=1)
    out = np.einsum("nk,nkj->nj", bary, uv[tv])
    return np.where(inside[:, None], out, fit), inside


@dataclass
class BeamFlux:
    """One beam's flux in fixed rasters (`beam_fluxes`): the texels it reaches (flat
    indices into the rasters' blocks of `FixedRasters.side`²), their flux (W,
    uncoloured), the flux landed beyond each raster, lost (missed every receiver) and
    landed out of view, its colour and its sub-cells (its cells' share of its batch's)."""

    texels: np.ndarray
    flux: np.ndarray
    outside: np.ndarray
    lost: float
    unseen: float
    color: np.ndarray
    subcells: int


@dataclass
class FixedRasters:
    """A layer's rasters kept as they are (texel lines, planes, resolutions): what
    `beam_fluxes` fills. ``slot_of`` (beams, patches): each beam's raster per patch."""

    patches: list[PatchLayer]
    slot_of: np.ndarray
    fr: dict
    side: int


def fixed_rasters(patches: list[PatchLayer], n_beams: int, n_patches: int) -> FixedRasters:
    """The rasters of ``patches`` (a `CausticLayer`'s, its beams numbered as their
    ``sources``), to fill again with other landings of those beams."""
    slot_of = np.full((n_beams, n_patches), -1, dtype=np.int64)
    outer = np.full(len(patches), -1, dtype=np.int64)
    for k, pl in enumerate(patches):  # the fine raster first, as `build_layer` makes them
        if not pl.coarse:
            slot_of[np.asarray(pl.sources, dtype=np.int64), pl.patch] = k
    for k, pl in enumerate(patches):  # a coarse one takes what lands beyond the fine one
        if not pl.coarse:
            continue
        beams = np.asarray(pl.sources, dtype=np.int64)
        first = slot_of[beams[0], pl.patch] if len(beams) else -1
        if first >= 0:
            outer[first] = k
        else:
            slot_of[beams, pl.patch] = k
    fr = {
        "au": np.array([pl.axis_u for pl in patches], dtype=float).reshape(-1, 3),
        "av": np.array([pl.axis_v for pl in patches], dtype=float).reshape(-1, 3),
        "res": np.array([pl.resolution for pl in patches], dtype=np.int64),
        "outer": outer,
    }
    for k, key in enumerate(("u", "v")):
        for j, name in enumerate(AXIS_FIELDS):
            fr[key + name] = np.array([float(pl.axes[k][j]) for pl in patches])
    fr["side"] = side = int(fr["res"].max(initial=1))
    return FixedRasters(list(patches), slot_of, fr, side)


def beam_fluxes(
    beams: list[BeamGrid],
    ids: list[int],
    index: ReceiverIndex,
    rasters: FixedRasters,
    own_objects=None,
    subcells_per_texel: float = 2.0,
    max_subdivision: int = 4,
    blur_shares: bool = True,
) -> list[BeamFlux]:
    """Each of ``beams`` (the rasters' beams ``ids``) landed on ``index`` (one cast for
    all) and splatted, alone, into the fixed ``rasters``: its flux per texel, to be
    summed with other beams' (`fixed_layer`). At most ``max_subdivision`` sub-cells per
    side of a cell (at most 8: no flux budget shared between beams, so a beam's
    texels do not depend on the others')."""
    if not beams:
        return []
    landed = land_beams(beams, index, own_objects)
    splat = (subcells_per_texel, min(int(max_subdivision), 8), 8_000_000, 0.0)
    out = []
    for a in range(0, len(beams), BATCH_BEAMS):  # one splat per batch, not per beam
        part = landed[a : a + BATCH_BEAMS]
        out += _alone(part, ids[a : a + BATCH_BEAMS], rasters, blur_shares, splat)
    return out


#: Beams splatted together by `beam_fluxes`, each into its own copy of the rasters
#: (their texels: 16 × a layer's, at most).
BATCH_BEAMS = 16


def _alone(landed, ids, rasters: FixedRasters, blur_shares, splat) -> list[BeamFlux]:
    """`beam_fluxes` of one batch: the rasters repeated once per beam (beam b fills
    copy b), all splatted in one `_accumulate_beams` call."""
    fr, n_slots, side = rasters.fr, len(rasters.patches), rasters.side
    b = len(landed)
    copies = {k: np.tile(v, (b,) + (1,) * (np.ndim(v) - 1)) for k, v in fr.items() if k != "side"}
    shift = np.repeat(np.arange(b) * n_slots, n_slots)
    copies["outer"] = np.where(copies["outer"] >= 0, copies["outer"] + shift, -1)
    copies["side"] = side
    rows = rasters.slot_of[np.asarray(ids, dtype=np.int64)]
    slot_of = np.where(rows >= 0, rows + (np.arange(b) * n_slots)[:, None], -1)
    acc, out_acc, lost, unseen, n_sub = _accumulate_beams(
        landed, list(range(b)), slot_of, copies, blur_shares, splat
    )
    n = n_slots * side * side
    out = []
    for k, lb in enumerate(landed):
        block = acc[k * n : (k + 1) * n]
        texels = np.flatnonzero(block)
        out.append(
            BeamFlux(
                texels,
                block[texels],
                out_acc[k * n_slots : (k + 1) * n_slots],
                float(lost[k]),
                float(unseen[k]),
                np.asarray(lb.beam.color),
                int(
                    n_sub
                    * lb.beam.cell_flux.size
                    / max(sum(x.beam.cell_flux.size for x in landed), 1)
                ),
            )
        )
    return out


def blur_flux(flux: np.ndarray, passes: int) -> np.ndarray:
    """``flux`` (r, r, ...) spread by ``passes`` binomial [1 2 1]/4 passes along each
    axis; what would leave the raster stays in its border texel (flux kept)."""
    for axis in (0, 1):
        for _ in range(passes):
            f = np.moveaxis(flux, axis, 0)
            out = 0.5 * f
            out[1:] += 0.25 * f[:-1]
            out[:-1] += 0.25 * f[1:]
            out[0] += 0.25 * f[0]
            out[-1] += 0.25 * f[-1]
            flux = np.moveaxis(out, 0, axis)
    return flux


def fixed_layer(
    rasters: FixedRasters, fluxes: list[BeamFlux], emitted: float, blur: int = 0
) -> CausticLayer:
    """The layer of ``rasters`` holding the sum of ``fluxes`` (coloured), the geometry of
    its patches unchanged (``emitted``: the beams' flux leaving the lenses); ``blur``:
    binomial passes over each raster's texel flux (`blur_flux`: a coarse splat's
    sampling noise smoothed, the flux kept)."""
    n_slots, side = len(rasters.patches), rasters.side
    size = n_slots * side * side
    texels = np.concatenate([f.texels for f in fluxes] + [np.zeros(0, dtype=np.int64)])
    flux = np.concatenate([f.flux for f in fluxes] + [np.zeros(0)])
    color = np.concatenate(
        [np.broadcast_to(f.color, (len(f.texels), 3)) for f in fluxes] + [np.zeros((0, 3))]
    )
    rgb = np.stack([np.bincount(texels, flux * color[:, c], minlength=size) for c in range(3)], 1)
    plain = np.bincount(texels, flux, minlength=size).reshape(n_slots, side * side).sum(axis=1)
    outside = np.sum([f.outside for f in fluxes], axis=0) if fluxes else np.zeros(n_slots)
    rgb = rgb.reshape(n_slots, side, side, 3)
    patches = []
    for k, pl in enumerate(rasters.patches):
        r = pl.resolution
        area = pl.texel_areas()[..., None]
        patches.append(
            dataclasses.replace(
                pl,
                irradiance=blur_flux(rgb[k, :r, :r], blur) / area,
                flux=float(plain[k]),
                flux_outside=float(outside[k]),
            )
        )
    return CausticLayer(
        patches=patches,
        flux_emitted=float(emitted),
        flux_in_rasters=float(plain.sum()),
        flux_outside=float(np.sum(outside)) + sum(f.unseen for f in fluxes),
        flux_lost=sum(f.lost for f in fluxes),
        n_rays=0,
        n_cells=0,
        n_subcells=sum(f.subcells for f in fluxes),
    )
