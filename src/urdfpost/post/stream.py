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
  place when the last piece is verified (nothing is left behind on an error).
- **Verification** reads back each piece's text with one reader (its modal state carries on
  too) and checks it against the piece's CL points, starting from the last row of the piece
  before: every block of the program is checked once. The figures are merged. On a machine
  with more than one core this runs in a worker process, one piece behind the planning, so
  the two share the work (a piece is handed over when the one before is checked: one piece
  waits at most). A piece that misses its tolerance stops the post all the same.

The singular spans of the report are numbered along the pieces' plan paths joined (each join
once), as :func:`post` numbers them along its plan's path. Figures that depend on the whole job
are taken from the first window: the program name
(``PARTNO``), the ball radius of the first cutter and the tool of the collision world.
"""

from __future__ import annotations

import contextlib
import logging
import multiprocessing
import os
import pickle
import sys
import tempfile
import threading
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, replace
from multiprocessing.connection import Connection
from multiprocessing.process import BaseProcess
from pathlib import Path
from typing import Any

import numpy as np

from urdfpost._files import give_mode
from urdfpost.errors import ToleranceError, UrdfpostError
from urdfpost.linearize import angle_between
from urdfpost.machine import Machine
from urdfpost.planning.strategies import STRATEGIES, Plan, tool_axis_of
from urdfpost.post.pipeline import (
    Continuation,
    PostOptions,
    build_program,
    check_against,
    check_collisions,
    intended_path,
    make_problem,
    make_report,
    strategy_name,
)
from urdfpost.program import Blocks, Insert, Move, MoveTable, Program
from urdfpost.tolerances import Tolerances
from urdfpost.toolpath import Motion, Toolpath
from urdfpost.verify import Verification, missed_note, rewind_note

log = logging.getLogger(__name__)

PIECE_POINTS = 100_000
"""CL points posted per piece by default."""

LOOKAHEAD = 50_000
"""CL points a piece's plan sees past its end, at most, by default (a fifth of the piece below
five times this)."""


_FORK = sys.platform.startswith("linux")
"""Whether verification workers are forked (where forking a process that runs numpy is safe);
elsewhere pieces are verified in the worker only when asked for, in a spawned process."""


@dataclass(frozen=True)
class StreamResult:
    """What :func:`post_stream` produced.

    Attributes
    ----------
    path : Path
        The program file written.
    verification : Verification
        Of the whole program read back, against the CL data (the pieces' checks merged).
    report : dict
        As :func:`urdfpost.post.pipeline.post` reports, with ``streamed`` figures (pieces, piece
        size, lookahead).
    """

    path: Path
    verification: Verification
    report: dict[str, Any]


# -- toolpath pieces -----------------------------------------------------------------------------


def toolpath_slice(toolpath: Toolpath, a: int, b: int, *, first_events: bool = True) -> Toolpath:
    """Points ``a`` to ``b - 1`` of a toolpath, with their events re-indexed.

    The events before points ``a + 1 .. b - 1`` come along, those before point ``a`` when
    ``first_events``, and those after the last point when ``b`` is the end. Array views, no
    copies.
    """
    n = len(toolpath)
    lo = a if first_events else a + 1
    events = tuple(
        replace(e, index=e.index - a)
        for e in toolpath.events
        if lo <= e.index < b or (b == n and e.index == n)
    )
    return replace(
        toolpath,
        tip=toolpath.tip[a:b],
        axis=toolpath.axis[a:b],
        feed=toolpath.feed[a:b],
        motion=toolpath.motion[a:b],
        line=toolpath.line[a:b],
        events=events,
    )


def toolpath_pieces(toolpath: Toolpath, points: int) -> Iterator[Toolpath]:
    """A toolpath as consecutive pieces of at most ``points`` points (the form
    :func:`urdfpost.readers.read_cl_chunks` gives; for jobs already in memory, and tests)."""
    n = len(toolpath)
    if n == 0:
        yield toolpath
        return
    for a in range(0, n, points):
        b = min(a + points, n)
        piece = toolpath_slice(toolpath, a, b)
        yield replace(piece, warnings=toolpath.warnings if a == 0 else ())


def _joined(first: Toolpath, more: list[Toolpath]) -> Toolpath:
    """Toolpaths appended to ``first`` (events after the last point of one come before the
    first point of the next)."""
    parts = [first, *more]
    offsets = np.cumsum([0, *(len(p) for p in parts)])
    return replace(
        more[-1],
        tip=np.concatenate([p.tip for p in parts]),
        axis=np.concatenate([p.axis for p in parts]),
        feed=np.concatenate([p.feed for p in parts]),
        motion=np.concatenate([p.motion for p in parts]),
        line=np.concatenate([p.line for p in parts]),
        events=tuple(
            replace(e, index=e.index + int(at))
            for p, at in zip(parts, offsets, strict=False)
            for e in p.events
        ),
        warnings=tuple(w for p in parts for w in p.warnings),
    )


# -- where a piece ends --------------------------------------------------------------------------


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


# -- merging the figures -------------------------------------------------------------------------


def merge_verifications(parts: list[Verification]) -> Verification:
    """One verification of the pieces' checks of a streamed program.

    Each piece after the first starts with the CL point and the program row the piece before
    ended with: they are counted once.
    """
    first = parts[0]
    joins = len(parts) - 1
    missed: list[int] = []
    for v in parts:
        lines = v.missed_lines
        if missed and lines and lines[0] == missed[-1]:
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
        worst_cl_line=worst.worst_cl_line,
        notes=notes,
        compared=compared,
        rewind_moves=rewinds,
    )


class _Figures:
    """The report figures of the pieces, added up."""

    def __init__(self) -> None:
        self.figures: dict[str, Any] = {}
        self.collisions: list[dict[str, Any]] = []
        self.offset = 0  # index of the piece's first point in the joined plan paths

    def add(self, figures: dict[str, Any], collisions: dict[str, Any]) -> None:
        f = self.figures
        for key in ("branch_switches", "pole_points", "inserted_blocks", "pole_turns"):
            f[key] = f.get(key, 0) + int(figures.get(key, 0))
        f.setdefault("rewinds", []).extend(figures.get("rewinds", []))
        strategy = dict(figures["strategy"])
        # span indices of the whole job: the pieces' plan paths joined, each join counted once
        at = self.offset
        strategy["spans"] = [
            {**sp, "first": sp["first"] + at, "last": sp["last"] + at} for sp in strategy["spans"]
        ]
        self.offset += len(figures["plan"].toolpath) - 1
        if "strategy" not in f:
            f["strategy"] = strategy
        else:
            s = f["strategy"]
            s["bent"] = bool(s["bent"] or strategy["bent"])
            s["lifts"] += strategy["lifts"]
            s["spans"] += strategy["spans"]
        warnings = f.setdefault("warnings", [])
        warnings += [w for w in figures.get("warnings", []) if w not in warnings]
        self.collisions.append(collisions)

    def collision_figures(self) -> dict[str, Any]:
        checked = [c for c in self.collisions if c.get("checked")]
        if not checked:
            return {"checked": False}
        out = dict(
            min(checked, key=lambda c: np.inf if c["min_clearance"] is None else c["min_clearance"])
        )
        out["moves"] = sum(c["moves"] for c in checked)
        out["samples"] = sum(c["samples"] for c in checked)
        out["clearance_points"] = sum(c["clearance_points"] for c in checked)
        return out


# -- the post ------------------------------------------------------------------------------------


def _prepended(program: Program, axes: tuple[str, ...], row: np.ndarray) -> Program:
    """``program`` with a first move at ``row`` (positions of ``axes``): where the piece before
    ended, so that the first block of the piece is checked too."""
    position = np.array([row[axes.index(a)] if a in axes else np.nan for a in program.axes])
    start = MoveTable(position[None, :], np.zeros(1, bool), np.full(1, np.nan), np.full(1, -1))
    return replace(program, blocks=Blocks((start, *program.parts)))


@dataclass(frozen=True)
class _Job:
    """What checking one piece takes: its text, its CL points and what its plan intended."""

    text: str
    inserts: list[str]  # the texts of the piece's inserted blocks, in order
    piece: Toolpath
    reference: Toolpath | None  # the strategy's path where it bent the axis (check_against)
    lifts: int
    strategy: dict[str, Any]
    tool_length: float  # mm

    @classmethod
    def of(cls, text: str, program: Program, piece: Toolpath, found: dict[str, Any]) -> _Job:
        """The job of a piece posted as ``program`` (written as ``text``), with the figures
        ``found`` of :func:`build_program`."""
        return cls(
            text=text,
            inserts=[b.text for b in program.parts if isinstance(b, Insert)],
            piece=piece,
            reference=intended_path(found),
            lifts=found["plan"].lifts,
            strategy=found["strategy"],
            tool_length=program.tool_length,
        )


class _Verifier:
    """Reads back the pieces' texts in order with one reader and checks each against its CL
    points, from the last row of the piece before (module docstring)."""

    def __init__(
        self, machine: Machine, controller: str, path: str, tol: Tolerances, units: str
    ) -> None:
        from urdfpost.dialects import dialect_for

        self.machine, self.tol, self.units = machine, tol, units
        self.reader = dialect_for(controller).reader(path=path)
        self.previous: tuple[tuple[str, ...], np.ndarray] | None = None  # axes, last row

    def check(self, job: _Job) -> tuple[Verification, Verification | None]:
        """The piece's verifications against the CL data and against its strategy's path.

        Raises
        ------
        ToleranceError
            Either misses its tolerance.
        """
        self.reader.feed(job.text, job.inserts)
        readback = self.reader.take()
        if self.previous is not None:
            readback = _prepended(readback, *self.previous)
        piece = job.piece
        check, intent = check_against(
            readback,
            self.machine,
            piece,
            job.reference,
            job.lifts,
            job.strategy,
            self.tol,
            job.tool_length,
        )
        for v, what in ((intent, "the path its strategy intended"), (check, "the CL data")):
            if v is not None and not v.ok:
                raise ToleranceError(
                    f"{piece.source}: the program misses its tolerance against {what} "
                    f"(lines {int(piece.line[0])} to {int(piece.line[-1])}), nothing "
                    f"written: {v.summary(self.units)}"
                    + (f"; worst near CL line {v.worst_cl_line}" if v.worst_cl_line else "")
                )
        table = readback.move_table()
        if len(table):
            self.previous = (readback.axes, np.asarray(table.position[-1]))
        return check, intent


def _serve(conn: Connection, *args: Any) -> None:
    """A verification worker: checks the jobs it receives with one :class:`_Verifier` and
    sends back ``(True, result)`` or ``(False, exception)``, until it receives None."""
    verifier = _Verifier(*args)
    while (job := conn.recv()) is not None:
        try:
            answer: tuple[bool, Any] = (True, verifier.check(job))
        except Exception as exc:  # sent back to be raised where the post runs
            answer = (False, exc)
            try:
                pickle.dumps(exc)
            except Exception:
                answer = (False, UrdfpostError(f"verification failed: {exc!r}"))
        conn.send(answer)


class _Checks:
    """The pieces' checks, in order: in a worker process while the next piece is planned (the
    two cores of a small machine share the work), or here one after the other.

    One piece is checked at a time; the next is handed over when the one before has been
    checked, so at most one piece waits (memory stays bounded).
    """

    def __init__(
        self,
        machine: Machine,
        controller: str,
        path: str,
        tol: Tolerances,
        units: str,
        parallel: bool,
    ) -> None:
        self.results: list[tuple[Verification, Verification | None]] = []
        self.local: _Verifier | None = None
        self.conn: Connection | None = None
        self.process: BaseProcess | None = None
        self.busy = False  # a job was handed over and its result not taken yet
        self.sender: threading.Thread | None = None
        self.sent = True  # whether the last job reached the worker
        args = (machine, controller, path, tol, units)
        if not parallel:
            self.local = _Verifier(*args)
            return
        # a fork carries the machine over as it is and does not import the caller's main
        # module again (which a script without a main guard would not survive)
        context = (
            multiprocessing.get_context("fork") if _FORK else multiprocessing.get_context("spawn")
        )
        self.conn, child = context.Pipe()
        self.process = context.Process(target=_serve, args=(child, *args), daemon=True)
        self.process.start()
        child.close()
        log.info("streamed pieces are verified in worker process %d", self.process.pid)

    def submit(self, job: _Job) -> None:
        """Check ``job`` (after the one before, which it waits for in the worker).

        The job is pickled and sent from a thread, so that planning the next piece goes on
        while the worker takes it in.
        """
        if self.local is not None:
            self.results.append(self.local.check(job))
            return
        self._collect()
        self.busy = True
        self.sender = threading.Thread(target=self._send, args=(job,), daemon=True)
        self.sender.start()

    def _send(self, job: _Job) -> None:
        assert self.conn is not None
        try:
            self.conn.send(job)
        except OSError:  # a broken pipe: the worker is gone (reported by _collect)
            self.sent = False

    def finish(self) -> list[tuple[Verification, Verification | None]]:
        """Every piece's verifications, in order, once all are checked."""
        self._collect()
        return self.results

    def _collect(self) -> None:
        if not self.busy:
            return
        assert self.conn is not None and self.process is not None
        self._join_sender()
        try:
            if not self.sent:
                raise OSError("not sent")
            ok, value = self.conn.recv()
        except (EOFError, OSError):
            raise self._gone() from None
        self.busy = False
        if not ok:
            raise value
        self.results.append(value)

    def _gone(self) -> UrdfpostError:
        """The error of a worker that stopped (killed, out of memory), nothing written."""
        assert self.process is not None
        self.process.join(timeout=10)
        self.busy = False
        return UrdfpostError(
            f"the verification worker (process {self.process.pid}) stopped with exit code "
            f"{self.process.exitcode} before the program was verified; nothing written"
        )

    def _join_sender(self) -> None:
        if self.sender is not None:
            self.sender.join()
            self.sender = None

    def close(self) -> None:
        """Stop the worker (at once when a check is still running: the post has failed)."""
        if self.process is None or self.conn is None:
            return
        if self.busy:
            self.process.terminate()
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
        ``piece_points``, at most :data:`LOOKAHEAD`.
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
    UnreachableError, CollisionError, ToleranceError, UrdfpostError
        As :func:`urdfpost.post.pipeline.post`; nothing is written then.
    ValueError
        ``piece_points`` under 2 or ``lookahead`` under 1.
    """
    from urdfpost.dialects import dialect_for

    if lookahead is None:
        lookahead = max(1, min(LOOKAHEAD, piece_points // 5))
    if piece_points < 2 or lookahead < 1:
        raise ValueError(
            f"piece_points must be at least 2 and lookahead at least 1, got {piece_points} and "
            f"{lookahead}"
        )
    options = options or PostOptions()
    out = Path(out)
    dialect = dialect_for(options.controller or machine.settings.controller)
    source = iter(pieces)
    buffer = next(source, None)
    if buffer is None:
        raise ValueError("post_stream: no toolpath pieces given")
    exhausted = False
    units = options.units or buffer.units
    tol = Tolerances.for_units(units, options.tolerance)
    base = None
    writer = None
    figures = _Figures()
    start: np.ndarray | None = None
    last_piece: Toolpath | None = None
    reader_warnings = list(buffer.warnings)  # the job's, in order
    buffer = replace(buffer, warnings=())
    program: Program | None = None
    checks: _Checks | None = None
    unsettled: list[int] = []  # CL lines of the joins whose branch choice rests on the lookahead
    count = 0
    fd, tmp_name = tempfile.mkstemp(prefix=f".{out.name}.", suffix=".part", dir=out.parent or ".")
    tmp = Path(tmp_name)
    try:
        with os.fdopen(fd, "w", encoding="utf-8", newline="") as handle:
            want = piece_points  # CL points of the next piece (more where no cut was found)
            while True:
                pending, have = [], len(buffer)
                while not exhausted and have < want + lookahead:
                    more = next(source, None)
                    if more is None:
                        exhausted = True
                    else:
                        reader_warnings += more.warnings
                        pending.append(replace(more, warnings=()))
                        have += len(more)
                if pending:
                    buffer = _joined(buffer, pending)
                last = exhausted and len(buffer) <= want + lookahead
                window = buffer if last else toolpath_slice(buffer, 0, want + lookahead)
                if base is None:
                    base = make_problem(window, machine, options, tol)
                if checks is None:
                    if parallel is None:
                        parallel = _FORK and not last and (os.cpu_count() or 1) > 1
                    checks = _Checks(machine, dialect.name, str(out), tol, units, parallel)
                problem = replace(base, toolpath=window, start=start)
                plan = STRATEGIES[strategy_name(machine, options)](problem)
                if last:
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
                    start=start, tcp_on=start is not None and options.tcp, last=last
                )
                program, found = build_program(
                    piece,
                    machine,
                    options,
                    tol,
                    plan=plan,
                    problem=replace(problem, toolpath=piece),
                    piece=continuation,
                )
                collisions = check_collisions(found, piece, units)
                if writer is None:
                    writer = dialect.writer(program, block_numbers=options.block_numbers or None)
                    header = None
                    if not options.tcp:
                        header = (
                            f"machine coordinates for machine {machine.name} with tool length "
                            f"{program.tool_length:.3f} mm from the gauge point: the tool "
                            "table length must be 0"
                        )
                    writer.open(header)
                writer.write_body(program)
                if last:
                    writer.close()
                text = writer.take()
                handle.write(text)
                checks.submit(_Job.of(text, program, piece, found))
                figures.add(found, collisions)
                if "joints" in found and len(found["joints"]):
                    start = found["joints"][-1]
                count += 1
                if progress:
                    progress(len(piece) - (1 if count > 1 else 0))
                if last:
                    break
                buffer = toolpath_slice(buffer, cut, len(buffer), first_events=False)
                log.info(
                    "streamed piece %d: CL lines %d to %d", count, piece.line[0], piece.line[-1]
                )
        assert checks is not None
        results = checks.finish()
        verification = merge_verifications([check for check, _ in results])
        intents = [intent for _, intent in results if intent is not None]
        assert program is not None and last_piece is not None
        merged = dict(figures.figures)
        merged["warnings"] = merged.get("warnings", [])
        if unsettled:
            merged["warnings"].append(
                f"{last_piece.source}: at {len(unsettled)} of {count - 1} joins of the "
                f"streamed pieces (the first at CL line {unsettled[0]}) the branch choice rests on "
                f"{lookahead} CL points of lookahead: the whole job could choose otherwise "
                "there (a travel limit further on); --piece-points 0 plans it whole"
            )
        job = replace(last_piece, warnings=tuple(reader_warnings))
        report = make_report(job, machine, program, verification, dialect.name, merged)
        report["collisions"] = figures.collision_figures()
        if intents:
            report["strategy"]["intended_path_check"] = merge_verifications(intents).as_dict()
        report["streamed"] = {
            "pieces": count,
            "piece_points": piece_points,
            "lookahead": lookahead,
            "worker": bool(parallel),  # pieces verified in a worker process
            # joins where the branch choice is not settled by the window (CL lines)
            "unsettled_joins": unsettled,
        }
        give_mode(tmp, out)
        os.replace(tmp, out)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    finally:
        if checks is not None:
            checks.close()
    return StreamResult(path=out, verification=verification, report=report)


# -- verifying a program against its CL data in pieces -----------------------------------------

TEXT_PIECE = 8 << 20
"""Characters of program text read at a time by :func:`verify_stream`."""


def program_texts(path: str | os.PathLike[str], size: int = TEXT_PIECE) -> Iterator[str]:
    """The text of a program file in pieces of about ``size`` characters, cut at line ends
    (as the CL readers read theirs: :func:`urdfpost.readers._stream.text_pieces`).

    Raises
    ------
    UrdfpostError
        The file cannot be read.
    """
    from urdfpost.errors import CLDataError
    from urdfpost.readers._stream import text_pieces

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

    The matching of CL points to rows is sequential (:func:`urdfpost.verify._match`): each
    point is searched from the row the point before reached. Cut at a point ``c`` reached by
    row ``r``, with the next point reached by a later row, the second side starts where the
    whole check is after ``c``; the first side holds every row the search for a point up to
    ``c`` looks at when the rows go on :data:`_REACH` past ``r`` (or the program ends). The
    blocks into and out of ``r`` are feed moves outside rewinds, so that the rapids and the
    rewinds of each side are what they are in the whole.

    Returns
    -------
    (c, r) or None
    """
    from urdfpost.program import rewind_moves
    from urdfpost.verify import _REACH, _at_pivot, _match, _row_poses_at_tip, program_joints

    values, rapid = program_joints(machine, program)
    n_rows, n_cl = len(values), len(cl)
    if n_rows < 3 or n_cl < 3:
        return None
    rows = _at_pivot(_row_poses_at_tip(machine, values, program.tcp, tool_length), pivot)
    match = _match(cl.tip + pivot * cl.axis, cl.axis, rows.tip, rows.axis, tol)
    aside = rapid | rewind_moves(program)
    j = np.arange(1, min(target, n_cl - 2) + 1)
    r = match[j]
    ok = (r >= 1) & (match[j + 1] > r) & (r + 1 < n_rows)
    if not program_ends:
        ok &= r + _REACH + 1 < n_rows
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
) -> tuple[Verification, Program]:
    """:func:`urdfpost.verify.verify` of a program file against CL data given in pieces, in
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
        Consecutive pieces of the CL data (:func:`urdfpost.readers.read_cl_chunks`).
    machine : Machine
    controller : str
        Dialect of the program.
    tol : Tolerances
    tool_length : float, mm
    pivot : float, mm
        As :func:`urdfpost.verify.verify`.
    piece_points : int
        CL points checked per piece, about.
    texts : iterable of str, optional
        The program text in pieces cut at line ends (default: read from ``program_path``).

    Returns
    -------
    verification : Verification
    header : Program
        The program's header (name, units, TCP, tool length) without blocks.

    Raises
    ------
    ProgramParseError, UrdfpostError
        A program line that cannot be read; a file that cannot.
    """
    from urdfpost.dialects import dialect_for
    from urdfpost.verify import _REACH, verify

    if piece_points < 2:
        raise ValueError(f"piece_points must be at least 2, got {piece_points}")
    reader = dialect_for(controller).reader(path=str(program_path))
    text_source = iter(program_texts(program_path) if texts is None else texts)
    cl_source = iter(cl_pieces)
    program: Program | None = None
    cl: Toolpath | None = None
    program_ends = cl_ends = False
    parts: list[Verification] = []
    header: Program | None = None
    want = piece_points
    rows_per_point = 1.5  # a first guess, then as the pieces so far had
    rows_done = points_done = 0
    while True:
        while not cl_ends and (cl is None or len(cl) < want + 2):
            more = next(cl_source, None)
            if more is None:
                cl_ends = True
            else:
                cl = more if cl is None else _joined(cl, [more])
        need = int(rows_per_point * want) + _REACH + 2
        while not program_ends and (program is None or len(program.move_table()) < need):
            text = next(text_source, None)
            if text is None:
                program_ends = True
                continue
            reader.feed(text)
            program = _joined_programs(program, reader.take())
        if program is None:
            program = reader.take()
        if header is None:
            header = replace(program, blocks=Blocks(()))
        assert cl is not None
        if cl_ends and program_ends:
            parts.append(
                verify(program, machine, cl, tool_length=tool_length, tol=tol, pivot=pivot)
            )
            break
        cut = _verify_cut(program, machine, cl, tol, tool_length, pivot, want, program_ends)
        if cut is None:  # nowhere to cut yet: a longer piece, and more rows
            want *= 2
            continue
        c, r = cut
        head, program = _split_rows(program, r)
        parts.append(
            verify(
                head, machine, toolpath_slice(cl, 0, c + 1), tool_length=tool_length, tol=tol,
                pivot=pivot,
            )
        )  # fmt: skip
        cl = toolpath_slice(cl, c, len(cl), first_events=False)
        rows_done += r
        points_done += c
        rows_per_point = max(1.0, 1.25 * rows_done / max(points_done, 1))
        want = piece_points
        log.info("verified a piece: CL lines to %d, program rows to %d", cl.line[0], rows_done)
    assert header is not None
    return merge_verifications(parts), header


__all__ = [
    "LOOKAHEAD",
    "PIECE_POINTS",
    "StreamResult",
    "merge_verifications",
    "post_stream",
    "program_texts",
    "toolpath_pieces",
    "toolpath_slice",
    "verify_stream",
]
