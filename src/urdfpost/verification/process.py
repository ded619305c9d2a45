"""The process of a program against its CL data: feeds, spindle, tools, program end.

The geometry of a program (:mod:`urdfpost.verification.measure`) says nothing of how it cuts: a
feed, a spindle speed or a tool number changed by hand moves no axis. This module compares
them with the CL data, as the post makes its process of it
(:func:`urdfpost.posting.process.checked_process`, the *expected* toolpath: feeds filled in and
spindle restarts added where the CL data has none):

- **feeds**: every cutting move of the program (a feed move toward a CL feed point, outside a
  rewind) has a feed; in a TCP program with feeds per minute it is not above the CL feed of
  that point beyond the rounding of the written F word (below it, an axis limit may have
  slowed the block: the tip feed the block gives is measured by the verification,
  :mod:`urdfpost.verification.feeds`, as it is for inverse-time and machine-coordinate
  programs, whose F words are no tip feeds); the move that arrives at a CL feed point is no
  rapid. Where the CL data has no feed (NaN, filled by
  ``--feed`` when the program was posted) any feed is accepted, and said in a note;
- **spindle**: at every cutting move the spindle runs in the CL data's direction at its speed
  (within the rounding of the S word); where the CL data never started it (``--spindle``) any
  clockwise speed is accepted, and said;
- **tools**: the program's tool changes, in order, load the CL data's tools (``LOADTL``); a
  first tool 1 where the CL data loads none before its first move (what the post adds) is
  accepted; at every tool change the spindle is stopped (the post writes M5 before each);
- **length offset registers**: every TCP switch selects the register the CL data asks for the
  tool (``LOADTL/3,ADJUST,7``: 7; no ADJUST: the tool number), as the reader finds it
  (:attr:`urdfpost.program.Tcp.offset`: the H word, or the tool called on controls without
  registers);
- **end**: the program ends (M30, M2, END PGM) and, where the control writes one, has its
  closing line after it (Fanuc's ``%``, Heidenhain's ``END PGM``): not cut short.

The program's rows are paired with CL points by the matching of the geometry
(:func:`urdfpost.verification.match_points`): a row belongs to the first CL point reached at
or after it, the point it moves toward. Only rows whose CL point and the point before it are
both reached are compared (with a point missed, the geometry fails anyway and the pairing is
unsure); inserted rows (subdivision, approach, turns in place) move toward the point they
belong to, at its feed; rewinds (:func:`urdfpost.program.rewind_moves`) leave the path on
purpose and are not compared.

The program's spindle is the reader's: the state its :class:`~urdfpost.program.Spindle` blocks
set (a tool change does not stop it there).

Everything is said of program move and tool change indices (:class:`Fault`); the file lines
are found on the text afterwards, only for the faults (:func:`located`).

Examples
--------
>>> ProcessCheck(faults=(), notes=(), cutting_moves=0, tool_changes=0).ok
True
"""

from __future__ import annotations

import logging
import math
import re
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np

from urdfpost.errors import ProgramParseError
from urdfpost.machine import Machine
from urdfpost.program import (
    FEED_PER_MINUTE,
    Arc,
    Blocks,
    Move,
    MoveTable,
    Program,
    Spindle,
    Tcp,
    ToolChange,
    arcs_as_moves,
    plane_count,
    rewind_moves,
)
from urdfpost.tolerances import Tolerances
from urdfpost.toolpath import Motion, Toolpath
from urdfpost.verification.match import match_points, program_joints, row_points
from urdfpost.verification.planes import PlaneFrames, in_own_frame

if TYPE_CHECKING:
    from urdfpost.dialects.dialect import Dialect

log = logging.getLogger(__name__)

_DIRECTIONS = {"off": 0, "cw": 1, "ccw": 2}
"""Spindle directions as codes (arrays)."""

_LOCATE_LINES = 512
"""Lines of program text read at a time when the lines of the faults are looked for: the lines
of a piece holding a fault are read one at a time."""


@dataclass(frozen=True)
class Rounding:
    """How finely a program writes its process words.

    Attributes
    ----------
    feed : float, mm/min
        One unit of the last decimal of an F word: a written feed is within half of it.
    feed_unit : float, mm/min
        What one unit of an F word is (1 in mm programs; 25.4, or Heidenhain 2.54, in inch).
    speed : float, rpm
        One unit of the last decimal of an S word.
    """

    feed: float = 0.1
    feed_unit: float = 1.0
    speed: float = 1.0

    def feed_words(self, feed: float) -> str:
        """A feed (mm/min) as an F word of the program; "any feed" for NaN."""
        if not math.isfinite(feed):
            return "any feed (none in the CL data)"
        return f"F{_fmt(feed / self.feed_unit)}"


def rounding_of(dialect: Dialect, units: str) -> Rounding:
    """The :class:`Rounding` of a control's programs in ``units`` ("mm" or "inch")."""
    spec = dialect.spec
    return Rounding(
        feed=dialect.resolution("F", units),
        feed_unit=spec.feed_inch_unit if units == "inch" else 1.0,
        speed=spec.rpm.resolution,
    )


def end_words(dialect: Dialect) -> str:
    """The words that end a program of ``dialect``, for messages: "M30", "M30 and END PGM"
    (the end, then the line that closes the program where the control has one: Fanuc's ``%``,
    Heidenhain's ``END PGM``)."""
    spec = dialect.spec

    def words(templates: tuple[str, ...]) -> str:
        found = [re.sub(r"\s*\{.*", "", t).strip() for t in templates]
        return " ".join(w for w in found if w)

    end, close = words(spec.finish) or "M30", words(spec.program_close)
    return f"{end} and {close}" if close else end


@dataclass(frozen=True)
class Fault:
    """One way the program's process differs from the CL data.

    Attributes
    ----------
    kind : str
        "feed", "spindle", "tool change" (the spindle running at one), "tool", "register"
        (a TCP switch's length offset register) or "end".
    message : str
        What was found and what the CL data has, without the program line.
    at : str
        What the fault is at: "move" (a motion block), "tool" (a tool change), "tcp" (a TCP
        switch on) or "end" (the last line of the program).
    index : int
        Index of that motion block (the moves of :meth:`Program.moves` and the arcs, in
        order), tool change or TCP switch on (of the program's), from the start of the
        program; 0 for "end".
    count : int
        Faults of this kind in all (only the first is described).
    """

    kind: str
    message: str
    at: str
    index: int = 0
    count: int = 1

    def text(self) -> str:
        """The message, with the count of the other moves (feed and spindle faults)."""
        others = self.count - 1
        if others < 1 or self.at != "move":
            return self.message
        return f"{self.message} (and {others} more cutting move{'s' if others > 1 else ''})"


@dataclass(frozen=True)
class ProcessCheck:
    """The process of a program compared with its CL data.

    Attributes
    ----------
    faults : tuple of Fault
        The first fault of each kind found, in the order feed, spindle, tool change, tool or
        register (registers are compared when the tools agree), end.
    notes : tuple of str
        What was accepted without a value to compare with (feeds or speeds the CL data does
        not give, the tool 1 the post assumes).
    cutting_moves : int
        Program moves compared as cuts.
    tool_changes : int
        Tool changes of the program.
    """

    faults: tuple[Fault, ...]
    notes: tuple[str, ...]
    cutting_moves: int
    tool_changes: int

    @property
    def ok(self) -> bool:
        """No fault found."""
        return not self.faults

    def summary(self) -> str:
        """One line for people."""
        if self.ok:
            tools = f"{self.tool_changes} tool change{'' if self.tool_changes == 1 else 's'}"
            return (
                f"process as in the CL data: feeds and spindle at {self.cutting_moves} cutting "
                f"moves, {tools}, program end"
            )
        kinds = ", ".join(f.kind for f in self.faults)
        return f"process DIFFERS from the CL data: {kinds}"

    def as_dict(self) -> dict:
        """Plain data for JSON reports (faults without their program lines)."""
        return {
            "ok": self.ok,
            "cutting_moves": self.cutting_moves,
            "tool_changes": self.tool_changes,
            "faults": [{"kind": f.kind, "message": f.text()} for f in self.faults],
            "notes": list(self.notes),
        }


@dataclass
class _Tools:
    """Tool numbers seen so far: the program's, and the CL data's with their lines."""

    program: list[int] = field(default_factory=list)
    cl: list[tuple[int, int]] = field(default_factory=list)  # (number, CL line)
    adjust: list[int | None] = field(default_factory=list)  # the CL's ADJUST of each
    assumed: bool = False  # the post adds tool 1 before the first move
    # the program's TCP switches on: (its index among them, the tool change before it, -1
    # for none, the length offset register it selects, None: none)
    registers: list[tuple[int, int, int | None]] = field(default_factory=list)
    tcp_on: int = 0  # TCP switches on so far


def _fmt(value: float) -> str:
    return f"{value:.6g}"


def _spindle_state(part: Spindle) -> tuple[int, float]:
    """The spindle state a program's :class:`~urdfpost.program.Spindle` block sets: direction
    code and speed, rpm (0 when off)."""
    code = _DIRECTIONS.get(part.direction, 0)
    return code, float(part.rpm) if code else 0.0


def _spindle_words(code: int, rpm: float) -> str:
    """A spindle state as the messages say it: "off", "S9000 CW"."""
    if code == 0:
        return "off"
    direction = "CW" if code == 1 else "CCW"
    return f"S(any) {direction}" if math.isnan(rpm) else f"S{_fmt(rpm)} {direction}"


def _cl_spindle_changes(
    expected: Toolpath, start: tuple[int, float]
) -> tuple[list[int], list[tuple[int, float]]]:
    """Where the CL data's spindle state changes: the indices of the points of its tool loads
    and spindle records, and the states (direction code, rpm; NaN: any speed), the first of
    them ``start`` (before the first change), the last the one ``expected`` ends with."""
    at: list[int] = []
    states = [start]
    state = start
    for e in sorted(expected.events, key=lambda e: e.index):
        if e.kind == "tool":
            state = (0, 0.0)
        elif e.kind == "spindle":
            direction = str(e.data.get("direction", "cw"))
            rpm = float(e.data.get("rpm", 0.0))
            code = _DIRECTIONS.get(direction, 1)
            on = code != 0 and not rpm <= 0  # NaN: a speed the CL data does not give
            state = (code, rpm) if on else (0, 0.0)
        else:
            continue
        at.append(e.index)
        states.append(state)
    return at, states


@dataclass(frozen=True)
class RowFindings:
    """What the rows of one piece show of its process (:meth:`PieceStart.compare`).

    Attributes
    ----------
    cutting : int
        Motion blocks compared as cuts.
    free_feed, free_speed : int
        Of them, those where the CL data has no feed, no spindle speed.
    faults : tuple of Fault
        The piece's first feed fault and first spindle fault, if any, at their motion blocks
        in the whole program, each counting the piece's blocks of its kind.
    """

    cutting: int = 0
    free_feed: int = 0
    free_speed: int = 0
    faults: tuple[Fault, ...] = ()


@dataclass(frozen=True)
class PieceStart:
    """What the row comparison of one piece (feeds and spindle at its cutting moves) takes from
    the pieces before it (:meth:`ProcessChecker.begin`): with it the piece is compared on its
    own, here or in a worker process (:meth:`compare`).

    Attributes
    ----------
    row0 : int
        Index of the piece's first motion block in the whole program.
    continued : bool
        The piece starts with the row and the CL point the piece before ended with.
    spindle : tuple of (int, float)
        The program's spindle at the piece's start: direction code and speed, rpm.
    cl_spindle : tuple of (int, float)
        The CL data's (speed NaN: any).
    tool_length, pivot : float, mm
    tol : Tolerances
    rounding : Rounding
        As :class:`ProcessChecker` has them for the piece.
    """

    row0: int
    continued: bool
    spindle: tuple[int, float]
    cl_spindle: tuple[int, float]
    tool_length: float
    pivot: float
    tol: Tolerances
    rounding: Rounding

    def compare(
        self,
        program: Program,
        expected: Toolpath,
        machine: Machine,
        match: np.ndarray | None = None,
    ) -> RowFindings:
        """Compare the feeds and the spindle of the piece's cutting moves with the CL data's
        (the module docstring).

        Parameters
        ----------
        program : Program
            The piece, in its own frame (as :meth:`ProcessChecker.begin` took it).
        expected : Toolpath
            Its expected CL data.
        machine : Machine
        match : ndarray, shape (len(expected),), int, optional
            The row of ``program`` reaching each CL point, or -1, as
            :func:`~urdfpost.verification.match_points` finds it on ``machine`` with this
            piece's tool length, pivot and tolerances (the verification of the same piece:
            :func:`urdfpost.verification.verify_matched`); used when the program has no arc,
            whose moves the rows here are. None: matched here.

        Returns
        -------
        RowFindings
        """
        run = _arcs_as_moves(program, self.tol)
        table = run.move_table()
        if not len(table) or not len(expected):
            return RowFindings()
        if match is None or run is not program:
            values, _ = program_joints(machine, run)
            point, axis = row_points(machine, values, run.tcp, self.tool_length, self.pivot)
            cl_tip = expected.tip + self.pivot * expected.axis
            match = match_points(cl_tip, expected.axis, point, axis, self.tol)
        # the moves made along an arc are one block of the program: counted as one, and a
        # fault on one is at that block (a motion block: a move or an arc)
        return _Rows(self, run, table, expected, _blocks_of_rows(program, run)).compare(match)


class _Rows:
    """The row comparison of one piece (:meth:`PieceStart.compare`): its arrays, and the
    findings as they are made."""

    def __init__(
        self,
        start: PieceStart,
        program: Program,
        table: MoveTable,
        expected: Toolpath,
        block_of_row: np.ndarray,
    ) -> None:
        self.start, self.program, self.table, self.expected = start, program, table, expected
        self.block_of_row = block_of_row
        self.faults: list[Fault] = []

    def compare(self, match: np.ndarray) -> RowFindings:
        """The findings of the rows, ``match`` the row reaching each CL point (or -1)."""
        program, table, expected = self.program, self.table, self.expected
        continued, rounding = self.start.continued, self.start.rounding
        n_rows, n_cl = len(table), len(expected)
        directions, speeds = self._program_spindle()
        cl_dir, cl_rpm = self._cl_spindle()
        reached = np.flatnonzero(match >= 0)
        # the CL point each row moves toward: the first reached at or after it
        k = np.searchsorted(match[reached], np.arange(n_rows), side="left")
        inside = k < len(reached)
        owner = np.full(n_rows, -1)
        owner[inside] = reached[k[inside]]
        # compared where the point before the owner is reached too (its span is sure)
        sure = np.ones(n_cl, dtype=bool)
        sure[1:] = match[:-1] >= 0
        if continued:
            sure[0] = False  # the join point's row was the last of the piece before
        owner[(owner >= 0) & ~sure[np.maximum(owner, 0)]] = -1
        o = np.maximum(owner, 0)
        feed_point = expected.motion == int(Motion.FEED)
        aside = rewind_moves(program)
        cutting = ~table.rapid & ~aside & (owner >= 0) & feed_point[o]
        cut_blocks = self._blocks_in(np.flatnonzero(cutting))
        lines = expected.line

        # feeds: the cutting moves at their point's feed; no rapid arriving at a feed point
        want = expected.feed[o]
        got = table.feed
        free = cutting & ~np.isfinite(want)
        free_feed = self._blocks_in(np.flatnonzero(free))
        slack = 0.5 * rounding.feed + 1e-9 * np.abs(np.where(np.isfinite(want), want, 0.0))
        off = cutting & ~free & ~(np.abs(got - want) <= slack)  # (NaN: no feed programmed)
        if program.tcp and program.feed_mode == FEED_PER_MINUTE:
            # an F below the CL feed may be an axis limit's: the tip-feed measure of the
            # verification judges it (:mod:`urdfpost.verification.feeds`)
            off &= ~(got < want)
        else:
            # F words that are no tip feeds (inverse time, F per block): only a missing
            # one here, their tip feed is the verification's
            off &= ~np.isfinite(got)
        j = np.flatnonzero((match >= 0) & feed_point & sure)
        r = match[j]
        previous = np.where(j > 0, match[np.maximum(j - 1, 0)], -1)
        arrive = np.zeros(n_rows, dtype=bool)
        arrive[r[(r != previous) & table.rapid[r] & ~aside[r]]] = True
        bad = np.flatnonzero(off | arrive)
        if bad.size:
            row = int(bad[0])
            point = int(owner[row]) if owner[row] >= 0 else int(j[np.searchsorted(r, row)])
            cl_feed = rounding.feed_words(float(expected.feed[point]))
            if arrive[row]:
                message = (
                    f"a rapid move where the CL has a cutting move at {cl_feed} (CL line "
                    f"{int(lines[point])})"
                )
            elif not math.isfinite(float(got[row])):
                message = (
                    f"a cutting move with no feed where the CL has {cl_feed} (CL line "
                    f"{int(lines[point])})"
                )
            else:
                message = (
                    f"feed {rounding.feed_words(float(got[row]))} where the CL has {cl_feed} "
                    f"(CL line {int(lines[point])})"
                )
            self._found("feed", message, row, self._blocks_in(bad))

        # spindle: running in the CL's direction at its speed at every cutting move
        want_dir, want_rpm = cl_dir[o], cl_rpm[o]
        any_speed = cutting & np.isnan(want_rpm)
        free_speed = self._blocks_in(np.flatnonzero(any_speed))
        speed_slack = 0.5 * rounding.speed + 1e-9 * np.nan_to_num(np.abs(want_rpm))
        wrong = cutting & (
            (directions != want_dir) | (~any_speed & ~(np.abs(speeds - want_rpm) <= speed_slack))
        )
        bad = np.flatnonzero(wrong)
        if bad.size:
            row = int(bad[0])
            point = int(owner[row])
            have = _spindle_words(int(directions[row]), float(speeds[row]))
            need = _spindle_words(int(want_dir[row]), float(want_rpm[row]))
            self._found(
                "spindle",
                f"spindle {have} where the CL has {need} (CL line {int(lines[point])})",
                row,
                self._blocks_in(bad),
            )
        return RowFindings(cut_blocks, free_feed, free_speed, tuple(self.faults))

    def _program_spindle(self) -> tuple[np.ndarray, np.ndarray]:
        """The program's spindle direction code and speed (rpm) at each row."""
        sizes: list[int] = []
        dirs: list[int] = []
        rpms: list[float] = []
        state = self.start.spindle
        for part in self.program.parts:
            if isinstance(part, MoveTable | Move):
                sizes.append(len(part) if isinstance(part, MoveTable) else 1)
                dirs.append(state[0])
                rpms.append(state[1])
            elif isinstance(part, Spindle):
                state = _spindle_state(part)
        count = np.array(sizes, dtype=np.int64)
        return (
            np.repeat(np.array(dirs, dtype=np.int64), count),
            np.repeat(np.array(rpms, dtype=float), count),
        )

    def _cl_spindle(self) -> tuple[np.ndarray, np.ndarray]:
        """The CL data's spindle direction code and speed (rpm, NaN: any) at each point."""
        at, states = _cl_spindle_changes(self.expected, self.start.cl_spindle)
        n = len(self.expected)
        k = np.searchsorted(np.array(at, dtype=np.int64), np.arange(n), side="right") - 1
        codes = np.array([s[0] for s in states], dtype=np.int64)
        rpms = np.array([s[1] for s in states], dtype=float)
        return codes[k + 1], rpms[k + 1]

    def _blocks_in(self, rows: np.ndarray) -> int:
        """How many motion blocks the piece's ``rows`` are (an arc's moves are one)."""
        if len(self.block_of_row) == 0 or rows.size == 0:
            return int(rows.size)
        return distinct(self.block_of_row[rows])

    def _found(self, kind: str, message: str, row: int, count: int) -> None:
        """The piece's first fault of ``kind``, at ``row``, and how many blocks have one."""
        block = int(self.block_of_row[row]) if row < len(self.block_of_row) else row
        self.faults.append(Fault(kind, message, "move", self.start.row0 + block, count))


class ProcessChecker:
    """Checks the process of a program given in consecutive pieces (a streamed verification).

    Each piece is a program and the expected CL data it was checked against; a piece after the
    first starts with the row and the CL point the piece before ended with (as
    :func:`urdfpost.posting.readback.verify_stream` cuts them). :func:`check_process` is the
    check of a whole program.

    :meth:`add` checks a piece in three steps, which a streamed verification takes apart: what
    follows the pieces in order (tools, spindle states, where the piece's blocks start) is
    :meth:`begin`, here; the comparison of the piece's rows (:meth:`PieceStart.compare`)
    needs nothing else, and runs where the piece is verified; :meth:`take` adds its findings,
    in the pieces' order.

    Parameters
    ----------
    machine : Machine
    tol : Tolerances
        Of the geometric matching (as the verification's).
    tool_length : float, mm
        The tool length machine-coordinate positions include.
    pivot : float, mm
        The measured point up the tool axis (as :func:`urdfpost.verification.verify`).
    rounding : Rounding, optional
        Of the written F and S words (:func:`rounding_of`); the feeds of the messages are in
        the program's F units.
    end : str
        The words that end a program, for the message (:func:`end_words`).
    stop_at_tool_change : bool
        The spindle must be stopped at every tool change: the post stops it (M5) before each
        one, for every control (:meth:`urdfpost.posting.transitions.Transitions.leave`), and
        does not count on the control's tool change to do it.
    """

    def __init__(
        self,
        machine: Machine,
        *,
        tol: Tolerances,
        tool_length: float,
        pivot: float = 0.0,
        rounding: Rounding | None = None,
        end: str = "M30",
        stop_at_tool_change: bool = True,
    ) -> None:
        self.machine = machine
        self.stop_at_tool_change = stop_at_tool_change
        self.tol = tol
        self.tool_length = tool_length
        self.pivot = pivot
        self.rounding = rounding or Rounding()
        self.end = end
        self._pieces = 0
        self._row0 = 0  # index of the next piece's first motion block in the whole program
        self._program_spindle: tuple[int, float] = (0, 0.0)
        self._cl_spindle: tuple[int, float] = (0, 0.0)
        self._tools = _Tools()
        self._first: dict[str, Fault] = {}
        self._counts: dict[str, int] = {}
        self._cutting = 0
        self._free_feed = 0  # cutting moves where the CL data has no feed
        self._free_speed = 0  # cutting moves where the CL data has no speed
        self._ended: bool | None = None

    # -- pieces ------------------------------------------------------------------------------

    def add(
        self,
        program: Program,
        expected: Toolpath,
        *,
        ended: bool | None = None,
        fresh: bool = False,
        tool_length: float | None = None,
        machine: Machine | None = None,
        match: np.ndarray | None = None,
    ) -> None:
        """Check the next piece.

        Parameters
        ----------
        program : Program
            The piece of the program, as read from its text.
        expected : Toolpath
            The piece of the CL data, as :func:`urdfpost.posting.process.checked_process`
            makes it (with the spindle state carried from the piece before).
        ended : bool, optional
            The last piece: whether the program text has its end (None: not checked).
        fresh : bool
            The piece shares no row and no CL point with the one before: it begins a tool
            section (:mod:`urdfpost.posting.tools`).
        tool_length : float, optional, mm
            The gauge length of the piece's machine-coordinate rows, from this piece on
            (default: as before).
        machine : Machine, optional
            The machine of the piece's rows, from this piece on: a section in another MCS,
            its program zero elsewhere (default: as before).
        match : ndarray, optional
            The row reaching each CL point as the verification of the piece matched them
            with this checker's tolerances and pivot and the piece's tool length and machine
            (:func:`urdfpost.verification.verify_matched`), as :meth:`PieceStart.compare`
            takes it; None: matched here.
        """
        on = self.machine if machine is None else machine
        program = in_own_frame(program, on)  # (as many moves, in the program's frame)
        start = self.begin(
            program, expected, ended=ended, fresh=fresh, tool_length=tool_length, machine=machine
        )
        self.take(start.compare(program, expected, on, match))

    def begin(
        self,
        program: Program,
        expected: Toolpath,
        *,
        ended: bool | None = None,
        fresh: bool = False,
        tool_length: float | None = None,
        machine: Machine | None = None,
    ) -> PieceStart:
        """The part of :meth:`add` that follows the pieces in order: the program's tool changes
        and TCP switches, the CL data's tool loads, the spindle states the piece starts and ends
        with, where its motion blocks start in the whole program. Its rows are compared with
        the returned :meth:`PieceStart.compare` (here, or in a worker process with what the
        verification of the piece matched), whose findings :meth:`take` adds, in the pieces'
        order.

        Parameters
        ----------
        program : Program
            The piece of the program in its own frame (its tilted planes taken out:
            :func:`~urdfpost.verification.planes.in_own_frame`).
        expected, ended, fresh, tool_length, machine
            As :meth:`add`.

        Returns
        -------
        PieceStart
        """
        first = self._pieces == 0
        if machine is not None:
            self.machine = machine
        if fresh and not first:
            self._row0 += 1  # the piece before's last row is not this piece's first
        self._pieces += 1
        if tool_length is not None:
            self.tool_length = tool_length
        if ended is not None:
            self._ended = ended
        if first:
            first_tool = min(
                (e.index for e in expected.events if e.kind == "tool"), default=len(expected) + 1
            )
            self._tools.assumed = len(expected) > 0 and first_tool > 0
        start = PieceStart(
            row0=self._row0,
            continued=not first and not fresh,
            spindle=self._program_spindle,
            cl_spindle=self._cl_spindle,
            tool_length=self.tool_length,
            pivot=self.pivot,
            tol=self.tol,
            rounding=self.rounding,
        )
        self._program_blocks(program)
        loads = [e for e in sorted(expected.events, key=lambda e: e.index) if e.kind == "tool"]
        self._tools.cl += [(int(e.data.get("number", 0)), e.line) for e in loads]
        self._tools.adjust += [
            None if e.data.get("adjust") is None else int(e.data["adjust"]) for e in loads
        ]
        _, states = _cl_spindle_changes(expected, self._cl_spindle)
        self._cl_spindle = states[-1]
        # a move or an arc is one motion block (an arc is checked as the moves along it)
        blocks = sum(
            len(p) if isinstance(p, MoveTable) else 1
            for p in program.parts
            if isinstance(p, MoveTable | Move | Arc)
        )
        if blocks:
            self._row0 += blocks - 1  # the next piece starts with this piece's last row
        return start

    def take(self, found: RowFindings) -> None:
        """Add what the rows of the next piece show (:meth:`PieceStart.compare` of what
        :meth:`begin` gave for it; the pieces taken in the order they were begun)."""
        self._cutting += found.cutting
        self._free_feed += found.free_feed
        self._free_speed += found.free_speed
        for fault in found.faults:
            self._counts[fault.kind] = self._counts.get(fault.kind, 0) + fault.count
            self._first.setdefault(fault.kind, fault)

    def result(self) -> ProcessCheck:
        """What the pieces added so far show."""
        faults = [self._counted(k) for k in ("feed", "spindle", "tool change") if k in self._first]
        tool = self._tool_fault()
        if tool is not None:
            faults.append(tool)
        else:
            register = self._register_fault()
            if register is not None:
                faults.append(register)
        if self._ended is False:
            faults.append(
                Fault(
                    "end",
                    f"no program end ({self.end}) after this line: the program is cut short",
                    "end",
                )
            )
        notes = []
        if self._free_feed:
            notes.append(
                f"{self._free_feed} cutting moves with no feed in the CL data (--feed when posted):"
                f" any feed accepted there"
            )
        if self._free_speed:
            notes.append(
                f"{self._free_speed} cutting moves where the CL data starts no spindle "
                f"(--spindle when posted): any clockwise speed accepted there"
            )
        tools = self._tools
        if tools.assumed and tools.program[:1] == [1] and self._tools_match(with_first=True):
            notes.append("no tool change in the CL data before its first move: tool 1 accepted")
        return ProcessCheck(
            faults=tuple(faults),
            notes=tuple(notes),
            cutting_moves=self._cutting,
            tool_changes=len(tools.program),
        )

    # -- the parts of a piece ----------------------------------------------------------------

    def _program_blocks(self, program: Program) -> None:
        """Record the tool changes and TCP switches of ``program`` (the next piece) and the
        spindle state it ends with."""
        state = self._program_spindle
        for part in program.parts:
            if isinstance(part, Spindle):
                state = _spindle_state(part)
            elif isinstance(part, ToolChange):
                if state[0] and self.stop_at_tool_change:
                    self._running_change(int(part.number), state)
                self._tools.program.append(int(part.number))
            elif isinstance(part, Tcp) and part.on:
                tools = self._tools
                tools.registers.append((tools.tcp_on, len(tools.program) - 1, part.offset))
                tools.tcp_on += 1
        self._program_spindle = state

    def _running_change(self, number: int, state: tuple[int, float]) -> None:
        """A tool change (the next of the program's) with the spindle running."""
        kind = "tool change"
        self._counts[kind] = self._counts.get(kind, 0) + 1
        if kind not in self._first:
            running = _spindle_words(*state)
            self._first[kind] = Fault(
                kind,
                f"tool change to T{number} with the spindle running ({running}); expected it "
                "stopped (M5) before the tool change, as the post writes it",
                "tool",
                len(self._tools.program),
            )

    def _counted(self, kind: str) -> Fault:
        first = self._first[kind]
        return Fault(first.kind, first.message, first.at, first.index, self._counts[kind])

    # -- tools -------------------------------------------------------------------------------

    def _register_fault(self) -> Fault | None:
        """The first TCP switch whose length offset register is not the CL's (its ADJUST,
        else the tool number), when the program's tools are the CL's."""
        tools = self._tools
        with_first = tools.assumed and self._tools_match(with_first=True)
        want = self._expected_tools(with_first)
        adjust = ([None] if with_first else []) + tools.adjust
        wrong: list[tuple[int, str]] = []
        for at, tool, register in tools.registers:
            if tool < 0:
                continue  # TCP on before any tool: the geometry (no tool length) tells
            number, line = want[tool]
            asked = adjust[tool]
            expected = number if asked is None else asked
            if register == expected:
                continue
            where = "" if line is None else f" (CL line {line})"
            cl = (
                f"ADJUST,{asked}{where}"
                if asked is not None
                else f"tool {number} and no ADJUST{where}: register {number}"
            )
            have = "none" if register is None else str(register)
            wrong.append((at, f"length offset register {have} for T{number} where the CL has {cl}"))
        if not wrong:
            return None
        at, message = wrong[0]
        return Fault("register", message, "tcp", at, len(wrong))

    def _expected_tools(self, with_first: bool) -> list[tuple[int, int | None]]:
        first: list[tuple[int, int | None]] = [(1, None)] if with_first else []
        return first + [(n, line) for n, line in self._tools.cl]

    def _tools_match(self, with_first: bool) -> bool:
        expected = [n for n, _ in self._expected_tools(with_first)]
        return self._tools.program == expected

    def _tool_fault(self) -> Fault | None:
        tools = self._tools
        options = [True, False] if tools.assumed else [False]
        if any(self._tools_match(o) for o in options):
            return None
        # against the expectation the program follows further
        program = tools.program

        def agree(with_first: bool) -> int:
            want = self._expected_tools(with_first)
            k = 0
            while k < min(len(want), len(program)) and want[k][0] == program[k]:
                k += 1
            return k

        with_first = max(options, key=agree)
        want = self._expected_tools(with_first)
        k = agree(with_first)
        if k < len(want) and k < len(program):
            number, line = want[k]
            where = (
                "loads no tool before its first move: tool 1"
                if line is None
                else (f"loads tool {number} (CL line {line})")
            )
            message = f"tool T{program[k]} where the CL {where}"
            return Fault("tool", message, "tool", k, len(program) - k)
        if k < len(program):
            loads = ", ".join(str(n) for n, _ in want) or "none"
            return Fault(
                "tool",
                f"tool change T{program[k]} that the CL does not have (it loads {loads})",
                "tool",
                k,
                len(program) - k,
            )
        number, line = want[k]
        return Fault(
            "tool",
            f"no tool change to T{number}: the CL loads it at line {line}; the program changes "
            f"tools {len(program)} times, the CL {len(want)}",
            "end",
            0,
            len(want) - k,
        )


def check_process(
    program: Program,
    machine: Machine,
    expected: Toolpath,
    *,
    tol: Tolerances | None = None,
    tool_length: float | None = None,
    pivot: float = 0.0,
    rounding: Rounding | None = None,
    ended: bool | None = None,
    end: str = "M30",
) -> ProcessCheck:
    """The process of a whole program against the CL data (see the module docstring).

    Parameters
    ----------
    program : Program
        As read from its text.
    machine : Machine
    expected : Toolpath
        The CL data as :func:`urdfpost.posting.process.checked_process` makes it; feeds (and
        spindle speeds) NaN where the CL data gives none.
    tol : Tolerances, optional
        Of the matching (default those of the program's units).
    tool_length : float, optional, mm
        Default the program's.
    pivot : float, mm
        As :func:`urdfpost.verification.verify`.
    rounding : Rounding, optional
        Of the written words (:func:`rounding_of`).
    ended : bool, optional
        Whether the program text has its end (:func:`read_with_end`); None: not checked.
    end : str
        The words that end a program (:func:`end_words`).

    Returns
    -------
    ProcessCheck
    """
    checker = ProcessChecker(
        machine,
        tol=tol or Tolerances.for_units(program.units),
        tool_length=program.tool_length if tool_length is None else tool_length,
        pivot=pivot,
        rounding=rounding,
        end=end,
    )
    checker.add(program, expected, ended=ended)
    return checker.result()


class PieceProcess:
    """The process check of a program written in pieces (a streamed post): each piece's
    text is read back with one reader (its modal state carries on) and checked against the
    piece's expected CL data, from the last row of the piece before, as a whole program is
    by :func:`check_process`.

    Parameters
    ----------
    dialect : Dialect
        Of the program.
    machine : Machine
    path : str
        The program, for the reader's messages.
    tol, tool_length, rounding
        As :class:`ProcessChecker`.
    """

    def __init__(
        self,
        dialect: Dialect,
        machine: Machine,
        path: str,
        *,
        tol: Tolerances,
        tool_length: float,
        rounding: Rounding | None = None,
    ) -> None:
        self.checker = ProcessChecker(
            machine, tol=tol, tool_length=tool_length, rounding=rounding, end=end_words(dialect)
        )
        self.reader = dialect.reader(path, rollover=machine.settings.rollover)
        self.frames = PlaneFrames(machine)
        self._last: tuple[tuple[str, ...], np.ndarray] | None = None  # axes, last row

    def add(
        self,
        text: str,
        inserts: Iterable[str],
        expected: Toolpath,
        *,
        fresh: bool = False,
        tool_length: float | None = None,
        machine: Machine | None = None,
    ) -> None:
        """Check the next piece: its text (whole lines), the texts of its inserted blocks and
        its expected CL data (starting with the CL point the piece before ended with, unless
        ``fresh``: a section of its own, with its ``tool_length`` and ``machine``, as
        :meth:`ProcessChecker.add` takes them).

        Raises
        ------
        ProgramParseError
            A line that cannot be read.
        """
        self.reader.feed(text, inserts)
        program = self.frames.feed(self.reader.take())  # (the planes' moves in the program's)
        self.add_program(program, expected, fresh=fresh, tool_length=tool_length, machine=machine)

    def add_program(
        self,
        program: Program,
        expected: Toolpath,
        *,
        fresh: bool = False,
        tool_length: float | None = None,
        machine: Machine | None = None,
    ) -> None:
        """:meth:`add` of a piece read already: ``program`` is what a reader that has read the
        pieces before gives for its text, its planes' moves in the program's coordinates
        (:class:`~urdfpost.verification.planes.PlaneFrames`), as the verification of the same
        piece reads it (one read for both checks)."""
        if self._last is not None and not fresh:
            axes, row = self._last
            position = np.array([row[axes.index(a)] if a in axes else np.nan for a in program.axes])
            start = MoveTable(position[None], np.zeros(1, bool), np.full(1, np.nan), np.full(1, -1))
            program = replace(program, blocks=Blocks((start, *program.parts)))
        self.checker.add(program, expected, fresh=fresh, tool_length=tool_length, machine=machine)
        table = _arcs_as_moves(program, self.checker.tol).move_table()  # where it ends
        if len(table):
            self._last = (program.axes, np.asarray(table.position[-1]))

    def result(self) -> ProcessCheck:
        """What the pieces so far show."""
        return self.checker.result()


# -- the program text ------------------------------------------------------------------------


def read_with_end(
    dialect: Dialect,
    text: str,
    path: str = "<string>",
    verbatim: Iterable[str] = (),
    rollover: frozenset[str] = frozenset(),
) -> tuple[Program, bool]:
    """A program read from its text, and whether the text has the program end (M30, M2,
    END PGM): what :meth:`Dialect.read` gives, and the end it does not say.

    Raises
    ------
    ProgramParseError
        A line that cannot be read.
    """
    reader = dialect.reader(path, rollover=rollover)
    reader.feed(text, verbatim)
    return reader.take(), reader.builder.ended


def _chunks(texts: Iterable[str]) -> Iterator[list[str]]:
    """The lines of ``texts`` (pieces cut at line ends), :data:`_LOCATE_LINES` at a time, each
    with its end of line."""
    for text in texts:
        lines = text.splitlines(keepends=True)
        for start in range(0, len(lines), _LOCATE_LINES):
            yield lines[start : start + _LOCATE_LINES]


def _arcs_as_moves(program: Program, tol: Tolerances) -> Program:
    """``program`` with its arcs as the moves the control makes along them, at most the tip
    tolerance apart (:func:`urdfpost.program.arcs_as_moves`): the CL points on an arc are
    reached by them, and each carries the arc's feed and spindle, which are checked as any
    move's."""
    if not any(isinstance(p, Arc) for p in program.parts):
        return program
    try:
        return arcs_as_moves(program, tol.tip)
    except ValueError as e:
        raise ProgramParseError(program.name, 0, str(e)) from None


def distinct(values: np.ndarray) -> int:
    """How many distinct values ``values`` (shape (n,)) holds: its changes counted where it is
    in order (the blocks of rows taken in order), else by sorting."""
    steps = np.diff(values)
    if (steps >= 0).all():
        return int(values.size > 0) + int(np.count_nonzero(steps))
    return int(np.unique(values).size)


def _blocks_of_rows(written: Program, run: Program) -> np.ndarray:
    """For each move of ``run`` (``written`` with its arcs as moves, :func:`_arcs_as_moves`),
    the motion block of ``written`` it belongs to (its moves and arcs counted in order),
    shape (rows,)."""
    out: list[np.ndarray] = []
    block = 0
    for part, ran in zip(written.parts, run.parts, strict=True):
        if isinstance(part, Arc):
            assert isinstance(ran, MoveTable)
            out.append(np.full(len(ran), block, dtype=np.int64))
            block += 1
        elif isinstance(part, MoveTable | Move):
            k = len(part) if isinstance(part, MoveTable) else 1
            out.append(block + np.arange(k, dtype=np.int64))
            block += k
    return np.concatenate(out) if out else np.zeros(0, dtype=np.int64)


def _counts(program: Program) -> tuple[int, int, int]:
    """Motion blocks (moves and arcs), tool changes and TCP switches on of ``program`` (a tilted
    plane switched on counts as one: :func:`urdfpost.program.untilted`)."""
    tools = sum(1 for p in program.parts if isinstance(p, ToolChange))
    tcps = sum(1 for p in program.parts if isinstance(p, Tcp) and p.on) + plane_count(program)
    arcs = sum(1 for p in program.parts if isinstance(p, Arc))
    return len(program.move_table()) + arcs, tools, tcps


def located(
    check: ProcessCheck,
    dialect: Dialect,
    texts: Callable[[], Iterable[str]],
    path: str,
    verbatim: Iterable[str] = (),
) -> list[str]:
    """The faults of ``check`` as messages ``path:line: message``.

    The text is read twice: once a few hundred lines at a time, counting the moves and tool
    changes, and again with the pieces that hold a fault read one line at a time.

    Parameters
    ----------
    check : ProcessCheck
    dialect : Dialect
        Of the program.
    texts : callable
        Gives the program text, in pieces cut at line ends, each time it is called.
    path : str
        The program file, for the messages.
    verbatim : iterable of str
        As :meth:`Dialect.read`.

    Returns
    -------
    list of str
        One per fault, in order; a fault at a move names the line of that move, at a tool
        change the line of its T word, at a TCP switch the line of its H word (else of the
        switch), at the end the last line that is not blank.

    Raises
    ------
    ProgramParseError
        A line that cannot be read (the text is not the one checked).
    """
    if check.ok:
        return []
    inserts = list(verbatim)
    wanted = {(f.at, f.index) for f in check.faults if f.at != "end"}
    holding: set[int] = set()  # chunks with a fault
    reader = dialect.reader(path)
    moves = tools = tcps = line = last = 0
    for c, chunk in enumerate(_chunks(texts())):
        reader.feed("".join(chunk), inserts)
        m, t, p = _counts(reader.take())
        if any(
            (at == "move" and moves <= i < moves + m)
            or (at == "tool" and tools <= i < tools + t)
            or (at == "tcp" and tcps <= i < tcps + p)
            for at, i in wanted
        ):
            holding.add(c)
        for k, text in enumerate(chunk):
            if text.strip():
                last = line + k + 1
        moves, tools, tcps, line = moves + m, tools + t, tcps + p, line + len(chunk)
    lines: dict[tuple[str, int], int] = {("end", 0): last}
    if holding:
        holding |= {c - 1 for c in holding if c > 0}  # (a T word a line before its M6)
        reader = dialect.reader(path)
        moves = tools = tcps = line = 0
        selected: int | None = None  # the line that selected the tool (T word), if read
        register: int | None = None  # the line of the H word before a TCP switch, if read
        for c, chunk in enumerate(_chunks(texts())):
            if c not in holding:
                reader.feed("".join(chunk), inserts)
                m, t, p = _counts(reader.take())
                moves, tools, tcps, line = moves + m, tools + t, tcps + p, line + len(chunk)
                selected = register = None
                continue
            for text in chunk:
                line += 1
                tool = reader.builder.tool
                reader.feed(text, inserts)
                if reader.builder.tool != tool or re.search(r"(?<![A-Z])T\d", text.upper()):
                    selected = line
                if re.search(r"(?<![A-Z])H\d", text.upper()):
                    register = line  # (LinuxCNC: G43 H7 the line before M428)
                m, t, p = _counts(reader.take())
                for at, i in wanted:
                    if at == "move" and moves <= i < moves + m:
                        lines[at, i] = line
                    elif at == "tcp" and tcps <= i < tcps + p:
                        lines[at, i] = line if register is None else register
                    elif at == "tool" and tools <= i < tools + t:
                        lines[at, i] = line if selected is None else selected
                if t:
                    selected = None
                if p:
                    register = None
                moves, tools, tcps = moves + m, tools + t, tcps + p
    return [f"{path}:{lines.get((f.at, f.index), last)}: {f.text()}" for f in check.faults]
