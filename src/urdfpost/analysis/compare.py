"""Strategies side by side: the same CL data, machine and control, the same metrics.

Every strategy is posted as ``urdfpost post`` would post it (program text written in the
dialect and read back), checked the same way, and measured by
:func:`urdfpost.analysis.metrics.measure`. A strategy whose program misses its tolerance is
still measured: the comparison shows how far it misses.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from urdfpost.analysis.metrics import Metrics, cl_path_position, measure
from urdfpost.errors import UnreachableError, UrdfpostError
from urdfpost.machine import Machine
from urdfpost.planning.singularity import Span
from urdfpost.planning.strategies import STRATEGIES
from urdfpost.posting.check import bent_tolerances
from urdfpost.posting.options import PostOptions, resolve
from urdfpost.posting.piece import post_piece
from urdfpost.posting.whole import travel_hint, written
from urdfpost.toolpath import Toolpath
from urdfpost.units import mm_per_unit

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
    bent : bool
        Whether the strategy moved the tool axis off the programmed one.
    """

    strategy: str
    metrics: Metrics | None
    verified: bool
    error: str | None
    bent: bool

    def as_dict(self) -> dict[str, Any]:
        """Plain data for JSON."""
        return {
            "strategy": self.strategy,
            "verified": self.verified,
            "error": self.error,
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
        Singular spans of the CL data (indices into the CL points as read).
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

    def as_dict(self) -> dict[str, Any]:
        """Plain data for JSON."""
        return {
            "machine": self.machine,
            "cl": self.source,
            "tcp": self.tcp,
            "controller": self.controller,
            "spans": [s.as_dict() for s in self.spans],
            "strategies": [o.as_dict() for o in self.outcomes],
        }


def _to_cl_indices(spans: Sequence[Span], toolpath: Toolpath) -> list[Span]:
    """Spans found on a toolpath with inserted points, re-indexed by CL source line."""
    lines = toolpath.line
    out = []
    for sp in spans:
        a = int(np.searchsorted(lines, sp.first_line, side="left"))
        b = int(np.searchsorted(lines, sp.last_line, side="right")) - 1
        out.append(replace(sp, first=min(a, len(lines) - 1), last=max(min(b, len(lines) - 1), a)))
    return out


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
            posted = post_piece(toolpath, job)
        except UrdfpostError as e:
            log.info("strategy %s: %s", name, e)
            hint = travel_hint(toolpath, job) if isinstance(e, UnreachableError) else ""
            outcomes.append(Outcome(name, None, False, f"{e}{hint}", False))
            continue
        plan = posted.plan
        if spans is None or name == "recursive":
            spans = _to_cl_indices(plan.spans, plan.toolpath)
        _, readback, (cl, intended) = written(posted, job)
        target, measure_tol = posted.target, job.tol
        if plan.bent:
            measure_tol = bent_tolerances(job.tol, target.angle_tolerance_deg, target.pivot_mm)
        metrics = measure(
            readback,
            machine,
            toolpath,
            tool_length=posted.program.tool_length,
            tol=measure_tol,
            pivot=target.pivot_mm if plan.bent else 0.0,
            lifts=plan.lifts,
        )
        ok = cl.ok and (intended is None or intended.ok)
        error = None
        if not ok:
            bad = intended if intended is not None and not intended.ok else cl
            error = bad.summary(job.units)
        outcomes.append(Outcome(name, metrics, bool(ok), error, bool(plan.bent)))
    return Comparison(
        machine=machine.name,
        source=toolpath.source,
        tcp=options.tcp,
        controller=job.dialect.name,
        outcomes=outcomes,
        spans=spans or [],
        cl_s=cl_path_position(toolpath),
    )


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
