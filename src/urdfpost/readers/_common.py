"""Helpers shared by the CL readers: number parsing, units, and the toolpath builder.

The builder collects motion points as plain Python lists (cheap to append one at a time) and
turns them into the arrays of a :class:`~urdfpost.toolpath.Toolpath` once, at the end.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from typing import Any

import numpy as np

from urdfpost.errors import CLDataError
from urdfpost.tolerances import MM_PER_INCH
from urdfpost.toolpath import Event, Motion, Toolpath

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

_UNIT_NAMES = {"mm": "mm", "inch": "inch", "in": "inch", "inches": "inch"}


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
    return MM_PER_INCH if units == "inch" else 1.0


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
        raise CLDataError(source, line, f"expected a number for {what}, got '{text}'")
    return float(text)


def format_values(values: Sequence[float]) -> str:
    """``(0, 0, 0)``-style text of a few numbers, for messages."""
    return "(" + ", ".join(f"{v:g}" for v in values) + ")"


class ToolpathBuilder:
    """Accumulates the points, events and warnings of one file.

    Parameters
    ----------
    source : str
        File name used in warnings and in the returned toolpath.
    """

    def __init__(self, source: str) -> None:
        self.source = source
        self._tip: list[float] = []
        self._axis: list[float] = []
        self._feed: list[float] = []
        self._motion: list[int] = []
        self._line: list[int] = []
        self.events: list[Event] = []
        self.warnings: list[str] = []

    def __len__(self) -> int:
        return len(self._motion)

    @property
    def last_tip(self) -> tuple[float, float, float] | None:
        """Tip of the last motion point (mm, workpiece frame), or None before the first."""
        if not self._motion:
            return None
        x, y, z = self._tip[-3:]
        return (x, y, z)

    def last_tips(self, count: int) -> np.ndarray:
        """Tips of the last ``count`` points, shape (<=count, 3), mm."""
        k = min(count, len(self))
        return np.asarray(self._tip[len(self._tip) - 3 * k :], dtype=float).reshape(k, 3)

    def last_motion(self) -> int | None:
        """Motion kind of the last point, or None before the first."""
        return self._motion[-1] if self._motion else None

    def last_line(self) -> int | None:
        """Source line of the last point, or None before the first."""
        return self._line[-1] if self._line else None

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

    def set_last_axis(self, axis: Sequence[float]) -> None:
        """Replace the tool axis of the last point."""
        self._axis[-3:] = list(axis)

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

    def build(self, *, units: str, multiaxis: bool) -> Toolpath:
        """Return the :class:`Toolpath` of everything added so far."""
        n = len(self)
        return Toolpath(
            tip=np.asarray(self._tip, dtype=float).reshape(n, 3),
            axis=np.asarray(self._axis, dtype=float).reshape(n, 3),
            feed=np.asarray(self._feed, dtype=float).reshape(n),
            motion=np.asarray(self._motion, dtype=np.int8).reshape(n),
            line=np.asarray(self._line, dtype=np.int64).reshape(n),
            events=tuple(self.events),
            units=units,
            source=self.source,
            warnings=tuple(self.warnings),
            multiaxis=multiaxis,
        )


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
