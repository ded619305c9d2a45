"""Random valid machines as URDF text, for property-based tests.

:func:`machines` is a Hypothesis strategy drawing a machine of any arrangement the urdfpost
convention allows (table-table, head-head, head-table, 4-axis with the rotary axis on either
side) and writing it as URDF text, with the facts a test needs to know about it
(:class:`GenMachine`).

How a machine is drawn:

- the rotary axes get random unit directions (in the frame of the root link at home) with
  the angle between the two at least 10 degrees, often a "nice" 90, 60, 45 or 30 degrees
  (nutating heads and tables);
- the three prismatic axes get well-conditioned but not axis-aligned directions, and each is put
  on the table side (moves the workpiece) or the head side (moves the tool) at random;
- along each side the joints are in the order real machines use (table: rotaries nearest the
  workpiece, then slides; head: slides, then rotaries), with 0-2 fixed joints with random
  origins (xyz up to 0.3 m, any rpy) between any two moving joints, and a random origin on
  every moving joint, so that pivots and frames are arbitrary;
- each joint's ``<axis>`` is written in its own (rotated) joint frame, computed here with a small
  independent forward-kinematics of the home pose;
- the tool frame gets any orientation; machines whose last rotary axis is within 10 degrees of
  the home tool axis are rejected (``assume``);
- links and joints are written in shuffled order, sometimes with a ``world`` root above the
  machine, off-chain decoration links, and with the workpiece or tool itself as the common
  ancestor when one side has no moving joint.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from hypothesis import assume
from hypothesis import strategies as st

from urdfpost.machine import Machine, machine_from_urdf

FAMILIES = ("table-table", "head-head", "head-table", "4-axis-table", "4-axis-head")
MIN_AXIS_ANGLE_DEG = 10.0


@dataclass(frozen=True)
class GenMachine:
    """A generated machine and what the generator knows about it.

    Attributes
    ----------
    urdf : str
        The URDF text.
    family : str
        Expected ``Machine.family``.
    rotary : tuple of str
        Rotary NC addresses in chain order from the workpiece.
    sides : dict of str to str
        NC address -> "table" or "head".
    kinds : dict of str to str
        NC address -> joint type.
    limits : dict of str to (float, float)
        NC address -> (lower, upper) in URDF units (metres, radians); continuous joints absent.
    directions : dict of str to ndarray
        NC address -> unit axis direction in the root frame at home (sign as written).
    home_tool_axis : ndarray
        Tool +Z in the root frame at home.
    rotary_angle_deg : float
        Angle between the two rotary axes (nan on 4-axis machines).
    ancestor : str
        Name of the common ancestor link of workpiece and tool.
    """

    urdf: str
    family: str
    rotary: tuple[str, ...]
    sides: dict[str, str] = field(repr=False)
    kinds: dict[str, str] = field(repr=False)
    limits: dict[str, tuple[float, float]] = field(repr=False)
    directions: dict[str, np.ndarray] = field(repr=False)
    home_tool_axis: np.ndarray = field(repr=False)
    rotary_angle_deg: float = float("nan")
    ancestor: str = "base"
    prefer: tuple[str, int] | None = None


def build(gen: GenMachine) -> Machine:
    """Load a generated machine."""
    return machine_from_urdf(gen.urdf, source="<generated>", name="generated")


# -- small independent geometry --------------------------------------------------------------


def rpy_matrix(rpy: np.ndarray) -> np.ndarray:
    """URDF fixed-axis roll-pitch-yaw: Rz(yaw) Ry(pitch) Rx(roll)."""
    r, p, y = rpy
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return rz @ ry @ rx


def angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    """Angle between two directions, degrees, in [0, 180]."""
    c = float(np.dot(a, b) / (np.linalg.norm(a) * np.linalg.norm(b)))
    return float(np.degrees(np.arccos(np.clip(c, -1.0, 1.0))))


def line_angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    """Angle between two lines (directions up to sign), degrees, in [0, 90]."""
    d = angle_deg(a, b)
    return min(d, 180.0 - d)


def _fmt(values: np.ndarray | list[float] | tuple[float, ...]) -> str:
    return " ".join(repr(float(v)) for v in values)


# -- strategies ------------------------------------------------------------------------------

_unit_interval = st.floats(-1.0, 1.0, allow_nan=False, allow_infinity=False)
_angle = st.floats(-np.pi, np.pi, allow_nan=False, allow_infinity=False)
_offset = st.floats(-0.3, 0.3, allow_nan=False, allow_infinity=False)


@st.composite
def unit_vectors(draw: st.DrawFn) -> np.ndarray:
    """Unit 3-vectors (not uniformly distributed; Hypothesis favours simple ones)."""
    v = np.array([draw(_unit_interval) for _ in range(3)])
    n = float(np.linalg.norm(v))
    assume(n > 0.2)
    return v / n


@st.composite
def rotations(draw: st.DrawFn) -> np.ndarray:
    """Rotation matrices from random rpy."""
    return rpy_matrix(np.array([draw(_angle) for _ in range(3)]))


@st.composite
def origins(draw: st.DrawFn) -> tuple[np.ndarray, np.ndarray]:
    """Random joint origins: xyz up to +/-0.3 m, rpy any (sometimes zero)."""
    xyz = np.array([draw(_offset) for _ in range(3)])
    if draw(st.booleans()):
        rpy = np.zeros(3)
    else:
        rpy = np.array([draw(_angle) for _ in range(3)])
    return xyz, rpy


@st.composite
def rotary_pair(draw: st.DrawFn) -> tuple[np.ndarray, np.ndarray, float]:
    """Two unit rotary directions at least 10 degrees apart (as lines), and their angle."""
    k1 = draw(unit_vectors())
    angle = draw(
        st.one_of(
            st.sampled_from([90.0, 45.0, 60.0, 30.0, 135.0]),
            st.floats(MIN_AXIS_ANGLE_DEG, 180.0 - MIN_AXIS_ANGLE_DEG),
        )
    )
    u = draw(unit_vectors())
    u_perp = u - k1 * float(k1 @ u)
    n = float(np.linalg.norm(u_perp))
    assume(n > 0.1)
    u_perp /= n
    a = np.radians(angle)
    k2 = np.cos(a) * k1 + np.sin(a) * u_perp
    return k1, k2 / np.linalg.norm(k2), angle


@st.composite
def linear_directions(draw: st.DrawFn) -> np.ndarray:
    """Three well-conditioned, not necessarily orthogonal unit directions (columns)."""
    base = draw(rotations())
    pert = np.array([[draw(st.floats(-0.3, 0.3)) for _ in range(3)] for _ in range(3)])
    m = base @ (np.eye(3) + pert)
    m /= np.linalg.norm(m, axis=0)
    signs = np.array([draw(st.sampled_from([-1.0, 1.0])) for _ in range(3)])
    m = m * signs
    assume(abs(np.linalg.det(m)) > 0.3)
    return m


@dataclass
class _Joint:
    name: str
    type: str
    parent: str
    child: str
    xyz: np.ndarray
    rpy: np.ndarray
    direction: np.ndarray | None = None  # root frame at home
    limits: tuple[float, float] | None = None
    velocity: float | None = None
    axis_local: np.ndarray | None = None


@st.composite
def machines(draw: st.DrawFn, families: tuple[str, ...] = FAMILIES) -> GenMachine:
    """Random valid machines as URDF text with metadata (:class:`GenMachine`).

    Parameters
    ----------
    families : tuple of str
        Arrangements to draw from, among :data:`FAMILIES` ("4-axis-table" and "4-axis-head" are
        the 4-axis family with the rotary axis moving the workpiece or the tool).
    """
    arrangement = draw(st.sampled_from(families))
    rot_sides = {
        "table-table": ["table", "table"],
        "head-head": ["head", "head"],
        "head-table": ["table", "head"],  # chain order from the workpiece
        "4-axis-table": ["table"],
        "4-axis-head": ["head"],
    }[arrangement]
    family = "4-axis" if arrangement.startswith("4-axis") else arrangement
    rot_names = list(draw(st.permutations(["A", "B", "C"])))[: len(rot_sides)]

    # directions in the root frame at home
    k1, k2, rot_angle = draw(rotary_pair())
    rot_dirs = [k1, k2][: len(rot_sides)]
    lin_dirs = draw(linear_directions())
    directions: dict[str, np.ndarray] = {n: rot_dirs[i] for i, n in enumerate(rot_names)}
    directions.update({n: lin_dirs[:, i] for i, n in enumerate("XYZ")})

    lin_sides = {n: draw(st.sampled_from(["table", "head"])) for n in "XYZ"}
    table_lin = [n for n in draw(st.permutations(list("XYZ"))) if lin_sides[n] == "table"]
    head_lin = [n for n in draw(st.permutations(list("XYZ"))) if lin_sides[n] == "head"]
    table_rot = [n for n, s in zip(rot_names, rot_sides, strict=True) if s == "table"]
    head_rot = [n for n, s in zip(rot_names, rot_sides, strict=True) if s == "head"]
    # parent-to-child order from the common ancestor
    table_moving = table_lin + list(reversed(table_rot))  # ... slides, far rotary, near rotary
    head_moving = head_lin + head_rot  # slides, then rotaries in chain order

    kinds: dict[str, str] = {}
    limits: dict[str, tuple[float, float]] = {}
    velocities: dict[str, float | None] = {}
    for n in "XYZ":
        kinds[n] = "prismatic"
        limits[n] = (draw(st.floats(-1.0, -0.05)), draw(st.floats(0.05, 1.0)))
    for n in rot_names:
        kinds[n] = draw(st.sampled_from(["revolute", "continuous"]))
        if kinds[n] == "revolute":
            limits[n] = (draw(st.floats(-2 * np.pi, -0.2)), draw(st.floats(0.2, 2 * np.pi)))
    for n in kinds:
        velocities[n] = draw(st.one_of(st.none(), st.floats(0.01, 10.0)))

    counter = iter(range(10_000))
    joints: list[_Joint] = []
    links: list[str] = []

    def new_link(prefix: str) -> str:
        name = f"{prefix}_{next(counter)}"
        links.append(name)
        return name

    def add_fixed(parent: str, child: str | None = None) -> str:
        child = child or new_link("frame")
        xyz, rpy = draw(origins())
        joints.append(_Joint(f"fixed_{next(counter)}", "fixed", parent, child, xyz, rpy))
        return child

    def grow(ancestor: str, moving: list[str], end: str) -> None:
        """Chain ancestor -> moving joints (with fixed joints between) -> end link."""
        link = ancestor
        for name in moving:
            for _ in range(draw(st.integers(0, 2))):
                link = add_fixed(link)
            child = new_link(f"{name.lower()}_carriage")
            xyz, rpy = draw(origins())
            joints.append(
                _Joint(
                    name,
                    kinds[name],
                    link,
                    child,
                    xyz,
                    rpy,
                    direction=directions[name],
                    limits=limits.get(name),
                    velocity=velocities[name],
                )
            )
            link = child
        for _ in range(draw(st.integers(0, 1))):
            link = add_fixed(link)
        add_fixed(link, end)

    # the common ancestor: a "base" link, or the workpiece / tool itself when its side has no
    # moving joint
    if not table_moving and draw(st.booleans()):
        ancestor = "workpiece"
    elif not head_moving and draw(st.booleans()):
        ancestor = "tool"
    else:
        ancestor = "base"
    links.extend(["workpiece", "tool"] if ancestor != "base" else ["base", "workpiece", "tool"])
    if ancestor != "workpiece":
        grow(ancestor, table_moving, "workpiece")
    if ancestor != "tool":
        grow(ancestor, head_moving, "tool")
    if draw(st.booleans()):  # a world root above the machine
        links.append("world")
        add_fixed("world", ancestor)
    if draw(st.booleans()):  # decoration off the chain
        add_fixed(draw(st.sampled_from(list(links))), new_link("cover"))

    # home pose of every link in the root frame (joints are in parent-before-child order
    # except the world joint, so iterate until all are placed)
    by_child = {j.child: j for j in joints}
    root = next(lk for lk in links if lk not in by_child)
    placed: dict[str, np.ndarray] = {root: np.eye(4)}
    pending = list(joints)
    while pending:
        rest = []
        for j in pending:
            if j.parent not in placed:
                rest.append(j)
                continue
            t = np.eye(4)
            t[:3, :3] = rpy_matrix(j.rpy)
            t[:3, 3] = j.xyz
            frame = placed[j.parent] @ t
            placed[j.child] = frame
            if j.direction is not None:
                j.axis_local = frame[:3, :3].T @ j.direction
        assert len(rest) < len(pending), "generator built a disconnected tree"
        pending = rest

    v0 = placed["tool"][:3, 2]
    # the last rotary axis along the chain must not be (nearly) parallel to the home tool axis
    last = rot_names[-1]
    assume(line_angle_deg(directions[last], v0) >= MIN_AXIS_ANGLE_DEG)

    text, prefer = _write(draw, links, joints, rot_names)
    return GenMachine(
        urdf=text,
        family=family,
        rotary=tuple(rot_names),
        sides={**lin_sides, **dict(zip(rot_names, rot_sides, strict=True))},
        kinds=kinds,
        limits=limits,
        directions=directions,
        home_tool_axis=v0,
        rotary_angle_deg=rot_angle if len(rot_names) == 2 else float("nan"),
        ancestor=ancestor,
        prefer=prefer,
    )


def _write(
    draw: st.DrawFn,
    links: list[str],
    joints: list[_Joint],
    rot_names: list[str],
) -> tuple[str, tuple[str, int] | None]:
    out = ['<?xml version="1.0"?>', '<robot name="generated">']
    elements: list[str] = []
    for lk in links:
        if draw(st.booleans()):
            elements.append(f'  <link name="{lk}"/>')
        else:
            elements.append(
                f'  <link name="{lk}">\n'
                '    <inertial><mass value="1"/>'
                '<inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial>\n'
                '    <visual><geometry><box size="0.1 0.1 0.1"/></geometry></visual>\n'
                "  </link>"
            )
    for j in joints:
        body = [f'    <parent link="{j.parent}"/>', f'    <child link="{j.child}"/>']
        body.append(f'    <origin xyz="{_fmt(j.xyz)}" rpy="{_fmt(j.rpy)}"/>')
        if j.axis_local is not None:
            body.append(f'    <axis xyz="{_fmt(j.axis_local)}"/>')
        if j.type in ("prismatic", "revolute"):
            assert j.limits is not None
            vel = j.velocity if j.velocity is not None else 1.0
            body.append(
                f'    <limit lower="{j.limits[0]!r}" upper="{j.limits[1]!r}" effort="100" '
                f'velocity="{vel!r}"/>'
            )
        elif j.type == "continuous" and j.velocity is not None:
            body.append(f'    <limit effort="100" velocity="{j.velocity!r}"/>')
        elements.append(
            f'  <joint name="{j.name}" type="{j.type}">\n' + "\n".join(body) + "\n  </joint>"
        )
    order = draw(st.permutations(range(len(elements))))
    out.extend(elements[i] for i in order)
    prefer = None
    if draw(st.booleans()):
        name = draw(st.sampled_from(rot_names))
        sign = draw(st.sampled_from("+-"))
        prefer = (name, 1 if sign == "+" else -1)
        out.append(  # home inside every travel the generator draws
            '  <urdfpost controller="heidenhain" units="mm" tool_length="0.1">'
            f'<prefer axis="{name}" sign="{sign}"/><home X="0.01" {name}="0.1"/></urdfpost>'
        )
    out.append("</robot>")
    return "\n".join(out) + "\n", prefer


# -- hand-described machines -----------------------------------------------------------------


@dataclass(frozen=True)
class J:
    """A joint for :func:`simple_urdf` (URDF units; strings as written in the file)."""

    name: str
    type: str
    axis: str = "0 0 1"
    xyz: str = "0 0 0"
    rpy: str = "0 0 0"
    lower: float = -1.0
    upper: float = 1.0


def simple_urdf(
    table: tuple[J, ...] | list[J] = (),
    head: tuple[J, ...] | list[J] = (),
    tool_xyz: str = "0 0 0",
    tool_rpy: str = "0 0 0",
    work_xyz: str = "0 0 0",
    work_rpy: str = "0 0 0",
    extra: str = "",
) -> str:
    """URDF text of a machine: ``base`` -> ``table`` joints -> ``workpiece`` and ``base`` ->
    ``head`` joints -> ``tool`` (joints listed parent first), with fixed end joints."""
    links = ["base"]
    joints = []

    def chain(js: tuple[J, ...] | list[J], end: str, xyz: str, rpy: str) -> None:
        parent = "base"
        for j in js:
            child = f"{j.name.lower()}_link"
            links.append(child)
            limit = (
                f'<limit lower="{j.lower!r}" upper="{j.upper!r}" effort="1" velocity="1"/>'
                if j.type in ("prismatic", "revolute")
                else ""
            )
            joints.append(
                f'<joint name="{j.name}" type="{j.type}"><parent link="{parent}"/>'
                f'<child link="{child}"/><origin xyz="{j.xyz}" rpy="{j.rpy}"/>'
                f'<axis xyz="{j.axis}"/>{limit}</joint>'
            )
            parent = child
        links.append(end)
        joints.append(
            f'<joint name="{end}_mount" type="fixed"><parent link="{parent}"/>'
            f'<child link="{end}"/><origin xyz="{xyz}" rpy="{rpy}"/></joint>'
        )

    chain(table, "workpiece", work_xyz, work_rpy)
    chain(head, "tool", tool_xyz, tool_rpy)
    body = "\n".join([*(f'<link name="{lk}"/>' for lk in links), *joints, extra])
    return f'<robot name="simple">\n{body}\n</robot>\n'
