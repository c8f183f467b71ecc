"""Reading the Blender scene as the final render sees it: the depsgraph walk, the render probe,
materials, occluders, receivers.

May import core and blender.ui.properties (the settings' names); never build, commands or
bi.
"""
