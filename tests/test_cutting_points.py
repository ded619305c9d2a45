"""Each tool bends about its own cutting point: the ball centre of a ball-end tool, the tip of
any other.

The post used the first cutter's ball radius for the whole job. In a job with a ball-end
finisher first and a flat end mill after it, the cone strategy pivoted the flat end mill about
a point 3 mm up its axis near the pole, which moved its tip 0.084 mm off the CL path, and the
post's own check (at that same point, with its looser tolerance) passed it. Now a tool change
to another cutting point begins a tool section (:func:`urdfpost.posting.tools.tool_sections`),
posted and checked at its own point, whole and streamed, and ``urdfpost verify
--angle-tolerance`` measures each section at its tool's point.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import pytest
import trimesh

from urdfpost.cli import main
from urdfpost.errors import CLDataError
from urdfpost.posting.tools import cutting_points, tool_sections
from urdfpost.readers import read_cl

DOME = Path(__file__).resolve().parents[1] / "examples" / "dome.apt"
BALL, FLAT = "CUTTER/6.0,3.0", "CUTTER/10.0,0.0"


def _job(tmp_path: Path, name: str, cutters: list[tuple[int, str]]) -> Path:
    """The dome's path once per ``(tool, CUTTER record)``, each after its tool change."""
    skip = ("PARTNO", "UNITS", "MULTAX", "LOADTL", "CUTTER", "FINI", "$$")
    body = [line for line in DOME.read_text().splitlines() if not line.startswith(skip)]
    lines = ["PARTNO TOOLS", "UNITS/MM", "MULTAX/ON"]
    for number, cutter in cutters:
        lines += [f"LOADTL/{number}", cutter, *body]
    path = tmp_path / f"{name}.apt"
    path.write_text("\n".join([*lines, "FINI"]) + "\n")
    return path


def _tip_deviation(capsys: pytest.CaptureFixture[str]) -> float:
    out = capsys.readouterr().out
    found = re.search(r"tool tip deviation max ([0-9.]+)", out)
    assert found, out
    return float(found[1])


def test_each_tool_has_its_cutting_point_and_a_change_of_it_begins_a_section(
    tmp_path: Path,
) -> None:
    """The ball radius of a ball-end cutter, 0 of a flat one, per tool; a section begins at
    the tool change to another point (and only with ``by_pivot``)."""
    path = _job(tmp_path, "two", [(2, BALL), (1, FLAT)])
    toolpath = read_cl(path)
    assert cutting_points(toolpath) == (3.0, {2: 3.0, 1: 0.0})
    sections = tool_sections(toolpath, 100.0, by_length=False, by_pivot=True)
    assert [s.pivot for s in sections] == [3.0, 0.0]
    assert sections[0].stop == sections[1].start == len(toolpath) // 2
    assert len(tool_sections(toolpath, 100.0, by_length=False)) == 1
    same = read_cl(_job(tmp_path, "same", [(2, BALL), (3, BALL)]))
    assert len(tool_sections(same, 100.0, by_length=False, by_pivot=True)) == 1
    # a first CUTTER record replaced before the first point: the one in force there counts
    text = path.read_text().replace("LOADTL/2", "CUTTER/8.0,0.5\nLOADTL/2", 1)
    (tmp_path / "again.apt").write_text(text)
    assert cutting_points(read_cl(tmp_path / "again.apt"))[0] == 3.0


@pytest.mark.parametrize("pieces", ["0", "100"])
@pytest.mark.parametrize("order", ["ball-first", "flat-first"])
def test_a_flat_end_mill_after_a_ball_end_mill_bends_about_its_tip(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], order: str, pieces: str
) -> None:
    """Posted whole and streamed, the two-tool job verifies (whole and streamed) with each
    section at its own cutting point; its flat tool's section alone, against a CL file of
    that tool only, keeps its tip within 0.01 mm (it was 0.084 mm off)."""
    cutters = [(2, BALL), (1, FLAT)] if order == "ball-first" else [(1, FLAT), (2, BALL)]
    cl = _job(tmp_path, "job", cutters)
    program = tmp_path / "job.h"
    post = ["post", str(cl), "-m", "dmu50", "-c", "heidenhain", "-q", "-o", str(program)]
    assert main([*post, "--piece-points", pieces]) == 0
    capsys.readouterr()
    verify = ["verify", str(program), "-m", "dmu50", "--angle-tolerance", "2"]
    for verify_pieces in ("0", "100"):
        assert main([*verify, "--cl", str(cl), "--piece-points", verify_pieces]) == 0
        capsys.readouterr()
    # the flat tool's half of the program, alone, at its tip (no pivot: a flat cutter first)
    text = program.read_text().splitlines(keepends=True)
    calls = [i for i, line in enumerate(text) if "TOOL CALL" in line]
    assert len(calls) == 2
    flat_half = text[: calls[1]] if order == "flat-first" else text[: calls[0]] + text[calls[1] :]
    alone = tmp_path / "flat.h"
    alone.write_text("".join(flat_half))
    flat_cl = _job(tmp_path, "flat", [(1, FLAT)])
    main(["verify", str(alone), "-m", "dmu50", "--angle-tolerance", "2", "--cl", str(flat_cl)])
    assert _tip_deviation(capsys) <= 0.01


def test_verify_measures_a_flat_tool_at_its_tip(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A program whose strategy bent a path about a ball centre, checked against the same path
    cut with a flat end mill: refused (its tip leaves the path by the ball radius times the
    bend), where one pivot for the job had passed it."""
    ball = _job(tmp_path, "ball", [(1, BALL)])
    program = tmp_path / "ball.h"
    assert (
        main(["post", str(ball), "-m", "dmu50", "-c", "heidenhain", "-q", "-o", str(program)]) == 0
    )
    capsys.readouterr()
    flat = _job(tmp_path, "flat", [(1, FLAT)])
    code = main(
        ["verify", str(program), "-m", "dmu50", "--cl", str(flat), "--angle-tolerance", "2"]
    )
    assert code == 1
    assert _tip_deviation(capsys) > 0.05


def _pass_through_box(tmp_path: Path, cutters: list[tuple[int, str]]) -> Path:
    """Each tool, 10 degrees off vertical, through the side of a 40 mm high box at 10 mm above
    its floor: a 20 mm end mill's flutes (60 mm) reach above it, a 6 mm one's (18 mm) do not,
    so its shank runs through the stock."""
    tilt = ",".join(
        f"{c:.6f}" for c in (math.sin(math.radians(10)), 0.0, math.cos(math.radians(10)))
    )
    lines = ["PARTNO BOX", "UNITS/MM", "MULTAX/ON"]
    for number, cutter in cutters:
        lines += [f"LOADTL/{number}", cutter, "SPINDL/8000,CLW", "RAPID"]
        lines += [f"GOTO/-40.0,0.0,60.0,{tilt}", "FEDRAT/MMPM,500"]
        lines += [f"GOTO/{x:.1f},0.0,10.0,{tilt}" for x in range(-40, 41, 5)]
        lines += ["RAPID", f"GOTO/40.0,0.0,60.0,{tilt}"]
    path = tmp_path / "box.apt"
    path.write_text("\n".join([*lines, "FINI"]) + "\n")
    return path


@pytest.mark.parametrize("pieces", ["0", "8"])
def test_collisions_are_checked_with_each_tool_s_own_body(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], pieces: str
) -> None:
    """A 6 mm end mill after a 20 mm one, whose shank runs through the stock: refused at its
    own CL line, whole and streamed (the first cutter's body for the whole job had found no
    collision and written the program); the 20 mm one alone is clear."""
    stock = tmp_path / "box.stl"
    mesh = trimesh.creation.box(extents=(40.0, 40.0, 40.0))
    mesh.apply_translation((0.0, 0.0, 20.0))
    mesh.export(stock)
    out = tmp_path / "box.h"
    post = ["post", "-m", "dmu50", "--stock", str(stock), "-q", "--piece-points", pieces]
    big = _pass_through_box(tmp_path, [(1, FLAT.replace("10.0", "20.0"))])
    assert main([*post, str(big), "-o", str(out)]) == 0
    capsys.readouterr()
    out.unlink()
    both = _pass_through_box(tmp_path, [(1, FLAT.replace("10.0", "20.0")), (2, "CUTTER/6.0,0.0")])
    assert main([*post, str(both), "-o", str(out)]) == 1
    err = capsys.readouterr().err
    found = re.search(r"box\.apt:(\d+): every branch collides", err)
    assert found and "shank collides with stock" in err, err
    second = both.read_text().splitlines().index("LOADTL/2") + 1
    assert int(found[1]) > second  # on the 6 mm tool's path
    assert not out.exists()


# -- one tool number, one tool -----------------------------------------------------------------


@pytest.mark.parametrize("streamed", [False, True])
def test_one_tool_number_for_two_cutters_is_refused(
    tmp_path: Path, streamed: bool, capsys: pytest.CaptureFixture[str]
) -> None:
    """Tool 1 loaded as the 6 mm ball and later as the 10 mm end mill: every tool's geometry
    is looked up by its number (and the machine has one tool in a pocket), so the post bent
    both about the end mill's tip and checked both bodies as the end mill's. Now the CL data is
    refused at the second cutter's line, naming the first; nothing is written."""
    cl = _job(tmp_path, "same", [(1, BALL), (1, FLAT)])
    out = tmp_path / "same.h"
    argv = ["post", str(cl), "-m", "dmu50", "-o", str(out), "-q"]
    if streamed:
        argv += ["--piece-points", "100"]
    assert main(argv) == 1
    err = capsys.readouterr().err
    second = next(k for k, x in enumerate(cl.read_text().splitlines(), 1) if x == FLAT)
    assert f"same.apt:{second}: tool 1 is a cutter of diameter 10" in err, err
    assert "a cutter of diameter 6, corner 3 at line 5" in err, err
    assert not out.exists()


def test_a_tool_loaded_again_as_itself_is_fine(tmp_path: Path) -> None:
    """The same tool loaded again with the same cutter (every operation repeating it), and
    two numbers with two cutters: read, one section per cutting point."""
    tp = read_cl(_job(tmp_path, "again", [(1, BALL), (2, FLAT), (1, BALL)]))
    sections = tool_sections(tp, 100.0, by_length=False, by_pivot=True)
    assert [s.pivot for s in sections] == [3.0, 0.0, 3.0]
    # written with more digits, or without its corner radius of 0: the same tool
    same = [(2, "CUTTER/10"), (1, BALL), (2, "CUTTER/10.000000,0.0"), (1, "CUTTER/6.0000001,3")]
    assert len(read_cl(_job(tmp_path, "same", same))) == 4 * len(read_cl(DOME))


def test_one_tool_number_for_two_lengths_is_refused(tmp_path: Path) -> None:
    """LOADTL/1,LENGTH,100 and later LOADTL/1,LENGTH,120: refused at the second."""
    cl = _job(tmp_path, "lengths", [(1, BALL), (1, BALL)])
    text = cl.read_text().replace("LOADTL/1", "LOADTL/1,LENGTH,100", 1)
    cl.write_text(text.replace("LOADTL/1\n", "LOADTL/1,LENGTH,120\n", 1))
    with pytest.raises(CLDataError, match=r"tool 1 is LENGTH 120 here but LENGTH 100 at line 4"):
        read_cl(cl)


def _midway(tmp_path: Path, name: str, head: list[str], cutter: str) -> Path:
    """The dome's path with ``head`` before it and ``cutter`` given halfway along it (after
    the tool's first moves, with no tool change)."""
    skip = ("PARTNO", "UNITS", "MULTAX", "LOADTL", "CUTTER", "FINI", "$$")
    body = [line for line in DOME.read_text().splitlines() if not line.startswith(skip)]
    half = len(body) // 2
    lines = ["PARTNO MIDWAY", "UNITS/MM", "MULTAX/ON", *head]
    lines += [*body[:half], cutter, *body[half:], "FINI"]
    path = tmp_path / f"{name}.apt"
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.mark.parametrize("streamed", [False, True])
@pytest.mark.parametrize("loaded", [True, False])
def test_another_cutter_after_a_tool_s_first_move_is_refused(
    tmp_path: Path, streamed: bool, loaded: bool, capsys: pytest.CaptureFixture[str]
) -> None:
    """A CUTTER that changes the cutter halfway along a tool's moves, with no tool change: a
    tool's cutting point and body come from its tool change, so the post bent the ball's moves
    before it about the end mill's tip (whole) or kept the ball for all (streamed, the tool
    change in an earlier piece), and the machine has no other tool there. Refused at the
    CUTTER's line, naming the cutter moved with; nothing is written."""
    head = ["LOADTL/1", BALL] if loaded else [BALL]
    cl = _midway(tmp_path, "midway", head, FLAT)
    out = tmp_path / "midway.h"
    argv = ["post", str(cl), "-m", "dmu50", "-o", str(out), "-q"]
    if streamed:
        argv += ["--piece-points", "100"]
    assert main(argv) == 1
    err = capsys.readouterr().err
    lines = cl.read_text().splitlines()
    at = lines.index(FLAT) + 1
    first = next(k for k, x in enumerate(lines, 1) if x.startswith("GOTO"))
    tool = "tool 1" if loaded else "the job"
    assert (
        f"midway.apt:{at}: CUTTER gives a cutter of diameter 10, corner 0 after the first move "
        f"of {tool} (line {first}), made with a cutter of diameter 6, corner 3 (line "
        f"{lines.index(BALL) + 1})" in err
    ), err
    assert "put a tool change before the new cutter" in err, err
    assert not out.exists()


def test_a_cutter_after_the_first_move_is_checked_at_the_next_move(tmp_path: Path) -> None:
    """What a cutter given after a tool's moves is for is known at the next record: the same
    cutter again (CAM systems repeat it per operation) is fine; one before the next tool change
    (NX writes TLDATA before LOAD/TOOL) is that tool's; one at the end of the file changes
    nothing; one given after moves made with no cutter at all is refused too."""
    same = read_cl(_midway(tmp_path, "same", ["LOADTL/1", BALL], "CUTTER/6.0000,3.0000"))
    assert cutting_points(same) == (3.0, {1: 3.0})
    nx = read_cl(_midway(tmp_path, "nx", ["LOADTL/1", BALL], f"{FLAT}\nLOADTL/2"))
    assert cutting_points(nx) == (3.0, {1: 3.0, 2: 0.0})
    sections = tool_sections(nx, 100.0, by_length=False, by_pivot=True)
    assert [s.pivot for s in sections] == [3.0, 0.0]
    end = _midway(tmp_path, "end", ["LOADTL/1", BALL], "")
    end.write_text(end.read_text().replace("FINI", f"{FLAT}\nFINI"))
    assert cutting_points(read_cl(end)) == (3.0, {1: 3.0})
    none = _midway(tmp_path, "none", ["LOADTL/1"], BALL)
    first = next(k for k, x in enumerate(none.read_text().splitlines(), 1) if "GOTO" in x)
    with pytest.raises(CLDataError, match=rf"tool 1 \(line {first}\), made with no cutter"):
        read_cl(none)
