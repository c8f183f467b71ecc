"""The bake's pure part (core/animation/light_tracks.py): keys, tracks over frames, visibility
keys, the D/R slice grid and its texture rows, frame ranges and output names.
Expected values are worked out by hand in each test."""

import math

import numpy as np
import pytest

from core.animation import light_tracks as bp
from core.animation.light_keys import LightKey, keys_of


def fl(key, x, energy=1.0, q=(1.0, 0.0, 0.0, 0.0), d_over_r=math.nan, group=None):
    return bp.FrameLight(
        key,
        dict(location=(x, 0.0, 0.0), rotation_quaternion=q, energy=energy),
        profile_group=group,
        d_over_r=d_over_r,
    )


def test_bake_keys_are_live_updates_keys_with_a_variant():
    # the bake keys its tracks with `light_keys.LightKey` (one identity for both)
    items = [
        ("Lamp", "Marble", "real", "EXACT_PROFILE", ""),
        ("Lamp", "Marble", "real", "EXACT_PROFILE", "near"),
        ("Lamp", "Marble", "real", "EXACT_PROFILE", ""),
        ("Lamp", "Marble", "virtual", "EXACT_PROFILE", ""),
        ("Lamp", "Grid/Ball#2", "real", "EXACT_PROFILE", ""),
    ]
    a, near, again, virtual, other = keys_of(items)
    assert a == LightKey("Lamp", "Marble", "real", "EXACT_PROFILE")
    assert near == LightKey("Lamp", "Marble", "real", "EXACT_PROFILE", variant="near")
    assert near != a and virtual != a and other != a
    assert again == LightKey("Lamp", "Marble", "real", "EXACT_PROFILE", index=1)  # a repeat
    # the next frame's keys equal this frame's: one track per key
    per_frame = [[fl(k, float(i)) for i, k in enumerate(keys_of(items))] for _ in range(2)]
    tracks = bp.build_tracks([1, 2], per_frame)
    assert [t.key for t in tracks] == [a, near, again, virtual, other]
    assert all(t.present.all() for t in tracks)
    # four-tuples (live update's existing lights) get the empty variant
    assert keys_of([("Lamp", "Marble", "real", "EXACT_PROFILE")]) == [a]


def test_near_slices_put_a_row_on_the_receiver():
    # the near table (512 rows, 0.25 … 31 R shifted) has a row centre on the
    # receiver: (M ln(z/h_min)/ln(h_max/h_min) − 0.5) is an integer
    z = 1.0 + 0.5 * 0.37  # a receiver 1.185 R from the lens centre
    h_min = bp.slice_h_min(z)
    y = 512 * math.log(z / h_min) / math.log(31.0 / 0.25) - 0.5
    assert y == pytest.approx(round(y), abs=1e-6)
    assert 0.25 / 1.01 < h_min < 0.25 * 1.01  # shifted by under a row (0.95 %)
    assert bp.slice_h_min(None) == pytest.approx(0.2)  # the far table's
    with pytest.raises(ValueError, match="receiver"):
        bp.profile_slice_table(4.0, 1.5, True)


def test_tracks_hold_each_frames_tables_like_the_values():
    # the near table and the mask per frame (role → (key, pixels) or None); an absent
    # frame holds its nearest present frame's, a present frame without one holds None
    t1, t2, m = ("n1", np.zeros(1)), ("n2", np.ones(1)), ("m", np.ones(2))
    per_frame = [
        [bp.FrameLight("a", {}, tables={"near": t1, "mask": m})],
        [],
        [bp.FrameLight("a", {}, tables={"near": t2})],
    ]
    (a,) = bp.build_tracks([1, 2, 3], per_frame)
    assert [k for k, _ in a.tables["near"]] == ["n1", "n1", "n2"]
    assert a.tables["mask"] == [m, m, None]


def test_tracks_carry_the_numbers_a_frame_records_beyond_the_channels():
    # a node tree's numbers, recorded under its Value nodes' names: held like the
    # channels, missing on a present frame: 0 (the bake keys a missing tilt plane
    # `lights.NO_PLANE` itself, from the frame's recorded plane count)
    per_frame = [
        [bp.FrameLight("a", {"Lens tilt 0 nx": 0.25, "Lens bake mask scale": 2.0})],
        [],
        [bp.FrameLight("a", {"Lens tilt 0 nx": -0.5})],
    ]
    (a,) = bp.build_tracks([1, 2, 3], per_frame)
    assert a.values["Lens tilt 0 nx"][:, 0].tolist() == [0.25, 0.25, -0.5]
    assert a.values["Lens bake mask scale"][:, 0].tolist() == [2.0, 2.0, 0.0]


def test_tracks_hold_the_nearest_present_values_and_mark_absence():
    # key "a" on frames 10, 11, 13; "b" only on frame 12
    per_frame = [[fl("a", 1.0)], [fl("a", 2.0)], [fl("b", 9.0, energy=5.0)], [fl("a", 4.0)]]
    a, b = bp.build_tracks([10, 11, 12, 13], per_frame)
    assert (a.key, b.key) == ("a", "b")
    assert a.present.tolist() == [True, True, False, True]
    # frame 12 holds the nearest present frame's values (11 and 13 are equally near:
    # the earlier one)
    assert a.values["location"][:, 0].tolist() == [1.0, 2.0, 2.0, 4.0]
    assert b.present.tolist() == [False, False, True, False]
    assert b.values["energy"][:, 0].tolist() == [5.0] * 4
    assert b.first == 2
    assert a.values["spot_blend"].shape == (4, 1)  # missing channels: zeros
    assert not a.values["spot_blend"].any()


def test_a_key_twice_on_one_frame_is_an_error():
    with pytest.raises(ValueError, match="two lens lights with the key 'a' on frame 3"):
        bp.build_tracks([3], [[fl("a", 0.0), fl("a", 1.0)]])


def test_quaternions_take_the_sign_nearest_the_previous_frame():
    q = np.array([[1, 0, 0, 0], [-0.99, -0.1, 0, 0], [0.98, 0.2, 0, 0]], dtype=float)
    out = bp.continuous_quaternions(q)
    assert out.tolist() == [[1, 0, 0, 0], [0.99, 0.1, 0, 0], [0.98, 0.2, 0, 0]]


def test_visibility_keys_only_where_presence_changes():
    frames = [1, 2, 3, 4, 5]
    assert bp.visibility_keys(frames, [True] * 5) == [(1, False)]
    assert bp.visibility_keys(frames, [False, True, True, False, True]) == [
        (1, True),
        (2, False),
        (4, True),
        (5, False),
    ]
    assert bp.single_frame_visibility(3, 1, 5) == [(2, True), (3, False), (4, True)]
    assert bp.single_frame_visibility(1, 1, 5) == [(1, False), (2, True)]
    assert bp.single_frame_visibility(5, 1, 5) == [(4, True), (5, False)]


def test_slice_grid_is_anchored_geometric_and_capped():
    # 1.04^k nodes around 4.0 … 4.8: k from floor(ln 4 / ln 1.04) = 35 to
    # ceil(ln 4.8 / ln 1.04) = 40
    grid = bp.slice_grid([4.0, 4.8, 4.4, math.inf])
    k = np.round(np.log(grid) / math.log(1.04)).astype(int)
    assert k.tolist() == list(range(35, 41))
    assert grid[0] <= 4.0 and grid[-1] >= 4.8
    # a still lens: its own D/R, one slice
    assert bp.slice_grid([4.0, 4.0]).tolist() == [4.0]
    # a wide range: the ratio is squared until at most MAX_SLICES nodes
    wide = bp.slice_grid([2.0, 200.0])
    assert len(wide) <= bp.MAX_SLICES
    assert wide[0] <= 2.0 and wide[-1] >= 200.0
    with pytest.raises(ValueError, match="no finite D/R"):
        bp.slice_grid([math.nan])


def test_slice_coordinate_is_linear_in_log_d_over_r():
    grid = [2.0, 4.0, 8.0]
    s = bp.slice_coordinate([2.0, 4.0, math.sqrt(8.0), 8.0, 1.5, 20.0], grid)
    assert np.allclose(s, [0.0, 1.0, 0.5, 2.0, 0.0, 2.0])
    assert bp.slice_coordinate([3.0], [4.0]).tolist() == [0.0]


def test_slice_rows_stay_inside_their_slice():
    # 3 slices of 4 rows: slice 1 spans v_img 1/3 … 2/3; row centres at
    # (1 + (j + 0.5)/4)/3
    assert bp.slice_row(0.0, 1, 3, 4) == pytest.approx((1 + 0.125) / 3)
    assert bp.slice_row(1.0, 1, 3, 4) == pytest.approx((1 + 0.875) / 3)
    assert bp.slice_row(0.5, 1, 3, 4) == pytest.approx(1.5 / 3)
    stacked = bp.stack_slices([np.zeros((4, 2)), np.ones((4, 2))])
    assert stacked.shape == (8, 2) and stacked[:4].sum() == 0 and stacked[4:].min() == 1
    with pytest.raises(ValueError, match="different sizes"):
        bp.stack_slices([np.zeros((4, 2)), np.zeros((3, 2))])


def test_profile_slice_is_generates_normalised_table():
    """A slice is Generate's table for that D/R: with energy = 2 × beam flux the
    texture is intensity / (energy/4π) = intensity / (flux/2π); so ∫ texture dΩ
    over a far row is 2π (all of the beam's flux within 90°)."""
    table = bp.profile_slice_table(4.0, 1.5, False)
    from core.tiers.exact_profile import PROFILE_ANGLES, PROFILE_GAMMA_MAX_DEG

    gmax = math.radians(PROFILE_GAMMA_MAX_DEG)
    edges = gmax * (np.arange(PROFILE_ANGLES + 1) / PROFILE_ANGLES) ** 2
    omega = np.diff(2 * math.pi * (1 - np.cos(edges)))
    total = float((table[-1].astype(float) * omega).sum())  # last row: 30 R away
    assert total == pytest.approx(2 * math.pi, rel=0.03)


def test_parse_frames():
    assert bp.parse_frames("1-120") == (1, 120)
    assert bp.parse_frames("7") == (7, 7)
    assert bp.parse_frames(" 3..5 ") == (3, 5)
    assert bp.parse_frames("-2-4") == (-2, 4)
    with pytest.raises(ValueError, match="ends before it starts"):
        bp.parse_frames("5-2")
    with pytest.raises(ValueError, match="expected a frame range"):
        bp.parse_frames("a-b")


def test_frame_path_pads_the_last_run_of_hashes():
    assert bp.frame_path("out/shot_####.png", 7) == "out/shot_0007.png"
    assert bp.frame_path("a#b_##.exr", 123) == "a#b_123.exr"
    assert bp.frame_path("still.png", 4) == "still.png"
    assert bp.frame_path("f_###.png", -3) == "f_-003.png"


def profile_track(key, d_over_r, lens="Marble", present=None):
    per = [
        [fl(key, 0.0, d_over_r=d, group=(lens, 1.5, False))] if p else []
        for d, p in zip(d_over_r, present or [True] * len(d_over_r), strict=True)
    ]
    return bp.build_tracks(range(len(d_over_r)), per)[0]


def test_profile_groups_share_a_lens_image_unless_a_key_is_far_off():
    a = profile_track("a", [4.0, 4.4, 4.8])
    b = profile_track("b", [4.5, 5.0, 6.0])
    c = profile_track("c", [1e6, 1e6, 1e6])  # a sun
    other = profile_track("d", [4.0, 4.0, 4.0], lens="Other")
    groups = bp.profile_groups([a, b, other])
    assert sorted(groups) == [("Marble", 1.5, False), ("Other", 1.5, False)]
    keys, grid = groups["Marble", 1.5, False]
    assert keys == ["a", "b"] and grid[0] <= 4.0 and grid[-1] >= 6.0
    assert groups["Other", 1.5, False][1].tolist() == [4.0]
    # 4 … 10⁶ needs far more than MAX_SLICES nodes at 1.04: one group per key
    groups = bp.profile_groups([a, b, c])
    assert sorted(groups, key=str) == sorted([("Marble", 1.5, False, k) for k in "abc"], key=str)
    assert groups["Marble", 1.5, False, "c"][1].tolist() == [1e6]
    assert bp.grid_size([4.0, 4.8]) == 6  # 1.04^35 … 1.04^40
    assert bp.grid_size([5.0]) == 1


def test_absent_frames_do_not_widen_the_grid():
    # the key's held values on absent frames repeat present ones: same range
    t = profile_track("a", [4.0, 9.0, 4.8], present=[True, False, True])
    ((keys, grid),) = bp.profile_groups([t]).values()
    assert grid[-1] < 5.0


def test_bake_message():
    fig = dict(objects=2, energy_model="EXACT_PROFILE", frame_start=1, frame_end=100)
    fig.update(frames=100, seconds=12.34, images=1)
    assert bp.bake_message(fig) == (
        "Baked 2 lens lights over frames 1–100 (100 frames, 12.3 s); 1 profile image"
    )
    fig.update(mask_images=2)
    assert bp.bake_message(fig).endswith("; 1 profile image; 2 shadow mask images")
    fig.update(mask_images=0)
    fig.update(objects=1, energy_model="CAUSTIC_LAYER", images=0)
    assert (
        bp.bake_message(fig)
        == "Baked 1 caustic layer object over frames 1–100 (100 frames, 12.3 s)"
    )


def test_a_finer_profile_step_takes_more_slices():
    a = profile_track("a", [4.0, 4.4, 4.8])
    ((_, grid4),) = bp.profile_groups([a]).values()
    ((_, grid2),) = bp.profile_groups([a], ratio=1.02).values()
    # 1.04^35 … 1.04^40 (6 nodes); 1.02^70 … 1.02^80 (11 nodes)
    assert len(grid4) == 6 and len(grid2) == 11
    assert np.allclose(np.log(grid2) / math.log(1.02), np.arange(70, 81))
