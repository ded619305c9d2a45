"""The machine: a URDF file read once into an immutable model.

A machine file follows the convention in ``docs/machines.md``: a ``workpiece`` link (the CL
frame), a ``tool`` link (gauge point, +Z toward the spindle), and between them 3 prismatic and 1
or 2 rotary joints named with their NC addresses. Everything urdfpost needs is derived here at
load time, with no per-machine code:

- the Pinocchio model (forward kinematics and Jacobians for checking);
- the chain from workpiece to tool as screws in the workpiece frame at home (product of
  exponentials), which the vectorised forward and inverse kinematics use;
- travel limits, velocities and the post settings of the ``<urdfpost>`` extension element.

Units inside urdfpost: millimetres and radians. URDF metres are converted here.
"""

from __future__ import annotations

import importlib.util
import logging
import os
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from urdfpost.errors import MachineDefinitionError
from urdfpost.units import M_TO_MM

if TYPE_CHECKING:
    from urdfpost.machine.urdf import Chain

log = logging.getLogger(__name__)

NC_ADDRESSES = ("X", "Y", "Z", "A", "B", "C")
MOVING_TYPES = ("prismatic", "revolute", "continuous")
ROTARY_TYPES = ("revolute", "continuous")

CONTROLLERS = ("heidenhain", "siemens", "fanuc", "linuxcnc")


@dataclass(frozen=True)
class Axis:
    """One moving joint of the chain between workpiece and tool.

    Attributes
    ----------
    name : str
        NC address (``X``..``C``), which is also the URDF joint name.
    kind : str
        "prismatic", "revolute" or "continuous".
    lower, upper : float
        Travel, mm or rad (``-inf``/``inf`` for continuous joints).
    velocity : float
        Maximum velocity, mm/s or rad/s (``inf`` when the URDF gives none).
    side : str
        "table" when the joint moves the workpiece (it lies between the workpiece and the
        common ancestor of workpiece and tool), "head" when it moves the tool.
    screw : ndarray, shape (6,)
        Unit screw (angular part first: omega, v) in the workpiece frame at home, signed so
        that a positive joint value moves the tool positively relative to the workpiece.
        Linear part in mm.
    chain_index : int
        Position along the chain counted from the workpiece.
    """

    name: str
    kind: str
    lower: float
    upper: float
    velocity: float
    side: str
    screw: np.ndarray
    chain_index: int

    @property
    def rotary(self) -> bool:
        """Whether the axis rotates."""
        return self.kind in ROTARY_TYPES

    @property
    def continuous(self) -> bool:
        """Whether the axis has unlimited travel."""
        return self.kind == "continuous"

    @property
    def direction(self) -> np.ndarray:
        """Axis direction in the workpiece frame at home, shape (3,)."""
        return self.screw[:3] if self.rotary else self.screw[3:]

    @property
    def pivot(self) -> np.ndarray:
        """Point of a rotary axis closest to the workpiece origin, shape (3,), mm."""
        w, v = self.screw[:3], self.screw[3:]
        return np.cross(w, v)


@dataclass(frozen=True)
class Settings:
    """Post settings from the ``<urdfpost>`` extension element, each with its default.

    Attributes
    ----------
    controller : str
        Default control dialect ("heidenhain").
    units : str
        Default program units when the CL data does not say ("mm").
    tool_length : float
        Default tool length, mm (0: the gauge point is programmed).
    prefer : tuple of (str, int) or None
        Preferred rotary branch: axis name and sign (+1 or -1) of its angle.
    home : dict of str to float
        Machine home position, mm / rad per axis (0 for axes not given).
    description : str
        One line describing the machine.
    strategy : str or None
        Default singularity strategy for this machine (``strategy`` attribute).
    """

    controller: str = "heidenhain"
    units: str = "mm"
    tool_length: float = 0.0
    prefer: tuple[str, int] | None = None
    home: dict[str, float] = field(default_factory=dict)
    description: str = ""
    strategy: str | None = None


@dataclass(frozen=True, eq=False)
class Machine:
    """An immutable machine model read from a URDF file.

    Build it with :func:`load_machine`. Joint vectors ``q`` used throughout urdfpost have one
    column per axis in :attr:`axis_names` order (X Y Z then A B C): mm for linear axes, rad for
    rotary ones.

    Attributes
    ----------
    name : str
        Machine name (the file stem).
    path : str
        File it was read from.
    axes : tuple of Axis
        The moving joints, in NC order (X, Y, Z, A, B, C).
    settings : Settings
        Post settings.
    home_tool_in_work : ndarray, shape (4, 4)
        Pose of the tool frame in the workpiece frame at q = 0, translation in mm.
    model : pinocchio.Model
        The Pinocchio model of the whole URDF.
    urdf_text : str
        The file's text (for collision geometry and views).
    """

    name: str
    path: str
    axes: tuple[Axis, ...]
    settings: Settings
    home_tool_in_work: np.ndarray
    model: object
    urdf_text: str
    _pin_index: tuple[tuple[int, int], ...]  # per axis: (idx_q, nq) in the Pinocchio model
    _frame_ids: tuple[int, int]  # (workpiece, tool)

    # -- description --------------------------------------------------------------------

    @property
    def axis_names(self) -> tuple[str, ...]:
        """NC addresses in joint-vector order."""
        return tuple(a.name for a in self.axes)

    @property
    def linear(self) -> tuple[Axis, ...]:
        """The three prismatic axes, in NC order."""
        return tuple(a for a in self.axes if not a.rotary)

    @property
    def rotary(self) -> tuple[Axis, ...]:
        """The rotary axes ordered along the chain from the workpiece (first = nearest)."""
        return tuple(sorted((a for a in self.axes if a.rotary), key=lambda a: a.chain_index))

    @property
    def rotary_columns(self) -> tuple[int, ...]:
        """Columns of the rotary axes in ``q``, in :attr:`rotary` (chain) order."""
        return tuple(self.axis_names.index(a.name) for a in self.rotary)

    @property
    def linear_columns(self) -> tuple[int, ...]:
        """Columns of the linear axes in ``q``."""
        return tuple(i for i, a in enumerate(self.axes) if not a.rotary)

    @property
    def family(self) -> str:
        """Kinematic family: "table-table", "head-head", "head-table" or "4-axis"."""
        sides = [a.side for a in self.rotary]
        if len(sides) == 1:
            return "4-axis"
        if sides == ["table", "table"]:
            return "table-table"
        if sides == ["head", "head"]:
            return "head-head"
        return "head-table"

    @property
    def lower(self) -> np.ndarray:
        """Lower travel per axis, shape (m,), mm / rad."""
        return np.array([a.lower for a in self.axes])

    @property
    def upper(self) -> np.ndarray:
        """Upper travel per axis, shape (m,), mm / rad."""
        return np.array([a.upper for a in self.axes])

    @property
    def home(self) -> np.ndarray:
        """Home position, shape (m,), mm / rad."""
        return np.array([self.settings.home.get(a.name, 0.0) for a in self.axes])

    @property
    def home_tool_axis(self) -> np.ndarray:
        """Tool axis in the workpiece frame at q = 0, shape (3,)."""
        return self.home_tool_in_work[:3, 2].copy()

    def axis(self, name: str) -> Axis:
        """The axis with NC address ``name``."""
        for a in self.axes:
            if a.name == name:
                return a
        raise KeyError(f"machine {self.name} has no axis {name}; it has {self.axis_names}")

    @cached_property
    def _pin_data(self) -> object:
        return self.model.createData()  # type: ignore[attr-defined]

    def pin_configuration(self, q: np.ndarray) -> np.ndarray:
        """Pinocchio configuration vector for one joint vector.

        Parameters
        ----------
        q : ndarray, shape (m,)
            Joint values, mm / rad.

        Returns
        -------
        ndarray, shape (model.nq,)
            Metres / radians; continuous joints as (cos, sin); joints off the chain at 0.
        """
        import pinocchio as pin

        qp = pin.neutral(self.model)
        for (idx, nq), a, value in zip(self._pin_index, self.axes, q, strict=True):
            if nq == 2:
                qp[idx], qp[idx + 1] = np.cos(value), np.sin(value)
            elif a.rotary:
                qp[idx] = value
            else:
                qp[idx] = value / M_TO_MM
        return qp


# -- loading ------------------------------------------------------------------------------


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


def load_machine(name_or_path: str | os.PathLike[str]) -> Machine:
    """Read and check a machine file.

    Parameters
    ----------
    name_or_path : str or path
        A URDF file, or the name of a machine in :func:`machine_dirs`.

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
        raise MachineDefinitionError(f"{path}: cannot read: {e}") from e
    return machine_from_urdf(text, source=str(path), name=path.stem)


def machine_from_urdf(text: str, source: str = "<string>", name: str = "machine") -> Machine:
    """Build a :class:`Machine` from URDF text (see :func:`load_machine`)."""
    from urdfpost.machine import urdf

    doc = urdf.parse_urdf(text, source)
    chain = urdf.check_chain(doc, source)
    settings = urdf.parse_settings(doc, source, chain.joints)
    return _build(text, source, name, chain, settings)


def _build(text: str, source: str, name: str, chain: Chain, settings: Settings) -> Machine:
    import pinocchio as pin

    from urdfpost.machine import urdf

    try:
        model = pin.buildModelFromXML(text)
    except Exception as e:  # Pinocchio raises plain RuntimeError/ValueError
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
        _pin_index=tuple(pin_index[a.name] for a in axes),
        _frame_ids=(fw, ft),
    )
    urdf.check_geometry(machine, source)
    log.debug("loaded machine %s (%s) from %s", name, machine.family, source)
    return machine
