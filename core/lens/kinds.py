"""The kinds of lens by name. Adding a kind: a new file with a `base.Lens` subclass whose
constructor takes ``(center, radius, ior, absorption, *params)``, and one line here."""

from __future__ import annotations

from .ball import BallLens
from .base import Lens
from .mesh import MeshLens

LENS_KINDS: dict[str, type[Lens]] = {
    "ball": BallLens,
    "mesh": MeshLens,
}


def make_lens(kind: str, center, radius, ior, absorption=0.0, params=()) -> Lens:
    """The lens of ``kind`` (a key of `LENS_KINDS`) with these numbers."""
    try:
        cls = LENS_KINDS[kind]
    except KeyError:
        raise ValueError(f"unknown lens kind {kind!r} (known: {', '.join(LENS_KINDS)})") from None
    return cls(center, radius, ior, absorption, *params)
