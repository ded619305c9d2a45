"""Posting: CL toolpath to a checked NC program, with no files opened.

``post(toolpath, machine, options)`` runs the whole chain: solution choice per point
(:mod:`urdfpost.planning.branches`), subdivision of feed moves until the nonlinear error is within
tolerance (:mod:`urdfpost.linearize`), the controller-neutral program (:mod:`urdfpost.program`),
its text in the chosen dialect, and the verification of that text read back through the machine
(:mod:`urdfpost.verify`). A program that misses its tolerance is an error.
"""

from __future__ import annotations

import logging
import re
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any

import numpy as np

from urdfpost.errors import CollisionError, ToleranceError, UrdfpostError
from urdfpost.linearize import angle_between, subdivide
from urdfpost.machine import Machine
from urdfpost.planning.branches import DEFAULT_RETRACT, Preference, rewind_rows
from urdfpost.planning.singularity import joined_runs
from urdfpost.planning.strategies import (
    DEFAULT_STRATEGY,
    STRATEGIES,
    Plan,
    Problem,
    entry_mask,
    midpoint_solver,
    realise,
    tool_axis_of,
)
from urdfpost.program import (
    REWIND_BEGIN,
    REWIND_END,
    Block,
    Blocks,
    Comment,
    Coolant,
    Home,
    Insert,
    MoveTable,
    Program,
    Spindle,
    Stop,
    Tcp,
    ToolChange,
)
from urdfpost.tolerances import Tolerances
from urdfpost.toolpath import Event, Motion, Toolpath
from urdfpost.units import mm_per_unit
from urdfpost.verify import Check, Verification, verify, verify_checks

if TYPE_CHECKING:
    from urdfpost.collision import CollisionWorld

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class PostOptions:
    """How to post.

    Attributes
    ----------
    controller : str or None
        Dialect name; default the machine file's controller.
    tcp : bool
        Write the tool tip in workpiece coordinates with TCP on (the control does the
        kinematics) instead of machine axis positions.
    units : str or None
        Program units ("mm" or "inch"); default the CL file's units.
    tool_length : float or None
        Tool length in mm (gauge point to tip); default the machine file's.
    tolerance : float or None
        Tool-tip tolerance in program units; default 0.01 mm or 0.0004 in.
    prefer : Preference or None
        Preferred rotary branch; default the machine file's.
    block_numbers : bool
        Number the blocks (Heidenhain always does).
    program_name : str or None
        Default: the CL PARTNO, else "URDFPOST".
    strategy : str or None
        Singularity strategy (:data:`urdfpost.planning.strategies.STRATEGIES`); default the
        machine file's, else :data:`~urdfpost.planning.strategies.DEFAULT_STRATEGY`.
    angle_tolerance : float
        How far a strategy may bend the tool axis from the programmed one, degrees.
    planner : str
        Branch choice over the whole path ("global") or point by point ("local").
    lift : float
        Lift along the tool axis inside singular spans (``spline`` strategy), program units;
        0 = off.
    retract : float or None
        Lift along the tool axis for a rewind, program units; default 50 mm (2 in).
    rewind_feed : float or None
        Feed of a rewind's lift and turn, program units per minute; None: rapid. The return
        to the part is at the feed of the cut.
    collisions : bool
        Check every branch candidate and the program's moves for collisions with FCL (always
        on when a stock is given).
    stock : str or None
        Stock or part mesh (STL, OBJ, ...) in the workpiece frame, program units.
    holder_diameter, holder_length : float or None
        Tool holder size, program units; default 40 x 60 mm.
    """

    controller: str | None = None
    tcp: bool = True
    units: str | None = None
    tool_length: float | None = None
    tolerance: float | None = None
    prefer: Preference | None = None
    block_numbers: bool = False
    program_name: str | None = None
    strategy: str | None = None
    angle_tolerance: float = 2.0
    planner: str = "global"
    lift: float = 0.0
    retract: float | None = None
    rewind_feed: float | None = None
    collisions: bool = False
    stock: str | None = None
    holder_diameter: float | None = None
    holder_length: float | None = None


@dataclass(frozen=True)
class PostResult:
    """Everything a post produces.

    Attributes
    ----------
    program : Program
        The controller-neutral program.
    text : str
        The program in the dialect.
    verification : Verification
        Of ``text`` read back through the machine.
    report : dict
        Figures for people and JSON (lengths in program units, angles in degrees).
    """

    program: Program
    text: str
    verification: Verification
    report: dict[str, Any] = field(default_factory=dict)


def _program_name(toolpath: Toolpath, options: PostOptions) -> str:
    if options.program_name:
        return options.program_name
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
    else:
        text = " ".join(f"{k}={v}" for k, v in data.items())
        out.append(Comment(f"{kind} {text}".strip()))
    return out


def _reference(
    toolpath: Toolpath,
    tip: np.ndarray,
    axis: np.ndarray,
    group: np.ndarray,
    is_cl: np.ndarray,
    turn: np.ndarray,
) -> Toolpath:
    """The path a plan follows, as CL data: every output row but the turns in place.

    Verification against it checks that the program does what the strategy intended (its
    rows and the points the subdivision took from its curve); how far that is from the CL
    data is checked separately.
    """
    n = len(toolpath)
    idx = np.flatnonzero(~turn)
    own = group[idx]
    cl = is_cl[idx]
    motion = np.where(cl, toolpath.motion[own], int(Motion.FEED)).astype(toolpath.motion.dtype)
    pos = np.full(n + 1, len(idx))
    pos[own[cl]] = np.flatnonzero(cl)
    return replace(
        toolpath,
        tip=tip[idx],
        axis=axis[idx],
        feed=toolpath.feed[own],
        motion=motion,
        line=toolpath.line[own],
        events=tuple(replace(e, index=int(pos[min(e.index, n)])) for e in toolpath.events),
    )


_CUT, _LIFT, _TURN, _RETURN = 0, 1, 2, 3  # kinds of program rows: a rewind lifts, turns, returns


def _with_rewinds(
    problem: Problem, plan: Plan, q: np.ndarray, tip: np.ndarray, axis: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Insert the lift and the turn of every rewind of a plan.

    A rewind is a row at the same position as the row before it whose joint-space turn from
    that row would swing the tool axis (a turn in place at a pole does not): the path arrives
    with one solution and leaves with another of the same pose. Between them the tool lifts
    along its axis by the retract distance, turns there, and comes back.

    Parameters
    ----------
    q : ndarray, shape (N, m)
    tip, axis : ndarray, shape (N, 3)
        The plan's rows as :func:`realise` gives them.

    Returns
    -------
    q, tip, axis, param : ndarray
        With the rows inserted.
    kind : ndarray, shape (N',), int
        ``_CUT``, or ``_LIFT`` / ``_TURN`` / ``_RETURN`` for the rows of a rewind.
    """
    machine, param = problem.machine, plan.param
    kind = np.zeros(len(param), dtype=int)
    same = np.flatnonzero(param[1:] == param[:-1]) + 1
    if not same.size:
        return q, tip, axis, param, kind
    rot = plan.rotary
    a, b = rot[same - 1], rot[same]
    end = tool_axis_of(machine, b)
    swing = np.max(
        [angle_between(tool_axis_of(machine, a + t * (b - a)), end) for t in (0.25, 0.5, 0.75)],
        axis=0,
    )
    ks = same[swing > problem.tol.orientation]
    if not ks.size:
        return q, tip, axis, param, kind
    lifted = np.vstack(
        [
            rewind_rows(
                machine, q[k - 1], q[k], tip[k], axis[k], problem.tool_length, problem.retract
            )[:2]
            for k in ks
        ]
    )
    at = np.repeat(ks, 2)
    up = np.repeat(tip[ks] + problem.retract * axis[ks], 2, axis=0)
    kind[ks] = _RETURN
    return (
        np.insert(q, at, lifted, axis=0),
        np.insert(tip, at, up, axis=0),
        np.insert(axis, at, np.repeat(axis[ks], 2, axis=0), axis=0),
        np.insert(param, at, param[at]),
        np.insert(kind, at, np.tile([_LIFT, _TURN], len(ks))),
    )


def _rewind_figures(
    machine: Machine,
    toolpath: Toolpath,
    q: np.ndarray,
    owner: np.ndarray,
    kind: np.ndarray,
    retract: float,
) -> list[dict[str, Any]]:
    """One entry per rewind: CL line, rotary angles before and after (deg), retract (mm)."""
    out = []
    for k in np.flatnonzero(kind == _LIFT):
        line = int(toolpath.line[owner[k]])
        turn = {
            a.name: [float(np.degrees(q[k - 1, c])), float(np.degrees(q[k + 2, c]))]
            for a, c in zip(machine.rotary, machine.rotary_columns, strict=True)
        }
        moved = ", ".join(
            f"{n} {f:.3f} -> {t:.3f}" for n, (f, t) in turn.items() if abs(t - f) > 1e-9
        )
        out.append(
            {
                "cl_line": line,
                "rotary_deg": turn,
                "retract_mm": retract,
                "comment": f"{REWIND_BEGIN} CL line {line}: {moved} deg, lift {retract:.3f} mm",
            }
        )
    return out


def strategy_name(machine: Machine, options: PostOptions) -> str:
    """The strategy a post uses: the options', the machine file's, or the default."""
    name = options.strategy or machine.settings.strategy or DEFAULT_STRATEGY
    if name not in STRATEGIES:
        raise UrdfpostError(
            f"unknown singularity strategy {name!r}; expected one of {', '.join(STRATEGIES)}"
        )
    return name


def ball_radius(toolpath: Toolpath) -> float:
    """Ball radius of the first cutter in the CL data when it is a ball-end tool, else 0 (mm)."""
    for e in toolpath.events:
        if e.kind in ("cutter", "tool") and e.data.get("diameter") is not None:
            d = float(e.data["diameter"])
            r = e.data.get("corner_radius")
            if r is not None and d > 0 and abs(float(r) - 0.5 * d) <= 1e-6 * max(d, 1.0):
                return 0.5 * d
            return 0.0
    return 0.0


def make_problem(
    toolpath: Toolpath, machine: Machine, options: PostOptions, tol: Tolerances
) -> Problem:
    """The strategy input for a post."""
    units = options.units or toolpath.units
    scale = mm_per_unit(units)
    tool_length = (
        machine.settings.tool_length if options.tool_length is None else options.tool_length
    )
    return Problem(
        machine=machine,
        toolpath=toolpath,
        tool_length=tool_length,
        tol=tol,
        angle_tolerance=float(np.radians(options.angle_tolerance)),
        pivot=ball_radius(toolpath),
        prefer=options.prefer,
        planner=options.planner,
        lift=options.lift * scale,
        collision=collision_world(toolpath, machine, options, tool_length),
        retract=DEFAULT_RETRACT if options.retract is None else options.retract * scale,
    )


def collision_world(
    toolpath: Toolpath, machine: Machine, options: PostOptions, tool_length: float
) -> CollisionWorld | None:
    """The FCL world a post checks against, or None when collisions are not checked.

    The tool is the first cutter of the CL data (diameter, corner radius, length) in the
    holder of the options; the stock mesh is read in program units and placed in the
    workpiece frame.
    """
    if not (options.collisions or options.stock):
        return None
    from urdfpost.collision import CollisionWorld, ToolBody, load_mesh

    units = options.units or toolpath.units
    scale = mm_per_unit(units)
    cutters = [
        e.data for e in toolpath.events if e.kind in ("cutter", "tool") and e.data.get("diameter")
    ]
    if len({(c.get("diameter"), c.get("corner_radius")) for c in cutters}) > 1:
        log.warning(
            "%s: several cutters; collisions are checked with the first one", toolpath.source
        )
    tool = ToolBody.from_cutter(
        cutters[0] if cutters else {},
        tool_length,
        holder_diameter=None
        if options.holder_diameter is None
        else options.holder_diameter * scale,
        holder_length=None if options.holder_length is None else options.holder_length * scale,
    )
    stock = None
    if options.stock:
        stock = load_mesh(options.stock)
        if scale != 1.0:
            stock.apply_scale(scale)
    return CollisionWorld.build(machine, tool, tool_length, stock)


@dataclass(frozen=True)
class _Rows:
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
        ``_CUT``, or ``_LIFT`` / ``_TURN`` / ``_RETURN`` for the rows of a rewind.
    """

    q: np.ndarray
    tip: np.ndarray
    point: np.ndarray
    reaches: np.ndarray
    kind: np.ndarray

    @classmethod
    def empty(cls, joints: int) -> _Rows:
        """No rows, for ``joints`` joints."""
        none = np.zeros(0, dtype=int)
        return cls(np.zeros((0, joints)), np.zeros((0, 3)), none, none.astype(bool), none)

    def __len__(self) -> int:
        return len(self.point)


def _move_table(
    toolpath: Toolpath,
    machine: Machine,
    tcp: bool,
    rows: _Rows,
    rewind_feed: float | None,
) -> MoveTable:
    """The motion blocks of the rows, as arrays.

    Positions in degrees for the rotary axes; in TCP programs X, Y, Z are the tip. A row that
    stands on a CL point already reached (a turn at a pole) moves at the feed of the move that
    follows, even when the point was reached by a rapid; the lift and turn of a rewind are off
    the part: rapid, or at ``rewind_feed`` (mm/min) when it is given.
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
    rapid = (toolpath.motion[g] == int(Motion.RAPID)) & ~turning
    feed = np.where(turning, next_feed[g], toolpath.feed[g])
    off = (rows.kind == _LIFT) | (rows.kind == _TURN)
    rapid[off] = rewind_feed is None
    feed[off] = np.nan if rewind_feed is None else rewind_feed
    feed = np.where(rapid | ~np.isfinite(feed), np.nan, feed)
    cl_line = np.where(rows.reaches, toolpath.line[g], -1)
    return MoveTable(position, rapid, feed, cl_line)


def _program_body(
    toolpath: Toolpath,
    machine: Machine,
    tcp: bool,
    rows: _Rows,
    events: list[Event],
    comments: list[str],
    rewind_feed: float | None,
    tcp_on: bool = False,
    close: bool = True,
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
    rows : _Rows
    events : list of Event
        Sorted by index: each goes before the first row whose CL point is at or after it.
    comments : list of str
        The comment before each rewind, in order.
    rewind_feed : float or None
        Feed of a rewind's lift and turn, mm/min; None: rapid.
    tcp_on : bool
        TCP is on before the body (a piece of a streamed post that continues one with TCP).
    close : bool
        The body ends the program: TCP is switched off at its end.

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
    lifts = np.flatnonzero(kind == _LIFT)
    ends = np.flatnonzero(kind == _RETURN) + 1  # a rewind's last comment after its return
    starts = np.union1d(np.union1d(at[at < count], lifts), ends[ends < count])
    if count:
        starts = np.union1d(starts, [0])
    body: list[Block | MoveTable] = []
    tcp_state = [tcp_on]
    by_row: dict[int, list[Event]] = {}
    for event, row in zip(events, at.tolist(), strict=True):
        by_row.setdefault(row, []).append(event)
    lift_comments = iter(comments)
    done = 0  # rows in tables so far
    for k in starts.tolist():
        before: list[Block] = []
        for event in by_row.get(k, []):
            before += _event_blocks(event, tcp_state, tcp)
        if kind[k] == _LIFT:
            before.append(Comment(next(lift_comments)))
        if tcp and not tcp_state[0]:
            before.append(Tcp(on=True))
            tcp_state[0] = True
        after_return = k > 0 and kind[k - 1] == _RETURN
        if before or after_return:
            if k > done:
                body.append(table.rows(done, k))
                done = k
            if after_return:
                body.append(Comment(REWIND_END))
            body += before
    if count > done:
        body.append(table.rows(done, count))
    if count and kind[count - 1] == _RETURN:
        body.append(Comment(REWIND_END))
    for event in by_row.get(count, []):
        body += _event_blocks(event, tcp_state, tcp)
    if tcp_state[0] and close:
        body.append(Tcp(on=False))
    return body


@dataclass(frozen=True)
class Continuation:
    """How a piece of a streamed post joins the pieces around it.

    Attributes
    ----------
    start : ndarray or None, shape (m,)
        Joint vector at the piece's first CL point, which the piece before ended on (its last
        row, already written): the piece's plan starts from it exactly, and its program leaves
        that row out. None for the first piece.
    tcp_on : bool
        TCP is on where the piece starts.
    last : bool
        The piece ends the program (TCP is switched off at its end).
    """

    start: np.ndarray | None
    tcp_on: bool
    last: bool


def build_program(
    toolpath: Toolpath,
    machine: Machine,
    options: PostOptions,
    tol: Tolerances,
    progress: Callable[[int], None] | None = None,
    plan: Plan | None = None,
    problem: Problem | None = None,
    piece: Continuation | None = None,
) -> tuple[Program, dict[str, Any]]:
    """The controller-neutral program for a toolpath (no verification).

    Parameters
    ----------
    toolpath : Toolpath
    machine : Machine
    options : PostOptions
    tol : Tolerances
    progress : callable, optional
    plan : Plan, optional
        The strategy's plan, when already made.
    problem : Problem, optional
        The strategy's input, when already made (:func:`make_problem`).
    piece : Continuation, optional
        When the toolpath is a piece of a streamed post: where it starts, and whether it ends
        the program. The program of a piece that continues another has no row for its first
        CL point (the other's last), and only the last piece switches TCP off at its end.

    Returns
    -------
    program : Program
    figures : dict
        Counts gathered on the way (branch switches, pole points, inserted blocks), the plan
        (``"plan"``) and the reference path the program follows (``"reference"``).
    """
    units = options.units or toolpath.units
    if problem is None:
        problem = make_problem(toolpath, machine, options, tol)
    continued = piece is not None and piece.start is not None
    if continued:
        assert piece is not None
        problem = replace(problem, start=piece.start)
    tool_length = problem.tool_length
    if plan is None:
        plan = STRATEGIES[strategy_name(machine, options)](problem)
    toolpath = plan.toolpath
    n = len(toolpath)
    entry = entry_mask(toolpath)
    figures: dict[str, Any] = {"branch_switches": 0, "pole_points": 0, "inserted_blocks": 0}
    warnings: list[str] = list(plan.notes)
    if not n:
        warnings.append(f"{toolpath.source}: no motion records; the program has no moves")
    first_tool = min((e.index for e in toolpath.events if e.kind == "tool"), default=n + 1)
    tool_events: tuple[Event, ...] = ()
    if n and first_tool > 0 and not continued:
        # controls need a tool (and its length offset) before motion; the CL data has none
        warnings.append(f"{toolpath.source}: no tool change before the first move; tool 1 assumed")
        tool_events = (Event(index=0, kind="tool", line=int(toolpath.line[0]), data={"number": 1}),)
    rows = _Rows.empty(len(machine.axis_names))
    reference = toolpath
    if n:
        q, tip, axis = realise(problem, plan)
        q, tip, axis, param, kind = _with_rewinds(problem, plan, q, tip, axis)
        whole = param == np.round(param)
        owner = np.where(whole, np.round(param), np.ceil(param)).astype(int)
        first = whole.copy()
        first[1:] &= owner[1:] != owner[:-1]  # the row arriving at its CL point
        rot = q[:, list(machine.rotary_columns)]
        figures["branch_switches"] = int(
            np.sum(np.abs(np.diff(rot[:, -1])) > np.pi / 2) if len(rot) > 1 else 0
        )
        figures["rewinds"] = _rewind_figures(machine, toolpath, q, owner, kind, problem.retract)
        figures["pole_points"] = int(
            np.sum(np.abs(toolpath.axis @ machine.rotary[0].direction) > 1 - 0.5 * tol.pole**2)
            if machine.rotary
            else 0
        )
        figures["pole_turns"] = int(np.sum(whole & ~first & (kind == _CUT)))
        joined = ((toolpath.motion[owner] == Motion.FEED) & ~entry[owner]) | ~first
        joined &= kind == _CUT  # a rewind is no cut: its moves are not subdivided
        solve_at = midpoint_solver(problem, plan)
        parts_q, parts_tip, parts_src, parts_axis = [], [], [], []
        done = 0
        for s, e in joined_runs(joined):
            lin = subdivide(
                machine,
                q[s : e + 1],
                tip[s : e + 1],
                axis[s : e + 1],
                tool_length=tool_length,
                tcp=options.tcp,
                tol=tol,
                param=param[s : e + 1],
                solve_at=solve_at,
            )
            parts_q += [q[done:s], lin.q]
            parts_tip += [tip[done:s], lin.tip]
            parts_axis += [axis[done:s], lin.axis]
            parts_src += [np.arange(done, s), np.where(lin.source >= 0, lin.source + s, -1)]
            done = e + 1
            figures["inserted_blocks"] += int(np.sum(lin.source < 0))
            if progress:
                progress(int(owner[e] - owner[s]))
        parts_q.append(q[done:])
        parts_tip.append(tip[done:])
        parts_axis.append(axis[done:])
        parts_src.append(np.arange(done, len(q)))
        out_q, out_tip = np.concatenate(parts_q), np.concatenate(parts_tip)
        src = np.concatenate(parts_src)
        # an inserted row belongs to the move towards the next original row
        nxt = np.where(src >= 0, src, len(q))
        nxt = np.minimum.accumulate(nxt[::-1])[::-1]
        group = owner[np.minimum(nxt, len(q) - 1)]
        is_cl = (src >= 0) & first[np.maximum(src, 0)]
        out_kind = np.where(src >= 0, kind[np.maximum(src, 0)], _CUT)
        rows = _Rows(q=out_q, tip=out_tip, point=group, reaches=is_cl, kind=out_kind)
        if continued:  # its first row is the last of the piece before, already written
            assert piece is not None and piece.start is not None
            if not np.allclose(out_q[0], piece.start, rtol=0.0, atol=1e-9):
                raise UrdfpostError(
                    f"{toolpath.source}:{int(toolpath.line[0])}: a streamed piece does not "
                    "start where the piece before ended (internal error)"
                )
            rows = _Rows(
                q=out_q[1:], tip=out_tip[1:], point=group[1:], reaches=is_cl[1:], kind=out_kind[1:]
            )
        figures["joints"] = out_q
        figures["joint_lines"] = toolpath.line[group]
        if plan.bent or plan.lift.any():
            out_axis = np.concatenate(parts_axis)
            turn = (src >= 0) & whole[np.maximum(src, 0)] & ~first[np.maximum(src, 0)]
            turn |= out_kind != _CUT
            reference = _reference(toolpath, out_tip, out_axis, group, is_cl, turn)
    figures["strategy"] = {
        "name": strategy_name(machine, options),
        "angle_tolerance_deg": options.angle_tolerance,
        "pivot_mm": problem.pivot,
        "bent": plan.bent,
        "lifts": plan.lifts,
        "spans": [sp.as_dict() for sp in plan.spans],
    }
    figures["plan"] = plan
    figures["reference"] = reference
    figures["world"] = problem.collision

    events = sorted(tool_events + toolpath.events, key=lambda e: e.index)
    scale = mm_per_unit(units)
    rewind_feed = None if options.rewind_feed is None else options.rewind_feed * scale
    comments = [r["comment"] for r in figures.get("rewinds", [])]
    body = _program_body(
        toolpath,
        machine,
        options.tcp,
        rows,
        events,
        comments,
        rewind_feed,
        tcp_on=piece is not None and piece.tcp_on,
        close=piece is None or piece.last,
    )
    program = Program(
        name=_program_name(toolpath, options),
        axes=machine.axis_names,
        rotary=frozenset(a.name for a in machine.rotary),
        units=units,
        tcp=options.tcp,
        blocks=Blocks(body),
        tool_length=tool_length,
        continuous=frozenset(a.name for a in machine.rotary if a.continuous),
    )
    figures["warnings"] = warnings
    return program, figures


def post(
    toolpath: Toolpath,
    machine: Machine,
    options: PostOptions | None = None,
    progress: Callable[[int], None] | None = None,
) -> PostResult:
    """Post a toolpath for a machine and check the program against the CL data.

    The whole job is planned at once, in this process. Long jobs post faster and in bounded
    memory in pieces: :func:`urdfpost.post.stream.post_stream`.

    Parameters
    ----------
    toolpath : Toolpath
    machine : Machine
    options : PostOptions, optional
    progress : callable, optional
        Called with the number of CL points just processed.

    Returns
    -------
    PostResult

    Raises
    ------
    UnreachableError
        A CL point no branch reaches within travel.
    ToleranceError
        The program read back deviates from the CL data beyond tolerance (the message carries
        the figures); nothing should be written then.
    """
    from urdfpost.dialects import dialect_for

    options = options or PostOptions()
    units = options.units or toolpath.units
    tol = Tolerances.for_units(units, options.tolerance)
    dialect = dialect_for(options.controller or machine.settings.controller)
    program, figures = build_program(toolpath, machine, options, tol, progress)
    collisions = check_collisions(figures, toolpath, units)
    header = None
    if not options.tcp:
        header = (
            f"machine coordinates for machine {machine.name} with tool length "
            f"{program.tool_length:.3f} mm from the gauge point: the tool table length must be 0"
        )
    text = dialect.write(program, block_numbers=options.block_numbers or None, header=header)
    inserts = [b.text for b in program.parts if isinstance(b, Insert)]
    readback = dialect.read(text, path=f"<{dialect.name} program>", verbatim=inserts)
    check, intent = check_program(readback, machine, toolpath, figures, tol, program.tool_length)
    report = make_report(toolpath, machine, program, check, dialect.name, figures)
    report["collisions"] = collisions
    if intent is not None:
        report["strategy"]["intended_path_check"] = intent.as_dict()
    failed = [c for c in (intent, check) if c is not None and not c.ok]
    if failed:
        c = failed[0]
        what = "the path its strategy intended" if c is intent else "the CL data"
        raise ToleranceError(
            f"{toolpath.source}: the program misses its tolerance against {what}, nothing "
            f"written: {c.summary(units)}"
            + (f"; worst near CL line {c.worst_cl_line}" if c.worst_cl_line else "")
        )
    return PostResult(program=program, text=text, verification=check, report=report)


CLEARANCE_POINTS = 500
"""CL points at which :func:`check_collisions` measures the clearance, at most."""


def check_collisions(figures: dict[str, Any], toolpath: Toolpath, units: str) -> dict[str, Any]:
    """Check the program's joint moves for collisions and measure the clearance.

    Every move of the program, rewinds included, is sampled as
    :meth:`CollisionWorld.check_moves` does; the clearance of the job's bodies (tool, holder,
    stock) from everything else is measured at the CL points (at most ``CLEARANCE_POINTS`` of
    them, spread evenly: the collision check itself covers every move).

    Parameters
    ----------
    figures : dict
        From :func:`build_program` (its ``world``, ``joints`` and ``joint_lines``).
    toolpath : Toolpath
        For messages.
    units : str
        Program units of the clearance in the result.

    Returns
    -------
    dict
        ``checked`` False when no collision world was built; else the bodies and pairs
        checked, the moves and samples, the smallest clearance, where and between what.

    Raises
    ------
    CollisionError
        A move of the program collides: names the CL line it leads to and the two bodies.
    """
    world = figures.get("world")
    if world is None or "joints" not in figures:
        return {"checked": False}
    from urdfpost.collision import JOB_BODIES

    q, lines = figures["joints"], figures["joint_lines"]
    moves = world.check_moves(q)
    if moves.hit.any():
        k = int(np.argmax(moves.hit))
        a, b = moves.pairs[k]
        raise CollisionError(
            f"{toolpath.source}:{int(lines[k + 1])}: the move to this CL point collides: {a} "
            f"with {b} (at {moves.at[k]:.0%} of the move); nothing written"
        )
    cl_rows = np.flatnonzero(np.r_[True, lines[1:] != lines[:-1]])
    # a distance query costs milliseconds against a large part: measured at no more than
    # CLEARANCE_POINTS CL points spread evenly over the job (all of them in smaller jobs)
    if len(cl_rows) > CLEARANCE_POINTS:
        cl_rows = cl_rows[np.linspace(0, len(cl_rows) - 1, CLEARANCE_POINTS).round().astype(int)]
    near = world.check(q[cl_rows], clearance=True, clearance_of=JOB_BODIES)
    scale = mm_per_unit(units)
    k = int(np.nanargmin(near.clearance)) if len(cl_rows) else 0
    return {
        "checked": True,
        "bodies": len(world.bodies),
        "pairs_checked": len(world.checked_pairs()),
        "moves": len(moves.hit),
        "samples": int(moves.samples.sum()),
        "min_clearance": float(near.clearance[k]) / scale if len(cl_rows) else None,
        "nearest": list(near.nearest[k]) if len(cl_rows) and near.nearest[k] else None,
        "at_cl_line": int(lines[cl_rows[k]]) if len(cl_rows) else None,
        "clearance_points": len(cl_rows),
    }


def bent_tolerances(tol: Tolerances, angle_tolerance_deg: float, pivot: float) -> Tolerances:
    """Tolerances against the CL data for a program whose strategy bent the tool axis.

    The orientation may deviate by the angle tolerance on top of its own; the cutting point,
    ``pivot`` mm up the tool axis (a ball centre), by the tip tolerance plus ``pivot`` times the
    orientation tolerance: what that point moves when tip and axis are each within theirs.
    """
    return replace(
        tol,
        orientation=tol.orientation + float(np.radians(angle_tolerance_deg)),
        tip=tol.tip + pivot * tol.orientation,
    )


def check_program(
    program: Program,
    machine: Machine,
    toolpath: Toolpath,
    figures: dict[str, Any],
    tol: Tolerances,
    tool_length: float,
) -> tuple[Verification, Verification | None]:
    """Verify a program against the CL data, and against its strategy's path when it bent it.

    A strategy that bends the tool axis is checked twice: against the path it intended (rows
    and curve: tip and orientation tolerances as usual), and against the CL data with the
    orientation allowed the angle tolerance on top, measured at the cutting point (the ball
    centre of a ball-end tool, whose tolerance is the tip tolerance plus the ball radius times
    the orientation tolerance: what a ball centre may move when tip and axis are each within
    theirs). A strategy that does not bend is checked against the CL data as it is.

    Parameters
    ----------
    program : Program
        As read back from the text.
    machine : Machine
    toolpath : Toolpath
        The CL data.
    figures : dict
        From :func:`build_program` (its plan, reference path and strategy figures).
    tol : Tolerances
    tool_length : float, mm
        Tool length the machine-coordinate positions include.

    Returns
    -------
    cl : Verification
        Against the CL data.
    intended : Verification or None
        Against the strategy's path (None when it did not bend the tool axis).
    """
    plan: Plan = figures["plan"]
    return check_against(
        program,
        machine,
        toolpath,
        intended_path(figures),
        plan.lifts,
        figures["strategy"],
        tol,
        tool_length,
    )


def intended_path(figures: dict[str, Any]) -> Toolpath | None:
    """The path a plan's strategy intended, from :func:`build_program`'s figures, where it
    bent the tool axis or moved the path; None where the CL data is the path."""
    plan: Plan = figures["plan"]
    reference: Toolpath = figures["reference"]
    return reference if reference is not plan.toolpath or plan.bent else None


def check_against(
    program: Program,
    machine: Machine,
    toolpath: Toolpath,
    reference: Toolpath | None,
    lifts: int,
    strategy: dict[str, Any],
    tol: Tolerances,
    tool_length: float,
) -> tuple[Verification, Verification | None]:
    """:func:`check_program` from the figures it reads.

    Parameters
    ----------
    program, machine, toolpath, tol, tool_length
        As :func:`check_program`.
    reference : Toolpath or None
        The path the strategy intended, where it bent the tool axis or moved the path; None:
        the CL data is the path.
    lifts : int
        Lifted spans of the plan.
    strategy : dict
        The strategy figures of :func:`build_program` (``pivot_mm``, ``angle_tolerance_deg``).

    Returns
    -------
    cl, intended : Verification, Verification or None
    """
    if reference is None:
        return verify(program, machine, toolpath, tool_length=tool_length, tol=tol), None
    pivot = strategy["pivot_mm"]
    loose = bent_tolerances(tol, strategy["angle_tolerance_deg"], pivot)
    intended, cl = verify_checks(
        program, machine, [Check(reference, tol), Check(toolpath, loose, pivot)], tool_length
    )
    if lifts:
        cl = replace(
            cl,
            ok=intended.ok,
            notes=[
                *cl.notes,
                f"{lifts} lifted spans: the tip leaves the CL path there by design",
            ],
        )
    return cl, intended


# figures that stay out of reports
_INTERNAL = ("plan", "reference", "joints", "joint_lines", "world")


def make_report(
    toolpath: Toolpath,
    machine: Machine,
    program: Program,
    check: Verification,
    controller: str,
    figures: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """Report figures: lengths in program units, angles in degrees."""
    scale = mm_per_unit(program.units)
    return {
        "machine": machine.name,
        "controller": controller,
        "tcp": program.tcp,
        "units": program.units,
        "cl_points": check.cl_points,
        "cl_points_reached": check.reached,
        "cl_lines_missed": check.missed_lines,
        "blocks": check.blocks,
        "max_tip_deviation": check.max_tip_deviation / scale,
        "mean_tip_deviation": check.mean_tip_deviation / scale,
        "tip_tolerance": check.tip_tolerance / scale,
        "max_orientation_deviation_deg": check.max_orientation_deviation_deg,
        "orientation_tolerance_deg": check.orientation_tolerance_deg,
        "max_rotary_step_deg": check.max_rotary_step_deg,
        "worst_cl_line": check.worst_cl_line,
        "tool_length_mm": program.tool_length,
        "verified": check.ok,
        **{k: v for k, v in (figures or {}).items() if k not in _INTERNAL},
        "warnings": list(toolpath.warnings) + list((figures or {}).get("warnings", [])),
    }
