"""Issue 25 in Blender: a closed glass mesh that is no sphere is read as a lens of its
own (`BlenderSceneRead.mesh_lenses`): its loop triangles, world vertices and the
corner normals Blender shades with, as the render sees them (modifiers applied);
open glass is left out with its reason.

Expected values are what the mesh was built as, worked out here by hand: a cube's 12
triangles and its corners placed by the object's matrix, a flat face's normal, a
smooth corner's normal along the corner's direction from the centre (a UV sphere's),
the inverse-transpose for a scaled object, Subdivision's 4 faces per quad.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

pytestmark = pytest.mark.blender

bpy = pytest.importorskip("bpy")

from blender_scene_helpers import (  # noqa: E402
    add_point_light,
    collection_instance,
    collection_of,
    glass_material,
)


def _read():
    from lens_lights.blender.read.scene import read_blender_scene

    return read_blender_scene(bpy.context)


def _glass(ob):
    ob.data.materials.append(glass_material(ior=1.5))
    return ob


def cube(name="Block", location=(0.0, 0.0, 1.0), scale=(1.0, 1.0, 1.0)):
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=location, scale=scale)
    ob = bpy.context.object
    ob.name = name
    return _glass(ob)


def test_a_glass_cube_is_a_mesh_lens_with_its_triangles_and_flat_normals(empty_blend):
    add_point_light("Lamp", (0.0, 0.0, 4.0))
    ob = cube(location=(1.0, 2.0, 3.0), scale=(2.0, 1.0, 0.5))
    ob.rotation_euler = (0.0, 0.0, math.pi / 2)  # local x → world y
    read = _read()
    assert [m.name for m in read.mesh_lenses] == ["Block"]
    assert not read.left_out_lenses and not read.unmodelled_glass
    lens = read.mesh_lenses[0]
    m = lens.mesh
    assert m.n_triangles == 12 and m.vertices.shape == (8, 3)
    # corners: (1, 2, 3) + Rz(90°) (±1, ±0.5, ±0.25) = (1 ∓ 0.5, 2 ± 1, 3 ± 0.25)
    lo, hi = m.vertices.min(axis=0), m.vertices.max(axis=0)
    assert np.allclose(lo, (0.5, 1.0, 2.75), atol=1e-6)
    assert np.allclose(hi, (1.5, 3.0, 3.25), atol=1e-6)
    assert np.allclose(m.center, (1.0, 2.0, 3.0), atol=1e-6)
    assert m.radius == pytest.approx(math.sqrt(0.25 + 1.0 + 0.0625), rel=1e-6)
    # flat shading: every corner's normal is its face's, one of ±x, ±y, ±z, pointing
    # away from the centre
    n = m.corner_normals.reshape(-1, 3)
    assert np.allclose(np.abs(n).max(axis=1), 1.0, atol=1e-6)
    corners = m.vertices[m.triangles].reshape(-1, 3)
    assert np.all(np.einsum("ij,ij->i", n, corners - m.center) > 0)
    assert lens.ior == pytest.approx(1.5)


def test_smooth_shading_scaled_and_subdivided(empty_blend):
    add_point_light("Lamp", (0.0, 0.0, 4.0))
    bpy.ops.mesh.primitive_uv_sphere_add(
        segments=16, ring_count=8, radius=1.0, location=(0.0, 0.0, 1.0)
    )
    egg = _glass(bpy.context.object)
    egg.scale = (2.0, 1.0, 1.0)  # the object's scale (a sphere fit fails: an ellipsoid)
    egg.name = "Egg"
    bpy.ops.object.shade_smooth()
    read = _read()
    assert [m.name for m in read.mesh_lenses] == ["Egg"]
    m = read.mesh_lenses[0].mesh
    # a UV sphere of 16 × 8: 16 × 6 quads (2 triangles) + 2 × 16 triangle fans
    assert m.n_triangles == 16 * 6 * 2 + 2 * 16
    # smooth: each corner's normal is its vertex's; on the unit sphere the local normal
    # is the local position p, placed by the inverse transpose: (p_x / 2, p_y, p_z)
    local = (m.vertices[m.triangles] - (0.0, 0.0, 1.0)) / (2.0, 1.0, 1.0)
    expect = local / (2.0, 1.0, 1.0)
    expect /= np.linalg.norm(expect, axis=-1, keepdims=True)
    # Blender's vertex normals weigh the faces around a vertex: within 5° of the
    # sphere's on 16 × 8
    cos = np.einsum("tci,tci->tc", m.corner_normals, expect)
    assert cos.min() > math.cos(math.radians(5.0))
    # and exactly the vertex normals Blender holds, placed by diag(½, 1, 1) by hand
    vn = np.array([tuple(v.normal) for v in egg.data.vertices]) / (2.0, 1.0, 1.0)
    vn /= np.linalg.norm(vn, axis=1, keepdims=True)
    assert np.allclose(m.corner_normals, vn[m.triangles], atol=1e-5)

    sub = egg.modifiers.new("Sub", "SUBSURF")
    sub.levels, sub.render_levels = 1, 2
    read = _read()
    m = read.mesh_lenses[0].mesh
    # as the render sees it, level 2: level 1 makes each quad 4 quads and each
    # triangle 3 (480 quads), level 2 each quad 4; 2 triangles per quad
    assert m.n_triangles == (16 * 6 * 4 + 2 * 16 * 3) * 4 * 2


def test_an_open_glass_plane_is_left_out_with_its_reason(empty_blend):
    add_point_light("Lamp", (0.0, 0.0, 4.0))
    bpy.ops.mesh.primitive_plane_add(size=2.0, location=(0.0, 0.0, 1.0))
    _glass(bpy.context.object).name = "Pane"
    read = _read()
    assert not read.mesh_lenses
    assert read.left_out_lenses == [
        (
            "Pane",
            "open mesh: a surface, not a glass volume "
            "(open glass is water only with water's index, 1.30–1.36)",
        )
    ]
    assert read.unmodelled_glass[0][0] == "Pane"


def test_smooth_by_angle_keeps_a_rods_sides_smooth_and_its_caps_flat(empty_blend):
    """Smooth by Angle (a modifier from 4.1 on): the cylinder's side corners get the
    radial normal of their vertex, the caps' corners the cap's ±x."""
    add_point_light("Lamp", (0.0, 0.0, 4.0))
    bpy.ops.mesh.primitive_cylinder_add(
        vertices=16, radius=0.25, depth=2.0, location=(0.0, 0.0, 1.0), rotation=(0, math.pi / 2, 0)
    )
    rod = _glass(bpy.context.object)
    rod.name = "Rod"
    bpy.ops.object.shade_auto_smooth(angle=math.radians(30.0))
    if bpy.app.version >= (5, 0, 0):
        assert any(md.type == "NODES" for md in rod.modifiers)  # the Smooth by Angle modifier
    elif not rod.modifiers:  # 4.5's bpy module has no Essentials asset: sharp edges instead
        bpy.ops.object.shade_smooth_by_angle(angle=math.radians(30.0))
    (lens,) = _read().mesh_lenses
    m = lens.mesh
    assert m.n_triangles == 16 * 2 + 2 * 14  # the sides' quads, the caps' 16-gons fanned
    p = m.vertices[m.triangles]  # (T, 3, 3) corner positions; axis along x
    n = m.corner_normals
    face = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])  # every vertex is on a rim:
    on_cap = np.abs(face[:, 0]) > 0.99 * np.linalg.norm(face, axis=1)  # caps face ±x
    assert on_cap.sum() == 28
    assert np.allclose(n[on_cap][..., 0], np.sign(p[on_cap][..., 0]), atol=1e-6)
    radial = p[~on_cap] - (0.0, 0.0, 1.0)
    radial[..., 0] = 0.0
    radial /= np.linalg.norm(radial, axis=-1, keepdims=True)
    assert np.allclose(n[~on_cap], radial, atol=1e-5)


def test_instances_of_a_glass_mesh_are_each_a_lens_placed_by_their_matrix(empty_blend):
    add_point_light("Lamp", (0.0, 0.0, 6.0))
    block = cube("Ice", location=(0.0, 0.0, 0.0))
    coll = collection_of("Ice tray", block)
    collection_instance("Tray A", coll, location=(2.0, 0.0, 1.0))
    collection_instance("Tray B", coll, location=(-2.0, 0.0, 1.0), scale=(2.0, 2.0, 2.0))
    read = _read()
    assert sorted(m.name for m in read.mesh_lenses) == ["Tray A/Ice", "Tray B/Ice"]
    by = {m.name: m.mesh for m in read.mesh_lenses}
    assert np.allclose(by["Tray A/Ice"].center, (2.0, 0.0, 1.0), atol=1e-6)
    assert np.allclose(by["Tray B/Ice"].center, (-2.0, 0.0, 1.0), atol=1e-6)
    # a unit cube, doubled: half-diagonal √3 / 2 × 2
    assert by["Tray B/Ice"].radius == pytest.approx(math.sqrt(3.0), rel=1e-6)
    assert by["Tray A/Ice"].radius == pytest.approx(math.sqrt(3.0) / 2.0, rel=1e-6)
