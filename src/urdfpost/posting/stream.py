"""Posting in pieces: a long job in bounded memory, written and verified as it goes.

:func:`post_stream` takes the CL data as consecutive pieces (from
:func:`urdfpost.readers.read_cl_chunks`, or slices of one toolpath) and posts them one piece of
about ``piece_points`` CL points at a time. Nothing of the whole job is held but what the
figures need, so memory depends on the piece size and not on the length of the job.

How the pieces join:

- **Planning** sees ahead. Each piece is planned over a window of ``lookahead`` more CL points
  than it posts (the singularity strategy, branch choice and rewinds as in :func:`post`), and
  only the part up to the cut is kept. The cut is a CL point where nothing spans it: a feed
  move on both sides, no CL event there, no singular span or lift within a point of it, the
  tool axis away from the poles and as programmed (not bent by the strategy), and one program
  row there. The next window starts at that point, which takes the angles the piece before
  chose exactly (``fixed_start`` of :func:`urdfpost.planning.branches.select`), so the joint path is
  continuous and no rewind or branch switch appears at a cut. The branch choice at a cut is
  the best one over the window, which sees ``lookahead`` points past it. Where the best paths
  into every candidate still possible at the window's end agree up to the cut (the survivors
  of the branch planner have met:
  :attr:`urdfpost.planning.branches.Selection.settled`), no CL points
  after the window can change it, and the choice is the one a plan of the whole job makes;
  such a cut is preferred (in the second half of the piece). Where there is none, as when
  both branches stay within travel all along, the choice rests on the lookahead: a travel
  limit further on that the other branch avoids would get a rewind later instead. The report
  lists those joins (``streamed.unsettled_joins``) and warns; the joins after one start from
  its choice, and are settled given it. A strategy that shapes a whole feed run (``cone``)
  shapes the two halves of a run cut in two on their own. Either way the program is checked
  like any other, and on jobs without such cases the text is the one :func:`post` writes.
- **Writing** is one program: the control's writer keeps its modal state and block numbers
  from piece to piece, and the text goes to a temporary file beside the output, renamed into
  place when the last piece is verified (nothing is left behind on an error). The pieces are
  written where they are verified (:class:`urdfpost.posting.worker.Writing`): the post hands
  over each piece's program.
- **Verification** reads back each piece's text with one reader (its modal state carries on
  too) and checks it against the piece's CL points, starting from the last row of the piece
  before: every block of the program is checked once. The figures are merged. On a machine
  with more than one core the writing and this run in a worker process, behind the
  planning, so the two share the work (a piece is handed over when the one two before it is
  checked: one piece waits at most, :data:`~urdfpost.posting.worker.POST_DEPTH`). A piece
  that misses its tolerance stops the post all the same. The process (feeds, spindle, tools,
  length offsets) is checked there too, from the same read
  (:class:`urdfpost.verification.process.PieceProcess`: the one read serves both checks, and
  the planning keeps its core), and refused at the end with the message of a whole post.

The singular spans of the report are numbered along the pieces' plan paths joined (each join
once), as :func:`post` numbers them along its plan's path. Figures that depend on the whole job
are taken from the first window: the program name
(``PARTNO``). The cutting point the strategy pivots about and the tool of the collision world
are those of each tool section (:func:`urdfpost.posting.tools.tool_sections`: a tool change to
another cutting point, or with collisions checked to another cutter, begins one).
"""

from __future__ import annotations

import logging
import os
import shutil
from collections.abc import Callable, Iterable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from urdfpost import _stops
from urdfpost._files import give_mode, temp_file
from urdfpost.dialects import Dialect
from urdfpost.errors import CLDataError, LinearTravelError, ToleranceError
from urdfpost.geometry import angle_between
from urdfpost.machine import Machine
from urdfpost.planning.strategies import STRATEGIES, Plan, tool_axis_of
from urdfpost.posting import LOOKAHEAD, PIECE_POINTS
from urdfpost.posting.body import coolant_after
from urdfpost.posting.header import HeaderFigures, job_header, stock_box
from urdfpost.posting.options import Job, PostOptions, resolve
from urdfpost.posting.piece import Continuation, make_problem, post_piece
from urdfpost.posting.process import SpindleState, checked_process, one_tool_length
from urdfpost.posting.readback import merge_verifications, program_texts
from urdfpost.posting.report import (
    Collisions,
    FeedFigures,
    PieceFigures,
    Report,
    StreamFigures,
)
from urdfpost.posting.tools import gauge_lengths, tool_sections
from urdfpost.posting.worker import FORK, POST_DEPTH, Checks, ProgramJob, Writing
from urdfpost.program import Blocks, Program
from urdfpost.tolerances import Tolerances
from urdfpost.toolpath import Motion, Toolpath, joined, toolpath_slice
from urdfpost.verification import Verification
from urdfpost.verification.process import located

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class StreamResult:
    """What :func:`post_stream` produced.

    Attributes
    ----------
    path : Path
        The program file written.
    verification : Verification
        Of the whole program read back, against the CL data (the pieces' checks merged).
    report : Report
        As :func:`urdfpost.posting.whole.post` reports, with ``streamed`` figures (pieces, piece
        size, lookahead).
    """

    path: Path
    verification: Verification
    report: Report


@dataclass(frozen=True)
class _Cut:
    point: int  # CL index in the window
    plan: Plan  # the plan up to it
    settled: bool  # whether the branch choice up to it is the one the whole job would make


def _cut(
    window: Toolpath, plan: Plan, target: int, machine: Machine, tol: Tolerances
) -> _Cut | None:
    """The last CL point at or before ``target`` where a piece can end (module docstring),
    and the window's plan up to it; None when there is none.

    A point where the branch choice is settled (:attr:`Plan.settled`: no CL points after the
    window could change it) is taken when there is one in the second half of the piece;
    otherwise the last possible point, whose choice rests on the lookahead.
    """
    n = len(window)
    hi = min(target, n - 2)
    lo = 1
    c = np.arange(lo, hi + 1)
    line, motion = window.line, window.motion
    ok = (motion[c] == Motion.FEED) & (motion[c + 1] == Motion.FEED)
    ok &= (line[c - 1] < line[c]) & (line[c] < line[c + 1])
    events = np.array([e.index for e in window.events], dtype=np.int64)
    ok &= ~np.isin(c, events) & ~np.isin(c + 1, events)
    if machine.rotary:  # the tool axis well away from the poles of the first rotary axis
        cos_pole = np.abs(window.axis[c] @ machine.rotary[0].direction)
        ok &= cos_pole < np.cos(10.0 * max(tol.pole, tol.pole_crossing))
    spans = [(s.first, s.last) for s in plan.spans]
    settled = len(plan.toolpath) - 1 if plan.settled is None else plan.settled
    points = c[ok]

    def last_regular(upto: int, down_to: int) -> tuple[int, int] | None:
        """The last point at or before CL point ``upto`` (and not before ``down_to``) where a
        piece can end, with its plan point."""
        for point in points[: np.searchsorted(points, upto, side="right")][::-1].tolist():
            if point < down_to:
                break
            at = _regular(window, plan, point, spans, machine)
            if at is not None:
                return point, at
        return None

    found = last_regular(target, 0)
    if found is None:
        return None
    if found[1] > settled and settled >= 0:  # a settled point in the second half?
        upto = int(np.searchsorted(line, plan.toolpath.line[settled], side="right")) - 1
        earlier = last_regular(upto, target // 2)
        if earlier is not None:
            return _kept(plan, *earlier, settled=True)
    return _kept(plan, *found, settled=found[1] <= settled)


def _regular(
    window: Toolpath, plan: Plan, point: int, spans: list[tuple[int, int]], machine: Machine
) -> int | None:
    """The plan's point of CL point ``point`` when a piece can end there (no span, lift, turn
    in place or bent axis at it: the module docstring), else None."""
    tp = plan.toolpath
    at = int(np.searchsorted(tp.line, window.line[point], side="right")) - 1
    if at < 1 or at >= len(tp) - 1 or tp.line[at] != window.line[point]:
        return None
    if not (
        np.array_equal(tp.tip[at], window.tip[point])
        and np.array_equal(tp.axis[at], window.axis[point])
    ):
        return None  # moved by the strategy
    if any(first - 1 <= at <= last + 1 for first, last in spans):
        return None
    r = int(np.searchsorted(plan.param, at, side="left"))
    if int(np.searchsorted(plan.param, at, side="right")) - r != 1:
        return None  # a turn in place or a rewind there, or no row
    if plan.lift[max(r - 1, 0) : r + 2].any():
        return None
    if angle_between(tool_axis_of(machine, plan.rotary[r : r + 1]), tp.axis[at])[0] > 1e-9:
        return None  # the strategy bent the tool axis there: the next piece starts exact
    return at


def _kept(plan: Plan, point: int, at: int, *, settled: bool) -> _Cut:
    """The cut at CL point ``point`` of the window, point ``at`` of the plan."""
    r = int(np.searchsorted(plan.param, at))
    kept = replace(
        plan,
        toolpath=toolpath_slice(plan.toolpath, 0, at + 1),
        param=plan.param[: r + 1],
        rotary=plan.rotary[: r + 1],
        lift=plan.lift[: r + 1],
        spans=[s for s in plan.spans if s.last < at],
        settled=min(at, len(plan.toolpath) - 1 if plan.settled is None else plan.settled),
    )
    return _Cut(point=point, plan=kept, settled=settled)


def post_stream(
    pieces: Iterable[Toolpath],
    machine: Machine,
    out: str | os.PathLike[str],
    options: PostOptions | None = None,
    *,
    piece_points: int = PIECE_POINTS,
    lookahead: int | None = None,
    progress: Callable[[int], None] | None = None,
    parallel: bool | None = None,
) -> StreamResult:
    """Post CL data given in pieces to a program file, a piece at a time (module docstring).

    Parameters
    ----------
    pieces : iterable of Toolpath
        Consecutive pieces of one job (:func:`urdfpost.readers.read_cl_chunks`), any sizes.
    machine : Machine
    out : path
        The program file; written only when the whole program is verified.
    options : PostOptions, optional
    piece_points : int
        CL points posted per piece (the last may be up to ``lookahead`` longer).
    lookahead : int, optional
        CL points past a piece's end its plan takes into account; default a fifth of
        ``piece_points``, at most :data:`~urdfpost.posting.LOOKAHEAD`.
    progress : callable, optional
        Called with the number of CL points just posted.
    parallel : bool, optional
        Verify each piece in a worker process while the next one is planned; default on Linux
        when the machine has more than one core and the job more than one piece. On Linux the
        worker is forked: from an application with other threads running (which a fork does
        not carry over, locks they hold included) pass False. Elsewhere it is spawned: the
        calling script needs the ``if __name__ == "__main__"`` guard of
        :mod:`multiprocessing`.

    Returns
    -------
    StreamResult

    Raises
    ------
    UnreachableError, CollisionError, GeometryError, ToleranceError, UrdfpostError
        As :func:`urdfpost.posting.whole.post`; nothing is written then.
    ValueError
        ``piece_points`` under 2 or ``lookahead`` under 1.
    """
    if lookahead is None:
        lookahead = max(1, min(LOOKAHEAD, piece_points // 5))
    if piece_points < 2 or lookahead < 1:
        raise ValueError(
            f"piece_points must be at least 2 and lookahead at least 1, got {piece_points} and "
            f"{lookahead}"
        )
    out = Path(out)
    source = iter(pieces)
    buffer = next(source, None)
    if buffer is None:
        raise ValueError("post_stream: no toolpath pieces given")
    exhausted = False
    job = resolve(options, machine, buffer.units)
    dialect, units, tol = job.dialect, job.units, job.tol
    base = None
    header: HeaderFigures | None = None  # the header's figures so far
    first_program: Program | None = None  # (without its blocks)
    blank = stock_box(job)  # the stock's box for the control's graphics (BLK FORM)
    placeholder = 0  # bytes of the program's opening written with the placeholder header
    figures: PieceFigures | None = None
    collisions: list[Collisions] = []
    offset = 0  # index of the piece's first point in the joined plan paths
    start: np.ndarray | None = None
    last_piece: Toolpath | None = None
    reader_warnings: list[str] = []  # the job's, in order
    spindle: SpindleState | None = None  # where the pieces read so far leave the spindle
    tools: frozenset[int] = frozenset()  # tool numbers seen
    lengths: dict[int, float] = {}  # machine coordinates: each tool's gauge length, mm

    def taken_in(read: Toolpath) -> Toolpath:
        """A piece as read, its process checked and filled in (:func:`checked_process`, from
        where the pieces before left it), its warnings added to the job's and its tools'
        gauge lengths noted."""
        nonlocal spindle, tools
        reader_warnings.extend(read.warnings)
        _refuse_cycles(read)
        read, spindle, notes = checked_process(
            replace(read, warnings=()),
            feed=job.feed,
            spindle=job.spindle,
            units=job.units,
            state=spindle,
            spec=dialect.spec,
            tcp=job.tcp,
        )
        reader_warnings.extend(notes)
        if not job.tcp:
            notes, tools = one_tool_length(read, job.tool_length, job.units, tools, job.tool_table)
            reader_warnings.extend(notes)
            lengths.update(gauge_lengths(read, job.tool_length, job.tool_table))
        return read

    buffer = taken_in(buffer)
    section = job  # the job with the gauge length of the tool section being posted
    entry: np.ndarray | None = None  # a new tool section: where the one before left the path
    fresh: list[bool] = []  # per piece: it begins a tool section
    checks: Checks | None = None
    inserts: list[str] = []  # the texts of the program's inserted blocks
    piece_feeds: list[FeedFigures | None] = []  # per piece: its feed timing's figures, if done here
    unsettled: list[int] = []  # CL lines of the joins whose branch choice rests on the lookahead
    count = 0
    tool_length = job.tool_length
    coolant: str | None = None  # on where the next piece starts
    fd, tmp = temp_file(out)  # (and the ones a killed post of ``out`` left, removed)
    try:
        os.close(fd)  # (written by the checks: :class:`~urdfpost.posting.worker.Writing`)
        want = piece_points  # CL points of the next piece (more where no cut was found)
        while True:
            pending, have = [], len(buffer)
            while not exhausted and have < want + lookahead:
                more = next(source, None)
                if more is None:
                    exhausted = True
                else:
                    pending.append(taken_in(more))
                    have += len(more)
            if pending:
                buffer = joined(buffer, pending)
            last = exhausted and len(buffer) <= want + lookahead
            window = buffer if last else toolpath_slice(buffer, 0, want + lookahead)
            boundary = None  # where the next tool section begins, in the window
            # (sections of gauge lengths in machine coordinates, of cutting points in any)
            cuts = tool_sections(
                window,
                job.tool_length,
                job.tool_table,
                length=section.tool_length,
                by_length=not job.tcp,
                by_pivot=True,
                pivot=section.pivot,
                by_cutter=job.collisions,
                cutter=section.cutter,
            )
            # (a TCP program keeps the job's length: its tools' lengths are the control's)
            first_length = section.tool_length if job.tcp else cuts[0].length
            now = (first_length, cuts[0].pivot, cuts[0].cutter)
            if now != (section.tool_length, section.pivot, section.cutter):
                # a tool change at the start (or the first piece's cutter)
                section = replace(
                    job, tool_length=first_length, pivot=cuts[0].pivot, cutter=cuts[0].cutter
                )
                base = None
            if len(cuts) > 1:
                boundary, next_section = cuts[1].start, cuts[1]
                window, last = toolpath_slice(buffer, 0, boundary), False
            if base is None:
                base = make_problem(window, section)
            if checks is None:
                if parallel is None:
                    parallel = FORK and not last and (os.cpu_count() or 1) > 1
                writing = Writing(dialect, job.block_numbers, str(tmp), blank)
                checks = Checks(
                    machine,
                    dialect.name,
                    str(out),
                    tol,
                    units,
                    parallel,
                    True,
                    writing,
                    depth=POST_DEPTH,
                )
            problem = replace(base, toolpath=window, start=start)
            plan = STRATEGIES[job.strategy](problem)
            if last or boundary is not None:
                piece, cut = window, len(window) - 1
            else:
                c = _cut(window, plan, want, machine, tol)
                if c is None:  # nowhere to end a piece: a longer one
                    want *= 2
                    log.info("no place to end a streamed piece; trying %d points", want)
                    continue
                cut, plan, want = c.point, c.plan, piece_points
                piece = toolpath_slice(window, 0, cut + 1)
                if not c.settled:
                    unsettled.append(int(window.line[cut]))
            last_piece = piece
            continuation = Continuation(
                start=start,
                tcp_on=start is not None and job.tcp,
                last=last,
                coolant=coolant,
                entry=entry,
                leave=boundary is not None,
            )
            # (its feeds timed where it is written: in the worker, while the next is planned)
            posted = post_piece(
                piece, section, problem=problem, plan=plan, piece=continuation, time_feeds=False
            )
            program = posted.program
            fresh.append(entry is not None)
            entry = None
            # (a piece that leaves for the next section stops the coolant: its last block)
            parts = program.parts[:-1] if boundary is not None else program.parts
            coolant = coolant_after(parts, coolant)
            if header is None:
                tool_length = program.tool_length  # the first tool section's
                header = HeaderFigures.empty(program)
            header.add(program)
            opening = None
            if first_program is None:
                # the header is known only at the end: a placeholder of as many lines now (the
                # block numbers after it stay), the real one spliced in at the end
                mode = program.feed_mode if posted.timing is None else posted.timing.feed_mode
                first_program = replace(program, blocks=Blocks(()), feed_mode=mode)
                opening = job_header(job, HeaderFigures.empty(program), tool_length)
                placeholder = len(_opening(dialect, first_program, job, opening).encode("utf-8"))
            # written (and read back) by the checks: in a worker while the next piece is planned
            piece_job = ProgramJob.of(posted, fresh=fresh[-1], last=last, header=opening)
            checks.submit(piece_job)
            inserts += piece_job.inserts
            found = posted.figures
            piece_feeds.append(found.feeds)
            figures = found if figures is None else figures.joined(found, offset)
            collisions.append(posted.collisions)
            if len(posted.joints):
                start = posted.joints[-1]
            count += 1
            if progress:
                progress(len(piece) - (0 if count == 1 or fresh[-1] else 1))
            if last:
                break
            if boundary is not None:  # the next piece begins the next tool section
                offset += len(posted.plan.toolpath)
                buffer = toolpath_slice(buffer, boundary, len(buffer))
                entry, start, base = start, None, None
                length = job.tool_length if job.tcp else next_section.length
                section = replace(
                    job, tool_length=length, pivot=next_section.pivot, cutter=next_section.cutter
                )
                continue
            offset += len(posted.plan.toolpath) - 1
            buffer = toolpath_slice(buffer, cut, len(buffer), first_events=False)
            log.info("streamed piece %d: CL lines %d to %d", count, piece.line[0], piece.line[-1])
        assert checks is not None
        results = checks.finish()
        checks.close_output()
        # the feed figures of the pieces in order, timed here or where they were written
        feeds: FeedFigures | None = None
        for here, there in zip(piece_feeds, checks.feed_figures(), strict=True):
            timed = here if here is not None else there
            if timed is not None:
                feeds = timed if feeds is None else feeds.joined(timed)
        # feeds, spindle, tools as a whole post checks them, from the same read
        process_check = checks.process_check()
        assert process_check is not None and last_piece is not None
        if not process_check.ok:  # as :func:`urdfpost.posting.whole.post` says it
            path = f"<{dialect.name} program>"
            faults = located(process_check, dialect, lambda: program_texts(tmp), path, inserts)
            raise ToleranceError(
                f"{last_piece.source}: the program's process differs from the CL data, nothing "
                f"written: {'; '.join(faults)}"
            )
        verification = merge_verifications([check for check, _ in results], fresh)
        intents = [intent for _, intent in results if intent is not None]
        assert figures is not None and last_piece is not None
        figures = replace(figures, feeds=feeds)
        warnings = figures.warnings
        if unsettled:
            warnings += (
                f"{last_piece.source}: at {len(unsettled)} of {count - 1} joins of the "
                f"streamed pieces (the first at CL line {unsettled[0]}) the branch choice rests on "
                f"{lookahead} CL points of lookahead: the whole job could choose otherwise "
                "there (a travel limit further on); --piece-points 0 plans it whole",
            )
        strategy = figures.strategy
        if intents:
            strategy = replace(strategy, intended_path_check=merge_verifications(intents))
        reduced = None if figures.feeds is None else figures.feeds.warning(last_piece.source)
        if reduced is not None:
            warnings += (reduced,)
        figures = replace(figures, strategy=strategy, warnings=warnings)
        report = Report(
            machine=machine.name,
            controller=dialect.name,
            tcp=job.tcp,
            units=units,
            verification=verification,
            tool_length_mm=tool_length,
            warnings=tuple(reader_warnings) + figures.warnings,
            figures=figures,
            collisions=Collisions.merged(collisions),
            tool_lengths_mm=lengths,
            streamed=StreamFigures(
                pieces=count,
                piece_points=piece_points,
                lookahead=lookahead,
                worker=bool(parallel),  # pieces verified in a worker process
                # joins where the branch choice is not settled by the window (CL lines)
                unsettled_joins=unsettled,
            ),
        )
        assert header is not None and first_program is not None
        final = _with_header(
            tmp, out, dialect, first_program, job, header, tool_length, placeholder, lengths, feeds
        )
        tmp.unlink()
        tmp = final
        give_mode(tmp, out)
        _stops.check()  # (a stop lost on the way: the old program stays)
        os.replace(tmp, out)
    except LinearTravelError as e:
        tmp.unlink(missing_ok=True)
        # the setup that brings every point into travel needs every point at once
        raise LinearTravelError(
            f"{e}; a streamed post cannot suggest a job setup (it never holds the whole CL "
            "data): post with --piece-points 0 for one"
        ) from e
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    finally:
        if checks is not None:
            checks.close()
    return StreamResult(path=out, verification=verification, report=report)


def _refuse_cycles(toolpath: Toolpath) -> None:
    """Refuse canned cycles in a streamed post: a piece cut inside a cycle would not know its
    holes (they are posted whole, ``--piece-points 0``).

    Raises
    ------
    CLDataError
        At the first ``CYCLE`` record.
    """
    for e in toolpath.events:
        if e.kind == "cycle":
            raise CLDataError(
                toolpath.source,
                e.line,
                "canned cycles (CYCLE records) are not posted in pieces; expected a whole post "
                "(--piece-points 0)",
            )


def _opening(dialect: Dialect, program: Program, job: Job, header: str) -> str:
    """The text a streamed program opens with, with ``header``, up to its first piece."""
    writer = dialect.writer(program, block_numbers=job.block_numbers)
    writer.open(header, stock_box(job))
    return writer.take()


def _with_header(
    tmp: Path,
    out: Path,
    dialect: Dialect,
    program: Program,
    job: Job,
    header: HeaderFigures,
    tool_length: float,
    placeholder: int,
    lengths: dict[int, float] | None = None,
    run: FeedFigures | None = None,
) -> Path:
    """A copy of the streamed program ``tmp`` whose opening has the real header.

    The opening is written again with the header of the whole program (as many lines as the
    placeholder's: the block numbers after it are unchanged) and the rest of ``tmp`` after
    its first ``placeholder`` bytes is copied behind it, into a new temporary file beside
    ``out``, which is returned.
    """
    header_text = job_header(job, header, tool_length, lengths, run=run)
    opening = _opening(dialect, program, job, header_text)
    fd, final = temp_file(out)
    try:
        with os.fdopen(fd, "wb") as dst, open(tmp, "rb") as src:
            dst.write(opening.encode("utf-8"))
            src.seek(placeholder)
            shutil.copyfileobj(src, dst, 1 << 20)
    except BaseException:
        final.unlink(missing_ok=True)
        raise
    return final


__all__ = ["StreamResult", "post_stream"]
