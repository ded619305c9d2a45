"""The branch search: :func:`select` and its state, :class:`BranchSearch`.

:func:`select` solves the inverse kinematics of every point, keeps the candidates within travel
(:mod:`.rules`), costs them (:mod:`.costs`), plans the path over them (:mod:`.engine`: over the
whole path, or point by point for the local planner), and plans again without what collides
(:mod:`.exclusion`) until the chosen path is clear.
"""

from __future__ import annotations

import logging
from typing import TYPE_CHECKING

import numpy as np

from urdfpost.errors import CollisionError, LinearTravelError, UnreachableError
from urdfpost.kinematics.inverse import IKResult, IKStatus, assemble, inverse, solve_linear
from urdfpost.machine import Machine
from urdfpost.planning.branches._arrays import _rows_any
from urdfpost.planning.branches.costs import _point_costs, _step_weights
from urdfpost.planning.branches.engine import _greedy, _viterbi
from urdfpost.planning.branches.exclusion import (
    _MAX_COLLISION_ROUNDS,
    _exclude_colliding_moves,
    _exclude_colliding_states,
    _exclusion_notes,
    _raise_dead_end,
)
from urdfpost.planning.branches.rules import (
    Preference,
    Selection,
    _candidates,
    _check_linear,
    _linear_message,
    _linear_ok,
    _unreachable_message,
)
from urdfpost.planning.branches.state import BranchSearch, _Exclusions
from urdfpost.planning.rewinds import DEFAULT_RETRACT
from urdfpost.tolerances import Tolerances

if TYPE_CHECKING:
    from urdfpost.collision import CollisionWorld

log = logging.getLogger(__name__)


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
    ik: IKResult | None = None,
) -> Selection:
    """Choose one solution per point (the rules: :mod:`urdfpost.planning.branches`).

    Parameters
    ----------
    machine : Machine
    tip : ndarray, shape (n, 3), mm
    axis : ndarray, shape (n, 3)
    tool_length : float, mm
    prefer : Preference, optional
        None: no preferred branch (a post passes the machine file's, resolved by
        :func:`urdfpost.posting.options.resolve`).
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
    ik : IKResult, optional
        The inverse kinematics of the points where the caller has it already: what
        ``inverse(machine, tip, axis, tool_length, tol, pole_angle=0.0)`` gives (the ``cone``
        plans a path again with points inserted, and keeps the old points'); read, never
        modified. None: solved here.

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
    if ik is None:
        ik = inverse(machine, tip, axis, tool_length, tol, pole_angle=0.0)
    elif len(ik.q) != n:
        raise ValueError(f"the inverse kinematics given has {len(ik.q)} points, the path {n}")
    values, ok, branch = _candidates(machine, ik.rotary.angles, ik.rotary.valid)
    pole = ik.status == IKStatus.POLE
    # linear travel: known per branch except at poles, where it depends on the held angle
    lin_ok = _linear_ok(machine, ik.q) | pole[:, None]
    within = ok & lin_ok[:, branch]
    dead = ~_rows_any(within)
    if dead.any():
        i = int(np.argmax(dead))
        if ok[i].any():
            raise LinearTravelError(
                _linear_message(machine, ik.q[i], tip[i], int(lines[i]), source)
            )
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

    search = BranchSearch(
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
    if fixed_start and not np.isfinite(search.first_state()[0]).any():
        raise UnreachableError(
            f"{source}:{int(lines[0])}: the path cannot go on from where the part before it "
            f"ended (rotary {np.degrees(search.start).round(4).tolist()} deg): no candidate "
            "there is within travel with those angles"
        )
    if collision is not None:
        _exclude_colliding_states(search, collision, ik.q, pole)
        blocked = ~search.usable().any(axis=1)
        if blocked.any():
            _raise_dead_end(search, int(np.argmax(blocked)))
    status = ik.status
    del ik  # (its joint vectors are the largest arrays here: the planner can reuse the memory)
    for _ in range(_MAX_COLLISION_ROUNDS):
        if planner == "global":
            chosen, arrive_k, rot_leave, rot_arrive, settled = _viterbi(search)
        else:  # each choice depends on the points before it only
            chosen, arrive_k, rot_leave, rot_arrive = _greedy(search)
            settled = n - 1
        lin = solve_linear(machine, rot_leave, tip, tool_length)
        q = assemble(machine, rot_leave, lin)
        rewind = chosen != arrive_k
        q_arrive = q.copy()
        if rewind.any():
            lin_a = solve_linear(machine, rot_arrive[rewind], tip[rewind], tool_length)
            q_arrive[rewind] = assemble(machine, rot_arrive[rewind], lin_a)
        if collision is None or not _exclude_colliding_moves(
            search, collision, q, q_arrive, chosen, arrive_k, tip, axis, tool_length, retract
        ):
            break
    else:  # pragma: no cover - a path this tangled is a modelling problem
        raise CollisionError(
            f"{source}: no collision-free choice found after {_MAX_COLLISION_ROUNDS} re-plans"
        )
    _check_linear(machine, q, pole, lines, source)
    if rewind.any():
        _check_linear(machine, q_arrive, pole, lines, source)
    notes = _exclusion_notes(search, chosen, arrive_k)
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
