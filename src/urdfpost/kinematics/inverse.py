"""Closed-form inverse kinematics for any machine with one or two rotary axes.

One algorithm for every machine, set up from the screws derived at load time
(:mod:`urdfpost.machine`). With the rotary axes k1 (nearest the workpiece along the chain) and
k2, signed so that positive angles are positive joint values, the tool axis in the workpiece
frame is

    v = R(k1, t1) R(k2, t2) v0,

v0 being the tool axis at home. This is Paden-Kahan subproblem 2:

1. k1 . v does not change under the first rotation, so ``u = R(k2, t2) v0`` must make the
   same angle theta with k1 as v. u runs on a cone about k2 (half-angle phi, the angle from k2
   to v0) and k1 is at psi from k2, so in the spherical triangle (k2, k1, u) the sides are
   psi, phi and theta, and the angle at k2 is ``half = |t2 - base|``, ``base`` being the t2
   that brings u nearest to k1: ``t2 = base +/- half``, two branches, one where they merge (the
   edges of the reachable band ``|psi - phi| <= theta <= psi + phi``), none outside it. By
   the half-angle formula of spherical trigonometry
   ``tan^2(half / 2) = (m - m_edge) / (p - p_edge)`` with ``m = 1 - cos(theta)``,
   ``p = 1 + cos(theta)`` and their values at the edges ``m_edge = 1 - cos(psi - phi)``,
   ``p_edge = 1 + cos(psi + phi)``. m and p are taken as ``|v -/+ k1|^2 / 2`` from the
   components of v across and along k1, so they keep full relative precision at the poles
   (v parallel to k1), where ``1 - k1 . v`` would cancel to nothing: an arccos of k1 . v
   there loses half the digits, and at an edge that is also a pole that moves the tool axis
   itself by ~1e-8 rad.
2. ``t1`` is the angle from u to v about k1, both projected onto the plane normal to k1;
   undefined when v is parallel to k1 (the pole).

With one rotary axis (4-axis machines) the tool axis must lie on the cone R(k1, t) v0, and t is
the angle about k1 as in step 2.

Given the rotary angles, the tool tip position is affine in the three linear joint values. The
rotations of the rotary axes that come before the first linear axis along the chain are undone
on the tip, those after it are applied to the tool tip at home, and what is left is a 3x3
linear system whose columns are the linear axis directions (constant on every conventional
chain), solved by Cramer's rule.

Everything is numpy over all points, on vectors kept as their three coordinate arrays and
rotated by Rodrigues' formula (no rotation matrices), in blocks of :data:`BLOCK` points.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass
from enum import IntEnum
from typing import overload

import numpy as np

from urdfpost.machine import Machine
from urdfpost.tolerances import Tolerances

BLOCK = 16384
"""Points per block of the vectorised solvers: the few dozen temporary arrays of a block stay
in the CPU cache, which makes numpy's element-wise work two to three times faster than over
millions of points at once."""

Coord = np.ndarray | float
Vec = tuple[Coord, Coord, Coord]
"""A vector as its x, y, z coordinates: floats for one constant vector, arrays of shape (k,)
for one vector per point (the two mix freely in the helpers below)."""

Constant = tuple[float, float, float]
"""A constant vector: three floats (the machine's directions and points)."""

Arrays = tuple[np.ndarray, np.ndarray, np.ndarray]
"""One vector per point: three coordinate arrays of shape (k,)."""


class IKStatus(IntEnum):
    """What the inverse kinematics found for one tool axis."""

    OK = 0
    """Two distinct branches (one on 4-axis machines)."""
    UNREACHABLE = 1
    """No rotary angles give this tool axis."""
    POLE = 2
    """The tool axis is parallel to the first rotary axis: that angle is undetermined (NaN)."""
    EDGE = 3
    """At the edge of the reachable orientations: the two branches merge into one."""


@dataclass(frozen=True)
class RotarySolutions:
    """Every rotary solution per tool axis.

    Attributes
    ----------
    angles : ndarray, shape (n, 2, r), rad
        Branch b of point i: ``angles[i, b]``, columns in ``machine.rotary`` (chain) order,
        each wrapped to (-pi, pi]. NaN where the branch does not exist, and in the first
        column at a pole (undetermined angle).
    valid : ndarray, shape (n, 2), bool
        Which branches exist.
    status : ndarray, shape (n,), int8
        :class:`IKStatus` per point.
    """

    angles: np.ndarray
    valid: np.ndarray
    status: np.ndarray

    @property
    def branch_count(self) -> np.ndarray:
        """Number of branches per point, shape (n,)."""
        return self.valid.sum(axis=1)


# -- vectors as coordinate triples ---------------------------------------------------------------


def _vec(a: np.ndarray) -> Constant:
    """A constant 3-vector as three floats."""
    x, y, z = a.tolist()
    return x, y, z


def _coords(a: np.ndarray) -> Arrays:
    """Rows of an (k, 3) array as three contiguous coordinate arrays."""
    x, y, z = np.ascontiguousarray(a.T)
    return x, y, z


def _add(a: Vec, b: Vec) -> Vec:
    return a[0] + b[0], a[1] + b[1], a[2] + b[2]


@overload
def _sub(a: Constant, b: Constant) -> Constant: ...
@overload
def _sub(a: Vec, b: Vec) -> Vec: ...
def _sub(a: Vec, b: Vec) -> Vec:
    return a[0] - b[0], a[1] - b[1], a[2] - b[2]


@overload
def _scale(s: float, a: Constant) -> Constant: ...
@overload
def _scale(s: Coord, a: Vec) -> Vec: ...
def _scale(s: Coord, a: Vec) -> Vec:
    return s * a[0], s * a[1], s * a[2]


@overload
def _dot(a: Constant, b: Constant) -> float: ...
@overload
def _dot(a: Vec, b: Arrays) -> np.ndarray: ...
@overload
def _dot(a: Arrays, b: Vec) -> np.ndarray: ...
@overload
def _dot(a: Vec, b: Vec) -> Coord: ...
def _dot(a: Vec, b: Vec) -> Coord:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@overload
def _cross(a: Constant, b: Constant) -> Constant: ...
@overload
def _cross(a: Vec, b: Vec) -> Vec: ...
def _cross(a: Vec, b: Vec) -> Vec:
    return a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]


def _turn(k: Vec, cos: Coord, sin: Coord, p: Vec) -> Vec:
    """``p`` rotated about the unit direction ``k`` by the angle of ``cos``, ``sin`` (Rodrigues)."""
    kxp = _cross(k, p)
    w = _dot(k, p) * (1.0 - cos)
    return (
        p[0] * cos + kxp[0] * sin + k[0] * w,
        p[1] * cos + kxp[1] * sin + k[1] * w,
        p[2] * cos + kxp[2] * sin + k[2] * w,
    )


def _unit(a: Constant) -> Constant:
    """A constant vector scaled to length 1."""
    norm = math.sqrt(_dot(a, a))
    return a[0] / norm, a[1] / norm, a[2] / norm


def _frame(k: Constant) -> tuple[Constant, Constant]:
    """Unit vectors e1, e2 with (e1, e2, k) orthonormal and right-handed (e1 x e2 = k)."""
    smallest = min(range(3), key=lambda i: abs(k[i]))
    hx, hy, hz = (float(i == smallest) for i in range(3))
    e1 = _unit(_cross(k, (hx, hy, hz)))
    return e1, _cross(k, e1)


def _angle_between(a: Constant, b: Constant) -> float:
    """Angle between two constant vectors, rad, accurate near 0 and pi."""
    c = _cross(a, b)
    return math.atan2(math.sqrt(_dot(c, c)), _dot(a, b))


def _wrap(a: np.ndarray) -> np.ndarray:
    """Angles in (-3 pi, 3 pi] wrapped to (-pi, pi]."""
    return a - 2 * np.pi * (a > np.pi) + 2 * np.pi * (a <= -np.pi)


def _blocks(n: int) -> Iterator[slice]:
    """Consecutive slices of at most :data:`BLOCK` points covering ``range(n)``."""
    for start in range(0, n, BLOCK):
        yield slice(start, min(start + BLOCK, n))


# -- the machine's constants -------------------------------------------------------------------


@dataclass(frozen=True)
class _SolveConstants:
    """The chain between workpiece and tool as the linear solve needs it.

    Attributes
    ----------
    lines : tuple of (Vec, Vec)
        Rotary axes in chain order: unit direction and a point on the axis (mm), at home.
    lead : int
        Number of rotary axes between the workpiece and the first linear axis.
    columns : tuple of (Vec, int)
        Per linear axis in NC order: its direction at home and the number of rotary axes
        before it along the chain.
    gauge : Vec
        Tool frame origin at home, mm.
    axis : Vec
        Tool axis at home.
    """

    lines: tuple[tuple[Constant, Constant], ...]
    lead: int
    columns: tuple[tuple[Constant, int], ...]
    gauge: Constant
    axis: Constant

    @classmethod
    def of(cls, machine: Machine) -> _SolveConstants:
        lines: list[tuple[Constant, Constant]] = []
        before: dict[str, int] = {}
        for a in sorted(machine.axes, key=lambda a: a.chain_index):
            if a.rotary:
                w, v = _vec(a.screw[:3]), _vec(a.screw[3:])
                lines.append((w, _cross(w, v)))  # the point of the axis nearest the origin
            else:
                before[a.name] = len(lines)
        home = machine.home_tool_in_work
        return cls(
            lines=tuple(lines),
            lead=min(before.values()),
            columns=tuple((_vec(a.direction), before[a.name]) for a in machine.linear),
            gauge=_vec(home[:3, 3]),
            axis=_vec(home[:3, 2]),
        )


@dataclass(frozen=True)
class _Tilt:
    """Constants of the rotary solution (module docstring), in the frame (e1, e2, k1).

    Attributes
    ----------
    e1, e2, k1 : Vec
        Orthonormal, right-handed; k1 the first rotary axis.
    home_axis : Vec
        v0 along e1, e2 and k1.
    swing : tuple of float
        Two rotary axes: (P1, F1, G1, P2, F2, G2) such that u = R(k2, base +/- half) v0 along
        e_i is ``P_i + F_i cos(half) +/- G_i sin(half)``.
    cos_base, sin_base : float
        Of ``base``, the t2 that brings u nearest to k1.
    m_edge, p_edge : float
        ``1 - cos(psi - phi)`` and ``1 + cos(psi + phi)``: the values of ``1 -/+ k1 . v`` at
        the two edges of the reachable band (each 0 when that edge is a pole).
    radius : float
        ``sin(psi) sin(phi)``: half the width of the band in ``k1 . v``.
    """

    e1: Constant
    e2: Constant
    k1: Constant
    home_axis: Constant
    swing: tuple[float, ...] = ()
    cos_base: float = 1.0
    sin_base: float = 0.0
    m_edge: float = 0.0
    p_edge: float = 0.0
    radius: float = 0.0

    @classmethod
    def of(cls, machine: Machine) -> _Tilt:
        rot = machine.rotary
        k1, v0 = _vec(rot[0].direction), _vec(machine.home_tool_axis)
        e1, e2 = _frame(k1)
        home_axis = (_dot(e1, v0), _dot(e2, v0), _dot(k1, v0))
        if len(rot) == 1:
            return cls(e1, e2, k1, home_axis)
        k2 = _vec(rot[1].direction)
        # turned by t2 about k2, v0 is along + cos(t2) across + sin(t2) side
        along = _scale(_dot(k2, v0), k2)
        across, side = _sub(v0, along), _cross(k2, v0)
        a, b = _dot(k1, across), _dot(k1, side)
        radius = math.hypot(a, b)  # > 0: the machine file checks forbid k2 parallel to k1, v0
        cos_base, sin_base = a / radius, b / radius
        swing: list[float] = []
        for e in (e1, e2):
            c, s = _dot(e, across), _dot(e, side)
            swing += [_dot(e, along), c * cos_base + s * sin_base, s * cos_base - c * sin_base]
        psi, phi = _angle_between(k2, k1), _angle_between(k2, v0)
        return cls(
            e1,
            e2,
            k1,
            home_axis,
            tuple(swing),
            cos_base,
            sin_base,
            m_edge=2.0 * math.sin(0.5 * (psi - phi)) ** 2,
            p_edge=2.0 * math.cos(0.5 * (psi + phi)) ** 2,
            radius=radius,
        )


# -- rotary axes ---------------------------------------------------------------------------------


@dataclass(frozen=True)
class _RotaryBlock:
    """Rotary solutions of one block of k points (see :class:`RotarySolutions`).

    ``turns[b][j]`` is (cos, sin) of rotary axis j on branch b (one branch with one rotary
    axis), arrays of shape (k,), for the linear solve; meaningless where the branch does not
    exist and, for the first axis, at a pole.
    """

    angles: np.ndarray  # (k, 2, r)
    valid: np.ndarray  # (k, 2)
    status: np.ndarray  # (k,)
    turns: tuple[tuple[tuple[np.ndarray, np.ndarray], ...], ...]


def _rotary_block(tilt: _Tilt, r: int, v: Arrays, tol: Tolerances) -> _RotaryBlock:
    """Rotary solutions for the tool axes ``v`` (coordinate arrays of shape (k,))."""
    v1, v2, v3 = _dot(tilt.e1, v), _dot(tilt.e2, v), _dot(tilt.k1, v)
    if r == 1:
        return _one_rotary(tilt, v1, v2, v3, tol)
    return _two_rotaries(tilt, v1, v2, v3, tol)


def _turn_between(
    u1: Coord, u2: Coord, v1: np.ndarray, v2: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Angle about k1 from u to v (step 2), with its cos and sin, from their e1, e2 parts."""
    cross, dot = u1 * v2 - u2 * v1, u1 * v1 + u2 * v2
    rho = np.sqrt(cross * cross + dot * dot)
    return _wrap(np.arctan2(cross, dot)), dot / rho, cross / rho


def _one_rotary(
    tilt: _Tilt, v1: np.ndarray, v2: np.ndarray, v3: np.ndarray, tol: Tolerances
) -> _RotaryBlock:
    """4-axis machines: the angle about k1 for tool axes with coordinates v1, v2, v3."""
    h1, h2, h3 = tilt.home_axis
    size = np.sqrt(v1 * v1 + v2 * v2)
    t1, cos1, sin1 = _turn_between(h1, h2, v1, v2)
    off_cone = np.abs(v3 - h3) > tol.four_axis_axis
    pole = (size < tol.pole) & ~off_cone
    # v0 turned by t1 misses v by the difference of their distances from k1 and their heights
    # along it
    radial = math.hypot(h1, h2) - size
    miss = np.sqrt(radial * radial + (v3 - h3) ** 2)
    ok = ~off_cone & ((miss <= tol.four_axis_axis) | pole)
    k = len(size)
    angles = np.full((k, 2, 1), np.nan)
    angles[:, 0, 0] = np.where(ok & ~pole, t1, np.nan)
    valid = np.zeros((k, 2), dtype=bool)
    valid[:, 0] = ok
    status = np.zeros(k, dtype=np.int8)
    status[~ok] = IKStatus.UNREACHABLE
    status[pole] = IKStatus.POLE
    return _RotaryBlock(angles, valid, status, (((cos1, sin1),),))


def _two_rotaries(
    tilt: _Tilt, v1: np.ndarray, v2: np.ndarray, v3: np.ndarray, tol: Tolerances
) -> _RotaryBlock:
    """Both branches (steps 1 and 2) for tool axes with coordinates v1, v2, v3."""
    across2 = v1 * v1 + v2 * v2  # |k1 x v|^2
    size = np.sqrt(across2)
    m = 0.5 * (across2 + (1.0 - v3) ** 2) - tilt.m_edge  # |v - k1|^2 / 2 - m_edge
    p = 0.5 * (across2 + (1.0 + v3) ** 2) - tilt.p_edge  # |v + k1|^2 / 2 - p_edge
    slack = -tol.reach * tilt.radius  # reach is in the cosine domain: |cos(half)| <= 1 + reach
    reachable = (m >= slack) & (p >= slack)
    m, p = np.maximum(m, 0.0), np.maximum(p, 0.0)  # onto the edge within the slack
    sm, sp = np.sqrt(m), np.sqrt(p)
    half = 2.0 * np.arctan2(sm, sp)
    cos_half, sin_half = (p - m) / (p + m), 2.0 * sm * sp / (p + m)
    # branches closer than branch_merge are one (the edge). Both are exact: the one kept is not
    # moved onto the edge, which turns the tool axis by first order where the edge is a pole
    edge = 0.5 * tol.branch_merge
    merged = reachable & ((half < edge) | (np.pi - half < edge))
    pole = reachable & (size < tol.pole)
    valid = np.stack([reachable, reachable & ~merged], axis=1)
    k = len(size)
    status = np.zeros(k, dtype=np.int8)
    status[merged] = IKStatus.EDGE
    status[pole] = IKStatus.POLE
    status[~reachable] = IKStatus.UNREACHABLE

    p1, f1, g1, p2, f2, g2 = tilt.swing
    even1, even2 = p1 + f1 * cos_half, p2 + f2 * cos_half
    odd1, odd2 = g1 * sin_half, g2 * sin_half
    cb, sb = tilt.cos_base, tilt.sin_base
    base = math.atan2(sb, cb)
    angles = np.empty((k, 2, 2))
    turns = []
    for b, sign in enumerate((1.0, -1.0)):
        t1, cos1, sin1 = _turn_between(even1 + sign * odd1, even2 + sign * odd2, v1, v2)
        t1[pole] = np.nan
        angles[:, b, 0] = t1
        angles[:, b, 1] = _wrap(base + sign * half)
        cos2, sin2 = cb * cos_half - sign * sb * sin_half, sb * cos_half + sign * cb * sin_half
        turns.append(((cos1, sin1), (cos2, sin2)))
    angles[~valid] = np.nan
    return _RotaryBlock(angles, valid, status, tuple(turns))


def solve_rotary(
    machine: Machine, axis: np.ndarray, tol: Tolerances | None = None
) -> RotarySolutions:
    """All rotary angles that point the tool along ``axis``.

    Parameters
    ----------
    machine : Machine
    axis : ndarray, shape (n, 3)
        Unit tool axes in the workpiece frame.
    tol : Tolerances, optional

    Returns
    -------
    RotarySolutions
    """
    tol = tol or Tolerances()
    v = np.asarray(axis, dtype=float).reshape(-1, 3)
    n, r = v.shape[0], len(machine.rotary)
    tilt = _Tilt.of(machine)
    angles = np.empty((n, 2, r))
    valid = np.empty((n, 2), dtype=bool)
    status = np.empty(n, dtype=np.int8)
    with np.errstate(invalid="ignore", divide="ignore"):
        for sl in _blocks(n):
            block = _rotary_block(tilt, r, _coords(v[sl]), tol)
            angles[sl], valid[sl], status[sl] = block.angles, block.valid, block.status
    return RotarySolutions(angles=angles, valid=valid, status=status)


# -- linear axes ---------------------------------------------------------------------------------


def _linear_block(
    chain: _SolveConstants,
    turns: tuple[tuple[np.ndarray, np.ndarray], ...],
    tip: Arrays,
    tool_length: float,
) -> Vec:
    """Linear axis values (NC order) putting the tip on ``tip`` with the rotary ``turns``.

    With ``T_i(p) = c_i + R_i (p - c_i)`` the motion of rotary axis i (chain order, about the
    line through c_i), L the rotary axes before the first linear one and e the tool tip at home,
    ``tip = T_1 ... T_L (sum_j x_j d_j' + T_L+1 ... T_r e)``, where d_j' is linear axis j's
    direction turned by the rotary axes between the first linear axis and it.

    ``turns`` holds (cos, sin) per rotary axis in chain order, arrays of shape (k,); ``tip``
    coordinate arrays of shape (k,), mm. Returns coordinate arrays of shape (k,), mm.
    """
    lead = chain.lead
    # undo the rotary axes between the workpiece and the linear axes on the tip ...
    p: Vec = tip
    for (k, c), (cos, sin) in zip(chain.lines[:lead], turns[:lead], strict=True):
        p = _add(c, _turn(k, cos, -sin, _sub(p, c)))
    # ... and apply those between the linear axes and the tool to the tool tip at home
    g: Vec = _sub(chain.gauge, _scale(tool_length, chain.axis))
    for (k, c), (cos, sin) in reversed(list(zip(chain.lines[lead:], turns[lead:], strict=True))):
        g = _add(c, _turn(k, cos, sin, _sub(g, c)))
    # the linear axes now move p - g along their directions (constant unless a rotary axis
    # sits between two of them along the chain)
    columns = []
    d: Vec  # a constant direction, turned by the rotary axes in between
    for d, before in chain.columns:
        for j in reversed(range(lead, before)):
            d = _turn(chain.lines[j][0], *turns[j], d)
        columns.append(d)
    return _cramer(columns, _sub(p, g))


def _cramer(columns: list[Vec], rhs: Vec) -> Vec:
    """Solution x of ``sum_j x_j columns[j] = rhs`` (Cramer's rule)."""
    a, b, c = columns
    normals = (_cross(b, c), _cross(c, a), _cross(a, b))
    det = _dot(a, normals[0])
    x, y, z = (_dot(nrm, rhs) / det for nrm in normals)
    return x, y, z


def assemble(machine: Machine, rotary: np.ndarray, linear: np.ndarray) -> np.ndarray:
    """Joint vectors from rotary angles (chain order) and linear values (NC order).

    Parameters
    ----------
    rotary : ndarray, shape (n, r), rad
    linear : ndarray, shape (n, 3), mm

    Returns
    -------
    ndarray, shape (n, m)
    """
    n = rotary.shape[0]
    q = np.empty((n, len(machine.axes)))
    rot, lin = list(machine.rotary_columns), list(machine.linear_columns)
    for sl in _blocks(n):  # (in blocks: what is written stays in the cache)
        qb = q[sl]
        qb[:, rot] = rotary[sl]
        qb[:, lin] = linear[sl]
    return q


def solve_linear(
    machine: Machine,
    rotary: np.ndarray,
    tip: np.ndarray,
    tool_length: float = 0.0,
) -> np.ndarray:
    """Linear axis values that put the tool tip on ``tip`` for the given rotary angles.

    Parameters
    ----------
    machine : Machine
    rotary : ndarray, shape (n, r), rad
        Rotary angles in ``machine.rotary`` (chain) order.
    tip : ndarray, shape (n, 3), mm
        Tool tip in the workpiece frame.
    tool_length : float, mm
        The gauge point is placed this far above the tip along the tool axis the angles give.

    Returns
    -------
    ndarray, shape (n, 3), mm
        X, Y, Z in NC order.
    """
    tip = np.asarray(tip, dtype=float).reshape(-1, 3)
    rotary = np.asarray(rotary, dtype=float).reshape(len(tip), -1)
    chain = _SolveConstants.of(machine)
    out = np.empty((len(tip), 3))
    for sl in _blocks(len(tip)):
        turns = tuple((np.cos(t), np.sin(t)) for t in rotary[sl].T)
        out[sl] = np.stack(_linear_block(chain, turns, _coords(tip[sl]), tool_length), axis=1)
    return out


# -- both ------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class IKResult:
    """Full joint solutions for every branch.

    Attributes
    ----------
    q : ndarray, shape (n, 2, m), mm / rad
        Joint vectors per branch (NaN where the branch does not exist). At a pole the first
        rotary angle is the ``pole_angle`` given to :func:`inverse`.
    rotary : RotarySolutions
    """

    q: np.ndarray
    rotary: RotarySolutions

    @property
    def valid(self) -> np.ndarray:
        """Which branches exist, shape (n, 2)."""
        return self.rotary.valid

    @property
    def status(self) -> np.ndarray:
        """:class:`IKStatus` per point, shape (n,)."""
        return self.rotary.status


def inverse(
    machine: Machine,
    tip: np.ndarray,
    axis: np.ndarray,
    tool_length: float = 0.0,
    tol: Tolerances | None = None,
    pole_angle: float = 0.0,
) -> IKResult:
    """Every joint solution that puts the tool tip on ``tip`` along ``axis``.

    Parameters
    ----------
    machine : Machine
    tip : ndarray, shape (n, 3), mm
    axis : ndarray, shape (n, 3)
        Unit tool axes.
    tool_length : float, mm
    tol : Tolerances, optional
    pole_angle : float, rad
        Value used for the first rotary angle where it is undetermined (at a pole); the
        branch selection usually passes the previous block's angle instead.

    Returns
    -------
    IKResult
    """
    tol = tol or Tolerances()
    tip = np.asarray(tip, dtype=float).reshape(-1, 3)
    axis = np.asarray(axis, dtype=float).reshape(-1, 3)
    n, r = tip.shape[0], len(machine.rotary)
    tilt, chain = _Tilt.of(machine), _SolveConstants.of(machine)
    rot_cols, lin_cols = list(machine.rotary_columns), list(machine.linear_columns)
    cos_pole, sin_pole = np.cos(pole_angle), np.sin(pole_angle)
    angles = np.empty((n, 2, r))
    valid = np.empty((n, 2), dtype=bool)
    status = np.empty(n, dtype=np.int8)
    q = np.empty((n, 2, len(machine.axes)))
    with np.errstate(invalid="ignore", divide="ignore"):
        for sl in _blocks(n):
            block = _rotary_block(tilt, r, _coords(axis[sl]), tol)
            angles[sl], valid[sl], status[sl] = block.angles, block.valid, block.status
            pole = block.status == IKStatus.POLE
            tip_b = _coords(tip[sl])
            qb = q[sl]
            qb[:, :, rot_cols] = block.angles
            for b, ((cos1, sin1), *rest) in enumerate(block.turns):
                cos1[pole], sin1[pole] = cos_pole, sin_pole
                lin = _linear_block(chain, ((cos1, sin1), *rest), tip_b, tool_length)
                for col, value in zip(lin_cols, lin, strict=True):
                    qb[:, b, col] = value
            qb[:, :, rot_cols[0]][pole] = pole_angle
            qb[~block.valid] = np.nan
    return IKResult(q=q, rotary=RotarySolutions(angles=angles, valid=valid, status=status))


# -- singular sets -------------------------------------------------------------------------------


@dataclass(frozen=True)
class SingularSet:
    """A set of tool directions where the inverse kinematics degenerates.

    Attributes
    ----------
    kind : str
        "pole" (the first rotary angle is undetermined) or "edge" (the two branches merge at
        the boundary of the reachable orientations).
    direction : ndarray, shape (3,)
        The pole direction, or the cone axis for an edge (the first rotary axis), in the
        workpiece frame at home.
    cone_angle : float, rad
        Angle of the tool axis from ``direction`` (0 for a pole).
    within_travel : bool
        Whether the machine's rotary travel reaches it.
    """

    kind: str
    direction: np.ndarray
    cone_angle: float
    within_travel: bool


def _within_travel(machine: Machine, axis: np.ndarray, tol: Tolerances) -> bool:
    sols = solve_rotary(machine, axis[None, :], tol)
    for b in range(2):
        if not sols.valid[0, b]:
            continue
        ok = True
        for j, a in enumerate(machine.rotary):
            value = sols.angles[0, b, j]
            if np.isnan(value) or a.continuous:
                continue
            shifts = value + 2 * np.pi * np.arange(-3, 4)
            ok &= bool(np.any((shifts >= a.lower - 1e-9) & (shifts <= a.upper + 1e-9)))
        if ok:
            return True
    return False


def singular_sets(machine: Machine, tol: Tolerances | None = None) -> list[SingularSet]:
    """The singular tool directions of a machine, derived from its rotary axes.

    Returns
    -------
    list of SingularSet
    """
    tol = tol or Tolerances()
    rot = machine.rotary
    k1 = rot[0].direction
    tilt = _Tilt.of(machine)
    out: list[SingularSet] = []
    if len(rot) == 1:
        cos_lo = cos_hi = tilt.home_axis[2]
    else:
        cos_lo, cos_hi = tilt.p_edge - 1.0, 1.0 - tilt.m_edge
    for sign in (1.0, -1.0):
        if (sign > 0 and cos_hi >= 1 - 1e-9) or (sign < 0 and cos_lo <= -1 + 1e-9):
            d = sign * k1
            out.append(SingularSet("pole", d, 0.0, _within_travel(machine, d, tol)))
    if len(rot) == 2:
        for cos_edge in {cos_lo, cos_hi}:
            if abs(cos_edge) < 1 - 1e-9:
                ang = float(np.arccos(cos_edge))
                # one direction on the cone, to test travel
                perp = np.cross(k1, [1.0, 0.0, 0.0])
                if np.linalg.norm(perp) < 1e-6:
                    perp = np.cross(k1, [0.0, 1.0, 0.0])
                perp /= np.linalg.norm(perp)
                d = np.cos(ang) * k1 + np.sin(ang) * perp
                out.append(SingularSet("edge", k1.copy(), ang, _within_travel(machine, d, tol)))
    return out


def nearest_solution(
    machine: Machine, axis: np.ndarray, guess: np.ndarray, tol: Tolerances
) -> np.ndarray:
    """Exact rotary angles for tool axes on the branch and turn nearest a guess.

    Parameters
    ----------
    machine : Machine
    axis : ndarray, shape (k, 3)
    guess : ndarray, shape (k, r), rad
        Rotary angles (chain order) to be near; an undetermined first angle (a pole) takes
        the guess's, and so does an unreachable axis (which a reachable path cannot give).

    Returns
    -------
    ndarray, shape (k, r), rad
    """
    sols = solve_rotary(machine, axis, tol)
    ang = sols.angles.copy()  # (k, 2, r)
    ang[:, :, 0] = np.where(np.isnan(ang[:, :, 0]), guess[:, None, 0], ang[:, :, 0])
    ang = ang + 2 * np.pi * np.round((guess[:, None, :] - ang) / (2 * np.pi))
    dist = np.abs(ang - guess[:, None, :]).sum(axis=2)
    dist = np.where(sols.valid, dist, np.inf)
    br = np.argmin(dist, axis=1)
    rot = ang[np.arange(len(br)), br]
    bad = ~np.isfinite(dist[np.arange(len(br)), br])
    rot[bad] = guess[bad]
    return rot
