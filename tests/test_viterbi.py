"""The blocked Viterbi recursion of the branch planner against the plain point-by-point one.

The reference below is the planner's recursion as it was first written (one point after the
other, the actual angles carried along): the blocked version must choose the same candidates
and give the same angles on every path, machine and block size, with poles (path-dependent
held angles), rewinds, entries and collision exclusions.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from urdfpost import load_machine
from urdfpost.analysis.testpaths import PATHS
from urdfpost.errors import UnreachableError
from urdfpost.planning.branches import JUMP, REWIND_COST, TWO_PI, Preference, engine, search, select
from urdfpost.planning.branches.exclusion import _raise_dead_end
from urdfpost.planning.branches.rules import _wrap
from urdfpost.planning.branches.state import BranchSearch

ROOT = Path(__file__).resolve().parents[1]
MACHINES = ("dmu50", "gantry-ca", "dmu50-nutating", "umc750", "monoblock", "xyzac-trt")


# -- the reference: the recursion point by point -----------------------------------------------


def _ref_diff(p: BranchSearch, i: int, state: np.ndarray) -> np.ndarray:
    diff = p.values[i][None, :, :] - state[:, None, :]
    diff[:, :, p.cont] = _wrap(diff[:, :, p.cont])
    return np.nan_to_num(diff, nan=0.0)


def _ref_steps(p: BranchSearch, i: int, state: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    diff = _ref_diff(p, i, state)
    cont = p.cont
    size = np.abs(diff)
    cost = size.sum(axis=2) + (size * p.weights).max(axis=2, initial=0.0)
    if not (p.singular[i] or p.singular[i - 1]):
        switch = p.branch[:, None] != p.branch[None, :]
        cost = cost + p.switch_cost * switch
        if p.cutting[i]:
            jump = switch & (size.sum(axis=2) > JUMP) | (size[:, :, ~cont] > np.pi).any(axis=2)
            cost = np.where(jump, np.inf, cost)
    for kp, k in p.exclude.moves.get(i, ()):
        cost[kp, k] = np.inf
    return diff, cost


def _ref_rewind_steps(p: BranchSearch, i: int, state: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    diff = _ref_diff(p, i, state)
    cost = REWIND_COST + np.abs(diff).sum(axis=2)
    np.fill_diagonal(cost, np.inf)
    for ki, k in p.exclude.rewinds.get(i, ()):
        cost[ki, k] = np.inf
    return diff, cost


def reference(p: BranchSearch, block: int | None = None):
    n, n_cand, r = p.values.shape
    usable = p.usable()
    state = p.values[0].copy()
    state[:, 0] = np.where(np.isnan(state[:, 0]), p.start[0], state[:, 0])
    cont = p.cont
    state[:, cont] += TWO_PI * np.round((p.start[cont] - state[:, cont]) / TWO_PI)
    cost = np.where(usable[0], p.pref_cost[0], np.inf)
    back = np.zeros((n, n_cand), dtype=np.int32)
    rback = np.full((n, n_cand), -1, dtype=np.int32)
    leave_hist = np.empty((n, n_cand, r))
    arrive_hist = np.empty((n, n_cand, r))
    leave_hist[0] = arrive_hist[0] = state
    cols = np.arange(n_cand)
    for i in range(1, n):
        diff, step = _ref_steps(p, i, state)
        total = cost[:, None] + step
        best = np.argmin(total, axis=0)
        arrive_cost = np.where(usable[i], total[best, cols] + p.pref_cost[i], np.inf)
        arrive_state = state[best] + diff[best, cols]
        back[i] = best
        arrive_hist[i] = arrive_state
        cost, state = arrive_cost, arrive_state
        if i + 1 < n and p.cutting[i + 1] and np.isfinite(arrive_cost).any():
            rdiff, rstep = _ref_rewind_steps(p, i, arrive_state)
            rtotal = arrive_cost[:, None] + rstep
            rbest = np.argmin(rtotal, axis=0)
            rcost = np.where(usable[i], rtotal[rbest, cols], np.inf)
            take = rcost < arrive_cost
            if take.any():
                rback[i] = np.where(take, rbest, -1)
                cost = np.where(take, rcost, arrive_cost)
                state = np.where(take[:, None], arrive_state[rbest] + rdiff[rbest, cols], state)
        leave_hist[i] = state
        if not np.isfinite(cost).any():
            _raise_dead_end(p, i)
    k = int(np.argmin(cost))
    chosen = np.empty(n, dtype=np.int64)
    arrive = np.empty(n, dtype=np.int64)
    for i in range(n - 1, -1, -1):
        chosen[i] = k
        if rback[i, k] >= 0:
            k = int(rback[i, k])
        arrive[i] = k
        k = int(back[i, k])
    idx = np.arange(n)
    return chosen, arrive, leave_hist[idx, chosen], arrive_hist[idx, arrive]


def walk(p: BranchSearch, chosen: np.ndarray, arrive: np.ndarray):
    """Cost of a path of candidates by the reference's steps, and its actual angles (leave,
    arrive), shapes (n, r)."""
    n = len(chosen)
    state = p.values[0].copy()
    state[:, 0] = np.where(np.isnan(state[:, 0]), p.start[0], state[:, 0])
    state[:, p.cont] += TWO_PI * np.round((p.start[p.cont] - state[:, p.cont]) / TWO_PI)
    cur = state[chosen[0]]
    cost = p.pref_cost[0, chosen[0]]
    leave, into = np.empty((n, len(cur))), np.empty((n, len(cur)))
    leave[0] = into[0] = cur
    rows = len(p.branch)
    for i in range(1, n):
        # every row the same state: the row picks the candidate it stands for (branch switches)
        diff, step = _ref_steps(p, i, np.repeat(cur[None], rows, axis=0))
        cost += step[chosen[i - 1], arrive[i]] + p.pref_cost[i, arrive[i]]
        cur = into[i] = cur + diff[0, arrive[i]]
        if chosen[i] != arrive[i]:
            diff, step = _ref_rewind_steps(p, i, np.repeat(cur[None], rows, axis=0))
            cost += step[arrive[i], chosen[i]]
            cur = cur + diff[0, chosen[i]]
        leave[i] = cur
    return cost, leave, into


# -- comparing both on the planner's own problems ----------------------------------------------


class Compared:
    """Runs the reference and the blocked recursion (several block sizes) on every problem
    :func:`select` plans, and counts the comparisons."""

    def __init__(self, blocks: tuple[int | None, ...] = (None, 8, 5)) -> None:
        self.blocks = blocks
        self.calls = 0
        self.rewinds = 0
        self.held = 0
        self.same = 0
        self.original = engine._viterbi

    def __call__(self, p: BranchSearch, block: int | None = None):
        self.calls += 1
        self.held += int(np.isnan(p.values).any(axis=2).any(axis=1).sum())
        try:
            want = reference(p)
        except UnreachableError as err:
            for b in self.blocks:
                with pytest.raises(type(err)) as got:
                    self.original(p, block=b)
                assert str(got.value) == str(err)
            raise
        want_cost, _, _ = walk(p, want[0], want[1])
        for b in self.blocks:
            got = self.original(p, block=b)
            cost, leave, arrive = walk(p, got[0], got[1])
            # the same least cost (two paths of equal cost may be told apart by rounding
            # alone, which a different order of the sums changes), the same rewinds, and the
            # angles the chosen candidates give
            assert cost == pytest.approx(want_cost, rel=1e-12, abs=1e-9), f"block {b}"
            assert int((got[0] != got[1]).sum()) == int((want[0] != want[1]).sum())
            np.testing.assert_allclose(got[2], leave, rtol=0, atol=1e-9)
            np.testing.assert_allclose(got[3], arrive, rtol=0, atol=1e-9)
            if np.array_equal(got[0], want[0]) and np.array_equal(got[1], want[1]):
                self.same += 1
                np.testing.assert_allclose(got[2], want[2], rtol=0, atol=1e-9)
        self.rewinds += int((want[0] != want[1]).sum())
        return got


@pytest.fixture
def compared(monkeypatch: pytest.MonkeyPatch) -> Compared:
    c = Compared()
    monkeypatch.setattr(search, "_viterbi", c)
    return c


def spiral_axis(turns: float, n: int, tilt_deg: float) -> tuple[np.ndarray, np.ndarray]:
    az = np.radians(np.linspace(0.0, 360.0 * turns, n))
    t = np.radians(tilt_deg)
    axis = np.stack([np.sin(t) * np.cos(az), np.sin(t) * np.sin(az), np.full(n, np.cos(t))], 1)
    tip = np.stack([40 * np.cos(az), 40 * np.sin(az), np.linspace(0, -6, n)], axis=1)
    return tip, axis


@pytest.mark.parametrize("name", MACHINES)
@pytest.mark.parametrize("path", sorted(PATHS))
def test_shipped_paths(compared: Compared, name: str, path: str) -> None:
    m = load_machine(name)
    tp = PATHS[path]()
    try:
        select(
            m,
            tp.tip,
            tp.axis,
            tool_length=m.settings.tool_length,
            lines=tp.line,
            source=tp.source,
            cutting=np.ones(len(tp), dtype=bool),
        )
    except UnreachableError:
        if not compared.calls:
            pytest.skip(f"{path} is not reachable on {name}")
    assert compared.calls == 1


@pytest.mark.parametrize("turns", [1.5, 3.0, 4.2])
def test_rewinds(compared: Compared, turns: float) -> None:
    m = load_machine("gantry-ca")  # C limited to +-360 degrees: rewinds
    tip, axis = spiral_axis(turns, 300, 30.0)
    sel = select(m, tip, axis, tool_length=m.settings.tool_length)
    assert compared.calls == 1
    assert compared.rewinds == int(sel.rewind.sum())
    if turns > 2:
        assert sel.rewind.any()


def random_walk(
    rng: np.random.Generator, n: int, pole_every: int, *, step: float, reach: float, turn: float
) -> tuple[np.ndarray, np.ndarray]:
    """A random walk of the tool axis about +Z (polar steps ``step`` rad, folded at ``reach``,
    azimuth steps ``turn`` rad; every ``pole_every``-th point exactly on +Z) and of the tip
    (2 mm steps): tip and axis, shape (n, 3)."""
    polar = np.abs(np.cumsum(rng.normal(0.0, step, n))) % reach
    az = np.cumsum(rng.normal(0.0, turn, n))
    if pole_every:
        polar[::pole_every] = 0.0
    axis = np.stack([np.sin(polar) * np.cos(az), np.sin(polar) * np.sin(az), np.cos(polar)], axis=1)
    return np.cumsum(rng.normal(0.0, 2.0, (n, 3)), axis=0), axis


@settings(max_examples=40, deadline=None)
@given(
    name=st.sampled_from(MACHINES),
    seed=st.integers(0, 2**32 - 1),
    n=st.integers(2, 120),
    pole_every=st.integers(0, 9),
    entries=st.integers(0, 3),
)
def test_random_walks(name: str, seed: int, n: int, pole_every: int, entries: int) -> None:
    """Random walks of the tool axis about +Z, some points exactly on it (held angles), with
    entries and rapids: both recursions agree, or both fail with the same message."""
    rng = np.random.default_rng(seed)
    m = load_machine(name)
    tip, axis = random_walk(rng, n, pole_every, step=0.08, reach=1.2, turn=0.5)
    entry = np.zeros(n, dtype=bool)
    entry[rng.integers(0, n, entries)] = True
    cutting = rng.random(n) > 0.1
    c = Compared(blocks=(None, 3, 7))
    original, search._viterbi = search._viterbi, c
    try:
        select(m, tip, axis, tool_length=m.settings.tool_length, entry=entry, cutting=cutting)
    except UnreachableError:
        pass
    finally:
        search._viterbi = original
    assert c.calls <= 1  # none when a point is out of reach before planning


def test_collision_exclusions(compared: Compared, tmp_path: Path) -> None:
    """Excluded moves are planned point by point; the re-plans agree too."""
    from test_planning import machine_with_fixtures, tilted_line

    from urdfpost.posting.options import PostOptions
    from urdfpost.posting.whole import post

    m = load_machine(machine_with_fixtures(tmp_path, (+1,)))
    result = post(tilted_line(), m, PostOptions(prefer=Preference("A", +1), collisions=True))
    assert result.verification.ok
    assert compared.calls >= 1


@pytest.mark.parametrize("path", ["hemisphere", "sweep-0.1"])
def test_without_the_step_cache(
    compared: Compared, monkeypatch: pytest.MonkeyPatch, path: str
) -> None:
    """Step matrices computed per block step (what paths too long for the cache get)."""
    monkeypatch.setattr(engine, "_CACHE_BYTES", 0)
    m = load_machine("gantry-ca")
    tp = PATHS[path]()
    select(m, tp.tip, tp.axis, tool_length=m.settings.tool_length, lines=tp.line)
    tip, axis = spiral_axis(3.0, 300, 30.0)
    select(m, tip, axis, tool_length=m.settings.tool_length)
    assert compared.calls == 2 and compared.rewinds > 0


# -- settled choices: what no later CL points can change ---------------------------------------


def _settled_by_walking(back: np.ndarray, rback: np.ndarray, alive: np.ndarray) -> int:
    """The last point where the paths into every alive candidate of the last point agree,
    each path followed back one point at a time."""
    n, _ = back.shape
    paths = []
    for k in np.flatnonzero(alive):
        path = np.empty(n, dtype=int)
        path[-1] = k
        for i in range(n - 1, 0, -1):
            a = rback[i, k] if rback[i, k] >= 0 else k
            k = back[i, a]
            path[i - 1] = k
        paths.append(path)
    if len(paths) <= 1:
        return n - 1
    agree = np.all(np.array(paths) == paths[0], axis=0)
    return int(np.flatnonzero(agree).max(initial=-1))


@settings(max_examples=200, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    n=st.integers(1, 90),
    n_cand=st.integers(1, 6),
    block=st.integers(1, 12),
    rewinds=st.floats(0.0, 0.3),
)
def test_settled_point_of_random_maps(
    seed: int, n: int, n_cand: int, block: int, rewinds: float
) -> None:
    """Followed back as a set, block by block, the survivors meet where following each one
    back point by point says they do."""
    rng = np.random.default_rng(seed)
    # maps that merge now and then (few distinct predecessors), like a real recursion's
    back = rng.integers(0, max(1, n_cand // 2 + rng.integers(0, 2)), (n, n_cand)).astype(np.int32)
    back = np.where(rng.random((n, n_cand)) < 0.7, np.arange(n_cand), back).astype(np.int32)
    rback = np.where(
        rng.random((n, n_cand)) < rewinds, rng.integers(0, n_cand, (n, n_cand)), -1
    ).astype(np.int32)
    alive = rng.random(n_cand) < 0.7
    alive[rng.integers(0, n_cand)] = True
    k_end = int(rng.choice(np.flatnonzero(alive)))
    *_, settled = engine._follow_back(k_end, back, rback, block, alive)
    assert settled == _settled_by_walking(back, rback, alive)


@settings(max_examples=40, deadline=None)
@given(
    name=st.sampled_from(MACHINES),
    seed=st.integers(0, 2**32 - 1),
    n=st.integers(20, 150),
    cut=st.floats(0.2, 0.9),
    pole_every=st.integers(0, 9),
)
def test_settled_choices_are_those_of_the_whole_path(
    name: str, seed: int, n: int, cut: float, pole_every: int
) -> None:
    """Planned over a first part of a path, the choices up to its settled point are those the
    plan over the whole path makes: what lets a streamed post cut there."""
    rng = np.random.default_rng(seed)
    m = load_machine(name)
    tip, axis = random_walk(rng, n, pole_every, step=0.1, reach=1.4, turn=0.4)
    part = max(2, int(cut * n))
    try:
        whole = select(m, tip, axis, tool_length=m.settings.tool_length)
        first = select(m, tip[:part], axis[:part], tool_length=m.settings.tool_length)
    except UnreachableError:
        return
    assert first.settled is not None and -1 <= first.settled < part
    s = first.settled + 1
    np.testing.assert_array_equal(first.branch[:s], whole.branch[:s])
    np.testing.assert_array_equal(first.rewind[:s], whole.rewind[:s])
    np.testing.assert_allclose(first.q[:s], whole.q[:s], rtol=0, atol=1e-9)


def test_two_branches_within_travel_stay_unsettled() -> None:
    """Where both branches reach every point and nothing forces either, the paths into them
    need not meet: such a choice is not settled (a streamed post reports the join)."""
    m = load_machine("umc750")  # B -35..120 deg: both tilts within travel up to 35 deg
    n = 200
    az = np.radians(np.linspace(0.0, 90.0, n))
    t = np.radians(20.0)
    axis = np.stack([np.sin(t) * np.cos(az), np.sin(t) * np.sin(az), np.full(n, np.cos(t))], 1)
    tip = np.stack([np.linspace(-20, 20, n), np.zeros(n), np.zeros(n)], axis=1)
    sel = select(m, tip, axis, tool_length=m.settings.tool_length)
    assert sel.settled is not None and sel.settled < n - 1
