"""The job around the tool path (issue 17): the program's start, the work offset, the approach
after a tool change, the end, and the process state (feed, spindle, coolant) checked before
anything is planned.

The programs are read as a control would read them: block by block, in order, with the
dialects' own readers; positions are checked with the machine's forward kinematics.
"""

from __future__ import annotations

import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from jobs import TWO_TOOLS

from urdfpost import load_machine
from urdfpost.cli import main
from urdfpost.dialects import DIALECTS
from urdfpost.errors import CLDataError
from urdfpost.kinematics.forward import tip_and_axis
from urdfpost.posting.options import PostOptions
from urdfpost.posting.process import SpindleState, checked_process
from urdfpost.posting.transitions import DEFAULT_CLEARANCE, retract_axis
from urdfpost.posting.whole import post
from urdfpost.program import (
    Coolant,
    MachineMove,
    Move,
    Smoothing,
    Spindle,
    Tcp,
    ToolChange,
    WorkOffset,
)
from urdfpost.readers import read_cl_text
from urdfpost.verification import program_joints

CONTROLLERS = ("heidenhain", "siemens", "fanuc", "linuxcnc")
MACHINES = ("dmu50", "gantry-ca", "monoblock")


def two_tools():
    return read_cl_text(TWO_TOOLS, source="two.apt")


def blocks_of(result, controller: str):
    """The program as the control reads it back from its text."""
    return DIALECTS[controller].read(result.text).blocks


def index(blocks, kind, start: int = 0, **match) -> int:
    for k in range(start, len(blocks)):
        b = blocks[k]
        if isinstance(b, kind) and all(getattr(b, key) == v for key, v in match.items()):
            return k
    raise AssertionError(f"no {kind.__name__} {match} after block {start}")


# -- the start ---------------------------------------------------------------------------------


@pytest.mark.parametrize("controller", CONTROLLERS)
@pytest.mark.parametrize("tcp", [True, False], ids=["tcp", "mc"])
def test_start_selects_the_work_offset_and_raises_the_tool_first(
    controller: str, tcp: bool
) -> None:
    result = post(two_tools(), load_machine("dmu50"), PostOptions(controller=controller, tcp=tcp))
    blocks = result.program.blocks
    first_move = index(blocks, Move)
    # the work offset, then the tool up to the top of Z in machine coordinates, then the tool
    assert index(blocks, WorkOffset, number=1) < index(blocks, MachineMove) < first_move
    up = blocks[index(blocks, MachineMove)]
    assert up.axes == ("Z",) and up.values == (0.0,)  # dmu50: Z travel ends at 0 (machine)
    assert index(blocks, ToolChange, number=1) < first_move
    # what the text says, read back by the dialect (TCP off at the start, G54 / preset 1)
    text = result.text
    first = {
        "heidenhain": [r"^\d FUNCTION RESET TCPM$", r"Q339=\+1 ;DATUM NUMBER", r" M91$"],
        "siemens": [r"^TRAFOOF$", r"^G54$", r"^SUPA G0 Z0\.000$"],
        "fanuc": [r"\bG49\b", r"^G54$", r"^G53 G0 Z0\.000$"],
        "linuxcnc": [r"^M429$", r"^G54$", r"^G53 G0 Z0\.000$"],
    }[controller]
    lines = text.splitlines()
    found = [next(k for k, x in enumerate(lines) if re.search(p, x)) for p in first]
    assert found == sorted(found), first
    tool = next(k for k, x in enumerate(lines) if re.search(r"TOOL CALL 1|^T1 (M6|D1)$", x))
    assert found[-1] < tool


@pytest.mark.parametrize("controller", CONTROLLERS)
def test_work_offset_option(controller: str) -> None:
    result = post(
        two_tools(), load_machine("dmu50"), PostOptions(controller=controller, work_offset=3)
    )
    want = {
        "heidenhain": r"Q339=\+3 ;DATUM NUMBER",
        "siemens": r"^G56$",
        "fanuc": r"^G56$",
        "linuxcnc": r"^G56$",
    }[controller]
    assert re.search(want, result.text, re.M)
    back = blocks_of(result, controller)
    assert any(isinstance(b, WorkOffset) and b.number == 3 for b in back)


def test_work_offset_beyond_the_control_is_refused(tmp_path: Path, capsys) -> None:
    cl = tmp_path / "two.apt"
    cl.write_text(TWO_TOOLS)
    out = tmp_path / "two.mpf"
    argv = ["post", str(cl), "-m", "dmu50", "-c", "siemens", "-o", str(out), "-q"]
    assert main([*argv, "--work-offset", "5"]) == 2  # a usage error, before any work
    assert "--work-offset 5: siemens has work offsets 1 to 4" in capsys.readouterr().err
    assert not out.exists()
    assert main([*argv, "--work-offset", "4"]) == 0
    assert "\nG57\n" in out.read_text()


# -- the approach after a tool change, and the end -----------------------------------------


@pytest.mark.parametrize("controller", CONTROLLERS)
@pytest.mark.parametrize("machine_name", MACHINES)
@pytest.mark.parametrize("tcp", [True, False], ids=["tcp", "mc"])
def test_tool_change_leaves_up_and_comes_back_from_above(
    controller: str, machine_name: str, tcp: bool
) -> None:
    """Before T2: TCP off, the tool up in machine coordinates, spindle and coolant off. After
    it: the rotary axes turn alone (TCP off), then TCP on, the tool above the first point as
    high as it goes, the approach point 10 mm above it along its tool axis, and the point."""
    m = load_machine(machine_name)
    tp = two_tools()
    # (the second tool's cut is at a fixed tilt: in five-axis form here, not in a plane)
    result = post(tp, m, PostOptions(controller=controller, tcp=tcp, tilted_planes=False))
    assert result.verification.ok
    blocks = result.program.blocks
    t2 = index(blocks, ToolChange, number=2)
    leave = blocks[index(blocks, Move, 0) : t2]
    # the last blocks before T2
    kinds = [type(b) for b in blocks[t2 - 4 : t2]]
    assert kinds[-3:] == [MachineMove, Spindle, Coolant], kinds
    assert blocks[t2 - 2] == Spindle("off") and blocks[t2 - 1] == Coolant("off")
    if tcp:
        assert blocks[t2 - 4] == Tcp(on=False)
    assert leave
    # after T2: the spindle restarts as before (no SPINDL in the CL), coolant as before
    assert blocks[t2 + 1] == Spindle("cw", 9000.0) and blocks[t2 + 2] == Coolant("flood")
    moves = result.program.moves()
    after = [k for k, b in enumerate(blocks) if isinstance(b, Move) and k > t2]
    turn, high, near, point = (blocks[k] for k in after[:4])
    rotary = [m.axis_names.index(a.name) for a in m.rotary]
    linear = list(m.linear_columns)
    assert all(np.isnan(turn.position[j]) for j in linear)  # rotaries alone
    assert not any(np.isnan(turn.position[j]) for j in rotary)
    assert all(np.isnan(high.position[j]) for j in rotary)  # then the linear axes alone
    assert turn.rapid and high.rapid and near.rapid and point.cl_line == 14
    if tcp:
        on = index(blocks, Tcp, t2, on=True)
        assert after[0] < on < after[1]
    # the approach point in the workpiece: 10 mm above the CL point along its tool axis
    values, _ = program_joints(m, result.program)
    k_near = sum(isinstance(b, Move) for b in blocks[: after[2]])
    rows = values[[k_near - 1, k_near, k_near + 1]]
    # (the tool axis in the workpiece depends on the rotary axes alone)
    tip, axis = tip_and_axis(m, rows, result.program.tool_length)
    if tcp:  # TCP positions are the tool tip itself
        tip = rows[:, linear]
    first = tp.tip[4]
    np.testing.assert_allclose(tip[2], first, atol=2e-3)
    np.testing.assert_allclose(tip[1], first + DEFAULT_CLEARANCE * tp.axis[4], atol=2e-3)
    # the high point is further up the same line, and the axis no longer turns
    up = (tip[0] - first) @ tp.axis[4]
    assert up > DEFAULT_CLEARANCE
    np.testing.assert_allclose(np.cross(tip[0] - first, tp.axis[4]), 0.0, atol=2e-3)
    np.testing.assert_allclose(axis, np.repeat(tp.axis[4][None], 3, 0), atol=1e-5)
    assert len(moves) == len(values)


@pytest.mark.parametrize("controller", CONTROLLERS)
@pytest.mark.parametrize("machine_name", MACHINES)
def test_end_goes_up_stops_and_turns_home(controller: str, machine_name: str) -> None:
    m = load_machine(machine_name)
    options = PostOptions(controller=controller, tcp=True, tilted_planes=False)
    result = post(two_tools(), m, options)
    blocks = result.program.blocks
    last_cut = max(k for k, b in enumerate(blocks) if isinstance(b, Move) and b.cl_line)
    tail = blocks[last_cut + 1 :]
    assert [type(b) for b in tail] == [Tcp, MachineMove, Spindle, Coolant, Move, Smoothing]
    assert tail[2] == Spindle("off") and tail[3] == Coolant("off")
    assert tail[5] == Smoothing(False)  # the control's path smoothing cancelled last
    home = tail[4]
    for a in m.rotary:
        assert home.position[m.axis_names.index(a.name)] == pytest.approx(0.0)
    # read back, the control ends the same way (and cancels the path smoothing last)
    back = blocks_of(result, controller)
    assert back[-1] == Smoothing(False)
    back = [b for b in back if not isinstance(b, Smoothing)]
    assert isinstance(back[-1], Move) or any(isinstance(b, Spindle) for b in back[-3:])


def test_retract_axis_of_every_shipped_machine_is_z_up() -> None:
    for name in ("dmu50", "gantry-ca", "monoblock", "umc750", "xyzac-trt", "vf2-4axis"):
        m = load_machine(name)
        column, top = retract_axis(m)
        assert m.axis_names[column] == "Z"
        assert top == pytest.approx(m.axes[column].upper)


# -- process state: feed and spindle ---------------------------------------------------------


NO_FEED = """\
UNITS/MM
MULTAX/ON
LOADTL/1
SPINDL/8000,CLW
RAPID
GOTO/0,0,20,0,0,1
GOTO/0,0,2,0,0,1
GOTO/20,0,2,0,0,1
FINI
"""

NO_SPINDLE = """\
UNITS/MM
MULTAX/ON
LOADTL/1
RAPID
GOTO/0,0,20,0,0,1
FEDRAT/MMPM,600
GOTO/0,0,2,0,0,1
GOTO/20,0,2,0,0,1
FINI
"""


def test_a_cut_with_no_feed_is_an_error_at_its_line() -> None:
    tp = read_cl_text(NO_FEED, source="nofeed.apt")
    with pytest.raises(CLDataError, match=r"nofeed\.apt:7: a cutting move with no feed"):
        post(tp, load_machine("dmu50"), PostOptions(controller="linuxcnc"))


def test_feed_option_fills_the_missing_feeds_with_a_warning() -> None:
    tp = read_cl_text(NO_FEED, source="nofeed.apt")
    result = post(tp, load_machine("dmu50"), PostOptions(controller="linuxcnc", feed=300.0))
    assert "\nG1 Z2.000 F300\n" in result.text  # the first cut has its F word
    warning = [w for w in result.report.as_json()["warnings"] if "--feed" in w]
    assert warning == [
        "nofeed.apt:7: 2 cutting moves with no feed in the CL data: F300 (mm/min, --feed) used"
    ]


def test_a_cut_with_the_spindle_off_is_an_error_at_its_line() -> None:
    tp = read_cl_text(NO_SPINDLE, source="nospindle.apt")
    with pytest.raises(CLDataError, match=r"nospindle\.apt:7: a cutting move with the spindle off"):
        post(tp, load_machine("dmu50"), PostOptions(controller="fanuc"))


@pytest.mark.parametrize("controller", CONTROLLERS)
def test_spindle_option_starts_it_before_the_approach(controller: str) -> None:
    tp = read_cl_text(NO_SPINDLE, source="nospindle.apt")
    result = post(tp, load_machine("dmu50"), PostOptions(controller=controller, spindle=7000.0))
    blocks = result.program.blocks
    assert index(blocks, Spindle, direction="cw") < index(blocks, Move)
    assert index(blocks, ToolChange) < index(blocks, Spindle, direction="cw")
    back = blocks_of(result, controller)
    assert Spindle("cw", 7000.0) in back
    assert any("S7000 CW (--spindle) used" in w for w in result.report.as_json()["warnings"])


def test_spindle_off_in_the_cl_and_a_later_cut_is_an_error() -> None:
    text = NO_FEED.replace(
        "GOTO/20,0,2,0,0,1\n", "SPINDL/OFF\nFEDRAT/MMPM,500\nGOTO/20,0,2,0,0,1\n"
    )
    text = text.replace("GOTO/0,0,2,0,0,1\n", "FEDRAT/MMPM,500\nGOTO/0,0,2,0,0,1\n", 1)
    tp = read_cl_text(text, source="off.apt")
    with pytest.raises(CLDataError, match=r"off\.apt:11: a cutting move with the spindle off"):
        post(tp, load_machine("dmu50"))


def test_checked_process_carries_the_spindle_across_pieces() -> None:
    """A streamed post checks piece by piece: a tool change at the end of one piece and the
    cut in the next still restart the spindle that ran before."""
    tp = two_tools()
    whole, end, notes = checked_process(tp, feed=None, spindle=None, units="mm")
    assert end == SpindleState("cw", 9000.0, True)
    assert len(notes) == 1 and "restarts at S9000 CW" in notes[0]
    restarted = [e for e in whole.events if e.kind == "spindle"]
    assert [e.data["rpm"] for e in restarted] == [9000.0, 9000.0]
    # the same in two pieces cut after the tool change's point
    from urdfpost.toolpath import toolpath_slice

    a, b = toolpath_slice(tp, 0, 4), toolpath_slice(tp, 4, len(tp))
    _, state, _ = checked_process(a, feed=None, spindle=None, units="mm")
    assert state.running
    second, _, more = checked_process(b, feed=None, spindle=None, units="mm", state=state)
    # (the tool change is in the second piece: it stops the spindle, which starts again)
    assert [e.kind for e in second.events if e.kind in ("tool", "spindle")] == ["tool", "spindle"]
    assert more and "restarts at S9000" in more[0]


@given(st.lists(st.sampled_from(["cut", "rapid", "tool", "on", "off"]), max_size=60))
def test_checked_process_runs_the_spindle_at_every_cut(steps: list[str]) -> None:
    """Whatever the tool changes and spindle records between the moves, the spindle runs at
    every cutting move of the checked process, started again once where a cut finds it
    stopped (by a tool change, SPINDL/OFF, or never started) and nowhere else."""
    from urdfpost.toolpath import Event, Motion, Toolpath

    moves: list[str] = []
    events: list[Event] = []
    for step in steps:
        if step in ("cut", "rapid"):
            moves.append(step)
        elif step == "tool":
            events.append(Event(index=len(moves), kind="tool", line=0, data={"number": 1}))
        else:
            data = {"rpm": 5000.0, "direction": "cw" if step == "on" else "off"}
            events.append(Event(index=len(moves), kind="spindle", line=0, data=data))
    n = len(moves)
    toolpath = Toolpath(
        tip=np.zeros((n, 3)),
        axis=np.tile([0.0, 0.0, 1.0], (n, 1)),
        feed=np.full(n, 500.0),
        motion=np.array([int(Motion.FEED if m == "cut" else Motion.RAPID) for m in moves]),
        line=np.arange(1, n + 1),
        events=tuple(events),
    )
    checked, _, _ = checked_process(toolpath, feed=None, spindle=1000.0, units="mm")

    def cuts_stopped(events: tuple[Event, ...], restart: bool) -> int:
        """The cuts that find the spindle stopped, each then counted as starting it when
        ``restart``."""
        running, stopped = False, 0
        for i, move in enumerate(moves):
            for e in (e for e in events if e.index == i):
                if e.kind == "tool":
                    running = False
                elif e.kind == "spindle":
                    running = e.data["direction"] != "off"
            if move == "cut" and not running:
                stopped += 1
                running = restart
        return stopped

    assert cuts_stopped(checked.events, restart=False) == 0
    added = len(checked.events) - len(events)
    assert added == cuts_stopped(toolpath.events, restart=True)


def test_command_line_feed_and_spindle(tmp_path: Path, capsys) -> None:
    cl = tmp_path / "nospindle.apt"
    cl.write_text(NO_SPINDLE)
    out = tmp_path / "p.ngc"
    argv = ["post", str(cl), "-m", "dmu50", "-c", "linuxcnc", "-o", str(out), "-q"]
    assert main(argv) == 1
    err = capsys.readouterr().err
    assert f"{cl}:7: a cutting move with the spindle off" in err and "--spindle" in err
    assert not out.exists()
    assert main([*argv, "--spindle", "6000"]) == 0
    assert "\nS6000 M3\n" in out.read_text()
    assert "S6000 CW (--spindle) used" in capsys.readouterr().err


def test_clearance_option_in_program_units() -> None:
    tp = two_tools()
    m = load_machine("dmu50")
    options = PostOptions(controller="fanuc", units="inch", clearance=1.0)
    result = post(tp, m, options)
    # first point Z20 mm = 0.7874 in; approach 1 in above it
    assert "\nZ1.7874\nZ0.7874" in result.text
    base = post(tp, m, replace(options, clearance=None))
    assert "\nZ1.1811\nZ0.7874" in base.text  # 10 mm


# -- the header --------------------------------------------------------------------------------


@pytest.mark.parametrize("controller", CONTROLLERS)
def test_header_names_machine_offset_tools_and_axis_ranges(controller: str) -> None:
    text = TWO_TOOLS.replace("LOADTL/1\n", "LOADTL/1\nCUTTER/10,5\n")
    text = text.replace("LOADTL/2\n", "LOADTL/2\nCUTTER/6,3\n")
    tp = read_cl_text(text, source="two.apt")
    m = load_machine("dmu50")
    result = post(tp, m, PostOptions(controller=controller, tcp=False, work_offset=2))
    comments = [b.text for b in blocks_of(result, controller) if type(b).__name__ == "Comment"]
    joined = "\n".join(comments).lower()
    assert "urdfpost: machine dmu50, machine coordinates, mm" in joined
    assert ("work offset: preset 2" if controller == "heidenhain" else "work offset: g55") in joined
    assert "tools: t1 d10.000, t2 d6.000" in joined
    # the ranges are those of the positions written
    line = next(c for c in comments if c.lower().startswith("axis ranges: "))
    values, _ = program_joints(m, result.program)
    positions = np.array([mv.position for mv in result.program.moves()], dtype=float)
    for name, j in zip(m.axis_names, range(len(m.axis_names)), strict=True):
        lo, hi = np.nanmin(positions[:, j]), np.nanmax(positions[:, j])
        d = 4 if name in ("B", "C") else 3
        assert f"{name}{lo:.{d}f}..{hi:.{d}f}".lower() in line.lower(), name
    assert "tool table length must be 0" in joined
    assert len(values) == len(positions)
    # no date, no time: the same job gives the same text
    assert post(tp, m, PostOptions(controller=controller, tcp=False, work_offset=2)).text == (
        result.text
    )


@pytest.mark.parametrize("controller", CONTROLLERS)
@pytest.mark.parametrize(
    ("options", "line", "stated"),
    [
        ({}, "tool axis: within 2 deg of the cl tool axis at singular spans, strategy cone: "
         "urdfpost verify --angle-tolerance 2", 2.0),
        ({"angle_tolerance": 1.5, "strategy": "spline"}, "tool axis: within 1.5 deg of "
         "the cl tool axis at singular spans, strategy spline: urdfpost verify --angle-tolerance "
         "1.5", 1.5),
        ({"strategy": "none"}, "tool axis: as in the cl data, strategy none", None),
    ],
)  # fmt: skip
def test_header_says_how_far_the_strategy_may_bend_the_tool_axis(
    controller: str, options: dict, line: str, stated: float | None
) -> None:
    """The header's last line names the singularity strategy and how far it may bend the tool
    axis: what ``urdfpost verify --angle-tolerance`` needs (:func:`bent_in_header` reads it
    back from every control's comments, Fanuc's in upper case)."""
    from urdfpost.posting.header import bent_in_header

    tp = read_cl_text(TWO_TOOLS, source="two.apt")
    result = post(tp, load_machine("dmu50"), PostOptions(controller=controller, **options))
    comments = [
        b.text.lower() for b in blocks_of(result, controller) if type(b).__name__ == "Comment"
    ]
    assert line in comments
    assert bent_in_header(DIALECTS[controller].read(result.text)) == stated


def test_heidenhain_blank_form_from_the_stock() -> None:
    root = Path(__file__).resolve().parent.parent / "examples"
    dome = read_cl_text((root / "dome.apt").read_text(), source="dome.apt")
    result = post(dome, load_machine("dmu50"), PostOptions(stock=str(root / "dome.stl")))
    lines = result.text.splitlines()
    import trimesh

    (x0, y0, z0), (x1, y1, z1) = trimesh.load(root / "dome.stl", force="mesh").bounds
    assert (x0, y0, z0, x1, y1, z1) == (-35.0, -35.0, -4.0, 35.0, 35.0, 30.0)  # the plate, dome
    assert lines[1] == "1 BLK FORM 0.1 Z X-35.000 Y-35.000 Z-4.000"
    assert lines[2] == "2 BLK FORM 0.2 X+35.000 Y+35.000 Z+30.000"
    plain = post(dome, load_machine("dmu50"), PostOptions()).text
    assert "BLK FORM" not in plain


TCP_ON = {
    "heidenhain": r"^\d+ FUNCTION TCPM .*\n",
    "siemens": r"^TRAORI\n",
    "fanuc": r"^G43\.4 H\d+\n",
    "linuxcnc": r"^M428\n",
}


@pytest.mark.parametrize("controller", CONTROLLERS)
def test_verify_refuses_a_tcp_program_that_cuts_with_tcp_off(
    controller: str, tmp_path: Path, capsys
) -> None:
    """Delete the TCP switch of a TCP program: its cuts are then machine positions among tool
    tips, and verify says where, with exit 1 (the intact program passes)."""
    cl = tmp_path / "two.apt"
    cl.write_text(TWO_TOOLS)
    options = PostOptions(controller=controller, tilted_planes=False)  # (TCP all along)
    result = post(two_tools(), load_machine("dmu50"), options)
    ext = DIALECTS[controller].extensions[0]
    good, bad = tmp_path / f"good{ext}", tmp_path / f"bad{ext}"
    good.write_text(result.text)
    # the second tool's TCP switch deleted (its cuts follow with TCP off)
    second = list(re.finditer(TCP_ON[controller], result.text, flags=re.M))[1]
    bad.write_text(result.text[: second.start()] + result.text[second.end() :])
    argv = ["verify", "-m", "dmu50", "--cl", str(cl), "-c", controller]
    assert main([*argv, str(good)]) == 0
    capsys.readouterr()
    assert main([*argv, str(bad)]) == 1
    err = capsys.readouterr().err
    assert f"{bad}:" in err and "a feed move of X/Y/Z with TCP off in a TCP program" in err
    # every TCP switch deleted: read as machine positions, which miss the CL points
    none = tmp_path / f"none{ext}"
    none.write_text(re.sub(TCP_ON[controller], "", result.text, flags=re.M))
    assert main([*argv, str(none)]) == 1
    assert "BEYOND TOLERANCE" in capsys.readouterr().out


def test_a_transition_that_collides_is_an_error_naming_its_line() -> None:
    """The transitions are checked with FCL against the stock and the machine (a move of
    theirs through the dome, made here from the program's own first row, is refused)."""
    from urdfpost.errors import CollisionError
    from urdfpost.posting.options import resolve
    from urdfpost.posting.piece import check_transitions, make_problem
    from urdfpost.posting.transitions import Transitions

    root = Path(__file__).resolve().parent.parent / "examples"
    dome = read_cl_text((root / "dome.apt").read_text(), source="dome.apt")
    m = load_machine("dmu50")
    options = PostOptions(stock=str(root / "dome.stl"), tcp=False)  # rows are joint values
    result = post(dome, m, options)
    assert result.report.as_json()["collisions"]["checked"]  # the real ones are clear
    job = resolve(options, m, dome.units)
    world = make_problem(dome, job).collision
    assert world is not None
    transitions = Transitions(m, False, result.program.tool_length, job.clearance)
    # the approach to the dome's top (tool vertical), then 40 mm further down into the dome
    top = int(np.argmax(dome.tip[:, 2]))
    q, _ = program_joints(m, result.program)
    on_cl = [k for k, mv in enumerate(result.program.moves()) if mv.cl_line == dome.line[top]]
    row = q[on_cl[0]].copy()
    transitions.approach(None, row, int(dome.line[top]))
    check_transitions(world, transitions, dome)  # from above: clear
    z, z_top = retract_axis(m)
    into = row.copy()
    into[z] += -40.0 if z_top >= row[z] else 40.0  # away from the retract: down into the dome
    transitions.paths.append((int(dome.line[top]), np.array([row, into])))
    with pytest.raises(CollisionError, match=rf"dome\.apt:{dome.line[top]}: the safe approach"):
        check_transitions(world, transitions, dome)


@pytest.mark.parametrize("pieces", ["0", "3"])
def test_machine_coordinates_warn_of_a_tool_without_a_length(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], pieces: str
) -> None:
    """Machine-coordinate positions include the tool length: a second tool with no gauge
    length of its own (no tool table, no LOADTL LENGTH) is posted with the job's one and
    gets a warning at its LOADTL line (whole and streamed); a TCP program, which leaves the
    length to the control, gets none."""
    cl = tmp_path / "two.apt"
    cl.write_text(TWO_TOOLS)
    line = next(k for k, t in enumerate(TWO_TOOLS.splitlines(), 1) if t.startswith("LOADTL/2"))
    base = ["post", str(cl), "-m", "dmu50", "-c", "fanuc", "-q", "--piece-points", pieces]
    assert main([*base, "--no-tcp", "-o", str(tmp_path / "mc.nc")]) == 0
    err = capsys.readouterr().err
    assert (
        f"two.apt:{line}: T2 has no gauge length in the tool table or the CL data (LOADTL "
        "LENGTH) and is posted with the job's tool length 100.000 mm"
    ) in err
    assert err.count("has no gauge length") == 1
    assert main([*base, "-o", str(tmp_path / "tcp.nc")]) == 0
    assert "tool length" not in capsys.readouterr().err


@pytest.mark.parametrize("controller", CONTROLLERS)
@pytest.mark.parametrize("tcp", [True, False], ids=["tcp", "mc"])
def test_stops_of_the_cl_data_at_a_tool_change_are_not_written_twice(
    controller: str, tcp: bool
) -> None:
    """CL data that stops the spindle and coolant itself before LOADTL and at its end (as NX
    and most CAM systems write it): one M5 and one M9 before the tool change and at the end,
    not the post's and the CL data's both."""
    after = "LOADTL/2\nSPINDL/9000,CLW\nCOOLNT/FLOOD"
    text = TWO_TOOLS.replace("LOADTL/2", f"COOLNT/OFF\nSPINDL/OFF\n{after}")
    text = text.replace("FINI", "COOLNT/OFF\nSPINDL/OFF\nFINI")
    result = post(read_cl_text(text, source="two.apt"), load_machine("dmu50"),
                  PostOptions(controller=controller, tcp=tcp))  # fmt: skip
    blocks = blocks_of(result, controller)
    change = index(blocks, ToolChange, number=2)
    last_cut = max(k for k in range(change) if isinstance(blocks[k], Move) and not blocks[k].rapid)
    between = blocks[last_cut:change]
    assert sum(isinstance(b, Spindle) and b.direction == "off" for b in between) == 1
    assert sum(isinstance(b, Coolant) and b.mode == "off" for b in between) == 1
    end = max(k for k, b in enumerate(blocks) if isinstance(b, Move) and not b.rapid)
    lines = result.text.splitlines()
    assert sum(isinstance(b, Spindle) and b.direction == "off" for b in blocks[end:]) == 1
    assert sum(isinstance(b, Coolant) and b.mode == "off" for b in blocks[end:]) == 1
    stops = [k for k, line in enumerate(lines) if re.search(r"\bM0?[59]\b", line)]
    assert len(stops) == 4, "\n".join(lines)  # M5 and M9 at the change, at the end
