"""Issue 17: NX MSYS is informational, CL units from the file or ``--cl-units``, program units
from ``--units``, else the machine file, else the CL data; the units' plausibility warning."""

from __future__ import annotations

import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from conftest import shared_cl

from urdfpost.cli import build_parser, main
from urdfpost.machine import load_machine
from urdfpost.posting.options import PostOptions, resolve
from urdfpost.readers import read_cl, read_cl_chunks, read_cl_text
from urdfpost.units import MM_PER_INCH, program_units, units_doubt

#: A small NX CLSF: one MCS, 10 in from the part's zero in X, turned 90 deg about Z.
NX_ONE_MCS = """\
TOOL PATH/FINISH,TOOL,BALL_MILL_0.5
TLDATA/MILL,0.5000,0.2500,3.0000,0.0000,0.0000
MSYS/10.0000,0.0000,0.0000,0.0000000,1.0000000,0.0000000,-1.0000000,0.0000000,0.0000000
$$ centerline data
SPINDL/RPM,10000,CLW
RAPID
GOTO/1.5000,-2.0000,3.0000,0.0000000,0.0000000,1.0000000
FEDRAT/IPM,20.0000
GOTO/1.5000,-2.0000,0.5000
GOTO/2.5000,-1.0000,0.2500,0.6000000,0.0000000,0.8000000
END-OF-PATH
"""

#: Two operations in two MCS: the first at the part's zero turned 90 deg about Z (its X along
#: the part's +Y, its Y along the part's -X), the second 10 mm along the part's X, not turned.
NX_TWO_MCS = """\
TOOL PATH/OP1,TOOL,MILL
MSYS/0,0,0,0,1,0,-1,0,0
GOTO/1,2,3,0,0,1
END-OF-PATH
TOOL PATH/OP2,TOOL,MILL
MSYS/10,0,0,1,0,0,0,1,0
GOTO/1,2,3,1,0,0
GOTO/4,5,6
MSYS/0,0,0,0,1,0,-1,0,0
GOTO/7,8,9
END-OF-PATH
"""


def nx(text: str, **kwargs):
    return read_cl_text(text, source="nx.cls", **kwargs)


# -- MSYS ---------------------------------------------------------------------------------------


def test_one_msys_is_informational():
    tp = nx(NX_ONE_MCS)
    assert tp.units == "inch" and tp.warnings == ()
    # the GOTO values as written (inch -> mm), the tool axis as written, modal in between
    np.testing.assert_array_equal(
        tp.tip, np.array([[1.5, -2.0, 3.0], [1.5, -2.0, 0.5], [2.5, -1.0, 0.25]]) * MM_PER_INCH
    )
    np.testing.assert_array_equal(tp.axis, [[0, 0, 1], [0, 0, 1], [0.6, 0, 0.8]])
    (msys,) = [e for e in tp.events if e.kind == "msys"]
    assert (msys.index, msys.line) == (0, 3)
    assert msys.data["mcs"] == 0 and msys.data["transformed"] is False
    np.testing.assert_allclose(msys.data["origin"], [10 * MM_PER_INCH, 0, 0], atol=1e-12)
    # rows of the matrix whose columns are the MCS axes: X = part +Y, Y = part -X, Z = part +Z
    np.testing.assert_allclose(msys.data["rotation"], [[0, -1, 0], [1, 0, 0], [0, 0, 1]])
    assert msys.data["text"] == "MCS 0 origin 10 0 0 inch, x-axis 0 1 0, z-axis 0 0 1"


def test_msys_repeated_with_the_same_mcs_changes_nothing():
    text = NX_ONE_MCS.replace("END-OF-PATH\n", "") + NX_ONE_MCS
    tp = nx(text)
    assert tp.warnings == ()
    np.testing.assert_array_equal(tp.tip[3:], tp.tip[:3])
    assert [(e.data["mcs"], e.data["transformed"]) for e in tp.events if e.kind == "msys"] == [
        (0, False),
        (0, False),
    ]


def test_two_mcs_are_transformed_into_the_first():
    tp = nx(NX_TWO_MCS, format="apt")
    # By hand. MCS 1: origin o1 = 0, axes R1 = [X1 Y1 Z1] = [(0,1,0) (-1,0,0) (0,0,1)] as
    # columns. MCS 2: origin o2 = (10, 0, 0), R2 = I. A point p in MCS 2 is o2 + p in the part
    # and R1^T (o2 + p - o1) in MCS 1; R1^T v = (X1.v, Y1.v, Z1.v) = (v_y, -v_x, v_z).
    #   (1, 2, 3) -> v = (11, 2, 3) -> (2, -11, 3)
    #   (4, 5, 6) -> v = (14, 5, 6) -> (5, -14, 6)
    # axis (1, 0, 0) -> (0, -1, 0), kept by the next GOTO. After the third MSYS (MCS 1 again)
    # the points are as written, and so is the modal axis: its values (1, 0, 0) are read in
    # the MCS now in force (as a 3-axis operation's (0, 0, 1) is each MCS's own Z).
    np.testing.assert_allclose(
        tp.tip, [[1, 2, 3], [2, -11, 3], [5, -14, 6], [7, 8, 9]], rtol=0, atol=1e-12
    )
    np.testing.assert_allclose(
        tp.axis, [[0, 0, 1], [0, -1, 0], [0, -1, 0], [1, 0, 0]], rtol=0, atol=1e-12
    )
    assert tp.warnings == (
        "nx.cls:6: MSYS at line 6 differs from the first MCS (line 2): points transformed "
        "into the first MCS",
    )
    msys = [
        (e.index, e.line, e.data["mcs"], e.data["transformed"])
        for e in tp.events
        if e.kind == "msys"
    ]
    assert msys == [(0, 2, 0, False), (1, 6, 1, True), (3, 9, 0, False)]
    (second,) = [e for e in tp.events if e.kind == "msys" and e.data["mcs"] == 1]
    assert second.data["text"] == (
        "MCS 1 origin 10 0 0 mm, x-axis 1 0 0, z-axis 0 0 1: points transformed into MCS 0"
    )


def test_two_mcs_left_separate_on_request():
    tp = nx(NX_TWO_MCS, format="apt", separate_mcs=True)
    np.testing.assert_array_equal(tp.tip, [[1, 2, 3], [1, 2, 3], [4, 5, 6], [7, 8, 9]])
    np.testing.assert_array_equal(tp.axis, [[0, 0, 1], [1, 0, 0], [1, 0, 0], [1, 0, 0]])
    assert tp.warnings == (
        "nx.cls:6: MSYS at line 6 differs from the first MCS (line 2): points left in MCS 1 "
        "(separate MCS)",
    )
    assert [(e.data["mcs"], e.data["transformed"]) for e in tp.events if e.kind == "msys"] == [
        (0, False),
        (1, False),
        (0, False),
    ]


@pytest.mark.parametrize("separate_mcs", [False, True])
def test_two_mcs_read_in_pieces_as_whole(tmp_path, separate_mcs):
    path = tmp_path / "two.cls"
    path.write_text(NX_TWO_MCS)
    whole = read_cl(path, separate_mcs=separate_mcs)
    pieces = list(read_cl_chunks(path, max_points=1, separate_mcs=separate_mcs, _text_piece=8))
    np.testing.assert_array_equal(np.concatenate([p.tip for p in pieces]), whole.tip)
    np.testing.assert_array_equal(np.concatenate([p.axis for p in pieces]), whole.axis)
    assert [w for p in pieces for w in p.warnings] == list(whole.warnings)


def test_real_nx_ballmill_first_goto_as_written():
    """NX's own post writes X-4.2721 Y-3.0148 for the first GOTO: the values as written."""
    path = shared_cl("nx_variable_axis_ballmill_inch.cls")
    text = path.read_text()
    first = re.search(r"^GOTO/([^\n$]*)", text, re.M)
    assert first is not None
    values = [float(v) for v in first.group(1).split(",")]
    assert values[:2] == [-4.2721, -3.0148]
    assert re.search(r"^MSYS/3\.0+,3\.0+,0\.0+,", text, re.M)  # an MCS away from the part's zero
    tp = read_cl(path)
    assert tp.units == "inch"
    np.testing.assert_allclose(tp.tip[0] / MM_PER_INCH, values[:3], rtol=0, atol=1e-12)
    axis = np.array(values[3:6])
    np.testing.assert_allclose(tp.axis[0], axis / np.linalg.norm(axis), rtol=0, atol=1e-12)
    assert not any("MSYS" in w for w in tp.warnings)


# -- CL units -----------------------------------------------------------------------------------


def test_cl_units_override_the_file_with_a_warning():
    tp = nx(NX_ONE_MCS, units="mm")
    assert tp.units == "mm"
    np.testing.assert_array_equal(tp.tip[0], [1.5, -2.0, 3.0])
    np.testing.assert_array_equal(tp.feed[1:], [20.0, 20.0])  # IPM gives the mode, not the unit
    # the file says inch by its first feed keyword (FEDRAT/IPM at line 8)
    assert tp.warnings == ("nx.cls:8: CL file says inch at line 8; read as mm (--cl-units)",)
    tp = read_cl_text("UNITS/MM\nGOTO/1,0,0\nUNITS/MM\n", source="a.apt", units="inch")
    np.testing.assert_array_equal(tp.tip, [[MM_PER_INCH, 0, 0]])
    assert tp.warnings == (
        "a.apt:1: CL file says mm at line 1; read as inch (--cl-units)",
        "a.apt:3: CL file says mm at line 3; read as inch (--cl-units)",
    )
    # a feed keyword of other units than the file's UNITS and those given: one warning
    tp = read_cl_text(
        "UNITS/MM\nFEDRAT/IPM,10\nGOTO/1,0,0\nFEDRAT/IPM,12\nGOTO/2,0,0\n",
        source="a.apt",
        units="mm",
    )
    np.testing.assert_array_equal(tp.feed, [10.0, 12.0])
    assert tp.warnings == ("a.apt:2: CL file says inch at line 2; read as mm (--cl-units)",)


def test_no_units_in_the_file_is_mm():
    tp = read_cl_text("GOTO/1,2,3\n", source="a.apt")
    assert tp.units == "mm" and tp.warnings == ()
    np.testing.assert_array_equal(tp.tip, [[1, 2, 3]])
    tp = read_cl_text("1 2 3\n", source="a.txt")
    assert tp.units == "mm" and tp.warnings == ()


#: A Creo file in mm that says UNITS/INCHES: a 1181.1 "IPM" feed (30 m/min), a "6 inch" cutter.
CREO_MM_SAYS_INCH = """\
PARTNO / BRACKET
UNITS / INCHES
CUTTER / 6.000000
SPINDL / RPM, 10000, CLW
FEDRAT / 1181.100000, IPM
GOTO / 0.0, 0.0, 50.0
GOTO / 120.0, 0.0, 50.0
GOTO / 120.0, 80.0, 50.0
FINI
"""


def test_units_doubt_warning_for_mm_data_said_to_be_inch():
    tp = read_cl_text(CREO_MM_SAYS_INCH, source="creo.ncl")
    assert tp.units == "inch"
    assert tp.warnings == (
        "creo.ncl:2: CL file says inch at line 2, but its figures look like mm: feeds up to "
        "1181 inch/min, a 6 inch cutter; check its units (--cl-units mm reads it in mm)",
    )
    # read as mm: plausible (1181 mm/min, a 6 mm cutter, a 120 mm path); only the override
    tp = read_cl_text(CREO_MM_SAYS_INCH, source="creo.ncl", units="mm")
    assert tp.warnings == ("creo.ncl:2: CL file says inch at line 2; read as mm (--cl-units)",)


def test_no_units_doubt_for_a_plausible_inch_file():
    text = (
        CREO_MM_SAYS_INCH.replace("6.000000", "0.500000")
        .replace("1181.100000", "40.0")
        .replace("120.0", "10.0")
        .replace("80.0", "6.0")
    )
    tp = read_cl_text(text, source="creo.ncl")
    assert tp.units == "inch" and tp.warnings == ()
    assert tp.feed[0] == pytest.approx(40 * MM_PER_INCH)


def test_units_doubt_needs_two_figures():
    assert units_doubt("inch", feed=1181.1, cutter=6.0, extent=4.7) == (
        "feeds up to 1181 inch/min, a 6 inch cutter"
    )
    assert units_doubt("inch", feed=1181.1, cutter=0.5, extent=4.7) is None  # a fast machine
    assert units_doubt("inch", feed=None, cutter=6.0, extent=None) is None
    assert units_doubt("mm", feed=2.0, cutter=0.25, extent=3.0) == (
        "feeds of at most 2 mm/min, a 0.25 mm cutter, a path of 3 mm"
    )
    assert units_doubt("mm", feed=2.0, cutter=6.0, extent=100.0) is None


def test_units_doubt_read_in_pieces_as_whole(tmp_path):
    path = tmp_path / "creo.ncl"
    path.write_text(CREO_MM_SAYS_INCH)
    whole = read_cl(path)
    pieces = list(read_cl_chunks(path, max_points=1, _text_piece=16))
    assert len(whole.warnings) == 1
    assert [w for p in pieces for w in p.warnings] == list(whole.warnings)


# -- program units ------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def dmu50():
    return load_machine("dmu50")


@pytest.mark.parametrize(
    ("asked", "machine_units", "cl_units", "expected"),
    [
        (None, None, "inch", "inch"),  # nothing set: the CL data's
        (None, None, "mm", "mm"),
        (None, "mm", "inch", "mm"),  # the machine file's setting before the CL data's
        (None, "inch", "mm", "inch"),
        ("inch", "mm", "mm", "inch"),  # --units before both
        ("mm", None, "inch", "mm"),
    ],
)
def test_program_units_through_resolve(dmu50, asked, machine_units, cl_units, expected):
    machine = replace(dmu50, settings=replace(dmu50.settings, units=machine_units))
    assert program_units(asked, machine_units, cl_units) == expected
    job = resolve(PostOptions(units=asked), machine, cl_units)
    assert job.units == expected
    assert job.tol.tip == pytest.approx(0.0004 * MM_PER_INCH if expected == "inch" else 0.01)
    # lengths given in program units are converted with the program's units
    job = resolve(PostOptions(units=asked, holder_diameter=2.0), machine, cl_units)
    assert job.holder_diameter == pytest.approx(2.0 * (MM_PER_INCH if expected == "inch" else 1))


# -- command line -------------------------------------------------------------------------------

SAYS_INCH = """\
UNITS/INCHES
MULTAX/ON
LOADTL/1
SPINDL/RPM,10000,CLW
FEDRAT/1000
GOTO/0,0,10,0,0.2588190,0.9659258
GOTO/20,0,10,0.2588190,0,0.9659258
FINI
"""


@pytest.mark.parametrize("command", ["post", "compare", "verify"])
def test_cl_units_option_parsed(command):
    args = {
        "post": ["post", "a.apt", "-m", "dmu50"],
        "compare": ["compare", "a.apt", "-m", "dmu50"],
        "verify": ["verify", "a.nc", "-m", "dmu50", "--cl", "a.apt"],
    }[command]
    parser = build_parser()
    assert parser.parse_args(args).cl_units is None
    assert parser.parse_args([*args, "--cl-units", "inch"]).cl_units == "inch"
    with pytest.raises(SystemExit):
        parser.parse_args([*args, "--cl-units", "cm"])


def test_units_help_names_the_machine_then_the_cl_file(capsys):
    with pytest.raises(SystemExit):
        build_parser().parse_args(["post", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "program units (default: the machine file's units setting, else the CL file's)" in text
    assert "--cl-units {mm,inch}" in text


def test_cli_cl_units_override(tmp_path: Path, capsys):
    cl = tmp_path / "says_inch.apt"
    cl.write_text(SAYS_INCH)
    out = tmp_path / "a.nc"
    argv = ["post", str(cl), "-m", "dmu50", "-c", "fanuc", "-o", str(out), "-q"]
    assert main([*argv, "--cl-units", "mm"]) == 0
    captured = capsys.readouterr()
    assert (
        f"urdfpost: warning: {cl}:1: CL file says inch at line 1; read as mm (--cl-units)"
        in captured.err
    )
    assert "(fanuc, TCP, mm) for machine dmu50" in captured.out
    text = out.read_text()
    assert re.search(r"^G21$", text, re.M)
    assert re.search(r"^X20\.000 ", text, re.M)  # GOTO/20,0,10 read as mm, written in mm
    # verify reads the CL file the same way (with the same warning)
    assert main(["verify", str(out), "-m", "dmu50", "--cl", str(cl), "--cl-units", "mm"]) == 0
    captured = capsys.readouterr()
    assert "CL file says inch at line 1; read as mm (--cl-units)" in captured.err
    assert "2/2 CL points reached" in captured.out


def test_cli_file_without_units_is_mm_on_an_inch_machine(tmp_path: Path, capsys):
    cl = tmp_path / "no_units.apt"
    cl.write_text(SAYS_INCH.replace("UNITS/INCHES\n", ""))
    out = tmp_path / "b.nc"
    assert main(["post", str(cl), "-m", "umc750", "-o", str(out), "-q"]) == 0
    captured = capsys.readouterr()
    assert "CL file" not in captured.err  # no units warning
    assert "(fanuc, TCP, inch) for machine umc750" in captured.out  # the machine's setting
    text = out.read_text()
    assert re.search(r"^G20$", text, re.M)
    assert re.search(rf"^X{20 / MM_PER_INCH:.4f} ", text, re.M)  # 20 mm, written in inch
    # --units asks for the program units
    assert main(["post", str(cl), "-m", "umc750", "-o", str(out), "-q", "--units", "mm"]) == 0
    assert "(fanuc, TCP, mm) for machine umc750" in capsys.readouterr().out
    assert re.search(r"^X20\.000 ", out.read_text(), re.M)
