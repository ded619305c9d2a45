"""What differs between NC controls, as data.

A :class:`DialectSpec` is a frozen table: comment delimiters, program frame templates, the
G-, M- and keyword tables shared by the writer and the reader, number formats, block numbering,
and two optional hooks for controls whose syntax is not word-address G-code (Heidenhain
conversational). The writer (:mod:`urdfpost.dialects.writer`) and the reader
(:mod:`urdfpost.dialects.reader`) hold all the logic; one module per control only fills a spec.

Code tables map a code to an *action* name. The writer looks codes up by action (the first code
listed for an action is the one written); the reader maps every listed code to its action, so a
code the writer emits can always be read back.

Reader actions for G-codes and keywords:

``rapid``, ``linear``
    Modal motion (G0, G1).
``mm``, ``inch``
    Units of lengths and feeds (G21/G20, Siemens G710/G700).
``mm_geometry``, ``inch_geometry``
    Units of lengths only, feeds unchanged (Siemens G71/G70).
``absolute``, ``incremental``
    Distance mode (G90/G91).
``tcp_on``, ``tcp_off``
    Tool-centre-point control (Fanuc G43.4/G49, Siemens TRAORI/TRAFOOF, LinuxCNC M428/M429).
``length_on``
    Tool length compensation that is part of the control's TCP sequence (LinuxCNC G43 before
    M428); takes an H word.
``home``
    Reference/fixed point return (G28, Siemens G74/G75); the named axes become unknown.
``machine``
    One block in machine coordinates (G53, Siemens SUPA); read as a :class:`Home`.
``dwell``
    G4; its P/X/F/S/U words are the dwell time, not motion or feed.
``work_offset``
    Work offset selection (G54...); one offset per program, a change is an error.
``blend``
    Path blending with tolerance words (LinuxCNC ``G64 P0.01 Q0.01``): smoothing on with the
    tolerance P (a ``G64`` without P: off, the control's default path mode).
``smoothing``
    Fanuc ``G05.1``: AI contour control on (``Q1``; ``Q2``/``Q3`` smooth interpolation and
    nano smoothing, which need it) or off (``Q0``), with an optional ``R`` level.
``noop``
    Modes that do not change linear motion (cycle cancel, path control).
``inverse_time``, ``per_minute``
    Feed mode (G93 / G94): F words are inverse times (1/min) or feeds per minute; the modal
    feed is forgotten at a switch (the next feed move must program F).
``arc_cw``, ``arc_ccw``
    Circular motion (G2, G3), modal like G0/G1: takes I, J, K words (the centre, incremental
    from the start).
``plane_xy``, ``plane_zx``, ``plane_yz``
    The arc plane (G17, G18, G19).
``comp_left``, ``comp_right``, ``comp_off``
    Cutter radius compensation (G41, G42, G40); G41/G42 take a D word (the offset register).

Reader actions for M-codes: ``stop``, ``optional_stop``, ``end``, ``spindle_cw``,
``spindle_ccw``, ``spindle_off``, ``tool_change``, ``coolant_mist``, ``coolant_flood``,
``coolant_off``, ``tcp_on``, ``tcp_off``, ``shortest_path``, ``noop``, and ``machine`` (Heidenhain
M91/M92: the block is in machine coordinates).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, fields
from types import MappingProxyType
from typing import Any, Protocol

from urdfpost.errors import DialectError

#: M-codes every control here shares (ISO 6983 / common practice).
STANDARD_M_CODES: Mapping[int, str] = MappingProxyType(
    {
        0: "stop",
        1: "optional_stop",
        30: "end",
        2: "end",
        3: "spindle_cw",
        4: "spindle_ccw",
        5: "spindle_off",
        6: "tool_change",
        8: "coolant_flood",
        7: "coolant_mist",
        9: "coolant_off",
    }
)

#: How a control applies a feed per minute to the machine axes of a block without TCP (see
#: :attr:`DialectSpec.axis_feed_rule`).
AXIS_FEED_RULES = ("combined", "linear-first")

#: Axis addresses the dialects know, in output order; A, B, C are rotary (degrees).
AXIS_ORDER = ("X", "Y", "Z", "A", "B", "C")
ROTARY_ADDRESSES = frozenset("ABC")


@dataclass(frozen=True)
class NumberFormat:
    """How one kind of number is written.

    Attributes
    ----------
    decimals : int
        Digits after the decimal point.
    plus_sign : bool
        Write ``+`` for positive values and zero (Heidenhain).
    trim : bool
        Drop trailing zeros after the decimal point (``F500`` rather than ``F500.0``).
    point : bool
        Keep the decimal point when trimming leaves an integer (``F500.``; Fanuc reads a number
        without a point as least input increments).
    """

    decimals: int
    plus_sign: bool = False
    trim: bool = False
    point: bool = False

    def format(self, value: float) -> str:
        """The text of ``value`` (never ``-0``).

        Parameters
        ----------
        value : float
            A finite number.

        Returns
        -------
        str
            E.g. ``"12.345"``, ``"+0.000"``, ``"500."``.
        """
        if not math.isfinite(value):
            raise DialectError(f"cannot write the non-finite number {value!r}")
        text = f"{value:.{self.decimals}f}"
        if float(text) == 0.0:
            text = text.lstrip("-")
        if self.trim and "." in text:
            text = text.rstrip("0")
            if text.endswith(".") and not self.point:
                text = text[:-1]
        elif self.point and "." not in text:
            text += "."
        if self.plus_sign and not text.startswith("-"):
            text = "+" + text
        return text

    @property
    def resolution(self) -> float:
        """One unit of the last written decimal."""
        return 10.0**-self.decimals


@dataclass(frozen=True)
class MotionWords:
    """One motion block, formatted, handed to :attr:`DialectSpec.format_motion`.

    Attributes
    ----------
    rapid : bool
        Rapid traverse.
    code : str or None
        Motion code to write (``"G0"``) or None when the modal code is unchanged.
    axes : tuple of (str, str)
        Address and formatted value of each axis to write.
    feed : str or None
        Formatted feed to write, or None to keep the modal feed.
    extra : tuple of str
        Words written after the axes (Heidenhain's radius compensation ``RL``, ``RR``,
        ``R0``: :attr:`DialectSpec.cutter_comp_words`).
    """

    rapid: bool
    code: str | None
    axes: tuple[tuple[str, str], ...]
    feed: str | None
    extra: tuple[str, ...] = ()


@dataclass(frozen=True)
class MotionLayout:
    """The words of a motion block in order, for writing many blocks at once.

    A block is, joined by single blanks: ``lead`` (when set), the motion code (when written),
    the axis words, ``rapid_word`` on rapid blocks (when set), and ``F<feed>`` (when written).
    It must give what :attr:`DialectSpec.format_motion` gives for the same words.

    Attributes
    ----------
    lead : str or None
        First word of every motion block (Heidenhain ``L``).
    rapid_word : str or None
        Word that makes a block rapid (Heidenhain ``FMAX``); None when the motion code does.
    """

    lead: str | None = None
    rapid_word: str | None = None


@dataclass(frozen=True)
class ArcWords:
    """One arc block, formatted, handed to :attr:`DialectSpec.format_arc`.

    Attributes
    ----------
    plane : str
        "XY", "ZX" or "YZ" (:data:`urdfpost.program.ARC_PLANES`).
    plane_code : str or None
        The plane's code to write before the arc (``"G17"``) when the plane changes; None.
    clockwise : bool
        Clockwise seen from the positive end of the plane's normal (G2).
    axes : tuple of (str, str)
        Address and formatted value of each axis of the end point to write.
    centre : tuple of (str, str)
        Address and formatted value of the centre: ``I``/``J``/``K`` incremental from the
        start for the plane's two axes (G-code), or the plane's axis letters and absolute
        values (:attr:`DialectSpec.arc_centre_absolute`, Heidenhain ``CC``).
    feed : str or None
        Formatted feed to write, or None to keep the modal feed.
    turn : str
        The angle turned from the start as written to the end, degrees, signed
        (counter-clockwise positive), formatted as the rotary axes are (Heidenhain's helix
        ``CP IPA``).
    climb : tuple of (str, str) or None
        A helix: the normal axis' address and its increment from the start to the end,
        formatted (Heidenhain ``IZ``); None for a planar arc.
    """

    plane: str
    plane_code: str | None
    clockwise: bool
    axes: tuple[tuple[str, str], ...]
    centre: tuple[tuple[str, str], ...]
    feed: str | None
    turn: str = ""
    climb: tuple[str, str] | None = None


def format_gcode_arc(words: ArcWords) -> tuple[str, ...]:
    """Word-address arc block: ``G17 G2 X1.000 Y2.000 I0.500 J0.000 F500``.

    Parameters
    ----------
    words : ArcWords

    Returns
    -------
    tuple of str
        The block (one line), without block number.
    """
    parts = [words.plane_code] if words.plane_code else []
    parts.append("G2" if words.clockwise else "G3")
    parts += [f"{address}{value}" for address, value in words.axes]
    parts += [f"{address}{value}" for address, value in words.centre]
    if words.feed is not None:
        parts.append(f"F{words.feed}")
    return (" ".join(parts),)


def format_gcode_motion(words: MotionWords) -> str:
    """Word-address motion block: ``G1 X1.000 Y2.000 F500``.

    Parameters
    ----------
    words : MotionWords
        The formatted parts.

    Returns
    -------
    str
        The block text without block number.
    """
    parts = [words.code] if words.code else []
    parts += [f"{address}{value}" for address, value in words.axes]
    if words.feed is not None:
        parts.append(f"F{words.feed}")
    return " ".join(parts)


def _identity(text: str) -> str:
    return text


def _empty() -> Mapping[str, str]:
    return MappingProxyType({})


class LineParser(Protocol):
    """A control's own reading of one program line (Heidenhain's conversational lines).

    Called with the control's spec, the reader's
    :class:`~urdfpost.dialects.reader.ProgramBuilder` (typed ``Any`` here: the reader imports
    this module, not the other way round) and the line as written.
    """

    def __call__(self, spec: DialectSpec, builder: Any, raw: str, /) -> None: ...


@dataclass(frozen=True)
class DialectSpec:
    """Everything that differs between two controls.

    Attributes
    ----------
    name, extensions
        Control name and output file extensions (lower case, with dot).
    comment_open, comment_close
        Comment delimiters as written (``"; "`` and ``""``, or ``"("`` and ``")"``).
    comment_upper : bool
        Write comments in upper case (Fanuc).
    comment_replace : mapping
        Characters replaced in comment text so it cannot end the comment early.
    comment_filter : callable
        Further clean-up of comment text (LinuxCNC active comments).
    paren_comments, semicolon_comments : bool
        Which comment forms the reader accepts.
    percent_lines : bool
        ``%`` tape delimiter lines are accepted by the reader.
    program_open, program_close : tuple of str
        Frame lines (templates with ``{name}``, ``{number}``, ``{unit_code}``); numbered only when
        ``number_frame``.
    setup, finish : tuple of str
        Code lines after the header and before the close (numbered when numbering is on).
    name_comment : bool
        Write the program name as the first comment, and read the first comment as the name.
    format_name : callable
        Makes a program name valid for the frame templates.
    default_program_number : int
        Program number for ``{number}`` (Fanuc ``O1000``) when the name is not a number.
    unit_words : mapping or None
        ``{unit_code}`` for "mm" and "inch" when it is not a G-code (Heidenhain ``MM``).
    g_codes, m_codes, keywords : mapping
        Code tables (see the module docstring). G keys are canonical numbers (``"0"``,
        ``"43.4"``).
    assignments : bool
        The reader accepts Siemens ``NAME=value`` words (``X=AC(1)``, ``FP=1``, ``Z1=0``).
    extra_words : frozenset of str
        Further addresses the reader accepts without effect on motion (Siemens ``D``).
    program_number_line : bool
        The reader accepts an ``O1000 (NAME)`` program number line (Fanuc).
    tool_change : tuple of str
        Tool change lines (``{tool}``).
    tool_numbers : (int, int)
        The lowest and highest tool number the tool change can call (the control's T word or
        tool table); a tool number outside is refused.
    length_offsets : (int, int) or None
        The tool length offset registers the TCP lines can select (``{offset}``, the ``H``
        word: the CL's ``LOADTL ADJUST``, else the tool number); None: the control has no such
        register, it takes the length of the tool it calls from its tool table (an ADJUST
        other than the tool number cannot be honoured and is refused).
    tool_change_speed : tuple of str or None
        Tool change with spindle speed merged in (Heidenhain ``TOOL CALL 1 Z S12000``).
    spindle_speed : str or None
        Separate speed-only line when speed cannot go on the spindle line (Heidenhain).
    spindle_on : str
        Spindle start (``{rpm}``, ``{code}``).
    tcp_on, tcp_off : tuple of str
        TCP switching lines (``{tool}`` is the last tool change number, ``{offset}`` its
        length offset register).
    home : tuple of str
        Lines written for a :class:`Home` block.
    home_comment : str or None
        Comment written before the home lines; the reader drops it again when a home return
        follows it directly.
    shortest_path : str or None
        Line written once at the start when the program has continuous rotary axes.
    machine_move : str
        A rapid in machine coordinates (:class:`~urdfpost.program.MachineMove`); ``{words}``
        is its axis words. The reader reads such a block as a home return (the axes named
        become unknown in the program's coordinates).
    work_offset : tuple of str
        Lines selecting a work offset (:class:`~urdfpost.program.WorkOffset`); ``{number}``
        is its number (1 for the first), ``{code}`` 53 + number (G54 for 1); lines after
        the first are continuation lines (never numbered).
    work_offsets : int
        How many work offsets the lines can select (G54 to G59: 6).
    work_offset_label : str
        A work offset as the header names it (``{number}``, ``{code}`` as above): "G54".
    blank_form : tuple of str
        Lines describing the blank (the stock's box, for the control's graphics) right after
        the program's opening: ``{x0}``..``{z1}`` its corners as axis values (Heidenhain
        ``BLK FORM``); empty: the control has none.
    linear_mm, linear_inch, rotary, feed_mm, feed_inch, rpm : NumberFormat
        Number formats.
    feed_inch_unit : float
        Millimetres per unit of an inch-program feed per minute (25.4; Heidenhain 2.54).
    require_point : bool
        Axis values must carry a decimal point (written always; reader rejects ``X10``).
    block_format : str
        Block number prefix (``"N{n}"``; Heidenhain ``"{n}"``).
    block_start, block_step, block_max : int
        First number, increment, and the largest number before wrapping to ``block_step``
        (0: never wrap).
    block_numbers_default, block_numbers_mandatory : bool
        Numbering when the caller does not say; whether every line must be numbered.
    number_frame, number_comments : bool
        Whether frame lines and comment lines get numbers.
    modal_axes : bool
        Write only the axes that changed since the last motion block.
    rapid_modal : bool
        The rapid code is modal (G0). False for Heidenhain ``FMAX`` (one block only).
    format_motion : callable
        Motion block formatter.
    motion_layout : MotionLayout or None
        The same as data, which lets the writer format long runs of motion blocks at once;
        None writes every block through ``format_motion``.
    parse_line : callable or None
        Reader hook for non-G-code syntax; None uses the shared word-address parser.
    cycle_lines : callable or None
        The lines of a :class:`~urdfpost.program.Cycle` block (``(cycle, axes, CycleFormat)
        -> lines``, :mod:`urdfpost.dialects._cycles`; a line starting with a blank is a
        continuation line, never numbered); None: the control's cycles are not written, a
        post writes the holes as their motion.
    dwell : tuple of str
        Lines of a :class:`~urdfpost.program.Dwell` (``{seconds}``); empty: none.
    dwell_p_ms : bool
        The P word of G4, G82 and G89 is in milliseconds (Fanuc), not seconds (LinuxCNC).
    cycle_dwell : frozenset of str
        The cycle kinds (:data:`urdfpost.program.CYCLE_KINDS`) whose cycle takes a dwell at
        the bottom on this control; a cycle of another kind with a dwell is written as its
        motion.
    smoothing_on : tuple of str
        Lines that switch the control's path smoothing on (:class:`~urdfpost.program.Smoothing`):
        ``{tol}`` the path tolerance in program units (linear format), ``{angle}`` the rotary
        axes' tolerance in degrees (rotary format); a control whose lines have no ``{tol}``
        takes its tolerance from its own parameters. Empty: the control has none.
    smoothing_off : tuple of str
        Lines that switch it off again (the control's default path mode).
    rollover_value : str
        How the value of a rollover axis is written after its address (``{value}``, in
        [0, 360)): ``"{value}"``, Siemens ``"=DC({value})"`` (shortest way).
    rollover_direction : str
        Which way the control turns a rollover axis to a value written so
        (:func:`~urdfpost.program.rollover_target`): "shortest"; "sign" (LinuxCNC
        ``WRAPPED_ROTARY``: the sign of the value is the direction, the value's magnitude the
        position); "direct" (the position in [0, 360) is reached without passing 0, Siemens
        ``G90`` with the default MD30455). A control with a :attr:`shortest_path` code takes
        the shortest way only after that code (Heidenhain ``M126``), "direct" before.
    call_keywords : mapping
        Keywords the reader takes with an argument list, to an action (Siemens
        ``CYCLE832(0.01,_ORI_FINISH,0.5)``: "smoothing").
    inverse_time : str or None
        The line that switches to inverse-time feed (``G93``); None: the control has none.
        In inverse time every feed block carries its F (one over the block's time in
        minutes), whatever the units.
    per_minute : str
        The line that switches back to feed per minute (``G94``), written before a tool
        change, a home return and the program end when inverse time is on.
    inverse_time_feed : NumberFormat
        Format of an inverse-time F word.
    inverse_time_max : float or None
        Largest inverse-time F the control takes, 1/min (None: no documented limit): a block
        is never programmed shorter than ``1 / inverse_time_max`` minutes.
    axis_feed_rule : str
        How the control applies a feed per minute to a block without TCP, whose axes are
        machine axes (:data:`AXIS_FEED_RULES`): ``"combined"``, to the length
        ``sqrt(sum dlinear^2 + sum drotary_deg^2)`` of the block in axis space, degrees
        counted as program length units (Fanuc); ``"linear-first"``, to the X/Y/Z length
        when a linear axis moves, else to the rotary length in degrees (RS274NGC, LinuxCNC;
        Siemens with its path axes X, Y, Z). See ``docs/job.md``.
    arc_planes : frozenset of str
        The planes ("XY", "ZX", "YZ") the control takes :class:`~urdfpost.program.Arc` blocks
        in (empty: none; the post writes arcs as lines).
    arc_tcp : bool
        Arcs with TCP on (in the workpiece frame, the rotary axes standing still).
    arc_helix : bool
        Arcs whose normal axis moves (helices).
    arc_centre_absolute : bool
        The centre is written absolute in the plane's axis letters (Heidenhain ``CC X Y``);
        else incremental from the start as ``I J K``.
    arc_centre_suffix : str
        Written between a centre address and its value (Siemens ``I=0.5``: ``"="``).
    format_arc : callable or None
        Arc block formatter (:class:`ArcWords` to the lines of the block).
    cutter_comp : mapping
        Lines of :class:`~urdfpost.program.CutterComp` by side ("left", "right", "off"):
        ``{register}`` its offset register (the tool number when it gives none), ``{plane}``
        the plane's code (``G17``); empty: the control writes them as words of the next
        straight line (:attr:`cutter_comp_words`).
    plane_convention : str or None
        How the control's tilted working plane gives its frame by three angles
        (:data:`urdfpost.program.PLANE_CONVENTIONS`); None: the control has no tilted plane
        (a post writes 3+2 operations as five-axis moves).
    plane_on : tuple of str
        Lines that switch a :class:`~urdfpost.program.TiltedPlane` on, with ``{a}``, ``{b}``,
        ``{c}`` its angles (rotary format), the rotary axes staying where they stand.
    plane_off : tuple of str
        Lines that switch it off (the rotary axes stay).
    plane_length_on : tuple of str
        In a TCP program, lines after :attr:`plane_on` that make the control add the tool's
        length along the plane's Z (``{offset}`` the length register; Fanuc ``G43 H1``): TCP
        is off in the plane. Empty: the control adds it anyway (the length of the tool
        called).
    plane_length_off : tuple of str
        Lines before :attr:`plane_off` that stop it again (Fanuc ``G49``).
    cutter_comp_words : mapping
        Words of the next straight line by side (Heidenhain ``RL``, ``RR``, ``R0``), in the
        working plane XY only.
    """

    name: str
    extensions: tuple[str, ...]
    comment_open: str
    comment_close: str
    comment_upper: bool = False
    comment_replace: Mapping[str, str] = field(default_factory=_empty)
    comment_filter: Callable[[str], str] = _identity
    paren_comments: bool = False
    semicolon_comments: bool = False
    percent_lines: bool = False
    program_open: tuple[str, ...] = ()
    program_close: tuple[str, ...] = ()
    setup: tuple[str, ...] = ()
    finish: tuple[str, ...] = ()
    name_comment: bool = False
    format_name: Callable[[str], str] = _identity
    default_program_number: int = 1000
    unit_words: Mapping[str, str] | None = None
    g_codes: Mapping[str, str] = field(default_factory=_empty)
    m_codes: Mapping[int, str] = field(default_factory=lambda: STANDARD_M_CODES)
    keywords: Mapping[str, str] = field(default_factory=_empty)
    assignments: bool = False
    extra_words: frozenset[str] = frozenset()
    program_number_line: bool = False
    tool_change: tuple[str, ...] = ("T{tool} M6",)
    tool_numbers: tuple[int, int] = (1, 9999)
    length_offsets: tuple[int, int] | None = None
    tool_change_speed: tuple[str, ...] | None = None
    spindle_speed: str | None = None
    spindle_on: str = "S{rpm} {code}"
    tcp_on: tuple[str, ...] = ()
    tcp_off: tuple[str, ...] = ()
    home: tuple[str, ...] = ()
    home_comment: str | None = None
    shortest_path: str | None = None
    machine_move: str = "G53 G0 {words}"
    work_offset: tuple[str, ...] = ("G{code}",)
    work_offsets: int = 6
    work_offset_label: str = "G{code}"
    blank_form: tuple[str, ...] = ()
    linear_mm: NumberFormat = NumberFormat(3)
    linear_inch: NumberFormat = NumberFormat(4)
    rotary: NumberFormat = NumberFormat(4)
    feed_mm: NumberFormat = NumberFormat(1, trim=True)
    feed_inch: NumberFormat = NumberFormat(2, trim=True)
    rpm: NumberFormat = NumberFormat(0)
    feed_inch_unit: float = 25.4
    require_point: bool = False
    block_format: str = "N{n}"
    block_start: int = 10
    block_step: int = 10
    block_max: int = 0
    block_numbers_default: bool = False
    block_numbers_mandatory: bool = False
    number_frame: bool = False
    number_comments: bool = False
    modal_axes: bool = True
    rapid_modal: bool = True
    format_motion: Callable[[MotionWords], str] = format_gcode_motion
    motion_layout: MotionLayout | None = None
    parse_line: LineParser | None = None
    cycle_lines: Callable[..., list[str]] | None = None
    dwell: tuple[str, ...] = ()
    dwell_p_ms: bool = False
    cycle_dwell: frozenset[str] = frozenset()

    def runs_cycle(self, kind: str, dwell: float) -> bool:
        """Whether the control's own cycle is written for a cycle of ``kind`` with a dwell of
        ``dwell`` seconds (:attr:`cycle_lines`, :attr:`cycle_dwell`)."""
        return self.cycle_lines is not None and (dwell <= 0.0 or kind in self.cycle_dwell)

    smoothing_on: tuple[str, ...] = ()
    smoothing_off: tuple[str, ...] = ()
    rollover_value: str = "{value}"
    rollover_direction: str = "shortest"
    call_keywords: Mapping[str, str] = field(default_factory=_empty)
    inverse_time: str | None = None
    per_minute: str = "G94"
    inverse_time_feed: NumberFormat = NumberFormat(4, trim=True, point=True)
    inverse_time_max: float | None = None
    axis_feed_rule: str = "combined"
    arc_planes: frozenset[str] = frozenset()
    arc_tcp: bool = True
    arc_helix: bool = False
    arc_centre_absolute: bool = False
    arc_centre_suffix: str = ""
    format_arc: Callable[[ArcWords], tuple[str, ...]] = format_gcode_arc
    cutter_comp: Mapping[str, str] = field(default_factory=_empty)
    cutter_comp_words: Mapping[str, str] = field(default_factory=_empty)
    plane_convention: str | None = None
    plane_on: tuple[str, ...] = ()
    plane_off: tuple[str, ...] = ()
    plane_length_on: tuple[str, ...] = ()
    plane_length_off: tuple[str, ...] = ()

    def __reduce__(self) -> tuple[Callable[..., DialectSpec], tuple[Any, ...]]:
        """Pickle the read-only tables (:class:`types.MappingProxyType`, which does not
        pickle) as plain mappings, read-only again when unpickled (a streamed post's
        verification worker writes the program: a spawned one is sent the control)."""
        values = {f.name: getattr(self, f.name) for f in fields(self)}
        tables = tuple(k for k, v in values.items() if isinstance(v, MappingProxyType))
        for k in tables:
            values[k] = dict(values[k])
        return _unpickled_spec, (values, tables)

    def g_code_for(self, action: str) -> str:
        """The G-code (``"G21"``) the writer uses for ``action``."""
        for code, act in self.g_codes.items():
            if act == action:
                return f"G{code}"
        raise DialectError(f"{self.name}: no G-code for {action!r}")

    def m_code_for(self, action: str) -> str:
        """The M-code (``"M8"``) the writer uses for ``action``."""
        for code, act in self.m_codes.items():
            if act == action:
                return f"M{code}"
        raise DialectError(f"{self.name}: no M-code for {action!r}")

    def comp_fault(self, register: int | None, tool: int | None, plane: str = "XY") -> str | None:
        """What is wrong with cutter radius compensation in ``plane`` ("XY", "ZX" or "YZ")
        from offset register ``register`` (the CL's ``CUTCOM/LEFT,n``; None: none given)
        with tool ``tool`` called (None: not known here), or None.

        A control that takes the radius of the tool called (Heidenhain's tool table, Siemens'
        tool edge: no register word) is given no register, or the tool's own number (the
        radius is then the same); one with a D word takes any. A control that writes the
        compensation on the next straight line (Heidenhain ``RL``) has it in the working plane
        only.

        Examples
        --------
        >>> spec = DialectSpec("x", (".x",), "(", ")", cutter_comp_words={"left": "RL"})
        >>> spec.comp_fault(3, 3) is None, spec.comp_fault(None, 3) is None
        (True, True)
        >>> print(spec.comp_fault(2, 3))  # doctest: +ELLIPSIS
        cutter radius compensation from offset register 2 with tool 3 called: x takes the ...
        >>> print(spec.comp_fault(None, 3, "ZX"))
        cutter radius compensation in the ZX plane: x has it in the working plane; expected XY
        """
        template = self.cutter_comp.get("left", "")
        if not template and plane != "XY":
            return (
                f"cutter radius compensation in the {plane} plane: {self.name} has it in the "
                "working plane; expected XY"
            )
        if register is None or "{register}" in template or register == tool:
            return None
        called = "no tool called" if tool is None else f"tool {tool} called"
        return (
            f"cutter radius compensation from offset register {register} with {called}: "
            f"{self.name} takes the radius of the tool called and has no register word; expected "
            "no register, or the tool's own number"
        )

    def tool_fault(self, number: int, offset: int | None = None, *, tcp: bool = True) -> str | None:
        """What is wrong with calling tool ``number`` with length offset register ``offset``
        on this control, or None.

        Parameters
        ----------
        number : int
            The tool number.
        offset : int, optional
            The length offset register asked for (the CL's ``LOADTL ADJUST``); None: the tool
            number.
        tcp : bool
            A TCP program: its TCP lines select the register. Without TCP the positions hold
            the tool length and no register is selected: only the tool number is checked.

        Returns
        -------
        str or None
            The fault, for a message (:attr:`tool_numbers`, :attr:`length_offsets`).

        Examples
        --------
        >>> spec = DialectSpec("x", (".x",), "(", ")", tool_numbers=(1, 99))
        >>> spec.tool_fault(100)
        'tool number 100 is outside the tool numbers of x (1 to 99)'
        >>> spec.tool_fault(3, 7) is None, spec.tool_fault(3, 7, tcp=False) is None
        (False, True)
        """
        low, high = self.tool_numbers
        if not low <= number <= high:
            return (
                f"tool number {number} is outside the tool numbers of {self.name} ({low} to {high})"
            )
        if not tcp:
            return None
        registers = self.length_offsets
        if registers is None:
            if offset is None or offset == number:
                return None
            return (
                f"length offset register {offset} (ADJUST) for tool {number}: {self.name} has "
                f"no length offset register, it takes the length of the tool it calls from its "
                f"tool table; expected ADJUST,{number} or none"
            )
        register = number if offset is None else offset
        low, high = registers
        if not low <= register <= high:
            given = "ADJUST" if offset is not None else "the tool number: no ADJUST given"
            return (
                f"length offset register H{register} ({given}) is outside the registers of "
                f"{self.name} (H{low} to H{high})"
            )
        return None

    def unit_code(self, units: str) -> str:
        """The units word for the program frame or setup (``G21``, ``G710``, ``MM``)."""
        if units not in ("mm", "inch"):
            raise DialectError(f"unknown program units {units!r}; expected 'mm' or 'inch'")
        if self.unit_words is not None:
            return self.unit_words[units]
        return self.g_code_for(units)

    def comment_text(self, text: str) -> str:
        """``text`` as it is written between the comment delimiters (and read back).

        Parameters
        ----------
        text : str
            Any text.

        Returns
        -------
        str
            One line, stripped, with delimiter characters replaced.
        """
        text = " ".join(text.split())
        for old, new in self.comment_replace.items():
            text = text.replace(old, new)
        if self.comment_upper:
            text = text.upper()
        return self.comment_filter(text).strip()

    def format_comment(self, text: str) -> str:
        """A whole comment line."""
        return f"{self.comment_open}{self.comment_text(text)}{self.comment_close}"


def _unpickled_spec(values: dict[str, Any], tables: tuple[str, ...]) -> DialectSpec:
    """A :class:`DialectSpec` from its pickled field ``values``, the ``tables`` read-only
    again (:meth:`DialectSpec.__reduce__`)."""
    kw: dict[str, Any] = {k: MappingProxyType(v) if k in tables else v for k, v in values.items()}
    return DialectSpec(**kw)
