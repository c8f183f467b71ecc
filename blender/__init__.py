"""The Blender side of Lens Lights: everything that touches bpy.

Each module listed here has `register()` / `unregister()`; they run in this order
and are undone in reverse, so that properties exist before the operators and panels
that use them. The others register nothing (the render probe registers its engine
only while it renders):

* `scene_reader` reads the scene as the renderer sees it, with `render_probe` (the
  render depsgraph), `material_reader` (materials' node trees) and `occluders`
  (rays against the read geometry); the numpy work is in `core.scene.assembly` and
  `core.scene.instances`;
* `live_update` (registers its handlers) keeps the lens lights in step with the
  scene while ``scene.lens_lights.live_update`` is on;
* `light_builder` creates and removes the lens lights; `bake` keys them over a
  frame range; `cycles_caustics` turns Cycles' own caustics of their lenses off
  and back on; `scene_state` says whether a scene has any (Clear's poll);
* `bi_scene_builder` builds and reads the Blender data of `.bi` scenes for `bi_io`.

Nothing here runs without bpy; what can is in `core/`.
"""

import importlib

_MODULE_NAMES = (
    "ui.properties",
    "commands.generate",
    "commands.bake",
    "commands.live_update",
    "ui.panel",
    "bi.operators",
)


def _modules():
    return [importlib.import_module(f".{name}", __name__) for name in _MODULE_NAMES]


def register():
    for module in _modules():
        module.register()


def unregister():
    for module in reversed(_modules()):
        module.unregister()
