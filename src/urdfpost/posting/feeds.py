"""The F words of a program: the CL's tip feed made true at the tip, within the axes' limits.

The blocks of a program carry the CL feed (:func:`urdfpost.posting.body.program_body`).
:func:`timed_program` gives each feed block the F that makes the control run it in the time
the CL feed sets for its tool tip path, in the job's feed mode (:data:`FEED_MODES`):

- ``tip``: F is the tip feed; right with TCP, where the control applies F at the tip;
  without TCP the control applies it to the axes' path (only right where the rotary axes do
  not move, which the verifier checks);
- ``inverse-time``: G93, F = 1 / block time in minutes (Fanuc, LinuxCNC, Siemens);
- ``per-block``: F per minute, F = the block's axis-space length by the control's rule /
  block time (for controls without inverse time: Heidenhain).

The block time is the tip path length (:func:`urdfpost.verification.feeds.tip_lengths`, the
measure the verifier takes of the text read back) over the CL feed, but never less than what
the fastest axis needs at its URDF velocity limit (``max_i |dq_i| / v_i``), nor, in inverse
time, than one over the control's largest F: there the F is lower than the tip feed asks for
(reported as capped blocks, :class:`~urdfpost.posting.report.FeedFigures`). Rapids get no
F. Lengths are taken of the positions as written (rounded to the control's decimals), so
the verifier measures the same blocks.

The same figures give how long the program runs (:meth:`FeedFigures.duration`): the feed
blocks' times (arcs along the arc; a turn in place under TCP, which the control times, at its
axes' velocity limits), the rapids at the axes' velocity limits, the dwells, and the motion of
the canned cycles as :func:`~urdfpost.program.expand_cycles` makes it; not the axes'
acceleration, the tool changes nor the retracts between sections.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from urdfpost.dialects._bulk import scaled_integers
from urdfpost.dialects.spec import DialectSpec
from urdfpost.machine import Machine
from urdfpost.posting.report import FeedFigures
from urdfpost.program import (
    FEED_INVERSE_TIME,
    FEED_PER_MINUTE,
    JOB_FEED_MODES,
    Arc,
    Blocks,
    Cycle,
    Dwell,
    Move,
    MoveTable,
    Program,
    expand_cycles,
    modal_filled,
)
from urdfpost.units import mm_per_unit
from urdfpost.verification.feeds import (
    IN_PLACE,
    axis_lengths,
    limit_times,
    machine_joints,
    tip_lengths_at,
)
from urdfpost.verification.match import program_joints

FEED_TIP = "tip"
FEED_INVERSE = "inverse-time"
FEED_PER_BLOCK = "per-block"
FEED_AUTO = "auto"

FEED_MODES = JOB_FEED_MODES
"""The feed modes a job can ask for; ``auto``: ``tip`` with TCP, else ``inverse-time`` where
the control has it, else ``per-block``."""

RANGE_CAP = "F range"
"""What caps a block whose inverse-time F would exceed the control's largest."""


def written_values(
    machine: Machine, values: np.ndarray, spec: DialectSpec, units: str
) -> np.ndarray:
    """Program rows as the text gives them back: rounded to the control's decimals.

    Parameters
    ----------
    machine : Machine
    values : ndarray, shape (N, m)
        Machine axis order, mm and rad.
    spec : DialectSpec
    units : str
        Program units.

    Returns
    -------
    ndarray, shape (N, m)
    """
    out = values.copy()
    scale = mm_per_unit(units)
    linear = spec.linear_inch if units == "inch" else spec.linear_mm
    for j, axis in enumerate(machine.axes):
        fmt = spec.rotary if axis.rotary else linear
        column = np.degrees(values[:, j]) if axis.rotary else values[:, j] / scale
        ints = scaled_integers(column, fmt.decimals)  # the digits the writer writes
        if ints is None:
            continue  # (too large to be written in bulk: the writer refuses or writes it)
        text = ints / 10.0**fmt.decimals
        out[:, j] = np.radians(text) if axis.rotary else text * scale
    return out


def _floored(value: np.ndarray, decimals: int, unit: float) -> np.ndarray:
    """``value`` (in units of ``unit``) rounded down to ``decimals`` decimals of its written
    form, at least one unit of the last decimal: a capped block's F may only get slower."""
    step = 10.0**-decimals
    written = np.floor(value / unit / step + 1e-9) * step
    return np.maximum(written, step) * unit


@dataclass(frozen=True)
class FeedTiming:
    """How a program's feed blocks are to be timed (:func:`timed_program`), handed on with a
    program whose feed moves still carry the CL feed: a streamed post times each piece where
    it is written (:class:`urdfpost.posting.worker.ProgramJob`).

    Attributes
    ----------
    mode : str
        ``tip``, ``inverse-time`` or ``per-block`` (resolved).
    spec : DialectSpec
        The control.
    tool_length : float, mm
    before : ndarray or None, shape (m,)
        As :func:`timed_program` takes them.
    """

    mode: str
    spec: DialectSpec
    tool_length: float
    before: np.ndarray | None

    @property
    def feed_mode(self) -> str:
        """The feed mode of the timed program (:attr:`urdfpost.program.Program.feed_mode`)."""
        return FEED_INVERSE_TIME if self.mode == FEED_INVERSE else FEED_PER_MINUTE

    def timed(self, program: Program, machine: Machine) -> tuple[Program, FeedFigures]:
        """:func:`timed_program` of ``program`` on ``machine``."""
        return timed_program(program, machine, self.mode, self.spec, self.tool_length, self.before)


def timed_program(
    program: Program,
    machine: Machine,
    mode: str,
    spec: DialectSpec,
    tool_length: float,
    before: np.ndarray | None = None,
) -> tuple[Program, FeedFigures]:
    """The program with the F of every feed block for the feed mode, capped by the axes.

    Parameters
    ----------
    program : Program
        Feed moves carry the CL feed (mm/min); per minute.
    machine : Machine
    mode : str
        ``tip``, ``inverse-time`` or ``per-block`` (resolved, not ``auto``).
    spec : DialectSpec
        The control: its decimals, axis feed rule and largest inverse-time F.
    tool_length : float, mm
    before : ndarray, shape (m,), optional
        The program row before the first move (a piece that continues another: the other's
        last row), machine axis order, mm and rad (TCP: X, Y, Z the tip).

    Returns
    -------
    program : Program
        In :data:`~urdfpost.program.FEED_INVERSE_TIME` for ``inverse-time`` (F in 1/min),
        else per minute.
    figures : FeedFigures
    """
    if any(isinstance(p, Cycle) for p in program.parts):
        # the cycles' motion is the control's (timed by it); its time counts in the figures
        timed, figures = _timed(program, machine, mode, spec, tool_length, before)
        try:
            expanded = expand_cycles(program)
        except ValueError:  # (a cycle the control runs in a tilted plane: along its axis)
            expanded = program
        _, motion = _timed(expanded, machine, mode, spec, tool_length, before)
        return timed, replace(
            figures,
            feed_minutes=motion.feed_minutes,
            rapid_minutes=motion.rapid_minutes,
            dwell_seconds=motion.dwell_seconds,
        )
    return _timed(program, machine, mode, spec, tool_length, before)


def _timed(
    program: Program,
    machine: Machine,
    mode: str,
    spec: DialectSpec,
    tool_length: float,
    before: np.ndarray | None = None,
) -> tuple[Program, FeedFigures]:
    """:func:`timed_program` of a program's moves (its canned cycles untimed)."""
    dwells = sum(p.seconds for p in program.parts if isinstance(p, Dwell))
    if any(isinstance(p, Arc) for p in program.parts):
        # an arc keeps its CL feed per minute (its rotary axes stand still: the tip feed is the
        # linear axes' own), in inverse time one over its time along it; the blocks after it
        # are timed from its end, where the axes stand
        flat, on_arc = _arcs_as_ends(program)
        timed, figures = _timed(flat, machine, mode, spec, tool_length, before)
        feeds = timed.move_table().feed[~on_arc]
        parts = _with_feeds(program, feeds)
        # (timed along its chord there: the rest of its length at its feed)
        longer = sum(
            (length - chord) / part.feed
            for part, (length, chord) in zip(
                (p for p in program.parts if isinstance(p, Arc)),
                _arc_lengths(flat, on_arc, program),
                strict=True,
            )
            if part.feed
        )
        figures = replace(figures, feed_minutes=figures.feed_minutes + longer)
        if mode == FEED_INVERSE:
            parts = _inverse_arcs(parts, flat, on_arc, spec)
        return replace(program, blocks=parts, feed_mode=timed.feed_mode), figures
    inverse = mode == FEED_INVERSE
    figures = FeedFigures(mode=mode, dwell_seconds=float(dwells))
    table = program.move_table()
    n = len(table)
    feed_mode = FEED_INVERSE_TIME if inverse else FEED_PER_MINUTE
    if not n:
        return replace(program, feed_mode=feed_mode), figures
    values, rapid = program_joints(machine, program)
    first = machine.home[None] if before is None else before[None]
    rows = written_values(machine, np.vstack([first, values]), spec, program.units)
    blocks = np.flatnonzero(~rapid & np.isfinite(table.feed))
    q0, q1 = rows[blocks], rows[blocks + 1]
    cl_feed = table.feed[blocks]
    tcp = program.tcp
    tip = tip_lengths_at(machine, rows, blocks, tcp, tool_length)
    m0 = machine_joints(machine, q0, tcp, tool_length)
    m1 = machine_joints(machine, q1, tcp, tool_length)
    dq = m1 - m0
    units = program.units
    scale = mm_per_unit(units)
    axis_len = axis_lengths(machine, m0, m1, spec.axis_feed_rule, units)
    control_len = tip if tcp else axis_len * scale  # what a feed per minute applies to, mm
    base = (control_len if mode == FEED_TIP else tip) / cl_feed
    limit, by_axis = limit_times(machine, dq)
    in_place = (tip < IN_PLACE) & (limit <= 0.0)
    base = np.where(in_place & ~tcp, axis_len * scale / cl_feed, base)
    time = np.maximum(base, limit)
    cause = np.where(limit > base, by_axis, -1)
    if inverse and spec.inverse_time_max:
        shortest = 1.0 / spec.inverse_time_max
        cause = np.where((shortest > time) & (shortest > base), -2, cause)
        time = np.maximum(time, shortest)
    limited = (cause != -1) & (time > 0.0)
    # a turn in place has no tip feed to reduce: not counted as capped. With TCP and feeds
    # per minute, F applies to a tip that does not move: the block is the control's to time,
    # its F left at the CL feed
    capped = limited & (tip >= IN_PLACE)
    untimed = tcp & ~inverse & (tip < IN_PLACE)
    # how long the program runs: a turn in place the control times runs at the axes' limits
    fast = np.flatnonzero(rapid)
    r0 = machine_joints(machine, rows[fast], tcp, tool_length)
    r1 = machine_joints(machine, rows[fast + 1], tcp, tool_length)
    figures = replace(
        figures,
        feed_minutes=float(np.nansum(np.where(untimed, limit, time))),
        rapid_minutes=float(np.nansum(limit_times(machine, r1 - r0)[0])),
    )
    time = np.where(untimed, 0.0, time)
    still = time <= 0.0  # (or no motion in the written values: any F)
    # near an axis limit the F is rounded down: the written F never drives an axis beyond it
    near = (limited | ((limit > 0.0) & (limit >= time * (1.0 - 1e-3)))) & ~still
    with np.errstate(divide="ignore", invalid="ignore"):
        if inverse:
            feed = 1.0 / time
            unit, decimals = 1.0, spec.inverse_time_feed.decimals
        else:
            feed = control_len / time
            fmt = spec.feed_inch if units == "inch" else spec.feed_mm
            unit = spec.feed_inch_unit if units == "inch" else 1.0
            decimals = fmt.decimals
    feed = np.where(near, _floored(np.where(near, feed, 1.0), decimals, unit), feed)
    if still.any():
        feed[still] = (spec.inverse_time_max or 1e4) if inverse else cl_feed[still]
    new_feed = table.feed.copy()
    new_feed[blocks] = feed
    # figures: the lowest share of the CL feed a capped block keeps, and what capped it
    if capped.any():
        with np.errstate(divide="ignore", invalid="ignore"):
            share = np.where(capped, base / time, np.inf)
        k = int(np.argmin(share))
        lines = _following_lines(table.cl_line)
        names = [RANGE_CAP if c == -2 else machine.axis_names[c] for c in cause[capped].tolist()]
        figures = replace(
            figures,
            feed_blocks=len(blocks),
            capped_blocks=int(capped.sum()),
            worst_cl_line=int(lines[blocks[k]]) if lines[blocks[k]] >= 0 else None,
            worst_share=float(share[k]),
            capped_by={name: names.count(name) for name in sorted(set(names))},
        )
    else:
        figures = replace(figures, feed_blocks=len(blocks))
    return replace(program, blocks=_with_feeds(program, new_feed), feed_mode=feed_mode), figures


def _following_lines(cl_line: np.ndarray) -> np.ndarray:
    """The CL line of each move, or of the next move that has one (inserted moves belong to
    the CL point they move toward); -1 after the last."""
    n = len(cl_line)
    index = np.where(cl_line >= 0, np.arange(n), n)
    index = np.minimum.accumulate(index[::-1])[::-1]
    padded = np.append(cl_line, -1)
    return padded[index]


def _arcs_as_ends(program: Program) -> tuple[Program, np.ndarray]:
    """The program with each :class:`~urdfpost.program.Arc` as one feed move to its end, and
    which of its moves those are (shape (N,), bool)."""
    parts: list = []
    on_arc: list[np.ndarray] = []
    for part in program.parts:
        if isinstance(part, Arc):
            parts.append(Move(False, part.position, part.feed, part.cl_line))
            on_arc.append(np.ones(1, dtype=bool))
        else:
            parts.append(part)
            if isinstance(part, MoveTable):
                on_arc.append(np.zeros(len(part), dtype=bool))
            elif isinstance(part, Move):
                on_arc.append(np.zeros(1, dtype=bool))
    mask = np.concatenate(on_arc) if on_arc else np.zeros(0, dtype=bool)
    return replace(program, blocks=Blocks(parts)), mask


def _arc_lengths(flat: Program, on_arc: np.ndarray, program: Program) -> list[tuple[float, float]]:
    """Per :class:`~urdfpost.program.Arc` of ``program``, in order: its length along the arc
    (:meth:`~urdfpost.program.Arc.points`, from where the axes stand before it: the row before
    it in ``flat``, :func:`_arcs_as_ends`) and its chord, mm (0, 0 for an arc with no row
    before it)."""
    filled = modal_filled(flat.move_table().position)  # an axis not written stays put
    xyz = [flat.axes.index(a) for a in "XYZ"]
    rows = np.flatnonzero(on_arc)
    out: list[tuple[float, float]] = []
    arcs = [p for p in program.parts if isinstance(p, Arc)]
    for part, row in zip(arcs, rows.tolist(), strict=True):
        if row == 0:
            out.append((0.0, 0.0))
            continue
        start = [float(v) for v in filled[row - 1, xyz]]
        radius = max(max(part.radii(start, flat.axes)), 1e-6)
        points = part.points(start, flat.axes, max(radius * 1e-3, 1e-4))
        path = np.vstack([start, points])
        length = float(np.linalg.norm(np.diff(path, axis=0), axis=1).sum())
        out.append((length, float(np.linalg.norm(path[-1] - path[0]))))
    return out


def _inverse_arcs(blocks: Blocks, flat: Program, on_arc: np.ndarray, spec: DialectSpec) -> Blocks:
    """``blocks`` with each arc's F one over its time (1/min): its length along the arc
    (:func:`_arc_lengths`) at its CL feed, and no shorter than the control's largest F
    allows."""
    program = replace(flat, blocks=blocks)
    lengths = iter(_arc_lengths(flat, on_arc, program))
    parts: list = []
    for part in blocks.parts:
        if isinstance(part, Arc):
            length, _ = next(lengths)
            if part.feed is not None and length > 0.0:
                time = length / part.feed
                if spec.inverse_time_max:
                    time = max(time, 1.0 / spec.inverse_time_max)
                part = replace(part, feed=1.0 / time if time > 0.0 else spec.inverse_time_max)
        parts.append(part)
    return Blocks(parts)


def _with_feeds(program: Program, feed: np.ndarray) -> Blocks:
    """The program's blocks with the feeds of its moves replaced, in order."""
    parts: list = []
    at = 0
    for part in program.parts:
        if isinstance(part, MoveTable):
            k = len(part)
            parts.append(MoveTable(part.position, part.rapid, feed[at : at + k], part.cl_line))
            at += k
        elif isinstance(part, Move):
            value = float(feed[at])
            parts.append(replace(part, feed=None if value != value else value))
            at += 1
        else:
            parts.append(part)
    return Blocks(parts)
