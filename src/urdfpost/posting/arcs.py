"""Which CL arcs a program writes as arcs (G2/G3, Heidenhain C), and their :class:`Arc` blocks.

The readers interpolate every CIRCLE record into points (planning, inverse kinematics,
collisions and verification work on points) and record the arc itself as an ``"arc"`` event
before its points (:mod:`urdfpost.readers.apt`). :func:`arc_spans` looks at each such arc and
the rows the post made of its points, and gives an :class:`ArcSpan` (the rows an :class:`Arc`
block replaces) where all of these hold; elsewhere the rows stay, linear, with a note saying why:

- the job writes arcs (``PostOptions.arcs``) and the control takes them in that plane, with
  TCP when the program is a TCP program, and as a helix when the arc climbs
  (:attr:`~urdfpost.dialects.spec.DialectSpec.arc_planes`, ``arc_tcp``, ``arc_helix``);
- the points are still the arc's: every one of them in the piece (a streamed piece may cut an
  arc), on the CIRCLE line, feed moves, with no event among them;
- the CL points are close chords of the arc (within :data:`CHORD_SHARE` of the tip
  tolerance), as the post's own reading gives them: the program is checked against them;
- the tool axis is fixed over the arc and the rotary axes stand still in every row of it (no
  rewind, no turn);
- the arc's plane is the XY, ZX or YZ plane of the program's frame: in TCP programs the
  workpiece frame; in machine-coordinate programs the machine's linear axes, found through the
  kinematics (with the rotary axes where they stand, the tip is an affine function of the
  linear axes, ``tip = M lin + c``; ``M`` must be a rotation, the linear axes orthonormal, and
  the arc's normal ``M^T n`` a machine axis);
- the start and end points are as far from the centre within :data:`RADIUS_SLACK` of the tip
  tolerance (a control refuses an arc whose end is off its circle), and at least
  :data:`MIN_CHORD` apart (rounded, a shorter arc could turn the other way round).

An arc of more than half a turn is written as several blocks of at most half a turn each
(:data:`MAX_SWEEP`), ending on interpolated CL points, so that a full circle, or several turns
(``TIMES``), is never an arc whose end is its start.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from urdfpost.dialects.spec import DialectSpec
from urdfpost.kinematics.forward import tip_and_axis
from urdfpost.machine import Machine
from urdfpost.planning.rewinds import CUT
from urdfpost.posting.body import ArcSpan, Rows
from urdfpost.program import ARC_PLANES, Arc
from urdfpost.tolerances import Tolerances
from urdfpost.toolpath import Event, Motion, Toolpath

#: Largest angle one Arc block turns (rad): half a turn.
MAX_SWEEP = math.pi

#: Share of the tip tolerance the distances of an arc's start and end from its centre may
#: differ by (the rest is the rounding of the written numbers and the path).
RADIUS_SLACK = 0.25

#: Share of the tip tolerance by which the arc may leave its plane at its radius (the tilt of
#: its normal from the program's axis times the radius).
PLANE_SLACK = 0.01

#: Largest turn of a rotary axis (rad), or of the tool axis, over an arc that still counts as
#: standing still.
STILL = 1e-9

#: Largest share of the tip tolerance the chords between an arc's CL points may leave it by:
#: the program is checked against those points, and the arc itself is that far from them
#: (the CL file read with a coarse chord tolerance: its arcs are written as lines).
CHORD_SHARE = 0.5

#: Shortest chord (mm) of an arc block: a shorter one could turn the other way round once its
#: ends are rounded to the written decimals (0.001 mm, 0.0001 in).
MIN_CHORD = 0.05

#: Largest move along the plane's normal (mm) of an arc that is no helix (a thousandth of the
#: last decimal a program writes: the rounding of the kinematics, not a climb).
CLIMB = 1e-6


@dataclass(frozen=True)
class ArcFigures:
    """What :func:`arc_spans` did.

    Attributes
    ----------
    spans : list of ArcSpan
        In row order.
    arcs : int
        CL arcs written as arcs (one or more blocks each).
    linear : int
        CL arcs written as lines.
    notes : list of str
        Why arcs were written as lines: one per reason, with the count and the first CIRCLE
        line.
    """

    spans: list[ArcSpan]
    arcs: int
    linear: int
    notes: list[str]


def _plane_of(normal: np.ndarray, radius: float, tip_tol: float) -> tuple[str, bool] | None:
    """The plane (key of :data:`ARC_PLANES`) whose normal is along ``normal`` (unit, program
    frame), and whether the arc turns clockwise seen from that normal's positive end (the arc
    turns counter-clockwise about ``normal``); None when it is no axis of the frame."""
    for plane, (_, _, axis) in ARC_PLANES.items():
        k = "XYZ".index(axis)
        tilt = math.sqrt(max(0.0, 1.0 - min(1.0, normal[k] * normal[k])))
        if radius * tilt <= PLANE_SLACK * tip_tol:
            return plane, bool(normal[k] < 0.0)
    return None


def _frame(machine: Machine, q: np.ndarray, tool_length: float) -> tuple[np.ndarray, np.ndarray]:
    """``M`` (3, 3) and ``c`` (3,) of ``tip = M lin + c`` with the rotary axes of ``q``, where
    ``lin`` are the values of the linear axes in the order X, Y, Z of their names."""
    lin = list(machine.linear_columns)
    names = [machine.axis_names[c] for c in lin]
    order = [lin[names.index(a)] for a in "XYZ"]
    base = np.tile(q, (4, 1))
    base[:, lin] = 0.0
    for i, col in enumerate(order):
        base[i + 1, col] = 1.0
    tip, _ = tip_and_axis(machine, base, tool_length)
    return (tip[1:] - tip[0]).T, tip[0]


def arc_spans(
    toolpath: Toolpath,
    arcs: list[Event],
    machine: Machine,
    rows: Rows,
    *,
    tcp: bool,
    tool_length: float,
    tol: Tolerances,
    spec: DialectSpec | None,
    events: list[Event],
    joints_before: np.ndarray | None = None,
) -> ArcFigures:
    """The arcs of a piece that its program writes as :class:`Arc` blocks.

    Parameters
    ----------
    toolpath : Toolpath
        The plan's CL data.
    arcs : list of Event
        Its ``"arc"`` events.
    machine : Machine
    rows : Rows
        The program's rows (:class:`~urdfpost.posting.body.Rows`).
    tcp : bool
        A TCP program.
    tool_length : float, mm
    tol : Tolerances
    spec : DialectSpec or None
        The control; None: arcs are not written (all are lines, no note).
    events : list of Event
        The piece's other events (an arc with one among its points is written as lines).
    joints_before : ndarray, shape (m,), optional
        A streamed piece that continues another: the joint vector at its first CL point,
        whose row the piece before wrote (``rows`` start after it); an arc from that point
        starts from that row.

    Returns
    -------
    ArcFigures
    """
    if spec is None or not arcs:
        return ArcFigures([], 0, 0, [])
    if any(a not in machine.axis_names for a in "XYZ"):
        return ArcFigures(
            [],
            0,
            len(arcs),
            [f"{len(arcs)} CL arcs written as lines: the machine has no X, Y and Z axes"],
        )
    n = len(toolpath)
    shift = 0  # rows put before the piece's own: the row of its first point, already written
    if joints_before is not None and n:
        shift = 1
        rows = Rows(
            q=np.vstack([joints_before, rows.q]),
            tip=np.vstack([toolpath.tip[:1], rows.tip]),
            point=np.concatenate([[0], rows.point]),
            reaches=np.concatenate([[True], rows.reaches]),
            kind=np.concatenate([[CUT], rows.kind]),
        )
    position = program_positions(machine, rows, tcp)
    reasons: dict[str, list[int]] = {}
    spans: list[ArcSpan] = []
    written = 0
    axes = machine.axis_names
    rotary = list(machine.rotary_columns)
    # the row reaching each CL point (-1: none)
    reach_row = np.full(n + 1, -1)
    reaching = np.flatnonzero(rows.reaches)
    reach_row[rows.point[reaching]] = reaching
    event_at = np.zeros(n + 2, dtype=np.int64)
    for e in events:
        event_at[min(e.index, n + 1)] += 1
    event_count = np.concatenate([[0], np.cumsum(event_at)])

    def linear(why: str, line: int) -> None:
        reasons.setdefault(why, []).append(line)

    for arc in arcs:
        line = arc.line
        first, count = arc.index, int(arc.data["points"])
        start, end = first - 1, first + count - 1
        if not spec.arc_planes:
            linear(f"{spec.name} takes no arcs here", line)
            continue
        if start < 0 or end >= n:
            linear("the arc is cut by the end of a streamed piece", line)
            continue
        pts = slice(first, end + 1)
        if (toolpath.line[pts] != line).any() or (toolpath.motion[pts] != Motion.FEED).any():
            linear("the strategy changed the arc's points", line)
            continue
        if event_count[end + 1] - event_count[first] > 0:
            linear("an event comes among the arc's points", line)
            continue
        r0, r1 = int(reach_row[start]), int(reach_row[end])
        if r0 < 0 or r1 <= r0:
            linear("the program has no row at the arc's start or end", line)
            continue
        span = slice(r0, r1 + 1)
        if (rows.kind[span] != CUT).any() or (rows.point[r0 + 1 : r1 + 1] < first).any():
            linear("a rewind or a turn in place on the arc", line)
            continue
        axis = toolpath.axis[start : end + 1]
        if (np.linalg.norm(axis - axis[0], axis=1) > STILL).any():
            linear("the tool axis changes over the arc", line)
            continue
        if rotary and (np.ptp(rows.q[span][:, rotary], axis=0) > STILL).any():
            linear("the rotary axes move over the arc", line)
            continue
        sagitta = _sagitta(float(arc.data["radius"]), float(arc.data["sweep"]), count)
        if sagitta > CHORD_SHARE * tol.tip:
            linear(
                "its CL points are chords more than half the tip tolerance off the arc (the CL "
                "data was read with a coarser chord tolerance)",
                line,
            )
            continue
        if tcp and not spec.arc_tcp:
            linear(f"{spec.name} takes no arcs with TCP on", line)
            continue
        centre = np.asarray(arc.data["centre"], dtype=float)
        normal = np.asarray(arc.data["normal"], dtype=float)
        radius = float(arc.data["radius"])
        if tcp:
            frame_centre, frame_normal = centre, normal
        else:
            m, c = _frame(machine, rows.q[r0], tool_length)
            if np.abs(m.T @ m - np.eye(3)).max() > 1e-9:
                linear("the machine's linear axes are not orthonormal", line)
                continue
            frame_centre, frame_normal = m.T @ (centre - c), m.T @ normal
        plane = _plane_of(frame_normal, radius, tol.tip)
        if plane is None:
            linear("the arc is in no XY, ZX or YZ plane of the program", line)
            continue
        name, clockwise = plane
        if name not in spec.arc_planes:
            linear(f"{spec.name} takes no arcs in the {name} plane", line)
            continue
        xyz = position[span][:, [axes.index(a) for a in "XYZ"]]
        normal_axis = "XYZ".index(ARC_PLANES[name][2])
        climb = float(np.abs(xyz[:, normal_axis] - xyz[0, normal_axis]).max())
        if climb > CLIMB and not spec.arc_helix:
            linear(f"{spec.name} takes no helix", line)
            continue
        cut = _cut_points(count, float(arc.data["sweep"]))
        blocks = _blocks(xyz, frame_centre, name, cut, rows.point[span] - start, tol.tip)
        if isinstance(blocks, str):
            linear(blocks, line)
            continue
        feed = float(toolpath.feed[end])
        for a, b, row in blocks:
            spans.append(
                ArcSpan(
                    first=r0 + a + 1 - shift,
                    last=r0 + b - shift,
                    block=Arc(
                        position=tuple(float(v) for v in position[r0 + b]),
                        centre=row,
                        plane=name,
                        clockwise=clockwise,
                        feed=feed if math.isfinite(feed) else None,
                        cl_line=line,
                    ),
                )
            )
        written += 1
    notes = [
        f"{len(lines)} CL arcs written as lines: {why} (first at CIRCLE line {lines[0]})"
        for why, lines in reasons.items()
    ]
    return ArcFigures(spans, written, sum(map(len, reasons.values())), notes)


def _sagitta(radius: float, sweep: float, count: int) -> float:
    """Largest distance (mm) of the arc from the chords between its ``count`` interpolated
    points (evenly spaced over ``sweep`` rad, radius ``radius`` mm)."""
    return radius * (1.0 - math.cos(0.5 * sweep / max(count, 1)))


def program_positions(machine: Machine, rows: Rows, tcp: bool) -> np.ndarray:
    """The rows' positions as the program writes them, shape (N, m): mm and degrees, the tip
    for X, Y, Z in TCP programs (what :func:`urdfpost.posting.body.program_body` writes)."""
    position = rows.q.copy()
    rotary = list(machine.rotary_columns)
    position[:, rotary] = np.degrees(position[:, rotary])
    if tcp:
        position[:, list(machine.linear_columns)] = rows.tip
    return position


def _cut_points(count: int, sweep: float) -> list[int]:
    """Indices (1..count) of the interpolated points the blocks of an arc of ``count`` points
    turning ``sweep`` (rad) end on: each block at most :data:`MAX_SWEEP` (the points are
    evenly spaced in angle)."""
    pieces = max(1, math.ceil(sweep / (0.9 * MAX_SWEEP) - 1e-12))
    cuts = sorted({max(1, round(count * i / pieces)) for i in range(1, pieces + 1)})
    return [c for c in cuts if c <= count]


def _blocks(
    xyz: np.ndarray,
    centre: np.ndarray,
    plane: str,
    cuts: list[int],
    point: np.ndarray,
    tip_tol: float,
) -> list[tuple[int, int, tuple[float, float, float]]] | str:
    """The blocks of one arc: (row after which it starts, row it ends on, centre) with rows
    counted from the arc's start row; or, when one cannot be written, why not (an end off the
    circle, a chord under :data:`MIN_CHORD`).

    ``xyz`` (k, 3) are the rows' X, Y, Z (mm), ``centre`` (3,) the arc's (mm), ``cuts`` the
    interpolated points the blocks end on (:func:`_cut_points`), ``point`` (k,) the CL point
    of each row counted from the start point (0) to the end (count).
    """
    first, second, normal = ARC_PLANES[plane]
    i, j, n = ("XYZ".index(a) for a in (first, second, normal))
    radius = np.hypot(xyz[:, i] - centre[i], xyz[:, j] - centre[j])
    out = []
    a = 0
    for cut in cuts:
        at = np.flatnonzero(point == cut)
        if not at.size:
            return "the program has no row at an interpolated point of the arc"
        b = int(at[-1])
        if abs(radius[b] - radius[a]) > RADIUS_SLACK * tip_tol:
            return "the arc's ends are not as far from its centre"
        if math.hypot(xyz[b, i] - xyz[a, i], xyz[b, j] - xyz[a, j]) < MIN_CHORD:
            return f"the arc's ends are closer than {MIN_CHORD} mm"
        row = centre.copy()
        row[n] = xyz[a, n]  # the centre is given at the start's height
        out.append((a, b, (float(row[0]), float(row[1]), float(row[2]))))
        a = b
    return out
