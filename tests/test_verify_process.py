"""``urdfpost verify`` checks the process too: feeds, spindle, tool numbers, program end.

Real jobs are posted for every control with the command line; the intact program verifies, and
each damage (made with the control's own words) exits 1 naming the program line, though the
geometry is still within tolerance (issue 23).
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from jobs import arc_job, drilling_job, two_tools

import urdfpost.posting.whole as whole
from urdfpost import load_machine
from urdfpost.cli import main
from urdfpost.dialects import DIALECTS
from urdfpost.dialects.writer import ProgramWriter
from urdfpost.errors import ToleranceError
from urdfpost.posting.options import PostOptions
from urdfpost.posting.process import checked_process
from urdfpost.posting.stream import post_stream
from urdfpost.program import Spindle
from urdfpost.readers import read_cl, read_cl_text
from urdfpost.tolerances import Tolerances
from urdfpost.toolpath import Motion, toolpath_pieces
from urdfpost.verification import verify, verify_matched
from urdfpost.verification.process import ProcessChecker, distinct

ROOT = Path(__file__).resolve().parents[1]
DOME = ROOT / "examples" / "dome.apt"
CONTROLLERS = ("heidenhain", "siemens", "fanuc", "linuxcnc")
TWO_TOOLS = two_tools(1200.0)  # the feed, which a damage turns into 9999
"""Two tools, the second without a SPINDL of its own (the post restarts the spindle)."""

DEFAULTS = """\
PARTNO DEFAULTS
UNITS/MM
MULTAX/ON
RAPID
GOTO/0,0,20,0,0,1
GOTO/0,0,2,0,0,1
GOTO/10,0,2,0,0,1
FEDRAT/MMPM,600
GOTO/20,0,2,0,0,1
GOTO/20,20,2,0,0,1
FINI
"""
"""No tool, no spindle, and cuts before the first feed: posted with --feed and --spindle."""


@dataclass(frozen=True)
class Job:
    """A CL file, and what the damages change in its programs."""

    cl: Path
    feed: int  # a CL feed (mm/min) whose first F word is changed
    tool: int  # the last tool loaded
    tool_line: int  # its LOADTL line


@dataclass(frozen=True)
class Posted:
    path: Path
    text: str
    controller: str
    job: Job


def _lines(text: str) -> list[str]:
    return text.splitlines()


def _line_at(text: str, offset: int) -> int:
    """1-based line of character ``offset``."""
    return text.count("\n", 0, offset) + 1


def _feed_word(feed: int) -> re.Pattern[str]:
    """The F word of ``feed`` as every control writes it (Fanuc: ``F1200.``)."""
    return re.compile(rf"(?<![A-Z])F{feed}\.?(?![\d.])")


def _cl_lines(job: Job) -> tuple[int, int]:
    """CL lines of the first cutting point and of the first point cut at ``job.feed``."""
    toolpath = read_cl(job.cl)
    cuts = toolpath.motion == int(Motion.FEED)
    first = int(toolpath.line[cuts.argmax()])
    at_feed = int(toolpath.line[(cuts & (toolpath.feed == job.feed)).argmax()])
    return first, at_feed


def _first_cut_line(posted: Posted, text: str) -> int:
    """The line of the program's first cutting move: the first F word."""
    match = re.search(r"(?<![A-Z])F\d", text)
    assert match is not None
    return _line_at(text, match.start())


Damage = Callable[[Posted], tuple[str, int, str]]
"""Makes the damaged text, the line ``verify`` names and a regular expression of its message."""


def feed_changed(posted: Posted) -> tuple[str, int, str]:
    match = _feed_word(posted.job.feed).search(posted.text)
    assert match is not None
    text = posted.text[: match.start()] + "F9999" + posted.text[match.end() :]
    _, cl_line = _cl_lines(posted.job)
    want = rf"feed F9999 where the CL has F{posted.job.feed} \(CL line {cl_line}\)"
    return text, _line_at(text, match.start()), want


def spindle_start_deleted(posted: Posted) -> tuple[str, int, str]:
    # Heidenhain starts the spindle on a line of its own ("12 M3"), the others after the S word
    own_line = r"^(?:\d+ )?M3\n" if posted.controller == "heidenhain" else r" M3\b"
    text, n = re.subn(own_line, "", posted.text, count=1, flags=re.M)
    assert n == 1
    first, _ = _cl_lines(posted.job)
    rpm = re.search(r"(?<![A-Z])S(\d+)", posted.text)
    assert rpm is not None
    want = rf"spindle off where the CL has S{rpm[1]} CW \(CL line {first}\)"
    return text, _first_cut_line(posted, text), want


def speed_times_ten(posted: Posted) -> tuple[str, int, str]:
    rpm = re.search(r"(?<![A-Z])S(\d+)", posted.text)
    assert rpm is not None
    text = re.sub(r"(?<![A-Z])S(\d+)", lambda m: f"S{int(m[1]) * 10}", posted.text)
    first, _ = _cl_lines(posted.job)
    want = rf"spindle S{int(rpm[1]) * 10} CW where the CL has S{rpm[1]} CW \(CL line {first}\)"
    return text, _first_cut_line(posted, text), want


def tool_changed(posted: Posted) -> tuple[str, int, str]:
    n = posted.job.tool
    if posted.controller == "heidenhain":
        word = re.compile(rf"(TOOL CALL ){n}\b")
    else:  # "T2 M6", "T2 D1", block numbers or not
        word = re.compile(rf"^((?:N\d+ )?T){n}\b", re.M)
    match = word.search(posted.text)
    assert match is not None
    text = word.sub(r"\g<1>7", posted.text, count=1)
    want = rf"tool T7 where the CL loads tool {n} \(CL line {posted.job.tool_line}\)"
    return text, _line_at(text, match.start()), want


def end_cut_off(posted: Posted) -> tuple[str, int, str]:
    """Every line after the last move gone (M30, %, END PGM, M2)."""
    lines = _lines(posted.text)
    last = max(i for i, x in enumerate(lines) if re.search(r"(?<![A-Z0-9])[XYZBC][-+]?\d", x))
    text = "\n".join(lines[: last + 1]) + "\n"
    return text, last + 1, r"no program end \(M\d+[^)]*\) after this line"


def end_marker_deleted(posted: Posted) -> tuple[str, int, str]:
    """The program's last line gone: Fanuc's ``%`` and Heidenhain's ``END PGM`` after M30,
    Siemens' M30, LinuxCNC's M2 (issue 23: a program with M30 but no closing ``%`` or ``END
    PGM`` was taken as whole)."""
    lines = _lines(posted.text)
    last = max(i for i, x in enumerate(lines) if x.strip())
    text = "\n".join(lines[:last]) + "\n"
    before = max(i for i, x in enumerate(lines[:last]) if x.strip())
    words = {
        "fanuc": r"M30 and %",
        "heidenhain": r"M30 and END PGM",
        "siemens": r"M30",
        "linuxcnc": r"M2",
    }[posted.controller]
    return text, before + 1, rf"no program end \({words}\) after this line"


DAMAGES: dict[str, Damage] = {
    "feed 9999": feed_changed,
    "M3 deleted": spindle_start_deleted,
    "S times ten": speed_times_ten,
    "tool 7": tool_changed,
    "end cut off": end_cut_off,
    "end marker deleted": end_marker_deleted,
}


@pytest.fixture(scope="module")
def jobs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Job]:
    folder = tmp_path_factory.mktemp("cl")
    two = folder / "two.apt"
    two.write_text(TWO_TOOLS)
    return {
        "dome": Job(DOME, feed=2000, tool=3, tool_line=5),
        "two tools": Job(two, feed=1200, tool=2, tool_line=13),
    }


@pytest.fixture(scope="module")
def posted(
    jobs: dict[str, Job], tmp_path_factory: pytest.TempPathFactory
) -> Callable[[str, str], Posted]:
    """The program of a job for a control, posted once by the command line."""
    folder = tmp_path_factory.mktemp("programs")
    done: dict[tuple[str, str], Posted] = {}

    def get(job: str, controller: str) -> Posted:
        if (job, controller) not in done:
            ext = DIALECTS[controller].extensions[0]
            out = folder / f"{job.replace(' ', '_')}_{controller}{ext}"
            argv = ["post", str(jobs[job].cl), "-m", "dmu50", "-c", controller, "-o", str(out)]
            assert main([*argv, "-q"]) == 0
            done[job, controller] = Posted(out, out.read_text(), controller, jobs[job])
        return done[job, controller]

    return get


def _verify(
    path: Path, job: Job, capsys: pytest.CaptureFixture[str], *extra: str
) -> tuple[int, str]:
    capsys.readouterr()
    argv = ["verify", str(path), "-m", "dmu50", "--cl", str(job.cl), "--angle-tolerance", "2"]
    code = main([*argv, *extra])
    return code, capsys.readouterr().out


@pytest.mark.parametrize("controller", CONTROLLERS)
@pytest.mark.parametrize("job", ["dome", "two tools"])
@pytest.mark.parametrize("damage", ["intact", *DAMAGES])
def test_verify_compares_the_process_with_the_cl_data(
    damage: str,
    job: str,
    controller: str,
    posted: Callable[[str, str], Posted],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    program = posted(job, controller)
    if damage == "intact":
        code, out = _verify(program.path, program.job, capsys)
        assert code == 0, out
        assert "verification within tolerance" in out
        assert "process as in the CL data" in out
        return
    text, line, message = DAMAGES[damage](program)
    assert text != program.text
    bad = tmp_path / f"damaged{program.path.suffix}"
    bad.write_text(text)
    code, out = _verify(bad, program.job, capsys)
    assert code == 1, out
    if damage == "feed 9999":  # the geometry did not change; the tip feed did
        assert "tip feed BEYOND TOLERANCE" in out, out
    else:
        assert "verification within tolerance" in out  # the geometry did not change
    assert "process DIFFERS" in out
    assert re.search(rf"^{re.escape(str(bad))}:{line}: {message}", out, re.M), out


@pytest.mark.parametrize("single", [False, True], ids=["workers", "single-process"])
@pytest.mark.parametrize("controller", ["heidenhain", "fanuc"])
@pytest.mark.parametrize("damage", ["intact", *DAMAGES])
def test_streamed_verify_compares_the_process_too(
    damage: str,
    controller: str,
    single: bool,
    posted: Callable[[str, str], Posted],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    """Checked in pieces of a few CL points, the process gives the same findings, lines and
    counts as checked whole: compared in the workers that verify the pieces, or here."""
    program = posted("dome", controller)
    path = program.path
    if damage != "intact":
        path = tmp_path / f"damaged{program.path.suffix}"
        path.write_text(DAMAGES[damage](program)[0])
    whole_code, whole_out = _verify(path, program.job, capsys)
    extra = ["--single-process"] if single else []
    code, out = _verify(path, program.job, capsys, "--piece-points", "40", *extra)
    assert code == whole_code == (0 if damage == "intact" else 1)

    def process_lines(text: str) -> list[str]:
        return [x for x in text.splitlines() if "verification" not in x]

    assert process_lines(out) == process_lines(whole_out)


@pytest.mark.parametrize("closed", [True, False])
def test_a_linuxcnc_program_opened_with_percent_must_close_with_it(
    closed: bool,
    posted: Callable[[str, str], Posted],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    """LinuxCNC writes no ``%``, but a file that starts with one must end with one (its
    interpreter: "percent sign missing from end of file")."""
    program = posted("dome", "linuxcnc")
    text = "%\n" + program.text + ("%\n" if closed else "")
    path = tmp_path / "percent.ngc"
    path.write_text(text)
    code, out = _verify(path, program.job, capsys)
    if closed:
        assert code == 0, out
        return
    assert code == 1, out
    line = len(text.splitlines())
    assert re.search(rf"^{re.escape(str(path))}:{line}: no program end \(M2\)", out, re.M), out


@pytest.mark.parametrize("controller", CONTROLLERS)
def test_a_spindle_running_through_a_tool_change_is_refused(
    controller: str,
    posted: Callable[[str, str], Posted],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    """Issue 23: the M5 before ``T2 M6`` deleted, the spindle runs through the tool change; the
    cuts are still at the CL's speed, but the post stops the spindle before every change."""
    program = posted("two tools", controller)
    change = re.compile(r"^(?:\d+ )?TOOL CALL 2\b|^(?:N\d+ )?T2\b", re.M).search(program.text)
    assert change is not None
    stops = list(re.finditer(r"^(?:\d+ |N\d+ )?M5\n", program.text[: change.start()], re.M))
    assert stops, "the post stops the spindle before the tool change"
    stop = stops[-1]
    text = program.text[: stop.start()] + program.text[stop.end() :]
    bad = tmp_path / f"damaged{program.path.suffix}"
    bad.write_text(text)
    code, out = _verify(bad, program.job, capsys)
    assert code == 1, out
    assert "verification within tolerance" in out
    assert "process DIFFERS from the CL data: tool change" in out
    line = _line_at(text, change.start() - (stop.end() - stop.start()))
    want = (
        rf"^{re.escape(str(bad))}:{line}: tool change to T2 with the spindle running "
        r"\(S9000 CW\); expected it stopped \(M5\) before the tool change"
    )
    assert re.search(want, out, re.M), out


@pytest.mark.parametrize("controller", CONTROLLERS)
def test_the_length_offset_register_is_compared_with_adjust(
    controller: str,
    posted: Callable[[str, str], Posted],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    """Issue 22: ``LOADTL/2,ADJUST,7`` asks for register 7. Fanuc and LinuxCNC programs
    with H2 there are refused at the H word's line; Heidenhain and Siemens have no register
    (the post refuses such an ADJUST): their program, with the tool's own length, is refused
    against that CL data at the TCP switch."""
    tool = read_cl_text("LOADTL/3,ADJUST,7\nGOTO/0,0,0\n", source="a.apt").events[0]
    if tool.data.get("adjust") != 7:
        pytest.skip("the APT reader does not give LOADTL ADJUST yet")
    cl = tmp_path / "adjust.apt"
    cl.write_text(TWO_TOOLS.replace("LOADTL/2", "LOADTL/2,ADJUST,7"))
    job = Job(cl, feed=1200, tool=2, tool_line=13)
    ext = DIALECTS[controller].extensions[0]
    if controller in ("fanuc", "linuxcnc"):
        good = tmp_path / f"adjust{ext}"
        argv = ["post", str(cl), "-m", "dmu50", "-c", controller, "-o", str(good), "-q"]
        assert main(argv) == 0
        code, out = _verify(good, job, capsys)
        assert code == 0, out
        word = re.compile(r"(?<![A-Z])H7\b")
        match = word.search(good.read_text())
        assert match is not None
        text = word.sub("H2", good.read_text())
        line, have = _line_at(text, match.start()), 2
    else:  # posted without the ADJUST: the tool's own length
        text = posted("two tools", controller).text
        # the TCP switch after T2, or the plane of its cut at a fixed tilt, whose length is
        # the tool's own too
        tcp = {"heidenhain": r"FUNCTION TCPM|PLANE SPATIAL", "siemens": r"TRAORI|CYCLE800\(0"}
        change = text.index("TOOL CALL 2" if controller == "heidenhain" else "T2 D1")
        switch = re.compile(tcp[controller]).search(text, change)
        assert switch is not None
        line, have = _line_at(text, switch.start()), 2
    bad = tmp_path / f"damaged{ext}"
    bad.write_text(text)
    code, out = _verify(bad, job, capsys)
    assert code == 1, out
    assert "verification within tolerance" in out
    assert "process DIFFERS from the CL data: register" in out
    want = (
        rf"^{re.escape(str(bad))}:{line}: length offset register {have} for T2 where the CL "
        r"has ADJUST,7 \(CL line 13\)"
    )
    assert re.search(want, out, re.M), out


def test_a_feed_the_cl_data_does_not_give_is_any_feed(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Cuts before the first FEDRAT were fed with --feed, the spindle started with --spindle
    and tool 1 assumed: verify accepts them, says so, and still checks the feeds the CL gives."""
    cl = tmp_path / "defaults.apt"
    cl.write_text(DEFAULTS)
    out_path = tmp_path / "defaults.nc"
    argv = ["post", str(cl), "-m", "dmu50", "-c", "fanuc", "-o", str(out_path), "-q"]
    assert main([*argv, "--feed", "1000", "--spindle", "8000"]) == 0
    text = out_path.read_text()
    job = Job(cl, feed=600, tool=1, tool_line=0)
    code, out = _verify(out_path, job, capsys)
    assert code == 0, out
    assert "2 cutting moves with no feed in the CL data (--feed when posted): any feed" in out
    assert "any clockwise speed accepted" in out
    assert "tool 1 accepted" in out
    # another feed where the CL has none is accepted; where it has one, it is not
    other = tmp_path / "other.nc"
    other.write_text(text.replace("F1000.", "F1500.", 1))
    assert _verify(other, job, capsys)[0] == 0
    wrong = tmp_path / "wrong.nc"
    wrong.write_text(text.replace("F600.", "F9999.", 1))
    code, out = _verify(wrong, job, capsys)
    assert code == 1
    assert "feed F9999 where the CL has F600 (CL line 9)" in out


def test_the_post_writes_no_program_verify_would_refuse(monkeypatch: pytest.MonkeyPatch) -> None:
    """The post's own read-back check includes the process: a writer that got the speed
    wrong is refused, nothing written."""
    written = whole.written

    def speed_times_ten(posted: Any, job: Any) -> tuple[str, Any, Any]:
        text, _, checks = written(posted, job)
        text = re.sub(r"(?<![A-Z])S(\d+)", lambda m: f"S{int(m[1]) * 10}", text)
        return text, job.dialect.read(text), checks

    monkeypatch.setattr(whole, "written", speed_times_ten)
    toolpath = read_cl_text(TWO_TOOLS, source="two.apt")
    with pytest.raises(
        ToleranceError,
        match=r"two.apt: the program's process differs from the CL data, nothing written: "
        r"<fanuc program>:\d+: spindle S90000 CW where the CL has S9000 CW \(CL line 10\)",
    ):
        whole.post(toolpath, load_machine("dmu50"), PostOptions(controller="fanuc"))


@pytest.mark.parametrize("parallel", [False, True], ids=["here", "worker"])
def test_a_streamed_post_checks_the_process_as_a_whole_post(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path, parallel: bool
) -> None:
    """A streamed post (pieces of 50 CL points) checked only the geometry of its pieces: a
    writer that got the speed wrong was written. It is refused as the whole post refuses it,
    with the same message, and nothing is written."""
    write_spindle = ProgramWriter.write_spindle

    def speed_times_ten(self: ProgramWriter, block: Spindle) -> None:
        write_spindle(self, replace(block, rpm=block.rpm * 10))

    monkeypatch.setattr(ProgramWriter, "write_spindle", speed_times_ten)
    toolpath = read_cl(DOME)
    machine = load_machine("dmu50")
    options = PostOptions(controller="fanuc")
    with pytest.raises(ToleranceError) as refused:
        whole.post(toolpath, machine, options)
    message = str(refused.value)
    assert re.match(
        rf"{re.escape(str(DOME))}: the program's process differs from the CL data, nothing "
        r"written: <fanuc program>:\d+: spindle S\d+0 CW where the CL has S\d+ CW",
        message,
    ), message
    out = tmp_path / "dome.nc"
    with pytest.raises(ToleranceError) as streamed:
        post_stream(
            toolpath_pieces(toolpath, 40), machine, out, options, piece_points=50,
            parallel=parallel,
        )  # fmt: skip
    assert str(streamed.value) == message
    assert not out.exists()
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("command", ["post", "verify"])
@pytest.mark.parametrize(
    "option",
    [
        ["--angle-tolerance", "nan"],
        ["--angle-tolerance", "-5"],
        ["--angle-tolerance=-inf"],
        ["--angle-tolerance=inf"],
        ["--angle-tolerance", "1e999"],
    ],
    ids=" ".join,
)
def test_angle_tolerance_is_refused_alike(
    command: str, option: list[str], capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    """One validation for both commands: a usage error (exit 2) naming the option and the
    value. (``verify`` takes 0, its default: the program follows the CL tool axis.)"""
    argv = {
        "post": ["post", str(DOME), "-m", "dmu50", "-o", str(tmp_path / "x.nc")],
        "verify": ["verify", str(tmp_path / "x.nc"), "-m", "dmu50", "--cl", str(DOME)],
    }[command]
    with pytest.raises(SystemExit) as exit_:
        main([*argv, *option])
    assert exit_.value.code == 2
    value = option[-1].removeprefix("--angle-tolerance=")
    err = capsys.readouterr().err
    assert f"argument --angle-tolerance: expected a non-negative number, got '{value}'" in err


@given(st.lists(st.integers(0, 6), max_size=40), st.booleans())
def test_distinct_counts_the_blocks_of_rows_in_order_and_not(
    values: list[int], order: bool
) -> None:
    """The count of blocks among a piece's rows: by its changes where in order, else sorted."""
    array = np.array(sorted(values) if order else values, dtype=np.int64)
    assert distinct(array) == np.unique(array).size


@pytest.mark.parametrize(
    ("job", "matched"), [("dome", True), ("arcs", False), ("cycles", False)], ids=str
)
def test_the_process_check_takes_the_rows_the_verification_matched(job: str, matched: bool) -> None:
    """The verification gives the row reaching each CL point as it matched them where its rows
    are the program's moves (``verify_matched``), and the process check of a piece takes them
    instead of matching again (``urdfpost verify`` in pieces, in its workers): the same
    findings, a fault included. With arcs (measured as moves along them) or canned cycles
    (expanded) the verification's rows are others, and it gives none."""
    machine = load_machine("dmu50")
    text = {"dome": DOME.read_text(), "arcs": arc_job(), "cycles": drilling_job()}[job]
    toolpath = read_cl_text(text, source=f"{job}.apt")
    result = whole.post(toolpath, machine, PostOptions(controller="fanuc"))
    program_text = result.text
    if job == "dome":  # the first feed of 2000 mm/min written as 9999
        program_text = _feed_word(2000).sub("F9999", program_text, count=1)
        assert program_text != result.text
    program = DIALECTS["fanuc"].read(program_text)
    expected, _, _ = checked_process(toolpath, feed=math.nan, spindle=math.nan, units="mm")
    tol = Tolerances.for_units("mm")
    length = result.program.tool_length
    check, match = verify_matched(program, machine, expected, tool_length=length, tol=tol)
    assert check == verify(program, machine, expected, tool_length=length, tol=tol)
    assert (match is not None) is matched
    start = ProcessChecker(machine, tol=tol, tool_length=length).begin(program, expected)
    found = start.compare(program, expected, machine, match)
    assert found == start.compare(program, expected, machine)
    assert [f.kind for f in found.faults] == (["feed"] if job == "dome" else [])
