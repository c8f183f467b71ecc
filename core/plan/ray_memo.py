"""Live update's planner rays remembered (issue 27): a lamp dragged over ten marbles
moves half the pairs of a two-lamp scene, yet every update cast the rays of all of
them again (the receiver behind each lens, the free distance, the side planes,
whether a lens is sunk: a fifth of an update).

`RayMemo.view` wraps the read's occluders: each bundle the planner casts
(`planning.cast_bundles`) is looked up by its exact rays (origins and direction) and
cast only when new or asked within a longer limit than it was cast with; it is cast
within ``HEADROOM`` times the caller's limit, which is applied after (the first hit
within a limit is the first hit within a longer one if it lies within the shorter:
the same hits as a cast with the caller's limit, while the scene's size, which moves
with a lamp, stays within the headroom). Valid only while the
geometry is the one they were cast against: `start` compares the occluders' spheres,
instance matrices, boxes and mesh groups with the last update's and forgets
everything when any differs. What those do not show (a mesh reshaped within its box:
an edit, a shape key or modifier on a frame change) the caller reports with `clear`
(`blender/commands/live_update.py`: an update whose depsgraph changed an object's
geometry, or a forced one). Occluders without those arrays (a test's stand-in) are
never remembered. What the planner derives from a pair's hits alone (its side
planes: `planning.all_other_planes`) is remembered beside them (`derived`), by the
pair's inputs, and forgotten with them.
"""

from __future__ import annotations

from collections import OrderedDict

import numpy as np

#: The occluders' arrays the rays meet (`blender/read/occluders.Occluders`).
GEOMETRY = ("centers", "radii", "matrices", "box_lo", "box_hi", "source_index")
#: A bundle is cast within this many times the limit asked (a later update may ask a
#: longer one: the scene's size grows as a lamp is dragged away).
HEADROOM = 2.0


class RayMemo:
    """The first hits of the bundles cast on this geometry, by their rays (see the
    module). ``cast`` / ``reused``: bundles cast and looked up since the last
    `start` (an update's: what the tests count)."""

    #: Bundles remembered at most (the oldest forgotten first): a few updates' worth
    #: of a 1000-lens scene.
    LIMIT = 65536

    def __init__(self):
        self._geometry = None
        self._hits: OrderedDict = OrderedDict()
        self._derived: OrderedDict = OrderedDict()
        self.cast = self.reused = 0

    def start(self, occluders) -> None:
        """Before an update's plan: keep what was cast against this geometry, else
        forget it all."""
        self.cast = self.reused = 0
        if any(not hasattr(occluders, k) for k in GEOMETRY):
            self.clear()
            return
        geometry = [np.asarray(getattr(occluders, k)) for k in GEOMETRY]
        same = self._geometry is not None and all(
            a.shape == b.shape and a.dtype == b.dtype and np.array_equal(a, b)
            for a, b in zip(self._geometry, geometry, strict=True)
        )
        if not same:
            self._hits.clear()
            self._derived.clear()
            self._geometry = [a.copy() for a in geometry]

    def clear(self) -> None:
        """Forget every bundle (the geometry changed in a way `start` cannot see)."""
        self._hits.clear()
        self._derived.clear()
        self._geometry = None

    def __len__(self) -> int:
        return len(self._hits)

    @staticmethod
    def key(*values) -> bytes:
        """A key of exact inputs: their float64 bytes."""
        return np.concatenate([np.ravel(np.asarray(v, dtype=np.float64)) for v in values]).tobytes()

    def derived(self, kind: str, key: bytes):
        """What was derived as `kind` from the hits of the inputs `key` on this
        geometry (None: not yet, or no geometry known)."""
        got = self._derived.get((kind, key))
        if got is not None:
            self._derived.move_to_end((kind, key))
        return got

    def remember(self, kind: str, key: bytes, value) -> None:
        """Keep `value` as `derived` (only while the geometry is known)."""
        if self._geometry is None:
            return
        self._derived[(kind, key)] = value
        while len(self._derived) > self.LIMIT:
            self._derived.popitem(last=False)

    def view(self, occluders) -> _Remembered:
        """`occluders` whose `first_hits` go through this memo (after `start`)."""
        return _Remembered(occluders, self)

    def first_hits(self, occluders, origins, directions, limit) -> np.ndarray:
        """`occluders.first_hits` of bundles (`origins` B × k × 3, one direction per
        bundle), the ones cast before on this geometry not cast again."""
        origins = np.asarray(origins, dtype=np.float64)
        directions = np.asarray(directions, dtype=np.float64).reshape(-1, 3)
        B, k = origins.shape[:2]
        if self._geometry is None or not B:
            self.cast += B
            return _cast(occluders, origins, directions, limit)
        rays = np.concatenate([origins.reshape(B, -1), directions], axis=1)
        keys = [(k, r.tobytes()) for r in np.ascontiguousarray(rays)]
        hits = np.empty((B, k))
        todo = []
        for b, key in enumerate(keys):
            got = self._hits.get(key)
            if got is None or got[1] < limit:  # new, or cast within a shorter limit
                todo.append(b)
            else:
                hits[b] = got[0]
                self._hits.move_to_end(key)
        self.reused += B - len(todo)
        if todo:
            self.cast += len(todo)
            rows = np.asarray(todo)
            reach = HEADROOM * float(limit)
            new = _cast(occluders, origins[rows], directions[rows], reach).reshape(len(todo), k)
            hits[rows] = new
            for b, h in zip(todo, new, strict=True):
                self._hits[keys[b]] = (h.copy(), reach)
                self._hits.move_to_end(keys[b])
            while len(self._hits) > max(self.LIMIT, 2 * B):
                self._hits.popitem(last=False)
        return np.where(hits <= limit, hits, np.inf)


def _cast(occluders, origins, directions, limit) -> np.ndarray:
    """`occluders.first_hits`, or bundle by bundle where they have only `first_hit`."""
    if hasattr(occluders, "first_hits"):
        return np.asarray(occluders.first_hits(origins, directions, limit), dtype=float)
    return np.array(
        [occluders.first_hit(o, d, limit) for o, d in zip(origins, directions, strict=True)],
        dtype=float,
    ).reshape(origins.shape[:2])


class _Remembered:
    """Occluders whose batched casts go through a `RayMemo` (``ray_memo``; anything
    else: theirs)."""

    def __init__(self, occluders, memo: RayMemo):
        self._occluders, self.ray_memo = occluders, memo

    def first_hits(self, origins, directions, limit):
        return self.ray_memo.first_hits(self._occluders, origins, directions, limit)

    def __getattr__(self, name):
        return getattr(self._occluders, name)
