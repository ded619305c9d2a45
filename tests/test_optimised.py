"""The ``optimised`` strategy (issue 18): least time, then least acceleration, of the first
rotary axis inside each singular span, within the tool-axis cone, the tip on the CL path."""

from __future__ import annotations

import numpy as np
import pytest

from urdfpost.analysis.testpaths import great_circle_sweep, hemisphere_raster
from urdfpost.geometry import angle_between
from urdfpost.machine import load_machine
from urdfpost.planning.singularity import step_times
from urdfpost.planning.strategies import (
    STRATEGIES,
    best_tilt,
    exact_selection,
    realise,
    tool_axis_of,
)
from urdfpost.planning.strategies.optimised import RATE_SHARE, cone_bounds, smooth_angles
from urdfpost.posting.options import PostOptions, resolve
from urdfpost.posting.piece import make_problem
from urdfpost.posting.whole import post

ANGLE = np.radians(2.0)


def step_exact(k: int = 20) -> np.ndarray:
    """A half turn in the middle of a span: what the exact solution does through a pole."""
    return np.r_[np.zeros(k // 2), np.full(k - k // 2 + 1, np.pi)]


def free(exact: np.ndarray, width: float = 10.0) -> tuple[np.ndarray, np.ndarray]:
    return exact - width, exact + width


def test_with_room_and_time_the_smoothest_turn_is_the_linear_ramp() -> None:
    # ends fixed, bounds far, rate feasible: zero acceleration at every inner point
    exact, dt = step_exact(), np.full(20, 0.1)
    x = smooth_angles(exact, *free(exact), dt, vmax=np.pi)
    assert x[0] == exact[0] and x[-1] == exact[-1]
    np.testing.assert_allclose(np.diff(x), np.pi / 20, atol=1e-6)


def test_without_time_the_turn_takes_the_least_time_the_limit_allows() -> None:
    exact, dt = step_exact(), np.full(20, 0.1)
    vmax = np.pi / 4  # half a turn needs 4 s; the feed gives 2 s
    x = smooth_angles(exact, *free(exact), dt, vmax=vmax)
    time = np.maximum(dt, np.abs(np.diff(x)) / vmax).sum()
    assert time == pytest.approx(4.0, rel=1e-6)
    # and no step is idle while another is slowed: the least time spread over the span
    np.testing.assert_allclose(np.diff(x), np.pi / 20, atol=1e-5)


def test_the_angles_keep_their_bounds_and_rate() -> None:
    rng = np.random.default_rng(7)
    exact = step_exact(30)
    lo = exact - rng.uniform(0.05, 0.6, exact.size)
    hi = exact + rng.uniform(0.05, 0.6, exact.size)
    dt = rng.uniform(0.05, 0.2, 30)
    vmax = 2.0
    x = smooth_angles(exact, lo, hi, dt, vmax=vmax)
    assert np.all(x >= lo - 1e-12) and np.all(x <= hi + 1e-12)
    assert x[0] == exact[0] and x[-1] == exact[-1]
    # the least time: each step at most the limit over its share of that time
    lp_time = np.maximum(dt, np.abs(np.diff(x)) / vmax).sum()
    ramp = np.clip(np.linspace(exact[0], exact[-1], exact.size), lo, hi)
    assert lp_time <= np.maximum(dt, np.abs(np.diff(ramp)) / vmax).sum() + 1e-9


def test_a_span_with_no_feed_is_smoothed_in_uniform_steps() -> None:
    exact = step_exact()
    x = smooth_angles(exact, *free(exact), np.full(20, np.nan), vmax=1.0)
    np.testing.assert_allclose(np.diff(x), np.pi / 20, atol=1e-6)


@pytest.mark.parametrize("machine", ["dmu50", "dmu50-nutating", "gantry-ca"])
def test_cone_bounds_are_where_the_tool_axis_reaches_the_angle_tolerance(machine: str) -> None:
    m = load_machine(machine)
    tp = great_circle_sweep(5.0)
    problem = make_problem(tp, resolve(PostOptions(), m, tp.units))
    q = exact_selection(problem, tp).q[:, list(m.rotary_columns)]
    lo, hi = cone_bounds(m, tp.axis, q, ANGLE)
    lo2, hi2 = m.rotary[1].lower, m.rotary[1].upper

    def dev(theta: np.ndarray) -> np.ndarray:
        t2 = np.clip(best_tilt(m, tp.axis, theta, q[:, 1]), lo2, hi2)
        return angle_between(tool_axis_of(m, np.stack([theta, t2], axis=1)), tp.axis)

    assert np.all(lo <= q[:, 0]) and np.all(q[:, 0] <= hi)
    inner = (hi - q[:, 0] < np.pi - 1e-9) & (q[:, 0] - lo < np.pi - 1e-9)
    assert inner.any()
    np.testing.assert_allclose(dev(hi)[inner], ANGLE, atol=1e-9)
    np.testing.assert_allclose(dev(lo)[inner], ANGLE, atol=1e-9)
    # and every angle between the bounds is in the cone
    for t in np.linspace(0.0, 1.0, 11):
        assert np.all(dev(lo + t * (hi - lo)) <= ANGLE * (1 + 1e-9))


def five_mm_problem(machine: str):
    m = load_machine(machine)
    tp = hemisphere_raster(offsets=(5.0,))
    job = resolve(PostOptions(strategy="optimised", detector="rate"), m, tp.units)
    return m, make_problem(tp, job)


def first_axis_time(plan_rotary: np.ndarray, dt: np.ndarray, vmax: float) -> float:
    """Time of the CL steps with the first rotary axis at most at ``vmax``, s."""
    timed = dt > 0  # feed steps (the approach is a rapid)
    return float(np.maximum(dt[timed], np.abs(np.diff(plan_rotary))[timed] / vmax).sum())


def test_on_the_5mm_pass_least_time_in_the_cone_with_the_tip_on_the_path() -> None:
    m, problem = five_mm_problem("dmu50")
    plan = STRATEGIES["optimised"](problem)
    assert plan.bent and [s.kind for s in plan.spans] == ["rate"]
    tp = plan.toolpath
    assert np.array_equal(plan.param, np.arange(len(tp)))  # a row per CL point
    dt, vmax = step_times(tp), RATE_SHARE * m.rotary[0].velocity
    exact = exact_selection(problem, tp).q[:, m.rotary_columns[0]]
    timed = dt > 0
    assert (np.abs(np.diff(exact))[timed] / dt[timed]).max() > 2 * m.rotary[0].velocity
    linear = STRATEGIES["linear"](problem)  # the same span, C linear across it
    assert np.array_equal(linear.param, plan.param)
    t_opt = first_axis_time(plan.rotary[:, 0], dt, vmax)
    assert t_opt < first_axis_time(linear.rotary[:, 0], dt, vmax) - 0.05
    assert t_opt < first_axis_time(exact, dt, vmax) - 0.1
    _, tip, axis = realise(problem, plan)
    assert np.all(angle_between(axis, tp.axis) <= problem.angle_tolerance * (1 + 1e-9))
    # the cutting point (the ball centre) is on the CL path at every row
    centre = tp.tip + problem.pivot * tp.axis
    np.testing.assert_allclose(tip + problem.pivot * axis, centre, atol=1e-9)
    # outside the span the rows are the exact solution
    sp = plan.spans[0]
    outside = np.r_[: sp.first + 1, sp.last : len(tp)]
    np.testing.assert_allclose(axis[outside], tp.axis[outside], atol=1e-9)


@pytest.mark.parametrize("machine", ["dmu50", "dmu50-nutating", "gantry-ca"])
@pytest.mark.parametrize("detector", ["geometric", "rate"])
def test_optimised_posts_and_verifies_the_hemisphere(machine: str, detector: str) -> None:
    tp = hemisphere_raster(offsets=(0.0, 0.5, 5.0))
    options = PostOptions(strategy="optimised", detector=detector)
    result = post(tp, load_machine(machine), options)
    assert result.verification.ok
    assert result.report.strategy.name == "optimised"
