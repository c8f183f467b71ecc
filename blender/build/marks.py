"""The marks and names every builder shares (no bpy): how the extension recognises what it
made, and what it calls it.

Everything the extension creates in a file carries the custom property
`COLLECTION_MARK`, whose value says what it is (the `*_MARK` values below). Clear
(`cleanup.clear`) removes only what is both listed in the scene's registry
(`scene.lens_lights.created_*`) and marked, or marked and used by nothing (images,
materials, actions); live update ignores the depsgraph updates of marked data (its own
edits). Lens light objects are marked by `object.lens_lights.is_lens_light` instead,
and are the extension's only while listed under their name in its collection
(`ownership`: a copy, a renamed or moved one is the user's, kept).

The builders (`lights`, `mask_nodes`, `layers`, `baked_layers`, and the bake's actions,
`blender/commands/bake.py`) mark; `cleanup` and the panel's poll
(`blender/ui/scene_state.py`) read the marks.
"""

#: Custom property set on every collection, image, material, mesh and action the
#: extension creates; its value is one of the marks below.
COLLECTION_MARK = "lens_lights_created"

#: The "Lens Lights" collection the lens lights and layers are in.
LIGHTS_MARK = "lights"
#: A light-linking collection (a group of lenses: "Lens link: group k", with
#: `LINK_GROUP`; one lens of a layer's fallback light: "Lens link: <lens>"; the layers'
#: fallback receivers: "Lens fallback: …").
LINK_MARK = "link"
#: An Exact profile's image (and a shadow mask's): removed once unused.
PROFILE_MARK = "profile"
#: A caustic layer's material or mesh: removed once unused.
LAYER_MARK = "layer"
#: A bake's action, or a baked layer's atlas image: removed once unused.
BAKE_MARK = "bake"

#: Object property of a caustic layer's reflection copy for EEVEE (`layers.create_reflection`).
REFLECTION_MARK = "lens_lights_reflection"

#: Object property of a water surface's caustic layer (and its reflection copy), Generate's
#: or baked (`water_stage`): live update rewrites these alone on a frame change.
WATER_MARK = "lens_lights_water"

#: Custom property of a group's linking collection: its group number (0-based).
LINK_GROUP = "lens_lights_link_group"

#: Custom property of a profile image: its cache key (`lights.profile_image`).
PROFILE_KEY = "lens_lights_profile_key"
#: On a linking collection that is a user light's own linking collection with its
#: lens lights' lenses excluded (`lights.link_lights`): (user collection, group).
USER_LINK = "lens_lights_user_link"

#: Names of what the builders make.
COLLECTION_NAME = "Lens Lights"
LINK_PREFIX = "Lens link: "
PROFILE_PREFIX = "Lens profile "
MASK_PREFIX = "Lens mask "
LAYER_PREFIX = "Lens caustic "
MATERIAL_PREFIX = "Lens caustic material "
INCLUDE_PREFIX = "Lens fallback: "
#: A user's kept lens light's own copy of the linking it had (`ownership`): unmarked, theirs.
KEPT_LINK_PREFIX = "Kept link: "
#: Custom property of such a collection (found again for the next kept light).
KEPT_LINK = "lens_lights_kept_link"
BAKE_IMAGE_PREFIX = "Lens caustic bake "
