"""The sequential matching of :func:`urdfpost.verification.match.match_points`, compiled.

The definition is a loop (each CL point searched from the row the point before reached), which
numpy can only run as rounds of guesses over runs of points; compiled with numba it is that loop
itself, about one row looked at per CL point. Imported by :func:`match_points` when it is first
called (numba's import takes a third of a second); the machine code is cached on disk beside
this module (``__pycache__``), so only the first call after an install compiles it.

Every comparison is made as the numpy path makes it, in the same order of operations
(``tests/test_verify.py`` holds the two to the same rows on real and generated programs):
the tip distance ``sqrt((dx^2 + dy^2) + dz^2)`` against the tip tolerance, the axis angle
``2 atan2(|u - v|, |u + v|)`` against the orientation tolerance, and the nearness of
:func:`urdfpost.verification.match._nearness`.

A CL point that repeats the point before it (a dwell) takes the next row or the same one
without a search, as in the numpy rounds. Only this loop keeps a long run of rows within the
tolerance of a CL point (a path back and forth within it) as a memo (:func:`_run_memo`), which
the same point found again inside the run answers from, for the same rows; the numpy rounds
hand a job with such runs to this loop (``match._LongRuns``).
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def _norm(x: float, y: float, z: float) -> float:
    return float(np.sqrt(x * x + y * y + z * z))


@njit(cache=True, nogil=True)
def _nearness(
    tip: np.ndarray,
    axis: np.ndarray,
    r: int,
    cl_tip: np.ndarray,
    cl_axis: np.ndarray,
    j: int,
    tol_tip: float,
    scale: float,
) -> float:
    """:func:`urdfpost.verification.match._nearness` of row r to CL point j (``scale`` is
    ``2 / orientation tolerance``)."""
    dist = _norm(tip[r, 0] - cl_tip[j, 0], tip[r, 1] - cl_tip[j, 1], tip[r, 2] - cl_tip[j, 2])
    dist /= tol_tip
    chord = _norm(
        axis[r, 0] - cl_axis[j, 0], axis[r, 1] - cl_axis[j, 1], axis[r, 2] - cl_axis[j, 2]
    )
    chord *= 0.5
    angle = np.arcsin(min(chord, 1.0)) * scale
    return max(dist, angle)


@njit(cache=True, nogil=True)
def _reaches(
    tip: np.ndarray,
    axis: np.ndarray,
    r: int,
    cx: float,
    cy: float,
    cz: float,
    ax: float,
    ay: float,
    az: float,
    tol_tip: float,
    tol_orientation: float,
) -> bool:
    """Whether row r reaches the CL point (cx, cy, cz) with axis (ax, ay, az)."""
    if _norm(tip[r, 0] - cx, tip[r, 1] - cy, tip[r, 2] - cz) > tol_tip:
        return False
    across = _norm(axis[r, 0] - ax, axis[r, 1] - ay, axis[r, 2] - az)
    along = _norm(axis[r, 0] + ax, axis[r, 1] + ay, axis[r, 2] + az)
    return bool(2.0 * np.arctan2(across, along) <= tol_orientation)


@njit(cache=True, nogil=True)
def _same(cl_tip: np.ndarray, cl_axis: np.ndarray, i: int, j: int) -> bool:
    """Whether CL points i and j are the same (tip and axis, to the bit)."""
    for c in range(3):
        if cl_tip[j, c] != cl_tip[i, c] or cl_axis[j, c] != cl_axis[i, c]:
            return False
    return True


@njit(cache=True, nogil=True)
def match_rows(
    cl_tip: np.ndarray,
    cl_axis: np.ndarray,
    tip: np.ndarray,
    axis: np.ndarray,
    tol_tip: float,
    tol_orientation: float,
    reach: int,
) -> np.ndarray:
    """For each CL point, the first row in ``[ptr, ptr + reach)`` that reaches it, moved on to
    the nearest row of the run of rows from there whose nearness is at most 1, or -1 (``ptr``:
    the last row matched); a CL point that repeats the point before it, matched, takes row
    ``ptr + 1`` or ``ptr`` where they reach it (:func:`urdfpost.verification.match._repeat_rows`).

    Parameters
    ----------
    cl_tip, cl_axis : ndarray, shape (n_cl, 3), C order
        The CL points (mm) and their unit tool axes.
    tip, axis : ndarray, shape (N, 3), C order
        The program rows'.
    tol_tip : float, mm
    tol_orientation : float, rad
    reach : int
        :data:`urdfpost.verification.match.REACH`.

    Returns
    -------
    ndarray, shape (n_cl,), int64
    """
    n_cl, n = cl_tip.shape[0], tip.shape[0]
    out = np.full(n_cl, -1, dtype=np.int64)
    scale = 2.0 / tol_orientation
    ptr = 0
    # the memos of the last two long runs (_run_memo): their CL points, rows and matches
    memo_point = np.full(2, -1, dtype=np.int64)
    memo_lo, memo_hi = np.full(2, -1, dtype=np.int64), np.full(2, -2, dtype=np.int64)
    memo_0, memo_1 = np.empty(0, dtype=np.int64), np.empty(0, dtype=np.int64)
    slot = 0
    for j in range(n_cl):
        cx, cy, cz = cl_tip[j, 0], cl_tip[j, 1], cl_tip[j, 2]
        ax, ay, az = cl_axis[j, 0], cl_axis[j, 1], cl_axis[j, 2]
        if j > 0 and _same(cl_tip, cl_axis, j - 1, j):  # a dwell (match._repeat_rows)
            if out[j - 1] < 0:  # (the same search from the same row: missed again)
                continue
            if ptr + 1 < n and _reaches(
                tip, axis, ptr + 1, cx, cy, cz, ax, ay, az, tol_tip, tol_orientation
            ):
                out[j] = ptr = ptr + 1
                continue
            if _reaches(tip, axis, ptr, cx, cy, cz, ax, ay, az, tol_tip, tol_orientation):
                out[j] = ptr
                continue
        found = -1
        for r in range(ptr, min(ptr + reach, n)):
            if _reaches(tip, axis, r, cx, cy, cz, ax, ay, az, tol_tip, tol_orientation):
                found = r
                break
        if found < 0:
            continue
        # the nearest row of the run of rows from there whose nearness is at most 1 (the
        # first of equals); from a long run of a CL point seen before, its memo
        hit = -1
        for k in range(2):
            if memo_lo[k] <= found <= memo_hi[k] and _same(cl_tip, cl_axis, memo_point[k], j):
                hit = k
        if hit >= 0:
            best = (memo_0 if hit == 0 else memo_1)[found - memo_lo[hit]]
            out[j] = ptr = best
            continue
        near = _nearness(tip, axis, found, cl_tip, cl_axis, j, tol_tip, scale)
        best, end = found, n - 1
        for r in range(found + 1, n):
            after = _nearness(tip, axis, r, cl_tip, cl_axis, j, tol_tip, scale)
            if not after <= 1.0:
                end = r - 1
                break
            if after < near:
                best, near = r, after
        out[j] = best
        ptr = best
        if end - found >= MEMO_FROM:
            memo = _run_memo(tip, axis, found, end, cl_tip, cl_axis, j, tol_tip, scale)
            k = slot
            slot = 1 - slot
            memo_lo[k], memo_hi[k] = found, end
            memo_point[k] = j
            if k == 0:
                memo_0 = memo
            else:
                memo_1 = memo
    return out


MEMO_FROM = 256
"""Rows of a run from which :func:`match_rows` keeps its memo (:func:`_run_memo`): only CL
points within the tolerance of many rows (a path back and forth within the tolerance) have such
runs, and each point of them would otherwise scan its run again (quadratic)."""


@njit(cache=True, nogil=True)
def _run_memo(
    tip: np.ndarray,
    axis: np.ndarray,
    lo: int,
    hi: int,
    cl_tip: np.ndarray,
    cl_axis: np.ndarray,
    j: int,
    tol_tip: float,
    scale: float,
) -> np.ndarray:
    """For every row f of the run ``lo .. hi`` of CL point j (found at ``lo``; every row after
    it has a nearness of at most 1), the row its scan from f gives: the first of the nearest of
    ``f .. hi`` (from ``lo`` itself, a row nearer than ``lo`` only).

    The same CL point found again at a row f of the run has the same run from there (its rows
    after f are the run's; the row after the run is not within 1), so its match is this
    memo's at f, without the scan.

    Returns
    -------
    ndarray, shape (hi - lo + 1,), int64
        Rows.
    """
    m = hi - lo + 1
    near = np.empty(m)
    for i in range(m):
        near[i] = _nearness(tip, axis, lo + i, cl_tip, cl_axis, j, tol_tip, scale)
    memo = np.empty(m, dtype=np.int64)
    b = m - 1
    for i in range(m - 1, 0, -1):
        if near[i] <= near[b]:  # (the first of equals)
            b = i
        memo[i] = lo + b
    memo[0] = lo
    if m > 1 and near[memo[1] - lo] < near[0]:  # (strictly nearer than the row found)
        memo[0] = memo[1]
    return memo
