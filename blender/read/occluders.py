"""First hits of rays against what the scene reader saw, without Blender's
`Scene.ray_cast`.

`Scene.ray_cast` visits every object instance of the depsgraph for each ray (about
1.5 ms per ray with 10 000 geometry-nodes instances, 5 ms with 10 000 collection
instances, ten times that at 100 000), and the generator casts five rays per beam.
Here the geometry the reader already has is used:

* the spheres (every instance that passed the sphere fit, lens or not) are hit
  analytically, all at once in numpy (`core.scene.ray_hits.sphere_hits`);
* every other mesh instance (floors, walls, ellipsoids …) is first tested by its
  world bounding box (a vectorised slab test, `core.scene.ray_hits.box_entries`); only
  the boxes a ray enters nearer than the best hit so far are tested exactly, against
  a `mathutils.bvhtree.BVHTree` of the instanced mesh in its local space (built
  once per mesh, on first use).

Curves, text, surfaces and metaballs are hit as their evaluated mesh; hair curves,
point clouds, volumes and grease pencil do not block (as for `Scene.ray_cast`,
which sees only meshes). A sphere is hit as the exact sphere, not its polygons
(the difference is under 1 % of the radius, the fit's tolerance).
"""

from __future__ import annotations

import math

import numpy as np

from ...core.scene.ray_hits import (
    BATCH_CELLS,
    box_entries,
    box_entries_bundles,
    sphere_hits,
    sphere_hits_bundles,
)

#: Hits nearer than this share of the scene size to the ray's origin are ignored
#: (the surface a ray starts on).
EPSILON = 1e-9


class MeshSource:
    """The local-space triangles of one (evaluated) mesh, read on first use."""

    def __init__(self, mesh=None, arrays=None):
        self._mesh, self._arrays, self._tree = mesh, arrays, None

    @staticmethod
    def from_object(ob):
        """Triangles of a non-mesh object (curve, text, surface, metaball) now,
        through `Object.to_mesh` (its mesh lives only as long as the object)."""
        try:
            mesh = ob.to_mesh()
        except RuntimeError:
            return None
        try:
            return MeshSource(arrays=mesh_triangles(mesh)) if mesh is not None else None
        finally:
            ob.to_mesh_clear()

    def release(self):
        """Forget the evaluated mesh (it is freed with its depsgraph); a source not
        read yet then blocks nothing."""
        self._mesh = None

    def tree(self):
        if self._tree is None:
            from mathutils.bvhtree import BVHTree

            if self._arrays is None:
                if self._mesh is None:
                    self._tree = False
                    return self._tree
                self._arrays = mesh_triangles(self._mesh)
                self._mesh = None
            v, t = self._arrays
            self._tree = (
                BVHTree.FromPolygons(v.tolist(), t.tolist(), all_triangles=True)
                if len(t)
                else False
            )
        return self._tree


def mesh_triangles(mesh):
    """(vertices N × 3, triangles M × 3) of a mesh."""
    v = np.empty(len(mesh.vertices) * 3)
    mesh.vertices.foreach_get("co", v)
    tris = mesh.loop_triangles
    t = np.empty(len(tris) * 3, dtype=np.int64)
    tris.foreach_get("vertices", t)
    return v.reshape(-1, 3), t.reshape(-1, 3)


class Occluders:
    """Spheres (centres, radii) and other mesh instances (matrices, world boxes,
    one `MeshSource` per group) of a read scene."""

    def __init__(self, centers, radii, matrices, box_lo, box_hi, source_index, sources):
        self.centers = np.asarray(centers, dtype=float).reshape(-1, 3)
        self.radii = np.asarray(radii, dtype=float).reshape(-1)
        self.matrices = np.asarray(matrices, dtype=float).reshape(-1, 4, 4)
        self.box_lo = np.asarray(box_lo, dtype=float).reshape(-1, 3)
        self.box_hi = np.asarray(box_hi, dtype=float).reshape(-1, 3)
        self.source_index = np.asarray(source_index, dtype=np.int64)
        self.sources = list(sources)
        self._inverse = None

    def release(self):
        """Call when the depsgraph the occluders were read from goes away."""
        for source in self.sources:
            source.release()

    def first_hit(self, origins, direction, limit) -> np.ndarray:
        """Distance from each origin (k × 3) along the unit `direction` to the first
        surface, within `limit` (inf: nothing)."""
        origins = np.asarray(origins, dtype=float).reshape(-1, 3)
        d = np.asarray(direction, dtype=float)
        d = d / np.linalg.norm(d)
        best = sphere_hits(self.centers, self.radii, origins, d)
        if len(self.source_index):
            enter, hit_box = box_entries(self.box_lo, self.box_hi, origins, d, limit)
            for k in range(len(origins)):
                cand = np.flatnonzero(hit_box[k])
                if cand.size == 0:
                    continue
                order = cand[np.argsort(np.maximum(enter[k, cand], 0.0))]
                for n in order:
                    if max(enter[k, n], 0.0) >= best[k]:
                        break
                    t = self._mesh_hit(n, origins[k], d)
                    if t < best[k]:
                        best[k] = t
        return np.where(best <= limit, best, np.inf)

    def first_hits(self, origins, directions, limit) -> np.ndarray:
        """`first_hit` of many bundles at once: `origins` (B × k × 3), one unit
        direction per bundle (B × 3) → (B × k). Spheres for all bundles in one
        numpy pass; the boxes likewise; then only the meshes whose box a ray
        enters nearer than its best hit so far, each transformed in numpy and cast
        against the mesh's BVH (the same hits as `first_hit` bundle by bundle)."""
        origins = np.asarray(origins, dtype=float)
        B, k = origins.shape[:2]
        d = np.asarray(directions, dtype=float).reshape(-1, 3)
        d = d / np.sqrt(np.sum(d * d, axis=1))[:, None]
        best = sphere_hits_bundles(self.centers, self.radii, origins, d)
        N = len(self.source_index)
        if N and B:
            step = max(1, BATCH_CELLS // (k * N))
            rays, boxes, enters = [], [], []
            for b0 in range(0, B, step):
                enter, hit = box_entries_bundles(
                    self.box_lo, self.box_hi, origins[b0 : b0 + step], d[b0 : b0 + step], limit
                )
                e = np.maximum(enter, 0.0)
                bi, ki, ni = np.nonzero(hit & (e < best[b0 : b0 + step, :, None]))
                rays.append((b0 + bi) * k + ki)
                boxes.append(ni)
                enters.append(e[bi, ki, ni])
            ray, box, enter = (np.concatenate(x) for x in (rays, boxes, enters))
            if ray.size:
                flat = best.reshape(-1)
                self._mesh_hits(ray, box, enter, origins.reshape(-1, 3), d, k, flat)
                best = flat.reshape(B, k)
        return np.where(best <= limit, best, np.inf)

    def _mesh_hits(self, ray, box, enter, origins, d, k, best):
        """Lower `best` (per ray) by the meshes `box` that `ray` enters at `enter`,
        nearest box first per ray, skipping boxes entered beyond the best hit so far
        (told by the BVH's own distance); the hits' world distances as `_mesh_hit`'s,
        in numpy at the end."""
        from mathutils import Vector

        order = np.lexsort((enter, ray))
        ray, box, enter = ray[order], box[order], enter[order]
        if self._inverse is None:
            self._inverse = np.linalg.pinv(self.matrices)
        inv = self._inverse[box]
        dirs = d[ray // k]
        o = np.einsum("pij,pj->pi", inv[:, :3, :3], origins[ray]) + inv[:, :3, 3]
        v = np.einsum("pij,pj->pi", inv[:, :3, :3], dirs)
        vlen = np.sqrt(np.sum(v * v, axis=1))
        ok = (np.all(np.isfinite(o), axis=1) & (vlen > 0)).tolist()
        near = best.tolist()  # the running best, for skipping boxes
        # per ray only Python floats and lists (the loop runs ~1 000 times a live
        # update): each pair's tree looked up once per box, the ray handed to the BVH
        # in `Vector`s
        tree_of = [None] * len(self.source_index)  # (built when a ray first needs it)
        source_of = self.source_index.tolist()
        hit_pairs, hit_locs = [], []
        ray_l, box_l, enter_l = ray.tolist(), box.tolist(), enter.tolist()
        o_l, v_l, len_l = o.tolist(), v.tolist(), vlen.tolist()
        for p in range(len(ray_l)):
            r = ray_l[p]
            if enter_l[p] >= near[r] or not ok[p]:
                continue
            tree = tree_of[box_l[p]]
            if tree is None:
                tree = tree_of[box_l[p]] = self.sources[source_of[box_l[p]]].tree()
            if not tree:
                continue
            loc, _normal, _index, dist = tree.ray_cast(Vector(o_l[p]), Vector(v_l[p]))
            if loc is None:
                continue
            hit_pairs.append(p)
            hit_locs.append(loc[:])
            near[r] = min(near[r], dist / len_l[p])
        if hit_pairs:
            p = np.asarray(hit_pairs)
            m = self.matrices[box[p]]
            w = np.einsum("pij,pj->pi", m[:, :3, :3], np.asarray(hit_locs)) + m[:, :3, 3]
            t = np.einsum("pj,pj->p", w - origins[ray[p]], dirs[p])
            np.minimum.at(best, ray[p], np.where(t > 0, t, np.inf))
        return best

    def _mesh_hit(self, n, origin, d) -> float:
        from mathutils import Vector

        tree = self.sources[self.source_index[n]].tree()
        if not tree:
            return math.inf
        if self._inverse is None:
            self._inverse = np.linalg.pinv(self.matrices)
        m, inv = self.matrices[n], self._inverse[n]
        o = inv[:3, :3] @ origin + inv[:3, 3]
        v = inv[:3, :3] @ d
        if not np.all(np.isfinite(o)) or not np.linalg.norm(v) > 0:
            return math.inf
        loc, _normal, _index, _dist = tree.ray_cast(Vector(o), Vector(v))
        if loc is None:
            return math.inf
        w = m[:3, :3] @ np.asarray(loc) + m[:3, 3]
        t = float((w - origin) @ d)
        return t if t > 0 else math.inf
