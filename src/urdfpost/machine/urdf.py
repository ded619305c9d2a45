"""Reading and checking a machine URDF against the urdfpost convention.

Validation happens here, once, before Pinocchio sees the file, so every message can name the
file, the line and the joint or link at fault. The functions parse the text
(:func:`parse_urdf`), find the moving joints between ``workpiece`` and ``tool``
(:func:`check_chain`), read the ``<urdfpost>`` settings (:func:`parse_settings`) and which axes
carry each link (:func:`link_axes`); :mod:`urdfpost.machine.load` builds the
:class:`~urdfpost.machine.model.Machine` from them.

This module is a leaf: it imports from urdfpost only the errors, the units, the machine's data
classes and the dialect registry (for the controller names).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from lxml import etree

from urdfpost.dialects import DIALECTS
from urdfpost.errors import MachineDefinitionError
from urdfpost.machine.model import NC_ADDRESSES, Settings
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


def _float(source: str, el: etree._Element, attr: str, default: float | None) -> float | None:
    raw = el.get(attr)
    if raw is None:
        return default
    try:
        return float(raw)
    except ValueError as e:
        raise MachineDefinitionError(
            f"{_where(source, el.sourceline)}: <{el.tag}> {attr}={raw!r}: expected a number"
        ) from e


def parse_urdf(text: str, source: str) -> UrdfDoc:
    """Parse URDF text into links and joints, checking well-formedness.

    Raises
    ------
    MachineDefinitionError
        For broken XML, a root that is not ``<robot>``, links or joints without names, joints
        without parent or child, axes that are not three numbers.
    """
    try:
        root = etree.fromstring(text.encode("utf-8"), parser=etree.XMLParser(remove_comments=True))
    except etree.XMLSyntaxError as e:
        raise MachineDefinitionError(f"{source}: not a URDF: broken XML: {e}") from e
    if root.tag != "robot":
        raise MachineDefinitionError(
            f"{_where(source, root.sourceline)}: not a URDF: expected root element <robot>, "
            f"got <{root.tag}>"
        )
    links: dict[str, int] = {}
    for el in root.findall("link"):
        name = el.get("name")
        if not name:
            raise MachineDefinitionError(f"{_where(source, el.sourceline)}: <link> without name")
        links[name] = el.sourceline
    joints: dict[str, JointSpec] = {}
    for el in root.findall("joint"):
        spec = _joint_spec(source, el)
        if spec.name in joints:
            raise MachineDefinitionError(
                f"{_where(source, spec.line)}: joint {spec.name!r} defined twice (a moving "
                "joint's name is its NC address, so two joints cannot share one)"
            )
        joints[spec.name] = spec
    return UrdfDoc(root=root, links=links, joints=joints)


def _joint_spec(source: str, el: etree._Element) -> JointSpec:
    where = _where(source, el.sourceline)
    name = el.get("name")
    jtype = el.get("type")
    if not name or not jtype:
        raise MachineDefinitionError(f"{where}: <joint> needs name and type attributes")
    parent, child = el.find("parent"), el.find("child")
    if parent is None or child is None or not parent.get("link") or not child.get("link"):
        raise MachineDefinitionError(
            f"{where}: joint {name!r} needs <parent link> and <child link>"
        )
    axis_el = el.find("axis")
    axis = (1.0, 0.0, 0.0)
    if axis_el is not None:
        parts = (axis_el.get("xyz") or "").split()
        try:
            axis = tuple(float(p) for p in parts)  # type: ignore[assignment]
        except ValueError as e:
            raise MachineDefinitionError(
                f"{where}: joint {name!r}: axis xyz={axis_el.get('xyz')!r}: expected 3 numbers"
            ) from e
        if len(axis) != 3:
            raise MachineDefinitionError(
                f"{where}: joint {name!r}: axis xyz={axis_el.get('xyz')!r}: expected 3 numbers"
            )
    limit = el.find("limit")
    lower = upper = 0.0
    velocity = None
    if limit is not None:
        lower = _float(source, limit, "lower", 0.0)  # type: ignore[assignment]
        upper = _float(source, limit, "upper", 0.0)  # type: ignore[assignment]
        velocity = _float(source, limit, "velocity", None)
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
        Missing links, floating/planar joints on the chain, wrong joint count, bad names,
        duplicate NC addresses, zero axes, inverted limits.
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
        if j.type not in ("fixed", "prismatic", "revolute", "continuous"):
            raise MachineDefinitionError(
                f"{_where(source, j.line)}: joint {j.name!r} has unknown type {j.type!r}"
            )
    moving = [j for j in chain if j.type != "fixed"]
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
        if float(np.linalg.norm(j.axis)) < 1e-9:
            raise MachineDefinitionError(
                f"{where}: joint {j.name!r}: zero axis vector {j.axis}: expected a direction"
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


def parse_settings(doc: UrdfDoc, source: str, joints: tuple[JointSpec, ...]) -> Settings:
    """Read the ``<urdfpost>`` extension element (all settings optional).

    Raises
    ------
    MachineDefinitionError
        For an unknown controller (one not in :data:`urdfpost.dialects.DIALECTS`) or units, a
        preference or home naming a missing axis, or a value that is not a number. The
        ``strategy`` name is not checked here: :attr:`Settings.where` lets the post report an
        unknown one against the file.
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
    units = el.get("units", "mm")
    if units not in ("mm", "inch"):
        raise MachineDefinitionError(f"{where}: <urdfpost units={units!r}>: expected mm or inch")
    tool_length = (_float(source, el, "tool_length", 0.0) or 0.0) * M_TO_MM
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
            value = _float(source, home_el, key, 0.0) or 0.0
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
    )


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
