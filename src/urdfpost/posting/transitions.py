"""The moves off the path: the safe approach, the retract at a tool change, the end.

Every approach to the path (at the start, and after each tool change) is, as the best posts do
it:

1. TCP off, and a retract of the *retract axis* (the linear axis that moves the tool along the
   spindle, found from the URDF) to the end of its travel, in machine coordinates
   (:class:`~urdfpost.program.MachineMove`: ``G53 G0 Z..``, ``SUPA G0 Z..``, ``L Z.. R0 FMAX
   M91``);
2. the rotary axes to their values at the first point, on their own (TCP still off);
3. TCP on (TCP programs), then the linear axes to the *high point*: the approach point moved
   up the tool axis as far as the travel allows (on a machine whose tool axis is fixed in the
   machine frame, that is the approach point's X and Y with the retract axis still at its end);
4. down the tool axis to the *approach point*, ``clearance`` above the first point along its
   tool axis;
5. the CL data's own first move (a rapid stays a rapid, a feed move is the feed move onto the
   path).

At a tool change: TCP off, the retract, spindle and coolant off, then the tool change; at the
end: TCP off, the retract, the rotary axes to their home values, spindle and coolant off.

All of it is rapid, in straight lines of the joint values (with the rotary axes fixed, a TCP
move at constant orientation is a straight line of the joints too), so the joint rows kept in
:attr:`Transitions.paths` are the moves the machine makes; the post checks them for
collisions like every other move.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from urdfpost.errors import UnreachableError
from urdfpost.kinematics import linear_directions, tip_and_axis
from urdfpost.machine import Machine
from urdfpost.program import Block, Coolant, MachineMove, Move, Spindle, Tcp

DEFAULT_CLEARANCE = 10.0
"""Approach point above the first CL point, along its tool axis (mm)."""

_REACH = 1e-9  # mm: travel slack of computed positions


def retract_axis(machine: Machine) -> tuple[int, float]:
    """The linear axis that moves the tool along the spindle, and its retract position.

    The axis whose direction is nearest the tool axis at home; it retracts to the end of its
    travel that takes the tool up its axis, away from the part.

    Returns
    -------
    column : int
        Its column in :attr:`Machine.axis_names`.
    value : float
        The travel limit it retracts to, mm.

    Raises
    ------
    UnreachableError
        The machine has no linear axis along the tool axis (it cannot retract).
    """
    axis = machine.home_tool_axis
    best = max(machine.linear, key=lambda a: abs(float(a.direction @ axis)), default=None)
    if best is None or abs(float(best.direction @ axis)) < 0.5:
        raise UnreachableError(
            f"machine {machine.name}: no linear axis along the tool axis to retract with"
        )
    up = float(best.direction @ axis) > 0
    return machine.axis_names.index(best.name), float(best.upper if up else best.lower)


@dataclass
class Transitions:
    """Makes the blocks of the moves off the path, and keeps their joint rows.

    Parameters
    ----------
    machine : Machine
    tcp : bool
        TCP program (X, Y, Z are the tool tip in the workpiece frame).
    tool_length : float
        mm.
    clearance : float
        Approach point above the first point, along its tool axis, mm.
    rollover : frozenset of str
        Rotary axes the control rolls over: their positioning turns go the shortest way
        (:mod:`urdfpost.posting.rollover`), and :attr:`paths` has them so.

    Attributes
    ----------
    paths : list of (int, ndarray)
        Per transition the CL line it leads to (or leaves) and its joint rows, shape (k, m):
        the moves to check for collisions.
    """

    machine: Machine
    tcp: bool
    tool_length: float
    clearance: float = DEFAULT_CLEARANCE
    paths: list[tuple[int, np.ndarray]] = field(default_factory=list)
    rollover: frozenset[str] = frozenset()

    def __post_init__(self) -> None:
        self.column, self.top = retract_axis(self.machine)
        m = self.machine
        self._rotary = list(m.rotary_columns)
        self._linear = list(m.linear_columns)
        self._names = m.axis_names
        self._rolled = [j for j, a in enumerate(m.axis_names) if a in self.rollover]

    def _shortest(self, rows: np.ndarray, turning: int) -> np.ndarray:
        """``rows`` (joint rows, shape (k, m)) with the rollover axes from row ``turning`` on
        moved by the whole turns that make the turn into that row the shortest way (no pose
        changes: the collision check sees the turn the control makes)."""
        out = rows.copy()
        for j in self._rolled:
            step = out[turning, j] - out[turning - 1, j]
            short = math.remainder(step, 2.0 * math.pi)
            out[turning:, j] += short - step
        return out

    # -- positions ------------------------------------------------------------------------

    def _position(self, q: np.ndarray, columns: list[int]) -> tuple[float, ...]:
        """Program positions of ``q`` (deg for rotary, tip or joints for linear), NaN where
        the axis is not in ``columns``."""
        out = np.full(len(q), np.nan)
        rotary = np.array(self._rotary, dtype=int)
        out[rotary] = np.degrees(q[rotary])
        linear = np.array(self._linear, dtype=int)
        if self.tcp:
            tip, _ = tip_and_axis(self.machine, q[None, :], self.tool_length)
            out[linear] = tip[0]
        else:
            out[linear] = q[linear]
        keep = np.zeros(len(q), dtype=bool)
        keep[columns] = True
        # math.nan itself (not a new NaN), so that equal programs compare equal, as the move
        # tables' rows do (Program.moves)
        return tuple(float(v) if k else math.nan for v, k in zip(out, keep, strict=True))

    def retract_block(self) -> MachineMove:
        """The retract, in machine coordinates."""
        return MachineMove((self._names[self.column],), (self.top,))

    def _retracted(self, q: np.ndarray) -> np.ndarray:
        out = q.copy()
        out[self.column] = self.top
        return out

    def high_and_approach(self, q: np.ndarray, line: int) -> tuple[np.ndarray, np.ndarray]:
        """Joint values of the high point and the approach point above the row ``q``.

        Raises
        ------
        UnreachableError
            The approach point is outside the travel.
        """
        m = self.machine
        _, axis = tip_and_axis(m, q[None, :], self.tool_length)
        jac = linear_directions(m, q[None, :])[0]  # d tip / d linear joints, (3, 3)
        up = np.linalg.solve(jac, axis[0])  # joints per mm up the tool axis
        lin = self._linear
        approach = q.copy()
        approach[lin] += self.clearance * up
        lower, upper = m.lower[lin], m.upper[lin]
        outside = (approach[lin] < lower - _REACH) | (approach[lin] > upper + _REACH)
        if outside.any():
            j = lin[int(np.argmax(outside))]
            raise UnreachableError(
                f"CL line {line}: the approach point {self.clearance:.3f} mm above the first "
                f"point needs {self._names[j]} {approach[j]:.3f} mm, outside the travel "
                f"{m.lower[j]:.3f} .. {m.upper[j]:.3f}; a smaller --clearance may fit"
            )
        # up the tool axis from the approach point, as far as the travel and the retract allow
        with np.errstate(divide="ignore", invalid="ignore"):
            room = np.where(up > 0, (upper - approach[lin]) / up, (lower - approach[lin]) / up)
        room = np.where(np.abs(up) > 1e-12, room, np.inf)
        rc = lin.index(self.column)
        if abs(up[rc]) > 1e-12:
            room[rc] = min(room[rc], (self.top - approach[self.column]) / up[rc])
        s = max(float(room.min()), 0.0)
        high = approach.copy()
        high[lin] += s * up
        high[self.column] = min(max(high[self.column], m.lower[self.column]), m.upper[self.column])
        return high, approach

    # -- sequences --------------------------------------------------------------------------

    def approach(self, before: np.ndarray | None, q: np.ndarray, line: int) -> list[Block]:
        """Blocks from the retract above ``before`` to the row ``q``.

        The tool is retracted already (the start, a tool change, a home return) and TCP is
        off; the blocks leave TCP on in TCP programs.

        Parameters
        ----------
        before : ndarray or None, shape (m,)
            Joint values before the retract; None at the start (the machine's home assumed
            for the collision check).
        q : ndarray, shape (m,)
            The row the approach leads to.
        line : int
            Its CL line, for messages.
        """
        high, approach = self.high_and_approach(q, line)
        start = self.machine.home.copy() if before is None else before.copy()
        retracted = self._retracted(start)
        turned = retracted.copy()
        turned[self._rotary] = q[self._rotary]
        path = [retracted, turned, high, approach, q]
        if before is not None:
            path.insert(0, start)
        turning = 2 if before is not None else 1  # the row the rotary axes turn into
        self.paths.append((line, self._shortest(np.array(path), turning)))
        blocks: list[Block] = []
        if self._rotary:
            blocks.append(Move(True, self._position(turned, self._rotary)))
        if self.tcp:
            blocks.append(Tcp(on=True))
        blocks.append(Move(True, self._position(high, self._linear)))
        blocks.append(Move(True, self._position(approach, self._linear)))
        return blocks

    def leave(self, q: np.ndarray, line: int, tcp_on: bool, stop: bool = True) -> list[Block]:
        """Blocks that leave the path at row ``q`` for a tool change: TCP off, the retract,
        spindle and coolant off (``stop``; else they stay on: the tool stays, as at a change of
        work offset)."""
        self.paths.append((line, np.array([q, self._retracted(q)])))
        blocks: list[Block] = [Tcp(on=False)] if tcp_on else []
        blocks.append(self.retract_block())
        return [*blocks, Spindle("off"), Coolant("off")] if stop else blocks

    def end(self, q: np.ndarray, line: int, tcp_on: bool) -> list[Block]:
        """Blocks that end the program after row ``q``: TCP off, the retract, spindle and
        coolant off, the rotary axes home."""
        retracted = self._retracted(q)
        home = retracted.copy()
        home[self._rotary] = self.machine.home[self._rotary]
        self.paths.append((line, self._shortest(np.array([q, retracted, home]), 2)))
        blocks: list[Block] = [Tcp(on=False)] if tcp_on else []
        blocks += [self.retract_block(), Spindle("off"), Coolant("off")]
        if self._rotary:
            blocks.append(Move(True, self._position(home, self._rotary)))
        return blocks
