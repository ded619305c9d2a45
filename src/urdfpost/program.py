"""The controller-neutral NC program.

The pipeline builds a :class:`Program`; a dialect turns it into text and reads text back into
one. Positions are millimetres for linear axes and degrees for rotary axes whatever the program
units; the dialect converts to inch on writing and back on reading.

Motion blocks are many and the other blocks few: a program holds its runs of moves as
:class:`MoveTable` arrays between the other blocks (:attr:`Program.parts`), and makes
:class:`Move` objects only for callers that iterate :attr:`Program.blocks` or ask for
:meth:`Program.moves`. Code that handles whole programs reads the arrays
(:meth:`Program.move_table`).

Examples
--------
>>> import numpy as np
>>> table = MoveTable(
...     position=np.array([[0.0, 0.0], [1.0, 2.0]]),
...     rapid=np.array([True, False]),
...     feed=np.array([np.nan, 500.0]),
...     cl_line=np.array([-1, 12]),
... )
>>> program = Program("P", ("X", "Y"), frozenset(), "mm", False, (ToolChange(1), table))
>>> len(program.blocks), program.blocks[2]
(3, Move(rapid=False, position=(1.0, 2.0), feed=500.0, cl_line=12))
>>> program.move_table().position.shape
(2, 2)
"""

from __future__ import annotations

import itertools
import math
import operator
import warnings
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass, field, replace
from typing import Any, cast, overload

import numpy as np

REWIND_BEGIN = "urdfpost rewind at"
"""Start of the comment before a rewind's moves (lift, turn, return)."""

REWIND_END = "urdfpost rewind end"
"""The comment after them."""

FEED_PER_MINUTE = "per-minute"
"""Feed mode of a program whose F words are feeds per minute (G94): :attr:`Move.feed` in mm/min."""

FEED_INVERSE_TIME = "inverse-time"
"""Feed mode of a program whose F words are inverse times (G93): :attr:`Move.feed` is one over
the block's time in minutes (1/min), whatever the program units."""

FEED_MODES = (FEED_PER_MINUTE, FEED_INVERSE_TIME)
"""The feed modes of a :class:`Program`."""

JOB_FEED_MODES = ("auto", "tip", "inverse-time", "per-block")
"""How a post makes the F words (``--feed-mode``, the machine file's ``feed_mode``; see
:mod:`urdfpost.posting.feeds`)."""


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
        Feed in mm/min (None for rapids, or to keep the modal feed); in a program whose
        :attr:`Program.feed_mode` is inverse time, one over the block's time, 1/min.
    cl_line : int or None
        Source line of the CL record the block ends on (None for inserted blocks).
    """

    rapid: bool
    position: tuple[float, ...]
    feed: float | None = None
    cl_line: int | None = None


@dataclass(frozen=True)
class ToolChange:
    """Tool change: ``number``, optional ``length`` (mm), ``diameter`` (mm), ``name``, and
    ``offset``: the tool length offset register the program selects for the tool (the CL's
    ``LOADTL ADJUST``, the ``H`` word of the TCP switch); None: the tool number."""

    number: int
    length: float | None = None
    diameter: float | None = None
    name: str | None = None
    offset: int | None = None


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
    """Tool-centre-point control on (``on=True``) or off.

    ``offset``, in a program read from text: the tool length offset register the switch
    selects (the ``H`` word of ``G43.4 H7`` / ``G43 H7``; on controls without such registers,
    Heidenhain and Siemens, the tool called), None where the text gives none. The program a
    post builds leaves it None (the writer writes the tool change's register); not compared.
    """

    on: bool
    offset: int | None = field(default=None, compare=False)


@dataclass(frozen=True)
class Stop:
    """Program stop (M0), or optional stop (M1) when ``optional``."""

    optional: bool = False


@dataclass(frozen=True)
class Home:
    """Return to the machine's home (reference) position."""


@dataclass(frozen=True)
class MachineMove:
    """A rapid in machine coordinates (``G53 G0``, ``SUPA G0``, ``L ... M91``).

    Work offsets and TCP do not apply to it: the values are machine axis positions, the ones
    the machine's URDF joints give. Used for the retract before a rotary move and at a tool
    change.

    Attributes
    ----------
    axes : tuple of str
        The axes that move (the others keep their place).
    values : tuple of float
        One per axis: mm for linear axes, degrees for rotary.
    """

    axes: tuple[str, ...]
    values: tuple[float, ...]


@dataclass(frozen=True)
class WorkOffset:
    """Selection of the work offset the program's coordinates are measured from.

    ``number`` 1 is the first offset of the control (G54, Heidenhain preset 1), 2 the second
    (G55), and so on.
    """

    number: int


CYCLE_KINDS = ("drill", "deep", "chipbreak", "tap", "bore")
"""The canned cycles a :class:`Cycle` can be: drilling (with a dwell at the bottom when
``dwell`` > 0), deep-hole drilling with full retracts, drilling with chip breaking, tapping,
boring (feed in, feed out)."""

CYCLE_BEGIN = "urdfpost cycle"
"""Start of the comment before the moves of an expanded cycle (:func:`expand_cycles`)."""

CYCLE_END = "urdfpost cycle end"
"""The comment after them."""

CHIP_BREAK_RETRACT = 0.254
"""mm. How far a chip-breaking peck backs off in the expanded motion: LinuxCNC's G73 (0.010
inch; its interpreter's canon output shows it). The other controls' distance is a machine
parameter or a cycle parameter (Fanuc parameter 5114, Heidenhain Q256, which the post writes
as this): verification checks the depth and the hole axis, not this distance."""

PECK_GAP = 0.254
"""mm. How far above the last peck's depth a deep-hole peck comes back down at rapid before
it feeds again: LinuxCNC's G83 (0.010 inch); Fanuc's is parameter 5115, Heidenhain's and
Siemens' the cycle's own (the expansion's model, as :data:`CHIP_BREAK_RETRACT`)."""


@dataclass(frozen=True)
class Cycle:
    """A canned drilling cycle and the holes it runs at.

    The holes are drilled along the program's Z axis, downwards: the post writes a cycle only
    where the tool axis is the program's +Z (a TCP program with the tool axis along the
    workpiece Z, or a machine-coordinate program whose Z axis moves the tool along its axis);
    other holes are written as their motion (:func:`expand_cycle`). Before the block the tool
    stands above the first hole at the retract height (a rapid :class:`Move`), and after it
    above the last.

    Attributes
    ----------
    kind : str
        One of :data:`CYCLE_KINDS`.
    depth : float, mm
        From the hole top down to its bottom (> 0).
    feed : float, mm/min
        Of the drilling move (tapping: the pitch times the spindle speed).
    clearance : float, mm
        Above the hole top, where the feed starts (the R plane, Q200, SDIS).
    retract : float, mm
        Above the hole top, where the tool goes between holes (the initial plane of G98,
        Q204, RTP); at least ``clearance``.
    holes : tuple of tuple of float
        Per hole, the position of its top: one value per axis of :attr:`Program.axes`
        (mm, degrees); all holes of a block have the same Z and rotary positions.
    step : float, mm
        Peck depth of "deep" and "chipbreak" (0 for the others).
    dwell : float, s
        Dwell at the bottom (0: none).
    cl_lines : tuple of int or None
        The CL line of each hole (None in a program read from text); not compared.
    up : tuple of float or None
        A tilted hole (its tool axis off the program's Z): per program axis, its motion for
        1 mm up the hole's axis (mm, degrees), the hole tops in the program's own coordinates.
        Such a cycle is only a step of a post: it is written in a tilted working plane
        (:mod:`urdfpost.posting.planes`, which gives it plane coordinates and None here) or as
        its motion (:func:`expand_cycle`), never as it is. None: along the program's +Z.
    """

    kind: str
    depth: float
    feed: float
    clearance: float
    retract: float
    holes: tuple[tuple[float, ...], ...]
    step: float = 0.0
    dwell: float = 0.0
    cl_lines: tuple[int | None, ...] = field(default=(), compare=False)
    up: tuple[float, ...] | None = None

    def __post_init__(self) -> None:
        if self.kind not in CYCLE_KINDS:
            raise ValueError(f"cycle kind {self.kind!r}; expected one of {', '.join(CYCLE_KINDS)}")
        if not self.holes:
            raise ValueError("a cycle without holes")


@dataclass(frozen=True)
class Dwell:
    """A dwell of ``seconds`` (G4, Heidenhain cycle 9)."""

    seconds: float


@dataclass(frozen=True)
class Smoothing:
    """The control's path smoothing (its tolerance cycle) switched on or, ``on`` False, off.

    Attributes
    ----------
    on : bool
        Smoothing on (Heidenhain ``CYCL DEF 32`` with a T, Siemens ``CYCLE832`` with a
        tolerance, Fanuc ``G05.1 Q1``, LinuxCNC ``G64 P``); off: the control's own default
        path mode again.
    tolerance : float or None
        Path tolerance, mm; None where the program gives none (Fanuc AI contour control takes
        its tolerance from the control's parameters), or when off.
    angle : float or None
        Tolerance of the rotary axes, degrees, where the control takes one (Heidenhain
        ``TA``, Siemens' orientation tolerance); None otherwise.
    """

    on: bool
    tolerance: float | None = None
    angle: float | None = None


@dataclass(frozen=True)
class Clamp:
    """A rotary axis clamped (``on``) or released: the machine's M code for it
    (:attr:`~urdfpost.machine.model.Settings.clamps`, written by the dialect made for the
    machine, :meth:`~urdfpost.dialects.dialect.Dialect.with_clamps`). A clamped axis does not
    move."""

    axis: str
    on: bool


PLANE_CONVENTIONS = ("xyz", "XYZ", "ZXZ")
"""How a :class:`TiltedPlane`'s three angles give its frame, as SciPy's
``Rotation.from_euler`` sequences: "xyz" about the fixed X, Y and Z axes in turn (Heidenhain
``PLANE SPATIAL SPA SPB SPC``), "XYZ" about X, then the turned Y, then the twice-turned Z
(Siemens ``CYCLE800`` axis by axis, mode 57), "ZXZ" the Euler angles about Z, the turned X
and the twice-turned Z (Fanuc ``G68.2 I J K``)."""


@dataclass(frozen=True)
class TiltedPlane:
    """A tilted working plane (3+2 machining) switched on or, ``angles`` None, off.

    While it is on, a program's X, Y and Z are coordinates in the plane's frame, whose origin
    is the program zero and whose axes are the columns of :meth:`frame` in the workpiece
    frame; its Z is the tool axis. They give the *control point*: the tool tip in a TCP
    program (whose length the control knows), the gauge point in machine coordinates (whose
    tool length the control does not add: its table length is 0). The rotary axes stand where
    the blocks before the plane put them (the plane is switched on with them there: Heidenhain
    ``STAY``); the plane's Z is their tool axis. Off: the program's own frame again, the rotary
    axes staying where they are (``PLANE RESET STAY``, ``CYCLE800()``, ``G69``).

    Attributes
    ----------
    angles : tuple of float or None
        The three angles, degrees, as written (rounded to the control's format).
    convention : str
        One of :data:`PLANE_CONVENTIONS`.
    offset : int or None
        In a program read back, the tool length offset register of the length the control
        adds along the plane's Z (as :attr:`Tcp.offset`); not compared.
    """

    angles: tuple[float, float, float] | None
    convention: str = "xyz"
    offset: int | None = field(default=None, compare=False)

    def __post_init__(self) -> None:
        if self.convention not in PLANE_CONVENTIONS:
            raise ValueError(
                f"plane convention {self.convention!r}; expected one of "
                f"{', '.join(PLANE_CONVENTIONS)}"
            )

    def frame(self) -> np.ndarray:
        """The plane's axes in the workpiece frame, as columns, shape (3, 3) (identity off)."""
        if self.angles is None:
            return np.eye(3)
        from scipy.spatial.transform import Rotation

        return Rotation.from_euler(self.convention, self.angles, degrees=True).as_matrix()

    @classmethod
    def of(cls, frame: np.ndarray, convention: str, decimals: int) -> TiltedPlane:
        """The plane nearest ``frame`` (shape (3, 3), columns the plane's axes) whose angles,
        in ``convention``, are rounded to ``decimals`` places of a degree."""
        from scipy.spatial.transform import Rotation

        with warnings.catch_warnings():  # (gimbal lock: SciPy sets the third angle to 0)
            warnings.simplefilter("ignore", UserWarning)
            angles = Rotation.from_matrix(frame).as_euler(convention, degrees=True)
        a, b, c = (round(float(v), decimals) + 0.0 for v in angles)
        return cls((a, b, c), convention)


#: Planes an :class:`Arc` lies in, with the axis of its normal (G17 XY: Z, G18 ZX: Y, G19 YZ:
#: X) and its two axes in the order the angle turns from the first to the second
#: counter-clockwise seen from the normal's positive end.
ARC_PLANES: dict[str, tuple[str, str, str]] = {
    "XY": ("X", "Y", "Z"),
    "ZX": ("Z", "X", "Y"),
    "YZ": ("Y", "Z", "X"),
}


@dataclass(frozen=True)
class Arc:
    """A circular (or helical) feed move of the linear axes (G2/G3, Heidenhain C).

    The arc runs from where the axes stand (the end of the block before) to ``position``,
    turning about the line through ``centre`` along the normal of ``plane``; a change of the
    normal's axis between start and end makes a helix (that axis moves linearly with the
    angle). The rotary axes do not move on an arc. Positions are those of :class:`Move`: in
    TCP programs X, Y, Z are the tool tip in the workpiece frame, otherwise the machine's
    linear axes.

    Attributes
    ----------
    position : tuple of float
        End, one value per axis of :attr:`Program.axes` (mm, degrees).
    centre : tuple of 3 floats, mm
        X, Y, Z of the centre; the value along the plane's normal is the start's.
    plane : str
        "XY" (G17), "ZX" (G18) or "YZ" (G19): a key of :data:`ARC_PLANES`.
    clockwise : bool
        Clockwise seen from the positive end of the plane's normal (G2); else G3.
    feed : float or None
        mm/min (None keeps the modal feed).
    cl_line : int or None
        The CIRCLE record's line.
    """

    position: tuple[float, ...]
    centre: tuple[float, float, float]
    plane: str
    clockwise: bool
    feed: float | None = None
    cl_line: int | None = None

    def sweep(self, start: Sequence[float], axes: Sequence[str]) -> float:
        """Angle turned from ``start`` (X, Y, Z, mm) to the end (rad, in (0, 2 pi]).

        An end at the start's angle is a full turn. ``axes``: the program's.
        """
        first, second, _ = ARC_PLANES[self.plane]
        i, j = "XYZ".index(first), "XYZ".index(second)
        end = self.xyz(axes)
        a0 = math.atan2(start[j] - self.centre[j], start[i] - self.centre[i])
        a1 = math.atan2(end[j] - self.centre[j], end[i] - self.centre[i])
        turn = (a0 - a1) if self.clockwise else (a1 - a0)
        turn %= 2.0 * math.pi
        return turn if turn > 0.0 else 2.0 * math.pi

    def xyz(self, axes: Sequence[str]) -> tuple[float, float, float]:
        """End X, Y, Z (mm) of :attr:`position`, whose values are those of ``axes`` (the
        program's; an axis it lacks is NaN)."""
        x, y, z = (self.position[axes.index(a)] if a in axes else math.nan for a in "XYZ")
        return (x, y, z)

    def radii(self, start: Sequence[float], axes: Sequence[str]) -> tuple[float, float]:
        """Distance of the start and of the end from the centre, in the plane (mm)."""
        first, second, _ = ARC_PLANES[self.plane]
        i, j = "XYZ".index(first), "XYZ".index(second)
        end = self.xyz(axes)
        r0 = math.hypot(start[i] - self.centre[i], start[j] - self.centre[j])
        r1 = math.hypot(end[i] - self.centre[i], end[j] - self.centre[j])
        return r0, r1

    def points(self, start: Sequence[float], axes: Sequence[str], max_step: float) -> np.ndarray:
        """Points of the arc as the control runs it, after the start, the last the end.

        The angle turns evenly; the distance from the centre goes linearly from the start's
        to the end's (what a control does with end points a rounding off the circle) and so
        does the axis along the normal (a helix).

        Parameters
        ----------
        start : sequence of 3 floats, mm
            X, Y, Z where the arc starts.
        axes : sequence of str
            The program's axes (those of :attr:`position`).
        max_step : float, mm
            Longest chord between two points (in the plane).

        Returns
        -------
        ndarray, shape (k, 3), mm
            X, Y, Z of each point.
        """
        first, second, normal = ARC_PLANES[self.plane]
        i, j, n = ("XYZ".index(a) for a in (first, second, normal))
        end = self.xyz(axes)
        r0, r1 = self.radii(start, axes)
        sweep = self.sweep(start, axes)
        count = max(1, math.ceil(sweep * max(r0, r1) / max_step))
        t = np.arange(1, count + 1, dtype=float) / count
        a0 = math.atan2(start[j] - self.centre[j], start[i] - self.centre[i])
        angle = a0 + (-sweep if self.clockwise else sweep) * t
        rho = r0 + (r1 - r0) * t
        out = np.empty((count, 3))
        out[:, i] = self.centre[i] + rho * np.cos(angle)
        out[:, j] = self.centre[j] + rho * np.sin(angle)
        out[:, n] = start[n] + (end[n] - start[n]) * t
        out[-1] = end
        return out


@dataclass(frozen=True)
class CutterComp:
    """Cutter radius compensation (G41 left, G42 right, G40 off; Heidenhain RL, RR, R0).

    The path programmed stays the CL path (the tool tip); the control offsets it by the
    tool's radius from its tool table. ``register``: the offset register (the G-code ``D``
    word; the CL's ``CUTCOM/LEFT,n``), None for the tool's own. ``plane``: "XY", "ZX" or
    "YZ".
    """

    side: str
    register: int | None = None
    plane: str = "XY"


Block = (
    Move
    | ToolChange
    | Spindle
    | Coolant
    | Comment
    | Insert
    | Tcp
    | Stop
    | Home
    | MachineMove
    | WorkOffset
    | Cycle
    | Dwell
    | Smoothing
    | Arc
    | CutterComp
    | TiltedPlane
    | Clamp
)


def _read_only(values: Any, dtype: type | np.dtype) -> np.ndarray:
    """``values`` as an array of ``dtype`` that cannot be written through (a view, no copy)."""
    out = np.asarray(values, dtype=dtype).view()
    out.flags.writeable = False
    return out


@dataclass(frozen=True, eq=False)
class MoveTable:
    """Consecutive motion blocks as arrays: row i is one :class:`Move`.

    Attributes
    ----------
    position : ndarray, shape (N, m), float
        One column per axis of :attr:`Program.axes`: mm for linear axes, degrees for rotary
        (see :attr:`Move.position`); NaN where a position is not known.
    rapid : ndarray, shape (N,), bool
        Rapid traverse instead of feed.
    feed : ndarray, shape (N,), float, mm/min
        NaN for no feed (:attr:`Move.feed` None).
    cl_line : ndarray, shape (N,), int64
        Source line of the CL record the block ends on; -1 for none (inserted blocks).

    The arrays are read-only views; rows are taken with :meth:`rows`, the :class:`Move` objects
    made with :meth:`moves` (NaN positions become ``math.nan`` itself, feeds NaN None and
    lines -1 None).
    """

    position: np.ndarray
    rapid: np.ndarray
    feed: np.ndarray
    cl_line: np.ndarray

    def __post_init__(self) -> None:
        position = _read_only(self.position, np.float64)
        n = position.shape[0] if position.ndim == 2 else -1
        columns = {
            "rapid": _read_only(self.rapid, np.bool_),
            "feed": _read_only(self.feed, np.float64),
            "cl_line": _read_only(self.cl_line, np.int64),
        }
        for name, got in (("position", position), *columns.items()):
            want = (n, position.shape[-1]) if name == "position" else (n,)
            if n < 0 or got.shape != want:
                raise ValueError(
                    f"MoveTable.{name}: expected shape "
                    f"{'(N, m)' if name == 'position' else '(N,)'} with N rows for every "
                    f"column, got {got.shape} (position {position.shape})"
                )
        object.__setattr__(self, "position", position)
        for name, got in columns.items():
            object.__setattr__(self, name, got)

    def __len__(self) -> int:
        return int(self.position.shape[0])

    def __repr__(self) -> str:
        return f"MoveTable({len(self)} moves, {self.position.shape[1]} axes)"

    @property
    def width(self) -> int:
        """Number of axes (columns of :attr:`position`)."""
        return int(self.position.shape[1])

    @classmethod
    def empty(cls, width: int) -> MoveTable:
        """A table of no moves for ``width`` axes."""
        return cls(np.zeros((0, width)), np.zeros(0, bool), np.zeros(0), np.zeros(0, np.int64))

    @classmethod
    def from_moves(cls, moves: Sequence[Move], width: int) -> MoveTable:
        """The table of ``moves``, each with ``width`` positions.

        Raises
        ------
        ValueError
            A move with another number of positions, or values that are not numbers.
        """
        k = len(moves)
        positions = list(map(operator.attrgetter("position"), moves))
        wrong = [i for i, p in enumerate(positions) if len(p) != width]
        if wrong:
            i = wrong[0]
            raise ValueError(
                f"move {i} has {len(positions[i])} positions; expected {width} (one per axis)"
            )
        # one flat pass (np.array of a list of tuples is several times slower)
        flat = itertools.chain.from_iterable(positions)
        position = np.fromiter(flat, dtype=float, count=k * width).reshape(k, width)
        feed = [math.nan if m.feed is None else m.feed for m in moves]
        line = [-1 if m.cl_line is None else m.cl_line for m in moves]
        return cls(
            position,
            np.fromiter(map(operator.attrgetter("rapid"), moves), dtype=bool, count=k),
            np.array(feed, dtype=float).reshape(k),
            np.array(line, dtype=np.int64).reshape(k),
        )

    @classmethod
    def concatenate(cls, tables: Sequence[MoveTable], width: int) -> MoveTable:
        """The rows of ``tables`` one after the other (``width`` axes when there are none)."""
        if len(tables) == 1:
            return tables[0]
        if not tables:
            return cls.empty(width)
        return cls(
            np.concatenate([t.position for t in tables]),
            np.concatenate([t.rapid for t in tables]),
            np.concatenate([t.feed for t in tables]),
            np.concatenate([t.cl_line for t in tables]),
        )

    def rows(self, start: int, stop: int) -> MoveTable:
        """Rows ``start`` to ``stop`` (exclusive), as views."""
        return MoveTable(
            self.position[start:stop],
            self.rapid[start:stop],
            self.feed[start:stop],
            self.cl_line[start:stop],
        )

    def moves(self) -> list[Move]:
        """The rows as :class:`Move` objects, in order (Python floats, bools and ints)."""
        position = self.position
        nan = np.isnan(position)
        if nan.any():  # math.nan itself, as a reader of single blocks gives
            cells = position.astype(object)
            cells[nan] = math.nan
            rows = cells.tolist()
        else:
            rows = position.tolist()
        feeds = [None if f != f else f for f in self.feed.tolist()]  # NaN: no feed
        lines = [None if c < 0 else c for c in self.cl_line.tolist()]
        return list(map(Move, self.rapid.tolist(), map(tuple, rows), feeds, lines))

    def move(self, index: int) -> Move:
        """Row ``index`` as a :class:`Move` (negative counts from the end)."""
        k = range(len(self))[index]
        return self.rows(k, k + 1).moves()[0]


class Blocks(Sequence[Block]):
    """The body of a :class:`Program`: a sequence of blocks stored as parts.

    A part is a non-motion block, a :class:`Move`, or a :class:`MoveTable` standing for its
    rows. Indexing, iteration, ``len``, ``in``, equality, hashing, ``repr``, ``+`` and ``*``
    are those of the tuple of blocks (moves of tables are made as they are reached, not kept);
    :attr:`parts` gives the parts themselves and :meth:`move_table` all the moves as one table
    (made once).
    """

    __slots__ = ("_ends", "_parts", "_plain", "_table")

    def __init__(self, parts: Iterable[Block | MoveTable] = ()) -> None:
        items = tuple(parts)
        self._plain = not any(isinstance(p, MoveTable) for p in items)
        if not self._plain:
            items = tuple(p for p in items if not (isinstance(p, MoveTable) and len(p) == 0))
        self._parts: tuple[Block | MoveTable, ...] = items
        self._ends: np.ndarray | None = None
        self._table: MoveTable | None = None

    @property
    def parts(self) -> tuple[Block | MoveTable, ...]:
        """The blocks as stored: runs of moves as :class:`MoveTable` (or single moves)."""
        return self._parts

    def _part_ends(self) -> np.ndarray:
        """Index after the last block of each part, shape (parts,)."""
        if self._ends is None:
            sizes = [len(p) if isinstance(p, MoveTable) else 1 for p in self._parts]
            self._ends = np.cumsum(np.array(sizes, dtype=np.int64))
        return self._ends

    def __len__(self) -> int:
        if self._plain:
            return len(self._parts)
        ends = self._part_ends()
        return int(ends[-1]) if ends.size else 0

    @overload
    def __getitem__(self, index: int) -> Block: ...

    @overload
    def __getitem__(self, index: slice) -> tuple[Block, ...]: ...

    def __getitem__(self, index: int | slice) -> Block | tuple[Block, ...]:
        if self._plain:  # every part is a block
            return cast("Block | tuple[Block, ...]", self._parts[index])
        if isinstance(index, slice):
            return tuple(self)[index]
        n = len(self)
        k = operator.index(index)
        if not -n <= k < n:
            raise IndexError("block index out of range")
        k %= n
        ends = self._part_ends()
        at = int(np.searchsorted(ends, k, side="right"))
        part = self._parts[at]
        if isinstance(part, MoveTable):
            return part.move(k - (int(ends[at - 1]) if at else 0))
        return part

    def __iter__(self) -> Iterator[Block]:
        if self._plain:
            return iter(self._parts)  # type: ignore[arg-type]
        return self._blocks_of_parts()

    def _blocks_of_parts(self) -> Iterator[Block]:
        for part in self._parts:
            if isinstance(part, MoveTable):
                yield from part.moves()
            else:
                yield part

    def _tuple(self) -> tuple[Block, ...]:
        """The blocks as a tuple (the parts themselves when there is no table)."""
        return self._parts if self._plain else tuple(self)  # type: ignore[return-value]

    def __eq__(self, other: object) -> bool:
        if isinstance(other, Blocks):
            return self._parts is other._parts or self._tuple() == other._tuple()
        if isinstance(other, tuple):
            return self._tuple() == other
        return NotImplemented

    def __hash__(self) -> int:
        return hash(self._tuple())

    def __add__(self, other: object) -> Blocks:
        if isinstance(other, Blocks):
            return Blocks(self._parts + other._parts)
        if isinstance(other, tuple):
            return Blocks(self._parts + other)
        return NotImplemented

    def __radd__(self, other: object) -> Blocks:
        if isinstance(other, tuple):
            return Blocks(other + self._parts)
        return NotImplemented

    def __mul__(self, count: int) -> Blocks:
        return Blocks(self._parts * operator.index(count))

    __rmul__ = __mul__

    def __repr__(self) -> str:
        return repr(self._tuple())

    def move_table(self, width: int) -> MoveTable:
        """All the moves as one table (made on the first call, then kept).

        Parameters
        ----------
        width : int
            Number of axes of the program (for programs without moves).

        Raises
        ------
        ValueError
            A :class:`Move` with another number of positions than ``width``.
        """
        if self._table is None or self._table.width != width:
            tables: list[MoveTable] = []
            run: list[Move] = []  # consecutive Move objects
            for part in self._parts:
                if isinstance(part, Move):
                    run.append(part)
                    continue
                if run:
                    tables.append(MoveTable.from_moves(run, width))
                    run = []
                if isinstance(part, MoveTable):
                    tables.append(part)
            if run:
                tables.append(MoveTable.from_moves(run, width))
            self._table = MoveTable.concatenate(tables, width)
        return self._table


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
    blocks : Blocks
        The program body, in order; start and end sequences are the dialect's. Given as an
        iterable of blocks, in which a :class:`MoveTable` stands for its rows; kept as
        :class:`Blocks`, a sequence of :class:`Block` equal to the tuple of them.
    tool_length : float
        Tool length in mm the machine-coordinate positions were computed for.
    continuous : frozenset of str
        Rotary axes with unlimited travel (the dialect may write shortest-path codes for them).
    cut_without_tcp : (str, int) or None
        A program read from text: the file and line of its first feed move of X/Y/Z with TCP
        off (a TCP program with such a move mixes machine positions with tool tips, which
        verification refuses); None otherwise. Not compared.
    offset_change : (str, int, str) or None
        A program read from text: the file, line and words ("from G54 to G55") of its first
        change of work offset (a program with one per MCS; verification refuses a program
        whose offset changes where it expects one); None otherwise. Not compared.
    rollover : frozenset of str
        Continuous rotary axes the control rolls over (modulo 360 display): written in
        [0, 360), and the control turns them the way :func:`rollover_direction` says rather
        than counting turns. A program read from text has the axes its reader was told of.
    feed_mode : str
        What the feeds of its feed moves are (:data:`FEED_MODES`): feeds per minute
        (:data:`FEED_PER_MINUTE`, G94; in a machine-coordinate program the control applies
        them to the axes' own path, see ``docs/job.md``) or inverse times
        (:data:`FEED_INVERSE_TIME`, G93: one over each block's time in minutes). A program
        read from text has the mode its feed moves were read in.
    """

    name: str
    axes: tuple[str, ...]
    rotary: frozenset[str]
    units: str
    tcp: bool
    blocks: Blocks
    tool_length: float = 0.0
    continuous: frozenset[str] = frozenset()
    cut_without_tcp: tuple[str, int] | None = field(default=None, compare=False)
    offset_change: tuple[str, int, str] | None = field(default=None, compare=False)
    rollover: frozenset[str] = frozenset()
    feed_mode: str = FEED_PER_MINUTE

    def __post_init__(self) -> None:
        if self.feed_mode not in FEED_MODES:
            raise ValueError(
                f"Program.feed_mode {self.feed_mode!r}: expected one of {', '.join(FEED_MODES)}"
            )
        if not isinstance(self.blocks, Blocks):
            object.__setattr__(self, "blocks", Blocks(self.blocks))

    @property
    def parts(self) -> tuple[Block | MoveTable, ...]:
        """The body as stored: the non-motion blocks, and runs of moves as tables."""
        return self.blocks.parts

    def move_table(self) -> MoveTable:
        """All motion blocks as one table, in order (made once per program).

        Raises
        ------
        ValueError
            A :class:`Move` without one position per axis.
        """
        return self.blocks.move_table(len(self.axes))

    def moves(self) -> list[Move]:
        """The motion blocks, in order."""
        if self.blocks._plain:
            return [b for b in self.blocks.parts if isinstance(b, Move)]
        out: list[Move] = []
        for part in self.blocks.parts:
            if isinstance(part, MoveTable):
                out += part.moves()
            elif isinstance(part, Move):
                out.append(part)
        return out


def rewind_moves(program: Program) -> np.ndarray:
    """Which moves belong to a rewind: those between the rewind comments.

    The comments survive writing and reading back (in any case), so a program read from text
    still tells its rewinds: their moves leave the CL path on purpose and are not compared
    with it. Computed per part of the program (:attr:`Program.parts`), not per move.

    Returns
    -------
    ndarray, shape (N,), bool
        One entry per move of :meth:`Program.moves`.
    """
    parts = program.parts
    # per part: +1 a rewind's first comment, -1 its last, 0 anything else; moves per part
    marker = np.zeros(len(parts), dtype=np.int8)
    size = np.zeros(len(parts), dtype=np.int64)
    for i, part in enumerate(parts):
        if isinstance(part, MoveTable):
            size[i] = len(part)
        elif isinstance(part, Move):
            size[i] = 1
        elif isinstance(part, Comment):
            text = part.text.strip().lower()
            if text.startswith(REWIND_BEGIN):
                marker[i] = 1
            elif text == REWIND_END:
                marker[i] = -1
    # inside a rewind: the last marker at or before the part is a first comment
    last = np.maximum.accumulate(np.where(marker != 0, np.arange(len(parts)), -1))
    inside = (last >= 0) & (marker[np.maximum(last, 0)] == 1)
    return np.repeat(inside, size)


def _peck_depths(cycle: Cycle) -> list[float]:
    """mm below the hole top where each feed of ``cycle`` ends, the last at its depth."""
    if cycle.kind not in ("deep", "chipbreak") or cycle.step <= 0.0:
        return [cycle.depth]
    count = max(1, math.ceil(cycle.depth / cycle.step - 1e-9))
    return [min(cycle.step * (i + 1), cycle.depth) for i in range(count)]


def expand_cycle(
    cycle: Cycle,
    axes: tuple[str, ...],
    spindle: Spindle | None = None,
    up: Sequence[float] | None = None,
) -> list[Block | MoveTable]:
    """The motion a control runs for ``cycle``, as plain blocks.

    Per hole: rapid to the retract height above it, rapid to the clearance, feed through the
    hole top (the CL point; the block carries its CL line) to the bottom, in pecks of
    ``step`` for "deep" (a rapid out to the clearance after each, and back down to
    :data:`PECK_GAP` above the depth reached) and "chipbreak" (backing off
    :data:`CHIP_BREAK_RETRACT` after each), the dwell, then out: rapid for the drilling kinds,
    at the feed to the clearance for "bore", and for "tap" with the spindle reversed (a
    floating tap holder's motion) and turned back after. The moves are enclosed in the
    comments :data:`CYCLE_BEGIN` and :data:`CYCLE_END`, by which :func:`cycle_moves` knows
    them in a program read back.

    Parameters
    ----------
    cycle : Cycle
    axes : tuple of str
        The program's axes (Z among them).
    spindle : Spindle, optional
        The spindle running before the cycle (needed for "tap").
    up : sequence of float, optional
        Per program axis, how far it moves for 1 mm up the hole's axis (mm, degrees): for a
        hole whose tool axis is not the program's Z (a tilted hole written as its motion).
        None: the program's +Z, as the controls run a cycle.

    Returns
    -------
    list of Block and MoveTable

    Raises
    ------
    ValueError
        A program without a Z axis, or a tapping cycle without the spindle running.
    """
    if "Z" not in axes:
        raise ValueError(f"a cycle in a program without a Z axis ({' '.join(axes)})")
    z = axes.index("Z")
    rise = np.zeros(len(axes)) if up is None else np.asarray(up, dtype=float)
    if up is None:
        rise[z] = 1.0
    if cycle.kind == "tap" and (spindle is None or spindle.direction == "off"):
        raise ValueError("a tapping cycle with the spindle off; expected it running")
    out: list[Block | MoveTable] = [Comment(f"{CYCLE_BEGIN} {cycle.kind}")]
    rows: list[tuple[tuple[float, ...], bool, float, int]] = []

    def flush() -> None:
        if rows:
            position, rapid, feed, line = zip(*rows, strict=True)
            table = MoveTable(np.array(position), np.array(rapid), np.array(feed), np.array(line))
            out.append(table)
            rows.clear()

    lines = cycle.cl_lines or (None,) * len(cycle.holes)
    for hole, cl_line in zip(cycle.holes, lines, strict=True):
        top = np.asarray(hole, dtype=float)

        def add(height: float, rapid: bool, line: int | None = None) -> None:
            position = tuple((top + height * rise).tolist())  # noqa: B023 (used at once)
            if rows and rows[-1][0] == position and line is None:
                return  # (the clearance at the retract height: one block)
            rows.append((position, rapid, math.nan if rapid else cycle.feed, line or -1))

        add(cycle.retract, True)
        add(cycle.clearance, True)
        for k, depth in enumerate(_peck_depths(cycle)):
            add(-depth, False, cl_line if k == 0 else None)  # (the feed into the hole: its top)
            if depth < cycle.depth and cycle.kind == "deep":
                add(cycle.clearance, True)
                add(min(PECK_GAP - depth, cycle.clearance), True)
            elif depth < cycle.depth:
                add(CHIP_BREAK_RETRACT - depth, True)
        if cycle.dwell > 0.0:
            flush()
            out.append(Dwell(cycle.dwell))
        if cycle.kind == "tap":
            assert spindle is not None
            flush()
            reverse = "ccw" if spindle.direction == "cw" else "cw"
            out.append(Spindle(reverse, spindle.rpm))
            add(cycle.clearance, False)
            flush()
            out.append(spindle)
        elif cycle.kind == "bore":
            add(cycle.clearance, False)
        add(cycle.retract, True)
    flush()
    out.append(Comment(CYCLE_END))
    return out


def modal_filled(position: np.ndarray) -> np.ndarray:
    """Positions as written (shape (N, m), NaN where a block does not write an axis) with each
    NaN the column's last value before it, as a control keeps a modal value (NaN before the
    first)."""
    n = len(position)
    idx = np.where(~np.isnan(position), np.arange(n)[:, None], -1)
    np.maximum.accumulate(idx, axis=0, out=idx)
    out = position[np.maximum(idx, 0), np.arange(position.shape[1])]
    out[idx < 0] = np.nan
    return out


def expand_cycles(program: Program) -> Program:
    """``program`` with every :class:`Cycle` block replaced by its motion
    (:func:`expand_cycle`); the program itself when it has none.

    Raises
    ------
    ValueError
        As :func:`expand_cycle`.
    """
    if not any(isinstance(p, Cycle) for p in program.parts):
        return program
    parts: list[Block | MoveTable] = []
    spindle: Spindle | None = None
    for part in program.parts:
        if isinstance(part, Spindle):
            spindle = part
        if isinstance(part, Cycle):
            parts += expand_cycle(part, program.axes, spindle, part.up)
        else:
            parts.append(part)
    return replace(program, blocks=Blocks(parts))


def cycle_moves(program: Program) -> np.ndarray:
    """Which moves belong to an expanded cycle: those between the cycle comments
    (:data:`CYCLE_BEGIN`, :data:`CYCLE_END`), which survive writing and reading back.

    Returns
    -------
    ndarray, shape (N,), bool
        One entry per move of :meth:`Program.moves`.
    """
    inside = False
    flags: list[np.ndarray] = []
    for part in program.parts:
        if isinstance(part, MoveTable):
            flags.append(np.full(len(part), inside))
        elif isinstance(part, Move):
            flags.append(np.array([inside]))
        elif isinstance(part, Comment):
            text = part.text.strip().lower()
            if text == CYCLE_END:
                inside = False
            elif text.startswith(CYCLE_BEGIN):
                inside = True
    return np.concatenate(flags) if flags else np.zeros(0, dtype=bool)


ROLLOVER_DIRECTIONS = ("shortest", "sign", "direct")
"""How a control turns a rollover axis to an absolute value (:func:`rollover_target`)."""


def rollover_target(previous: float, value: float, direction: str) -> float:
    """Where a rollover axis ends, in counted degrees, when a block programs ``value``.

    Parameters
    ----------
    previous : float
        The axis position before the block, degrees counted over turns (any real number); NaN
        when not known (the control's position after a home return): then ``value`` in
        [0, 360) for "shortest" and "direct", its magnitude for "sign".
    value : float
        The value written, degrees: in [0, 360), or in (-360, 360) for "sign".
    direction : str
        "shortest": the shorter way to ``value`` modulo 360 (half a turn: positive);
        "sign": LinuxCNC's ``WRAPPED_ROTARY``, positive ``value`` (``+0`` too) turns positive,
        negative (``-0`` too) negative, to ``abs(value)`` modulo 360, less than a turn
        (interp_convert.cc ``unwrap_rotary``); "direct": to the position ``value`` in [0, 360)
        without passing 0 (Siemens ``G90`` on a modulo axis, MD30455 bit 2 = 0; Heidenhain
        without ``M126``).

    Returns
    -------
    float
        Degrees, counted over turns.

    Examples
    --------
    >>> rollover_target(350.0, 10.0, "shortest"), rollover_target(350.0, 10.0, "direct")
    (370.0, 10.0)
    >>> rollover_target(10.0, -350.0, "sign"), rollover_target(10.0, -0.0, "sign")
    (-10.0, 0.0)
    """
    if direction == "sign":
        position = abs(value)
        if math.isnan(previous):
            return position
        # as LinuxCNC's unwrap_rotary: the turn of ``previous``, then at most one turn on
        result = position + math.floor(previous / 360.0) * 360.0
        negative = math.copysign(1.0, value) < 0.0
        if not negative and result < previous:
            result += 360.0
        if negative and result > previous:
            result -= 360.0
        return result
    position = value % 360.0
    if math.isnan(previous):
        return position
    if direction == "shortest":
        step = 180.0 - (previous - position + 180.0) % 360.0  # in (-180, 180]
        return previous + step
    if direction == "direct":
        return previous - previous % 360.0 + position
    raise ValueError(f"unknown rollover direction {direction!r}; expected {ROLLOVER_DIRECTIONS}")


def smoothing_summary(program: Program, units: str) -> str:
    """What a program does with the control's path smoothing, for people (``verify``).

    Parameters
    ----------
    program : Program
        Usually read from text (its :class:`Smoothing` blocks).
    units : str
        Of the tolerance shown ("mm" or "inch").

    Returns
    -------
    str
        E.g. ``"smoothing on 2 times (tolerance 0.0100 mm, rotary axes 0.500 deg), off 2
        times, off at the end"``; ``"no smoothing cycle (the control's own path mode)"``.
    """
    states = [b for b in program.parts if isinstance(b, Smoothing)]
    if not states:
        return "no smoothing cycle (the control's own path mode)"
    ons = [b for b in states if b.on]
    parts = []
    if ons:
        shown = []
        for b in dict.fromkeys(ons):
            words = []
            if b.tolerance is not None:
                scale = 25.4 if units == "inch" else 1.0
                words.append(f"tolerance {b.tolerance / scale:.4f} {units}")
            else:
                words.append("the control's tolerance")
            if b.angle is not None:
                words.append(f"rotary axes {b.angle:.3f} deg")
            shown.append(", ".join(words))
        parts.append(f"smoothing on {len(ons)} times ({'; '.join(shown)})")
    offs = len(states) - len(ons)
    if offs:
        parts.append(f"off {offs} times")
    parts.append("off at the end" if not states[-1].on else "still on at the end")
    return ", ".join(parts)


def arcs_as_moves(program: Program, max_step: float) -> Program:
    """The program with each :class:`Arc` block replaced by feed moves along it, as the
    control runs it (:meth:`Arc.points`): what verification measures.

    The moves of an arc carry its feed (in inverse time, :data:`FEED_INVERSE_TIME`, each its
    share of the arc's time by its length: F times the arc's length over the move's); the last
    one its CL line and the arc's end (every axis), the others no CL line. A program without
    arcs is returned as it is.

    Parameters
    ----------
    program : Program
    max_step : float, mm
        Longest chord between two moves on an arc.

    Raises
    ------
    ValueError
        An arc whose start is not known (no motion block before it gives X, Y and Z).
    """
    parts = program.parts
    if not any(isinstance(p, Arc) for p in parts):
        return program
    width = len(program.axes)
    xyz = [program.axes.index(a) if a in program.axes else -1 for a in "XYZ"]
    last = np.full(width, np.nan)  # where the axes stand (NaN: not known yet)
    out: list[Block | MoveTable] = []
    for part in parts:
        if isinstance(part, MoveTable | Move):
            table = part if isinstance(part, MoveTable) else MoveTable.from_moves([part], width)
            if len(table):
                known = ~np.isnan(table.position)
                for j in range(width):
                    rows = np.flatnonzero(known[:, j])
                    if rows.size:
                        last[j] = table.position[rows[-1], j]
            out.append(part)
            continue
        if not isinstance(part, Arc):
            if isinstance(part, Home | MachineMove):
                last[:] = np.nan  # the axes stand where the program does not say
            out.append(part)
            continue
        start = [last[j] if j >= 0 else math.nan for j in xyz]
        if not all(math.isfinite(v) for v in start):
            raise ValueError(f"arc {part} from an unknown position")
        points = part.points(start, program.axes, max_step)
        k = len(points)
        position = np.tile(np.where(np.isnan(last), np.asarray(part.position), last), (k, 1))
        for axis, j in zip(range(3), xyz, strict=True):
            if j >= 0:
                position[:, j] = points[:, axis]
        position[-1] = part.position
        feed = np.full(k, math.nan if part.feed is None else part.feed)
        if program.feed_mode == FEED_INVERSE_TIME and part.feed is not None:
            # F is one over the whole arc's time: each move takes its share of it, by length
            chords = np.linalg.norm(np.diff(np.vstack([start, points]), axis=0), axis=1)
            total = float(chords.sum())
            if total > 0.0:
                feed = part.feed * total / np.maximum(chords, total * 1e-12)
        line = np.full(k, -1, dtype=np.int64)
        line[-1] = -1 if part.cl_line is None else part.cl_line
        out.append(MoveTable(position, np.zeros(k, bool), feed, line))
        last = np.asarray(part.position, dtype=float).copy()
    return replace(program, blocks=Blocks(out))


def with_positions(
    parts: Iterable[Block | MoveTable], width: int, start: np.ndarray | None = None
) -> Iterator[tuple[Block | MoveTable, np.ndarray]]:
    """Each part with where the axes stand before it: per axis the last value the moves before
    it give (``start``, default NaN: none yet), shape (width,). The array is the walk's own:
    read it before the next step."""
    last = np.full(width, np.nan) if start is None else np.array(start, dtype=float)
    for part in parts:
        yield part, last
        if isinstance(part, MoveTable | Move):
            table = part if isinstance(part, MoveTable) else MoveTable.from_moves([part], width)
            known = ~np.isnan(table.position)
            rows = np.where(known, np.arange(len(table))[:, None], -1).max(axis=0, initial=-1)
            seen = rows >= 0
            last[seen] = table.position[rows[seen], np.flatnonzero(seen)]


def _in_frame(frame: np.ndarray, xyz: list[int], position: np.ndarray) -> np.ndarray:
    """``position`` (rows of program values, shape (k, m)) with its X, Y, Z taken from
    plane coordinates to the program's frame (``frame`` columns the plane's axes); NaN stays
    NaN where the whole of X, Y, Z is not known."""
    out = position.copy()
    out[:, xyz] = position[:, xyz] @ frame.T
    return out


def plane_count(program: Program) -> int:
    """Tilted working planes switched on in ``program``."""
    return sum(1 for p in program.parts if isinstance(p, TiltedPlane) and p.angles is not None)


def untilted(program: Program) -> Program:
    """``program`` with its tilted working planes (:class:`TiltedPlane`) taken out: the moves
    and the canned cycles' holes in a plane in the program's own frame, as the control runs
    them (X, Y, Z the plane's frame's columns times the plane coordinates; a cycle in a plane
    drills along the plane's Z: a :class:`Cycle` with :attr:`Cycle.up`), each plane's switch
    on a :class:`Tcp` switch on (the control points through the plane, the tool tip, as TCP
    does: its length register the plane's, :attr:`TiltedPlane.offset`) and its switch off a
    switch off: as many moves, cycles and TCP switches on as the program has moves, cycles and
    switches on of TCP and planes. A program without planes is returned as it is.

    Raises
    ------
    ValueError
        A plane in a program that is not a TCP program (its coordinates would be the gauge
        point, which machine-coordinate programs do not have), a rotary axis that moves or an
        arc in a plane, a motion block in a plane whose X, Y and Z are not all known.
    """
    return Untilter().feed(program)


class Untilter:
    """:func:`untilted` of a program given in pieces, in order: a plane switched on in one
    piece holds in the next (where the axes stand, the plane on and its rotary values are
    carried over)."""

    def __init__(self) -> None:
        self.frame: np.ndarray | None = None  # the plane on (its axes, columns)
        self.stand: dict[str, float] = {}  # the rotary values in it
        self.last: dict[str, float] = {}  # where the axes stand, as programmed

    def feed(self, program: Program) -> Program:
        """The next piece of the program, untilted (raises as :func:`untilted`)."""
        parts = program.parts
        axes = program.axes
        if self.frame is None and not any(isinstance(p, TiltedPlane) for p in parts):
            self._remember(program)
            return program
        if not program.tcp:
            raise ValueError(
                "a tilted working plane in a machine-coordinate program; expected one only in a "
                "TCP program"
            )
        if not all(a in axes for a in "XYZ"):
            raise ValueError(f"a tilted working plane in a program without X, Y and Z ({axes})")
        xyz = [axes.index(a) for a in "XYZ"]
        rotary = [j for j, a in enumerate(axes) if a in program.rotary]
        out: list[Block | MoveTable] = []

        def rotaries_stand(position: np.ndarray) -> None:
            for j in rotary:
                stand = self.stand.get(axes[j], math.nan)
                values = position[:, j]
                moved = ~np.isnan(values) & ~np.isclose(values, stand, rtol=0.0, atol=1e-9)
                if moved.any():
                    raise ValueError(
                        f"{axes[j]} moves in a tilted working plane; expected the rotary axes to "
                        "stand"
                    )

        start = np.array([self.last.get(a, math.nan) for a in axes])
        for part, where in with_positions(parts, len(axes), start):
            frame = self.frame
            if isinstance(part, TiltedPlane):
                if part.angles is None:
                    if frame is not None:
                        out.append(Tcp(False))
                    self.frame, self.stand = None, {}
                else:
                    self.frame = part.frame()
                    self.stand = {axes[j]: float(where[j]) for j in rotary}
                    out.append(Tcp(True, part.offset))
            elif frame is None:
                out.append(part)
            elif isinstance(part, Move | MoveTable):
                width = len(axes)
                table = part if isinstance(part, MoveTable) else MoveTable.from_moves([part], width)
                if np.isnan(table.position[:, xyz]).any():
                    raise ValueError(
                        "a move in a tilted working plane without all of X, Y and Z known; "
                        "expected every axis written after the plane is switched on"
                    )
                rotaries_stand(table.position)
                moved = _in_frame(frame, xyz, table.position)
                out.append(MoveTable(moved, table.rapid, table.feed, table.cl_line))
            elif isinstance(part, Cycle):
                holes = np.array(part.holes, dtype=float)
                rotaries_stand(holes)
                up = np.zeros(len(axes))
                up[xyz] = frame[:, 2]
                turned = _in_frame(frame, xyz, holes)
                out.append(replace(part, holes=tuple(map(tuple, turned.tolist())), up=tuple(up)))
            elif isinstance(part, Arc):
                raise ValueError("an arc in a tilted working plane; expected lines there")
            else:
                out.append(part)
        self._remember(program)
        return replace(program, blocks=Blocks(out))

    def _remember(self, program: Program) -> None:
        """Where the axes stand after ``program`` (as programmed: plane coordinates in one)."""
        table = program.move_table()
        for j, a in enumerate(program.axes):
            known = np.flatnonzero(~np.isnan(table.position[:, j]))
            if known.size:
                self.last[a] = float(table.position[known[-1], j])
