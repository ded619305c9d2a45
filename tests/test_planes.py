"""3+2 operations in tilted working planes (issue 19): written, read back and verified.

The 3+2 job of ``tests/jobs.py`` (:func:`jobs.indexed_job`: a flat cut, then two operations at
a fixed tilt, the second with a drilling cycle at holes of two heights along its axis) is
posted with TCP for every control and compared with ``tests/golden/planes/<machine>_<control>``
(regenerate with ``URDFPOST_REGEN_GOLDEN=1``): two planes on the controls that have them
(Heidenhain ``PLANE SPATIAL ... STAY``, Siemens ``CYCLE800``, Fanuc ``G68.2`` + ``G53.1``), the
moves in them in the plane's coordinates with no rotary word, the holes the control's cycle
along the plane's Z; LinuxCNC's five-axis fallback. The read-back program, taken back out of
its planes, is the five-axis program the post makes without them; a plane whose angles or
coordinates are damaged is refused.
"""

from __future__ import annotations

import difflib
import os
import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from jobs import drilling_job, indexed_job, long_indexed_job, rotary_sweep

from urdfpost import load_machine
from urdfpost.cli import main
from urdfpost.dialects import DIALECTS
from urdfpost.errors import DialectError, MachineDefinitionError, ProgramParseError
from urdfpost.machine.load import resolve_machine
from urdfpost.posting.options import PostOptions
from urdfpost.posting.planes import plane_count
from urdfpost.posting.whole import post
from urdfpost.program import (
    PLANE_CONVENTIONS,
    Clamp,
    Cycle,
    Move,
    MoveTable,
    Tcp,
    TiltedPlane,
    untilted,
)
from urdfpost.readers import read_cl_text
from urdfpost.toolpath import cycle_holes
from urdfpost.verification import program_joints, verify

GOLDEN = Path(__file__).parent / "golden" / "planes"
REGEN = os.environ.get("URDFPOST_REGEN_GOLDEN") == "1"
CONTROLLERS = ("heidenhain", "siemens", "fanuc", "linuxcnc")
WITH_PLANES = ("heidenhain", "siemens", "fanuc")
#: a table-table, a head-table, a tilting head and a 45-degree nutating machine
MACHINES = ("dmu50", "monoblock", "gantry-ca", "dmu50-nutating")


def job():
    return read_cl_text(indexed_job(), source="indexed.apt")


def posted(controller: str, machine: str = "dmu50", **options):
    return post(job(), load_machine(machine), PostOptions(controller=controller, **options))


def planes_of(program) -> list[TiltedPlane]:
    return [p for p in program.parts if isinstance(p, TiltedPlane) and p.angles is not None]


def moves_in_planes(program) -> list[np.ndarray]:
    """Per plane, the positions of the moves in it (rows, shape (k, m))."""
    out: list[list[np.ndarray]] = []
    inside = False
    for part in program.parts:
        if isinstance(part, TiltedPlane):
            inside = part.angles is not None
            if inside:
                out.append([])
        elif inside and isinstance(part, MoveTable | Move):
            table = part if isinstance(part, MoveTable) else MoveTable.from_moves([part], 5)
            out[-1].append(table.position)
    return [np.concatenate(p) if p else np.zeros((0, 5)) for p in out]


@pytest.mark.parametrize("controller", CONTROLLERS)
@pytest.mark.parametrize("machine", ["dmu50", "gantry-ca"])
def test_golden_indexed_program(controller: str, machine: str) -> None:
    result = posted(controller, machine)
    path = GOLDEN / f"{machine}_{controller}{DIALECTS[controller].extensions[0]}"
    if REGEN:
        path.parent.mkdir(exist_ok=True)
        path.write_text(result.text, encoding="utf-8", newline="\n")
    expected = path.read_text(encoding="utf-8")
    if result.text != expected:
        diff = difflib.unified_diff(expected.splitlines(True), result.text.splitlines(True))
        pytest.fail("".join(list(diff)[:60]))
    assert result.verification.ok
    assert result.verification.reached == result.verification.cl_points


@pytest.mark.parametrize("controller", CONTROLLERS)
@pytest.mark.parametrize("machine", MACHINES)
def test_two_operations_at_a_fixed_tilt_are_two_planes(controller: str, machine: str) -> None:
    result = posted(controller, machine)
    m = load_machine(machine)
    assert result.verification.ok
    dialect = DIALECTS[controller]
    back = dialect.read(result.text)
    expected = 2 if controller in WITH_PLANES else 0
    assert plane_count(back) == plane_count(result.program) == expected
    assert result.report.as_json()["tilted_planes"] == expected
    if not expected:
        assert not any(isinstance(p, TiltedPlane) for p in back.parts)
        return
    # each plane's Z is the CL tool axis of its operation, its convention the control's
    axes = {"one": (0.5, 0.0, 0.8660254), "two": (0.0, -0.3420201, 0.9396926)}
    for plane, want in zip(planes_of(back), axes.values(), strict=True):
        assert plane.convention == dialect.spec.plane_convention in PLANE_CONVENTIONS
        z = plane.frame()[:, 2]
        unit = np.array(want) / np.linalg.norm(want)
        assert np.degrees(np.arccos(np.clip(z @ unit, -1, 1))) < 2e-4
    # the rotary axes stand in a plane and the control reads no rotary word there
    inside = moves_in_planes(back)
    rotary = [back.axes.index(a.name) for a in m.rotary]
    for rows in inside:
        assert len(rows) and np.ptp(rows[:, rotary], axis=0).max() == 0.0
    words = re.compile(r"\b[ABC][+-]?\d")
    text_in = re.findall(
        r"(?:PLANE SPATIAL|CYCLE800\(0|G68\.2)(.*?)(?:PLANE RESET|CYCLE800\(\)|G69)",
        result.text,
        re.S,
    )
    assert len(text_in) == 2
    for block in text_in:
        body = [ln for ln in block.splitlines()[1:] if "SPA" not in ln and "CYCLE800" not in ln]
        assert not any(words.search(re.sub(r"\(.*?\)|;.*", "", ln)) for ln in body), body
    # TCP is off in a plane and on again after it
    assert not any(isinstance(p, Tcp) and p.on for p in _between_planes(back))


def _between_planes(program) -> list:
    inside, out = False, []
    for part in program.parts:
        if isinstance(part, TiltedPlane):
            inside = part.angles is not None
        elif inside:
            out.append(part)
    return out


@pytest.mark.parametrize("controller", WITH_PLANES)
@pytest.mark.parametrize("machine", MACHINES)
def test_read_back_out_of_its_planes_is_the_five_axis_program(
    controller: str, machine: str
) -> None:
    """The control's motion: the read-back program taken out of its planes moves the machine's
    joints along the rows of the five-axis program the post makes without planes (within the
    text's rounding)."""
    m = load_machine(machine)
    plain = posted(controller, machine, tilted_planes=False)
    planes = posted(controller, machine)
    a, b = untilted(planes.program), plain.program
    qa, _ = program_joints(m, a)
    qb, _ = program_joints(m, b)
    # the cycles are the plane program's own blocks there; compare the rows of the CL points
    lines_a, lines_b = a.move_table().cl_line, b.move_table().cl_line
    common = sorted(set(lines_a[lines_a > 0].tolist()) & set(lines_b[lines_b > 0].tolist()))
    assert len(common) >= 12
    for line in common:
        ia = int(np.flatnonzero(lines_a == line)[0])
        ib = int(np.flatnonzero(lines_b == line)[0])
        np.testing.assert_allclose(qa[ia], qb[ib], atol=1e-9)
    # read back from the text: the same rows, within its rounding
    back = untilted(DIALECTS[controller].read(planes.text))
    qc, _ = program_joints(m, back)
    assert qc.shape == qa.shape
    linear = list(m.linear_columns)
    np.testing.assert_allclose(qc[:, linear], qa[:, linear], atol=1.5e-3)
    np.testing.assert_allclose(
        qc[:, list(m.rotary_columns)], qa[:, list(m.rotary_columns)], atol=1e-5
    )


@pytest.mark.parametrize("controller", WITH_PLANES)
def test_a_plane_whose_angle_is_damaged_is_refused(controller: str) -> None:
    text = posted(controller).text
    damaged = {
        "heidenhain": ("SPB+30.0000", "SPB+31.0000"),
        "siemens": (",0.0000,30.0000,0.0000,", ",0.0000,31.0000,0.0000,"),
        "fanuc": ("J30.0000", "J31.0000"),
    }[controller]
    assert damaged[0] in text
    program = DIALECTS[controller].read(text.replace(*damaged, 1))
    with pytest.raises(ProgramParseError, match=r"tilted plane 1 .*its Z is 1\.0000 deg from"):
        verify(program, load_machine("dmu50"), job())


@pytest.mark.parametrize("controller", WITH_PLANES)
def test_a_move_in_a_plane_that_is_damaged_fails_verification(controller: str) -> None:
    result = posted(controller)
    lines = result.text.splitlines(True)
    # the first feed move in the first plane, its Y moved by 0.5 mm
    start = next(
        i for i, ln in enumerate(lines) if re.search(r"PLANE SPATIAL|CYCLE800\(0|G68\.2", ln)
    )
    k = next(i for i in range(start, len(lines)) if re.search(r"Y[+=]?20\.000", lines[i]))
    lines[k] = re.sub(r"Y([+=]?)20\.000", r"Y\g<1>20.500", lines[k])
    check = verify(DIALECTS[controller].read("".join(lines)), load_machine("dmu50"), job())
    assert not check.ok
    assert check.max_tip_deviation == pytest.approx(0.5, abs=0.01)


def test_a_machine_coordinate_post_has_no_plane() -> None:
    """Without TCP the positions are the joints: the post did the kinematics a plane would ask
    of the control."""
    for controller in WITH_PLANES:
        result = posted(controller, tcp=False)
        assert result.verification.ok and plane_count(result.program) == 0


def test_no_tilted_planes_option_and_machine_setting(tmp_path: Path) -> None:
    cl = tmp_path / "indexed.apt"
    cl.write_text(indexed_job())
    out = tmp_path / "a.h"
    assert main(["post", str(cl), "-m", "dmu50", "-c", "heidenhain", "-o", str(out)]) == 0
    assert out.read_text().count("PLANE SPATIAL") == 2
    assert (
        main(
            [
                "post",
                str(cl),
                "-m",
                "dmu50",
                "-c",
                "heidenhain",
                "-o",
                str(out),
                "--no-tilted-planes",
            ]
        )
        == 0
    )
    assert "PLANE SPATIAL" not in out.read_text()
    # the machine file's tilted_planes="off"
    source = resolve_machine("dmu50")
    text = Path(source).read_text()
    assert "<urdfpost" in text
    urdf = tmp_path / "dmu50_off.urdf"
    urdf.write_text(re.sub(r"<urdfpost\s", '<urdfpost tilted_planes="off" ', text, count=1))
    for mesh in Path(source).parent.iterdir():  # (meshes beside it)
        if mesh.is_dir():
            (tmp_path / mesh.name).symlink_to(mesh)
    assert main(["post", str(cl), "-m", str(urdf), "-c", "heidenhain", "-o", str(out)]) == 0
    assert "PLANE SPATIAL" not in out.read_text()
    assert (
        main(
            [
                "post",
                str(cl),
                "-m",
                str(urdf),
                "-c",
                "heidenhain",
                "-o",
                str(out),
                "--tilted-planes",
            ]
        )
        == 0
    )
    assert out.read_text().count("PLANE SPATIAL") == 2


def test_a_five_axis_path_is_not_put_in_a_plane() -> None:
    """The rotary sweep turns its axes at feed moves: no operation at a fixed tilt, even where
    the tool axis stands still for a stretch."""
    tp = read_cl_text(rotary_sweep(), source="sweep.apt")
    for controller in WITH_PLANES:
        result = post(tp, load_machine("dmu50"), PostOptions(controller=controller))
        assert result.verification.ok and plane_count(result.program) == 0


def test_drilling_job_flat_and_tilted_in_a_plane() -> None:
    """The drilling job's three flat cycles stay in the program's frame, its tilted hole is a
    cycle in a plane: drilled along the plane's Z, at the CL's depth."""
    tp = read_cl_text(drilling_job(tilted=True), source="drill.apt")
    m = load_machine("dmu50")
    for controller in WITH_PLANES:
        result = post(tp, m, PostOptions(controller=controller))
        back = DIALECTS[controller].read(result.text)
        (plane,) = planes_of(back)
        inside = [p for p in _between_planes(back) if isinstance(p, Cycle)]
        (event,) = [e for e in tp.events if e.kind == "cycle" and e.line == 22]
        assert [c.kind for c in inside] == ["drill"]
        # the hole's bottom in the plane's frame: the CL point, the CL's depth down its axis
        hole = inside[0]
        bottom = plane.frame() @ (np.array(hole.holes[0][:3]) - [0.0, 0.0, hole.depth])
        axis = np.array([0.5, 0.0, 0.8660254])
        want = np.array([40.0, -20.0, -2.0]) - float(event.data["depth"]) * axis / np.linalg.norm(
            axis
        )
        np.testing.assert_allclose(bottom, want, atol=2e-3)
        assert verify(back, m, tp).ok


READ_ERRORS = [
    ("heidenhain", "PLANE SPATIAL SPA+0 SPB+30 STAY", r"expected PLANE SPATIAL SPA\.\. SPB\.\."),
    ("heidenhain", "PLANE SPATIAL SPA+0 SPB+30 SPC+0 TURN", r"expected PLANE SPATIAL"),
    ("siemens", 'CYCLE800(0,"",0,27,0,0,0,0,30,0,0,0,0,0,0,1)', r"mode 27; expected"),
    ("siemens", 'CYCLE800(0,"",0,57,5,0,0,0,30,0,0,0,0,0,0,1)', r"parameter 5 is 5"),
    ("fanuc", "G68.2 X10. Y0. Z0. I0. J30. K0.", r"G68\.2 with X10\.; expected the plane's zero"),
]


@pytest.mark.parametrize(("controller", "line", "match"), READ_ERRORS)
def test_a_plane_the_reader_does_not_take_is_an_error_at_its_line(
    controller: str, line: str, match: str
) -> None:
    text = posted(controller).text
    pattern = {
        "heidenhain": r"PLANE SPATIAL[^\n]*",
        "siemens": r'CYCLE800\(0,"[^\n]*',
        "fanuc": r"G68\.2[^\n]*",
    }[controller]
    first = re.search(pattern, text)
    assert first is not None
    prefix = text[: first.start()]
    bad = prefix + line + text[first.end() :]
    number = prefix.count("\n") + 1
    with pytest.raises(ProgramParseError, match=match) as err:
        DIALECTS[controller].read(bad, path="bad")
    assert err.value.line == number


def test_tcp_on_in_a_plane_is_an_error() -> None:
    text = posted("fanuc").text
    text = text.replace("G43 H1\n", "G43 H1\nG43.4 H1\n", 1)
    with pytest.raises(ProgramParseError, match="TCP on in a tilted working plane"):
        DIALECTS["fanuc"].read(text)


def test_untilted_refuses_a_rotary_move_in_a_plane() -> None:
    text = posted("heidenhain").text
    first = re.search(r"PLANE SPATIAL[^\n]*\n(\d+) L ([^\n]*)", text)
    assert first is not None
    line = first.group(0)
    bad = text.replace(line, re.sub(r"(Z[+-][\d.]+)", r"\1 B+33.0000", line, count=1), 1)
    assert bad != text
    with pytest.raises(ValueError, match="B moves in a tilted working plane"):
        untilted(DIALECTS["heidenhain"].read(bad))


# -- rotary clamps ---------------------------------------------------------------------------


def _machine_with(tmp_path: Path, attributes: str) -> Path:
    """The dmu50 machine file with ``attributes`` on its ``<urdfpost>`` element, beside its
    meshes."""
    source = resolve_machine("dmu50")
    text = Path(source).read_text()
    urdf = tmp_path / "dmu50_clamped.urdf"
    urdf.write_text(re.sub(r"<urdfpost\s", f"<urdfpost {attributes} ", text, count=1))
    for entry in Path(source).parent.iterdir():
        if entry.is_dir() and not (tmp_path / entry.name).exists():
            (tmp_path / entry.name).symlink_to(entry)
    return urdf


@pytest.mark.parametrize("controller", WITH_PLANES)
def test_rotary_clamps_around_each_plane(controller: str, tmp_path: Path) -> None:
    m = load_machine(_machine_with(tmp_path, 'clamp="B:M10/M11 C:M12/M13"'))
    assert m.settings.clamps == (("B", 10, 11), ("C", 12, 13))
    result = post(job(), m, PostOptions(controller=controller))
    assert result.verification.ok
    text = result.text
    # clamped after the plane, released before it is switched off: twice
    on, off = {
        "heidenhain": (r"PLANE SPATIAL", r"PLANE RESET STAY"),
        "siemens": (r'CYCLE800\(0,"', r"CYCLE800\(\)"),
        "fanuc": (r"G68\.2", r"G69"),
    }[controller]
    number = r"(?:\d+ )?"
    pattern = (
        rf"{on}[^\n]*\n(?:[^\n]*(?:G53\.1|G43 H)[^\n]*\n)*{number}M10\n{number}M12\n"
        rf"(?:(?!M1[0-3]\n)[^\n]*\n)*?{number}M13\n{number}M11\n(?:{number}G49\n)?{number}{off}"
    )
    assert len(re.findall(pattern, text)) == 2, text
    dialect = DIALECTS[controller].with_clamps(m.settings.clamps)
    back = dialect.read(text)
    clamps = [(p.axis, p.on) for p in back.parts if isinstance(p, Clamp)]
    assert clamps == [("B", True), ("C", True), ("C", False), ("B", False)] * 2
    assert verify(back, m, job()).ok
    # the plain control does not know the machine's codes: an error at the line
    with pytest.raises(ProgramParseError, match="unknown M-code M10"):
        DIALECTS[controller].read(text)
    # B released no more before the second operation turns it: refused
    lines = text.splitlines(True)
    k = next(i for i, ln in enumerate(lines) if re.fullmatch(rf"{number}M11\n", ln))
    damaged = "".join(lines[:k] + lines[k + 1 :])
    with pytest.raises(ProgramParseError, match="B turns to 20 deg while clamped"):
        verify(dialect.read(damaged), m, job())


def test_clamps_through_the_command_line(tmp_path: Path) -> None:
    urdf = _machine_with(tmp_path, 'clamp="B:M10/M11"')
    cl = tmp_path / "indexed.apt"
    cl.write_text(indexed_job())
    out = tmp_path / "a.nc"
    argv = ["post", str(cl), "-m", str(urdf), "-c", "fanuc", "-o", str(out)]
    assert main(argv) == 0
    assert out.read_text().count("\nM10\n") == 2
    assert main(["verify", str(out), "-m", str(urdf), "--cl", str(cl), "-c", "fanuc"]) == 0


@pytest.mark.parametrize(
    ("attribute", "match"),
    [
        ('clamp="Q:M10/M11"', r"'Q:M10/M11'; expected AXIS:Mclamp/Mrelease for rotary joints"),
        ('clamp="B:M10"', r"'B:M10'; expected AXIS:Mclamp/Mrelease"),
        ('clamp="B:M10/M11 C:M11/M12"', r"expected each axis once and each M code once"),
    ],
)
def test_a_bad_clamp_setting_is_an_error_at_its_line(
    attribute: str, match: str, tmp_path: Path
) -> None:
    with pytest.raises(MachineDefinitionError, match=match) as err:
        load_machine(_machine_with(tmp_path, attribute))
    assert "dmu50_clamped.urdf:" in str(err.value)


def test_a_clamp_code_the_control_has_is_refused(tmp_path: Path) -> None:
    m = load_machine(_machine_with(tmp_path, 'clamp="B:M8/M11"'))
    with pytest.raises(DialectError, match="clamp code M8 for B: fanuc has M8 for coolant flood"):
        post(job(), m, PostOptions(controller="fanuc"))


@pytest.mark.parametrize("controller", CONTROLLERS)
def test_numbered_blocks_and_inch_read_back(controller: str) -> None:
    """Block numbers (a Siemens MCALL after its N word was refused) and inch programs: the
    planes, cycles and clamps read back and verify."""
    tp = read_cl_text(drilling_job(tilted=True), source="drill.apt")
    for options in (PostOptions(block_numbers=True), PostOptions(units="inch")):
        result = post(tp, load_machine("dmu50"), replace(options, controller=controller))
        back = DIALECTS[controller].read(result.text)
        assert plane_count(back) == (controller in WITH_PLANES)
        assert len([c for c in back.parts if isinstance(c, Cycle)]) >= 3
        assert verify(back, load_machine("dmu50"), tp).ok


def test_the_view_draws_a_plane_program_in_the_workpiece_frame() -> None:
    """The 3-D view reads the moves of a plane in the plane's frame: the trace's move ends are
    at the CL points (in the plane's own coordinates they would be metres off)."""
    import base64

    from urdfpost.analysis.view import view_data

    m = load_machine("dmu50")
    result = posted("heidenhain")
    dialect = DIALECTS["heidenhain"]
    program = dialect.read(result.text)
    data = view_data(m, program, result.text, dialect, cl=job())
    n = data["samples"]
    tip = np.frombuffer(base64.b64decode(data["tip"]), dtype="<f4").reshape(n, 3).astype(float)
    move = np.frombuffer(base64.b64decode(data["move"]), dtype="<i4")
    ends = np.flatnonzero(np.diff(np.append(move, -1)) != 0)
    tp = job()
    holes = {k for k, _ in cycle_holes(tp)}  # (drilled by the cycle, not drawn as moves)
    cl = tp.tip[[k for k in range(len(tp)) if k not in holes]]
    gap = np.linalg.norm(cl[:, None, :] - tip[ends][None, :, :], axis=2).min(axis=1)
    assert gap.max() < 1e-2, gap.max()


@pytest.mark.parametrize("controller", WITH_PLANES)
def test_verify_in_pieces_carries_a_plane_across_them(
    controller: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``urdfpost verify --piece-points`` cuts the program inside its planes (read in the
    plane's frame, the CL points are found there: without it no piece could be cut before the
    plane's end), a piece that begins in a plane is read in it, and a damaged move there is
    still found."""
    cl = tmp_path / "long.apt"
    cl.write_text(long_indexed_job())
    out = tmp_path / f"long{DIALECTS[controller].extensions[0]}"
    assert main(["post", str(cl), "-m", "dmu50", "-c", controller, "-o", str(out), "-q"]) == 0
    text = out.read_text()
    assert plane_count(DIALECTS[controller].read(text)) == 2
    argv = ["verify", "-m", "dmu50", "--cl", str(cl), "-c", controller, "--piece-points", "25"]
    capsys.readouterr()
    assert main(["-v", *argv, str(out)]) == 0
    assert capsys.readouterr().err.count("verified a piece") >= 6
    # a feed move in the middle of the second plane moved by 0.3 mm in Y
    lines = text.splitlines(True)
    second = [i for i, ln in enumerate(lines) if re.search(r"PLANE SPATIAL|CYCLE800\(0|G68\.2", ln)]
    k = next(i for i in range(second[1] + 60, len(lines)) if re.search(r"Y[+=]?-?\d", lines[i]))
    lines[k] = re.sub(
        r"Y([+=]?)(-?[\d.]+)", lambda m: f"Y{m[1]}{float(m[2]) + 0.3:.3f}", lines[k], count=1
    )
    bad = tmp_path / f"bad{out.suffix}"
    bad.write_text("".join(lines))
    assert main([*argv, str(bad)]) == 1


@pytest.mark.parametrize("controller", WITH_PLANES)
@pytest.mark.parametrize("between", ["OPSTOP", "STOP", "INSERT/M8"])
def test_a_stop_between_two_cuts_begins_no_plane(controller: str, between: str) -> None:
    """A program stop (or an inserted block) between two feed moves of an operation at a fixed
    tilt: the tool is on the part there, so the moves after it are not an operation entered at
    a rapid (the post switched TCP off and a plane on right there, and the moves before it
    into a plane of their own). That operation keeps its five-axis form; the other one is
    still a plane, and a stop between operations (after the retract) begins one as before."""
    mid = indexed_job().replace(
        "GOTO/40,0,0,0.5,0,0.8660254\n", f"GOTO/40,0,0,0.5,0,0.8660254\n{between}\n", 1
    )
    machine = load_machine("dmu50")
    options = PostOptions(controller=controller)
    result = post(read_cl_text(mid, source="mid.apt"), machine, options)
    assert result.verification.ok
    back = DIALECTS[controller].read(result.text)
    assert plane_count(back) == plane_count(result.program) == 1
    # the remaining plane is the second operation's (its tool axis leans about -X)
    z = planes_of(back)[0].frame()[:, 2]
    assert z @ np.array([0.0, -0.3420201, 0.9396926]) > 0.99999
    after = indexed_job().replace("RAPID\nGOTO/0,-40,20", f"{between}\nRAPID\nGOTO/0,-40,20", 1)
    result = post(read_cl_text(after, source="after.apt"), machine, options)
    assert result.verification.ok
    assert plane_count(DIALECTS[controller].read(result.text)) == 2
