"""Issue 28 item 7: a share in a report reads as people read it, never as
floating-point dust ("1.3e-46 %")."""

from core.shared.words import share_text


def test_shares_read_in_plain_figures():
    assert share_text(12.0, 100.0) == "12 %"
    assert share_text(96.0, 100.0) == "96 %"
    assert share_text(100.0, 100.0) == "100 %"
    assert share_text(0.4, 100.0) == "0.4 %"
    assert share_text(5.55, 100.0) == "5.5 %"  # two figures under 10 %
    assert share_text(0.05, 100.0) == "under 0.1 %"  # 5e-4


def test_dust_and_nothing_are_not_said():
    assert share_text(1.3e-48, 1.0) == ""  # the "1.3e-46 %"
    assert share_text(1.1e-16, 1.0) == ""  # 1 − 0.7999999999999999 / 0.8
    assert share_text(9.9e-7, 1.0) == ""
    assert share_text(0.0, 1.0) == ""
    assert share_text(1.0, 0.0) == ""  # no whole
