"""Pieces the strategy modules share: pole crossings, turns in place, the closest tilt.

- :func:`split_at_pole_crossings`: points inserted where a feed move's tool axis passes a pole;
- :func:`_turn_at_poles`, :func:`_with_arrivals`: the rows of an exact selection, with the
  first rotary axis turned in place on the pole and the arrival rows of rewinds;
- :func:`_plain`: those rows as a plan (the exact solution, nothing bent);
- :func:`best_tilt`: the second rotary angle closest to a tool axis for a given first one.
"""

from __future__ import annotations

import logging
from dataclasses import replace

import numpy as np

from urdfpost.geometry import angle_between
from urdfpost.kinematics.forward import cross, rotate
from urdfpost.kinematics.inverse import IKStatus
from urdfpost.machine import Machine
from urdfpost.planning.branches import Selection
from urdfpost.planning.problem import Plan, Problem, entry_mask
from urdfpost.planning.singularity import Span, detect
from urdfpost.toolpath import Motion, Toolpath

log = logging.getLogger(__name__)


TWO_PI = 2.0 * np.pi


def best_tilt(
    machine: Machine, axis: np.ndarray, theta1: np.ndarray, near: np.ndarray
) -> np.ndarray:
    """The second rotary angle that brings the tool closest to ``axis`` for a given first one.

    With ``v = R(k1, t1) R(k2, t2) v0``, the angle to the target ``w`` is smallest where
    ``(R(k1, -t1) w) . R(k2, t2) v0`` is largest: ``t2 = atan2(B, A)`` with
    ``A = w'.(v0 - k2 (k2.v0))`` and ``B = w'.(k2 x v0)``. Where the first angle is exact this
    is the exact tilt.

    Parameters
    ----------
    machine : Machine
    axis : ndarray, shape (k, 3)
        Target tool axes.
    theta1 : ndarray, shape (k,), rad
    near : ndarray, shape (k,), rad
        The 360-degree multiple nearest these is returned.

    Returns
    -------
    ndarray, shape (k,), rad
    """
    k1, k2 = machine.rotary[0].direction, machine.rotary[1].direction
    v0 = machine.home_tool_axis
    w = rotate(k1, -theta1, axis)
    a = w @ (v0 - k2 * (k2 @ v0))
    b = w @ np.cross(k2, v0)
    t2 = np.arctan2(b, a)
    return t2 + TWO_PI * np.round((near - t2) / TWO_PI)


def split_at_pole_crossings(
    toolpath: Toolpath,
    machine: Machine,
    within: float,
    snap_points: bool = False,
    pivot: float = 0.0,
) -> Toolpath:
    """Insert the point where a feed move's tool axis passes a pole within ``within`` rad.

    Between two CL points the tool axis follows the great circle from one axis to the other.
    Where that arc passes a pole (the tool axis along the first rotary axis) closer than
    ``within``, a point is added on the CL segment at the closest approach with its axis on
    the pole (moving the orientation there by at most ``within``). With ``snap_points``, a CL
    point that is itself the closest approach (nearer the pole than both neighbours, within
    ``within``) has its axis moved onto the pole instead. Points whose axis is moved keep the
    cutting point ``pivot`` mm up the tool axis from the tip on the CL path (the ball centre of
    a ball-end tool); their tip moves instead.

    Returns
    -------
    Toolpath
        A new toolpath (the same object when nothing changes); inserted points carry the line
        of the move's end point; events re-indexed.
    """
    n = len(toolpath)
    if n < 2 or not machine.rotary:
        return toolpath
    va, vb = toolpath.axis[:-1], toolpath.axis[1:]
    normal = cross(va, vb)
    size = np.linalg.norm(normal, axis=1)
    feed = toolpath.motion[1:] == Motion.FEED
    k1 = machine.rotary[0].direction
    with np.errstate(invalid="ignore", divide="ignore"):
        # sine of the distance of the pole from each great circle (both poles alike)
        off_plane = np.abs(normal @ k1) / size
    near = np.flatnonzero(feed & (size > 1e-12) & (off_plane < np.sin(within)))
    va, vb, normal, size = va[near], vb[near], normal[near], size[near]
    span = np.arctan2(size, np.sum(va * vb, axis=1))
    inserts: list[tuple[int, float, np.ndarray]] = []
    new_axis = toolpath.axis
    for pole in (k1, -k1):
        with np.errstate(invalid="ignore", divide="ignore"):
            nrm = normal / size[:, None]
            proj = pole - (nrm @ pole)[:, None] * nrm
            proj /= np.linalg.norm(proj, axis=1, keepdims=True)
            sa = np.arctan2(np.linalg.norm(cross(va, proj), axis=1), np.sum(va * proj, axis=1))
            sb = np.arctan2(np.linalg.norm(cross(proj, vb), axis=1), np.sum(proj * vb, axis=1))
        on_arc = np.abs(sa + sb - span) < 1e-9
        s = sa / np.where(span > 0, span, 1.0)
        hit = on_arc & (sa > 1e-6) & (sb > 1e-6)
        inserts += [(int(near[i]), float(s[i]), pole) for i in np.flatnonzero(hit)]
        if snap_points and n >= 3:
            dist = angle_between(toolpath.axis, pole)
            inner = np.zeros(n, dtype=bool)
            inner[1:-1] = (dist[1:-1] <= dist[:-2]) & (dist[1:-1] <= dist[2:])
            moving = np.zeros(n, dtype=bool)
            moving[1:-1] = feed[:-1] & feed[1:]
            snap = inner & moving & (dist < within) & (dist > 0)
            if snap.any():
                new_axis = new_axis.copy() if new_axis is toolpath.axis else new_axis
                new_axis[snap] = pole
    new_tip = toolpath.tip + pivot * (toolpath.axis - new_axis)
    if not inserts and new_axis is toolpath.axis:
        return toolpath
    inserts.sort(key=lambda x: (x[0], x[1]))
    at = np.array([i + 1 for i, _, _ in inserts], dtype=int)
    cut = toolpath.tip + pivot * toolpath.axis
    tips = np.array(
        [cut[i] + s * (cut[i + 1] - cut[i]) - pivot * pole for i, s, pole in inserts]
    ).reshape(-1, 3)
    axes = np.array([pole for _, _, pole in inserts]).reshape(-1, 3)
    new_index = np.arange(n) + np.searchsorted(at, np.arange(n), side="right")
    log.debug("%d pole crossings between CL points", len(inserts))
    return replace(
        toolpath,
        tip=np.insert(new_tip, at, tips, axis=0),
        axis=np.insert(new_axis, at, axes, axis=0),
        feed=np.insert(toolpath.feed, at, toolpath.feed[at]),
        motion=np.insert(toolpath.motion, at, Motion.FEED),
        line=np.insert(toolpath.line, at, toolpath.line[at]),
        events=tuple(
            replace(e, index=int(new_index[e.index]) if e.index < n else len(toolpath) + len(at))
            for e in toolpath.events
        ),
    )


def _turn_at_poles(
    machine: Machine, sel: Selection, toolpath: Toolpath
) -> tuple[np.ndarray, np.ndarray]:
    """Rows turning the first rotary axis in place where the path leaves a pole, and the rows
    of rewinds.

    At a pole the first rotary axis lies along the tool axis, so turning it there does not
    change the orientation: the angle the next point needs is reached while the tool stands
    on the pole point, instead of during the move away from it. At a rewind point
    (:attr:`Selection.rewind`) the path arrives with one solution and leaves with another of
    the same pose: two rows at the same position, which the pipeline turns into lift, turn and
    return.

    Returns
    -------
    param : ndarray, shape (N,)
    rotary : ndarray, shape (N, r)
    """
    n = len(toolpath)
    rot = sel.q[:, list(machine.rotary_columns)]
    pole = sel.status == IKStatus.POLE
    entry = entry_mask(toolpath)
    turn = np.flatnonzero(pole[:-1] & (np.abs(np.diff(rot[:, 0])) > 1e-9) & ~entry[1:])
    owner = np.insert(np.arange(n), turn + 1, turn)
    out = rot[owner].copy()
    rows = turn + 1 + np.arange(len(turn))
    out[rows, 0] = rot[turn + 1, 0]
    return _with_arrivals(machine, sel, owner.astype(float), out)


def _with_arrivals(
    machine: Machine, sel: Selection, param: np.ndarray, rotary: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Insert, before the first row of each rewind point, the row the path arrives with."""
    at = sel.rewinds
    if not at.size:
        return param, rotary
    first = np.searchsorted(param, at, side="left")
    arrive = sel.arrive[at][:, list(machine.rotary_columns)]
    return np.insert(param, first, at.astype(float)), np.insert(rotary, first, arrive, axis=0)


def _plain(problem: Problem, toolpath: Toolpath, sel: Selection, spans: list[Span]) -> Plan:
    """The exact solutions of ``sel`` as a plan: one row per point of ``toolpath``, with the
    turns in place on the pole and the arrivals of rewinds (:func:`_turn_at_poles`), nothing
    bent, no curve."""
    param, rotary = _turn_at_poles(problem.machine, sel, toolpath)
    return Plan(
        toolpath=toolpath,
        param=param,
        rotary=rotary,
        lift=np.zeros(len(param)),
        spans=spans,
        notes=list(sel.notes),
        settled=sel.settled,
    )


def _spans(problem: Problem, toolpath: Toolpath, sel: Selection) -> list[Span]:
    """The singular spans of ``toolpath`` along the joint path ``sel`` chose."""
    return detect(problem.machine, toolpath, sel.q, problem.tol)
