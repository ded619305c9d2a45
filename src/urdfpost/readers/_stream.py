"""Streaming CL readers: a file read in text pieces, its toolpath handed out in pieces.

A file is read from disk in pieces of about ``text_piece`` characters, each cut after a line
break (never between CR and LF), so that no piece starts inside a line. The readers keep the
state of the whole-file readers from piece to piece: the APT scanner its continued record, the
APT interpreter its modal state (feed, units, tool, tool axis, frame, pending RAPID and
CIRCLE, last points), the plain reader its tool axis, and both the line number. A
:class:`~urdfpost.readers._common.ToolpathBuilder` collects the points and hands them out with
:meth:`~urdfpost.readers._common.ToolpathBuilder.take` as soon as more than a piece is held.

What an APT reader needs from the whole file before it can interpret the first record (the
file's units, NX dialect, a continued record cut off by the end of the file) comes from a
quick pre-scan (:func:`_apt_facts`) that passes over the runs of plain GOTO lines without
parsing them.
"""

from __future__ import annotations

import itertools
import logging
import math
import re
from collections.abc import Callable, Iterable, Iterator

from urdfpost.errors import CLDataError
from urdfpost.toolpath import Toolpath

from ._common import ToolpathBuilder, normalise_units
from ._encoding import HEAD_BYTES, check_text, encoding_of
from .apt import (
    APT_LINE,
    GotoRun,
    Record,
    _AptInterpreter,
    _Scanner,
    declared_units,
    feed_units,
    is_nx_record,
    normalise_breaks,
    scan_piece,
    skipped_line,
)
from .plain import PlainReader

logger = logging.getLogger(__name__)

__all__ = ["STREAM_READERS", "check_chord_tolerance", "detect_file_format", "text_pieces"]

#: Points a builder keeps after handing out a piece: a CIRCLE looks back at the last two tips
#: (to check the arc's start direction).
_KEEP = 2
#: Characters of text scanned into records at a time, and of the runs of GOTO lines read in
#: bulk: bounds the records held and the parser's temporary copies (4 bytes a character) to a
#: few times this, whatever the text piece.
_BULK_PIECE = 1 << 18
#: Characters a GOTO line needs before it may be passed over by the pre-scan: one that holds
#: none of them cannot continue onto the next line, start a comment or name feed units.
_NOTABLE = ("$", "P", "p")
#: Blocks of lines the pre-scan passes over: GOTO records (any case and blanks) with none of
#: :data:`_NOTABLE`, which can say nothing of the file's units or dialect.
_PLAIN_GOTO_LINES = re.compile(r"(?:^[ \t]*[Gg][Oo][Tt][Oo][ \t]*/[^$Pp\n]*(?:\n|\Z))+", re.M)


def text_pieces(source: str, size: int) -> Iterator[str]:
    """The text of a file in pieces cut at line breaks, decoded as
    :func:`~urdfpost.readers.read_cl` decodes it (UTF-8, or UTF-16/32 with a byte-order mark;
    undecodable bytes replaced; a NUL byte is an error at its line).

    Parameters
    ----------
    source : str
        The file.
    size : int
        Bytes read at a time (characters, for ASCII text); a piece is the text up to the last
        line break read so far (so it is longer than ``size`` when a line is).

    Yields
    ------
    str
        Consecutive pieces of the text :func:`~urdfpost.readers.read_cl` reads, line breaks
        as written; every piece but the last ends with ``\\n`` or ``\\r``, and a CR LF pair
        is never cut.

    Raises
    ------
    CLDataError
        When the file cannot be read (line 0), as :func:`~urdfpost.readers.read_cl` says it.
    """
    # The bytes are read into one buffer and decoded here, up to the last line break: no copy
    # of a piece but its text (a text file object's read(size) holds several). A line break
    # is one ASCII byte, never part of a character, so text decoded piece by piece is the
    # text decoded at once.
    try:
        handle = open(source, "rb")
    except OSError as exc:
        raise CLDataError(source, 0, f"cannot read: {exc.strerror or exc}") from exc
    with handle:
        try:
            codec, mark = encoding_of(handle.read(HEAD_BYTES))
            handle.seek(mark)
        except OSError as exc:
            raise CLDataError(source, 0, f"cannot read: {exc.strerror or exc}") from exc
        if codec != "utf-8":
            handle.close()
            yield from _wide_text_pieces(source, codec, size)
            return
        buffer = bytearray(size)
        filled = 0  # bytes of the buffer read and not yet handed out
        offset = mark  # of the buffer's start in the file
        while True:
            if filled == len(buffer):  # a line longer than the buffer: make room
                buffer.extend(bytes(len(buffer)))
            try:
                with memoryview(buffer) as view:
                    got = handle.readinto(view[filled : filled + size])
            except OSError as exc:
                raise CLDataError(source, 0, f"cannot read: {exc.strerror or exc}") from exc
            if not got:
                break
            filled += got
            # a CR at the very end may be the first half of CR LF: not a place to cut yet
            cut = max(buffer.rfind(b"\n", 0, filled), buffer.rfind(b"\r", 0, filled - 1)) + 1
            if not cut:
                continue
            with memoryview(buffer) as view:
                text = str(view[:cut], "utf-8", "replace")
            if "\x00" in text:
                check_text(text, source, _line_at(source, offset))
            buffer[: filled - cut] = buffer[cut:filled]
            filled -= cut
            offset += cut
            if text:
                yield text
            del text  # hold no reference to the piece while the caller works on it
        with memoryview(buffer) as view:
            text = str(view[:filled], "utf-8", "replace")
        if "\x00" in text:
            check_text(text, source, _line_at(source, offset))
        if text:
            yield text


def _line_at(source: str, offset: int) -> int:
    """Number of the line that starts at byte ``offset`` of a UTF-8 file (for a message)."""
    with open(source, "rb") as handle:
        head = handle.read(offset)
    return head.count(b"\n") + head.count(b"\r") - head.count(b"\r\n") + 1


def _wide_text_pieces(source: str, codec: str, size: int) -> Iterator[str]:
    """:func:`text_pieces` of a UTF-16 or UTF-32 file (it has a byte-order mark)."""
    try:
        handle = open(source, encoding=codec, errors="replace", newline="")
    except OSError as exc:  # pragma: no cover - it was just opened
        raise CLDataError(source, 0, f"cannot read: {exc.strerror or exc}") from exc
    with handle:
        rest, line = "", 1
        while True:
            try:
                got = handle.read(size)
            except OSError as exc:
                raise CLDataError(source, 0, f"cannot read: {exc.strerror or exc}") from exc
            if line == 1 and not rest:
                got = got.removeprefix("\ufeff")
            if not got:
                break
            rest += got
            cut = max(rest.rfind("\n"), rest.rfind("\r", 0, len(rest) - 1)) + 1
            if not cut:
                continue
            text, rest = rest[:cut], rest[cut:]
            check_text(text, source, line)
            line += text.count("\n") + text.count("\r") - text.count("\r\n")
            yield text
        if rest:
            yield check_text(rest, source, line)


def _line_count(text: str) -> int:
    """Lines of a piece of text with ``\\n`` line breaks that starts at a line's start."""
    return text.count("\n") + (not text.endswith("\n"))


def _lines(text: str) -> Iterator[str]:
    """The lines of a piece of text with ``\\n`` line breaks (one at a time, without them).

    A piece that ends with a line break has no line after it: :func:`_line_count` lines.
    """
    pos, size = 0, len(text)
    while pos < size:
        end = text.find("\n", pos)
        if end < 0:
            yield text[pos:]
            return
        yield text[pos:end]
        pos = end + 1


def _parts(text: str, size: int) -> Iterator[str]:
    """``text`` (``\\n`` line breaks) in parts of about ``size`` characters cut after line
    breaks (bounds the records and arrays made from one part at a time)."""
    start = 0
    while len(text) - start > 2 * size:
        cut = text.find("\n", start + size) + 1
        if not cut:
            break
        yield text[start:cut]
        start = cut
    if start < len(text):
        yield text[start:] if start else text


def detect_file_format(source: str, size: int) -> str:
    """:func:`~urdfpost.readers.detect_format` of a file, read in pieces until it is known.

    An APT file is known at its first record; a plain file is read to the end.
    """
    line_start = True  # whether the piece starts where the whole text has a "^" (after LF)
    for piece in text_pieces(source, size):
        # a record's match ends before its line's break, so it lies in one piece
        if APT_LINE.search(piece, 0 if line_start else 1):
            return "apt"
        line_start = piece.endswith("\n")
    return "plain"


def check_chord_tolerance(chord_tolerance: float) -> float:
    """The chord tolerance (mm), checked as the APT reader checks it.

    Raises
    ------
    ValueError
        When it is not a positive finite length.
    """
    if not (math.isfinite(chord_tolerance) and chord_tolerance > 0.0):
        raise ValueError(f"chord_tolerance: expected a positive length, got {chord_tolerance!r}")
    return chord_tolerance


def _hand_out(
    builder: ToolpathBuilder, max_points: int, units: str, multiaxis_from: int | None, keep: int
) -> Iterator[Toolpath]:
    """Pieces of ``max_points`` points while the builder holds more than ``max_points + keep``.

    ``multiaxis_from`` is the index of the first point made by a record at or after the first
    record that carried a tool axis (None before one): a piece is multi-axis when that point
    is in it or before it.
    """
    while builder.held > max_points + keep:
        end = len(builder) - builder.held + max_points
        multiaxis = multiaxis_from is not None and multiaxis_from < end
        yield builder.take(max_points, units=units, multiaxis=multiaxis)


def _last_pieces(
    builder: ToolpathBuilder,
    max_points: int,
    units: str,
    multiaxis_from: int | None,
    multiaxis: bool,
) -> Iterator[Toolpath]:
    """The pieces of the points still held at the end of the file (at least one piece)."""
    yield from _hand_out(builder, max_points, units, multiaxis_from, 0)
    yield builder.build(units=units, multiaxis=multiaxis)


# -- APT ---------------------------------------------------------------------------------------


def _apt_parts(source: str, text_piece: int) -> Iterator[str]:
    """The text of a file with ``\\n`` line breaks, in parts of about :data:`_BULK_PIECE`
    characters (longer for a longer line) cut after line breaks; no reference kept to the
    earlier ones."""
    for piece in text_pieces(source, text_piece):
        text = normalise_breaks(piece)
        del piece
        yield from _parts(text, _BULK_PIECE)
        del text


def _apt_facts(source: str, size: int) -> tuple[str | None, bool]:
    """What an APT file says of itself before FINI: declared units and NX dialect.

    The records are those of :func:`~urdfpost.readers.apt.scan_text`, except that blocks of
    :data:`_PLAIN_GOTO_LINES` are passed over (as one record each they could only be GOTO
    records with no feed-unit keyword).

    Returns
    -------
    units : str or None
        As ``_file_units`` of the whole file: the first UNITS record, else the first feed-unit
        keyword, else None.
    nx : bool
        Whether the file has NX listing lines or NX-only records.

    Raises
    ------
    CLDataError
        When the file ends inside a continued record (as the whole-file reader raises it,
        before any record is interpreted).
    """
    scanner = _Scanner(source)
    declared: str | None = None
    in_feeds: str | None = None
    nx = False
    line = 1
    for text in _apt_parts(source, size):
        count = _line_count(text)
        if not (scanner.pending is None and _only_plain_gotos(text, count)):
            _prescan_piece(scanner, text, line)
        for record in scanner.scan.records:
            declared = declared or declared_units(record)
            in_feeds = in_feeds or feed_units(record)
            nx = nx or is_nx_record(record)
        scanner.scan.records.clear()
        if scanner.fini:
            break
        line += count
        del text
    scan = scanner.finish()
    return declared or in_feeds, nx or scan.listing_lines > 0


def _only_plain_gotos(text: str, count: int) -> bool:
    """Whether all ``count`` lines of ``text`` start with ``GOTO/`` and none holds any of
    :data:`_NOTABLE` (a quick test for most of a large file)."""
    return (
        text.startswith("GOTO/")
        and text.count("\nGOTO/") == count - 1
        and not any(c in text for c in _NOTABLE)
    )


def _prescan_piece(scanner: _Scanner, text: str, line: int) -> None:
    """Scan the lines of ``text`` (``\\n`` breaks; its first line is ``line``) into
    ``scanner``, passing over the blocks of :data:`_PLAIN_GOTO_LINES`."""
    pos = 0
    for block in _PLAIN_GOTO_LINES.finditer(text):
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


def _stream_apt(
    source: str, *, max_points: int, units: str | None, chord_tolerance: float, text_piece: int
) -> Iterator[Toolpath]:
    """:func:`~urdfpost.readers.apt.read_apt_text` of a file, in pieces."""
    fallback = normalise_units(units)
    check_chord_tolerance(chord_tolerance)
    declared, nx = _apt_facts(source, text_piece)
    file_units = declared or fallback
    logger.debug("%s: units %s, dialect %s", source, file_units, "NX CLSF" if nx else "APT")
    interpreter = _AptInterpreter(source, file_units, chord_tolerance, nx)
    builder = interpreter.builder
    scanner = _Scanner(source)
    multiaxis_from: int | None = None
    after, count_after = 0, 0  # first line after FINI to warn about, and how many
    line = 1
    parts = _apt_parts(source, text_piece)
    for part in parts:
        rest = scan_piece(scanner, part, line, _BULK_PIECE)
        records, scanner.scan.records = scanner.scan.records, []
        line += part.count("\n")
        del part  # the records hold what they need of it
        for record in records:
            before = len(builder)
            interpreter.step(record)
            if multiaxis_from is None and interpreter.multiaxis:
                multiaxis_from = _first_point_of(record, before, len(builder))
            if builder.held > max_points + _KEEP - 1:
                yield from _hand_out(builder, max_points, file_units, multiaxis_from, _KEEP - 1)
        del records
        if rest is not None:  # FINI: the rest of the file is only looked at for the warning
            after, count_after = _after_fini(rest, scanner.fini + 1)
            for part in parts:
                number, count = _after_fini(_lines(part), line)
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
    yield from _last_pieces(builder, max_points, file_units, multiaxis_from, interpreter.multiaxis)


# -- plain -------------------------------------------------------------------------------------


def _stream_plain(
    source: str, *, max_points: int, units: str | None, chord_tolerance: float, text_piece: int
) -> Iterator[Toolpath]:
    """:func:`~urdfpost.readers.plain.read_plain_text` of a file, in pieces."""
    del chord_tolerance  # no arcs, as in read_plain_text
    reader = PlainReader(source, units)
    builder, file_units = reader.builder, reader.units
    line = 1
    for piece in text_pieces(source, text_piece):
        text = normalise_breaks(piece)
        del piece
        count = _line_count(text)
        lines = _lines(text)
        for first in range(line, line + count, max_points):  # a line makes at most one point
            reader.feed(itertools.islice(lines, max_points), first)
            yield from _hand_out(builder, max_points, file_units, reader.multiaxis_from, _KEEP - 1)
        line += count
        del text, lines
    logger.debug("%s: %d points, units %s", source, len(builder), file_units)
    yield from _last_pieces(
        builder, max_points, file_units, reader.multiaxis_from, reader.multiaxis
    )


#: Streaming reader of each format of :data:`~urdfpost.readers.READERS`:
#: ``reader(source, *, max_points, units, chord_tolerance, text_piece) -> Iterator[Toolpath]``.
STREAM_READERS: dict[str, Callable[..., Iterator[Toolpath]]] = {
    "apt": _stream_apt,
    "plain": _stream_plain,
}
