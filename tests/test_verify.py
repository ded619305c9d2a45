"""Verification: it accepts what the post wrote, catches edited programs (library and CLI), and
measures the nonlinear error inside blocks, not only at their ends or midpoints."""

from __future__ import annotations

import functools
import json
import re
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from conftest import StandIn
from hypothesis import given, settings
from hypothesis import strategies as st
from jobs import write_hemisphere

import urdfpost.linearize as linearize_module
import urdfpost.verification.measure as verify_module
from urdfpost import load_machine
from urdfpost.cli import main
from urdfpost.dialects import DIALECTS
from urdfpost.geometry import Arcs, Segments, angle_between, cos_sin
from urdfpost.kinematics.forward import tip_and_axis, tip_and_axis_along
from urdfpost.linearize import RowPoses, _error_bounds, _orientation_error, _Slack
from urdfpost.machine import Machine
from urdfpost.posting.options import PostOptions, resolve
from urdfpost.posting.piece import post_piece
from urdfpost.posting.whole import PostResult, post
from urdfpost.program import Move, MoveTable, Program, Tcp, ToolChange
from urdfpost.readers import read_cl
from urdfpost.tolerances import Tolerances
from urdfpost.toolpath import Toolpath
from urdfpost.verification import Verification, match_points, program_joints, verify
from urdfpost.verification.match import _row_poses, row_points
from urdfpost.verification.measure import _Blocks, _Polyline

ROOT = Path(__file__).resolve().parents[1]
DOME = ROOT / "examples" / "dome.apt"

_HOME_WORDS = ("M91", "G28", "G75", "G53")
_AXIS_WORD = re.compile(r"(?<![A-Z0-9_=])([XYZABC])([-+]?\d*\.?\d+)")


def code_body(line: str) -> str:
    return re.sub(r"^(?:N?\d+\s+)", "", line.strip())


def motion_lines(text: str) -> list[int]:
    """Indices of the motion blocks of a program text (home moves excluded)."""
    out = []
    for i, line in enumerate(text.splitlines()):
        body = code_body(line)
        if not body or body.startswith((";", "(", "%")):
            continue
        if any(w in body.split() for w in _HOME_WORDS):
            continue
        if _AXIS_WORD.search(body):
            out.append(i)
    return out


@functools.cache
def machine(name: str) -> Machine:
    return load_machine(name)


@functools.cache
def dome() -> Toolpath:
    return read_cl(DOME)


@functools.cache
def dome_post(controller: str, tcp: bool) -> PostResult:
    return post(
        dome(), machine("dmu50"), PostOptions(strategy="recursive", controller=controller, tcp=tcp)
    )


def check(text: str, controller: str, result: PostResult) -> Verification:
    program = DIALECTS[controller].read(text, path=f"<edited {controller}>")
    return verify(
        program,
        machine("dmu50"),
        dome(),
        tool_length=result.program.tool_length,
        tol=Tolerances.for_units("mm"),
    )


def pick_block(result: PostResult, address: str) -> tuple[int, int]:
    """A feed block in the middle of the program that reaches a CL point and writes
    ``address``, as does the next motion block (so an edit of it stays in one block).

    Returns (text line index, CL line)."""
    lines = result.text.splitlines()
    motion = motion_lines(result.text)
    moves = result.program.moves()
    assert len(motion) == len(moves)
    for k in range(len(moves) // 2, len(moves) - 1):
        mv = moves[k]
        if mv.rapid or moves[k + 1].rapid or mv.cl_line is None:
            continue
        here = dict(_AXIS_WORD.findall(code_body(lines[motion[k]])))
        there = dict(_AXIS_WORD.findall(code_body(lines[motion[k + 1]])))
        if address in here and address in there:
            return motion[k], mv.cl_line
    raise AssertionError(f"no block writing {address} twice in a row")


def edit_word(line: str, address: str, delta: float) -> str:
    """Add ``delta`` to the value of ``address`` in ``line``, keeping the number format."""

    def repl(m: re.Match[str]) -> str:
        text = m.group(2)
        decimals = len(text.split(".")[1]) if "." in text else 0
        value = float(text) + delta
        sign = "+" if text.startswith("+") and value >= 0 else ""
        return f"{m.group(1)}{sign}{value:.{decimals}f}"

    out, n = re.subn(rf"(?<![A-Z0-9_=])({address})([-+]?\d*\.?\d+)", repl, line, count=1)
    assert n == 1 and out != line
    return out


# --------------------------------------------------------------------------------------------
# edited programs are caught

CONTROLLERS = ("heidenhain", "fanuc")
MODES = {"tcp": True, "mc": False}
#: edit name -> (address, delta); None = delete the block
EDITS = {
    "x+0.1mm": ("X", 0.1),
    "z-0.1mm": ("Z", -0.1),
    "b+1deg": ("B", 1.0),
    "c+1deg": ("C", 1.0),
    "delete": None,
}


@pytest.mark.parametrize("controller", CONTROLLERS)
@pytest.mark.parametrize("mode", MODES)
def test_unedited_program_verifies(controller: str, mode: str) -> None:
    result = dome_post(controller, MODES[mode])
    v = check(result.text, controller, result)
    assert v.ok
    assert v.reached == v.cl_points == len(dome())
    assert v.max_tip_deviation == pytest.approx(result.verification.max_tip_deviation)


#: With TCP, 1 deg of C turns the tool axis by only sin(tilt) deg (about 0.4 deg in the middle
#: of a dome pass, under the 0.5 deg tolerance): C edits are checked in machine coordinates.
EDIT_CASES = [
    (mode, controller, edit)
    for mode in MODES
    for controller in CONTROLLERS
    for edit in EDITS
    if not (MODES[mode] and edit == "c+1deg")
]


@pytest.mark.parametrize(("mode", "controller", "edit"), EDIT_CASES)
def test_edited_program_fails(controller: str, mode: str, edit: str) -> None:
    tcp = MODES[mode]
    result = dome_post(controller, tcp)
    spec = EDITS[edit]
    address = spec[0] if spec else "X"
    index, cl_line = pick_block(result, address)
    lines = result.text.splitlines()
    if spec is None:
        del lines[index]
    else:
        lines[index] = edit_word(lines[index], *spec)
    v = check("\n".join(lines) + "\n", controller, result)
    assert not v.ok
    # the CL point of that block is no longer reached, and only it
    assert v.missed_lines == [cl_line]
    if tcp and edit == "b+1deg":
        assert v.max_orientation_deviation_deg > 0.9


def test_cli_verify_exit_codes(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    for controller in CONTROLLERS:
        for mode, tcp in MODES.items():
            result = dome_post(controller, tcp)
            ext = DIALECTS[controller].extensions[0]
            good = tmp_path / f"dome_{mode}{ext}"
            good.write_text(result.text)
            index, cl_line = pick_block(result, "X")
            lines = result.text.splitlines()
            lines[index] = edit_word(lines[index], "X", 0.1)
            bad = tmp_path / f"dome_{mode}_edited{ext}"
            bad.write_text("\n".join(lines) + "\n")
            common = ["--machine", "dmu50", "--cl", str(DOME)]  # control from the extension
            assert main(["verify", str(good), *common]) == 0
            out = capsys.readouterr().out
            assert "within tolerance" in out and f"{len(dome())}/{len(dome())}" in out
            report = tmp_path / "report.json"
            assert main(["verify", str(bad), *common, "--report", str(report)]) == 1
            out = capsys.readouterr().out
            assert "BEYOND TOLERANCE" in out
            assert f"missed CL lines: {cl_line}" in out
            data = json.loads(report.read_text())
            assert data["verified"] is False
            assert data["cl_lines_missed"] == [cl_line]
            assert data["cl_points_reached"] == len(dome()) - 1


def test_cli_verify_machine_coordinates_needs_the_tool_length(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A machine-coordinate program holds the tool length: verifying it with another one
    fails, with the one it was posted for (mm here) passes."""
    result = dome_post("heidenhain", False)
    prog = tmp_path / "dome.h"
    prog.write_text(result.text)
    common = ["verify", str(prog), "-m", "dmu50", "--cl", str(DOME)]
    assert main([*common, "--tool-length", "100"]) == 0
    assert main([*common, "--tool-length", "99.9"]) == 1
    capsys.readouterr()


# --------------------------------------------------------------------------------------------
# nonlinear error of machine-coordinate moves


def test_machine_coordinates_are_subdivided_until_within_tolerance() -> None:
    m, tp = machine("dmu50"), dome()
    options = PostOptions(strategy="recursive", controller="heidenhain", tcp=False)
    default = Tolerances.for_units("mm")
    coarse_post = post_piece(tp, resolve(replace(options, tolerance=1000.0), m, tp.units))
    fine_post = post_piece(tp, resolve(options, m, tp.units))
    coarse, fine = coarse_post.program, fine_post.program
    assert coarse_post.figures.inserted_blocks == 0
    assert fine_post.figures.inserted_blocks > 100
    assert len(fine.moves()) == len(coarse.moves()) + fine_post.figures.inserted_blocks
    # the CL points alone, joined by straight lines in machine axes, miss the path
    v_coarse = verify(coarse, m, tp, tol=default)
    assert v_coarse.reached == len(tp)  # every end point is right ...
    assert not v_coarse.ok
    assert v_coarse.max_tip_deviation > 1.0  # ... but between them the tip leaves the path
    v_fine = verify(fine, m, tp, tol=default)
    assert v_fine.ok
    assert v_fine.max_tip_deviation <= default.tip
    # and the program as written and read back (rounded) is still within tolerance
    result = dome_post("heidenhain", False)
    assert result.verification.ok
    assert result.verification.max_tip_deviation <= default.tip
    assert len(result.program.moves()) == len(fine.moves())


def _two_block_program(m: Machine, q0: np.ndarray, q1: np.ndarray, tool_length: float) -> Program:
    """Machine-coordinate program of two feed moves (joint values in mm and rad)."""
    rotary = frozenset(a.name for a in m.rotary)
    deg = [a in rotary for a in m.axis_names]
    blocks = [ToolChange(1)]
    for q in (q0, q1):
        pos = np.where(deg, np.degrees(q), q)
        blocks.append(Move(False, tuple(float(x) for x in pos), feed=1000.0))
    return Program(
        name="TWO",
        axes=m.axis_names,
        rotary=rotary,
        units="mm",
        tcp=False,
        blocks=tuple(blocks),
        tool_length=tool_length,
    )


def _chord_deviation(m: Machine, q0: np.ndarray, q1: np.ndarray, tool_length: float) -> float:
    """Largest distance of the tip from the chord of its end points, by dense sampling."""
    t = np.linspace(0.0, 1.0, 200001)[:, None]
    tip, _ = tip_and_axis(m, q0 + t * (q1 - q0), tool_length)
    a, b = tip[0], tip[-1]
    u = (b - a) / np.linalg.norm(b - a)
    rel = tip - a
    s = np.clip(rel @ u, 0.0, np.linalg.norm(b - a))
    return float(np.linalg.norm(rel - s[:, None] * u, axis=1).max())


@pytest.mark.parametrize(
    ("label", "dx", "db"),
    [("C only", 0.0, 0.0), ("C with X", 12.0, 0.0), ("C with B and X", -8.0, 20.0)],
)
def test_deviation_inside_a_block_is_measured(label: str, dx: float, db: float) -> None:
    m = machine("dmu50")
    tool_length = m.settings.tool_length
    cols = {name: i for i, name in enumerate(m.axis_names)}
    c_axis = next(a for a in m.rotary if a.name == "C")
    # put the tip 50 mm from the C axis: at home the workpiece frame is the table's, so the
    # tip at q = 0 is the gauge point minus the tool length along +Z
    home_tip, _ = tip_and_axis(m, np.zeros((1, len(m.axes))), tool_length)
    q0 = np.zeros(len(m.axes))
    q0[cols["X"]] = c_axis.pivot[0] + 50.0 - home_tip[0, 0]
    q0[cols["Y"]] = c_axis.pivot[1] - home_tip[0, 1]
    q0[cols["Z"]] = -350.0
    q1 = q0.copy()
    q1[cols["C"]] = np.radians(90.0)
    q1[cols["X"]] += dx
    q1[cols["B"]] = np.radians(db)
    tip0, _ = tip_and_axis(m, q0[None], tool_length)
    radius = np.linalg.norm((tip0[0] - c_axis.pivot)[:2])
    assert radius == pytest.approx(50.0)
    tips, axes = tip_and_axis(m, np.vstack([q0, q1]), tool_length)
    tp = Toolpath.from_points(tips, axes, feed=1000.0, spindle=10000.0)
    program = _two_block_program(m, q0, q1, tool_length)
    v = verify(program, m, tp, tol=Tolerances.for_units("mm"))
    expected = _chord_deviation(m, q0, q1, tool_length)
    if label == "C only":
        # an arc of 90 deg at radius 50 mm: sagitta r (1 - cos 45 deg)
        assert expected == pytest.approx(50.0 * (1 - np.cos(np.radians(45.0))), abs=1e-6)
    assert v.reached == 2
    assert v.max_tip_deviation == pytest.approx(expected, abs=1e-3)
    assert not v.ok
    # the midpoint of the block alone would not give this figure unless the curve is symmetric
    mid, _ = tip_and_axis(m, ((q0 + q1) / 2)[None], tool_length)
    u = (tips[1] - tips[0]) / np.linalg.norm(tips[1] - tips[0])
    rel = mid[0] - tips[0]
    at_mid = float(np.linalg.norm(rel - (rel @ u) * u))
    if label != "C only":
        assert abs(at_mid - expected) > 1e-3
    # the same move with TCP on is a straight line: no deviation
    lin = list(m.linear_columns)
    tcp_blocks = []
    for q, tip in ((q0, tips[0]), (q1, tips[1])):
        pos = np.where([a in program.rotary for a in m.axis_names], np.degrees(q), q)
        pos[lin] = tip
        tcp_blocks.append(Move(False, tuple(float(x) for x in pos), feed=1000.0))
    tcp_program = Program(
        name="TWO",
        axes=m.axis_names,
        rotary=program.rotary,
        units="mm",
        tcp=True,
        blocks=(Tcp(True), *tcp_blocks),
        tool_length=tool_length,
    )
    v_tcp = verify(tcp_program, m, tp, tol=Tolerances.for_units("mm"))
    assert v_tcp.max_tip_deviation < 1e-9
    # (turning B and C together is not a great circle of the tool axis: only C alone is)
    assert v_tcp.ok is (db == 0.0)


def test_cl_points_closer_than_the_tolerance() -> None:
    """A program through exactly the CL points deviates by nothing, even where the CL points
    are closer together than the tolerance (a CL point must not be matched to a block that
    only passes near it, which would measure the next block against the wrong CL span)."""
    m = machine("dmu50")
    tips = np.array(
        [[0, 0, 5.0], [0.008, 0, 5], [0.008, 20, 5], [0.008, 20.006, 5], [10, 20.006, 5]]
    )
    axes = np.tile([0.0, 0.0, 1.0], (len(tips), 1))
    tp = Toolpath.from_points(tips, axes, feed=1000.0, spindle=10000.0)
    blocks = (Tcp(True), *(Move(False, (*t, 0.0, 0.0), feed=1000.0) for t in tips))
    program = Program(
        name="DENSE",
        axes=m.axis_names,
        rotary=frozenset({"B", "C"}),
        units="mm",
        tcp=True,
        blocks=blocks,
        tool_length=100.0,
    )
    v = verify(program, m, tp)
    assert v.ok
    assert v.reached == 5
    assert v.max_tip_deviation < 1e-9


# --------------------------------------------------------------------------------------------
# matching CL points to program points: the vectorised search is the sequential definition


def _match_sequential(
    cl_tip: np.ndarray, cl_axis: np.ndarray, tip: np.ndarray, axis: np.ndarray, tol: Tolerances
) -> np.ndarray:
    """The definition, one CL point after the other (verify's loop before it was vectorised;
    the first row reaching a point moved on to the nearest of the run of rows within both
    tolerances from there; a point repeating the point before, matched, at the next row or the
    same one where they reach it)."""
    n_cl, n = len(cl_tip), len(tip)
    out = np.full(n_cl, -1)
    ptr = 0

    def reaches(r: int, j: int) -> bool:
        d = float(np.linalg.norm(tip[r : r + 1] - cl_tip[j], axis=1)[0])
        return d <= tol.tip and float(angle_between(axis[r], cl_axis[j])) <= tol.orientation

    for j in range(n_cl):
        repeat = (
            j > 0 and (cl_tip[j] == cl_tip[j - 1]).all() and (cl_axis[j] == cl_axis[j - 1]).all()
        )
        if repeat and out[j - 1] >= 0:  # a dwell: the next row, or the same one, if they reach
            told = [r for r in (ptr + 1, ptr) if r < n and reaches(r, j)]
            if told:
                out[j] = ptr = told[0]
                continue
        start, width = ptr, 64
        while start < n:
            stop = min(n, start + width)
            d = np.linalg.norm(tip[start:stop] - cl_tip[j], axis=1)
            a = angle_between(axis[start:stop], cl_axis[j])
            hit = np.flatnonzero((d <= tol.tip) & (a <= tol.orientation))
            if hit.size:
                k = start + int(hit[0])
                # (row-wise norms, as the search: the loop took the 1-D norm, a BLAS dot whose
                # last bit may differ, which only matters for rows exactly as near as the next)

                def near(k: int, j: int = j) -> float:
                    """Larger share of the tip and the orientation tolerance."""
                    d = float(np.linalg.norm(tip[k] - cl_tip[j], axis=-1)) / tol.tip
                    chord = float(np.linalg.norm(axis[k] - cl_axis[j], axis=-1))
                    a = float(np.arcsin(np.array([min(0.5 * chord, 1.0)]))[0])
                    return max(d, a * (2.0 / tol.orientation))

                # the nearest row of the run of rows within both tolerances (nearness at most
                # 1; the first of equals)
                best, dist = k, near(k)
                r = k + 1
                while r < n and (here := near(r)) <= 1.0:
                    if here < dist:
                        best, dist = r, here
                    r += 1
                out[j] = best
                ptr = best
                break
            if width >= 4096:
                break
            start, width = stop, width * 4
    return out


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _cl_and_program(
    rng: np.random.Generator, n_cl: int, p: dict[str, float]
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A CL path and the points of a program for it, with what real programs have: leading
    moves elsewhere, points inserted on the segments (a few, or runs longer than the first
    search window, or longer than the whole search), points turning in place, CL points
    closer together than the tolerance or repeated (the tip; with ``p["dwell"]`` the whole
    point, up to 20 times: a dwell), points moved off (missed) or left out."""
    step = rng.choice(
        [0.0, 0.004, 0.3], size=n_cl, p=[p["repeat"], p["dense"], 1 - p["repeat"] - p["dense"]]
    )
    cl_tip = np.cumsum(_unit(rng.normal(size=(n_cl, 3))) * step[:, None], axis=0)
    cl_axis = _unit(np.array([0.0, 0.0, 1.0]) + np.cumsum(rng.normal(0, 0.003, (n_cl, 3)), axis=0))
    if p.get("dwell", 0.0):
        dwell = rng.random(n_cl) < p["dwell"]
        times = np.where(dwell, rng.choice([2, 5, 20], size=n_cl), 1)
        cl_tip, cl_axis = np.repeat(cl_tip, times, axis=0), np.repeat(cl_axis, times, axis=0)
        n_cl = len(cl_tip)
    tips, axes = [rng.normal(0, 50, (3, 3))], [np.tile([0.0, 0.0, 1.0], (3, 1))]
    for j in range(n_cl):
        if j:
            extra = rng.choice(
                [0, 1, 3, 40, 6000],
                p=[
                    1 - p["insert"] - 0.002,
                    p["insert"] * 0.7,
                    p["insert"] * 0.25,
                    p["insert"] * 0.05,
                    0.002,
                ],
            )
            f = np.linspace(0, 1, extra + 2)[1:-1, None]
            tips.append(cl_tip[j - 1] + f * (cl_tip[j] - cl_tip[j - 1]))
            axes.append(_unit(cl_axis[j - 1] + f * (cl_axis[j] - cl_axis[j - 1])))
        r = rng.random()
        if r < p["drop"]:
            continue
        here = cl_tip[j] + rng.normal(0, 0.001, 3)
        if r < p["drop"] + p["off"]:
            here = here + 0.05
        tips.append(here[None])
        axes.append(cl_axis[j][None])
        if rng.random() < p["turn"]:
            tips.append(np.repeat(here[None], 2, axis=0))
            axes.append(_unit(cl_axis[j] + rng.normal(0, 0.05, (2, 3))))
    return cl_tip, cl_axis, np.vstack(tips), np.vstack(axes)


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    n_cl=st.integers(1, 400),
    repeat=st.sampled_from([0.0, 0.05]),
    dense=st.sampled_from([0.0, 0.1, 0.5]),
    insert=st.sampled_from([0.0, 0.1, 0.6]),
    drop=st.sampled_from([0.0, 0.02, 0.3]),
    off=st.sampled_from([0.0, 0.02]),
    turn=st.sampled_from([0.0, 0.05]),
    dwell=st.sampled_from([0.0, 0.03]),
)
def test_matching_is_the_sequential_search(
    seed: int,
    n_cl: int,
    repeat: float,
    dense: float,
    insert: float,
    drop: float,
    off: float,
    turn: float,
    dwell: float,
) -> None:
    """The numpy rounds and the compiled loop (numba, what ``match_points`` runs from
    ``COMPILED_FROM`` points on) both find the rows of the sequential definition (with a
    dwell too: the repeated points take the row before without a search)."""
    from urdfpost.verification._match_kernel import match_rows
    from urdfpost.verification.match import REACH, match_points_numpy

    p = {"repeat": repeat, "dense": dense, "insert": insert, "drop": drop, "off": off, "turn": turn}
    p["dwell"] = dwell
    cl_tip, cl_axis, tip, axis = _cl_and_program(np.random.default_rng(seed), n_cl, p)
    tol = Tolerances()
    want = _match_sequential(cl_tip, cl_axis, tip, axis, tol)
    np.testing.assert_array_equal(match_points_numpy(cl_tip, cl_axis, tip, axis, tol), want)
    compiled = match_rows(cl_tip, cl_axis, tip, axis, tol.tip, tol.orientation, REACH)
    np.testing.assert_array_equal(compiled, want)


@pytest.mark.parametrize("damage", [False, True])
def test_compiled_matching_of_posted_programs(
    damage: bool, monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    """A posted program read back from its text (and the same with a stretch of its X words
    0.5 mm off, its CL points missed): ``match_points`` on the compiled loop finds the rows
    the numpy rounds find."""
    from urdfpost.dialects import dialect_for
    from urdfpost.verification import match
    from urdfpost.verification.match import match_points_numpy, program_joints, row_poses_at_tip

    job = read_cl(write_hemisphere(20_000, tmp_path / "hemisphere.apt"))
    m = machine("dmu50")
    result = post(job, m, PostOptions(controller="fanuc", tcp=False))
    text = result.text
    if damage:
        lines = text.splitlines(keepends=True)
        a, b = len(lines) // 3, len(lines) // 2
        lines[a:b] = [re.sub(r"X(-?[0-9.]+)", lambda w: f"X{float(w[1]) + 0.5:.3f}", x)
                      for x in lines[a:b]]  # fmt: skip
        text = "".join(lines)
    program = dialect_for("fanuc").read(text, path="prog.nc")
    values, _ = program_joints(m, program)
    rows = row_poses_at_tip(m, values, program.tcp, result.program.tool_length)
    tol = Tolerances.for_units("mm")
    want = match_points_numpy(job.tip, job.axis, rows.tip, rows.axis, tol)
    assert bool((want < 0).sum() > 1000) == damage  # the stretch's points missed
    monkeypatch.setattr(match.KERNELS, "start", 1)
    got = match.match_points(job.tip, job.axis, rows.tip, rows.axis, tol)
    np.testing.assert_array_equal(got, want)


def test_matching_a_program_that_reaches_nothing() -> None:
    rng = np.random.default_rng(5)
    cl_tip = np.cumsum(rng.normal(0, 0.3, (3000, 3)), axis=0)
    cl_axis = np.tile([0.0, 0.0, 1.0], (3000, 1))
    tip = cl_tip + 1.0  # every point off by more than the tolerance
    got = match_points(cl_tip, cl_axis, tip, cl_axis, Tolerances())
    assert (got == -1).all()


# --------------------------------------------------------------------------------------------
# the maximum inside every block: refined wherever the refinement could change a result


def _random_moves(
    m: Machine, rng: np.random.Generator, n: int, scale: float
) -> tuple[np.ndarray, np.ndarray]:
    """A random walk of n joint vectors (steps up to ``scale`` rad and 20 * scale mm) and CL
    tool axes near the ones it gives."""
    step = np.column_stack(
        [rng.uniform(-scale, scale, n) * (1.0 if a.rotary else 20.0) for a in m.axes]
    )
    q = np.cumsum(step, axis=0) + np.array([0.0 if a.rotary else 10.0 for a in m.axes])
    _, axis = tip_and_axis(m, q, 0.0)
    cl_axis = axis + rng.normal(0.0, 0.2 * scale, axis.shape)
    return q, cl_axis / np.linalg.norm(cl_axis, axis=1, keepdims=True)


@given(
    st.lists(st.tuples(*[st.one_of(st.just(np.nan), st.floats(-400.0, 400.0))] * 2), max_size=30)
)
def test_program_joints_fill_each_axis_forward_from_home(rows: list[tuple[float, float]]) -> None:
    """An axis not programmed yet stands at home, and then keeps its last programmed value,
    whether its unknown values are only before its first one or also after it."""
    m = machine("dmu50")
    position = np.array(rows, dtype=float).reshape(-1, 2)
    n = len(position)
    table = MoveTable(position, np.zeros(n, bool), np.full(n, np.nan), np.full(n, -1))
    program = Program("P", ("X", "C"), frozenset({"C"}), "mm", False, (table,))
    values, _ = program_joints(m, program)
    for j, name in enumerate(program.axes):
        col = m.axis_names.index(name)
        last = m.home[col]
        for i, value in enumerate(position[:, j]):
            if not np.isnan(value):
                last = np.radians(value) if name == "C" else value
            assert values[i, col] == last


@pytest.mark.parametrize("name", ["dmu50", "dmu50-nutating", "gantry-ca", "vf2-4axis"])
@pytest.mark.parametrize("tcp", [False, True])
@pytest.mark.parametrize("pivot", [0.0, 3.0])
def test_row_points_are_the_poses_the_matching_had(name: str, tcp: bool, pivot: float) -> None:
    """The rows' points and axes without the reach and swing (what the streamed verifier's
    cut and the process check match with) are bit for bit those of the rows' poses."""
    m = machine(name)
    q, _ = _random_moves(m, np.random.default_rng(5), 500, 0.5)
    values = q.copy()
    if tcp:
        values[:, list(m.linear_columns)] = tip_and_axis(m, q, 100.0)[0]
    poses = _row_poses(m, values, tcp, 100.0, pivot)
    point, axis = row_points(m, values, tcp, 100.0, pivot)
    np.testing.assert_array_equal(point, poses.tip)
    np.testing.assert_array_equal(axis, poses.axis)


@pytest.mark.parametrize("name", ["dmu50", "dmu50-nutating", "gantry-ca", "vf2-4axis"])
@pytest.mark.parametrize("tcp", [False, True])
@pytest.mark.parametrize("pivot", [0.0, 3.0])
@pytest.mark.parametrize("samples", [10, 18])
@pytest.mark.parametrize("shift", [0.0, 0.3])
@pytest.mark.parametrize("squeeze", [1.0, 1e-4])
def test_verify_block_bounds_hold(
    name: str, tcp: bool, pivot: float, samples: int, shift: float, squeeze: float
) -> None:
    """The bounds that decide which blocks verification refines are above the deviation
    anywhere in the block (dense samples). With ``shift`` the CL points move along the path
    by that share of a step, so the projection on a CL segment leaves [0, 1] inside blocks
    (the clip's kink is between samples). With ``squeeze`` the CL tips are drawn together to
    micrometre segments, shorter than the window of the orientation comparison."""
    m = machine(name)
    rng = np.random.default_rng(11)
    for scale in (0.002, 0.05, 0.5):
        q, cl_axis = _random_moves(m, rng, 60, scale)
        tip, axis = tip_and_axis(m, q, 100.0)
        along = np.gradient(tip, axis=0) * rng.uniform(-shift, shift, (len(tip), 1))
        cl_tip = tip + along + rng.normal(0.0, 0.01, tip.shape) + pivot * axis
        cl_tip = cl_tip[0] + squeeze * (cl_tip - cl_tip[0])
        values = q.copy()
        if tcp:
            values[:, list(m.linear_columns)] = tip
        feed = _Blocks(
            machine=m,
            values=values,
            rows=_row_poses(m, values, tcp, 100.0, pivot),
            start=np.arange(len(q) - 1),
            ja=np.arange(len(q) - 1),
            jb=np.arange(1, len(q)),
            polyline=_Polyline.of(cl_tip, cl_axis, pivot),
            tcp=tcp,
            tool_length=100.0,
            window=0.01,
        )
        blocks = np.arange(len(q) - 1)
        t = np.linspace(0.0, 1.0, samples)
        first: list = []
        sampled = feed.errors(blocks, t, first)
        tip_bound, chord_bound = feed.bounds(blocks, *sampled, first[0], t[1] - t[0])
        dist2, chord2 = feed.errors(blocks, np.linspace(0.0, 1.0, 2001))
        assert np.all(np.sqrt(dist2.max(axis=0)) <= tip_bound + 1e-12)
        assert np.all(np.sqrt(chord2.max(axis=0)) <= chord_bound + 1e-12)


def _largest_errors(
    m: Machine, q: np.ndarray, seg: Segments, arc: Arcs, t: np.ndarray, tcp: bool, window: float
) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
    """Largest squared tip distance, axis chord at t (TCP only) and orientation error at t in
    the blocks joining rows of q."""
    p, v = tip_and_axis_along(m, q[:-1], q[1:], t, 100.0, with_tip=not tcp)
    dist2, chord2, path2 = _orientation_error(seg, arc, p, v, t[:, None], tcp, window)
    return (
        np.zeros(path2.shape[1]) if dist2 is None else dist2.max(axis=0),
        None if chord2 is None else chord2.max(axis=0),
        path2.max(axis=0),
    )


@pytest.mark.parametrize("name", ["dmu50", "dmu50-nutating", "gantry-ca", "vf2-4axis"])
@pytest.mark.parametrize("tcp", [False, True])
@pytest.mark.parametrize("squeeze", [1.0, 1e-4])
def test_subdivision_block_bounds_hold(name: str, tcp: bool, squeeze: float) -> None:
    """Likewise for the bounds that decide which blocks the subdivision refines (``squeeze``
    as above)."""
    m = machine(name)
    rng = np.random.default_rng(12)
    samples = Tolerances().samples_per_block
    window = 0.008
    for scale in (0.002, 0.05, 0.5):
        q, cl_axis = _random_moves(m, rng, 60, scale)
        tip, _ = tip_and_axis(m, q, 100.0)
        cl_tip = tip + rng.normal(0.0, 0.01, tip.shape)
        cl_tip = cl_tip[0] + squeeze * (cl_tip - cl_tip[0])
        seg = Segments.between(cl_tip[:-1], cl_tip[1:])
        arc = Arcs.between(cl_axis[:-1], cl_axis[1:])
        poses = RowPoses.of(m, q, 100.0)
        ends = (poses.take(slice(0, -1)), poses.take(slice(1, None)))

        t = np.arange(1, samples + 1) / (samples + 1)
        sampled = _largest_errors(m, q, seg, arc, t, tcp, window)
        bound = _error_bounds(m, q[:-1], q[1:], seg, arc, ends, *sampled, t[0], tcp, window)
        dense = _largest_errors(m, q, seg, arc, np.linspace(0.0, 1.0, 2001), tcp, window)
        assert np.all(np.sqrt(dense[0]) <= bound[0] + 1e-12)
        assert np.all(np.sqrt(dense[2]) <= bound[1] + 1e-12)
        # from the block ends alone (what rules out sampling a chunk at all): looser, and a
        # bound all the same
        slack = _Slack.of(m, q[:-1], q[1:], seg, arc, ends, t[0], tcp, window)
        zero = np.zeros(len(q) - 1)
        tip_bound, chord_bound = slack.spaced(1.0).bounds(zero, zero, zero)
        assert np.all(np.sqrt(dense[0]) <= tip_bound + 1e-12)
        assert np.all(np.sqrt(dense[2]) <= chord_bound + 1e-12)
        # and where it keeps blocks below the targets, it says so with those bounds
        targets = (float(np.median(tip_bound)), 2.0 * np.arcsin(np.median(chord_bound) / 2.0))
        got_tip, got_chord, clear = slack.cleared(targets)
        np.testing.assert_array_equal(got_tip, tip_bound)
        np.testing.assert_array_equal(got_chord, chord_bound)
        below = chord_bound < np.median(chord_bound) * (1.0 - 1e-6)
        if not tcp:
            below &= tip_bound < np.median(tip_bound) * (1.0 - 1e-6)
        np.testing.assert_array_equal(clear, below)


@pytest.mark.parametrize("tcp", [False, True])
@pytest.mark.parametrize("name", ["dmu50", "gantry-ca", "dmu50-nutating"])
def test_subdivision_skips_blocks_its_bounds_clear(
    monkeypatch: pytest.MonkeyPatch, name: str, tcp: bool
) -> None:
    """The subdivision samples no block whose ends alone keep it below the targets: the same
    rows (to the bit) as sampling every block, on a path where most blocks are cleared and
    some are not (a fine raster with a stretch of large steps), and it did skip."""
    from urdfpost.linearize import subdivide

    m = machine(name)
    rng = np.random.default_rng(3)
    tol = Tolerances()
    fine, _ = _random_moves(m, rng, 20000, 0.0005)
    coarse, _ = _random_moves(m, rng, 300, 0.3)
    q = np.concatenate([fine, coarse + (fine[-1] - coarse[0])])
    tip, axis_at = tip_and_axis(m, q, 100.0)
    cleared: list[np.ndarray] = []
    real = linearize_module._Slack.cleared

    def counted(self: _Slack, targets: tuple[float, float]) -> tuple[np.ndarray, ...]:
        out = real(self, targets)
        cleared.append(out[2])
        return out

    monkeypatch.setattr(linearize_module._Slack, "cleared", counted)
    got = subdivide(m, q, tip, axis_at, tool_length=100.0, tcp=tcp, tol=tol)
    share = np.concatenate(cleared).mean()
    assert 0.5 < share < 1.0, share

    def nothing(self: _Slack, targets: tuple[float, float]) -> tuple[np.ndarray, ...]:
        tip_bound, chord_bound, clear = real(self, targets)
        return tip_bound, chord_bound, np.zeros_like(clear)

    monkeypatch.setattr(linearize_module._Slack, "cleared", nothing)
    want = subdivide(m, q, tip, axis_at, tool_length=100.0, tcp=tcp, tol=tol)
    for field in ("q", "tip", "axis", "source"):
        np.testing.assert_array_equal(getattr(got, field), getattr(want, field))
    assert len(got.q) > len(q)  # the coarse stretch was bisected


def _refine_everywhere(monkeypatch: pytest.MonkeyPatch) -> None:
    def always(bound: np.ndarray, level: float | np.ndarray) -> np.ndarray:
        return np.ones(np.shape(bound), dtype=bool)

    monkeypatch.setattr(linearize_module, "may_reach", always)
    monkeypatch.setattr(verify_module, "may_reach", always)


@pytest.mark.parametrize("tcp", [False, True])
@pytest.mark.parametrize("strategy", ["recursive", "cone"])
def test_refining_where_it_matters_is_refining_everywhere(
    monkeypatch: pytest.MonkeyPatch, tcp: bool, strategy: str
) -> None:
    """Skipping the golden-section search where the bounds rule out a change gives the same
    program and the same verification as searching every block (up to deviations below a
    billionth of the tolerance, which verification does not refine)."""
    m, tp = machine("dmu50"), dome()
    options = PostOptions(strategy=strategy, controller="heidenhain", tcp=tcp)
    tol = Tolerances.for_units("mm")
    program = post_piece(tp, resolve(options, m, tp.units)).program
    checks = [verify(program, m, tp, tol=tol, pivot=pivot) for pivot in (0.0, 3.0)]
    _refine_everywhere(monkeypatch)
    program_all = post_piece(tp, resolve(options, m, tp.units)).program
    assert program_all == program
    for pivot, check in zip((0.0, 3.0), checks, strict=True):
        everywhere = verify(program, m, tp, tol=tol, pivot=pivot)
        tip = check.max_tip_deviation
        assert everywhere.max_tip_deviation == pytest.approx(tip, rel=0, abs=1e-9 * tol.tip)
        assert everywhere.max_orientation_deviation_deg == pytest.approx(
            check.max_orientation_deviation_deg, rel=0, abs=1e-9 * check.orientation_tolerance_deg
        )
        if tip > 1e-6 * tol.tip:  # (below, the worst is any of many blocks on the CL path)
            assert everywhere.worst_cl_line == check.worst_cl_line
        fields = ("ok", "reached", "missed_lines", "blocks", "mean_tip_deviation", "notes")
        assert [getattr(everywhere, f) for f in fields] == [getattr(check, f) for f in fields]


@pytest.mark.parametrize("largest", [0.0, 1e-6, 1e-3, 0.03, 0.1, 0.5, 4.0])
def test_cos_sin_of_small_angles(largest: float) -> None:
    """The Taylor polynomials for the small angles between CL axes are as good as numpy."""
    angle = np.linspace(-largest, largest, 10001)
    cos, sin = cos_sin(angle)
    np.testing.assert_allclose(cos, np.cos(angle), rtol=0, atol=2.3e-16)
    np.testing.assert_allclose(sin, np.sin(angle), rtol=0, atol=2.3e-16)


def test_matching_falls_back_to_numpy_when_the_compiled_loop_fails(
    monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture, stand_in: StandIn
) -> None:
    """numba that cannot compile or cache the loop on this machine: a warning, and the numpy
    rounds give the rows (for the rest of the process too)."""
    from urdfpost.verification import match

    def broken(*args: object) -> np.ndarray:
        raise RuntimeError("cannot cache function 'match_rows': no locator available")

    monkeypatch.setattr(match.KERNELS, "start", 1)
    stand_in(match.KERNELS, SimpleNamespace(match_rows=broken))
    p = {"repeat": 0.0, "dense": 0.1, "insert": 0.1, "drop": 0.02, "off": 0.02, "turn": 0.05}
    cl_tip, cl_axis, tip, axis = _cl_and_program(np.random.default_rng(3), 300, p)
    tol = Tolerances()
    want = match.match_points_numpy(cl_tip, cl_axis, tip, axis, tol)
    with caplog.at_level("WARNING", logger="urdfpost.verification.match"):
        np.testing.assert_array_equal(match.match_points(cl_tip, cl_axis, tip, axis, tol), want)
    assert "compiled matching unavailable (cannot cache function" in caplog.text
    assert match.KERNELS.failed
    np.testing.assert_array_equal(match.match_points(cl_tip, cl_axis, tip, axis, tol), want)


def test_a_blip_in_the_nearness_along_a_run_does_not_stop_the_match_early() -> None:
    """CL points closer together than the tip tolerance, and rows every quarter of a CL segment
    on the line but the one before each CL point, 2 um off it and so a little farther from the
    point than the row before (what the read-back's rounding gives near the pole):
    each CL point is matched to its own row, the nearest of the run reaching it, by the numpy
    rounds and the compiled loop alike (the first row after which the next was not nearer
    used to stop at the blip, a CL segment early)."""
    from urdfpost.verification._match_kernel import match_rows
    from urdfpost.verification.match import REACH, match_points_numpy

    tol = Tolerances()
    n_cl, per = 6, 4
    cl_tip = np.zeros((n_cl, 3))
    cl_tip[:, 0] = 0.004 * np.arange(n_cl)  # 0.4 of the tip tolerance apart
    cl_axis = np.tile([0.0, 0.0, 1.0], (n_cl, 1))
    x = 0.004 * np.arange((n_cl - 1) * per + 1) / per
    tip = np.stack([x, np.zeros_like(x), np.zeros_like(x)], axis=1)
    for j in range(1, n_cl):  # the blip: the row before each point farther than the one before
        tip[j * per - 1, 1] = 0.002  # (0.00224 mm from the point, against 0.002)
    axis = np.tile([0.0, 0.0, 1.0], (len(x), 1))
    want = np.arange(n_cl) * per
    np.testing.assert_array_equal(match_points_numpy(cl_tip, cl_axis, tip, axis, tol), want)
    compiled = match_rows(cl_tip, cl_axis, tip, axis, tol.tip, tol.orientation, REACH)
    np.testing.assert_array_equal(compiled, want)
    np.testing.assert_array_equal(_match_sequential(cl_tip, cl_axis, tip, axis, tol), want)


@pytest.mark.parametrize("rows_per_point", [1, 0], ids=["a-block-each", "one-block"])
def test_a_dwell_longer_than_the_search_keeps_the_path_after_it(rows_per_point: int) -> None:
    """A CL point repeated more times than the search looks rows ahead (``REACH``), written
    as one block per CL point: the repeated points take the dwell's blocks one by one, so the
    path after the dwell is found (it used to be missed from the dwell's first block on, the
    nearest of the equal rows), by the numpy rounds, the compiled loop and the definition
    alike. Written as one block for the whole dwell, every repeat takes that block."""
    from urdfpost.verification._match_kernel import match_rows
    from urdfpost.verification.match import REACH, match_points_numpy

    tol = Tolerances()
    dwell = REACH + 500
    line = np.zeros((40, 3))
    line[:, 0] = 0.5 * np.arange(40)
    cl_tip = np.concatenate([line[:20], np.repeat(line[20:21], dwell, axis=0), line[21:]])
    cl_axis = np.tile([0.0, 0.0, 1.0], (len(cl_tip), 1))
    off = np.array([0.0, 0.0005, 0.0])  # (the rows 0.5 um beside the CL points)
    if rows_per_point:
        tip, want = cl_tip + off, np.arange(len(cl_tip))
    else:
        tip = line + off
        want = np.concatenate([np.arange(20), np.full(dwell, 20), np.arange(21, 40)])
    axis = np.tile([0.0, 0.0, 1.0], (len(tip), 1))
    np.testing.assert_array_equal(match_points_numpy(cl_tip, cl_axis, tip, axis, tol), want)
    compiled = match_rows(cl_tip, cl_axis, tip, axis, tol.tip, tol.orientation, REACH)
    np.testing.assert_array_equal(compiled, want)
    np.testing.assert_array_equal(_match_sequential(cl_tip, cl_axis, tip, axis, tol), want)


@pytest.mark.parametrize(("seed", "noise"), [(0, 0.0), (1, 1e-4), (2, 3e-3)])
def test_a_path_back_and_forth_within_the_tolerance_is_matched_as_defined(
    seed: int, noise: float, monkeypatch: pytest.MonkeyPatch
) -> None:
    """CL points alternating between two places 0.001 mm apart (within the tip tolerance of
    each other), rows at them with or without noise: every point's run is the rest of the
    program. The compiled loop keeps a memo of the long runs of a point seen before
    (``_match_kernel._run_memo``), and the numpy rounds hand such a job to it
    (``_LongRuns``): the rows of the definition either way, in linear time (a 32k-point job
    took 84 s, now 2 s)."""
    from urdfpost.verification import match
    from urdfpost.verification._match_kernel import MEMO_FROM, match_rows
    from urdfpost.verification.match import REACH, match_points_numpy

    tol = Tolerances()
    rng = np.random.default_rng(seed)
    n = 600
    there = np.where((np.arange(n) % 2 == 0)[:, None], [0.0, 0.0, 5.0], [0.001, 0.0, 5.0])
    cl_tip = np.concatenate([[[-5.0, 0.0, 5.0]], there, [[5.0, 0.0, 5.0]]])
    cl_axis = np.tile([0.0, 0.0, 1.0], (len(cl_tip), 1))
    tip = cl_tip + (rng.normal(0.0, noise, cl_tip.shape) if noise else 0.0)
    axis = cl_axis.copy()
    want = _match_sequential(cl_tip, cl_axis, tip, axis, tol)
    assert (want >= 0).all()
    if not noise:  # (equal rows: each point its own)
        np.testing.assert_array_equal(want, np.arange(len(cl_tip)))
    assert n > MEMO_FROM  # (the runs are memos)
    compiled = match_rows(cl_tip, cl_axis, tip, axis, tol.tip, tol.orientation, REACH)
    np.testing.assert_array_equal(compiled, want)
    np.testing.assert_array_equal(match_points_numpy(cl_tip, cl_axis, tip, axis, tol), want)
    # the numpy rounds stop at a long run (not with rows 3 um off: short runs), and the
    # compiled loop takes the job
    monkeypatch.setattr(match, "_LONG_RUN", 64)
    if noise < 1e-3:
        with pytest.raises(match._LongRuns):
            match_points_numpy(cl_tip, cl_axis, tip, axis, tol, handoff=True)
    monkeypatch.setattr(match.KERNELS, "start", 10**9)
    np.testing.assert_array_equal(match.match_points(cl_tip, cl_axis, tip, axis, tol), want)
