"""The collision world's box culling, compiled: pair box gaps and the stock tree's descents.

:class:`urdfpost.collision.world.CollisionWorld` culls the pairs it hands to FCL with box gaps
(:meth:`~urdfpost.collision.world.CollisionWorld._lower_bounds`: axis-aligned, then oriented
boxes) and descents of the stock's box tree (:meth:`~urdfpost.collision.world._BoxTree.separation`
and :meth:`~urdfpost.collision.world._BoxTree.near`). In numpy those are whole-array passes over
(configurations, pairs) and (queries, tree nodes) with fancy indexing; here they are loops over
configurations and pairs, one query's descent at a time. Imported by the world when a query is
large enough (numba's import takes about half a second); the machine code is cached beside this
module (``__pycache__``), so only the first call after an install compiles it.

The formulas and the order of their operations are those of the numpy path (the oracle, which
runs without numba). Both round, and numpy's small matrix products may round differently
(BLAS, fused multiply-adds), so every gap computed here is lowered by ``slack`` (the world passes
``KERNEL_SLACK_MM``, 1e-10 mm: far above the rounding of these sums of a few terms of at most a
few metres, far below ``GAP_MM``), and every test ``gap <= limit`` is made on the lowered gap:
the kernels are conservative (they keep, for FCL, every pair and node the numpy path keeps,
and at most a few more within ``slack`` of a limit). ``tests/test_collision_kernels.py`` holds
them to the numpy path.
"""

from __future__ import annotations

import numpy as np
from numba import njit

_INF = np.inf


@njit(cache=True, nogil=True)
def _obb_gap(
    rot: np.ndarray, s: int, a: int, b: int, between: np.ndarray, box_half: np.ndarray
) -> float:
    """The largest gap between the oriented boxes of bodies a and b in configuration s along
    any of their six axes, mm (``between``: centre of b less centre of a, (3,), mm);
    :meth:`CollisionWorld._box_gaps`."""
    best = -_INF
    for ll in range(6):
        body = a if ll < 3 else b
        col = ll % 3
        u0, u1, u2 = rot[s, body, 0, col], rot[s, body, 1, col], rot[s, body, 2, col]
        d = abs(between[0] * u0 + between[1] * u1 + between[2] * u2)
        reach_a = 0.0
        reach_b = 0.0
        for i in range(3):
            reach_a += box_half[a, i] * abs(
                rot[s, a, 0, i] * u0 + rot[s, a, 1, i] * u1 + rot[s, a, 2, i] * u2
            )
            reach_b += box_half[b, i] * abs(
                rot[s, b, 0, i] * u0 + rot[s, b, 1, i] * u1 + rot[s, b, 2, i] * u2
            )
        g = d - (reach_a + reach_b)
        if g > best:
            best = g
    return best


@njit(cache=True, nogil=True)
def pair_bounds(
    rot: np.ndarray,
    center: np.ndarray,
    box_half: np.ndarray,
    ia: np.ndarray,
    ib: np.ndarray,
    need: np.ndarray,
    allowed: np.ndarray,
    use_allowed: bool,
    slack: float,
) -> np.ndarray:
    """:meth:`CollisionWorld._lower_bounds`, lowered by ``slack``.

    Parameters
    ----------
    rot : ndarray, shape (n, b, 3, 3)
        Axes (columns) of every body's box per configuration, workpiece frame.
    center : ndarray, shape (n, b, 3)
        Centres of those boxes, mm.
    box_half : ndarray, shape (b, 3)
        Half sizes of the boxes, mm.
    ia, ib : ndarray, shape (p,), int
        The pairs' bodies.
    need : ndarray, shape (n,)
        mm: the oriented boxes are measured where the axis-aligned gap (lowered) is at most this.
    allowed : ndarray, shape (n, p), bool
        With ``use_allowed``, the entries to compute (+inf elsewhere); else ignored.
    use_allowed : bool
    slack : float
        mm.

    Returns
    -------
    ndarray, shape (n, p), mm
        The axis-aligned boxes' gap (at least 0), where it is within ``need`` the larger of it
        and the oriented boxes' separating-axis gap; less ``slack``.
    """
    n, nb = rot.shape[0], rot.shape[1]
    p = ia.shape[0]
    out = np.empty((n, p))
    ext = np.empty((nb, 3))
    between = np.empty(3)
    for s in range(n):
        any_here = True
        if use_allowed:
            any_here = False
            for k in range(p):
                if allowed[s, k]:
                    any_here = True
                    break
        if not any_here:
            for k in range(p):
                out[s, k] = _INF
            continue
        for bb in range(nb):
            for r in range(3):
                ext[bb, r] = (
                    abs(rot[s, bb, r, 0]) * box_half[bb, 0]
                    + abs(rot[s, bb, r, 1]) * box_half[bb, 1]
                    + abs(rot[s, bb, r, 2]) * box_half[bb, 2]
                )
        for k in range(p):
            if use_allowed and not allowed[s, k]:
                out[s, k] = _INF
                continue
            a, b = ia[k], ib[k]
            gap = -_INF
            for r in range(3):
                between[r] = center[s, b, r] - center[s, a, r]
                g = abs(between[r]) - ext[a, r] - ext[b, r]
                if g > gap:
                    gap = g
            if gap < 0.0:
                gap = 0.0
            gap -= slack
            if gap <= need[s]:
                obb = _obb_gap(rot, s, a, b, between, box_half) - slack
                if obb > gap:
                    gap = obb
            out[s, k] = gap
    return out


@njit(cache=True, nogil=True)
def _node_test(
    lo: np.ndarray,
    hi: np.ndarray,
    node: int,
    c: np.ndarray,
    r: np.ndarray,
    half: np.ndarray,
    spread: np.ndarray,
    base: np.ndarray,
    limit: float,
    near_mode: bool,
    slack: float,
) -> float:
    """One tree node against one oriented box (centre ``c``, axes ``r``, half sizes ``half``).

    Separation mode: the node's gap (:meth:`_BoxTree.separation`, less ``slack``; +inf for an
    empty node: NaN). Near mode (``base``: world half sizes of the box inflated by ``limit``):
    -inf where :meth:`_BoxTree.near` keeps the node at gap ``limit`` (within ``slack``), +inf
    where it does not, NaN for an empty node.
    """
    if not (lo[node, 0] <= hi[node, 0] and lo[node, 1] <= hi[node, 1]):
        return np.nan
    if not lo[node, 2] <= hi[node, 2]:
        return np.nan
    d = np.empty(3)
    ext = np.empty(3)
    for i in range(3):
        d[i] = (lo[node, i] + hi[node, i]) / 2 - c[i]
        ext[i] = (hi[node, i] - lo[node, i]) / 2
    gap = -_INF
    for i in range(3):
        if near_mode:
            if abs(d[i]) - slack > base[i] + ext[i]:
                return _INF
        else:
            g = (abs(d[i]) - base[i] - ext[i]) / spread[i]
            if g > gap:
                gap = g
    for j in range(3):
        d_box = abs(r[0, j] * d[0] + r[1, j] * d[1] + r[2, j] * d[2])
        ext_box = abs(r[0, j]) * ext[0] + abs(r[1, j]) * ext[1] + abs(r[2, j]) * ext[2]
        if near_mode:
            if d_box - slack > half[j] + limit + ext_box:
                return _INF
        else:
            g = d_box - half[j] - ext_box
            if g > gap:
                gap = g
    if near_mode:
        return -_INF
    return gap - slack


@njit(cache=True, nogil=True)
def _descend(
    lo: np.ndarray,
    hi: np.ndarray,
    levels: int,
    c: np.ndarray,
    r: np.ndarray,
    half: np.ndarray,
    limit: float,
    near_mode: bool,
    frontier: int,
    slack: float,
    cur: np.ndarray,
    kept: np.ndarray,
) -> float:
    """One oriented box down the tree, level by level as the numpy descent (the nodes within
    ``limit`` kept, their children visited; more than ``frontier`` kept above the leaves: -inf).

    ``lo``, ``hi`` (2**levels - 1, 3): the tree's levels one after the other from the root.
    Separation mode: the smallest leaf gap (less ``slack``) at most ``limit``, +inf if none,
    -inf where crowded. Near mode: -inf where near at gap ``limit`` (or crowded), else +inf.
    ``cur``, ``kept``: work arrays of at least ``2 * frontier + 2`` entries.
    """
    spread = np.empty(3)
    base = np.empty(3)
    for i in range(3):
        spread[i] = abs(r[i, 0]) + abs(r[i, 1]) + abs(r[i, 2])
        if near_mode:
            base[i] = (
                abs(r[i, 0]) * (half[0] + limit)
                + abs(r[i, 1]) * (half[1] + limit)
                + abs(r[i, 2]) * (half[2] + limit)
            )
        else:
            base[i] = abs(r[i, 0]) * half[0] + abs(r[i, 1]) * half[1] + abs(r[i, 2]) * half[2]
    best = _INF
    count = 1
    cur[0] = 0
    for level in range(levels):
        offset = (1 << level) - 1
        n_kept = 0
        last = level == levels - 1
        for t in range(count):
            node = offset + cur[t]
            g = _node_test(lo, hi, node, c, r, half, spread, base, limit, near_mode, slack)
            if near_mode:
                if not g < 0.0:
                    continue
            elif not g <= limit:
                continue
            if last:
                if g < best:
                    best = g
            else:
                kept[n_kept] = cur[t]
                n_kept += 1
        if last:
            break
        if n_kept > frontier:
            return -_INF
        if n_kept == 0:
            break
        for t in range(n_kept):
            cur[2 * t] = 2 * kept[t]
            cur[2 * t + 1] = 2 * kept[t] + 1
        count = 2 * n_kept
    return best


@njit(cache=True, nogil=True)
def _partner(
    rot: np.ndarray,
    center: np.ndarray,
    s: int,
    other: int,
    r_inv: np.ndarray,
    t_s: np.ndarray,
    c: np.ndarray,
    r: np.ndarray,
) -> None:
    """Body ``other``'s box in configuration s in the stock's frame: centre into ``c`` (3,),
    axes into ``r`` (3, 3) (:meth:`CollisionWorld._partner_box`)."""
    for i in range(3):
        c[i] = (
            (center[s, other, 0] - t_s[0]) * r_inv[i, 0]
            + (center[s, other, 1] - t_s[1]) * r_inv[i, 1]
            + (center[s, other, 2] - t_s[2]) * r_inv[i, 2]
        )
        for k in range(3):
            r[i, k] = (
                r_inv[i, 0] * rot[s, other, 0, k]
                + r_inv[i, 1] * rot[s, other, 1, k]
                + r_inv[i, 2] * rot[s, other, 2, k]
            )


@njit(cache=True, nogil=True)
def stock_separations(
    rot: np.ndarray,
    center: np.ndarray,
    box_half: np.ndarray,
    others: np.ndarray,
    r_inv: np.ndarray,
    t_s: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    levels: int,
    most: np.ndarray,
    frontier: int,
    slack: float,
) -> np.ndarray:
    """:meth:`CollisionWorld._stock_separations`, lowered by ``slack``.

    Parameters
    ----------
    rot, center, box_half
        As :func:`pair_bounds`.
    others : ndarray, shape (s,), int
        Per stock pair, the stock's partner body.
    r_inv : ndarray, shape (3, 3)
        The stock's rotation, transposed (workpiece frame to the stock's).
    t_s : ndarray, shape (3,)
        The stock's origin in the workpiece frame, mm.
    lo, hi : ndarray, shape (2**levels - 1, 3)
        The stock tree's node boxes, level after level from the root, mm.
    levels : int
    most : ndarray, shape (n,)
        mm: the largest gap asked about per configuration.
    frontier : int
        ``_TREE_FRONTIER``.
    slack : float
        mm.

    Returns
    -------
    ndarray, shape (n, s), mm
        +inf beyond ``most``, -inf where the descent met too many nodes.
    """
    n = rot.shape[0]
    out = np.empty((n, others.shape[0]))
    c = np.empty(3)
    r = np.empty((3, 3))
    cur = np.empty(2 * frontier + 2, dtype=np.int64)
    kept = np.empty(2 * frontier + 2, dtype=np.int64)
    for s in range(n):
        for col in range(others.shape[0]):
            o = others[col]
            _partner(rot, center, s, o, r_inv, t_s, c, r)
            out[s, col] = _descend(
                lo, hi, levels, c, r, box_half[o], most[s], False, frontier, slack, cur, kept
            )
    return out


@njit(cache=True, nogil=True)
def cull_stock_pairs(
    ask: np.ndarray,
    stock_pairs: np.ndarray,
    others: np.ndarray,
    rot: np.ndarray,
    center: np.ndarray,
    box_half: np.ndarray,
    r_inv: np.ndarray,
    t_s: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    levels: int,
    gaps: np.ndarray,
    frontier: int,
    slack: float,
) -> None:
    """:meth:`CollisionWorld._cull_stock_pairs`: clear, in ``ask`` (n, p), the stock pairs
    (columns ``stock_pairs``, partners ``others``) that :meth:`_BoxTree.near` at ``gaps`` (n,)
    mm clears, within ``slack``; the other arguments as :func:`stock_separations`."""
    c = np.empty(3)
    r = np.empty((3, 3))
    cur = np.empty(2 * frontier + 2, dtype=np.int64)
    kept = np.empty(2 * frontier + 2, dtype=np.int64)
    for s in range(ask.shape[0]):
        for col in range(stock_pairs.shape[0]):
            p = stock_pairs[col]
            if not ask[s, p]:
                continue
            o = others[col]
            _partner(rot, center, s, o, r_inv, t_s, c, r)
            g = _descend(
                lo, hi, levels, c, r, box_half[o], gaps[s], True, frontier, slack, cur, kept
            )
            ask[s, p] = g < 0.0
