"""File > Import / Export > "Bitracer Scene (.bi)".

Also callable as `bpy.ops.import_scene.bi(filepath=…)` and
`bpy.ops.export_scene.bi(filepath=…)`. A `.bi` file can be dropped on the 3D
viewport too (a FileHandler). Errors are reported as "FILE:LINE: message" (the
core's BiFormatError), never as a traceback in the interface.
"""

from __future__ import annotations

import os
import traceback

import bpy
from bpy.props import StringProperty
from bpy_extras.io_utils import ExportHelper, ImportHelper

from ...core.bi.conversions import BlenderLimitError
from ...core.bi.format import BiFormatError, read_bi, write_bi
from ...core.bi.records import file_line, summary
from . import scene_data as builder


class IMPORT_SCENE_OT_bi(bpy.types.Operator, ImportHelper):
    """Import a Bitracer scene (.bi): camera, point lights, spheres and their materials"""

    bl_idname = "import_scene.bi"
    bl_label = "Import Bitracer Scene (.bi)"
    bl_options = {"REGISTER", "UNDO", "PRESET"}

    filename_ext = ".bi"
    filter_glob: StringProperty(default="*.bi", options={"HIDDEN"})

    def execute(self, context):
        path = self.filepath
        try:
            scene = read_bi(path)
        except BiFormatError as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        wm = context.window_manager
        wm.progress_begin(0, max(1, len(scene.lights) + len(scene.objects)))
        built = None
        try:
            built = builder.build_scene(
                scene,
                context,
                name=os.path.basename(path),
                progress=lambda i, n: wm.progress_update(i),
            )
        except BlenderLimitError as e:
            self.report({"ERROR"}, f"{path}:{file_line(path, e.record)}: {e}")
            return {"CANCELLED"}
        except Exception as e:  # never a traceback in the UI; details on the console
            traceback.print_exc()
            self.report({"ERROR"}, f"{path}: cannot build the scene ({type(e).__name__}: {e})")
            return {"CANCELLED"}
        finally:
            wm.progress_end()
        for warning in built.warnings:
            self.report({"WARNING"}, f"{path}: {warning}")
        self.report(
            {"INFO"},
            f"Imported {os.path.basename(path)}: {len(built.lights)} "
            f"light(s), {len(built.spheres)} sphere(s)",
        )
        return {"FINISHED"}


class EXPORT_SCENE_OT_bi(bpy.types.Operator, ExportHelper):
    """Export the scene as a Bitracer scene (.bi): the camera, point lights and the
    spheres Lens Lights recognises"""

    bl_idname = "export_scene.bi"
    bl_label = "Export Bitracer Scene (.bi)"
    bl_description = (
        "Export the scene as a Bitracer scene (.bi): the camera, point lights "
        "and the spheres Lens Lights recognises"
    )
    bl_options = {"REGISTER", "PRESET"}

    filename_ext = ".bi"
    filter_glob: StringProperty(default="*.bi", options={"HIDDEN"})

    def execute(self, context):
        path = self.filepath
        try:
            read = builder.read_for_export(context)
        except Exception as e:
            traceback.print_exc()
            self.report({"ERROR"}, f"{path}: cannot read the scene ({type(e).__name__}: {e})")
            return {"CANCELLED"}
        try:
            write_bi(read.scene, path)
        except OSError as e:
            self.report({"ERROR"}, f"{path}: cannot write the file: {e.strerror or e}")
            return {"CANCELLED"}
        except ValueError as e:
            self.report({"ERROR"}, f"{path}: {e}")
            return {"CANCELLED"}
        for warning in read.warnings:
            self.report({"WARNING"}, warning)
        if read.left_out:
            print(f"{path}: left out of the .bi file:")
            for name, reason in read.left_out:
                print(f"  {name}: {reason}")
            self.report(
                {"WARNING"},
                f"Left out {len(read.left_out)} object(s): "
                + summary([f"{name} ({reason})" for name, reason in read.left_out]),
            )
        self.report(
            {"INFO"},
            f"Exported {len(read.scene.lights)} light(s) and "
            f"{len(read.scene.objects)} sphere(s) to {path}",
        )
        return {"FINISHED"}


class IO_FH_lens_lights_bi(bpy.types.FileHandler):
    bl_idname = "IO_FH_lens_lights_bi"
    bl_label = "Bitracer Scene"
    bl_import_operator = "import_scene.bi"
    bl_export_operator = "export_scene.bi"
    bl_file_extensions = ".bi"

    @classmethod
    def poll_drop(cls, context):
        return context.area is not None and context.area.type == "VIEW_3D"


def menu_import(self, context):
    self.layout.operator(IMPORT_SCENE_OT_bi.bl_idname, text="Bitracer Scene (.bi)")


def menu_export(self, context):
    self.layout.operator(EXPORT_SCENE_OT_bi.bl_idname, text="Bitracer Scene (.bi)")


_classes = (IMPORT_SCENE_OT_bi, EXPORT_SCENE_OT_bi, IO_FH_lens_lights_bi)


_register_classes, _unregister_classes = bpy.utils.register_classes_factory(_classes)


def register():
    _register_classes()
    bpy.types.TOPBAR_MT_file_import.append(menu_import)
    bpy.types.TOPBAR_MT_file_export.append(menu_export)


def unregister():
    bpy.types.TOPBAR_MT_file_export.remove(menu_export)
    bpy.types.TOPBAR_MT_file_import.remove(menu_import)
    _unregister_classes()
