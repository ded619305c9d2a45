"""A program's tilted working planes read back: their frames checked against the machine, and
the program in its own frame for the rest of verification (:func:`urdfpost.program.untilted`).
"""

from __future__ import annotations

import math

import numpy as np

from urdfpost.errors import ProgramParseError
from urdfpost.kinematics import tip_and_axis
from urdfpost.machine import Machine
from urdfpost.program import (
    Clamp,
    Move,
    MoveTable,
    Program,
    TiltedPlane,
    Untilter,
    plane_count,
    with_positions,
)

PLANE_AXIS_DEG = 0.01
"""Degrees. How far a tilted plane's Z may be from the tool axis of the rotary values it is
switched on at: the angles are written to 0.0001 degree, and a tool axis off the plane's Z
by this much moves the tip by 0.02 mm over a 100 mm deep move along it."""


def plane_faults(
    program: Program,
    machine: Machine,
    start: np.ndarray | None = None,
    count: int = 0,
) -> list[str]:
    """What is wrong with the tilted planes of ``program``: per plane switched on, its Z
    against the tool axis at the rotary values that stand when it is (more than
    :data:`PLANE_AXIS_DEG` apart, or the rotary values not known). ``start``: where the axes
    stand before it (a piece of a program; default not known), ``count``: the planes before
    it (for the messages)."""
    axes = program.axes
    faults: list[str] = []
    for part, last in with_positions(program.parts, len(axes), start):
        if isinstance(part, TiltedPlane) and part.angles is not None:
            count += 1
            q = machine.home.copy()
            missing = []
            for axis in machine.rotary:
                if axis.name not in axes:
                    continue
                value = last[axes.index(axis.name)]
                if math.isnan(value):
                    missing.append(axis.name)
                else:
                    q[machine.axis_names.index(axis.name)] = math.radians(value)
            if missing:
                faults.append(
                    f"tilted plane {count}: {' '.join(missing)} not programmed before it; "
                    "expected the rotary axes positioned before the plane is switched on"
                )
                continue
            _, tool = tip_and_axis(machine, q[None, :], 0.0)
            z = part.frame()[:, 2]
            angle = math.degrees(math.acos(max(-1.0, min(1.0, float(z @ tool[0])))))
            if angle > PLANE_AXIS_DEG:
                faults.append(
                    f"tilted plane {count} ({' '.join(f'{a:g}' for a in part.angles)} deg): its Z "
                    f"is {angle:.4f} deg from the tool axis of the rotary axes standing there; "
                    f"expected within {PLANE_AXIS_DEG} deg"
                )
    return faults


def clamp_faults(program: Program) -> list[str]:
    """The moves of ``program`` that turn a clamped rotary axis (between a
    :class:`~urdfpost.program.Clamp` on and off of it): one message per axis, at its first."""
    axes = program.axes
    clamped: dict[str, int] = {}  # axis -> the clamp's place among the program's clamps
    faults: dict[str, str] = {}
    count = 0
    moves = 0
    for part, last in with_positions(program.parts, len(axes)):
        if isinstance(part, Clamp):
            count += 1
            if part.on:
                clamped[part.axis] = count
            else:
                clamped.pop(part.axis, None)
        elif isinstance(part, MoveTable | Move):
            table = part if isinstance(part, MoveTable) else MoveTable.from_moves([part], len(axes))
            for axis, at in clamped.items():
                if axis not in axes or axis in faults:
                    continue
                j = axes.index(axis)
                column = np.concatenate([[last[j]], table.position[:, j]])
                known = column[~np.isnan(column)]
                if known.size and not np.allclose(known, known[0], rtol=0.0, atol=1e-9):
                    where = np.flatnonzero(~np.isclose(known, known[0], rtol=0.0, atol=1e-9))
                    faults[axis] = (
                        f"{axis} turns to {known[where[0]]:g} deg while clamped (clamp {at} of "
                        f"the program), near move {moves + 1}; expected it released first"
                    )
            moves += len(table)
    return list(faults.values())


def in_own_frame(program: Program, machine: Machine) -> Program:
    """``program`` with its tilted planes checked (:func:`plane_faults`) and taken out
    (:func:`urdfpost.program.untilted`).

    Raises
    ------
    ProgramParseError
        A plane's frame does not fit the machine, or the program cannot be untilted.
    """
    if not any(isinstance(p, TiltedPlane) for p in program.parts):
        return program
    return PlaneFrames(machine).feed(program)


class PlaneFrames:
    """:func:`in_own_frame` of a program read in pieces, in order (a plane switched on in one
    piece holds in the next: :class:`urdfpost.program.Untilter`)."""

    def __init__(self, machine: Machine) -> None:
        self.machine = machine
        self.untilter = Untilter()
        self.planes = 0  # switched on so far

    def feed(self, program: Program) -> Program:
        """The next piece, its planes checked and taken out.

        Raises
        ------
        ProgramParseError
            As :func:`in_own_frame`.
        """
        ons = plane_count(program)
        if ons:
            last = self.untilter.last
            start = np.array([last.get(a, math.nan) for a in program.axes])
            faults = plane_faults(program, self.machine, start, self.planes)
            if faults:
                raise ProgramParseError(program.name, 0, "; ".join(faults))
        self.planes += ons
        try:
            return self.untilter.feed(program)
        except ValueError as e:
            raise ProgramParseError(program.name, 0, str(e)) from None
