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
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass, field, replace
from typing import Any, cast, overload

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
    | Arc
    | CutterComp
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

    def __post_init__(self) -> None:
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


def arcs_as_moves(program: Program, max_step: float) -> Program:
    """The program with each :class:`Arc` block replaced by feed moves along it, as the
    control runs it (:meth:`Arc.points`): what verification measures.

    The moves of an arc carry its feed; the last one its CL line and the arc's end (every
    axis), the others no CL line. A program without arcs is returned as it is.

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
        feed = math.nan if part.feed is None else part.feed
        line = np.full(k, -1, dtype=np.int64)
        line[-1] = -1 if part.cl_line is None else part.cl_line
        out.append(MoveTable(position, np.zeros(k, bool), np.full(k, feed), line))
        last = np.asarray(part.position, dtype=float).copy()
    return replace(program, blocks=Blocks(out))
