"""Lens Lights: the caustics of glass as lights and caustic layers (Blender extension).

Register/unregister only; the Blender side lives in `blender/`, the bpy-free core
in `core/`.
"""


def register():
    from . import blender

    blender.register()


def unregister():
    from . import blender

    blender.unregister()
