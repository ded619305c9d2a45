"""The post of a whole job at once, in this process: :func:`post`."""

from __future__ import annotations

import functools
import itertools
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from urdfpost.errors import ToleranceError, UnreachableError, UrdfpostError
from urdfpost.machine import Machine
from urdfpost.planning.setup_fit import fit_setup
from urdfpost.posting.body import coolant_after
from urdfpost.posting.check import check_piece, tolerance_error
from urdfpost.posting.header import HeaderFigures, job_header, stock_box
from urdfpost.posting.options import Job, PostOptions, resolve
from urdfpost.posting.piece import Continuation, PostedPiece, post_piece
from urdfpost.posting.process import checked_process, one_tool_length
from urdfpost.posting.readback import merge_verifications
from urdfpost.posting.report import Collisions, FeedFigures, Report
from urdfpost.posting.tools import (
    Section,
    gauge_lengths,
    in_own_mcs,
    mcs_machine,
    mcs_shifts,
    several_lengths,
    tool_sections,
    transformed_mcs,
)
from urdfpost.posting.worker import PieceJob, PieceVerifier
from urdfpost.program import Blocks, Insert, Program
from urdfpost.toolpath import Toolpath, toolpath_slice
from urdfpost.units import mm_per_unit
from urdfpost.verification import Verification
from urdfpost.verification.process import check_process, located, rounding_of


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
    report : Report
        Figures for people and JSON (:meth:`Report.as_json`).
    posted : PostedPiece
        The program's plan and what it was checked against (a job posted in tool sections,
        :mod:`urdfpost.posting.tools`: the first section's plan and target, with the whole
        program, joints and figures).
    """

    program: Program
    text: str
    verification: Verification
    report: Report
    posted: PostedPiece


def written(
    posted: PostedPiece, job: Job
) -> tuple[str, Program, tuple[Verification, Verification | None]]:
    """The text of a posted piece that is a whole program, read back and checked.

    Returns
    -------
    text : str
    readback : Program
        The program read back from ``text``.
    checks : (Verification, Verification or None)
        Of :func:`urdfpost.posting.check.check_piece`.
    """
    dialect, program = job.dialect, posted.program
    figures = HeaderFigures.empty(program).add(program)
    header = job_header(job, figures, program.tool_length, run=posted.figures.feeds)
    text = dialect.write(
        program, block_numbers=job.block_numbers, header=header, blank=stock_box(job)
    )
    inserts = [b.text for b in program.parts if isinstance(b, Insert)]
    path = f"<{dialect.name} program>"
    readback = dialect.read(text, path=path, verbatim=inserts, rollover=program.rollover)
    return text, readback, check_piece(readback, job.machine, posted.target, job.tol)


def post(
    toolpath: Toolpath,
    machine: Machine,
    options: PostOptions | None = None,
    progress: Callable[[int], None] | None = None,
) -> PostResult:
    """Post a toolpath for a machine and check the program against the CL data.

    The whole job is planned at once, in this process. Long jobs post faster and in bounded
    memory in pieces: :func:`urdfpost.posting.stream.post_stream`.

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
        A CL point no branch reaches within travel; when the points are outside the linear
        travel, the message ends with the job setup that would bring them in, if one does
        (:func:`travel_hint`).
    CollisionError
        A move of the program collides.
    GeometryError
        Collision geometry that cannot be built (a stock file, a ``<collision>`` element).
    ToleranceError
        The program read back deviates from the CL data beyond tolerance (the message carries
        the figures), or its feeds, spindle or tools differ from the CL data's
        (:mod:`urdfpost.verification.process`); nothing should be written then.
    """
    job = resolve(options, machine, toolpath.units)
    toolpath, _, notes = checked_process(
        toolpath,
        feed=job.feed,
        spindle=job.spindle,
        units=job.units,
        spec=job.dialect.spec,
        tcp=job.tcp,
    )
    if not job.tcp:
        notes += one_tool_length(toolpath, job.tool_length, job.units, table=job.tool_table)[0]
    sections = tool_sections(
        toolpath,
        job.tool_length,
        job.tool_table,
        by_length=not job.tcp,
        by_mcs=job.mcs_offsets,
        by_pivot=True,
        by_cutter=job.collisions,
    )
    if notes:
        toolpath = replace(toolpath, warnings=toolpath.warnings + tuple(notes))
    if several_lengths(sections):
        return _post_sections(toolpath, job, sections, progress)
    only = sections[0]  # one section: machine coordinates with its tool's gauge length
    length = job.tool_length if job.tcp else only.length
    job = replace(job, tool_length=length, pivot=only.pivot, cutter=only.cutter)
    try:
        posted = post_piece(toolpath, job, progress=progress)
    except UnreachableError as e:
        hint = travel_hint(toolpath, job)
        if not hint:
            raise
        raise UnreachableError(f"{e}{hint}") from e
    text, readback, checks = written(posted, job)
    report = make_report(toolpath, job, posted, checks)
    error = tolerance_error(toolpath, checks, job.units)
    if error is not None:
        raise error
    # feeds, spindle and tools as ``urdfpost verify`` checks them: no program it would refuse
    target = posted.target
    process = check_process(
        readback,
        job.machine,
        target.intended or target.cl,
        tol=job.tol,
        tool_length=target.tool_length,
        rounding=rounding_of(job.dialect, job.units),
    )
    if not process.ok:
        inserts = [b.text for b in posted.program.parts if isinstance(b, Insert)]
        path = f"<{job.dialect.name} program>"
        faults = located(process, job.dialect, lambda: [text], path, inserts)
        raise ToleranceError(
            f"{toolpath.source}: the program's process differs from the CL data, nothing "
            f"written: {'; '.join(faults)}"
        )
    return PostResult(posted.program, text, checks[0], report, posted)


def _post_sections(
    toolpath: Toolpath,
    job: Job,
    sections: list[Section],
    progress: Callable[[int], None] | None,
) -> PostResult:
    """:func:`post` of a job in sections (:mod:`urdfpost.posting.tools`): a machine-coordinate
    job whose tools have different gauge lengths, or a job with a work offset per MCS.

    Each section is planned and checked with its tool's length, on the machine of its MCS
    (its program zero there, its points in its MCS, its work offset selected as it begins): a
    piece of the program that leaves the path at its end as for a tool change, the next one
    approached from there. The pieces are written as one program and read back with one
    reader, each checked on its own against its CL points (its geometry, and its feeds,
    spindle and tools as ``urdfpost verify`` checks them).
    """
    dialect, machine = job.dialect, job.machine
    shifts = mcs_shifts(toolpath) if job.mcs_offsets else {}
    machines = {k: mcs_machine(machine, shift) for k, shift in shifts.items()}
    transformed = transformed_mcs(toolpath)
    last_offset = job.work_offset + max((s.mcs for s in sections), default=0)
    if last_offset > dialect.spec.work_offsets:
        raise UrdfpostError(
            f"{toolpath.source}: {len(shifts)} MCS need work offsets {job.work_offset} to "
            f"{last_offset}; {dialect.name} has work offsets 1 to {dialect.spec.work_offsets}"
        )
    pieces: list[PostedPiece] = []
    entry = None
    coolant = None
    for k, section in enumerate(sections):
        part = toolpath_slice(toolpath, section.start, section.stop)
        part = replace(part, warnings=toolpath.warnings if k == 0 else ())
        section_machine = machines.get(section.mcs, machine)
        if section.mcs in shifts:  # its points as its MCS has them
            part = in_own_mcs(part, shifts[section.mcs], transformed)
        piece_job = replace(
            job,
            # (a TCP program keeps the job's length: its tools' lengths are the control's)
            tool_length=job.tool_length if job.tcp else section.length,
            machine=section_machine,
            pivot=section.pivot,
            cutter=section.cutter,
        )
        last = k == len(sections) - 1
        other_mcs = k > 0 and section.mcs != sections[k - 1].mcs
        joining = Continuation(
            start=None,
            tcp_on=False,
            last=last,
            coolant=coolant,
            entry=entry,
            leave=not last,
            offset=job.work_offset + section.mcs if other_mcs else None,
            keep_tool=not last and not _begins_with_tool(toolpath, sections[k + 1]),
        )
        try:
            posted = post_piece(part, piece_job, progress=progress, piece=joining)
        except UnreachableError as e:
            hint = travel_hint(part, piece_job)
            if not hint:
                raise
            raise UnreachableError(f"{e}{hint}") from e
        pieces.append(posted)
        if len(posted.joints):
            entry = posted.joints[-1]
        # the coolant on before the section's leave (which stops it for a tool change)
        parts = posted.program.parts
        coolant = coolant_after(parts if last or joining.keep_tool else parts[:-1], coolant)
    lengths = gauge_lengths(toolpath, job.tool_length, job.tool_table)
    blocks = [part for posted in pieces for part in posted.program.parts]
    program = replace(pieces[0].program, blocks=Blocks(blocks))
    figures = HeaderFigures.empty(program).add(program)
    writer = dialect.writer(program, block_numbers=job.block_numbers)
    offsets = {job.work_offset + k: shift for k, shift in shifts.items()}
    feeds = [p.figures.feeds for p in pieces]
    run = None if None in feeds else functools.reduce(FeedFigures.joined, feeds)  # type: ignore[arg-type]
    header = job_header(
        job, figures, sections[0].length, lengths if not job.tcp else None, offsets, run
    )
    writer.open(header, stock_box(job))
    path = f"<{dialect.name} program>"
    # (the process of each section checked from the verification's read of it)
    verifier = PieceVerifier(machine, dialect.name, path, job.tol, job.units, process=True)
    texts: list[str] = []
    results: list[tuple[Verification, Verification | None]] = []
    for k, posted in enumerate(pieces):
        writer.write_body(posted.program)
        if k == len(pieces) - 1:
            writer.close()
        texts.append(writer.take())
        piece = PieceJob.of(texts[-1], posted, fresh=k > 0)
        section_machine = machines.get(sections[k].mcs, machine)
        results.append(verifier.check(piece, section_machine))
    text = "".join(texts)
    fresh = [k > 0 for k in range(len(pieces))]
    check = merge_verifications([c for c, _ in results], fresh)
    intents = [i for _, i in results if i is not None]
    intent = merge_verifications(intents) if intents else None
    found = pieces[0].figures
    offset = 0  # the sections share no point: their plan paths joined end to end
    for before, posted in itertools.pairwise(pieces):
        offset += len(before.plan.toolpath)
        found = found.joined(posted.figures, offset)
    merged = replace(
        pieces[0],
        program=program,
        figures=found,
        joints=np.concatenate([p.joints for p in pieces]),
        joint_lines=np.concatenate([p.joint_lines for p in pieces]),
    )
    report = make_report(toolpath, job, merged, (check, intent))
    report = replace(
        report,
        collisions=Collisions.merged([p.collisions for p in pieces]),
        tool_lengths_mm={} if job.tcp else lengths,
    )
    result = verifier.process_check()
    assert result is not None
    if not result.ok:
        inserts = [b.text for b in program.parts if isinstance(b, Insert)]
        faults = located(result, dialect, lambda: [text], path, inserts)
        raise ToleranceError(
            f"{toolpath.source}: the program's process differs from the CL data, nothing "
            f"written: {'; '.join(faults)}"
        )
    return PostResult(program, text, check, report, merged)


def _begins_with_tool(toolpath: Toolpath, section: Section) -> bool:
    """Whether a tool change begins the section (else a change of work offset does)."""
    return any(e.kind == "tool" and e.index == section.start for e in toolpath.events)


def travel_hint(toolpath: Toolpath, job: Job) -> str:
    """What ends the message of a post refused for linear travel: the job setup
    (``--setup``, in the program units) that brings every CL point into travel, or that
    none does; empty when the CL points are within travel (the refusal has another cause).

    See :func:`urdfpost.planning.setup_fit.fit_setup`: the linear axes kept ``job.clearance``
    inside their travel where it allows, at least the rounding of the printed setup.
    """
    scale = mm_per_unit(job.units)
    fit = fit_setup(
        job.machine,
        toolpath.tip,
        toolpath.axis,
        job.tool_length,
        margin=job.clearance,
        min_margin=1e-3 * scale,  # the printed setup's last digit
        tol=job.tol,
    )
    return fit.hint(job.units)


def make_report(
    toolpath: Toolpath,
    job: Job,
    posted: PostedPiece,
    checks: tuple[Verification, Verification | None],
) -> Report:
    """The report of a whole post."""
    check, intent = checks
    figures = posted.figures
    if intent is not None:
        figures = replace(figures, strategy=replace(figures.strategy, intended_path_check=intent))
    reduced = None if figures.feeds is None else figures.feeds.warning(toolpath.source)
    if reduced is not None:
        figures = replace(figures, warnings=(*figures.warnings, reduced))
    return Report(
        machine=job.machine.name,
        controller=job.dialect.name,
        tcp=job.tcp,
        units=job.units,
        verification=check,
        tool_length_mm=posted.program.tool_length,
        warnings=tuple(toolpath.warnings) + figures.warnings,
        figures=figures,
        collisions=posted.collisions,
        tool_lengths_mm={}
        if job.tcp
        else {
            int(e.data.get("number", 0)): posted.program.tool_length
            for e in toolpath.events
            if e.kind == "tool"
        },
    )
