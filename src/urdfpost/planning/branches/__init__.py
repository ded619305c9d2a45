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
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from urdfpost.errors import CollisionError, UnreachableError
from urdfpost.kinematics.inverse import (
    IKStatus,
    assemble,
    inverse,
    solve_linear,
)
from urdfpost.machine import Machine
from urdfpost.tolerances import Tolerances

if TYPE_CHECKING:
    from urdfpost.collision import CollisionWorld

log = logging.getLogger(__name__)

TWO_PI = 2.0 * np.pi
_SAME_ANGLE = 1e-7  # rad: a candidate with the start's angles (continued paths)
_SLACK = 1e-9  # rad or mm beyond travel still accepted (rounding of limits written in degrees)

DEFAULT_RETRACT = 50.0
"""Lift along the tool axis for a rewind, mm."""


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
        Joint vectors the path leaves each point with; rotary angles unwrapped along the path.
    branch : ndarray, shape (n,), int
        IK branch taken (0 or 1).
    status : ndarray, shape (n,), int8
        :class:`IKStatus` of each point.
    arrive : ndarray, shape (n, m), mm / rad
        Joint vectors the path arrives at each point with: ``q`` except at rewinds.
    rewind : ndarray, shape (n,), bool
        Points where the path stops, lifts off, turns from ``arrive`` to ``q`` (the other
        branch, or the same orientation a turn back) and returns: no continuous solution
        within travel (or clear of collisions) goes on from there.
    notes : list of str
        Why candidates were passed over (collisions), for the report.
    settled : int or None
        The last point whose choice no points after the path could change (the best paths
        into every candidate still possible at the last point agree up to it), -1 when none;
        None: not known.
    """

    q: np.ndarray
    branch: np.ndarray
    status: np.ndarray
    arrive: np.ndarray
    rewind: np.ndarray
    notes: list[str] = field(default_factory=list)
    settled: int | None = None

    @property
    def rewinds(self) -> np.ndarray:
        """Indices of the rewind points, shape (k,)."""
        return np.flatnonzero(self.rewind)


def _wrap(a: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """Angles wrapped to (-pi, pi]: ``pi - mod(pi - a, 2 pi)``.

    Bit for bit what that formula gives with ``np.mod``, which is ``fmod`` plus a turn where
    the remainder is negative (a zero remainder's sign does not matter after ``pi -``), several
    times faster: the turns are added as 0 or 2 pi (no branches on the data), and for
    ``pi - a`` within (-2 pi, 4 pi), as for differences of two wrapped angles, ``fmod`` is a
    turn off where it is 2 pi or more, which is exact there. A few angles take the formula
    itself (fewer calls). ``out`` may be ``a``.
    """
    m = np.subtract(np.pi, a, out=out)
    if m.size <= 64:  # a few angles: the fewest calls
        return np.subtract(np.pi, np.mod(m, TWO_PI), out=out)
    if m.min() > -TWO_PI and m.max() < 2.0 * TWO_PI:
        m -= TWO_PI * (m >= TWO_PI)
    else:
        np.fmod(m, TWO_PI, out=m)
    m += TWO_PI * (m < 0.0)
    return np.subtract(np.pi, m, out=m)


def _total(size: list[np.ndarray]) -> np.ndarray:
    """Sum of the rotary axes' motions ``size`` (one array per axis), in order: with one or
    two axes, to the bit what a sum over an axis of one array gives. May be ``size[0]``."""
    if len(size) == 1:
        return size[0]
    total = np.add(size[0], size[1])
    for s in size[2:]:
        total += s
    return total


def _rows_any(a: np.ndarray) -> np.ndarray:
    """Whether each row of a boolean array of shape (n, k) has a true entry, shape (n,): one
    column at a time, which is much faster than numpy's reduction over a short last axis."""
    out = np.zeros(len(a), dtype=bool)
    for c in range(a.shape[1]):
        out |= a[:, c]
    return out


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
    n, _, r = angles.shape
    lo = np.array([a.lower for a in rot]) - _SLACK
    hi = np.array([a.upper for a in rot]) + _SLACK
    shift_sets = []
    for j, a in enumerate(rot):
        col = angles[:, :, j]
        if a.continuous or not np.isfinite(col).any():
            shift_sets.append(np.array([0.0]))
            continue
        # the multiples that can put some angle of the path within travel
        top, bottom = np.nanmax(col), np.nanmin(col)
        k_lo = int(np.floor((a.lower - top) / TWO_PI))
        k_hi = int(np.ceil((a.upper - bottom) / TWO_PI))
        shifts = TWO_PI * np.arange(k_lo, k_hi + 1)
        if not (np.isnan(col) & valid).any():
            # without those that put none (rounding is monotonic: nothing is above top +
            # shift), which could never be taken; an undetermined angle fits every multiple
            shifts = shifts[(top + shifts >= lo[j]) & (bottom + shifts <= hi[j])]
        shift_sets.append(shifts)
    grids = np.meshgrid(*shift_sets, indexing="ij")
    shifts = np.stack([g.ravel() for g in grids], axis=1)  # (W, r)
    values = np.empty((n, 2, len(shifts), r))
    ok = np.repeat(valid, len(shifts), axis=1)
    limited = [j for j in range(r) if lo[j] > -np.inf or hi[j] < np.inf]  # (others: all within)
    for sl in _chunks(n, values[0].size):  # temporaries in cache
        out = values[sl]
        for w in range(len(shifts)):
            for j in range(r):
                np.add(angles[sl, :, j], shifts[w, j], out=out[:, :, w, j])
        out = out.reshape(len(out), -1, r)
        for j in limited:
            v = out[:, :, j]
            ok[sl] &= (v >= lo[j]) & (v <= hi[j]) | np.isnan(v)
    branch = np.repeat(np.arange(2), len(shifts))
    return values.reshape(n, 2 * len(shifts), r), ok, branch


def _chunks(n: int, size: int) -> list[slice]:
    """Slices of ``range(n)`` with about :data:`_CHUNK` array entries each, for points that
    take ``size`` entries each."""
    rows = max(1, _CHUNK // max(1, size))
    return [slice(lo, lo + rows) for lo in range(0, n, rows)]


def _linear_ok(machine: Machine, q: np.ndarray) -> np.ndarray:
    """Whether the linear axes of ``q`` (n, 2, m) are within travel, shape (n, 2)."""
    ok = np.ones(q.shape[:2], dtype=bool)
    for sl in _chunks(len(q), q[0].size):
        for j in machine.linear_columns:
            v = q[sl, :, j]
            ok[sl] &= (v >= machine.lower[j] - _SLACK) & (v <= machine.upper[j] + _SLACK)
    return ok


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


REWIND_COST = 1e6
"""Cost of one rewind, in the planner's units (radians of rotary travel): far above any motion
along a path, so a rewind is taken only where no continuous solution exists (or none is clear
of collisions), and the fewest of them."""

LIMIT_MARGIN = np.radians(5.0)
"""Within this of a travel limit (rad), a limited rotary axis is penalised."""

LIMIT_WEIGHT = 0.05
"""Penalty (radians of travel equivalent) per point for a limited axis at its limit, falling
linearly to 0 at ``LIMIT_MARGIN`` from it: enough to break ties away from the limits, never
enough to buy real travel."""

TIME_WEIGHT = 0.5
"""Weight of the time a step takes (its slowest axis: angle over that axis' velocity, times the
slowest rotary axis' velocity so the unit is radians) against the plain rotary travel."""

JUMP = 0.5 * np.pi
"""A branch switch between regular points whose rotary axes move more than this in total (rad)
is a jump: on a cutting move it needs a rewind. Smaller switches pass close to a pole."""

_MAX_COLLISION_ROUNDS = 50  # re-plans after colliding moves were found on the chosen path


@dataclass
class _Exclusions:
    """What the collision checks ruled out, indexed by point and candidate."""

    state: np.ndarray  # (n, K) bool: candidate collides at the point
    why: dict[tuple[int, int], tuple[str, str]] = field(default_factory=dict)
    moves: dict[int, set[tuple[int, int]]] = field(default_factory=dict)  # i -> (k_prev, k)
    rewinds: dict[int, set[tuple[int, int]]] = field(default_factory=dict)  # i -> (k_in, k_out)
    move_why: dict[tuple[int, int, int], tuple[str, str]] = field(default_factory=dict)


def _limit_penalty(machine: Machine, values: np.ndarray) -> np.ndarray:
    """Penalty for running close to travel limits, shape (n, K) (``values`` (n, K, r))."""
    pen = np.zeros(values.shape[:2])
    for j, a in enumerate(machine.rotary):
        if a.continuous or not (np.isfinite(a.lower) and np.isfinite(a.upper)):
            continue
        v = values[:, :, j]
        close = np.minimum(v - a.lower, a.upper - v)  # the room left, then how close
        np.divide(close, LIMIT_MARGIN, out=close)
        np.subtract(1.0, close, out=close)
        np.clip(close, 0.0, 1.0, out=close)
        np.nan_to_num(close, copy=False, nan=0.0)
        close *= LIMIT_WEIGHT
        pen += close
    return pen


def _point_costs(
    machine: Machine,
    values: np.ndarray,
    entry: np.ndarray,
    prefer: Preference | None,
    limits: bool,
) -> np.ndarray:
    """Cost of taking each candidate at each point, shape (n, K) (``values`` (n, K, r)): the
    preference, a tiny pull toward small angles, and (``limits``) the penalty near travel
    limits. Computed a few thousand points at a time (temporaries in cache)."""
    names = [a.name for a in machine.rotary]
    j = names.index(prefer.axis) if prefer is not None and prefer.axis in names else None
    out = np.empty(values.shape[:2])
    for sl in _chunks(len(values), values[0].size):
        v = values[sl]
        cost = np.zeros(v.shape[:2])
        if prefer is not None and j is not None:
            wrong = v[:, :, j] * prefer.sign < -1e-9  # (an undetermined angle is not)
            # at an entry the preference outweighs any difference in motion but not a flip
            # it would force later (a flip costs half a turn plus the jump); elsewhere it
            # breaks ties
            cost = np.where(wrong, 1.0, 0.0) * np.where(entry[sl], np.pi, 1e-6)[:, None]
        # a tiny pull toward small angles makes ties (e.g. +-180 degrees) deterministic
        pull = _total([np.nan_to_num(np.abs(v[:, :, a]), copy=False) for a in range(v.shape[2])])
        pull *= 1e-9
        cost += pull
        if limits:
            cost += _limit_penalty(machine, v)
        out[sl] = cost
    return out


def _step_weights(machine: Machine) -> np.ndarray:
    """Time weight per rotary axis: slowest rotary velocity over the axis' own, shape (r,)."""
    vel = np.array([a.velocity for a in machine.rotary], dtype=float)
    vel = np.where(np.isfinite(vel) & (vel > 0), vel, np.nan)
    if np.isnan(vel).all():
        return np.zeros(len(vel))
    return TIME_WEIGHT * np.nan_to_num(np.nanmin(vel) / vel, nan=0.0)


def _label(machine: Machine, rot: np.ndarray) -> str:
    return " ".join(
        f"{a.name}{np.degrees(v):.3f}" for a, v in zip(machine.rotary, rot, strict=True)
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
    cutting: np.ndarray | None = None,
    collision: CollisionWorld | None = None,
    retract: float = DEFAULT_RETRACT,
    fixed_start: bool = False,
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
    cutting : ndarray, shape (n,), bool, optional
        Whether the move into each point cuts (a feed move): there the rotary axes must move
        continuously, and a jump (a branch switch between regular points, a limited axis
        turning more than half a turn) needs a rewind. Default: every move but those into
        entry points.
    collision : CollisionWorld, optional
        Candidates that collide at a point, and moves of the chosen path that collide, are
        excluded; None: no collision checks.
    retract : float, mm
        Lift along the tool axis for a rewind.
    fixed_start : bool
        The first point continues a path posted before (a piece of a streamed post): it must
        take the rotary angles of ``start`` exactly (unwrapped as they are), whatever the
        preference; ``start`` is required then.

    Returns
    -------
    Selection

    Raises
    ------
    UnreachableError
        Naming the CL line of the first point no branch reaches within travel, or from which
        no continuous solution goes on and no rewind is possible.
    CollisionError
        Naming the CL line and the two bodies where every candidate collides.
    """
    tol = tol or Tolerances()
    tip = np.asarray(tip, dtype=float).reshape(-1, 3)
    axis = np.asarray(axis, dtype=float).reshape(-1, 3)
    n = tip.shape[0]
    lines = np.arange(1, n + 1) if lines is None else np.asarray(lines)
    if prefer is None and machine.settings.prefer is not None:
        prefer = Preference(*machine.settings.prefer)
    if fixed_start and start is None:
        raise ValueError("fixed_start needs the joint vector to start from")
    start = machine.home if start is None else np.asarray(start, dtype=float)
    if planner not in ("global", "local"):
        raise ValueError(f"unknown planner {planner!r}; expected 'global' or 'local'")

    if n == 0:
        none = np.zeros((0, len(machine.axes)))
        return Selection(
            q=none,
            branch=np.zeros(0, dtype=int),
            status=np.zeros(0, dtype=np.int8),
            arrive=none,
            rewind=np.zeros(0, dtype=bool),
        )
    ik = inverse(machine, tip, axis, tool_length, tol, pole_angle=0.0)
    values, ok, branch = _candidates(machine, ik.rotary.angles, ik.rotary.valid)
    pole = ik.status == IKStatus.POLE
    # linear travel: known per branch except at poles, where it depends on the held angle
    lin_ok = _linear_ok(machine, ik.q) | pole[:, None]
    within = ok & lin_ok[:, branch]
    dead = ~_rows_any(within)
    if dead.any():
        i = int(np.argmax(dead))
        if ok[i].any():
            raise UnreachableError(_linear_message(machine, ik.q[i], tip[i], int(lines[i]), source))
        raise UnreachableError(
            _unreachable_message(machine, axis[i], int(ik.status[i]), int(lines[i]), source)
        )

    ok = within
    # candidates (360-degree multiples) within travel nowhere on the path are never taken
    keep = np.array([ok[:, k].any() for k in range(ok.shape[1])], dtype=bool)
    if not keep.all():  # (compress keeps the arrays in point order, which the planner walks)
        values, ok, branch = values.compress(keep, 1), ok.compress(keep, 1), branch[keep]

    entry = np.zeros(n, dtype=bool) if entry is None else np.asarray(entry, dtype=bool).copy()
    entry[0] = True
    cutting = ~entry if cutting is None else np.asarray(cutting, dtype=bool) & ~entry
    pref_cost = _point_costs(machine, values, entry, prefer, planner == "global")

    problem = _Plan(
        machine=machine,
        values=values,
        ok=ok,
        branch=branch,
        pref_cost=pref_cost,
        start=start[list(machine.rotary_columns)],
        singular=pole | (ik.status == IKStatus.EDGE),
        cutting=cutting,
        weights=_step_weights(machine),
        switch_cost=np.pi if planner == "global" else 0.0,
        lines=lines,
        source=source,
        exclude=_Exclusions(state=np.zeros(values.shape[:2], dtype=bool)),
        fixed_start=fixed_start,
    )
    if fixed_start and not np.isfinite(problem.first_state()[0]).any():
        raise UnreachableError(
            f"{source}:{int(lines[0])}: the path cannot go on from where the part before it "
            f"ended (rotary {np.degrees(problem.start).round(4).tolist()} deg): no candidate "
            "there is within travel with those angles"
        )
    if collision is not None:
        _exclude_colliding_states(problem, collision, ik.q, pole)
        blocked = ~problem.usable().any(axis=1)
        if blocked.any():
            _raise_dead_end(problem, int(np.argmax(blocked)))
    status = ik.status
    del ik  # (its joint vectors are the largest arrays here: the planner can reuse the memory)
    for _ in range(_MAX_COLLISION_ROUNDS):
        if planner == "global":
            chosen, arrive_k, rot_leave, rot_arrive, settled = _viterbi(problem)
        else:  # each choice depends on the points before it only
            chosen, arrive_k, rot_leave, rot_arrive = _greedy(problem)
            settled = n - 1
        lin = solve_linear(machine, rot_leave, tip, tool_length)
        q = assemble(machine, rot_leave, lin)
        rewind = chosen != arrive_k
        q_arrive = q.copy()
        if rewind.any():
            lin_a = solve_linear(machine, rot_arrive[rewind], tip[rewind], tool_length)
            q_arrive[rewind] = assemble(machine, rot_arrive[rewind], lin_a)
        if collision is None or not _exclude_colliding_moves(
            problem, collision, q, q_arrive, chosen, arrive_k, tip, axis, tool_length, retract
        ):
            break
    else:  # pragma: no cover - a path this tangled is a modelling problem
        raise CollisionError(
            f"{source}: no collision-free choice found after {_MAX_COLLISION_ROUNDS} re-plans"
        )
    _check_linear(machine, q, pole, lines, source)
    if rewind.any():
        _check_linear(machine, q_arrive, pole, lines, source)
    notes = _exclusion_notes(problem, chosen, arrive_k)
    if log.isEnabledFor(logging.DEBUG):  # (the counts are passes over the whole path)
        log.debug(
            "selected %d points, branch switches: %d, rewinds: %d",
            n,
            int(np.sum(np.diff(branch[chosen]) != 0)),
            int(rewind.sum()),
        )
    return Selection(
        q=q,
        branch=branch[chosen],
        status=status.copy(),
        arrive=q_arrive,
        rewind=rewind,
        notes=notes,
        settled=settled,
    )


@dataclass
class _Plan:
    """The planning problem over the candidates of every point."""

    machine: Machine
    values: np.ndarray  # (n, K, r) candidate rotary angles, NaN where undetermined
    ok: np.ndarray  # (n, K) within travel
    branch: np.ndarray  # (K,)
    pref_cost: np.ndarray  # (n, K)
    start: np.ndarray  # (r,)
    singular: np.ndarray  # (n,)
    cutting: np.ndarray  # (n,)
    weights: np.ndarray  # (r,) time weight per axis
    switch_cost: float  # added for a branch switch between regular points, rad
    lines: np.ndarray
    source: str
    exclude: _Exclusions
    fixed_start: bool = False  # the first point takes the start's angles (a continued path)

    def __post_init__(self) -> None:
        self.cont = np.array([a.continuous for a in self.machine.rotary], dtype=bool)
        self.switch = self.branch[:, None] != self.branch[None, :]  # (K, K): a branch switch
        self.cont_axes = [int(a) for a in np.flatnonzero(self.cont)]

    def _diff(self, i: int, state: np.ndarray) -> np.ndarray:
        """Rotary motion from states to every candidate at point ``i``.

        Parameters
        ----------
        i : int
        state : ndarray, shape (S, r), rad
            States (rows) the motion starts from.

        Returns
        -------
        ndarray, shape (S, K, r), rad
            Limited axes land on the candidate, continuous ones take the shortest rotation to
            it, an undetermined angle holds.
        """
        diff = self.values[i] - state[:, None, :]
        for a in self.cont_axes:
            _wrap(diff[..., a], out=diff[..., a])
        if np.isnan(diff).any():
            np.nan_to_num(diff, copy=False, nan=0.0)
        return diff

    def _size(self, diff: np.ndarray, axis: int, nan: bool) -> np.ndarray:
        """How far rotary axis ``axis`` moves: the absolute value of what :meth:`_diff`
        gives for it, made in place from ``diff``, the candidates' angles less the states'
        (``nan``: whether there may be undetermined angles)."""
        if self.cont[axis]:
            _wrap(diff, out=diff)
        if nan:
            np.nan_to_num(diff, copy=False, nan=0.0)
        return np.abs(diff, out=diff)

    def _move_cost(
        self,
        size: list[np.ndarray],
        regular: np.ndarray | bool,
        cutting: np.ndarray | bool,
        switch: np.ndarray,
        out: np.ndarray,
    ) -> np.ndarray:
        """Cost of moves, in ``out``: inf for a move that would need a jump on a cutting move
        (collisions not included).

        Parameters
        ----------
        size : list of ndarray
            How far each rotary axis moves (:meth:`_size`), from each state to each
            candidate. The axes are summed in order: with one or two rotary axes that is to
            the bit the sum over an axis of one array.
        regular, cutting : ndarray or bool
            Whether each move is between regular points, and whether it cuts (a bool for
            all alike).
        switch : ndarray, bool
            Whether each move switches branch.
        out : ndarray
            Of the shape all of these broadcast to.
        """
        # the largest weighted size (sizes and weights are at least 0: no need to start
        # the largest from 0), plus the travel
        cost = np.multiply(size[0], self.weights[0], out=out)
        travel = _total(size)
        if len(size) > 1:
            weighted = np.empty_like(size[0])
            for s, w in zip(size[1:], self.weights[1:], strict=True):
                np.maximum(cost, np.multiply(s, w, out=weighted), out=cost)
        cost += travel
        # the branches meet only at singular points; a switch between two regular points
        # turns the first axis by about half a turn within one block unless the tilt is small
        # (the path passes close to the pole there)
        if self.switch_cost and regular is not False:  # (adding 0 elsewhere)
            switch_cost = np.where(switch, self.switch_cost, 0.0)
            cost += switch_cost if regular is True else switch_cost * np.asarray(regular, float)
        # a jump no subdivision can follow while cutting: a switch that swings the axes, or a
        # limited axis turning the long way round
        if regular is False or cutting is False:
            return cost
        jump = switch & (travel > JUMP)
        for s, cont in zip(size, self.cont, strict=True):
            if not cont:
                jump |= s > np.pi
        if regular is not True:
            jump &= regular
        if cutting is not True:
            jump &= cutting
        np.putmask(cost, jump, np.inf)
        return cost

    def usable(self) -> np.ndarray:
        return self.ok & ~self.exclude.state

    def first_state(self) -> tuple[np.ndarray, np.ndarray]:
        """Cost and actual angles of each candidate at the first point."""
        state = self.values[0].copy()
        state[:, 0] = np.where(np.isnan(state[:, 0]), self.start[0], state[:, 0])
        cont = self.cont
        state[:, cont] += TWO_PI * np.round((self.start[cont] - state[:, cont]) / TWO_PI)
        cost = np.where(self.usable()[0], self.pref_cost[0], np.inf)
        if self.fixed_start:
            # only the candidates with the start's angles, which they take exactly
            same = np.all(np.abs(state - self.start) <= _SAME_ANGLE, axis=1)
            cost = np.where(same & np.isfinite(cost), 0.0, np.inf)
            state[same] = self.start
        return cost, state

    def steps(self, i: int, state: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Moves from every state (rows) to every candidate at point ``i`` (columns).

        Returns
        -------
        diff : ndarray, shape (S, K, r), rad
            Limited axes land on the candidate, continuous ones take the shortest rotation to
            it, an undetermined angle holds.
        cost : ndarray, shape (S, K)
            Inf for a move that would need a jump on a cutting move, or that collides.
        """
        diff = self._diff(i, state)
        size = np.abs(diff)
        regular = not (self.singular[i] or self.singular[i - 1])
        cost = self._move_cost(
            [size[..., a] for a in range(size.shape[2])],
            regular,
            bool(self.cutting[i]),
            self.switch,
            np.empty(self.switch.shape),
        )
        for kp, k in self.exclude.moves.get(i, ()):
            cost[kp, k] = np.inf
        return diff, cost

    def rewind_steps(self, i: int, state: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Rewinds at point ``i`` from each arrival state (rows) to each candidate (columns)."""
        diff = self._diff(i, state)
        size = np.abs(diff)
        cost = REWIND_COST + _total([size[..., a] for a in range(size.shape[2])])
        diag = np.arange(len(cost))
        cost[diag, diag] = np.inf
        for ki, k in self.exclude.rewinds.get(i, ()):
            cost[ki, k] = np.inf
        return diff, cost

    def rewinds_at(self, idx: np.ndarray) -> np.ndarray:
        """Whether a rewind may follow the arrival at points ``idx`` (the move on cuts)."""
        nxt = np.minimum(idx + 1, len(self.cutting) - 1)
        return (idx + 1 < len(self.cutting)) & self.cutting[nxt]


_MIN_PLUS_BLOCK = (8, 512)  # smallest and largest block of the blocked recursion, points


def _min_plus(a: np.ndarray, b: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """Min-plus products of matrices stacked along the last axis, (K, K, j) x (K, K, j) ->
    (K, K, j).

    One sum and one minimum per inner index, each over all matrices at once (the minimum is
    exact, so the order does not matter). ``out`` must not overlap ``a`` or ``b``.
    """
    out = np.add(a[:, :1], b[None, 0], out=out)
    if len(a) > 1:
        term = np.empty_like(out)
        for t in range(1, len(a)):
            np.minimum(out, np.add(a[:, t : t + 1], b[None, t], out=term), out=out)
    return out


def _min_arg(
    cost: np.ndarray, step: np.ndarray, out: np.ndarray, arg: np.ndarray, scratch: np.ndarray
) -> None:
    """Least ``cost[s] + step[s, k]`` over the rows s, with the first row that gives it (what
    ``argmin`` picks), for matrices stacked along the last axis.

    Parameters
    ----------
    cost : ndarray, shape (K, j)
    step : ndarray, shape (K, K, j)
    out : ndarray, shape (K, j)
        Filled with the least costs.
    arg : ndarray, shape (K, j), int
        Filled with their rows.
    scratch : ndarray, shape (K, j)
    """
    np.add(cost[0], step[0], out=out)
    arg.fill(0)
    for s in range(1, len(cost)):
        term = np.add(cost[s], step[s], out=scratch)
        np.copyto(arg, s, where=term < out)
        np.minimum(out, term, out=out)


def _viterbi(
    p: _Plan, block: int | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, int]:
    """Least-cost candidates over the whole path, with rewinds where needed.

    The recursion over the points, ``cost_i[k] = min_s cost_{i-1}[s] + step_i[s, k]`` (then the
    rewind layer at the point), is a chain of min-plus products of the step matrices. Where a
    step's costs do not depend on the path (neither end holds an undetermined angle and no
    collision excluded a move there), they are computed for many points at once, and the
    chain is evaluated in blocks: the min-plus product of each block's steps (all blocks at
    once, one point of each per array operation), then the costs at the block starts (one
    small product per block, in order), then each block again from its start cost, recording
    the best predecessors (all blocks at once). Blocks with path-dependent steps are run point
    by point from their start state. The predecessors are followed back the same way (maps
    composed per block), and the actual (unwrapped) angles are rebuilt along the chosen path.

    With a few candidates per point numpy's cost is per operation, not per number: the step
    matrices of the blocks done at once are laid out step by step with the blocks last
    (:class:`_Steps`), so that each operation of the block passes runs along all blocks in
    contiguous memory, and they are made a few thousand entries per operation (temporaries
    in cache). The layout changes no number: each is the same operations in the same order.

    Parameters
    ----------
    p : _Plan
    block : int, optional
        Points per block (default about the square root of the path length).

    Returns
    -------
    chosen : ndarray, shape (n,), int
        Candidate the path leaves each point with.
    arrive : ndarray, shape (n,), int
        Candidate it arrives with (differs at rewinds).
    rot_leave, rot_arrive : ndarray, shape (n, r), rad
        The actual (unwrapped) angles.
    settled : int
        The last point whose choice no later CL points could change (-1: none; see
        :func:`_follow_back`).
    """
    n, n_cand, _ = p.values.shape
    usable = p.usable()
    cost0, state0 = p.first_state()
    back = np.zeros((n, n_cand), dtype=np.int32)
    rback = np.full((n, n_cand), -1, dtype=np.int32)
    held = np.zeros(n, dtype=bool)  # a usable candidate holds an undetermined angle
    for k in range(n_cand):
        held |= _rows_any(np.isnan(p.values[:, k])) & usable[:, k]
    irregular = np.zeros(n, dtype=bool)  # steps into these points depend on the path
    irregular[1:] = held[1:] | held[:-1]
    irregular[list(p.exclude.moves) + list(p.exclude.rewinds)] = True
    irregular[0] = False
    if block is None:
        block = int(np.clip(np.sqrt(n), *_MIN_PLUS_BLOCK))
    first = np.arange(1, n, block)  # first step of each block
    last = np.minimum(first + block, n)  # one past its last
    seq = np.logical_or.reduceat(irregular, first) if len(first) else np.zeros(0, dtype=bool)
    bulk = np.flatnonzero(~seq)
    product_of = np.cumsum(~seq) - 1  # block -> its product (bulk blocks)
    # the bulk blocks in runs whose step matrices fit in _CACHE_BYTES: one run has them
    # computed once for both passes, several have them computed again for the second
    size = max(1, int(_CACHE_BYTES // (block * _Steps.bytes_per_step(n_cand))))
    runs = [slice(a, a + size) for a in range(0, len(bulk), size)]
    products = np.empty((len(bulk), n_cand, n_cand))
    kept: _Steps | None = None
    for run in runs:
        kept = _Steps(p, usable, first[bulk[run]], last[bulk[run]])
        products[run] = _block_products(kept)
    # costs at the block starts, in order
    starts = np.empty((len(first), n_cand))
    cost, state = cost0, state0
    for b, (a, e) in enumerate(zip(first, last, strict=True)):
        starts[b] = cost
        if not seq[b]:
            new = (cost[:, None] + products[product_of[b]]).min(axis=0)
            if np.isfinite(new).any():
                cost, state = new, p.values[e - 1]
                continue
        # path-dependent steps, or a dead end to locate: point by point
        cost, state = _sequential(p, usable, a, e, cost, state, back, rback)
    ends = np.empty((len(bulk), n_cand))
    for run in reversed(runs):  # the last run first: its step matrices are still there
        steps = kept or _Steps(p, usable, first[bulk[run]], last[bulk[run]])
        kept = None
        ends[run] = _block_steps(steps, starts[bulk[run]], back, rback)
    if len(first) and not seq[-1]:
        cost = ends[-1]  # the recorded arithmetic, which the predecessors follow
    chosen, arrive, settled = _follow_back(
        int(np.argmin(cost)), back, rback, block, np.isfinite(cost)
    )
    rot_leave, rot_arrive = _angles_along(p, state0, chosen, arrive)
    return chosen, arrive, rot_leave, rot_arrive, settled


def _sequential(
    p: _Plan,
    usable: np.ndarray,
    lo: int | np.integer,
    hi: int | np.integer,
    cost: np.ndarray,
    state: np.ndarray,
    back: np.ndarray,
    rback: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """The recursion point by point over steps ``lo..hi-1`` from ``cost`` and the actual
    angles ``state`` (K, r) at point ``lo - 1``; fills ``back`` and ``rback`` there."""
    cols = np.arange(len(cost))
    may_rewind = p.rewinds_at(np.arange(lo, hi))
    for i in range(lo, hi):
        diff, step = p.steps(i, state)
        total = cost[:, None] + step
        best = np.argmin(total, axis=0)
        arrive_cost = np.where(usable[i], total[best, cols] + p.pref_cost[i], np.inf)
        arrive_state = state[best] + diff[best, cols]
        back[i] = best
        cost, state = arrive_cost, arrive_state
        if may_rewind[i - lo] and np.isfinite(arrive_cost).any():
            rdiff, rstep = p.rewind_steps(i, arrive_state)
            rtotal = arrive_cost[:, None] + rstep
            rbest = np.argmin(rtotal, axis=0)
            rcost = np.where(usable[i], rtotal[rbest, cols], np.inf)
            take = rcost < arrive_cost
            if take.any():
                rback[i] = np.where(take, rbest, -1)
                cost = np.where(take, rcost, arrive_cost)
                state = np.where(take[:, None], arrive_state[rbest] + rdiff[rbest, cols], state)
        if not np.isfinite(cost).any():
            _raise_dead_end(p, i)
    return cost, state


_CACHE_BYTES = 256e6  # step matrices kept between the passes when they fit in this
_CHUNK = 32768  # array entries per operation in the element-wise passes (temporaries in cache)
_COPY = 262144  # array entries per copy when laying arrays out anew


def _by_step(a: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """``a[rows]`` laid out step by step with the blocks last: ``out[j, ..., b]`` is
    ``a[rows[b, j]]``.

    Gathered and moved a few blocks at a time, so that what is read and written stays in the
    cache and the address translation buffers (a point's neighbours along the path are far
    apart in the result).
    """
    out = np.empty((rows.shape[1], *a.shape[1:], rows.shape[0]), dtype=a.dtype)
    per = max(1, _COPY // max(1, rows.shape[1] * a[0].size))
    for lo in range(0, len(rows), per):
        out[..., lo : lo + per] = np.moveaxis(np.take(a, rows[lo : lo + per], axis=0), 0, -1)
    return out


def _blocks_last(a: np.ndarray) -> np.ndarray:
    """The first axis of ``a`` (the blocks) moved last, as a new array, a few blocks at a
    time (as :func:`_by_step`)."""
    out = np.empty((*a.shape[1:], a.shape[0]), dtype=a.dtype)
    per = max(1, _COPY // max(1, a[0].size))
    for lo in range(0, len(a), per):
        out[..., lo : lo + per] = np.moveaxis(a[lo : lo + per], 0, -1)
    return out


def _blocks_first(a: np.ndarray) -> np.ndarray:
    """The last axis of ``a`` (the blocks) moved first, as a new array, a few blocks at a
    time (as :func:`_by_step`)."""
    out = np.empty((a.shape[-1], *a.shape[:-1]), dtype=a.dtype)
    per = max(1, _COPY // max(1, out[0].size))
    for lo in range(0, len(out), per):
        out[lo : lo + per] = np.moveaxis(a[..., lo : lo + per], -1, 0)
    return out


class _Steps:
    """Step matrices of a run of blocks whose steps do not depend on the path (neither end
    holds an undetermined angle), laid out step by step with the blocks last (``move[j, s,
    k, b]``: step ``j`` of block ``b``), so that each step of the block passes takes slices
    and works along the blocks. The blocks are as long as the first but the last, which may
    be shorter: the first ``count[j]`` have a step ``j``.

    Attributes
    ----------
    move : ndarray, shape (J, K, K, B)
        Move costs (without the preference cost of the candidate).
    layer : ndarray, shape (J, K, K, B), or None
        Rewind layers: 0 on the diagonal (no rewind), the rewind costs into usable
        candidates elsewhere where a rewind may follow, inf otherwise; None where no rewind
        may follow in the run.
    rewinds : ndarray, shape (J,), bool
        Whether a rewind may follow step ``j`` in some block.
    pref : ndarray, shape (J, K, B)
        Preference costs of the candidates.
    unusable : ndarray, shape (J, K, B), bool
    count : ndarray, shape (J,), int
    first, last : ndarray, shape (B,), int
        The blocks' first steps and one past their last.
    """

    def __init__(self, p: _Plan, usable: np.ndarray, first: np.ndarray, last: np.ndarray) -> None:
        self.first, self.last = first, last
        n_cand, r = p.values.shape[1:]
        n_steps = int((last - first).max(initial=0))
        steps = np.arange(n_steps + 1)
        # the point before each block and its points (past its end: its last point)
        rows = np.minimum(first[:, None] - 1 + steps, (last - 1)[:, None])
        at = np.ascontiguousarray(rows.T)  # step by step
        inside = steps[:-1] < (last - first)[:, None]
        self.count = inside.sum(axis=0)
        singular = p.singular[at]
        regular = ~(singular[1:] | singular[:-1])
        cutting = p.cutting[at[1:]]
        may = p.rewinds_at(at[1:]) & inside.T
        self.rewinds = may.any(axis=1)
        self.pref = _by_step(p.pref_cost, rows[:, 1:])
        self.unusable = _by_step(usable, rows[:, 1:])
        np.logical_not(self.unusable, out=self.unusable)
        self.move = np.empty((n_steps, n_cand, n_cand, len(first)))
        self.layer = np.empty_like(self.move) if may.any() else None
        switch = p.switch[:, :, None]
        k = np.arange(n_cand)
        per = max(1, _CHUNK // (n_cand * n_cand * len(first)))
        for lo in range(0, n_steps, per):
            s = slice(lo, min(lo + per, n_steps))
            values = np.take(p.values, at[s.start : s.stop + 1], axis=0)  # (j + 1, B, K, r)
            values = np.ascontiguousarray(np.moveaxis(values, 1, -1))
            here, prev = values[1:], values[:-1]
            nan = bool(np.isnan(here).any() or np.isnan(prev).any())
            size = [p._size(here[:, None, :, a] - prev[:, :, None, a], a, nan) for a in range(r)]
            p._move_cost(size, regular[s, None, None], cutting[s, None, None], switch, self.move[s])
            if self.layer is None:
                continue
            layer = self.layer[s]
            if may[s].any():
                size = [
                    p._size(here[:, None, :, a] - here[:, :, None, a], a, nan) for a in range(r)
                ]
                np.add(REWIND_COST, _total(size), out=layer)
                np.copyto(layer, np.inf, where=~may[s, None, None])
                np.copyto(layer, np.inf, where=self.unusable[s, None])
            else:
                layer.fill(np.inf)
            layer[:, k, k] = 0.0

    @staticmethod
    def bytes_per_step(n_cand: int) -> int:
        """Memory a step of one block takes (its matrices, costs and indices), bytes."""
        return 16 * n_cand * n_cand + 9 * n_cand + 24


def _block_products(s: _Steps) -> np.ndarray:
    """Min-plus product of the steps of each block (moves, preference costs, rewinds), all
    blocks at once, shape (B, K, K)."""
    n_cand, n_blocks = s.move.shape[2:]
    eye = np.eye(n_cand, dtype=bool)[:, :, None]
    out = np.where(eye, 0.0, np.inf).repeat(n_blocks, axis=2)
    step, turned, product = np.empty_like(out), np.empty_like(out), np.empty_like(out)
    for j, c in enumerate(s.count):
        move = np.add(s.move[j, ..., :c], s.pref[j, None, :, :c], out=step[..., :c])
        np.copyto(move, np.inf, where=s.unusable[j, None, :, :c])
        if s.layer is not None and s.rewinds[j]:
            move = _min_plus(move, s.layer[j, ..., :c], out=turned[..., :c])
        out[..., :c] = _min_plus(out[..., :c], move, out=product[..., :c])
    return _blocks_first(out)


def _block_steps(s: _Steps, starts: np.ndarray, back: np.ndarray, rback: np.ndarray) -> np.ndarray:
    """The recursion within each block from its start cost (``starts``, shape (B, K)), all
    blocks at once; fills ``back`` and ``rback`` (same arithmetic as :func:`_sequential`)
    and returns the costs at the blocks' last points, shape (B, K).

    The rewind layer's zero diagonal stands for no rewind: a rewind is taken where it is
    cheaper than arriving, as in :func:`_sequential`, whose diagonal is inf."""
    cost = starts.T.copy()
    back_s = np.zeros(s.pref.shape, dtype=back.dtype)
    rback_s = np.full_like(back_s, -1)
    arrive, rcost, scratch = np.empty_like(cost), np.empty_like(cost), np.empty_like(cost)
    best = np.empty(cost.shape, dtype=np.intp)
    for j, c in enumerate(s.count):
        _min_arg(cost[:, :c], s.move[j, ..., :c], arrive[:, :c], best[:, :c], scratch[:, :c])
        back_s[j, :, :c] = best[:, :c]
        arrive[:, :c] += s.pref[j, :, :c]
        np.copyto(arrive[:, :c], np.inf, where=s.unusable[j, :, :c])
        if s.layer is not None and s.rewinds[j]:
            _min_arg(arrive[:, :c], s.layer[j, ..., :c], rcost[:, :c], best[:, :c], scratch[:, :c])
            np.copyto(rback_s[j, :, :c], best[:, :c], where=rcost[:, :c] < arrive[:, :c])
            np.minimum(arrive[:, :c], rcost[:, :c], out=arrive[:, :c])
        cost[:, :c] = arrive[:, :c]
    # back into point order, a run of adjacent blocks at a time (all as long as the first
    # but the last)
    back_b, rback_b = _blocks_first(back_s), _blocks_first(rback_s)
    n_cand = back.shape[1]
    cut = np.flatnonzero(s.first[1:] != s.last[:-1]) + 1
    for lo, hi in zip(np.r_[0, cut], np.r_[cut, len(s.first)], strict=True):
        a, e = s.first[lo], s.last[hi - 1]
        back[a:e] = back_b[lo:hi].reshape(-1, n_cand)[: e - a]
        rback[a:e] = rback_b[lo:hi].reshape(-1, n_cand)[: e - a]
    return cost.T


def _follow_back(
    k_end: int, back: np.ndarray, rback: np.ndarray, block: int, alive: np.ndarray
) -> tuple[np.ndarray, np.ndarray, int]:
    """Candidates along the best path from the last point's ``k_end``, back to the first, and
    how far the paths into every ``alive`` candidate of the last point agree.

    At each point ``i`` the path leaves with ``chosen[i]``, arrived with ``arrive[i]``
    (``rback`` where a rewind was taken) and came from ``back[i, arrive[i]]``. The maps from
    the candidate at a block's last point to that before its first are composed for all
    blocks at once, followed block by block, then every block is walked at once. The blocks
    end at the last point; the first is filled up with points that keep the candidate.

    The best paths into the alive candidates of the last point (the survivors) are followed
    back as a set, block by block and then step by step in the block where they meet: once
    two meet they agree on every point before. Whatever points came after the last one, the
    best path over them all would continue one of the survivors, so its choices up to the
    point where all survivors agree are these (the choice there is settled).

    Returns
    -------
    chosen, arrive : ndarray, shape (n,), int
    settled : int
        The last point where every survivor leaves with the same candidate (-1: none).
    """
    n, n_cand = back.shape
    keep = np.arange(n_cand)
    rewound = rback >= 0
    arrive_of = np.where(rewound, rback, keep[None, :]) if rewound.any() else None  # (n, K)
    # leave at i -> leave at i - 1
    came = back if arrive_of is None else np.take_along_axis(back, arrive_of, axis=1)
    n_blocks = -(-n // block)
    pad = n_blocks * block - n
    maps = np.empty((n_blocks * block, n_cand), dtype=came.dtype)
    maps[:pad] = keep
    maps[pad:] = came
    maps = _blocks_last(maps.reshape(n_blocks, block, n_cand))  # [j, :, b]: step j of block b
    at = np.arange(n_blocks)  # each block's column in a step's flattened maps
    # composed maps: leave at a block's last point -> leave at the point before its first
    comp = np.repeat(keep[:, None], n_blocks, axis=1)
    for j in range(block - 1, -1, -1):
        comp = np.take(maps[j], comp * n_blocks + at)
    ends = np.empty(n_blocks, dtype=np.int64)
    k = k_end
    for b in range(n_blocks - 1, -1, -1):
        ends[b] = k
        k = int(comp[k, b])
    settled = _settled(np.flatnonzero(alive), comp, maps, block, pad)
    chosen = np.empty((block, n_blocks), dtype=np.int64)
    cur = ends
    for j in range(block - 1, -1, -1):
        chosen[j] = cur
        cur = np.take(maps[j], cur * n_blocks + at)
    leave = _blocks_first(chosen).reshape(-1)[pad:]
    if arrive_of is None:
        return leave, leave.copy(), settled
    return leave, np.take(arrive_of, leave + np.arange(n) * n_cand), settled


def _settled(
    survivors: np.ndarray, comp: np.ndarray, maps: np.ndarray, block: int, pad: int
) -> int:
    """The last point where the paths into ``survivors`` (candidates at the last point) all
    leave with the same candidate, -1 when they never do (:func:`_follow_back`'s maps:
    ``comp[:, b]`` over block b, ``maps[j][k, b]`` over its step j, ``pad`` points of filling
    before the first)."""
    n_blocks = comp.shape[1]
    last = n_blocks * block - 1 - pad
    if len(survivors) <= 1:
        return last
    at = survivors
    for b in range(n_blocks - 1, -1, -1):
        before = np.unique(comp[at, b])
        if len(before) > 1:
            at = before
            continue
        for j in range(block - 1, -1, -1):  # they meet in block b: where
            if len(at) == 1:
                return max(b * block + j - pad, -1)
            at = np.unique(maps[j][at, b])
        return max(b * block - 1 - pad, -1)
    return -1


def _angles_along(
    p: _Plan, state0: np.ndarray, chosen: np.ndarray, arrive: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Actual rotary angles along the chosen path, shapes (n, r) each (leave, arrive).

    The path arrives at each point and leaves it (after a rewind, on another candidate). Along
    that sequence limited axes take the candidates' values, an undetermined angle holds the
    last determined one, and continuous axes take the shortest rotation from the previous
    value (the first point starts from ``state0``, the candidate's angles nearest the start).
    A point without a rewind is one state in the sequence: the step from arriving to leaving
    it would be zero, and adds nothing to the running sums.
    """
    n, n_cand, r = p.values.shape
    flat = p.values.reshape(-1, r)
    at = np.arange(n) * n_cand
    turn = chosen != arrive  # never at the first point
    into = out = None
    if turn.any():
        into = np.arange(n) + np.cumsum(turn) - turn  # where each arrival is in the sequence
        out = into + turn
        seq = np.empty((n + int(turn.sum()), r))
        seq[into] = np.take(flat, at + arrive, axis=0)
        seq[out] = np.take(flat, at + chosen, axis=0)
    else:
        seq = np.take(flat, at + chosen, axis=0)
    seq[0] = state0[chosen[0]]
    for a in range(r):
        known = ~np.isnan(seq[:, a])
        if known.all():
            continue
        seq[:, a] = seq[np.maximum.accumulate(np.where(known, np.arange(len(seq)), 0)), a]
    for c in np.flatnonzero(p.cont):
        col = seq[:, c]
        col[1:] = col[0] + np.cumsum(_wrap(np.diff(col)))
    if into is None or out is None:
        return seq, seq.copy()
    return seq[out], seq[into]


def _greedy(p: _Plan) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Each point takes the candidate nearest the previous point's angles; where no candidate
    goes on continuously, a rewind at the previous point to the candidate that does."""
    n, _, r = p.values.shape
    usable = p.usable()
    cost0, state0 = p.first_state()
    k = int(np.argmin(cost0))
    cur = state0[k].copy()
    leave = np.empty((n, r))
    arrive_rot = np.empty((n, r))
    chosen = np.empty(n, dtype=np.int64)
    arrive = np.empty(n, dtype=np.int64)
    leave[0] = arrive_rot[0] = cur
    chosen[0] = arrive[0] = k
    for i in range(1, n):
        diff, step = p.steps(i, cur[None, :])
        step = np.where(usable[i], step[0] + 1e-9 * p.branch, np.inf)
        if not np.isfinite(step).any():
            # rewind at the previous point onto a candidate that goes on from there
            rdiff, rcost = p.rewind_steps(i - 1, cur[None, :])
            rcost = np.where(usable[i - 1], rcost[0], np.inf)
            for kk in np.argsort(rcost):
                if not np.isfinite(rcost[kk]):
                    break
                turned = cur + rdiff[0, kk]
                d2, s2 = p.steps(i, turned[None, :])
                s2 = np.where(usable[i], s2[0], np.inf)
                if np.isfinite(s2).any():
                    chosen[i - 1] = kk
                    leave[i - 1] = cur = turned
                    diff, step = d2, s2
                    break
            else:
                _raise_dead_end(p, i)
        k = int(np.argmin(step))
        cur = cur + diff[0, k]
        leave[i] = arrive_rot[i] = cur
        chosen[i] = arrive[i] = k
    return chosen, arrive, leave, arrive_rot


def _raise_dead_end(p: _Plan, i: int) -> None:
    """Error for a point no candidate reaches (collisions or no continuous way on)."""
    line = f"{p.source}:{int(p.lines[i])}"
    # one candidate per branch (their 360-degree multiples are the same pose)
    size = np.abs(np.nan_to_num(p.values[i])).sum(axis=1)
    per_branch = {int(p.branch[k]): int(k) for k in np.flatnonzero(p.ok[i])[::-1]}
    for k in np.flatnonzero(p.ok[i]):
        b = int(p.branch[k])
        if size[k] < size[per_branch[b]]:
            per_branch[b] = int(k)
    why = [
        f"branch {_label(p.machine, p.values[i, k])}: {a} collides with {b}"
        for k in sorted(per_branch.values())
        for a, b in [p.exclude.why.get((i, k), (None, None))]
        if a is not None
    ]
    moves = [
        f"the move there collides: {a} with {b}"
        for (j, _kp, _k), (a, b) in p.exclude.move_why.items()
        if j == i
    ]
    if why and len(why) == len(per_branch):
        raise CollisionError(f"{line}: every branch collides: {'; '.join(why)}")
    if why or moves:
        raise CollisionError(f"{line}: no collision-free way on: {'; '.join(why + moves[:2])}")
    raise UnreachableError(
        f"{line}: no continuous solution reaches this point within the travel of machine "
        f"{p.machine.name}, and no rewind is possible before it"
    )


def _exclude_colliding_states(
    p: _Plan, world: CollisionWorld, q: np.ndarray, pole: np.ndarray
) -> None:
    """Mark the candidates that collide at their point (every 360-degree multiple of a branch
    is the same pose). At poles the held angle is not known yet: the chosen path's check
    covers them."""
    for b in range(q.shape[1]):
        rows = np.flatnonzero(~np.isnan(q[:, b]).any(axis=1) & ~pole)
        if not len(rows):
            continue
        res = world.check(q[rows, b])
        for i, pair in zip(
            rows[res.hit], [res.pairs[k] for k in np.flatnonzero(res.hit)], strict=True
        ):
            for k in np.flatnonzero(p.branch == b):
                if p.ok[i, k]:
                    p.exclude.state[i, k] = True
                    # (the pair of a configuration that hits is never None)
                    p.exclude.why[(int(i), int(k))] = pair  # type: ignore[assignment]


def rewind_rows(
    machine: Machine,
    q_from: np.ndarray,
    q_to: np.ndarray,
    tip: np.ndarray,
    axis: np.ndarray,
    tool_length: float,
    retract: float,
) -> np.ndarray:
    """Joint vectors of a rewind at one point: lift, turn, return.

    Parameters
    ----------
    q_from, q_to : ndarray, shape (m,)
        The configuration the path arrives with and the one it leaves with (same tool pose).
    tip, axis : ndarray, shape (3,)
        The point, mm, and its tool axis.
    tool_length, retract : float, mm

    Returns
    -------
    ndarray, shape (4, m)
        ``q_from`` lifted by ``retract`` along the tool axis, ``q_to`` lifted, ``q_to``; the
        path goes from ``q_from`` through these.
    """
    cols = list(machine.rotary_columns)
    rot = np.stack([q_from[cols], q_to[cols]])
    up = np.repeat((tip + retract * axis)[None, :], 2, axis=0)
    lifted = assemble(machine, rot, solve_linear(machine, rot, up, tool_length))
    return np.vstack([lifted, q_to[None, :]])


def _exclude_colliding_moves(
    p: _Plan,
    world: CollisionWorld,
    q: np.ndarray,
    q_arrive: np.ndarray,
    chosen: np.ndarray,
    arrive_k: np.ndarray,
    tip: np.ndarray,
    axis: np.ndarray,
    tool_length: float,
    retract: float,
) -> bool:
    """Check the chosen path's configurations and moves; exclude what collides.

    Returns
    -------
    bool
        Whether anything was excluded (the path must be planned again).
    """
    n = len(q)
    found = False
    # the path: arrive at each point, then (at rewinds) lift, turn, return
    rows = [q_arrive[:1]]
    into: list[tuple[str, int]] = []  # what each move of the path is
    for i in range(n):
        if i:
            rows.append(q_arrive[i : i + 1])
            into.append(("move", i))
        if chosen[i] != arrive_k[i]:
            rows.append(
                rewind_rows(p.machine, q_arrive[i], q[i], tip[i], axis[i], tool_length, retract)
            )
            into += [("rewind", i)] * 3
    path = np.vstack(rows)
    lo, hi = p.machine.lower - _SLACK, p.machine.upper + _SLACK
    res = world.check_moves(path)
    bad = np.flatnonzero(res.hit)
    outside = np.flatnonzero(((path[1:] < lo) | (path[1:] > hi)).any(axis=1))
    for m in np.concatenate([bad, outside]):
        kind, i = into[int(m)]
        pair = res.pairs[int(m)] or ("lifted tool", "travel limit")
        if kind == "move":
            key = (int(chosen[i - 1]), int(arrive_k[i]))
            p.exclude.moves.setdefault(i, set()).add(key)
            p.exclude.move_why[(i, *key)] = pair
        else:
            key = (int(arrive_k[i]), int(chosen[i]))
            p.exclude.rewinds.setdefault(i, set()).add(key)
            p.exclude.move_why[(i, *key)] = pair
        found = True
    return found


def _exclusion_notes(p: _Plan, chosen: np.ndarray, arrive_k: np.ndarray) -> list[str]:
    """One note per run of points where a collision decided the branch."""
    notes: list[str] = []
    excluded = _rows_any(p.exclude.state)
    runs = np.flatnonzero(excluded & ~np.r_[False, excluded[:-1]])
    for i in runs:
        k_bad = int(np.flatnonzero(p.exclude.state[i])[0])
        a, b = p.exclude.why[(int(i), k_bad)]
        end = i
        while end + 1 < len(excluded) and excluded[end + 1]:
            end += 1
        notes.append(
            f"{p.source}:{int(p.lines[i])}: branch {_label(p.machine, p.values[i, k_bad])} "
            f"collides ({a} with {b}) through line {int(p.lines[end])}; took "
            f"{_label(p.machine, p.values[i, int(chosen[i])])}"
        )
    for (at, _kp, _k), (a, b) in p.exclude.move_why.items():
        notes.append(
            f"{p.source}:{int(p.lines[at])}: a move there collides ({a} with {b}); re-planned"
        )
    return notes


def _check_linear(
    machine: Machine, q: np.ndarray, pole: np.ndarray, lines: np.ndarray, source: str
) -> None:
    """Linear travel at the poles (where it was unknown before the angle was held)."""
    cols = list(machine.linear_columns)
    lo, hi = machine.lower[cols] - _SLACK, machine.upper[cols] + _SLACK
    at = np.flatnonzero(pole)
    bad = ((q[at][:, cols] < lo) | (q[at][:, cols] > hi)).any(axis=1)
    if bad.any():
        i = int(at[np.argmax(bad)])
        j = int(np.argmax((q[i, cols] < lo) | (q[i, cols] > hi)))
        a = machine.linear[j]
        raise UnreachableError(
            f"{source}:{int(lines[i])}: axis {a.name} would need {q[i, cols[j]]:.3f} mm, outside "
            f"its travel {a.lower:.3f}..{a.upper:.3f} mm"
        )
