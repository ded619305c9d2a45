"""The branch planner's cost model, in radians of rotary travel.

A path costs, per step, its rotary travel plus the time the step takes (its slowest axis,
weighted by :data:`TIME_WEIGHT`), half a turn for a branch switch between regular points, and
inf for a jump on a cutting move (:data:`JUMP`); :data:`REWIND_COST` per rewind; and per point
the preference and the penalty near travel limits (:data:`LIMIT_MARGIN`,
:data:`LIMIT_WEIGHT`). This module holds the weights and the costs of the points; the costs of
the steps between two points' candidates are made by
:class:`~urdfpost.planning.branches.state.BranchSearch`.
"""

from __future__ import annotations

import numpy as np

from urdfpost.machine import Machine
from urdfpost.planning.branches._arrays import _chunks, _total
from urdfpost.planning.branches.rules import Preference

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
