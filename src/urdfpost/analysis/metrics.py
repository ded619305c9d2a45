"""One set of figures for every strategy: how a program moves the machine and how well it cuts.

:func:`measure` takes a program (as built, or as read back from the dialect text), the machine
and the original CL data, and returns :class:`Metrics` (``../shared/docs/singularity-research.md``
section 6, option 1):

Timing
    Block ``k`` joins program points ``k - 1`` and ``k``. It lasts
    ``T_k = max(L_k / F_k, max_j |dq_jk| / vmax_j)``: ``L_k`` is the straight distance between
    the programmed tool tips of its ends (the X Y Z words of a TCP program; forward kinematics of
    the axis values otherwise), ``F_k`` its feed (the program's feeds are mm/min whatever its
    units, see :class:`~urdfpost.program.Move`) and ``vmax_j`` each axis' velocity limit from the
    URDF (``inf`` when none is given). A rapid lasts ``max_j |dq_jk| / vmax_j``: the machine's
    rapid traverse is taken as every axis at its limit, there is no separate rapid rate.

Axis kinematics
    Figures are for the machine's axes: for a TCP program the linear axes are solved from the
    tool tip and the rotary angles (what the control does at the block ends). Per feed block the
    velocity is ``dq_k / T_k`` (at the middle of the block); the acceleration at the junction of
    blocks ``k - 1`` and ``k`` is ``(v_k - v_{k-1}) / ((T_{k-1} + T_k) / 2)``, and the jerk over
    block ``k`` is ``(a_{k+1} - a_k) / T_k``. Differences are taken within a feed run only (a
    rapid, or the program start, separates runs) and skip blocks that take no time. The
    *demanded* velocity ``|dq_k| / (L_k / F_k)`` is what the feed alone would ask of an axis
    (the closed-form ``F / y0`` of the hemisphere raster); it is not defined for blocks that do
    not move the tip (less than :data:`STILL`).

Accuracy and conditioning
    Tool-tip and tool-axis deviation come from :func:`urdfpost.verification.verify` (between
    blocks, as the control interpolates); the conditioning of the orientation Jacobian
    (:func:`urdfpost.planning.singularity.conditioning`) is taken at every end of a feed block.

Angles are reported in degrees and lengths in mm, whatever the program units.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from urdfpost.kinematics.forward import tip_and_axis
from urdfpost.kinematics.inverse import solve_linear
from urdfpost.machine import Machine
from urdfpost.planning.singularity import conditioning
from urdfpost.program import Program
from urdfpost.strict_json import json_ready
from urdfpost.tolerances import Tolerances
from urdfpost.toolpath import Toolpath
from urdfpost.verification import program_joints, verify

log = logging.getLogger(__name__)

__all__ = ["Metrics", "Profile", "block_times", "cl_path_position", "measure"]

#: mm. A block whose tool tip moves less than this turns in place (demanded speed infinite):
#: forward kinematics of a turn about the tip leaves ~1e-13 mm of noise, while the shortest
#: block a post writes is at its output resolution (0.001 mm, 0.0001 in).
STILL = 1e-6


@dataclass(frozen=True, eq=False)
class Profile:
    """The program as a time-parameterised trajectory, one row per motion block (for plots).

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
        Time at each point, rapids included.
    q : ndarray, shape (N, m), deg / mm
        Machine axis positions (for TCP programs the linear axes the control drives).
    velocity : ndarray, shape (N, m), deg/s / mm/s
        Velocity over the block ending at the row, with the axis limits (0 at row 0 and for
        blocks that take no time).
    demand : ndarray, shape (N, m), deg/s / mm/s
        Speed ``|dq| / (L / F)`` the feed alone would demand over the block: ``inf`` where a
        feed block moves the axis without moving the tool tip, NaN for rapids.
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
    peak_velocity, p95_velocity, peak_acceleration, peak_jerk : dict of str to float
        Of ``|q'|``, ``|q''|``, ``|q'''|`` per axis at the programmed feed within the axis
        velocity limits (``inf`` where a block turns an axis with no limit in no time).
    peak_demand_velocity : dict of str to float
        Largest ``|dq| / (L / F)`` per axis over the feed blocks that move the tool tip: what
        the feed alone would demand (turns in place are counted in ``turns_in_place``).
    velocity_limit : dict of str to float
        Each axis' limit (``inf`` when the URDF gives none).
    time_s : float
        Estimated time of the feed blocks.
    rapid_time_s : float
        Estimated time of the rapid blocks (every axis at its limit).
    nominal_time_s : float
        Sum of ``L / F`` over the feed blocks.
    slowdown : float
        ``time_s / nominal_time_s`` (1 when nothing is slowed down, or there is no feed motion).
    velocity_limited_blocks : int
        Feed blocks whose duration an axis velocity limit set rather than the feed.
    turns_in_place : int
        Feed blocks that move an axis without moving the tool tip.
    max_tip_deviation : float, mm
    max_orientation_deviation_deg : float
    cl_points_reached : int
    verified : bool
        Verification found every CL point reached and the deviations within tolerance.
    min_sigma : float
        Smallest singular value of the orientation Jacobian at the feed block ends.
    max_kappa : float
        Largest condition number there.
    lifts : int
        Retracts a strategy added (given by the caller).
    notes : tuple of str
        What the figures could not take into account (feed blocks with no feed, ...).
    profile : Profile or None
        The trajectory, for plots; not part of :meth:`as_dict`.
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
    p95_velocity: dict[str, float]
    peak_acceleration: dict[str, float]
    peak_jerk: dict[str, float]
    peak_demand_velocity: dict[str, float]
    velocity_limit: dict[str, float]
    time_s: float
    rapid_time_s: float
    nominal_time_s: float
    slowdown: float
    velocity_limited_blocks: int
    turns_in_place: int
    max_tip_deviation: float
    max_orientation_deviation_deg: float
    cl_points_reached: int
    verified: bool
    min_sigma: float
    max_kappa: float
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


def _derivatives(
    velocity: np.ndarray, time: np.ndarray, run: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Junction accelerations and block jerks within runs (see the module docstring).

    Parameters
    ----------
    velocity : ndarray, shape (k, m)
        Per block, in time order; only blocks with ``time > 0`` are passed.
    time : ndarray, shape (k,), s
    run : ndarray, shape (k,), int
        Feed-run id of each block.

    Returns
    -------
    acceleration : ndarray, shape (a, m)
    jerk : ndarray, shape (j, m)
    """
    m = velocity.shape[1]
    if len(velocity) < 2:
        return np.zeros((0, m)), np.zeros((0, m))
    same = run[1:] == run[:-1]
    # acc[i]: at the junction of blocks i and i + 1, half a block from either middle
    acc = (velocity[1:] - velocity[:-1]) / ((time[1:] + time[:-1]) / 2.0)[:, None]
    # jerk[i]: over block i + 1, between the junctions at its two ends
    jerk = (acc[1:] - acc[:-1]) / time[1:-1, None]
    return acc[same], jerk[same[:-1] & same[1:]]


def measure(
    program: Program,
    machine: Machine,
    toolpath: Toolpath,
    *,
    tool_length: float | None = None,
    tol: Tolerances | None = None,
    pivot: float = 0.0,
    lifts: int = 0,
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
        Passed to :func:`~urdfpost.verification.verify`: deviations are measured this far up
        the tool axis (the ball centre for a strategy that bends the axis about it).
    lifts : int
        Retracts the strategy added, reported as is.

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
    check = verify(program, machine, toolpath, tool_length=tool_length, tol=tol, pivot=pivot)
    values, rapid = program_joints(machine, program)
    moves = program.moves()
    # the strategy's path only: not the post's own approach before the first CL point and
    # end after the last (moves with no CL line there); a program read back from text has no
    # CL lines and is measured whole
    on_cl = np.flatnonzero([mv.cl_line is not None for mv in moves])
    if on_cl.size:
        first, last = int(on_cl[0]), int(on_cl[-1]) + 1
        values, rapid, moves = values[first:last], rapid[first:last], moves[first:last]
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
    limit = np.array([a.velocity for a in machine.axes], dtype=float)

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
    feed = np.where(rapid | np.isnan(feed), np.inf, feed)

    dq = np.diff(q, axis=0)
    length = np.linalg.norm(np.diff(tip, axis=0), axis=1)
    length = np.where(length < STILL, 0.0, length)
    blk_feed = feed[1:]
    blk_rapid = rapid[1:]
    time, limited = block_times(dq, length, blk_feed, limit)
    with np.errstate(divide="ignore", invalid="ignore"):
        velocity = np.where(time[:, None] > 0, dq / time[:, None], 0.0)
        velocity = np.where((time[:, None] == 0) & (dq != 0), np.inf * np.sign(dq), velocity)
        nominal = np.where(blk_rapid | ~np.isfinite(blk_feed), 0.0, length / blk_feed)
        demand = np.where((~blk_rapid & (nominal > 0))[:, None], np.abs(dq) / nominal[:, None], 0.0)
        demand = np.where((~blk_rapid & (nominal == 0))[:, None] & (dq != 0), np.inf, demand)
        demand = np.where(blk_rapid[:, None], np.nan, demand)
    is_feed = ~blk_rapid
    moving = is_feed & (time > 0)
    run = np.cumsum(blk_rapid)  # feed blocks between two rapids share an id
    acc, jerk = _derivatives(velocity[moving], time[moving], run[moving])

    scale = np.where([a.rotary for a in machine.axes], 180.0 / math.pi, 1.0)
    fv = np.abs(velocity[is_feed]) * scale
    acc, jerk = np.abs(acc) * scale, np.abs(jerk) * scale

    def per_axis(a: np.ndarray, reduce: str) -> dict[str, float]:
        out = {}
        for j, name in enumerate(names):
            col = a[:, j][~np.isnan(a[:, j])]
            if col.size == 0:
                out[name] = 0.0
            else:
                out[name] = float(col.max() if reduce == "max" else np.percentile(col, 95))
        return out

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

    feed_time = float(time[is_feed].sum())
    nominal_time = float(nominal[is_feed].sum())
    slowdown = feed_time / nominal_time if nominal_time > 0 else 1.0
    turns = int(np.sum(is_feed & (length == 0) & (np.abs(dq).max(axis=1, initial=0.0) > 0)))

    s = np.concatenate([[0.0], np.cumsum(length)]) if n else np.zeros(0)
    t = np.concatenate([[0.0], np.cumsum(time)]) if n else np.zeros(0)
    zero_row = np.zeros((min(n, 1), len(names)))
    profile = Profile(
        axes=names,
        rotary=rotary_names,
        s=s,
        t=t,
        q=q * scale,
        velocity=np.concatenate([zero_row, velocity * scale]),
        demand=np.concatenate([np.full_like(zero_row, np.nan), demand * scale]),
        rapid=np.concatenate([[True], blk_rapid]) if n else np.zeros(0, dtype=bool),
        limit=limit * scale,
    )
    log.debug(
        "metrics of %s on %s: %d blocks, time %.3f s (nominal %.3f s)",
        program.name,
        machine.name,
        n,
        feed_time,
        nominal_time,
    )
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
        peak_velocity=per_axis(fv, "max"),
        p95_velocity=per_axis(fv, "p95"),
        peak_acceleration=per_axis(acc, "max"),
        peak_jerk=per_axis(jerk, "max"),
        peak_demand_velocity=per_axis(demand_deg, "max"),
        velocity_limit={a: float(v) for a, v in zip(names, limit * scale, strict=True)},
        time_s=feed_time,
        rapid_time_s=float(time[blk_rapid].sum()),
        nominal_time_s=nominal_time,
        slowdown=float(slowdown),
        velocity_limited_blocks=int(np.sum(limited & is_feed)),
        turns_in_place=turns,
        max_tip_deviation=check.max_tip_deviation,
        max_orientation_deviation_deg=check.max_orientation_deviation_deg,
        cl_points_reached=check.reached,
        verified=check.ok,
        min_sigma=min_sigma,
        max_kappa=max_kappa,
        lifts=int(lifts),
        notes=tuple(notes + check.notes),
        profile=profile,
    )
