"""Strategies side by side: the same CL data, machine and control, the same metrics.

Every strategy is posted as ``urdfpost post`` would post it (program text written in the
dialect and read back), checked the same way, and measured by
:func:`urdfpost.analysis.metrics.measure`. A strategy whose program misses its tolerance is
still measured: the comparison shows how far it misses. A strategy that makes no program (a
point out of travel, a limit, ...) is an outcome too, with the error that refused it: a job no
strategy can post is compared like any other.
"""

from __future__ import annotations

import logging
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from itertools import pairwise
from typing import Any

import numpy as np

from urdfpost.analysis.metrics import Metrics, cl_path_position, measure
from urdfpost.errors import UnreachableError, UrdfpostError
from urdfpost.machine import Machine
from urdfpost.planning.singularity import Span
from urdfpost.planning.strategies import STRATEGIES
from urdfpost.posting.check import bent_tolerances
from urdfpost.posting.options import Job, PostOptions, resolve
from urdfpost.posting.piece import post_piece
from urdfpost.posting.whole import travel_hint, written
from urdfpost.program import Program
from urdfpost.tolerances import Tolerances
from urdfpost.toolpath import Toolpath
from urdfpost.units import mm_per_unit
from urdfpost.verification import (
    Verification,
    at_pivot,
    match_points,
    program_joints,
    row_poses_at_tip,
)

#: Characters of an error message kept in :attr:`Outcome.reason` (plot legends, one line).
REASON_CHARS = 120

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Outcome:
    """One strategy's result.

    Attributes
    ----------
    strategy : str
    metrics : Metrics or None
        None when the strategy could not make a program at all (``error`` says why).
    verified : bool
        The program meets its tolerances (against the CL data, and against the strategy's
        intended path when it bends the tool axis).
    error : str or None
        Why not: the error that refused the job, or the summary of the failed verification.
    bent : bool
        Whether the strategy moved the tool axis off the programmed one.
    reason : str or None
        ``error`` in one short line of at most :data:`REASON_CHARS` characters (for plot
        legends): which figures missed their tolerance and near which CL line, or the first
        clause of the error message.
    cl_index : ndarray or None, shape (N,)
        Position of each row of ``metrics.profile`` along the CL points: the index of the CL
        point a row reaches, fractional between them (by tip path length, by row where the tip
        stands); NaN before the first CL point reached and after the last (the moves the post
        adds: approach, retract, home). Not part of :meth:`as_dict`.
    """

    strategy: str
    metrics: Metrics | None
    verified: bool
    error: str | None
    bent: bool
    reason: str | None = None
    cl_index: np.ndarray | None = field(default=None, repr=False, compare=False)

    def as_dict(self) -> dict[str, Any]:
        """Plain data for JSON."""
        return {
            "strategy": self.strategy,
            "verified": self.verified,
            "error": self.error,
            "reason": self.reason,
            "bent": self.bent,
            "metrics": self.metrics.as_dict() if self.metrics else None,
        }


@dataclass(frozen=True)
class Comparison:
    """All strategies on one job.

    Attributes
    ----------
    machine : str
    source : str
    tcp : bool
    controller : str
    outcomes : list of Outcome
    spans : list of Span
        Singular spans of the CL data: ``first`` and ``last`` index the CL points as read
        (0 .. n - 1), ``first_line`` and ``last_line`` are their lines in the CL file.
    cl_s : ndarray, shape (n,), mm
        Path position of each CL point.
    """

    machine: str
    source: str
    tcp: bool
    controller: str
    outcomes: list[Outcome]
    spans: list[Span]
    cl_s: np.ndarray

    @property
    def posted(self) -> bool:
        """Whether any strategy made a verified program (one ``urdfpost post`` would write)."""
        return any(o.verified for o in self.outcomes)

    def as_dict(self) -> dict[str, Any]:
        """Plain data for JSON."""
        return {
            "machine": self.machine,
            "cl": self.source,
            "tcp": self.tcp,
            "controller": self.controller,
            "cl_points": len(self.cl_s),
            "posted": self.posted,
            "spans": [s.as_dict() for s in self.spans],
            "strategies": [o.as_dict() for o in self.outcomes],
        }


def spans_on_cl(spans: Sequence[Span], cl: Toolpath) -> list[Span]:
    """Spans a strategy found on its own toolpath, indexed by the CL points as read.

    A strategy may detect spans on a copy of the CL data with points inserted (pole
    crossings), so its indices run past the CL points; the CL lines it names are those of
    the CL file (an inserted point carries the line of the move's end). The span is taken
    from the first CL point of its first line to the last CL point of its last line: exact
    for one point per record, the whole record for a record of several (an arc).

    Parameters
    ----------
    spans : sequence of Span
    cl : Toolpath
        The CL data as read (lines non-decreasing).

    Returns
    -------
    list of Span
        ``0 <= first <= last <= len(cl) - 1``.
    """
    lines, n = cl.line, len(cl)
    out = []
    for sp in spans:
        a = int(np.searchsorted(lines, sp.first_line, side="left"))
        b = int(np.searchsorted(lines, sp.last_line, side="right")) - 1
        a = min(max(a, 0), n - 1)
        out.append(replace(sp, first=a, last=min(max(b, a), n - 1)))
    return out


def cl_index_of_rows(
    program: Program,
    machine: Machine,
    cl: Toolpath,
    s: np.ndarray,
    *,
    tool_length: float,
    tol: Tolerances,
    pivot: float = 0.0,
) -> np.ndarray | None:
    """Where each row of a program is along the CL points (see :attr:`Outcome.cl_index`).

    Parameters
    ----------
    program : Program
        As read back from its text (every row is a row of its metrics' profile).
    machine : Machine
    cl : Toolpath
        The CL data.
    s : ndarray, shape (N,), mm
        Tip path position of the rows (:attr:`urdfpost.analysis.metrics.Profile.s`).
    tool_length : float, mm
    tol : Tolerances
        Which rows reach a CL point (:func:`urdfpost.verification.match_points`).
    pivot : float, mm
        The point compared, this far up the tool axis.

    Returns
    -------
    ndarray, shape (N,), or None
        NaN outside the rows that reach the first and the last CL point reached; None when
        the rows are not those of ``s``, or reach no CL point.
    """
    values, _ = program_joints(machine, program)
    if len(values) != len(s) or len(values) == 0 or len(cl) == 0:
        return None
    rows = at_pivot(row_poses_at_tip(machine, values, program.tcp, tool_length), pivot)
    match = match_points(cl.tip + pivot * cl.axis, cl.axis, rows.tip, rows.axis, tol)
    reached = np.flatnonzero(match >= 0)
    if reached.size == 0:
        return None
    at = match[reached]
    out = np.full(len(s), np.nan)
    out[at[-1]] = reached[-1]
    for (r0, r1), (j0, j1) in zip(pairwise(at), pairwise(reached), strict=True):
        k = np.arange(r0, r1 + 1)
        length = s[r1] - s[r0]
        frac = (s[k] - s[r0]) / length if length > 0 else (k - r0) / max(r1 - r0, 1)
        out[k] = j0 + np.clip(frac, 0.0, 1.0) * (j1 - j0)
    return out


_CLAUSE = 30
"""Characters a message's first clause has at least: a ": " or "; " before them does not end it
(it ends a name: "cone: ...")."""


def _short(text: str, source: str = "") -> str:
    """The first clause of a message, in :data:`REASON_CHARS` characters at most; a leading
    ``source:LINE:`` becomes ``line LINE:``."""
    text = " ".join(text.split())
    if source and text.startswith(f"{source}:"):
        text = re.sub(r"^(\d+): ", r"line \1: ", text[len(source) + 1 :].lstrip())
    cuts = [i for i in (text.find(": ", _CLAUSE), text.find("; ", _CLAUSE)) if i > 0]
    if cuts:
        text = text[: min(cuts)]
    return text if len(text) <= REASON_CHARS else text[: REASON_CHARS - 3].rstrip() + "..."


def _check_reason(check: Verification, units: str, against: str) -> str:
    """The figures of a failed verification in one line."""
    scale = mm_per_unit(units)
    parts = []
    if check.reached < check.cl_points:
        parts.append(f"{check.cl_points - check.reached}/{check.cl_points} CL points missed")
    if check.max_tip_deviation > check.tip_tolerance:
        parts.append(
            f"tip {check.max_tip_deviation / scale:.4g} > {check.tip_tolerance / scale:.4g} {units}"
        )
    if check.max_orientation_deviation_deg > check.orientation_tolerance_deg:
        parts.append(
            f"axis {check.max_orientation_deviation_deg:.3g} > "
            f"{check.orientation_tolerance_deg:.3g} deg"
        )
    where = f" near CL line {check.worst_cl_line}" if check.worst_cl_line else ""
    text = f"{', '.join(parts) or 'beyond tolerance'}{where}{against}"
    return text if len(text) <= REASON_CHARS else text[: REASON_CHARS - 3].rstrip() + "..."


def compare(
    toolpath: Toolpath,
    machine: Machine,
    strategies: Sequence[str],
    options: PostOptions | None = None,
    progress: Callable[[str], None] | None = None,
) -> Comparison:
    """Post ``toolpath`` with each strategy and measure every program the same way.

    Parameters
    ----------
    toolpath : Toolpath
    machine : Machine
    strategies : sequence of str
        Names from :data:`~urdfpost.planning.strategies.STRATEGIES`.
    options : PostOptions, optional
        Everything but the strategy.
    progress : callable, optional
        Called with each strategy's name before it runs.

    Returns
    -------
    Comparison
        One outcome per strategy, in order: a program that posting refused (an error) is an
        outcome with no metrics, never an exception.
    """
    options = options or PostOptions()
    unknown = [s for s in strategies if s not in STRATEGIES]
    if unknown:
        raise UrdfpostError(
            f"unknown strategies {', '.join(unknown)}; expected names from {', '.join(STRATEGIES)}"
        )
    outcomes: list[Outcome] = []
    spans: list[Span] | None = None
    job = resolve(options, machine, toolpath.units)
    for name in strategies:
        if progress:
            progress(name)
        job = replace(job, strategy=name)
        try:
            outcome, plan_spans = _outcome(toolpath, job, name)
        except UrdfpostError as e:
            log.info("strategy %s: %s", name, e)
            hint = travel_hint(toolpath, job) if isinstance(e, UnreachableError) else ""
            error = f"{e}{hint}"
            outcomes.append(
                Outcome(name, None, False, error, False, _short(error, toolpath.source))
            )
            continue
        if spans is None or name == "recursive":
            spans = spans_on_cl(plan_spans, toolpath)
        outcomes.append(outcome)
    return Comparison(
        machine=machine.name,
        source=toolpath.source,
        tcp=options.tcp,
        controller=job.dialect.name,
        outcomes=outcomes,
        spans=spans or [],
        cl_s=cl_path_position(toolpath),
    )


def _outcome(toolpath: Toolpath, job: Job, name: str) -> tuple[Outcome, list[Span]]:
    """Post, read back, check and measure one strategy; the spans its plan saw.

    Raises
    ------
    UrdfpostError
        When the strategy makes no program.
    """
    posted = post_piece(toolpath, job)
    plan = posted.plan
    _, readback, (cl, intended) = written(posted, job)
    target, measure_tol = posted.target, job.tol
    pivot = target.pivot_mm if plan.bent else 0.0
    if plan.bent:
        measure_tol = bent_tolerances(job.tol, target.angle_tolerance_deg, target.pivot_mm)
    tool_length = posted.program.tool_length
    metrics = measure(
        readback,
        job.machine,
        toolpath,
        tool_length=tool_length,
        tol=measure_tol,
        pivot=pivot,
        lifts=plan.lifts,
    )
    cl_index = None
    if metrics.profile is not None:
        cl_index = cl_index_of_rows(
            readback,
            job.machine,
            toolpath,
            metrics.profile.s,
            tool_length=tool_length,
            tol=measure_tol,
            pivot=pivot,
        )
    ok = cl.ok and (intended is None or intended.ok)
    error = reason = None
    if not ok:
        own = intended is not None and not intended.ok
        bad = intended if own and intended is not None else cl
        error = bad.summary(job.units)
        if bad.worst_cl_line:
            error += f"; worst near CL line {bad.worst_cl_line}"
        reason = _check_reason(bad, job.units, " (intended path)" if own else "")
    outcome = Outcome(name, metrics, bool(ok), error, bool(plan.bent), reason, cl_index)
    return outcome, list(plan.spans)


def table(comparison: Comparison, units: str = "mm") -> str:
    """The comparison as a fixed-width text table (one row per strategy).

    Columns: verified, blocks, added blocks, largest step of the first rotary axis, its peak
    velocity at the programmed feed within the velocity limits and the peak the feed alone
    would demand, peak acceleration and jerk, estimated time and slow-down, tip and
    orientation deviation from the CL data, smallest conditioning, lifts.
    """
    scale = mm_per_unit(units)
    first = None
    for o in comparison.outcomes:
        if o.metrics and o.metrics.max_step_deg:
            first = next(iter(o.metrics.max_step_deg))
            break
    a = first or "-"
    head = (
        f"{'strategy':<12} {'ok':>3} {'blocks':>7} {'added':>6} {'max ' + a + ' step':>11} "
        f"{a + ' vel':>9} {a + ' demand':>10} {a + ' acc':>10} {a + ' jerk':>11} "
        f"{'time s':>8} {'slow':>6} {'tip dev':>8} {'axis dev':>8} {'min sig':>8} {'lifts':>5}"
    )
    lines = [
        f"{comparison.source} on {comparison.machine} ({comparison.controller}, "
        f"{'TCP' if comparison.tcp else 'machine coordinates'}); {len(comparison.spans)} singular "
        f"spans; angles deg, rates deg/s, deviations {units} and deg",
        head,
        "-" * len(head),
    ]

    def g(d: dict[str, float], k: str | None) -> float:
        return float(d.get(k, float("nan"))) if k else float("nan")

    for o in comparison.outcomes:
        m = o.metrics
        if m is None:
            lines.append(f"{o.strategy:<12} {'no':>3}  failed: {o.error}")
            continue
        lines.append(
            f"{o.strategy:<12} {'yes' if o.verified else 'NO':>3} {m.blocks:>7d} "
            f"{m.added_blocks:>6d} {g(m.max_step_deg, first):>11.2f} "
            f"{g(m.peak_velocity, first):>9.1f} {g(m.peak_demand_velocity, first):>10.1f} "
            f"{g(m.peak_acceleration, first):>10.3g} {g(m.peak_jerk, first):>11.3g} "
            f"{m.time_s:>8.2f} {m.slowdown:>6.2f} {m.max_tip_deviation / scale:>8.4f} "
            f"{m.max_orientation_deviation_deg:>8.3f} {m.min_sigma:>8.4f} {m.lifts:>5d}"
        )
    return "\n".join(lines)
