"""The operators' work: the one pipeline (read → plan) that Generate, Bake and Live update
share, the operators themselves, the live update handlers.

May import core, blender.read, blender.build, blender.ui.properties and
blender.ui.scene_state.
"""
