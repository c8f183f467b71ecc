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

from ..scene.light_props import LightRecord

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
#: Kinds of entry (the print's first character).
LIGHT, SURFACE, OTHER = "L", "S", "X"
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


def frame_prints(inputs, extra: dict | None = None) -> dict[str, str]:
    """Per top object of `inputs` (`core.scene.assembly.ReadInputs`) its print "K
    where what shape" (K: `LIGHT`, `SURFACE` or `OTHER`; each part `PART_HEX` hex
    digits), and per entry of `extra` (name → plain data, e.g. the settings) an
    `OTHER` print of its value."""
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
    zero = "0" * PART_HEX
    for name, value in (extra or {}).items():
        out[name] = OTHER + zero + _digest(canonical(value)) + zero
    return out


@dataclass
class Change:
    name: str
    what: str  # "moved", "changed", "shape", "added", "removed"
    kind: str = SURFACE


def changes(baked: dict, now: dict, shapes: bool = True) -> list[Change]:
    """What differs between a frame's `baked` prints and those read `now` (names in
    order; per name its first difference: where, what, shape); `shapes` False:
    shapes not compared (the two reads evaluated meshes differently: the viewport's
    modifier levels against the render's)."""
    out = []
    for name in sorted(set(baked) | set(now)):
        a, b = baked.get(name), now.get(name)
        if a == b:
            continue
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
        elif a[what] != b[what] or a[0] != b[0]:
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
