"""Reading a file in text pieces and handing its toolpath out in pieces: what every format's
streaming reader (``Format.read_stream``) shares.

A file is read from disk in pieces of about ``text_piece`` characters, each cut after a line
break (never between CR and LF), so that no piece starts inside a line (:func:`text_pieces`).
Each format's streaming reader (in its own module, beside its whole-file reader) keeps the
state of the whole-file reader from piece to piece: the APT scanner its continued record, the
APT interpreter its modal state (feed, units, tool, tool axis, frame, pending RAPID and
CIRCLE, last points), the plain reader its tool axis, and both the line number. A
:class:`~urdfpost.readers._common.ToolpathBuilder` collects the points and hands them out with
:meth:`~urdfpost.readers._common.ToolpathBuilder.take` as soon as more than a piece is held
(:func:`hand_out`, :func:`last_pieces`).
"""

from __future__ import annotations

import math
from collections.abc import Iterator

from urdfpost.errors import CLDataError
from urdfpost.toolpath import Toolpath

from ._common import ToolpathBuilder
from ._encoding import HEAD_BYTES, check_text, encoding_of

__all__ = [
    "KEEP",
    "check_chord_tolerance",
    "hand_out",
    "iter_lines",
    "last_pieces",
    "line_count",
    "split_parts",
    "text_pieces",
]

#: Points a builder keeps after handing out a piece: a CIRCLE looks back at the last two tips
#: (to check the arc's start direction).
KEEP = 2


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
        mark = True  # the byte-order mark is still to be dropped (once: a second is text)
        while True:
            try:
                got = handle.read(size)
            except OSError as exc:
                raise CLDataError(source, 0, f"cannot read: {exc.strerror or exc}") from exc
            if not got:
                break
            if mark:  # (a piece of one character may be the mark alone: then nothing is left)
                got, mark = got.removeprefix("\ufeff"), False
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


def line_count(text: str) -> int:
    """Lines of a piece of text with ``\\n`` line breaks that starts at a line's start."""
    return text.count("\n") + (not text.endswith("\n"))


def iter_lines(text: str) -> Iterator[str]:
    """The lines of a piece of text with ``\\n`` line breaks (one at a time, without them).

    A piece that ends with a line break has no line after it: :func:`line_count` lines.
    """
    pos, size = 0, len(text)
    while pos < size:
        end = text.find("\n", pos)
        if end < 0:
            yield text[pos:]
            return
        yield text[pos:end]
        pos = end + 1


def split_parts(text: str, size: int) -> Iterator[str]:
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


def hand_out(
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


def last_pieces(
    builder: ToolpathBuilder,
    max_points: int,
    units: str,
    multiaxis_from: int | None,
    multiaxis: bool,
) -> Iterator[Toolpath]:
    """The pieces of the points still held at the end of the file (at least one piece)."""
    yield from hand_out(builder, max_points, units, multiaxis_from, 0)
    yield builder.build(units=units, multiaxis=multiaxis)
