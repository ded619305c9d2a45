"""Nonlinear error of joint-space interpolation, and subdivision until it is within tolerance.

Between two blocks a control without tool-centre-point control moves every axis linearly,
``q(t) = q0 + t (q1 - q0)``, so the tool tip leaves the straight CL segment whenever rotary axes
move. With TCP the control keeps the tip on the segment, but the tool axis still follows the
linear interpolation of the rotary axes rather than the CL orientation (slerp). This module
measures both deviations as maxima over each block (samples, then golden-section refinement
around the worst sample; not only the midpoint) and bisects blocks, solving the inserted CL
points on the neighbours' branch, until they are within tolerance.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from urdfpost.kinematics.forward import tip_and_axis
from urdfpost.kinematics.inverse import assemble, solve_linear, solve_rotary
from urdfpost.machine import Machine
from urdfpost.tolerances import Tolerances

log = logging.getLogger(__name__)

_GOLDEN = (np.sqrt(5.0) - 1.0) / 2.0


def slerp(v0: np.ndarray, v1: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Spherical interpolation of unit vectors.

    Parameters
    ----------
    v0, v1 : ndarray, shape (n, 3)
    t : ndarray, shape (n,) or (n, s)

    Returns
    -------
    ndarray, shape (n, 3) or (n, s, 3)
    """
    t = np.asarray(t, dtype=float)
    dot = np.clip(np.sum(v0 * v1, axis=-1), -1.0, 1.0)
    omega = np.arccos(dot)
    if t.ndim == 2:
        v0, v1, omega = v0[:, None, :], v1[:, None, :], omega[:, None]
    small = omega < 1e-9
    so = np.where(small, 1.0, np.sin(omega))
    a = np.where(small, 1.0 - t, np.sin((1.0 - t) * omega) / so)
    b = np.where(small, t, np.sin(t * omega) / so)
    out = a[..., None] * v0 + b[..., None] * v1
    return out / np.linalg.norm(out, axis=-1, keepdims=True)


def angle_between(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Angle between unit vectors along the last axis, rad (robust near 0)."""
    return 2.0 * np.arctan2(np.linalg.norm(u - v, axis=-1), np.linalg.norm(u + v, axis=-1))


def point_segment_distance(
    p: np.ndarray, a: np.ndarray, b: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Distance from points to segments and the parameter of the closest point.

    Parameters
    ----------
    p : ndarray, shape (..., 3)
    a, b : ndarray, shape (..., 3)
        Segment ends, broadcast against ``p``.

    Returns
    -------
    distance : ndarray, shape (...)
    s : ndarray, shape (...)
        In [0, 1].
    """
    d = b - a
    dd = np.sum(d * d, axis=-1)
    s = np.where(dd > 0, np.sum((p - a) * d, axis=-1) / np.where(dd > 0, dd, 1.0), 0.0)
    s = np.clip(s, 0.0, 1.0)
    return np.linalg.norm(p - (a + s[..., None] * d), axis=-1), s


def refine_max(
    f: Callable[[np.ndarray], np.ndarray],
    t: np.ndarray,
    values: np.ndarray,
    iterations: int = 12,
) -> np.ndarray:
    """Maximum of a per-block function of the block parameter, refined around the worst sample.

    Golden-section search on the bracket of one sample spacing either side of each block's
    worst sample (the maximum is not always at a sample, nor at the midpoint).

    Parameters
    ----------
    f : callable
        ``f(t)`` with ``t`` of shape (n,) (one parameter per block) returns shape (n,).
    t : ndarray, shape (n, s)
        Sample parameters in [0, 1], evenly spaced.
    values : ndarray, shape (n, s)
        ``f`` at the samples.
    iterations : int

    Returns
    -------
    ndarray, shape (n,)
        The largest value seen per block.
    """
    n = t.shape[0]
    rows = np.arange(n)
    h = t[0, 1] - t[0, 0] if t.shape[1] > 1 else 0.5
    k = np.argmax(values, axis=1)
    lo = np.clip(t[rows, k] - h, 0.0, 1.0)
    hi = np.clip(t[rows, k] + h, 0.0, 1.0)
    best = values[rows, k]
    for _ in range(iterations):
        a = hi - _GOLDEN * (hi - lo)
        b = lo + _GOLDEN * (hi - lo)
        fa, fb = f(a), f(b)
        best = np.maximum(best, np.maximum(fa, fb))
        left = fa > fb
        hi = np.where(left, b, hi)
        lo = np.where(left, lo, a)
    return best


@dataclass(frozen=True)
class BlockError:
    """Worst deviation within each block.

    Attributes
    ----------
    tip : ndarray, shape (n,), mm
        Maximum distance of the tool tip from the CL segment.
    orientation : ndarray, shape (n,), rad
        Maximum angle between the tool axis and the CL axis (slerp) at the same parameter.
    """

    tip: np.ndarray
    orientation: np.ndarray


def _errors_at(
    machine: Machine,
    q0: np.ndarray,
    q1: np.ndarray,
    p0: np.ndarray,
    p1: np.ndarray,
    v0: np.ndarray,
    v1: np.ndarray,
    t: np.ndarray,
    tool_length: float,
    tcp: bool,
) -> tuple[np.ndarray, np.ndarray]:
    """Tip and orientation errors at parameters ``t`` (n, s) of each block."""
    n, s = t.shape
    q = q0[:, None, :] + t[..., None] * (q1 - q0)[:, None, :]
    tip, ax = tip_and_axis(machine, q.reshape(n * s, -1), tool_length)
    tip, ax = tip.reshape(n, s, 3), ax.reshape(n, s, 3)
    if tcp:
        tip = p0[:, None, :] + t[..., None] * (p1 - p0)[:, None, :]
    dist, _ = point_segment_distance(tip, p0[:, None, :], p1[:, None, :])
    ori = angle_between(ax, slerp(v0, v1, t))
    return dist, ori


def block_errors(
    machine: Machine,
    q: np.ndarray,
    tip: np.ndarray,
    axis: np.ndarray,
    *,
    tool_length: float = 0.0,
    tcp: bool = False,
    tol: Tolerances | None = None,
) -> BlockError:
    """Maximum deviation between consecutive points when the control interpolates the axes.

    Parameters
    ----------
    machine : Machine
    q : ndarray, shape (n, m)
        Joint vectors at the block ends, mm / rad.
    tip : ndarray, shape (n, 3), mm
        CL points the blocks should join with straight segments.
    axis : ndarray, shape (n, 3)
        CL tool axes.
    tool_length : float, mm
    tcp : bool
        The control keeps the tip on the segment (only the orientation can deviate).
    tol : Tolerances, optional

    Returns
    -------
    BlockError
        Arrays of shape (n - 1,).
    """
    tol = tol or Tolerances()
    if q.shape[0] <= 1:
        return BlockError(np.zeros(0), np.zeros(0))
    return _block_errors(
        machine, q[:-1], q[1:], tip[:-1], tip[1:], axis[:-1], axis[1:], tool_length, tcp, tol
    )


def _block_errors(
    machine: Machine,
    q0: np.ndarray,
    q1: np.ndarray,
    p0: np.ndarray,
    p1: np.ndarray,
    v0: np.ndarray,
    v1: np.ndarray,
    tool_length: float,
    tcp: bool,
    tol: Tolerances,
) -> BlockError:
    """Worst deviation of blocks from (q0, p0, v0) to (q1, p1, v1), each of length n."""
    n = q0.shape[0]
    if n == 0:
        return BlockError(np.zeros(0), np.zeros(0))
    s = tol.samples_per_block
    t = np.broadcast_to(np.arange(1, s + 1) / (s + 1), (n, s))
    d, o = _errors_at(machine, q0, q1, p0, p1, v0, v1, t, tool_length, tcp)
    out = []
    for values, pick in ((d, 0), (o, 1)):

        def measure(tt: np.ndarray, pick: int = pick) -> np.ndarray:
            e = _errors_at(machine, q0, q1, p0, p1, v0, v1, tt[:, None], tool_length, tcp)
            return e[pick][:, 0]

        out.append(refine_max(measure, t, values))
    return BlockError(tip=out[0], orientation=out[1])


@dataclass(frozen=True)
class Linearized:
    """A path after subdivision.

    Attributes
    ----------
    q : ndarray, shape (N, m)
    tip : ndarray, shape (N, 3), mm
    axis : ndarray, shape (N, 3)
    source : ndarray, shape (N,), int
        Index of the input point each row is, or -1 for inserted points.
    error : BlockError
        Final deviation of every block, arrays of shape (N - 1,).
    """

    q: np.ndarray
    tip: np.ndarray
    axis: np.ndarray
    source: np.ndarray
    error: BlockError


def nearest_solution(
    machine: Machine, axis: np.ndarray, guess: np.ndarray, tol: Tolerances
) -> np.ndarray:
    """Exact rotary angles for tool axes on the branch and turn nearest a guess.

    Parameters
    ----------
    machine : Machine
    axis : ndarray, shape (k, 3)
    guess : ndarray, shape (k, r), rad
        Rotary angles (chain order) to be near; an undetermined first angle (a pole) takes
        the guess's, and so does an unreachable axis (which a reachable path cannot give).

    Returns
    -------
    ndarray, shape (k, r), rad
    """
    sols = solve_rotary(machine, axis, tol)
    ang = sols.angles.copy()  # (k, 2, r)
    ang[:, :, 0] = np.where(np.isnan(ang[:, :, 0]), guess[:, None, 0], ang[:, :, 0])
    ang = ang + 2 * np.pi * np.round((guess[:, None, :] - ang) / (2 * np.pi))
    dist = np.abs(ang - guess[:, None, :]).sum(axis=2)
    dist = np.where(sols.valid, dist, np.inf)
    br = np.argmin(dist, axis=1)
    rot = ang[np.arange(len(br)), br]
    bad = ~np.isfinite(dist[np.arange(len(br)), br])
    rot[bad] = guess[bad]
    return rot


def _midpoints(
    machine: Machine,
    qa: np.ndarray,
    qb: np.ndarray,
    pa: np.ndarray,
    pb: np.ndarray,
    va: np.ndarray,
    vb: np.ndarray,
    tool_length: float,
    tol: Tolerances,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """CL midpoints of blocks, solved on the branch nearest the neighbours' interpolation."""
    tip = 0.5 * (pa + pb)
    ax = slerp(va, vb, np.full(len(pa), 0.5))
    cols = list(machine.rotary_columns)
    rot = nearest_solution(machine, ax, 0.5 * (qa[:, cols] + qb[:, cols]), tol)
    lin = solve_linear(machine, rot, tip, tool_length)
    return assemble(machine, rot, lin), tip, ax


def _measure(
    machine: Machine,
    q: np.ndarray,
    tip: np.ndarray,
    axis: np.ndarray,
    blocks: np.ndarray | None,
    tool_length: float,
    tcp: bool,
    tol: Tolerances,
) -> tuple[np.ndarray, np.ndarray]:
    """Errors of the given blocks (all when None): block k joins rows k and k + 1."""
    if blocks is None:
        blocks = np.arange(len(q) - 1)
    a, b = blocks, blocks + 1
    e = _block_errors(machine, q[a], q[b], tip[a], tip[b], axis[a], axis[b], tool_length, tcp, tol)
    return e.tip, e.orientation


def subdivide(
    machine: Machine,
    q: np.ndarray,
    tip: np.ndarray,
    axis: np.ndarray,
    *,
    tool_length: float = 0.0,
    tcp: bool = False,
    tol: Tolerances | None = None,
    param: np.ndarray | None = None,
    solve_at: Callable[
        [np.ndarray, np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray]
    ]
    | None = None,
) -> Linearized:
    """Bisect blocks until the tip and orientation deviations are within tolerance.

    The targets are ``tol.tip`` and ``tol.orientation`` times ``tol.interpolation_share`` (the
    rest of each tolerance is kept for the rounding of the written program).
    Blocks are bisected at most ``tol.max_subdivision_depth`` times.

    Parameters
    ----------
    machine : Machine
    q : ndarray, shape (n, m)
        Selected joint vectors of one continuous feed path.
    tip, axis : ndarray, shape (n, 3)
        Its CL points and tool axes.
    tool_length : float, mm
    tcp : bool
    tol : Tolerances, optional
    param : ndarray, shape (n,), optional
        Position of each row along the path (any increasing measure); with ``solve_at``.
    solve_at : callable, optional
        ``solve_at(param (k,), qa (k, m), qb (k, m)) -> (q, tip, axis)``: the row at a position
        between two rows (a strategy's joint curve). Default: the CL midpoint, solved exactly
        on the branch nearest the neighbours' interpolation.

    Returns
    -------
    Linearized
    """
    tol = tol or Tolerances()
    q, tip, axis = np.array(q, dtype=float), np.array(tip, dtype=float), np.array(axis, dtype=float)
    source = np.arange(len(q))
    target_tip = tol.tip * tol.interpolation_share
    target_ori = tol.orientation * tol.interpolation_share
    err_tip, err_ori = _measure(machine, q, tip, axis, None, tool_length, tcp, tol)
    for depth in range(tol.max_subdivision_depth):
        bad = (err_tip > target_tip) | (err_ori > target_ori)
        if not bad.any():
            break
        idx = np.flatnonzero(bad)
        if solve_at is not None and param is not None:
            pmid = 0.5 * (param[idx] + param[idx + 1])
            qm, pm, vm = solve_at(pmid, q[idx], q[idx + 1])
            param = np.insert(param, idx + 1, pmid)
        else:
            qm, pm, vm = _midpoints(
                machine,
                q[idx],
                q[idx + 1],
                tip[idx],
                tip[idx + 1],
                axis[idx],
                axis[idx + 1],
                tool_length,
                tol,
            )
        log.debug("subdivision depth %d: %d blocks bisected", depth + 1, len(idx))
        q = np.insert(q, idx + 1, qm, axis=0)
        tip = np.insert(tip, idx + 1, pm, axis=0)
        axis = np.insert(axis, idx + 1, vm, axis=0)
        source = np.insert(source, idx + 1, -1)
        err_tip = np.insert(err_tip, idx + 1, 0.0)
        err_ori = np.insert(err_ori, idx + 1, 0.0)
        # only the two halves of each bisected block need measuring again
        first = idx + np.arange(len(idx))
        changed = np.concatenate([first, first + 1])
        err_tip[changed], err_ori[changed] = _measure(
            machine, q, tip, axis, changed, tool_length, tcp, tol
        )
    err = BlockError(tip=err_tip, orientation=err_ori)
    return Linearized(q=q, tip=tip, axis=axis, source=source, error=err)
