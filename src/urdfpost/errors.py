"""Exceptions raised by urdfpost.

One base class, :class:`UrdfpostError`, and one subclass per kind of failure. Every message
names what was at fault (file, line, joint, link) and what was expected, so the command line can
print it as it is.
"""

from __future__ import annotations


class UrdfpostError(Exception):
    """Base class of every error urdfpost raises on purpose."""


class MachineDefinitionError(UrdfpostError):
    """A machine file (URDF) does not describe a machine urdfpost can post for."""


class CLDataError(UrdfpostError):
    """Cutter-location data that cannot be read.

    Parameters
    ----------
    path : str
        File the data came from (``"<string>"`` for text without a file).
    line : int
        1-based line number of the record at fault; 0 for the file as a whole (it cannot be
        read): the message then names the file alone.
    message : str
        What was found and what was expected.
    """

    def __init__(self, path: str, line: int, message: str) -> None:
        self.path = path
        self.line = line
        self.detail = message
        super().__init__(f"{path}:{line}: {message}" if line else f"{path}: {message}")

    def __reduce__(self) -> tuple[type, tuple[str, int, str]]:
        # rebuilt from the three parts (a verification worker sends its errors back)
        return type(self), (self.path, self.line, self.detail)


class UnreachableError(UrdfpostError):
    """A CL point that no inverse-kinematics branch reaches within the machine's travel."""


class LinearTravelError(UnreachableError):
    """A CL point whose rotary angles fit but whose linear axes leave their travel on every
    branch (a job setup may bring it in)."""


class GeometryError(UrdfpostError):
    """Collision geometry that cannot be built: a stock or mesh file that cannot be read, a
    ``<collision>`` element urdfpost does not understand, or tool sizes that make no sense."""


class CollisionError(UrdfpostError):
    """A move that collides: every branch at a CL point, or a move of the program, brings two
    bodies into contact (the message names the CL line and the bodies)."""


class ToleranceError(UrdfpostError):
    """A program whose verified deviation from the CL data exceeds the tolerance."""


class DialectError(UrdfpostError):
    """An unknown control, or an NC program that cannot be read back in its dialect."""


class ProgramParseError(DialectError):
    """An NC program line that cannot be read back.

    Parameters
    ----------
    path : str
        Program file name.
    line : int
        1-based line number.
    message : str
        What was found and what was expected.
    """

    def __init__(self, path: str, line: int, message: str) -> None:
        self.path = path
        self.line = line
        self.detail = message
        super().__init__(f"{path}:{line}: {message}")

    def __reduce__(self) -> tuple[type, tuple[str, int, str]]:
        # rebuilt from the three parts (a verification worker sends its errors back)
        return type(self), (self.path, self.line, self.detail)
