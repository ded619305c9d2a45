"""Choosing one joint solution per CL point.

The rules of Source A (``docs`` of the project: seeds.md), applied to the whole path at once:

- a candidate outside the travel of any axis (rotary or linear) is never taken; a point with no
  candidate left is an error naming its CL line;
- at the start (and after a tool change), the preferred branch is taken when it is within
  travel, unless keeping it would force a flip of branch later in the cut;
- a switch of branch between two regular points costs half a turn (it is a jump of the first
  rotary axis within one block); at a pole or edge the branches meet and switching is free;
- otherwise the choice follows the previous block: the total rotary motion along the path is
  minimised by dynamic programming (Viterbi) over every branch and every 360-degree multiple
  within travel, which is "nearest to the previous block" made global, so one block's greedy
  choice cannot lead the path into a travel limit that the other branch avoids;
- continuous axes take the 360-degree multiple nearest the previous block (the shortest rotation),
  so the steps to the previous and the next block are as small as they can be;
- at a pole (tool axis along the first rotary axis) that axis is undetermined and holds its
  previous value (its home value at the start).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from urdfpost.errors import UnreachableError
from urdfpost.kinematics.inverse import (
    IKStatus,
    assemble,
    inverse,
    solve_linear,
)
from urdfpost.machine import Machine
from urdfpost.tolerances import Tolerances

log = logging.getLogger(__name__)

TWO_PI = 2.0 * np.pi
_SLACK = 1e-9  # rad or mm beyond travel still accepted (rounding of limits written in degrees)


@dataclass(frozen=True)
class Preference:
    """A preferred rotary branch: the sign of one rotary axis' angle.

    Attributes
    ----------
    axis : str
        NC address of a rotary axis.
    sign : int
        +1 or -1.
    """

    axis: str
    sign: int

    @classmethod
    def parse(cls, text: str) -> Preference:
        """Read ``"B+"``, ``"B-"``, ``"+B"`` or ``"-B"``.

        Raises
        ------
        ValueError
            With the expected form.
        """
        t = text.strip().upper()
        if len(t) == 2 and t[0] in "ABC" and t[1] in "+-":
            return cls(t[0], 1 if t[1] == "+" else -1)
        if len(t) == 2 and t[1] in "ABC" and t[0] in "+-":
            return cls(t[1], 1 if t[0] == "+" else -1)
        raise ValueError(f"expected a preferred branch like B+ or C-, got {text!r}")


@dataclass(frozen=True)
class Selection:
    """The chosen solution per point.

    Attributes
    ----------
    q : ndarray, shape (n, m), mm / rad
        Joint vectors; rotary angles unwrapped along the path.
    branch : ndarray, shape (n,), int
        IK branch taken (0 or 1).
    status : ndarray, shape (n,), int8
        :class:`IKStatus` of each point.
    """

    q: np.ndarray
    branch: np.ndarray
    status: np.ndarray


def _wrap(a: np.ndarray) -> np.ndarray:
    return np.pi - np.mod(np.pi - a, TWO_PI)


def _candidates(
    machine: Machine, angles: np.ndarray, valid: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Expand branches by the 360-degree multiples each limited rotary axis can take.

    Parameters
    ----------
    angles : ndarray, shape (n, 2, r)
    valid : ndarray, shape (n, 2)

    Returns
    -------
    values : ndarray, shape (n, K, r)
    ok : ndarray, shape (n, K), bool
        Exists and lies within rotary travel (an undetermined angle counts as within).
    branch : ndarray, shape (K,), int
    """
    rot = machine.rotary
    shift_sets = []
    for a in rot:
        if a.continuous:
            shift_sets.append(np.array([0.0]))
        else:
            k_lo = int(np.floor((a.lower - np.pi) / TWO_PI))
            k_hi = int(np.ceil((a.upper + np.pi) / TWO_PI))
            shift_sets.append(TWO_PI * np.arange(k_lo, k_hi + 1))
    grids = np.meshgrid(*shift_sets, indexing="ij")
    shifts = np.stack([g.ravel() for g in grids], axis=1)  # (W, r)
    values = (angles[:, :, None, :] + shifts[None, None, :, :]).reshape(
        angles.shape[0], -1, len(rot)
    )
    branch = np.repeat(np.arange(2), shifts.shape[0])
    ok = np.repeat(valid, shifts.shape[0], axis=1)
    lo = np.array([a.lower for a in rot]) - _SLACK
    hi = np.array([a.upper for a in rot]) + _SLACK
    inside = (values >= lo) & (values <= hi) | np.isnan(values)
    return values, ok & inside.all(axis=2), branch


def _linear_ok(machine: Machine, q: np.ndarray) -> np.ndarray:
    """Whether the linear axes of ``q`` (n, 2, m) are within travel, shape (n, 2)."""
    cols = list(machine.linear_columns)
    lin = q[:, :, cols]
    lo, hi = machine.lower[cols] - _SLACK, machine.upper[cols] + _SLACK
    return ((lin >= lo) & (lin <= hi)).all(axis=2)


def _unreachable_message(
    machine: Machine, axis: np.ndarray, status: int, line: int, source: str
) -> str:
    v = ", ".join(f"{c:.6g}" for c in axis)
    where = f"{source}:{line}"
    if status == IKStatus.UNREACHABLE:
        return (
            f"{where}: tool axis ({v}) is outside the orientations machine {machine.name} can "
            "reach with its rotary axes"
        )
    travel = "; ".join(
        f"{a.name} {np.degrees(a.lower):.3f}..{np.degrees(a.upper):.3f} deg"
        if a.rotary
        else f"{a.name} {a.lower:.3f}..{a.upper:.3f} mm"
        for a in machine.axes
        if np.isfinite(a.lower)
    )
    return (
        f"{where}: tool axis ({v}) cannot be reached within the travel of machine "
        f"{machine.name} on any branch ({travel}); change the CL data, the fixture position or "
        "the machine"
    )


def _linear_message(
    machine: Machine, q: np.ndarray, tip: np.ndarray, line: int, source: str
) -> str:
    """Message for a point whose rotary angles fit but whose linear axes leave their travel.

    Parameters
    ----------
    q : ndarray, shape (2, m)
        The point's solutions per branch (NaN rows for missing branches).
    """
    cols = list(machine.linear_columns)
    parts = []
    for b in range(q.shape[0]):
        if np.isnan(q[b, cols]).any():
            continue
        for j, a in zip(cols, machine.linear, strict=True):
            if not a.lower - _SLACK <= q[b, j] <= a.upper + _SLACK:
                parts.append(
                    f"{a.name} would need {q[b, j]:.3f} mm (travel {a.lower:.3f}..{a.upper:.3f})"
                )
    p = ", ".join(f"{c:.4f}" for c in tip)
    return (
        f"{source}:{line}: CL point ({p}) mm is outside the linear travel of machine "
        f"{machine.name} on every branch: {'; '.join(dict.fromkeys(parts))}; check the tool "
        "length and where the workpiece sits on the machine"
    )


def select(
    machine: Machine,
    tip: np.ndarray,
    axis: np.ndarray,
    *,
    tool_length: float = 0.0,
    prefer: Preference | None = None,
    entry: np.ndarray | None = None,
    start: np.ndarray | None = None,
    lines: np.ndarray | None = None,
    source: str = "<toolpath>",
    tol: Tolerances | None = None,
    planner: str = "global",
) -> Selection:
    """Choose one solution per point (see the module docstring for the rules).

    Parameters
    ----------
    machine : Machine
    tip : ndarray, shape (n, 3), mm
    axis : ndarray, shape (n, 3)
    tool_length : float, mm
    prefer : Preference, optional
        Defaults to the machine file's preference.
    entry : ndarray, shape (n,), bool, optional
        Points where the preference applies again (the path is entered anew, e.g. after a
        tool change). The first point always is one.
    start : ndarray, shape (m,), optional
        Joint vector before the first point (default: the machine's home).
    lines : ndarray, shape (n,), int, optional
        CL source lines, for messages.
    source : str
        CL file name, for messages.
    tol : Tolerances, optional
    planner : str
        "global" (dynamic programming over the whole path, the default) or "local" (each
        point takes the candidate nearest the previous one, the preference only at entries:
        what a naive post does; kept as the baseline to compare against).

    Returns
    -------
    Selection

    Raises
    ------
    UnreachableError
        Naming the CL line of the first point no branch reaches within travel.
    """
    tol = tol or Tolerances()
    tip = np.asarray(tip, dtype=float).reshape(-1, 3)
    axis = np.asarray(axis, dtype=float).reshape(-1, 3)
    n = tip.shape[0]
    lines = np.arange(1, n + 1) if lines is None else np.asarray(lines)
    if prefer is None and machine.settings.prefer is not None:
        prefer = Preference(*machine.settings.prefer)
    start = machine.home if start is None else np.asarray(start, dtype=float)
    rot_cols = list(machine.rotary_columns)
    start_rot = start[rot_cols]

    ik = inverse(machine, tip, axis, tool_length, tol, pole_angle=0.0)
    values, ok, branch = _candidates(machine, ik.rotary.angles, ik.rotary.valid)
    pole = ik.status == IKStatus.POLE
    # linear travel: known per branch except at poles, where it depends on the held angle
    lin_ok = _linear_ok(machine, ik.q) | pole[:, None]
    rotary_ok = ok.any(axis=1)
    ok &= lin_ok[:, branch]
    dead = ~ok.any(axis=1)
    if dead.any():
        i = int(np.argmax(dead))
        if rotary_ok[i]:
            raise UnreachableError(_linear_message(machine, ik.q[i], tip[i], int(lines[i]), source))
        raise UnreachableError(
            _unreachable_message(machine, axis[i], int(ik.status[i]), int(lines[i]), source)
        )

    entry = np.zeros(n, dtype=bool) if entry is None else np.asarray(entry, dtype=bool).copy()
    entry[0] = True
    pref_cost = np.zeros(values.shape[:2])
    if prefer is not None and prefer.axis in [a.name for a in machine.rotary]:
        j = [a.name for a in machine.rotary].index(prefer.axis)
        wrong = np.nan_to_num(values[:, :, j] * prefer.sign, nan=0.0) < -1e-9
        # at an entry the preference outweighs any difference in motion but not a flip it
        # would force later (a flip costs half a turn plus the jump); elsewhere it breaks ties
        pref_cost = np.where(wrong, 1.0, 0.0) * np.where(entry, np.pi, 1e-6)[:, None]
    # a tiny pull toward small angles makes ties (e.g. +-180 degrees) deterministic
    pref_cost = pref_cost + 1e-9 * np.abs(np.nan_to_num(values)).sum(axis=2)

    cont = np.array([a.continuous for a in machine.rotary])
    singular = (ik.status == IKStatus.POLE) | (ik.status == IKStatus.EDGE)
    n_cand = values.shape[1]
    cost = np.where(ok[0], pref_cost[0], np.inf)
    state = values[0].copy()  # (K, r) actual values of each candidate state
    state[:, 0] = np.where(np.isnan(state[:, 0]), start_rot[0], state[:, 0])
    state[:, cont] = state[:, cont] + TWO_PI * np.round((start_rot[cont] - state[:, cont]) / TWO_PI)
    if planner == "local":
        return _select_local(machine, values, ok, branch, cost, state, cont, tip, tool_length, ik)
    if planner != "global":
        raise ValueError(f"unknown planner {planner!r}; expected 'global' or 'local'")
    back = np.zeros((n, n_cand), dtype=np.int32)
    history = np.empty((n, n_cand, values.shape[2]))
    history[0] = state
    for i in range(1, n):
        cand = values[i]  # (K, r)
        # step from every previous state (rows) to every candidate (columns)
        diff = cand[None, :, :] - state[:, None, :]
        diff[:, :, cont] = _wrap(diff[:, :, cont])
        diff = np.nan_to_num(diff, nan=0.0)  # undetermined angle: held, no motion
        step = np.abs(diff).sum(axis=2)
        # the branches meet only at singular points; a switch between two regular points
        # needs a jump of the first axis somewhere in the block, which no subdivision removes
        if not (singular[i] or singular[i - 1]):
            step = step + np.pi * (branch[:, None] != branch[None, :])
        total = cost[:, None] + step
        best = np.argmin(total, axis=0)
        cost = np.where(ok[i], total[best, np.arange(n_cand)] + pref_cost[i], np.inf)
        back[i] = best
        # limited axes land on the candidate, continuous ones on the shortest rotation to it,
        # an undetermined angle holds
        state = state[best] + diff[best, np.arange(n_cand)]
        history[i] = state
        if not np.isfinite(cost).any():  # pragma: no cover - excluded by the dead check
            raise UnreachableError(f"{source}:{int(lines[i])}: no continuous solution")
    k = int(np.argmin(cost))
    chosen = np.empty(n, dtype=np.int64)
    for i in range(n - 1, -1, -1):
        chosen[i] = k
        k = back[i, k]
    rot = history[np.arange(n), chosen]
    lin = solve_linear(machine, rot, tip, tool_length)
    q = assemble(machine, rot, lin)
    _check_linear(machine, q, pole, lines, source)
    log.debug(
        "selected %d points, branch switches: %d", n, int(np.sum(np.diff(branch[chosen]) != 0))
    )
    return Selection(q=q, branch=branch[chosen], status=ik.status.copy())


def _select_local(
    machine: Machine,
    values: np.ndarray,
    ok: np.ndarray,
    branch: np.ndarray,
    cost0: np.ndarray,
    state0: np.ndarray,
    cont: np.ndarray,
    tip: np.ndarray,
    tool_length: float,
    ik: object,
) -> Selection:
    """Greedy choice: each point takes the candidate nearest the previous point's angles."""
    n = values.shape[0]
    k = int(np.argmin(cost0))
    cur = state0[k].copy()
    rot = np.empty((n, values.shape[2]))
    chosen = np.empty(n, dtype=np.int64)
    rot[0], chosen[0] = cur, k
    for i in range(1, n):
        diff = values[i] - cur[None, :]
        diff[:, cont] = _wrap(diff[:, cont])
        diff = np.nan_to_num(diff, nan=0.0)
        step = np.where(ok[i], np.abs(diff).sum(axis=1) + 1e-9 * branch, np.inf)
        k = int(np.argmin(step))
        cur = cur + diff[k]
        rot[i], chosen[i] = cur, k
    lin = solve_linear(machine, rot, tip, tool_length)
    q = assemble(machine, rot, lin)
    return Selection(q=q, branch=branch[chosen], status=ik.status.copy())  # type: ignore[attr-defined]


def _check_linear(
    machine: Machine, q: np.ndarray, pole: np.ndarray, lines: np.ndarray, source: str
) -> None:
    """Linear travel at the poles (where it was unknown before the angle was held)."""
    cols = list(machine.linear_columns)
    lo, hi = machine.lower[cols] - _SLACK, machine.upper[cols] + _SLACK
    bad = ((q[:, cols] < lo) | (q[:, cols] > hi)).any(axis=1) & pole
    if bad.any():
        i = int(np.argmax(bad))
        j = int(np.argmax((q[i, cols] < lo) | (q[i, cols] > hi)))
        a = machine.linear[j]
        raise UnreachableError(
            f"{source}:{int(lines[i])}: axis {a.name} would need {q[i, cols[j]]:.3f} mm, outside "
            f"its travel {a.lower:.3f}..{a.upper:.3f} mm"
        )
