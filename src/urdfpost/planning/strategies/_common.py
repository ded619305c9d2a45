"""Pieces the strategy modules share: pole crossings, branch switches, turns in place, the
closest tilt.

- :func:`split_at_pole_crossings`: points inserted where a feed move's tool axis passes a pole;
- :func:`split_at_switches`, :func:`exact_split`: a branch switch between two CL points made a
  turn at one point inserted where the branches meet;
- :func:`insert_points`, :func:`rows_on_points`: points inserted on CL segments, and a plan's
  rows between CL points made points of its toolpath;
- :func:`_turn_at_poles`, :func:`_with_arrivals`: the rows of an exact selection, with the
  first rotary axis turned in place on the pole and the arrival rows of rewinds;
- :func:`_plain`: those rows as a plan (the exact solution, nothing bent);
- :func:`best_tilt`: the second rotary angle closest to a tool axis for a given first one.
"""

from __future__ import annotations

import logging
from dataclasses import replace

import numpy as np

from urdfpost.geometry import angle_between, slerp
from urdfpost.kinematics.forward import cross, rotate, row_chunks
from urdfpost.kinematics.inverse import IKStatus, assemble, solve_linear, solve_rotary
from urdfpost.machine import Machine
from urdfpost.planning.branches import Selection
from urdfpost.planning.problem import Plan, Problem, at_param, entry_mask, exact_selection
from urdfpost.planning.singularity import Span, detect
from urdfpost.tolerances import Tolerances
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
    is the exact tilt. ``w'`` is worked out :data:`~urdfpost.kinematics.forward.ROWS` rows at
    a time (its temporaries in the CPU cache; element by element, so the bits of one pass),
    ``A`` and ``B`` over all rows at once (the last bits of a matrix product can depend on how
    its rows are split).

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
    w = np.empty((len(theta1), 3))
    for part in row_chunks(len(theta1)):
        w[part] = rotate(k1, -theta1[part], axis[part])
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


def insert_points(
    toolpath: Toolpath, param: np.ndarray, pivot: float = 0.0
) -> tuple[Toolpath, np.ndarray, np.ndarray]:
    """Points inserted on the CL segments at positions ``param`` along the path.

    Each new point lies on its segment as :func:`~urdfpost.planning.problem.at_param` puts a
    position: the cutting point ``pivot`` mm up the tool axis on the straight line between the
    segment's cutting points, the tool axis on the great circle (slerp). The new segments then
    run along the old ones: a position on them is a position on the old path.

    Parameters
    ----------
    toolpath : Toolpath
    param : ndarray, shape (k,)
        Increasing positions strictly inside segments (``i + t``, ``0 < t < 1``).
    pivot : float, mm

    Returns
    -------
    toolpath : Toolpath
        A new toolpath (the same object when ``param`` is empty); each inserted point has the
        feed, motion and line of its segment's end point; events re-indexed.
    old : ndarray, shape (n,), int
        Index of each point of ``toolpath`` in the new one.
    new : ndarray, shape (k,), int
        Index of each inserted point in the new one.
    """
    n = len(toolpath)
    param = np.asarray(param, dtype=float)
    if not param.size:
        return toolpath, np.arange(n), np.zeros(0, dtype=int)
    seg = np.clip(np.floor(param).astype(int), 0, n - 2)
    point, axis = at_param(toolpath, param, pivot)
    tip = point - pivot * axis
    at = seg + 1
    old = np.arange(n) + np.searchsorted(at, np.arange(n), side="right")
    new = at + np.arange(len(at))
    total = n + len(at)
    out = replace(
        toolpath,
        tip=np.insert(toolpath.tip, at, tip, axis=0),
        axis=np.insert(toolpath.axis, at, axis, axis=0),
        feed=np.insert(toolpath.feed, at, toolpath.feed[at]),
        motion=np.insert(toolpath.motion, at, toolpath.motion[at]),
        line=np.insert(toolpath.line, at, toolpath.line[at]),
        events=tuple(
            replace(e, index=int(old[e.index]) if e.index < n else total) for e in toolpath.events
        ),
    )
    return out, old, new


def rows_on_points(plan: Plan, pivot: float = 0.0) -> Plan:
    """The plan with a CL point inserted at every row that lies between two points.

    The posting counts a row at a whole position as the row that reaches its CL point when it
    is the first row there; rows inserted between CL points (a curve sampled along a segment)
    are kept as points of the plan's toolpath instead, on the segments where they lay
    (:func:`insert_points`, cutting points on the line of the segment's cutting points), so
    every row stands on a point of its toolpath. Positions, curve, spans and the settled point
    are carried over to the new toolpath; the rows themselves do not change.

    Parameters
    ----------
    plan : Plan
    pivot : float, mm
        Where the cutting point is (the problem's pivot).

    Returns
    -------
    Plan
        ``plan`` itself when every row stands on a point already.
    """
    inside = plan.param != np.round(plan.param)
    if not inside.any():
        return plan
    at = np.unique(plan.param[inside])
    n = len(plan.toolpath)
    tp, old, new = insert_points(plan.toolpath, at, pivot)
    param = np.where(
        inside,
        new[np.minimum(np.searchsorted(at, plan.param), len(at) - 1)].astype(float),
        old[np.clip(np.round(plan.param).astype(int), 0, n - 1)].astype(float),
    )
    knots = np.concatenate([old, new]).astype(float)
    before = np.concatenate([np.arange(n, dtype=float), at])
    order = np.argsort(knots)
    knots, before = knots[order], before[order]
    curve = plan.curve

    def on_new(x: np.ndarray) -> np.ndarray:
        assert curve is not None
        return curve(np.interp(x, knots, before))

    settled = plan.settled
    return replace(
        plan,
        toolpath=tp,
        param=param,
        curve=None if curve is None else on_new,
        spans=[replace(sp, first=int(old[sp.first]), last=int(old[sp.last])) for sp in plan.spans],
        settled=None if settled is None or settled < 0 else int(old[settled]),
    )


SWITCH_SAMPLES = 33
"""Tool axes sampled along a CL segment (twice: the segment, then the best cell) to find where
a branch switch on it is made (:func:`split_at_switches`)."""


def split_at_switches(
    problem: Problem, toolpath: Toolpath, sel: Selection
) -> tuple[Toolpath, Selection, np.ndarray]:
    """Make each branch switch on a cutting move a turn at one point, where the branches meet.

    Near a pole the two inverse kinematics branches are close (the first rotary axis half a
    turn apart, the tilts of opposite sign), and the branch choice may switch between two
    regular CL points. Written as it is, that move turns the first rotary axis by about half a
    turn in one joint block while the tool axis hardly moves: in machine coordinates the tip
    swings off the path, and no exact point between the two rows shortens the move. Instead,
    a point is inserted on the segment where the two branches are closest (the tool axis
    nearest the pole: sampled, then refined), where the path arrives on the one branch and
    leaves on the other (a rewind point of the selection: two rows at one position). The turn
    between them is then subdivided in joint space with the tip held on the point
    (:func:`urdfpost.planning.realise.midpoint_solver`); the tool axis leaves the programmed
    one by about the distance the path misses the pole, and a turn that would swing it beyond
    the orientation tolerance lifts off like any rewind
    (:func:`urdfpost.planning.realise.with_rewinds`).

    Returns
    -------
    toolpath : Toolpath
        The same object when there is no switch.
    sel : Selection
        With a point for each inserted one (``arrive`` on the first branch, ``q`` on the
        second, ``rewind`` True).
    old : ndarray, shape (n,), int
        Index of each point of ``toolpath`` in the returned one.
    """
    machine, tol = problem.machine, problem.tol
    n = len(toolpath)
    if n < 2 or len(machine.rotary) != 2:
        return toolpath, sel, np.arange(n)
    ok = sel.status == IKStatus.OK
    entry = entry_mask(toolpath)
    moving = (toolpath.motion == Motion.FEED) & ~entry & ~sel.rewind
    at = np.flatnonzero(ok[:-1] & ok[1:] & moving[1:] & (sel.branch[:-1] != sel.branch[1:]))
    if not at.size:
        return toolpath, sel, np.arange(n)
    cols = list(machine.rotary_columns)
    lo = np.array([a.lower for a in machine.rotary])
    hi = np.array([a.upper for a in machine.rotary])
    params, arrive, leave = [], [], []
    for i in at.tolist():
        t = _closest_branches(machine, toolpath.axis[i], toolpath.axis[i + 1], tol)
        axis = slerp(toolpath.axis[i : i + 1], toolpath.axis[i + 1 : i + 2], np.array([t]))
        sols = solve_rotary(machine, axis, tol)
        rows = []
        for own in (i, i + 1):
            b = int(sel.branch[own])
            ang = sols.angles[0, b].copy()
            if not sols.valid[0, b] or np.isnan(ang).any():
                break
            near = sel.q[own, cols]
            ang += TWO_PI * np.round((near - ang) / TWO_PI)
            if np.any(ang < lo - 1e-9) or np.any(ang > hi + 1e-9):
                break
            rows.append(ang)
        if len(rows) == 2:
            params.append(i + t)
            arrive.append(rows[0])
            leave.append(rows[1])
    if not params:
        return toolpath, sel, np.arange(n)
    new_tp, old, new = insert_points(toolpath, np.array(params))
    tip = new_tp.tip[new]
    q_arrive, q_leave = (
        assemble(machine, r, solve_linear(machine, r, tip, problem.tool_length))
        for r in (np.array(arrive), np.array(leave))
    )
    log.debug("%d branch switches made turns at a point between CL points", len(params))
    ins = np.floor(params).astype(int) + 1  # where they go in the old arrays
    sel = replace(
        sel,
        q=np.insert(sel.q, ins, q_leave, axis=0),
        arrive=np.insert(sel.arrive, ins, q_arrive, axis=0),
        branch=np.insert(sel.branch, ins, sel.branch[ins]),
        status=np.insert(sel.status, ins, IKStatus.OK),
        rewind=np.insert(sel.rewind, ins, True),
        settled=None if sel.settled is None or sel.settled < 0 else int(old[sel.settled]),
    )
    return new_tp, sel, old


def _closest_branches(machine: Machine, va: np.ndarray, vb: np.ndarray, tol: Tolerances) -> float:
    """Where between tool axes ``va`` and ``vb`` (slerp parameter, inside (0, 1)) the two
    branches' second rotary angles are closest."""
    lo, hi = 0.0, 1.0
    best = 0.5
    for _ in range(2):
        t = np.linspace(lo, hi, SWITCH_SAMPLES)
        axes = slerp(np.broadcast_to(va, (len(t), 3)), np.broadcast_to(vb, (len(t), 3)), t)
        ang = solve_rotary(machine, axes, tol).angles[:, :, 1]
        gap = np.abs(np.angle(np.exp(1j * (ang[:, 0] - ang[:, 1]))))
        gap = np.where(np.isnan(gap), np.inf, gap)
        k = int(np.argmin(gap))
        best = float(t[k])
        h = (hi - lo) / (SWITCH_SAMPLES - 1)
        lo, hi = max(lo, best - h), min(hi, best + h)
    edge = 1.0 / (2 * (SWITCH_SAMPLES - 1))
    return float(np.clip(best, edge, 1.0 - edge))


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


def exact_split(problem: Problem, toolpath: Toolpath) -> tuple[Toolpath, Selection]:
    """The exact branch choice on ``toolpath`` with its branch switches made turns at a point
    (:func:`split_at_switches`): the toolpath the plan's rows then refer to, and the choice."""
    tp, sel, _ = split_at_switches(problem, toolpath, exact_selection(problem, toolpath))
    return tp, sel


def _spans(problem: Problem, toolpath: Toolpath, sel: Selection) -> list[Span]:
    """The singular spans of ``toolpath`` along the joint path ``sel`` chose."""
    return detect(problem.machine, toolpath, sel.q, problem.tol)
