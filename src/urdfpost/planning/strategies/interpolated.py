"""Strategies that run the first rotary angle along a curve across each singular span.

``linear``
    Sørby-type: inside each singular span the first rotary angle runs linearly (in path length)
    from its exact value at the span's entry to its value at the exit; the tilt is the one
    closest to the programmed orientation for that angle.
``spline``
    Source A: a cubic Hermite curve of the first rotary angle across each span, with end
    tangents from the neighbouring blocks so its rate has no step; rows inserted every
    ``Tolerances.spline_step`` of rotary motion; the tilt as for ``linear``; optional lift
    along the tool axis inside the span (``Problem.lift``, off by default).

Both keep every orientation within the angle tolerance: a row that would deviate more becomes
an anchor with exact inverse kinematics, splitting its span.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable

import numpy as np

from urdfpost.geometry import angle_between
from urdfpost.planning.problem import (
    Plan,
    Problem,
    arc_length,
    at_param,
    tool_axis_of,
)
from urdfpost.planning.strategies._common import (
    _plain,
    _spans,
    _turn_at_poles,
    best_tilt,
    exact_split,
    rows_on_points,
    split_at_pole_crossings,
)
from urdfpost.planning.strategies._registry import strategy
from urdfpost.toolpath import Toolpath


@strategy("linear", rank=40)
def strategy_linear(problem: Problem) -> Plan:
    """Sørby-type: first rotary angle linear across each span, closest tilt."""
    return _interpolated(problem, "linear")


@strategy("spline", rank=50)
def strategy_spline(problem: Problem) -> Plan:
    """Source A: cubic Hermite first rotary angle across each span, closest tilt, optional lift."""
    return _interpolated(problem, "spline")


def _interpolated(problem: Problem, shape: str) -> Plan:
    """``linear`` and ``spline``: the first rotary angle along a curve across each span."""
    machine = problem.machine
    tp = split_at_pole_crossings(problem.toolpath, machine, problem.tol.pole_crossing)
    tp, sel = exact_split(problem, tp)
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

    plan = Plan(
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
    # the rows the spline inserts along a segment become points of the toolpath
    return rows_on_points(plan, problem.pivot)


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
