"""NC control dialects: golden output, write/read round trips, lookup and parse errors.

Regenerate the golden files after an intended output change with
``URDFPOST_REGEN_GOLDEN=1 pytest tests/test_dialects.py`` and inspect the diff.
"""

from __future__ import annotations

import math
import os
import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import urdfpost.dialects as dialects_module
import urdfpost.dialects.reader as reader_module
import urdfpost.dialects.writer as writer_module
from urdfpost.dialects import DIALECTS, Dialect, dialect_for
from urdfpost.errors import DialectError, ProgramParseError
from urdfpost.program import (
    Block,
    Comment,
    Coolant,
    Home,
    Insert,
    Move,
    Program,
    Smoothing,
    Spindle,
    Stop,
    Tcp,
    ToolChange,
)
from urdfpost.units import mm_per_unit

GOLDEN = Path(__file__).parent / "golden" / "dialects"
REGEN = os.environ.get("URDFPOST_REGEN_GOLDEN") == "1"
NAMES = sorted(DIALECTS)

#: Text inserted verbatim, chosen so that the reader understands it.
INSERTS = {
    "heidenhain": "CYCL DEF 32.0 TOLERANCE\nCYCL DEF 32.1 T0.01",
    "siemens": "G64",
    "fanuc": "G64",
    "linuxcnc": "G64 P0.01",
}
#: Controls whose insert above switches path smoothing on (read back as a Smoothing block).
SMOOTHING_INSERTS = frozenset({"heidenhain", "linuxcnc"})


def sample_mm(insert: str) -> Program:
    """Five-axis BC program in mm with TCP, two tools, every kind of block."""
    axes = ("X", "Y", "Z", "B", "C")
    blocks: tuple[Block, ...] = (
        Comment("Roughing (T1: D10 flat); pass 1"),
        ToolChange(1, length=75.0, diameter=10.0, name="FLAT D10"),
        Spindle("cw", 12000),
        Coolant("flood"),
        Tcp(True),
        Move(True, (10.0, -5.0, 50.0, 0.0, 90.0)),
        Move(False, (10.0, -5.0, 2.0, 0.0, 90.0), feed=500.0, cl_line=12),
        Move(False, (12.3456, -5.0, 2.0, 10.0, -20.5), feed=None, cl_line=13),
        Move(False, (-0.0004, -5.0, -1.25, 10.0, -20.5), feed=1250.5, cl_line=14),
        Move(False, (-0.0004, -5.0, -1.25, 10.0, -20.5), feed=1250.5, cl_line=15),
        Insert(insert),
        Move(True, (-0.0004, -5.0, 50.0, 10.0, -20.5)),
        Tcp(False),
        Stop(optional=True),
        Spindle("off"),
        Coolant("off"),
        Home(),
        Comment("Finishing"),
        ToolChange(2),
        Spindle("ccw", 8000),
        Coolant("mist"),
        Tcp(True),
        Move(True, (0.0, 0.0, 30.0, -45.0, 370.0)),
        Move(False, (5.5, -7.25, 0.5, -45.0, 370.0), feed=800.0),
        Move(False, (5.5, -7.25, 0.5, -44.9999, 371.0), feed=800.0),
        Tcp(False),
        Spindle("off"),
        Coolant("off"),
        Stop(),
        Home(),
    )
    return Program(
        name="Demo part 1",
        axes=axes,
        rotary=frozenset("BC"),
        units="mm",
        tcp=True,
        blocks=blocks,
        tool_length=75.0,
        continuous=frozenset("C"),
    )


def sample_inch(insert: str) -> Program:
    """Machine-coordinate (no TCP) AC program written in inch."""
    blocks: tuple[Block, ...] = (
        Comment("inch program"),
        ToolChange(7),
        Spindle("cw", 9000),
        Coolant("flood"),
        Move(True, (25.4, -50.8, 127.0, 0.0, 0.0)),
        Move(False, (25.4, -50.8, 2.54, 0.0, 0.0), feed=254.0),
        Move(False, (26.67, -49.53, 2.54, -30.0, 45.0), feed=635.0),
        Insert(insert),
        Move(True, (26.67, -49.53, 127.0, -30.0, 45.0)),
        Spindle("off"),
        Coolant("off"),
        Home(),
    )
    return Program(
        name="INCH1",
        axes=("X", "Y", "Z", "A", "C"),
        rotary=frozenset("AC"),
        units="inch",
        tcp=False,
        blocks=blocks,
    )


SAMPLES = {"mm": sample_mm, "inch": sample_inch}


# -- helpers ---------------------------------------------------------------------------------


def expected_blocks(program: Program, dialect: Dialect) -> list[Block]:
    """The non-motion blocks reading ``dialect.write(program)`` gives back, in order.

    Inserts are not recoverable; comments come back as written; TCP and spindle blocks only when
    the state changes; coolant modes without a code come back as flood; a coolant stop right
    after another (no coolant on, stop or insert between) is not written; consecutive home
    returns are one.
    """
    out: list[Block] = []
    tcp = False
    spindle = ("off", 0.0)
    coolant_off = False  # the last coolant block written stopped it
    for block in program.blocks:
        if isinstance(block, Stop | Insert):
            coolant_off = False
        match block:
            case Insert():
                # the inserts of Heidenhain and LinuxCNC switch path smoothing on (T0.01, P0.01)
                if block.text == INSERTS.get(dialect.name) and dialect.name in SMOOTHING_INSERTS:
                    out.append(Smoothing(True, 0.01 * mm_per_unit(program.units)))
                continue
            case Comment():
                out.append(Comment(dialect.comment_text(block.text)))
            case Tcp():
                if block.on != tcp:
                    tcp = block.on
                    out.append(block)
            case Spindle():
                state = (block.direction, 0.0 if block.direction == "off" else float(block.rpm))
                if state != spindle:
                    spindle = state
                    out.append(Spindle(*state))
            case Coolant():
                if block.mode == "off" and coolant_off:
                    continue
                coolant_off = block.mode == "off"
                out.append(Coolant("flood" if block.mode in ("through", "air") else block.mode))
            case ToolChange():
                out.append(ToolChange(block.number))
            case Home():
                if not (out and isinstance(out[-1], Home)):
                    out.append(block)
            case Move():
                out.append(Move(block.rapid, (), None))
            case _:
                out.append(block)
    return out


def expected_feeds(program: Program) -> list[float | None]:
    """Modal feed of every move (None for rapids and before the first F)."""
    feeds: list[float | None] = []
    modal = None
    for move in program.moves():
        if not move.rapid and move.feed is not None:
            modal = move.feed
        feeds.append(None if move.rapid else modal)
    return feeds


def assert_round_trip(program: Program, dialect: Dialect, block_numbers: bool | None) -> None:
    """write -> read gives the same program within the output rounding."""
    text = dialect.write(program, block_numbers=block_numbers)
    back = dialect.read(text, path="rt" + dialect.extensions[0])
    if program.moves():
        assert back.axes == program.axes
        assert back.rotary == program.rotary
    assert back.units == program.units
    if any(not m.rapid for m in program.moves()):
        assert back.tcp == _tcp_at_first_feed(program)
    shapes = [Move(b.rapid, (), None) if isinstance(b, Move) else b for b in back.blocks]
    assert shapes == expected_blocks(program, dialect)
    moves = back.moves()
    assert len(moves) == len(program.moves())
    tolerances = [dialect.resolution(a, program.units) / 2 + 1e-9 for a in program.axes]
    feed_tolerance = dialect.resolution("F", program.units) / 2 + 1e-9
    for got, want, feed in zip(moves, program.moves(), expected_feeds(program), strict=True):
        assert got.rapid == want.rapid
        pairs = zip(program.axes, got.position, want.position, tolerances, strict=True)
        for axis, g, w, tol in pairs:
            assert abs(g - w) <= tol, (axis, g, w, text)
        if feed is None:
            assert got.feed is None
        else:
            assert got.feed is not None and abs(got.feed - feed) <= feed_tolerance


def _tcp_at_first_feed(program: Program) -> bool:
    tcp = False
    for block in program.blocks:
        if isinstance(block, Tcp):
            tcp = block.on
        if isinstance(block, Move) and not block.rapid:
            return tcp
    return tcp


def read(dialect: str, text: str, path: str = "prog.nc") -> Program:
    return DIALECTS[dialect].read(text, path=path)


# -- golden files ----------------------------------------------------------------------------


@pytest.mark.parametrize("units", sorted(SAMPLES))
@pytest.mark.parametrize("name", NAMES)
def test_golden(name: str, units: str) -> None:
    dialect = DIALECTS[name]
    program = SAMPLES[units](INSERTS[name])
    text = dialect.write(program)
    path = GOLDEN / f"{name}_{units}{dialect.extensions[0]}"
    if REGEN or not path.exists():
        if not REGEN:
            pytest.fail(f"missing golden file {path}; run with URDFPOST_REGEN_GOLDEN=1")
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    assert text == path.read_text()


@pytest.mark.parametrize("units", sorted(SAMPLES))
@pytest.mark.parametrize("name", NAMES)
def test_golden_reads_back(name: str, units: str) -> None:
    dialect = DIALECTS[name]
    program = SAMPLES[units](INSERTS[name])
    assert_round_trip(program, dialect, None)


@pytest.mark.parametrize("name", NAMES)
def test_write_read_write_is_stable(name: str) -> None:
    dialect = DIALECTS[name]
    program = sample_mm(INSERTS[name])
    program = Program(**{**vars(program), "blocks": tuple(
        b for b in program.blocks if not isinstance(b, Insert))})  # fmt: skip
    text = dialect.write(program)
    assert dialect.write(dialect.read(text)) == text


@pytest.mark.parametrize("name", NAMES)
def test_write_is_deterministic_and_header_is_comments(name: str) -> None:
    dialect = DIALECTS[name]
    program = sample_mm(INSERTS[name])
    assert dialect.write(program) == dialect.write(program)
    text = dialect.write(program, header="urdfpost 0.1\nmachine: demo")
    header = [dialect.comment_text("urdfpost 0.1"), dialect.comment_text("machine: demo")]
    assert all(line in text for line in header)
    comments = [b.text for b in dialect.read(text).blocks if isinstance(b, Comment)]
    assert comments[:2] == header


# -- what each control writes ----------------------------------------------------------------


def test_heidenhain_syntax() -> None:
    text = DIALECTS["heidenhain"].write(sample_mm(INSERTS["heidenhain"]))
    lines = text.splitlines()
    assert lines[0] == "0 BEGIN PGM DEMO_PART_1 MM"
    assert lines[-1] == f"{len(lines) - 1} END PGM DEMO_PART_1 MM"
    assert [int(line.split()[0]) for line in lines] == list(range(len(lines)))
    # the start resets what an earlier program may have left on (TCPM, a tilted plane)
    assert lines[1:3] == ["1 FUNCTION RESET TCPM", "2 PLANE RESET STAY"]
    assert "3 M126" in lines
    assert "5 TOOL CALL 1 Z S12000" in lines and "6 M3" in lines
    assert any(line.endswith("FUNCTION TCPM F TCP AXIS POS PATHCTRL AXIS") for line in lines)
    assert any(
        line.endswith("L X+10.000 Y-5.000 Z+50.000 B+0.0000 C+90.0000 FMAX") for line in lines
    )
    assert any(line.endswith("L Z+2.000 F500") for line in lines)
    assert any(line.endswith("L X+0.000 Z-1.250 F1250.5") for line in lines)  # -0.0004 -> +0.000
    assert any(line.endswith("; Roughing (T1: D10 flat); pass 1") for line in lines)
    assert any(line.endswith("L Z+0 R0 FMAX M91") for line in lines)
    assert "25 TOOL CALL 2 Z S8000" in lines and "26 M4" in lines


def test_heidenhain_speed_change_without_tool_change() -> None:
    blocks = (ToolChange(3), Coolant("flood"), Spindle("cw", 5000), Move(True, (1.0,)))
    blocks += (Spindle("cw", 6000), Spindle("ccw", 6000), Spindle("off"), Spindle("cw", 6000))
    dialect = DIALECTS["heidenhain"]
    text = dialect.write(Program("S", ("X",), frozenset(), "mm", False, blocks))
    assert text.splitlines()[3:-2] == [
        "3 TOOL CALL 3 Z S5000", "4 M8", "5 M3", "6 L X+1.000 FMAX", "7 TOOL CALL Z S6000",
        "8 M3", "9 M4", "10 M5", "11 M3",
    ]  # fmt: skip
    spindles = [b for b in dialect.read(text).blocks if isinstance(b, Spindle)]
    assert spindles == [Spindle("cw", 5000.0), Spindle("cw", 6000.0), Spindle("ccw", 6000.0),
                        Spindle("off"), Spindle("cw", 6000.0)]  # fmt: skip


def test_fanuc_syntax() -> None:
    text = DIALECTS["fanuc"].write(sample_mm(INSERTS["fanuc"]), block_numbers=True)
    lines = text.splitlines()
    assert lines[0] == "%" and lines[-1] == "%"
    assert lines[1] == "O1000 (DEMO PART 1)"
    assert "(ROUGHING [T1: D10 FLAT], PASS 1)" in lines
    assert any(line.endswith("G43.4 H1") for line in lines)
    assert any(line.endswith("G43.4 H2") for line in lines)
    assert any(line.endswith("G1 Z2.000 F500.") for line in lines)
    assert any(line.endswith("G28 G91 Z0.") for line in lines)
    assert lines[2].startswith("N10 ")
    numbered = DIALECTS["fanuc"].write(sample_mm(""), program_number=42)
    assert numbered.splitlines()[1] == "O0042 (DEMO PART 1)"


def test_fanuc_tcp_needs_a_tool() -> None:
    program = Program("P", ("X",), frozenset(), "mm", True, (Tcp(True), Move(True, (1.0,))))
    with pytest.raises(DialectError, match="ToolChange before the Tcp"):
        DIALECTS["fanuc"].write(program)


def test_linuxcnc_comments_stay_passive() -> None:
    dialect = DIALECTS["linuxcnc"]
    assert dialect.comment_text("MSG, hello (world)") == "MSG: hello [world]"
    assert dialect.comment_text("debug , x") == "debug: x"
    assert dialect.comment_text("a message, fine") == "a message, fine"


def test_siemens_and_linuxcnc_tcp_codes() -> None:
    siemens = DIALECTS["siemens"].write(sample_mm(INSERTS["siemens"])).splitlines()
    assert "TRAORI" in siemens and "TRAFOOF" in siemens and "G710" in siemens
    assert siemens[-1] == "M30"
    linuxcnc = DIALECTS["linuxcnc"].write(sample_mm(INSERTS["linuxcnc"])).splitlines()
    assert linuxcnc[linuxcnc.index("M428") - 1] == "G43 H1"
    assert linuxcnc[linuxcnc.index("M429", linuxcnc.index("M428")) + 1] == "G49"
    assert linuxcnc.index("M429") < linuxcnc.index("M428")  # TCP off at the start too
    assert linuxcnc[-1] == "M2"


def test_heidenhain_is_always_numbered() -> None:
    with pytest.raises(DialectError, match="always numbered"):
        DIALECTS["heidenhain"].write(sample_mm(""), block_numbers=False)


# -- round trip property ---------------------------------------------------------------------

AXIS_SETS = [
    ("X", "Y", "Z", "B", "C"),
    ("X", "Y", "Z", "A", "C"),
    ("X", "Y", "Z", "A"),
    ("X", "Y", "Z"),
]
LINEAR = st.floats(-2000, 2000, allow_nan=False)
ROTARY = st.floats(-720, 720, allow_nan=False)
FEED = st.one_of(st.none(), st.floats(1.0, 20000.0))
TEXT = st.text(st.sampled_from("abcXYZ 0123456789.,:;-_()"), max_size=20)


@st.composite
def programs(draw: st.DrawFn) -> Program:
    axes = draw(st.sampled_from(AXIS_SETS))
    rotary = frozenset(a for a in axes if a in "ABC")
    move = st.builds(
        Move,
        rapid=st.booleans(),
        position=st.tuples(*(ROTARY if a in rotary else LINEAR for a in axes)),
        feed=FEED,
    )
    other = st.one_of(
        st.builds(ToolChange, st.integers(1, 99)),
        st.builds(Spindle, st.sampled_from(["cw", "ccw"]), st.integers(100, 30000).map(float)),
        st.just(Spindle("off")),
        st.builds(Coolant, st.sampled_from(["flood", "mist", "off", "through"])),
        st.builds(Comment, TEXT),
        st.builds(Tcp, st.booleans()),
        st.builds(Stop, st.booleans()),
        st.just(Home()),
    )
    body = draw(st.lists(st.one_of(move, move, move, other), max_size=30))
    first_tool = ToolChange(draw(st.integers(1, 99)))
    return Program(
        name=draw(st.sampled_from(["P1", "part", "1234"])),
        axes=axes,
        rotary=rotary,
        units=draw(st.sampled_from(["mm", "inch"])),
        tcp=False,
        blocks=(first_tool, *body),
        continuous=draw(st.sampled_from([frozenset(), rotary])),
    )


@pytest.mark.parametrize("block_numbers", [False, True])
@pytest.mark.parametrize("name", NAMES)
@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(program=programs())
def test_round_trip(name: str, block_numbers: bool, program: Program) -> None:
    dialect = DIALECTS[name]
    if name == "heidenhain" and not block_numbers:
        block_numbers = True
    assert_round_trip(program, dialect, block_numbers)


# -- units -----------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("name", "x_word", "feed_word"),
    [
        ("heidenhain", "X+1.0000", "F100"),  # 10 in/min is F100 (0.1 in/min)
        ("siemens", "X1.0000", "F10"),
        ("fanuc", "X1.0000", "F10."),
        ("linuxcnc", "X1.0000", "F10"),
    ],
)
def test_inch_conversion(name: str, x_word: str, feed_word: str) -> None:
    dialect = DIALECTS[name]
    program = Program(
        "INCH",
        ("X", "Y", "Z", "B"),
        frozenset("B"),
        "inch",
        False,
        (ToolChange(1), Move(False, (25.4, -12.7, 0.0, 30.0), feed=254.0)),
    )
    text = dialect.write(program)
    line = next(line for line in text.splitlines() if x_word in line)
    assert feed_word in line.split()
    assert "Y-0.5000" in line and ("B+30.0000" in line or "B30.0000" in line)
    back = dialect.read(text)
    assert back.units == "inch"
    (move,) = back.moves()
    assert move.position == pytest.approx((25.4, -12.7, 0.0, 30.0), abs=1e-9)
    assert move.feed == pytest.approx(254.0)


def test_units_switch_in_program_are_followed() -> None:
    program = read("fanuc", "G21\nG0 X10.\nG20\nG0 X1.\nG1 X2. F10.\n")
    assert program.units == "mm"
    assert [m.position[0] for m in program.moves()] == pytest.approx([10.0, 25.4, 50.8])
    assert program.moves()[-1].feed == pytest.approx(254.0)


def test_siemens_g70_keeps_feed_units() -> None:
    program = read("siemens", "G710\nG70\nG1 X1 F100\n", "p.mpf")
    assert program.moves()[0].position == pytest.approx((25.4,))
    assert program.moves()[0].feed == pytest.approx(100.0)


# -- reading: modal state, NaN, hand-edited programs -----------------------------------------


def test_modal_axes_feed_and_motion_carried_forward() -> None:
    program = read("linuxcnc", "g21 g90\ng0 x1 y2 z3\ng1 z0 f200\nx5\ng0 z10\ny7\n", "p.ngc")
    assert program.axes == ("X", "Y", "Z")
    assert [m.position for m in program.moves()] == [
        (1.0, 2.0, 3.0),
        (1.0, 2.0, 0.0),
        (5.0, 2.0, 0.0),
        (5.0, 2.0, 10.0),
        (5.0, 7.0, 10.0),
    ]
    assert [m.rapid for m in program.moves()] == [True, False, False, True, True]
    assert [m.feed for m in program.moves()] == [None, 200.0, 200.0, None, None]


def test_unprogrammed_axes_are_nan() -> None:
    program = read("fanuc", "G0 X1.\nG1 Y2. F100.\nB10.\n")
    first, second, third = program.moves()
    assert program.axes == ("X", "Y", "B")
    assert first.position[0] == 1.0 and math.isnan(first.position[1])
    assert math.isnan(first.position[2]) and math.isnan(second.position[2])
    assert third.position == (1.0, 2.0, 10.0)


def test_fanuc_home_sequence_and_incremental() -> None:
    text = "G90 G0 X10. Y10. Z10.\nG28 G91 Z0.\nG28 X0. Y0.\nG90\nG0 X1.\nG91 G1 X2. F100.\n"
    program = read("fanuc", text)
    assert [type(b).__name__ for b in program.blocks] == ["Move", "Home", "Move", "Move"]
    after_home = program.moves()[1]
    assert after_home.position[0] == 1.0
    assert math.isnan(after_home.position[1]) and math.isnan(after_home.position[2])
    assert program.moves()[2].position[0] == 3.0


def test_heidenhain_hand_edited() -> None:
    text = "\n".join(
        [
            "0 BEGIN PGM P MM",
            "1 BLK FORM 0.1 Z X+0 Y+0 Z-20",
            "2 * - roughing",
            "3 TOOL CALL 5 Z S3000 F400",
            "4 M128",
            "5 L X+10 Y+0 Z+5 R0 FMAX M3 ; approach",
            "6 L Z-1",
            "7 L IX+5 F200",
            "8 L Z+50 FMAX",
            "9 L X+0 F100",
            "10 M129",
            "11 STOP M30",
            "12 END PGM P MM",
        ]
    )
    program = read("heidenhain", text, "p.h")
    assert program.name == "P" and program.tcp
    kinds = [type(b).__name__ for b in program.blocks]
    assert kinds == ["Comment", "ToolChange", "Tcp", "Spindle", "Move", "Comment", "Move",
                     "Move", "Move", "Move", "Tcp", "Stop"]  # fmt: skip
    assert program.blocks[3] == Spindle("cw", 3000.0)
    moves = program.moves()
    assert [m.position for m in moves] == [
        (10.0, 0.0, 5.0), (10.0, 0.0, -1.0), (15.0, 0.0, -1.0), (15.0, 0.0, 50.0), (0.0, 0.0, 50.0)
    ]  # fmt: skip
    assert [m.feed for m in moves] == [None, 400.0, 200.0, None, 100.0]


def test_siemens_hand_edited() -> None:
    text = "N10 G710 G90\nN20 T3 D1\nN30 M6\nN40 TRAORI(1)\nN50 G1 X=10 Y=AC(2) Z5 F300\n"
    text += "N60 X=IC(1.5) C=DC(270)\nN70 SUPA G0 Z0 D0\nN80 M30\n"
    program = read("siemens", text, "p.mpf")
    assert program.tcp and program.axes == ("X", "Y", "Z", "C")
    first, second = program.moves()
    assert first.position[:3] == (10.0, 2.0, 5.0) and math.isnan(first.position[3])
    assert second.position == (11.5, 2.0, 5.0, 270.0)
    assert isinstance(program.blocks[-1], Home)


@pytest.mark.parametrize("name", NAMES)
def test_inline_and_comment_only_lines(name: str) -> None:
    dialect = DIALECTS[name]
    text = dialect.write(
        Program("C", ("X",), frozenset(), "mm", False, (Comment("hello"), Move(True, (1.0,))))
    )
    assert Comment(dialect.comment_text("hello")) in dialect.read(text).blocks


# -- lookup ----------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("path", "name"),
    [
        ("part.h", "heidenhain"),
        ("PART.H", "heidenhain"),
        ("dir/part.mpf", "siemens"),
        ("sub.SPF", "siemens"),
        ("part.nc", "fanuc"),
        (Path("part.ngc"), "linuxcnc"),
    ],
)
def test_dialect_for_extension(path: str | Path, name: str) -> None:
    assert dialect_for(path=path).name == name


def test_dialect_for_name_wins_and_is_case_insensitive() -> None:
    assert dialect_for("Fanuc", path="x.h").name == "fanuc"
    assert dialect_for(" LINUXCNC ").name == "linuxcnc"


def test_unknown_controller_lists_known() -> None:
    with pytest.raises(DialectError, match=r"unknown control 'okuma'.*fanuc.*heidenhain.*linuxcnc"):
        dialect_for("okuma")
    known = r"fanuc \(\.nc\), heidenhain \(\.h\), linuxcnc \(\.ngc\), siemens \(\.mpf/\.spf\)"
    with pytest.raises(DialectError, match=rf"extension '\.txt'.*{known}"):
        dialect_for(path="prog.txt")
    with pytest.raises(DialectError, match="no control given"):
        dialect_for()


def test_dialects_order() -> None:
    assert list(DIALECTS) == ["heidenhain", "siemens", "fanuc", "linuxcnc"]
    assert all(name == dialect.name for name, dialect in DIALECTS.items())


#: The example of the urdfpost.dialects docstring: a control is one module.
_MAZAK = """
import dataclasses

from urdfpost.dialects import fanuc

RANK = 4

SPEC = dataclasses.replace(fanuc.SPEC, name="mazak", extensions=(".eia",))
"""


def control_package(root: Path, name: str, **modules: str) -> tuple[str, list[str]]:
    """A package ``name`` under ``root`` with the given modules: its name and path."""
    package = root / name
    package.mkdir()
    (package / "__init__.py").write_text("")
    for module, text in modules.items():
        (package / f"{module}.py").write_text(text)
    return name, [str(package)]


def test_a_control_is_one_module(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.syspath_prepend(str(tmp_path))
    fanuc = "from urdfpost.dialects.fanuc import SPEC\nRANK = 9\n"
    unranked = "import dataclasses\nfrom urdfpost.dialects.siemens import SPEC as S\n"
    name, path = control_package(
        tmp_path,
        "controls_a",
        mazak=_MAZAK,
        zz=unranked + 'SPEC = dataclasses.replace(S, name="zz", extensions=(".zz",))\n',
        aa=unranked + 'SPEC = dataclasses.replace(S, name="aa", extensions=(".aa",))\n',
        fanuc=fanuc,
        helper="X = 1\n",
        _private=unranked + "SPEC = S\n",
    )
    found = dialects_module._discover(name, path)
    assert list(found) == ["mazak", "fanuc", "aa", "zz"]  # by RANK, then unranked by name
    monkeypatch.setattr(dialects_module, "DIALECTS", found)
    mazak = dialect_for(path="part.EIA")
    assert mazak.name == "mazak" and dialect_for("Mazak") is mazak
    program = sample_mm(INSERTS["fanuc"])
    assert mazak.write(program) == DIALECTS["fanuc"].write(program)


@pytest.mark.parametrize(
    ("package", "modules", "message"),
    [
        (
            "controls_b",
            {
                "one": "from urdfpost.dialects.fanuc import SPEC\n",
                "two": "from urdfpost.dialects.fanuc import SPEC\n",
            },
            r"controls_b\.two: control 'fanuc' is declared twice",
        ),
        (
            "controls_c",
            {"one": "from urdfpost.dialects.fanuc import SPEC\nRANK = '1'\n"},
            r"controls_c\.one: expected an int RANK, got '1'",
        ),
    ],
)
def test_control_discovery_errors(
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    package: str,
    modules: dict[str, str],
    message: str,
) -> None:
    monkeypatch.syspath_prepend(str(tmp_path))
    name, path = control_package(tmp_path, package, **modules)
    with pytest.raises(TypeError, match=message):
        dialects_module._discover(name, path)


# -- parse errors ----------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("name", "text", "line", "match"),
    [
        ("fanuc", "G21\nG0 X1.2.3\n", 2, r"malformed number X1\.2\.3; expected e\.g\. X12\.345"),
        ("siemens", "G710\nG1 X1 F100\nY1.2.3\n", 3, r"malformed number Y1\.2\.3"),
        ("linuxcnc", "g21\ng0 z1..2\n", 2, r"malformed number Z1\.\.2"),
        ("heidenhain", "0 BEGIN PGM P MM\n1 L X+1.2.3 FMAX\n", 2, r"malformed number X\+1\.2\.3"),
        ("fanuc", "G0 X1. Y2.\nG1 X2. Q5. F100.\n", 2, r"unknown word Q5\.; expected"),
        ("linuxcnc", "g0 x1 y2\ng1 x2 u5 f100\n", 2, r"unknown word U5; expected"),
        ("siemens", "G0 X1\nG1 X2 ZZ=5\n", 2, r"unexpected ZZ="),
        ("heidenhain", "0 BEGIN PGM P MM\n1 L X+1 Q5 FMAX\n", 2, r"unknown word 'Q5' in L block"),
        ("fanuc", "G0 X10\n", 1, r"X10 has no decimal point.*expected X10\."),
        ("fanuc", "G0 X1.\nG2 X2. Y1. R1.\n", 2, r"unknown word R1\.; expected A B C F I J K"),
        ("linuxcnc", "g41 d1 p2\n", 1, r"unknown word P2; expected"),
        ("fanuc", "M50\n", 1, r"unknown M-code M50; this reader understands M0 M1"),
        ("fanuc", "X1.\n", 1, r"axis words before any motion mode; expected G0 or G1"),
        ("fanuc", "G0 G91 X1.\n", 1, r"incremental X move from an unknown position"),
        ("fanuc", "G0 X1.\nM30\nG0 X2.\n", 3, r"code after the program end"),
        ("linuxcnc", "g0 x1 (unclosed\n", 1, r"not closed; expected '\)'"),
        ("linuxcnc", "#1=5\n", 1, r"unexpected '#'"),
        ("heidenhain", "BEGIN PGM P MM\n", 1, r"expected a block number"),
        ("heidenhain", "0 BEGIN PGM P MM\n1 L X+1 R+ F100\n", 2, r"paraxial radius comp"),
        ("heidenhain", "0 BEGIN PGM P MM\n1 CYCL DEF 7.0 DATUM SHIFT\n", 2, r"unknown block"),
        ("heidenhain", "0 BEGIN PGM P MM\n1 L X+1 FMAX M140\n", 2, r"unknown M-code M140"),
        ("heidenhain", "0 BEGIN PGM P MM\n1 FUNCTION TCPM F TCP AXIS SPAT\n", 2, r"AXIS SPAT"),
        ("heidenhain", "0 BEGIN PGM P MM\n1 TOOL CALL 1 Z S100 DL+0.5\n", 2, r"DL\+0\.5"),
        ("heidenhain", "0 BEGIN PGM P MM\n1 TOOL CALL 1 X\n", 2, r"tool axis X"),
        ("siemens", 'T="MILL"\n', 1, r"unreadable value for T="),
        ("fanuc", "M6\n", 1, r"tool change without a tool number"),
    ],
)
def test_parse_errors(name: str, text: str, line: int, match: str) -> None:
    path = "job" + DIALECTS[name].extensions[0]
    with pytest.raises(ProgramParseError, match=rf"^job\.\w+:{line}: .*{match}") as info:
        DIALECTS[name].read(text, path=path)
    assert info.value.path == path and info.value.line == line


@pytest.mark.parametrize("name", NAMES)
def test_verbatim_inserts_are_trusted(name: str) -> None:
    dialect = DIALECTS[name]
    insert = "M50\nCYCLE832(0.01,_ORI_FINISH,1)"
    program = Program(
        "I",
        ("X",),
        frozenset(),
        "mm",
        False,
        (Move(True, (1.0,)), Insert(insert), Move(True, (2.0,))),
    )
    text = dialect.write(program)
    with pytest.raises(ProgramParseError):
        dialect.read(text)
    back = dialect.read(text, verbatim=[insert])
    cycle = "CYCLE832(0.01,_ORI_FINISH,1)"
    assert back.blocks == (Move(True, (1.0,)), Insert("M50"), Insert(cycle), Move(True, (2.0,)))


def test_parse_error_default_path() -> None:
    with pytest.raises(ProgramParseError, match=r"^<string>:1: "):
        DIALECTS["fanuc"].read("G0 X1.2.3")


def test_write_rejects_bad_programs() -> None:
    fanuc = DIALECTS["fanuc"]
    with pytest.raises(DialectError, match="distinct letters"):
        fanuc.write(Program("P", ("X", "U"), frozenset(), "mm", False, ()))
    with pytest.raises(DialectError, match="rotary"):
        fanuc.write(Program("P", ("X", "B"), frozenset(), "mm", False, ()))
    with pytest.raises(DialectError, match="units"):
        fanuc.write(Program("P", ("X",), frozenset(), "furlong", False, ()))
    with pytest.raises(DialectError, match="values for axes"):
        fanuc.write(Program("P", ("X",), frozenset(), "mm", False, (Move(True, (1.0, 2.0)),)))
    with pytest.raises(DialectError, match="spindle direction"):
        fanuc.write(Program("P", ("X",), frozenset(), "mm", False, (Spindle("up", 1.0),)))


def test_nan_axes_are_not_written() -> None:
    program = Program("P", ("X", "Y"), frozenset(), "mm", False, (Move(True, (1.0, math.nan)),))
    assert "G0 X1.000\n" in DIALECTS["linuxcnc"].write(program)


# -- many blocks at once: the same text and the same program as block by block ----------------


def _outcome(call):
    try:
        return call()
    except DialectError as exc:
        return (type(exc), str(exc))


def write_both(monkeypatch, dialect: Dialect, program: Program, **kwargs):
    """``dialect.write`` with runs of moves formatted at once, and block by block."""
    out = []
    for least in (2, 10**9):
        monkeypatch.setattr(writer_module, "BULK_MIN_MOVES", least)
        out.append(_outcome(lambda: dialect.write(program, **kwargs)))
    return out


def read_both(monkeypatch, dialect: Dialect, text: str, **kwargs):
    """``dialect.read`` with runs of plain motion blocks read at once, and line by line."""
    out = []
    for least in (1, 10**9):
        monkeypatch.setattr(reader_module, "BULK_MIN_LINES", least)
        # repr tells apart every float (and -0.0 from 0.0, NaN from numbers)
        out.append(_outcome(lambda: repr(dialect.read(text, **kwargs))))
    return out


#: Coordinates that exercise the formatting: exact repeats (modal axes), signed zeros, values
#: a hair from a rounding tie, long decimals, big numbers.
BULK_LINEAR = st.one_of(
    st.sampled_from([0.0, -0.0, 1.0, -0.0004, 0.0005, -0.0005, 2.5e-4, 12.3455, 0.1 + 0.2]),
    st.floats(-2000, 2000, allow_nan=False),
    st.integers(-99999, 99999).map(lambda k: k / 1000),
    st.integers(-99999, 99999).map(lambda k: k / 1000 + 0.0005),
)
BULK_ROTARY = st.one_of(BULK_LINEAR, st.floats(-720, 720))


@st.composite
def bulk_programs(draw: st.DrawFn) -> Program:
    """Programs with long runs of moves, repeated values and the odd special value."""
    axes = draw(st.sampled_from(AXIS_SETS))
    rotary = frozenset(a for a in axes if a in "ABC")
    values = st.tuples(*(BULK_ROTARY if a in rotary else BULK_LINEAR for a in axes))
    feed = st.one_of(st.none(), st.sampled_from([500.0, 500.04, 1250.5, 0.01, 3.0]), FEED)
    special = st.sampled_from(
        [
            Move(False, tuple(math.nan for _ in axes), 100.0),
            Move(False, (math.nan,) + (1.0,) * (len(axes) - 1), 100.0),
            Move(False, (1.0,) * len(axes), 0.0),
            Move(False, (1.0,) * len(axes), math.inf),
            Move(False, (math.inf,) * len(axes), 1.0),
            Move(False, (1.0,) * (len(axes) + 1), 1.0),
            Move(1, (1.0,) * len(axes), 1.0),  # type: ignore[arg-type]
            Move(False, (1e300,) * len(axes), 1.0),
        ]
    )

    def run(items: list) -> list[Move]:
        moves = []
        position = list(draw(values))
        for rapid, change, feed_value, new in items:
            position[change % len(axes)] = new[change % len(axes)]
            moves.append(Move(rapid, tuple(position), None if rapid else feed_value))
        return moves

    step = st.tuples(st.booleans(), st.integers(0, 5), feed, values)
    body: list[Block] = [ToolChange(draw(st.integers(1, 99)))]
    for _ in range(draw(st.integers(1, 4))):
        body += run(draw(st.lists(step, min_size=0, max_size=40)))
        if draw(st.integers(0, 9)) == 0:
            body.append(draw(special))
        body.append(
            draw(
                st.sampled_from(
                    [Tcp(True), Tcp(False), Comment("c"), Home(), Coolant("mist"), Stop(True)]
                )
            )
        )
    return Program(
        name="P1",
        axes=axes,
        rotary=rotary,
        units=draw(st.sampled_from(["mm", "inch"])),
        tcp=False,
        blocks=tuple(body),
        continuous=draw(st.sampled_from([frozenset(), rotary])),
    )


@pytest.mark.parametrize("name", NAMES)
@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(program=bulk_programs(), block_numbers=st.sampled_from([None, True]))
def test_bulk_write_and_read_equal_block_by_block(name, program, block_numbers) -> None:
    dialect = DIALECTS[name]
    with pytest.MonkeyPatch.context() as monkeypatch:
        bulk, single = write_both(monkeypatch, dialect, program, block_numbers=block_numbers)
        assert bulk == single
        if isinstance(bulk, str):
            back_bulk, back_single = read_both(monkeypatch, dialect, bulk)
            assert back_bulk == back_single


def _long_program(count: int) -> Program:
    moves = tuple(
        Move(k % 50 == 0, (k * 0.001, -(k % 977) * 0.01, 5.0, (k % 90) * 0.5, k * 0.1), 800.0)
        for k in range(count)
    )
    return Program(
        "LONG", ("X", "Y", "Z", "B", "C"), frozenset("BC"), "mm", False, (ToolChange(3), *moves)
    )


@pytest.mark.parametrize("name", NAMES)
def test_bulk_block_numbers_wrap(name, monkeypatch) -> None:
    """Fanuc and LinuxCNC numbers wrap after N99990; more rows than one chunk of the writer."""
    program = _long_program(12_000)
    numbers = None if name == "heidenhain" else True
    monkeypatch.setattr(reader_module, "_BULK_PIECE", 20_000)  # the text in many pieces
    bulk, single = write_both(monkeypatch, DIALECTS[name], program, block_numbers=numbers)
    assert bulk == single
    if name in ("fanuc", "linuxcnc"):
        assert "\nN99990 " in bulk and "\nN10 " in bulk.split("N99990", 1)[1]
    back_bulk, back_single = read_both(monkeypatch, DIALECTS[name], bulk)
    assert back_bulk == back_single


#: Lines that the bulk reader must leave to the line-by-line reader, or read the same way.
EDITS = {
    "gcode": [
        "G1 X1. Y2.",
        "G0 X1.5",
        "X1.5 Y-2.5 F300.",
        "N5 G1 X1.",
        "G01 X1.",
        "G-0 X1.",
        "G1.0 X1.",
        "G91 G1 X1.",
        "G90",
        "G20",
        "G21",
        "G1 X1. X2.",
        "G1 F0. X1.",
        "G1 Y1. X1.",
        "g1 x1.",
        "G1  X1.",
        " G1 X1.",
        "G1 X1. ",
        "G1 X1",
        "G1 X1.2.3",
        "G1 X+-1.",
        "G1 X1. (note)",
        "G1 X1. ; note",
        "F500.",
        "G28 G91 Z0.",
        "M30",
        "",
        "%",
        "G1 X=AC(1)",
        "G1 X1. M8",
        "G2 X1. Y1.",
        "T5 M6",
        "/G1 X1.",
        "G1 X1e3",
        "G1 Xnan",
        "G1 X١.",
    ],
    "heidenhain": [
        "L X+1.000 Y+2.000",
        "L X+1.5 FMAX",
        "L X+1.5 F300",
        "L X+1.5 F0",
        "L X+1.5 FMAX F300",
        "L X+1.5 F300 FMAX",
        "L IX+1.5",
        "L X+1.5 R0",
        "L X+1.5 M91",
        "L Y+1 X+1",
        "L X+1 X+2",
        "L  X+1",
        "l x+1",
        "L X1.2.3",
        "L",
        "X+1",
        "; note",
        "L X+1 ; note",
        "M30",
        "TOOL CALL 4 Z S1000",
        "FUNCTION RESET TCPM",
    ],
}


@pytest.mark.parametrize("name", NAMES)
@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_bulk_read_of_edited_programs_equals_line_by_line(name, data) -> None:
    dialect = DIALECTS[name]
    program = _long_program(60)
    lines = dialect.write(program, block_numbers=True if name == "heidenhain" else None)
    lines = lines.splitlines()
    edits = EDITS["heidenhain" if name == "heidenhain" else "gcode"]
    for _ in range(data.draw(st.integers(0, 6))):
        at = data.draw(st.integers(0, len(lines)))
        edit = data.draw(st.sampled_from(edits))
        if name == "heidenhain":
            edit = f"{at} {edit}" if data.draw(st.booleans()) else edit
        lines.insert(at, edit)
    newline = data.draw(st.sampled_from(["\n", "\r\n", "\r"]))
    text = newline.join(lines) + data.draw(st.sampled_from(["", newline]))
    verbatim = data.draw(st.sampled_from([[], ["G1 X1."], ["L X+1.5 FMAX"], ["M30"]]))
    with pytest.MonkeyPatch.context() as monkeypatch:
        bulk, single = read_both(monkeypatch, dialect, text, verbatim=verbatim)
    assert bulk == single


def _formats() -> list:
    from urdfpost.dialects import NumberFormat

    specs = [d.spec for d in DIALECTS.values()]
    found = {
        fmt
        for spec in specs
        for fmt in (spec.linear_mm, spec.linear_inch, spec.rotary, spec.feed_mm, spec.feed_inch)
    }
    return sorted(
        found | {NumberFormat(0, point=True), NumberFormat(0, trim=True), NumberFormat(2)},
        key=repr,
    )


@pytest.mark.parametrize("fmt", _formats(), ids=repr)
def test_numbers_formatted_at_once_equal_number_format(fmt) -> None:
    from urdfpost.dialects import _bulk

    rng = np.random.default_rng(7)
    d = fmt.decimals
    ties = (np.arange(-2000, 2000) + 0.5) / 10**d  # exact and inexact rounding ties
    values = np.concatenate(
        [
            ties,
            np.nextafter(ties, np.inf),
            np.nextafter(ties, -np.inf),
            rng.uniform(-1e4, 1e4, 3000),
            rng.uniform(-1, 1, 3000),
            np.round(rng.uniform(-1e3, 1e3, 1000), d),
            [0.0, -0.0, 5e-324, -5e-324, 0.0004, -0.0004, 0.0005, -0.0005, 1e9, -1e9, 0.1 + 0.2],
        ]
    )
    scaled = _bulk.scaled_integers(values, d)
    assert scaled is not None
    text = _bulk.text_of_rows(
        np.hstack(
            [
                _bulk.number_slots(scaled, values < 0, fmt),
                np.full((values.size, 1), ord("\n"), dtype=np.uint8),
            ]
        )
    )
    assert text.splitlines() == [fmt.format(float(v)) for v in values]
    assert _bulk.scaled_integers(np.array([1e300]), d) is None


@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize(
    "special",
    [
        Move(False, (math.nan, 1.0, 2.0, 3.0, 4.0), 100.0),
        Move(False, (math.nan,) * 5, 100.0),
        Move(False, (1.0, 2.0, 3.0, 4.0, 5.0), 0.0),
        Move(False, (1.0, 2.0, 3.0, 4.0, 5.0), 0.04),
        Move(False, (1.0, 2.0, 3.0, 4.0, 5.0), -5.0),
        Move(False, (1.0, 2.0, 3.0, 4.0, 5.0), math.inf),
        Move(False, (1.0, 2.0, 3.0, 4.0, 5.0), math.nan),
        Move(False, (math.inf, 2.0, 3.0, 4.0, 5.0), 1.0),
        Move(False, (1.0, 2.0, 3.0), 1.0),
        Move(False, (1.0, 2.0, 3.0, 4.0, 5.0, 6.0), 1.0),
        Move(1, (1.0, 2.0, 3.0, 4.0, 5.0), 1.0),  # type: ignore[arg-type]
        Move(False, (1e300, 2.0, 3.0, 4.0, 5.0), 1.0),
        Move(False, (1e15, 2.0, 3.0, 4.0, 5.0), 1.0),
    ],
    ids=repr,
)
def test_bulk_write_of_special_moves_equals_block_by_block(name, special, monkeypatch) -> None:
    moves = list(_long_program(80).blocks)
    for at in (1, 2, 40):  # the first move of a run, the first of a chunk, inside a chunk
        program = replace(_long_program(80), blocks=(*moves[:at], special, *moves[at:]))
        bulk, single = write_both(monkeypatch, DIALECTS[name], program)
        assert bulk == single


@pytest.mark.parametrize("name", NAMES)
def test_bulk_write_without_modal_axes_and_odd_block_format(name, monkeypatch) -> None:
    program = _long_program(200)
    spec = DIALECTS[name].spec
    for changed in (
        replace(spec, modal_axes=False),
        replace(spec, block_format="N{n:05d}"),
        replace(spec, block_format="#{n}:"),
        replace(spec, motion_layout=None),
    ):
        dialect = Dialect(changed)
        bulk, single = write_both(monkeypatch, dialect, program, block_numbers=True)
        assert bulk == single
        if isinstance(bulk, str):
            back_bulk, back_single = read_both(monkeypatch, dialect, bulk)
            assert back_bulk == back_single


@pytest.mark.parametrize("name", NAMES)
def test_bulk_read_with_other_line_breaks(name, monkeypatch) -> None:
    text = DIALECTS[name].write(_long_program(40))
    for other in ("\x0c", "\x85", "\u2028"):
        edited = text.replace("\n", other, 3)
        bulk, single = read_both(monkeypatch, DIALECTS[name], edited)
        assert bulk == single


@pytest.mark.parametrize("name", NAMES)
def test_a_stop_after_a_stop_is_not_written(name: str) -> None:
    """Spindle and coolant stops when they are stopped already are not written again (a tool
    change's stop, then the CL data's own before its LOADTL); after a program stop or an
    insert (the operator's, or text the post cannot follow) the state is unknown: written."""
    dialect = DIALECTS[name]
    blocks = (ToolChange(3), Spindle("cw", 5000), Coolant("flood"), Move(True, (1.0,)))
    blocks += (Spindle("off"), Coolant("off"), Coolant("off"), Spindle("off"))
    blocks += (Stop(False), Coolant("off"), Spindle("off"), Insert("; text"), Coolant("off"))
    text = dialect.write(Program("S", ("X",), frozenset(), "mm", False, blocks))
    codes = re.findall(r"\bM0?([59])\b", text)
    assert codes == ["5", "9", "9", "5", "9"], text
