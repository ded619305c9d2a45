"""Arcs: CIRCLE records written as G2/G3 (Heidenhain CC + C), read back and verified (issue 19).

The planar arc job of ``tests/jobs.py`` (:func:`jobs.arc_job`: arcs in the XY plane both ways,
a half circle in the ZX plane, a helix) is posted on the table-table machine for every control
and compared with ``tests/golden/arcs/dmu50_<control>.<ext>`` (regenerate with
``URDFPOST_REGEN_GOLDEN=1``); LinuxCNC's interpreter reads the LinuxCNC program (its ARC_FEED
calls are sampled as LinuxCNC defines them and compared with the CL points); a program whose arc
turns the wrong way or has its centre moved is refused by the verifier; the real NX
15-operation file's CIRCLE records come out as arcs.
"""

from __future__ import annotations

import difflib
import math
import os
import re
from pathlib import Path

import numpy as np
import pytest
from conftest import shared_cl
from jobs import arc_job, cutcom_job
from rs274 import run_rs274

from urdfpost import load_machine
from urdfpost.cli import main
from urdfpost.dialects import DIALECTS
from urdfpost.errors import CLDataError, DialectError, ProgramParseError
from urdfpost.posting.options import PostOptions, resolve
from urdfpost.posting.piece import post_piece
from urdfpost.posting.stream import post_stream
from urdfpost.posting.whole import post
from urdfpost.program import ARC_PLANES, Arc, CutterComp, MoveTable, Program, arcs_as_moves
from urdfpost.readers import read_cl, read_cl_chunks, read_cl_text
from urdfpost.tolerances import Tolerances
from urdfpost.toolpath import toolpath_slice
from urdfpost.verification import verify
from urdfpost.verification.feeds import FeedRules
from urdfpost.verification.process import check_process

GOLDEN = Path(__file__).parent / "golden" / "arcs"
REGEN = os.environ.get("URDFPOST_REGEN_GOLDEN") == "1"
CONTROLLERS = ("heidenhain", "siemens", "fanuc", "linuxcnc")

#: Arc blocks of the job per control: 6 CIRCLE records, five quarter circles (one a helix) in
#: one block each, the ZX half circle in two (at most 0.9 of half a turn a block); Heidenhain
#: writes arcs in the XY plane only (the helix as CP IPA IZ).
ARC_BLOCKS = {"heidenhain": 5, "siemens": 7, "fanuc": 7, "linuxcnc": 7}


def job():
    return read_cl_text(arc_job(), source="arc_job.apt")


#: The feed mode of the machine-coordinate posts: the default (auto: G93 on Fanuc, LinuxCNC
#: and Siemens, F per block on Heidenhain); test_arcs_in_both_feed_modes takes the other.
MC_FEED: str | None = None


def posted(controller: str, tcp: bool = True):
    options = PostOptions(controller=controller, tcp=tcp, feed_mode=None if tcp else MC_FEED)
    return post(job(), load_machine("dmu50"), options)


def arc_lines(controller: str, text: str) -> list[str]:
    pattern = r"^\d+ (C X|CP IPA)" if controller == "heidenhain" else r"^(G1[789] )?G[23] "
    return [line for line in text.splitlines() if re.match(pattern, line)]


@pytest.mark.parametrize("controller", CONTROLLERS)
def test_golden_arc_program(controller: str) -> None:
    result = posted(controller)
    path = GOLDEN / f"dmu50_{controller}{DIALECTS[controller].extensions[0]}"
    if REGEN:
        path.parent.mkdir(exist_ok=True)
        path.write_text(result.text, encoding="utf-8", newline="\n")
    expected = path.read_text(encoding="utf-8")
    if result.text != expected:
        diff = difflib.unified_diff(expected.splitlines(True), result.text.splitlines(True))
        pytest.fail("".join(list(diff)[:60]))
    v = result.verification
    assert v.ok and v.reached == v.cl_points == len(job())
    # the CL points are 0.001 mm chords of the arcs; an arc is measured at moves a fifth of
    # the tolerance apart (up to a tenth of it where a CL point falls between two)
    assert v.max_tip_deviation <= 0.001 + 0.1 * v.tip_tolerance + 0.0005
    back = DIALECTS[controller].read(result.text)
    arcs = [p for p in back.parts if isinstance(p, Arc)]
    assert len(arcs) == len(arc_lines(controller, result.text)) == ARC_BLOCKS[controller]
    assert [(a.plane, a.clockwise) for a in arcs] == [
        (a.plane, a.clockwise) for a in result.program.parts if isinstance(a, Arc)
    ]
    r = result.report.as_json()
    linear = {"heidenhain": 1}.get(controller, 0)  # the ZX half circle
    assert (r["arcs"], r["arcs_linear"]) == (6 - linear, linear)
    notes = [w for w in r["warnings"] if "CL arcs written as lines" in w]
    assert len(notes) == linear
    if controller == "heidenhain":
        assert any("no arcs in the ZX plane (first at CIRCLE line 20)" in w for w in notes)
        assert re.search(r"^\d+ CP IPA\+90\.0000 IZ-2\.000 DR\+$", result.text, re.MULTILINE)


@pytest.mark.parametrize("controller", CONTROLLERS)
def test_machine_coordinate_arcs(controller: str) -> None:
    """Without TCP the arcs are in the machine's linear axes (rotaries at 0: the same planes)."""
    result = posted(controller, tcp=False)
    assert result.verification.ok
    assert len(arc_lines(controller, result.text)) == ARC_BLOCKS[controller]


def test_no_arcs_option_writes_lines() -> None:
    result = post(job(), load_machine("dmu50"), PostOptions(controller="fanuc", arcs=False))
    assert not arc_lines("fanuc", result.text)
    assert result.report.as_json()["arcs"] == 0
    assert len(result.program.moves()) > 400


def _sample_arc_feed(start: np.ndarray, call, plane: str, step: float) -> np.ndarray:
    """Points of an rs274 ARC_FEED(first_end, second_end, first_axis, second_axis, rotation,
    axis_end_point, a, b, c) as LinuxCNC's canon defines it: the plane's first and second
    axes (XY: X Y; XZ, G18: Z X; YZ: Y Z), rotation > 0 counter-clockwise (|rotation| - 1 more
    full turns), the third axis linear."""
    first, second, normal = ARC_PLANES[plane]
    i, j, n = ("XYZ".index(a) for a in (first, second, normal))
    end = np.empty(3)
    end[i], end[j], end[n] = call.number(0), call.number(1), call.number(5)
    centre = (call.number(2), call.number(3))
    rotation = int(call.number(4))
    a0 = math.atan2(start[j] - centre[1], start[i] - centre[0])
    a1 = math.atan2(end[j] - centre[1], end[i] - centre[0])
    sweep = (a1 - a0) % (2 * math.pi) if rotation > 0 else -((a0 - a1) % (2 * math.pi))
    sweep += math.copysign(2 * math.pi * (abs(rotation) - 1), rotation)
    r0 = math.hypot(start[i] - centre[0], start[j] - centre[1])
    r1 = math.hypot(end[i] - centre[0], end[j] - centre[1])
    k = max(2, math.ceil(abs(sweep) * max(r0, r1) / step))
    t = np.linspace(0.0, 1.0, k + 1)[1:]
    out = np.empty((k, 3))
    out[:, i] = centre[0] + (r0 + (r1 - r0) * t) * np.cos(a0 + sweep * t)
    out[:, j] = centre[1] + (r0 + (r1 - r0) * t) * np.sin(a0 + sweep * t)
    out[:, n] = start[n] + (end[n] - start[n]) * t
    return out


def _polyline_distance(points: np.ndarray, vertices: np.ndarray) -> np.ndarray:
    """Distance of each of ``points`` (k, 3) from the polyline through ``vertices`` (n, 3)."""
    a, b = vertices[:-1], vertices[1:]
    d = b - a
    dd = np.maximum(np.einsum("ij,ij->i", d, d), 1e-30)
    t = np.clip(np.einsum("kij,ij->ki", points[:, None, :] - a[None], d) / dd, 0.0, 1.0)
    nearest = a[None] + t[..., None] * d[None]
    return np.linalg.norm(points[:, None, :] - nearest, axis=2).min(axis=1)


def test_linuxcnc_arcs_through_rs274(tmp_path: Path) -> None:
    """rs274 reads the LinuxCNC program (TCP: the tip in the workpiece frame, G54 zero); its
    ARC_FEED calls, sampled as LinuxCNC defines them, lie on the CL arcs."""
    result = posted("linuxcnc")
    run = run_rs274(result.text, {3: result.program.tool_length}, tmp_path)
    assert run.ended
    arcs = run.named("ARC_FEED")
    assert len(arcs) == ARC_BLOCKS["linuxcnc"]
    tp = job()
    tol = Tolerances.for_units("mm")
    plane, position = "XY", None
    seen = 0
    for call in run.calls:
        if call.name == "SELECT_PLANE":
            plane = {"CANON_PLANE_XY": "XY", "CANON_PLANE_XZ": "ZX", "CANON_PLANE_YZ": "YZ"}[
                str(call.args[0])
            ]
        elif call.name in ("STRAIGHT_FEED", "STRAIGHT_TRAVERSE"):
            position = np.array([call.number(0), call.number(1), call.number(2)])
        elif call.name == "ARC_FEED":
            assert position is not None
            points = _sample_arc_feed(position, call, plane, 0.01)
            # every sample near the CL polyline (the arc's points, chord tolerance apart)
            d = _polyline_distance(points, tp.tip)
            assert d.max() <= tol.tip, (call.text, d.max())
            position = points[-1]
            seen += 1
    assert seen == len(arcs)


def _damage(text: str, controller: str, how: str) -> str:
    """The program with its first arc turned the other way, or its centre moved 0.5 mm."""
    lines = text.splitlines()
    k = next(i for i, line in enumerate(lines) if line in arc_lines(controller, text))
    if how == "direction":
        swap = {"G2": "G3", "G3": "G2", "DR+": "DR-", "DR-": "DR+"}
        lines[k] = " ".join(swap.get(w, w) for w in lines[k].split())
    elif controller == "heidenhain":  # the CC before the C
        lines[k - 1] = re.sub(
            r"X([+-]\d+\.\d+)", lambda m: f"X{float(m[1]) + 0.5:+.3f}", lines[k - 1]
        )
    else:
        lines[k] = re.sub(
            r"\bI(=?)(-?\d+\.\d+)", lambda m: f"I{m[1]}{float(m[2]) + 0.5:.3f}", lines[k]
        )
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize("how", ["direction", "centre"])
@pytest.mark.parametrize("controller", CONTROLLERS)
def test_damaged_arc_is_caught(controller: str, how: str) -> None:
    result = posted(controller)
    machine = load_machine("dmu50")
    good = DIALECTS[controller].read(result.text)
    assert verify(good, machine, job(), tool_length=result.program.tool_length).ok
    damaged = _damage(result.text, controller, how)
    assert damaged != result.text
    bad = DIALECTS[controller].read(damaged)
    v = verify(bad, machine, job(), tool_length=result.program.tool_length)
    assert not v.ok
    if how == "centre":  # a 0.5 mm shift: far beyond the 0.01 mm tolerance, every point reached
        assert v.max_tip_deviation > 0.1
    else:  # the other way round: the arc's points are not reached
        assert v.reached < v.cl_points


def test_arc_samples_as_the_control_runs_it() -> None:
    """A quarter circle G3 from (10, 0) about the origin to (0, 10), sampled 0.01 mm apart."""
    axes = ("X", "Y", "Z")
    arc = Arc((0.0, 10.0, 0.0), (0.0, 0.0, 0.0), "XY", False, 500.0, 7)
    program = Program(
        "P",
        axes,
        frozenset(),
        "mm",
        True,
        (
            MoveTable(
                np.array([[10.0, 0.0, 0.0]]), np.array([False]), np.array([500.0]), np.array([-1])
            ),
            arc,
        ),
    )
    moves = arcs_as_moves(program, 0.01).move_table()
    assert len(moves) == 1 + math.ceil(0.5 * math.pi * 10 / 0.01)
    radius = np.linalg.norm(moves.position[:, :2], axis=1)
    assert np.abs(radius - 10.0).max() < 1e-12
    assert (np.diff(np.arctan2(moves.position[:, 1], moves.position[:, 0])) > 0).all()
    assert moves.cl_line[-1] == 7 and (moves.cl_line[1:-1] == -1).all()
    assert arc.sweep((10.0, 0.0, 0.0), axes) == pytest.approx(0.5 * math.pi)
    clockwise = Arc((0.0, 10.0, 0.0), (0.0, 0.0, 0.0), "XY", True)
    assert clockwise.sweep((10.0, 0.0, 0.0), axes) == pytest.approx(1.5 * math.pi)


def test_writer_refuses_an_arc_it_cannot_write() -> None:
    axes = ("X", "Y", "Z")
    arc = Arc((0.0, 10.0, 0.0), (0.0, 0.0, 0.0), "ZX", False)
    program = Program("P", axes, frozenset(), "mm", False, (arc,))
    with pytest.raises(DialectError, match="heidenhain takes no arcs in the ZX plane"):
        DIALECTS["heidenhain"].write(program)
    with pytest.raises(DialectError, match="expected a motion block before it"):
        DIALECTS["fanuc"].write(program)


def test_reader_records_the_arc() -> None:
    tp = job()
    arcs = [e for e in tp.events if e.kind == "arc"]
    assert [e.line for e in arcs] == [9, 11, 14, 18, 20, 23]
    first = arcs[0]
    assert first.data["centre"] == (0.0, 0.0, -1.0)
    assert first.data["normal"] == (0.0, 0.0, 1.0)
    assert first.data["radius"] == 20.0
    assert first.data["sweep"] == pytest.approx(0.5 * math.pi)
    end = first.index + first.data["points"] - 1
    assert tp.tip[first.index - 1].tolist() == [20.0, 0.0, -1.0]
    assert tp.tip[end].tolist() == [0.0, 20.0, -1.0]
    assert (tp.line[first.index : end + 1] == 9).all()


# --------------------------------------------------------------------------------------------
# the real NX 15-operation file (inch) on the UMC-750


NX_CIRCLES = 146


@pytest.mark.parametrize("controller", CONTROLLERS)
def test_nx_circles_come_out_as_arcs(controller: str) -> None:
    machine = load_machine("umc750")
    tol = Tolerances.for_units("inch")
    tp = read_cl(
        shared_cl("nx_project2_15ops_inch.cls"),
        units=machine.settings.units,
        chord_tolerance=tol.chord,
    )
    assert sum(e.kind == "arc" for e in tp.events) == NX_CIRCLES
    result = post(
        tp,
        machine,
        PostOptions(controller=controller, strategy="recursive", spindle=8000.0),
    )
    v = result.verification
    assert v.ok and v.reached == v.cl_points == len(tp)
    r = result.report.as_json()
    assert r["arcs"] + r["arcs_linear"] == NX_CIRCLES
    # the arcs of the tilted operations (tool axis off Z, in no XY/ZX/YZ plane of the
    # workpiece frame) stay lines; every arc in a plane of the frame is an arc (helical ramps
    # included: Heidenhain CP IPA IZ)
    written = 102
    assert r["arcs"] == written
    blocks = [p for p in result.program.parts if isinstance(p, Arc)]
    back = DIALECTS[controller].read(result.text)
    assert len([p for p in back.parts if isinstance(p, Arc)]) == len(blocks) >= written
    assert len(arc_lines(controller, result.text)) == len(blocks)


def test_an_arc_cut_by_the_end_of_a_piece_is_written_as_lines() -> None:
    """A piece that ends inside an arc (a streamed post never cuts there: its cuts need a new
    CL line on both sides; a piece of a toolpath can) writes the arc's points as lines, and
    says so."""
    tp = job()
    machine = load_machine("dmu50")
    first = next(e for e in tp.events if e.kind == "arc")
    piece = toolpath_slice(tp, 0, first.index + first.data["points"] // 2)
    posted = post_piece(piece, resolve(PostOptions(controller="fanuc"), machine, tp.units))
    assert not any(isinstance(p, Arc) for p in posted.program.parts)
    assert (posted.figures.arcs, posted.figures.arcs_linear) == (0, 1)
    assert any(
        "1 CL arcs written as lines: the arc is cut by the end of a streamed piece (first at "
        "CIRCLE line 9)" in w
        for w in posted.figures.warnings
    )


def test_streamed_nx_post_writes_the_arcs_of_the_whole_post(tmp_path: Path) -> None:
    """Streamed in pieces of 1500 CL points from the file read in chunks, the NX job's arcs
    are those of the whole post: its cuts never fall inside an arc, and an arc that starts at
    a cut starts from the row the piece before wrote."""
    machine = load_machine("umc750")
    tol = Tolerances.for_units("inch")
    path = shared_cl("nx_project2_15ops_inch.cls")
    options = PostOptions(controller="fanuc", strategy="recursive", spindle=8000.0)
    whole = post(read_cl(path, units="inch", chord_tolerance=tol.chord), machine, options)
    out = tmp_path / "nx.nc"
    pieces = read_cl_chunks(path, max_points=1000, units="inch", chord_tolerance=tol.chord)
    streamed = post_stream(pieces, machine, out, options, piece_points=1500, parallel=False)
    r = streamed.report.as_json()
    assert r["verified"] and r["streamed"]["pieces"] > 1
    assert (r["arcs"], r["arcs_linear"]) == (102, NX_CIRCLES - 102)
    text = out.read_text()
    assert len(arc_lines("fanuc", text)) == len(arc_lines("fanuc", whole.text))


# --------------------------------------------------------------------------------------------
# cutter radius compensation (CUTCOM)

#: The compensation lines (or L blocks) each control writes for the CUTCOM job.
CUTCOM_LINES = {
    "fanuc": [r"^G17 G41 D3$", r"^G40$"],
    "linuxcnc": [r"^G17 G41 D3$", r"^G40$"],
    "siemens": [r"^G17 G41$", r"^G40$"],
    "heidenhain": [r"^\d+ L X-10\.000 Y-10\.000 RL$", r"^\d+ L X-20\.000 Y-20\.000 R0$"],
}


@pytest.mark.parametrize("controller", CONTROLLERS)
def test_cutcom_round_trip(controller: str) -> None:
    tp = read_cl_text(cutcom_job(), source="cutcom.apt")
    comps = [e for e in tp.events if e.kind == "cutcom"]
    assert [(e.line, e.data) for e in comps] == [
        (9, {"side": "left", "plane": "XY"}),
        (17, {"side": "off"}),
    ]
    result = post(tp, load_machine("dmu50"), PostOptions(controller=controller))
    assert result.verification.ok
    lines = result.text.splitlines()
    for pattern in CUTCOM_LINES[controller]:
        assert sum(bool(re.match(pattern, line)) for line in lines) == 1, pattern
    written = [p for p in result.program.parts if isinstance(p, CutterComp)]
    back = [p for p in DIALECTS[controller].read(result.text).parts if isinstance(p, CutterComp)]
    assert [(c.side, c.plane) for c in written] == [(c.side, c.plane) for c in back]
    assert [c.side for c in back] == ["left", "off"]
    # the compensation is the control's: the report says so
    warnings = result.report.as_json()["warnings"]
    assert any("cutter radius compensation left is the control's" in w for w in warnings)


def test_cutcom_through_rs274(tmp_path: Path) -> None:
    """LinuxCNC's interpreter takes the compensated program (the tool table's radius: 0)."""
    tp = read_cl_text(cutcom_job(), source="cutcom.apt")
    result = post(tp, load_machine("dmu50"), PostOptions(controller="linuxcnc"))
    run = run_rs274(result.text, {3: result.program.tool_length}, tmp_path)
    assert run.ended
    assert len(run.named("ARC_FEED")) == 1


@pytest.mark.parametrize(
    ("record", "match"),
    [
        ("CUTCOM/LEFT,BOTH", r"unexpected 'BOTH' in CUTCOM; expected CUTCOM/LEFT, RIGHT or OFF"),
        ("CUTCOM/XYPLAN", r"expected LEFT, RIGHT or OFF in CUTCOM, got none"),
    ],
)
def test_cutcom_errors(record: str, match: str) -> None:
    text = cutcom_job().replace("CUTCOM/LEFT,XYPLAN", record)
    with pytest.raises(CLDataError, match=rf"cutcom\.apt:9: {match}"):
        read_cl_text(text, source="cutcom.apt")


def test_cutcom_register_and_plane() -> None:
    text = cutcom_job().replace("CUTCOM/LEFT,XYPLAN", "CUTCOM/ON,RIGHT,7")
    tp = read_cl_text(text, source="cutcom.apt")
    comp = next(e for e in tp.events if e.kind == "cutcom")
    assert comp.data == {"side": "right", "register": 7}
    result = post(tp, load_machine("dmu50"), PostOptions(controller="fanuc"))
    assert re.search(r"^G17 G42 D7$", result.text, re.MULTILINE)
    # controls that take the radius of the tool called (no register word) refuse another
    # register than the tool's, at the CUTCOM line; the tool's own number is that radius
    for controller in ("heidenhain", "siemens"):
        with pytest.raises(
            CLDataError,
            match=rf"cutcom\.apt:9: cutter radius compensation from offset register 7 with tool "
            rf"3 called: {controller} takes the radius of the tool called",
        ):
            post(tp, load_machine("dmu50"), PostOptions(controller=controller))
        own = read_cl_text(text.replace("RIGHT,7", "RIGHT,3"), source="cutcom.apt")
        result = post(own, load_machine("dmu50"), PostOptions(controller=controller))
        back = DIALECTS[controller].read(result.text)
        comps = [p for p in back.parts if isinstance(p, CutterComp)]
        assert [(c.side, c.register) for c in comps] == [("right", None), ("off", None)]
    # Heidenhain's RL/RR is in the working plane only: refused at the CUTCOM line
    zx = read_cl_text(cutcom_job().replace("LEFT,XYPLAN", "LEFT,ZXPLAN"), source="cutcom.apt")
    with pytest.raises(CLDataError, match=r"cutcom\.apt:9: .* in the ZX plane: heidenhain has"):
        post(zx, load_machine("dmu50"), PostOptions(controller="heidenhain"))
    assert "G18 G41" in post(zx, load_machine("dmu50"), PostOptions(controller="fanuc")).text


def test_the_feed_of_an_arc_is_checked() -> None:
    """The feed of an arc block is checked as any move's: F300 on the G2 of CIRCLE line 18
    (FEDRAT 400 there) is a tip-feed fault at that CL line (the process check leaves an F that
    is not missing to the verifier's tip-feed measure); as written the process is the CL's."""
    result = posted("fanuc")
    machine = load_machine("dmu50")
    tp = job()
    good = check_process(DIALECTS["fanuc"].read(result.text), machine, tp)
    assert good.ok and good.cutting_moves == 4 + 7  # the straight feed moves, the arc blocks
    rules = FeedRules.of(DIALECTS["fanuc"].spec, "mm")
    ok = verify(DIALECTS["fanuc"].read(result.text), machine, tp, feed_rules=rules)
    assert ok.ok and ok.feeds is not None and ok.feeds.max_deviation_pct < 1.0
    lines = result.text.splitlines()
    k = next(i for i, line in enumerate(lines) if line.startswith("G2 X10.000 Y-30.000"))
    lines[k] += " F300."
    text = "\n".join(lines) + "\n"
    bad = verify(DIALECTS["fanuc"].read(text), machine, tp, feed_rules=rules)
    assert not bad.ok
    assert bad.feeds is not None
    assert bad.feeds.max_deviation_pct == pytest.approx(25.0, abs=0.5)
    assert bad.feeds.worst_cl_line in (18, 19)  # the arc's CL points (CIRCLE line, its GOTO)


# --------------------------------------------------------------------------------------------
# reading arcs written by hand


def _arcs_of(controller: str, text: str) -> list[Arc]:
    return [p for p in DIALECTS[controller].read(text).parts if isinstance(p, Arc)]


def test_read_gcode_arcs_in_every_plane() -> None:
    text = (
        "G21\nG90\nG0 X10. Y0. Z0.\nG17 G3 X0. Y10. I-10. J0. F500.\n"
        "G18 G2 X-10. Z-10. I0. K-10.\nG19 G3 Y0. Z0. J-10. K10.\nG1 X0.\nM30\n"
    )
    arcs = _arcs_of("linuxcnc", text)
    assert [(a.plane, a.clockwise, a.centre) for a in arcs] == [
        ("XY", False, (0.0, 0.0, 0.0)),
        ("ZX", True, (0.0, 10.0, -10.0)),
        ("YZ", False, (-10.0, 0.0, 0.0)),
    ]
    assert arcs[0].feed == 500.0 and arcs[0].position == (0.0, 10.0, 0.0)


def test_read_siemens_absolute_centre() -> None:
    text = "G710\nG90\nG0 X10 Y0 Z0\nG2 X0 Y-10 I=AC(0) J=AC(0) F500\nM30\n"
    (arc,) = _arcs_of("siemens", text)
    assert (arc.plane, arc.clockwise, arc.centre) == ("XY", True, (0.0, 0.0, 0.0))


def test_read_heidenhain_helix() -> None:
    text = (
        "0 BEGIN PGM P MM\n1 L X+10 Y+0 Z+0 FMAX\n2 CC X+0 Y+0\n3 CP IPA-90 IZ-2 DR- F500\n"
        "4 END PGM P MM\n"
    )
    (arc,) = _arcs_of("heidenhain", text)
    assert (arc.plane, arc.clockwise, arc.centre) == ("XY", True, (0.0, 0.0, 0.0))
    assert np.allclose(arc.position, (0.0, -10.0, -2.0), atol=1e-12)
    with pytest.raises(ProgramParseError, match=r"job\.h:4: CP IPA-90 with DR\+; expected one"):
        DIALECTS["heidenhain"].read(text.replace("DR-", "DR+"), path="job.h")


def test_read_heidenhain_circle() -> None:
    text = (
        "0 BEGIN PGM P MM\n1 L X+10 Y+0 Z+0 FMAX\n2 CC X+0 Y+0\n3 C X+0 Y+10 DR+ F500\n"
        "4 L X+5\n5 END PGM P MM\n"
    )
    (arc,) = _arcs_of("heidenhain", text)
    assert (arc.plane, arc.clockwise, arc.centre, arc.feed) == ("XY", False, (0.0, 0.0, 0.0), 500.0)


@pytest.mark.parametrize(
    ("controller", "text", "line", "match"),
    [
        ("fanuc", "G21\nG2 X1. Y1. I1. J0.\n", 2, r"arc from an unknown X position"),
        ("fanuc", "G21\nG0 X0. Y0. Z0.\nG2 X1. Y1.\n", 3, r"G2 without I, J or K; expected"),
        ("fanuc", "G21\nG0 X0. Y0. Z0.\nG17 G2 X1. Y1. K1.\n", 3, r"K word in a XY arc"),
        ("fanuc", "G21\nG0 X0. Y0. Z0. B0.\nG2 X1. Y1. I1. B5.\n", 3, r"B word in an arc block"),
        (
            "heidenhain",
            "0 BEGIN PGM P MM\n1 L X+1 Y+0 Z+0 FMAX\n2 C X+0 Y+1 DR+\n",
            3,
            r"C without a CC",
        ),
        (
            "heidenhain",
            "0 BEGIN PGM P MM\n1 CC X+0 Y+0\n2 C X+0 Y+1\n",
            3,
            r"C without DR\+ or DR-",
        ),
        ("heidenhain", "0 BEGIN PGM P MM\n1 CC X+0 Z+0\n", 2, r"unknown word 'Z\+0' in CC"),
    ],
)
def test_read_arc_errors(controller: str, text: str, line: int, match: str) -> None:
    path = "job" + DIALECTS[controller].extensions[0]
    with pytest.raises(ProgramParseError, match=rf"^job\.\w+:{line}: .*{match}"):
        DIALECTS[controller].read(text, path=path)


@pytest.mark.parametrize("controller", CONTROLLERS)
def test_arc_blocks_round_trip(controller: str) -> None:
    """The posted program's arcs read back as written (to the written decimals)."""
    result = posted(controller)
    written = [p for p in result.program.parts if isinstance(p, Arc)]
    back = _arcs_of(controller, result.text)
    assert len(back) == len(written)
    for a, b in zip(written, back, strict=True):
        assert (a.plane, a.clockwise) == (b.plane, b.clockwise)
        assert a.feed == b.feed  # the reader gives the modal feed, the post each arc's
        assert np.abs(np.subtract(a.centre, b.centre)).max() <= 0.0005 + 1e-9
        assert np.abs(np.subtract(a.position[:3], b.position[:3])).max() <= 0.0005 + 1e-9


def _tilted_job() -> str:
    """A quarter circle of radius 20 in a plane tilted 30 degrees about X, the tool along its
    normal (a 3+2 arc)."""
    a = math.radians(30.0)
    rotation = np.array([[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]])
    k = rotation @ np.array([0.0, 0.0, 1.0])
    out = ["PARTNO TILTED", "UNITS/MM", "MULTAX/ON", "LOADTL/3", "SPINDL/8000,CLW"]
    out.append("FEDRAT/MMPM,500")
    for word, point in [
        ("GOTO", (20, 0, 2)),
        ("GOTO", (20, 0, -1)),
        ("CIRCLE", (0, 0, -1)),
        ("GOTO", (0, 20, -1)),
        ("GOTO", (-20, 20, -1)),
    ]:
        q = rotation @ np.array(point, dtype=float)
        if word == "GOTO":
            out.append("GOTO/{:.6f},{:.6f},{:.6f},{:.7f},{:.7f},{:.7f}".format(*q, *k))
        else:
            out.append("CIRCLE/{:.6f},{:.6f},{:.6f},{:.7f},{:.7f},{:.7f},20".format(*q, *k))
    return "\n".join([*out, "FINI"]) + "\n"


@pytest.mark.parametrize(
    ("machine_name", "tcp", "arcs"),
    [
        ("dmu50", True, 0),  # tilted in the workpiece frame
        ("dmu50", False, 1),  # the table tilts the part: the arc is in the machine's XY
        ("gantry-ca", False, 0),  # the head tilts: the arc stays tilted in the machine's axes
        ("monoblock", False, 0),
    ],
)
def test_tilted_arc_through_the_kinematics(machine_name: str, tcp: bool, arcs: int) -> None:
    tp = read_cl_text(_tilted_job(), source="tilted.apt")
    options = PostOptions(controller="fanuc", tcp=tcp, feed_mode=None if tcp else MC_FEED)
    result = post(tp, load_machine(machine_name), options)
    assert result.verification.ok
    r = result.report.as_json()
    assert (r["arcs"], r["arcs_linear"]) == (arcs, 1 - arcs)
    assert len(arc_lines("fanuc", result.text)) == arcs
    if not arcs:
        assert any("the arc is in no XY, ZX or YZ plane of the program" in w for w in r["warnings"])


def test_command_line_no_arcs(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cl = tmp_path / "arc_job.apt"
    cl.write_text(arc_job())
    for extra, count in (([], ARC_BLOCKS["linuxcnc"]), (["--no-arcs"], 0)):
        out = tmp_path / "out.ngc"
        argv = ["post", str(cl), "-m", "dmu50", "--controller", "linuxcnc", "-o", str(out)]
        assert main(argv + extra) == 0
        assert len(arc_lines("linuxcnc", out.read_text())) == count
    capsys.readouterr()


@pytest.mark.parametrize("tcp", [True, False], ids=["tcp", "mc"])
def test_nx_arcs_through_rs274(tmp_path: Path, tcp: bool) -> None:
    """LinuxCNC's interpreter takes every arc of the NX job (inch, four decimals: the radius
    at the end within its tolerance of the start's), with TCP and in machine coordinates, where
    the trunnion table turns the tilted operations' arcs into the machine's planes too."""
    machine = load_machine("umc750")
    tol = Tolerances.for_units("inch")
    path = shared_cl("nx_project2_15ops_inch.cls")
    tp = read_cl(path, units="inch", chord_tolerance=tol.chord)
    options = PostOptions(
        controller="linuxcnc",
        strategy="recursive",
        spindle=8000.0,
        tcp=tcp,
        feed_mode=None if tcp else MC_FEED,
    )
    result = post(tp, machine, options)
    assert result.verification.ok
    r = result.report.as_json()
    assert r["arcs"] + r["arcs_linear"] == NX_CIRCLES
    assert r["arcs"] == 102 if tcp else r["arcs"] > 102
    length = result.program.tool_length / 25.4 if tcp else 0.0
    run = run_rs274(result.text, dict.fromkeys((1, 2, 3), length), tmp_path, units="inch")
    assert run.ended
    assert len(run.named("ARC_FEED")) == len(arc_lines("linuxcnc", result.text)) >= r["arcs"]


def test_streamed_reading_carries_the_arcs() -> None:
    """read_cl_chunks gives every arc event, at the same point as the whole file's reading
    (an arc's points may run on into the next piece)."""
    tol = Tolerances.for_units("inch")
    path = shared_cl("nx_project2_15ops_inch.cls")
    whole = [
        (e.index, e.line, e.data)
        for e in read_cl(path, units="inch", chord_tolerance=tol.chord).events
        if e.kind == "arc"
    ]
    pieces, offset = [], 0
    for piece in read_cl_chunks(path, max_points=500, units="inch", chord_tolerance=tol.chord):
        pieces += [(e.index + offset, e.line, e.data) for e in piece.events if e.kind == "arc"]
        offset += len(piece)
    assert len(whole) == NX_CIRCLES
    assert pieces == whole


def test_view_shows_the_arcs_as_the_control_runs_them() -> None:
    """The 3-D view samples an arc block along the arc (not as the chord to its end): its
    worst tip deviation from the CL path is that of the arcs, and the NC line of the moves
    along an arc is the arc's line."""
    from urdfpost.analysis.view import view_data

    result = posted("linuxcnc")
    dialect = DIALECTS["linuxcnc"]
    program = dialect.read(result.text)
    data = view_data(load_machine("dmu50"), program, result.text, dialect, cl=job())
    (worst,) = [m for m in data["marks"] if m["kind"] == "worst"]
    deviation = float(re.search(r"worst tip deviation ([\d.]+) mm", worst["label"])[1])
    assert deviation < 0.01
    arc_numbers = {
        str(k + 1)
        for k, line in enumerate(result.text.splitlines())
        if line in arc_lines("linuxcnc", result.text)
    }
    assert len(arc_numbers) == ARC_BLOCKS["linuxcnc"]
    assert arc_numbers <= set(data["text"])  # the NC lines the samples show


def test_arcs_read_with_a_coarse_chord_tolerance_are_written_as_lines() -> None:
    """CL points read 0.01 mm chords off the arcs (the whole tip tolerance): the arcs would be
    that far from the points the program is checked against, so they are lines, said so."""
    tp = read_cl_text(arc_job(), source="arc_job.apt", chord_tolerance=0.01)
    result = post(tp, load_machine("dmu50"), PostOptions(controller="fanuc"))
    assert result.verification.ok
    r = result.report.as_json()
    assert (r["arcs"], r["arcs_linear"]) == (0, 6)
    assert any(
        "6 CL arcs written as lines: its CL points are chords more than half the tip tolerance "
        "off the arc" in w
        for w in r["warnings"]
    )


@pytest.mark.parametrize("controller", ["siemens", "fanuc", "linuxcnc"])
@pytest.mark.parametrize("mode", ["inverse-time", "per-block"])
def test_arcs_in_both_feed_modes(controller: str, mode: str, tmp_path: Path) -> None:
    """Machine coordinates: in inverse time an arc's F is one over its time along it (the
    CL feed over its length: a quarter circle of radius 20 mm at 600 mm/min is F19.0986), per
    block its CL feed; both verify with the tip feed of every move along the arc at the CL
    feed, and LinuxCNC's interpreter runs both."""
    options = PostOptions(controller=controller, tcp=False, feed_mode=mode)
    result = post(job(), load_machine("dmu50"), options)
    assert result.verification.ok
    assert result.verification.feeds is not None
    assert result.verification.feeds.max_deviation_pct < 1.0
    assert len(arc_lines(controller, result.text)) == ARC_BLOCKS[controller]
    program = DIALECTS[controller].read(result.text)
    assert program.feed_mode == ("inverse-time" if mode == "inverse-time" else "per-minute")
    first = next(p for p in program.parts if isinstance(p, Arc))
    assert first.feed is not None
    # the first CIRCLE: a quarter circle of radius 20 mm at FEDRAT 600
    quarter = math.pi * 20.0 / 2.0
    want = 600.0 / quarter if mode == "inverse-time" else 600.0
    assert first.feed == pytest.approx(want, rel=1e-4)
    if controller == "linuxcnc":
        run = run_rs274(result.text, {3: 0.0}, tmp_path / "rs274")
        assert sum(c.name == "ARC_FEED" for c in run.calls) >= ARC_BLOCKS[controller]
