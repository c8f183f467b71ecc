"""Make the repository root importable so tests can `import core` without Blender, and the
tests' helpers (tests/helpers/) and the scripts importable by name."""

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

sys.path.insert(0, str(ROOT / "scripts"))
sys.path.insert(0, str(ROOT / "tests" / "helpers"))

import pytest  # noqa: E402
from dev_extension import load_extension  # noqa: E402


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


@pytest.fixture
def auto_builds_lights(extension, monkeypatch):
    """AUTO in EEVEE builds Fitted lights, as before the Caustic layer tier: for the
    tests of the light pipeline (reading, planning, building, clearing lights), which
    run in the factory scene's EEVEE. The layer's own: tests/blender/build/test_blender_layer.py."""
    from lens_lights.core import tiers

    for engine in ("BLENDER_EEVEE", "BLENDER_EEVEE_NEXT"):
        monkeypatch.setitem(tiers.AUTO_RESOLUTION, engine, tiers.FITTED)


@pytest.fixture
def interactive(extension):
    """Live update as in Blender's window (`live_update.INTERACTIVE`: coarse states while
    updates follow one another, the `refine` timer after them); put back after."""
    import bpy
    from lens_lights.blender.commands import live_update

    live_update.INTERACTIVE = True
    yield live_update
    live_update.INTERACTIVE = None
    if bpy.app.timers.is_registered(live_update.refine):
        bpy.app.timers.unregister(live_update.refine)


def pytest_configure(config):
    # `./lens-lights test --blender 4.2` runs only these (`-m blender`) on another release.
    config.addinivalue_line("markers", "blender: the module runs Blender (the bpy module)")
