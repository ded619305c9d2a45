"""The contracts between the planning stages: what a strategy is given and what it returns.

A strategy (:data:`Strategy`) takes a :class:`Problem` (the CL data, the machine and the
limits) and returns a :class:`Plan`: the rotary angles at a sequence of positions along the CL
path, and optionally the joint curve it follows between them. It never returns linear axis
values: the pipeline solves X, Y, Z from the rotary angles so that the cutting point lies on
the CL path at every row (:func:`urdfpost.planning.realise.realise`), and the generic
linearisation then subdivides blocks, taking its midpoints from the strategy's curve, until the
nonlinear error is within tolerance. No strategy mutates its input.

The cutting point is the tool tip, or for a ball-end tool the ball centre (``Problem.pivot`` is
the ball radius): a strategy that bends the tool axis pivots it about that point, so a
ball-end tool machines the same surface.

The helpers here read the CL path the way every stage does (:func:`entry_mask`,
:func:`at_param`, :func:`arc_length`, :func:`tool_axis_of`), and :func:`exact_selection` makes
the exact branch choice with the problem's rules.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from urdfpost.geometry import angle_between, norms, slerp
from urdfpost.kinematics.forward import rotate, row_chunks
from urdfpost.kinematics.inverse import IKResult
from urdfpost.machine import Machine
from urdfpost.planning.branches import Preference, Selection, select
from urdfpost.planning.rewinds import DEFAULT_RETRACT
from urdfpost.planning.singularity import Span
from urdfpost.tolerances import Tolerances
from urdfpost.toolpath import Motion, Toolpath

if TYPE_CHECKING:
    from urdfpost.collision import CollisionWorld


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


def curve_defined(curve: Callable[[np.ndarray], np.ndarray], param: np.ndarray) -> np.ndarray:
    """Where a plan's curve is defined (finite rotary angles) at positions ``param`` (k,),
    shape (k,) bool: the curve's own ``defined(param)`` where it has one (the same answer
    without working out the angles), else the curve evaluated."""
    defined = getattr(curve, "defined", None)
    if defined is not None:
        return np.asarray(defined(param), dtype=bool)
    return np.isfinite(curve(param)).all(axis=1)


Strategy = Callable[[Problem], Plan]
"""What every strategy is: ``strategy(problem) -> plan``; ``problem`` is never mutated."""


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


def exact_selection(
    problem: Problem,
    toolpath: Toolpath,
    planner: str | None = None,
    ik: IKResult | None = None,
) -> Selection:
    """Exact solutions at every point of ``toolpath`` with the problem's branch rules (``ik``:
    the inverse kinematics of its points where the caller has it,
    :func:`urdfpost.planning.branches.select`)."""
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
        ik=ik,
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
    """Tool axis in the workpiece frame for rotary angles (chain order), shape (k, 3).

    Worked out :data:`~urdfpost.kinematics.forward.ROWS` rows at a time, so that the
    temporaries stay in the CPU cache (about half the time of one pass over 100k rows); each
    row is made by element-by-element operations, so it has the bits of one pass over all.
    """
    rot = machine.rotary
    if not rot:
        return np.broadcast_to(machine.home_tool_axis, (len(rotary), 3)).copy()
    out = np.empty((len(rotary), 3))
    for part in row_chunks(len(rotary)):
        # the home axis is the same in every row: the last joint turns it as a constant
        v = rotate(rot[-1].direction, rotary[part, -1], machine.home_tool_axis)
        for j in range(len(rot) - 2, -1, -1):
            v = rotate(rot[j].direction, rotary[part, j], v)
        out[part] = v
    return out


def arc_length(toolpath: Toolpath) -> np.ndarray:
    """Cumulative path measure at each CL point, shape (n,).

    Tip path length in mm plus the tool-axis turn in rad times 1 mm, so a rotation in place
    still advances.
    """
    if len(toolpath) == 0:
        return np.zeros(0)
    d = norms(np.diff(toolpath.tip, axis=0))
    a = angle_between(toolpath.axis[:-1], toolpath.axis[1:])
    return np.concatenate([[0.0], np.cumsum(d + a)])
