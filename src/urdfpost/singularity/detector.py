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

from urdfpost.kinematics.forward import cross, rotate, tip_and_axis
from urdfpost.machine import Machine
from urdfpost.tolerances import Tolerances
from urdfpost.toolpath import Motion, Toolpath

log = logging.getLogger(__name__)


def orientation_jacobian(machine: Machine, q: np.ndarray) -> np.ndarray:
    """Jacobian of the tool-axis vector with respect to the rotary joints (vectorised).

    Column j is ``omega_j(q) x v``, where ``omega_j`` is the direction of rotary joint j in the
    workpiece frame at configuration ``q`` (signed so that a positive joint value turns the
    tool positively relative to the workpiece) and ``v`` the tool axis. The tests hold it to
    :func:`urdfpost.kinematics.forward.jacobian_pin` (Pinocchio).

    Parameters
    ----------
    machine : Machine
    q : ndarray, shape (n, m) or (m,), mm / rad

    Returns
    -------
    ndarray, shape (n, 3, r)
        Columns in :attr:`Machine.rotary` (chain) order, per radian.
    """
    q = np.asarray(q, dtype=float).reshape(-1, len(machine.axes))
    n = q.shape[0]
    _, v = tip_and_axis(machine, q)
    chain = [a for a in sorted(machine.axes, key=lambda a: a.chain_index) if a.rotary]
    cols = []
    for j, a in enumerate(chain):
        # the joint's direction turned by the joints before it in the chain
        w = np.broadcast_to(a.screw[:3], (n, 3))
        for b in chain[j - 1 :: -1] if j else ():
            w = rotate(b.screw[:3], q[:, machine.axis_names.index(b.name)], w)
        cols.append(cross(w, v))
    return np.stack(cols, axis=2)


def conditioning(machine: Machine, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Smallest singular value and condition number of the orientation Jacobian.

    For a machine with one rotary axis the Jacobian is a single column; its norm is both the
    smallest and largest singular value (condition number 1 where it is non-zero).

    Parameters
    ----------
    machine : Machine
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
    j = orientation_jacobian(machine, q)
    if j.shape[2] == 2:
        # two columns: s1^2 + s2^2 is the sum of their squared lengths and s1 s2 the area of
        # the parallelogram they span (which keeps its precision where s2 is tiny)
        total = np.einsum("nij,nij->n", j, j)
        area = np.linalg.norm(cross(j[:, :, 0], j[:, :, 1]), axis=1)
        smax = np.sqrt(0.5 * (total + np.sqrt(np.maximum(total**2 - 4.0 * area**2, 0.0))))
        with np.errstate(divide="ignore", invalid="ignore"):
            smin = np.where(smax > 0, area / np.where(smax > 0, smax, 1.0), 0.0)
    else:
        s = np.linalg.svd(j, compute_uv=False)  # (n, r), descending
        smin, smax = s[:, -1], s[:, 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        kappa = np.where(smin > 0, smax / np.where(smin > 0, smin, 1.0), np.inf)
    return smin, kappa


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

    ``joined[i]`` says point i continues the run of point i - 1.
    """
    n = len(joined)
    runs = []
    i = 0
    while i < n - 1:
        if joined[i + 1]:
            j = i + 1
            while j + 1 < n and joined[j + 1]:
                j += 1
            runs.append((i, j))
            i = j
        else:
            i += 1
    return runs


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
    sigma, kappa = conditioning(machine, q)
    rot_cols = list(machine.rotary_columns)
    rot = q[:, rot_cols]
    step = np.zeros((n, len(rot_cols)))
    step[1:] = np.abs(np.diff(rot, axis=0))
    k1 = machine.rotary[0].direction
    _, v = tip_and_axis(machine, q)
    near_pole = np.sqrt(np.clip(1.0 - (v @ k1) ** 2, 0.0, None)) < tol.singular_sigma
    spans: list[Span] = []
    for s, e in runs:
        low = sigma[s : e + 1] < tol.singular_sigma
        swing = np.zeros(e - s + 1, dtype=bool)
        big = (step[s + 1 : e + 1] > tol.swing_limit).any(axis=1)
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
            if (sigma[sl] < tol.singular_sigma).any():
                kind = "pole" if near_pole[sl].any() else "edge"
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
                    swing_deg=float(np.degrees(step[a + 1 : b + 1, 0].sum())),
                    max_step_deg=float(np.degrees(step[a + 1 : b + 1].max(initial=0.0))),
                )
            )
    log.debug("%d singular spans", len(spans))
    return spans
