"""Reader and writer of the thesis' `.bi` scene files (SPEC section 8).

A file is plain UTF-8 text (a byte-order mark is allowed), one record a line: a
key, then numbers separated by blanks. Lines end with LF, CRLF or a lone CR (an
old Mac line break): universal newlines, as Python's `open()` reads text, so a
line number in a message is the one an editor shows. Records, in this order:

    V w h                  viewport size: positive integers
    C x y z                camera position
    A x y z                camera target (must differ from the position)
    U x y z                camera up vector (must not be zero)
    B h v                  opening angles in degrees, each in (0, 180)
    L n                    number of lights, then n times:
        C r g b            light colour
        P x y z            light position
        I b                brightness (>= 0)
    O n                    number of objects, then n times:
        T 0                object type: 0 sphere (1, polyhedron, is refused)
        C x y z            sphere centre
        R r                radius (> 0)
        S                  surface block follows: the seven records
        #C r g b  #A ka  #D kd  #S ks  #T kt  #E exponent  #N ior

Rules chosen where SPEC section 8 is silent:

- Header, light and object records come in exactly the order above (the key `C`
  means three different things, so only the position can tell them apart).
- The seven `#` records of a surface come each exactly once, in any order, right
  after `S`; the block ends at the first line whose key does not start with `#`.
  A missing one is reported on the `S` line, a duplicate on its second line.
- Comments are `/* ... */`, C style (not nested): before, between or after
  records, and they may span lines. A comment separates tokens like a blank.
  An unterminated comment is reported on the line where it starts.
- Keys are case-sensitive. Counts and the viewport size are integers written
  without a decimal point; every other value is a decimal number (no nan, inf).
- Ranges: colours, brightness, ka, kd, ks and the exponent >= 0; kt in [0, 1];
  radius and ior > 0. An ior <= 1 or kt = 0 is a legal (non-lens) sphere.
- Colour scale, decided per file: if any colour component in the file (light or
  surface) is greater than 1, the whole file is in 0-255 and every colour is
  divided by 255 (`Scene.color_scale = 255.0`); otherwise it is in 0-1
  (`color_scale = 1.0`). The division is done exactly on the decimal text, so
  writing multiplies back to the very same numbers.
- The format has no names and no light radius: `Sphere.name`/`Light.name` are
  left "" and `Light.radius` 0 on read; the writer does not store them.

Writing then reading gives an equal `Scene` (floats are written as the shortest
text that reads back to the same double). The writer keeps `scene.color_scale`
unless the file would read back in the other scale (0-255 colours all <= 1, or
0-1 colours above 1); then it switches scale and only `color_scale` differs.

Errors: `BiFormatError` (a `ValueError`) is the only exception the reader lets
out, whatever the input; its text is "FILE:LINE: what was expected". A record
missing at the end of the file is reported on the file's last line.
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Callable
from dataclasses import dataclass
from decimal import Context, Decimal, localcontext
from fractions import Fraction
from typing import Union

from ..scene.model import Camera, Light, Scene, Sphere, Surface

__all__ = ["BiFormatError", "read_bi", "read_bi_arrays", "parse_bi", "write_bi", "format_bi"]

PathLike = Union[str, "os.PathLike[str]"]


class BiFormatError(ValueError):
    """A `.bi` file that cannot be read: `str(e)` is "FILE:LINE: message"."""

    def __init__(self, path: str, line: int | None, message: str):
        self.path = path
        self.line = line
        self.message = message
        where = f"{path}:{line}" if line is not None else f"{path}"
        super().__init__(f"{where}: {message}")


# --------------------------------------------------------------------------- #
# Record descriptions: shared by the reader's messages and the writer's checks.

# A check is (predicate, text shown in the message), e.g. (> 0, "> 0").
Check = tuple[Callable[[float], bool], str]
ANY: Check | None = None
NON_NEGATIVE: Check = (lambda v: v >= 0.0, ">= 0")
POSITIVE: Check = (lambda v: v > 0.0, "> 0")
UNIT: Check = (lambda v: 0.0 <= v <= 1.0, "in [0, 1]")
ANGLE: Check = (lambda v: 0.0 < v < 180.0, "in (0, 180)")


@dataclass(frozen=True)
class Rec:
    key: str
    args: tuple[str, ...]  # names of the values, shown as <name>
    what: str  # what the record means, for messages
    check: Check | None = ANY

    @property
    def usage(self) -> str:
        return " ".join([self.key] + [f"<{a}>" for a in self.args])


XYZ = ("x", "y", "z")
RGB = ("r", "g", "b")

VIEWPORT = Rec("V", ("width", "height"), "viewport size in pixels", POSITIVE)
CAM_POS = Rec("C", XYZ, "camera position")
CAM_TARGET = Rec("A", XYZ, "camera target point")
CAM_UP = Rec("U", XYZ, "camera up vector")
CAM_FOV = Rec("B", ("horizontal", "vertical"), "camera opening angles in degrees", ANGLE)
N_LIGHTS = Rec("L", ("count",), "number of lights", NON_NEGATIVE)
LIGHT_COLOR = Rec("C", RGB, "light colour", NON_NEGATIVE)
LIGHT_POS = Rec("P", XYZ, "light position")
LIGHT_BRIGHT = Rec("I", ("brightness",), "light brightness", NON_NEGATIVE)
N_OBJECTS = Rec("O", ("count",), "number of objects", NON_NEGATIVE)
OBJ_TYPE = Rec("T", ("type",), "object type: 0 sphere")
SPH_CENTER = Rec("C", XYZ, "sphere centre")
SPH_RADIUS = Rec("R", ("radius",), "sphere radius", POSITIVE)
SURFACE = Rec("S", (), "surface definition follows")

# Surface records in the order they are written; each maps to a Surface field.
SURFACE_RECS = {
    "#C": (Rec("#C", RGB, "surface colour", NON_NEGATIVE), "color"),
    "#A": (Rec("#A", ("ka",), "ambient coefficient", NON_NEGATIVE), "ambient"),
    "#D": (Rec("#D", ("kd",), "diffuse coefficient", NON_NEGATIVE), "diffuse"),
    "#S": (Rec("#S", ("ks",), "specular coefficient", NON_NEGATIVE), "specular"),
    "#T": (Rec("#T", ("kt",), "transmission coefficient", UNIT), "transmission"),
    "#E": (Rec("#E", ("exponent",), "Phong exponent", NON_NEGATIVE), "exponent"),
    "#N": (Rec("#N", ("n",), "index of refraction", POSITIVE), "ior"),
}

# Strict ASCII number syntax: float() alone would also take "nan", "1_0", "١".
# Written so that no digit can match two ways (no quadratic backtracking).
_FLOAT_RE = re.compile(r"[+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?", re.ASCII)
_INT_RE = re.compile(r"[+-]?\d{1,30}", re.ASCII)


# --------------------------------------------------------------------------- #
# Reading


@dataclass
class _Line:
    number: int
    tokens: list[str]


def _strip_comments(text: str, path: str) -> str:
    """Replace every /* ... */ by a blank, keeping its newlines (line numbers)."""
    pieces = text.split("/*")
    if len(pieces) == 1:
        return text
    # The common case, comments within one line: piece k > 0 follows a "/*" and
    # its first "*/" ends that comment (the loop below finds the same ends).
    kept = [pieces[0]]
    for piece in pieces[1:]:
        end = piece.find("*/")
        if end < 0 or "\n" in piece[:end]:
            break
        kept.append(piece[end + 2 :])
    else:
        return " ".join(kept)
    parts = []
    pos = 0
    while True:
        start = text.find("/*", pos)
        if start < 0:
            parts.append(text[pos:])
            return "".join(parts)
        end = text.find("*/", start + 2)
        if end < 0:
            line = text.count("\n", 0, start) + 1
            raise BiFormatError(path, line, "unterminated comment: '/*' without a closing '*/'")
        parts.append(text[pos:start])
        parts.append(" " + "\n" * text.count("\n", start, end))
        pos = end + 2


def _show(text: str, limit: int = 40) -> str:
    """Text of the offending line for a message: one line, printable, short."""
    if len(text) > limit:
        text = text[:limit] + "..."
    return "".join(
        c if c.isprintable() else c.encode("unicode_escape").decode("ascii") for c in text
    )


class _Reader:
    """Walks the records of one file; every error names the current line."""

    def __init__(self, text: str, path: str):
        self.path = path
        text = text.replace("\r\n", "\n").replace("\r", "\n")
        raw_lines = text.split("\n")
        if raw_lines and raw_lines[-1] == "":
            raw_lines.pop()  # a final newline ends the last line
        self.last_line = max(1, len(raw_lines))  # where "missing at end" is reported
        self.line_no = 1  # line of the record being read
        # Records are split off lazily (`peek`): the spheres of a large file are
        # read in bulk (`_bulk_spheres`) without a Python object per line.
        self.lines = _strip_comments("\n".join(raw_lines), path).split("\n")
        self.pos = 0  # index into `lines` of the next line
        self.next: _Line | None = None  # the record at `pos`, once split
        self.colors: list[tuple[list[str], Callable[[tuple], None]]] = []

    # -- errors ----------------------------------------------------------------
    def error(self, message: str, line: int | None = None) -> BiFormatError:
        return BiFormatError(self.path, self.line_no if line is None else line, message)

    # -- records ---------------------------------------------------------------
    def peek(self) -> _Line | None:
        if self.next is None:
            while self.pos < len(self.lines):
                tokens = self.lines[self.pos].split()
                if tokens:
                    self.next = _Line(self.pos + 1, tokens)
                    break
                self.pos += 1
        return self.next

    def take(self, rec: Rec, what: str = "") -> list[str]:
        """The value tokens of the next record, which must be `rec`; `what`
        replaces its meaning in a message (first record of light 2 of 3...)."""
        expected = f"expected '{rec.usage}' ({what or rec.what})"
        line = self.peek()
        if line is None:
            self.line_no = self.last_line
            raise self.error(f"{expected}, got end of file")
        self.pos += 1
        self.next = None
        self.line_no = line.number
        if line.tokens[0] != rec.key or len(line.tokens) != 1 + len(rec.args):
            raise self.error(f"{expected}, got '{_show(' '.join(line.tokens))}'")
        return line.tokens[1:]

    # -- values ----------------------------------------------------------------
    def number(self, rec: Rec, name: str, token: str) -> float:
        if not _FLOAT_RE.fullmatch(token):
            raise self.error(
                f"expected a number for <{name}> in '{rec.usage}' "
                f"({rec.what}), got '{_show(token)}'"
            )
        value = float(token)
        if not math.isfinite(value):
            raise self.error(
                f"expected a finite number for <{name}> ({rec.what}), got '{_show(token)}'"
            )
        self.check(rec, name, token, value)
        return value

    def integer(self, rec: Rec, name: str, token: str) -> int:
        if not _INT_RE.fullmatch(token):
            raise self.error(
                f"expected an integer for <{name}> in '{rec.usage}' "
                f"({rec.what}), got '{_show(token)}'"
            )
        value = int(token)
        self.check(rec, name, token, value)
        return value

    def check(self, rec: Rec, name: str, token: str, value: float) -> None:
        if rec.check is not None and not rec.check[0](value):
            raise self.error(f"expected <{name}> {rec.check[1]} ({rec.what}), got '{_show(token)}'")

    def floats(self, rec: Rec) -> tuple[float, ...]:
        return tuple(self.number(rec, n, t) for n, t in zip(rec.args, self.take(rec), strict=False))

    def ints(self, rec: Rec) -> tuple[int, ...]:
        return tuple(
            self.integer(rec, n, t) for n, t in zip(rec.args, self.take(rec), strict=False)
        )

    def color(self, rec: Rec, store: Callable[[tuple], None], what: str = "") -> None:
        """Check a colour now; convert it once the whole file's scale is known."""
        tokens = self.take(rec, what)
        for name, token in zip(rec.args, tokens, strict=False):
            self.number(rec, name, token)
        self.colors.append((tokens, store))

    # -- blocks ----------------------------------------------------------------
    def head(self) -> tuple[int, int, Camera, list[Light], int]:
        """The records before the objects: viewport, camera, lights, object count."""
        width, height = self.ints(VIEWPORT)
        camera = self.camera()
        (n_lights,) = self.ints(N_LIGHTS)
        # No list is built from a count up front: "L 999999999" fails at the
        # first missing light, naming how many the count announced.
        lights = []
        while len(lights) < n_lights:
            lights.append(self.light(len(lights) + 1, n_lights))
        (n_objects,) = self.ints(N_OBJECTS)
        return width, height, camera, lights, n_objects

    def scene(self) -> Scene:
        width, height, camera, lights, n_objects = self.head()
        objects = _bulk_spheres(self, n_objects) or []
        while len(objects) < n_objects:
            objects.append(self.sphere(len(objects) + 1, n_objects))
        extra = self.peek()
        if extra is not None:
            self.line_no = extra.number
            raise self.error(
                f"expected end of file after {n_objects} object(s) "
                f"(O {n_objects}), got '{_show(' '.join(extra.tokens))}'"
            )
        scale = self.color_scale()
        for tokens, store in self.colors:
            if isinstance(tokens, _BulkColors):
                store(tokens.convert(scale))
            else:
                store(tuple(_color_from_text(t, scale) for t in tokens))
        return Scene(
            width=width,
            height=height,
            camera=camera,
            lights=lights,
            objects=objects,
            color_scale=scale,
        )

    def camera(self) -> Camera:
        position = self.floats(CAM_POS)
        target = self.floats(CAM_TARGET)
        if target == position:
            raise self.error("expected a camera target different from the camera position")
        up = self.floats(CAM_UP)
        if up == (0.0, 0.0, 0.0):
            raise self.error("expected a non-zero camera up vector")
        fov = self.floats(CAM_FOV)
        return Camera(position=position, target=target, up=up, fov_deg=fov)

    def light(self, index: int, count: int) -> Light:
        light = Light(position=(0.0, 0.0, 0.0))
        self.color(
            LIGHT_COLOR, lambda c: setattr(light, "color", c), f"colour of light {index} of {count}"
        )
        light.position = self.floats(LIGHT_POS)
        (light.brightness,) = self.floats(LIGHT_BRIGHT)
        return light

    def sphere(self, index: int, count: int) -> Sphere:
        tokens = self.take(OBJ_TYPE, f"type of object {index} of {count}: 0 sphere")
        if tokens[0] == "1":
            raise self.error("polyhedron objects (T 1) are not supported; only spheres (T 0)")
        if tokens[0] != "0":
            raise self.error(f"expected 'T 0' ({OBJ_TYPE.what}), got 'T {_show(tokens[0])}'")
        center = self.floats(SPH_CENTER)
        (radius,) = self.floats(SPH_RADIUS)
        self.take(SURFACE)
        return Sphere(center=center, radius=radius, surface=self.surface(index))

    def surface(self, index: int) -> Surface:
        s_line = self.line_no
        surface = Surface()
        seen: dict[str, int] = {}
        while (line := self.peek()) is not None and line.tokens[0].startswith("#"):
            key = line.tokens[0]
            self.line_no = line.number
            if key not in SURFACE_RECS:
                raise self.error(
                    f"expected one of {' '.join(SURFACE_RECS)} (surface record), "
                    f"got '{_show(' '.join(line.tokens))}'"
                )
            if key in seen:
                raise self.error(
                    f"duplicate '{key}' in the surface of object {index} "
                    f"(first at line {seen[key]})"
                )
            seen[key] = line.number
            rec, attr = SURFACE_RECS[key]
            if key == "#C":
                self.color(rec, lambda c: setattr(surface, "color", c))
            else:
                (value,) = self.floats(rec)
                setattr(surface, attr, value)
        missing = [k for k in SURFACE_RECS if k not in seen]
        if missing:
            rec = SURFACE_RECS[missing[0]][0]
            raise self.error(
                f"the surface of object {index} is missing '{rec.usage}' ({rec.what})", line=s_line
            )
        return surface

    def color_scale(self) -> float:
        above_one = any(float(t) > 1.0 for tokens, _ in self.colors for t in tokens)
        return 255.0 if above_one else 1.0


# The bulk path for the spheres: when the remaining tokens are exactly `count`
# spheres in the written layout (keys where the layout puts them, the surface
# records in the written order, plain numbers elsewhere, each line starting with
# a key), they are converted and range-checked as arrays. Anything else, and
# any value out of range, falls back to the record by record reader, which
# names the line: errors are unchanged.
_SPHERE_KEYS = (
    "T",
    "0",
    "C",
    None,
    None,
    None,
    "R",
    None,
    "S",
    "#C",
    None,
    None,
    None,
    "#A",
    None,
    "#D",
    None,
    "#S",
    None,
    "#T",
    None,
    "#E",
    None,
    "#N",
    None,
)
_SPHERE_TOKENS = len(_SPHERE_KEYS)
_KEY_COLUMNS = [k for k, key in enumerate(_SPHERE_KEYS) if key is not None]
_SPHERE_NUMBERS = [k for k, key in enumerate(_SPHERE_KEYS) if key is None]
#: A line whose first token starts like a number continues a record: not the layout.
_LINE_STARTS_WITH_NUMBER = re.compile(r"\n[^\S\n]*[-+.0-9]")  # searched in "\n" + block
#: Numbers never start with a key's first character: such a token after a blank is a
#: key after another token (or an indented key: left to the record reader too).
_KEY_INSIDE_LINE = re.compile(r"[^\S\n][TCRS#]")
#: Within these characters, float() accepts exactly what _FLOAT_RE does.
_NOT_NUMBER_CHAR = re.compile(r"[^0-9.eE+\-\n]")


def _spheres_in_range(v, radius, color, ka, kd, ks, kt, ex, ior) -> bool:
    """Whether every sphere column of a fast path is finite and within the grammar's
    ranges (anything else goes to the record reader, which names the line)."""
    import numpy as np

    return bool(
        np.all(np.isfinite(v))
        and np.all(radius > 0)
        and np.all(color >= 0)
        and np.all(ka >= 0)
        and np.all(kd >= 0)
        and np.all(ks >= 0)
        and np.all((kt >= 0) & (kt <= 1))
        and np.all(ex >= 0)
        and np.all(ior > 0)
    )


def _bulk_spheres(reader: _Reader, count: int) -> list[Sphere] | None:
    """The `count` spheres that end the file, read at once, or None (then the
    record by record reader goes on from the same place)."""
    if count < 64:  # not worth it: the plain path is as fast
        return None
    block = "\n".join(reader.lines[reader.pos :])
    tokens = block.split()
    if len(tokens) != _SPHERE_TOKENS * count or _LINE_STARTS_WITH_NUMBER.search("\n" + block):
        return None
    # Column k of the layout is tokens[k::25]: list slices, compared and converted
    # in C (no per-token Python code).
    for k in _KEY_COLUMNS:
        if tokens[k::_SPHERE_TOKENS] != [_SPHERE_KEYS[k]] * count:
            return None
    # No line starts with a number and no key follows a token on its line: one record a line.
    if _KEY_INSIDE_LINE.search(block):
        return None
    columns = [tokens[k::_SPHERE_TOKENS] for k in _SPHERE_NUMBERS]
    numbers = [t for column in columns for t in column]
    if _NOT_NUMBER_CHAR.search("\n".join(numbers)):
        return None
    # numpy only here: the reader needs none for small files.
    import numpy as np

    try:
        with np.errstate(all="ignore"):
            v = np.array(list(map(float, numbers)), dtype=float).reshape(-1, count).T
    except ValueError:
        return None
    center, radius, color = v[:, 0:3], v[:, 3], v[:, 4:7]
    ka, kd, ks, kt, ex, ior = v[:, 7], v[:, 8], v[:, 9], v[:, 10], v[:, 11], v[:, 12]
    if not _spheres_in_range(v, radius, color, ka, kd, ks, kt, ex, ior):
        return None
    reader.pos, reader.next = len(reader.lines), None
    spheres = [
        Sphere(
            center=(x, y, z),
            radius=r,
            surface=Surface(ambient=a, diffuse=d, specular=s, transmission=t, exponent=e, ior=n),
        )
        for x, y, z, r, a, d, s, t, e, n in zip(
            *center.T.tolist(),
            radius.tolist(),
            ka.tolist(),
            kd.tolist(),
            ks.tolist(),
            kt.tolist(),
            ex.tolist(),
            ior.tolist(),
            strict=True,
        )
    ]
    # Colours wait for the file's scale like the others; one entry for all of them.
    color_text = columns[4:7]

    def store(scaled):
        for sphere, c in zip(spheres, scaled, strict=True):
            sphere.surface.color = c

    reader.colors.append((_BulkColors(color_text, color), store))
    return spheres


class _BulkColors:
    """The colour tokens of the bulk spheres (three columns of text, their values),
    as `_Reader.colors` holds them: iterating gives a token above 1 if there is one
    (all `color_scale` asks); `convert` works once per distinct token."""

    def __init__(self, text, values):
        self.text, self.values = text, values

    def __iter__(self):  # what `_Reader.color_scale` looks at
        rows, cols = (self.values > 1.0).nonzero()
        return iter([self.text[int(cols[0])][int(rows[0])]] if rows.size else [])

    def convert(self, scale: float) -> list[tuple[float, float, float]]:
        if scale == 1.0:
            return list(map(tuple, self.values.tolist()))
        memo: dict[str, float] = {}
        r, g, b = (
            [
                memo[t] if t in memo else memo.setdefault(t, _color_from_text(t, scale))
                for t in column
            ]
            for column in self.text
        )
        return list(zip(r, g, b, strict=True))


def _color_from_text(token: str, scale: float) -> float:
    """A colour component in 0-1. Dividing the exact decimal by 255 and rounding
    once makes the writer's text for `value * 255` read back bit for bit."""
    value = float(token)
    if scale == 1.0 or value == 0.0:  # also avoids Fraction("1e-999999999")
        return value
    # Via Decimal: Fraction("1.000...") would hit int()'s 4300-digit limit.
    return float(Fraction(Decimal(token)) / 255)


def parse_bi(text: str, path: str = "<string>") -> Scene:
    """Parse the text of a `.bi` file; errors name `path` and the line."""
    reader = None
    try:
        reader = _Reader(text, path)
        return reader.scene()
    except BiFormatError:
        raise
    except Exception as exc:  # a safety net: no other exception may escape
        line = reader.line_no if reader is not None else None
        raise BiFormatError(
            path, line, f"cannot read this line ({type(exc).__name__}: {_show(str(exc), 80)})"
        ) from exc


def _decode(data: bytes, path: str) -> str:
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        head = data[: exc.start]  # LF, CRLF and a lone CR each end a line
        line = head.count(b"\n") + head.count(b"\r") - head.count(b"\r\n") + 1
        raise BiFormatError(
            path, line, "expected UTF-8 text (the file has bytes that are not UTF-8)"
        ) from exc


def _read_bytes(path: PathLike) -> tuple[bytes, str]:
    """The file's bytes and its name; a file that cannot be opened is a BiFormatError."""
    name = os.fspath(path)
    try:
        with open(name, "rb") as f:
            return f.read(), name
    except OSError as exc:
        raise BiFormatError(name, None, f"cannot read the file: {exc.strerror or exc}") from exc


def _read_text(path: PathLike) -> tuple[str, str]:
    data, name = _read_bytes(path)
    return _decode(data, name), name


def read_bi(path: PathLike) -> Scene:
    """Read a `.bi` file. A file that cannot be opened is a BiFormatError too."""
    text, name = _read_text(path)
    return parse_bi(text, name)


def read_bi_arrays(path: PathLike):
    """What phase 1 needs of a `.bi` file (`phase1.SceneArrays`): the very numbers
    of `SceneArrays.from_scene(read_bi(path))`, read as columns without a Python
    object per sphere when the spheres are written one record a line (as
    `format_bi` writes them): numpy on the file's bytes (`_arrays_from_bytes`),
    else on its text (`_arrays_in_layout`). Anything else, and every error, goes
    through `read_bi`'s record reader: the same scene, the same messages."""
    data, name = _read_bytes(path)
    arrays = _arrays_or_none(_arrays_from_bytes, data, name)
    return arrays if arrays is not None else _parse_arrays_text(_decode(data, name), name)


def parse_bi_arrays(text: str, path: str = "<string>"):
    """`read_bi_arrays` on the text of a file."""
    arrays = None
    if text.isascii():
        arrays = _arrays_or_none(_arrays_from_bytes, text.encode("ascii"), path)
    return arrays if arrays is not None else _parse_arrays_text(text, path)


def _arrays_or_none(fast, data, path):
    """A fast path's arrays, or None where it gives up (or trips on unusual text:
    the slower paths then decide, and name the line)."""
    try:
        return fast(data, path)
    except Exception:
        return None


def _parse_arrays_text(text: str, path: str):
    """The text paths: spheres one record a line as lists of tokens, else the record
    reader."""
    arrays = _arrays_or_none(_arrays_in_layout, text, path)
    if arrays is None:
        from ..scene.arrays import SceneArrays

        arrays = SceneArrays.from_scene(parse_bi(text, path))
    return arrays


#: The objects' count record: the only key "O" (none of the records before it has it).
_OBJECTS_LINE = re.compile(r"^[^\S\n]*O(?:[^\S\n][^\n]*)?$", re.MULTILINE)
_OBJECTS_LINE_BYTES = re.compile(rb"^[^\S\n]*O(?:[^\S\n][^\n]*)?$", re.MULTILINE)
#: First character of each record of a sphere, in the written order.
_SPHERE_LINE_STARTS = "TCRS" + "#" * 7
_SPHERE_LINES = len(_SPHERE_LINE_STARTS)


def _arrays_in_layout(text: str, path: str):
    """The `SceneArrays` of a file whose spheres are one record a line, or None.

    The records before the objects go through the record reader (a few lines).
    The spheres' lines: one per record (each non-blank line starts with the key
    of the record due there, the keys stand where the layout puts them: then no
    line holds two records or a part of one), values checked as the reader does
    (the number syntax, finite, the ranges), converted per column."""
    import numpy as np

    if "\r" in text:
        text = text.replace("\r\n", "\n").replace("\r", "\n")
    text = _strip_comments(text, path)
    m = _OBJECTS_LINE.search(text)
    if m is None:
        return None
    head = _Reader(text[: m.end()], path)
    _, _, _, lights, count = head.head()
    if head.peek() is not None:
        return None
    lines = list(filter(None, map(str.strip, text[m.end() :].split("\n"))))
    if len(lines) != _SPHERE_LINES * count:
        return None
    if "".join([line[0] for line in lines]) != _SPHERE_LINE_STARTS * count:
        return None
    # Each line starts with a key's first character, no number does (checked
    # below), and there are as many lines as keys: each line is one record.
    tokens = " ".join(lines).split()
    if len(tokens) != _SPHERE_TOKENS * count:
        return None
    for k in _KEY_COLUMNS:
        if tokens[k::_SPHERE_TOKENS].count(_SPHERE_KEYS[k]) != count:
            return None
    v = np.empty((len(_SPHERE_NUMBERS), count))
    for row, k in enumerate(_SPHERE_NUMBERS):
        if not _number_column(tokens[k::_SPHERE_TOKENS], v[row]):
            return None
    return _scene_arrays(lights, [tokens for tokens, _ in head.colors], v)


def _scene_arrays(lights: list[Light], light_colors: list[list[str]], v):
    """`SceneArrays` of the head's lights (their colours as tokens: the scale waits
    for the spheres') and the sphere columns `v` (`_SPHERE_NUMBERS`' values, one row
    each), or None if a sphere value is out of the grammar's ranges (the record
    reader then names its line)."""
    import numpy as np

    from ..scene.arrays import SceneArrays

    center, radius, color = v[0:3].T, v[3], v[4:7]
    ka, kd, ks, kt, ex, ior = v[7], v[8], v[9], v[10], v[11], v[12]
    if not _spheres_in_range(v, radius, color, ka, kd, ks, kt, ex, ior):
        return None
    above_one = bool(np.any(color > 1.0)) or any(float(t) > 1.0 for c in light_colors for t in c)
    scale = 255.0 if above_one else 1.0
    n = len(lights)
    return SceneArrays(
        light_position=np.array([lt.position for lt in lights], dtype=float).reshape(n, 3),
        light_brightness=np.array([lt.brightness for lt in lights], dtype=float).reshape(n),
        light_color=np.array(
            [[_color_from_text(t, scale) for t in c] for c in light_colors], dtype=float
        ).reshape(n, 3),
        center=np.ascontiguousarray(center),
        radius=radius.copy(),
        ior=ior.copy(),
        kt=kt.copy(),
    )


# The bytes path: numpy over the file's bytes, no Python object per line or token.
# It takes a file whose spheres are one record a line in the written order (blanks,
# tabs, blank lines and comments anywhere) and gives up (None) on anything else.

_BLANK, _NEWLINE, _TAB = ord(" "), ord("\n"), ord("\t")
#: Bytes of the sphere block besides the keys' letters: blanks and the number syntax.
_NUMBER_BYTES = b"0123456789.eE+- \t\n"
#: What deleting `_NUMBER_BYTES` leaves of one sphere's keys ("T0CRS#C…" → "TCRS#C…").
_KEY_LETTERS = "".join(k for k in _SPHERE_KEYS if k).encode().translate(None, _NUMBER_BYTES)
#: Token indices (in a sphere's 25) that begin a record, hence a line.
_RECORD_STARTS = [k for k, key in enumerate(_SPHERE_KEYS) if key is not None and key != "0"]
#: Widest number token the bytes path gathers (longer ones: the text path).
_MAX_NUMBER_WIDTH = 64


def _arrays_from_bytes(data: bytes, path: str):
    """The `SceneArrays` of a file's bytes, or None (then the text paths decide).

    Comments are blanked in place (newlines kept: every token stays on its line);
    the head (the records before the objects) goes through the record reader. The
    sphere block is checked as a whole: deleting blanks and number bytes leaves
    exactly the keys' letters of `count` spheres in order; there are 25 tokens per
    sphere, the keys are whole tokens where the layout puts them, and a newline
    stands before each record and nowhere inside one. Then every other token is a
    number of ASCII digits, `.`, `e`, `E`, `+`, `-`, which `float` reads iff it
    matches the grammar (`_FLOAT_RE`); each column is converted by numpy's cast
    (the same correctly rounded double as `float`), a column of one repeated token
    once."""
    import numpy as np

    if data.startswith(b"\xef\xbb\xbf"):
        data = data[3:]
    if not data.isascii():
        data.decode("utf-8")  # bad UTF-8: the text path's message
        # UTF-8 in a comment is fine; anywhere else the text paths decide.
    if b"\r" in data:
        data = data.replace(b"\r\n", b"\n").replace(b"\r", b"\n")
    if b"/*" in data or b"*/" in data:
        blanked = _blank_comments(np.frombuffer(data, dtype=np.uint8))
        if blanked is None:
            return None
        data = blanked.tobytes()
    if not data.isascii():
        return None
    m = _OBJECTS_LINE_BYTES.search(data)
    if m is None:
        return None
    head = _Reader(data[: m.end()].decode("ascii"), path)
    _, _, _, lights, count = head.head()
    if head.peek() is not None:
        return None
    v = _sphere_columns(data[m.end() :], count)
    if v is None:
        return None
    return _scene_arrays(lights, [tokens for tokens, _ in head.colors], v)


def _blank_comments(a):
    """The bytes `a` with each /* … */ comment's bytes blanked, newlines kept (the
    record reader's rule: the first "/*", then the first "*/" after it), or None if
    comments are not simple (nested openings, a stray or missing end)."""
    import numpy as np

    from ..shared.ranges import concat_ranges

    slash = np.flatnonzero(a == ord("/"))
    opens = slash[slash + 1 < a.size]
    opens = opens[a[opens + 1] == ord("*")]
    closes = slash[slash > 0] - 1
    closes = closes[a[closes] == ord("*")]
    # "/*/": that '*' opens (or, inside a comment, closes: then it is given up below)
    closes = closes[(closes == 0) | (a[closes - 1] != ord("/"))]
    if opens.size != closes.size:
        return None
    # open < its close (not sharing the '*') < the next open (not sharing the '/')
    if np.any(closes < opens + 2) or np.any(opens[1:] < closes[:-1] + 2):
        return None
    inside = concat_ranges(opens, closes + 2 - opens)
    out = a.copy()
    out[inside[a[inside] != _NEWLINE]] = _BLANK
    return out


def _sphere_columns(block: bytes, count: int):
    """The `_SPHERE_NUMBERS` columns (rows of `count` values) of a sphere block in the
    written layout (see `_arrays_from_bytes`), or None."""
    import numpy as np

    n_tokens = _SPHERE_TOKENS * count
    if 2 * n_tokens > len(block):  # each token and the blank before it: a byte at least
        return None
    if block.translate(None, _NUMBER_BYTES) != _KEY_LETTERS * count:
        return None
    if count == 0:
        # Nothing but blanks may follow "O 0" (a stray number is the reader's error).
        return None if block.strip() else np.empty((len(_SPHERE_NUMBERS), 0))
    padded = np.frombuffer(block + bytes(_MAX_NUMBER_WIDTH), dtype=np.uint8)
    a = padded[: len(block)]
    blank = np.empty(a.size + 2, dtype=bool)
    blank[0] = blank[-1] = True
    np.equal(a, _BLANK, out=blank[1:-1])
    blank[1:-1] |= a == _NEWLINE
    blank[1:-1] |= a == _TAB
    edges = np.flatnonzero(blank[1:] != blank[:-1])
    if edges.size != 2 * n_tokens:
        return None
    start, end = edges[0::2], edges[1::2]
    # A newline in the gap before each record's first token, none before the others.
    # The gaps' first or last byte tells (a blank line, a blanked comment line, the
    # indentation of a key); the rest (trailing blanks) are counted.
    gap_start, gap_end = np.r_[0, end[:-1]], start
    nl = (a[gap_start] == _NEWLINE) | (a[gap_end - 1] == _NEWLINE)
    unsure = np.flatnonzero(~nl & (gap_end - gap_start > 2))
    if unsure.size:
        lines = np.flatnonzero(a == _NEWLINE)
        nl[unsure] = np.searchsorted(lines, gap_start[unsure]) < np.searchsorted(
            lines, gap_end[unsure]
        )
    want = np.zeros(_SPHERE_TOKENS, dtype=bool)
    want[_RECORD_STARTS] = True
    if np.any(nl.reshape(count, _SPHERE_TOKENS) != want):
        return None
    start = start.reshape(count, _SPHERE_TOKENS)
    length = end.reshape(count, _SPHERE_TOKENS) - start
    for k in _KEY_COLUMNS:
        key = _SPHERE_KEYS[k].encode()
        if np.any(length[:, k] != len(key)):
            return None
        if np.any(_windows(padded, start[:, k], len(key)) != np.frombuffer(key, np.uint8)):
            return None
    v = np.empty((len(_SPHERE_NUMBERS), count))
    for row, k in enumerate(_SPHERE_NUMBERS):
        if not _convert_column(padded, start[:, k], length[:, k], v[row]):
            return None
    return v


def _windows(padded, start, width):
    """padded[start[r] : start[r] + width] of every r, as rows (len(start), width):
    a sliding-window view indexed by row (no index made per byte)."""
    from numpy.lib.stride_tricks import as_strided

    view = as_strided(padded, shape=(padded.size - width + 1, width), strides=(1, 1))
    return view[start]


def _convert_column(padded, start, length, out) -> bool:
    """Convert the number tokens padded[start : start + length] into `out`; False if
    one is too long for the gather (`padded`: the block, then _MAX_NUMBER_WIDTH
    zero bytes)."""
    import numpy as np

    if not length.size:
        return True
    n0 = int(length[0])
    if np.all(length == n0):
        texts = _windows(padded, start, n0)
        if np.all(texts == texts[0]):  # one material for all: one value
            out[:] = float(texts[0].tobytes())
            return True
    width = int(length.max())
    if width > _MAX_NUMBER_WIDTH:
        return False
    chars = _windows(padded, start, width)
    chars[np.arange(width) >= length[:, None]] = 0  # numpy's bytes strings end there
    out[:] = chars.view(f"S{width}").ravel().astype(float)  # ValueError: not a number
    return True


def _number_column(tokens: list[str], out) -> bool:
    """Convert a column of number tokens into `out`; False if one is not a number.
    A column of few distinct tokens (a material shared by many spheres) converts
    each distinct token once."""
    # A column of distinct numbers (centres, radii) is told by its first tokens.
    if len(set(tokens[:64])) <= 16 and 4 * len(distinct := set(tokens)) <= len(tokens):
        memo = {}
        for t in distinct:
            if not _FLOAT_RE.fullmatch(t):
                return False
            memo[t] = float(t)
        if len(memo) == 1:  # one material for all: one value
            out[:] = memo.popitem()[1]
        else:
            out[:] = list(map(memo.__getitem__, tokens))
        return True
    if _NOT_NUMBER_CHAR.search("\n".join(tokens)):
        return False
    out[:] = list(map(float, tokens))  # ValueError for a malformed one: the caller falls back
    return True


# --------------------------------------------------------------------------- #
# Writing


def _float_text(value: float) -> str:
    """Shortest text that reads back to the same double; integral values short."""
    if value.is_integer() and abs(value) < 1e16:
        return str(int(value))
    return repr(value)


def _color_text(value: float, scale: float) -> str:
    """Text of a colour component that `_color_from_text` maps back to `value`."""
    if scale == 1.0 or value == 0.0:
        return _float_text(value)
    with localcontext(Context(prec=2000)):
        exact = Decimal(value) * 255  # exact: a double has < 800 digits
    # The exact product always works; look for the shortest decimal that does.
    for digits in range(1, 2000):
        candidate = Context(prec=digits).plus(exact)
        if float(Fraction(candidate) / 255) == value:
            break
    if candidate == candidate.to_integral_value() and abs(candidate) < 10**16:
        return str(int(candidate))
    return format(candidate, "g").replace("E", "e")


class _Writer:
    """Checks each value as the reader would, so a written file always reads."""

    def __init__(self):
        self.lines: list[str] = []
        self.where = ""

    def fail(self, rec: Rec, name: str, value) -> ValueError:
        cond = f" {rec.check[1]}" if rec.check is not None else ""
        return ValueError(
            f"cannot write {self.where}{rec.what}: expected <{name}> "
            f"a finite number{cond}, got {value!r}"
        )

    def value(self, rec: Rec, name: str, value) -> float:
        try:
            value = float(value)
        except (TypeError, ValueError):
            raise self.fail(rec, name, value) from None
        if not math.isfinite(value) or (rec.check and not rec.check[0](value)):
            raise self.fail(rec, name, value)
        return value

    def integer(self, rec: Rec, name: str, value) -> int:
        try:
            ok = not isinstance(value, bool) and int(value) == value
        except (TypeError, ValueError, OverflowError):
            ok = False
        if not ok or (rec.check and not rec.check[0](value)):
            raise ValueError(
                f"cannot write {self.where}{rec.what}: expected <{name}> "
                f"an integer{' ' + rec.check[1] if rec.check else ''}, "
                f"got {value!r}"
            )
        return int(value)

    def record(self, rec: Rec, values, comment: str = "") -> None:
        texts = [
            _float_text(self.value(rec, n, v))
            for n, v in zip(rec.args, self.sized(rec, values), strict=False)
        ]
        self.emit(rec, texts, comment)

    def int_record(self, rec: Rec, values, comment: str = "") -> None:
        texts = [
            str(self.integer(rec, n, v))
            for n, v in zip(rec.args, self.sized(rec, values), strict=False)
        ]
        self.emit(rec, texts, comment)

    def color(self, rec: Rec, values, scale: float) -> None:
        values = [
            self.value(rec, n, v) for n, v in zip(rec.args, self.sized(rec, values), strict=False)
        ]
        texts = [_color_text(v, scale) for v in values]
        for name, text, v in zip(rec.args, texts, values, strict=False):
            if not math.isfinite(float(text)):  # v * 255 beyond the largest double
                raise self.fail(rec, name, v)
        self.emit(rec, texts)

    def sized(self, rec: Rec, values) -> tuple:
        values = tuple(values)
        if len(values) != len(rec.args):
            raise ValueError(
                f"cannot write {self.where}{rec.what}: expected "
                f"{len(rec.args)} values, got {len(values)}"
            )
        return values

    def emit(self, rec: Rec, texts: list[str], comment: str = "") -> None:
        line = " ".join([rec.key] + texts)
        self.lines.append(f"{line:<24}/* {comment} */" if comment else line)


def _scene_colors(scene: Scene) -> list[float]:
    colors = [c for light in scene.lights for c in light.color]
    colors += [c for sphere in scene.objects for c in sphere.surface.color]
    return [float(c) for c in colors]


def _write_scale(scene: Scene) -> float:
    """The scale to write in: the scene's own, unless reading would not give it back."""
    try:
        colors = _scene_colors(scene)
    except (TypeError, ValueError):
        return 1.0  # the writer reports the value
    if any(not math.isfinite(c) for c in colors):
        return 1.0
    if any(c > 1.0 for c in colors):
        return 255.0  # only 0-255 can say "above 1"
    if scene.color_scale == 255.0 and any(float(_color_text(c, 255.0)) > 1.0 for c in colors):
        return 255.0
    return 1.0


def format_bi(scene: Scene) -> str:
    """The text of a `.bi` file for `scene`. Raises ValueError for a scene that
    the reader would refuse (non-finite numbers, radius <= 0, ...)."""
    scale = _write_scale(scene)
    w = _Writer()
    w.lines.append(f"/* Lens Lights scene; colours in 0-{255 if scale == 255.0 else 1} */")
    w.int_record(VIEWPORT, (scene.width, scene.height), "viewport width height")
    cam = scene.camera
    w.record(CAM_POS, cam.position, "camera position")
    w.record(CAM_TARGET, cam.target, "camera target")
    w.record(CAM_UP, cam.up, "camera up vector")
    w.record(CAM_FOV, cam.fov_deg, "opening angles h v (degrees)")
    w.lines.append("")
    w.int_record(N_LIGHTS, (len(scene.lights),), "number of lights")
    for index, light in enumerate(scene.lights, 1):
        w.where = f"light {index}: "
        w.lines += ["", f"/* light {index} */"]
        w.color(LIGHT_COLOR, light.color, scale)
        w.record(LIGHT_POS, light.position)
        w.record(LIGHT_BRIGHT, (light.brightness,))
    w.where = ""
    w.lines.append("")
    w.int_record(N_OBJECTS, (len(scene.objects),), "number of objects")
    for index, sphere in enumerate(scene.objects, 1):
        w.where = f"object {index}: "
        w.lines += ["", f"/* object {index}: sphere */"]
        w.lines.append("T 0")
        w.record(SPH_CENTER, sphere.center)
        w.record(SPH_RADIUS, (sphere.radius,))
        w.lines.append("S")
        for key, (rec, attr) in SURFACE_RECS.items():
            value = getattr(sphere.surface, attr)
            if key == "#C":
                w.color(rec, value, scale)
            else:
                w.record(rec, (value,))
    _check_camera(scene.camera)
    return "\n".join(w.lines) + "\n"


def _check_camera(cam: Camera) -> None:
    """The camera checks the reader makes beyond the single values."""
    if tuple(map(float, cam.target)) == tuple(map(float, cam.position)):
        raise ValueError("cannot write the camera: the target equals the position")
    if all(float(c) == 0.0 for c in cam.up):
        raise ValueError("cannot write the camera: the up vector is zero")


def write_bi(scene: Scene, path: PathLike) -> None:
    """Write `scene` to a `.bi` file (UTF-8, `\\n` line ends)."""
    text = format_bi(scene)
    with open(os.fspath(path), "w", encoding="utf-8", newline="\n") as f:
        f.write(text)
