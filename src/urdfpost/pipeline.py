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

from urdfpost.branches import Preference
from urdfpost.errors import ToleranceError, UrdfpostError
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
from urdfpost.singularity.detector import joined_runs
from urdfpost.singularity.strategies import (
    DEFAULT_STRATEGY,
    STRATEGIES,
    Plan,
    Problem,
    entry_mask,
    midpoint_solver,
    realise,
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
    strategy : str or None
        Singularity strategy (:data:`urdfpost.singularity.strategies.STRATEGIES`); default the
        machine file's, else :data:`~urdfpost.singularity.strategies.DEFAULT_STRATEGY`.
    angle_tolerance : float
        How far a strategy may bend the tool axis from the programmed one, degrees.
    planner : str
        Branch choice over the whole path ("global") or point by point ("local").
    lift : float
        Lift along the tool axis inside singular spans (``spline`` strategy), program units;
        0 = off.
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
    scale = MM_PER_INCH if units == "inch" else 1.0
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
    )


def build_program(
    toolpath: Toolpath,
    machine: Machine,
    options: PostOptions,
    tol: Tolerances,
    progress: Callable[[int], None] | None = None,
    plan: Plan | None = None,
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

    Returns
    -------
    program : Program
    figures : dict
        Counts gathered on the way (branch switches, pole points, inserted blocks), the plan
        (``"plan"``) and the reference path the program follows (``"reference"``).
    """
    units = options.units or toolpath.units
    problem = make_problem(toolpath, machine, options, tol)
    tool_length = problem.tool_length
    if plan is None:
        plan = STRATEGIES[strategy_name(machine, options)](problem)
    toolpath = plan.toolpath
    n = len(toolpath)
    entry = entry_mask(toolpath)
    figures: dict[str, Any] = {"branch_switches": 0, "pole_points": 0, "inserted_blocks": 0}
    warnings: list[str] = list(plan.notes)
    first_tool = min((e.index for e in toolpath.events if e.kind == "tool"), default=n + 1)
    tool_events: tuple[Event, ...] = ()
    if n and first_tool > 0:
        # controls need a tool (and its length offset) before motion; the CL data has none
        warnings.append(f"{toolpath.source}: no tool change before the first move; tool 1 assumed")
        tool_events = (Event(index=0, kind="tool", line=int(toolpath.line[0]), data={"number": 1}),)
    rows: list[tuple[np.ndarray, np.ndarray, int]] = []  # per output move: q, tip, cl index
    reference = toolpath
    if n:
        q, tip, axis = realise(problem, plan)
        param = plan.param
        whole = param == np.round(param)
        owner = np.where(whole, np.round(param), np.ceil(param)).astype(int)
        first = whole.copy()
        first[1:] &= owner[1:] != owner[:-1]  # the row arriving at its CL point
        rot = plan.rotary
        figures["branch_switches"] = int(
            np.sum(np.abs(np.diff(rot[:, -1])) > np.pi / 2) if len(rot) > 1 else 0
        )
        figures["pole_points"] = int(
            np.sum(np.abs(toolpath.axis @ machine.rotary[0].direction) > 1 - 0.5 * tol.pole**2)
            if machine.rotary
            else 0
        )
        figures["pole_turns"] = int(np.sum(whole & ~first))
        joined = ((toolpath.motion[owner] == Motion.FEED) & ~entry[owner]) | ~first
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
        rows = [
            (out_q[k], out_tip[k], int(group[k]) if is_cl[k] else -1 - int(group[k]))
            for k in range(len(out_q))
        ]
        if plan.bent or plan.lift.any():
            out_axis = np.concatenate(parts_axis)
            turn = (src >= 0) & whole[np.maximum(src, 0)] & ~first[np.maximum(src, 0)]
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
    check, intent = check_program(readback, machine, toolpath, figures, tol, program.tool_length)
    report = make_report(toolpath, machine, program, check, dialect.name, figures)
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
    reference: Toolpath = figures["reference"]
    if reference is plan.toolpath and not plan.bent:
        return verify(program, machine, toolpath, tool_length=tool_length, tol=tol), None
    intended = verify(program, machine, reference, tool_length=tool_length, tol=tol)
    pivot = figures["strategy"]["pivot_mm"]
    loose = bent_tolerances(tol, figures["strategy"]["angle_tolerance_deg"], pivot)
    cl = verify(program, machine, toolpath, tool_length=tool_length, tol=loose, pivot=pivot)
    if plan.lifts:
        cl = replace(
            cl,
            ok=intended.ok,
            notes=[
                *cl.notes,
                f"{plan.lifts} lifted spans: the tip leaves the CL path there by design",
            ],
        )
    return cl, intended


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
        **{k: v for k, v in (figures or {}).items() if k not in ("plan", "reference")},
        "warnings": list(toolpath.warnings) + list((figures or {}).get("warnings", [])),
    }
