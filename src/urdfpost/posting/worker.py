"""Verification of a streamed post's pieces, in a worker process or here.

A streamed post hands each piece's program to :class:`Checks` as soon as it is posted
(:class:`ProgramJob`). On a machine with more than one core a worker process writes the
pieces' text in order with one writer (:class:`Writing`: its modal state and block numbers
carry on) and reads it back with one reader, and checks each piece against its CL points
while the next piece is planned; otherwise the pieces are written and checked here, one after
the other. (A whole post checks its pieces' texts, :class:`PieceJob`.) Either
way the check is :func:`urdfpost.posting.check.check_piece`, the one of every post, and the
piece's process (feeds, spindle, tools) is checked from the same read
(:meth:`PieceVerifier.process_check`).

``urdfpost verify`` in pieces reads and cuts the program itself and hands each piece read
(:class:`ReadPiece`) to :class:`ReadChecks`: workers, one per core, each verifying the next
piece in turn (a read piece carries no state to the next). With the piece comes what its
process check takes from the pieces before it (:class:`~urdfpost.verification.process.PieceStart`):
the worker compares the piece's feeds and spindle too, with the rows the verification matched
to the CL points, and hands back what it found with the verification.

The worker never outlives the post: it ignores Ctrl-C and ``SIGTERM`` (the post stops it:
a ``SIGTERM`` sent to the whole process group is the post's to report, not a worker's death;
:meth:`Checks.close` kills it) and leaves when the post's process is gone, even killed
outright: on Linux the kernel kills it then (``PR_SET_PDEATHSIG``); elsewhere
it sees the post's end of the connection close, or its parent change, within
:data:`PARENT_POLL` seconds of the piece it checks. It holds the caller's standard output and
error no longer than that.
"""

from __future__ import annotations

import contextlib
import ctypes
import logging
import math
import mmap
import multiprocessing
import os
import pickle
import signal
import sys
import tempfile
import threading
from collections.abc import Iterator
from dataclasses import dataclass, replace
from multiprocessing.connection import Connection, wait
from multiprocessing.process import BaseProcess
from typing import TYPE_CHECKING, Any, TextIO

import numpy as np

from urdfpost import _stops
from urdfpost.errors import UrdfpostError
from urdfpost.machine import Machine
from urdfpost.posting.check import CheckTarget, PieceLevels, check_piece, tolerance_error
from urdfpost.program import Blocks, Insert, MoveTable, Program, arcs_as_moves
from urdfpost.tolerances import Tolerances
from urdfpost.toolpath import Toolpath
from urdfpost.verification import Verification, verify_matched
from urdfpost.verification.feeds import FeedRules
from urdfpost.verification.planes import PlaneFrames
from urdfpost.verification.process import (
    PieceProcess,
    PieceStart,
    ProcessCheck,
    RowFindings,
    rounding_of,
)

if TYPE_CHECKING:
    from urdfpost.dialects import Dialect
    from urdfpost.dialects.writer import ProgramWriter
    from urdfpost.posting.feeds import FeedTiming
    from urdfpost.posting.piece import PostedPiece
    from urdfpost.posting.report import FeedFigures

log = logging.getLogger(__name__)

FORK = sys.platform.startswith("linux")
"""Whether verification workers are forked (where forking a process that runs numpy is safe);
elsewhere pieces are verified in the worker only when asked for, in a spawned process."""

PARENT_POLL = 1.0
"""Seconds between the idle worker's checks that the post's process still runs (where the
kernel does not stop the worker with it, and a fork of the post keeps the end of the
connection open that would tell)."""

POST_DEPTH = 2
"""Pieces a streamed post hands to its worker at once (:class:`Checks`): the one checked and
the next, so that neither the planning nor the worker waits for the other on a piece that
takes one of them longer (one piece more in memory)."""

_PR_SET_PDEATHSIG = 1  # <linux/prctl.h>
_PROCESS = "process check"  # what the post sends for the process check of the pieces checked
_WRITTEN = "close the program"  # what it sends when all is written (:class:`Writing`)
_FEEDS = "feed figures"  # what it sends for the figures of the feeds timed in the worker
_STOPS = {signal.SIGINT, signal.SIGTERM}  # what stops a post (Ctrl-C, kill)


def _prepended(program: Program, axes: tuple[str, ...], row: np.ndarray) -> Program:
    """``program`` with a first move at ``row`` (positions of ``axes``): where the piece before
    ended, so that the first block of the piece is checked too."""
    position = np.array([row[axes.index(a)] if a in axes else np.nan for a in program.axes])
    start = MoveTable(position[None, :], np.zeros(1, bool), np.full(1, np.nan), np.full(1, -1))
    return replace(program, blocks=Blocks((start, *program.parts)))


@dataclass(frozen=True)
class PieceJob:
    """What checking one piece takes: its text and what it is checked against.

    Attributes
    ----------
    text : str
        The piece's program text.
    inserts : list of str
        The texts of the piece's inserted blocks, in order.
    target : CheckTarget
    fresh : bool
        The piece begins a tool section (:mod:`urdfpost.posting.tools`): it is checked on
        its own, not from the last row of the piece before (a row of another tool length).
    """

    text: str
    inserts: list[str]
    target: CheckTarget
    fresh: bool = False

    @classmethod
    def of(cls, text: str, posted: PostedPiece, fresh: bool = False) -> PieceJob:
        """The job of a posted piece written as ``text`` (``fresh``: it begins a tool
        section, and shares no row with the piece before)."""
        return cls(
            text=text,
            inserts=_inserts(posted.program),
            target=posted.target,
            fresh=fresh,
        )


@dataclass(frozen=True)
class Writing:
    """How a verifier writes the pieces handed to it as programs (:class:`ProgramJob`): a
    streamed post's text is made where it is read back, so that the post's own process only
    plans and posts.

    Attributes
    ----------
    dialect : Dialect
        The control's dialect the post writes with.
    block_numbers : bool or None
        Number the blocks; None: as the control does by default.
    path : str
        The (temporary) file the program text goes to, written from its start: made by the
        post, and not made again when it is gone (the post has failed).
    blank : ndarray or None, shape (2, 3)
        The stock's box for the control's graphics (:func:`urdfpost.posting.header.stock_box`).
    """

    dialect: Dialect
    block_numbers: bool | None
    path: str
    blank: np.ndarray | None


@dataclass(frozen=True)
class ProgramJob:
    """A posted piece handed over as its program: written (:class:`Writing`), then checked as
    a :class:`PieceJob` of its text.

    Attributes
    ----------
    program : Program
        The piece's program.
    target : CheckTarget
    fresh : bool
        As :attr:`PieceJob.fresh`.
    last : bool
        The piece ends the program (its end is written after it).
    header : str or None
        The first piece: the header the program opens with; None for the others.
    timing : FeedTiming or None
        How the program's feed blocks are to be timed before it is written (its feed moves
        carry the CL feed); None: they are timed.
    """

    program: Program
    target: CheckTarget
    fresh: bool
    last: bool
    header: str | None = None
    timing: FeedTiming | None = None

    @classmethod
    def of(
        cls, posted: PostedPiece, *, fresh: bool, last: bool, header: str | None = None
    ) -> ProgramJob:
        """The job of a posted piece."""
        return cls(posted.program, posted.target, fresh, last, header, posted.timing)

    @property
    def inserts(self) -> list[str]:
        """The texts of the piece's inserted blocks, in order."""
        return _inserts(self.program)


SHARED_DIR = "/dev/shm"
"""Where the large arrays of a job travel to the worker, in a file (memory, not disk: tmpfs)
rather than through the pipe (:class:`_Shared`); jobs go through the pipe where it is not a
directory."""

SHARED_FROM = 1 << 20
"""Bytes of arrays from which a job's arrays travel in a file of :data:`SHARED_DIR`."""

_SHARED_PREFIX = "urdfpost-job-"


@dataclass(frozen=True)
class _Shared:
    """A job pickled with its arrays out of band, written to a file of :data:`SHARED_DIR`
    (:func:`_share`): the worker maps the file and takes the arrays in as they are
    (:func:`_taken`), where the pipe would copy them four times (pickled, written, read,
    unpickled).

    Attributes
    ----------
    data : bytes
        The pickle, without the arrays' bytes.
    path : str
        The file of the arrays' bytes, one after the other (the worker removes it).
    sizes : list of int
        Bytes of each array, in order.
    """

    data: bytes
    path: str
    sizes: list[int]


def _share(job: object) -> _Shared | None:
    """``job`` with its arrays in a file of :data:`SHARED_DIR`, or None where they are fewer
    than :data:`SHARED_FROM` bytes or there is no such directory (the job goes whole)."""
    if not os.path.isdir(SHARED_DIR):
        return None
    buffers: list[pickle.PickleBuffer] = []
    data = pickle.dumps(job, protocol=5, buffer_callback=buffers.append)
    raws = [b.raw() for b in buffers]
    if sum(r.nbytes for r in raws) < SHARED_FROM:
        return None
    fd, path = tempfile.mkstemp(prefix=f"{_SHARED_PREFIX}{os.getpid()}-", dir=SHARED_DIR)
    try:
        with os.fdopen(fd, "wb") as out:
            for raw in raws:
                out.write(raw)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(path)
        raise
    return _Shared(data, path, [r.nbytes for r in raws])


def _taken(shared: _Shared) -> Any:
    """The job of :func:`_share`, its arrays on the file's pages (mapped copy-on-write: the
    job may write to them), the file removed."""
    try:
        with open(shared.path, "rb") as f:
            mapped = mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_COPY) if shared.sizes else None
    finally:
        with contextlib.suppress(OSError):
            os.unlink(shared.path)
    views = []
    if mapped is not None:
        whole, at = memoryview(mapped), 0
        for size in shared.sizes:
            views.append(whole[at : at + size])
            at += size
    return pickle.loads(shared.data, buffers=views)


def _stale_shared() -> None:
    """Remove the files of :func:`_share` that posts which are gone left (killed before their
    worker took the job in)."""
    with contextlib.suppress(OSError):
        for name in os.listdir(SHARED_DIR):
            if not name.startswith(_SHARED_PREFIX):
                continue
            pid = name[len(_SHARED_PREFIX) :].split("-", 1)[0]
            if pid.isdigit() and not _alive(int(pid)):
                with contextlib.suppress(OSError):
                    os.unlink(os.path.join(SHARED_DIR, name))


def _alive(pid: int) -> bool:
    """Whether process ``pid`` runs (or may: one of another user's)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _inserts(program: Program) -> list[str]:
    """The texts of ``program``'s inserted blocks, in order (what its reader is given)."""
    return [b.text for b in program.parts if isinstance(b, Insert)]


@dataclass(frozen=True)
class ReadPiece:
    """A piece of a program read already (``urdfpost verify`` in pieces), to be verified
    against its CL points with :func:`urdfpost.verification.verify`, and its process checked.

    Attributes
    ----------
    program : Program
        The piece's rows, read back, in the program's frame (its first row the last of the
        piece before).
    cl : Toolpath
        Its CL points (the expected ones when its process is checked).
    tool_length, pivot : float, mm
    feed_rules : FeedRules or None
        As :func:`urdfpost.verification.verify` takes them.
    process : PieceStart or None
        The start of the piece's process check
        (:meth:`urdfpost.verification.process.ProcessChecker.begin`); None: not checked.
    tol : Tolerances or None
        Its tolerances (None: the verifier's; a tool section measured at its own cutting
        point has its own).
    """

    program: Program
    cl: Toolpath
    tool_length: float
    pivot: float
    feed_rules: FeedRules | None = None
    process: PieceStart | None = None
    tol: Tolerances | None = None


class PieceVerifier:
    """Reads back the pieces' texts in order with one reader and checks each against its CL
    points, from the last row of the piece before (module docstring).

    With ``process``, each piece read back is also checked for its process (feeds, spindle,
    tools, length offsets: :class:`urdfpost.verification.process.PieceProcess`) from the same
    read, against the path its strategy intended (:meth:`process_check`).
    """

    def __init__(
        self,
        machine: Machine,
        controller: str,
        path: str,
        tol: Tolerances,
        units: str,
        process: bool = False,
        writing: Writing | None = None,
    ) -> None:
        from urdfpost.dialects import dialect_for

        self.machine, self.tol, self.units = machine, tol, units
        self.writing = writing
        self.writer: ProgramWriter | None = None  # (the first program job makes it)
        self.out: TextIO | None = None  # the program file being written
        # per program job: the figures of the feed timing done here (None: timed already)
        self.feeds: list[FeedFigures | None] = []
        rollover = machine.settings.rollover
        self.dialect = dialect_for(controller).with_clamps(machine.settings.clamps)
        self.reader = self.dialect.reader(path=path, rollover=rollover)
        self.frames = PlaneFrames(machine)
        self.previous: tuple[tuple[str, ...], np.ndarray] | None = None  # axes, last row
        self.path = path
        self.with_process = process
        self.process: PieceProcess | None = None  # made with the first piece's tool length
        self.levels = PieceLevels()  # what the pieces checked reached (no refining below)

    def check(
        self, job: PieceJob, machine: Machine | None = None
    ) -> tuple[Verification, Verification | None]:
        """The piece's verifications against the CL data and against its strategy's path
        (on ``machine``: a section in another MCS, its program zero elsewhere; default the
        verifier's).

        Raises
        ------
        ToleranceError
            Either misses its tolerance (a posted piece).
        """
        self.reader.feed(job.text, job.inserts)
        read = self.frames.feed(self.reader.take())  # (the planes' moves in the program's)
        readback = read
        if self.previous is not None and not job.fresh:
            readback = _prepended(readback, *self.previous)
        floors = self.levels.floors(self.tol, job.target)
        checks = check_piece(readback, machine or self.machine, job.target, self.tol, floors)
        error = tolerance_error(job.target.cl, checks, self.units, piece=True)
        if error is not None:
            if any(floors):  # the figures of the message, each block refined
                checks = check_piece(readback, machine or self.machine, job.target, self.tol)
                error = tolerance_error(job.target.cl, checks, self.units, piece=True) or error
            raise error
        self.levels.add(checks)
        if self.with_process:
            self._process(job, read, machine)
        check, intent = checks
        table = arcs_as_moves(readback, math.inf).move_table()  # (an arc's end: its last row)
        if len(table):
            self.previous = (readback.axes, np.asarray(table.position[-1]))
        return check, intent

    def written(self, job: ProgramJob) -> PieceJob:
        """The text of a piece handed over as its program, its feeds timed first where the
        job says so (:attr:`feeds`), appended to the program file (:class:`Writing`; the
        first piece opens it), as a job to check."""
        if self.writing is None:
            raise ValueError("a program job for a verifier that does not write")
        program, feeds = job.program, None
        if job.timing is not None:
            program, feeds = job.timing.timed(program, self.machine)
        self.feeds.append(feeds)
        opening = ""
        if self.writer is None:
            self.writer = self.writing.dialect.writer(
                program, block_numbers=self.writing.block_numbers
            )
            self.writer.open(job.header, self.writing.blank)
            opening = self.writer.take()
            # the file the post made (never made again here: a post that has failed and
            # removed it leaves nothing behind)
            fd = os.open(self.writing.path, os.O_WRONLY | os.O_TRUNC)
            self.out = os.fdopen(fd, "w", encoding="utf-8", newline="")
        self.writer.write_body(program)
        if job.last:
            self.writer.close()
        text = opening + self.writer.take()
        assert self.out is not None
        self.out.write(text)
        return PieceJob(text, job.inserts, job.target, job.fresh)

    def close_output(self) -> None:
        """Close the program file (all written to it)."""
        if self.out is not None:
            self.out.close()
            self.out = None

    def check_read(self, job: ReadPiece) -> tuple[Verification, RowFindings | None]:
        """The verification of a piece read already, whatever its figures, and what its rows
        show of its process (None: not asked for). The process check matches the rows to the
        CL points as the verification did (:func:`urdfpost.verification.verify_matched`) where
        it can (the same tool length, pivot and tolerances; no arc, no canned cycle)."""
        tol = self.tol if job.tol is None else job.tol
        check, match = verify_matched(
            job.program,
            self.machine,
            job.cl,
            tool_length=job.tool_length,
            tol=tol,
            pivot=job.pivot,
            feed_rules=job.feed_rules,
        )
        start = job.process
        if start is None:
            return check, None
        if (start.tol, start.pivot, start.tool_length) != (tol, job.pivot, job.tool_length):
            match = None
        return check, start.compare(job.program, job.cl, self.machine, match)

    def _process(self, job: PieceJob, read: Program, machine: Machine | None) -> None:
        """The process check of a piece read back (``read``: before the row of the piece
        before is put in front, which the process check puts there itself)."""
        target = job.target
        if self.process is None:
            self.process = PieceProcess(
                self.dialect,
                self.machine,
                self.path,
                tol=self.tol,
                tool_length=target.tool_length,
                rounding=rounding_of(self.dialect, self.units),
            )
        self.process.add_program(
            read,
            target.intended or target.cl,
            fresh=job.fresh,
            tool_length=target.tool_length,
            machine=machine,
        )

    def process_check(self) -> ProcessCheck | None:
        """The process check of the pieces so far (None: not asked for, or no piece yet)."""
        return None if self.process is None else self.process.result()


@contextlib.contextmanager
def _stops_held() -> Iterator[None]:
    """Hold back Ctrl-C and ``SIGTERM`` in this thread while a worker is forked, so that none
    reaches the worker before it has set its own handlers (the post's, which a fork copies,
    would raise there and print the worker's traceback); released, they take effect here."""
    if not hasattr(signal, "pthread_sigmask"):
        yield
        return
    held = signal.pthread_sigmask(signal.SIG_BLOCK, _STOPS)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, held)


def _die_with_parent(parent: int) -> bool:
    """Ask the kernel to kill this process when its parent (process ``parent``) ends; returns
    whether the parent still runs (it may have ended before the request). Where there is no
    ``prctl`` (not Linux) only the check is made.

    The kernel acts when the thread that forked this process ends: the one that runs
    :func:`~urdfpost.posting.stream.post_stream`, which stops the worker before it returns.
    """
    if sys.platform.startswith("linux"):
        try:
            libc = ctypes.CDLL(None, use_errno=True)
            if libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0) != 0:
                log.debug("prctl(PR_SET_PDEATHSIG) failed: errno %d", ctypes.get_errno())
        except (OSError, AttributeError) as e:  # a libc without prctl
            log.debug("no prctl: %s", e)
    return os.getppid() == parent


def _detach(post_end: Connection | None) -> bool:
    """What a worker does first: its own signal handling, the post's end of the connection
    closed (a fork inherits it: the worker would never see the end of the connection), death
    with the post's process. Returns whether that process still runs."""
    # Ctrl-C and SIGTERM reach the post, which stops us (a SIGTERM to the process group that
    # ended us first would be told as a worker's death instead of the post's stop)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    _stops.forget()  # (one the post received before the fork is the post's)
    if hasattr(signal, "pthread_sigmask"):
        signal.pthread_sigmask(signal.SIG_UNBLOCK, _STOPS)  # held while forking (_stops_held)
    if post_end is not None:
        post_end.close()
    parent = multiprocessing.parent_process()
    return parent is not None and parent.pid is not None and _die_with_parent(parent.pid)


def _checked(
    verifier: PieceVerifier, job: PieceJob | ProgramJob | ReadPiece
) -> tuple[Verification, Any]:
    """The check of ``job``: a posted piece's verifications (:meth:`PieceVerifier.check`; a
    program job written first, :meth:`PieceVerifier.written`) or a read piece's verification
    and process findings (:meth:`PieceVerifier.check_read`)."""
    if isinstance(job, ReadPiece):
        return verifier.check_read(job)
    if isinstance(job, ProgramJob):
        return verifier.check(verifier.written(job))
    return verifier.check(job)


def _next_job(conn: Connection) -> PieceJob | ProgramJob | ReadPiece | str | None:
    """The next job (or one of :data:`_PROCESS`, :data:`_WRITTEN`, :data:`_FEEDS`), or None
    when the post says so or its process is gone."""
    parent = multiprocessing.parent_process()
    assert parent is not None
    while True:
        ready = wait([conn, parent.sentinel], timeout=PARENT_POLL)
        if parent.sentinel in ready or os.getppid() != parent.pid:
            log.debug("the post's process %d is gone: the worker stops", parent.pid)
            return None
        if ready:
            try:
                job: PieceJob | ProgramJob | ReadPiece | _Shared | str | None = conn.recv()
            except (EOFError, OSError):  # the post's end closed
                return None
            if isinstance(job, _Shared):
                taken: PieceJob | ProgramJob | ReadPiece = _taken(job)
                return taken
            return job


def _serve(conn: Connection, post_end: Connection | None, *args: Any) -> None:
    """A verification worker: checks the jobs it receives with one :class:`PieceVerifier` and
    sends back ``(True, result)`` or ``(False, exception)``, until it receives None or the post
    is gone (module docstring); for :data:`_PROCESS`, ``(True, the process check)``, for
    :data:`_WRITTEN` ``(True, None)`` once the program file is closed, and for :data:`_FEEDS`
    ``(True, the figures of the feeds timed here)`` (:attr:`PieceVerifier.feeds`).

    Parameters
    ----------
    conn : Connection
        The worker's end of the connection.
    post_end : Connection or None
        The post's end, which a forked worker inherits and closes; None when spawned.
    *args
        Those of :class:`PieceVerifier`.
    """
    if not _detach(post_end):
        return
    verifier = PieceVerifier(*args)
    while (job := _next_job(conn)) is not None:
        try:
            if job == _WRITTEN:
                verifier.close_output()
                answer: tuple[bool, Any] = (True, None)
            elif job == _FEEDS:
                answer = (True, verifier.feeds)
            elif isinstance(job, str):
                answer = (True, verifier.process_check())
            else:
                answer = (True, _checked(verifier, job))
        except Exception as exc:  # sent back to be raised where the post runs
            answer = (False, exc)
            try:
                pickle.dumps(exc)
            except Exception:
                answer = (False, UrdfpostError(f"verification failed: {exc!r}"))
        try:
            conn.send(answer)
        except OSError:  # the post is gone
            return


class Checks:
    """The pieces' checks, in order: in a worker process while the next piece is planned (the
    two cores of a small machine share the work), or here one after the other.

    One piece is checked at a time. Up to ``depth`` pieces are handed over at once: the one
    checked and ``depth - 1`` waiting in turn (memory stays bounded); the next is handed over
    when the oldest has been checked. With two, neither process waits for the other on a
    piece that takes it longer than the one before (:data:`POST_DEPTH`). With ``process``, the
    pieces' process is checked there too, from the same read (:meth:`process_check`).
    """

    def __init__(
        self,
        machine: Machine,
        controller: str,
        path: str,
        tol: Tolerances,
        units: str,
        parallel: bool,
        process: bool = False,
        writing: Writing | None = None,
        depth: int = 1,
    ) -> None:
        # per piece: its verification, and a posted piece's of its intended path or a read
        # piece's process findings (:func:`_checked`)
        self.results: list[tuple[Verification, Any]] = []
        self.local: PieceVerifier | None = None
        self.conn: Connection | None = None
        self.process: BaseProcess | None = None
        self.depth = max(1, depth)
        self.waiting = 0  # jobs handed over whose results are not taken yet
        self.sender: threading.Thread | None = None
        self.sent = True  # whether the last job reached the worker
        self.shared: list[str] = []  # the files of the jobs' arrays (:func:`_share`)
        args = (machine, controller, path, tol, units, process, writing)
        if not parallel:
            self.local = PieceVerifier(*args)
            return
        # a fork carries the machine over as it is and does not import the caller's main
        # module again (which a script without a main guard would not survive)
        context = (
            multiprocessing.get_context("fork") if FORK else multiprocessing.get_context("spawn")
        )
        _stale_shared()
        self.conn, child = context.Pipe()
        post_end = self.conn if FORK else None  # for a forked worker to close
        self.process = context.Process(target=_serve, args=(child, post_end, *args), daemon=True)
        try:
            with _stops_held():
                self.process.start()
        except BaseException:  # (a Ctrl-C held back while forking shows here)
            if self.process.pid is not None:  # started: stopped again
                self.close()
            raise
        finally:
            child.close()
        log.info("streamed pieces are verified in worker process %d", self.process.pid)

    def submit(self, job: PieceJob | ProgramJob | ReadPiece) -> None:
        """Check ``job`` (after those before it, which it waits for in the worker; first the
        oldest result is taken when ``depth`` jobs are handed over already). A stop received
        and lost on the way here is raised first (:func:`urdfpost._stops.check`): every piece
        passes here.

        The job is pickled and sent from a thread, so that planning the next piece goes on
        while the worker takes it in.
        """
        _stops.check()
        if self.local is not None:
            self.results.append(_checked(self.local, job))
            return
        while self.waiting >= self.depth:
            self._take_one()
        self._join_sender()  # (one job is sent at a time, in order)
        self.waiting += 1
        self.sender = threading.Thread(target=self._send, args=(job,), daemon=True)
        self.sender.start()

    def _send(self, job: PieceJob | ProgramJob | ReadPiece) -> None:
        assert self.conn is not None
        try:
            shared = None
            with contextlib.suppress(OSError):  # (no room there: through the pipe)
                shared = _share(job)  # its arrays in a file, where they are many
            if shared is not None:
                self.shared.append(shared.path)
            self.conn.send(job if shared is None else shared)
        except OSError:  # a broken pipe: the worker is gone (reported by _collect)
            self.sent = False

    def finish(self) -> list[tuple[Verification, Any]]:
        """Every piece's verifications (:attr:`results`), in order, once all are checked."""
        self._collect()
        return self.results

    def process_check(self) -> ProcessCheck | None:
        """The process check of every piece checked (once all are), None when not asked for
        or no piece was."""
        if self.local is not None:
            return self.local.process_check()
        value = self._ask(_PROCESS)
        assert value is None or isinstance(value, ProcessCheck)
        return value

    def feed_figures(self) -> list[FeedFigures | None]:
        """Per program job, in order, once all are written: the figures of the feed timing
        done where it was written (:attr:`ProgramJob.timing`), None where it came timed."""
        if self.local is not None:
            return self.local.feeds
        value = self._ask(_FEEDS)
        assert isinstance(value, list)
        return value

    def close_output(self) -> None:
        """Close the program file the pieces were written to (:class:`Writing`), once every
        piece is written."""
        if self.local is not None:
            self.local.close_output()
        else:
            self._ask(_WRITTEN)

    def _ask(self, request: str) -> Any:
        """The worker's answer to ``request``, once it has checked every piece."""
        self._collect()
        assert self.conn is not None
        try:
            self.conn.send(request)
            ok, value = self.conn.recv()
        except (EOFError, OSError):
            raise self._gone() from None
        if not ok:
            raise value
        return value

    def _collect(self) -> None:
        """Take the results of every job handed over."""
        self._join_sender()
        while self.waiting:
            self._take_one()

    def _take_one(self) -> None:
        """Take the result of the oldest job handed over (the worker answers in order)."""
        assert self.conn is not None and self.process is not None
        try:
            if not self.sent:
                raise OSError("not sent")
            ok, value = self.conn.recv()
        except (EOFError, OSError):
            raise self._gone() from None
        self.waiting -= 1
        if not ok:
            raise value
        self.results.append(value)

    def _gone(self) -> UrdfpostError:
        """The error of a worker that stopped (killed, out of memory), nothing written."""
        assert self.process is not None
        self.process.join(timeout=10)
        self.waiting = 0
        return UrdfpostError(
            f"the verification worker (process {self.process.pid}) stopped with exit code "
            f"{self.process.exitcode} before the program was verified; nothing written"
        )

    def _join_sender(self) -> None:
        sender, self.sender = self.sender, None
        if sender is not None:
            # a start cut short (Ctrl-C) leaves a thread that cannot be joined: it never ran,
            # or its write fails once the worker is gone
            with contextlib.suppress(RuntimeError):
                sender.join()

    def close(self) -> None:
        """Stop the worker (at once when a check is still running: the post has failed), or
        close the program file here."""
        if self.local is not None:
            self.local.close_output()
        if self.process is None or self.conn is None:
            return
        if self.waiting:
            self.process.kill()  # (it ignores SIGTERM)
            self._join_sender()  # its write fails once the worker is gone
        else:
            with contextlib.suppress(OSError):
                self.conn.send(None)
        self.process.join(timeout=10)
        if self.process.is_alive():
            self.process.kill()
            self.process.join()
        self.conn.close()
        self.process = None
        for path in self.shared:  # (those of jobs the worker did not take in)
            with contextlib.suppress(OSError):
                os.unlink(path)
        self.shared.clear()


class ReadChecks:
    """Pieces read already (:class:`ReadPiece`, ``urdfpost verify`` in pieces) verified by
    several workers, each piece by the next worker in turn, the results in the pieces' order.

    A read piece is verified on its own (no state carries from one to the next), so the
    pieces can go to as many workers as the machine has cores while this process reads and
    cuts the next ones; each worker holds at most one piece waiting (memory stays bounded).
    With one worker or ``parallel`` False it is :class:`Checks`.
    """

    def __init__(
        self,
        machine: Machine,
        controller: str,
        path: str,
        tol: Tolerances,
        units: str,
        parallel: bool,
        workers: int = 1,
    ) -> None:
        self.members: list[Checks] = []
        self.count = 0  # pieces submitted
        try:
            for _ in range(max(1, workers) if parallel else 1):
                self.members.append(Checks(machine, controller, path, tol, units, parallel))
        except BaseException:
            self.close()
            raise

    def submit(self, job: ReadPiece) -> None:
        """Verify ``job`` in the next worker (after the piece that worker has, if any)."""
        self.members[self.count % len(self.members)].submit(job)
        self.count += 1

    def finish(self) -> list[tuple[Verification, RowFindings | None]]:
        """Every piece's verification and process findings (:meth:`PieceVerifier.check_read`),
        in the order submitted, once all are checked."""
        done = [member.finish() for member in self.members]
        k = len(self.members)
        return [done[i % k][i // k] for i in range(self.count)]

    def close(self) -> None:
        """Stop the workers."""
        for member in self.members:
            member.close()
