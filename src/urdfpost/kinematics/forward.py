"""Forward kinematics and Jacobians of the tool frame relative to the workpiece frame.

Two independent routes to the same numbers:

- the product of exponentials derived at load time (``T = E_1 ... E_k T_home``, chain order
  from the workpiece), vectorised over many joint vectors: a tool point and tool vectors given
  at home are carried through the joints from the tool back, each rotary joint turning them by
  Rodrigues' formula with one cosine and sine per joint value (no rotation matrices).
  :func:`tip_and_axis` carries the tip and the axis, :func:`tool_in_work` the whole frame,
  :func:`tip_and_axis_along` samples straight joint-space moves (with angle addition for
  evenly spaced samples), and :func:`interpolation_bounds` bounds how fast the tip and the
  axis move and turn along such moves. Subdivision and verification use these;
- Pinocchio, one configuration at a time: ``tool_in_work_pin``, ``tip_and_axis_pin`` and
  ``jacobian_pin`` in the tests' ``tests/oracles.py``. The tests hold every vectorised function
  to them, on every shipped machine and on generated ones.

Callers that go through a long path in chunks derive the machine's :class:`PoeChain` once (every
function that takes a machine also takes its chain) and may hand :func:`tip_and_axis_along` a
:class:`Scratch`: its temporaries are then the same few arrays for every chunk rather than fresh
memory each time (the results are the same, bit for bit).

Joint vectors ``q`` have shape (n, m): one column per machine axis in ``machine.axis_names``
order, mm for linear axes and rad for rotary axes. Positions are mm in the workpiece frame.
"""

from __future__ import annotations

import itertools
import math
import sys
from collections.abc import Callable
from dataclasses import dataclass
from typing import cast, overload

import numpy as np

from urdfpost.machine import Machine


def skew(k: np.ndarray) -> np.ndarray:
    """Cross-product matrix of ``k``, shape (..., 3, 3) for ``k`` of shape (..., 3)."""
    k = np.asarray(k, dtype=float)
    z = np.zeros(k.shape[:-1])
    return np.stack(
        [
            np.stack([z, -k[..., 2], k[..., 1]], -1),
            np.stack([k[..., 2], z, -k[..., 0]], -1),
            np.stack([-k[..., 1], k[..., 0], z], -1),
        ],
        -2,
    )


def rotation_about(k: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """Rodrigues rotation about unit axis ``k`` by angles ``theta``.

    Parameters
    ----------
    k : ndarray, shape (3,)
        Unit axis.
    theta : ndarray, shape (n,), rad

    Returns
    -------
    ndarray, shape (n, 3, 3)
    """
    theta = np.asarray(theta, dtype=float)
    kk = skew(k)
    s, c = np.sin(theta)[:, None, None], np.cos(theta)[:, None, None]
    return np.eye(3) + s * kk + (1.0 - c) * (kk @ kk)


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross products of 3-vectors along the last axis (``np.cross`` without its overhead on
    many short vectors; the same products and differences, so the same values).

    Parameters
    ----------
    a, b : ndarray, shape (..., 3)
        Broadcast against each other.

    Returns
    -------
    ndarray, shape (..., 3)
    """
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


def rotate(k: np.ndarray, theta: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate vectors ``v`` about unit axis ``k`` by ``theta`` (Rodrigues, vectorised).

    Parameters
    ----------
    k : ndarray, shape (3,) or (n, 3)
    theta : ndarray, shape (n,), rad
    v : ndarray, shape (3,) or (n, 3)

    Returns
    -------
    ndarray, shape (n, 3)
    """
    k = np.asarray(k, dtype=float)
    theta = np.asarray(theta, dtype=float)
    if k.ndim == 1 and theta.ndim == 1:
        if np.ndim(v) == 1:  # one vector for every row: its products with k worked out once
            c = np.asarray(v, dtype=float)
            return _rotate_constant(
                (float(k[0]), float(k[1]), float(k[2])),
                (float(c[0]), float(c[1]), float(c[2])),
                (np.cos(theta), np.sin(theta)),
            )
        return _rotate_about(k, theta, v)
    theta = theta[..., None]
    k = np.broadcast_to(k, (*theta.shape[:-1], 3))
    v = np.broadcast_to(v, (*theta.shape[:-1], 3))
    kv = np.sum(k * v, axis=-1, keepdims=True)
    cos, sin = np.cos(theta), np.sin(theta)
    return v * cos + cross(k, v) * sin + k * kv * (1.0 - cos)


def _rotate_about(
    k: np.ndarray,
    theta: np.ndarray,
    v: np.ndarray,
    cos_sin: tuple[np.ndarray, np.ndarray] | None = None,
) -> np.ndarray:
    """:func:`rotate` about one axis ``k`` (3,), column by column: the same operations on
    every element, in the same order, without the (n, 3) temporaries of ``k``. ``cos_sin``:
    the cosine and sine of ``theta`` when the caller has them."""
    n = theta.shape[0]
    v = np.broadcast_to(np.asarray(v, dtype=float), (n, 3))
    k0, k1, k2 = (float(x) for x in k)
    v0, v1, v2 = v[:, 0], v[:, 1], v[:, 2]
    kv = k0 * v0 + k1 * v1 + k2 * v2
    cos, sin = (np.cos(theta), np.sin(theta)) if cos_sin is None else cos_sin
    rest = 1.0 - cos
    out = np.empty((n, 3))
    for i, (ki, vi, ci) in enumerate(
        (
            (k0, v0, k1 * v2 - k2 * v1),
            (k1, v1, k2 * v0 - k0 * v2),
            (k2, v2, k0 * v1 - k1 * v0),
        )
    ):
        out[:, i] = vi * cos + ci * sin + ki * kv * rest
    return out


def _as_q(machine: Machine | PoeChain, q: np.ndarray) -> np.ndarray:
    q = np.asarray(q, dtype=float)
    n_axes = machine.n_axes if isinstance(machine, PoeChain) else len(machine.axes)
    return q.reshape(-1, n_axes)


# -- the chain on vectors kept as coordinate triples ------------------------------------------

Coord = np.ndarray | float
Vec = tuple[Coord, Coord, Coord]
"""A vector as its x, y, z coordinates: floats for a constant, arrays (all of one shape) for one
vector per configuration. The helpers skip exact zeros and unit factors of the constants, so a
machine whose axes lie along the coordinate axes costs only the products it needs (a turn about
Z is four products and two sums per vector)."""

Constant = tuple[float, float, float]
"""A constant vector as three floats (the :data:`Vec` of a vector the joints have not moved)."""

Arrays = tuple[np.ndarray, np.ndarray, np.ndarray]
"""A vector per configuration as three coordinate arrays (a :data:`Vec` with no constants)."""

New = Callable[[], np.ndarray] | None
"""Where the chain helpers put the arrays they compute: None for new arrays, else a function
handing out arrays of the shape of the computation (:meth:`Scratch.take`)."""


def _zero(x: Coord) -> bool:
    return isinstance(x, float) and x == 0.0


@overload
def _binary(op: np.ufunc, a: np.ndarray, b: Coord, new: New) -> np.ndarray: ...
@overload
def _binary(op: np.ufunc, a: Coord, b: np.ndarray, new: New) -> np.ndarray: ...
@overload
def _binary(op: np.ufunc, a: Coord, b: Coord, new: New) -> Coord: ...
def _binary(op: np.ufunc, a: Coord, b: Coord, new: New) -> Coord:
    """``op(a, b)``, into an array from ``new`` when there is one and the result is an array."""
    if new is None or (isinstance(a, float) and isinstance(b, float)):
        return op(a, b)
    return op(a, b, out=new())


def _neg(x: Coord, new: New) -> Coord:
    return -x if new is None or isinstance(x, float) else np.negative(x, out=new())


def _times(c: Coord, x: Coord, new: New = None) -> Coord:
    """``c * x``, without the work when either is an exact zero or a constant +-1 (``c * 1.0``
    is ``c``, bit for bit)."""
    if _zero(c) or _zero(x):
        return 0.0
    if isinstance(c, float) and abs(c) == 1.0:
        return x if c > 0.0 else _neg(x, new)
    if isinstance(x, float) and x == 1.0:
        return c
    if new is None:
        return c * x
    return _binary(np.multiply, c, x, new)


def _sum(*terms: Coord, new: New = None) -> Coord:
    """Sum of the terms that are not exact zeros."""
    out: Coord = 0.0
    for t in terms:
        if not _zero(t):
            if _zero(out):
                out = t
            else:
                out = out + t if new is None else _binary(np.add, out, t, new)
    return out


def _norm(v: Vec, new: New = None) -> Coord:
    square = _sum(*(_times(c, c, new) for c in v), new=new)
    if new is None or isinstance(square, float):
        return np.sqrt(square)
    return np.sqrt(square, out=new())


def _plane(
    c: np.ndarray, s: np.ndarray, u: Coord, v: Coord, new: New = None
) -> tuple[Coord, Coord]:
    """``(c u - s v, s u + c v)``: the turn of (u, v) in its plane, with as few new arrays as
    the zeros allow (numpy's element-wise work costs about twice as much into a new array).
    ``c``, ``s``: a cosine and sine, one per configuration."""
    if _zero(v):
        return _times(c, u, new), _times(s, u, new)
    if _zero(u):
        return _times(s, _neg(v, new), new), _times(c, v, new)
    if new is None:
        first, second = c * u, s * u
        both = s * v
    else:
        first, second = _binary(np.multiply, c, u, new), _binary(np.multiply, s, u, new)
        both = _binary(np.multiply, s, v, new)
    first -= both
    np.multiply(c, v, out=both)
    second += both
    return first, second


def _turn(
    w: Constant, cos: np.ndarray, sin: np.ndarray, x: Vec, new: New = None
) -> tuple[Vec, Vec]:
    """``x`` turned about the unit direction ``w`` (Rodrigues), and the part of ``x`` across ``w``.

    ``x' = w (w . x) + cos (x - w (w . x)) + sin (w x x)``; the part across ``w`` has the length
    of the distance of ``x`` from the line along ``w``. About a coordinate axis it is a turn in
    the plane of the other two.
    """
    for k in range(3):
        a, b = (k + 1) % 3, (k + 2) % 3  # (a, b, k) right-handed
        # exactly along axis k: (0, 1e-9, 1) is a unit vector whose 1e-9 still turns x
        if abs(w[k]) == 1.0 and w[a] == 0.0 and w[b] == 0.0:
            out: list[Coord] = [0.0, 0.0, 0.0]
            # w[k] is +-1, so _times gives sin or its negation: an array
            signed_sin = cast(np.ndarray, _times(w[k], sin, new))
            out[a], out[b] = _plane(cos, signed_sin, x[a], x[b], new)
            out[k] = x[k]
            across: list[Coord] = [0.0, 0.0, 0.0]
            across[a], across[b] = x[a], x[b]
            return tuple(out), tuple(across)  # type: ignore[return-value]
    along = _sum(*(_times(w[i], x[i], new) for i in range(3)), new=new)
    across = [_sum(x[i], _times(-w[i], along, new), new=new) for i in range(3)]
    cross = (
        _sum(_times(w[1], x[2], new), _times(-w[2], x[1], new), new=new),
        _sum(_times(w[2], x[0], new), _times(-w[0], x[2], new), new=new),
        _sum(_times(w[0], x[1], new), _times(-w[1], x[0], new), new=new),
    )
    turned = tuple(
        _sum(
            _times(w[i], along, new),
            _times(cos, across[i], new),
            _times(sin, cross[i], new),
            new=new,
        )
        for i in range(3)
    )
    return turned, tuple(across)  # type: ignore[return-value]


@dataclass(frozen=True)
class _Joint:
    """One axis of the chain: its column in ``q``, unit direction, and (rotary) the point of its
    line nearest the workpiece origin, in the workpiece frame at home (mm)."""

    column: int
    rotary: bool
    direction: Constant
    pivot: Constant


def _joints_from_tool(machine: Machine) -> tuple[_Joint, ...]:
    """The axes in the order their motions apply to a tool point: from the tool back to the
    workpiece (the product of exponentials ``T = E_1 ... E_k T_home`` acts on a point from the
    right)."""
    out = []
    for a in sorted(machine.axes, key=lambda a: a.chain_index, reverse=True):
        w, v = _vec(a.screw[:3]), _vec(a.screw[3:])
        pivot = (w[1] * v[2] - w[2] * v[1], w[2] * v[0] - w[0] * v[2], w[0] * v[1] - w[1] * v[0])
        out.append(
            _Joint(
                column=machine.axis_names.index(a.name),
                rotary=a.rotary,
                direction=w if a.rotary else v,
                pivot=pivot if a.rotary else (0.0, 0.0, 0.0),  # Axis.pivot, w x v
            )
        )
    return tuple(out)


@dataclass(frozen=True)
class PoeChain:
    """The machine's chain as products of exponentials: what the vectorised kinematics need of
    a machine, derived once (:func:`chain_of`).

    Attributes
    ----------
    joints : tuple of _Joint
        The axes from the tool back to the workpiece (:func:`_joints_from_tool`).
    n_axes : int
        Columns of a joint vector.
    linear_columns, rotary_columns : tuple of int
        As :attr:`Machine.linear_columns` and :attr:`Machine.rotary_columns`.
    home_tool_in_work : ndarray, shape (4, 4)
        As :attr:`Machine.home_tool_in_work`, translation in mm.
    """

    joints: tuple[_Joint, ...]
    n_axes: int
    linear_columns: tuple[int, ...]
    rotary_columns: tuple[int, ...]
    home_tool_in_work: np.ndarray

    @property
    def home_tool_axis(self) -> np.ndarray:
        """Tool axis in the workpiece frame at q = 0, shape (3,)."""
        return self.home_tool_in_work[:3, 2].copy()


def chain_of(machine: Machine | PoeChain) -> PoeChain:
    """The chain of a machine (a chain is its own).

    Deriving it takes about a tenth of a millisecond: a caller that goes through a path in
    thousands of chunks derives it once and passes it wherever a machine is asked for.
    """
    if isinstance(machine, PoeChain):
        return machine
    return PoeChain(
        joints=_joints_from_tool(machine),
        n_axes=len(machine.axes),
        linear_columns=machine.linear_columns,
        rotary_columns=machine.rotary_columns,
        home_tool_in_work=machine.home_tool_in_work,
    )


def _refcount_of_listed() -> int:
    """What ``sys.getrefcount(items[i])`` says of an array only the list ``items`` refers to
    (the same expression as in :meth:`Scratch.take`, so the same count whatever the
    interpreter adds for the call)."""
    items = [np.empty(1)]
    return sys.getrefcount(items[0])


_UNREFERENCED = _refcount_of_listed()


class Scratch:
    """Working arrays that are used again as soon as nothing refers to them any more.

    numpy takes a temporary of a few hundred kB from the system and gives it back when it is
    freed, unless the allocator happens to keep it; memory the system hands out is touched
    for the first time, which costs about as much as the arithmetic that fills it. A
    computation that goes through a path in chunks takes its temporaries from a scratch
    instead: an array handed out earlier is handed out again once the last reference to it (a
    view of it included) is gone, so the few arrays alive at once are used over and over and
    stay in the CPU cache. (Sampling the blocks of a long path, :mod:`urdfpost.linearize`, is
    about 5 % faster so; one chunk on its own more than twice as fast.)

    Examples
    --------
    >>> work = Scratch().start((2, 3))
    >>> a = work.take()
    >>> a.shape
    (2, 3)
    >>> b = work.take()  # a is still referred to: another array
    >>> b is a
    False
    """

    def __init__(self) -> None:
        self._flat: list[np.ndarray] = []
        self.shape: tuple[int, ...] = (0,)

    def start(self, shape: tuple[int, ...]) -> Scratch:
        """Hand out arrays of ``shape`` from now on; returns the scratch."""
        self.shape = tuple(shape)
        return self

    def take(self) -> np.ndarray:
        """An array of the current shape (uninitialised) that nothing else refers to."""
        size = math.prod(self.shape)
        for i in range(len(self._flat)):
            # referred to by the list (and the call) only: no view of it is alive
            if sys.getrefcount(self._flat[i]) == _UNREFERENCED:
                if self._flat[i].size < size:
                    self._flat[i] = np.empty(size)
                return self._flat[i][:size].reshape(self.shape)
        self._flat.append(np.empty(size))
        return self._flat[-1][:size].reshape(self.shape)


def _scratch_new(scratch: Scratch | None, shape: tuple[int, ...]) -> New:
    """The ``new`` of the chain helpers for a computation of ``shape``."""
    if scratch is None:
        return None
    if scratch.shape != tuple(shape):
        raise ValueError(f"scratch started for shape {scratch.shape}, the arrays are {shape}")
    return scratch.take


def _carry(
    joints: tuple[_Joint, ...],
    linear: dict[int, np.ndarray],
    trig: dict[int, tuple[np.ndarray, np.ndarray]],
    point: Vec | None,
    vectors: list[Vec],
    radii: bool = False,
    new: New = None,
) -> tuple[Vec | None, list[Vec], dict[int, Coord], dict[int, Coord]]:
    """A tool point and tool vectors, given at home, carried through the joints.

    Parameters
    ----------
    joints : tuple of _Joint
        From :func:`_joints_from_tool` (or a tail of it).
    linear : dict
        Linear joint values by column, mm.
    trig : dict
        Cosine and sine of the rotary joint values by column.
    point : Vec or None
        Point at home in the workpiece frame, mm (None: carry vectors only).
    vectors : list of Vec
        Directions at home.
    radii : bool
        Also return, per rotary column, the distance of the point from that axis' line and the
        length of the first vector's part across that axis, both as that joint sees them (after
        the joints nearer the tool have moved them).
    new : callable, optional
        Where the arrays computed go (see :data:`New`); the same values either way.

    Returns
    -------
    point, vectors, reach, swing
    """
    reach: dict[int, Coord] = {}
    swing: dict[int, Coord] = {}
    for j in joints:
        if not j.rotary:
            if point is not None:
                value = linear[j.column]
                point = tuple(  # type: ignore[assignment]
                    _sum(point[i], _times(j.direction[i], value, new), new=new) for i in range(3)
                )
            continue
        cos, sin = trig[j.column]
        if point is not None:
            rel = tuple(_sum(point[i], -j.pivot[i], new=new) for i in range(3))
            turned, across = _turn(j.direction, cos, sin, rel, new)  # type: ignore[arg-type]
            point = tuple(_sum(turned[i], j.pivot[i], new=new) for i in range(3))  # type: ignore[assignment]
            if radii:
                reach[j.column] = _norm(across, new)
        out = []
        for k, v in enumerate(vectors):
            turned, across = _turn(j.direction, cos, sin, v, new)
            out.append(turned)
            if radii and k == 0:
                swing[j.column] = _norm(across, new)
        vectors = out
    return point, vectors, reach, swing


def _trig(machine: Machine | PoeChain, q: np.ndarray) -> dict[int, tuple[np.ndarray, np.ndarray]]:
    cols = machine.rotary_columns
    return {c: (np.cos(q[:, c]), np.sin(q[:, c])) for c in cols}


def _vec(a: np.ndarray) -> Constant:
    """A constant 3-vector as three floats."""
    return float(a[0]), float(a[1]), float(a[2])


@dataclass(frozen=True)
class ChainArrays:
    """A chain as plain arrays, for compiled loops that carry a tool point and axis through it
    the way :func:`_carry` does (:mod:`urdfpost.verification._deviation_kernel`).

    Attributes
    ----------
    column : ndarray, shape (k,), int64
        Column in ``q`` of each joint, from the tool back (:attr:`PoeChain.joints`).
    rotary : ndarray, shape (k,), bool
    direction : ndarray, shape (k, 3)
        Unit direction of each joint.
    pivot : ndarray, shape (k, 3), mm
        A rotary joint's point of its line nearest the workpiece origin (zeros for a linear one).
    rotary_index : ndarray, shape (k,), int64
        A rotary joint's place in :attr:`PoeChain.rotary_columns` (the columns of ``reach`` and
        ``swing`` of :func:`tip_axis_and_reach`); -1 for a linear one.
    tool_point : ndarray, shape (3,), mm
        The tool tip at home, for the tool length asked for.
    home_axis : ndarray, shape (3,)
        The tool axis at home.
    """

    column: np.ndarray
    rotary: np.ndarray
    direction: np.ndarray
    pivot: np.ndarray
    rotary_index: np.ndarray
    tool_point: np.ndarray
    home_axis: np.ndarray


def chain_arrays(machine: Machine | PoeChain, tool_length: float) -> ChainArrays:
    """The chain of ``machine`` as plain arrays, the tip ``tool_length`` mm from the gauge point."""
    chain = chain_of(machine)
    joints = chain.joints
    index = {c: i for i, c in enumerate(chain.rotary_columns)}
    return ChainArrays(
        column=np.array([j.column for j in joints], dtype=np.int64),
        rotary=np.array([j.rotary for j in joints], dtype=np.bool_),
        direction=np.array([j.direction for j in joints], dtype=float).reshape(-1, 3),
        pivot=np.array([j.pivot for j in joints], dtype=float).reshape(-1, 3),
        rotary_index=np.array(
            [index[j.column] if j.rotary else -1 for j in joints], dtype=np.int64
        ),
        tool_point=np.array(_tool_point(chain, -tool_length), dtype=float),
        home_axis=np.array(_vec(chain.home_tool_axis), dtype=float),
    )


def _rows(v: Vec, n: int) -> np.ndarray:
    """A vector as an (n, 3) array."""
    out = np.empty((n, 3))
    for i in range(3):
        out[:, i] = v[i]
    return out


def _tool_point(machine: Machine | PoeChain, offset: float) -> Constant:
    """Point ``offset`` mm along the tool axis from the gauge point, at home."""
    home = machine.home_tool_in_work
    return _vec(home[:3, 3] + offset * home[:3, 2])


def tool_in_work(machine: Machine, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pose of the tool frame in the workpiece frame (product of exponentials, vectorised).

    The gauge point and the three columns of the tool frame's rotation at home are carried
    through the joints (Rodrigues on vectors, no rotation matrices).

    Parameters
    ----------
    machine : Machine
    q : ndarray, shape (n, m) or (m,)
        Joint values, mm / rad.

    Returns
    -------
    rotation : ndarray, shape (n, 3, 3)
    gauge : ndarray, shape (n, 3), mm
        Tool frame origin (gauge point) in the workpiece frame.
    """
    q = _as_q(machine, q)
    n = q.shape[0]
    home = machine.home_tool_in_work
    columns: list[Vec] = [_vec(home[:3, c]) for c in range(3)]
    linear = {c: q[:, c] for c in machine.linear_columns}
    gauge, cols, _, _ = _carry(
        _joints_from_tool(machine), linear, _trig(machine, q), _tool_point(machine, 0.0), columns
    )
    rot = np.stack([_rows(c, n) for c in cols], axis=2)
    return rot, _rows(gauge, n)  # type: ignore[arg-type]


def linear_directions(machine: Machine, q: np.ndarray) -> np.ndarray:
    """Derivative of the gauge point with respect to each linear axis (exact, vectorised).

    Each linear axis moves the tool, relative to the workpiece, along its direction rotated by
    the rotary joints that come before it in the chain from the workpiece.

    Parameters
    ----------
    machine : Machine
    q : ndarray, shape (n, m), mm / rad

    Returns
    -------
    ndarray, shape (n, 3, 3)
        Column j is d(gauge)/d(linear axis j), linear axes in NC order (mm per mm).
    """
    q = _as_q(machine, q)
    n = q.shape[0]
    joints = _joints_from_tool(machine)
    trig = _trig(machine, q)
    cols = []
    for a in machine.linear:
        at = [j.column for j in joints].index(machine.axis_names.index(a.name))
        _, (v,), _, _ = _carry(joints[at + 1 :], {}, trig, None, [_vec(a.direction)])
        cols.append(_rows(v, n))
    return np.stack(cols, axis=2)


ROWS = 8192
"""Joint vectors carried through the chain at a time by the row-wise functions
(:func:`tip_and_axis`, :func:`tip_axis_and_reach`): their temporaries, 64 kB each, stay in the
CPU cache and come from memory already in use, where those of a million rows at once are fresh
memory of 8 MB each."""


def row_chunks(n: int, size: int = ROWS) -> list[slice]:
    """Consecutive slices of at most ``size`` rows covering ``range(n)``."""
    return [slice(i, min(i + size, n)) for i in range(0, n, size)]


def _put_rows(out: np.ndarray, v: Vec) -> None:
    """Write a vector into the rows of ``out`` (k, 3) (as :func:`_rows`)."""
    for i in range(3):
        out[:, i] = v[i]


def tip_and_axis(
    machine: Machine | PoeChain, q: np.ndarray, tool_length: float = 0.0
) -> tuple[np.ndarray, np.ndarray]:
    """Tool tip and tool axis in the workpiece frame (vectorised).

    Only the tip and the axis are carried through the joints (Rodrigues on vectors, one cosine
    and sine per rotary axis); see :func:`tool_in_work` for the whole pose.

    Parameters
    ----------
    machine : Machine or PoeChain
    q : ndarray, shape (n, m), mm / rad
    tool_length : float, mm
        Distance from the gauge point to the tool tip along the tool axis.

    Returns
    -------
    tip : ndarray, shape (n, 3), mm
    axis : ndarray, shape (n, 3)
        Unit tool axis (tool frame +Z).
    """
    chain = chain_of(machine)
    q = _as_q(chain, q)
    tip, axis = np.empty((q.shape[0], 3)), np.empty((q.shape[0], 3))
    for part in row_chunks(q.shape[0]):
        p, (a,), _, _ = _tip_and_axis_carried(chain, q[part], tool_length)
        _put_rows(tip[part], p)  # type: ignore[arg-type]
        _put_rows(axis[part], a)
    return tip, axis


def axis_and_joint_directions(
    machine: Machine | PoeChain, q: np.ndarray
) -> tuple[np.ndarray, list[np.ndarray]]:
    """Tool axis and the directions of the rotary joints, in the workpiece frame (vectorised).

    What the orientation Jacobian (:func:`urdfpost.planning.singularity.orientation_jacobian`)
    is made of; the cosine and sine of each rotary value serve both. Meant for a few thousand
    rows at a time (:func:`row_chunks`).

    Parameters
    ----------
    machine : Machine or PoeChain
    q : ndarray, shape (n, m), mm / rad

    Returns
    -------
    axis : ndarray, shape (n, 3)
        As :func:`tip_and_axis` gives it.
    directions : list of ndarray, shape (n, 3)
        Per rotary joint, in :attr:`Machine.rotary` (chain) order: its unit direction turned
        by the rotary joints before it in the chain (:func:`rotate`, from the nearest one to
        the workpiece end).
    """
    chain = chain_of(machine)
    q = _as_q(chain, q)
    n = q.shape[0]
    trig = _trig(chain, q)
    axis = np.empty((n, 3))
    _put_rows(axis, _axis_carried(chain, trig))
    rotary = [j for j in reversed(chain.joints) if j.rotary]  # chain order
    directions = []
    for i, a in enumerate(rotary):
        w = None  # while None, the constant direction at home
        for b in rotary[i - 1 :: -1] if i else ():
            cos_sin = trig[b.column]
            if w is None:
                w = _rotate_constant(b.direction, a.direction, cos_sin)
            else:
                w = _rotate_about(np.array(b.direction), q[:, b.column], w, cos_sin)
        directions.append(np.broadcast_to(np.array(a.direction), (n, 3)) if w is None else w)
    return axis, directions


def _rotate_constant(
    k: Constant,
    v: Constant,
    cos_sin: tuple[np.ndarray, np.ndarray],
) -> np.ndarray:
    """:func:`_rotate_about` of one constant vector ``v``: its products with ``k`` are the
    same in every row, so they are worked out once (the same operations, so the same values).
    """
    cos, sin = cos_sin
    k0, k1, k2 = k
    v0, v1, v2 = v
    kv = k0 * v0 + k1 * v1 + k2 * v2
    rest = 1.0 - cos
    out = np.empty((cos.shape[0], 3))
    for i, (ki, vi, ci) in enumerate(
        (
            (k0, v0, k1 * v2 - k2 * v1),
            (k1, v1, k2 * v0 - k0 * v2),
            (k2, v2, k0 * v1 - k1 * v0),
        )
    ):
        col = out[:, i]
        np.multiply(vi, cos, out=col)
        col += ci * sin
        col += ki * kv * rest
    return out


def _axis_carried(chain: PoeChain, trig: dict[int, tuple[np.ndarray, np.ndarray]]) -> Vec:
    """The tool axis carried through the joints, given the cosines and sines of the rotary
    values (the same values as :func:`_tip_and_axis_carried` gives it)."""
    _, (axis,), _, _ = _carry(chain.joints, {}, trig, None, [_vec(chain.home_tool_axis)])
    return axis


def _tip_and_axis_carried(
    machine: Machine | PoeChain, q: np.ndarray, tool_length: float, radii: bool = False
) -> tuple[Vec | None, list[Vec], dict[int, Coord], dict[int, Coord]]:
    """:func:`_carry` of the tip and the tool axis through joint vectors ``q`` (n, m)."""
    chain = chain_of(machine)
    return _carry(
        chain.joints,
        {c: q[:, c] for c in chain.linear_columns},
        _trig(chain, q),
        _tool_point(chain, -tool_length),
        [_vec(chain.home_tool_axis)],
        radii=radii,
    )


def cos_sin_along(
    theta0: np.ndarray,
    step: np.ndarray,
    t: np.ndarray,
    out: tuple[np.ndarray, np.ndarray] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Cosine and sine of ``theta0 + t * step`` for evenly spaced ``t``.

    Angle addition from one sample to the next (a rotation of (cos, sin) by ``h * step``): two
    cosines and sines per column instead of per sample; the error grows by a few ulp per
    sample.

    Parameters
    ----------
    theta0, step : ndarray, shape (n,), rad
    t : ndarray, shape (s,)
        Evenly spaced.
    out : tuple of two ndarray, shape (s, n), optional
        Where to put the cosines and sines.

    Returns
    -------
    cos, sin : ndarray, shape (s, n)
    """
    s = len(t)
    if out is None:
        cos, sin = np.empty((s, len(theta0))), np.empty((s, len(theta0)))
    else:
        cos, sin = out
    start = theta0 + t[0] * step
    np.cos(start, out=cos[0])
    np.sin(start, out=sin[0])
    if s > 1:
        h = (t[-1] - t[0]) / (s - 1)
        hs = h * step
        cd, sd = np.cos(hs), np.sin(hs)
        part = start  # no longer needed
        for k in range(1, s):
            np.multiply(cos[k - 1], cd, out=cos[k])
            np.multiply(sin[k - 1], sd, out=part)
            cos[k] -= part
            np.multiply(sin[k - 1], cd, out=sin[k])
            np.multiply(cos[k - 1], sd, out=part)
            sin[k] += part
    return cos, sin


def _evenly_spaced(t: np.ndarray) -> bool:
    if t.ndim != 1 or len(t) < 3:
        return t.ndim == 1
    if len(t) > 64:
        d = np.diff(t)
        return bool(np.all(np.abs(d - d[0]) <= 1e-12 * max(1.0, float(np.abs(t).max()))))
    v = t.tolist()  # the same differences and comparisons in Python floats, for few samples
    d0, slack = v[1] - v[0], 1e-12 * max(1.0, max(abs(x) for x in v))
    return all(abs((b - a) - d0) <= slack for a, b in itertools.pairwise(v))


def tip_and_axis_along(
    machine: Machine | PoeChain,
    q0: np.ndarray,
    q1: np.ndarray,
    t: np.ndarray,
    tool_length: float = 0.0,
    *,
    with_tip: bool = True,
    scratch: Scratch | None = None,
) -> tuple[Arrays | None, Arrays]:
    """Tool tip and axis along straight joint-space moves ``q0 + t (q1 - q0)`` (vectorised).

    What a control without tool-centre-point control does between two blocks. With ``t`` one
    evenly spaced set of parameters for every move, the cosines and sines come from angle
    addition along the samples (two per rotary axis and move, not per sample).

    Parameters
    ----------
    machine : Machine or PoeChain
    q0, q1 : ndarray, shape (n, m)
        Joint values at the ends of n moves, mm / rad.
    t : ndarray, shape (s,) or (s, n)
        Parameters in [0, 1]: the same for every move, or one column per move.
    tool_length : float, mm
    with_tip : bool
        False: the tool axis only (the tip is returned as None).
    scratch : Scratch, optional
        Started for shape (s, n): the arrays computed are taken from it. The same values
        either way.

    Returns
    -------
    tip : Arrays, mm, or None
        The x, y and z coordinates, each an array of shape (s, n): sample, move.
    axis : Arrays
        Likewise.
    """
    chain = chain_of(machine)
    q0, q1 = _as_q(chain, q0), _as_q(chain, q1)
    t = np.asarray(t, dtype=float)
    n = q0.shape[0]
    shape = (t.shape[0], n)
    new = _scratch_new(scratch, shape)
    dq = q1 - q0
    grid = t[:, None] if t.ndim == 1 else t
    linear = {}
    if with_tip:
        for c in chain.linear_columns:
            v = grid * dq[:, c] if new is None else np.multiply(grid, dq[:, c], out=new())
            v += q0[:, c]
            linear[c] = v
    if _evenly_spaced(t):
        trig = {
            c: cos_sin_along(q0[:, c], dq[:, c], t, None if new is None else (new(), new()))
            for c in chain.rotary_columns
        }
    else:
        trig = {}
        for c in chain.rotary_columns:
            angle = grid * dq[:, c] if new is None else np.multiply(grid, dq[:, c], out=new())
            angle += q0[:, c]  # q0 + t dq, the sum of the same two terms
            if new is None:
                trig[c] = (np.cos(angle), np.sin(angle))
            else:
                trig[c] = (np.cos(angle, out=new()), np.sin(angle, out=angle))
    point = _tool_point(chain, -tool_length) if with_tip else None
    tip, (axis,), _, _ = _carry(
        chain.joints, linear, trig, point, [_vec(chain.home_tool_axis)], new=new
    )

    def full(v: Vec) -> Arrays:  # coordinates no joint moved are still constants
        x, y, z = (c if isinstance(c, np.ndarray) else np.full(shape, c) for c in v)
        return x, y, z

    return (full(tip) if tip is not None else None), full(axis)


def tip_axis_and_reach(
    machine: Machine | PoeChain, q: np.ndarray, tool_length: float = 0.0
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Tool tip and axis, and how far each rotary axis sees them from itself (vectorised).

    What :func:`interpolation_bounds` needs at the ends of a move.

    Parameters
    ----------
    machine : Machine or PoeChain
    q : ndarray, shape (n, m), mm / rad
    tool_length : float, mm

    Returns
    -------
    tip, axis : ndarray, shape (n, 3)
        As :func:`tip_and_axis`.
    reach : ndarray, shape (n, r), mm
        Per rotary axis (:attr:`Machine.rotary` order): distance of the tip from the axis' line
        with the joints between that axis and the tool moved, the axis and those before it not.
    swing : ndarray, shape (n, r)
        Likewise, the sine of the angle between the rotary axis and the tool axis.
    """
    chain = chain_of(machine)
    q = _as_q(chain, q)
    n = q.shape[0]
    cols = chain.rotary_columns
    tip, axis = np.empty((n, 3)), np.empty((n, 3))
    reach_a, swing_a = np.empty((n, len(cols))), np.empty((n, len(cols)))
    for part in row_chunks(n):
        p, (a,), reach, swing = _tip_and_axis_carried(chain, q[part], tool_length, radii=True)
        _put_rows(tip[part], p)  # type: ignore[arg-type]
        _put_rows(axis[part], a)
        for i, c in enumerate(cols):
            reach_a[part, i], swing_a[part, i] = reach[c], swing[c]
    return tip, axis, reach_a, swing_a


def interpolation_bounds(
    machine: Machine | PoeChain,
    q0: np.ndarray,
    q1: np.ndarray,
    reach0: np.ndarray,
    reach1: np.ndarray,
    swing0: np.ndarray,
    swing1: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Upper bounds on the speed and acceleration of the tool tip and axis along moves.

    Along ``q(t) = q0 + t (q1 - q0)``, t in [0, 1], the tip is ``p(t) = E_1 ... E_k p_home``
    with ``E_j = exp(xi_j q_j(t))`` (chain order from the workpiece). With ``d_j = |q1_j -
    q0_j|``, ``y_j`` the tip moved by the joints after j only, and ``r_j`` its distance from the
    line of rotary joint j (1 for a linear joint, whose twist moves every point by its unit
    direction):

    - ``|p'| <= sum_j d_j r_j``: joint j moves ``E_j y_j`` by at most ``d_j r_j``, and the rigid
      motions before it keep lengths;
    - ``|p''| <= sum_j d_j r_j (d_j [j rotary] + 2 sum_{i < j, i rotary} d_i)``: the second
      derivative of the product has the terms ``xi_j^2`` (a rotary joint's centripetal term,
      ``d_j^2 r_j``; zero for a linear one) and ``2 xi_i ... xi_j`` for i < j, where the
      velocity ``xi_j E_j y_j`` (length ``r_j``) is turned by rotary joint i at rate ``d_i``
      (a linear joint i does not turn vectors);
    - ``r_j(t)`` is bounded by its larger end value plus half the largest change of ``y_j``
      over the move (any t is within 1/2 of an end), ``sum_{l > j} d_l r_l / 2``, built from
      the tool back.

    The tool axis is the same with the sine of its angle to each rotary axis in place of
    ``r_j`` (linear joints do not turn it). These bound the deviation between samples: a
    function with ``|f''| <= M`` is within ``M h^2 / 8`` of the chord through two samples h
    apart, one with ``|f'| <= L`` within ``L h / 2`` of their mean.

    Parameters
    ----------
    machine : Machine or PoeChain
    q0, q1 : ndarray, shape (n, m)
        Joint values at the ends of the moves, mm / rad.
    reach0, reach1, swing0, swing1 : ndarray, shape (n, r)
        From :func:`tip_axis_and_reach` at q0 and q1 (the same tool length as the bounds are
        wanted for).

    Returns
    -------
    tip_speed : ndarray, shape (n,), mm per unit t
    tip_curvature : ndarray, shape (n,), mm per unit t squared
    axis_speed : ndarray, shape (n,), rad per unit t
    axis_curvature : ndarray, shape (n,), per unit t squared
    """
    chain = chain_of(machine)
    q0, q1 = _as_q(chain, q0), _as_q(chain, q1)
    joints = chain.joints
    index = {c: i for i, c in enumerate(chain.rotary_columns)}
    rate = np.abs(q1 - q0)
    reach: dict[int, Coord] = {}
    swing: dict[int, Coord] = {}
    tip_speed: Coord = 0.0
    axis_speed: Coord = 0.0
    for j in joints:  # from the tool back: the bounds of r_j need those of the joints after j
        d = rate[:, j.column]
        if j.rotary:
            i = index[j.column]
            reach[j.column] = np.maximum(reach0[:, i], reach1[:, i]) + 0.5 * tip_speed
            swing[j.column] = np.minimum(
                1.0, np.maximum(swing0[:, i], swing1[:, i]) + 0.5 * axis_speed
            )
            axis_speed = axis_speed + d * swing[j.column]
        else:
            reach[j.column] = 1.0
        tip_speed = tip_speed + d * reach[j.column]
    tip_curvature: Coord = 0.0
    axis_curvature: Coord = 0.0
    turning: Coord = 0.0  # sum of d_i over the rotary joints before j
    for j in reversed(joints):  # from the workpiece
        d = rate[:, j.column]
        own = d if j.rotary else 0.0
        factor = d * (own + 2.0 * turning)
        tip_curvature = tip_curvature + factor * reach[j.column]
        if j.rotary:
            axis_curvature = axis_curvature + factor * swing[j.column]
            turning = turning + d
    n = q0.shape[0]
    return tuple(
        np.broadcast_to(x, (n,)).copy()
        for x in (tip_speed, tip_curvature, axis_speed, axis_curvature)
    )  # type: ignore[return-value]
