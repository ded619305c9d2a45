"""The figures of a post, typed: what a piece found on the way, and the report of a whole job.

Every number a post reports travels in one of these dataclasses, from the stage that finds it
to :meth:`Report.as_json`, the one place that turns them into plain data for JSON (lengths in
program units, angles in degrees). Internal state (the plan, the joint rows, the collision
world) never travels in them: it is a field of :class:`urdfpost.posting.piece.PostedPiece`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass, field, replace
from typing import Any

import numpy as np

from urdfpost.planning.singularity import Span
from urdfpost.units import mm_per_unit
from urdfpost.verification import Verification


@dataclass(frozen=True)
class Rewind:
    """One rewind of a program: where, how far the rotary axes turned, how high it lifted.

    Attributes
    ----------
    cl_line : int
        CL line the rewind happens at.
    rotary_deg : dict of str to [float, float]
        Angle of each rotary axis before and after, degrees.
    retract_mm : float
        Lift along the tool axis, mm.
    comment : str
        The comment written into the program before the rewind.
    """

    cl_line: int
    rotary_deg: dict[str, list[float]]
    retract_mm: float
    comment: str

    def as_json(self) -> dict[str, Any]:
        """Plain data for JSON."""
        return asdict(self)


@dataclass(frozen=True)
class StrategyFigures:
    """What the singularity strategy of a post did.

    Attributes
    ----------
    name : str
        The strategy (:data:`urdfpost.planning.strategies.STRATEGIES`).
    angle_tolerance_deg : float
        How far it may bend the tool axis, degrees.
    pivot_mm : float
        Ball radius of the cutter (the point a bent axis turns about), mm.
    bent : bool
        It bent the tool axis somewhere.
    lifts : int
        Spans where it lifted the tool off the path.
    spans : list of Span
        The singular spans, indexed along the plan's path.
    intended_path_check : Verification or None
        The program checked against the path the strategy intended (where it bent or moved
        the path).
    """

    name: str
    angle_tolerance_deg: float
    pivot_mm: float
    bent: bool
    lifts: int
    spans: tuple[Span, ...]
    intended_path_check: Verification | None = None

    def as_json(self) -> dict[str, Any]:
        """Plain data for JSON."""
        out: dict[str, Any] = {
            "name": self.name,
            "angle_tolerance_deg": self.angle_tolerance_deg,
            "pivot_mm": self.pivot_mm,
            "bent": self.bent,
            "lifts": self.lifts,
            "spans": [sp.as_dict() for sp in self.spans],
        }
        if self.intended_path_check is not None:
            out["intended_path_check"] = self.intended_path_check.as_dict()
        return out


@dataclass(frozen=True)
class FeedFigures:
    """How the post programmed the feeds (:mod:`urdfpost.posting.feeds`).

    Attributes
    ----------
    mode : str
        The job's feed mode: "tip", "inverse-time" or "per-block".
    feed_blocks : int
        Feed blocks timed.
    capped_blocks : int
        Blocks whose F was reduced so that no axis exceeds its velocity limit (or, in
        inverse time, so that F stays within the control's range).
    worst_cl_line : int or None
        CL line of the block reduced most.
    worst_share : float or None
        The share of the CL tip feed that block keeps (0.25: a quarter).
    capped_by : dict of str to int
        Blocks capped per axis (or "F range").
    feed_minutes, rapid_minutes : float
        How long the program's feed moves (at the F written, along arcs; a turn in place
        under TCP at its axes' velocity limits) and its rapids (at the axes' velocity limits)
        take, minutes: the motion of canned cycles included; acceleration, tool changes and
        the retracts between sections not.
    dwell_seconds : float
        The program's dwells (canned cycles' included), s.
    """

    mode: str
    feed_blocks: int = 0
    capped_blocks: int = 0
    worst_cl_line: int | None = None
    worst_share: float | None = None
    capped_by: dict[str, int] = field(default_factory=dict)
    feed_minutes: float = 0.0
    rapid_minutes: float = 0.0
    dwell_seconds: float = 0.0

    def joined(self, other: FeedFigures) -> FeedFigures:
        """These figures and those of the next piece, added up."""
        worst = self
        if other.worst_share is not None and (
            self.worst_share is None or other.worst_share < self.worst_share
        ):
            worst = other
        by = dict(self.capped_by)
        for name, count in other.capped_by.items():
            by[name] = by.get(name, 0) + count
        return FeedFigures(
            mode=self.mode,
            feed_blocks=self.feed_blocks + other.feed_blocks,
            capped_blocks=self.capped_blocks + other.capped_blocks,
            worst_cl_line=worst.worst_cl_line,
            worst_share=worst.worst_share,
            capped_by=dict(sorted(by.items())),
            feed_minutes=self.feed_minutes + other.feed_minutes,
            rapid_minutes=self.rapid_minutes + other.rapid_minutes,
            dwell_seconds=self.dwell_seconds + other.dwell_seconds,
        )

    def header_line(self) -> str:
        """The program header's line of :meth:`duration` (no apostrophe: ISO 840 comments)."""
        return self._run_time("feed", "rapid", "dwell") + "; without acceleration and tool changes"

    def duration(self) -> str:
        """How long the program runs, in words (:attr:`feed_minutes` and the others)."""
        return self._run_time("feed moves", "rapids", "dwells") + (
            " (at the F written and the axes' velocity limits; acceleration and tool changes "
            "not counted)"
        )

    def _run_time(self, feed: str, rapid: str, dwell: str) -> str:
        """ "run time about T: ``feed`` F, ``rapid`` R, ``dwell`` D s"."""
        total = self.feed_minutes + self.rapid_minutes + self.dwell_seconds / 60.0
        return (
            f"run time about {_minutes(total)}: {feed} {_minutes(self.feed_minutes)}, {rapid} "
            f"{_minutes(self.rapid_minutes)}, {dwell} {self.dwell_seconds:.1f} s"
        )

    def warning(self, source: str) -> str | None:
        """The warning of a post that reduced feeds (None when it reduced none)."""
        if not self.capped_blocks or self.worst_share is None:
            return None
        axes = ", ".join(f"{n} {c}" for n, c in self.capped_by.items() if n != "F range")
        why = [f"axis velocity limits: {axes}"] if axes else []
        if "F range" in self.capped_by:
            why.append(f"the control's largest inverse-time F: {self.capped_by['F range']}")
        line = f" at CL line {self.worst_cl_line}" if self.worst_cl_line is not None else ""
        return (
            f"{source}: feed reduced on {self.capped_blocks} blocks ({'; '.join(why)}), "
            f"worst{line} (to {100.0 * self.worst_share:.1f}% of programmed)"
        )

    def as_json(self) -> dict[str, Any]:
        """Plain data for JSON (the worst share in percent)."""
        out = asdict(self)
        share = out.pop("worst_share")
        out["worst_percent_of_programmed"] = None if share is None else 100.0 * share
        return out


def _minutes(minutes: float) -> str:
    """A time in minutes as "1 h 02 min 03 s", "12 min 03 s" or "4.2 s"."""
    seconds = minutes * 60.0
    if seconds < 60.0:
        return f"{seconds:.1f} s"
    whole = round(seconds)
    h, rest = divmod(whole, 3600)
    m, sec = divmod(rest, 60)
    return f"{h} h {m:02d} min {sec:02d} s" if h else f"{m} min {sec:02d} s"


@dataclass(frozen=True)
class PieceFigures:
    """Counts a post gathers on the way from the plan to the program (one piece, or a whole
    job once the pieces are added up with :meth:`joined`).

    Attributes
    ----------
    branch_switches : int
        Steps of the last rotary axis over 90 degrees.
    pole_points : int
        CL points with the tool axis at a pole of the first rotary axis.
    inserted_blocks : int
        Blocks the subdivision inserted to hold the tolerance.
    rewinds : tuple of Rewind
    pole_turns : int
        Turns in place at a pole.
    strategy : StrategyFigures
    warnings : tuple of str
        The post's warnings (the readers' are the toolpath's).
    feeds : FeedFigures or None
        How the feeds were programmed (None: a post that did not time them).
    arcs : int
        CL arcs written as arcs (:mod:`urdfpost.posting.arcs`).
    arcs_linear : int
        CL arcs written as lines (a warning says why).
    planes : int
        Operations at a fixed tilt written in a tilted working plane
        (:mod:`urdfpost.posting.planes`).
    """

    branch_switches: int
    pole_points: int
    inserted_blocks: int
    rewinds: tuple[Rewind, ...]
    pole_turns: int
    strategy: StrategyFigures
    warnings: tuple[str, ...] = ()
    feeds: FeedFigures | None = None
    arcs: int = 0
    arcs_linear: int = 0
    planes: int = 0

    def joined(self, other: PieceFigures, offset: int) -> PieceFigures:
        """These figures and those of the piece after, added up.

        Parameters
        ----------
        other : PieceFigures
            Of the next piece.
        offset : int
            Index of the next piece's first point along the pieces' plan paths joined (each
            join counted once): its spans are re-indexed by it.
        """
        s, o = self.strategy, other.strategy
        spans = tuple(replace(sp, first=sp.first + offset, last=sp.last + offset) for sp in o.spans)
        strategy = replace(s, bent=bool(s.bent or o.bent), lifts=s.lifts + o.lifts)
        return PieceFigures(
            branch_switches=self.branch_switches + other.branch_switches,
            pole_points=self.pole_points + other.pole_points,
            inserted_blocks=self.inserted_blocks + other.inserted_blocks,
            rewinds=self.rewinds + other.rewinds,
            pole_turns=self.pole_turns + other.pole_turns,
            strategy=replace(strategy, spans=s.spans + spans),
            warnings=self.warnings + tuple(w for w in other.warnings if w not in self.warnings),
            feeds=other.feeds
            if self.feeds is None
            else (self.feeds if other.feeds is None else self.feeds.joined(other.feeds)),
            arcs=self.arcs + other.arcs,
            arcs_linear=self.arcs_linear + other.arcs_linear,
            planes=self.planes + other.planes,
        )


@dataclass(frozen=True)
class Collisions:
    """The collision check of a program's moves and the clearance at its CL points.

    Attributes
    ----------
    checked : bool
        False when no collision world was built (the other fields are then empty).
    bodies, pairs_checked : int
        Bodies of the world and body pairs that can touch.
    moves, samples : int
        Joint moves checked and the configurations sampled along them.
    min_clearance : float or None
        Smallest clearance of the job's bodies (tool, holder, stock), mm.
    nearest : list of str or None
        The two bodies nearest each other there.
    at_cl_line : int or None
        CL line of the smallest clearance.
    clearance_points : int
        CL points the clearance was measured at.
    """

    checked: bool = False
    bodies: int = 0
    pairs_checked: int = 0
    moves: int = 0
    samples: int = 0
    min_clearance: float | None = None
    nearest: list[str] | None = None
    at_cl_line: int | None = None
    clearance_points: int = 0

    @staticmethod
    def merged(parts: list[Collisions]) -> Collisions:
        """The checks of consecutive pieces as one: the moves and samples added up, the
        smallest clearance of all."""
        checked = [c for c in parts if c.checked]
        if not checked:
            return Collisions()
        least = min(checked, key=lambda c: np.inf if c.min_clearance is None else c.min_clearance)
        return replace(
            least,
            moves=sum(c.moves for c in checked),
            samples=sum(c.samples for c in checked),
            clearance_points=sum(c.clearance_points for c in checked),
        )

    def as_json(self, units: str) -> dict[str, Any]:
        """Plain data for JSON, the clearance in ``units``."""
        if not self.checked:
            return {"checked": False}
        out = asdict(self)
        if self.min_clearance is not None:
            out["min_clearance"] = self.min_clearance / mm_per_unit(units)
        return out


@dataclass(frozen=True)
class StreamFigures:
    """How a streamed post cut the job.

    Attributes
    ----------
    pieces, piece_points, lookahead : int
    worker : bool
        The pieces were verified in a worker process.
    unsettled_joins : list of int
        CL lines of the joins whose branch choice rests on the lookahead.
    """

    pieces: int
    piece_points: int
    lookahead: int
    worker: bool
    unsettled_joins: list[int] = field(default_factory=list)

    def as_json(self) -> dict[str, Any]:
        """Plain data for JSON."""
        return asdict(self)


@dataclass(frozen=True)
class Report:
    """The report of a post (or of ``urdfpost verify``, which has no post figures).

    Attributes
    ----------
    machine, controller : str
    tcp : bool
    units : str
        Program units: the lengths of :meth:`as_json` are in them.
    verification : Verification
        Of the program read back, against the CL data.
    tool_length_mm : float
    warnings : tuple of str
        The readers' warnings and the post's, in order.
    figures : PieceFigures or None
        What the post found on the way (None for a verification of a program file).
    collisions : Collisions
    streamed : StreamFigures or None
        For a post in pieces.
    tool_lengths_mm : mapping of int to float
        A machine-coordinate program: the gauge length each tool's moves were computed with
        (:mod:`urdfpost.posting.tools`), mm; empty for TCP programs.
    """

    machine: str
    controller: str
    tcp: bool
    units: str
    verification: Verification
    tool_length_mm: float
    warnings: tuple[str, ...] = ()
    figures: PieceFigures | None = None
    collisions: Collisions = Collisions()
    streamed: StreamFigures | None = None
    tool_lengths_mm: Mapping[int, float] = field(default_factory=dict)

    @property
    def strategy(self) -> StrategyFigures | None:
        """The strategy figures of the post (None for a verification)."""
        return None if self.figures is None else self.figures.strategy

    @property
    def rewinds(self) -> tuple[Rewind, ...]:
        """The rewinds of the program (none for a verification)."""
        return () if self.figures is None else self.figures.rewinds

    def as_json(self) -> dict[str, Any]:
        """Plain data for JSON: lengths in program units, angles in degrees (non-finite
        figures are turned into null by :func:`urdfpost.strict_json.report_json`)."""
        v, scale = self.verification, mm_per_unit(self.units)
        out: dict[str, Any] = {
            "machine": self.machine,
            "controller": self.controller,
            "tcp": self.tcp,
            "units": self.units,
            "cl_points": v.cl_points,
            "cl_points_reached": v.reached,
            "cl_lines_missed": v.missed_lines,
            "blocks": v.blocks,
            "max_tip_deviation": v.max_tip_deviation / scale,
            "mean_tip_deviation": v.mean_tip_deviation / scale,
            "tip_tolerance": v.tip_tolerance / scale,
            "max_orientation_deviation_deg": v.max_orientation_deviation_deg,
            "orientation_tolerance_deg": v.orientation_tolerance_deg,
            "max_rotary_step_deg": v.max_rotary_step_deg,
            "worst_cl_line": v.worst_cl_line,
            "tool_length_mm": self.tool_length_mm,
            "tool_lengths_mm": {str(k): x for k, x in sorted(self.tool_lengths_mm.items())},
            "verified": v.ok,
        }
        f = self.figures
        if f is not None:
            out |= {
                "branch_switches": f.branch_switches,
                "pole_points": f.pole_points,
                "inserted_blocks": f.inserted_blocks,
                "rewinds": [r.as_json() for r in f.rewinds],
                "pole_turns": f.pole_turns,
                "strategy": f.strategy.as_json(),
                "arcs": f.arcs,
                "arcs_linear": f.arcs_linear,
                "tilted_planes": f.planes,
            }
            if f.feeds is not None:
                out["feeds"] = f.feeds.as_json()
        if v.feeds is not None:
            out["feed_check"] = asdict(v.feeds) | {"ok": v.feeds.ok}
        out["warnings"] = list(self.warnings)
        if f is not None:
            out["collisions"] = self.collisions.as_json(self.units)
        if self.streamed is not None:
            out["streamed"] = self.streamed.as_json()
        return out
