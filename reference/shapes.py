"""Glass solids of the glass tracer (:mod:`.glass_tracer`) with exact ray intersection.

Every shape answers :meth:`hit`: for rays ``origin + t direction`` (unit directions)
the nearest surface point ahead, ``t > t_min``, seen from outside (``inside`` False:
the entry) or from inside (``inside`` True: the exit), its outward unit normal (the
shading normal: interpolated for a smooth mesh) and the outward geometric normal.
``t`` is ``inf`` where the ray meets nothing.

The analytic shapes are convex: the intersection of a few primitives (balls,
ellipsoids, half-spaces, infinite cylinders), each giving the interval of the line
inside it; the solid's interval is the intersection of those, its entry the largest
start and its exit the smallest end.  A ray inside the solid therefore exits at the
far root of whichever primitive ends first: no epsilon decides which surface a ray
starting on the boundary is on.  :class:`TriangleMesh` is any closed mesh (Suzanne,
a wine glass, the tessellated analytic shapes) with its own small BVH.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .vectors import dot, unit

__all__ = [
    "Ellipsoid",
    "Biconvex",
    "Rod",
    "Box",
    "TriangleMesh",
    "Hit",
    "rotation_to",
]


@dataclass(frozen=True)
class Hit:
    """Nearest hits of a batch: ``t`` ``(m,)`` (inf: none), ``normal`` outward shading
    normals and ``geo_normal`` outward geometric normals ``(m, 3)``, ``prim`` the
    triangle hit (meshes; -1 otherwise)."""

    t: np.ndarray
    normal: np.ndarray
    geo_normal: np.ndarray
    prim: np.ndarray


def rotation_to(axis):
    """A rotation matrix taking local +z to the unit ``axis`` (columns: local axes)."""
    w = unit(np.asarray(axis, float))
    a = np.array([1.0, 0.0, 0.0]) if abs(w[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = unit(np.cross(a, w))
    return np.column_stack([u, np.cross(w, u), w])


def _quadratic(a, b_half, c):
    """Roots ``t0 <= t1`` of ``a t^2 + 2 b_half t + c = 0`` (a > 0) in the stable form
    (the larger-magnitude root first, the other as c / q), and where they exist."""
    disc = b_half * b_half - a * c
    ok = disc >= 0.0
    sq = np.sqrt(np.where(ok, disc, 0.0))
    q = -b_half - np.where(b_half >= 0.0, 1.0, -1.0) * sq
    with np.errstate(divide="ignore", invalid="ignore"):
        r1 = np.where(q != 0.0, q / a, 0.0)
        r2 = np.where(q != 0.0, c / np.where(q != 0.0, q, 1.0), 0.0)
    return np.minimum(r1, r2), np.maximum(r1, r2), ok


class _Convex:
    """A convex solid as an intersection of primitives; subclasses list them in
    :meth:`_intervals` as ``(t_in, t_out, normal_fn)`` with ``normal_fn(points)``
    the primitive's outward normal (an empty interval has ``t_in > t_out``)."""

    def _intervals(self, o, d):
        raise NotImplementedError

    def hit(self, o, d, inside, t_min=0.0, skip_prim=None) -> Hit:
        m = o.shape[0]
        t_in = np.full(m, -np.inf)
        t_out = np.full(m, np.inf)
        k_in = np.full(m, -1)
        k_out = np.full(m, -1)
        fns = []
        for k, (a, b, fn) in enumerate(self._intervals(o, d)):
            k_in = np.where(a > t_in, k, k_in)
            t_in = np.maximum(t_in, a)
            k_out = np.where(b < t_out, k, k_out)
            t_out = np.minimum(t_out, b)
            fns.append(fn)
        valid = t_in <= t_out
        inside = np.broadcast_to(np.asarray(inside, bool), (m,))
        # outside: the entry ahead; inside: the exit ahead (the interval may come out
        # a hair empty for a ray starting on the boundary: the exit still stands)
        t = np.where(
            inside,
            np.where(t_out > t_min, t_out, np.inf),
            np.where(valid & (t_in > t_min), t_in, np.inf),
        )
        t = np.where(np.isfinite(t), t, np.inf)
        k = np.where(inside, k_out, k_in)
        p = o + np.where(np.isfinite(t), t, 0.0)[:, None] * d
        nrm = np.zeros((m, 3))
        for j, fn in enumerate(fns):
            sel = (k == j) & np.isfinite(t)
            if np.any(sel):
                nrm[sel] = fn(p[sel])
        return Hit(t, nrm, nrm, np.full(m, -1))

    def contains(self, p):
        """Whether points lie inside (a short ray test: entry behind, exit ahead)."""
        d = np.tile([0.0, 0.0, 1.0], (p.shape[0], 1))
        t_in = np.full(p.shape[0], -np.inf)
        t_out = np.full(p.shape[0], np.inf)
        for a, b, _ in self._intervals(p, d):
            t_in, t_out = np.maximum(t_in, a), np.minimum(t_out, b)
        return (t_in <= 0.0) & (t_out >= 0.0)


def _ball(o, d, c, r):
    """Interval of the lines in the ball (robust quadratic) and its normal."""
    f = o - c
    beta = dot(f, d)
    perp = f - beta[:, None] * d
    disc = r * r - dot(perp, perp)
    ok = disc >= 0.0
    sq = np.sqrt(np.where(ok, disc, 0.0))
    q = -beta - np.where(beta >= 0.0, 1.0, -1.0) * sq
    cc = (np.sqrt(dot(f, f)) - r) * (np.sqrt(dot(f, f)) + r)
    with np.errstate(divide="ignore", invalid="ignore"):
        other = np.where(q != 0.0, cc / np.where(q != 0.0, q, 1.0), 0.0)
    a = np.where(ok, np.minimum(q, other), np.inf)
    b = np.where(ok, np.maximum(q, other), -np.inf)
    return a, b, lambda p: (p - c) / r


def _half_space(o, d, n, h):
    """Interval of the lines in ``n . x <= h`` (unit ``n``: the outward normal)."""
    dn = d @ n
    s = h - o @ n  # >= 0 inside
    with np.errstate(divide="ignore", invalid="ignore"):
        t = s / dn
    a = np.where(dn < 0.0, t, np.where(dn > 0.0, -np.inf, np.where(s >= 0.0, -np.inf, np.inf)))
    b = np.where(dn > 0.0, t, np.where(dn < 0.0, np.inf, np.where(s >= 0.0, np.inf, -np.inf)))
    return a, b, lambda p: np.broadcast_to(n, p.shape).copy()


def _cylinder(o, d, c, axis, r):
    """Interval of the lines in the infinite cylinder of radius ``r`` about the line
    through ``c`` along the unit ``axis``."""
    f = o - c
    fp = f - np.outer(f @ axis, axis)
    dp = d - np.outer(d @ axis, axis)
    a2 = dot(dp, dp)
    par = a2 < 1e-24  # parallel to the axis: all or nothing
    a2s = np.where(par, 1.0, a2)
    t0, t1, ok = _quadratic(a2s, dot(fp, dp), dot(fp, fp) - r * r)
    inside_par = dot(fp, fp) <= r * r
    a = np.where(par, np.where(inside_par, -np.inf, np.inf), np.where(ok, t0, np.inf))
    b = np.where(par, np.where(inside_par, np.inf, -np.inf), np.where(ok, t1, -np.inf))

    def normal(p):
        q = p - c
        return unit(q - np.outer(q @ axis, axis))

    return a, b, normal


@dataclass(frozen=True)
class Ellipsoid(_Convex):
    """``center``, semi-axes ``axes`` (a, b, c along the local x, y, z) and
    ``rotation`` (3x3, columns the local axes in the world; identity by default)."""

    center: tuple
    axes: tuple
    rotation: tuple | None = None

    @property
    def _rot(self):
        return np.eye(3) if self.rotation is None else np.asarray(self.rotation, float)

    def bounding_sphere(self):
        return np.asarray(self.center, float), float(max(self.axes))

    def _intervals(self, o, d):
        c, rot, ax = np.asarray(self.center, float), self._rot, np.asarray(self.axes, float)
        # to the unit sphere: x_local = R^T (x - c) / axes
        ol = ((o - c) @ rot) / ax
        dl = (d @ rot) / ax
        t0, t1, ok = _quadratic(dot(dl, dl), dot(ol, dl), dot(ol, ol) - 1.0)
        a = np.where(ok, t0, np.inf)
        b = np.where(ok, t1, -np.inf)

        def normal(p):
            q = ((p - c) @ rot) / (ax * ax)  # gradient of |x_local|^2, local axes
            return unit(q @ rot.T)

        return [(a, b, normal)]


@dataclass(frozen=True)
class Biconvex(_Convex):
    """A lens: the intersection of two balls.  ``center`` the middle of the lens on
    its ``axis``; ``thickness`` at the centre; ``r_front`` the radius of the surface
    bulging toward +axis, ``r_back`` toward -axis (``inf``: flat, a plano-convex
    lens); ``diameter`` optionally cuts a cylindrical rim (None: the balls' own
    edge)."""

    center: tuple
    axis: tuple
    r_front: float
    r_back: float
    thickness: float
    diameter: float | None = None

    def edge_radius(self):
        """Radius of the rim (where the two surfaces meet, or the cut)."""
        h = 0.5 * self.thickness
        rims = []
        for r in (self.r_front, self.r_back):
            if math.isfinite(r):
                rims.append(r)
        # the surfaces meet where both sags add up to the thickness: solve numerically
        lo, hi = 0.0, min(rims) if rims else 1e9
        for _ in range(100):
            mid = 0.5 * (lo + hi)
            sag = sum(r - math.sqrt(max(r * r - mid * mid, 0.0)) for r in rims)
            lo, hi = (mid, hi) if sag < 2.0 * h else (lo, mid)
        rim = lo
        return min(rim, 0.5 * self.diameter) if self.diameter else rim

    def bounding_sphere(self):
        return np.asarray(self.center, float), math.hypot(self.edge_radius(), 0.5 * self.thickness)

    def _intervals(self, o, d):
        c, w, h = (
            np.asarray(self.center, float),
            unit(np.asarray(self.axis, float)),
            0.5 * self.thickness,
        )
        out = []
        for sgn, r in ((1.0, self.r_front), (-1.0, self.r_back)):
            if math.isfinite(r):
                out.append(_ball(o, d, c + sgn * (h - r) * w, r))
            else:
                out.append(_half_space(o, d, sgn * w, sgn * (c @ w) + h))
        if self.diameter:
            out.append(_cylinder(o, d, c, w, 0.5 * self.diameter))
        return out


@dataclass(frozen=True)
class Rod(_Convex):
    """A cylinder with flat caps: ``center``, unit ``axis``, ``radius``, ``length``."""

    center: tuple
    axis: tuple
    radius: float
    length: float

    def bounding_sphere(self):
        return np.asarray(self.center, float), math.hypot(self.radius, 0.5 * self.length)

    def _intervals(self, o, d):
        c, w, h = (
            np.asarray(self.center, float),
            unit(np.asarray(self.axis, float)),
            0.5 * self.length,
        )
        return [
            _cylinder(o, d, c, w, self.radius),
            _half_space(o, d, w, c @ w + h),
            _half_space(o, d, -w, -(c @ w) + h),
        ]


@dataclass(frozen=True)
class Box(_Convex):
    """A box (an ice cube): ``center``, full edge lengths ``size``, ``rotation``
    (3x3, columns the box's axes; identity by default).  Sharp edges."""

    center: tuple
    size: tuple
    rotation: tuple | None = None

    def bounding_sphere(self):
        return np.asarray(self.center, float), 0.5 * float(np.linalg.norm(self.size))

    def _intervals(self, o, d):
        c = np.asarray(self.center, float)
        rot = np.eye(3) if self.rotation is None else np.asarray(self.rotation, float)
        out = []
        for k in range(3):
            n, h = rot[:, k], 0.5 * self.size[k]
            out.append(_half_space(o, d, n, c @ n + h))
            out.append(_half_space(o, d, -n, -(c @ n) + h))
        return out


# --- triangle meshes -------------------------------------------------------------


def _cross(a, b):
    """Row-wise cross product (np.cross's axis handling costs more than the math)."""
    out = np.empty_like(a)
    out[:, 0] = a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1]
    out[:, 1] = a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2]
    out[:, 2] = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    return out


@dataclass
class _Bvh:
    lo: np.ndarray  # (nodes, 3) box corners
    hi: np.ndarray
    left: np.ndarray  # child nodes (-1 for a leaf)
    right: np.ndarray
    start: np.ndarray  # leaf: first triangle in `order`, count
    count: np.ndarray
    order: np.ndarray  # triangle indices, leaves contiguous


def _build_bvh(tri_lo, tri_hi, leaf_size=6) -> _Bvh:
    """Median split of the triangles' centroids along the widest axis (iterative)."""
    cen = 0.5 * (tri_lo + tri_hi)
    order = np.arange(tri_lo.shape[0])
    lo, hi, left, right, start, count = [], [], [], [], [], []
    stack = [(0, tri_lo.shape[0], -1, 0)]  # (begin, end, parent, which child)
    while stack:
        b, e, parent, side = stack.pop()
        idx = order[b:e]
        node = len(lo)
        lo.append(tri_lo[idx].min(axis=0))
        hi.append(tri_hi[idx].max(axis=0))
        left.append(-1)
        right.append(-1)
        start.append(b)
        count.append(e - b)
        if parent >= 0:
            (left if side == 0 else right)[parent] = node
        if e - b <= leaf_size:
            continue
        span = cen[idx].max(axis=0) - cen[idx].min(axis=0)
        ax = int(np.argmax(span))
        order[b:e] = idx[np.argsort(cen[idx, ax], kind="stable")]
        mid = (b + e) // 2
        count[node] = 0
        stack.append((mid, e, node, 1))
        stack.append((b, mid, node, 0))
    return _Bvh(
        np.array(lo),
        np.array(hi),
        np.array(left),
        np.array(right),
        np.array(start),
        np.array(count),
        order,
    )


@dataclass
class TriangleMesh:
    """A closed, consistently wound triangle mesh: ``vertices`` ``(n, 3)``,
    ``triangles`` ``(f, 3)`` indices.  The winding is made outward (by the signed
    volume).  ``corner_normals`` ``(f, 3, 3)``: per-corner normals to interpolate
    (smooth shading, as Blender shades: barycentric, then normalised); None: flat."""

    vertices: np.ndarray
    triangles: np.ndarray
    corner_normals: np.ndarray | None = None
    leaf_size: int = 8
    _bvh: _Bvh = field(init=False, repr=False)

    def __post_init__(self):
        v = np.asarray(self.vertices, float)
        f = np.asarray(self.triangles, np.int64)
        a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
        volume = np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0
        if volume < 0.0:  # inward winding: flip
            f = f[:, ::-1].copy()
            if self.corner_normals is not None:
                self.corner_normals = np.asarray(self.corner_normals, float)[:, ::-1].copy()
            a, c = c, a
        self.vertices, self.triangles = v, f
        self._a, self._e1, self._e2 = a, b - a, c - a
        self._n = unit(np.cross(self._e1, self._e2))
        lo = np.minimum(np.minimum(a, b), c)
        hi = np.maximum(np.maximum(a, b), c)
        self._bvh = _build_bvh(lo, hi, self.leaf_size)
        bvh = self._bvh
        # each leaf's triangles in a padded row (-1: none), for batched tests
        self._leaf_tris = np.full((bvh.lo.shape[0], self.leaf_size), -1)
        for k in np.flatnonzero(bvh.left < 0):
            self._leaf_tris[k, : bvh.count[k]] = bvh.order[
                bvh.start[k] : bvh.start[k] + bvh.count[k]
            ]
        self._slack = 1e-12 * float(np.abs(v).max() + 1.0)
        if self.corner_normals is not None:
            self.corner_normals = np.asarray(self.corner_normals, float)

    def bounding_sphere(self):
        lo, hi = self.vertices.min(axis=0), self.vertices.max(axis=0)
        c = 0.5 * (lo + hi)
        return c, float(np.sqrt(np.max(np.sum((self.vertices - c) ** 2, axis=1))))

    def volume(self):
        return float(np.einsum("ij,ij->i", self._a, np.cross(self._e1, self._e2)).sum() / 6.0)

    def hit(self, o, d, inside, t_min=0.0, skip_prim=None) -> Hit:
        """Nearest triangle ahead (``t > t_min``; ``skip_prim``: a triangle per ray to
        ignore, the one it leaves).  ``inside`` is not needed (the nearest triangle
        is the exit from inside, the entry from outside) and is not used."""
        m = o.shape[0]
        skip = np.full(m, -1) if skip_prim is None else np.asarray(skip_prim)
        best, best_tri = self._nearest(o, d, t_min, skip)
        ok = best_tri >= 0
        tri = np.where(ok, best_tri, 0)
        geo = np.where(ok[:, None], self._n[tri], 0.0)
        if self.corner_normals is None:
            nrm = geo
        else:
            p = o + np.where(ok, best, 0.0)[:, None] * d
            u, v = self._barycentric(p, tri)
            cn = self.corner_normals[tri]
            nrm = unit(
                (1 - u - v)[:, None] * cn[:, 0] + u[:, None] * cn[:, 1] + v[:, None] * cn[:, 2]
            )
            nrm = np.where(ok[:, None], nrm, 0.0)
        return Hit(best, nrm, geo, np.where(ok, best_tri, -1))

    def _boxes(self, o, inv, nodes, t_min, best):
        """Entry distance of each ray into each node's box (inf: missed, or not
        before ``best``)."""
        bvh = self._bvh
        t1 = (bvh.lo[nodes] - o) * inv
        t2 = (bvh.hi[nodes] - o) * inv
        tn = np.minimum(t1, t2).max(axis=1)
        tf = np.maximum(t1, t2).min(axis=1)
        ok = (tn <= tf + self._slack) & (tf > t_min) & (tn < best)
        return np.where(ok, tn, np.inf)

    def _nearest(self, o, d, t_min, skip):
        """Depth-first BVH traversal of all rays in lockstep: each ray holds one
        current node and its own stack; the nearer child first, the farther pushed
        with its entry distance and skipped once a closer hit is known."""
        bvh, m, width = self._bvh, o.shape[0], self._leaf_tris.shape[1]
        inv = 1.0 / np.where(np.abs(d) < 1e-300, 1e-300, d)
        best = np.full(m, np.inf)
        best_tri = np.full(m, -1)
        stack = np.zeros((m, 64), np.int64)
        stack_t = np.zeros((m, 64))
        sp = np.zeros(m, np.int64)
        cur_t = self._boxes(o, inv, np.zeros(m, np.int64), t_min, best)
        cur = np.where(np.isfinite(cur_t), 0, -1)
        act = np.flatnonzero(cur >= 0)
        while act.size:
            c = cur[act]
            valid = cur_t[act] < best[act]
            leaf = valid & (bvh.left[c] < 0)
            inner = valid & ~leaf
            if np.any(leaf):
                r = act[leaf]
                tt = self._leaf_tris[c[leaf]].reshape(-1)
                rr = np.repeat(r, width)
                ok = tt >= 0
                rr, tt = rr[ok], tt[ok]
                t = self._triangle_t(o[rr], d[rr], tt)
                t = np.where((t > t_min) & (tt != skip[rr]), t, np.inf)
                np.minimum.at(best, rr, t)
                won = np.isfinite(t) & (t == best[rr])
                best_tri[rr[won]] = tt[won]
            popping = [act[~inner]]
            if np.any(inner):
                r = act[inner]
                lc, rc = bvh.left[c[inner]], bvh.right[c[inner]]
                tl = self._boxes(o[r], inv[r], lc, t_min, best[r])
                tr = self._boxes(o[r], inv[r], rc, t_min, best[r])
                left_first = tl <= tr
                near, far = np.where(left_first, lc, rc), np.where(left_first, rc, lc)
                tn, tf = np.minimum(tl, tr), np.maximum(tl, tr)
                both = np.isfinite(tf)
                pr = r[both]
                stack[pr, sp[pr]] = far[both]
                stack_t[pr, sp[pr]] = tf[both]
                sp[pr] += 1
                go = np.isfinite(tn)
                cur[r[go]] = near[go]
                cur_t[r[go]] = tn[go]
                popping.append(r[~go])
            popping = np.concatenate(popping)
            has = sp[popping] > 0
            py = popping[has]
            sp[py] -= 1
            cur[py] = stack[py, sp[py]]
            cur_t[py] = stack_t[py, sp[py]]
            cur[popping[~has]] = -1
            act = act[cur[act] >= 0]
        return best, best_tri

    def _triangle_t(self, o, d, tri):
        """Möller–Trumbore, both faces; inf where the line misses the triangle."""
        e1, e2 = self._e1[tri], self._e2[tri]
        pv = _cross(d, e2)
        det = dot(e1, pv)
        ok = np.abs(det) > 1e-300
        inv = 1.0 / np.where(ok, det, 1.0)
        tv = o - self._a[tri]
        u = dot(tv, pv) * inv
        qv = _cross(tv, e1)
        v = dot(d, qv) * inv
        t = dot(e2, qv) * inv
        ok &= (u >= 0.0) & (v >= 0.0) & (u + v <= 1.0)
        return np.where(ok, t, np.inf)

    def _barycentric(self, p, tri):
        e1, e2 = self._e1[tri], self._e2[tri]
        w = p - self._a[tri]
        d11, d12, d22 = dot(e1, e1), dot(e1, e2), dot(e2, e2)
        w1, w2 = dot(w, e1), dot(w, e2)
        den = d11 * d22 - d12 * d12
        return (d22 * w1 - d12 * w2) / den, (d11 * w2 - d12 * w1) / den
