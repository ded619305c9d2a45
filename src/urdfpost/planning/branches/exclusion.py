"""Collision exclusion: candidates and moves that collide are taken out of the search.

Two checks (:func:`urdfpost.planning.branches.select`): before planning, every candidate
configuration at its point (:func:`_exclude_colliding_states`); after, the moves and rewinds of
the chosen path (:func:`_exclude_colliding_moves`), which is then planned again without what
collided, at most :data:`_MAX_COLLISION_ROUNDS` times. What was excluded, and why, is kept in
the search's :class:`_Exclusions`: for the report (:func:`_exclusion_notes`) and for the error
where no way on is left (:func:`_raise_dead_end`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from urdfpost.errors import CollisionError, UnreachableError
from urdfpost.planning.branches._arrays import _rows_any
from urdfpost.planning.branches.rules import _SLACK, _label
from urdfpost.planning.branches.state import BranchSearch
from urdfpost.planning.rewinds import rewind_rows

if TYPE_CHECKING:
    from urdfpost.collision import CollisionWorld


_MAX_COLLISION_ROUNDS = 50  # re-plans after colliding moves were found on the chosen path


def _exclude_colliding_states(
    p: BranchSearch, world: CollisionWorld, q: np.ndarray, pole: np.ndarray
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


def _exclude_colliding_moves(
    p: BranchSearch,
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


def _exclusion_notes(p: BranchSearch, chosen: np.ndarray, arrive_k: np.ndarray) -> list[str]:
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


def _raise_dead_end(p: BranchSearch, i: int) -> None:
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
