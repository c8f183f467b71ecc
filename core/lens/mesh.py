"""Any closed glass mesh, traced exactly: rays through its triangles (a numpy BVH), Snell
and unpolarised Fresnel at every crossing with the normals Blender shades with, total
internal reflection, partial internal reflections up to a budget, Beer absorption inside.

The rays move in waves: every live path segment of every ray is cast at once (a convex
mesh's: its one hit on the side the segment is on, found by walking the surface from a
guess, `core.shared.surface_walk`, the BVH only where a walk does not arrive; any other
mesh's: the nearest hit, from the BVH), and each hit makes the next wave's segments (the
transmitted and, when branches are followed, the reflected part). Which side of the
surface a hit is on comes from the triangle's geometric normal (outward by the winding):
crossing from outside is an entry, from inside an exit, so a crack or a re-entry (a
concave mesh, the light leaving and meeting the glass again) needs no bookkeeping. The
optics use the shading normal (the corner normals interpolated with the hit's
barycentrics, renormalised, turned to the geometric normal's side). A shading normal can
disagree with the surface: where the ray would meet it from behind, or where the
refracted or reflected ray it gives would cross back to the wrong side of the triangle,
that crossing uses the geometric normal instead (continuous at the places where both
agree, and no ray is stuck or leaks). Each new segment starts a hair (``eps``, 1e-7 of
the radius) off the surface on the side it travels to (along its own line, which stays
exact), so it cannot hit the triangle it left.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import ClassVar

import numpy as np

from ..shared import parallel
from ..shared.surface_walk import build_walk, intersect_convex
from ..shared.triangle_bvh import build_bvh
from ..shared.triangle_bvh import intersect as bvh_intersect
from ..shared.vectors import cross, dot, norm
from .base import BranchRays, ExitRays, Lens
from .refraction import fresnel_from_cosines, refract

#: Corner normals closer than this (cosine) on both ends of a shared edge: one smooth
#: face group there (the path signature does not change across the edge).
SMOOTH_COS = 0.9999
#: The sine of a fold between two faces below which `MeshLens.convex` calls them flat.
FLAT_SIN = 1e-4
_HASH = np.uint64(1_000_003)
#: Rays from which a walk is split over threads (≥ half of them each). A walk's steps
#: are many short numpy calls on the rays still walking (the Python between them holds
#: the GIL): at a Generate's ~17 000 rays two threads took as long as one, with up to
#: 25 % more CPU (bench glass_generate_speed, issue 25), so only far larger walks split.
WALK_ROWS = 1 << 17


def canonical_order(triangles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(T, 3) corner order of each triangle (from its lowest vertex index, the winding
    kept) and the order of the triangles (by their corners so turned): the same mesh
    in any face order and corner rotation gives one list."""
    t = len(triangles)
    rot = (np.argmin(triangles, axis=1)[:, None] + np.arange(3)) % 3
    turned = np.take_along_axis(triangles, rot, axis=1)
    order = np.lexsort((turned[:, 2], turned[:, 1], turned[:, 0])) if t else np.zeros(0, int)
    return rot, order


def _unit(v):
    n = norm(v)[..., None]
    return v / np.where(n > 0.0, n, 1.0)


@dataclass
class _Segments:
    """Live path segments (flat, one row each): which ray, where it starts (``origin``,
    a hair off the surface; ``at`` the exact point), its direction, its power in the
    s and p parts of the last crossing (``ws``, ``wp``; ``s_dir`` the unit s direction
    there, 0 before the first), length inside so far, crossings, path hash, the
    triangle it left (−1: none) and whether it was launched into the glass."""

    ray: np.ndarray
    origin: np.ndarray
    at: np.ndarray
    direction: np.ndarray
    ws: np.ndarray
    wp: np.ndarray
    s_dir: np.ndarray
    path: np.ndarray
    crossings: np.ndarray
    signature: np.ndarray
    face: np.ndarray
    inside: np.ndarray

    @property
    def weight(self) -> np.ndarray:
        return self.ws + self.wp

    def take(self, rows) -> _Segments:
        """The rows of a mask or an index array (np.take by index: faster than a
        boolean mask on the (n, 3) fields)."""
        rows = np.asarray(rows)
        idx = np.flatnonzero(rows) if rows.dtype == bool else rows
        return _Segments(*(np.take(getattr(self, f), idx, axis=0) for f in _FIELDS))

    @staticmethod
    def join(parts) -> _Segments:
        return _Segments(
            *(
                np.concatenate([getattr(p, f) for p in parts])
                for f in _Segments.__dataclass_fields__
            )
        )


class MeshLens(Lens):
    """A closed, outward-oriented triangle mesh of glass in air.

    ``center``/``radius``: its bounding sphere (world; the radius grown to hold every
    vertex if it does not); ``ior``: relative index;
    ``absorption``: Beer per unit length (as the ball's); ``vertices`` (V, 3) world
    coordinates; ``triangles`` (T, 3) vertex indices; ``corner_normals`` (T, 3, 3): the
    shading normal at each triangle corner as Blender shades (None: flat, the face
    normals). Several pieces of glass traced together (light through one, then the
    other: `core.caustic_layer.glass_groups`) may differ in index and absorption:
    ``triangle_ior`` / ``triangle_absorption`` (T,) per triangle (None: ``ior`` /
    ``absorption`` everywhere). The BVH is built once, here."""

    point_image: ClassVar[bool] = False

    def __init__(
        self,
        center,
        radius,
        ior,
        absorption,
        vertices,
        triangles,
        corner_normals=None,
        triangle_ior=None,
        triangle_absorption=None,
    ) -> None:
        self.center = np.asarray(center, dtype=float).reshape(3)
        self.ior = float(ior)
        self.absorption = float(absorption)
        self.vertices = np.asarray(vertices, dtype=float).reshape(-1, 3)
        # the ray grids cover the bounding sphere: it must hold every vertex
        reach = np.linalg.norm(self.vertices - self.center, axis=1).max(initial=0.0)
        self.radius = max(float(radius), float(reach) * (1.0 + 1e-9))
        # one order of the triangles, and of each one's corners, whatever Blender's: it
        # may hand the same mesh's faces in another order run to run (a UV sphere), and
        # sums over them would differ in their last bits
        rot, order = canonical_order(np.asarray(triangles, dtype=np.int64).reshape(-1, 3))
        self.triangles = np.take_along_axis(
            np.asarray(triangles, dtype=np.int64).reshape(-1, 3), rot, axis=1
        )[order]
        corners = self.vertices[self.triangles]
        c = cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
        self.face_normals = _unit(c)  # outward by the winding
        if corner_normals is None:
            cn = np.repeat(self.face_normals[:, None, :], 3, axis=1)
        else:
            cn = np.asarray(corner_normals, dtype=float).reshape(-1, 3, 3)
            cn = _unit(np.take_along_axis(cn, rot[:, :, None], axis=1)[order])
        self.corner_normals = cn
        scale = max(self.radius, float(np.abs(self.vertices).max(initial=0.0)) * 1e-2)
        self.eps = 1e-7 * scale
        t = len(self.triangles)
        self.triangle_ior = _per_triangle(triangle_ior, self.ior, t)[order]
        self.triangle_absorption = _per_triangle(triangle_absorption, self.absorption, t)[order]
        self.bvh = build_bvh(self.vertices, self.triangles)

    # ------------------------------------------------------------------ the interface

    def bounding_sphere(self):
        return self.center, np.asarray(self.radius)

    def intersect(self, origins, directions):
        o, d, shape = _flat(origins, directions)
        h = bvh_intersect(self.bvh, o, d)
        hit = h.triangle >= 0
        nrm = np.where(hit[:, None], self.face_normals[np.maximum(h.triangle, 0)], 0.0)
        return h.t.reshape(shape), nrm.reshape((*shape, 3))

    def trace(self, origins, directions, aimed: bool = False) -> ExitRays:
        """The straight transmitted path: transmitted at every crossing unless totally
        reflected (then reflected, weight unchanged), re-entering where the light meets
        the glass again, up to 32 crossings; Fresnel × Beer in ``weight``."""
        b = self._walk(origins, directions, max_depth=32, min_weight=0.0, split=False)
        return ExitRays(b.points[0], b.directions[0], b.weight[0], b.hit[0], b.path[0])

    def trace_branches(self, origins, directions, max_depth: int = 8, min_weight: float = 1e-3):
        return self._walk(origins, directions, max_depth, min_weight, split=True)

    # ------------------------------------------------------------------ the topology

    @cached_property
    def _edges(self):
        """Each interior edge once: (triangle a, triangle b, corner k of a where the
        edge starts, its two vertex indices), from the sorted half-edges."""
        t = len(self.triangles)
        k0 = np.tile(np.arange(3), t)
        tri = np.repeat(np.arange(t), 3)
        a, b = self.triangles[tri, k0], self.triangles[tri, (k0 + 1) % 3]
        lo, hi = np.minimum(a, b), np.maximum(a, b)
        order = np.lexsort((hi, lo))
        lo, hi, tri, k0 = lo[order], hi[order], tri[order], k0[order]
        i = np.nonzero((lo[1:] == lo[:-1]) & (hi[1:] == hi[:-1]))[0]
        return tri[i], tri[i + 1], lo[i], hi[i]

    @cached_property
    def convex(self) -> bool:
        """Whether the mesh is convex: one piece, and at every edge each face's far
        vertex lies on or behind the other face (a connected closed surface convex at
        every edge is convex). Then light that has left it never meets it again: no
        re-entry test."""
        ta, tb, _, _ = self._edges
        if len(ta) * 2 != 3 * len(self.triangles):
            return False  # not every edge shared by two faces
        if _components(ta, tb, len(self.triangles)).max(initial=0) > 0:
            return False  # several pieces
        v = self.vertices
        tol = 1e-9 * max(self.radius, 1e-300)
        for x, cy in ((ta, self.triangles[tb]), (tb, self.triangles[ta])):
            n, p0 = self.face_normals[x], v[self.triangles[x, 0]]
            off = v[cy] - p0[:, None, :]
            # a flat quad read from Blender's float32 coordinates bends by ~1e-6 of its
            # size either way: a fold below FLAT_SIN (of the far vertex's distance)
            # is flat (a ray grazing so close to the plane carries no flux to speak of)
            slack = tol + FLAT_SIN * np.linalg.norm(off, axis=2)
            if (dot(off, n[:, None, :]) > slack).any():
                return False
        return True

    @cached_property
    def walker(self):
        """The BVH with the edge neighbours and a cube map of guesses
        (`core.shared.surface_walk`): a convex mesh's waves walk its surface to their
        hits instead of traversing the BVH."""
        return build_walk(self.bvh)

    def _cast(self, seg):
        """The nearest hit of each segment (a convex mesh: its one hit on the side the
        segment is on, found by walking where it can)."""
        if not self.convex:
            return bvh_intersect(self.bvh, seg.origin, seg.direction)
        side = np.where(seg.inside, -1, 1)
        return intersect_convex(self.walker, seg.origin, seg.direction, side)

    # ------------------------------------------------------------------ the groups

    @cached_property
    def face_groups(self) -> np.ndarray:
        """(T,) smooth face group of each triangle: connected across edges whose two
        corner normals agree at both ends (a smooth sphere: one group; a cube: six)."""
        t = len(self.triangles)
        if t == 0:
            return np.zeros(0, dtype=np.int64)
        ta, tb, lo, hi = self._edges
        cn = self.corner_normals

        def normal_at(rows, vertex):  # the corner normal of triangle rows at that vertex
            k = np.argmax(self.triangles[rows] == vertex[:, None], axis=1)
            return cn[rows, k]

        smooth = np.ones(len(ta), dtype=bool)
        for vtx in (lo, hi):
            smooth &= dot(normal_at(ta, vtx), normal_at(tb, vtx)) >= SMOOTH_COS
        return _components(ta[smooth], tb[smooth], len(self.triangles))

    # ------------------------------------------------------------------ the walk

    def _walk(self, origins, directions, max_depth, min_weight, split) -> BranchRays:
        """Every ray's paths (`trace_branches`; ``split`` False: `trace`'s one path).
        Each ray's paths are its own: blocks of rays walk in threads (numpy lets go of
        the GIL in its loops), each block's waves inline, and the blocks' branches
        joined in ray order give what one walk of all the rays gives."""
        o, d, shape = _flat(origins, directions)
        groups = self.face_groups if split else np.zeros(len(self.triangles), dtype=np.int64)
        if self.convex:  # built once here, not by the threads
            _ = self.walker

        def run(block: slice):
            with parallel.inline():
                return self._walk_block(o[block], d[block], max_depth, min_weight, split, groups)

        blocks = parallel.split(len(o), parallel.workers(len(o), WALK_ROWS))
        if len(blocks) == 1:
            parts = [self._walk_block(o, d, max_depth, min_weight, split, groups)]
        else:
            parts = parallel.map_slices(run, len(o), threads=len(blocks))
        for (out, *_), block in zip(parts, blocks, strict=True):
            out.ray += block.start
        out = _Segments.join([p[0] for p in parts])
        absorbed, dropped, leaked = (np.concatenate([p[i] for p in parts]) for i in (1, 2, 3))
        return _assemble(out, o, d, shape, absorbed, dropped, leaked)

    def _walk_block(self, o, d, max_depth, min_weight, split, groups):
        """The finished segments of the rays (o, d) (rows of a block) and per ray the
        weight absorbed, dropped, and whether some leaked."""
        n = len(o)
        seg = _Segments(
            ray=np.arange(n),
            origin=o,
            at=o,
            direction=d,
            ws=np.full(n, 0.5),
            wp=np.full(n, 0.5),
            s_dir=np.zeros((n, 3)),
            path=np.zeros(n),
            crossings=np.zeros(n, dtype=np.int64),
            signature=np.zeros(n, dtype=np.uint64),
            face=np.full(n, -1, dtype=np.int64),
            inside=np.zeros(n, dtype=bool),
        )
        done: list[_Segments] = []
        absorbed = np.zeros(n)
        dropped = np.zeros(n)
        leaked = np.zeros(n, dtype=bool)
        for _wave in range(max_depth + 1):
            if len(seg.ray) == 0:
                break
            # a convex mesh: one way in (a face toward the ray), one way out
            h = self._cast(seg)
            miss = h.triangle < 0
            done.append(seg.take(miss & ~seg.inside))
            lost = miss & seg.inside  # a crack: nothing to leave by
            np.add.at(dropped, seg.ray[lost], seg.weight[lost])
            leaked[seg.ray[lost]] = True
            over = ~miss & (seg.crossings >= max_depth)
            np.add.at(dropped, seg.ray[over], seg.weight[over])
            keep = np.flatnonzero(~miss & ~over)
            seg, h_tri = seg.take(keep), h.triangle[keep]
            t, u, v, p = h.t[keep], h.u[keep], h.v[keep], h.point[keep]
            if len(seg.ray) == 0:
                seg = seg.take(np.zeros(0, dtype=bool))
                break
            kid_t, kid_r, tir = self._cross(seg, h_tri, t, u, v, p, groups, absorbed)
            # one path (`trace`): the reflected part is followed only where it is total
            kids = [kid_t, kid_r] if split else [kid_t, kid_r.take(tir)]
            nxt = _Segments.join(kids)
            small = nxt.weight < min_weight
            small |= nxt.weight <= 0.0
            np.add.at(dropped, nxt.ray[small], nxt.weight[small])
            if self.convex:  # what leaves a convex glass never meets it again
                done.append(nxt.take(~nxt.inside & ~small))
                seg = nxt.take(nxt.inside & ~small)
            else:
                seg = nxt.take(~small)
        np.add.at(dropped, seg.ray, seg.weight)  # still live after the last wave
        return _Segments.join(done), absorbed, dropped, leaked

    def _cross(self, seg, tri, t, u, v, p, groups, absorbed):
        """One surface crossing of every segment: Beer on the way if it ran inside,
        then the transmitted and the reflected children (the s and p parts times their
        Fresnel transmittances t_s, t_p and 1 − t_s, 1 − t_p) and where the crossing
        totally reflects."""
        ng = self.face_normals[tri]
        exiting = dot(seg.direction, ng) > 0.0  # the hit seen from inside
        inside = np.where(exiting, norm(p - seg.at), 0.0)  # from the surface
        # a piece's light leaves it where it entered it (pieces never overlap)
        att = 1.0  # clear glass (the usual): no exponentials, nothing absorbed
        if self.triangle_absorption.any():
            att = np.exp(-self.triangle_absorption[tri] * inside)
            np.add.at(absorbed, seg.ray, seg.weight * (1.0 - att))
        path = seg.path + inside
        cn = self.corner_normals[tri]
        bary = np.stack([1.0 - u - v, u, v], axis=1)
        ns = _unit(np.einsum("nk,nki->ni", bary, cn))
        ns = np.where((dot(ns, ng) < 0.0)[:, None], -ns, ns)
        sgn = np.where(exiting, -1.0, 1.0)[:, None]
        facing = sgn * ng  # geometric normal toward the incoming side
        nsf = sgn * ns
        ior = self.triangle_ior[tri]
        eta = np.where(exiting, ior, 1.0 / ior)
        d = seg.direction
        use_geo = dot(d, nsf) >= 0.0  # the shading normal meets the ray from behind
        nrm = np.where(use_geo[:, None], facing, nsf)
        rf = refract(d, nrm, eta)
        refl = d - 2.0 * dot(d, nrm)[:, None] * nrm
        wrong = (~rf.tir & (dot(rf.directions, facing) >= 0.0)) | (dot(refl, facing) <= 0.0)
        if wrong.any():  # bent back by the shading normal: the geometric one there
            nrm = np.where(wrong[:, None], facing, nrm)
            rf = refract(d, nrm, eta)
            refl = d - 2.0 * dot(d, nrm)[:, None] * nrm
        n1 = np.where(exiting, ior, 1.0)
        n2 = np.where(exiting, 1.0, ior)
        ts, tp = fresnel_from_cosines(rf.cos_i, rf.cos_t, n1, n2)
        ts, tp = np.where(rf.tir, 0.0, ts), np.where(rf.tir, 0.0, tp)
        # The s and p powers carried into this crossing's plane of incidence: both s
        # directions are across the ray, at an angle α (cos² α of each part stays);
        # at normal incidence (no plane) the last s direction is kept.
        s_new = cross(d, nrm)
        s_len = norm(s_new)
        sd = seg.s_dir  # no s direction yet (columns compared: no short-axis reduction)
        first = (sd[:, 0] == 0.0) & (sd[:, 1] == 0.0) & (sd[:, 2] == 0.0)
        plane = s_len > 1e-12
        s_new = np.where(plane[:, None], s_new / np.maximum(s_len, 1e-300)[:, None], seg.s_dir)
        c2 = np.where(first | ~plane, 1.0, dot(seg.s_dir, s_new) ** 2)
        ws = (seg.ws * c2 + seg.wp * (1.0 - c2)) * att
        wp = (seg.ws * (1.0 - c2) + seg.wp * c2) * att
        g = groups[tri].astype(np.uint64) * np.uint64(2)
        with np.errstate(over="ignore"):
            sig_t = seg.signature * _HASH + g + np.uint64(1)
            sig_r = seg.signature * _HASH + g + np.uint64(2)

        def child(direction, w_s, w_p, sig, into):
            return _Segments(
                ray=seg.ray,
                origin=p + self.eps * direction,
                at=p,
                direction=direction,
                ws=w_s,
                wp=w_p,
                s_dir=s_new,
                path=path,
                crossings=seg.crossings + 1,
                signature=sig,
                face=tri,
                inside=into,
            )

        kid_t = child(rf.directions, ws * ts, wp * tp, sig_t, ~exiting)
        kid_r = child(_unit(refl), ws * (1.0 - ts), wp * (1.0 - tp), sig_r, exiting)
        return kid_t, kid_r, rf.tir


def _per_triangle(values, default: float, n: int) -> np.ndarray:
    """(n,) floats: ``values`` per triangle, or ``default`` for all when None."""
    if values is None:
        return np.full(n, float(default))
    out = np.asarray(values, dtype=float).reshape(-1)
    if len(out) != n:
        raise ValueError(f"{len(out)} per-triangle values for {n} triangles")
    return out


_FIELDS = tuple(_Segments.__dataclass_fields__)


def _components(ea, eb, n: int) -> np.ndarray:
    """(n,) connected component (0, 1, …) of each of n items joined by the pairs
    (ea, eb): roots hooked onto the smaller root, then pointers jumped, until stable."""
    label = np.arange(n)
    while True:
        ra, rb = label[ea], label[eb]
        low = np.minimum(ra, rb)
        before = label.copy()
        np.minimum.at(label, ra, low)
        np.minimum.at(label, rb, low)
        while True:
            nxt = label[label]
            if np.array_equal(nxt, label):
                break
            label = nxt
        if np.array_equal(label, before):
            break
    return np.unique(label, return_inverse=True)[1]


def _flat(origins, directions):
    o, d = np.broadcast_arrays(
        np.asarray(origins, dtype=float), np.asarray(directions, dtype=float)
    )
    shape = d.shape[:-1]
    return o.reshape(-1, 3), d.reshape(-1, 3), shape


def _assemble(out: _Segments, o, d, shape, absorbed, dropped, leaked) -> BranchRays:
    """The finished branches as (B, …) arrays, strongest first per ray."""
    n = len(o)
    order = np.lexsort((-out.weight, out.ray))
    out = out.take(order)
    start = np.searchsorted(out.ray, np.arange(n))
    rank = np.arange(len(out.ray)) - start[out.ray]
    nb = int(rank.max(initial=0)) + 1
    pts = np.broadcast_to(o, (nb, n, 3)).copy()
    dirs = np.broadcast_to(d, (nb, n, 3)).copy()
    weight = np.zeros((nb, n))
    path = np.zeros((nb, n))
    crossings = np.zeros((nb, n), dtype=np.int64)
    signature = np.zeros((nb, n), dtype=np.uint64)
    face = np.full((nb, n), -1, dtype=np.int64)
    idx = (rank, out.ray)
    pts[idx], dirs[idx], weight[idx], path[idx] = out.at, out.direction, out.weight, out.path
    crossings[idx], signature[idx], face[idx] = out.crossings, out.signature, out.face
    met = np.zeros(n, dtype=bool)  # the ray met the glass (even if nothing came out)
    met[out.ray[out.crossings > 0]] = True
    met |= leaked | (dropped > 0.0)
    hit = crossings > 0
    hit[0] |= met
    # a ray that missed: one branch, unchanged, weight 1 (crossings 0)
    return BranchRays(
        points=pts.reshape(nb, *shape, 3),
        directions=dirs.reshape(nb, *shape, 3),
        weight=weight.reshape(nb, *shape),
        hit=hit.reshape(nb, *shape),
        path=path.reshape(nb, *shape),
        crossings=crossings.reshape(nb, *shape),
        signature=signature.reshape(nb, *shape),
        exit_face=face.reshape(nb, *shape),
        absorbed=absorbed.reshape(shape),
        dropped=dropped.reshape(shape),
        leaked=leaked.reshape(shape),
    )
