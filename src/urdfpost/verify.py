"""Verification: a program's motion, run through the machine, compared with the CL data.

The program is taken as the control executes it: every block end goes through Pinocchio's
forward kinematics (tool tip and axis in the workpiece frame); between feed blocks the axes are
interpolated linearly as the control does (in TCP programs the tip moves on the straight line and
the rotary axes interpolate linearly), sampled densely with a golden-section refinement of the
worst sample. The result is compared with the CL path: tool-tip distance to the CL polyline,
tool-axis angle to the CL axis interpolated (slerp) at the same place, and which CL points the
program reaches, in order.
"""

from __future__ import annotations

import logging
from dataclasses import asdict, dataclass, field

import numpy as np

from urdfpost.errors import DialectError
from urdfpost.kinematics.forward import tip_and_axis, tip_and_axis_pin
from urdfpost.linearize import angle_between, point_segment_distance, refine_max, slerp
from urdfpost.machine import Machine
from urdfpost.program import Program, rewind_moves
from urdfpost.tolerances import Tolerances
from urdfpost.toolpath import Toolpath

log = logging.getLogger(__name__)

_SAMPLES = 16


@dataclass(frozen=True)
class Verification:
    """What verification measured (lengths mm, angles degrees).

    Attributes
    ----------
    ok : bool
        Every CL point reached, tip and orientation deviations within tolerance.
    cl_points : int
    reached : int
    missed_lines : list of int
        CL source lines of the points the program does not reach (in order).
    blocks : int
        Motion blocks in the program.
    max_tip_deviation, mean_tip_deviation : float, mm
    max_orientation_deviation_deg : float
    max_rotary_step_deg : dict
        Largest step of each rotary axis between consecutive blocks.
    tip_tolerance : float, mm
    orientation_tolerance_deg : float
    worst_cl_line : int or None
        CL line nearest the worst tip deviation.
    tcp : bool
    """

    ok: bool
    cl_points: int
    reached: int
    missed_lines: list[int]
    blocks: int
    max_tip_deviation: float
    mean_tip_deviation: float
    max_orientation_deviation_deg: float
    max_rotary_step_deg: dict[str, float]
    tip_tolerance: float
    orientation_tolerance_deg: float
    worst_cl_line: int | None
    tcp: bool
    notes: list[str] = field(default_factory=list)

    def as_dict(self) -> dict:
        """Plain data for JSON reports."""
        return asdict(self)

    def summary(self, units: str = "mm") -> str:
        """One paragraph for people, lengths in ``units``."""
        scale = 25.4 if units == "inch" else 1.0
        fmt = ".5f" if units == "inch" else ".4f"
        steps = ", ".join(f"{k} {v:.3f}" for k, v in self.max_rotary_step_deg.items())
        verdict = "within tolerance" if self.ok else "BEYOND TOLERANCE"
        return (
            f"verification {verdict}: {self.reached}/{self.cl_points} CL points reached, "
            f"{self.blocks} blocks; tool tip deviation max {self.max_tip_deviation / scale:{fmt}} "
            f"mean {self.mean_tip_deviation / scale:{fmt}} {units} (tolerance "
            f"{self.tip_tolerance / scale:{fmt}}); tool axis deviation max "
            f"{self.max_orientation_deviation_deg:.4f} deg (tolerance "
            f"{self.orientation_tolerance_deg:.3f}); largest rotary step {steps or 'none'} deg"
        )


def program_joints(machine: Machine, program: Program) -> tuple[np.ndarray, np.ndarray]:
    """Joint values and rapid flags of a program's moves.

    Axes the program never writes stay at the machine's home; values not yet programmed at
    the start are taken from home too.

    Returns
    -------
    values : ndarray, shape (N, m)
        Machine axis order; X Y Z in mm (tool tip in workpiece coordinates for TCP programs),
        rotary in rad.
    rapid : ndarray, shape (N,), bool
    """
    moves = program.moves()
    unknown = [a for a in program.axes if a not in machine.axis_names]
    if unknown:
        raise DialectError(
            f"program {program.name} writes axes {' '.join(unknown)} that machine "
            f"{machine.name} does not have ({' '.join(machine.axis_names)})"
        )
    values = np.tile(machine.home, (len(moves), 1))
    if moves:
        pos = np.array([m.position for m in moves], dtype=float)
        for j, name in enumerate(program.axes):
            col = machine.axis_names.index(name)
            column = pos[:, j]
            if name in program.rotary:
                column = np.radians(column)
            # forward fill NaN (modal value not yet programmed), home before the first value
            ok = ~np.isnan(column)
            idx = np.where(ok, np.arange(len(column)), -1)
            idx = np.maximum.accumulate(idx)
            filled = np.where(idx >= 0, column[np.maximum(idx, 0)], values[:, col])
            values[:, col] = filled
    rapid = np.array([m.rapid for m in moves], dtype=bool)
    return values, rapid


def _pose(
    machine: Machine, values: np.ndarray, tcp: bool, tool_length: float, pin: bool
) -> tuple[np.ndarray, np.ndarray]:
    """Tool tip and axis for program values (rows), through Pinocchio when ``pin``."""
    fk = tip_and_axis_pin if pin else tip_and_axis
    if not tcp:
        return fk(machine, values, tool_length)
    q = values.copy()
    q[:, list(machine.linear_columns)] = 0.0
    _, axis = fk(machine, q, 0.0)
    return values[:, list(machine.linear_columns)].copy(), axis


def _match(
    cl_tip: np.ndarray,
    cl_axis: np.ndarray,
    tip: np.ndarray,
    axis: np.ndarray,
    tol: Tolerances,
) -> np.ndarray:
    """For each CL point, the program point at or after the previous match that reaches it (tip
    within tolerance, axis within orientation tolerance; the nearest of a run of such points),
    or -1.

    Returns
    -------
    ndarray, shape (n_cl,), int
    """
    n_cl, n = len(cl_tip), len(tip)
    out = np.full(n_cl, -1)
    ptr = 0
    for j in range(n_cl):
        start, width = ptr, 64
        while start < n:
            stop = min(n, start + width)
            d = np.linalg.norm(tip[start:stop] - cl_tip[j], axis=1)
            a = angle_between(axis[start:stop], cl_axis[j])
            hit = np.flatnonzero((d <= tol.tip) & (a <= tol.orientation))
            if hit.size:
                # CL points closer together than the tolerance: walk on to the nearest one
                k = start + int(hit[0])
                dist = float(np.linalg.norm(tip[k] - cl_tip[j]))
                while k + 1 < n:
                    nxt = float(np.linalg.norm(tip[k + 1] - cl_tip[j]))
                    if nxt >= dist:
                        break
                    k, dist = k + 1, nxt
                out[j] = k
                ptr = k
                break
            # a missed CL point must not make the search run away through the whole program
            if width >= 4096:
                break
            start, width = stop, width * 4
    return out


def _span_deviation(
    pts: np.ndarray,
    axes: np.ndarray,
    cl_tip: np.ndarray,
    cl_axis: np.ndarray,
    ja: np.ndarray,
    jb: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Distance of sample points to the CL polyline between CL indices ``ja`` and ``jb``.

    Parameters
    ----------
    pts, axes : ndarray, shape (n, s, 3)
        Samples of n blocks.
    ja, jb : ndarray, shape (n,), int
        CL span of each block (``jb >= ja``).

    Returns
    -------
    dist : ndarray, shape (n, s), mm
    ang : ndarray, shape (n, s), rad
    """
    n, s, _ = pts.shape
    dist = np.full((n, s), np.inf)
    ang = np.zeros((n, s))
    span = np.maximum(jb - ja, 1)
    last = len(cl_tip) - 1
    for off in range(int(span.max())):
        active = off < span
        a = np.minimum(ja + off, last)
        b = np.minimum(a + 1, last)
        d, t = point_segment_distance(pts, cl_tip[a][:, None, :], cl_tip[b][:, None, :])
        expected = slerp(cl_axis[a], cl_axis[b], t)
        o = angle_between(axes, expected)
        better = active[:, None] & (d < dist)
        dist = np.where(better, d, dist)
        ang = np.where(better, o, ang)
    return dist, ang


def verify(
    program: Program,
    machine: Machine,
    toolpath: Toolpath,
    *,
    tool_length: float | None = None,
    tol: Tolerances | None = None,
    pivot: float = 0.0,
) -> Verification:
    """Run a program through the machine and compare it with the CL data.

    Parameters
    ----------
    program : Program
        As written, or as read back from text by a dialect.
    machine : Machine
    toolpath : Toolpath
        The CL data the program was made from.
    tool_length : float, optional, mm
        Tool length machine-coordinate positions include (default: the program's).
    tol : Tolerances, optional
    pivot : float, mm
        Measure the point this far up the tool axis from the tip instead of the tip, on both
        sides (the ball centre of a ball-end tool, about which a strategy that bends the tool
        axis pivots). 0 measures the tip.

    Returns
    -------
    Verification
    """
    tol = tol or Tolerances.for_units(program.units)
    tool_length = program.tool_length if tool_length is None else tool_length
    values, rapid = program_joints(machine, program)
    notes: list[str] = []
    # a rewind leaves the CL path on purpose (lift, turn, return): checked like a rapid, by
    # its end points only
    rewind = rewind_moves(program)
    if rewind.any():
        rapid = rapid | rewind
        notes.append(f"{int(rewind.sum())} rewind moves are not compared with the CL path")
    n_cl = len(toolpath)
    if len(values) == 0 or n_cl == 0:
        return Verification(
            ok=n_cl == 0,
            cl_points=n_cl,
            reached=0,
            missed_lines=[int(x) for x in toolpath.line],
            blocks=len(values),
            max_tip_deviation=0.0,
            mean_tip_deviation=0.0,
            max_orientation_deviation_deg=0.0,
            max_rotary_step_deg={},
            tip_tolerance=tol.tip,
            orientation_tolerance_deg=float(np.degrees(tol.orientation)),
            worst_cl_line=None,
            tcp=program.tcp,
            notes=["program has no motion"] if len(values) == 0 else ["CL data has no motion"],
        )
    tip, axis = _pose(machine, values, program.tcp, tool_length, pin=True)
    tip = tip + pivot * axis
    cl_tip = toolpath.tip + pivot * toolpath.axis
    match = _match(cl_tip, toolpath.axis, tip, axis, tol)
    reached = match >= 0
    missed_lines = [int(x) for x in toolpath.line[~reached]]

    # CL span of every program point: last CL index matched at or before it, first after it
    owner = np.full(len(values), -1)
    owner[match[reached]] = np.flatnonzero(reached)
    before = np.maximum.accumulate(np.where(owner >= 0, owner, -1))
    after_src = np.where(owner >= 0, owner, n_cl)
    after = np.minimum.accumulate(after_src[::-1])[::-1]

    blocks = np.flatnonzero(~rapid[1:]) + 1  # feed block k joins program points k-1 and k
    blocks = blocks[(before[blocks - 1] >= 0) & (after[blocks] < n_cl)]
    dmax = np.zeros(len(blocks))
    dsum = 0.0
    count = 0
    omax = 0.0
    if len(blocks):
        q0, q1 = values[blocks - 1], values[blocks]
        ja = before[blocks - 1]
        jb = np.maximum(after[blocks], ja)
        t = np.linspace(0.0, 1.0, _SAMPLES + 2)[None, :].repeat(len(blocks), 0)

        def measure(tt: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            n, s = tt.shape
            q = q0[:, None, :] + tt[..., None] * (q1 - q0)[:, None, :]
            p, v = _pose(machine, q.reshape(n * s, -1), program.tcp, tool_length, pin=False)
            if program.tcp:
                p0, p1 = tip[blocks - 1], tip[blocks]
                p0, p1 = p0 - pivot * axis[blocks - 1], p1 - pivot * axis[blocks]
                p = (p0[:, None, :] + tt[..., None] * (p1 - p0)[:, None, :]).reshape(n * s, 3)
            p = p + pivot * v
            return _span_deviation(
                p.reshape(n, s, 3), v.reshape(n, s, 3), cl_tip, toolpath.axis, ja, jb
            )

        d, o = measure(t)
        dsum, count = float(d.sum()), d.size
        dmax = d.max(axis=1)
        omax = float(o.max())
        # refine the worst sample of each block (the maximum is not always at a sample)
        dmax = refine_max(lambda tt: measure(tt[:, None])[0][:, 0], t, d)
        omax = max(omax, float(refine_max(lambda tt: measure(tt[:, None])[1][:, 0], t, o).max()))
    # the block ends themselves (rapids included) against their CL span
    ja_pt = np.maximum(before, 0)
    jb_pt = np.where(after < n_cl, after, n_cl - 1)
    jb_pt = np.maximum(jb_pt, ja_pt)
    dp, op = _span_deviation(tip[:, None, :], axis[:, None, :], cl_tip, toolpath.axis, ja_pt, jb_pt)
    feed_pts = ~rapid | (owner >= 0)
    dp, op = dp[feed_pts, 0], op[feed_pts, 0]
    max_tip = float(max(dmax.max(initial=0.0), dp.max(initial=0.0)))
    mean_tip = (dsum + float(dp.sum())) / max(count + dp.size, 1)
    max_ori = max(omax, float(op.max(initial=0.0)))
    worst_line = None
    if len(blocks) and dmax.max() >= dp.max(initial=0.0):
        worst_line = int(toolpath.line[before[blocks[int(np.argmax(dmax))] - 1]])
    elif dp.size:
        worst_line = int(toolpath.line[ja_pt[feed_pts][int(np.argmax(dp))]])

    steps: dict[str, float] = {}
    for a in machine.rotary:
        col = machine.axis_names.index(a.name)
        steps[a.name] = float(np.degrees(np.abs(np.diff(values[:, col])).max(initial=0.0)))
    ok = not missed_lines and max_tip <= tol.tip and max_ori <= tol.orientation
    if missed_lines:
        notes.append(f"{len(missed_lines)} CL points not reached, first at line {missed_lines[0]}")
    return Verification(
        ok=bool(ok),
        cl_points=n_cl,
        reached=int(reached.sum()),
        missed_lines=missed_lines,
        blocks=len(values),
        max_tip_deviation=max_tip,
        mean_tip_deviation=float(mean_tip),
        max_orientation_deviation_deg=float(np.degrees(max_ori)),
        max_rotary_step_deg=steps,
        tip_tolerance=tol.tip,
        orientation_tolerance_deg=float(np.degrees(tol.orientation)),
        worst_cl_line=worst_line,
        tcp=program.tcp,
        notes=notes,
    )
