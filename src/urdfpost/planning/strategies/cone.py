"""The ``cone`` strategy: the tool axis bent within a cone to keep a rotary axis' rate.

``cone``
    The tool axis moves within a cone of the angle tolerance around the programmed one so that
    the first rotary axis keeps within its velocity limit at the programmed feed: a
    velocity-limited path through the band of angles the cone allows, closest to the exact
    angles (:func:`_tube`). The orientations keep within the angle tolerance: where a
    non-orthogonal machine deviates more than the small-angle formula predicts, the band is
    halved there (up to four times).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from urdfpost.geometry import angle_between
from urdfpost.planning.problem import (
    Plan,
    Problem,
    at_param,
    exact_selection,
    tool_axis_of,
)
from urdfpost.planning.singularity import feed_runs
from urdfpost.planning.strategies._common import (
    _plain,
    _spans,
    _turn_at_poles,
    best_tilt,
    split_at_pole_crossings,
)
from urdfpost.planning.strategies._registry import strategy


@strategy("cone", rank=60)
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
