"""The machine model: immutable data read from a URDF file (see :mod:`urdfpost.machine.load`).

:class:`Machine` holds everything urdfpost derives from a machine file: the axes with their
screws in the workpiece frame at home (product of exponentials), travel limits and velocities,
the post settings of the ``<urdfpost>`` element, the Pinocchio model, which machine axes carry
each link, and the links' collision shapes as plain data.

Units inside urdfpost: millimetres and radians.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from urdfpost.errors import GeometryError
from urdfpost.machine.setup import WorkpieceMount
from urdfpost.machine.shapes import LinkShape
from urdfpost.units import M_TO_MM

NC_ADDRESSES = ("X", "Y", "Z", "A", "B", "C")
"""NC addresses, which are also the names of the moving joints, in joint-vector order."""

MOVING_TYPES = ("prismatic", "revolute", "continuous")
"""URDF joint types of a machine axis."""

ROTARY_TYPES = ("revolute", "continuous")
"""URDF joint types of a rotary axis."""


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
    units : str or None
        Program units when the post is not given any (``--units``): "mm" or "inch"; None when
        the machine file sets none (the program is then in the CL data's units).
    tool_length : float
        Default tool length, mm (0: the gauge point is programmed).
    prefer : tuple of (str, int) or None
        Preferred rotary branch: axis name and sign (+1 or -1) of its angle.
    home : dict of str to float
        Machine home position, mm / rad per axis (0 for axes not given).
    description : str
        One line describing the machine.
    strategy : str or None
        Default singularity strategy for this machine (``strategy`` attribute), as written: the
        name is checked against the strategies where the post options are resolved.
    where : str
        ``file:line`` of the ``<urdfpost>`` element, for messages about its settings (empty
        when the file has none).
    smoothing : bool
        Write the control's path smoothing (tolerance) cycle by default (``smoothing``
        attribute, "on" or "off"; default on).
    rollover : frozenset of str
        Continuous rotary axes the control rolls over (``rollover`` attribute, e.g. "C"):
        modulo 360 display, an absolute value reached the way the control's dialect says
        (shortest way, or the sign's direction on LinuxCNC); the others count turns.
    feed_mode : str or None
        Default feed mode of a post (``feed_mode`` attribute,
        :data:`urdfpost.program.JOB_FEED_MODES`); None: ``auto``.
    clamps : tuple of (str, int, int)
        Rotary axes with clamps (``clamp`` attribute, ``"B:M10/M11 C:M12/M13"``): per axis its
        name, the M code that clamps it and the one that releases it. The post clamps them for
        an operation in a tilted plane (:mod:`urdfpost.posting.planes`), the verifier refuses
        a move of a clamped axis.
    tilted_planes : bool
        Write operations at a fixed tilt in a tilted working plane by default
        (``tilted_planes`` attribute, "on" or "off"; default on;
        :mod:`urdfpost.posting.planes`).
    """

    controller: str = "heidenhain"
    units: str | None = None
    tool_length: float = 0.0
    prefer: tuple[str, int] | None = None
    home: dict[str, float] = field(default_factory=dict)
    description: str = ""
    strategy: str | None = None
    where: str = ""
    smoothing: bool = True
    rollover: frozenset[str] = frozenset()
    feed_mode: str | None = None
    tilted_planes: bool = True
    clamps: tuple[tuple[str, int, int], ...] = ()


@dataclass(frozen=True, eq=False)
class Machine:
    """An immutable machine model read from a URDF file.

    Build it with :func:`~urdfpost.machine.load_machine`. Joint vectors ``q`` used throughout
    urdfpost have one column per axis in :attr:`axis_names` order (X Y Z then A B C): mm for
    linear axes, rad for rotary ones.

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
        The Pinocchio model of every link and joint of the URDF (kinematics only: its inertias
        are zero, as urdfpost gives Pinocchio no ``<inertial>``; the shapes are in
        :attr:`shapes`).
    urdf_text : str
        The file's text (for views and for building variants of the machine).
    link_axes : dict of str to tuple of str
        Per link of the URDF: the machine axes between the root link and it, from the root.
        Links with equal axes never move relative to each other.
    shapes : tuple of LinkShape
        The ``<collision>`` shapes of every link, in file order (a property: see
        :attr:`shapes`).
    mount : WorkpieceMount or None
        Where the program zero (``workpiece``) sits on its parent link, and the job setup the
        machine was loaded with (:mod:`urdfpost.machine.setup`); None when the workpiece hangs
        on no fixed joint.
    """

    name: str
    path: str
    axes: tuple[Axis, ...]
    settings: Settings
    home_tool_in_work: np.ndarray
    model: object
    urdf_text: str
    link_axes: dict[str, tuple[str, ...]]
    # the links' collision shapes, or why they cannot be read (raised by ``shapes``)
    _shapes: tuple[LinkShape, ...] | GeometryError
    _pin_index: tuple[tuple[int, int], ...]  # per axis: (idx_q, nq) in the Pinocchio model
    _frame_ids: tuple[int, int]  # (workpiece, tool)
    mount: WorkpieceMount | None = None

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

    @property
    def shapes(self) -> tuple[LinkShape, ...]:
        """The ``<collision>`` shapes of every link, in file order.

        Read with the machine file, but a shape that cannot be read is reported only here, when
        the collision geometry is asked for: a machine whose shapes are broken (a mesh file
        that is not there) still posts without collision checks.

        Raises
        ------
        GeometryError
            Naming the file, line and link of the ``<collision>`` element at fault.
        """
        if isinstance(self._shapes, GeometryError):
            raise GeometryError(str(self._shapes)) from self._shapes.__cause__
        return self._shapes

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
