"""Which of Cycles' own caustic paths to turn off so that a lens light's caustic
is not rendered twice (SPEC §9, last bullets), and the report's words (pure).

Cycles renders part of a lens's caustic itself: by path tracing when refractive
caustics are on (``scene.cycles.caustics_refractive``, default on; the glass
roughened by Filter Glossy, lights with a radius) and by manifold next-event
estimation (MNEE) when the lens is a caustics caster
(``object.cycles.is_caustics_caster``, with a caster-flagged receiver and light).
A lens light already adds that caustic, so with "Replace Cycles' Caustics" on,
Generate turns both off: scene-wide for path tracing (Blender has no per-object
switch for it), per lens for MNEE. Every change is a `Change` the Blender side
records (`blender.build.cycles_caustics`); Clear puts back each value that is still
the one Generate set (a value the user changed since is theirs).
"""

from __future__ import annotations

from dataclasses import dataclass

#: The owner of a scene-wide setting in a `Change`.
SCENE = ""
#: (property, the value that replaces Cycles' caustic) on the scene's Cycles settings.
SCENE_SETTINGS = (("caustics_refractive", False),)
#: The same on each lens object's Cycles settings.
LENS_SETTINGS = (("is_caustics_caster", False),)

_WHAT = {
    "caustics_refractive": "refractive caustics (scene)",
    "is_caustics_caster": "shadow caustics caster",
}


@dataclass(frozen=True)
class Change:
    owner: str  # SCENE, or the lens object's name
    prop: str
    old: bool
    new: bool


def planned_changes(scene_values: dict, lens_values: dict) -> list[Change]:
    """The changes that turn Cycles' caustics of the lenses off: `scene_values`
    {prop: value} of the scene's Cycles settings, `lens_values` {lens name: {prop:
    value}} of each lens that got a lens light. Only values that differ."""
    out = [
        Change(SCENE, p, bool(scene_values[p]), v)
        for p, v in SCENE_SETTINGS
        if p in scene_values and bool(scene_values[p]) != v
    ]
    for name in sorted(lens_values):
        values = lens_values[name]
        out += [
            Change(name, p, bool(values[p]), v)
            for p, v in LENS_SETTINGS
            if p in values and bool(values[p]) != v
        ]
    return out


def should_restore(change: Change, current: bool) -> bool:
    """Whether Clear puts the old value back: only if nobody changed it since."""
    return bool(current) == change.new


def describe(changes, verb: str = "turned off") -> str:
    """'Cycles' caustics turned off: refractive caustics (scene), shadow caustics
    caster of Marble' ('' when nothing changed)."""
    if not changes:
        return ""
    parts = []
    for c in changes:
        what = _WHAT.get(c.prop, c.prop)
        parts.append(what if c.owner == SCENE else f"{what} of {c.owner}")
    return f"Cycles' own caustics {verb} (the lens lights replace them): " + ", ".join(parts)


def double_light_warning(engine: str, scene_values: dict, lights_made: int) -> str:
    """The warning when Cycles would render the lens lights' caustics a second time
    (Replace Cycles' Caustics off, refractive caustics on, Cycles)."""
    if lights_made and engine == "CYCLES" and scene_values.get("caustics_refractive", False):
        return (
            "Cycles' refractive caustics are on and Replace Cycles' Caustics is off: "
            "the lenses' caustics may be rendered twice"
        )
    return ""
