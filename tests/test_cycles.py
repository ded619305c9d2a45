"""Canned drilling cycles: the APT CYCLE records, the Cycle blocks, the four controls' cycles,
their reading back and their check by the verifier, the expansion (``--expand-cycles``), and
LinuxCNC's interpreter running the cycles.

The job (:func:`jobs.drilling_job`) drills two holes with a dwell, pecks two holes at another
height and taps one, flat, on the table-table dmu50. Golden programs:
``tests/golden/cycles/<control>_<native|expanded>.<ext>``; regenerate with
``URDFPOST_REGEN_GOLDEN=1`` and read the diff.
"""

from __future__ import annotations

import functools
import math
import os
import re
from pathlib import Path

import numpy as np
import pytest
from jobs import drilling_job
from rs274 import run_rs274

from urdfpost import load_machine
from urdfpost.dialects import DIALECTS
from urdfpost.errors import CLDataError, ProgramParseError
from urdfpost.machine import Machine
from urdfpost.posting.options import PostOptions
from urdfpost.posting.planes import plane_count
from urdfpost.posting.whole import PostResult, post
from urdfpost.program import (
    CHIP_BREAK_RETRACT,
    PECK_GAP,
    Cycle,
    Dwell,
    Program,
    Spindle,
    cycle_moves,
    expand_cycle,
    expand_cycles,
)
from urdfpost.readers import read_cl_text
from urdfpost.toolpath import Toolpath, cycle_holes
from urdfpost.verification import verify

GOLDEN = Path(__file__).parent / "golden" / "cycles"
REGEN = os.environ.get("URDFPOST_REGEN_GOLDEN") == "1"
CONTROLS = ("heidenhain", "siemens", "fanuc", "linuxcnc")
#: (x, y) of each hole of the job: its top and bottom z, mm, and the cycle's feed, mm/min
HOLES = {
    (10.0, 10.0): (0.0, -6.0, 150.0),
    (30.0, 10.0): (0.0, -6.0, 150.0),
    (30.0, -10.0): (-1.0, -15.0, 90.0),
    (10.0, -10.0): (-1.0, -15.0, 90.0),
    (20.0, 0.0): (0.0, -10.0, 1500.0),
}


@functools.cache
def machine() -> Machine:
    return load_machine("dmu50")


@functools.cache
def job(units: str = "MM", tilted: bool = False) -> Toolpath:
    return read_cl_text(drilling_job(units, tilted), source="drill.apt")


@functools.cache
def posted(control: str, expand: bool = False, tcp: bool = True) -> PostResult:
    return post(job(), machine(), PostOptions(controller=control, expand_cycles=expand, tcp=tcp))


def _cycles(program: Program) -> list[Cycle]:
    return [b for b in program.parts if isinstance(b, Cycle)]


# -- reading CL data -------------------------------------------------------------------------


def test_cycle_records_become_events_and_holes() -> None:
    toolpath = job()
    starts = [e for e in toolpath.events if e.kind == "cycle" and e.data["cycle"] != "off"]
    assert [e.data["cycle"] for e in starts] == ["drill", "deep", "tap"]
    drill, deep, tap = (e.data for e in starts)
    # NX keyword form: FEDTO negative, RAPTO the clearance, RTRCTO the retract height
    assert (drill["depth"], drill["clearance"], drill["retract"]) == (6.0, 2.0, 10.0)
    assert (drill["feed"], drill["dwell"]) == (150.0, 0.5)
    assert (deep["depth"], deep["step"], deep["clearance"], deep["retract"]) == (14, 5, 3, 3)
    assert tap["feed"] == pytest.approx(1.25 * 1200)  # MMPR: the pitch times the speed
    holes = cycle_holes(toolpath)
    assert [int(toolpath.line[i]) for i, _ in holes] == [10, 11, 14, 15, 18]
    assert all(toolpath.motion[i] == 1 for i, _ in holes)  # reached at rapid
    assert not toolpath.warnings


def test_inch_cycle_is_converted() -> None:
    mm, inch = job(), job("INCHES")
    for a, b in zip(mm.events, inch.events, strict=True):
        if a.kind == "cycle":
            assert a.data.keys() == b.data.keys()
            for key, value in a.data.items():
                if isinstance(value, float):
                    assert b.data[key] == pytest.approx(value, rel=1e-5), key


def test_positional_form() -> None:
    text = "UNITS/MM\nSPINDL/1000\nCYCLE/DRILL,4,MMPM,200,2\nGOTO/1,2,0\nCYCLE/OFF\nFINI\n"
    (event,) = [e for e in read_cl_text(text).events if e.kind == "cycle"][:1]
    assert (event.data["depth"], event.data["feed"], event.data["clearance"]) == (4, 200, 2)


@pytest.mark.parametrize(
    ("record", "match"),
    [
        ("CYCLE/DRILL,MMPM,100,RAPTO,2", r"drill.apt:3: expected the depth of the hole"),
        ("CYCLE/SPOT,FEDTO,2,MMPM,100,RAPTO,2", r"drill.apt:3: unknown cycle kind SPOT"),
        ("CYCLE/DRILL,FEDTO,2,MMPM,100", r"drill.apt:3: expected the clearance"),
        ("CYCLE/DRILL,DEEP,FEDTO,9,MMPM,100,RAPTO,2", r"drill.apt:3: expected the peck depth"),
        ("CYCLE/DRILL,FEDTO,2,MMPM,100,RAPTO,2,ORIENT,0", r"unknown CYCLE keyword ORIENT"),
        ("CYCLE/DRILL,FEDTO,2,MMPM,-5,RAPTO,2", r"expected a positive feed"),
        ("CYCLE/DRILL,FEDTO,2,MMPM,100,RAPTO,5,RTRCTO,1", r"expected 0 <= clearance <= retract"),
        ("CYCLE/DRILL,FEDTO,2,RAPTO,2", r"expected a feed \(MMPM,f or IPM,f\) or a FEDRAT"),
        ("CYCLE/DRILL,FEDTO,X,MMPM,100,RAPTO,2", r"drill.apt:3: expected a number after FEDTO"),
        ("CYCLE/DRILL,1,2,3,MMPM,100", r"values more than the depth and clearance"),
        ("CYCLE", r"drill.apt:3: expected a cycle kind"),
    ],
)
def test_bad_cycle_records_name_file_and_line(record: str, match: str) -> None:
    text = f"UNITS/MM\nSPINDL/1000\n{record}\nGOTO/1,2,0\nCYCLE/OFF\nFINI\n"
    with pytest.raises(CLDataError, match=match):
        read_cl_text(text, source="drill.apt")


# -- the expansion -----------------------------------------------------------------------------


def _rows(blocks: list) -> np.ndarray:
    return np.concatenate([b.position for b in blocks if hasattr(b, "position")])


def test_expansion_of_pecks_dwell_and_tap() -> None:
    axes = ("X", "Y", "Z")
    deep = Cycle("deep", 10.0, 100.0, 2.0, 5.0, ((1.0, 2.0, 0.0),), step=4.0, dwell=1.0)
    blocks = expand_cycle(deep, axes)
    z = _rows(blocks)[:, 2].tolist()
    gap = PECK_GAP
    assert z == [5, 2, -4, 2, -4 + gap, -8, 2, -8 + gap, -10, 5]
    assert Dwell(1.0) in blocks
    chip = Cycle("chipbreak", 10.0, 100.0, 2.0, 2.0, ((1.0, 2.0, 0.0),), step=4.0)
    z = _rows(expand_cycle(chip, axes))[:, 2].tolist()
    retract = CHIP_BREAK_RETRACT
    assert z == [2, -4, -4 + retract, -8, -8 + retract, -10, 2]
    tap = Cycle("tap", 8.0, 1250.0, 3.0, 3.0, ((1.0, 2.0, 0.0),))
    with pytest.raises(ValueError, match="spindle off"):
        expand_cycle(tap, axes)
    blocks = expand_cycle(tap, axes, Spindle("cw", 1000.0))
    spindles = [b for b in blocks if isinstance(b, Spindle)]
    assert spindles == [Spindle("ccw", 1000.0), Spindle("cw", 1000.0)]


# -- posting: every control ----------------------------------------------------------------------


def golden_path(control: str, mode: str) -> Path:
    return GOLDEN / f"{control}_{mode}{DIALECTS[control].extensions[0]}"


@pytest.mark.parametrize("expand", [False, True], ids=["native", "expanded"])
@pytest.mark.parametrize("control", CONTROLS)
def test_golden(control: str, expand: bool) -> None:
    text = posted(control, expand).text
    path = golden_path(control, "expanded" if expand else "native")
    if REGEN:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    assert path.exists(), f"missing golden file {path}; run with URDFPOST_REGEN_GOLDEN=1"
    assert text == path.read_text()


@pytest.mark.parametrize("control", CONTROLS)
def test_golden_tilted(control: str) -> None:
    """The three flat cycles and the tilted hole: in a tilted plane (CYCL DEF 200 after PLANE
    SPATIAL, CYCLE81 after CYCLE800, G81 after G68.2), on LinuxCNC as its motion."""
    result = post(job(tilted=True), machine(), PostOptions(controller=control))
    path = golden_path(control, "tilted")
    if REGEN:
        path.write_text(result.text)
    assert path.exists(), f"missing golden file {path}; run with URDFPOST_REGEN_GOLDEN=1"
    assert result.text == path.read_text()
    assert result.verification.ok


#: The lines of a control's cycles (block numbers stripped).
CYCLE_LINES = {
    "heidenhain": (r"^CYCL DEF 200 DRILLING", r"^CYCL DEF 203 ", r"^CYCL DEF 207 ", r"M99$"),
    "siemens": (r"^MCALL CYCLE82\(", r"^MCALL CYCLE83\(", r"^MCALL CYCLE84\(", r"^MCALL$"),
    "fanuc": (r"^G98 G82 .* P500 ", r"^G98 G83 .* Q5\.000 ", r"^G98 G84 ", r"^G80$"),
    "linuxcnc": (r"^G98 G82 .* P0\.5 ", r"^G98 G83 .* Q5\.000 ", r"^G98 G84 ", r"^G80$"),
}


@pytest.mark.parametrize("control", CONTROLS)
def test_cycles_are_written_read_back_and_verified(control: str) -> None:
    result = posted(control)
    lines = [re.sub(r"^N?\d+ ", "", line) for line in result.text.splitlines()]
    for pattern in CYCLE_LINES[control]:
        assert any(re.search(pattern, line) for line in lines), pattern
    assert not result.report.warnings
    program = DIALECTS[control].read(result.text)
    cycles = _cycles(program)
    assert [c.kind for c in cycles] == ["drill", "deep", "tap"]
    assert [len(c.holes) for c in cycles] == [2, 2, 1]
    assert not cycle_moves(program).any()  # nothing expanded: the control's own cycles
    check = verify(program, machine(), job())
    assert check.ok, check.summary()
    assert "5 holes of canned cycles: largest deviations: bottom 0.0000 mm" in check.summary()
    # the hole bottoms of the cycles read back: the CL tops plus the depths
    for cycle in cycles:
        for hole in cycle.holes:
            _top, bottom, feed = HOLES[(round(hole[0], 3), round(hole[1], 3))]
            assert hole[2] - cycle.depth == pytest.approx(bottom, abs=1e-9)
            assert cycle.feed == pytest.approx(feed)


@pytest.mark.parametrize("control", CONTROLS)
def test_expanded_cycles_are_plain_motion_and_verified(control: str) -> None:
    result = posted(control, expand=True)
    program = DIALECTS[control].read(result.text)
    assert not _cycles(program)
    assert cycle_moves(program).sum() > 20
    check = verify(program, machine(), job())
    assert check.ok, check.summary()
    moves = program.move_table()
    for (x, y), (_top, bottom, feed) in HOLES.items():
        here = (np.abs(moves.position[:, 0] - x) < 1e-6) & (np.abs(moves.position[:, 1] - y) < 1e-6)
        assert np.nanmin(moves.position[here, 2]) == pytest.approx(bottom, abs=1e-9)
        assert np.nanmax(moves.feed[here & ~moves.rapid]) == pytest.approx(feed)


@pytest.mark.parametrize("control", CONTROLS)
def test_machine_coordinates_drill_with_the_machine_z(control: str) -> None:
    result = posted(control, tcp=False)
    program = DIALECTS[control].read(result.text)
    assert [c.kind for c in _cycles(program)] == ["drill", "deep", "tap"]
    length = result.program.tool_length
    assert verify(program, machine(), job(), tool_length=length).ok


def _deepened(control: str, text: str) -> str:
    """The program with the first cycle's bottom 0.5 mm deeper."""
    patterns = {
        "heidenhain": (r"Q201=-6\.000", "Q201=-6.500"),
        "siemens": (r"(MCALL CYCLE82\([^,]*,[^,]*,[^,]*,)-6\.000", r"\g<1>-6.500"),
        "fanuc": (r"(G82 X10\.000 Y10\.000 )Z-6\.000", r"\g<1>Z-6.500"),
        "linuxcnc": (r"(G82 X10\.000 Y10\.000 )Z-6\.000", r"\g<1>Z-6.500"),
    }
    pattern, replacement = patterns[control]
    changed, count = re.subn(pattern, replacement, text)
    assert count == 1
    return changed


@pytest.mark.parametrize("control", CONTROLS)
def test_a_wrong_depth_fails_verification(control: str) -> None:
    text = _deepened(control, posted(control).text)
    check = verify(DIALECTS[control].read(text), machine(), job())
    assert not check.ok
    assert check.worst_cl_line == 10
    assert "beyond tolerance: CL lines 10 11" in " ".join(check.notes)


def test_a_missing_hole_fails_verification() -> None:
    text = posted("fanuc").text.replace("X30.000 Y10.000\nG80", "G80", 1)
    check = verify(DIALECTS["fanuc"].read(text), machine(), job())
    assert not check.ok
    assert 11 in check.missed_lines


def test_a_cycle_the_control_lacks_is_expanded_with_a_warning() -> None:
    text = drilling_job().replace("CLEAR,3", "CLEAR,3,DWELL,1")  # G83 takes no dwell
    result = post(read_cl_text(text, source="d.apt"), machine(), PostOptions(controller="fanuc"))
    assert result.report.warnings == (
        "d.apt:13: CYCLE deep: the control has no deep cycle with a dwell at the bottom; its "
        "holes are written as their motion",
    )
    assert "G83" not in result.text and "G4 X1." in result.text


@pytest.mark.parametrize("control", CONTROLS)
def test_tilted_hole_in_tcp_is_a_cycle_in_a_tilted_plane(control: str) -> None:
    toolpath = job(tilted=True)
    result = post(toolpath, machine(), PostOptions(controller=control))
    program = DIALECTS[control].read(result.text)
    has_plane = DIALECTS[control].spec.plane_convention is not None
    if has_plane:  # drilled along the plane's Z by the control's own cycle
        assert not result.report.warnings
        assert [c.kind for c in _cycles(program)] == ["drill", "deep", "tap", "drill"]
        assert plane_count(program) == 1
    else:  # LinuxCNC: no tilted plane, the hole as its motion
        (warning,) = result.report.warnings
        assert warning.startswith("drill.apt:22: CYCLE drill: the hole at line 23 has its tool")
        assert [c.kind for c in _cycles(program)] == ["drill", "deep", "tap"]
    assert verify(program, machine(), toolpath).ok


@pytest.mark.parametrize("control", CONTROLS)
def test_tilted_hole_without_planes_is_expanded_with_a_warning(control: str) -> None:
    toolpath = job(tilted=True)
    result = post(toolpath, machine(), PostOptions(controller=control, tilted_planes=False))
    (warning,) = result.report.warnings
    assert warning.startswith("drill.apt:22: CYCLE drill: the hole at line 23 has its tool axis")
    program = DIALECTS[control].read(result.text)
    assert [c.kind for c in _cycles(program)] == ["drill", "deep", "tap"]
    assert plane_count(program) == 0
    assert verify(program, machine(), toolpath).ok
    # in machine coordinates the table tilts the hole under the spindle: a cycle again
    result = post(toolpath, machine(), PostOptions(controller=control, tcp=False))
    assert not result.report.warnings
    program = DIALECTS[control].read(result.text)
    assert [c.kind for c in _cycles(program)] == ["drill", "deep", "tap", "drill"]
    assert plane_count(program) == 0
    length = result.program.tool_length
    assert verify(program, machine(), toolpath, tool_length=length).ok


def test_expand_cycles_of_a_read_program_is_the_written_expansion() -> None:
    native = DIALECTS["linuxcnc"].read(posted("linuxcnc").text)
    expanded = expand_cycles(native)
    assert not _cycles(expanded) and cycle_moves(expanded).any()
    assert expand_cycles(expanded) is expanded


# -- LinuxCNC runs the cycles ----------------------------------------------------------------------


@pytest.mark.parametrize("expand", [False, True], ids=["native", "expanded"])
def test_rs274_drills_the_hole_bottoms_at_the_cycle_feeds(expand: bool, tmp_path: Path) -> None:
    result = posted("linuxcnc", expand)
    run = run_rs274(result.text, {3: 0.0}, tmp_path)
    feed = math.nan
    bottoms: dict[tuple[float, float], float] = {}
    feeds: dict[tuple[float, float], set[float]] = {}
    for call in run.calls:
        if call.name == "SET_FEED_RATE":
            feed = float(call.args[0])
        elif call.name == "STRAIGHT_FEED":
            x, y, z = (float(v) for v in call.args[:3])
            key = (round(x, 3), round(y, 3))
            bottoms[key] = min(bottoms.get(key, math.inf), z)
            feeds.setdefault(key, set()).add(feed)
    assert set(bottoms) == set(HOLES)
    for key, (_top, bottom, rate) in HOLES.items():
        assert bottoms[key] == pytest.approx(bottom, abs=5e-4), key
        assert feeds[key] == {rate}, key
    dwells = [c for c in run.calls if c.name == "DWELL"]
    assert len([d for d in dwells if float(d.args[0]) == 0.5]) >= 2  # the drill's, per hole


# -- every kind on every control -------------------------------------------------------------

#: Cycles of every kind the controls run (kind, step, dwell), at two holes 2 mm below zero.
KINDS = [
    ("drill", 0.0, 0.0),
    ("drill", 0.0, 1.5),
    ("deep", 4.0, 0.0),
    ("chipbreak", 3.0, 0.0),
    ("tap", 0.0, 0.0),
    ("bore", 0.0, 0.0),
    ("bore", 0.0, 0.5),
]


def _kind_program(kind: str, step: float, dwell: float, units: str = "mm") -> Program:
    holes = ((10.0, 5.0, -2.0, 0.0, 0.0), (-20.0, 5.0, -2.0, 0.0, 0.0))
    cycle = Cycle(kind, 11.0, 600.0, 2.5, 7.5, holes, step=step, dwell=dwell)
    above = (10.0, 5.0, 5.5, 0.0, 0.0)
    from urdfpost.program import Move, Tcp, ToolChange

    blocks = (ToolChange(2), Spindle("cw", 800.0), Tcp(True), Move(True, above), cycle, Tcp(False))
    return Program("KINDS", ("X", "Y", "Z", "B", "C"), frozenset("BC"), units, True, blocks)


def _bottoms(program: Program) -> list[tuple[float, float, float, float]]:
    """(x, y, deepest z, feed) of the feed moves of each hole of the program's expansion."""
    table = expand_cycles(program).move_table()
    out = []
    for x in (10.0, -20.0):
        here = (np.abs(table.position[:, 0] - x) < 0.01) & ~table.rapid
        out.append((x, 5.0, float(table.position[here, 2].min()), float(table.feed[here].max())))
    return out


@pytest.mark.parametrize("units", ["mm", "inch"])
@pytest.mark.parametrize(("kind", "step", "dwell"), KINDS)
@pytest.mark.parametrize("control", CONTROLS)
def test_every_kind_reads_back(
    control: str, kind: str, step: float, dwell: float, units: str
) -> None:
    spec = DIALECTS[control].spec
    program = _kind_program(kind, step, dwell, units)
    if not spec.runs_cycle(kind, dwell):
        with pytest.raises(Exception, match="dwell"):
            DIALECTS[control].write(program)
        return
    text = DIALECTS[control].write(program)
    back = DIALECTS[control].read(text)
    (cycle,) = _cycles(back)
    assert (cycle.kind, cycle.dwell) == (kind, dwell)
    tol = 0.0013 if units == "inch" else 1e-9  # (inch: four decimals, half a unit off)
    assert cycle.step == pytest.approx(step, abs=tol)
    for got, want in zip(_bottoms(back), _bottoms(program), strict=True):
        assert got[2] == pytest.approx(want[2], abs=tol)
        assert got[3] == pytest.approx(want[3], rel=1e-3)
    if control in ("heidenhain", "siemens"):  # the hole top and both heights are written
        written = _cycles(program)[0]
        assert cycle.clearance == pytest.approx(written.clearance, abs=tol)
        assert cycle.retract == pytest.approx(written.retract, abs=2 * tol)  # (RTP - RFP)
        assert cycle.holes[0][2] == pytest.approx(written.holes[0][2], abs=tol)


@pytest.mark.parametrize(
    ("kind", "step", "dwell"), [k for k in KINDS if k not in (("tap", 0, 0), ("bore", 0, 0.5))]
)
def test_rs274_runs_every_iso_kind_as_expanded(
    kind: str, step: float, dwell: float, tmp_path: Path
) -> None:
    """LinuxCNC's interpreter runs each cycle through the same points as its expansion (feeds
    and traverses, row for row). Not G84 and G89: LinuxCNC feeds them out to the initial plane,
    the expansion (as Fanuc) to the R plane and then at rapid; the cut is the same."""
    program = _kind_program(kind, step, dwell)
    text = DIALECTS["linuxcnc"].write(program)
    run = run_rs274(text, {2: 0.0}, tmp_path)
    moves = [c for c in run.calls if c.name in ("STRAIGHT_FEED", "STRAIGHT_TRAVERSE")]
    ran = [
        (c.name == "STRAIGHT_TRAVERSE", *(round(float(v), 3) for v in c.args[:3])) for c in moves
    ]
    table = expand_cycles(DIALECTS["linuxcnc"].read(text)).move_table()
    expanded = [
        (bool(r), *(round(float(v), 3) for v in p[:3]))
        for r, p in zip(table.rapid, table.position, strict=True)
    ]
    # a block to where the tool stands is no motion (rs274 repeats the initial plane)
    ran = [m for k, m in enumerate(ran) if k == 0 or m[1:] != ran[k - 1][1:]]
    expanded = [m for k, m in enumerate(expanded) if k == 0 or m[1:] != expanded[k - 1][1:]]
    assert ran == expanded
    dwells = [float(c.args[0]) for c in run.calls if c.name == "DWELL"]
    assert dwells == ([dwell, dwell] if dwell else [])


def test_streamed_post_refuses_cycles(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from urdfpost.cli import main

    cl = tmp_path / "drill.apt"
    cl.write_text(drilling_job())
    out = tmp_path / "drill.nc"
    args = ["post", str(cl), "-m", "dmu50", "-c", "fanuc", "-o", str(out), "--piece-points", "2"]
    assert main([*args, "-q"]) == 1
    assert "drill.apt:9: canned cycles (CYCLE records) are not posted in pieces" in (
        capsys.readouterr().err
    )
    assert not out.exists()
    assert main(["post", str(cl), "-m", "dmu50", "-c", "fanuc", "-o", str(out), "-q"]) == 0
    assert "G98 G82" in out.read_text()
    assert main([*args[:-2], "--expand-cycles", "-q"]) == 0
    assert "G82" not in out.read_text() and "G4 X0.5" in out.read_text()


@pytest.mark.parametrize(
    ("control", "lines", "match"),
    [
        ("fanuc", ["G0 X0. Y0. Z10.", "G98 G81 X1. Y1. Z-5. F100."], r":3: G81 without Z and R"),
        ("fanuc", ["G0 X0. Y0. Z10.", "G98 G83 X1. Y1. Z-5. R2. F100."], r":3: G83 without a peck"),
        ("linuxcnc", ["G98 G81 X1 Y1 Z-5 R2 F100"], r":2: G81 from an unknown Z"),
        ("siemens", ["G0 X0 Y0 Z10", "F100", "MCALL CYCLE81(10,0,2)"], r":4: CYCLE81: expected DP"),
        ("siemens", ["G0 X0 Y0 Z10", "MCALL CYCLE99(10,0,2,-5)"], r":3: unknown modal call"),
        ("heidenhain", ["1 L X+1 Y+1 FMAX M99"], r":2: M99 / CYCL CALL with no cycle defined"),
        (
            "heidenhain",
            ["1 CYCL DEF 200 DRILLING ~", "  Q200=+2 ;SET-UP CLEARANCE ~", "  Q206=+100 ;FEED"],
            r":4: CYCL DEF 200: expected Q201",
        ),
        ("heidenhain", ["1 CYCL DEF 200 DRILLING ~", "2 L X+1 FMAX"], r":3: expected Q parameter"),
    ],
)
def test_bad_cycles_in_programs_name_the_line(control: str, lines: list[str], match: str) -> None:
    head = {"heidenhain": "0 BEGIN PGM P MM", "fanuc": "G21", "linuxcnc": "G21", "siemens": "G710"}
    text = "\n".join([head[control], *lines]) + "\n"
    with pytest.raises(ProgramParseError, match=match):
        DIALECTS[control].read(text, path="p.nc")


# -- the holes' motion: travel and collisions -------------------------------------------------


def _one_hole(depth: float, top: float = 60.0) -> str:
    return (
        "UNITS/MM\nMULTAX/ON\nLOADTL/1\nSPINDL/RPM,1000,CLW\nRAPID\nGOTO/0,0,100,0,0,1\n"
        f"CYCLE/DRILL,FEDTO,{depth:g},MMPM,100,RAPTO,2,RTRCTO,5\nGOTO/0,0,{top:g},0,0,1\n"
        "CYCLE/OFF\nRAPID\nGOTO/0,0,100,0,0,1\nFINI\n"
    )


def test_a_hole_bottom_beyond_the_travel_is_refused() -> None:
    from urdfpost.errors import LinearTravelError

    toolpath = read_cl_text(_one_hole(900), source="deep.apt")
    with pytest.raises(LinearTravelError, match=r"deep.apt:8: the hole's bottom needs Z"):
        post(toolpath, machine(), PostOptions(controller="fanuc"))


def test_the_holder_drilled_into_the_stock_collides(tmp_path: Path) -> None:
    """The collision check follows the hole's motion to its bottom: a shallow hole cuts the
    stock with the cutter only, a deep one takes the shank into it, one below the program
    zero (the fixture plate's top) drills the fixture; the CL points, the hole tops, are clear
    either way."""
    import trimesh

    from urdfpost.errors import CollisionError

    mesh = trimesh.creation.box(extents=(80.0, 80.0, 60.0))  # on the fixture plate
    mesh.apply_translation((0.0, 0.0, 30.0))
    stock = tmp_path / "block.stl"
    mesh.export(stock)
    options = PostOptions(controller="fanuc", stock=str(stock))
    shallow = post(read_cl_text(_one_hole(6), source="a.apt"), machine(), options)
    assert "G98 G81" in shallow.text
    with pytest.raises(CollisionError, match=r"a.apt:8: .*(shank|holder) with stock"):
        post(read_cl_text(_one_hole(55), source="a.apt"), machine(), options)
    bare = PostOptions(controller="fanuc", collisions=True)  # (no stock)
    with pytest.raises(CollisionError, match=r"a.apt:8: .*cutter with fixture_plate"):
        post(read_cl_text(_one_hole(3, top=0), source="a.apt"), machine(), bare)
