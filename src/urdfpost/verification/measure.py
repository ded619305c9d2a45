"""Verification: a program's motion, run through the machine, compared with the CL data.

The program is taken as the control executes it: every block end goes through the forward
kinematics (tool tip and axis in the workpiece frame; the vectorised product of exponentials,
which the tests hold to Pinocchio on every shipped machine and on generated ones); between
feed blocks the axes are interpolated linearly as the control does (in TCP programs the tip
moves on the straight line and the rotary axes interpolate linearly), sampled densely, and the
worst sample refined by golden-section search in every block where that could change the
result (elsewhere a bound on the deviation between samples rules it out). The result is
compared with the CL path: tool-tip distance to the CL polyline, tool-axis angle to the CL
orientation path near the tip (:func:`_span_deviation`: on every CL segment the tip and the axis
move together on one parameter, and the axis is compared with the part of the segment's slerp
whose tip is within the tip tolerance of the sample's; the whole arc for a reorientation in
place; ``docs/verification.md``), and which CL points the program reaches, in order
(:mod:`urdfpost.verification.match`). Everything runs on arrays, in chunks of blocks.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, replace
from types import ModuleType

import numpy as np

from urdfpost._compiled import Kernels
from urdfpost.errors import DialectError, ProgramParseError
from urdfpost.geometry import (
    Arcs,
    Segments,
    VecArrays,
    angle_from_chord2,
    chunks,
    coords,
    may_reach,
    refine_max,
)
from urdfpost.kinematics.forward import (
    ChainArrays,
    chain_arrays,
    interpolation_bounds,
    tip_and_axis_along,
)
from urdfpost.linearize import RowPoses, _frame, orientation_path_chord2
from urdfpost.machine import Machine
from urdfpost.program import (
    Arc,
    Program,
    WorkOffset,
    arcs_as_moves,
    cycle_moves,
    expand_cycles,
    rewind_moves,
)
from urdfpost.tolerances import Tolerances
from urdfpost.toolpath import Toolpath
from urdfpost.verification.feeds import (
    TIP_SAMPLES,
    FeedCheck,
    FeedRules,
    block_trig,
    measure_feeds,
    tip_lengths,
)
from urdfpost.verification.holes import HOLES_NOTE, check_holes, without_holes
from urdfpost.verification.match import (
    at_pivot,
    match_points,
    nearness,
    program_joints,
    row_poses_at_tip,
)
from urdfpost.verification.planes import clamp_faults, in_own_frame

log = logging.getLogger(__name__)

_SAMPLES = 8
"""Samples inside every block, besides its ends (the bounds of :meth:`_Blocks.bounds` are of
second order in their spacing, so few blocks need refining after 8)."""

_LONG = 32
"""Blocks compared with more CL segments than this (a program that left the CL path, where a
run of CL points is missed) have their other segments searched with bounds
(:func:`_far_segments`) rather than one by one: the work per sample grows with the segments
near it, not with the span."""

_GROUPS = (64, 8)
"""Sizes of the groups of consecutive CL segments bounded by one sphere
(:meth:`_Polyline.spheres`), coarse to fine, each a multiple of the next."""

_ITERATIONS = 14
"""Golden-section iterations of the refinement: the bracket of two sample spacings shrinks to
under 3e-4 of the block."""

ARC_STEP_SHARE = 0.2
"""Longest chord between the moves an arc block is measured as, in shares of the tip
tolerance (:func:`urdfpost.program.arcs_as_moves`). Every point of the arc is within a tenth
of the tolerance of one of them: the CL points on the arc are reached, and the row that reaches
one, compared with the CL segment from it on, adds at most that tenth to the deviation
measured (the rows of lines pass through their CL points; an arc's need not)."""

_NEGLIGIBLE = 1e-9
"""Share of a tolerance below which a deviation is not refined (when nothing larger is seen)."""


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
        CL line nearest the worst deviation: of the tool axis when the orientation is beyond
        its tolerance by a larger share than the tip, else of the tool tip.
    tcp : bool
    notes : list of str
    compared : int
        How many deviations the mean is over (kept out of :meth:`as_dict`; merging the
        verifications of the pieces of a streamed post weighs their means by it).
    rewind_moves : int
        Moves of rewinds, not compared with the CL path (:func:`rewind_note`; kept out of
        :meth:`as_dict` too).
    feeds : FeedCheck or None
        The tip feed of the feed blocks against the CL feed, and the axes' speeds against
        their limits (:mod:`urdfpost.verification.feeds`); None where not measured. Part of
        :attr:`ok`.
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
    compared: int = 0
    rewind_moves: int = 0
    feeds: FeedCheck | None = None

    def as_dict(self) -> dict:
        """Plain data for JSON reports."""
        out = asdict(self)
        del out["compared"], out["rewind_moves"]
        return out

    def summary(self, units: str = "mm") -> str:
        """One paragraph for people, lengths in ``units``."""
        scale = 25.4 if units == "inch" else 1.0
        fmt = ".5f" if units == "inch" else ".4f"
        steps = ", ".join(f"{k} {v:.3f}" for k, v in self.max_rotary_step_deg.items())
        verdict = "within tolerance" if self.ok else "BEYOND TOLERANCE"
        text = (
            f"verification {verdict}: {self.reached}/{self.cl_points} CL points reached, "
            f"{self.blocks} blocks; tool tip deviation max {self.max_tip_deviation / scale:{fmt}} "
            f"mean {self.mean_tip_deviation / scale:{fmt}} {units} (tolerance "
            f"{self.tip_tolerance / scale:{fmt}}); tool axis deviation max "
            f"{self.max_orientation_deviation_deg:.4f} deg (tolerance "
            f"{self.orientation_tolerance_deg:.3f}); largest rotary step {steps or 'none'} deg"
            + "".join(f"; {note}" for note in self.notes if HOLES_NOTE in note)
        )
        return text if self.feeds is None else f"{text}; {self.feeds.summary()}"


def rewind_note(moves: int) -> str:
    """The note of a verification that left ``moves`` rewind moves out."""
    return f"{moves} rewind moves are not compared with the CL path"


def missed_note(lines: list[int]) -> str:
    """The note of a verification that missed the CL points of ``lines`` (not empty)."""
    return f"{len(lines)} CL points not reached, first at line {lines[0]}"


def _sampled_once(rows: np.ndarray) -> VecArrays:
    """Rows of an (n, 3) array as coordinate arrays of shape (1, n): one sample of n blocks."""
    x, y, z = coords(rows)
    return x[None], y[None], z[None]


@dataclass(frozen=True)
class _Polyline:
    """The CL path as segments: segment j runs from CL point j to j + 1 (the last is a point).

    The segments and arcs are made for the CL indices asked for (:meth:`take`), not kept for
    the whole path.

    With a pivot r (the measured point r up the tool axis from the tip: a ball centre), the
    CL points are those points, and the path between two of them is not their chord but the
    curve the CL segment moves that point on, the tip straight and the axis on its slerp:
    ``c(u) = A + u d + r g(u)``, with the chord from A to A + d and ``g(u) = slerp(u) -
    lerp(u)`` of the axes (:func:`_curve_distance2`). It leaves the chord by at most ``r (1 -
    cos(omega / 2))`` (:meth:`sag`), omega the angle the axis turns through.

    Attributes
    ----------
    tip : VecArrays
        Coordinate arrays of the CL points (at the pivot), shape (n,), mm.
    axis : VecArrays
        Of the CL tool axes (unit).
    pivot : float, mm
        How far up the tool axis from the tip the points are (0: the tip; the chords are the
        path).
    """

    tip: VecArrays
    axis: VecArrays
    pivot: float = 0.0
    _spheres: dict[int, tuple[VecArrays, np.ndarray]] = field(
        default_factory=dict, compare=False, repr=False
    )
    _omega: list[np.ndarray] = field(default_factory=list, compare=False, repr=False)
    _live: dict[int, tuple[np.ndarray, np.ndarray]] = field(
        default_factory=dict, compare=False, repr=False
    )

    @classmethod
    def of(cls, tip: np.ndarray, axis: np.ndarray, pivot: float = 0.0) -> _Polyline:
        """The polyline of CL points ``tip`` (at the pivot) and axes ``axis``, shape (n, 3)."""
        return cls(coords(tip), coords(axis), float(pivot))

    def __len__(self) -> int:
        return len(self.tip[0])

    def spheres(self, size: int) -> tuple[VecArrays, np.ndarray]:
        """Bounding spheres of the CL points ``size g .. size (g + 1)``, and so of the segments
        ``size g .. size (g + 1) - 1`` (with a pivot, of their curves: the radius grows by the
        largest :meth:`sag` of them): centres (coordinate arrays, mm) and radii (mm), shape
        (ceil(n / size),). Made once per size."""
        if size not in self._spheres:
            n = len(self)
            index = np.minimum(
                np.arange(0, max(n, 1), size)[:, None] + np.arange(size + 1), max(n - 1, 0)
            )
            pts = [c[index] for c in self.tip]
            centre = [p.mean(axis=1) for p in pts]
            r2 = sum((p - c[:, None]) ** 2 for p, c in zip(pts, centre, strict=True))
            radius = np.sqrt(np.max(r2, axis=1))
            if self.pivot and n:
                radius += np.maximum.reduceat(self.sag(), np.arange(0, n, size))
            self._spheres[size] = ((centre[0], centre[1], centre[2]), radius)
        return self._spheres[size]

    def sag(self, index: np.ndarray | None = None) -> np.ndarray:
        """How far the curve of each CL segment (of ``index``; None: all) leaves its chord
        at most: ``|r| (1 - cos(omega / 2)) = 2 |r| sin^2(omega / 4)`` (mm; 0 without a pivot).

        ``|slerp(u) - lerp(u)|`` of two unit vectors an angle omega apart is largest halfway,
        where it is ``1 - cos(omega / 2)`` (``tests/test_verify_curve.py`` checks it)."""
        omega = self.omega() if index is None else self.omega()[index]
        return _sag(omega, self.pivot)

    def omega(self) -> np.ndarray:
        """Angle of the arc of the axes from every CL point to the next (0 for the last),
        shape (n,), rad: :attr:`Arcs.omega` of :meth:`take` of every index. Made once."""
        if not self._omega:
            n = len(self)
            nxt = np.minimum(np.arange(1, n + 1), n - 1)
            ax, ay, az = self.axis
            self._omega.append(Arcs.of_coords(self.axis, (ax[nxt], ay[nxt], az[nxt])).omega)
        return self._omega[0]

    def live(self, size: int) -> tuple[np.ndarray, np.ndarray]:
        """The groups of ``size`` segments (``size g .. size (g + 1) - 1``) that hold a segment
        other than the one before it, and how many of them come before each group.

        A segment equal to the one before it (both endpoints and axes to the bit: three CL
        points in a row at one place, a dwell) is as near any sample as that one is and comes
        after it, so it is never the nearest (the first of equals), nor another chord within
        the window: the search passes over it (:func:`_far_segments`), and over a group of
        such segments only. Made once per size.

        Returns
        -------
        groups : ndarray, shape (k,), int
            Those groups, in order.
        before : ndarray, shape (ceil(n / size) + 1,), int
            ``before[g]``: how many of them are less than g.
        """
        if size not in self._live:
            n = len(self)
            same = np.zeros(n, dtype=bool)  # CL point i is point i - 1 again
            if n > 1:
                same[1:] = np.logical_and.reduce([c[1:] == c[:-1] for c in (*self.tip, *self.axis)])
            repeat = same & np.append(same[1:], True)  # segment i is segment i - 1 again
            count = np.add.reduceat(~repeat, np.arange(0, n, size)) if n else np.zeros(0, int)
            groups = np.flatnonzero(count > 0)
            self._live[size] = (groups, np.searchsorted(groups, np.arange(len(count) + 1)))
        return self._live[size]

    def take(self, index: np.ndarray) -> tuple[Segments, Arcs]:
        """The segments of the tips (mm) and the arcs of the axes (slerp) from CL points
        ``index`` to the next ones, shape (k,)."""
        nxt = np.minimum(index + 1, len(self) - 1)
        (px, py, pz), (ax, ay, az) = self.tip, self.axis
        segments = Segments.of_coords(
            (px[index], py[index], pz[index]), (px[nxt], py[nxt], pz[nxt])
        )
        arcs = Arcs.of_coords((ax[index], ay[index], az[index]), (ax[nxt], ay[nxt], az[nxt]))
        return segments, arcs


def _sag(omega: np.ndarray, pivot: float) -> np.ndarray:
    """``2 |pivot| sin^2(omega / 4)``: :meth:`_Polyline.sag` of arcs of angle omega (rad)."""
    quarter = np.sin(0.25 * omega)
    return 2.0 * abs(pivot) * (quarter * quarter)


_NEWTON = 8
"""Newton steps from the chord's projection to the nearest point of a CL segment's curve
(:func:`_curve_distance2`)."""

_SETTLED = 1e-12
"""A Newton step of the curve's parameter no larger than this ends the steps of a point: the
distance there is that of the nearest point to far below a nanometre (its error is of second
order in the step)."""


_FLAT = 1e-6
"""A CL segment whose curve leaves its chord by at most this (its sag, mm) is measured at the
curve's point at the chord's projection parameter, without Newton steps: that is a point of
the curve, and its distance exceeds the distance from the curve by at most twice the sag (the
chord's nearest point is within the sag of the curve, and the curve's point at its parameter
within the sag of it). Most segments of a finishing path are such: consecutive tool axes
0.1 degrees apart on a 3 mm ball give a sag of 1e-6 mm."""


def _curve_distance2(
    seg: Segments, arc: Arcs, points: VecArrays, s: np.ndarray, pivot: float
) -> tuple[np.ndarray, np.ndarray]:
    """Squared distance of points from the curves of CL segments with a pivot, and where on
    the curve it is measured.

    The curve (:class:`_Polyline`) is ``c(u) = A + u d + r g(u)``, u in [0, 1], with
    ``g(u) = alpha(u) v0 + beta(u) n`` in the arc's frame (v0 and the unit normal towards its
    end, :func:`urdfpost.linearize._frame`), ``alpha = cos(u omega) - 1 + u (1 - cos omega)``
    and ``beta = sin(u omega) - u sin omega``: the slerp less the straight line between the
    axes, 0 at both ends. From the chord's projection parameter, :data:`_NEWTON` Newton steps
    on ``|p - c(u)|^2 / 2`` (where its second derivative is not positive, Gauss-Newton's),
    each clipped to [0, 1] (a point's steps end once its step is at most :data:`_SETTLED`; a
    segment whose curve's sag is at most :data:`_FLAT` takes none); the smallest squared
    distance of the parameters met is taken.
    That is the distance to a point of the curve: never less than the distance from the
    curve, and equal to it once the steps converge (quadratically: the curve's curvature is
    at most ``r omega^2 / |c'|^2``, and a program within tolerance is within a fraction of a
    millimetre of it).

    Parameters
    ----------
    seg : Segments
        The chords (between the CL points at the pivot), shape (n,).
    arc : Arcs
        The arcs of the CL axes, shape (n,).
    points : VecArrays
        Coordinate arrays of shape (s, n) or (n,), mm.
    s : ndarray, shape of ``points[0]``
        The projection parameters on the chords, in [0, 1].
    pivot : float, mm

    Returns
    -------
    dist2 : ndarray, shape of ``s``, mm^2
    u : ndarray, shape of ``s``
        The parameter of the point of the curve measured to, in [0, 1].
    """
    _, normal, _ = _frame(arc)
    a, d, v0, omega = seg.a, seg.d, arc.v0, arc.omega
    cos_w, sin_w = np.cos(omega), np.sin(omega)
    steps = ~(_sag(omega, pivot) <= _FLAT)  # (the segments that take Newton steps)
    w0 = [points[i] - a[i] for i in range(3)]
    u, best, best_u = s, np.zeros(0), s
    for step in range(_NEWTON + 1):
        angle = u * omega
        cos_a, sin_a = np.cos(angle), np.sin(angle)
        alpha = (cos_a - 1.0) + u * (1.0 - cos_w)
        beta = sin_a - u * sin_w
        ra, rb = pivot * alpha, pivot * beta
        w = [w0[i] - u * d[i] - (ra * v0[i] + rb * normal[i]) for i in range(3)]
        d2 = w[0] * w[0] + w[1] * w[1] + w[2] * w[2]
        if step == 0:
            best, best_u = d2, u
        else:
            better = d2 < best
            best, best_u = np.where(better, d2, best), np.where(better, u, best_u)
        if step == _NEWTON:
            break
        da = (1.0 - cos_w) - omega * sin_a
        db = omega * cos_a - sin_w
        c1 = [d[i] + pivot * (da * v0[i] + db * normal[i]) for i in range(3)]
        bend = pivot * (omega * omega)
        c2 = [bend * (cos_a * v0[i] + sin_a * normal[i]) for i in range(3)]  # -c''(u)
        grad = w[0] * c1[0] + w[1] * c1[1] + w[2] * c1[2]
        speed2 = c1[0] * c1[0] + c1[1] * c1[1] + c1[2] * c1[2]
        curv = speed2 + (w[0] * c2[0] + w[1] * c2[1] + w[2] * c2[2])
        den = np.where(curv > 0.0, curv, speed2)
        move = np.divide(
            grad, den, out=np.zeros(np.broadcast_shapes(grad.shape, den.shape)), where=den > 0.0
        )
        # settled where the step is below _SETTLED (or clipped to nothing): the kernel stops
        # there, and the steps left would repeat this one
        nxt = np.where((np.abs(move) > _SETTLED) & steps, np.clip(u + move, 0.0, 1.0), u)
        if np.array_equal(nxt, u):
            break
        u = nxt
    return best, best_u


@dataclass(frozen=True)
class _FirstSpan:
    """The first CL segment and arc of the spans of blocks, how far the projection parameter
    of samples on that segment falls outside [0, 1] (shape (s, n); 0 inside), and the
    squared chord from their tool axes to the CL axis at that parameter (clipped; shape
    (s, n)), which bounds the deviation measured (:func:`orientation_path_chord2`); with a
    pivot, the parameter of the point of the segment's curve the samples are measured to
    (:func:`_curve_distance2`; None without)."""

    segments: Segments
    arcs: Arcs
    outside: np.ndarray
    at: np.ndarray
    par: np.ndarray | None = None


def _segment_errors(
    seg: Segments, arc: Arcs, points: VecArrays, axes: VecArrays, window: float, pivot: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
    """Squared tip distance and axis chord of samples from one CL segment and arc each
    (:func:`_span_deviation`'s measure), how far the projection parameter falls outside [0, 1],
    and the chord at the clipped parameter (:func:`orientation_path_chord2`), all of the
    samples' shape; and with a pivot, the parameter on the segment's curve the distance is
    measured at (None without).

    With a pivot the distance is from the segment's curve (:func:`_curve_distance2`), and the
    window of the axis grows by the curve's :meth:`_Polyline.sag`: the chord's projection
    parameter, about which the window is, is then within the window of the curve's nearest
    point for any sample within ``window`` of the curve."""
    outside: list[np.ndarray] = []
    d2, s = seg.distance2(points, outside)
    u = np.where(s >= 1.0, 1.0 + outside[0], s - outside[0])  # not clipped
    reach: float | np.ndarray = window
    par = None
    if pivot:
        d2, par = _curve_distance2(seg, arc, points, s, pivot)
        reach = window + _sag(arc.omega, pivot)
    half = np.where(seg.inv_dd > 0, reach * np.sqrt(seg.inv_dd), np.inf)  # window / |d|
    at, c2 = orientation_path_chord2(arc, axes, u, half)
    return d2, c2, outside[0], at, par


def _span_deviation(
    points: VecArrays,
    axes: VecArrays,
    polyline: _Polyline,
    ja: np.ndarray,
    jb: np.ndarray,
    window: float,
    first: list[_FirstSpan] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Distance of sample points from the CL polyline between CL indices ``ja`` and ``jb``, and
    of their tool axes from the CL orientation path there.

    On each CL segment the tip and the axis move together on one parameter (straight tip,
    slerp axis). The tip deviation is the distance to the nearest segment of the span; the
    axis deviation is the angle to the part of a segment's arc whose tip lies within
    ``window`` of the sample's, along the segment, of its projection
    (:func:`urdfpost.linearize.orientation_path_chord2`; the whole arc for a segment shorter
    than the window, such as a reorientation in place), the smallest over the segments whose
    tip is within ``window`` of the sample, or that of the nearest segment when none is
    (``docs/verification.md``). Spans of more than :data:`_LONG` segments are searched with
    bounds (:func:`_far_segments`), to the same result.

    Parameters
    ----------
    points, axes : VecArrays
        Coordinate arrays of shape (s, n): s samples of n blocks.
    polyline : _Polyline
    ja, jb : ndarray, shape (n,), int
        CL span of each block (``jb >= ja``).
    window : float, mm
        How far along a segment from the sample's tip the CL orientation is compared (the
        tip tolerance).
    first : list, optional
        When given, the span's first segment and arc, how far the projection parameter on
        that segment falls outside [0, 1], and the chord at that parameter are appended to it
        (:class:`_FirstSpan`).

    Returns
    -------
    dist2 : ndarray, shape (s, n), mm^2
        Squared distance from the nearest segment of the span (the first of equals).
    chord2 : ndarray, shape (s, n)
        Squared chord between the tool axis and the nearest CL orientation in the window
        (see :func:`urdfpost.geometry.angle_from_chord2`).
    """
    span = np.maximum(jb - ja, 1)
    last = len(polyline) - 1
    window2 = window * window
    dist2 = chord2 = within = np.zeros(0)
    long = span > _LONG
    short_max = int(span[~long].max(initial=1))
    for off in range(short_max):
        cols = np.flatnonzero((span > off) & ~long) if off else slice(None)
        a = np.minimum(ja[cols] + off, last)
        pts = points if off == 0 else (points[0][:, cols], points[1][:, cols], points[2][:, cols])
        axs = axes if off == 0 else (axes[0][:, cols], axes[1][:, cols], axes[2][:, cols])
        seg, arc = polyline.take(a)
        d2, c2, outside, at, par = _segment_errors(seg, arc, pts, axs, window, polyline.pivot)
        if off == 0:
            if first is not None:
                first.append(_FirstSpan(seg, arc, outside, at, par))
            dist2, chord2 = d2, c2
            within = np.where(d2 <= window2, c2, np.inf)  # best chord of the segments near
            continue
        better = d2 < dist2[:, cols]
        dist2[:, cols] = np.where(better, d2, dist2[:, cols])
        chord2[:, cols] = np.where(better, c2, chord2[:, cols])
        within[:, cols] = np.minimum(within[:, cols], np.where(d2 <= window2, c2, np.inf))
    if long.any():
        _far_segments(
            points, axes, polyline, ja, jb, window, np.flatnonzero(long), dist2, chord2, within
        )
    if int(span.max(initial=1)) > 1:
        chord2 = np.where(np.isfinite(within), within, chord2)
    return dist2, chord2


def _far_segments(
    points: VecArrays,
    axes: VecArrays,
    polyline: _Polyline,
    ja: np.ndarray,
    jb: np.ndarray,
    window: float,
    cols: np.ndarray,
    dist2: np.ndarray,
    chord2: np.ndarray,
    within: np.ndarray,
) -> None:
    """The segments after the first of long spans, for :func:`_span_deviation`: the same
    nearest segment (the first of equals), chord and best chord within the window as taking
    them one by one, from the segments that can be nearest or within the window only.

    A sample's distance from the span is at most its distance ``ub`` from any CL point of the
    span (one per group of segments looked at, and the first segment's distance, already
    known). A group of segments farther than ``max(ub, window)`` from the sample (by its
    bounding sphere, :meth:`_Polyline.spheres`; groups of :data:`_GROUPS` segments, coarse to
    fine) holds neither the nearest segment nor one within the window, and is not looked into;
    nor is a segment farther than that by its own bound (distance to its midpoint less half its
    length). The bounds get a relative and absolute slack of 1e-9 (mm) against rounding; more
    segments evaluated change nothing. Nor is a segment that is the one before it again, or a
    group of such segments only (:meth:`_Polyline.live`: a dwell, whose span would otherwise
    cost its length for every sample of every block over it).

    Parameters
    ----------
    points, axes, polyline, ja, jb, window
        As :func:`_span_deviation`.
    cols : ndarray, shape (m,), int
        The long blocks (their first segment, ``ja``, already in ``dist2``, ``chord2`` and
        ``within``).
    dist2, chord2, within : ndarray, shape (s, n)
        Updated in place at ``cols``.
    """
    s, m = points[0].shape[0], len(cols)
    px, py, pz = polyline.tip
    first, stop = ja[cols] + 1, jb[cols]  # the segments first .. stop - 1 of each block
    ub = np.sqrt(dist2[:, cols]).ravel()  # per key = sample * m + block, from the first segment
    # (key, group) pairs of the coarsest groups, each key's groups over its span
    size = _GROUPS[0]
    key, grp = _live_ranges(
        polyline, size, np.arange(s * m), np.tile(first // size, s), np.tile((stop - 1) // size, s)
    )

    def distance(key: np.ndarray, x: np.ndarray, y: np.ndarray, z: np.ndarray) -> np.ndarray:
        """Distance of each key's sample from the point (x, y, z), mm."""
        sample, block = key // m, cols[key % m]
        return np.sqrt(
            (points[0][sample, block] - x) ** 2
            + (points[1][sample, block] - y) ** 2
            + (points[2][sample, block] - z) ** 2
        )

    for level, size in enumerate((*_GROUPS, 1)):
        col = key % m
        if size > 1:  # groups: their spheres
            rep = np.clip(grp * size + size // 2, first[col], stop[col])  # a CL point of the span
            np.minimum.at(ub, key, distance(key, px[rep], py[rep], pz[rep]))
            (cx, cy, cz), radius = polyline.spheres(size)
            centre = (cx[grp], cy[grp], cz[grp])
            half_size = radius[grp]
        else:  # segments: their midpoints and half lengths
            np.minimum.at(ub, key, distance(key, px[grp], py[grp], pz[grp]))
            nxt = np.minimum(grp + 1, len(polyline) - 1)
            centre = tuple((c[grp] + c[nxt]) * 0.5 for c in polyline.tip)
            half_size = 0.5 * np.sqrt(
                (px[nxt] - px[grp]) ** 2 + (py[nxt] - py[grp]) ** 2 + (pz[nxt] - pz[grp]) ** 2
            )
            if polyline.pivot:  # the curve, within its sag of the chord
                half_size = half_size + polyline.sag(grp)
        threshold = np.maximum(ub, window) * (1.0 + 1e-9) + 1e-9
        keep = distance(key, *centre) - half_size <= threshold[key]
        key, grp, col = key[keep], grp[keep], col[keep]
        if size == 1:
            break
        finer = _GROUPS[level + 1] if level + 1 < len(_GROUPS) else 1
        lo = np.maximum(grp * size, first[col]) // finer
        hi = (np.minimum(grp * size + size, stop[col]) - 1) // finer
        key, grp = _live_ranges(polyline, finer, key, lo, hi)
    if not key.size:
        return
    sample, block, index = key // m, cols[key % m], grp
    seg, arc = polyline.take(index)
    pts = (points[0][sample, block], points[1][sample, block], points[2][sample, block])
    axs = (axes[0][sample, block], axes[1][sample, block], axes[2][sample, block])
    d2, c2, _, _, _ = _segment_errors(seg, arc, pts, axs, window, polyline.pivot)
    # per key: the nearest segment, the first of equals (the smallest index)
    order = np.lexsort((index, d2, key))
    head = order[np.r_[True, key[order][1:] != key[order][:-1]]]
    at = (sample[head], block[head])
    better = d2[head] < dist2[at]
    dist2[at] = np.where(better, d2[head], dist2[at])
    chord2[at] = np.where(better, c2[head], chord2[at])
    best = np.full(s * m, np.inf)
    np.minimum.at(best, key, np.where(d2 <= window * window, c2, np.inf))
    within[:, cols] = np.minimum(within[:, cols], best.reshape(s, m))


def _live_ranges(
    polyline: _Polyline, size: int, key: np.ndarray, lo: np.ndarray, hi: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The (key, group) pairs of every key's groups of ``size`` segments from ``lo`` to ``hi``
    (inclusive) that hold a segment other than the one before it (:meth:`_Polyline.live`),
    in order."""
    groups, before = polyline.live(size)
    a = before[lo]
    count = before[hi + 1] - a
    return np.repeat(key, count), groups[_ranges(a, count)]


def _ranges(start: np.ndarray, count: np.ndarray) -> np.ndarray:
    """``start[i], start[i] + 1, .., start[i] + count[i] - 1`` for every i, one after another."""
    return np.arange(int(count.sum())) - np.repeat(np.cumsum(count) - count - start, count)


@dataclass(frozen=True)
class _Blocks:
    """The feed blocks of a program, and how to evaluate them anywhere.

    Block i moves from program row ``start[i]`` to ``start[i] + 1`` and is compared with the CL
    span ``ja[i] .. jb[i]``, where ``valid[i]`` (None: every block); ``window`` (mm) is the
    window of :func:`_span_deviation`. The point measured is the polyline's pivot up the tool
    axis (:attr:`pivot`).
    """

    machine: Machine
    values: np.ndarray
    rows: RowPoses
    start: np.ndarray
    ja: np.ndarray
    jb: np.ndarray
    polyline: _Polyline
    tcp: bool
    tool_length: float
    window: float
    valid: np.ndarray | None = None

    @property
    def pivot(self) -> float:
        """How far up the tool axis from the tip the point measured is (mm): that of the CL
        points of the polyline."""
        return self.polyline.pivot

    def along(self, blocks: np.ndarray, t: np.ndarray) -> tuple[VecArrays | None, VecArrays]:
        """Tool tip (None in TCP programs) and axis along blocks at parameters t, the
        coordinate arrays of shape (s, k) of :func:`tip_and_axis_along`.

        The same for every comparison of one program (the pivot is added in :meth:`errors`).
        """
        q0, q1 = self.values[self.start[blocks]], self.values[self.start[blocks] + 1]
        return tip_and_axis_along(self.machine, q0, q1, t, self.tool_length, with_tip=not self.tcp)

    def errors(
        self,
        blocks: np.ndarray,
        t: np.ndarray,
        first: list[_FirstSpan] | None = None,
        along: tuple[VecArrays | None, VecArrays] | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Squared distance and chord (:func:`_span_deviation`) of blocks at parameters t.

        Parameters
        ----------
        blocks : ndarray, shape (k,), int
        t : ndarray, shape (s,) (the same for every block) or (s, k)
        first : list, optional
            See :func:`_span_deviation`.
        along : tuple, optional
            :meth:`along` of the same blocks and t, when known.

        Returns
        -------
        dist2, chord2 : ndarray, shape (s, k)
        """
        tip, axis = self.along(blocks, t) if along is None else along
        if tip is None:  # TCP: the control moves the tip on the straight line
            q0, q1 = self.values[self.start[blocks]], self.values[self.start[blocks] + 1]
            lin = list(self.machine.linear_columns)
            p0, dp = q0[:, lin], q1[:, lin] - q0[:, lin]
            tt = t[:, None] if t.ndim == 1 else t
            x, y, z = (p0[:, i] + tt * dp[:, i] + self.pivot * axis[i] for i in range(3))
            p = (x, y, z)
        elif self.pivot:
            x, y, z = (tip[i] + self.pivot * axis[i] for i in range(3))
            p = (x, y, z)
        else:
            p = tip
        return _span_deviation(
            p,
            axis,
            self.polyline,
            self.ja[blocks],
            self.jb[blocks],
            self.window,
            first,
        )

    def bounds(
        self,
        blocks: np.ndarray,
        dist2: np.ndarray,
        chord2: np.ndarray,
        span: _FirstSpan,
        h: float,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Upper bounds on the tip deviation (mm) and on the chord of the axis deviation over
        each whole block, from its samples (evenly spaced h apart, both ends included).

        Where a block is compared with one CL segment, from A to A + d, with ``|p'| <= L`` and
        ``|p''| <= M`` for the measured point p(t) and ``|a'| <= L_a``, ``|a''| <= M_a`` for the
        tool axis a(t) (:func:`interpolation_bounds`; in TCP programs p is the straight line
        plus the pivot times the tool axis):

        - the tip deviation is the distance of p(t) from the segment, a convex and 1-Lipschitz
          function of p: it is at most the largest sample plus ``M h^2 / 8`` (p stays that
          close to the chord between two samples, and on the chord the distance is at most the
          larger of theirs). With a pivot r it is the distance from the segment's curve c
          (:func:`_curve_distance2`), measured at the samples k to the points ``c(u_k)``: it is
          at most ``|p(t) - c(u(t))|`` with u linear between the samples' u_k, a function whose
          second derivative is at most ``M + r omega^2 (u_{k+1} - u_k)^2 / h^2`` (c is straight
          but for r times the slerp, of acceleration omega^2), so the bound gains ``r omega^2
          max (u_{k+1} - u_k)^2 / 8``;
        - the axis deviation (the chord to the nearest CL axis of the window about u, ``u =
          (p - A).d / |d|^2``, :func:`_span_deviation`) is at most the chord ``|a(t) -
          e(s(t))|`` to the CL slerp e (angle omega, speed omega) at the clipped projection
          parameter ``s = clip(u)``, which is in the window (its samples are
          ``span.at``). Without the clip, ``f = a - e(u)`` is smooth with ``|f''| <= M_a + omega^2
          u'^2 + omega |u''|``, ``|u'| <= L / |d|``, ``|u''| <= M / |d|``, so ``|f|`` is at
          most its largest sample plus ``|f''| h^2 / 8``; the clip moves e by at most omega
          times how far u is outside [0, 1], which between samples exceeds the largest sampled
          excess by at most ``|u''| h^2 / 8``. Together: the largest sampled chord, plus twice
          omega times the largest sampled excess, plus ``(M_a + omega^2 L^2 / |d|^2 + 2 omega
          M / |d|) h^2 / 8``. A first-order bound holds too (the chord changes at most at the
          speed ``L_a + omega L / |d|``: between two samples at most their mean plus that speed
          times h / 2). And the deviation itself moves, from the nearest sample, by at most
          the axis' motion ``L_a h / 2`` plus omega times the motion of the window's ends,
          which follow u and stay in [0, 1]: ``min(omega L / |d| h / 2, omega)`` (the bound
          that keeps blocks on micrometre segments, where ``L / |d|`` is huge, from being
          refined for nothing). The smallest of the three is taken.

        A block compared with more than one CL segment gets no bound (infinite).

        Parameters
        ----------
        blocks : ndarray, shape (k,), int
        dist2, chord2 : ndarray, shape (s, k)
            Samples from :meth:`errors`.
        span : _FirstSpan
            The blocks' first CL segments and arcs, how far the projection parameter falls
            outside [0, 1] at the samples and the chord at it (from :meth:`errors`).
        h : float

        Returns
        -------
        tip, chord : ndarray, shape (k,)
        """
        r = self.rows
        a, b = self.start[blocks], self.start[blocks] + 1
        q0, q1 = self.values[a], self.values[b]
        tip_speed, tip_curv, axis_speed, axis_curv = interpolation_bounds(
            self.machine, q0, q1, r.reach[a], r.reach[b], r.swing[a], r.swing[b]
        )
        if self.tcp:
            lin = list(self.machine.linear_columns)
            chord = np.linalg.norm(q1[:, lin] - q0[:, lin], axis=1)
            tip_speed = chord + abs(self.pivot) * axis_speed
            tip_curv = abs(self.pivot) * axis_curv
        ja = self.ja[blocks]
        inv_length = np.sqrt(span.segments.inv_dd)  # 0 for a point
        omega = span.arcs.omega
        spin = omega * tip_speed * inv_length
        g = np.sqrt(span.at)
        room = h * h / 8.0
        tip_bound = np.sqrt(dist2.max(axis=0)) + tip_curv * room
        if span.par is not None:  # the curve's bend between the parameters measured to
            du = span.par[1:] - span.par[:-1]
            tip_bound = tip_bound + abs(self.pivot) * (omega * omega) * (du * du).max(axis=0) / 8.0
        first = 0.5 * (g[1:] + g[:-1]).max(axis=0) + (axis_speed + spin) * (h / 2.0)
        curv = axis_curv + spin * spin + 2.0 * omega * tip_curv * inv_length
        second = g.max(axis=0) + 2.0 * omega * span.outside.max(axis=0) + curv * room
        # the deviation itself moves by at most the axis' motion plus omega times the window's
        # (at most the speed of u, and never more than the whole arc)
        moves = axis_speed * (h / 2.0) + np.minimum(spin * (h / 2.0), omega)
        third = np.sqrt(chord2.max(axis=0)) + moves
        chord_bound = np.minimum(np.minimum(first, second), third)
        one = self.jb[blocks] - ja <= 1
        return np.where(one, tip_bound, np.inf), np.where(one, chord_bound, np.inf)


@dataclass
class _Deviation:
    """What :func:`_block_deviation` measured in the blocks of one comparison.

    Attributes
    ----------
    tip : ndarray, shape (n,), mm
        Largest tip deviation seen per block (0 where the block is not compared).
    total : float, mm
        Sum of the sampled tip deviations.
    count : int
        Number of samples.
    chord2 : float
        Largest squared axis chord seen in any block.
    block_chord2 : ndarray, shape (n,)
        Largest squared axis chord seen per block (0 where the block is not compared).
    tip_length : ndarray or None, shape (n,), mm
        The tool tip's path length through every block's samples, the same numbers as
        :func:`urdfpost.verification.feeds.tip_lengths`, where the compiled pass worked them
        out on the way (None: not worked out).
    """

    tip: np.ndarray
    total: float
    count: int
    chord2: float
    block_chord2: np.ndarray
    tip_length: np.ndarray | None = None


COMPILED_FROM = 50_000
"""Feed blocks from which :func:`_block_deviation` samples, bounds and refines them with the
compiled loops (:mod:`urdfpost.verification._deviation_kernel`, with numba installed: the
``fast`` extra) rather than numpy: several times faster per block, after a fixed cost per process
(numba's import, shared with the compiled matching, and the cached machine code's loading)."""


def _load_kernels() -> ModuleType:
    from urdfpost.verification import _deviation_kernel

    return _deviation_kernel


KERNELS = Kernels(
    _load_kernels,
    "block deviation",
    start=COMPILED_FROM,
    stays=False,
    logger=log,
    warning="compiled %s unavailable (%s); numpy runs",
)
"""The compiled loops (:mod:`urdfpost.verification._deviation_kernel`), used from
:data:`COMPILED_FROM` feed blocks or rows on."""


@dataclass(frozen=True)
class _KernelInputs:
    """What the compiled first pass needs of one comparison, as contiguous arrays (made once
    per comparison; :func:`urdfpost.verification._deviation_kernel.block_deviation`).

    Attributes
    ----------
    chain : ChainArrays
    linear : ndarray, shape (3,), int64
        Columns of X, Y, Z.
    values : ndarray, shape (N, m)
    reach, swing : ndarray, shape (N, r)
    start, ja, jb : ndarray, shape (n,), int64
    valid : ndarray, shape (n,), bool
    omega : ndarray, shape (n_cl,), rad
        Angle of the CL arc from each CL point to the next (0 for the last).
    """

    chain: ChainArrays
    linear: np.ndarray
    values: np.ndarray
    reach: np.ndarray
    swing: np.ndarray
    start: np.ndarray
    ja: np.ndarray
    jb: np.ndarray
    valid: np.ndarray
    omega: np.ndarray

    @classmethod
    def of(cls, feed: _Blocks) -> _KernelInputs | None:
        """The inputs of ``feed``; None for a machine the kernel does not take (a TCP program
        on a machine without three linear axes)."""
        linear = np.array(feed.machine.linear_columns, dtype=np.int64)
        if feed.tcp and len(linear) != 3:
            return None
        ints = [np.ascontiguousarray(a, dtype=np.int64) for a in (feed.start, feed.ja, feed.jb)]
        n = len(feed.start)
        valid = np.ones(n, dtype=np.bool_) if feed.valid is None else feed.valid
        return cls(
            chain=chain_arrays(feed.machine, feed.tool_length),
            linear=np.resize(linear, 3),
            values=np.ascontiguousarray(feed.values, dtype=float),
            reach=np.ascontiguousarray(feed.rows.reach, dtype=float),
            swing=np.ascontiguousarray(feed.rows.swing, dtype=float),
            start=ints[0],
            ja=ints[1],
            jb=ints[2],
            valid=np.ascontiguousarray(valid, dtype=np.bool_),
            omega=feed.polyline.omega(),
        )


def _first_pass_compiled(
    kernel: Callable[..., None],
    inputs: _KernelInputs,
    feed: _Blocks,
    part: slice,
    t: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The first pass of :func:`_block_deviation` over the blocks of ``part`` of one
    comparison, compiled; the blocks of long spans (more than :data:`_LONG` CL segments) by
    numpy (:meth:`_Blocks.errors`).

    Returns
    -------
    dist2 : ndarray, shape (s, k), mm^2
        Squared tip distance of every sample (0 in blocks not compared).
    best : ndarray, shape (2, k)
        Largest squared distance and squared chord of each block.
    worst : ndarray, shape (2, k), int
        The samples they are at.
    bound : ndarray, shape (2, k)
        :meth:`_Blocks.bounds` (-inf in blocks not compared).
    length : ndarray, shape (k,), mm
        The tool tip's path through the samples of every block, compared or not
        (:func:`urdfpost.verification.feeds.tip_lengths` of them; 0 in TCP programs).
    """
    k, s = part.stop - part.start, len(t)
    dist2, best = np.empty((s, k)), np.empty((2, k))
    worst, bound = np.empty((2, k), dtype=np.int64), np.empty((2, k))
    long, length = np.empty(k, dtype=np.bool_), np.empty(k)
    c = inputs.chain
    trig = block_trig(c, inputs.values, inputs.start[part], t)  # as cos_sin_along
    (px, py, pz), (ax, ay, az) = feed.polyline.tip, feed.polyline.axis
    kernel(
        c.column,
        c.rotary,
        c.direction,
        c.pivot,
        c.rotary_index,
        inputs.linear,
        c.tool_point,
        c.home_axis,
        inputs.values,
        inputs.reach,
        inputs.swing,
        inputs.start[part],
        inputs.ja[part],
        inputs.jb[part],
        inputs.valid[part],
        px,
        py,
        pz,
        ax,
        ay,
        az,
        inputs.omega,
        trig,
        t,
        bool(feed.tcp),
        float(feed.pivot),
        float(feed.window),
        _LONG,
        dist2,
        best,
        worst,
        bound,
        long,
        length,
    )
    if long.any():  # searched with bounds by numpy; bounded by nothing (more than one segment)
        cols = np.flatnonzero(long)
        d2, c2 = feed.errors(cols + part.start, t)
        dist2[:, cols] = d2
        for i, e in enumerate((d2, c2)):
            worst[i, cols] = np.argmax(e, axis=0)
            best[i, cols] = e[worst[i, cols], np.arange(len(cols))]
        bound[:, cols] = np.inf
    return dist2, best, worst, bound, length


def _refine_compiled(
    kernel: Callable[..., None],
    inputs: _KernelInputs,
    feed: _Blocks,
    todo: np.ndarray,
    t: np.ndarray,
    worst: tuple[np.ndarray, np.ndarray],
    best: tuple[np.ndarray, np.ndarray],
    wanted: tuple[np.ndarray, np.ndarray],
) -> np.ndarray:
    """The refinement of :func:`_block_deviation` of the blocks ``todo`` of one comparison,
    compiled (:func:`urdfpost.verification._deviation_kernel.refine_deviation`): what
    :func:`refine_max` gives with the kernel's evaluations, every block's searches in one loop.
    The blocks of long spans (more than :data:`_LONG` CL segments) are left to numpy, as
    everything is when the kernel fails.

    Parameters
    ----------
    kernel : callable
    inputs : _KernelInputs
    feed : _Blocks
    todo : ndarray, shape (k,), int
        The blocks refined.
    t : ndarray, shape (s,)
        The first pass's sample parameters.
    worst, best, wanted : tuple of two ndarray, shape (n,)
        As :func:`refine_max`, of every block of the comparison; ``best`` is updated in place
        at the blocks refined here.

    Returns
    -------
    ndarray, shape (m,), int
        The blocks of ``todo`` left to refine.
    """
    ja, jb = inputs.ja[todo], inputs.jb[todo]
    short = np.maximum(jb - ja, 1) <= _LONG
    blocks = todo[short]
    found = np.stack([best[0][blocks], best[1][blocks]])
    c = inputs.chain
    try:
        kernel(
            c.column,
            c.rotary,
            c.direction,
            c.pivot,
            inputs.linear,
            c.tool_point,
            c.home_axis,
            inputs.values,
            inputs.start[blocks],
            ja[short],
            jb[short],
            *feed.polyline.tip,
            *feed.polyline.axis,
            inputs.omega,
            t,
            bool(feed.tcp),
            float(feed.pivot),
            float(feed.window),
            _ITERATIONS,
            np.stack([worst[0][blocks], worst[1][blocks]]).astype(np.int64),
            np.stack([wanted[0][blocks], wanted[1][blocks]]),
            found,
        )
    except Exception as err:  # numba could not compile or cache it here: numpy
        KERNELS.fail(err)
        return todo
    best[0][blocks], best[1][blocks] = found
    return todo[~short]


def _block_deviation(feeds: list[_Blocks], levels: list[tuple[float, float]]) -> list[_Deviation]:
    """Deviation of every feed block, sampled and refined where it can matter, in one or more
    comparisons of the same program blocks (the kinematics along them evaluated once).

    Every block is sampled at ``_SAMPLES + 2`` evenly spaced parameters, its ends included. The
    worst samples are refined by golden-section search (:func:`refine_max`) in the blocks where
    that could change what verification reports: where the bound of :meth:`_Blocks.bounds`
    reaches the largest deviation sampled in any block, or the level given (the largest at the
    program points). Elsewhere the refined value would stay below that, so the reported maxima
    (and the block they are in) are those of refining every block. From :data:`COMPILED_FROM`
    blocks on, with numba, both passes are compiled (:func:`_first_pass_compiled`,
    :func:`_refine_compiled`).

    Parameters
    ----------
    feeds : list of _Blocks
        The comparisons; the same machine, program values and blocks (``start``), each with
        its own CL spans, pivot and the blocks it compares (``valid``).
    levels : list of (float, float)
        Per comparison: no block needs refining below this tip deviation (mm) and squared axis
        chord.

    Returns
    -------
    list of _Deviation
    """
    n = len(feeds[0].start)
    t = np.linspace(0.0, 1.0, _SAMPLES + 2)
    h = float(t[1] - t[0])
    out = []
    best = [(np.zeros(n), np.zeros(n)) for _ in feeds]
    worst = [(np.zeros(n, dtype=int), np.zeros(n, dtype=int)) for _ in feeds]
    bound = [(np.zeros(n), np.zeros(n)) for _ in feeds]
    total = [0.0 for _ in feeds]
    kernels = KERNELS.get(n)
    kernel = None if kernels is None else kernels.block_deviation
    inputs = [_KernelInputs.of(feed) for feed in feeds] if kernel is not None else []
    # the tip's path through the samples, a by-product of the compiled pass (feeds.tip_lengths)
    lengths = np.empty(n)
    measured_lengths = kernel is not None and not feeds[0].tcp and len(t) == TIP_SAMPLES
    for part in chunks(n, len(t)):
        blocks = np.arange(part.start, part.stop)
        along: tuple[VecArrays | None, VecArrays] | None = None
        cols = np.arange(len(blocks))
        for f, feed in enumerate(feeds):
            ins = inputs[f] if kernel is not None else None
            if kernel is not None and ins is not None:
                try:
                    dist2, b2, w2, bd, ln = _first_pass_compiled(kernel, ins, feed, part, t)
                except Exception as err:  # numba could not compile or cache it here: numpy
                    KERNELS.fail(err)
                    kernel = None
                else:
                    if f == 0:
                        lengths[part] = ln
                    total[f] += float(np.sqrt(dist2).sum())
                    for i in range(2):
                        best[f][i][part], worst[f][i][part] = b2[i], w2[i]
                        bound[f][i][part] = bd[i]
                    continue
            if f == 0:
                measured_lengths = False
            if along is None:
                along = feeds[0].along(blocks, t)
            first: list[_FirstSpan] = []
            dist2, chord2 = feed.errors(blocks, t, first, along)
            valid = None if feed.valid is None else feed.valid[part]
            if valid is not None:
                dist2[:, ~valid] = 0.0
                chord2[:, ~valid] = 0.0
            total[f] += float(np.sqrt(dist2).sum())
            for i, e in enumerate((dist2, chord2)):
                worst[f][i][part] = np.argmax(e, axis=0)
                best[f][i][part] = e[worst[f][i][part], cols]
            tip_bound, chord_bound = feed.bounds(blocks, dist2, chord2, first[0], h)
            if valid is not None:  # blocks not compared are never refined
                tip_bound[~valid] = -np.inf
                chord_bound[~valid] = -np.inf
            bound[f][0][part], bound[f][1][part] = tip_bound, chord_bound
    for f, feed in enumerate(feeds):
        tip_level, chord2_level = levels[f]
        level = (
            max(float(np.sqrt(best[f][0].max(initial=0.0))), tip_level),
            float(np.sqrt(max(best[f][1].max(initial=0.0), chord2_level))),
        )
        wanted = (may_reach(bound[f][0], level[0]), may_reach(bound[f][1], level[1]))
        todo = np.flatnonzero(wanted[0] | wanted[1])
        log.debug(
            "verify: %d blocks, tip refined in %d, orientation in %d",
            n,
            wanted[0].sum(),
            wanted[1].sum(),
        )
        ins = inputs[f] if inputs else None
        kernels = KERNELS.load() if ins is not None and len(todo) else None  # (None: failed)
        if kernels is not None and ins is not None:
            refine = kernels.refine_deviation
            todo = _refine_compiled(refine, ins, feed, todo, t, worst[f], best[f], wanted)
        for part in chunks(len(todo), 4):  # four evaluations per block at a time
            sub = todo[part]

            def errors(
                idx: np.ndarray, tt: np.ndarray, sub: np.ndarray = sub, feed: _Blocks = feed
            ) -> tuple[np.ndarray, np.ndarray]:
                dist2, chord2 = feed.errors(sub[idx], tt[None, :])
                return dist2[0], chord2[0]

            refined = refine_max(
                errors,
                t,
                (worst[f][0][sub], worst[f][1][sub]),
                (best[f][0][sub], best[f][1][sub]),
                (wanted[0][sub], wanted[1][sub]),
                iterations=_ITERATIONS,
            )
            best[f][0][sub], best[f][1][sub] = refined
        compared = n if feed.valid is None else int(feed.valid.sum())
        out.append(
            _Deviation(
                tip=np.sqrt(best[f][0]),
                total=total[f],
                count=compared * len(t),
                chord2=float(best[f][1].max(initial=0.0)),
                block_chord2=best[f][1],
                tip_length=lengths if measured_lengths else None,
            )
        )
    return out


@dataclass(frozen=True)
class Check:
    """One comparison of a program with CL data (see :func:`verify`).

    Attributes
    ----------
    toolpath : Toolpath
    tol : Tolerances
    pivot : float, mm
        The point measured, this far up the tool axis from the tip.
    orientation_floor : float, rad
        An orientation deviation the program is known to reach elsewhere (in the pieces of a
        streamed program checked before this one): no block is refined for an orientation
        deviation below it, nor below the tolerance. The verification's maximum orientation
        deviation (and the block it names) is then exact where it reaches the smaller of the
        two, and below it otherwise; whether it is within the tolerance is always exact.
        0 (the default): every block that can reach the check's own maximum is refined.
    """

    toolpath: Toolpath
    tol: Tolerances
    pivot: float = 0.0
    orientation_floor: float = 0.0


def verify(
    program: Program,
    machine: Machine,
    toolpath: Toolpath,
    *,
    tool_length: float | None = None,
    tol: Tolerances | None = None,
    pivot: float = 0.0,
    feed_rules: FeedRules | None = None,
    orientation_floor: float = 0.0,
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
    feed_rules : FeedRules, optional
        How the program's control times its blocks: the tip feed of every feed block is
        measured against the CL feed (:attr:`Verification.feeds`). None: not measured.
    orientation_floor : float, rad
        An orientation deviation the program reaches elsewhere (:attr:`Check.orientation_floor`).

    Returns
    -------
    Verification
    """
    return verify_matched(
        program,
        machine,
        toolpath,
        tool_length=tool_length,
        tol=tol,
        pivot=pivot,
        feed_rules=feed_rules,
        orientation_floor=orientation_floor,
    )[0]


def verify_matched(
    program: Program,
    machine: Machine,
    toolpath: Toolpath,
    *,
    tool_length: float | None = None,
    tol: Tolerances | None = None,
    pivot: float = 0.0,
    feed_rules: FeedRules | None = None,
    orientation_floor: float = 0.0,
) -> tuple[Verification, np.ndarray | None]:
    """:func:`verify`, and the row of the program reaching each CL point as the verification
    matched them (:func:`~urdfpost.verification.match.match_points`), for a check of the same
    rows that needs the matching too (the process check of a piece:
    :meth:`urdfpost.verification.process.PieceStart.compare`).

    Parameters
    ----------
    program, machine, toolpath, tool_length, tol, pivot, feed_rules, orientation_floor
        As :func:`verify`.

    Returns
    -------
    verification : Verification
    match : ndarray, shape (len(toolpath),), int, or None
        The index of the move of ``program`` (:meth:`Program.move_table`) reaching each CL
        point, -1 where none does; None where the rows compared are not the program's moves
        (an arc, measured as moves along it; canned cycles, expanded, whose holes are checked
        on their own) or nothing was compared (no moves, no CL points).
    """
    tol = tol or Tolerances.for_units(program.units)
    (check,), matches = _verified(
        program, machine, [Check(toolpath, tol, pivot, orientation_floor)], tool_length, feed_rules
    )
    return check, None if matches is None else matches[0]


def verify_checks(
    program: Program,
    machine: Machine,
    checks: list[Check],
    tool_length: float | None = None,
    feed_rules: FeedRules | None = None,
) -> list[Verification]:
    """:func:`verify` of one program against several CL paths, tolerances or pivots.

    The program is read and run through the machine once: its joint values, the kinematics
    at its rows and along its blocks are shared by the comparisons.

    Parameters
    ----------
    program : Program
    machine : Machine
    checks : list of Check
    tool_length : float, optional, mm
        As :func:`verify`.
    feed_rules : FeedRules, optional
        As :func:`verify`: the tip feed is measured against each check's CL feed.

    Returns
    -------
    list of Verification
        One per check, in order.
    """
    return _verified(program, machine, checks, tool_length, feed_rules)[0]


def _verified(
    program: Program,
    machine: Machine,
    checks: list[Check],
    tool_length: float | None,
    feed_rules: FeedRules | None,
) -> tuple[list[Verification], list[np.ndarray] | None]:
    """:func:`verify_checks`, and per check the row reaching each CL point
    (:func:`verify_matched`; None where the rows compared are not the program's moves)."""
    if program.tcp and program.cut_without_tcp is not None:
        # its X/Y/Z would be machine positions among tool tips: no program of one kind
        path, line = program.cut_without_tcp
        raise ProgramParseError(
            path,
            line,
            "a feed move of X/Y/Z with TCP off in a TCP program; expected TCP on before "
            "every cutting move",
        )
    offsets = {b.number for b in program.parts if isinstance(b, WorkOffset)}
    if len(offsets) > 1:
        # positions in two frames: checked only section by section, each on its MCS's machine
        if program.offset_change is not None:
            path, line, change = program.offset_change
            what = f"work offset changes {change}"
        else:
            path, line = "<program>", 0
            what = f"work offsets {', '.join(str(n) for n in sorted(offsets))} selected"
        raise ProgramParseError(
            path,
            line,
            f"{what}; expected one work offset per program (a program with one per MCS is "
            "verified with --mcs-offsets)",
        )
    tool_length = program.tool_length if tool_length is None else tool_length
    clamped = clamp_faults(program)
    if clamped:
        raise ProgramParseError(program.name, 0, "; ".join(clamped))
    program = in_own_frame(program, machine)  # tilted planes: the moves in the program's frame
    if checks and any(isinstance(p, Arc) for p in program.parts):
        # an arc is measured as the control runs it: moves along it, at most half the tip
        # tolerance apart (so its CL points are reached by them and checked as every move)
        written = len(program.move_table()) + sum(isinstance(p, Arc) for p in program.parts)
        step = ARC_STEP_SHARE * min(c.tol.tip for c in checks)
        try:
            run = arcs_as_moves(program, step)
        except ValueError as e:
            raise ProgramParseError(program.name, 0, str(e)) from None
        out = verify_checks(run, machine, checks, tool_length, feed_rules)
        return [replace(v, blocks=written) for v in out], None
    try:  # canned cycles as the motion the control runs
        expanded = expand_cycles(program)
    except ValueError as e:
        raise DialectError(f"program {program.name}: {e}") from e
    own_rows = expanded is program
    program = expanded
    values, rapid = program_joints(machine, program)
    notes: list[str] = []
    # a rewind leaves the CL path on purpose (lift, turn, return): checked like a rapid, by
    # its end points only
    rewind = rewind_moves(program)
    if rewind.any():
        rapid = rapid | rewind
        notes.append(rewind_note(int(rewind.sum())))
    # so do the moves of canned cycles, whose holes are checked on their own (check_holes)
    cycle = cycle_moves(program)
    holes = []
    if cycle.any() or any(e.kind == "cycle" for c in checks for e in c.toolpath.events):
        drilled = row_poses_at_tip(machine, values, program.tcp, tool_length)
        feed = program.move_table().feed
        holes = [
            check_holes(c.toolpath, drilled.tip, drilled.axis, rapid, feed, cycle, c.tol)
            for c in checks
        ]
        rapid = rapid | cycle
        checks = [replace(c, toolpath=without_holes(c.toolpath)) for c in checks]
        own_rows = False  # (the CL points matched are those off the holes)
    out, matches = _verify_rows(
        program, machine, checks, tool_length, values, rapid, notes, feed_rules
    )
    if holes and any(h is not None for h in holes):
        out = [_with_holes(v, h, program.units) for v, h in zip(out, holes, strict=True)]
    return out, matches if own_rows else None


def _with_holes(verification: Verification, holes, units: str) -> Verification:
    """A verification with the check of the holes (:func:`check_holes`) added."""
    if holes is None:
        return verification
    return replace(
        verification,
        ok=verification.ok and holes.ok,
        cl_points=verification.cl_points + holes.holes,
        reached=verification.reached + holes.holes - len(holes.missing),
        missed_lines=sorted(verification.missed_lines + holes.missing),
        worst_cl_line=verification.worst_cl_line
        if holes.ok or (verification.worst_cl_line is not None and not verification.ok)
        else holes.bad_lines[0],
        notes=[*verification.notes, holes.note(units)],
    )


def _verify_rows(
    program: Program,
    machine: Machine,
    checks: list[Check],
    tool_length: float,
    values: np.ndarray,
    rapid: np.ndarray,
    notes: list[str],
    rules: FeedRules | None = None,
) -> tuple[list[Verification], list[np.ndarray] | None]:
    """:func:`verify_checks` of the program's rows (``values``, ``rapid`` as compared;
    ``rules``: the tip feed measured, as :func:`verify_checks` says), and per check the row
    reaching each CL point (None: nothing compared)."""
    rewind = rewind_moves(program)
    if len(values) == 0 or not all(len(c.toolpath) for c in checks):
        if len(values) and len(checks) > 1:  # compare those with CL points on their own
            out = [verify_checks(program, machine, [c], tool_length, rules)[0] for c in checks]
            return out, None
        return [_nothing_to_compare(program, values, c) for c in checks], None
    rows = row_poses_at_tip(machine, values, program.tcp, tool_length)
    steps: dict[str, float] = {}
    for a in machine.rotary:
        col = machine.axis_names.index(a.name)
        steps[a.name] = float(np.degrees(np.abs(np.diff(values[:, col])).max(initial=0.0)))
    blocks = np.flatnonzero(~rapid[1:]) + 1  # feed block k joins program points k-1 and k
    parts = [_Comparison.of(c, rows, rapid, blocks) for c in checks]
    feeds = [
        _Blocks(
            machine=machine,
            values=values,
            rows=part.rows,
            start=blocks - 1,
            ja=part.ja,
            jb=part.jb,
            polyline=part.polyline,
            tcp=program.tcp,
            tool_length=tool_length,
            window=c.tol.tip,
            valid=part.valid,
        )
        for c, part in zip(checks, parts, strict=True)
    ]
    deviations = _block_deviation(
        feeds, [part.levels(c) for c, part in zip(checks, parts, strict=True)]
    )
    out = [
        replace(
            part.verification(program, c, deviation, blocks, steps, notes),
            rewind_moves=int(rewind.sum()),
        )
        for c, part, deviation in zip(checks, parts, deviations, strict=True)
    ]
    matches = [part.match for part in parts]
    if rules is None:
        return out, matches
    q0, q1 = values[blocks - 1], values[blocks]
    known = deviations[0].tip_length
    tip = tip_lengths(machine, q0, q1, program.tcp, tool_length) if known is None else known
    feed = program.move_table().feed[blocks]
    measured = []
    for v, c, part in zip(out, checks, parts, strict=True):
        compared = np.ones(len(blocks), dtype=bool) if part.valid is None else part.valid
        cl_feed = np.where(compared, c.toolpath.feed[part.jb], np.nan)
        other = _feeds_at_points(c, part, blocks, cl_feed)
        check = measure_feeds(
            machine,
            program.feed_mode,
            program.tcp,
            program.units,
            q0,
            q1,
            feed,
            cl_feed,
            c.toolpath.line[part.jb],
            rules,
            c.tol.feed_share,
            tool_length,
            tip=tip,
            other_cl_feed=other,
        )
        measured.append(replace(v, feeds=check, ok=v.ok and check.ok))
    return measured, matches


def _feeds_at_points(
    check: Check, part: _Comparison, blocks: np.ndarray, cl_feed: np.ndarray
) -> np.ndarray | None:
    """The other CL feeds a feed block may be programmed at, where the CL feed changes at a
    CL point and the block lies at that point.

    A block's CL feed is that of the CL point its span ends at (``cl_feed``, the feed of
    ``jb``). But where the rows of a run of them all reach a CL point (points closer together
    than the tolerance, rows a strategy inserted next to the point), the row the matching
    takes for the point (the nearest in shares of both tolerances, :func:`match_points`) need
    not be the one the post took (the row at the point's position on the path), and a block
    between the two is at the point, after it or before it as one looks: both of its ends
    reach the point. Such a block may be programmed at the feed on either side of the point:
    at that of ``ja`` where both its ends reach ``ja``, at that of ``jb + 1`` where both reach
    ``jb``.

    Returns
    -------
    ndarray, shape (n_blocks, 2), mm/min, or None
        The feed of ``ja`` and that of ``jb + 1`` where the block may have it, else NaN; None
        where no block may.
    """
    feed, n = check.toolpath.feed, len(check.toolpath)
    ja, jb = part.ja, part.jb
    nxt = np.minimum(jb + 1, n - 1)
    compared = np.isfinite(cl_feed)
    sides = (
        (ja, feed[ja], compared & (feed[ja] != cl_feed)),
        (jb, feed[nxt], compared & (jb + 1 < n) & (feed[nxt] != cl_feed)),
    )
    if not any(changes.any() for _, _, changes in sides):
        return None
    out = np.full((len(blocks), 2), np.nan)
    toolpath, rows = check.toolpath, part.rows
    for side, (point, other, changes) in enumerate(sides):
        k = np.flatnonzero(changes)
        js = point[k]
        cl_tip = toolpath.tip[js] + check.pivot * toolpath.axis[js]
        cl_axis = toolpath.axis[js]
        near = np.ones(len(k), dtype=bool)
        for row in (blocks[k] - 1, blocks[k]):
            near &= nearness(rows.tip[row], rows.axis[row], cl_tip, cl_axis, check.tol) <= 1.0
        out[k[near], side] = other[k[near]]
    return out


def _nothing_to_compare(program: Program, values: np.ndarray, check: Check) -> Verification:
    """The verification of a program without motion, or against CL data without motion."""
    tol, n_cl = check.tol, len(check.toolpath)
    return Verification(
        ok=n_cl == 0,
        cl_points=n_cl,
        reached=0,
        missed_lines=[int(x) for x in check.toolpath.line],
        blocks=len(values),
        max_tip_deviation=0.0,
        mean_tip_deviation=0.0,
        max_orientation_deviation_deg=0.0,
        max_rotary_step_deg={},
        tip_tolerance=tol.tip,
        orientation_tolerance_deg=float(np.degrees(tol.orientation)),
        worst_cl_line=None,
        tcp=program.tcp,
        notes=["program has no motion" if len(values) == 0 else "CL data has no motion"],
    )


def _row_deviation(
    rows: RowPoses, polyline: _Polyline, ja: np.ndarray, jb: np.ndarray, window: float
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_span_deviation` of the program rows themselves (one sample each) against their
    CL spans ``ja .. jb``: squared distance (mm^2) and squared chord, shape (N,).

    From :data:`COMPILED_FROM` rows on, with numba, compiled
    (:func:`urdfpost.verification._deviation_kernel.point_deviation`; the rows of long spans
    by numpy); else by numpy in chunks.
    """
    n = len(rows.tip)
    dp2, op2 = np.empty(n), np.empty(n)
    kernels = KERNELS.get(n)
    todo: np.ndarray | None = None  # rows left to numpy (None: all)
    if kernels is not None:
        long = np.empty(n, dtype=np.bool_)
        try:
            kernels.point_deviation(
                rows.tip[:, 0],  # views (strided): no copies of the rows
                rows.tip[:, 1],
                rows.tip[:, 2],
                rows.axis[:, 0],
                rows.axis[:, 1],
                rows.axis[:, 2],
                np.ascontiguousarray(ja, dtype=np.int64),
                np.ascontiguousarray(jb, dtype=np.int64),
                *polyline.tip,
                *polyline.axis,
                polyline.omega(),
                polyline.pivot,
                float(window),
                _LONG,
                dp2,
                op2,
                long,
            )
        except Exception as err:  # numba could not compile or cache it here: numpy
            KERNELS.fail(err)
        else:
            todo = np.flatnonzero(long)
    for part in chunks(n if todo is None else len(todo), 1):
        at = part if todo is None else todo[part]
        at_rows = (_sampled_once(rows.tip[at]), _sampled_once(rows.axis[at]))
        d2, c2 = _span_deviation(*at_rows, polyline, ja[at], jb[at], window)
        dp2[at], op2[at] = d2[0], c2[0]
    return dp2, op2


@dataclass(frozen=True)
class _Comparison:
    """One check's view of a program: which CL points its rows reach, the CL span of every
    row and feed block, and the deviation at the rows.

    Attributes
    ----------
    rows : RowPoses
        At the check's pivot.
    polyline : _Polyline
        Of the CL points (at the pivot).
    match : ndarray, shape (n_cl,), int
        The row reaching each CL point, -1 where none does (:func:`match_points`).
    reached : ndarray, shape (n_cl,), bool
    before : ndarray, shape (N,), int
        Last CL index matched at or before each program row (-1 before the first).
    ja, jb : ndarray, shape (n_blocks,), int
        CL span of each feed block (0 where it is not compared).
    valid : ndarray or None, shape (n_blocks,), bool
        The feed blocks compared: those between the first and last CL point reached (None:
        all of them).
    row_tip : ndarray, shape (k,), mm
        Tip deviation at the rows compared (feed rows and rows reaching a CL point).
    row_chord2 : ndarray, shape (k,)
        Squared axis chord there.
    row_span : ndarray, shape (k,), int
        First CL index of their spans.
    """

    rows: RowPoses
    polyline: _Polyline
    match: np.ndarray
    reached: np.ndarray
    before: np.ndarray
    ja: np.ndarray
    jb: np.ndarray
    valid: np.ndarray | None
    row_tip: np.ndarray
    row_chord2: np.ndarray
    row_span: np.ndarray

    @classmethod
    def of(
        cls, check: Check, tip_rows: RowPoses, rapid: np.ndarray, blocks: np.ndarray
    ) -> _Comparison:
        """Match the CL points of ``check`` with the rows (poses at the tip ``tip_rows``)."""
        toolpath, n_cl = check.toolpath, len(check.toolpath)
        rows = at_pivot(tip_rows, check.pivot)
        cl_tip = toolpath.tip + check.pivot * toolpath.axis
        match = match_points(cl_tip, toolpath.axis, rows.tip, rows.axis, check.tol)
        reached = match >= 0
        # CL span of every program point: last CL index matched at or before it, first after
        owner = np.full(len(rows.tip), -1)
        owner[match[reached]] = np.flatnonzero(reached)
        before = np.maximum.accumulate(np.where(owner >= 0, owner, -1))
        after_src = np.where(owner >= 0, owner, n_cl)
        after = np.minimum.accumulate(after_src[::-1])[::-1]

        # the block ends themselves (rapids included) against their CL span
        ja_pt = np.maximum(before, 0)
        jb_pt = np.maximum(np.where(after < n_cl, after, n_cl - 1), ja_pt)
        polyline = _Polyline.of(cl_tip, toolpath.axis, check.pivot)
        dp2, op2 = _row_deviation(rows, polyline, ja_pt, jb_pt, check.tol.tip)
        feed_pts = ~rapid | (owner >= 0)

        # a feed block is compared along its length with its CL span unless it starts before
        # the first CL point, ends after the last, or starts at a rapid on no CL point: an
        # approach the post added (after a tool change, a home return), which leaves the CL
        # path on purpose; its end is compared as a row. (A program whose rapid misses its CL
        # point fails anyway: that point is not reached.)
        from_approach = rapid[blocks - 1] & (owner[blocks - 1] < 0)
        valid = (before[blocks - 1] >= 0) & (after[blocks] < n_cl) & ~from_approach
        ja = np.where(valid, before[blocks - 1], 0)
        jb = np.where(valid, np.maximum(after[blocks], ja), 0)
        return cls(
            rows=rows,
            polyline=polyline,
            match=match,
            reached=reached,
            before=before,
            ja=ja,
            jb=jb,
            valid=None if valid.all() else valid,
            row_tip=np.sqrt(dp2[feed_pts]),
            row_chord2=op2[feed_pts],
            row_span=ja_pt[feed_pts],
        )

    def levels(self, check: Check) -> tuple[float, float]:
        """What no block needs refining for: the largest deviation at a program row, or (when
        there is next to none) a billionth of the tolerance; for the orientation, at least the
        check's :attr:`~Check.orientation_floor` within the tolerance (tip mm, squared chord)."""
        tol = check.tol
        tip_level = max(self.row_tip.max(initial=0.0), _NEGLIGIBLE * tol.tip)
        floor = max(min(check.orientation_floor, tol.orientation), _NEGLIGIBLE * tol.orientation)
        chord2_level = max(self.row_chord2.max(initial=0.0), (2.0 * np.sin(floor / 2)) ** 2)
        return float(tip_level), float(chord2_level)

    def _worst_line(
        self, toolpath: Toolpath, compared: np.ndarray, in_blocks: np.ndarray, at_rows: np.ndarray
    ) -> int | None:
        """CL line of the largest of a deviation measured in the ``compared`` feed blocks and
        at the rows (a block names the CL point it starts from; None: nothing compared)."""
        if len(compared) and in_blocks.max() >= at_rows.max(initial=0.0):
            return int(toolpath.line[self.before[compared[int(np.argmax(in_blocks))] - 1]])
        if at_rows.size:
            return int(toolpath.line[self.row_span[int(np.argmax(at_rows))]])
        return None

    def verification(
        self,
        program: Program,
        check: Check,
        deviation: _Deviation,
        blocks: np.ndarray,
        steps: dict[str, float],
        notes: list[str],
    ) -> Verification:
        """The figures of this comparison, with the feed blocks' ``deviation``."""
        tol, toolpath = check.tol, check.toolpath
        dp = self.row_tip
        dmax = deviation.tip if self.valid is None else deviation.tip[self.valid]
        compared = blocks if self.valid is None else blocks[self.valid]
        max_tip = float(max(dmax.max(initial=0.0), dp.max(initial=0.0)))
        mean_tip = (deviation.total + float(dp.sum())) / max(deviation.count + dp.size, 1)
        max_chord2 = max(deviation.chord2, float(self.row_chord2.max(initial=0.0)))
        max_ori = float(angle_from_chord2(max_chord2))
        worst_line = self._worst_line(toolpath, compared, dmax, dp)
        if max_ori > tol.orientation and max_ori / tol.orientation > max_tip / tol.tip:
            cmax = deviation.block_chord2
            cmax = cmax if self.valid is None else cmax[self.valid]
            worst_line = self._worst_line(toolpath, compared, cmax, self.row_chord2)
        missed_lines = [int(x) for x in toolpath.line[~self.reached]]
        ok = not missed_lines and max_tip <= tol.tip and max_ori <= tol.orientation
        notes = list(notes)
        if missed_lines:
            notes.append(missed_note(missed_lines))
        return Verification(
            ok=bool(ok),
            cl_points=len(toolpath),
            reached=int(self.reached.sum()),
            missed_lines=missed_lines,
            blocks=len(self.rows.tip),
            max_tip_deviation=max_tip,
            mean_tip_deviation=float(mean_tip),
            max_orientation_deviation_deg=float(np.degrees(max_ori)),
            max_rotary_step_deg=steps,
            tip_tolerance=tol.tip,
            orientation_tolerance_deg=float(np.degrees(tol.orientation)),
            worst_cl_line=worst_line,
            tcp=program.tcp,
            notes=notes,
            compared=deviation.count + dp.size,
        )
