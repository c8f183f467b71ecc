"""Lens Lights: the caustics of glass spheres as spot lights (Blender extension).

Register/unregister only; the Blender side lives in `operators/`, the bpy-free core
in `addon/`.
"""


def register():
    from . import operators

    operators.register()


def unregister():
    from . import operators

    operators.unregister()
