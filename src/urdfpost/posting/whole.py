"""The post of a whole job at once, in this process: :func:`post`."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

from urdfpost.machine import Machine
from urdfpost.posting.check import check_piece, tolerance_error
from urdfpost.posting.options import Job, PostOptions, resolve
from urdfpost.posting.piece import PostedPiece, post_piece
from urdfpost.posting.report import Report
from urdfpost.program import Insert, Program
from urdfpost.toolpath import Toolpath
from urdfpost.verification import Verification


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
    text = dialect.write(program, block_numbers=job.block_numbers, header=job.header)
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
        A CL point no branch reaches within travel.
    CollisionError
        A move of the program collides.
    GeometryError
        Collision geometry that cannot be built (a stock file, a ``<collision>`` element).
    ToleranceError
        The program read back deviates from the CL data beyond tolerance (the message carries
        the figures); nothing should be written then.
    """
    job = resolve(options, machine, toolpath.units)
    posted = post_piece(toolpath, job, progress=progress)
    text, _, checks = written(posted, job)
    report = make_report(toolpath, job, posted, checks)
    error = tolerance_error(toolpath, checks, job.units)
    if error is not None:
        raise error
    return PostResult(posted.program, text, checks[0], report, posted)


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
