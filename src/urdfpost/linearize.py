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
    angle_from_chord2,
    chunks,
    coords,
    cos_sin,
    may_reach,
    refine_max,
    slerp,
)
from urdfpost.kinematics.forward import (
    ROWS,
    PoeChain,
    Scratch,
    chain_of,
    cos_sin_along,
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
        Maximum angle between the tool axis and the CL axis (slerp) at the same parameter.
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
    :func:`_sampled_errors`).

    The blocks go through the kinematics a chunk (:func:`urdfpost.geometry.chunks`) at a time,
    the same chunks whatever else changes: the refinement's cosines depend on the largest angle
    refined in a chunk (:func:`urdfpost.geometry.cos_sin`).
    """
    n = q0.shape[0]
    samples = tol.samples_per_block
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
            slack = _Slack.of(chain, q0[part], q1[part], seg, arc, pose, 1.0 / (samples + 1), tcp)
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
        )
    return BlockError(tip=tip_err, orientation=ori_err)


@dataclass(frozen=True)
class _Slack:
    """What bounds the errors of whole blocks besides their largest samples.

    See :func:`_error_bounds`. Per block (arrays of shape (n,)): the larger of the squared tip
    distances at the two block ends and the room the tip's curvature leaves between samples
    (both None in TCP programs, where the tip is on the segment), and likewise for the squared
    chord of the orientation error.
    """

    end_dist2: np.ndarray | None
    tip_room: np.ndarray | None
    end_chord2: np.ndarray
    chord_room: np.ndarray

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
    ) -> _Slack:
        """The slack of blocks from ``q0`` to ``q1`` (n, m) with samples ``h`` apart."""
        _, tip_curv, _, axis_curv = interpolation_bounds(
            machine, q0, q1, ends[0].reach, ends[1].reach, ends[0].swing, ends[1].swing
        )
        at_ends = [
            arc.chord2(coords(e.axis), c, s)
            for e, c, s in ((ends[0], 1.0, 0.0), (ends[1], np.cos(arc.omega), np.sin(arc.omega)))
        ]
        room = h * h / 8.0
        end_chord2, chord_room = np.maximum(*at_ends), (axis_curv + arc.omega**2) * room
        if tcp:
            return cls(None, None, end_chord2, chord_room)
        at_ends = [seg.distance2(coords(e.tip))[0] for e in ends]
        return cls(np.maximum(*at_ends), tip_curv * room, end_chord2, chord_room)

    def take(self, index: slice) -> _Slack:
        """The slack of the blocks at ``index``."""
        return _Slack(
            None if self.end_dist2 is None else self.end_dist2[index],
            None if self.tip_room is None else self.tip_room[index],
            self.end_chord2[index],
            self.chord_room[index],
        )

    def bounds(self, dist2: np.ndarray, chord2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Bounds on the tip error (mm; 0 in TCP programs) and the chord of the orientation
        error of blocks whose largest samples are ``dist2`` and ``chord2`` (n,)."""
        chord = np.sqrt(np.maximum(chord2, self.end_chord2)) + self.chord_room
        if self.end_dist2 is None or self.tip_room is None:
            return np.zeros_like(chord), chord
        return np.sqrt(np.maximum(dist2, self.end_dist2)) + self.tip_room, chord


def _error_bounds(
    machine: Machine | PoeChain,
    q0: np.ndarray,
    q1: np.ndarray,
    seg: Segments,
    arc: Arcs,
    ends: tuple[RowPoses, RowPoses],
    dist2: np.ndarray,
    chord2: np.ndarray,
    h: float,
    tcp: bool,
) -> tuple[np.ndarray, np.ndarray]:
    """Upper bounds on the tip error (mm) and on the chord of the orientation error over whole
    blocks, from evenly spaced samples.

    With the block ends (the rows) as the outer samples, h apart, on each interval between
    two samples:

    - the tip error is the distance of the tip p(t) from a segment, a convex and 1-Lipschitz
      function of p; p stays within ``M h^2 / 8`` of the chord between the two samples when
      ``|p''| <= M``, and on that chord the distance is at most the larger of the two sampled
      ones; so the tip error is at most the largest sample plus ``M h^2 / 8``;
    - likewise the chord ``|a(t) - e(t)|`` between the tool axis a and the slerp e: a convex
      function of ``a - e``, whose second derivative is at most ``|a''| + omega^2`` (e runs at
      the constant speed omega on its great circle). The angle increases with the chord.

    M and ``|a''|`` come from :func:`urdfpost.kinematics.forward.interpolation_bounds`; the
    terms that do not depend on the samples are :class:`_Slack`.

    Parameters
    ----------
    dist2, chord2 : ndarray, shape (n,)
        Largest squared tip distance and squared chord sampled inside each block.
    h : float
        Sample spacing (the first sample is h from the block start).
    tcp : bool
        The tip is on the segment (its bound is 0).

    Returns
    -------
    tip, chord : ndarray, shape (n,)
    """
    return _Slack.of(machine, q0, q1, seg, arc, ends, h, tcp).bounds(dist2, chord2)


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
) -> tuple[np.ndarray, np.ndarray]:
    """Tip (mm) and orientation (rad) errors of one chunk of blocks; see :func:`_block_errors`.

    The samples' temporaries come from ``scratch``, the same arrays for every chunk.
    ``slack`` (with ``targets`` only) completes the bounds of :func:`_error_bounds`.

    A block is refined where :func:`_error_bounds` does not keep it below the target. The
    golden-section search only ever reports values of the function, at most its maximum, so
    it cannot take a block past a target that the bound keeps it below: skipping it there
    changes no decision.
    """
    n = q0.shape[0]
    t = np.arange(1, samples + 1) / (samples + 1)
    scratch.start((samples, n))
    tip, axis = tip_and_axis_along(chain, q0, q1, t, tool_length, with_tip=not tcp, scratch=scratch)
    cos, sin = cos_sin_along(np.zeros(n), arc.omega, t, out=(scratch.take(), scratch.take()))
    chord2 = arc.chord2(axis, cos, sin, scratch)
    if tcp:  # the control keeps the tip on the segment
        dist2, best = None, (np.zeros(n), _column_max(chord2))
    else:
        assert tip is not None
        dist2 = seg.distance2(tip, scratch=scratch)[0]
        best = (_column_max(dist2), _column_max(chord2))
    if targets is None:
        wanted = (np.full(n, not tcp), np.ones(n, dtype=bool))
    else:
        assert slack is not None
        bound = slack.bounds(best[0], best[1])
        want_tip = np.zeros(n, dtype=bool) if tcp else may_reach(bound[0], targets[0])
        wanted = (want_tip, may_reach(bound[1], 2.0 * np.sin(targets[1] / 2.0)))

    def errors(blocks: np.ndarray, tt: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        p, v = tip_and_axis_along(
            chain, q0[blocks], q1[blocks], tt[None, :], tool_length, with_tip=not tcp
        )
        sub = arc.take(blocks)
        c2 = sub.chord2((v[0][0], v[1][0], v[2][0]), *cos_sin(tt * sub.omega))
        if p is None:
            return np.zeros(len(blocks)), c2
        return seg.take(blocks).distance2((p[0][0], p[1][0], p[2][0]))[0], c2

    log.debug(
        "%d blocks: tip refined in %d, orientation in %d", n, wanted[0].sum(), wanted[1].sum()
    )
    # the worst sample only where the search starts from it
    worst = (
        np.zeros(n, dtype=np.intp) if dist2 is None else _first_largest(dist2, wanted[0]),
        _first_largest(chord2, wanted[1]),
    )
    best = refine_max(errors, t, worst, best, wanted)
    return np.sqrt(best[0]), angle_from_chord2(best[1])


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
