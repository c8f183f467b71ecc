"""Object instances read from a depsgraph, in numpy: their names, their transforms'
scale, and the bookkeeping of what was left out.

Pure (numpy only). The Blender side (`blender/read/scene.py`) walks the
depsgraph once and hands over, per instance, a *group* index (instances of one
evaluated object / data / original share a group), a 4 × 4 world matrix and an
instancer index (−1: not an instance); everything here works on those arrays.

* Names: an instance is named "instancer/object"; a name met again gets "#k"
  for its k-th repeat (`instance_names`, `InstanceNames`, `occurrences`).
* Scale: a sphere may be rotated, mirrored and scaled uniformly; `scale_codes`
  sorts the matrices by what is wrong with them, `scale_reason` says it in words.
* Left out: `LeftOut` gathers (name, reason) entries, one per instancer, object
  and reason ("Grid/Cube (250 instances)").
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np


class _Seq(Sequence):
    """Read-only sequence with list equality (what tests and callers compare)."""

    def __eq__(self, other):
        return list(self) == list(other)

    def __repr__(self):
        return repr(list(self))


class Indexed(_Seq):
    """``values[index[i]]``: one value per group, looked up per item."""

    def __init__(self, values, index):
        self.values, self.index = list(values), np.asarray(index, dtype=np.int64)

    def __len__(self):
        return int(self.index.size)

    def __getitem__(self, i):
        if isinstance(i, slice):
            return [self.values[k] for k in self.index[i]]
        return self.values[self.index[i]]


class InstanceNames(_Seq):
    """Names made on demand: ``bases[base[i]]``, with ``#k`` for the k-th repeat."""

    def __init__(self, bases, base, occurrence):
        self.bases = list(bases)
        self.base = np.asarray(base, dtype=np.int64)
        self.occurrence = np.asarray(occurrence, dtype=np.int64)

    def __len__(self):
        return int(self.base.size)

    def __getitem__(self, i):
        if isinstance(i, slice):
            return [self[k] for k in range(*i.indices(len(self)))]
        b, k = self.bases[self.base[i]], int(self.occurrence[i])
        return b if k == 0 else f"{b}#{k}"

    def subset(self, idx) -> InstanceNames:
        """The names of the items `idx` (their repeat numbers kept)."""
        return InstanceNames(self.bases, self.base[idx], self.occurrence[idx])


def occurrences(keys: np.ndarray) -> np.ndarray:
    """For each item, how many earlier items have the same key (0, 1, 2 …)."""
    if keys.size == 0:
        return np.zeros(0, dtype=np.int64)
    order = np.argsort(keys, kind="stable")
    sk = keys[order]
    run_start = np.r_[True, sk[1:] != sk[:-1]]
    first = np.maximum.accumulate(np.where(run_start, np.arange(sk.size), 0))
    occ = np.empty(keys.size, dtype=np.int64)
    occ[order] = np.arange(sk.size) - first
    return occ


def instance_names(
    group_names: Sequence[str], gid: np.ndarray, pid: np.ndarray, parent_names: Sequence[str]
) -> InstanceNames:
    """Names of the instances: the group's name, "instancer/name" for an instance
    (`pid[i]` ≥ 0 indexes `parent_names`), "#k" for the k-th repeat of a name.
    Each distinct (instancer, group) pair is formatted once."""
    n, n_groups = gid.size, max(len(group_names), 1)
    pair = pid * n_groups + gid
    pairs, pair_of = np.unique(pair, return_inverse=True)
    parents, groups = np.divmod(pairs, n_groups)  # floored: −1 for no instancer
    texts = [
        group_names[g] if p < 0 else f"{parent_names[p]}/{group_names[g]}"
        for p, g in zip(parents.tolist(), groups.tolist(), strict=True)
    ]
    base_ids: dict[str, int] = {}
    pair_base = np.array([base_ids.setdefault(t, len(base_ids)) for t in texts], dtype=np.int64)
    base = pair_base[pair_of.ravel()] if n else np.zeros(0, np.int64)
    return InstanceNames(list(base_ids), base, occurrences(base))


def scale_codes(m: np.ndarray) -> np.ndarray:
    """Which of `scale_reason`'s cases each matrix (K × 4 × 4) is, as a number:
    0 non-finite, 1 zero scale, 2 zero on an axis, 3 non-uniform or sheared,
    4 uniform (a sphere stays a sphere)."""
    axes = np.linalg.norm(m[:, :3, :3], axis=1)
    with np.errstate(invalid="ignore"):
        code = np.where(axes.max(axis=1) > 0, np.where(axes.min(axis=1) > 0, 3, 2), 1)
        uniform = np.all(np.abs(axes - axes[:, :1]) <= 1e-3 * np.abs(axes[:, :1]), axis=1)
    code = np.where((code == 3) & uniform, 4, code)
    return np.where(np.all(np.isfinite(m), axis=(1, 2)), code, 0).astype(np.int64)


def scale_reason(m: np.ndarray) -> str:
    """Why a sphere with the 4 × 4 transform `m` is no sphere in the world."""
    axes = np.linalg.norm(m[:3, :3], axis=0)
    if not np.all(np.isfinite(m)):
        return "invalid transform (non-finite numbers)"
    if not axes.max() > 0:
        return "zero scale: nothing is rendered"
    scales = ", ".join(f"{s:.4g}" for s in axes)
    if not axes.min() > 0:
        return f"zero scale on an axis ({scales}): flat, not a sphere"
    if np.allclose(axes, axes[0], rtol=1e-3):
        return "sheared transform: not a sphere"
    return f"non-uniform scale ({scales}): an ellipsoid, not a sphere"


class LeftOut:
    """(name, reason) of what is not in the model, one entry per instancer, object
    and reason; `entries()` lists them in the order of their first instance."""

    def __init__(self, names: InstanceNames):
        self.names = names
        self._left: dict[tuple[str, str], list] = {}  # (base, reason) → [count, first, lens?]

    def add(self, i: int, reason: str, lens: bool, count: int = 1):
        """Leave out `count` instances named like instance `i` for `reason`;
        `lens`: it looked like a lens (worth reporting)."""
        key = (self.names.bases[self.names.base[i]], reason)
        entry = self._left.get(key)
        if entry is None:
            self._left[key] = [count, int(i), lens]
        else:
            entry[0] += count
            entry[1] = min(entry[1], int(i))

    def add_grouped(self, idx: np.ndarray, code: np.ndarray, reason_of, lens_of):
        """`add` for the instances `idx`, one call per (name, reason `code`):
        `reason_of(i)` / `lens_of(i)` of the first instance of each."""
        if idx.size == 0:
            return
        keys = self.names.base[idx] * (int(code.max()) + 1) + code
        _, first, counts = np.unique(keys, return_index=True, return_counts=True)
        for f, c in zip(first, counts, strict=True):
            i = idx[f]
            self.add(i, reason_of(i), lens_of(i), int(c))

    def entries(self) -> list[tuple[str, str, bool]]:
        """(name, reason, looked like a lens): "name" for one instance, "base
        (N instances)" for several."""
        out = []
        for (b, reason), (count, first, lens) in sorted(
            self._left.items(), key=lambda kv: kv[1][1]
        ):
            name = self.names[first] if count == 1 else f"{b} ({count} instances)"
            out.append((name, reason, lens))
        return out
