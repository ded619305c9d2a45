"""One piece of a post: CL points in, the controller-neutral program and what it was made from out.

:func:`post_piece` is the posting sequence every post runs, once for a whole job
(:func:`urdfpost.posting.whole.post`), once per piece of a streamed one
(:func:`urdfpost.posting.stream.post_stream`) and once per strategy in a comparison
(:func:`urdfpost.analysis.compare.compare`): the strategy's plan, its rewinds, the subdivision of
the feed moves, the program's blocks, and the collision check of its moves. Writing the text,
reading it back and checking it follow in :mod:`urdfpost.posting.check`.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

from urdfpost import _stops
from urdfpost.errors import CollisionError, UrdfpostError
from urdfpost.linearize import subdivide
from urdfpost.machine import Machine
from urdfpost.planning.realise import with_rewinds
from urdfpost.planning.rewinds import CUT, LIFT
from urdfpost.planning.singularity import joined_runs
from urdfpost.planning.strategies import (
    STRATEGIES,
    Plan,
    Problem,
    entry_mask,
    midpoint_solver,
    realise,
)
from urdfpost.posting.arcs import arc_spans
from urdfpost.posting.body import Rows, program_body, program_name
from urdfpost.posting.check import CheckTarget
from urdfpost.posting.feeds import FeedTiming
from urdfpost.posting.options import Job
from urdfpost.posting.planes import PlaneFigures, tilted_planes
from urdfpost.posting.report import Collisions, PieceFigures, Rewind, StrategyFigures
from urdfpost.posting.rollover import with_rollover
from urdfpost.posting.tools import cutting_points, tool_cutters
from urdfpost.posting.transitions import Transitions
from urdfpost.program import REWIND_BEGIN, Blocks, Program
from urdfpost.toolpath import Event, Motion, Toolpath
from urdfpost.units import mm_per_unit
from urdfpost.verification.feeds import FeedRules

if TYPE_CHECKING:
    from urdfpost.collision import CollisionWorld

log = logging.getLogger(__name__)


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


def _rewind_figures(
    machine: Machine,
    toolpath: Toolpath,
    q: np.ndarray,
    owner: np.ndarray,
    kind: np.ndarray,
    retract: float,
) -> tuple[Rewind, ...]:
    """One entry per rewind: CL line, rotary angles before and after (deg), retract (mm)."""
    out = []
    for k in np.flatnonzero(kind == LIFT):
        line = int(toolpath.line[owner[k]])
        turn = {
            a.name: [float(np.degrees(q[k - 1, c])), float(np.degrees(q[k + 2, c]))]
            for a, c in zip(machine.rotary, machine.rotary_columns, strict=True)
        }
        moved = ", ".join(
            f"{n} {f:.3f} -> {t:.3f}" for n, (f, t) in turn.items() if abs(t - f) > 1e-9
        )
        out.append(
            Rewind(
                cl_line=line,
                rotary_deg=turn,
                retract_mm=retract,
                comment=f"{REWIND_BEGIN} CL line {line}: {moved} deg, lift {retract:.3f} mm",
            )
        )
    return tuple(out)


def make_problem(toolpath: Toolpath, job: Job) -> Problem:
    """The strategy input for a post of ``toolpath`` (its collision world built here)."""
    return Problem(
        machine=job.machine,
        toolpath=toolpath,
        tool_length=job.tool_length,
        tol=job.tol,
        angle_tolerance=float(np.radians(job.angle_tolerance_deg)),
        pivot=cutting_points(toolpath)[0] if job.pivot is None else job.pivot,
        prefer=job.prefer,
        planner=job.planner,
        lift=job.lift,
        collision=collision_world(toolpath, job),
        retract=job.retract,
    )


def collision_world(toolpath: Toolpath, job: Job) -> CollisionWorld | None:
    """The FCL world a post checks against, or None when collisions are not checked.

    The tool is the job's cutter (its tool section's, :attr:`Job.cutter`), else the CL data's
    at its first point (diameter, corner radius, length), in the holder of the job; the
    stock mesh is read in program units and placed in the workpiece frame.
    """
    if not job.collisions:
        return None
    from urdfpost.collision import CollisionWorld, ToolBody, load_mesh

    scale = mm_per_unit(job.units)
    cutter = tool_cutters(toolpath)[0] if job.cutter is None else job.cutter  # the section's
    keys = ("diameter", "corner_radius", "length")
    data = {} if cutter is None else dict(zip(keys, cutter, strict=True))
    tool = ToolBody.from_cutter(
        data,
        job.tool_length,
        holder_diameter=job.holder_diameter,
        holder_length=job.holder_length,
    )
    stock = None
    if job.stock:
        stock = load_mesh(job.stock)
        if scale != 1.0:
            stock.apply_scale(scale)
    return CollisionWorld.build(job.machine, tool, job.tool_length, stock)


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
    coolant : str or None
        The coolant mode on where the piece starts (None: off), which a tool change in the
        piece stops and starts again.
    entry : ndarray or None, shape (m,)
        The piece begins a tool section after another (:mod:`urdfpost.posting.tools`): the
        joint vector where the section before left the path (``start`` is None then: the
        piece is planned afresh with its tool's length, and approached as after a tool
        change; ``coolant`` is the one the section before had on, started again).
    leave : bool
        The piece ends a tool section that another follows: it leaves the path after its
        last point as for a tool change.
    offset : int or None
        With ``entry``: the work offset the section selects (a section in another MCS, with
        ``--mcs-offsets``); None: the one before stays.
    keep_tool : bool
        With ``leave``: the next section keeps the tool (no tool change begins it): the
        spindle and coolant stay on.
    """

    start: np.ndarray | None
    tcp_on: bool
    last: bool
    coolant: str | None = None
    entry: np.ndarray | None = None
    leave: bool = False
    offset: int | None = None
    keep_tool: bool = False


@dataclass(frozen=True)
class PostedPiece:
    """What :func:`post_piece` made of a piece of CL data.

    Attributes
    ----------
    program : Program
        The controller-neutral program of the piece.
    plan : Plan
        The strategy's plan it follows.
    target : CheckTarget
        What the program is checked against: the CL points of the piece, and the path the
        strategy intended where it bent the tool axis or moved the path.
    figures : PieceFigures
        Counts gathered on the way, for the report.
    collisions : Collisions
        The collision check of the program's moves.
    joints : ndarray, shape (N, m)
        Joint positions of every row of the program (with the first row of a piece that
        continues another, which its program leaves out), machine units (mm, rad).
    joint_lines : ndarray, shape (N,), int
        The CL line each row belongs to.
    timing : FeedTiming or None
        How the program's feed blocks are still to be timed (``time_feeds`` False: its feed
        moves carry the CL feed, and ``figures.feeds`` is None); None: they are timed.
    """

    program: Program
    plan: Plan
    target: CheckTarget
    figures: PieceFigures
    collisions: Collisions
    joints: np.ndarray
    joint_lines: np.ndarray
    timing: FeedTiming | None = None


def post_piece(
    toolpath: Toolpath,
    job: Job,
    *,
    problem: Problem | None = None,
    plan: Plan | None = None,
    piece: Continuation | None = None,
    progress: Callable[[int], None] | None = None,
    time_feeds: bool = True,
) -> PostedPiece:
    """The program of a piece of CL data, its moves checked for collisions (no text yet).

    Parameters
    ----------
    toolpath : Toolpath
        The CL points of the piece (a whole job is one piece).
    job : Job
        The post's settings (:func:`urdfpost.posting.options.resolve`).
    problem : Problem, optional
        The strategy's input, when already made (:func:`make_problem`; a streamed post makes
        it once and hands it on piece by piece).
    plan : Plan, optional
        The strategy's plan, when already made.
    piece : Continuation, optional
        When the toolpath is a piece of a streamed post: where it starts, and whether it ends
        the program. The program of a piece that continues another has no row for its first
        CL point (the other's last), and only the last piece switches TCP off at its end.
    progress : callable, optional
        Called with the number of CL points just processed.
    time_feeds : bool
        Time the feed blocks here (:func:`urdfpost.posting.feeds.timed_program`); False: the
        caller does, as :attr:`PostedPiece.timing` says (a piece with tilted working planes
        is timed here all the same: the planes are made from the timed program).

    Returns
    -------
    PostedPiece

    Raises
    ------
    UnreachableError
        A CL point no branch reaches within travel.
    CollisionError
        A move of the program collides.
    GeometryError
        Collision geometry that cannot be built (a stock file, a ``<collision>`` element).
    """
    machine, tol, tool_length = job.machine, job.tol, job.tool_length
    cl = toolpath
    if problem is None:
        problem = make_problem(toolpath, job)
    problem = replace(problem, toolpath=toolpath)
    continued = piece is not None and piece.start is not None
    if continued:
        assert piece is not None
        problem = replace(problem, start=piece.start)
    if plan is None:
        plan = STRATEGIES[job.strategy](problem)
    toolpath = plan.toolpath
    n = len(toolpath)
    entry = entry_mask(toolpath)
    branch_switches = pole_points = inserted_blocks = pole_turns = 0
    rewinds: tuple[Rewind, ...] = ()
    warnings: list[str] = list(plan.notes)
    if not n:
        warnings.append(f"{toolpath.source}: no motion records; the program has no moves")
    first_tool = min((e.index for e in toolpath.events if e.kind == "tool"), default=n + 1)
    tool_events: tuple[Event, ...] = ()
    entering = piece is not None and piece.entry is not None  # the tool is in the spindle
    if n and first_tool > 0 and not continued and not entering:
        # controls need a tool (and its length offset) before motion; the CL data has none
        warnings.append(f"{toolpath.source}: no tool change before the first move; tool 1 assumed")
        tool_events = (Event(index=0, kind="tool", line=int(toolpath.line[0]), data={"number": 1}),)
    rows = Rows.empty(len(machine.axis_names))
    start_position = None  # program position where a continued piece starts
    reference = toolpath
    joints = np.zeros((0, len(machine.axis_names)))
    joint_lines = np.zeros(0, dtype=int)
    before: np.ndarray | None = None  # the program row before a continued piece's first
    if n:
        q, tip, axis = realise(problem, plan)
        q, tip, axis, param, kind = with_rewinds(problem, plan, q, tip, axis)
        whole = param == np.round(param)
        owner = np.where(whole, np.round(param), np.ceil(param)).astype(int)
        first = whole.copy()
        # the row arriving at its CL point: not a repeat of the whole row before it (a turn
        # in place), though it may follow rows inserted on the segment to it
        first[1:] &= ~(whole[:-1] & (owner[1:] == owner[:-1]))
        rot = q[:, list(machine.rotary_columns)]
        branch_switches = int(
            np.sum(np.abs(np.diff(rot[:, -1])) > np.pi / 2) if len(rot) > 1 else 0
        )
        rewinds = _rewind_figures(machine, toolpath, q, owner, kind, problem.retract)
        pole_points = int(
            np.sum(np.abs(toolpath.axis @ machine.rotary[0].direction) > 1 - 0.5 * tol.pole**2)
            if machine.rotary
            else 0
        )
        pole_turns = int(np.sum(whole & ~first & (kind == CUT)))
        joined = ((toolpath.motion[owner] == Motion.FEED) & ~entry[owner]) | ~first
        # a turn standing on a reached point goes with the move that leaves the point: before
        # a RAPID it is one rapid block (the written program's too), not subdivided
        standing = whole & ~first
        feed_next = np.append(toolpath.motion[1:] == Motion.FEED, True)
        joined = np.where(standing, feed_next[owner], joined)
        joined &= kind == CUT  # a rewind is no cut: its moves are not subdivided
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
                tcp=job.tcp,
                tol=tol,
                param=param[s : e + 1],
                solve_at=solve_at,
            )
            parts_q += [q[done:s], lin.q]
            parts_tip += [tip[done:s], lin.tip]
            parts_axis += [axis[done:s], lin.axis]
            parts_src += [np.arange(done, s), np.where(lin.source >= 0, lin.source + s, -1)]
            done = e + 1
            inserted_blocks += int(np.sum(lin.source < 0))
            _stops.check()  # (a stop lost on the way, raised between the runs)
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
        out_kind = np.where(src >= 0, kind[np.maximum(src, 0)], CUT)
        rows = Rows(q=out_q, tip=out_tip, point=group, reaches=is_cl, kind=out_kind)
        if continued:  # its first row is the last of the piece before, already written
            assert piece is not None and piece.start is not None
            if not np.allclose(out_q[0], piece.start, rtol=0.0, atol=1e-9):
                raise UrdfpostError(
                    f"{toolpath.source}:{int(toolpath.line[0])}: a streamed piece does not "
                    "start where the piece before ended (internal error)"
                )
            rows = Rows(
                q=out_q[1:], tip=out_tip[1:], point=group[1:], reaches=is_cl[1:], kind=out_kind[1:]
            )
            start_position = program_position(machine, job.tcp, out_q[0], out_tip[0])
            before = out_q[0].copy()
            if job.tcp:
                before[list(machine.linear_columns)] = out_tip[0]
        joints, joint_lines = out_q, toolpath.line[group]
        if plan.bent or plan.lift.any():
            out_axis = np.concatenate(parts_axis)
            turn = (src >= 0) & whole[np.maximum(src, 0)] & ~first[np.maximum(src, 0)]
            turn |= out_kind != CUT
            reference = _reference(toolpath, out_tip, out_axis, group, is_cl, turn)
    strategy = StrategyFigures(
        name=job.strategy,
        angle_tolerance_deg=job.angle_tolerance_deg,
        pivot_mm=problem.pivot,
        bent=plan.bent,
        lifts=plan.lifts,
        spans=tuple(plan.spans),
    )
    events = sorted(tool_events + toolpath.events, key=lambda e: e.index)
    holes: list = []  # the record of the canned cycles' holes (their joint rows)
    rollover = job.rollover & frozenset(a.name for a in machine.rotary if a.continuous)
    transitions = Transitions(machine, job.tcp, tool_length, job.clearance, rollover=rollover)
    arc_events = [e for e in events if e.kind == "arc"]
    events = [e for e in events if e.kind != "arc"]
    arcs = arc_spans(
        toolpath,
        arc_events,
        machine,
        rows,
        tcp=job.tcp,
        tool_length=tool_length,
        tol=tol,
        spec=job.dialect.spec if job.arcs else None,
        events=events,
        joints_before=piece.start if piece is not None and continued else None,
    )
    warnings += [f"{toolpath.source}: {note}" for note in arcs.notes]
    comp = next((e for e in events if e.kind == "cutcom" and e.data.get("side") != "off"), None)
    if comp is not None:
        warnings.append(
            f"{toolpath.source}:{comp.line}: cutter radius compensation {comp.data['side']} "
            "is the control's (G41/G42, RL/RR): the program is the CL path, which "
            "verification checks; the control offsets it by the radius in its tool table"
        )
    # 3+2 operations in tilted planes: TCP posts on a control that has them, of whole tool
    # sections (a streamed piece that begins or ends within one may cut an operation in two)
    whole = piece is None or (piece.start is None and (piece.last or piece.leave))
    planes = (
        job.tilted_planes and job.tcp and whole and job.dialect.spec.plane_convention is not None
    )
    body = program_body(
        toolpath,
        machine,
        job.tcp,
        rows,
        events,
        [r.comment for r in rewinds],
        job.rewind_feed,
        tcp_on=piece is not None and piece.tcp_on,
        coolant=None if piece is None else piece.coolant,
        close=piece is None or piece.last,
        transitions=transitions,
        work_offset=_work_offset(job, piece),
        entry=None if piece is None else piece.entry,
        leave=piece is not None and piece.leave,
        keep_tool=piece is not None and piece.keep_tool,
        expand_cycles=job.expand_cycles,
        notes=warnings,
        runs_cycle=job.dialect.spec.runs_cycle,
        motion=holes,
        smoothing=job.smoothing,
        arcs=arcs.spans,
        tilted_cycles=planes,
    )
    body, rolled = with_rollover(body, machine.axis_names, rollover, tol, start_position)
    if rolled.splits:
        log.info(
            "%s: %d moves that turn a rollover axis by more than %.0f deg split",
            toolpath.source,
            rolled.splits,
            np.degrees(tol.rollover_turn),
        )
    program = Program(
        name=program_name(toolpath, job.program_name),
        axes=machine.axis_names,
        rotary=frozenset(a.name for a in machine.rotary),
        units=job.units,
        tcp=job.tcp,
        blocks=Blocks(body),
        tool_length=tool_length,
        continuous=frozenset(a.name for a in machine.rotary if a.continuous),
        rollover=rollover,
    )
    spec = job.dialect.spec
    timing: FeedTiming | None = FeedTiming(job.feed_mode, spec, tool_length, before)
    feed_figures = None
    if time_feeds or planes:
        assert timing is not None
        program, feed_figures = timing.timed(program, machine)
        timing = None
    plane_figures = PlaneFigures()
    if planes:
        plane_notes: list[str] = []
        program, plane_figures = tilted_planes(
            program, machine, spec, plane_notes, machine.settings.clamps
        )
        warnings += [f"{toolpath.source}: {note}" for note in plane_notes]
    figures = PieceFigures(
        branch_switches=branch_switches,
        pole_points=pole_points,
        inserted_blocks=inserted_blocks,
        rewinds=rewinds,
        pole_turns=pole_turns,
        strategy=strategy,
        warnings=tuple(warnings),
        feeds=feed_figures,
        arcs=arcs.arcs,
        arcs_linear=arcs.linear,
        planes=plane_figures.planes,
    )
    intended = reference if reference is not plan.toolpath or plan.bent else None
    target = CheckTarget(
        cl=cl,
        intended=intended,
        lifts=plan.lifts,
        pivot_mm=problem.pivot,
        angle_tolerance_deg=job.angle_tolerance_deg,
        tool_length=tool_length,
        # (the largest inverse-time F counts in inverse time only)
        feed_rules=FeedRules.of(spec, job.units),
    )
    # the moves as the program makes them: a canned cycle's holes drilled, not its CL points
    moved, moved_lines = (
        holes[0].joint_path(joints, joint_lines) if holes else (joints, joint_lines)
    )
    collisions = check_collisions(problem.collision, moved, moved_lines, cl)
    check_transitions(problem.collision, transitions, cl)
    return PostedPiece(program, plan, target, figures, collisions, joints, joint_lines, timing)


def _work_offset(job: Job, piece: Continuation | None) -> int | None:
    """The work offset the piece's body selects: the job's where it starts the program, a
    section's own where it enters one in another MCS, else none."""
    if piece is None or (piece.start is None and piece.entry is None):
        return job.work_offset
    return piece.offset if piece.entry is not None else None


def program_position(machine: Machine, tcp: bool, q: np.ndarray, tip: np.ndarray) -> np.ndarray:
    """The program's axis values of one row: degrees for the rotary axes, the tip (TCP) or
    the joints (mm) for the linear ones; shape (m,)."""
    rotary = np.array([a.rotary for a in machine.axes])
    position = np.where(rotary, np.degrees(q), q)
    if tcp:
        position[list(machine.linear_columns)] = tip
    return position


CLEARANCE_POINTS = 500


def check_transitions(
    world: CollisionWorld | None, transitions: Transitions, toolpath: Toolpath
) -> None:
    """Check the moves off the path (approach, retract, end) for collisions.

    Raises
    ------
    CollisionError
        A move collides: names the CL line the transition leads to or leaves.
    """
    if world is None:
        return
    for line, path in transitions.paths:
        moves = world.check_moves(path)
        if moves.hit.any():
            k = int(np.argmax(moves.hit))
            hit = moves.pairs[k]
            assert hit is not None
            raise CollisionError(
                f"{toolpath.source}:{line}: the safe approach or retract at this CL point "
                f"collides: {hit[0]} with {hit[1]} (move {k + 1} of {len(path) - 1}, at "
                f"{moves.at[k]:.0%}); a larger --clearance may help; nothing written"
            )


def check_collisions(
    world: CollisionWorld | None, q: np.ndarray, lines: np.ndarray, toolpath: Toolpath
) -> Collisions:
    """Check the program's joint moves for collisions and measure the clearance.

    Every move of the program, rewinds included, is sampled as
    :meth:`CollisionWorld.check_moves` does; the clearance of the job's bodies (tool, holder,
    stock) from everything else is measured at the CL points (at most ``CLEARANCE_POINTS`` of
    them, spread evenly: the collision check itself covers every move).

    Parameters
    ----------
    world : CollisionWorld or None
        None: collisions are not checked.
    q : ndarray, shape (N, m)
        Joint positions of the program's rows (mm, rad).
    lines : ndarray, shape (N,), int
        The CL line of each row.
    toolpath : Toolpath
        For messages.

    Returns
    -------
    Collisions

    Raises
    ------
    CollisionError
        A move of the program collides: names the CL line it leads to and the two bodies.
    """
    if world is None or not len(q):
        return Collisions()
    from urdfpost.collision import JOB_BODIES

    moves = world.check_moves(q)
    if moves.hit.any():
        k = int(np.argmax(moves.hit))
        hit = moves.pairs[k]
        assert hit is not None  # a colliding move names its pair
        a, b = hit
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
    assert near.clearance is not None and near.nearest is not None  # asked for
    k = int(np.nanargmin(near.clearance)) if len(cl_rows) else 0
    return Collisions(
        checked=True,
        bodies=len(world.bodies),
        pairs_checked=len(world.checked_pairs()),
        moves=len(moves.hit),
        samples=int(moves.samples.sum()),
        min_clearance=float(near.clearance[k]) if len(cl_rows) else None,
        nearest=list(pair) if len(cl_rows) and (pair := near.nearest[k]) else None,
        at_cl_line=int(lines[cl_rows[k]]) if len(cl_rows) else None,
        clearance_points=len(cl_rows),
    )
