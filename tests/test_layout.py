"""The structure issue 11 asks for: one registry of tiers, the README's tier table
generated from it, skip reasons as codes, no import cycles in `addon/`, and the
operator holding only what needs Blender. Pure, no Blender."""

import ast
import re
from pathlib import Path

import pytest

from addon import phase1
from addon.skip_reasons import Reason, SkippedPair, reason_kind, reason_text
from addon.tiers import (
    AUTO,
    AUTO_RESOLUTION,
    ENUM_NUMBERS,
    TIER_LINES,
    TIERS,
    energy_model_items,
    resolve_energy_model,
)
from addon.tiers.base import Tier

ROOT = Path(__file__).resolve().parent.parent


# --------------------------------------------------------------------------- registry


def test_each_tier_has_one_home_and_one_entry():
    from addon.tiers import caustic_layer, exact_profile, fitted, physical, thesis

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
        assert getattr(phase1, name) == Reason[name]
    assert (
        phase1.reason_text(Reason.TOTALLY_BLOCKED, 1.0, 1.5, 1.0, 4)
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


def _imports(path: Path, package: str) -> set[str]:
    """Modules of `addon` that `path` (module `package`.stem) imports."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    is_pkg = path.name == "__init__.py"
    base = package.split(".") if is_pkg else package.split(".")[:-1]
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            parts = base[: len(base) - (node.level - 1)] if node.level else []
            mod = ".".join(parts + ([node.module] if node.module else []))
            if not node.level and not mod.startswith("addon"):
                continue
            for alias in node.names:
                out.add(f"{mod}.{alias.name}" if f"{mod}.{alias.name}" in _MODULES else mod)
        elif isinstance(node, ast.Import):
            out |= {a.name for a in node.names if a.name.startswith("addon")}
    return {m for m in out if m in _MODULES}


def _module_name(path: Path) -> str:
    rel = path.relative_to(ROOT).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


_FILES = sorted((ROOT / "addon").rglob("*.py"))
_MODULES = {_module_name(p) for p in _FILES}


def test_no_import_cycles_in_addon():
    graph = {_module_name(p): _imports(p, _module_name(p)) for p in _FILES}
    assert "addon.tiers.base" in graph["addon.tiers.fitted"]  # the walker sees imports
    state: dict[str, int] = {}

    def visit(m, stack):
        state[m] = 1
        for d in graph.get(m, ()):
            if d == m:
                continue
            if state.get(d) == 1:
                pytest.fail("import cycle: " + " → ".join(stack + [m, d]))
            if d not in state:
                visit(d, stack + [m])
        state[m] = 2

    for m in graph:
        if m not in state:
            visit(m, [])


def test_addon_never_imports_bpy_and_nothing_imports_the_old_modules():
    for p in _FILES:
        text = p.read_text(encoding="utf-8")
        assert "import bpy" not in text, p
    gone = {"light_models", "lens_tiers", "spot_irradiance", "fitted_table", "accuracy"}
    line = re.compile(r"^\s*from\s+([\w.]+)\s+import\s+\(?([\w ,]+)", re.MULTILINE)
    for folder in ("addon", "operators", "scripts", "tests", "examples", "bench"):
        for p in (ROOT / folder).rglob("*.py"):
            for module, names in line.findall(p.read_text(encoding="utf-8")):
                if not (module.startswith(("addon", ".")) or "lens_lights.addon" in module):
                    continue
                used = set(module.split(".")) | (
                    {n.split(" as ")[0].strip() for n in names.split(",")}
                    if module.split(".")[-1] in ("addon", "")
                    else set()
                )
                assert not used & gone, (p, module, names)
    for folder in ("addon", "operators"):
        for p in (ROOT / folder).rglob("*.py"):
            assert "NODE_TREE_RECIPE" not in p.read_text(encoding="utf-8"), p


def test_generate_operator_holds_only_blender_code():
    """Every function left in operators/generate.py works on Blender objects
    (a context, a depsgraph, settings); the pure work is in addon/."""
    tree = ast.parse((ROOT / "operators" / "generate.py").read_text(encoding="utf-8"))
    funcs = [n for n in tree.body if isinstance(n, ast.FunctionDef)]
    assert {f.name for f in funcs} <= {"plan_scene", "_options", "_store", "generate"}
    blender_args = {"depsgraph", "settings", "context"}
    for f in funcs:
        assert blender_args & {a.arg for a in f.args.args}, f.name
