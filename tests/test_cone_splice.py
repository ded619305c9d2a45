"""The cone's last round spliced from round 1 and its windows (issue 21): the plan of planning the
whole path again, within the stated bound.

Where the rounds on windows converged, ``cone._spliced`` takes the last round's branch choice,
spans and bent angles from round 1 outside the windows and from the windows' last rounds inside
them, instead of planning the whole path once more. The oracle here is that whole round
(``cone.SPLICE`` False): the same toolpath, rows, spans, settled point and notes, and angles
within ``cone.SPLICE_BOUND`` (what differs is the rounding of running sums, about 1e-14 rad),
on generated jobs and machines of the families where the windows' rounds converge; and the
splice is refused, with the whole round planned, where a window's ends are not round 1's.
"""

from __future__ import annotations

import numpy as np
import pytest
from test_cone_spans import MACHINES, jobs

from urdfpost.analysis.testpaths import hemisphere_raster
from urdfpost.machine import load_machine
from urdfpost.planning.problem import Plan, Problem
from urdfpost.planning.strategies import STRATEGIES, cone
from urdfpost.tolerances import Tolerances
from urdfpost.toolpath import Toolpath


def all_jobs() -> dict[str, Toolpath]:
    """The cone's test jobs and a raster ten times denser (where the default windows cover less
    than half the path)."""
    return {**jobs(), "raster 0.05 mm": hemisphere_raster(step=0.05)}


def planned(problem: Problem, monkeypatch: pytest.MonkeyPatch, splice: bool) -> tuple[Plan, int]:
    """The cone's plan with or without the splice, and how many rounds were spliced."""
    spliced = cone._spliced
    count = [0]

    def counted(*args: object) -> object:
        r = spliced(*args)  # type: ignore[arg-type]
        count[0] += r is not None
        return r

    with monkeypatch.context() as mp:
        mp.setattr(cone, "SPLICE", splice)
        mp.setattr(cone, "_spliced", counted)
        plan = STRATEGIES["cone"](problem)
    return plan, count[0]


def assert_same_plan(plan: Plan, oracle: Plan, bound: float, what: str) -> None:
    """The same plan but for angles within ``bound`` (rad)."""
    assert np.array_equal(plan.toolpath.tip, oracle.toolpath.tip), what
    assert np.array_equal(plan.toolpath.axis, oracle.toolpath.axis), what
    assert np.array_equal(plan.param, oracle.param), what
    assert plan.rotary.shape == oracle.rotary.shape, what
    assert np.array_equal(np.isnan(plan.rotary), np.isnan(oracle.rotary)), what
    assert np.nanmax(np.abs(plan.rotary - oracle.rotary), initial=0.0) <= bound, what
    assert plan.settled == oracle.settled, what
    assert plan.notes == oracle.notes, what
    assert plan.bent == oracle.bent, what
    assert len(plan.spans) == len(oracle.spans), what
    for a, b in zip(plan.spans, oracle.spans, strict=True):
        assert (a.first, a.last, a.first_line, a.last_line, a.kind) == (
            b.first,
            b.last,
            b.first_line,
            b.last_line,
            b.kind,
        ), what
        for f in ("min_sigma", "max_kappa", "swing_deg", "max_step_deg"):
            x, y = getattr(a, f), getattr(b, f)
            assert x == y or abs(x - y) <= 1e-9 * max(1.0, abs(y)), (what, f)
    if plan.curve is not None:
        assert oracle.curve is not None
        x = np.linspace(0.0, len(plan.toolpath) - 1.0, 5 * len(plan.toolpath))
        on, off = plan.curve(x), oracle.curve(x)
        assert np.array_equal(np.isnan(on), np.isnan(off)), what
        assert np.nanmax(np.abs(on - off), initial=0.0) <= bound, what


@pytest.mark.parametrize("margin", [cone.WINDOW_MARGIN, 8])
@pytest.mark.parametrize("machine_name", MACHINES)
def test_the_spliced_last_round_is_the_whole_paths(
    machine_name: str, margin: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Spliced or planned on the whole path again, the last round gives the same plan (angles
    within ``SPLICE_BOUND``); the splice is taken on the dense raster of dmu50 (default
    windows) and on the nutating machine's coarse rasters (narrow windows)."""
    m = load_machine(machine_name)
    monkeypatch.setattr(cone, "WINDOW_MARGIN", margin)
    taken = []
    for name, tp in all_jobs().items():
        problem = Problem(m, tp, tool_length=m.settings.tool_length, tol=Tolerances())
        plan, count = planned(problem, monkeypatch, True)
        oracle, none = planned(problem, monkeypatch, False)
        assert none == 0
        assert_same_plan(plan, oracle, cone.SPLICE_BOUND, f"{machine_name}, {name}")
        if count:
            taken.append(name)
    if machine_name == "dmu50":
        assert "raster 0.05 mm" in taken
    if machine_name == "dmu50-nutating" and margin == 8:
        assert {"raster 1 mm", "raster 2 mm"} <= set(taken), taken


def test_a_window_whose_ends_are_not_round_1s_is_not_spliced(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Where a window's last round bent its end rows otherwise than round 1 (beyond the bound),
    the splice is refused and the whole path planned again: the plan is the whole round's to
    the bit."""
    m = load_machine("dmu50")
    problem = Problem(
        m, hemisphere_raster(step=0.05), tool_length=m.settings.tool_length, tol=Tolerances()
    )
    oracle, _ = planned(problem, monkeypatch, False)
    window_round = cone._window_round
    spoilt = [0]

    def moved_ends(*args: object) -> object:
        found = window_round(*args)  # type: ignore[arg-type]
        if found is None:
            return None
        over, rounds = found
        out = []
        for a, b, local in rounds:
            if local.bent is not None:
                bent = local.bent.copy()
                bent[-1, 0] += 10 * cone.SPLICE_BOUND
                local = cone._Round(**{**local.__dict__, "bent": bent})
                spoilt[0] += 1
            out.append((a, b, local))
        return over, out

    monkeypatch.setattr(cone, "_window_round", moved_ends)
    plan, count = planned(problem, monkeypatch, True)
    assert spoilt[0] and count == 0
    assert_same_plan(plan, oracle, 0.0, "refused")
