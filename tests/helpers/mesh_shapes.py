"""Meshes as the Blender reader hands them over (vertices; per face its centre — the
vertex mean —, unit outward normal and area), built here by hand: a UV sphere, a
cylinder, a box, for the shape words' tests."""

from __future__ import annotations

import numpy as np


def face_data(verts, faces):
    """(centres, unit outward normals, areas) of polygon `faces` (vertex indices) of a
    mesh around its vertex mean."""
    centers, normals, areas = [], [], []
    for f in faces:
        p = verts[f]
        cross = sum(np.cross(p[k] - p[0], p[k + 1] - p[0]) for k in range(1, len(p) - 1))
        area = np.linalg.norm(cross) / 2
        n = cross / (2 * area)
        if n @ (p.mean(axis=0) - verts.mean(axis=0)) < 0:
            n = -n
        centers.append(p.mean(axis=0))
        normals.append(n)
        areas.append(area)
    return np.array(centers), np.array(normals), np.array(areas)


def uv_sphere(segments=32, rings=16):
    """Blender's UV sphere of radius 1: (vertices, faces)."""
    lat = np.pi * np.arange(1, rings) / rings
    lon = 2 * np.pi * np.arange(segments) / segments
    ring = np.stack(
        [
            np.outer(np.sin(lat), np.cos(lon)),
            np.outer(np.sin(lat), np.sin(lon)),
            np.repeat(np.cos(lat)[:, None], segments, axis=1),
        ],
        axis=-1,
    )
    verts = np.concatenate([[[0, 0, 1]], ring.reshape(-1, 3), [[0, 0, -1]]])
    idx = lambda i, j: 1 + i * segments + (j % segments)  # noqa: E731
    faces = []
    for j in range(segments):
        faces.append([0, idx(0, j), idx(0, j + 1)])
        faces.append([len(verts) - 1, idx(rings - 2, j + 1), idx(rings - 2, j)])
    for i in range(rings - 2):
        for j in range(segments):
            faces.append([idx(i, j), idx(i + 1, j), idx(i + 1, j + 1), idx(i, j + 1)])
    return verts, faces


def cylinder(segments=32, radius=1.0, depth=2.0, caps=True):
    """Blender's cylinder (n-gon caps): (vertices, faces)."""
    lon = 2 * np.pi * np.arange(segments) / segments
    ring = np.column_stack([radius * np.cos(lon), radius * np.sin(lon)])
    verts = np.concatenate(
        [np.column_stack([ring, np.full(segments, z)]) for z in (-depth / 2, depth / 2)]
    )
    faces = [
        [j, (j + 1) % segments, segments + (j + 1) % segments, segments + j]
        for j in range(segments)
    ]
    if caps:
        faces += [list(range(segments)), list(range(segments, 2 * segments))]
    return verts, faces


def box(sx=2.0, sy=2.0, sz=2.0):
    """An axis-aligned box of sides sx × sy × sz about the origin: (vertices, faces)."""
    verts = np.array(
        [(x, y, z) for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=float
    ) * (0.5 * np.array([sx, sy, sz]))
    faces = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]]
    return verts, faces


def transformed(verts, faces, matrix):
    """A mesh's vertices through a 3 × 3 `matrix` (its faces unchanged)."""
    return np.asarray(verts) @ np.asarray(matrix, dtype=float).T, faces


def mesh_arrays(verts, faces):
    """(vertices, face centres, normals, areas): what `fit_sphere` takes."""
    verts = np.asarray(verts, dtype=float)
    return (verts, *face_data(verts, faces))


def open_edges(faces) -> int:
    """Edges of one face only, counted here by hand."""
    count: dict = {}
    for f in faces:
        for k in range(len(f)):
            e = tuple(sorted((f[k], f[(k + 1) % len(f)])))
            count[e] = count.get(e, 0) + 1
    return sum(1 for c in count.values() if c == 1)
