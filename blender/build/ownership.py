"""Which lens lights are still the extension's, and which are the user's (bpy).

The extension lists what it makes in the scene's registry
(`scene.lens_lights.created_objects`: the object and the name it was given, `register`)
and marks it (`object.lens_lights.is_lens_light`). An object is still the extension's
only while it is exactly what was made (`created_objects`): listed (the registry points
at the object itself, and Blender never hands that pointer to a copy), under the name
it was given, and in no collection but the extension's "Lens Lights". Everything else
that carries the mark is the user's:

* a copy: Shift+D and `Object.copy()` copy the custom properties (the mark, not the
  registry entry), Alt+D shares the light data too;
* a lens light renamed, or moved (or also linked) into a collection of the user's.

The user's lens lights are kept by Generate, Clear, Bake and live update (`keep_users`,
which Clear runs first). They stay marked, flagged ``kept`` ("yours" in the panel and
the report), so that the scene reader still skips them: a lens light is its lens' image,
never a primary light (else the next Generate would give it lens lights of its own
through the marble) nor a receiver. And they keep working as they did:

* linking: a kept light whose light or shadow linking collection is one of the
  extension's (a group "Lens link: group k", which the next Generate refills or
  removes) gets a collection of its own with the same members and states ("Kept link:
  …", unmarked: the user's, never removed, counted as the user's linking by
  `lights.user_linking`; kept lights with the same linking share one), so its lens
  stays out of it exactly as before;
* data: a light (or mesh) data an extension's object shares with a kept one (Alt+D)
  is left to the kept one and the extension's object gets a copy, so that live update
  and Clear never reach the user's light; the images and node trees the user's light
  uses stay (Clear removes marked images only once nothing uses them).
"""

from __future__ import annotations

import bpy

from ...core.report.message import kept_text
from .marks import (
    COLLECTION_MARK,
    KEPT_LINK,
    KEPT_LINK_PREFIX,
    LIGHTS_MARK,
    LINK_MARK,
    REFLECTION_MARK,
)

#: An object in one collection and listed in the registry (a pointer property holds
#: a user) has this many users; more: something else links it (another collection?).
PLAIN_USERS = 2


def register(scene, ob) -> None:
    """List `ob` (just made) in `scene`'s registry, under its name."""
    item = scene.lens_lights.created_objects.add()
    item.object = ob
    item.name = ob.name


def _members(scene) -> set:
    """Pointers of the objects in the extension's "Lens Lights" collection(s)."""
    out = set()
    for item in scene.lens_lights.created_collections:
        coll = item.collection
        if coll is not None and coll.get(COLLECTION_MARK) == LIGHTS_MARK:
            out.update(ob.as_pointer() for ob in coll.all_objects)
    return out


def _still_ours(ob, name: str, members: set) -> bool:
    """Is `ob`, listed under `name`, still exactly what the extension made?"""
    if ob is None:
        return False
    if not ob.lens_lights.is_lens_light:  # (a kept one is never listed: `keep_users`)
        return False
    if name and ob.name != name:  # renamed ("": a file from before the names)
        return False
    if ob.as_pointer() not in members:  # moved out of "Lens Lights"
        return False
    # users_collection scans every collection: asked only when something else holds it
    return ob.users <= PLAIN_USERS or all(
        c.get(COLLECTION_MARK) == LIGHTS_MARK for c in ob.users_collection
    )


def created_objects(scene) -> list:
    """The objects (lens lights and caustic layers) still exactly the extension's in
    `scene`: listed, marked, under their name, in its collection only."""
    members = _members(scene)
    out, seen = [], set()
    for item in scene.lens_lights.created_objects:
        ob = item.object
        if _still_ours(ob, item.name, members):
            ptr = ob.as_pointer()
            if ptr not in seen:
                seen.add(ptr)
                out.append(ob)
    return out


def kept_objects(scene) -> list:
    """The user's lens lights and layers in `scene`: marked, not the extension's (a
    copy, renamed or moved; or linked from a library, which cannot be flagged)."""
    ours = {ob.as_pointer() for ob in created_objects(scene)}
    return [
        ob for ob in scene.objects if ob.lens_lights.is_lens_light and ob.as_pointer() not in ours
    ]


def _membership(coll) -> frozenset:
    return frozenset(
        [
            (ob.as_pointer(), m.light_linking.link_state)
            for ob, m in zip(coll.objects, coll.collection_objects, strict=True)
        ]
        + [
            (c.as_pointer(), m.light_linking.link_state)
            for c, m in zip(coll.children, coll.collection_children, strict=True)
        ]
    )


def _copy_linking(coll):
    """A collection of the user's with `coll`'s members and their link states: one
    made for an earlier kept light with the same members, or a new one."""
    same = _membership(coll)
    for old in bpy.data.collections:
        if old.get(KEPT_LINK) and old.library is None and _membership(old) == same:
            return old
    names = [ob.name for ob in coll.objects] + [c.name for c in coll.children]
    shown = ", ".join(names[:3]) + (f" and {len(names) - 3} more" if len(names) > 3 else "")
    mine = bpy.data.collections.new(KEPT_LINK_PREFIX + shown)
    mine[KEPT_LINK] = True  # (not `COLLECTION_MARK`: the user's, never removed)
    for ob, member in zip(coll.objects, coll.collection_objects, strict=True):
        mine.objects.link(ob)
        mine.collection_objects[-1].light_linking.link_state = member.light_linking.link_state
    for child, link in zip(coll.children, coll.collection_children, strict=True):
        mine.children.link(child)
        mine.collection_children[-1].light_linking.link_state = link.light_linking.link_state
    return mine


def keep_users(scene) -> list:
    """Hand the user's lens lights in `scene` over to the user (see the module's
    docstring): taken off the registry, flagged ``kept``, their linking made their
    own, their data no longer shared with the extension's. Returns them (every kept
    one in the scene, kept now or before)."""
    settings = scene.lens_lights
    members = _members(scene)
    ours, theirs = {}, []
    for k, item in enumerate(settings.created_objects):
        ob = item.object
        if ob is None:
            continue
        if _still_ours(ob, item.name, members):
            ours[ob.as_pointer()] = ob
        elif ob.lens_lights.is_lens_light:
            theirs.append(k)
    for k in reversed(theirs):
        settings.created_objects.remove(k)  # renamed or moved: the user's now
    kept = [
        ob for ob in scene.objects if ob.lens_lights.is_lens_light and ob.as_pointer() not in ours
    ]
    copies: dict = {}  # one collection of the user's per collection of ours
    for ob in kept:
        if ob.library is not None:
            continue  # linked from a library: read-only, the library's to change
        if not ob.lens_lights.kept:
            ob.lens_lights.kept = True
        ll = ob.light_linking if ob.type == "LIGHT" else None
        for attr in ("receiver_collection", "blocker_collection") if ll is not None else ():
            coll = getattr(ll, attr)
            if coll is not None and coll.get(COLLECTION_MARK) == LINK_MARK:
                mine = copies.get(coll.as_pointer())
                if mine is None:
                    mine = copies[coll.as_pointer()] = _copy_linking(coll)
                setattr(ll, attr, mine)
    shared = {ob.data.as_pointer() for ob in kept if ob.data is not None}
    for ob in ours.values():
        if ob.data is not None and ob.data.as_pointer() in shared:
            ob.data = ob.data.copy()  # Alt+D: the data stays with the user's light
    return kept


def kept_note(scene, made=()) -> tuple[str, bool]:
    """The report's words on the user's lens lights (and layers) kept in `scene` beside
    the objects `made` now (`kept_text`: "Marble has 2 lens lights: … (made now) and …
    (yours, kept)"), and whether a lens has both (its caustic is painted twice)."""
    kept = kept_objects(scene)
    notes, doubled = [], False
    for word, is_light in (("lens light", True), ("caustic layer", False)):
        k = [(o.name, _on(o)) for o in kept if _is(o, is_light)]
        m = [(o.name, _on(o)) for o in made if _is(o, is_light)]
        doubled = doubled or bool({lens for _, lens in k} & {lens for _, lens in m})
        notes.append(kept_text(m, k, word))
    return "; ".join(n for n in notes if n), doubled


def _on(ob) -> str:
    """What a lens light is of (its lens), or what a caustic layer lies on (its
    receiver; a baked layer names none: its lenses then)."""
    meta = ob.lens_lights
    if ob.type == "LIGHT":
        return meta.source_lens
    return meta.receiver or meta.source_lens


def _is(ob, light: bool) -> bool:
    """A lens light (``light``) or a caustic layer (not its copy for EEVEE's reflections,
    which is part of it)."""
    if light:
        return ob.type == "LIGHT"
    return ob.type != "LIGHT" and not ob.get(REFLECTION_MARK, False)
