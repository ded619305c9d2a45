"""Posting: CL toolpath to a checked NC program, with no files opened.

``post(toolpath, machine, options)`` runs the whole chain: solution choice per point
(:mod:`urdfpost.branches`), subdivision of feed moves until the nonlinear error is within
tolerance (:mod:`urdfpost.linearize`), the controller-neutral program (:mod:`urdfpost.program`),
its text in the chosen dialect, and the verification of that text read back through the machine
(:mod:`urdfpost.verify`). A program that misses its tolerance is an error.
"""

from __future__ import annotations

import logging
import re
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from urdfpost.branches import Preference, select
from urdfpost.errors import ToleranceError
from urdfpost.kinematics.inverse import IKStatus, solve_linear
from urdfpost.linearize import subdivide
from urdfpost.machine import Machine
from urdfpost.program import (
    Block,
    Comment,
    Coolant,
    Home,
    Insert,
    Move,
    Program,
    Spindle,
    Stop,
    Tcp,
    ToolChange,
)
from urdfpost.tolerances import MM_PER_INCH, Tolerances
from urdfpost.toolpath import Event, Motion, Toolpath
from urdfpost.verify import Verification, verify

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
    """

    controller: str | None = None
    tcp: bool = True
    units: str | None = None
    tool_length: float | None = None
    tolerance: float | None = None
    prefer: Preference | None = None
    block_numbers: bool = False
    program_name: str | None = None


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


def _feed_runs(joined: np.ndarray) -> list[tuple[int, int]]:
    """Maximal runs [s, e] of points joined by feed moves (e > s).

    ``joined[i]`` says point i is reached from point i - 1 by a feed move of the same cut.
    """
    runs = []
    n = len(joined)
    i = 0
    while i < n - 1:
        if joined[i + 1]:
            j = i + 1
            while j + 1 < n and joined[j + 1]:
                j += 1
            runs.append((i, j))
            i = j
        else:
            i += 1
    return runs


def split_at_pole_crossings(toolpath: Toolpath, machine: Machine, tol: Tolerances) -> Toolpath:
    """Insert the point where a feed move's tool axis sweeps through a pole.

    Between two CL points the tool axis follows the great circle from one axis to the other.
    Where that arc passes a pole (the tool axis along the first rotary axis) within
    ``tol.pole_crossing``, the crossing point is added on the CL segment with its axis exactly
    on the pole; the branch choice holds the first rotary angle there and the pipeline turns it
    in place, instead of leaving a half turn inside one block.

    Returns
    -------
    Toolpath
        With the crossing points added (their ``line`` is that of the move's end point), events
        re-indexed; the same object when nothing crosses.
    """
    n = len(toolpath)
    if n < 2:
        return toolpath
    va, vb = toolpath.axis[:-1], toolpath.axis[1:]
    normal = np.cross(va, vb)
    size = np.linalg.norm(normal, axis=1)
    span = np.arctan2(size, np.sum(va * vb, axis=1))
    feed = toolpath.motion[1:] == Motion.FEED
    inserts: list[tuple[int, float, np.ndarray]] = []
    for pole in (machine.rotary[0].direction, -machine.rotary[0].direction):
        with np.errstate(invalid="ignore", divide="ignore"):
            nrm = normal / size[:, None]
            off_plane = np.abs(nrm @ pole)  # sine of the distance of the pole from the circle
            proj = pole - (nrm @ pole)[:, None] * nrm
            proj /= np.linalg.norm(proj, axis=1, keepdims=True)
            sa = np.arctan2(np.linalg.norm(np.cross(va, proj), axis=1), np.sum(va * proj, axis=1))
            sb = np.arctan2(np.linalg.norm(np.cross(proj, vb), axis=1), np.sum(proj * vb, axis=1))
        on_arc = np.abs(sa + sb - span) < 1e-9
        s = sa / np.where(span > 0, span, 1.0)
        hit = (
            feed
            & (size > 1e-12)
            & (off_plane < np.sin(tol.pole_crossing))
            & on_arc
            & (sa > tol.pole_crossing)
            & (sb > tol.pole_crossing)
        )
        inserts += [(int(i), float(s[i]), pole) for i in np.flatnonzero(hit)]
    if not inserts:
        return toolpath
    inserts.sort(key=lambda x: (x[0], x[1]))
    at = np.array([i + 1 for i, _, _ in inserts])
    tips = np.array(
        [toolpath.tip[i] + s * (toolpath.tip[i + 1] - toolpath.tip[i]) for i, s, _ in inserts]
    )
    axes = np.array([pole for _, _, pole in inserts])
    new_index = np.arange(n) + np.searchsorted(at, np.arange(n), side="right")
    log.debug("%d pole crossings between CL points", len(inserts))
    return replace(
        toolpath,
        tip=np.insert(toolpath.tip, at, tips, axis=0),
        axis=np.insert(toolpath.axis, at, axes, axis=0),
        feed=np.insert(toolpath.feed, at, toolpath.feed[at]),
        motion=np.insert(toolpath.motion, at, Motion.FEED),
        line=np.insert(toolpath.line, at, toolpath.line[at]),
        events=tuple(
            replace(e, index=int(new_index[e.index]) if e.index < n else len(toolpath) + len(at))
            for e in toolpath.events
        ),
    )


def _turn_at_poles(
    machine: Machine, sel: Any, toolpath: Toolpath, tool_length: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Insert a turn of the first rotary axis in place where the path leaves a pole.

    At a pole the first rotary axis lies along the tool axis, so turning it does not change
    the orientation: the angle the next point needs is reached while the tool stands on the
    pole point (tip held, linear axes re-solved), instead of during the move away from it.

    Returns
    -------
    q : ndarray, shape (N, m)
    tip, axis : ndarray, shape (N, 3)
    owner : ndarray, shape (N,), int
        CL point index of each row (an inserted row repeats its pole point).
    """
    n = len(toolpath)
    col = machine.rotary_columns[0]
    pole = sel.status == IKStatus.POLE
    entry = np.zeros(n, dtype=bool)
    for e in toolpath.events:
        if e.kind == "tool" and e.index < n:
            entry[e.index] = True
    turn = np.flatnonzero(pole[:-1] & (np.abs(np.diff(sel.q[:, col])) > 1e-9) & ~entry[1:])
    owner = np.insert(np.arange(n), turn + 1, turn)
    q = sel.q[owner].copy()
    rows = turn + 1 + np.arange(len(turn))  # positions of the inserted rows
    if len(turn):
        q[rows, col] = sel.q[turn + 1, col]
        rot = q[rows][:, list(machine.rotary_columns)]
        lin = solve_linear(machine, rot, toolpath.tip[turn], tool_length)
        q[rows[:, None], list(machine.linear_columns)] = lin
    return q, toolpath.tip[owner], toolpath.axis[owner], owner


def build_program(
    toolpath: Toolpath,
    machine: Machine,
    options: PostOptions,
    tol: Tolerances,
    progress: Callable[[int], None] | None = None,
) -> tuple[Program, dict[str, Any]]:
    """The controller-neutral program for a toolpath (no verification).

    Returns
    -------
    program : Program
    figures : dict
        Counts gathered on the way (branch switches, pole points, inserted blocks).
    """
    units = options.units or toolpath.units
    toolpath = split_at_pole_crossings(toolpath, machine, tol)
    tool_length = (
        machine.settings.tool_length if options.tool_length is None else options.tool_length
    )
    n = len(toolpath)
    entry = np.zeros(n, dtype=bool)
    for e in toolpath.events:
        if e.kind == "tool" and e.index < n:
            entry[e.index] = True
    figures: dict[str, Any] = {"branch_switches": 0, "pole_points": 0, "inserted_blocks": 0}
    warnings: list[str] = []
    first_tool = min((e.index for e in toolpath.events if e.kind == "tool"), default=n + 1)
    tool_events: tuple[Event, ...] = ()
    if n and first_tool > 0:
        # controls need a tool (and its length offset) before motion; the CL data has none
        warnings.append(f"{toolpath.source}: no tool change before the first move; tool 1 assumed")
        tool_events = (Event(index=0, kind="tool", line=int(toolpath.line[0]), data={"number": 1}),)
    rows: list[tuple[np.ndarray, np.ndarray, int]] = []  # per output move: q, tip, cl index
    if n:
        sel = select(
            machine,
            toolpath.tip,
            toolpath.axis,
            tool_length=tool_length,
            prefer=options.prefer,
            entry=entry,
            lines=toolpath.line,
            source=toolpath.source,
            tol=tol,
        )
        figures["branch_switches"] = int(np.sum(np.diff(sel.branch) != 0))
        figures["pole_points"] = int(np.sum(sel.status == IKStatus.POLE))
        q, tip, axis, owner = _turn_at_poles(machine, sel, toolpath, tool_length)
        figures["pole_turns"] = int(len(q) - n)
        first = np.ones(len(q), dtype=bool)
        first[1:] = owner[1:] != owner[:-1]  # the row arriving at its CL point
        joined = ((toolpath.motion[owner] == Motion.FEED) & ~entry[owner]) | ~first
        parts_q, parts_tip, parts_src = [], [], []
        done = 0
        for s, e in _feed_runs(joined):
            lin = subdivide(
                machine,
                q[s : e + 1],
                tip[s : e + 1],
                axis[s : e + 1],
                tool_length=tool_length,
                tcp=options.tcp,
                tol=tol,
            )
            parts_q += [q[done:s], lin.q]
            parts_tip += [tip[done:s], lin.tip]
            parts_src += [np.arange(done, s), np.where(lin.source >= 0, lin.source + s, -1)]
            done = e + 1
            figures["inserted_blocks"] += int(np.sum(lin.source < 0))
            if progress:
                progress(int(owner[e] - owner[s]))
        parts_q.append(q[done:])
        parts_tip.append(tip[done:])
        parts_src.append(np.arange(done, len(q)))
        out_q, out_tip = np.concatenate(parts_q), np.concatenate(parts_tip)
        src = np.concatenate(parts_src)
        # an inserted row belongs to the move towards the next original row
        nxt = np.where(src >= 0, src, len(q))
        nxt = np.minimum.accumulate(nxt[::-1])[::-1]
        group = owner[np.minimum(nxt, len(q) - 1)]
        is_cl = (src >= 0) & first[np.maximum(src, 0)]
        rows = [
            (out_q[k], out_tip[k], int(group[k]) if is_cl[k] else -1 - int(group[k]))
            for k in range(len(out_q))
        ]

    axes = machine.axis_names
    rotary = frozenset(a.name for a in machine.rotary)
    lin_cols = list(machine.linear_columns)
    blocks: list[Block] = []
    tcp_state = [False]
    # first programmed feed after each point (backward fill), for turns in place
    fill = np.where(np.isfinite(toolpath.feed), np.arange(n), n)
    fill = np.minimum.accumulate(fill[::-1])[::-1]
    feeds = np.append(toolpath.feed, np.nan)
    next_feed = feeds[np.append(fill[1:], n)] if n else feeds
    events = sorted(tool_events + toolpath.events, key=lambda e: e.index)
    ev = 0
    arrived = -1  # last CL point reached
    for q, tip, code in rows:
        g = code if code >= 0 else -1 - code  # the CL point this row reaches or stands on
        while ev < len(events) and events[ev].index <= g:
            blocks.extend(_event_blocks(events[ev], tcp_state, options.tcp))
            ev += 1
        position = np.where([a in rotary for a in axes], np.degrees(q), q)
        if options.tcp:
            position[lin_cols] = tip
            if not tcp_state[0]:
                blocks.append(Tcp(on=True))
                tcp_state[0] = True
        # rows standing on a reached point (a turn at a pole) move at the feed of the move
        # that follows, even when the point was reached by a rapid
        turning = g == arrived
        rapid = bool(toolpath.motion[g] == Motion.RAPID) and not turning
        f = next_feed[g] if turning else toolpath.feed[g]
        feed = float(f) if np.isfinite(f) else None
        blocks.append(
            Move(
                rapid=rapid,
                position=tuple(float(x) for x in position),
                feed=None if rapid else feed,
                cl_line=int(toolpath.line[g]) if code >= 0 else None,
            )
        )
        if code >= 0:
            arrived = g
    for e in events[ev:]:
        blocks.extend(_event_blocks(e, tcp_state, options.tcp))
    if tcp_state[0]:
        blocks.append(Tcp(on=False))
    program = Program(
        name=_program_name(toolpath, options),
        axes=axes,
        rotary=rotary,
        units=units,
        tcp=options.tcp,
        blocks=tuple(blocks),
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
    header = None
    if not options.tcp:
        header = (
            f"machine coordinates for machine {machine.name} with tool length "
            f"{program.tool_length:.3f} mm from the gauge point: the tool table length must be 0"
        )
    text = dialect.write(program, block_numbers=options.block_numbers or None, header=header)
    inserts = [b.text for b in program.blocks if isinstance(b, Insert)]
    readback = dialect.read(text, path=f"<{dialect.name} program>", verbatim=inserts)
    check = verify(readback, machine, toolpath, tool_length=program.tool_length, tol=tol)
    report = make_report(toolpath, machine, program, check, dialect.name, figures)
    if not check.ok:
        raise ToleranceError(
            f"{toolpath.source}: the program misses its tolerance, nothing written: "
            f"{check.summary(units)}"
            + (f"; worst near CL line {check.worst_cl_line}" if check.worst_cl_line else "")
        )
    return PostResult(program=program, text=text, verification=check, report=report)


def make_report(
    toolpath: Toolpath,
    machine: Machine,
    program: Program,
    check: Verification,
    controller: str,
    figures: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """Report figures: lengths in program units, angles in degrees."""
    scale = MM_PER_INCH if program.units == "inch" else 1.0
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
        **(figures or {}),
        "warnings": list(toolpath.warnings) + list((figures or {}).get("warnings", [])),
    }
