"""Live update's planner rays remembered per pair (issue 27): a lamp dragged over ten
marbles moves half the pairs of a two-lamp scene, yet every update cast the rays of
all of them again (the receiver behind each lens, the free distance, the side planes,
whether a lens is sunk: a fifth of an update).

`RayMemo` keeps each row's result by the exact inputs of its rays (the lens' axis,
centre and radius, and what the kind reads besides: the receiver's distance and
normal for the side planes), valid only while the geometry the rays meet is the one
they were cast against: `start` compares the occluders' spheres, instance matrices,
boxes and mesh groups and the scene's size with the last update's and forgets
everything when any differs. What those do not show (a mesh deformed within its box:
an edit, a shape key or modifier on a frame change) the caller reports with `clear`
(`blender/commands/live_update.py`: an update whose depsgraph changed a geometry, or
a forced one). Occluders without those arrays (a test's stand-in) are never
remembered. Pure Python + numpy; `planning.plan_result` takes it as ``rays``.
"""

from __future__ import annotations

from collections import OrderedDict

import numpy as np

#: The occluders' arrays the rays meet (`blender/read/occluders.Occluders`).
GEOMETRY = ("centers", "radii", "matrices", "box_lo", "box_hi", "source_index")


class RayMemo:
    """Per-row results of the planner's casts, by kind and exact inputs (see the
    module). ``cast_rows``: rows cast since made, per kind (what the tests count)."""

    #: Rows remembered at most (the oldest forgotten first): a few updates' worth of
    #: a 1000-lens scene.
    LIMIT = 16384

    def __init__(self):
        self._geometry = None
        self._entries: OrderedDict = OrderedDict()
        self.cast_rows: dict = {}

    def start(self, occluders, scene_size) -> None:
        """Before an update's plan: keep what was cast against this geometry, else
        forget it all."""
        if any(not hasattr(occluders, k) for k in GEOMETRY):
            self._geometry = None
            self._entries.clear()
            return
        geometry = [np.array(float(scene_size))] + [
            np.asarray(getattr(occluders, k)) for k in GEOMETRY
        ]
        same = self._geometry is not None and all(
            a.shape == b.shape and a.dtype == b.dtype and np.array_equal(a, b)
            for a, b in zip(self._geometry, geometry, strict=True)
        )
        if not same:
            self._entries.clear()
            self._geometry = [a.copy() for a in geometry]

    def clear(self) -> None:
        """Forget every row (the geometry changed in a way `start` cannot see)."""
        self._entries.clear()
        self._geometry = None

    def __len__(self) -> int:
        return len(self._entries)

    @staticmethod
    def keys(*columns) -> list[bytes]:
        """One key per row of `columns` (arrays with as many rows): their float64
        bytes, row by row."""
        n = len(columns[0])
        if not n:
            return []
        parts = [np.asarray(c, dtype=np.float64).reshape(n, -1) for c in columns]
        rows = np.ascontiguousarray(np.concatenate(parts, axis=1))
        return [r.tobytes() for r in rows]

    def rows(self, kind: str, keys: list, cast) -> list:
        """Per key the remembered result of `kind`, the missing ones from
        ``cast(rows)`` (their row indices: one result per row, in order). Without a
        geometry (`start` saw none) everything is cast and nothing kept."""
        keep = self._geometry is not None
        out = [self._entries.get((kind, k)) if keep else None for k in keys]
        todo = [i for i, got in enumerate(out) if got is None]
        if todo:
            self.cast_rows[kind] = self.cast_rows.get(kind, 0) + len(todo)
            made = cast(np.asarray(todo, dtype=np.int64))
            for i, got in zip(todo, made, strict=True):
                out[i] = got
                if keep:
                    self._entries[(kind, keys[i])] = got
        if keep:
            for k in keys:  # what this update read is the newest
                self._entries.move_to_end((kind, k))
            while len(self._entries) > max(self.LIMIT, 2 * len(keys)):
                self._entries.popitem(last=False)
        return out
