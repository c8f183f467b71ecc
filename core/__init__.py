"""Lens Lights' pure core: lenses, the scene model, phase 1, tiers, plans, the caustic layer,
animation and `.bi` files.

Python + numpy only; never imports bpy (or anything of Blender's), so all of it is tested
without Blender.
"""
