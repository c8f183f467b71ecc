"""The structure issues 11 and 23 ask for: one registry of tiers, the README's tier table
generated from it, skip reasons as codes; the core and the Blender side in layers with no
import cycle and no private name imported across modules, the core importable without
Blender, tests mirroring the tree. Pure, no Blender."""

import ast
import re
from pathlib import Path

import pytest

from core.phase1 import point_lights
from core.phase1.skip_reasons import Reason, SkippedPair, reason_kind, reason_text
from core.tiers import (
    AUTO,
    AUTO_RESOLUTION,
    ENUM_NUMBERS,
    TIER_LINES,
    TIERS,
    energy_model_items,
    resolve_energy_model,
)
from core.tiers.base import Tier

ROOT = Path(__file__).resolve().parent.parent


# --------------------------------------------------------------------------- registry


def test_each_tier_has_one_home_and_one_entry():
    from core.tiers import caustic_layer, exact_profile, fitted, physical, thesis

    modules = {
        "THESIS": thesis,
        "PHYSICAL": physical,
        "FITTED": fitted,
        "EXACT_PROFILE": exact_profile,
        "CAUSTIC_LAYER": caustic_layer,
    }
    assert list(TIERS) == list(modules)
    for name, module in modules.items():
        tier = TIERS[name]
        assert tier is module.TIER and isinstance(tier, Tier) and tier.name == module.NAME
        assert tier.label and tier.description and tier.trades and tier.engines
        assert callable(tier.make) and tier.accuracy.l1_mean > 0
        assert TIER_LINES[name] == tier.trades  # the panel's line
    items = {i[0]: i for i in energy_model_items(include_auto=True)}
    assert {k: v[3] for k, v in items.items()} == ENUM_NUMBERS
    assert items["FITTED"][2] == TIERS["FITTED"].description
    # the accuracy figures in the tooltips are the tier's own
    assert "0.50" in TIERS["FITTED"].description and "0.024" in TIERS["EXACT_PROFILE"].description


def test_auto_resolves_per_engine_from_the_table():
    assert resolve_energy_model(AUTO, "CYCLES")[0] == AUTO_RESOLUTION["CYCLES"]
    assert resolve_energy_model(AUTO, "BLENDER_EEVEE")[0] == AUTO_RESOLUTION["BLENDER_EEVEE"]
    assert resolve_energy_model(AUTO, "BLENDER_WORKBENCH")[0] == AUTO_RESOLUTION[None]
    for name, tier in TIERS.items():
        if tier.engines == ("CYCLES",):
            assert resolve_energy_model(name, "BLENDER_EEVEE")[0] == "FITTED"


def test_readme_tier_table_is_generated_and_up_to_date():
    """Fails when the registry changed and `python scripts/readme_tables.py` was not run."""
    import readme_tables

    text = (ROOT / "README.md").read_text(encoding="utf-8")
    assert "<!-- BEGIN tiers" in text and "<!-- END tiers -->" in text
    assert readme_tables.update(text) == text, "run: python scripts/readme_tables.py"
    for tier in TIERS.values():
        assert f"| **{tier.short_label}** |" in text and tier.trades in text


# --------------------------------------------------------------------------- skip reasons


def test_phase1_codes_are_the_skip_reasons():
    names = [
        "INVALID_LIGHT",
        "INVALID_SPHERE_NONFINITE",
        "INVALID_SPHERE_RADIUS",
        "OPAQUE",
        "INVALID_KT",
        "NOT_CONVERGING",
        "LIGHT_INSIDE",
        "LIGHT_ON_SURFACE",
        "LIGHT_INSIDE_OTHER",
        "LIGHT_ON_OTHER",
        "TOTALLY_BLOCKED",
        "OUT_OF_RANGE",
    ]
    for name in names:
        assert getattr(point_lights, name) == Reason[name]
    assert (
        point_lights.reason_text(Reason.TOTALLY_BLOCKED, 1.0, 1.5, 1.0, 4)
        == "totally blocked by sphere 4"
    )


def test_skipped_pairs_carry_code_and_details():
    p = SkippedPair("Lamp", "Ball", Reason.DIMMER_THAN_CUTOFF, dict(relative=0.23, cutoff=0.5))
    assert p == ("Lamp", "Ball", "dimmer than the cut-off (0.23 < 0.5)")
    assert p.code is Reason.DIMMER_THAN_CUTOFF and p.kind == "dimmer than the cut-off"
    assert (
        reason_kind(Reason.BEYOND_MAXIMUM, dict(limit=8)) == "beyond the maximum of 8 lens lights"
    )
    assert reason_text(Reason.OPAQUE) == "opaque (kt = 0)"
    light, lens, why = p
    assert (light, lens) == ("Lamp", "Ball")


# --------------------------------------------------------------------------- imports

#: What each package may import (besides itself), from the docstring of its
#: `__init__.py`: the core in layers, the Blender side above it. A module imports from
#: the module that defines a name.
LAYERS = {
    "core.shared": set(),
    "core.lens": {"core.shared"},
    "core.scene": {"core.shared", "core.lens"},
    "core.phase1": {"core.shared", "core.lens", "core.scene"},
    "core.tiers": {"core.shared", "core.lens", "core.scene", "core.phase1"},
    "core.plan": {"core.shared", "core.lens", "core.scene", "core.phase1", "core.tiers"},
    "core.caustic_layer": {"core.shared", "core.lens", "core.scene", "core.phase1", "core.tiers"},
    "core.report": {"core.shared", "core.lens", "core.scene", "core.phase1", "core.tiers"},
    "core.animation": {
        "core.shared",
        "core.lens",
        "core.scene",
        "core.phase1",
        "core.tiers",
        "core.plan",
        "core.caustic_layer",
    },
    "core.bi": {"core.shared", "core.lens", "core.scene"},
}
_CORE = set(LAYERS)
LAYERS.update(
    {
        "blender.read": _CORE | {"blender.ui.properties"},
        "blender.build": _CORE | {"blender.read"},
        "blender.commands": _CORE
        | {"blender.read", "blender.build", "blender.ui.properties", "blender.ui.scene_state"},
        "blender.ui": _CORE | {"blender.read", "blender.build", "blender.commands"},
        "blender.bi": _CORE | {"blender.read", "blender.ui.properties"},
    }
)


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


_FILES = sorted(p for top in ("core", "blender") for p in (ROOT / top).rglob("*.py"))
_MODULES = {_module_name(p) for p in _FILES}


def _imported(path: Path):
    """(line, module of ours, names) of every `from … import …` in `path`, deferred
    imports included, `lens_lights.` taken off."""
    module = _module_name(path)
    base = module.split(".") if path.name == "__init__.py" else module.split(".")[:-1]
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                parts = base[: len(base) - (node.level - 1)]
                mod = ".".join(parts + ([node.module] if node.module else []))
            else:
                mod = (node.module or "").removeprefix("lens_lights.")
            if mod.split(".")[0] in ("core", "blender"):
                yield node.lineno, mod, [a.name for a in node.names]
        elif isinstance(node, ast.Import):
            for a in node.names:
                name = a.name.removeprefix("lens_lights.")
                if name.split(".")[0] in ("core", "blender"):
                    yield node.lineno, name, []


def _imports(path: Path) -> set[str]:
    """The modules of ours that `path` imports (a package's submodule when a name is one)."""
    out = set()
    for _, mod, names in _imported(path):
        subs = {f"{mod}.{n}" for n in names} & _MODULES
        out |= subs or (
            {mod} if not names or set(names) - {s.rsplit(".", 1)[1] for s in subs} else set()
        )
    return out & _MODULES


def _package(module: str) -> str:
    return ".".join(module.split(".")[:2])


def test_no_import_cycles_in_either_side():
    """Deferred imports count: a circle is a name on the wrong floor, not a reason to
    import inside a function."""
    graph = {_module_name(p): _imports(p) for p in _FILES}
    assert "core.tiers.base" in graph["core.tiers.fitted"]  # the walker sees imports
    state: dict[str, int] = {}

    def visit(m, stack):
        state[m] = 1
        for d in sorted(graph.get(m, ())):
            if d == m:
                continue
            if state.get(d) == 1:
                pytest.fail("import cycle: " + " → ".join(stack + [m, d]))
            if d not in state:
                visit(d, stack + [m])
        state[m] = 2

    for m in sorted(graph):
        if m not in state:
            visit(m, [])


#: Imports of our own modules inside a function, each for a slow dependency: the `.bi`
#: reader starts without numpy (the command line's `phase1` on a small file).
DEFERRED = {
    ("core.bi.format", "core.scene.arrays"),
    ("core.bi.format", "core.shared.ranges"),
}


def test_own_modules_are_imported_at_the_top():
    """A deferred import only for a slow or optional dependency, never to break a circle."""
    found = set()
    for p in _FILES:
        for fn in ast.walk(ast.parse(p.read_text(encoding="utf-8"))):
            if isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
                inner = [n for n in ast.walk(fn) if isinstance(n, ast.ImportFrom) and n.level]
                found |= {(_module_name(p), d) for n in inner for d in _imports_of(p, n)}
    assert found == DEFERRED


def _imports_of(path: Path, node: ast.ImportFrom) -> set[str]:
    module = _module_name(path)
    base = module.split(".") if path.name == "__init__.py" else module.split(".")[:-1]
    mod = ".".join(base[: len(base) - (node.level - 1)] + ([node.module] if node.module else []))
    subs = {f"{mod}.{a.name}" for a in node.names} & _MODULES
    return subs or {mod}


def test_packages_import_only_the_layers_below_them():
    assert set(LAYERS) == {_package(m) for m in _MODULES if m.count(".")}
    wrong = []
    for p in _FILES:
        module = _module_name(p)
        if module.count(".") == 0:
            continue
        allowed = LAYERS[_package(module)]
        for d in _imports(p):
            if _package(d) == _package(module) or _package(d) in allowed or d in allowed:
                continue
            wrong.append(f"{module} imports {d}")
    assert not wrong, wrong


def test_no_private_name_is_imported_across_modules():
    """A name two modules need is public in the lower one (tests may reach in)."""
    wrong = []
    for folder in ("core", "blender", "reference", "bench", "scripts", "examples"):
        for p in (ROOT / folder).rglob("*.py"):
            for node in ast.walk(ast.parse(p.read_text(encoding="utf-8"))):
                if isinstance(node, ast.ImportFrom) and node.module != "__future__":
                    for a in node.names:
                        if a.name.startswith("_") or (a.asname or "").startswith("_"):
                            wrong.append(f"{p.relative_to(ROOT)}:{node.lineno} {a.name}")
    assert not wrong, wrong


def test_every_core_module_imports_without_blender():
    """Each core module imported on its own in a Python where bpy, mathutils and
    bmesh cannot be imported."""
    import subprocess
    import sys

    names = sorted(m for m in _MODULES if m.startswith("core"))
    code = (
        "import sys, importlib\n"
        "for b in ('bpy', 'mathutils', 'bmesh', 'gpu', 'bpy_extras'):\n"
        "    sys.modules[b] = None\n"
        f"sys.path.insert(0, {str(ROOT)!r})\n"
        f"for name in {names!r}:\n"
        "    importlib.import_module(name)\n"
        "print(len(sys.modules))\n"
    )
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
    assert len(names) > 60


def test_nothing_imports_the_old_layout():
    """addon/ and operators/ are gone (core/ and blender/); nothing names them."""
    assert not (ROOT / "addon").exists() and not (ROOT / "operators").exists()
    old = re.compile(r"^\s*(from|import)\s+(lens_lights\.)?(addon|operators)\b", re.MULTILINE)
    for folder in ("core", "blender", "reference", "scripts", "tests", "examples", "bench"):
        for p in (ROOT / folder).rglob("*.py"):
            assert not old.search(p.read_text(encoding="utf-8")), p
    for p in _FILES:
        assert "import bpy" not in p.read_text(encoding="utf-8") or p.parts[-3] != "core", p


def test_tests_mirror_the_source_tree():
    """tests/core/<package>/ and tests/blender/<package>/ for packages that exist."""
    for side in ("core", "blender"):
        for folder in (ROOT / "tests" / side).iterdir():
            if folder.is_dir() and folder.name != "__pycache__":
                assert (ROOT / side / folder.name / "__init__.py").exists(), folder


def test_generate_operator_holds_only_blender_code():
    """Every function left in blender/commands/generate.py and in the pipeline it shares
    with Bake and Live update (blender/commands/pipeline.py) works on Blender objects (a
    context, a depsgraph, settings); the pure work is in core/."""
    expected = {
        "generate.py": {"_store", "generate"},
        "pipeline.py": {"options_from", "plan_scene"},
    }
    blender_args = {"depsgraph", "settings", "context"}
    for name, allowed in expected.items():
        tree = ast.parse((ROOT / "blender" / "commands" / name).read_text(encoding="utf-8"))
        funcs = [n for n in tree.body if isinstance(n, ast.FunctionDef)]
        assert {f.name for f in funcs} <= allowed, name
        for f in funcs:
            assert blender_args & {a.arg for a in f.args.args}, f.name


def test_generate_bake_and_live_update_plan_through_the_one_pipeline():
    """Generate, Bake and Live update plan with `pipeline.plan_scene` (none of them reads
    or plans on its own) and take their options from `pipeline.options_from`."""
    for name in ("generate.py", "bake.py", "live_update.py"):
        text = (ROOT / "blender" / "commands" / name).read_text(encoding="utf-8")
        assert "pipeline.plan_scene(" in text and "pipeline.options_from(" in text, name
        for own in ("read_depsgraph", "compute_phase1_primaries", "plan_result"):
            assert own not in text, (name, own)
