"""The check of a posted piece: its program read back, against the CL data and the strategy's path.

Every post ends here, whole or in pieces, in this process or in a verification worker:
:func:`check_piece` measures the program read back from its text against what the piece was
made from (a :class:`CheckTarget`), and :func:`tolerance_error` is the error of a program that
misses its tolerance. The measuring itself is :mod:`urdfpost.verification`.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from urdfpost.errors import ToleranceError
from urdfpost.machine import Machine
from urdfpost.program import Program
from urdfpost.tolerances import Tolerances
from urdfpost.toolpath import Toolpath
from urdfpost.verification import Check, Verification, verify, verify_checks
from urdfpost.verification.feeds import FeedRules


@dataclass(frozen=True)
class CheckTarget:
    """What the program of a piece is checked against (small enough to send to a worker).

    Attributes
    ----------
    cl : Toolpath
        The CL points of the piece.
    intended : Toolpath or None
        The path the strategy intended, where it bent the tool axis or moved the path; None:
        the CL data is the path.
    lifts : int
        Lifted spans of the plan (the tip leaves the CL path there by design).
    pivot_mm : float
        Ball radius of the cutter: a bent axis is checked at the ball centre.
    angle_tolerance_deg : float
        How far the strategy may bend the tool axis.
    tool_length : float
        mm: the length the machine-coordinate positions include.
    feed_rules : FeedRules or None
        How the control times the blocks (:mod:`urdfpost.verification.feeds`): the tip feed
        of every feed block is checked against the CL feed; None: not checked.
    """

    cl: Toolpath
    intended: Toolpath | None
    lifts: int
    pivot_mm: float
    angle_tolerance_deg: float
    tool_length: float
    feed_rules: FeedRules | None = None


def bent_tolerances(tol: Tolerances, angle_tolerance_deg: float, pivot: float) -> Tolerances:
    """Tolerances against the CL data for a program whose strategy bent the tool axis.

    The orientation may deviate by the angle tolerance on top of its own; the cutting point,
    ``pivot`` mm up the tool axis (a ball centre), by the tip tolerance plus ``pivot`` times the
    orientation tolerance: what that point moves when tip and axis are each within theirs.
    """
    return replace(
        tol,
        orientation=tol.orientation + float(np.radians(angle_tolerance_deg)),
        tip=tol.tip + pivot * tol.orientation,
    )


def check_piece(
    program: Program,
    machine: Machine,
    target: CheckTarget,
    tol: Tolerances,
    floors: tuple[float, float] = (0.0, 0.0),
) -> tuple[Verification, Verification | None]:
    """A piece's program, read back, against the CL data and against its strategy's path.

    A strategy that bends the tool axis is checked twice: against the path it intended (rows
    and curve: tip and orientation tolerances as usual), and against the CL data with the
    orientation allowed the angle tolerance on top, measured at the cutting point (the ball
    centre of a ball-end tool, whose tolerance is the tip tolerance plus the ball radius times
    the orientation tolerance: what a ball centre may move when tip and axis are each within
    theirs). A strategy that does not bend is checked against the CL data as it is.

    Parameters
    ----------
    program : Program
        As read back from the text.
    machine : Machine
    target : CheckTarget
    tol : Tolerances
    floors : (float, float), rad
        The orientation deviations the program is known to reach against the CL data and
        against the intended path in the pieces checked before (:class:`PieceLevels`): no
        block is refined for less (:attr:`urdfpost.verification.Check.orientation_floor`).

    Returns
    -------
    cl : Verification
        Against the CL data.
    intended : Verification or None
        Against the strategy's path (None when the CL data is the path).
    """
    length = target.tool_length
    if target.intended is None:
        return verify(
            program,
            machine,
            target.cl,
            tool_length=length,
            tol=tol,
            feed_rules=target.feed_rules,
            orientation_floor=floors[0],
        ), None
    pivot = target.pivot_mm
    loose = bent_tolerances(tol, target.angle_tolerance_deg, pivot)
    checks = [
        Check(target.intended, tol, orientation_floor=floors[1]),
        Check(target.cl, loose, pivot, orientation_floor=floors[0]),
    ]
    intended, cl = verify_checks(program, machine, checks, length, feed_rules=target.feed_rules)
    if target.lifts:
        cl = replace(
            cl,
            ok=intended.ok,
            notes=[
                *cl.notes,
                f"{target.lifts} lifted spans: the tip leaves the CL path there by design",
            ],
        )
    return cl, intended


@dataclass
class PieceLevels:
    """What the pieces of a streamed program checked so far reached, against the CL data and
    against the paths their strategies intended: the orientation deviation below which the
    next piece's blocks need no refining (:func:`check_piece`'s ``floors``).

    The merged verification of the pieces
    (:func:`urdfpost.posting.readback.merge_verifications`) reports the largest orientation
    deviation of any piece, the largest share of its tolerances any piece takes and that
    piece's worst CL line. A piece whose blocks stay below the largest
    orientation deviation reported before it, below its own orientation tolerance times the
    largest share reported before it, and below its tolerance, changes none of these, nor
    whether it is within its tolerance; so its blocks below the smallest of the three need no
    refining. The first piece that reaches the program's largest deviation or share (its
    maximum with every block refined) reaches these levels and is refined as before, and so
    reports the same figures. Pieces are taken in order (a later piece never beats an earlier
    one with the same share).

    Attributes
    ----------
    orientation : list of float, rad
        The largest orientation deviation reported, against the CL data and the intended path.
    share : list of float
        The largest share of its tolerances (tip or orientation) a piece took, likewise.
    """

    orientation: list[float] = field(default_factory=lambda: [0.0, 0.0])
    share: list[float] = field(default_factory=lambda: [0.0, 0.0])

    def floors(self, tol: Tolerances, target: CheckTarget) -> tuple[float, float]:
        """The floors for a piece checked with ``tol`` (rad; against the CL data and the intended
        path), a little below the levels so that their rounding refines no less."""
        cl_tol = tol
        if target.intended is not None:
            cl_tol = bent_tolerances(tol, target.angle_tolerance_deg, target.pivot_mm)
        out = []
        for i, t in enumerate((cl_tol, tol)):
            level = min(self.orientation[i], self.share[i] * t.orientation)
            out.append(level * (1.0 - _FLOOR_MARGIN))
        return out[0], out[1]

    def add(self, checks: tuple[Verification, Verification | None]) -> None:
        """Take in a piece's verifications (of :func:`check_piece`)."""
        for i, v in enumerate(checks):
            if v is None:
                continue
            self.orientation[i] = max(
                self.orientation[i], float(np.radians(v.max_orientation_deviation_deg))
            )
            self.share[i] = max(self.share[i], tolerance_share(v))


def tolerance_share(v: Verification) -> float:
    """The larger share of its tolerance a verification's tip or orientation deviation takes
    (the piece whose :attr:`~Verification.worst_cl_line` a merged verification names:
    :func:`urdfpost.posting.readback.merge_verifications`)."""
    return max(
        v.max_tip_deviation / v.tip_tolerance,
        v.max_orientation_deviation_deg / v.orientation_tolerance_deg,
    )


_FLOOR_MARGIN = 1e-9
"""Relative margin below the levels of :class:`PieceLevels` (their conversions from degrees
and back round)."""


def tolerance_error(
    cl: Toolpath,
    checks: tuple[Verification, Verification | None],
    units: str,
    *,
    piece: bool = False,
) -> ToleranceError | None:
    """The error of a program that misses its tolerance, or None when it does not.

    Parameters
    ----------
    cl : Toolpath
        The CL data checked against (for the message).
    checks : (Verification, Verification or None)
        Of :func:`check_piece`: the one against the intended path is reported first.
    units : str
        Of the figures in the message.
    piece : bool
        ``cl`` is a piece of a streamed post: the message names its CL lines.
    """
    check, intent = checks
    for v, what in ((intent, "the path its strategy intended"), (check, "the CL data")):
        if v is not None and not v.ok:
            lines = f" (lines {int(cl.line[0])} to {int(cl.line[-1])})" if piece else ""
            return ToleranceError(
                f"{cl.source}: the program misses its tolerance against {what}{lines}, nothing "
                f"written: {v.summary(units)}"
                + (f"; worst near CL line {v.worst_cl_line}" if v.worst_cl_line else "")
            )
    return None
