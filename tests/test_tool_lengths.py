"""Each tool's own gauge length in machine-coordinate programs (issue 17).

Machine-coordinate positions include the tool's gauge length. A job whose tools have different
lengths (the tool table ``--tool-table``, else ``LOADTL LENGTH``) is posted in tool sections,
each computed and checked with its tool's length; ``urdfpost verify`` cuts the program the
same way. The positions are checked here against Pinocchio's forward kinematics with each
tool's length, independently of urdfpost's own kinematics and verifier.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from jobs import TWO_TOOLS
from oracles import tip_and_axis_pin

from urdfpost import load_machine
from urdfpost.cli import main
from urdfpost.dialects import dialect_for
from urdfpost.errors import UrdfpostError
from urdfpost.posting.options import PostOptions
from urdfpost.posting.stream import post_stream
from urdfpost.posting.tools import read_tool_table, tool_sections
from urdfpost.posting.whole import post
from urdfpost.program import ToolChange
from urdfpost.readers import read_cl_text
from urdfpost.toolpath import toolpath_pieces
from urdfpost.verification.match import program_joints

CONTROLLERS = ("heidenhain", "siemens", "fanuc", "linuxcnc")
LENGTHS = {1: 120.0, 2: 80.0}


def with_lengths(first: float | None = 120.0, second: float | None = 80.0) -> str:
    """TWO_TOOLS with ``LOADTL/n,LENGTH,l`` (None: no LENGTH)."""
    text = TWO_TOOLS
    for n, length in ((1, first), (2, second)):
        if length is not None:
            text = text.replace(f"LOADTL/{n}\n", f"LOADTL/{n},LENGTH,{length:g}\n")
    return text


def section_tips(text: str, controller: str, lengths: dict[int, float]) -> list[np.ndarray]:
    """The tool tip of every move of a program read back, by Pinocchio with the length of the
    tool in the spindle (mm, workpiece frame): one array per tool change."""
    machine = load_machine("dmu50")
    program = dialect_for(controller).read(text)
    q, _ = program_joints(machine, program)
    out: list[np.ndarray] = []
    row, tool = 0, None
    rows: list[int] = []
    for part in program.parts:
        if isinstance(part, ToolChange):
            if rows:
                out.append(tip_and_axis_pin(machine, q[rows], lengths[tool])[0])
            rows, tool = [], part.number
        elif hasattr(part, "position"):
            size = 1 if not hasattr(part, "rows") else len(part)
            rows += list(range(row, row + size))
            row += size
    if rows and tool is not None:
        out.append(tip_and_axis_pin(machine, q[rows], lengths[tool])[0])
    return out


def reaches(tips: np.ndarray, points: np.ndarray, tol: float = 0.01) -> bool:
    """Whether each point is within ``tol`` mm of one of the tips."""
    gaps = np.linalg.norm(tips[None, :, :] - points[:, None, :], axis=2).min(axis=1)
    return bool(np.all(gaps < tol))


@pytest.mark.parametrize("controller", CONTROLLERS)
def test_each_tool_is_posted_with_its_own_gauge_length(controller: str) -> None:
    """LOADTL LENGTH 120 and 80: the moves of each tool put its own tip on its CL points (by
    Pinocchio with that length); with the other tool's length they would not."""
    toolpath = read_cl_text(with_lengths(), source="two.apt")
    result = post(toolpath, load_machine("dmu50"), PostOptions(controller=controller, tcp=False))
    assert result.verification.ok
    assert result.report.tool_lengths_mm == LENGTHS
    first, second = section_tips(result.text, controller, LENGTHS)
    cut = next(e.index for e in toolpath.events if e.kind == "tool" and e.data["number"] == 2)
    assert reaches(first, toolpath.tip[1:cut])  # (point 0 is the rapid's start)
    assert reaches(second, toolpath.tip[cut:])
    swapped = section_tips(result.text, controller, {1: 120.0, 2: 120.0})[1]
    assert not reaches(swapped, toolpath.tip[cut:])
    header = "EACH TOOL'S GAUGE LENGTH [T1 120.000, T2 80.000 MM]"  # (Fanuc: upper case)
    assert header in result.text.upper().replace("(", "[").replace(")", "]")


def test_the_tool_table_comes_before_loadtl_length(tmp_path: Path) -> None:
    toolpath = read_cl_text(with_lengths(), source="two.apt")
    table = {1: 110.0, 2: 90.0}
    result = post(
        toolpath,
        load_machine("dmu50"),
        PostOptions(controller="fanuc", tcp=False, tool_table=table),
    )
    assert result.report.tool_lengths_mm == table
    first, second = section_tips(result.text, "fanuc", table)
    cut = next(e.index for e in toolpath.events if e.kind == "tool" and e.data["number"] == 2)
    assert reaches(first, toolpath.tip[1:cut])
    assert reaches(second, toolpath.tip[cut:])


def test_equal_lengths_are_one_section() -> None:
    """Both tools at the job's length: the program of a job without any (one section)."""
    machine = load_machine("dmu50")
    options = PostOptions(controller="linuxcnc", tcp=False)
    plain = post(read_cl_text(TWO_TOOLS, source="two.apt"), machine, options)
    same = post(read_cl_text(with_lengths(100.0, 100.0), source="two.apt"), machine, options)
    drop = [line for line in same.text.splitlines() if "tools:" not in line]
    assert drop == [line for line in plain.text.splitlines() if "tools:" not in line]
    toolpath = read_cl_text(with_lengths(100.0, 100.0), source="two.apt")
    assert len(tool_sections(toolpath, 100.0)) == 1
    assert len(tool_sections(toolpath, 100.0, {2: 50.0})) == 2


@pytest.mark.parametrize("controller", CONTROLLERS)
@pytest.mark.parametrize("pieces", [2, 3, 100])
def test_a_streamed_post_writes_what_the_whole_one_does(
    controller: str, pieces: int, tmp_path: Path
) -> None:
    toolpath = read_cl_text(with_lengths(), source="two.apt")
    machine = load_machine("dmu50")
    options = PostOptions(controller=controller, tcp=False)
    whole = post(toolpath, machine, options)
    out = tmp_path / "two.nc"
    streamed = post_stream(
        toolpath_pieces(toolpath, 2), machine, out, options, piece_points=pieces, parallel=False
    )
    assert out.read_text() == whole.text
    assert streamed.verification.ok
    assert streamed.verification.cl_points == whole.verification.cl_points == len(toolpath)
    assert streamed.verification.blocks == whole.verification.blocks
    assert streamed.report.tool_lengths_mm == LENGTHS


@pytest.mark.parametrize("pieces", ["0", "2"])
def test_verify_checks_each_tool_with_its_length(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], pieces: str
) -> None:
    """``urdfpost verify --tool-table``: the table the program was posted with verifies it;
    one tool 1 mm off is caught at that tool's CL lines, whole and in pieces."""
    cl = tmp_path / "two.apt"
    cl.write_text(TWO_TOOLS)
    good = tmp_path / "tools.tbl"
    good.write_text("T1 P1 Z120.0 D10 ;rougher\nT2 P2 Z80 D6\n")
    bad = tmp_path / "wrong.tbl"
    bad.write_text("T1 P1 Z120.0 D10\nT2 P2 Z81 D6\n")
    out = tmp_path / "two.ngc"
    base = ["-m", "dmu50", "-q"]
    assert (
        main(["post", str(cl), *base, "--no-tcp", "--tool-table", str(good), "-o", str(out)]) == 0
    )
    verify = ["verify", str(out), "--cl", str(cl), "-m", "dmu50", "--piece-points", pieces]
    capsys.readouterr()
    assert main([*verify, "--tool-table", str(good)]) == 0
    assert "within tolerance: 6/6 CL points" in capsys.readouterr().out
    assert main([*verify, "--tool-table", str(bad)]) == 1
    text = capsys.readouterr().out
    assert "BEYOND TOLERANCE: 4/6 CL points" in text
    assert "missed CL lines: 14, 16" in text
    assert main(verify) == 1  # no table: both tools at the machine file's 100 mm


def test_read_tool_table(tmp_path: Path) -> None:
    path = tmp_path / "t.tbl"
    path.write_text("; comment\n\nT1 P1 Z4 D0.5 ;a\nT12 P3 X0 Z2.5\n")
    assert read_tool_table(path, 25.4) == {1: 4 * 25.4, 12: 2.5 * 25.4}


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("T1 P1 D6\n", r"t\.tbl:1: expected a tool number T and a length Z, got no Z"),
        ("P1 Z6\n", r"t\.tbl:1: expected a tool number T and a length Z, got no T"),
        ("T1 Z100\nT1 Z90\n", r"t\.tbl:2: T1 is listed twice"),
        ("T1 Z-5\n", r"t\.tbl:1: expected a positive gauge length for T1, got Z-5"),
        ("T1.5 Z5\n", r"t\.tbl:1: expected a whole tool number, got T1\.5"),
        ("T1 Z5 length\n", r"t\.tbl:1: expected tool table words .* got 'length'"),
        ("T1 Z5 Z6\n", r"t\.tbl:1: expected one Z word, got two"),
    ],
)
def test_a_bad_tool_table_names_its_line(tmp_path: Path, text: str, message: str) -> None:
    path = tmp_path / "t.tbl"
    path.write_text(text)
    with pytest.raises(UrdfpostError, match=message):
        read_tool_table(path)


def test_a_bad_tool_table_on_the_command_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Exit 1 with the file and line; no program written."""
    cl = tmp_path / "two.apt"
    cl.write_text(TWO_TOOLS)
    table = tmp_path / "t.tbl"
    table.write_text("T1 Z100\nT2 P2\n")
    out = tmp_path / "two.nc"
    argv = ["post", str(cl), "-m", "dmu50", "--no-tcp", "--tool-table", str(table), "-o", str(out)]
    assert main([*argv, "-q"]) == 1
    assert (
        f"{table}:2: expected a tool number T and a length Z, got no Z" in capsys.readouterr().err
    )
    assert not out.exists()
    assert main([*argv[:-4], "--tool-table", str(tmp_path / "none.tbl"), "-o", str(out)]) == 1
    assert "cannot read the tool table" in capsys.readouterr().err
