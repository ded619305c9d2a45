"""NC text -> Program, for any :class:`~urdfpost.dialects.spec.DialectSpec`.

Two layers:

* :class:`ProgramBuilder` holds the control's modal state while a program is read (units,
  absolute/incremental, motion mode, feed, axis positions, tool, spindle, TCP) and turns
  semantic events into :class:`~urdfpost.program.Program` blocks.
* :func:`parse_gcode_line` reads one line of word-address G-code (Fanuc, Siemens, LinuxCNC) into
  those events, driven by the spec's code tables. Heidenhain conversational brings its own line
  parser (:attr:`DialectSpec.parse_line`) feeding the same builder.

Reading rules:

* Positions come out in mm and degrees whatever the file units; feeds in mm/min.
* Axis words are modal: every :class:`Move` carries the position of every axis of the program.
  An axis that has not been programmed yet, or whose position became unknown after a home
  return or a machine-coordinate block, is NaN.
* Rapid moves have ``feed=None``; feed moves carry the modal feed (None before any F word).
* Feed mode (G93 / G94, where the control has them): in inverse time (G93) the F words are
  1/min whatever the units and every feed block must have one; a switch of mode forgets the
  modal feed. The feed moves of a program are all in one mode, the program's
  :attr:`~urdfpost.program.Program.feed_mode`.
* Consecutive motion blocks come out as one :class:`~urdfpost.program.MoveTable` in the
  program's parts (``cl_line`` -1: a program read from text does not know its CL lines).
* A program's ``axes`` are the axis letters used in motion blocks, in X Y Z A B C order.
* ``tcp`` is whether TCP was on at the first feed move (or was switched on at all, when the
  program has no feed move).
* Spindle and TCP blocks are emitted when the state changes, so a repeated ``M3`` or a ``G49``
  in the safety line with TCP already off adds nothing.
* Consecutive home returns (Fanuc ``G28 G91 Z0.`` then ``G28 X0. Y0.``) are one :class:`Home`.
* Arcs (G2/G3 with I J K, incremental from the start unless ``I=AC(..)``, in the plane of
  G17/G18/G19; Heidenhain ``CC`` + ``C``) come out as :class:`~urdfpost.program.Arc` blocks
  between the tables; cutter compensation (G41/G42 with D, G40; Heidenhain RL/RR/R0) as
  :class:`~urdfpost.program.CutterComp` blocks when it changes.
* Nothing that can move the machine is skipped: an unknown word, code or line, a malformed
  number, arcs by radius (``R``), canned cycles and the like raise
  :class:`~urdfpost.errors.ProgramParseError` with the file, line and what was expected.
"""

from __future__ import annotations

import itertools
import math
import re
from collections.abc import Iterable
from dataclasses import dataclass, field, replace
from pathlib import PurePath

import numpy as np

from urdfpost.dialects import _bulk
from urdfpost.dialects._cycles import (
    ISO_KINDS,
    CycleDefinition,
    cycle_of,
    iso_definition,
    siemens_definition,
)
from urdfpost.dialects.spec import AXIS_ORDER, ROTARY_ADDRESSES, DialectSpec
from urdfpost.errors import ProgramParseError
from urdfpost.program import (
    ARC_PLANES,
    FEED_INVERSE_TIME,
    FEED_PER_MINUTE,
    Arc,
    Block,
    Blocks,
    Clamp,
    Comment,
    Coolant,
    CutterComp,
    Dwell,
    Home,
    Insert,
    MoveTable,
    Program,
    Smoothing,
    Spindle,
    Stop,
    Tcp,
    TiltedPlane,
    ToolChange,
    WorkOffset,
    rollover_target,
)
from urdfpost.units import mm_per_unit

NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)\Z")

#: Why common codes this reader refuses are refused.
_G_HINTS = {
    "2": "circular interpolation is not supported",
    "3": "circular interpolation is not supported",
    "41": "cutter radius compensation is not supported",
    "42": "cutter radius compensation is not supported",
    "43": "tool length compensation without TCP is not supported",
    "43.5": "vector TCP (G43.5) is not supported",
    "93": "inverse-time feed is not supported",
    "95": "feed per revolution is not supported",
    **{str(c): "canned cycles are not supported" for c in range(73, 90) if c != 80},
}


@dataclass
class _ReadMove:
    rapid: bool
    position: dict[str, float]
    feed: float | None


@dataclass
class _ReadCycle:
    """A canned cycle read, with its holes so far (positions per address, mm / degrees)."""

    definition: CycleDefinition
    holes: list[dict[str, float]]


@dataclass
class _ReadArc:
    """An arc read: its end (every axis known so far), centre (X, Y, Z, mm), plane, sense."""

    position: dict[str, float]
    centre: tuple[float, float, float]
    plane: str
    clockwise: bool
    feed: float | None


class _ReadMoves:
    """Consecutive moves read at once.

    Attributes
    ----------
    position : ndarray, shape (k, 6)
        Positions in mm and degrees, columns in AXIS_ORDER; NaN where unknown.
    rapid : ndarray, shape (k,), bool
    feed : ndarray, shape (k,)
        mm/min; NaN for rapids and before any feed.
    """

    def __init__(self, position: np.ndarray, rapid: np.ndarray, feed: np.ndarray) -> None:
        self.position = position
        self.rapid = rapid
        self.feed = feed

    def columns(self, axes: tuple[str, ...]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Positions of ``axes`` (shape (k, len(axes))), rapid flags and feeds."""
        position = self.position[:, [AXIS_ORDER.index(a) for a in axes]]
        return position, self.rapid, self.feed


def _columns_of_singles(
    moves: list[_ReadMove], axes: tuple[str, ...]
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Moves read one by one as :meth:`_ReadMoves.columns` gives them (NaN: unknown, no feed)."""
    k = len(moves)
    rows = [[m.position.get(a, math.nan) for a in axes] for m in moves]
    position = np.array(rows, dtype=float).reshape(k, len(axes))
    rapid = np.array([m.rapid for m in moves], dtype=bool).reshape(k)
    feed = np.array([math.nan if m.feed is None else m.feed for m in moves], dtype=float)
    return position, rapid, feed.reshape(k)


class ProgramBuilder:
    """Modal state of a control while a program is read, and the blocks read so far.

    Parameters
    ----------
    spec : DialectSpec
        The control.
    path : str
        File name for error messages.
    """

    def __init__(self, spec: DialectSpec, path: str) -> None:
        self.spec = spec
        self.path = path
        self.line = 0
        self.name: str | None = None
        self.units: str | None = None
        self.linear_scale = 1.0
        self.feed_scale = 1.0
        self.absolute = True
        self.motion: bool | None = None  # True rapid, False linear
        self.arc: bool | None = None  # in arc mode: True clockwise (G2), False (G3)
        self.plane = "XY"  # the arc plane (G17)
        self.circle_centre: tuple[float, float] | None = None  # Heidenhain CC, file units
        self.comp: tuple[str, int | None, str] = ("off", None, "XY")  # radius compensation
        self.feed: float | None = None
        self.position: dict[str, float] = {}
        self.axes_seen: set[str] = set()
        self.tcp = False
        self.tcp_ever = False
        self.tcp_at_first_feed: bool | None = None
        self.cut_without_tcp: int | None = None  # line of the first X/Y/Z feed move, TCP off
        self.tool: int | None = None
        self.offset: int | None = None  # the H word since the last tool change
        self.rpm = 0.0
        self.spindle_state: tuple[str, float] = ("off", 0.0)
        self._speed_change: Block | _ReadMove | _ReadMoves | _ReadCycle | _ReadArc | None = None
        self.continuous = False
        self.work_offset: str | None = None
        self.offset_change: tuple[int, str] | None = None  # line and words of the first change
        self.cycle: int | None = None  # a cycle whose parameters follow on the next lines
        # canned drilling cycles: the one active (ISO G81..., Siemens MCALL, Heidenhain CYCL
        # DEF 200...), its block of holes read so far, G98 (True) or G99
        self.drill: CycleDefinition | None = None
        self.drill_block: _ReadCycle | None = None
        self.drill_initial = True
        self.drill_q: dict[int, float] = {}  # Heidenhain Q parameters of a CYCL DEF
        self.drill_defined: CycleDefinition | None = None  # Heidenhain: the last CYCL DEF
        self.finished = False  # the program end (M30, M2, END PGM) was read
        self.closed = not spec.program_close  # its closing line (Fanuc %, END PGM) too
        self.code_seen = False
        self.feed_mode = FEED_PER_MINUTE  # the control's (G94 / G93)
        self.moves_feed_mode: str | None = None  # the mode of the feed moves read
        self.feed_word_line = 0  # line of the last F word
        self.items: list[Block | _ReadMove | _ReadMoves | _ReadCycle | _ReadArc] = []
        # the text line of every move read, in order (the 3-D view shows each block's line)
        self.move_lines: list[int | np.ndarray] = []
        # continuous rotary axes the control rolls over (modulo 360), as the machine says
        self.rollover: frozenset[str] = frozenset()
        self.smoothing_state = Smoothing(False)
        # a smoothing switched on whose rotary tolerance may follow on the next line
        self.smoothing_pending: Smoothing | None = None
        self.arc_lines: list[int] = []  # the text line of every arc read
        self.plane_on = False  # a tilted working plane is on
        self.plane_frame = np.eye(3)  # its axes (columns) in the program's frame
        self.plane_pending: TiltedPlane | None = None  # a plane on not yet added to items

    # -- helpers -----------------------------------------------------------------------------

    def error(self, message: str) -> ProgramParseError:
        """A parse error at the current line."""
        return ProgramParseError(self.path, self.line, message)

    def number(self, address: str, text: str) -> float:
        """Check and convert the number of word ``address``."""
        if not NUMBER.match(text):
            raise self.error(f"malformed number {address}{text}; expected e.g. {address}12.345")
        return float(text)

    def to_internal(self, address: str, value: float) -> float:
        """File units -> mm (linear axes) or degrees (rotary)."""
        return value if address in ROTARY_ADDRESSES else value * self.linear_scale

    def _add(self, item: Block | _ReadMove | _ReadMoves | _ReadCycle | _ReadArc) -> None:
        if self.finished and not isinstance(item, Comment):
            raise self.error("code after the program end; expected nothing but comments")
        if not isinstance(item, _ReadCycle):
            self.drill_block = None  # the next hole starts another Cycle block
        if self.plane_pending is not None and not isinstance(item, Comment):
            self.items.append(self.plane_pending)  # (its length register read by now)
            self.plane_pending = None
        self.items.append(item)

    # -- canned cycles -----------------------------------------------------------------------

    def cycle_start(self, definition: CycleDefinition) -> None:
        """A canned cycle is defined (its holes follow: :meth:`cycle_hole`)."""
        self.drill = definition
        self.drill_block = None

    def cycle_hole(self, values: dict[str, tuple[float, bool]]) -> None:
        """A hole of the active cycle at the position ``values`` (as :meth:`move`) names; the
        tool ends above it at the cycle's retract height."""
        definition = self.drill
        assert definition is not None
        position = dict(self.position)
        for address, (value, incremental) in values.items():
            target = self.to_internal(address, value)
            if incremental:
                start = self.position.get(address, math.nan)
                if math.isnan(start):
                    raise self.error(
                        f"incremental {address} hole from an unknown position; expected an "
                        "absolute position first"
                    )
                target += start
            position[address] = target
        for address in ("X", "Y"):
            if math.isnan(position.get(address, math.nan)):
                raise self.error(f"a hole with no {address} position; expected X and Y")
        position["Z"] = definition.top
        if self.drill_block is None or self.drill_block.definition is not definition:
            block = _ReadCycle(definition, [])
            self._add(block)
            self.drill_block = block
        self.drill_block.holes.append(position)
        self.axes_seen.update(values)
        self.axes_seen.add("Z")
        if self.tcp_at_first_feed is None:
            self.tcp_at_first_feed = self.tcp or self.plane_on
        self.position = {**position, "Z": definition.top + definition.retract}

    def cycle_off(self) -> None:
        """The active cycle ends (G80, MCALL, another cycle)."""
        self.drill = None
        self.drill_block = None

    def dwell(self, seconds: float) -> None:
        """A dwell (G4, Heidenhain cycle 9)."""
        if not (math.isfinite(seconds) and seconds >= 0.0):
            raise self.error(f"dwell of {seconds:g} s; expected a time >= 0")
        self._add(Dwell(seconds))

    # -- events ------------------------------------------------------------------------------

    def code(self) -> None:
        """Note that the current line holds code (the name comment must come first)."""
        if self.finished:
            raise self.error("code after the program end; expected nothing but comments")
        self.code_seen = True

    def comment(self, text: str) -> None:
        """A comment; the first one is the program name for controls that write it so."""
        if self.spec.name_comment and self.name is None and not self.code_seen:
            self.name = text
            return
        self._add(Comment(text))

    def set_units(self, units: str, feeds: bool = True) -> None:
        """Switch units of lengths (and feeds); the first units seen are the program's."""
        self.units = self.units or units
        self.linear_scale = mm_per_unit(units)
        if feeds:
            self.feed_scale = self.spec.feed_inch_unit if units == "inch" else 1.0

    def set_feed(self, value: float) -> None:
        """Modal feed in file units per minute (in inverse time: 1/min)."""
        if value <= 0.0:
            raise self.error(f"feed F{value:g} must be positive")
        self.feed = value * (1.0 if self.feed_mode == FEED_INVERSE_TIME else self.feed_scale)
        self.feed_word_line = self.line

    def set_feed_mode(self, mode: str) -> None:
        """Feed per minute (G94) or inverse time (G93); a change forgets the modal feed."""
        if mode != self.feed_mode:
            self.feed_mode = mode
            self.feed = None

    def _feed_move_mode(self, line: int, has_feed: bool) -> None:
        """Check a feed move against the feed mode: an F word in its block in inverse time,
        the mode of the program's other feed moves."""
        inverse = self.feed_mode == FEED_INVERSE_TIME
        if inverse and not has_feed:
            raise ProgramParseError(
                self.path,
                line,
                "feed move in inverse time (G93) without an F word; expected F (1/min) in "
                "every feed block",
            )
        if self.moves_feed_mode is None:
            self.moves_feed_mode = self.feed_mode
        elif self.moves_feed_mode != self.feed_mode:
            raise ProgramParseError(
                self.path,
                line,
                f"feed move in {self.feed_mode} feed after feed moves in "
                f"{self.moves_feed_mode} feed; expected one feed mode for the feed moves of "
                "a program",
            )

    def select_work_offset(self, code: str) -> None:
        """Work offset (G54... or "preset N"): a WorkOffset block (1 for G54 or preset 1, 2
        for G55...) where one is selected that is not the one in effect (a program with one
        offset per MCS changes it; the check of the program knows which it expects). (Siemens
        G500, no settable offset, gives none.)"""
        if self.work_offset != code:
            if self.work_offset is not None and self.offset_change is None:
                self.offset_change = (self.line, f"from {self.work_offset} to {code}")
            if code.startswith("preset "):
                self._add(WorkOffset(int(code.split()[1])))
            elif code != "G500":
                self._add(WorkOffset(int(code[1:]) - 53))
        self.work_offset = code

    def rollover_direction(self) -> str:
        """How the control turns a rollover axis to a plain absolute value now: the spec's
        :attr:`~urdfpost.dialects.spec.DialectSpec.rollover_direction`, "direct" on a control
        with a shortest-path code before that code."""
        if self.spec.shortest_path and not self.continuous:
            return "direct"
        return self.spec.rollover_direction

    def smoothing(self, on: bool, tolerance: float | None = None, pending: bool = False) -> None:
        """Path smoothing on (``tolerance`` in file units; None: the control's own) or off.

        ``pending``: its rotary tolerance may follow (:meth:`smoothing_angle`, Heidenhain's
        ``CYCL DEF 32.2`` on the next line): the block is added with it, or by
        :meth:`flush_smoothing` before the next line of another kind.
        """
        self.flush_smoothing()
        if on and tolerance is not None and tolerance <= 0.0:
            raise self.error(f"path tolerance {tolerance:g} must be positive")
        mm = None if tolerance is None or not on else tolerance * self.linear_scale
        state = Smoothing(on, mm)
        self.smoothing_state = state
        if pending and on:
            self.smoothing_pending = state
        else:
            self._add(state)

    def smoothing_angle(self, angle: float) -> None:
        """The rotary axes' tolerance (degrees) of the smoothing switched on just before."""
        last = self.smoothing_pending
        if last is None and self.items:
            item = self.items[-1]
            if isinstance(item, Smoothing) and item.on:
                last = item
                self.items.pop()
        if last is None or angle < 0.0:
            raise self.error(
                f"rotary tolerance {angle:g} deg; expected a tolerance >= 0 right after the "
                "path tolerance that switches smoothing on"
            )
        self.smoothing_pending = None
        self.smoothing_state = replace(last, angle=angle)
        self._add(self.smoothing_state)

    def flush_smoothing(self) -> None:
        """Add the smoothing block that waits for a rotary tolerance, if any."""
        if self.smoothing_pending is not None:
            pending, self.smoothing_pending = self.smoothing_pending, None
            self._add(pending)

    def move(
        self,
        values: dict[str, tuple[float, bool]],
        rapid: bool | None,
        modes: dict[str, str] | None = None,
    ) -> None:
        """A motion block.

        Parameters
        ----------
        values : dict
            Address -> (value in file units, incremental).
        rapid : bool or None
            Rapid traverse; None when no motion mode has been programmed.
        modes : dict, optional
            Address -> the direction an absolute value of a rollover axis is reached in
            (:func:`~urdfpost.program.rollover_target`; Siemens ``DC``: "shortest", ``ACP``,
            ``ACN``: "positive", "negative"), where the block says; else the control's.
        """
        if rapid is None:
            raise self.error("axis words before any motion mode; expected G0 or G1 first")
        position = dict(self.position)
        for address, (value, incremental) in values.items():
            target = self.to_internal(address, value)
            if address in self.rollover and not incremental:
                target = self._rolled(address, target, (modes or {}).get(address))
            elif incremental:
                start = self.position.get(address, math.nan)
                if math.isnan(start):
                    raise self.error(
                        f"incremental {address} move from an unknown position; expected an "
                        "absolute position first"
                    )
                target += start
            position[address] = target
        self.position = position
        self.axes_seen.update(values)
        if not rapid and self.tcp_at_first_feed is None:
            self.tcp_at_first_feed = self.tcp or self.plane_on
        if not rapid:
            self._feed_move_mode(self.line, self.feed_word_line == self.line)
        if not rapid and not (self.tcp or self.plane_on) and self.cut_without_tcp is None:
            if any(a not in ROTARY_ADDRESSES for a in values):
                self.cut_without_tcp = self.line
        self._add(_ReadMove(rapid, position, None if rapid else self.feed))
        self.move_lines.append(self.line)

    def _rolled(self, address: str, value: float, mode: str | None) -> float:
        """Where a rollover axis ends for the value ``value`` (degrees) written."""
        previous = self.position.get(address, math.nan)
        if mode == "positive" or mode == "negative":
            signed = math.copysign(abs(value), 1.0 if mode == "positive" else -1.0)
            return rollover_target(previous, signed, "sign")
        direction = mode or self.rollover_direction()
        if direction != "sign" and not 0.0 <= value < 360.0:
            raise self.error(f"{address}{value:g} on a rollover axis; expected a value in [0, 360)")
        if direction == "sign" and not -360.0 < value < 360.0:
            raise self.error(
                f"{address}{value:g} on a rollover axis; expected a value in (-360, 360)"
            )
        target = rollover_target(previous, value, direction)
        if direction == "shortest" and abs(abs(target - previous) - 180.0) < 1e-9:
            raise self.error(
                f"{address}{value:g} is half a turn from {previous % 360.0:g}: the shortest "
                "way is either way; expected a turn of less than 180 degrees"
            )
        return target

    def cutter_comp(self, side: str, register: int | None, plane: str | None = None) -> None:
        """Cutter radius compensation ("left", "right", "off"): a block when it changes."""
        state = (side, register if side != "off" else None, plane or self.plane)
        if side == "off":
            state = ("off", None, self.comp[2])
        if state[0] != self.comp[0] or (side != "off" and state != self.comp):
            self._add(CutterComp(state[0], state[1], state[2]))
        self.comp = state

    def arc_move(
        self,
        values: dict[str, tuple[float, bool]],
        centre: dict[str, tuple[float, bool]],
        clockwise: bool,
        plane: str | None = None,
    ) -> None:
        """An arc block from where the axes stand.

        Parameters
        ----------
        values : dict
            End: address -> (value in file units, incremental), as :meth:`move`.
        centre : dict
            Centre of the plane's two axes: axis letter -> (value in file units, absolute);
            an axis not given is the start's (an I, J or K of 0).
        clockwise : bool
            G2 (clockwise seen from the positive end of the plane's normal).
        plane : str, optional
            The plane (default the modal one, :attr:`plane`).

        Raises
        ------
        ProgramParseError
            The start is not known, or the arc turns a rotary axis.
        """
        plane = plane or self.plane
        first, second, normal = ARC_PLANES[plane]
        unknown = [a for a in (first, second, normal) if math.isnan(self.position.get(a, math.nan))]
        if unknown:
            raise self.error(
                f"arc from an unknown {unknown[0]} position; expected a move to the arc's start "
                "first"
            )
        rotary = [a for a in values if a in ROTARY_ADDRESSES]
        if rotary:
            raise self.error(f"{rotary[0]} word in an arc block; expected only X, Y, Z")
        start = dict(self.position)
        centre_mm = [start.get(a, 0.0) for a in "XYZ"]
        for address, (value, absolute) in centre.items():
            k = "XYZ".index(address)
            mm = self.to_internal(address, value)
            centre_mm[k] = mm if absolute else start[address] + mm
        self.move(values, False)  # the end, modal state and checks of a feed move
        read = self.items.pop()
        assert isinstance(read, _ReadMove)
        self.move_lines.pop()
        self.motion = None  # no linear mode: an axis word alone continues the arc
        x, y, z = centre_mm
        self._add(_ReadArc(read.position, (x, y, z), plane, clockwise, read.feed))
        self.arc_lines.append(self.line)

    def moves(self, lines: _bulk.MotionLines, rows: slice, first_line: int) -> bool:
        """Plain motion blocks, read at once: as :meth:`move` (and the feed and motion code of
        each block) on each, in order.

        Parameters
        ----------
        lines : MotionLines
            Words of the blocks; ``rows`` selects consecutive plain ones.
        first_line : int
            Line number of the first block.

        Returns
        -------
        bool
            False, with nothing done, when the blocks need the block-by-block reader (the
            program has ended, incremental mode, no motion mode yet).
        """
        if self.finished or not self.absolute or self.drill is not None or self.rollover:
            # (the blocks after a canned cycle are its holes; rollover axes: each block turns
            # from where the one before ended)
            return False
        k = rows.stop - rows.start
        code = lines.code[rows]
        if self.arc is not None and code[0] < 0:
            return False  # (in arc mode, a block before a G0 or G1 is an arc)
        if self.spec.motion_layout is not None and self.spec.motion_layout.rapid_word:
            rapid = lines.rapid_word[rows].copy()
        else:
            start = math.nan if self.motion is None else float(self.motion)
            mode = _fill_forward(np.where(code >= 0, code, np.nan), start)
            if np.isnan(mode).any():
                return False
            rapid = mode == 1.0
        written = lines.axes[rows]
        scale = np.array([1.0 if a in ROTARY_ADDRESSES else self.linear_scale for a in AXIS_ORDER])
        position = np.empty((k, len(AXIS_ORDER)))
        for j, address in enumerate(AXIS_ORDER):
            start = self.position.get(address, math.nan)
            position[:, j] = _fill_forward(written[:, j] * scale[j], start)
        inverse = self.feed_mode == FEED_INVERSE_TIME
        feed_words = lines.feed[rows] * (1.0 if inverse else self.feed_scale)
        if not rapid.all():
            if inverse and np.isnan(feed_words[~rapid]).any():
                return False  # (line by line: the error names the line)
            if self.moves_feed_mode not in (None, self.feed_mode):
                return False
            self._feed_move_mode(first_line, True)
        start_feed = math.nan if self.feed is None else self.feed
        feed = _fill_forward(feed_words, start_feed)
        self.code_seen = True
        self.line = first_line + k - 1
        if self.tcp_at_first_feed is None and not rapid.all():
            self.tcp_at_first_feed = self.tcp or self.plane_on
        if not (self.tcp or self.plane_on) and self.cut_without_tcp is None:
            linear = [j for j, a in enumerate(AXIS_ORDER) if a not in ROTARY_ADDRESSES]
            cuts = np.flatnonzero(~rapid & ~np.isnan(written[:, linear]).all(axis=1))
            if cuts.size:
                self.cut_without_tcp = first_line + int(cuts[0])
        seen = [a for j, a in enumerate(AXIS_ORDER) if not np.isnan(written[:, j]).all()]
        self.axes_seen.update(seen)
        self.position = {
            **self.position,
            **{a: float(position[-1, AXIS_ORDER.index(a)]) for a in seen},
        }
        if (code >= 0).any():
            self.motion = bool(code[code >= 0][-1] == 1)
            self.arc = None  # (G0 / G1 end the arc mode)
        if not np.isnan(feed_words).all():
            self.feed = float(feed[-1])
        self._add(_ReadMoves(position, rapid, np.where(rapid, math.nan, feed)))
        self.move_lines.append(np.arange(first_line, first_line + k))
        return True

    def home(self, axes: list[str]) -> None:
        """Reference return or machine-coordinate block: the axes' positions become unknown."""
        self.position = {**self.position, **dict.fromkeys(axes or AXIS_ORDER, math.nan)}
        home_comment = self.spec.home_comment
        if home_comment is not None and self.items and self.items[-1] == Comment(home_comment):
            self.items.pop()  # written by the dialect as part of its home sequence
        if not (self.items and isinstance(self.items[-1], Home)):
            self._add(Home())

    def select_tool(self, number: int) -> None:
        """T word (tool selection, executed by the tool change)."""
        self.tool = number

    def select_offset(self, register: int) -> None:
        """H word (a tool length offset register, with the TCP or length offset switch; in a
        tilted plane, the register of the plane's length, Fanuc ``G43 H..``)."""
        self.offset = register
        if self.plane_pending is not None:
            self.plane_pending = replace(self.plane_pending, offset=register)

    def tool_change(self, number: int | None = None) -> None:
        """Tool change (M6, TOOL CALL)."""
        if number is not None:
            self.tool = number
        if self.tool is None:
            raise self.error("tool change without a tool number; expected T<number>")
        self.offset = None
        self._add(ToolChange(self.tool))

    def set_speed(self, rpm: float) -> None:
        """Spindle speed; a running spindle changes speed."""
        self.rpm = rpm
        if self.spindle_state[0] != "off":
            count = len(self.items)
            self.spindle(self.spindle_state[0])
            self._speed_change = self.items[-1] if len(self.items) > count else None

    def spindle(self, direction: str) -> None:
        """Spindle start or stop (a block only when the state changes).

        A speed change directly followed by a start or stop (``S6000 M4``, or Heidenhain
        ``TOOL CALL Z S6000`` then ``M4``) is one block.
        """
        state = (direction, 0.0 if direction == "off" else self.rpm)
        if state != self.spindle_state:
            if self.items and self._speed_change is self.items[-1]:
                self.items.pop()
            self.spindle_state = state
            self._add(Spindle(*state))
        self._speed_change = None

    def coolant(self, mode: str) -> None:
        """Coolant on/off."""
        self._add(Coolant(mode))

    def set_tcp(self, on: bool) -> None:
        """TCP on/off (a block only when the state changes).

        TCP on says the tool length offset register it uses (:attr:`Tcp.offset`): the H word
        since the tool change on controls that have such registers (None without one), the
        tool called on the others (they take the length from its tool table row).
        """
        if on and self.plane_on:
            raise self.error("TCP on in a tilted working plane; expected the plane off first")
        if on != self.tcp:
            self.tcp = on
            self.tcp_ever |= on
            register = self.offset if self.spec.length_offsets is not None else self.tool
            self._add(Tcp(on, register if on else None))

    def tilted_plane(self, angles: tuple[float, float, float] | None) -> None:
        """A tilted working plane on by ``angles`` (degrees, in the control's convention,
        :attr:`DialectSpec.plane_convention`), or off (None; a block only when one is on)."""
        convention = self.spec.plane_convention
        if convention is None:
            raise self.error(f"{self.spec.name}: a tilted working plane; expected none")
        if angles is None:
            if self.plane_on:
                self.plane_on = False
                self._turn_position(self.plane_frame)
                self._add(TiltedPlane(None, convention))
            return
        if self.plane_on:
            raise self.error("a tilted working plane while one is on; expected it off first")
        if self.tcp:
            raise self.error("a tilted working plane with TCP on; expected TCP off first")
        self.plane_on = True
        register = self.offset if self.spec.length_offsets is not None else self.tool
        block = TiltedPlane(angles, convention, register)
        self.plane_frame = block.frame()
        self._turn_position(self.plane_frame.T)
        if self.spec.plane_length_on:
            # added with the next block: a length switch follows with its register (G43 H..)
            self.plane_pending = block
        else:
            self._add(block)

    def _turn_position(self, rotation: np.ndarray) -> None:
        """The modal X, Y, Z (where the tool stands) in a new frame: ``rotation`` times them
        (the control shows the same point in the plane's coordinates, or out of them)."""
        if all(a in self.position for a in "XYZ"):
            turned = rotation @ np.array([self.position[a] for a in "XYZ"])
            self.position = {**self.position, **dict(zip("XYZ", turned.tolist(), strict=True))}

    def clamp(self, axis: str, on: bool) -> None:
        """A rotary axis clamped or released (the machine's M code)."""
        self._add(Clamp(axis, on))

    def insert(self, text: str) -> None:
        """A line inserted verbatim, taken on trust."""
        self.code()
        self._add(Insert(text))

    def stop(self, optional: bool) -> None:
        """Program stop (M0) or optional stop (M1)."""
        self._add(Stop(optional))

    def end(self) -> None:
        """Program end (M2, M30, END PGM)."""
        self.finished = True

    def close(self) -> None:
        """The line that closes a program after its end (Fanuc ``%``, Heidenhain ``END PGM``:
        the control's ``program_close``)."""
        if self.finished:
            self.closed = True

    def percent(self) -> None:
        """A ``%`` line: after the program end it closes the program; before any code it is
        the tape start, which a ``%`` after the end must then close (LinuxCNC: "percent sign
        missing from end of file"), whatever the control writes itself."""
        if self.finished:
            self.closed = True
        elif not self.code_seen:
            self.closed = False

    @property
    def ended(self) -> bool:
        """The program has its end and, where the control writes one, its closing line after
        it (a Fanuc program without its last ``%``, a Heidenhain one without ``END PGM`` has
        not ended: the file is cut short)."""
        return self.finished and self.closed

    # -- result ------------------------------------------------------------------------------

    def build(self) -> Program:
        """The program read."""
        if self.plane_pending is not None and self.finished:
            self.items.append(self.plane_pending)
            self.plane_pending = None
        axes = tuple(a for a in AXIS_ORDER if a in self.axes_seen)
        parts: list[Block | MoveTable] = []
        run: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []  # consecutive moves
        singles: list[_ReadMove] = []

        def end_singles() -> None:
            if singles:
                run.append(_columns_of_singles(singles, axes))
                singles.clear()

        def end_run() -> None:
            end_singles()
            if run:
                position, rapid, feed = (np.concatenate(c) for c in zip(*run, strict=True))
                parts.append(MoveTable(position, rapid, feed, np.full(len(feed), -1)))
                run.clear()

        for item in self.items:
            if isinstance(item, _ReadArc):
                end_run()
                parts.append(
                    Arc(
                        position=tuple(item.position.get(a, math.nan) for a in axes),
                        centre=item.centre,
                        plane=item.plane,
                        clockwise=item.clockwise,
                        feed=item.feed,
                    )
                )
                continue
            if isinstance(item, _ReadMove):
                singles.append(item)
            elif isinstance(item, _ReadMoves):
                end_singles()
                run.append(item.columns(axes))
            elif isinstance(item, _ReadCycle):
                end_run()
                parts.append(cycle_of(item.definition, item.holes, axes))
            else:
                end_run()
                parts.append(item)
        end_run()
        rotary = frozenset(axes) & ROTARY_ADDRESSES
        tcp = self.tcp_at_first_feed if self.tcp_at_first_feed is not None else self.tcp_ever
        name = self.name or (PurePath(self.path).stem if self.path != "<string>" else "PROGRAM")
        return Program(
            name=name,
            axes=axes,
            rotary=rotary,
            units=self.units or "mm",
            tcp=tcp,
            blocks=Blocks(parts),
            continuous=rotary if self.continuous else frozenset(),
            cut_without_tcp=None
            if self.cut_without_tcp is None
            else (self.path, self.cut_without_tcp),
            offset_change=None if self.offset_change is None else (self.path, *self.offset_change),
            rollover=self.rollover & rotary,
            feed_mode=self.moves_feed_mode or FEED_PER_MINUTE,
        )


# -- word-address G-code ---------------------------------------------------------------------


@dataclass(frozen=True)
class _Word:
    address: str
    text: str
    mode: str | None = None  # Siemens AC/IC/DC/ACP/ACN value form


@dataclass(frozen=True)
class _Keyword:
    name: str


@dataclass(frozen=True)
class _Assign:
    name: str
    text: str


@dataclass(frozen=True)
class _Call:
    name: str
    args: tuple[str, ...]  # as written, stripped


_Token = _Word | _Keyword | _Assign | _Call
_BLOCK_NUMBER = re.compile(r"N\d+\s+")

_CALL_ARGS = re.compile(r"\(([^()]*)\)")

_IDENT = re.compile(r"[A-Z_][A-Z0-9_]*")
_LETTER_NUMBER = re.compile(r"([A-Z])\s*([+\-0-9.]*)")
_ASSIGN = re.compile(r"([A-Z]{1,3}\d?)\s*=\s*")
_ASSIGN_VALUE = re.compile(r"(?:(AC|IC|DC|ACP|ACN)\(\s*([^)\s]*)\s*\)|([+\-0-9.]+))")
_KEYWORD_ARGS = re.compile(r"\(\s*\d*\s*\)")


def split_comments(spec: DialectSpec, builder: ProgramBuilder, raw: str) -> tuple[str, list[str]]:
    """Separate code from ``(...)`` and ``;`` comments.

    Returns
    -------
    tuple
        The code text and the comment texts (stripped), in order.
    """
    code: list[str] = []
    comments: list[str] = []
    i = 0
    while i < len(raw):
        char = raw[i]
        if char == "(" and spec.paren_comments:
            close = raw.find(")", i + 1)
            if close < 0:
                raise builder.error("comment '(' is not closed; expected ')'")
            inner = raw[i + 1 : close]
            if "(" in inner:
                raise builder.error("nested '(' inside a comment; expected one level of (...)")
            comments.append(inner.strip())
            i = close + 1
            continue
        if char == ";" and spec.semicolon_comments:
            comments.append(raw[i + 1 :].strip())
            break
        code.append(char)
        i += 1
    return "".join(code), comments


def tokenize(spec: DialectSpec, builder: ProgramBuilder, text: str) -> list[_Token]:
    """Split upper-case code text into words, keywords and Siemens assignments."""
    tokens: list[_Token] = []
    pos = 0
    while pos < len(text):
        if text[pos].isspace():
            pos += 1
            continue
        token, pos = _next_token(spec, builder, text, pos)
        tokens.append(token)
    return tokens


def _next_token(
    spec: DialectSpec, builder: ProgramBuilder, text: str, pos: int
) -> tuple[_Token, int]:
    ident = _IDENT.match(text, pos)
    if ident and ident.group() in spec.call_keywords:
        args = _CALL_ARGS.match(text, ident.end())
        if args is None:
            raise builder.error(f"{ident.group()} without its (...) argument list")
        inner = args.group(1).strip()
        values = tuple(a.strip() for a in inner.split(",")) if inner else ()
        return _Call(ident.group(), values), args.end()
    if ident and ident.group() in spec.keywords:
        end = ident.end()
        args = _KEYWORD_ARGS.match(text, end)
        return _Keyword(ident.group()), args.end() if args else end
    if spec.assignments:
        assign = _ASSIGN.match(text, pos)
        if assign:
            return _assignment(builder, text, assign)
    if ident and len(ident.group()) > 1 and ident.group()[1].isalpha():
        raise builder.error(f"unknown word {ident.group()!r}; expected address words like X12.5")
    word = _LETTER_NUMBER.match(text, pos)
    if word is None:
        raise builder.error(f"unexpected {text[pos]!r}; expected address words like X12.5")
    if not word.group(2):
        raise builder.error(f"address {word.group(1)} without a number; expected e.g. X12.5")
    return _Word(word.group(1), word.group(2)), word.end()


def _assignment(builder: ProgramBuilder, text: str, assign: re.Match[str]) -> tuple[_Token, int]:
    name = assign.group(1)
    value = _ASSIGN_VALUE.match(text, assign.end())
    if value is None:
        raise builder.error(f"unreadable value for {name}=; expected a number or AC/IC/DC(...)")
    if value.group(1):
        if len(name) != 1:
            raise builder.error(f"{name}={value.group(1)}(...) is not supported")
        return _Word(name, value.group(2), value.group(1)), value.end()
    if len(name) == 1:
        return _Word(name, value.group(3)), value.end()
    return _Assign(name, value.group(3)), value.end()


def canonical_g(builder: ProgramBuilder, text: str) -> str:
    """``"00"`` -> ``"0"``, ``"43.40"`` -> ``"43.4"``."""
    return f"{builder.number('G', text):g}"


def _integer(builder: ProgramBuilder, address: str, text: str) -> int:
    if not re.fullmatch(r"\d+", text):
        raise builder.error(f"{address}{text}: expected a whole number after {address}")
    return int(text)


@dataclass
class _Block:
    """One G-code line, sorted by kind."""

    g_actions: list[tuple[str, str]]  # (code, action)
    m_actions: list[str]
    keywords: list[str]
    words: dict[str, _Word]
    assigns: dict[str, str]
    calls: list[_Call] = field(default_factory=list)

    @property
    def actions(self) -> set[str]:
        return {a for _, a in self.g_actions} | set(self.keywords)


def _classify(spec: DialectSpec, builder: ProgramBuilder, tokens: list[_Token]) -> _Block:
    block = _Block([], [], [], {}, {})
    for token in tokens:
        if isinstance(token, _Keyword):
            block.keywords.append(spec.keywords[token.name])
        elif isinstance(token, _Call):
            block.calls.append(token)
        elif isinstance(token, _Assign):
            block.assigns[token.name] = token.text
        elif token.address == "G":
            code = canonical_g(builder, token.text)
            if code not in spec.g_codes:
                hint = _G_HINTS.get(code, "unknown G-code")
                known = " ".join(f"G{c}" for c in spec.g_codes)
                raise builder.error(f"G{token.text}: {hint}; this reader understands {known}")
            block.g_actions.append((code, spec.g_codes[code]))
        elif token.address == "M":
            m_code = _integer(builder, "M", token.text)
            if m_code not in spec.m_codes:
                known = " ".join(f"M{c}" for c in spec.m_codes)
                raise builder.error(f"unknown M-code M{m_code}; this reader understands {known}")
            block.m_actions.append(spec.m_codes[m_code])
        elif token.address in block.words:
            raise builder.error(f"two {token.address} words in one block")
        else:
            block.words[token.address] = token
    return block


def parse_gcode_line(spec: DialectSpec, builder: ProgramBuilder, raw: str) -> None:
    """Read one line of word-address G-code into ``builder``.

    Parameters
    ----------
    spec : DialectSpec
        The control.
    builder : ProgramBuilder
        Receives the line's events; ``builder.line`` is the line number.
    raw : str
        The line without its end-of-line.

    Raises
    ------
    ProgramParseError
        The line cannot be read (see the module docstring).
    """
    text, comments = split_comments(spec, builder, raw)
    text = text.strip().upper()
    if spec.percent_lines and text == "%":
        builder.percent()
        text = ""
    if text.startswith("/"):  # block delete: the block runs unless the operator skips it
        text = text[1:]
    number = _BLOCK_NUMBER.match(text)  # (N.. before a modal call: read past, as below)
    if spec.cycle_lines is not None and number and text[number.end() :].startswith("MCALL"):
        text = text[number.end() :]
    if spec.cycle_lines is not None and text.startswith("MCALL"):
        builder.code()
        _mcall(builder, text)
        for comment in comments:
            builder.comment(comment)
        return
    tokens = tokenize(spec, builder, text)
    if tokens and isinstance(tokens[0], _Word) and tokens[0].address == "N":
        _integer(builder, "N", tokens[0].text)
        tokens = tokens[1:]
    if tokens and isinstance(tokens[0], _Word) and tokens[0].address == "O":
        _program_number_line(spec, builder, tokens, comments)
        return
    if tokens:
        builder.code()
        _execute(spec, builder, _classify(spec, builder, tokens))
    for comment in comments:
        builder.comment(comment)


def _program_number_line(
    spec: DialectSpec, builder: ProgramBuilder, tokens: list[_Token], comments: list[str]
) -> None:
    word = tokens[0]
    if not spec.program_number_line or len(tokens) != 1 or builder.code_seen:
        raise builder.error("unexpected O word; expected a program number line before any code")
    assert isinstance(word, _Word)  # the caller saw an O word first
    number = _integer(builder, "O", word.text)
    builder.name = comments[0] if comments else f"O{number}"
    for comment in comments[1:]:
        builder.comment(comment)


BEFORE_MOTION_M = {
    "tool_change",
    "spindle_cw",
    "spindle_ccw",
    "coolant_flood",
    "coolant_mist",
    "tcp_on",
    "tcp_off",
    "shortest_path",
}


def _execute(spec: DialectSpec, builder: ProgramBuilder, block: _Block) -> None:
    actions = block.actions | set(block.m_actions)
    _check_words(builder, block, actions)
    _apply_modes(builder, block)
    _apply_smoothing(spec, builder, block)
    dwell = "dwell" in actions
    for action in block.actions & {"cycle_off", "cycle_initial", "cycle_r"}:
        if action == "cycle_off":
            builder.cycle_off()
        else:
            builder.drill_initial = action == "cycle_initial"
    if "F" in block.words and not dwell:
        builder.set_feed(builder.number("F", block.words["F"].text))
    if "T" in block.words:
        builder.select_tool(_integer(builder, "T", block.words["T"].text))
    comp = actions & {"comp_left", "comp_right", "comp_off"}
    if comp:
        side = next(iter(comp)).removeprefix("comp_")
        register = _integer(builder, "D", block.words["D"].text) if "D" in block.words else None
        builder.cutter_comp(side, register)
    if "H" in block.words:  # (only with tcp_on or length_on: _check_words)
        builder.select_offset(_integer(builder, "H", block.words["H"].text))
    if "S" in block.words and not dwell:
        builder.set_speed(builder.number("S", block.words["S"].text))
    for action in block.actions & {"tcp_on", "tcp_off"}:  # G-codes and keywords
        builder.set_tcp(action == "tcp_on")
    for action in block.m_actions:
        if action in BEFORE_MOTION_M:
            apply_m_action(builder, action)
    if "plane_off" in actions:
        builder.tilted_plane(None)
    if "plane_on" in actions:
        _iso_plane(builder, block)  # (its X Y Z are the plane's zero, not a move)
    else:
        _motion(spec, builder, block, actions)
    for action in block.m_actions:
        if action not in BEFORE_MOTION_M:
            apply_m_action(builder, action)


def _check_words(builder: ProgramBuilder, block: _Block, actions: set[str]) -> None:
    allowed = set(AXIS_ORDER) | {"F", "S", "T"} | set(builder.spec.extra_words)
    if actions & {"tcp_on", "length_on"}:
        allowed.add("H")
    if "dwell" in actions:
        allowed |= {"P", "U"}
    if "blend" in actions:
        allowed |= {"P", "Q"}
    if "cycle" in actions:
        allowed |= {"R", "Q", "P"}
    if "smoothing" in actions:
        allowed |= {"Q", "R"}
    if "plane_on" in actions:
        allowed |= {"I", "J", "K"}
    if actions & {"comp_left", "comp_right"}:
        allowed.add("D")
    if actions & {"arc_cw", "arc_ccw"} or (
        builder.arc is not None and not actions & {"rapid", "linear"}
    ):
        allowed |= {"I", "J", "K"}
    for address in block.words:
        if address not in allowed:
            raise builder.error(
                f"unknown word {address}{block.words[address].text}; expected "
                f"{' '.join(sorted(allowed))} (and G, M)"
            )
    if block.assigns and not actions & {"home"}:
        name = next(iter(block.assigns))
        raise builder.error(f"unexpected {name}=; expected it only in a home block (G74/G75)")


def _apply_modes(builder: ProgramBuilder, block: _Block) -> None:
    for code, action in block.g_actions:
        if action in ("rapid", "linear"):
            builder.motion = action == "rapid"
            builder.arc = None
        elif action in ("arc_cw", "arc_ccw"):
            builder.arc = action == "arc_cw"
            builder.motion = None
        elif action in ("plane_xy", "plane_zx", "plane_yz"):
            builder.plane = action.removeprefix("plane_").upper()
        elif action in ("mm", "inch"):
            builder.set_units(action)
        elif action in ("mm_geometry", "inch_geometry"):
            builder.set_units(action.removesuffix("_geometry"), feeds=False)
        elif action in ("absolute", "incremental"):
            builder.absolute = action == "absolute"
        elif action in ("inverse_time", "per_minute"):
            inverse = action == "inverse_time"
            builder.set_feed_mode(FEED_INVERSE_TIME if inverse else FEED_PER_MINUTE)
        elif action == "work_offset":
            builder.select_work_offset(f"G{code}")


#: Siemens CYCLE832 machining types (the constants of the cycle's second parameter), whether
#: they switch smoothing on and whether the third parameter is the orientation tolerance.
_CYCLE832_TYPES = {
    "_OFF": (False, False),
    "_FINISH": (True, False),
    "_SEMIFIN": (True, False),
    "_ROUGH": (True, False),
    "_ORI_FINISH": (True, True),
    "_ORI_SEMIFIN": (True, True),
    "_ORI_ROUGH": (True, True),
}


def _apply_smoothing(spec: DialectSpec, builder: ProgramBuilder, block: _Block) -> None:
    """LinuxCNC ``G64 P..``, Fanuc ``G05.1 Q..``, Siemens ``CYCLE832(...)``."""
    actions = {a for _, a in block.g_actions}
    if "blend" in actions:
        p = block.words.get("P")
        if p is None:
            builder.smoothing(False)
        else:
            builder.smoothing(True, builder.number("P", p.text))
    if "smoothing" in actions:
        q = block.words.get("Q")
        mode = _integer(builder, "Q", q.text) if q is not None else None
        if mode not in (0, 1, 2, 3):
            raise builder.error("G05.1 needs Q0 (off), Q1 (AI contour control), Q2 or Q3")
        builder.smoothing(mode != 0)
    for call in block.calls:
        action = spec.call_keywords[call.name]
        if action == "plane":
            _cycle800(builder, call)
        elif action == "smoothing":
            _cycle832(builder, call)
        else:
            raise builder.error(f"{call.name}(...) is not allowed here")


#: CYCLE800's parameters: how many, and which hold the angles (_A, _B, _C).
_CYCLE800_ARGS = 16
_CYCLE800_ANGLES = (7, 8, 9)


def _cycle800(builder: ProgramBuilder, call: _Call) -> None:
    """``CYCLE800(_FR,_TC,_ST,_MODE,_X0,_Y0,_Z0,_A,_B,_C,_X1,_Y1,_Z1,_DIR,_FR_I,_DMODE)``: a
    tilted plane by angles axis by axis, X then Y then Z (mode 57), with no swivelling (_DIR
    0) and its zero at the program's; ``CYCLE800()`` switches it off."""
    args = call.args
    if not args or args == ("",):
        builder.tilted_plane(None)
        return
    expected = (
        'CYCLE800(0,"",0,57,0,0,0,A,B,C,0,0,0,0,0,1): mode 57 (axis by axis, X Y Z), the zero '
        "at the program's, _DIR 0 (no swivelling)"
    )
    if len(args) != _CYCLE800_ARGS:
        raise builder.error(f"{call.name} with {len(args)} arguments; expected {expected}")
    values = [a.strip() for a in args]
    if builder.number("_MODE", values[3]) != 57.0:
        raise builder.error(f"{call.name}: mode {values[3]}; expected {expected}")
    for k in (4, 5, 6, 10, 11, 12, 13):
        if builder.number(f"{call.name} parameter {k + 1}", values[k]) != 0.0:
            raise builder.error(
                f"{call.name}: parameter {k + 1} is {values[k]}; expected {expected}"
            )
    a, b, c = (builder.number("angle", values[k]) for k in _CYCLE800_ANGLES)
    builder.tilted_plane((a, b, c))


def _iso_plane(builder: ProgramBuilder, block: _Block) -> None:
    """Fanuc ``G68.2 X0. Y0. Z0. I.. J.. K..`` (the plane's zero at the program's, Euler
    angles Z X Z)."""
    for address in "XYZ":
        word = block.words.get(address)
        if word is not None and builder.number(address, word.text) != 0.0:
            raise builder.error(
                f"G68.2 with {address}{word.text}; expected the plane's zero at the program's "
                "(X0. Y0. Z0.)"
            )
    angles = []
    for address in "IJK":
        word = block.words.get(address)
        angles.append(0.0 if word is None else builder.number(address, word.text))
    builder.tilted_plane((angles[0], angles[1], angles[2]))


def _cycle832(builder: ProgramBuilder, call: _Call) -> None:
    """``CYCLE832(tolerance, machining type, orientation tolerance or version)``; no
    arguments, or the type ``_OFF`` / ``0``, switch it off."""
    args = call.args
    if not args:
        builder.smoothing(False)
        return
    if len(args) > 3:
        raise builder.error(f"{call.name} with {len(args)} arguments; expected at most 3")
    kind = args[1].upper() if len(args) > 1 else "_FINISH"
    on_ori = _CYCLE832_TYPES.get(kind)
    if on_ori is None and re.fullmatch(r"\d+", kind):  # the numeric form: units 0 deselect
        number = int(kind)
        on_ori = (number % 10 != 0, number // 10 % 10 == 1)
    if on_ori is None:
        known = ", ".join(_CYCLE832_TYPES)
        raise builder.error(f"{call.name}: machining type {args[1]!r}; expected one of {known}")
    on, ori = on_ori
    tolerance = builder.number("tolerance", args[0])
    if not on or tolerance == 0.0:
        builder.smoothing(False)
        return
    builder.smoothing(True, tolerance)
    if ori and len(args) > 2:
        builder.smoothing_angle(builder.number("orientation tolerance", args[2]))


def _motion(spec: DialectSpec, builder: ProgramBuilder, block: _Block, actions: set[str]) -> None:
    axes = {a: w for a, w in block.words.items() if a in AXIS_ORDER}
    if "dwell" in actions:
        stray = [a for a in axes if a != "X"]  # Fanuc G4 X<seconds>
        if stray:
            raise builder.error(f"{stray[0]} word in a dwell block; expected only the dwell time")
        _dwell(spec, builder, block)
        return
    if "cycle" in actions:
        _iso_cycle(spec, builder, block, axes)
        return
    if actions & {"rapid", "linear"}:
        builder.cycle_off()  # G0 / G1 end a canned cycle (Fanuc group 01)
    if builder.drill is not None and axes and not actions & {"home", "machine"}:
        builder.cycle_hole({a: _axis_value(spec, builder, w) for a, w in axes.items()})
        return
    if actions & {"home", "machine"}:
        named = list(axes) + [n[0] for n in block.assigns if n[0] in AXIS_ORDER]
        for word in axes.values():
            _check_axis_number(spec, builder, word)
        if axes or "home" in actions:
            builder.home(named)
        return
    centre_words = {a: w for a, w in block.words.items() if a in "IJK"}
    if builder.arc is not None and (axes or centre_words):
        _arc(spec, builder, axes, centre_words)
        return
    if not axes:
        return
    values = {}
    for address in AXIS_ORDER:
        if address in axes:
            values[address] = _axis_value(spec, builder, axes[address])
    modes = {a: _ROLLOVER_MODES[w.mode] for a, w in axes.items() if w.mode in _ROLLOVER_MODES}
    builder.move(values, builder.motion, modes)


#: Siemens value forms of a rotary axis, as the direction a rollover axis turns in.
_ROLLOVER_MODES = {"DC": "shortest", "ACP": "positive", "ACN": "negative"}


def _dwell(spec: DialectSpec, builder: ProgramBuilder, block: _Block) -> None:
    """G4: P (seconds, Fanuc milliseconds), X (Fanuc seconds) or F (Siemens seconds)."""
    for address in ("P", "X", "F"):
        if address in block.words:
            value = builder.number(address, block.words[address].text)
            ms = address == "P" and spec.dwell_p_ms and "." not in block.words[address].text
            builder.dwell(value / 1000.0 if ms else value)
            return


def _iso_cycle(
    spec: DialectSpec, builder: ProgramBuilder, block: _Block, axes: dict[str, _Word]
) -> None:
    """A ``G81``.. block: the cycle's definition, and its first hole at the block's position
    (the position the tool stands at when the block has no X, Y)."""
    code = next(c for c, a in block.g_actions if a == "cycle")
    if code not in ISO_KINDS:
        raise builder.error(f"G{code}: not a drilling cycle this reader knows")
    words = {a: builder.number(a, w.text) for a, w in block.words.items() if a in "ZRQP"}
    if "P" in words and spec.dwell_p_ms and "." not in block.words["P"].text:
        words["P"] /= 1000.0
    start_z = builder.position.get("Z", math.nan)
    definition = iso_definition(
        code, words, start_z, builder.feed, builder.linear_scale, builder.error
    )
    if not builder.drill_initial:
        definition.retract = 0.0
    builder.cycle_start(definition)
    hole = {a: _axis_value(spec, builder, w) for a, w in axes.items() if a != "Z"}
    builder.cycle_hole(hole)


def _mcall(builder: ProgramBuilder, text: str) -> None:
    """Siemens ``MCALL CYCLE8x(...)`` (the holes follow) or ``MCALL`` (the end)."""
    if text.strip() == "MCALL":
        builder.cycle_off()
        return
    definition = siemens_definition(
        text, builder.linear_scale, builder.feed_scale, builder.feed, builder.error
    )
    if definition is None:
        raise builder.error(
            f"unknown modal call {text!r}; expected MCALL CYCLE81..CYCLE85(...) or MCALL"
        )
    builder.cycle_start(definition)


def _arc(
    spec: DialectSpec, builder: ProgramBuilder, axes: dict[str, _Word], centre: dict[str, _Word]
) -> None:
    """A G2/G3 block: end words and I J K (incremental from the start unless ``=AC(..)``)."""
    assert builder.arc is not None
    first, second, _ = ARC_PLANES[builder.plane]
    letters = {"I": "X", "J": "Y", "K": "Z"}
    stray = [w for w in centre if letters[w] not in (first, second)]
    if stray:
        raise builder.error(
            f"{stray[0]} word in a {builder.plane} arc; expected the centre words of "
            f"{first} and {second}"
        )
    if not centre:
        raise builder.error(
            f"G{'2' if builder.arc else '3'} without I, J or K; expected the centre of the "
            f"{builder.plane} arc (I J K incremental from the start)"
        )
    values = {a: _axis_value(spec, builder, axes[a]) for a in AXIS_ORDER if a in axes}
    given = {}
    for letter, word in centre.items():
        if word.mode not in (None, "AC", "IC"):
            raise builder.error(f"{letter}={word.mode}(...): expected {letter}=AC(...) or IC(...)")
        value = builder.number(letter, word.text)
        given[letters[letter]] = (value, word.mode == "AC")
    builder.arc_move(values, given, builder.arc)


def _check_axis_number(spec: DialectSpec, builder: ProgramBuilder, word: _Word) -> float:
    value = builder.number(word.address, word.text)
    if spec.require_point and "." not in word.text:
        raise builder.error(
            f"{word.address}{word.text} has no decimal point: {spec.name} reads it in least "
            f"input increments (0.001 mm); expected {word.address}{word.text}."
        )
    return value


def _axis_value(spec: DialectSpec, builder: ProgramBuilder, word: _Word) -> tuple[float, bool]:
    value = _check_axis_number(spec, builder, word)
    if word.mode is None:
        return value, not builder.absolute
    if word.mode in ("DC", "ACP", "ACN") and word.address not in ROTARY_ADDRESSES:
        raise builder.error(f"{word.address}={word.mode}(...) needs a rotary axis")
    return value, word.mode == "IC"


def apply_m_action(builder: ProgramBuilder, action: str) -> None:
    """Apply one M-code action (shared with the Heidenhain reader)."""
    match action:
        case "stop" | "optional_stop":
            builder.stop(action == "optional_stop")
        case "end":
            builder.end()
        case "spindle_cw" | "spindle_ccw" | "spindle_off":
            builder.spindle(action.removeprefix("spindle_"))
        case "tool_change":
            builder.tool_change()
        case "coolant_flood" | "coolant_mist" | "coolant_off":
            builder.coolant(action.removeprefix("coolant_"))
        case "tcp_on" | "tcp_off":
            builder.set_tcp(action == "tcp_on")
        case "shortest_path":
            builder.continuous = True
        case "noop":
            pass
        case _ if action.startswith(("clamp_on:", "clamp_off:")):
            kind, axis = action.split(":")
            builder.clamp(axis, kind == "clamp_on")
        case _:
            raise builder.error(f"M-code action {action!r} is not allowed here")


#: Line breaks of ``str.splitlines`` other than ``\\n`` and ``\\r``; a text with any of them is
#: read line by line only.
_OTHER_BREAKS = re.compile("[\x0b\x0c\x1c\x1d\x1e\x85\u2028\u2029]")
#: Fewest consecutive plain motion blocks read at once.
BULK_MIN_LINES = 8
#: Characters of text split into words at once (bounds the temporary arrays, ~40 bytes each).
_BULK_PIECE = 1 << 20
COMPILED_FROM = 3 << 20
"""Characters read by a :class:`ProgramReader` (in all, this text included) from which it reads
the plain motion blocks by the compiled loop (:mod:`urdfpost.dialects._line_kernel`, with numba
installed: the ``fast`` extra) rather than by the numpy path: some 7 times faster (about 2.5 ns
a character), after a fixed cost of 0.4 to 0.9 s per process for numba's import and the loading
of machine code. From this size on (50k to 80k blocks), the verification that reads a program
back matches its rows to the CL points by a compiled loop as well (from
:data:`urdfpost.verification.match.COMPILED_FROM` points), so the two share that cost."""


def _has_other_breaks(text: str) -> bool:
    """Whether ``text`` has a line break of ``str.splitlines`` other than LF and CR."""
    if text.isascii():  # str.find is much faster than a regular expression
        return any(char in text for char in "\x0b\x0c\x1c\x1d\x1e")
    return _OTHER_BREAKS.search(text) is not None


def _fill_forward(values: np.ndarray, start: float) -> np.ndarray:
    """``values``, shape (k,), with each NaN replaced by the last number before it (``start``
    before the first)."""
    have = ~np.isnan(values)
    index = np.where(have, np.arange(values.shape[0]), -1)
    np.maximum.accumulate(index, out=index)
    return np.where(index >= 0, values[np.maximum(index, 0)], start)


def _grammar(spec: DialectSpec) -> _bulk.MotionGrammar | None:
    """The plain motion blocks of a control's programs, when its spec has a motion layout."""
    layout = spec.motion_layout
    if layout is None:
        return None
    prefix, placeholder, suffix = spec.block_format.partition("{n}")
    if not placeholder or suffix or len(prefix) > 1 or (prefix and not prefix.isupper()):
        return None
    codes: dict[float, bool] = {}
    if layout.rapid_word is None:
        for key, action in spec.g_codes.items():
            if action in ("rapid", "linear"):
                codes[float(key)] = action == "rapid"
        if sorted(codes.values()) != [False, True]:
            return None
    return _bulk.MotionGrammar(
        number_letter=prefix,
        number_required=spec.block_numbers_mandatory,
        lead=layout.lead,
        codes=codes,
        rapid_word=layout.rapid_word,
        require_point=spec.require_point,
    )


def read_program(
    spec: DialectSpec,
    text: str,
    path: str = "<string>",
    verbatim: Iterable[str] = (),
    rollover: frozenset[str] = frozenset(),
) -> Program:
    """Read NC text of the control described by ``spec``.

    Runs of plain motion blocks (see :class:`~urdfpost.dialects._bulk.MotionGrammar`) are read
    many at a time when the spec has a motion layout, with the same result as line by line.

    Parameters
    ----------
    spec : DialectSpec
        The control.
    text : str
        The program.
    path : str
        File name for error messages.
    verbatim : iterable of str
        Texts inserted verbatim (:class:`Insert` blocks of the program written). Lines equal
        to one of their lines (after the block number, for controls that number every line)
        are read as :class:`Insert` blocks without being parsed: taken on trust, they do not
        change the modal state.
    rollover : frozenset of str
        Rotary axes the control rolls over (the machine's ``rollover`` setting): each block
        turns them from where the one before ended, the way the control does
        (:meth:`ProgramBuilder.rollover_direction`), so their positions count turns.

    Returns
    -------
    Program
        Positions in mm and degrees; NaN where an axis position is not known.

    Raises
    ------
    ProgramParseError
        A line cannot be read.
    """
    reader = ProgramReader(spec, path, rollover)
    reader.feed(text, verbatim)
    reader.builder.flush_smoothing()  # (the whole text is read: nothing more can follow)
    return reader.take()


class ProgramReader:
    """Reads a program given in pieces (a streamed post reads back what it writes as it goes).

    Feeding the text of a program in pieces cut at line ends and taking the program read after
    each gives the blocks :func:`read_program` gives for the whole text, piece by piece: the
    modal state and the line numbers carry on.

    Parameters
    ----------
    spec : DialectSpec
        The control.
    path : str
        File name for error messages.
    rollover : frozenset of str
        Rotary axes the control rolls over (see :func:`read_program`).
    """

    def __init__(
        self, spec: DialectSpec, path: str = "<string>", rollover: frozenset[str] = frozenset()
    ) -> None:
        self.spec = spec
        self.builder = ProgramBuilder(spec, path)
        self.builder.rollover = frozenset(rollover)
        self.parse_line = spec.parse_line or parse_gcode_line
        self.grammar = _grammar(spec)
        self.lines_read = 0
        self.characters_read = 0

    def feed(self, text: str, verbatim: Iterable[str] = ()) -> None:
        """Read the next piece of the text (whole lines), with the verbatim texts of its
        :class:`Insert` blocks (see :func:`read_program`).

        Raises
        ------
        ProgramParseError
            A line that cannot be read (numbered within the whole text fed so far).
        """
        spec, builder, parse_line = self.spec, self.builder, self.parse_line
        trusted = {line.strip() for insert in verbatim for line in insert.splitlines()} - {""}

        def read_line(number: int, line: str) -> None:
            builder.line = number
            content = line.strip()
            if spec.block_numbers_mandatory:
                content = re.sub(r"^\d+\s+", "", content)
            if content in trusted:
                builder.insert(content)
            elif content:
                parse_line(spec, builder, line)

        self.characters_read += len(text)
        compiled = self.characters_read >= COMPILED_FROM
        grammar = self.grammar
        if grammar is None or _has_other_breaks(text):
            lines = text.splitlines()
            for number, line in enumerate(lines, start=self.lines_read + 1):
                read_line(number, line)
            self.lines_read += len(lines)
            return
        if "\r" in text:  # one \n per line break: the line numbers of splitlines
            text = text.replace("\r\n", "\n").replace("\r", "\n")
        number = self.lines_read + 1  # of the first line of the piece
        start = 0
        while start < len(text):
            end = text.find("\n", start + _BULK_PIECE) + 1 or len(text)
            piece = text[start:end]
            motion = _bulk.motion_lines(piece, grammar, compiled=compiled)
            plain = motion.plain.copy()
            if trusted:
                plain &= ~_trusted_lines(piece, motion, trusted, spec.block_numbers_mandatory)
            edges = [0, *(np.flatnonzero(np.diff(plain)) + 1).tolist(), plain.shape[0]]
            for row, stop in itertools.pairwise(edges):
                bulk = bool(plain[row]) and stop - row >= BULK_MIN_LINES
                if not (bulk and builder.moves(motion, slice(row, stop), number + row)):
                    for r in range(row, stop):
                        read_line(number + r, piece[motion.starts[r] : motion.ends[r]])
            number += plain.shape[0]
            start = end
        self.lines_read = number - 1

    def take(self) -> Program:
        """The blocks read since the last call, as a program (its axes: those seen so far)."""
        program = self.builder.build()
        self.builder.items = []
        return program


def _trusted_lines(
    piece: str, lines: _bulk.MotionLines, trusted: set[str], numbered: bool
) -> np.ndarray:
    """Which lines of ``piece`` are verbatim inserts, shape (L,), bool."""
    out = np.zeros(lines.starts.shape[0], dtype=bool)
    for text in trusted:
        at = piece.find(text)
        while at >= 0:
            row = int(np.searchsorted(lines.starts, at, side="right")) - 1
            content = piece[lines.starts[row] : lines.ends[row]].strip()
            if numbered:
                content = re.sub(r"^\d+\s+", "", content)
            out[row] |= content in trusted
            at = piece.find(text, at + 1)
    return out
