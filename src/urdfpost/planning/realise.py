"""Realising a plan: joint vectors from a strategy's rotary angles.

A :class:`~urdfpost.planning.problem.Plan` holds rotary angles only; here X, Y, Z are solved
from them so that the cutting point (or the tip) lies on the CL path at every row
(:func:`realise`, :func:`solve_rows`), and the generic subdivision gets its midpoints along the
plan's curve, or from exact inverse kinematics where the plan has none
(:func:`midpoint_solver`). The rows of the plan's rewinds (lift, turn, return) are inserted by
:func:`with_rewinds`.
"""

from __future__ import annotations

import logging
from collections.abc import Callable

import numpy as np

from urdfpost.geometry import angle_between
from urdfpost.kinematics.inverse import assemble, nearest_solution, solve_linear
from urdfpost.machine import Machine
from urdfpost.planning.problem import (
    Plan,
    Problem,
    _cutting_point,
    _on_segments,
    at_param,
    curve_defined,
    tool_axis_of,
)
from urdfpost.planning.rewinds import LIFT, RETURN, TURN, rewind_rows
from urdfpost.tolerances import Tolerances
from urdfpost.toolpath import Toolpath

log = logging.getLogger(__name__)


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
        bent = curve_defined(plan.curve, plan.param)
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
    i, j, t = _on_segments(toolpath, param)
    axis = tool_axis_of(machine, rotary)
    pv = np.broadcast_to(pivot, (len(param),))
    # the tip where the cutting point is, or the cutting point above it along the tool axis
    # (pv > 0): each worked out in the rows that take it (the larger share whole, the other
    # rows after), row by row the same numbers
    pivoted = pv > 0
    most = 2 * np.count_nonzero(pivoted) > len(pv)
    if most:
        tip = _cutting_point(toolpath, i, j, t, problem.pivot)
        tip -= pv[:, None] * axis
    else:
        tip = _cutting_point(toolpath, i, j, t, 0.0)
    rows = np.flatnonzero(~pivoted if most else pivoted)
    if rows.size:
        at = (i[rows], j[rows], t[rows])
        if most:
            tip[rows] = _cutting_point(toolpath, *at, 0.0)
        else:
            tip[rows] = _cutting_point(toolpath, *at, problem.pivot) - pv[rows, None] * axis[rows]
    tip += lift[:, None] * axis
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
            rot[exact] = _exact_or_across(machine, ax, qa[exact][:, cols], qb[exact][:, cols], tol)
        lift = (
            np.interp(param, lift_param, lift_value) if lift_value.any() else np.zeros(len(param))
        )
        return solve_rows(problem, plan.toolpath, param, rot, lift, bent=~exact)

    return solve


NO_PROGRESS = 0.25
"""A bisected block whose exact midpoint leaves a half at least ``1 - NO_PROGRESS`` of the
block's rotary step long (the midpoint near an end, or beyond one) makes no progress there: it
may join two branches (:func:`_exact_or_across`)."""


def _exact_or_across(
    machine: Machine, axis: np.ndarray, rot_a: np.ndarray, rot_b: np.ndarray, tol: Tolerances
) -> np.ndarray:
    """Rotary angles of the midpoints of blocks: exact, or across a branch switch.

    A block whose ends lie on two inverse kinematics branches (near a pole the planner may
    switch there: the first rotary axis turns by about half a turn and the tilt changes sign
    while the tool axis hardly moves) has no exact solution between them: the exact midpoint
    is one of its ends again (or beyond one), and bisecting never shortens the joint move,
    which then carries the tool tip off the path. Where the exact midpoint leaves a half
    nearly as long as the block (:data:`NO_PROGRESS`), the midpoint is the middle of the joint
    move itself (its X, Y, Z are solved to keep the tip on the path like any row), provided its
    tool axis stays within the orientation tolerance of the programmed one (the tolerance
    :func:`with_rewinds` lifts a turn beyond); the tilt then runs through the pole by the
    distance the path misses it.

    Parameters
    ----------
    machine : Machine
    axis : ndarray, shape (k, 3)
        Programmed tool axes at the midpoints.
    rot_a, rot_b : ndarray, shape (k, r), rad
        Rotary angles at the block ends.
    tol : Tolerances

    Returns
    -------
    ndarray, shape (k, r), rad
    """
    guess = 0.5 * (rot_a + rot_b)
    rot = nearest_solution(machine, axis, guess, tol)
    step = np.abs(rot_b - rot_a).max(axis=1, initial=0.0)
    longer = np.maximum(
        np.abs(rot - rot_a).max(axis=1, initial=0.0), np.abs(rot - rot_b).max(axis=1, initial=0.0)
    )
    stuck = (step > tol.orientation) & (longer >= (1.0 - NO_PROGRESS) * step)
    if stuck.any():
        off = angle_between(tool_axis_of(machine, guess[stuck]), axis[stuck])
        across = np.flatnonzero(stuck)[off <= tol.orientation]
        if across.size:
            log.debug("%d midpoints across a branch switch (joint-space middle)", across.size)
            rot[across] = guess[across]
    return rot


def with_rewinds(
    problem: Problem, plan: Plan, q: np.ndarray, tip: np.ndarray, axis: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Insert the lift and the turn of every rewind of a plan.

    A rewind is a row at the same position as the row before it whose joint-space turn from
    that row would swing the tool axis (a turn in place at a pole does not): the path arrives
    with one solution and leaves with another of the same pose. Between them the tool lifts
    along its axis by the retract distance, turns there, and comes back.

    Parameters
    ----------
    q : ndarray, shape (N, m)
    tip, axis : ndarray, shape (N, 3)
        The plan's rows as :func:`urdfpost.planning.realise.realise` gives them.

    Returns
    -------
    q, tip, axis, param : ndarray
        With the rows inserted.
    kind : ndarray, shape (N',), int
        ``CUT``, or ``LIFT`` / ``TURN`` / ``RETURN`` for the rows of a rewind.
    """
    machine, param = problem.machine, plan.param
    kind = np.zeros(len(param), dtype=int)
    same = np.flatnonzero(param[1:] == param[:-1]) + 1
    if not same.size:
        return q, tip, axis, param, kind
    rot = plan.rotary
    a, b = rot[same - 1], rot[same]
    end = tool_axis_of(machine, b)
    swing = np.max(
        [angle_between(tool_axis_of(machine, a + t * (b - a)), end) for t in (0.25, 0.5, 0.75)],
        axis=0,
    )
    ks = same[swing > problem.tol.orientation]
    if not ks.size:
        return q, tip, axis, param, kind
    lifted = np.vstack(
        [
            rewind_rows(
                machine, q[k - 1], q[k], tip[k], axis[k], problem.tool_length, problem.retract
            )[:2]
            for k in ks
        ]
    )
    at = np.repeat(ks, 2)
    up = np.repeat(tip[ks] + problem.retract * axis[ks], 2, axis=0)
    kind[ks] = RETURN
    return (
        np.insert(q, at, lifted, axis=0),
        np.insert(tip, at, up, axis=0),
        np.insert(axis, at, np.repeat(axis[ks], 2, axis=0), axis=0),
        np.insert(param, at, param[at]),
        np.insert(kind, at, np.tile([LIFT, TURN], len(ks))),
    )
