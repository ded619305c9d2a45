"""The cone's rounds take the inverse kinematics of their old points over (issue 21): the same
plans as solving every point of every round.

Each round of the cone plans the toolpath of the round before with a few points inserted (or a
window of it); the inverse kinematics of the old points is taken over from the round before
(``cone._solved``, a :class:`~urdfpost.planning.strategies._pointwise.PointMemo`), which is exact
because it is a row function. Checked here: the memo against the plain call of its function,
the row function property of the inverse kinematics on every machine family, and the cone's
plans with the memo against those solving every point, on jobs that insert points in several
rounds, cross the pole and switch branch between CL points.
"""

from __future__ import annotations

import numpy as np
import pytest
from test_cone_spans import MACHINES, jobs
from test_strategy_defects import loops_near_the_pole

from urdfpost.kinematics.inverse import inverse
from urdfpost.machine import Machine, load_machine
from urdfpost.planning.problem import Problem
from urdfpost.planning.strategies import STRATEGIES, cone, split_at_pole_crossings
from urdfpost.planning.strategies._pointwise import PointMemo
from urdfpost.tolerances import Tolerances
from urdfpost.toolpath import Toolpath


def bits(a: np.ndarray) -> bytes:
    return np.ascontiguousarray(a).tobytes()


def test_the_memo_gives_the_plain_call_and_computes_only_new_rows() -> None:
    """Points inserted, a window, rows whose inputs changed and several rows on one point: the
    outputs are those of calling the function on every row, and only the rows without a kept
    equal are computed."""
    computed: list[int] = []

    def fn(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        computed.append(len(x))
        return np.sin(x) * y[:, 0] + y[:, 1], np.stack([np.arctan2(x, y[:, 0]), x], axis=1)

    rng = np.random.default_rng(3)
    n = 50
    x, y = rng.normal(size=n), rng.normal(size=(n, 2))
    memo = PointMemo.new(fn, n)
    out, memo = memo(np.arange(n), x, y)
    assert computed == [n]
    assert all(bits(a) == bits(b) for a, b in zip(out, fn(x, y), strict=True))
    # three points inserted (at 5, 20 and the end), one old point's input changed
    old = np.delete(np.arange(n + 3), [5, 20, n + 2])
    x2, y2 = np.empty(n + 3), np.empty((n + 3, 2))
    x2[old], y2[old] = x, y
    new = np.setdiff1d(np.arange(n + 3), old)
    x2[new], y2[new] = rng.normal(size=3), rng.normal(size=(3, 2))
    y2[old[7], 1] = np.nextafter(y2[old[7], 1], np.inf)  # one bit off
    memo = memo.moved(old, n + 3)
    computed.clear()
    every = np.arange(n + 3)
    out, memo2 = memo(every, x2, y2)
    assert computed == [4]
    assert all(bits(a) == bits(b) for a, b in zip(out, fn(x2, y2), strict=True))
    # a window of the points, and rows sharing points (a second row on point 12, other values)
    at = np.array([10, 11, 12, 12, 13, 30])
    xs, ys = x2[at].copy(), y2[at].copy()
    xs[3] += 1.0
    computed.clear()
    out, _ = memo2.taken(slice(0, 40))(at, xs, ys)
    assert computed == [1]
    assert all(bits(a) == bits(b) for a, b in zip(out, fn(xs, ys), strict=True))


def path_points(tp: Toolpath, m: Machine) -> tuple[np.ndarray, np.ndarray]:
    """Tips and tool axes of ``tp`` with the points the pole crossings of ``m`` insert."""
    split = split_at_pole_crossings(tp, m, Tolerances().pole_crossing)
    return split.tip, split.axis


@pytest.mark.parametrize("machine_name", MACHINES)
def test_the_inverse_kinematics_is_a_row_function(machine_name: str) -> None:
    """What the memo relies on: the rows of the inverse kinematics of any part of the points,
    gathered (a point, a few, more than a block of the solver, each at any place), are the
    bits of those of all of them."""
    m = load_machine(machine_name)
    parts = [path_points(tp, m) for tp in [*jobs().values(), loops_near_the_pole()]]
    tip = np.concatenate([p[0] for p in parts] * 60)  # more than a solver's block
    axis = np.concatenate([p[1] for p in parts] * 60)
    rng = np.random.default_rng(5)
    axis[::7] = rng.normal(size=(len(axis[::7]), 3))  # and orientations all over the sphere
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    whole = inverse(m, tip, axis, 150.0, Tolerances(), pole_angle=0.0)
    for k in (1, 2, 3, 17, 1000, len(tip) - 1):
        at = np.sort(rng.choice(len(tip), k, replace=False))
        part = inverse(m, tip[at], axis[at], 150.0, Tolerances(), pole_angle=0.0)
        assert bits(part.q) == bits(whole.q[at]), k
        assert bits(part.rotary.angles) == bits(whole.rotary.angles[at]), k
        assert bits(part.valid) == bits(whole.valid[at]), k
        assert bits(part.status) == bits(whole.status[at]), k


@pytest.mark.parametrize("machine_name", MACHINES)
def test_the_cone_plans_the_same_with_the_old_points_solutions_taken_over(
    machine_name: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The cone with the memo and solving every point of every round: the same plans to the
    bit, on jobs where it inserts points over several rounds (on windows and the whole path),
    passes over the pole (points on it) and, on the gantry, switches branch between CL points
    (a point inserted by the branch choice itself). The memo does take solutions over."""
    m = load_machine(machine_name)
    solved: list[int] = []
    plain_inverse = cone.inverse

    def counted(machine, tip, *args, **kwargs):  # type: ignore[no-untyped-def]
        solved.append(len(tip))
        return plain_inverse(machine, tip, *args, **kwargs)

    def plain_call(memo: PointMemo, at: np.ndarray, *args: np.ndarray) -> tuple:
        return memo.fn(*args), memo

    switches: list[int] = []  # points the branch choice inserts
    plain_split = cone.split_at_switches

    def split(problem, tp, sel):  # type: ignore[no-untyped-def]
        out = plain_split(problem, tp, sel)
        switches.append(len(out[0]) - len(tp))
        return out

    monkeypatch.setattr(cone, "inverse", counted)
    monkeypatch.setattr(cone, "split_at_switches", split)
    for name, tp in {**jobs(), "loops": loops_near_the_pole()}.items():
        problem = Problem(m, tp, tool_length=m.settings.tool_length, tol=Tolerances())
        solved.clear()
        plan = STRATEGIES["cone"](problem)
        with_memo = sum(solved)
        with monkeypatch.context() as mp:
            mp.setattr(PointMemo, "__call__", plain_call)
            solved.clear()
            oracle = STRATEGIES["cone"](problem)
        assert np.array_equal(plan.toolpath.tip, oracle.toolpath.tip), name
        assert np.array_equal(plan.toolpath.axis, oracle.toolpath.axis), name
        assert np.array_equal(plan.param, oracle.param), name
        assert bits(plan.rotary) == bits(oracle.rotary), name
        assert plan.notes == oracle.notes and plan.spans == oracle.spans, name
        assert plan.settled == oracle.settled, name
        if plan.curve is not None:
            assert oracle.curve is not None
            x = np.linspace(0.0, len(plan.toolpath) - 1.0, 5 * len(plan.toolpath))
            assert bits(plan.curve(x)) == bits(oracle.curve(x)), name
        if len(solved) > 1:  # rounds after the first: solutions taken over
            assert with_memo < sum(solved), name
    if machine_name == "gantry-ca":
        assert sum(switches) > 0
