"""The controller-neutral program of a piece: its blocks from the joint rows and the CL events.

:func:`program_body` turns the rows a plan and its subdivision gave (joint positions, the CL
point each belongs to, whether it reaches it, and what kind of row it is) and the CL events
(tool changes, spindle, coolant, comments...) into the blocks of a
:class:`~urdfpost.program.Program`. No dialect is known here: :mod:`urdfpost.dialects` writes
the blocks.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, replace

import numpy as np

from urdfpost.errors import LinearTravelError
from urdfpost.linearize import RowPoses
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
    Cycle,
    Dwell,
    Home,
    Insert,
    MachineMove,
    Move,
    MoveTable,
    Smoothing,
    Spindle,
    Stop,
    Tcp,
    ToolChange,
    WorkOffset,
    expand_cycle,
)
from urdfpost.toolpath import Event, Motion, Toolpath, cycle_holes


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
    elif kind == "dwell":
        out.append(Dwell(float(data["seconds"])))
    elif kind == "cycle":  # its holes become a Cycle block (program_body); named here
        if data.get("cycle") != "off":
            out.append(Comment(f"cycle {data.get('cycle')}"))
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
    entry: np.ndarray | None = None,
    leave: bool = False,
    keep_tool: bool = False,
    expand_cycles: bool = False,
    notes: list[str] | None = None,
    runs_cycle: Callable[[str, float], bool] | None = None,
    motion: list[_Holes] | None = None,
    smoothing: Smoothing | None = None,
    arcs: Sequence[ArcSpan] = (),
    tilted_cycles: bool = False,
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
        ``transitions``, a retract before the first tool change. With ``entry``: the work
        offset of the section's MCS, selected before its tool change and approach.
    coolant : str, optional
        The coolant on before the body (a streamed piece): a tool change stops it and, unless
        the CL data sets the coolant there, starts it again.
    entry : ndarray, shape (m,), optional
        The body begins a tool section after another (:mod:`urdfpost.posting.tools`): the
        joint values where the section before left the path. With ``transitions``, its tool
        change is approached as any tool change, from the retract above them.
    leave : bool
        The body ends where the next tool section's tool change comes: with ``transitions``,
        it leaves the path after its last row as for a tool change (TCP off, the retract,
        spindle and coolant off).
    keep_tool : bool
        With ``leave``: the next section keeps the tool (it begins with a change of work
        offset, not a tool change): the spindle and coolant stay on.
    expand_cycles : bool
        Write the holes of the CL data's canned cycles as their motion instead of
        :class:`~urdfpost.program.Cycle` blocks (:func:`cycle_parts`).
    notes : list of str, optional
        Receives the warnings (a tilted hole written as its motion).
    runs_cycle : callable, optional
        ``(kind, dwell) -> bool``: whether the control runs such a cycle
        (:meth:`~urdfpost.dialects.spec.DialectSpec.runs_cycle`); one it does not is written
        as its motion, with a warning. None: every cycle is written.
    motion : list, optional
        Receives the holes' record, whose :meth:`_Holes.joint_path` gives the joint rows of
        the program's motion (for the collision check).
    smoothing : Smoothing, optional
        The control's path smoothing: switched on before the approach and first cut of
        each tool, off before each tool change and at the end of the program. A body
        that does not start the program (no ``work_offset``) starts with it on.
    arcs : sequence of ArcSpan
        Rows written as :class:`~urdfpost.program.Arc` blocks instead (in row order; none
        holds a row before which a block other than moves comes,
        :func:`urdfpost.posting.arcs.arc_spans`).
    tilted_cycles : bool
        Write a hole whose tool axis is off the program's Z as a
        :class:`~urdfpost.program.Cycle` with its :attr:`~urdfpost.program.Cycle.up` (no rapid
        before it), for :func:`urdfpost.posting.planes.tilted_planes` to put in a tilted plane
        or write as its motion; else as its motion here, with a warning.

    Returns
    -------
    list of Block and MoveTable
        Only the few non-motion blocks are made one by one; the moves between them are rows of
        one table.
    """
    table = _move_table(toolpath, machine, tcp, rows, rewind_feed)
    holes = _Holes.of(
        toolpath, machine, tcp, rows, table, expand_cycles, notes, runs_cycle, tilted_cycles
    )
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
    starting = work_offset is not None and entry is None
    smooth = [smoothing is not None and not starting and entry is None]  # smoothing on
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
        enters = k == 0 and entry is not None  # a tool section after another
        restart = None  # the coolant a tool change stopped, to start again after it
        if smooth[0] and k > 0 and any(e.kind == "tool" for e in here):
            before.append(Smoothing(False))  # off for the tool change
            smooth[0] = False
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
        if enters and work_offset is not None:  # a section in another MCS: its offset first
            before.insert(0, WorkOffset(work_offset))
        keeps = enters and not any(e.kind == "tool" for e in here)  # the coolant still on
        if enters and not keeps and not any(e.kind == "coolant" for e in here) and coolant:
            before.append(Coolant(mode=coolant))  # the section before stopped it
        entering = leaves or enters or (starting and k == 0)
        if smoothing is not None and not smooth[0] and entering:
            before.append(smoothing)  # before the tool's approach and first cut
            smooth[0] = True
        if transitions is not None and entering:
            if tcp_state[0]:
                before.append(Tcp(on=False))
                tcp_state[0] = False
            line = int(toolpath.line[g_of(rows, k)])
            before += transitions.approach(rows.q[k - 1] if k else entry, rows.q[k], line)
            tcp_state[0] = tcp
        if tcp and not tcp_state[0]:
            before.append(Tcp(on=True))
            tcp_state[0] = True
        after_return = k > 0 and kind[k - 1] == RETURN
        if before or after_return:
            if k > done:
                body += holes.parts(done, k, body, rows_of)
                done = k
            if after_return:
                body.append(Comment(REWIND_END))
            body += before
    if count > done:
        body += holes.parts(done, count, body, rows_of)
    if count and kind[count - 1] == RETURN:
        body.append(Comment(REWIND_END))
    for event in by_row.get(count, []):
        body += _event_blocks(event, tcp_state, tcp)
    if transitions is not None and leave and count and not close:
        if smooth[0]:  # off for the next section's tool change or work offset
            body.append(Smoothing(False))
            smooth[0] = False
        line = int(toolpath.line[g_of(rows, count - 1)])
        body += transitions.leave(rows.q[count - 1], line, tcp_state[0], stop=not keep_tool)
        tcp_state[0] = False
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
    if motion is not None:
        motion.append(holes)
    if smooth[0] and close:
        body.append(Smoothing(False))
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


TRAVEL_SLACK = 1e-9
"""mm. A hole's joint rows may pass a linear axis's travel limit by this much (rounding)."""

NATIVE_AXIS = 1e-6
"""How far (the length of the difference of unit vectors) the up direction of a hole, in
program coordinates, may be from the program's +Z for the hole to be written as a cycle: 0.1
micrometre over 100 mm of travel."""


@dataclass
class _Holes:
    """The rows of the CL data's canned cycles and what they become (:meth:`parts`).

    Attributes
    ----------
    toolpath : Toolpath
    machine : Machine
    tcp : bool
    rows : Rows
    table : MoveTable
        The moves of all the rows.
    event : dict of int to Event
        The cycle of each hole (CL point index).
    expand : bool
        Write every hole as its motion.
    notes : list of str or None
        Receives the warnings.
    runs : callable or None
        Whether the control runs a cycle (kind, dwell).
    warned : set of int
        CL lines of the cycles warned of.
    motion : dict of int to ndarray
        Per hole row, the joint rows of its motion, shape (4, m) (:meth:`_hole_motion`).
    tilted : bool
        Write a tilted hole (its tool axis off the program's Z) as a :class:`Cycle` with
        :attr:`Cycle.up`, for a tilted working plane (:mod:`urdfpost.posting.planes`).
    """

    toolpath: Toolpath
    machine: Machine
    tcp: bool
    rows: Rows
    table: MoveTable
    event: dict[int, Event]
    expand: bool
    notes: list[str] | None
    runs: Callable[[str, float], bool] | None
    warned: set[int]
    motion: dict[int, np.ndarray]
    tilted: bool = False

    @classmethod
    def of(
        cls,
        toolpath: Toolpath,
        machine: Machine,
        tcp: bool,
        rows: Rows,
        table: MoveTable,
        expand: bool,
        notes: list[str] | None,
        runs: Callable[[str, float], bool] | None = None,
        tilted: bool = False,
    ) -> _Holes:
        event = dict(cycle_holes(toolpath))
        return cls(
            toolpath, machine, tcp, rows, table, event, expand, notes, runs, set(), {}, tilted
        )

    def parts(
        self,
        start: int,
        stop: int,
        body: list[Block | MoveTable],
        plain: Callable[[int, int], list[Block | MoveTable]] | None = None,
    ) -> list[Block | MoveTable]:
        """The blocks of rows ``start`` to ``stop`` (exclusive): the moves as a table (or as
        ``plain(a, b)`` makes rows ``a`` to ``b - 1``: with the arcs among them), and the
        rows of holes as :class:`Cycle` blocks, each after a rapid to the retract height above
        its first hole (or, expanded, as their motion: :func:`expand_cycle`). The rows on the
        way to a hole (inserted by the subdivision) are not written: the control moves from
        hole to hole at the retract height."""

        def rows(a: int, b: int) -> list[Block | MoveTable]:
            return [self.table.rows(a, b)] if plain is None else plain(a, b)

        if not self.event:
            return rows(start, stop)
        point = self.rows.point[start:stop]
        inside = np.isin(point, np.fromiter(self.event, dtype=np.int64, count=len(self.event)))
        out: list[Block | MoveTable] = []
        k = 0
        n = stop - start
        while k < n:
            j = k
            while j < n and inside[j] == inside[k]:
                j += 1
            if inside[k]:
                out += self._cycles(start + k, start + j, body + out)
            else:
                out += rows(start + k, start + j)
            k = j
        return out

    def _joint_up(self, row: int) -> np.ndarray:
        """Per joint, its motion for 1 mm up the tool axis at ``row`` (mm; the rotary axes
        fixed): the linear axes' motion that moves the tip along the tool axis, from the
        kinematics (with the rotary axes fixed the tip is an affine function of the linear
        axes)."""
        machine, g = self.machine, int(self.rows.point[row])
        up = np.zeros(len(machine.axis_names))
        linear = list(machine.linear_columns)
        q = np.tile(self.rows.q[row], (len(linear) + 1, 1))
        for i, col in enumerate(linear):
            q[i + 1, col] += 1.0
        tip = RowPoses.of(machine, q, 0.0).tip
        step = (tip[1:] - tip[0]).T  # column i: the tip's motion for 1 mm of linear axis i
        up[linear] = np.linalg.solve(step, self.toolpath.axis[g])
        return up

    def _up(self, row: int) -> np.ndarray:
        """Per program axis, its motion for 1 mm up the tool axis at ``row`` (mm, degrees):
        the tool axis itself in TCP programs, :meth:`_joint_up` in machine coordinates."""
        if not self.tcp:
            return self._joint_up(row)
        up = np.zeros(len(self.machine.axis_names))
        up[list(self.machine.linear_columns)] = self.toolpath.axis[int(self.rows.point[row])]
        return up

    def _hole_motion(self, row: int) -> None:
        """The joint rows of the hole at ``row`` (above it at the retract height, at the
        clearance, at the bottom, above it again) for the collision check, after checking them
        against the linear axes' travel.

        Raises
        ------
        LinearTravelError
            The retract height or the bottom puts a linear axis beyond its travel.
        """
        data = self._event(row).data
        retract, clearance = float(data["retract"]), float(data["clearance"])
        heights = np.array([retract, clearance, -float(data["depth"]), retract])
        q = self.rows.q[row] + heights[:, None] * self._joint_up(row)
        for j in self.machine.linear_columns:
            axis = self.machine.axes[j]
            outside = (q[:, j] < axis.lower - TRAVEL_SLACK) | (q[:, j] > axis.upper + TRAVEL_SLACK)
            if outside.any():
                k = int(np.argmax(outside))
                where = "bottom" if k == 2 else "retract height"
                line = int(self.toolpath.line[self.rows.point[row]])
                raise LinearTravelError(
                    f"{self.toolpath.source}:{line}: the hole's {where} needs {axis.name}"
                    f"{q[k, j]:.3f} mm, beyond its travel {axis.lower:.3f} to {axis.upper:.3f} "
                    f"mm; expected the cycle's depth and retract height ({data['cycle']} at CL "
                    f"line {self._event(row).line}) within the machine's travel"
                )
        self.motion[row] = q

    def joint_path(self, q: np.ndarray, lines: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The joint rows of the program's motion: ``q`` (the rows, shape (N, m)) with each
        hole's row replaced by the hole's motion and the rows on the way between holes left
        out (the control moves from hole to hole at the retract height); ``lines`` (N,) the
        CL line of each row, given to the hole's rows too."""
        if not self.motion:
            return q, lines
        inside = np.isin(self.rows.point, np.fromiter(self.event, dtype=np.int64))
        parts_q: list[np.ndarray] = []
        parts_line: list[np.ndarray] = []
        for k in range(len(q)):
            if k in self.motion:
                parts_q.append(self.motion[k])
                parts_line.append(np.full(len(self.motion[k]), lines[k]))
            elif not inside[k]:
                parts_q.append(q[k : k + 1])
                parts_line.append(lines[k : k + 1])
        return np.concatenate(parts_q), np.concatenate(parts_line)

    def _cycles(
        self, start: int, stop: int, before: list[Block | MoveTable]
    ) -> list[Block | MoveTable]:
        """The blocks of the hole rows ``start`` to ``stop``."""
        names = self.machine.axis_names
        z = names.index("Z")
        rotary = list(self.machine.rotary_columns)
        plus_z = np.zeros(len(names))
        plus_z[z] = 1.0
        out: list[Block | MoveTable] = []
        group: list[int] = []  # rows of holes for one Cycle block
        tilt: list[np.ndarray | None] = [None]  # the group's up, when its holes are tilted

        def close() -> None:
            if not group:
                return
            cycle = self._cycle(group)
            if tilt[0] is not None:  # in a tilted plane: :mod:`urdfpost.posting.planes`
                out.append(replace(cycle, up=tuple(tilt[0].tolist())))
            else:
                above = self.table.position[group[0]].copy()
                above[z] += cycle.retract
                out.append(Move(True, tuple(above.tolist())))
                out.append(cycle)
            group.clear()

        for row in range(start, stop):
            if not self.rows.reaches[row]:
                continue
            self._hole_motion(row)
            up = self._up(row)
            along_z = float(np.linalg.norm(up - plus_z)) <= NATIVE_AXIS
            data = self._event(row).data
            runs = self.runs is None or self.runs(str(data["cycle"]), float(data["dwell"]))
            if self.expand or not runs or (not along_z and not self.tilted):
                close()
                self._warn_expanded(row, "tilted" if not along_z else "control")
                cycle = self._cycle([row])
                out += expand_cycle(cycle, names, _spindle_before(before + out), tuple(up))
                continue
            if group:
                first, here = self.table.position[group[0]], self.table.position[row]
                same = (
                    self._event(group[0]) is self._event(row)
                    and (not along_z or abs(here[z] - first[z]) <= 1e-9 * max(1.0, abs(first[z])))
                    and np.array_equal(here[rotary], first[rotary])
                    and (tilt[0] is None) == along_z
                )
                if not same:
                    close()
            tilt[0] = None if along_z else up
            group.append(row)
        close()
        return out

    def _event(self, row: int) -> Event:
        return self.event[int(self.rows.point[row])]

    def _cycle(self, group: list[int]) -> Cycle:
        data = self._event(group[0]).data
        return Cycle(
            kind=str(data["cycle"]),
            depth=float(data["depth"]),
            feed=float(data["feed"]),
            clearance=float(data["clearance"]),
            retract=float(data["retract"]),
            holes=tuple(tuple(self.table.position[r].tolist()) for r in group),
            step=float(data.get("step", 0.0)),
            dwell=float(data.get("dwell", 0.0)),
            cl_lines=tuple(int(self.toolpath.line[self.rows.point[r]]) for r in group),
        )

    def _warn_expanded(self, row: int, why: str) -> None:
        """One warning per cycle whose holes are written as their motion without being asked
        to: ``why`` "tilted" (a hole's tool axis is not the program's Z) or "control" (the
        control has no such cycle)."""
        event = self._event(row)
        if self.expand or self.notes is None or event.line in self.warned:
            return
        self.warned.add(event.line)
        line = int(self.toolpath.line[self.rows.point[row]])
        kind = event.data["cycle"]
        reason = (
            f"the hole at line {line} has its tool axis off the program's Z axis (a tilted hole "
            "needs a tilted working plane: a TCP program on a control that has one, "
            "--tilted-planes)"
            if why == "tilted"
            else f"the control has no {kind} cycle with a dwell at the bottom"
        )
        self.notes.append(
            f"{self.toolpath.source}:{event.line}: CYCLE {kind}: {reason}; its holes are "
            "written as their motion"
        )


def _spindle_before(body: list[Block | MoveTable]) -> Spindle | None:
    """The last Spindle block of ``body`` (None: none)."""
    for block in reversed(body):
        if isinstance(block, Spindle):
            return block
    return None
