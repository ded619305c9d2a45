"""Canned drilling cycles in the controls' own syntax: the lines of a
:class:`~urdfpost.program.Cycle` block, and the reading of them.

Every cycle drills along the program's Z axis from a hole top (the CL point) ``depth`` mm down,
at ``feed``, starting ``clearance`` mm above the top and going back to ``retract`` mm above it
between holes. The tool stands above the first hole at the retract height before the cycle
(the writer's move before the block), so that the controls' "initial plane" is the retract
height.

ISO G-code (Fanuc 30i, LinuxCNC)::

    G98 G81 X10.000 Y10.000 Z-5.000 R2.000 F100.     (G82 with P dwell, G83/G73 with Q peck,
    X20.000 Y10.000                                    G84 tapping, G85 boring, G89 boring
    G80                                                with P dwell)

``Z`` is the bottom, ``R`` the clearance plane (absolute), ``Q`` the peck depth (incremental),
``P`` the dwell (Fanuc: milliseconds, no decimal point; LinuxCNC: seconds), ``G98`` returns to
the initial plane between holes, ``G80`` ends the cycle. References: Fanuc 30i-B operator's
manual B-64484EN, "Canned cycle for drilling" (G73, G74, G76, G80-G89); LinuxCNC G-code
reference, "G81 - G89 canned cycles" (its ``rs274`` interpreter runs the tests' programs).
The hole top is not among the words: read back, a cycle's top is its R plane (clearance 0),
which the verifier's check of the holes allows (the CL top must lie on the feed into the hole).

Siemens 840D sl (SINUMERIK Operate programming manual "Cycles", drilling cycles)::

    F100
    MCALL CYCLE81(12.000,2.000,2.000,-5.000)      (RTP, RFP, SDIS, DP)
    X10.000 Y10.000
    X20.000 Y10.000
    MCALL

``CYCLE81(RTP,RFP,SDIS,DP,DPR)`` drilling, ``CYCLE82(RTP,RFP,SDIS,DP,DPR,DTB)`` with dwell,
``CYCLE83(RTP,RFP,SDIS,DP,DPR,FDEP,FDPR,DAM,DTB,DTS,FRF,VARI)`` deep-hole (VARI 1 full retract,
0 chip breaking; FDPR the peck, DAM 0 no degression), ``CYCLE84(RTP,RFP,SDIS,DP,DPR,DTB,SDAC,
MPIT,PIT,POSS,SST,SST1)`` rigid tapping (PIT the pitch, SST the speed), ``CYCLE85(RTP,RFP,
SDIS,DP,DPR,DTB,FFR,RFF)`` boring: RTP the retract plane and RFP the reference plane (the hole
top), absolute; SDIS the safety distance; DP the bottom, absolute; DTB dwell, s. CYCLE81 to 83
drill at the programmed F.

Heidenhain TNC 640 (user's manual "Cycle programming", fixed cycles 200, 201, 203, 207)::

    CYCL DEF 200 DRILLING ~
      Q200=+2.000 ;SET-UP CLEARANCE ~
      Q201=-5.000 ;DEPTH ~
      Q206=+100 ;FEED RATE FOR PLNGNG ~
      Q202=+5.000 ;PLUNGING DEPTH ~
      Q210=+0 ;DWELL TIME AT TOP ~
      Q203=+0.000 ;SURFACE COORDINATE ~
      Q204=+10.000 ;2ND SET-UP CLEARANCE ~
      Q211=+0 ;DWELL TIME AT DEPTH
    L X+10.000 Y+10.000 FMAX M99
    L X+20.000 Y+10.000 FMAX M99

200 DRILLING (drill, drill with dwell: Q202 the whole depth), 203 UNIVERSAL DRILLING (deep:
Q202 the peck, Q213 0 chip breaks, a retract after every peck; chip breaking: Q213 99 breaks of
Q256), 207 RIGID TAPPING NEW (Q239 the pitch: the feed over the spindle speed), 201 REAMING
(bore: Q208 the retraction feed). Q201 is negative (down), Q200, Q204 above Q203.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from dataclasses import dataclass

from urdfpost.program import Cycle

ISO_CODES = {"drill": "81", "deep": "83", "chipbreak": "73", "tap": "84", "bore": "85"}
"""G-code of each cycle kind (G82 for a drill with a dwell, G89 for a bore with one)."""

ISO_KINDS = {"81": "drill", "82": "drill", "83": "deep", "73": "chipbreak", "84": "tap"}
ISO_KINDS |= {"85": "bore", "89": "bore"}

SIEMENS_CYCLES = {"drill": "CYCLE81", "deep": "CYCLE83", "chipbreak": "CYCLE83"}
SIEMENS_CYCLES |= {"tap": "CYCLE84", "bore": "CYCLE85"}

HEIDENHAIN_CYCLES = {
    "drill": "200 DRILLING",
    "deep": "203 UNIVERSAL DRILLING",
    "chipbreak": "203 UNIVERSAL DRILLING",
    "tap": "207 RIGID TAPPING NEW",
    "bore": "201 REAMING",
}

CHIP_BREAKS = 99
"""Heidenhain Q213 of a chip-breaking cycle 203: chip breaks before a full retract (its
largest value)."""


@dataclass(frozen=True)
class CycleFormat:
    """How the writer formats the words of a cycle.

    Attributes
    ----------
    axis : callable
        ``(address, value in mm) -> text`` of a position (the program's number format).
    length : callable
        ``value in mm -> text`` of a length parameter (the Z format).
    feed : callable
        ``mm/min -> text``.
    rpm : float or None
        The spindle speed running (for tapping cycles given by the pitch).
    scale : float
        mm per program unit (a pitch is written in program units).
    """

    axis: Callable[[str, float], str]
    length: Callable[[float], str]
    feed: Callable[[float], str]
    rpm: float | None
    scale: float = 1.0


def seconds(value: float) -> str:
    """A dwell in seconds as written (``0.5``, ``2``)."""
    return f"{value:.3f}".rstrip("0").rstrip(".") or "0"


def _top(cycle: Cycle, axes: tuple[str, ...]) -> float:
    return cycle.holes[0][axes.index("Z")]


def _hole_words(cycle: Cycle, axes: tuple[str, ...], fmt: CycleFormat, sep: str = "") -> list[str]:
    """``X.. Y..`` of each hole."""
    out = []
    for hole in cycle.holes:
        words = [f"{a}{sep}{fmt.axis(a, v)}" for a, v in zip(axes, hole, strict=True) if a in "XY"]
        out.append(" ".join(words))
    return out


def _pitch(cycle: Cycle, fmt: CycleFormat) -> tuple[float, float]:
    """Pitch (program units) and speed (rpm) of a tapping cycle."""
    if not fmt.rpm:
        raise ValueError("a tapping cycle with no spindle speed; expected the spindle running")
    return cycle.feed / fmt.rpm / fmt.scale, fmt.rpm


def iso_lines(cycle: Cycle, axes: tuple[str, ...], fmt: CycleFormat, dwell_ms: bool) -> list[str]:
    """The lines of a cycle in ISO G-code (see the module docstring).

    ``dwell_ms``: P is in milliseconds (Fanuc) rather than seconds (LinuxCNC).
    """
    top = _top(cycle, axes)
    code = ISO_CODES[cycle.kind]
    if cycle.dwell > 0.0 and cycle.kind not in ("drill", "bore"):
        raise ValueError(f"a {cycle.kind} cycle with a dwell; expected one only in G82, G89")
    if cycle.dwell > 0.0:
        code = {"81": "82", "85": "89"}.get(code, code)
    words = [f"G98 G{code}", _hole_words(cycle, axes, fmt)[0]]
    words += [f"Z{fmt.length(top - cycle.depth)}", f"R{fmt.length(top + cycle.clearance)}"]
    if cycle.kind in ("deep", "chipbreak"):
        words.append(f"Q{fmt.length(cycle.step)}")
    if cycle.dwell > 0.0:
        words.append(f"P{round(cycle.dwell * 1000)}" if dwell_ms else f"P{seconds(cycle.dwell)}")
    words.append(f"F{fmt.feed(cycle.feed)}")
    return [" ".join(words), *_hole_words(cycle, axes, fmt)[1:], "G80"]


def siemens_lines(cycle: Cycle, axes: tuple[str, ...], fmt: CycleFormat) -> list[str]:
    """The lines of a cycle on Sinumerik (see the module docstring)."""
    top = _top(cycle, axes)
    base = [top + cycle.retract, top, cycle.clearance, top - cycle.depth]
    values = [fmt.length(v) for v in base]
    dwell = seconds(cycle.dwell)
    name = SIEMENS_CYCLES[cycle.kind]
    if cycle.kind == "drill" and cycle.dwell > 0.0:
        name = "CYCLE82"
        values += ["", dwell]
    elif cycle.kind in ("deep", "chipbreak"):
        vari = "1" if cycle.kind == "deep" else "0"
        values += ["", "", fmt.length(cycle.step), "0", dwell, "0", "1", vari]
    elif cycle.kind == "tap":
        pitch, rpm = _pitch(cycle, fmt)
        speed = f"{rpm:.0f}"
        values += ["", dwell, "3", "", f"{pitch:.5f}", "0", speed, speed]
    elif cycle.kind == "bore":
        feed = fmt.feed(cycle.feed)
        values += ["", dwell, feed, feed]
    lines = [] if cycle.kind in ("tap", "bore") else [f"F{fmt.feed(cycle.feed)}"]
    lines.append(f"MCALL {name}({','.join(values)})")
    return [*lines, *_hole_words(cycle, axes, fmt), "MCALL"]


def heidenhain_lines(cycle: Cycle, axes: tuple[str, ...], fmt: CycleFormat) -> list[str]:
    """The lines of a cycle on a TNC (see the module docstring); lines after the first are
    continuation lines (no block number)."""
    top = _top(cycle, axes)
    length, feed = fmt.length, fmt.feed
    q: list[tuple[str, str, str]] = [
        ("200", length(cycle.clearance), "SET-UP CLEARANCE"),
        ("201", length(-cycle.depth), "DEPTH"),
    ]
    if cycle.kind == "tap":
        pitch, _ = _pitch(cycle, fmt)
        q.append(("239", f"{pitch:+.5f}", "THREAD PITCH"))
    else:
        q.append(("206", f"+{feed(cycle.feed)}", "FEED RATE FOR PLNGNG"))
    if cycle.kind == "drill":
        q += [("202", length(cycle.depth), "PLUNGING DEPTH"), ("210", "+0", "DWELL TIME AT TOP")]
    elif cycle.kind in ("deep", "chipbreak"):
        q += [("202", length(cycle.step), "PLUNGING DEPTH"), ("210", "+0", "DWELL TIME AT TOP")]
    elif cycle.kind == "bore":
        q.append(("211", f"+{seconds(cycle.dwell)}", "DWELL TIME AT DEPTH"))
        q.append(("208", f"+{feed(cycle.feed)}", "RETRACTION FEED RATE"))
    q += [
        ("203", length(top), "SURFACE COORDINATE"),
        ("204", length(cycle.retract), "2ND SET-UP CLEARANCE"),
    ]
    if cycle.kind in ("deep", "chipbreak"):
        breaks = "+0" if cycle.kind == "deep" else f"+{CHIP_BREAKS}"
        q += [
            ("212", "+0", "DECREMENT"),
            ("213", breaks, "BREAKS"),
            ("205", "+0", "MIN. PLUNGING DEPTH"),
            ("211", f"+{seconds(cycle.dwell)}", "DWELL TIME AT DEPTH"),
            ("208", "+99999", "RETRACTION FEED RATE"),
            ("256", length(0.254), "DIST FOR CHIP BRKNG"),
        ]
    elif cycle.kind == "drill":
        q.append(("211", f"+{seconds(cycle.dwell)}", "DWELL TIME AT DEPTH"))
    lines = [f"CYCL DEF {HEIDENHAIN_CYCLES[cycle.kind]} ~"]
    for i, (number, value, label) in enumerate(q):
        more = " ~" if i < len(q) - 1 else ""
        lines.append(f"  Q{number}={value} ;{label}{more}")
    return lines + [f"L {words} FMAX M99" for words in _hole_words(cycle, axes, fmt)]


# -- reading ---------------------------------------------------------------------------------


@dataclass
class CycleDefinition:
    """A cycle read from text, before its holes (lengths in mm, feed mm/min).

    ``top``: the hole top's Z (None for ISO G-code, where it is the R plane).
    """

    kind: str
    depth: float
    feed: float
    clearance: float
    retract: float
    top: float
    step: float = 0.0
    dwell: float = 0.0


_SIEMENS_CALL = re.compile(r"MCALL\s+(CYCLE8[1-5])\s*\((.*)\)\s*\Z")
_Q_LINE = re.compile(r"\s*Q(\d+)\s*=\s*([+-]?[0-9.]+)\s*(?:;[^~]*)?(~?)\s*\Z")
_HEIDENHAIN_DEF = re.compile(r"CYCL DEF (200|201|203|207)\b.*~\s*\Z")


def siemens_definition(
    text: str,
    scale: float,
    feed_scale: float,
    feed: float | None,
    error: Callable[[str], Exception],
) -> CycleDefinition | None:
    """The cycle of a line ``MCALL CYCLE8x(...)``; None when the line is not one.

    Parameters
    ----------
    text : str
        The line (upper case, without comments).
    scale : float
        mm per program unit.
    feed_scale : float
        mm/min per program feed unit.
    feed : float or None
        The modal feed, mm/min.
    error : callable
        Makes the parse error of a message.
    """
    match = _SIEMENS_CALL.match(text)
    if match is None:
        return None
    name, args = match.group(1), [a.strip() for a in match.group(2).split(",")]

    def value(i: int, what: str, required: bool = True) -> float:
        if i >= len(args) or not args[i]:
            if required:
                raise error(f"{name}: expected {what} as its parameter {i + 1}")
            return 0.0
        try:
            return float(args[i])
        except ValueError:
            raise error(f"{name}: malformed {what} {args[i]!r}") from None

    rtp, rfp = value(0, "RTP") * scale, value(1, "RFP") * scale
    sdis = value(2, "SDIS") * scale
    dp = value(3, "DP", required=False)
    if len(args) > 3 and args[3]:
        depth = rfp - dp * scale
    else:
        depth = value(4, "DP or DPR") * scale
    modal = feed
    kind, step, dwell = "drill", 0.0, 0.0
    if name == "CYCLE82":
        dwell = value(5, "DTB", required=False)
    elif name == "CYCLE83":
        step = value(6, "FDPR") * scale
        dwell = value(8, "DTB", required=False)
        kind = "deep" if value(11, "VARI", required=False) == 1.0 else "chipbreak"
    elif name == "CYCLE84":
        kind = "tap"
        dwell = value(5, "DTB", required=False)
        modal = value(8, "PIT") * scale * value(10, "SST")
    elif name == "CYCLE85":
        kind = "bore"
        dwell = value(5, "DTB", required=False)
        modal = value(6, "FFR") * feed_scale
    if modal is None or not modal > 0.0:
        raise error(f"{name} with no feed; expected an F word before it")
    return CycleDefinition(kind, depth, modal, sdis, rtp - rfp, rfp, step, dwell)


def heidenhain_start(code: str) -> int | None:
    """The cycle number of a ``CYCL DEF 200|201|203|207 ... ~`` line, else None."""
    match = _HEIDENHAIN_DEF.match(code)
    return None if match is None else int(match.group(1))


def heidenhain_parameter(raw: str) -> tuple[int, float, bool] | None:
    """``Q200=+2 ;TEXT ~``: the parameter, its value and whether a line follows; None when
    the line is not a parameter line."""
    match = _Q_LINE.match(raw)
    if match is None:
        return None
    return int(match.group(1)), float(match.group(2)), bool(match.group(3))


def heidenhain_definition(
    number: int,
    q: dict[int, float],
    scale: float,
    feed_scale: float,
    rpm: float,
    error: Callable[[str], Exception],
) -> CycleDefinition:
    """The cycle of a ``CYCL DEF`` with its Q parameters (file units)."""

    def get(key: int) -> float:
        if key not in q:
            raise error(f"CYCL DEF {number}: expected Q{key}")
        return q[key]

    clearance, depth = get(200) * scale, -get(201) * scale
    top, retract = get(203) * scale, get(204) * scale
    step = dwell = 0.0
    if number == 207:
        if not rpm > 0.0:
            raise error("CYCL DEF 207 with no spindle speed; expected a TOOL CALL S first")
        kind, feed = "tap", get(239) * scale * rpm
    else:
        feed = get(206) * feed_scale
        dwell = q.get(211, 0.0)
        if number == 200:  # pecks of Q202 with retracts when shallower than the depth
            plunge = get(202) * scale
            kind = "drill" if plunge >= depth - 1e-9 * max(1.0, depth) else "deep"
            step = 0.0 if kind == "drill" else plunge
            if not plunge > 0.0:
                raise error(f"CYCL DEF 200: Q202 {get(202)}; expected a plunging depth > 0")
        elif number == 201:
            kind = "bore"
        else:
            kind = "chipbreak" if get(213) > 0 else "deep"
            step = get(202) * scale
    if not depth > 0.0:
        raise error(f"CYCL DEF {number}: Q201 {q.get(201)}; expected a negative depth")
    return CycleDefinition(kind, depth, feed, clearance, retract, top, step, dwell)


def iso_definition(
    code: str,
    words: dict[str, float],
    start_z: float | None,
    feed: float | None,
    scale: float,
    error: Callable[[str], Exception],
) -> CycleDefinition:
    """The cycle of a ``G8x`` block (word values in file units, ``start_z`` mm: the initial
    plane; ``feed`` mm/min, the block's F applied). Seconds of P: as the caller converts."""
    if "Z" not in words or "R" not in words:
        raise error(f"G{code} without Z and R; expected both (the bottom and the R plane)")
    if start_z is None or math.isnan(start_z):
        raise error(f"G{code} from an unknown Z; expected a Z position before the cycle")
    bottom, plane = words["Z"] * scale, words["R"] * scale
    if not plane > bottom:
        raise error(f"G{code}: R{words['R']:g} not above Z{words['Z']:g}")
    kind = ISO_KINDS[code]
    step = words.get("Q", 0.0) * scale
    if kind in ("deep", "chipbreak") and not step > 0.0:
        raise error(f"G{code} without a peck depth; expected Q")
    if feed is None:
        raise error(f"G{code} with no feed; expected an F word")
    retract = max(start_z - plane, 0.0)
    return CycleDefinition(
        kind, plane - bottom, feed, 0.0, retract, plane, step, words.get("P", 0.0)
    )


def cycle_of(
    definition: CycleDefinition, holes: list[dict[str, float]], axes: tuple[str, ...]
) -> Cycle:
    """The :class:`Cycle` block of a definition and its holes (positions per address, mm /
    degrees; NaN for axes not known)."""
    return Cycle(
        kind=definition.kind,
        depth=definition.depth,
        feed=definition.feed,
        clearance=definition.clearance,
        retract=definition.retract,
        holes=tuple(tuple(h.get(a, math.nan) for a in axes) for h in holes),
        step=definition.step,
        dwell=definition.dwell,
    )
