"""Timed kinematics: the posted joint path run as fast as the axis limits and the feed allow.

:func:`time_program` takes a program's rows (the axis positions the control reaches, the tool
tips, the rapids and the feeds) and returns :class:`Timing`: when the machine reaches each row
and how its axes move on the way, under

- each axis' velocity limit (the URDF ``<limit velocity>``) and acceleration limit (the
  ``<urdfpost><axis_limits acceleration>`` extension, :func:`urdfpost.machine.load.axis_limits`);
- the programmed feed as a cap on the tool-tip speed.

The path
    The rows of one feed run (consecutive feed blocks between rapids; the machine is at rest at
    both ends) are joined as the control joins them: in a TCP program the tool tip and the
    rotary angles linearly, the linear machine axes solved from them; in machine coordinates
    every axis linearly. Knots are put every :data:`KNOT_LENGTH` of tip path and every
    :data:`KNOT_ANGLE` of rotary motion, so the linear axes follow a TCP block's arc. The machine
    axes are a cubic spline (``not-a-knot``) through the knots, what a control's spline
    compressor makes of short blocks (it rounds a corner over about one knot step); the tip
    path length is linear between the knots (exact within a block), so its rate never
    overshoots the feed's cap. The path parameter ``u`` (mm) adds the tip path length and
    :data:`ROTARY_LENGTH` mm per radian of the largest rotary step, so a turn in place (a pole
    turn, no tip motion) has a length of its own.

The parameterisation
    ``toppra`` (TOPP-RA, Pham & Pham 2018) finds the fastest ``u(t)`` on gridpoints every
    :data:`GRID_STEP` of ``u`` and at every knot (the first and last step halved
    :data:`END_LEVELS` times): velocity constraints (axes, and tip speed <= feed) and
    acceleration constraints (axes, collocated) at every gridpoint, at rest at both ends of the
    run. TOPP-RA does not bound jerk, and no well-kept library does along a path with a feed
    constraint (``ruckig``'s open-source version plans motions to a target state, not along a
    given path).

The jerk
    The TOPP-RA trajectory is sampled on the control's clock (:data:`CLOCK`) and passed through
    a moving average of :func:`jerk_window` (the FIR jerk filter of a control): an acceleration
    step of at most ``2 a_j`` becomes a ramp within each axis' jerk limit, at the cost of the
    window's length per run (the motion ends that much later; a row is reached half of it
    later). Velocity, acceleration and jerk are differences of the filtered trajectory on that
    clock, never over program blocks. Rapids are timed as before (every axis at its velocity
    limit, :func:`urdfpost.analysis.metrics.block_times`).

Units: mm, rad, s in and out.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np

from urdfpost.errors import UrdfpostError
from urdfpost.kinematics.forward import tip_and_axis
from urdfpost.kinematics.inverse import solve_linear
from urdfpost.machine import Machine
from urdfpost.machine.load import AxisLimits

log = logging.getLogger(__name__)

__all__ = [
    "GRID_STEP",
    "KNOT_ANGLE",
    "KNOT_LENGTH",
    "ROTARY_LENGTH",
    "Timing",
    "jerk_window",
    "require_toppra",
    "time_program",
]

#: mm of path parameter per radian of rotary motion: weight of a rotary step in ``u`` (a turn of
#: 1 degree counts as 0.87 mm). It only spaces the gridpoints; the optimal time does not depend
#: on how the path is parameterised.
ROTARY_LENGTH = 50.0
#: mm. Largest tip path between two knots of the geometric path.
KNOT_LENGTH = 1.0
#: rad. Largest rotary step between two knots (1 degree).
KNOT_ANGLE = math.radians(1.0)
#: mm of ``u`` between TOPP-RA gridpoints.
GRID_STEP = 0.5
#: Finite stand-in for "no limit" in TOPP-RA's linear programs (mm or rad per s, per s^2).
UNBOUNDED = 1e9
#: Times the first and the last grid step are halved (:func:`_grid`).
END_LEVELS = 10
#: s. Clock of the trajectory after TOPP-RA: the control's interpolation cycle (1 ms is
#: typical; Heidenhain and Siemens run 0.1 to 4 ms).
CLOCK = 1e-3
#: Further tries of a run on a grid of one more point when TOPP-RA fails numerically.
RETRIES = 3
#: Share of the programmed feed below which the tip counts as slowed down (``slow_fraction``).
SLOW_SHARE = 0.95


def require_toppra() -> None:
    """Check that toppra can be imported.

    Raises
    ------
    UrdfpostError
        When it cannot, saying how to install it.
    """
    try:
        import toppra  # type: ignore[import-untyped]  # noqa: F401 (only its presence is checked)
    except ImportError as e:
        raise UrdfpostError(
            "timed kinematics (urdfpost compare) need toppra: pip install 'urdfpost[timing]'"
        ) from e


@dataclass(frozen=True, eq=False)
class Timing:
    """A program timed under the axis velocity and acceleration limits and the feed.

    Row ``k`` is program row ``k`` (as in :class:`urdfpost.analysis.metrics.Profile`).

    Attributes
    ----------
    t : ndarray, shape (N,), s
        When the machine reaches each row (rapids included).
    velocity, acceleration, jerk : ndarray, shape (N, m), mm or rad per s, s^2, s^3
        Axis derivatives at each row on the timed trajectory (0 at the rows that end a rapid
        and start no feed run; jerk NaN there).
    tip_speed : ndarray, shape (N,), mm/s
        Tool-tip speed at each row.
    peak_velocity, peak_acceleration, peak_jerk : ndarray, shape (m,)
        Largest ``|q'|``, ``|q''|``, ``|q'''|`` over the feed runs (every clock sample).
    jerk_over_limit_s : ndarray, shape (m,), s
        Time each axis spends above its jerk limit on the feed runs.
    feed_time_s : float
        Time of the feed runs.
    rapid_time_s : float
        Time of the rapid blocks.
    nominal_time_s : float
        Tip path length over the programmed feed, summed over the feed blocks.
    slow_fraction : float
        Share of the feed runs' tip path where the tip runs below :data:`SLOW_SHARE` of the
        programmed feed (0 when there is no feed motion).
    failed_runs : int
        Feed runs TOPP-RA could not parameterise (timed by the velocity limits only).
    """

    t: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    jerk: np.ndarray
    tip_speed: np.ndarray
    peak_velocity: np.ndarray
    peak_acceleration: np.ndarray
    peak_jerk: np.ndarray
    jerk_over_limit_s: np.ndarray
    feed_time_s: float
    rapid_time_s: float
    nominal_time_s: float
    slow_fraction: float
    failed_runs: int

    @property
    def feed_ratio(self) -> float:
        """``nominal_time_s / feed_time_s``: the mean tip speed as a share of the programmed
        feed (1 when the machine keeps the feed everywhere; 1 with no feed motion)."""
        return self.nominal_time_s / self.feed_time_s if self.feed_time_s > 0 else 1.0


@dataclass(frozen=True, eq=False)
class _Run:
    """One feed run, timed (internal)."""

    time: float
    row_t: np.ndarray  # (r,) time of the run's rows from its start
    row_v: np.ndarray  # (r, m)
    row_a: np.ndarray
    row_j: np.ndarray
    row_tip: np.ndarray  # (r,)
    peak_v: np.ndarray  # (m,)
    peak_a: np.ndarray
    peak_j: np.ndarray
    jerk_over: np.ndarray  # (m,) s
    slow_length: float
    length: float
    failed: bool


def _knots(
    machine: Machine, values: np.ndarray, tcp: bool, tool_length: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Knots of the geometric path of one run's rows (see the module docstring).

    Parameters
    ----------
    values : ndarray, shape (r, m), mm / rad
        The rows as programmed (tips for the linear columns of a TCP program).

    Returns
    -------
    q : ndarray, shape (K, m)
        Machine axes at the knots.
    tip : ndarray, shape (K, 3), mm
    row_knot : ndarray, shape (r,), int
        Knot of each row.
    rot_step : ndarray, shape (K - 1,), rad
        Largest rotary step between consecutive knots.
    """
    lin, rot = list(machine.linear_columns), list(machine.rotary_columns)
    if tcp:
        row_tip = values[:, lin]
    else:
        row_tip = tip_and_axis(machine, values, tool_length)[0]
    step_len = np.linalg.norm(np.diff(row_tip, axis=0), axis=1)
    step_rot = np.abs(np.diff(values[:, rot], axis=0)).max(axis=1, initial=0.0)
    pieces = np.maximum(
        np.ceil(np.maximum(step_len / KNOT_LENGTH, step_rot / KNOT_ANGLE)), 1
    ).astype(int)
    # fraction along each block of every knot after the block's start
    block = np.repeat(np.arange(len(pieces)), pieces)
    first = np.concatenate([[0], np.cumsum(pieces)[:-1]])
    frac = (np.arange(len(block)) - first[block] + 1) / pieces[block]
    start, delta = values[block], np.diff(values, axis=0)[block]
    inner = np.concatenate([values[:1], start + frac[:, None] * delta])
    row_knot = np.concatenate([[0], np.cumsum(pieces)])
    if tcp:
        tip = inner[:, lin]
        q = inner.copy()
        q[:, lin] = solve_linear(machine, inner[:, rot], tip, tool_length)
    else:
        q = inner
        tip = tip_and_axis(machine, inner, tool_length)[0]
    rot_step = np.abs(np.diff(inner[:, rot], axis=0)).max(axis=1, initial=0.0)
    return q, tip, row_knot, rot_step


def _time_run(
    machine: Machine,
    values: np.ndarray,
    feed: np.ndarray,
    limits: AxisLimits,
    tcp: bool,
    tool_length: float,
    window: float,
) -> _Run:
    """TOPP-RA on one feed run: rows ``values`` (r, m), ``feed`` (r - 1,) mm/s per block,
    then the jerk filter of ``window`` s (:func:`jerk_window`)."""

    m = values.shape[1]
    r = len(values)
    q, tip, row_knot, rot_step = _knots(machine, values, tcp, tool_length)
    tip_step = np.linalg.norm(np.diff(tip, axis=0), axis=1)
    du = tip_step + ROTARY_LENGTH * rot_step
    u_all = np.concatenate([[0.0], np.cumsum(du)])
    sigma_all = np.concatenate([[0.0], np.cumsum(tip_step)])
    block_of_knot = np.searchsorted(row_knot, np.arange(1, len(u_all)), side="left") - 1
    knot_feed = feed[np.clip(block_of_knot, 0, len(feed) - 1)]  # feed of the step into a knot
    keep = np.concatenate([[True], du > 1e-9])
    length = float(sigma_all[-1])
    zero = np.zeros(m)
    if keep.sum() < 2:  # nothing moves
        return _Run(
            0.0,
            np.zeros(r),
            np.zeros((r, m)),
            np.zeros((r, m)),
            np.zeros((r, m)),
            np.zeros(r),
            zero,
            zero,
            zero,
            zero,
            0.0,
            0.0,
            False,
        )
    u, sigma = u_all[keep], sigma_all[keep]
    points = np.column_stack([q[keep], sigma])
    step_feed = knot_feed[keep[1:]]  # (K - 1,) feed of each interval of u
    row_u = u_all[row_knot]
    path = _path_class()(u, points[:, :m], points[:, m])

    vmax = np.where(np.isfinite(limits.velocity), limits.velocity, UNBOUNDED)
    amax = np.where(np.isfinite(limits.acceleration), limits.acceleration, UNBOUNDED)
    base = max(math.ceil(u[-1] / GRID_STEP), 2) + 1
    for attempt in range(RETRIES + 1):
        # seidel's two-variable programs now and then fail on a degenerate gridpoint (the
        # controllable set "can't be computed"); a grid of one point more moves it
        grid = np.union1d(_grid(u[-1], base + attempt), u)
        grid_feed = _grid_feed(u, step_feed, grid)
        x = _topp(path, grid, grid_feed, vmax, amax, m)
        if x is not None:
            break
        log.debug("TOPP-RA failed on %d gridpoints, retrying", len(grid))
    n_grid = len(grid)
    ds = np.diff(grid)
    if x is None:
        return _velocity_only_run(path, grid, grid_feed, vmax, row_u, length, m)
    speed_sum = np.sqrt(x[1:]) + np.sqrt(x[:-1])
    dt = 2.0 * ds / speed_sum
    t_grid = np.concatenate([[0.0], np.cumsum(dt)])
    sdd = np.diff(x) / (2.0 * ds)  # constant over each interval
    sd = np.sqrt(x)
    d1 = path(grid, 1)
    tip_mid = np.abs(d1[:-1, m] + d1[1:, m]) / 2 * (sd[:-1] + sd[1:]) / 2
    slow = tip_mid < SLOW_SHARE * grid_feed[:-1]
    seg_len = np.abs(np.diff(path(grid)[:, m]))

    # the trajectory on the control's clock, through the jerk filter
    clock = np.arange(0.0, t_grid[-1] + CLOCK, CLOCK)
    cell = np.clip(np.searchsorted(t_grid, clock, side="right") - 1, 0, n_grid - 2)
    tau = clock - t_grid[cell]
    s_t = np.clip(
        grid[cell] + sd[cell] * tau + 0.5 * sdd[cell] * tau**2, grid[cell], grid[cell + 1]
    )
    q_t = path(s_t)
    width = max(round(window / CLOCK), 1)
    # the filtered velocity is the mean of the clock's velocities over the window: the lag
    # difference of the positions (no running sum, whose rounding the jerk would amplify)
    padded = np.concatenate([np.repeat(q_t[:1], width, 0), q_t, np.repeat(q_t[-1:], width, 0)])
    del q_t
    vel = (padded[width:] - padded[:-width]) / (width * CLOCK)
    del padded
    acc = np.diff(vel, axis=0) / CLOCK
    jerk = np.diff(acc, axis=0) / CLOCK
    delay = (width - 1) * CLOCK / 2.0  # the filter's group delay

    # the rows: reached at their TOPP-RA time plus the filter's delay; the run leaves its first
    # row at its start and settles on its last at its end
    run_time = float((len(vel) - 2) * CLOCK)  # settled once the window holds only the end
    row_t = np.clip(np.interp(row_u, grid, t_grid) + delay, 0.0, run_time)
    row_t[0], row_t[-1] = 0.0, run_time
    at = np.clip(np.round(row_t / CLOCK).astype(int), 0, len(jerk) - 1)
    jerk_over = ((np.abs(jerk[:, :m]) > limits.jerk * (1 + 1e-9)) * CLOCK).sum(axis=0)
    return _Run(
        time=run_time,
        row_t=row_t,
        row_v=vel[np.minimum(at, len(vel) - 1), :m],
        row_a=acc[np.minimum(at, len(acc) - 1), :m],
        row_j=jerk[at, :m],
        row_tip=np.abs(vel[np.minimum(at, len(vel) - 1), m]),
        peak_v=np.abs(vel[:, :m]).max(axis=0, initial=0.0),
        peak_a=np.abs(acc[:, :m]).max(axis=0, initial=0.0),
        peak_j=np.abs(jerk[:, :m]).max(axis=0, initial=0.0),
        jerk_over=jerk_over,
        slow_length=float(seg_len[slow].sum()),
        length=length,
        failed=False,
    )


def _path_class() -> type:
    """The geometric path as toppra wants it (toppra imported here, lazily)."""
    import toppra
    from scipy.interpolate import CubicSpline

    class KnotPath(toppra.interpolator.AbstractGeometricPath):
        """Machine axes: a ``not-a-knot`` cubic spline through the knots; the tip path
        length: linear between them (exact: the knots of a block are evenly spaced in tip
        path and rotary angle), so its rate never overshoots the feed's cap. At a knot the
        rate is the larger of its two sides."""

        def __init__(self, u: np.ndarray, q: np.ndarray, sigma: np.ndarray) -> None:
            self._u, self._sigma = u, sigma
            self._axes = CubicSpline(u, q, bc_type="not-a-knot")
            slope = np.diff(sigma) / np.diff(u)
            self._slope = slope
            self._at_knot = np.maximum(np.append(slope, slope[-1]), np.append(slope[0], slope))

        def __call__(self, s: np.ndarray | float, order: int = 0) -> np.ndarray:
            ss = np.atleast_1d(np.asarray(s, dtype=float))
            axes = self._axes(ss, order)
            if order == 0:
                tip = np.interp(ss, self._u, self._sigma)
            elif order == 1:
                cell = np.clip(
                    np.searchsorted(self._u, ss, side="right") - 1, 0, len(self._slope) - 1
                )
                tip = self._slope[cell]
                knot = np.searchsorted(self._u, ss)
                on = (knot < len(self._u)) & (self._u[np.minimum(knot, len(self._u) - 1)] == ss)
                tip = np.where(on, self._at_knot[np.minimum(knot, len(self._u) - 1)], tip)
            else:
                tip = np.zeros(len(ss))
            out = np.column_stack([axes, tip])
            return out if np.ndim(s) else out[0]

        @property
        def dof(self) -> int:
            return int(self._axes.c.shape[-1]) + 1

        @property
        def path_interval(self) -> np.ndarray:
            return np.array([self._u[0], self._u[-1]])

        @property
        def waypoints(self) -> tuple[np.ndarray, np.ndarray]:
            return self._u, np.column_stack([self._axes(self._u), self._sigma])

    return KnotPath


def _grid(length: float, n: int) -> np.ndarray:
    """``n`` even gridpoints over ``[0, length]``, the first and last step halved
    :data:`END_LEVELS` times: at rest at both ends, the run speeds up and slows down within a
    fraction of a step, which an even grid would stretch over a whole one."""
    grid = np.linspace(0.0, length, n)
    h = grid[1] - grid[0]
    ends = h * 0.5 ** np.arange(1, END_LEVELS + 1)
    return np.unique(np.concatenate([grid, ends, length - ends]))


def _grid_feed(u: np.ndarray, step_feed: np.ndarray, grid: np.ndarray) -> np.ndarray:
    """Programmed feed at each gridpoint (the smaller of the two blocks at a knot), mm/s."""
    right = np.clip(np.searchsorted(u, grid, side="right") - 1, 0, len(step_feed) - 1)
    left = np.clip(np.searchsorted(u, grid, side="left") - 1, 0, len(step_feed) - 1)
    return np.minimum(step_feed[right], step_feed[left])


def _topp(
    path: object,
    grid: np.ndarray,
    grid_feed: np.ndarray,
    vmax: np.ndarray,
    amax: np.ndarray,
    m: int,
) -> np.ndarray | None:
    """TOPP-RA at rest at both ends: ``x = s'^2`` at the gridpoints, or None when it fails.

    The path has ``m`` machine axes and the tip path length as its last coordinate; the axes
    get ``vmax`` and ``amax``, the tip path the feed (no acceleration limit of its own).
    """
    import toppra.algorithm  # type: ignore[import-untyped]
    import toppra.constraint  # type: ignore[import-untyped]

    n_grid = len(grid)
    vlim_grid = np.empty((n_grid, m + 1, 2))
    vlim_grid[:, :m, 1] = vmax
    vlim_grid[:, m, 1] = np.where(np.isfinite(grid_feed), grid_feed, UNBOUNDED)
    vlim_grid[:, :, 0] = -vlim_grid[:, :, 1]

    def vlim(s: float) -> np.ndarray:
        return vlim_grid[min(int(np.searchsorted(grid, s)), n_grid - 1)]

    alim = np.column_stack([-np.append(amax, UNBOUNDED), np.append(amax, UNBOUNDED)])
    constraints = [
        toppra.constraint.JointVelocityConstraintVarying(vlim),
        toppra.constraint.JointAccelerationConstraint(
            alim, discretization_scheme=toppra.constraint.DiscretizationType.Collocation
        ),
    ]
    problem = toppra.algorithm.TOPPRA(constraints, path, gridpoints=grid, solver_wrapper="seidel")
    # a failure is retried (or reported) by the caller: toppra's own warnings stay quiet
    quiet = logging.getLogger("toppra")
    level = quiet.level
    quiet.setLevel(logging.ERROR)
    try:
        problem.compute_parameterization(0.0, 0.0)
    finally:
        quiet.setLevel(level)
    sd = problem.problem_data.sd_vec
    if sd is None or not np.all(np.isfinite(sd)):
        return None
    x = np.maximum(np.asarray(sd, dtype=float), 0.0) ** 2
    if not np.all(np.sqrt(x[1:]) + np.sqrt(x[:-1]) > 0):
        return None
    return x


def _velocity_only_run(
    path: object,
    grid: np.ndarray,
    grid_feed: np.ndarray,
    vmax: np.ndarray,
    row_u: np.ndarray,
    length: float,
    m: int,
) -> _Run:
    """A run TOPP-RA could not parameterise: the largest path speed the velocity limits allow
    at each gridpoint, no acceleration (logged; counted in :attr:`Timing.failed_runs`)."""
    log.warning("TOPP-RA could not time a feed run: timed by the velocity limits only")
    d1 = path(grid, 1)  # type: ignore[operator]
    with np.errstate(divide="ignore"):
        bound = np.where(np.abs(d1[:, :m]) > 0, vmax / np.abs(d1[:, :m]), np.inf).min(axis=1)
        bound = np.minimum(
            bound, np.where(np.abs(d1[:, m]) > 0, grid_feed / np.abs(d1[:, m]), np.inf)
        )
    bound = np.where(np.isfinite(bound), bound, UNBOUNDED)
    dt = np.diff(grid) / np.minimum(bound[1:], bound[:-1])
    t_grid = np.concatenate([[0.0], np.cumsum(dt)])
    nan = np.full((len(row_u), m), np.nan)
    vel = d1[:, :m] * bound[:, None]
    return _Run(
        time=float(t_grid[-1]),
        row_t=np.interp(row_u, grid, t_grid),
        row_v=nan,
        row_a=nan.copy(),
        row_j=nan.copy(),
        row_tip=np.full(len(row_u), np.nan),
        peak_v=np.abs(vel).max(axis=0),
        peak_a=np.full(m, np.nan),
        peak_j=np.full(m, np.nan),
        jerk_over=np.zeros(m),
        slow_length=math.nan,
        length=length,
        failed=True,
    )


def jerk_window(limits: AxisLimits) -> float:
    """Length of the jerk filter: ``max_j 2 a_j / j_j`` over the axes with both limits (s).

    A moving average of length ``T`` turns an acceleration that changes by at most ``2 a``
    (from ``+a`` to ``-a``) into one that changes at most ``2 a / T`` per second: within the
    jerk limit of every axis when ``T >= 2 a_j / j_j``. 0 when no axis has both limits (no
    filter: jerk then is the clock's differences, unlimited).

    Examples
    --------
    >>> from urdfpost.machine import load_machine
    >>> from urdfpost.machine.load import axis_limits
    >>> round(jerk_window(axis_limits(load_machine("dmu50"))), 3)
    0.2
    """
    both = np.isfinite(limits.acceleration) & np.isfinite(limits.jerk)
    if not both.any():
        return 0.0
    return float((2.0 * limits.acceleration[both] / limits.jerk[both]).max())


def time_program(
    machine: Machine,
    values: np.ndarray,
    rapid: np.ndarray,
    feed: np.ndarray,
    limits: AxisLimits,
    *,
    tcp: bool,
    tool_length: float,
    rapid_time: np.ndarray,
) -> Timing:
    """Time a program's rows under the axis limits and the feed (see the module docstring).

    Parameters
    ----------
    machine : Machine
    values : ndarray, shape (N, m), mm / rad
        The rows as programmed: for a TCP program the linear columns are the tool tip.
    rapid : ndarray, shape (N,), bool
        Whether the block ending at each row is a rapid (row 0: True, the start).
    feed : ndarray, shape (N,), mm/s
        Programmed feed of the block ending at each row (``inf`` for rapids and for feed blocks
        with no feed).
    limits : AxisLimits
        Of :func:`urdfpost.machine.load.axis_limits`.
    tcp : bool
    tool_length : float, mm
    rapid_time : ndarray, shape (N - 1,), s
        Duration of each block when it is a rapid (only those entries are used).

    Returns
    -------
    Timing

    Raises
    ------
    UrdfpostError
        When toppra is not installed (the message says how to install it).
    """
    require_toppra()
    window = jerk_window(limits)
    n, m = values.shape
    t = np.zeros(n)
    vel, acc, jerk = np.zeros((n, m)), np.zeros((n, m)), np.full((n, m), np.nan)
    tip_speed = np.zeros(n)
    peak_v, peak_a, peak_j, jerk_over = (np.zeros(m) for _ in range(4))
    feed_time = rapid_t = nominal = slow_len = total_len = 0.0
    failed = 0
    is_feed = ~np.asarray(rapid, dtype=bool)
    if n:
        is_feed[0] = False
    k, clock = 1, 0.0
    while k < n:
        if not is_feed[k]:
            clock += float(rapid_time[k - 1])
            rapid_t += float(rapid_time[k - 1])
            t[k] = clock
            k += 1
            continue
        end = k
        while end < n and is_feed[end]:
            end += 1
        rows = slice(k - 1, end)  # the run's rows: the rest point before it, its blocks' ends
        run = _time_run(machine, values[rows], feed[k:end], limits, tcp, tool_length, window)
        t[rows] = clock + run.row_t
        vel[rows], acc[rows], jerk[rows], tip_speed[rows] = (
            run.row_v,
            run.row_a,
            run.row_j,
            run.row_tip,
        )
        peak_v = np.fmax(peak_v, run.peak_v)
        peak_a = np.fmax(peak_a, run.peak_a)
        peak_j = np.fmax(peak_j, run.peak_j)
        jerk_over += run.jerk_over
        clock += run.time
        feed_time += run.time
        lengths = np.linalg.norm(
            np.diff(_tips(machine, values[rows], tcp, tool_length), axis=0), axis=1
        )
        finite = np.isfinite(feed[k:end])
        nominal += float((lengths[finite] / feed[k:end][finite]).sum())
        slow_len += run.slow_length
        total_len += run.length
        failed += int(run.failed)
        k = end
    return Timing(
        t=t,
        velocity=vel,
        acceleration=acc,
        jerk=jerk,
        tip_speed=tip_speed,
        peak_velocity=peak_v,
        peak_acceleration=peak_a,
        peak_jerk=peak_j,
        jerk_over_limit_s=jerk_over,
        feed_time_s=feed_time,
        rapid_time_s=rapid_t,
        nominal_time_s=nominal,
        slow_fraction=slow_len / total_len if total_len > 0 else 0.0,
        failed_runs=failed,
    )


def _tips(machine: Machine, values: np.ndarray, tcp: bool, tool_length: float) -> np.ndarray:
    """Tool tips of rows (mm)."""
    if tcp:
        return values[:, list(machine.linear_columns)]
    return tip_and_axis(machine, values, tool_length)[0]
