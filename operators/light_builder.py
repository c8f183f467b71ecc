"""Create and remove the lens lights (bpy).

Every lens light is a SPOT light object in the collection "Lens Lights" (created on
demand, under the scene's collection), placed, turned and shaped from a
`BlenderLight` (`addon/light_models.py`):

* location and rotation: the light's local −Z along `direction`;
* scale (k, k, 1) when the cone is narrower than Blender's 1° minimum;
* energy, colour, spot_size, spot_blend, radius (`shadow_soft_size`), and EEVEE's
  custom influence distance;
* light linking and shadow linking: both the receiver and the blocker collection
  are a collection "Lens link: <lens>" holding the lens with state EXCLUDE, so the
  light neither lights nor is blocked by its own lens (everything else as usual).
  One such collection per lens, shared by all of its lights. Objects instanced
  from one original share its linking: all instances of that original are
  excluded (Blender links objects, not instances).
* `object.lens_lights` records the origin: primary light, lens, kind, full,
  unblocked share, energy model, relative brightness, notes.

Everything created is listed in `scene.lens_lights.created_*` and marked
(`object.lens_lights.is_lens_light`, collection custom property
`properties.COLLECTION_MARK`); `clear` removes only what is both listed and marked.
"""
from __future__ import annotations

import math

import bpy
from mathutils import Vector

from .properties import COLLECTION_MARK

COLLECTION_NAME = "Lens Lights"
LINK_PREFIX = "Lens link: "


def _register_collection(settings, coll):
    item = settings.created_collections.add()
    item.collection = coll


def lights_collection(scene):
    """The extension's "Lens Lights" collection in `scene`, created if needed."""
    settings = scene.lens_lights
    for item in settings.created_collections:
        coll = item.collection
        if coll is not None and coll.get(COLLECTION_MARK) == "lights":
            if coll.name not in scene.collection.children:
                scene.collection.children.link(coll)
            return coll
    coll = bpy.data.collections.new(COLLECTION_NAME)
    coll[COLLECTION_MARK] = "lights"
    scene.collection.children.link(coll)
    _register_collection(settings, coll)
    return coll


def link_collection(scene, lens_object, cache):
    """The linking collection that excludes `lens_object` (one per lens, per run)."""
    coll = cache.get(lens_object.name)
    if coll is None:
        coll = bpy.data.collections.new(LINK_PREFIX + lens_object.name)
        coll[COLLECTION_MARK] = "link"
        coll.objects.link(lens_object)
        for member in coll.collection_objects:
            member.light_linking.link_state = "EXCLUDE"
        _register_collection(scene.lens_lights, coll)
        cache[lens_object.name] = coll
    return coll


def create_light(scene, planned, lens_object, collection, link_cache, model_name=""):
    """One lens light object from a `PlannedLight`."""
    bl = planned.light
    name = f"Lens light {planned.light_name} > {planned.lens_name}"
    data = bpy.data.lights.new(name, "SPOT")
    data.energy = bl.energy_w
    data.color = bl.color
    data.spot_size = math.radians(bl.spot_size_deg)
    data.spot_blend = bl.spot_blend
    data.shadow_soft_size = bl.radius
    data.use_custom_distance = True
    data.cutoff_distance = bl.cutoff_distance
    ob = bpy.data.objects.new(name, data)
    collection.objects.link(ob)
    ob.location = bl.location
    ob.rotation_mode = "QUATERNION"
    ob.rotation_quaternion = Vector(bl.direction).to_track_quat("-Z", "Y")
    ob.scale = (bl.scale_xy, bl.scale_xy, 1.0)
    if lens_object is not None:
        link = link_collection(scene, lens_object, link_cache)
        ob.light_linking.receiver_collection = link
        ob.light_linking.blocker_collection = link
    meta = ob.lens_lights
    meta.is_lens_light = True
    meta.source_light = planned.light_name
    meta.source_lens = planned.lens_name
    meta.kind = bl.kind
    meta.full = bool(planned.source.full)
    meta.unblocked_fraction = float(planned.source.unblocked_fraction)
    meta.energy_model = model_name or bl.model
    meta.relative_brightness = bl.relative_brightness
    meta.note = bl.note
    item = scene.lens_lights.created_objects.add()
    item.object = ob
    return ob


def build(scene, plan, lens_objects, progress=None):
    """Create the planned lights; `lens_objects[i]`: original object of sphere i.
    `progress(k)` is called with the number of lights made so far."""
    collection = lights_collection(scene)
    cache: dict = {}
    made = []
    for k, planned in enumerate(plan.lights):
        made.append(create_light(scene, planned, lens_objects[planned.source.lens],
                                 collection, cache))
        if progress is not None and k % 16 == 15:
            progress(k + 1)
    return made


def created_objects(scene):
    """The extension's lights in `scene` (listed in the registry and marked)."""
    out = []
    for item in scene.lens_lights.created_objects:
        ob = item.object
        if ob is not None and ob.lens_lights.is_lens_light and ob not in out:
            out.append(ob)
    return out


def clear(scene) -> int:
    """Remove every lens light the extension created in `scene` (and its linking
    collections; the "Lens Lights" collection too once nothing else is in it).
    Returns how many lights were removed. Nothing else is touched."""
    settings = scene.lens_lights
    objects = created_objects(scene)
    datas = {ob.data for ob in objects if ob.data is not None}
    removed = len(objects)
    if objects:
        bpy.data.batch_remove(objects)          # one pass: fast for many lights
    orphans = [d for d in datas if d.users == 0]
    if orphans:
        bpy.data.batch_remove(orphans)
    settings.created_objects.clear()
    keep = []
    for item in settings.created_collections:
        coll = item.collection
        if coll is None or coll.get(COLLECTION_MARK) is None:
            continue
        if coll.get(COLLECTION_MARK) == "link" or (not coll.objects and not coll.children):
            bpy.data.collections.remove(coll)
        else:
            keep.append(coll)       # the user put something of theirs in it
    settings.created_collections.clear()
    for coll in keep:
        _register_collection(settings, coll)
    return removed
