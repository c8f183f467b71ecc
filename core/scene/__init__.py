"""The scene as plain data: the `.bi` model, light types and their radiometry, instances, the
assembly of what the Blender side read.

May import core.shared, core.lens and core.tiers.base (a primary's effective cone); never
core.phase1 or above.
"""
