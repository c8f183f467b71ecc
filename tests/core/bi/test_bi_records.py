"""The `.bi` importer's and exporter's pure helpers (`core.bi.records`), without
Blender; expected values worked out by hand."""

from core.bi.records import (
    f32,
    f32v,
    file_line,
    natural_key,
    order_key,
    scene_extent,
    sphere_name,
    summary,
    surface_dict,
    surface_from_dict,
)
from core.scene.model import Camera, Light, Scene, Sphere, Surface


def test_names_and_order():
    assert sphere_name(3) == "Sphere 3"
    names = ["Sphere 10", "sphere 2", "Sphere 1"]
    assert sorted(names, key=natural_key) == ["Sphere 1", "sphere 2", "Sphere 10"]
    keys = [order_key({"index": 5}, "B"), order_key({}, "A"), order_key({"index": 1}, "Z")]
    assert sorted(keys) == [(0, 1, ["z"]), (0, 5, ["b"]), (1, 0, ["a"])]


def test_float32_shortest_decimal_and_surface_dict():
    assert f32(0.30000001192092896) == 0.3
    assert f32v((0.1, 0.5)) == (0.1, 0.5)
    s = Surface(
        color=(1.0, 0.5, 0.25),
        ambient=0.1,
        diffuse=0.2,
        specular=0.3,
        transmission=0.9,
        exponent=80.0,
        ior=1.5,
    )
    assert surface_dict(s)["n"] == 1.5 and surface_from_dict(surface_dict(s)) == s


def test_scene_extent_summary_and_file_line(tmp_path):
    # camera at the origin looking at (0, 0, −3); a light 5 away; a sphere 4 + 2 away
    scene = Scene(
        camera=Camera(position=(0, 0, 0), target=(0, 0, -3)),
        lights=[Light(position=(3, 4, 0))],
        objects=[Sphere(center=(0, 4, 0), radius=2.0, surface=Surface())],
    )
    assert scene_extent(scene) == 6.0
    assert summary(["a", "b", "c"], limit=2) == "a, b, … (1 more)"
    assert summary(["a"]) == "a"
    assert file_line(str(tmp_path / "missing.bi"), "V") == 1
