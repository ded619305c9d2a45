"""``hold``: the first rotary axis held inside singular spans while the cone allows it.

An example of a urdfpost strategy plug-in: a function ``Problem -> Plan`` declared in the
entry-point group ``urdfpost.strategies`` (``pyproject.toml``). It uses only urdfpost's
public strategy API (``urdfpost.planning.strategies``, ``urdfpost.planning.singularity``).

Inside each singular span the first rotary angle keeps the value of the point before as long
as the tool axis, with the tilt closest to the programmed axis, stays within
``Problem.angle_tolerance`` of it (ModuleWorks' ``FREEZE_ANGLE_AROUND_POLE``); where it would
not, the point takes its exact angle, and holds from there. The span's end points stay exact.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from urdfpost.geometry import angle_between
from urdfpost.kinematics.inverse import IKStatus
from urdfpost.planning.singularity import detect
from urdfpost.planning.strategies import (
    Plan,
    Problem,
    at_param,
    best_tilt,
    exact_plan,
    exact_rows,
    exact_selection,
    split_at_pole_crossings,
    tool_axis_of,
)

__all__ = ["strategy_hold"]


def strategy_hold(problem: Problem) -> Plan:
    """Hold the first rotary axis inside each singular span while the cone allows it."""
    machine, tol = problem.machine, problem.tol
    tp = split_at_pole_crossings(problem.toolpath, machine, tol.pole_crossing)
    sel = exact_selection(problem, tp)
    spans = detect(machine, tp, sel.q, tol)
    if len(machine.rotary) < 2:
        return exact_plan(problem, tp, sel, spans)
    c1, c2 = machine.rotary_columns[0], machine.rotary_columns[1]
    lo2, hi2 = machine.rotary[1].lower, machine.rotary[1].upper
    q, status = sel.q.copy(), sel.status.copy()
    held = np.zeros(len(tp), dtype=bool)
    for sp in spans:
        if sel.rewind[sp.first : sp.last + 1].any():
            continue
        for i in range(sp.first + 1, sp.last):
            axis, theta = tp.axis[i : i + 1], q[i - 1 : i, c1]
            tilt = np.clip(best_tilt(machine, axis, theta, q[i : i + 1, c2]), lo2, hi2)
            rot = np.stack([theta, tilt], axis=1)
            if angle_between(tool_axis_of(machine, rot), axis)[0] <= problem.angle_tolerance:
                q[i, [c1, c2]] = rot[0]
                held[i] = True
                status[i] = IKStatus.OK  # no turn in place: the angle is the held one
    if not held.any():
        return exact_plan(problem, tp, sel, spans)
    param, rotary = exact_rows(problem, tp, replace(sel, q=q, status=status))
    # the joint curve: the first angle linear between rows next to a held point, the tilt
    # closest to the programmed axis; NaN (exact inverse kinematics) elsewhere

    def curve(x: np.ndarray) -> np.ndarray:
        out = np.full((len(x), 2), np.nan)
        i = np.clip(np.floor(x).astype(int), 0, len(tp) - 1)
        j = np.clip(i + 1, 0, len(tp) - 1)
        on = (held[i] | held[j]) & (param.min() <= x)
        if on.any():
            t1 = np.interp(x[on], param, rotary[:, 0])
            ref = np.interp(x[on], param, rotary[:, 1])
            _, axis = at_param(tp, x[on], 0.0)
            out[on] = np.stack([t1, np.clip(best_tilt(machine, axis, t1, ref), lo2, hi2)], axis=1)
        return out

    return Plan(
        toolpath=tp,
        param=param,
        rotary=rotary,
        lift=np.zeros(len(param)),
        curve=curve,
        spans=spans,
        bent=True,
        notes=list(sel.notes),
        settled=sel.settled,
    )


strategy_hold.rank = 900  # type: ignore[attr-defined]  # after urdfpost's own strategies
