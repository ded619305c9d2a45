"""Where a path comes near a singular configuration.

The orientation Jacobian ``J_v`` maps rotary-axis rates to the rate of the tool-axis vector in
the workpiece frame (3 x r). Near a pole (tool axis along the first rotary axis) or at the edge
of a nutating machine's tilt range its smallest singular value goes to zero and the inverse
kinematics asks for unbounded rotary speed. The detector marks the CL points whose conditioning
is below ``Tolerances.singular_sigma`` and the steps whose rotary swing exceeds
``Tolerances.swing_limit``, joins them into spans, widens each by ``Tolerances.singular_margin``
points within its feed run, and reports every span.
"""

from __future__ import annotations

import logging
from dataclasses import asdict, dataclass

import numpy as np

from urdfpost.kinematics.forward import (
    ROWS,
    PoeChain,
    axis_and_joint_directions,
    chain_of,
    row_chunks,
)
from urdfpost.machine import Machine
from urdfpost.tolerances import Tolerances
from urdfpost.toolpath import Motion, Toolpath

log = logging.getLogger(__name__)


def orientation_jacobian(machine: Machine | PoeChain, q: np.ndarray) -> np.ndarray:
    """Jacobian of the tool-axis vector with respect to the rotary joints (vectorised).

    Column j is ``omega_j(q) x v``, where ``omega_j`` is the direction of rotary joint j in the
    workpiece frame at configuration ``q`` (signed so that a positive joint value turns the
    tool positively relative to the workpiece) and ``v`` the tool axis. The tests hold it to
    Pinocchio's Jacobian (``jacobian_pin`` in ``tests/oracles.py``).

    Parameters
    ----------
    machine : Machine or PoeChain
    q : ndarray, shape (n, m) or (m,), mm / rad

    Returns
    -------
    ndarray, shape (n, 3, r)
        Columns in :attr:`Machine.rotary` (chain) order, per radian.
    """
    chain = chain_of(machine)
    q = np.asarray(q, dtype=float).reshape(-1, chain.n_axes)
    out = np.empty((q.shape[0], 3, len(chain.rotary_columns)))
    for part in row_chunks(q.shape[0]):
        _jacobian_into(out[part], chain, q[part])
    return out


def _jacobian_into(out: np.ndarray, chain: PoeChain, q: np.ndarray) -> np.ndarray:
    """:func:`orientation_jacobian` of a few thousand rows ``q`` into ``out`` (k, 3, r); returns
    the tool axis (k, 3)."""
    v, directions = axis_and_joint_directions(chain, q)
    v0, v1, v2 = v[:, 0], v[:, 1], v[:, 2]
    for j, w in enumerate(directions):  # cross(w, v), the same products and differences
        w0, w1, w2 = w[:, 0], w[:, 1], w[:, 2]
        for i, (a, b, c, d) in enumerate(((w1, v2, w2, v1), (w2, v0, w0, v2), (w0, v1, w1, v0))):
            col = out[:, i, j]
            np.multiply(a, b, out=col)
            col -= c * d
    return v


def _conditioning_of(j: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Smallest singular value and condition number of Jacobians ``j`` (n, 3, r)."""
    if j.shape[2] == 2:
        # two columns: s1^2 + s2^2 is the sum of their squared lengths and s1 s2 the area of
        # the parallelogram they span (which keeps its precision where s2 is tiny)
        total = np.einsum("nij,nij->n", j, j)
        (a0, b0), (a1, b1), (a2, b2) = ((j[:, i, 0], j[:, i, 1]) for i in range(3))
        # the length of their cross product, by the same operations as
        # np.linalg.norm(cross(a, b), axis=1) without its reduction over rows of three
        c0, c1, c2 = a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0
        area = np.sqrt(c0 * c0 + c1 * c1 + c2 * c2)
        smax = np.sqrt(0.5 * (total + np.sqrt(np.maximum(total**2 - 4.0 * area**2, 0.0))))
        with np.errstate(divide="ignore", invalid="ignore"):
            smin = np.where(smax > 0, area / np.where(smax > 0, smax, 1.0), 0.0)
    else:
        s = np.linalg.svd(j, compute_uv=False)  # (n, r), descending
        smin, smax = s[:, -1], s[:, 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        kappa = np.where(smin > 0, smax / np.where(smin > 0, smin, 1.0), np.inf)
    return smin, kappa


def _conditioning_and_axis(
    machine: Machine | PoeChain, q: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`conditioning` and the tool axis (n, 3), a few thousand rows at a time (the
    Jacobians of one chunk stay in the CPU cache and are not kept)."""
    chain = chain_of(machine)
    q = np.asarray(q, dtype=float).reshape(-1, chain.n_axes)
    n = q.shape[0]
    sigma, kappa, axis = np.empty(n), np.empty(n), np.empty((n, 3))
    size = max(1, min(n, ROWS))
    j = np.empty((size, 3, len(chain.rotary_columns)))
    for part in row_chunks(n, size):
        k = part.stop - part.start
        axis[part] = _jacobian_into(j[:k], chain, q[part])
        sigma[part], kappa[part] = _conditioning_of(j[:k])
    return sigma, kappa, axis


def conditioning(machine: Machine | PoeChain, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Smallest singular value and condition number of the orientation Jacobian.

    For a machine with one rotary axis the Jacobian is a single column; its norm is both the
    smallest and largest singular value (condition number 1 where it is non-zero).

    Parameters
    ----------
    machine : Machine or PoeChain
    q : ndarray, shape (n, m) or (m,), mm / rad

    Returns
    -------
    sigma_min : ndarray, shape (n,)
        Rad/s of tool-axis motion per rad/s of joint motion in the worst direction; for an
        orthogonal two-axis machine it is the sine of the angle between the tool axis and the
        first rotary axis.
    kappa : ndarray, shape (n,)
        sigma_max / sigma_min (``inf`` at a singular point).
    """
    sigma, kappa, _ = _conditioning_and_axis(machine, q)
    return sigma, kappa


@dataclass(frozen=True)
class Span:
    """A singular span of a path: contiguous CL points a strategy may repair.

    Attributes
    ----------
    first, last : int
        Indices of its first and last CL point (inclusive, margin included); the strategies
        keep the exact inverse kinematics at both.
    first_line, last_line : int
        Their CL source lines.
    kind : str
        "pole" (tool axis near the first rotary axis), "edge" (near the limit of the reachable
        tilt, where two branches merge) or "swing" (large rotary steps at fine conditioning).
    min_sigma : float
        Smallest singular value of the orientation Jacobian at its points.
    max_kappa : float
        Largest condition number at its points.
    swing_deg : float
        Total motion of the first rotary axis across the span with the exact inverse
        kinematics, degrees.
    max_step_deg : float
        Largest step of any rotary axis between neighbouring points in the span, degrees.
    """

    first: int
    last: int
    first_line: int
    last_line: int
    kind: str
    min_sigma: float
    max_kappa: float
    swing_deg: float
    max_step_deg: float

    def as_dict(self) -> dict:
        """Plain data for JSON reports."""
        return asdict(self)


def joined_runs(joined: np.ndarray) -> list[tuple[int, int]]:
    """Maximal runs [s, e] (e > s) of points each joined to the one before it.

    ``joined[i]`` says point i continues the run of point i - 1 (``joined[0]`` is not read).

    Examples
    --------
    >>> joined_runs(np.array([True, True, True, False, True, False, False]))
    [(0, 2), (3, 4)]
    """
    links = np.zeros(max(len(joined) + 1, 2), dtype=np.int8)  # links[i]: i joined to i - 1
    links[1:-1] = np.asarray(joined, dtype=bool)[1:]
    change = np.diff(links)
    starts = np.flatnonzero(change == 1)  # the first link of a run joins its start to the next
    ends = np.flatnonzero(change == -1)
    return [(int(a), int(b)) for a, b in zip(starts, ends, strict=True)]


def feed_runs(toolpath: Toolpath) -> list[tuple[int, int]]:
    """Maximal runs [s, e] of CL points joined by feed moves of one cut (e > s).

    Point i belongs to the run of point i - 1 when it is reached by a feed move and no tool
    change happens at it.
    """
    n = len(toolpath)
    joined = toolpath.motion == Motion.FEED
    for e in toolpath.events:
        if e.kind == "tool" and e.index < n:
            joined[e.index] = False
    return joined_runs(joined)


def detect(
    machine: Machine,
    toolpath: Toolpath,
    q: np.ndarray,
    tol: Tolerances | None = None,
    runs: list[tuple[int, int]] | None = None,
) -> list[Span]:
    """Singular spans of a path, from its exact inverse kinematics.

    Parameters
    ----------
    machine : Machine
    toolpath : Toolpath
    q : ndarray, shape (n, m), mm / rad
        The exact solution chosen at every CL point (rotary angles unwrapped along the path).
    tol : Tolerances, optional
        ``singular_sigma``, ``swing_limit`` and ``singular_margin`` are used.
    runs : list of (int, int), optional
        Feed runs (default :func:`feed_runs`); spans never leave their run.

    Returns
    -------
    list of Span
        In path order, not overlapping.
    """
    tol = tol or Tolerances()
    n = len(toolpath)
    if n == 0 or not machine.rotary:
        return []
    runs = feed_runs(toolpath) if runs is None else runs
    sigma, kappa, v = _conditioning_and_axis(machine, q)
    rot_cols = list(machine.rotary_columns)
    # cosine of the angle between the tool axis and the first rotary axis, of the whole path
    # at once (the last bits of a matrix product can depend on how its rows are split); the
    # rest is element-wise, worked out per run and per span
    along_k1 = v @ machine.rotary[0].direction
    spans: list[Span] = []
    for s, e in runs:
        low = sigma[s : e + 1] < tol.singular_sigma
        swing = np.zeros(e - s + 1, dtype=bool)
        big = np.zeros(e - s, dtype=bool)  # a rotary step into the point after
        for c in rot_cols:
            big |= np.abs(np.diff(q[s : e + 1, c])) > tol.swing_limit
        swing[1:] |= big
        swing[:-1] |= big
        mark = low | swing
        if not mark.any():
            continue
        # contiguous marked runs, widened by the margin, merged where they touch
        idx = np.flatnonzero(mark) + s
        breaks = np.flatnonzero(np.diff(idx) > 1)
        starts = np.concatenate([[idx[0]], idx[breaks + 1]])
        ends = np.concatenate([idx[breaks], [idx[-1]]])
        merged: list[list[int]] = []
        for a, b in zip(starts, ends, strict=True):
            a = max(s, int(a) - tol.singular_margin)
            b = min(e, int(b) + tol.singular_margin)
            if merged and a <= merged[-1][1]:
                merged[-1][1] = max(merged[-1][1], b)
            else:
                merged.append([a, b])
        for a, b in merged:
            sl = slice(a, b + 1)
            step = np.zeros((b - a + 1, len(rot_cols)))  # rotary steps into each point
            step[1:] = np.abs(np.diff(q[sl][:, rot_cols], axis=0))
            if (sigma[sl] < tol.singular_sigma).any():
                sin_k1 = np.sqrt(np.clip(1.0 - along_k1[sl] ** 2, 0.0, None))
                kind = "pole" if (sin_k1 < tol.singular_sigma).any() else "edge"
            else:
                kind = "swing"
            spans.append(
                Span(
                    first=a,
                    last=b,
                    first_line=int(toolpath.line[a]),
                    last_line=int(toolpath.line[b]),
                    kind=kind,
                    min_sigma=float(sigma[sl].min()),
                    max_kappa=float(kappa[sl].max()),
                    swing_deg=float(np.degrees(step[1:, 0].sum())),
                    max_step_deg=float(np.degrees(step[1:].max(initial=0.0))),
                )
            )
    log.debug("%d singular spans", len(spans))
    return spans
