"""Cutter-location data as arrays.

A :class:`Toolpath` is what every reader returns and what the pipeline consumes: motion points as
numpy arrays in the workpiece frame (millimetres, unit tool axes) and the non-motion records as
:class:`Event` objects that point at the motion they precede. Readers convert inch files to mm
and remember the file's units so the program is written in them.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field, replace
from enum import IntEnum
from typing import Any

import numpy as np

CYCLE_KINDS = ("drill", "deep", "chipbreak", "tap", "bore")
"""Kinds of a ``cycle`` event (as :data:`urdfpost.program.CYCLE_KINDS`)."""


class Motion(IntEnum):
    """Kind of a motion point."""

    FEED = 0
    RAPID = 1


@dataclass(frozen=True)
class Event:
    """A non-motion record of the CL data.

    Attributes
    ----------
    index : int
        Index of the motion point this event comes before (``len(toolpath)`` for events after
        the last motion).
    kind : str
        One of:

        - ``"partno"``: ``data["text"]``
        - ``"comment"``: ``data["text"]`` (``$$`` comments, PPRINT)
        - ``"insert"``: ``data["text"]`` passed through verbatim to the program
        - ``"tool"``: tool change, ``data["number"]`` (int), optional ``data["diameter"]``,
          ``data["corner_radius"]``, ``data["cutter_length"]`` (mm: the cutter's own length,
          of CUTTER or TLDATA), ``data["length"]`` (mm: the gauge length, LOADTL LENGTH),
          ``data["name"]``
        - ``"spindle"``: ``data["rpm"]`` (float), ``data["direction"]`` ("cw", "ccw" or "off")
        - ``"coolant"``: ``data["mode"]`` ("flood", "mist", "through", "air", "off")
        - ``"home"``: GOHOME
        - ``"stop"``: ``data["optional"]`` (bool)
        - ``"dwell"``: ``data["seconds"]`` (float, s; APT ``DELAY``)
        - ``"operation"``: start of an operation (NX ``TOOL PATH/``), ``data["name"]``,
          optional ``data["tool_name"]``
        - ``"cutter"``: tool size (CUTTER, TLDATA): ``data["diameter"]``, optional
          ``data["corner_radius"]``, ``data["length"]`` (mm)
        - ``"cycle"``: a canned cycle starts (APT ``CYCLE/DRILL`` ...): ``data["kind"]``
          (one of :data:`CYCLE_KINDS`), ``data["depth"]`` (mm, hole top to bottom along the
          tool axis), ``data["feed"]`` (mm/min), ``data["clearance"]`` (mm above the hole
          top where the feed starts), ``data["retract"]`` (mm above the hole top the tool
          returns to), ``data["step"]`` (mm, peck depth; 0: none), ``data["dwell"]`` (s);
          or ends (``CYCLE/OFF``): ``data["cycle"]`` "off". The points between a cycle's
          start and its end are its holes: the hole tops with their tool axes
          (:func:`cycle_holes`), RAPID points
        - ``"arc"``: a circular arc whose interpolated points follow the event (a CIRCLE):
          ``data["centre"]`` (mm), ``data["normal"]`` (unit; the arc turns counter-clockwise
          about it), ``data["radius"]`` (mm), ``data["points"]`` (how many points follow; the
          point before the event is the arc's start), ``data["sweep"]`` (rad)
        - ``"cutcom"``: cutter radius compensation, ``data["side"]`` ("left", "right",
          "off"), optional ``data["register"]`` (int), ``data["plane"]`` ("XY", "ZX", "YZ")
        - ``"unknown"``: a record the reader does not translate, ``data["text"]`` (carried
          into the program as a comment; the reader also adds a warning)
    line : int
        1-based source line of the record.
    data : dict
        Kind-specific values, as listed above.
    """

    index: int
    kind: str
    line: int
    data: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class Toolpath:
    """CL data of one file, in the workpiece frame.

    Attributes
    ----------
    tip : ndarray, shape (n, 3), mm
        Tool tip (CL point) per motion point.
    axis : ndarray, shape (n, 3)
        Unit tool axis, from the tip toward the spindle.
    feed : ndarray, shape (n,), mm/min
        Programmed feed of the move that ends at the point; NaN for rapid moves or when no
        feed was programmed yet.
    motion : ndarray, shape (n,), int8
        :class:`Motion` per point.
    line : ndarray, shape (n,), int
        1-based source line of the record that produced the point (the first line of a
        continued record; for points interpolated on an arc, the CIRCLE record's line).
    events : tuple of Event
        Non-motion records in file order.
    units : str
        Units the file was written in ("mm" or "inch"); the program is written in them.
    source : str
        File name, for messages.
    warnings : tuple of str
        Reader warnings, each naming file and line.
    multiaxis : bool
        Whether any record carried a tool axis (MULTAX/ON or six-value GOTO).
    """

    tip: np.ndarray
    axis: np.ndarray
    feed: np.ndarray
    motion: np.ndarray
    line: np.ndarray
    events: tuple[Event, ...] = ()
    units: str = "mm"
    source: str = "<string>"
    warnings: tuple[str, ...] = ()
    multiaxis: bool = True

    def __len__(self) -> int:
        return int(self.tip.shape[0])

    def __post_init__(self) -> None:
        n = self.tip.shape[0]
        shapes = {
            "tip": (self.tip.shape, (n, 3)),
            "axis": (self.axis.shape, (n, 3)),
            "feed": (self.feed.shape, (n,)),
            "motion": (self.motion.shape, (n,)),
            "line": (self.line.shape, (n,)),
        }
        for name, (got, want) in shapes.items():
            if got != want:
                raise ValueError(f"Toolpath.{name}: expected shape {want}, got {got}")

    @classmethod
    def from_points(
        cls,
        tip: np.ndarray,
        axis: np.ndarray,
        feed: float | np.ndarray = np.nan,
        units: str = "mm",
        source: str = "<points>",
        spindle: float | None = None,
    ) -> Toolpath:
        """Build a feed-only toolpath from arrays (for scripts and tests).

        Parameters
        ----------
        tip : array_like, shape (n, 3), mm
        axis : array_like, shape (n, 3)
            Normalised here.
        feed : float or array_like, shape (n,), mm/min
        units : str
            Units to write the program in.
        source : str
            Name used in messages.
        spindle : float, optional, rpm
            Start the spindle (clockwise) before the first point: a "spindle" event. Without
            it the toolpath cuts with the spindle off, which a post refuses unless its job
            gives a spindle speed (``PostOptions.spindle``).
        """
        tip = np.asarray(tip, dtype=float).reshape(-1, 3)
        axis = np.asarray(axis, dtype=float).reshape(-1, 3)
        axis = axis / np.linalg.norm(axis, axis=1, keepdims=True)
        n = tip.shape[0]
        return cls(
            tip=tip,
            axis=axis,
            feed=np.broadcast_to(np.asarray(feed, dtype=float), (n,)).copy(),
            motion=np.full(n, Motion.FEED, dtype=np.int8),
            line=np.arange(1, n + 1),
            units=units,
            source=source,
            events=()
            if spindle is None
            else (Event(0, "spindle", 1, {"rpm": float(spindle), "direction": "cw"}),),
        )


def toolpath_slice(toolpath: Toolpath, a: int, b: int, *, first_events: bool = True) -> Toolpath:
    """Points ``a`` to ``b - 1`` of a toolpath, with their events re-indexed.

    The events before points ``a + 1 .. b - 1`` come along, those before point ``a`` when
    ``first_events``, and those after the last point when ``b`` is the end. Array views, no
    copies.
    """
    n = len(toolpath)
    lo = a if first_events else a + 1
    events = tuple(
        replace(e, index=e.index - a)
        for e in toolpath.events
        if lo <= e.index < b or (b == n and e.index == n)
    )
    return replace(
        toolpath,
        tip=toolpath.tip[a:b],
        axis=toolpath.axis[a:b],
        feed=toolpath.feed[a:b],
        motion=toolpath.motion[a:b],
        line=toolpath.line[a:b],
        events=events,
    )


def toolpath_pieces(toolpath: Toolpath, points: int) -> Iterator[Toolpath]:
    """A toolpath as consecutive pieces of at most ``points`` points (the form
    :func:`urdfpost.readers.read_cl_chunks` gives; for jobs already in memory, and tests)."""
    n = len(toolpath)
    if n == 0:
        yield toolpath
        return
    for a in range(0, n, points):
        b = min(a + points, n)
        piece = toolpath_slice(toolpath, a, b)
        yield replace(piece, warnings=toolpath.warnings if a == 0 else ())


def joined(first: Toolpath, more: list[Toolpath]) -> Toolpath:
    """Toolpaths appended to ``first`` (events after the last point of one come before the
    first point of the next)."""
    parts = [first, *more]
    offsets = np.cumsum([0, *(len(p) for p in parts)])
    return replace(
        more[-1],
        tip=np.concatenate([p.tip for p in parts]),
        axis=np.concatenate([p.axis for p in parts]),
        feed=np.concatenate([p.feed for p in parts]),
        motion=np.concatenate([p.motion for p in parts]),
        line=np.concatenate([p.line for p in parts]),
        events=tuple(
            replace(e, index=e.index + int(at))
            for p, at in zip(parts, offsets, strict=False)
            for e in p.events
        ),
        warnings=tuple(w for p in parts for w in p.warnings),
    )


def cycle_holes(toolpath: Toolpath) -> list[tuple[int, Event]]:
    """The holes of the toolpath's canned cycles: each point between a ``cycle`` event and
    the ``cycle`` event "off" after it, with the event that started its cycle.

    Returns
    -------
    list of (int, Event)
        Point index and its cycle's event, in order.
    """
    out: list[tuple[int, Event]] = []
    active: Event | None = None
    for event in toolpath.events:
        if event.kind != "cycle":
            continue
        if active is not None:
            out += [(i, active) for i in range(active.index, event.index)]
        active = None if event.data.get("cycle") == "off" else event
    if active is not None:  # a cycle not switched off: up to the end
        out += [(i, active) for i in range(active.index, len(toolpath))]
    return out
