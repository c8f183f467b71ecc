"""Index ranges, vectorised: the one trick behind shadow lists and grid joins."""

import numpy as np


def concat_ranges(starts, counts) -> np.ndarray:
    """The indices starts[i] … starts[i] + counts[i] − 1, for every i, concatenated
    (no Python loop: each index is its range's start plus its rank in the range)."""
    starts = np.asarray(starts, dtype=np.int64)
    counts = np.asarray(counts, dtype=np.int64)
    first = np.cumsum(counts) - counts  # where each range begins in the output
    return np.repeat(starts - first, counts) + np.arange(int(counts.sum()), dtype=np.int64)
