"""The min-plus (Viterbi) engine of the branch planner.

:func:`_viterbi` finds the least-cost path over the candidates of every point, with a rewind
layer at each point: in blocks of min-plus products where the step costs do not depend on the
path (:class:`_Steps`, :func:`_block_products`, :func:`_block_steps`), point by point where
they do (:func:`_sequential`). :func:`_follow_back` follows the predecessors back and says how
far the choice is settled (:func:`_settled`); :func:`_angles_along` rebuilds the actual angles
along the chosen path. :func:`_greedy` is the local planner: each point nearest the previous
one.

Every function reads the search state
(:class:`~urdfpost.planning.branches.state.BranchSearch`: candidates, costs, exclusions) and
none changes it.
"""

from __future__ import annotations

from types import ModuleType

import numpy as np

from urdfpost._compiled import Kernels
from urdfpost.planning.branches._arrays import _CHUNK, _rows_any, _total
from urdfpost.planning.branches.costs import JUMP, REWIND_COST
from urdfpost.planning.branches.exclusion import _raise_dead_end
from urdfpost.planning.branches.rules import _wrap
from urdfpost.planning.branches.state import BranchSearch

_MIN_PLUS_BLOCK = (8, 512)  # smallest and largest block of the blocked recursion, points
_CACHE_BYTES = 256e6  # step matrices kept between the passes when they fit in this
_COPY = 262144  # array entries per copy when laying arrays out anew


def _load_kernels() -> ModuleType:
    from urdfpost.planning.branches import _viterbi_kernel

    return _viterbi_kernel


KERNELS = Kernels(_load_kernels, "branch choice")
"""The compiled recursion (:mod:`urdfpost.planning.branches._viterbi_kernel`), loaded by
:func:`_viterbi` for a large path (:data:`urdfpost._compiled.COMPILED_FROM`)."""


def _min_plus(a: np.ndarray, b: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """Min-plus products of matrices stacked along the last axis, (K, K, j) x (K, K, j) ->
    (K, K, j).

    One sum and one minimum per inner index, each over all matrices at once (the minimum is
    exact, so the order does not matter). ``out`` must not overlap ``a`` or ``b``.
    """
    out = np.add(a[:, :1], b[None, 0], out=out)
    if len(a) > 1:
        term = np.empty_like(out)
        for t in range(1, len(a)):
            np.minimum(out, np.add(a[:, t : t + 1], b[None, t], out=term), out=out)
    return out


def _min_arg(
    cost: np.ndarray, step: np.ndarray, out: np.ndarray, arg: np.ndarray, scratch: np.ndarray
) -> None:
    """Least ``cost[s] + step[s, k]`` over the rows s, with the first row that gives it (what
    ``argmin`` picks), for matrices stacked along the last axis.

    Parameters
    ----------
    cost : ndarray, shape (K, j)
    step : ndarray, shape (K, K, j)
    out : ndarray, shape (K, j)
        Filled with the least costs.
    arg : ndarray, shape (K, j), int
        Filled with their rows.
    scratch : ndarray, shape (K, j)
    """
    np.add(cost[0], step[0], out=out)
    arg.fill(0)
    for s in range(1, len(cost)):
        term = np.add(cost[s], step[s], out=scratch)
        np.copyto(arg, s, where=term < out)
        np.minimum(out, term, out=out)


def _viterbi(
    p: BranchSearch, block: int | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, int]:
    """Least-cost candidates over the whole path, with rewinds where needed.

    The recursion over the points, ``cost_i[k] = min_s cost_{i-1}[s] + step_i[s, k]`` (then the
    rewind layer at the point), is a chain of min-plus products of the step matrices. Where a
    step's costs do not depend on the path (neither end holds an undetermined angle and no
    collision excluded a move there), they are computed for many points at once, and the
    chain is evaluated in blocks: the min-plus product of each block's steps (all blocks at
    once, one point of each per array operation), then the costs at the block starts (one
    small product per block, in order), then each block again from its start cost, recording
    the best predecessors (all blocks at once). Blocks with path-dependent steps are run point
    by point from their start state. The predecessors are followed back the same way (maps
    composed per block), and the actual (unwrapped) angles are rebuilt along the chosen path.

    With a few candidates per point numpy's cost is per operation, not per number: the step
    matrices of the blocks done at once are laid out step by step with the blocks last
    (:class:`_Steps`), so that each operation of the block passes runs along all blocks in
    contiguous memory, and they are made a few thousand entries per operation (temporaries
    in cache). The layout changes no number: each is the same operations in the same order.

    Parameters
    ----------
    p : BranchSearch
    block : int, optional
        Points per block (default about the square root of the path length).

    Returns
    -------
    chosen : ndarray, shape (n,), int
        Candidate the path leaves each point with.
    arrive : ndarray, shape (n,), int
        Candidate it arrives with (differs at rewinds).
    rot_leave, rot_arrive : ndarray, shape (n, r), rad
        The actual (unwrapped) angles.
    settled : int
        The last point whose choice no later CL points could change (-1: none; see
        :func:`_follow_back`).
    """
    n, n_cand, _ = p.values.shape
    usable = p.usable()
    cost0, state0 = p.first_state()
    back = np.zeros((n, n_cand), dtype=np.int32)
    rback = np.full((n, n_cand), -1, dtype=np.int32)
    held = np.zeros(n, dtype=bool)  # a usable candidate holds an undetermined angle
    for k in range(n_cand):
        held |= _rows_any(np.isnan(p.values[:, k])) & usable[:, k]
    irregular = np.zeros(n, dtype=bool)  # steps into these points depend on the path
    irregular[1:] = held[1:] | held[:-1]
    irregular[list(p.exclude.moves) + list(p.exclude.rewinds)] = True
    irregular[0] = False
    if block is None:
        block = int(np.clip(np.sqrt(n), *_MIN_PLUS_BLOCK))
    kernel = KERNELS.get(n)
    if kernel is not None and not (p.exclude.moves or p.exclude.rewinds):
        try:
            found = _compiled(kernel, p, usable, irregular, cost0, state0, block)
        except Exception as err:  # numba could not compile or cache it here: numpy runs
            KERNELS.fail(err)
        else:
            chosen, arrive, settled, dead = found
            if dead >= 0:
                _raise_dead_end(p, dead)
            rot_leave, rot_arrive = _angles_along(p, state0, chosen, arrive)
            return chosen, arrive, rot_leave, rot_arrive, settled
    first = np.arange(1, n, block)  # first step of each block
    last = np.minimum(first + block, n)  # one past its last
    seq = np.logical_or.reduceat(irregular, first) if len(first) else np.zeros(0, dtype=bool)
    bulk = np.flatnonzero(~seq)
    product_of = np.cumsum(~seq) - 1  # block -> its product (bulk blocks)
    # the bulk blocks in runs whose step matrices fit in _CACHE_BYTES: one run has them
    # computed once for both passes, several have them computed again for the second
    size = max(1, int(_CACHE_BYTES // (block * _Steps.bytes_per_step(n_cand))))
    runs = [slice(a, a + size) for a in range(0, len(bulk), size)]
    products = np.empty((len(bulk), n_cand, n_cand))
    kept: _Steps | None = None
    for run in runs:
        kept = _Steps(p, usable, first[bulk[run]], last[bulk[run]])
        products[run] = _block_products(kept)
    # costs at the block starts, in order
    starts = np.empty((len(first), n_cand))
    cost, state = cost0, state0
    for b, (a, e) in enumerate(zip(first, last, strict=True)):
        starts[b] = cost
        if not seq[b]:
            new = (cost[:, None] + products[product_of[b]]).min(axis=0)
            if np.isfinite(new).any():
                cost, state = new, p.values[e - 1]
                continue
        # path-dependent steps, or a dead end to locate: point by point
        cost, state = _sequential(p, usable, a, e, cost, state, back, rback)
    ends = np.empty((len(bulk), n_cand))
    for run in reversed(runs):  # the last run first: its step matrices are still there
        steps = kept or _Steps(p, usable, first[bulk[run]], last[bulk[run]])
        kept = None
        ends[run] = _block_steps(steps, starts[bulk[run]], back, rback)
    if len(first) and not seq[-1]:
        cost = ends[-1]  # the recorded arithmetic, which the predecessors follow
    chosen, arrive, settled = _follow_back(
        int(np.argmin(cost)), back, rback, block, np.isfinite(cost)
    )
    rot_leave, rot_arrive = _angles_along(p, state0, chosen, arrive)
    return chosen, arrive, rot_leave, rot_arrive, settled


def _compiled(
    kernel: ModuleType,
    p: BranchSearch,
    usable: np.ndarray,
    irregular: np.ndarray,
    cost0: np.ndarray,
    state0: np.ndarray,
    block: int,
) -> tuple[np.ndarray, np.ndarray, int, int]:
    """The recursion and the path followed back, compiled
    (:func:`urdfpost.planning.branches._viterbi_kernel.viterbi` and ``follow_back``: the
    numbers of the numpy passes); the chosen and arrival candidates, the settled point (as
    :func:`_follow_back`), and the point of a dead end (-1: none; the caller raises there,
    as :func:`_sequential` does)."""
    n = len(usable)
    back, rback, cost, dead = kernel.viterbi(
        np.ascontiguousarray(p.values, dtype=float),
        np.ascontiguousarray(usable, dtype=bool),
        np.ascontiguousarray(p.pref_cost, dtype=float),
        np.ascontiguousarray(p.singular, dtype=bool),
        np.ascontiguousarray(p.cutting, dtype=bool),
        np.ascontiguousarray(p.rewinds_at(np.arange(n)), dtype=bool),
        np.ascontiguousarray(irregular, dtype=bool),
        np.ascontiguousarray(p.switch, dtype=bool),
        np.ascontiguousarray(p.weights, dtype=float),
        np.ascontiguousarray(p.cont, dtype=bool),
        float(p.switch_cost),
        float(JUMP),
        float(REWIND_COST),
        np.ascontiguousarray(cost0, dtype=float),
        np.ascontiguousarray(state0, dtype=float),
        int(block),
    )
    if dead >= 0:
        return back[:0, 0], back[:0, 0], -1, int(dead)
    chosen, arrive, settled = kernel.follow_back(
        int(np.argmin(cost)), back, rback, np.isfinite(cost)
    )
    return chosen, arrive, int(settled), -1


def _sequential(
    p: BranchSearch,
    usable: np.ndarray,
    lo: int | np.integer,
    hi: int | np.integer,
    cost: np.ndarray,
    state: np.ndarray,
    back: np.ndarray,
    rback: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """The recursion point by point over steps ``lo..hi-1`` from ``cost`` and the actual
    angles ``state`` (K, r) at point ``lo - 1``; fills ``back`` and ``rback`` there."""
    cols = np.arange(len(cost))
    may_rewind = p.rewinds_at(np.arange(lo, hi))
    for i in range(lo, hi):
        diff, step = p.steps(i, state)
        total = cost[:, None] + step
        best = np.argmin(total, axis=0)
        arrive_cost = np.where(usable[i], total[best, cols] + p.pref_cost[i], np.inf)
        arrive_state = state[best] + diff[best, cols]
        back[i] = best
        cost, state = arrive_cost, arrive_state
        if may_rewind[i - lo] and np.isfinite(arrive_cost).any():
            rdiff, rstep = p.rewind_steps(i, arrive_state)
            rtotal = arrive_cost[:, None] + rstep
            rbest = np.argmin(rtotal, axis=0)
            rcost = np.where(usable[i], rtotal[rbest, cols], np.inf)
            take = rcost < arrive_cost
            if take.any():
                rback[i] = np.where(take, rbest, -1)
                cost = np.where(take, rcost, arrive_cost)
                state = np.where(take[:, None], arrive_state[rbest] + rdiff[rbest, cols], state)
        if not np.isfinite(cost).any():
            _raise_dead_end(p, i)
    return cost, state


def _by_step(a: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """``a[rows]`` laid out step by step with the blocks last: ``out[j, ..., b]`` is
    ``a[rows[b, j]]``.

    Gathered and moved a few blocks at a time, so that what is read and written stays in the
    cache and the address translation buffers (a point's neighbours along the path are far
    apart in the result).
    """
    out = np.empty((rows.shape[1], *a.shape[1:], rows.shape[0]), dtype=a.dtype)
    per = max(1, _COPY // max(1, rows.shape[1] * a[0].size))
    for lo in range(0, len(rows), per):
        out[..., lo : lo + per] = np.moveaxis(np.take(a, rows[lo : lo + per], axis=0), 0, -1)
    return out


def _blocks_last(a: np.ndarray) -> np.ndarray:
    """The first axis of ``a`` (the blocks) moved last, as a new array, a few blocks at a
    time (as :func:`_by_step`)."""
    out = np.empty((*a.shape[1:], a.shape[0]), dtype=a.dtype)
    per = max(1, _COPY // max(1, a[0].size))
    for lo in range(0, len(a), per):
        out[..., lo : lo + per] = np.moveaxis(a[lo : lo + per], 0, -1)
    return out


def _blocks_first(a: np.ndarray) -> np.ndarray:
    """The last axis of ``a`` (the blocks) moved first, as a new array, a few blocks at a
    time (as :func:`_by_step`)."""
    out = np.empty((a.shape[-1], *a.shape[:-1]), dtype=a.dtype)
    per = max(1, _COPY // max(1, out[0].size))
    for lo in range(0, len(out), per):
        out[lo : lo + per] = np.moveaxis(a[..., lo : lo + per], -1, 0)
    return out


class _Steps:
    """Step matrices of a run of blocks whose steps do not depend on the path (neither end
    holds an undetermined angle), laid out step by step with the blocks last (``move[j, s,
    k, b]``: step ``j`` of block ``b``), so that each step of the block passes takes slices
    and works along the blocks. The blocks are as long as the first but the last, which may
    be shorter: the first ``count[j]`` have a step ``j``.

    Attributes
    ----------
    move : ndarray, shape (J, K, K, B)
        Move costs (without the preference cost of the candidate).
    layer : ndarray, shape (J, K, K, B), or None
        Rewind layers: 0 on the diagonal (no rewind), the rewind costs into usable
        candidates elsewhere where a rewind may follow, inf otherwise; None where no rewind
        may follow in the run.
    rewinds : ndarray, shape (J,), bool
        Whether a rewind may follow step ``j`` in some block.
    pref : ndarray, shape (J, K, B)
        Preference costs of the candidates.
    unusable : ndarray, shape (J, K, B), bool
    count : ndarray, shape (J,), int
    first, last : ndarray, shape (B,), int
        The blocks' first steps and one past their last.
    """

    def __init__(
        self, p: BranchSearch, usable: np.ndarray, first: np.ndarray, last: np.ndarray
    ) -> None:
        self.first, self.last = first, last
        n_cand, r = p.values.shape[1:]
        n_steps = int((last - first).max(initial=0))
        steps = np.arange(n_steps + 1)
        # the point before each block and its points (past its end: its last point)
        rows = np.minimum(first[:, None] - 1 + steps, (last - 1)[:, None])
        at = np.ascontiguousarray(rows.T)  # step by step
        inside = steps[:-1] < (last - first)[:, None]
        self.count = inside.sum(axis=0)
        singular = p.singular[at]
        regular = ~(singular[1:] | singular[:-1])
        cutting = p.cutting[at[1:]]
        may = p.rewinds_at(at[1:]) & inside.T
        self.rewinds = may.any(axis=1)
        self.pref = _by_step(p.pref_cost, rows[:, 1:])
        self.unusable = _by_step(usable, rows[:, 1:])
        np.logical_not(self.unusable, out=self.unusable)
        self.move = np.empty((n_steps, n_cand, n_cand, len(first)))
        self.layer = np.empty_like(self.move) if may.any() else None
        switch = p.switch[:, :, None]
        k = np.arange(n_cand)
        per = max(1, _CHUNK // (n_cand * n_cand * len(first)))
        for lo in range(0, n_steps, per):
            s = slice(lo, min(lo + per, n_steps))
            values = np.take(p.values, at[s.start : s.stop + 1], axis=0)  # (j + 1, B, K, r)
            values = np.ascontiguousarray(np.moveaxis(values, 1, -1))
            here, prev = values[1:], values[:-1]
            nan = bool(np.isnan(here).any() or np.isnan(prev).any())
            size = [p._size(here[:, None, :, a] - prev[:, :, None, a], a, nan) for a in range(r)]
            p._move_cost(size, regular[s, None, None], cutting[s, None, None], switch, self.move[s])
            if self.layer is None:
                continue
            layer = self.layer[s]
            if may[s].any():
                size = [
                    p._size(here[:, None, :, a] - here[:, :, None, a], a, nan) for a in range(r)
                ]
                np.add(REWIND_COST, _total(size), out=layer)
                np.copyto(layer, np.inf, where=~may[s, None, None])
                np.copyto(layer, np.inf, where=self.unusable[s, None])
            else:
                layer.fill(np.inf)
            layer[:, k, k] = 0.0

    @staticmethod
    def bytes_per_step(n_cand: int) -> int:
        """Memory a step of one block takes (its matrices, costs and indices), bytes."""
        return 16 * n_cand * n_cand + 9 * n_cand + 24


def _block_products(s: _Steps) -> np.ndarray:
    """Min-plus product of the steps of each block (moves, preference costs, rewinds), all
    blocks at once, shape (B, K, K)."""
    n_cand, n_blocks = s.move.shape[2:]
    eye = np.eye(n_cand, dtype=bool)[:, :, None]
    out = np.where(eye, 0.0, np.inf).repeat(n_blocks, axis=2)
    step, turned, product = np.empty_like(out), np.empty_like(out), np.empty_like(out)
    for j, c in enumerate(s.count):
        move = np.add(s.move[j, ..., :c], s.pref[j, None, :, :c], out=step[..., :c])
        np.copyto(move, np.inf, where=s.unusable[j, None, :, :c])
        if s.layer is not None and s.rewinds[j]:
            move = _min_plus(move, s.layer[j, ..., :c], out=turned[..., :c])
        out[..., :c] = _min_plus(out[..., :c], move, out=product[..., :c])
    return _blocks_first(out)


def _block_steps(s: _Steps, starts: np.ndarray, back: np.ndarray, rback: np.ndarray) -> np.ndarray:
    """The recursion within each block from its start cost (``starts``, shape (B, K)), all
    blocks at once; fills ``back`` and ``rback`` (same arithmetic as :func:`_sequential`)
    and returns the costs at the blocks' last points, shape (B, K).

    The rewind layer's zero diagonal stands for no rewind: a rewind is taken where it is
    cheaper than arriving, as in :func:`_sequential`, whose diagonal is inf."""
    cost = starts.T.copy()
    back_s = np.zeros(s.pref.shape, dtype=back.dtype)
    rback_s = np.full_like(back_s, -1)
    arrive, rcost, scratch = np.empty_like(cost), np.empty_like(cost), np.empty_like(cost)
    best = np.empty(cost.shape, dtype=np.intp)
    for j, c in enumerate(s.count):
        _min_arg(cost[:, :c], s.move[j, ..., :c], arrive[:, :c], best[:, :c], scratch[:, :c])
        back_s[j, :, :c] = best[:, :c]
        arrive[:, :c] += s.pref[j, :, :c]
        np.copyto(arrive[:, :c], np.inf, where=s.unusable[j, :, :c])
        if s.layer is not None and s.rewinds[j]:
            _min_arg(arrive[:, :c], s.layer[j, ..., :c], rcost[:, :c], best[:, :c], scratch[:, :c])
            np.copyto(rback_s[j, :, :c], best[:, :c], where=rcost[:, :c] < arrive[:, :c])
            np.minimum(arrive[:, :c], rcost[:, :c], out=arrive[:, :c])
        cost[:, :c] = arrive[:, :c]
    # back into point order, a run of adjacent blocks at a time (all as long as the first
    # but the last)
    back_b, rback_b = _blocks_first(back_s), _blocks_first(rback_s)
    n_cand = back.shape[1]
    cut = np.flatnonzero(s.first[1:] != s.last[:-1]) + 1
    for lo, hi in zip(np.r_[0, cut], np.r_[cut, len(s.first)], strict=True):
        a, e = s.first[lo], s.last[hi - 1]
        back[a:e] = back_b[lo:hi].reshape(-1, n_cand)[: e - a]
        rback[a:e] = rback_b[lo:hi].reshape(-1, n_cand)[: e - a]
    return cost.T


def _follow_back(
    k_end: int, back: np.ndarray, rback: np.ndarray, block: int, alive: np.ndarray
) -> tuple[np.ndarray, np.ndarray, int]:
    """Candidates along the best path from the last point's ``k_end``, back to the first, and
    how far the paths into every ``alive`` candidate of the last point agree.

    At each point ``i`` the path leaves with ``chosen[i]``, arrived with ``arrive[i]``
    (``rback`` where a rewind was taken) and came from ``back[i, arrive[i]]``. The maps from
    the candidate at a block's last point to that before its first are composed for all
    blocks at once, followed block by block, then every block is walked at once. The blocks
    end at the last point; the first is filled up with points that keep the candidate.

    The best paths into the alive candidates of the last point (the survivors) are followed
    back as a set, block by block and then step by step in the block where they meet: once
    two meet they agree on every point before. Whatever points came after the last one, the
    best path over them all would continue one of the survivors, so its choices up to the
    point where all survivors agree are these (the choice there is settled).

    Returns
    -------
    chosen, arrive : ndarray, shape (n,), int
    settled : int
        The last point where every survivor leaves with the same candidate (-1: none).
    """
    n, n_cand = back.shape
    keep = np.arange(n_cand)
    rewound = rback >= 0
    arrive_of = np.where(rewound, rback, keep[None, :]) if rewound.any() else None  # (n, K)
    # leave at i -> leave at i - 1
    came = back if arrive_of is None else np.take_along_axis(back, arrive_of, axis=1)
    n_blocks = -(-n // block)
    pad = n_blocks * block - n
    maps = np.empty((n_blocks * block, n_cand), dtype=came.dtype)
    maps[:pad] = keep
    maps[pad:] = came
    maps = _blocks_last(maps.reshape(n_blocks, block, n_cand))  # [j, :, b]: step j of block b
    at = np.arange(n_blocks)  # each block's column in a step's flattened maps
    # composed maps: leave at a block's last point -> leave at the point before its first
    comp = np.repeat(keep[:, None], n_blocks, axis=1)
    for j in range(block - 1, -1, -1):
        comp = np.take(maps[j], comp * n_blocks + at)
    ends = np.empty(n_blocks, dtype=np.int64)
    k = k_end
    for b in range(n_blocks - 1, -1, -1):
        ends[b] = k
        k = int(comp[k, b])
    settled = _settled(np.flatnonzero(alive), comp, maps, block, pad)
    chosen = np.empty((block, n_blocks), dtype=np.int64)
    cur = ends
    for j in range(block - 1, -1, -1):
        chosen[j] = cur
        cur = np.take(maps[j], cur * n_blocks + at)
    leave = _blocks_first(chosen).reshape(-1)[pad:]
    if arrive_of is None:
        return leave, leave.copy(), settled
    return leave, np.take(arrive_of, leave + np.arange(n) * n_cand), settled


def _settled(
    survivors: np.ndarray, comp: np.ndarray, maps: np.ndarray, block: int, pad: int
) -> int:
    """The last point where the paths into ``survivors`` (candidates at the last point) all
    leave with the same candidate, -1 when they never do (:func:`_follow_back`'s maps:
    ``comp[:, b]`` over block b, ``maps[j][k, b]`` over its step j, ``pad`` points of filling
    before the first)."""
    n_blocks = comp.shape[1]
    last = n_blocks * block - 1 - pad
    if len(survivors) <= 1:
        return last
    at = survivors
    for b in range(n_blocks - 1, -1, -1):
        before = np.unique(comp[at, b])
        if len(before) > 1:
            at = before
            continue
        for j in range(block - 1, -1, -1):  # they meet in block b: where
            if len(at) == 1:
                return max(b * block + j - pad, -1)
            at = np.unique(maps[j][at, b])
        return max(b * block - 1 - pad, -1)
    return -1


def _angles_along(
    p: BranchSearch, state0: np.ndarray, chosen: np.ndarray, arrive: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Actual rotary angles along the chosen path, shapes (n, r) each (leave, arrive).

    The path arrives at each point and leaves it (after a rewind, on another candidate). Along
    that sequence limited axes take the candidates' values, an undetermined angle holds the
    last determined one, and continuous axes take the shortest rotation from the previous
    value (the first point starts from ``state0``, the candidate's angles nearest the start).
    A point without a rewind is one state in the sequence: the step from arriving to leaving
    it would be zero, and adds nothing to the running sums.
    """
    n, n_cand, r = p.values.shape
    flat = p.values.reshape(-1, r)
    at = np.arange(n) * n_cand
    turn = chosen != arrive  # never at the first point
    into = out = None
    if turn.any():
        into = np.arange(n) + np.cumsum(turn) - turn  # where each arrival is in the sequence
        out = into + turn
        seq = np.empty((n + int(turn.sum()), r))
        seq[into] = np.take(flat, at + arrive, axis=0)
        seq[out] = np.take(flat, at + chosen, axis=0)
    else:
        seq = np.take(flat, at + chosen, axis=0)
    seq[0] = state0[chosen[0]]
    for a in range(r):
        known = ~np.isnan(seq[:, a])
        if known.all():
            continue
        seq[:, a] = seq[np.maximum.accumulate(np.where(known, np.arange(len(seq)), 0)), a]
    for c in np.flatnonzero(p.cont):
        col = seq[:, c]
        col[1:] = col[0] + np.cumsum(_wrap(np.diff(col)))
    if into is None or out is None:
        return seq, seq.copy()
    return seq[out], seq[into]


def _greedy(p: BranchSearch) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Each point takes the candidate nearest the previous point's angles; where no candidate
    goes on continuously, a rewind at the previous point to the candidate that does."""
    n, _, r = p.values.shape
    usable = p.usable()
    cost0, state0 = p.first_state()
    k = int(np.argmin(cost0))
    cur = state0[k].copy()
    leave = np.empty((n, r))
    arrive_rot = np.empty((n, r))
    chosen = np.empty(n, dtype=np.int64)
    arrive = np.empty(n, dtype=np.int64)
    leave[0] = arrive_rot[0] = cur
    chosen[0] = arrive[0] = k
    for i in range(1, n):
        diff, step = p.steps(i, cur[None, :])
        step = np.where(usable[i], step[0] + 1e-9 * p.branch, np.inf)
        if not np.isfinite(step).any():
            # rewind at the previous point onto a candidate that goes on from there
            rdiff, rcost = p.rewind_steps(i - 1, cur[None, :])
            rcost = np.where(usable[i - 1], rcost[0], np.inf)
            for kk in np.argsort(rcost):
                if not np.isfinite(rcost[kk]):
                    break
                turned = cur + rdiff[0, kk]
                d2, s2 = p.steps(i, turned[None, :])
                s2 = np.where(usable[i], s2[0], np.inf)
                if np.isfinite(s2).any():
                    chosen[i - 1] = kk
                    leave[i - 1] = cur = turned
                    diff, step = d2, s2
                    break
            else:
                _raise_dead_end(p, i)
        k = int(np.argmin(step))
        cur = cur + diff[0, k]
        leave[i] = arrive_rot[i] = cur
        chosen[i] = arrive[i] = k
    return chosen, arrive, leave, arrive_rot
