"""The rows of a plan (:func:`urdfpost.planning.realise.solve_rows`): the tip worked out only in
the rows that take it (on the CL path, or the cutting point above it along the tool axis), the
same numbers as worked out in every row and chosen after."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from urdfpost import load_machine
from urdfpost.kinematics.inverse import assemble, solve_linear
from urdfpost.planning.problem import Problem, _cutting_point, _on_segments, tool_axis_of
from urdfpost.planning.realise import solve_rows
from urdfpost.readers import read_cl
from urdfpost.tolerances import Tolerances
from urdfpost.toolpath import Toolpath

DOME = Path(__file__).resolve().parents[1] / "examples" / "dome.apt"


def _rows_everywhere(
    problem: Problem,
    toolpath: Toolpath,
    param: np.ndarray,
    rotary: np.ndarray,
    lift: np.ndarray,
    bent: np.ndarray | None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`solve_rows` as it was written: both points in every row, then chosen."""
    machine = problem.machine
    pivot = problem.pivot if bent is None else np.where(bent, problem.pivot, 0.0)
    where = _on_segments(toolpath, param)
    point = _cutting_point(toolpath, *where, 0.0)
    centre = _cutting_point(toolpath, *where, problem.pivot)
    axis = tool_axis_of(machine, rotary)
    pv = np.broadcast_to(pivot, (len(param),))[:, None]
    tip = np.where(pv > 0, centre - pv * axis, point) + lift[:, None] * axis
    lin = solve_linear(machine, rotary, tip, problem.tool_length)
    return assemble(machine, rotary, lin), tip, axis


@pytest.mark.parametrize("pivot", [0.0, 3.0, -1.0])
@pytest.mark.parametrize("share", [None, 0.0, 0.3, 0.7, 1.0])
@pytest.mark.parametrize("lifted", [False, True])
def test_rows_are_those_worked_out_everywhere(
    pivot: float, share: float | None, lifted: bool
) -> None:
    """Bent rows none, some, most or all (or not given), with a pivot above, at or below the
    tip, lifted or not: the same joints, tips and axes bit for bit."""
    m = load_machine("dmu50")
    toolpath = read_cl(DOME)
    rng = np.random.default_rng(7)
    n = 3000
    problem = Problem(m, toolpath, tool_length=100.0, tol=Tolerances(), pivot=pivot)
    param = np.sort(rng.uniform(0.0, len(toolpath) - 1, n))
    whole = rng.random(n) < 0.2  # rows at CL points
    param[whole] = np.floor(param[whole])
    rotary = np.column_stack([rng.uniform(-0.5, 1.0, n), rng.uniform(-3.0, 3.0, n)])
    lift = rng.uniform(0.0, 2.0, n) * (rng.random(n) < 0.3) if lifted else np.zeros(n)
    bent = None if share is None else rng.random(n) < share
    got = solve_rows(problem, toolpath, param, rotary, lift, bent=bent)
    want = _rows_everywhere(problem, toolpath, param, rotary, lift, bent)
    for a, b in zip(got, want, strict=True):
        assert np.array_equal(a, b)
