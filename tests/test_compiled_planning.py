"""The planning's compiled kernels (issue 21) against their numpy paths, to the bit.

The numpy paths stay the oracle: the cone's tube (``cone._tube_numpy``, ``cone._reachable``)
and the branch choice's blocked recursion (``engine._viterbi`` with the kernels off). The
kernels must give the same numbers, not close ones: the same tube, the same candidates,
angles and settled point, the same cone plans on machines of every family; where numba
fails, the numpy path runs with a warning.
"""

from __future__ import annotations

import logging
import sys
from collections.abc import Iterator

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

pytest.importorskip("numba")

from test_cone_spans import MACHINES as CONE_MACHINES
from test_cone_spans import jobs
from test_tube import pole_pass
from test_viterbi import MACHINES, random_walk, spiral_axis

from urdfpost._compiled import Kernels
from urdfpost.analysis.testpaths import PATHS, hemisphere_raster
from urdfpost.errors import UnreachableError
from urdfpost.machine import load_machine
from urdfpost.planning.branches import engine, search, select
from urdfpost.planning.branches.state import BranchSearch, _Exclusions
from urdfpost.planning.problem import Problem, entry_mask
from urdfpost.planning.strategies import STRATEGIES, _cone_kernel, cone
from urdfpost.tolerances import Tolerances
from urdfpost.toolpath import Motion


def bits(a: np.ndarray) -> np.ndarray:
    """The bytes of an array: equal arrays of these are equal to the bit (NaN and -0 too)."""
    return np.ascontiguousarray(a).view(np.uint8)


@pytest.fixture(autouse=True)
def kernels_restored() -> Iterator[None]:
    """Each test leaves both kernel modules as it found them."""
    saved = [(k, dict(vars(k))) for k in (engine.KERNELS, cone.KERNELS)]
    yield
    for k, state in saved:
        vars(k).clear()
        vars(k).update(state)


def use(kernels: Kernels, on: bool) -> None:
    kernels.forced = on
    if on:
        assert kernels.get(0) is not None


# -- the tube -------------------------------------------------------------------------------


@settings(max_examples=80, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    n=st.integers(2, 3000),
    width=st.floats(0.0002, 0.2),
    offset=st.floats(0.001, 0.3),
    zero_steps=st.booleans(),
)
def test_the_compiled_tube_is_the_numpy_tube(
    seed: int, n: int, width: float, offset: float, zero_steps: bool
) -> None:
    """Passes beside the pole, narrow and wide (the bisection for the rate factor runs on the
    narrow ones), some steps 0 (an infinite need): the same tube to the bit."""
    rng = np.random.default_rng(seed)
    exact, half, step = pole_pass(rng, n, width, offset)
    if zero_steps:
        step[rng.random(n - 1) < 0.05] = 0.0
    assert np.array_equal(
        bits(_cone_kernel.tube(exact, half, step)), bits(cone._tube_numpy(exact, half, step))
    )


@settings(max_examples=80, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    n=st.integers(2, 400),
    tight=st.booleans(),
    k=st.sampled_from([1.0, 0.7, 3.25]),
)
def test_the_compiled_forward_pass_is_the_numpy_one(
    seed: int, n: int, tight: bool, k: float
) -> None:
    """Random bands and steps (intervals closing and restarting): the same intervals to the
    bit, the same feasibility, with and without stopping at the first closed one."""
    rng = np.random.default_rng(seed)
    centre = rng.normal(0.0, 0.3, n).cumsum()
    width = rng.uniform(0.0, 0.05 if tight else 0.5, n)
    width[rng.random(n) < 0.1] = 0.0
    lo, hi = centre - width, centre + width
    step = rng.uniform(0.0, 0.2 if tight else 1.0, n - 1)
    want = cone._reachable(lo, hi, step * k)
    got = _cone_kernel.reachable(lo, hi, step, k, False)
    assert got[2] == want[2]
    assert np.array_equal(bits(got[0]), bits(want[0]))
    assert np.array_equal(bits(got[1]), bits(want[1]))
    assert _cone_kernel.reachable(lo, hi, step, k, True)[2] == want[2]


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(2, 2000), slack=st.sampled_from([0, 1, 4]))
def test_intervals_closed_by_rounding_alone_are_one_value(seed: int, n: int, slack: int) -> None:
    """Points pinned to one value each and steps exactly their differences (a few ulps more or
    less): the running sums close intervals by their rounding alone, which the allowance
    keeps open, in the kernel as in numpy (a kernel without it fails here)."""
    rng = np.random.default_rng(seed)
    centre = rng.normal(0.0, 0.3, n).cumsum()
    step = np.abs(np.diff(centre))
    for _ in range(slack):
        step = np.nextafter(step, np.where(rng.random(n - 1) < 0.5, 0.0, np.inf))
    want = cone._reachable(centre, centre, step)
    got = _cone_kernel.reachable(centre, centre, step, 1.0, False)
    assert got[2] == want[2]
    assert np.array_equal(bits(got[0]), bits(want[0]))
    assert np.array_equal(bits(got[1]), bits(want[1]))
    half = np.zeros(n)
    assert np.array_equal(
        bits(_cone_kernel.tube(centre, half, step)), bits(cone._tube_numpy(centre, half, step))
    )


@pytest.mark.parametrize("n", [0, 1, 7, 8, 9, 127, 128, 129, 255, 256, 1000, 8193, 250_001])
def test_the_rounding_allowance_sums_as_numpy_does(n: int) -> None:
    """numpy adds ``np.abs(step).sum()`` pairwise: the kernel's sum is the same to the bit,
    and so the allowance for the rounding of the running sums."""
    rng = np.random.default_rng(n)
    a = rng.normal(size=n) * 10.0 ** rng.uniform(-8, 3, n)
    for lo in (0, n // 3):
        assert _cone_kernel._pairwise_abs(a, lo, n - lo, 1.5) == float(np.abs(a[lo:] * 1.5).sum())
    if n:
        b, c = rng.normal(size=n), rng.normal(size=n)
        assert _cone_kernel._rounding(b, c, a, 0, 1.0) == cone._rounding(b, c, a)


# -- the branch choice ----------------------------------------------------------------------


class Both:
    """``search._viterbi`` replaced: the numpy recursion and the compiled one on every branch
    search (several block sizes), their results compared to the bit; numpy's returned."""

    def __init__(self, blocks: tuple[int | None, ...] = (None, 3, 7)) -> None:
        self.blocks = blocks
        self.calls = 0
        self.rewinds = 0

    def __call__(self, p: BranchSearch, block: int | None = None) -> tuple:
        self.calls += 1
        use(engine.KERNELS, False)
        try:
            want = engine._viterbi(p, block)
        except UnreachableError as err:
            use(engine.KERNELS, True)
            for b in self.blocks:
                with pytest.raises(UnreachableError) as got:
                    engine._viterbi(p, b)
                assert str(got.value) == str(err)
            raise
        for b in self.blocks:
            use(engine.KERNELS, False)
            ref = want if b == block else engine._viterbi(p, b)
            use(engine.KERNELS, True)
            got = engine._viterbi(p, b)
            assert engine.KERNELS.failed is None
            for x, y in zip(got[:4], ref[:4], strict=True):
                assert np.array_equal(bits(np.asarray(x)), bits(np.asarray(y))), f"block {b}"
            assert got[4] == ref[4], f"block {b}: settled"
        self.rewinds += int((want[0] != want[1]).sum())
        return want


@pytest.fixture
def both(monkeypatch: pytest.MonkeyPatch) -> Both:
    b = Both()
    monkeypatch.setattr(search, "_viterbi", b)
    return b


@pytest.mark.parametrize("name", MACHINES)
@pytest.mark.parametrize("path", sorted(PATHS))
def test_the_compiled_branch_choice_on_shipped_paths(both: Both, name: str, path: str) -> None:
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
        if not both.calls:
            pytest.skip(f"{path} is not reachable on {name}")
    assert both.calls == 1


@pytest.mark.parametrize("turns", [1.5, 3.0, 4.2])
def test_the_compiled_branch_choice_rewinds(both: Both, turns: float) -> None:
    m = load_machine("gantry-ca")  # C limited to +-360 degrees: rewinds
    tip, axis = spiral_axis(turns, 300, 30.0)
    sel = select(m, tip, axis, tool_length=m.settings.tool_length)
    assert both.calls == 1 and both.rewinds == int(sel.rewind.sum())
    if turns > 2:
        assert sel.rewind.any()


@settings(max_examples=60, deadline=None)
@given(
    name=st.sampled_from(MACHINES),
    seed=st.integers(0, 2**32 - 1),
    n=st.integers(2, 150),
    pole_every=st.integers(0, 9),
    entries=st.integers(0, 3),
    turn=st.sampled_from([0.05, 0.5, 1.5]),
)
def test_the_compiled_branch_choice_on_random_walks(
    name: str, seed: int, n: int, pole_every: int, entries: int, turn: float
) -> None:
    """Random walks about +Z, some points on it (held angles: the point-by-point blocks),
    entries, rapids, fast turns (rewinds, dead ends): the same choice, or the same error."""
    rng = np.random.default_rng(seed)
    m = load_machine(name)
    tip, axis = random_walk(rng, n, pole_every, step=0.08, reach=1.2, turn=turn)
    entry = np.zeros(n, dtype=bool)
    entry[rng.integers(0, n, entries)] = True
    cutting = rng.random(n) > 0.1
    b = Both()
    original, search._viterbi = search._viterbi, b
    try:
        select(m, tip, axis, tool_length=m.settings.tool_length, entry=entry, cutting=cutting)
    except UnreachableError:
        pass
    finally:
        search._viterbi = original


@settings(max_examples=150, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    n=st.integers(2, 400),
    n_cand=st.integers(1, 5),
    held=st.sampled_from([0.0, 0.02, 0.3]),
    block=st.sampled_from([None, 2, 5, 16]),
)
def test_the_compiled_recursion_breaks_ties_as_numpy(
    seed: int, n: int, n_cand: int, held: float, block: int | None
) -> None:
    """Candidates on a coarse grid of angles (steps of pi/8, some candidates twins of
    others, equal preference costs): equal costs everywhere, which the first candidate wins
    in numpy's ``argmin`` and minimum; with undetermined angles (the point-by-point blocks),
    unusable candidates, singular points, rapids and rewinds. The same choice, angles and
    settled point to the bit, or the same dead end."""
    rng = np.random.default_rng(seed)
    m = load_machine("dmu50")
    r = len(m.rotary)
    values = rng.integers(-16, 17, (n, n_cand, r)) * (np.pi / 8)
    if n_cand > 1:
        values[:, -1] = values[:, 0]  # twins
    values[rng.random((n, n_cand)) < held, 0] = np.nan
    ok = rng.random((n, n_cand)) < 0.9
    ok[:, 0] |= ~ok.any(axis=1)
    p = BranchSearch(
        machine=m,
        values=values,
        ok=ok,
        branch=rng.integers(0, 2, n_cand),
        pref_cost=np.where(rng.random((n, n_cand)) < 0.5, 0.0, 0.25),
        start=np.zeros(r),
        singular=rng.random(n) < 0.1,
        cutting=rng.random(n) < 0.8,
        weights=np.array([0.5, 0.25])[:r],
        switch_cost=np.pi,
        lines=np.arange(1, n + 1),
        source="grid",
        exclude=_Exclusions(state=np.zeros((n, n_cand), dtype=bool)),
    )
    use(engine.KERNELS, False)
    try:
        want = engine._viterbi(p, block)
    except UnreachableError as err:
        use(engine.KERNELS, True)
        with pytest.raises(UnreachableError) as got_err:
            engine._viterbi(p, block)
        assert str(got_err.value) == str(err)
        return
    use(engine.KERNELS, True)
    got = engine._viterbi(p, block)
    for x, y in zip(got[:4], want[:4], strict=True):
        assert np.array_equal(bits(np.asarray(x)), bits(np.asarray(y)))
    assert got[4] == want[4]


# -- the cone's plans -----------------------------------------------------------------------


def cone_plan(problem: Problem, on: bool) -> object:
    use(engine.KERNELS, on)
    use(cone.KERNELS, on)
    plan = STRATEGIES["cone"](problem)
    assert engine.KERNELS.failed is None and cone.KERNELS.failed is None
    return plan


@pytest.mark.parametrize("machine_name", CONE_MACHINES)
def test_the_cone_plans_the_same_with_the_kernels(machine_name: str) -> None:
    """The cone's plans (branch choice, tube, rounds on windows) on the jobs that make it bend
    and insert points, a dense raster too: the same toolpath, rows and curve to the bit."""
    m = load_machine(machine_name)
    for name, tp in {**jobs(), "raster 0.1 mm": hemisphere_raster(step=0.1)}.items():
        problem = Problem(m, tp, tool_length=m.settings.tool_length, tol=Tolerances())
        want, got = cone_plan(problem, False), cone_plan(problem, True)
        for a in ("tip", "axis", "line"):
            assert np.array_equal(getattr(got.toolpath, a), getattr(want.toolpath, a)), name
        assert np.array_equal(bits(got.param), bits(want.param)), name
        assert np.array_equal(bits(got.rotary), bits(want.rotary)), name
        assert got.notes == want.notes and got.settled == want.settled, name
        if want.curve is not None:
            x = np.linspace(0.0, len(want.toolpath) - 1.0, 5 * len(want.toolpath))
            assert np.array_equal(bits(got.curve(x)), bits(want.curve(x))), name


@pytest.mark.parametrize("machine_name", CONE_MACHINES)
def test_the_compiled_deviation_bound_is_numpys(machine_name: str) -> None:
    """The bound of the cone's curve on every feed segment of its plans, and with rows whose
    tilt lies beyond travel or whose angles are NaN: the same numbers to the bit."""
    m = load_machine(machine_name)
    for name, tp in jobs().items():
        problem = Problem(m, tp, tool_length=m.settings.tool_length, tol=Tolerances())
        plan = cone_plan(problem, True)
        path = plan.toolpath
        seg = np.flatnonzero((path.motion[1:] == Motion.FEED) & ~entry_mask(path)[1:])
        rows = (plan.param, plan.rotary)
        use(cone.KERNELS, True)
        got = cone._deviation_bound(m, path, *rows, seg)
        use(cone.KERNELS, False)
        want = cone._deviation_bound(m, path, *rows, seg)
        assert np.array_equal(bits(got), bits(want)), name
        lo2, hi2 = m.rotary[1].lower, m.rotary[1].upper
        tilted = plan.rotary.copy()
        tilted[::7, 1] = np.where(np.arange(len(tilted))[::7] % 2, hi2 + 0.01, lo2 - 0.02)
        tilted[3::11, 0] = np.nan  # as on a turn in place
        use(cone.KERNELS, True)
        got = cone._deviation_bound(m, path, plan.param, tilted, seg)
        use(cone.KERNELS, False)
        want = cone._deviation_bound(m, path, plan.param, tilted, seg)
        assert np.array_equal(bits(got), bits(want)), name


def test_the_compiled_axis_deviation_is_numpys() -> None:
    """The angle between the tool axis of rotary angles and given axes (``cone._axis_deviation``)
    on every shipped machine with rotary axes: random angles over several turns, NaN rows, and
    axes at the rows' own tool axes (angle 0) and opposite them (pi): the same numbers as
    numpy's ``angle_between(tool_axis_of(...))`` to the bit."""
    from urdfpost.machine import list_machines
    from urdfpost.planning.problem import tool_axis_of

    rng = np.random.default_rng(21)
    tried = 0
    for name in sorted(list_machines()):
        m = load_machine(name)
        if not m.rotary:
            continue
        k, r = 4000, len(m.rotary)
        rotary = rng.uniform(-3 * np.pi, 3 * np.pi, size=(k, r))
        rotary[::97] = np.nan
        axis = rng.normal(size=(k, 3))
        axis /= np.linalg.norm(axis, axis=1)[:, None]
        own = tool_axis_of(m, rotary)
        axis[1::5], axis[2::5] = own[1::5], -own[2::5]
        use(cone.KERNELS, True)
        got = cone._axis_deviation(m, rotary, axis)
        use(cone.KERNELS, False)
        want = cone._axis_deviation(m, rotary, axis)
        assert np.array_equal(bits(got), bits(want)), name
        assert cone.KERNELS.failed is None
        tried += 1
    assert tried >= 4


# -- without numba, or where it fails -------------------------------------------------------


def test_a_failing_kernel_falls_back_to_numpy_with_a_warning(
    monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    """A kernel that raises (numba could not compile or cache it) is not used again in the
    process: the numpy paths run, the same plan, one warning each."""
    m = load_machine("dmu50")
    problem = Problem(
        m, jobs()["raster 2 mm"], tool_length=m.settings.tool_length, tol=Tolerances()
    )
    want = cone_plan(problem, False)
    for kernels in (engine.KERNELS, cone.KERNELS):
        use(kernels, True)

    def broken(*args: object) -> None:
        raise RuntimeError("no machine code here")

    monkeypatch.setattr(engine.KERNELS.module, "viterbi", broken)
    monkeypatch.setattr(cone.KERNELS.module, "tube", broken)
    with caplog.at_level(logging.WARNING, logger="urdfpost._compiled"):
        got = STRATEGIES["cone"](problem)
    assert engine.KERNELS.failed and cone.KERNELS.failed
    assert engine.KERNELS.loaded() is None and cone.KERNELS.loaded() is None
    warned = [r.getMessage() for r in caplog.records]
    assert len(warned) == 2 and all("the numpy path runs" in w for w in warned), warned
    assert np.array_equal(bits(got.rotary), bits(want.rotary))
    assert np.array_equal(bits(got.param), bits(want.param))


def test_without_numba_the_numpy_paths_run(monkeypatch: pytest.MonkeyPatch) -> None:
    """Where the kernel modules cannot be imported (numba missing), nothing is loaded, no
    warning, and the plan is the numpy one; small paths never load the kernels."""
    assert Kernels(engine._load_kernels, "test").get(100) is None  # below COMPILED_FROM
    m = load_machine("dmu50")
    problem = Problem(
        m, jobs()["raster 2 mm"], tool_length=m.settings.tool_length, tol=Tolerances()
    )
    want = cone_plan(problem, False)
    for module in (_cone_kernel, engine._load_kernels()):
        package, _, name = module.__name__.rpartition(".")
        monkeypatch.setitem(sys.modules, module.__name__, None)  # import fails
        monkeypatch.delattr(sys.modules[package], name)
    monkeypatch.setitem(sys.modules, "numba", None)
    for owner in (engine, cone):
        fresh = Kernels(owner._load_kernels, "test")
        monkeypatch.setattr(owner, "KERNELS", fresh)
        assert fresh.get(10**7) is None and fresh.loaded() is None and fresh.failed is None
        fresh.forced = True
        assert fresh.get(10**7) is None
    got = STRATEGIES["cone"](problem)
    assert np.array_equal(bits(got.rotary), bits(want.rotary))
