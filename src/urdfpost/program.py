"""The controller-neutral NC program.

The pipeline builds a :class:`Program`; a dialect turns it into text and reads text back into
one. Positions are millimetres for linear axes and degrees for rotary axes whatever the program
units; the dialect converts to inch on writing and back on reading.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

REWIND_BEGIN = "urdfpost rewind at"
"""Start of the comment before a rewind's moves (lift, turn, return)."""

REWIND_END = "urdfpost rewind end"
"""The comment after them."""


@dataclass(frozen=True)
class Move:
    """One motion block.

    Attributes
    ----------
    rapid : bool
        Rapid traverse (G0 / FMAX) instead of feed.
    position : tuple of float
        One value per axis of :attr:`Program.axes`: mm for linear axes, degrees for rotary.
        In TCP programs X, Y, Z are the tool tip in the workpiece frame; otherwise they are the
        machine's linear axis positions.
    feed : float or None
        Feed in mm/min (None for rapids, or to keep the modal feed).
    cl_line : int or None
        Source line of the CL record the block ends on (None for inserted blocks).
    """

    rapid: bool
    position: tuple[float, ...]
    feed: float | None = None
    cl_line: int | None = None


@dataclass(frozen=True)
class ToolChange:
    """Tool change: ``number``, optional ``length`` (mm), ``diameter`` (mm), ``name``."""

    number: int
    length: float | None = None
    diameter: float | None = None
    name: str | None = None


@dataclass(frozen=True)
class Spindle:
    """Spindle on (``direction`` "cw" or "ccw", ``rpm``) or off (``direction`` "off")."""

    direction: str
    rpm: float = 0.0


@dataclass(frozen=True)
class Coolant:
    """Coolant ``mode``: "flood", "mist", "through", "air" or "off"."""

    mode: str


@dataclass(frozen=True)
class Comment:
    """A comment line (text without the control's comment delimiters)."""

    text: str


@dataclass(frozen=True)
class Insert:
    """Text passed through to the program verbatim (APT INSERT)."""

    text: str


@dataclass(frozen=True)
class Tcp:
    """Tool-centre-point control on (``on=True``) or off."""

    on: bool


@dataclass(frozen=True)
class Stop:
    """Program stop (M0), or optional stop (M1) when ``optional``."""

    optional: bool = False


@dataclass(frozen=True)
class Home:
    """Return to the machine's home (reference) position."""


Block = Move | ToolChange | Spindle | Coolant | Comment | Insert | Tcp | Stop | Home


@dataclass(frozen=True)
class Program:
    """A whole NC program, independent of the control.

    Attributes
    ----------
    name : str
        Program name (Heidenhain ``BEGIN PGM`` name, Fanuc comment, ...).
    axes : tuple of str
        NC addresses in output order, e.g. ``("X", "Y", "Z", "B", "C")``.
    rotary : frozenset of str
        Which of ``axes`` are rotary (values in degrees).
    units : str
        "mm" or "inch": the units the text is written in.
    tcp : bool
        Whether motion is written as tool tip in workpiece coordinates (the control does the
        kinematics) rather than machine axis positions.
    blocks : tuple of Block
        The program body, in order; start and end sequences are the dialect's.
    tool_length : float
        Tool length in mm the machine-coordinate positions were computed for.
    continuous : frozenset of str
        Rotary axes with unlimited travel (the dialect may write shortest-path codes for them).
    """

    name: str
    axes: tuple[str, ...]
    rotary: frozenset[str]
    units: str
    tcp: bool
    blocks: tuple[Block, ...]
    tool_length: float = 0.0
    continuous: frozenset[str] = frozenset()

    def moves(self) -> list[Move]:
        """The motion blocks, in order."""
        return [b for b in self.blocks if isinstance(b, Move)]


def rewind_moves(program: Program) -> np.ndarray:
    """Which moves belong to a rewind: those between the rewind comments.

    The comments survive writing and reading back (in any case), so a program read from text
    still tells its rewinds: their moves leave the CL path on purpose and are not compared
    with it.

    Returns
    -------
    ndarray, shape (N,), bool
        One entry per move of :meth:`Program.moves`.
    """
    out: list[bool] = []
    inside = False
    for b in program.blocks:
        if isinstance(b, Comment):
            text = b.text.strip().lower()
            if text.startswith(REWIND_BEGIN):
                inside = True
            elif text == REWIND_END:
                inside = False
        elif isinstance(b, Move):
            out.append(inside)
    return np.array(out, dtype=bool)
