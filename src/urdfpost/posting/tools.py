"""Per-tool gauge lengths of machine-coordinate programs, and the tool sections they cut.

A machine-coordinate program holds the machine's axis positions, and those include the tool's
gauge length (gauge point to tip): each tool's moves must be computed with its own length, and
checked with it. The length of tool ``n`` is, first found:

1. the tool table (``--tool-table``, :func:`read_tool_table`: the lengths measured on the
   machine);
2. the CL data's ``LOADTL/n,LENGTH,l``: APT's gauge length of the tool;
3. the job's one length (``--tool-length``, else the machine file's ``tool_length``).

``TLDATA`` and ``CUTTER`` lengths are not gauge lengths: NX's ``TLDATA/MILL`` length is the
cutter's own length (tip to the holder), without the holder, so they are never used for it.

A job whose tools have different lengths is posted in *tool sections*: the points from one
tool change to the next one that changes the length (:func:`tool_sections`), each planned,
written and checked with its tool's length. The program is one; its sections are found again
in the program read back at the tool changes that begin them (:func:`program_sections`).
TCP programs hold tool tips: their tool lengths are the control's (its tool table and the
length offset register the TCP switch selects), and they are one section.

A tool change to a cutter of another ball radius begins a section too, in any program
(``by_pivot``): a strategy that bends the tool axis pivots it about the cutting point, the
ball centre of a ball-end tool and the tip of any other (:func:`cutting_points`), and the
program is checked against the CL data at that point. One pivot for a whole job moved a flat
end mill's tip by the first tool's ball radius times the bend (0.084 mm on the dome, checked
at the ball centre and passed). When collisions are checked, a tool change to another cutter
begins a section as well (``by_cutter``, :func:`tool_cutters`): each is checked with its own
tool body (the first cutter's for the whole job let a 6 mm end mill's shank run through the
stock where the 20 mm one before it was clear).
"""

from __future__ import annotations

import itertools
import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from urdfpost.errors import ToleranceError, UrdfpostError
from urdfpost.machine import Machine, with_setup
from urdfpost.machine.setup import Setup
from urdfpost.program import Blocks, Move, MoveTable, Program, ToolChange, WorkOffset
from urdfpost.toolpath import Toolpath, toolpath_slice

#: One word of a LinuxCNC tool table line: a letter and a number.
_WORD = re.compile(r"([A-Za-z])([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)")


def read_tool_table(path: str | Path, scale: float = 1.0) -> dict[int, float]:
    """The tool lengths of a LinuxCNC tool table file.

    Each line is ``T<n> P<pocket> Z<length> D<diameter> ;comment`` (LinuxCNC's format, any
    order of the words; X, Y, A..W offsets, D, I, J, Q are read past). The Z word is the
    tool's gauge length. Blank lines and comment lines (``;`` or ``#`` first) are skipped.

    Parameters
    ----------
    path : path
    scale : float
        mm per unit of the table's lengths (the program units'; 25.4 for inch).

    Returns
    -------
    dict of int to float
        Gauge length of each tool number, mm.

    Raises
    ------
    UrdfpostError
        The file cannot be read, or a line without a tool number or length, with a number
        that is not one, a length that is not finite and positive, or a tool listed twice
        (the message names the file and line).
    """
    try:
        text = Path(path).read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as e:
        reason = e.strerror if isinstance(e, OSError) and e.strerror else e
        raise UrdfpostError(f"{path}: cannot read the tool table: {reason}") from e
    lengths: dict[int, float] = {}
    for number, raw in enumerate(text.splitlines(), start=1):
        line = raw.split(";", 1)[0].strip()
        if not line or line.startswith("#"):
            continue

        def bad(what: str, line_number: int = number) -> UrdfpostError:
            return UrdfpostError(f"{path}:{line_number}: {what}")

        words: dict[str, str] = {}
        for token in line.split():
            word = _WORD.fullmatch(token)
            if word is None:
                raise bad(f"expected tool table words such as T1 P1 Z100.0 D10.0, got '{token}'")
            letter = word[1].upper()
            if letter in words:
                raise bad(f"expected one {letter} word, got two")
            words[letter] = word[2]
        if "T" not in words or "Z" not in words:
            missing = " and ".join(w for w in ("T", "Z") if w not in words)
            raise bad(f"expected a tool number T and a length Z, got no {missing}")
        tool = float(words["T"])
        if not (tool.is_integer() and tool >= 0):
            raise bad(f"expected a whole tool number, got T{words['T']}")
        length = float(words["Z"]) * scale
        if not (math.isfinite(length) and length > 0.0):
            raise bad(f"expected a positive gauge length for T{int(tool)}, got Z{words['Z']}")
        if int(tool) in lengths:
            raise bad(f"T{int(tool)} is listed twice")
        lengths[int(tool)] = length
    return lengths


def gauge_lengths(
    toolpath: Toolpath, default: float, table: Mapping[int, float] | None = None
) -> dict[int, float]:
    """The gauge length of each tool the CL data loads (module docstring: the table, else
    ``LOADTL LENGTH``, else ``default``), mm."""
    table = table or {}
    out: dict[int, float] = {}
    for e in toolpath.events:
        if e.kind != "tool":
            continue
        number = int(e.data.get("number", 0))
        cl = e.data.get("length")
        out[number] = table.get(number, float(cl) if cl is not None else default)
    return out


Cutter = tuple[float | None, float | None, float | None]
"""A cutter's diameter, corner radius and length (mm; None where the CL data gives none): what
its collision body is made of (:meth:`urdfpost.collision.ToolBody.from_cutter`)."""


def cutter_of(data: Mapping[str, object], kind: str = "cutter") -> Cutter:
    """The :data:`Cutter` of a ``cutter`` or ``tool`` (``kind``) event's data: a tool event's
    cutter length is its ``cutter_length`` (its ``length`` is the gauge length)."""

    def number(key: str) -> float | None:
        value = data.get(key)
        return None if value is None else float(value)  # type: ignore[arg-type]

    length = "cutter_length" if kind == "tool" else "length"
    return number("diameter"), number("corner_radius"), number(length)


def tool_cutters(toolpath: Toolpath) -> tuple[Cutter | None, dict[int, Cutter]]:
    """The cutter of each tool the CL data loads.

    A tool's cutter is the last ``CUTTER`` (or ``LOADTL`` with a diameter) among the events
    before the same CL point as its tool change. One given after the tool's first point is
    not the tool's (the APT reader refuses one that changes the cutter moves follow with; one
    after the last point cuts nothing).

    Returns
    -------
    first : Cutter or None
        The cutter at the first CL point: the last one before it, else the first of the CL
        data (None without one).
    by_tool : dict of int to Cutter
        Per tool number loaded; a tool with no cutter is not in it (it keeps the cutter of the
        tool before).
    """
    first: Cutter | None = None
    start: Cutter | None = None  # the last cutter before the first point
    by_tool: dict[int, Cutter] = {}
    n = len(toolpath)
    for index, at in itertools.groupby(
        sorted(toolpath.events, key=lambda e: e.index), key=lambda e: e.index
    ):
        if index >= n and n > 0:
            break  # after the last point
        group = list(at)  # the events before one CL point
        tools = [int(e.data.get("number", 0)) for e in group if e.kind == "tool"]
        tool = tools[-1] if tools else None  # (loaded at this point)
        for e in group:
            if e.kind in ("cutter", "tool") and e.data.get("diameter") is not None:
                cutter = cutter_of(e.data, e.kind)
                first = cutter if first is None else first
                if e.index <= 0:
                    start = cutter
                if tool is not None:
                    by_tool[tool] = cutter
    return (first if start is None else start), by_tool


def cutting_point(cutter: Cutter | None) -> float:
    """How far up the tool axis from the tip a cutter cuts (mm): its ball radius, half its
    diameter, when its corner radius is that (a ball-end cutter), else 0 (the tip)."""
    d, corner = (None, None) if cutter is None else cutter[:2]
    if d is None:
        return 0.0
    if corner is not None and d > 0 and abs(corner - 0.5 * d) <= 1e-6 * max(d, 1.0):
        return 0.5 * d
    return 0.0


def cutting_points(toolpath: Toolpath) -> tuple[float, dict[int, float]]:
    """How far up the tool axis from the tip each tool cuts (mm), from its cutter
    (:func:`tool_cutters`, :func:`cutting_point`).

    Returns
    -------
    first : float, mm
        At the first CL point (0 without a cutter).
    by_tool : dict of int to float, mm
        Per tool number loaded that has a cutter.
    """
    first, by_tool = tool_cutters(toolpath)
    return cutting_point(first), {n: cutting_point(c) for n, c in by_tool.items()}


def mcs_shifts(toolpath: Toolpath) -> dict[int, np.ndarray]:
    """Where each MCS of the CL data (its ``msys`` events) sits in the first one.

    Returns
    -------
    dict of int to ndarray, shape (3,), mm
        The origin of MCS ``k`` in MCS 0's coordinates (0 for MCS 0; empty: no MSYS).

    Raises
    ------
    UrdfpostError
        An MCS turned against MCS 0: a work offset per MCS holds a shift, not a rotation (the
        message names the MSYS line).
    """
    out: dict[int, np.ndarray] = {}
    first = None
    for e in toolpath.events:
        if e.kind != "msys":
            continue
        k = int(e.data.get("mcs", 0))
        origin = np.asarray(e.data["origin"], dtype=float)
        rotation = np.asarray(e.data["rotation"], dtype=float)
        if first is None:
            first = (origin, rotation, e.line)
        o0, r0, line0 = first
        if k in out:
            continue
        if not np.allclose(rotation, r0, rtol=0.0, atol=1e-9):
            raise UrdfpostError(
                f"{toolpath.source}:{e.line}: MCS {k} is turned against MCS 0 (MSYS at line "
                f"{line0}); a work offset per MCS holds a shift, not a rotation: post without "
                "--mcs-offsets (its points are then transformed into MCS 0)"
            )
        out[k] = r0.T @ (origin - o0)
    return out


def transformed_mcs(toolpath: Toolpath) -> bool:
    """Whether the reader transformed the points of the other MCS into MCS 0 (their ``msys``
    events say ``transformed``; a file read with ``separate_mcs`` keeps them as written)."""
    return any(e.kind == "msys" and e.data.get("transformed") for e in toolpath.events)


def in_own_mcs(toolpath: Toolpath, shift: np.ndarray, transformed: bool) -> Toolpath:
    """The points of a section of one MCS in that MCS's coordinates: moved by ``-shift`` (its
    origin in MCS 0, :func:`mcs_shifts`) when ``transformed`` (:func:`transformed_mcs` of the
    whole CL data), else as they are."""
    if not transformed or not np.any(shift):
        return toolpath
    return replace(toolpath, tip=toolpath.tip - np.asarray(shift, dtype=float))


@dataclass(frozen=True)
class Section:
    """Consecutive CL points posted with one gauge length and in one MCS.

    Attributes
    ----------
    start, stop : int
        Points ``start`` to ``stop - 1`` of the toolpath; the events that begin the section
        (its tool change, its MSYS) come before ``start``.
    length : float, mm
        The gauge length of its tool.
    tool : int or None
        Its tool number (None: before any tool change).
    mcs : int
        Its MCS (0: the first; :func:`mcs_shifts`), with ``--mcs-offsets`` (else 0).
    pivot : float, mm
        Its tool's cutting point up the tool axis from the tip (:func:`cutting_points`).
    cutter : Cutter or None
        Its tool's cutter (:func:`tool_cutters`).
    """

    start: int
    stop: int
    length: float
    tool: int | None
    mcs: int = 0
    pivot: float = 0.0
    cutter: Cutter | None = None


def tool_sections(
    toolpath: Toolpath,
    default: float,
    table: Mapping[int, float] | None = None,
    length: float | None = None,
    *,
    by_length: bool = True,
    by_mcs: bool = False,
    by_pivot: bool = False,
    pivot: float | None = None,
    by_cutter: bool = False,
    cutter: Cutter | None = None,
) -> list[Section]:
    """The sections of a job: a new one at each tool change whose gauge length differs from
    the one before (``by_length``: machine coordinates; equal lengths share a section), at
    each tool change to another cutting point (``by_pivot``, :func:`cutting_points`), and at
    each MSYS of another MCS (``by_mcs``: a work offset per MCS).

    Parameters
    ----------
    toolpath : Toolpath
    default : float, mm
        The job's length (tools with no table entry or ``LOADTL LENGTH``).
    table : mapping, optional
        Tool number to gauge length, mm (:func:`read_tool_table`).
    length : float, optional, mm
        The length in use where the toolpath starts (a piece of a streamed job); default
        ``default``.
    by_length, by_mcs, by_pivot : bool
        What begins a section.
    pivot : float, optional, mm
        The cutting point in use where the toolpath starts (a piece of a streamed job);
        default the first cutter's.
    by_cutter : bool
        A section at each tool change to another cutter (a collision body of its own).
    cutter : Cutter, optional
        The cutter in use where the toolpath starts (a piece of a streamed job; with
        ``pivot``); default the first.

    Returns
    -------
    list of Section
        At least one; they cover every point in order.
    """
    lengths = gauge_lengths(toolpath, default, table)
    first, cutters = tool_cutters(toolpath)
    n = len(toolpath)
    current = default if length is None else length
    point = cutting_point(first) if pivot is None else pivot
    held = first if pivot is None else cutter
    tool: int | None = None
    mcs = 0
    sections: list[Section] = []
    start = 0
    for e in sorted(toolpath.events, key=lambda e: e.index):
        if e.kind == "tool":
            number = int(e.data.get("number", 0))
            new_length, new_mcs = lengths[number], mcs
            new_held = cutters.get(number, held)
            new_point = point if number not in cutters else cutting_point(new_held)
        elif e.kind == "msys" and by_mcs:
            new_length, new_mcs = current, int(e.data.get("mcs", 0))
            new_point, new_held = point, held
        else:
            continue
        changes = (
            (by_length and new_length != current)
            or (by_pivot and new_point != point)
            or (by_cutter and new_held != held)
            or new_mcs != mcs
        )
        if start < e.index < n and changes:
            sections.append(Section(start, e.index, current, tool, mcs, point, held))
            start = e.index
        if e.index < n or not sections:
            current, mcs, point, held = new_length, new_mcs, new_point, new_held
            if e.kind == "tool":
                tool = int(e.data.get("number", 0))
    sections.append(Section(start, n, current, tool, mcs, point, held))
    return sections


def several_lengths(sections: Sequence[Section]) -> bool:
    """Whether a job needs its sections (more than one)."""
    return len(sections) > 1


def mcs_machine(machine: Machine, shift: np.ndarray) -> Machine:
    """``machine`` with its program zero moved to an MCS ``shift`` (3,) mm from it, in the
    workpiece frame (:func:`mcs_shifts`): the machine a section of that MCS is posted and
    checked on, its positions written in that MCS's work offset.

    Raises
    ------
    UrdfpostError
        The machine file places no workpiece (no ``workpiece`` joint to move).
    """
    if not np.any(shift):
        return machine
    mount = machine.mount
    if mount is None:
        raise UrdfpostError(
            f"{machine.path}: no joint places the workpiece link, so an MCS cannot be put "
            "elsewhere on the machine; expected a fixed joint whose child is 'workpiece'"
        )
    offset = mount.offset_for(mount.rotation @ np.asarray(shift, dtype=float))
    return with_setup(machine, Setup(offset, mount.setup.rotation))


def program_sections(
    program: Program,
    lengths: Mapping[int, float],
    default: float,
    *,
    by_length: bool = True,
    by_mcs: bool = False,
    pivots: tuple[float, Mapping[int, float]] | None = None,
) -> list[tuple[Program, float, int | None]]:
    """A program read back cut as :func:`tool_sections` cuts its CL data: at the tool changes
    that change the gauge length (``by_length``), at those that change the cutting point
    (``pivots``: :func:`cutting_points` of the CL data; None: not), and at the work offset
    changes (``by_mcs``: a work offset per MCS).

    Each section but the first begins with the block that changes (its
    :class:`~urdfpost.program.WorkOffset` or :class:`~urdfpost.program.ToolChange`); the
    blocks before it (the retract, spindle and coolant off of the section before) end the
    section before. ``lengths`` are the tools' gauge lengths (mm, :func:`gauge_lengths`);
    a tool not in it has ``default``.

    Returns
    -------
    list of (Program, float, int or None)
        Each section, its gauge length (mm; the first section's is that of the first tool,
        ``default`` before any) and the work offset it selects (None: none).
    """
    parts = program.parts
    cuts: list[tuple[int, float, int | None]] = [(0, default, None)]
    offset: int | None = None
    length = default
    point = 0.0 if pivots is None else pivots[0]
    moved = False  # a move since the section began: a change now begins another
    for i, part in enumerate(parts):
        if isinstance(part, Move) or (isinstance(part, MoveTable) and len(part)):
            moved = True
            continue
        new_point = point
        if isinstance(part, ToolChange):
            new_length, new_offset = lengths.get(part.number, default), offset
            if pivots is not None:
                new_point = pivots[1].get(part.number, point)
        elif isinstance(part, WorkOffset) and by_mcs:
            new_length, new_offset = length, part.number
        else:
            continue
        changes = (
            (by_length and new_length != length)
            or new_point != point
            or (offset is not None and new_offset != offset)
        )
        if moved and changes:
            cuts.append((i, new_length, new_offset))
            moved = False
        length, offset, point = new_length, new_offset, new_point
        cuts[-1] = (cuts[-1][0], length, offset)
    out: list[tuple[Program, float, int | None]] = []
    for k, (i, section_length, number) in enumerate(cuts):
        stop = cuts[k + 1][0] if k + 1 < len(cuts) else len(parts)
        section = replace(program, blocks=Blocks(parts[i:stop]), tool_length=section_length)
        out.append((section, section_length, number))
    return out


def paired_sections(
    program: Program,
    toolpath: Toolpath,
    default: float,
    table: Mapping[int, float] | None = None,
    *,
    by_mcs: bool = False,
    by_pivot: bool = False,
) -> list[tuple[Program, Toolpath, Section]]:
    """A program and its CL data cut into the same sections (:func:`tool_sections`), to be
    checked each with its gauge length, ``by_pivot`` at its tool's cutting point, and,
    ``by_mcs``, on the machine of its MCS (:func:`mcs_machine`).

    Parameters
    ----------
    program : Program
        As read back (the tool length matters in machine coordinates only).
    toolpath : Toolpath
        The CL data it is checked against.
    default : float, mm
        The job's tool length.
    table : mapping, optional
        The tool table (tool number to gauge length, mm).
    by_mcs : bool
        A work offset per MCS: a section at each MSYS of another MCS.
    by_pivot : bool
        A section at each tool change to another cutting point (:func:`cutting_points`).

    Returns
    -------
    list of (Program, Toolpath, Section)
        Each section of the program, of the CL data, and the section. One section, with the
        first tool's length, when the program does not change tools where the CL data
        changes length (the process check then names the tool at fault).

    Raises
    ------
    ToleranceError
        ``by_mcs``: the program's work offsets are not one per MCS of the CL data, in order
        (the first, then one more for each other MCS).
    """
    by_length = not program.tcp
    sections = tool_sections(
        toolpath, default, table, by_length=by_length, by_mcs=by_mcs, by_pivot=by_pivot
    )
    lengths = gauge_lengths(toolpath, default, table)
    pivots = cutting_points(toolpath) if by_pivot else None
    cut = program_sections(
        program, lengths, default, by_length=by_length, by_mcs=by_mcs, pivots=pivots
    )
    if by_mcs:
        have = [number for _, _, number in cut]
        first = have[0] if have[0] is not None else 1
        want = [first + s.mcs for s in sections]
        if have != want:

            def named(numbers: list[int | None]) -> str:
                return ", ".join("none" if n is None else f"offset {n}" for n in numbers)

            raise ToleranceError(
                f"{toolpath.source}: the program's work offsets are {named(have)} where the "
                f"CL data's MCS, in order, need {named(list(want))} (one per MCS)"
            )
    if len(sections) == 1 or len(cut) != len(sections):
        return [(program, toolpath, sections[0])]
    return [
        (part, toolpath_slice(toolpath, s.start, s.stop), s)
        for (part, _, _), s in zip(cut, sections, strict=True)
    ]


def row_tool_values(program: Program, values: Mapping[int, float], default: float) -> np.ndarray:
    """A value of the tool each move of a program is made with (its gauge length, its
    diameter...): that of the tool loaded before it in ``values`` (a tool not in it and the
    moves before any tool change: ``default``).

    Returns
    -------
    ndarray, shape (N,)
        One per move of :meth:`Program.move_table`.
    """
    out: list[np.ndarray] = []
    value = default
    for part in program.parts:
        if isinstance(part, ToolChange):
            value = values.get(part.number, default)
        elif isinstance(part, MoveTable):
            out.append(np.full(len(part), value))
        elif isinstance(part, Move):
            out.append(np.full(1, value))
    return np.concatenate(out) if out else np.zeros(0)
