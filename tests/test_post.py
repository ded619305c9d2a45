"""End-to-end posting: golden programs on three machine families, the real NX files, units.

The golden job (``tests/golden/post/short_job.apt``, 16 CL points) has a tool change, spindle,
coolant, a rapid approach with a vertical tool, a tilted five-axis feed pass whose tool axis
swings from 30 deg one side through 2 deg from vertical to 30 deg the other side (a near-pole
crossing), a feed retract and GOHOME. It is posted for every control, with TCP and in machine
coordinates, on a table-table (dmu50), a head-head (gantry-ca) and a head-table (monoblock)
machine, and compared with ``tests/golden/post/<machine>_<control>_<tcp|mc>.<ext>``.

Regenerate the golden files after an intended output change with
``URDFPOST_REGEN_GOLDEN=1 pytest tests/test_post.py`` and read the diff.
"""

from __future__ import annotations

import difflib
import functools
import math
import os
import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from conftest import shared_cl

from urdfpost import load_machine
from urdfpost.dialects import DIALECTS
from urdfpost.kinematics.forward import tip_and_axis
from urdfpost.machine import Machine
from urdfpost.posting.options import PostOptions
from urdfpost.posting.whole import PostResult, post
from urdfpost.program import Move, MoveTable, Program, TiltedPlane, untilted
from urdfpost.readers import read_cl, read_cl_text
from urdfpost.toolpath import Toolpath

GOLDEN = Path(__file__).parent / "golden" / "post"
JOB = GOLDEN / "short_job.apt"
REGEN = os.environ.get("URDFPOST_REGEN_GOLDEN") == "1"

MACHINES = ("dmu50", "gantry-ca", "monoblock")  # table-table, head-head, head-table
CONTROLLERS = ("heidenhain", "siemens", "fanuc", "linuxcnc")
MODES = {"tcp": True, "mc": False}
CASES = [(m, c, mode) for m in MACHINES for c in CONTROLLERS for mode in MODES]

MM_PER_INCH = 25.4
INCH_TOL_MM = 0.0004 * MM_PER_INCH

#: Lines that mark the structure of a program, per control (block numbers stripped).
MARKERS = {
    "heidenhain": {
        "tool": r"^TOOL CALL 5 Z\b",
        "on": r"^FUNCTION TCPM\b",
        "off": r"^FUNCTION RESET TCPM$",
        "home": r"\bM91\b",
        "end": r"^END PGM GOLDEN_SHORT MM$",
        "spindle": r"\bM3$",
        "coolant": r"^M8$",
        "spindle_off": r"^M5$",
        "coolant_off": r"^M9$",
    },
    "siemens": {
        "tool": r"^T5\b",
        "on": r"^TRAORI$",
        "off": r"^TRAFOOF$",
        "home": r"^G75\b",
        "end": r"^M30$",
        "spindle": r"^S8000 M3$",
        "coolant": r"^M8$",
        "spindle_off": r"^M5$",
        "coolant_off": r"^M9$",
    },
    "fanuc": {
        "tool": r"^T5 M6$",
        "on": r"^G43\.4 H5$",
        "off": r"^G49$",
        "home": r"^G28\b",
        "end": r"^M30$",
        "spindle": r"^S8000 M3$",
        "coolant": r"^M8$",
        "spindle_off": r"^M5$",
        "coolant_off": r"^M9$",
    },
    "linuxcnc": {
        "tool": r"^T5 M6$",
        "on": r"^M428$",
        "off": r"^M429$",
        "home": r"^G28\b",
        "end": r"^M2$",
        "spindle": r"^S8000 M3$",
        "coolant": r"^M8$",
        "spindle_off": r"^M5$",
        "coolant_off": r"^M9$",
    },
}

#: Units line of an inch / mm program, per control.
UNITS_LINE = {
    "heidenhain": {"inch": r"^BEGIN PGM \w+ INCH$", "mm": r"^BEGIN PGM \w+ MM$"},
    "siemens": {"inch": r"^G700$", "mm": r"^G710$"},
    "fanuc": {"inch": r"^G20$", "mm": r"^G21$"},
    "linuxcnc": {"inch": r"^G20$", "mm": r"^G21$"},
}

_HOME_WORDS = ("M91", "G28", "G75", "G53", "SUPA")
_AXIS_WORD = re.compile(r"(?<![A-Z0-9_=])([XYZABC])([-+]?\d*\.?\d+)")


# --------------------------------------------------------------------------------------------
# helpers (also used by test_verify.py and test_cli.py through plain copies of the idea)


def code_body(line: str) -> str:
    """A program line without its block number (``12 L ...``, ``N10 G1 ...``)."""
    return re.sub(r"^(?:N?\d+\s+)", "", line.strip())


def is_comment(body: str) -> bool:
    return not body or body.startswith((";", "(", "%"))


def motion_lines(text: str) -> list[int]:
    """Indices of the lines of ``text`` that are motion blocks (home moves excluded)."""
    out = []
    for i, line in enumerate(text.splitlines()):
        body = code_body(line)
        if is_comment(body) or any(w in body.split() for w in _HOME_WORDS):
            continue
        if _AXIS_WORD.search(body):
            out.append(i)
    return out


def first_index(lines: list[str], pattern: str, after: int = -1) -> int:
    hits = [i for i, line in enumerate(lines) if i > after and re.search(pattern, code_body(line))]
    assert hits, f"no line after {after} matches {pattern!r}"
    return hits[0]


def last_index(lines: list[str], pattern: str) -> int:
    hits = [i for i, line in enumerate(lines) if re.search(pattern, code_body(line))]
    assert hits, f"no line matches {pattern!r}"
    return hits[-1]


def has_line(lines: list[str], pattern: str) -> bool:
    return any(re.search(pattern, code_body(line)) for line in lines)


@functools.cache
def machine(name: str) -> Machine:
    return load_machine(name)


@functools.cache
def job() -> Toolpath:
    return read_cl(JOB)


@functools.cache
def posted(machine_name: str, controller: str, tcp: bool) -> PostResult:
    return post(
        job(),
        machine(machine_name),
        PostOptions(strategy="recursive", controller=controller, tcp=tcp),
    )


def golden_path(machine_name: str, controller: str, mode: str) -> Path:
    ext = DIALECTS[controller].extensions[0]
    return GOLDEN / f"{machine_name}_{controller}_{mode}{ext}"


def readback(result: PostResult, controller: str) -> Program:
    return DIALECTS[controller].read(result.text, path=f"<{controller}>")


def filled_positions(program: Program) -> np.ndarray:
    """Move positions (program axis order, mm and deg) with modal values filled forward
    (NaN where an axis is not programmed yet)."""
    pos = np.array([mv.position for mv in program.moves()], dtype=float)
    for c in range(pos.shape[1]):
        col = pos[:, c]
        idx = np.maximum.accumulate(np.where(np.isnan(col), -1, np.arange(len(col))))
        pos[:, c] = np.where(idx >= 0, col[np.maximum(idx, 0)], np.nan)
    return pos


def check_reaches_cl_points(
    m: Machine,
    program: Program,
    readback_program: Program,
    toolpath: Toolpath,
    tip_tol: float,
    axis_tol_deg: float,
) -> None:
    """Every move that carries a CL line reaches that CL point, through the numpy forward
    kinematics (not the Pinocchio route verify uses), from the positions read back from text."""
    moves, back = program.moves(), readback_program.moves()
    assert len(moves) == len(back)
    assert [mv.rapid for mv in moves] == [b.rapid for b in back]
    cols = [m.axis_names.index(a) for a in readback_program.axes]
    rotary = [a in readback_program.rotary for a in readback_program.axes]
    q = np.tile(m.home, (len(back), 1))
    pos = filled_positions(readback_program)
    pos = np.where(rotary, np.radians(pos), pos)
    q[:, cols] = np.where(np.isnan(pos), q[:, cols], pos)
    if program.tcp:
        q0 = q.copy()
        q0[:, list(m.linear_columns)] = 0.0
        _, axis = tip_and_axis(m, q0, 0.0)
        tip = q[:, list(m.linear_columns)]
    else:
        tip, axis = tip_and_axis(m, q, program.tool_length)
    line_to_index = {int(line): i for i, line in enumerate(toolpath.line)}
    reached = []
    for k, mv in enumerate(moves):
        if mv.cl_line is None:
            continue
        j = line_to_index[mv.cl_line]
        reached.append(j)
        d = float(np.linalg.norm(tip[k] - toolpath.tip[j]))
        a = math.degrees(math.acos(min(1.0, float(np.dot(axis[k], toolpath.axis[j])))))
        assert d <= tip_tol, f"move {k} (CL line {mv.cl_line}): tip off by {d:.5f} mm"
        assert a <= axis_tol_deg, f"move {k} (CL line {mv.cl_line}): axis off by {a:.5f} deg"
    assert reached == list(range(len(toolpath))), "each CL point reached once, in order"


# --------------------------------------------------------------------------------------------
# golden programs


def test_golden_job_is_short_and_reachable() -> None:
    tp = job()
    assert 15 <= len(tp) <= 25
    kinds = [e.kind for e in tp.events]
    for kind in ("tool", "spindle", "coolant", "home"):
        assert kind in kinds
    # the pass crosses near the vertical: 2 deg from +Z at its middle, 30 deg at its ends
    tilt = np.degrees(np.arccos(np.clip(tp.axis[:, 2], -1, 1)))
    assert tilt.max() == pytest.approx(30.06, abs=0.01)
    assert tilt[2:-1].min() == pytest.approx(2.0, abs=1e-3)


@pytest.mark.parametrize(("machine_name", "controller", "mode"), CASES)
def test_golden_program(machine_name: str, controller: str, mode: str) -> None:
    result = posted(machine_name, controller, MODES[mode])
    path = golden_path(machine_name, controller, mode)
    if REGEN:
        path.write_text(result.text, encoding="utf-8", newline="\n")
    assert path.is_file(), f"{path} missing: run with URDFPOST_REGEN_GOLDEN=1"
    expected = path.read_text(encoding="utf-8")
    if result.text != expected:
        diff = "".join(
            list(
                difflib.unified_diff(
                    expected.splitlines(True),
                    result.text.splitlines(True),
                    str(path),
                    "posted",
                )
            )[:60]
        )
        pytest.fail(f"posted program differs from {path.name}:\n{diff}")

    v = result.verification
    assert v.ok
    assert v.cl_points == v.reached == len(job()) == 16
    assert v.missed_lines == []
    assert v.max_tip_deviation <= v.tip_tolerance == 0.01
    assert v.max_orientation_deviation_deg <= 0.5
    r = result.report.as_json()
    assert r["machine"] == machine_name
    assert r["controller"] == controller
    assert r["tcp"] is MODES[mode]
    assert r["units"] == "mm"
    assert r["verified"] is True
    assert r["cl_points"] == r["cl_points_reached"] == 16
    assert r["cl_lines_missed"] == []
    assert r["blocks"] == len(result.program.moves())
    # the only warning: feeds reduced to the axes' velocity limits (the job turns C fast
    # near the pole), with the figures of the report
    feeds = r["feeds"]
    reduced = [w for w in r["warnings"] if "feed reduced on" in w]
    assert r["warnings"] == reduced
    assert len(reduced) == (1 if feeds["capped_blocks"] else 0)
    if reduced:
        assert f"feed reduced on {feeds['capped_blocks']} blocks" in reduced[0]
        assert f"at CL line {feeds['worst_cl_line']}" in reduced[0]
    check = r["feed_check"]
    assert check["ok"] and check["max_deviation_pct"] <= 1.0 and check["max_axis_share"] <= 1.0
    assert check["capped"] == feeds["capped_blocks"]
    # the post's own moves: rotaries to the first orientation, above the first point as high
    # as the travel allows, the approach point, and rotaries home at the end
    transitions = 4
    assert sum(mv.cl_line is None for mv in result.program.moves()) >= transitions
    if MODES[mode]:
        # only the pole turn and the two blocks either side of the near-pole point are added
        assert r["blocks"] == 19 + transitions
    else:
        # machine coordinates: the swing of the rotary axes near the pole is subdivided
        assert r["blocks"] > 100
        assert r["inserted_blocks"] == r["blocks"] - 16 - r["pole_turns"] - transitions


@pytest.mark.parametrize(("machine_name", "controller", "mode"), CASES)
def test_golden_program_structure(machine_name: str, controller: str, mode: str) -> None:
    """What a reader checks by eye: tool call, spindle and coolant, TCP on before the first
    move, TCP off before going home, end of program last, modal axis words, travel limits,
    and every CL point reached by the positions as written."""
    tcp = MODES[mode]
    m = machine(machine_name)
    result = posted(machine_name, controller, tcp)
    lines = result.text.splitlines()
    marks = MARKERS[controller]
    moves = motion_lines(result.text)
    program_moves = result.program.moves()
    assert len(moves) == len(program_moves)
    # the CL moves; the post's own (approach, rotaries home at the end) have no CL line
    cl_moves = [i for i, mv in zip(moves, program_moves, strict=True) if mv.cl_line is not None]
    first, last = cl_moves[0], cl_moves[-1]
    end = len(lines) - 1

    assert has_line(lines, UNITS_LINE[controller]["mm"])
    assert first_index(lines, marks["tool"]) < first
    for key in ("spindle", "coolant"):
        assert first_index(lines, marks[key]) < first, key
    # the spindle and coolant stop after the last cut (as the CL says), and before the end
    for key in ("spindle_off", "coolant_off"):
        assert last < last_index(lines, marks[key]) < end, key
    home = first_index(lines, marks["home"], after=last)
    code = [code_body(x) for x in lines if not is_comment(code_body(x))]
    assert re.search(marks["end"], code[-1]), code[-1]
    if tcp:
        on, off = first_index(lines, marks["on"]), first_index(lines, marks["off"], after=last)
        assert first_index(lines, marks["tool"]) < on < first
        assert last < off < home
        assert not re.search(r"tool table length must be 0", result.text, re.I)
    else:
        assert not has_line(lines, marks["on"])
        assert re.search(r"tool table length must be 0", result.text, re.I)
    # the table or head back to zero after the last cut, with the tool up
    rotary = [a.name for a in m.rotary]
    back_home = [i for i in moves if i > home and all(f"{a}" in lines[i] for a in rotary)]
    assert back_home, "no move of the rotary axes home after the last cut"

    # modal axis words: no word repeats the value the axis already has
    # (a mode change, a home return, a machine-coordinate move or a tool change makes the
    # next move state its axes again)
    modal: dict[str, float] = {}
    resets = {
        i
        for i, line in enumerate(lines)
        if i not in moves
        and (
            any(re.search(marks[k], code_body(line)) for k in ("on", "off", "home", "tool"))
            or any(w in code_body(line).split() for w in _HOME_WORDS)
        )
    }
    for i in range(len(lines)):
        if i in resets:
            modal.clear()
        if i not in moves:
            continue
        for address, value in _AXIS_WORD.findall(code_body(lines[i])):
            assert modal.get(address) != float(value), f"line {i}: {address} repeated"
            modal[address] = float(value)

    back = readback(result, controller)
    assert back.tcp is tcp
    assert back.units == "mm"
    # travel: rotary axes always, linear axes when they are machine positions
    pos = np.array([b.position for b in back.moves()], dtype=float)
    for j, name in enumerate(back.axes):
        a = m.axes[m.axis_names.index(name)]
        if a.rotary and a.continuous:
            continue
        if not a.rotary and tcp:
            continue
        lo, hi = (math.degrees(a.lower), math.degrees(a.upper)) if a.rotary else (a.lower, a.upper)
        values = pos[:, j][~np.isnan(pos[:, j])]
        assert values.min() >= lo - 1e-6 and values.max() <= hi + 1e-6, name
    # rounding: 0.001 mm, and 0.0001 deg at up to ~0.6 m from a rotary axis
    check_reaches_cl_points(m, result.program, back, job(), tip_tol=0.003, axis_tol_deg=0.001)


def test_golden_signs_and_values_by_eye() -> None:
    """A few values read off the golden programs and checked against what the machine
    geometry says they must be."""
    # TCP programs write the CL tip itself: the first feed point of the pass
    fanuc = posted("dmu50", "fanuc", True).text
    assert "\nG1 X-18.000 Y-4.000 Z3.648 F600.\n" in fanuc
    heid = posted("dmu50", "heidenhain", True).text
    assert re.search(r"^\d+ L X-18\.000 Y-4\.000 Z\+3\.648 F600$", heid, re.M)
    # C turns in place at the vertical approach point (RAPID in the CL: FMAX, G0)
    # after the approach from above (TCP on: every axis stated again); the turn before the
    # next RAPID is rapid too
    assert "\nZ70.000\nZ60.000 B0.0000 C0.0000\nC176.0049\nX-15.502" in fanuc
    # tilt 30.06 deg at the ends of the pass (table cradle B is positive only on dmu50: -5..110)
    assert "B+30.0604" in heid
    # monoblock swivel head tilts negative (B -120..30, preferred B-), gantry fork A negative
    assert "B-30.0604" in posted("monoblock", "linuxcnc", True).text
    assert "A-30.0604" in posted("gantry-ca", "siemens", True).text
    # at the near-pole point (tool axis (0, sin 2deg, cos 2deg)) the tilt is exactly 2 deg
    for m, ctl, word in (
        ("dmu50", "fanuc", "B2.0000"),
        ("monoblock", "fanuc", "B-2.0000"),
        ("gantry-ca", "fanuc", "A-2.0000"),
    ):
        assert re.search(rf"^X0\.000 Z3\.000 {word} C", posted(m, ctl, True).text, re.M), m


def test_golden_files_are_all_used() -> None:
    expected = {golden_path(*case).name for case in CASES} | {JOB.name}
    present = {p.name for p in GOLDEN.iterdir() if p.is_file()}
    assert present == expected


def test_every_feed_move_has_a_feed() -> None:
    """Every feed move has a feed in force: the in-place pole turn at the rapid approach point,
    before any FEDRAT, moves at the feed of the move that follows (controls alarm on G1 with
    no feed programmed; was a bug before 2bd2324)."""
    bad = []
    for machine_name, controller, mode in CASES:
        feed = None
        for k, mv in enumerate(posted(machine_name, controller, MODES[mode]).program.moves()):
            if mv.rapid:
                continue
            feed = mv.feed if mv.feed is not None else feed
            if feed is None:
                bad.append(f"{machine_name} {controller} {mode}: move {k} {mv.position}")
                break
    assert not bad, "feed moves before any feed was programmed:\n" + "\n".join(bad)


# --------------------------------------------------------------------------------------------
# real NX files on the UMC-750 (inch, Fanuc)


def _post_real(name: str, tcp: bool) -> tuple[Toolpath, PostResult]:
    m = machine("umc750")
    tp = read_cl(shared_cl(name), units=m.settings.units, chord_tolerance=INCH_TOL_MM)
    # the file starts no spindle: the job gives one (as --spindle); its arcs as lines, every
    # CL point a block (the arcs themselves: tests/test_arcs.py)
    options = PostOptions(strategy="recursive", tcp=tcp, spindle=8000.0, arcs=False)
    return tp, post(tp, m, options)


def in_planes(program: Program) -> np.ndarray:
    """Which moves of ``program`` are in a tilted working plane, shape (N,), bool."""
    flags: list[np.ndarray] = []
    inside = False
    for part in program.parts:
        if isinstance(part, TiltedPlane):
            inside = part.angles is not None
        elif isinstance(part, MoveTable):
            flags.append(np.full(len(part), inside))
        elif isinstance(part, Move):
            flags.append(np.array([inside]))
    return np.concatenate(flags) if flags else np.zeros(0, dtype=bool)


def _check_real(tp: Toolpath, result: PostResult, tcp: bool) -> None:
    v = result.verification
    assert tp.units == "inch"
    assert v.ok, v.summary("inch")
    assert v.cl_points == v.reached == len(tp)
    assert v.missed_lines == []
    assert v.max_tip_deviation <= INCH_TOL_MM
    assert v.tip_tolerance == pytest.approx(INCH_TOL_MM)
    assert v.max_orientation_deviation_deg <= 0.5
    r = result.report.as_json()
    assert r["units"] == "inch"
    assert r["controller"] == "fanuc"
    assert r["max_tip_deviation"] <= 0.0004
    assert r["tip_tolerance"] == pytest.approx(0.0004)
    lines = result.text.splitlines()
    assert has_line(lines, r"^G20$")
    assert not has_line(lines, r"^G21$")
    assert has_line(lines, r"^G43\.4 H\d+$") is tcp
    back = DIALECTS["fanuc"].read(result.text, path="<fanuc>")
    assert back.units == "inch"
    if tcp:
        # a TCP program only carries the rounding of its 4 decimals (0.00005 in per axis)
        assert v.max_tip_deviation <= math.sqrt(3) * 0.00005 * MM_PER_INCH + 1e-9
        # every CL point is written, converted to inch, within rounding
        on_cl = [k for k, mv in enumerate(result.program.moves()) if mv.cl_line is not None]
        assert len(on_cl) == len(tp)
        xyz = filled_positions(untilted(back))[on_cl, :3]  # (3+2 operations: in planes)
        err = np.abs(xyz - tp.tip) / MM_PER_INCH
        # in a tilted plane the rounding is the plane's axes': within sqrt(3) of it in all
        planar = in_planes(back)[on_cl]
        assert planar.sum() == 0 if not result.report.as_json()["tilted_planes"] else planar.any()
        assert err[~planar].max() <= 0.00005 + 1e-9
        if planar.any():
            assert np.linalg.norm(err[planar], axis=1).max() <= math.sqrt(3) * 0.00005 + 1e-9


def test_nx_ballmill_first_goto_in_tcp_program() -> None:
    tp, result = _post_real("nx_variable_axis_ballmill_inch.cls", True)
    # GOTO/-4.2721,-3.0148,3.0000 in the MCS, as written: MSYS (3, 3, 0) in says where the
    # MCS lies in the part and moves no point (NX's own post writes X-4.2721 Y-3.0148)
    first = tp.tip[0] / MM_PER_INCH
    assert first == pytest.approx([-4.2721, -3.0148, 3.0], abs=1e-9)
    # approached from above along the tool axis, then the point itself
    lines = result.text.splitlines()
    at = [k for k, x in enumerate(lines) if re.match(r"^X-4\.2721 Y-3\.0148 Z3\.0000 B", x)]
    assert at, "first GOTO not written as it is"
    assert re.match(r"^X-4\.\d{4} Y-3\.\d{4} Z3\.3\d{3}$", lines[at[0] - 1])  # 0.39 in above


@pytest.mark.parametrize("tcp", [True, False], ids=["tcp", "mc"])
def test_nx_ballmill_umc750(tcp: bool) -> None:
    tp, result = _post_real("nx_variable_axis_ballmill_inch.cls", tcp)
    assert len(tp) == 348
    _check_real(tp, result, tcp)
    # the file has no tool change: tool 1 is assumed, with a warning naming the file
    assert any("no tool change" in w for w in result.report.as_json()["warnings"])


@pytest.mark.slow
@pytest.mark.parametrize("tcp", [True, False], ids=["tcp", "mc"])
def test_nx_project2_umc750(tcp: bool) -> None:
    tp, result = _post_real("nx_project2_15ops_inch.cls", tcp)
    assert len(tp) >= 10585  # GOTO records, plus points interpolated on the 146 arcs
    _check_real(tp, result, tcp)
    # its side operations at B 82.875 deg, one per side and pass: in tilted planes with TCP
    assert result.report.as_json()["tilted_planes"] == (8 if tcp else 0)


# --------------------------------------------------------------------------------------------
# units

INCH_JOB = """\
PARTNO INCH JOB
UNITS/INCHES
MULTAX/ON
LOADTL/2
SPINDL/6000,CLW
RAPID
GOTO/1.0000,0.0000,1.0000,0.0000000,0.0000000,1.0000000
FEDRAT/IPM,20.0000
GOTO/1.0000,0.0000,0.5000
GOTO/0.5000,0.2500,0.5000,0.2588190,0.0000000,0.9659258
GOTO/-0.5000,0.2500,0.5000,0.0000000,0.2588190,0.9659258
GOTO/-1.0000,-1.0000,0.5000,0.0000000,0.0000000,1.0000000
GOHOME
FINI
"""


@pytest.mark.parametrize("controller", CONTROLLERS)
@pytest.mark.parametrize("tcp", [True, False], ids=["tcp", "mc"])
def test_inch_cl_gives_inch_program_and_report(controller: str, tcp: bool) -> None:
    tp = read_cl_text(INCH_JOB, source="inch.apt")
    assert tp.units == "inch"
    # dmu50 writes mm programs (its <urdfpost units="mm">): inch asked for
    options = PostOptions(strategy="recursive", controller=controller, tcp=tcp)
    assert post(tp, machine("dmu50"), options).program.units == "mm"
    result = post(tp, machine("dmu50"), replace(options, units="inch"))
    lines = result.text.splitlines()
    assert has_line(lines, UNITS_LINE[controller]["inch"])
    assert not has_line(lines, UNITS_LINE[controller]["mm"])
    back = readback(result, controller)
    assert back.units == "inch"
    r, v = result.report.as_json(), result.verification
    assert v.ok
    assert r["units"] == "inch"
    assert r["tip_tolerance"] == pytest.approx(0.0004)
    assert r["max_tip_deviation"] == pytest.approx(v.max_tip_deviation / MM_PER_INCH)
    assert r["mean_tip_deviation"] == pytest.approx(v.mean_tip_deviation / MM_PER_INCH)
    assert r["max_tip_deviation"] <= 0.0004
    assert r["tool_length_mm"] == pytest.approx(100.0)  # named in mm, stays in mm
    check_reaches_cl_points(
        machine("dmu50"), result.program, back, tp, tip_tol=0.003, axis_tol_deg=0.001
    )
    if tcp:
        # the first point written in inch, 4 decimals
        # (approached from 0.3937 in, 10 mm, above it)
        assert re.search(r"Z\+?1\.3937( FMAX)?\n(\d+ L )?Z\+?1\.0000", result.text)
        assert re.search(r"X\+?1\.0000 Y\+?0\.0000 Z\+?\d+\.\d{4}( FMAX)?\n", result.text)


def test_units_option_writes_a_mm_job_in_inch() -> None:
    result = post(
        job(), machine("dmu50"), PostOptions(strategy="recursive", controller="fanuc", units="inch")
    )
    assert has_line(result.text.splitlines(), r"^G20$")
    assert result.report.as_json()["units"] == "inch"
    assert result.report.as_json()["tip_tolerance"] == pytest.approx(0.0004)
    assert result.verification.ok
    # -18 mm written as inch
    assert "X-0.7087 Y-0.1575 Z0.1436" in result.text


# --------------------------------------------------------------------------------------------
# a feed move whose tool axis sweeps exactly through the pole between two CL points

POLE_CROSSING = """\
UNITS/MM
MULTAX/ON
LOADTL/1
SPINDL/10000,CLW
FEDRAT/MMPM,1000
GOTO/10.0000,5.0000,10.0000,0.2588190,0.0000000,0.9659258
GOTO/-10.0000,5.0000,10.0000,-0.2588190,0.0000000,0.9659258
FINI
"""


@pytest.mark.parametrize("machine_name", MACHINES)
def test_pole_crossing_between_cl_points_tcp(machine_name: str) -> None:
    tp = read_cl_text(POLE_CROSSING, source="pole.apt")
    result = post(
        tp, machine(machine_name), PostOptions(strategy="recursive", controller="fanuc", tcp=True)
    )
    assert result.verification.ok
    assert result.verification.max_orientation_deviation_deg <= 0.5


@pytest.mark.parametrize("machine_name", MACHINES)
def test_pole_crossing_between_cl_points_machine_coordinates(machine_name: str) -> None:
    tp = read_cl_text(POLE_CROSSING, source="pole.apt")
    # (failed with ToleranceError, 1.96 mm on dmu50, before the crossing point was inserted)
    result = post(
        tp, machine(machine_name), PostOptions(strategy="recursive", controller="fanuc", tcp=False)
    )
    v = result.verification
    assert v.ok
    assert v.reached == v.cl_points == 2
    assert v.max_tip_deviation <= 0.01


def test_the_package_api_is_the_functions_of_the_readme() -> None:
    """``from urdfpost import post`` is the post function (not a subpackage of that name),
    whatever modules were imported before."""
    import urdfpost
    import urdfpost.posting.stream
    import urdfpost.verification.match  # submodules imported first
    from urdfpost import PostOptions, PostResult, post, read_cl, verify

    assert callable(post) and post.__name__ == "post"
    assert urdfpost.post is post and urdfpost.posting.stream.post_stream
    assert urdfpost.verification.match.match_points
    assert PostOptions.__name__ == "PostOptions" and PostResult.__name__ == "PostResult"
    assert callable(read_cl) and callable(verify)
