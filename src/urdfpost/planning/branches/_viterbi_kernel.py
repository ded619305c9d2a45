"""The dynamic programme of :func:`urdfpost.planning.branches.engine._viterbi`, compiled.

numpy runs the recursion over the points as array operations over many points at once: the
step matrices of the blocks whose steps do not depend on the path laid out step by step, their
min-plus products, the costs at the block starts, each block again from its start cost; the
blocks with path-dependent steps (undetermined angles, near the poles) point by point in
Python. Compiled with numba it is the same recursion, block by block and point by point, with
each step matrix computed where it is used and never stored.

The numbers are the numpy path's to the bit: the move and rewind costs are its formulas
(:meth:`~urdfpost.planning.branches.state.BranchSearch._move_cost`, ``_size``, ``_diff``,
:func:`~urdfpost.planning.branches.rules._wrap` as ``pi - mod(pi - a, 2 pi)``) entry by entry
in the same order of operations; the costs at the block starts come from the blocks' min-plus
products (the sums of a block's steps added up first, then to the start cost) and the
recorded costs within a block from its start cost step by step, as numpy adds them; minima
pick the first of equal candidates, as ``argmin`` does. ``tests/test_viterbi.py`` holds the
two to the same choice, costs and predecessors.
"""

from __future__ import annotations

import numpy as np
from numba import njit

_TWO_PI = 2.0 * np.pi


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _wrap(a: float) -> float:
    """``pi - mod(pi - a, 2 pi)`` (numpy's ``mod``: ``fmod`` plus a turn where negative);
    for ``pi - a`` within (-2 pi, 4 pi) a turn added or taken off, which is exact there (as
    :func:`~urdfpost.planning.branches.rules._wrap` does)."""
    m = np.pi - a
    if -_TWO_PI < m < 2.0 * _TWO_PI:
        if m >= _TWO_PI:
            m -= _TWO_PI
        if m < 0.0:
            m += _TWO_PI
        return np.pi - m
    r = np.fmod(m, _TWO_PI)
    if r != 0.0:
        if r < 0.0:
            r += _TWO_PI
    else:
        r = 0.0
    return np.pi - r


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _size(x: float, cont: bool) -> float:
    """How far an axis moves for the difference ``x``: wrapped for a continuous axis, 0 for
    an undetermined angle (NaN), absolute."""
    if cont:
        x = _wrap(x)
    if np.isnan(x):
        x = 0.0
    return abs(x)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _move(
    here: np.ndarray,
    k: int,
    state: np.ndarray,
    s: int,
    weights: np.ndarray,
    cont: np.ndarray,
    switch: bool,
    switch_cost: float,
    regular: bool,
    cutting: bool,
    jump: float,
) -> float:
    """The cost of the move from the actual angles ``state[s]`` to the candidate ``here[k]``
    (:meth:`~urdfpost.planning.branches.state.BranchSearch._move_cost`)."""
    r = here.shape[1]
    s0 = _size(here[k, 0] - state[s, 0], cont[0])
    cost = s0 * weights[0]
    travel = s0
    far = (not cont[0]) and s0 > np.pi
    for a in range(1, r):
        x = _size(here[k, a] - state[s, a], cont[a])
        travel = travel + x
        w = x * weights[a]
        if not cost >= w:  # np.maximum: the first where they tie
            cost = w
        if (not cont[a]) and x > np.pi:
            far = True
    cost += travel
    if regular and switch_cost != 0.0:
        cost += switch_cost if switch else 0.0
    if regular and cutting and ((switch and travel > jump) or far):
        cost = np.inf
    return cost


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _rewind(here: np.ndarray, k: int, state: np.ndarray, t: int, cont: np.ndarray) -> float:
    """How far a rewind from the actual angles ``state[t]`` to the candidate ``here[k]``
    turns the axes (summed in order; the caller adds the rewind cost)."""
    r = here.shape[1]
    total = _size(here[k, 0] - state[t, 0], cont[0])
    for a in range(1, r):
        total = total + _size(here[k, a] - state[t, a], cont[a])
    return total


@njit(cache=True, nogil=True, error_model="numpy")
def _fill(
    values: np.ndarray,
    usable: np.ndarray,
    singular: np.ndarray,
    cutting: np.ndarray,
    may_rewind: np.ndarray,
    switch: np.ndarray,
    weights: np.ndarray,
    cont: np.ndarray,
    switch_cost: float,
    jump: float,
    rewind_cost: float,
    lo: int,
    hi: int,
    moves: np.ndarray,
    layers: np.ndarray,
) -> None:
    """The steps ``lo..hi-1`` of a block whose steps do not depend on the path: the move
    costs into point ``i`` from the candidates of ``i - 1`` (their own angles; without the
    preference cost) in ``moves[i - lo, s, k]``, and where a rewind may follow, the rewind
    layer between the candidates of ``i`` in ``layers[i - lo, t, k]`` (0 on the diagonal: no
    rewind; inf into unusable candidates); as :class:`~urdfpost.planning.branches.engine._Steps`
    lays them out."""
    n_cand = values.shape[1]
    for i in range(lo, hi):
        j = i - lo
        regular = not (singular[i] or singular[i - 1])
        here, prev = values[i], values[i - 1]
        for s in range(n_cand):
            for k in range(n_cand):
                moves[j, s, k] = _move(
                    here,
                    k,
                    prev,
                    s,
                    weights,
                    cont,
                    switch[s, k],
                    switch_cost,
                    regular,
                    cutting[i],
                    jump,
                )
        if may_rewind[i]:
            for t in range(n_cand):
                for k in range(n_cand):
                    if t == k:
                        layers[j, t, k] = 0.0
                    elif not usable[i, k]:
                        layers[j, t, k] = np.inf
                    else:
                        layers[j, t, k] = rewind_cost + _rewind(here, k, here, t, cont)


@njit(cache=True, nogil=True, error_model="numpy")
def _sequential(
    values: np.ndarray,
    usable: np.ndarray,
    pref: np.ndarray,
    singular: np.ndarray,
    cutting: np.ndarray,
    may_rewind: np.ndarray,
    switch: np.ndarray,
    weights: np.ndarray,
    cont: np.ndarray,
    switch_cost: float,
    jump: float,
    rewind_cost: float,
    lo: int,
    hi: int,
    cost: np.ndarray,
    state: np.ndarray,
    back: np.ndarray,
    rback: np.ndarray,
) -> int:
    """:func:`~urdfpost.planning.branches.engine._sequential` over steps ``lo..hi-1``, in
    place on ``cost`` (K,) and ``state`` (K, r); the point of a dead end, or -1."""
    n_cand, r = values.shape[1], values.shape[2]
    diff = np.empty((n_cand, n_cand, r))
    step = np.empty((n_cand, n_cand))
    arrive = np.empty(n_cand)
    arrive_state = np.empty((n_cand, r))
    best = np.empty(n_cand, dtype=np.int64)
    rcost = np.empty(n_cand)
    rbest = np.empty(n_cand, dtype=np.int64)
    rdiff = np.empty((n_cand, n_cand, r))
    for i in range(lo, hi):
        regular = not (singular[i] or singular[i - 1])
        here = values[i]
        for s in range(n_cand):
            for k in range(n_cand):
                for a in range(r):
                    d = here[k, a] - state[s, a]
                    if cont[a]:
                        d = _wrap(d)
                    if np.isnan(d):
                        d = 0.0
                    diff[s, k, a] = d
                step[s, k] = _move(
                    here,
                    k,
                    state,
                    s,
                    weights,
                    cont,
                    switch[s, k],
                    switch_cost,
                    regular,
                    cutting[i],
                    jump,
                )
        finite = False
        for k in range(n_cand):
            m = cost[0] + step[0, k]
            b = 0
            for s in range(1, n_cand):
                x = cost[s] + step[s, k]
                if x < m:
                    m = x
                    b = s
            best[k] = b
            back[i, k] = b
            arrive[k] = m + pref[i, k] if usable[i, k] else np.inf
            for a in range(r):
                arrive_state[k, a] = state[b, a] + diff[b, k, a]
            if np.isfinite(arrive[k]):
                finite = True
        for k in range(n_cand):
            cost[k] = arrive[k]
            for a in range(r):
                state[k, a] = arrive_state[k, a]
        if may_rewind[i] and finite:
            for t in range(n_cand):
                for k in range(n_cand):
                    for a in range(r):
                        d = here[k, a] - arrive_state[t, a]
                        if cont[a]:
                            d = _wrap(d)
                        if np.isnan(d):
                            d = 0.0
                        rdiff[t, k, a] = d
            taken = False
            for k in range(n_cand):
                m = np.inf
                b = 0
                for t in range(n_cand):
                    if t == k:
                        x = arrive[t] + np.inf
                    else:
                        x = arrive[t] + (rewind_cost + _rewind(here, k, arrive_state, t, cont))
                    if t == 0:
                        m = x
                    elif x < m:
                        m = x
                        b = t
                rbest[k] = b
                rcost[k] = m if usable[i, k] else np.inf
                if rcost[k] < arrive[k]:
                    taken = True
            if taken:
                for k in range(n_cand):
                    if rcost[k] < arrive[k]:
                        rback[i, k] = rbest[k]
                        cost[k] = rcost[k]
                        for a in range(r):
                            state[k, a] = arrive_state[rbest[k], a] + rdiff[rbest[k], k, a]
                    else:
                        rback[i, k] = -1
        alive = False
        for k in range(n_cand):
            if np.isfinite(cost[k]):
                alive = True
        if not alive:
            return i
    return -1


@njit(cache=True, nogil=True, error_model="numpy")
def _block_pass(
    usable: np.ndarray,
    pref: np.ndarray,
    may_rewind: np.ndarray,
    lo: int,
    hi: int,
    start: np.ndarray,
    back: np.ndarray,
    rback: np.ndarray,
    moves: np.ndarray,
    layers: np.ndarray,
) -> np.ndarray:
    """:func:`~urdfpost.planning.branches.engine._block_steps` of one block (steps
    ``lo..hi-1``, filled in by :func:`_fill`) from its start cost: fills ``back`` and
    ``rback`` there and returns the cost at its last point, shape (K,)."""
    n_cand = start.shape[0]
    rewound = np.empty(n_cand)
    cost = start.copy()
    arrive = np.empty(n_cand)
    for i in range(lo, hi):
        j = i - lo
        for k in range(n_cand):  # _min_arg: the first least, np.minimum
            m = cost[0] + moves[j, 0, k]
            b = 0
            for s in range(1, n_cand):
                x = cost[s] + moves[j, s, k]
                if x < m:
                    b = s
                if not m <= x:
                    m = x
            back[i, k] = b
            m = m + pref[i, k]
            arrive[k] = np.inf if not usable[i, k] else m
            rback[i, k] = -1
        if may_rewind[i]:
            for k in range(n_cand):
                m = arrive[0] + layers[j, 0, k]
                b = 0
                for t in range(1, n_cand):
                    x = arrive[t] + layers[j, t, k]
                    if x < m:
                        b = t
                    if not m <= x:
                        m = x
                if m < arrive[k]:
                    rback[i, k] = b
                rewound[k] = m
            for k in range(n_cand):
                if not arrive[k] <= rewound[k]:
                    arrive[k] = rewound[k]
        for k in range(n_cand):
            cost[k] = arrive[k]
    return cost


@njit(cache=True, nogil=True, error_model="numpy")
def _block_product(
    usable: np.ndarray,
    pref: np.ndarray,
    may_rewind: np.ndarray,
    lo: int,
    hi: int,
    moves: np.ndarray,
    layers: np.ndarray,
) -> np.ndarray:
    """:func:`~urdfpost.planning.branches.engine._block_products` of one block (steps
    ``lo..hi-1``, filled in by :func:`_fill`): the min-plus product of its steps with the
    preference costs and rewinds, shape (K, K)."""
    n_cand = usable.shape[1]
    out = np.full((n_cand, n_cand), np.inf)
    for k in range(n_cand):
        out[k, k] = 0.0
    move = np.empty((n_cand, n_cand))
    turned = np.empty((n_cand, n_cand))
    product = np.empty((n_cand, n_cand))
    for i in range(lo, hi):
        j = i - lo
        for s in range(n_cand):
            for k in range(n_cand):
                move[s, k] = np.inf if not usable[i, k] else moves[j, s, k] + pref[i, k]
        step = move
        if may_rewind[i]:  # min-plus with the rewind layer
            for s in range(n_cand):
                for k in range(n_cand):
                    m = move[s, 0] + layers[j, 0, k]
                    for t in range(1, n_cand):
                        x = move[s, t] + layers[j, t, k]
                        if not m <= x:  # np.minimum
                            m = x
                    turned[s, k] = m
            step = turned
        for s in range(n_cand):  # out = out (min-plus) step
            for k in range(n_cand):
                m = out[s, 0] + step[0, k]
                for t in range(1, n_cand):
                    x = out[s, t] + step[t, k]
                    if not m <= x:
                        m = x
                product[s, k] = m
        out, product = product, out
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def viterbi(
    values: np.ndarray,
    usable: np.ndarray,
    pref: np.ndarray,
    singular: np.ndarray,
    cutting: np.ndarray,
    may_rewind: np.ndarray,
    irregular: np.ndarray,
    switch: np.ndarray,
    weights: np.ndarray,
    cont: np.ndarray,
    switch_cost: float,
    jump: float,
    rewind_cost: float,
    cost0: np.ndarray,
    state0: np.ndarray,
    block: int,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """The recursion of :func:`~urdfpost.planning.branches.engine._viterbi` over the whole
    path (no collision exclusions of moves or rewinds).

    Parameters
    ----------
    values : ndarray, shape (n, K, r), rad
        Candidate angles (NaN where undetermined).
    usable : ndarray, shape (n, K), bool
    pref : ndarray, shape (n, K)
        Preference costs.
    singular, cutting, may_rewind, irregular : ndarray, shape (n,), bool
        Singular points, cutting moves into the points, whether a rewind may follow the
        arrival, and points the steps into which depend on the path.
    switch : ndarray, shape (K, K), bool
    weights : ndarray, shape (r,)
    cont : ndarray, shape (r,), bool
    switch_cost, jump, rewind_cost : float
    cost0 : ndarray, shape (K,)
    state0 : ndarray, shape (K, r), rad
    block : int
        Points per block.

    Returns
    -------
    back, rback : ndarray, shape (n, K), int32
        Best predecessors, and the candidates rewound from (-1: none).
    cost : ndarray, shape (K,)
        Costs at the last point.
    dead : int
        The point of a dead end (no candidate reachable), or -1.
    """
    n, n_cand = values.shape[0], values.shape[1]
    back = np.zeros((n, n_cand), dtype=np.int32)
    rback = np.full((n, n_cand), -1, dtype=np.int32)
    cost = cost0.copy()
    state = state0.copy()
    args = (values, usable, pref, singular, cutting, may_rewind, switch, weights, cont)
    last_bulk = False
    ends = cost
    moves = np.empty((block, n_cand, n_cand))
    layers = np.empty((block, n_cand, n_cand))
    for a in range(1, n, block):
        e = min(a + block, n)
        seq = False
        for i in range(a, e):
            if irregular[i]:
                seq = True
                break
        last_bulk = not seq
        if not seq:
            _fill(
                values,
                usable,
                singular,
                cutting,
                may_rewind,
                switch,
                weights,
                cont,
                switch_cost,
                jump,
                rewind_cost,
                a,
                e,
                moves,
                layers,
            )
            product = _block_product(usable, pref, may_rewind, a, e, moves, layers)
            new = np.empty(n_cand)
            finite = False
            for k in range(n_cand):
                m = cost[0] + product[0, k]
                for s in range(1, n_cand):
                    x = cost[s] + product[s, k]
                    if not m <= x:
                        m = x
                new[k] = m
                if np.isfinite(m):
                    finite = True
            if finite:
                ends = _block_pass(usable, pref, may_rewind, a, e, cost, back, rback, moves, layers)
                cost = new
                state = values[e - 1].copy()
                continue
        start = cost.copy()
        dead = _sequential(*args, switch_cost, jump, rewind_cost, a, e, cost, state, back, rback)
        if dead >= 0:
            return back, rback, cost, dead
        if not seq:  # (numpy records a bulk block's predecessors from its start afterwards)
            ends = _block_pass(usable, pref, may_rewind, a, e, start, back, rback, moves, layers)
    if last_bulk:
        cost = ends  # the recorded arithmetic, which the predecessors follow
    return back, rback, cost, -1


@njit(cache=True, nogil=True)
def follow_back(
    k_end: int, back: np.ndarray, rback: np.ndarray, alive: np.ndarray
) -> tuple[np.ndarray, np.ndarray, int]:
    """:func:`~urdfpost.planning.branches.engine._follow_back`: the candidates along the best
    path from ``k_end`` at the last point, and the last point where the best paths into the
    ``alive`` candidates of the last point all leave with the same candidate (-1: none).

    Returns
    -------
    chosen, arrive : ndarray, shape (n,), int64
    settled : int
    """
    n, n_cand = back.shape
    chosen = np.empty(n, dtype=np.int64)
    arrive = np.empty(n, dtype=np.int64)
    k = k_end
    for i in range(n - 1, -1, -1):
        chosen[i] = k
        a = rback[i, k] if rback[i, k] >= 0 else k
        arrive[i] = a
        k = back[i, a]
    at = np.zeros(n_cand, dtype=np.bool_)
    count = 0
    for k in range(n_cand):
        if alive[k]:
            at[k] = True
            count += 1
    if count <= 1:
        return chosen, arrive, n - 1
    nxt = np.zeros(n_cand, dtype=np.bool_)
    for i in range(n - 1, -1, -1):
        if count == 1:
            return chosen, arrive, i
        nxt[:] = False
        count = 0
        for k in range(n_cand):
            if at[k]:
                a = rback[i, k] if rback[i, k] >= 0 else k
                p = back[i, a]
                if not nxt[p]:
                    nxt[p] = True
                    count += 1
        at[:] = nxt
    return chosen, arrive, -1
