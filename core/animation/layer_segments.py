"""The Caustic layer's animation bake with a fixed topology (the pure part of
`blender/commands/bake.py`'s layer bake).

Generate fits each frame's rasters to that frame's landings
(`core.caustic_layer.rasters`): their extent and texel lines move with the caustic, so one mesh per
frame would be needed. The bake instead keeps one mesh per **segment**:

* **Tracks.** A raster of a frame is "the same" as one of another frame when it lies
  on the same receiver plane (receiver name, normal toward the light, offset) and
  holds the caustics of the same lens lights (their bake keys, `light_keys`).
* **Union raster.** A track's frames share one raster: its extent is the union of the
  frames' extents, its texel lines a sinh warp (as Generate's) centred between the
  frames' cores, its width `s` chosen so that at each frame's core the texel is as
  close to that frame's own as it can be (`union_axis`). Where one raster over all
  frames would make a frame's core texel more than `COARSEN_LIMIT` times its own (a
  caustic that travels far), the track is cut into consecutive segments, each its own
  mesh shown on its frames only (`segments`).
* **Re-landing.** Each frame's beams (the same traced rays as Generate's: same
  budgets) are landed again on its segments' rasters (`caustic_layer.RasterFrame`),
  so a slice holds what Generate's layer holds on that frame, on the segment's texels
  (`bake_frames`; a frame whose segments' rasters are its own keeps Generate's).
* **Mesh.** The material finds each point's texel from its position (the inverse
  warp, `raster_coordinate`), so a segment needs one quad where the receiver's UVs
  are affine (`baked_mesh`): the file does not grow with the raster's resolution.
* **Slices.** Every segment's rasters on every frame become slices of one atlas
  image (`atlas_layout`, `stack_atlas`): tiles of res × res texels, slice k at tile
  (k mod cols, k div cols), each normalised to its own maximum (the scale and the
  colour are keyed per frame), one channel when every slice is one colour times a
  scalar (`split_colour`).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from ..caustic_layer.pipeline import bake as sheet_bake
from ..caustic_layer.rasters import PatchLayer, RasterFrame

#: A segment's texel at a frame's caustic core may be at most this many times that
#: frame's own core texel (Generate's); beyond, the track is cut in time.
COARSEN_LIMIT = 2.0
#: Largest image side (GPU texture limit of common hardware and of Blender).
MAX_IMAGE_SIDE = 16384


@dataclass
class FrameLayers:
    """One frame as Generate baked it (`layer_generate.prepare`)."""

    sources: list  # pipeline.SheetSource per planned light
    sheet: object  # pipeline.SheetBake: its layer, budgets, resolution and index
    source_keys: list  # hashable bake key per source (`light_keys.LightKey`)
    receiver_names: list  # per receiver object id
    skip_objects: frozenset = frozenset()  # receiver object ids with no layer (fallback)
    # (raster_frames, res) → the patches landed on them, for beams that are not
    # `pipeline.bake`'s (water's: `water_sources.water_bake`); None: `pipeline.bake`
    reland: object = None


@dataclass
class Segment:
    """One baked layer object: a raster fixed over `frames`."""

    key: tuple  # (receiver name, plane, source keys, coarse: out of view)
    object_id: int  # receiver object id (on the segment's first frame)
    frames: list  # indices into the bake's frames
    axes: tuple  # ((c, s, ξ0, dξ) u, v) the union raster's texel lines
    coarsening: float  # max over frames and axes: texel at the core / the frame's own
    plane: tuple  # (normal, axis_u, axis_v)
    members: dict = field(default_factory=dict)  # frame index → (patch, beams) on it
    own: dict = field(default_factory=dict)  # frame index → Generate's PatchLayer there
    layer: PatchLayer | None = None  # re-landed on its first frame (the mesh)
    slices: list = field(default_factory=list)  # (res, res, 3) float32 irradiance per frame
    flux: list = field(default_factory=list)  # W in the raster per frame


def plane_key(layer: PatchLayer, name: str) -> tuple:
    """A receiver plane, the same over frames: its object's name, the normal toward
    the light and the offset along it (rounded: read per frame in float32)."""
    n = np.asarray(layer.normal, dtype=float)
    return (name, *np.round(n, 5).tolist(), round(float(np.dot(layer.origin, n)), 5))


def axis_facts(axis, res: int) -> tuple[float, float, float, float, float]:
    """(c, s, lo, hi, core texel) of a raster axis (c, s, ξ0, dξ) of `res` texels."""
    c, s, xi0, dxi = (float(x) for x in axis)
    return c, s, c + s * math.sinh(xi0), c + s * math.sinh(xi0 + res * dxi), s * dxi


def union_axis(facts, res: int) -> tuple[tuple, np.ndarray]:
    """One axis over the frames' axes (`axis_facts` each): the union of their extents,
    `res` texels on a sinh warp centred midway between their cores, its width chosen
    (among 96 from fine to uniform) to make the worst ratio of its texel at a frame's
    core to that frame's own core texel least, never finer than the finest frame's.
    Returns ((c, s, ξ0, dξ), ratio per frame)."""
    f = np.asarray(facts, dtype=float).reshape(-1, 5)
    cores, own = f[:, 0], f[:, 4]
    lo, hi = float(f[:, 2].min()), float(f[:, 3].max())
    c = 0.5 * (float(cores.min()) + float(cores.max()))
    span = hi - lo
    s = np.geomspace(max(float(f[:, 1].min()), 1e-6 * span), 1e3 * span, 96)[:, None]
    dxi = (np.arcsinh((hi - c) / s) - np.arcsinh((lo - c) / s)) / res
    ratio = np.hypot(s, cores[None, :] - c) * dxi / own[None, :]  # (candidates, frames)
    worst = ratio.max(axis=1)
    worst[(s * dxi)[:, 0] < own.min() * (1.0 - 1e-9)] = np.inf  # aliasing floor
    k = int(np.argmin(worst)) if np.isfinite(worst).any() else len(worst) - 1
    sk = float(s[k, 0])
    return (c, sk, math.asinh((lo - c) / sk), float(dxi[k, 0])), ratio[k]


def _union(axes, resolutions, res):
    """Union axes (u, v) of some frames' axes (Generate's, `res_k` texels each) and
    their worst coarsening. Frames whose rasters are all the same (a still caustic)
    keep that raster exactly: the slices are then Generate's layers texel for texel."""
    if all(r == res for r in resolutions) and all(
        np.array_equal(np.asarray(a, dtype=float), np.asarray(axes[0], dtype=float)) for a in axes
    ):
        return tuple(tuple(float(x) for x in a) for a in axes[0]), 1.0
    out, worst = [], 0.0
    for k in (0, 1):
        facts = [axis_facts(a[k], r) for a, r in zip(axes, resolutions, strict=True)]
        ax, ratio = union_axis(facts, res)
        out.append(ax)
        worst = max(worst, float(ratio.max()))
    return tuple(out), worst


def segments(axes, resolutions, res: int, limit=COARSEN_LIMIT, capacity: int | None = None):
    """Cut a track's frames (Generate's axes (u, v) and resolution per frame, in
    frame order) into consecutive runs whose union raster coarsens no frame's core
    texel more than `limit` times (and of at most `capacity` frames). Returns
    [(first, end, axes, coarsening)]."""
    out, start, n = [], 0, len(axes)
    while start < n:
        end = start + 1
        u, worst = _union(axes[start:end], resolutions[start:end], res)
        while end < n and (capacity is None or end - start < capacity):
            axes2, worst2 = _union(axes[start : end + 1], resolutions[start : end + 1], res)
            if worst2 > limit:
                break
            end, u, worst = end + 1, axes2, worst2
        out.append((start, end, u, worst))
        start = end
    return out


def plan_segments(frames: list[FrameLayers], limit: float = COARSEN_LIMIT) -> tuple[list, int]:
    """The segments of every track over `frames` and the bake's one resolution (the
    largest of the frames')."""
    res = max((fl.sheet.resolution for fl in frames if fl.sheet is not None), default=16)
    capacity = atlas_capacity(res)
    tracks: dict = {}
    for i, fl in enumerate(frames):
        if fl.sheet is None:
            continue
        for pl in fl.sheet.layer.patches:
            if pl.object_id in fl.skip_objects:
                continue
            keys = tuple(sorted((fl.source_keys[int(b)] for b in pl.sources), key=repr))
            # a coarse raster (out of view) is a track of its own beside the one in view
            key = (*plane_key(pl, fl.receiver_names[pl.object_id]), keys, bool(pl.coarse))
            tracks.setdefault(key, []).append((i, pl))
    out = []
    for key, rows in tracks.items():
        axes = [r[1].axes for r in rows]
        resolutions = [r[1].resolution for r in rows]
        for a, b, union, worst in segments(axes, resolutions, res, limit, capacity):
            first = rows[a][1]
            seg = Segment(
                key=key,
                object_id=first.object_id,
                frames=[r[0] for r in rows[a:b]],
                axes=union,
                coarsening=worst,
                plane=(first.normal, first.axis_u, first.axis_v),
            )
            seg.members = {i: (pl.patch, tuple(int(x) for x in pl.sources)) for i, pl in rows[a:b]}
            seg.own = dict(rows[a:b])
            out.append(seg)
    return out, res


def bake_frames(frames: list[FrameLayers], limit: float = COARSEN_LIMIT) -> tuple[list, int]:
    """The segments with their slices: each frame's beams (Generate's budgets) landed
    again on the rasters of the segments it belongs to (a frame whose segments' rasters
    are all its own, as a still caustic's, keeps Generate's: the same values).
    Returns (segments, res)."""
    segs, res = plan_segments(frames, limit)
    for i, fl in enumerate(frames):
        here = [s for s in segs if i in s.members]
        if not here:
            continue
        if all(_is_own_raster(s.own[i], s.axes, res) for s in here):
            layers = [s.own[i] for s in here]
        elif fl.reland is not None:
            given = [RasterFrame(*s.members[i], *s.plane, s.axes, s.key[-1]) for s in here]
            layers = fl.reland(given, res)
        else:
            given = [RasterFrame(*s.members[i], *s.plane, s.axes, s.key[-1]) for s in here]
            layers = sheet_bake(
                fl.sources,
                fl.sheet.index,
                budgets=fl.sheet.budgets,
                resolution=res,
                raster_frames=given,
            ).layer.patches
        for s, pl in zip(here, layers, strict=True):
            if s.layer is None:
                s.layer = pl
            s.slices.append(np.asarray(pl.irradiance, dtype=np.float32))  # (the image: half)
            s.flux.append(float(pl.flux))
    return segs, res


def _is_own_raster(layer: PatchLayer, axes, res: int) -> bool:
    return layer.resolution == res and all(
        np.array_equal(np.asarray(a, dtype=float), np.asarray(b, dtype=float))
        for a, b in zip(layer.axes, axes, strict=True)
    )


# --------------------------------------------------------------------------- the atlas


def atlas_capacity(res: int, side: int = MAX_IMAGE_SIDE) -> int:
    """How many res × res slices one image of at most `side` × `side` holds."""
    return max(side // int(res), 1) ** 2


def atlas_layout(count: int, res: int, side: int = MAX_IMAGE_SIDE) -> tuple[int, int]:
    """(columns, rows) of tiles for `count` slices: near square, within `side`."""
    if count > atlas_capacity(res, side):
        raise ValueError(f"{count} slices of {res}² texels do not fit in a {side}² image")
    cols = max(1, min(math.ceil(math.sqrt(count)), side // int(res)))
    return cols, math.ceil(count / cols)


def tile_of(k: int, cols: int) -> tuple[int, int]:
    """(column, row) of slice k: what the baked material computes from the keyed
    slice index (row = floor((k + ½) / cols), column = k − row · cols)."""
    row = math.floor((k + 0.5) / cols)
    return k - row * cols, row


def stack_atlas(slices, cols: int, rows: int) -> np.ndarray:
    """The slices (each (res, res[, C]), rows along v) in one image array
    (rows·res, cols·res[, C]), Blender's row 0 at the bottom: slice k's texel
    (iy, ix) at pixel (row·res + iy, col·res + ix); unused tiles 0."""
    first = np.asarray(slices[0])
    res = first.shape[0]
    out = np.zeros((rows * res, cols * res, *first.shape[2:]), dtype=np.float32)
    for k, sl in enumerate(slices):
        col, row = tile_of(k, cols)
        out[row * res : (row + 1) * res, col * res : (col + 1) * res] = sl
    return out


def read_atlas(image: np.ndarray, k: int, cols: int, res: int) -> np.ndarray:
    """Slice k back from an atlas (`stack_atlas`)."""
    col, row = tile_of(k, cols)
    return image[row * res : (row + 1) * res, col * res : (col + 1) * res]


def split_colour(slices, rel_tol: float = 1e-5):
    """Each slice (res, res, 3) as (normalised scalar image, scale, colour): the
    slice ≈ image × scale × colour with the image's maximum 1 and the colour's
    largest component 1; `mono` is True when every slice is one colour times a
    scalar (to `rel_tol` of its maximum; then the image needs one channel), else the
    images keep RGB (normalised to their largest component, colour white).
    Returns (images, scales, colours, mono)."""
    arrs = [np.asarray(s, dtype=float) for s in slices]
    cols, mono = [], True
    for a in arrs:
        tot = a.reshape(-1, 3).sum(axis=0)
        col = tot / tot.max() if tot.max() > 0 else np.ones(3)
        j = int(np.argmax(col))
        peak = float(a.max())
        if peak > 0 and np.abs(a - a[..., j : j + 1] * col).max() > rel_tol * peak:
            mono = False
        cols.append(col)
    images, scales, colours = [], [], []
    for a, col in zip(arrs, cols, strict=True):
        peak = float(a.max())
        scale = peak if peak > 0 else 1.0
        if mono:
            j = int(np.argmax(col))
            images.append((a[..., j] / scale).astype(np.float32))
            colours.append(tuple(float(x) for x in col))
        else:
            images.append((a / scale).astype(np.float32))
            colours.append((1.0, 1.0, 1.0))
        scales.append(scale)
    return images, scales, colours, mono


def raster_coordinate(points, axes, axis_u, axis_v, res: int) -> np.ndarray:
    """(N, 2) the raster coordinate (u, v in 0…1 over the raster, texel (iy, ix) at
    [ix, ix + 1)/res × [iy, iy + 1)/res) of world `points` on a segment's plane: the
    inverse of its texel lines' warp, x = c + s·sinh(ξ0 + t·res·dξ), what the baked
    material computes from the object's coordinates (asinh as sign · ln(|x| + √(x²+1)),
    exact in float32 far from the core too)."""
    p = np.asarray(points, dtype=float).reshape(-1, 3)
    out = []
    for axis, a in zip(axes, (axis_u, axis_v), strict=True):
        c, s, xi0, dxi = (float(x) for x in axis)
        x = (p @ np.asarray(a, dtype=float) - c) / s
        xi = np.sign(x) * np.log(np.abs(x) + np.sqrt(x * x + 1.0))
        out.append((xi - xi0) / (res * dxi))
    return np.stack(out, axis=1)


def baked_mesh(layer: PatchLayer) -> PatchLayer:
    """The mesh a segment needs: the material finds each point's texel from its
    position (`raster_coordinate`), so where the receiver's UVs are affine over the
    plane (`uv_inside` None) one quad over the raster's corners carries them exactly;
    else Generate's vertex grid (its UVs interpolated per vertex)."""
    if layer.uv_inside is not None:
        return layer
    res = layer.resolution
    corners = [0, res, (res + 1) * res, (res + 1) * (res + 1) - 1]
    return dataclasses.replace(
        layer,
        vertices=np.asarray(layer.vertices)[corners],
        faces=np.array([[0, 1, 3, 2]]),
        uvs=None if layer.uvs is None else np.asarray(layer.uvs)[corners],
        irradiance=np.zeros((1, 1, 3)),
    )
