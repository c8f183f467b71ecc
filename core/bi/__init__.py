"""The thesis' `.bi` scene files: grammar, reader and writer (with the line of every error),
records and unit conversions to and from Blender's data.

May import core.shared, core.lens and core.scene.
"""
