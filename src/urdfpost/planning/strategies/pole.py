"""Strategies that keep the exact inverse kinematics and handle the pole.

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
"""

from __future__ import annotations

import logging
from dataclasses import replace

import numpy as np

from urdfpost.geometry import angle_between
from urdfpost.planning.problem import Plan, Problem, exact_selection
from urdfpost.planning.singularity import feed_runs
from urdfpost.planning.strategies._common import (
    _plain,
    _spans,
    _with_arrivals,
    exact_split,
    split_at_pole_crossings,
)
from urdfpost.planning.strategies._registry import strategy
from urdfpost.toolpath import Toolpath

log = logging.getLogger(__name__)


@strategy("none", rank=10)
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


@strategy("recursive", rank=20)
def strategy_recursive(problem: Problem) -> Plan:
    """Exact inverse kinematics, exact pole crossings, bisection by the generic subdivision."""
    tp = split_at_pole_crossings(problem.toolpath, problem.machine, problem.tol.pole_crossing)
    tp, sel = exact_split(problem, tp)
    return _plain(problem, tp, sel, _spans(problem, tp, sel))


@strategy("branch-flip", rank=30)
def strategy_branch_flip(problem: Problem) -> Plan:
    """Pass through the pole: bend near misses onto it, flip the tilt or turn in place there."""
    machine = problem.machine
    if len(machine.rotary) < 2:
        return strategy_recursive(problem)
    base = split_at_pole_crossings(problem.toolpath, machine, problem.tol.pole_crossing)
    base, base_sel = exact_split(problem, base)
    spans = _spans(problem, base, base_sel)
    bent_tp = _bend_through_pole(problem, problem.toolpath)
    tp = split_at_pole_crossings(
        bent_tp, machine, problem.angle_tolerance, snap_points=True, pivot=problem.pivot
    )
    bent = tp is not problem.toolpath and (
        len(tp) != len(problem.toolpath) or not np.array_equal(tp.axis, problem.toolpath.axis)
    )
    tp, sel = exact_split(problem, tp)
    plan = _plain(problem, tp, sel, spans)
    if not bent:
        return plan
    # bending pays only where the travel lets the tilt change sign: otherwise the first axis
    # turns half a turn in place on the pole, more than the exact path turns
    exact = _plain(problem, base, base_sel, spans)
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
