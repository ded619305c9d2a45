"""Helpers shared by the CL readers: number parsing, units, and the toolpath builder.

The builder collects motion points as plain Python lists (cheap to append one at a time) or as
arrays (runs of records read in bulk) and turns them into the arrays of a
:class:`~urdfpost.toolpath.Toolpath` once, at the end.
"""

from __future__ import annotations

import bisect
import math
import re
from collections.abc import Sequence
from typing import Any

import numpy as np

from urdfpost.errors import CLDataError
from urdfpost.toolpath import Event, Motion, Toolpath
from urdfpost.units import mm_per_unit

#: A decimal number as CAM systems write them (``1``, ``-1.5``, ``.5``, ``1.2E-3``); ``nan`` and
#: ``inf`` are accepted as numbers so that the check of their role gives the clearer message.
_NUMBER = re.compile(
    r"[+-]?(?:(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?|nan|inf|infinity)", re.IGNORECASE
)

#: Smallest length of a tool axis (or circle axis) that is not taken as zero.
ZERO_AXIS = 1e-9
#: Relative deviation of an axis length from 1 above which the reader warns before normalising
#: (CL files print 4 to 10 decimals: 1e-3 is far above their rounding).
AXIS_LENGTH_SLACK = 1e-3

#: mm. Largest length a reader accepts after conversion to mm: a coordinate, a circle's centre or
#: radius, a tool's size or length, a frame origin. A kilometre is already absurd for a machine
#: tool; 1e9 mm keeps every later product and sum of lengths far from float overflow (squares
#: stay below 1e18, where 1.8e308 overflows), while an inch value such as 1e308 overflows to inf
#: on conversion. A value beyond it is a :class:`~urdfpost.errors.CLDataError` at its record.
MAX_LENGTH_MM = 1e9
#: mm/min. Fastest feed a reader accepts (after conversion, a feed per revolution times the
#: spindle speed): :data:`MAX_LENGTH_MM` per minute, over 16 km/s. A feed per revolution is a
#: length, bounded by :data:`MAX_LENGTH_MM` per revolution.
MAX_FEED_MM_PER_MIN = MAX_LENGTH_MM

#: Characters of a record's text a message quotes: a junk line of megabytes would otherwise
#: become a warning of megabytes. The rest is counted: "... (N more characters)".
QUOTE_CHARS = 80
#: Characters of text a carried comment keeps (an unknown record, a ``$$`` comment, PPRINT,
#: PARTNO, an NX operation name): more than any real comment, so a real one is never cut,
#: while a junk line does not become a comment of megabytes in the program. The text beyond
#: it is kept nowhere; the record's warning says that it was shortened.
COMMENT_CHARS = 200

_UNIT_NAMES = {"mm": "mm", "inch": "inch", "in": "inch", "inches": "inch"}


def quote(text: str, limit: int = QUOTE_CHARS) -> str:
    """``text`` for a message, at most ``limit`` characters of it.

    Examples
    --------
    >>> quote("GOTO/1,2,3")
    'GOTO/1,2,3'
    >>> quote("x" * 100, 10)
    'xxxxxxxxxx... (90 more characters)'
    """
    if len(text) <= limit:
        return text
    return f"{text[:limit]}... ({len(text) - limit} more characters)"


def shorten(text: str, limit: int = COMMENT_CHARS) -> tuple[str, int]:
    """``text`` cut to ``limit`` characters, and how many were cut off (0 when none).

    Examples
    --------
    >>> shorten("abcdef", 4)
    ('abcd', 2)
    """
    if len(text) <= limit:
        return text, 0
    return text[:limit], len(text) - limit


def ordinal(n: int) -> str:
    """English ordinal of a positive integer: 1st, 2nd, 3rd, 4th, 11th, 21st."""
    if 10 <= n % 100 <= 20:
        suffix = "th"
    else:
        suffix = {1: "st", 2: "nd", 3: "rd"}.get(n % 10, "th")
    return f"{n}{suffix}"


def normalise_units(units: str | None) -> str:
    """Return "mm" or "inch" for a units name (default "mm").

    Raises
    ------
    ValueError
        For a name that is neither.
    """
    if units is None:
        return "mm"
    try:
        return _UNIT_NAMES[units.strip().lower()]
    except KeyError:
        raise ValueError(f"units: expected 'mm' or 'inch', got {units!r}") from None


def scale_of(units: str) -> float:
    """Millimetres per unit of length of ``units`` ("mm" or "inch")."""
    return mm_per_unit(units)


def parse_number(token: str, *, source: str, line: int, what: str) -> float:
    """Parse one number of a record.

    Parameters
    ----------
    token : str
        The text of the value (surrounding blanks are ignored).
    source, line : str, int
        Where the record is, for the error.
    what : str
        Which value it is, e.g. "the 4th value of GOTO".

    Raises
    ------
    CLDataError
        When the text is not a number.
    """
    text = token.strip()
    if not _NUMBER.fullmatch(text):
        raise CLDataError(source, line, f"expected a number for {what}, got '{quote(text)}'")
    return float(text)


def format_number(value: float) -> str:
    """Short text of a number for messages: ``1e308``, ``-2.54e9``, ``0.01``, ``nan``."""
    text = f"{value:.6g}"
    mantissa, e, exponent = text.partition("e")
    return f"{mantissa}e{int(exponent)}" if e else text


def beyond_length(what: str, value: float, units: str) -> str:
    """Message for a length beyond :data:`MAX_LENGTH_MM`.

    Parameters
    ----------
    what : str
        The value's role, e.g. "GOTO: x", "CIRCLE: radius".
    value : float
        The value as written, in ``units``.
    units : str
        Units of the value as written ("mm" or "inch").

    Examples
    --------
    >>> beyond_length("GOTO: x", 1e308, "inch")
    'GOTO: x 1e308 inch is beyond the largest length urdfpost accepts (1e9 mm)'
    """
    return (
        f"{what} {format_number(value)} {units} is beyond the largest length urdfpost accepts "
        f"({format_number(MAX_LENGTH_MM)} mm)"
    )


def check_length(
    value: float, scale: float, *, units: str, source: str, line: int, what: str
) -> float:
    """Convert a length to mm and check it against :data:`MAX_LENGTH_MM`.

    Parameters
    ----------
    value : float
        The length as written, finite.
    scale : float
        Millimetres per unit of ``units``.
    units : str
        Units of ``value`` ("mm" or "inch"), for the message.
    source, line : str, int
        Where the record is, for the error.
    what : str
        The value's role, as for :func:`beyond_length`.

    Returns
    -------
    float, mm
        ``value * scale``.

    Raises
    ------
    CLDataError
        When ``abs(value * scale)`` exceeds :data:`MAX_LENGTH_MM` (or overflows).
    """
    length = value * scale
    if not abs(length) <= MAX_LENGTH_MM:
        raise CLDataError(source, line, beyond_length(what, value, units))
    return length


def check_coordinates(
    values: Sequence[float],
    tokens: Sequence[str],
    scale: float,
    *,
    units: str,
    source: str,
    line: int,
    record: str,
    role: str = "",
) -> None:
    """Raise the error of the first of x, y, z that is not finite or beyond the bound.

    Called when a quick test of a point's three coordinates failed; the checks and messages
    are those of one coordinate at a time, in order.

    Parameters
    ----------
    values : sequence of floats
        The numbers of the record; the first three are x, y, z as written.
    tokens : sequence of str
        Their text, for the message about a value that is not finite.
    scale : float
        Millimetres per unit of ``units``.
    units : str
        Units of the values ("mm" or "inch").
    source, line : str, int
        Where the record is.
    record : str
        Name of the record in messages ("GOTO", "CIRCLE"), or "" for a plain point.
    role : str
        What the point is, when it is not the record's motion ("centre").

    Raises
    ------
    CLDataError
        For the first coordinate that is not finite, or beyond :data:`MAX_LENGTH_MM` in mm.
    """
    of = f" of {record}" if record else ""
    prefix = f"{record}: " if record else ""
    if role:
        prefix += f"{role} "
    for k, name in enumerate("xyz"):
        value = values[k]
        if not math.isfinite(value):
            raise CLDataError(
                source,
                line,
                f"expected a finite number for the {ordinal(k + 1)} value{of}, "
                f"got '{quote(tokens[k].strip())}'",
            )
        check_length(value, scale, units=units, source=source, line=line, what=prefix + name)


def format_values(values: Sequence[float]) -> str:
    """``(0, 0, 0)``-style text of a few numbers, for messages."""
    return "(" + ", ".join(f"{v:g}" for v in values) + ")"


class ToolpathBuilder:
    """Accumulates the points, events and warnings of one file.

    Points come one at a time (:meth:`add_point`, kept in Python lists, cheap to append) or as
    whole arrays (:meth:`add_arrays`, for runs of records read in bulk); both end up in order
    in the arrays of :meth:`build`. A streaming reader hands out the points in pieces with
    :meth:`take` and builds the rest at the end; point indices (``len``, event indices) stay
    those of the whole file.

    Parameters
    ----------
    source : str
        File name used in warnings and in the returned toolpath.
    """

    def __init__(self, source: str) -> None:
        self.source = source
        # points added one at a time since the last chunk
        self._tip: list[float] = []
        self._axis: list[float] = []
        self._feed: list[float] = []
        self._motion: list[int] = []
        self._line: list[int] = []
        # earlier points as arrays: (tip, axis, feed, motion, line) per chunk
        self._chunks: list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = []
        self._chunked = 0
        self._taken = 0  # points handed out by take()
        self.events: list[Event] = []
        self.warnings: list[str] = []
        self._warned_at: list[int] = []  # index of the next point when each warning came
        # box of the tips and fastest feed of every point added (for the units' plausibility)
        self._low = np.full(3, np.inf)
        self._high = np.full(3, -np.inf)
        self._fastest = -np.inf

    def __len__(self) -> int:
        return self._taken + self._chunked + len(self._motion)

    @property
    def held(self) -> int:
        """Points added and not yet handed out by :meth:`take`."""
        return self._chunked + len(self._motion)

    def _flush(self) -> None:
        """Move the points added one at a time into a chunk of arrays."""
        k = len(self._motion)
        if not k:
            return
        self._chunks.append(
            (
                np.asarray(self._tip, dtype=float).reshape(k, 3),
                np.asarray(self._axis, dtype=float).reshape(k, 3),
                np.asarray(self._feed, dtype=float).reshape(k),
                np.asarray(self._motion, dtype=np.int8).reshape(k),
                np.asarray(self._line, dtype=np.int64).reshape(k),
            )
        )
        self._note(self._chunks[-1][0], self._chunks[-1][2])
        self._chunked += k
        self._tip, self._axis, self._feed, self._motion, self._line = [], [], [], [], []

    @property
    def last_tip(self) -> tuple[float, float, float] | None:
        """Tip of the last motion point (mm, workpiece frame), or None before the first."""
        if self._motion:
            x, y, z = self._tip[-3:]
        elif self._chunks:
            x, y, z = self._chunks[-1][0][-1].tolist()
        else:
            return None
        return (x, y, z)

    def last_tips(self, count: int) -> np.ndarray:
        """Tips of the last ``count`` points, shape (<=count, 3), mm."""
        self._flush()
        parts: list[np.ndarray] = []
        need = min(count, len(self))
        for tip, *_ in reversed(self._chunks):
            if need <= 0:
                break
            take = min(need, tip.shape[0])
            parts.append(tip[tip.shape[0] - take :])
            need -= take
        if not parts:
            return np.empty((0, 3))
        return np.concatenate(parts[::-1]).astype(float, copy=True)

    def last_motion(self) -> int | None:
        """Motion kind of the last point, or None before the first."""
        if self._motion:
            return self._motion[-1]
        return int(self._chunks[-1][3][-1]) if self._chunks else None

    def last_line(self) -> int | None:
        """Source line of the last point, or None before the first."""
        if self._line:
            return self._line[-1]
        return int(self._chunks[-1][4][-1]) if self._chunks else None

    def add_point(
        self,
        tip: Sequence[float],
        axis: Sequence[float],
        feed: float,
        motion: Motion,
        line: int,
    ) -> None:
        """Append one motion point (tip in mm, unit axis, feed in mm/min or NaN)."""
        self._tip.extend(tip)
        self._axis.extend(axis)
        self._feed.append(feed)
        self._motion.append(int(motion))
        self._line.append(line)

    def add_points(
        self, tips: np.ndarray, axis: Sequence[float], feed: float, motion: Motion, line: int
    ) -> None:
        """Append several points sharing axis, feed, kind and line.

        Parameters
        ----------
        tips : ndarray, shape (k, 3), mm
        axis : sequence of 3 floats
            Unit tool axis of every point.
        """
        k = tips.shape[0]
        self._tip.extend(tips.ravel().tolist())
        self._axis.extend(list(axis) * k)
        self._feed.extend([feed] * k)
        self._motion.extend([int(motion)] * k)
        self._line.extend([line] * k)

    def add_arrays(
        self,
        tip: np.ndarray,
        axis: np.ndarray,
        feed: np.ndarray,
        motion: np.ndarray,
        line: np.ndarray,
    ) -> None:
        """Append points given as arrays (the builder keeps them: do not change them after).

        Parameters
        ----------
        tip : ndarray, shape (k, 3), mm
        axis : ndarray, shape (k, 3)
            Unit tool axes.
        feed : ndarray, shape (k,), mm/min
            NaN for rapids or an unknown feed.
        motion : ndarray, shape (k,)
            :class:`Motion` values.
        line : ndarray, shape (k,)
            Source lines.
        """
        k = tip.shape[0]
        if not k:
            return
        self._flush()
        self._chunks.append(
            (
                np.asarray(tip, dtype=float).reshape(k, 3),
                np.asarray(axis, dtype=float).reshape(k, 3),
                np.asarray(feed, dtype=float).reshape(k),
                np.asarray(motion, dtype=np.int8).reshape(k),
                np.asarray(line, dtype=np.int64).reshape(k),
            )
        )
        self._note(self._chunks[-1][0], self._chunks[-1][2])
        self._chunked += k

    def _note(self, tip: np.ndarray, feed: np.ndarray) -> None:
        """Widen the box of the tips and raise the fastest feed by a chunk's points."""
        with np.errstate(invalid="ignore"):
            np.minimum(self._low, tip.min(axis=0), out=self._low)
            np.maximum(self._high, tip.max(axis=0), out=self._high)
        finite = feed[np.isfinite(feed)]
        if finite.size:
            self._fastest = max(self._fastest, float(finite.max()))

    def figures(self) -> tuple[float | None, float | None]:
        """The largest side of the box around every tip added (mm) and the fastest feed of any
        point (mm/min); None for no points or no feed."""
        self._flush()
        extent = float((self._high - self._low).max()) if len(self) else None
        fastest = self._fastest if np.isfinite(self._fastest) else None
        return extent, fastest

    def set_last_axis(self, axis: Sequence[float]) -> None:
        """Replace the tool axis of the last point."""
        if self._motion:
            self._axis[-3:] = list(axis)
        else:
            self._chunks[-1][1][-1] = axis

    def add_event(self, kind: str, line: int, **data: Any) -> None:
        """Append an event that comes before the next motion point."""
        self.events.append(Event(index=len(self), kind=kind, line=line, data=data))

    def amend_last_event(self, kind: str, **data: Any) -> bool:
        """Add ``data`` to the last event when it is of ``kind`` and no motion followed it.

        Returns
        -------
        bool
            Whether an event was amended.
        """
        if not self.events:
            return False
        last = self.events[-1]
        if last.kind != kind or last.index != len(self):
            return False
        self.events[-1] = Event(
            index=last.index, kind=last.kind, line=last.line, data={**last.data, **data}
        )
        return True

    def warn(self, line: int, message: str) -> None:
        """Record a warning "FILE:LINE: message"."""
        self.warnings.append(f"{self.source}:{line}: {message}")
        self._warned_at.append(len(self))

    def build(self, *, units: str, multiaxis: bool) -> Toolpath:
        """Return the :class:`Toolpath` of everything added (and not taken) so far.

        After :meth:`take`, the event indices are counted from the first point held.
        """
        self._flush()
        chunks = self._chunks
        if len(chunks) == 1:
            tip, axis, feed, motion, line = chunks[0]
        elif chunks:
            parts = zip(*chunks, strict=True)
            tip, axis, feed, motion, line = (np.concatenate(part) for part in parts)
        else:
            tip, axis = np.empty((0, 3)), np.empty((0, 3))
            feed, motion = np.empty(0), np.empty(0, dtype=np.int8)
            line = np.empty(0, dtype=np.int64)
        return Toolpath(
            tip=tip,
            axis=axis,
            feed=feed,
            motion=motion,
            line=line,
            events=_shifted(self.events, self._taken),
            units=units,
            source=self.source,
            warnings=tuple(self.warnings),
            multiaxis=multiaxis,
        )

    def take(self, count: int, *, units: str, multiaxis: bool) -> Toolpath:
        """Hand out the first ``count`` points held as a :class:`Toolpath`, and forget them.

        The piece carries the events and warnings recorded before its last point's successor
        was added (events re-indexed from the piece's first point). Later points, events and
        warnings stay for the next piece or :meth:`build`.

        Parameters
        ----------
        count : int
            Points to hand out, ``1 <= count <= held``.
        units : str
            Units of the file, for the piece.
        multiaxis : bool
            Whether a record up to the piece's last point carried a tool axis.
        """
        if not 0 < count <= self.held:
            raise ValueError(f"count: expected 1 to {self.held} points, got {count}")
        self._flush()
        parts: list[tuple[np.ndarray, ...]] = []
        need = count
        while need:
            chunk = self._chunks[0]
            size = chunk[0].shape[0]
            if size <= need:
                parts.append(chunk)
                del self._chunks[0]
                need -= size
            else:  # split the chunk; copy the piece so that it holds no view of the rest
                parts.append(tuple(a[:need].copy() for a in chunk))
                self._chunks[0] = tuple(a[need:] for a in chunk)  # type: ignore[assignment]
                need = 0
        if len(parts) == 1:
            tip, axis, feed, motion, line = parts[0]
        else:
            tip, axis, feed, motion, line = (np.concatenate(p) for p in zip(*parts, strict=True))
        first = self._taken
        self._chunked -= count
        self._taken += count
        split = bisect.bisect_left([e.index for e in self.events], self._taken)
        events = self.events[:split]
        del self.events[:split]
        split = bisect.bisect_left(self._warned_at, self._taken)
        warnings = self.warnings[:split]
        del self.warnings[:split], self._warned_at[:split]
        return Toolpath(
            tip=tip,
            axis=axis,
            feed=feed,
            motion=motion,
            line=line,
            events=_shifted(events, first),
            units=units,
            source=self.source,
            warnings=tuple(warnings),
            multiaxis=multiaxis,
        )


def _shifted(events: Sequence[Event], offset: int) -> tuple[Event, ...]:
    """``events`` with ``offset`` subtracted from their indices."""
    if not offset:
        return tuple(events)
    return tuple(Event(e.index - offset, e.kind, e.line, e.data) for e in events)


def unit_vector(
    values: Sequence[float],
    *,
    builder: ToolpathBuilder,
    line: int,
    what: str = "tool axis",
) -> tuple[float, float, float]:
    """Normalise a tool or circle axis read from a record.

    Parameters
    ----------
    values : sequence of 3 floats
        The axis as written.
    builder : ToolpathBuilder
        Receives a warning when the length is off 1 by more than :data:`AXIS_LENGTH_SLACK`.
    line : int
        Source line, for the error and the warning.
    what : str
        Name used in messages ("tool axis", "circle axis").

    Raises
    ------
    CLDataError
        When a component is not finite or the length is (near) zero.
    """
    i, j, k = values
    length = math.sqrt(i * i + j * j + k * k)
    if not math.isfinite(length) or length < ZERO_AXIS:
        raise CLDataError(
            builder.source, line, f"expected a unit {what}, got {format_values(values)}"
        )
    if abs(length - 1.0) > AXIS_LENGTH_SLACK:
        builder.warn(line, f"{what} {format_values(values)} has length {length:.6g}; normalised")
    return (i / length, j / length, k / length)
