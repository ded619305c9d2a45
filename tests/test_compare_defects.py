"""Regression tests of ``compare`` (issue 18): a job no strategy can post, span indices after
inserted pole points, the CL line named for a failed orientation, what the plot shows, one
acceptance rule and one planner for every strategy, and the per-block data."""

from __future__ import annotations

import csv
import functools
import io
import json
import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from urdfpost.analysis.compare import (
    FIXED_PLANNER,
    Comparison,
    compare,
    per_block_csv,
    spans_on_cl,
    table,
)
from urdfpost.analysis.plot import TIME_LABEL, comparison_figure
from urdfpost.analysis.testpaths import great_circle_sweep, to_apt
from urdfpost.cli import main
from urdfpost.dialects import dialect_for
from urdfpost.errors import UrdfpostError
from urdfpost.machine import Machine, load_machine
from urdfpost.planning.problem import Plan, Problem
from urdfpost.planning.strategies import STRATEGIES
from urdfpost.posting.options import PostOptions
from urdfpost.posting.whole import post
from urdfpost.toolpath import Toolpath, toolpath_slice
from urdfpost.verification import verify

PNG = b"\x89PNG\r\n\x1a\n"


@functools.cache
def machine(name: str) -> Machine:
    return load_machine(name)


def out_of_travel() -> Toolpath:
    """A short sweep 5 m beside the table: out of dmu50's linear travel on every branch."""
    tp = great_circle_sweep(1.0, points=5)
    return replace(tp, tip=tp.tip + np.array([5000.0, 0.0, 0.0]))


def pole_at_the_end() -> Toolpath:
    """Five CL points (an approach and four feed moves, no retract) whose tool axis crosses the
    pole between two of them: the strategies insert a pole point there, and the singular span
    runs to the last CL point."""
    return toolpath_slice(great_circle_sweep(0.0, points=4), 0, 5)


def labels(comparison: Comparison) -> list[str]:
    fig = comparison_figure(comparison)
    return [t.get_text() for legend in fig.legends for t in legend.get_texts()]


# -- a job no strategy can post -----------------------------------------------------------------


def test_compare_reports_why_each_strategy_fails() -> None:
    result = compare(out_of_travel(), machine("dmu50"), ["none", "cone"])
    assert not result.posted
    assert [o.strategy for o in result.outcomes] == ["none", "cone"]
    for o in result.outcomes:
        assert o.metrics is None and not o.verified
        assert o.error is not None and "outside the linear travel" in o.error
        assert o.reason == (
            "line 9: CL point (4978.2635, 0.1719, 9.8466) mm is outside the linear travel of "
            "machine dmu50 on every branch"
        )
    data = result.as_dict()
    assert data["posted"] is False
    assert all(s["error"] and s["reason"] for s in data["strategies"])


def test_compare_command_without_any_program_writes_report_and_plot_and_exits_1(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """It raised ValueError from the plot (a traceback) and exited without a report."""
    cl = tmp_path / "far.apt"
    cl.write_text(to_apt(out_of_travel()), encoding="utf-8")
    report, plot = tmp_path / "c.json", tmp_path / "c.png"
    argv = ["compare", str(cl), "-m", "dmu50", "--strategies", "none,cone"]
    assert main([*argv, "--report", str(report), "--plot", str(plot)]) == 1
    out, err = capsys.readouterr()
    assert "Traceback" not in err
    assert err.startswith("urdfpost: no strategy makes a verified program of "), err
    for name in ("none", "cone"):
        assert re.search(
            rf"^{name} +no +(local|global) +failed: .*outside the linear travel", out, re.M
        ), out
    data = json.loads(report.read_text(encoding="utf-8"))
    assert data["posted"] is False
    assert [s["strategy"] for s in data["strategies"]] == ["none", "cone"]
    assert all("outside the linear travel" in s["error"] for s in data["strategies"])
    assert plot.read_bytes()[:8] == PNG


def test_compare_help_names_the_exit_status(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        main(["compare", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "1 when none does" in text and "0 when at least one strategy" in text


def test_plot_of_a_job_nothing_posts_names_every_failure() -> None:
    result = compare(out_of_travel(), machine("dmu50"), ["none", "cone"])
    texts = labels(result)
    assert [t.split(":")[0] for t in texts] == ["none", "cone"]
    assert all(": failed: " in t and "outside the linear travel" in t for t in texts)


# -- span indices after inserted pole points ----------------------------------------------------


def test_spans_are_cl_indices_when_pole_points_were_inserted() -> None:
    """``_to_cl_indices`` searched the plan's toolpath (one point more): ``last`` was 5."""
    tp = pole_at_the_end()
    assert len(tp) == 5
    result = compare(tp, machine("dmu50"), ["recursive"])
    assert result.spans
    for sp in result.spans:
        assert 0 <= sp.first <= sp.last <= len(tp) - 1
        assert (tp.line[sp.first], tp.line[sp.last]) == (sp.first_line, sp.last_line)
    assert (result.spans[-1].first, result.spans[-1].last) == (2, 4)


def test_spans_on_cl_keep_the_lines_and_stay_in_range() -> None:
    tp = pole_at_the_end()  # lines 9 11 12 13 14
    plan_spans = compare(tp, machine("dmu50"), ["recursive"]).spans
    inserted = [replace(sp, first=sp.first + 1, last=sp.last + 1) for sp in plan_spans]
    assert spans_on_cl(inserted, tp) == plan_spans


def test_compare_command_plots_spans_that_end_at_the_last_cl_point(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The plot raised IndexError (index 5 of 5 CL points)."""
    cl = tmp_path / "p5.apt"
    cl.write_text(to_apt(pole_at_the_end()), encoding="utf-8")
    report, plot = tmp_path / "c.json", tmp_path / "c.png"
    argv = ["compare", str(cl), "-m", "dmu50", "--strategies", "none,recursive"]
    assert main([*argv, "--report", str(report), "--plot", str(plot)]) == 0
    assert "Traceback" not in capsys.readouterr().err
    data = json.loads(report.read_text(encoding="utf-8"))
    assert data["cl_points"] == 5 and data["spans"]
    assert all(0 <= s["first"] <= s["last"] <= 4 for s in data["spans"])
    assert (data["spans"][-1]["first_line"], data["spans"][-1]["last_line"]) == (12, 14)
    assert plot.read_bytes()[:8] == PNG


# -- the CL line named for a failed orientation -------------------------------------------------


def edit_word(line: str, address: str, delta: float) -> str:
    """``line`` with ``delta`` added to the value of its word ``address`` (same decimals)."""

    def repl(m: re.Match[str]) -> str:
        text = m.group(1)
        decimals = len(text.split(".")[1]) if "." in text else 0
        return f"{address}{float(text) + delta:+.{decimals}f}"

    out, n = re.subn(rf"\b{address}([-+]?\d*\.?\d+)", repl, line, count=1)
    assert n == 1 and out != line, line
    return out


def shift_y(lines: list[str], row: int, dy: float) -> None:
    """Move the tip of program row ``row`` (a block that writes X but not Y, after one at
    Y 0) by ``dy`` across the path, and the next row back onto it (Y is modal)."""
    for k, y in ((row, dy), (row + 1, 0.0)):
        assert " Y" not in lines[k], lines[k]
        lines[k] = re.sub(r"( X[-+]?\d*\.?\d+)", rf"\1 Y{y:+.3f}", lines[k], count=1)


def test_worst_line_of_a_failed_orientation_is_where_the_axis_deviates() -> None:
    """With the tip within tolerance and the orientation not, "worst near CL line" named the
    line of the worst tip deviation (line 932 for a turn at lines 1430-1432)."""
    tp = great_circle_sweep(5.0, points=9, half_angle_deg=20.0)
    m = machine("dmu50")
    result = post(tp, m, PostOptions(strategy="recursive", controller="heidenhain"))
    lines = result.text.splitlines()
    feed = tp.motion == 0
    line_of = {
        x: int(tp.line[np.flatnonzero(np.isclose(tp.tip[:, 0], x) & feed)[0]])
        for x in (-15.0, 0.0, 5.0)
    }
    tip_row = next(i for i, t in enumerate(lines) if " X-15.000 " in t)
    axis_row = next(i for i, t in enumerate(lines) if " X+5.000 " in t)
    shift_y(lines, tip_row, 0.005)  # tip off by half its tolerance
    lines[axis_row] = edit_word(lines[axis_row], "B", 1.0)  # axis off by 1 deg (0.5 allowed)
    readback = dialect_for("heidenhain").read("\n".join(lines) + "\n")
    check = verify(readback, m, tp)
    assert not check.ok
    assert check.max_tip_deviation == pytest.approx(0.005, abs=1e-3)
    assert check.max_orientation_deviation_deg > 0.9
    # the axis is off at the CL point of line_of[5] (not reached), between its neighbours
    assert line_of[0.0] <= check.worst_cl_line <= line_of[5.0], (check.worst_cl_line, line_of)


def test_worst_line_of_a_failed_tip_is_still_the_tip() -> None:
    tp = great_circle_sweep(5.0, points=9, half_angle_deg=20.0)
    m = machine("dmu50")
    result = post(tp, m, PostOptions(strategy="recursive", controller="heidenhain"))
    lines = result.text.splitlines()
    row = next(i for i, t in enumerate(lines) if " X-15.000 " in t)
    shift_y(lines, row, 0.05)
    check = verify(dialect_for("heidenhain").read("\n".join(lines) + "\n"), m, tp)
    x15 = int(tp.line[np.flatnonzero(np.isclose(tp.tip[:, 0], -15.0))[0]])
    assert not check.ok and check.max_orientation_deviation_deg < 0.5
    assert x15 - 1 <= check.worst_cl_line <= x15


# -- what the plot shows -----------------------------------------------------------------------


def _broken(problem: Problem) -> Plan:
    raise UrdfpostError(f"{problem.toolpath.source}: broken: refuses every job")


def test_plot_has_a_legend_entry_for_every_strategy_marker_and_band(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Failing strategies are marked, the turn-in-place triangles and the limit lines have
    legend entries, and the panels are against the CL index and against time."""
    monkeypatch.setitem(STRATEGIES, "broken", _broken)
    tp = pole_at_the_end()
    result = compare(tp, machine("dmu50"), ["none", "recursive", "broken"])
    by_name = {o.strategy: o for o in result.outcomes}
    assert not by_name["none"].verified and by_name["recursive"].verified
    assert by_name["broken"].metrics is None
    texts = labels(result)
    assert "recursive" in texts
    assert any(t.startswith("none: NOT verified: axis ") for t in texts), texts
    assert "broken: failed: broken: refuses every job" in texts
    assert any(t.startswith("turn in place") for t in texts), texts
    assert {"C velocity limit", "B velocity limit", "singular span (pole)"} <= set(texts)

    fig = comparison_figure(result)
    xlabels = {ax.get_xlabel() for ax in fig.axes} - {""}
    assert xlabels == {
        "CL index (0 .. 4, CL points as read)",
        TIME_LABEL,
    }
    # every line drawn is a strategy's, a limit or a marker with an entry
    colours = {line.get_color() for ax in fig.axes for line in ax.get_lines()}
    assert colours <= {"C0", "C1", "k"}


def test_cl_index_of_rows_runs_over_the_cl_points() -> None:
    tp = pole_at_the_end()
    result = compare(tp, machine("dmu50"), ["recursive"])
    (o,) = result.outcomes
    assert o.cl_index is not None and o.metrics is not None and o.metrics.profile is not None
    x = o.cl_index[np.isfinite(o.cl_index)]
    assert len(o.cl_index) == len(o.metrics.profile.s)
    assert x[0] == 0 and x[-1] == len(tp) - 1
    assert np.all(np.diff(x) >= 0)


# -- one acceptance rule, one planner, figures that carry information (issue 18) -------------------


def test_every_strategy_is_accepted_by_one_rule_with_tip_and_ball_deviation() -> None:
    """Bent strategies were measured at the ball centre and exact ones at the tip; now every
    strategy reports both, and the rule's tolerances are in the report."""
    tp = great_circle_sweep(0.1, points=21)
    result = compare(tp, machine("gantry-ca"), list(STRATEGIES))
    acc = result.acceptance
    assert acc["ball_radius"] > 0 and acc["angle"] == pytest.approx(2.0)
    assert acc["tip"] > 0 and acc["axis"] > 0
    for o in result.outcomes:
        m = o.metrics
        assert m is not None, o.strategy
        assert m.max_ball_deviation is not None, o.strategy
        # the ball centre of an exact program is off by at most the tip plus r times the axis
        if not o.bent:
            bound = m.max_tip_deviation + acc["ball_radius"] * np.radians(
                m.max_orientation_deviation_deg
            )
            assert m.max_ball_deviation <= bound + 1e-6, o.strategy
    data = result.as_dict()
    assert data["acceptance"] == acc
    assert set(data["limits"]["C"]) == {"velocity", "acceleration", "jerk"}


def test_the_planner_column_tells_the_truth() -> None:
    """``none`` plans point by point whatever the job says: its row says "local", the others
    run with the job's planner."""
    tp = great_circle_sweep(0.1, points=21)
    m = machine("gantry-ca")
    texts = {
        planner: post(tp, m, PostOptions(strategy="none", planner=planner)).text
        for planner in ("global", "local")
    }
    assert texts["global"] == texts["local"]  # FIXED_PLANNER["none"] is what the strategy does
    result = compare(tp, m, ["none", "recursive"], PostOptions(planner="global"))
    assert [o.planner for o in result.outcomes] == [FIXED_PLANNER["none"], "global"]
    local = compare(tp, m, ["recursive"], PostOptions(planner="local"))
    assert local.outcomes[0].planner == "local"


def test_table_drops_the_velocity_that_equals_the_limit_and_counts_turns() -> None:
    """ "C vel" was the velocity limit by construction; "C demand" left out turns in place
    without saying so."""
    tp = pole_at_the_end()
    result = compare(tp, machine("dmu50"), ["recursive"])
    text = table(result)
    head = text.splitlines()[1].split()
    assert "vel" not in head and "turns" in head and "sing" in head
    row = text.splitlines()[3].split()
    assert int(row[head.index("turns")]) == result.outcomes[0].metrics.turns_in_place >= 1
    assert "ball dev" in text.splitlines()[1] and "accepted:" in text.splitlines()[0]


def test_time_in_singular_spans_is_part_of_the_timed_path() -> None:
    tp = great_circle_sweep(0.1, points=21)
    result = compare(tp, machine("gantry-ca"), ["recursive", "cone"])
    assert result.spans
    for o in result.outcomes:
        assert o.metrics is not None and o.singular_time_s is not None
        assert 0 < o.singular_time_s < o.metrics.time_s
    assert result.as_dict()["strategies"][0]["singular_time_s"] == pytest.approx(
        result.outcomes[0].singular_time_s
    )


# -- per-block data -----------------------------------------------------------------------------


def test_per_block_csv_has_a_row_per_program_row_per_strategy() -> None:
    tp = great_circle_sweep(0.1, points=21)
    result = compare(tp, machine("gantry-ca"), ["linear", "spline"])
    rows = list(csv.DictReader(io.StringIO(per_block_csv(result))))
    for o in result.outcomes:
        mine = [r for r in rows if r["strategy"] == o.strategy]
        assert o.metrics is not None and o.metrics.profile is not None
        prof = o.metrics.profile
        assert len(mine) == len(prof.s)
        assert [int(r["block"]) for r in mine] == list(range(len(mine)))
        t = np.array([float(r["t_s"]) for r in mine])
        assert np.all(np.diff(t) >= 0) and t[-1] == pytest.approx(prof.t[-1])
        c = np.array([float(r["q_C"]) for r in mine])
        np.testing.assert_allclose(c, prof.q[:, prof.column("C")], rtol=1e-8, atol=1e-9)
        ci = np.array([float(r["cl_index"]) if r["cl_index"] else np.nan for r in mine])
        finite = ci[np.isfinite(ci)]
        assert finite[0] == 0 and finite[-1] == len(tp) - 1 and np.all(np.diff(finite) >= 0)
        on_cl = [r for r in mine if r["cl_index"] and not int(r["rapid"])]
        tip = np.array([float(r["tip_dev_mm"]) for r in on_cl])
        axis = np.array([float(r["axis_dev_deg"]) for r in on_cl])
        # sampled per block, the axis at the nearest CL place; the verification refines every
        # block and compares the axis at its own place along the path: the maxima of the
        # report are the verification's, the per-block figures close to them
        assert tip.max() <= o.metrics.max_tip_deviation * (1 + 1e-4) + 1e-9
        assert axis.max() == pytest.approx(o.metrics.max_orientation_deviation_deg, rel=0.05)
        speed = np.array([float(r["tip_speed_mm_s"]) for r in on_cl])
        # where the post slowed blocks to an axis limit the F changes from block to block,
        # and the timed speed at a row follows the feeds of the blocks about it (the timing
        # blends the speed over its samples, and moves the joints linearly between rows,
        # whose tip path is a little longer than a TCP control's straight line: within the
        # feed tolerance there); elsewhere at most the CL feed
        programmed = 1000.0 / 60.0  # the sweep's CL feed, mm/s
        feeds = np.array([float(r["feed_mm_s"]) if r["feed_mm_s"] else programmed for r in mine])
        window = np.lib.stride_tricks.sliding_window_view(np.pad(feeds, 2, mode="edge"), 5)
        at = [mine.index(r) for r in on_cl]
        around, slowed = window.max(axis=1)[at], (window < programmed * (1 - 1e-9)).any(axis=1)[at]
        assert np.all(speed[~slowed] <= programmed * (1 + 1e-3))
        assert np.all(speed[slowed] <= around[slowed] * (1 + 1e-2))


def test_compare_command_writes_the_csv_and_refuses_one_file_for_two(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    cl = tmp_path / "sweep.apt"
    cl.write_text(to_apt(great_circle_sweep(0.1, points=21)), encoding="utf-8")
    out = tmp_path / "blocks.csv"
    argv = ["compare", str(cl), "-m", "gantry-ca", "--strategies", "linear,spline"]
    assert main([*argv, "--csv", str(out)]) == 0
    text = out.read_text(encoding="utf-8")
    assert text.startswith("strategy,verified,block,cl_index,")
    assert {r["strategy"] for r in csv.DictReader(io.StringIO(text))} == {"linear", "spline"}
    capsys.readouterr()
    same = tmp_path / "same"
    assert main([*argv, "--csv", str(same), "--report", str(same)]) == 2
    assert "--csv and --report name the same file" in capsys.readouterr().err
    assert not same.exists()
