"""The operators' work: `pipeline` (the options and the one read → plan Generate, Bake and
Live update share; `layer_stage`: the Caustic layer's part of it and its build), then
`generate` (Generate and Clear), `bake` (Bake) and `live_update` (its handlers), each
importing `pipeline` and none of the others but `bake_check` (what a bake was baked
from: its prints, the check the panel and renders run; live update leaves a bake
alone).

May import core, blender.read, blender.build, blender.ui.properties and
blender.ui.scene_state; never bi or ui.panel.
"""
