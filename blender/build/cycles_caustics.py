"""Turn Cycles' own caustics of the lenses off on Generate and back on on Clear
(what and why: `core.plan.cycles_caustics`). The original values are kept in
``scene.lens_lights.replaced`` (one item per change), so Clear restores them
and Undo restores them with the rest of the scene."""

from __future__ import annotations

from ...core.caustic_layer.mesh_sources import members_of
from ...core.phase1.skip_reasons import Reason
from ...core.plan.cycles_caustics import (
    LENS_SETTINGS,
    SCENE,
    SCENE_SETTINGS,
    Change,
    describe,
    double_light_warning,
    kept_on_warning,
    linked_caster_warning,
    planned_changes,
    should_restore,
)

BEYOND = Reason.BEYOND_MAXIMUM


def _settings(owner):
    return getattr(owner, "cycles", None)  # None without the Cycles add-on


def scene_values(scene) -> dict:
    cy = _settings(scene)
    return {p: getattr(cy, p) for p, _ in SCENE_SETTINGS if cy is not None and hasattr(cy, p)}


def linked_casters(lens_objects) -> list[str]:
    """The lenses among `lens_objects` that are linked from a library with their
    Shadow Caustics caster on: their settings are the library's (a change to them is
    not saved with this file), so `replace` leaves them and the report says so."""
    return sorted(
        ob.name
        for ob in lens_objects
        if ob is not None
        and ob.library is not None
        and getattr(_settings(ob), "is_caustics_caster", False)
    )


def replace(scene, lens_objects, keep_scene: bool = False) -> list[Change]:
    """Turn the Cycles caustics of `lens_objects` (and the scene's, unless
    `keep_scene`) off; record each change. Returns the changes. Objects linked from a
    library are left as they are (`linked_casters`)."""
    lenses = {ob.name: ob for ob in lens_objects if ob is not None and ob.library is None}
    lens_values = {}
    for name, ob in lenses.items():
        cy = _settings(ob)
        if cy is not None:
            lens_values[name] = {p: getattr(cy, p) for p, _ in LENS_SETTINGS if hasattr(cy, p)}
    changes = planned_changes(scene_values(scene), lens_values, keep_scene)
    record = scene.lens_lights.replaced
    for c in changes:
        owner = scene if c.owner == SCENE else lenses[c.owner]
        setattr(_settings(owner), c.prop, c.new)
        item = record.add()
        item.object = None if c.owner == SCENE else owner
        item.prop, item.old, item.new = c.prop, c.old, c.new
    return changes


def restore(scene) -> list[Change]:
    """Put back what `replace` changed (each value still as it was set); forget the
    record. Returns the changes undone."""
    undone = []
    record = scene.lens_lights.replaced
    for item in record:
        owner = scene if item.object is None else item.object
        cy = _settings(owner)
        if cy is None or not hasattr(cy, item.prop):
            continue
        change = Change(
            SCENE if item.object is None else item.object.name, item.prop, item.old, item.new
        )
        if should_restore(change, getattr(cy, item.prop)):
            setattr(cy, item.prop, change.old)
            undone.append(change)
    record.clear()
    return undone


def after_build(scene, plan, read, made: int, layers: bool = False) -> tuple[str, bool]:
    """On Generate, once the lights are made: with Replace Cycles' Caustics on, turn
    Cycles' own caustics of the lenses that got lens lights off — but not the
    scene-wide switch while the scene holds glass Lens Lights does not model
    (``read.unmodelled_glass``, lenses sunk into another surface) or lenses Maximum
    Lens Lights left without a lens light (they would lose their caustic), which
    are then named;
    else say when they will be rendered twice. Returns the report's words ('' for
    nothing) and whether they are a warning; `layers`: caustic layers were made
    (the words name them)."""
    if not made:
        return "", False
    engine = scene.render.engine
    if scene.lens_lights.replace_cycles_caustics:
        lenses = {read.sphere_objects[p.source.lens] for p in plan.lights}
        if layers:  # the glass meshes traced as lenses: their layers replace Cycles'
            meshes = getattr(read, "mesh_lenses", [])
            lenses |= {
                meshes[k].orig
                for _light, key in getattr(read, "mesh_pairs", [])
                for k in members_of(key)
            }
        lenses = sorted(lenses, key=_name)
        glass = [name for name, _why in getattr(read, "unmodelled_glass", [])]
        # A lens sunk into another surface has no lens light: only Cycles' caustic.
        glass += sorted({s[1] for s in plan.skipped if s.code == Reason.SUNK})
        # Lenses left without a lens light by Maximum Lens Lights have only Cycles'.
        lit = {ob.name for ob in lenses}
        unlit = sorted({s[1] for s in plan.skipped if s.code == BEYOND} - lit)
        values = scene_values(scene)
        changes = replace(scene, lenses, keep_scene=bool(glass or unlit))
        by = "the caustic layers" if layers else "the lens lights"
        note = describe(changes, by=by)
        note += " (Clear restores them)" if note else ""
        lit_names = [ob.name for ob in lenses]
        warning = "; ".join(
            x
            for x in (
                kept_on_warning(engine, values, glass, lit_names, by, unlit),
                linked_caster_warning(engine, linked_casters(lenses), by),
            )
            if x
        )
        return "; ".join(x for x in (note, warning) if x), bool(warning)
    warning = double_light_warning(engine, scene_values(scene), made)
    return warning, bool(warning)


def _name(ob):
    return ob.name
