"""`./lens-lights SUBCOMMAND …`: the project's command line (run by the launcher
with the pinned environment's python).

Subcommands:
  phase1 SCENE.bi [--json [--indent N]] [--model TIER]
                             secondary light sources of a `.bi` scene and the
                             Blender light of each for a lens-light tier
                             (thesis|physical|fitted|exact_profile; default
                             fitted: the most accurate tier that renders in both
                             EEVEE and Cycles)
  lint                       ruff check and ruff format --check (what CI runs first)
  test [PYTEST ARGS]         the whole test suite on Blender 5.2, then the Blender
                             tests on 4.5 (`--blender X.Y`: on that release only;
                             paths: those tests only)
  render SCENE -o OUT.png    render a .blend or .bi scene with lens lights
                             [--engine cycles|eevee] [--samples N] [--resolution WxH]
                             [--no-lens-lights | --compare]; OUT's extension picks
                             the format (.png .jpg/.jpeg .exr .tif/.tiff .webp);
                             [--frame N | --frames A-B] (OUT_####.png: the frame
                             number) [--bake BAKED.blend] (lens lights keyed over
                             the frames: renders without the extension)
  demo [--out DIR]           render the showcase scene without and with lens lights
  build [ARGS]               build the extension's zip (scripts/build_extension.py)
  bench NAME [ARGS]          a benchmark of bench/ (e.g. `bench scale`), report in reports/
  fuzz [--count N] [--seed S]
                             fuzz the .bi reader and `phase1` (100 000 inputs by default)
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import threading
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

EXIT_BAD_INPUT = 2


def _call(*args, **kwargs) -> int:
    """`subprocess.call`, imported only by the commands that run one."""
    import subprocess

    return subprocess.call(*args, **kwargs)


def _fail(message: str) -> int:
    print(f"lens-lights: {message}", file=sys.stderr)
    return EXIT_BAD_INPUT


# --------------------------------------------------------------------------- phase1


def _fmt_vec(v) -> str:
    return "(" + ", ".join(f"{x:.4g}" for x in v) + ")"


#: `--model` values (lower case) → tiers of `core.tiers`.
PHASE1_MODELS = ("thesis", "physical", "fitted", "exact_profile")
#: The default: the most accurate tier that renders in both EEVEE and Cycles
#: (reports/accuracy.md); EXACT_PROFILE is more accurate but Cycles only.
PHASE1_DEFAULT_MODEL = "fitted"


def blender_lights(scene, result, model: str) -> list:
    """The Blender light (`tiers.BlenderLight`) of each source of `result`
    for the tier `model`, as the add-on makes it for this scene once imported
    (`File › Import › Bitracer scene`): a light of brightness b is a point light
    of b × 10 000 W (`bi_conversions.watts_from_brightness`) with the file's
    colour, a sphere's transmission weight is its kt (clear: Base Color white),
    the scene's bounds are those of its lights and spheres."""
    import numpy as np

    from core.bi.conversions import watts_from_brightness
    from core.lens.glass import LensOptics
    from core.scene.primaries import PrimaryLight
    from core.tiers import make_blender_light

    pts = [np.asarray(lt.position, dtype=float) for lt in scene.lights]
    for o in scene.objects:
        c, r = np.asarray(o.center, dtype=float), abs(float(o.radius))
        pts += [c - r, c + r]
    bounds, size = None, 1.0
    if pts:
        lo, hi = np.min(pts, axis=0), np.max(pts, axis=0)
        if np.all(np.isfinite(lo)) and np.all(np.isfinite(hi)):
            bounds = (tuple(lo), tuple(hi))
            size = float(np.linalg.norm(hi - lo)) or 1.0
    out = []
    for s in result.sources:
        light = scene.lights[s.light]
        primary = PrimaryLight(
            power_w=watts_from_brightness(light.brightness),
            radius=float(light.radius),
            color=tuple(light.color),
        )
        optics = LensOptics(transmission_weight=float(scene.objects[s.lens].surface.transmission))
        out.append(
            make_blender_light(
                s, primary, model.upper(), optics=optics, scene_size=size, scene_bounds=bounds
            )
        )
    return out


def format_phase1_table(result, lights=None, model: str = "") -> str:
    """A readable report of phase 1: one row per source (with `lights`, a
    `tiers.LightTable` or a list of `BlenderLight`, the energy of its
    Blender light for the tier `model`), then the skipped pairs."""
    lines = [
        f"{len(result.sources)} secondary light source(s), "
        f"{len(result.skipped)} light × sphere pair(s) skipped",
        "",
    ]
    if result.sources:
        energy = f"{'energy W':>10} " if lights is not None else ""
        header = (
            f"{'light':>5} {'lens':>4}  {'kind':<10} {'position':<28} "
            f"{'spread°':>8} {'R_C':>8} {'intensity':>9} {energy} shadow"
        )
        if lights is not None:
            lines.insert(1, f"energy: Blender light power (W) with the {model.lower()} tier")
            energies = (
                lights.energy_w.tolist()
                if hasattr(lights, "energy_w")
                else [bl.energy_w for bl in lights]
            )
        lines += [header, "-" * len(header)]
        for k, s in enumerate(result.sources):
            rc = f"{s.cylinder_radius:.4g}" if s.cylinder_radius is not None else "-"
            shadow = (
                "full"
                if s.full
                else "non-full, blocked by " + ", ".join(f"sphere {k}" for k in s.shadow_list)
            )
            e = f"{energies[k]:>10.4g} " if lights is not None else ""
            lines.append(
                f"{s.light:>5} {s.lens:>4}  {s.kind:<10} "
                f"{_fmt_vec(s.position):<28} {s.spread_deg:>8.4g} {rc:>8} "
                f"{s.intensity:>9.4g} {e} {shadow}"
            )
    if result.skipped:
        lines += ["", "skipped:"]
        lines += [f"  light {k.light} × sphere {k.lens}: {k.reason}" for k in result.skipped]
    return "\n".join(lines)


def phase1_light_table(scene, result, model: str):
    """`blender_lights` for every source at once (`tiers.make_light_table`: columns,
    the same lights as the per-source makers)."""
    import numpy as np

    radius = np.array([float(lt.radius) for lt in scene.lights], dtype=float)
    return bi_scene_light_table(result._arrays, result.table, model, radius)


def bi_scene_light_table(arrays, table, model: str, light_radius=None):
    """`blender_lights` on columns: the lights of the sources `table` (a
    `phase1.SourceTable`) of a scene given as `arrays` (its `phase1.SceneArrays`),
    with the same conventions (point lights of b × 10 000 W, kt as transmission
    weight, the bounds of the lights and spheres, no receiver known)."""
    import numpy as np

    from core.bi.conversions import watts_from_brightness
    from core.tiers import Primaries, make_light_table

    j, i = table.light, table.lens
    radius = (
        np.zeros(len(arrays.light_brightness))
        if light_radius is None
        else np.asarray(light_radius, dtype=float)
    )
    primaries = Primaries(
        power_w=arrays.light_brightness[j] * watts_from_brightness(1.0),
        radius=radius[j],
        color=arrays.light_color[j],
        transmission_weight=arrays.kt[i],
    )
    r = np.abs(arrays.radius)[:, None]
    pts = np.concatenate([arrays.light_position, arrays.center - r, arrays.center + r])
    bounds, size = None, 1.0
    if pts.size:
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        if np.all(np.isfinite(lo)) and np.all(np.isfinite(hi)):
            bounds = (tuple(lo.tolist()), tuple(hi.tolist()))
            size = float(np.linalg.norm(hi - lo)) or 1.0
    return make_light_table(table, primaries, model.upper(), scene_size=size, scene_bounds=bounds)


def _split(flat: list, offsets: list) -> list[list]:
    return [flat[a:b] for a, b in zip(offsets[:-1], offsets[1:], strict=True)]


def _skip_reasons(result) -> list[tuple[int, int, str]]:
    """(light, lens, reason) of each skipped pair; a text made once per distinct
    (code, the numbers it names)."""
    from core.phase1 import point_lights as p1

    a, k = result._arrays, result.skip_table
    memo: dict = {}

    def reason(code, lens, other):
        key = (
            code,
            lens if code in (p1.INVALID_SPHERE_RADIUS, p1.INVALID_KT, p1.NOT_CONVERGING) else -1,
            other,
        )
        if key not in memo:
            memo[key] = p1.reason_text(
                code, float(a.radius[lens]), float(a.ior[lens]), float(a.kt[lens]), other
            )
        return memo[key]

    return [
        (j, i, reason(c, i, o))
        for j, i, c, o in zip(
            k.light.tolist(), k.lens.tolist(), k.code.tolist(), k.other.tolist(), strict=True
        )
    ]


def _floats(values) -> list:
    """`values.tolist()` with None (JSON's null) for each non-finite number."""
    import numpy as np

    v = np.asarray(values, dtype=float)
    bad = ~np.isfinite(v)
    if not bad.any():
        return v.tolist()
    v = v.astype(object)
    v[bad] = None
    return v.tolist()


def phase1_json_rows(result, lights):
    """The JSON of each source (with its Blender light) and of each skipped pair,
    made from the columns: every array becomes a list once; a non-finite number
    becomes None (null), as in the compact writer."""
    import numpy as np

    t = result.table
    col = t.kind == 2
    with np.errstate(divide="ignore", invalid="ignore"):
        image = np.where(col, np.nan, 1.0 / t.vergence)
        magnification = np.where(col, np.nan, -1.0 / (t.vergence * t.distance))

    def maybe(values, when):  # None where `when`
        return _floats(np.where(when, np.nan, values))

    bl = lights.json_columns()
    for k in ("energy_w", "spot_size_deg", "spot_blend", "radius"):
        bl[k] = _floats(getattr(lights, k))
    bl_keys = list(bl)
    blender = [dict(zip(bl_keys, row, strict=True)) for row in zip(*bl.values(), strict=True)]
    shadow = _split(t.shadow_spheres.tolist(), t.shadow_offsets.tolist())
    kinds = np.asarray(t.KINDS)[t.kind].tolist()
    sources = [
        {
            "light": j,
            "lens": i,
            "kind": k,
            "position": pos,
            "axis": ax,
            "spread_deg": sp,
            "cylinder_radius": rc,
            "intensity": it,
            "color": c,
            "full": not sh,
            "shadow_list": sh,
            "image_distance": im,
            "magnification": m,
            "brightness_factor": bf,
            "unblocked_fraction": uf,
            "blender_light": b,
        }
        for j, i, k, pos, ax, sp, rc, it, c, sh, im, m, bf, uf, b in zip(
            t.light.tolist(),
            t.lens.tolist(),
            kinds,
            _floats(t.position),
            _floats(t.axis),
            _floats(np.degrees(t.spread)),
            maybe(t.cylinder_radius, ~col),
            _floats(t.intensity),
            _floats(t.color),
            shadow,
            maybe(image, col),
            maybe(magnification, col),
            _floats(t.brightness_factor),
            _floats(t.unblocked_fraction),
            blender,
            strict=True,
        )
    ]
    skipped = [{"light": j, "lens": i, "reason": r} for j, i, r in _skip_reasons(result)]
    return sources, skipped


#: Rows encoded per `json.dumps` call when streaming (bounded memory, few writes).
JSON_CHUNK = 20_000


def write_phase1_json(
    out, model: str, sources: list, skipped: list, indent: int | None = None
) -> None:
    """`{"model": …, "sources": […], "skipped": […]}` to `out`, streamed in chunks
    of rows, each encoded by the C encoder at once. `indent`: as `json.dump`'s
    (the text is the same as `json.dump` of the whole object would write); None:
    compact, no blanks. Never NaN or Infinity (`allow_nan=False`: the rows carry
    None there)."""
    seps = (",", ":") if indent is None else (",", ": ")
    nl = "" if indent is None else "\n"
    pad = "" if indent is None else " " * indent

    def rows(items, depth):
        for start in range(0, len(items), JSON_CHUNK):
            text = json.dumps(
                items[start : start + JSON_CHUNK], indent=indent, separators=seps, allow_nan=False
            )[1:-1]
            if indent is not None:  # "\n  row,\n  row\n", one level deeper
                text = text[:-1].replace("\n", "\n" + pad * (depth - 1))[1:]
            yield ("," + nl if start else "") + text

    out.write("{" + nl + pad + json.dumps("model") + seps[1] + json.dumps(model) + "," + nl)
    for name, items, last in (("sources", sources, False), ("skipped", skipped, True)):
        out.write(pad + json.dumps(name) + seps[1] + "[")
        if items:
            out.write(nl)
            for chunk in rows(items, 2):
                out.write(chunk)
            out.write(nl + pad)
        out.write("]" + ("" if last else ",") + nl)
    out.write("}\n")


class _Pieces:
    """Texts of JSON values in one byte buffer, one per row: row r's text is
    buf[start[r] : start[r] + length[r]]. Built by numpy from orjson's output,
    so that no Python object is made per value."""

    def __init__(self, buf: bytes, start, length):
        import numpy as np

        self.buf = np.frombuffer(buf, dtype=np.uint8)
        self.start = np.asarray(start, dtype=np.int64)
        self.length = np.asarray(length, dtype=np.int64)

    @classmethod
    def constant(cls, text: str, n: int) -> _Pieces:
        import numpy as np

        return cls(text.encode(), np.zeros(n), np.full(n, len(text.encode())))

    @classmethod
    def choice(cls, texts: list[str], which) -> _Pieces:
        """texts[which[r]] for each row."""
        import numpy as np

        raw = [t.encode() for t in texts]
        lengths = np.array([len(t) for t in raw], dtype=np.int64)
        which = np.asarray(which, dtype=np.int64)
        return cls(b"".join(raw), (np.cumsum(lengths) - lengths)[which], lengths[which])

    @classmethod
    def numbers(cls, values, null=None) -> _Pieces:
        """The JSON text of each number of a 1-D numpy column, printed by orjson
        straight from the array; null where `null` (and orjson's null for a
        non-finite float: never NaN or Infinity)."""
        import numpy as np
        import orjson

        values = np.ascontiguousarray(values)
        buf = orjson.dumps(values, option=orjson.OPT_SERIALIZE_NUMPY) + b"null"
        commas = np.flatnonzero(np.frombuffer(buf, dtype=np.uint8) == ord(","))
        if not values.size:
            commas = commas[:0]
        start = np.r_[1, commas + 1] if values.size else np.zeros(0, dtype=np.int64)
        end = np.r_[commas, len(buf) - 5] if values.size else np.zeros(0, dtype=np.int64)
        pieces = cls(buf, start, end - start)
        if null is not None:
            pieces.start[null] = len(buf) - 4
            pieces.length[null] = 4
        return pieces

    @classmethod
    def lists(cls, values, offsets) -> _Pieces:
        """The numbers values[offsets[r] : offsets[r + 1]] of each row, comma
        separated (the text inside a JSON list)."""
        import numpy as np

        items = cls.numbers(values)
        first, last = offsets[:-1], offsets[1:] - 1
        full = last >= first
        start = np.zeros(first.size, dtype=np.int64)
        length = np.zeros(first.size, dtype=np.int64)
        start[full] = items.start[first[full]]
        length[full] = items.start[last[full]] + items.length[last[full]] - start[full]
        return cls(items.buf.tobytes(), start, length)


def _matrix_texts(values):
    """orjson's text of a 2-D numeric array (n ≥ 1 rows, k columns) as bytes, and
    where each number's text starts and ends in it (n, k): "[[a,b],[c,d]]" has
    k − 1 commas inside each row and one after it (the last row's: its final "]").
    A non-finite float is orjson's null."""
    import numpy as np
    import orjson

    buf = orjson.dumps(np.ascontiguousarray(values), option=orjson.OPT_SERIALIZE_NUMPY)
    n, k = values.shape
    b = np.frombuffer(buf, dtype=np.uint8)
    sep = np.append(np.flatnonzero(b == ord(",")), len(buf) - 1).reshape(n, k)
    start, end = np.empty((n, k), dtype=np.int64), np.empty((n, k), dtype=np.int64)
    start[:, 1:], end[:, :-1] = sep[:, :-1] + 1, sep[:, :-1]
    start[0, 0], start[1:, 0] = 2, sep[:-1, -1] + 2  # after "[[", after "],["
    end[:, -1] = sep[:, -1] - 1  # before the row's "]"
    return b, start, end


def _gather(src, start, length, work=None) -> bytes:
    """The bytes src[start[p] : start[p] + length[p]] of every piece p in turn, in one
    numpy gather: the index of each output byte is the previous one + 1 within a
    piece, a jump where a piece begins (a cumulative sum, no index per byte made in
    Python). `work`: a list holding an int64 buffer reused from call to call (fresh
    arrays of this size cost page faults)."""
    import numpy as np

    keep = length > 0
    start, length = start[keep], length[keep]
    if not start.size:
        return b""
    ends = np.cumsum(length)
    total = int(ends[-1])
    if work is None:
        work = [np.empty(0, dtype=np.int64)]
    if work[0].size < total:
        work[0] = np.empty(total, dtype=np.int64)
    idx = work[0][:total]
    idx.fill(1)
    idx[0] = start[0]
    idx[ends[:-1]] = start[1:] - start[:-1] - length[:-1] + 1
    np.cumsum(idx, out=idx)
    return src[idx].tobytes()


#: Sources per chunk of the compact writer (about 0.6 kB of text each).
COMPACT_CHUNK = 8192


def _in_order(fn, items):
    """`fn` over `items`, results in order, one item per core computed side by side
    (threads: numpy's gathers let go of the GIL; 16 × 10 000 droplets' 94 MB of JSON
    0.67 → 0.58 s), at most one more than the cores in hand: memory stays a few chunks."""
    from collections import deque
    from concurrent.futures import ThreadPoolExecutor

    from core.shared.parallel import cores

    n = min(cores(), len(items))
    if n < 2:
        yield from map(fn, items)
        return
    with ThreadPoolExecutor(n) as pool:
        pending = deque()
        for item in items:
            pending.append(pool.submit(fn, item))
            if len(pending) > n:
                yield pending.popleft().result()
        while pending:
            yield pending.popleft().result()


def phase1_compact_json(result, lights, model: str):
    """The compact JSON of `phase1 --json` as chunks of bytes (one document,
    streamed COMPACT_CHUNK sources at a time), printed by orjson straight from the
    columns and assembled by numpy: no dict and no Python object per source or
    per number. Per chunk, orjson prints two matrices (the ints light, lens; the
    20 floats of a row in the row's order, null where a field is null) and the
    shadow lists; a row is the template's constant texts and ranges of those
    outputs (a vector's "x,y,z" is one range), gathered at once (`_gather`).

    The same JSON content as `write_phase1_json` of `phase1_json_rows` (the
    json module's writer, kept for `--indent`), with one difference in form and
    one in contract: orjson prints a float as the shortest text that reads back
    to the same double, like Python's repr, but spells exponents without
    padding (1e-7 where repr says 1e-07; 1e+16 like repr); and a non-finite
    number (an image at infinity, a NaN from a degenerate input) is written as
    null, so the output is always valid JSON (never NaN or Infinity)."""
    import numpy as np
    import orjson

    t = result.table
    col = t.kind == 2
    with np.errstate(divide="ignore", invalid="ignore"):
        image = np.where(col, np.nan, 1.0 / t.vergence)
        magnification = np.where(col, np.nan, -1.0 / (t.vergence * t.distance))
    # The floats of a row in the order it prints them (columns of `floats` below).
    float_columns = [
        *t.position.T,
        *t.axis.T,
        np.degrees(t.spread),
        np.where(col, t.cylinder_radius, np.nan),
        t.intensity,
        *t.color.T,
        image,
        magnification,
        t.brightness_factor,
        t.unblocked_fraction,
        lights.energy_w,
        lights.spot_size_deg,
        lights.spot_blend,
        lights.radius,
    ]
    kinds = [orjson.dumps(k).decode() for k in t.KINDS]
    profiles = None
    if lights.profile_info is not None:
        profiles = [
            orjson.dumps(p, option=orjson.OPT_SERIALIZE_NUMPY)
            for p in lights.json_columns()["profile"]
        ]
    offsets = t.shadow_offsets
    # A row: constant text, then a range of a source, in turn. Sources: "i" the ints'
    # text, "f" the floats', (column, last column) of their matrix; or a `_Pieces`.
    template = [
        (',{"light":', ("i", 0, 0)),
        (',"lens":', ("i", 1, 1)),
        (',"kind":', "kind"),
        (',"position":[', ("f", 0, 2)),
        ('],"axis":[', ("f", 3, 5)),
        ('],"spread_deg":', ("f", 6, 6)),
        (',"cylinder_radius":', ("f", 7, 7)),
        (',"intensity":', ("f", 8, 8)),
        (',"color":[', ("f", 9, 11)),
        ('],"full":', "full"),
        (',"shadow_list":[', "shadow"),
        ('],"image_distance":', ("f", 12, 12)),
        (',"magnification":', ("f", 13, 13)),
        (',"brightness_factor":', ("f", 14, 14)),
        (',"unblocked_fraction":', ("f", 15, 15)),
        (',"blender_light":{"type":"SPOT","energy_w":', ("f", 16, 16)),
        (',"spot_size_deg":', ("f", 17, 17)),
        (',"spot_blend":', ("f", 18, 18)),
        (',"radius":', ("f", 19, 19)),
    ]
    if profiles is not None:
        template.append((',"profile":', "profile"))
    template.append(("}}", None))
    const = [text.encode() for text, _ in template]
    const_buf = np.frombuffer(b"".join(const), dtype=np.uint8)
    const_len = np.array([len(c) for c in const], dtype=np.int64)
    const_start = np.cumsum(const_len) - const_len
    reasons = _skip_reasons(result)
    per_thread = threading.local()  # `_gather`'s index buffer, one per thread

    def rows(a, b):
        n = b - a
        ints_buf, i_start, i_end = _matrix_texts(np.stack([t.light[a:b], t.lens[a:b]], axis=1))
        floats = np.empty((n, len(float_columns)))
        for c, column in enumerate(float_columns):
            floats[:, c] = column[a:b]
        float_buf, f_start, f_end = _matrix_texts(floats)
        other = {
            "kind": _Pieces.choice(kinds, t.kind[a:b]),
            "full": _Pieces.choice(["false", "true"], offsets[a + 1 : b + 1] == offsets[a:b]),
            "shadow": _Pieces.lists(
                t.shadow_spheres[offsets[a] : offsets[b]], offsets[a : b + 1] - offsets[a]
            ),
        }
        if profiles is not None:
            lengths = np.array([len(p) for p in profiles[a:b]], dtype=np.int64)
            other["profile"] = _Pieces(
                b"".join(profiles[a:b]), np.cumsum(lengths) - lengths, lengths
            )
        bufs = [const_buf, ints_buf, float_buf] + [p.buf for p in other.values()]
        sizes = np.cumsum([0] + [x.size for x in bufs])[:-1]
        base = dict(zip(["const", "i", "f", *other], sizes, strict=True))
        start = np.empty((n, 2 * len(template)), dtype=np.int64)
        length = np.zeros((n, 2 * len(template)), dtype=np.int64)
        for p, (_, source) in enumerate(template):
            start[:, 2 * p] = base["const"] + const_start[p]
            length[:, 2 * p] = const_len[p]
            if source is None:
                continue
            if isinstance(source, tuple):
                name, first, last = source
                s, e = (i_start, i_end) if name == "i" else (f_start, f_end)
                start[:, 2 * p + 1] = base[name] + s[:, first]
                length[:, 2 * p + 1] = e[:, last] - s[:, first]
            else:
                start[:, 2 * p + 1] = base[source] + other[source].start
                length[:, 2 * p + 1] = other[source].length
        if not hasattr(per_thread, "work"):
            per_thread.work = [np.empty(0, dtype=np.int64)]
        return _gather(np.concatenate(bufs), start.ravel(), length.ravel(), per_thread.work)

    def chunks():
        yield b'{"model":' + orjson.dumps(model) + b',"sources":['
        n = len(t)
        spans = [(a, min(a + COMPACT_CHUNK, n)) for a in range(0, n, COMPACT_CHUNK)]
        for (a, _), text in zip(spans, _in_order(lambda ab: rows(*ab), spans), strict=True):
            yield text[1:] if a == 0 else text  # no comma before the first row
        yield b'],"skipped":['
        for a in range(0, len(reasons), JSON_CHUNK):
            rows_ = [
                {"light": j, "lens": i, "reason": r} for j, i, r in reasons[a : a + JSON_CHUNK]
            ]
            yield (b"," if a else b"") + orjson.dumps(rows_)[1:-1]
        yield b"]}\n"

    return chunks()


def cmd_phase1(args) -> int:
    from core.bi.format import BiFormatError, read_bi_arrays
    from core.phase1.point_lights import compute_phase1

    try:
        # Columns straight from the file: no Python object per sphere.
        arrays = read_bi_arrays(args.scene)
    except BiFormatError as e:
        return _fail(str(e))
    except OSError as e:
        return _fail(f"{args.scene}: {e.strerror or e}")
    result = compute_phase1(arrays)
    # A `.bi` light has no radius: point lights, as `phase1_light_table` makes them.
    lights = bi_scene_light_table(arrays, result.table, args.model)
    if args.json:
        if args.indent is None:
            sys.stdout.flush()
            for text in phase1_compact_json(result, lights, args.model.upper()):
                sys.stdout.buffer.write(text)
        else:
            sources, skipped = phase1_json_rows(result, lights)
            write_phase1_json(sys.stdout, args.model.upper(), sources, skipped, args.indent)
    else:
        print(format_phase1_table(result, lights, args.model))
    return 0


# --------------------------------------------------------------------------- test

#: The release whose environment the launcher picks without `--blender`.
DEFAULT_BLENDER = "5.2"
#: The manifest's `blender_version_min`: plain `test` also runs the Blender tests there.
MINIMUM_BLENDER = "4.5"


def cmd_test(args, extra) -> int:
    """Plain `test`: the whole suite on the default release, then the Blender-side
    tests on the minimum release (its own environment, made on first use). Paths or
    `--blender X.Y` narrow it to one pytest run."""
    # Paths given on the command line replace the default (the whole suite).
    targets = [] if any(not a.startswith("-") for a in extra) else [str(ROOT / "tests")]
    chosen = os.environ.get("LENS_LIGHTS_BLENDER") or ""
    release = chosen or DEFAULT_BLENDER
    # Another release than the default: the Blender-side tests only; the pure core
    # is the same code on every release.
    marks = ["-m", "blender"] if release != DEFAULT_BLENDER and "-m" not in extra else []
    cmd = [sys.executable, "-m", "pytest", *targets, "-q", *marks, *extra]
    code = _call(cmd, cwd=ROOT)
    if code != 0 or chosen or not targets:
        return code
    print(
        f"lens-lights: the Blender tests on Blender {MINIMUM_BLENDER} (the manifest's minimum)",
        flush=True,
    )
    return _call(
        [str(ROOT / "lens-lights"), "test", "--blender", MINIMUM_BLENDER, *extra], cwd=ROOT
    )


# --------------------------------------------------------------------------- lint


def cmd_lint(args, extra) -> int:
    """`ruff check` and `ruff format --check` (pyproject.toml), as CI runs them."""
    ruff = Path(sys.executable).with_name("ruff")
    if not ruff.is_file():
        return _fail(f"ruff is not installed beside {sys.executable}")
    code = _call([str(ruff), "check", *extra, "."], cwd=ROOT)
    return _call([str(ruff), "format", "--check", *extra, "."], cwd=ROOT) or code


# --------------------------------------------------------------------------- bench


def cmd_bench(args, extra) -> int:
    script = ROOT / "bench" / f"{args.name}.py"
    if not script.is_file():
        names = sorted(p.stem for p in (ROOT / "bench").glob("*.py") if not p.stem.startswith("_"))
        return _fail(f"no benchmark {args.name!r}; there are: {', '.join(names)}")
    return _call([sys.executable, str(script), *extra], cwd=ROOT)


# --------------------------------------------------------------------------- render, demo, build


def _load_script(name: str):
    """A module of scripts/ by file (cli.py may run from anywhere)."""
    import importlib.util

    path = ROOT / "scripts" / f"{name}.py"
    spec = importlib.util.spec_from_file_location(f"lens_lights_scripts_{name}", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def cmd_render(args) -> int:
    """`render` and `demo`: scripts/render.py, in this process (bpy is imported there)."""
    return _load_script("render").run(args)


def cmd_build(args, extra) -> int:
    if not (ROOT / "scripts" / "build_extension.py").is_file():
        return _fail("scripts/build_extension.py is missing")
    return _load_script("build_extension").main(extra) or 0


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(
        prog="lens-lights",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("phase1", help="secondary light sources of a .bi scene")
    p.add_argument("scene", help="a .bi scene file")
    p.add_argument(
        "--json",
        action="store_true",
        help="print JSON instead of a table (compact: one line, no blanks)",
    )
    p.add_argument(
        "--indent",
        type=int,
        default=None,
        metavar="N",
        help="with --json: indent nested levels by N spaces, for people",
    )
    p.add_argument(
        "--model",
        choices=PHASE1_MODELS,
        default=PHASE1_DEFAULT_MODEL,
        type=str.lower,
        help=(
            "lens-light tier of each source's Blender light (default: "
            f"{PHASE1_DEFAULT_MODEL}, the most accurate that renders in both "
            "EEVEE and Cycles; exact_profile is Cycles only)"
        ),
    )

    sub.add_parser("test", help="run the whole test suite (extra args go to pytest)")
    sub.add_parser("lint", help="ruff check and ruff format --check, as CI runs them")

    # Its options (--count, --seed) and --help are scripts/fuzz_bi.py's own.
    sub.add_parser(
        "fuzz", add_help=False, help="fuzz the .bi reader and phase1 (`fuzz --help`: its options)"
    )

    p = sub.add_parser("bench", help="run a benchmark of bench/ (extra args go to it)")
    p.add_argument("name", help="benchmark name, e.g. scale or accuracy")

    p_render = sub.add_parser(
        "render", help="render a .blend or .bi scene (with lens lights by default)"
    )
    p_demo = sub.add_parser("demo", help="render the showcase scene without and with lens lights")
    # The command: the first word (the top-level parser has no option taking a value).
    # Only render and demo need their options, hence scripts/render.py (and numpy).
    command = next((a for a in (sys.argv[1:] if argv is None else argv) if a[:1] != "-"), None)
    if command in ("render", "demo"):
        render = _load_script("render")
        render.add_render_arguments(p_render)
        render.add_demo_arguments(p_demo)
    if command == "phase1":
        # Phase 1 is elementwise numpy: BLAS threads (OpenBLAS makes one per core at
        # import) would only add their start-up to the command's time.
        os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    sub.add_parser(
        "build",
        add_help=False,
        help="build the extension's zip (args go to scripts/build_extension.py)",
    )

    args, extra = parser.parse_known_args(argv)
    if args.command == "build":
        return cmd_build(args, extra)
    if args.command == "test":
        return cmd_test(args, extra)
    if args.command == "lint":
        return cmd_lint(args, extra)
    if args.command == "bench":
        return cmd_bench(args, extra)
    if args.command == "fuzz":
        return _call([sys.executable, str(ROOT / "scripts" / "fuzz_bi.py"), *extra])
    if extra:
        parser.error(f"unrecognized arguments: {' '.join(extra)}")
    return {"phase1": cmd_phase1, "render": cmd_render, "demo": cmd_render}[args.command](args)


if __name__ == "__main__":
    try:
        code = main()
    except BrokenPipeError:  # `… | head` closed the pipe: not an error
        sys.stderr.close()
        code = 0
    # The bpy module of Blender 4.2 crashes (4.5: hangs) in its static destructors at
    # interpreter exit, after the work is done: leave without running them.
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (BrokenPipeError, ValueError):
            pass
    os._exit(code or 0)
