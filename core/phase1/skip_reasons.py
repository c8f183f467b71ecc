"""Why a light × sphere pair gets no lens light: a code, its details, and the
two texts made from them (the full reason, and the kind the report counts by).

Phase 1 stores the codes in its columnar skip table (`phase1.SkipTable.code`, a
scene of 100 000 opaque spheres skips 100 000 pairs per light); planning adds its
own (`planning.plan_lights`, the pre-selection). The report counts by code and
never reads a reason back out of its text.
"""

from __future__ import annotations

from enum import IntEnum


class Reason(IntEnum):
    # phase 1 (the numbers phase1.SkipTable.code holds; details: radius, ior, kt, other)
    INVALID_LIGHT = 0
    INVALID_SPHERE_NONFINITE = 1
    INVALID_SPHERE_RADIUS = 2
    OPAQUE = 3
    INVALID_KT = 4
    NOT_CONVERGING = 5
    LIGHT_INSIDE = 6
    LIGHT_ON_SURFACE = 7
    LIGHT_INSIDE_OTHER = 8
    LIGHT_ON_OTHER = 9
    TOTALLY_BLOCKED = 10
    OUT_OF_RANGE = 11
    OUTSIDE_EMISSION = 12  # outside a spot's cone, behind an area light
    # planning (details: relative, cutoff / limit / count)
    NO_LIGHT_THROUGH = 100
    DIMMER_THAN_CUTOFF = 101
    BEYOND_MAXIMUM = 102
    NOT_AMONG_STRONGEST = 103
    SUNK = 104  # the lens cuts into another surface (details: none)
    LINKED_LIGHT_IN_LAYER = 105  # the light's own linking, which a layer cannot keep


_KIND = {
    Reason.INVALID_LIGHT: "invalid light",
    Reason.INVALID_SPHERE_NONFINITE: "invalid sphere",
    Reason.INVALID_SPHERE_RADIUS: "invalid sphere",
    Reason.OPAQUE: "opaque",
    Reason.INVALID_KT: "invalid transmission",
    Reason.NOT_CONVERGING: "not a converging lens",
    Reason.LIGHT_INSIDE: "light inside the sphere",
    Reason.LIGHT_ON_SURFACE: "light on the sphere's surface",
    Reason.LIGHT_INSIDE_OTHER: "light inside another sphere",
    Reason.LIGHT_ON_OTHER: "light on another sphere",
    Reason.TOTALLY_BLOCKED: "totally blocked",
    Reason.OUT_OF_RANGE: "out of range",
    Reason.OUTSIDE_EMISSION: "outside the light's emission",
    Reason.NO_LIGHT_THROUGH: "no light gets through",
    Reason.DIMMER_THAN_CUTOFF: "dimmer than the cut-off",
    Reason.BEYOND_MAXIMUM: "beyond the maximum of {limit} lens lights",
    Reason.NOT_AMONG_STRONGEST: "not among the {count} strongest by flux",
    Reason.SUNK: "sunk into another surface",
    Reason.LINKED_LIGHT_IN_LAYER: "the light's own linking (no caustic layer keeps it)",
}

_TEXT = {
    Reason.INVALID_LIGHT: "invalid light (non-finite number)",
    Reason.INVALID_SPHERE_NONFINITE: "invalid sphere (non-finite number)",
    Reason.INVALID_SPHERE_RADIUS: "invalid sphere (radius {radius:g} ≤ 0)",
    Reason.OPAQUE: "opaque (kt = 0)",
    Reason.INVALID_KT: "invalid transmission (kt = {kt:g} outside 0…1)",
    Reason.NOT_CONVERGING: "not a converging lens (n = {ior:g} ≤ 1)",
    Reason.LIGHT_INSIDE_OTHER: "light inside sphere {other}",
    Reason.LIGHT_ON_OTHER: "light on the surface of sphere {other}",
    Reason.TOTALLY_BLOCKED: "totally blocked by sphere {other}",
    Reason.OUT_OF_RANGE: "out of range (the light's distance overflows floating point)",
    Reason.DIMMER_THAN_CUTOFF: "dimmer than the cut-off ({relative:.3g} < {cutoff:g})",
    Reason.OUTSIDE_EMISSION: (
        "outside the light's emission (beyond the spot's cone, behind the area light, "
        "or where its IES profile is dark)"
    ),
    Reason.LINKED_LIGHT_IN_LAYER: (
        "the light has light or shadow linking of its own, which a caustic layer cannot "
        "keep (lens lights keep it: choose a lens-light energy model)"
    ),
    Reason.SUNK: (
        "sunk into another surface (the lens cuts into it, as a marble sunk into the "
        "table): its light focuses inside that surface, which Lens Lights does not "
        "model; Cycles renders that caustic itself"
    ),
}


def reason_kind(code: int, details: dict | None = None) -> str:
    """What the report counts `code` by (numbers of the pair left out)."""
    return _KIND[Reason(code)].format(**(details or {}))


def reason_text(code: int, details: dict | None = None) -> str:
    """The full reason, with its details."""
    code = Reason(code)
    return _TEXT.get(code, _KIND[code]).format(**(details or {}))


class SkippedPair(tuple):
    """``(light name, lens name, reason text)`` — compares as that tuple — plus
    the reason's ``code`` and ``details``."""

    code: Reason
    details: dict

    def __new__(
        cls, light: str, lens: str, code: int, details: dict | None = None, text: str | None = None
    ):
        details = dict(details or {})
        self = super().__new__(cls, (light, lens, text or reason_text(code, details)))
        self.code, self.details = Reason(code), details
        return self

    def __getnewargs__(self):
        return (self[0], self[1], int(self.code), self.details, self[2])

    @property
    def kind(self) -> str:
        return reason_kind(self.code, self.details)
