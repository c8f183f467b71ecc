"""Clear: remove what the extension made in a scene (bpy), and nothing else.

This module sits above every builder, so that it may know what each one leaves: the
lens lights and their data (`lights`, with their embedded node trees), the linking
collections and the "Lens Lights" collection, the profile and shadow mask images
(`lights`, `mask_nodes`), the caustic layers' materials (`layers`), the baked layers'
atlas images (`baked_layers`) and the bake's actions (`blender/commands/bake.py`).
What is removed is what is still exactly the extension's (listed in the scene's
registry under its name, marked, in its collection: `ownership`), or marked and used
by nothing; the user's copies, renamed and moved lens lights are kept (`ownership.keep_users`).
"""

from __future__ import annotations

import bpy

from .baked_layers import remove_unused_bake_images
from .layers import remove_unused_layer_materials
from .lights import remove_unused_profile_images
from .marks import BAKE_MARK, COLLECTION_MARK, LINK_MARK
from .ownership import created_objects, keep_users


def clear(scene) -> int:
    """Remove every lens light the extension created in `scene` (and its linking
    collections; the "Lens Lights" collection too once nothing else is in it; the
    profile images, layer materials, bake actions and baked images nothing uses any
    more). Returns how many lights were removed. Nothing else is touched: the user's
    lens lights (copies, renamed or moved ones: `ownership`) are kept, working, with
    what they use."""
    settings = scene.lens_lights
    keep_users(scene)
    objects = created_objects(scene)
    refs: dict = {}
    for ob in objects:
        if ob.data is not None:
            refs[ob.data] = refs.get(ob.data, 0) + 1
    # a datablock only these objects use goes with them, in the same pass (each
    # batch_remove scans the whole file: slow with many objects); one that something
    # else uses too (the user linked it) stays
    owned = [d for d, k in refs.items() if d.users == k]
    removed = len(objects)
    if objects:
        bpy.data.batch_remove(objects + owned)  # with their embedded node trees
    remove_unused_profile_images()
    remove_unused_layer_materials()
    remove_unused_bake_actions()
    settings.created_objects.clear()
    settings.baked_from = ""  # no bake left (`blender/commands/bake_check.py`)
    keep = []
    for item in settings.created_collections:
        coll = item.collection
        if coll is None or coll.get(COLLECTION_MARK) is None:
            continue
        if coll.get(COLLECTION_MARK) == LINK_MARK or (not coll.objects and not coll.children):
            bpy.data.collections.remove(coll)
        else:
            keep.append(coll)  # the user put something of theirs in it
    settings.created_collections.clear()
    for coll in keep:
        settings.created_collections.add().collection = coll
    return removed


def remove_unused_bake_actions() -> int:
    """Remove the bake's actions (marked) that nothing uses, and the baked layers'
    images nothing uses. Returns how many actions were removed."""
    unused = [a for a in bpy.data.actions if a.get(COLLECTION_MARK) == BAKE_MARK and a.users == 0]
    if unused:
        bpy.data.batch_remove(unused)
    remove_unused_bake_images()
    return len(unused)
