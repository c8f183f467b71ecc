"""The scene reader's pure half without Blender (`core.scene.instances`,
`core.scene.assembly`): names, scale checks, left-out entries, one object's rules and
the assembly of a hand-made set of instances; every expected value is worked out
by hand."""

import math

import numpy as np
import pytest

from core.lens.glass import LensOptics, MaterialOptics
from core.lens.sphere_fit import SphereFit
from core.scene.assembly import (
    LIGHT_GROUP,
    OTHER_GROUP,
    SPHERE_GROUP,
    GeometryRecord,
    assemble,
    box_fit_failure,
    box_fit_failures,
    groups_of,
    lens_materials,
    perspective_fov,
    render_size,
)
from core.scene.instances import (
    Indexed,
    InstanceNames,
    LeftOut,
    instance_names,
    occurrences,
    scale_codes,
    scale_reason,
)
from core.scene.light_props import (
    LightNodes,
    LightRecord,
    light_colors,
    light_power,
    uses_light_nodes,
)


def matrix(scale=(1.0, 1.0, 1.0), translation=(0.0, 0.0, 0.0)):
    m = np.diag([*scale, 1.0])
    m[:3, 3] = translation
    return m


CUBE = np.array([[x, y, z] for x in (-1.0, 1.0) for y in (-1.0, 1.0) for z in (-1.0, 1.0)])


def test_occurrences_count_earlier_equal_keys():
    assert occurrences(np.array([5, 3, 5, 5, 3])).tolist() == [0, 0, 1, 2, 1]
    assert occurrences(np.zeros(0, dtype=np.int64)).tolist() == []


def test_instance_names_join_instancer_and_number_repeats():
    names = instance_names(
        ["Cube", "Bead"], np.array([0, 1, 1, 0]), np.array([-1, 0, 0, -1]), ["Grid"]
    )
    assert names == ["Cube", "Grid/Bead", "Grid/Bead#1", "Cube#1"]
    assert names[1:3] == ["Grid/Bead", "Grid/Bead#1"]
    assert names.subset(np.array([2, 3])) == ["Grid/Bead#1", "Cube#1"]
    assert InstanceNames(["A"], [0, 0], [0, 2]) == ["A", "A#2"]
    assert Indexed(["x", "y"], [1, 1, 0]) == ["y", "y", "x"]


def test_scale_codes_and_reasons():
    shear = matrix()
    shear[0, 1] = 1.0  # axes (1, √2, 1): not uniform
    sheared_uniform = np.array([[1.0, 0.6, 0, 0], [0, 0.8, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]])
    nan = matrix()
    nan[0, 3] = np.nan
    ms = np.array(
        [
            matrix(),
            matrix((2, 2, 2)),
            matrix((-1, 1, 1)),
            matrix((1, 2, 1)),
            matrix((0, 0, 0)),
            matrix((1, 0, 1)),
            nan,
            shear,
        ]
    )
    assert scale_codes(ms).tolist() == [4, 4, 4, 3, 1, 2, 0, 3]
    assert (
        scale_reason(matrix((1, 2, 1))) == "non-uniform scale (1, 2, 1): an ellipsoid, not a sphere"
    )
    assert scale_reason(matrix((1, 0, 1))) == "zero scale on an axis (1, 0, 1): flat, not a sphere"
    assert scale_reason(matrix((0, 0, 0))) == "zero scale: nothing is rendered"
    assert scale_reason(nan) == "invalid transform (non-finite numbers)"
    # columns (1, 0, 0) and (0.6, 0.8, 0): both of length 1, but not orthogonal
    assert scale_reason(sheared_uniform) == "sheared transform: not a sphere"


def test_left_out_groups_instances_by_name_and_reason():
    names = InstanceNames(["Grid/Cube", "Lamp"], [0, 0, 1, 0], [0, 1, 0, 2])
    left = LeftOut(names)
    left.add(2, "sun light: only point lights make lens lights", False)
    left.add_grouped(
        np.array([0, 1, 3]), np.array([7, 7, 7]), lambda i: "not a sphere", lambda i: True
    )
    assert left.entries() == [
        ("Grid/Cube (3 instances)", "not a sphere", True),
        ("Lamp", "sun light: only point lights make lens lights", False),
    ]


def test_one_objects_rules():
    assert render_size(1920, 1080, 50) == (960, 540)
    assert light_power(10.0, 1.0, True, 0.1) == 20.0  # 10 W × 2¹
    assert light_power(1.0, 0.0, False, 0.5) == pytest.approx(math.pi)  # × 4π 0.5²
    assert light_colors(
        [
            LightRecord("A", None, "POINT", 1.0, (1.0, 0.5, 0.25), (0.5, 1.0, 1.0)),
            LightRecord("B", None, "POINT", 1.0, (1.0, 0.5, 0.25, 1.0)),
        ]
    ) == [(0.5, 0.5, 0.25), (1.0, 0.5, 0.25)]
    assert light_colors([LightRecord("B", None, "SUN", 1.0, (0.1, 0.2, 0.3))]) == [(0.1, 0.2, 0.3)]
    plain = ("ShaderNodeEmission", "ShaderNodeOutputLight")
    assert not uses_light_nodes(None)
    assert not uses_light_nodes(LightNodes(plain, 1))
    assert uses_light_nodes(LightNodes(plain, 1, strength=2.0))
    assert uses_light_nodes(LightNodes(plain, 1, linked_inputs=1))
    assert uses_light_nodes(LightNodes(("ShaderNodeOutputLight",), 0))
    opaque = MaterialOptics(ior=1.45, transmission=0.0)
    glass = MaterialOptics(ior=1.33, transmission=0.8)
    # the rules on all spheres at once, one row each, against the rules by hand
    rows = [(glass, "AUTO", None), (glass, "NEVER", 1.7), (opaque, "ALWAYS", None)]
    rows += [(glass, "ALWAYS", 1.7), (opaque, "AUTO", 1.2), (opaque, "NEVER", None)]
    ior, kt, weight = lens_materials(
        [o.ior for o, _, _ in rows],
        [o.transmission for o, _, _ in rows],
        [m for _, m, _ in rows],
        [x for _, _, x in rows],
    )
    assert list(zip(ior.tolist(), kt.tolist(), weight.tolist(), strict=True)) == [
        (1.33, 0.8, 0.8),  # the material decides
        (1.33, 0.0, 0.0),  # NEVER: opaque, the override ignored
        (1.5, 1.0, 1.0),  # ALWAYS on an opaque material: clear glass of IOR 1.5
        (1.7, 0.8, 0.8),  # ALWAYS on glass: its transmission, the override's IOR
        (1.2, 0.0, 0.0),  # an opaque AUTO sphere keeps its override but stays opaque
        (1.45, 0.0, 0.0),
    ]
    assert box_fit_failure(np.array([2.0, 2.0, 1.9])) is None
    fits = box_fit_failures(np.array([[2.0, 2.0, 1.9], [np.nan, 1.0, 1.0], [2.0, 2.0, 1.0]]))
    assert fits[0] is None
    assert fits[1].reason == "not a sphere: non-finite vertex coordinates"
    assert fits[2].reason == box_fit_failure(np.array([2.0, 2.0, 1.0])).reason
    assert (
        box_fit_failure(np.array([2.0, 2.0, 1.0])).reason
        == "not a sphere: its bounding box (2 × 2 × 1) is not a cube"
    )
    assert box_fit_failure(np.zeros(3)).reason == "zero size: all its vertices are at one point"
    # a 90° sensor across the wider side of a 2:1 image: 2 atan(tan 45° / 2) = 53.13° high
    h, v = perspective_fov(0.0, 0.0, math.radians(90.0), "AUTO", 200, 100)
    assert (h, v) == pytest.approx((90.0, 53.130102354))
    assert perspective_fov(0.5, 0.25, 9.0, "VERTICAL", 1, 1) == pytest.approx(
        (math.degrees(0.5), math.degrees(0.25))
    )


def test_assemble_a_hand_made_scene():
    lamp = LightRecord("Lamp", "lamp-object", "POINT", 100.0, radius=0.1)
    sun = LightRecord("Sun", "sun-object", "SUN", 3.0)
    dark = LightRecord("Dark", "dark-object", "SPOT", 0.0)
    glass = MaterialOptics(ior=1.5, transmission=1.0, tint=(1.0, 0.9, 0.8), notes=["n"])
    ball = GeometryRecord(
        "Ball",
        "ball-object",
        "MESH",
        CUBE,
        optics=glass,
        color=(0.1, 0.2, 0.3),
        fit=SphereFit(True, np.zeros(3), 1.0),
        mesh_source="ball-mesh",
    )
    plane = GeometryRecord(
        "Plane",
        "plane-object",
        "MESH",
        CUBE * np.array([5.0, 5.0, 0.0]),
        optics=MaterialOptics(),
        fit=SphereFit(False, np.zeros(3), 0.0, "not a sphere: flat"),
        mesh_source="plane-mesh",
    )
    groups = [lamp, sun, ball, plane, dark]
    # lamp at z 5; sun; ball scaled 2 at x 1 and squashed (1, 2, 1) in "Grid"; plane;
    # a spot without power
    gid = np.array([0, 1, 2, 2, 3, 4])
    M = np.array(
        [
            matrix(translation=(0, 0, 5)),
            matrix(),
            matrix((2, 2, 2), (1, 0, 0)),
            matrix((1, 2, 1)),
            matrix(),
            matrix(),
        ]
    )
    pid = np.array([-1, -1, 0, 0, -1, -1])
    read, blocking = assemble(groups, gid, M, pid, ["Grid"], "render", 64, 32)

    a = read.arrays
    assert a.light_position[0].tolist() == [0.0, 0.0, 5.0]
    assert np.isnan(a.light_position[1]).all()  # a sun has no position
    # a sun's nominal power: 4π × its strength (primaries.nominal_power)
    assert a.light_brightness.tolist() == pytest.approx([100.0, 4 * math.pi * 3.0])
    assert a.center.tolist() == [[1.0, 0.0, 0.0]] and a.radius.tolist() == [2.0]
    assert a.ior.tolist() == [1.5] and a.kt.tolist() == [1.0]
    assert read.light_sources == ["Lamp", "Sun"]
    assert read.light_objects == ["lamp-object", "sun-object"]
    assert read.primary_lights[1].direction == (0.0, 0.0, -1.0)
    assert read.point_light_sources == ["Lamp"] and len(read.lights) == 1
    assert read.sphere_sources == ["Grid/Ball"] and read.sphere_objects == ["ball-object"]
    assert read.lens_optics == [LensOptics(1.0, (1.0, 0.9, 0.8), (0.0, 0.0, 0.0))]
    surface = read.surfaces[0]
    assert (surface.color, surface.diffuse, surface.transmission) == ((0.1, 0.2, 0.3), 0.0, 1.0)
    assert read.material_notes == [["n"]]
    assert read.lens_candidates.tolist() == [True]
    assert read.primaries[0].power_w == 100.0 and read.lights[0].radius == 0.1
    assert read.light_notes == [("Dark", "spot light without power (0 W)")]
    assert read.left_out == [
        ("Grid/Ball#1", "non-uniform scale (1, 2, 1): an ellipsoid, not a sphere"),
        ("Plane", "not a sphere: flat"),
        ("Dark", "spot light without power (0 W)"),
    ]
    assert read.left_out_lenses == [read.left_out[0]]
    # boxes: ball 1 [−1, 3] × [−2, 2]², ball 2 [−1, 1] × [−2, 2] × [−1, 1],
    # plane [−5, 5]² × {0}; the lamp at z 5
    lo, hi = read.bounds
    assert lo.tolist() == [-5.0, -5.0, -2.0] and hi.tolist() == [5.0, 5.0, 5.0]
    assert (read.width, read.height, read.how) == (64, 32, "render")
    # what blocks rays besides the spheres: the plane and the ellipsoid
    assert blocking.sources == ["ball-mesh", "plane-mesh"]
    assert blocking.source_index == [1, 0]
    assert blocking.box_lo.tolist() == [[-5.0, -5.0, 0.0], [-1.0, -2.0, -1.0]]
    assert read.scene_size == pytest.approx(math.sqrt(10**2 + 10**2 + 7**2))


def test_ray_hits_on_spheres_and_boxes():
    from core.scene.ray_hits import box_entries, sphere_hits

    d = np.array([0.0, 0.0, 1.0])
    origins = np.array([[0.0, 0.0, 0.0], [0.6, 0.0, 0.0], [3.0, 0.0, 0.0]])
    # unit sphere at z 5: the axis ray enters at 4; at x 0.6 at 5 − √(1 − 0.36) = 4.2;
    # the ray at x 3 misses; from inside (z 5) the far side at 1
    t = sphere_hits(np.array([[0.0, 0.0, 5.0]]), np.array([1.0]), origins, d)
    assert t.tolist() == pytest.approx([4.0, 4.2, np.inf])
    assert sphere_hits(
        np.array([[0.0, 0.0, 5.0]]), np.array([1.0]), np.array([[0.0, 0.0, 5.0]]), d
    ).tolist() == [1.0]
    assert sphere_hits(np.zeros((0, 3)), np.zeros(0), origins, d).tolist() == [np.inf] * 3
    # box [−1, 1]² × [2, 3]: entered at 2 by the first two rays; the third misses it
    enter, hit = box_entries(
        np.array([[-1.0, -1.0, 2.0]]), np.array([[1.0, 1.0, 3.0]]), origins, d, limit=10.0
    )
    assert hit[:, 0].tolist() == [True, True, False]
    assert enter[:2, 0].tolist() == [2.0, 2.0]
    assert not box_entries(
        np.array([[-1.0, -1.0, 2.0]]), np.array([[1.0, 1.0, 3.0]]), origins, d, limit=1.0
    )[1].any()


def test_panel_text_wraps_to_the_region_width():
    from core.report.panel_text import DEFAULT_CHARS, chars_per_line, wrap

    assert chars_per_line(None) == DEFAULT_CHARS
    assert chars_per_line(300, 1.0) == 41  # (300 − 30) / 6.5 = 41.5
    assert chars_per_line(600, 2.0) == 41  # the same at twice the scale
    assert chars_per_line(20, 1.0) == 12  # never narrower
    assert wrap("one two three four", 9) == ["one two", "three", "four"]
    assert wrap("a verylongword b", 4) == ["a", "verylongword", "b"]
    assert wrap("") == []


def test_what_each_record_is():
    """`groups_of`: lights, spheres and other geometry, why, and which look like lenses
    (lens mode ALWAYS, or AUTO and a refracting material); ALWAYS makes an opaque
    sphere a lens (IOR 1.5 unless overridden), NEVER an opaque one."""
    fit = SphereFit(True, np.array([0.0, 0.0, 1.0]), 2.0)
    opaque = MaterialOptics(ior=1.45)
    glass = MaterialOptics(ior=1.33, transmission=0.8)
    records = [
        GeometryRecord("Curve", "c", "CURVE", mode="ALWAYS"),
        LightRecord("Lamp", "l", "POINT", 10.0, (1.0, 0.5, 0.5), (0.5, 1.0, 1.0)),
        GeometryRecord("Forced", "f", "MESH", CUBE, "ALWAYS", 1.7, opaque, fit=fit),
        GeometryRecord("Never", "n", "MESH", CUBE, "NEVER", 1.7, glass, fit=fit),
        GeometryRecord("Glass", "g", "MESH", CUBE, "AUTO", None, glass, fit=fit),
        GeometryRecord(
            "Cube",
            "b",
            "MESH",
            CUBE,
            "AUTO",
            None,
            glass,
            fit=SphereFit(False, np.zeros(3), 0.0, "not a sphere: a cube"),
        ),
    ]
    g = groups_of(records)
    assert g.kind.tolist() == [OTHER_GROUP, LIGHT_GROUP] + [SPHERE_GROUP] * 3 + [OTHER_GROUP]
    assert g.reason == ["not a mesh (curve)", "", "", "", "", "not a sphere: a cube"]
    assert g.looks_like_lens.tolist() == [True, False, True, False, True, True]
    assert g.ior[2:5].tolist() == [1.7, 1.33, 1.33] and g.kt[2:5].tolist() == [1.0, 0.0, 0.8]
    assert g.lens_like.tolist() == [False, False, True, False, True, False]
    assert g.center[2].tolist() == [0.0, 0.0, 1.0] and g.radius[2] == 2.0
    assert g.light[1].color == (0.5, 0.5, 0.5) and g.light[1].energy == 10.0
    assert g.surface[3].transmission == 0.0 and g.surface[3].ior == 1.0
    assert np.isnan(g.corners[1]).all() and g.corners[2].tolist() == CUBE.tolist()
