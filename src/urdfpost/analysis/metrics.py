"""One set of figures for every strategy: how a program moves the machine and how well it cuts.

:func:`measure` takes a program (as built, or as read back from the dialect text), the machine
and the original CL data, and returns :class:`Metrics` (``../shared/docs/singularity-research.md``
section 6, option 1):

Timed kinematics
    The program is run as fast as the axes' velocity and acceleration limits and the programmed
    feed (a cap on the tool-tip speed) allow: a time-optimal parameterisation of its joint path
    (TOPP-RA, :mod:`urdfpost.analysis.timing`), then a jerk filter. ``time_s``, the peak
    velocity, acceleration and jerk per axis, the feed ratio (mean tip speed over programmed
    feed) and the share of the path slowed down come from that timed trajectory.

Velocity-only estimate (the former model, kept for comparison)
    Block ``k`` joins program points ``k - 1`` and ``k``. It lasts
    ``T_k = max(L_k / F_k, max_j |dq_jk| / vmax_j)``: ``L_k`` is the straight distance between
    the programmed tool tips of its ends (the X Y Z words of a TCP program; forward kinematics of
    the axis values otherwise), ``F_k`` its feed (the program's feeds are mm/min whatever its
    units, see :class:`~urdfpost.program.Move`) and ``vmax_j`` each axis' velocity limit from the
    URDF (``inf`` when none is given). A rapid lasts ``max_j |dq_jk| / vmax_j``: the machine's
    rapid traverse is taken as every axis at its limit, there is no separate rapid rate; rapids
    are timed this way in both models. The *demanded* velocity ``|dq_k| / (L_k / F_k)``, with
    ``F_k`` the CL feed of the block (the post's F may be lower, where it slowed the block to
    an axis limit), is what the feed alone would ask of an axis (the closed-form ``F / y0`` of
    the hemisphere raster);
    it is not defined for blocks that do not move the tip (less than :data:`STILL`): those are
    the turns in place, counted in ``turns_in_place``.

Accuracy and conditioning
    Tool-tip and tool-axis deviation come from :func:`urdfpost.verification.verify` (between
    blocks, as the control interpolates), at the tip and, for a ball-end tool, at the ball
    centre; the conditioning of the orientation Jacobian
    (:func:`urdfpost.planning.singularity.conditioning`) is taken at every end of a feed block.

Angles are reported in degrees and lengths in mm, whatever the program units.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from urdfpost.analysis.timing import Timing, time_program
from urdfpost.kinematics.forward import tip_and_axis
from urdfpost.kinematics.inverse import solve_linear
from urdfpost.machine import Machine
from urdfpost.machine.load import AxisLimits, axis_limits
from urdfpost.planning.singularity import conditioning
from urdfpost.program import FEED_INVERSE_TIME, Program
from urdfpost.strict_json import json_ready
from urdfpost.tolerances import Tolerances
from urdfpost.toolpath import Toolpath
from urdfpost.verification import Check, program_joints, verify_checks
from urdfpost.verification.feeds import cl_feeds_of_rows, tip_feeds

log = logging.getLogger(__name__)

__all__ = ["Metrics", "Profile", "block_times", "cl_path_position", "measure"]

#: mm. A block whose tool tip moves less than this turns in place (demanded speed infinite):
#: forward kinematics of a turn about the tip leaves ~1e-13 mm of noise, while the shortest
#: block a post writes is at its output resolution (0.001 mm, 0.0001 in).
STILL = 1e-6


@dataclass(frozen=True, eq=False)
class Profile:
    """The program as a trajectory, one row per motion block (for plots and per-block data).

    Row ``k`` describes program point ``k`` and the block that ends there (row 0: the first
    point, no block).

    Attributes
    ----------
    axes : tuple of str
        Machine axis names, the column order of ``q``, ``velocity`` and ``demand``.
    rotary : tuple of str
        Which of ``axes`` are rotary (degrees); the others are mm.
    s : ndarray, shape (N,), mm
        Path position: cumulative straight distance between consecutive programmed tool tips,
        rapids included (comparable with :func:`cl_path_position` of the CL data).
    t : ndarray, shape (N,), s
        Time at each point on the timed trajectory (:mod:`urdfpost.analysis.timing`), rapids
        included.
    q : ndarray, shape (N, m), deg / mm
        Machine axis positions (for TCP programs the linear axes the control drives).
    velocity, acceleration, jerk : ndarray, shape (N, m), deg / mm per s, s^2, s^3
        On the timed trajectory at each point (0 and NaN at rows between rapids).
    tip_speed : ndarray, shape (N,), mm/s
        Tool-tip speed at each point on the timed trajectory.
    feed : ndarray, shape (N,), mm/s
        Programmed feed of the block ending at the row (NaN for rapids).
    t_velocity_only : ndarray, shape (N,), s
        Time at each point in the velocity-only estimate (the module docstring).
    demand : ndarray, shape (N, m), deg/s / mm/s
        Speed ``|dq| / (L / F)`` the feed alone would demand over the block, F the CL feed of
        the block (the program's F may be lower: the post slows a block to an axis limit):
        ``inf`` where a feed block moves the axis without moving the tool tip, NaN for rapids.
    rapid : ndarray, shape (N,), bool
        Whether the block ending at the row is a rapid (row 0: True).
    limit : ndarray, shape (m,), deg/s / mm/s
        Velocity limit of each axis (``inf`` when the URDF gives none).
    """

    axes: tuple[str, ...]
    rotary: tuple[str, ...]
    s: np.ndarray
    t: np.ndarray
    q: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    jerk: np.ndarray
    tip_speed: np.ndarray
    feed: np.ndarray
    t_velocity_only: np.ndarray
    demand: np.ndarray
    rapid: np.ndarray
    limit: np.ndarray

    def column(self, name: str) -> int:
        """Column of axis ``name`` in ``q``, ``velocity`` and ``demand``."""
        return self.axes.index(name)


@dataclass(frozen=True)
class Metrics:
    """Figures of one program (angles degrees, lengths mm, times seconds).

    Per-axis figures are dicts keyed by axis name: degrees (per second, ...) for rotary axes,
    mm (per second, ...) for linear ones. Step and kinematic figures cover feed blocks only.

    Attributes
    ----------
    machine : str
    tcp : bool
    blocks : int
        Motion blocks of the program.
    cl_points : int
        Motion points of the CL data.
    added_blocks : int
        ``max(blocks - cl_points, 0)``.
    max_step_deg, mean_step_deg, travel_deg : dict of str to float
        Largest, mean and summed ``|step|`` of each rotary axis over the feed blocks.
    peak_velocity, peak_acceleration, peak_jerk : dict of str to float
        Largest ``|q'|``, ``|q''|``, ``|q'''|`` per axis on the timed trajectory of the feed
        runs (:mod:`urdfpost.analysis.timing`): within the velocity and acceleration limits at
        TOPP-RA's gridpoints, within the jerk limit by the jerk filter where the acceleration
        is (between gridpoints it may exceed a little: ``jerk_over_limit_s``).
    jerk_over_limit_s : dict of str to float
        Time each axis spends above its jerk limit (0 for an axis without one).
    peak_demand_velocity : dict of str to float
        Largest ``|dq| / (L / F)`` per axis over the feed blocks that move the tool tip, F the
        CL feed: what the feed alone would demand (turns in place are counted in
        ``turns_in_place``).
    velocity_limit, acceleration_limit, jerk_limit : dict of str to float
        Each axis' limits (``inf`` when the machine file gives none).
    time_s : float
        Machining time: the feed runs on the timed trajectory.
    rapid_time_s : float
        Time of the rapid blocks (every axis at its velocity limit).
    nominal_time_s : float
        Sum of ``L / F`` over the feed blocks.
    slowdown : float
        ``time_s / nominal_time_s`` (1 with no feed motion).
    feed_ratio : float
        ``nominal_time_s / time_s``: the mean tip speed as a share of the programmed feed.
    slow_fraction : float
        Share of the tip path run below 95 % of the programmed feed.
    velocity_only_time_s : float
        The feed blocks' time in the velocity-only estimate (no acceleration).
    velocity_limited_blocks : int
        Feed blocks whose duration an axis velocity limit set rather than the feed, in the
        velocity-only estimate.
    turns_in_place : int
        Feed blocks that move an axis without moving the tool tip.
    max_tip_deviation : float, mm
        At the tool tip, whatever the tool.
    max_ball_deviation : float or None, mm
        At the ball centre of a ball-end tool (None for other tools).
    max_orientation_deviation_deg : float
    cl_points_reached : int
    verified : bool
        Verification (at the tolerances and the point the caller gave) found every CL point
        reached and the deviations within tolerance.
    min_sigma : float
        Smallest singular value of the orientation Jacobian at the feed block ends.
    max_kappa : float
        Largest condition number there.
    timing_failed_runs : int
        Feed runs the time-optimal parameterisation could not time (timed by the velocity
        limits only; their acceleration and jerk are not in the peaks).
    lifts : int
        Retracts a strategy added (given by the caller).
    notes : tuple of str
        What the figures could not take into account (feed blocks with no feed, ...).
    profile : Profile or None
        The trajectory, for plots and per-block data; not part of :meth:`as_dict`.
    """

    machine: str
    tcp: bool
    blocks: int
    cl_points: int
    added_blocks: int
    max_step_deg: dict[str, float]
    mean_step_deg: dict[str, float]
    travel_deg: dict[str, float]
    peak_velocity: dict[str, float]
    peak_acceleration: dict[str, float]
    peak_jerk: dict[str, float]
    jerk_over_limit_s: dict[str, float]
    peak_demand_velocity: dict[str, float]
    velocity_limit: dict[str, float]
    acceleration_limit: dict[str, float]
    jerk_limit: dict[str, float]
    time_s: float
    rapid_time_s: float
    nominal_time_s: float
    slowdown: float
    feed_ratio: float
    slow_fraction: float
    velocity_only_time_s: float
    velocity_limited_blocks: int
    turns_in_place: int
    max_tip_deviation: float
    max_ball_deviation: float | None
    max_orientation_deviation_deg: float
    cl_points_reached: int
    verified: bool
    min_sigma: float
    max_kappa: float
    timing_failed_runs: int = 0
    lifts: int = 0
    notes: tuple[str, ...] = ()
    profile: Profile | None = field(default=None, repr=False, compare=False)

    def as_dict(self) -> dict[str, Any]:
        """Plain JSON-ready data (no arrays; ``inf`` and NaN become ``None``)."""
        return {
            name: json_ready(getattr(self, name))
            for name in self.__dataclass_fields__
            if name != "profile"
        }


def cl_path_position(toolpath: Toolpath) -> np.ndarray:
    """Cumulative straight distance between consecutive CL tips (rapids included).

    The same measure as :attr:`Profile.s`, so spans given by CL index can be drawn on a
    program's profile.

    Returns
    -------
    ndarray, shape (n,), mm
    """
    if len(toolpath) == 0:
        return np.zeros(0)
    step = np.linalg.norm(np.diff(toolpath.tip, axis=0), axis=1)
    return np.concatenate([[0.0], np.cumsum(step)])


def block_times(
    dq: np.ndarray, length: np.ndarray, feed: np.ndarray, limit: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Duration of blocks under the feed and the axis velocity limits.

    Parameters
    ----------
    dq : ndarray, shape (k, m), mm / rad
        Axis steps of the blocks.
    length : ndarray, shape (k,), mm
        Tool-tip path length of each block.
    feed : ndarray, shape (k,), mm/s
        Feed of each block; ``inf`` for rapids (time from the axis limits only).
    limit : ndarray, shape (m,), mm/s / rad/s
        Axis velocity limits (``inf`` for none).

    Returns
    -------
    time : ndarray, shape (k,), s
        ``max(L / F, max_j |dq_j| / vmax_j)``.
    limited : ndarray, shape (k,), bool
        Whether an axis limit, not the feed, set the duration.
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        nominal = np.where(length > 0, length / feed, 0.0)
        axis_time = np.nan_to_num(np.abs(dq) / limit, nan=0.0).max(axis=1, initial=0.0)
    return np.maximum(nominal, axis_time), axis_time > nominal


def measure(
    program: Program,
    machine: Machine,
    toolpath: Toolpath,
    *,
    tool_length: float | None = None,
    tol: Tolerances | None = None,
    pivot: float = 0.0,
    ball_radius: float = 0.0,
    lifts: int = 0,
    limits: AxisLimits | None = None,
    axis_feed_rule: str = "combined",
) -> Metrics:
    """Measure a program against its machine and the original CL data.

    Parameters
    ----------
    program : Program
        As built, or as read back from its text.
    machine : Machine
    toolpath : Toolpath
        The original CL data (before any strategy changed it).
    tool_length : float, optional, mm
        Tool length of the program's positions (default: the program's).
    tol : Tolerances, optional
        For verification (default: for the program's units).
    pivot : float, mm
        Where :attr:`Metrics.verified` is decided: this far up the tool axis (the ball centre
        in the acceptance rule of :mod:`urdfpost.analysis.compare`).
    ball_radius : float, mm
        Ball radius of a ball-end tool (0 for other tools): the deviation is also measured at
        the ball centre, this far up the tool axis.
    lifts : int
        Retracts the strategy added, reported as is.
    limits : AxisLimits, optional
        Axis velocity, acceleration and jerk limits (default: the machine file's,
        :func:`urdfpost.machine.load.axis_limits`).
    axis_feed_rule : str
        How the program's control applies a feed per minute without TCP
        (:func:`urdfpost.verification.feeds.tip_feeds`): the blocks are timed by the tip feed
        they give.

    Returns
    -------
    Metrics

    Examples
    --------
    >>> from urdfpost.machine import load_machine
    >>> from urdfpost.posting.options import PostOptions
    >>> from urdfpost.posting.whole import post
    >>> from urdfpost.analysis.testpaths import great_circle_sweep
    >>> tp = great_circle_sweep(5.0)
    >>> dmu50 = load_machine("dmu50")
    >>> m = measure(post(tp, dmu50, PostOptions(strategy="none")).program, dmu50, tp)
    >>> m.blocks == m.cl_points, round(m.max_step_deg["B"], 3)
    (True, 0.444)
    """
    tool_length = program.tool_length if tool_length is None else tool_length
    tol = tol or Tolerances.for_units(program.units)
    limits = axis_limits(machine) if limits is None else limits
    checks = [Check(toolpath, tol, pivot)]
    at_check = {pivot: 0}
    for at in (0.0, ball_radius):
        if at not in at_check:
            at_check[at] = len(checks)
            checks.append(Check(toolpath, tol, at))
    found = verify_checks(program, machine, checks, tool_length)
    check = found[0]
    values, rapid = program_joints(machine, program)
    moves = program.moves()
    given = None  # the tip feed of each move where the F words are no tip feeds
    if not program.tcp or program.feed_mode == FEED_INVERSE_TIME:
        given = tip_feeds(machine, program, tool_length, axis_feed_rule)
    # what the CL feed alone demands of the axes: the post may have slowed a block to an axis
    # limit, its F is then below the CL feed
    asked = cl_feeds_of_rows(machine, program, toolpath, tol, tool_length)
    # the strategy's path only: not the post's own approach before the first CL point and
    # end after the last (moves with no CL line there); a program read back from text has no
    # CL lines and is measured whole
    on_cl = np.flatnonzero([mv.cl_line is not None for mv in moves])
    if on_cl.size:
        first, last = int(on_cl[0]), int(on_cl[-1]) + 1
        values, rapid, moves = values[first:last], rapid[first:last], moves[first:last]
        given = None if given is None else given[first:last]
        asked = asked[first:last]
    n = len(values)
    lin = list(machine.linear_columns)
    rot = list(machine.rotary_columns)
    names = machine.axis_names
    rotary_names = tuple(machine.axis_names[c] for c in rot)
    notes: list[str] = []

    # tool tips (what L measures) and machine axis positions (what the limits apply to)
    if program.tcp:
        tip = values[:, lin].copy()
        q = values.copy()
        if n:
            q[:, lin] = solve_linear(machine, values[:, rot], tip, tool_length)
    else:
        tip, _ = tip_and_axis(machine, values, tool_length) if n else (np.zeros((0, 3)), None)
        q = values
    limit = limits.velocity

    # feeds, mm/s; modal where a feed block has none
    feed = np.full(n, np.nan)
    current = math.nan
    for k, mv in enumerate(moves):
        if mv.feed is not None:
            current = mv.feed
        if not mv.rapid:
            feed[k] = current / 60.0
    missing = ~rapid & np.isnan(feed)
    missing[:1] = False
    if missing.any():
        notes.append(f"{int(missing.sum())} feed blocks have no feed: timed by axis limits only")
    if given is not None:  # (inverse time, machine coordinates: what the block gives)
        feed = np.where(rapid, np.nan, given / 60.0)
    feed = np.where(rapid | np.isnan(feed), np.inf, feed)

    dq = np.diff(q, axis=0)
    length = np.linalg.norm(np.diff(tip, axis=0), axis=1)
    length = np.where(length < STILL, 0.0, length)
    blk_feed = feed[1:]
    blk_rapid = rapid[1:]
    time, limited = block_times(dq, length, blk_feed, limit)
    cl_feed = np.where(np.isfinite(asked[1:]), asked[1:] / 60.0, blk_feed)  # mm/s
    with np.errstate(divide="ignore", invalid="ignore"):
        nominal = np.where(blk_rapid | ~np.isfinite(blk_feed), 0.0, length / blk_feed)
        at_cl = np.where(blk_rapid | ~np.isfinite(cl_feed), 0.0, length / cl_feed)
        demand = np.where((~blk_rapid & (at_cl > 0))[:, None], np.abs(dq) / at_cl[:, None], 0.0)
        demand = np.where((~blk_rapid & (at_cl == 0))[:, None] & (dq != 0), np.inf, demand)
        demand = np.where(blk_rapid[:, None], np.nan, demand)
    is_feed = ~blk_rapid
    scale = np.where([a.rotary for a in machine.axes], 180.0 / math.pi, 1.0)
    timing: Timing = time_program(
        machine,
        values,
        rapid,
        feed,
        limits,
        tcp=program.tcp,
        tool_length=tool_length,
        rapid_time=time,
    )
    if timing.failed_runs:
        notes.append(
            f"{timing.failed_runs} feed runs could not be timed under the acceleration limits: "
            "timed by the velocity limits only"
        )

    def per_axis(a: np.ndarray) -> dict[str, float]:
        return {name: float(v) for name, v in zip(names, a * scale, strict=True)}

    rot_steps = np.degrees(np.abs(dq[is_feed][:, rot]))
    demand_deg = demand[is_feed & (length > 0)] * scale
    feed_ends = np.zeros(n, dtype=bool)
    feed_ends[1:] |= is_feed
    feed_ends[:-1] |= is_feed
    if feed_ends.any():
        sigma, kappa = conditioning(machine, values[feed_ends])
        min_sigma, max_kappa = float(sigma.min()), float(kappa.max())
    else:
        min_sigma, max_kappa = math.nan, math.nan

    velocity_only_time = float(time[is_feed].sum())
    nominal_time = float(nominal[is_feed].sum())
    feed_time = timing.feed_time_s
    slowdown = feed_time / nominal_time if nominal_time > 0 else 1.0
    turns = int(np.sum(is_feed & (length == 0) & (np.abs(dq).max(axis=1, initial=0.0) > 0)))

    s = np.concatenate([[0.0], np.cumsum(length)]) if n else np.zeros(0)
    t_vel = np.concatenate([[0.0], np.cumsum(time)]) if n else np.zeros(0)
    zero_row = np.zeros((min(n, 1), len(names)))
    profile = Profile(
        axes=names,
        rotary=rotary_names,
        s=s,
        t=timing.t,
        q=q * scale,
        velocity=timing.velocity * scale,
        acceleration=timing.acceleration * scale,
        jerk=timing.jerk * scale,
        tip_speed=timing.tip_speed,
        feed=np.where(np.isfinite(feed) & ~rapid, feed, np.nan),
        t_velocity_only=t_vel,
        demand=np.concatenate([np.full_like(zero_row, np.nan), demand * scale]),
        rapid=np.concatenate([[True], blk_rapid]) if n else np.zeros(0, dtype=bool),
        limit=limit * scale,
    )
    log.debug(
        "metrics of %s on %s: %d blocks, time %.3f s (velocity only %.3f s, nominal %.3f s)",
        program.name,
        machine.name,
        n,
        feed_time,
        velocity_only_time,
        nominal_time,
    )
    tip_check = found[at_check[0.0]]
    ball_check = found[at_check[ball_radius]] if ball_radius > 0 else None
    return Metrics(
        machine=machine.name,
        tcp=program.tcp,
        blocks=n,
        cl_points=len(toolpath),
        added_blocks=max(n - len(toolpath), 0),
        max_step_deg={
            a: float(rot_steps[:, i].max(initial=0.0)) for i, a in enumerate(rotary_names)
        },
        mean_step_deg={
            a: float(rot_steps[:, i].mean()) if len(rot_steps) else 0.0
            for i, a in enumerate(rotary_names)
        },
        travel_deg={a: float(rot_steps[:, i].sum()) for i, a in enumerate(rotary_names)},
        peak_velocity=per_axis(timing.peak_velocity),
        peak_acceleration=per_axis(timing.peak_acceleration),
        peak_jerk=per_axis(timing.peak_jerk),
        jerk_over_limit_s={
            name: float(v) for name, v in zip(names, timing.jerk_over_limit_s, strict=True)
        },
        peak_demand_velocity={
            name: float(demand_deg[:, j].max(initial=0.0)) for j, name in enumerate(names)
        },
        velocity_limit=per_axis(limit),
        acceleration_limit=per_axis(limits.acceleration),
        jerk_limit=per_axis(limits.jerk),
        time_s=feed_time,
        rapid_time_s=timing.rapid_time_s,
        nominal_time_s=nominal_time,
        slowdown=float(slowdown),
        feed_ratio=float(timing.feed_ratio),
        slow_fraction=float(timing.slow_fraction),
        velocity_only_time_s=velocity_only_time,
        velocity_limited_blocks=int(np.sum(limited & is_feed)),
        turns_in_place=turns,
        max_tip_deviation=tip_check.max_tip_deviation,
        max_ball_deviation=None if ball_check is None else ball_check.max_tip_deviation,
        max_orientation_deviation_deg=check.max_orientation_deviation_deg,
        cl_points_reached=check.reached,
        verified=check.ok,
        min_sigma=min_sigma,
        max_kappa=max_kappa,
        timing_failed_runs=timing.failed_runs,
        lifts=int(lifts),
        notes=tuple(notes + check.notes),
        profile=profile,
    )
