"""The stable keys and matching of live update (`core/animation/light_keys.py`), without Blender."""

from core.animation.light_keys import LightKey, keys_of, match


def test_repeats_of_one_tuple_are_numbered_in_order():
    keys = keys_of([("A", "S", "real", "FITTED"), None, ("A", "S", "real", "FITTED")])
    assert keys == [
        LightKey("A", "S", "real", "FITTED", 0),
        None,
        LightKey("A", "S", "real", "FITTED", 1),
    ]


def test_matching_keeps_updates_creates_new_and_removes_vanished():
    old = keys_of(
        [
            ("A", "S1", "real", "PHYSICAL"),
            ("B", "S1", "real", "PHYSICAL"),
            None,  # e.g. a caustic layer: never matched
            ("A", "S2", "virtual", "PHYSICAL"),
        ]
    )
    new = keys_of(
        [
            ("A", "S2", "virtual", "PHYSICAL"),  # existing #3
            ("C", "S1", "real", "PHYSICAL"),  # new
            ("A", "S1", "real", "PHYSICAL"),  # existing #0
        ]
    )
    m = match(old, new)
    assert sorted(m.update) == [(0, 2), (3, 0)]
    assert m.create == [1]
    assert m.remove == [1, 2]
    assert not m.same_set


def test_a_tier_change_or_a_kind_change_is_another_light():
    old = keys_of([("A", "S", "real", "PHYSICAL")])
    assert match(old, keys_of([("A", "S", "real", "FITTED")])).remove == [0]
    assert match(old, keys_of([("A", "S", "virtual", "PHYSICAL")])).create == [0]


def test_same_keys_are_all_updates():
    keys = keys_of([("A", "S", "real", "X"), ("A", "S", "real", "X"), ("B", "S", "real", "X")])
    m = match(keys, keys)
    assert m.update == [(0, 0), (1, 1), (2, 2)] and m.same_set


def test_duplicate_existing_keys_keep_one_and_remove_the_rest():
    k = LightKey("A", "S", "real", "X")
    m = match([k, k], [k])
    assert m.update == [(0, 0)] and m.remove == [1] and m.create == []
