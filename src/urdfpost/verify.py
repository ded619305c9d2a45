"""Verification: a program's motion, run through the machine, compared with the CL data.

The program is taken as the control executes it: every block end goes through the forward
kinematics (tool tip and axis in the workpiece frame; the vectorised product of exponentials,
which the tests hold to Pinocchio on every shipped machine and on generated ones); between
feed blocks the axes are interpolated linearly as the control does (in TCP programs the tip
moves on the straight line and the rotary axes interpolate linearly), sampled densely, and the
worst sample refined by golden-section search in every block where that could change the
result (elsewhere a bound on the deviation between samples rules it out). The result is
compared with the CL path: tool-tip distance to the CL polyline, tool-axis angle to the CL axis
interpolated (slerp) at the same place, and which CL points the program reaches, in order.
Everything runs on arrays, in chunks of blocks.
"""

from __future__ import annotations

import logging
from dataclasses import asdict, dataclass, field, replace

import numpy as np

from urdfpost.errors import DialectError
from urdfpost.kinematics.forward import Vec, interpolation_bounds, tip_and_axis_along
from urdfpost.linearize import (
    Arcs,
    RowPoses,
    Segments,
    angle_between,
    angle_from_chord2,
    chunks,
    coords,
    cos_sin,
    may_reach,
    refine_max,
)
from urdfpost.machine import Machine
from urdfpost.program import Program, rewind_moves
from urdfpost.tolerances import Tolerances
from urdfpost.toolpath import Toolpath

log = logging.getLogger(__name__)

_SAMPLES = 16

_NEGLIGIBLE = 1e-9
"""Share of a tolerance below which a deviation is not refined (when nothing larger is seen)."""


@dataclass(frozen=True)
class Verification:
    """What verification measured (lengths mm, angles degrees).

    Attributes
    ----------
    ok : bool
        Every CL point reached, tip and orientation deviations within tolerance.
    cl_points : int
    reached : int
    missed_lines : list of int
        CL source lines of the points the program does not reach (in order).
    blocks : int
        Motion blocks in the program.
    max_tip_deviation, mean_tip_deviation : float, mm
    max_orientation_deviation_deg : float
    max_rotary_step_deg : dict
        Largest step of each rotary axis between consecutive blocks.
    tip_tolerance : float, mm
    orientation_tolerance_deg : float
    worst_cl_line : int or None
        CL line nearest the worst tip deviation.
    tcp : bool
    """

    ok: bool
    cl_points: int
    reached: int
    missed_lines: list[int]
    blocks: int
    max_tip_deviation: float
    mean_tip_deviation: float
    max_orientation_deviation_deg: float
    max_rotary_step_deg: dict[str, float]
    tip_tolerance: float
    orientation_tolerance_deg: float
    worst_cl_line: int | None
    tcp: bool
    notes: list[str] = field(default_factory=list)

    def as_dict(self) -> dict:
        """Plain data for JSON reports."""
        return asdict(self)

    def summary(self, units: str = "mm") -> str:
        """One paragraph for people, lengths in ``units``."""
        scale = 25.4 if units == "inch" else 1.0
        fmt = ".5f" if units == "inch" else ".4f"
        steps = ", ".join(f"{k} {v:.3f}" for k, v in self.max_rotary_step_deg.items())
        verdict = "within tolerance" if self.ok else "BEYOND TOLERANCE"
        return (
            f"verification {verdict}: {self.reached}/{self.cl_points} CL points reached, "
            f"{self.blocks} blocks; tool tip deviation max {self.max_tip_deviation / scale:{fmt}} "
            f"mean {self.mean_tip_deviation / scale:{fmt}} {units} (tolerance "
            f"{self.tip_tolerance / scale:{fmt}}); tool axis deviation max "
            f"{self.max_orientation_deviation_deg:.4f} deg (tolerance "
            f"{self.orientation_tolerance_deg:.3f}); largest rotary step {steps or 'none'} deg"
        )


def program_joints(machine: Machine, program: Program) -> tuple[np.ndarray, np.ndarray]:
    """Joint values and rapid flags of a program's moves (from :meth:`Program.move_table`).

    Axes the program never writes stay at the machine's home; values not yet programmed at
    the start are taken from home too.

    Returns
    -------
    values : ndarray, shape (N, m)
        Machine axis order; X Y Z in mm (tool tip in workpiece coordinates for TCP programs),
        rotary in rad.
    rapid : ndarray, shape (N,), bool
    """
    unknown = [a for a in program.axes if a not in machine.axis_names]
    if unknown:
        raise DialectError(
            f"program {program.name} writes axes {' '.join(unknown)} that machine "
            f"{machine.name} does not have ({' '.join(machine.axis_names)})"
        )
    table = program.move_table()
    pos = table.position
    values = np.tile(machine.home, (len(table), 1))
    for j, name in enumerate(program.axes):
        col = machine.axis_names.index(name)
        column = pos[:, j]
        if name in program.rotary:
            column = np.radians(column)
        # forward fill NaN (modal value not yet programmed), home before the first value
        ok = ~np.isnan(column)
        idx = np.where(ok, np.arange(len(column)), -1)
        idx = np.maximum.accumulate(idx)
        filled = np.where(idx >= 0, column[np.maximum(idx, 0)], values[:, col])
        values[:, col] = filled
    rapid = table.rapid.copy()
    return values, rapid


def _row_poses(
    machine: Machine, values: np.ndarray, tcp: bool, tool_length: float, pivot: float
) -> RowPoses:
    """The measured point (``pivot`` up the tool axis from the tip) and axis of program rows.

    In TCP programs the linear values are the tip: only the rotary axes go through the
    kinematics (with the linear ones at 0, which do not turn the tool axis).
    """
    if not tcp:
        return RowPoses.of(machine, values, tool_length - pivot)
    q = values.copy()
    lin = list(machine.linear_columns)
    q[:, lin] = 0.0
    poses = RowPoses.of(machine, q, 0.0)
    return replace(poses, tip=values[:, lin] + pivot * poses.axis)


_REACH = 64 + 256 + 1024 + 4096
"""Rows after the previous match that the search for a CL point looks at."""

_WINDOWS = (2, 14, 48, 256, 1024, 4096)
"""Successive pieces of those rows searched (most CL points are reached within the first)."""

_NEAR = 2
"""Pieces of :data:`_WINDOWS` searched from a guessed start (the first 16 rows)."""

_RUN = 8192
"""Most CL points :func:`_match` takes at once (every round looks at the rest of the run)."""

_ROUNDS = 16
"""Rounds of :func:`_match` before a run of CL points is cut at its exact prefix."""

_SEQUENTIAL = 256
"""CL points taken one at a time, at most, per round of :func:`_match`."""

_PAIRS = 1 << 20
"""Largest (CL point, row) distance matrix built at once."""

_UNKNOWN = -2


def _first_reaching(
    cl_tip: np.ndarray,
    cl_axis: np.ndarray,
    tip: np.ndarray,
    axis: np.ndarray,
    tol: Tolerances,
    js: np.ndarray,
    start: np.ndarray,
    windows: tuple[int, ...] = _WINDOWS,
) -> np.ndarray:
    """For CL points ``js``, the first row at or after ``start`` that reaches each (tip within
    tolerance, axis within the orientation tolerance), searching the rows ``windows`` cover.

    Returns
    -------
    ndarray, shape of ``js``, int
        The row; -1 when none does and ``windows`` cover :data:`_REACH` rows or the rest of
        the program, ``_UNKNOWN`` when they cover fewer.
    """
    n = len(tip)
    out = np.full(len(js), -1)
    todo = np.flatnonzero(start < n)
    lo = 0
    for width in windows:
        off = np.arange(lo, lo + width)
        step = max(1, _PAIRS // width)
        left = []
        for part in range(0, len(todo), step):
            sub = todo[part : part + step]
            rows = start[sub, None] + off
            safe = np.minimum(rows, n - 1)
            j = js[sub, None]
            hit = (np.linalg.norm(tip[safe] - cl_tip[j], axis=2) <= tol.tip) & (rows < n)
            near = np.nonzero(hit)
            hit[near] = angle_between(axis[safe[near]], cl_axis[j[near[0], 0]]) <= tol.orientation
            found = hit.any(axis=1)
            out[sub[found]] = rows[found, np.argmax(hit[found], axis=1)]
            left.append(sub[~found & (start[sub] + lo + width < n)])
        todo = np.concatenate(left) if left else todo
        lo += width
        if not todo.size:
            break
    out[todo] = _UNKNOWN if lo < _REACH else -1
    return out


def _walk(cl_tip: np.ndarray, tip: np.ndarray, js: np.ndarray, k: np.ndarray) -> np.ndarray:
    """Rows ``k`` moved on while the next row is strictly nearer to CL points ``js`` (distances
    computed as the search computes them), a few rows at a time and then more."""
    n = len(tip)
    k = k.copy()
    active = np.arange(len(k))
    width = 4
    while active.size:
        rows = k[active, None] + np.arange(width)
        dist = np.linalg.norm(tip[np.minimum(rows, n - 1)] - cl_tip[js[active], None], axis=2)
        dist[rows >= n] = np.inf  # past the end: not nearer
        stop = ~(dist[:, 1:] < dist[:, :-1])
        stops = stop.any(axis=1)
        k[active] += np.where(stops, np.argmax(stop, axis=1), width - 1)
        active = active[~stops]
        width = min(8 * width, 4096)
    return k


def _starts(m: np.ndarray, ptr: int) -> np.ndarray:
    """Where the search for each point of a run starts, given the results known so far.

    The last match before a point, ``ptr`` before the first; a point whose result is not known
    yet counts as a match one row on (one row per CL point, what a program usually has).
    """
    index = np.arange(len(m))
    known = np.maximum.accumulate(np.where(m >= 0, index, -1))  # last match at or before
    base = np.where(known >= 0, m[np.maximum(known, 0)], ptr)
    unknown = np.cumsum(m == _UNKNOWN)
    since = unknown - np.where(known >= 0, unknown[np.maximum(known, 0)], 0)
    after = base + since  # the start for the point after each
    return np.concatenate([[ptr], after[:-1]])


def _match(
    cl_tip: np.ndarray,
    cl_axis: np.ndarray,
    tip: np.ndarray,
    axis: np.ndarray,
    tol: Tolerances,
) -> np.ndarray:
    """For each CL point, the program point at or after the previous match that reaches it (tip
    within tolerance, axis within orientation tolerance; the nearest of a run of such points),
    or -1.

    The definition is sequential: with ``ptr = 0``, for each CL point j in turn, ``m_j`` is the
    first row in ``[ptr, ptr + _REACH)`` that reaches it, walked on while the next row is
    strictly nearer (CL points closer together than the tolerance); ``ptr = m_j`` when there
    is one, else ``ptr`` stays. So ``m_j = F_j(ptr_j)``, a function of the start alone, and
    ``ptr_{j+1}`` is the last match up to j.

    It is computed for runs of CL points at once as a fixed point. Guess every start (one row
    per CL point after the last match known), evaluate ``F_j`` there over the first rows only
    (most points are reached within them; the others are unknown), set the guesses from the
    results (:func:`_starts`), and repeat, evaluating again only where a guess changed. The
    first point whose guess differs from its recomputed start, or whose result is unknown, has
    an exact start (every point before it is consistent, and the run starts at the exact
    ``ptr``): it is searched from there, and so is every point after it, one at a time, until
    one is reached within the first rows of its search (after missed CL points, or long runs
    of inserted rows); the guesses after that follow from it again. When every result is known
    and every guess equals its start, the recurrence holds at every point, and its solution
    from the exact first start is unique: it is the sequential answer. A run that needs many
    rounds is cut at its exact prefix and the runs get shorter.

    Returns
    -------
    ndarray, shape (n_cl,), int
    """
    n_cl = len(cl_tip)
    out = np.full(n_cl, -1)
    ptr, j0, size = 0, 0, 1024

    def evaluate(i: np.ndarray, start: np.ndarray, windows: tuple[int, ...]) -> None:
        """Results of points i from the given starts: first row reaching, and walked on."""
        hit = _first_reaching(cl_tip, cl_axis, tip, axis, tol, js[i], start, windows)
        first[i], done_for[i] = hit, start
        ok = hit >= 0
        hit[ok] = _walk(cl_tip, tip, js[i][ok], hit[ok])
        m[i] = hit

    def holds(i: np.ndarray | int, start: np.ndarray | int) -> np.ndarray | bool:
        """Whether the results of points i hold for these starts: computed for them, or for
        an earlier start with the first row reaching at or after them (nothing in between)."""
        return (done_for[i] == start) | (
            (done_for[i] >= 0) & (start > done_for[i]) & (first[i] >= start)
        )

    while j0 < n_cl:
        js = np.arange(j0, min(j0 + size, n_cl))
        k = len(js)
        guess = ptr + np.arange(k)
        m = np.full(k, _UNKNOWN)  # results
        first = np.full(k, _UNKNOWN)  # first rows reaching (before the walk)
        done_for = np.full(k, -1)  # the start each result was computed for
        exact, rounds = 0, 0  # the points before exact are final
        while rounds < _ROUNDS:
            rounds += 1
            stale = np.flatnonzero(done_for != guess)
            same = holds(stale, guess[stale])
            done_for[stale[same]] = guess[stale[same]]
            stale = stale[~same]
            evaluate(stale, guess[stale], _WINDOWS[:_NEAR])
            start = _starts(m, ptr)
            off = np.flatnonzero((start != guess) | (m == _UNKNOWN))
            if not off.size:
                exact = k
                break
            e, s = int(off[0]), int(start[off[0]])
            for _ in range(_SEQUENTIAL):  # e's start s is exact
                if not holds(e, s):
                    evaluate(np.array([e]), np.array([s]), _WINDOWS[:_NEAR])
                if m[e] == _UNKNOWN:
                    evaluate(np.array([e]), np.array([s]), (_REACH,))
                done_for[e] = guess[e] = s
                s = int(m[e]) if m[e] >= 0 else s
                e += 1
                if e == k or (holds(e, s) and m[e] != _UNKNOWN):
                    break  # the next result holds: back to the rounds
            exact = e
            guess[e:] = _starts(m, ptr)[e:]
        out[js[:exact]] = m[:exact]
        if exact == k:
            ptr, j0 = int(_starts(np.append(m, _UNKNOWN), ptr)[-1]), int(js[-1]) + 1
            size = min(2 * size, _RUN) if rounds <= 3 else max(16, size // 2)
        else:  # too many rounds: start again from the exact prefix
            ptr, j0 = int(guess[exact]), int(js[exact])
            size = max(16, size // 4)
    return out


def _sampled_once(rows: np.ndarray) -> Vec:
    """Rows of an (n, 3) array as coordinate arrays of shape (1, n): one sample of n blocks."""
    x, y, z = coords(rows)
    return x[None], y[None], z[None]


@dataclass(frozen=True)
class _Polyline:
    """The CL path as segments: segment j runs from CL point j to j + 1 (the last is a point).

    Attributes
    ----------
    segments : Segments
        Of the tips (mm).
    arcs : Arcs
        Of the tool axes (slerp).
    """

    segments: Segments
    arcs: Arcs

    @classmethod
    def of(cls, tip: np.ndarray, axis: np.ndarray) -> _Polyline:
        """The polyline of CL points ``tip`` and axes ``axis``, shape (n, 3)."""
        nxt = np.minimum(np.arange(len(tip)) + 1, len(tip) - 1)
        return cls(Segments.between(tip, tip[nxt]), Arcs.between(axis, axis[nxt]))

    def __len__(self) -> int:
        return len(self.arcs.omega)


def _span_deviation(
    points: Vec, axes: Vec, polyline: _Polyline, ja: np.ndarray, jb: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Distance of sample points from the CL polyline between CL indices ``ja`` and ``jb``, and
    of their tool axes from the CL axis interpolated (slerp) at the nearest place.

    Parameters
    ----------
    points, axes : Vec
        Coordinate arrays of shape (s, n): s samples of n blocks.
    polyline : _Polyline
    ja, jb : ndarray, shape (n,), int
        CL span of each block (``jb >= ja``).

    Returns
    -------
    dist2 : ndarray, shape (s, n), mm^2
        Squared distance from the nearest segment of the span (the first of equals).
    chord2 : ndarray, shape (s, n)
        Squared chord between the tool axis and the CL axis there (see
        :func:`urdfpost.linearize.angle_from_chord2`).
    """
    span = np.maximum(jb - ja, 1)
    last = len(polyline) - 1
    dist2 = chord2 = np.zeros(0)
    for off in range(int(span.max(initial=1))):
        cols = np.flatnonzero(span > off) if off else slice(None)
        a = np.minimum(ja[cols] + off, last)
        pts = points if off == 0 else (points[0][:, cols], points[1][:, cols], points[2][:, cols])
        axs = axes if off == 0 else (axes[0][:, cols], axes[1][:, cols], axes[2][:, cols])
        d2, u = polyline.segments.take(a).distance2(pts)
        arc = polyline.arcs.take(a)
        c2 = arc.chord2(axs, *cos_sin(u * arc.omega))
        if off == 0:
            dist2, chord2 = d2, c2
            continue
        better = d2 < dist2[:, cols]
        dist2[:, cols] = np.where(better, d2, dist2[:, cols])
        chord2[:, cols] = np.where(better, c2, chord2[:, cols])
    return dist2, chord2


@dataclass(frozen=True)
class _Blocks:
    """The feed blocks of a program, and how to evaluate them anywhere.

    Block i moves from program row ``start[i]`` to ``start[i] + 1`` and is compared with the CL
    span ``ja[i] .. jb[i]``.
    """

    machine: Machine
    values: np.ndarray
    rows: RowPoses
    start: np.ndarray
    ja: np.ndarray
    jb: np.ndarray
    polyline: _Polyline
    tcp: bool
    tool_length: float
    pivot: float

    def errors(self, blocks: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Squared distance and chord (:func:`_span_deviation`) of blocks at parameters t.

        Parameters
        ----------
        blocks : ndarray, shape (k,), int
        t : ndarray, shape (s,) (the same for every block) or (s, k)

        Returns
        -------
        dist2, chord2 : ndarray, shape (s, k)
        """
        q0, q1 = self.values[self.start[blocks]], self.values[self.start[blocks] + 1]
        length = self.tool_length - self.pivot
        p, axis = tip_and_axis_along(self.machine, q0, q1, t, length, with_tip=not self.tcp)
        if p is None:  # TCP: the control moves the tip on the straight line
            lin = list(self.machine.linear_columns)
            p0, dp = q0[:, lin], q1[:, lin] - q0[:, lin]
            tt = t[:, None] if t.ndim == 1 else t
            p = tuple(p0[:, i] + tt * dp[:, i] + self.pivot * axis[i] for i in range(3))
        return _span_deviation(
            p,  # type: ignore[arg-type]
            axis,
            self.polyline,
            self.ja[blocks],
            self.jb[blocks],
        )

    def bounds(
        self, blocks: np.ndarray, dist2: np.ndarray, chord2: np.ndarray, h: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """Upper bounds on the tip deviation (mm) and on the chord of the axis deviation over
        each whole block, from its samples (evenly spaced h apart, both ends included).

        Where a block is compared with one CL segment:

        - the tip deviation is the distance of the point p(t) from the segment, a convex and
          1-Lipschitz function of p; with ``|p''| <= M`` (:func:`interpolation_bounds`; in TCP
          programs p is the straight line plus the pivot times the tool axis) it is at most
          the larger of two neighbouring samples plus ``M h^2 / 8`` between them;
        - the chord ``|a(t) - e(t)|`` between the tool axis a and the CL axis e (the slerp at
          the clipped projection parameter s of p on the segment: a kink where the clip
          starts, so no curvature bound) changes at most at the speed ``|a'| + omega |s'|``,
          with ``|s'| <= |p'| / |segment|``: between two samples it is at most their mean plus
          that speed times h / 2.

        A block compared with more than one CL segment gets no bound (infinite).

        Returns
        -------
        tip, chord : ndarray, shape (k,)
        """
        r = self.rows
        a, b = self.start[blocks], self.start[blocks] + 1
        q0, q1 = self.values[a], self.values[b]
        tip_speed, tip_curv, axis_speed, axis_curv = interpolation_bounds(
            self.machine, q0, q1, r.reach[a], r.reach[b], r.swing[a], r.swing[b]
        )
        if self.tcp:
            lin = list(self.machine.linear_columns)
            chord = np.linalg.norm(q1[:, lin] - q0[:, lin], axis=1)
            tip_speed = chord + abs(self.pivot) * axis_speed
            tip_curv = abs(self.pivot) * axis_curv
        ja = self.ja[blocks]
        inv_length = np.sqrt(self.polyline.segments.inv_dd[ja])  # 0 for a point
        spin = self.polyline.arcs.omega[ja] * tip_speed * inv_length
        g = np.sqrt(chord2)
        tip_bound = np.sqrt(dist2.max(axis=0)) + tip_curv * (h * h / 8.0)
        chord_bound = 0.5 * (g[1:] + g[:-1]).max(axis=0) + (axis_speed + spin) * (h / 2.0)
        one = self.jb[blocks] - ja <= 1
        return np.where(one, tip_bound, np.inf), np.where(one, chord_bound, np.inf)


def _block_deviation(
    feed: _Blocks, tip_level: float, chord2_level: float
) -> tuple[np.ndarray, float, int, float]:
    """Deviation of every feed block, sampled and refined where it can matter.

    Every block is sampled at ``_SAMPLES + 2`` evenly spaced parameters, its ends included. The
    worst samples are refined by golden-section search (:func:`refine_max`) in the blocks where
    that could change what verification reports: where the bound of :meth:`_Blocks.bounds`
    reaches the largest deviation sampled in any block, or the level given (the largest at the
    program points). Elsewhere the refined value would stay below that, so the reported maxima
    (and the block they are in) are those of refining every block.

    Parameters
    ----------
    feed : _Blocks
    tip_level : float, mm
        No block needs refining below this tip deviation.
    chord2_level : float
        Likewise for the squared axis chord.

    Returns
    -------
    tip : ndarray, shape (n,), mm
        Largest tip deviation seen per block.
    total : float, mm
        Sum of the sampled tip deviations.
    count : int
        Number of samples.
    chord2 : float
        Largest squared axis chord seen in any block.
    """
    n = len(feed.start)
    t = np.linspace(0.0, 1.0, _SAMPLES + 2)
    h = float(t[1] - t[0])
    best = (np.zeros(n), np.zeros(n))
    worst = (np.zeros(n, dtype=int), np.zeros(n, dtype=int))
    bound = (np.zeros(n), np.zeros(n))
    total = 0.0
    for part in chunks(n, len(t)):
        blocks = np.arange(part.start, part.stop)
        dist2, chord2 = feed.errors(blocks, t)
        total += float(np.sqrt(dist2).sum())
        cols = np.arange(len(blocks))
        for i, e in enumerate((dist2, chord2)):
            worst[i][part] = np.argmax(e, axis=0)
            best[i][part] = e[worst[i][part], cols]
        bound[0][part], bound[1][part] = feed.bounds(blocks, dist2, chord2, h)
    levels = (
        max(float(np.sqrt(best[0].max(initial=0.0))), tip_level),
        float(np.sqrt(max(best[1].max(initial=0.0), chord2_level))),
    )
    wanted = (may_reach(bound[0], levels[0]), may_reach(bound[1], levels[1]))
    todo = np.flatnonzero(wanted[0] | wanted[1])
    log.debug(
        "verify: %d blocks, tip refined in %d, orientation in %d",
        n,
        wanted[0].sum(),
        wanted[1].sum(),
    )
    for part in chunks(len(todo), 4):  # four evaluations per block at a time
        sub = todo[part]

        def errors(
            idx: np.ndarray, tt: np.ndarray, sub: np.ndarray = sub
        ) -> tuple[np.ndarray, np.ndarray]:
            dist2, chord2 = feed.errors(sub[idx], tt[None, :])
            return dist2[0], chord2[0]

        refined = refine_max(
            errors,
            t,
            (worst[0][sub], worst[1][sub]),
            (best[0][sub], best[1][sub]),
            (wanted[0][sub], wanted[1][sub]),
        )
        best[0][sub], best[1][sub] = refined
    return np.sqrt(best[0]), total, n * len(t), float(best[1].max(initial=0.0))


def verify(
    program: Program,
    machine: Machine,
    toolpath: Toolpath,
    *,
    tool_length: float | None = None,
    tol: Tolerances | None = None,
    pivot: float = 0.0,
) -> Verification:
    """Run a program through the machine and compare it with the CL data.

    Parameters
    ----------
    program : Program
        As written, or as read back from text by a dialect.
    machine : Machine
    toolpath : Toolpath
        The CL data the program was made from.
    tool_length : float, optional, mm
        Tool length machine-coordinate positions include (default: the program's).
    tol : Tolerances, optional
    pivot : float, mm
        Measure the point this far up the tool axis from the tip instead of the tip, on both
        sides (the ball centre of a ball-end tool, about which a strategy that bends the tool
        axis pivots). 0 measures the tip.

    Returns
    -------
    Verification
    """
    tol = tol or Tolerances.for_units(program.units)
    tool_length = program.tool_length if tool_length is None else tool_length
    values, rapid = program_joints(machine, program)
    notes: list[str] = []
    # a rewind leaves the CL path on purpose (lift, turn, return): checked like a rapid, by
    # its end points only
    rewind = rewind_moves(program)
    if rewind.any():
        rapid = rapid | rewind
        notes.append(f"{int(rewind.sum())} rewind moves are not compared with the CL path")
    n_cl = len(toolpath)
    if len(values) == 0 or n_cl == 0:
        return Verification(
            ok=n_cl == 0,
            cl_points=n_cl,
            reached=0,
            missed_lines=[int(x) for x in toolpath.line],
            blocks=len(values),
            max_tip_deviation=0.0,
            mean_tip_deviation=0.0,
            max_orientation_deviation_deg=0.0,
            max_rotary_step_deg={},
            tip_tolerance=tol.tip,
            orientation_tolerance_deg=float(np.degrees(tol.orientation)),
            worst_cl_line=None,
            tcp=program.tcp,
            notes=["program has no motion"] if len(values) == 0 else ["CL data has no motion"],
        )
    rows = _row_poses(machine, values, program.tcp, tool_length, pivot)
    tip, axis = rows.tip, rows.axis
    cl_tip = toolpath.tip + pivot * toolpath.axis
    match = _match(cl_tip, toolpath.axis, tip, axis, tol)
    reached = match >= 0
    missed_lines = [int(x) for x in toolpath.line[~reached]]

    # CL span of every program point: last CL index matched at or before it, first after it
    owner = np.full(len(values), -1)
    owner[match[reached]] = np.flatnonzero(reached)
    before = np.maximum.accumulate(np.where(owner >= 0, owner, -1))
    after_src = np.where(owner >= 0, owner, n_cl)
    after = np.minimum.accumulate(after_src[::-1])[::-1]

    # the block ends themselves (rapids included) against their CL span
    ja_pt = np.maximum(before, 0)
    jb_pt = np.where(after < n_cl, after, n_cl - 1)
    jb_pt = np.maximum(jb_pt, ja_pt)
    at_rows = (_sampled_once(tip), _sampled_once(axis))
    polyline = _Polyline.of(cl_tip, toolpath.axis)
    dp2, op2 = _span_deviation(*at_rows, polyline, ja_pt, jb_pt)
    feed_pts = ~rapid | (owner >= 0)
    dp, op2 = np.sqrt(dp2[0, feed_pts]), op2[0, feed_pts]

    blocks = np.flatnonzero(~rapid[1:]) + 1  # feed block k joins program points k-1 and k
    blocks = blocks[(before[blocks - 1] >= 0) & (after[blocks] < n_cl)]
    ja = before[blocks - 1]
    feed = _Blocks(
        machine=machine,
        values=values,
        rows=rows,
        start=blocks - 1,
        ja=ja,
        jb=np.maximum(after[blocks], ja),
        polyline=polyline,
        tcp=program.tcp,
        tool_length=tool_length,
        pivot=pivot,
    )
    # what no block needs refining for: the largest deviation at a program point, or (when
    # there is next to none) a billionth of the tolerance
    tip_level = max(dp.max(initial=0.0), _NEGLIGIBLE * tol.tip)
    chord2_level = max(op2.max(initial=0.0), (2.0 * np.sin(_NEGLIGIBLE * tol.orientation / 2)) ** 2)
    dmax, dsum, count, omax = _block_deviation(feed, tip_level, chord2_level)
    max_tip = float(max(dmax.max(initial=0.0), dp.max(initial=0.0)))
    mean_tip = (dsum + float(dp.sum())) / max(count + dp.size, 1)
    max_ori = float(angle_from_chord2(max(omax, float(op2.max(initial=0.0)))))
    worst_line = None
    if len(blocks) and dmax.max() >= dp.max(initial=0.0):
        worst_line = int(toolpath.line[before[blocks[int(np.argmax(dmax))] - 1]])
    elif dp.size:
        worst_line = int(toolpath.line[ja_pt[feed_pts][int(np.argmax(dp))]])

    steps: dict[str, float] = {}
    for a in machine.rotary:
        col = machine.axis_names.index(a.name)
        steps[a.name] = float(np.degrees(np.abs(np.diff(values[:, col])).max(initial=0.0)))
    ok = not missed_lines and max_tip <= tol.tip and max_ori <= tol.orientation
    if missed_lines:
        notes.append(f"{len(missed_lines)} CL points not reached, first at line {missed_lines[0]}")
    return Verification(
        ok=bool(ok),
        cl_points=n_cl,
        reached=int(reached.sum()),
        missed_lines=missed_lines,
        blocks=len(values),
        max_tip_deviation=max_tip,
        mean_tip_deviation=float(mean_tip),
        max_orientation_deviation_deg=float(np.degrees(max_ori)),
        max_rotary_step_deg=steps,
        tip_tolerance=tol.tip,
        orientation_tolerance_deg=float(np.degrees(tol.orientation)),
        worst_cl_line=worst_line,
        tcp=program.tcp,
        notes=notes,
    )
