"""The controller-neutral program of a piece: its blocks from the joint rows and the CL events.

:func:`program_body` turns the rows a plan and its subdivision gave (joint positions, the CL
point each belongs to, whether it reaches it, and what kind of row it is) and the CL events
(tool changes, spindle, coolant, comments...) into the blocks of a
:class:`~urdfpost.program.Program`. No dialect is known here: :mod:`urdfpost.dialects` writes
the blocks.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from urdfpost.machine import Machine
from urdfpost.planning.rewinds import LIFT, RETURN, TURN
from urdfpost.posting.transitions import Transitions
from urdfpost.program import (
    REWIND_END,
    Arc,
    Block,
    Comment,
    Coolant,
    CutterComp,
    Home,
    Insert,
    MachineMove,
    MoveTable,
    Spindle,
    Stop,
    Tcp,
    ToolChange,
    WorkOffset,
)
from urdfpost.toolpath import Event, Motion, Toolpath


def program_name(toolpath: Toolpath, name: str | None) -> str:
    """The program's name: ``name``, else the CL data's PARTNO, else "URDFPOST"."""
    if name:
        return name
    for e in toolpath.events:
        if e.kind == "partno" and e.data.get("text", "").strip():
            name = re.sub(r"[^A-Za-z0-9_]+", "_", e.data["text"].strip()).strip("_")
            return name.upper()[:24] or "URDFPOST"
    return "URDFPOST"


def _event_blocks(event: Event, tcp_state: list[bool], tcp: bool) -> list[Block]:
    """Blocks for one CL event; ``tcp_state`` is updated when TCP is switched."""
    kind, data = event.kind, event.data
    out: list[Block] = []

    def tcp_off() -> None:
        if tcp_state[0]:
            out.append(Tcp(on=False))
            tcp_state[0] = False

    if kind in ("comment", "partno", "unknown"):
        out.append(Comment(str(data.get("text", ""))))
    elif kind == "operation":
        out.append(Comment(f"operation {data.get('name', '')}".strip()))
    elif kind == "insert":
        out.append(Insert(str(data.get("text", ""))))
    elif kind == "tool":
        tcp_off()
        out.append(
            ToolChange(
                number=int(data.get("number", 0)),
                length=data.get("length"),
                diameter=data.get("diameter"),
                name=data.get("name"),
                offset=None if data.get("adjust") is None else int(data["adjust"]),
            )
        )
    elif kind == "cutter":
        size = ", ".join(
            f"{k.replace('_', ' ')} {float(v):.4g} mm" for k, v in data.items() if v is not None
        )
        out.append(Comment(f"cutter {size}"))
    elif kind == "spindle":
        rpm = float(data.get("rpm", 0.0))
        out.append(
            Spindle(
                direction=str(data.get("direction", "cw")), rpm=rpm if np.isfinite(rpm) else 0.0
            )
        )
    elif kind == "coolant":
        out.append(Coolant(mode=str(data.get("mode", "flood"))))
    elif kind == "home":
        tcp_off()
        out.append(Home())
    elif kind == "stop":
        out.append(Stop(optional=bool(data.get("optional", False))))
    elif kind == "cutcom":
        register = data.get("register")
        out.append(
            CutterComp(
                side=str(data["side"]),
                register=None if register is None else int(register),
                plane=str(data.get("plane", "XY")),
            )
        )
    elif kind == "msys":  # where the program zero lies in the part (information only)
        out.append(Comment(f"MSYS {data.get('text', '')}".strip()))
    else:
        text = " ".join(f"{k}={v}" for k, v in data.items())
        out.append(Comment(f"{kind} {text}".strip()))
    return out


@dataclass(frozen=True)
class ArcSpan:
    """Rows of a program's move table that one :class:`Arc` block replaces.

    Attributes
    ----------
    first, last : int
        The first row replaced and the last (the one reaching the arc's end point),
        inclusive.
    block : Arc
    """

    first: int
    last: int
    block: Arc


@dataclass(frozen=True)
class Rows:
    """The rows of a program's moves, before they become blocks.

    Attributes
    ----------
    q : ndarray, shape (N, m)
        Joint values (mm, rad), machine axis order.
    tip : ndarray, shape (N, 3), mm
        Tool tip in the workpiece frame.
    point : ndarray, shape (N,), int
        The CL point each row reaches or stands on (index into the plan's toolpath).
    reaches : ndarray, shape (N,), bool
        Whether the row arrives at its CL point (else it is inserted on the way to it, or
        stands on a point already reached).
    kind : ndarray, shape (N,), int
        ``CUT``, or ``LIFT`` / ``TURN`` / ``RETURN`` for the rows of a rewind.
    """

    q: np.ndarray
    tip: np.ndarray
    point: np.ndarray
    reaches: np.ndarray
    kind: np.ndarray

    @classmethod
    def empty(cls, joints: int) -> Rows:
        """No rows, for ``joints`` joints."""
        none = np.zeros(0, dtype=int)
        return cls(np.zeros((0, joints)), np.zeros((0, 3)), none, none.astype(bool), none)

    def __len__(self) -> int:
        return len(self.point)


def _move_table(
    toolpath: Toolpath,
    machine: Machine,
    tcp: bool,
    rows: Rows,
    rewind_feed: float | None,
) -> MoveTable:
    """The motion blocks of the rows, as arrays.

    Positions in degrees for the rotary axes; in TCP programs X, Y, Z are the tip. A row that
    stands on a CL point already reached (a turn at a pole) goes with the move that leaves the
    point: rapid when that move is a RAPID (a reorientation between rapids stays rapid), else
    at its feed, even when the point was reached by a rapid; the lift and turn of a rewind are
    off the part: rapid, or at ``rewind_feed`` (mm/min) when it is given.
    """
    n, g = len(toolpath), rows.point
    rotary_names = {a.name for a in machine.rotary}
    rotary = np.array([a in rotary_names for a in machine.axis_names])
    position = np.where(rotary, np.degrees(rows.q), rows.q)
    if tcp:
        position[:, list(machine.linear_columns)] = rows.tip
    # first programmed feed after each point (backward fill), for turns in place
    fill = np.where(np.isfinite(toolpath.feed), np.arange(n), n)
    fill = np.minimum.accumulate(fill[::-1])[::-1]
    feeds = np.append(toolpath.feed, np.nan)
    next_feed = feeds[np.append(fill[1:], n)] if n else feeds
    # the CL point reached last before each row (-1 before the first)
    last = np.maximum.accumulate(np.where(rows.reaches, np.arange(len(rows)), -1))
    before = np.concatenate([[-1], last[:-1]]) if len(rows) else last
    arrived = np.where(before >= 0, g[np.maximum(before, 0)], -1)
    turning = g == arrived
    # a turn standing on a point goes with the move that leaves it: rapid before a RAPID
    rapid_next = np.append(toolpath.motion[1:] == int(Motion.RAPID), False)
    rapid = np.where(turning, rapid_next[g], toolpath.motion[g] == int(Motion.RAPID))
    feed = np.where(turning, next_feed[g], toolpath.feed[g])
    off = (rows.kind == LIFT) | (rows.kind == TURN)
    rapid[off] = rewind_feed is None
    feed[off] = np.nan if rewind_feed is None else rewind_feed
    feed = np.where(rapid | ~np.isfinite(feed), np.nan, feed)
    cl_line = np.where(rows.reaches, toolpath.line[g], -1)
    return MoveTable(position, rapid, feed, cl_line)


def program_body(
    toolpath: Toolpath,
    machine: Machine,
    tcp: bool,
    rows: Rows,
    events: list[Event],
    comments: list[str],
    rewind_feed: float | None,
    tcp_on: bool = False,
    close: bool = True,
    transitions: Transitions | None = None,
    work_offset: int | None = None,
    coolant: str | None = None,
    arcs: Sequence[ArcSpan] = (),
) -> list[Block | MoveTable]:
    """The program body: the rows' moves as tables, the events' blocks between them.

    Parameters
    ----------
    toolpath : Toolpath
        The plan's CL data (feeds, motion kinds, lines of the rows' points).
    machine : Machine
    tcp : bool
        TCP program: TCP is switched on before the first move and after every event that
        switched it off (tool change, home).
    rows : Rows
    events : list of Event
        Sorted by index: each goes before the first row whose CL point is at or after it.
    comments : list of str
        The comment before each rewind, in order.
    rewind_feed : float or None
        Feed of a rewind's lift and turn, mm/min; None: rapid.
    tcp_on : bool
        TCP is on before the body (a piece of a streamed post that continues one with TCP).
    close : bool
        The body ends the program: TCP is switched off at its end (and with
        ``transitions``, the tool retracts and the rotary axes go home).
    transitions : Transitions, optional
        Makes the moves off the path (:mod:`urdfpost.posting.transitions`): the safe approach
        before the first row (when the body starts the program, i.e. ``work_offset`` is
        given) and after every tool change or home return, the retract before a tool change,
        the end. None: the rows only, as planned.
    work_offset : int, optional
        The body starts the program: the work offset it selects (1 for G54) and, with
        ``transitions``, a retract before the first tool change.
    coolant : str, optional
        The coolant on before the body (a streamed piece): a tool change stops it and, unless
        the CL data sets the coolant there, starts it again.
    arcs : sequence of ArcSpan
        Rows written as :class:`~urdfpost.program.Arc` blocks instead (in row order; none
        holds a row before which a block other than moves comes,
        :func:`urdfpost.posting.arcs.arc_spans`).

    Returns
    -------
    list of Block and MoveTable
        Only the few non-motion blocks are made one by one; the moves between them are rows of
        one table.
    """
    table = _move_table(toolpath, machine, tcp, rows, rewind_feed)
    count, kind = len(rows), rows.kind
    # the row before which each event comes (count: after the last row)
    reach = np.maximum.accumulate(rows.point) if count else rows.point
    at = np.searchsorted(reach, np.array([e.index for e in events], dtype=np.int64))
    lifts = np.flatnonzero(kind == LIFT)
    ends = np.flatnonzero(kind == RETURN) + 1  # a rewind's last comment after its return
    starts = np.union1d(np.union1d(at[at < count], lifts), ends[ends < count])
    if count:
        starts = np.union1d(starts, [0])
    body: list[Block | MoveTable] = []
    spans = list(arcs)

    def rows_of(a: int, b: int) -> list[Block | MoveTable]:
        """Rows ``a`` to ``b - 1`` as table rows, and the arcs among them."""
        out: list[Block | MoveTable] = []
        while spans and spans[0].first < b:
            span = spans.pop(0)
            assert a <= span.first and span.last < b, "an arc across a block between rows"
            out += [table.rows(a, span.first), span.block]
            a = span.last + 1
        return [*out, table.rows(a, b)]

    tcp_state = [tcp_on]
    by_row: dict[int, list[Event]] = {}
    for event, row in zip(events, at.tolist(), strict=True):
        by_row.setdefault(row, []).append(event)
    starting = work_offset is not None
    if starting:
        assert work_offset is not None
        body.append(WorkOffset(work_offset))
        if transitions is not None and count:  # a program without motion moves nothing
            body.append(transitions.retract_block())
    lift_comments = iter(comments)
    done = 0  # rows in tables so far
    for k in starts.tolist():
        before: list[Block] = []
        here = by_row.get(k, [])
        leaves = k > 0 and any(e.kind in ("tool", "home") for e in here)
        restart = None  # the coolant a tool change stopped, to start again after it
        if transitions is not None and leaves and any(e.kind == "tool" for e in here):
            line = int(toolpath.line[g_of(rows, k - 1)])
            before += transitions.leave(rows.q[k - 1], line, tcp_state[0])
            tcp_state[0] = False
            restart = _coolant_on(body, coolant)
        for event in here:
            before += _event_blocks(event, tcp_state, tcp)
        if restart is not None and not any(e.kind == "coolant" for e in here):
            before.append(Coolant(mode=restart))
        if kind[k] == LIFT:
            before.append(Comment(next(lift_comments)))
        if transitions is not None and (leaves or (starting and k == 0)):
            if tcp_state[0]:
                before.append(Tcp(on=False))
                tcp_state[0] = False
            line = int(toolpath.line[g_of(rows, k)])
            before += transitions.approach(rows.q[k - 1] if k else None, rows.q[k], line)
            tcp_state[0] = tcp
        if tcp and not tcp_state[0]:
            before.append(Tcp(on=True))
            tcp_state[0] = True
        after_return = k > 0 and kind[k - 1] == RETURN
        if before or after_return:
            if k > done:
                body += rows_of(done, k)
                done = k
            if after_return:
                body.append(Comment(REWIND_END))
            body += before
    if count > done:
        body += rows_of(done, count)
    if count and kind[count - 1] == RETURN:
        body.append(Comment(REWIND_END))
    for event in by_row.get(count, []):
        body += _event_blocks(event, tcp_state, tcp)
    if transitions is not None and close and count:
        line = int(toolpath.line[g_of(rows, count - 1)])
        ending = transitions.end(rows.q[count - 1], line, tcp_state[0])
        # not again what the CL data's own end did: spindle or coolant off, a home return
        spindles = [b for b in body if isinstance(b, Spindle)]
        coolants = [b for b in body if isinstance(b, Coolant)]
        homed = bool(body) and isinstance(body[-1], Home)
        body += [
            b
            for b in ending
            if not (isinstance(b, Spindle) and spindles and spindles[-1].direction == "off")
            and not (isinstance(b, Coolant) and coolants and coolants[-1].mode == "off")
            and not (isinstance(b, MachineMove) and homed)
        ]
        tcp_state[0] = False
    if tcp_state[0] and close:
        body.append(Tcp(on=False))
    return body


def _coolant_on(body: list[Block | MoveTable], before: str | None) -> str | None:
    """The coolant mode the body leaves on (its last Coolant block; ``before`` when it has
    none), None when off."""
    for block in reversed(body):
        if isinstance(block, Coolant):
            return None if block.mode == "off" else block.mode
    return before


def coolant_after(blocks: Iterable[Block | MoveTable], before: str | None) -> str | None:
    """The coolant mode on after ``blocks`` (``before`` when they set none), None when off."""
    return _coolant_on(list(blocks), before)


def g_of(rows: Rows, k: int) -> int:
    """The CL point (index into the plan's toolpath) of row ``k``."""
    return int(rows.point[k])
