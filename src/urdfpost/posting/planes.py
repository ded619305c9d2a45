"""3+2 operations written in a tilted working plane.

An *operation at a fixed tilt* is a stretch of a TCP program's motion in which the rotary axes
stand still at values whose tool axis is off the program's Z, with at least one cut (a feed
move or a canned cycle) in it, and which the tool enters and leaves at a rapid (or at a block
that is not motion: a tool change, TCP off, the retract; not at a program stop or an inserted
block, which may come with the tool on the part): the rotary axes turn only between
operations. :func:`tilted_planes` writes each such stretch in a tilted working plane
(:class:`~urdfpost.program.TiltedPlane`: Heidenhain ``PLANE SPATIAL ... STAY``, Siemens
``CYCLE800``, Fanuc ``G68.2`` + ``G53.1``):

- the plane is switched on right after the move that turned the rotary axes to the stretch's
  values (TCP switched off first, the plane does what TCP did: the control points the tool
  tip in the plane's frame), and off after its last move; TCP is switched on again after it
  where the program goes on with TCP;
- the plane's Z is the tool axis at those rotary values and its X and Y the tool frame's (the
  machine's own axes in the plane: a table machine's linear axes move along the plane's); its
  angles are rounded as the control's format writes them, and the coordinates computed from
  the rounded frame, so that they are the CL points in the frame the control sets up;
- the moves in it are the same moves: a rotation changes neither the path nor its length, so
  the joint path, its collision check and the feeds stay as they were; the rotary axes are
  not written again in it;
- the machine's rotary clamps (the machine file's ``clamp`` setting, ``B:M10/M11``) are
  clamped right after the plane is switched on and released before it is switched off;
- the canned cycles' tilted holes in it (a :class:`~urdfpost.program.Cycle` with
  :attr:`~urdfpost.program.Cycle.up`) become the control's cycles in the plane, drilling along
  its Z; one whose stretch is not an operation at a fixed tilt is written as its motion, with
  a warning.

A control without a tilted plane (LinuxCNC: :attr:`DialectSpec.plane_convention` None), a
machine-coordinate program (whose positions are the joints: the post has done the kinematics
the plane would ask of the control) and a streamed post keep such stretches as five-axis moves
at fixed rotary values (``docs/job.md``). Verification reads a plane back through the same
frame (:func:`urdfpost.program.untilted`).
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from urdfpost.dialects.spec import DialectSpec
from urdfpost.kinematics.forward import tool_in_work
from urdfpost.machine import Machine
from urdfpost.program import (
    Arc,
    Block,
    Blocks,
    Clamp,
    Comment,
    Coolant,
    CutterComp,
    Cycle,
    Dwell,
    Insert,
    Move,
    MoveTable,
    Program,
    Smoothing,
    Spindle,
    Stop,
    Tcp,
    TiltedPlane,
    expand_cycle,
    modal_filled,
    plane_count,
)

__all__ = ["PlaneFigures", "plane_count", "tilted_planes"]

log = logging.getLogger(__name__)

STAND = 1e-9
"""Degrees. Rotary values this close are the same (they stand still between them)."""

ALONG_Z = 1e-6
"""The length of the difference of unit vectors under which a tool axis is the program's +Z
(no plane needed), as :data:`urdfpost.posting.body.NATIVE_AXIS`."""

_NEUTRAL = (Comment, Coolant, Spindle, Dwell, Smoothing)
"""Blocks that may come between the moves of an operation in a plane."""

_INSIDE = (Arc, CutterComp, Stop, Insert)
"""Blocks that end a stretch but neither begin nor end an operation: they may come with the
tool on the part (a stop or an inserted block between two cuts: the operation after it is not
entered at a rapid, and TCP is not switched off there for a plane)."""


@dataclass(frozen=True)
class _Stretch:
    """Rows ``first`` to ``last`` (of the program's motion rows) in one plane."""

    first: int
    last: int
    plane: TiltedPlane
    frame: np.ndarray  # (3, 3): the plane's axes, columns, from its rounded angles


@dataclass(frozen=True)
class PlaneFigures:
    """What :func:`tilted_planes` did.

    Attributes
    ----------
    planes : int
        Operations written in a tilted plane.
    cl_lines : tuple of int
        The CL line of each one's first cut (-1: none known).
    """

    planes: int = 0
    cl_lines: tuple[int, ...] = ()


def _rows(parts: Sequence[Block | MoveTable], width: int):
    """The program's motion rows: positions (N, m) as written (NaN: not written), rapid (N,),
    CL line (N,), the part of each (N,), the rows before which a block comes that ends an
    operation (a set), the rows of tilted holes (a set: a :class:`Cycle` with ``up``), and the
    rows before which an arc, a radius compensation switch, a program stop or an inserted
    block comes and no block that ends an operation away from the part (a set: what comes in
    the middle of an operation, the tool on the part, which neither begins nor ends it)."""
    position: list[np.ndarray] = []
    rapid: list[np.ndarray] = []
    line: list[np.ndarray] = []
    owner: list[np.ndarray] = []
    breaks: set[int] = set()
    tilted: set[int] = set()
    dirty: set[int] = set()
    lifted: set[int] = set()  # rows after a block that ends an operation away from the part
    count = 0
    for k, part in enumerate(parts):
        if isinstance(part, MoveTable | Move):
            table = part if isinstance(part, MoveTable) else MoveTable.from_moves([part], width)
            n = len(table)
            position.append(table.position)
            rapid.append(table.rapid)
            line.append(table.cl_line)
        elif isinstance(part, Cycle):
            n = 1
            position.append(np.array([part.holes[0]], dtype=float))
            rapid.append(np.array([False]))
            first = part.cl_lines[0] if part.cl_lines else None
            line.append(np.array([-1 if first is None else first]))
            if part.up is not None:
                tilted.add(count)
        else:
            if isinstance(part, _NEUTRAL) or (isinstance(part, Tcp) and part.on):
                continue
            breaks.add(count)
            (dirty if isinstance(part, _INSIDE) else lifted).add(count)
            continue
        owner.append(np.full(n, k))
        count += n
    dirty -= lifted  # (a tool change after a stop: the tool is away)
    if not position:
        empty = np.zeros(0, dtype=np.int64)
        return np.zeros((0, width)), np.zeros(0, bool), empty, empty, breaks, tilted, dirty
    return (
        np.concatenate(position),
        np.concatenate(rapid).astype(bool),
        np.concatenate(line),
        np.concatenate(owner),
        breaks,
        tilted,
        dirty,
    )


def _stretches(
    program: Program,
    machine: Machine,
    spec: DialectSpec,
    filled: np.ndarray,
    rapid: np.ndarray,
    breaks: set[int],
    entries: set[int],
    dirty: set[int],
) -> list[_Stretch]:
    """The operations at a fixed tilt (module docstring), in row order. ``entries``: the rows
    of tilted holes whose rotary values differ from the row before's; the cycle's rapid to
    its first hole turns them, and may begin an operation. ``dirty``: the rows after an arc or a
    radius compensation switch, which end a stretch but neither enter nor leave one."""
    axes = program.axes
    rotary = [j for j, a in enumerate(axes) if a in program.rotary]
    n = len(filled)
    if n == 0 or not rotary:
        return []
    values = filled[:, rotary]
    before = np.vstack([np.full((1, len(rotary)), np.nan), values[:-1]])
    stands = (np.abs(values - before) <= STAND).all(axis=1)  # (False where NaN)
    entry = np.array(sorted(entries), dtype=np.int64)
    stands[entry] = True
    breaks = breaks | entries
    cut = np.array(sorted(b for b in breaks if 0 < b < n), dtype=np.int64)
    starts = np.flatnonzero(stands & ~np.concatenate([[False], stands[:-1]]))
    starts = np.union1d(starts, cut[stands[cut]]) if cut.size else starts
    out: list[_Stretch] = []
    columns = [machine.axis_names.index(axes[j]) for j in rotary]
    # a stretch from row a goes on while the rows stand with nothing that ends it before them
    goes_on = stands.copy()
    goes_on[cut] = False
    stops = np.flatnonzero(~goes_on)
    ends = np.searchsorted(stops, starts + 1)
    lasts = np.where(ends < len(stops), stops[np.minimum(ends, len(stops) - 1)] - 1, n - 1)
    for a, b in zip(starts.tolist(), lasts.tolist(), strict=True):
        entered = a == 0 or (a in breaks and a not in dirty) or bool(rapid[a - 1])
        left = b == n - 1 or ((b + 1) in breaks and (b + 1) not in dirty) or bool(rapid[b + 1])
        if not (entered and left) or bool(rapid[a : b + 1].all()):
            continue
        q = machine.home.copy()
        q[columns] = np.radians(values[a])
        rotation, _ = tool_in_work(machine, q)
        tool = rotation[0]
        if float(np.linalg.norm(tool[:, 2] - np.array([0.0, 0.0, 1.0]))) <= ALONG_Z:
            continue
        assert spec.plane_convention is not None
        plane = TiltedPlane.of(tool, spec.plane_convention, spec.rotary.decimals)
        out.append(_Stretch(a, b, plane, plane.frame()))
    # a stretch starts after the one before (stands and starts give disjoint runs)
    return out


def tilted_planes(
    program: Program,
    machine: Machine,
    spec: DialectSpec,
    notes: list[str] | None = None,
    clamps: Sequence[tuple[str, int, int]] = (),
) -> tuple[Program, PlaneFigures]:
    """``program`` with its operations at a fixed tilt in tilted working planes, and its
    other tilted holes written as their motion (module docstring).

    Parameters
    ----------
    program : Program
        A whole program, the neutral one a post makes (its canned cycles' tilted holes as
        :class:`~urdfpost.program.Cycle` blocks with :attr:`~urdfpost.program.Cycle.up`).
    machine : Machine
    spec : DialectSpec
        The control: its plane convention and the rotary format its angles are rounded to.
    notes : list of str, optional
        Receives a warning per tilted hole written as its motion.
    clamps : sequence of (str, int, int)
        The machine's rotary clamps (:attr:`~urdfpost.machine.model.Settings.clamps`): the
        program's rotary axes among them are clamped after a plane is switched on and
        released before it is switched off.

    Returns
    -------
    Program
    PlaneFigures
    """
    parts = list(program.parts)
    width = len(program.axes)
    position, rapid, line, owner, breaks, tilted, dirty = _rows(parts, width)
    filled = modal_filled(position)
    rotary = [j for j, a in enumerate(program.axes) if a in program.rotary]
    entries = {
        r
        for r in tilted
        if r == 0 or not np.allclose(filled[r, rotary], filled[r - 1, rotary], rtol=0, atol=STAND)
    }
    usable = spec.plane_convention is not None and program.tcp
    stretches = (
        _stretches(program, machine, spec, filled, rapid, breaks, entries, dirty) if usable else []
    )
    xyz = [program.axes.index(a) for a in "XYZ"] if usable else []
    # per part, the plane of each of its rows (-1: none)
    in_plane = np.full(len(filled), -1, dtype=np.int64)
    for i, s in enumerate(stretches):
        in_plane[s.first : s.last + 1] = i
    # where each plane is switched on: right after the row that turned the rotary axes into
    # it (before the blocks that follow that row), or before its first row
    on_after = {
        s.first - 1: i
        for i, s in enumerate(stretches)
        if s.first > 0 and s.first not in breaks and s.first not in entries
    }
    # the first row of each part with motion (the rows are in part order)
    first_rows = np.flatnonzero(np.r_[True, owner[1:] != owner[:-1]]) if len(owner) else owner
    row_of_part = dict(zip(owner[first_rows].tolist(), first_rows.tolist(), strict=True))
    out: list[Block | MoveTable] = []
    tcp = [False]  # TCP on as the program has it
    out_tcp = [False]  # TCP on as written here
    offset: list[int | None] = [None]
    active = [-1]  # the plane on in the output
    spindle: list[Spindle | None] = [None]

    clamped = [a for a, _, _ in clamps if a in program.rotary and a in program.axes]

    def plane_on(i: int) -> None:
        if out_tcp[0]:
            out.append(Tcp(False))
            out_tcp[0] = False
        out.append(stretches[i].plane)
        out.extend(Clamp(a, True) for a in clamped)
        active[0] = i

    def plane_off() -> None:
        out.extend(Clamp(a, False) for a in reversed(clamped))
        out.append(TiltedPlane(None, stretches[active[0]].plane.convention))
        active[0] = -1

    def motion() -> None:
        """Before motion out of a plane: TCP on again where the program has it on."""
        if tcp[0] and not out_tcp[0]:
            out.append(Tcp(True, offset[0]))
            out_tcp[0] = True

    def moves(table: MoveTable, first_row: int) -> None:
        """The rows of ``table`` (program rows from ``first_row``), split at the planes."""
        n = len(table)
        k = 0
        while k < n:
            row = first_row + k
            plane = int(in_plane[row])
            j = k
            while j < n and int(in_plane[first_row + j]) == plane:
                j += 1
            piece = table.rows(k, j)
            if plane >= 0:
                if active[0] != plane:
                    plane_on(plane)
                s = stretches[plane]
                pos = filled[first_row + k : first_row + j].copy()
                pos[:, xyz] = pos[:, xyz] @ s.frame
                pos[:, rotary] = filled[s.first, rotary]
                piece = MoveTable(pos, piece.rapid, piece.feed, piece.cl_line)
            else:
                motion()
            out.append(piece)
            last = first_row + j - 1
            if plane >= 0 and last == stretches[plane].last:
                plane_off()
            if last in on_after:
                plane_on(on_after[last])
            k = j

    for k, part in enumerate(parts):
        if isinstance(part, Spindle):
            spindle[0] = part
        if isinstance(part, Tcp):
            tcp[0] = part.on
            if part.on:
                offset[0] = part.offset
            if active[0] < 0 and part.on != out_tcp[0]:
                out.append(part)
                out_tcp[0] = part.on
            # (in a plane the control points the tip as TCP does; a switch to where TCP is
            # already, after a plane, is not written)
        elif isinstance(part, MoveTable | Move):
            table = part if isinstance(part, MoveTable) else MoveTable.from_moves([part], width)
            if len(table):
                moves(table, row_of_part[k])
            else:
                out.append(part)
        elif isinstance(part, Cycle):
            row = row_of_part[k]
            plane = int(in_plane[row])
            if plane >= 0:
                if active[0] != plane:
                    if row in entries and part.up is not None:  # its rapid turns the rotary axes
                        motion()
                        above = filled[row] + part.retract * np.asarray(part.up)
                        out.append(Move(True, tuple(above.tolist())))
                    plane_on(plane)
                out.extend(_cycles_in_plane(part, stretches[plane], xyz, rotary, filled[row]))
                if row == stretches[plane].last:
                    plane_off()
            else:
                motion()
                if part.up is not None:
                    out.extend(expand_cycle(part, program.axes, spindle[0], part.up))
                    if notes is not None:
                        lines = [c for c in part.cl_lines if c is not None]
                        where = f"CL line {lines[0]}" if lines else "a hole"
                        notes.append(
                            f"{where}: the tilted hole is not in an operation at a fixed tilt "
                            "(its rotary axes turn at a feed move next to it); its holes are "
                            "written as their motion"
                        )
                else:
                    out.append(part)
            if row in on_after:
                plane_on(on_after[row])
        else:
            if isinstance(part, Arc):
                motion()
            out.append(part)
    figures = PlaneFigures(
        len(stretches),
        tuple(_first_cut(line, rapid, s) for s in stretches),
    )
    if stretches:
        log.info("%s: %d operations at a fixed tilt in tilted planes", program.name, len(stretches))
    return replace(program, blocks=Blocks(out)), figures


def _first_cut(line: np.ndarray, rapid: np.ndarray, s: _Stretch) -> int:
    """CL line of the first cut of ``s`` (-1: none known)."""
    for row in range(s.first, s.last + 1):
        if not rapid[row] and line[row] >= 0:
            return int(line[row])
    return -1


def _cycles_in_plane(
    cycle: Cycle, s: _Stretch, xyz: list[int], rotary: list[int], at: np.ndarray
) -> list[Block | MoveTable]:
    """``cycle`` (its holes in the program's frame) in the plane of ``s``: per height of its
    holes along the plane's Z, a rapid above the first hole at the retract height and the
    cycle at those holes (plane coordinates, drilled along the plane's Z)."""
    holes = np.array(cycle.holes, dtype=float)
    holes[:, xyz] = holes[:, xyz] @ s.frame
    holes[:, rotary] = at[rotary]
    if cycle.up is not None:
        up = np.asarray(cycle.up, dtype=float)[xyz] @ s.frame
        if float(np.linalg.norm(up - np.array([0.0, 0.0, 1.0]))) > 1e-4:
            raise AssertionError(f"a hole's axis {up} off its plane's Z")  # (same rotary values)
    out: list[Block | MoveTable] = []
    z = xyz[2]
    groups: list[list[int]] = []
    for i in range(len(holes)):
        scale = max(1.0, abs(holes[i, z]))
        if groups and abs(holes[i, z] - holes[groups[-1][0], z]) <= 1e-9 * scale:
            groups[-1].append(i)
        else:
            groups.append([i])
    lines = cycle.cl_lines or (None,) * len(holes)
    for group in groups:
        above = holes[group[0]].copy()
        above[z] += cycle.retract
        out.append(Move(True, tuple(above.tolist())))
        out.append(
            replace(
                cycle,
                holes=tuple(tuple(holes[i].tolist()) for i in group),
                cl_lines=tuple(lines[i] for i in group),
                up=None,
            )
        )
    return out
