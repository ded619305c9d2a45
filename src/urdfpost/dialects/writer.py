"""Program -> NC text, for any :class:`~urdfpost.dialects.spec.DialectSpec`.

The writer keeps the modal state a control keeps: the last written value of every axis (as
text, so a value that rounds to the same text is not repeated), the motion code, the feed, the
tool and the spindle speed. The first motion block after the start, a tool change, a TCP
switch, a home return or an inserted text writes every axis, the motion code and the feed.

Long runs of motion blocks are written many at a time when the control's spec has a
:class:`~urdfpost.dialects.spec.MotionLayout`: the same modal rules and number formats applied
to arrays (:mod:`urdfpost.dialects._bulk`), giving the same text as block by block. The arrays
are the program's :class:`~urdfpost.program.MoveTable` runs themselves (runs given as
:class:`~urdfpost.program.Move` objects are turned into arrays chunk by chunk).
"""

from __future__ import annotations

import itertools
import logging
import math
import operator
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from urdfpost.dialects import _bulk
from urdfpost.dialects._cycles import CycleFormat, seconds
from urdfpost.dialects.spec import (
    AXIS_ORDER,
    ROTARY_ADDRESSES,
    ArcWords,
    DialectSpec,
    MotionWords,
    NumberFormat,
)
from urdfpost.errors import DialectError
from urdfpost.program import (
    ARC_PLANES,
    FEED_INVERSE_TIME,
    Arc,
    Block,
    Clamp,
    Comment,
    Coolant,
    CutterComp,
    Cycle,
    Dwell,
    Home,
    Insert,
    MachineMove,
    Move,
    MoveTable,
    Program,
    Smoothing,
    Spindle,
    Stop,
    Tcp,
    TiltedPlane,
    ToolChange,
    WorkOffset,
)
from urdfpost.units import mm_per_unit

logger = logging.getLogger(__name__)

#: Fewest consecutive motion blocks written at once (shorter runs go block by block).
BULK_MIN_MOVES = 16
#: Motion blocks formatted together (their arrays, ~100 bytes a block, stay in the cache).
_BULK_ROWS = 1 << 13

_RAPID, _POSITION, _FEED = (operator.attrgetter(name) for name in ("rapid", "position", "feed"))
#: Masks of a cell (four characters, see :mod:`~urdfpost.dialects._bulk`): all of it, all but
#: its first character (the blank before a word that starts a line).
_ALL_CHARACTERS = np.uint32(0xFFFFFFFF)
_NOT_FIRST_CHARACTER = ~_bulk.character_mask(0)

_SPINDLE_ACTIONS = {"cw": "spindle_cw", "ccw": "spindle_ccw", "off": "spindle_off"}
_COOLANT_ACTIONS = {"flood": "coolant_flood", "mist": "coolant_mist", "off": "coolant_off"}
_COOLANT_FALLBACK = frozenset({"through", "air"})


@dataclass
class _Modal:
    """What the control remembers between blocks (writer side)."""

    axes: dict[str, str] = field(default_factory=dict)
    motion: bool | None = None  # True rapid, False linear, None unknown
    feed: str | None = None
    tool: int | None = None
    offset: int | None = None  # the tool's length offset register
    rpm: str | None = None
    spindle: str = "off"
    # whether the last spindle (coolant) block written stopped it: a second stop is not
    # written (a tool change's stop, then the CL data's own before its LOADTL)
    spindle_stopped: bool = False
    coolant_stopped: bool = False
    force: bool = True
    plane: str | None = None  # the arc plane last written
    comp_word: str | None = None  # a radius compensation word for the next straight line

    def invalidate(self) -> None:
        """Forget axes, motion code and feed: the next motion block writes them all."""
        self.axes.clear()
        self.motion = None
        self.feed = None
        self.force = True


class ProgramWriter:
    """Writes one program; use :func:`write_program`.

    Parameters
    ----------
    spec : DialectSpec
        The control.
    program : Program
        What to write.
    block_numbers : bool
        Number the blocks.
    program_number : int or None
        Program number for ``{number}`` templates.
    """

    def __init__(
        self,
        spec: DialectSpec,
        program: Program,
        block_numbers: bool,
        program_number: int | None,
    ) -> None:
        self.spec = spec
        self.program = program
        self.numbered = block_numbers
        self.lines: list[str] = []
        self.modal = _Modal()
        self._next_number = spec.block_start
        self._merges: dict[int, int] = {}  # tool change index -> merged spindle index
        self._spindle_running = False  # at the end of the pieces written so far
        self._rpm: float | None = None  # the speed of the spindle running (tapping cycles)
        self._check_program()
        self.fields = {
            "name": spec.format_name(program.name),
            "number": program_number if program_number is not None else _number(spec, program),
            "unit_code": spec.unit_code(program.units),
        }
        self.scale = mm_per_unit(program.units)
        self.feed_scale = spec.feed_inch_unit if program.units == "inch" else 1.0
        self.linear = spec.linear_inch if program.units == "inch" else spec.linear_mm
        self.feed_format = spec.feed_inch if program.units == "inch" else spec.feed_mm
        # inverse time: F is 1/min whatever the units, written in every feed block, between
        # the control's G93 and G94 (on: the control is in G93)
        self.inverse = program.feed_mode == FEED_INVERSE_TIME
        self.inverse_on = False
        if self.inverse:
            if spec.inverse_time is None:
                raise DialectError(
                    f"{spec.name} has no inverse-time feed; expected a program with feeds per "
                    "minute (a feed per block, docs/job.md)"
                )
            self.feed_scale = 1.0
            self.feed_format = spec.inverse_time_feed
        prefix, n, suffix = spec.block_format.partition("{n}")
        plain = n and "{" not in prefix + suffix and "}" not in prefix + suffix
        self._number_affixes = (prefix, suffix) if plain else None
        # rollover axes: written modulo 360, each with the last value written (counted turns)
        self._rollover = program.rollover & program.rotary & frozenset(program.axes)
        self._rolled: dict[str, float] = {}
        self._plane = False  # a tilted working plane is on

    # -- output primitives -------------------------------------------------------------------

    def emit(self, text: str, numbered: bool = True) -> None:
        """Append one line, with a block number when numbering is on and ``numbered``."""
        if self.numbered and numbered:
            number = self.spec.block_format.format(n=self._next_number)
            text = f"{number} {text}" if text else number
            self._next_number += self.spec.block_step
            if self.spec.block_max and self._next_number > self.spec.block_max:
                self._next_number = self.spec.block_step
        self.lines.append(text)

    def emit_templates(self, templates: tuple[str, ...], numbered: bool = True, **extra) -> None:
        """Append template lines filled with the program fields and ``extra``."""
        for template in templates:
            self.emit(template.format(**self.fields, **extra), numbered)

    def emit_comment(self, text: str) -> None:
        """Append a comment line."""
        self.emit(self.spec.format_comment(text), self.spec.number_comments)

    # -- program -----------------------------------------------------------------------------

    def write(self, header: str | None, blank: np.ndarray | None = None) -> str:
        """The whole program text, ending with a newline (``blank``: as for :meth:`open`)."""
        self.open(header, blank)
        self.write_body()
        self.close()
        text = "\n".join(self.lines) + "\n"
        self.lines = []
        return text

    def open(self, header: str | None, blank: np.ndarray | None = None) -> None:
        """Write the program start: its opening, the blank, name and ``header`` comments and
        the setup.

        Parameters
        ----------
        header : str or None
            Comment lines.
        blank : ndarray, shape (2, 3), optional
            Lowest and highest corner of the stock's box in the workpiece frame, mm: the
            control's ``blank_form`` lines when it has them.
        """
        spec = self.spec
        self.emit_templates(spec.program_open, spec.number_frame)
        if blank is not None and spec.blank_form:
            corners = {
                f"{a}{k}": self.format_axis(a.upper(), float(blank[k, j]))
                for k in (0, 1)
                for j, a in enumerate("xyz")
            }
            self.emit_templates(spec.blank_form, True, **corners)
        if spec.name_comment:
            self.emit_comment(self.program.name)
        for line in (header or "").splitlines():
            self.emit_comment(line)
        self.emit_templates(spec.setup)
        rotary_continuous = self.program.continuous & frozenset(self.program.axes)
        if spec.shortest_path and rotary_continuous & self.program.rotary:
            self.emit(spec.shortest_path)

    def write_body(self, program: Program | None = None) -> None:
        """Write the blocks of ``program`` (default: the program given at construction).

        A program written in pieces (a streamed post) passes each piece in turn, between
        :meth:`open` and :meth:`close`: the modal state and the block numbers carry on, so
        the text is the one the pieces would make as one program. The pieces must have the
        axes, units and TCP mode of the first.
        """
        if program is not None:
            if (program.axes, program.units, program.tcp) != (
                self.program.axes,
                self.program.units,
                self.program.tcp,
            ):
                raise DialectError(
                    f"a piece of program {self.program.name} has axes {program.axes}, units "
                    f"{program.units}, TCP {program.tcp}; the program has "
                    f"{self.program.axes}, {self.program.units}, TCP {self.program.tcp}"
                )
            if program.feed_mode != self.program.feed_mode:
                raise DialectError(
                    f"a piece of program {self.program.name} has feed mode "
                    f"{program.feed_mode}; the program has {self.program.feed_mode}"
                )
            self.program = program
            self._merges = {}
        self._plan_spindle_merges()
        parts = self.program.parts  # runs of moves as tables (or Move objects)
        is_move = np.fromiter(map(isinstance, parts, itertools.repeat(Move)), bool, len(parts))
        edges = np.flatnonzero(np.diff(is_move)) + 1
        for start, end in zip([0, *edges.tolist()], [*edges.tolist(), len(parts)], strict=True):
            if start == end:
                continue
            if is_move[start]:
                self.write_moves(parts[start:end])  # type: ignore[arg-type]
            else:
                for index in range(start, end):
                    part = parts[index]
                    if isinstance(part, MoveTable):
                        self.write_moves(part)
                    else:
                        self.write_block(index, part)

    def close(self) -> None:
        """Write the program end (after leaving inverse time)."""
        self.leave_inverse_time()
        self.emit_templates(self.spec.finish)
        self.emit_templates(self.spec.program_close, self.spec.number_frame)

    def take(self) -> str:
        """The lines written since the last call, each ending with a newline ("" if none)."""
        if not self.lines:
            return ""
        text = "\n".join(self.lines) + "\n"
        self.lines = []
        return text

    def _check_program(self) -> None:
        axes = self.program.axes
        unknown = [a for a in axes if a not in AXIS_ORDER]
        if unknown or len(set(axes)) != len(axes):
            raise DialectError(
                f"program axes {axes} must be distinct letters among {' '.join(AXIS_ORDER)}"
            )
        wrong = set(axes) & (self.program.rotary ^ ROTARY_ADDRESSES)
        if wrong:
            raise DialectError(
                f"axes {sorted(wrong)}: X, Y, Z must be linear and A, B, C rotary "
                f"(program.rotary={sorted(self.program.rotary)})"
            )

    def _plan_spindle_merges(self) -> None:
        """Find spindle starts whose speed can go into the preceding tool change block.

        Only while the spindle is stopped: a speed in the tool change would otherwise change
        the speed of the running spindle before its next start block.
        """
        blocks = self.program.parts  # a MoveTable is neither a comment nor coolant
        running = self._spindle_running  # (as the pieces before left it)
        for block in blocks:
            if isinstance(block, Spindle):
                running = block.direction != "off"
        running, self._spindle_running = self._spindle_running, running
        if self.spec.tool_change_speed is None:
            return
        for index, block in enumerate(blocks):
            if isinstance(block, Spindle):
                running = block.direction != "off"
            if not isinstance(block, ToolChange) or running:
                continue
            for later in range(index + 1, len(blocks)):
                candidate = blocks[later]
                if isinstance(candidate, Spindle):
                    if candidate.direction != "off" and candidate.rpm > 0:
                        self._merges[index] = later
                    break
                if not isinstance(candidate, Comment | Coolant):
                    break

    # -- blocks ------------------------------------------------------------------------------

    def write_block(self, index: int, block: Block) -> None:
        """Write one program block (``index``: its place in :attr:`Program.parts`)."""
        match block:
            case Move():
                self.write_move(block)
            case ToolChange():
                self.leave_inverse_time()
                self.write_tool_change(index, block)
            case Spindle():
                self._rpm = block.rpm if block.direction != "off" else None
                self.write_spindle(block)
            case Coolant():
                self.write_coolant(block)
            case Comment():
                self.emit_comment(block.text)
            case Insert():
                for line in block.text.splitlines():
                    self.emit(line, self.spec.block_numbers_mandatory)
                self.modal.invalidate()
                self.modal.spindle_stopped = self.modal.coolant_stopped = False  # unknown
            case Tcp():
                self.write_tcp(block)
            case Stop():
                self.emit(self.spec.m_code_for("optional_stop" if block.optional else "stop"))
                self.modal.spindle_stopped = self.modal.coolant_stopped = False  # the operator's
            case Home():
                self.leave_inverse_time()
                if self.spec.home_comment is not None:
                    self.emit_comment(self.spec.home_comment)
                self.emit_templates(self.spec.home)
                self.modal.invalidate()
                self._rolled.clear()  # the axes' positions are the control's home
            case MachineMove():
                self.write_machine_move(block)
            case Smoothing():
                self.write_smoothing(block)
            case Arc():
                self.write_arc(block)
            case CutterComp():
                self.write_cutter_comp(block)
            case TiltedPlane():
                self.write_plane(block)
            case Clamp():
                self.emit(self.spec.m_code_for(f"clamp_{'on' if block.on else 'off'}:{block.axis}"))
            case WorkOffset():
                count = self.spec.work_offsets
                if not 1 <= block.number <= count:
                    raise DialectError(
                        f"work offset {block.number}: {self.spec.name} has work offsets 1 "
                        f"to {count}"
                    )
                for i, line in enumerate(self.spec.work_offset):  # continuation lines: no N
                    self.emit(line.format(number=block.number, code=53 + block.number), i == 0)
            case Cycle():
                self.write_cycle(block)
            case Dwell():
                if not self.spec.dwell:
                    raise DialectError(f"{self.spec.name}: no dwell block")
                text = seconds(block.seconds)
                if self.spec.require_point and "." not in text:
                    text += "."  # (Fanuc G4 X1 would be a millisecond)
                self.emit_templates(self.spec.dwell, seconds=text)
            case _:
                raise DialectError(f"cannot write block {block!r}")

    def write_cycle(self, cycle: Cycle) -> None:
        """A canned cycle in the control's syntax (:attr:`DialectSpec.cycle_lines`); the next
        motion block writes every axis."""
        if self.spec.cycle_lines is None:
            raise DialectError(f"{self.spec.name}: canned cycles are not written for this control")
        axes = self.program.axes
        if cycle.up is not None:
            raise DialectError(
                f"cycle {cycle}: a tilted hole; expected it in a tilted plane or as its motion"
            )
        if "Z" not in axes or len(cycle.holes[0]) != len(axes):
            raise DialectError(
                f"cycle {cycle}: expected one position per axis of {axes}, Z among them"
            )
        fmt = CycleFormat(
            axis=self.format_axis,
            length=lambda v: self.format_axis("Z", v),
            feed=lambda f: self.feed_format.format(f / self.feed_scale),
            rpm=self._rpm,
            scale=self.scale,
        )
        try:
            lines = self.spec.cycle_lines(cycle, axes, fmt)
        except ValueError as e:
            raise DialectError(f"{self.spec.name}: {e}") from e
        for line in lines:
            self.emit(line, not line.startswith(" "))
        self.modal.invalidate()

    def write_plane(self, block: TiltedPlane) -> None:
        """A tilted working plane on (:attr:`DialectSpec.plane_on`, then in a TCP program
        :attr:`DialectSpec.plane_length_on`) or off."""
        spec = self.spec
        if spec.plane_convention is None:
            raise DialectError(f"{spec.name}: no tilted working plane")
        self._plane = block.angles is not None
        if block.angles is None:
            if self.program.tcp:
                self.emit_templates(spec.plane_length_off, offset=self.modal.offset)
            self.emit_templates(spec.plane_off)
        else:
            if block.convention != spec.plane_convention:
                raise DialectError(
                    f"{spec.name}: a tilted plane by {block.convention} angles; expected "
                    f"{spec.plane_convention} angles"
                )
            a, b, c = (spec.rotary.format(v) for v in block.angles)
            self.emit_templates(spec.plane_on, a=a, b=b, c=c)
            if self.program.tcp:
                if self.modal.offset is None and any("{offset}" in t for t in spec.plane_length_on):
                    raise DialectError(
                        f"{spec.name}: a tilted plane in a TCP program needs the tool's length "
                        "offset register; put a ToolChange before it"
                    )
                self.emit_templates(spec.plane_length_on, offset=self.modal.offset)
        # the linear axes' values are in another frame: the next motion block writes them (and
        # its motion code and feed); the rotary axes stand, and are not written again
        modal = self.modal
        for address in "XYZ":
            modal.axes.pop(address, None)
        modal.motion = None
        modal.feed = None

    def write_machine_move(self, move: MachineMove) -> None:
        """A rapid in machine coordinates; the next motion block writes every axis."""
        if not move.axes or len(move.axes) != len(move.values):
            raise DialectError(f"machine move {move}: expected one value per axis")
        words = " ".join(
            f"{a}{self._axis_word(a, v)}" for a, v in zip(move.axes, move.values, strict=True)
        )
        self.emit(self.spec.machine_move.format(words=words))
        self.modal.invalidate()

    def _axis_text(self, address: str, value: float) -> str:
        """The modal text of an axis value: :meth:`format_axis`, or for a rollover axis the
        value modulo 360 in [0, 360) as written."""
        if address not in self._rollover:
            return self.format_axis(address, value)
        text = self.spec.rotary.format(value % 360.0)
        if float(text) >= 360.0:  # rounds up to a whole turn
            text = self.spec.rotary.format(0.0)
        return text

    def _axis_word(self, address: str, value: float, text: str | None = None) -> str:
        """What follows the address of an axis word written now: its text, or for a rollover
        axis :attr:`DialectSpec.rollover_value` of it, signed with the direction of the turn
        from the value written last where the control reads the sign so (the turn of a
        rollover axis is less than half a turn: :func:`urdfpost.posting.rollover`)."""
        text = self._axis_text(address, value) if text is None else text
        if address not in self._rollover:
            return text
        if self.spec.rollover_direction == "sign":
            last = self._rolled.get(address)
            step = 0.0 if last is None else 180.0 - (last - value + 180.0) % 360.0
            if step < 0.0:
                text = "-" + text.lstrip("+")
        self._rolled[address] = value
        return self.spec.rollover_value.format(value=text)

    def write_smoothing(self, block: Smoothing) -> None:
        """The control's path smoothing on (its tolerance cycle, in program units and degrees)
        or off."""
        spec = self.spec
        templates = spec.smoothing_on if block.on else spec.smoothing_off
        if not templates:
            raise DialectError(f"{spec.name}: no path smoothing cycle to write {block}")
        needs = any("{tol}" in t for t in templates)
        if block.on and needs and block.tolerance is None:
            raise DialectError(f"{spec.name}: path smoothing needs a tolerance; got {block}")
        angles = any("{angle}" in t for t in templates)
        if block.on and angles and block.angle is None:
            raise DialectError(f"{spec.name}: path smoothing needs a rotary tolerance; {block}")
        fields: dict[str, str] = {}
        if block.on and needs:
            assert block.tolerance is not None
            # the program's decimals, without sign or trailing zeros: T0.01, P0.0004
            tol_format = NumberFormat(self.linear.decimals, trim=True)
            fields["tol"] = tol_format.format(block.tolerance / self.scale)
            if float(fields["tol"]) <= 0.0:
                raise DialectError(
                    f"{spec.name}: path tolerance {block.tolerance} mm is written as "
                    f"{fields['tol']}; expected a tolerance the program's decimals can write"
                )
        if block.on and angles:
            assert block.angle is not None
            fields["angle"] = NumberFormat(spec.rotary.decimals, trim=True).format(block.angle)
        self.emit_templates(templates, True, **fields)

    def write_move(self, move: Move) -> None:
        """Write a motion block with only the changed axes (all after a forced state)."""
        if len(move.position) != len(self.program.axes):
            raise DialectError(
                f"move {move} has {len(move.position)} values for axes {self.program.axes}"
            )
        pairs = zip(self.program.axes, move.position, strict=True)
        known = [(a, self._axis_text(a, v)) for a, v in pairs if not math.isnan(v)]
        modal = self.modal
        if self._plane:  # the rotary axes stand in a tilted plane: not written
            modal.axes.update((a, t) for a, t in known if a in ROTARY_ADDRESSES)
            known = [(a, t) for a, t in known if a not in ROTARY_ADDRESSES]
        if not known:
            raise DialectError(f"move {move} has no axis value (all NaN, or rotary in a plane)")
        changed = [(a, text) for a, text in known if modal.axes.get(a) != text]
        if modal.force or not self.spec.modal_axes or not changed:
            changed = known
        modal.axes.update(changed)
        if self._rollover:
            value = dict(zip(self.program.axes, move.position, strict=True))
            changed = [(a, self._axis_word(a, value[a], text)) for a, text in changed]
        code = None
        if self.spec.rapid_modal and (modal.force or modal.motion is not move.rapid):
            code = self.spec.g_code_for("rapid" if move.rapid else "linear")
        modal.motion = move.rapid
        feed = None
        if not move.rapid and self.inverse:
            if move.feed is None:
                raise DialectError(
                    f"move {move}: a feed move of an inverse-time program without its F "
                    "(one over the block's time)"
                )
            self.enter_inverse_time()
        if not move.rapid and move.feed is not None:
            text = self.feed_format.format(move.feed / self.feed_scale)
            if float(text) <= 0.0:
                unit = "1/min" if self.inverse else "mm/min"
                raise DialectError(f"feed {move.feed} {unit} is written as F{text}")
            if text != modal.feed or self.inverse:  # G93: F in every feed block
                feed = modal.feed = text
        modal.force = False
        extra: tuple[str, ...] = ()
        if modal.comp_word is not None:
            extra, modal.comp_word = (modal.comp_word,), None
        words = MotionWords(move.rapid, code, tuple(changed), feed, extra)
        self.emit(self.spec.format_motion(words))

    def write_cutter_comp(self, block: CutterComp) -> None:
        """Cutter radius compensation: the control's line (G41 D1, G42, G40), or a word the
        next straight line carries (Heidenhain RL, RR, R0).

        Raises
        ------
        DialectError
            A side other than left, right or off; on a control with words, another plane than
            XY.
        """
        spec = self.spec
        if block.side not in ("left", "right", "off"):
            raise DialectError(
                f"cutter compensation side {block.side!r}; expected 'left', 'right' or 'off'"
            )
        if spec.cutter_comp:
            action = {"XY": "plane_xy", "ZX": "plane_zx", "YZ": "plane_yz"}[block.plane]
            plane = spec.g_code_for(action) if action in spec.g_codes.values() else ""
            template = spec.cutter_comp[block.side]
            if fault := spec.comp_fault(block.register, self.modal.tool):
                raise DialectError(fault)
            register = block.register if block.register is not None else self.modal.tool
            if register is None and "{register}" in template:
                raise DialectError(
                    f"{spec.name}: cutter compensation {block.side} before any tool change; "
                    "expected a ToolChange before it (its number is the D word)"
                )
            line = template.format(register=register, plane=plane)
            self.emit(" ".join(line.split()))
            if block.side != "off":
                self.modal.plane = block.plane
            return
        if not spec.cutter_comp_words:
            raise DialectError(f"{spec.name} writes no cutter radius compensation")
        if fault := spec.comp_fault(block.register, self.modal.tool, block.plane):
            raise DialectError(fault)
        self.modal.comp_word = spec.cutter_comp_words[block.side]

    def write_arc(self, arc: Arc) -> None:
        """Write an arc block from where the axes stand (their last written values).

        The plane's two axes are always written, the other axes when their text changes; the
        centre incremental from the start as written (I, J, K), or absolute
        (:attr:`DialectSpec.arc_centre_absolute`). The next linear block writes its motion
        code again.

        Raises
        ------
        DialectError
            The control takes no arcs in the plane, the start is not known (no motion block
            before, or after a home return), a rotary axis would move, or the arc climbs on a
            control without helices.
        """
        spec, modal, axes = self.spec, self.modal, self.program.axes
        if modal.comp_word is not None:
            raise DialectError(
                f"{spec.name}: radius compensation {modal.comp_word} on an arc; expected it on "
                "a straight line"
            )
        if arc.plane not in spec.arc_planes:
            raise DialectError(f"{spec.name} takes no arcs in the {arc.plane} plane: {arc}")
        if len(arc.position) != len(axes):
            raise DialectError(f"arc {arc} has {len(arc.position)} values for axes {axes}")
        first, second, normal = ARC_PLANES[arc.plane]
        if modal.force or any(modal.axes.get(a) is None for a in (first, second, normal)):
            raise DialectError(
                f"arc {arc}: expected a motion block before it (the arc starts where the axes "
                "stand)"
            )
        texts = {a: self.format_axis(a, v) for a, v in zip(axes, arc.position, strict=True)}
        moved = [a for a in axes if a in ROTARY_ADDRESSES and texts[a] != modal.axes.get(a)]
        if moved:
            raise DialectError(f"arc {arc}: rotary axis {moved[0]} moves on an arc")
        if texts[normal] != modal.axes[normal] and not spec.arc_helix:
            raise DialectError(f"{spec.name} takes no helix: {arc}")
        words = [(a, texts[a]) for a in axes if a in (first, second)]
        words += [
            (a, t) for a, t in texts.items() if a not in (first, second) and t != modal.axes.get(a)
        ]
        centre = dict(zip("XYZ", arc.centre, strict=True))
        if spec.arc_centre_absolute:
            centre_words = tuple((a, self.format_axis(a, centre[a])) for a in (first, second))
        else:
            letters = {"X": "I", "Y": "J", "Z": "K"}
            start = {a: float(modal.axes[a]) for a in (first, second)}
            order = sorted((first, second))  # I J K in that order
            centre_words = tuple(
                (
                    letters[a] + spec.arc_centre_suffix,
                    self.linear.format(centre[a] / self.scale - start[a]),
                )
                for a in order
            )
        feed = None
        if self.inverse:
            if arc.feed is None:
                raise DialectError(
                    f"arc {arc}: a feed move of an inverse-time program without its F (one "
                    "over the arc's time)"
                )
            self.enter_inverse_time()
        if arc.feed is not None:
            text = self.feed_format.format(arc.feed / self.feed_scale)
            if float(text) <= 0.0:
                unit = "1/min" if self.inverse else "mm/min"
                raise DialectError(f"feed {arc.feed} {unit} is written as F{text}")
            if text != modal.feed or self.inverse:  # G93: F in every feed block
                feed = modal.feed = text
        plane_code = None
        if arc.plane != modal.plane:
            action = {"XY": "plane_xy", "ZX": "plane_zx", "YZ": "plane_yz"}[arc.plane]
            plane_code = spec.g_code_for(action) if action in spec.g_codes.values() else None
            modal.plane = arc.plane
        # the turn and the climb from the start as written (for a control that takes an
        # incremental angle, Heidenhain CP IPA)
        scale = self.scale
        start_xyz = [math.nan] * 3
        for a in (first, second, normal):
            start_xyz["XYZ".index(a)] = float(modal.axes[a]) * scale
        end_xyz = [math.nan] * 3
        for a in (first, second, normal):
            end_xyz["XYZ".index(a)] = float(texts[a]) * scale
        centre_xyz = list(arc.centre)
        for a, text in centre_words if spec.arc_centre_absolute else ():
            centre_xyz["XYZ".index(a)] = float(text) * scale
        written = Arc(
            tuple(end_xyz), (centre_xyz[0], centre_xyz[1], centre_xyz[2]), arc.plane, arc.clockwise
        )
        sweep = math.degrees(written.sweep(start_xyz, ("X", "Y", "Z")))
        turn = spec.rotary.format(-sweep if arc.clockwise else sweep)
        climb = None
        if texts[normal] != modal.axes[normal]:
            rise = float(texts[normal]) - float(modal.axes[normal])
            climb = (normal, self.linear.format(rise))
        lines = spec.format_arc(
            ArcWords(
                arc.plane,
                plane_code,
                arc.clockwise,
                tuple(words),
                centre_words,
                feed,
                turn,
                climb,
            )
        )
        for line in lines:
            self.emit(line)
        modal.axes.update(texts)
        modal.motion = None  # the next linear block writes G1 (L on Heidenhain anyway)

    def write_moves(self, moves: Sequence[Move] | MoveTable) -> None:
        """Write consecutive motion blocks: as :meth:`write_move` on each, many at a time.

        The first block goes through :meth:`write_move` (it may follow a forced state); the
        others are formatted in chunks when the spec has a motion layout, from the table's
        arrays (or arrays made of the Move objects). A chunk whose values the block-by-block
        path would refuse or treat specially (NaN, a wrong number of values, a feed written as
        zero) is written block by block from there on, errors included.
        """
        width = len(self.program.axes)
        if isinstance(moves, MoveTable):
            table = moves

            def arrays(start: int, stop: int) -> _MoveArrays | None:
                return _arrays_of_table(table.rows(start, stop))

            def objects(start: int, stop: int) -> Sequence[Move]:
                return table.rows(start, stop).moves()
        else:
            run = moves

            def arrays(start: int, stop: int) -> _MoveArrays | None:
                return _arrays_of_moves(run[start:stop], width)

            def objects(start: int, stop: int) -> Sequence[Move]:
                return run[start:stop]

        count = len(moves)
        if self.inverse and not self.inverse_on:
            # G93 right before the first feed move (the rapids before it are not affected)
            rapids = moves.rapid if isinstance(moves, MoveTable) else [m.rapid for m in moves]
            cuts = np.flatnonzero(~np.asarray(rapids, dtype=bool))
            if cuts.size:
                first = int(cuts[0])
                head: Sequence[Move] | MoveTable
                tail: Sequence[Move] | MoveTable
                if isinstance(moves, MoveTable):
                    head, tail = moves.rows(0, first), moves.rows(first, count)
                else:
                    head, tail = moves[:first], moves[first:]
                if first:
                    self.write_moves(head)
                self.enter_inverse_time()
                self.write_moves(tail)
                return
        if self.spec.motion_layout is None or count < BULK_MIN_MOVES:
            for move in objects(0, count):
                self.write_move(move)
            return
        self.write_move(objects(0, 1)[0])
        for start in range(1, count, _BULK_ROWS):
            chunk = arrays(start, start + _BULK_ROWS)
            if chunk is None or not self._write_move_chunk(*chunk):
                for move in objects(start, count):
                    self.write_move(move)
                return

    def _write_move_chunk(
        self, pos: np.ndarray, rapid: np.ndarray, feed: np.ndarray, has_feed: np.ndarray
    ) -> bool:
        """Write motion blocks that follow a motion block, all at once.

        Parameters
        ----------
        pos : ndarray, shape (k, m)
            Positions, one column per program axis (mm, degrees).
        rapid : ndarray, shape (k,), bool
        feed : ndarray, shape (k,), mm/min
            Where ``has_feed``.
        has_feed : ndarray, shape (k,), bool
            Whether the block has a feed (:attr:`Move.feed` not None).

        Returns
        -------
        bool
            False, with nothing written, when the blocks are not all plain (finite values for
            every axis, feeds written as positive numbers), the modal state is not known in
            full, or the block numbers are not a plain ``prefix{n}suffix``.
        """
        spec, modal, layout = self.spec, self.modal, self.spec.motion_layout
        axes = self.program.axes
        k = len(rapid)
        if (
            layout is None
            or self._rollover  # (written block by block: the words depend on the turn)
            or modal.force
            or not (modal.motion is True or modal.motion is False)
            or any(a not in modal.axes for a in axes)
            or (self.numbered and self._number_affixes is None)
            or (self.numbered and 0 < spec.block_max < spec.block_step)
        ):
            return False
        if pos.shape != (k, len(axes)) or not np.isfinite(pos).all():
            return False
        if self.inverse and (not self.inverse_on or not has_feed[~rapid].all()):
            return False  # (the block-by-block writer says what is wrong)
        # -- axis values: scaled integers stand for their texts ---------------------------
        formats: list[NumberFormat] = []
        scaled = np.empty((k, len(axes)), dtype=np.int64)
        previous = np.empty(len(axes), dtype=np.int64)
        for j, address in enumerate(axes):
            rotary = address in ROTARY_ADDRESSES
            fmt = spec.rotary if rotary else self.linear
            column = pos[:, j] if rotary else pos[:, j] / self.scale
            ints = _bulk.scaled_integers(column, fmt.decimals)
            if ints is None:
                return False
            last = _scaled_from_text(modal.axes[address], fmt.decimals)
            if last is None:
                return False
            formats.append(fmt)
            scaled[:, j] = ints
            previous[j] = last
        before = np.vstack([previous, scaled[:-1]])
        changed = scaled != before
        if spec.modal_axes:
            written = changed | ~changed.any(axis=1, keepdims=True)
        else:
            written = np.ones_like(changed)
        # -- feed: written when it changes among the feed moves --------------------------
        feed_rows = np.flatnonzero(~rapid & has_feed)
        feed_scaled = np.zeros(0, dtype=np.int64)
        if feed_rows.size:
            values = feed[feed_rows] / self.feed_scale
            if not np.isfinite(values).all():
                return False
            feed_ints = _bulk.scaled_integers(values, self.feed_format.decimals)
            if feed_ints is None or (feed_ints <= 0).any():
                return False
            feed_scaled = feed_ints
        last_feed = None
        if modal.feed is not None:
            last_feed = _scaled_from_text(modal.feed, self.feed_format.decimals)
            if last_feed is None:
                return False
        feed_written = np.ones(feed_rows.size, dtype=bool)
        if feed_rows.size and not self.inverse:  # (inverse time: F in every feed block)
            feed_written[1:] = feed_scaled[1:] != feed_scaled[:-1]
            feed_written[0] = last_feed is None or feed_scaled[0] != last_feed
        # -- the lines, one column each: cells of four characters, NUL where none ---------
        blocks = [self._block_number_cells(k)] if self.numbered else []
        # lines with a word already (the next needs a blank): the block number's is the blank
        # after it
        started = np.full(k, self.numbered)

        def add(cells: np.ndarray, present: np.ndarray | None) -> None:
            """A word (a blank, then its text) on the lines ``present`` (None: all)."""
            if present is not None:
                cells *= present
            cells[0] &= np.where(started, _ALL_CHARACTERS, _NOT_FIRST_CHARACTER)
            if present is None:
                started[:] = True
            else:
                started[:] |= present
            blocks.append(cells)

        if layout.lead:
            add(_bulk.repeated_cells(" " + layout.lead, k), None)
        if spec.rapid_modal:
            code_rows = rapid != np.concatenate([[modal.motion], rapid[:-1]])
            rapid_code = _bulk.text_cells(" " + spec.g_code_for("rapid"))
            linear_code = _bulk.text_cells(" " + spec.g_code_for("linear"))
            width = max(rapid_code.size, linear_code.size)  # NUL cells for the shorter
            rapid_code = np.pad(rapid_code, (0, width - rapid_code.size))
            linear_code = np.pad(linear_code, (0, width - linear_code.size))
            add(np.where(rapid[None, :], rapid_code[:, None], linear_code[:, None]), code_rows)
        for j, address in enumerate(axes):
            add(
                _bulk.number_cells(scaled[:, j], pos[:, j] < 0, formats[j], " " + address),
                written[:, j],
            )
        if layout.rapid_word:
            add(_bulk.repeated_cells(" " + layout.rapid_word, k), rapid)
        if feed_written.any():
            at = feed_rows[feed_written]
            cells = _bulk.number_cells(
                feed_scaled[feed_written], np.zeros(at.size, dtype=bool), self.feed_format, " F"
            )
            feeds = np.zeros((cells.shape[0], k), dtype=np.uint32)
            feeds[:, at] = cells
            present = np.zeros(k, dtype=bool)
            present[at] = True
            add(feeds, present)
        blocks.append(_bulk.repeated_cells("\n", k))
        self.lines.append(_bulk.text_of_cells(np.concatenate(blocks))[:-1])
        # -- the modal state after the last block -----------------------------------------
        last = pos[-1].tolist()
        modal.axes.update((a, self.format_axis(a, v)) for a, v in zip(axes, last, strict=True))
        modal.motion = bool(rapid[-1])
        if feed_rows.size:
            modal.feed = self.feed_format.format(float(feed[feed_rows[-1]]) / self.feed_scale)
        return True

    def enter_inverse_time(self) -> None:
        """Switch the control to inverse-time feed (G93) unless it is in it; the next feed
        block writes its F."""
        if self.inverse and not self.inverse_on:
            assert self.spec.inverse_time is not None  # (checked at construction)
            self.emit(self.spec.inverse_time)
            self.inverse_on = True
            self.modal.feed = None

    def leave_inverse_time(self) -> None:
        """Switch the control back to feed per minute (G94) when it is in inverse time
        (before a tool change, a home return, the program end)."""
        if self.inverse_on:
            self.emit(self.spec.per_minute)
            self.inverse_on = False
            self.modal.feed = None

    def _block_number_cells(self, k: int) -> np.ndarray:
        """Block numbers of the next ``k`` lines (without the blank after them), one column
        of cells each (see :func:`~urdfpost.dialects._bulk.text_of_cells`), shape (c, k)."""
        spec = self.spec
        step, top = spec.block_step, spec.block_max
        numbers = self._next_number + step * np.arange(k, dtype=np.int64)
        if top:
            wrapped = numbers > top
            if wrapped.any():
                w = int(np.argmax(wrapped))
                period = top // step
                numbers[w:] = step + step * (np.arange(k - w, dtype=np.int64) % period)
        following = int(numbers[-1]) + step
        self._next_number = step if top and following > top else following
        assert self._number_affixes is not None
        prefix, suffix = self._number_affixes
        return np.concatenate(
            [
                _bulk.repeated_cells(prefix, k),
                _bulk.integer_cells(numbers),
                _bulk.repeated_cells(suffix, k),
            ]
        )

    def format_axis(self, address: str, value: float) -> str:
        """Axis value text in program units."""
        if address in ROTARY_ADDRESSES:
            return self.spec.rotary.format(value)
        return self.linear.format(value / self.scale)

    def write_tool_change(self, index: int, block: ToolChange) -> None:
        """Tool change, with the next spindle speed merged in when the control does that."""
        fault = self.spec.tool_fault(block.number, block.offset, tcp=self.program.tcp)
        if fault is not None:
            raise DialectError(fault)
        self.modal.tool = block.number
        self.modal.offset = block.number if block.offset is None else block.offset
        merged = self.program.parts[self._merges[index]] if index in self._merges else None
        if isinstance(merged, Spindle) and self.spec.tool_change_speed is not None:
            rpm = self.spec.rpm.format(merged.rpm)
            self.emit_templates(self.spec.tool_change_speed, tool=block.number, rpm=rpm)
            self.modal.rpm = rpm
        else:
            self.emit_templates(self.spec.tool_change, tool=block.number)
        self.modal.invalidate()

    def write_spindle(self, block: Spindle) -> None:
        """Spindle start, stop or speed change."""
        action = _SPINDLE_ACTIONS.get(block.direction)
        if action is None:
            raise DialectError(
                f"unknown spindle direction {block.direction!r}; expected 'cw', 'ccw' or 'off'"
            )
        code = self.spec.m_code_for(action)
        self.modal.spindle = block.direction
        if block.direction == "off":
            if not self.modal.spindle_stopped:  # (stopped already: nothing to write)
                self.emit(code)
            self.modal.spindle_stopped = True
            return
        self.modal.spindle_stopped = False
        rpm = self.spec.rpm.format(block.rpm)
        if self.spec.spindle_speed is not None and rpm != self.modal.rpm:
            self.emit(self.spec.spindle_speed.format(rpm=rpm))  # not merged into a tool call
        self.modal.rpm = rpm
        self.emit(self.spec.spindle_on.format(rpm=rpm, code=code))

    def write_coolant(self, block: Coolant) -> None:
        """Coolant on or off; modes without a standard code are written as flood."""
        mode = block.mode
        if mode in _COOLANT_FALLBACK:
            logger.warning(
                "%s has no standard code for coolant %r; writing flood coolant",
                self.spec.name,
                mode,
            )
            mode = "flood"
        action = _COOLANT_ACTIONS.get(mode)
        if action is None:
            raise DialectError(
                f"unknown coolant mode {block.mode!r}; expected flood, mist, through, air or off"
            )
        if mode == "off" and self.modal.coolant_stopped:  # off already: nothing to write
            return
        self.modal.coolant_stopped = mode == "off"
        self.emit(self.spec.m_code_for(action))

    def write_tcp(self, block: Tcp) -> None:
        """TCP on or off; the on lines may need the current tool number and its length offset
        register (:attr:`ToolChange.offset`, else the tool number)."""
        templates = self.spec.tcp_on if block.on else self.spec.tcp_off
        needs = any("{tool}" in t or "{offset}" in t for t in templates)
        if needs and self.modal.tool is None:
            raise DialectError(
                f"{self.spec.name}: switching TCP {'on' if block.on else 'off'} needs the tool "
                "length offset number; put a ToolChange before the Tcp block"
            )
        self.emit_templates(templates, tool=self.modal.tool, offset=self.modal.offset)
        self.modal.invalidate()


_MoveArrays = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]
"""Positions (k, m), rapid flags (k,), feeds (k,) and whether each block has a feed (k,)."""


def _arrays_of_table(table: MoveTable) -> _MoveArrays:
    """The arrays :meth:`ProgramWriter._write_move_chunk` takes, of a table (NaN: no feed)."""
    return table.position, table.rapid, table.feed, ~np.isnan(table.feed)


def _arrays_of_moves(moves: Sequence[Move], width: int) -> _MoveArrays | None:
    """The same of Move objects; None when they are not plain (a non-bool rapid flag, another
    number of positions than ``width``, values that are not numbers)."""
    k = len(moves)
    rapid_list = list(map(_RAPID, moves))
    positions = list(map(_POSITION, moves))
    feed_list = list(map(_FEED, moves))
    if set(map(type, rapid_list)) != {bool} or set(map(len, positions)) != {width}:
        return None
    try:
        values = itertools.chain.from_iterable(positions)
        pos = np.fromiter(values, dtype=float, count=k * width).reshape(k, width)
        feed = np.array(feed_list, dtype=float)  # None -> NaN
    except (TypeError, ValueError):
        return None
    has_feed = np.fromiter(map(operator.is_not, feed_list, itertools.repeat(None)), bool, k)
    return pos, np.array(rapid_list, dtype=bool), feed, has_feed


def _scaled_from_text(text: str, decimals: int) -> int | None:
    """A number written with ``decimals`` decimals as the integer of its digits (``"-1.5"``
    and 2 decimals: -150); None beyond what :func:`_bulk.scaled_integers` gives."""
    sign = -1 if text.startswith("-") else 1
    whole, _, fraction = text.lstrip("+-").partition(".")
    fraction = (fraction + "0" * decimals)[:decimals]
    value = sign * (int(whole or "0") * 10**decimals + int(fraction or "0"))
    return value if abs(value) < _bulk.MAX_SCALED else None


def _number(spec: DialectSpec, program: Program) -> int:
    """Program number: the name when it is one (``"1234"``, ``"O1234"``), else the default."""
    digits = program.name.upper().removeprefix("O")
    return int(digits) if digits.isdigit() else spec.default_program_number


def write_program(
    spec: DialectSpec,
    program: Program,
    *,
    block_numbers: bool | None = None,
    header: str | None = None,
    program_number: int | None = None,
    blank: np.ndarray | None = None,
) -> str:
    """Write ``program`` for the control described by ``spec``.

    Parameters
    ----------
    spec : DialectSpec
        The control.
    program : Program
        The program (mm and degrees; converted to inch when ``program.units == "inch"``).
    block_numbers : bool, optional
        Number the blocks; default the control's usual practice. Controls that require
        numbers reject False.
    header : str, optional
        Text written as comment lines after the program start (e.g. a date, the machine).
    program_number : int, optional
        Program number where the control has one (Fanuc ``O``-number).
    blank : ndarray, shape (2, 3), optional
        The stock's box, mm (:meth:`ProgramWriter.open`).

    Returns
    -------
    str
        The program text.

    Raises
    ------
    DialectError
        The program cannot be written for this control.
    """
    return program_writer(spec, program, block_numbers, program_number).write(header, blank)


def program_writer(
    spec: DialectSpec, program: Program, block_numbers: bool | None, program_number: int | None
) -> ProgramWriter:
    """A :class:`ProgramWriter` with the control's block numbering rules applied (see
    :func:`write_program` for the parameters)."""
    if block_numbers is None:
        block_numbers = spec.block_numbers_default or spec.block_numbers_mandatory
    if spec.block_numbers_mandatory and not block_numbers:
        raise DialectError(f"{spec.name} programs are always numbered")
    return ProgramWriter(spec, program, block_numbers, program_number)
