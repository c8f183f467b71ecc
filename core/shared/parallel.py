"""Threads inside one light's phase 1: row-independent numpy work split in chunks.

numpy lets go of the GIL in its loops, so a large elementwise job split into a few
contiguous chunks runs on several cores. Each chunk is computed by the same code as
the whole would be, elementwise, so the concatenated result is bit for bit the inline
one. When phase 1 already runs lights side by side in threads, those threads call
:func:`inline` and every map inside them runs in the calling thread (no nesting).
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager

import numpy as np

#: Rows below which a map runs inline: below it a chunk's numpy steps are too short
#: for the threads' start and the GIL's hand-overs to pay.
MIN_ROWS = 50_000

_state = threading.local()


def cores() -> int:
    """Cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


@contextmanager
def inline():
    """Within it, this thread's maps run inline (its caller already runs threads)."""
    before = getattr(_state, "inline", False)
    _state.inline = True
    try:
        yield
    finally:
        _state.inline = before


def workers(n_rows: int, min_rows: int | None = None) -> int:
    """Threads a map over `n_rows` rows uses: 1 when inline or below `min_rows`
    (None: `MIN_ROWS`), else the cores (at most one per `min_rows // 2` rows)."""
    min_rows = MIN_ROWS if min_rows is None else min_rows
    if getattr(_state, "inline", False) or n_rows < min_rows:
        return 1
    return max(1, min(cores(), n_rows // max(1, min_rows // 2)))


def split(n_rows: int, parts: int) -> list[slice]:
    """`parts` contiguous slices covering range(n_rows), in order."""
    edges = np.linspace(0, n_rows, parts + 1).astype(np.int64)
    return [slice(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:], strict=True)]


def map_slices(
    fn: Callable[[slice], object],
    n_rows: int,
    min_rows: int | None = None,
    threads: int | None = None,
) -> list:
    """`[fn(s) for s in slices]` over contiguous slices of range(n_rows), in order;
    one slice (inline) when small or inside :func:`inline`, else one per thread
    (`threads`: that many, as :func:`workers` chose them for the caller)."""
    n = workers(n_rows, min_rows) if threads is None else max(1, min(threads, n_rows))
    if n <= 1:
        return [fn(slice(0, n_rows))]
    parts = split(n_rows, n)
    with ThreadPoolExecutor(n) as pool:
        return list(pool.map(fn, parts))


def map_items(fn: Callable[[object], object], items, work: int | None = None) -> list:
    """`[fn(x) for x in items]` in order, the items handed to the cores' threads as
    each comes free (jobs of unequal size balance themselves); inline when there are
    fewer than two, inside :func:`inline`, or when ``work`` (rows in all, say) is
    below `MIN_ROWS`. The caller combines the results in order: the same as inline."""
    items = list(items)
    n = min(cores(), len(items))
    if getattr(_state, "inline", False) or (work is not None and work < MIN_ROWS):
        n = 1
    if n <= 1:
        return [fn(x) for x in items]
    with ThreadPoolExecutor(n) as pool:
        return list(pool.map(fn, items))
