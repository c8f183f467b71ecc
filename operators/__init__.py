"""The Blender side of Lens Lights: everything that touches bpy.

Each module listed here has `register()` / `unregister()`; they run in this order
and are undone in reverse, so that properties exist before the operators and panels
that use them.
"""
import importlib

_MODULE_NAMES = (
    "properties",
    "generate",
    "panel",
    "bi_io",
)


def _modules():
    return [importlib.import_module(f".{name}", __name__) for name in _MODULE_NAMES]


def register():
    for module in _modules():
        module.register()


def unregister():
    for module in reversed(_modules()):
        module.unregister()
