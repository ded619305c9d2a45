"""The ``optimised`` strategy: the first rotary angle of each span by convex optimisation.

``optimised``
    Inside each singular span (:func:`urdfpost.planning.singularity.detect`, with the job's
    detector) the first rotary angle is chosen by optimisation, in the family of the
    kinematically constrained joint patches (Grandguillaume, Lavernhe and Tournier 2016) and of
    orientation smoothing in a domain of admissible orientations (Castagnetti, Duc and Ray
    2008); ``docs/strategies.md`` has the sources and the comparison with ``cone``:

    1. **The cone as bounds.** For each point the interval of first rotary angles whose tool
       axis, with the tilt closest to the programmed axis (:func:`best_tilt`, clipped to its
       travel), stays within the angle tolerance of the programmed axis, found on the exact
       deviation (:func:`cone_bounds`), so it holds for any machine, nutating ones included.
    2. **Least time** (a linear programme, HiGHS through :func:`scipy.optimize.linprog`):
       variables the angles at the span's inner points and the duration of every step; each
       step lasts at least what the programmed feed gives it, and long enough for the first
       rotary axis at 0.95 of its velocity limit (the margin ``cone`` keeps); the span's end
       points keep their exact angles.
    3. **Least acceleration at that time** (a convex quadratic programme, ``trust-constr``
       through :func:`scipy.optimize.minimize` with its constant Hessian): the sum of squared
       accelerations of the first rotary axis (finite differences over the steps' feed times)
       under the same bounds and rate constraints, with the total time held to the optimum of
       2 (plus 1e-6 of it). The linear programme alone ends at a vertex: a bang-bang rate with
       the slowing in one step.

    The tool tip (the cutting point of a ball-end tool) stays on the CL path exactly: the
    pipeline solves X, Y, Z from the rotary angles (:func:`urdfpost.planning.realise.realise`).
    A span with a rewind in it keeps its exact solution, as does one the solvers fail on (a
    note says so). Between rows the first rotary angle runs linearly and the tilt follows the
    programmed axis, as in ``cone``; outside the spans the rows are the exact solution.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import replace
from typing import TYPE_CHECKING, Final

import numpy as np

from urdfpost.geometry import angle_between
from urdfpost.kinematics.inverse import IKStatus
from urdfpost.machine import Machine
from urdfpost.planning.problem import Plan, Problem, at_param, exact_selection, tool_axis_of
from urdfpost.planning.singularity import step_times
from urdfpost.planning.strategies._common import (
    _plain,
    _spans,
    _turn_at_poles,
    best_tilt,
    split_at_pole_crossings,
)
from urdfpost.planning.strategies._registry import strategy
from urdfpost.toolpath import Toolpath

if TYPE_CHECKING:
    from scipy import sparse

log = logging.getLogger(__name__)

#: Share of the first rotary axis' velocity limit the least-time step keeps to (as ``cone``).
RATE_SHARE: Final = 0.95

#: Spans of more steps than this keep the least-time solution without the acceleration pass:
#: its Hessian and Jacobian are dense (the work grows with the cube of the span's size), the
#: linear programme is sparse.
MAX_SMOOTH_STEPS: Final = 400

#: Bisection steps for the bounds of the cone (pi / 2**40 rad: far below any output rounding).
BISECTIONS: Final = 40

#: Samples of half a turn on each side of the exact first angle, for the first one out of the
#: cone (2.8 degrees apart: a cone of a few degrees around a tilt of more than a degree or two
#: is wider than that; a band narrower than a sample is still found, from the exact angle).
SCAN: Final = 64

#: Times the bounds of the points that leave the cone are halved before a span keeps its exact
#: solution (as ``cone`` does).
HALVINGS: Final = 4


@strategy("optimised", rank=70)
def strategy_optimised(problem: Problem) -> Plan:
    """Least time, then least acceleration, of the first rotary axis across each span."""
    machine, tol = problem.machine, problem.tol
    tp = split_at_pole_crossings(problem.toolpath, machine, tol.pole_crossing)
    sel = exact_selection(problem, tp)
    spans = _spans(problem, tp, sel)
    if len(machine.rotary) < 2 or not spans:
        return _plain(problem, tp, sel, spans)
    cols = list(machine.rotary_columns)
    rot = sel.q[:, cols].copy()
    dt = step_times(tp)
    vmax = RATE_SHARE * machine.rotary[0].velocity
    lo2, hi2 = machine.rotary[1].lower, machine.rotary[1].upper
    notes = list(sel.notes)
    done: list[tuple[int, int]] = []
    for sp in spans:
        a, b = sp.first, sp.last
        if b - a < 2 or sel.rewind[a : b + 1].any():
            continue
        axis, exact = tp.axis[a : b + 1], rot[a : b + 1]
        lo, hi = cone_bounds(machine, axis, exact, problem.angle_tolerance)
        where = f"optimised: CL lines {sp.first_line}-{sp.last_line}"
        for _ in range(HALVINGS + 1):
            theta = smooth_angles(exact[:, 0], lo, hi, dt[a:b], vmax)
            if theta is None:
                notes.append(f"{where}: no solution found; exact inverse kinematics kept")
                break
            t2 = np.clip(best_tilt(machine, axis, theta, exact[:, 1]), lo2, hi2)
            cand = np.stack([theta, t2], axis=1)
            dev = angle_between(tool_axis_of(machine, cand), axis)
            over = dev > problem.angle_tolerance * (1 + 1e-9)
            if not over.any():
                rot[a : b + 1] = cand
                done.append((a, b))
                break
            # the cone is not an interval of the first angle there: a narrower band
            mid = exact[:, 0]
            lo = np.where(over, mid - 0.5 * (mid - lo), lo)
            hi = np.where(over, mid + 0.5 * (hi - mid), hi)
        else:
            notes.append(
                f"{where}: the solution leaves the cone (tool axis {np.degrees(dev.max()):.4f} "
                "deg off); exact inverse kinematics kept"
            )
    if not done:
        return _plain(problem, tp, sel, spans)
    q = sel.q.copy()
    q[:, cols] = rot
    status = sel.status.copy()
    for a, b in done:  # the optimiser chose these angles: no turns in place inside a span
        status[a + 1 : b] = np.where(
            status[a + 1 : b] == IKStatus.POLE, IKStatus.OK, status[a + 1 : b]
        )
    param, rows = _turn_at_poles(machine, replace(sel, q=q, status=status), tp)
    return Plan(
        toolpath=tp,
        param=param,
        rotary=rows,
        lift=np.zeros(len(param)),
        curve=_curve(machine, tp, param, rows, done),
        spans=spans,
        bent=True,
        notes=notes,
        settled=sel.settled,
    )


def _curve(
    machine: Machine,
    tp: Toolpath,
    param: np.ndarray,
    rows: np.ndarray,
    done: list[tuple[int, int]],
) -> Callable[[np.ndarray], np.ndarray]:
    """Joint curve between rows: inside the optimised spans the first angle linear and the tilt
    closest to the programmed axis (clipped to travel); NaN (exact) elsewhere."""
    lo2, hi2 = machine.rotary[1].lower, machine.rotary[1].upper
    first = np.array([a for a, _ in done], dtype=float)
    last = np.array([b for _, b in done], dtype=float)
    turns = param[1:][param[1:] == param[:-1]]

    def curve(x: np.ndarray) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        out = np.full((len(x), 2), np.nan)
        k = np.searchsorted(first, x, side="right") - 1
        inside = (k >= 0) & (x <= last[np.clip(k, 0, None)]) & ~np.isin(x, turns)
        if inside.any():
            xi = x[inside]
            t1 = np.interp(xi, param, rows[:, 0])
            ref = np.interp(xi, param, rows[:, 1])
            _, ax = at_param(tp, xi, 0.0)
            t2 = np.clip(best_tilt(machine, ax, t1, ref), lo2, hi2)
            out[inside] = np.stack([t1, t2], axis=1)
        return out

    return curve


def cone_bounds(
    machine: Machine, axis: np.ndarray, exact: np.ndarray, angle: float
) -> tuple[np.ndarray, np.ndarray]:
    """The first rotary angles whose tool axis keeps within ``angle`` of the programmed one.

    With the tilt closest to the programmed axis for each first angle (clipped to its travel),
    the deviation grows with the distance from the exact first angle up to where the other
    branch comes back. Each side's bound is the first of :data:`SCAN` samples over half a turn
    that leaves the cone, refined by bisection on the exact deviation (:data:`BISECTIONS`
    steps), and clipped to the travel of the first rotary axis; where no sample leaves it (on
    and near the pole) the bound is half a turn.

    Parameters
    ----------
    machine : Machine
    axis : ndarray, shape (k, 3)
        Programmed tool axes.
    exact : ndarray, shape (k, 2), rad
        The exact rotary angles there.
    angle : float, rad

    Returns
    -------
    lo, hi : ndarray, shape (k,), rad
        ``lo <= exact[:, 0] <= hi``.
    """
    lo2, hi2 = machine.rotary[1].lower, machine.rotary[1].upper

    def within(theta: np.ndarray) -> np.ndarray:
        t2 = np.clip(best_tilt(machine, axis, theta, exact[:, 1]), lo2, hi2)
        v = tool_axis_of(machine, np.stack([theta, t2], axis=1))
        return angle_between(v, axis) <= angle

    bounds = []
    grid = np.linspace(0.0, np.pi, SCAN + 1)[1:]
    for sign in (-1.0, 1.0):
        # the first sample out of the cone: the set is not an interval where a second branch
        # (tilt of the other sign, first angle half a turn on) comes back into it
        out = np.stack([~within(exact[:, 0] + sign * g) for g in grid], axis=1)  # (k, SCAN)
        first_out = np.where(out.any(axis=1), out.argmax(axis=1), SCAN)
        good = np.where(first_out > 0, grid[np.maximum(first_out - 1, 0)], 0.0)
        good[first_out == SCAN] = np.pi
        bad = np.where(first_out < SCAN, grid[np.minimum(first_out, SCAN - 1)], np.pi)
        for _ in range(BISECTIONS):
            mid = 0.5 * (good + bad)
            ok = within(exact[:, 0] + sign * mid)
            good, bad = np.where(ok, mid, good), np.where(ok, bad, mid)
        bounds.append(exact[:, 0] + sign * good)
    lo1, hi1 = machine.rotary[0].lower, machine.rotary[0].upper
    lo = np.minimum(np.maximum(bounds[0], lo1), exact[:, 0])
    hi = np.maximum(np.minimum(bounds[1], hi1), exact[:, 0])
    return lo, hi


def smooth_angles(
    exact: np.ndarray, lo: np.ndarray, hi: np.ndarray, dt: np.ndarray, vmax: float
) -> np.ndarray | None:
    """The first rotary angle across a span: least time, then least squared acceleration.

    Parameters
    ----------
    exact : ndarray, shape (k + 1,), rad
        Exact angles; the two ends are kept.
    lo, hi : ndarray, shape (k + 1,), rad
        Bounds of each angle (:func:`cone_bounds`).
    dt : ndarray, shape (k,), s
        Step times at the programmed feed (:func:`~urdfpost.planning.singularity.step_times`);
        NaN (no feed) makes the steps uniform and the rate unbounded.
    vmax : float, rad/s
        Velocity the axis may use (``inf``: no limit, least acceleration only).

    Returns
    -------
    ndarray, shape (k + 1,), rad, or None
        None when a solver fails.
    """
    # scipy's imports (0.7 s) only for the strategy that solves
    from scipy import optimize, sparse

    k = len(exact) - 1
    m = k - 1  # inner points
    if m < 1:
        return exact.copy()
    if not np.isfinite(dt).all():
        dt, vmax = np.ones(k), np.inf
    scale = float(dt[dt > 0].mean()) if (dt > 0).any() else 1.0
    h = np.maximum(dt / scale, 1e-3)  # feed times in mean steps (turns in place count a little)
    x_lo, x_hi = lo[1:-1], hi[1:-1]
    x0 = np.clip(exact[1:-1], x_lo, x_hi)
    # steps: u_j = x_{j+1} - x_j = D x + c, the fixed ends in c
    d = sparse.diags([-np.ones(k), np.ones(k)], [-1, 0], shape=(k, m), format="csr")
    c = np.zeros(k)
    c[0] -= exact[0]
    c[-1] += exact[-1]
    start, timed = x0, None
    if np.isfinite(vmax) and vmax > 0:
        # least time: |D x + c| <= vmax * scale * tau, tau >= the feed time, as two rows of
        # [D, -v I] [x; tau] <= [-c; c]
        v = vmax * scale
        eye = sparse.identity(k, format="csr")
        a_ub = sparse.vstack([sparse.hstack([d, -v * eye]), sparse.hstack([-d, -v * eye])])
        a_ub = sparse.csr_matrix(a_ub)
        b_ub = np.concatenate([-c, c])
        tau_lo = dt / scale
        bounds = list(zip(x_lo, x_hi, strict=True)) + [(t, None) for t in tau_lo]
        cost = np.concatenate([np.zeros(m), np.ones(k)])
        lp = optimize.linprog(cost, A_ub=a_ub, b_ub=b_ub, bounds=bounds, method="highs")
        if lp.status != 0:
            log.debug("optimised: least-time LP failed: %s", lp.message)
            return None
        start = np.concatenate([np.clip(lp.x[:m], x_lo, x_hi), lp.x[m:]])
        timed = (a_ub, b_ub, tau_lo, float(lp.fun))
    if k > MAX_SMOOTH_STEPS:
        return np.concatenate([[exact[0]], start[:m], [exact[-1]]])
    return _least_acceleration(exact, x_lo, x_hi, start, timed, h, d, c)


def _acceleration_operator(
    h: np.ndarray, d: sparse.csr_matrix, c: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """``acc = A x + a0`` at the inner points, with step times ``h`` (k,) in mean steps.

    The step velocities are ``(D x + c) / h``; the acceleration at inner point i is the
    difference of the velocities of its two steps over their mean time.

    Returns
    -------
    A : ndarray, shape (k - 1, m)
    a0 : ndarray, shape (k - 1,)
    """
    k = len(h)
    from scipy import sparse

    vel = sparse.diags(1.0 / h) @ d  # step velocities, (k, m)
    vel0 = c / h
    diff = sparse.diags([-np.ones(k - 1), np.ones(k - 1)], [0, 1], shape=(k - 1, k))
    gap = sparse.diags(2.0 / (h[:-1] + h[1:]))
    return (gap @ diff @ vel).toarray(), gap @ diff @ vel0


def _least_acceleration(
    exact: np.ndarray,
    x_lo: np.ndarray,
    x_hi: np.ndarray,
    start: np.ndarray,
    timed: tuple[sparse.csr_matrix, np.ndarray, np.ndarray, float] | None,
    h: np.ndarray,
    d: sparse.csr_matrix,
    c: np.ndarray,
) -> np.ndarray:
    """Least sum of squared accelerations of the first angle at the least time.

    Variables: the inner angles ``x`` (m) and, with ``timed`` = ``(A_ub, b_ub, tau_lo,
    time)``, the step times ``tau`` (k, in mean feed steps): ``x_lo <= x <= x_hi``,
    ``A_ub [x; tau] <= b_ub`` (the rate), ``tau >= tau_lo`` (the feed) and ``sum(tau) <=
    time`` (the least time, plus 1e-6 of it). A convex quadratic programme, solved by
    ``trust-constr`` with its constant Hessian, from the least-time solution ``start``, which
    is kept when the solver fails or breaks a constraint.
    """
    from scipy import optimize, sparse  # (imported only for the strategy that solves)

    m = len(x_lo)
    acc, acc0 = _acceleration_operator(h, d, c)
    base = float(np.sum((acc @ start[:m] + acc0) ** 2))
    norm = base if base > 1e-12 else 1.0
    n = len(start)
    hess = np.zeros((n, n))
    hess[:m, :m] = 2.0 * acc.T @ acc / norm
    lin = np.zeros(n)
    lin[:m] = 2.0 * acc.T @ acc0 / norm

    def fun(y: np.ndarray) -> float:
        r = acc @ y[:m] + acc0
        return float(r @ r) / norm

    def jac(y: np.ndarray) -> np.ndarray:
        return hess @ y + lin

    lower, upper = x_lo, x_hi
    constraints = []
    if timed is not None:
        a_ub, b_ub, tau_lo, time = timed
        k = len(tau_lo)
        total = sparse.hstack([sparse.csr_matrix((1, m)), sparse.csr_matrix(np.ones((1, k)))])
        constraints = [
            optimize.LinearConstraint(a_ub, -np.inf, b_ub),
            optimize.LinearConstraint(total, -np.inf, time * (1 + 1e-6)),
        ]
        lower = np.concatenate([x_lo, tau_lo])
        upper = np.concatenate([x_hi, np.full(k, np.inf)])
    bounds = optimize.Bounds(lower, upper)

    def feasible(y: np.ndarray) -> bool:
        if timed is None:
            return True
        a_ub, b_ub, _, time = timed
        return bool(np.all(a_ub @ y <= b_ub + 1e-9)) and y[m:].sum() <= time * (1 + 1e-5)

    # trust-constr: robust from the degenerate vertex the linear programme ends at, where
    # SLSQP often stops early (and it is no faster on spans of a hundred points)
    res = optimize.minimize(
        fun,
        start,
        jac=jac,
        hess=lambda y: hess,
        bounds=bounds,
        constraints=constraints,
        method="trust-constr",
        options={"maxiter": 1000, "gtol": 1e-9, "xtol": 1e-11},
    )
    y = np.clip(res.x, lower, upper)
    if not (res.status in (1, 2) and feasible(y) and fun(y) <= fun(start) + 1e-12):
        log.debug("optimised: least-acceleration QP: %s; least-time angles kept", res.message)
        y = start
    x = y[:m]
    return np.concatenate([[exact[0]], x, [exact[-1]]])
