"""The bake's prints (`core.animation.bake_inputs`): the same read gives the same
prints, a moved, edited, added or removed object is named, float noise below the
rounding is not seen, and the record of a bake keeps each frame's prints."""

import dataclasses
from types import SimpleNamespace

import numpy as np

from core.animation.bake_inputs import (
    CAMERA,
    SETTINGS,
    BakeInputs,
    changes,
    changes_text,
    frame_prints,
    light_paths,
    quantised,
    stale_text,
)
from core.lens.glass import MaterialOptics
from core.lens.sphere_fit import SphereFit
from core.scene.assembly import GeometryRecord, ReadInputs
from core.scene.light_props import LightRecord
from core.scene.primaries import PointPrimary


def translation(x, y, z):
    m = np.eye(4)
    m[:3, 3] = (x, y, z)
    return m


def scene(marble=(0.0, 0.0, 1.0), power=1000.0, ior=1.5, noise=0.0, extra_cube=False, grid=(9, 12)):
    """A marble (R 0.5), a table (10 × 10 at z = 0) and a lamp 4 up (+ two cubes of
    side 2 under "Grid" at x = grid, and maybe one more at x = −9)."""
    cube = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    glass = MaterialOptics(ior=ior, transmission=1.0)
    records = [
        GeometryRecord(
            "Marble", None, "MESH", 0.5 * cube, optics=glass, fit=SphereFit(True, np.zeros(3), 0.5)
        ),
        GeometryRecord("Table", None, "MESH", cube * [5, 5, 0], optics=MaterialOptics()),
        LightRecord("Lamp", None, "POINT", power, radius=0.1),
        GeometryRecord("Cube", None, "MESH", cube, optics=MaterialOptics()),
    ]
    gid = [0, 1, 2, 3, 3]
    mats = [translation(*marble), np.eye(4), translation(0, 0, 4)]
    mats += [translation(grid[0], 0, 0), translation(grid[1], 0, 0)]
    pid = [-1, -1, -1, 0, 0]
    if extra_cube:
        gid.append(3)
        mats.append(translation(-9, 0, 0))
        pid.append(-1)
    mats = np.array(mats) + noise
    return ReadInputs(records, np.array(gid), mats, np.array(pid), ["Grid"])


SETTINGS_VALUE = dict(energy_model="EXACT_PROFILE", min_brightness=0.01)


def prints(**kw):
    settings = kw.pop("settings", SETTINGS_VALUE)
    return frame_prints(scene(**kw), {SETTINGS: settings})


def test_same_inputs_same_prints_one_per_top_object():
    a, b = prints(), prints()
    assert a == b
    # the instances of "Grid" are one entry under their instancer
    assert set(a) == {"Marble", "Table", "Lamp", "Grid", SETTINGS}
    assert changes(a, b) == []


def test_a_moved_marble_is_named():
    found = changes(prints(), prints(marble=(0.3, 0.0, 1.0)))
    assert [(c.name, c.what) for c in found] == [("Marble", "moved")]
    assert changes_text(found) == "Marble moved"


def test_noise_below_the_rounding_is_not_seen_and_a_millimetre_is():
    assert changes(prints(), prints(noise=1e-9)) == []
    assert changes(prints(), prints(marble=(0.0, 0.0, 1.0 + 3e-9))) == []
    moved = changes(prints(), prints(marble=(0.0, 0.0, 1.001)))
    assert [(c.name, c.what) for c in moved] == [("Marble", "moved")]


def test_quantised_keeps_six_significant_digits():
    q = quantised([1.0000001, 123456.78, 1e-9, -0.0, 0.3333333333])
    assert q.tolist() == [1.0, 123457.0, 0.0, 0.0, 0.333333]
    assert np.signbit(q).sum() == 0


def test_light_material_settings_and_added_objects_are_named():
    base = prints()
    light = changes(base, prints(power=500.0))
    assert [(c.name, c.what) for c in light] == [("Lamp", "changed")]
    assert changes_text(light) == "Lamp's light settings changed"
    glass = changes(base, prints(ior=1.33))
    assert changes_text(glass) == "Marble's material or lens settings changed"
    settings = changes(base, prints(settings=dict(SETTINGS_VALUE, min_brightness=0.1)))
    assert changes_text(settings) == "the Lens Lights settings changed"
    added = changes(base, prints(extra_cube=True))
    assert changes_text(added) == "Cube is new (or shown)"
    gone = changes(prints(extra_cube=True), base)
    assert changes_text(gone) == "Cube is gone (or hidden)"


def test_shape_compared_only_when_asked():
    a = scene()
    b = scene()
    b.records[0] = dataclasses.replace(b.records[0], fit=SphereFit(True, np.zeros(3), 0.49))
    pa, pb = frame_prints(a), frame_prints(b)
    assert changes_text(changes(pa, pb)) == "Marble's mesh changed"
    assert changes(pa, pb, shapes=False) == []


def test_many_changes_name_three_and_count_the_rest():
    base = prints()
    now = prints(marble=(1, 0, 0), power=1.0, extra_cube=True, settings={})
    text = changes_text(changes(base, now))
    assert text == (
        "Cube is new (or shown), Lamp's light settings changed, Marble moved, 1 more change"
    )


def test_bake_inputs_keep_each_frames_prints_compactly():
    frames = [1, 2, 3, 4]
    per_frame = [prints(marble=(0.1 * f, 0, 1)) for f in frames]
    per_frame[2] = {k: v for k, v in per_frame[2].items() if k != "Table"}  # hidden on 3
    rec = BakeInputs.of_frames(frames, per_frame, render=True)
    assert len(rec.runs["Lamp"]) == 1  # still: one run
    assert len(rec.runs["Marble"]) == 4
    assert len(rec.runs["Table"]) == 3  # shown, hidden on 3, shown
    back = BakeInputs.from_text(rec.to_text())
    assert back == rec
    for f, p in zip(frames, per_frame, strict=True):
        assert back.at(f) == p
    assert back.covers(1) and back.covers(4) and not back.covers(5)
    assert BakeInputs.from_text("") is None
    assert BakeInputs.from_text('{"v": 0}') is None
    # a few tens of bytes per object and frame at most
    assert len(rec.to_text()) < 60 * 4 * 5


def test_stale_text_says_range_frame_what_and_what_to_do():
    found = changes(prints(), prints(marble=(0.3, 0, 1)))
    assert stale_text(1, 10, 5, found) == (
        "The bake (frames 1–10) is out of date at frame 5: Marble moved since it was baked; "
        "Bake again"
    )
    cam = changes({CAMERA: "X" + "0" * 24}, {CAMERA: "X" + "1" * 24})
    assert changes_text(cam) == "the camera changed"


def paths_of(marble=(0.0, 0.0, 1.0)):
    """The light's paths of `scene`: the lamp (a point at z = 4) to the marble and
    the marble's axis both ways (as a read holds them; the scene 30 across)."""
    read = SimpleNamespace(
        lens_candidates=np.array([True]),
        primary_lights=[PointPrimary((0.0, 0.0, 4.0), 1000.0, 0.1)],
        arrays=SimpleNamespace(center=np.array([marble], float), radius=np.array([0.5])),
        scene_size=30.0,
    )
    return light_paths(read)


def test_an_object_away_from_the_light_is_no_change_until_it_enters_it():
    paths = paths_of()
    base = frame_prints(scene(), paths=paths)
    # the cubes at x = 9, 12 (side 2) are far from the lamp → marble → table line
    assert base["Grid"][0] == "s" and base["Table"][0] == "S" and base["Marble"][0] == "S"
    far = frame_prints(scene(grid=(9, 14)), paths=paths)
    assert changes(base, far) == []
    # one of them under the marble, in the axis' capsule (1.05 R = 0.525 wide): counted
    inside = frame_prints(scene(grid=(1.4, 12)), paths=paths)
    assert [(c.name, c.what) for c in changes(base, inside)] == [("Grid", "moved")]
    # a cube 1.6 from the axis (its near face at 0.6 > 0.525) stays away
    beside = frame_prints(scene(grid=(1.6, 12)), paths=paths)
    assert changes(base, beside) == []
    # the table (in the light) counts wherever it goes; the glass marble too
    assert changes(base, frame_prints(scene(marble=(0, 0, 1.5)), paths=paths_of((0, 0, 1.5))))
