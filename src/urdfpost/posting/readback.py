"""Checking a program file against its CL data in bounded memory (``urdfpost verify`` of a
large job), and the merging of verifications checked in pieces.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from urdfpost.dialects import dialect_for
from urdfpost.errors import CLDataError, UrdfpostError
from urdfpost.machine import Machine
from urdfpost.posting import PIECE_POINTS
from urdfpost.posting.check import tolerance_share
from urdfpost.posting.tools import (
    Section,
    cutting_points,
    gauge_lengths,
    program_sections,
    tool_sections,
)
from urdfpost.posting.worker import FORK, ReadChecks, ReadPiece
from urdfpost.program import Blocks, Move, MoveTable, Program, Smoothing, rewind_moves
from urdfpost.readers._stream import text_pieces
from urdfpost.tolerances import Tolerances
from urdfpost.toolpath import Toolpath, joined, toolpath_slice
from urdfpost.verification import (
    REACH,
    Verification,
    match_points,
    missed_note,
    program_joints,
    rewind_note,
    row_points,
)
from urdfpost.verification.feeds import FeedCheck, FeedRules
from urdfpost.verification.planes import PlaneFrames
from urdfpost.verification.process import ProcessChecker

log = logging.getLogger(__name__)


def merge_verifications(parts: list[Verification], fresh: Sequence[bool] = ()) -> Verification:
    """One verification of the pieces' checks of a streamed program.

    Each piece after the first starts with the CL point and the program row the piece before
    ended with: they are counted once. A piece ``k`` with ``fresh[k]`` true begins a tool
    section (:mod:`urdfpost.posting.tools`) and shares nothing with the one before.
    """
    first = parts[0]
    starts = [k > 0 and k < len(fresh) and bool(fresh[k]) for k in range(len(parts))]
    joins = len(parts) - 1 - sum(starts)
    missed: list[int] = []
    for v, own in zip(parts, starts, strict=True):
        lines = v.missed_lines
        if missed and lines and lines[0] == missed[-1] and not own:
            lines = lines[1:]  # the point at a join, missed in both pieces
        missed += lines
    cl_points = sum(v.cl_points for v in parts) - joins
    worst = max(parts, key=lambda v: v.max_tip_deviation)
    compared = sum(v.compared for v in parts)
    mean = sum(v.mean_tip_deviation * v.compared for v in parts) / max(compared, 1)
    steps: dict[str, float] = {}
    for v in parts:
        for k, x in v.max_rotary_step_deg.items():
            steps[k] = max(steps.get(k, 0.0), x)
    # the pieces' notes once each; those that count something, counted over the whole
    notes: list[str] = []
    rewinds = sum(v.rewind_moves for v in parts)
    for v in parts:
        counted = {rewind_note(v.rewind_moves)} | (
            {missed_note(v.missed_lines)} if v.missed_lines else set()
        )
        notes += [x for x in v.notes if x not in counted and x not in notes]
    if rewinds:
        notes.insert(0, rewind_note(rewinds))
    if missed:
        notes.append(missed_note(missed))
    return replace(
        first,
        ok=all(v.ok for v in parts),
        cl_points=cl_points,
        reached=cl_points - len(missed),
        missed_lines=missed,
        blocks=sum(v.blocks for v in parts) - joins,
        max_tip_deviation=worst.max_tip_deviation,
        mean_tip_deviation=float(mean),
        max_orientation_deviation_deg=max(v.max_orientation_deviation_deg for v in parts),
        max_rotary_step_deg=steps,
        worst_cl_line=max(parts, key=tolerance_share).worst_cl_line,
        # each piece is within its own: a piece whose strategy bent the tool axis was checked
        # with the bent tolerances (as a whole post checks the whole program), the others with
        # the plain ones; the figures name the loosest, which every piece met
        tip_tolerance=max(v.tip_tolerance for v in parts),
        orientation_tolerance_deg=max(v.orientation_tolerance_deg for v in parts),
        notes=notes,
        compared=compared,
        rewind_moves=rewinds,
        feeds=FeedCheck.merged([v.feeds for v in parts if v.feeds is not None]),
    )


TEXT_PIECE = 8 << 20
"""Characters of program text read at a time by :func:`verify_stream`."""

CUT_MARGIN = 2
"""CL points past a piece's ``piece_points`` that :func:`verify_stream` holds before it cuts
the piece (:func:`_verify_cut` matches the point after the cut too): CL data given in pieces of
``piece_points + CUT_MARGIN`` points is read one piece per cut."""


def program_texts(path: str | os.PathLike[str], size: int = TEXT_PIECE) -> Iterator[str]:
    """The text of a program file in pieces of about ``size`` characters, cut at line ends
    (as the CL readers read theirs: :func:`urdfpost.readers._stream.text_pieces`).

    Raises
    ------
    UrdfpostError
        The file cannot be read.
    """
    try:
        yield from text_pieces(str(path), size)
    except CLDataError as e:  # (said of a CL file there)
        raise UrdfpostError(f"{path}: {e.detail}") from e


def _joined_programs(head: Program | None, tail: Program) -> Program:
    """The blocks of ``tail`` after those of ``head`` (the header of ``tail``, which has seen
    as much of the text)."""
    if head is None:
        return tail
    return replace(tail, blocks=Blocks((*head.parts, *tail.parts)))


def _split_rows(program: Program, row: int) -> tuple[Program, Program]:
    """The program up to move ``row`` and from it (the move in both; the other blocks after
    it in the second)."""
    head: list[Any] = []
    tail: list[Any] = []
    seen = 0  # moves before the part
    for part in program.parts:
        if isinstance(part, MoveTable):
            size = len(part)
            if seen + size <= row:
                head.append(part)
            elif seen > row:
                tail.append(part)
            else:
                at = row - seen
                head.append(part.rows(0, at + 1))
                tail.append(part.rows(at, size))
        elif isinstance(part, Move):
            size = 1
            if seen < row:
                head.append(part)
            elif seen > row:
                tail.append(part)
            else:
                head.append(part)
                tail.append(part)
        else:
            size = 0
            (head if seen <= row else tail).append(part)
        seen += size
    return (
        replace(program, blocks=Blocks(tuple(head))),
        replace(program, blocks=Blocks(tuple(tail))),
    )


def _verify_cut(
    program: Program,
    machine: Machine,
    cl: Toolpath,
    tol: Tolerances,
    tool_length: float,
    pivot: float,
    target: int,
    program_ends: bool,
) -> tuple[int, int] | None:
    """Where the check of a program against CL data can be cut in two: a CL point at or
    before ``target`` and the program row that reaches it, such that checking the two sides
    on their own (the row and the point in both) gives what checking them together gives.

    The matching of CL points to rows is sequential
    (:func:`urdfpost.verification.match_points`): each point is searched from the row the
    point before reached. Cut at a point ``c`` reached by row ``r``, with the next point
    reached by a later row, the second side starts where the whole check is after ``c``; the first
    side holds every row the search for a point up to ``c`` looks at when the rows go on
    :data:`REACH` past ``r`` (or the program ends). The blocks into and out of ``r`` are feed moves
    outside rewinds, so that the rapids and the rewinds of each side are what they are in the whole.

    Returns
    -------
    (c, r) or None
    """
    values, rapid = program_joints(machine, program)
    n_rows, n_cl = len(values), len(cl)
    if n_rows < 3 or n_cl < 3:
        return None
    point, axis = row_points(machine, values, program.tcp, tool_length, pivot)
    match = match_points(cl.tip + pivot * cl.axis, cl.axis, point, axis, tol)
    aside = rapid | rewind_moves(program)
    j = np.arange(1, min(target, n_cl - CUT_MARGIN) + 1)  # (the point after j matched too)
    r = match[j]
    ok = (r >= 1) & (match[j + 1] > r) & (r + 1 < n_rows)
    if not program_ends:
        ok &= r + REACH + 1 < n_rows
    safe = np.clip(r, 0, n_rows - 2)
    ok &= ~aside[safe] & ~aside[safe + 1]
    if not ok.any():
        return None
    c = int(j[ok][-1])
    return c, int(match[c])


def verify_stream(
    program_path: str | os.PathLike[str],
    cl_pieces: Iterable[Toolpath],
    machine: Machine,
    controller: str,
    *,
    tol: Tolerances,
    tool_length: float,
    pivot: float = 0.0,
    piece_points: int = PIECE_POINTS,
    texts: Iterable[str] | None = None,
    process: ProcessChecker | None = None,
    table: Mapping[int, float] | None = None,
    feed_rules: FeedRules | None = None,
    parallel: bool | None = None,
    bent: float | None = None,
) -> tuple[Verification, Program]:
    """:func:`urdfpost.verification.verify` of a program file against CL data given in pieces, in
    bounded memory: the program is read and checked a piece at a time.

    Each piece is cut at a CL point and the program row that reaches it where the two sides
    check as the whole does (:func:`_verify_cut`); the next piece starts with that point and
    row. The figures are merged as for a streamed post (:func:`merge_verifications`): every
    block is checked once; only the mean deviation counts the join rows twice.

    Parameters
    ----------
    program_path : path
        The program file (for reading and messages).
    cl_pieces : iterable of Toolpath
        Consecutive pieces of the CL data (:func:`urdfpost.readers.read_cl_chunks`), of any
        size (the pieces checked are the same); of ``piece_points + CUT_MARGIN`` points
        (:data:`CUT_MARGIN`), one is read per piece checked.
    machine : Machine
    controller : str
        Dialect of the program.
    tol : Tolerances
    tool_length : float, mm
    pivot : float, mm
        As :func:`urdfpost.verification.verify`.
    piece_points : int
        CL points checked per piece, about.
    texts : iterable of str, optional
        The program text in pieces cut at line ends (default: read from ``program_path``).
    process : ProcessChecker, optional
        Is given every piece checked, with its CL data (the process of the program,
        :mod:`urdfpost.verification.process`; the CL pieces are then the expected ones): each
        piece is begun here (:meth:`~urdfpost.verification.process.ProcessChecker.begin`), its
        rows compared where it is verified, and the findings taken in the pieces' order at the
        end. Its machine is ``machine`` (where the rows are compared).
    table : mapping, optional
        A machine-coordinate program: the tool table (tool number to gauge length, mm). Each
        tool section (:mod:`urdfpost.posting.tools`) is checked with its tool's length: the
        table's, else the CL data's ``LOADTL LENGTH``, else ``tool_length``.
    feed_rules : FeedRules, optional
        How the control times the blocks: the tip feed of every piece is measured
        (:func:`urdfpost.verification.verify`); None: not measured.
    parallel : bool, optional
        Verify the pieces (and compare the rows of their process) in worker processes, one per
        core, each piece by the next worker in turn, while the next ones are read and cut; default
        on Linux when the machine has more than one core and the program more than one piece
        (as :func:`urdfpost.posting.stream.post_stream`).
    bent : float, optional, degrees
        The angle tolerance of a program a strategy bent: each tool section is measured at its
        tool's cutting point (:func:`urdfpost.posting.tools.cutting_points`; ``pivot`` is not
        used) with ``tol`` bent by it there (:func:`urdfpost.posting.check.bent_tolerances`).
        None: every piece at ``pivot`` with ``tol``.

    Returns
    -------
    verification : Verification
    header : Program
        The program's header (name, units, TCP, tool length); its blocks are only its path
        smoothing blocks (:class:`~urdfpost.program.Smoothing`), in order.

    Raises
    ------
    ProgramParseError, UrdfpostError
        A program line that cannot be read; a file that cannot.
    """
    if piece_points < 2:
        raise ValueError(f"piece_points must be at least 2, got {piece_points}")
    rollover = machine.settings.rollover
    dialect = dialect_for(controller).with_clamps(machine.settings.clamps)
    reader = dialect.reader(path=str(program_path), rollover=rollover)
    frames = PlaneFrames(machine)
    text_source = iter(program_texts(program_path) if texts is None else texts)
    cl_source = iter(cl_pieces)
    program: Program | None = None
    cl: Toolpath | None = None
    program_ends = cl_ends = False
    header: Program | None = None
    smoothing: list[Smoothing] = []  # the program's path smoothing blocks, in order
    want = piece_points
    rows_per_point = 1.5  # a first guess, then as the pieces so far had
    rows_done = points_done = 0
    lengths: dict[int, float] = {}  # each tool's gauge length, mm
    points: dict[int, float] = {}  # each tool's cutting point (with ``bent``), mm
    at: float | None = None if bent is not None else pivot  # the section's (None: not known yet)
    checks: ReadChecks | None = None  # where the pieces are verified, in order

    def tol_at(point: float) -> Tolerances:
        """The tolerances of a section measured at ``point``."""
        if bent is None:
            return tol
        from urdfpost.posting.check import bent_tolerances

        return bent_tolerances(tol, bent, point)

    def check(
        head: Program,
        part: Toolpath,
        length: float,
        rules: FeedRules | None,
        ended: bool | None = None,
    ) -> None:
        """Verify a piece and compare its process (in a worker, when there are workers), its
        results taken in order at the end; the piece begins a tool section when ``starts``
        (``ended``: the last piece, whether the program text has its end)."""
        nonlocal checks
        if checks is None:
            cores = os.cpu_count() or 1
            if parallel is None:  # workers for a program of more than one piece
                use = FORK and not (cl_ends and program_ends) and cores > 1
            else:
                use = parallel
            checks = ReadChecks(
                machine, controller, str(program_path), tol, head.units, use, workers=cores
            )
        fresh.append(starts)
        start = None
        if process is not None:
            start = process.begin(head, part, ended=ended, fresh=starts, tool_length=length)
        assert at is not None
        checks.submit(ReadPiece(head, part, length, at, rules, start, tol_at(at)))

    length = tool_length  # of the tool section being checked
    fresh: list[bool] = []  # per piece: it begins a tool section
    starts = False  # the next piece begins one
    more_text = False  # the program's next tool section is not read yet
    try:
        while True:
            while not cl_ends and (cl is None or len(cl) < want + CUT_MARGIN):
                more = next(cl_source, None)
                if more is None:
                    cl_ends = True
                else:
                    lengths |= gauge_lengths(more, tool_length, table)
                    if bent is not None:
                        points |= cutting_points(more)[1]
                    cl = more if cl is None else joined(cl, [more])
            need = int(rows_per_point * want) + REACH + 2
            while not program_ends and (
                program is None or len(program.move_table()) < need or more_text
            ):
                more_text = False
                text = next(text_source, None)
                if text is None:
                    program_ends = True
                    continue
                reader.feed(text)
                taken = frames.feed(reader.take())  # (the planes' moves in the program's frame)
                smoothing += [b for b in taken.parts if isinstance(b, Smoothing)]
                program = _joined_programs(program, taken)
            if program is None:
                program = reader.take()
            if header is None:
                header = replace(program, blocks=Blocks(()))
            assert cl is not None
            sections = [Section(0, len(cl), length, None, 0, pivot)]
            if not program.tcp or bent is not None:
                sections = tool_sections(
                    cl,
                    tool_length,
                    table,
                    length=length,
                    by_length=not program.tcp,
                    by_pivot=bent is not None,
                    pivot=at,
                )
                length = sections[0].length  # (a tool change at the piece's start)
                at = sections[0].pivot if bent is not None else at
            if len(sections) > 1:  # the section ends in this piece: checked on its own
                assert at is not None
                cut_program = program_sections(
                    program,
                    lengths,
                    tool_length,
                    by_length=not program.tcp,
                    pivots=None if bent is None else (at, points),
                )
                if len(cut_program) == 1 and not program_ends:
                    more_text = True  # its end is further on in the program text
                    continue
                if len(cut_program) > 1:
                    head = cut_program[0][0]
                    program = replace(program, blocks=Blocks(program.parts[len(head.parts) :]))
                    end = sections[0].stop
                    check(head, toolpath_slice(cl, 0, end), length, None)
                    cl = toolpath_slice(cl, end, len(cl))
                    length, starts = sections[1].length, True
                    at = sections[1].pivot if bent is not None else at
                    continue
            if cl_ends and program_ends:
                check(program, cl, length, feed_rules, ended=reader.builder.ended)
                break
            assert at is not None
            cut = _verify_cut(program, machine, cl, tol_at(at), length, at, want, program_ends)
            if cut is None:  # nowhere to cut yet: a longer piece, and more rows
                want *= 2
                continue
            c, r = cut
            head, program = _split_rows(program, r)
            check(head, toolpath_slice(cl, 0, c + 1), length, feed_rules)
            starts = False
            cl = toolpath_slice(cl, c, len(cl), first_events=False)
            rows_done += r
            points_done += c
            rows_per_point = max(1.0, 1.25 * rows_done / max(points_done, 1))
            want = piece_points
            log.info("verified a piece: CL lines to %d, program rows to %d", cl.line[0], rows_done)
        assert header is not None and checks is not None
        results = checks.finish()
    finally:
        if checks is not None:
            checks.close()
    if process is not None:
        for _, found in results:
            assert found is not None
            process.take(found)
    parts = [c for c, _ in results]
    return merge_verifications(parts, fresh), replace(header, blocks=Blocks(tuple(smoothing)))
