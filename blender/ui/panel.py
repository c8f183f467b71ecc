"""The "Lens Lights" tab of the 3D View's sidebar (N panel).

Main panel: the Generate and Clear buttons, the settings (energy model — with the
tier it builds for the render engine and one line on what that tier trades —, minimum
brightness, maximum number of lens lights, spot blend, merging nearby lens lights,
live update)
and the last run's figures.
Sub-panel "Object": for the active mesh its lens mode and IOR override; for a lens
light where it came from, and for an Exact-profile one that the power Blender shows
for it is a sampling weight (the node tree holds the intensity); for a caustic layer
the receiver it lies on, the lenses and lights whose caustic it draws and its flux
(for its fallback spot, the glossy or transparent receivers it lights).

Long texts are wrapped to the region's width (`core.report.panel_text`); labels are
translatable (`iface_` with format placeholders; names and numbers are not
translated).
"""

import bpy
from bpy.app.translations import pgettext_iface as iface_

from ...core.animation.bake_inputs import LIVE_UPDATE_WAITS
from ...core.report.panel_text import chars_per_line, wrap
from ...core.tiers import CAUSTIC_LAYER, EXACT_PROFILE, TIER_LINES, resolve_energy_model
from ...core.tiers import TIERS as ENERGY_MODELS
from ..commands import bake_check

#: Shown for an Exact-profile lens light (issue 10): its Blender power is only what
#: Cycles samples it by; the node tree's emission carries the caustic's intensity.
EXACT_POWER_NOTE = (
    "The power shown in the light's properties is a sampling weight; "
    "its node tree holds the intensity"
)


def _width(context) -> int:
    """Characters per label line in the context's region (the sidebar)."""
    region = getattr(context, "region", None)
    prefs = getattr(context, "preferences", None)
    scale = prefs.system.ui_scale if prefs is not None else 1.0
    return chars_per_line(region.width if region is not None else None, scale)


def _lines(layout, text, width, **kw):
    """`text` (already translated) as labels wrapped to `width` characters."""
    for line in wrap(text, width):
        layout.label(text=line, translate=False, **kw)
        kw.pop("icon", None)  # only on the first line


#: The Object sub-panel's line on a lens light the user duplicated, renamed or moved.
KEPT_NOTE = (
    "Yours: a copy, or renamed or moved. Generate and Clear keep it as it is, "
    "live update leaves it alone"
)


def _figure(layout, text, value):
    """A label "text: value" with `text` translated."""
    layout.label(text=iface_(text).format(value), translate=False)


def _layer_figures(col, ob, meta, width):
    """A caustic layer (a mesh) or its fallback spot (a light) in the layer's terms:
    what it lies on or lights, whose caustic it draws, the flux it holds."""
    if ob.type == "LIGHT":  # the Fitted spot standing in on glossy/transparent receivers
        _figure(col, "Fallback spot on: {}", meta.receiver or "-")
        _lines(col, iface_("(glossy or transparent: no caustic layer shows there)"), width)
        _figure(col, "Light: {}", meta.source_light)
        _figure(col, "Lens: {}", meta.source_lens)
        _lines(col, meta.note, width)
        return
    _figure(col, "Caustic layer on: {}", meta.receiver or "-")
    if meta.source_lens:  # (a baked layer keeps its sources by key only)
        _lines(col, iface_("Lenses: {}").format(meta.source_lens), width)
        _lines(col, iface_("Lights: {}").format(meta.source_light), width)
    _figure(col, "Flux drawn: {} W", f"{meta.relative_brightness:.3g}")
    _lines(col, meta.note, width)


class VIEW3D_PT_lens_lights(bpy.types.Panel):
    bl_label = "Lens Lights"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Lens Lights"

    def draw(self, context):
        layout = self.layout
        settings = context.scene.lens_lights
        width = _width(context)
        row = layout.row(align=True)
        row.scale_y = 1.4
        row.operator("lens_lights.generate", icon="LIGHT_SPOT")
        row.operator("lens_lights.clear", icon="TRASH", text="")
        layout.operator("lens_lights.bake", icon="KEYTYPE_KEYFRAME_VEC")

        col = layout.column()
        col.use_property_split = True
        col.use_property_decorate = False
        col.prop(settings, "energy_model")
        # The tier that will be built (AUTO resolved for the engine) and what it trades.
        tier, warning = resolve_energy_model(settings.energy_model, context.scene.render.engine)
        info = col.column(align=True)
        info.label(
            text=iface_("Builds: {}").format(iface_(ENERGY_MODELS[tier].label)),
            icon="ERROR" if warning else "INFO",
            translate=False,
        )
        _lines(info, iface_(TIER_LINES.get(tier, "")), width)
        if warning:
            _lines(info, iface_(warning), width)
        col.prop(settings, "min_brightness")
        col.prop(settings, "max_lights")
        sub = col.row()
        sub.active = tier in ("THESIS", "PHYSICAL")  # the other tiers set their own blend
        sub.prop(settings, "spot_blend")
        row = col.row(heading="Merge Nearby")
        row.prop(settings, "use_merge", text="")
        sub = row.row()
        sub.active = settings.use_merge
        sub.prop(settings, "merge_distance", text="")
        col.prop(settings, "replace_cycles_caustics")
        baked = bake_check.has_bake(context.scene)
        sub = col.row()
        sub.active = not baked  # the bake's keys drive the lights: live update waits
        sub.prop(settings, "live_update")
        if baked and settings.live_update:
            _lines(col.column(align=True), iface_(LIVE_UPDATE_WAITS), width, icon="INFO")

        box = layout.box()
        if not settings.last_run:
            box.label(text="Not run yet", icon="INFO")
            return
        grid = box.grid_flow(columns=2, even_columns=True, align=True)
        if settings.last_layers:
            _figure(grid, "Caustic layers: {}", settings.last_layers)
        if settings.last_fallback:
            _figure(grid, "Fallback spots: {}", settings.last_fallback)
        _figure(grid, "Lens lights: {}", settings.last_created)
        _figure(grid, "Sources: {}", settings.last_sources)
        _figure(grid, "Lights: {}", settings.last_primaries)
        _figure(grid, "Lenses: {}", settings.last_lenses)
        _figure(grid, "Skipped pairs: {}", settings.last_skipped)
        _figure(grid, "Left out: {}", settings.last_left_out)
        _figure(box, "Time: {} s", f"{settings.last_seconds:.3f}")
        if settings.last_report:
            _lines(box.column(align=True), settings.last_report, width)
        if baked:
            _bake_status(layout, context, width)


def _bake_status(layout, context, width):
    """An out-of-date bake: what changed since, and Bake Again over its frames
    (`bake_check.status`: read once per depsgraph update or frame, not per redraw)."""
    status = bake_check.status(context)
    if status is None or not status.stale:
        return
    box = layout.box()
    _lines(box.column(align=True), status.text, width, icon="ERROR")
    op = box.operator("lens_lights.bake", text=iface_("Bake Again"), icon="FILE_REFRESH")
    op.frame_start, op.frame_end = status.first, status.last


class VIEW3D_PT_lens_lights_object(bpy.types.Panel):
    bl_label = "Object"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Lens Lights"
    bl_parent_id = "VIEW3D_PT_lens_lights"

    @classmethod
    def poll(cls, context):
        ob = context.object
        return ob is not None and (ob.type == "MESH" or ob.lens_lights.is_lens_light)

    def draw(self, context):
        layout = self.layout
        ob = context.object
        meta = ob.lens_lights
        width = _width(context)
        layout.label(text=ob.name, icon="OBJECT_DATA", translate=False)
        if meta.is_lens_light and meta.energy_model == CAUSTIC_LAYER:
            _layer_figures(layout.column(align=True), ob, meta, width)
            return
        if meta.is_lens_light:
            if meta.kept:  # a copy, renamed or moved: the user's (blender/build/ownership.py)
                _lines(layout.column(align=True), iface_(KEPT_NOTE), width, icon="INFO")
            col = layout.column(align=True)
            _figure(col, "From: {}", meta.source_light)
            _figure(col, "Lens: {}", meta.source_lens)
            col.label(
                text=iface_("Kind: {}, {}").format(
                    iface_(meta.kind), iface_("full") if meta.full else iface_("non-full")
                ),
                translate=False,
            )
            if not meta.full:
                _figure(col, "Unblocked: {}", f"{meta.unblocked_fraction:.3f}")
            tier = ENERGY_MODELS.get(meta.energy_model)
            col.label(
                text=iface_("Model: {}, brightness {}").format(
                    iface_(tier.label) if tier else meta.energy_model,
                    f"{meta.relative_brightness:.3g}",
                ),
                translate=False,
            )
            _lines(col, meta.note, width)
            if meta.energy_model == EXACT_PROFILE:
                _lines(layout.column(align=True), iface_(EXACT_POWER_NOTE), width, icon="INFO")
            return
        col = layout.column()
        col.use_property_split = True
        col.use_property_decorate = False
        col.prop(meta, "lens_mode")
        row = col.row(heading="Override IOR")
        row.prop(meta, "use_ior_override", text="")
        sub = row.row()
        sub.active = meta.use_ior_override
        sub.prop(meta, "ior_override", text="")


_CLASSES = (VIEW3D_PT_lens_lights, VIEW3D_PT_lens_lights_object)


register, unregister = bpy.utils.register_classes_factory(_CLASSES)
