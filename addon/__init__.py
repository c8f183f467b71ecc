"""Lens Lights' pure core: scene model, phase-1 optics, `.bi` files, exact optics.

Python + numpy only; never imports bpy, so everything here is tested without Blender.
"""
