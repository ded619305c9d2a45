"""Reader of APT-family CL data: generic APT, CATIA, Creo and Siemens NX CLSF listings.

A file is read in three steps:

1. :func:`scan_records` turns lines into logical records: ``$`` continuations are joined, ``$$``
   comments split off, NX listing header/trailer lines skipped, and reading stops at ``FINI``.
2. The file's units are taken from the records (``UNITS/``, else the first ``IPM``/``MMPM``/
   ``IPR``/``MMPR`` keyword; else mm; units given by the caller override them, with a
   warning when the file says otherwise), and the dialect from NX-only records
   (``TOOL PATH/``, ``TLDATA/``, ``MSYS/``, ``PAINT/``, ``END-OF-PATH``, listing lines).
3. :class:`_AptInterpreter` walks the records with the modal state (tool axis, feed, spindle,
   MCS, pending ``RAPID``/``CIRCLE``) and fills a toolpath builder. At the end, one warning
   when the feeds, cutter and extents look like the other unit
   (:func:`urdfpost.units.units_doubt`).

Coordinates (NX ``MSYS``): GOTO, CIRCLE and tool-axis values are in the MCS, the program zero,
and are kept as written (``GODLTA/dx,dy,dz`` moves by that much from the last point, in the
MCS's axes; ``GODLTA/d`` moves ``d`` along the tool axis).
``MSYS/x,y,z,xi,xj,xk,yi,yj,yk`` says where that MCS lies in the part's absolute frame; it
is recorded (an ``msys`` event) and changes no point while every MSYS of the file gives the
same MCS (equal within 1e-9, relative). After an MSYS of another
MCS, the points, tool axes and arcs are transformed into the first MCS (``p_first = F1^-1 F2
p``), with the warning "MSYS at line L differs from the first MCS (line K): points
transformed into the first MCS"; with ``separate_mcs`` they are left in their MCS and the
``msys`` event's ``mcs`` index marks the change (for a program with one work offset per MCS).

Steps 1 and 3 keep their state between calls, so that :func:`read_apt_stream` (the reader of
:func:`~urdfpost.readers.read_cl_chunks`) can feed them a file piece by piece
(:func:`scan_piece`, :meth:`_AptInterpreter.step`) after a quick pass for step 2
(:func:`_apt_facts`: what the reader needs from the whole file before it can interpret the
first record, the file's units, NX dialect, a continued record cut off by the end of the file,
from a pre-scan that passes over the runs of plain GOTO lines without parsing them; the
streaming reader's stops at the part of the file with the first UNITS record, and the NX
dialect, which sets only the arc sense, is then looked for in the whole file at the first
CIRCLE, and the cut-off record at the first error or at the end).

Large files are mostly runs of one-line ``GOTO/x,y,z[,i,j,k]`` records, in feed-optimised data
with a one-line ``FEDRAT`` before each (:class:`FeedLines`). Step 1 finds such runs
(:func:`scan_text`) and reads their numbers in bulk into a :class:`GotoRun`, with numpy or, for
large files with numba installed (:data:`COMPILED_FROM`), with one compiled loop
over the text's bytes (:mod:`urdfpost.readers._goto_kernel`: the same runs' numbers, bit for
bit, as ``float()`` reads them). Step 3 applies the modal state to the whole run at once,
with the same arithmetic in the same order as for one record, so the points are bit-identical.
A run whose values would need a message (a non-finite number, a length beyond
:data:`~urdfpost.readers._common.MAX_LENGTH_MM` once in mm, a tool axis of zero or non-unit
length, a feed that FEDRAT would refuse or warn about) or that follows a ``RAPID`` or
``CIRCLE`` is read record by record for those records, exactly as any other line; so is
everything that is not a plain GOTO or feed line.

Event kinds and data keys emitted (lengths in mm, feeds in mm/min):

- ``"partno"``: ``text``
- ``"comment"``: ``text`` (whole-line ``$$`` comments and ``PPRINT``)
- ``"insert"``: ``text`` (``INSERT``, verbatim)
- ``"operation"``: ``name``, and ``tool_name`` when given (NX ``TOOL PATH/op,TOOL,tool``)
- ``"cutter"``: ``diameter``, and ``corner_radius``, ``length`` when given (``CUTTER/``,
  NX ``TLDATA/MILL``). The same values are also put into the ``"tool"`` event of the tool
  change they belong to (the next one, or the last one when no motion came in between).
- ``"tool"``: ``number`` (int), and ``diameter``, ``corner_radius``, ``cutter_length`` (the
  cutter's own length of ``CUTTER``/``TLDATA``), ``name`` when known (``LOADTL/``, NX
  ``LOAD/TOOL``, ``SELECT/TOOL``), and ``adjust`` (int: the length-offset register,
  ``LOADTL/3,ADJUST,7`` or ``LOAD/TOOL,3,ADJUST,7``) when given; ``LENGTH,l`` gives
  ``length`` (the gauge length). Other values after the tool number get a warning and are
  ignored; an ADJUST that is not a whole number >= 0 is an error at the record
- ``"spindle"``: ``rpm`` (float; 0.0 for off, NaN for ``SPINDL/ON`` with no speed yet) and
  ``direction`` ("cw", "ccw", "off")
- ``"coolant"``: ``mode`` ("flood", "mist", "through", "air", "off")
- ``"home"`` (``GOHOME``), ``"stop"``: ``optional`` (``STOP`` False, ``OPSTOP`` True)
- ``"msys"``: ``mcs`` (int: 0 for the first MCS, 1, 2... for each other distinct one, in the
  order they come), ``origin`` (mm) and ``rotation`` (rows of the 3x3 matrix whose columns
  are the MCS's X, Y, Z axes) of the MCS in the part's absolute frame, ``transformed`` (bool:
  the points after it are transformed into MCS 0), ``text`` (the same in words, lengths in
  the file's units: "MCS 0 origin 3 3 0 inch, x-axis 1 0 0, z-axis 0 0 1"; the post writes
  it as a comment)
- ``"cycle"``: ``cycle`` (the kind: "drill", "deep", "chipbreak", "tap", "bore"; "off" for
  ``CYCLE/OFF``), ``depth``, ``clearance``, ``retract``, ``step`` (mm), ``feed`` (mm/min),
  ``dwell`` (s): a canned cycle (:mod:`urdfpost.readers._cycle`). The GOTOs between a cycle and
  its ``CYCLE/OFF`` are its holes, RAPID points at the hole tops
  (:func:`urdfpost.toolpath.cycle_holes`)
- ``"arc"``: a CIRCLE and the GOTO after it, before the points interpolated on it:
  ``centre`` (mm, a point of the circle axis), ``normal`` (unit: the arc turns
  counter-clockwise about it, the sense rules below applied), ``radius`` (mm), ``points``
  (how many points were interpolated: the event's index is the first, the point before it
  the arc's start, the last the GOTO's point), ``sweep`` (rad, the angle turned, ``TIMES``
  turns included). The points are the path; the event lets a post write the arc as one
  (G2/G3).
- ``"cutcom"``: ``CUTCOM/LEFT|RIGHT|OFF``: ``side`` ("left", "right", "off"), and when
  given ``register`` (int, the offset register of ``CUTCOM/LEFT,n`` or ``CUTCOM/LEFT,
  ...,n``) and ``plane`` ("XY", "ZX", "YZ" from ``XYPLAN``, ``ZXPLAN``, ``YZPLAN``)
- ``"unknown"``: ``text`` (the record as written; a warning is added too)

Text carried into the program as a comment (``comment``, ``partno`` and ``unknown`` texts, an
``operation``'s names) keeps at most :data:`~urdfpost.readers._common.COMMENT_CHARS` (200)
characters; a longer one is cut there, with a warning at its line that says so (the rest is
kept nowhere). ``insert`` text is NC code and is never cut. A warning or error quotes at most
:data:`~urdfpost.readers._common.QUOTE_CHARS` (80) characters of a record, then "... (N more
characters)".

Junk: a file that is mostly not CL data is refused at the end of the reading (whole or in
pieces alike) with a :class:`~urdfpost.errors.CLDataError` at its first unknown record: when
more than half of its records are unknown (:data:`UNKNOWN_SHARE_REFUSED`) and either more than
:data:`UNKNOWN_RECORDS_ALLOWED` (20) of them are or it has no motion record ("not a CL file:
2170 of 2300 records are unknown, the first at line 1; expected APT/CLSF records such as GOTO,
FEDRAT, CIRCLE"). Fewer unknown records are carried as comments, each with a warning.

Arc direction (``CIRCLE/xc,yc,zc,i,j,k,r``): generic APT arcs turn counter-clockwise seen from
the tip of (i,j,k) (right-hand rule). NX CLSF arcs turn the other way, clockwise about (i,j,k):
in the 146 CIRCLE records of a real NX file every arc whose neighbouring linear moves are not
perpendicular to it continues them tangentially only with that sense, and its ``TIMES,7``
helical ramps come out at exactly the 3.00 degree ramp angle only with it.

No record declares the sense: it is inferred from the dialect, NX CLSF when the file has an NX
listing line or an NX-only record, else APT. So the first CIRCLE gets one warning that says
which sense was inferred and why ("CIRCLE sense inferred, not declared: arcs turn clockwise
about the circle axis, the NX CLSF convention (the NX record TOOL PATH at line 3); ..."), and each
arc is checked against the linear feed moves into and out of it: when the tangent of the arc
at a move agrees with the other sense (cosine <= -:data:`TANGENT_EVIDENCE`) and at no move
with the inferred one, the arc gets a warning at its CIRCLE line ("arc turns against the feed
moves around it (start tangent cosine -1.00, end tangent cosine -1.00): the other sense ...").
The inferred sense is kept (the warning names each arc; a file's arcs are not turned on the
evidence of neighbouring moves, which are not always tangent).
"""

from __future__ import annotations

import io
import itertools
import logging
import math
import os
import re
import types
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, cast

import numpy as np

from urdfpost._compiled import Kernels
from urdfpost.errors import CLDataError
from urdfpost.toolpath import Motion, Toolpath
from urdfpost.units import MM_PER_INCH, other_units, units_doubt

from ._common import (
    AXIS_LENGTH_SLACK,
    COMMENT_CHARS,
    MAX_FEED_MM_PER_MIN,
    MAX_LENGTH_MM,
    ZERO_AXIS,
    ToolpathBuilder,
    check_coordinates,
    check_length,
    format_number,
    format_values,
    normalise_units,
    ordinal,
    parse_number,
    quote,
    scale_of,
    shorten,
    unit_vector,
)
from ._cycle import parse_cycle
from ._format import Format
from ._geometry import IDENTITY, ArcTooFineError, Frame, interpolate_arc
from ._stream import (
    KEEP,
    check_chord_tolerance,
    hand_out,
    iter_lines,
    last_pieces,
    line_count,
    split_parts,
    text_pieces,
)

logger = logging.getLogger(__name__)

RADIUS_MISMATCH_WARN = 0.005
"""mm. Arc end points further than this from the CIRCLE radius get a warning: files printed with
four decimals in inch round by up to 0.0013 mm per coordinate, so less is only rounding."""

__all__ = [
    "FORMAT",
    "GotoRun",
    "Record",
    "declared_units",
    "detect_apt",
    "feed_units",
    "is_nx_record",
    "normalise_breaks",
    "read_apt_stream",
    "read_apt_text",
    "scan_piece",
    "scan_records",
    "scan_text",
    "skipped_line",
]

#: NX "Information listing" header and "Tool Path Listing" trailer lines.
_LISTING_LINE = re.compile(
    r"(?:information listing created by\b"
    r"|(?:date|current work part|node name)\s*[:\t]"
    r"|tool path listing has \d+ lines\b)",
    re.IGNORECASE,
)
#: A rule of dashes or equals signs (NX listings have them, and so do hand-edited APT files):
#: skipped, and no evidence of the dialect.
_SEPARATOR_LINE = re.compile(r"[-=]{3,}\s*$")


def skipped_line(stripped: str) -> bool:
    """Whether a stripped line outside any record is listing text or a rule: no CL data."""
    return bool(_LISTING_LINE.match(stripped) or _SEPARATOR_LINE.match(stripped))


#: Lines that start a motion record: never the continuation of another record.
_MOTION_START = re.compile(r"(GOTO|FROM|GODLTA|CIRCLE)[ \t]*/", re.I)
#: Records whose whole text after the keyword is free text.
_TEXT_RECORD = re.compile(r"(PPRINT|PARTNO|INSERT)(?![A-Za-z0-9_])[ \t]*/?(.*)", re.I | re.S)
#: ``WORD[ WORD]/args`` or a bare ``WORD``.
_WORD_RECORD = re.compile(
    r"([A-Za-z][A-Za-z0-9_-]*(?:[ \t]+[A-Za-z][A-Za-z0-9_-]*)*)[ \t]*(?:/(.*))?", re.S
)
#: A line that looks like an APT/CLSF record (``WORD/...``) or an APT comment.
APT_LINE = re.compile(
    r"(?:^|(?<=\r))[ \t]*(?:[A-Za-z][A-Za-z0-9_-]*(?:[ \t]+[A-Za-z][A-Za-z0-9_-]*)*[ \t]*/|\$\$)",
    re.M,
)
"""A line that looks like an APT/CLSF record, at the start of a line: after LF, or after a
lone CR (a file with CR line ends, which the reader reads as such)."""
_KEYWORD = re.compile(r"[A-Za-z][A-Za-z0-9_]*")
_NOT_KEYWORDS = frozenset({"NAN", "INF", "INFINITY"})

#: Words of the records that move the tool.
_MOTION_WORDS = frozenset({"GOTO", "FROM", "GODLTA", "CIRCLE"})
#: A file is refused as not CL data when more than this share of its records are unknown and
#: either more than :data:`UNKNOWN_RECORDS_ALLOWED` are or it has no motion record: random text
#: is nearly all unknown records, a real CL file nearly all GOTO records.
UNKNOWN_SHARE_REFUSED = 0.5
#: Unknown records a file with motion may have whatever their share (a short hand-written
#: file with a few machine-specific words is still CL data).
UNKNOWN_RECORDS_ALLOWED = 20

#: Cosine between an arc's tangent and the linear feed move touching it from which the move
#: counts as evidence of the arc's sense (60 degrees): tangent moves give 1, the other sense
#: -1, moves square to the arc (plunges, retracts) about 0 and no evidence.
TANGENT_EVIDENCE = 0.5

#: Fewest consecutive one-line GOTO records read in bulk; shorter runs are read record by
#: record (numpy's set-up cost would exceed the saving).
BULK_MIN_RECORDS = 32
#: Characters of text read in one piece by the bulk reader (bounds its temporary copies).
_BULK_PIECE = 1 << 22
#: A line break not followed by a GOTO or FEDRAT record at the start of the next line.
_NOT_GOTO_NEXT = re.compile(r"\n(?!GOTO[ \t]*/|FEDRAT/)")
#: A GOTO record's word and slash at a line start (CATIA writes ``GOTO  /``).
_GOTO_HEAD = re.compile(r"^GOTO[ \t]*/", re.M)
#: A FEDRAT line (at a line start) with its line break.
_FEED_LINE_START = re.compile(r"^FEDRAT/[^\n]*(?:\n|\Z)", re.M)
#: A feed line the bulk reader takes into a run (:func:`_plain_feed_line`): one number, with
#: or without one keyword before or after it (the numpy path takes none with a comment).
_PLAIN_FEED = re.compile(
    r"FEDRAT/[ \t]*(?:([A-Za-z]+)[ \t]*,[ \t]*)?([+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+))"
    r"[ \t]*(?:,[ \t]*([A-Za-z]+)[ \t]*)?\n?"
)

_NX_WORDS = frozenset({"TOOL PATH", "TLDATA", "MSYS", "PAINT", "END-OF-PATH"})
_UNITS_WORDS = {"INCHES": "inch", "INCH": "inch", "MM": "mm"}
FEED_KEYWORDS = ("", "MMPM", "IPM", "MMPR", "IPR")
"""The feed keywords of the feed lines of a run (:class:`FeedLines`), by their code (0: none;
the codes of :mod:`urdfpost.readers._goto_kernel`)."""
_FEED_MODES = {  # keyword: (per revolution, mm per unit)
    "IPM": (False, MM_PER_INCH),
    "MMPM": (False, 1.0),
    "IPR": (True, MM_PER_INCH),
    "MMPR": (True, 1.0),
}
# _FEED_MODES by the code of FEED_KEYWORDS (none: feed per minute, the file's unit)
_KEYWORD_PER_REV = np.array([False] + [_FEED_MODES[w][0] for w in FEED_KEYWORDS[1:]])
_KEYWORD_SCALE = np.array([np.nan] + [_FEED_MODES[w][1] for w in FEED_KEYWORDS[1:]])
_COOLANT_MODES = {
    "FLOOD": "flood",
    "MIST": "mist",
    "THRU": "through",
    "THROUGH": "through",
    "AIR": "air",
    "OFF": "off",
}


@dataclass(frozen=True)
class Record:
    """One logical record of an APT file.

    Attributes
    ----------
    line : int
        1-based line where the record starts.
    word : str
        Major word, upper case, blanks collapsed ("GOTO", "TOOL PATH"); "$$" for a whole-line
        comment; "" when the record does not start with a word.
    args : list of str or None
        Comma-separated values after "/", stripped; None when there is no "/".
    text : str
        The record as written (continuations joined, trailing ``$$`` comment removed).
    rest : str
        For free-text records (PPRINT, PARTNO, INSERT, ``$$``): the text after the keyword.
    """

    line: int
    word: str
    args: list[str] | None
    text: str
    rest: str = ""


@dataclass(frozen=True)
class FeedLines:
    """The feed lines (``FEDRAT/`` and one number, with or without one keyword) between the
    GOTO records of a :class:`GotoRun`: feed-optimised CL data has one before every move.

    Attributes
    ----------
    at : ndarray, shape (f,), int64
        Per feed line, how many GOTO records of the run come before it (increasing; several
        feed lines may come before the same record).
    values : ndarray, shape (f,), float64
        Their numbers, as written.
    keywords : ndarray, shape (f,), int
        Their keywords, by their index in :data:`FEED_KEYWORDS` (0: none).
    """

    at: np.ndarray
    values: np.ndarray
    keywords: np.ndarray

    def __len__(self) -> int:
        return int(self.at.shape[0])


@dataclass(frozen=True)
class GotoRun:
    """Consecutive one-line ``GOTO`` records whose numbers were read in bulk, with any feed
    lines between them.

    Attributes
    ----------
    line : int
        1-based line of the first record; without feed lines, record ``i`` is on line
        ``line + i`` (:meth:`lines`).
    values : ndarray, shape (k, 3) or (k, 6)
        The numbers as written (file units, frame of the file).
    text : str
        Text the records are part of (``\\n`` line breaks).
    start : int
        Offset in ``text`` of the first record; the run's records are the :attr:`line_count`
        lines from there.
    feeds : FeedLines or None
        The feed lines among them (None: none).
    """

    line: int
    values: np.ndarray
    text: str = field(repr=False)
    start: int
    feeds: FeedLines | None = None
    word: str = "GOTO"
    args: None = None

    def __len__(self) -> int:
        return int(self.values.shape[0])

    @property
    def line_count(self) -> int:
        """Lines of the run: its GOTO records and its feed lines."""
        return len(self) + (0 if self.feeds is None else len(self.feeds))

    def lines(self) -> np.ndarray:
        """Line of each GOTO record, shape (k,), int64."""
        lines = np.arange(self.line, self.line + len(self), dtype=np.int64)
        if self.feeds is not None:  # each record comes after the feed lines before it
            lines += np.searchsorted(self.feeds.at, np.arange(len(self)), side="right")
        return lines

    def records(self) -> list[Record]:
        """Every record of the run (feed lines too), as :func:`scan_records` makes them."""
        records = []
        pos = self.start
        for i in range(self.line_count):
            end = self.text.find("\n", pos)
            end = len(self.text) if end < 0 else end
            code = self.text[pos:end].strip().partition("$$")[0].rstrip()
            records.append(parse_record(code, self.line + i))
            pos = end + 1
        return records


@dataclass
class _Scan:
    """Result of :func:`scan_records` and :func:`scan_text`."""

    records: list[Record | GotoRun] = field(default_factory=list)
    listing_lines: int = 0
    first_listing: int = 0  # line of the first listing line (0: none)
    trailing_comments: int = 0
    after_fini: list[int] = field(default_factory=list)


def split_lines(text: str) -> list[str]:
    """Split on LF, CRLF or CR, keeping line numbers as editors count them."""
    return re.split(r"\r\n|\r|\n", text)


def parse_record(code: str, line: int) -> Record:
    """Split the text of one logical record into word and arguments."""
    code = code.strip()
    match = _TEXT_RECORD.fullmatch(code)
    if match:
        return Record(line, match[1].upper(), None, code, match[2].strip())
    match = _WORD_RECORD.fullmatch(code)
    if not match:
        return Record(line, "", None, code)
    word = " ".join(match[1].upper().split())
    args = None if match[2] is None else [a.strip() for a in match[2].split(",")]
    return Record(line, word, args, code)


class _Scanner:
    """Turns lines into records, keeping the state of a continued record between calls."""

    def __init__(self, source: str) -> None:
        self.source = source
        self.scan = _Scan()
        self.pending: str | None = None
        self.start = 0
        self.fini = 0  # line of FINI once read
        self.line = 1  # number of the line after those scan_piece has scanned (until FINI)

    def feed(self, lines: Iterable[str], first: int) -> int:
        """Scan ``lines``, numbered from ``first``.

        Returns
        -------
        int
            How many lines were scanned: all of them, or up to and including FINI.
        """
        scan = self.scan
        count = 0
        for number, raw in enumerate(lines, start=first):
            count += 1
            stripped = raw.strip()
            if not stripped:
                continue
            if self.pending is None and _LISTING_LINE.match(stripped):
                scan.listing_lines += 1
                scan.first_listing = scan.first_listing or number
                continue
            if self.pending is None and _SEPARATOR_LINE.match(stripped):
                continue
            if stripped.startswith("$$"):
                scan.records.append(Record(number, "$$", None, stripped, stripped[2:].strip()))
                continue
            if self.pending is None and _TEXT_RECORD.match(stripped):
                # free text is one line: a "$" or "$$" in it is text, not a continuation
                scan.records.append(parse_record(stripped, number))
                continue
            if self.pending is not None and _MOTION_START.match(stripped):
                raise CLDataError(
                    self.source,
                    self.start,
                    "expected the continuation of this record (its last line ends with '$'), "
                    f"got the motion record at line {number}",
                )
            code, sep, _ = stripped.partition("$$")
            scan.trailing_comments += bool(sep)
            code = code.rstrip()
            continued = code.endswith("$")
            if continued:
                code = code[:-1]
            if self.pending is None:
                self.pending, self.start = code, number
            else:
                self.pending += code
            if continued:
                continue
            record = parse_record(self.pending, self.start)
            self.pending = None
            scan.records.append(record)
            if record.word == "FINI":
                self.fini = number
                break
        return count

    def add_run(self, run: GotoRun) -> None:
        """Append a run of GOTO records (the previous record must be complete)."""
        assert self.pending is None
        self.scan.records.append(run)

    def after_fini(self, lines: Iterable[str]) -> None:
        """Note the non-blank lines after FINI; ``lines`` start on the line after it."""
        self.scan.after_fini = [
            self.fini + 1 + k
            for k, rest in enumerate(lines)
            if rest.strip() and not skipped_line(rest.strip())
        ]

    def finish(self) -> _Scan:
        """The records.

        Raises
        ------
        CLDataError
            When the file ends inside a continued record.
        """
        if self.pending is not None:
            raise CLDataError(
                self.source,
                self.start,
                "expected the continuation of this record (its last line ends with '$'), "
                "got the end of the file",
            )
        return self.scan


def scan_records(lines: Sequence[str], source: str) -> _Scan:
    """Turn lines into logical records.

    ``$`` at the end of a line continues the record on the next line; ``$$`` starts a comment
    (a whole-line one becomes a "$$" record, a trailing one is dropped: NX writes contact
    points there). Blank lines and NX listing lines are skipped. Scanning stops after FINI;
    the numbers of non-blank lines after it are returned in ``after_fini``.

    Raises
    ------
    CLDataError
        When the file ends inside a continued record.
    """
    scanner = _Scanner(source)
    scanned = scanner.feed(lines, 1)
    if scanner.fini:
        scanner.after_fini(lines[scanned:])
    return scanner.finish()


def _goto_blocks(text: str) -> Iterator[tuple[int, int]]:
    """Offsets ``(start, end)`` of the blocks of consecutive lines that start with ``GOTO/``
    or ``FEDRAT/``.

    ``text`` has ``\\n`` line breaks only. ``start`` is the start of the block's first line,
    ``end`` the position after its last line break (or the end of the text).
    """
    # the starts of the other lines
    others: Iterator[int] = (m.end() for m in _NOT_GOTO_NEXT.finditer(text))
    if not (text.startswith("FEDRAT/") or _GOTO_HEAD.match(text)):
        others = itertools.chain([0], others)
    block = 0
    for other in others:
        if other > block:
            yield block, other
        end = text.find("\n", other)
        if end < 0:
            return
        block = end + 1
    if block < len(text):
        yield block, len(text)


def _goto_values(lines: str, count: int) -> np.ndarray | None:
    """The numbers of ``count`` GOTO lines ``GOTO/x,y,z[,i,j,k]``, or None.

    Every line of ``lines`` starts with ``GOTO/`` (blanks allowed before the slash). None
    unless every line is that and the same number of values (3 or 6) that
    :func:`parse_number` accepts (blanks around them allowed), and nothing else: no ``$``
    continuation or comment, no other characters.

    Returns
    -------
    ndarray, shape (count, 3) or (count, 6), or None
    """
    if not lines.isascii() or "_" in lines:  # float() reads 1_000; parse_number does not
        return None
    numbers = lines.replace("GOTO/", "")
    if len(lines) - len(numbers) != 5 * count:  # blanks before a slash, or a GOTO/ elsewhere
        numbers, heads = _GOTO_HEAD.subn("", lines)
        if heads != count or "GOTO" in numbers:
            return None
    try:
        # loadtxt parses like float() on the stripped field, and insists on one column count
        values = np.loadtxt(
            io.StringIO(numbers),
            delimiter=",",
            comments=None,
            ndmin=2,
            dtype=float,
        )
    except ValueError:
        return None
    if values.shape not in ((count, 3), (count, 6)):
        return None
    return values


_Run = tuple[int, int, np.ndarray, int, FeedLines | None]
"""A run of :func:`_bulk_runs`: its start and end in the text, its GOTO values, its lines with
a ``$$`` comment and its feed lines."""


def _bulk_runs(text: str, bulk_piece: int | None = None, compiled: bool = False) -> Iterator[_Run]:
    """Runs of one-line GOTO records in ``text`` with their numbers read in bulk.

    With ``compiled`` and numba installed, found and read by the compiled byte loop
    (:func:`_compiled_runs`), else by :func:`_bulk_runs_numpy`: the same records, the same
    numbers to the bit.

    Parameters
    ----------
    text : str
        Lines with ``\\n`` line breaks.
    bulk_piece : int, optional
        Characters after which a run is cut (default :data:`_BULK_PIECE`): bounds the memory
        of the temporary arrays made of a run.
    compiled : bool
        Whether to read with the compiled loop (when numba is there): for large texts, which
        make up for its import.

    Yields
    ------
    start, end : int
        Offsets of the run's first line and after its last line break (or the text's end).
    values : ndarray, shape (k, 3) or (k, 6)
    comments : int
        Lines of the run with a trailing ``$$`` comment.
    feeds : FeedLines or None
        The run's feed lines (:class:`GotoRun`), None when it has none.
    """
    size = _BULK_PIECE if bulk_piece is None else bulk_piece
    runs = _compiled_runs(text, size) if compiled else None
    return iter(runs) if runs is not None else _bulk_runs_numpy(text, size)


COMPILED_FROM = 1 << 25
"""Characters of text (a whole file's, or a streamed file's bytes) from which the runs of GOTO
lines are found and read by the compiled byte loop (:mod:`urdfpost.readers._goto_kernel`, with
numba installed: the ``fast`` extra) rather than the numpy path, in a process that has not
imported numba yet. Numba's import and the loading of its cached machine code take 0.4-0.9 s
there; the loop saves about 6 ns a character (0.33 s for a million GOTO lines, 57 MB): a file
read alone breaks even at about 70-100 MB, and a post of a file this large loads numba anyway
(the verification's matching, from 50,000 points), so its read may as well (bench/RESULTS.md,
December 7 2026)."""

COMPILED_WARM_FROM = 1 << 21
"""Characters from which the compiled loop runs once numba is imported in this process (by this
reader or another compiled loop): then only the loop's own cached code is loaded (about 0.06
s the first time)."""


def _load_kernels() -> types.ModuleType:
    from urdfpost.readers import _goto_kernel

    return _goto_kernel


KERNELS = Kernels(
    _load_kernels,
    "GOTO scan",
    start=COMPILED_FROM,
    warm_start=COMPILED_WARM_FROM,
    stays=False,
    logger=logger,
)
"""The compiled loops (:mod:`urdfpost.readers._goto_kernel`); a text of ``size`` characters
is read with them where ``KERNELS.wanted(size)`` (:data:`COMPILED_FROM`,
:data:`COMPILED_WARM_FROM`)."""


def _compiled(loop: str, data: np.ndarray, *args: int) -> Any:
    """The compiled ``loop`` of :mod:`urdfpost.readers._goto_kernel` run on ``data`` (the
    bytes of a text, :func:`_bytes_of`) and ``args``: what the loop returns; None without
    numba, or when it fails here (once: the warning "compiled GOTO scan unavailable (why); the
    numpy path runs", and no more tries)."""
    kernel = KERNELS.load()
    if kernel is None:
        return None
    try:
        return getattr(kernel, loop)(data, *args)
    except Exception as e:  # numba could not compile or load it here: the numpy path
        KERNELS.fail(e)
        return None


def _bytes_of(text: str) -> np.ndarray:
    """The bytes the compiled loops read of ``text``, shape (len(text),), uint8: one per
    character (a character that is not ASCII as ``?``, which no number or keyword has), so that
    their offsets are the text's."""
    return np.frombuffer(text.encode("ascii", "replace"), dtype=np.uint8)


_FEED_SAMPLE = 1 << 20
"""Characters of a text :func:`_compiled_runs` counts feed lines in, to size the loop's
array of them."""


def _compiled_runs(text: str, size: int) -> list[_Run] | None:
    """:func:`_bulk_runs` of ``text`` by the compiled loop, or None without it (or when it
    failed here, or when the numbers of an odd GOTO line are not for ``np.loadtxt``: then the
    numpy path reads the text).

    The odd lines of its runs (numbers with exponents, many digits, ``nan``...) are read here
    with :func:`_goto_values`, as the numpy path reads every line.
    """
    if KERNELS.load() is None:
        return None
    data = _bytes_of(text)
    # rows for runs, odd lines and feed lines (as many as the text's first MB suggests, with
    # a margin: counting them all would take a quarter of the loop's time); more when the
    # loop says so
    sample = min(len(text), _FEED_SAMPLE)
    feeds = text.count("FEDRAT/", 0, sample) * len(text) // max(sample, 1)
    rooms = (64, 64, 64 + feeds + feeds // 4)
    while True:
        got = _compiled("goto_runs", data, BULK_MIN_RECORDS, size, *rooms)
        if got is None:
            return None
        runs, values, odd, feeds, feed_values, *needed = got
        if all(need <= room for need, room in zip(needed, rooms, strict=True)):
            break
        rooms = tuple(max(need, room) for need, room in zip(needed, rooms, strict=True))
    del data
    if len(odd) and not _read_odd(text, odd, values):
        return None
    out: list[_Run] = []
    for start, end, count, width, comments, first, first_feed, feed_count in runs.tolist():
        lines = None
        if feed_count:
            rows = slice(first_feed, first_feed + feed_count)
            lines = FeedLines(feeds[rows, 0].copy(), feed_values[rows], feeds[rows, 1].copy())
        run = values[first : first + count * width].reshape(count, width)
        out.append((start, end, run, comments, lines))
    return out


def _read_odd(text: str, odd: np.ndarray, values: np.ndarray) -> bool:
    """Fill in ``values`` the numbers of the odd GOTO lines of :func:`_compiled_runs`.

    Parameters
    ----------
    text : str
    odd : ndarray, shape (o, 3), int
        Per line: its offset in ``text``, the offset after its code, the offset in ``values``
        of its first number.
    values : ndarray, shape (v,)

    Returns
    -------
    bool
        False when :func:`_goto_values` does not read them (then nothing is to be trusted).
    """
    codes = [text[start:end].strip() for start, end, _ in odd.tolist()]
    widths = np.array([code.count(",") + 1 for code in codes])
    for width in (3, 6):
        chosen = np.flatnonzero(widths == width)
        if not chosen.size:
            continue
        got = _goto_values("\n".join(codes[k] for k in chosen.tolist()), chosen.size)
        if got is None or got.shape[1] != width:
            return False
        values[odd[chosen, 2][:, None] + np.arange(width)] = got
    return True


def _bulk_runs_numpy(text: str, size: int) -> Iterator[_Run]:
    """:func:`_bulk_runs` with numpy: blocks of lines that start with ``GOTO/`` (or
    ``FEDRAT/``) found with a regular expression and their numbers read by ``np.loadtxt``, in
    pieces of about ``size`` characters (long blocks are cut after ``size`` characters when
    longer than ``2 * size``).
    """
    for start, end in _goto_blocks(text):
        while start < end:
            cut = end
            if end - start > 2 * size:
                cut = text.find("\n", start + size, end) + 1 or end
            piece = text[start:cut]
            if "FEDRAT/" in piece:
                yield from _feed_runs(piece, start)
            else:
                yield from _plain_runs(piece, start)
            start = cut


def _plain_runs(piece: str, offset: int) -> Iterator[_Run]:
    """:func:`_bulk_runs` of a piece of a block of GOTO lines (at ``offset`` in the text)."""
    count = piece.count("\n") + (not piece.endswith("\n"))
    if count >= BULK_MIN_RECORDS:
        values = _goto_values(piece, count)
        if values is not None:
            yield offset, offset + len(piece), values, 0, None
        else:  # mixed value counts, trailing $$ comments, ...: group the plain lines
            yield from _bulk_runs_by_line(piece, offset)


def _plain_feed_line(line: str) -> tuple[int, float] | None:
    """The keyword (its index in :data:`FEED_KEYWORDS`, 0 for none) and number of a feed line
    the bulk reader takes into a run (:data:`_PLAIN_FEED`; the line with or without its line
    break), else None."""
    match = _PLAIN_FEED.fullmatch(line)
    if match is None or (match[1] and match[3]):
        return None
    word = (match[1] or match[3] or "").upper()
    if word not in FEED_KEYWORDS:
        return None
    return FEED_KEYWORDS.index(word), float(match[2])


def _feed_runs(piece: str, offset: int) -> Iterator[_Run]:
    """:func:`_bulk_runs` of a piece of a block of GOTO and FEDRAT lines (at ``offset`` in the
    text).

    The GOTO lines between the feed lines of :func:`_plain_feed_line` are read by one
    ``np.loadtxt`` (:func:`_goto_values`) and make one run with those feed lines; a run starts
    and ends with a GOTO line. Any other FEDRAT line ends a run (the scanner reads it), and a
    run whose GOTO lines are not all plain and of one value count is read as the GOTO lines
    between its feed lines, each block as :func:`_plain_runs`.
    """
    segments: list[tuple[int, int]] = []  # of the open run: its blocks of GOTO lines
    feeds: list[tuple[int, int, float]] = []  # its feed lines: GOTO lines before, keyword, value
    count = 0  # its GOTO lines
    pos = 0
    for start, end in itertools.chain(_feed_line_spans(piece), [(len(piece), len(piece))]):
        if start > pos:
            segments.append((pos, start))
            count += piece.count("\n", pos, start) + (not piece.endswith("\n", pos, start))
        feed = None if start == len(piece) else _plain_feed_line(piece[start:end])
        if feed is not None and segments:  # (a feed line before the run's first GOTO: scanned)
            feeds.append((count, *feed))
        elif segments:  # the open run ends before this line
            yield from _feed_run(piece, offset, segments, feeds, count)
            segments, feeds, count = [], [], 0
        pos = end


def _feed_line_spans(text: str) -> Iterator[tuple[int, int]]:
    """Offsets of the start of each line of ``text`` that starts with ``FEDRAT/`` and after
    its line break (or the text's end)."""
    start = 0 if text.startswith("FEDRAT/") else text.find("\nFEDRAT/") + 1
    if not start and not text.startswith("FEDRAT/"):
        return
    while True:
        end = text.find("\n", start) + 1 or len(text)
        yield start, end
        start = text.find("\nFEDRAT/", end - 1) + 1  # (from the line break ending this one)
        if not start:
            return


def _feed_run(
    piece: str,
    offset: int,
    segments: list[tuple[int, int]],
    feeds: list[tuple[int, int, float]],
    count: int,
) -> Iterator[_Run]:
    """The run of :func:`_feed_runs` made of the blocks of GOTO lines ``segments`` (offsets in
    ``piece``, which is at ``offset`` in the text), ``count`` lines in all, and the feed lines
    between them (those after the last block are left to the scanner)."""
    feeds = [feed for feed in feeds if feed[0] < count]
    if count >= BULK_MIN_RECORDS:
        values = _goto_values("".join(piece[a:b] for a, b in segments), count)
        if values is not None:
            lines = None
            if feeds:
                at, keywords, numbers = np.array(feeds).T
                lines = FeedLines(at.astype(np.int64), numbers, keywords.astype(np.int64))
            yield offset + segments[0][0], offset + segments[-1][1], values, 0, lines
            return
    for a, b in segments:
        yield from _plain_runs(piece[a:b], offset + a)


def _bulk_runs_by_line(block: str, offset: int) -> Iterator[_Run]:
    """:func:`_bulk_runs` within a piece of a block of GOTO lines not read in one go."""
    lines = block.split("\n")
    if block.endswith("\n"):
        lines.pop()
    parts = [raw.partition("$$") for raw in lines]
    codes = [code.strip() for code, _, _ in parts]
    kinds = []  # values per line when plain (3 or 6), else 0
    for code in codes:
        commas = code.count(",")
        kinds.append(commas + 1 if commas in (2, 5) and not code.endswith("$") else 0)
    position = offset  # of line k
    k = 0
    for kind, group in itertools.groupby(kinds):
        size = sum(1 for _ in group)
        length = sum(len(raw) + 1 for raw in lines[k : k + size])
        if kind and size >= BULK_MIN_RECORDS:
            values = _goto_values("\n".join(codes[k : k + size]), size)
            if values is not None:
                comments = sum(bool(sep) for _, sep, _ in parts[k : k + size])
                end = min(position + length, offset + len(block))
                yield position, end, values, comments, None
        position += length
        k += size


def scan_text(text: str, source: str) -> _Scan:
    """:func:`scan_records` of a whole text, with runs of plain GOTO records read in bulk.

    The records are those of ``scan_records(split_lines(text), source)``, except that runs of
    at least :data:`BULK_MIN_RECORDS` consecutive one-line ``GOTO`` records with plain numbers
    come as one :class:`GotoRun` each (found and read by the compiled loop from
    :data:`COMPILED_FROM` characters on, see :data:`KERNELS`).

    Raises
    ------
    CLDataError
        When the file ends inside a continued record.
    """
    scanner = _Scanner(source)
    after = scan_piece(scanner, normalise_breaks(text), 1, compiled=KERNELS.wanted(len(text)))
    if after is not None:
        scanner.after_fini(after)
    return scanner.finish()


def normalise_breaks(text: str) -> str:
    """``text`` with one ``\\n`` per line break (CRLF and CR replaced).

    Line numbers stay those of :func:`split_lines`. A text cut after a line break (never
    between CR and LF) can be normalised piece by piece.
    """
    if "\r" in text:
        text = text.replace("\r\n", "\n").replace("\r", "\n")
    return text


def scan_piece(
    scanner: _Scanner,
    text: str,
    line: int,
    bulk_piece: int | None = None,
    *,
    compiled: bool = False,
) -> Iterator[str] | None:
    """Scan the lines of ``text`` into ``scanner``'s records, GOTO runs read in bulk.

    ``text`` has ``\\n`` line breaks only and starts at the start of line number ``line``; the
    scanner may hold a continued record from the lines before. Called on consecutive pieces
    of a file cut at line breaks, it makes the records of the whole file (GOTO runs may be
    cut where the pieces are). ``bulk_piece`` and ``compiled`` are as for :func:`_bulk_runs`.

    Returns
    -------
    iterator of str or None
        None (and the number of the line after ``text`` in ``scanner.line``), or when the
        scanner reads FINI, the lines of ``text`` after it.
    """
    pos = 0  # start of the next line to scan; its number is ``line``
    for start, end, values, comments, feeds in _bulk_runs(text, bulk_piece, compiled):
        if start > pos:
            lines = text[pos : start - 1].split("\n")
            scanned = scanner.feed(lines, line)
            if scanner.fini:
                return itertools.chain(lines[scanned:], text[start:].split("\n"))
            line += len(lines)
        if scanner.pending is not None and feeds is not None:  # scanned line by line
            lines = text[start:end].split("\n")
            if text.endswith("\n", start, end):
                lines.pop()
            scanned = scanner.feed(lines, line)
            if scanner.fini:
                return itertools.chain(lines[scanned:], text[end:].split("\n"))
            line += len(lines)
            pos = end
            continue
        if scanner.pending is not None:  # the first GOTO line continues a record
            first_end = text.find("\n", start, end)
            first_end = end if first_end < 0 else first_end + 1
            scanner.feed([text[start:first_end].rstrip("\n")], line)
            if scanner.fini:
                return iter(text[first_end:].split("\n"))
            comments -= "$$" in text[start:first_end]  # counted by the scanner
            start, values, line = first_end, values[1:], line + 1
        scanner.scan.trailing_comments += comments
        if len(values):
            run = GotoRun(line, values, text, start, feeds)
            scanner.add_run(run)
            line += run.line_count
        pos = end
    lines = text[pos:].split("\n")
    scanned = scanner.feed(lines, line)
    if scanner.fini:
        return iter(lines[scanned:])
    scanner.line = line + len(lines) - 1  # the text's line breaks after ``line``
    return None


def detect_apt(text: str, line_start: bool = True) -> bool:
    """Whether any line of ``text`` looks like an APT/CLSF record (``WORD/...`` or ``$$``).

    :data:`APT_LINE` finds lines after a lone CR too, so a piece that follows one starts a
    line (``line_start`` False, :class:`~urdfpost.readers._format.Detector`) as any other.
    """
    return APT_LINE.search(text) is not None


def _file_units(records: Sequence[Record | GotoRun]) -> tuple[str, int] | None:
    """Units the records declare and the line that says so: the first UNITS record, else the
    first feed-unit keyword; None when they say nothing."""
    for record in records:
        units = declared_units(record)
        if units:
            return units, record.line
    for record in records:
        if said := feed_units(record):
            return said
    return None


def declared_units(record: Record | GotoRun) -> str | None:
    """Units of a ``UNITS/`` record ("mm" or "inch"), or None."""
    if record.word == "UNITS" and record.args:
        return _UNITS_WORDS.get(record.args[0].upper())
    return None


def feed_units(record: Record | GotoRun) -> tuple[str, int] | None:
    """Units of the first feed-unit keyword (``IPM``, ``MMPR``, ...) among the arguments (of
    the feed lines of a run), and the line it is on; None when there is none."""
    if isinstance(record, GotoRun):
        feeds = record.feeds
        if feeds is None:
            return None
        said = np.flatnonzero(feeds.keywords)
        if not said.size:
            return None
        j = int(said[0])  # (feed line j comes after at[j] GOTO lines and j feed lines)
        units = _feed_keyword_units(FEED_KEYWORDS[int(feeds.keywords[j])])
        return None if units is None else (units, record.line + int(feeds.at[j]) + j)
    for token in record.args or ():
        units = _feed_keyword_units(token)
        if units:
            return units, record.line
    return None


def _feed_keyword_units(token: str) -> str | None:
    """The units of a feed keyword: "inch" for ``IPM``, ``IPR``, "mm" for ``MMPM``, ``MMPR``
    (any case), else None."""
    upper = token.upper()
    if upper in ("IPM", "IPR"):
        return "inch"
    if upper in ("MMPM", "MMPR"):
        return "mm"
    return None


def is_nx_record(record: Record | GotoRun) -> bool:
    """Whether a record is one that only NX CLSF listings have."""
    return record.word in _NX_WORDS


def nx_evidence(
    records: Iterable[Record | GotoRun], first_listing: int = 0
) -> tuple[int, str] | None:
    """Where a file first shows that it is an NX CLSF listing, or None.

    Parameters
    ----------
    records : iterable of Record or GotoRun
        The file's records, in order (read until the first NX-only record).
    first_listing : int
        Line of the file's first NX listing line, 0 for none.

    Returns
    -------
    (int, str) or None
        The line and what is there ("the NX record TOOL PATH", "an NX listing line"): the
        first NX-only record or listing line, whichever comes first.
    """
    found = next(((r.line, f"the NX record {r.word}") for r in records if is_nx_record(r)), None)
    if first_listing and (found is None or first_listing < found[0]):
        return first_listing, "an NX listing line"
    return found


_STILL = 1e-6
"""A move whose tool tip moves at most this far (mm) does not move it (an inverse-time feed
then gives no tip feed: :meth:`_AptInterpreter._move_feed`)."""


def _cutter_value(data: Mapping[str, object]) -> tuple[float, float | None]:
    """A cutter's diameter and corner radius (mm; None for none given) from a CUTTER, TLDATA
    or tool event's data."""
    corner = data.get("corner_radius")
    return float(data["diameter"]), (None if corner is None else float(corner))  # type: ignore[arg-type]


def _same_tool_value(a: object, b: object) -> bool:
    """Whether two cutters (diameter and corner radius, mm; no corner radius is 0) or two
    LOADTL lengths (mm) of a tool number are the same to 1e-6 mm (the same tool written with
    more or fewer digits, or with its corner radius left out; no LENGTH is no number)."""
    if (a is None) != (b is None):
        return False
    first = np.array(a if isinstance(a, tuple) else (a,), dtype=float)
    second = np.array(b if isinstance(b, tuple) else (b,), dtype=float)
    return bool(np.allclose(np.nan_to_num(first), np.nan_to_num(second), rtol=0.0, atol=1e-6))


def _split_tokens(record: Record, source: str) -> tuple[list[str], list[float]]:
    """Keywords (upper case) and numbers of a record's arguments, in their own order.

    Raises
    ------
    CLDataError
        For an argument that is neither a keyword nor a number.
    """
    words: list[str] = []
    numbers: list[float] = []
    for position, token in enumerate(record.args or (), start=1):
        if _KEYWORD.fullmatch(token) and token.upper() not in _NOT_KEYWORDS:
            words.append(token.upper())
        else:
            what = f"the {ordinal(position)} value of {record.word}"
            numbers.append(parse_number(token, source=source, line=record.line, what=what))
    return words, numbers


@dataclass(frozen=True)
class _ArcCheck:
    """An arc whose sense is checked against the moves around it, waiting for the next move.

    Attributes
    ----------
    line : int
        Line of the CIRCLE record.
    end : ndarray, shape (3,), mm
        End point of the arc (workpiece frame).
    end_tangent : ndarray, shape (3,)
        Unit direction of motion at the end.
    start_cosine : float or None
        Cosine between the feed move into the arc and its start tangent; None when there is
        no such move (the arc follows an arc, a rapid, or nothing).
    """

    line: int
    end: np.ndarray
    end_tangent: np.ndarray
    start_cosine: float | None


@dataclass(frozen=True)
class _PendingCircle:
    """A CIRCLE record waiting for its end GOTO (all in the workpiece frame, mm)."""

    line: int
    centre: tuple[float, float, float]
    rotation_axis: tuple[float, float, float]
    radius: float
    turns: int


class _AptInterpreter:
    """Walks the records of one file with the modal state of an APT post-processor.

    Parameters
    ----------
    source : str
        File name for messages.
    units : str
        Units the values are read in ("mm" or "inch").
    chord_tolerance : float, mm
        Chord error allowed when interpolating arcs.
    nx : tuple of (int, str), or None
        Where the file shows that it is NX CLSF (:func:`nx_evidence`): then arcs turn
        clockwise about the circle axis. None: APT, counter-clockwise.
    declared : tuple of (str, int), optional
        The units the file declares and the line that says so (None: it says nothing).
    forced : bool
        ``units`` were given by the caller: they apply whatever the file says (a declaration
        of other units gets a warning, feed keywords give the feed mode only: the first of
        other units than ``units`` gets the same warning, unless the declaration had one).
    separate_mcs : bool
        Leave the points after an ``MSYS`` of another MCS in that MCS (the ``msys`` event
        marks the change) instead of transforming them into the first MCS.
    """

    def __init__(
        self,
        source: str,
        units: str,
        chord_tolerance: float,
        nx: tuple[int, str] | None,
        *,
        declared: tuple[str, int] | None = None,
        forced: bool = False,
        separate_mcs: bool = False,
    ) -> None:
        self.source = source
        self.units = self.file_units = units
        self.scale = scale_of(units)
        self.chord_tolerance = chord_tolerance
        self.arc_sense = -1.0 if nx else 1.0
        self.nx = nx
        # where the NX evidence of the whole file is not known yet (a streaming reader that
        # looked only at the file's start): what finds it, asked at the first CIRCLE
        self.nx_of_file: Callable[[], tuple[int, str] | None] | None = None
        self.sense_noted = False  # whether the warning on the inferred sense was given
        self.arc_end: _ArcCheck | None = None  # the last arc, until the move after it
        self.builder = ToolpathBuilder(source)
        self.declared = declared
        self.forced = forced
        # a feed keyword of other units than those given gets one warning, unless the
        # declaration already had one
        self.feed_units_warned = False
        if forced and declared is not None and declared[0] != units:
            self.feed_units_warned = True
            self.builder.warn(declared[1], _forced_message(declared[0], declared[1], units))
        # MSYS: each distinct MCS (in the part frame, mm) with the line that first set it; the
        # frame of the points read now in the program's (the first MCS's) coordinates
        self.separate_mcs = separate_mcs
        self.mcs: list[tuple[Frame, int]] = []
        self.frame: Frame = IDENTITY
        self.largest_cutter: float | None = None
        self.axis_local: tuple[float, float, float] = (0.0, 0.0, 1.0)
        self.axis = self.axis_local
        self.multiaxis = False
        self.rapid_next = False
        self.cycle_on = False  # between CYCLE/<kind> and CYCLE/OFF: GOTOs are holes
        self.feed_value = math.nan
        self.feed_per_rev = False
        self.inverse: tuple[float, int] | None = None  # FEDRAT/INVERS: 1/min, and its line
        self.feed_scale = self.scale
        self.rpm: float | None = None
        self.spindle_direction = "cw"
        self.spindle_on = False
        self.coolant_mode = "flood"
        self.tool_data: dict[str, object] = {}
        # one tool per tool number: the cutter (diameter, corner radius) and the LOADTL LENGTH
        # each number was first given, with its line; the number of the tool loaded
        self.tools_seen: dict[tuple[int, str], tuple[object, int, int]] = {}
        self.loaded: tuple[int, int] | None = None  # the tool's number and its change's line
        # the cutter the moves are made with (diameter, corner radius; None before any) and
        # its line; the line of the first move since the last tool change (None: none yet);
        # a cutter given after that move, with no tool change since (checked at the next move)
        self.cutter_in_use: tuple[tuple[float, float | None] | None, int] = (None, 0)
        self.first_move: int | None = None
        self.late_cutter: tuple[Record, tuple[float, float | None]] | None = None
        self.circle: _PendingCircle | None = None
        self.last_point_on_arc = False
        self.ignored: dict[str, int] = {}
        # records interpreted (a run of k GOTO records counts k), motion records among them,
        # unknown ones and the line of the first: for the refusal of a file of junk
        self.record_count = 0
        self.motion_count = 0
        self.unknown_count = 0
        self.first_unknown = 0
        self.handlers: dict[str, Callable[[Record], None]] = {
            "$$": self._comment,
            "GOTO": self._goto,
            "FROM": self._from,
            "GODLTA": self._godlta,
            "CIRCLE": self._circle,
            "RAPID": self._rapid,
            "CYCLE": self._cycle,
            "FEDRAT": self._fedrat,
            "SPINDL": self._spindl,
            "COOLNT": self._coolnt,
            "LOADTL": self._loadtl,
            "LOAD": self._load,
            "SELECT": self._load,
            "CUTTER": self._cutter,
            "DELAY": self._delay,
            "TLDATA": self._tldata,
            "TOOL PATH": self._tool_path,
            "MSYS": self._msys,
            "MULTAX": self._multax,
            "CUTCOM": self._cutcom,
            "UNITS": self._units,
            "PARTNO": self._text_event("partno"),
            "PPRINT": self._text_event("comment"),
            "INSERT": self._text_event("insert"),
            "GOHOME": self._bare_event("home"),
            "STOP": self._bare_event("stop", optional=False),
            "OPSTOP": self._bare_event("stop", optional=True),
            "END": self._ignore,
            "FINI": self._ignore,
            "PAINT": self._ignore,
            "END-OF-PATH": self._ignore,
        }

    # -- driving --------------------------------------------------------------------------

    def run(self, records: Sequence[Record | GotoRun]) -> None:
        """Interpret ``records`` in order, those of a whole file."""
        for record in records:
            self.step(record)
        self.finish()

    def step(self, record: Record | GotoRun) -> None:
        """Interpret one record (or run of GOTO records)."""
        if self.first_move is None or self.late_cutter is not None:
            if isinstance(record, GotoRun) or record.word in _MOTION_WORDS:
                self._moving(record.line)
        if isinstance(record, GotoRun):
            self.record_count += record.line_count
            self.motion_count += len(record)
            self._goto_run(record)
            return
        self.record_count += 1
        self.motion_count += record.word in _MOTION_WORDS
        if self.circle is not None and record.word not in ("GOTO", "PAINT", "$$"):
            raise CLDataError(
                self.source,
                self.circle.line,
                f"expected a GOTO after CIRCLE, got '{quote(record.text)}' on line {record.line}",
            )
        self.handlers.get(record.word, self._unknown)(record)

    def finish(self) -> None:
        """Check the end of the file: it is CL data (:meth:`_check_not_junk`), no CIRCLE waits
        for its GOTO; warn when the figures (feeds, cutter, extents) look like the other unit
        (:func:`~urdfpost.units.units_doubt`).

        Raises
        ------
        CLDataError
            For a file that is mostly not CL data, or when a CIRCLE has no GOTO after it.
        """
        self._check_not_junk()
        if self.circle is not None:
            raise CLDataError(
                self.source, self.circle.line, "expected a GOTO after CIRCLE, got the end of file"
            )
        self._check_arc(None, Motion.FEED)
        if self.ignored:
            logger.debug("%s: ignored records %s", self.source, self.ignored)
        self._check_units()

    def _check_units(self) -> None:
        """One warning when the data, read in the file's units, look like the other unit."""
        units, scale = self.file_units, scale_of(self.file_units)
        extent, fastest = self.builder.figures()
        doubt = units_doubt(
            units,
            feed=None if fastest is None else fastest / scale,
            cutter=None if self.largest_cutter is None else self.largest_cutter / scale,
            extent=None if extent is None else extent / scale,
        )
        if doubt is None:
            return
        other = other_units(units)
        if self.forced:
            line, read = 1, f"read in {units} (--cl-units)"
        elif self.declared is not None:
            line, read = self.declared[1], f"says {units} at line {self.declared[1]}"
        else:
            line, read = 1, f"says no units and is read in {units}"
        self.builder.warn(
            line,
            f"CL file {read}, but its figures look like {other}: {doubt}; "
            f"check its units (--cl-units {other} reads it in {other})",
        )

    def _check_not_junk(self) -> None:
        """Refuse a file that is mostly not CL data (random text, a file of another kind).

        It is refused when more than :data:`UNKNOWN_SHARE_REFUSED` of its records are unknown
        and either more than :data:`UNKNOWN_RECORDS_ALLOWED` of them are or it has no motion
        record at all. A real CL file is mostly GOTO records; its few unknown records (a
        machine-specific word) are carried as comments with a warning each.

        Raises
        ------
        CLDataError
            At the first unknown record's line, naming how many of how many are unknown.
        """
        unknown, records = self.unknown_count, self.record_count
        if not unknown or unknown <= UNKNOWN_SHARE_REFUSED * records:
            return
        if unknown <= UNKNOWN_RECORDS_ALLOWED and self.motion_count:
            return
        motion = "" if self.motion_count else "no motion record, and "
        raise CLDataError(
            self.source,
            self.first_unknown,
            f"not a CL file: {motion}{unknown} of {records} records are unknown, the first at "
            f"line {self.first_unknown}; expected APT/CLSF records such as GOTO, FEDRAT, "
            "CIRCLE",
        )

    def error(self, record: Record, message: str) -> CLDataError:
        """A CLDataError for ``record``."""
        return CLDataError(self.source, record.line, message)

    def _unknown(self, record: Record) -> None:
        """A record not understood: an ``unknown`` event (its text, at most
        :data:`~urdfpost.readers._common.COMMENT_CHARS` characters) and a warning."""
        self.unknown_count += 1
        self.first_unknown = self.first_unknown or record.line
        text, cut = shorten(record.text)
        self.builder.add_event("unknown", record.line, text=text)
        self.builder.warn(
            record.line,
            f"unknown record '{quote(record.text)}' carried as a comment{_shortened(cut)}",
        )

    def _carried(self, record: Record, text: str) -> str:
        """The text of a comment carried into the program: ``text``, shortened to
        :data:`~urdfpost.readers._common.COMMENT_CHARS` characters with a warning."""
        kept, cut = shorten(text)
        if cut:
            self.builder.warn(
                record.line, f"{_record_name(record)} carried as a comment{_shortened(cut)}"
            )
        return kept

    def _ignore(self, record: Record) -> None:
        """Records that carry nothing for the program (display, end markers)."""
        self.ignored[record.word] = self.ignored.get(record.word, 0) + 1

    # -- motion ---------------------------------------------------------------------------

    def _point(self, record: Record) -> tuple[tuple[float, float, float], bool]:
        """Tip (mm, workpiece frame) of a GOTO/FROM; updates the modal tool axis.

        Returns
        -------
        tip : tuple of 3 floats, mm
        has_axis : bool
            Whether the record carried its own tool axis.
        """
        args = record.args or []
        if len(args) not in (3, 6):
            raise self.error(record, f"expected 3 or 6 values in {record.word}, got {len(args)}")
        values = [
            parse_number(
                token,
                source=self.source,
                line=record.line,
                what=f"the {ordinal(k)} value of {record.word}",
            )
            for k, token in enumerate(args, start=1)
        ]
        scale = self.scale
        x, y, z = values[0] * scale, values[1] * scale, values[2] * scale
        if not (abs(x) <= MAX_LENGTH_MM and abs(y) <= MAX_LENGTH_MM and abs(z) <= MAX_LENGTH_MM):
            self._check_coordinates(record, values, args)
        tip = self.frame.point((x, y, z))
        if len(values) == 6:
            self.axis_local = unit_vector(values[3:], builder=self.builder, line=record.line)
            self.axis = self.frame.vector(self.axis_local)
            self.multiaxis = True
        return tip, len(values) == 6

    def _check_coordinates(
        self, record: Record, values: Sequence[float], args: Sequence[str], role: str = ""
    ) -> None:
        """Raise the error of the first of x, y, z (``values[:3]``) not finite or too large."""
        check_coordinates(
            values,
            args,
            self.scale,
            units=self.units,
            source=self.source,
            line=record.line,
            record=record.word,
            role=role,
        )

    def _length(self, record: Record, value: float, what: str) -> float:
        """A finite length of ``record`` in mm, checked against :data:`MAX_LENGTH_MM`."""
        return check_length(
            value,
            self.scale,
            units=self.units,
            source=self.source,
            line=record.line,
            what=f"{record.word}: {what}",
        )

    def _current_feed(self) -> float:
        """Feed of a feed move now, mm/min (NaN when unknown)."""
        if not self.feed_per_rev:
            return self.feed_value * self.feed_scale
        if self.rpm is None or not self.spindle_on:
            return math.nan
        return self.feed_value * self.feed_scale * self.rpm

    def _goto(self, record: Record) -> None:
        axis_before = self.axis
        tip, has_axis = self._point(record)
        if self.circle is not None:
            self._finish_arc(record, tip, axis_before, has_axis)
            return
        self._check_arc(tip, Motion.RAPID if self.rapid_next else Motion.FEED)
        if self.rapid_next or self.cycle_on:  # a hole of a cycle: its top, reached at rapid
            self.builder.add_point(tip, self.axis, math.nan, Motion.RAPID, record.line)
            self.rapid_next = False
        else:
            feed = self._move_feed(record, np.array([tip]))
            self.builder.add_point(tip, self.axis, feed, Motion.FEED, record.line)
        self.last_point_on_arc = False

    def _goto_run(self, run: GotoRun) -> None:
        """A run of plain GOTO records (and feed lines): as :meth:`_goto` on each (and
        :meth:`_fedrat`), in bulk where it can be.

        The first record goes alone when it ends an arc or follows RAPID. The others are
        computed with the arithmetic of :meth:`_point` and :meth:`Frame.point` in the same
        order (so bit for bit the same points), and their feeds with that of
        :meth:`_current_feed`; when a value would need a message (not finite, beyond
        :data:`MAX_LENGTH_MM` in mm, a tool axis of zero or non-unit length, a feed a
        FEDRAT record would refuse or warn about), the records are read one by one instead.
        """
        first = 0
        if self.cycle_on or self.inverse is not None:  # holes: few; a feed per move's length
            self._run_records(run, 0)
            return
        if self.circle is not None or self.rapid_next:
            if run.feeds is not None and run.feeds.at[0] == 0:  # (a run cut after a GOTO)
                self._run_records(run, 0)
                return
            self._goto(_first_record(run))
            first = 1
        values = run.values[first:]
        k = values.shape[0]
        if not k:
            return
        feeds = self._run_feeds(run.feeds, first, k)
        points = None if feeds is None else self._bulk_points(values)
        if feeds is None or points is None:
            self._run_records(run, first)
            return
        feed, modal = feeds
        if modal is not None:  # the feed the last feed line sets
            self.feed_value, self.feed_per_rev, self.feed_scale = modal
            self.inverse = None
        tip, axis = points
        self._check_arc(tip[0], Motion.FEED)
        self.builder.add_arrays(
            tip,
            axis,
            feed,
            np.full(k, Motion.FEED, dtype=np.int8),
            run.lines()[first:],
        )
        self.last_point_on_arc = False

    def _run_records(self, run: GotoRun, first: int) -> None:
        """The records of ``run`` from its GOTO record ``first`` on (with the feed lines after
        the GOTO record before it), one by one."""
        records = run.records()
        if first:  # (record i of the run is on line run.line + i)
            records = records[int(run.lines()[first - 1]) - run.line + 1 :]
        for record in records:
            self.handlers.get(record.word, self._unknown)(record)

    def _run_feeds(
        self, feeds: FeedLines | None, first: int, k: int
    ) -> tuple[np.ndarray, tuple[float, bool, float] | None] | None:
        """The feed (mm/min, NaN when unknown) of the GOTO records ``first:first + k`` of a
        run with ``feeds`` between them, shape (k,), and the modal feed the last feed line
        sets (value, per revolution, scale; None without feed lines), for the caller to set;
        None when a feed line would get an error or a warning from :meth:`_fedrat`."""
        if feeds is None or not len(feeds):
            return np.full(k, self._current_feed()), None
        keywords = feeds.keywords
        per_rev, scale = _KEYWORD_PER_REV[keywords], _KEYWORD_SCALE[keywords]
        if self.forced:  # the keyword's unit is the file's, which the caller overrode
            says_other = (keywords != 0) & ((scale != 1.0) != (self.units == "inch"))
            if says_other.any() and not self.feed_units_warned:  # _fedrat warns
                return None
            scale = np.full(len(feeds), self.scale)
        else:
            scale = np.where(keywords == 0, self.scale, scale)
        value = feeds.values
        feed = value * scale
        rpm = self.rpm
        if not (
            (value > 0.0).all()
            and (np.where(per_rev, feed, 0.0) <= MAX_LENGTH_MM).all()
            and (np.where(per_rev, 0.0, feed) <= MAX_FEED_MM_PER_MIN).all()
        ):
            return None  # not finite, not positive, too fast: _fedrat says so
        if per_rev.any():
            if rpm is None or not self.spindle_on:  # _fedrat warns
                return None
            if not (np.where(per_rev, feed * rpm, 0.0) <= MAX_FEED_MM_PER_MIN).all():
                return None
            feed = np.where(per_rev, feed * rpm, feed)  # _current_feed, term by term
        # the feed of each record: the last feed line before it, else the one in force
        before = np.searchsorted(feeds.at, np.arange(first, first + k), side="right")
        out = np.concatenate([[self._current_feed()], feed])[before]
        return out, (float(value[-1]), bool(per_rev[-1]), float(scale[-1]))

    def _bulk_points(self, values: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        """Tips (mm, workpiece frame) and axes of GOTO values, shape (k, 3) each.

        Updates the modal tool axis as the last record would. None (and no change) when a
        value would get an error or a warning from :meth:`_point`.

        Parameters
        ----------
        values : ndarray, shape (k, 3) or (k, 6)
            Numbers as written.
        """
        # the test of _point on every record at once; the whole array first (one contiguous
        # pass, and tool axis components are small), the coordinates alone when it fails
        scale = self.scale
        if not (_within_bound(values, scale) or _within_bound(values[:, :3], scale)):
            return None
        (a, b, c), (d, e, f), (g, h, i) = self.frame.rotation
        ox, oy, oz = self.frame.origin
        k = values.shape[0]
        with np.errstate(over="ignore", invalid="ignore"):  # as with Python floats: inf, quietly
            x = values[:, 0] * self.scale
            y = values[:, 1] * self.scale
            z = values[:, 2] * self.scale
            tip = np.empty((k, 3))
            tip[:, 0] = ox + a * x + b * y + c * z  # Frame.point, term by term
            tip[:, 1] = oy + d * x + e * y + f * z
            tip[:, 2] = oz + g * x + h * y + i * z
            if values.shape[1] == 3:
                return tip, np.tile(np.asarray(self.axis, dtype=float), (k, 1))
            u, v, w = values[:, 3], values[:, 4], values[:, 5]
            length = np.sqrt(u * u + v * v + w * w)  # unit_vector, term by term
            if not (
                np.isfinite(length).all()
                and (length >= ZERO_AXIS).all()
                and (np.abs(length - 1.0) <= AXIS_LENGTH_SLACK).all()
            ):
                return None
            u, v, w = u / length, v / length, w / length
            axis = np.empty_like(tip)
            axis[:, 0] = a * u + b * v + c * w  # Frame.vector, term by term
            axis[:, 1] = d * u + e * v + f * w
            axis[:, 2] = g * u + h * v + i * w
        self.axis_local = (float(u[-1]), float(v[-1]), float(w[-1]))
        self.axis = self.frame.vector(self.axis_local)
        self.multiaxis = True
        return tip, axis

    def _from(self, record: Record) -> None:
        tip, _ = self._point(record)
        self._check_arc(tip, Motion.RAPID)
        self.builder.add_point(tip, self.axis, math.nan, Motion.RAPID, record.line)
        self.last_point_on_arc = False

    def _godlta(self, record: Record) -> None:
        """``GODLTA/dx,dy,dz``: a move by that much (MCS axes, file units) from the last
        point; ``GODLTA/d``: a move of ``d`` along the tool axis. A feed move, or a rapid
        after RAPID, as a GOTO.

        Raises
        ------
        CLDataError
            For other than 1 or 3 values, one that is not a finite length, or no point
            before it to move from.
        """
        args = record.args or []
        if len(args) not in (1, 3):
            raise self.error(
                record,
                "expected 1 value (a distance along the tool axis) or 3 (dx, dy, dz) in "
                f"GODLTA, got {len(args)}",
            )
        names = ("distance",) if len(args) == 1 else ("dx", "dy", "dz")
        deltas = []
        for k, (token, name) in enumerate(zip(args, names, strict=True), start=1):
            what = f"the {ordinal(k)} value of GODLTA"
            value = parse_number(token, source=self.source, line=record.line, what=what)
            if not math.isfinite(value):
                raise self.error(
                    record, f"expected a finite number for {what}, got '{quote(token.strip())}'"
                )
            deltas.append(self._length(record, value, name))
        start = self.builder.last_tip
        if start is None:
            raise self.error(
                record, "expected a motion before GODLTA (it moves from there), got none"
            )
        if len(deltas) == 1:
            delta = tuple(deltas[0] * a for a in self.axis)
        else:
            delta = self.frame.vector(deltas)
        tip = (start[0] + delta[0], start[1] + delta[1], start[2] + delta[2])
        motion = Motion.RAPID if self.rapid_next else Motion.FEED
        self._check_arc(tip, motion)
        feed = math.nan if self.rapid_next else self._move_feed(record, np.array([tip]))
        self.builder.add_point(tip, self.axis, feed, motion, record.line)
        self.rapid_next = False
        self.last_point_on_arc = False

    def _rapid(self, record: Record) -> None:
        if record.args is not None:
            self._unknown(record)
            return
        self.rapid_next = True

    def _circle(self, record: Record) -> None:
        if self.nx_of_file is not None:  # the arc sense needs the whole file's NX evidence
            self.nx, self.nx_of_file = self.nx_of_file(), None
            self.arc_sense = -1.0 if self.nx else 1.0
        args = record.args or []
        if len(args) < 7:
            raise self.error(record, f"expected at least 7 values in CIRCLE, got {len(args)}")
        values = [
            parse_number(
                token,
                source=self.source,
                line=record.line,
                what=f"the {ordinal(k)} value of CIRCLE",
            )
            for k, token in enumerate(args[:7], start=1)
        ]
        self._check_coordinates(record, values, args, "centre")
        radius = values[6]
        if not (math.isfinite(radius) and radius > 0.0):
            raise self.error(
                record,
                f"expected a positive radius for the 7th value of CIRCLE, got '{quote(args[6])}'",
            )
        radius_mm = self._length(record, radius, "radius")
        axis = unit_vector(values[3:6], builder=self.builder, line=record.line, what="circle axis")
        turns = self._circle_turns(record, args[7:])
        if self.builder.last_tip is None:
            raise self.error(
                record, "expected a motion before CIRCLE (the arc starts there), got none"
            )
        if self.rapid_next:
            self.builder.warn(record.line, "RAPID before CIRCLE ignored: arcs are feed moves")
            self.rapid_next = False
        self._check_arc(None, Motion.FEED)  # an arc after an arc: no linear move to compare
        if not self.sense_noted:
            self.sense_noted = True
            self.builder.warn(
                record.line,
                f"CIRCLE sense inferred, not declared: arcs turn {self._sense_text(1)} "
                f"({self._sense_reason()}); each arc is checked against the feed moves before "
                "and after it",
            )
        world_axis = self.frame.vector(axis)
        self.circle = _PendingCircle(
            line=record.line,
            centre=self.frame.point([v * self.scale for v in values[:3]]),
            rotation_axis=tuple(self.arc_sense * a for a in world_axis),  # type: ignore[arg-type]
            radius=radius_mm,
            turns=turns,
        )

    def _circle_turns(self, record: Record, extra: Sequence[str]) -> int:
        """``TIMES,n`` among the values after the 7th (tolerances etc. are ignored)."""
        turns = 1
        for k, token in enumerate(extra):
            if token.upper() != "TIMES":
                continue
            value = extra[k + 1] if k + 1 < len(extra) else ""
            position = ordinal(8 + k + 1)
            n = parse_number(
                value, source=self.source, line=record.line, what=f"the {position} value of CIRCLE"
            )
            if not (math.isfinite(n) and n >= 1 and n == int(n)):
                raise self.error(
                    record, f"expected a whole number of turns after TIMES, got '{quote(value)}'"
                )
            turns = int(n)
        return turns

    def _finish_arc(
        self,
        record: Record,
        end: tuple[float, float, float],
        axis_before: tuple[float, float, float],
        has_axis: bool,
    ) -> None:
        circle = self.circle
        assert circle is not None
        self.circle = None
        start = self.builder.last_tip
        assert start is not None
        try:
            arc = interpolate_arc(
                start,
                end,
                circle.centre,
                circle.rotation_axis,
                circle.radius,
                turns=circle.turns,
                chord_tolerance=self.chord_tolerance,
            )
        except ArcTooFineError as e:
            raise CLDataError(self.source, circle.line, str(e)) from None
        except ValueError:
            raise CLDataError(
                self.source,
                circle.line,
                "expected the arc's start and end points off the circle axis, got a point on it",
            ) from None
        if arc.radius_error > max(self.chord_tolerance, RADIUS_MISMATCH_WARN):
            self.builder.warn(
                circle.line,
                f"arc end points are {arc.radius_error:.4g} mm off the CIRCLE radius "
                f"{circle.radius:.6g} mm; the arc is blended between them",
            )
        self.arc_end = _ArcCheck(
            circle.line,
            np.asarray(end, dtype=float),
            arc.end_tangent,
            self._incoming_cosine(arc.start_tangent),
        )
        # the arc itself, for a post that writes it as an arc (its points follow the event)
        self.builder.add_event(
            "arc",
            circle.line,
            centre=circle.centre,
            normal=circle.rotation_axis,
            radius=circle.radius,
            points=int(arc.points.shape[0]),
            sweep=arc.sweep,
        )
        feed = self._move_feed(record, arc.points)  # (its start: the point before the event)
        self.builder.add_points(arc.points, axis_before, feed, Motion.FEED, circle.line)
        if has_axis:
            self.builder.set_last_axis(self.axis)
            if float(np.dot(axis_before, self.axis)) < math.cos(1e-6):
                self.builder.warn(
                    record.line,
                    "tool axis changes on an arc; the interpolated points keep the start axis",
                )
        self.last_point_on_arc = True

    def _incoming_cosine(self, tangent: np.ndarray) -> float | None:
        """Cosine between the feed move into the last point and ``tangent``; None when the
        last point is not the end of a linear feed move (or the move is too short)."""
        if (
            self.last_point_on_arc
            or len(self.builder) < 2
            or self.builder.last_motion() != Motion.FEED
        ):
            return None
        before = self.builder.last_tips(2)
        incoming = before[1] - before[0]
        length = float(np.linalg.norm(incoming))
        if not length >= 1e-6:
            return None
        return float(incoming @ tangent) / length

    def _check_arc(self, tip: Sequence[float] | np.ndarray | None, motion: Motion) -> None:
        """Check the sense of the last arc, now that the move after it is known.

        Called before the point ``tip`` is added (None: no linear move follows the arc: a
        CIRCLE, or the end of the file). Each tangent of the arc is compared with the feed
        move that touches it: a cosine of at least :data:`TANGENT_EVIDENCE` agrees with the
        sense, one of at most ``-TANGENT_EVIDENCE`` agrees with the other (the other sense
        turns the same arc the other way round: every tangent reversed). An arc that only
        the other sense continues gets a warning at its CIRCLE line; the sense used stays the
        inferred one (a file's arcs are not turned on the evidence of its neighbouring moves:
        a warning names each arc that disagrees).
        """
        check = self.arc_end
        if check is None:
            return
        self.arc_end = None
        end_cosine = None
        if tip is not None and motion == Motion.FEED:
            outgoing = np.asarray(tip, dtype=float) - check.end
            length = float(np.linalg.norm(outgoing))
            if length >= 1e-6:
                end_cosine = float(outgoing @ check.end_tangent) / length
        cosines = {"start": check.start_cosine, "end": end_cosine}
        known = {k: c for k, c in cosines.items() if c is not None and math.isfinite(c)}
        if any(c >= TANGENT_EVIDENCE for c in known.values()) or not any(
            c <= -TANGENT_EVIDENCE for c in known.values()
        ):
            return
        figures = ", ".join(f"{k} tangent cosine {c:.2f}" for k, c in known.items())
        self.builder.warn(
            check.line,
            f"arc turns against the feed moves around it ({figures}): the other sense, "
            f"{self._sense_text(-1)}, would continue them; the CIRCLE sense was inferred "
            f"({self._sense_reason()}): check the CIRCLE direction convention",
        )

    def _sense_text(self, which: int) -> str:
        """The arc sense in words: the one used (``which`` 1) or the other (-1)."""
        if self.arc_sense * which > 0:
            return "counter-clockwise about the circle axis (right-hand rule), the APT convention"
        return "clockwise about the circle axis, the NX CLSF convention"

    def _sense_reason(self) -> str:
        """Why the sense is the one used: the NX evidence, or its absence."""
        if self.nx is None:
            return "no NX CLSF record in the file"
        line, what = self.nx
        return f"{what} at line {line}"

    # -- feeds, spindle, coolant ----------------------------------------------------------

    def _cycle(self, record: Record) -> None:
        """``CYCLE/<kind>,...`` starts a canned cycle (a ``cycle`` event; the GOTOs after it
        are its holes), ``CYCLE/OFF`` ends it: :func:`parse_cycle`."""
        data = parse_cycle(record, self)
        self.cycle_on = data["cycle"] != "off"
        self.builder.add_event("cycle", record.line, **data)

    def _fedrat(self, record: Record) -> None:
        words, numbers = _split_tokens(record, self.source)
        if words == ["INVERS"]:
            self._inverse_time(record, numbers)
            return
        if any(w not in _FEED_MODES for w in words) or len(words) > 1:
            self._unknown(record)
            return
        if len(numbers) != 1:
            raise self.error(record, f"expected one feed value in FEDRAT, got {len(numbers)}")
        value = numbers[0]
        if not (math.isfinite(value) and value > 0.0):
            raise self.error(record, f"expected a positive feed in FEDRAT, got {value:g}")
        per_rev, feed_scale = _FEED_MODES[words[0]] if words else (False, self.scale)
        if self.forced:  # the keyword's unit is the file's, which the caller overrode
            feed_scale = self.scale
            said = feed_units(record)
            says = None if said is None else said[0]
            if says is not None and says != self.units and not self.feed_units_warned:
                self.feed_units_warned = True
                self.builder.warn(record.line, _forced_message(says, record.line, self.units))
        self._check_feed(record, value, per_rev, feed_scale, self.rpm)
        self.feed_value, self.feed_per_rev, self.feed_scale = value, per_rev, feed_scale
        self.inverse = None
        if per_rev and (self.rpm is None or not self.spindle_on):
            self.builder.warn(
                record.line,
                "feed per revolution with no spindle speed; feed left unset until a SPINDL record",
            )

    def _inverse_time(self, record: Record, numbers: Sequence[float]) -> None:
        """``FEDRAT/INVERS,f``: each feed move after it takes ``1/f`` minutes (until the next
        FEDRAT), so its tool tip moves at ``f`` times its length per minute
        (:meth:`_move_feed`).

        Raises
        ------
        CLDataError
            For anything but one finite number > 0.
        """
        if len(numbers) != 1:
            raise self.error(
                record, f"expected one inverse-time feed in FEDRAT/INVERS, got {len(numbers)}"
            )
        value = numbers[0]
        if not (math.isfinite(value) and value > 0.0):
            raise self.error(
                record, f"expected a positive inverse-time feed in FEDRAT/INVERS, got {value:g}"
            )
        self.inverse = (value, record.line)

    def _move_feed(self, record: Record, tips: np.ndarray) -> float:
        """The feed (mm/min; NaN when unknown) of a feed move from the last point through
        ``tips`` (shape (k, 3), mm): :meth:`_current_feed`, or at an inverse-time feed, the
        length of the move times it.

        Raises
        ------
        CLDataError
            At an inverse-time feed, for a move with no point before it or one that does not
            move the tool tip (its time is what the CL data gives, and the post times a move
            by the feed of its tip), or a feed beyond the fastest accepted.
        """
        if self.inverse is None:
            return self._current_feed()
        inverse, line = self.inverse
        start = self.builder.last_tip
        said = f"at the inverse-time feed of FEDRAT/INVERS,{format_number(inverse)} (line {line})"
        if start is None:
            raise self.error(record, f"a first move {said}: no point before it to time it from")
        path = np.vstack([np.asarray(start, dtype=float), tips])
        length = float(np.linalg.norm(np.diff(path, axis=0), axis=1).sum())
        if not length > _STILL:
            raise self.error(
                record,
                f"a move that does not move the tool tip {said}: the post times each move "
                "by its tip's feed; expected the CL data with feeds per minute (FEDRAT/MMPM)",
            )
        feed = inverse * length
        self._check_feed(record, feed, False, 1.0, None)
        return feed

    def _check_feed(
        self, record: Record, value: float, per_rev: bool, feed_scale: float, rpm: float | None
    ) -> None:
        """Check a feed (``value * feed_scale`` mm/min or mm/rev) against the bounds.

        Raises
        ------
        CLDataError
            For a feed per minute beyond :data:`MAX_FEED_MM_PER_MIN`, a feed per revolution
            beyond :data:`MAX_LENGTH_MM`, or one whose product with ``rpm`` (when known) is
            beyond :data:`MAX_FEED_MM_PER_MIN`.
        """
        feed = value * feed_scale
        units = "mm" if feed_scale == 1.0 else "inch"
        written = f"feed {format_number(value)} {units}/{'rev' if per_rev else 'min'}"
        bound = format_number(MAX_FEED_MM_PER_MIN)
        fastest = f"is beyond the fastest feed urdfpost accepts ({bound} mm/min)"
        if not per_rev:
            if not feed <= MAX_FEED_MM_PER_MIN:
                raise self.error(record, f"{record.word}: {written} {fastest}")
            return
        if not feed <= MAX_LENGTH_MM:
            raise self.error(
                record,
                f"{record.word}: {written} is beyond the largest feed per revolution urdfpost "
                f"accepts ({format_number(MAX_LENGTH_MM)} mm/rev)",
            )
        if rpm is not None and not feed * rpm <= MAX_FEED_MM_PER_MIN:
            raise self.error(
                record, f"{record.word}: {written} at {format_number(rpm)} rpm {fastest}"
            )

    def _spindl(self, record: Record) -> None:
        words, numbers = _split_tokens(record, self.source)
        known = {"RPM", "CLW", "CCLW", "ON", "OFF"}
        if any(w not in known for w in words) or len(numbers) > 1:
            self._unknown(record)
            return
        if "OFF" in words:
            if numbers or len(words) > 1:
                self._unknown(record)
                return
            self.spindle_on = False
            self.builder.add_event("spindle", record.line, rpm=0.0, direction="off")
            return
        if numbers:
            rpm = numbers[0]
            if not (math.isfinite(rpm) and rpm >= 0.0):
                raise self.error(record, f"expected a spindle speed >= 0 in SPINDL, got {rpm:g}")
            if self.feed_per_rev:
                self._check_feed(record, self.feed_value, True, self.feed_scale, rpm)
            self.rpm = rpm
        if "CLW" in words:
            self.spindle_direction = "cw"
        if "CCLW" in words:
            self.spindle_direction = "ccw"
        if self.rpm is None:
            self.builder.warn(record.line, "spindle turned on with no speed programmed yet")
        self.spindle_on = True
        rpm = math.nan if self.rpm is None else self.rpm
        self.builder.add_event("spindle", record.line, rpm=rpm, direction=self.spindle_direction)

    def _coolnt(self, record: Record) -> None:
        words = [a.upper() for a in record.args or ()]
        modes = [w for w in words if w != "ON"]
        if not words or len(modes) > 1 or any(m not in _COOLANT_MODES for m in modes):
            self._unknown(record)
            return
        mode = _COOLANT_MODES[modes[0]] if modes else self.coolant_mode
        if mode != "off":
            self.coolant_mode = mode
        self.builder.add_event("coolant", record.line, mode=mode)

    # -- tools ----------------------------------------------------------------------------

    def _tool_change(self, record: Record, tokens: Sequence[str], position: int) -> None:
        """Tool change: ``tokens[0]`` is the tool number (the ``position``-th value), then
        ``LENGTH,l`` (mm: ``length``) and ``ADJUST,h`` (the length-offset register:
        ``adjust``), each at most once, in any order. Other values get a warning with the line
        and are ignored.

        Raises
        ------
        CLDataError
            For a tool number or an ADJUST register that is not a whole number >= 0 (or is
            missing), a LENGTH that is not a finite length, or LENGTH or ADJUST given twice.
        """
        what = f"the {ordinal(position)} value of {record.word}"
        token = tokens[0] if tokens else ""
        number = parse_number(token, source=self.source, line=record.line, what=what)
        if not (math.isfinite(number) and number >= 0 and number == int(number)):
            raise self.error(record, f"expected a tool number for {what}, got '{quote(token)}'")
        data: dict[str, object] = {"number": int(number), **self.tool_data}
        given: set[str] = set()
        ignored: list[str] = []
        k = 1
        while k < len(tokens):
            word = tokens[k].upper()
            if word not in ("LENGTH", "ADJUST"):
                ignored.append(tokens[k])
                k += 1
                continue
            if word in given:
                raise self.error(record, f"expected one {word} in {record.word}, got two")
            given.add(word)
            what = f"the {ordinal(position + k + 1)} value of {record.word}"
            value = tokens[k + 1] if k + 1 < len(tokens) else ""
            if word == "ADJUST":
                data["adjust"] = self._register(record, value, what)
            else:
                length = parse_number(value, source=self.source, line=record.line, what=what)
                if not math.isfinite(length):
                    raise self.error(
                        record, f"expected a finite tool length for {what}, got '{quote(value)}'"
                    )
                data["length"] = self._length(record, length, "length")
            k += 2
        if ignored:
            self.builder.warn(
                record.line,
                f"{record.word}: '{quote(','.join(ignored))}' after the tool number not "
                "understood; ignored (LENGTH and ADJUST are read)",
            )
        self.tool_data = {}
        seen = self.tools_seen.get((int(number), "LENGTH"))
        if "LENGTH" not in given and seen is not None and seen[0] is not None:
            data["length"] = seen[0]  # the tool loaded again: its LENGTH, given before
        self.builder.add_event("tool", record.line, **data)
        self.loaded = (int(number), record.line)
        self.first_move, self.late_cutter = None, None  # (a cutter given since is the tool's)
        if data.get("diameter") is not None:
            self.cutter_in_use = (_cutter_value(data), record.line)
        if "LENGTH" in given:
            self._one_tool(record, "LENGTH", data["length"])
        elif seen is None:  # (a later LENGTH for this number would make it two tools)
            self.tools_seen[int(number), "LENGTH"] = (None, record.line, record.line)
        if data.get("diameter") is not None:
            self._one_tool(record, "cutter", _cutter_value(data))

    def _register(self, record: Record, token: str, what: str) -> int:
        """The length-offset register after ``ADJUST`` (``what``: which value it is).

        Raises
        ------
        CLDataError
            When ``token`` is missing or not a whole number >= 0.
        """
        expected = (
            f"expected a length-offset register (a whole number >= 0) for {what} after ADJUST"
        )
        if not token:
            raise self.error(record, f"{expected}, got nothing")
        try:
            value = parse_number(token, source=self.source, line=record.line, what=what)
        except CLDataError:
            value = math.nan
        if not (math.isfinite(value) and value >= 0 and value == int(value)):
            raise self.error(record, f"{expected}, got '{quote(token)}'")
        return int(value)

    def _loadtl(self, record: Record) -> None:
        self._tool_change(record, record.args or [], 1)

    def _load(self, record: Record) -> None:
        """NX ``LOAD/TOOL,n[,...]`` and ``SELECT/TOOL,n``."""
        args = record.args or []
        if not args or args[0].upper() != "TOOL":
            self._unknown(record)
            return
        self._tool_change(record, args[1:], 2)

    def _set_cutter(self, record: Record, data: dict[str, float]) -> None:
        self.largest_cutter = max(self.largest_cutter or 0.0, data["diameter"])
        # in the tool event, the cutter's own length (tip to holder) is "cutter_length":
        # "length" there is the gauge length of LOADTL LENGTH
        tool = {("cutter_length" if k == "length" else k): v for k, v in data.items()}
        value = _cutter_value(data)
        if self.builder.amend_last_event("tool", **tool):  # the cutter of the tool just loaded
            self._one_tool(record, "cutter", value)
        elif self.first_move is None and self.loaded is not None:  # (records between)
            self._one_tool(record, "cutter", value)  # the tool's, not the next one's
        else:  # (NX: TLDATA before LOAD/TOOL) for the next tool change
            self.tool_data.update(tool)
        if self.first_move is None:
            self.cutter_in_use = (value, record.line)
        else:  # the next tool's, unless a move comes first (:meth:`_moving`)
            self.late_cutter = (record, value)
        self.builder.add_event("cutter", record.line, **data)

    def _moving(self, line: int) -> None:
        """A move on ``line``: the first of the tool loaded, or the first after a cutter given
        after that (:attr:`late_cutter`).

        Raises
        ------
        CLDataError
            When that cutter is another than the one the tool has moved with: the moves of one
            tool are one cutter's, whole or in pieces (:func:`~urdfpost.posting.tools.tool_cutters`
            takes a tool's cutter from its tool change).
        """
        if self.first_move is None:
            self.first_move = line
        if self.late_cutter is None:
            return
        (record, value), self.late_cutter = self.late_cutter, None
        in_use, since = self.cutter_in_use
        if in_use is not None and _same_tool_value(in_use, value):
            return
        tool = "the job" if self.loaded is None else f"tool {self.loaded[0]}"
        made = "no cutter" if in_use is None else f"{self._said('cutter', in_use)} (line {since})"
        raise self.error(
            record,
            f"{record.word} gives {self._said('cutter', value)} after the first move of {tool} "
            f"(line {self.first_move}), made with {made}, and moves follow with no tool change: "
            "a tool has one cutter; put a tool change before the new cutter, or the cutter "
            "before the tool's first move",
        )

    def _said(self, what: str, value: object) -> str:
        """A cutter (``what`` "cutter": diameter and corner radius, mm) or a LOADTL LENGTH
        (mm, None for none) in words, in the file's units."""
        if what == "LENGTH":
            if value is None:
                return "no LENGTH (the job's tool length)"
            return f"LENGTH {format_number(float(value) / self.scale)}"  # type: ignore[arg-type]
        d, corner = cast(tuple[float, float | None], value)
        text = f"a cutter of diameter {format_number(d / self.scale)}"
        return text + ("" if corner is None else f", corner {format_number(corner / self.scale)}")

    def _one_tool(self, record: Record, what: str, value: object) -> None:
        """Note the cutter (``what`` "cutter": diameter and corner radius, mm) or the LOADTL
        LENGTH (mm) of the tool loaded (a later one of the same tool change replaces it).

        Raises
        ------
        CLDataError
            When another change to the same tool number gave it another: one number, two
            tools (the machine has one tool in that pocket, and every tool's geometry is looked
            up by its number).
        """
        assert self.loaded is not None
        number, change = self.loaded
        seen = self.tools_seen.setdefault((number, what), (value, record.line, change))
        if _same_tool_value(seen[0], value) or seen[2] == change:
            self.tools_seen[number, what] = (value, record.line, change)
            return
        raise self.error(
            record,
            f"tool {number} is {self._said(what, value)} here but {self._said(what, seen[0])} "
            f"at line {seen[1]}: "
            "one tool number for two tools (a machine has one tool in a pocket); give each "
            "tool its own number in the CAM system",
        )

    def _cutter(self, record: Record) -> None:
        args = record.args or []
        if not args or not all(_is_value(a) for a in args):
            self._unknown(record)
            return
        _, values = _split_tokens(record, self.source)
        data = self._tool_geometry(record, values, length_index=6)
        self._set_cutter(record, data)

    def _tldata(self, record: Record) -> None:
        args = record.args or []
        if len(args) < 2 or args[0].upper() != "MILL":
            self._unknown(record)
            return
        sub = Record(record.line, record.word, args[1:], record.text)
        _, values = _split_tokens(sub, self.source)
        self._set_cutter(record, self._tool_geometry(record, values, length_index=2))

    def _tool_geometry(
        self, record: Record, values: Sequence[float], length_index: int
    ) -> dict[str, float]:
        """Diameter, corner radius and length (mm) from the values of CUTTER/TLDATA."""
        for value in values:
            if not (math.isfinite(value) and value >= 0.0):
                raise self.error(
                    record, f"expected tool dimensions >= 0 in {record.word}, got {value:g}"
                )
        data = {"diameter": self._length(record, values[0], "diameter")}
        if len(values) > 1:
            data["corner_radius"] = self._length(record, values[1], "corner radius")
        if len(values) > length_index:
            data["length"] = self._length(record, values[length_index], "length")
        return data

    def _tool_path(self, record: Record) -> None:
        args = record.args or []
        if not args or not args[0]:
            self._unknown(record)
            return
        data = {"name": self._carried(record, args[0])}
        if len(args) >= 3 and args[1].upper() == "TOOL":
            data["tool_name"] = self._carried(record, args[2])
            self.tool_data["name"] = data["tool_name"]
        self.builder.add_event("operation", record.line, **data)

    # -- frames, modes, units -------------------------------------------------------------

    def _msys(self, record: Record) -> None:
        """``MSYS/x,y,z,xi,xj,xk,yi,yj,yk``: where the MCS (the program zero, in which the
        GOTO values are) lies in the part's absolute frame.

        Informative while every MSYS gives one MCS: the points stay as written. After an
        MSYS of another MCS, the points are transformed into the first MCS (with a warning),
        or, with ``separate_mcs``, left in theirs. Either way an ``msys`` event records it.
        """
        args = record.args or []
        if len(args) != 9:
            raise self.error(record, f"expected 9 values in MSYS, got {len(args)}")
        _, v = _split_tokens(record, self.source)
        if not all(math.isfinite(x) for x in v):
            raise self.error(record, f"expected finite numbers in MSYS, got {format_values(v)}")
        origin = [
            self._length(record, x, f"origin {name}") for x, name in zip(v[:3], "xyz", strict=True)
        ]
        try:
            mcs = Frame.from_axes(origin, v[3:6], v[6:9])
        except ValueError:
            raise self.error(
                record,
                f"expected two independent axis vectors in MSYS, got {format_values(v[3:6])} "
                f"and {format_values(v[6:9])}",
            ) from None
        x, y = np.asarray(v[3:6]), np.asarray(v[6:9])
        if abs(float(x @ y)) > 1e-3 * float(np.linalg.norm(x) * np.linalg.norm(y)):
            self.builder.warn(record.line, "MSYS axes are not orthogonal; orthonormalised")
        index = next((k for k, (seen, _) in enumerate(self.mcs) if mcs.near(seen)), None)
        if index is None:
            index = len(self.mcs)
            self.mcs.append((mcs, record.line))
        first, first_line = self.mcs[0]
        transformed = bool(index) and not self.separate_mcs
        self.frame = mcs.in_frame(first) if transformed else IDENTITY
        if index:
            done = (
                "points transformed into the first MCS"
                if transformed
                else f"points left in MCS {index} (separate MCS)"
            )
            self.builder.warn(
                record.line,
                f"MSYS at line {record.line} differs from the first MCS (line {first_line}): "
                f"{done}",
            )
        self.axis = self.frame.vector(self.axis_local)
        self.builder.add_event(
            "msys",
            record.line,
            mcs=index,
            origin=mcs.origin,
            rotation=mcs.rotation,
            transformed=transformed,
            text=self._mcs_text(mcs, index, transformed),
        )
        logger.debug("%s:%d: MSYS %s, MCS %d", self.source, record.line, mcs, index)

    def _mcs_text(self, mcs: Frame, index: int, transformed: bool) -> str:
        """The ``msys`` event's text, lengths in the file's units."""
        scale = self.scale
        (a, _, c), (d, _, f), (g, _, i) = mcs.rotation

        def triple(values: Iterable[float]) -> str:
            return " ".join(format_number(0.0 if abs(u) < 1e-12 else u) for u in values)

        text = (
            f"MCS {index} origin {triple(o / scale for o in mcs.origin)} {self.units}, "
            f"x-axis {triple((a, d, g))}, z-axis {triple((c, f, i))}"
        )
        if transformed:
            text += ": points transformed into MCS 0"
        return text

    def _multax(self, record: Record) -> None:
        mode = [a.upper() for a in record.args] if record.args is not None else ["ON"]
        if mode == ["ON"]:
            self.multiaxis = True
        elif mode != ["OFF"]:
            self._unknown(record)

    def _cutcom(self, record: Record) -> None:
        """``CUTCOM/LEFT|RIGHT|OFF`` with, in any order after it, a plane (``XYPLAN``,
        ``ZXPLAN``, ``YZPLAN``), an offset register (a whole number) and ``ON`` (NX writes
        ``CUTCOM/ON,LEFT``): a ``cutcom`` event.

        Raises
        ------
        CLDataError
            No side, two of them, or a value that is none of these.
        """
        sides = {"LEFT": "left", "RIGHT": "right", "OFF": "off"}
        planes = {"XYPLAN": "XY", "ZXPLAN": "ZX", "YZPLAN": "YZ"}
        data: dict[str, object] = {}
        for token in (t.strip().upper() for t in record.args or []):
            if token in sides and "side" not in data:
                data["side"] = sides[token]
            elif token in planes and "plane" not in data:
                data["plane"] = planes[token]
            elif token == "ON":
                continue
            elif re.fullmatch(r"\d+", token) and "register" not in data:
                data["register"] = int(token)
            else:
                raise self.error(
                    record,
                    f"unexpected '{quote(token)}' in CUTCOM; expected CUTCOM/LEFT, RIGHT or OFF, "
                    "then optionally XYPLAN, ZXPLAN or YZPLAN and an offset register",
                )
        if "side" not in data:
            raise self.error(record, "expected LEFT, RIGHT or OFF in CUTCOM, got none")
        self.builder.add_event("cutcom", record.line, **data)

    def _units(self, record: Record) -> None:
        units = _UNITS_WORDS.get(record.args[0].upper()) if record.args else None
        if units is None or len(record.args or ()) != 1:
            self._unknown(record)
            return
        if self.forced:
            declared_here = self.declared is not None and self.declared[1] == record.line
            if units != self.units and not declared_here:  # the declaration has its warning
                self.builder.warn(record.line, _forced_message(units, record.line, self.units))
            return
        if units != self.units:
            self.builder.warn(
                record.line, f"UNITS change from {self.units} to {units}; later values in {units}"
            )
            self.units, self.scale = units, scale_of(units)

    # -- events ---------------------------------------------------------------------------

    def _comment(self, record: Record) -> None:
        if record.rest:
            self.builder.add_event("comment", record.line, text=self._carried(record, record.rest))

    def _text_event(self, kind: str) -> Callable[[Record], None]:
        def handler(record: Record) -> None:
            # INSERT is NC code, verbatim: never cut
            text = record.rest if kind == "insert" else self._carried(record, record.rest)
            self.builder.add_event(kind, record.line, text=text)

        return handler

    def _delay(self, record: Record) -> None:
        """``DELAY/t`` (or ``DELAY/SEC,t``): a dwell of ``t`` seconds; ``DELAY/REV,n``: of
        ``n`` turns of the spindle at the speed programmed (a ``dwell`` event, in seconds).

        Raises
        ------
        CLDataError
            For a time or a count of turns that is not one finite number >= 0, another
            keyword, or turns with the spindle stopped or its speed unknown.
        """
        words, values = _split_tokens(record, self.source)
        if len(values) != 1 or len(words) > 1 or any(w not in ("SEC", "REV") for w in words):
            raise self.error(
                record,
                f"expected DELAY/seconds, DELAY/SEC,seconds or DELAY/REV,turns, got "
                f"'{quote(record.text)}'",
            )
        value = values[0]
        if not (math.isfinite(value) and value >= 0.0):
            raise self.error(record, f"expected a dwell >= 0 in DELAY, got {value:g}")
        if words == ["REV"]:
            if not (self.spindle_on and self.rpm):
                raise self.error(
                    record,
                    "DELAY/REV: a dwell in spindle turns with the spindle "
                    + ("stopped" if not self.spindle_on else "speed unknown")
                    + "; expected a SPINDL with its speed before it, or DELAY/seconds",
                )
            value = 60.0 * value / self.rpm
        self.builder.add_event("dwell", record.line, seconds=value)

    def _bare_event(self, kind: str, **data: object) -> Callable[[Record], None]:
        def handler(record: Record) -> None:
            if record.args is not None:
                self._unknown(record)
                return
            self.builder.add_event(kind, record.line, **data)

        return handler


def _shortened(cut: int) -> str:
    """The end of the warning about a carried comment that was shortened by ``cut``
    characters ("" when it was not)."""
    if not cut:
        return ""
    return f", shortened to its first {COMMENT_CHARS} characters ({cut} more dropped)"


def _record_name(record: Record) -> str:
    """How a warning names a record: "$$ comment", "PPRINT", "TOOL PATH"."""
    return "$$ comment" if record.word == "$$" else record.word


def _read_units(units: str | None, declared: tuple[str, int] | None) -> str:
    """The units a file is read in: those given (``units``), else those it declares
    (``declared``: units and line), else mm."""
    if units is not None or declared is None:
        return normalise_units(units)
    return declared[0]


def _forced_message(says: str, line: int, units: str) -> str:
    """The warning for a file that says ``says`` at ``line`` and is read in ``units``."""
    return f"CL file says {says} at line {line}; read as {units} (--cl-units)"


def _within_bound(values: np.ndarray, scale: float) -> bool:
    """Whether ``abs(v * scale) <= MAX_LENGTH_MM`` for every ``v`` of ``values``.

    The test of :meth:`_AptInterpreter._point` on a whole array, with the same result: scaling
    by a positive factor keeps the order, so the largest ``abs(v * scale)`` is that of the
    largest or the smallest ``v``. False when a value is NaN (the extremes are NaN).
    """
    return (
        float(values.max()) * scale <= MAX_LENGTH_MM
        and -float(values.min()) * scale <= MAX_LENGTH_MM
    )


def _first_record(run: GotoRun) -> Record:
    """The first record of a run, as :func:`scan_records` makes it."""
    end = run.text.find("\n", run.start)
    end = len(run.text) if end < 0 else end
    code = run.text[run.start : end].strip().partition("$$")[0].rstrip()
    return parse_record(code, run.line)


def _is_value(token: str) -> bool:
    """Whether a token is meant as a number (not a keyword)."""
    return not (_KEYWORD.fullmatch(token) and token.upper() not in _NOT_KEYWORDS)


def read_apt_text(
    text: str,
    *,
    source: str = "<string>",
    units: str | None = None,
    chord_tolerance: float = 0.001,
    separate_mcs: bool = False,
) -> Toolpath:
    """Read APT / CATIA / Creo / NX CLSF cutter-location data.

    Parameters
    ----------
    text : str
        Whole file contents.
    source : str
        File name for messages.
    units : str, optional
        "mm" or "inch": the units of the values, whatever the file says (a file that declares
        others gets the warning "CL file says inch at line L; read as mm (--cl-units)", and
        its feed keywords, ``IPM`` or ``MMPM``, give the feed mode only; the first of other
        units gets the same warning unless the declaration had one). None: the units the
        file declares (``UNITS/``, else the first ``IPM``/``MMPM``/``IPR``/``MMPR``), else mm.
    chord_tolerance : float, mm
        Largest chord error of the points interpolated on CIRCLE arcs.
    separate_mcs : bool
        After an ``MSYS`` of an MCS other than the first, leave the points in that MCS (its
        ``msys`` event marks the change) instead of transforming them into the first MCS.

    Returns
    -------
    Toolpath
        Tips in mm in the program's coordinates (the first MCS: GOTO values as written), unit
        axes, feeds in mm/min. Its ``units`` are those the values were read in.

    Raises
    ------
    CLDataError
        For data that cannot be read (message names the line and what was expected).
    """
    normalise_units(units)  # bad units refused before reading
    if not (math.isfinite(chord_tolerance) and chord_tolerance > 0.0):
        raise ValueError(f"chord_tolerance: expected a positive length, got {chord_tolerance!r}")
    scan = scan_text(text, source)
    declared = _file_units(scan.records)
    file_units = _read_units(units, declared)
    nx = nx_evidence(scan.records, scan.first_listing)
    runs = [r for r in scan.records if isinstance(r, GotoRun)]
    logger.debug(
        "%s: %d records (%d GOTO in %d runs read in bulk), units %s, dialect %s, "
        "%d listing lines skipped, %d trailing $$ comments ignored",
        source,
        len(scan.records) - len(runs) + sum(len(r) for r in runs),
        sum(len(r) for r in runs),
        len(runs),
        file_units,
        "NX CLSF" if nx else "APT",
        scan.listing_lines,
        scan.trailing_comments,
    )
    interpreter = _AptInterpreter(
        source,
        file_units,
        chord_tolerance,
        nx,
        declared=declared,
        forced=units is not None,
        separate_mcs=separate_mcs,
    )
    interpreter.run(scan.records)
    if scan.after_fini:
        interpreter.builder.warn(
            scan.after_fini[0],
            f"{len(scan.after_fini)} non-blank line(s) after FINI ignored",
        )
    return interpreter.builder.build(units=file_units, multiaxis=interpreter.multiaxis)


# -- a file in pieces ------------------------------------------------------------------------------

#: Characters of text scanned into records at a time, and of the runs of GOTO lines read in
#: bulk: bounds the records held and the parser's temporary copies (4 bytes a character) to a
#: few times this, whatever the text piece.
_STREAM_PART = 1 << 18
#: Characters a GOTO line needs before it may be passed over by the pre-scan: one that holds
#: none of them cannot continue onto the next line, start a comment or name feed units.
_NOTABLE = ("$", "P", "p")
#: Blocks of lines the pre-scan passes over: GOTO records (any case and blanks) with none of
#: :data:`_NOTABLE`, which can say nothing of the file's units or dialect.
_PLAIN_GOTO_LINES = re.compile(
    r"(?:^[ \t]*(?:[Gg][Oo][Tt][Oo]|[Ff][Ee][Dd][Rr][Aa][Tt])[ \t]*/[^$Pp\n]*(?:\n|\Z))+", re.M
)
#: :data:`_PLAIN_GOTO_LINES`, and any one-line FEDRAT record: once the units are known.
_PLAIN_MOTION_LINES = re.compile(
    r"(?:^[ \t]*(?:[Gg][Oo][Tt][Oo][ \t]*/[^$Pp\n]*|[Ff][Ee][Dd][Rr][Aa][Tt][ \t]*/[^$\n]*)"
    r"(?:\n|\Z))+",
    re.M,
)


def _apt_parts(source: str, text_piece: int) -> Iterator[str]:
    """The text of a file with ``\\n`` line breaks, in parts of about :data:`_STREAM_PART`
    characters (longer for a longer line) cut after line breaks; no reference kept to the
    earlier ones."""
    for piece in text_pieces(source, text_piece):
        text = normalise_breaks(piece)
        del piece
        yield from split_parts(text, _STREAM_PART)
        del text


def _apt_facts(
    source: str, size: int, *, whole: bool = True
) -> tuple[tuple[str, int] | None, tuple[int, str] | None, bool]:
    """What an APT file says of itself before FINI: declared units and NX dialect.

    The records are those of :func:`~urdfpost.readers.apt.scan_text`, except that blocks of
    :data:`_PLAIN_GOTO_LINES` are passed over (as one record each they could only be GOTO or
    FEDRAT records with no feed-unit keyword), and once the units are known, those of
    :data:`_PLAIN_MOTION_LINES` (FEDRAT records with a feed-unit keyword too: feed-optimised
    data has one before every move).

    With ``whole`` False the pass stops after the part of the file in which it finds the
    first UNITS record: the units are known then, and so is the NX evidence if that part
    has it; otherwise the evidence (which only the arc sense depends on) is left for a whole
    pass at the first CIRCLE, and the end of the file for the reader's own scan.

    Returns
    -------
    units : tuple of (str, int), or None
        As ``_file_units`` of the whole file: the units of the first UNITS record, else of the
        first feed-unit keyword, and its line; else None.
    nx : tuple of (int, str), or None
        As :func:`nx_evidence` of the whole file: where it first shows that it is an NX CLSF
        listing (a listing line or an NX-only record); None when it does not (or, with
        ``whole`` False and ``complete`` False, not in the part looked at).
    complete : bool
        Whether ``nx`` is that of the whole file (the pass read it to its end, or to FINI, or
        found the evidence).

    Raises
    ------
    CLDataError
        When the file ends inside a continued record (as the whole-file reader raises it,
        before any record is interpreted; a pass that stops early does not look there).
    """
    scanner = _Scanner(source)
    declared: tuple[str, int] | None = None
    in_feeds: tuple[str, int] | None = None
    nx: tuple[int, str] | None = None
    line = 1
    compiled = KERNELS.wanted(_file_size(source))
    for text in _apt_parts(source, size):
        known = declared is not None or in_feeds is not None  # then FEDRAT says nothing more
        count, plain = _plain_facts(text, compiled, known)
        if not (scanner.pending is None and plain):
            _prescan_piece(scanner, text, line, _PLAIN_MOTION_LINES if known else None)
        for record in scanner.scan.records:
            if declared is None and (units := declared_units(record)):
                declared = (units, record.line)
            if in_feeds is None:
                in_feeds = feed_units(record)
        nx = nx or nx_evidence(scanner.scan.records)
        scanner.scan.records.clear()
        if scanner.fini:
            break
        if not whole and declared is not None:  # the units known: the rest is the reader's
            listing = scanner.scan.first_listing
            if listing and (nx is None or listing < nx[0]):
                nx = (listing, "an NX listing line")
            return declared, nx, nx is not None
        line += count
        del text
    scan = scanner.finish()
    if scan.first_listing and (nx is None or scan.first_listing < nx[0]):
        nx = (scan.first_listing, "an NX listing line")
    return declared or in_feeds, nx, True


def _plain_facts(text: str, compiled: bool, feeds: bool = False) -> tuple[int, bool]:
    """The lines of ``text`` (:func:`~urdfpost.readers._stream.line_count`) and
    :func:`_only_plain_gotos` of them (with ``feeds``); by a compiled loop when ``compiled``
    and numba is there (:func:`urdfpost.readers._goto_kernel.plain_goto_lines`)."""
    got = None
    if compiled:
        got = _compiled("plain_goto_lines", _bytes_of(text), feeds)
    if got is not None:
        return int(got[0]), bool(got[1])
    count = line_count(text)
    return count, _only_plain_gotos(text, count, feeds)


def _only_plain_gotos(text: str, count: int, feeds: bool = False) -> bool:
    """Whether all ``count`` lines of ``text`` start with ``GOTO/`` (blanks allowed before the
    slash; or, with ``feeds``, ``FEDRAT/``) and none holds any of :data:`_NOTABLE` (``P`` and
    ``p`` are allowed in a FEDRAT line: a quick test for most of a large file)."""
    heads = text.count("\nGOTO/") + text.startswith("GOTO/")
    if heads != count:  # (blanks before a slash: CATIA's GOTO  /)
        heads = len(_GOTO_HEAD.findall(text))
    if feeds:
        heads += text.count("\nFEDRAT/") + text.startswith("FEDRAT/")
    if not (heads == count and "$" not in text):
        return False
    rest = _FEED_LINE_START.sub("", text) if feeds else text  # (lines start with GOTO/)
    return not any(c in rest for c in _NOTABLE)


def _prescan_piece(
    scanner: _Scanner, text: str, line: int, passed: re.Pattern[str] | None = None
) -> None:
    """Scan the lines of ``text`` (``\\n`` breaks; its first line is ``line``) into
    ``scanner``, passing over the blocks of ``passed`` (default :data:`_PLAIN_GOTO_LINES`)."""
    pos = 0
    for block in (passed or _PLAIN_GOTO_LINES).finditer(text):
        start, end = block.span()
        if start > pos:
            lines = text[pos : start - 1].split("\n")
            scanner.feed(lines, line)
            if scanner.fini:
                return
            line += len(lines)
        if scanner.pending is not None:  # its first line ends a continued record
            first_end = text.find("\n", start, end)
            scanner.feed([text[start : end if first_end < 0 else first_end]], line)
            if scanner.fini:
                return
        line += text.count("\n", start, end) + (text[end - 1] != "\n")
        pos = end
    if pos < len(text):
        scanner.feed(text[pos:].split("\n"), line)


def _after_fini(lines: Iterable[str], first: int) -> tuple[int, int]:
    """The lines after FINI that the whole-file reader warns about: the first one's number
    (0 for none) and how many there are; ``lines`` are numbered from ``first``."""
    number, count = 0, 0
    for k, raw in enumerate(lines, start=first):
        stripped = raw.strip()
        if stripped and not skipped_line(stripped):
            number, count = number or k, count + 1
    return number, count


def _first_point_of(record: Record | GotoRun, before: int, after: int) -> int:
    """Index of the first point made by ``record``, which added points ``before:after``.

    The points of an arc but its last are made by the CIRCLE record; the GOTO that ends it
    makes the last one. A record that makes no point gives the index of the next one.
    """
    if isinstance(record, GotoRun):  # one point per record, but the first may end an arc
        return after - len(record)
    return max(before, after - 1)


def _file_size(source: str) -> int:
    """Bytes of the file ``source`` (0 when it cannot be told: the reading will say why)."""
    try:
        return os.path.getsize(source)
    except OSError:
        return 0


def read_apt_stream(
    source: str,
    *,
    max_points: int,
    units: str | None,
    chord_tolerance: float,
    text_piece: int,
    separate_mcs: bool = False,
) -> Iterator[Toolpath]:
    """:func:`read_apt_text` of a file, in pieces (``FORMAT.read_stream``)."""
    normalise_units(units)  # bad units refused before reading
    check_chord_tolerance(chord_tolerance)
    declared, nx, complete = _apt_facts(source, text_piece, whole=False)
    file_units = _read_units(units, declared)
    logger.debug("%s: units %s, dialect %s", source, file_units, "NX CLSF" if nx else "APT")
    interpreter = _AptInterpreter(
        source,
        file_units,
        chord_tolerance,
        nx,
        declared=declared,
        forced=units is not None,
        separate_mcs=separate_mcs,
    )
    if not complete:  # (the file's start had no NX evidence: the first CIRCLE asks)
        interpreter.nx_of_file = lambda: _apt_facts(source, text_piece)[1]
    try:
        yield from _stream_records(
            source, interpreter, file_units, max_points=max_points, text_piece=text_piece
        )
    except CLDataError:
        if not complete:  # a continued record cut off by the file's end is said first, as
            _apt_facts(source, text_piece)  # the whole-file reader says it (it raises)
        raise


def _stream_records(
    source: str,
    interpreter: _AptInterpreter,
    file_units: str,
    *,
    max_points: int,
    text_piece: int,
) -> Iterator[Toolpath]:
    """The pieces of :func:`read_apt_stream`: the file's records scanned and interpreted by
    ``interpreter``, part by part."""
    builder = interpreter.builder
    scanner = _Scanner(source)
    compiled = KERNELS.wanted(_file_size(source))
    multiaxis_from: int | None = None
    after, count_after = 0, 0  # first line after FINI to warn about, and how many
    line = 1
    parts = _apt_parts(source, text_piece)
    for part in parts:
        rest = scan_piece(scanner, part, line, _STREAM_PART, compiled=compiled)
        records, scanner.scan.records = scanner.scan.records, []
        line = scanner.line if rest is None else line + part.count("\n")
        del part  # the records hold what they need of it
        for record in records:
            before = len(builder)
            interpreter.step(record)
            if multiaxis_from is None and interpreter.multiaxis:
                multiaxis_from = _first_point_of(record, before, len(builder))
            if builder.held > max_points + KEEP - 1:
                yield from hand_out(builder, max_points, file_units, multiaxis_from, KEEP - 1)
        del records
        if rest is not None:  # FINI: the rest of the file is only looked at for the warning
            after, count_after = _after_fini(rest, scanner.fini + 1)
            for part in parts:
                number, count = _after_fini(iter_lines(part), line)
                after, count_after = after or number, count_after + count
                line += part.count("\n")
            break
    scanner.finish()  # the pre-scan found any record left open by the end of the file
    interpreter.finish()
    if after:
        builder.warn(after, f"{count_after} non-blank line(s) after FINI ignored")
    logger.debug(
        "%s: %d points, %d listing lines skipped, %d trailing $$ comments ignored",
        source,
        len(builder),
        scanner.scan.listing_lines,
        scanner.scan.trailing_comments,
    )
    yield from last_pieces(builder, max_points, file_units, multiaxis_from, interpreter.multiaxis)


FORMAT = Format(
    name="apt",
    description="APT-family records (generic APT, CATIA, Creo, Siemens NX CLSF listings)",
    read_text=read_apt_text,
    read_stream=read_apt_stream,
    detect=detect_apt,
    arcs=True,
)
