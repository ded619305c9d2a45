"""Singularity repair strategies: one registry, one signature, none mutates its input.

A strategy takes a :class:`Problem` (the CL data, the machine and the limits) and returns a
:class:`Plan`: the rotary angles at a sequence of positions along the CL path, and optionally
the joint curve it follows between them. It never returns linear axis values: the pipeline
solves X, Y, Z from the rotary angles so that the cutting point lies on the CL path at every
row (:func:`realise`), and the generic linearisation then subdivides blocks, taking its
midpoints from the strategy's curve, until the nonlinear error is within tolerance.

The cutting point is the tool tip, or for a ball-end tool the ball centre (``Problem.pivot`` is
the ball radius): a strategy that bends the tool axis pivots it about that point, so a
ball-end tool machines the same surface.

Strategies (sources in ``docs/singularity.md``):

``none``
    Exact inverse kinematics at every CL point, each point taking the solution nearest the
    previous one. What a naive post does; the baseline.
``recursive``
    Exact inverse kinematics, branches planned over the whole path, exact pole crossings
    inserted and the first rotary axis turned in place on the pole, blocks bisected until the
    nonlinear error is within tolerance (She-type).
``branch-flip``
    As ``recursive``, and where the tool axis passes the pole within the angle tolerance the
    orientation is bent through the pole (the closest point moved onto it), so the path can
    change tilt sign with the first rotary axis standing still, or turn it in place on the pole
    where the travel does not allow the flip.
``linear``
    Sørby-type: inside each singular span the first rotary angle runs linearly (in path length)
    from its exact value at the span's entry to its value at the exit; the tilt is the one
    closest to the programmed orientation for that angle.
``spline``
    Source A: a cubic Hermite curve of the first rotary angle across each span, with end
    tangents from the neighbouring blocks so its rate has no step; rows inserted every
    ``Tolerances.spline_step`` of rotary motion; the tilt as for ``linear``; optional lift
    along the tool axis inside the span (``Problem.lift``, off by default).
``cone``
    The tool axis moves within a cone of the angle tolerance around the programmed one so that
    the first rotary axis keeps within its velocity limit at the programmed feed: a
    velocity-limited path through the band of angles the cone allows, closest to the exact
    angles.

``linear``, ``spline`` and ``cone`` keep every orientation within the angle tolerance: a row
that would deviate more becomes an anchor with exact inverse kinematics, splitting its span.
"""

from __future__ import annotations

import itertools
import logging
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np

from urdfpost.kinematics.forward import cross, rotate
from urdfpost.kinematics.inverse import (
    IKStatus,
    assemble,
    solve_linear,
)
from urdfpost.linearize import angle_between, nearest_solution, slerp
from urdfpost.machine import Machine
from urdfpost.planning.branches import DEFAULT_RETRACT, Preference, Selection, select
from urdfpost.planning.singularity import Span, detect, feed_runs
from urdfpost.tolerances import Tolerances
from urdfpost.toolpath import Motion, Toolpath

if TYPE_CHECKING:
    from urdfpost.collision import CollisionWorld

log = logging.getLogger(__name__)

TWO_PI = 2.0 * np.pi


@dataclass(frozen=True)
class Problem:
    """What a strategy is given.

    Attributes
    ----------
    machine : Machine
    toolpath : Toolpath
        The CL data (never modified).
    tool_length : float, mm
    tol : Tolerances
    angle_tolerance : float, rad
        How far a strategy may bend the tool axis from the programmed one.
    pivot : float, mm
        Distance of the cutting point above the tip along the tool axis (the ball radius of a
        ball-end tool, else 0): a bent tool axis pivots about that point.
    prefer : Preference or None
    planner : str
        "global" or "local" branch choice for the exact solutions.
    lift : float, mm
        Lift along the tool axis inside a span (``spline`` only; 0 = off).
    collision : CollisionWorld or None
        Branch candidates and moves that collide are excluded (None: not checked).
    retract : float, mm
        Lift along the tool axis for a rewind.
    start : ndarray or None, shape (m,)
        Joint vector the path continues from (a piece of a streamed post): the first point
        takes its rotary angles exactly. None: the path starts afresh from home.
    """

    machine: Machine
    toolpath: Toolpath
    tool_length: float
    tol: Tolerances
    angle_tolerance: float = np.radians(2.0)
    pivot: float = 0.0
    prefer: Preference | None = None
    planner: str = "global"
    lift: float = 0.0
    collision: CollisionWorld | None = None
    retract: float = DEFAULT_RETRACT
    start: np.ndarray | None = None


@dataclass(frozen=True)
class Plan:
    """A strategy's answer.

    Attributes
    ----------
    toolpath : Toolpath
        The CL data the rows refer to: the input, or a copy with points inserted on CL segments
        (pole crossings), whose programmed axes may be bent (``branch-flip``).
    param : ndarray, shape (N,), float
        Position of each row along ``toolpath``: ``i + t`` is the fraction t of segment i to
        i + 1. Non-decreasing; rows with equal positions turn in place.
    rotary : ndarray, shape (N, r), rad
        Rotary angles of each row, chain order, unwrapped.
    lift : ndarray, shape (N,), mm
        Lift of the cutting point along the tool axis at each row.
    curve : callable or None
        ``curve(param) -> rotary (k, r)`` along the strategy's joint curve for subdivision; rows
        of NaN (or no curve) mean: exact inverse kinematics of the programmed orientation.
    spans : list of Span
        The singular spans the strategy saw.
    bent : bool
        Whether the tool axis was moved off the programmed one anywhere.
    notes : list of str
    settled : int or None
        The last point of ``toolpath`` whose branch choice no CL points after the path could
        change (:attr:`urdfpost.planning.branches.Selection.settled`); None: not known.
    """

    toolpath: Toolpath
    param: np.ndarray
    rotary: np.ndarray
    lift: np.ndarray
    curve: Callable[[np.ndarray], np.ndarray] | None = None
    spans: list[Span] = field(default_factory=list)
    bent: bool = False
    notes: list[str] = field(default_factory=list)
    settled: int | None = None

    @property
    def lifts(self) -> int:
        """Number of lifted stretches."""
        up = self.lift > 0
        return int(np.sum(up[1:] & ~up[:-1]) + (1 if up.size and up[0] else 0))


# -- shared pieces ---------------------------------------------------------------------------


def entry_mask(toolpath: Toolpath) -> np.ndarray:
    """Points where the path is entered anew (the first one and tool changes), shape (n,)."""
    n = len(toolpath)
    entry = np.zeros(n, dtype=bool)
    if n:
        entry[0] = True
    for e in toolpath.events:
        if e.kind == "tool" and e.index < n:
            entry[e.index] = True
    return entry


def exact_selection(problem: Problem, toolpath: Toolpath, planner: str | None = None) -> Selection:
    """Exact solutions at every point of ``toolpath`` with the problem's branch rules."""
    return select(
        problem.machine,
        toolpath.tip,
        toolpath.axis,
        tool_length=problem.tool_length,
        prefer=problem.prefer,
        entry=entry_mask(toolpath),
        lines=toolpath.line,
        source=toolpath.source,
        tol=problem.tol,
        planner=planner or problem.planner,
        cutting=toolpath.motion == Motion.FEED,
        collision=problem.collision,
        retract=problem.retract,
        start=problem.start,
        fixed_start=problem.start is not None,
    )


def at_param(toolpath: Toolpath, param: np.ndarray, pivot: float) -> tuple[np.ndarray, np.ndarray]:
    """Cutting point and programmed tool axis at positions along the CL path.

    Parameters
    ----------
    toolpath : Toolpath
    param : ndarray, shape (k,)
    pivot : float, mm

    Returns
    -------
    point : ndarray, shape (k, 3), mm
        The cutting point (tip + pivot * axis), linear along each CL segment.
    axis : ndarray, shape (k, 3)
        The programmed axis, slerp along each segment.
    """
    i, j, t = _on_segments(toolpath, param)
    return _cutting_point(toolpath, i, j, t, pivot), slerp(toolpath.axis[i], toolpath.axis[j], t)


def _on_segments(
    toolpath: Toolpath, param: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The CL segment (from point i to point j) and the parameter in it of positions
    ``param`` along the path, each of shape (k,)."""
    param = np.asarray(param, dtype=float)
    n = len(toolpath)
    if n == 1:
        i = np.zeros(param.shape, dtype=int)
        return i, i, np.zeros(param.shape)
    i = np.clip(np.floor(param).astype(int), 0, n - 2)
    return i, i + 1, np.clip(param - i, 0.0, 1.0)


def _cutting_point(
    toolpath: Toolpath, i: np.ndarray, j: np.ndarray, t: np.ndarray, pivot: float
) -> np.ndarray:
    """The cutting point (see :func:`at_param`) on segments i to j at parameters t, (k, 3) mm."""
    a, b = toolpath.tip[i], toolpath.tip[j]
    if pivot:
        a = a + pivot * toolpath.axis[i]
        b = b + pivot * toolpath.axis[j]
    return a + t[:, None] * (b - a)


def tool_axis_of(machine: Machine, rotary: np.ndarray) -> np.ndarray:
    """Tool axis in the workpiece frame for rotary angles (chain order), shape (k, 3)."""
    rot = machine.rotary
    v = np.broadcast_to(machine.home_tool_axis, (len(rotary), 3)).copy()
    for j in range(len(rot) - 1, -1, -1):
        v = rotate(rot[j].direction, rotary[:, j], v)
    return v


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


def arc_length(toolpath: Toolpath) -> np.ndarray:
    """Cumulative path measure at each CL point, shape (n,).

    Tip path length in mm plus the tool-axis turn in rad times 1 mm, so a rotation in place
    still advances.
    """
    if len(toolpath) == 0:
        return np.zeros(0)
    d = np.linalg.norm(np.diff(toolpath.tip, axis=0), axis=1)
    a = angle_between(toolpath.axis[:-1], toolpath.axis[1:])
    return np.concatenate([[0.0], np.cumsum(d + a)])


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


# -- strategies ------------------------------------------------------------------------------


def _plain(problem: Problem, toolpath: Toolpath, sel: Selection, spans: list[Span]) -> Plan:
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
    return detect(problem.machine, toolpath, sel.q, problem.tol)


def strategy_none(problem: Problem) -> Plan:
    """Exact inverse kinematics, each point nearest the previous one (naive posts)."""
    tp = problem.toolpath
    sel = exact_selection(problem, tp, planner="local")
    rotary = sel.q[:, list(problem.machine.rotary_columns)]
    param, rotary = _with_arrivals(problem.machine, sel, np.arange(len(tp), dtype=float), rotary)
    return Plan(
        toolpath=tp,
        param=param,
        rotary=rotary,
        lift=np.zeros(len(param)),
        spans=_spans(problem, tp, sel),
        notes=list(sel.notes),
        settled=sel.settled,
    )


def strategy_recursive(problem: Problem) -> Plan:
    """Exact inverse kinematics, exact pole crossings, bisection by the generic subdivision."""
    tp = split_at_pole_crossings(problem.toolpath, problem.machine, problem.tol.pole_crossing)
    sel = exact_selection(problem, tp)
    return _plain(problem, tp, sel, _spans(problem, tp, sel))


def strategy_branch_flip(problem: Problem) -> Plan:
    """Pass through the pole: bend near misses onto it, flip the tilt or turn in place there."""
    machine = problem.machine
    if len(machine.rotary) < 2:
        return strategy_recursive(problem)
    base = split_at_pole_crossings(problem.toolpath, machine, problem.tol.pole_crossing)
    spans = _spans(problem, base, exact_selection(problem, base))
    bent_tp = _bend_through_pole(problem, problem.toolpath)
    tp = split_at_pole_crossings(
        bent_tp, machine, problem.angle_tolerance, snap_points=True, pivot=problem.pivot
    )
    sel = exact_selection(problem, tp)
    plan = _plain(problem, tp, sel, spans)
    bent = tp is not problem.toolpath and (
        len(tp) != len(problem.toolpath) or not np.array_equal(tp.axis, problem.toolpath.axis)
    )
    if not bent:
        return plan
    # bending pays only where the travel lets the tilt change sign: otherwise the first axis
    # turns half a turn in place on the pole, more than the exact path turns
    exact = _plain(problem, base, exact_selection(problem, base), spans)
    travel_bent = np.abs(np.diff(plan.rotary, axis=0)).sum()
    travel_exact = np.abs(np.diff(exact.rotary, axis=0)).sum()
    if travel_bent >= travel_exact:
        note = (
            f"{problem.toolpath.source}: branch-flip: passing through the pole would not "
            "reduce rotary travel here (the tilt cannot change sign within travel); the exact "
            "solution is kept"
        )
        log.info(note)
        return replace(exact, notes=[*exact.notes, note])
    return replace(plan, bent=True)


def _bend_through_pole(problem: Problem, tp: Toolpath) -> Toolpath:
    """Shift near misses of the pole so the tool-axis trace runs through it.

    In the plane normal to the first rotary axis, the tool axis of a pass near the pole traces
    a curve that misses the origin (the pole) by ``d``. The points of the pass that lie within
    the angle tolerance of the pole, and the one beyond each end of that stretch, are shifted
    by ``-d`` (the outer ones by half), so the trace runs through the pole: each orientation
    moves by about ``|d|``, at most the angle tolerance, and the path can pass the pole with
    the tilt changing sign and the first rotary axis standing still.
    """
    machine = problem.machine
    k1 = machine.rotary[0].direction
    n = len(tp)
    if n < 3:
        return tp
    side = np.sign(tp.axis @ k1)
    perp = tp.axis - np.outer(tp.axis @ k1, k1)
    sin_phi = np.linalg.norm(perp, axis=1)
    limit = np.sin(problem.angle_tolerance)
    new_axis = tp.axis.copy()
    changed = False
    for s, e in feed_runs(tp):
        near = sin_phi[s : e + 1] < limit
        if not near.any():
            continue
        idx = np.flatnonzero(near) + s
        groups = np.split(idx, np.flatnonzero(np.diff(idx) > 1) + 1)
        for g in groups:
            a, b = max(s, int(g[0]) - 1), min(e, int(g[-1]) + 1)
            if b - a < 2 or np.any(side[a : b + 1] != side[a]):
                continue
            # closest point of the projected polyline to the pole
            pa, pb = perp[a:b], perp[a + 1 : b + 1]
            seg = pb - pa
            with np.errstate(invalid="ignore", divide="ignore"):
                t = np.clip(-np.sum(pa * seg, axis=1) / np.sum(seg * seg, axis=1), 0.0, 1.0)
            t = np.nan_to_num(t)
            closest = pa + t[:, None] * seg
            k = int(np.argmin(np.linalg.norm(closest, axis=1)))
            d = closest[k]
            if np.linalg.norm(d) < 1e-12 or np.linalg.norm(d) >= limit:
                continue
            weight = np.ones(b - a + 1)
            weight[0] = 0.5 if a < int(g[0]) else 1.0
            weight[-1] = 0.5 if b > int(g[-1]) else 1.0
            p_new = perp[a : b + 1] - weight[:, None] * d
            size = np.linalg.norm(p_new, axis=1)
            if np.any(size >= 1.0):
                continue
            along = side[a] * np.sqrt(1.0 - size**2)
            new_axis[a : b + 1] = p_new + along[:, None] * k1
            changed = True
    if not changed:
        return tp
    moved = angle_between(new_axis, tp.axis)
    log.debug(
        "branch-flip: %d orientations bent by up to %.4f deg",
        int(np.sum(moved > 0)),
        float(np.degrees(moved.max())),
    )
    return replace(tp, tip=tp.tip + problem.pivot * (tp.axis - new_axis), axis=new_axis)


def _interpolated(problem: Problem, shape: str) -> Plan:
    """``linear`` and ``spline``: the first rotary angle along a curve across each span."""
    machine = problem.machine
    tp = split_at_pole_crossings(problem.toolpath, machine, problem.tol.pole_crossing)
    sel = exact_selection(problem, tp)
    spans = _spans(problem, tp, sel)
    if len(machine.rotary) < 2 or not spans:
        return _plain(problem, tp, sel, spans)
    rot_exact = sel.q[:, list(machine.rotary_columns)]
    s_all = arc_length(tp)
    params: list[np.ndarray] = []
    rotary: list[np.ndarray] = []
    lifts: list[np.ndarray] = []
    pieces: list[tuple[float, float, Callable[[np.ndarray], np.ndarray]]] = []
    done = 0
    rows_param, rows_rot = _turn_at_poles(machine, sel, tp)
    for span in spans:
        a, b = span.first, span.last
        # exact rows before the span (with their turns in place)
        keep = (rows_param >= done) & (rows_param < a)
        params.append(rows_param[keep])
        rotary.append(rows_rot[keep])
        lifts.append(np.zeros(int(keep.sum())))
        anchors = [a, b]
        while True:
            p, r, pcs, worst = _span_rows(problem, tp, s_all, rot_exact, anchors, shape)
            if worst is None:
                break
            anchors = sorted(set(anchors) | {worst})
        lift = np.zeros(len(p))
        if problem.lift > 0 and shape == "spline":
            s_p = np.interp(p, np.arange(len(tp)), s_all)
            lo, hi = s_all[a], s_all[b]
            if hi > lo:
                lift = problem.lift * np.sin(np.pi * (s_p - lo) / (hi - lo)) ** 2
        params.append(p)
        rotary.append(r)
        lifts.append(lift)
        pieces += pcs
        done = b + 1
    keep = rows_param >= done
    params.append(rows_param[keep])
    rotary.append(rows_rot[keep])
    lifts.append(np.zeros(int(keep.sum())))
    param = np.concatenate(params)
    rot = np.concatenate(rotary)
    lift = np.concatenate(lifts)

    def curve(x: np.ndarray) -> np.ndarray:
        out = np.full((len(x), len(machine.rotary)), np.nan)
        for lo, hi, f in pieces:
            inside = (x >= lo) & (x <= hi)
            if inside.any():
                out[inside] = f(x[inside])
        return out

    return Plan(
        toolpath=tp,
        param=param,
        rotary=rot,
        lift=lift,
        curve=curve,
        spans=spans,
        bent=True,
        notes=list(sel.notes),
        settled=sel.settled,
    )


def _span_rows(
    problem: Problem,
    tp: Toolpath,
    s_all: np.ndarray,
    rot_exact: np.ndarray,
    anchors: list[int],
    shape: str,
) -> tuple[np.ndarray, np.ndarray, list, int | None]:
    """Rows of one span between exact anchors; the worst point beyond the angle tolerance."""
    machine, tol = problem.machine, problem.tol
    params: list[np.ndarray] = []
    rots: list[np.ndarray] = []
    pieces: list[tuple[float, float, Callable[[np.ndarray], np.ndarray]]] = []
    worst, worst_dev = None, problem.angle_tolerance
    for a, b in itertools.pairwise(anchors):
        t1a, t1b = rot_exact[a, 0], rot_exact[b, 0]
        sa, sb = s_all[a], s_all[b]
        length = max(sb - sa, 1e-12)
        if shape == "spline":
            # end tangents from the neighbouring blocks, in rad per unit of path measure
            da = _slope(rot_exact[:, 0], s_all, a, -1, a, b)
            db = _slope(rot_exact[:, 0], s_all, b, +1, a, b)
        else:
            da = db = (t1b - t1a) / length

        def theta1(x: np.ndarray, a=a, b=b, t1a=t1a, t1b=t1b, sa=sa, length=length, da=da, db=db):
            s = np.interp(x, np.arange(len(tp)), s_all)
            u = np.clip((s - sa) / length, 0.0, 1.0)
            if shape == "spline":
                h00 = 2 * u**3 - 3 * u**2 + 1
                h10 = u**3 - 2 * u**2 + u
                h01 = -2 * u**3 + 3 * u**2
                h11 = u**3 - u**2
                return h00 * t1a + h10 * length * da + h01 * t1b + h11 * length * db
            return t1a + u * (t1b - t1a)

        p = np.arange(a, b + 1, dtype=float)
        if shape == "spline":
            p = _refine(p, theta1, tol.spline_step)
        th1 = theta1(p)
        th1[0], th1[-1] = t1a, t1b
        # tilt nearest the exact tilt, interpolated between the rows' exact values
        ref2 = np.interp(p, np.arange(a, b + 1), rot_exact[a : b + 1, 1])
        _, prog_axis = at_param(tp, p, 0.0)
        th2 = best_tilt(machine, prog_axis, th1, ref2)
        th2[0], th2[-1] = rot_exact[a, 1], rot_exact[b, 1]
        rot = np.stack([th1, th2], axis=1)
        if len(machine.rotary) > 2:  # pragma: no cover - machines have at most two
            raise NotImplementedError("more than two rotary axes")
        dev = angle_between(tool_axis_of(machine, rot), prog_axis)
        inner = (p > a) & (p < b) & (p == np.round(p))
        bad = np.where(inner, dev, 0.0)
        if bad.max(initial=0.0) > worst_dev:
            worst_dev = float(bad.max())
            worst = int(p[int(np.argmax(bad))])
        lo2, hi2 = machine.rotary[1].lower, machine.rotary[1].upper
        rot[:, 1] = np.clip(rot[:, 1], lo2, hi2)

        def piece(x: np.ndarray, theta1=theta1, a=a, b=b, lo2=lo2, hi2=hi2) -> np.ndarray:
            t1 = theta1(x)
            ref = np.interp(x, np.arange(a, b + 1), rot_exact[a : b + 1, 1])
            _, ax = at_param(tp, x, 0.0)
            t2 = np.clip(best_tilt(machine, ax, t1, ref), lo2, hi2)
            return np.stack([t1, t2], axis=1)

        pieces.append((float(a), float(b), piece))
        params.append(p if not params else p[1:])
        rots.append(rot if not rots else rot[1:])
    return np.concatenate(params), np.concatenate(rots), pieces, worst


def _slope(theta: np.ndarray, s_all: np.ndarray, i: int, side: int, a: int, b: int) -> float:
    """Rate of an angle per unit path measure on the block beside point ``i`` outside [a, b]."""
    j = i + side
    if 0 <= j < len(theta) and not (a < j < b):
        ds = s_all[max(i, j)] - s_all[min(i, j)]
        if ds > 1e-12 and np.isfinite(theta[j]):
            return float((theta[max(i, j)] - theta[min(i, j)]) / ds)
    return float((theta[b] - theta[a]) / max(s_all[b] - s_all[a], 1e-12))


def _refine(p: np.ndarray, f: Callable[[np.ndarray], np.ndarray], step: float) -> np.ndarray:
    """Bisect parameter intervals until ``f`` changes by at most ``step`` between rows.

    Each interval is first split evenly by the motion sampled along it, then any piece still
    turning more than ``step`` is halved (at most 20 rounds).
    """
    out = [p[:1]]
    v = f(p)
    for k in range(len(p) - 1):
        fine = f(np.linspace(p[k], p[k + 1], 9))
        total = max(abs(v[k + 1] - v[k]), float(np.abs(np.diff(fine)).sum()))
        pieces = max(1, int(np.ceil(total / step)))
        out.append(np.linspace(p[k], p[k + 1], pieces + 1)[1:])
    rows = np.concatenate(out)
    for _ in range(20):
        big = np.flatnonzero(np.abs(np.diff(f(rows))) > step)
        if not big.size:
            break
        rows = np.insert(rows, big + 1, 0.5 * (rows[big] + rows[big + 1]))
    return rows


def strategy_linear(problem: Problem) -> Plan:
    """Sørby-type: first rotary angle linear across each span, closest tilt."""
    return _interpolated(problem, "linear")


def strategy_spline(problem: Problem) -> Plan:
    """Source A: cubic Hermite first rotary angle across each span, closest tilt, optional lift."""
    return _interpolated(problem, "spline")


def strategy_cone(problem: Problem) -> Plan:
    """Keep the first rotary axis within its velocity limit by moving the tool axis in a cone."""
    machine, tol = problem.machine, problem.tol
    tp = split_at_pole_crossings(problem.toolpath, machine, tol.pole_crossing)
    sel = exact_selection(problem, tp)
    spans = _spans(problem, tp, sel)
    if len(machine.rotary) < 2:
        return _plain(problem, tp, sel, spans)
    rot = sel.q[:, list(machine.rotary_columns)].copy()
    k1 = machine.rotary[0].direction
    vmax = machine.rotary[0].velocity
    if not np.isfinite(vmax):
        return _plain(problem, tp, sel, spans)
    length = np.linalg.norm(np.diff(tp.tip, axis=0), axis=1)
    feed = np.nan_to_num(tp.feed[1:], nan=np.inf) / 60.0  # mm/s
    with np.errstate(divide="ignore", invalid="ignore"):
        dt = np.where(feed > 0, length / feed, 0.0)
    step_max = 0.95 * vmax * dt
    sin_phi = np.sqrt(np.clip(1.0 - (tp.axis @ k1) ** 2, 0.0, None))
    changed = False
    for s, e in feed_runs(tp):
        exact = rot[s : e + 1, 0].copy()
        if np.all(np.abs(np.diff(exact)) <= step_max[s:e] + 1e-12) or sel.rewind[s : e + 1].any():
            continue
        scale = np.ones(e - s + 1)
        for _ in range(4):
            ratio = np.sin(problem.angle_tolerance) * scale / np.maximum(sin_phi[s : e + 1], 1e-12)
            half = np.where(ratio >= 1.0, np.pi, np.arcsin(np.clip(ratio, 0.0, 1.0)))
            half[[0, -1]] = 0.0  # the run's ends stay exact
            theta = _tube(exact, half, step_max[s:e])
            t2 = best_tilt(machine, tp.axis[s : e + 1], theta, rot[s : e + 1, 1])
            cand = np.stack([theta, t2], axis=1)
            dev = angle_between(tool_axis_of(machine, cand), tp.axis[s : e + 1])
            over = dev > problem.angle_tolerance * (1 + 1e-9)
            if not over.any():
                break
            scale = np.where(over, scale * 0.5, scale)
        lo2, hi2 = machine.rotary[1].lower, machine.rotary[1].upper
        cand[:, 1] = np.clip(cand[:, 1], lo2, hi2)
        if np.abs(cand - rot[s : e + 1]).max() > 1e-12:
            changed = True
        rot[s : e + 1] = cand
    if not changed:
        return _plain(problem, tp, sel, spans)
    # rows are the CL points, with a turn in place where a row stands on the pole
    q = sel.q.copy()
    q[:, list(machine.rotary_columns)] = rot
    param, rot = _turn_at_poles(machine, replace(sel, q=q), tp)

    turns = param[1:][param[1:] == param[:-1]]

    def curve(x: np.ndarray) -> np.ndarray:
        t1 = np.interp(x, param, rot[:, 0])
        ref = np.interp(x, param, rot[:, 1])
        _, ax = at_param(tp, x, 0.0)
        t2 = np.clip(
            best_tilt(machine, ax, t1, ref), machine.rotary[1].lower, machine.rotary[1].upper
        )
        out = np.stack([t1, t2], axis=1)
        # a turn in place on the pole: exact solution (the first angle between the two rows)
        out[np.isin(x, turns)] = np.nan
        return out

    return Plan(
        toolpath=tp,
        param=param,
        rotary=rot,
        lift=np.zeros(len(param)),
        curve=curve,
        spans=spans,
        bent=True,
        notes=list(sel.notes),
        settled=sel.settled,
    )


def _rounding(a: np.ndarray, b: np.ndarray, step: np.ndarray) -> float:
    """Rounding of the running sums over two bands ``a``, ``b`` and the steps ``step`` (rad):
    intervals closed by no more than this are one value."""
    scale = float(np.abs(a).max(initial=0.0)) + float(np.abs(b).max(initial=0.0))
    return 16.0 * float(np.spacing(scale + float(np.abs(step).sum())))


def _reachable(
    lo: np.ndarray, hi: np.ndarray, step: np.ndarray, stop: bool = False
) -> tuple[np.ndarray, np.ndarray, bool]:
    """Forward pass: the interval reachable at each point within the band and step limits.

    ``r_lo[i] = max(lo[i], r_lo[i-1] - step[i-1])`` (and ``r_hi`` alike) is, unrolled,
    ``max over j <= i of lo[j] - (steps from j to i)``: a running maximum of ``lo`` plus the
    cumulative steps, less those. Where the interval closes (no value is reachable), it is
    restarted from the middle of the previous one, clipped to the band, and ``ok`` is False;
    intervals closed by no more than the rounding of the cumulative sums count as one value.

    Parameters
    ----------
    lo, hi : ndarray, shape (n,), rad
    step : ndarray, shape (n - 1,), rad
    stop : bool
        Return at the first closed interval (only ``ok`` is wanted); the intervals after it
        are then not computed.

    Returns
    -------
    r_lo, r_hi : ndarray, shape (n,)
    ok : bool
    """
    n = len(lo)
    r_lo, r_hi = lo.copy(), hi.copy()
    ok = True
    s = 0
    while s < n - 1:
        cum = np.concatenate([[0.0], np.cumsum(step[s:])])
        own_lo = np.concatenate([[r_lo[s]], lo[s + 1 :]])
        own_hi = np.concatenate([[r_hi[s]], hi[s + 1 :]])
        a, b = own_lo + cum, own_hi - cum
        run_lo, run_hi = np.maximum.accumulate(a), np.minimum.accumulate(b)
        # where the band itself bounds the interval, its own value (no rounding of the sums)
        a = np.where(run_lo == a, own_lo, run_lo - cum)
        b = np.where(run_hi == b, own_hi, run_hi + cum)
        eps = _rounding(lo[s:], hi[s:], step[s:])
        closed = np.flatnonzero(a > b + eps)
        f = int(closed[0]) if closed.size else len(a)
        tight = np.flatnonzero(a[:f] > b[:f])
        a[tight] = b[tight] = 0.5 * (a[tight] + b[tight])
        r_lo[s + 1 : s + f], r_hi[s + 1 : s + f] = a[1:f], b[1:f]
        if not closed.size:
            break
        ok = False
        i = s + f
        if stop:
            break
        mid = float(np.clip(0.5 * (r_lo[i - 1] + r_hi[i - 1]), lo[i], hi[i]))
        r_lo[i] = r_hi[i] = mid
        s = i
    return r_lo, r_hi, ok


def _tube(exact: np.ndarray, half: np.ndarray, step: np.ndarray) -> np.ndarray:
    """A rate-limited sequence within ``exact +- half``, as close to ``exact`` as it can be.

    Forward pass: the interval of values reachable at each point from the start within the
    band and the step limits; backward pass: the value nearest the exact one that still reaches
    the next chosen value. Where the band leaves no room for the step limits, they are raised
    by the smallest common factor that makes the band feasible (found by bisection), so the
    peak rate is as low as the band allows.

    The backward pass is sequential only where it must be: from a point that takes its exact
    value, the one before does too wherever its exact value is reachable and within a step of
    the next exact value, so those stretches are filled at once.

    Parameters
    ----------
    exact, half : ndarray, shape (n,), rad
    step : ndarray, shape (n - 1,), rad
        Largest allowed change between neighbours.

    Returns
    -------
    ndarray, shape (n,)
    """
    lo, hi = exact - half, exact + half
    r_lo, r_hi, ok = _reachable(lo, hi, step, stop=True)
    if not ok:
        with np.errstate(divide="ignore", invalid="ignore"):
            need = np.abs(np.diff(exact)) / step
        k_lo, k_hi = 1.0, float(np.nanmax(np.where(np.isfinite(need), need, 1.0), initial=1.0))
        k_hi = max(k_hi, 1.0) * (1 + 1e-9)
        for _ in range(40):
            k = np.sqrt(k_lo * k_hi)
            if _reachable(lo, hi, step * k, stop=True)[2]:
                k_hi = k
            else:
                k_lo = k
            if k_hi / k_lo < 1.001:
                break
        step = step * k_hi
        r_lo, r_hi, _ = _reachable(lo, hi, step)
    n = len(exact)
    out = np.empty(n)
    out[-1] = np.clip(exact[-1], r_lo[-1], r_hi[-1])
    if n == 1:
        return out
    # where the next point is exact, this one is exact too unless ``easy`` fails
    e0, e1 = exact[:-1], exact[1:]
    easy = (np.maximum(r_lo[:-1], e1 - step) <= e0) & (e0 <= np.minimum(r_hi[:-1], e1 + step))
    hard = np.flatnonzero(~easy)
    eps = _rounding(exact, half, step)
    i = n - 2
    while i >= 0:
        nxt = float(out[i + 1])
        if nxt == exact[i + 1] and easy[i]:
            # exact back to the last point where that may fail
            k = int(np.searchsorted(hard, i)) - 1
            j = int(hard[k]) if k >= 0 else -1
            out[j + 1 : i + 1] = exact[j + 1 : i + 1]
            i = j
            continue
        a = max(float(r_lo[i]), nxt - float(step[i]))
        b = min(float(r_hi[i]), nxt + float(step[i]))
        e = float(exact[i])
        if a <= b:
            out[i] = min(max(e, a), b)
        elif a <= b + eps:  # one value, closed by rounding
            out[i] = 0.5 * (a + b)
        else:
            out[i] = min(max(e, float(r_lo[i])), float(r_hi[i]))
        i -= 1
    return out


Strategy = Callable[[Problem], Plan]

STRATEGIES: dict[str, Strategy] = {
    "none": strategy_none,
    "recursive": strategy_recursive,
    "branch-flip": strategy_branch_flip,
    "linear": strategy_linear,
    "spline": strategy_spline,
    "cone": strategy_cone,
}

DEFAULT_STRATEGY = "cone"


def realise(problem: Problem, plan: Plan) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Joint vectors of a plan's rows, with X, Y, Z solved from the rotary angles.

    Returns
    -------
    q : ndarray, shape (N, m)
    tip : ndarray, shape (N, 3), mm
        Where the tip is (the cutting point minus the pivot along the tool axis, plus the lift).
    axis : ndarray, shape (N, 3)
        The tool axis the rows point along.
    """
    bent = np.zeros(len(plan.param), dtype=bool)
    if plan.curve is not None:
        bent = np.isfinite(plan.curve(plan.param)).all(axis=1)
    return solve_rows(problem, plan.toolpath, plan.param, plan.rotary, plan.lift, bent=bent)


def solve_rows(
    problem: Problem,
    toolpath: Toolpath,
    param: np.ndarray,
    rotary: np.ndarray,
    lift: np.ndarray,
    bent: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Joint vectors for rotary angles at positions along the CL path (see :func:`realise`).

    Rows marked ``bent`` keep the cutting point (pivot) on the CL path, the others the tip
    (default: all rows keep the cutting point; at a CL point with the programmed axis the two
    are the same).
    """
    machine = problem.machine
    pivot = problem.pivot if bent is None else np.where(bent, problem.pivot, 0.0)
    where = _on_segments(toolpath, param)
    point = _cutting_point(toolpath, *where, 0.0)
    centre = _cutting_point(toolpath, *where, problem.pivot)
    axis = tool_axis_of(machine, rotary)
    pv = np.broadcast_to(pivot, (len(param),))[:, None]
    tip = np.where(pv > 0, centre - pv * axis, point) + lift[:, None] * axis
    lin = solve_linear(machine, rotary, tip, problem.tool_length)
    return assemble(machine, rotary, lin), tip, axis


def midpoint_solver(
    problem: Problem, plan: Plan
) -> Callable[[np.ndarray, np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Midpoints for the generic subdivision along the plan's curve (or exact elsewhere).

    Returns
    -------
    callable
        ``solve(param (k,), qa (k, m), qb (k, m)) -> (q, tip, axis)``.
    """
    machine, tol = problem.machine, problem.tol
    cols = list(machine.rotary_columns)
    lift_param, lift_value = plan.param, plan.lift

    def solve(param: np.ndarray, qa: np.ndarray, qb: np.ndarray):
        guess = 0.5 * (qa[:, cols] + qb[:, cols])
        rot = np.full_like(guess, np.nan)
        if plan.curve is not None:
            rot = plan.curve(param)
        exact = np.isnan(rot).any(axis=1)
        if exact.any():
            _, ax = at_param(plan.toolpath, param[exact], 0.0)
            rot[exact] = nearest_solution(machine, ax, guess[exact], tol)
        lift = (
            np.interp(param, lift_param, lift_value) if lift_value.any() else np.zeros(len(param))
        )
        return solve_rows(problem, plan.toolpath, param, rot, lift, bent=~exact)

    return solve
