"""Reader of plain point lists: one ``x y z [i j k]`` point per line.

Values are separated by blanks or commas. Three values keep the previous tool axis (initially
(0, 0, 1)). Text after ``#`` or ``;`` is a comment (a "comment" event). Blank lines are
ignored. Every point is a feed move with no programmed feed (NaN); the file has no units, so
the caller's ``units`` apply, else mm.

It is the format of text in which no other format is detected (``FORMAT.fallback``).
"""

from __future__ import annotations

import itertools
import logging
import math
import re
from collections.abc import Iterable, Iterator

from urdfpost.errors import CLDataError
from urdfpost.toolpath import Motion, Toolpath

from ._common import (
    MAX_LENGTH_MM,
    ToolpathBuilder,
    check_coordinates,
    normalise_units,
    ordinal,
    parse_number,
    scale_of,
    unit_vector,
)
from ._format import Format
from ._stream import KEEP, hand_out, iter_lines, last_pieces, line_count, text_pieces
from .apt import normalise_breaks, split_lines

logger = logging.getLogger(__name__)

__all__ = ["FORMAT", "PlainReader", "read_plain_stream", "read_plain_text"]

_SEPARATOR = re.compile(r"\s*,\s*|\s+")
_COMMENT = re.compile(r"[#;]")


def read_plain_text(
    text: str,
    *,
    source: str = "<string>",
    units: str | None = None,
    chord_tolerance: float = 0.001,
    separate_mcs: bool = False,
) -> Toolpath:
    """Read a plain list of points.

    Parameters
    ----------
    text : str
        Whole file contents.
    source : str
        File name for messages.
    units : str, optional
        Units of the values ("mm" or "inch"; default "mm").
    chord_tolerance : float, mm
        Unused (plain files have no arcs); accepted for a common reader signature.
    separate_mcs : bool
        Unused (plain files have one coordinate system); accepted for a common signature.

    Returns
    -------
    Toolpath
        Tips in mm, unit axes, feeds NaN, all points FEED.

    Raises
    ------
    CLDataError
        For a line that is not 3 or 6 numbers, or a tool axis of zero length.
    """
    del chord_tolerance, separate_mcs
    reader = PlainReader(source, units)
    reader.feed(split_lines(text), 1)
    return reader.build()


class PlainReader:
    """Reads the lines of a plain point list, a few at a time, keeping the modal tool axis.

    Parameters
    ----------
    source : str
        File name for messages.
    units : str, optional
        Units of the values ("mm" or "inch"; default "mm").

    Attributes
    ----------
    builder : ToolpathBuilder
        The points, events and warnings read so far.
    units : str
        "mm" or "inch".
    multiaxis_from : int or None
        Index of the first point with its own tool axis (None before one).
    """

    def __init__(self, source: str, units: str | None) -> None:
        self.source = source
        self.units = normalise_units(units)
        self.scale = scale_of(self.units)
        self.builder = ToolpathBuilder(source)
        self.axis = (0.0, 0.0, 1.0)
        self.multiaxis_from: int | None = None

    def feed(self, lines: Iterable[str], first: int) -> None:
        """Read ``lines`` (without line breaks), the first of which is line number ``first``.

        Raises
        ------
        CLDataError
            For a line that is not 3 or 6 numbers, a coordinate that is not finite or beyond
            :data:`~urdfpost.readers._common.MAX_LENGTH_MM` in mm, or a tool axis of zero
            length.
        """
        source, scale, builder, axis = self.source, self.scale, self.builder, self.axis
        try:
            for number, raw in enumerate(lines, start=first):
                code, comment = _split_comment(raw)
                if comment:
                    builder.add_event("comment", number, text=comment)
                if not code:
                    continue
                tokens, values = _values(code, source, number)
                x, y, z = values[0] * scale, values[1] * scale, values[2] * scale
                if not (
                    abs(x) <= MAX_LENGTH_MM and abs(y) <= MAX_LENGTH_MM and abs(z) <= MAX_LENGTH_MM
                ):
                    check_coordinates(
                        values,
                        tokens,
                        scale,
                        units=self.units,
                        source=source,
                        line=number,
                        record="",
                    )
                if len(values) == 6:
                    axis = unit_vector(values[3:], builder=builder, line=number)
                    if self.multiaxis_from is None:
                        self.multiaxis_from = len(builder)
                builder.add_point((x, y, z), axis, math.nan, Motion.FEED, number)
        finally:
            self.axis = axis

    @property
    def multiaxis(self) -> bool:
        """Whether any line so far gave a tool axis."""
        return self.multiaxis_from is not None

    def build(self) -> Toolpath:
        """The toolpath of the lines read (after :meth:`ToolpathBuilder.take`: the rest)."""
        logger.debug("%s: %d points, units %s", self.source, len(self.builder), self.units)
        return self.builder.build(units=self.units, multiaxis=self.multiaxis)


def _split_comment(raw: str) -> tuple[str, str]:
    """Code and comment text of a line (either may be empty)."""
    match = _COMMENT.search(raw)
    if match is None:
        return raw.strip(), ""
    return raw[: match.start()].strip(), raw[match.end() :].strip()


def _values(code: str, source: str, line: int) -> tuple[list[str], list[float]]:
    """The tokens and the 3 or 6 numbers of a point line (the coordinates not yet checked)."""
    tokens = _SEPARATOR.split(code)
    if len(tokens) not in (3, 6):
        raise CLDataError(
            source, line, f"expected 3 or 6 values (x y z [i j k]), got {len(tokens)}"
        )
    values = [
        parse_number(token, source=source, line=line, what=f"the {ordinal(k)} value")
        for k, token in enumerate(tokens, start=1)
    ]
    return tokens, values


def read_plain_stream(
    source: str,
    *,
    max_points: int,
    units: str | None,
    chord_tolerance: float,
    text_piece: int,
    separate_mcs: bool = False,
) -> Iterator[Toolpath]:
    """:func:`read_plain_text` of a file, in pieces."""
    del chord_tolerance, separate_mcs  # no arcs and one frame, as in read_plain_text
    reader = PlainReader(source, units)
    builder, file_units = reader.builder, reader.units
    line = 1
    for piece in text_pieces(source, text_piece):
        text = normalise_breaks(piece)
        del piece
        count = line_count(text)
        lines = iter_lines(text)
        for first in range(line, line + count, max_points):  # a line makes at most one point
            reader.feed(itertools.islice(lines, max_points), first)
            yield from hand_out(builder, max_points, file_units, reader.multiaxis_from, KEEP - 1)
        line += count
        del text, lines
    logger.debug("%s: %d points, units %s", source, len(builder), file_units)
    yield from last_pieces(builder, max_points, file_units, reader.multiaxis_from, reader.multiaxis)


FORMAT = Format(
    name="plain",
    description="one x y z [i j k] point per line",
    read_text=read_plain_text,
    read_stream=read_plain_stream,
    fallback=True,
)
