"""Nonlinear error of joint-space interpolation, and subdivision until it is within tolerance.

Between two blocks a control without tool-centre-point control moves every axis linearly,
``q(t) = q0 + t (q1 - q0)``, so the tool tip leaves the straight CL segment whenever rotary axes
move. With TCP the control keeps the tip on the segment, but the tool axis still follows the
linear interpolation of the rotary axes rather than the CL orientation (slerp). This module
measures both deviations as maxima over each block (samples, then golden-section refinement
around the worst sample; not only the midpoint) and bisects blocks, solving the inserted CL
points on the neighbours' branch, until they are within tolerance.

The blocks are measured in chunks, on coordinate arrays. The refinement runs where it can
change a decision: a bound on the error between samples (from the curvature bounds of
:func:`urdfpost.kinematics.forward.interpolation_bounds`) rules it out elsewhere.

The geometry the measurement shares with verification and the strategies (segments, arcs,
slerp, chunks, the golden-section refinement) is :mod:`urdfpost.geometry`; what needs the
machine's kinematics (:class:`RowPoses`, the inserted points' solutions) is here.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from urdfpost.geometry import (
    Arcs,
    Segments,
    Temporaries,
    VecArrays,
    angle_from_chord2,
    chunks,
    coords,
    may_reach,
    refine_max,
    slerp,
)
from urdfpost.kinematics.forward import (
    ROWS,
    PoeChain,
    Scratch,
    chain_of,
    interpolation_bounds,
    tip_and_axis_along,
    tip_axis_and_reach,
)
from urdfpost.kinematics.inverse import assemble, nearest_solution, solve_linear
from urdfpost.machine import Machine
from urdfpost.tolerances import Tolerances

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class BlockError:
    """Worst deviation within each block.

    Attributes
    ----------
    tip : ndarray, shape (n,), mm
        Maximum distance of the tool tip from the CL segment.
    orientation : ndarray, shape (n,), rad
        Maximum angle between the tool axis and the CL orientation path near the tip, as
        verification measures it (:func:`orientation_path_chord2`).
    """

    tip: np.ndarray
    orientation: np.ndarray


@dataclass(frozen=True)
class RowPoses:
    """Forward kinematics at the rows of a path, what bounding its blocks' errors needs.

    Attributes
    ----------
    tip, axis : ndarray, shape (n, 3)
        Tool tip (mm) and axis in the workpiece frame.
    reach, swing : ndarray, shape (n, r)
        See :func:`urdfpost.kinematics.forward.tip_axis_and_reach`.
    """

    tip: np.ndarray
    axis: np.ndarray
    reach: np.ndarray
    swing: np.ndarray

    @classmethod
    def of(cls, machine: Machine | PoeChain, q: np.ndarray, tool_length: float) -> RowPoses:
        """The poses at joint values ``q`` (n, m), mm / rad."""
        return cls(*tip_axis_and_reach(machine, q, tool_length))

    def take(self, index: np.ndarray | slice) -> RowPoses:
        """The poses at ``index`` (a slice gives views)."""
        return RowPoses(self.tip[index], self.axis[index], self.reach[index], self.swing[index])


POSE_ROWS = 2 * ROWS
"""Rows whose poses (:class:`RowPoses`) :func:`_block_errors` works out at a time, when it
works them out: a few chunks' worth, in pieces of :data:`urdfpost.kinematics.forward.ROWS`."""


def _block_errors(
    machine: Machine,
    q0: np.ndarray,
    q1: np.ndarray,
    p0: np.ndarray,
    p1: np.ndarray,
    v0: np.ndarray,
    v1: np.ndarray,
    ends: tuple[RowPoses, RowPoses] | None,
    tool_length: float,
    tcp: bool,
    tol: Tolerances,
    targets: tuple[float, float] | None,
) -> BlockError:
    """Worst deviation of blocks from (q0, p0, v0) to (q1, p1, v1), each of length n.

    ``ends`` are the poses at q0 and q1; None when the blocks join consecutive rows of one
    path (``q1[i]`` is ``q0[i + 1]``): they are then worked out where they are needed, a few
    chunks at a time (:data:`POSE_ROWS`), each row once.

    Every block is sampled at ``tol.samples_per_block`` evenly spaced parameters. The maximum
    is refined (:func:`urdfpost.geometry.refine_max`) where it matters: everywhere when
    ``targets`` is None, otherwise only in blocks where the refinement could take it past a
    target (tip mm, orientation rad). Elsewhere the largest sample is kept, which is then
    within the refinement's reach of the true maximum and below the target either way (see
    :func:`_sampled_errors`). With ``targets``, a block whose ends alone keep it below them
    (:meth:`_Slack.cleared`) is not sampled at all: it gets those bounds as its errors, which
    decide the same (no bisection); the others of its chunk are sampled on their own, to the
    same values (every operation is element by element).

    The blocks go through the kinematics a chunk (:func:`urdfpost.geometry.chunks`) at a time.
    """
    n = q0.shape[0]
    samples = tol.samples_per_block
    window = tol.tip * tol.interpolation_share  # the tip target: the verifier's window, scaled
    tip_err, ori_err = np.empty(n), np.empty(n)
    chain, scratch = chain_of(machine), Scratch()
    poses, first, last = None, 0, -1  # poses of the rows first .. last of consecutive blocks
    for part in chunks(n, samples):
        seg = Segments.between(p0[part], p1[part])
        arc = Arcs.between(v0[part], v1[part])
        slack = None
        if targets is not None:
            if ends is not None:
                pose = (ends[0].take(part), ends[1].take(part))
            else:  # each row's pose once, for a few chunks at a time
                if part.stop > last:
                    first, last = part.start, min(n, part.start + POSE_ROWS - 1)
                    rows = np.concatenate([q0[first:last], q1[last - 1 : last]])
                    poses = RowPoses.of(chain, rows, tool_length)
                assert poses is not None
                k, at = part.stop - part.start, part.start - first
                pose = (poses.take(slice(at, at + k)), poses.take(slice(at + 1, at + k + 1)))
            slack = _Slack.of(
                chain, q0[part], q1[part], seg, arc, pose, 1.0 / (samples + 1), tcp, window
            )
            tip_bound, chord_bound, clear = slack.cleared(targets)
            if clear.any():  # no sample could bisect these blocks: their bounds decide
                tip_err[part] = np.where(clear, tip_bound, 0.0)
                ori_err[part] = np.where(clear, angle_from_chord2(chord_bound**2), 0.0)
                if clear.all():
                    continue
                # the others sampled on their own (every operation is element by element:
                # the same values as sampled with the chunk)
                keep = np.flatnonzero(~clear)
                at = keep + part.start
                tip_err[at], ori_err[at] = _sampled_errors(
                    chain,
                    scratch,
                    q0[at],
                    q1[at],
                    seg.take(keep),
                    arc.take(keep),
                    slack.take(keep),
                    tool_length,
                    tcp,
                    samples,
                    targets,
                    window,
                )
                continue
        tip_err[part], ori_err[part] = _sampled_errors(
            chain,
            scratch,
            q0[part],
            q1[part],
            seg,
            arc,
            slack,
            tool_length,
            tcp,
            samples,
            targets,
            window,
        )
    return BlockError(tip=tip_err, orientation=ori_err)


@dataclass(frozen=True)
class _Slack:
    """What bounds the errors of whole blocks besides their largest samples.

    See :func:`_error_bounds`. Per block (arrays of shape (n,)): the larger of the squared tip
    distances at the two block ends and the tip's curvature bound (both None in TCP programs,
    where the tip is on the segment), likewise for the squared chord to the CL axis at the
    block parameter (``end_chord2``, and the curvature of the chord, ``chord_curv``; a bound on
    the orientation error in TCP programs only, where the tip's parameter is the block's), and
    for the orientation error itself (``end_path2``; the tool axis' speed ``axis_speed``, the
    CL arc's angle ``omega`` and its speed through the window ``window_speed``). The room each
    leaves between samples ``h`` apart (``h`` itself, or :meth:`spaced`) comes from them.
    """

    end_dist2: np.ndarray | None
    tip_curv: np.ndarray | None
    end_chord2: np.ndarray
    chord_curv: np.ndarray
    end_path2: np.ndarray
    axis_speed: np.ndarray
    window_speed: np.ndarray
    omega: np.ndarray
    h: float

    @classmethod
    def of(
        cls,
        machine: Machine | PoeChain,
        q0: np.ndarray,
        q1: np.ndarray,
        seg: Segments,
        arc: Arcs,
        ends: tuple[RowPoses, RowPoses],
        h: float,
        tcp: bool,
        window: float,
    ) -> _Slack:
        """The slack of blocks from ``q0`` to ``q1`` (n, m) with samples ``h`` apart, the
        orientation compared within ``window`` (mm) of the tip (:func:`_orientation_error`)."""
        tip_speed, tip_curv, axis_speed, axis_curv = interpolation_bounds(
            machine, q0, q1, ends[0].reach, ends[1].reach, ends[0].swing, ends[1].swing
        )
        at_ends = [
            arc.chord2(coords(e.axis), c, s)
            for e, c, s in ((ends[0], 1.0, 0.0), (ends[1], np.cos(arc.omega), np.sin(arc.omega)))
        ]
        end_chord2, chord_curv = np.maximum(*at_ends), axis_curv + arc.omega**2
        # the window follows the tip's parameter u: at the block's own speed with TCP, at most
        # |p'| / |d| without; the nearest CL axis in it moves by at most omega times that
        # (and never by more than the whole arc), the tool axis by |a'|
        u_speed = np.ones_like(arc.omega) if tcp else tip_speed * np.sqrt(seg.inv_dd)
        end_path2 = np.maximum(
            *(
                _orientation_error(seg, arc, coords(e.tip), coords(e.axis), t, tcp, window)[2]
                for e, t in ((ends[0], 0.0), (ends[1], 1.0))
            )
        )
        turning = (end_chord2, chord_curv, end_path2, axis_speed, arc.omega * u_speed, arc.omega)
        if tcp:
            return cls(None, None, *turning, h)
        at_ends = [seg.distance2(coords(e.tip))[0] for e in ends]
        return cls(np.maximum(*at_ends), tip_curv, *turning, h)

    def spaced(self, h: float) -> _Slack:
        """The slack of the same blocks with samples ``h`` apart."""
        return replace(self, h=h)

    @property
    def tip_room(self) -> np.ndarray | None:
        """How far the tip error may exceed the largest sample, mm (None with TCP)."""
        return None if self.tip_curv is None else self.tip_curv * (self.h * self.h / 8.0)

    @property
    def chord_room(self) -> np.ndarray:
        """Likewise the chord to the CL axis at the block parameter."""
        return self.chord_curv * (self.h * self.h / 8.0)

    @property
    def path_room(self) -> np.ndarray:
        """Likewise the chord of the orientation error."""
        half = self.h / 2.0
        return self.axis_speed * half + np.minimum(self.window_speed * half, self.omega)

    def take(self, index: slice | np.ndarray) -> _Slack:
        """The slack of the blocks at ``index``."""
        return _Slack(
            None if self.end_dist2 is None else self.end_dist2[index],
            None if self.tip_curv is None else self.tip_curv[index],
            self.end_chord2[index],
            self.chord_curv[index],
            self.end_path2[index],
            self.axis_speed[index],
            self.window_speed[index],
            self.omega[index],
            self.h,
        )

    def bounds(
        self, dist2: np.ndarray, chord2: np.ndarray | None, path2: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Bounds on the tip error (mm; 0 in TCP programs) and the chord of the orientation
        error of blocks whose largest samples are ``dist2``, ``chord2`` (to the CL axis at the
        block parameter; used in TCP programs only) and ``path2`` (the orientation error),
        shape (n,)."""
        path = np.sqrt(np.maximum(path2, self.end_path2)) + self.path_room
        tip_room = self.tip_room
        if self.end_dist2 is None or tip_room is None:
            assert chord2 is not None  # (TCP)
            chord = np.sqrt(np.maximum(chord2, self.end_chord2)) + self.chord_room
            return np.zeros_like(path), np.minimum(chord, path)
        return np.sqrt(np.maximum(dist2, self.end_dist2)) + tip_room, path

    def cleared(self, targets: tuple[float, float]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The bounds of the blocks from their ends alone (the ends as the only samples, one
        block apart), and where they keep a block below the targets (tip mm, orientation rad)
        with the slack of :func:`urdfpost.geometry.may_reach`.

        A block's sampled and refined errors are values of its error functions, which these
        bound: where a block is cleared, no sample of it can decide a bisection.

        Returns
        -------
        tip, chord : ndarray, shape (n,)
            The bounds (tip mm, 0 with TCP; the chord of the orientation error).
        clear : ndarray, shape (n,), bool
        """
        ends = self.spaced(1.0)
        zero = np.zeros_like(self.end_path2)
        tip, chord = ends.bounds(zero, zero, zero)
        clear = ~may_reach(chord, 2.0 * np.sin(targets[1] / 2.0))
        if self.end_dist2 is not None:
            clear &= ~may_reach(tip, targets[0])
        return tip, chord, clear


def _error_bounds(
    machine: Machine | PoeChain,
    q0: np.ndarray,
    q1: np.ndarray,
    seg: Segments,
    arc: Arcs,
    ends: tuple[RowPoses, RowPoses],
    dist2: np.ndarray,
    chord2: np.ndarray | None,
    path2: np.ndarray,
    h: float,
    tcp: bool,
    window: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Upper bounds on the tip error (mm) and on the chord of the orientation error over whole
    blocks, from evenly spaced samples.

    With the block ends (the rows) as the outer samples, h apart, on each interval between
    two samples:

    - the tip error is the distance of the tip p(t) from a segment, a convex and 1-Lipschitz
      function of p; p stays within ``M h^2 / 8`` of the chord between the two samples when
      ``|p''| <= M``, and on that chord the distance is at most the larger of the two sampled
      ones; so the tip error is at most the largest sample plus ``M h^2 / 8``;
    - the orientation error f(t) is the chord from the tool axis a(t) to the nearest CL axis
      e(s) in a window of parameters about the tip's parameter u(t)
      (:func:`orientation_path_chord2`). Moving from a sample by dt moves a by at most
      ``|a'| dt``, and the window's ends by at most ``|u'| dt`` (and 1), so the nearest CL
      axis by at most ``omega`` times that: f is at most the nearest sample plus
      ``(|a'| + omega |u'|) h / 2``, with ``|u'| = 1`` in TCP programs (the tip on the
      segment at the block parameter) and at most ``|p'| / |d|`` otherwise;
    - in TCP programs also (u = t, inside the window) f is at most the chord ``|a(t) -
      e(t)|``, a convex function of ``a - e`` whose second derivative is at most ``|a''| +
      omega^2`` (e runs at the constant speed omega on its great circle): at most the largest
      sample plus ``(|a''| + omega^2) h^2 / 8``. The angle increases with the chord.

    ``|p'|``, M, ``|a'|`` and ``|a''|`` come from
    :func:`urdfpost.kinematics.forward.interpolation_bounds`; the terms that do not depend on
    the samples are :class:`_Slack`.

    Parameters
    ----------
    dist2, chord2, path2 : ndarray, shape (n,)
        Largest squared tip distance, squared chord to the CL axis at the block parameter and
        squared orientation error sampled inside each block.
    h : float
        Sample spacing (the first sample is h from the block start).
    tcp : bool
        The tip is on the segment (its bound is 0).
    window : float, mm
        Of :func:`_orientation_error`.

    Returns
    -------
    tip, chord : ndarray, shape (n,)
    """
    slack = _Slack.of(machine, q0, q1, seg, arc, ends, h, tcp, window)
    return slack.bounds(dist2, chord2, path2)


def _orientation_error(
    seg: Segments,
    arc: Arcs,
    tip: VecArrays | None,
    axis: VecArrays,
    t: np.ndarray | float,
    tcp: bool,
    window: float,
    scratch: Temporaries | None = None,
) -> tuple[np.ndarray | None, np.ndarray | None, np.ndarray]:
    """Tip distance and orientation error of samples of blocks, as verification measures them.

    The tool axis is compared with the CL orientation within ``window`` (mm, along the
    segment) of the tip's place on the segment (:func:`orientation_path_chord2`): in TCP
    programs the block parameter ``t`` itself (the control moves the tip on the segment), else
    the projection of the tip onto the segment.

    Parameters
    ----------
    seg, arc : Segments, Arcs
        The blocks' CL segments and arcs (n,).
    tip : VecArrays or None
        The tool tips, coordinate arrays of shape (s, n) or (n,) (None with ``tcp``).
    axis : VecArrays
        The tool axes, of the same shape.
    t : ndarray or float
        The block parameters of the samples, broadcast against the coordinates.
    tcp, window : bool, float
    scratch : Temporaries, optional
        For the tip distance (:meth:`Segments.distance2`).

    Returns
    -------
    dist2 : ndarray or None
        Squared tip distance from the segment (None with ``tcp``), mm^2.
    chord2 : ndarray or None
        Squared chord to the CL axis at ``t`` (with ``tcp`` only, where it bounds ``path2``:
        ``t`` is in the window).
    path2 : ndarray
        Squared chord to the nearest CL axis in the window: the orientation error.
    """
    half = np.where(seg.inv_dd > 0, window * np.sqrt(seg.inv_dd), np.inf)  # window / |d|
    if tcp or tip is None:
        u = np.broadcast_to(np.asarray(t, dtype=float), np.shape(axis[0]))
        chord2, path2 = orientation_path_chord2(arc, axis, u, half)
        return None, chord2, path2
    outside: list[np.ndarray] = []
    dist2, s = seg.distance2(tip, outside, scratch)
    u = np.where(s >= 1.0, 1.0 + outside[0], s - outside[0])  # not clipped
    return dist2, None, orientation_path_chord2(arc, axis, u, half)[1]


def _sampled_errors(
    chain: PoeChain,
    scratch: Scratch,
    q0: np.ndarray,
    q1: np.ndarray,
    seg: Segments,
    arc: Arcs,
    slack: _Slack | None,
    tool_length: float,
    tcp: bool,
    samples: int,
    targets: tuple[float, float] | None,
    window: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Tip (mm) and orientation (rad) errors of one chunk of blocks; see :func:`_block_errors`.

    The orientation error is the one verification measures (:func:`_orientation_error`, the
    CL orientation compared within ``window`` mm of the tip). The samples' temporaries come
    from ``scratch``, the same arrays for every chunk. ``slack`` (with ``targets`` only)
    completes the bounds of :func:`_error_bounds`.

    A block is refined where :func:`_error_bounds` does not keep it below the target. The
    golden-section search only ever reports values of the function, at most its maximum, so
    it cannot take a block past a target that the bound keeps it below: skipping it there
    changes no decision.
    """
    n = q0.shape[0]
    t = np.arange(1, samples + 1) / (samples + 1)
    scratch.start((samples, n))
    tip, axis = tip_and_axis_along(chain, q0, q1, t, tool_length, with_tip=not tcp, scratch=scratch)
    dist2, chord2, path2 = _orientation_error(seg, arc, tip, axis, t[:, None], tcp, window, scratch)
    if dist2 is None:  # TCP: the control keeps the tip on the segment
        best = (np.zeros(n), _column_max(path2))
    else:
        best = (_column_max(dist2), _column_max(path2))
    if targets is None:
        wanted = (np.full(n, not tcp), np.ones(n, dtype=bool))
    else:
        assert slack is not None
        bound = slack.bounds(best[0], None if chord2 is None else _column_max(chord2), best[1])
        want_tip = np.zeros(n, dtype=bool) if tcp else may_reach(bound[0], targets[0])
        wanted = (want_tip, may_reach(bound[1], 2.0 * np.sin(targets[1] / 2.0)))

    def errors(blocks: np.ndarray, tt: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        p, v = tip_and_axis_along(
            chain, q0[blocks], q1[blocks], tt[None, :], tool_length, with_tip=not tcp
        )
        d2, _, c2 = _orientation_error(
            seg.take(blocks),
            arc.take(blocks),
            None if p is None else (p[0][0], p[1][0], p[2][0]),
            (v[0][0], v[1][0], v[2][0]),
            tt,
            tcp,
            window,
        )
        return (np.zeros(len(blocks)) if d2 is None else d2), c2

    log.debug(
        "%d blocks: tip refined in %d, orientation in %d", n, wanted[0].sum(), wanted[1].sum()
    )
    # the worst sample only where the search starts from it
    worst = (
        np.zeros(n, dtype=np.intp) if dist2 is None else _first_largest(dist2, wanted[0]),
        _first_largest(path2, wanted[1]),
    )
    best = refine_max(errors, t, worst, best, wanted)
    return np.sqrt(best[0]), angle_from_chord2(best[1])


def orientation_path_chord2(
    arc: Arcs,
    v: VecArrays,
    u: np.ndarray,
    half: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Squared chord from tool axes to the CL orientation path near a tip parameter.

    A CL segment moves the tip ``P(s)`` (straight) and the axis ``e(s)`` (slerp) together on
    one parameter ``s`` in [0, 1]. A tool axis ``v`` measured where the tip's parameter is
    ``u`` is compared with the part of the arc whose tip lies within the window radius of
    that place along the segment: ``e([clip(u - half), clip(u + half)])`` with ``half`` the
    radius over the segment's length (infinite for a segment of no length, a reorientation in
    place: the whole arc). The distance to that part of a great circle has a closed form:
    in the frame ``(v0, normal, v0 x normal)`` of the arc, the nearest point of the whole
    circle is the direction of ``v``'s projection onto its plane; it is the nearest of the
    part when inside its wedge, else the nearer end is. See ``docs/verification.md``.

    Parameters
    ----------
    arc : Arcs
        One arc per column (block), angle ``omega`` rad.
    v : VecArrays
        Unit tool axes, coordinate arrays of shape (s, n) (s samples of n blocks) or (n,).
    u : ndarray, shape of ``v[0]``
        The tip's parameter on the segment (the projection, not clipped; in [0, 1] for a tip
        on it).
    half : ndarray, shape (n,)
        Window radius over the segment length (``inf`` for a segment of no length).

    Returns
    -------
    at : ndarray, shape of ``v[0]``
        ``|v - e(clip(u))|^2``: the chord at the tip's parameter itself (an upper bound on
        ``path``; what the bounds between samples are worked out for).
    path : ndarray, shape of ``v[0]``
        The squared chord to the nearest point of the window; the angle is
        :func:`urdfpost.geometry.angle_from_chord2` of it.

    Examples
    --------
    A reorientation in place (no tip motion) from +Z to +X; the axis halfway along the arc
    is on it, wherever the tip parameter says it is:

    >>> from urdfpost.geometry import Arcs, coords
    >>> arc = Arcs.between(np.array([[0.0, 0.0, 1.0]]), np.array([[1.0, 0.0, 0.0]]))
    >>> v = coords(np.array([[np.sqrt(0.5), 0.0, np.sqrt(0.5)]]))
    >>> at, path = orientation_path_chord2(arc, v, np.zeros(1), np.full(1, np.inf))
    >>> round(float(at[0]), 6), float(path[0])
    (0.585786, 0.0)
    """
    omega = arc.omega
    v0, normal, across = _frame(arc)
    # v = x v0 + y normal + z across; |v - e(theta)|^2 = z^2 + (1 - rho)^2 + 4 rho
    # sin^2((theta - nearest) / 2), where rho and nearest are the length and the angle of v's
    # projection onto the plane: the nearest point of the whole great circle is at that angle
    x, y, base = _dot(v, v0), _dot(v, normal), _dot(v, across)
    base *= base  # z^2
    gap = _one_minus_rho(base)  # 1 - rho, from z^2 (v is a unit vector)
    rho = np.subtract(1.0, gap)
    gap *= gap
    base += gap
    nearest = np.arctan2(y, x, out=x)
    at = np.clip(u, 0.0, 1.0, out=y)
    at *= omega
    at -= nearest
    _turn_chord2(at, gap)
    at *= rho
    at += base
    # turned to within pi of the window's middle (the window is less than pi wide) and clipped
    # to the window, it is the window's nearest point
    lo = np.subtract(u, half)
    np.clip(lo, 0.0, 1.0, out=lo)
    lo *= omega
    hi = np.add(u, half)
    np.clip(hi, 0.0, 1.0, out=hi)
    hi *= omega
    mid = np.add(lo, hi, out=gap)
    mid *= 0.5
    mid -= np.pi
    np.add(nearest, 2.0 * np.pi, out=nearest, where=nearest < mid)
    path = np.clip(nearest, lo, hi, out=lo)
    path -= nearest
    _turn_chord2(path, hi)
    path *= rho
    path += base
    np.minimum(path, at, out=path)
    return at, path


def _frame(arc: Arcs) -> tuple[VecArrays, VecArrays, VecArrays]:
    """An orthonormal frame of each arc: v0, the normal towards the arc's end in its plane, and
    their cross product.

    The normal is made orthogonal to v0 again; where it is rounding noise or zero (an arc of
    next to no angle), any unit vector orthogonal to v0 stands in for it.
    """
    v0 = arc.v0
    dot = _dot(arc.normal, v0)
    normal = [arc.normal[i] - dot * v0[i] for i in range(3)]
    length = np.sqrt(_dot(normal, normal))
    lost = length < 0.5
    if lost.any():  # v0 x the coordinate axis least along it
        least = np.argmin(np.abs(np.stack(v0)), axis=0)
        other = [np.where(least == i, 1.0, 0.0) for i in range(3)]
        stand_in = _cross(v0, other)
        normal = [np.where(lost, stand_in[i], normal[i]) for i in range(3)]
        length = np.sqrt(_dot(normal, normal))
    nx, ny, nz = (c / length for c in normal)
    return v0, (nx, ny, nz), _cross(v0, (nx, ny, nz))


def _dot(a: VecArrays | list[np.ndarray], b: VecArrays | list[np.ndarray]) -> np.ndarray:
    """Dot products of vectors given as coordinate arrays (broadcast), in a new array."""
    out = np.multiply(a[0], b[0])
    part = np.multiply(a[1], b[1])
    out += part
    np.multiply(a[2], b[2], out=part)
    out += part
    return out


def _cross(a: VecArrays | list[np.ndarray], b: VecArrays | list[np.ndarray]) -> VecArrays:
    """Cross products of vectors given as coordinate arrays."""
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _one_minus_rho(z2: np.ndarray) -> np.ndarray:
    """``1 - sqrt(1 - z2)`` in a new array, accurate for small ``z2`` (in [0, 1]).

    A Taylor polynomial where ``z2`` is at most 1e-4 (the terms left out are below 6e-18 of
    the result), ``z2 / (1 + sqrt(1 - z2))`` elsewhere: faster than a square root for every
    sample of tool axes near the CL orientation's great circle.
    """
    out = np.multiply(z2, 7.0 / 256.0)
    out += 5.0 / 128.0
    out *= z2
    out += 1.0 / 16.0
    out *= z2
    out += 1.0 / 8.0
    out *= z2
    out += 0.5
    out *= z2
    if z2.max(initial=0.0) > 1e-4:
        far = np.flatnonzero(z2 > 1e-4)
        w = np.minimum(z2.flat[far], 1.0)
        out.flat[far] = w / (1.0 + np.sqrt(1.0 - w))
    return out


_SMALL_TURN = 0.1
"""Turns up to this (rad) get their squared chord from a Taylor polynomial in
:func:`_turn_chord2`."""

_TURN_TERMS = (1.0, -1.0 / 12.0, 1.0 / 360.0, -1.0 / 20160.0, 1.0 / 1814400.0)
"""Coefficients of ``4 sin^2(t / 2) = t^2 (1 - t^2 / 12 + t^4 / 360 - ...)`` in powers of
``t^2`` (the next, ``-2 / 12!``, is below 5e-19 of the result for turns up to
:data:`_SMALL_TURN`)."""


def _turn_chord2(turn: np.ndarray, scratch: np.ndarray) -> np.ndarray:
    """Squared chord ``4 sin^2(turn / 2)`` between unit vectors ``turn`` (rad) apart on a great
    circle, in place of ``turn``.

    Where ``|turn|`` is at most :data:`_SMALL_TURN`, the Taylor polynomial to ``turn^10``
    (the next term is below 5e-19 of the result), several times faster than ``np.sin``; the
    rest through ``np.sin``.

    Parameters
    ----------
    turn : ndarray, any shape, rad
        Overwritten with the result.
    scratch : ndarray, shape of ``turn``
        Overwritten.

    Returns
    -------
    ndarray
        ``turn``.

    Examples
    --------
    >>> round(float(_turn_chord2(np.array([np.pi / 2]), np.empty(1))[0]), 12)  # chord sqrt(2)
    2.0
    """
    t2 = np.multiply(turn, turn, out=scratch)
    largest = float(t2.max(initial=0.0))
    large = np.flatnonzero(t2 > _SMALL_TURN**2) if largest > _SMALL_TURN**2 else None
    if large is not None:
        big = turn.flat[large]
    # as many terms as the largest turn needs for the next to stay below 1e-17 of the result
    terms, reach = 1, min(largest, _SMALL_TURN**2)
    while terms < len(_TURN_TERMS) and abs(_TURN_TERMS[terms]) * reach**terms > 1e-17:
        terms += 1
    turn.fill(_TURN_TERMS[terms - 1])
    for c in _TURN_TERMS[terms - 2 :: -1]:
        turn *= t2
        turn += c
    turn *= t2
    if large is not None:
        turn.flat[large] = 4.0 * np.sin(0.5 * big) ** 2
    return turn


def _column_max(values: np.ndarray) -> np.ndarray:
    """Largest value of each column of ``values`` (s, n), as the value at its first maximum
    (``np.argmax`` along the first axis) is: the same number, except where a NaN or a zero
    is the largest (NaNs may differ in payload, zeros in sign), which go by argmax."""
    best = values.max(axis=0)
    if np.isnan(best).any() or not best.all():
        best = values[np.argmax(values, axis=0), np.arange(values.shape[1])]
    return best


def _first_largest(values: np.ndarray, wanted: np.ndarray) -> np.ndarray:
    """Row of the first maximum of each column of ``values`` (s, n) where ``wanted`` (0 in
    the other columns)."""
    index = np.zeros(values.shape[1], dtype=np.intp)
    cols = np.flatnonzero(wanted)
    if cols.size:
        index[cols] = np.argmax(values[:, cols], axis=0)
    return index


@dataclass(frozen=True)
class Linearized:
    """A path after subdivision.

    Attributes
    ----------
    q : ndarray, shape (N, m)
    tip : ndarray, shape (N, 3), mm
    axis : ndarray, shape (N, 3)
    source : ndarray, shape (N,), int
        Index of the input point each row is, or -1 for inserted points.
    error : BlockError
        Final deviation of every block, arrays of shape (N - 1,): the refined maximum, or,
        where a bound keeps a block below the targets, its largest sample.
    """

    q: np.ndarray
    tip: np.ndarray
    axis: np.ndarray
    source: np.ndarray
    error: BlockError


def _midpoints(
    machine: Machine,
    qa: np.ndarray,
    qb: np.ndarray,
    pa: np.ndarray,
    pb: np.ndarray,
    va: np.ndarray,
    vb: np.ndarray,
    tool_length: float,
    tol: Tolerances,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """CL midpoints of blocks, solved on the branch nearest the neighbours' interpolation."""
    tip = 0.5 * (pa + pb)
    ax = slerp(va, vb, np.full(len(pa), 0.5))
    cols = list(machine.rotary_columns)
    rot = nearest_solution(machine, ax, 0.5 * (qa[:, cols] + qb[:, cols]), tol)
    lin = solve_linear(machine, rot, tip, tool_length)
    return assemble(machine, rot, lin), tip, ax


@dataclass(frozen=True)
class _Rows:
    """Rows of a path being subdivided.

    Attributes
    ----------
    q : ndarray, shape (k, m)
    tip, axis : ndarray, shape (k, 3)
    param : ndarray, shape (k,), or None
    key : ndarray, shape (k,)
        Where the row goes: its index in the input, inserted rows halfway between their
        neighbours' keys (dyadic fractions, exact in floating point).
    poses : RowPoses or None
        None until needed (:meth:`posed`): the blocks between consecutive input rows work
        them out a few chunks at a time (:func:`_block_errors`).
    """

    q: np.ndarray
    tip: np.ndarray
    axis: np.ndarray
    param: np.ndarray | None
    key: np.ndarray
    poses: RowPoses | None

    def take(self, index: np.ndarray | slice) -> _Rows:
        """The rows at ``index`` (a slice gives views)."""
        return _Rows(
            self.q[index],
            self.tip[index],
            self.axis[index],
            None if self.param is None else self.param[index],
            self.key[index],
            None if self.poses is None else self.poses.take(index),
        )

    def posed(self, machine: Machine, tool_length: float) -> _Rows:
        """The rows with their poses worked out."""
        if self.poses is not None:
            return self
        return replace(self, poses=RowPoses.of(machine, self.q, tool_length))

    @staticmethod
    def concat(parts: list[_Rows]) -> _Rows:
        def cat(name: str) -> np.ndarray:
            return np.concatenate([getattr(p, name) for p in parts])

        poses = [p.poses for p in parts]
        assert all(p is not None for p in poses), "concatenated rows have their poses"
        return _Rows(
            cat("q"),
            cat("tip"),
            cat("axis"),
            None if parts[0].param is None else cat("param"),
            cat("key"),
            RowPoses(*(np.concatenate([getattr(p, f) for p in poses]) for f in _POSE_FIELDS)),
        )


_POSE_FIELDS = ("tip", "axis", "reach", "swing")


def _measure(
    machine: Machine,
    a: _Rows,
    b: _Rows,
    tool_length: float,
    tcp: bool,
    tol: Tolerances,
    targets: tuple[float, float] | None,
) -> tuple[np.ndarray, np.ndarray]:
    """Errors of the blocks from rows ``a`` to rows ``b``; rows without their poses are
    consecutive rows of one path (``b.q[i]`` is ``a.q[i + 1]``)."""
    e = _block_errors(
        machine,
        a.q,
        b.q,
        a.tip,
        b.tip,
        a.axis,
        b.axis,
        None if a.poses is None or b.poses is None else (a.poses, b.poses),
        tool_length,
        tcp,
        tol,
        targets,
    )
    return e.tip, e.orientation


def block_errors(
    machine: Machine,
    q: np.ndarray,
    tip: np.ndarray,
    axis: np.ndarray,
    *,
    tool_length: float = 0.0,
    tcp: bool = False,
    tol: Tolerances | None = None,
) -> BlockError:
    """Maximum deviation between consecutive points when the control interpolates the axes.

    Parameters
    ----------
    machine : Machine
    q : ndarray, shape (n, m)
        Joint vectors at the block ends, mm / rad.
    tip : ndarray, shape (n, 3), mm
        CL points the blocks should join with straight segments.
    axis : ndarray, shape (n, 3)
        CL tool axes.
    tool_length : float, mm
    tcp : bool
        The control keeps the tip on the segment (only the orientation can deviate; the tip
        error is 0).
    tol : Tolerances, optional

    Returns
    -------
    BlockError
        Arrays of shape (n - 1,).
    """
    tol = tol or Tolerances()
    if q.shape[0] <= 1:
        return BlockError(np.zeros(0), np.zeros(0))
    n = q.shape[0]
    rows = _Rows(q, tip, axis, None, np.arange(n, dtype=float), None)
    err = _measure(
        machine,
        rows.take(slice(0, n - 1)),
        rows.take(slice(1, n)),
        tool_length,
        tcp,
        tol,
        None,
    )
    return BlockError(tip=err[0], orientation=err[1])


def subdivide(
    machine: Machine,
    q: np.ndarray,
    tip: np.ndarray,
    axis: np.ndarray,
    *,
    tool_length: float = 0.0,
    tcp: bool = False,
    tol: Tolerances | None = None,
    param: np.ndarray | None = None,
    solve_at: Callable[
        [np.ndarray, np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray]
    ]
    | None = None,
) -> Linearized:
    """Bisect blocks until the tip and orientation deviations are within tolerance.

    The targets are ``tol.tip`` and ``tol.orientation`` times ``tol.interpolation_share`` (the
    rest of each tolerance is kept for the rounding of the written program).
    Blocks are bisected at most ``tol.max_subdivision_depth`` times.

    Parameters
    ----------
    machine : Machine
    q : ndarray, shape (n, m)
        Selected joint vectors of one continuous feed path.
    tip, axis : ndarray, shape (n, 3)
        Its CL points and tool axes.
    tool_length : float, mm
    tcp : bool
    tol : Tolerances, optional
    param : ndarray, shape (n,), optional
        Position of each row along the path (any increasing measure); with ``solve_at``.
    solve_at : callable, optional
        ``solve_at(param (k,), qa (k, m), qb (k, m)) -> (q, tip, axis)``: the row at a position
        between two rows (a strategy's joint curve). Default: the CL midpoint, solved exactly
        on the branch nearest the neighbours' interpolation.

    Returns
    -------
    Linearized
    """
    tol = tol or Tolerances()
    q, tip, axis = (np.asarray(x, dtype=float) for x in (q, tip, axis))
    n = len(q)
    targets = (tol.tip * tol.interpolation_share, tol.orientation * tol.interpolation_share)
    rows = _Rows(
        q,
        tip,
        axis,
        None if param is None else np.asarray(param, dtype=float),
        np.arange(n, dtype=float),
        None,
    )
    # the blocks still to decide, as the rows they join; the bisected ones are replaced by
    # their halves, and only those are measured again
    a, b = rows.take(slice(0, n - 1)), rows.take(slice(1, n))
    err = _measure(machine, a, b, tool_length, tcp, tol, targets)
    inserted: list[_Rows] = []
    done: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []  # block keys, tip, orientation
    for depth in range(tol.max_subdivision_depth):
        bad = (err[0] > targets[0]) | (err[1] > targets[1])
        done.append((a.key[~bad], err[0][~bad], err[1][~bad]))
        if not bad.any():
            a = a.take(np.zeros(0, dtype=int))
            break
        idx = np.flatnonzero(bad)
        a, b = a.take(idx).posed(machine, tool_length), b.take(idx).posed(machine, tool_length)
        pmid = None if a.param is None or b.param is None else 0.5 * (a.param + b.param)
        if solve_at is not None and pmid is not None:
            qm, pm, vm = solve_at(pmid, a.q, b.q)
        else:
            qm, pm, vm = _midpoints(
                machine, a.q, b.q, a.tip, b.tip, a.axis, b.axis, tool_length, tol
            )
        log.debug("subdivision depth %d: %d blocks bisected", depth + 1, len(idx))
        mid = _Rows(qm, pm, vm, pmid, 0.5 * (a.key + b.key), RowPoses.of(machine, qm, tool_length))
        inserted.append(mid)
        a, b = _Rows.concat([a, mid]), _Rows.concat([mid, b])
        err = _measure(machine, a, b, tool_length, tcp, tol, targets)
    else:
        done.append((a.key, err[0], err[1]))  # still beyond the targets at the largest depth
    # the rows and the blocks in key order: the first of each are in order already, the few
    # added after them are merged in
    if inserted:
        extra = _Rows.concat(inserted)
        at, order = _merge_positions(rows.key, extra.key)
        q, tip, axis = (
            _inserted(whole, at, part[order])
            for whole, part in ((q, extra.q), (tip, extra.tip), (axis, extra.axis))
        )
        source = _inserted(np.arange(n), at, np.full(len(order), -1))
    else:
        q, tip, axis, source = q.copy(), tip.copy(), axis.copy(), np.arange(n)
    if len(done) > 1:
        at, order = _merge_positions(done[0][0], np.concatenate([d[0] for d in done[1:]]))
        err_tip, err_ori = (
            _inserted(done[0][i], at, np.concatenate([d[i] for d in done[1:]])[order])
            for i in (1, 2)
        )
    else:
        err_tip, err_ori = done[0][1], done[0][2]
    return Linearized(
        q=q, tip=tip, axis=axis, source=source, error=BlockError(tip=err_tip, orientation=err_ori)
    )


def _merge_positions(first: np.ndarray, more: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Where the keys ``more`` go among the sorted keys ``first``, as a stable sort of both
    would put them (after equal keys of ``first``).

    Returns
    -------
    at : ndarray, shape (k,), int
        Per key of ``more`` in sorted order: the number of keys of ``first`` before it.
    order : ndarray, shape (k,), int
        The stable sort of ``more``.
    """
    order = np.argsort(more, kind="stable")
    return np.searchsorted(first, more[order], side="right"), order


def _inserted(whole: np.ndarray, at: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """``whole`` with ``rows`` inserted in order, row i after the first ``at[i]`` of ``whole``
    (``at`` non-decreasing): copies of the stretches between them when they are few."""
    out = np.empty((len(whole) + len(rows), *whole.shape[1:]), dtype=whole.dtype)
    final = at + np.arange(len(rows))  # where the rows land
    if len(rows) > _FEW_INSERTED:
        keep = np.ones(len(out), dtype=bool)
        keep[final] = False
        out[keep] = whole
        out[final] = rows
        return out
    prev = 0
    for i, (k, f) in enumerate(zip(at.tolist(), final.tolist(), strict=True)):
        out[prev + i : f] = whole[prev:k]
        out[f] = rows[i]
        prev = k
    out[prev + len(rows) :] = whole[prev:]
    return out


_FEW_INSERTED = 256
"""Up to this many inserted rows, :func:`_inserted` copies the stretches between them; beyond,
masks are faster."""
