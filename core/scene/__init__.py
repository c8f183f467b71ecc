"""The scene as plain data: the `.bi` model, light types and their radiometry (with a
light's IES profile: `ies`), instances, the assembly of what the Blender side read.

May import core.shared and core.lens; never core.phase1 or above.
"""
