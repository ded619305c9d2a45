"""Heidenhain TNC 640 conversational (Klartext, ``.h``).

Written (every line numbered from 0)::

    0 BEGIN PGM NAME MM
    1 M126                                   (shortest path; only with continuous rotary axes)
    2 TOOL CALL 1 Z S12000                   (speed of the following spindle start merged in)
    3 M3
    4 M8
    5 FUNCTION TCPM F TCP AXIS POS PATHCTRL AXIS
    6 L X+10.000 Y-5.000 Z+50.000 B+0.0000 C+90.0000 FMAX
    7 L Z+2.000 F500
    8 FUNCTION RESET TCPM
    9 ; home
    10 L Z+0 R0 FMAX M91
    11 L X+0 Y+0 R0 FMAX M91
    12 M30
    13 END PGM NAME MM

``FMAX`` acts on its own block only; the programmed feed stays modal across it. In INCH
programs coordinates are inch and feeds are in 0.1 inch/min (TNC convention). A spindle speed
that cannot go into a tool call is written as ``TOOL CALL Z S<rpm>`` (speed-only tool call).

Arcs are ``CC X.. Y..`` (the centre, absolute) then ``C X.. Y.. DR+`` (counter-clockwise seen
from +Z) or ``DR-``, in the working plane XY only; a helix is ``CP IPA.. IZ.. DR..`` after the
``CC`` (the angle turned and the climb, incremental); radius compensation is ``RL``, ``RR`` or
``R0`` on the next straight ``L`` block.

The reader accepts the lines above plus ``* - structure comments``, inline ``; comments``,
``STOP``, ``TOOL DEF``, ``BLK FORM``, ``CYCL DEF 32`` (tolerance: read as a
:class:`~urdfpost.program.Smoothing` block, which the writer writes as ``CYCL DEF 32.0
TOLERANCE``, ``32.1 T..``, ``32.2 HSC-MODE:0 TA..``), ``M128``/``M129`` (older TCPM),
``IX+..`` incremental coordinates and ``R0``. ``L ... M91``/``M92`` blocks are machine
coordinates and read as a home return.
"""

from __future__ import annotations

import math
import re
from types import MappingProxyType

from urdfpost.dialects._cycles import (
    heidenhain_definition,
    heidenhain_lines,
    heidenhain_parameter,
    heidenhain_start,
)
from urdfpost.dialects.reader import BEFORE_MOTION_M, ProgramBuilder, apply_m_action
from urdfpost.dialects.spec import (
    STANDARD_M_CODES,
    ArcWords,
    DialectSpec,
    MotionLayout,
    MotionWords,
    NumberFormat,
)

_LINE = re.compile(r"\s*(\d+)(?:\s+(.*))?\Z")
_BEGIN = re.compile(r"BEGIN PGM (\S+) (MM|INCH)\Z")
_END = re.compile(r"END PGM (\S+) (MM|INCH)\Z")
_AXIS = re.compile(r"(I?)([XYZABC])(.*)\Z")
_TOOL_CALL_WORD = re.compile(r"(DR2|DL|DR|S|F)(.*)\Z")  # DR, DR2: radius only, no effect
_PRESET = re.compile(r"\s*Q339\s*=\s*\+?(\d+)\s*(?:;.*)?\Z")
_MOTION_WORDS = "X.. Y.. Z.. A.. B.. C.. (IX.. incremental), R0, F.., FMAX, M.."


def format_name(name: str) -> str:
    """Program name for BEGIN/END PGM: upper case, letters, digits, ``_`` and ``-`` only."""
    return re.sub(r"[^A-Z0-9_-]", "_", name.strip().upper()) or "PROGRAM"


def format_motion(words: MotionWords) -> str:
    """``L X+1.000 Y-2.000 FMAX`` or ``L Z+2.000 RL F500``."""
    parts = ["L", *(f"{address}{value}" for address, value in words.axes), *words.extra]
    if words.rapid:
        parts.append("FMAX")
    elif words.feed is not None:
        parts.append(f"F{words.feed}")
    return " ".join(parts)


def format_arc(words: ArcWords) -> tuple[str, ...]:
    """``CC X+1.000 Y+2.000`` (the centre, absolute) and ``C X+3.000 Y+2.000 DR+ F500``, or
    for a helix ``CP IPA+90.0000 IZ-2.000 DR+ F500`` (the angle turned and the climb, both
    incremental from the start; IPA and DR of one sign).

    DR+ is the mathematically positive sense, counter-clockwise seen from the positive tool
    axis (Z); the post writes arcs in the working plane only (``arc_planes``).
    """
    centre = " ".join(f"{address}{value}" for address, value in words.centre)
    if words.climb is not None:  # a helix: the incremental polar angle and climb about CC
        address, rise = words.climb
        parts = ["CP", f"IPA{words.turn}", f"I{address}{rise}"]
    else:
        parts = ["C", *(f"{address}{value}" for address, value in words.axes)]
    parts.append("DR-" if words.clockwise else "DR+")
    if words.feed is not None:
        parts.append(f"F{words.feed}")
    return (f"CC {centre}", " ".join(parts))


def parse_line(spec: DialectSpec, builder: ProgramBuilder, raw: str) -> None:
    """Read one numbered conversational line into ``builder``.

    Parameters
    ----------
    spec : DialectSpec
        The Heidenhain spec.
    builder : ProgramBuilder
        Receives the events.
    raw : str
        The line.

    Raises
    ------
    ProgramParseError
        Missing block number, unknown block or word, malformed number.
    """
    if builder.smoothing_pending is not None and "CYCL DEF 32.2" not in raw:
        builder.flush_smoothing()  # (no rotary tolerance after the path tolerance)
    match = _LINE.match(raw)
    cycle, builder.cycle = builder.cycle, None
    if cycle in (200, 201, 203, 207):
        _cycle_parameter(builder, cycle, raw)
        return
    if match is None and cycle == 247 and (preset := _PRESET.match(raw)):
        builder.select_work_offset(f"preset {int(preset.group(1))}")
        return
    if cycle == 247:
        raise builder.error("expected Q339=+<preset number> after CYCL DEF 247 DATUM SETTING ~")
    if match is None:
        raise builder.error(f"expected a block number at the start of {raw.strip()!r}")
    content = (match.group(2) or "").strip()
    if content.startswith(";"):
        builder.comment(content[1:].strip())
        return
    if content.startswith("*"):
        builder.comment(content[1:].strip().removeprefix("-").strip())
        return
    code, semicolon, comment = content.partition(";")
    code = code.strip()
    if code:
        _parse_code(spec, builder, code)
    if semicolon:
        builder.comment(comment.strip())


_PLANE_WORDS = ("SPA", "SPB", "SPC")


def _plane(builder: ProgramBuilder, words: list[str]) -> None:
    """``PLANE SPATIAL SPA+0 SPB+30 SPC+0 STAY``: a tilted working plane by spatial angles, the
    rotary axes standing where they are (``TURN`` would move them: not read)."""
    expected = "PLANE SPATIAL SPA.. SPB.. SPC.. STAY (or PLANE RESET STAY)"
    if len(words) != 5 or words[0] != "SPATIAL" or words[4] != "STAY":
        raise builder.error(f"PLANE {' '.join(words)}; expected {expected}")
    angles = []
    for word, name in zip(words[1:4], _PLANE_WORDS, strict=True):
        if not word.startswith(name):
            raise builder.error(f"PLANE SPATIAL: {word}; expected {name}.. ({expected})")
        angles.append(builder.number(name, word.removeprefix(name)))
    builder.tilted_plane((angles[0], angles[1], angles[2]))


def _parse_code(spec: DialectSpec, builder: ProgramBuilder, code: str) -> None:
    if begin := _BEGIN.match(code):
        builder.code()
        builder.name = begin.group(1)
        builder.set_units("mm" if begin.group(2) == "MM" else "inch")
        return
    if _END.match(code):
        builder.end()
        builder.close()
        return
    builder.code()
    words = code.split()
    head = " ".join(words[:2])
    if head == "TOOL CALL":
        _tool_call(builder, words[2:])
    elif code.startswith("CYCL DEF 32."):
        _tolerance_cycle(builder, code)
    elif head in ("TOOL DEF", "BLK FORM"):
        return  # tool preselection, graphics blank: no motion
    elif code == "CYCL DEF 247 DATUM SETTING ~":
        builder.cycle = 247  # the preset number follows on the next line
    elif (number := heidenhain_start(code)) is not None:
        builder.cycle = number  # its Q parameters follow, one a line
        builder.drill_q = {}
    elif code == "CYCL DEF 9.0 DWELL TIME":
        return  # the time follows in 9.1
    elif code.startswith("CYCL DEF 9.1 DWELL"):
        builder.dwell(builder.number("DWELL", code.removeprefix("CYCL DEF 9.1 DWELL").strip()))
    elif code == "CYCL CALL":
        _cycle_call(builder, {})
    elif code == "PLANE RESET STAY":
        builder.tilted_plane(None)  # the rotary axes stay
    elif words[0] == "PLANE":
        _plane(builder, words[1:])
    elif code == "FUNCTION RESET TCPM":
        builder.set_tcp(False)
    elif code.startswith("FUNCTION TCPM"):
        if "AXIS SPAT" in code:
            raise builder.error("FUNCTION TCPM ... AXIS SPAT (spatial angles); expected AXIS POS")
        builder.set_tcp(True)
    elif words[0] == "L":
        _line(spec, builder, words[1:])
    elif words[0] == "CC":
        _circle_centre(builder, words[1:])
    elif words[0] == "C":
        _circle(spec, builder, words[1:])
    elif words[0] == "CP":
        _polar_circle(spec, builder, words[1:])
    elif words[0] == "STOP":
        builder.stop(False)
        _m_only(spec, builder, words[1:])
    elif words[0].startswith("M"):
        _m_only(spec, builder, words)
    else:
        raise builder.error(
            f"unknown block {code!r}; expected L, CC, C, TOOL CALL, FUNCTION TCPM, FUNCTION "
            "RESET TCPM, M.., STOP or a ; comment"
        )


_CYCLE_32 = re.compile(r"CYCL DEF 32\.([012])(?:\s+(.*))?\Z")
_CYCLE_32_HEAD = ("TOLERANCE", "TOLERANZ")
_CYCLE_32_T = re.compile(r"T\s*(\S+)\Z")
_CYCLE_32_MODE = re.compile(r"(?:HSC-MODE:\s*[01]\s*)?(?:TA\s*(\S+))?\Z")


def _tolerance_cycle(builder: ProgramBuilder, code: str) -> None:
    """Cycle 32 TOLERANCE: ``32.0 TOLERANCE``, then ``32.1 T<tolerance>`` (smoothing on; no T:
    off, the control's default) and ``32.2 HSC-MODE:<0|1> TA<rotary tolerance>``."""
    match = _CYCLE_32.match(code)
    part, rest = (match.group(1), (match.group(2) or "").strip()) if match else ("", "")
    if match is None or (part == "0" and rest not in _CYCLE_32_HEAD):
        raise builder.error(
            f"unreadable {code!r}; expected CYCL DEF 32.0 TOLERANCE, 32.1 T.. or 32.2 TA.."
        )
    if part == "1":
        if not rest:
            builder.smoothing(False)
            return
        t = _CYCLE_32_T.match(rest)
        if t is None:
            raise builder.error(f"unreadable {code!r}; expected CYCL DEF 32.1 T<tolerance>")
        builder.smoothing(True, builder.number("T", t.group(1)), pending=True)
    elif part == "2":
        mode = _CYCLE_32_MODE.match(rest)
        if mode is None:
            raise builder.error(
                f"unreadable {code!r}; expected CYCL DEF 32.2 HSC-MODE:0 TA<rotary tolerance>"
            )
        if mode.group(1) is not None:
            builder.smoothing_angle(builder.number("TA", mode.group(1)))


def _tool_call(builder: ProgramBuilder, words: list[str]) -> None:
    """``TOOL CALL [n] [Z] [S..] [F..] [DL..] [DR..] [DR2..]``."""
    number = speed = None
    if words and re.fullmatch(r"\d+", words[0]):
        number = int(words.pop(0))
    elif words and words[0].startswith('"'):
        raise builder.error("tool called by name; expected TOOL CALL <number>")
    for word in words:
        if word in ("X", "Y"):
            raise builder.error(f"tool axis {word} is not supported; expected Z")
        if word == "Z":
            continue
        parts = _TOOL_CALL_WORD.match(word)
        if parts is None:
            raise builder.error(f"unknown word {word!r} in TOOL CALL; expected n Z S.. F..")
        address = parts.group(1)
        value = builder.number(address, parts.group(2))
        if address == "S":
            speed = value
        elif address == "F":
            builder.set_feed(value)
        elif address == "DL" and value != 0.0:
            raise builder.error(f"tool length oversize {word} is not supported; expected DL+0")
    if number is not None:
        builder.tool_change(number)
    if speed is not None:
        builder.set_speed(speed)


def _m_codes(spec: DialectSpec, builder: ProgramBuilder, words: list[str]) -> list[str]:
    actions = []
    for word in words:
        if not re.fullmatch(r"M\d+", word):
            raise builder.error(f"unexpected {word!r}; expected M-codes only")
        code = int(word[1:])
        if code not in spec.m_codes:
            known = " ".join(f"M{c}" for c in spec.m_codes)
            raise builder.error(f"unknown M-code {word}; this reader understands {known}")
        actions.append(spec.m_codes[code])
    return actions


def _m_only(spec: DialectSpec, builder: ProgramBuilder, words: list[str]) -> None:
    for action in _m_codes(spec, builder, words):
        if action == "machine":
            raise builder.error("M91/M92 without coordinates; expected L ... M91")
        apply_m_action(builder, action)


def _line(spec: DialectSpec, builder: ProgramBuilder, words: list[str]) -> None:
    """``L`` block: coordinates, R0, F/FMAX, M-codes."""
    values: dict[str, tuple[float, bool]] = {}
    rapid = False
    m_words = []
    for word in words:
        axis = _AXIS.match(word)
        if axis:
            incremental, address, text = axis.groups()
            if address in values:
                raise builder.error(f"two {address} coordinates in one block")
            values[address] = (builder.number(address, text), bool(incremental))
        elif word == "FMAX":
            rapid = True
        elif word == "FAUTO":
            continue
        elif word.startswith("F"):
            builder.set_feed(builder.number("F", word[1:]))
        elif word in ("R0", "RL", "RR"):
            builder.cutter_comp({"R0": "off", "RL": "left", "RR": "right"}[word], None, "XY")
        elif word in ("R+", "R-"):
            raise builder.error(f"paraxial radius compensation {word} is not supported")
        elif word.startswith("M"):
            m_words.append(word)
        else:
            raise builder.error(f"unknown word {word!r} in L block; expected {_MOTION_WORDS}")
    actions = _m_codes(spec, builder, m_words)
    for action in actions:
        if action in BEFORE_MOTION_M:
            apply_m_action(builder, action)
    if "cycle_call" in actions:
        if not rapid:
            raise builder.error("M99 in a block without FMAX; expected L X.. Y.. FMAX M99")
        _cycle_call(builder, values)
        actions = [a for a in actions if a != "cycle_call"]
    elif "machine" in actions:
        builder.home(list(values))
    elif values:
        builder.cycle_off()  # a move without M99 ends the block of holes, not the definition
        builder.move(values, rapid)
    for action in actions:
        if action not in BEFORE_MOTION_M and action != "machine":
            apply_m_action(builder, action)


def _cycle_parameter(builder: ProgramBuilder, number: int, raw: str) -> None:
    """One ``Q...=...`` line of a ``CYCL DEF``; the last (no ``~``) defines the cycle."""
    parameter = heidenhain_parameter(raw)
    if parameter is None:
        raise builder.error(f"expected Q parameter lines (Q200=+2 ;TEXT ~) after CYCL DEF {number}")
    key, value, more = parameter
    builder.drill_q[key] = value
    if more:
        builder.cycle = number
        return
    builder.drill_defined = heidenhain_definition(
        number,
        builder.drill_q,
        builder.linear_scale,
        builder.feed_scale,
        builder.rpm,
        builder.error,
    )


def _cycle_call(builder: ProgramBuilder, values: dict[str, tuple[float, bool]]) -> None:
    """A hole of the cycle defined last (``L X.. Y.. FMAX M99``, ``CYCL CALL``)."""
    definition = builder.drill_defined
    if definition is None:
        raise builder.error("M99 / CYCL CALL with no cycle defined; expected CYCL DEF 200.. first")
    if builder.drill is not definition:
        builder.cycle_start(definition)
    builder.cycle_hole(values)


def _circle_centre(builder: ProgramBuilder, words: list[str]) -> None:
    """``CC X.. Y..``: the circle centre (modal, file units) in the working plane XY; no
    motion."""
    centre: dict[str, float] = {}
    for word in words:
        axis = _AXIS.match(word)
        if axis is None or axis.group(2) not in "XY" or axis.group(1):
            raise builder.error(f"unknown word {word!r} in CC; expected X.. Y.. (absolute)")
        if axis.group(2) in centre:
            raise builder.error(f"two {axis.group(2)} coordinates in one CC block")
        centre[axis.group(2)] = builder.number(axis.group(2), axis.group(3))
    if set(centre) != {"X", "Y"}:
        raise builder.error("CC without both X and Y; expected CC X.. Y..")
    builder.circle_centre = (centre["X"], centre["Y"])


def _circle(spec: DialectSpec, builder: ProgramBuilder, words: list[str]) -> None:
    """``C X.. Y.. DR+|DR- [R0] [F..] [M..]``: an arc about the last CC in the XY plane."""
    centre = builder.circle_centre
    if centre is None:
        raise builder.error("C without a CC before it; expected CC X.. Y.. first")
    values: dict[str, tuple[float, bool]] = {}
    sense = None
    m_words = []
    for word in words:
        axis = _AXIS.match(word)
        if axis and axis.group(2) in "XY":
            incremental, address, text = axis.groups()
            if address in values:
                raise builder.error(f"two {address} coordinates in one block")
            values[address] = (builder.number(address, text), bool(incremental))
        elif word in ("DR+", "DR-"):
            sense = word
        elif word.startswith("F") and word != "FMAX":
            builder.set_feed(builder.number("F", word[1:]))
        elif word == "R0":
            continue
        elif word.startswith("M"):
            m_words.append(word)
        else:
            raise builder.error(
                f"unknown word {word!r} in C block; expected X.. Y.. DR+ or DR-, F.., M.."
            )
    if sense is None:
        raise builder.error("C without DR+ or DR-; expected the sense of rotation")
    actions = _m_codes(spec, builder, m_words)
    if "machine" in actions:
        raise builder.error("M91/M92 in a C block; expected them in L blocks only")
    for action in actions:
        if action in BEFORE_MOTION_M:
            apply_m_action(builder, action)
    builder.arc_move(
        values,
        {"X": (centre[0], True), "Y": (centre[1], True)},
        sense == "DR-",
        plane="XY",
    )
    for action in actions:
        if action not in BEFORE_MOTION_M:
            apply_m_action(builder, action)


_POLAR = re.compile(r"(IPA|IZ)(.*)\Z")


def _polar_circle(spec: DialectSpec, builder: ProgramBuilder, words: list[str]) -> None:
    """``CP IPA.. [IZ..] DR+|DR- [F..] [M..]``: a helix (or arc) about the last CC, turning
    ``IPA`` degrees from the start at the start's distance from CC, climbing ``IZ``."""
    centre = builder.circle_centre
    if centre is None:
        raise builder.error("CP without a CC before it; expected CC X.. Y.. first")
    given: dict[str, float] = {}
    sense = None
    m_words = []
    for word in words:
        polar = _POLAR.match(word)
        if polar:
            if polar.group(1) in given:
                raise builder.error(f"two {polar.group(1)} words in one CP block")
            given[polar.group(1)] = builder.number(polar.group(1), polar.group(2))
        elif word in ("DR+", "DR-"):
            sense = word
        elif word.startswith("F") and word != "FMAX":
            builder.set_feed(builder.number("F", word[1:]))
        elif word == "R0":
            continue
        elif word.startswith("M"):
            m_words.append(word)
        else:
            raise builder.error(
                f"unknown word {word!r} in CP block; expected IPA.., IZ.., DR+ or DR-, F.., M.."
            )
    if sense is None or "IPA" not in given:
        raise builder.error("CP without IPA and DR+ or DR-; expected CP IPA.. IZ.. DR+")
    if (given["IPA"] < 0) != (sense == "DR-"):
        raise builder.error(f"CP IPA{given['IPA']:+g} with {sense}; expected one sign for both")
    start = {a: builder.position.get(a, math.nan) / builder.linear_scale for a in "XYZ"}
    if any(math.isnan(v) for v in start.values()):
        raise builder.error("CP from an unknown position; expected a move to its start first")
    dx, dy = start["X"] - centre[0], start["Y"] - centre[1]
    angle = math.atan2(dy, dx) + math.radians(given["IPA"])
    radius = math.hypot(dx, dy)
    end = {
        "X": (centre[0] + radius * math.cos(angle), False),
        "Y": (centre[1] + radius * math.sin(angle), False),
        "Z": (start["Z"] + given.get("IZ", 0.0), False),
    }
    actions = _m_codes(spec, builder, m_words)
    if "machine" in actions:
        raise builder.error("M91/M92 in a CP block; expected them in L blocks only")
    for action in actions:
        if action in BEFORE_MOTION_M:
            apply_m_action(builder, action)
    builder.arc_move(
        end, {"X": (centre[0], True), "Y": (centre[1], True)}, sense == "DR-", plane="XY"
    )
    for action in actions:
        if action not in BEFORE_MOTION_M:
            apply_m_action(builder, action)


M_CODES = MappingProxyType(
    {
        **{code: action for code, action in STANDARD_M_CODES.items() if code != 6},
        91: "machine",
        92: "machine",
        99: "cycle_call",
        126: "shortest_path",
        127: "noop",
        128: "tcp_on",
        129: "tcp_off",
    }
)

#: Place among the controls (see :mod:`urdfpost.dialects`).
RANK = 0

SPEC = DialectSpec(
    name="heidenhain",
    extensions=(".h",),
    comment_open="; ",
    comment_close="",
    program_open=("BEGIN PGM {name} {unit_code}",),
    program_close=("END PGM {name} {unit_code}",),
    finish=("M30",),
    format_name=format_name,
    unit_words=MappingProxyType({"mm": "MM", "inch": "INCH"}),
    m_codes=M_CODES,
    tool_change=("TOOL CALL {tool} Z",),
    # 0 is the zero tool (no tool, length 0); no length offset register: the tool table row
    tool_numbers=(1, 32767),
    tool_change_speed=("TOOL CALL {tool} Z S{rpm}",),
    spindle_speed="TOOL CALL Z S{rpm}",
    spindle_on="{code}",
    tcp_on=("FUNCTION TCPM F TCP AXIS POS PATHCTRL AXIS",),
    tcp_off=("FUNCTION RESET TCPM",),
    setup=("FUNCTION RESET TCPM", "PLANE RESET STAY"),
    # PLANE SPATIAL: the angles about the fixed X, Y, Z in turn; STAY: the rotary axes stay
    # where the program put them (TNC 640 User's Manual, "PLANE SPATIAL", "STAY")
    plane_convention="xyz",
    plane_on=("PLANE SPATIAL SPA{a} SPB{b} SPC{c} STAY",),
    plane_off=("PLANE RESET STAY",),
    home=("L Z+0 R0 FMAX M91", "L X+0 Y+0 R0 FMAX M91"),
    home_comment="home",
    machine_move="L {words} R0 FMAX M91",
    work_offset=("CYCL DEF 247 DATUM SETTING ~", "  Q339=+{number} ;DATUM NUMBER"),
    work_offsets=99,
    work_offset_label="preset {number}",
    blank_form=("BLK FORM 0.1 Z X{x0} Y{y0} Z{z0}", "BLK FORM 0.2 X{x1} Y{y1} Z{z1}"),
    shortest_path="M126",
    linear_mm=NumberFormat(3, plus_sign=True),
    linear_inch=NumberFormat(4, plus_sign=True),
    rotary=NumberFormat(4, plus_sign=True),
    feed_mm=NumberFormat(1, trim=True),
    feed_inch=NumberFormat(1, trim=True),
    feed_inch_unit=2.54,
    block_format="{n}",
    block_start=0,
    block_step=1,
    block_numbers_mandatory=True,
    number_frame=True,
    number_comments=True,
    rapid_modal=False,
    format_motion=format_motion,
    motion_layout=MotionLayout(lead="L", rapid_word="FMAX"),
    parse_line=parse_line,
    cycle_lines=heidenhain_lines,
    dwell=("CYCL DEF 9.0 DWELL TIME", "CYCL DEF 9.1 DWELL {seconds}"),
    cycle_dwell=frozenset({"drill", "deep", "chipbreak", "bore"}),
    # Cycle 32 TOLERANCE (TNC 640 cycle programming manual; "TOLERANZ" in German programs):
    # T the path tolerance, HSC-MODE:0 finishing, TA the rotary axes' tolerance in degrees
    # (with FUNCTION TCPM); 32.1 without T resets it to the machine's default
    smoothing_on=(
        "CYCL DEF 32.0 TOLERANCE",
        "CYCL DEF 32.1 T{tol}",
        "CYCL DEF 32.2 HSC-MODE:0 TA{angle}",
    ),
    smoothing_off=("CYCL DEF 32.0 TOLERANCE", "CYCL DEF 32.1"),
    # no inverse-time feed: machine-coordinate programs get a feed per block (docs/job.md);
    # the TNC applies F to the block's axis-space length, degrees counted as mm (the manual
    # says rotary-only F is degrees per minute; the mixed-block rule is assumed, docs/job.md)
    axis_feed_rule="combined",
    arc_planes=frozenset({"XY"}),
    arc_helix=True,
    arc_centre_absolute=True,
    format_arc=format_arc,
    cutter_comp_words=MappingProxyType({"left": "RL", "right": "RR", "off": "R0"}),
)
