"""The post of a whole job at once, in this process: :func:`post`."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

from urdfpost.errors import ToleranceError, UnreachableError
from urdfpost.machine import Machine
from urdfpost.planning.setup_fit import fit_setup
from urdfpost.posting.check import check_piece, tolerance_error
from urdfpost.posting.header import HeaderFigures, job_header, stock_box
from urdfpost.posting.options import Job, PostOptions, resolve
from urdfpost.posting.piece import PostedPiece, post_piece
from urdfpost.posting.process import checked_process, one_tool_length
from urdfpost.posting.report import Report
from urdfpost.program import Insert, Program
from urdfpost.toolpath import Toolpath
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
        The program's plan and what it was checked against.
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
    header = job_header(job, HeaderFigures.empty(program).add(program), program.tool_length)
    text = dialect.write(
        program, block_numbers=job.block_numbers, header=header, blank=stock_box(job)
    )
    inserts = [b.text for b in program.parts if isinstance(b, Insert)]
    readback = dialect.read(text, path=f"<{dialect.name} program>", verbatim=inserts)
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
        notes += one_tool_length(toolpath, job.tool_length, job.units)[0]
    if notes:
        toolpath = replace(toolpath, warnings=toolpath.warnings + tuple(notes))
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
    )
