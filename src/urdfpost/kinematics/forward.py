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
- :func:`tool_in_work_pin` and :func:`jacobian_pin` ask Pinocchio, one configuration at a time.
  The tests hold every vectorised function to them, on every shipped machine and on generated
  ones.

Joint vectors ``q`` have shape (n, m): one column per machine axis in ``machine.axis_names``
order, mm for linear axes and rad for rotary axes. Positions are mm in the workpiece frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from urdfpost.machine import M_TO_MM, Machine


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
        return _rotate_about(k, theta, v)
    theta = theta[..., None]
    k = np.broadcast_to(k, (*theta.shape[:-1], 3))
    v = np.broadcast_to(v, (*theta.shape[:-1], 3))
    kv = np.sum(k * v, axis=-1, keepdims=True)
    cos, sin = np.cos(theta), np.sin(theta)
    return v * cos + cross(k, v) * sin + k * kv * (1.0 - cos)


def _rotate_about(k: np.ndarray, theta: np.ndarray, v: np.ndarray) -> np.ndarray:
    """:func:`rotate` about one axis ``k`` (3,), column by column: the same operations on
    every element, in the same order, without the (n, 3) temporaries of ``k``."""
    n = theta.shape[0]
    v = np.broadcast_to(np.asarray(v, dtype=float), (n, 3))
    k0, k1, k2 = (float(x) for x in k)
    v0, v1, v2 = v[:, 0], v[:, 1], v[:, 2]
    kv = k0 * v0 + k1 * v1 + k2 * v2
    cos, sin = np.cos(theta), np.sin(theta)
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


def _as_q(machine: Machine, q: np.ndarray) -> np.ndarray:
    q = np.asarray(q, dtype=float)
    q2 = q.reshape(-1, len(machine.axes))
    return q2


# -- the chain on vectors kept as coordinate triples ------------------------------------------

Coord = np.ndarray | float
Vec = tuple[Coord, Coord, Coord]
"""A vector as its x, y, z coordinates: floats for a constant, arrays (all of one shape) for one
vector per configuration. The helpers skip exact zeros and unit factors of the constants, so a
machine whose axes lie along the coordinate axes costs only the products it needs (a turn about
Z is four products and two sums per vector)."""


def _zero(x: Coord) -> bool:
    return isinstance(x, float) and x == 0.0


def _times(c: Coord, x: Coord) -> Coord:
    """``c * x``, without the work when either is an exact zero or ``c`` is a constant +-1."""
    if _zero(c) or _zero(x):
        return 0.0
    if isinstance(c, float) and abs(c) == 1.0:
        return x if c > 0.0 else -x
    return c * x


def _sum(*terms: Coord) -> Coord:
    """Sum of the terms that are not exact zeros."""
    out: Coord = 0.0
    for t in terms:
        if not _zero(t):
            out = t if _zero(out) else out + t
    return out


def _norm(v: Vec) -> Coord:
    return np.sqrt(_sum(*(_times(c, c) for c in v)))


def _plane(c: Coord, s: Coord, u: Coord, v: Coord) -> tuple[Coord, Coord]:
    """``(c u - s v, s u + c v)``: the turn of (u, v) in its plane, with as few new arrays as
    the zeros allow (numpy's element-wise work costs about twice as much into a new array)."""
    if _zero(v):
        return _times(c, u), _times(s, u)
    if _zero(u):
        return _times(s, -v), _times(c, v)
    first, second = c * u, s * u
    both = s * v
    first -= both
    np.multiply(c, v, out=both)
    second += both
    return first, second


def _turn(w: tuple[float, float, float], cos: Coord, sin: Coord, x: Vec) -> tuple[Vec, Vec]:
    """``x`` turned about the unit direction ``w`` (Rodrigues), and the part of ``x`` across ``w``.

    ``x' = w (w . x) + cos (x - w (w . x)) + sin (w x x)``; the part across ``w`` has the length
    of the distance of ``x`` from the line along ``w``. About a coordinate axis it is a turn in
    the plane of the other two.
    """
    for k in range(3):
        if abs(w[k]) == 1.0:
            a, b = (k + 1) % 3, (k + 2) % 3  # (a, b, k) right-handed
            out: list[Coord] = [0.0, 0.0, 0.0]
            out[a], out[b] = _plane(cos, _times(w[k], sin), x[a], x[b])
            out[k] = x[k]
            across: list[Coord] = [0.0, 0.0, 0.0]
            across[a], across[b] = x[a], x[b]
            return tuple(out), tuple(across)  # type: ignore[return-value]
    along = _sum(*(_times(w[i], x[i]) for i in range(3)))
    across = [_sum(x[i], _times(-w[i], along)) for i in range(3)]
    cross = (
        _sum(_times(w[1], x[2]), _times(-w[2], x[1])),
        _sum(_times(w[2], x[0]), _times(-w[0], x[2])),
        _sum(_times(w[0], x[1]), _times(-w[1], x[0])),
    )
    turned = tuple(
        _sum(_times(w[i], along), _times(cos, across[i]), _times(sin, cross[i])) for i in range(3)
    )
    return turned, tuple(across)  # type: ignore[return-value]


@dataclass(frozen=True)
class _Joint:
    """One axis of the chain: its column in ``q``, unit direction, and (rotary) the point of its
    line nearest the workpiece origin, in the workpiece frame at home (mm)."""

    column: int
    rotary: bool
    direction: tuple[float, float, float]
    pivot: tuple[float, float, float]


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


def _carry(
    joints: tuple[_Joint, ...],
    linear: dict[int, Coord],
    trig: dict[int, tuple[Coord, Coord]],
    point: Vec | None,
    vectors: list[Vec],
    radii: bool = False,
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

    Returns
    -------
    point, vectors, reach, swing
    """
    reach: dict[int, Coord] = {}
    swing: dict[int, Coord] = {}
    for j in joints:
        if not j.rotary:
            if point is not None:
                v = linear[j.column]
                point = tuple(_sum(point[i], _times(j.direction[i], v)) for i in range(3))  # type: ignore[assignment]
            continue
        cos, sin = trig[j.column]
        if point is not None:
            rel = tuple(_sum(point[i], -j.pivot[i]) for i in range(3))
            turned, across = _turn(j.direction, cos, sin, rel)  # type: ignore[arg-type]
            point = tuple(_sum(turned[i], j.pivot[i]) for i in range(3))  # type: ignore[assignment]
            if radii:
                reach[j.column] = _norm(across)
        out = []
        for k, v in enumerate(vectors):
            turned, across = _turn(j.direction, cos, sin, v)
            out.append(turned)
            if radii and k == 0:
                swing[j.column] = _norm(across)
        vectors = out
    return point, vectors, reach, swing


def _trig(machine: Machine, q: np.ndarray) -> dict[int, tuple[Coord, Coord]]:
    cols = machine.rotary_columns
    return {c: (np.cos(q[:, c]), np.sin(q[:, c])) for c in cols}


def _vec(a: np.ndarray) -> Vec:
    """A constant 3-vector as three floats."""
    return float(a[0]), float(a[1]), float(a[2])


def _rows(v: Vec, n: int) -> np.ndarray:
    """A vector as an (n, 3) array."""
    out = np.empty((n, 3))
    for i in range(3):
        out[:, i] = v[i]
    return out


def _tool_point(machine: Machine, offset: float) -> Vec:
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
    columns = [_vec(home[:3, c]) for c in range(3)]
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


def tip_and_axis(
    machine: Machine, q: np.ndarray, tool_length: float = 0.0
) -> tuple[np.ndarray, np.ndarray]:
    """Tool tip and tool axis in the workpiece frame (vectorised).

    Only the tip and the axis are carried through the joints (Rodrigues on vectors, one cosine
    and sine per rotary axis); see :func:`tool_in_work` for the whole pose.

    Parameters
    ----------
    machine : Machine
    q : ndarray, shape (n, m), mm / rad
    tool_length : float, mm
        Distance from the gauge point to the tool tip along the tool axis.

    Returns
    -------
    tip : ndarray, shape (n, 3), mm
    axis : ndarray, shape (n, 3)
        Unit tool axis (tool frame +Z).
    """
    q = _as_q(machine, q)
    tip, (axis,), _, _ = _tip_and_axis_carried(machine, q, tool_length)
    return _rows(tip, q.shape[0]), _rows(axis, q.shape[0])  # type: ignore[arg-type]


def _tip_and_axis_carried(
    machine: Machine, q: np.ndarray, tool_length: float, radii: bool = False
) -> tuple[Vec | None, list[Vec], dict[int, Coord], dict[int, Coord]]:
    """:func:`_carry` of the tip and the tool axis through joint vectors ``q`` (n, m)."""
    return _carry(
        _joints_from_tool(machine),
        {c: q[:, c] for c in machine.linear_columns},
        _trig(machine, q),
        _tool_point(machine, -tool_length),
        [_vec(machine.home_tool_axis)],
        radii=radii,
    )


def cos_sin_along(
    theta0: np.ndarray, step: np.ndarray, t: np.ndarray
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

    Returns
    -------
    cos, sin : ndarray, shape (s, n)
    """
    s = len(t)
    cos, sin = np.empty((s, len(theta0))), np.empty((s, len(theta0)))
    start = theta0 + t[0] * step
    cos[0], sin[0] = np.cos(start), np.sin(start)
    if s > 1:
        h = (t[-1] - t[0]) / (s - 1)
        cd, sd = np.cos(h * step), np.sin(h * step)
        part = np.empty(len(theta0))
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
    d = np.diff(t)
    return bool(np.all(np.abs(d - d[0]) <= 1e-12 * max(1.0, float(np.abs(t).max()))))


def tip_and_axis_along(
    machine: Machine,
    q0: np.ndarray,
    q1: np.ndarray,
    t: np.ndarray,
    tool_length: float = 0.0,
    *,
    with_tip: bool = True,
) -> tuple[Vec | None, Vec]:
    """Tool tip and axis along straight joint-space moves ``q0 + t (q1 - q0)`` (vectorised).

    What a control without tool-centre-point control does between two blocks. With ``t`` one
    evenly spaced set of parameters for every move, the cosines and sines come from angle
    addition along the samples (two per rotary axis and move, not per sample).

    Parameters
    ----------
    machine : Machine
    q0, q1 : ndarray, shape (n, m)
        Joint values at the ends of n moves, mm / rad.
    t : ndarray, shape (s,) or (s, n)
        Parameters in [0, 1]: the same for every move, or one column per move.
    tool_length : float, mm
    with_tip : bool
        False: the tool axis only (the tip is returned as None).

    Returns
    -------
    tip : Vec, mm, or None
        The x, y and z coordinates, each an array of shape (s, n): sample, move.
    axis : Vec
        Likewise.
    """
    q0, q1 = _as_q(machine, q0), _as_q(machine, q1)
    t = np.asarray(t, dtype=float)
    n = q0.shape[0]
    shape = (t.shape[0], n)
    dq = q1 - q0
    grid = t[:, None] if t.ndim == 1 else t
    linear = {}
    if with_tip:
        for c in machine.linear_columns:
            linear[c] = grid * dq[:, c]
            linear[c] += q0[:, c]
    if _evenly_spaced(t):
        trig = {c: cos_sin_along(q0[:, c], dq[:, c], t) for c in machine.rotary_columns}
    else:
        trig = {}
        for c in machine.rotary_columns:
            angle = q0[:, c] + grid * dq[:, c]
            trig[c] = (np.cos(angle), np.sin(angle))
    point = _tool_point(machine, -tool_length) if with_tip else None
    tip, (axis,), _, _ = _carry(
        _joints_from_tool(machine), linear, trig, point, [_vec(machine.home_tool_axis)]
    )

    def full(v: Vec) -> Vec:  # coordinates no joint moved are still constants
        x, y, z = (c if isinstance(c, np.ndarray) else np.full(shape, c) for c in v)
        return x, y, z

    return (full(tip) if tip is not None else None), full(axis)


def tip_axis_and_reach(
    machine: Machine, q: np.ndarray, tool_length: float = 0.0
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Tool tip and axis, and how far each rotary axis sees them from itself (vectorised).

    What :func:`interpolation_bounds` needs at the ends of a move.

    Parameters
    ----------
    machine : Machine
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
    q = _as_q(machine, q)
    n = q.shape[0]
    tip, (axis,), reach, swing = _tip_and_axis_carried(machine, q, tool_length, radii=True)
    cols = machine.rotary_columns
    reach_a, swing_a = np.empty((n, len(cols))), np.empty((n, len(cols)))
    for i, c in enumerate(cols):
        reach_a[:, i], swing_a[:, i] = reach[c], swing[c]
    return _rows(tip, n), _rows(axis, n), reach_a, swing_a  # type: ignore[arg-type]


def interpolation_bounds(
    machine: Machine,
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
    machine : Machine
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
    q0, q1 = _as_q(machine, q0), _as_q(machine, q1)
    joints = _joints_from_tool(machine)
    index = {c: i for i, c in enumerate(machine.rotary_columns)}
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


def tool_in_work_pin(machine: Machine, q: np.ndarray) -> np.ndarray:
    """Pose of the tool frame in the workpiece frame, from Pinocchio.

    Parameters
    ----------
    machine : Machine
    q : ndarray, shape (n, m) or (m,), mm / rad

    Returns
    -------
    ndarray, shape (n, 4, 4)
        Homogeneous transforms, translation in mm.
    """
    import pinocchio as pin

    q = _as_q(machine, q)
    model, data = machine.model, machine._pin_data
    fw, ft = machine._frame_ids
    out = np.empty((q.shape[0], 4, 4))
    for i, qi in enumerate(q):
        pin.framesForwardKinematics(model, data, machine.pin_configuration(qi))
        out[i] = (data.oMf[fw].inverse() * data.oMf[ft]).homogeneous
    out[:, :3, 3] *= M_TO_MM
    return out


def tip_and_axis_pin(
    machine: Machine, q: np.ndarray, tool_length: float = 0.0
) -> tuple[np.ndarray, np.ndarray]:
    """Tool tip (mm) and axis in the workpiece frame from Pinocchio; see :func:`tip_and_axis`."""
    t = tool_in_work_pin(machine, q)
    axis = t[:, :3, 2]
    return t[:, :3, 3] - tool_length * axis, axis


def jacobian_pin(machine: Machine, q: np.ndarray, tool_length: float = 0.0) -> np.ndarray:
    """Jacobian of the tool tip relative to the workpiece, in the workpiece frame, from Pinocchio.

    Parameters
    ----------
    machine : Machine
    q : ndarray, shape (n, m) or (m,), mm / rad
    tool_length : float, mm
        The tip is this far from the gauge point along the tool axis.

    Returns
    -------
    ndarray, shape (n, 6, m)
        Rows 0-2: tip velocity (mm per mm, or mm per rad); rows 3-5: angular velocity of the tool
        relative to the workpiece (rad per mm, or rad per rad). Columns in ``axis_names`` order.
    """
    import pinocchio as pin

    q = _as_q(machine, q)
    model, data = machine.model, machine._pin_data
    fw, ft = machine._frame_ids
    lwa = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
    cols = [model.joints[model.getJointId(a.name)].idx_v for a in machine.axes]
    scale = np.array([1.0 if a.rotary else 1.0 / M_TO_MM for a in machine.axes])
    out = np.empty((q.shape[0], 6, len(machine.axes)))
    for i, qi in enumerate(q):
        qp = machine.pin_configuration(qi)
        pin.computeJointJacobians(model, data, qp)
        pin.updateFramePlacements(model, data)
        j_t = pin.getFrameJacobian(model, data, ft, lwa)[:, cols]
        j_w = pin.getFrameJacobian(model, data, fw, lwa)[:, cols]
        o_m_w, o_m_t = data.oMf[fw], data.oMf[ft]
        r_w = o_m_w.rotation
        tip = o_m_t.translation - tool_length / M_TO_MM * o_m_t.rotation[:, 2]
        w_rel = j_t[3:] - j_w[3:]
        # tip velocity: frame origin velocity plus omega x (tip - origin); relative to the
        # workpiece frame, which moves with v_w + omega_w x (point - workpiece origin)
        v_tip = j_t[:3] + skew(tip - o_m_t.translation).T @ j_t[3:]
        v_work = j_w[:3] + skew(tip - o_m_w.translation).T @ j_w[3:]
        lin = r_w.T @ (v_tip - v_work) * M_TO_MM
        ang = r_w.T @ w_rel
        out[i] = np.vstack([lin, ang]) * scale
    return out
