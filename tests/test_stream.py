"""The streamed post (urdfpost.posting.stream): pieces joined into the program a whole post
writes."""

from __future__ import annotations

import json
import os
import re
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from jobs import write_hemisphere

from urdfpost import load_machine
from urdfpost.errors import ToleranceError, UnreachableError
from urdfpost.planning.branches import select
from urdfpost.posting.options import PostOptions
from urdfpost.posting.readback import merge_verifications
from urdfpost.posting.stream import post_stream
from urdfpost.posting.whole import post
from urdfpost.readers import read_cl
from urdfpost.toolpath import Event, Toolpath, toolpath_pieces, toolpath_slice
from urdfpost.verification import Verification

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def raster(tmp_path_factory: pytest.TempPathFactory) -> Toolpath:
    """The benchmark's hemisphere raster (passes over and beside the pole), 6000 points."""
    return read_cl(
        write_hemisphere(6000, tmp_path_factory.mktemp("raster") / "hemisphere_6000.apt")
    )


def with_events(toolpath: Toolpath) -> Toolpath:
    """The toolpath with events in the middle and at the end (a tool change and spindle, a
    home return, an insert, a stop), which the pieces must not cut through."""
    n = len(toolpath)
    extra = (
        Event(index=n // 3, kind="tool", line=1, data={"number": 2}),
        Event(index=n // 3, kind="spindle", line=2, data={"rpm": 9000.0, "direction": "cw"}),
        Event(index=n // 2, kind="home", line=3),
        Event(index=n // 2, kind="insert", line=4, data={"text": "M50"}),
        Event(index=n // 2 + 1, kind="stop", line=5, data={"optional": True}),
        Event(index=n, kind="comment", line=6, data={"text": "the end"}),
    )
    events = sorted(toolpath.events + extra, key=lambda e: e.index)
    return replace(toolpath, events=tuple(events))


def assert_same_text(got: str, want: str) -> None:
    """Equal texts, or the first line that differs (pytest's diff of long texts is slow)."""
    a, b = got.splitlines(), want.splitlines()
    for k, (x, y) in enumerate(zip(a, b, strict=False)):
        assert x == y, f"line {k + 1}: {x!r} != {y!r}"
    assert len(a) == len(b) and got == want


def streamed_text(tmp_path: Path, toolpath: Toolpath, options: PostOptions, **kw) -> tuple:
    out = tmp_path / "out.nc"
    result = post_stream(
        toolpath_pieces(toolpath, kw.pop("read", 997)), load_machine("dmu50"), out, options, **kw
    )
    return out.read_text(encoding="utf-8"), result


@pytest.mark.parametrize(
    ("controller", "tcp", "pieces", "lookahead"),
    [
        ("heidenhain", False, 1500, 400),
        ("fanuc", False, 2000, 300),
        ("siemens", False, 700, 700),
        ("linuxcnc", False, 2500, 50),
    ],
)
def test_streamed_program_is_the_whole_post(
    tmp_path: Path, raster: Toolpath, controller: str, tcp: bool, pieces: int, lookahead: int
) -> None:
    """Cut into pieces, with CL events on the way, the text is the one post() writes, and the
    merged verification has its figures."""
    job = with_events(raster)
    options = PostOptions(controller=controller, tcp=tcp)
    whole = post(job, load_machine("dmu50"), options)
    text, result = streamed_text(tmp_path, job, options, piece_points=pieces, lookahead=lookahead)
    assert result.report.as_json()["streamed"]["pieces"] > 2
    assert_same_text(text, whole.text)
    v, w = result.verification, whole.verification
    assert v.ok and (v.cl_points, v.reached, v.blocks) == (w.cl_points, w.reached, w.blocks)
    assert v.max_tip_deviation == w.max_tip_deviation
    assert v.max_orientation_deviation_deg == w.max_orientation_deviation_deg
    assert v.max_rotary_step_deg == w.max_rotary_step_deg
    # the mean counts the deviations at each join twice: close, not equal
    assert v.mean_tip_deviation == pytest.approx(w.mean_tip_deviation, rel=0.01)
    for key in ("branch_switches", "pole_points", "inserted_blocks"):
        assert result.report.as_json()[key] == whole.report.as_json()[key], key
    # the singular spans numbered along the whole job (their conditioning figures come from
    # arrays of another length: equal to rounding)
    spans, want = (
        result.report.as_json()["strategy"]["spans"],
        whole.report.as_json()["strategy"]["spans"],
    )
    assert spans and len(spans) == len(want)
    for got, expected in zip(spans, want, strict=True):
        assert got.keys() == expected.keys()
        exact = {k: v for k, v in expected.items() if not isinstance(v, float)}
        assert {k: got[k] for k in exact} == exact
        close = {k: v for k, v in expected.items() if isinstance(v, float)}
        assert {k: got[k] for k in close} == pytest.approx(close, rel=1e-12, abs=0.0)
    assert not list(tmp_path.glob(".out.nc.*")), "temporary file left behind"


def test_streamed_tcp_program_within_rounding_of_the_whole_post(
    tmp_path: Path, raster: Toolpath
) -> None:
    """In TCP output the blocks inserted on a piece's moves come from positions along the CL
    path counted from the piece's start: the same numbers within rounding, so the written
    values agree to one unit of the last decimal."""
    options = PostOptions(controller="heidenhain", tcp=True)
    whole = post(raster, load_machine("dmu50"), options)
    text, result = streamed_text(tmp_path, raster, options, piece_points=1000, lookahead=300)
    a, b = whole.text.splitlines(), text.splitlines()
    assert len(a) == len(b)
    differ = [(x, y) for x, y in zip(a, b, strict=True) if x != y]
    assert len(differ) < 0.1 * len(a)
    for x, y in differ:
        wx, wy = x.split(), y.split()
        assert [w[0] for w in wx] == [w[0] for w in wy]
        for p, q in zip(wx, wy, strict=True):
            if p != q and p[0] == "F":
                # the F of a block slowed to an axis limit follows its rounded positions:
                # within the verifier's feed tolerance
                assert abs(float(p[1:]) / float(q[1:]) - 1.0) <= 0.01, (x, y)
            elif p != q:
                assert abs(float(p[1:]) - float(q[1:])) <= 1.001e-3, (x, y)
    assert result.verification.ok


def test_streamed_figures_name_the_tolerances_of_the_whole_post(tmp_path: Path) -> None:
    """The dome job bends the tool axis in some pieces only: the streamed summary names the
    tolerances those pieces met (bent: 2.5 deg, the ball-centre tip tolerance), as the whole
    post's does, not the plain ones of the first piece."""
    dome = read_cl(str(Path(__file__).resolve().parents[1] / "examples" / "dome.apt"))
    options = PostOptions(controller="heidenhain", tcp=True)
    whole = post(dome, load_machine("dmu50"), options)
    _, result = streamed_text(tmp_path, dome, options, piece_points=50)
    assert result.verification.max_orientation_deviation_deg > 0.5  # (a bent piece)
    for v in (whole.verification, result.verification):
        assert v.orientation_tolerance_deg == pytest.approx(2.5)
    assert result.verification.tip_tolerance == pytest.approx(whole.verification.tip_tolerance)


def test_worker_and_serial_checks_agree(tmp_path: Path, raster: Toolpath) -> None:
    """Pieces verified in the worker process or here, one after the other: the same program
    and the same figures."""
    options = PostOptions(controller="siemens", tcp=True)
    job = with_events(raster)
    got = {
        parallel: streamed_text(
            tmp_path, job, options, piece_points=900, lookahead=200, parallel=parallel
        )
        for parallel in (False, True)
    }
    assert_same_text(got[True][0], got[False][0])
    assert got[True][1].verification == got[False][1].verification
    reports = {k: v[1].report.as_json() for k, v in got.items()}
    assert reports[True].pop("streamed")["worker"] is True
    assert reports[False].pop("streamed")["worker"] is False
    assert reports[True] == reports[False]
    assert got[True][1].report.as_json()["streamed"]["pieces"] > 4


def test_a_spawned_worker_writes_the_program_as_here(
    tmp_path: Path, raster: Toolpath, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Where workers are spawned, not forked (not Linux), the worker is sent how to write the
    program (the control, whose tables are read-only mappings, pickled): the same program and
    figures as posting here."""
    import urdfpost.posting.worker as worker

    options = PostOptions(controller="fanuc", tcp=False)
    (tmp_path / "here").mkdir()
    (tmp_path / "spawned").mkdir()
    here = streamed_text(tmp_path / "here", raster, options, piece_points=900, parallel=False)
    monkeypatch.setattr(worker, "FORK", False)
    spawned = streamed_text(tmp_path / "spawned", raster, options, piece_points=900,
                            parallel=True)  # fmt: skip
    assert spawned[1].report.streamed.worker
    assert_same_text(spawned[0], here[0])
    assert spawned[1].verification == here[1].verification


def test_joins_that_rest_on_the_lookahead_are_reported(tmp_path: Path) -> None:
    """Both branches within travel all along (tilt 20 deg on a B -35..120 machine): the first
    join's branch choice is not settled by its window (the whole job could take the other
    branch from the start). Later joins start from that choice: leaving it would take a
    rewind, so their choices are settled given it. The program is still verified; the report
    lists the join and warns once."""
    m = load_machine("umc750")
    n = 3000
    az = np.radians(np.linspace(0.0, 120.0, n))
    t = np.radians(20.0)
    axis = np.stack([np.sin(t) * np.cos(az), np.sin(t) * np.sin(az), np.full(n, np.cos(t))], 1)
    tip = np.stack([np.linspace(-20, 20, n), 5 * np.sin(az), np.zeros(n)], axis=1)
    job = Toolpath.from_points(tip, axis, feed=1000.0, source="twofold", spindle=10000.0)
    out = tmp_path / "out.nc"
    options = PostOptions(controller="heidenhain", tcp=False)
    result = post_stream(toolpath_pieces(job, 700), m, out, options, piece_points=800,
                         lookahead=100)  # fmt: skip
    streamed = result.report.as_json()["streamed"]
    assert streamed["pieces"] >= 3 and result.verification.ok
    assert streamed["unsettled_joins"] == [int(job.line[800])]  # the first join, at the target
    (warning,) = [w for w in result.report.as_json()["warnings"] if "lookahead" in w]
    assert warning.startswith("twofold: at ") and "--piece-points 0" in warning


def test_reader_piece_sizes_do_not_matter(tmp_path: Path, raster: Toolpath) -> None:
    options = PostOptions(controller="heidenhain", tcp=False)
    small = toolpath_slice(raster, 0, 1200)
    texts = {
        read: streamed_text(tmp_path, small, options, read=read, piece_points=400, lookahead=90)[0]
        for read in (1, 7, 1200)
    }
    assert_same_text(texts[1], texts[1200])
    assert_same_text(texts[7], texts[1200])


@pytest.mark.parametrize("parallel", [False, True])
def test_piece_that_misses_its_tolerance_writes_nothing(
    tmp_path: Path, raster: Toolpath, monkeypatch: pytest.MonkeyPatch, parallel: bool
) -> None:
    """A piece that fails its check after others were written (its CL points moved 0.1 mm
    before they are checked, in this process or in the worker): the old file stays, and no
    temporary file is left."""
    from urdfpost.posting.worker import Checks

    real = Checks.submit
    jobs = []

    def second_moved(self, job):
        jobs.append(1)
        if len(jobs) == 2:
            cl = job.target.cl
            moved = replace(cl, tip=cl.tip + np.array([0.0, 0.1, 0.0]))
            job = replace(job, target=replace(job.target, cl=moved))
        real(self, job)

    monkeypatch.setattr(Checks, "submit", second_moved)
    out = tmp_path / "out.nc"
    out.write_text("old program\n")
    options = PostOptions(controller="heidenhain", tcp=False)
    with pytest.raises(ToleranceError, match="misses its tolerance against the CL data") as err:
        post_stream(toolpath_pieces(raster, 500), load_machine("dmu50"), out, options,
                    piece_points=1000, lookahead=100, parallel=parallel)  # fmt: skip
    assert len(jobs) >= 2
    second = raster.line[1000]  # about where the second piece starts
    lines = [int(x) for x in re.findall(r"lines (\d+) to (\d+)", str(err.value))[0]]
    assert lines[0] <= second <= lines[1]
    assert out.read_text() == "old program\n"
    assert [p.name for p in tmp_path.iterdir()] == ["out.nc"]


@pytest.mark.parametrize("parallel", [False, True])
def test_a_piece_that_fails_to_post_fails_the_post_first(
    tmp_path: Path, raster: Toolpath, monkeypatch: pytest.MonkeyPatch, parallel: bool
) -> None:
    """The second piece fails to post, with the pieces verified in a worker or here: the post
    raises its error before the third is planned, and writes nothing."""
    import urdfpost.posting.stream as stream
    from urdfpost.errors import CollisionError

    real_post, posts = stream.post_piece, []
    real_plan, plans = stream.STRATEGIES["cone"], []

    def post_piece(*args, **kw):
        posts.append(1)
        if len(posts) == 2:
            raise CollisionError("the second piece collides")
        return real_post(*args, **kw)

    def plan(problem):
        plans.append(1)
        return real_plan(problem)

    monkeypatch.setattr(stream, "post_piece", post_piece)
    monkeypatch.setitem(stream.STRATEGIES, "cone", plan)
    out = tmp_path / "out.nc"
    options = PostOptions(controller="heidenhain", tcp=False, strategy="cone")
    with pytest.raises(CollisionError, match="the second piece collides"):
        post_stream(toolpath_pieces(raster, 500), load_machine("dmu50"), out, options,
                    piece_points=1000, lookahead=100, parallel=parallel)  # fmt: skip
    assert len(plans) == 2 and len(posts) == 2
    assert not list(tmp_path.iterdir())


def bad_late(tmp_path: Path, name: str = "bad.apt", points: int = 4000) -> tuple[Path, int]:
    """A hemisphere job whose GOTO at file index 3300 or after (line ``bad``, in the
    fourth piece of 800 points or later) the reader rejects; returns the file and the line."""
    path = write_hemisphere(points, tmp_path / name)
    lines = path.read_text().splitlines(keepends=True)
    bad = next(k for k in range(3300, len(lines)) if lines[k].startswith("GOTO/"))
    lines[bad] = "GOTO/1.0,2.0,x3.0\n"
    path.write_text("".join(lines))
    return path, bad + 1


@pytest.mark.parametrize("parallel", [False, True], ids=["here", "worker"])
def test_a_bad_cl_line_late_in_the_file_stops_the_post(tmp_path: Path, parallel: bool) -> None:
    """A CL line the reader rejects in the fourth piece, with the pieces verified in a worker
    or here: the post raises the reader's error with its file and line, once the pieces before
    it are posted, writes nothing and leaves no process."""
    import multiprocessing

    import urdfpost.posting.stream as stream
    from urdfpost.errors import CLDataError
    from urdfpost.readers import read_cl_chunks

    path, bad = bad_late(tmp_path)
    posted = []
    real = stream.post_piece

    def post_piece(*args, **kw):
        posted.append(1)
        return real(*args, **kw)

    out = tmp_path / "out.nc"
    pieces = read_cl_chunks(path, max_points=800, units="mm")
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(stream, "post_piece", post_piece)
        with pytest.raises(CLDataError) as err:
            post_stream(pieces, load_machine("dmu50"), out, PostOptions(controller="heidenhain"),
                        piece_points=900, lookahead=100, parallel=parallel)  # fmt: skip
    assert (Path(err.value.path).name, err.value.line) == ("bad.apt", bad)
    assert len(posted) >= 2  # (the pieces before it were posted)
    assert [p.name for p in tmp_path.iterdir()] == ["bad.apt"]
    assert multiprocessing.active_children() == []


@pytest.mark.parametrize("parallel", [False, True], ids=["here", "workers"])
def test_a_bad_cl_line_late_in_the_file_stops_the_verify(tmp_path: Path, parallel: bool) -> None:
    """``verify`` in pieces of CL data with a line the reader rejects in the fourth piece, the
    pieces verified in workers or here: the reader's error with its file and line, raised once
    the pieces before it are taken (in order), and no process left."""
    import multiprocessing

    from urdfpost.errors import CLDataError
    from urdfpost.posting.readback import CUT_MARGIN, verify_stream
    from urdfpost.readers import read_cl_chunks
    from urdfpost.tolerances import Tolerances

    machine = load_machine("dmu50")
    good = write_hemisphere(4000, tmp_path / "good.apt")
    program = tmp_path / "good.h"
    options = PostOptions(controller="heidenhain", tcp=False)
    post_stream(read_cl_chunks(good, max_points=900, units="mm"), machine, program, options,
                piece_points=900, lookahead=100, parallel=False)  # fmt: skip
    path, bad = bad_late(tmp_path)
    taken: list[int] = []  # the first CL line of each piece taken, in order

    def counted(pieces: Iterator[Toolpath]) -> Iterator[Toolpath]:
        for piece in pieces:
            taken.append(int(piece.line[0]))
            yield piece

    chunks = read_cl_chunks(path, max_points=800 + CUT_MARGIN, units="mm")
    with pytest.raises(CLDataError) as err:
        verify_stream(program, counted(chunks), machine, "heidenhain",
                      tol=Tolerances.for_units("mm"), tool_length=machine.settings.tool_length,
                      piece_points=800, parallel=parallel)  # fmt: skip
    assert (Path(err.value.path).name, err.value.line) == ("bad.apt", bad)
    assert len(taken) >= 3 and taken == sorted(taken)  # the pieces before it, in order
    assert multiprocessing.active_children() == []


@pytest.mark.parametrize("command", ["post", "verify"])
def test_a_bad_cl_line_of_a_command_in_pieces_writes_nothing(
    tmp_path: Path, command: str, capsys: pytest.CaptureFixture[str]
) -> None:
    """``urdfpost post`` and ``verify`` in pieces: a bad line late in the file is one message
    with its file and line, exit 1, nothing written."""
    from urdfpost.cli import main

    good = write_hemisphere(4000, tmp_path / "good.apt")
    program = tmp_path / "good.h"
    common = ["-m", "dmu50", "--piece-points", "800", "--report", str(tmp_path / "r.json")]
    if command == "verify":
        argv = ["post", str(good), "-m", "dmu50", "-q", "-c", "heidenhain", "-o", str(program)]
        assert main(argv) == 0
    capsys.readouterr()
    path, bad = bad_late(tmp_path)
    before = sorted(p.name for p in tmp_path.iterdir())
    if command == "post":
        argv = ["post", str(path), "-q", "-c", "heidenhain", "-o", str(tmp_path / "x.h")]
    else:
        argv = ["verify", str(program), "--cl", str(path)]
    assert main(argv + common) == 1
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith(f"urdfpost: {path}:{bad}: "), err
    assert sorted(p.name for p in tmp_path.iterdir()) == before


@pytest.mark.parametrize("depth", [1, 2])
def test_worker_errors_come_back_with_their_file_and_line(tmp_path: Path, depth: int) -> None:
    """An error in the verification worker (here a program line the reader rejects) is raised
    where the post runs, as the same error with its file and line; with two pieces handed over
    at once, the first piece's error, not the second's (the line after it)."""
    from urdfpost.errors import ProgramParseError
    from urdfpost.posting.check import CheckTarget
    from urdfpost.posting.worker import Checks, PieceJob
    from urdfpost.tolerances import Tolerances

    checks = Checks(
        load_machine("dmu50"), "heidenhain", "prog.h", Tolerances.for_units("mm"), "mm", True,
        depth=depth,
    )  # fmt: skip
    try:
        piece = toolpath_slice(read_cl(ROOT / "examples/dome.apt"), 0, 2)
        target = CheckTarget(piece, None, 0, 0.0, 2.0, 0.0)
        checks.submit(PieceJob(text="0 BEGIN PGM X MM\nL X1 Y\n", inserts=[], target=target))
        with pytest.raises(ProgramParseError) as err:  # (taken before the next is handed over)
            checks.submit(PieceJob(text="L X2 Z\n", inserts=[], target=target))
            checks.finish()
        assert (err.value.path, err.value.line) == ("prog.h", 2)
    finally:
        checks.close()
    assert checks.process is None


def test_a_worker_that_dies_is_an_error(tmp_path: Path) -> None:
    """A verification worker killed while it checks a piece (out of memory, say): the post
    fails with a clear error instead of waiting."""
    import os
    import signal

    from urdfpost.errors import UrdfpostError
    from urdfpost.posting.check import CheckTarget
    from urdfpost.posting.worker import Checks, PieceJob
    from urdfpost.tolerances import Tolerances

    checks = Checks(
        load_machine("dmu50"), "heidenhain", "prog.h", Tolerances.for_units("mm"), "mm", True
    )
    try:
        assert checks.process is not None and checks.process.pid is not None
        os.kill(checks.process.pid, signal.SIGKILL)
        checks.process.join()
        piece = toolpath_slice(read_cl(ROOT / "examples/dome.apt"), 0, 2)
        job = PieceJob(text="", inserts=[], target=CheckTarget(piece, None, 0, 0.0, 2.0, 0.0))
        with pytest.raises(UrdfpostError, match=r"verification worker .* exit code -9"):
            checks.submit(job)
            checks.finish()
    finally:
        checks.close()


def assert_same_figures(got: Verification, whole: Verification, *, worst: bool) -> None:
    """The figures of a check in pieces and of the whole check agree.

    The counts, lines and steps exactly. The largest deviations to rounding: each piece
    refines its blocks' samples down to the largest deviation at its own rows, which may be
    smaller than the whole's, so the samples (and their last bits) may differ. The mean to 1%:
    the join rows count twice. The worst CL line where one block stands out (``worst``).
    """
    assert got.max_tip_deviation == pytest.approx(whole.max_tip_deviation, rel=1e-9)
    assert got.max_orientation_deviation_deg == pytest.approx(
        whole.max_orientation_deviation_deg, rel=1e-9
    )
    assert got.mean_tip_deviation == pytest.approx(whole.mean_tip_deviation, rel=0.01)
    if worst:
        assert got.worst_cl_line == whole.worst_cl_line
    loose = {
        "max_tip_deviation": 0.0,
        "max_orientation_deviation_deg": 0.0,
        "mean_tip_deviation": 0.0,
        "compared": 0,
        "worst_cl_line": None,
    }
    assert replace(got, **loose) == replace(whole, **loose)


def _damaged(text: str) -> str:
    """The program with three blocks moved 0.5 mm in X and thirty lines taken out."""
    lines = text.splitlines(keepends=True)
    moved = 0
    for k in range(len(lines) // 7, len(lines), len(lines) // 4):
        line = lines[k]
        word = re.search(r"X([-+]?\d+\.\d+)", line)
        if word:
            value = float(word.group(1)) + 0.5
            lines[k] = line[: word.start(1)] + f"{value:+.3f}".lstrip("+") + line[word.end(1) :]
            moved += 1
    assert moved >= 3
    del lines[len(lines) // 2 : len(lines) // 2 + 30]
    return "".join(lines)


@pytest.mark.parametrize(
    ("controller", "tcp", "damage", "text_piece"),
    [
        ("heidenhain", False, False, 1 << 20),
        ("fanuc", False, True, 20_000),
        ("siemens", True, True, 7_000),
        ("linuxcnc", True, False, 50_000),
    ],
)
def test_verify_in_pieces_is_the_whole_verify(
    tmp_path: Path, raster: Toolpath, controller: str, tcp: bool, damage: bool, text_piece: int
) -> None:
    """Read and checked in pieces (the text and the CL data cut anywhere), a program gets the
    figures of the whole check: reached and missed points, blocks, the worst deviations and
    where, the rotary steps, the notes; only the mean counts the join rows twice."""
    from urdfpost.dialects import dialect_for
    from urdfpost.posting.readback import program_texts, verify_stream
    from urdfpost.tolerances import Tolerances
    from urdfpost.verification import verify

    m = load_machine("dmu50")
    events = with_events(raster).events  # (an insert is read back only knowing its text)
    job = replace(raster, events=tuple(e for e in events if e.kind != "insert"))
    result = post(job, m, PostOptions(controller=controller, tcp=tcp, strategy="recursive"))
    text = _damaged(result.text) if damage else result.text
    path = tmp_path / "prog.nc"
    path.write_text(text, encoding="utf-8")
    tol = Tolerances.for_units("mm")
    length = result.program.tool_length
    program = dialect_for(controller).read(text, path=str(path))
    whole = verify(program, m, job, tool_length=length, tol=tol)
    got, header = verify_stream(
        path, toolpath_pieces(job, 613), m, controller, tol=tol, tool_length=length,
        piece_points=900, texts=program_texts(path, text_piece),
    )  # fmt: skip
    assert got.compared > whole.compared  # pieces were joined (each join row counted twice)
    assert got.ok is whole.ok is (not damage)
    if damage:
        assert whole.missed_lines and whole.max_tip_deviation > 0.4
    assert_same_figures(got, whole, worst=damage)
    assert (header.tcp, header.units, header.name) == (program.tcp, program.units, program.name)


def _spiral(n: int = 3000) -> Toolpath:
    """A spiral of 4.2 turns at 30 degrees of tilt: more than a C axis limited to two turns
    (gantry-ca) follows without rewinds."""
    az = np.radians(np.linspace(0.0, 360.0 * 4.2, n))
    t = np.radians(30.0)
    axis = np.stack([np.sin(t) * np.cos(az), np.sin(t) * np.sin(az), np.full(n, np.cos(t))], 1)
    tip = np.stack([40 * np.cos(az), 40 * np.sin(az), np.linspace(0, -6, n)], axis=1)
    return Toolpath.from_points(tip, axis, feed=800.0, source="spiral", spindle=10000.0)


def test_verify_in_pieces_with_rewinds(tmp_path: Path) -> None:
    """A program with rewinds (a C axis limited to two turns, a spiral of four): the pieces
    are never cut inside one, and the figures are those of the whole check."""
    from urdfpost.dialects import dialect_for
    from urdfpost.posting.readback import verify_stream
    from urdfpost.tolerances import Tolerances
    from urdfpost.verification import verify

    m = load_machine("gantry-ca")
    job = _spiral()
    result = post(job, m, PostOptions(controller="fanuc", tcp=False, strategy="recursive"))
    assert result.report.as_json()["rewinds"]
    path = tmp_path / "spiral.nc"
    path.write_text(result.text, encoding="utf-8")
    tol = Tolerances.for_units("mm")
    length = result.program.tool_length
    program = dialect_for("fanuc").read(result.text)
    whole = verify(program, m, job, tool_length=length, tol=tol)
    got, _ = verify_stream(path, toolpath_pieces(job, 500), m, "fanuc", tol=tol,
                           tool_length=length, piece_points=300)  # fmt: skip
    assert got.compared > whole.compared and got.ok and whole.ok
    assert any("rewind moves" in x for x in whole.notes)
    assert_same_figures(got, whole, worst=False)


@pytest.mark.parametrize("controller", ["fanuc", "heidenhain"])
def test_verify_in_pieces_in_a_worker_is_the_same_verify(
    tmp_path: Path, controller: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``urdfpost verify`` in pieces hands each piece read to a worker process to verify while
    the next is read: the figures are exactly those of verifying the pieces here, whole
    program and damaged (a missed stretch), and an error in the worker comes back."""
    from urdfpost.dialects import dialect_for
    from urdfpost.posting.readback import verify_stream
    from urdfpost.tolerances import Tolerances

    m = load_machine("gantry-ca")
    job = _spiral()
    result = post(job, m, PostOptions(controller=controller, tcp=False, strategy="recursive"))
    tol = Tolerances.for_units("mm")
    length = result.program.tool_length
    for text in (result.text, _damaged(result.text)):
        path = tmp_path / f"spiral{dialect_for(controller).extensions[0]}"
        path.write_text(text, encoding="utf-8")
        got = {
            parallel: verify_stream(
                path, toolpath_pieces(job, 500), m, controller, tol=tol, tool_length=length,
                piece_points=300, parallel=parallel,
            )[0]
            for parallel in (False, True)
        }  # fmt: skip
        assert got[True] == got[False]
        assert got[True].ok is (text == result.text)
    # an error in the worker (forked: it has the patch) comes back as the error
    from urdfpost.errors import UrdfpostError
    from urdfpost.posting import worker

    def broken(*args: object, **kwargs: object) -> Verification:
        raise UrdfpostError("verification broke")

    monkeypatch.setattr(worker, "verify_matched", broken)
    with pytest.raises(UrdfpostError, match="verification broke"):
        verify_stream(path, toolpath_pieces(job, 500), m, controller, tol=tol,
                      tool_length=length, piece_points=300, parallel=True)  # fmt: skip


def _process_damaged(text: str, controller: str) -> list[str]:
    """``text`` with a rapid move two thirds in (a feed fault) and, separately, with the
    spindle stopped half way (a spindle fault at every cutting move after it)."""
    lines = text.splitlines(keepends=True)
    rapid = list(lines)
    at = len(lines) * 2 // 3
    if controller == "heidenhain":
        rapid[at] = re.sub(r" F[\d.]+", " FMAX", rapid[at])  # (FMAX holds for its block)
    else:
        rapid[at], rapid[at + 1] = "G0 " + rapid[at], "G1 " + rapid[at + 1]
    stopped = list(lines)
    stopped.insert(len(lines) // 2, "1500 M5\n" if controller == "heidenhain" else "M5\n")
    return ["".join(rapid), "".join(stopped)]


@pytest.mark.parametrize("controller", ["fanuc", "heidenhain"])
def test_verify_in_pieces_compares_the_process_in_the_workers_as_here(
    tmp_path: Path, controller: str
) -> None:
    """The process check of a program verified in pieces compares each piece's feeds and
    spindle where the piece is verified (in a worker, with the rows the verification matched),
    the findings taken in the pieces' order: it is the check of comparing the pieces here,
    and that of the whole program, with a fault in a later piece (the move it is at, the
    message, the count) and without."""
    import math

    from urdfpost.dialects import dialect_for
    from urdfpost.posting.process import checked_process
    from urdfpost.posting.readback import verify_stream
    from urdfpost.tolerances import Tolerances
    from urdfpost.verification.process import (
        ProcessChecker,
        check_process,
        end_words,
        read_with_end,
        rounding_of,
    )

    m = load_machine("gantry-ca")
    job = _spiral()
    result = post(job, m, PostOptions(controller=controller, tcp=False, strategy="recursive"))
    expected, _, _ = checked_process(job, feed=math.nan, spindle=math.nan, units="mm")
    dialect = dialect_for(controller)
    tol = Tolerances.for_units("mm")
    length = result.program.tool_length
    path = tmp_path / f"spiral{dialect.extensions[0]}"
    kinds = []
    for text in (result.text, *_process_damaged(result.text, controller)):
        path.write_text(text, encoding="utf-8")
        got = {}
        for parallel in (False, True):
            process = ProcessChecker(
                m, tol=tol, tool_length=length, rounding=rounding_of(dialect, "mm"),
                end=end_words(dialect),
            )  # fmt: skip
            check, _ = verify_stream(
                path, toolpath_pieces(expected, 500), m, controller, tol=tol, tool_length=length,
                piece_points=300, process=process, parallel=parallel,
            )  # fmt: skip
            got[parallel] = (check, process.result())
        assert got[True] == got[False]
        program, ended = read_with_end(dialect, text, path=str(path))
        whole = check_process(
            program, m, expected, tol=tol, tool_length=length,
            rounding=rounding_of(dialect, "mm"), ended=ended, end=end_words(dialect),
        )  # fmt: skip
        assert got[True][1] == whole
        kinds.append([(f.kind, f.index > 1000) for f in whole.faults])
    assert kinds == [[], [("feed", True)], [("spindle", True)]]


def test_cli_verifies_in_pieces(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``urdfpost verify --piece-points N`` prints what the whole check prints."""
    from urdfpost.cli import main

    dome = str(ROOT / "examples" / "dome.apt")
    prog = tmp_path / "dome.h"
    assert main(["post", dome, "-m", "dmu50", "-q", "-o", str(prog)]) == 0
    capsys.readouterr()
    common = ["verify", str(prog), "--cl", dome, "-m", "dmu50", "--angle-tolerance", "2"]
    assert main([*common, "--piece-points", "0"]) == 0
    whole = capsys.readouterr().out
    assert main([*common, "--piece-points", "60"]) == 0
    pieces = capsys.readouterr().out
    assert "301/301 CL points reached" in whole
    # the same line but for the mean deviation
    strip = re.compile(r"mean \d+\.\d+")
    assert strip.sub("mean", pieces) == strip.sub("mean", whole)
    # (a piece of one point is a usage error: test_cli_rejects_a_bad_piece_size_as_a_usage_error)


def test_pieces_reassemble_the_toolpath(raster: Toolpath) -> None:
    job = with_events(raster)
    pieces = list(toolpath_pieces(job, 777))
    assert sum(len(p) for p in pieces) == len(job)
    np.testing.assert_array_equal(np.concatenate([p.tip for p in pieces]), job.tip)
    at = np.cumsum([0] + [len(p) for p in pieces])
    events = [replace(e, index=e.index + int(a)) for p, a in zip(pieces, at, strict=False)
              for e in p.events]  # fmt: skip
    assert tuple(events) == job.events


def test_fixed_start_takes_the_start_angles() -> None:
    """A continued path starts on the branch it ended on, even against the preference, and a
    start no candidate has is an error naming the line."""
    machine = load_machine("dmu50")
    tip = np.array([[10.0, 0.0, 100.0], [11.0, 0.0, 100.0]])
    axis = np.array([[0.3, 0.0, 1.0], [0.31, 0.0, 1.0]])
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    free = select(machine, tip, axis, lines=np.array([5, 6]))
    c = [machine.axis_names.index(a.name) for a in machine.rotary]
    turned = free.q[0].copy()
    assert machine.rotary[0].continuous
    turned[c[0]] += 4 * np.pi  # two turns more on the continuous table
    fixed = select(machine, tip, axis, start=turned, fixed_start=True, lines=np.array([5, 6]))
    np.testing.assert_allclose(fixed.q[0, c], turned[c], atol=0.0)
    assert abs(fixed.q[1, c[0]] - turned[c[0]]) < 0.1  # and goes on from there
    wrong = free.q[0].copy()
    wrong[c[1]] += 0.3  # a tilt the point does not have
    with pytest.raises(UnreachableError, match=":5: the path cannot go on"):
        select(machine, tip, axis, start=wrong, fixed_start=True, lines=np.array([5, 6]))


def test_merge_counts_the_joins_once() -> None:
    def part(points: int, blocks: int, missed: list[int], worst: float, line: int) -> Verification:
        return Verification(
            ok=not missed,
            cl_points=points,
            reached=points - len(missed),
            missed_lines=missed,
            blocks=blocks,
            max_tip_deviation=worst,
            mean_tip_deviation=worst / 2,
            max_orientation_deviation_deg=worst,
            max_rotary_step_deg={"B": worst, "C": 1.0},
            tip_tolerance=0.01,
            orientation_tolerance_deg=0.1,
            worst_cl_line=line,
            tcp=False,
            notes=["a"],
            compared=10 * blocks,
        )

    merged = merge_verifications([part(10, 12, [], 0.002, 3), part(5, 6, [40], 0.004, 44)])
    assert (merged.cl_points, merged.reached, merged.blocks) == (14, 13, 17)
    assert merged.missed_lines == [40] and not merged.ok
    assert merged.max_tip_deviation == 0.004 and merged.worst_cl_line == 44
    assert merged.mean_tip_deviation == pytest.approx((0.001 * 120 + 0.002 * 60) / 180)
    assert merged.max_rotary_step_deg == {"B": 0.004, "C": 1.0}
    # the notes once each, the counting ones counted over the whole
    assert merged.notes == ["a", "1 CL points not reached, first at line 40"]
    # a point missed at the join is one point
    twice = merge_verifications([part(10, 12, [9], 0.0, 1), part(5, 6, [9], 0.0, 1)])
    assert twice.missed_lines == [9] and twice.reached == 13
    rewinds = [
        replace(part(10, 12, [], 0.0, 1), notes=[f"{k} rewind moves are not compared with "
                                                 "the CL path", "a"], rewind_moves=k)
        for k in (3, 4)
    ]  # fmt: skip
    assert merge_verifications(rewinds).notes == [
        "7 rewind moves are not compared with the CL path",
        "a",
    ]


@pytest.mark.parametrize("single", [False, True])
def test_cli_posts_in_pieces(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], single: bool
) -> None:
    """``urdfpost post --piece-points N`` reads, writes and verifies in pieces (in a worker
    process, or not with ``--single-process``): the example job in three pieces is the program
    of the whole post, and the report says so."""
    from urdfpost.cli import main

    dome = ROOT / "examples" / "dome.apt"
    whole, pieces = tmp_path / "whole.h", tmp_path / "pieces.h"
    common = ["post", str(dome), "--machine", "dmu50", "--no-tcp", "-q"]
    assert main([*common, "-o", str(whole)]) == 0
    report = tmp_path / "r.json"
    extra = ["--single-process"] if single else []
    args = [*common, "-o", str(pieces), "--piece-points", "100", "--report", str(report), *extra]
    assert main(args) == 0
    assert_same_text(pieces.read_text(), whole.read_text())
    figures = json.loads(report.read_text())
    worker = not single and (os.cpu_count() or 1) > 1
    assert figures["streamed"] == {
        "pieces": 3,
        "piece_points": 100,
        "lookahead": 20,
        "worker": worker,
        "unsettled_joins": [],  # one branch within travel at the joins
    }
    assert figures["cl_points"] == figures["cl_points_reached"] == 301 and figures["verified"]
    assert "301/301 CL points reached" in capsys.readouterr().out


@pytest.mark.parametrize("command", ["post", "verify"])
@pytest.mark.parametrize(("value", "said"), [("1", "got 1"), ("-3", "got -3"), ("x", "'x'")])
def test_cli_rejects_a_bad_piece_size_as_a_usage_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], command: str, value: str, said: str
) -> None:
    """A piece of one point, a negative or non-numeric count: usage errors (exit 2), for both
    commands, before anything is read."""
    from urdfpost.cli import main

    out = tmp_path / "x.h"
    dome = str(ROOT / "examples" / "dome.apt")
    args = [command, dome if command == "post" else str(out), "--machine", "dmu50"]
    args += ["-o", str(out)] if command == "post" else ["--cl", dome]
    with pytest.raises(SystemExit) as exc:
        main([*args, "--piece-points", value])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "--piece-points" in err and said in err, err
    assert not out.exists()


def test_cli_checks_collisions_in_pieces(tmp_path: Path) -> None:
    """With a stock mesh, every move of a streamed post is checked for collisions (the world
    built once, before the worker is forked), as in the whole post."""
    from urdfpost.cli import main

    dome, stock = str(ROOT / "examples" / "dome.apt"), str(ROOT / "examples" / "dome.stl")
    reports = {}
    for pieces in ("0", "100"):
        report = tmp_path / f"r{pieces}.json"
        args = ["post", dome, "-m", "dmu50", "--stock", stock, "-q", "--piece-points", pieces]
        assert main([*args, "-o", str(tmp_path / f"p{pieces}.h"), "--report", str(report)]) == 0
        reports[pieces] = json.loads(report.read_text())["collisions"]
    whole, streamed = reports["0"], reports["100"]
    assert whole["checked"] and streamed["checked"]
    assert streamed["moves"] == whole["moves"] > 300
    assert streamed["min_clearance"] == pytest.approx(whole["min_clearance"], abs=1e-6)
