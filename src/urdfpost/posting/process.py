"""The process state of a job checked before anything is planned: tools, feed and spindle.

Every tool change calls a tool the control has, with a length offset register it can select
(:meth:`urdfpost.dialects.spec.DialectSpec.tool_fault`: the control's tool numbers, and in TCP
programs the CL's ``LOADTL ADJUST`` register, or the tool number): else the post stops with
the file and the line of the tool change (:class:`~urdfpost.errors.CLDataError`).

A cutting move (a CL feed move) needs a programmed feed and a running spindle. Where the CL
data gives neither, the post stops with the file and line (:class:`~urdfpost.errors.CLDataError`),
unless the job gives a default (``--feed``, ``--spindle``): then the default is used and said as
a warning. After a tool change the spindle is off (the post stops it before the change); when
the CL data does not start it again before the next cut, the post restarts it at the speed and
direction it had, with a warning.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace

import numpy as np

from urdfpost.dialects.spec import DialectSpec
from urdfpost.errors import CLDataError
from urdfpost.toolpath import Event, Motion, Toolpath, cycle_holes
from urdfpost.units import mm_per_unit


@dataclass(frozen=True)
class SpindleState:
    """The spindle where a piece of CL data starts.

    Attributes
    ----------
    direction : str
        "cw", "ccw" or "off": the last speed the CL data started the spindle with.
    rpm : float
        The last speed the spindle was started with (0: never started).
    running : bool
        Whether the spindle turns (False after a tool change or ``SPINDL/OFF``).
    """

    direction: str = "off"
    rpm: float = 0.0
    running: bool = False

    @property
    def started(self) -> bool:
        """The spindle has been started with a speed (so it can be restarted at it)."""
        return self.direction != "off" and self.rpm > 0


def _feeds(toolpath: Toolpath, feed: float | None, units: str) -> tuple[np.ndarray, list[str]]:
    cut = toolpath.motion == int(Motion.FEED)
    missing = cut & ~np.isfinite(toolpath.feed)
    if not missing.any():
        return toolpath.feed, []
    first = int(toolpath.line[int(np.argmax(missing))])
    if feed is None:
        raise CLDataError(
            toolpath.source,
            first,
            "a cutting move with no feed (no FEDRAT before it); expected a FEDRAT record, or "
            "give the job a feed with --feed",
        )
    out = np.where(missing, feed, toolpath.feed)
    scale = mm_per_unit(units)
    return out, [
        f"{toolpath.source}:{first}: {int(missing.sum())} cutting moves with no feed in the CL "
        f"data: F{feed / scale:g} ({units}/min, --feed) used"
    ]


def check_tools(toolpath: Toolpath, spec: DialectSpec, tcp: bool) -> None:
    """Refuse a tool change the control cannot make as the CL data asks.

    Parameters
    ----------
    toolpath : Toolpath
    spec : DialectSpec
        The control's (:attr:`~DialectSpec.tool_numbers`, :attr:`~DialectSpec.length_offsets`).
    tcp : bool
        A TCP program (its TCP lines select the length offset register).

    Raises
    ------
    CLDataError
        At the line of the first tool change (``LOADTL``) whose tool number is outside the
        control's, or whose length offset register (``ADJUST``, else the tool number) the
        control cannot select; or of a ``CUTCOM`` whose offset register the control cannot
        select with the tool called or in a plane it has none in (:meth:`DialectSpec.comp_fault`).

    Examples
    --------
    >>> from urdfpost.dialects import DIALECTS
    >>> from urdfpost.readers import read_cl_text
    >>> tp = read_cl_text("LOADTL/123456\\nGOTO/0,0,0\\n", source="a.apt")
    >>> check_tools(tp, DIALECTS["heidenhain"].spec, tcp=True)  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    urdfpost.errors.CLDataError: a.apt:1: tool number 123456 is outside the tool numbers of ...
    """
    tool: int | None = None  # (the tool called before the toolpath starts: not known here)
    for e in sorted(toolpath.events, key=lambda e: e.index):
        if e.kind == "cutcom" and e.data.get("side") != "off":
            register = e.data.get("register")
            plane = str(e.data.get("plane", "XY"))
            # (the register against the tool called where that is known: a piece of a
            # streamed post may begin after it, and the writer checks it there)
            asked = None if register is None or tool is None else int(register)
            if wrong := spec.comp_fault(asked, tool, plane):
                raise CLDataError(toolpath.source, e.line, wrong)
        if e.kind != "tool":
            continue
        tool = int(e.data.get("number", 0))
        adjust = e.data.get("adjust")
        fault = spec.tool_fault(
            int(e.data.get("number", 0)), None if adjust is None else int(adjust), tcp=tcp
        )
        if fault is not None:
            if "; expected" not in fault:
                fault += "; expected a tool the control has"
            raise CLDataError(toolpath.source, e.line, fault)


def checked_process(
    toolpath: Toolpath,
    *,
    feed: float | None,
    spindle: float | None,
    units: str,
    state: SpindleState | None = None,
    spec: DialectSpec | None = None,
    tcp: bool = True,
) -> tuple[Toolpath, SpindleState, list[str]]:
    """``toolpath`` with every cutting move fed and cut with the spindle on.

    Parameters
    ----------
    toolpath : Toolpath
    feed : float or None
        mm/min for cutting moves without a feed; None: such a move is an error.
    spindle : float or None
        rpm (clockwise) for cutting with the spindle never started; None: an error.
    units : str
        Program units, for the warnings.
    state : SpindleState, optional
        The spindle where ``toolpath`` starts (a piece of a streamed post); default off.
    spec : DialectSpec, optional
        The control the program is for: its tool changes are checked (:func:`check_tools`);
        None: not checked (``urdfpost verify`` compares the program's tools instead).
    tcp : bool
        A TCP program (:func:`check_tools`).

    Returns
    -------
    toolpath : Toolpath
        With the feeds filled in and spindle events added where needed.
    state : SpindleState
        The spindle at its end.
    warnings : list of str

    Raises
    ------
    CLDataError
        A tool the control cannot call as asked (:func:`check_tools`); a cutting move with no
        feed or with the spindle off, and no default for it.
    """
    if spec is not None:
        check_tools(toolpath, spec, tcp)
    state = state or SpindleState()
    feeds, warnings = _feeds(toolpath, feed, units)
    cutting = toolpath.motion == int(Motion.FEED)
    cutting[[i for i, _ in cycle_holes(toolpath)]] = True  # a canned cycle cuts at its holes
    cuts = np.flatnonzero(cutting)
    events = sorted(toolpath.events, key=lambda e: e.index)  # stable: file order kept
    added: list[Event] = []
    last_on = state if state.started else None  # what a tool change stopped
    running = state.running and state.started
    k = 0  # next event
    since = 0  # index of the last event that stopped the spindle (tool change, SPINDL/OFF)
    pending_tool: Event | None = None  # the last tool change with no spindle start after it
    at_cut = 0  # the next cut (of cuts)
    while at_cut < len(cuts):
        point = int(cuts[at_cut])
        # the events before this point
        while k < len(events) and events[k].index <= point:
            e = events[k]
            if e.kind == "tool":
                if running:
                    running = False
                pending_tool = e
                since = e.index
            elif e.kind == "spindle":
                rpm = float(e.data.get("rpm", 0.0))
                direction = str(e.data.get("direction", "cw"))
                on = direction != "off" and math.isfinite(rpm) and rpm > 0
                running = on
                pending_tool = None
                if not on:
                    since = e.index
                if on:
                    last_on = SpindleState(direction, rpm, True)
            k += 1
        if running:  # nothing changes before the next event: on to its first cut
            if k == len(events):
                break
            at_cut = int(np.searchsorted(cuts, events[k].index))
            continue
        line = int(toolpath.line[point])
        # the spindle starts where the CL data changed the tool or stopped it, else before the
        # first point of the piece: before the approach, not at the cut
        at = pending_tool.index if pending_tool is not None else since
        if last_on is not None and pending_tool is not None:
            restart = last_on
            warnings.append(
                f"{toolpath.source}:{pending_tool.line}: no SPINDL after the tool change before "
                f"the cut at line {line}; the spindle restarts at S{restart.rpm:g} "
                f"{restart.direction.upper()} as before the change"
            )
        elif spindle is not None:
            restart = SpindleState("cw", float(spindle), True)
            warnings.append(
                f"{toolpath.source}:{line}: cutting with the spindle off (no SPINDL before this "
                f"move): S{spindle:g} CW (--spindle) used"
            )
        else:
            raise CLDataError(
                toolpath.source,
                line,
                "a cutting move with the spindle off (no SPINDL before it); expected a SPINDL "
                "record, or give the job a spindle speed with --spindle",
            )
        added.append(
            Event(
                index=at,
                kind="spindle",
                line=pending_tool.line if pending_tool is not None else line,
                data={"rpm": restart.rpm, "direction": restart.direction},
            )
        )
        running, last_on, pending_tool = True, restart, None
        at_cut += 1
    # the events after the last cut set the state the next piece starts with
    for e in events[k:]:
        if e.kind == "tool":
            running = False
        elif e.kind == "spindle":
            rpm = float(e.data.get("rpm", 0.0))
            direction = str(e.data.get("direction", "cw"))
            running = direction != "off" and math.isfinite(rpm) and rpm > 0
            if running:
                last_on = SpindleState(direction, rpm, True)
    end = (
        SpindleState(last_on.direction, last_on.rpm, running)
        if last_on is not None
        else SpindleState()
    )
    if not added and not warnings:
        return toolpath, end, []
    # a restart goes after the tool change it follows: after every event at its index
    merged = list(toolpath.events)
    for extra in added:
        after = max((i for i, e in enumerate(merged) if e.index <= extra.index), default=-1)
        merged.insert(after + 1, extra)
    return replace(toolpath, feed=feeds, events=tuple(merged)), end, warnings


def one_tool_length(
    toolpath: Toolpath,
    tool_length: float,
    units: str,
    seen: frozenset[int] = frozenset(),
    table: Mapping[int, float] | None = None,
) -> tuple[list[str], frozenset[int]]:
    """The warnings of a machine-coordinate job about tools with no gauge length of their own.

    Machine-coordinate positions include the tool's gauge length; each tool is posted with its
    own (:mod:`urdfpost.posting.tools`: the tool table, else ``LOADTL LENGTH``), else with
    the job's one length (``--tool-length``, else the machine file's). A tool after the first
    that has no length of its own is posted with the job's: right only if its gauge length is
    that. One warning per such tool number.

    Parameters
    ----------
    toolpath : Toolpath
    tool_length : float, mm
        The job's length.
    units : str
        Program units, for the message.
    seen : frozenset of int
        Tool numbers seen before ``toolpath`` (a piece of a streamed post).
    table : mapping, optional
        The job's tool table (tool number to gauge length, mm).

    Returns
    -------
    warnings : list of str
    seen : frozenset of int
        With the tool numbers of ``toolpath``.
    """
    notes: list[str] = []
    numbers = set(seen)
    table = table or {}
    length = tool_length / mm_per_unit(units)
    for e in toolpath.events:
        if e.kind != "tool":
            continue
        number = int(e.data.get("number", 0))
        own = number in table or e.data.get("length") is not None
        if numbers and number not in numbers and not own:
            notes.append(
                f"{toolpath.source}:{e.line}: T{number} has no gauge length in the tool table "
                f"or the CL data (LOADTL LENGTH) and is posted with the job's tool length "
                f"{length:.3f} {units} (machine coordinates include it): right only if its "
                "gauge length is that; else give it with --tool-table, or post with TCP"
            )
        numbers.add(number)
    return notes, frozenset(numbers)
