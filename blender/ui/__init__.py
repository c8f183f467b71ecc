"""Settings stored in the .blend (properties), the sidebar panel and what the polls ask of a
scene (scene_state).

properties imports core only: the Live Update switch's update callback runs a hook that
`blender/commands/live_update.py` installs when it registers
(`properties.set_live_update_hook`); scene_state reads the marks of `blender/build/marks.py`;
panel may import commands.
"""
