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
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

from urdfpost.errors import UrdfpostError
from urdfpost.program import Blocks, Move, MoveTable, Program, ToolChange
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


@dataclass(frozen=True)
class Section:
    """Consecutive CL points posted with one gauge length.

    Attributes
    ----------
    start, stop : int
        Points ``start`` to ``stop - 1`` of the toolpath; the section's tool change is the
        event before ``start``.
    length : float, mm
        The gauge length of its tool.
    tool : int or None
        Its tool number (None: before any tool change).
    """

    start: int
    stop: int
    length: float
    tool: int | None


def tool_sections(
    toolpath: Toolpath,
    default: float,
    table: Mapping[int, float] | None = None,
    length: float | None = None,
) -> list[Section]:
    """The tool sections of a machine-coordinate job: a new one at each tool change whose
    gauge length differs from the one before (equal lengths share a section).

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

    Returns
    -------
    list of Section
        At least one; they cover every point in order.
    """
    lengths = gauge_lengths(toolpath, default, table)
    n = len(toolpath)
    current = default if length is None else length
    tool: int | None = None
    sections: list[Section] = []
    start = 0
    for e in sorted(toolpath.events, key=lambda e: e.index):
        if e.kind != "tool":
            continue
        number = int(e.data.get("number", 0))
        new = lengths[number]
        if e.index <= start or e.index >= n:  # before any point of the section: its own
            if e.index <= start:
                current, tool = new, number
            continue
        if new != current:
            sections.append(Section(start, e.index, current, tool))
            start = e.index
        current, tool = new, number
    sections.append(Section(start, n, current, tool))
    return sections


def several_lengths(sections: Sequence[Section]) -> bool:
    """Whether the sections hold more than one gauge length (the job needs them)."""
    return len({s.length for s in sections}) > 1


def program_sections(
    program: Program, lengths: Mapping[int, float], default: float
) -> list[tuple[Program, float]]:
    """A machine-coordinate program cut at the tool changes that change the gauge length.

    Each section but the first begins with its :class:`~urdfpost.program.ToolChange`; the
    blocks before it (the retract, spindle and coolant off of the tool before) end the
    section before. ``lengths`` are the tools' gauge lengths (mm, :func:`gauge_lengths`);
    a tool not in it has ``default``.

    Returns
    -------
    list of (Program, float)
        Each section and its gauge length, mm; the first section's length is that of the
        first tool (``default`` before any).
    """
    parts = program.parts
    cuts: list[tuple[int, float]] = [(0, default)]
    seen_move = False  # a move before the tool change: it begins a section
    for i, part in enumerate(parts):
        if isinstance(part, Move) or (isinstance(part, MoveTable) and len(part)):
            seen_move = True
        elif isinstance(part, ToolChange):
            new = lengths.get(part.number, default)
            if not seen_move:
                cuts[0] = (0, new)
            elif new != cuts[-1][1]:
                cuts.append((i, new))
    out: list[tuple[Program, float]] = []
    for k, (i, length) in enumerate(cuts):
        stop = cuts[k + 1][0] if k + 1 < len(cuts) else len(parts)
        out.append((replace(program, blocks=Blocks(parts[i:stop]), tool_length=length), length))
    return out


def paired_sections(
    program: Program,
    toolpath: Toolpath,
    default: float,
    table: Mapping[int, float] | None = None,
) -> list[tuple[Program, Toolpath, float]]:
    """A machine-coordinate program and its CL data cut into the same tool sections, to be
    checked each with its gauge length.

    Parameters
    ----------
    program : Program
        As read back (a TCP program is one section).
    toolpath : Toolpath
        The CL data it is checked against.
    default : float, mm
        The job's tool length.
    table : mapping, optional
        The tool table (tool number to gauge length, mm).

    Returns
    -------
    list of (Program, Toolpath, float)
        Each section of the program, of the CL data, and its length (mm). One section, with
        the first tool's length, when the program does not change tools where the CL data
        changes length (the process check names that fault).
    """
    sections = tool_sections(toolpath, default, table)
    if program.tcp or len(sections) == 1:
        return [(program, toolpath, sections[0].length)]
    cut = program_sections(program, gauge_lengths(toolpath, default, table), default)
    if len(cut) != len(sections):
        return [(program, toolpath, sections[0].length)]
    return [
        (part, toolpath_slice(toolpath, s.start, s.stop), s.length)
        for (part, _), s in zip(cut, sections, strict=True)
    ]
