"""The APT ``CYCLE`` record: canned drilling cycles.

Two forms are read, as CAM systems write them:

- keyword form (ISO 4343:2000, NX CLSF, the APT posts of CAM systems): a kind, then
  ``keyword,value`` pairs in any order::

      CYCLE/DRILL,RAPTO,3.0000,FEDTO,-33.0043,RTRCTO,AUTO,MMPM,250.0000
      CYCLE/DRILL,DEEP,FEDTO,20,INCR,5,MMPM,120,CLEAR,2,RTRCTO,10
      CYCLE/TAP,FEDTO,12,MMPR,1.25,RAPTO,3

- positional form (ISO 4343:1978): ``CYCLE/DRILL,depth,MMPM,feed,clearance``; the depth and
  the clearance are the values that follow no keyword, in that order.

Kinds: ``DRILL`` ("drill"; a ``DWELL`` makes it drilling with a dwell), ``DRILL,DEEP`` or
``DEEP`` ("deep": pecks with full retracts), ``DRILL,BRKCHP`` or ``BRKCHP`` ("chipbreak"),
``TAP`` ("tap"), ``BORE`` and ``REAM`` ("bore": feed in, feed out); ``CYCLE/OFF`` ends the
cycle.

Keywords (lengths in the file's units, along the tool axis from the hole point, the GOTO
after the record, which is the hole top):

``FEDTO d`` / ``DEPTH d``
    The depth of the hole below its top. NX writes it negative (the bottom's offset along
    the tool axis), other writers positive: the sign is not read, a hole always goes into the
    material, against the tool axis.
``RAPTO r``
    The clearance above the top where the feed starts (the R plane).
``CLEAR c``
    The clearance when there is no ``RAPTO``; with one, the retract height.
``RTRCTO t`` / ``RTRCTO,AUTO``
    The height above the top the tool goes back to between holes; ``AUTO`` (or none): the
    ``CLEAR`` height when both are given, else the clearance.
``MMPM f``, ``IPM f``, ``MMPR f``, ``IPR f``
    The feed (per revolution: times the spindle speed, the pitch of a tap); none: the modal
    ``FEDRAT`` feed.
``INCR s`` / ``STEP s``
    The peck depth of ``DEEP`` and ``BRKCHP``.
``DWELL t``
    Seconds at the bottom.

Any other keyword is refused, with the record's line: a cycle read in part would drill
something other than the CAM system meant.
"""

from __future__ import annotations

import math
from typing import Any, Protocol

from urdfpost.errors import CLDataError
from urdfpost.units import MM_PER_INCH

from ._common import ToolpathBuilder, check_length, parse_number, quote

_KINDS = {
    "DRILL": "drill",
    "DEEP": "deep",
    "BRKCHP": "chipbreak",
    "TAP": "tap",
    "BORE": "bore",
    "REAM": "bore",
}
_FEEDS = {"MMPM": (False, 1.0), "IPM": (False, MM_PER_INCH)}
_FEEDS_PER_REV = {"MMPR": (True, 1.0), "IPR": (True, MM_PER_INCH)}
_LENGTHS = {"FEDTO": "depth", "DEPTH": "depth", "RAPTO": "rapto", "CLEAR": "clear"}
_LENGTHS |= {"INCR": "step", "STEP": "step", "RTRCTO": "rtrcto"}
_EXPECTED = "DRILL, DRILL,DEEP, DRILL,BRKCHP, DEEP, BRKCHP, TAP, BORE, REAM or OFF"
_KEYWORDS = "FEDTO, DEPTH, RAPTO, CLEAR, RTRCTO, MMPM, IPM, MMPR, IPR, INCR, STEP, DWELL"


class _Interpreter(Protocol):
    """What :func:`parse_cycle` reads of the APT interpreter's modal state."""

    source: str
    units: str
    scale: float
    rpm: float | None
    spindle_on: bool
    builder: ToolpathBuilder

    def _current_feed(self) -> float: ...


def _is_keyword(token: str) -> bool:
    return token[:1].isalpha() and token.upper() not in ("NAN", "INF", "INFINITY")


def parse_cycle(record: Any, state: _Interpreter) -> dict[str, Any]:
    """The data of the ``cycle`` event of a ``CYCLE`` record (see the module docstring).

    Parameters
    ----------
    record : Record
        The ``CYCLE`` record.
    state : _AptInterpreter
        Its units, spindle and modal feed.

    Returns
    -------
    dict
        ``cycle`` "off", or ``cycle`` (the kind), ``depth`` (mm), ``feed`` (mm/min), ``clearance``,
        ``retract``, ``step`` (mm), ``dwell`` (s).

    Raises
    ------
    CLDataError
        An unknown kind or keyword, a value missing or out of range (file and line).
    """
    source, line = state.source, record.line
    text = quote(record.text)

    def error(message: str) -> CLDataError:
        return CLDataError(source, line, f"{message} in '{text}'")

    tokens = [t for t in (record.args or []) if t]
    if not tokens or not _is_keyword(tokens[0]):
        raise error(f"expected a cycle kind ({_EXPECTED})")
    head = tokens[0].upper()
    if head == "OFF":
        if len(tokens) > 1:
            raise error("expected nothing after CYCLE/OFF")
        return {"cycle": "off"}
    if head not in _KINDS:
        raise error(f"unknown cycle kind {tokens[0]}; expected {_EXPECTED}")
    kind, rest = _KINDS[head], tokens[1:]
    if head == "DRILL" and rest and rest[0].upper() in ("DEEP", "BRKCHP"):
        kind, rest = _KINDS[rest[0].upper()], rest[1:]
    values: dict[str, float | str] = {}
    positional: list[float] = []
    feed: tuple[bool, float, float] | None = None  # per rev, mm per unit, value
    k = 0

    def number(at: int, what: str) -> float:
        if at >= len(rest) or _is_keyword(rest[at]):
            raise error(f"expected a number after {what}")
        return parse_number(rest[at], source=source, line=line, what=f"the {what} of CYCLE")

    while k < len(rest):
        token = rest[k]
        word = token.upper()
        if not _is_keyword(token):
            positional.append(parse_number(token, source=source, line=line, what="CYCLE"))
            k += 1
            continue
        if word in _FEEDS or word in _FEEDS_PER_REV:
            per_rev, unit = (_FEEDS | _FEEDS_PER_REV)[word]
            feed = (per_rev, unit, number(k + 1, word))
        elif word == "RTRCTO" and k + 1 < len(rest) and rest[k + 1].upper() == "AUTO":
            values["rtrcto"] = "AUTO"
        elif word in _LENGTHS:
            values[_LENGTHS[word]] = number(k + 1, word)
        elif word == "DWELL":
            values["dwell"] = number(k + 1, word)
        else:
            raise error(f"unknown CYCLE keyword {token}; expected {_KEYWORDS}")
        k += 2
    for key in ("depth", "clear"):  # positional values fill what the keywords did not
        if positional and key not in values:
            values[key] = positional.pop(0)
    if positional:
        raise error(
            f"{len(positional)} values more than the depth and clearance; expected keyword "
            f"values ({_KEYWORDS})"
        )

    def length(key: str, what: str) -> float:
        value = float(values[key])
        return check_length(
            value, state.scale, units=state.units, source=source, line=line, what=f"CYCLE {what}"
        )

    if "depth" not in values:
        raise error("expected the depth of the hole (FEDTO,d or DEPTH,d)")
    depth = abs(length("depth", "depth"))
    if not depth > 0.0:
        raise error("expected a depth other than 0")
    if "rapto" in values:
        clearance = length("rapto", "clearance (RAPTO)")
    elif "clear" in values:
        clearance = length("clear", "clearance (CLEAR)")
    else:
        raise error("expected the clearance above the hole (RAPTO,r or CLEAR,c)")
    if isinstance(values.get("rtrcto"), float):
        retract = length("rtrcto", "retract height (RTRCTO)")
    elif "rapto" in values and "clear" in values:
        retract = length("clear", "retract height (CLEAR)")
    else:
        retract = clearance
    if clearance < 0.0 or retract < clearance:
        raise error(
            f"clearance {clearance:g} mm and retract {retract:g} mm above the hole; expected "
            "0 <= clearance <= retract"
        )
    step = 0.0
    if kind in ("deep", "chipbreak"):
        if "step" not in values:
            raise error("expected the peck depth of a DEEP or BRKCHP cycle (INCR,s or STEP,s)")
        step = abs(length("step", "peck depth"))
        if not step > 0.0:
            raise error("expected a peck depth other than 0")
    elif "step" in values:
        raise error(f"a peck depth (INCR, STEP) in a {head} cycle; expected it with DEEP, BRKCHP")
    dwell = float(values.get("dwell", 0.0))
    if not (math.isfinite(dwell) and 0.0 <= dwell <= 3600.0):
        raise error(f"dwell {dwell:g} s; expected 0 to 3600 seconds")
    if feed is None:
        rate = state._current_feed()
        if not math.isfinite(rate):
            raise error("expected a feed (MMPM,f or IPM,f) or a FEDRAT before the cycle")
    else:
        per_rev, unit, value = feed
        if not (math.isfinite(value) and value > 0.0):
            raise error(f"expected a positive feed, got {value:g}")
        if per_rev:
            if state.rpm is None or not state.spindle_on:
                raise error("a feed per revolution with the spindle off; expected SPINDL first")
            rate = value * unit * state.rpm
        else:
            rate = value * unit
    return {
        "cycle": kind,
        "depth": depth,
        "feed": rate,
        "clearance": clearance,
        "retract": retract,
        "step": step,
        "dwell": dwell,
    }
