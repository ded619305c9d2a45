"""Row functions computed once per CL point across a strategy's rounds (:class:`PointMemo`).

A strategy that plans a toolpath, inserts a few points on it and plans it again (the ``cone``'s
rounds, :mod:`urdfpost.planning.strategies.cone`) computes again what depends on each old
point alone, from the same inputs: the inverse kinematics of a point from its tip and tool
axis, which the insertion copies bit for bit. Such a computation is a *row function*: every
output row is made from the same input row alone, by element-by-element numpy operations (no
reduction across rows and no matrix product, whose last bits can depend on how the rows are
split), so the bits of a row do not depend on the rows computed with it. Where the inputs of a
row are, bit for bit, those its point had in the call kept, the output row kept is the one
computing it again gives; only the other rows are computed (together), and the result is the
array computing every row gives.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

RowFunction = Callable[..., tuple[np.ndarray, ...]]
"""``fn(*args) -> outputs``: arrays whose first axis is the row; each output row made from the
same row of every input alone, by element-by-element operations."""


@dataclass(frozen=True)
class PointMemo:
    """A row function with the rows of its last call, for the points of a toolpath.

    The arrays of the last call are kept as they were given and returned (not copied): neither
    they nor the arrays a call returns may be modified afterwards.

    Attributes
    ----------
    fn : RowFunction
    args, out : tuple of ndarray
        The inputs and outputs of the last call kept (empty before the first).
    src : ndarray, shape (n,), int
        For each point of the toolpath this memo is on, the row of that call made for it; -1
        where there is none.
    """

    fn: RowFunction
    src: np.ndarray
    args: tuple[np.ndarray, ...] = ()
    out: tuple[np.ndarray, ...] = ()

    @classmethod
    def new(cls, fn: RowFunction, n: int) -> PointMemo:
        """A memo of ``fn`` for a toolpath of ``n`` points, no call kept yet."""
        return cls(fn, np.full(n, -1, dtype=np.int64))

    def __call__(
        self, at: np.ndarray, *args: np.ndarray
    ) -> tuple[tuple[np.ndarray, ...], PointMemo]:
        """``fn(*args)``, the rows whose inputs are the bits the kept call had for their point
        taken from it; and the memo keeping this call instead.

        Parameters
        ----------
        at : ndarray, shape (k,), int
            The point of each row (several rows may share one; the memo keeps one of them).
        *args : ndarray, each of shape (k, ...)

        Returns
        -------
        out : tuple of ndarray, each of shape (k, ...)
            What ``fn(*args)`` returns, to the bit.
        memo : PointMemo
            On the same toolpath, keeping this call.
        """
        row = self.src[at]
        same = row >= 0
        for arg, old in zip(args, self.args, strict=True) if self.args else ():
            same &= _same_rows(arg, np.take(old, np.maximum(row, 0), axis=0))
        if not same.any():  # the plain call
            out = self.fn(*args)
        else:
            new = np.flatnonzero(~same)
            out = tuple(np.take(o, np.maximum(row, 0), axis=0) for o in self.out)
            if new.size:
                for o, f in zip(out, self.fn(*(a[new] for a in args)), strict=True):
                    o[new] = f
        src = np.full(len(self.src), -1, dtype=np.int64)
        src[at] = np.arange(len(at))
        return out, PointMemo(self.fn, src, args, out)

    def moved(self, old: np.ndarray, n: int) -> PointMemo:
        """The memo on a toolpath of ``n`` points made of this one's with points inserted,
        ``old`` (shape (m,), int) the index of each point of this one there."""
        src = np.full(n, -1, dtype=np.int64)
        src[old] = self.src
        return PointMemo(self.fn, src, self.args, self.out)

    def taken(self, part: slice) -> PointMemo:
        """The memo on the points ``part`` of this one's toolpath."""
        return PointMemo(self.fn, self.src[part], self.args, self.out)


def _same_rows(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Whether each row of ``a`` is, bit for bit, that row of ``b`` (same shape and dtype),
    shape (k,) bool."""
    if not len(a):
        return np.zeros(0, dtype=bool)
    bits = np.dtype(f"u{a.itemsize}")
    equal = np.ascontiguousarray(a).view(bits) == np.ascontiguousarray(b).view(bits)
    columns = equal.reshape(len(a), -1)
    same = columns[:, 0].copy()
    for j in range(1, columns.shape[1]):  # (faster than all(axis=1) over a few columns)
        same &= columns[:, j]
    return same
