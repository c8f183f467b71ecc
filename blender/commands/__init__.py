"""The operators' work: the one pipeline (read → plan) that Generate, Bake and Live update
share, the operators themselves, the live update handlers.

May import core and every other blender package but bi and ui.panel.
"""
