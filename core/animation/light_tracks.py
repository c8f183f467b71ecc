"""The pure part of the animation bake (`blender/commands/bake.py`): which lens light is
"the same" from one frame to the next, its values over the frames as keyframe
columns, and the Exact profile's one table per lens for all frames.

* **Keys.** A lens light keeps its Blender object over the frames when its key is
  equal: live update's `light_keys.LightKey` (the primary light's name, the lens'
  (object or instance) name, the source's kind, the tier, an occurrence number) with
  a variant (the Exact profile's near field has another table geometry).
* **Tracks.** Per key, one row per frame of every keyed value (`Track`); a frame
  without the key holds its nearest present values (so nothing jumps in or out
  between keys) and is keyed hidden. Quaternions are made continuous (q and −q are
  the same rotation; interpolating across a sign flip would spin the light).
* **Profile slices.** The Exact profile's table depends on the lens' D/R (and n);
  a moving light changes D/R on every frame. Instead of one image per frame, the
  bake tabulates a geometric grid of D/R values (anchored at 1, ratio
  `SLICE_RATIO`, so lenses and re-bakes share tables) covering the D/R the key
  takes, stacks the grid's tables in one image (slice k: rows k·M … (k+1)·M − 1)
  and keys a fractional slice coordinate per frame: the node tree blends the two
  neighbouring slices (`slice_coordinate`). The number of images is the number of
  (lens, n, near) groups, whatever the number of frames. The near field's table
  has a row on the receiver (`tiers.exact_profile.table_geometry`; a plane even half
  a row off it reads −48 % at the caustic's centre, reports/bake_near_field.md): a
  near track reads each frame's own table, Generate's, through
  `frame_tables` (`FrameLight.tables`), as it reads each frame's shadow mask.
* **Frame ranges** of the command line (`parse_frames`, `frame_path`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..tiers.exact_profile import NEAR_DISTANCES, cached_profile, table_geometry

#: Ratio between neighbouring D/R slices of a baked profile table (a 4 % step moves
#: the paraxial focus by about 2 % of its distance, one table row); widened
#: (squared) until a group needs at most `MAX_SLICES`.
SLICE_RATIO = 1.04
MAX_SLICES = 12
#: The D/R grid's range (the exact trace needs D > R; a sun's D/R is huge).
MIN_D_OVER_R, MAX_D_OVER_R = 1.0 + 1e-6, 1e6

#: Keyed per frame: name → number of components. A frame may record more (the
#: numbers of its node tree, named after the Value node the bake keys with them):
#: their sizes are their first frame's.
CHANNELS = {
    "location": 3,
    "rotation_quaternion": 4,
    "scale_xy": 1,
    "energy": 1,
    "color": 3,
    "spot_size": 1,
    "spot_blend": 1,
    "radius": 1,
    "slice": 1,  # Exact profile: the fractional slice coordinate
    "h_min": 1,  # Exact profile: the table's first distance (world units)
    "receiver": 1,  # Exact profile, near field: the receiver's distance (R); not keyed
    "lens_radius": 1,  # Exact profile: R (world units); not keyed
}


@dataclass
class FrameLight:
    """One lens light on one frame (world units; angles in radians)."""

    key: object  # hashable: a `light_keys.LightKey`
    values: dict  # channel name → float or sequence (see CHANNELS); missing: 0
    #: Exact profile: (lens name, n, near) of its table group, and its D/R.
    profile_group: tuple | None = None
    d_over_r: float = math.nan
    #: The frame's own tables its node tree reads (role → (key, pixels), None: none
    #: this frame): the near field's table, the shadow mask (`frame_tables`).
    tables: dict = field(default_factory=dict)


@dataclass
class Track:
    """One key over the bake's frames."""

    key: object
    frames: np.ndarray  # (F,) int
    present: np.ndarray  # (F,) bool
    values: dict = field(default_factory=dict)  # channel → (F, components)
    profile_group: tuple | None = None
    d_over_r: np.ndarray | None = None  # (F,), held like the values
    #: role → per frame (key, pixels) or None, held like the values
    tables: dict = field(default_factory=dict)

    @property
    def first(self) -> int:
        """Index of the first frame the key exists on."""
        return int(np.argmax(self.present))


def _fill_nearest(present: np.ndarray) -> np.ndarray:
    """For each frame, the index of the nearest present frame (earlier on a tie)."""
    idx = np.flatnonzero(present)
    pos = np.arange(len(present))
    right = np.clip(np.searchsorted(idx, pos), 0, len(idx) - 1)
    left = np.clip(right - 1, 0, len(idx) - 1)
    use_left = np.abs(pos - idx[left]) <= np.abs(idx[right] - pos)
    return np.where(use_left, idx[left], idx[right])


def continuous_quaternions(q: np.ndarray) -> np.ndarray:
    """`q` (F, 4) with each row's sign chosen to be nearest the previous row."""
    q = np.array(q, dtype=float)
    for k in range(1, len(q)):
        if float(np.dot(q[k], q[k - 1])) < 0.0:
            q[k] = -q[k]
    return q


def build_tracks(frames, per_frame) -> list[Track]:
    """Tracks for `frames` (list of int) from `per_frame[i]` (the `FrameLight`s of
    frame i), in order of first appearance. A key present twice on one frame is an
    error (keys must identify a light)."""
    frames = np.asarray(list(frames), dtype=np.int64)
    if len(frames) != len(per_frame):
        raise ValueError(f"{len(frames)} frames but {len(per_frame)} frame plans")
    order: dict = {}
    rows: list[dict[int, FrameLight]] = []
    for i, lights in enumerate(per_frame):
        for fl in lights:
            t = order.get(fl.key)
            if t is None:
                t = order[fl.key] = len(rows)
                rows.append({})
            if i in rows[t]:
                raise ValueError(f"two lens lights with the key '{fl.key}' on frame {frames[i]}")
            rows[t][i] = fl
    out = []
    n = len(frames)
    for key, t in order.items():
        got = rows[t]
        present = np.zeros(n, dtype=bool)
        present[list(got)] = True
        near = _fill_nearest(present)
        first = got[min(got)]
        track = Track(key, frames, present, profile_group=first.profile_group)
        channels = dict(CHANNELS)
        for fl in got.values():
            for name, v in fl.values.items():
                channels.setdefault(name, int(np.size(v)))
        for name, size in channels.items():
            col = np.zeros((n, size))
            for i, fl in got.items():
                v = fl.values.get(name, 0.0)
                col[i] = np.broadcast_to(np.asarray(v, dtype=float), (size,))
            track.values[name] = col[near]
        track.values["rotation_quaternion"] = continuous_quaternions(
            track.values["rotation_quaternion"]
        )
        dr = np.full(n, np.nan)
        for i, fl in got.items():
            dr[i] = fl.d_over_r
        track.d_over_r = dr[near]
        for role in {r for fl in got.values() for r in fl.tables}:
            track.tables[role] = [got[int(j)].tables.get(role) for j in near]
        out.append(track)
    return out


def visibility_keys(frames, present) -> list[tuple[int, bool]]:
    """(frame, hidden) keyframes, CONSTANT interpolation: the first frame and every
    frame where presence changes (before the first key Blender holds its value,
    after the last too)."""
    out = []
    prev = None
    for f, p in zip(np.asarray(frames).tolist(), np.asarray(present).tolist(), strict=True):
        if p != prev:
            out.append((int(f), not p))
            prev = p
    return out


def single_frame_visibility(frame: int, first: int, last: int) -> list[tuple[int, bool]]:
    """(frame, hidden) keys for an object shown only on `frame` of `first…last`."""
    keys = []
    if frame > first:
        keys.append((frame - 1, True))
    keys.append((frame, False))
    if frame < last:
        keys.append((frame + 1, True))
    return keys


# --------------------------------------------------------------------------- profile slices


def _clamped(d_over_r) -> np.ndarray:
    return np.clip(np.asarray(d_over_r, dtype=float), MIN_D_OVER_R, MAX_D_OVER_R)


def slice_grid(d_over_r_values, ratio: float = SLICE_RATIO, max_slices: int = MAX_SLICES):
    """The D/R grid covering `d_over_r_values` (finite ones): ``ratio**k`` for the
    k spanning them (one value if they all round to one node), the ratio squared
    until at most `max_slices` nodes are needed. Returns a float array."""
    v = _clamped([x for x in np.ravel(d_over_r_values) if math.isfinite(x)])
    if not len(v):
        raise ValueError("no finite D/R to tabulate")
    lo, hi = float(v.min()), float(v.max())
    if math.isclose(lo, hi, rel_tol=1e-9):
        return np.array([lo])  # a still lens: its own table, as Generate makes it
    while True:
        step = math.log(ratio)
        k0 = math.floor(math.log(lo) / step + 1e-9)
        k1 = math.ceil(math.log(hi) / step - 1e-9)
        if k1 - k0 + 1 <= max_slices:
            return np.exp(np.arange(k0, k1 + 1) * step)
        ratio *= ratio


def grid_size(d_over_r_values, ratio: float = SLICE_RATIO) -> int:
    """How many nodes of the `ratio` grid cover `d_over_r_values` (finite ones)."""
    v = _clamped([x for x in np.ravel(d_over_r_values) if math.isfinite(x)])
    if not len(v) or math.isclose(float(v.min()), float(v.max()), rel_tol=1e-9):
        return 1
    step = math.log(ratio)
    return (
        math.ceil(math.log(float(v.max())) / step - 1e-9)
        - math.floor(math.log(float(v.min())) / step + 1e-9)
        + 1
    )


def profile_groups(tracks, ratio: float = SLICE_RATIO, max_slices: int = MAX_SLICES) -> dict:
    """{image group: (track keys, D/R grid)} for the Exact profile tracks: one group
    per (lens, n, near field) whose keys' D/R fit in `MAX_SLICES` nodes of the
    `SLICE_RATIO` grid together; else (a sun and a lamp on one lens: D/R 10⁶ and 4)
    each key of it is a group of its own, so that one far-off key does not coarsen
    the others' slices."""
    by_lens: dict = {}
    for t in tracks:
        if t.profile_group is not None:
            by_lens.setdefault(t.profile_group, []).append(t)
    out = {}
    for group, members in by_lens.items():
        values = [x for t in members for x in t.d_over_r[t.present]]
        if len(members) == 1 or grid_size(values, ratio) <= max_slices:
            out[group] = ([t.key for t in members], slice_grid(values, ratio, max_slices))
            continue
        for t in members:
            grid = slice_grid(t.d_over_r[t.present], ratio, max_slices)
            out[(*group, t.key)] = ([t.key], grid)
    return out


def slice_coordinate(d_over_r, grid) -> np.ndarray:
    """The fractional slice index (0 … len(grid) − 1) of each D/R, linear in
    log(D/R) between the grid's nodes, clamped at its ends."""
    g = np.log(np.asarray(grid, dtype=float))
    x = np.log(_clamped(d_over_r))
    if len(g) == 1:
        return np.zeros_like(x)
    return np.interp(x, g, np.arange(len(g), dtype=float))


def stack_slices(tables) -> np.ndarray:
    """The tables (each (M, K), already normalised) stacked bottom-up: slice k at
    rows k·M … (k+1)·M − 1 (Blender's row 0 is the bottom row)."""
    tables = [np.asarray(t, dtype=np.float32) for t in tables]
    shapes = {t.shape for t in tables}
    if len(shapes) != 1:
        raise ValueError(f"slices of different sizes: {sorted(shapes)}")
    return np.concatenate(tables, axis=0)


def slice_row(v: float, slice_index: int, slices: int, rows: int) -> float:
    """The image's vertical texture coordinate of the table coordinate `v` in slice
    `slice_index` of `slices` of `rows` rows each: `v` clamped to the slice's first
    and last row centres, so the linear filter never reads a neighbouring slice
    (what the node tree of `blender/commands/bake.py` computes)."""
    half = 0.5 / rows
    return (slice_index + min(max(v, half), 1.0 - half)) / slices


def slice_h_min(receiver: float | None) -> float:
    """The first distance (R) of the table `profile_slice_table` makes for
    `receiver` (None: the far table)."""
    return table_geometry(receiver, NEAR_DISTANCES, on_row=True)[1]


def profile_slice_table(
    d_over_r: float, n: float, near: bool, receiver: float | None = None
) -> np.ndarray:
    """The Exact profile's table for one D/R (near field: with its row on the
    receiver `receiver` R from the lens centre, as Generate makes it), normalised as
    Generate normalises it (intensity over energy/(4π),
    `tiers.exact_profile.make_profile_light`)."""
    if near and receiver is None:
        raise ValueError("a near-field slice needs its receiver distance")
    z = round(float(receiver), 6) if near else None
    prof = cached_profile(round(float(d_over_r), 9), round(float(n), 9), bool(near), z)
    t_ref = prof.flux / (2.0 * math.pi) if prof.flux > 0 else 1.0
    return (prof.table / t_ref).astype(np.float32)


# --------------------------------------------------------------------------- report


def bake_message(figures: dict) -> str:
    """The report of a bake (`blender/commands/bake.py`'s figures)."""
    water = figures.get("water_objects", 0)  # the water's layers, in every tier
    n = figures["objects"] - water
    what = "caustic layer object" if figures["energy_model"] == "CAUSTIC_LAYER" else "lens light"
    what += "s" if n != 1 else ""
    parts = [f"{n} {what}"] if n or not water else []
    if water:
        parts.append(f"{water} water caustic layer object{'s' if water != 1 else ''}")
    text = (
        f"Baked {' and '.join(parts)} over frames {figures['frame_start']}–"
        f"{figures['frame_end']} ({figures['frames']} frames, {figures['seconds']:.1f} s)"
    )
    if figures.get("images"):
        kind = "layer" if "layer_resolution" in figures else "profile"
        text += f"; {figures['images']} {kind} image{'s' if figures['images'] != 1 else ''}"
    if figures.get("water_images"):
        k = figures["water_images"]
        text += f"; {k} water layer image{'s' if k != 1 else ''}"
    masks = figures.get("mask_images", 0)
    if masks:
        text += f"; {masks} shadow mask image{'s' if masks != 1 else ''}"
    return text


# --------------------------------------------------------------------------- frame ranges


def parse_frames(text: str) -> tuple[int, int]:
    """'A-B' (or 'A..B', or one frame 'A') → (A, B), A ≤ B; a clear ValueError else."""
    s = str(text).strip()
    for sep in ("..", ":"):
        s = s.replace(sep, "-")
    parts = s[1:].split("-", 1) if s.startswith("-") else s.split("-", 1)
    if s.startswith("-"):
        parts[0] = "-" + parts[0]
    try:
        a = int(parts[0])
        b = int(parts[1]) if len(parts) > 1 else a
    except ValueError:
        raise ValueError(f"expected a frame range START-END, e.g. 1-120, got '{text}'") from None
    if b < a:
        raise ValueError(f"the frame range {text} ends before it starts (did you mean {b}-{a}?)")
    return a, b


def frame_path(pattern: str, frame: int) -> str:
    """`pattern` with its last run of '#' replaced by `frame`, zero-padded to the run's
    length (Blender's convention); unchanged when it has no '#'."""
    end = pattern.rfind("#")
    if end < 0:
        return pattern
    start = end
    while start > 0 and pattern[start - 1] == "#":
        start -= 1
    width = end - start + 1
    sign = "-" if frame < 0 else ""
    return f"{pattern[:start]}{sign}{abs(frame):0{width}d}{pattern[end + 1 :]}"
