"""The program header an operator reads before running a program: what it is for, which tools
it calls, how far the axes go, and the work offset; no date, so that the same job gives the
same text.

The header has a fixed number of comment lines whatever the job (the tools are listed on one
line), so that a streamed post can write a placeholder of the same lines first and the real
header once the last piece is known, without changing any block number after it
(:mod:`urdfpost.posting.stream`).

Example (a TCP job on dmu50, Heidenhain, mm)::

    ; urdfpost: machine dmu50, TCP (the control keeps the tool tip on the path), mm
    ; work offset: preset 1
    ; tools: T3 D6.000 L100.000
    ; axis ranges: X-14.871..14.871 Y-14.871..14.871 Z0.000..40.000 B0.0000..56.6392 ...
    ; tool axis: within 2 deg of the CL tool axis at singular spans, strategy cone: urdfpost ...
    ; run time about 26.6 s: feed 23.2 s, rapid 3.5 s, dwell 0.0 s; without acceleration and ...

The fifth line says how far the post's singularity strategy may bend the tool axis, which
``urdfpost verify`` must be told (:func:`bent_in_header` reads it back for its message); the
sixth how long the program runs (:meth:`~urdfpost.posting.report.FeedFigures.header_line`).
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from urdfpost.program import Comment, Cycle, Move, MoveTable, Program, ToolChange
from urdfpost.units import mm_per_unit

if TYPE_CHECKING:
    from urdfpost.posting.options import Job
    from urdfpost.posting.report import FeedFigures

__all__ = ["HeaderFigures", "bent_in_header", "header_text", "job_header", "stock_box"]


@dataclass
class HeaderFigures:
    """What the header says of the program, gathered piece by piece.

    Attributes
    ----------
    axes : tuple of str
        Program axis names.
    rotary : frozenset of str
    low, high : ndarray, shape (m,)
        Smallest and largest position of each axis in the moves seen (program units and
        degrees; inf / -inf for an axis not moved).
    tools : dict of int to (float or None, float or None)
        Tool number to (diameter, length), mm, in the order the tools are called.
    """

    axes: tuple[str, ...]
    rotary: frozenset[str]
    low: np.ndarray
    high: np.ndarray
    tools: dict[int, tuple[float | None, float | None]] = field(default_factory=dict)

    @classmethod
    def empty(cls, program: Program) -> HeaderFigures:
        """Nothing seen yet, for programs with the axes of ``program``."""
        m = len(program.axes)
        return cls(program.axes, program.rotary, np.full(m, np.inf), np.full(m, -np.inf))

    def add(self, program: Program) -> HeaderFigures:
        """Take in the moves, canned cycles and tool calls of ``program`` (a whole program or
        a piece)."""
        for part in program.parts:  # the tables as they are: no joined copy of the moves
            if isinstance(part, ToolChange) and part.number not in self.tools:
                self.tools[part.number] = (part.diameter, part.length)
                continue
            if isinstance(part, MoveTable):
                position = part.position
            elif isinstance(part, Cycle):  # its holes from the retract height to the bottom
                holes = np.asarray(part.holes, dtype=float)
                z = program.axes.index("Z")
                low_z, high_z = holes.copy(), holes.copy()
                low_z[:, z] -= part.depth
                high_z[:, z] += part.retract
                position = np.concatenate([low_z, high_z])
            elif isinstance(part, Move):
                position = np.asarray([part.position], dtype=float)
            else:
                continue
            if len(position):
                known = ~np.isnan(position)
                low = np.where(known, position, np.inf).min(axis=0)
                high = np.where(known, position, -np.inf).max(axis=0)
                np.minimum(self.low, low, out=self.low)
                np.maximum(self.high, high, out=self.high)
        return self


def _tool(number: int, diameter: float | None, length: float | None, scale: float, d: int) -> str:
    words = [f"T{number}"]
    if diameter is not None:
        words.append(f"D{diameter / scale:.{d}f}")
    if length is not None:
        words.append(f"L{length / scale:.{d}f}")
    return " ".join(words)


def header_text(
    figures: HeaderFigures,
    *,
    machine: str,
    tcp: bool,
    units: str,
    work_offset: str,
    tool_length: float,
    zero: str | None = None,
    tool_lengths: Mapping[int, float] | None = None,
    offsets: Mapping[str, np.ndarray] | None = None,
    rollover: frozenset[str] = frozenset(),
    strategy: tuple[str, float] | None = None,
    run: str | None = None,
) -> str:
    """The header's comment lines (without comment marks), one per line.

    Parameters
    ----------
    figures : HeaderFigures
    machine : str
        Machine name.
    tcp : bool
    units : str
        Program units ("mm" or "inch").
    work_offset : str
        The work offset as the control names it ("G54", "preset 1").
    tool_length : float, mm
        The tool length machine-coordinate positions were computed with.
    zero : str, optional
        Where the program zero sits on the machine, in words (the work offset line says it).
    tool_lengths : mapping of int to float, optional, mm
        A machine-coordinate program posted in tool sections (:mod:`urdfpost.posting.tools`):
        the gauge length of each tool, named instead of ``tool_length``.
    offsets : mapping of str to ndarray, optional
        A work offset per MCS (``--mcs-offsets``): each offset as the control names it and
        its MCS's origin in the first MCS (shape (3,), mm); the first is ``work_offset``.
    rollover : frozenset of str
        Rotary axes the control rolls over: their range counts turns, the program writes
        them modulo 360 (the line says so).
    strategy : tuple of (str, float), optional
        The singularity strategy's name and how far it may bend the tool axis (degrees): a
        line says so, and what ``urdfpost verify`` needs to be told (none: no such line).
    run : str, optional
        How long the program runs (:meth:`~urdfpost.posting.report.FeedFigures.header_line`;
        None: a line that says it is not known, as in a streamed post's placeholder).

    Returns
    -------
    str
        Four lines, with ``strategy`` the strategy's line and the run time's after them,
        and in machine coordinates a last one (the tool length the positions assume, which
        the control's tool table must not add again).
    """
    scale = mm_per_unit(units)
    decimals = 4 if units == "inch" else 3
    mode = "TCP (the control keeps the tool tip on the path)" if tcp else "machine coordinates"
    tools = ", ".join(
        _tool(n, dia, length, scale, decimals) for n, (dia, length) in figures.tools.items()
    )
    ranges = []
    for name, lo, hi in zip(figures.axes, figures.low, figures.high, strict=True):
        if not (np.isfinite(lo) and np.isfinite(hi)):
            continue
        d = 4 if name in figures.rotary else decimals
        rolls = " (rolls over: written modulo 360)" if name in rollover else ""
        ranges.append(f"{name}{lo:.{d}f}..{hi:.{d}f}{rolls}")
    offset_line = f"work offset: {work_offset}" + (f"; {zero}" if zero else "")
    if offsets and len(offsets) > 1:
        shifted = "; ".join(
            f"{name} = {work_offset} shifted by "
            f"({', '.join(f'{v / scale:.{decimals}f}' for v in shift)}) {units} (MCS {k})"
            for k, (name, shift) in enumerate(offsets.items())
            if k > 0
        )
        offset_line = f"work offsets: {work_offset} (MCS 0){f', {zero}' if zero else ''}; {shifted}"
    lines = [
        f"urdfpost: machine {machine}, {mode}, {units}",
        offset_line,
        f"tools: {tools or 'none'}",
        f"axis ranges: {' '.join(ranges) or 'no motion'}",
    ]
    if strategy is not None:
        lines.append(_strategy_line(*strategy))
        lines.append(run or "run time: not known")
    if not tcp and tool_lengths and len(set(tool_lengths.values())) > 1:
        each = ", ".join(f"T{n} {x:.3f}" for n, x in sorted(tool_lengths.items()))
        lines.append(
            f"machine coordinates with each tool's gauge length ({each} mm): the tool table "
            "lengths must be 0, and the work offset zero (the program zero's place is in the "
            "positions)"
        )
    elif not tcp:
        lines.append(
            f"machine coordinates with tool length {tool_length:.3f} mm from the gauge point: "
            "the tool table length must be 0, and the work offset zero (the program zero's place "
            "is in the positions)"
        )
    return "\n".join(lines)


def _strategy_line(name: str, bend_deg: float) -> str:
    """The header's line of the singularity strategy ``name`` that may bend the tool axis by
    ``bend_deg`` degrees (0, or the strategy ``none``: it follows the CL data's)."""
    if name == "none" or bend_deg <= 0.0:
        return f"tool axis: as in the CL data, strategy {name}"
    return (
        f"tool axis: within {bend_deg:g} deg of the CL tool axis at singular spans, strategy "
        f"{name}: urdfpost verify --angle-tolerance {bend_deg:g}"
    )


_BENT = re.compile(r"tool axis: within (\S+) deg .*verify --angle-tolerance (\S+)", re.I)


def bent_in_header(program: Program) -> float | None:
    """How far the program's header says its strategy may bend the tool axis (degrees; the
    line of :func:`header_text`, in any letter case), or None where it says nothing of it."""
    for part in program.parts:
        if isinstance(part, Comment) and (found := _BENT.search(part.text)):
            try:
                return float(found[2])
            except ValueError:
                return None
        if isinstance(part, Move | MoveTable):  # (the header comes before the first move)
            return None
    return None


def job_header(
    job: Job,
    figures: HeaderFigures,
    tool_length: float,
    tool_lengths: Mapping[int, float] | None = None,
    offsets: Mapping[int, np.ndarray] | None = None,
    run: FeedFigures | None = None,
) -> str:
    """:func:`header_text` for a job's program (``tool_length`` mm: the program's;
    ``tool_lengths``: each tool's, of a program in tool sections; ``offsets``: each work
    offset number's MCS origin in the first MCS, mm, with ``--mcs-offsets``; ``run``: the feed
    timing's figures, for the run time)."""
    spec = job.dialect.spec

    def named(number: int) -> str:
        return spec.work_offset_label.format(number=number, code=53 + number)

    label = named(job.work_offset)
    mount = job.machine.mount
    zero = None
    if mount is not None:
        x, y, z = mount.origin
        turned = f", turned {mount.setup.rotation:g} deg" if mount.setup.rotation else ""
        given = " (--setup)" if mount.setup != type(mount.setup)() else ""
        zero = f"program zero at {x:.3f} {y:.3f} {z:.3f} mm on {mount.parent}{turned}{given}"
    return header_text(
        figures,
        machine=job.machine.name,
        tcp=job.tcp,
        units=job.units,
        work_offset=label,
        tool_length=tool_length,
        zero=zero,
        tool_lengths=tool_lengths,
        offsets=None if not offsets else {named(n): v for n, v in sorted(offsets.items())},
        rollover=job.rollover,
        strategy=(job.strategy, job.angle_tolerance_deg),
        run=None if run is None else run.header_line(),
    )


def stock_box(job: Job) -> np.ndarray | None:
    """The lowest and highest corner of the job's stock mesh (shape (2, 3), mm, workpiece
    frame), or None without a stock."""
    if job.stock is None:
        return None
    from urdfpost.collision.mesh import load_mesh

    mesh = load_mesh(job.stock)
    return np.asarray(mesh.bounds, dtype=float) * mm_per_unit(job.units)
