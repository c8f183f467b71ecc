"""Issue 25: which glass meshes are closed volumes the mesh lens traces, and the mesh
placed in world space (core/lens/closed_mesh.py), on meshes written out by hand."""

from __future__ import annotations

import numpy as np

from core.lens.closed_mesh import (
    INWARD_REASON,
    OPEN_REASON,
    LocalMesh,
    mean_chord,
    problem,
    signed_volume,
    world_mesh,
)

# A unit cube [0, 1]³: 8 corners, 12 outward triangles (counter-clockwise seen from
# outside), written out face by face.
CUBE_V = np.array(
    [[x, y, z] for x in (0.0, 1.0) for y in (0.0, 1.0) for z in (0.0, 1.0)]
)  # index = 4x + 2y + z
CUBE_T = np.array(
    [
        [0, 1, 3], [0, 3, 2],  # x = 0 (normal −x)
        [4, 6, 7], [4, 7, 5],  # x = 1
        [0, 4, 5], [0, 5, 1],  # y = 0
        [2, 3, 7], [2, 7, 6],  # y = 1
        [0, 2, 6], [0, 6, 4],  # z = 0
        [1, 5, 7], [1, 7, 3],  # z = 1
    ]
)  # fmt: skip


def test_closed_cube_is_a_volume():
    assert problem(CUBE_V, CUBE_T) == ""
    assert abs(signed_volume(CUBE_V, CUBE_T) - 1.0) < 1e-12
    # Cauchy: 4 V / S = 4 / 6 for the unit cube
    assert abs(mean_chord(CUBE_V, CUBE_T) - 4.0 / 6.0) < 1e-12


def test_open_and_inward_and_flipped_and_fanned():
    assert problem(CUBE_V, CUBE_T[2:]) == OPEN_REASON  # one face missing
    assert problem(CUBE_V, CUBE_T[:, ::-1]) == INWARD_REASON
    one_flipped = CUBE_T.copy()
    one_flipped[0] = one_flipped[0, ::-1]
    assert problem(CUBE_V, one_flipped).startswith("faces flipped")
    # an inner wall (two triangles through the diagonal 0–7, both sides): edges in 4
    fanned = np.vstack([CUBE_T, [[0, 6, 7], [0, 7, 1]], [[0, 7, 6], [0, 1, 7]]])
    assert problem(CUBE_V, fanned).startswith("non-manifold")
    assert problem(CUBE_V, np.zeros((0, 3), int)) == "no faces"


def test_split_vertices_are_welded():
    # every triangle with its own three vertices (a mesh split on every edge)
    v = CUBE_V[CUBE_T].reshape(-1, 3)
    t = np.arange(len(v)).reshape(-1, 3)
    assert problem(v, t) == ""


def test_world_mesh_places_normals_by_inverse_transpose_and_mirrors():
    n = np.zeros((12, 3, 3))
    # a smooth-shaded corner normal along (1, 1, 0)/√2 everywhere (a direction test)
    n[:] = np.array([1.0, 1.0, 0.0]) / np.sqrt(2.0)
    local = LocalMesh(CUBE_V, CUBE_T, n)
    m = np.diag([2.0, 1.0, 1.0, 1.0])
    m[:3, 3] = (5.0, 0.0, 0.0)
    w = world_mesh(local, m)
    assert np.allclose(w.vertices[7], (7.0, 1.0, 1.0))
    # inverse transpose of diag(2,1,1) is diag(½,1,1): (½, 1, 0)/|…|
    expect = np.array([0.5, 1.0, 0.0]) / np.hypot(0.5, 1.0)
    assert np.allclose(w.corner_normals[3, 1], expect)
    assert np.allclose(w.center, (6.0, 0.5, 0.5))
    assert abs(w.radius - np.sqrt(1.0 + 0.25 + 0.25)) < 1e-12
    assert problem(w.vertices, w.triangles) == ""
    mirror = np.diag([-1.0, 1.0, 1.0, 1.0])
    wm = world_mesh(local, mirror)
    assert problem(wm.vertices, wm.triangles) == ""  # still outward
    assert np.allclose(wm.triangles[0], CUBE_T[0, ::-1])
