"""Machine files: the shipped machines, bad files, and a URDF written by someone else."""

from __future__ import annotations

import re
import zlib
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from oracles import tip_and_axis_pin
from test_kinematics import axis_angle_error, check_round_trip
from urdfgen import J, simple_urdf

from urdfpost.dialects import DIALECTS
from urdfpost.errors import GeometryError, MachineDefinitionError
from urdfpost.kinematics import assemble, solve_rotary
from urdfpost.machine import Machine, Settings, list_machines, load_machine, machine_from_urdf

ROOT = Path(__file__).resolve().parents[1]
SHIPPED = sorted((ROOT / "robots" / "urdf").glob("*.urdf"))
FAMILIES = ("table-table", "head-head", "head-table", "4-axis")


def q_within_travel(m: Machine, rng: np.random.Generator, n: int) -> np.ndarray:
    """Joint vectors inside the travel; continuous axes over +/-3 pi (checked mod 2 pi)."""
    q = np.empty((n, len(m.axes)))
    for j, a in enumerate(m.axes):
        lo, hi = (-3 * np.pi, 3 * np.pi) if a.continuous else (a.lower, a.upper)
        q[:, j] = rng.uniform(lo, hi, n)
    q[0] = np.clip(0.0, m.lower, m.upper)
    q[1] = m.home
    return q


# -- shipped machines ------------------------------------------------------------------------


def test_shipped_machines_present():
    if not SHIPPED:
        pytest.skip("robots/urdf/ has no machines yet")
    known = list_machines()
    for path in SHIPPED:
        assert path.stem in known, f"list_machines() misses {path.stem}"
        assert known[path.stem].resolve() == path.resolve()


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: p.stem)
def test_shipped_machine_structure(path):
    m = load_machine(path)
    assert m.name == path.stem
    assert m.family in FAMILIES
    assert tuple(a.name for a in m.linear) == ("X", "Y", "Z")
    assert 1 <= len(m.rotary) <= 2
    assert (m.family == "4-axis") == (len(m.rotary) == 1)
    sides = sorted(a.side for a in m.rotary)
    by_sides = {
        ("table",): "4-axis",
        ("head",): "4-axis",
        ("table", "table"): "table-table",
        ("head", "head"): "head-head",
        ("head", "table"): "head-table",
    }
    assert m.family == by_sides[tuple(sides)]
    for a in m.axes:
        assert np.linalg.norm(a.direction) == pytest.approx(1.0, abs=1e-12)
        if not a.continuous:
            assert a.lower < a.upper, a.name
        assert a.velocity > 0
    h = m.home_tool_in_work
    np.testing.assert_allclose(h[:3, :3] @ h[:3, :3].T, np.eye(3), atol=1e-12)
    # settings are sane: controller and units known, preference on a rotary axis, home in travel
    s = m.settings
    assert s.controller in DIALECTS
    assert s.units in ("mm", "inch")
    assert s.tool_length >= 0
    if s.prefer is not None:
        assert s.prefer[0] in {a.name for a in m.rotary}
        assert s.prefer[1] in (1, -1)
    assert np.all(m.home >= m.lower) and np.all(m.home <= m.upper), "home outside travel"
    # by name, the same machine
    by_name = load_machine(path.stem)
    assert by_name.axis_names == m.axis_names
    np.testing.assert_array_equal(by_name.home_tool_in_work, m.home_tool_in_work)


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: p.stem)
def test_shipped_machine_pivots_not_zero(path):
    """No rotary axis line passes through programming zero (docs: a few mm to tens of mm off)."""
    m = load_machine(path)
    for a in m.rotary:
        assert np.linalg.norm(a.pivot) >= 1.0, (
            f"{path.stem}: the {a.name} axis line passes {np.linalg.norm(a.pivot):.3g} mm "
            "from the workpiece origin"
        )
        # the pivot is the foot of the perpendicular from the origin onto the axis line
        assert a.pivot @ a.direction == pytest.approx(0.0, abs=1e-9)


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: p.stem)
def test_shipped_machine_round_trip(path):
    m = load_machine(path)
    q = q_within_travel(m, np.random.default_rng(zlib.crc32(path.stem.encode())), 300)
    for tool_length in (0.0, m.settings.tool_length or 100.0):
        check_round_trip(m, q, tool_length)


# -- the minimal example in docs/machines.md -------------------------------------------------


def test_docs_minimal_example():
    docs = ROOT / "docs" / "machines.md"
    if not docs.is_file():
        pytest.skip("docs/machines.md not written yet")
    blocks = [b for b in re.findall(r"```xml\n(.*?)```", docs.read_text(), re.S) if "<robot" in b]
    if not blocks:
        pytest.skip("docs/machines.md has no complete example")
    m = machine_from_urdf(blocks[0], source="docs/machines.md", name="my-trunnion")
    assert m.family == "table-table"
    assert m.settings == Settings()  # no <urdfpost>: every default
    # claims made in the text below the example
    np.testing.assert_allclose(m.home_tool_axis, [0, 0, 1], atol=1e-12)
    assert m.home_tool_in_work[2, 3] == pytest.approx(520.0)
    q = np.zeros(len(m.axes))
    q[m.axis_names.index("B")] = np.radians(30)
    _, axis = tip_and_axis_pin(m, q)
    np.testing.assert_allclose(axis[0], [0.5, 0, np.sqrt(3) / 2], atol=1e-12)
    c, b = m.axis("C"), m.axis("B")
    assert np.linalg.norm(c.pivot) == pytest.approx(25.0, abs=0.05)
    assert np.linalg.norm(b.pivot) == pytest.approx(30.0, abs=0.5)
    n = np.cross(c.direction, b.direction)
    assert abs((c.pivot - b.pivot) @ n) / np.linalg.norm(n) == pytest.approx(2.0, abs=1e-9)


# -- machines found by name ------------------------------------------------------------------


def test_unknown_machine_name():
    with pytest.raises(MachineDefinitionError, match="no-such-machine: no such machine file"):
        load_machine("no-such-machine")


def test_machine_dirs_env_first(tmp_path, monkeypatch):
    (tmp_path / "dmu50.urdf").write_text(GOOD, encoding="utf-8")
    (tmp_path / "mine.urdf").write_text(GOOD, encoding="utf-8")
    monkeypatch.setenv("URDFPOST_MACHINES", str(tmp_path))
    known = list_machines()
    assert known["mine"] == tmp_path / "mine.urdf"
    assert known["dmu50"] == tmp_path / "dmu50.urdf"  # first folder wins
    m = load_machine("mine")
    assert m.name == "mine" and m.path == str(tmp_path / "mine.urdf")


# -- bad files -------------------------------------------------------------------------------

GOOD = simple_urdf(
    table=[
        J("X", "prismatic", "1 0 0"),
        J("B", "revolute", "0 1 0", xyz="0 0 0.2", lower=-2, upper=2),
        J("C", "continuous", "0 0 1", xyz="0.02 0.01 0.1"),
    ],
    head=[J("Y", "prismatic", "0 1 0"), J("Z", "prismatic", "0 0 1")],
    tool_xyz="0 0 0.5",
    work_xyz="0.01 0.02 0.05",
)


def joint_line(text: str, name: str, nth: int = 0) -> int:
    """1-based line of the ``nth`` joint named ``name``."""
    lines = [i + 1 for i, ln in enumerate(text.splitlines()) if f'<joint name="{name}"' in ln]
    return lines[nth]


def edit_joint(text: str, name: str, old: str, new: str) -> str:
    """Replace ``old`` by ``new`` inside the (one-line) joint ``name``."""
    out = []
    for ln in text.splitlines(keepends=True):
        if f'<joint name="{name}"' in ln:
            assert old in ln, (old, ln)
            ln = ln.replace(old, new)
        out.append(ln)
    return "".join(out)


def with_settings(xml: str) -> str:
    return GOOD.replace("</robot>", xml + "\n</robot>")


THREE_ROTARY = simple_urdf(
    table=[
        J("X", "prismatic", "1 0 0"),
        J("B", "revolute", "0 1 0", xyz="0 0 0.2", lower=-2, upper=2),
        J("C", "continuous", "0 0 1", xyz="0.02 0.01 0.1"),
    ],
    head=[
        J("Y", "prismatic", "0 1 0"),
        J("Z", "prismatic", "0 0 1"),
        J("A", "revolute", "1 0 0", xyz="0 0 0.3"),
    ],
)

# id, text, fragments the message must contain, joint whose line it must give (name, nth)
BAD = [
    ("not-xml", "this is not a URDF at all\n", ["not a URDF", "broken XML"], None),
    ("broken-xml", GOOD[: len(GOOD) // 2], ["not a URDF", "broken XML"], None),
    (
        "root-not-robot",
        GOOD.replace("<robot", "<sdf").replace("</robot>", "</sdf>"),
        ["expected root element <robot>", "got <sdf>"],
        None,
    ),
    ("no-workpiece", GOOD.replace('"workpiece"', '"part"'), ["no link named 'workpiece'"], None),
    ("no-tool", GOOD.replace('"tool"', '"spindle_nose"'), ["no link named 'tool'"], None),
    (
        "two-prismatic",
        edit_joint(GOOD, "Y", 'type="prismatic"', 'type="fixed"'),
        [
            "exactly 3 prismatic",
            "it has 2 prismatic and 2 rotary",
            "X (prismatic)",
            "C (continuous)",
        ],
        None,
    ),
    (
        "three-rotary",
        THREE_ROTARY,
        ["exactly 3 prismatic", "it has 3 prismatic and 3 rotary", "A (revolute)"],
        None,
    ),
    (
        "floating-on-chain",
        edit_joint(GOOD, "workpiece_mount", 'type="fixed"', 'type="floating"'),
        ["joint 'workpiece_mount' is floating"],
        ("workpiece_mount", 0),
    ),
    (
        "planar-on-chain",
        edit_joint(GOOD, "X", 'type="prismatic"', 'type="planar"'),
        ["joint 'X' is planar"],
        ("X", 0),
    ),
    (
        "unknown-type",
        edit_joint(GOOD, "tool_mount", 'type="fixed"', 'type="screw"'),
        ["joint 'tool_mount' has unknown type 'screw'"],
        ("tool_mount", 0),
    ),
    (
        # a duplicate NC address is necessarily a duplicate joint name
        "two-joints-named-X",
        edit_joint(GOOD, "Y", '<joint name="Y"', '<joint name="X"'),
        ["joint 'X' defined twice"],
        ("X", 1),
    ),
    (
        "lowercase-x",
        edit_joint(GOOD, "X", '<joint name="X"', '<joint name="x"'),
        ["joint 'x'", "must be named with its NC address"],
        ("x", 0),
    ),
    (
        "rotary-named-Q",
        edit_joint(GOOD, "C", '<joint name="C"', '<joint name="Q"'),
        ["joint 'Q'", "must be named with its NC address"],
        ("Q", 0),
    ),
    (
        "prismatic-named-A",
        edit_joint(GOOD, "X", '<joint name="X"', '<joint name="A"'),
        ["joint 'A' is prismatic", "linear axes are named X, Y or Z"],
        ("A", 0),
    ),
    (
        "zero-axis",
        edit_joint(GOOD, "X", 'axis xyz="1 0 0"', 'axis xyz="0 0 0"'),
        ["joint 'X'", "zero axis vector"],
        ("X", 0),
    ),
    (
        "axis-two-numbers",
        edit_joint(GOOD, "B", 'axis xyz="0 1 0"', 'axis xyz="0 1"'),
        ["joint 'B'", "expected 3 numbers"],
        ("B", 0),
    ),
    (
        "lower-above-upper",
        edit_joint(GOOD, "X", 'lower="-1.0" upper="1.0"', 'lower="0.5" upper="-0.5"'),
        ["joint 'X'", "lower limit 0.5 is above upper limit -0.5"],
        ("X", 0),
    ),
    (
        "no-travel",
        edit_joint(GOOD, "B", 'lower="-2" upper="2"', 'lower="0" upper="0"'),
        ["joint 'B'", "no travel"],
        ("B", 0),
    ),
    (
        "limit-not-a-number",
        edit_joint(GOOD, "Z", 'lower="-1.0"', 'lower="far"'),
        ["<limit> lower='far'", "expected a number"],
        ("Z", 0),
    ),
    (
        "negative-velocity",
        edit_joint(GOOD, "Y", 'velocity="1"', 'velocity="-1"'),
        ["joint 'Y'", "velocity limit -1.0 must be positive"],
        ("Y", 0),
    ),
    (
        "parallel-rotary",
        edit_joint(GOOD, "C", 'axis xyz="0 0 1"', 'axis xyz="0 -1 0"'),
        ["rotary joints 'C' and 'B' are parallel"],
        None,
    ),
    (
        "last-rotary-along-tool",
        edit_joint(
            edit_joint(GOOD, "C", 'axis xyz="0 0 1"', 'axis xyz="1 0 0"'),
            "B",
            'axis xyz="0 1 0"',
            'axis xyz="0 0 1"',
        ),
        ["rotary joint 'B' is parallel to the tool axis"],
        None,
    ),
    (
        "coplanar-linear",
        edit_joint(GOOD, "Z", 'axis xyz="0 0 1"', 'axis xyz="1 1 0"'),
        ["linear axes X, Y, Z do not span space"],
        None,
    ),
    (
        "not-connected",
        edit_joint(GOOD, "tool_mount", '<parent link="z_link"/>', '<parent link="nowhere"/>'),
        ["'workpiece' and 'tool' are not connected"],
        None,
    ),
    (
        "loop",
        GOOD.replace(
            "</robot>",
            '<joint name="loop" type="fixed"><parent link="workpiece"/>'
            '<child link="base"/></joint>\n</robot>',
        ),
        ["joint 'loop' closes a loop"],
        None,
    ),
    (
        "bad-controller",
        with_settings('<urdfpost controller="okuma"/>'),
        ["<urdfpost controller='okuma'>", "heidenhain"],
        None,
    ),
    ("bad-units", with_settings('<urdfpost units="cm"/>'), ["units='cm'", "mm or inch"], None),
    (
        "tool-length-not-a-number",
        with_settings('<urdfpost tool_length="long"/>'),
        ["tool_length='long'", "expected a number"],
        None,
    ),
    (
        "prefer-unknown-axis",
        with_settings('<urdfpost><prefer axis="Q" sign="+"/></urdfpost>'),
        ["<prefer axis='Q' sign='+'>", "expected a rotary axis"],
        None,
    ),
    (
        "prefer-bad-sign",
        with_settings('<urdfpost><prefer axis="B" sign="up"/></urdfpost>'),
        ["<prefer axis='B' sign='up'>"],
        None,
    ),
    (
        "home-unknown-axis",
        with_settings('<urdfpost><home X="0" Q="1"/></urdfpost>'),
        ["<home Q=...>: no such axis"],
        None,
    ),
    (
        "home-not-a-number",
        with_settings('<urdfpost><home X="far"/></urdfpost>'),
        ["X='far'", "expected a number"],
        None,
    ),
]

# regressions: bugs this suite found (were accepted silently)
BAD += [
    (
        # was: parse_settings checked <prefer axis> against every chain joint
        "prefer-linear-axis",
        with_settings('<urdfpost><prefer axis="X" sign="+"/></urdfpost>'),
        ["<prefer axis='X' sign='+'>", "expected a rotary axis of the chain (C B)"],
        None,
    ),
    (
        # was: home outside the travel accepted although docs/machines.md forbids it
        "home-outside-travel",
        with_settings('<urdfpost><home X="5"/></urdfpost>'),
        ["<home X=5>", "outside the travel of joint 'X'"],
        None,
    ),
    (
        "home-rotary-outside-travel",
        with_settings('<urdfpost><home B="3"/></urdfpost>'),
        ["<home B=3>", "outside the travel of joint 'B'"],
        None,
    ),
]


@pytest.mark.parametrize(
    ("case", "text", "fragments", "at"), [pytest.param(*b, id=b[0]) for b in BAD]
)
def test_bad_file(tmp_path, case, text, fragments, at):
    path = tmp_path / f"{case}.urdf"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(MachineDefinitionError, match=re.escape(str(path))) as info:
        load_machine(path)
    msg = str(info.value)
    assert msg.startswith(str(path)), msg
    for fragment in fragments:
        assert fragment in msg, f"{fragment!r} not in {msg!r}"
    if at is not None:
        assert msg.startswith(f"{path}:{joint_line(text, *at)}:"), msg


def line_of(text: str, needle: str, nth: int = 0) -> int:
    """1-based line of the ``nth`` line containing ``needle``."""
    return [i for i, ln in enumerate(text.splitlines(), 1) if needle in ln][nth]


DOOR = (  # an off-chain moving joint, edited by the cases below
    '<link name="door"/><joint name="door_slide" type="prismatic"><parent link="base"/>'
    '<child link="door"/><axis xyz="1 0 0"/>'
    '<limit lower="0" upper="0.5" effort="1" velocity="1"/></joint>\n</robot>'
)
WITH_DOOR = GOOD.replace("</robot>", DOOR)
ENTITY_HEAD = '<?xml version="1.0"?>\n<!DOCTYPE robot [\n  <!ENTITY {decl}>\n]>\n'

# Issue 22: faults that reached Pinocchio's C++ parser, which printed to stderr and failed with
# a message without line (or was not caught at all). Each must be found in urdfpost's own pass:
# id, text, fragments, line of the message (a needle and which line holding it)
BEFORE_PINOCCHIO = [
    (
        "axis-nan",
        edit_joint(GOOD, "B", 'axis xyz="0 1 0"', 'axis xyz="nan 0 1"'),
        ["joint 'B': <axis> xyz='nan 0 1': expected 3 finite numbers"],
        ('<joint name="B"', 0),
    ),
    (
        "axis-inf",
        edit_joint(GOOD, "X", 'axis xyz="1 0 0"', 'axis xyz="-inf 0 0"'),
        ["joint 'X': <axis> xyz='-inf 0 0': expected 3 finite numbers"],
        ('<joint name="X"', 0),
    ),
    (
        "axis-comma",
        edit_joint(GOOD, "B", 'axis xyz="0 1 0"', 'axis xyz="0,1,0"'),
        ["joint 'B': <axis> xyz='0,1,0': expected 3 numbers"],
        ('<joint name="B"', 0),
    ),
    (
        "lower-nan",
        edit_joint(GOOD, "B", 'lower="-2"', 'lower="nan"'),
        ["joint 'B': <limit> lower='nan': expected a finite number"],
        ('<joint name="B"', 0),
    ),
    (
        "upper-nan",
        edit_joint(GOOD, "B", 'upper="2"', 'upper="NaN"'),
        ["joint 'B': <limit> upper='NaN': expected a finite number"],
        ('<joint name="B"', 0),
    ),
    (
        "upper-overflows",
        edit_joint(GOOD, "X", 'upper="1.0"', 'upper="1e999"'),
        ["joint 'X': <limit> upper='1e999': expected a finite number"],
        ('<joint name="X"', 0),
    ),
    (
        # Python's float reads "1_0" as 10; URDF readers do not
        "lower-python-only-number",
        edit_joint(GOOD, "Z", 'lower="-1.0"', 'lower="-1_0"'),
        ["joint 'Z': <limit> lower='-1_0': expected a number"],
        ('<joint name="Z"', 0),
    ),
    (
        "velocity-nan",
        edit_joint(GOOD, "B", 'velocity="1"', 'velocity="nan"'),
        ["joint 'B': <limit> velocity='nan': expected a finite number"],
        ('<joint name="B"', 0),
    ),
    (
        "velocity-inf",
        edit_joint(GOOD, "Y", 'velocity="1"', 'velocity="inf"'),
        ["joint 'Y': <limit> velocity='inf': expected a finite number"],
        ('<joint name="Y"', 0),
    ),
    (
        "effort-nan",
        edit_joint(GOOD, "B", 'effort="1"', 'effort="nan"'),
        ["joint 'B': <limit> effort='nan': expected a finite number"],
        ('<joint name="B"', 0),
    ),
    (
        "effort-negative",
        edit_joint(GOOD, "B", 'effort="1"', 'effort="-1"'),
        ["joint 'B': effort limit -1.0 must not be negative"],
        ('<joint name="B"', 0),
    ),
    (
        "limit-without-effort",
        edit_joint(GOOD, "Y", ' effort="1"', ""),
        ["joint 'Y': <limit> needs effort and velocity"],
        ('<joint name="Y"', 0),
    ),
    (
        "origin-xyz-nan",
        edit_joint(GOOD, "B", 'xyz="0 0 0.2"', 'xyz="nan 0 0.2"'),
        ["joint 'B': <origin> xyz='nan 0 0.2': expected 3 finite numbers"],
        ('<joint name="B"', 0),
    ),
    (
        "origin-rpy-nan",
        edit_joint(GOOD, "C", 'rpy="0 0 0"', 'rpy="0 nan 0"'),
        ["joint 'C': <origin> rpy='0 nan 0': expected 3 finite numbers"],
        ('<joint name="C"', 0),
    ),
    (
        "origin-two-numbers",
        edit_joint(GOOD, "workpiece_mount", 'xyz="0.01 0.02 0.05"', 'xyz="0.01 0.02"'),
        ["joint 'workpiece_mount': <origin> xyz='0.01 0.02': expected 3 numbers"],
        ('<joint name="workpiece_mount"', 0),
    ),
    (
        "dynamics-nan",
        edit_joint(GOOD, "C", "</joint>", '<dynamics damping="nan"/></joint>'),
        ["joint 'C': <dynamics> damping='nan': expected a finite number"],
        ('<joint name="C"', 0),
    ),
    (
        "mimic-without-joint",
        edit_joint(GOOD, "C", "</joint>", '<mimic multiplier="2"/></joint>'),
        ["joint 'C': <mimic> needs joint"],
        ('<joint name="C"', 0),
    ),
    (
        "off-chain-joint-nan",
        edit_joint(WITH_DOOR, "door_slide", 'upper="0.5"', 'upper="nan"'),
        ["joint 'door_slide': <limit> upper='nan': expected a finite number"],
        ('<joint name="door_slide"', 0),
    ),
    (
        "off-chain-unknown-type",
        edit_joint(WITH_DOOR, "door_slide", 'type="prismatic"', 'type="telescopic"'),
        ["joint 'door_slide' has unknown type 'telescopic'"],
        ('<joint name="door_slide"', 0),
    ),
    (
        "off-chain-revolute-without-limit",
        GOOD.replace(
            "</robot>",
            '<link name="door"/><joint name="hinge" type="revolute"><parent link="base"/>'
            '<child link="door"/><axis xyz="0 0 1"/></joint>\n</robot>',
        ),
        ["joint 'hinge' is revolute: it needs <limit"],
        ('<joint name="hinge"', 0),
    ),
    (
        "off-chain-zero-axis",
        edit_joint(WITH_DOOR, "door_slide", 'axis xyz="1 0 0"', 'axis xyz="0 0 0"'),
        ["joint 'door_slide': zero axis vector"],
        ('<joint name="door_slide"', 0),
    ),
    (
        "off-chain-parent-not-defined",
        edit_joint(WITH_DOOR, "door_slide", '<parent link="base"/>', '<parent link="frame"/>'),
        ["joint 'door_slide': parent link 'frame' is not defined"],
        ('<joint name="door_slide"', 0),
    ),
    (
        "duplicate-link",
        GOOD.replace('<link name="tool"/>', '<link name="tool"/>\n<link name="b_link"/>'),
        ["link 'b_link' defined twice (first at line 4)"],
        ('<link name="b_link"', 1),
    ),
    (
        "duplicate-fixed-joint",
        edit_joint(GOOD, "tool_mount", 'name="tool_mount"', 'name="workpiece_mount"'),
        ["joint 'workpiece_mount' defined twice (first at line 13"],
        ('<joint name="workpiece_mount"', 1),
    ),
    (
        "link-with-two-parents",
        GOOD.replace(
            "</robot>",
            '<joint name="second_mount" type="fixed"><parent link="base"/>'
            '<child link="tool"/></joint>\n</robot>',
        ),
        ["joint 'second_mount': link 'tool' is already the child of joint 'tool_mount'"],
        ('<joint name="second_mount"', 0),
    ),
    (
        "second-root-link",
        GOOD.replace('<link name="tool"/>', '<link name="tool"/>\n<link name="cover"/>'),
        ["link 'cover' is attached by no joint", "one root link ('base' here)"],
        ('<link name="cover"', 0),
    ),
    (
        "robot-without-name",
        GOOD.replace('<robot name="simple">', "<robot>"),
        ["<robot> without name"],
        ("<robot>", 0),
    ),
    (
        "robot-unknown-version",
        GOOD.replace('<robot name="simple">', '<robot name="simple" version="2.0">'),
        ["<robot version='2.0'>: expected one of 1.0 1.1 1.2"],
        ("<robot", 0),
    ),
    (
        "internal-entity",
        ENTITY_HEAD.format(decl='ax "0 1 0"')
        + edit_joint(GOOD, "B", 'axis xyz="0 1 0"', 'axis xyz="&ax;"'),
        ["<!ENTITY ax>: entity declarations are not allowed"],
        ("<!ENTITY", 0),
    ),
    (
        # was accepted, and the entity was read from the disc
        "external-entity",
        ENTITY_HEAD.format(decl='desc SYSTEM "file:///etc/hostname"')
        + with_settings("<urdfpost><description>&desc;</description></urdfpost>"),
        ["<!ENTITY desc>: entity declarations are not allowed"],
        ("<!ENTITY", 0),
    ),
    (
        "entity-expansion-bomb",
        ENTITY_HEAD.format(decl='a "aaaaaaaaaa"><!ENTITY b "&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;"')
        + GOOD.replace('<robot name="simple">', '<robot name="&b;">'),
        ["<!ENTITY a>: entity declarations are not allowed"],
        ("<!ENTITY", 0),
    ),
]


@pytest.mark.parametrize(
    ("case", "text", "fragments", "at"), [pytest.param(*b, id=b[0]) for b in BEFORE_PINOCCHIO]
)
def test_bad_file_caught_before_pinocchio(tmp_path, capfd, case, text, fragments, at):
    path = tmp_path / f"{case}.urdf"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(MachineDefinitionError) as info:
        load_machine(path)
    msg = str(info.value)
    assert msg.startswith(f"{path}:{line_of(text, *at)}: "), msg
    for fragment in fragments:
        assert fragment in msg, f"{fragment!r} not in {msg!r}"
    assert "Pinocchio" not in msg
    assert capfd.readouterr().err == ""  # Pinocchio's parser printed nothing


@pytest.mark.parametrize(
    ("mimic", "other"), [("C", "B"), ("B", "C"), ("X", "Y")], ids=["C-B", "B-C", "X-Y"]
)
def test_mimic_joint_on_the_chain_is_refused_at_its_line(tmp_path, capfd, mimic, other):
    """Issue 22: C mimicking B was read as an independent axis (the program had B-20 C0). The
    kinematics has independent axes only: refused at the <mimic> line, naming both joints."""
    text = edit_joint(
        GOOD, mimic, "</joint>", f'\n  <mimic joint="{other}" multiplier="1" offset="0"/></joint>'
    )
    path = tmp_path / "mimic.urdf"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(MachineDefinitionError) as info:
        load_machine(path)
    msg = str(info.value)
    assert msg.startswith(f"{path}:{line_of(text, '<mimic')}: "), msg
    assert f"joint {mimic!r} mimics joint {other!r} (<mimic>)" in msg
    assert "must move on its own" in msg
    assert capfd.readouterr().err == ""


def test_mimic_joint_off_the_chain_is_no_machine_axis(tmp_path):
    """A mimic joint off the chain (a door following another) takes no part: accepted."""
    text = WITH_DOOR.replace(
        "</robot>",
        '<link name="door2"/><joint name="door_follow" type="prismatic"><parent link="base"/>'
        '<child link="door2"/><axis xyz="1 0 0"/>'
        '<limit lower="0" upper="0.5" effort="1" velocity="1"/>'
        '<mimic joint="door_slide" multiplier="-1"/></joint>\n</robot>',
    )
    m = machine_from_urdf(text)
    assert m.axis_names == machine_from_urdf(GOOD).axis_names


# Issue 22: <urdfpost> settings that were accepted (and blamed on the CL file later) or said
# the wrong thing: id, settings, fragment
BAD_SETTINGS = [
    ("tool-length-nan", '<urdfpost tool_length="nan"/>', "tool_length='nan'"),
    ("tool-length-inf", '<urdfpost tool_length="inf"/>', "tool_length='inf'"),
    ("tool-length-negative", '<urdfpost tool_length="-0.1"/>', "tool_length='-0.1'"),
]


@pytest.mark.parametrize(
    ("case", "xml", "fragment"), BAD_SETTINGS, ids=[b[0] for b in BAD_SETTINGS]
)
def test_bad_tool_length(tmp_path, case, xml, fragment):
    path = tmp_path / f"{case}.urdf"
    text = with_settings(xml)
    path.write_text(text, encoding="utf-8")
    with pytest.raises(MachineDefinitionError) as info:
        load_machine(path)
    assert str(info.value) == (
        f"{path}:{line_of(text, '<urdfpost')}: <urdfpost> {fragment}: expected a finite length "
        ">= 0 m"
    )


@pytest.mark.parametrize(
    ("axis", "value"), [("X", "nan"), ("B", "nan"), ("C", "nan"), ("C", "inf"), ("C", "-inf")]
)
def test_home_not_finite(tmp_path, axis, value):
    """Was: NaN on a limited axis said 'outside the travel', and a continuous axis took any."""
    path = tmp_path / "home.urdf"
    text = with_settings(f'<urdfpost>\n<home Y="0" {axis}="{value}"/>\n</urdfpost>')
    path.write_text(text, encoding="utf-8")
    with pytest.raises(MachineDefinitionError) as info:
        load_machine(path)
    assert str(info.value) == (
        f"{path}:{line_of(text, '<home')}: <home> {axis}='{value}': expected a finite number"
    )


def test_zero_tool_length_and_plain_doctype_are_fine(tmp_path):
    path = tmp_path / "fine.urdf"
    text = '<?xml version="1.0"?>\n<!DOCTYPE robot>\n' + with_settings(
        '<urdfpost tool_length="0"><home C="-6.5"/></urdfpost>'
    )
    path.write_text(text, encoding="utf-8")
    m = load_machine(path)
    assert m.settings.tool_length == 0.0
    assert m.settings.home == {"C": -6.5}


@pytest.mark.parametrize(
    ("collision", "message"),
    [
        (
            '<geometry><box size="nan 0.1 0.1"/></geometry>',
            "<box size>: 'nan 0.1 0.1': expected 3 finite numbers",
        ),
        (
            '<origin xyz="0 inf 0"/><geometry><box size="0.1 0.1 0.1"/></geometry>',
            "<origin xyz>: '0 inf 0': expected 3 finite numbers",
        ),
        (
            '<geometry><sphere radius="nan"/></geometry>',
            "<sphere radius>: 'nan': expected a finite number",
        ),
        (
            '<geometry><cylinder radius="-0.1" length="0.2"/></geometry>',
            "<cylinder radius>: '-0.1': expected sizes >= 0",
        ),
    ],
    ids=["box-size-nan", "origin-inf", "sphere-radius-nan", "cylinder-radius-negative"],
)
def test_bad_collision_shape_is_urdfposts_to_say(tmp_path, capfd, collision, message):
    """Pinocchio is given no shapes: a bad one is said (lazily) by urdfpost alone."""
    text = GOOD.replace(
        '<link name="b_link"/>', f'<link name="b_link">\n<collision>{collision}</collision></link>'
    )
    path = tmp_path / "shape.urdf"
    path.write_text(text, encoding="utf-8")
    m = load_machine(path)  # still loads: collision checks say it when asked for
    with pytest.raises(GeometryError) as info:
        m.shapes  # noqa: B018
    assert (
        str(info.value)
        == f"{path}:{line_of(text, '<collision>')}: link 'b_link' <collision>: {message}"
    )
    assert capfd.readouterr().err == ""


def test_parts_urdfpost_does_not_use_do_not_reach_pinocchio(capfd):
    """Sloppy visuals, materials and inertials (which Pinocchio's parser complains about on
    stderr) do not stop a machine or make noise: urdfpost gives Pinocchio links and joints."""
    text = GOOD.replace(
        '<link name="b_link"/>',
        '<material name="grey"/><material name="grey"/>'
        '<link name="b_link"><visual><geometry><capsule/></geometry><material name="none"/>'
        '</visual><inertial><mass value="nan"/></inertial></link>',
    )
    m = machine_from_urdf(text)
    assert m.axis_names == machine_from_urdf(GOOD).axis_names
    assert capfd.readouterr().err == ""


def test_good_base_file_loads(tmp_path):
    """The base the bad cases are edited from is itself fine (so each edit is the fault)."""
    path = tmp_path / "good.urdf"
    path.write_text(GOOD, encoding="utf-8")
    m = load_machine(path)
    assert m.family == "table-table"
    assert m.settings == Settings()
    # no units setting: None, so that a post's program takes the CL data's units
    assert m.settings.controller == "heidenhain" and m.settings.units is None
    assert m.settings.tool_length == 0.0 and m.settings.prefer is None
    assert m.settings.home == {} and np.all(m.home == 0.0)


def test_settings_parsed(tmp_path):
    path = tmp_path / "set.urdf"
    path.write_text(
        with_settings(
            '<urdfpost controller="siemens" units="inch" tool_length="0.125">'
            "<description>  A  test\n machine </description>"
            '<prefer axis="C" sign="-"/><home X="0.1" Z="-0.2" B="0.5"/></urdfpost>'
        ),
        encoding="utf-8",
    )
    s = load_machine(path).settings
    assert s.controller == "siemens"
    assert s.units == "inch"
    assert s.tool_length == pytest.approx(125.0)
    assert s.prefer == ("C", -1)
    assert s.home == pytest.approx({"X": 100.0, "Z": -200.0, "B": 0.5})
    assert s.description == "A test machine"
    m = load_machine(path)
    np.testing.assert_allclose(m.home, [100.0, 0.0, -200.0, 0.5, 0.0])


def test_settings_say_where_they_are_and_keep_the_strategy_as_written(tmp_path):
    """The strategy name is checked by the post (against its strategies), not at load: the
    settings keep it with the file and line of the <urdfpost> element for that message."""
    path = tmp_path / "strategy.urdf"
    text = with_settings('<urdfpost strategy="no-such-strategy"/>')
    path.write_text(text, encoding="utf-8")
    s = load_machine(path).settings
    assert s.strategy == "no-such-strategy"
    line = next(i for i, ln in enumerate(text.splitlines(), 1) if "<urdfpost" in ln)
    assert s.where == f"{path}:{line}"


@pytest.mark.parametrize("controller", sorted(DIALECTS))
def test_every_dialect_is_a_machine_controller(tmp_path, controller):
    path = tmp_path / "controller.urdf"
    path.write_text(with_settings(f'<urdfpost controller="{controller}"/>'), encoding="utf-8")
    assert load_machine(path).settings.controller == controller


def test_off_chain_joints_ignored(tmp_path):
    """Moving joints off the chain (doors, tool changer) are allowed and take no part."""
    extra = (
        '<link name="door"/><link name="arm"/>'
        '<joint name="door_slide" type="prismatic"><parent link="base"/><child link="door"/>'
        '<axis xyz="1 0 0"/><limit lower="0" upper="0.5" effort="1" velocity="1"/></joint>'
        '<joint name="changer" type="continuous"><parent link="door"/><child link="arm"/>'
        '<origin xyz="0.3 0.2 0.1"/><axis xyz="0 0 1"/></joint>'
    )
    text = simple_urdf(
        table=[
            J("X", "prismatic", "1 0 0"),
            J("B", "revolute", "0 1 0", xyz="0 0 0.2", lower=-2, upper=2),
            J("C", "continuous", "0 0 1", xyz="0.02 0.01 0.1"),
        ],
        head=[J("Y", "prismatic", "0 1 0"), J("Z", "prismatic", "0 0 1")],
        tool_xyz="0 0 0.5",
        work_xyz="0.01 0.02 0.05",
        extra=extra,
    )
    m = machine_from_urdf(text)
    plain = machine_from_urdf(GOOD)
    assert m.axis_names == plain.axis_names
    q = np.random.default_rng(3).uniform(-1, 1, (20, 5)) * [300, 300, 300, 2, 3]
    tip, axis = tip_and_axis_pin(m, q, 20.0)
    tip0, axis0 = tip_and_axis_pin(plain, q, 20.0)
    np.testing.assert_allclose(tip, tip0, atol=1e-9)
    np.testing.assert_allclose(axis, axis0, atol=1e-12)
    check_round_trip(m, q, 20.0)


# -- a URDF written by someone else ----------------------------------------------------------

# A horizontal 5-axis machine (HMC with a swivel head), written in another style: CamelCase link
# names, joints declared child-first and out of chain order, frames rotated with rpy so the axis
# vectors are not the machine directions, a non-unit axis vector, meshes, materials, gazebo and
# transmission elements, comments. The spindle is horizontal: the tool frame is rotated so its
# +Z points from the tip back into the spindle, along world +Y.
HORIZONTAL = """<?xml version="1.0" encoding="utf-8"?>
<!-- Exported by hand from the OEM kinematics sheet. HMC-500 with swivel head. -->
<robot name="HMC500_swivel">
  <!-- ============ spindle side ============ -->
  <joint name="GaugeLine" type="fixed">
    <origin rpy="0 -1.5707963267948966 0" xyz="0 0 0"/>
    <parent link="SpindleNose"/>
    <child link="tool"/>
  </joint>
  <joint name="A" type="revolute">
    <origin rpy="0 0 0" xyz="0.0 0.0 0.0"/>
    <parent link="Headstock"/>
    <child link="SwivelHead"/>
    <axis xyz="0 2 0"/> <!-- world +X (the headstock frame is yawed -90 deg); not normalised -->
    <limit effort="500" lower="-0.5" upper="1.9" velocity="1.5"/>
    <dynamics damping="0.1" friction="0.0"/>
  </joint>
  <joint name="PivotArm" type="fixed">
    <origin rpy="0 0 0" xyz="0.25 0.002 0"/>  <!-- nose 250 mm from the A axis, 2 mm off -->
    <parent link="SwivelHead"/>
    <child link="SpindleNose"/>
  </joint>
  <joint name="Y" type="prismatic">
    <origin rpy="0 0 0" xyz="0 0 0.8"/>
    <parent link="Column"/>
    <child link="Headstock"/>
    <axis xyz="0 0 1"/>
    <limit effort="8000" lower="0.0" upper="0.7" velocity="0.6"/>
  </joint>
  <joint name="Z" type="prismatic">
    <origin rpy="0 0 0" xyz="0 0 0"/>
    <parent link="ColumnFoot"/>
    <child link="Column"/>
    <axis xyz="-1 0 0"/>  <!-- column frame yawed -90 deg: local -x is world +y -->
    <limit effort="8000" lower="-0.5" upper="0.2" velocity="0.6"/>
  </joint>
  <joint name="ColumnOnBed" type="fixed">
    <origin rpy="0 0 -1.5707963267948966" xyz="0 1.2 0"/>
    <parent link="Bed"/>
    <child link="ColumnFoot"/>
  </joint>
  <!-- ============ table side ============ -->
  <joint name="PalletClamp" type="fixed">
    <origin rpy="-1.5707963267948966 0 0.4" xyz="0.03 0.12 -0.02"/>
    <parent link="RotaryTable"/>
    <child link="workpiece"/>
  </joint>
  <joint name="B" type="continuous">
    <origin rpy="1.5707963267948966 0 0" xyz="0 0 0.1"/>
    <parent link="Saddle"/>
    <child link="RotaryTable"/>
    <axis xyz="0 -1 0"/>  <!-- local y is world z here: table turns about world -Z -->
    <limit effort="1000" velocity="3.0"/>
  </joint>
  <joint name="X" type="prismatic">
    <origin rpy="0 0 3.141592653589793" xyz="0 0 0.5"/>
    <parent link="Bed"/>
    <child link="Saddle"/>
    <axis xyz="1 0 0"/>  <!-- saddle frame yawed 180 deg: the table moves to world -X -->
    <limit effort="8000" lower="-0.4" upper="0.4" velocity="0.8"/>
  </joint>
  <material name="Grey"><color rgba="0.5 0.5 0.5 1"/></material>
  <link name="tool"/>
  <link name="SpindleNose">
    <visual><geometry><cylinder length="0.2" radius="0.06"/></geometry>
      <material name="Grey"/></visual>
  </link>
  <link name="SwivelHead">
    <visual><geometry>
      <mesh filename="package://hmc500/meshes/head.stl" scale="0.001 0.001 0.001"/>
    </geometry></visual>
    <inertial><mass value="300"/>
      <inertia ixx="10" ixy="0" ixz="0" iyy="10" iyz="0" izz="10"/></inertial>
  </link>
  <link name="Headstock"/>
  <link name="Column"/>
  <link name="ColumnFoot"/>
  <link name="Bed"><collision><geometry><box size="2 2 0.5"/></geometry></collision></link>
  <link name="Saddle"/>
  <link name="RotaryTable">
    <visual><geometry><cylinder length="0.05" radius="0.25"/></geometry></visual></link>
  <link name="workpiece"/>
  <transmission name="trans_X"><type>transmission_interface/SimpleTransmission</type>
    <joint name="X"><hardwareInterface>EffortJointInterface</hardwareInterface></joint>
    <actuator name="motor_X"><mechanicalReduction>1</mechanicalReduction></actuator>
  </transmission>
  <gazebo reference="Bed"><material>Gazebo/Grey</material></gazebo>
</robot>
"""


def test_urdf_written_by_someone_else(tmp_path):
    path = tmp_path / "HMC500_swivel.urdf"
    path.write_text(HORIZONTAL, encoding="utf-8")
    m = load_machine(path)
    assert m.family == "head-table"
    assert m.axis_names == ("X", "Y", "Z", "A", "B")
    assert [a.name for a in m.rotary] == ["B", "A"]
    assert {a.name: a.side for a in m.axes} == {
        "X": "table",
        "B": "table",
        "Y": "head",
        "Z": "head",
        "A": "head",
    }
    # in the world (bed) frame: spindle horizontal along +Y, B vertical, A along X
    model = m.model
    data = model.createData()
    pin.framesForwardKinematics(model, data, pin.neutral(model))
    r_tool = data.oMf[model.getFrameId("tool")].rotation
    r_work = data.oMf[model.getFrameId("workpiece")].rotation
    np.testing.assert_allclose(r_tool[:, 2], [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(r_work @ m.axis("B").direction, [0, 0, 1], atol=1e-12)
    np.testing.assert_allclose(r_work @ m.axis("A").direction, [1, 0, 0], atol=1e-12)
    # NC directions: +X moves the tool to +X (the table moves), +Z away from the part along the
    # spindle, +Y up
    np.testing.assert_allclose(r_work @ m.axis("X").direction, [1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(r_work @ m.axis("Z").direction, [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(r_work @ m.axis("Y").direction, [0, 0, 1], atol=1e-12)
    # horizontal spindle: the tool axis is normal to the vertical B axis, frame-independently
    assert m.home_tool_axis @ m.axis("B").direction == pytest.approx(0.0, abs=1e-12)
    # A = +90 deg (right-handed about +X) turns the spindle to vertical, pointing down
    q = np.zeros(5)
    q[m.axis_names.index("A")] = np.pi / 2
    _, axis = tip_and_axis_pin(m, q)
    np.testing.assert_allclose(r_work @ axis[0], [0, 0, 1], atol=1e-12)
    # round trip inside the travel, with the file's own defaults
    assert m.settings == Settings()
    q = q_within_travel(m, np.random.default_rng(11), 400)
    for tool_length in (0.0, 180.0):
        check_round_trip(m, q, tool_length)
    # B normal to A normal to the tool: every tool direction is reachable
    dirs = np.random.default_rng(2).normal(size=(200, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    sols = solve_rotary(m, dirs)
    assert np.all(sols.valid[:, 0])
    q = assemble(m, sols.angles[:, 0], np.zeros((200, 3)))
    _, axis_back = tip_and_axis_pin(m, q)
    assert axis_angle_error(axis_back, dirs).max() <= 1e-9


@pytest.mark.parametrize(
    "text",
    [*(p.read_text() for p in SHIPPED), HORIZONTAL],
    ids=[*(p.stem for p in SHIPPED), "horizontal"],
)
def test_pinocchio_model_same_as_from_whole_file(text):
    """The links and joints alone give Pinocchio the model the whole file gives (inertias
    apart): same joints, frames and placements."""
    m = machine_from_urdf(text)
    whole = pin.buildModelFromXML(text)
    model = m.model
    assert list(model.names) == list(whole.names)
    assert (model.nq, model.nv) == (whole.nq, whole.nv)
    assert [f.name for f in model.frames] == [f.name for f in whole.frames]
    assert [f.parentJoint for f in model.frames] == [f.parentJoint for f in whole.frames]
    for a, b in zip(model.frames, whole.frames, strict=True):
        np.testing.assert_array_equal(a.placement.homogeneous, b.placement.homogeneous)
    for a, b in zip(model.jointPlacements, whole.jointPlacements, strict=True):
        np.testing.assert_array_equal(a.homogeneous, b.homogeneous)
    for attr in ("lowerPositionLimit", "upperPositionLimit", "velocityLimit", "effortLimit"):
        np.testing.assert_array_equal(getattr(model, attr), getattr(whole, attr))
    assert [j.shortname() for j in model.joints] == [j.shortname() for j in whole.joints]
