"""Which of Cycles' own caustic paths to turn off so that a lens light's caustic
is not rendered twice (SPEC §9, last bullets), and the report's words (pure).

Cycles renders part of a lens's caustic itself: by path tracing when refractive
caustics are on (``scene.cycles.caustics_refractive``, default on; the glass
roughened by Filter Glossy, lights with a radius) and by manifold next-event
estimation (MNEE) when the lens is a caustics caster
(``object.cycles.is_caustics_caster``, with a caster-flagged receiver and light).
A lens light already adds that caustic, so with "Replace Cycles' Caustics" on,
Generate turns both off: scene-wide for path tracing (Blender has no per-object
switch for it), per lens for MNEE. But when the scene holds glass Lens Lights does
not model (a glass cylinder, a cube, an ellipsoid, thin-walled glass …), turning
path tracing's caustics off would take that glass's caustic (and, in Cycles, the
light it lets through onto what lies behind it) away: then the scene-wide switch
stays on and the report warns, naming that glass and the cost — Cycles' own caustic
of the lenses is added to their lens lights' (`kept_on_warning`). Every change is
a `Change` the Blender side records (`blender.build.cycles_caustics`); Clear puts
back each value that is still the one Generate set (a value the user changed since
is theirs).
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


def planned_changes(
    scene_values: dict, lens_values: dict, keep_scene: bool = False
) -> list[Change]:
    """The changes that turn Cycles' caustics of the lenses off: `scene_values`
    {prop: value} of the scene's Cycles settings, `lens_values` {lens name: {prop:
    value}} of each lens that got a lens light. Only values that differ;
    `keep_scene`: leave the scene-wide settings (glass Lens Lights does not model
    needs them)."""
    out = [
        Change(SCENE, p, bool(scene_values[p]), v)
        for p, v in SCENE_SETTINGS
        if not keep_scene and p in scene_values and bool(scene_values[p]) != v
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


def describe(changes, verb: str = "turned off", by: str = "the lens lights") -> str:
    """'Cycles' caustics turned off (the lens lights replace them): refractive
    caustics (scene), shadow caustics caster of Marble' ('' when nothing changed);
    `by`: what replaces them ("the caustic layers")."""
    if not changes:
        return ""
    parts = []
    for c in changes:
        what = _WHAT.get(c.prop, c.prop)
        parts.append(what if c.owner == SCENE else f"{what} of {c.owner}")
    return f"Cycles' own caustics {verb} ({by} replace them): " + ", ".join(parts)


def describe_restored(changes) -> str:
    """What Clear put back, in true words: 'Cycles' own caustics back as they were:
    refractive caustics (scene) on, shadow caustics caster of Marble on' ('' when
    nothing was put back)."""
    if not changes:
        return ""
    parts = []
    for c in changes:
        what = _WHAT.get(c.prop, c.prop)
        what = what if c.owner == SCENE else f"{what} of {c.owner}"
        parts.append(f"{what} {'on' if c.old else 'off'}")
    return "Cycles' own caustics back as they were: " + ", ".join(parts)


#: How many names a warning lists before "and N more".
NAMES_SHOWN = 3


def _names(names) -> str:
    names = list(names)
    shown = ", ".join(names[:NAMES_SHOWN])
    more = len(names) - NAMES_SHOWN
    return shown + (f" and {more} more" if more > 0 else "")


def kept_on_warning(
    engine: str, scene_values: dict, glass, lenses, by: str = "the lens lights", unlit=()
) -> str:
    """The warning when Replace Cycles' Caustics left path tracing's refractive
    caustics on for the `glass` (names) that Lens Lights does not model and the
    lenses Maximum Lens Lights left without a lens light (`unlit`), while the
    `lenses` (names) got lens lights (`by`: or caustic layers); '' when the switch
    is off anyway or the engine is not Cycles."""
    if not (glass or unlit) or engine != "CYCLES":
        return ""
    if not scene_values.get("caustics_refractive", False):
        return ""
    why = []
    if glass:
        why.append(f"Lens Lights does not model the glass of {_names(glass)}")
    if unlit:
        why.append(f"Maximum Lens Lights left {_names(unlit)} without a lens light")
    return (
        f"Cycles' refractive caustics left on: {' and '.join(why)}, whose caustics only "
        f"Cycles renders (turning them off would lose them); so Cycles also renders its "
        f"own caustic of {_names(lenses)} on top of {by}' (for lights with a radius, about "
        "20 % more light in those caustics: reports/real_scenes.md). To drop it, turn "
        "Render › Light Paths › Caustics › Refractive off (that glass then casts no caustic)"
    )


def linked_caster_warning(engine: str, names, by: str = "the lens lights") -> str:
    """The warning for lenses linked from a library with their Shadow Caustics caster
    on (`names`): Generate cannot turn it off for good (a linked object's settings
    are the library's, and a change to them is not saved), so Cycles renders their
    shadow caustic on top of `by`'; '' when there are none or the engine is not
    Cycles."""
    if not names or engine != "CYCLES":
        return ""
    return (
        f"Shadow caustics caster left on for {_names(names)}: linked from a library, "
        "its settings are the library's and a change would not be saved with this file, "
        f"so Cycles renders its shadow caustic on top of {by}'. Make it local or a "
        "library override (Object › Library Override) and Generate again, or turn its "
        "Shadow Caustics caster off in the library"
    )


def double_light_warning(engine: str, scene_values: dict, lights_made: int) -> str:
    """The warning when Cycles would render the lens lights' caustics a second time
    (Replace Cycles' Caustics off, refractive caustics on, Cycles)."""
    if lights_made and engine == "CYCLES" and scene_values.get("caustics_refractive", False):
        return (
            "Cycles' refractive caustics are on and Replace Cycles' Caustics is off: "
            "the lenses' caustics may be rendered twice"
        )
    return ""
