"""The job setup: where the program zero (the ``workpiece`` link, the CL frame) sits on the machine.

A machine file places the program zero with the fixed joint whose child is ``workpiece`` (in
the shipped machines ``workpiece_mount``, on the rotary table or the fixture plate). That is
the default; a job gives its own with a :class:`Setup`, which :func:`apply_setup` writes into
that joint's ``<origin xyz rpy>`` in the parsed document before the machine is built
(:func:`place_workpiece`, called by :mod:`urdfpost.machine.load`), so that
every kinematic quantity (screws, pivots, the Pinocchio model) follows. The result is recorded
as a :class:`WorkpieceMount` on the machine (:attr:`Machine.mount
<urdfpost.machine.model.Machine>`).

Conventions
-----------
The *mount link* is the parent link of the workpiece joint. The setup's ``offset`` is the
program zero's origin in the mount link's frame, mm. Its ``rotation`` is an angle in degrees
about the mount link's +Z axis, right-handed (counter-clockwise seen from +Z looking down),
applied on top of the URDF's orientation of the workpiece::

    R_work_in_mount = Rz(rotation) @ R_urdf        R_urdf = Rz(yaw) Ry(pitch) Rx(roll)

It turns the orientation only: the origin is the offset (or the URDF's xyz) whatever the
rotation, so the part turns about the line along the mount link's Z through its zero.

On the shipped machines the mount link is the C table (``c_table``) of ``dmu50``,
``dmu50-nutating``, ``umc750``, ``monoblock`` and ``xyzac-trt``, whose Z is the table axis:
their C joints have ``<axis xyz="0 0 -1">`` (a positive C angle turns the table clockwise
seen from +Z), except ``xyzac-trt``'s ``0 0 1``. A setup rotation of +r degrees therefore
turns the part as C-r turns the table on the first four and as C+r on ``xyzac-trt``. On
``vf2-4axis`` the mount link is the A faceplate (``a_faceplate``), whose Z is vertical at A=0,
across the A axis (X); on ``gantry-ca`` it is the machine ``base`` (Z vertical).

This module is a leaf: the machine model records a :class:`WorkpieceMount`, the loader edits
the document with :func:`place_workpiece`; it imports neither.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from lxml import etree

from urdfpost.units import M_TO_MM

WORKPIECE = "workpiece"
"""The link of the program zero (the CL frame)."""


@dataclass(frozen=True)
class Setup:
    """Where a job puts the program zero on the machine (module docstring for the frames).

    Attributes
    ----------
    offset : (float, float, float) or None
        The program zero's origin in the frame of the link the workpiece is mounted on (the
        parent link of the ``workpiece`` joint), mm; None: the URDF's own.
    rotation : float
        Degrees about that link's +Z axis (right-handed), added to the URDF's orientation of
        the workpiece: ``R = Rz(rotation) @ R_urdf``. 0: the URDF's orientation.

    Examples
    --------
    >>> Setup((15.0, -10.0, 80.0), 90.0).is_default
    False
    >>> Setup.parse("15,-10,80,90")
    Setup(offset=(15.0, -10.0, 80.0), rotation=90.0)
    """

    offset: tuple[float, float, float] | None = None
    rotation: float = 0.0

    def __post_init__(self) -> None:
        if self.offset is not None:
            values = tuple(float(v) for v in self.offset)
            if len(values) != 3 or not all(math.isfinite(v) for v in values):
                raise ValueError(f"expected a setup offset of 3 finite numbers, got {self.offset}")
            object.__setattr__(self, "offset", values)
        rotation = float(self.rotation)
        if not math.isfinite(rotation):
            raise ValueError(f"expected a finite setup rotation in degrees, got {self.rotation}")
        object.__setattr__(self, "rotation", rotation)

    @property
    def is_default(self) -> bool:
        """Whether the setup leaves the URDF's placement as it is."""
        return self.offset is None and self.rotation == 0.0

    @classmethod
    def parse(cls, text: str) -> Setup:
        """Read ``"X,Y,Z"`` or ``"X,Y,Z,ROT"`` (numbers as given: the caller scales units).

        Raises
        ------
        ValueError
            With the expected form.
        """
        parts = [p.strip() for p in text.split(",")]
        try:
            values = [float(p) for p in parts]
        except ValueError:
            values = []
        if len(values) not in (3, 4) or not all(math.isfinite(v) for v in values):
            raise ValueError(
                f"expected X,Y,Z or X,Y,Z,ROT (finite numbers: the program zero on the mount "
                f"link, and degrees about its Z), got {text!r}"
            )
        return cls((values[0], values[1], values[2]), values[3] if len(values) == 4 else 0.0)

    def scaled(self, factor: float) -> Setup:
        """The setup with its offset multiplied by ``factor`` (mm per program unit)."""
        if self.offset is None:
            return self
        x, y, z = self.offset
        return Setup((x * factor, y * factor, z * factor), self.rotation)


@dataclass(frozen=True)
class WorkpieceMount:
    """Where the program zero sits on a loaded machine.

    Attributes
    ----------
    joint : str
        The fixed joint whose child is ``workpiece``.
    parent : str
        Its parent link (the mount link): the frame of ``origin``.
    origin : (float, float, float)
        The program zero in the mount link's frame, mm, as loaded (the setup's offset, else
        the URDF's).
    rpy : (float, float, float)
        The workpiece's orientation in the mount link's frame as loaded, URDF roll-pitch-yaw,
        rad.
    urdf_origin : (float, float, float)
        The URDF's own origin, mm.
    urdf_rpy : (float, float, float)
        The URDF's own orientation, rad.
    setup : Setup
        The setup the machine was loaded with (``Setup()``: the URDF's placement).
    """

    joint: str
    parent: str
    origin: tuple[float, float, float]
    rpy: tuple[float, float, float]
    urdf_origin: tuple[float, float, float]
    urdf_rpy: tuple[float, float, float]
    setup: Setup = Setup()

    @property
    def rotation(self) -> np.ndarray:
        """The workpiece frame's rotation in the mount link's frame, shape (3, 3)."""
        return matrix_from_rpy(np.array(self.rpy))

    def offset_for(self, shift: np.ndarray) -> tuple[float, float, float]:
        """The setup offset that moves the program zero by ``shift`` (3,), mm, mount frame."""
        x, y, z = (np.asarray(self.origin) + np.asarray(shift, dtype=float)).tolist()
        return (x, y, z)


def matrix_from_rpy(rpy: np.ndarray) -> np.ndarray:
    """URDF roll-pitch-yaw (fixed axes X, Y, Z) as a rotation matrix, shape (3, 3).

    ``Rz(yaw) @ Ry(pitch) @ Rx(roll)``, ``rpy`` shape (3,), rad.
    """
    import pinocchio as pin

    r, p, y = (float(v) for v in np.asarray(rpy, dtype=float).reshape(3))
    return np.asarray(pin.rpy.rpyToMatrix(r, p, y), dtype=float)


def rpy_from_matrix(rotation: np.ndarray) -> np.ndarray:
    """Roll-pitch-yaw of a rotation matrix (3, 3), rad, shape (3,): the inverse of
    :func:`matrix_from_rpy`, pitch in [-pi/2, pi/2] (Pinocchio's ``matrixToRpy``)."""
    import pinocchio as pin

    return np.asarray(pin.rpy.matrixToRpy(np.asarray(rotation, dtype=float)), dtype=float)


def rotation_about_z(degrees: float) -> np.ndarray:
    """Right-handed rotation by ``degrees`` about +Z, shape (3, 3)."""
    c, s = math.cos(math.radians(degrees)), math.sin(math.radians(degrees))
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _triple(values: np.ndarray) -> tuple[float, float, float]:
    x, y, z = (float(v) + 0.0 for v in values)  # (+ 0.0: no -0.0)
    return (x, y, z)


def _numbers(el: etree._Element | None, attr: str) -> np.ndarray:
    """An ``<origin>`` attribute as 3 numbers (0 0 0 when absent; checked by the parse)."""
    raw = None if el is None else el.get(attr)
    return np.zeros(3) if raw is None else np.array([float(v) for v in raw.split()])


def _format(values: np.ndarray) -> str:
    # repr: the shortest text that reads back to the same double (urdfdom reads it so too)
    return " ".join(repr(float(v) + 0.0) for v in values)  # (+ 0.0: no "-0.0")


def place_workpiece(joint: etree._Element, parent: str, setup: Setup) -> WorkpieceMount:
    """Write ``setup`` into the ``<origin>`` of the workpiece's fixed joint element.

    The element is changed in place (before the machine is built from its document); the
    default setup changes nothing.

    Parameters
    ----------
    joint : lxml.etree._Element
        The fixed ``<joint>`` whose child is ``workpiece``, already checked (its numbers read).
    parent : str
        Its parent link.
    setup : Setup

    Returns
    -------
    WorkpieceMount
    """
    origin = joint.find("origin")
    xyz_m, rpy = _numbers(origin, "xyz"), _numbers(origin, "rpy")
    new_xyz_m, new_rpy = xyz_m, rpy
    origin_mm = _triple(xyz_m * M_TO_MM)
    if setup.offset is not None:
        new_xyz_m, origin_mm = np.array(setup.offset) / M_TO_MM, setup.offset
    if setup.rotation != 0.0:
        new_rpy = rpy_from_matrix(rotation_about_z(setup.rotation) @ matrix_from_rpy(rpy))
    if not setup.is_default:
        if origin is None:
            origin = etree.SubElement(joint, "origin")
        origin.set("xyz", _format(new_xyz_m))
        origin.set("rpy", _format(new_rpy))
    return WorkpieceMount(
        joint=str(joint.get("name")),
        parent=parent,
        origin=origin_mm,
        rpy=_triple(new_rpy),
        urdf_origin=_triple(xyz_m * M_TO_MM),
        urdf_rpy=_triple(rpy),
        setup=setup,
    )
