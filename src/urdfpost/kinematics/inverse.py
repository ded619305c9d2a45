"""Closed-form inverse kinematics for any machine with one or two rotary axes.

One algorithm for every machine, set up from the screws derived at load time
(:mod:`urdfpost.machine`). With the rotary axes k1 (nearest the workpiece along the chain) and
k2, signed so that positive angles are positive joint values, the tool axis in the workpiece
frame is

    v = R(k1, t1) R(k2, t2) v0,

v0 being the tool axis at home. This is Paden-Kahan subproblem 2:

1. k1 . v does not change under the first rotation, so ``A cos t2 + B sin t2 = C'`` with
   ``A = k1 . (v0 - k2 (k2 . v0))``, ``B = k1 . (k2 x v0)``, ``C' = k1 . v - (k1 . k2)(k2 . v0)``;
   ``t2 = atan2(B, A) +/- arccos(C' / sqrt(A^2 + B^2))``: two branches, one where they merge
   (the edge of the reachable set), none outside it;
2. ``t1`` is the angle from u = R(k2, t2) v0 to v about k1, both projected onto the plane normal
   to k1; undefined when v is parallel to k1 (the pole).

With one rotary axis (4-axis machines) the tool axis must lie on the cone R(k1, t) v0, and t is
the angle about k1 as in step 2.

Given the rotary angles, the tool tip position is affine in the three linear joint values, so
they follow from one 3x3 linear solve per point. Everything is numpy over all points.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum

import numpy as np

from urdfpost.kinematics.forward import linear_directions, rotate, tool_in_work
from urdfpost.machine import Machine
from urdfpost.tolerances import Tolerances


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


def _wrap(a: np.ndarray) -> np.ndarray:
    """Angles wrapped to (-pi, pi]."""
    return np.pi - np.mod(np.pi - a, 2 * np.pi)


def _angle_about(k: np.ndarray, u: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Signed angle about ``k`` taking ``u`` to ``v`` (projected), and the projection length.

    Returns
    -------
    angle : ndarray, shape (n,), rad
    size : ndarray, shape (n,)
        Length of v projected onto the plane normal to k (sine of the angle between v and k).
    """
    u_p = u - np.outer(u @ k, k)
    v_p = v - np.outer(v @ k, k)
    angle = np.arctan2(np.cross(u_p, v_p) @ k, np.sum(u_p * v_p, axis=1))
    return angle, np.linalg.norm(v_p, axis=1)


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
    n = v.shape[0]
    rot = machine.rotary
    v0 = machine.home_tool_axis
    k1 = rot[0].direction
    status = np.full(n, IKStatus.OK, dtype=np.int8)
    if len(rot) == 1:
        angles = np.full((n, 2, 1), np.nan)
        valid = np.zeros((n, 2), dtype=bool)
        off_cone = np.abs(v @ k1 - k1 @ v0) > tol.four_axis_axis
        t1, size = _angle_about(k1, np.broadcast_to(v0, v.shape), v)
        pole = (size < tol.pole) & ~off_cone
        # the cone must also be hit in the right place: rotate v0 and compare
        hit = np.linalg.norm(rotate(k1, t1, v0) - v, axis=1) <= tol.four_axis_axis
        ok = ~off_cone & (hit | pole)
        angles[ok & ~pole, 0, 0] = t1[ok & ~pole]
        valid[ok, 0] = True
        status[~ok] = IKStatus.UNREACHABLE
        status[pole] = IKStatus.POLE
        return RotarySolutions(angles=angles, valid=valid, status=status)

    k2 = rot[1].direction
    a = k1 @ (v0 - k2 * (k2 @ v0))
    b = k1 @ np.cross(k2, v0)
    c = v @ k1 - (k1 @ k2) * (k2 @ v0)
    r = np.hypot(a, b)
    ratio = c / r
    reachable = np.abs(ratio) <= 1.0 + tol.reach
    half = np.arccos(np.clip(ratio, -1.0, 1.0))
    # at the edge the two branches meet; arccos turns a ratio rounded to 1 - k eps into
    # sqrt(2 k eps), so snap: the orientation then moves by only r * half^2 / 2
    edge = 0.5 * tol.branch_merge
    low, high = half < edge, np.pi - half < edge
    merged = reachable & (low | high)
    half = np.where(low, 0.0, np.where(high, np.pi, half))
    base = np.arctan2(b, a)
    t2 = np.stack([base + half, base - half], axis=1)  # (n, 2)
    valid = np.stack([reachable, reachable & ~merged], axis=1)

    t1 = np.full((n, 2), np.nan)
    size = np.zeros(n)
    for br in range(2):
        u = rotate(k2, t2[:, br], v0)
        t1[:, br], size = _angle_about(k1, u, v)
    pole = reachable & (size < tol.pole)
    t1[pole] = np.nan
    angles = np.stack([_wrap(t1), _wrap(t2)], axis=2)
    angles[~valid] = np.nan
    status[merged & reachable] = IKStatus.EDGE
    status[pole] = IKStatus.POLE
    status[~reachable] = IKStatus.UNREACHABLE
    return RotarySolutions(angles=angles, valid=valid, status=status)


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
    q[:, list(machine.rotary_columns)] = rotary
    q[:, list(machine.linear_columns)] = linear
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
    rotary = np.asarray(rotary, dtype=float).reshape(len(tip), -1)
    n = rotary.shape[0]
    zero = assemble(machine, rotary, np.zeros((n, 3)))
    rot0, gauge0 = tool_in_work(machine, zero)
    # the tool axis reached with these angles (equal to ``axis`` for exact IK answers)
    target = np.asarray(tip, dtype=float) + tool_length * rot0[:, :, 2]
    jac = linear_directions(machine, zero)  # (n, 3, 3), exact
    return np.linalg.solve(jac, (target - gauge0)[:, :, None])[:, :, 0]


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
    tip = np.asarray(tip, dtype=float).reshape(-1, 3)
    axis = np.asarray(axis, dtype=float).reshape(-1, 3)
    sols = solve_rotary(machine, axis, tol)
    n = tip.shape[0]
    q = np.full((n, 2, len(machine.axes)), np.nan)
    for br in range(2):
        ok = sols.valid[:, br]
        if not ok.any():
            continue
        ang = sols.angles[ok, br].copy()
        ang[:, 0] = np.where(np.isnan(ang[:, 0]), pole_angle, ang[:, 0])
        lin = solve_linear(machine, ang, tip[ok], tool_length)
        q[ok, br] = assemble(machine, ang, lin)
    return IKResult(q=q, rotary=sols)


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
    v0 = machine.home_tool_axis
    out: list[SingularSet] = []
    if len(rot) == 1:
        cos_lo = cos_hi = float(k1 @ v0)
    else:
        k2 = rot[1].direction
        a = k1 @ (v0 - k2 * (k2 @ v0))
        b = k1 @ np.cross(k2, v0)
        c = (k1 @ k2) * (k2 @ v0)
        r = float(np.hypot(a, b))
        cos_lo, cos_hi = max(-1.0, c - r), min(1.0, c + r)
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
