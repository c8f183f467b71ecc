"""Figures in a report's words (pure): a share of a whole as people read it.

Every report line that gives a share of flux uses `share_text`, so that none shows
floating-point dust ("1.3e-46 %") or a share nobody could act on.
"""

from __future__ import annotations

#: Below this share of the whole, a part is rounding dust (sums over rays and
#: texels in float64): not worth a word.
NEGLIGIBLE_SHARE = 1e-6
#: Below this share the figure reads "under 0.1 %".
SMALL_SHARE = 1e-3


def share_text(part: float, whole: float) -> str:
    """`part` of `whole` as people read it: "12 %", "0.4 %", "under 0.1 %"; "" when
    there is no whole or the part is negligible (under a millionth of it)."""
    if not whole > 0.0:
        return ""
    x = part / whole
    if not x >= NEGLIGIBLE_SHARE:
        return ""
    if x < SMALL_SHARE:
        return "under 0.1 %"
    return f"{100 * x:.2g} %" if x < 0.1 else f"{100 * x:.3g} %"
