"""`.bi` import/export in Blender: what the importer builds, round trips of the
example files, bad files, and phase 1 through Blender = `lens-lights phase1`."""

import math
from pathlib import Path

import numpy as np
import pytest

from core.bi import conversions as conv
from core.bi.format import format_bi, read_bi, write_bi
from core.phase1.point_lights import compute_phase1
from core.scene.model import Camera, Light, Scene, Sphere

pytestmark = pytest.mark.blender

ROOT = Path(__file__).resolve().parents[3]
EXAMPLES = sorted((ROOT / "examples").glob("*.bi"))
THESIS = [ROOT / "examples" / f"fig{i}.bi" for i in (1, 2, 3)]

#: Import → export → import, for values that no longer carry the file's numbers
#: (edited in Blender, or from a foreign scene): Blender stores float32.
REL_TOL = 2e-6
#: Phase 1 from Blender's float32 numbers vs from the file's doubles: the spreading
#: angle amplifies the inputs' rounding (~6e-8) up to about 50 times.
PHASE1_REL_TOL = 1e-5


def import_bi(path):
    import bpy

    result = bpy.ops.import_scene.bi(filepath=str(path))
    assert result == {"FINISHED"}
    return bpy.context.scene


def export_bi(path):
    import bpy

    result = bpy.ops.export_scene.bi(filepath=str(path))
    assert result == {"FINISHED"}
    return read_bi(path)


# --------------------------------------------------------------------------- import


def test_operators_and_menus_registered(extension):
    import bpy
    from lens_lights.blender.bi import operators as bi_operators

    assert bpy.ops.import_scene.bi.get_rna_type().name == "Import Bitracer Scene (.bi)"
    assert bpy.ops.export_scene.bi.get_rna_type().name == "Export Bitracer Scene (.bi)"

    assert bi_operators.menu_import in bpy.types.TOPBAR_MT_file_import._dyn_ui_initialize()
    assert bi_operators.menu_export in bpy.types.TOPBAR_MT_file_export._dyn_ui_initialize()


def test_import_fig1_builds_everything(empty_blend):
    scene = import_bi(THESIS[0])
    names = sorted(o.name for o in scene.objects)
    assert names == ["Camera", "Light 0", "Sphere 0", "Sphere 1"]
    assert sorted(scene.collection.children["fig1.bi"].objects.keys()) == names

    cam = scene.camera
    assert cam.name == "Camera" and cam.data.type == "PERSP"
    assert cam.data.sensor_fit == "HORIZONTAL"
    assert cam.data.lens == pytest.approx(18 / math.tan(math.radians(22.5)), rel=1e-6)
    assert tuple(cam.location) == (0, 0, 10)
    r = scene.render
    assert (r.resolution_x, r.resolution_y, r.resolution_percentage) == (200, 200, 100)
    assert (r.pixel_aspect_x, r.pixel_aspect_y) == (1, 1)
    assert cam.data.dof.focus_distance == pytest.approx(math.sqrt(1 + 1 + 121), rel=1e-6)

    light = scene.objects["Light 0"]
    assert light.data.type == "POINT"
    assert light.data.energy == pytest.approx(10_000)
    assert tuple(light.data.color) == pytest.approx((100 / 255,) * 3)
    assert tuple(light.location) == (10, 10, 10)

    lens, red = scene.objects["Sphere 0"], scene.objects["Sphere 1"]
    assert tuple(lens.location) == (3, 3, 3) and tuple(lens.scale) == (1, 1, 1)
    assert tuple(red.location) == (1, 1, -1) and tuple(red.scale) == (2, 2, 2)
    for sphere in (lens, red):
        verts = np.array([v.co for v in sphere.data.vertices])
        assert np.allclose(np.linalg.norm(verts, axis=1), 1.0, atol=1e-6)
        assert all(p.use_smooth for p in sphere.data.polygons)
    node = next(n for n in lens.active_material.node_tree.nodes if n.type == "BSDF_PRINCIPLED")
    assert node.inputs["Transmission Weight"].default_value == pytest.approx(0.7)
    assert node.inputs["IOR"].default_value == pytest.approx(1.5171)
    assert node.inputs["Roughness"].default_value == 0
    assert tuple(node.inputs["Base Color"].default_value) == (1, 1, 1, 1)  # untinted
    assert tuple(lens.active_material.diffuse_color)[:3] == pytest.approx(
        (100 / 255, 10 / 255, 10 / 255)
    )
    node = next(n for n in red.active_material.node_tree.nodes if n.type == "BSDF_PRINCIPLED")
    assert node.inputs["Transmission Weight"].default_value == 0
    assert node.inputs["Roughness"].default_value == pytest.approx(math.sqrt(2 / 72))
    assert tuple(node.inputs["Base Color"].default_value)[:3] == pytest.approx((250 / 255, 0, 0))

    world = scene.world
    bg = [n for n in world.node_tree.nodes if n.type == "BACKGROUND"]
    assert any(
        tuple(n.inputs["Color"].default_value)[:3] == pytest.approx(conv.AMBIENT_COLOR)
        and n.inputs["Strength"].default_value == 1
        for n in bg
    )
    assert scene["lens_lights_bi_color_scale"] == 255.0


@pytest.mark.parametrize("path", THESIS, ids=lambda p: p.stem)
def test_imported_camera_sees_what_the_file_says(empty_blend, path):
    """Project points with Blender's own camera maths: the target lands in the
    image centre, points at half the opening angles on the image's edges, and the
    up vector points up."""
    import bpy
    from bpy_extras.object_utils import world_to_camera_view
    from mathutils import Vector

    scene = import_bi(path)
    bi = read_bi(path)
    cam = bi.camera
    bpy.context.view_layer.update()
    pos, target = np.array(cam.position), np.array(cam.target)
    rot, _ = conv.look_at(cam.position, cam.target, cam.up)
    x, y, z = rot[:, 0], rot[:, 1], rot[:, 2]
    fwd = -z

    def project(p):
        return tuple(world_to_camera_view(scene, scene.camera, Vector(p)))[:2]

    assert project(target) == pytest.approx((0.5, 0.5), abs=1e-6)
    th, tv = (math.tan(math.radians(a) / 2) for a in cam.fov_deg)
    assert project(pos + 5 * (fwd + th * x)) == pytest.approx((1.0, 0.5), abs=1e-5)
    assert project(pos + 5 * (fwd - tv * y)) == pytest.approx((0.5, 0.0), abs=1e-5)
    above = project(target + 0.1 * np.array(cam.up) / np.linalg.norm(cam.up))
    assert above[1] > 0.5


def test_import_non_square_pixels(empty_blend, tmp_path):
    """Opening angles that do not match the image's shape: pixel aspect."""
    from bpy_extras.object_utils import world_to_camera_view
    from mathutils import Vector

    bi = Scene(
        width=300,
        height=100,
        camera=Camera((0, 0, 5), (0, 0, 0), (0, 1, 0), (60, 30)),
        lights=[Light((0, 5, 5))],
        objects=[Sphere((0, 0, 0), 1)],
    )
    write_bi(bi, tmp_path / "wide.bi")
    scene = import_bi(tmp_path / "wide.bi")
    r = scene.render
    ratio = math.tan(math.radians(30)) * 100 / (math.tan(math.radians(15)) * 300)
    assert r.pixel_aspect_x == 1 and r.pixel_aspect_y == pytest.approx(1 / ratio, rel=1e-6)
    edge = math.tan(math.radians(15)) * 5
    assert tuple(world_to_camera_view(scene, scene.camera, Vector((0, edge, 0))))[
        1
    ] == pytest.approx(1.0, abs=1e-5)


# --------------------------------------------------------------------------- bad files

BAD = [
    ("missing.bi", None, ": cannot read the file"),
    ("polyhedron", "V 10 10\nC 0 0 5\nA 0 0 0\nU 0 1 0\nB 45 45\nL 0\nO 1\nT 1\n", ":8:"),
    ("truncated", "V 10 10\nC 0 0 5\nA 0 0 0\nU 0 1 0\nB 45 45\nL 1\nC 1 1 1\n", ":7:"),
    ("word", "V 10 10\nC 0 0 five\n", ":2:"),
    ("tiny viewport", "V 2 2\nC 0 0 5\nA 0 0 0\nU 0 1 0\nB 45 45\nL 0\nO 0\n", ":1:"),
    (
        "pixel aspect",
        "/* wide */\nV 200 200\nC 0 0 5\nA 0 0 0\nU 0 1 0\n\nB 179 1\nL 0\nO 0\n",
        ":7:",
    ),
]


@pytest.mark.parametrize("name,text,where", BAD, ids=[b[0] for b in BAD])
def test_bad_file_reports_file_and_line(empty_blend, tmp_path, name, text, where):
    """Errors are the operator's report ("FILE:LINE: message"; from Python,
    bpy.ops raises it as RuntimeError) and nothing is created."""
    import bpy

    path = tmp_path / ("bad.bi" if text is not None else name)
    if text is not None:
        path.write_text(text)
    with pytest.raises(RuntimeError) as info:
        bpy.ops.import_scene.bi(filepath=str(path))
    message = str(info.value)
    assert f"{path}{where}" in message
    assert "Traceback" not in message
    assert len(bpy.data.objects) == 0 and len(bpy.data.collections) == 0


# --------------------------------------------------------------------------- export


def scenes_equal(a: Scene, b: Scene):
    assert (a.width, a.height) == (b.width, b.height)
    fields = ("position", "target", "up", "fov_deg")
    assert [getattr(a.camera, f) for f in fields] == [getattr(b.camera, f) for f in fields]
    assert [(lt.position, lt.color, lt.brightness) for lt in a.lights] == [
        (lt.position, lt.color, lt.brightness) for lt in b.lights
    ]
    assert [(s.center, s.radius, s.surface) for s in a.objects] == [
        (s.center, s.radius, s.surface) for s in b.objects
    ]


@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: p.stem)
def test_round_trip_is_exact(empty_blend, tmp_path, path):
    """Import → export → import of an unchanged scene gives the file's numbers
    exactly (the importer keeps them; Blender's float32 values still match)."""
    original = read_bi(path)
    import_bi(path)
    exported = export_bi(tmp_path / "out.bi")
    scenes_equal(exported, original)
    assert exported.color_scale == original.color_scale
    # and once more through Blender
    import bpy

    bpy.ops.wm.read_factory_settings(use_empty=True)
    import_bi(tmp_path / "out.bi")
    assert format_bi(export_bi(tmp_path / "again.bi")) == format_bi(original)


def strip_stored_numbers():
    """Forget what the importer stored: export from Blender's own values."""
    import bpy

    for block in [*bpy.data.objects, *bpy.data.materials]:
        if "lens_lights_bi" in block:
            del block["lens_lights_bi"]


@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: p.stem)
def test_round_trip_from_blender_values(empty_blend, tmp_path, path):
    """Without the stored numbers the export reads Blender's float32 values and
    the conversions' inverses: the same within REL_TOL (colours, positions,
    radii, brightness, angles), the same view, the same lens parameters."""
    original = read_bi(path)
    import_bi(path)
    strip_stored_numbers()
    exported = export_bi(tmp_path / "out.bi")
    size = max(np.abs(np.array([s.center for s in original.objects])).max(), 1.0)

    def close(a, b, scale=1.0):
        assert np.allclose(a, b, rtol=REL_TOL, atol=REL_TOL * scale), (a, b)

    assert (exported.width, exported.height) == (original.width, original.height)
    close(exported.camera.position, original.camera.position, size)
    close(exported.camera.fov_deg, original.camera.fov_deg)
    assert conv.same_view(exported.camera, original.camera, REL_TOL)
    close(exported.camera.target, original.camera.target, size)
    for a, b in zip(exported.lights, original.lights, strict=True):
        close(a.position, b.position, size)
        close(a.color, b.color)
        close(a.brightness, b.brightness)
    for a, b in zip(exported.objects, original.objects, strict=True):
        close(a.center, b.center, size)
        close(a.radius, b.radius)
        close(a.surface.color, b.surface.color)
        close(a.surface.transmission, b.surface.transmission)
        if b.surface.transmission > 0:
            close(a.surface.ior, b.surface.ior)
        else:
            close(a.surface.exponent, b.surface.exponent)
    # and phase 1 gives the same secondary sources
    compare_phase1(compute_phase1(exported), compute_phase1(original), rel=PHASE1_REL_TOL)


def test_export_edited_scene_writes_the_edits(empty_blend, tmp_path):
    import bpy

    scene = import_bi(THESIS[0])
    scene.objects["Sphere 0"].location.x += 0.5
    scene.objects["Light 0"].data.energy = 5000
    node = next(
        n for n in bpy.data.materials["Sphere 0"].node_tree.nodes if n.type == "BSDF_PRINCIPLED"
    )
    node.inputs["IOR"].default_value = 1.33
    exported = export_bi(tmp_path / "out.bi")
    assert exported.objects[0].center == (3.5, 3, 3)
    assert exported.lights[0].brightness == 0.5
    assert exported.objects[0].surface.ior == pytest.approx(1.33, rel=1e-6)
    assert exported.objects[1] == read_bi(THESIS[0]).objects[1]  # untouched


def test_export_camera_with_track_to_constraint(empty_blend, tmp_path):
    """The exporter reads the evaluated camera (constraints applied) and takes the
    focus object as the target."""
    import bpy

    scene = import_bi(THESIS[0])
    target = bpy.data.objects.new("Target", None)
    scene.collection.objects.link(target)
    target.location = (2, 0, -3)
    cam = scene.camera
    cam.location = (1, 2, 12)
    track = cam.constraints.new("TRACK_TO")
    track.target, track.track_axis, track.up_axis = target, "TRACK_NEGATIVE_Z", "UP_Y"
    cam.data.dof.focus_object = target
    exported = export_bi(tmp_path / "out.bi").camera
    assert exported.position == (1, 2, 12)
    assert np.allclose(exported.target, (2, 0, -3), atol=1e-5)
    assert exported.fov_deg == pytest.approx((45, 45), rel=1e-6)
    up = np.array(exported.up)
    forward = np.subtract((2, 0, -3), (1, 2, 12))
    assert abs(up @ forward) < 1e-5 and up[2] > 0  # Track To: local Y towards world Z


def test_export_lists_what_is_left_out(empty_blend, tmp_path):
    import bpy
    from lens_lights.blender.bi.scene_data import read_for_export

    import_bi(THESIS[2])
    bpy.ops.mesh.primitive_cube_add(location=(5, 0, 0))
    cube = bpy.context.object.name
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    bpy.context.scene.collection.objects.link(sun)
    read = read_for_export(bpy.context)
    left = dict(read.left_out)
    assert cube in left and "Sun" in left
    assert len(read.scene.objects) == 3 and len(read.scene.lights) == 1
    assert export_bi(tmp_path / "out.bi").objects == read_bi(THESIS[2]).objects


def test_export_without_camera_warns(empty_blend, tmp_path):
    import bpy
    from lens_lights.blender.bi.scene_data import read_for_export

    import_bi(THESIS[0])
    bpy.context.scene.camera = None
    read = read_for_export(bpy.context)
    assert any("no camera" in w for w in read.warnings)
    cam, default = read.scene.camera, Camera()
    assert (cam.position, cam.target, cam.up, cam.fov_deg) == (
        default.position,
        default.target,
        default.up,
        default.fov_deg,
    )
    export_bi(tmp_path / "out.bi")


def test_export_to_unwritable_path_reports(empty_blend, tmp_path):
    import bpy

    import_bi(THESIS[0])
    with pytest.raises(RuntimeError, match="cannot write the file"):
        bpy.ops.export_scene.bi(filepath=str(tmp_path / "no" / "such" / "dir.bi"))


# --------------------------------------------------------------------------- phase 1 in Blender


def compare_phase1(got, want, rel=1e-6, brightness_scale=1.0):
    """Same secondary sources (matched by light and lens index), same skipped pairs."""
    assert sorted((s.light, s.lens) for s in got.sources) == sorted(
        (s.light, s.lens) for s in want.sources
    )
    by_key = {(s.light, s.lens): s for s in got.sources}
    for w in want.sources:
        g = by_key[(w.light, w.lens)]
        scale = max(1.0, float(np.abs(w.position).max()))
        assert g.kind == w.kind
        assert np.allclose(g.position, w.position, rtol=rel, atol=rel * scale)
        assert np.allclose(g.axis, w.axis, atol=rel)
        assert g.spread_deg == pytest.approx(w.spread_deg, rel=rel, abs=rel)
        assert g.intensity * brightness_scale == pytest.approx(w.intensity, rel=rel)
        assert g.shadow_list == w.shadow_list and g.full == w.full
    assert sorted((k.light, k.lens) for k in got.skipped) == sorted(
        (k.light, k.lens) for k in want.skipped
    )


@pytest.mark.parametrize("path", THESIS, ids=lambda p: p.stem)
def test_blender_scene_reader_gives_phase1_of_the_file(empty_blend, path):
    """The imported scene, read back by the generator's scene reader, gives the
    secondary sources of `lens-lights phase1` (the reader's brightness is watts)."""
    import bpy
    from lens_lights.blender.read.scene import read_blender_scene

    import_bi(path)
    read = read_blender_scene(bpy.context)
    # the reader's order may differ from the file's: map by the spheres' names
    order = [int(name.split()[-1]) for name in read.sphere_sources]
    lights = [int(name.split()[-1]) for name in read.light_sources]
    got = compute_phase1(read.scene)
    for s in got.sources:
        s.light, s.lens = lights[s.light], order[s.lens]
        s.shadow_list = sorted(order[k] for k in s.shadow_list)
    for k in got.skipped:
        k.light, k.lens = lights[k.light], order[k.lens]
    compare_phase1(
        got,
        compute_phase1(read_bi(path)),
        rel=PHASE1_REL_TOL,
        brightness_scale=1.0 / conv.WATTS_PER_BRIGHTNESS,
    )


@pytest.mark.parametrize("path", THESIS, ids=lambda p: p.stem)
def test_generated_lens_lights_are_phase1_of_the_file(empty_blend, path):
    """Import a thesis scene, generate the lens lights with the thesis' energy
    model: one spot light per secondary source of `lens-lights phase1`, at its
    position, along its axis, with its spreading angle, its brightness
    (energy = brightness × WATTS_PER_BRIGHTNESS × unblocked share) and its
    shadow state (full / non-full)."""
    import bpy

    scene = import_bi(path)
    settings = scene.lens_lights
    settings.energy_model = "THESIS"
    settings.min_brightness = 0.0
    settings.max_lights = 1000
    assert bpy.ops.lens_lights.generate() == {"FINISHED"}
    want = phase1_cli(path)
    lights = [o for o in scene.objects if o.type == "LIGHT" and o.lens_lights.is_lens_light]
    got = {
        (int(o.lens_lights.source_light.split()[-1]), int(o.lens_lights.source_lens.split()[-1])): o
        for o in lights
    }
    assert sorted(got) == sorted((s.light, s.lens) for s in want.sources)
    for s in want.sources:
        ob = got[(s.light, s.lens)]
        assert s.kind in ("real", "virtual") and ob.lens_lights.kind == s.kind
        m = ob.matrix_world
        scale = max(1.0, float(np.abs(s.position).max()))
        assert np.allclose(
            tuple(m.translation), s.position, rtol=PHASE1_REL_TOL, atol=PHASE1_REL_TOL * scale
        )
        direction = -np.array(m.col[2][:3])
        direction /= np.linalg.norm(direction)
        assert np.allclose(direction, s.axis, atol=PHASE1_REL_TOL)
        k = ob.scale.x / ob.scale.z
        half = math.degrees(math.atan(math.tan(ob.data.spot_size / 2) * k))
        assert half == pytest.approx(s.spread_deg, rel=PHASE1_REL_TOL)
        brightness = ob.data.energy / conv.WATTS_PER_BRIGHTNESS / s.unblocked_fraction
        assert brightness == pytest.approx(s.intensity, rel=PHASE1_REL_TOL)
        assert tuple(ob.data.color) == pytest.approx(read_bi(path).lights[s.light].color, rel=1e-6)
        assert ob.lens_lights.full == s.full
        assert ob.lens_lights.unblocked_fraction == pytest.approx(s.unblocked_fraction, rel=1e-5)
    if path.stem == "fig3":  # thesis: the small sphere 0 partly blocks lens 1
        (source,) = want.sources
        assert (source.lens, source.full, source.shadow_list) == (1, False, [0])
        assert not got[(0, 1)].lens_lights.full


def phase1_cli(path):
    """`lens-lights phase1 PATH --json`, as objects with attributes."""
    import json
    import subprocess
    import sys
    from types import SimpleNamespace

    out = subprocess.run(
        [sys.executable, str(ROOT / "scripts" / "cli.py"), "phase1", str(path), "--json"],
        capture_output=True,
        text=True,
        check=True,
    )
    data = json.loads(out.stdout)
    return SimpleNamespace(
        sources=[SimpleNamespace(**s) for s in data["sources"]],
        skipped=[SimpleNamespace(**k) for k in data["skipped"]],
    )
