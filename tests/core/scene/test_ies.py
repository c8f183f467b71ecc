"""IES LM-63 files read as Cycles reads them (issue 28 item 7): the numbers by hand
from the files written here (Fac = candela × multiplier × ballast factors × 4π/177.83,
v from the light's −Z, h = atan2(x, y) + π), LM-63's symmetries, and a file that
cannot be read says why."""

import math

import numpy as np
import pytest

from core.scene.ies import CANDELA_TO_FAC, IesError, LightProfile, light_frame, parse_ies


def _file(v, h, rows, header="1 1000 {m} {nv} {nh} 1 2 0 0 0\n0.5 2 100\n", m=1.0, tilt="NONE"):
    body = " ".join(map(str, v)) + "\n" + " ".join(map(str, h)) + "\n"
    body += "\n".join(" ".join(map(str, r)) for r in rows)
    return (
        f"IESNA:LM-63-2002\n[TEST] x\nTILT={tilt}\n"
        + header.format(m=m, nv=len(v), nh=len(h))
        + body
    )


def _dir(v_deg, h_deg):
    """The local direction of vertical angle v and horizontal angle h (Cycles')."""
    v, a = math.radians(v_deg), math.radians(h_deg) - math.pi  # a = atan2(x, y)
    return [math.sin(v) * math.sin(a), math.sin(v) * math.cos(a), -math.cos(v)]


def test_the_units_are_cycles_fac():
    # multiplier 3, ballast 0.5, ballast-lamp factor 2: × 3
    p = parse_ies(_file([0, 45, 90], [0], [[10, 20, 0]], m=3.0))
    assert p.fac(_dir(0, 0)) == pytest.approx(30 * CANDELA_TO_FAC)
    assert p.fac(_dir(45, 123)) == pytest.approx(60 * CANDELA_TO_FAC)  # one plane: all h
    assert p.fac(_dir(90, 0)) == 0.0  # at the last angle and past it: 0
    assert p.fac(_dir(120, 0)) == 0.0
    assert CANDELA_TO_FAC == pytest.approx(0.0706650768394)


def test_a_quadrant_is_mirrored_to_the_full_turn():
    p = parse_ies(_file([0, 45, 90, 180], [0, 45, 90], [[1, 2, 3, 0], [1, 4, 5, 0], [1, 6, 7, 0]]))
    f = CANDELA_TO_FAC
    for h, want in ((0, 2), (45, 4), (90, 6), (135, 4), (180, 2), (225, 4), (270, 6), (315, 4)):
        assert float(p.fac(_dir(45, h))) == pytest.approx(want * f), h
    assert np.degrees(p.h_angles).tolist() == pytest.approx(
        [0, 45, 90, 135, 180, 225, 270, 315, 360]
    )


def test_a_tilt_block_is_skipped_and_the_360_plane_added():
    tilted = _file([0, 90], [0, 90, 180, 270], [[1, 0], [2, 0], [3, 0], [4, 0]], tilt="INCLUDE")
    tilted = tilted.replace("TILT=INCLUDE\n", "TILT=INCLUDE\n1\n2\n0 90\n1 1\n")
    p = parse_ies(tilted)
    assert np.degrees(p.h_angles)[-1] == pytest.approx(360.0)
    assert p.values[-1, 0] == p.values[0, 0] == pytest.approx(0.5 * 2 * CANDELA_TO_FAC)


def test_the_profile_turns_with_the_light():
    p = parse_ies(
        _file([0, 45, 90], [0, 90, 180, 270], [[0, 1, 0], [0, 2, 0], [0, 3, 0], [0, 4, 0]])
    )
    # h 270° is local +x; the light turned 90° about z puts its local +x on world +y
    turned = np.array([[0, -1, 0, 0], [1, 0, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])
    prof = LightProfile(p, light_frame(turned))
    assert float(prof.fac_world([0.0, 1.0, -1.0])) == pytest.approx(4 * CANDELA_TO_FAC)
    assert float(prof.fac_world([-1.0, 0.0, -1.0])) == pytest.approx(3 * CANDELA_TO_FAC)  # 180°
    # toward a lens: the mean over its disc; a small lens straight at 45°: that value
    got = prof.toward([0, 0, 0], [[0.0, 10.0, -10.0]], [1e-4])
    assert got == pytest.approx([4 * CANDELA_TO_FAC], rel=1e-4)


@pytest.mark.parametrize(
    "text, why",
    [
        ("no tilt here", "no TILT= line"),
        (_file([0, 90], [0], [[1, 0]]).replace("TILT=NONE", "TILT=lamp.tlt"), "another file"),
        (_file([0, 90], [0], [[1]]), "cut short"),
        (_file([0, 90], [0], [[1, 0]]).replace(" 1 2 0 0 0", " 3 2 0 0 0"), "type A"),
        (_file([10, 90], [0], [[1, 0]]), "start at 10°"),
    ],
)
def test_what_cannot_be_read_says_why(text, why):
    with pytest.raises(IesError, match=why):
        parse_ies(text)
