"""What the extension has made in a scene (for the operators' polls)."""

from __future__ import annotations

import bpy

from ..build.marks import COLLECTION_MARK, LAYER_MARK, LINK_MARK, PROFILE_MARK
from ..build.ownership import created_objects


def has_lens_lights(scene) -> bool:
    """Whether Clear would remove anything: a lens light the extension created in
    `scene` (listed in its registry and marked), a Cycles setting it changed, a
    linking collection or an empty "Lens Lights" collection it made, or one of its
    profile images nothing uses."""
    if scene is None:
        return False
    settings = scene.lens_lights
    if len(settings.replaced):
        return True  # Cycles settings to restore (`cycles_caustics`)
    if created_objects(scene):  # (a copy, renamed or moved lens light is the user's)
        return True
    for item in settings.created_collections:
        coll = item.collection
        mark = coll.get(COLLECTION_MARK) if coll is not None else None
        if mark == LINK_MARK or (mark is not None and not coll.objects and not coll.children):
            return True
    return any(
        img.get(COLLECTION_MARK) == PROFILE_MARK and img.users == 0 for img in bpy.data.images
    ) or any(m.get(COLLECTION_MARK) == LAYER_MARK and m.users == 0 for m in bpy.data.materials)
