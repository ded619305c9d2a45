"""The state of the branch search: the candidates, their costs and what collisions excluded.

:class:`BranchSearch` is built by :func:`urdfpost.planning.branches.search.select` and read by
the engine (:mod:`~urdfpost.planning.branches.engine`) and by the collision exclusion
(:mod:`~urdfpost.planning.branches.exclusion`); it imports neither.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from urdfpost.machine import Machine
from urdfpost.planning.branches._arrays import _total
from urdfpost.planning.branches.costs import JUMP, REWIND_COST
from urdfpost.planning.branches.rules import _SAME_ANGLE, TWO_PI, _wrap


@dataclass
class _Exclusions:
    """What the collision checks ruled out, indexed by point and candidate."""

    state: np.ndarray  # (n, K) bool: candidate collides at the point
    why: dict[tuple[int, int], tuple[str, str]] = field(default_factory=dict)
    moves: dict[int, set[tuple[int, int]]] = field(default_factory=dict)  # i -> (k_prev, k)
    rewinds: dict[int, set[tuple[int, int]]] = field(default_factory=dict)  # i -> (k_in, k_out)
    move_why: dict[tuple[int, int, int], tuple[str, str]] = field(default_factory=dict)


@dataclass
class BranchSearch:
    """The state of the search: the candidates of every point, their costs, what collisions
    excluded, and the costs of the moves between the candidates of neighbouring points."""

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
