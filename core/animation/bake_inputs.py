"""What a bake was baked from, to tell when the scene has changed under it (issue 28).

At every baked frame the bake keeps a *print* of each object the read held
(`frame_prints`: the plain records `blender/read/scene.py` made, no bpy): one short
digest each of where it is (its instances' world matrices), what it is (a light's
settings, a surface's material and lens settings) and its shape (its local box and
sphere fit), plus pseudo-objects for the Lens Lights settings and, for the caustic
layer (fitted to the view), the camera. Numbers are rounded to
``DIGITS`` significant digits (and to 0 below ``FLOOR``) first, so that evaluation
noise does not count. Instances are printed under their top object (the instancer's
name: "Grid changed", not 400 names).

`BakeInputs` holds the frames' prints compactly (per object a run of equal prints
is stored once) as JSON text in the .blend; `changes` compares a frame's prints
with those read now, and `stale_text` says what changed in words.
"""

from __future__ import annotations

import dataclasses
import enum
import hashlib
import json
from dataclasses import dataclass, field

import numpy as np

from ..plan import watch
from ..plan.watch import Capsules
from ..scene.light_props import LightRecord
from ..scene.primaries import PrimaryArrays
from ..tiers.base import COLLIMATED_DISTANCE_FACTOR

#: Significant digits kept of every number before hashing.
DIGITS = 6
#: Numbers smaller than this (absolute) count as 0 (a rotation's 1e-17 noise).
FLOOR = 1e-6
#: Hex digits of each part of a print (where / what / shape).
PART_HEX = 8
#: Record fields that are no input: names (the key already), Blender's objects,
#: the mesh that blocks rays (its box and fit stand for it), the fit's error figures.
_SKIPPED = frozenset(
    {"name", "orig", "mesh_source", "fit", "corners", "vertex_deviation", "face_depth"}
)
#: The pseudo-objects' names.
SETTINGS = "the Lens Lights settings"
CAMERA = "the camera"
#: Kinds of entry (the print's first character). A surface away from every path of
#: the light when it was baked: `AWAY` (its edits count only where it now touches one).
LIGHT, SURFACE, OTHER, AWAY = "L", "S", "X", "s"
#: How many changed objects a message names.
NAMED = 3
VERSION = 1


def quantised(values) -> np.ndarray:
    """`values` rounded to `DIGITS` significant digits (0 below `FLOOR`; NaN and
    infinities kept)."""
    x = np.asarray(values, dtype=float)
    small = ~(np.abs(x) >= FLOOR)  # NaN too: kept below
    with np.errstate(divide="ignore", invalid="ignore"):
        scale = 10.0 ** (DIGITS - 1 - np.floor(np.log10(np.where(small, 1.0, np.abs(x)))))
        q = np.round(x * scale) / scale
    q = np.where(small, 0.0, q)
    return np.where(np.isfinite(x), q, x) + 0.0  # + 0.0: no −0


def _number(x: float) -> str:
    """One number as `quantised` rounds it (in Python: no array for a scalar)."""
    x = float(x)
    if x != x or x in (float("inf"), float("-inf")):
        return repr(x)
    if abs(x) < FLOOR:
        return "0.0"
    return repr(float(f"{x:.{DIGITS}g}") + 0.0)


_FIELDS: dict = {}


def _fields(cls) -> tuple:
    """A dataclass' field names but `_SKIPPED` (looked up once per class)."""
    names = _FIELDS.get(cls)
    if names is None:
        names = _FIELDS[cls] = tuple(
            f.name for f in dataclasses.fields(cls) if f.name not in _SKIPPED
        )
    return names


def canonical(value, memo: dict | None = None) -> str:
    """A stable text of plain data (dataclasses, sequences, dicts, numbers, text,
    numpy arrays) with every number rounded as `quantised` does; `_SKIPPED` fields
    left out. `memo` (id → text) shares the text of a dataclass met again (a
    material's optics, read once per material)."""
    if value is None or isinstance(value, (bool, str)):
        return repr(value)
    if isinstance(value, enum.Enum):
        return repr(value.value)
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    if isinstance(value, (float, np.floating)):
        return _number(value)
    if isinstance(value, np.ndarray):
        return repr(quantised(value).tolist())
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        if memo is not None and id(value) in memo:
            return memo[id(value)]
        parts = [f"{n}={canonical(getattr(value, n), memo)}" for n in _fields(type(value))]
        text = f"{type(value).__name__}({', '.join(parts)})"
        if memo is not None:
            memo[id(value)] = text
        return text
    if isinstance(value, dict):
        items = sorted((str(k), canonical(v, memo)) for k, v in value.items())
        return "{" + ", ".join(f"{k}: {v}" for k, v in items) + "}"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(canonical(v, memo) for v in value) + "]"
    return repr(value)


def _digest(*chunks) -> str:
    h = hashlib.blake2b(digest_size=PART_HEX // 2)
    for c in chunks:
        h.update(c if isinstance(c, bytes) else str(c).encode())
    return h.hexdigest()


def _shapes(records) -> list[bytes]:
    """Each record's shape: its local box and sphere fit (centre, radius, or why
    none), rounded all at once."""
    n = len(records)
    corners = np.full((n, 8, 3), np.nan)
    fits = np.full((n, 5), np.nan)  # ok, centre, radius
    reasons = []
    for k, r in enumerate(records):
        c = getattr(r, "corners", None)
        if c is not None:
            corners[k] = c
        fit = getattr(r, "fit", None)
        if fit is not None:
            fits[k] = (float(fit.ok), *np.asarray(fit.center, float).reshape(3), fit.radius)
        reasons.append(fit.reason.encode() if fit is not None else b"-")
    corners, fits = quantised(corners), quantised(fits)
    return [corners[k].tobytes() + fits[k].tobytes() + reasons[k] for k in range(n)]


_PLAIN = (str, int, float, bool, type(None), tuple)


def _whats(records, memo) -> list[str]:
    """`canonical` of each record, once per distinct content (records alike but for
    their names, e.g. many objects of one material, share one text)."""
    texts: dict = {}
    out = []
    for r in records:
        key = (type(r), *(getattr(r, n) for n in _fields(type(r))))
        key = tuple(x if isinstance(x, _PLAIN) else id(x) for x in key)
        try:
            text = texts.get(key)
        except TypeError:  # a tuple holding something unhashable
            key, text = None, None
        if text is None:
            text = canonical(r, memo)
            if key is not None:
                texts[key] = text
        out.append(text)
    return out


def _glassy(record) -> bool:
    """Glass (a lens, or glass Lens Lights leaves to Cycles) or forced a lens: it
    counts wherever it is."""
    o = getattr(record, "optics", None)
    return getattr(record, "mode", "") == "ALWAYS" or (
        o is not None and (o.is_transmissive or o.thin_wall > 0)
    )


def light_paths(read) -> Capsules:
    """Where the light of `read` (a `core.scene.assembly.BlenderSceneRead`) can go
    that a plan looks at (`core.plan.watch`): every light to every lens it could
    have, and every such pair's axis through the lens both ways (the receiver, its
    tilt, the free distance behind the lens), as far as the planner casts."""
    lenses = np.flatnonzero(np.asarray(read.lens_candidates, bool))
    primaries = PrimaryArrays.from_primaries(read.primary_lights)
    origins, sizes, suns = watch.light_extents(primaries)
    centers = np.asarray(read.arrays.center, float)[lenses]
    radii = np.asarray(read.arrays.radius, float)[lenses]
    reach = COLLIMATED_DISTANCE_FACTOR * read.scene_size
    if not len(origins) or not len(centers):
        return Capsules.empty()
    axes = np.where(suns[:, None, None], origins[:, None, :], centers[None] - origins[:, None])
    n = np.linalg.norm(axes, axis=2)
    axes = np.where(n[..., None] > 0, axes, (0.0, 0.0, 1.0)).reshape(-1, 3)
    along = watch.along_axes(
        np.tile(centers, (len(origins), 1)), np.tile(radii, len(origins)), axes, reach
    )
    return Capsules.join([watch.light_to_lens(origins, sizes, suns, centers, radii, reach), along])


def owner_boxes(inputs, names) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """The world box (lo, hi) of each top object of `names` (all its instances'
    boxes: local corners through their matrices); an object without corners is
    left out."""
    names = set(names)
    owner = inputs.owners().astype(str)
    rows = np.flatnonzero(np.isin(owner, list(names)))
    corners = np.full((len(inputs.records), 8, 3), np.nan)
    for g, r in enumerate(inputs.records):
        c = getattr(r, "corners", None)
        if c is not None:
            corners[g] = c
    gid = np.asarray(inputs.gid, dtype=np.int64)[rows]
    m = np.asarray(inputs.matrices, float).reshape(-1, 4, 4)[rows]
    world = np.einsum("nij,nkj->nki", m[:, :3, :3], corners[gid]) + m[:, None, :3, 3]
    out = {}
    for name in np.unique(owner[rows]):
        w = world[owner[rows] == name].reshape(-1, 3)
        w = w[np.isfinite(w).all(axis=1)]
        if len(w):
            out[str(name)] = (w.min(axis=0), w.max(axis=0))
    return out


def away(inputs, names, paths: Capsules) -> set[str]:
    """The top objects of `names` that are surfaces of no glass whose world box
    touches none of `paths` (`light_paths`): away from the light."""
    names = {str(n) for n in names}
    owner = inputs.owners().astype(str)
    rows = np.isin(owner, list(names))
    records = inputs.records
    counted = np.array([isinstance(r, LightRecord) or _glassy(r) for r in records], dtype=bool)
    gid = np.asarray(inputs.gid, dtype=np.int64)
    always = set(owner[rows & counted[gid]]) if len(gid) else set()
    boxes = owner_boxes(inputs, names - always)
    if not boxes:
        return set()
    keys = list(boxes)
    lo = np.array([boxes[k][0] for k in keys])
    hi = np.array([boxes[k][1] for k in keys])
    return {k for k, t in zip(keys, paths.touching(lo, hi), strict=True) if not t}


def frame_prints(inputs, extra: dict | None = None, paths: Capsules | None = None) -> dict:
    """Per top object of `inputs` (`core.scene.assembly.ReadInputs`) its print "K
    where what shape" (K: `LIGHT`, `SURFACE` or `OTHER`; each part `PART_HEX` hex
    digits), and per entry of `extra` (name → plain data, e.g. the settings) an
    `OTHER` print of its value. With `paths` (`light_paths`), a surface that is no
    glass and touches none of them is `AWAY`."""
    out: dict[str, str] = {}
    records = inputs.records
    memo: dict = {}  # alive while `records` are: ids stay theirs
    what = _whats(records, memo)
    shape = _shapes(records)
    gid = np.asarray(inputs.gid, dtype=np.int64).reshape(-1)
    mats = quantised(np.asarray(inputs.matrices, dtype=float).reshape(-1, 4, 4))
    is_light = np.array([isinstance(r, LightRecord) for r in records], dtype=bool)
    if gid.size:
        owner = inputs.owners()
        names, which = np.unique(owner.astype(str), return_inverse=True)
        order = np.argsort(which, kind="stable")  # instances by owner, in read order
        bounds = np.searchsorted(which[order], np.arange(len(names) + 1))
        for k, name in enumerate(names):
            rows = order[bounds[k] : bounds[k + 1]]
            gs = gid[rows]
            light = bool(is_light[gs].all())
            out[str(name)] = "".join(
                (
                    LIGHT if light else SURFACE,
                    _digest(mats[rows].tobytes()),
                    _digest(*(what[g] for g in gs)),
                    _digest(*(shape[g] for g in gs)),
                )
            )
        if paths is not None:
            for name in away(inputs, names, paths):
                out[name] = AWAY + out[name][1:]
    zero = "0" * PART_HEX
    for name, value in (extra or {}).items():
        out[name] = OTHER + zero + _digest(canonical(value)) + zero
    return out


@dataclass
class Change:
    name: str
    what: str  # "moved", "changed", "shape", "added", "removed"
    kind: str = SURFACE


def same(a: str | None, b: str | None) -> bool:
    """Two prints of one object alike (`AWAY` or not aside)?"""
    if a is None or b is None:
        return a is b
    return a[1:] == b[1:] and a[0].upper() == b[0].upper()


def differing(baked: dict, now: dict) -> list[str]:
    """The names whose prints differ (`same`), in order."""
    return [n for n in sorted(set(baked) | set(now)) if not same(baked.get(n), now.get(n))]


def changes(baked: dict, now: dict, shapes: bool = True) -> list[Change]:
    """What differs between a frame's `baked` prints and those read `now` (names in
    order; per name its first difference: where, what, shape); `shapes` False:
    shapes not compared (the two reads evaluated meshes differently: the viewport's
    modifier levels against the render's). An object `AWAY` from the light on both
    sides (or on the one side it is on) is no change: it touched no path of the light
    when baked and touches none now."""
    out = []
    for name in differing(baked, now):
        a, b = baked.get(name), now.get(name)
        if all(x is None or x[0] == AWAY for x in (a, b)):
            continue  # away from the light then and now
        if a is None:
            out.append(Change(name, "added", b[0]))
            continue
        if b is None:
            out.append(Change(name, "removed", a[0]))
            continue
        n = PART_HEX
        where, what, shape = (slice(1 + k * n, 1 + (k + 1) * n) for k in range(3))
        if a[where] != b[where]:
            out.append(Change(name, "moved", a[0]))
        elif a[what] != b[what] or a[0].upper() != b[0].upper():
            out.append(Change(name, "changed", a[0]))
        elif shapes and a[shape] != b[shape]:
            out.append(Change(name, "shape", a[0]))
    return out


def change_words(c: Change) -> str:
    """One change in words: "Marble moved", "Lamp's light settings changed"."""
    if c.kind == OTHER:
        return f"{c.name} changed"
    if c.what == "moved":
        return f"{c.name} moved"
    if c.what == "added":
        return f"{c.name} is new (or shown)"
    if c.what == "removed":
        return f"{c.name} is gone (or hidden)"
    if c.what == "shape":
        return f"{c.name}'s mesh changed"
    if c.kind == LIGHT:
        return f"{c.name}'s light settings changed"
    return f"{c.name}'s material or lens settings changed"


def changes_text(found: list[Change], named: int = NAMED) -> str:
    """The first `named` changes in words, and how many more."""
    words = [change_words(c) for c in found[:named]]
    more = len(found) - len(words)
    if more > 0:
        words.append(f"{more} more change{'s' if more != 1 else ''}")
    return ", ".join(words)


#: The panel's line under Live Update while a bake exists.
LIVE_UPDATE_WAITS = (
    "Live update is off while a bake exists: its keys drive the lens lights "
    "(Clear or Generate to follow the scene live, Bake again to update the bake)"
)


def stale_text(first: int, last: int, frame: int, found: list[Change]) -> str:
    """The words: "The bake (frames 1–10) is out of date at frame 5: Marble moved since it was
    baked; Bake again"."""
    return (
        f"The bake (frames {first}–{last}) is out of date at frame {frame}: "
        f"{changes_text(found)} since it was baked; Bake again"
    )


@dataclass
class BakeInputs:
    """The prints of a bake's frames ``first``–``last``: per name a list of runs
    (first frame, print; "" for frames where the read did not hold it). ``render``:
    the frames were read as the render evaluates them (a probe render, or the
    viewport's depsgraph where nothing renders differently)."""

    first: int
    last: int
    render: bool = True
    runs: dict = field(default_factory=dict)

    @classmethod
    def of_frames(cls, frames, prints, render: bool = True) -> BakeInputs:
        """From consecutive `frames` and their `frame_prints` dicts."""
        frames = [int(f) for f in frames]
        out = cls(frames[0], frames[-1], bool(render))
        names = sorted({n for p in prints for n in p})
        for name in names:
            runs, last = [], None
            for f, p in zip(frames, prints, strict=True):
                x = p.get(name, "")
                if x != last:
                    runs.append([f, x])
                    last = x
            out.runs[name] = runs
        return out

    def covers(self, frame: int) -> bool:
        return self.first <= int(frame) <= self.last

    def at(self, frame: int) -> dict[str, str]:
        """The prints of `frame` (within the range)."""
        out = {}
        for name, runs in self.runs.items():
            x = ""
            for f, p in runs:
                if f > frame:
                    break
                x = p
            if x:
                out[name] = x
        return out

    def to_text(self) -> str:
        return json.dumps(
            dict(v=VERSION, first=self.first, last=self.last, render=self.render, runs=self.runs),
            separators=(",", ":"),
        )

    @classmethod
    def from_text(cls, text: str) -> BakeInputs | None:
        """None for an empty text, or one of another version (an older extension's)."""
        if not text:
            return None
        try:
            d = json.loads(text)
        except ValueError:
            return None
        if not isinstance(d, dict) or d.get("v") != VERSION:
            return None
        return cls(int(d["first"]), int(d["last"]), bool(d["render"]), dict(d["runs"]))
