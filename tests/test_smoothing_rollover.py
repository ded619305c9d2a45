"""Path smoothing cycles and rollover axes (issue 19).

Smoothing: every control's tolerance cycle (Heidenhain ``CYCL DEF 32``, Siemens ``CYCLE832``,
Fanuc ``G05.1 Q1``, LinuxCNC ``G64 P Q``) is written before each tool's approach and cancelled
before a tool change and at the end, switchable by job option, command line and machine file,
and read back into :class:`~urdfpost.program.Smoothing` blocks.

Rollover: on a machine whose continuous C rolls over (``<urdfpost rollover="C">``) the program
writes C modulo 360, splits the turns of more than 179 degrees, takes the positioning moves
(and the end) the shortest way, and the reader unwinds C as the control does. The job is a
spiral of 2.75 turns around the table with a tilted tool, ending with a move across the pole
(a half turn of C in place, which is split). Golden programs per control in
``tests/golden/rollover`` (regenerate with ``URDFPOST_REGEN_GOLDEN=1``); the LinuxCNC program
goes through the standalone interpreter with ``[AXIS_C] WRAPPED_ROTARY = 1``.
"""

from __future__ import annotations

import math
import os
import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from rs274 import run_rs274

import urdfpost.posting.piece as piece_module
from urdfpost import load_machine, read_cl
from urdfpost.cli import main
from urdfpost.dialects import DIALECTS
from urdfpost.errors import MachineDefinitionError, ProgramParseError, UrdfpostError
from urdfpost.machine import Machine
from urdfpost.posting import post
from urdfpost.posting.options import PostOptions
from urdfpost.posting.rollover import with_rollover
from urdfpost.posting.stream import post_stream
from urdfpost.program import (
    Home,
    MachineMove,
    Move,
    MoveTable,
    Program,
    Smoothing,
    ToolChange,
    rollover_target,
)
from urdfpost.readers import read_cl_chunks
from urdfpost.tolerances import Tolerances
from urdfpost.toolpath import Toolpath
from urdfpost.verification import verify

ROOT = Path(__file__).resolve().parent.parent
GOLDEN = ROOT / "tests" / "golden" / "rollover"
SHORT_JOB = ROOT / "tests" / "golden" / "post" / "short_job.apt"
REGEN = os.environ.get("URDFPOST_REGEN_GOLDEN") == "1"
CONTROLS = sorted(DIALECTS)

#: The lines of each control's cycle for the short job (tolerance 0.01 mm, 0.5 deg).
SMOOTHING_ON = {
    "heidenhain": [
        "CYCL DEF 32.0 TOLERANCE",
        "CYCL DEF 32.1 T0.01",
        "CYCL DEF 32.2 HSC-MODE:0 TA0.5",
    ],
    "siemens": ["CYCLE832(0.01,_ORI_FINISH,0.5)"],
    "fanuc": ["G05.1 Q1"],
    "linuxcnc": ["G64 P0.01 Q0.01"],
}
SMOOTHING_OFF = {
    "heidenhain": ["CYCL DEF 32.0 TOLERANCE", "CYCL DEF 32.1"],
    "siemens": ["CYCLE832(0,_OFF,1)"],
    "fanuc": ["G05.1 Q0"],
    "linuxcnc": ["G64"],
}


def spiral_apt(turns: float = 2.75, step: float = 5.0, tilt: float = 20.0) -> str:
    """A spiral around the table's C axis, radius 20 mm, the tool tilted ``tilt`` degrees
    outwards and going down 0.01 mm per point, then a feed move across the pole."""
    s, c = math.sin(math.radians(tilt)), math.cos(math.radians(tilt))

    def point(k: int) -> tuple[float, ...]:
        t = math.radians(k * step)
        return 20 * math.cos(t), 20 * math.sin(t), -0.01 * k, s * math.cos(t), s * math.sin(t), c

    def goto(p: tuple[float, ...]) -> str:
        return "GOTO/{:.4f},{:.4f},{:.4f},{:.6f},{:.6f},{:.6f}".format(*p)

    n = round(turns * 360 / step)
    x, y, z, i, j, k = point(0)
    lines = [
        "PARTNO ROLLOVER SPIRAL",
        "UNITS/MM",
        "MULTAX/ON",
        "LOADTL/3",
        "CUTTER/6.0,3.0",
        "SPINDL/9000,CLW",
        "COOLNT/FLOOD",
        "RAPID",
        goto((x, y, z + 10, i, j, k)),
        "FEDRAT/MMPM,800",
        *(goto(point(m)) for m in range(n + 1)),
    ]
    x, y, z, i, j, k = point(n)
    lines += [goto((-x, -y, z, -i, -j, k)), "FINI"]
    return "\n".join(lines) + "\n"


def machine_variant(tmp_path: Path, name: str, attributes: str) -> Machine:
    """Machine ``name`` of robots/ with ``attributes`` added to its ``<urdfpost>`` element."""
    text = (ROOT / "robots" / "urdf" / f"{name}.urdf").read_text()
    text, n = re.subn(r"<urdfpost ", f"<urdfpost {attributes} ", text, count=1)
    assert n == 1
    path = tmp_path / f"{name}-variant.urdf"
    path.write_text(text)
    return load_machine(str(path))


@pytest.fixture(scope="module")
def work(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("smooth")


@pytest.fixture(scope="module")
def spiral(work: Path) -> Toolpath:
    path = work / "spiral.apt"
    path.write_text(spiral_apt())
    return read_cl(str(path))


@pytest.fixture(scope="module")
def rolling(work: Path) -> Machine:
    return machine_variant(work, "dmu50", 'rollover="C"')


def c_values(program: Program) -> np.ndarray:
    """The C column of the program's moves, filled forward over the moves that leave it out."""
    column = program.move_table().position[:, program.axes.index("C")]
    known = ~np.isnan(column)
    index = np.maximum.accumulate(np.where(known, np.arange(len(column)), 0))
    return np.where(known[index], column[index], np.nan)


def written_c(text: str) -> list[float]:
    """Every C value written in ``text`` (Siemens ``C=DC(..)`` too)."""
    return [float(v) for v in re.findall(r"\bC(?:=DC\()?([+-]?\d+\.\d+)", text)]


def without_smoothing(text: str, controller: str) -> list[str]:
    """The lines of ``text`` but the control's smoothing lines, block numbers dropped."""
    cycle = set(SMOOTHING_ON[controller]) | set(SMOOTHING_OFF[controller])
    lines = [re.sub(r"^\d+ ", "", line) for line in text.splitlines()]
    return [line for line in lines if line not in cycle]


# -- smoothing -------------------------------------------------------------------------------


@pytest.mark.parametrize("controller", CONTROLS)
def test_smoothing_on_and_off(controller: str) -> None:
    """On (the default): the cycle before the tool's approach, the cancel at the end, both
    read back; off: the same program without them."""
    job, m = read_cl(str(SHORT_JOB)), load_machine("dmu50")
    on = post(job, m, PostOptions(strategy="recursive", controller=controller))
    off = post(job, m, PostOptions(strategy="recursive", controller=controller, smoothing=False))
    lines = [re.sub(r"^\d+ ", "", line) for line in on.text.splitlines()]
    first = lines.index(SMOOTHING_ON[controller][0])
    assert lines[first : first + len(SMOOTHING_ON[controller])] == SMOOTHING_ON[controller]
    cut = next(k for k, line in enumerate(lines) if re.search(r"F600\.?$", line))
    tool = next(k for k, line in enumerate(lines) if re.match(r"(T5\b|TOOL CALL 5)", line))
    assert tool < first < cut
    off_lines = SMOOTHING_OFF[controller]
    end = len(lines) - lines[::-1].index(off_lines[-1]) - 1
    assert lines[end - len(off_lines) + 1 : end + 1] == off_lines
    assert end > max(k for k, line in enumerate(lines) if line.startswith(("G0 B", "L B")))
    assert without_smoothing(on.text, controller) == without_smoothing(off.text, controller)
    dialect = DIALECTS[controller]
    back = [b for b in dialect.read(on.text).blocks if isinstance(b, Smoothing)]
    tolerance = None if controller == "fanuc" else 0.01
    angle = 0.5 if controller in ("heidenhain", "siemens") else None
    assert back == [Smoothing(True, tolerance, angle), Smoothing(False)]
    assert not [b for b in dialect.read(off.text).blocks if isinstance(b, Smoothing)]
    assert on.verification.ok and off.verification.ok


@pytest.mark.parametrize(
    ("controller", "line"),
    [
        ("heidenhain", "CYCL DEF 32.1 T0.005"),
        ("siemens", "CYCLE832(0.005,_ORI_FINISH,0.5)"),
        ("linuxcnc", "G64 P0.005 Q0.005"),
    ],
)
def test_smoothing_tolerance_option(controller: str, line: str) -> None:
    job, m = read_cl(str(SHORT_JOB)), load_machine("dmu50")
    options = PostOptions(strategy="recursive", controller=controller, smoothing_tolerance=0.005)
    result = post(job, m, options)
    assert re.search(rf"^(\d+ )?{re.escape(line)}$", result.text, re.M)
    back = [b for b in DIALECTS[controller].read(result.text).blocks if isinstance(b, Smoothing)]
    assert back[0].tolerance == pytest.approx(0.005)


def test_smoothing_tolerance_in_inch_programs() -> None:
    job, m = read_cl(str(SHORT_JOB)), load_machine("dmu50")
    options = PostOptions(strategy="recursive", controller="heidenhain", units="inch")
    assert "CYCL DEF 32.1 T0.0004\n" in post(job, m, options).text  # the 0.0004 in default
    options = replace(options, smoothing_tolerance=0.001)
    text = post(job, m, options).text
    assert "CYCL DEF 32.1 T0.001\n" in text
    back = [b for b in DIALECTS["heidenhain"].read(text).blocks if isinstance(b, Smoothing)]
    assert back[0].tolerance == pytest.approx(0.0254)


def test_smoothing_setting_of_the_machine_file(tmp_path: Path) -> None:
    job = read_cl(str(SHORT_JOB))
    m = machine_variant(tmp_path, "dmu50", 'smoothing="off"')
    assert not m.settings.smoothing and load_machine("dmu50").settings.smoothing
    options = PostOptions(strategy="recursive", controller="fanuc")
    assert "G05.1" not in post(job, m, options).text
    assert "G05.1 Q1" in post(job, m, replace(options, smoothing=True)).text


def test_smoothing_is_off_for_each_tool_change(tmp_path: Path) -> None:
    from jobs import TWO_TOOLS

    path = tmp_path / "two.apt"
    path.write_text(TWO_TOOLS)
    result = post(read_cl(str(path)), load_machine("dmu50"), PostOptions(controller="siemens"))
    back = DIALECTS["siemens"].read(result.text).blocks
    order = [
        ("on" if b.on else "off") if isinstance(b, Smoothing) else "tool"
        for b in back
        if isinstance(b, Smoothing | ToolChange)
    ]
    assert order == ["tool", "on", "off", "tool", "on", "off"]


@pytest.mark.parametrize(
    ("controller", "text", "blocks"),
    [
        (
            "heidenhain",
            "0 CYCL DEF 32.0 TOLERANZ\n1 CYCL DEF 32.1 T0.02\n",
            [Smoothing(True, 0.02)],
        ),
        (
            "heidenhain",
            "0 CYCL DEF 32.0 TOLERANCE\n1 CYCL DEF 32.1 T0.02\n2 CYCL DEF 32.2 HSC-MODE:1 TA1\n",
            [Smoothing(True, 0.02, 1.0)],
        ),
        ("heidenhain", "0 CYCL DEF 32.0 TOLERANCE\n1 CYCL DEF 32.1\n", [Smoothing(False)]),
        ("siemens", "CYCLE832(0.02,_FINISH,1)\n", [Smoothing(True, 0.02)]),
        ("siemens", "CYCLE832(0.02,_ORI_ROUGH,2)\n", [Smoothing(True, 0.02, 2.0)]),
        ("siemens", "CYCLE832(0.02,11,1.5)\n", [Smoothing(True, 0.02, 1.5)]),
        ("siemens", "CYCLE832()\nCYCLE832(0,_OFF,1)\n", [Smoothing(False), Smoothing(False)]),
        (
            "fanuc",
            "G05.1 Q1\nG5.1 Q3\nG05.1 Q0\n",
            [Smoothing(True), Smoothing(True), Smoothing(False)],
        ),
        ("fanuc", "G05.1 Q1 R5\n", [Smoothing(True)]),
        ("linuxcnc", "G64 P0.02\nG64\n", [Smoothing(True, 0.02), Smoothing(False)]),
        ("linuxcnc", "G20\nG64 P0.001 Q0.001\n", [Smoothing(True, 0.001 * 25.4)]),
    ],
)
def test_smoothing_is_read(controller: str, text: str, blocks: list[Smoothing]) -> None:
    got = [b for b in DIALECTS[controller].read(text).blocks if isinstance(b, Smoothing)]
    assert got == blocks


@pytest.mark.parametrize(
    ("controller", "text", "match"),
    [
        ("heidenhain", "0 CYCL DEF 32.1 T0.01\n1 CYCL DEF 32.2 TA\n", "unreadable"),
        ("heidenhain", "0 CYCL DEF 32.0 TOLERANCE\n1 CYCL DEF 32.1 X0.01\n", "32.1 T<tol"),
        ("heidenhain", "0 CYCL DEF 32.2 HSC-MODE:0 TA0.5\n", "right after the path tolerance"),
        ("heidenhain", "0 CYCL DEF 32.0 SPEED\n", "expected CYCL DEF 32.0 TOLERANCE"),
        ("heidenhain", "0 CYCL DEF 32.1 T-0.01\n", "must be positive"),
        ("siemens", "CYCLE832(0.01,_FAST,1)\n", "machining type '_FAST'"),
        ("siemens", "CYCLE832\n", "argument list"),
        ("fanuc", "G05.1 Q7\n", "Q0 \\(off\\), Q1"),
        ("fanuc", "G05.1\n", "Q0 \\(off\\), Q1"),
    ],
)
def test_smoothing_errors(controller: str, text: str, match: str) -> None:
    with pytest.raises(ProgramParseError, match=match):
        DIALECTS[controller].read(text)


def test_smoothing_rs274(tmp_path: Path) -> None:
    """The interpreter sets the blending tolerance before the first cut and drops it at the
    end."""
    job, m = read_cl(str(SHORT_JOB)), load_machine("dmu50")
    result = post(job, m, PostOptions(strategy="recursive", controller="linuxcnc"))
    run = run_rs274(result.text, {5: 100.0}, tmp_path)
    names = [c.name for c in run.calls]
    modes = run.named("SET_MOTION_CONTROL_MODE")
    assert [c.args for c in modes] == [("CANON_CONTINUOUS", 0.01), ("CANON_CONTINUOUS", 0.0)]
    first_feed = names.index("STRAIGHT_FEED")
    assert run.calls.index(modes[0]) < first_feed
    last_feed = len(names) - 1 - names[::-1].index("STRAIGHT_FEED")
    assert run.calls.index(modes[1]) > last_feed


def test_smoothing_command_line(tmp_path: Path) -> None:
    out = tmp_path / "p.h"
    args = ["post", str(SHORT_JOB), "-m", "dmu50", "-c", "heidenhain", "-o", str(out)]
    assert main([*args, "--smoothing", "0.02", "--strategy", "recursive"]) == 0
    assert "CYCL DEF 32.1 T0.02\n" in out.read_text()
    assert main([*args, "--smoothing", "--strategy", "recursive"]) == 0
    assert "CYCL DEF 32.1 T0.01\n" in out.read_text()
    assert main([*args, "--no-smoothing", "--strategy", "recursive"]) == 0
    assert "CYCL DEF 32" not in out.read_text()
    with pytest.raises(SystemExit):
        main([*args, "--smoothing", "0"])


def test_smoothing_tolerance_must_be_positive() -> None:
    job, m = read_cl(str(SHORT_JOB)), load_machine("dmu50")
    with pytest.raises(UrdfpostError, match="smoothing tolerance -1"):
        post(job, m, PostOptions(strategy="recursive", smoothing_tolerance=-1.0))


@pytest.mark.parametrize(
    ("attributes", "match"),
    [
        ('smoothing="maybe"', r"<urdfpost smoothing='maybe'>: expected on or off"),
        (
            'rollover="B"',
            r"<urdfpost rollover='B'>: expected continuous joints of the chain, each once \(C\)",
        ),
        ('rollover="C C"', "each once"),
        ('rollover=""', "expected continuous joints"),
    ],
)
def test_machine_file_settings_are_checked(tmp_path: Path, attributes: str, match: str) -> None:
    with pytest.raises(MachineDefinitionError, match=r"dmu50-variant\.urdf:\d+: .*" + match):
        machine_variant(tmp_path, "dmu50", attributes)


# -- rollover ----------------------------------------------------------------------------------


def test_rollover_target() -> None:
    assert rollover_target(350.0, 10.0, "shortest") == 370.0
    assert rollover_target(10.0, 350.0, "shortest") == -10.0
    assert rollover_target(720.0 + 350.0, 10.0, "direct") == 720.0 + 10.0
    assert rollover_target(math.nan, 10.0, "shortest") == 10.0
    # LinuxCNC's unwrap_rotary: the sign is the direction, even for zero
    assert rollover_target(10.0, -350.0, "sign") == -10.0
    assert rollover_target(10.0, -0.0, "sign") == 0.0
    assert rollover_target(10.0, 0.0, "sign") == 360.0
    assert rollover_target(-10.0, 5.0, "sign") == 5.0
    with pytest.raises(ValueError, match="unknown rollover direction"):
        rollover_target(0.0, 1.0, "up")


def test_with_rollover_splits_long_turns_and_shortens_positioning() -> None:
    axes, tol = ("X", "C"), Tolerances()
    nan = math.nan
    table = MoveTable(
        position=np.array([[0.0, 10.0], [10.0, 400.0], [nan, 1000.0], [nan, 0.0], [5.0, 10.0]]),
        rapid=np.array([False, False, True, True, False]),
        feed=np.array([100.0, 100.0, nan, nan, 100.0]),
        cl_line=np.array([1, 2, -1, -1, 3]),
    )
    parts, state = with_rollover(
        [table, MachineMove(("C",), (720.0,)), Home(), Move(True, (nan, 200.0))],
        axes,
        frozenset({"C"}),
        tol,
    )
    rows = parts[0]
    assert isinstance(rows, MoveTable)
    c = rows.position[:, 1].tolist()
    # 10 -> 400 (390 deg) in three equal feed moves on the line X 0 -> 10; the positioning
    # rapids take the shortest way (400 -> 1000 is 240 the short way: -120, then 1000 -> 0 is
    # +80), and the rows after them keep their poses (shifted by whole turns)
    assert c == pytest.approx([10.0, 140.0, 270.0, 400.0, 280.0, 360.0, 370.0])
    assert rows.position[1:4, 0].tolist() == pytest.approx([10 / 3, 20 / 3, 10.0])
    assert rows.cl_line.tolist()[:4] == [1, -1, -1, 2] and rows.feed[1:4].tolist() == [100.0] * 3
    ends = {0: 10.0, 3: 400.0, 4: 1000.0, 5: 0.0, 6: 10.0}  # rows that end a move as given
    assert all(abs(c[k] - t) % 360.0 < 1e-9 for k, t in ends.items())
    assert state.splits == 1
    machine_move = parts[1]
    assert isinstance(machine_move, MachineMove) and machine_move.values == (360.0,)
    after_home = parts[3]  # from where the home return left C: the value, by whole turns
    assert isinstance(after_home, Move) and after_home.position[1] % 360.0 == 200.0
    unchanged, _ = with_rollover([table], axes, frozenset(), tol)
    assert unchanged == [table]


@pytest.mark.parametrize("controller", CONTROLS)
def test_rollover_golden(controller: str, spiral: Toolpath, rolling: Machine) -> None:
    result = post(spiral, rolling, PostOptions(controller=controller))
    path = GOLDEN / f"dmu50_{controller}{DIALECTS[controller].extensions[0]}"
    if REGEN:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(result.text)
    assert result.text == path.read_text(), f"{path.name} differs (URDFPOST_REGEN_GOLDEN=1)"
    assert result.program.rollover == frozenset({"C"})
    values = written_c(result.text)
    signed = controller == "linuxcnc"  # (the sign is the direction)
    assert values and all((-360.0 < v if signed else 0.0 <= v) and v < 360.0 for v in values)
    back = DIALECTS[controller].read(result.text, rollover=frozenset({"C"}))
    c = c_values(back)
    steps = np.abs(np.diff(c[~np.isnan(c)]))
    # the path winds up 2.75 turns and the end goes the short way home
    assert np.nanmax(c) - np.nanmin(c) > 2.5 * 360
    assert steps.max() <= 179.0 + 1e-6
    assert result.verification.ok
    assert result.verification.max_rotary_step_deg["C"] <= 90.0 + 1e-6  # the split half turn
    v = verify(back, rolling, spiral, tool_length=rolling.settings.tool_length)
    assert v.ok


def test_counting_turns_unwinds_at_the_end(spiral: Toolpath) -> None:
    """Without rollover the program counts turns: the end turns C back all of them."""
    result = post(spiral, load_machine("dmu50"), PostOptions(controller="fanuc"))
    assert result.program.rollover == frozenset()
    back = DIALECTS["fanuc"].read(result.text)
    assert max(written_c(result.text)) > 900.0
    assert result.verification.max_rotary_step_deg["C"] > 900.0
    assert back.move_table().position[-1, back.axes.index("C")] == 0.0


def test_rollover_rs274(spiral: Toolpath, rolling: Machine, tmp_path: Path) -> None:
    """LinuxCNC's interpreter, with C wrapped, turns C as the reader does at every cut; without
    WRAPPED_ROTARY it reads the signed values as positions and does not."""
    result = post(spiral, rolling, PostOptions(controller="linuxcnc"))
    back = DIALECTS["linuxcnc"].read(result.text, rollover=frozenset({"C"}))
    table = back.move_table()
    c = c_values(back)[~table.rapid]
    tools = {3: rolling.settings.tool_length}
    run = run_rs274(result.text, tools, tmp_path / "wrapped", wrapped=("C",))
    canon = np.array([call.number(5) for call in run.named("STRAIGHT_FEED")])
    assert len(canon) == len(c) > 60
    assert np.abs(canon - c).max() < 1e-4
    plain = run_rs274(result.text, tools, tmp_path / "plain")
    plain_c = np.array([call.number(5) for call in plain.named("STRAIGHT_FEED")])
    assert np.abs(plain_c - c).max() > 180.0


def test_rollover_streamed_is_the_whole_post(
    spiral: Toolpath, rolling: Machine, work: Path, tmp_path: Path
) -> None:
    options = PostOptions(controller="linuxcnc")
    whole = post(spiral, rolling, options)
    source = work / "spiral.apt"
    out = tmp_path / "spiral.ngc"
    result = post_stream(
        read_cl_chunks(str(source), max_points=20),
        rolling,
        out,
        options,
        piece_points=20,
        parallel=False,
    )
    assert result.report.as_json()["streamed"]["pieces"] > 2
    assert out.read_text() == whole.text


@pytest.mark.parametrize(
    ("controller", "edit"),
    [
        # the control without M126 (M127): a modulo axis goes to the value without passing 0
        ("heidenhain", lambda text: re.sub(r"^(\d+) M126$", r"\1 M127", text, flags=re.M)),
        # C= without DC: under G90 the default MD30455 goes without passing 0 as well
        ("siemens", lambda text: text.replace("C=DC(", "C=AC(")),
        # a sign turned: LinuxCNC turns the other way round, almost a whole turn
        (
            "linuxcnc",
            lambda text: re.sub(
                r"^(X\S+ Y\S+ Z\S+) C(\d+\.\d+)$", r"\1 C-\2", text, count=1, flags=re.M
            ),
        ),
    ],
)
def test_the_verifier_catches_a_wrong_direction(
    controller: str, edit, spiral: Toolpath, rolling: Machine
) -> None:
    result = post(spiral, rolling, PostOptions(controller=controller))
    text = edit(result.text)
    assert text != result.text
    back = DIALECTS[controller].read(text, rollover=frozenset({"C"}))
    v = verify(back, rolling, spiral, tool_length=rolling.settings.tool_length)
    assert not v.ok
    assert v.max_orientation_deviation_deg > 10.0


def test_the_verifier_catches_a_control_that_counts_turns(
    spiral: Toolpath, rolling: Machine
) -> None:
    """A rollover program on a control that counts turns (Fanuc: no rollover parameter): read
    as absolute positions, C turns the long way across 0 and the tool axis leaves the path."""
    result = post(spiral, rolling, PostOptions(controller="fanuc"))
    back = DIALECTS["fanuc"].read(result.text)
    v = verify(back, rolling, spiral, tool_length=rolling.settings.tool_length)
    assert not v.ok and v.max_orientation_deviation_deg > 10.0


def test_a_half_turn_is_refused(
    monkeypatch: pytest.MonkeyPatch, spiral: Toolpath, rolling: Machine
) -> None:
    """Without the split the half turn across the pole is written as one block, which a
    control that takes the shortest way could take either way: the read-back refuses it."""

    def no_split(parts, axes, rollover, tol, start=None):  # type: ignore[no-untyped-def]
        return with_rollover(
            parts, axes, rollover, replace(tol, rollover_turn=math.radians(359)), start
        )

    monkeypatch.setattr(piece_module, "with_rollover", no_split)
    with pytest.raises(ProgramParseError, match="half a turn from 270"):
        post(spiral, rolling, PostOptions(controller="fanuc"))


def test_nx_project_rollover(tmp_path: Path) -> None:
    """The 15-operation NX job on the UMC-750 whose C rolls over: 6 half turns at poles split,
    the end 150 degrees the short way instead of 5610 back (15.6 turns; 6330 while its ball-end
    tool 3 was planned with the flat tools before it, about their tip, not in a tool section
    of its own about its ball centre)."""
    cl = Path("/work/shared/testdata/cl/nx_project2_15ops_inch.cls")
    if not cl.exists():
        pytest.skip("the NX test data is not here")
    toolpath = read_cl(str(cl))
    options = PostOptions(controller="fanuc", spindle=8000.0)
    counting = post(toolpath, load_machine("umc750"), options)
    assert counting.verification.max_rotary_step_deg["C"] == pytest.approx(5610.0)
    m = machine_variant(tmp_path, "umc750", 'rollover="C"')
    result = post(toolpath, m, options)
    assert result.verification.ok
    assert result.verification.max_rotary_step_deg["C"] == pytest.approx(150.0)
    assert len(result.program.moves()) == len(counting.program.moves()) + 6


def test_verify_reads_rollover_and_reports_smoothing(
    capsys: pytest.CaptureFixture[str], spiral: Toolpath, rolling: Machine, work: Path
) -> None:
    """``urdfpost verify`` reads the golden program as the machine's control does (C rolls
    over) and says what it does with the smoothing."""
    golden = GOLDEN / "dmu50_heidenhain.h"
    args = ["verify", "--machine", rolling.path, "--cl", str(work / "spiral.apt"), str(golden)]
    assert main(args) == 0
    out = capsys.readouterr().out
    assert "verification within tolerance" in out
    assert (
        "smoothing on 1 times (tolerance 0.0100 mm, rotary axes 0.500 deg), off 1 times, "
        "off at the end" in out
    )
    assert (
        main(["verify", "--machine", "dmu50", "--cl", str(work / "spiral.apt"), str(golden)]) == 1
    )
    assert "BEYOND TOLERANCE" in capsys.readouterr().out  # read as counting turns


def test_smoothing_tolerance_is_one_the_program_can_write() -> None:
    """A tool-tip tolerance below the program's last decimal gives the smallest tolerance
    the program can write; one asked for below it is refused."""
    job, m = read_cl(str(SHORT_JOB)), load_machine("dmu50")
    options = PostOptions(strategy="recursive", controller="linuxcnc", tolerance=0.01)
    with pytest.raises(UrdfpostError, match=r"below the program's last decimal \(0.001 mm\)"):
        post(job, m, replace(options, smoothing_tolerance=0.0004))
    from urdfpost.posting.options import resolve

    job_settings = resolve(replace(options, tolerance=1e-7), m, "mm")
    assert job_settings.smoothing == Smoothing(True, 0.001)
