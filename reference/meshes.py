"""Plain receiver meshes for tests, benchmarks and simple scenes: gridded rectangles
(with UVs) and their union."""

from __future__ import annotations

import numpy as np

from core.caustic_layer.emitters import perpendicular_frame
from core.caustic_layer.receiver_bvh import ReceiverMesh


def rectangle(
    center, normal, size_u, size_v, n_u=1, n_v=1, axis_u=None, object_id=0
) -> ReceiverMesh:
    """A flat ``size_u`` × ``size_v`` rectangle centred at ``center`` facing ``normal``,
    cut into ``n_u`` × ``n_v`` quads (2 triangles each), UV 0..1 across it."""
    nrm = np.asarray(normal, dtype=float)
    nrm = nrm / np.linalg.norm(nrm)
    if axis_u is None:
        au, av = perpendicular_frame(nrm)
    else:
        au = np.asarray(axis_u, dtype=float)
        au = au - (au @ nrm) * nrm
        au /= np.linalg.norm(au)
        av = np.cross(nrm, au)
    s, t = np.meshgrid(
        np.linspace(0.0, 1.0, n_u + 1), np.linspace(0.0, 1.0, n_v + 1), indexing="ij"
    )
    s, t = s.reshape(-1), t.reshape(-1)
    verts = (
        np.asarray(center, dtype=float)
        + ((s - 0.5) * size_u)[:, None] * au
        + ((t - 0.5) * size_v)[:, None] * av
    )
    idx = np.arange((n_u + 1) * (n_v + 1)).reshape(n_u + 1, n_v + 1)
    a, b = idx[:-1, :-1].reshape(-1), idx[1:, :-1].reshape(-1)
    c, d = idx[1:, 1:].reshape(-1), idx[:-1, 1:].reshape(-1)
    tris = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    return ReceiverMesh(
        verts, tris, np.column_stack([s, t]), np.full(len(tris), object_id, dtype=np.int64)
    )


def merge(*meshes: ReceiverMesh) -> ReceiverMesh:
    """One mesh from several (UVs kept only if all have them)."""
    verts, tris, uvs, ids, base = [], [], [], [], 0
    for m in meshes:
        verts.append(np.asarray(m.vertices, dtype=float))
        tris.append(np.asarray(m.triangles, dtype=np.int64) + base)
        uvs.append(m.uvs)
        ids.append(m.ids)
        base += len(m.vertices)
    all_uv = None if any(u is None for u in uvs) else np.concatenate(uvs)
    return ReceiverMesh(np.concatenate(verts), np.concatenate(tris), all_uv, np.concatenate(ids))


def uv_sphere(center, radius, n_lat=12, n_lon=24, object_id=0) -> ReceiverMesh:
    """A latitude–longitude triangulated sphere (poles shared), UV = (lon, lat) in 0..1."""
    lat = np.linspace(0.0, np.pi, n_lat + 1)[1:-1]
    lon = np.linspace(0.0, 2.0 * np.pi, n_lon, endpoint=False)
    la, lo = np.meshgrid(lat, lon, indexing="ij")
    ring = np.stack([np.sin(la) * np.cos(lo), np.sin(la) * np.sin(lo), np.cos(la)], -1)
    verts = np.concatenate([[[0.0, 0.0, 1.0]], ring.reshape(-1, 3), [[0.0, 0.0, -1.0]]])
    uv = np.concatenate(
        [
            [[0.5, 0.0]],
            np.column_stack([lo.reshape(-1) / (2 * np.pi), la.reshape(-1) / np.pi]),
            [[0.5, 1.0]],
        ]
    )
    idx = 1 + np.arange((n_lat - 1) * n_lon).reshape(n_lat - 1, n_lon)
    nxt = np.roll(idx, -1, axis=1)
    top = np.stack([np.zeros(n_lon, dtype=np.int64), idx[0], nxt[0]], 1)
    bottom = np.stack([np.full(n_lon, len(verts) - 1), nxt[-1], idx[-1]], 1)
    a, b, c, d = idx[:-1], idx[1:], nxt[1:], nxt[:-1]
    body = np.concatenate(
        [np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)]
    )
    tris = np.concatenate([top, body, bottom])
    return ReceiverMesh(
        np.asarray(center, dtype=float) + radius * verts,
        tris,
        uv,
        np.full(len(tris), object_id, dtype=np.int64),
    )
