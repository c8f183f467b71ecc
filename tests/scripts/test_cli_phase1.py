"""`./lens-lights phase1` as a user runs it (a subprocess through the launcher):
the JSON's keys and each source's Blender light, the README's example, `--model`,
and bad input (exit 2, `FILE:LINE: message`, no traceback)."""

import json
import math
import subprocess
from pathlib import Path

import orjson
import pytest

from core.bi.format import read_bi
from core.lens.glass import head_on_transmission

ROOT = Path(__file__).resolve().parents[2]
LAUNCHER = ROOT / "lens-lights"
FIG1 = ROOT / "examples" / "fig1.bi"
FIG3 = ROOT / "examples" / "fig3.bi"
MODELS = ("thesis", "physical", "fitted", "exact_profile")
SOURCE_KEYS = {
    "light",
    "lens",
    "kind",
    "position",
    "axis",
    "spread_deg",
    "cylinder_radius",
    "intensity",
    "color",
    "full",
    "shadow_list",
    "image_distance",
    "magnification",
    "brightness_factor",
    "unblocked_fraction",
    "blender_light",
}
LIGHT_KEYS = {"type", "energy_w", "spot_size_deg", "spot_blend", "radius"}
#: The import rule (README, core/bi/conversions.py): brightness 1 = 10 000 W.
WATTS_PER_BRIGHTNESS = 10_000.0


def phase1(*args, timeout=300):
    return subprocess.run(
        [str(LAUNCHER), "phase1", *map(str, args)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=timeout,
    )


def phase1_json(*args):
    result = phase1(*args, "--json")
    assert result.returncode == 0, result.stderr
    return json.loads(result.stdout)


def test_json_keys_and_the_readme_example():
    out = phase1_json(FIG3)
    assert set(out) == {"model", "sources", "skipped"}
    assert out["model"] == "FITTED"  # the documented default
    # README: one source (light 0 through sphere 1, real, blocked by sphere 0),
    # two opaque spheres skipped
    (src,) = out["sources"]
    assert set(src) == SOURCE_KEYS
    assert (src["light"], src["lens"], src["kind"], src["full"], src["shadow_list"]) == (
        0,
        1,
        "real",
        False,
        [0],
    )
    assert src["position"] == pytest.approx([0.294, 4.353, 1.529], abs=5e-4)
    assert src["spread_deg"] == pytest.approx(1.075, abs=5e-4)
    assert src["intensity"] == pytest.approx(0.4975, abs=5e-5)
    assert [(k["light"], k["lens"], k["reason"]) for k in out["skipped"]] == [
        (0, 0, "opaque (kt = 0)"),
        (0, 2, "opaque (kt = 0)"),
    ]
    bl = src["blender_light"]
    assert set(bl) == LIGHT_KEYS
    assert bl["type"] == "SPOT" and bl["energy_w"] > 0 and 0 < bl["spot_size_deg"] <= 180
    assert 0 <= bl["spot_blend"] <= 1 and bl["radius"] == 0.0  # .bi lights have no radius


def test_table_has_the_energy_of_the_chosen_tier():
    result = phase1(FIG3, "--model", "physical")
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    assert lines[0] == "1 secondary light source(s), 2 light × sphere pair(s) skipped"
    assert lines[1] == "energy: Blender light power (W) with the physical tier"
    header = next(line for line in lines if line.lstrip().startswith("light lens"))
    assert "energy W" in header and header.index("intensity") < header.index(
        "energy W"
    ) < header.index("shadow")
    row = lines[lines.index(header) + 2]
    energy = phase1_json(FIG3, "--model", "physical")["sources"][0]["blender_light"]["energy_w"]
    assert f"{energy:.4g}" in row.split()
    assert "skipped:" in lines and lines[-1] == "  light 0 × sphere 2: opaque (kt = 0)"


@pytest.mark.parametrize("model", MODELS)
def test_every_model_is_accepted(model):
    out = phase1_json(FIG1, "--model", model)
    assert out["model"] == model.upper()
    (src,) = out["sources"]
    bl = src["blender_light"]
    assert set(bl) >= LIGHT_KEYS and bl["energy_w"] > 0
    if model == "exact_profile":
        assert (bl["spot_size_deg"], bl["spot_blend"]) == (180.0, 0.0)
        assert set(bl) == LIGHT_KEYS | {"profile"} and "pixels" not in bl["profile"]
        assert (bl["profile"]["width"], bl["profile"]["height"]) == (256, 256)
    else:
        assert set(bl) == LIGHT_KEYS
    assert phase1(FIG1, "--model", model.upper()).returncode == 0  # any case


def test_primary_power_follows_the_import_rule():
    """Brightness b → a point light of b × 10 000 W; a sphere's transmission weight
    is its kt. THESIS: energy = power × the eq. 5.22 factor (the source's
    intensity is brightness × factor); PHYSICAL: power × T(0) × m² × kt²."""
    scene = read_bi(FIG1)
    b = scene.lights[0].brightness
    kt, n = scene.objects[0].surface.transmission, scene.objects[0].surface.ior
    thesis = phase1_json(FIG1, "--model", "thesis")["sources"][0]
    assert thesis["kind"] == "real" and thesis["full"]
    assert thesis["blender_light"]["energy_w"] == pytest.approx(
        WATTS_PER_BRIGHTNESS * thesis["intensity"], rel=1e-9
    )
    assert thesis["intensity"] == pytest.approx(b * thesis["brightness_factor"], rel=1e-12)
    physical = phase1_json(FIG1, "--model", "physical")["sources"][0]
    m = physical["magnification"]
    assert physical["blender_light"]["energy_w"] == pytest.approx(
        WATTS_PER_BRIGHTNESS * b * head_on_transmission(n) * m * m * kt * kt, rel=1e-9
    )
    # and the non-full source of fig3 is scaled by its unblocked share
    src = phase1_json(FIG3, "--model", "thesis")["sources"][0]
    assert src["blender_light"]["energy_w"] == pytest.approx(
        WATTS_PER_BRIGHTNESS * src["intensity"] * src["unblocked_fraction"], rel=1e-9
    )


def test_default_model_is_fitted_and_documented():
    assert phase1_json(FIG3)["sources"] == phase1_json(FIG3, "--model", "fitted")["sources"]
    help_text = phase1("--help").stdout
    assert "--model" in help_text and "fitted" in help_text and "EEVEE and Cycles" in help_text


@pytest.mark.parametrize(
    "content,expect",
    [
        (None, ": cannot read the file"),  # no line to name
        ("garbage\n", ":1: expected 'V <width> <height>'"),
        ("V 200 200\nC 0 0 10\nA 0 0 0\nU 0 1 0\nB 45 45\nL 1\nC 1 1 1\nP 1 2\n", ":8: "),
        ("V 200 200\nC 0 0 10\nA 0 0 0\nU 0 0 0\n", ":4: "),
    ],
    ids=["missing", "garbage", "short record", "zero up"],
)
@pytest.mark.parametrize(
    "flags",
    [(), ("--json",), ("--json", "--model", "exact_profile")],
    ids=["table", "json", "json-exact"],
)
def test_bad_file_exits_2_with_file_and_line(tmp_path, content, expect, flags):
    path = tmp_path / "bad.bi"
    if content is not None:
        path.write_text(content)
    result = phase1(path, *flags)
    assert result.returncode == 2
    assert f"lens-lights: {path}{expect}" in result.stderr
    assert "Traceback" not in result.stderr and result.stdout == ""


def test_bad_model_exits_2_without_traceback():
    result = phase1(FIG3, "--model", "bogus")
    assert result.returncode == 2
    assert "invalid choice: 'bogus'" in result.stderr and "Traceback" not in result.stderr
    assert result.stdout == ""


def test_exact_profile_energy_is_twice_the_beams_flux():
    """A 180° spot emits half its energy: the exact-profile light's power is twice
    the flux the exact optics put through the lens (ball_optics.lens_flux)."""
    from core.lens import ball_optics

    scene = read_bi(FIG1)
    light, lens = scene.lights[0], scene.objects[0]
    out = phase1_json(FIG1, "--model", "exact_profile")["sources"][0]
    D = math.dist(light.position, lens.center)
    i0 = WATTS_PER_BRIGHTNESS * light.brightness / (4 * math.pi)
    flux = ball_optics.lens_flux(i0, D, lens.radius, lens.surface.ior)
    kt = lens.surface.transmission
    assert out["blender_light"]["energy_w"] == pytest.approx(2 * flux * kt * kt, rel=1e-3)


def test_json_is_compact_by_default_and_indent_is_for_people():
    compact = phase1(FIG3, "--json")
    assert compact.returncode == 0, compact.stderr
    out = json.loads(compact.stdout)
    # One line, no blanks between tokens: what orjson writes of the same content.
    assert compact.stdout == orjson.dumps(out).decode() + "\n"
    for n in (2, 4):
        people = phase1(FIG3, "--json", "--indent", str(n))
        assert people.returncode == 0, people.stderr
        assert people.stdout == json.dumps(out, indent=n) + "\n"


@pytest.mark.parametrize("indent", [None, 0, 2, 3])
def test_json_streamed_in_chunks_is_one_json_document(indent, monkeypatch):
    """Rows are encoded a chunk at a time: the text is still exactly json.dump's."""
    import io
    import sys

    from core.phase1.point_lights import compute_phase1

    sys.path.insert(0, str(ROOT / "scripts"))
    import cli

    scene = read_bi(FIG1)
    scene.lights = scene.lights * 5  # 5 sources and 5 skipped pairs
    result = compute_phase1(scene)
    lights = cli.phase1_light_table(scene, result, "fitted")
    sources, skipped = cli.phase1_json_rows(result, lights)
    assert len(sources) == 5 and len(skipped) == 5
    monkeypatch.setattr(cli, "JSON_CHUNK", 2)
    out = io.StringIO()
    cli.write_phase1_json(out, "FITTED", sources, skipped, indent)
    whole = {"model": "FITTED", "sources": sources, "skipped": skipped}
    seps = (",", ":") if indent is None else None
    assert out.getvalue() == json.dumps(whole, indent=indent, separators=seps) + "\n"
    # and the rows are what the per-source objects say (SecondarySource.to_json)
    for row, src, bl in zip(
        sources, result.sources, cli.blender_lights(scene, result, "fitted"), strict=True
    ):
        assert {k: v for k, v in row.items() if k != "blender_light"} == src.to_json()
        want = bl.to_json()
        assert row["blender_light"].pop("type") == want.pop("type")
        assert row["blender_light"] == pytest.approx(want, rel=1e-12)
    assert [r["reason"] for r in skipped] == [k.reason for k in result.skipped]


def _same(a, b) -> bool:
    """Equal JSON content, floats bit for bit (-0.0 is not 0.0, 1 is not 1.0)."""
    if type(a) is not type(b):
        return False
    if isinstance(a, dict):
        return list(a) == list(b) and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, list):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, float):
        return a == b and math.copysign(1.0, a) == math.copysign(1.0, b)
    return a == b


def _reference_json(result, lights, model) -> str:
    """The previous compact writer's text: json.dumps of the rows (the json
    module's shortest round-trip floats), never NaN (allow_nan=False)."""
    import sys

    sys.path.insert(0, str(ROOT / "scripts"))
    import cli

    sources, skipped = cli.phase1_json_rows(result, lights)
    whole = {"model": model, "sources": sources, "skipped": skipped}
    return json.dumps(whole, separators=(",", ":"), allow_nan=False) + "\n"


def _no_constants(name):
    raise AssertionError(f"{name} in the JSON")


def _compact(result, lights, model) -> str:
    import sys

    sys.path.insert(0, str(ROOT / "scripts"))
    import cli

    text = b"".join(cli.phase1_compact_json(result, lights, model)).decode()
    # Valid JSON: no NaN, Infinity or -Infinity.
    json.loads(text, parse_constant=_no_constants)
    return text


@pytest.mark.parametrize("seed", range(3))
@pytest.mark.parametrize("model", MODELS)
def test_compact_json_is_the_json_modules_content(seed, model, monkeypatch):
    """The orjson writer (numbers printed from the columns, rows gathered by
    numpy, in chunks) writes the same content as json.dumps of the rows, every
    float bit for bit, for every kind of source, skip reason and tier."""
    import sys

    sys.path.insert(0, str(ROOT / "scripts"))
    sys.path.insert(0, str(ROOT / "tests"))
    import cli
    from random_scenes import random_scene

    from core.phase1.point_lights import compute_phase1

    scene = random_scene(seed)
    scene.objects[0].radius = -1.0  # a skip reason that names a number
    result = compute_phase1(scene)
    lights = cli.phase1_light_table(scene, result, model)
    monkeypatch.setattr(cli, "COMPACT_CHUNK", 7)
    monkeypatch.setattr(cli, "JSON_CHUNK", 3)
    text = _compact(result, lights, model.upper())
    want = json.loads(_reference_json(result, lights, model.upper()))
    assert {s["kind"] for s in want["sources"]} == {"real", "virtual", "collimated"}
    assert want["skipped"]
    assert _same(json.loads(text), want)
    assert text.count("\n") == 1 and text.endswith("\n")


def test_compact_json_numbers_read_back_bit_for_bit():
    """Each number's text (orjson's, from the numpy column) reads back to the
    same double, -0.0, subnormals and huge exponents included; ints stay ints;
    a non-finite number or a row marked null is null."""
    import sys

    import numpy as np

    sys.path.insert(0, str(ROOT / "scripts"))
    import cli

    rng = np.random.default_rng(5)
    special = [-0.0, 0.0, 5e-324, 2.2250738585072014e-308, 1e-300, 1e-7, 1e-5, 0.1, 1 / 3]
    special += [1e15, 1e16, 1.2345678901234568e17, 1e300, 1.7976931348623157e308]
    values = np.array(
        special
        + [-v for v in special]
        + (rng.normal(size=200) * 10.0 ** rng.integers(-300, 300, 200)).tolist()
    )
    pieces = cli._Pieces.numbers(values)
    texts = [
        pieces.buf[a : a + n].tobytes().decode()
        for a, n in zip(pieces.start.tolist(), pieces.length.tolist(), strict=True)
    ]
    assert len(texts) == values.size
    for text, v in zip(texts, values.tolist(), strict=True):
        assert _same(json.loads(text), v), (text, v)
    bad = np.array([np.nan, np.inf, -np.inf, 2.5, 1.0])
    null = np.array([False, False, False, False, True])
    pieces = cli._Pieces.numbers(bad, null)
    texts = [
        pieces.buf[a : a + n].tobytes().decode()
        for a, n in zip(pieces.start.tolist(), pieces.length.tolist(), strict=True)
    ]
    assert texts == ["null", "null", "null", "2.5", "null"]
    ints = cli._Pieces.numbers(np.array([0, -3, 2**40], dtype=np.int64))
    assert json.loads(b"[" + ints.buf[1:-5].tobytes() + b"]") == [0, -3, 2**40]


@pytest.mark.parametrize("indent", [None, 2])
def test_json_never_writes_nan_or_infinity(indent, monkeypatch):
    """A non-finite number (an image at infinity, a NaN from degenerate input)
    is null in both writers: the output stays valid JSON, and the rest of the
    content is unchanged."""
    import io
    import sys

    import numpy as np

    sys.path.insert(0, str(ROOT / "scripts"))
    sys.path.insert(0, str(ROOT / "tests"))
    import cli
    from random_scenes import random_scene

    from core.phase1.point_lights import compute_phase1

    scene = random_scene(2)
    result = compute_phase1(scene)
    lights = cli.phase1_light_table(scene, result, "fitted")
    clean = json.loads(_reference_json(result, lights, "FITTED"))
    t = result.table
    real = int(np.flatnonzero(t.kind == 0)[0])
    t.intensity[0] = np.nan
    t.position[1, 2] = -np.inf
    t.vergence[real] = 0.0  # image at infinity: 1/0
    lights.energy_w[2] = np.inf
    if indent is None:
        monkeypatch.setattr(cli, "COMPACT_CHUNK", 2)
        got = json.loads(_compact(result, lights, "FITTED"))
    else:
        sources, skipped = cli.phase1_json_rows(result, lights)
        out = io.StringIO()
        cli.write_phase1_json(out, "FITTED", sources, skipped, indent)
        assert "NaN" not in out.getvalue() and "Infinity" not in out.getvalue()
        got = json.loads(out.getvalue(), parse_constant=_no_constants)
    want = clean
    want["sources"][0]["intensity"] = None
    want["sources"][1]["position"][2] = None
    want["sources"][real]["image_distance"] = None
    want["sources"][real]["magnification"] = None
    want["sources"][2]["blender_light"]["energy_w"] = None
    assert _same(got, want)


def test_compact_json_of_many_sources_is_the_json_modules_content(monkeypatch):
    """Hundreds of sources sharing lights and materials, across many chunks."""
    import sys

    sys.path.insert(0, str(ROOT / "scripts"))
    sys.path.insert(0, str(ROOT / "tests"))
    import cli
    from random_scenes import random_scene

    from core.phase1.point_lights import compute_phase1

    scene = random_scene(4, n_lights=4, n_spheres=120)
    result = compute_phase1(scene)
    assert len(result.table) > 100
    lights = cli.phase1_light_table(scene, result, "fitted")
    monkeypatch.setattr(cli, "COMPACT_CHUNK", 50)
    text = _compact(result, lights, "FITTED")
    assert _same(json.loads(text), json.loads(_reference_json(result, lights, "FITTED")))


@pytest.mark.parametrize("seed", range(3))
@pytest.mark.parametrize("model", MODELS)
@pytest.mark.parametrize("chunk", [1, 7, 8192])
def test_compact_json_is_orjson_of_the_rows_byte_for_byte(seed, model, chunk, monkeypatch):
    """The compact writer (two orjson matrices per chunk, rows gathered by numpy)
    writes byte for byte what orjson writes for the rows made one by one as
    Python objects (`phase1_json_rows`, None for null), non-finite numbers
    included, whatever the chunk size."""
    import sys

    import numpy as np

    sys.path.insert(0, str(ROOT / "scripts"))
    sys.path.insert(0, str(ROOT / "tests"))
    import cli
    from random_scenes import random_scene

    from core.phase1.point_lights import compute_phase1

    scene = random_scene(seed, n_lights=2, n_spheres=30)
    scene.objects[0].radius = -1.0  # a skipped pair
    result = compute_phase1(scene)
    lights = cli.phase1_light_table(scene, result, model)
    t = result.table
    t.intensity[0] = np.nan
    t.position[-1, 1] = -np.inf
    t.vergence[len(t) // 2] = 0.0  # an image at infinity, where the kind has one
    monkeypatch.setattr(cli, "COMPACT_CHUNK", chunk)
    got = b"".join(cli.phase1_compact_json(result, lights, model.upper()))
    sources, skipped = cli.phase1_json_rows(result, lights)
    whole = {"model": model.upper(), "sources": sources, "skipped": skipped}
    assert got == orjson.dumps(whole, option=orjson.OPT_SERIALIZE_NUMPY) + b"\n"


def test_gather_and_matrix_texts_against_slices():
    """`_gather` is the pieces' slices joined; `_matrix_texts` finds each number's
    text in orjson's print of a matrix (one row, one column, nulls, ints)."""
    import sys

    import numpy as np

    sys.path.insert(0, str(ROOT / "scripts"))
    import cli

    rng = np.random.default_rng(3)
    src = rng.integers(0, 256, 500).astype(np.uint8)
    work = [np.empty(0, dtype=np.int64)]
    for _ in range(50):
        n = int(rng.integers(0, 30))
        start = rng.integers(0, 400, n)
        length = rng.integers(0, 5, n)  # empty pieces too
        want = b"".join(src[a : a + k].tobytes() for a, k in zip(start, length, strict=True))
        assert cli._gather(src, start, length, work) == want
        assert cli._gather(src, start, length) == want
    for shape in [(1, 1), (1, 4), (5, 1), (6, 3)]:
        values = rng.normal(size=shape) * 10.0 ** rng.integers(-20, 20, shape)
        values.flat[0] = np.nan
        for v in (values, rng.integers(-(10**12), 10**12, shape)):
            buf, start, end = cli._matrix_texts(v)
            texts = [
                [buf[a:b].tobytes() for a, b in zip(r, e, strict=True)]
                for r, e in zip(start, end, strict=True)
            ]
            want = [[orjson.dumps(x, option=orjson.OPT_SERIALIZE_NUMPY) for x in row] for row in v]
            assert texts == want


def test_phase1_starts_lean_and_render_keeps_its_options():
    """`phase1` loads neither scripts/render.py nor subprocess, and runs numpy with one
    BLAS thread unless the user chose otherwise; `render` and `demo` still have their
    options (loaded for them only)."""
    import os
    import sys

    code = (
        "import contextlib, io, json, os, sys\n"
        f"sys.path.insert(0, {str(ROOT / 'scripts')!r})\n"
        "import cli\n"
        "out = io.TextIOWrapper(io.BytesIO())\n"
        "with contextlib.redirect_stdout(out):\n"
        f"    code = cli.main(['phase1', {str(FIG1)!r}, '--json'])\n"
        "print(json.dumps([code, 'lens_lights_scripts_render' in sys.modules,\n"
        "    'subprocess' in sys.modules, os.environ.get('OPENBLAS_NUM_THREADS')]))\n"
    )
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}
    res = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=300
    )
    assert res.returncode == 0, res.stderr
    assert json.loads(res.stdout.splitlines()[-1]) == [0, False, False, "1"]
    env["OPENBLAS_NUM_THREADS"] = "2"
    res = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=300
    )
    assert json.loads(res.stdout.splitlines()[-1])[3] == "2"
    for command, option in (("render", "--engine"), ("demo", "--out")):
        res = subprocess.run(
            [str(LAUNCHER), command, "--help"], capture_output=True, text=True, timeout=300
        )
        assert res.returncode == 0 and option in res.stdout, res.stderr
