"""The operators' work: `pipeline` (the options and the one read → plan Generate, Bake and
Live update share; `layer_stage`: the Caustic layer's part of it and its build), then
`generate` (Generate and Clear), `bake` (Bake) and `live_update` (its handlers), each
importing `pipeline` and none of the others.

May import core, blender.read, blender.build, blender.ui.properties and
blender.ui.scene_state; never bi or ui.panel.
"""
