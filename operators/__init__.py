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
    for name in _MODULE_NAMES:
        try:
            yield importlib.import_module(f".{name}", __name__)
        except ModuleNotFoundError as e:
            if e.name != f"{__name__}.{name}":
                raise      # a real import error inside an existing module


def register():
    for module in _modules():
        module.register()


def unregister():
    for module in reversed(list(_modules())):
        module.unregister()
