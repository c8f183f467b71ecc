"""Make the repository root importable so tests can `import addon` without Blender."""
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

import importlib.util

import pytest

EXTENSION_NAME = "lens_lights"


def load_extension():
    """Import the repository root as the package `lens_lights` (as Blender would,
    so relative imports work) without installing it."""
    if EXTENSION_NAME in sys.modules:
        return sys.modules[EXTENSION_NAME]
    spec = importlib.util.spec_from_file_location(
        EXTENSION_NAME, ROOT / "__init__.py", submodule_search_locations=[str(ROOT)])
    module = importlib.util.module_from_spec(spec)
    sys.modules[EXTENSION_NAME] = module
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="session")
def extension():
    """The extension, registered once in the bpy module for the whole session."""
    import bpy  # noqa: F401  (the pinned environment has it; never skip)
    module = load_extension()
    module.register()
    yield module
    module.unregister()


@pytest.fixture
def empty_blend(extension):
    """A fresh empty file for one test (the extension stays registered)."""
    import bpy
    bpy.ops.wm.read_factory_settings(use_empty=True)
    return bpy.context
