"""The ``cone`` strategy: the tool axis bent within a cone to keep a rotary axis' rate.

``cone``
    The tool axis moves within a cone of the angle tolerance around the programmed one so that
    the first rotary axis keeps within its velocity limit at the programmed feed: a
    velocity-limited path through the band of angles the cone allows, closest to the exact
    angles (:func:`_tube`). The orientations keep within the angle tolerance: where a
    non-orthogonal machine deviates more than the small-angle formula predicts, the band is
    halved there (up to four times, then the point is exact), and where the curve between two
    rows leaves it, a point is inserted on that CL segment and the cone planned again
    (:data:`ROUNDS`): the rounds after the first on windows around what it bent
    (:func:`_inserted`), then the last round spliced from the first and the windows' where
    they converged (:func:`_spliced`), else planned on the whole path once more. Without a
    programmed feed there is no time to rate the axis by: it is bent only inside the singular
    spans, to the least turn per unit path the cone allows.
"""

from __future__ import annotations

import itertools
import logging
from collections.abc import Callable
from dataclasses import dataclass, replace
from types import ModuleType

import numpy as np

from urdfpost._compiled import Kernels
from urdfpost.geometry import angle_between, norms
from urdfpost.kinematics.inverse import IKResult, RotarySolutions, inverse
from urdfpost.machine import Machine
from urdfpost.planning.branches import Selection
from urdfpost.planning.problem import (
    Plan,
    Problem,
    arc_length,
    at_param,
    entry_mask,
    exact_selection,
    tool_axis_of,
)
from urdfpost.planning.singularity import Span, feed_runs
from urdfpost.planning.strategies._common import (
    _plain,
    _spans,
    _turn_at_poles,
    best_tilt,
    exact_split,
    insert_points,
    split_at_pole_crossings,
    split_at_switches,
)
from urdfpost.planning.strategies._pointwise import PointMemo
from urdfpost.planning.strategies._registry import strategy
from urdfpost.tolerances import IN_PLACE
from urdfpost.toolpath import Motion, Toolpath, toolpath_slice

log = logging.getLogger(__name__)


HALVINGS = 4
"""Times the band of a point whose orientation leaves the cone is halved (a non-orthogonal
machine deviates more than the small-angle formula predicts, a tilt clipped to its travel
too); after them the point keeps its exact angles."""

CURVE_SAMPLES = 8
"""Positions per CL segment (at ``k / CURVE_SAMPLES``) where the cone's curve between its rows
is checked against the angle tolerance."""

ROUNDS = 4
"""Rounds of points inserted where the curve between two rows leaves the angle tolerance."""

WINDOW_MARGIN = 256
"""CL points a window of the rounds after the first reaches beyond what the cone bent, its
spans and its inserted points (:func:`_inserted`)."""

SPLICE = True
"""Whether the last round is spliced from round 1 and its windows' last rounds where they
converged (:func:`_spliced`) instead of planned on the whole path again; False: always the
whole path (the tests compare the two)."""

SPLICE_BOUND = 1e-9
"""Largest difference (rad) between a window's last round and round 1 at the points they
share (their branch choice, and the bent angles at the window's ends) for the two to be
spliced (:func:`_spliced`): the same angles but for the rounding of the running sums (the
unwrapped angles, the tube's forward pass), which reaches about 1e-12 rad."""

GEOMETRIC_SHARE = 1e-3
"""Without a feed, the step limits the tube starts from, as a share of the exact path's peak
turn per unit path measure (the tube raises them to the least that fits the cone)."""


def _load_kernels() -> ModuleType:
    from urdfpost.planning.strategies import _cone_kernel

    return _cone_kernel


KERNELS = Kernels(_load_kernels, "cone tube")
"""The compiled tube (:mod:`urdfpost.planning.strategies._cone_kernel`), loaded by
:func:`strategy_cone` for a large path (:data:`urdfpost._compiled.COMPILED_FROM`)."""


@strategy("cone", rank=60)
def strategy_cone(problem: Problem) -> Plan:
    """Keep the first rotary axis within its velocity limit by moving the tool axis in a cone.

    The rows are the CL points; between two of them the first rotary angle runs linearly and
    the tilt is the closest to the programmed axis (the plan's curve). Where that curve leaves
    the angle tolerance between two rows (long CL segments near a pole, where the programmed
    orientation turns faster in the first rotary angle mid-segment than at the ends), a point
    is inserted on the segment where it leaves it most, and the cone is planned again, up to
    :data:`ROUNDS` times. The rounds after the first are planned on windows around what the
    cone bent (:func:`_inserted`); where those converged, the last round is spliced from the
    first and the windows' last rounds (:func:`_spliced`), else planned on the whole path
    again. Each round takes the inverse kinematics of the points it shares with the round
    before over from it (:func:`_solved`).

    A cutting move with no feed has no time to rate the first rotary axis by: in a feed run
    with such a move, the axis is bent only inside the singular spans, to the least peak turn
    per unit path measure the cone allows there (what any constant feed would need least),
    and the plan says so once (its notes).
    """
    machine = problem.machine
    tp = split_at_pole_crossings(problem.toolpath, machine, problem.tol.pole_crossing)
    KERNELS.get(len(tp))  # the compiled tube, for a large path
    if len(machine.rotary) < 2 or not np.isfinite(machine.rotary[0].velocity):
        tp, sel = exact_split(problem, tp)
        return _plain(problem, tp, sel, _spans(problem, tp, sel))
    done = 0  # rounds of points inserted
    solved = _solved(problem, len(tp))
    splice: _Splice | None = None
    while True:
        spliced = None if splice is None else _spliced(problem, tp, solved, splice)
        r = _planned(problem, tp, solved) if spliced is None else spliced
        if r.bent is None:
            _say(r.notes)
            plain = _plain(problem, r.tp, r.sel, r.spans)
            return replace(plain, notes=[*r.sel.notes, *r.notes])
        if not r.over.size or done == ROUNDS:
            break
        tp, rounds, solved, splice = _inserted(problem, r, ROUNDS - done)
        log.debug("cone: %d rounds of points inserted where the curve leaves the cone", rounds)
        done += rounds
    assert r.curve is not None
    _say(r.notes)
    return Plan(
        toolpath=r.tp,
        param=r.param,
        rotary=r.rot,
        lift=np.zeros(len(r.param)),
        curve=r.curve,
        spans=r.spans,
        bent=True,
        notes=[*r.sel.notes, *r.notes],
        settled=r.sel.settled,
    )


@dataclass(frozen=True)
class _Round:
    """The cone planned once on a toolpath (:func:`_planned`).

    Attributes
    ----------
    tp : Toolpath
        The toolpath the rows refer to (branch switches made turns at a point).
    sel : Selection
        The exact branch choice on it.
    spans : list of Span
    notes : list of str
    bent : ndarray or None, shape (n, r), rad
        The cone's rotary angles at the points; None where nothing is bent.
    param, rot : ndarray, shapes (N,) and (N, r)
        The rows (empty when nothing is bent).
    curve : callable or None
        The joint curve through the rows.
    over : ndarray, shape (k,)
        Positions where the curve leaves the angle tolerance (:func:`_beyond`).
    solved : PointMemo
        The inverse kinematics of the points of ``tp`` (:func:`_solved`).
    """

    tp: Toolpath
    sel: Selection
    spans: list[Span]
    notes: list[str]
    bent: np.ndarray | None
    param: np.ndarray
    rot: np.ndarray
    curve: _ConeCurve | None
    over: np.ndarray
    solved: PointMemo


def _solved(problem: Problem, n: int) -> PointMemo:
    """The inverse kinematics of the branch choice (:func:`urdfpost.planning.branches.select`)
    as a row function of the points' tips and tool axes, ``(tip (k, 3), axis (k, 3)) -> (q,
    angles, valid, status)`` (the fields of :class:`urdfpost.kinematics.inverse.IKResult`),
    for a toolpath of ``n`` points: each round plans the points of the round before with a few
    inserted, and takes their solutions over (why that is exact:
    :mod:`urdfpost.planning.strategies._pointwise`)."""
    machine = problem.machine

    def solved(tip: np.ndarray, axis: np.ndarray) -> tuple[np.ndarray, ...]:
        ik = inverse(machine, tip, axis, problem.tool_length, problem.tol, pole_angle=0.0)
        return ik.q, ik.rotary.angles, ik.rotary.valid, ik.rotary.status

    return PointMemo.new(solved, n)


def _planned(problem: Problem, tp: Toolpath, solved: PointMemo) -> _Round:
    """One round of the cone on ``tp``: branch choice, spans, the bent angles, the rows and
    their curve, and where the curve leaves the angle tolerance. ``solved``: the inverse
    kinematics the round before computed (:func:`_solved`), on ``tp``."""
    machine = problem.machine
    (q, angles, valid, status), solved = solved(np.arange(len(tp)), tp.tip, tp.axis)
    sel = exact_selection(problem, tp, ik=IKResult(q, RotarySolutions(angles, valid, status)))
    tp, sel, old = split_at_switches(problem, tp, sel)
    solved = solved.moved(old, len(tp))
    spans = _spans(problem, tp, sel)
    bent, notes = _bend(problem, tp, sel, spans)
    if bent is None:
        none = np.zeros(0)
        return _Round(tp, sel, spans, notes, None, none, none.reshape(0, 2), None, none, solved)
    param, rot, curve = _rows(machine, tp, sel, bent)
    over = _beyond(problem, tp, curve, param, rot)
    return _Round(tp, sel, spans, notes, bent, param, rot, curve, over, solved)


def _inserted(
    problem: Problem, r: _Round, left: int
) -> tuple[Toolpath, int, PointMemo, _Splice | None]:
    """The toolpath of round ``r`` with the points it asks for inserted, and with those the
    next rounds would insert, found on windows of the path; how many rounds of points that is
    (1 to ``left``); the inverse kinematics ``r`` computed, on that toolpath; and, where the
    windows' rounds converged (the last asked for no points), ``r`` with the windows' last
    rounds (:func:`_spliced`), else None.

    A round changes the plan only where the cone bends, on the spans and where points are
    inserted: each stretch of ``r`` that has any of these gets a window reaching
    :data:`WINDOW_MARGIN` points beyond them (within the stretch, whose ends the cone keeps
    exact). The next round is planned on each window alone (starting from the angles ``r``
    chose at its first point), and its points inserted; and so on while the windows' branch
    choice is that of ``r`` and they ask for points. Where the windows' rounds are those of
    the whole path, the toolpath is the same as after as many rounds on the whole path; the
    caller splices the last round, or plans the whole path again, whose next round inserts
    what is still missing.
    """
    tp, old, _ = insert_points(r.tp, r.over, problem.pivot)
    solved = r.solved.moved(old, len(tp))
    windows = _windows(problem.machine, r)
    pos = old  # index in ``tp`` of each point of ``r.tp``
    rounds = 1
    while rounds < left and windows:
        found = _window_round(problem, r, tp, pos, windows, solved)
        if found is None:
            break
        over, local = found
        if not over.size:
            return tp, rounds, solved, _Splice(r, pos, local)
        tp, old, _ = insert_points(tp, over, problem.pivot)
        solved = solved.moved(old, len(tp))
        pos = old[pos]
        rounds += 1
    return tp, rounds, solved, None


@dataclass(frozen=True)
class _Splice:
    """Round ``first`` on the whole path and the last rounds on its windows, which asked for
    no points (:func:`_inserted`), on the toolpath they made (:func:`_spliced`).

    Attributes
    ----------
    first : _Round
        The round on the whole path the windows were cut from.
    pos : ndarray, shape (m,), int
        The index of each point of ``first.tp`` in the toolpath.
    local : list of tuple (int, int, _Round)
        Each window's first and last point in the toolpath, and its last round (on the window
        alone, its points those of the toolpath from the first to the last).
    """

    first: _Round
    pos: np.ndarray
    local: list[tuple[int, int, _Round]]


def _spliced(problem: Problem, tp: Toolpath, solved: PointMemo, s: _Splice) -> _Round | None:
    """The last round of the cone on ``tp``, spliced from round 1 (``s.first``) outside the
    windows and from the windows' last rounds inside them; None where they may not be spliced
    (the caller plans the whole path then).

    Outside the windows nothing changed from round 1: the same points, whose inverse
    kinematics is a row function (:func:`_solved`); no span, no bent angle and no point
    inserted (a window reaches :data:`WINDOW_MARGIN` points beyond each); the first round's
    curve was within the angle tolerance. Inside, each window's last round is the cone planned
    on the window alone from round 1's angles at its first point, and it asked for no points.
    They are spliced where:

    - round 1 and every window's last round bent only fed stretches (no notes) and passed over
      no candidate (no selection notes), and the windows' rows are one per point;
    - each window's branch choice is round 1's at the points they share (leaving joints but at
      the window's end, arriving ones but at its start, within :data:`SPLICE_BOUND`; the same
      rewinds), and its bent angles at its two ends are round 1's there (exact both, but for
      the tube's rounding);
    - every span of round 1 lies inside a window, no window's span touches its ends, and round
      1's settled point (:attr:`urdfpost.planning.branches.Selection.settled`) is outside the
      windows.

    The tube of a stretch (:func:`_tube`) bends it only where the exact angles turn faster
    than the steps allow: its forward pass's intervals bind nowhere near a window's ends, where
    round 1 kept the angles exact, so the whole path's tube bends each window as the window's
    own does. The branch choice is round 1's at every point it had and the window's at the
    inserted ones. ``tests/test_cone_splice.py`` compares this round with planning the whole
    path again, on every machine family.
    """
    r = s.first
    if not SPLICE or r.bent is None or r.notes or r.sel.notes:
        return None
    machine = problem.machine
    cols = list(machine.rotary_columns)
    n = len(tp)
    sel = r.sel
    q = np.empty((n, sel.q.shape[1]))
    arrive = np.empty_like(q)
    branch = np.empty(n, dtype=sel.branch.dtype)
    status = np.empty(n, dtype=sel.status.dtype)
    rewind = np.zeros(n, dtype=bool)
    bend = np.empty((n, len(cols)))  # the bent angles less the exact ones
    covered = np.zeros(n, dtype=bool)
    q[s.pos], arrive[s.pos], branch[s.pos] = sel.q, sel.arrive, sel.branch
    status[s.pos], rewind[s.pos], covered[s.pos] = sel.status, sel.rewind, True
    bend[s.pos] = r.bent - sel.q[:, cols]
    inside = np.zeros(n, dtype=bool)  # strictly inside a window
    spans = []
    for a, b, local in s.local:
        loc = local.sel
        if local.bent is None or local.notes or loc.notes or len(local.tp) != b - a + 1:
            return None
        own = loc.q[:, cols]
        ends = local.bent[[0, -1]] - own[[0, -1]]
        if not _near(ends, bend[[a, b]]):
            log.debug("cone: the ends of window %d-%d are not round 1's; not spliced", a, b)
            return None
        old = covered[a : b + 1]  # round 1's points in the window
        leave, arrive_at = old.copy(), old.copy()
        leave[-1] = arrive_at[0] = False  # (the window's own end and start)
        if not (
            _near(loc.q[leave], q[a : b + 1][leave])
            and _near(loc.arrive[arrive_at], arrive[a : b + 1][arrive_at])
            and np.array_equal(loc.rewind[old], rewind[a : b + 1][old])
        ):
            log.debug("cone: window %d-%d chose otherwise than round 1; not spliced", a, b)
            return None
        if any(sp.first <= 0 or sp.last >= b - a for sp in local.spans):
            return None
        # leaving angles but at the window's end, arriving ones but at its start
        q[a:b], arrive[a + 1 : b + 1] = loc.q[:-1], loc.arrive[1:]
        branch[a + 1 : b], status[a + 1 : b] = loc.branch[1:-1], loc.status[1:-1]
        rewind[a + 1 : b] = loc.rewind[1:-1]
        bend[a + 1 : b] = local.bent[1:-1] - own[1:-1]
        covered[a : b + 1] = True
        inside[a + 1 : b] = True
        spans += [replace(sp, first=sp.first + a, last=sp.last + a) for sp in local.spans]
    if not covered.all():
        return None
    for sp in r.spans:  # each inside a window (replaced by its own)
        if not inside[s.pos[sp.first] : s.pos[sp.last] + 1].all():
            return None
    settled = sel.settled
    if settled is not None and settled >= 0:
        if inside[s.pos[settled]]:
            return None
        settled = int(s.pos[settled])
    sel = replace(
        sel,
        q=q,
        branch=branch,
        status=status,
        arrive=arrive,
        rewind=rewind,
        notes=[],
        settled=settled,
    )
    spans.sort(key=lambda sp: sp.first)
    bent = q[:, cols] + bend  # (where nothing was bent, exact to the bit)
    param, rot, curve = _rows(machine, tp, sel, bent)
    log.debug("cone: the last round spliced from round 1 and %d windows", len(s.local))
    return _Round(tp, sel, spans, [], bent, param, rot, curve, np.zeros(0), solved)


def _near(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether ``a`` and ``b`` differ by at most :data:`SPLICE_BOUND` everywhere."""
    return bool(np.abs(a - b).max(initial=0.0) <= SPLICE_BOUND)


def _axis_deviation(machine: Machine, rotary: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """The angle between the tool axis of rotary angles ``rotary`` (k, r) rad and ``axis`` (k,
    3), shape (k,) rad: ``angle_between(tool_axis_of(machine, rotary), axis)``, compiled where
    the kernels are loaded (:data:`KERNELS`; the cosines, sines and ``arctan2`` by numpy, the
    rest in numpy's order of operations: the same numbers,
    :func:`urdfpost.planning.strategies._cone_kernel.axis_deviation`)."""
    kernel = KERNELS.loaded()
    if kernel is not None and len(rotary) and machine.rotary:
        cols = range(rotary.shape[1])
        try:
            across, along = np.empty(len(rotary)), np.empty(len(rotary))
            kernel.axis_deviation(
                np.array([a.direction for a in machine.rotary], dtype=float),
                np.ascontiguousarray(machine.home_tool_axis, dtype=float),
                np.stack([np.cos(rotary[:, j]) for j in cols], axis=1),
                np.stack([np.sin(rotary[:, j]) for j in cols], axis=1),
                np.ascontiguousarray(axis, dtype=float),
                across,
                along,
            )
            out: np.ndarray = 2.0 * np.arctan2(across, along)
            return out
        except Exception as err:  # numba could not compile or cache it here
            KERNELS.fail(err)
    return angle_between(tool_axis_of(machine, rotary), axis)


def _windows(machine: Machine, r: _Round) -> list[tuple[int, int]]:
    """Windows [a, b] (indices of ``r.tp``) around what round ``r`` bent, its spans and the
    points it inserts, one per stretch that has any of them (:func:`_inserted`); none where
    they would cover half the path or more (planning the whole path costs no more then)."""
    assert r.bent is not None
    exact = r.sel.q[:, machine.rotary_columns[0]]
    active = r.bent[:, 0] != exact
    for sp in r.spans:
        active[sp.first : sp.last + 1] = True
    seg = np.floor(r.over).astype(int)
    active[seg] = active[seg + 1] = True
    out = []
    for a, b in _stretches(r.tp, r.sel):
        at = np.flatnonzero(active[a : b + 1])
        if at.size:
            out.append(
                (max(a, a + int(at[0]) - WINDOW_MARGIN), min(b, a + int(at[-1]) + WINDOW_MARGIN))
            )
    if 2 * sum(b - a + 1 for a, b in out) >= len(r.tp):
        return []
    return out


def _window_round(
    problem: Problem,
    r: _Round,
    tp: Toolpath,
    pos: np.ndarray,
    windows: list[tuple[int, int]],
    solved: PointMemo,
) -> tuple[np.ndarray, list[tuple[int, int, _Round]]] | None:
    """The positions on ``tp`` where the next round, planned on each window alone, inserts
    points, shape (k,), and each window's first and last point on ``tp`` with that round; None
    where a window's branch choice is not that of ``r`` (at the
    points of ``r.tp``, ``pos`` their indices in ``tp``) or it bends nothing. ``solved``: the
    inverse kinematics ``r`` computed, on ``tp``."""
    cols = list(problem.machine.rotary_columns)
    found = []
    rounds = []
    for ra, rb in windows:
        a, b = int(pos[ra]), int(pos[rb])
        sub = toolpath_slice(tp, a, b + 1)
        local = _planned(
            replace(problem, toolpath=sub, start=r.sel.q[ra]), sub, solved.taken(slice(a, b + 1))
        )
        if local.bent is None or len(local.tp) != len(sub):
            return None
        at = pos[ra : rb + 1] - a
        # leaving angles but at the window's end, arriving ones but at its start (rewinds)
        same = np.allclose(local.sel.q[at[:-1]][:, cols], r.sel.q[ra:rb][:, cols], atol=1e-9)
        same &= np.allclose(
            local.sel.arrive[at[1:]][:, cols], r.sel.arrive[ra + 1 : rb + 1][:, cols], atol=1e-9
        )
        if not same:
            log.debug("cone: the branch choice of window %d-%d is not the whole path's", a, b)
            return None
        found.append(local.over + a)
        rounds.append((a, b, local))
    return (np.concatenate(found) if found else np.zeros(0)), rounds


def _say(notes: list[str]) -> None:
    """Log the plan's notes once, as warnings: a post always has a feed (``posting.process``
    fills it in or refuses the job), a comparison or a script may not, and a comparison shows
    no plan notes."""
    for note in notes:
        log.warning(note)


def _bend(
    problem: Problem, tp: Toolpath, sel: Selection, spans: list[Span]
) -> tuple[np.ndarray | None, list[str]]:
    """The cone's rotary angles at the CL points of ``tp``, shape (n, 2) rad, or None where
    nothing is bent; and the notes (a feed run with no feed)."""
    machine = problem.machine
    rot = sel.q[:, list(machine.rotary_columns)].copy()
    k1 = machine.rotary[0].direction
    vmax = machine.rotary[0].velocity
    length = norms(np.diff(tp.tip, axis=0))
    feed = tp.feed[1:] / 60.0  # mm/s
    with np.errstate(divide="ignore", invalid="ignore"):
        dt = np.where(feed > 0, length / feed, 0.0)
    step_max = 0.95 * vmax * dt
    # a turn in place (the tip held) has no tip feed to keep: the control takes the time its
    # axes need, so its step is not limited (a whole turn). Limited by its zero time, such a
    # turn left the tube no room (every interval closed: quadratic) and bent the whole stretch
    step_max[(feed > 0) & (length < IN_PLACE)] = 2.0 * np.pi
    measure: np.ndarray | None = None  # path measure of each step, for a run with no feed
    inside = np.zeros(len(tp), dtype=bool)  # strictly inside a span (its ends stay exact)
    for sp in spans:
        inside[sp.first + 1 : sp.last] = True
    sin_phi = np.sqrt(np.clip(1.0 - (tp.axis @ k1) ** 2, 0.0, None))
    arrive = sel.arrive[:, list(machine.rotary_columns)]
    changed = False
    unfed: int | None = None
    for a, b in _stretches(tp, sel):
        # a stretch ends on a rewind (or branch switch) point with the angles it arrives with
        arrives = bool(sel.rewind[b])
        exact, tilt = rot[a : b + 1, 0].copy(), rot[a : b + 1, 1].copy()
        if arrives:
            exact[-1], tilt[-1] = arrive[b]
        step = step_max[a:b]
        allowed = np.ones(b - a + 1, dtype=bool)
        if not (feed[a:b] > 0).all():  # no time to rate the axis by: the geometric cone
            unfed = a if unfed is None else min(unfed, a)
            allowed = inside[a : b + 1]
            if measure is None:
                measure = np.diff(arc_length(tp))
            ds = np.maximum(measure[a:b], 1e-12)
            rate = np.abs(np.diff(exact)) / ds
            if not allowed.any() or not rate.max(initial=0.0) > 0:
                continue
            step = GEOMETRIC_SHARE * float(rate.max()) * ds
        if np.all(np.abs(np.diff(exact)) <= step + 1e-12):
            continue
        cand = _in_cone(problem, tp.axis[a : b + 1], exact, tilt, sin_phi[a : b + 1], step, allowed)
        upto = b if arrives else b + 1  # the point's own (leaving) angles stay
        if np.abs(cand[: upto - a] - rot[a:upto]).max(initial=0.0) > 1e-12:
            changed = True
            rot[a:upto] = cand[: upto - a]
    notes = []
    if unfed is not None:
        note = (
            f"{tp.source}:{int(tp.line[min(unfed + 1, len(tp) - 1)])}: cone: cutting moves "
            "with no feed, so no time to rate the first rotary axis by; there it is bent only "
            "inside the singular spans, to the least turn per unit path the angle tolerance "
            "allows"
        )
        notes.append(note)
    return (rot if changed else None), notes


def _stretches(tp: Toolpath, sel: Selection) -> list[tuple[int, int]]:
    """The stretches [a, b] of the feed runs between their rewind points (where the selection
    arrives with one solution and leaves with another: a rewind, or a branch switch made a
    turn at a point): the cone bends each on its own, its ends exact."""
    out = []
    for s, e in feed_runs(tp):
        cuts = [s, *(np.flatnonzero(sel.rewind[s + 1 : e + 1]) + s + 1).tolist()]
        if cuts[-1] != e:
            cuts.append(e)
        out += [(a, b) for a, b in itertools.pairwise(cuts) if b > a]
    return out


def _in_cone(
    problem: Problem,
    axis: np.ndarray,
    exact: np.ndarray,
    tilt: np.ndarray,
    sin_phi: np.ndarray,
    step: np.ndarray,
    allowed: np.ndarray,
) -> np.ndarray:
    """Rotary angles of one stretch within the cone, shape (k, 2) rad.

    Parameters
    ----------
    axis : ndarray, shape (k, 3)
        Programmed tool axes.
    exact, tilt : ndarray, shape (k,), rad
        The exact first rotary angles, and the tilts to stay near.
    sin_phi : ndarray, shape (k,)
        Sine of each axis' angle from the pole.
    step : ndarray, shape (k - 1,), rad
        Largest change of the first angle between neighbours.
    allowed : ndarray, shape (k,), bool
        Points that may be bent (the stretch's ends never are).
    """
    machine = problem.machine
    scale = np.ones(len(exact))
    for attempt in range(HALVINGS + 1):
        ratio = np.sin(problem.angle_tolerance) * scale / np.maximum(sin_phi, 1e-12)
        half = np.where(ratio >= 1.0, np.pi, np.arcsin(np.clip(ratio, 0.0, 1.0)))
        half[[0, -1]] = 0.0  # the stretch's ends stay exact
        half[~allowed] = 0.0
        theta = _tube(exact, half, step)
        t2 = best_tilt(machine, axis, theta, tilt)
        t2 = np.clip(t2, machine.rotary[1].lower, machine.rotary[1].upper)
        cand = np.stack([theta, t2], axis=1)
        dev = _axis_deviation(machine, cand, axis)
        over = dev > problem.angle_tolerance * (1 + 1e-9)
        if not over.any():
            break
        # halved where the orientation left the cone; after HALVINGS, exact there
        scale = np.where(over, 0.0 if attempt == HALVINGS - 1 else scale * 0.5, scale)
    return cand


def _rows(
    machine: Machine, tp: Toolpath, sel: Selection, bent: np.ndarray
) -> tuple[np.ndarray, np.ndarray, _ConeCurve]:
    """The cone's rows for the bent angles ``bent`` (n, r) rad at the CL points of ``tp``
    (branch choice ``sel``): one per CL point, with a turn in place where a row stands on the
    pole (:func:`_turn_at_poles`), as ``param`` (N,) and ``rot`` (N, r); and their curve."""
    q = sel.q.copy()
    q[:, list(machine.rotary_columns)] = bent
    param, rot = _turn_at_poles(machine, replace(sel, q=q), tp)
    return param, rot, _curve(machine, tp, param, rot)


def _curve(machine: Machine, tp: Toolpath, param: np.ndarray, rot: np.ndarray) -> _ConeCurve:
    """The cone's joint curve through its rows (:class:`_ConeCurve`)."""
    return _ConeCurve(machine, tp, param, rot, param[1:][param[1:] == param[:-1]])


@dataclass(frozen=True)
class _ConeCurve:
    """The cone's joint curve through its rows: the first rotary angle linear in the position,
    the tilt closest to the programmed axis; NaN at a turn in place on the pole (the exact
    solution between its two rows).

    Attributes
    ----------
    machine : Machine
    tp : Toolpath
    param, rot : ndarray, shapes (N,) and (N, 2)
        The rows (finite).
    turns : ndarray, shape (k,)
        The positions of the turns in place (two rows at one position).
    """

    machine: Machine
    tp: Toolpath
    param: np.ndarray
    rot: np.ndarray
    turns: np.ndarray

    def __call__(self, x: np.ndarray) -> np.ndarray:
        """The rotary angles at positions ``x`` (k,), shape (k, 2) rad."""
        machine, param, rot = self.machine, self.param, self.rot
        t1 = np.interp(x, param, rot[:, 0])
        ref = np.interp(x, param, rot[:, 1])
        _, ax = at_param(self.tp, x, 0.0)
        lo2, hi2 = machine.rotary[1].lower, machine.rotary[1].upper
        t2 = np.clip(best_tilt(machine, ax, t1, ref), lo2, hi2)
        out = np.stack([t1, t2], axis=1)
        out[~self.defined(x)] = np.nan
        return out

    def defined(self, x: np.ndarray) -> np.ndarray:
        """Where the curve is defined (finite) at positions ``x`` (k,) on the path, shape (k,)
        bool, without evaluating it: every position but the turns in place (the rows, the CL
        points and the interpolation between them are finite)."""
        return ~np.isin(x, self.turns)


def _beyond(
    problem: Problem,
    tp: Toolpath,
    curve: Callable[[np.ndarray], np.ndarray],
    param: np.ndarray,
    rot: np.ndarray,
) -> np.ndarray:
    """Positions where the curve leaves the angle tolerance most, one per CL segment that it
    leaves between its rows (sampled at :data:`CURVE_SAMPLES` per segment), shape (k,).

    Only the segments whose bound (:func:`_deviation_bound`) exceeds the tolerance are
    sampled: the others (on a dense path all but those of the bent and fast-turning stretches
    near the singular spans) keep within it. The rounding of the sampled deviations is far
    inside the ``1e-9`` relative margin of the test.
    """
    n = len(tp)
    if n < 2:
        return np.zeros(0)
    feed = np.flatnonzero((tp.motion[1:] == Motion.FEED) & ~entry_mask(tp)[1:])
    bound = _deviation_bound(problem.machine, tp, param, rot, feed)
    feed = feed[~(bound <= problem.angle_tolerance)]  # NaN: sampled
    if not feed.size:
        return np.zeros(0)
    frac = np.arange(1, CURVE_SAMPLES) / CURVE_SAMPLES
    x = (feed[:, None] + frac[None, :]).ravel()
    on_curve = curve(x)
    _, prog = at_param(tp, x, 0.0)
    dev = np.zeros(len(x))
    ok = np.isfinite(on_curve).all(axis=1)
    dev[ok] = _axis_deviation(problem.machine, on_curve[ok], prog[ok])
    per_segment = dev.reshape(len(feed), len(frac))
    worst = np.argmax(per_segment, axis=1)
    bad = per_segment[np.arange(len(feed)), worst] > problem.angle_tolerance * (1 + 1e-9)
    return feed[bad] + frac[worst[bad]]


def _deviation_bound(
    machine: Machine, tp: Toolpath, param: np.ndarray, rot: np.ndarray, seg: np.ndarray
) -> np.ndarray:
    """Bounds of the deviation of the cone's curve from the programmed tool axis on the CL
    segments ``seg`` (from point i to i + 1), shape (k,) rad.

    On segment i the curve (:func:`_curve`) runs the first rotary angle linearly between the
    rows at i and i + 1 and takes the tilt closest to the programmed axis, clipped to travel.
    Its deviation is at most that of the curve with the tilt linear between the rows too (for
    a given first angle the deviation is unimodal in the tilt, and the clipped closest tilt
    lies between the linear one and the closest). That curve's tool axis moves by at most
    ``t * turn`` from the first row's (``turn``: the rows' summed rotary steps; a rotation
    moves a unit vector by at most its angle), the programmed axis by ``t * alpha`` (slerp
    over the angle ``alpha``); so at ``t`` the deviation is at most ``d0 + t (turn + alpha)``,
    and from the other end ``d1 + (1 - t) (turn + alpha)``, with ``d0``, ``d1`` the rows' own
    deviations: never more than ``(d0 + d1 + turn + alpha) / 2``. A row's tilt may lie beyond
    its travel by the slack the branch choice allows; the clipped tilt then lies that much
    beyond the linear one at most, which adds as much to the deviation (a turn of the tilt
    moves the tool axis by at most its angle), and to the bound.

    Parameters
    ----------
    machine : Machine
    tp : Toolpath
    param, rot : ndarray, shapes (N,) and (N, r)
        The cone's rows, each on a CL point (several on one point: turns in place on the pole
        and rewind arrivals).
    seg : ndarray, shape (k,), int

    Returns
    -------
    ndarray, shape (k,), rad
        NaN where a row's angles are NaN.

    Where the kernels are loaded (:data:`KERNELS`), the arithmetic after the deviations runs
    compiled (:func:`urdfpost.planning.strategies._cone_kernel.deviation_bound`, the same
    numbers).
    """
    dev = _axis_deviation(machine, rot, tp.axis[param.astype(int)])
    alpha = angle_between(tp.axis[seg], tp.axis[seg + 1])
    tilt, lo2, hi2 = rot[:, 1], machine.rotary[1].lower, machine.rotary[1].upper
    kernel = KERNELS.loaded()
    if (
        kernel is not None
        and len(seg)
        and len(param)
        and seg[-1] + 1 <= param[-1]  # (beyond the rows numpy raises)
        and bool(np.all(np.diff(seg) > 0))
    ):
        args = [np.ascontiguousarray(a, dtype=float) for a in (dev, rot, param)]
        try:
            bound: np.ndarray = kernel.deviation_bound(
                *args,
                np.ascontiguousarray(seg, dtype=np.int64),
                np.ascontiguousarray(alpha, dtype=float),
                float(lo2),
                float(hi2),
            )
            return bound
        except Exception as err:  # numba could not compile or cache it here
            KERNELS.fail(err)
    beyond = np.maximum(np.maximum(tilt - hi2, lo2 - tilt), 0.0)  # beyond the tilt's travel
    first = np.searchsorted(param, seg, side="right") - 1  # the last row at point i
    last = np.searchsorted(param, seg + 1, side="left")  # the first row at point i + 1
    turn = np.abs(rot[last] - rot[first]).sum(axis=1)
    clipped = np.maximum(beyond[first], beyond[last])
    return 0.5 * (dev[first] + dev[last] + turn + alpha) + clipped


def _rounding(a: np.ndarray, b: np.ndarray, step: np.ndarray) -> float:
    """Rounding of the running sums over two bands ``a``, ``b`` and the steps ``step`` (rad):
    intervals closed by no more than this are one value."""
    scale = float(np.abs(a).max(initial=0.0)) + float(np.abs(b).max(initial=0.0))
    return 16.0 * float(np.spacing(scale + float(np.abs(step).sum())))


def _reachable(
    lo: np.ndarray, hi: np.ndarray, step: np.ndarray, stop: bool = False
) -> tuple[np.ndarray, np.ndarray, bool]:
    """Forward pass: the interval reachable at each point within the band and step limits.

    ``r_lo[i] = max(lo[i], r_lo[i-1] - step[i-1])`` (and ``r_hi`` alike) is, unrolled,
    ``max over j <= i of lo[j] - (steps from j to i)``: a running maximum of ``lo`` plus the
    cumulative steps, less those. Where the interval closes (no value is reachable), it is
    restarted from the middle of the previous one, clipped to the band, and ``ok`` is False;
    intervals closed by no more than the rounding of the cumulative sums count as one value.

    Parameters
    ----------
    lo, hi : ndarray, shape (n,), rad
    step : ndarray, shape (n - 1,), rad
    stop : bool
        Return at the first closed interval (only ``ok`` is wanted); the intervals after it
        are then not computed.

    Returns
    -------
    r_lo, r_hi : ndarray, shape (n,)
    ok : bool
    """
    n = len(lo)
    r_lo, r_hi = lo.copy(), hi.copy()
    ok = True
    s = 0
    while s < n - 1:
        cum = np.concatenate([[0.0], np.cumsum(step[s:])])
        own_lo = np.concatenate([[r_lo[s]], lo[s + 1 :]])
        own_hi = np.concatenate([[r_hi[s]], hi[s + 1 :]])
        a, b = own_lo + cum, own_hi - cum
        run_lo, run_hi = np.maximum.accumulate(a), np.minimum.accumulate(b)
        # where the band itself bounds the interval, its own value (no rounding of the sums)
        a = np.where(run_lo == a, own_lo, run_lo - cum)
        b = np.where(run_hi == b, own_hi, run_hi + cum)
        eps = _rounding(lo[s:], hi[s:], step[s:])
        closed = np.flatnonzero(a > b + eps)
        f = int(closed[0]) if closed.size else len(a)
        tight = np.flatnonzero(a[:f] > b[:f])
        a[tight] = b[tight] = 0.5 * (a[tight] + b[tight])
        r_lo[s + 1 : s + f], r_hi[s + 1 : s + f] = a[1:f], b[1:f]
        if not closed.size:
            break
        ok = False
        i = s + f
        if stop:
            break
        mid = float(np.clip(0.5 * (r_lo[i - 1] + r_hi[i - 1]), lo[i], hi[i]))
        r_lo[i] = r_hi[i] = mid
        s = i
    return r_lo, r_hi, ok


def _tube(exact: np.ndarray, half: np.ndarray, step: np.ndarray) -> np.ndarray:
    """:func:`_tube_numpy`, compiled where the kernels are loaded (:data:`KERNELS`, the same
    numbers: :func:`urdfpost.planning.strategies._cone_kernel.tube`).

    Parameters
    ----------
    exact, half : ndarray, shape (n,), rad
    step : ndarray, shape (n - 1,), rad

    Returns
    -------
    ndarray, shape (n,)
    """
    kernel = KERNELS.loaded()
    if kernel is not None and len(exact) > 1:
        args = [np.ascontiguousarray(a, dtype=float) for a in (exact, half, step)]
        if all(np.isfinite(a).all() for a in args) and (args[1] >= 0).all():
            try:
                tube: np.ndarray = kernel.tube(*args)
                return tube
            except Exception as err:  # numba could not compile or cache it here
                KERNELS.fail(err)
    return _tube_numpy(exact, half, step)


def _tube_numpy(exact: np.ndarray, half: np.ndarray, step: np.ndarray) -> np.ndarray:
    """A rate-limited sequence within ``exact +- half``, as close to ``exact`` as it can be.

    Forward pass: the interval of values reachable at each point from the start within the
    band and the step limits; backward pass: the value nearest the exact one that still reaches
    the next chosen value. Where the band leaves no room for the step limits, they are raised
    by the smallest common factor that makes the band feasible (found by bisection), so the
    peak rate is as low as the band allows.

    The backward pass is sequential only where it must be: from a point that takes its exact
    value, the one before does too wherever its exact value is reachable and within a step of
    the next exact value, so those stretches are filled at once.

    Parameters
    ----------
    exact, half : ndarray, shape (n,), rad
    step : ndarray, shape (n - 1,), rad
        Largest allowed change between neighbours.

    Returns
    -------
    ndarray, shape (n,)
    """
    lo, hi = exact - half, exact + half
    r_lo, r_hi, ok = _reachable(lo, hi, step, stop=True)
    if not ok:
        with np.errstate(divide="ignore", invalid="ignore"):
            need = np.abs(np.diff(exact)) / step
        k_lo, k_hi = 1.0, float(np.nanmax(np.where(np.isfinite(need), need, 1.0), initial=1.0))
        k_hi = max(k_hi, 1.0) * (1 + 1e-9)
        for _ in range(40):
            k = np.sqrt(k_lo * k_hi)
            if _reachable(lo, hi, step * k, stop=True)[2]:
                k_hi = k
            else:
                k_lo = k
            if k_hi / k_lo < 1.001:
                break
        step = step * k_hi
        r_lo, r_hi, _ = _reachable(lo, hi, step)
    n = len(exact)
    out = np.empty(n)
    out[-1] = np.clip(exact[-1], r_lo[-1], r_hi[-1])
    if n == 1:
        return out
    # where the next point is exact, this one is exact too unless ``easy`` fails
    e0, e1 = exact[:-1], exact[1:]
    easy = (np.maximum(r_lo[:-1], e1 - step) <= e0) & (e0 <= np.minimum(r_hi[:-1], e1 + step))
    hard = np.flatnonzero(~easy)
    eps = _rounding(exact, half, step)
    i = n - 2
    while i >= 0:
        nxt = float(out[i + 1])
        if nxt == exact[i + 1] and easy[i]:
            # exact back to the last point where that may fail
            k = int(np.searchsorted(hard, i)) - 1
            j = int(hard[k]) if k >= 0 else -1
            out[j + 1 : i + 1] = exact[j + 1 : i + 1]
            i = j
            continue
        a = max(float(r_lo[i]), nxt - float(step[i]))
        b = min(float(r_hi[i]), nxt + float(step[i]))
        e = float(exact[i])
        if a <= b:
            out[i] = min(max(e, a), b)
        elif a <= b + eps:  # one value, closed by rounding
            out[i] = 0.5 * (a + b)
        else:
            out[i] = min(max(e, float(r_lo[i])), float(r_hi[i]))
        i -= 1
    return out
