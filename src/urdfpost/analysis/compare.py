"""Strategies side by side: the same CL data, machine and control, the same metrics.

Every strategy is posted as ``urdfpost post`` would post it (program text written in the
dialect and read back), checked the same way, and measured by
:func:`urdfpost.analysis.metrics.measure`. A strategy whose program misses its tolerance is
still measured: the comparison shows how far it misses. A strategy that makes no program (a
point out of travel, a limit, ...) is an outcome too, with the error that refused it: a job no
strategy can post is compared like any other.

One acceptance rule for every strategy (``verified``)
    A program is accepted when (1) it follows the path its strategy planned within the post's
    tolerances, tip and tool axis (for a strategy that does not bend the tool axis, the planned
    path is the CL data), and (2) it follows the CL data with the tool axis allowed the angle
    tolerance on top of the axis tolerance, measured at the cutting point: the ball centre of a
    ball-end tool, with the tip tolerance plus ball radius times axis tolerance (what a ball
    centre moves when tip and axis are each within theirs), else the tip. Both are the checks
    ``urdfpost post`` makes; here they are made, with the same figures, for every strategy.
    The deviation is reported at the tip and at the ball centre for every strategy.

One planner
    Every strategy runs with the job's planner, except a strategy whose definition fixes its
    own (:data:`FIXED_PLANNER`); the outcome names the planner used.
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
from urdfpost.geometry import slerp
from urdfpost.linearize import RowPoses
from urdfpost.machine import Machine
from urdfpost.machine.load import axis_limits
from urdfpost.planning.singularity import Span
from urdfpost.planning.strategies import STRATEGIES
from urdfpost.posting.check import bent_tolerances
from urdfpost.posting.options import Job, PostOptions, resolve
from urdfpost.posting.piece import post_piece
from urdfpost.posting.whole import travel_hint, written
from urdfpost.program import Program
from urdfpost.strict_json import json_ready
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

#: Strategies whose definition fixes the branch planner whatever the job's (``none`` is the
#: naive post: each point nearest the previous one, :mod:`urdfpost.planning.strategies.pole`).
FIXED_PLANNER = {"none": "local"}

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
    planner : str
        The branch planner the strategy ran with ("global" or "local").
    singular_time_s : float or None
        Time the timed trajectory spends in the singular spans (from the first CL point of a
        span to its last), None without a program or without spans.
    cl_index : ndarray or None, shape (N,)
        Position of each row of ``metrics.profile`` along the CL points: the index of the CL
        point a row reaches, fractional between them (by tip path length, by row where the tip
        stands); NaN before the first CL point reached and after the last (the moves the post
        adds: approach, retract, home). Not part of :meth:`as_dict`.
    deviation : ndarray or None, shape (N, 3)
        Per row: the largest tip deviation (mm), ball-centre deviation (mm; NaN for a tool that
        is not ball-ended) and tool-axis deviation (deg) from the CL data of the block ending
        there, sampled at the block's end and middle (:func:`block_deviation`); NaN where the
        row has no place on the CL points. Not part of :meth:`as_dict`.
    """

    strategy: str
    metrics: Metrics | None
    verified: bool
    error: str | None
    bent: bool
    reason: str | None = None
    planner: str = "global"
    singular_time_s: float | None = None
    cl_index: np.ndarray | None = field(default=None, repr=False, compare=False)
    deviation: np.ndarray | None = field(default=None, repr=False, compare=False)

    def as_dict(self) -> dict[str, Any]:
        """Plain data for JSON."""
        return {
            "strategy": self.strategy,
            "verified": self.verified,
            "error": self.error,
            "reason": self.reason,
            "bent": self.bent,
            "planner": self.planner,
            "singular_time_s": json_ready(self.singular_time_s),
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
    limits : dict
        The axis limits the timed kinematics used, per axis ``{"velocity", "acceleration",
        "jerk"}`` (degrees for rotary axes, mm for linear ones; ``inf`` for none).
    acceptance : dict
        The acceptance rule's tolerances: ``tip`` (mm), ``axis`` (deg), ``angle`` (deg, the
        bending allowed on top against the CL data), ``ball_radius`` (mm, 0 when the cutting
        point is the tip).
    """

    machine: str
    source: str
    tcp: bool
    controller: str
    outcomes: list[Outcome]
    spans: list[Span]
    cl_s: np.ndarray
    limits: dict[str, dict[str, float]] = field(default_factory=dict)
    acceptance: dict[str, float] = field(default_factory=dict)

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
            "limits": json_ready(self.limits),
            "acceptance": json_ready(self.acceptance),
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
    # the strategies' programs as lines: their figures (timing, metrics) are of moves, and an
    # arc block is none (urdfpost.posting.arcs writes arcs in a post)
    job = replace(resolve(options, machine, toolpath.units), arcs=False)
    acceptance: dict[str, float] = {}
    for name in strategies:
        if progress:
            progress(name)
        job = replace(job, strategy=name)
        planner = FIXED_PLANNER.get(name, job.planner)
        try:
            outcome, plan_spans, acceptance = _outcome(toolpath, job, name, planner)
        except UrdfpostError as e:
            log.info("strategy %s: %s", name, e)
            hint = travel_hint(toolpath, job) if isinstance(e, UnreachableError) else ""
            error = f"{e}{hint}"
            short = _short(error, toolpath.source)
            outcomes.append(Outcome(name, None, False, error, False, short, planner))
            continue
        if spans is None or name == "recursive":
            spans = spans_on_cl(plan_spans, toolpath)
        outcomes.append(outcome)
    spans = spans or []
    outcomes = [replace(o, singular_time_s=singular_time(o, spans)) for o in outcomes]
    rotary = frozenset(a.name for a in machine.rotary)
    return Comparison(
        machine=machine.name,
        source=toolpath.source,
        tcp=options.tcp,
        controller=job.dialect.name,
        outcomes=outcomes,
        spans=spans,
        cl_s=cl_path_position(toolpath),
        limits=axis_limits(machine).as_dict(rotary),
        acceptance=acceptance,
    )


def singular_time(outcome: Outcome, spans: Sequence[Span]) -> float | None:
    """Time an outcome's timed trajectory spends in the singular spans.

    A span runs from the first row at or after its first CL point to the last row at or
    before its last CL point (:attr:`Outcome.cl_index`).

    Returns
    -------
    float or None, s
        None when the outcome has no program, its rows have no CL index, or there are no spans.
    """
    m, ci = outcome.metrics, outcome.cl_index
    if m is None or m.profile is None or ci is None or not spans:
        return None
    t = m.profile.t
    total = 0.0
    for sp in spans:
        inside = np.flatnonzero(np.isfinite(ci) & (ci >= sp.first) & (ci <= sp.last))
        if inside.size:
            total += float(t[inside[-1]] - t[inside[0]])
    return total


def _outcome(
    toolpath: Toolpath, job: Job, name: str, planner: str
) -> tuple[Outcome, list[Span], dict[str, float]]:
    """Post, read back, check and measure one strategy; the spans its plan saw; the
    acceptance rule's tolerances (see the module docstring).

    Raises
    ------
    UrdfpostError
        When the strategy makes no program.
    """
    posted = post_piece(toolpath, job)
    plan = posted.plan
    _, readback, (cl, intended) = written(posted, job)
    target = posted.target
    ball = float(target.pivot_mm)
    rule = bent_tolerances(job.tol, target.angle_tolerance_deg, ball)
    tool_length = posted.program.tool_length
    metrics = measure(
        readback,
        job.machine,
        toolpath,
        tool_length=tool_length,
        tol=rule,
        pivot=ball,
        ball_radius=ball,
        lifts=plan.lifts,
        axis_feed_rule=job.dialect.spec.axis_feed_rule,
    )
    cl_index = deviation = None
    if metrics.profile is not None:
        cl_index = cl_index_of_rows(
            readback,
            job.machine,
            toolpath,
            metrics.profile.s,
            tool_length=tool_length,
            tol=rule,
            pivot=ball,
        )
    if cl_index is not None:
        deviation = block_deviation(
            readback, job.machine, toolpath, cl_index, tool_length=tool_length, ball_radius=ball
        )
    # (1) its own path at the post's tolerances: the intended path of a bent plan, else the
    # CL data as it is; (2) the CL data with the angle allowance at the cutting point
    own = intended if plan.bent and intended is not None else cl
    ok = own.ok and metrics.verified
    error = reason = None
    if not ok:
        is_own = not own.ok and own is intended
        bad = own if not own.ok else cl
        error = bad.summary(job.units)
        if bad.worst_cl_line:
            error += f"; worst near CL line {bad.worst_cl_line}"
        reason = _check_reason(bad, job.units, " (intended path)" if is_own else "")
    acceptance = {
        "tip": float(job.tol.tip),
        "axis": float(np.degrees(job.tol.orientation)),
        "angle": float(target.angle_tolerance_deg),
        "ball_radius": ball,
    }
    outcome = Outcome(
        name,
        metrics,
        bool(ok),
        error,
        bool(plan.bent),
        reason,
        planner,
        cl_index=cl_index,
        deviation=deviation,
    )
    return outcome, list(plan.spans), acceptance


def block_deviation(
    program: Program,
    machine: Machine,
    cl: Toolpath,
    cl_index: np.ndarray,
    *,
    tool_length: float,
    ball_radius: float = 0.0,
) -> np.ndarray:
    """Deviation of each block from the CL data, sampled at its end and its middle.

    The middle is where the control puts it (TCP: tip and rotary angles halfway; machine
    coordinates: every axis halfway). Each sample is compared with the CL segments the block
    spans (by :attr:`Outcome.cl_index`): the distance to the nearest, and the angle to the CL
    tool axis interpolated there. The largest figures of a program are those of
    :func:`urdfpost.verification.verify` (:class:`Metrics`), which samples and refines every
    block; these are for per-block data.

    Parameters
    ----------
    program : Program
        As read back (its rows are those of ``cl_index``).
    machine : Machine
    cl : Toolpath
    cl_index : ndarray, shape (N,)
    tool_length : float, mm
    ball_radius : float, mm
        0 for a tool that is not ball-ended (its ball column is NaN).

    Returns
    -------
    ndarray, shape (N, 3)
        Tip mm, ball centre mm, tool axis deg; NaN where a row or the block's start has no CL
        index (row 0: the row alone).
    """
    values, _ = program_joints(machine, program)
    n = len(values)
    out = np.full((n, 3), np.nan)
    if n == 0 or len(cl) < 2:
        return out
    ends = row_poses_at_tip(machine, values, program.tcp, tool_length)
    mids = row_poses_at_tip(machine, 0.5 * (values[1:] + values[:-1]), program.tcp, tool_length)
    lo = np.concatenate([cl_index[:1], np.fmin(cl_index[1:], cl_index[:-1])])
    hi = np.concatenate([cl_index[:1], np.fmax(cl_index[1:], cl_index[:-1])])
    has = np.isfinite(lo) & np.isfinite(hi)
    has[1:] &= np.isfinite(cl_index[:-1]) & np.isfinite(cl_index[1:])
    k = np.flatnonzero(has)
    if k.size == 0:
        return out
    first = np.clip(np.floor(lo[k]).astype(int), 0, len(cl) - 2)
    last = np.clip(np.ceil(hi[k]).astype(int), first + 1, len(cl) - 1)
    # tip and ball centre; the axis where the cut is decided (the ball centre of a ball tool)
    for col, at in ((0, 0.0), (1, ball_radius)):
        if col == 1 and ball_radius <= 0:
            continue
        tip_dev, axis_dev = _sample_deviation(cl, at, ends, k, first, last)
        sel = k > 0
        if sel.any():
            mid_tip, mid_axis = _sample_deviation(cl, at, mids, k[sel] - 1, first[sel], last[sel])
            tip_dev[sel] = np.fmax(tip_dev[sel], mid_tip)
            axis_dev[sel] = np.fmax(axis_dev[sel], mid_axis)
        out[k, col] = tip_dev
        if at == ball_radius:
            out[k, 2] = axis_dev
    return out


_MAX_SEGMENTS = 16
"""CL segments a block is compared with at most (from its first; a block spanning more is a
post's own move, an approach or a rewind)."""


def _sample_deviation(
    cl: Toolpath,
    pivot: float,
    poses: RowPoses,
    rows: np.ndarray,
    first: np.ndarray,
    last: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Distance (mm) of sampled points ``pivot`` up the axis to CL segments ``first`` ..
    ``last``, and the tool-axis angle (deg) to the CL axis at the nearest place."""
    at = at_pivot(poses, pivot)
    p, v = at.tip[rows], at.axis[rows]
    a_pts = cl.tip + pivot * cl.axis
    count = np.minimum(last - first, _MAX_SEGMENTS)
    best = np.full(len(rows), np.inf)
    best_axis = np.zeros(len(rows))
    for off in range(int(count.max(initial=0))):
        live = off < count
        j = np.where(live, first + off, first)
        a, b = a_pts[j], a_pts[j + 1]
        ab = b - a
        denom = np.einsum("ij,ij->i", ab, ab)
        with np.errstate(invalid="ignore", divide="ignore"):
            t = np.where(denom > 0, np.einsum("ij,ij->i", p - a, ab) / denom, 0.0)
        t = np.clip(t, 0.0, 1.0)
        d = np.linalg.norm(p - (a + t[:, None] * ab), axis=1)
        axis = slerp(cl.axis[j], cl.axis[j + 1], t)
        ang = np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", axis, v), -1.0, 1.0)))
        better = live & (d < best)
        best = np.where(better, d, best)
        best_axis = np.where(better, ang, best_axis)
    return best, best_axis


def table(comparison: Comparison, units: str = "mm") -> str:
    """The comparison as a fixed-width text table (one row per strategy).

    Columns: verified (the one acceptance rule), planner, blocks, added blocks, turns in
    place, largest step of the first rotary axis, the peak speed the feed alone demands of it
    (turns in place left out: they are counted), its peak acceleration and jerk on the timed
    trajectory, the timed machining time, the velocity-only estimate, the feed ratio (mean tip
    speed over programmed feed), the time in singular spans, tip, ball-centre and orientation
    deviation from the CL data, smallest conditioning, lifts.
    """
    scale = mm_per_unit(units)
    first = None
    for o in comparison.outcomes:
        if o.metrics and o.metrics.max_step_deg:
            first = next(iter(o.metrics.max_step_deg))
            break
    a = first or "-"
    head = (
        f"{'strategy':<12} {'ok':>3} {'planner':>7} {'blocks':>6} {'added':>5} {'turns':>5} "
        f"{'max ' + a + ' step':>10} {a + ' demand':>9} {a + ' acc':>9} {a + ' jerk':>9} "
        f"{'time s':>7} {'v-only s':>8} {'feed':>5} {'sing s':>6} {'tip dev':>8} "
        f"{'ball dev':>8} {'axis dev':>8} {'min sig':>7} {'lifts':>5}"
    )
    acc = comparison.acceptance
    rule = ""
    if acc:
        at = (
            f"ball centre (r {acc['ball_radius'] / scale:g} {units})"
            if acc["ball_radius"]
            else "tip"
        )
        rule = (
            f"; accepted: own path within tip {acc['tip'] / scale:g} {units} and axis "
            f"{acc['axis']:g} deg, CL data within axis {acc['axis'] + acc['angle']:g} deg at "
            f"the {at}"
        )
    lines = [
        f"{comparison.source} on {comparison.machine} ({comparison.controller}, "
        f"{'TCP' if comparison.tcp else 'machine coordinates'}); {len(comparison.spans)} singular "
        f"spans; angles deg, rates deg/s (acc deg/s^2, jerk deg/s^3), deviations {units} and "
        f"deg{rule}",
        head,
        "-" * len(head),
    ]

    def g(d: dict[str, float], k: str | None) -> float:
        return float(d.get(k, float("nan"))) if k else float("nan")

    def opt(value: float | None, fmt: str) -> str:
        return format(value, fmt) if value is not None else "-"

    for o in comparison.outcomes:
        m = o.metrics
        if m is None:
            lines.append(f"{o.strategy:<12} {'no':>3} {o.planner:>7}  failed: {o.error}")
            continue
        ball = None if m.max_ball_deviation is None else m.max_ball_deviation / scale
        lines.append(
            f"{o.strategy:<12} {'yes' if o.verified else 'NO':>3} {o.planner:>7} "
            f"{m.blocks:>6d} {m.added_blocks:>5d} {m.turns_in_place:>5d} "
            f"{g(m.max_step_deg, first):>10.2f} {g(m.peak_demand_velocity, first):>9.1f} "
            f"{g(m.peak_acceleration, first):>9.3g} {g(m.peak_jerk, first):>9.3g} "
            f"{m.time_s:>7.2f} {m.velocity_only_time_s:>8.2f} {m.feed_ratio:>5.2f} "
            f"{opt(o.singular_time_s, '6.2f'):>6} {m.max_tip_deviation / scale:>8.4f} "
            f"{opt(ball, '8.4f'):>8} {m.max_orientation_deviation_deg:>8.3f} "
            f"{m.min_sigma:>7.4f} {m.lifts:>5d}"
        )
    return "\n".join(lines)


#: Columns of :func:`per_block_csv` before the per-axis ones.
CSV_HEAD = ("strategy", "verified", "block", "cl_index", "rapid", "t_s", "t_velocity_only_s")
#: Columns after them.
CSV_TAIL = ("tip_speed_mm_s", "feed_mm_s", "tip_dev_mm", "ball_dev_mm", "axis_dev_deg")


def per_block_csv(comparison: Comparison) -> str:
    """One CSV row per program row (block end) per strategy with a program.

    Columns: :data:`CSV_HEAD`; per axis ``q_<A>``, ``v_<A>``, ``a_<A>``, ``j_<A>`` (position,
    velocity, acceleration and jerk on the timed trajectory) and ``demand_<A>`` (the speed
    the feed alone demands over the block; ``inf`` for a turn in place); then
    :data:`CSV_TAIL`. Degrees for rotary axes, mm for linear ones, seconds; lengths in mm
    whatever the program units. ``block`` counts the program's motion rows from 0 (row 0 ends
    no block); ``cl_index`` is :attr:`Outcome.cl_index` (empty before the first CL point and
    after the last); the deviations are :func:`block_deviation` (empty where not defined).

    Returns
    -------
    str
        CSV text with a header row (``\\n`` line ends, deterministic).
    """
    import csv
    import io

    axes: tuple[str, ...] = ()
    for o in comparison.outcomes:
        if o.metrics is not None and o.metrics.profile is not None:
            axes = o.metrics.profile.axes
            break
    header = list(CSV_HEAD)
    for a in axes:
        header += [f"q_{a}", f"v_{a}", f"a_{a}", f"j_{a}", f"demand_{a}"]
    header += list(CSV_TAIL)
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(header)

    def num(x: float) -> str:
        if np.isnan(x):
            return ""
        return "inf" if np.isinf(x) else f"{x:.9g}"

    for o in comparison.outcomes:
        m = o.metrics
        if m is None or m.profile is None:
            continue
        p = m.profile
        n = len(p.s)
        ci = o.cl_index if o.cl_index is not None else np.full(n, np.nan)
        dev = o.deviation if o.deviation is not None else np.full((n, 3), np.nan)
        for k in range(n):
            row = [o.strategy, int(o.verified), k, num(ci[k]), int(p.rapid[k])]
            row += [num(p.t[k]), num(p.t_velocity_only[k])]
            for j in range(len(axes)):
                row += [
                    num(p.q[k, j]),
                    num(p.velocity[k, j]),
                    num(p.acceleration[k, j]),
                    num(p.jerk[k, j]),
                    num(p.demand[k, j]),
                ]
            row += [num(p.tip_speed[k]), num(p.feed[k]), *(num(d) for d in dev[k])]
            writer.writerow(row)
    return buf.getvalue()
