"""Where a path comes near a singular configuration, or asks for more than the axes can give.

The orientation Jacobian ``J_v`` maps rotary-axis rates to the rate of the tool-axis vector in
the workpiece frame (3 x r). Near a pole (tool axis along the first rotary axis) or at the edge
of a nutating machine's tilt range its smallest singular value goes to zero and the inverse
kinematics asks for unbounded rotary speed. Two detectors mark the CL points a strategy should
repair (:data:`DETECTORS`; ``docs/strategies.md`` gives their sources):

``geometric`` (the default)
    The CL points whose conditioning is below ``Tolerances.singular_sigma`` and the steps whose
    rotary swing exceeds ``Tolerances.swing_limit``. Blind to the feed and the axis limits.
``rate``
    The steps whose rotary-axis speed at the programmed feed (:func:`demanded_rates`) exceeds
    the axis' velocity limit times ``DetectorTolerances.rate_share``. Each marked stretch is
    widened until the net turn of every rotary axis across it fits its limit in the time the
    feed gives the stretch, so a strategy has room to spread the turn. A cut with a feed move
    of no feed, or a machine with no velocity limit on its rotary axes, falls back to the
    geometric detector with a warning.

Marked points are joined into spans, widened by ``Tolerances.singular_margin`` points within
their feed run, and reported.
"""

from __future__ import annotations

import logging
from dataclasses import asdict, dataclass
from typing import Final

import numpy as np

from urdfpost.kinematics.forward import (
    ROWS,
    PoeChain,
    axis_and_joint_directions,
    chain_of,
    row_chunks,
)
from urdfpost.machine import Machine
from urdfpost.tolerances import Tolerances
from urdfpost.toolpath import Motion, Toolpath

log = logging.getLogger(__name__)

DETECTORS: Final = ("geometric", "rate")
"""The singularity detectors, by name: ``--detector`` choices."""

DEFAULT_DETECTOR: Final = "geometric"
"""The detector taken when the options name none (see ``docs/strategies.md`` for why)."""

#: mm. A step whose tool tip moves less than this turns in place: its demanded axis speed at
#: the feed is not defined (a pure reorientation has no path length for the feed to act on).
STILL: Final = 1e-6


@dataclass(frozen=True)
class DetectorTolerances(Tolerances):
    """:class:`~urdfpost.tolerances.Tolerances` with the choice of singularity detector.

    :func:`detect` reads these fields from the thresholds a problem carries; a plain
    :class:`~urdfpost.tolerances.Tolerances` means the geometric detector.

    Attributes
    ----------
    detector : str
        "geometric" or "rate" (:data:`DETECTORS`).
    rate_share : float
        Share of an axis' velocity limit above which the rate detector marks a step. 1.0: the
        limit itself, the issue's definition ("the axis speed it demands at the programmed feed
        exceeds the axis limit").
    """

    detector: str = DEFAULT_DETECTOR
    rate_share: float = 1.0

    def __post_init__(self) -> None:
        if self.detector not in DETECTORS:
            raise ValueError(
                f"unknown singularity detector {self.detector!r}; expected one of "
                f"{', '.join(DETECTORS)}"
            )
        if not self.rate_share > 0:
            raise ValueError(f"rate_share must be > 0, got {self.rate_share!r}")


def with_detector(tol: Tolerances, detector: str) -> DetectorTolerances:
    """``tol`` with the singularity detector ``detector`` (its other thresholds kept)."""
    fields = {k: v for k, v in asdict(tol).items() if k not in ("detector",)}
    return DetectorTolerances(**fields, detector=detector)


def detector_of(tol: Tolerances) -> str:
    """The singularity detector the thresholds ``tol`` ask for."""
    return tol.detector if isinstance(tol, DetectorTolerances) else DEFAULT_DETECTOR


def step_times(toolpath: Toolpath) -> np.ndarray:
    """Duration of each CL step at its programmed feed, shape (n - 1,), s.

    ``|tip[i + 1] - tip[i]| / (feed[i + 1] / 60)``; NaN where the move has no positive feed
    (a rapid, or a feed move with no feed), 0 where the tip stands still (less than
    :data:`STILL`).
    """
    length = np.linalg.norm(np.diff(toolpath.tip, axis=0), axis=1)
    feed = toolpath.feed[1:] / 60.0  # mm/s
    with np.errstate(divide="ignore", invalid="ignore"):
        dt = np.where(feed > 0, length / feed, np.nan)
    return np.where(length < STILL, np.where(np.isnan(dt), np.nan, 0.0), dt)


def demanded_rates(machine: Machine, toolpath: Toolpath, q: np.ndarray) -> np.ndarray:
    """Speed each rotary axis needs to follow the joint path ``q`` at the programmed feed.

    ``|q[i + 1, j] - q[i, j]| / dt[i]`` with ``dt`` from :func:`step_times`: the joint step
    between CL points over the time the feed gives the tip step (the closed form of a
    hemisphere pass at offset y0 is ``F / y0``, ``../shared/docs/singularity-research.md``
    section 7).

    Parameters
    ----------
    machine : Machine
    toolpath : Toolpath
    q : ndarray, shape (n, m), mm / rad

    Returns
    -------
    ndarray, shape (n - 1, r), rad/s
        Columns in :attr:`Machine.rotary` order; NaN where the step has no feed or the tip
        stands still (the speed is not defined), never negative.
    """
    cols = list(machine.rotary_columns)
    step = np.abs(np.diff(np.asarray(q, dtype=float)[:, cols], axis=0))
    dt = step_times(toolpath)[:, None]
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(dt > 0, step / np.where(dt > 0, dt, 1.0), np.nan)


def orientation_jacobian(machine: Machine | PoeChain, q: np.ndarray) -> np.ndarray:
    """Jacobian of the tool-axis vector with respect to the rotary joints (vectorised).

    Column j is ``omega_j(q) x v``, where ``omega_j`` is the direction of rotary joint j in the
    workpiece frame at configuration ``q`` (signed so that a positive joint value turns the
    tool positively relative to the workpiece) and ``v`` the tool axis. The tests hold it to
    Pinocchio's Jacobian (``jacobian_pin`` in ``tests/oracles.py``).

    Parameters
    ----------
    machine : Machine or PoeChain
    q : ndarray, shape (n, m) or (m,), mm / rad

    Returns
    -------
    ndarray, shape (n, 3, r)
        Columns in :attr:`Machine.rotary` (chain) order, per radian.
    """
    chain = chain_of(machine)
    q = np.asarray(q, dtype=float).reshape(-1, chain.n_axes)
    out = np.empty((q.shape[0], 3, len(chain.rotary_columns)))
    for part in row_chunks(q.shape[0]):
        _jacobian_into(out[part], chain, q[part])
    return out


def _jacobian_into(out: np.ndarray, chain: PoeChain, q: np.ndarray) -> np.ndarray:
    """:func:`orientation_jacobian` of a few thousand rows ``q`` into ``out`` (k, 3, r); returns
    the tool axis (k, 3)."""
    v, directions = axis_and_joint_directions(chain, q)
    v0, v1, v2 = v[:, 0], v[:, 1], v[:, 2]
    for j, w in enumerate(directions):  # cross(w, v), the same products and differences
        w0, w1, w2 = w[:, 0], w[:, 1], w[:, 2]
        for i, (a, b, c, d) in enumerate(((w1, v2, w2, v1), (w2, v0, w0, v2), (w0, v1, w1, v0))):
            col = out[:, i, j]
            np.multiply(a, b, out=col)
            col -= c * d
    return v


def _conditioning_of(j: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Smallest singular value and condition number of Jacobians ``j`` (n, 3, r)."""
    if j.shape[2] == 2:
        # two columns: s1^2 + s2^2 is the sum of their squared lengths and s1 s2 the area of
        # the parallelogram they span (which keeps its precision where s2 is tiny)
        total = np.einsum("nij,nij->n", j, j)
        (a0, b0), (a1, b1), (a2, b2) = ((j[:, i, 0], j[:, i, 1]) for i in range(3))
        # the length of their cross product, by the same operations as
        # np.linalg.norm(cross(a, b), axis=1) without its reduction over rows of three
        c0, c1, c2 = a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0
        area = np.sqrt(c0 * c0 + c1 * c1 + c2 * c2)
        smax = np.sqrt(0.5 * (total + np.sqrt(np.maximum(total**2 - 4.0 * area**2, 0.0))))
        with np.errstate(divide="ignore", invalid="ignore"):
            smin = np.where(smax > 0, area / np.where(smax > 0, smax, 1.0), 0.0)
    else:
        s = np.linalg.svd(j, compute_uv=False)  # (n, r), descending
        smin, smax = s[:, -1], s[:, 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        kappa = np.where(smin > 0, smax / np.where(smin > 0, smin, 1.0), np.inf)
    return smin, kappa


def _conditioning_and_axis(
    machine: Machine | PoeChain, q: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`conditioning` and the tool axis (n, 3), a few thousand rows at a time (the
    Jacobians of one chunk stay in the CPU cache and are not kept)."""
    chain = chain_of(machine)
    q = np.asarray(q, dtype=float).reshape(-1, chain.n_axes)
    n = q.shape[0]
    sigma, kappa, axis = np.empty(n), np.empty(n), np.empty((n, 3))
    size = max(1, min(n, ROWS))
    j = np.empty((size, 3, len(chain.rotary_columns)))
    for part in row_chunks(n, size):
        k = part.stop - part.start
        axis[part] = _jacobian_into(j[:k], chain, q[part])
        sigma[part], kappa[part] = _conditioning_of(j[:k])
    return sigma, kappa, axis


def conditioning(machine: Machine | PoeChain, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Smallest singular value and condition number of the orientation Jacobian.

    For a machine with one rotary axis the Jacobian is a single column; its norm is both the
    smallest and largest singular value (condition number 1 where it is non-zero).

    Parameters
    ----------
    machine : Machine or PoeChain
    q : ndarray, shape (n, m) or (m,), mm / rad

    Returns
    -------
    sigma_min : ndarray, shape (n,)
        Rad/s of tool-axis motion per rad/s of joint motion in the worst direction; for an
        orthogonal two-axis machine it is the sine of the angle between the tool axis and the
        first rotary axis.
    kappa : ndarray, shape (n,)
        sigma_max / sigma_min (``inf`` at a singular point).
    """
    sigma, kappa, _ = _conditioning_and_axis(machine, q)
    return sigma, kappa


@dataclass(frozen=True)
class Span:
    """A singular span of a path: contiguous CL points a strategy may repair.

    Attributes
    ----------
    first, last : int
        Indices of its first and last CL point (inclusive, margin included); the strategies
        keep the exact inverse kinematics at both.
    first_line, last_line : int
        Their CL source lines.
    kind : str
        "pole" (tool axis near the first rotary axis), "edge" (near the limit of the reachable
        tilt, where two branches merge), "swing" (large rotary steps at fine conditioning, the
        geometric detector) or "rate" (a rotary axis over its velocity limit at the programmed
        feed at fine conditioning, the rate detector).
    min_sigma : float
        Smallest singular value of the orientation Jacobian at its points.
    max_kappa : float
        Largest condition number at its points.
    swing_deg : float
        Total motion of the first rotary axis across the span with the exact inverse
        kinematics, degrees.
    max_step_deg : float
        Largest step of any rotary axis between neighbouring points in the span, degrees.
    """

    first: int
    last: int
    first_line: int
    last_line: int
    kind: str
    min_sigma: float
    max_kappa: float
    swing_deg: float
    max_step_deg: float

    def as_dict(self) -> dict:
        """Plain data for JSON reports."""
        return asdict(self)


def joined_runs(joined: np.ndarray) -> list[tuple[int, int]]:
    """Maximal runs [s, e] (e > s) of points each joined to the one before it.

    ``joined[i]`` says point i continues the run of point i - 1 (``joined[0]`` is not read).

    Examples
    --------
    >>> joined_runs(np.array([True, True, True, False, True, False, False]))
    [(0, 2), (3, 4)]
    """
    links = np.zeros(max(len(joined) + 1, 2), dtype=np.int8)  # links[i]: i joined to i - 1
    links[1:-1] = np.asarray(joined, dtype=bool)[1:]
    change = np.diff(links)
    starts = np.flatnonzero(change == 1)  # the first link of a run joins its start to the next
    ends = np.flatnonzero(change == -1)
    return [(int(a), int(b)) for a, b in zip(starts, ends, strict=True)]


def feed_runs(toolpath: Toolpath) -> list[tuple[int, int]]:
    """Maximal runs [s, e] of CL points joined by feed moves of one cut (e > s).

    Point i belongs to the run of point i - 1 when it is reached by a feed move and no tool
    change happens at it.
    """
    n = len(toolpath)
    joined = toolpath.motion == Motion.FEED
    for e in toolpath.events:
        if e.kind == "tool" and e.index < n:
            joined[e.index] = False
    return joined_runs(joined)


def _geometric_marks(
    sigma: np.ndarray, q: np.ndarray, rot_cols: list[int], s: int, e: int, tol: Tolerances
) -> np.ndarray:
    """Points of run [s, e] the geometric detector marks, shape (e - s + 1,)."""
    low = sigma[s : e + 1] < tol.singular_sigma
    swing = np.zeros(e - s + 1, dtype=bool)
    big = np.zeros(e - s, dtype=bool)  # a rotary step into the point after
    for c in rot_cols:
        big |= np.abs(np.diff(q[s : e + 1, c])) > tol.swing_limit
    swing[1:] |= big
    swing[:-1] |= big
    return low | swing


def _rate_marks(rate: np.ndarray, limit: np.ndarray, s: int, e: int) -> np.ndarray:
    """Points of run [s, e] at either end of a step over the rate limit, shape (e - s + 1,)."""
    over = np.zeros(e - s, dtype=bool)
    with np.errstate(invalid="ignore"):
        over |= (rate[s:e] > limit[None, :]).any(axis=1)
    mark = np.zeros(e - s + 1, dtype=bool)
    mark[1:] |= over
    mark[:-1] |= over
    return mark


def _fits(q: np.ndarray, t: np.ndarray, limit: np.ndarray, a: int, b: int) -> bool:
    """Whether the net rotary turn from point a to b fits the limits in the time between them.

    ``q`` (n, r) rotary angles, ``t`` (n,) cumulative step times, ``limit`` (r,) rad/s.
    """
    return bool(np.all(np.abs(q[b] - q[a]) <= limit * (t[b] - t[a]) + 1e-12))


def _widened(
    q: np.ndarray, t: np.ndarray, limit: np.ndarray, a: int, b: int, s: int, e: int
) -> tuple[int, int]:
    """[a, b] grown by a point on each side (within [s, e]) until :func:`_fits` holds."""
    while not _fits(q, t, limit, a, b) and (a > s or b < e):
        a, b = max(s, a - 1), min(e, b + 1)
    return a, b


def _stretches(mark: np.ndarray, s: int) -> list[tuple[int, int]]:
    """Contiguous marked stretches [a, b] of a run starting at point s."""
    idx = np.flatnonzero(mark) + s
    if not idx.size:
        return []
    breaks = np.flatnonzero(np.diff(idx) > 1)
    starts = np.concatenate([[idx[0]], idx[breaks + 1]])
    ends = np.concatenate([idx[breaks], [idx[-1]]])
    return [(int(a), int(b)) for a, b in zip(starts, ends, strict=True)]


def detect(
    machine: Machine,
    toolpath: Toolpath,
    q: np.ndarray,
    tol: Tolerances | None = None,
    runs: list[tuple[int, int]] | None = None,
) -> list[Span]:
    """Singular spans of a path, from its exact inverse kinematics.

    Parameters
    ----------
    machine : Machine
    toolpath : Toolpath
    q : ndarray, shape (n, m), mm / rad
        The exact solution chosen at every CL point (rotary angles unwrapped along the path).
    tol : Tolerances, optional
        ``singular_sigma``, ``swing_limit`` and ``singular_margin`` are used; a
        :class:`DetectorTolerances` chooses the detector (default geometric) and its
        ``rate_share``.
    runs : list of (int, int), optional
        Feed runs (default :func:`feed_runs`); spans never leave their run.

    Returns
    -------
    list of Span
        In path order, not overlapping.
    """
    tol = tol or Tolerances()
    n = len(toolpath)
    if n == 0 or not machine.rotary:
        return []
    runs = feed_runs(toolpath) if runs is None else runs
    sigma, kappa, v = _conditioning_and_axis(machine, q)
    rot_cols = list(machine.rotary_columns)
    by_rate = detector_of(tol) == "rate"
    share = tol.rate_share if isinstance(tol, DetectorTolerances) else 1.0
    limit = np.array([a.velocity for a in machine.rotary]) * share
    if by_rate and not np.isfinite(limit).any():
        log.warning(
            "rate singularity detector: machine %s gives no velocity limit for its rotary axes "
            "(URDF <limit velocity>); singular spans by the geometric threshold",
            machine.name,
        )
        by_rate = False
    fallback: list[int] = []  # rate detector: the first point without feed of each such run
    dt = step_times(toolpath) if by_rate else np.zeros(max(n - 1, 0))
    if by_rate:
        rate = demanded_rates(machine, toolpath, q)
        rot_q = q[:, rot_cols]
        elapsed = np.concatenate([[0.0], np.cumsum(np.nan_to_num(dt, nan=0.0))])
    # cosine of the angle between the tool axis and the first rotary axis, of the whole path
    # at once (the last bits of a matrix product can depend on how its rows are split); the
    # rest is element-wise, worked out per run and per span
    along_k1 = v @ machine.rotary[0].direction
    spans: list[Span] = []
    for s, e in runs:
        rate_here = by_rate and bool(np.isfinite(dt[s:e]).all())
        if by_rate and not rate_here:
            fallback.append(s + 1 + int(np.flatnonzero(~np.isfinite(dt[s:e]))[0]))
        if rate_here:
            stretches = [
                _widened(rot_q, elapsed, limit, a, b, s, e)
                for a, b in _stretches(_rate_marks(rate, limit, s, e), s)
            ]
        else:
            stretches = _stretches(_geometric_marks(sigma, q, rot_cols, s, e, tol), s)
        if not stretches:
            continue
        # widened by the margin, merged where they touch
        merged: list[list[int]] = []
        for a, b in sorted(stretches):
            a = max(s, a - tol.singular_margin)
            b = min(e, b + tol.singular_margin)
            if merged and a <= merged[-1][1]:
                merged[-1][1] = max(merged[-1][1], b)
            else:
                merged.append([a, b])
        for a, b in merged:
            sl = slice(a, b + 1)
            step = np.zeros((b - a + 1, len(rot_cols)))  # rotary steps into each point
            step[1:] = np.abs(np.diff(q[sl][:, rot_cols], axis=0))
            if (sigma[sl] < tol.singular_sigma).any():
                sin_k1 = np.sqrt(np.clip(1.0 - along_k1[sl] ** 2, 0.0, None))
                kind = "pole" if (sin_k1 < tol.singular_sigma).any() else "edge"
            else:
                kind = "rate" if rate_here else "swing"
            spans.append(
                Span(
                    first=a,
                    last=b,
                    first_line=int(toolpath.line[a]),
                    last_line=int(toolpath.line[b]),
                    kind=kind,
                    min_sigma=float(sigma[sl].min()),
                    max_kappa=float(kappa[sl].max()),
                    swing_deg=float(np.degrees(step[1:, 0].sum())),
                    max_step_deg=float(np.degrees(step[1:].max(initial=0.0))),
                )
            )
    if by_rate and fallback:
        lines = ", ".join(str(int(toolpath.line[i])) for i in fallback[:5])
        more = f" and {len(fallback) - 5} more" if len(fallback) > 5 else ""
        log.warning(
            "rate singularity detector: %s: a feed move with no feed (CL line %s%s); singular "
            "spans of %s by the geometric threshold",
            toolpath.source,
            lines,
            more,
            "that cut" if len(fallback) == 1 else "those cuts",
        )
    log.debug("%d singular spans", len(spans))
    return spans
