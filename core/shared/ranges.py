"""Index ranges, vectorised: the one trick behind shadow lists and grid joins."""

import numpy as np


def concat_ranges(starts, counts) -> np.ndarray:
    """The indices starts[i] … starts[i] + counts[i] − 1, for every i, concatenated
    (no Python loop: each index is its range's start plus its rank in the range)."""
    starts = np.asarray(starts, dtype=np.int64)
    counts = np.asarray(counts, dtype=np.int64)
    first = np.cumsum(counts) - counts  # where each range begins in the output
    return np.repeat(starts - first, counts) + np.arange(int(counts.sum()), dtype=np.int64)


def expand_ranges(starts, counts) -> tuple[np.ndarray, np.ndarray]:
    """(which, at): `at` is `concat_ranges(starts, counts)`, `which` the range each
    index is from. Marks where each range begins and takes their running sum, not
    `np.repeat` (much slower for ranges of a few), and skips the empty ranges."""
    starts = np.asarray(starts, dtype=np.int64)
    counts = np.asarray(counts, dtype=np.int64)
    has = np.flatnonzero(counts)
    c = counts[has]
    ends = np.cumsum(c)
    which = np.zeros(int(ends[-1]) if ends.size else 0, dtype=np.int64)
    which[ends[:-1]] = 1
    np.cumsum(which, out=which)
    at = (starts[has] - (ends - c))[which]
    at += np.arange(at.size, dtype=np.int64)
    return has[which], at
