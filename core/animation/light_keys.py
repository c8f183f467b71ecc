"""Which lens light is which from one update to the next (live update).

A lens light's key is what it was made from: its primary light's name, its lens'
object or instance name, its kind (real, virtual, collimated) and the tier it was
built with, plus an occurrence number for the rare repeats of one such tuple (counted
in order: plan order for the planned lights, creation order for the existing ones)
and a variant (the bake's Exact profile near field, another table geometry:
`blender/commands/bake.py` keys its tracks with these too).
`match` pairs the existing lights with the planned ones by key: those are updated
in place (the Blender object is kept, so selection, undo and the user's edits of
other properties survive), planned keys without a light are created, and lights
whose key is no longer planned (or that have no key: not a lens light) are removed.
"""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass(frozen=True)
class LightKey:
    light: str
    lens: str
    kind: str
    model: str
    index: int = 0  # the k-th light with the same (light, lens, kind, model, variant)
    variant: str = ""


def keys_of(items) -> list[LightKey | None]:
    """Keys of `items` ((light, lens, kind, model[, variant]) tuples, or None for an
    object that has none), numbering repeats in order."""
    seen: dict = {}
    out: list[LightKey | None] = []
    for item in items:
        if item is None:
            out.append(None)
            continue
        base = tuple(item)
        k = seen.get(base, 0)
        seen[base] = k + 1
        out.append(LightKey(*base[:4], index=k, variant=base[4] if len(base) > 4 else ""))
    return out


@dataclass
class Matching:
    update: list[tuple[int, int]] = field(default_factory=list)  # (existing, planned)
    create: list[int] = field(default_factory=list)  # planned indices
    remove: list[int] = field(default_factory=list)  # existing indices

    @property
    def same_set(self) -> bool:
        """Nothing to create or remove: the lights only change values."""
        return not self.create and not self.remove


def match(existing: list[LightKey | None], planned: list[LightKey]) -> Matching:
    """Pair `existing` with `planned` by key (see the module's docstring)."""
    where = {}
    for i, key in enumerate(existing):
        if key is not None and key not in where:
            where[key] = i
    out = Matching()
    used = set()
    for j, key in enumerate(planned):
        i = where.get(key)
        if i is None:
            out.create.append(j)
        else:
            out.update.append((i, j))
            used.add(i)
    out.remove = [i for i in range(len(existing)) if i not in used]
    return out
