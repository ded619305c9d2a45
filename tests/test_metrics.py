"""Strategy metrics: the velocity-only block-duration rule, the timed kinematics (closed-form
trapezoids, limits held, jerk independent of how the path is cut into blocks), units, the
hemisphere's closed-form C rate, JSON output and the comparison plot."""

from __future__ import annotations

import functools
import json
import math
from pathlib import Path

import numpy as np
import pytest

from urdfpost.analysis.compare import compare
from urdfpost.analysis.metrics import (
    block_times,
    cl_path_position,
    measure,
)
from urdfpost.analysis.plot import plot_comparison
from urdfpost.analysis.testpaths import great_circle_sweep, hemisphere_raster
from urdfpost.dialects import dialect_for
from urdfpost.kinematics.forward import tip_and_axis
from urdfpost.machine import Machine, load_machine
from urdfpost.machine.load import AxisLimits, axis_limits
from urdfpost.posting.options import PostOptions
from urdfpost.posting.whole import PostResult, post
from urdfpost.program import Move, Program, Tcp
from urdfpost.toolpath import Motion, Toolpath
from urdfpost.verification import program_joints


@functools.cache
def machine(name: str) -> Machine:
    return load_machine(name)


def tcp_program(m: Machine, rows: list[tuple[bool, float | None, dict[str, float]]]) -> Program:
    """A TCP program from (rapid, feed mm/min, {axis: value}) rows (other axes 0)."""
    moves = tuple(
        Move(rapid=rapid, position=tuple(pos.get(a, 0.0) for a in m.axis_names), feed=feed)
        for rapid, feed, pos in rows
    )
    return Program(
        name="T",
        axes=m.axis_names,
        rotary=frozenset(a.name for a in m.rotary),
        units="mm",
        tcp=True,
        blocks=(Tcp(on=True), *moves, Tcp(on=False)),
        tool_length=100.0,
    )


def cl_of(m: Machine, program: Program) -> Toolpath:
    """The CL data a TCP program reaches exactly (its tips and tool axes, its feeds)."""
    values, rapid = program_joints(m, program)
    _, axis = tip_and_axis(m, values)
    tp = Toolpath.from_points(values[:, list(m.linear_columns)], axis, feed=1000.0, spindle=10000.0)
    tp.motion[rapid] = Motion.RAPID
    feed = program.move_table().feed
    tp.feed[:] = np.where(np.isfinite(feed), feed, 1000.0)  # (the modal feed of the text)
    tp.feed[rapid] = np.nan
    return tp


# -- the duration rule --------------------------------------------------------------------------


def test_block_time_is_the_feed_or_the_axis_limit_whichever_is_longer() -> None:
    m = machine("dmu50")
    c_limit = math.degrees(m.axis("C").velocity)  # 179.9 deg/s
    program = tcp_program(
        m,
        [
            (True, None, {"X": 0.0, "B": 30.0, "C": 0.0}),
            (False, 600.0, {"X": 10.0, "B": 30.0, "C": 1.0}),  # L/F = 1 s, C 1 deg: feed
            (False, 600.0, {"X": 11.0, "B": 30.0, "C": 91.0}),  # L/F = 0.1 s, C 90 deg: limit
            (False, 600.0, {"X": 16.0, "B": 30.0, "C": 91.0}),  # linear only: 0.5 s
        ],
    )
    metrics = measure(program, m, cl_of(m, program))
    expected = np.array([1.0, 90.0 / c_limit, 0.5])
    np.testing.assert_allclose(np.diff(metrics.profile.t_velocity_only), expected, rtol=1e-12)
    assert metrics.velocity_limited_blocks == 1
    assert metrics.velocity_only_time_s == pytest.approx(expected.sum())
    assert metrics.nominal_time_s == pytest.approx(1.6)
    # the timed trajectory is slower still: it starts and ends at rest
    assert metrics.time_s > metrics.velocity_only_time_s
    assert metrics.slowdown == pytest.approx(metrics.time_s / 1.6)
    assert metrics.peak_velocity["C"] <= c_limit * (1 + 1e-6)
    assert metrics.peak_demand_velocity["C"] == pytest.approx(900.0)  # 90 deg in 0.1 s
    assert metrics.max_step_deg == pytest.approx({"B": 0.0, "C": 90.0})
    assert metrics.mean_step_deg["C"] == pytest.approx(91.0 / 3)
    assert metrics.blocks == 4 and metrics.cl_points == 4 and metrics.added_blocks == 0
    # the 90 degree C block turns the tool axis off the CL slerp: only the tip is exact here
    assert metrics.cl_points_reached == 4 and metrics.max_tip_deviation < 1e-9


def test_block_times_of_rapids_come_from_the_axis_limits() -> None:
    dq = np.array([[10.0, 0.0], [0.0, 2.0], [0.0, 0.0]])
    time, limited = block_times(
        dq,
        length=np.array([10.0, 0.0, 5.0]),
        feed=np.array([np.inf, np.inf, 10.0]),
        limit=np.array([100.0, np.inf]),
    )
    np.testing.assert_allclose(time, [0.1, 0.0, 0.5])
    np.testing.assert_array_equal(limited, [True, False, False])


# -- timed kinematics ---------------------------------------------------------------------------


def limits_of(m: Machine, acceleration: float, jerk: float = math.inf) -> AxisLimits:
    """The machine's velocity limits; every axis the same acceleration and jerk limit."""
    n = len(m.axes)
    return AxisLimits(
        m.axis_names, axis_limits(m).velocity, np.full(n, acceleration), np.full(n, jerk)
    )


def line_rows(points: list[float]) -> list[tuple[bool, float | None, dict[str, float]]]:
    """A rapid to X = 0, then feed moves along X through ``points`` at 600 mm/min (B, C = 0)."""
    rows: list[tuple[bool, float | None, dict[str, float]]] = [(True, None, {"X": 0.0})]
    return rows + [(False, 600.0, {"X": x}) for x in points]


@pytest.mark.parametrize("acceleration", [20.0, 100.0, 1000.0])
def test_a_straight_line_from_rest_to_rest_is_a_trapezoid(acceleration: float) -> None:
    """10 mm at 10 mm/s: ``L / F + F / a`` (0.5 s at constant speed took 0.5 s before)."""
    m = machine("dmu50")
    program = tcp_program(m, line_rows([float(k) for k in range(1, 11)]))
    metrics = measure(program, m, cl_of(m, program), limits=limits_of(m, acceleration))
    closed_form = 10.0 / 10.0 + 10.0 / acceleration
    assert metrics.time_s == pytest.approx(closed_form, abs=2e-3)  # the 1 ms clock
    assert metrics.velocity_only_time_s == pytest.approx(1.0)
    assert metrics.peak_velocity["X"] == pytest.approx(10.0, rel=1e-6)
    assert metrics.peak_acceleration["X"] == pytest.approx(acceleration, rel=1e-3)
    assert metrics.feed_ratio == pytest.approx(1.0 / closed_form, abs=2e-3)


def test_a_turn_in_place_is_a_trapezoid_of_its_rotary_axis() -> None:
    m = machine("dmu50")
    program = tcp_program(
        m, [(True, None, {"B": 30.0, "C": 0.0}), (False, 600.0, {"B": 30.0, "C": 90.0})]
    )
    limits = axis_limits(m)  # the linear axes follow the turn about the tip: not limiting
    limits = AxisLimits(limits.axes, limits.velocity, limits.acceleration, limits.jerk * np.inf)
    c = m.axis_names.index("C")
    w, a = limits.velocity[c], limits.acceleration[c]
    metrics = measure(program, m, cl_of(m, program), limits=limits)
    assert metrics.turns_in_place == 1
    assert metrics.time_s == pytest.approx(math.pi / 2 / w + w / a, abs=2e-3)
    assert metrics.peak_velocity["C"] == pytest.approx(math.degrees(w), rel=1e-6)
    assert metrics.peak_acceleration["C"] == pytest.approx(math.degrees(a), rel=1e-3)


def test_the_jerk_filter_holds_the_jerk_limit_and_costs_its_length() -> None:
    m = machine("dmu50")
    program = tcp_program(m, line_rows([float(k) for k in range(1, 11)]))
    a, j = 1000.0, 10000.0  # a filter of 2 a / j = 0.2 s
    metrics = measure(program, m, cl_of(m, program), limits=limits_of(m, a, j))
    assert metrics.time_s == pytest.approx(1.0 + 10.0 / a + 0.2, abs=3e-3)
    assert 0 < metrics.peak_jerk["X"] <= j * (1 + 1e-6)
    assert metrics.jerk_over_limit_s["X"] == 0.0
    assert metrics.peak_velocity["X"] == pytest.approx(10.0, rel=1e-3)


def test_jerk_does_not_depend_on_how_the_path_is_cut_into_blocks() -> None:
    """A collinear 0.1 um block changes nothing on the timed trajectory."""
    m = machine("dmu50")
    points = [float(k) for k in range(1, 11)]
    cut = [*points[:5], 5.0001, *points[5:]]
    limits = limits_of(m, 1000.0, 10000.0)
    whole, split = (
        measure(p, m, cl_of(m, p), limits=limits)
        for p in (tcp_program(m, line_rows(points)), tcp_program(m, line_rows(cut)))
    )
    assert split.blocks == whole.blocks + 1
    assert split.peak_jerk["X"] == pytest.approx(whole.peak_jerk["X"], rel=1e-3)
    assert split.peak_acceleration["X"] == pytest.approx(whole.peak_acceleration["X"], rel=1e-3)
    assert split.time_s == pytest.approx(whole.time_s, abs=2e-3)


def test_a_rounded_micro_block_gives_no_jerk_spike() -> None:
    """Issue 18: jerk was a finite difference over blocks, so a 0.1 um block whose C word is
    rounded (C 5.000 at X 5.0001 on a path of 1 deg/mm) lasted 10 us and gave 4e7 deg/s^3
    (1.45e13 on the real hemisphere). On the timed trajectory the block is a knot like any
    other: the figures stay those of the path without it, and within the jerk limit."""
    m = machine("dmu50")

    def rows(pts: list[tuple[float, float]]) -> list[tuple[bool, float | None, dict[str, float]]]:
        start: list[tuple[bool, float | None, dict[str, float]]] = [
            (True, None, {"B": 30.0, "C": 0.0})
        ]
        return start + [(False, 600.0, {"X": x, "B": 30.0, "C": c}) for x, c in pts]

    line = [(float(k), float(k)) for k in range(1, 11)]
    rounded = [*line[:5], (5.0001, 5.0), *line[5:]]
    limits = limits_of(m, 1000.0, 10000.0)
    whole, split = (
        measure(p, m, cl_of(m, p), limits=limits)
        for p in (tcp_program(m, rows(line)), tcp_program(m, rows(rounded)))
    )
    c_jerk_limit = math.degrees(10000.0)
    assert 0 < split.peak_jerk["C"] <= c_jerk_limit
    assert split.peak_jerk["C"] == pytest.approx(whole.peak_jerk["C"], rel=0.05)
    assert split.peak_acceleration["C"] == pytest.approx(whole.peak_acceleration["C"], rel=0.05)
    assert split.time_s == pytest.approx(whole.time_s, rel=0.02)


def test_timed_hemisphere_keeps_every_limit_and_the_feed() -> None:
    tp = hemisphere_raster(offsets=(2.0,), step=0.5, max_tilt_deg=30.0)
    m = machine("gantry-ca")
    result = post(tp, m, PostOptions(tcp=True, strategy="recursive"))
    metrics = measure(readback(result, m), m, tp, tool_length=result.program.tool_length)
    limits = axis_limits(m).as_dict(frozenset(a.name for a in m.rotary))
    for name, lim in limits.items():
        assert metrics.peak_velocity[name] <= lim["velocity"] * (1 + 1e-6), name
        assert metrics.peak_acceleration[name] <= lim["acceleration"] * 1.01, name
    prof = metrics.profile
    feed = prof.feed[np.isfinite(prof.feed)]
    assert np.all(prof.tip_speed[np.isfinite(prof.feed)] <= feed * (1 + 1e-3))
    assert np.all(np.diff(prof.t) >= 0) and prof.t[-1] >= metrics.time_s
    # the post slowed the blocks where an axis would exceed its velocity limit (issue 19):
    # the program's own feeds already give the velocity-only time
    assert metrics.time_s > metrics.velocity_only_time_s >= metrics.nominal_time_s
    assert metrics.timing_failed_runs == 0
    assert 0 < metrics.slow_fraction < 1


def test_profile_and_cl_positions_measure_the_same_path() -> None:
    tp = great_circle_sweep(5.0)
    m = machine("gantry-ca")
    result = post(tp, m, PostOptions(tcp=True, strategy="none"))
    metrics = measure(result.program, m, tp)
    prof = metrics.profile
    assert metrics.blocks == len(tp)
    np.testing.assert_allclose(prof.s, cl_path_position(tp), atol=1e-9)
    c = prof.column("C")
    assert prof.q.shape == prof.velocity.shape == prof.demand.shape == (len(tp), 5)
    assert np.all(np.isnan(prof.demand[prof.rapid, c]))


# -- units ------------------------------------------------------------------------------------


def readback(result: PostResult, m: Machine) -> Program:
    return dialect_for(m.settings.controller).read(result.text)


def test_inch_program_gives_the_same_figures_as_mm() -> None:
    tp = hemisphere_raster(offsets=(5.0,), step=0.5, max_tilt_deg=20.0)
    m = machine("umc750")
    figures = {}
    for units in ("mm", "inch"):
        result = post(tp, m, PostOptions(tcp=True, units=units, strategy="none"))
        program = readback(result, m)
        assert program.units == units
        figures[units] = measure(program, m, tp, tool_length=result.program.tool_length)
    mm, inch = figures["mm"], figures["inch"]
    assert inch.verified and mm.verified
    assert inch.nominal_time_s == pytest.approx(mm.nominal_time_s, rel=1e-3)
    assert inch.velocity_only_time_s == pytest.approx(mm.velocity_only_time_s, rel=1e-3)
    # the timed trajectory follows the path's curvature, which rounding to 0.0001 in (2.5 um
    # on 0.5 mm blocks) changes a little
    assert inch.time_s == pytest.approx(mm.time_s, rel=5e-3)
    assert inch.peak_demand_velocity["C"] == pytest.approx(mm.peak_demand_velocity["C"], rel=5e-3)
    # 2000 mm/min over a path of known length, but where the post slowed the blocks that
    # would drive C beyond its limit (issue 19): those take the axis' time, which the
    # program's own feeds then give
    at_feed = cl_path_position(tp)[-2] / (2000 / 60)
    assert mm.nominal_time_s > at_feed * 0.98
    assert mm.velocity_only_time_s == pytest.approx(mm.nominal_time_s, rel=1e-3)


# -- the closed form --------------------------------------------------------------------------


@pytest.mark.parametrize("tcp", [True, False], ids=["tcp", "machine"])
@pytest.mark.parametrize("y0", [2.0, 5.0])
def test_hemisphere_c_demand_peaks_at_feed_over_offset(y0: float, tcp: bool) -> None:
    feed = 2000.0
    tp = hemisphere_raster(offsets=(y0,), feed=feed, step=0.1, max_tilt_deg=20.0)
    m = machine("dmu50")
    result = post(tp, m, PostOptions(tcp=tcp, strategy="none"))
    metrics = measure(readback(result, m), m, tp, tool_length=result.program.tool_length)
    closed_form = math.degrees(feed / 60.0 / y0)  # deg/s
    assert metrics.min_sigma == pytest.approx(y0 / 50.0, rel=0.01)  # sin(arcsin(y0 / R))
    # the C limit (179.9 deg/s) is below F / y0 here: the axis limit sets the pace. The post
    # slows those blocks to it (issue 19): the slowest keeps the share limit / (F / y0) of
    # the CL feed
    c_limit = math.degrees(m.axis("C").velocity)
    figures = result.report.figures
    assert figures is not None and figures.feeds is not None
    assert figures.feeds.capped_blocks > 0 and figures.feeds.capped_by.get("C", 0) > 0
    assert figures.feeds.worst_share == pytest.approx(c_limit / closed_form, rel=0.01)
    # what the CL feed demands of C (the program's F is lower there)
    assert metrics.peak_demand_velocity["C"] == pytest.approx(closed_form, rel=0.01)
    # timed with the axes' acceleration too, C gets near its limit, never beyond it
    assert 0.95 * c_limit <= metrics.peak_velocity["C"] <= c_limit * (1 + 1e-6)
    assert metrics.verified and metrics.cl_points_reached == len(tp)


# -- reports ------------------------------------------------------------------------------------


def test_as_dict_is_json_ready_and_a_pole_turn_is_counted() -> None:
    m = machine("dmu50")
    # down to the pole (B = 0), half a turn of C in place there, and away on the other side
    rows: list[tuple[bool, float | None, dict[str, float]]] = [(True, None, {"B": 10.0})]
    rows += [(False, 600.0, {"X": float(k), "B": 10.0 - 2.0 * k}) for k in range(1, 6)]
    rows += [(False, 600.0, {"X": 5.0, "B": 0.0, "C": 180.0})]
    rows += [(False, 600.0, {"X": 5.0 + k, "B": 2.0 * k, "C": 180.0}) for k in range(1, 6)]
    program = tcp_program(m, rows)
    metrics = measure(program, m, cl_of(m, program), lifts=2)
    assert metrics.turns_in_place == 1 and metrics.min_sigma == pytest.approx(0.0, abs=1e-12)
    assert metrics.max_step_deg["C"] == pytest.approx(180.0)
    assert metrics.peak_demand_velocity["C"] == 0.0  # the turn moves no tip: not a demand
    assert np.isinf(metrics.profile.demand[6, metrics.profile.column("C")])
    c_limit = math.degrees(m.axis("C").velocity)
    assert np.diff(metrics.profile.t_velocity_only)[5] == pytest.approx(180.0 / c_limit)
    assert metrics.verified
    data = metrics.as_dict()
    text = json.dumps(data, allow_nan=False)
    assert "profile" not in data and data["lifts"] == 2
    assert data["max_kappa"] is None  # infinite on the pole
    for key in (
        "blocks",
        "cl_points",
        "added_blocks",
        "max_step_deg",
        "mean_step_deg",
        "peak_velocity",
        "peak_acceleration",
        "peak_jerk",
        "jerk_over_limit_s",
        "acceleration_limit",
        "jerk_limit",
        "feed_ratio",
        "slow_fraction",
        "velocity_only_time_s",
        "turns_in_place",
        "max_ball_deviation",
        "peak_demand_velocity",
        "time_s",
        "rapid_time_s",
        "nominal_time_s",
        "slowdown",
        "max_tip_deviation",
        "max_orientation_deviation_deg",
        "cl_points_reached",
        "min_sigma",
        "max_kappa",
        "velocity_limited_blocks",
        "lifts",
    ):
        assert key in data, key
    assert json.loads(text)["blocks"] == metrics.blocks


def test_plot_comparison_writes_a_png(tmp_path: Path) -> None:
    tp = great_circle_sweep(1.0, points=9)
    result = compare(tp, machine("dmu50"), ["none", "cone"])
    target = tmp_path / "compare.png"
    plot_comparison(result, target, title="sweep 1 deg")
    assert target.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert [p.name for p in tmp_path.iterdir()] == ["compare.png"]  # no temporary left
