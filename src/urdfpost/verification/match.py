"""Matching a program's rows to the CL points they reach, and the poses of its rows.

A program reaches a CL point where one of its rows has the tool tip within the tip tolerance of
it and the tool axis within the orientation tolerance of its axis. The rows are searched in
order (:func:`match_points`): each CL point from the row the point before reached, at most
:data:`REACH` rows on. The rows' joint values come from the program's move table
(:func:`program_joints`) and their poses from the forward kinematics
(:func:`row_poses_at_tip`, :func:`at_pivot`; :func:`row_points` where only the matching needs
them).

The deviation between the rows (the blocks) is :mod:`urdfpost.verification.measure`; the streamed
verifier (:func:`urdfpost.posting.readback.verify_stream`) cuts its pieces where this matching can
be cut.
"""

from __future__ import annotations

import logging
from dataclasses import replace
from types import ModuleType

import numpy as np

from urdfpost._compiled import Kernels
from urdfpost.errors import DialectError
from urdfpost.geometry import VecArrays, angle_between, coords
from urdfpost.kinematics.forward import tip_and_axis
from urdfpost.linearize import RowPoses
from urdfpost.machine import Machine
from urdfpost.program import Program
from urdfpost.tolerances import Tolerances

log = logging.getLogger(__name__)


def program_joints(machine: Machine, program: Program) -> tuple[np.ndarray, np.ndarray]:
    """Joint values and rapid flags of a program's moves (from :meth:`Program.move_table`).

    Axes the program never writes stay at the machine's home; values not yet programmed at
    the start are taken from home too.

    Parameters
    ----------
    machine : Machine
    program : Program
        As written, or as read back from text by a dialect.

    Returns
    -------
    values : ndarray, shape (N, m)
        Machine axis order; X Y Z in mm (tool tip in workpiece coordinates for TCP programs),
        rotary in rad.
    rapid : ndarray, shape (N,), bool

    Raises
    ------
    DialectError
        The program writes an axis the machine does not have.
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
        first = int(ok.argmax()) if len(ok) else 0
        if ok[first:].all():  # (the common case: NaN only before the first value)
            values[first:, col] = column[first:]
            continue
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

    :func:`at_pivot` of :func:`row_poses_at_tip`.
    """
    return at_pivot(row_poses_at_tip(machine, values, tcp, tool_length), pivot)


def row_poses_at_tip(
    machine: Machine, values: np.ndarray, tcp: bool, tool_length: float
) -> RowPoses:
    """Tool tip and axis of program rows, and the reach and swing that bound the blocks.

    In TCP programs the linear values are the tip: only the rotary axes go through the
    kinematics (with the linear ones at 0, which do not turn the tool axis).

    Parameters
    ----------
    machine : Machine
    values : ndarray, shape (N, m)
        Joint values of the rows (:func:`program_joints`), mm / rad.
    tcp : bool
        The program is a TCP program (its linear values are the tool tip).
    tool_length : float, mm
        The tool length machine-coordinate positions include (not used in TCP programs).

    Returns
    -------
    RowPoses
        Arrays of N rows; tip in mm, in the workpiece frame.
    """
    if not tcp:
        return RowPoses.of(machine, values, tool_length)
    poses = RowPoses.of(machine, _rotary_only(machine, values), 0.0)
    return replace(poses, tip=values[:, list(machine.linear_columns)])


def _rotary_only(machine: Machine, values: np.ndarray) -> np.ndarray:
    """``values`` (N, m) with the linear axes at 0: the rotary axes of TCP rows, which alone
    turn the tool axis (their linear values are the tip)."""
    q = values.copy()
    q[:, list(machine.linear_columns)] = 0.0
    return q


def row_points(
    machine: Machine, values: np.ndarray, tcp: bool, tool_length: float, pivot: float = 0.0
) -> tuple[np.ndarray, np.ndarray]:
    """The measured point and the tool axis of program rows: those of :func:`at_pivot` of
    :func:`row_poses_at_tip`, the same values, without the reach and swing that only bound
    the blocks (what :func:`match_points` needs, for less work).

    Parameters
    ----------
    machine : Machine
    values : ndarray, shape (N, m)
        Joint values of the rows (:func:`program_joints`), mm / rad.
    tcp : bool
        The program is a TCP program (its linear values are the tool tip).
    tool_length : float, mm
        The tool length machine-coordinate positions include (not used in TCP programs).
    pivot : float, mm
        How far up the tool axis the measured point is (0: the tip).

    Returns
    -------
    point, axis : ndarray, shape (N, 3)
        Point in mm, in the workpiece frame; unit tool axis.
    """
    if tcp:
        _, axis = tip_and_axis(machine, _rotary_only(machine, values), 0.0)
        point = values[:, list(machine.linear_columns)]
    else:
        point, axis = tip_and_axis(machine, values, tool_length)
    return (point if pivot == 0.0 else point + pivot * axis), axis


def at_pivot(rows: RowPoses, pivot: float) -> RowPoses:
    """Poses of the point ``pivot`` up the tool axis from the tip of ``rows``.

    The reach grows by at most ``|pivot|`` times the swing (the part of ``pivot`` times the
    tool axis across each rotary axis' line): an upper bound, which is what the bounds of
    the deviation between samples (:mod:`urdfpost.verification.measure`) need.

    Parameters
    ----------
    rows : RowPoses
        At the tool tip (:func:`row_poses_at_tip`).
    pivot : float, mm
        How far up the tool axis the measured point is (0: the tip; ``rows`` are returned).

    Returns
    -------
    RowPoses
    """
    if pivot == 0.0:
        return rows
    return RowPoses(
        rows.tip + pivot * rows.axis, rows.axis, rows.reach + abs(pivot) * rows.swing, rows.swing
    )


REACH = 64 + 256 + 1024 + 4096
"""Rows after the previous match that the search for a CL point looks at (:func:`match_points`):
a CL point no row reaches within them is missed. Whoever cuts a program and its CL data in
pieces to match them apart (:func:`urdfpost.posting.readback.verify_stream`) keeps this many rows
after a cut on the first side."""

_WINDOWS = (2, 14, 48, 256, 1024, 4096)
"""Successive pieces of those rows searched (most CL points are reached within the first)."""

_NEAR = 2
"""Pieces of :data:`_WINDOWS` searched from a guessed start (the first 16 rows)."""

_RUN = 8192
"""Most CL points :func:`match_points` takes at once (every round looks at the rest of the run)."""

_ROUNDS = 16
"""Rounds of :func:`match_points` before a run of CL points is cut at its exact prefix."""

_SEQUENTIAL = 256
"""CL points taken one at a time, at most, per round of :func:`match_points`."""

_PAIRS = 1 << 20
"""Largest (CL point, row) distance matrix built at once."""

_UNKNOWN = -2


def _distance(tip: VecArrays, cl_tip: VecArrays, rows: np.ndarray, js: np.ndarray) -> np.ndarray:
    """Distances of program rows from CL points (as ``np.linalg.norm`` computes them).

    Parameters
    ----------
    tip, cl_tip : VecArrays
        Coordinate arrays of the program rows' and the CL points' tips, mm.
    rows : ndarray, shape (k, w), int
    js : ndarray, shape (k, 1), int

    Returns
    -------
    ndarray, shape (k, w), mm
    """
    d = tip[0][rows] - cl_tip[0][js]
    out = d * d
    for i in (1, 2):
        np.subtract(tip[i][rows], cl_tip[i][js], out=d)
        d *= d
        out += d
    return np.sqrt(out, out=out)


def _first_reaching(
    cl_tip: VecArrays,
    cl_axis: np.ndarray,
    tip: VecArrays,
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
        The row; -1 when none does and ``windows`` cover :data:`REACH` rows or the rest of
        the program, ``_UNKNOWN`` when they cover fewer.
    """
    n = len(tip[0])
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
            hit = (_distance(tip, cl_tip, safe, j) <= tol.tip) & (rows < n)
            near = np.nonzero(hit)
            hit[near] = angle_between(axis[safe[near]], cl_axis[j[near[0], 0]]) <= tol.orientation
            found = hit.any(axis=1)
            out[sub[found]] = rows[found, np.argmax(hit[found], axis=1)]
            left.append(sub[~found & (start[sub] + lo + width < n)])
        todo = np.concatenate(left) if left else todo
        lo += width
        if not todo.size:
            break
    out[todo] = _UNKNOWN if lo < REACH else -1
    return out


def _nearness(
    tip: VecArrays,
    cl_tip: VecArrays,
    axis: VecArrays,
    cl_axis: VecArrays,
    tol: Tolerances,
    rows: np.ndarray,
    js: np.ndarray,
) -> np.ndarray:
    """How near program rows are to CL points, in shares of the tolerances: the larger of the
    tip distance over ``tol.tip`` and the axis angle over ``tol.orientation`` (at most 1 for a
    row that reaches the point).

    Both count: where the tip stands still (a reorientation in place) the tip distances of
    the rows differ by rounding only, and the axis tells which row is at the CL point.

    Parameters
    ----------
    tip, cl_tip : VecArrays
        Coordinate arrays of the program rows' and the CL points' tips, mm.
    axis, cl_axis : VecArrays
        Of their unit tool axes.
    tol : Tolerances
    rows : ndarray, shape (k, w), int
    js : ndarray, shape (k, 1), int

    Returns
    -------
    ndarray, shape (k, w)
    """
    dist = _distance(tip, cl_tip, rows, js)
    dist /= tol.tip
    chord = _distance(axis, cl_axis, rows, js)  # the angle is 2 arcsin(chord / 2)
    chord *= 0.5
    np.minimum(chord, 1.0, out=chord)
    angle = np.arcsin(chord, out=chord)
    angle *= 2.0 / tol.orientation
    return np.maximum(dist, angle, out=dist)


def nearness(
    tip: np.ndarray, axis: np.ndarray, cl_tip: np.ndarray, cl_axis: np.ndarray, tol: Tolerances
) -> np.ndarray:
    """How near program rows are to CL points, pair by pair, in shares of the tolerances
    (:func:`_nearness`: at most 1 where the row reaches the point).

    Parameters
    ----------
    tip, axis : ndarray, shape (k, 3)
        The program rows' measured points (mm) and unit tool axes.
    cl_tip, cl_axis : ndarray, shape (k, 3)
        The CL points' (mm) and their unit tool axes.
    tol : Tolerances

    Returns
    -------
    ndarray, shape (k,)
    """
    pairs = np.arange(len(tip))[:, None]
    got = _nearness(coords(tip), coords(cl_tip), coords(axis), coords(cl_axis), tol, pairs, pairs)
    return got[:, 0]


def _walk(
    cl_xyz: VecArrays,
    xyz: VecArrays,
    cl_ijk: VecArrays,
    ijk: VecArrays,
    tol: Tolerances,
    js: np.ndarray,
    k: np.ndarray,
    handoff: bool = False,
) -> np.ndarray:
    """Rows ``k``, each reaching its CL point of ``js``, moved to the nearest row
    (:func:`_nearness`, the first of equals) of the run of rows from there whose nearness is
    at most 1 (within both tolerances), looked at a few rows at a time and then more.

    The nearest of the whole run, not the first row after which the next is not nearer: where
    CL points lie closer together than the tip tolerance, the rounding of the written words
    makes the nearness along the run go up and down by about a thousandth of the tolerance,
    and the first such blip would stop the walk rows before the one at the point (a
    micro-step path near the pole: a match a CL segment early, and the blocks after it
    compared with the wrong segment).

    Parameters
    ----------
    cl_xyz, xyz, cl_ijk, ijk : VecArrays
        Coordinate arrays of the CL points' and the rows' tips (mm) and unit tool axes.
    tol : Tolerances
    js, k : ndarray, shape (m,), int
    handoff : bool
        Raise :class:`_LongRuns` at a run longer than :data:`_LONG_RUN` rows.
    """
    n = len(xyz[0])
    best = k.copy()
    best_near = np.full(len(k), np.inf)
    nxt = k.copy()  # the next row to look at
    active = np.arange(len(k))
    width = 4
    while active.size:
        rows = nxt[active, None] + np.arange(width)
        safe = np.minimum(rows, n - 1)
        dist = _nearness(xyz, cl_xyz, ijk, cl_ijk, tol, safe, js[active, None])
        ends = ~(dist <= 1.0) | (rows >= n)
        if width == 4:  # (the first window: its first row is the one found, which reaches)
            ends[:, 0] = False
        stops = ends.any(axis=1)
        run = np.where(stops, np.argmax(ends, axis=1), width)  # the run's rows in the window
        dist[np.arange(width)[None, :] >= run[:, None]] = np.inf
        w = np.argmin(dist, axis=1)  # (the first of equals)
        d = dist[np.arange(len(active)), w]
        better = d < best_near[active]
        best[active[better]] = rows[better, w[better]]
        best_near[active[better]] = d[better]
        nxt[active] += width
        active = active[~stops & (nxt[active] < n)]
        if handoff and active.size and (nxt[active] - k[active]).max() > _LONG_RUN:
            raise _LongRuns
        width = min(8 * width, 4096)
    return best


_LONG_RUN = 2048
"""Rows of a run beyond which :func:`match_points` leaves the numpy rounds for the compiled
loop (:class:`_LongRuns`)."""


class _LongRuns(Exception):
    """A CL point within the tolerance of more than :data:`_LONG_RUN` rows (a path back and
    forth within the tolerance): the numpy rounds would look at that run again for every point
    of it (quadratic), the compiled loop keeps its memo
    (:func:`urdfpost.verification._match_kernel._run_memo`)."""


def _repeats(cl_tip: np.ndarray, cl_axis: np.ndarray) -> np.ndarray:
    """Which CL points repeat the point before them (tip and axis, to the bit): a dwell.

    Returns
    -------
    ndarray, shape (n_cl,), bool
    """
    same = np.zeros(len(cl_tip), dtype=bool)
    if len(cl_tip) > 1:
        tips = (cl_tip[1:] == cl_tip[:-1]).all(axis=1)
        same[1:] = tips & (cl_axis[1:] == cl_axis[:-1]).all(axis=1)
    return same


def _repeat_rows(
    cl_xyz: VecArrays,
    cl_axis: np.ndarray,
    xyz: VecArrays,
    axis: np.ndarray,
    tol: Tolerances,
    js: np.ndarray,
    start: np.ndarray,
) -> np.ndarray:
    """The rows of CL points ``js`` that repeat the point before them, searched from
    ``start`` (the row of the point before, where it was matched): the row after it where
    that reaches the point, else the row itself where that does; -1 where neither does (the
    point is searched as any other).

    A dwell written as one block per CL point thus takes its blocks one by one, so the point
    after it is searched from the dwell's last block (not from its first, which the nearest
    of a run of equal rows is: every point of a dwell longer than :data:`REACH` rows after it
    was missed), and each repeated point costs two tests, not the run of the dwell's rows.
    Where the point before was missed no row at or after the start reaches this one either
    (the same point, the same start): -1, and the search misses it too.

    Returns
    -------
    ndarray, shape (k,), int
    """
    n = len(xyz[0])
    out = np.full(len(js), -1)
    for step in (1, 0):  # the row after the start, then the start
        rows = start + step
        todo = np.flatnonzero((out < 0) & (rows < n))
        r, j = rows[todo], js[todo]
        near = _distance(xyz, cl_xyz, r[:, None], j[:, None])[:, 0] <= tol.tip
        reach = near & (angle_between(axis[r], cl_axis[j]) <= tol.orientation)
        out[todo[reach]] = r[reach]
    return out


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


COMPILED_FROM = 50_000
"""CL points from which :func:`match_points` runs the compiled loop
(:mod:`urdfpost.verification._match_kernel`, with numba installed: the ``fast`` extra) rather
than the numpy rounds: about 20 times faster per point, after a fixed cost of about 0.9 s per
process (numba's import and the cached machine code's loading), which a run of this many points
makes up for."""


def _load_kernel() -> ModuleType:
    from urdfpost.verification import _match_kernel

    return _match_kernel


KERNELS = Kernels(_load_kernel, "matching", start=COMPILED_FROM, stays=False, logger=log)
"""The compiled matching loop (:mod:`urdfpost.verification._match_kernel`), used by
:func:`match_points` from :data:`COMPILED_FROM` CL points on."""


def match_points(
    cl_tip: np.ndarray,
    cl_axis: np.ndarray,
    tip: np.ndarray,
    axis: np.ndarray,
    tol: Tolerances,
) -> np.ndarray:
    """The row reaching each CL point, or -1, as :func:`match_points_numpy` defines it.

    The definition is sequential. From :data:`COMPILED_FROM` CL
    points on, with numba installed, it runs as that loop compiled
    (:func:`urdfpost.verification._match_kernel.match_rows`, the same comparisons in the same
    order); else as the numpy rounds of :func:`match_points_numpy`. The tests hold the two to
    the same rows.

    Parameters
    ----------
    cl_tip, cl_axis, tip, axis, tol
        As :func:`match_points_numpy`.

    Returns
    -------
    ndarray, shape (n_cl,), int
    """
    kernel = KERNELS.get(len(cl_tip))
    if kernel is None:
        try:
            return match_points_numpy(cl_tip, cl_axis, tip, axis, tol, handoff=True)
        except _LongRuns:  # (quadratic in numpy: the compiled loop, if it can be had)
            kernel = KERNELS.load()
            if kernel is None:
                return match_points_numpy(cl_tip, cl_axis, tip, axis, tol)
    arrays = [np.ascontiguousarray(a, dtype=float) for a in (cl_tip, cl_axis, tip, axis)]
    try:
        return kernel.match_rows(*arrays, float(tol.tip), float(tol.orientation), REACH)
    except Exception as e:  # numba could not compile or cache it here: the numpy rounds
        KERNELS.fail(e)
        return match_points_numpy(cl_tip, cl_axis, tip, axis, tol)


def match_points_numpy(
    cl_tip: np.ndarray,
    cl_axis: np.ndarray,
    tip: np.ndarray,
    axis: np.ndarray,
    tol: Tolerances,
    handoff: bool = False,
) -> np.ndarray:
    """For each CL point, the program point at or after the previous match that reaches it (tip
    within tolerance, axis within orientation tolerance; the nearest of a run of such points in
    shares of the tolerances, :func:`_nearness`), or -1.

    The definition is sequential: with ``ptr = 0``, for each CL point j in turn, ``m_j`` is the
    first row in ``[ptr, ptr + REACH)`` that reaches it, moved on to the nearest row of the
    run of rows from there whose nearness is at most 1 (CL points closer together than the
    tolerance, or the rows of a reorientation in place: :func:`_walk`); ``ptr = m_j`` when
    there is one, else ``ptr`` stays. A CL point that repeats the point before it (a dwell)
    takes the next row, or the same one, where they reach it (:func:`_repeat_rows`). So
    ``m_j = F_j(ptr_j)``, a function of the start alone, and ``ptr_{j+1}`` is the last match
    up to j.

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

    Parameters
    ----------
    cl_tip : ndarray, shape (n_cl, 3), mm
        The CL points (at the measured point: the tip, or the pivot up the tool axis).
    cl_axis : ndarray, shape (n_cl, 3)
        Their unit tool axes.
    tip : ndarray, shape (N, 3), mm
        The program rows' measured points in the workpiece frame (:func:`at_pivot`).
    axis : ndarray, shape (N, 3)
        Their unit tool axes.
    tol : Tolerances
        ``tol.tip`` (mm) and ``tol.orientation`` (rad) decide what reaches a point.
    handoff : bool
        Stop with :class:`_LongRuns` at a run of more than :data:`_LONG_RUN` rows (the caller
        runs the compiled loop instead).

    Returns
    -------
    ndarray, shape (n_cl,), int
        The row reaching each CL point, non-decreasing over the points reached; -1 for a
        point not reached.
    """
    n_cl = len(cl_tip)
    out = np.full(n_cl, -1)
    ptr, j0, size = 0, 0, 1024
    cl_xyz, xyz = coords(cl_tip), coords(tip)
    cl_ijk, ijk = coords(cl_axis), coords(axis)
    repeats = _repeats(cl_tip, cl_axis)

    def evaluate(i: np.ndarray, start: np.ndarray, windows: tuple[int, ...]) -> None:
        """Results of points i from the given starts: first row reaching, and the nearest of
        the run from there (:func:`_walk`); a repeated point's by :func:`_repeat_rows` where
        it tells."""
        done_for[i] = start
        again = repeats[js[i]]
        if again.any():
            rows = _repeat_rows(cl_xyz, cl_axis, xyz, axis, tol, js[i[again]], start[again])
            m[i[again]] = rows
            first[i[again]] = -1  # (its result holds for its start alone)
            told = np.flatnonzero(again)[rows >= 0]
            keep = np.ones(len(i), dtype=bool)
            keep[told] = False
            i, start = i[keep], start[keep]
        hit = _first_reaching(cl_xyz, cl_axis, xyz, axis, tol, js[i], start, windows)
        first[i] = np.where(repeats[js[i]], -1, hit)
        ok = hit >= 0
        hit[ok] = _walk(cl_xyz, xyz, cl_ijk, ijk, tol, js[i][ok], hit[ok], handoff)
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
                    evaluate(np.array([e]), np.array([s]), (REACH,))
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
