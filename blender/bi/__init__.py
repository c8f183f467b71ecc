"""Import and export of `.bi` files: the File menu operators and the Blender data each way.

May import core, blender.read and blender.ui.properties.
"""
