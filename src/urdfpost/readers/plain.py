"""Reader of plain point lists: one ``x y z [i j k]`` point per line.

Values are separated by blanks or commas. Three values keep the previous tool axis (initially
(0, 0, 1)). Text after ``#`` or ``;`` is a comment (a "comment" event). Blank lines are
ignored. Every point is a feed move with no programmed feed (NaN); the file has no units, so
the caller's ``units`` (default "mm") apply.
"""

from __future__ import annotations

import logging
import math
import re

from urdfpost.errors import CLDataError
from urdfpost.toolpath import Motion, Toolpath

from ._common import (
    ToolpathBuilder,
    normalise_units,
    ordinal,
    parse_number,
    scale_of,
    unit_vector,
)
from .apt import split_lines

logger = logging.getLogger(__name__)

__all__ = ["read_plain_text"]

_SEPARATOR = re.compile(r"\s*,\s*|\s+")
_COMMENT = re.compile(r"[#;]")


def read_plain_text(
    text: str,
    *,
    source: str = "<string>",
    units: str | None = None,
    chord_tolerance: float = 0.001,
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

    Returns
    -------
    Toolpath
        Tips in mm, unit axes, feeds NaN, all points FEED.

    Raises
    ------
    CLDataError
        For a line that is not 3 or 6 numbers, or a tool axis of zero length.
    """
    del chord_tolerance
    file_units = normalise_units(units)
    scale = scale_of(file_units)
    builder = ToolpathBuilder(source)
    axis = (0.0, 0.0, 1.0)
    multiaxis = False
    for number, raw in enumerate(split_lines(text), start=1):
        code, comment = _split_comment(raw)
        if comment:
            builder.add_event("comment", number, text=comment)
        if not code:
            continue
        values = _values(code, source, number)
        if len(values) == 6:
            axis = unit_vector(values[3:], builder=builder, line=number)
            multiaxis = True
        tip = tuple(v * scale for v in values[:3])
        builder.add_point(tip, axis, math.nan, Motion.FEED, number)
    logger.debug("%s: %d points, units %s", source, len(builder), file_units)
    return builder.build(units=file_units, multiaxis=multiaxis)


def _split_comment(raw: str) -> tuple[str, str]:
    """Code and comment text of a line (either may be empty)."""
    match = _COMMENT.search(raw)
    if match is None:
        return raw.strip(), ""
    return raw[: match.start()].strip(), raw[match.end() :].strip()


def _values(code: str, source: str, line: int) -> list[float]:
    """The 3 or 6 finite numbers of a point line."""
    tokens = _SEPARATOR.split(code)
    if len(tokens) not in (3, 6):
        raise CLDataError(
            source, line, f"expected 3 or 6 values (x y z [i j k]), got {len(tokens)}"
        )
    values = [
        parse_number(token, source=source, line=line, what=f"the {ordinal(k)} value")
        for k, token in enumerate(tokens, start=1)
    ]
    for k, value in enumerate(values[:3], start=1):
        if not math.isfinite(value):
            raise CLDataError(
                source, line, f"expected a finite number for the {ordinal(k)} value, got '{value}'"
            )
    return values
