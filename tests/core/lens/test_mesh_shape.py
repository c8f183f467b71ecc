"""Issue 24, item 6: a glass object that is no sphere is named by its shape in plain
words (core/lens/mesh_shape.py), from meshes built here by hand; the expected word is
what the mesh was built as."""

from __future__ import annotations

import math

import numpy as np
import pytest
from mesh_shapes import box, cylinder, mesh_arrays, open_edges, transformed, uv_sphere

from core.lens.mesh_shape import (
    BOX,
    CYLINDER,
    ELLIPSOID,
    FLAT_SHEET,
    OPEN_MESH,
    mesh_shape,
    shape_reason,
)
from core.lens.sphere_fit import fit_sphere


def _rotation(ax, ay, az):
    cx, sx, cy, sy, cz, sz = (f(a) for a in (ax, ay, az) for f in (math.cos, math.sin))
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return rz @ ry @ rx


TURN = _rotation(0.3, -0.7, 1.1)

CASES = {
    "Blender's default cylinder": (cylinder(), CYLINDER),
    "a tall thin cylinder, turned": (transformed(*cylinder(16, 0.2, 3.0), TURN), CYLINDER),
    "a hexagonal prism": (cylinder(6), CYLINDER),
    "Blender's default cube": (box(), BOX),
    "a brick, turned": (transformed(*box(3.0, 1.0, 0.5), TURN), BOX),
    "a UV sphere stretched 1.5 × along z": (
        transformed(*uv_sphere(), np.diag([1, 1, 1.5])),
        f"{ELLIPSOID} (axes 1 : 0.67 : 0.67)",
    ),
    "a UV sphere squashed and turned": (
        transformed(*uv_sphere(), TURN @ np.diag([1.0, 0.6, 1.3])),
        f"{ELLIPSOID} (axes 1 : 0.77 : 0.46)",  # 1.3 : 1 : 0.6
    ),
    "a tube without caps": (cylinder(caps=False), OPEN_MESH),
    "a plane": (
        (np.array([(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], float), [[0, 1, 2, 3]]),
        FLAT_SHEET,
    ),
    "a UV sphere too coarse to be one (8 × 4)": (uv_sphere(8, 4), ""),
}


@pytest.mark.parametrize("name", list(CASES))
def test_shape_words(name):
    mesh, word = CASES[name]
    arrays = mesh_arrays(*mesh)
    assert mesh_shape(*arrays, open_edges(mesh[1])) == word
    if word:  # every one of them is no sphere to the fit
        assert not fit_sphere(*arrays).ok


def test_a_sphere_is_none_of_these_and_the_reasons_read_plainly():
    arrays = mesh_arrays(*uv_sphere())
    assert fit_sphere(*arrays).ok and mesh_shape(*arrays) == ""
    assert shape_reason(CYLINDER) == "a cylinder, not a sphere"
    assert shape_reason(BOX) == "a box, not a sphere"
    assert shape_reason(f"{ELLIPSOID} (axes 1 : 0.5 : 0.5)") == (
        "an ellipsoid (axes 1 : 0.5 : 0.5), not a sphere"
    )
    assert shape_reason(OPEN_MESH) == "an open mesh, not a closed surface"
