"""How long a posted program runs (:meth:`~urdfpost.posting.report.FeedFigures.duration`).

The post times every feed block for its F (:mod:`urdfpost.posting.feeds`); the same figures
add up to the program's run time: feed moves at the F written (arcs along the arc), a turn in
place under TCP at its axes' velocity limits, rapids at the axes' velocity limits, dwells, and
the motion of canned cycles. Checked against the program read back: each G93 block takes
1 / F minutes, each rapid the longest of its axes' travels over their velocity limits.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from jobs import arc_job, drilling_job

from urdfpost import load_machine
from urdfpost.cli import main
from urdfpost.dialects import DIALECTS
from urdfpost.posting.options import PostOptions
from urdfpost.posting.whole import post
from urdfpost.program import FEED_INVERSE_TIME, expand_cycles
from urdfpost.readers import read_cl, read_cl_text
from urdfpost.verification.feeds import axis_lengths, machine_joints
from urdfpost.verification.match import program_joints

DOME = Path(__file__).resolve().parents[1] / "examples" / "dome.apt"


def _read_back_minutes(text: str, controller: str, machine_name: str, tool_length: float):
    """Feed and rapid minutes of a machine-coordinate program as the control runs it (its
    cycles expanded): 1 / F per G93 feed block, or its axis path over F per minute; per rapid,
    the longest axis travel over its velocity limit."""
    program = expand_cycles(DIALECTS[controller].read(text))
    machine = load_machine(machine_name)
    table = program.move_table()
    values, rapid = program_joints(machine, program)
    q = np.vstack([machine.home[None], values])
    m = machine_joints(machine, q, program.tcp, tool_length)
    feed = table.feed
    cut = ~rapid & np.isfinite(feed)
    if program.feed_mode == FEED_INVERSE_TIME:
        feed_minutes = float(np.sum(1.0 / feed[cut]))
    else:
        rule = DIALECTS[controller].spec.axis_feed_rule
        length = axis_lengths(machine, m[:-1][cut], m[1:][cut], rule, program.units)
        feed_minutes = float(np.sum(length / feed[cut]))
    travel = np.abs(np.diff(m, axis=0))[rapid]
    velocity = np.array([a.velocity for a in machine.axes]) * 60.0  # per minute
    rapid_minutes = float(np.max(travel / velocity, axis=1).sum())
    return feed_minutes, rapid_minutes


@pytest.mark.parametrize("controller", ["fanuc", "linuxcnc", "siemens"])
def test_the_run_time_is_that_of_the_program_read_back(controller: str) -> None:
    """The dome in machine coordinates in inverse time: the post's feed minutes are the sum
    of 1 / F read back (within the F words' rounding: 1e-5), its rapid minutes those of the rapids
    read back."""
    result = post(
        read_cl(DOME), load_machine("dmu50"), PostOptions(controller=controller, tcp=False)
    )
    feeds = result.report.figures.feeds
    want_feed, want_rapid = _read_back_minutes(
        result.text, controller, "dmu50", result.program.tool_length
    )
    assert feeds.feed_minutes == pytest.approx(want_feed, rel=1e-5)
    assert feeds.rapid_minutes == pytest.approx(want_rapid, rel=1e-6)
    assert feeds.dwell_seconds == 0.0
    assert 0.2 < feeds.feed_minutes < 1.0  # (about 23 s at 800-2000 mm/min)


def test_canned_cycles_and_dwells_count() -> None:
    """A drilling job: the cycles' motion (feeds into the holes, their rapids, the dwell at
    the bottom, a tap's way in and out) is in the run time, as the control runs it expanded.
    (Without the job's peck cycle: the post times a peck cycle's motion as the CL data asks
    for it, the first peck from the hole top, which Fanuc's G83 counts from its R plane.)"""
    text = drilling_job()
    start = text.index("CYCLE/DRILL,DEEP")
    text = text[:start] + text[text.index("CYCLE/OFF", start) + len("CYCLE/OFF\n") :]
    result = post(
        read_cl_text(text, source="drill.apt"),
        load_machine("dmu50"),
        PostOptions(controller="fanuc", tcp=False),
    )
    feeds = result.report.figures.feeds
    want_feed, want_rapid = _read_back_minutes(
        result.text, "fanuc", "dmu50", result.program.tool_length
    )
    assert feeds.feed_minutes == pytest.approx(want_feed, rel=1e-5)
    assert feeds.rapid_minutes == pytest.approx(want_rapid, rel=1e-6)
    assert feeds.dwell_seconds == pytest.approx(2 * 0.5)  # two holes dwell 0.5 s each


def test_arcs_are_timed_along_the_arc() -> None:
    """A job with arcs, in TCP (the arcs keep their CL feed per minute): the arcs' feed time
    is their length along the arc over their feed, not their chord's."""
    job = read_cl_text(arc_job(), source="arcs.apt")
    with_arcs = post(job, load_machine("dmu50"), PostOptions(controller="fanuc"))
    as_lines = post(job, load_machine("dmu50"), PostOptions(controller="fanuc", arcs=False))
    a = with_arcs.report.figures.feeds.feed_minutes
    b = as_lines.report.figures.feeds.feed_minutes
    assert a == pytest.approx(b, rel=1e-3)  # the lines follow the arc within the tolerance


def test_the_post_prints_it_and_reports_it_whole_and_in_pieces(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The post's last line says it; the report has it (``feeds``); a post in pieces adds up
    its pieces' figures to the same (within 1e-5: its program differs in the last digit of a
    few X words where the cone planned the pieces apart)."""
    import json

    figures = []
    for args in ([], ["--piece-points", "100"]):
        out, report = tmp_path / "dome.h", tmp_path / "dome.json"
        assert (
            main(["post", str(DOME), "-m", "dmu50", "-o", str(out), "--report", str(report), *args])
            == 0
        )
        last = capsys.readouterr().out.splitlines()[-1]
        assert last.startswith("run time about 26.6 s: feed moves 23.2 s, rapids 3.5 s"), last
        figures.append(json.loads(report.read_text())["feeds"])
    whole, pieces = figures
    for key in ("feed_minutes", "rapid_minutes", "dwell_seconds"):
        assert pieces[key] == pytest.approx(whole[key], rel=1e-5), key


@pytest.mark.parametrize("controller", ["heidenhain", "fanuc"])
def test_the_header_says_it_whole_and_in_pieces(tmp_path: Path, controller: str) -> None:
    """The header's run time line: the report's figures, whole and in pieces (the streamed
    post's placeholder line replaced), and in tool sections (the sections' times added)."""
    from jobs import TWO_TOOLS

    from urdfpost.posting.report import FeedFigures

    for cl, args in ((DOME, []), (DOME, ["--piece-points", "100"])):
        out = tmp_path / f"p{DIALECTS[controller].extensions[0]}"
        argv = ["post", str(cl), "-m", "dmu50", "-c", controller, "-o", str(out), "-q"]
        assert main([*argv, "--report", str(tmp_path / "r.json"), *args]) == 0
        import json

        feeds = json.loads((tmp_path / "r.json").read_text())["feeds"]
        figures = FeedFigures(
            mode=feeds["mode"],
            feed_minutes=feeds["feed_minutes"],
            rapid_minutes=feeds["rapid_minutes"],
            dwell_seconds=feeds["dwell_seconds"],
        )
        line = DIALECTS[controller].spec.comment_text(figures.header_line())
        assert line in out.read_text(), (args, line)
        assert "run time: not known" not in out.read_text().lower()
    # a machine-coordinate job in two tool sections (two gauge lengths)
    two = read_cl_text(TWO_TOOLS.replace("LOADTL/2", "LOADTL/2,LENGTH,120"), source="two.apt")
    result = post(two, load_machine("dmu50"), PostOptions(controller=controller, tcp=False))
    line = DIALECTS[controller].spec.comment_text(result.report.figures.feeds.header_line())
    assert line in result.text
    assert result.report.figures.feeds.feed_minutes > 0
