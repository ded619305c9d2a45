"""Reading and checking a machine URDF against the urdfpost convention.

Validation happens here, once, before Pinocchio sees the file, so every message can name the
file, the line and the joint or link at fault. The functions parse the text
(:func:`parse_urdf`), find the moving joints between ``workpiece`` and ``tool``
(:func:`check_chain`), check that the links form one tree (:func:`check_tree`), read the
``<urdfpost>`` settings (:func:`parse_settings`) and which axes carry each link
(:func:`link_axes`); :mod:`urdfpost.machine.load` builds the
:class:`~urdfpost.machine.model.Machine` from them, handing Pinocchio only the links and joints
(:func:`kinematic_urdf`).

The checks cover everything in a joint that Pinocchio's URDF parser (urdfdom) reads, so that a
file passing them never makes it fail or print: every number is finite and written as urdfdom
reads numbers, every joint has a known type, limits where its type needs them, and links that
exist. Entity declarations are refused (the file is parsed without expanding them, and without
network or DTD access).

This module is a leaf: it imports from urdfpost only the errors, the units, the machine's data
classes and the dialect registry (for the controller names).
"""

from __future__ import annotations

import copy
import math
import re
from dataclasses import dataclass

from lxml import etree

from urdfpost.dialects import DIALECTS
from urdfpost.errors import MachineDefinitionError
from urdfpost.machine.model import NC_ADDRESSES, Settings
from urdfpost.program import JOB_FEED_MODES
from urdfpost.units import M_TO_MM


@dataclass(frozen=True)
class JointSpec:
    """A joint as written in the URDF (URDF units: metres, radians)."""

    name: str
    type: str
    parent: str
    child: str
    axis: tuple[float, float, float]
    lower: float
    upper: float
    velocity: float | None
    line: int
    side: str = ""
    mimic: tuple[str, int] | None = None
    """The joint this one mimics (``<mimic joint>``) and the line of the ``<mimic>``; None
    for an independent joint."""


@dataclass(frozen=True)
class JointChain:
    """The moving joints between ``workpiece`` and ``tool`` as the file gives them.

    Attributes
    ----------
    joints : tuple of JointSpec
        Ordered from the workpiece, each with its ``side``.
    ancestor : str
        The link where the paths from ``workpiece`` and from ``tool`` to the root meet.
    """

    joints: tuple[JointSpec, ...]
    ancestor: str


@dataclass(frozen=True)
class UrdfDoc:
    """The parts of a URDF that the checks need.

    Attributes
    ----------
    root : lxml.etree._Element
        The ``<robot>`` element.
    links : dict of str to int
        Link name to the line it is defined on, in file order.
    joints : dict of str to JointSpec
        Joint name to joint, in file order.
    """

    root: etree._Element
    links: dict[str, int]  # name -> line
    joints: dict[str, JointSpec]


def _where(source: str, line: int | None) -> str:
    return f"{source}:{line}" if line else source


# URDF joint types (urdfdom refuses others)
JOINT_TYPES = ("fixed", "prismatic", "revolute", "continuous", "floating", "planar")

# URDF versions urdfdom reads
URDF_VERSIONS = ("1.0", "1.1", "1.2")


def _parse_number(raw: str) -> float | None:
    """``raw`` as a float (possibly not finite), or None when it is no number urdfdom reads.

    Python's ``float`` reads more than urdfdom (Pinocchio's URDF parser) does: "1_0",
    non-ASCII digits and trailing blanks too. These are refused here (urdfdom does take leading
    blanks); "nan" and "inf" are read, for the caller to refuse as not finite.
    """
    try:
        value = float(raw)
    except ValueError:
        return None
    if "_" in raw or not raw.isascii() or raw[-1:].isspace():
        return None
    return value


def _float_or_none(source: str, el: etree._Element, attr: str, what: str = "") -> float | None:
    """The finite number in attribute ``attr`` of ``el``; None when the attribute is absent.

    ``what`` starts the message (``"joint 'B': "``), after the file and the element's line.
    """
    raw = el.get(attr)
    if raw is None:
        return None
    value = _parse_number(raw)
    if value is None or not math.isfinite(value):
        finite = "" if value is None else "finite "
        raise MachineDefinitionError(
            f"{_where(source, el.sourceline)}: {what}<{el.tag}> {attr}={raw!r}: "
            f"expected a {finite}number"
        )
    return value


def _float(source: str, el: etree._Element, attr: str, default: float, what: str = "") -> float:
    """As :func:`_float_or_none`, with ``default`` for an absent attribute."""
    value = _float_or_none(source, el, attr, what)
    return default if value is None else value


def _vector(
    source: str, el: etree._Element, attr: str, what: str
) -> tuple[float, float, float] | None:
    """The three finite numbers in attribute ``attr`` of ``el``; None when it is absent."""
    raw = el.get(attr)
    if raw is None:
        return None
    parts = raw.split()
    numbers = [v for v in map(_parse_number, parts) if v is not None]
    if len(parts) != 3 or len(numbers) != 3:
        expected = "3 numbers"
    elif not all(map(math.isfinite, numbers)):
        expected = "3 finite numbers"
    else:
        return numbers[0], numbers[1], numbers[2]
    raise MachineDefinitionError(
        f"{_where(source, el.sourceline)}: {what}<{el.tag}> {attr}={raw!r}: expected {expected}"
    )


def _check_doctype(root: etree._Element, text: str, source: str) -> None:
    """Refuse entity declarations: urdfpost does not expand them, and other URDF tools differ."""
    dtd = root.getroottree().docinfo.internalDTD
    entities = list(dtd.iterentities()) if dtd is not None else []
    if entities:
        at = text.find("<!ENTITY")
        line = text.count("\n", 0, at) + 1 if at >= 0 else 1
        raise MachineDefinitionError(
            f"{source}:{line}: <!ENTITY {entities[0].name}>: entity declarations are not "
            "allowed in a machine file (they are not expanded); write the value itself"
        )


def parse_urdf(text: str, source: str) -> UrdfDoc:
    """Parse URDF text into links and joints, checking each element on its own.

    The XML is parsed without expanding entities, without loading a DTD and without network
    access.

    Raises
    ------
    MachineDefinitionError
        For broken XML, entity declarations, a root that is not ``<robot>`` or has no name or an
        unknown ``version``, links or joints without names or defined twice, a link that is the
        child of two joints, and every fault :func:`check_joint` finds.
    """
    parser = etree.XMLParser(
        remove_comments=True,
        resolve_entities=False,
        load_dtd=False,
        no_network=True,
        huge_tree=False,
    )
    try:
        root = etree.fromstring(text.encode("utf-8"), parser=parser)
    except etree.XMLSyntaxError as e:
        raise MachineDefinitionError(
            f"{_where(source, e.lineno)}: not a URDF: broken XML: {e.msg}"
        ) from e
    _check_doctype(root, text, source)
    where = _where(source, root.sourceline)
    if root.tag != "robot":
        raise MachineDefinitionError(
            f"{where}: not a URDF: expected root element <robot>, got <{root.tag}>"
        )
    if not root.get("name"):
        raise MachineDefinitionError(f"{where}: <robot> without name")
    version = root.get("version")
    if version is not None and version not in URDF_VERSIONS:
        raise MachineDefinitionError(
            f"{where}: <robot version={version!r}>: expected one of {' '.join(URDF_VERSIONS)}"
        )
    links: dict[str, int] = {}
    for el in root.findall("link"):
        name = el.get("name")
        if not name:
            raise MachineDefinitionError(f"{_where(source, el.sourceline)}: <link> without name")
        if name in links:
            raise MachineDefinitionError(
                f"{_where(source, el.sourceline)}: link {name!r} defined twice (first at line "
                f"{links[name]})"
            )
        links[name] = el.sourceline
    joints: dict[str, JointSpec] = {}
    parent_joint: dict[str, JointSpec] = {}  # child link -> its joint
    for el in root.findall("joint"):
        spec = check_joint(source, el)
        if spec.name in joints:
            raise MachineDefinitionError(
                f"{_where(source, spec.line)}: joint {spec.name!r} defined twice (first at line "
                f"{joints[spec.name].line}): joint names must be unique"
            )
        if spec.child in parent_joint:
            first = parent_joint[spec.child]
            raise MachineDefinitionError(
                f"{_where(source, spec.line)}: joint {spec.name!r}: link {spec.child!r} is "
                f"already the child of joint {first.name!r} (line {first.line}); a link has one "
                "parent"
            )
        joints[spec.name] = spec
        parent_joint[spec.child] = spec
    return UrdfDoc(root=root, links=links, joints=joints)


def check_joint(source: str, el: etree._Element) -> JointSpec:
    """Read a ``<joint>`` element, checking everything in it that URDF readers read.

    Parameters
    ----------
    source : str
        The file, for messages.
    el : lxml.etree._Element
        The ``<joint>`` element.

    Returns
    -------
    JointSpec
        URDF units (metres, radians); ``side`` empty.

    Raises
    ------
    MachineDefinitionError
        At the line of the element at fault, naming the joint: a missing name, type, parent or
        child; an unknown type; a number that is not a finite number (``<origin xyz rpy>``,
        ``<axis xyz>``, ``<limit>``, ``<dynamics>``, ``<safety_controller>``,
        ``<calibration>``, ``<mimic>``); a zero axis on a moving joint; a prismatic or revolute
        joint without ``<limit>``, a ``<limit>`` without ``effort`` and ``velocity``, a
        negative effort or velocity; a ``<safety_controller>`` without ``k_velocity`` or a
        ``<mimic>`` without ``joint``.
    """
    where = _where(source, el.sourceline)
    name = el.get("name")
    jtype = el.get("type")
    if not name or not jtype:
        raise MachineDefinitionError(f"{where}: <joint> needs name and type attributes")
    if jtype not in JOINT_TYPES:
        raise MachineDefinitionError(f"{where}: joint {name!r} has unknown type {jtype!r}")
    what = f"joint {name!r}: "
    sub: dict[object, etree._Element] = {}  # tag -> first child with it (one pass: find is slow)
    for c in el:
        sub.setdefault(c.tag, c)
    parent, child = sub.get("parent"), sub.get("child")
    if parent is None or child is None or not parent.get("link") or not child.get("link"):
        raise MachineDefinitionError(
            f"{where}: joint {name!r} needs <parent link> and <child link>"
        )
    origin = sub.get("origin")
    if origin is not None:
        _vector(source, origin, "xyz", what)
        _vector(source, origin, "rpy", what)
    axis_el = sub.get("axis")
    axis = (1.0, 0.0, 0.0)
    if axis_el is not None:
        xyz = _vector(source, axis_el, "xyz", what)
        if xyz is None:
            raise MachineDefinitionError(
                f"{_where(source, axis_el.sourceline)}: joint {name!r}: <axis> needs xyz"
            )
        axis = xyz
    if jtype in ("prismatic", "revolute", "continuous", "planar") and math.hypot(*axis) < 1e-9:
        raise MachineDefinitionError(
            f"{_where(source, axis_el.sourceline if axis_el is not None else el.sourceline)}: "
            f"joint {name!r}: zero axis vector {axis}: "
            "expected a direction"
        )
    limit = sub.get("limit")
    lower = upper = 0.0
    velocity = None
    if limit is None and jtype in ("prismatic", "revolute"):
        raise MachineDefinitionError(
            f"{where}: joint {name!r} is {jtype}: it needs "
            '<limit lower="..." upper="..." effort="..." velocity="..."/>'
        )
    if limit is not None:
        lwhere = _where(source, limit.sourceline)
        lower = _float(source, limit, "lower", 0.0, what)
        upper = _float(source, limit, "upper", 0.0, what)
        effort = _float_or_none(source, limit, "effort", what)
        velocity = _float_or_none(source, limit, "velocity", what)
        if effort is None or velocity is None:
            raise MachineDefinitionError(
                f"{lwhere}: joint {name!r}: <limit> needs effort and velocity attributes (URDF "
                "requires both; urdfpost uses velocity, any effort >= 0 will do)"
            )
        if effort < 0:
            raise MachineDefinitionError(
                f"{lwhere}: joint {name!r}: effort limit {effort} must not be negative"
            )
        if velocity < 0:
            raise MachineDefinitionError(
                f"{lwhere}: joint {name!r}: velocity limit {velocity} must be positive"
            )
    for tag, attrs, needs in _JOINT_NUMBERS:
        other = sub.get(tag)
        if other is None:
            continue
        for attr in attrs:
            _float_or_none(source, other, attr, what)
        if needs and all(other.get(a) is None for a in needs):
            raise MachineDefinitionError(
                f"{_where(source, other.sourceline)}: joint {name!r}: <{tag}> needs "
                f"{' or '.join(needs)}"
            )
    mimic = sub.get("mimic")
    return JointSpec(
        name=name,
        type=jtype,
        parent=parent.get("link"),
        child=child.get("link"),
        axis=axis,
        lower=lower,
        upper=upper,
        velocity=velocity,
        line=el.sourceline,
        mimic=None if mimic is None else (str(mimic.get("joint")), mimic.sourceline),
    )


# the other elements of a joint that urdfdom reads: tag, its number attributes, the attributes
# of which it needs at least one
_JOINT_NUMBERS: tuple[tuple[str, tuple[str, ...], tuple[str, ...]], ...] = (
    ("dynamics", ("damping", "friction"), ("damping", "friction")),
    (
        "safety_controller",
        ("soft_lower_limit", "soft_upper_limit", "k_position", "k_velocity"),
        ("k_velocity",),
    ),
    ("calibration", ("rising", "falling"), ()),
    ("mimic", ("multiplier", "offset"), ("joint",)),
)


def _path_to_root(doc: UrdfDoc, link: str) -> list[JointSpec]:
    """Joints from ``link`` up to the root, nearest first."""
    by_child = {j.child: j for j in doc.joints.values()}
    path: list[JointSpec] = []
    seen = {link}
    while link in by_child:
        j = by_child[link]
        path.append(j)
        link = j.parent
        if link in seen:
            raise MachineDefinitionError(f"joint {j.name!r} closes a loop at link {link!r}")
        seen.add(link)
    return path


def check_chain(doc: UrdfDoc, source: str) -> JointChain:
    """Find and check the moving joints between ``workpiece`` and ``tool``.

    Returns
    -------
    JointChain
        Moving joints ordered from the workpiece, each with ``side`` "table" (moves the
        workpiece) or "head" (moves the tool).

    Raises
    ------
    MachineDefinitionError
        Missing links, floating/planar joints on the chain, a moving joint on the chain that
        mimics another (``<mimic>``, at its line: the kinematics has independent axes only),
        wrong joint count, bad names, inverted limits, no travel, a velocity that is not
        positive.
    """
    for link in ("workpiece", "tool"):
        if link not in doc.links:
            raise MachineDefinitionError(
                f"{source}: no link named {link!r}: the convention needs a 'workpiece' link "
                "(CL frame) and a 'tool' link (gauge point, +Z toward the spindle)"
            )
    try:
        up_w = _path_to_root(doc, "workpiece")
        up_t = _path_to_root(doc, "tool")
    except MachineDefinitionError as e:
        raise MachineDefinitionError(f"{source}: {e}") from e
    links_w = ["workpiece"] + [j.parent for j in up_w]
    links_t = ["tool"] + [j.parent for j in up_t]
    common = next((lk for lk in links_w if lk in links_t), None)
    if common is None:
        raise MachineDefinitionError(
            f"{source}: links 'workpiece' and 'tool' are not connected by joints"
        )
    table_side = [
        _sided(j, "table") for j in up_w[: links_w.index(common)]
    ]  # from workpiece upward
    head_side = [_sided(j, "head") for j in reversed(up_t[: links_t.index(common)])]
    chain = table_side + head_side
    for j in chain:
        if j.type in ("floating", "planar"):
            raise MachineDefinitionError(
                f"{_where(source, j.line)}: joint {j.name!r} is {j.type}: a machine axis must "
                "be prismatic, revolute or continuous (fixed joints are allowed too)"
            )
    moving = [j for j in chain if j.type != "fixed"]
    for j in moving:
        if j.mimic is not None:
            other, line = j.mimic
            raise MachineDefinitionError(
                f"{_where(source, line)}: joint {j.name!r} mimics joint {other!r} (<mimic>): "
                "a machine axis between 'workpiece' and 'tool' must move on its own; urdfpost's "
                "kinematics (the closed-form inverse kinematics of independent rotary axes) "
                f"cannot keep {j.name} coupled to {other}, so the program would move it "
                f"independently; make {j.name!r} independent, or a fixed joint"
            )
    n_lin = sum(j.type == "prismatic" for j in moving)
    n_rot = len(moving) - n_lin
    if n_lin != 3 or n_rot not in (1, 2):
        names = ", ".join(f"{j.name} ({j.type})" for j in moving) or "none"
        raise MachineDefinitionError(
            f"{source}: the chain between 'workpiece' and 'tool' must have exactly 3 prismatic "
            f"and 1 or 2 revolute/continuous joints; it has {n_lin} prismatic and {n_rot} "
            f"rotary: {names}"
        )
    for j in moving:
        where = _where(source, j.line)
        if j.name.upper() not in NC_ADDRESSES or j.name != j.name.upper():
            raise MachineDefinitionError(
                f"{where}: joint {j.name!r}: a moving joint must be named with its NC address, "
                f"one of {' '.join(NC_ADDRESSES)}"
            )
        if j.type == "prismatic" and j.name not in ("X", "Y", "Z"):
            raise MachineDefinitionError(
                f"{where}: joint {j.name!r} is prismatic: linear axes are named X, Y or Z"
            )
        if j.type != "prismatic" and j.name not in ("A", "B", "C"):
            raise MachineDefinitionError(
                f"{where}: joint {j.name!r} is {j.type}: rotary axes are named A, B or C"
            )
        if j.type != "continuous" and j.lower > j.upper:
            raise MachineDefinitionError(
                f"{where}: joint {j.name!r}: lower limit {j.lower} is above upper limit {j.upper}"
            )
        if j.type != "continuous" and j.lower == j.upper:
            raise MachineDefinitionError(
                f"{where}: joint {j.name!r}: no travel (lower == upper == {j.lower}); "
                "give <limit lower=... upper=...>"
            )
        if j.velocity is not None and j.velocity <= 0:
            raise MachineDefinitionError(
                f"{where}: joint {j.name!r}: velocity limit {j.velocity} must be positive"
            )
    return JointChain(joints=tuple(moving), ancestor=common)


def _sided(j: JointSpec, side: str) -> JointSpec:
    return JointSpec(**{**j.__dict__, "side": side})


def check_tree(doc: UrdfDoc, source: str) -> str:
    """Check that the links form one tree, as URDF requires (after :func:`check_chain`).

    Returns
    -------
    str
        The root link (the one link that is no joint's child).

    Raises
    ------
    MachineDefinitionError
        For a joint whose parent or child link is not defined, or a second root link (a link no
        joint attaches to the tree of the workpiece).
    """
    for j in doc.joints.values():
        for role, link in (("parent", j.parent), ("child", j.child)):
            if link not in doc.links:
                raise MachineDefinitionError(
                    f"{_where(source, j.line)}: joint {j.name!r}: {role} link {link!r} is not "
                    "defined"
                )
    children = {j.child for j in doc.joints.values()}
    root = "workpiece"
    by_child = {j.child: j for j in doc.joints.values()}
    while root in by_child:  # no loop: check_chain has walked this path
        root = by_child[root].parent
    for link, line in doc.links.items():
        if link not in children and link != root:
            raise MachineDefinitionError(
                f"{_where(source, line)}: link {link!r} is attached by no joint: a URDF is one "
                f"tree with one root link ({root!r} here); attach {link!r} to it with a joint"
            )
    return root


def kinematic_urdf(doc: UrdfDoc) -> str:
    """The links and joints of a checked document as URDF text, for Pinocchio.

    Everything else is left out: the shapes (``<collision>``, ``<visual>``, read by
    :mod:`urdfpost.machine.shapes` with their own messages), ``<inertial>`` and ``<material>``
    (urdfpost uses no masses or colours) and extension elements. Pinocchio's parser then reads
    only what :func:`check_joint` has checked, and prints nothing.

    Parameters
    ----------
    doc : UrdfDoc
        A document that passed :func:`parse_urdf`, :func:`check_chain` and :func:`check_tree`.

    Returns
    -------
    str
        A URDF with the same links, joints and order, so the same Pinocchio model (but for
        the inertias, all zero).
    """
    robot = etree.Element("robot", name=doc.root.get("name", ""))
    for link in doc.links:
        etree.SubElement(robot, "link", name=link)
    for joint in doc.root.iterfind("joint"):
        robot.append(copy.deepcopy(joint))
    return etree.tostring(robot, encoding="unicode")


def parse_settings(doc: UrdfDoc, source: str, joints: tuple[JointSpec, ...]) -> Settings:
    """Read the ``<urdfpost>`` extension element (all settings optional).

    Raises
    ------
    MachineDefinitionError
        At the line of the element: for an unknown controller (one not in
        :data:`urdfpost.dialects.DIALECTS`) or units, a ``tool_length`` that is not a finite
        length >= 0, a preference or home naming a missing axis, a home value that is not a
        finite number or is outside the travel, a ``feed_mode`` that is none of
        :data:`urdfpost.program.JOB_FEED_MODES`. The ``strategy`` name is not checked here:
        :attr:`Settings.where` lets the post report an unknown one against the file.
    """
    axis_names = [j.name for j in joints]
    rotary_names = [j.name for j in joints if j.type != "prismatic"]
    el = doc.root.find("urdfpost")
    if el is None:
        return Settings()
    where = _where(source, el.sourceline)
    controller = el.get("controller", "heidenhain")
    if controller not in DIALECTS:
        raise MachineDefinitionError(
            f"{where}: <urdfpost controller={controller!r}>: expected one of {tuple(DIALECTS)}"
        )
    units = el.get("units")  # None: the program takes the CL data's units
    if units is not None and units not in ("mm", "inch"):
        raise MachineDefinitionError(f"{where}: <urdfpost units={units!r}>: expected mm or inch")
    tool_length = _tool_length(source, el)
    prefer = None
    pref_el = el.find("prefer")
    if pref_el is not None:
        axis, sign = pref_el.get("axis"), pref_el.get("sign", "+")
        if axis not in rotary_names or sign not in ("+", "-"):
            raise MachineDefinitionError(
                f"{_where(source, pref_el.sourceline)}: <prefer axis={axis!r} sign={sign!r}>: "
                f"expected a rotary axis of the chain ({' '.join(rotary_names)}) and sign + or -"
            )
        prefer = (axis, 1 if sign == "+" else -1)
    home: dict[str, float] = {}
    home_el = el.find("home")
    if home_el is not None:
        for key in home_el.keys():
            if key not in axis_names:
                raise MachineDefinitionError(
                    f"{_where(source, home_el.sourceline)}: <home {key}=...>: no such axis; "
                    f"expected one of {' '.join(axis_names)}"
                )
            value = _float(source, home_el, key, 0.0)
            joint = joints[axis_names.index(key)]
            if (
                joint.type != "continuous"
                and not joint.lower - 1e-12 <= value <= joint.upper + 1e-12
            ):
                raise MachineDefinitionError(
                    f"{_where(source, home_el.sourceline)}: <home {key}={value:g}>: outside the "
                    f"travel of joint {key!r} ({joint.lower:g} .. {joint.upper:g})"
                )
            home[key] = value * (M_TO_MM if key in ("X", "Y", "Z") else 1.0)
    strategy = el.get("strategy")
    smoothing = _switch(where, el, "smoothing", True)
    tilted_planes = _switch(where, el, "tilted_planes", True)
    clamps = _clamps(where, el, joints)
    rollover = _rollover(where, el, joints)
    feed_mode = el.get("feed_mode")
    if feed_mode is not None and feed_mode not in JOB_FEED_MODES:
        raise MachineDefinitionError(
            f"{where}: <urdfpost feed_mode={feed_mode!r}>: expected one of "
            f"{', '.join(JOB_FEED_MODES)}"
        )
    desc_el = el.find("description")
    description = " ".join((desc_el.text or "").split()) if desc_el is not None else ""
    return Settings(
        controller=controller,
        units=units,
        tool_length=tool_length,
        prefer=prefer,
        home=home,
        description=description,
        strategy=strategy,
        where=where,
        smoothing=smoothing,
        rollover=rollover,
        feed_mode=feed_mode,
        tilted_planes=tilted_planes,
        clamps=clamps,
    )


_SWITCH = {"on": True, "true": True, "1": True, "off": False, "false": False, "0": False}


def _switch(where: str, el: etree._Element, name: str, default: bool) -> bool:
    """An on/off attribute of ``<urdfpost>``."""
    raw = el.get(name)
    if raw is None:
        return default
    value = _SWITCH.get(raw.strip().lower())
    if value is None:
        raise MachineDefinitionError(f"{where}: <urdfpost {name}={raw!r}>: expected on or off")
    return value


_CLAMP = re.compile(r"([A-Z]+):M(\d+)/M(\d+)\Z")


def _clamps(
    where: str, el: etree._Element, joints: tuple[JointSpec, ...]
) -> tuple[tuple[str, int, int], ...]:
    """The ``clamp`` attribute: rotary joints of the chain with their clamp and release M
    codes, ``"B:M10/M11 C:M12/M13"``."""
    raw = el.get("clamp")
    if raw is None:
        return ()
    rotary = [j.name for j in joints if j.type in ("revolute", "continuous")]
    out: list[tuple[str, int, int]] = []
    for item in raw.replace(",", " ").split():
        match = _CLAMP.match(item)
        if match is None or match.group(1) not in rotary:
            raise MachineDefinitionError(
                f"{where}: <urdfpost clamp={raw!r}>: {item!r}; expected AXIS:Mclamp/Mrelease "
                f"for rotary joints of the chain ({' '.join(rotary) or 'none'}), e.g. B:M10/M11"
            )
        out.append((match.group(1), int(match.group(2)), int(match.group(3))))
    codes = [c for _, on, off in out for c in (on, off)]
    names = [a for a, _, _ in out]
    if len(set(codes)) != len(codes) or len(set(names)) != len(names):
        raise MachineDefinitionError(
            f"{where}: <urdfpost clamp={raw!r}>: expected each axis once and each M code once"
        )
    return tuple(out)


def _rollover(where: str, el: etree._Element, joints: tuple[JointSpec, ...]) -> frozenset[str]:
    """The ``rollover`` attribute: continuous joints of the chain, by name ("C", "A C")."""
    raw = el.get("rollover")
    if raw is None:
        return frozenset()
    names = raw.replace(",", " ").split()
    continuous = [j.name for j in joints if j.type == "continuous"]
    wrong = [n for n in names if n not in continuous]
    if wrong or not names or len(set(names)) != len(names):
        expected = " ".join(continuous) if continuous else "none: the chain has none"
        raise MachineDefinitionError(
            f"{where}: <urdfpost rollover={raw!r}>: expected continuous joints of the chain, "
            f"each once ({expected})"
        )
    return frozenset(names)


def _tool_length(source: str, el: etree._Element) -> float:
    """The ``tool_length`` setting, mm (URDF metres in the file)."""
    raw = el.get("tool_length")
    if raw is None:
        return 0.0
    value = _parse_number(raw)
    if value is None:
        raise MachineDefinitionError(
            f"{_where(source, el.sourceline)}: <urdfpost> tool_length={raw!r}: expected a number"
        )
    if not (math.isfinite(value) and value >= 0):
        raise MachineDefinitionError(
            f"{_where(source, el.sourceline)}: <urdfpost> tool_length={raw!r}: expected a "
            "finite length >= 0 m"
        )
    return value * M_TO_MM


def link_axes(doc: UrdfDoc, axis_names: tuple[str, ...]) -> dict[str, tuple[str, ...]]:
    """Per link: the machine axes between the root link and it, from the root.

    Parameters
    ----------
    doc : UrdfDoc
    axis_names : tuple of str
        The machine's axes (the moving joints of the chain).

    Returns
    -------
    dict of str to tuple of str
        For every link, in file order.
    """
    by_child = {j.child: j for j in doc.joints.values()}
    names = set(axis_names)
    paths = {}
    for link in doc.links:
        path, at, seen = [], link, {link}
        while at in by_child:
            j = by_child[at]
            if j.name in names:
                path.append(j.name)
            at = j.parent
            if at in seen:  # a loop off the chain (Pinocchio refuses the file)
                break
            seen.add(at)
        paths[link] = tuple(path[::-1])
    return paths
