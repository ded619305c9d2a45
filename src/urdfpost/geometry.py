"""The geometry kernel of subdivision, verification and the joint-curve strategies.

Unit-vector interpolation (slerp) and angles; straight CL segments and great-circle arcs of CL
tool axes as coordinate arrays, with the squared distances and chords of sampled points from
them; the chunks long paths are measured in; the golden-section refinement of per-block maxima;
and the test of a bound against a level that decides where the refinement runs.

Pure functions over numpy arrays: nothing here knows the machine or its kinematics. The
callers (:mod:`urdfpost.linearize`, :mod:`urdfpost.verification`,
:mod:`urdfpost.planning.strategies`) bring the points and axes.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol, overload

import numpy as np


class Temporaries(Protocol):
    """Where working arrays come from: :class:`urdfpost.kinematics.forward.Scratch`, started
    for the shape of the computation."""

    def take(self) -> np.ndarray:
        """An array of the current shape (uninitialised) that nothing else refers to."""
        ...


def slerp(v0: np.ndarray, v1: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Spherical interpolation of unit vectors.

    Parameters
    ----------
    v0, v1 : ndarray, shape (n, 3)
        Unit vectors at the start and the end (CL tool axes).
    t : ndarray, shape (n,) or (n, s)
        Parameters in [0, 1]: one per row, or s per row.

    Returns
    -------
    ndarray, shape (n, 3) or (n, s, 3)
        Unit vectors at the angle ``t * omega`` from ``v0`` towards ``v1`` (omega the angle
        between them); the normalised linear interpolation where they (nearly) coincide.

    Examples
    --------
    >>> v = slerp(np.array([[1.0, 0.0, 0.0]]), np.array([[0.0, 1.0, 0.0]]), np.array([0.5]))
    >>> np.round(v, 6).tolist()
    [[0.707107, 0.707107, 0.0]]
    """
    t = np.asarray(t, dtype=float)
    dot = np.clip(np.sum(v0 * v1, axis=-1), -1.0, 1.0)
    omega = np.arccos(dot)
    if t.ndim == 2:
        v0, v1, omega = v0[:, None, :], v1[:, None, :], omega[:, None]
    small = omega < 1e-9
    so = np.where(small, 1.0, np.sin(omega))
    a = np.where(small, 1.0 - t, np.sin((1.0 - t) * omega) / so)
    b = np.where(small, t, np.sin(t * omega) / so)
    out = a[..., None] * v0 + b[..., None] * v1
    return out / np.linalg.norm(out, axis=-1, keepdims=True)


def angle_between(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Angle between unit vectors along the last axis, rad.

    As ``2 atan2(|u - v|, |u + v|)``, accurate near 0 and near pi (``arccos`` of the dot
    product is not).

    Parameters
    ----------
    u, v : ndarray, shape (..., 3)
        Unit vectors (broadcast against each other).

    Returns
    -------
    ndarray, shape (...), rad

    Examples
    --------
    >>> float(angle_between(np.array([0.0, 0.0, 1.0]), np.array([0.0, 1.0, 0.0])))
    1.5707963267948966
    """
    u, v = np.asarray(u, dtype=float), np.asarray(v, dtype=float)
    return 2.0 * np.arctan2(norms(u - v), norms(u + v))


def norms(x: np.ndarray) -> np.ndarray:
    """Lengths of 3-vectors along the last axis: ``np.linalg.norm(x, axis=-1)`` to the bit.

    numpy adds the three squares in order, ``(x0^2 + x1^2) + x2^2``, as this does; but its
    reduction over a last axis of three entries runs an inner loop per row, about three times
    slower than these whole-column operations.

    Parameters
    ----------
    x : ndarray, shape (..., 3)

    Returns
    -------
    ndarray, shape (...)
    """
    x0, x1, x2 = x[..., 0], x[..., 1], x[..., 2]
    return np.sqrt(x0 * x0 + x1 * x1 + x2 * x2)


CHUNK = 32768
"""Samples (blocks times samples per block) evaluated at a time. The few dozen temporary arrays
of a chunk stay in the CPU cache, which makes numpy's element-wise work about twice as fast as
over a million samples at once (measured: 16k to 64k are alike, smaller chunks lose to the
per-call overhead), and the memory of a path of a million blocks is that of one chunk."""


def chunks(n: int, samples: int) -> list[slice]:
    """Consecutive slices covering ``range(n)`` blocks, :data:`CHUNK` samples each at most.

    Parameters
    ----------
    n : int
        Blocks.
    samples : int
        Samples per block (at least one block per slice, however many).

    Returns
    -------
    list of slice

    Examples
    --------
    >>> chunks(5, CHUNK // 2)
    [slice(0, 2, None), slice(2, 4, None), slice(4, 5, None)]
    """
    size = max(1, CHUNK // max(samples, 1))
    return [slice(i, min(i + size, n)) for i in range(0, n, size)]


# -- errors on vectors kept as coordinate triples --------------------------------------------

VecArrays = tuple[np.ndarray, np.ndarray, np.ndarray]
"""A vector per block or sample as its x, y, z coordinate arrays, all of one shape (the
:data:`urdfpost.kinematics.forward.Vec` of arrays only: no coordinate is a constant float)."""


def coords(a: np.ndarray) -> VecArrays:
    """Rows of an (n, 3) array as three contiguous coordinate arrays of shape (n,)."""
    x, y, z = np.ascontiguousarray(np.asarray(a, dtype=float).T)
    return x, y, z


@dataclass(frozen=True)
class Segments:
    """Straight segments from ``a`` to ``a + d``, one per block (coordinate arrays (n,), mm)."""

    a: VecArrays
    d: VecArrays
    inv_dd: np.ndarray  # 1 / |d|^2, 0 for a segment of zero length

    @classmethod
    def between(cls, p0: np.ndarray, p1: np.ndarray) -> Segments:
        """Segments from the rows of ``p0`` to those of ``p1``, shape (n, 3)."""
        d = p1 - p0
        dd = np.einsum("ij,ij->i", d, d)
        return cls(coords(p0), coords(d), np.divide(1.0, dd, out=np.zeros_like(dd), where=dd > 0))

    @classmethod
    def of_coords(cls, p0: VecArrays, p1: VecArrays) -> Segments:
        """Segments from points ``p0`` to ``p1``, coordinate arrays of shape (n,)."""
        d = (p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2])
        dd = d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
        return cls(p0, d, np.divide(1.0, dd, out=np.zeros_like(dd), where=dd > 0))

    def take(self, index: np.ndarray | slice) -> Segments:
        """The segments at ``index`` (a slice gives views)."""
        (ax, ay, az), (dx, dy, dz) = self.a, self.d
        return Segments(
            (ax[index], ay[index], az[index]), (dx[index], dy[index], dz[index]), self.inv_dd[index]
        )

    def distance2(
        self,
        p: VecArrays,
        outside: list[np.ndarray] | None = None,
        scratch: Temporaries | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Squared distance of points from the segments, and the parameter of the closest point.

        Parameters
        ----------
        p : VecArrays
            Coordinate arrays of shape (..., n): points of each block.
        outside : list, optional
            When given, how far the projection parameter falls outside [0, 1] (0 inside) is
            appended to it, an array of the shape of ``s``.
        scratch : Temporaries, optional
            Started for the shape of ``p`` (a :class:`urdfpost.kinematics.forward.Scratch`):
            the results and temporaries are taken from it.

        Returns
        -------
        dist2 : ndarray, shape (..., n), mm^2
        s : ndarray, shape (..., n)
            In [0, 1].
        """
        a, d = self.a, self.d
        if scratch is None:
            w = [p[0] - a[0], p[1] - a[1], p[2] - a[2]]
            s = w[0] * d[0]
            part = w[1] * d[1]
        else:
            w = [np.subtract(p[i], a[i], out=scratch.take()) for i in range(3)]
            s = np.multiply(w[0], d[0], out=scratch.take())
            part = np.multiply(w[1], d[1], out=scratch.take())
        s += part
        np.multiply(w[2], d[2], out=part)
        s += part
        s *= self.inv_dd
        if outside is not None:
            raw = s.copy()
        np.clip(s, 0.0, 1.0, out=s)
        if outside is not None:
            raw -= s
            outside.append(np.abs(raw, out=raw))
        dist2: np.ndarray | None = None
        for i in range(3):  # w turns into the offset from the closest point, in place
            np.multiply(s, d[i], out=part)
            w[i] -= part
            w[i] *= w[i]
            if dist2 is None:
                dist2 = w[i]
            else:
                dist2 += w[i]
        assert dist2 is not None  # set in the loop's first pass
        return dist2, s


@dataclass(frozen=True)
class Arcs:
    """Great-circle arcs of unit vectors from ``v0`` towards ``v1``, one per block: the slerp
    ``cos(t omega) v0 + sin(t omega) normal``."""

    v0: VecArrays
    normal: VecArrays  # unit, normal to v0 in the plane of v0 and v1 (zero when they are parallel)
    omega: np.ndarray  # angle from v0 to v1, rad

    @classmethod
    def between(cls, v0: np.ndarray, v1: np.ndarray) -> Arcs:
        """Arcs from the rows of ``v0`` to those of ``v1``, shape (n, 3), unit vectors."""
        dot = np.einsum("ij,ij->i", v0, v1)
        across = v1 - dot[:, None] * v0
        sin = np.sqrt(np.einsum("ij,ij->i", across, across))
        normal = np.divide(across, sin[:, None], out=np.zeros_like(across), where=sin[:, None] > 0)
        return cls(coords(v0), coords(normal), np.arctan2(sin, dot))

    @classmethod
    def of_coords(cls, v0: VecArrays, v1: VecArrays) -> Arcs:
        """Arcs from unit vectors ``v0`` to ``v1``, coordinate arrays of shape (n,)."""
        dot = v0[0] * v1[0] + v0[1] * v1[1] + v0[2] * v1[2]
        across = [v1[i] - dot * v0[i] for i in range(3)]
        sin = np.sqrt(across[0] * across[0] + across[1] * across[1] + across[2] * across[2])
        inv = np.divide(1.0, sin, out=np.zeros_like(sin), where=sin > 0)
        normal = (across[0] * inv, across[1] * inv, across[2] * inv)
        return cls(v0, normal, np.arctan2(sin, dot))

    def take(self, index: np.ndarray | slice) -> Arcs:
        """The arcs at ``index`` (a slice gives views)."""
        (vx, vy, vz), (nx, ny, nz) = self.v0, self.normal
        return Arcs(
            (vx[index], vy[index], vz[index]), (nx[index], ny[index], nz[index]), self.omega[index]
        )

    def chord2(
        self,
        v: VecArrays,
        cos: np.ndarray | float,
        sin: np.ndarray | float,
        scratch: Temporaries | None = None,
    ) -> np.ndarray:
        """Squared chord from unit vectors ``v`` to the arcs' points of the given angles.

        Parameters
        ----------
        v : VecArrays
            Coordinate arrays of shape (..., n).
        cos, sin : ndarray, shape (..., n), or float
            Of ``t * omega`` at each of them (a float: the same at every one).
        scratch : Temporaries, optional
            Started for the shape of the result (a
            :class:`urdfpost.kinematics.forward.Scratch`): it and the temporaries are taken
            from it.

        Returns
        -------
        ndarray, shape (..., n)
            ``|v - slerp|^2``; the angle is :func:`angle_from_chord2` of it.
        """
        shape = np.broadcast_shapes(np.shape(v[0]), np.shape(cos))
        if scratch is None:
            out, r, part = np.empty(shape), np.empty(shape), np.empty(shape)
        else:
            out, r, part = scratch.take(), scratch.take(), scratch.take()
        for i in range(3):
            np.multiply(cos, self.v0[i], out=r)
            np.subtract(v[i], r, out=r)
            np.multiply(sin, self.normal[i], out=part)
            r -= part
            if i == 0:  # the sum starts at 0, and 0 + r^2 is r^2 (a square is never -0)
                np.multiply(r, r, out=out)
            else:
                r *= r
                out += r
        return out


_SMALL = 0.1
"""Angles up to this (rad) get their cosine and sine from Taylor polynomials in :func:`cos_sin`."""


def cos_sin(angle: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Cosine and sine of angles, rad.

    The angles between consecutive CL tool axes are small: there Taylor polynomials, with as
    many terms as the largest angle needs for the terms left out to stay below 1e-17, are
    several times faster than ``np.cos`` and ``np.sin`` and as accurate (an ulp or two).

    Parameters
    ----------
    angle : ndarray, any shape, rad

    Returns
    -------
    cos, sin : ndarray, shape of ``angle``
    """
    angle = np.asarray(angle, dtype=float)
    largest = float(np.abs(angle).max(initial=0.0))
    if largest > _SMALL:
        return np.cos(angle), np.sin(angle)
    terms = 1  # sin to x^(2 terms - 1), cos to x^(2 terms): the next terms are the error
    while largest ** (2 * terms + 1) / math.factorial(2 * terms + 1) > 1e-17:
        terms += 1
    x2 = angle * angle
    sin = np.full_like(angle, (-1.0) ** (terms - 1) / math.factorial(2 * terms - 1))
    cos = np.full_like(angle, (-1.0) ** terms / math.factorial(2 * terms))
    for k in range(terms - 1, -1, -1):
        if k:
            sin *= x2
            sin += (-1.0) ** (k - 1) / math.factorial(2 * k - 1)
        cos *= x2
        cos += (-1.0) ** k / math.factorial(2 * k)
    sin *= angle
    return cos, sin


@overload
def angle_from_chord2(chord2: float) -> np.float64: ...


@overload
def angle_from_chord2(chord2: np.ndarray) -> np.ndarray: ...


def angle_from_chord2(chord2: np.ndarray | float) -> np.ndarray | np.float64:
    """Angle between unit vectors from their squared chord, rad (as :func:`angle_between`).

    Parameters
    ----------
    chord2 : ndarray or float
        ``|u - v|^2`` of unit vectors u and v, in [0, 4] (more is taken as 4).

    Returns
    -------
    ndarray of the shape of ``chord2``, or a numpy float for a float, rad

    Examples
    --------
    >>> float(angle_from_chord2(2.0))  # a right angle
    1.5707963267948966
    """
    chord2 = np.asarray(chord2, dtype=float)
    return 2.0 * np.arctan2(np.sqrt(chord2), np.sqrt(np.maximum(4.0 - chord2, 0.0)))


GOLDEN = (np.sqrt(5.0) - 1.0) / 2.0
"""The inverse golden ratio: the golden-section search of :func:`refine_max` keeps this share
of its bracket every iteration."""


def refine_max(
    errors: Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]],
    t: np.ndarray,
    worst: tuple[np.ndarray, np.ndarray],
    best: tuple[np.ndarray, np.ndarray],
    wanted: tuple[np.ndarray, np.ndarray],
    iterations: int = 12,
) -> tuple[np.ndarray, np.ndarray]:
    """Maxima of two per-block functions of the block parameter, refined around the worst samples.

    Golden-section search on the bracket of one sample spacing either side of a block's worst
    sample of each function (the maximum is not always at a sample, nor at the midpoint). The
    two searches go through the kinematics together, one call per iteration for both, and only
    in the blocks that want them; each takes its maximum from its own evaluations, so a block
    gets the same value whether or not the other function is refined too.

    Parameters
    ----------
    errors : callable
        ``errors(blocks, tt)`` with block indices and parameters of shape (k,) returns both
        functions there, two arrays of shape (k,).
    t : ndarray, shape (s,)
        Sample parameters in [0, 1], evenly spaced, the same for every block.
    worst : tuple of two ndarray, shape (n,), int
        Index into ``t`` of each block's worst sample of each function.
    best : tuple of two ndarray, shape (n,)
        Largest values sampled.
    wanted : tuple of two ndarray, shape (n,), bool
        Blocks whose maximum of that function is to be refined.
    iterations : int

    Returns
    -------
    tuple of two ndarray, shape (n,)
        The largest value seen of each function per block.
    """
    h = t[1] - t[0] if len(t) > 1 else 0.5
    out = [best[0].copy(), best[1].copy()]
    rows = [np.flatnonzero(w) for w in wanted]
    if not (rows[0].size or rows[1].size):
        return out[0], out[1]
    lo = [np.clip(t[worst[i][rows[i]]] - h, 0.0, 1.0) for i in range(2)]
    hi = [np.clip(t[worst[i][rows[i]]] + h, 0.0, 1.0) for i in range(2)]
    blocks = np.concatenate([rows[0], rows[0], rows[1], rows[1]])
    n0, n1 = len(rows[0]), len(rows[1])
    parts = [slice(0, n0), slice(n0, 2 * n0), slice(2 * n0, 2 * n0 + n1), slice(2 * n0 + n1, None)]
    for _ in range(iterations):
        a = [hi[i] - GOLDEN * (hi[i] - lo[i]) for i in range(2)]
        b = [lo[i] + GOLDEN * (hi[i] - lo[i]) for i in range(2)]
        values = errors(blocks, np.concatenate([a[0], b[0], a[1], b[1]]))
        for i in range(2):
            fa, fb = values[i][parts[2 * i]], values[i][parts[2 * i + 1]]
            out[i][rows[i]] = np.maximum(out[i][rows[i]], np.maximum(fa, fb))
            left = fa > fb
            hi[i] = np.where(left, b[i], hi[i])
            lo[i] = np.where(left, lo[i], a[i])
    return out[0], out[1]


#: Relative and absolute slack on the bounds that decide which blocks to refine: the sampled
#: errors carry a few ulp of the lever arms (about 1e-12 mm), far below any tolerance.
_BOUND_SLACK = (1e-9, 1e-12)


def may_reach(bound: np.ndarray, level: float | np.ndarray) -> np.ndarray:
    """Where a bound on a block's maximum does not rule out reaching ``level``.

    Parameters
    ----------
    bound : ndarray, shape (n,)
        Upper bounds on the blocks' maxima (a length in mm or a chord).
    level : float or ndarray, shape (n,)
        In the bound's unit.

    Returns
    -------
    ndarray, shape (n,), bool
        The bound, with a little slack (:data:`_BOUND_SLACK`) for rounding, reaches ``level``.
    """
    return bound * (1.0 + _BOUND_SLACK[0]) + _BOUND_SLACK[1] >= level
