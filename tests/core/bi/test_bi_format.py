"""Tests of the `.bi` reader and writer (core/bi/format.py); no Blender needed."""

import math
import os
import tempfile
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from core.bi.format import BiFormatError, format_bi, parse_bi, read_bi, write_bi
from core.scene.model import Camera, Light, Scene, Sphere, Surface

EXAMPLES = Path(__file__).resolve().parents[3] / "examples"


def example(name):
    return read_bi(EXAMPLES / name)


def rgb255(r, g, b):
    return (r / 255, g / 255, b / 255)


# A minimal valid file; tests break it one line at a time. Line numbers:
#  1 V  2 C  3 A  4 U  5 B  6 L  7 C  8 P  9 I  10 O  11 T  12 C  13 R  14 S  15-21 #
GOOD = """V 200 200
C 15 15 15
A 6 6 6
U 0 1 0
B 20 20
L 1
C 1 1 1
P 15 15 15
I 1
O 1
T 0
C 3 7 1
R 2
S
#C 1 0 0
#A 0.1
#D 0.5
#S 0.4
#T 0
#E 6
#N 1
"""


def with_line(number, text, source=GOOD):
    """GOOD with line `number` (1-based) replaced by `text` (None: deleted)."""
    lines = source.splitlines()
    if text is None:
        del lines[number - 1]
    else:
        lines[number - 1] = text
    return "\n".join(lines) + "\n"


def error_of(text, path="x.bi"):
    with pytest.raises(BiFormatError) as info:
        parse_bi(text, path)
    return info.value


def assert_error(text, line, *fragments):
    err = error_of(text)
    assert str(err).startswith(f"x.bi:{line}: "), str(err)
    assert err.line == line and err.path == "x.bi"
    for fragment in fragments:
        assert fragment in err.message, str(err)
    return err


# --------------------------------------------------------------------------- #
# The example files against SPEC section 8


def test_esfera_is_the_spec_sample():
    s = example("esfera.bi")
    assert (s.width, s.height) == (200, 200)
    assert s.camera == Camera(
        position=(15, 15, 15), target=(6, 6, 6), up=(0, 1, 0), fov_deg=(20, 20)
    )
    assert s.color_scale == 1.0
    assert s.lights == [Light(position=(15, 15, 15), color=(1, 1, 1), brightness=1)]
    assert s.objects == [
        Sphere(
            center=(3, 7, 1),
            radius=2,
            surface=Surface(
                color=(1, 0, 0),
                ambient=0.1,
                diffuse=0.5,
                specular=0.4,
                transmission=0,
                exponent=6,
                ior=1,
            ),
        )
    ]


def test_fig1():
    s = example("fig1.bi")
    assert s.color_scale == 255.0 and (s.width, s.height) == (200, 200)
    assert s.camera == Camera(
        position=(0, 0, 10), target=(1, 1, -1), up=(0, 1, 0), fov_deg=(45, 45)
    )
    assert s.lights == [Light(position=(10, 10, 10), color=rgb255(100, 100, 100))]
    lens, red = s.objects
    assert (lens.center, lens.radius) == ((3, 3, 3), 1)
    assert lens.surface == Surface(rgb255(100, 10, 10), 0.1, 0.2, 0, 0.7, 80, 1.5171)
    assert (red.center, red.radius) == ((1, 1, -1), 2)
    assert red.surface == Surface(rgb255(250, 0, 0), 0.1, 0.9, 0, 0, 70, 1.0)
    assert [o.is_lens for o in s.objects] == [True, False]


def test_fig2():
    s = example("fig2.bi")
    assert s.camera == Camera(
        position=(0, 0, 10), target=(-2, 2, 1), up=(0, 1, 0), fov_deg=(30, 30)
    )
    assert s.lights == [Light(position=(-12, 12, 2), color=rgb255(100, 0, 0))]
    lens, blue = s.objects
    assert (lens.center, lens.radius) == ((-4.5, 4.5, 1.5), 1)
    assert lens.surface == Surface(rgb255(10, 0, 100), 0.03, 0.02, 0.35, 0.6, 80, 1.5)
    assert (blue.center, blue.radius) == ((0, 0, 0), 2)
    assert blue.surface == Surface(rgb255(0, 0, 100), 0.2, 0, 0.8, 0, 70, 1.0)


def test_fig3():
    s = example("fig3.bi")
    assert s.camera == Camera(
        position=(6, 10, 4), target=(0.5, 3, 0), up=(0, 1, 0), fov_deg=(37, 37)
    )
    assert s.lights == [Light(position=(4, 13, 4), color=rgb255(100, 0, 0), brightness=1)]
    small, glass, big = s.objects
    assert (small.center, small.radius) == ((1.5, 7, 2), 0.25)
    assert small.surface == Surface((0, 0, 0), 0.2, 0.4, 0.4, 0, 80, 1.0)
    assert (glass.center, glass.radius) == ((1, 6, 2), 1)
    assert glass.surface.transmission == 0.6 and glass.surface.ior == 1.5
    assert glass.surface.color == rgb255(100, 100, 100)
    assert (big.center, big.radius) == ((-1, 0, 0), 2)
    assert big.surface == Surface(rgb255(100, 100, 100), 0.2, 0, 0.8, 0, 70, 1.0)
    assert [o.is_lens for o in s.objects] == [False, True, False]
    assert all(o.name == "" for o in s.objects) and s.lights[0].radius == 0


# --------------------------------------------------------------------------- #
# Round trips


@pytest.mark.parametrize("name", ["esfera.bi", "fig1.bi", "fig2.bi", "fig3.bi"])
def test_examples_round_trip(name, tmp_path):
    scene = example(name)
    write_bi(scene, tmp_path / name)
    again = read_bi(tmp_path / name)
    assert again == scene
    # The 0-255 numbers come back as written in the thesis.
    assert format_bi(again) == format_bi(scene)


def test_fig3_writes_the_thesis_numbers():
    text = format_bi(example("fig3.bi"))
    assert "\nC 100 0 0\n" in text and "\n#C 100 100 100\n" in text
    assert "\nR 0.25\n" in text and "\n#N 1.5\n" in text


AWKWARD = [
    0.1,
    1e-300,
    123456789.123,
    -2.5e-7,
    1 / 3,
    5e-324,
    1.7976931348623157e308,
    2.0**60,
    -0.0,
    7.0,
]


def awkward_scene(scale):
    colors = [(0.1, 1 / 3, 5e-324), (1.0, 0.7, 1e-300), (2 / 255, 0.5, 0.999999999)]
    return Scene(
        width=640,
        height=1,
        camera=Camera(
            position=(0.1, 1e-300, 123456789.123),
            target=(-2.5e-7, 1 / 3, 7.0),
            up=(5e-324, 0.0, -0.0),
            fov_deg=(179.99999999999997, 1e-9),
        ),
        lights=[
            Light(
                position=(1.7976931348623157e308, 2.0**60, -0.1), color=colors[0], brightness=1e-300
            ),
            Light(position=(0, 0, 0), color=colors[1], brightness=123456789.123),
        ],
        objects=[
            Sphere(
                center=(0.1, 0.2, 0.3),
                radius=1e-300,
                surface=Surface(colors[2], 0.1, 1e-300, 123456789.123, 1 / 3, 0.0, 1.5171),
            )
        ],
        color_scale=scale,
    )


@pytest.mark.parametrize("scale", [1.0, 255.0])
def test_awkward_floats_round_trip_exactly(scale):
    scene = awkward_scene(scale)
    again = parse_bi(format_bi(scene))
    assert again == scene
    for a, b in zip(
        again.lights[0].color + again.objects[0].surface.color,
        scene.lights[0].color + scene.objects[0].surface.color,
        strict=False,
    ):
        assert a.hex() == b.hex() if a else a == b


def test_empty_scene_round_trips():
    scene = Scene()
    assert parse_bi(format_bi(scene)) == scene


def test_names_and_light_radius_are_not_written():
    scene = Scene(
        lights=[Light(position=(1, 2, 3), radius=0.5, name="key")],
        objects=[Sphere(center=(0, 0, 0), radius=1, name="sphere 1")],
    )
    again = parse_bi(format_bi(scene))
    assert again.lights[0].radius == 0 and again.lights[0].name == ""
    assert again.objects[0].name == ""
    assert "key" not in format_bi(scene) and "sphere 1" not in format_bi(scene)


finite = st.floats(allow_nan=False, allow_infinity=False)
unit = st.floats(0, 1)
nonneg = st.floats(0, 1e300)
positive = st.floats(0, 1e300, exclude_min=True)
vec = st.tuples(finite, finite, finite)
color = st.tuples(st.floats(0, 1e6), st.floats(0, 1e6), st.floats(0, 1e6))
surfaces = st.builds(Surface, color, nonneg, nonneg, nonneg, unit, nonneg, positive)
spheres = st.builds(Sphere, vec, positive, surfaces)
lights = st.builds(Light, vec, color, nonneg)
cameras = st.builds(
    Camera,
    st.just((1.0, 2.0, 3.0)),
    vec.filter(lambda v: v != (1, 2, 3)),
    vec.filter(lambda v: any(v)),
    st.tuples(
        st.floats(0, 180, exclude_min=True, exclude_max=True),
        st.floats(0, 180, exclude_min=True, exclude_max=True),
    ),
)
scenes = st.builds(
    Scene,
    st.integers(1, 10**6),
    st.integers(1, 10**6),
    cameras,
    st.lists(lights, max_size=3),
    st.lists(spheres, max_size=3),
    st.sampled_from([1.0, 255.0]),
)


@settings(max_examples=100, deadline=None)
@given(scenes)
def test_random_scenes_round_trip(scene):
    again = parse_bi(format_bi(scene))
    # Colours always come back; the scale only where the file can express it.
    expected_scale = again.color_scale
    assert again == Scene(**{**scene.__dict__, "color_scale": expected_scale})
    colors = [c for lt in scene.lights for c in lt.color] + [
        c for o in scene.objects for c in o.surface.color
    ]
    if any(c > 1 for c in colors):
        assert again.color_scale == 255.0
    elif scene.color_scale == 255.0 and any(c > 1 / 255 for c in colors):
        assert again.color_scale == 255.0
    elif all(c <= 1 / 256 for c in colors):
        assert again.color_scale == 1.0


def test_writer_refuses_what_the_reader_would_refuse():
    bad = [
        Scene(objects=[Sphere(center=(0, 0, 0), radius=0)]),
        Scene(objects=[Sphere(center=(0, 0, 0), radius=1, surface=Surface(transmission=2))]),
        Scene(lights=[Light(position=(math.nan, 0, 0))]),
        Scene(lights=[Light(position=(0, 0, 0), color=(-1, 0, 0))]),
        Scene(lights=[Light(position=(0, 0, 0), color=(1e308, 0, 0))]),  # 255 x: inf
        Scene(width=0),
        Scene(width=2.5),
        Scene(camera=Camera(position=(1, 1, 1), target=(1, 1, 1))),
        Scene(camera=Camera(up=(0, 0, 0))),
        Scene(camera=Camera(fov_deg=(180, 45))),
    ]
    for scene in bad:
        with pytest.raises(ValueError):
            format_bi(scene)


# --------------------------------------------------------------------------- #
# Comments, blanks, layout


def test_comments_in_all_positions():
    text = """/* leading comment
   over two lines */

V 200 200 /* after a record */
C 15 /* inside */ 15 15
/* on its own line */ A 6 6 6
U 0 1 0/*glued*/
B 20 20


L 1 /* a comment that
   spans lines after a record */
C 1 1 1
P 15 15 15
I 1
O 1
T 0
C 3 7 1
R 2
S /**/
#C 1 0 0
#A 0.1
#D 0.5
#S 0.4
#T 0
#E 6
#N 1 /* trailing */
/* final comment */"""
    assert parse_bi(text) == parse_bi(GOOD)


def test_crlf_bom_and_tabs(tmp_path):
    path = tmp_path / "w.bi"
    path.write_bytes(b"\xef\xbb\xbf" + GOOD.replace("\n", "\r\n").replace(" ", "\t").encode())
    assert read_bi(path) == parse_bi(GOOD)


def test_surface_records_in_any_order():
    lines = GOOD.splitlines()
    shuffled = lines[:14] + list(reversed(lines[14:]))
    assert parse_bi("\n".join(shuffled)) == parse_bi(GOOD)


def test_no_lights_and_no_objects():
    text = "V 1 1\nC 0 0 1\nA 0 0 0\nU 0 1 0\nB 45 45\nL 0\nO 0\n"
    scene = parse_bi(text)
    assert scene.lights == [] and scene.objects == []


def test_legal_non_lens_spheres():
    # n <= 1 and kt = 0 are legal scenes (phase 1 skips them).
    scene = parse_bi(with_line(21, "#N 0.8", with_line(19, "#T 1")))
    assert scene.objects[0].surface.ior == 0.8 and not scene.objects[0].is_lens


# --------------------------------------------------------------------------- #
# The colour scale rule


def test_colors_all_at_most_one_are_0_to_1():
    scene = parse_bi(with_line(15, "#C 1 0.5 0"))
    assert scene.color_scale == 1.0 and scene.objects[0].surface.color == (1, 0.5, 0)


def test_one_color_above_one_makes_the_whole_file_0_to_255():
    scene = parse_bi(with_line(15, "#C 1.5 0 0"))  # light stays "C 1 1 1"
    assert scene.color_scale == 255.0
    assert scene.objects[0].surface.color == (1.5 / 255, 0, 0)
    assert scene.lights[0].color == (1 / 255, 1 / 255, 1 / 255)


def test_light_color_alone_decides_too():
    scene = parse_bi(with_line(7, "C 255 255 255"))
    assert scene.color_scale == 255.0 and scene.lights[0].color == (1, 1, 1)
    assert scene.objects[0].surface.color == (1 / 255, 0, 0)


def test_other_values_above_one_do_not_change_the_scale():
    scene = parse_bi(with_line(9, "I 100", with_line(20, "#E 80")))
    assert scene.color_scale == 1.0 and scene.lights[0].color == (1, 1, 1)


def test_writer_switches_scale_when_the_file_would_read_back_differently():
    dim = Scene(lights=[Light(position=(0, 0, 0), color=(1 / 255, 0, 0))], color_scale=255.0)
    again = parse_bi(format_bi(dim))  # all 0-255 values <= 1: written in 0-1
    assert again.lights == dim.lights and again.color_scale == 1.0
    hdr = Scene(lights=[Light(position=(0, 0, 0), color=(2.0, 0, 0))], color_scale=1.0)
    again = parse_bi(format_bi(hdr))  # a colour above 1 needs the 0-255 scale
    assert again.lights == hdr.lights and again.color_scale == 255.0


# --------------------------------------------------------------------------- #
# Errors: one test per class, each with its exact line


def test_empty_file():
    assert_error("", 1, "expected 'V <width> <height>'", "end of file")
    assert_error("/* only a comment */\n\n", 2, "end of file")


def test_wrong_key():
    err = assert_error(with_line(13, "Q 1"), 13, "expected 'R <radius>' (sphere radius)")
    assert str(err) == "x.bi:13: expected 'R <radius>' (sphere radius), got 'Q 1'"


def test_keys_are_case_sensitive():
    assert_error(with_line(1, "v 200 200"), 1, "got 'v 200 200'")


def test_wrong_number_of_values():
    assert_error(with_line(2, "C 15 15"), 2, "expected 'C <x> <y> <z>' (camera position)")
    assert_error(with_line(9, "I 1 2"), 9, "'I <brightness>'")
    assert_error(with_line(14, "S 1"), 14, "expected 'S'")


def test_not_a_number():
    assert_error(with_line(12, "C 3 seven 1"), 12, "expected a number for <y>", "'seven'")


def test_non_finite_numbers():
    for bad in ("nan", "inf", "-Infinity"):
        assert_error(with_line(8, f"P 15 {bad} 15"), 8, "expected a number")
    assert_error(with_line(8, "P 15 1e999 15"), 8, "expected a finite number", "'1e999'")


def test_counts_must_be_non_negative_integers():
    assert_error(with_line(6, "L 1.0"), 6, "expected an integer for <count>")
    assert_error(with_line(6, "L -1"), 6, "expected <count> >= 0")
    assert_error(with_line(10, "O 1e0"), 10, "expected an integer")


def test_viewport_must_be_positive_integers():
    assert_error(with_line(1, "V 0 200"), 1, "expected <width> > 0")
    assert_error(with_line(1, "V 200 -5"), 1, "expected <height> > 0")
    assert_error(with_line(1, "V 200.5 200"), 1, "expected an integer")


def test_fewer_lights_than_announced():
    # L 2 with one light: light 2 would start where the O record is (line 10).
    assert_error(with_line(6, "L 2"), 10, "colour of light 2 of 2", "got 'O 1'")


def test_fewer_objects_than_announced():
    assert_error(with_line(10, "O 2"), 21, "type of object 2 of 2", "end of file")
    assert_error(with_line(10, "O 99999999999999999999"), 21, "end of file")


def test_extra_trailing_record():
    assert_error(GOOD + "\n/* c */\nT 0\n", 24, "expected end of file after 1 object(s)")
    assert_error(with_line(10, "O 0"), 11, "expected end of file", "got 'T 0'")


def test_truncated_file():
    text = "".join(GOOD.splitlines(keepends=True)[:12])  # ends after the centre
    assert_error(text, 12, "expected 'R <radius>'", "end of file")


def test_polyhedron_refused():
    err = assert_error(with_line(11, "T 1"), 11)
    assert str(err) == ("x.bi:11: polyhedron objects (T 1) are not supported; only spheres (T 0)")


def test_unknown_object_type():
    assert_error(with_line(11, "T 2"), 11, "expected 'T 0'", "got 'T 2'")
    assert_error(with_line(11, "T 0.0"), 11, "expected 'T 0'")


def test_radius_must_be_positive():
    assert_error(with_line(13, "R 0"), 13, "expected <radius> > 0 (sphere radius)", "'0'")
    assert_error(with_line(13, "R -2"), 13, "expected <radius> > 0")


def test_physical_ranges():
    assert_error(with_line(19, "#T 1.5"), 19, "expected <kt> in [0, 1]")
    assert_error(with_line(19, "#T -0.1"), 19, "<kt> in [0, 1]")
    assert_error(with_line(21, "#N -1.5"), 21, "expected <n> > 0")
    assert_error(with_line(21, "#N 0"), 21, "expected <n> > 0")
    assert_error(with_line(16, "#A -0.1"), 16, "expected <ka> >= 0")
    assert_error(with_line(20, "#E -1"), 20, "expected <exponent> >= 0")
    assert_error(with_line(9, "I -1"), 9, "expected <brightness> >= 0")
    assert_error(with_line(5, "B 0 20"), 5, "expected <horizontal> in (0, 180)")
    assert_error(with_line(5, "B 20 180"), 5, "expected <vertical> in (0, 180)")


def test_negative_colours():
    assert_error(with_line(7, "C 1 -1 1"), 7, "expected <g> >= 0 (light colour)")
    assert_error(with_line(15, "#C 0 0 -0.5"), 15, "expected <b> >= 0 (surface colour)")


def test_degenerate_camera():
    assert_error(with_line(3, "A 15 15 15"), 3, "target different from the camera position")
    assert_error(with_line(4, "U 0 0 0"), 4, "non-zero camera up vector")


def test_missing_surface_record_names_the_S_line():
    assert_error(with_line(18, None), 14, "surface of object 1 is missing '#S <ks>'")


def test_duplicate_surface_record():
    assert_error(with_line(18, "#A 0.3"), 18, "duplicate '#A'", "first at line 16")


def test_unknown_surface_record():
    assert_error(with_line(18, "#X 0.3"), 18, "expected one of #C #A #D #S #T #E #N")


def test_unterminated_comment_names_its_first_line():
    assert_error(with_line(5, "B 20 20 /* open"), 5, "unterminated comment")
    assert_error(GOOD + "/* at the end\n\n\n", 22, "unterminated comment")


def test_stray_comment_end():
    assert_error(with_line(4, "U 0 1 0 */"), 4, "'U <x> <y> <z>'")


def test_bytes_that_are_not_utf8(tmp_path):
    path = tmp_path / "bad.bi"
    path.write_bytes(GOOD.encode()[:40] + b"\xff\xfe" + GOOD.encode()[40:])
    with pytest.raises(BiFormatError) as info:
        read_bi(path)
    assert info.value.line == GOOD.encode()[:40].count(b"\n") + 1
    assert str(info.value).startswith(f"{path}:{info.value.line}: expected UTF-8")


def test_missing_file_is_a_bi_format_error(tmp_path):
    with pytest.raises(BiFormatError) as info:
        read_bi(tmp_path / "nope.bi")
    assert info.value.line is None


def test_message_shows_unprintable_characters_escaped():
    err = error_of(with_line(1, "V\x00 1 2"))
    assert "\\x00" in str(err) and "\x00" not in str(err)


# --------------------------------------------------------------------------- #
# Fuzzing: nothing but BiFormatError may come out

FIG3 = (EXAMPLES / "fig3.bi").read_text()
PIECES = [
    "/*",
    "*/",
    "\n",
    " ",
    "-",
    ".",
    "e",
    "1e999",
    "nan",
    "0",
    "1",
    "255",
    "#",
    "T 1",
    "L 9",
    "O 0",
    "\r",
    "\x00",
    "\u00e9",
    "\ud800",
]


def parse_only_bi_errors(text):
    try:
        scene = parse_bi(text, "fuzz.bi")
    except BiFormatError as err:
        assert err.path == "fuzz.bi" and str(err).startswith("fuzz.bi")
        # Universal newlines (the reader's rule): LF, CRLF and a lone CR end a line.
        breaks = text.count("\n") + text.count("\r") - text.count("\r\n")
        assert err.line is None or 1 <= err.line <= breaks + 2
    else:
        assert isinstance(scene, Scene)
        assert parse_bi(format_bi(scene)) == scene


@settings(max_examples=100, deadline=None)
@given(
    st.text(
        alphabet=st.sampled_from("VCAUBLPIOTRS#0123456789.-+eE /*\n\t") | st.characters(),
        max_size=300,
    )
)
def test_random_text_raises_only_bi_format_error(text):
    parse_only_bi_errors(text)


@settings(max_examples=150, deadline=None)
@given(
    st.lists(
        st.tuples(
            st.integers(0, len(FIG3)),
            st.integers(0, 6),
            st.sampled_from(PIECES) | st.text(max_size=4),
        ),
        max_size=5,
    )
)
def test_mutated_fig3_raises_only_bi_format_error(edits):
    text = FIG3
    for at, cut, insert in edits:
        at = min(at, len(text))
        text = text[:at] + insert + text[at + cut :]
    parse_only_bi_errors(text)


@settings(max_examples=50, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.binary(max_size=200), st.integers(0, len(FIG3)))
def test_random_bytes_in_a_file_raise_only_bi_format_error(noise, at):
    data = FIG3.encode()[:at] + noise + FIG3.encode()[at:]
    fd, name = tempfile.mkstemp(suffix=".bi")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        read_bi(name)
    except BiFormatError as err:
        assert err.path == name
    finally:
        os.unlink(name)


def test_lone_cr_is_a_line_break():
    # Universal newlines: an old Mac file (CR only) reads like LF and CRLF, and an
    # error names the line an editor shows.
    assert parse_bi(FIG3.replace("\n", "\r")) == parse_bi(FIG3)
    bad = FIG3.replace("R 2", "R -2").replace("\n", "\r")
    line = FIG3.replace("R 2", "R -2").splitlines().index("R -2") + 1
    with pytest.raises(BiFormatError, match=f"^fuzz.bi:{line}: "):
        parse_bi(bad, "fuzz.bi")


def test_bad_utf8_is_reported_on_its_line_with_cr_breaks(tmp_path):
    path = tmp_path / "mac.bi"
    path.write_bytes(b"V 200 200\rC 0 0 10\r\xff\r")
    with pytest.raises(BiFormatError, match=r":3: expected UTF-8"):
        read_bi(path)


def _many_spheres_text(n=100, scale255=False):
    rng = __import__("random").Random(5)
    objects = [
        Sphere(
            center=(rng.uniform(-9, 9), rng.uniform(-9, 9), rng.uniform(-9, 9)),
            radius=rng.uniform(0.1, 2),
            surface=Surface(
                color=(rng.choice([0.2, 0.5, 1.0]), 0.7, 0.25),
                transmission=rng.choice([0.0, 0.9]),
                ior=1.5,
            ),
        )
        for _ in range(n)
    ]
    scene = Scene(
        lights=[Light(position=(0.0, 20.0, 0.0))],
        objects=objects,
        color_scale=255.0 if scale255 else 1.0,
    )
    return format_bi(scene)


def _plain_parse(text, monkeypatch):
    import core.bi.format as bf

    with monkeypatch.context() as m:
        m.setattr(bf, "_bulk_spheres", lambda reader, count: None)
        try:
            return parse_bi(text, "big.bi")
        except BiFormatError as err:
            return str(err)


@pytest.mark.parametrize("scale255", [False, True])
def test_bulk_sphere_path_reads_like_the_record_reader(scale255, monkeypatch):
    text = _many_spheres_text(scale255=scale255)
    assert parse_bi(text, "big.bi") == _plain_parse(text, monkeypatch)


@pytest.mark.parametrize(
    "edit",
    [
        ("R ", "R -"),  # out of range: record reader's message and line
        ("#T 0.9", "#T 1.9"),
        ("#A 0.1\n#D", "#A 0.1 #D"),  # two records on a line
        ("C ", "C\n"),  # a record split over two lines
        ("#A 0.1", "#A nan"),
        ("#E 6", "#E 1_0"),
        ("#N 1.5\n", "#N 1.5\n#N 1.5\n"),
        ("#A 0.1\n#D 0.5", "#D 0.5\n#A 0.1"),  # other order: legal, record reader
    ],
)
def test_bulk_sphere_path_leaves_anything_else_to_the_record_reader(edit, monkeypatch):
    text = _many_spheres_text()
    cut = text.index("object 80")
    text = text[:cut] + text[cut:].replace(*edit, 1)
    got = parse_bi(text, "big.bi") if not isinstance(_plain_parse(text, monkeypatch), str) else None
    want = _plain_parse(text, monkeypatch)
    if isinstance(want, str):
        with pytest.raises(BiFormatError) as err:
            parse_bi(text, "big.bi")
        assert str(err.value) == want
    else:
        assert got == want


# --------------------------------------------------------------------------- #
# `read_bi_arrays`: the columns phase 1 reads, the fast path against the record
# reader (`SceneArrays.from_scene(parse_bi(...))`), on the same text.


def arrays_of_record_reader(text):
    from core.scene.arrays import SceneArrays

    return SceneArrays.from_scene(parse_bi(text, "x.bi"))


def assert_same_arrays(fast, slow):
    for name in ("light_position", "light_brightness", "light_color", "center", "radius"):
        a, b = getattr(fast, name), getattr(slow, name)
        assert a.dtype == b.dtype and a.shape == b.shape, name
        assert a.tobytes() == b.tobytes(), name  # bit for bit (-0.0, the last digit)
    for name in ("ior", "kt"):
        assert getattr(fast, name).tobytes() == getattr(slow, name).tobytes(), name


def assert_same_outcome(text):
    """parse_bi_arrays gives the record reader's arrays, or its very error."""
    from core.bi.format import parse_bi_arrays

    try:
        slow = arrays_of_record_reader(text)
    except BiFormatError as err:
        with pytest.raises(BiFormatError) as info:
            parse_bi_arrays(text, "x.bi")
        assert str(info.value) == str(err)
        return None
    fast = parse_bi_arrays(text, "x.bi")
    assert_same_arrays(fast, slow)
    return fast


@settings(max_examples=100, deadline=None)
@given(scenes)
def test_arrays_fast_path_reads_written_files_like_the_record_reader(scene):
    from core.bi.format import _arrays_in_layout

    text = format_bi(scene)
    fast = _arrays_in_layout(text, "x.bi")
    assert fast is not None  # the writer's layout is the fast path's
    assert_same_arrays(fast, arrays_of_record_reader(text))


#: Edits of one line of a written file: some keep it valid in another layout (the
#: fast path must then give up or agree), the others make the reader refuse it.
EDITS = [
    lambda line: line.replace(" ", "\t"),
    lambda line: line.replace(" ", "  "),
    lambda line: "  " + line,
    lambda line: line + " /* a\ncomment */",
    lambda line: "/* x */" + line,
    lambda line: line.replace(" ", "\n", 1),  # a record split over two lines
    lambda line: line + "\n",
    lambda line: line + " 1",
    lambda line: line.rsplit(" ", 1)[0],
    lambda line: line.replace("1", "nan"),
    lambda line: line.replace("0.", "1e999"),
    lambda line: line.replace("1", "-1"),
    lambda line: line.replace(".", ".5.", 1),
    lambda line: line.replace("5", "\u0665"),  # an Arabic-Indic digit
    lambda line: line + "/*",
    lambda line: line.replace("C", "c"),
    lambda line: line.replace("0", "1_0"),
    lambda line: "",
]


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    scenes,
    st.lists(st.tuples(st.integers(0, 10**6), st.sampled_from(range(len(EDITS)))), max_size=3),
    st.booleans(),
)
def test_arrays_fast_and_record_reader_agree_on_edited_files(scene, edits, join):
    lines = format_bi(scene).split("\n")
    for where, edit in edits:
        k = where % len(lines)
        lines[k] = EDITS[edit](lines[k])
    text = "\n".join(lines)
    if join and len(lines) > 2:  # two records on one line
        text = text.replace("\nR ", " R ", 1).replace("\n#A", " #A", 1)
    assert_same_outcome(text)


def droplets(n, seed=0, shared=True):
    """n spheres, enough for the per-column conversions (shared materials)."""
    import random

    rng = random.Random(seed)
    surface = Surface(color=(0.9, 0.95, 1.0), transmission=0.95, ior=1.33)
    objects = [
        Sphere(
            center=(rng.uniform(-9, 9), rng.uniform(-9, 9), rng.uniform(0, 1)),
            radius=rng.uniform(0.05, 0.3),
            surface=surface
            if shared
            else Surface(color=(rng.random(), 0.5, 1.0), transmission=rng.random(), ior=1.5),
        )
        for _ in range(n)
    ]
    lights = [Light(position=(1.0, 2.0, 9.0), color=(1.0, 0.5, 0.25), brightness=2.0)]
    return Scene(lights=lights, objects=objects)


@pytest.mark.parametrize("shared", [True, False])
def test_arrays_of_a_large_file_and_its_edits(shared):
    from core.bi.format import _arrays_in_layout

    text = format_bi(droplets(300, shared=shared))
    assert _arrays_in_layout(text, "x.bi") is not None
    fast = assert_same_outcome(text)
    assert fast.radius.shape == (300,)
    lines = text.split("\n")
    for k in (40, 1000, len(lines) - 3):
        for edit in EDITS:
            edited = lines.copy()
            edited[k] = edit(edited[k])
            assert_same_outcome("\n".join(edited))


def test_arrays_colour_scale_from_a_sphere_colour(tmp_path):
    """A surface colour above 1 puts the whole file in 0-255: the light colour is
    divided by 255 too (the fast path never makes a Surface, yet must know)."""
    from core.bi.format import read_bi_arrays

    lines = format_bi(droplets(100)).split("\n")
    k = [i for i, line in enumerate(lines) if line.startswith("#C ")][57]
    lines[k] = "#C 200 1 1"
    path = tmp_path / "s.bi"
    path.write_text("\n".join(lines))
    arrays = read_bi_arrays(path)
    assert arrays.light_color.tolist() == [[1 / 255, 0.5 / 255, 0.25 / 255]]
    assert_same_arrays(arrays, arrays_of_record_reader(path.read_text()))


def test_arrays_errors_name_the_line(tmp_path):
    from core.bi.format import read_bi_arrays

    text = format_bi(droplets(100)).split("\n")
    k = next(i for i, line in enumerate(text) if line.startswith("R ")) + 20 * 13
    text[k] = "R -0.5"
    path = tmp_path / "bad.bi"
    path.write_text("\n".join(text))
    with pytest.raises(BiFormatError) as info:
        read_bi_arrays(path)
    assert info.value.line == k + 1 and "radius" in info.value.message
    with pytest.raises(BiFormatError):
        read_bi_arrays(tmp_path / "missing.bi")


@pytest.mark.parametrize(
    "text",
    [
        "a /* b */ c /* d */\n",
        "a /* b\n */ c /* d */\n",
        "/**/ /*/ */ x\n",
        "a /*/*/ b\n",
        "a */ /* b */*/ c\n",
        "a /* b /* c */ d */\n",
        "/* never closed\n x\n",
    ],
)
def test_comment_stripping_matches_the_rule(text):
    """One-line comments are cut by a split; the result is the loop's."""
    import re

    from core.bi.format import _strip_comments

    try:
        got = _strip_comments(text, "x.bi")
    except BiFormatError:
        assert "*/" not in text.split("/*", 1)[1]
        return
    # The rule: the first "/*", then the first "*/" after it, is one comment.
    want, pos = [], 0
    while (start := text.find("/*", pos)) >= 0:
        end = text.find("*/", start + 2)
        want += [text[pos:start], " " + "\n" * text.count("\n", start, end)]
        pos = end + 2
    want.append(text[pos:])
    assert got == "".join(want)
    assert re.sub(r"\s+", " ", got) == re.sub(r"\s+", " ", "".join(want))


# --------------------------------------------------------------------------- #
# The bytes path of `read_bi_arrays` (`_arrays_from_bytes`: numpy over the file's
# bytes) against the record reader: the same arrays bit for bit, or it gives up
# (None) and the text paths decide; never arrays for a file the reader refuses.


def bytes_path(text):
    from core.bi.format import _arrays_from_bytes, _arrays_or_none

    return _arrays_or_none(_arrays_from_bytes, text.encode("utf-8"), "x.bi")


def assert_bytes_path_agrees(text):
    """The bytes path's arrays are the record reader's; None where it gives up; and
    None whenever the record reader refuses the text. Returns its arrays."""
    fast = bytes_path(text)
    try:
        slow = arrays_of_record_reader(text)
    except BiFormatError:
        assert fast is None
        return None
    if fast is not None:
        assert_same_arrays(fast, slow)
    return fast


@settings(max_examples=100, deadline=None)
@given(scenes)
def test_bytes_path_reads_written_files_like_the_record_reader(scene):
    text = format_bi(scene)
    assert bytes_path(text) is not None  # the writer's layout is the bytes path's
    assert_bytes_path_agrees(text)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    scenes,
    st.lists(st.tuples(st.integers(0, 10**6), st.sampled_from(range(len(EDITS)))), max_size=3),
    st.booleans(),
)
def test_bytes_path_and_record_reader_agree_on_edited_files(scene, edits, join):
    lines = format_bi(scene).split("\n")
    for where, edit in edits:
        k = where % len(lines)
        lines[k] = EDITS[edit](lines[k])
    text = "\n".join(lines)
    if join and len(lines) > 2:  # two records on one line
        text = text.replace("\nR ", " R ", 1).replace("\n#A", " #A", 1)
    assert_bytes_path_agrees(text)


@pytest.mark.parametrize("shared", [True, False])
def test_bytes_path_on_a_large_file_and_its_edits(shared):
    text = format_bi(droplets(300, shared=shared))
    assert assert_bytes_path_agrees(text).radius.shape == (300,)
    lines = text.split("\n")
    for k in (40, 1000, len(lines) - 3):
        for edit in EDITS:
            edited = lines.copy()
            edited[k] = edit(edited[k])
            assert_bytes_path_agrees("\n".join(edited))


@pytest.mark.parametrize(
    "change",
    [
        lambda t: t.replace("\n", "\r\n"),
        lambda t: t.replace("\n", "\r"),
        lambda t: "\ufeff" + t,
        lambda t: t.replace(" ", "\t"),
        lambda t: t.replace("\n", "\n  "),
        lambda t: t.replace("\n", " \n\n"),
        lambda t: t.replace("\n#A", " /* é, a comment\nover lines */\n#A"),
        lambda t: t.replace("\nR", "/**/\nR").replace("\nS", " /*/ x */\nS"),
        lambda t: t.rstrip("\n"),
    ],
)
def test_bytes_path_takes_blanks_comments_and_line_ends(change):
    """Other blanks, line ends, a byte-order mark and comments anywhere (on their own
    lines, after a record, over several lines, with UTF-8 in them) keep a file in the
    layout: the bytes path reads it, like the record reader."""
    text = change(format_bi(droplets(100, shared=False)))
    fast = bytes_path(text)
    assert fast is not None
    # A file's byte-order mark is read as a file's (`read_bi`), not as text.
    assert_same_arrays(fast, arrays_of_record_reader(text.removeprefix("\ufeff")))


GOOD_NUMBERS = [
    "1.",
    ".5",
    "+3",
    "-0",
    "-0.0e0",
    "1e5",
    "1E-5",
    "+.5e+3",
    "007",
    "9007199254740993",  # 2^53 + 1: a tie, rounded to even
    "0.30000000000000004",
    "2.2250738585072014e-308",
    "4.9e-324",
    "1e-400",
    "1.7976931348623157e308",
    "0.1000000000000000055511151231257827021181583404541015625",
]
BAD_NUMBERS = ["1e", "1.2.3", "+-1", ".", "e5", "--1", "1-2", "nan", "inf", "1e999", "0x10", "1_0"]


@pytest.mark.parametrize("token", GOOD_NUMBERS + BAD_NUMBERS)
def test_bytes_path_numbers_read_like_float_or_go_to_the_record_reader(token, tmp_path):
    """A centre coordinate of one sphere among many: read as `float` reads it (bit
    for bit), or refused with the record reader's message and line."""
    from core.bi.format import read_bi_arrays

    lines = format_bi(droplets(100, shared=False)).split("\n")
    k = lines.index("/* object 70: sphere */") + 2
    assert lines[k].startswith("C ")
    lines[k] = f"C 1 {token} 2"
    text = "\n".join(lines)
    fast = assert_bytes_path_agrees(text)
    if token in GOOD_NUMBERS:
        assert fast is not None
        got = fast.center[69, 1]
        assert math.copysign(1, got) == math.copysign(1, float(token)) and got == float(token)
    else:
        path = tmp_path / "n.bi"
        path.write_text(text)
        with pytest.raises(BiFormatError) as info:
            read_bi_arrays(path)
        assert info.value.line == k + 1


@pytest.mark.parametrize(
    "text",
    [
        "a /* b */ c /* d */\n",
        "a /* b\n */ c /* d */\n",
        "/**/ /*/ */ x\n",
        "a /*/*/ b\n",
        "a */ /* b */*/ c\n",
        "a /* b /* c */ d */\n",
        "/* never closed\n x\n",
        "*/ a\n",
        "a /* b */* c\n",
    ],
)
def test_bytes_comment_blanking_matches_the_rule(text):
    """Comments the bytes path blanks are the rule's (the first "/*", then the first
    "*/" after it; newlines kept); where it cannot tell simply, it gives up."""
    import numpy as np

    from core.bi.format import _blank_comments

    got = _blank_comments(np.frombuffer(text.encode(), dtype=np.uint8))
    want, pos, ok = [], 0, True
    while (start := text.find("/*", pos)) >= 0:
        end = text.find("*/", start + 2)
        if end < 0:
            ok = False
            break
        want += [text[pos:start], "".join(c if c == "\n" else " " for c in text[start : end + 2])]
        pos = end + 2
    want.append(text[pos:])
    if got is None:
        return  # gave up: the text paths decide
    assert ok and "*/" not in text[pos:]
    assert got.tobytes().decode() == "".join(want)


def test_a_stray_number_after_no_objects_is_the_readers_error():
    """Found by the edited-files property: the bytes path read "O 0" followed by a
    stray number as a scene without spheres; the record reader names the line."""
    from core.bi.format import parse_bi_arrays

    text = (
        "V 1 1\nC 1 2 3\nA 0 0 0\nU 0 0 1\nB 1 1\nL 1\nC 0 0 0\nP 0 0 0\nI 0\n"
        "O 0                     /* number of objects */\n 1"
    )
    with pytest.raises(BiFormatError, match=r"x.bi:11: expected end of file after 0 object"):
        parse_bi_arrays(text, "x.bi")
