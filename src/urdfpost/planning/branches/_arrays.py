"""Array helpers of the branch planner, exact to the bit and quick on short last axes.

The planner works on a few candidates per point over many points: numpy's cost there is per
operation, not per number, so these do the few operations that the general functions would
spread over many (and keep their temporaries in cache).
"""

from __future__ import annotations

import numpy as np

_CHUNK = 32768  # array entries per operation in the element-wise passes (temporaries in cache)


def _chunks(n: int, size: int) -> list[slice]:
    """Slices of ``range(n)`` with about :data:`_CHUNK` array entries each, for points that
    take ``size`` entries each."""
    rows = max(1, _CHUNK // max(1, size))
    return [slice(lo, lo + rows) for lo in range(0, n, rows)]


def _total(size: list[np.ndarray]) -> np.ndarray:
    """Sum of the rotary axes' motions ``size`` (one array per axis), in order: with one or
    two axes, to the bit what a sum over an axis of one array gives. May be ``size[0]``."""
    if len(size) == 1:
        return size[0]
    total = np.add(size[0], size[1])
    for s in size[2:]:
        total += s
    return total


def _rows_any(a: np.ndarray) -> np.ndarray:
    """Whether each row of a boolean array of shape (n, k) has a true entry, shape (n,): one
    column at a time, which is much faster than numpy's reduction over a short last axis."""
    out = np.zeros(len(a), dtype=bool)
    for c in range(a.shape[1]):
        out |= a[:, c]
    return out
