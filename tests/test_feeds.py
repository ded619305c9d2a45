"""Feeds that are true at the tool tip, axis velocity caps, and the verifier's tip-feed measure
(issue 19).

A path with large rotary moves (:func:`jobs.rotary_sweep`) is posted in machine coordinates on
each control (inverse time on Fanuc, LinuxCNC and Siemens, a feed per block on Heidenhain) and
the program read back is measured here on its own: the tool tip through the forward kinematics
at many points of every block, the block's time from its F by the control's rule, written out
below (not the post's functions). Every block must give the CL feed within 1 %, or run at an
axis limit, and no axis may exceed its URDF velocity limit.

Regenerate the goldens with ``URDFPOST_REGEN_GOLDEN=1 pytest tests/test_feeds.py``.
"""

from __future__ import annotations

import math
import os
import re
from pathlib import Path

import numpy as np
import pytest
from jobs import rotary_sweep
from rs274 import Rs274Error, run_rs274

from urdfpost import load_machine
from urdfpost.cli import main
from urdfpost.dialects import DIALECTS
from urdfpost.errors import ProgramParseError, UrdfpostError
from urdfpost.kinematics.forward import tip_and_axis
from urdfpost.machine import Machine
from urdfpost.posting.options import PostOptions
from urdfpost.posting.whole import PostResult, post
from urdfpost.program import FEED_INVERSE_TIME, FEED_PER_MINUTE, Program
from urdfpost.readers import read_cl_text
from urdfpost.units import mm_per_unit
from urdfpost.verification import program_joints

ROOT = Path(__file__).resolve().parents[1]
GOLDEN = ROOT / "tests" / "golden" / "feeds"
REGEN = os.environ.get("URDFPOST_REGEN_GOLDEN") == "1"

#: machine, control, tool length (mm; None: the machine file's): each control on a machine it
#: is made for
CASES = {
    "heidenhain": ("dmu50", None),
    "fanuc": ("umc750", None),
    "linuxcnc": ("xyzac-trt", 80.0),
    "siemens": ("gantry-ca", None),
}
SLOW = 300.0  # mm/min: no axis near its limit on the sweep
FAST = 6000.0  # mm/min: the turn is limited by the rotary axes

_SAMPLES = 200  # tool tip positions per block of the independent measure


def _machine(controller: str) -> Machine:
    return load_machine(ROOT / "robots" / "urdf" / f"{CASES[controller][0]}.urdf")


def _posted(controller: str, feed: float, tcp: bool = False) -> PostResult:
    toolpath = read_cl_text(rotary_sweep(feed), source="sweep.apt")
    options = PostOptions(
        controller=controller, tcp=tcp, units="mm", tool_length=CASES[controller][1]
    )
    return post(toolpath, _machine(controller), options)


def _tool_length(controller: str, machine: Machine) -> float:
    given = CASES[controller][1]
    return machine.settings.tool_length if given is None else given


def _measured(
    text: str, controller: str, machine: Machine, tool_length: float
) -> tuple[Program, np.ndarray, np.ndarray, np.ndarray]:
    """Per feed block of the text read back: tip feed (mm/min), axis speeds over their limits
    (shape (n, m)), and whether its slowest axis sets its time (within 0.5 %)."""
    dialect = DIALECTS[controller]
    program = dialect.read(text)
    values, rapid = program_joints(machine, program)
    feed = program.move_table().feed
    scale = mm_per_unit(program.units)
    velocity = np.array([a.velocity for a in machine.axes]) * 60.0  # per minute
    rotary = np.array([a.rotary for a in machine.axes])
    tips, shares, limited = [], [], []
    t = np.linspace(0.0, 1.0, _SAMPLES + 1)[:, None]
    for k in np.flatnonzero(~rapid[1:]) + 1:
        q0, q1 = values[k - 1], values[k]
        tip, _ = tip_and_axis(machine, q0 + t * (q1 - q0), tool_length)
        length = float(np.linalg.norm(np.diff(tip, axis=0), axis=1).sum())
        dq = q1 - q0
        if program.feed_mode == FEED_INVERSE_TIME:  # G93: the block takes 1/F minutes
            time = 1.0 / feed[k]
        else:  # Heidenhain: F along sqrt(dx^2 + dy^2 + dz^2 + dB^2 + dC^2), degrees as mm
            linear = np.where(rotary, 0.0, dq) / scale
            degrees = np.degrees(np.where(rotary, dq, 0.0))
            time = math.hypot(*linear, *degrees) / (feed[k] / scale)
        tips.append(length / time)
        speed = np.abs(dq) / time / velocity
        shares.append(speed)
        slowest = float((np.abs(dq) / velocity).max())
        limited.append(slowest >= 0.995 * time)
    return program, np.array(tips), np.array(shares), np.array(limited)


@pytest.mark.parametrize("controller", sorted(CASES))
def test_machine_coordinates_cut_at_the_programmed_tip_feed(controller: str) -> None:
    """Inverse time (or F per block on Heidenhain): every block gives the CL feed at the tip
    within 1 %, no axis near its limit, and the verifier says so."""
    result = _posted(controller, SLOW)
    machine = _machine(controller)
    program, tip_feed, shares, _ = _measured(
        result.text, controller, machine, _tool_length(controller, machine)
    )
    inverse = controller != "heidenhain"
    assert program.feed_mode == (FEED_INVERSE_TIME if inverse else FEED_PER_MINUTE)
    assert ("G93" in result.text) is inverse
    assert len(tip_feed) > 50
    assert np.abs(tip_feed / SLOW - 1.0).max() <= 0.01, tip_feed
    assert shares.max() < 1.0
    # the rotary axes really move: C turns 270 degrees
    c = program.axes.index("C")
    positions = program.move_table().position[:, c]
    assert np.nanmax(positions) - np.nanmin(positions) > 200.0
    check = result.verification.feeds
    assert check is not None and check.ok and check.capped == 0
    assert check.compared == len(tip_feed)
    assert check.max_deviation_pct <= 1.0
    report = result.report.as_json()
    assert report["feeds"]["mode"] == ("inverse-time" if inverse else "per-block")
    assert report["feeds"]["capped_blocks"] == 0
    assert not [w for w in report["warnings"] if "feed reduced" in w]


def test_feed_along_the_axes_is_five_times_off_without_the_feed_mode() -> None:
    """The problem of the issue: the CL feed copied as a feed per minute (mode ``tip``) in
    machine coordinates is applied to the axes' path, and the verifier refuses it."""
    toolpath = read_cl_text(rotary_sweep(SLOW), source="sweep.apt")
    machine = _machine("heidenhain")
    options = PostOptions(controller="heidenhain", tcp=False, units="mm", feed_mode="tip")
    with pytest.raises(UrdfpostError, match="tip feed BEYOND TOLERANCE"):
        post(toolpath, machine, options)


@pytest.mark.parametrize("controller", sorted(CASES))
def test_feeds_are_capped_at_the_axes_velocity_limits(controller: str) -> None:
    """At a high feed the turn would drive C (and B or A) beyond their limits: those blocks'
    F is lowered so the fastest axis runs at its limit, reported by the post and by the
    verifier; the other blocks keep the CL feed."""
    result = _posted(controller, FAST)
    machine = _machine(controller)
    _, tip_feed, shares, limited = _measured(
        result.text, controller, machine, _tool_length(controller, machine)
    )
    top = shares.max(axis=1)
    assert top.max() <= 1.0 + 1e-3  # (the independent measure samples more densely)
    assert limited.sum() > 10
    # a block slower than programmed runs at an axis limit; the others at the CL feed
    slow = tip_feed < FAST * 0.99
    assert slow.any() and (top[slow] >= 0.99).all()
    assert np.abs(tip_feed[~slow] / FAST - 1.0).max() <= 0.01
    figures = result.report.figures
    assert figures is not None and figures.feeds is not None
    capped = figures.feeds
    assert capped.capped_blocks == int(slow.sum())
    assert capped.worst_share == pytest.approx(float(tip_feed.min() / FAST), rel=0.01)
    warning = [w for w in result.report.warnings if "feed reduced on" in w]
    assert len(warning) == 1
    assert re.search(
        rf"feed reduced on {capped.capped_blocks} blocks .* worst at CL line "
        rf"{capped.worst_cl_line} \(to {100 * capped.worst_share:.1f}% of programmed\)",
        warning[0],
    ), warning
    check = result.verification.feeds
    assert check is not None and check.ok
    assert check.capped == capped.capped_blocks
    assert check.slowest_capped_cl_line == capped.worst_cl_line
    assert check.max_axis_share == pytest.approx(1.0, abs=1e-3)


def test_tcp_feeds_are_capped_too() -> None:
    """With TCP the control applies F at the tip: a block whose rotary axes would exceed
    their limits at the CL feed gets a lower F."""
    result = _posted("fanuc", FAST, tcp=True)
    figures = result.report.figures
    assert figures is not None and figures.feeds is not None
    assert figures.feeds.mode == "tip" and figures.feeds.capped_blocks > 0
    feeds = [m.feed for m in result.program.moves() if not m.rapid and m.feed is not None]
    assert min(feeds) < FAST and max(feeds) == pytest.approx(FAST)
    check = result.verification.feeds
    assert check is not None and check.ok and check.capped == figures.feeds.capped_blocks
    assert check.max_axis_share <= 1.0 + 1e-9


# -- golden programs, and LinuxCNC's interpreter on them -----------------------------------------


@pytest.mark.parametrize("controller", sorted(CASES))
def test_golden_program(controller: str) -> None:
    result = _posted(controller, SLOW)
    ext = DIALECTS[controller].extensions[0]
    path = GOLDEN / f"sweep_{CASES[controller][0]}_{controller}_mc{ext}"
    if REGEN:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(result.text, encoding="utf-8", newline="\n")
    assert path.is_file(), f"{path} missing: run with URDFPOST_REGEN_GOLDEN=1"
    assert result.text == path.read_text(encoding="utf-8"), f"posted program differs from {path}"


def test_rs274_runs_the_inverse_time_program(tmp_path: Path) -> None:
    """LinuxCNC's interpreter takes the program in G93 (no "F word missing"), turns every F
    into the feed per minute its own rule gives (X/Y/Z length, else degrees, times F), and the
    tip feed of the blocks at those feeds is the CL feed."""
    path = GOLDEN / "sweep_xyzac-trt_linuxcnc_mc.ngc"
    text = path.read_text()
    result = run_rs274(text, {1: 0.0}, tmp_path)
    calls = result.calls
    names = [c.name for c in calls]
    inverse = [
        k
        for k, c in enumerate(calls)
        if c.name == "COMMENT" and "feed mode set to inverse time" in str(c.args[0])
    ]
    feeds = [k for k, n in enumerate(names) if n == "STRAIGHT_FEED"]
    assert inverse and feeds and inverse[0] < feeds[0]
    program = DIALECTS["linuxcnc"].read(text)
    moves = program.moves()
    cuts = [m for m in moves if not m.rapid]
    assert len(feeds) == len(cuts)
    # the feed rate in effect at each STRAIGHT_FEED, and the block it moves
    rate = math.nan
    rates = []
    for call in calls:
        if call.name == "SET_FEED_RATE":
            rate = call.number(0)
        elif call.name == "STRAIGHT_FEED":
            rates.append(rate)
    machine = _machine("linuxcnc")
    values, rapid = program_joints(machine, program)
    blocks = np.flatnonzero(~rapid[1:]) + 1
    lin, rot = list(machine.linear_columns), list(machine.rotary_columns)
    tip_feed = []
    for k, r in zip(blocks.tolist(), rates[-len(blocks) :], strict=True):
        dq = values[k] - values[k - 1]
        xyz = float(np.linalg.norm(dq[lin]))
        length = xyz if xyz > 0 else float(np.degrees(np.linalg.norm(dq[rot])))
        assert r == pytest.approx(length * program.move_table().feed[k], rel=1e-4, abs=1e-3)
        t = np.linspace(0.0, 1.0, _SAMPLES + 1)[:, None]
        tip, _ = tip_and_axis(machine, values[k - 1] + t * dq, 80.0)
        tip_feed.append(float(np.linalg.norm(np.diff(tip, axis=0), axis=1).sum()) * r / length)
    assert np.abs(np.array(tip_feed) / SLOW - 1.0).max() <= 0.01


# -- the verifier sees a wrong F --------------------------------------------------------------


def _verify(path: Path, controller: str, cl: Path, capsys: pytest.CaptureFixture[str]) -> str:
    machine, length = CASES[controller]
    argv = ["verify", str(path), "-m", machine, "--cl", str(cl), "-c", controller]
    if length is not None:
        argv += ["--tool-length", str(length)]
    capsys.readouterr()
    code = main(argv)
    out = capsys.readouterr().out
    return f"{code}\n{out}"


@pytest.mark.parametrize(
    ("controller", "factor"), [("fanuc", 1.5), ("linuxcnc", 0.5), ("heidenhain", 2.0)]
)
def test_verify_reports_a_wrong_feed(
    controller: str, factor: float, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """An F changed by hand in a written program: the tip feed of that block is off, which
    ``urdfpost verify`` reports with its CL line; the program as written verifies."""
    result = _posted(controller, SLOW)
    cl = tmp_path / "sweep.apt"
    cl.write_text(rotary_sweep(SLOW))
    good = tmp_path / f"good{DIALECTS[controller].extensions[0]}"
    good.write_text(result.text)
    out = _verify(good, controller, cl, capsys)
    assert out.startswith("0\n"), out
    assert "tip feed within tolerance" in out
    words = list(re.finditer(r"(?<![A-Z])F(\d+\.?\d*)", result.text))
    word = words[len(words) // 2]  # a block in the turn
    value = float(word[1]) * factor
    text = result.text[: word.start()] + f"F{value:.3f}" + result.text[word.end() :]
    bad = tmp_path / f"bad{DIALECTS[controller].extensions[0]}"
    bad.write_text(text)
    out = _verify(bad, controller, cl, capsys)
    assert out.startswith("1\n"), out
    share = abs(factor - 1.0)  # the tip feed goes with F (1/time, or length/time)
    found = r"tip feed BEYOND TOLERANCE: .* deviation from the CL feed max ([\d.]+)%"
    match = re.search(found, out)
    assert match, out
    assert float(match[1]) == pytest.approx(100.0 * share, rel=0.02)
    assert "worst tip feed near CL line" in out


# -- reading and writing the feed mode --------------------------------------------------------


def test_inverse_time_needs_f_in_every_feed_block(tmp_path: Path) -> None:
    """The reader refuses what LinuxCNC's interpreter refuses, at the same line."""
    text = "(P)\nG21\nG90 G94\nT1 M6\nS1000 M3\nG0 X0 Y0 Z0\nG93\nG1 X1 F10\nG1 X2\nM2\n"
    with pytest.raises(ProgramParseError, match=r":9: feed move in inverse time \(G93\) without"):
        DIALECTS["linuxcnc"].read(text, path="p.ngc")
    with pytest.raises(
        Rs274Error, match=r"F word missing with inverse time g1 move \(program line 9"
    ):
        run_rs274(text, {1: 0.0}, tmp_path)


def test_one_feed_mode_for_the_feed_moves_of_a_program() -> None:
    text = "(P)\nG21\nG90 G94\nT1 M6\nG0 X0 Y0 Z0\nG1 X1 F100\nG93\nG1 X2 F10\nM2\n"
    with pytest.raises(ProgramParseError, match=r":8: feed move in inverse-time feed after"):
        DIALECTS["linuxcnc"].read(text, path="p.ngc")


def test_an_f_after_a_mode_switch_is_needed_again() -> None:
    """A switch of feed mode forgets the modal feed (Siemens: "the path feedrate value has to
    be reprogrammed"); the reader gives the move no feed, which the process check refuses."""
    text = "; P\nG710\nG90 G94\nT1 D1\nM6\nG0 X0 Y0 Z0\nG1 X1 F100\nG93\nG94\nG1 X2\nM30\n"
    program = DIALECTS["siemens"].read(text)
    assert [m.feed for m in program.moves()] == [None, 100.0, None]


def test_heidenhain_has_no_inverse_time() -> None:
    toolpath = read_cl_text(rotary_sweep(SLOW), source="sweep.apt")
    options = PostOptions(controller="heidenhain", tcp=False, feed_mode="inverse-time")
    with pytest.raises(UrdfpostError, match="heidenhain has no inverse-time feed"):
        post(toolpath, _machine("heidenhain"), options)


def test_inverse_time_is_written_between_g93_and_g94() -> None:
    """G93 before the first feed run, G94 after the last and before the program end, F in
    every feed block; read back the same feeds, in 1/min whatever the units."""
    result = _posted("fanuc", SLOW)
    lines = result.text.splitlines()
    first = lines.index("G93")
    end = max(k for k, x in enumerate(lines) if x == "G94")
    last_feed = max(k for k, x in enumerate(lines) if " F" in x)
    assert first < last_feed < end < lines.index("M30")
    feed_blocks = [x for x in lines[first:end] if x.startswith(("G1 ", "X", "Y", "Z", "B", "C"))]
    cuts = [x for x in feed_blocks if not x.startswith("G0")]
    assert cuts and all(" F" in x for x in cuts[1:])
    back = DIALECTS["fanuc"].read(result.text)
    assert back.feed_mode == FEED_INVERSE_TIME
    wrote = [m.feed for m in result.program.moves() if not m.rapid]
    read = [m.feed for m in back.moves() if not m.rapid]
    assert read == pytest.approx(wrote, abs=5e-4)


def test_the_machine_file_gives_the_default_feed_mode(tmp_path: Path) -> None:
    """``<urdfpost feed_mode=...>``: the machine's default, overridden by the job; an unknown
    name, or one its control has not, is refused naming the file and line."""
    source = (ROOT / "robots" / "urdf" / "umc750.urdf").read_text()
    toolpath = read_cl_text(rotary_sweep(SLOW), source="sweep.apt")

    def machine_with(setting: str, controller: str = "fanuc") -> Path:
        path = tmp_path / f"m{len(list(tmp_path.iterdir()))}.urdf"
        tag = f'controller="{controller}" {setting}'
        path.write_text(source.replace('controller="fanuc"', tag, 1))
        return path

    per_block = load_machine(machine_with('feed_mode="per-block"'))
    result = post(toolpath, per_block, PostOptions(tcp=False, units="mm"))
    assert "G93" not in result.text and result.program.feed_mode == FEED_PER_MINUTE
    assert result.verification.feeds is not None and result.verification.feeds.ok
    overridden = PostOptions(tcp=False, units="mm", feed_mode="inverse-time")
    assert "G93" in post(toolpath, per_block, overridden).text
    with pytest.raises(UrdfpostError, match=r"m\d\.urdf:\d+: <urdfpost feed_mode='fast'>"):
        load_machine(machine_with('feed_mode="fast"'))
    heidenhain = load_machine(machine_with('feed_mode="inverse-time"', "heidenhain"))
    with pytest.raises(UrdfpostError, match=r"m\d\.urdf:\d+: <urdfpost feed_mode=\.\.\.>: "):
        post(toolpath, heidenhain, PostOptions(tcp=False, units="mm"))


# -- a block at a CL point where the CL feed changes ---------------------------------------------


def _pole_pass(phase: int = 2) -> str:
    """The middle pass of ``bench/make_large_cl.py``'s hemisphere raster near its top, with a
    FEDRAT before every GOTO (feed-optimised data: 1500 to 2100 mm/min, changing at every CL
    point). The cone bends the tool axis near the top, and inserts rows next to CL points
    0.05 mm apart: with this phase of the feeds the matching took, before the fix, a row
    0.9 um before CL point 463 as the one reaching it, so the block from there to the point was
    compared with the next point's feed (5.26 % off) and the post refused its own program."""
    disc = 40.0 * math.sin(math.radians(60.0))
    x = np.linspace(-disc, disc, 1435)[212:1212]
    z = np.sqrt(1600.0 - x * x)
    lines = ["UNITS/MM", "MULTAX/ON", "LOADTL/1", "CUTTER/6.0,3.0", "SPINDL/12000,CLW"]
    lines.append("FEDRAT/MMPM,1000.0")
    for k, (xk, zk) in enumerate(zip(x, z, strict=True), start=212):
        lines.append(f"FEDRAT/MMPM,{1500 + (k + phase) % 7 * 100}.0")
        lines.append(f"GOTO/{xk:.4f},0.0000,{zk:.4f},{xk / 40:.6f},0.000000,{zk / 40:.6f}")
    return "\n".join([*lines, "FINI", ""])


@pytest.mark.parametrize("piece_points", [None, 100])
def test_feed_changing_at_every_point_near_the_pole(
    piece_points: int | None, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Feed-optimised data through a bent stretch: the post writes its program (whole and in
    pieces) and ``urdfpost verify`` accepts it; an F of a block between CL points changed by
    5 % is refused."""
    cl = tmp_path / "pole.apt"
    cl.write_text(_pole_pass())
    program = tmp_path / "pole.h"
    argv = ["post", str(cl), "-m", "dmu50", "-c", "heidenhain", "--no-tcp", "-o", str(program)]
    if piece_points is not None:
        argv += ["--piece-points", str(piece_points)]
    capsys.readouterr()
    assert main(argv) == 0, capsys.readouterr()
    assert "tip feed within tolerance" in capsys.readouterr().out
    verify = ["verify", str(program), "-m", "dmu50", "--cl", str(cl), "--angle-tolerance", "2.5"]
    assert main(verify) == 0, capsys.readouterr()
    assert "tip feed within tolerance" in capsys.readouterr().out
    # a block well before the bent stretch (free of any axis limit), F 5 % off
    text = program.read_text()
    words = list(re.finditer(r" F(\d+\.?\d*)", text))
    word = words[100]
    value = float(word[1]) * 1.05
    program.write_text(text[: word.start()] + f" F{value:.1f}" + text[word.end() :])
    assert main(verify) == 1
    assert "tip feed BEYOND TOLERANCE" in capsys.readouterr().out


def test_feed_at_a_point_is_either_side_of_it_only() -> None:
    """A block both of whose ends reach a CL point may be at the feed before the point or
    after it (``other_cl_feed``), not at any other."""
    from urdfpost.verification.feeds import FeedRules, measure_feeds

    machine = _machine("heidenhain")
    q0 = np.zeros((3, len(machine.axes)))
    q1 = q0.copy()
    q1[:, 0] = 0.01  # X 0.01 mm: the tip moves 0.01 mm
    rules = FeedRules(axis_feed_rule="combined", feed_step=0.0, inverse_step=0.0)
    cl_feed = np.array([1000.0, 1000.0, 1000.0])
    feed = np.array([900.0, 1000.0, 800.0])  # the last at neither side's feed
    other = np.array([[900.0, np.nan], [np.nan, np.nan], [np.nan, 900.0]])
    args = (machine, FEED_PER_MINUTE, False, "mm", q0, q1, feed, cl_feed, np.arange(3), rules)
    alone = measure_feeds(*args, 0.01, 100.0)
    assert not alone.ok and alone.max_deviation_pct == pytest.approx(20.0)
    either = measure_feeds(*args, 0.01, 100.0, other_cl_feed=other)
    assert not either.ok and either.max_deviation_pct == pytest.approx(100.0 * (1 - 800 / 900))
    assert either.worst_cl_line == 2
    feed[2] = 900.0
    assert measure_feeds(*args, 0.01, 100.0, other_cl_feed=other).ok
    assert not measure_feeds(*args, 0.01, 100.0).ok
