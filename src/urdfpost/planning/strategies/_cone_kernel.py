"""The cone's tube (:func:`urdfpost.planning.strategies.cone._tube`), compiled.

The tube's forward pass (the interval reachable at each point within the band and the step
limits), the bisection for the common rate factor and the backward pass are loops over the
points; numpy runs the forward pass as running sums and maxima over whole arrays (and again
for each factor tried), the backward pass point by point in Python where it is not exact.
Compiled with numba they are those loops, each stopping where it may (the bisection's passes
at the first closed interval).

Every number is computed as the numpy path computes it, in the same order of operations: the
cumulative sums ``cum`` of the steps one after the other (``np.cumsum``), ``lo + cum`` and
its running maximum less ``cum`` where the band does not bound the interval itself, the
rounding allowance of :func:`~urdfpost.planning.strategies.cone._rounding` with numpy's
pairwise summation, and the same comparisons and ties (``tests/test_tube.py`` holds the two to
the bit).
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True, error_model="numpy")
def _block_abs(a: np.ndarray, lo: int, n: int, k: float) -> float:
    """numpy's sum of up to 128 entries ``abs(a[lo:lo + n] * k)``: in order below 8 entries,
    else eight partial sums combined pairwise, then the remainder in order."""
    if n < 8:
        res = 0.0
        for i in range(lo, lo + n):
            res += abs(a[i] * k)
        return res
    r0, r1 = abs(a[lo] * k), abs(a[lo + 1] * k)
    r2, r3 = abs(a[lo + 2] * k), abs(a[lo + 3] * k)
    r4, r5 = abs(a[lo + 4] * k), abs(a[lo + 5] * k)
    r6, r7 = abs(a[lo + 6] * k), abs(a[lo + 7] * k)
    m = n - n % 8
    i = 8
    while i < m:
        j = lo + i
        r0 += abs(a[j] * k)
        r1 += abs(a[j + 1] * k)
        r2 += abs(a[j + 2] * k)
        r3 += abs(a[j + 3] * k)
        r4 += abs(a[j + 4] * k)
        r5 += abs(a[j + 5] * k)
        r6 += abs(a[j + 6] * k)
        r7 += abs(a[j + 7] * k)
        i += 8
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < n:
        res += abs(a[lo + i] * k)
        i += 1
    return res


@njit(cache=True, nogil=True, error_model="numpy")
def _pairwise_abs(a: np.ndarray, lo: int, n: int, k: float) -> float:
    """``np.abs(a[lo:lo + n] * k).sum()`` as numpy adds it up: pairwise, halves (the first a
    multiple of 8 entries) down to blocks of at most 128 (:func:`_block_abs`).

    numpy's recursion is run on an explicit stack (numba's cache does not load recursive
    functions reliably). Each frame is a range with its stage: 0 its first half to do, 1
    waiting for it, 2 its second half to do, 3 waiting for that.
    """
    if n <= 128:
        return _block_abs(a, lo, n, k)
    f_lo = np.empty(64, dtype=np.int64)
    f_n = np.empty(64, dtype=np.int64)
    stage = np.zeros(64, dtype=np.int64)
    first = np.empty(64)
    top = 0
    f_lo[0], f_n[0] = lo, n
    ret = 0.0  # the sum of the frame last finished
    while True:
        m = f_n[top]
        h = m // 2
        h -= h % 8
        if stage[top] == 0:
            if h <= 128:
                first[top] = _block_abs(a, f_lo[top], h, k)
                stage[top] = 2
            else:
                stage[top] = 1
                top += 1
                f_lo[top], f_n[top], stage[top] = f_lo[top - 1], h, 0
            continue
        if stage[top] == 1:
            first[top] = ret
            stage[top] = 2
        if stage[top] == 2:
            if m - h <= 128:
                ret = first[top] + _block_abs(a, f_lo[top] + h, m - h, k)
            else:
                stage[top] = 3
                top += 1
                f_lo[top], f_n[top], stage[top] = f_lo[top - 1] + h, m - h, 0
                continue
        else:  # stage 3: the second half is done
            ret = first[top] + ret
        top -= 1
        if top < 0:
            return ret


@njit(cache=True, nogil=True, error_model="numpy")
def _abs_max(a: np.ndarray, lo: int) -> float:
    """``float(np.abs(a[lo:]).max(initial=0.0))`` (finite entries)."""
    m = 0.0
    for i in range(lo, a.shape[0]):
        x = abs(a[i])
        if x > m:
            m = x
    return m


@njit(cache=True, nogil=True, error_model="numpy")
def _rounding(
    a: np.ndarray, b: np.ndarray, step: np.ndarray, lo: int, k: float, scale: float = -1.0
) -> float:
    """:func:`~urdfpost.planning.strategies.cone._rounding` of ``a[lo:]``, ``b[lo:]`` and
    ``step[lo:] * k``; ``scale``, when not negative, is their largest magnitudes' sum
    (``_abs_max(a, lo) + _abs_max(b, lo)``, the same for every factor ``k``)."""
    if scale < 0.0:
        scale = _abs_max(a, lo) + _abs_max(b, lo)
    x = scale + _pairwise_abs(step, lo, step.shape[0] - lo, k)
    return 16.0 * (np.nextafter(x, np.inf) - x)


@njit(cache=True, nogil=True, error_model="numpy")
def reachable(
    lo: np.ndarray, hi: np.ndarray, step: np.ndarray, k: float, stop: bool, scale: float = -1.0
) -> tuple[np.ndarray, np.ndarray, bool]:
    """:func:`~urdfpost.planning.strategies.cone._reachable` of ``lo``, ``hi`` and the steps
    ``step * k``.

    Parameters
    ----------
    lo, hi : ndarray, shape (n,), rad
    step : ndarray, shape (n - 1,), rad
    k : float
        Factor of the steps (the numpy path's ``step * k``, entry by entry).
    stop : bool
        Return at the first closed interval (the entries after it are ``lo`` and ``hi``).
    scale : float
        ``max |lo| + max |hi|`` when known (negative: not known), for the rounding
        allowance from the first point.

    Returns
    -------
    r_lo, r_hi : ndarray, shape (n,)
    ok : bool
    """
    n = lo.shape[0]
    r_lo, r_hi = lo.copy(), hi.copy()
    ok = True
    s = 0
    while s < n - 1:
        eps = _rounding(lo, hi, step, s, k, scale if s == 0 else -1.0)
        own_lo, own_hi = r_lo[s], r_hi[s]
        # point s itself: a = own + 0.0, which is its own running extreme
        run_lo, run_hi = own_lo + 0.0, own_hi - 0.0
        cum = 0.0
        f = n - s  # the first closed interval, relative to s (none: n - s)
        if own_lo > own_hi + eps:
            f = 0
        else:
            for j in range(1, n - s):
                cum = step[s] * k if j == 1 else cum + step[s + j - 1] * k
                own_lo, own_hi = lo[s + j], hi[s + j]
                a = own_lo + cum
                b = own_hi - cum
                # np.maximum / np.minimum.accumulate: the running value where it ties
                if not run_lo >= a:
                    run_lo = a
                if not run_hi <= b:
                    run_hi = b
                a = own_lo if run_lo == a else run_lo - cum
                b = own_hi if run_hi == b else run_hi + cum
                if a > b + eps:
                    f = j
                    break
                if a > b:
                    a = b = 0.5 * (a + b)
                r_lo[s + j], r_hi[s + j] = a, b
        if f == n - s:
            break
        ok = False
        i = s + f
        if stop or f == 0:
            break
        mid = 0.5 * (r_lo[i - 1] + r_hi[i - 1])
        mid = mid if mid > lo[i] else lo[i]  # np.clip
        mid = mid if mid < hi[i] else hi[i]
        r_lo[i] = r_hi[i] = mid
        s = i
    return r_lo, r_hi, ok


@njit(cache=True, nogil=True, error_model="numpy")
def tube(exact: np.ndarray, half: np.ndarray, step: np.ndarray) -> np.ndarray:
    """:func:`~urdfpost.planning.strategies.cone._tube` (finite inputs, ``half >= 0``).

    Parameters
    ----------
    exact, half : ndarray, shape (n,), rad
    step : ndarray, shape (n - 1,), rad

    Returns
    -------
    ndarray, shape (n,), rad
    """
    n = exact.shape[0]
    lo = exact - half
    hi = exact + half
    scale = _abs_max(lo, 0) + _abs_max(hi, 0)  # (for every factor the bisection tries)
    r_lo, r_hi, ok = reachable(lo, hi, step, 1.0, True, scale)
    k_hi = 1.0
    if not ok:
        for i in range(n - 1):
            need = abs(exact[i + 1] - exact[i]) / step[i]
            if np.isfinite(need) and need > k_hi:
                k_hi = need
        k_hi = k_hi * (1 + 1e-9)
        k_lo = 1.0
        for _ in range(40):
            k = np.sqrt(k_lo * k_hi)
            fine = reachable(lo, hi, step, k, True, scale)[2]
            if fine:
                k_hi = k
            else:
                k_lo = k
            if k_hi / k_lo < 1.001:
                break
        r_lo, r_hi, _ = reachable(lo, hi, step, k_hi, False, scale)
    out = np.empty(n)
    x = exact[n - 1]
    x = x if x > r_lo[n - 1] else r_lo[n - 1]  # np.clip
    out[n - 1] = x if x < r_hi[n - 1] else r_hi[n - 1]
    if n == 1:
        return out
    eps = _rounding(exact, half, step, 0, k_hi)
    for i in range(n - 2, -1, -1):
        st = step[i] * k_hi
        nxt = out[i + 1]
        e = exact[i]
        if nxt == exact[i + 1]:
            # ``easy``: the exact value reachable and within a step of the next exact one
            lo_e = nxt - st
            hi_e = nxt + st
            if max(r_lo[i], lo_e) <= e and e <= min(r_hi[i], hi_e):
                out[i] = e
                continue
        a = nxt - st
        if not a > r_lo[i]:  # Python's max(r_lo, a): the first where they tie
            a = r_lo[i]
        b = nxt + st
        if not b < r_hi[i]:
            b = r_hi[i]
        if a <= b:
            v = a if a > e else e  # min(max(e, a), b)
            out[i] = b if b < v else v
        elif a <= b + eps:  # one value, closed by rounding
            out[i] = 0.5 * (a + b)
        else:
            v = r_lo[i] if r_lo[i] > e else e
            out[i] = r_hi[i] if r_hi[i] < v else v
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def _maximum(a: float, b: float) -> float:
    """``np.maximum``: NaN where either is."""
    return a if (a >= b or np.isnan(a)) else b


@njit(cache=True, nogil=True, error_model="numpy")
def deviation_bound(
    dev: np.ndarray,
    rot: np.ndarray,
    param: np.ndarray,
    seg: np.ndarray,
    alpha: np.ndarray,
    lo2: float,
    hi2: float,
) -> np.ndarray:
    """The arithmetic of :func:`~urdfpost.planning.strategies.cone._deviation_bound` from the
    rows' deviations and the programmed axes' turns: on each segment, the last row at its
    first point and the first row at its second (numpy's two ``searchsorted`` as one walk
    along the sorted rows), their summed rotary steps, and the tilt beyond travel.

    Parameters
    ----------
    dev : ndarray, shape (N,), rad
        The rows' deviations from the programmed axis.
    rot : ndarray, shape (N, r), rad
    param : ndarray, shape (N,)
        The rows' positions, in order.
    seg : ndarray, shape (k,), int
        The segments, in increasing order.
    alpha : ndarray, shape (k,), rad
        The angle between the programmed axes at either end of each.
    lo2, hi2 : float, rad
        The tilt's travel.

    Returns
    -------
    ndarray, shape (k,), rad
    """
    n_rows, r = rot.shape
    out = np.empty(seg.shape[0])
    f = 0  # rows with param <= seg: searchsorted(param, seg, "right")
    g = 0  # rows with param < seg + 1: searchsorted(param, seg + 1, "left")
    for j in range(seg.shape[0]):
        x = float(seg[j])
        while f < n_rows and param[f] <= x:
            f += 1
        while g < n_rows and param[g] < x + 1.0:
            g += 1
        first = f - 1 if f > 0 else n_rows - 1  # (numpy's index -1: the last row)
        last = g
        turn = abs(rot[last, 0] - rot[first, 0])
        for a in range(1, r):
            turn = turn + abs(rot[last, a] - rot[first, a])
        t0, t1 = rot[first, 1], rot[last, 1]
        b0 = _maximum(_maximum(t0 - hi2, lo2 - t0), 0.0)
        b1 = _maximum(_maximum(t1 - hi2, lo2 - t1), 0.0)
        out[j] = 0.5 * (dev[first] + dev[last] + turn + alpha[j]) + _maximum(b0, b1)
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def axis_deviation(
    direction: np.ndarray,
    home: np.ndarray,
    cos: np.ndarray,
    sin: np.ndarray,
    axis: np.ndarray,
    across: np.ndarray,
    along: np.ndarray,
) -> None:
    """For the angle between the tool axis of rotary angles and a given axis, row by row
    (:func:`urdfpost.planning.strategies.cone._axis_deviation`): the home tool axis turned
    about each rotary joint's direction from the last to the first (Rodrigues, as
    :func:`urdfpost.kinematics.forward.rotate` turns it: ``((v c + (k x v) s) + (k (k . v))
    (1 - c))``), then ``|u - v|`` and ``|u + v|`` (:func:`urdfpost.geometry.angle_between`
    takes ``2 atan2`` of them: numpy's, whose last bit differs from the C library's that numba
    calls), in numpy's order of operations.

    Parameters
    ----------
    direction : ndarray, shape (r, 3)
        The rotary joints' unit directions, in chain order.
    home : ndarray, shape (3,)
        The tool axis at home.
    cos, sin : ndarray, shape (k, r)
        The cosine and sine of every angle (worked out by numpy).
    axis : ndarray, shape (k, 3)
        The axes to compare with.

    Returns
    -------
    None
        Written: ``across`` and ``along``, shape (k,).
    """
    r = direction.shape[0]
    for i in range(cos.shape[0]):
        x0, x1, x2 = home[0], home[1], home[2]
        for j in range(r - 1, -1, -1):
            k0, k1, k2 = direction[j, 0], direction[j, 1], direction[j, 2]
            c, s = cos[i, j], sin[i, j]
            kv = k0 * x0 + k1 * x1 + k2 * x2
            rest = 1.0 - c
            c0 = k1 * x2 - k2 * x1
            c1 = k2 * x0 - k0 * x2
            c2 = k0 * x1 - k1 * x0
            x0, x1, x2 = (
                x0 * c + c0 * s + k0 * kv * rest,
                x1 * c + c1 * s + k1 * kv * rest,
                x2 * c + c2 * s + k2 * kv * rest,
            )
        d0, d1, d2 = x0 - axis[i, 0], x1 - axis[i, 1], x2 - axis[i, 2]
        e0, e1, e2 = x0 + axis[i, 0], x1 + axis[i, 1], x2 + axis[i, 2]
        across[i] = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        along[i] = np.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
