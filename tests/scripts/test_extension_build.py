"""Build the extension zip (scripts/build_extension.py, with the bpy wheel's
blender_ext.py), validate it, install it the way "Install from Disk" does
(`bpy.ops.extensions.package_install_files`) into a throw-away user folder, enable
it and run the operator — in a fresh Python process, so the installed package
(`bl_ext.user_default.lens_lights`) is the only copy loaded."""

import json
import os
import subprocess
import sys
import textwrap
import tomllib
import zipfile
from pathlib import Path

import pytest

pytestmark = pytest.mark.blender

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "scripts"))

import build_extension  # noqa: E402


@pytest.fixture(scope="module")
def built_zip(tmp_path_factory):
    out = tmp_path_factory.mktemp("dist")
    assert build_extension.main(["--output-dir", str(out)]) == 0
    (zip_path,) = out.glob("*.zip")
    return zip_path


def test_zip_holds_the_extension_only(built_zip):
    m = build_extension.manifest()
    assert built_zip.name == f"{m['id']}-{m['version']}.zip"
    names = zipfile.ZipFile(built_zip).namelist()
    for required in (
        "blender_manifest.toml",
        "__init__.py",
        "blender/__init__.py",
        "blender/commands/generate.py",
        "blender/ui/properties.py",
        "blender/ui/panel.py",
        "blender/read/scene.py",
        "blender/build/lights.py",
        "core/phase1/point_lights.py",
        "core/tiers/__init__.py",
        "core/lens/sphere_fit.py",
        "core/lens/glass.py",
        "core/scene/model.py",
        "core/plan/planning.py",
        "core/report/message.py",
        "core/phase1/skip_reasons.py",
        # the tiers (the panel imports them) and what they need
        "core/tiers/fitted.py",
        "core/tiers/fitted_table.json",
        "core/tiers/exact_profile.py",
        "core/tiers/beam_error.py",
        "core/lens/ball_optics.py",
        "core/scene/blender_spot.py",
    ):
        assert required in names, required
    for name in names:
        top = name.split("/")[0]
        assert top not in (
            "tests",
            "examples",
            "scripts",
            "docs",
            "bench",
            "reports",
            "dist",
            "reference",
        ), name
        assert not top.startswith("."), name
        assert "__pycache__" not in name and not name.endswith(".pyc"), name


def test_validate_rejects_a_broken_package(tmp_path):
    bad = tmp_path / "bad.zip"
    with zipfile.ZipFile(bad, "w") as z:
        z.writestr("__init__.py", "")
    res = build_extension.run_tool("validate", bad)
    assert res.returncode != 0 or "error" in (res.stdout + res.stderr).lower()


INSTALL_AND_RUN = textwrap.dedent("""
    import json, sys
    import bpy, addon_utils
    zip_path = sys.argv[1]
    bpy.ops.wm.read_factory_settings(use_empty=True)
    res = bpy.ops.extensions.package_install_files(
        filepath=zip_path, repo="user_default", enable_on_install=True)
    module = "bl_ext.user_default.lens_lights"
    loaded, enabled = addon_utils.check(module)
    # A scene: a floor, a glass sphere and a point light above it.
    bpy.ops.mesh.primitive_plane_add(size=10, location=(0, 0, -1))
    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.5, location=(0, 0, 1))
    sphere = bpy.context.object
    mat = bpy.data.materials.new("Glass")
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True                # Blender 4.x: no node tree until then
    bsdf = mat.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Transmission Weight"].default_value = 1.0
    bsdf.inputs["IOR"].default_value = 1.5
    sphere.data.materials.append(mat)
    bpy.ops.object.light_add(type="POINT", location=(0, 0, 3))
    bpy.context.object.data.energy = 500.0
    bpy.context.scene.lens_lights.energy_model = "PHYSICAL"   # (the default is AUTO)
    gen = bpy.ops.lens_lights.generate()
    made = [(o.data.type, round(o.location.z, 6))
            for o in bpy.data.objects if o.lens_lights.is_lens_light]
    clear = bpy.ops.lens_lights.clear()
    left = [o for o in bpy.data.objects if o.lens_lights.is_lens_light]
    bpy.ops.preferences.addon_disable(module=module)
    print("RESULT " + json.dumps(dict(
        install=sorted(res), loaded=loaded, enabled=enabled, generate=sorted(gen),
        made=made,
        clear=sorted(clear), left=len(left),
        modules=sorted(m for m in sys.modules if m.endswith("lens_lights")),
        disabled=not addon_utils.check(module)[1])))
    # Blender 4.2's bpy module crashes in its static destructors at exit, after
    # the work: leave without running them.
    import os
    sys.stdout.flush()
    os._exit(0)
""")


def test_install_from_disk_enable_and_run(built_zip, tmp_path):
    script = tmp_path / "install_and_run.py"
    script.write_text(INSTALL_AND_RUN)
    env = dict(os.environ, BLENDER_USER_RESOURCES=str(tmp_path / "blender-user"))
    res = subprocess.run(
        [sys.executable, str(script), str(built_zip)],
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
        cwd=tmp_path,
    )
    lines = [line for line in res.stdout.splitlines() if line.startswith("RESULT ")]
    assert res.returncode == 0 and lines, res.stdout[-3000:] + res.stderr[-3000:]
    out = json.loads(lines[-1][len("RESULT ") :])
    assert out["install"] == ["FINISHED"] and out["loaded"] and out["enabled"]
    assert out["generate"] == ["FINISHED"] and out["clear"] == ["FINISHED"]
    # R 0.5, n 1.5, D 2: image 1.2 below the centre at z = 1
    assert out["made"] == [["SPOT", pytest.approx(-0.2, abs=1e-5)]]
    assert out["left"] == 0 and out["disabled"]
    assert out["modules"] == ["bl_ext.user_default.lens_lights"]  # not this checkout
    assert (
        tmp_path
        / "blender-user"
        / "extensions"
        / "user_default"
        / "lens_lights"
        / "blender_manifest.toml"
    ).exists()


def test_zip_ships_the_license_and_declares_file_access(built_zip):
    """GPL-3.0-or-later wants its text beside the code; import/export write files, which
    the extensions platform asks to be declared (`[permissions] files`)."""
    with zipfile.ZipFile(built_zip) as z:
        license_text = z.read("LICENSE").decode()
        manifest = tomllib.loads(z.read("blender_manifest.toml").decode())
    assert "GNU GENERAL PUBLIC LICENSE" in license_text and "Version 3" in license_text
    assert manifest["license"] == ["SPDX:GPL-3.0-or-later"]
    assert set(manifest["permissions"]) == {"files"}
    assert ".bi" in manifest["permissions"]["files"]
