"""Settings and bookkeeping stored in the .blend file.

* ``scene.lens_lights`` (:class:`LensLightsSceneSettings`): the generator's settings,
  the last run's figures, and the registry of what the extension created (objects
  and collections). Clear/regenerate remove only what is in the registry *and*
  carries the extension's mark, so a user's own lights — and even a user's
  duplicate of a lens light (it copies the mark but is not in the registry) — are
  never touched (the marks: `blender/build/marks.py`).
* ``object.lens_lights`` (:class:`LensLightsObjectSettings`): per object, whether it
  is a lens (Auto / Always / Never) and an IOR override; on the lights the
  extension creates, where they came from (primary light, lens, kind, full …).

The Live Update switch's update callback runs the hook that live update installs when it
registers (`set_live_update_hook`; `blender/commands/live_update.py`), so that this
module, below every other of the Blender side, imports none of them.
"""

import bpy
from bpy.props import (
    BoolProperty,
    CollectionProperty,
    EnumProperty,
    FloatProperty,
    IntProperty,
    PointerProperty,
    StringProperty,
)

from ...core.tiers import DEFAULT_ENERGY_MODEL, DEFAULT_SPOT_BLEND, energy_model_items

LENS_MODES = [
    ("AUTO", "Auto", "A lens when its material refracts (transmission > 0 and IOR > 1)"),
    (
        "ALWAYS",
        "Always",
        "Always a lens, whatever the material says "
        "(IOR from the override, else the material, else 1.5)",
    ),
    ("NEVER", "Never", "Never a lens; as a sphere it still blocks light"),
]

#: AUTO (the default: Exact profile in Cycles, Fitted otherwise) and the four tiers.
_ENERGY_MODEL_ITEMS = energy_model_items(
    include_auto=True
)  # keep a reference: Blender needs it alive


class LensLightsCreatedObject(bpy.types.PropertyGroup):
    """One object the extension made (`blender/build/ownership.py`): the object and the
    name it was given (renamed, it is the user's; "" in files from before the names)."""

    object: PointerProperty(type=bpy.types.Object)
    name: StringProperty()


class LensLightsCreatedCollection(bpy.types.PropertyGroup):
    collection: PointerProperty(type=bpy.types.Collection)


class LensLightsReplacedSetting(bpy.types.PropertyGroup):
    """One Cycles setting Generate changed (`cycles_caustics`): on the scene
    (``object`` None) or a lens, its property name, the user's value and the one set."""

    object: PointerProperty(type=bpy.types.Object)
    prop: StringProperty()
    old: BoolProperty()
    new: BoolProperty()


class LensLightsSceneSettings(bpy.types.PropertyGroup):
    energy_model: EnumProperty(
        name="Energy Model",
        items=_ENERGY_MODEL_ITEMS,
        default=DEFAULT_ENERGY_MODEL,
        description="What to build for each caustic: lens lights of one of four tiers, "
        "or caustic layers (emissive meshes on the receivers); how close each comes to "
        "the exact caustic, and which engines render it",
    )
    min_brightness: FloatProperty(
        name="Minimum Brightness",
        default=0.01,
        min=0.0,
        soft_max=1.0,
        precision=3,
        description=(
            "Leave out caustics (lens lights, or beams of a caustic layer) dimmer than "
            "this share of the primary light's irradiance at the lens"
        ),
    )
    max_lights: IntProperty(
        name="Maximum Lens Lights",
        default=64,
        min=1,
        soft_max=512,
        max=100000,
        description="Create at most this many lens lights, or caustics in the layers "
        "(the brightest)",
    )
    spot_blend: FloatProperty(
        name="Spot Blend",
        default=DEFAULT_SPOT_BLEND,
        min=0.0,
        max=1.0,
        description=(
            "Softness of the edge of each lens light's cone (Thesis and Physical; "
            "Fitted and Exact profile set their own)"
        ),
    )
    use_merge: BoolProperty(
        name="Merge Nearby Lens Lights",
        default=False,
        description=(
            "Make one lens light of the sources of one point light whose images lie "
            "within the merge distance and point the same way (it carries their "
            "summed power)"
        ),
    )
    merge_distance: FloatProperty(
        name="Merge Distance",
        default=0.05,
        min=0.0,
        soft_max=1.0,
        subtype="DISTANCE",
        precision=3,
        description="Sources whose images are this close may be merged",
    )
    replace_cycles_caustics: BoolProperty(
        name="Replace Cycles' Caustics",
        default=True,
        description=(
            "Turn Cycles' own caustics of the lenses off while they have lens lights or "
            "caustic layers (refractive caustics of the scene, shadow caustics of each "
            "lens), so that "
            "no caustic is rendered twice; Clear restores them. The scene's refractive "
            "caustics stay on (with a warning naming it) while it holds glass Lens "
            "Lights does not model (a glass cylinder, box, ellipsoid, thin-walled glass), "
            "which would lose its caustic"
        ),
    )
    live_update: BoolProperty(
        name="Live Update",
        default=False,
        description=(
            "Lens lights and caustic layers follow the scene: when lights, lenses or "
            "receivers move, on "
            "frame change and on every frame of a render (slower playback; the Caustic "
            "layer is rebuilt on each update). Off while a bake exists"
        ),
        update=lambda settings, context: _live_update_switched(settings, context),
    )

    # The last run's figures (shown in the panel).
    last_run: BoolProperty(default=False, options={"HIDDEN"})
    last_created: IntProperty(name="Created", default=0)
    last_layers: IntProperty(name="Caustic Layers", default=0)
    last_fallback: IntProperty(name="Fallback Spots", default=0)
    last_sources: IntProperty(name="Secondary Sources", default=0)
    last_skipped: IntProperty(name="Skipped Pairs", default=0)
    last_primaries: IntProperty(name="Lights", default=0)
    last_lenses: IntProperty(name="Lenses", default=0)
    last_left_out: IntProperty(name="Left Out", default=0)
    last_seconds: FloatProperty(name="Time (s)", default=0.0, precision=3)
    last_report: StringProperty(name="Last Report", default="")
    #: What the bake was baked from (`core.animation.bake_inputs.BakeInputs` as JSON;
    #: empty: no bake): the panel and renders say when the scene has changed under it.
    baked_from: StringProperty(default="", options={"HIDDEN"})

    created_objects: CollectionProperty(type=LensLightsCreatedObject, options={"HIDDEN"})
    created_collections: CollectionProperty(type=LensLightsCreatedCollection, options={"HIDDEN"})
    replaced: CollectionProperty(type=LensLightsReplacedSetting, options={"HIDDEN"})


class LensLightsObjectSettings(bpy.types.PropertyGroup):
    lens_mode: EnumProperty(
        name="Lens", items=LENS_MODES, default="AUTO", description="Whether this object is a lens"
    )
    use_ior_override: BoolProperty(
        name="Override IOR",
        default=False,
        description="Use this index of refraction instead of the material's",
    )
    ior_override: FloatProperty(
        name="IOR",
        default=1.5,
        min=1.0,
        soft_max=3.0,
        precision=4,
        description="Index of refraction used instead of the material's",
    )

    # Set on the lights the extension creates.
    is_lens_light: BoolProperty(default=False, options={"HIDDEN"})
    source_light: StringProperty(name="Primary Light")
    source_lens: StringProperty(name="Lens")
    receiver: StringProperty(name="Receiver", description="The object a caustic layer lies on")
    kind: StringProperty(name="Kind", description="Real, virtual or collimated")
    full: BoolProperty(name="Full", description="Nothing blocks the light on its way to the lens")
    unblocked_fraction: FloatProperty(name="Unblocked", precision=4)
    energy_model: StringProperty(
        name="Energy Model", description="The tier this light was made with"
    )
    relative_brightness: FloatProperty(name="Relative Brightness", precision=4)
    note: StringProperty(name="Note")
    # Set on a lens light (or layer) the user duplicated, renamed or moved: theirs, kept
    # by Generate, Clear and live update (`blender/build/ownership.py`).
    kept: BoolProperty(
        name="Yours",
        default=False,
        options={"HIDDEN"},
        description="A lens light you duplicated, renamed or moved: yours, kept by "
        "Generate and Clear, never a primary light",
    )


#: What the Live Update switch runs when it is flipped, (settings, context) → None: set
#: by live update when it registers, None before (the switch then only stores its value).
_live_update_hook = None


def set_live_update_hook(hook):
    """Install `hook(settings, context)` as the Live Update switch's update callback
    (None removes it)."""
    global _live_update_hook
    _live_update_hook = hook


def _live_update_switched(settings, context):
    if _live_update_hook is not None:
        _live_update_hook(settings, context)


_CLASSES = (
    LensLightsCreatedObject,
    LensLightsCreatedCollection,
    LensLightsReplacedSetting,
    LensLightsSceneSettings,
    LensLightsObjectSettings,
)


_register_classes, _unregister_classes = bpy.utils.register_classes_factory(_CLASSES)


def register():
    _register_classes()
    bpy.types.Scene.lens_lights = PointerProperty(type=LensLightsSceneSettings)
    bpy.types.Object.lens_lights = PointerProperty(type=LensLightsObjectSettings)


def unregister():
    del bpy.types.Object.lens_lights
    del bpy.types.Scene.lens_lights
    _unregister_classes()
