"""Glass meshes traced together for one light (issue 25: "several glass objects on one
path"). Where light through one piece of glass reaches another (a magnifier held over a
pebble, two ice cubes side by side under a low sun), or one piece stands between the
light and another, the pieces are traced as one lens: a `MeshLens` over all their
triangles, each piece with its own index and absorption. Light through the first is
then bent again by the second, and the second's own light is not drawn as if the first
were not there. Pieces that do not meet one another's light stay lenses of their own (a
grid over their common bounding sphere would spend most of its rays between them).

Whether A's light reaches B is probed with a small grid of rays from the light over A's
bounding disc, traced with their branches through A: a share of the light through A
that meets B's triangles on its way out, or a ray on its way to A that meets them
first, joins them. Joins are transitive
(a chain of three pieces is one group)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..lens.mesh import MeshLens

#: Rays per side of the probe grid over a piece's bounding disc.
PROBE = 12
#: Branches lighter than this share of a probe ray are not followed.
PROBE_MIN_WEIGHT = 0.01
#: A piece joins another when at least this share of the light through that other
#: reaches it (less: an internal reflection's stray light, drawn as if the piece
#: were not there, costs less than a grid over both).
PROBE_SHARE = 0.02


def _sphere_t(points, dirs, center, radius):
    """Where rays ``points + t dirs`` enter the sphere (t ≥ 0 while outside; 0 when they
    start inside), inf where they miss it or it lies behind them."""
    oc = points - center
    b = np.einsum("ij,ij->i", oc, dirs)
    c = np.einsum("ij,ij->i", oc, oc) - radius * radius
    disc = b * b - c
    root = np.sqrt(np.maximum(disc, 0.0))
    near, far = -b - root, -b + root
    t = np.where(near >= 0.0, near, np.where(far >= 0.0, 0.0, np.inf))
    return np.where(disc >= 0.0, t, np.inf)


def probe_rays(position, center, radius, n: int = PROBE):
    """(origins, directions) of an n × n grid of rays from ``position`` over the disc of
    the sphere (``center``, ``radius``) across the line of sight (the rays inside it)."""
    p, c = np.asarray(position, float), np.asarray(center, float)
    axis = c - p
    dist = float(np.linalg.norm(axis))
    axis = axis / dist
    helper = np.array([1.0, 0.0, 0.0]) if abs(axis[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = np.cross(axis, helper)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(axis, e1)
    s = (np.arange(n) + 0.5) / n * 2.0 - 1.0
    u, v = np.meshgrid(s, s)
    inside = u * u + v * v <= 1.0
    u, v = u[inside], v[inside]
    targets = c + float(radius) * (u[:, None] * e1 + v[:, None] * e2)
    d = targets - p
    d /= np.linalg.norm(d, axis=1)[:, None]
    return np.broadcast_to(p, d.shape).copy(), d


def reaches(position, lens: MeshLens, others) -> np.ndarray:
    """(K,) bool: which of the `MeshLens` es ``others`` the light at ``position`` reaches
    through ``lens`` with at least `PROBE_SHARE` of what goes through it (its
    transmitted branches, on their way out), or meets first on its way to it (a piece in
    front of the lens)."""
    out = np.zeros(len(others), dtype=bool)
    if not len(others):
        return out
    o, d = probe_rays(position, lens.center, lens.radius)
    t_lens, _ = lens.intersect(o, d)
    aimed = np.isfinite(t_lens) & (t_lens >= 0.0)
    br = lens.trace_branches(o, d, max_depth=6, min_weight=PROBE_MIN_WEIGHT)
    through = (br.crossings >= 2) & (br.weight >= PROBE_MIN_WEIGHT)
    pts, dirs, w = br.points[through], br.directions[through], br.weight[through]
    total = float(w.sum())
    for k, other in enumerate(others):
        # the bounding sphere first (cheap), then the other's own triangles
        near = _sphere_t(o[aimed], d[aimed], other.center, other.radius) < t_lens[aimed]
        if near.any():
            t, _ = other.intersect(o[aimed][near], d[aimed][near])
            if (np.isfinite(t) & (t < t_lens[aimed][near])).any():
                out[k] = True
                continue
        toward = _sphere_t(pts, dirs, other.center, other.radius) < np.inf
        if total > 0.0 and w[toward].sum() >= PROBE_SHARE * total:
            t, _ = other.intersect(pts[toward], dirs[toward])
            out[k] = bool(w[toward][np.isfinite(t)].sum() >= PROBE_SHARE * total)
    return out


def glass_groups(positions, lenses) -> list[list[int]]:
    """The groups (lists of indices into ``lenses``, `MeshLens` es, each group sorted,
    groups by their first) of pieces traced together for one light; ``positions``
    (K, 3): the light's point toward each piece (a sun's stands in at a distance)."""
    k = len(lenses)
    parent = list(range(k))

    def root(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    if k > 1:
        for a in range(k):
            others = [b for b in range(k) if b != a]
            hit = reaches(positions[a], lenses[a], [lenses[b] for b in others])
            for b in np.asarray(others)[hit].tolist():
                parent[root(b)] = root(a)
    groups: dict[int, list[int]] = {}
    for i in range(k):
        groups.setdefault(root(i), []).append(i)
    return sorted(groups.values())


@dataclass(frozen=True)
class JoinedMesh:
    """The pieces of a group as one triangle list: ``vertices`` (V, 3), ``triangles``
    (T, 3), ``corner_normals`` (T, 3, 3), ``triangle_ior`` and ``triangle_absorption``
    (T,), and the bounding sphere (``center``, ``radius``) of all of them."""

    vertices: np.ndarray
    triangles: np.ndarray
    corner_normals: np.ndarray
    triangle_ior: np.ndarray
    triangle_absorption: np.ndarray
    center: np.ndarray
    radius: float


def join(lenses) -> JoinedMesh:
    """The `MeshLens` es ``lenses`` as one triangle list (their shading normals kept)."""
    verts, tris, normals, ior, absorption = [], [], [], [], []
    offset = 0
    for m in lenses:
        verts.append(m.vertices)
        tris.append(m.triangles + offset)
        normals.append(m.corner_normals)
        ior.append(m.triangle_ior)
        absorption.append(m.triangle_absorption)
        offset += len(m.vertices)
    v = np.concatenate(verts)
    center = 0.5 * (v.min(axis=0) + v.max(axis=0))
    return JoinedMesh(
        vertices=v,
        triangles=np.concatenate(tris),
        corner_normals=np.concatenate(normals),
        triangle_ior=np.concatenate(ior),
        triangle_absorption=np.concatenate(absorption),
        center=center,
        radius=float(np.linalg.norm(v - center, axis=1).max()) * (1.0 + 1e-9),
    )
