"""The "Lens Lights" tab of the 3D View's sidebar (N panel).

Main panel: the Generate and Clear buttons, the settings (energy model — with the
tier it builds for the render engine and one line on what that tier trades —, minimum
brightness, maximum number of lens lights, spot blend, merging nearby lens lights)
and the last run's figures.
Sub-panel "Object": for the active mesh its lens mode and IOR override; for a lens
light where it came from.
"""
import bpy

from ..addon.tiers import TIER_LINES, resolve_energy_model
from ..addon.tiers import TIERS as ENERGY_MODELS

#: Characters per line when the last report is wrapped in the panel.
WRAP = 42


def _wrap(text, width=WRAP):
    lines, line = [], ""
    for word in text.split():
        if line and len(line) + 1 + len(word) > width:
            lines.append(line)
            line = word
        else:
            line = f"{line} {word}" if line else word
    if line:
        lines.append(line)
    return lines


class VIEW3D_PT_lens_lights(bpy.types.Panel):
    bl_label = "Lens Lights"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Lens Lights"

    def draw(self, context):
        layout = self.layout
        settings = context.scene.lens_lights
        row = layout.row(align=True)
        row.scale_y = 1.4
        row.operator("lens_lights.generate", icon="LIGHT_SPOT")
        row.operator("lens_lights.clear", icon="TRASH", text="")

        col = layout.column()
        col.use_property_split = True
        col.use_property_decorate = False
        col.prop(settings, "energy_model")
        # The tier that will be built (AUTO resolved for the engine) and what it trades.
        tier, warning = resolve_energy_model(settings.energy_model, context.scene.render.engine)
        info = col.column(align=True)
        info.label(text=f"Builds: {ENERGY_MODELS[tier].label}", icon="ERROR" if warning else "INFO")
        for line in _wrap(TIER_LINES.get(tier, "")) + (_wrap(warning) if warning else []):
            info.label(text=line)
        col.prop(settings, "min_brightness")
        col.prop(settings, "max_lights")
        sub = col.row()
        sub.active = tier in ("THESIS", "PHYSICAL")     # the other tiers set their own blend
        sub.prop(settings, "spot_blend")
        row = col.row(heading="Merge nearby")
        row.prop(settings, "use_merge", text="")
        sub = row.row()
        sub.active = settings.use_merge
        sub.prop(settings, "merge_distance", text="")

        box = layout.box()
        if not settings.last_run:
            box.label(text="Not run yet", icon="INFO")
            return
        grid = box.grid_flow(columns=2, even_columns=True, align=True)
        grid.label(text=f"Lens lights: {settings.last_created}")
        grid.label(text=f"Sources: {settings.last_sources}")
        grid.label(text=f"Point lights: {settings.last_primaries}")
        grid.label(text=f"Lenses: {settings.last_lenses}")
        grid.label(text=f"Skipped pairs: {settings.last_skipped}")
        grid.label(text=f"Left out: {settings.last_left_out}")
        box.label(text=f"Time: {settings.last_seconds:.3f} s")
        if settings.last_report:
            col = box.column(align=True)
            for line in _wrap(settings.last_report):
                col.label(text=line)


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
        layout.label(text=ob.name, icon="OBJECT_DATA")
        if meta.is_lens_light:
            col = layout.column(align=True)
            col.label(text=f"From: {meta.source_light}")
            col.label(text=f"Lens: {meta.source_lens}")
            col.label(text=f"Kind: {meta.kind}, {'full' if meta.full else 'non-full'}")
            if not meta.full:
                col.label(text=f"Unblocked: {meta.unblocked_fraction:.3f}")
            col.label(text=f"Model: {meta.energy_model}, "
                           f"brightness {meta.relative_brightness:.3g}")
            for line in _wrap(meta.note):
                col.label(text=line)
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
