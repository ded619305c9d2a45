"""Jobs posted in sections (issue 17): each tool's own gauge length in machine-coordinate
programs, and a work offset per NX MCS.

Machine-coordinate positions include the tool's gauge length. A job whose tools have different
lengths (the tool table ``--tool-table``, else ``LOADTL LENGTH``) is posted in tool sections,
each computed and checked with its tool's length; ``urdfpost verify`` cuts the program the
same way. The positions are checked here against Pinocchio's forward kinematics with each
tool's length, independently of urdfpost's own kinematics and verifier.

With ``--mcs-offsets`` each MCS of an NX file gets its own work offset (G54, G55...), its
points written as its MSYS has them; the program is checked section by section, each on the
machine with the program zero at its MCS, and by LinuxCNC's interpreter.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from jobs import TWO_TOOLS
from oracles import tip_and_axis_pin
from rs274 import run_rs274

from urdfpost import load_machine
from urdfpost.cli import main
from urdfpost.dialects import DIALECTS, dialect_for
from urdfpost.errors import UrdfpostError
from urdfpost.posting.options import PostOptions
from urdfpost.posting.stream import post_stream
from urdfpost.posting.tools import read_tool_table, tool_sections
from urdfpost.posting.whole import post
from urdfpost.program import ToolChange, WorkOffset
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


# -- a work offset per MCS -----------------------------------------------------------------------

#: Two operations in two MCS, the second 30 mm along the part's X and 10 along Y, not turned.
TWO_MCS = """\
TOOL PATH/OP1,TOOL,MILL
MSYS/0,0,0,1,0,0,0,1,0
LOAD/TOOL,1
SPINDL/RPM,9000,CLW
RAPID
GOTO/0,0,20,0,0,1
FEDRAT/MMPM,500
GOTO/0,0,2,0,0,1
GOTO/20,0,2
END-OF-PATH
TOOL PATH/OP2,TOOL,MILL
MSYS/30,10,0,1,0,0,0,1,0
RAPID
GOTO/0,0,20,0,0,1
FEDRAT/MMPM,500
GOTO/0,0,2,0,0,1
GOTO/-10,5,2,0,0.258819,0.965926
END-OF-PATH
"""


def offsets_of(text: str, controller: str) -> list[int]:
    return [b.number for b in dialect_for(controller).read(text).parts if isinstance(b, WorkOffset)]


@pytest.mark.parametrize("controller", CONTROLLERS)
def test_a_work_offset_per_mcs(
    controller: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The second MCS's points as the file has them (X-10 Y5 Z2), in the second work
    offset; verified with --mcs-offsets, refused at the change without it."""
    cl = tmp_path / "mcs.cls"
    cl.write_text(TWO_MCS)
    out = tmp_path / f"mcs{DIALECTS[controller].extensions[0]}"
    argv = ["post", str(cl), "-m", "dmu50", "-c", controller, "-q", "-o", str(out)]
    assert main([*argv, "--mcs-offsets"]) == 0
    text = out.read_text()
    assert offsets_of(text, controller) == [1, 2]
    program = dialect_for(controller).read(text)
    last = program.moves()[-1]
    shifted = [m for m in program.moves() if not m.rapid]
    assert last.rapid  # (the rotaries home)
    x, y, z = shifted[-1].position[:3]
    assert (x, y, z) == pytest.approx((-10.0, 5.0, 2.0), abs=1e-3)
    header = text.upper().replace("[", "(").replace("]", ")")  # (Fanuc: upper case)
    assert "SHIFTED BY (30.000, 10.000, 0.000) MM (MCS 1)" in header
    verify = ["verify", str(out), "--cl", str(cl), "-m", "dmu50", "-c", controller]
    capsys.readouterr()
    assert main([*verify, "--mcs-offsets"]) == 0
    assert "within tolerance: 6/6 CL points" in capsys.readouterr().out
    assert main(verify) == 1
    assert "work offset changes from" in capsys.readouterr().err


def test_the_api_post_of_a_transformed_read_is_the_same(tmp_path: Path) -> None:
    """A toolpath read the default way (the second MCS transformed into the first) posts with
    mcs_offsets=True to what the command line writes from a separate read."""
    cl = tmp_path / "mcs.cls"
    cl.write_text(TWO_MCS)
    out = tmp_path / "mcs.ngc"
    argv = ["post", str(cl), "-m", "dmu50", "-c", "linuxcnc", "-q", "--mcs-offsets"]
    assert main([*argv, "-o", str(out)]) == 0
    toolpath = read_cl_text(TWO_MCS, source=str(cl))
    result = post(
        toolpath, load_machine("dmu50"), PostOptions(controller="linuxcnc", mcs_offsets=True)
    )
    strip = [line for line in result.text.splitlines() if "MSYS" not in line]
    assert strip == [line for line in out.read_text().splitlines() if "MSYS" not in line]


def test_a_wrong_work_offset_is_caught(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The second operation cut in G54 (the first MCS's zero): beyond tolerance there."""
    cl = tmp_path / "mcs.cls"
    cl.write_text(TWO_MCS)
    out = tmp_path / "mcs.nc"
    argv = ["post", str(cl), "-m", "dmu50", "-c", "fanuc", "-q", "--mcs-offsets", "-o", str(out)]
    assert main(argv) == 0
    out.write_text(out.read_text().replace("\nG55\n", "\nG54\n"))
    capsys.readouterr()
    verify = ["verify", str(out), "--cl", str(cl), "-m", "dmu50", "--mcs-offsets"]
    assert main(verify) == 1
    assert (
        "the program's work offsets are offset 1 where the CL data's MCS, in order, need "
        "offset 1, offset 2 (one per MCS)"
    ) in capsys.readouterr().err


def test_the_interpreter_cuts_the_second_mcs_in_g55(tmp_path: Path) -> None:
    """rs274: the cuts of the first operation in G54, those of the second in G55, at the
    program's own positions."""
    cl = tmp_path / "mcs.cls"
    cl.write_text(TWO_MCS)
    out = tmp_path / "mcs.ngc"
    argv = ["post", str(cl), "-m", "dmu50", "-c", "linuxcnc", "-q", "--mcs-offsets"]
    assert main([*argv, "-o", str(out)]) == 0
    text = out.read_text()
    result = run_rs274(text, {1: 100.0}, tmp_path / "rs274")
    g5x, cut = 0, []  # the work offset in effect at each feed move
    for call in result.calls:
        if call.name == "SET_G5X_OFFSET":
            g5x = int(call.number(0))
        elif call.name == "STRAIGHT_FEED":
            cut.append((g5x, tuple(call.number(k) for k in range(3))))
    assert [g for g, _ in cut] == [1, 1, 2, 2, 2]
    assert cut[1][1] == pytest.approx((20.0, 0.0, 2.0), abs=1e-3)
    assert cut[-1][1] == pytest.approx((-10.0, 5.0, 2.0), abs=1e-3)


def test_a_turned_mcs_has_no_work_offset(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    cl = tmp_path / "mcs.cls"
    cl.write_text(TWO_MCS.replace("MSYS/30,10,0,1,0,0,0,1,0", "MSYS/30,10,0,0,1,0,-1,0,0"))
    out = tmp_path / "mcs.nc"
    argv = ["post", str(cl), "-m", "dmu50", "-c", "fanuc", "-q", "--mcs-offsets", "-o", str(out)]
    assert main(argv) == 1
    err = capsys.readouterr().err
    assert f"{cl}:12: MCS 1 is turned against MCS 0 (MSYS at line 2)" in err
    assert not out.exists()


def test_mcs_offsets_need_tcp_and_enough_offsets(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    cl = tmp_path / "mcs.cls"
    cl.write_text(TWO_MCS)
    out = tmp_path / "mcs.nc"
    argv = ["post", str(cl), "-m", "dmu50", "-c", "fanuc", "-q", "--mcs-offsets", "-o", str(out)]
    assert main([*argv, "--no-tcp"]) == 1
    assert "a work offset per MCS needs TCP" in capsys.readouterr().err
    assert main([*argv, "--work-offset", "6"]) == 1
    assert "2 MCS need work offsets 6 to 7; fanuc has work offsets 1 to 6" in (
        capsys.readouterr().err
    )
    assert main([*argv, "--piece-points", "100"]) == 2
    assert not out.exists()


def test_the_view_draws_each_tool_with_its_length(tmp_path: Path) -> None:
    """The 3-D view's tool-tip trace of a program in tool sections: each tool's length puts the
    trace on the CL path; the one length of the job would leave T2's 40 mm off."""
    from urdfpost.analysis.view import view_data

    toolpath = read_cl_text(with_lengths(), source="two.apt")
    machine = load_machine("dmu50")
    result = post(toolpath, machine, PostOptions(controller="heidenhain", tcp=False))
    dialect = dialect_for("heidenhain")
    program = dialect.read(result.text)

    def worst(lengths: dict[int, float] | None) -> float:
        data = view_data(
            machine, program, result.text, dialect, cl=toolpath, color="deviation",
            tool_lengths=lengths,
        )  # fmt: skip
        (mark,) = [m for m in data["marks"] if m["kind"] == "worst"]
        return float(mark["label"].split()[3])

    assert worst(LENGTHS) < 0.01
    assert worst(None) > 10.0
