"""Rollover axes: a program's blocks made to turn them the way the path needs.

A continuous rotary axis the control rolls over (the machine's ``rollover`` setting) is
written modulo 360 (:mod:`urdfpost.dialects.writer`), and the control reaches each value the
way its dialect says (:func:`urdfpost.program.rollover_target`): the shortest way, or, on
LinuxCNC, the way of the value's sign, which the writer sets from the turn. Either way a block
cannot turn such an axis by half a turn or more. :func:`with_rollover` therefore

- splits a move that turns a rollover axis by more than ``tol.rollover_turn`` into equal
  moves, on the straight line of the program's values between its ends (the line the control
  interpolates, and the verifier measures), so that each turns less than half a turn in the
  direction the path takes;
- lets a positioning move (a rapid that gives no linear axis: the rotary axes turning on their
  own, retracted, before an approach or at the end) and a machine-coordinate move take the
  shortest way, as the control does: the end no longer unwinds the turns the job wound up. The
  values after such a move are shifted by the whole turns it saved, which changes no pose.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np

from urdfpost.program import Block, Home, MachineMove, Move, MoveTable
from urdfpost.tolerances import Tolerances


def _shortest(previous: float, target: float) -> float:
    """``target`` moved by whole turns to within half a turn of ``previous`` (degrees)."""
    if math.isnan(previous) or math.isnan(target):
        return target
    return previous + 180.0 - (previous - target + 180.0) % 360.0


class RolloverState:
    """Where a program's axes are while its blocks are gone through, and the whole turns saved.

    Parameters
    ----------
    axes : tuple of str
        The program's axes.
    rollover : frozenset of str
        Its rollover axes.
    start : ndarray, shape (m,), optional
        Program position before the first block (mm, degrees; a streamed piece: where the
        piece before ended); default unknown (NaN).
    """

    def __init__(
        self, axes: tuple[str, ...], rollover: frozenset[str], start: np.ndarray | None = None
    ) -> None:
        self.axes = axes
        self.columns = [j for j, a in enumerate(axes) if a in rollover]
        self.linear = np.array([a in "XYZ" for a in axes])
        self.last = np.full(len(axes), np.nan) if start is None else np.array(start, float)
        self.offset = np.zeros(len(axes))  # degrees added to the values of each column
        self.splits = 0  # moves split
        self.saved = 0.0  # degrees of turning the positioning moves saved


def with_rollover(
    parts: Iterable[Block | MoveTable],
    axes: tuple[str, ...],
    rollover: frozenset[str],
    tol: Tolerances,
    start: np.ndarray | None = None,
) -> tuple[list[Block | MoveTable], RolloverState]:
    """The blocks with the rollover axes' turns as the control makes them (module docstring).

    Parameters
    ----------
    parts : iterable of Block and MoveTable
        A program body (:attr:`~urdfpost.program.Program.parts`).
    axes : tuple of str
        The program's axes.
    rollover : frozenset of str
        Its rollover axes; none: ``parts`` unchanged.
    tol : Tolerances
        ``rollover_turn``: the largest turn of one block (rad).
    start : ndarray, shape (m,), optional
        Program position before the first block (see :class:`RolloverState`).

    Returns
    -------
    parts : list of Block and MoveTable
        Moves split and shifted; other blocks as they were (machine moves shifted).
    state : RolloverState
        How many moves were split and how many degrees the positioning moves saved.
    """
    state = RolloverState(axes, rollover, start)
    if not state.columns:
        return list(parts), state
    limit = math.degrees(tol.rollover_turn)
    out: list[Block | MoveTable] = []
    for part in parts:
        if isinstance(part, MoveTable):
            out.append(_table(part, state, limit))
        elif isinstance(part, Move):
            table = _table(MoveTable.from_moves([part], len(axes)), state, limit)
            out += table.moves()
        elif isinstance(part, MachineMove):
            out.append(_machine_move(part, state))
        else:
            if isinstance(part, Home):
                state.last[:] = np.nan
            out.append(part)
    return out, state


def _machine_move(move: MachineMove, state: RolloverState) -> MachineMove:
    """A machine-coordinate move: the rollover axes the shortest way, the others unknown in
    program coordinates afterwards (as the reader takes them)."""
    values = list(move.values)
    for i, name in enumerate(move.axes):
        j = state.axes.index(name) if name in state.axes else -1
        if j < 0:
            continue
        if j in state.columns:
            target = values[i] + state.offset[j]
            values[i] = _shortest(state.last[j], target)
            state.saved += abs(target - values[i])
            state.offset[j] += values[i] - target
            state.last[j] = values[i]
        else:
            state.last[j] = np.nan
    return MachineMove(move.axes, tuple(values))


def _table(table: MoveTable, state: RolloverState, limit: float) -> MoveTable:
    """The moves of ``table``, shifted by the turns saved, positioning moves the shortest way,
    and the moves that turn a rollover axis by more than ``limit`` degrees split."""
    position = table.position.copy()
    cols = state.columns
    position[:, cols] += state.offset[cols]
    positioning = table.rapid & np.isnan(position[:, state.linear]).all(axis=1)
    start_known = ~np.isnan(_filled(position, state.last)[:-1])
    # the shortest way: positioning moves, and moves of an axis from where it is not known
    # (after a home return the control, as the reader, takes the value the shortest way)
    for j in cols:
        value_known = ~np.isnan(position[:, j])
        rows = np.flatnonzero(value_known & (positioning | ~start_known[:, j]))
        for i in rows.tolist():
            before = _filled(position[:i, j : j + 1], state.last[j : j + 1])[-1, 0]
            target = position[i, j]
            shifted = _shortest(before, target)
            if shifted != target:
                position[i:, j] += shifted - target
                state.offset[j] += shifted - target
                state.saved += abs(shifted - target)
    filled = _filled(position, state.last)
    before = filled[:-1]
    state.last = filled[-1].copy()
    turn = np.abs(position[:, cols] - before[:, cols])
    turn = np.where(np.isnan(turn), 0.0, turn).max(axis=1, initial=0.0)
    pieces = np.maximum(np.ceil(turn / limit), 1).astype(np.int64)
    if (pieces == 1).all():
        return MoveTable(position, table.rapid, table.feed, table.cl_line)
    state.splits += int(np.sum(pieces > 1))
    # row i becomes pieces[i] rows: the fractions 1/n .. n/n of the way from where it starts
    owner = np.repeat(np.arange(len(position)), pieces)
    first = np.repeat(np.cumsum(pieces) - pieces, pieces)
    step = np.arange(len(owner)) - first + 1
    fraction = (step / pieces[owner])[:, None]
    start, end = before[owner], position[owner]
    # an axis the row does not give (NaN) stays unwritten on every piece
    split = np.where(np.isnan(end), np.nan, start + fraction * (end - start))
    last_piece = step == pieces[owner]
    split[last_piece] = end[last_piece]  # exactly the row's values
    cl_line = np.where(last_piece, table.cl_line[owner], -1)
    return MoveTable(split, table.rapid[owner], table.feed[owner], cl_line)


def _filled(position: np.ndarray, last: np.ndarray) -> np.ndarray:
    """Where each axis is before the first row and after each row: ``last`` (shape (m,)),
    then each column's last value that is not NaN, shape (k + 1, m)."""
    rows = np.vstack([last[None, :], position])
    have = ~np.isnan(rows)
    index = np.where(have, np.arange(rows.shape[0])[:, None], 0)
    np.maximum.accumulate(index, axis=0, out=index)
    return np.take_along_axis(rows, index, axis=0)
