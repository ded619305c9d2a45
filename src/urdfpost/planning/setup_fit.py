"""Which job setup would bring a path into the linear travel: :func:`fit_setup`.

A post refused because CL points lie outside the linear travel usually means that the program
zero is not where the machine file puts it (:mod:`urdfpost.machine.setup`). Moving the zero by
``d`` (mm, in the frame of the link the workpiece is mounted on) leaves every tool axis, and so
every rotary solution, as it is, and moves each CL point by ``R^T d`` in the old workpiece frame
(``R``: the workpiece's rotation on that link). For fixed rotary angles the linear axes are
affine in the tip (:func:`urdfpost.kinematics.inverse.solve_linear`), so per point

    q_lin(d) = q_lin(0) + A_i d,        A_i = dq_lin/dtip (angles_i) @ R^T   (3 x 3),

evaluated at the tip and at the tip moved by the three unit shifts. Every point must satisfy
``lower + t <= q_lin(d) <= upper - t`` with margin ``t``: a linear program in (d, t), solved with
HiGHS (:func:`scipy.optimize.linprog`) for each of the two rotary branches taken throughout the
path (a point where that branch is outside rotary travel takes the other one; a pole takes the
first angle of the point before it, as the planner holds it), then, when neither fits, for a
mix: per point the branch with more room at the shift that comes nearest. Objective:

    minimise  |d|_1 - W t,     min_margin <= t <= margin,   W = 1000,

that is: first as much margin as ``margin`` (the approach clearance: the approach point above
the first point of a path stays within travel too), then the smallest shift from the present
zero; the branch with the lower objective wins. ``min_margin`` keeps the shift away from the
very edge of travel, so that rounding the printed setup does not throw a point out again.

There are six constraints per point; HiGHS takes most of a second on 120 000 of them, so they
are generated lazily: the LP is solved on the tightest rows of each axis, the solution checked
against every row at once (numpy), the most violated rows added, until none is. A subset that is
infeasible proves the whole infeasible.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, replace

import numpy as np

from urdfpost.kinematics.inverse import solve_linear, solve_rotary
from urdfpost.machine import Machine
from urdfpost.tolerances import Tolerances
from urdfpost.units import mm_per_unit

log = logging.getLogger(__name__)

MARGIN_WEIGHT = 1000.0
"""Objective weight of 1 mm of margin against 1 mm of shift (|d|_1): margin comes first."""

_SLACK = 1e-9  # mm: travel slack, as the branch selection allows
_FIRST_ROWS = 32  # rows per axis and side in the first LP
_ADD_ROWS = 256  # most violated rows added per round
_ROUNDS = 60


@dataclass(frozen=True)
class SetupFit:
    """What :func:`fit_setup` found.

    Attributes
    ----------
    needed : bool
        Some CL point is outside the linear travel on every branch within rotary travel with
        the present setup, and every point's tool axis is reachable within rotary travel (a
        translation of the zero can only help then).
    shift : ndarray, shape (3,), mm, or None
        Translation of the program zero in the mount link's frame that brings every point
        into travel; None when none does (or none is needed).
    offset : (float, float, float) or None
        The setup offset that makes: the present origin plus ``shift``, mm.
    margin : float
        The smallest distance of a linear axis inside its travel with ``shift``, mm (0 when
        no shift was found).
    shortfall : float or None
        When no shift fits: how far outside travel the nearest one leaves some linear axis,
        mm (with the same branch throughout), None when not known.
    parent : str
        The mount link (the frame of ``shift`` and ``offset``).
    rotation : float
        The setup rotation kept, degrees.
    """

    needed: bool
    shift: np.ndarray | None = None
    offset: tuple[float, float, float] | None = None
    margin: float = 0.0
    shortfall: float | None = None
    parent: str = ""
    rotation: float = 0.0

    def hint(self, units: str = "mm") -> str:
        """The sentence a travel error ends with (empty when no setup is needed), numbers in
        ``units`` as ``--setup`` takes them.

        Examples
        --------
        >>> SetupFit(needed=True, parent="c_table").hint()
        '; no setup of the program zero brings every CL point into travel (no shift of it on c_table found)'
        """  # noqa: E501
        if not self.needed:
            return ""
        scale = mm_per_unit(units)
        if self.shift is None or self.offset is None:
            short = (
                ""
                if self.shortfall is None
                else f"; the nearest leaves a linear axis {self.shortfall / scale:.3f} {units} "
                "outside its travel"
            )
            return (
                "; no setup of the program zero brings every CL point into travel (no shift of "
                f"it on {self.parent} found{short})"
            )
        numbers = [f"{v / scale:.3f}" for v in self.offset]
        if self.rotation != 0.0:
            numbers.append(f"{self.rotation:.10g}")
        moved = ", ".join(f"{v / scale:.3f}" for v in self.shift)
        return (
            f"; --setup={','.join(numbers)} (the program zero moved by ({moved}) {units} in the "
            f"frame of {self.parent}; every linear axis then at least "
            f"{self.margin / scale:.3f} {units} inside its travel) would bring every CL point "
            "into travel"
        )


def _within_rotary(machine: Machine, angles: np.ndarray) -> np.ndarray:
    """Whether some 360-degree multiple of each angle set (n, 2, r) is within rotary travel
    (an undetermined angle counts as within), shape (n, 2)."""
    ok = np.ones(angles.shape[:2], dtype=bool)
    turn = 2.0 * np.pi
    for j, a in enumerate(machine.rotary):
        if a.continuous:
            continue
        v = angles[:, :, j]
        with np.errstate(invalid="ignore"):
            fits = np.ceil((a.lower - _SLACK - v) / turn) <= np.floor((a.upper + _SLACK - v) / turn)
        ok &= fits | np.isnan(v)
    return ok


def _held(angles: np.ndarray) -> np.ndarray:
    """``angles`` (n, r) with NaN (a pole's undetermined first angle) replaced by the last
    determined one before it (after it at the start of the path; 0 when there is none)."""
    out = angles.copy()
    for j in range(out.shape[1]):
        col = out[:, j]
        known = ~np.isnan(col)
        if known.all():
            continue
        if not known.any():
            col[:] = 0.0
            continue
        index = np.where(known, np.arange(len(col)), 0)
        np.maximum.accumulate(index, out=index)
        first = int(np.argmax(known))
        index[:first] = first
        out[:, j] = col[index]
    return out


def _linear_map(
    machine: Machine,
    rotary: np.ndarray,
    tip: np.ndarray,
    tool_length: float,
    mount_rotation: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """The linear axes at zero shift and their derivative by the shift.

    ``mount_rotation`` (3, 3) is the workpiece's rotation on the mount link: a shift along the
    mount frame's axis k moves the points by its row k in the workpiece frame (``R^T e_k``).

    Returns
    -------
    q0 : ndarray, shape (n, 3), mm
    jac : ndarray, shape (n, 3, 3)
        ``jac[i] @ d`` is how far the linear axes of point i move for a shift d.
    """
    q0 = solve_linear(machine, rotary, tip, tool_length)
    step = 100.0  # mm (exact up to rounding: the map is affine)
    jac = np.empty((len(tip), 3, 3))
    for k in range(3):
        moved = solve_linear(machine, rotary, tip + step * mount_rotation[k], tool_length)
        jac[:, :, k] = (moved - q0) / step
    return q0, jac


def _rows(
    q0: np.ndarray, jac: np.ndarray, lower: np.ndarray, upper: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The constraint rows ``G d + t <= h``: G (6n, 3), h (6n,), mm; in six groups of n (the
    upper then the lower limit of each axis)."""
    g = np.concatenate(
        [jac.transpose(1, 0, 2).reshape(-1, 3), -jac.transpose(1, 0, 2).reshape(-1, 3)]
    )
    h = np.concatenate([(upper - q0).T.ravel(), (q0 - lower).T.ravel()])
    return g, h


def _solve(
    g: np.ndarray, h: np.ndarray, margin: float, min_margin: float | None
) -> tuple[np.ndarray, float, float] | None:
    """min |d|_1 - W t subject to G d + t <= h, min_margin <= t <= margin, by constraint
    generation (module docstring); (d, t, objective), or None when infeasible. With
    ``min_margin`` None the margin may be negative: the shift that leaves the points least
    far outside travel."""
    from scipy.optimize import linprog

    groups = 6
    per = len(h) // groups
    active = np.zeros(len(h), dtype=bool)
    for grp in range(groups):  # the tightest rows of each axis and side
        part = h[grp * per : (grp + 1) * per]
        k = min(_FIRST_ROWS, per)
        active[grp * per + np.argpartition(part, k - 1)[:k]] = True
    eye = np.eye(3)
    box = np.block([[eye, -eye, np.zeros((3, 1))], [-eye, -eye, np.zeros((3, 1))]])
    cost = np.r_[np.zeros(3), np.ones(3), -MARGIN_WEIGHT]
    top = margin if min_margin is None else max(margin, min_margin)
    bounds = [(None, None)] * 3 + [(0, None)] * 3 + [(min_margin, top)]
    for _ in range(_ROUNDS):
        rows = np.flatnonzero(active)
        a_ub = np.vstack(
            [np.hstack([g[rows], np.zeros((len(rows), 3)), np.ones((len(rows), 1))]), box]
        )
        b_ub = np.r_[h[rows], np.zeros(6)]
        res = linprog(cost, A_ub=a_ub, b_ub=b_ub, bounds=bounds, method="highs")
        if res.status != 0:  # 2: infeasible on a subset, so on the whole
            if res.status != 2:
                log.debug("setup fit: linprog status %d: %s", res.status, res.message)
            return None
        d, t = res.x[:3], float(res.x[6])
        slack = h - g @ d - t
        bad = np.flatnonzero((slack < -1e-7) & ~active)
        if not len(bad):
            # the margin of every row (the LP's feasibility tolerance aside)
            return d, float(min(t, (h - g @ d).min())), float(res.fun)
        worst = bad[np.argsort(slack[bad])[:_ADD_ROWS]]
        active[worst] = True
    log.debug("setup fit: no convergence in %d rounds", _ROUNDS)
    return None


def _margins(
    q0: np.ndarray, jac: np.ndarray, d: np.ndarray, lower: np.ndarray, upper: np.ndarray
) -> np.ndarray:
    """Per point the smallest distance of its linear axes inside travel with shift d, (n,)."""
    q = q0 + jac @ d
    return np.minimum(q - lower, upper - q).min(axis=1)


def fit_setup(
    machine: Machine,
    tip: np.ndarray,
    axis: np.ndarray,
    tool_length: float = 0.0,
    margin: float = 10.0,
    min_margin: float = 1e-3,
    tol: Tolerances | None = None,
) -> SetupFit:
    """The translation of the program zero that brings every CL point into linear travel.

    Each point takes one rotary branch: first the same one throughout the path (either), then,
    when neither fits and both exist at some points, per point the branch with the more room
    at the shift that comes nearest (a few rounds). Within a branch choice the answer is exact
    (a linear program); over the choices it is a search, which may miss a mix that fits.

    Parameters
    ----------
    machine : Machine
        Loaded with the present setup (its :attr:`~urdfpost.machine.Machine.mount` is the
        frame of the answer).
    tip : ndarray, shape (n, 3), mm
        CL points in the workpiece frame.
    axis : ndarray, shape (n, 3)
        Unit tool axes.
    tool_length : float, mm
    margin : float, mm
        How far inside travel the linear axes should stay when the travel allows.
    min_margin : float, mm
        How far inside travel they must stay (the rounding of the setup as it is printed).
    tol : Tolerances, optional

    Returns
    -------
    SetupFit
        ``needed`` False when the points are within travel with the present setup, or when a
        tool axis is outside the rotary travel (no translation helps then).
    """
    mount = machine.mount
    tip = np.asarray(tip, dtype=float).reshape(-1, 3)
    axis = np.asarray(axis, dtype=float).reshape(-1, 3)
    if mount is None or not len(tip):
        return SetupFit(needed=False)
    solutions = solve_rotary(machine, axis, tol)
    usable = solutions.valid & _within_rotary(machine, solutions.angles)
    if not usable.any(axis=1).all():
        return SetupFit(needed=False)  # a tool axis outside rotary travel
    lower = np.array([a.lower for a in machine.linear]) - _SLACK
    upper = np.array([a.upper for a in machine.linear]) + _SLACK
    n = len(tip)
    maps = []
    for b in (0, 1):
        take = np.where(usable[:, b], b, 1 - b)  # the other where this one is not usable
        rotary = _held(solutions.angles[np.arange(n), take])
        maps.append(_linear_map(machine, rotary, tip, tool_length, mount.rotation))
    q0 = np.stack([m[0] for m in maps], axis=1)  # (n, 2, 3)
    jac = np.stack([m[1] for m in maps], axis=1)  # (n, 2, 3, 3)
    zero = np.zeros(3)
    room = np.stack([_margins(q0[:, b], jac[:, b], zero, lower, upper) for b in (0, 1)], axis=1)
    none = SetupFit(needed=True, parent=mount.parent, rotation=mount.setup.rotation)
    if ((room >= 0.0) & usable).any(axis=1).all():
        return replace(none, needed=False)

    def solve(take: np.ndarray, floor: float | None) -> tuple[np.ndarray, float, float] | None:
        rows = _rows(q0[np.arange(n), take], jac[np.arange(n), take], lower, upper)
        return _solve(*rows, margin, floor)

    choices = [np.where(usable[:, b], b, 1 - b) for b in (0, 1)]
    found = [r for r in (solve(c, min_margin) for c in choices) if r is not None]
    if not found and usable.all(axis=1).any():  # a mix of branches may fit
        take = choices[0]
        for _ in range(4):
            nearest = solve(take, None)
            if nearest is None:
                break
            d = nearest[0]
            at_d = np.stack(
                [_margins(q0[:, b], jac[:, b], d, lower, upper) for b in (0, 1)], axis=1
            )
            better = np.where(usable, at_d, -np.inf).argmax(axis=1)
            if (better == take).all():
                break
            take = better
            result = solve(take, min_margin)
            if result is not None:
                found.append(result)
                break
    if not found:
        nearest = solve(choices[0], None)
        short = None if nearest is None else max(-nearest[1], 0.0)
        return replace(none, shortfall=short)
    d, t, _ = min(found, key=lambda f: f[2])
    d = np.where(np.abs(d) < 1e-9, 0.0, d) + 0.0
    return replace(none, shift=d, offset=mount.offset_for(d), margin=t)
