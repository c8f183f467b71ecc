"""The Blender side of Lens Lights: everything that touches bpy, in packages by floor (each
package's `__init__` says what it may import; `tests/test_layout.py` checks it, and that no
import makes a circle):

* `read` reads the scene as the renderer sees it: `read.scene` (the depsgraph walk),
  `read.render_probe` (the render depsgraph), `read.materials` (materials' node trees),
  `read.occluders` (rays against the read geometry), `read.receivers` (the Caustic
  layer's receivers); the numpy work is in `core.scene.assembly` and
  `core.scene.instances`;
* `build` makes what Generate and Bake put in the scene: `build.marks` (the marks and
  names), `build.lights` (the lens lights), `build.mask_nodes` (shadow masks),
  `build.layers` and `build.baked_layers` (caustic layers), `build.cycles_caustics`
  (Cycles' own caustics of the lenses off and back on), `build.cleanup` (Clear);
* `commands` runs the operators: `commands.pipeline` (the options and the one read →
  plan they share, with `commands.layer_stage`), `commands.generate` (Generate, Clear),
  `commands.bake` (keys the lens lights over a frame range), `commands.live_update`
  (registers its handlers; keeps the lens lights in step with the scene while
  ``scene.lens_lights.live_update`` is on and no bake exists), `commands.bake_check`
  (registers its handlers: says when the scene changed under a bake);
* `ui`: `ui.properties` (the settings in the .blend), `ui.panel` (the sidebar),
  `ui.scene_state` (whether a scene has anything to clear: Clear's poll);
* `bi`: `bi.scene_data` builds and reads the Blender data of `.bi` scenes,
  `bi.operators` the File menu's import and export.

Each module listed in `_MODULE_NAMES` has `register()` / `unregister()`; they run in
this order and are undone in reverse, so that properties exist before the operators
and panels that use them (and live update installs the Live Update switch's hook,
`ui.properties.set_live_update_hook`). The others register nothing (the render probe
registers its engine only while it renders).

Nothing here runs without bpy; what can is in `core/`.
"""

import importlib

_MODULE_NAMES = (
    "ui.properties",
    "commands.generate",
    "commands.bake",
    "commands.live_update",
    "commands.bake_check",
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
