"""Planning over the whole path: collisions decide the branch, rewinds where travel runs out,
and the global planner against the local one."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import trimesh
from oracles import tip_and_axis_pin

from urdfpost import load_machine
from urdfpost.analysis.testpaths import PATHS
from urdfpost.cli import main
from urdfpost.dialects import dialect_for
from urdfpost.errors import CollisionError, UnreachableError
from urdfpost.planning.branches import Preference, select
from urdfpost.posting.options import PostOptions
from urdfpost.posting.whole import post
from urdfpost.program import Comment, Move, rewind_moves
from urdfpost.toolpath import Event, Motion, Toolpath
from urdfpost.verification import program_joints

ROOT = Path(__file__).resolve().parents[1]
GANTRY = ROOT / "robots" / "urdf" / "gantry-ca.urdf"
CONTROLS = ("heidenhain", "siemens", "fanuc", "linuxcnc")

# a motor housing on one side of the C head of gantry-ca: the head is no longer symmetric about
# C, so the two branches (A+ with C, A- with C + 180) put it on opposite sides of the tool
MOTOR = (
    '<collision name="c_motor"><origin xyz="0.30 0 -0.15" rpy="0 0 0"/>'
    '<geometry><box size="0.12 0.12 0.2"/></geometry></collision>\n    '
)


def _fixture(side: int) -> str:
    name = "tall_fixture_plus" if side > 0 else "tall_fixture_minus"
    return (
        f'<collision name="{name}"><origin xyz="{side * 0.33} 0 0.3" rpy="0 0 0"/>'
        '<geometry><box size="0.18 0.6 0.6"/></geometry></collision>\n'
    )


def machine_with_fixtures(tmp_path: Path, sides: tuple[int, ...]) -> Path:
    """gantry-ca with the motor housing and 600 mm tall fixtures beside the part at +X / -X."""
    text = GANTRY.read_text(encoding="utf-8")
    text = text.replace('<collision name="c_housing">', MOTOR + '<collision name="c_housing">', 1)
    start = text.index('<link name="workpiece">')
    end = text.index("</link>", start)
    text = text[:end] + "".join(_fixture(s) for s in sides) + text[end:]
    path = tmp_path / f"gantry-fixtures{len(sides)}.urdf"
    path.write_text(text, encoding="utf-8")
    return path


def toolpath_of(tip: np.ndarray, axis: np.ndarray, cutter: dict | None = None) -> Toolpath:
    """A feed path (first move rapid) with a 10 mm flat cutter, lines 10, 11, ..."""
    n = len(tip)
    motion = np.full(n, Motion.FEED, dtype=np.int8)
    motion[0] = Motion.RAPID
    data = cutter or {"diameter": 10.0, "corner_radius": 0.0}
    return Toolpath(
        tip=np.asarray(tip, dtype=float),
        axis=np.asarray(axis, dtype=float),
        feed=np.full(n, 1000.0),
        motion=motion,
        line=np.arange(10, 10 + n),
        events=(
            Event(index=0, kind="tool", line=8, data={"number": 1}),
            Event(index=0, kind="cutter", line=9, data=data),
            Event(index=0, kind="spindle", line=9, data={"rpm": 10000.0, "direction": "cw"}),
        ),
        source="job.apt",
        units="mm",
    )


def tilted_line(n: int = 20, tilt_deg: float = 20.0) -> Toolpath:
    """Tool tilted about X (A axis) along a line in X: C stands, A+ or A- with C + 180."""
    t = np.radians(tilt_deg)
    axis = np.tile([0.0, -np.sin(t), np.cos(t)], (n, 1))
    tip = np.stack([np.linspace(-20, 20, n), np.zeros(n), np.full(n, 20.0)], axis=1)
    return toolpath_of(tip, axis)


def spiral(turns: float = 3.0, n: int = 400, tilt_deg: float = 30.0) -> Toolpath:
    """The tool axis turns ``turns`` times about Z at a constant tilt: C has to follow."""
    az = np.radians(np.linspace(0.0, 360.0 * turns, n))
    t = np.radians(tilt_deg)
    axis = np.stack([np.sin(t) * np.cos(az), np.sin(t) * np.sin(az), np.full(n, np.cos(t))], 1)
    tip = np.stack([40 * np.cos(az), 40 * np.sin(az), np.linspace(0, -6, n)], axis=1)
    return toolpath_of(tip, axis)


# -- collisions decide the branch ----------------------------------------------------------


def test_preferred_branch_hits_a_tall_fixture_and_the_clear_one_is_taken(tmp_path: Path) -> None:
    m = load_machine(machine_with_fixtures(tmp_path, (+1,)))
    tp = tilted_line()
    a = m.axis_names.index("A")
    # without collision checks the preference (A+) wins and the motor housing is in the fixture
    plain = post(tp, m, PostOptions(prefer=Preference("A", +1), strategy="recursive"))
    cut = [mv.cl_line is not None for mv in plain.program.moves()]  # not the post's own
    assert np.all(program_joints(m, plain.program)[0][cut, a] > 0)
    assert plain.report.as_json()["collisions"] == {"checked": False}
    checked = post(
        tp, m, PostOptions(prefer=Preference("A", +1), strategy="recursive", collisions=True)
    )
    values, _ = program_joints(m, checked.program)
    cut = [mv.cl_line is not None for mv in checked.program.moves()]
    assert np.all(values[cut, a] < 0)
    assert checked.verification.ok
    why = [w for w in checked.report.as_json()["warnings"] if "collides" in w]
    assert why and "job.apt:10" in why[0] and "c_motor with tall_fixture_plus" in why[0]
    assert checked.report.as_json()["collisions"]["checked"]
    assert checked.report.as_json()["collisions"]["min_clearance"] > 0


def test_every_branch_colliding_is_an_error_naming_the_line_and_bodies(tmp_path: Path) -> None:
    m = load_machine(machine_with_fixtures(tmp_path, (+1, -1)))
    with pytest.raises(CollisionError) as err:
        post(tilted_line(), m, PostOptions(collisions=True, strategy="recursive"))
    text = str(err.value)
    assert "job.apt:10: every branch collides" in text
    assert "c_motor collides with tall_fixture_plus" in text
    assert "c_motor collides with tall_fixture_minus" in text


def test_holder_in_the_stock_is_an_error_naming_holder_and_stock(tmp_path: Path) -> None:
    """A pocket bottom 60 mm deep in an 80 mm block: a tool sticking out 50 mm puts its shank
    and holder into the block on every branch."""
    stock = trimesh.creation.box(extents=(300, 300, 80))
    stock.apply_translation((0, 0, 40))  # on the fixture plate, top at z = 80
    stock_file = tmp_path / "stock.stl"
    stock.export(stock_file)
    n = 5
    t = np.radians(10.0)
    tip = np.stack([np.linspace(-5, 5, n), np.zeros(n), np.full(n, 20.0)], axis=1)
    axis = np.tile([0.0, -np.sin(t), np.cos(t)], (n, 1))
    tp = toolpath_of(tip, axis, {"diameter": 10.0, "length": 50.0})
    with pytest.raises(
        CollisionError,
        match=r"job\.apt:10: every branch collides: .*(shank|holder) collides with stock",
    ):
        post(tp, load_machine("gantry-ca"), PostOptions(stock=str(stock_file)))


def test_post_with_stock_reports_the_clearance_on_the_dome(tmp_path: Path) -> None:
    report = tmp_path / "dome.json"
    code = main(
        [
            "post",
            str(ROOT / "examples" / "dome.apt"),
            "-m",
            "dmu50",
            "-o",
            str(tmp_path / "dome.h"),
            "--stock",
            str(ROOT / "examples" / "dome.stl"),
            "--report",
            str(report),
            "-q",
        ]
    )
    assert code == 0
    hits = json.loads(report.read_text())["collisions"]
    assert hits["checked"] and hits["moves"] > 300
    # the shank of the 6 mm ball mill passes the dome with the clearance the geometry gives:
    # positive, below the 15 mm link height
    assert 0 < hits["min_clearance"] < 15
    assert "stock" in hits["nearest"]


# -- rewinds ----------------------------------------------------------------------------------


@pytest.mark.parametrize("tcp", [True, False], ids=["tcp", "mc"])
@pytest.mark.parametrize("control", CONTROLS)
def test_c_running_out_of_travel_rewinds_in_every_dialect(control: str, tcp: bool) -> None:
    """Three turns about Z on a head with C limited to +-360 deg: one rewind (lift 50 mm along
    the tool axis, turn, return), listed with its CL line, and the program verifies."""
    m = load_machine("gantry-ca")
    tp = spiral()
    result = post(tp, m, PostOptions(controller=control, tcp=tcp, strategy="recursive"))
    rewinds = result.report.as_json()["rewinds"]
    assert len(rewinds) == 1
    line = rewinds[0]["cl_line"]
    assert line in tp.line
    assert result.verification.ok and result.verification.reached == len(tp)
    dialect = dialect_for(control)
    back = dialect.read(result.text)
    assert any(isinstance(b, Comment) and f"cl line {line}" in b.text.lower() for b in back.blocks)
    values, rapid = program_joints(m, back)
    cols = list(m.rotary_columns) if tcp else list(range(len(m.axes)))  # TCP: X Y Z are the tip
    assert np.all(
        (values[:, cols] >= m.lower[cols] - 1e-6) & (values[:, cols] <= m.upper[cols] + 1e-6)
    )
    marked = np.flatnonzero(rewind_moves(back))
    assert len(marked) == 3  # lift, turn, return
    lift, turn, ret = marked
    assert rapid[lift] and rapid[turn] and not rapid[ret]
    i = int(np.flatnonzero(tp.line == line)[0])
    if tcp:
        up = values[lift, list(m.linear_columns)]
    else:
        up = tip_and_axis_pin(m, values[lift : lift + 1], m.settings.tool_length)[0][0]
    np.testing.assert_allclose(up, tp.tip[i] + 50.0 * tp.axis[i], atol=2e-3)
    # the turn changes branch or unwinds: C moves by more than half a turn
    c = m.axis_names.index("C")
    assert abs(values[turn, c] - values[lift, c]) > np.pi


def test_rewind_feed_and_retract_are_configurable() -> None:
    m = load_machine("gantry-ca")
    result = post(spiral(), m, PostOptions(controller="siemens", retract=20.0, rewind_feed=3000.0))
    moves = result.program.moves()
    marked = np.flatnonzero(rewind_moves(result.program))
    assert all(not moves[k].rapid for k in marked)
    assert moves[marked[0]].feed == pytest.approx(3000.0)
    assert result.report.as_json()["rewinds"][0]["retract_mm"] == pytest.approx(20.0)
    assert result.verification.ok


def test_no_rewind_when_travel_suffices() -> None:
    """One and a half turns fit in C's 720 degrees, though not from where the preferred start
    (C nearest 0) would begin: the planner starts where the whole path fits."""
    result = post(spiral(turns=1.5), load_machine("gantry-ca"), PostOptions(strategy="recursive"))
    assert result.report.as_json()["rewinds"] == []
    assert not rewind_moves(result.program).any()
    moves = [b for b in result.program.blocks if isinstance(b, Move) and b.cl_line is not None]
    assert sum(b.rapid for b in moves) == 1  # the CL's approach only
    assert moves[0].position[-1] == pytest.approx(-270.0)  # C: the start from which 540 fits


# -- global against local ---------------------------------------------------------------------


def _travel(m, q: np.ndarray) -> float:
    return float(np.abs(np.diff(q[:, list(m.rotary_columns)], axis=0)).sum())


@pytest.mark.parametrize("path", sorted(PATHS))
@pytest.mark.parametrize("name", ["dmu50", "gantry-ca", "umc750", "monoblock", "dmu50-nutating"])
def test_global_rotary_travel_is_never_worse_than_local(name: str, path: str) -> None:
    m = load_machine(name)
    tp = PATHS[path]()
    kwargs = dict(tool_length=m.settings.tool_length, lines=tp.line, source=tp.source)
    try:
        local = select(m, tp.tip, tp.axis, planner="local", **kwargs)
    except UnreachableError:
        pytest.skip(f"{path} is not reachable on {name}")
    best = select(m, tp.tip, tp.axis, planner="global", **kwargs)
    assert int(best.rewind.sum()) <= int(local.rewind.sum())
    if best.rewind.sum() == local.rewind.sum():
        assert _travel(m, best.q) <= _travel(m, local.q) + 1e-9


def test_compare_checks_collisions_as_a_post_does(tmp_path: Path) -> None:
    """``compare`` posts each strategy through the post's own path (``post_piece``), collision
    world and check of the program's moves included: with every branch colliding, every
    strategy fails with the post's collision error, where without collision checks all
    verify."""
    from urdfpost.analysis.compare import compare

    m = load_machine(machine_with_fixtures(tmp_path, (+1, -1)))
    names = ["none", "recursive", "cone"]
    unchecked = compare(tilted_line(), m, names, PostOptions())
    assert all(o.verified for o in unchecked.outcomes)
    checked = compare(tilted_line(), m, names, PostOptions(collisions=True))
    for o in checked.outcomes:
        assert not o.verified and o.metrics is None
        assert o.error is not None and "job.apt:10: every branch collides" in o.error
