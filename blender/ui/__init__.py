"""Settings stored in the .blend (properties), the sidebar panel and what the polls ask of a
scene.

properties imports core only (the live update switch's callback is looked up at run time
through its registered handler); panel may import commands.
"""
