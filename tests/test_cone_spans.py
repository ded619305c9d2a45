"""The cone's repair on the singular spans only (issue 21): the same plan as over whole layers.

The cone checks its curve between rows against the angle tolerance (``cone._beyond``). It used
to sample every feed segment of the path, each round; it now samples only the segments whose
deviation a bound cannot clear (``cone._may_leave``). Kept here as the oracle: the sampling of
every segment. On generated jobs, machines of every family (a nutating one too), the positions
it flags are the same at every round, the plans are the same to the bit, and the bound holds
on the segments it clears (sampled four times finer than the cone samples them).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from urdfpost.analysis.testpaths import great_circle_sweep, hemisphere_raster
from urdfpost.geometry import angle_between
from urdfpost.machine import load_machine
from urdfpost.planning.problem import Problem, at_param, entry_mask, tool_axis_of
from urdfpost.planning.strategies import STRATEGIES, cone
from urdfpost.tolerances import Tolerances
from urdfpost.toolpath import Motion, Toolpath

MACHINES = ["dmu50", "gantry-ca", "monoblock", "dmu50-nutating"]


def jobs() -> dict[str, Toolpath]:
    """Jobs on which the cone bends and inserts points: coarse rasters over a hemisphere
    (passes over, beside and away from the pole), and short sweeps past the pole."""
    return {
        "raster 0.5 mm": hemisphere_raster(),  # as dense as a finishing job
        "raster 1 mm": hemisphere_raster(step=1.0, offsets=(0.2, 1.0, 3.0, 8.0)),
        "raster 2 mm": hemisphere_raster(step=2.0, offsets=(0.0, 0.5, 2.0, 5.0, 12.0)),
        "raster 5 mm": hemisphere_raster(step=5.0, offsets=(0.3, 1.0, 3.0)),
        "sweep 0.3 deg": great_circle_sweep(0.3, half_angle_deg=30.0, points=7),
        "sweep 1 deg": great_circle_sweep(1.0, half_angle_deg=20.0, points=11),
    }


def beyond_everywhere(
    problem: Problem,
    tp: Toolpath,
    curve: Callable[[np.ndarray], np.ndarray],
    param: np.ndarray,
    rot: np.ndarray,
) -> np.ndarray:
    """``cone._beyond`` as it was: the curve sampled on every feed segment of the path."""
    n = len(tp)
    if n < 2:
        return np.zeros(0)
    feed = np.flatnonzero((tp.motion[1:] == Motion.FEED) & ~entry_mask(tp)[1:])
    if not feed.size:
        return np.zeros(0)
    frac = np.arange(1, cone.CURVE_SAMPLES) / cone.CURVE_SAMPLES
    x = (feed[:, None] + frac[None, :]).ravel()
    rows = curve(x)
    _, prog = at_param(tp, x, 0.0)
    dev = np.zeros(len(x))
    ok = np.isfinite(rows).all(axis=1)
    dev[ok] = angle_between(tool_axis_of(problem.machine, rows[ok]), prog[ok])
    per_segment = dev.reshape(len(feed), len(frac))
    worst = np.argmax(per_segment, axis=1)
    bad = per_segment[np.arange(len(feed)), worst] > problem.angle_tolerance * (1 + 1e-9)
    return feed[bad] + frac[worst[bad]]


def bound_and_deviation(
    problem: Problem,
    tp: Toolpath,
    curve: Callable[[np.ndarray], np.ndarray],
    param: np.ndarray,
    rot: np.ndarray,
    samples: int,
) -> tuple[np.ndarray, np.ndarray]:
    """``cone._deviation_bound`` of every feed segment, and the curve's largest deviation on
    it (``samples`` positions per segment)."""
    feed = np.flatnonzero((tp.motion[1:] == Motion.FEED) & ~entry_mask(tp)[1:])
    bound = cone._deviation_bound(problem.machine, tp, param, rot, feed)
    frac = np.arange(1, samples) / samples
    x = (feed[:, None] + frac[None, :]).ravel()
    rows = curve(x)
    ok = np.isfinite(rows).all(axis=1)
    _, prog = at_param(tp, x, 0.0)
    dev = np.zeros(len(x))
    dev[ok] = angle_between(tool_axis_of(problem.machine, rows[ok]), prog[ok])
    return bound, dev.reshape(len(feed), len(frac)).max(axis=1, initial=0.0)


def compared_rounds(
    label: str, restricted: Callable[..., np.ndarray]
) -> tuple[Callable[..., np.ndarray], list[tuple[np.ndarray, np.ndarray]]]:
    """A ``_beyond`` that runs ``restricted`` and the oracle and asserts they agree; and the
    list it fills with each round's bounds and sampled deviations
    (:func:`bound_and_deviation`)."""
    rounds: list[tuple[np.ndarray, np.ndarray]] = []

    def both(problem, tp, curve, param, rot):  # type: ignore[no-untyped-def]
        got = restricted(problem, tp, curve, param, rot)
        want = beyond_everywhere(problem, tp, curve, param, rot)
        assert np.array_equal(got, want), f"{label}: round {len(rounds)}"
        rounds.append(bound_and_deviation(problem, tp, curve, param, rot, 32))
        return got

    return both, rounds


@pytest.mark.parametrize("machine_name", MACHINES)
def test_the_cone_flags_the_same_points_as_sampling_every_segment(
    machine_name: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    m = load_machine(machine_name)
    restricted = cone._beyond
    for name, tp in jobs().items():
        problem = Problem(m, tp, tool_length=m.settings.tool_length, tol=Tolerances())
        both, rounds = compared_rounds(f"{machine_name}, {name}", restricted)
        monkeypatch.setattr(cone, "_beyond", both)
        plan = STRATEGIES["cone"](problem)
        monkeypatch.setattr(cone, "_beyond", beyond_everywhere)
        oracle = STRATEGIES["cone"](problem)
        monkeypatch.setattr(cone, "_beyond", restricted)
        assert rounds, name
        # the same plan, to the bit
        assert np.array_equal(plan.toolpath.tip, oracle.toolpath.tip)
        assert np.array_equal(plan.toolpath.axis, oracle.toolpath.axis)
        assert np.array_equal(plan.param, oracle.param)
        assert np.array_equal(plan.rotary, oracle.rotary, equal_nan=True)
        if plan.curve is not None:
            assert oracle.curve is not None
            x = np.linspace(0.0, len(plan.toolpath) - 1.0, 5 * len(plan.toolpath))
            assert np.array_equal(plan.curve(x), oracle.curve(x), equal_nan=True)
        # the bound holds on every segment, sampled four times finer than the cone samples
        # (where it is tight, the exact rows' deviations and the samples' differ by rounding)
        for bound, worst in rounds:
            assert np.all(worst <= bound + 1e-12), (name, np.max(worst - bound))


def test_the_jobs_make_the_cone_insert_points_and_the_bound_skip_most_segments() -> None:
    """The comparison above is not empty: on dmu50 the cone inserts points on these jobs; and
    on a raster as dense as a finishing job's (0.5 mm) the bound leaves most segments
    unsampled (on the coarse rasters the tool axis turns by about the tolerance from one CL
    point to the next, and the bound clears few)."""
    m = load_machine("dmu50")
    for name, tp in jobs().items():
        problem = Problem(m, tp, tool_length=m.settings.tool_length, tol=Tolerances())
        plan = STRATEGIES["cone"](problem)
        assert plan.bent and len(plan.toolpath) > len(tp), name
    plan = STRATEGIES["cone"](
        Problem(m, hemisphere_raster(), tool_length=m.settings.tool_length, tol=Tolerances())
    )
    tp = plan.toolpath
    feed = np.flatnonzero((tp.motion[1:] == Motion.FEED) & ~entry_mask(tp)[1:])
    bound = cone._deviation_bound(m, tp, plan.param, plan.rotary, feed)
    sampled = ~(bound <= np.radians(2.0))
    assert 0 < sampled.sum() < 0.2 * feed.size


def whole_rounds(monkeypatch: pytest.MonkeyPatch, problem: Problem) -> tuple[object, int]:
    """The cone with every round planned on the whole path (no windows: the oracle), and how
    many rounds it planned."""
    planned = cone._planned
    count = [0]

    def counted(p: Problem, tp: Toolpath, solved: object) -> object:
        count[0] += 1
        return planned(p, tp, solved)

    with monkeypatch.context() as mp:
        mp.setattr(cone, "_windows", lambda machine, r: [])
        mp.setattr(cone, "_planned", counted)
        plan = STRATEGIES["cone"](problem)
    return plan, count[0]


@pytest.mark.parametrize("margin", [cone.WINDOW_MARGIN, 8])
@pytest.mark.parametrize("machine_name", MACHINES)
def test_rounds_on_windows_give_the_plan_of_rounds_on_the_whole_path(
    machine_name: str, margin: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The rounds after the first are planned on windows around the bent points (``_inserted``),
    and the plan made on the whole path afterwards: on these jobs (a raster ten times denser
    too, where the default windows cover less than half the path; with narrow windows, on all)
    it is the plan of planning every round on the whole path, to the bit; and the whole path
    is planned no more often, on the dense rasters of dmu50 twice. (Without the splice of the
    last round, which gives this plan within a bound: ``tests/test_cone_splice.py``.)"""
    m = load_machine(machine_name)
    monkeypatch.setattr(cone, "WINDOW_MARGIN", margin)
    monkeypatch.setattr(cone, "SPLICE", False)
    planned = cone._planned
    for name, tp in {**jobs(), "raster 0.05 mm": hemisphere_raster(step=0.05)}.items():
        problem = Problem(m, tp, tool_length=m.settings.tool_length, tol=Tolerances())
        full: list[int] = []
        windows: list[int] = []

        def counted(
            p: Problem,
            path: Toolpath,
            solved: object,
            full: list[int] = full,
            windows: list[int] = windows,
        ) -> object:
            (full if p.start is None else windows).append(len(path))
            return planned(p, path, solved)

        monkeypatch.setattr(cone, "_planned", counted)
        plan = STRATEGIES["cone"](problem)
        monkeypatch.setattr(cone, "_planned", planned)
        oracle, oracle_rounds = whole_rounds(monkeypatch, problem)
        assert np.array_equal(plan.toolpath.tip, oracle.toolpath.tip), name
        assert np.array_equal(plan.toolpath.axis, oracle.toolpath.axis), name
        assert np.array_equal(plan.param, oracle.param), name
        assert np.array_equal(plan.rotary, oracle.rotary, equal_nan=True), name
        assert plan.notes == oracle.notes
        if plan.curve is not None:
            assert oracle.curve is not None
            x = np.linspace(0.0, len(plan.toolpath) - 1.0, 5 * len(plan.toolpath))
            assert np.array_equal(plan.curve(x), oracle.curve(x), equal_nan=True)
        assert len(full) <= oracle_rounds, name
        dense = name in ("raster 0.05 mm", "raster 0.5 mm" if margin == 8 else "")
        if machine_name == "dmu50" and dense:
            assert oracle_rounds > 2 and len(full) == 2 and windows, (name, full, oracle_rounds)


@pytest.mark.parametrize(
    ("machine_name", "turns"),
    [("dmu50", True), ("gantry-ca", False), ("monoblock", True), ("dmu50-nutating", True)],
)
def test_the_curve_says_where_it_is_defined_as_evaluating_it_does(
    machine_name: str, turns: bool
) -> None:
    """``realise`` takes where the cone's curve is defined (every position but its turns in
    place on the pole) from the curve, without evaluating it: the same rows as evaluating it,
    at the rows and between them, on paths with and without turns in place."""
    from urdfpost.analysis.testpaths import PATHS
    from urdfpost.errors import UrdfpostError
    from urdfpost.planning.problem import curve_defined

    machine = load_machine(machine_name)
    paths = {**jobs(), **{name: make() for name, make in PATHS.items()}}
    turning = 0
    for label, tp in paths.items():
        problem = Problem(machine, tp, tool_length=machine.settings.tool_length, tol=Tolerances())
        try:
            plan = cone.strategy_cone(problem)
        except UrdfpostError:  # (a test path beyond this machine's travel)
            continue
        if plan.curve is None:
            continue
        between = (plan.param[:-1, None] + np.linspace(0.0, 1.0, 5)[None, :-1]).ravel()
        for x in (plan.param, between, plan.param[1:][plan.param[1:] == plan.param[:-1]]):
            want = np.isfinite(plan.curve(x)).all(axis=1)
            assert np.array_equal(curve_defined(plan.curve, x), want), label
        turning += int((~curve_defined(plan.curve, plan.param)).sum())
    assert bool(turning) == turns, "the paths turn in place on the pole (or do not)"
