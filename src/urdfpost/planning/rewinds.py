"""Rewinds: where a path stops, lifts off along the tool axis, turns and returns.

A rewind happens at one CL point where no continuous solution within travel (or clear of
collisions) goes on: the path arrives with one configuration and leaves with another of the
same tool pose (the other branch, or the same orientation a turn back). The branch planner
(:mod:`urdfpost.planning.branches`) decides where; this module says what the machine does
there.
"""

from __future__ import annotations

import numpy as np

from urdfpost.kinematics.inverse import assemble, solve_linear
from urdfpost.machine import Machine

DEFAULT_RETRACT = 50.0
"""Lift along the tool axis for a rewind, mm."""

CUT, LIFT, TURN, RETURN = 0, 1, 2, 3
"""Kinds of program rows: a cut, or the lift, turn and return of a rewind."""


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
    ndarray, shape (3, m)
        ``q_from`` lifted by ``retract`` along the tool axis, ``q_to`` lifted, ``q_to``; the
        path goes from ``q_from`` through these.
    """
    cols = list(machine.rotary_columns)
    rot = np.stack([q_from[cols], q_to[cols]])
    up = np.repeat((tip + retract * axis)[None, :], 2, axis=0)
    lifted = assemble(machine, rot, solve_linear(machine, rot, up, tool_length))
    return np.vstack([lifted, q_to[None, :]])
