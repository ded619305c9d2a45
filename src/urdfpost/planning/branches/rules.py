"""What a branch may be: the candidates of each point and the travel they must keep.

- :func:`_candidates`: both inverse kinematics branches of each point, expanded by the
  360-degree multiples each limited rotary axis can take, marked where they lie within rotary
  travel (an undetermined angle counts as within);
- :func:`_linear_ok`, :func:`_check_linear`: the travel of the linear axes (at a pole known
  only once the held angle is);
- :func:`_wrap`: angles wrapped to (-pi, pi], so continuous axes take the shortest rotation;
- the messages naming the CL line of a point that no candidate reaches within travel.

:class:`Preference` (the branch asked for) and :class:`Selection` (the planner's answer) are
the types the rest of the package speaks.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from urdfpost.errors import UnreachableError
from urdfpost.kinematics.inverse import IKStatus
from urdfpost.machine import Machine
from urdfpost.planning.branches._arrays import _chunks

TWO_PI = 2.0 * np.pi
_SAME_ANGLE = 1e-7  # rad: a candidate with the start's angles (continued paths)
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
        within travel (or clear of collisions) goes on from there. The strategies also mark
        so the points they insert where a branch switch next to a pole is made a turn at one
        point (:func:`urdfpost.planning.strategies._common.split_at_switches`); a turn that
        does not swing the tool axis beyond the orientation tolerance is made without the
        lift (:func:`urdfpost.planning.realise.with_rewinds`).
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


def _linear_ok(machine: Machine, q: np.ndarray) -> np.ndarray:
    """Whether the linear axes of ``q`` (n, 2, m) are within travel, shape (n, 2)."""
    ok = np.ones(q.shape[:2], dtype=bool)
    for sl in _chunks(len(q), q[0].size):
        for j in machine.linear_columns:
            v = q[sl, :, j]
            ok[sl] &= (v >= machine.lower[j] - _SLACK) & (v <= machine.upper[j] + _SLACK)
    return ok


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


def _unreachable_message(
    machine: Machine, axis: np.ndarray, status: int, line: int, source: str
) -> str:
    """Message for a point no branch reaches: a tool axis (3,) outside the orientations the
    machine can take (``status`` :attr:`IKStatus.UNREACHABLE`), or outside travel on every
    branch."""
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


def _label(machine: Machine, rot: np.ndarray) -> str:
    """Rotary angles ``rot`` (r,) rad as NC words in degrees, e.g. ``"B12.000 C-90.000"``."""
    return " ".join(
        f"{a.name}{np.degrees(v):.3f}" for a, v in zip(machine.rotary, rot, strict=True)
    )
