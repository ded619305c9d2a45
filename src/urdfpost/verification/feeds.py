"""The feed a program gives at the tool tip, and how fast it drives the machine's axes.

A control runs a feed block in a time the program's feed mode sets:

- **inverse time** (G93): ``1 / F`` minutes;
- **feed per minute, TCP**: the tool tip's straight line divided by F (the control's TCP
  applies F at the tip);
- **feed per minute, machine coordinates**: the block's length in axis space divided by F, by
  the control's rule (:data:`~urdfpost.dialects.spec.AXIS_FEED_RULES`): ``"combined"``
  ``sqrt(sum dlinear^2 + sum drotary_deg^2)``, degrees counted as program length units (Fanuc,
  Heidenhain); ``"linear-first"`` the X/Y/Z length when a linear axis moves, else the rotary
  length in degrees (RS274NGC, LinuxCNC, Siemens). Lengths in program units, F in program
  units per minute.

The tip feed a block gives is its tip path length (the tool tip through the forward
kinematics at :data:`TIP_SAMPLES` evenly spaced parameters, as verification samples the block;
in a TCP program the straight line) over that time; an axis' speed is its travel over that
time. The post (:mod:`urdfpost.posting.feeds`) times its blocks with the same functions, so
what it programs and what the verifier measures of the text read back are one measure.

A block runs at an axis limit when its time is what its fastest axis needs at its URDF
velocity limit (``max_i |dq_i| / v_i``), or what the control's largest inverse-time F allows:
such a block is slower than programmed by design (the post lengthened it) and is reported,
not refused. Any other block whose tip feed differs from the CL feed by more than the feed
tolerance (:attr:`urdfpost.tolerances.Tolerances.feed_share`), and any axis above its limit,
fail the verification.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, replace
from types import ModuleType
from typing import Any

import numpy as np

from urdfpost._compiled import COMPILED_FROM, Kernels
from urdfpost.dialects.spec import DialectSpec
from urdfpost.geometry import chunks
from urdfpost.kinematics.forward import ChainArrays, chain_arrays, tip_and_axis_along
from urdfpost.kinematics.inverse import solve_linear
from urdfpost.machine import Machine
from urdfpost.program import FEED_INVERSE_TIME, Program
from urdfpost.tolerances import IN_PLACE, Tolerances
from urdfpost.toolpath import Toolpath
from urdfpost.units import mm_per_unit
from urdfpost.verification.match import match_points, program_joints, row_poses_at_tip

TIP_SAMPLES = 10
"""Tool tip positions per block (its ends included) whose polyline is the block's tip path."""

_SPEED_SLACK = 1e-9
"""Share by which an axis may exceed its limit (the floating point of the times)."""

_PER_MINUTE = 60.0
"""Seconds per minute (URDF velocities are per second, feeds per minute)."""

log = logging.getLogger(__name__)


def _load_kernels() -> ModuleType:
    from urdfpost.verification import _feeds_kernel

    return _feeds_kernel


KERNELS = Kernels(
    _load_kernels,
    "tip lengths",
    start=COMPILED_FROM,
    warm_start=COMPILED_FROM // 10,
    logger=log,
    warning="compiled %s unavailable (%s); numpy runs",
)
"""The compiled tip path lengths (:mod:`urdfpost.verification._feeds_kernel`) of programs
without TCP, used from :data:`~urdfpost._compiled.COMPILED_FROM` blocks on (a tenth of that
once numba is imported in the process: then only their cached machine code is loaded)."""


@dataclass(frozen=True)
class FeedRules:
    """How a control times the feed blocks of a program (of its dialect's spec).

    Attributes
    ----------
    axis_feed_rule : str
        :attr:`~urdfpost.dialects.spec.DialectSpec.axis_feed_rule`.
    inverse_time_max : float or None
        Largest inverse-time F, 1/min (None: no limit).
    feed_step : float, mm/min
        One unit of the last decimal of a written feed per minute (0: not known): a block
        slowed to an axis limit has its F rounded down by less than that.
    inverse_step : float, 1/min
        The same of a written inverse-time F.
    """

    axis_feed_rule: str = "combined"
    inverse_time_max: float | None = None
    feed_step: float = 0.0
    inverse_step: float = 0.0

    @classmethod
    def of(cls, spec: DialectSpec, units: str) -> FeedRules:
        """The rules of a control's programs in ``units`` ("mm" or "inch")."""
        inch = units == "inch"
        per_minute = spec.feed_inch if inch else spec.feed_mm
        return cls(
            spec.axis_feed_rule,
            spec.inverse_time_max,
            per_minute.resolution * (spec.feed_inch_unit if inch else 1.0),
            spec.inverse_time_feed.resolution,
        )


def machine_joints(
    machine: Machine, values: np.ndarray, tcp: bool, tool_length: float
) -> np.ndarray:
    """The machine's axis values at program rows.

    Parameters
    ----------
    machine : Machine
    values : ndarray, shape (N, m)
        Program rows in machine axis order (mm, rad); in TCP programs X, Y, Z are the tool tip.
    tcp : bool
    tool_length : float, mm

    Returns
    -------
    ndarray, shape (N, m)
        mm, rad: in TCP programs the linear axes that put the tip there.
    """
    if not tcp or not len(values):
        return values
    q = values.copy()
    lin, rot = list(machine.linear_columns), list(machine.rotary_columns)
    q[:, lin] = solve_linear(machine, values[:, rot], values[:, lin], tool_length)
    return q


def tip_lengths(
    machine: Machine, q0: np.ndarray, q1: np.ndarray, tcp: bool, tool_length: float
) -> np.ndarray:
    """Tool tip path length of blocks from program rows ``q0`` to ``q1``.

    Parameters
    ----------
    machine : Machine
    q0, q1 : ndarray, shape (n, m)
        Program rows (mm, rad; in TCP programs X, Y, Z are the tip).
    tcp : bool
        The control moves the tip on the straight line (the length is its chord).
    tool_length : float, mm

    Returns
    -------
    ndarray, shape (n,), mm
        The polyline of the tip at :data:`TIP_SAMPLES` parameters (TCP: the chord).
    """
    n = len(q0)
    if tcp:
        lin = list(machine.linear_columns)
        return np.linalg.norm(q1[:, lin] - q0[:, lin], axis=1)
    kernels = KERNELS.get(n) if n else None
    if kernels is not None:  # the compiled loop takes blocks as pairs of rows
        values = np.empty((2 * n, q0.shape[1]))
        values[0::2], values[1::2] = q0, q1
        out = _tip_lengths_compiled(kernels, machine, values, np.arange(0, 2 * n, 2), tool_length)
        if out is not None:
            return out
    return _tip_lengths_numpy(machine, q0, q1, tool_length)


def _tip_lengths_numpy(
    machine: Machine, q0: np.ndarray, q1: np.ndarray, tool_length: float
) -> np.ndarray:
    """:func:`tip_lengths` of a program without TCP, by numpy: the definition."""
    n = len(q0)
    out = np.empty(n)
    t = np.linspace(0.0, 1.0, TIP_SAMPLES)
    for part in chunks(n, TIP_SAMPLES):
        tip, _ = tip_and_axis_along(machine, q0[part], q1[part], t, tool_length)
        assert tip is not None
        step = sum(np.diff(c, axis=0) ** 2 for c in tip)
        chords = np.sqrt(step)
        # summed sample after sample, as numpy sums along the first axis of many blocks (of a
        # chunk of one block it would sum them pairwise): the same bits whatever the chunks
        total = chords[0]
        for chord in chords[1:]:
            total += chord
        out[part] = total
    return out


def tip_lengths_at(
    machine: Machine, values: np.ndarray, start: np.ndarray, tcp: bool, tool_length: float
) -> np.ndarray:
    """:func:`tip_lengths` of the blocks from rows ``start`` of ``values`` to the next rows.

    From :data:`KERNELS`' size on (with numba: the ``fast`` extra) compiled
    (:func:`urdfpost.verification._feeds_kernel.tip_lengths`, the same numbers), else numpy.

    Parameters
    ----------
    machine : Machine
    values : ndarray, shape (N, m)
        Program rows (mm, rad; in TCP programs X, Y, Z are the tip).
    start : ndarray, shape (n,), int
        The first row of each block, below ``N - 1``.
    tcp : bool
    tool_length : float, mm

    Returns
    -------
    ndarray, shape (n,), mm
    """
    if tcp:
        return tip_lengths(machine, values[start], values[start + 1], tcp, tool_length)
    kernels = KERNELS.get(len(start)) if len(start) else None
    if kernels is not None:
        out = _tip_lengths_compiled(kernels, machine, values, start, tool_length)
        if out is not None:
            return out
    return _tip_lengths_numpy(machine, values[start], values[start + 1], tool_length)


def _tip_lengths_compiled(
    kernels: ModuleType, machine: Machine, values: np.ndarray, start: np.ndarray, tool_length: float
) -> np.ndarray | None:
    """:func:`tip_lengths_at` of a program without TCP, compiled; None when the kernel failed
    (then numpy runs from now on)."""
    c = chain_arrays(machine, tool_length)
    t = np.linspace(0.0, 1.0, TIP_SAMPLES)
    values = np.ascontiguousarray(values, dtype=float)
    start = np.ascontiguousarray(start, dtype=np.int64)
    out = np.empty(len(start))
    try:
        kernels.tip_lengths(
            c.column, c.rotary, c.direction, c.pivot, c.tool_point, c.home_axis, values, start,
            block_trig(c, values, start, t), t, out,
        )  # fmt: skip
    except Exception as err:  # numba could not compile or cache it here
        KERNELS.fail(err)
        return None
    return out


def block_trig(
    chain: ChainArrays, values: np.ndarray, start: np.ndarray, t: np.ndarray
) -> np.ndarray:
    """The cosines and sines the compiled loops sample blocks from by angle addition, as
    :func:`urdfpost.kinematics.forward.cos_sin_along` works them out.

    Parameters
    ----------
    chain : ChainArrays
    values : ndarray, shape (N, m)
        Program rows, mm / rad.
    start : ndarray, shape (n,), int
        The first row of each block (it runs to the next row).
    t : ndarray, shape (s,)
        Evenly spaced sample parameters, s >= 2.

    Returns
    -------
    ndarray, shape (k, 4, n)
        Per joint of the chain and block: the cosine and sine of the joint's angle at
        ``t[0]`` and of its change from one sample to the next (zeros for a linear joint).
    """
    trig = np.zeros((len(chain.column), 4, len(start)))
    h = (t[-1] - t[0]) / (len(t) - 1)
    for j in np.flatnonzero(chain.rotary):
        theta0 = values[start, chain.column[j]]
        step = values[start + 1, chain.column[j]] - theta0
        first = theta0 + t[0] * step
        np.cos(first, out=trig[j, 0])
        np.sin(first, out=trig[j, 1])
        hs = h * step
        np.cos(hs, out=trig[j, 2])
        np.sin(hs, out=trig[j, 3])
    return trig


def axis_lengths(
    machine: Machine, q0: np.ndarray, q1: np.ndarray, rule: str, units: str
) -> np.ndarray:
    """Length of blocks in axis space, as a control without TCP applies a feed to it.

    Parameters
    ----------
    machine : Machine
    q0, q1 : ndarray, shape (n, m)
        Machine axis values (mm, rad).
    rule : str
        ``"combined"`` or ``"linear-first"`` (see the module docstring).
    units : str
        Program units: linear lengths in them, rotary in degrees.

    Returns
    -------
    ndarray, shape (n,), program units (degrees counted as one)
    """
    linear = _column_norm(q0, q1, machine.linear_columns) / mm_per_unit(units)
    rotary = np.degrees(_column_norm(q0, q1, machine.rotary_columns))
    if rule == "combined":
        return np.hypot(linear, rotary)
    if rule == "linear-first":
        return np.where(linear > 0.0, linear, rotary)
    raise ValueError(f"axis feed rule {rule!r}: expected 'combined' or 'linear-first'")


def _column_norm(q0: np.ndarray, q1: np.ndarray, columns: tuple[int, ...]) -> np.ndarray:
    """``np.linalg.norm(q1[:, columns] - q0[:, columns], axis=1)`` column by column (the
    squares summed in the order numpy sums a row of a few, so the same bits; numpy's sum along
    a short axis is the slow one), shape (n,)."""
    total = np.zeros(len(q0))
    for k, j in enumerate(columns):
        d = q1[:, j] - q0[:, j]
        d *= d
        total = d if k == 0 else np.add(total, d, out=total)
    return np.sqrt(total, out=total)


def limit_times(machine: Machine, dq: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The least time of moves at the axes' velocity limits.

    Parameters
    ----------
    machine : Machine
    dq : ndarray, shape (n, m)
        Axis travel of each move (mm, rad).

    Returns
    -------
    time : ndarray, shape (n,), minutes
        ``max_i |dq_i| / v_i`` over the axes with a finite limit (0 without one).
    axis : ndarray, shape (n,), int
        The column of the axis that sets it (-1 where none moves).
    """
    velocity = np.array([a.velocity for a in machine.axes], dtype=float) * _PER_MINUTE
    finite = np.flatnonzero(np.isfinite(velocity) & (velocity > 0.0))
    # column by column (numpy's argmax along a short axis is slow): the largest need, NaN if
    # any is (as np.maximum carries it); then the first axis that needs it (the argmax: a row
    # where no axis needs time, or one needs NaN, names none)
    time = np.zeros(len(dq))
    need = [np.abs(dq[:, j]) / velocity[j] for j in finite]
    for column in need:
        np.maximum(time, column, out=time)
    axis = np.full(len(dq), -1)
    for j, column in zip(finite[::-1], need[::-1], strict=True):
        axis[column == time] = j
    return time, np.where(time > 0.0, axis, -1)


def block_times(
    feed: np.ndarray,
    feed_mode: str,
    tcp: bool,
    tip: np.ndarray,
    axis: np.ndarray,
    units: str,
) -> np.ndarray:
    """The time a control takes for feed blocks at their programmed F.

    Parameters
    ----------
    feed : ndarray, shape (n,)
        The blocks' F: mm/min (the program's :attr:`~urdfpost.program.Move.feed`), or 1/min
        in inverse time.
    feed_mode : str
        The program's.
    tcp : bool
    tip : ndarray, shape (n,), mm
        Tip path lengths (:func:`tip_lengths`).
    axis : ndarray, shape (n,), program units
        Axis-space lengths (:func:`axis_lengths`).
    units : str
        Program units.

    Returns
    -------
    ndarray, shape (n,), minutes
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        if feed_mode == FEED_INVERSE_TIME:
            return 1.0 / feed
        if tcp:
            return tip / feed
        return axis / (feed / mm_per_unit(units))


@dataclass(frozen=True)
class FeedCheck:
    """The tip feed and axis speeds of a program's feed blocks, against the CL feed.

    Attributes
    ----------
    feed_mode : str
        The program's (per-minute or inverse-time).
    tolerance_pct : float
        How far a block's tip feed may differ from the CL feed, percent.
    compared : int
        Feed blocks compared (with a CL feed and a tip path).
    max_deviation_pct : float
        Largest deviation of the tip feed from the CL feed over the blocks not at an axis
        limit, percent, beyond the rounding of the block's F word (half a unit of its last
        decimal, relative to the F written).
    worst_cl_line : int or None
        CL line of that block.
    capped : int
        Blocks slower than the CL feed because an axis (or the control's F range) sets their
        time.
    slowest_capped_pct : float or None
        The lowest tip feed of those, percent of the CL feed.
    slowest_capped_cl_line : int or None
    max_axis_share : float
        Fastest axis speed over its velocity limit, over every feed block (1: at the limit).
    max_axis : str or None
        That axis.
    max_axis_cl_line : int or None
    in_place : int
        Feed blocks that turn the tool in place (no tip feed to compare).
    """

    feed_mode: str
    tolerance_pct: float
    compared: int = 0
    max_deviation_pct: float = 0.0
    worst_cl_line: int | None = None
    capped: int = 0
    slowest_capped_pct: float | None = None
    slowest_capped_cl_line: int | None = None
    max_axis_share: float = 0.0
    max_axis: str | None = None
    max_axis_cl_line: int | None = None
    in_place: int = 0

    @property
    def ok(self) -> bool:
        """Every block at the CL feed within tolerance (or at an axis limit), no axis above
        its limit."""
        return (
            self.max_deviation_pct <= self.tolerance_pct
            and self.max_axis_share <= 1.0 + _SPEED_SLACK
        )

    def summary(self) -> str:
        """One line for people."""
        verdict = "within tolerance" if self.ok else "BEYOND TOLERANCE"
        worst = f" at CL line {self.worst_cl_line}" if self.worst_cl_line is not None else ""
        text = (
            f"tip feed {verdict}: {self.compared} feed blocks ({self.feed_mode}), deviation from "
            f"the CL feed max {self.max_deviation_pct:.3f}%{worst} (tolerance "
            f"{self.tolerance_pct:g}%)"
        )
        if self.capped:
            text += (
                f"; {self.capped} blocks slowed to a limit (an axis' velocity or the control's "
                f"largest inverse-time F), slowest at "
                f"{self.slowest_capped_pct:.1f}% of the CL feed (CL line "
                f"{self.slowest_capped_cl_line})"
            )
        if self.max_axis is not None:
            share = 100.0 * self.max_axis_share
            text += f"; fastest axis {self.max_axis} at {share:.1f}% of its limit"
        return text

    @staticmethod
    def merged(parts: list[FeedCheck]) -> FeedCheck | None:
        """The checks of consecutive pieces of a program as one (None when there are none)."""
        if not parts:
            return None
        worst = max(parts, key=lambda f: f.max_deviation_pct)
        fastest = max(parts, key=lambda f: f.max_axis_share)
        capped = [f for f in parts if f.slowest_capped_pct is not None]
        slowest = min(capped, key=lambda f: f.slowest_capped_pct or 0.0) if capped else None
        return FeedCheck(
            feed_mode=parts[0].feed_mode,
            tolerance_pct=parts[0].tolerance_pct,
            compared=sum(f.compared for f in parts),
            max_deviation_pct=worst.max_deviation_pct,
            worst_cl_line=worst.worst_cl_line,
            capped=sum(f.capped for f in parts),
            slowest_capped_pct=None if slowest is None else slowest.slowest_capped_pct,
            slowest_capped_cl_line=None if slowest is None else slowest.slowest_capped_cl_line,
            max_axis_share=fastest.max_axis_share,
            max_axis=fastest.max_axis,
            max_axis_cl_line=fastest.max_axis_cl_line,
            in_place=sum(f.in_place for f in parts),
        )


def measure_feeds(
    machine: Machine,
    feed_mode: str,
    tcp: bool,
    units: str,
    q0: np.ndarray,
    q1: np.ndarray,
    feed: np.ndarray,
    cl_feed: np.ndarray,
    cl_line: np.ndarray,
    rules: FeedRules,
    tolerance_share: float,
    tool_length: float,
    tip: np.ndarray | None = None,
    other_cl_feed: np.ndarray | None = None,
) -> FeedCheck:
    """The tip feed and axis speeds of feed blocks, against the CL feed.

    Parameters
    ----------
    machine : Machine
    feed_mode : str
        The program's.
    tcp : bool
    units : str
        Program units.
    q0, q1 : ndarray, shape (n, m)
        Program rows at the start and end of each block (mm, rad; TCP: X, Y, Z the tip).
    feed : ndarray, shape (n,)
        The blocks' F (mm/min, or 1/min in inverse time).
    cl_feed : ndarray, shape (n,), mm/min
        The CL feed each block is programmed at; NaN: not compared.
    cl_line : ndarray, shape (n,), int
        The CL line of each block, for the figures.
    rules : FeedRules
    tolerance_share : float
        Allowed deviation of the tip feed, a share of the CL feed.
    tool_length : float, mm
    tip : ndarray, shape (n,), optional
        :func:`tip_lengths` of the blocks, when known.
    other_cl_feed : ndarray, shape (n, a), mm/min, optional
        Other CL feeds a block may be programmed at (NaN where not): a block is compared with
        the one its tip feed is nearest of these and ``cl_feed`` (a block at a CL point where
        the CL feed changes, :func:`urdfpost.verification.measure._feeds_at_points`).

    Returns
    -------
    FeedCheck
    """
    out = FeedCheck(feed_mode=feed_mode, tolerance_pct=100.0 * tolerance_share)
    if not len(q0):
        return out
    tip = tip_lengths(machine, q0, q1, tcp, tool_length) if tip is None else tip
    m0 = machine_joints(machine, q0, tcp, tool_length)
    m1 = machine_joints(machine, q1, tcp, tool_length)
    dq = m1 - m0
    axis_len = axis_lengths(machine, m0, m1, rules.axis_feed_rule, units)
    time = block_times(feed, feed_mode, tcp, tip, axis_len, units)
    travel = [np.abs(dq[:, j]) for j in range(dq.shape[1])]
    largest = np.zeros(len(dq))  # np.abs(dq).max(axis=1, initial=0.0), column by column
    for column in travel:
        np.maximum(largest, column, out=largest)
    timed = (largest > 0.0) & np.isfinite(time) & (time > 0.0)
    # the axes' speeds over their limits
    velocity = np.array([a.velocity for a in machine.axes], dtype=float) * _PER_MINUTE
    fields: dict[str, Any] = {}
    row, col, top = _fastest(travel, time, velocity, timed)
    if top > 0.0:
        fields |= {
            "max_axis_share": top,
            "max_axis": machine.axis_names[col],
            "max_axis_cl_line": int(cl_line[row]),
        }
    # the tip feed against the CL feed, where the block is not at a limit
    limit, _ = limit_times(machine, dq)
    if feed_mode == FEED_INVERSE_TIME and rules.inverse_time_max:
        limit = np.maximum(limit, 1.0 / rules.inverse_time_max)
    in_place = timed & (tip < IN_PLACE)
    compared = timed & ~in_place & np.isfinite(cl_feed) & (cl_feed > 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = tip / time / cl_feed
        for other in () if other_cl_feed is None else other_cl_feed.T:
            got = tip / time / other
            nearer = np.abs(got - 1.0) < np.abs(ratio - 1.0)  # (False where either is NaN)
            ratio = np.where(nearer, got, ratio)
    slack = 1.0 + tolerance_share
    # at a limit: within the slack of it, or the next F the program could write would be
    # over it (a slow block's F rounded down to its last decimal)
    step = rules.inverse_step if feed_mode == FEED_INVERSE_TIME else rules.feed_step
    faster = block_times(feed + step, feed_mode, tcp, tip, axis_len, units) if step else time
    at_limit = compared & (ratio < 1.0) & ((time <= limit * slack) | (faster < limit))
    free = compared & ~at_limit
    # beyond what the last decimal of the F word allows (half a unit of it, relative to F):
    # a slow block's F, a few units of its last decimal, cannot be written closer
    with np.errstate(divide="ignore", invalid="ignore"):
        rounding = np.where(feed > 0.0, 0.5 * step / feed, 0.0)
    deviation = np.where(free, np.maximum(np.abs(ratio - 1.0) - rounding, 0.0), 0.0)
    fields |= {"compared": int(compared.sum()), "in_place": int(in_place.sum())}
    if free.any():
        k = int(np.argmax(deviation))
        fields |= {
            "max_deviation_pct": 100.0 * float(deviation[k]),
            "worst_cl_line": int(cl_line[k]),
        }
    if at_limit.any():
        low = np.where(at_limit, ratio, np.inf)
        k = int(np.argmin(low))
        fields |= {
            "capped": int(at_limit.sum()),
            "slowest_capped_pct": 100.0 * float(ratio[k]),
            "slowest_capped_cl_line": int(cl_line[k]),
        }
    return replace(out, **fields)


def _fastest(
    travel: list[np.ndarray], time: np.ndarray, velocity: np.ndarray, timed: np.ndarray
) -> tuple[int, int, float]:
    """The block and axis of the largest speed over its limit, and that share: the first in
    row-major order of the largest of ``np.abs(dq) / time[:, None] / velocity`` over the
    ``timed`` rows (NaN counted as 0, as ``np.nan_to_num`` counts it), worked out column by
    column.

    Parameters
    ----------
    travel : list of ndarray, shape (n,)
        Every axis' ``|dq|``, mm or rad.
    time : ndarray, shape (n,), minutes
    velocity : ndarray, shape (m,)
        Per minute.
    timed : ndarray, shape (n,), bool

    Returns
    -------
    row, col : int
    share : float
        0 (and any row and column) when no timed block moves an axis.
    """
    shares, tops = [], []
    with np.errstate(divide="ignore", invalid="ignore"):
        for j, column in enumerate(travel):
            shares.append(np.where(timed, column / time / velocity[j], 0.0))
            tops.append(float(np.fmax.reduce(shares[-1], initial=0.0)))  # (NaN left out)
    top = max(tops, default=0.0)
    if not top > 0.0:
        return 0, 0, 0.0
    n = len(time)
    first = [int(np.argmax(s == top)) if t == top else n for s, t in zip(shares, tops, strict=True)]
    row = min(first)
    return row, first.index(row), top


def tip_feeds(
    machine: Machine, program: Program, tool_length: float, axis_feed_rule: str = "combined"
) -> np.ndarray:
    """The tool-tip feed each feed move of a program gives, whatever its feed mode.

    For the lab tools that time a program by its tip feed (:mod:`urdfpost.analysis`): a TCP
    program with feeds per minute gives its F; an inverse-time or machine-coordinate program
    gives its tip path over the block time (:func:`block_times`). Modal: a feed move without
    F keeps the F before it.

    Parameters
    ----------
    machine : Machine
    program : Program
    tool_length : float, mm
    axis_feed_rule : str
        The control's (:attr:`~urdfpost.dialects.spec.DialectSpec.axis_feed_rule`), for
        machine-coordinate programs with feeds per minute.

    Returns
    -------
    ndarray, shape (N,), mm/min
        One per move of :meth:`~urdfpost.program.Program.move_table`; NaN for rapids, moves
        before any F, the first move (no block before it) and blocks whose tip does not move.
    """
    table = program.move_table()
    feed = table.feed.copy()
    have = np.isfinite(feed) | table.rapid
    last = np.maximum.accumulate(np.where(np.isfinite(feed), np.arange(len(feed)), -1))
    feed = np.where(~have & (last >= 0), feed[np.maximum(last, 0)], feed)
    feed = np.where(table.rapid, np.nan, feed)
    if program.tcp and program.feed_mode != FEED_INVERSE_TIME:
        return feed
    out = np.full(len(feed), np.nan)
    values, _ = program_joints(machine, program)
    blocks = np.flatnonzero(np.isfinite(feed[1:])) + 1
    if not blocks.size:
        return out
    q0, q1 = values[blocks - 1], values[blocks]
    tip = tip_lengths(machine, q0, q1, program.tcp, tool_length)
    m0 = machine_joints(machine, q0, program.tcp, tool_length)
    m1 = machine_joints(machine, q1, program.tcp, tool_length)
    axis = axis_lengths(machine, m0, m1, axis_feed_rule, program.units)
    time = block_times(feed[blocks], program.feed_mode, program.tcp, tip, axis, program.units)
    with np.errstate(divide="ignore", invalid="ignore"):
        out[blocks] = np.where((tip >= IN_PLACE) & (time > 0.0), tip / time, np.nan)
    return out


def cl_feeds_of_rows(
    machine: Machine,
    program: Program,
    toolpath: Toolpath,
    tol: Tolerances,
    tool_length: float,
) -> np.ndarray:
    """The CL feed each move of a program moves at: that of the first CL point reached at or
    after it (:func:`~urdfpost.verification.match.match_points`), as the post programs it.

    For the lab tools that ask what the CL feed alone would demand of the axes
    (:mod:`urdfpost.analysis.metrics`), where the program's F may be lower (an axis limit) or
    no tip feed at all (inverse time, machine coordinates).

    Returns
    -------
    ndarray, shape (N,), mm/min
        NaN after the last CL point reached and where the CL data has no feed.
    """
    values, _ = program_joints(machine, program)
    rows = row_poses_at_tip(machine, values, program.tcp, tool_length)
    match = match_points(toolpath.tip, toolpath.axis, rows.tip, rows.axis, tol)
    reached = np.flatnonzero(match >= 0)
    out = np.full(len(values), np.nan)
    if not reached.size:
        return out
    k = np.searchsorted(match[reached], np.arange(len(values)), side="left")
    inside = k < reached.size
    out[inside] = toolpath.feed[reached[k[inside]]]
    return out
