"""Loading a machine: finding its file by name, reading it and building the :class:`Machine`.

A machine file follows the convention in ``docs/machines.md``: a ``workpiece`` link (the CL
frame), a ``tool`` link (gauge point, +Z toward the spindle), and between them 3 prismatic and 1
or 2 rotary joints named with their NC addresses. Everything urdfpost needs is derived here at
load time, with no per-machine code:

- the Pinocchio model of the links and joints (forward kinematics and Jacobians for checking);
- the chain from workpiece to tool as screws in the workpiece frame at home (product of
  exponentials), which the vectorised forward and inverse kinematics use;
- travel limits, velocities and the post settings of the ``<urdfpost>`` extension element;
- the axes' acceleration and jerk limits of that element (:func:`axis_limits`), which URDF's
  ``<limit>`` has no attribute for;
- which axes carry each link, and the links' ``<collision>`` shapes (as data).

A job may put the program zero elsewhere than the file does (:class:`~urdfpost.machine.setup.
Setup`): the setup is written into the workpiece joint of the parsed document before any of
that is derived (:func:`~urdfpost.machine.setup.apply_setup`), so everything follows it.

URDF metres are converted to millimetres here. :mod:`urdfpost.machine.urdf` reads and checks the
file, :mod:`urdfpost.machine.shapes` its collision shapes, :mod:`urdfpost.machine.model` holds
the result.
"""

from __future__ import annotations

import functools
import importlib.util
import logging
import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from lxml import etree

from urdfpost.errors import GeometryError, MachineDefinitionError
from urdfpost.machine.model import NC_ADDRESSES, ROTARY_TYPES, Axis, Machine, Settings
from urdfpost.machine.setup import WORKPIECE, Setup, WorkpieceMount, place_workpiece
from urdfpost.machine.shapes import LinkShape, link_shapes
from urdfpost.machine.urdf import (
    JointChain,
    UrdfDoc,
    check_chain,
    check_tree,
    kinematic_urdf,
    link_axes,
    parse_settings,
    parse_urdf,
)
from urdfpost.units import M_TO_MM

log = logging.getLogger(__name__)


def machine_dirs() -> list[Path]:
    """Folders searched for machines by name: ``$URDFPOST_MACHINES`` then the shipped ones."""
    dirs = [Path(p) for p in os.environ.get("URDFPOST_MACHINES", "").split(os.pathsep) if p]
    dirs.append(shipped_machine_dir())
    return dirs


def shipped_machine_dir() -> Path:
    """Folder of the machines shipped with urdfpost."""
    spec = importlib.util.find_spec("urdfpost.robots")
    if spec is not None and spec.submodule_search_locations:
        return Path(next(iter(spec.submodule_search_locations)))
    return Path(__file__).resolve().parents[3] / "robots" / "urdf"  # source tree


def list_machines() -> dict[str, Path]:
    """Machines findable by name, ``{name: path}``, first folder wins."""
    found: dict[str, Path] = {}
    for d in machine_dirs():
        if d.is_dir():
            for p in sorted(d.glob("*.urdf")):
                found.setdefault(p.stem, p)
    return found


def resolve_machine(name_or_path: str | os.PathLike[str]) -> Path:
    """Path of a machine given by file path or by name.

    Raises
    ------
    MachineDefinitionError
        When neither a file nor a known machine name matches, listing the known names.
    """
    p = Path(name_or_path)
    if p.is_file():
        return p
    known = list_machines()
    if str(name_or_path) in known:
        return known[str(name_or_path)]
    raise MachineDefinitionError(
        f"{name_or_path}: no such machine file or shipped machine; known machines: "
        f"{', '.join(sorted(known)) or 'none'}"
    )


def load_machine(name_or_path: str | os.PathLike[str], setup: Setup | None = None) -> Machine:
    """Read and check a machine file.

    Parameters
    ----------
    name_or_path : str or path
        A URDF file, or the name of a machine in :func:`machine_dirs`.
    setup : Setup, optional
        Where the job puts the program zero (:mod:`urdfpost.machine.setup`); default the
        file's own placement.

    Returns
    -------
    Machine

    Raises
    ------
    MachineDefinitionError
        Naming the file and the joint or link at fault.
    """
    path = resolve_machine(name_or_path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as e:
        why = e.strerror if isinstance(e, OSError) and e.strerror else e
        raise MachineDefinitionError(f"{path}: cannot read: {why}") from e
    return machine_from_urdf(text, source=str(path), name=path.stem, setup=setup)


def machine_from_urdf(
    text: str, source: str = "<string>", name: str = "machine", setup: Setup | None = None
) -> Machine:
    """Build a :class:`Machine` from URDF text (see :func:`load_machine`).

    Parameters
    ----------
    text : str
        The URDF.
    source : str
        Where it came from, for messages and for finding mesh files.
    name : str
        Machine name.
    setup : Setup, optional
        Where the job puts the program zero; default the URDF's own placement.

    Returns
    -------
    Machine

    Raises
    ------
    MachineDefinitionError
        Naming the file and the joint or link at fault.
    """
    doc = parse_urdf(text, source)
    chain = check_chain(doc, source)
    check_tree(doc, source)
    settings = parse_settings(doc, source, chain.joints)
    _parse_axis_limits(doc.root, source, {j.name: j.type for j in chain.joints})
    mount = _mount(doc, source, setup or Setup())
    return _build(text, source, name, doc, chain, settings, mount)


def _mount(doc: UrdfDoc, source: str, setup: Setup) -> WorkpieceMount | None:
    """Apply the job setup to the workpiece's joint in ``doc`` (in place) and say where the
    program zero is; None when the workpiece hangs on no fixed joint (and no setup is asked).

    Raises
    ------
    MachineDefinitionError
        A setup asked of a machine whose workpiece is the root link or the child of a moving
        joint (the setup would move the axis, not the part).
    """
    spec = next((j for j in doc.joints.values() if j.child == WORKPIECE), None)
    if spec is not None and spec.type == "fixed":
        element = next(el for el in doc.root.iterfind("joint") if el.get("name") == spec.name)
        return place_workpiece(element, spec.parent, setup)
    if setup.is_default:
        return None
    why = (
        "the workpiece is the root link"
        if spec is None
        else f"the workpiece is the child of the {spec.type} joint {spec.name!r}"
    )
    where = source if spec is None else f"{source}:{spec.line}"
    raise MachineDefinitionError(
        f"{where}: cannot apply the job setup: {why}; a setup changes the fixed joint that "
        "mounts 'workpiece' on its parent link: add one (docs/machines.md)"
    )


def with_setup(machine: Machine, setup: Setup | None) -> Machine:
    """The same machine file loaded with another job setup (from :attr:`Machine.urdf_text`,
    which is the file's own text: the setup replaces the one ``machine`` was loaded with).

    Parameters
    ----------
    machine : Machine
    setup : Setup or None
        None or the default: the URDF's own placement.

    Returns
    -------
    Machine
    """
    return machine_from_urdf(machine.urdf_text, machine.path, machine.name, setup)


def _shapes_of(doc: UrdfDoc, source: str) -> tuple[LinkShape, ...] | GeometryError:
    """The links' collision shapes, or the error that says why they cannot be read.

    The error is kept, not raised: the machine still loads and posts without collision checks,
    and :attr:`Machine.shapes` raises it when collision geometry is asked for.
    """
    try:
        return link_shapes(doc.root, source)
    except GeometryError as e:
        log.debug("%s: collision shapes cannot be read: %s", source, e)
        # the tracebacks would hold on to the parse; the message and its cause are what count
        e.__traceback__ = None
        if e.__cause__ is not None:
            e.__cause__.__traceback__ = None
        return e


def _build(
    text: str,
    source: str,
    name: str,
    doc: UrdfDoc,
    chain: JointChain,
    settings: Settings,
    mount: WorkpieceMount | None = None,
) -> Machine:
    """The Machine of a checked document: Pinocchio model, axes and screws, home pose.

    Pinocchio reads only the links and joints (:func:`~urdfpost.machine.urdf.kinematic_urdf`),
    all checked already, so it neither fails nor prints on a file that passed the checks.
    """
    import pinocchio as pin

    try:
        model = pin.buildModelFromXML(kinematic_urdf(doc))
    except Exception as e:  # Pinocchio raises plain RuntimeError/ValueError; not expected here
        raise MachineDefinitionError(f"{source}: Pinocchio cannot read the URDF: {e}") from e
    data = model.createData()
    pin.forwardKinematics(model, data, pin.neutral(model))
    pin.updateFramePlacements(model, data)
    fw, ft = model.getFrameId("workpiece"), model.getFrameId("tool")
    o_m_w = data.oMf[fw]
    r_w = o_m_w.rotation
    home = (o_m_w.inverse() * data.oMf[ft]).homogeneous.copy()
    home[:3, 3] *= M_TO_MM

    axes: list[Axis] = []
    pin_index: dict[str, tuple[int, int]] = {}
    for i, j in enumerate(chain.joints):
        jid = model.getJointId(j.name)
        jm = model.joints[jid]
        pin_index[j.name] = (jm.idx_q, jm.nq)
        motion = np.asarray(data.joints[jid].S).reshape(6)  # local frame, linear first
        o_m_j = data.oMi[jid]
        sign = -1.0 if j.side == "table" else 1.0
        if j.type == "prismatic":
            direction = r_w.T @ (o_m_j.rotation @ motion[:3])
            screw = np.concatenate([np.zeros(3), sign * direction])
        else:
            w = r_w.T @ (o_m_j.rotation @ motion[3:])
            point = r_w.T @ (o_m_j.translation - o_m_w.translation) * M_TO_MM
            screw = sign * np.concatenate([w, -np.cross(w, point)])
        scale = 1.0 if j.type in ROTARY_TYPES else M_TO_MM
        lower, upper = (-np.inf, np.inf) if j.type == "continuous" else (j.lower, j.upper)
        axes.append(
            Axis(
                name=j.name,
                kind=j.type,
                lower=lower * scale,
                upper=upper * scale,
                velocity=(j.velocity * scale) if j.velocity is not None else np.inf,
                side=j.side,
                screw=screw,
                chain_index=i,
            )
        )
    axes.sort(key=lambda a: NC_ADDRESSES.index(a.name))
    for a in axes:
        a.screw.setflags(write=False)
    home.setflags(write=False)
    machine = Machine(
        name=name,
        path=source,
        axes=tuple(axes),
        settings=settings,
        home_tool_in_work=home,
        model=model,
        urdf_text=text,
        link_axes=link_axes(doc, tuple(a.name for a in axes)),
        _shapes=_shapes_of(doc, source),
        _pin_index=tuple(pin_index[a.name] for a in axes),
        _frame_ids=(fw, ft),
        mount=mount,
    )
    check_geometry(machine, source)
    log.debug("loaded machine %s (%s) from %s", name, machine.family, source)
    if mount is not None and not mount.setup.is_default:
        log.info(
            "%s: program zero at (%.3f, %.3f, %.3f) mm on link %s, turned %.3f deg about its Z "
            "(the job setup)",
            name,
            *mount.origin,
            mount.parent,
            mount.setup.rotation,
        )
    return machine


def check_geometry(machine: Machine, source: str) -> None:
    """Checks that need the numbers: independent linear axes, usable rotary axes.

    Raises
    ------
    MachineDefinitionError
        When two rotary axes are parallel, when the second rotary axis is parallel to the
        tool axis (it would not change the orientation), or when the linear axes do not span
        space.
    """
    lin = np.array([a.direction for a in machine.linear])
    if abs(np.linalg.det(lin)) < 1e-6:
        names = ", ".join(a.name for a in machine.linear)
        raise MachineDefinitionError(
            f"{source}: linear axes {names} do not span space (their directions are coplanar)"
        )
    rot = machine.rotary
    v0 = machine.home_tool_axis
    if len(rot) == 2:
        k1, k2 = rot[0].direction, rot[1].direction
        if np.linalg.norm(np.cross(k1, k2)) < 1e-6:
            raise MachineDefinitionError(
                f"{source}: rotary joints {rot[0].name!r} and {rot[1].name!r} are parallel: "
                "no five-axis orientation is possible"
            )
    last = rot[-1]
    if len(rot) == 2 and np.linalg.norm(np.cross(last.direction, v0)) < 1e-6:
        raise MachineDefinitionError(
            f"{source}: rotary joint {last.name!r} is parallel to the tool axis at home, so it "
            "cannot change the tool orientation"
        )


#: Attributes of ``<urdfpost><axis_limits .../>``: URDF units (m/s^2, m/s^3 for a linear axis,
#: rad/s^2, rad/s^3 for a rotary one).
AXIS_LIMIT_ATTRIBUTES = ("axis", "acceleration", "jerk")


@dataclass(frozen=True, eq=False)
class AxisLimits:
    """Velocity, acceleration and jerk limit of every axis of a machine.

    The velocity is the joint's URDF ``<limit velocity>``; acceleration and jerk come from the
    ``<axis_limits axis="C" acceleration="..." jerk="..."/>`` children of the ``<urdfpost>``
    element (URDF units: m and rad per second squared and cubed). A limit the file does not give
    is ``inf`` (no limit).

    Attributes
    ----------
    axes : tuple of str
        Axis names, in :attr:`Machine.axes` order (the columns of a joint vector).
    velocity : ndarray, shape (m,), mm/s or rad/s
    acceleration : ndarray, shape (m,), mm/s^2 or rad/s^2
    jerk : ndarray, shape (m,), mm/s^3 or rad/s^3
    """

    axes: tuple[str, ...]
    velocity: np.ndarray
    acceleration: np.ndarray
    jerk: np.ndarray

    def as_dict(self, rotary: frozenset[str] = frozenset()) -> dict[str, dict[str, float]]:
        """Per axis ``{"velocity", "acceleration", "jerk"}``; the axes in ``rotary`` in degrees
        (per second, squared, cubed), the others in mm."""
        out = {}
        for j, name in enumerate(self.axes):
            scale = math.degrees(1.0) if name in rotary else 1.0
            out[name] = {
                "velocity": float(self.velocity[j] * scale),
                "acceleration": float(self.acceleration[j] * scale),
                "jerk": float(self.jerk[j] * scale),
            }
        return out


def _parse_axis_limits(
    root: etree._Element, source: str, joint_types: dict[str, str]
) -> dict[str, tuple[float, float]]:
    """The ``<axis_limits>`` elements of ``<urdfpost>``: ``{axis: (acceleration, jerk)}`` in
    mm or rad per second squared and cubed (``inf`` where not given).

    Raises
    ------
    MachineDefinitionError
        At the element's line: an axis that is not a moving joint of the chain, an axis given
        twice, an unknown attribute, or a limit that is not a finite number > 0.
    """
    out: dict[str, tuple[float, float]] = {}
    settings = root.find("urdfpost")
    if settings is None:
        return out
    for el in settings.findall("axis_limits"):
        where = f"{source}:{el.sourceline}" if el.sourceline else source
        unknown = [k for k in el.keys() if k not in AXIS_LIMIT_ATTRIBUTES]
        if unknown:
            raise MachineDefinitionError(
                f"{where}: <axis_limits {unknown[0]}=...>: unknown attribute; expected "
                f"{', '.join(AXIS_LIMIT_ATTRIBUTES)}"
            )
        axis = el.get("axis")
        if axis not in joint_types:
            raise MachineDefinitionError(
                f"{where}: <axis_limits axis={axis!r}>: expected a moving joint of the chain "
                f"({' '.join(joint_types)})"
            )
        if axis in out:
            raise MachineDefinitionError(f"{where}: <axis_limits axis={axis!r}> given twice")
        scale = 1.0 if joint_types[axis] in ROTARY_TYPES else M_TO_MM
        values = []
        for attr in ("acceleration", "jerk"):
            raw = el.get(attr)
            if raw is None:
                values.append(math.inf)
                continue
            try:
                value = float(raw)
            except ValueError:
                value = math.nan
            if not (math.isfinite(value) and value > 0):
                unit = "rad/s" if scale == 1.0 else "m/s"
                power = "^2" if attr == "acceleration" else "^3"
                raise MachineDefinitionError(
                    f"{where}: <axis_limits axis={axis!r} {attr}={raw!r}>: expected a finite "
                    f"number > 0 ({unit}{power})"
                )
            values.append(value * scale)
        out[axis] = (values[0], values[1])
    return out


@functools.lru_cache(maxsize=32)
def _limits_of_text(
    text: str, source: str, joint_types: tuple[tuple[str, str], ...]
) -> dict[str, tuple[float, float]]:
    parser = etree.XMLParser(
        remove_comments=True, resolve_entities=False, load_dtd=False, no_network=True
    )
    root = etree.fromstring(text.encode("utf-8"), parser=parser)
    return _parse_axis_limits(root, source, dict(joint_types))


def axis_limits(machine: Machine) -> AxisLimits:
    """The velocity, acceleration and jerk limits of ``machine``'s axes (see :class:`AxisLimits`).

    Read from the machine's file (its text, checked when the machine was loaded).

    Examples
    --------
    >>> from urdfpost.machine import load_machine
    >>> limits = axis_limits(load_machine("dmu50"))
    >>> limits.axes, round(float(limits.acceleration[0]))
    (('X', 'Y', 'Z', 'B', 'C'), 5000)
    """
    types = tuple((a.name, a.kind) for a in machine.axes)
    given = _limits_of_text(machine.urdf_text, machine.path, types)
    names = machine.axis_names
    inf = (math.inf, math.inf)
    return AxisLimits(
        axes=names,
        velocity=np.array([a.velocity for a in machine.axes], dtype=float),
        acceleration=np.array([given.get(n, inf)[0] for n in names], dtype=float),
        jerk=np.array([given.get(n, inf)[1] for n in names], dtype=float),
    )
