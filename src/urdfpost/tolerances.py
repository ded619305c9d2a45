"""Every numerical threshold urdfpost uses, in one documented place.

Thresholds are passed explicitly (a :class:`Tolerances` instance travels with the options); there
is no mutable module state. Lengths are millimetres, angles radians, unless a name says otherwise.
"""

from __future__ import annotations

from dataclasses import dataclass

from urdfpost.units import mm_per_unit

IN_PLACE = 1e-6
"""Tip path below which (mm) a block turns the tool in place: it has no tip feed to keep or
compare (a turn at a pole, a reorientation with the tip held); its time is its axes' limit or,
without one, its axis-space length at the CL feed (:mod:`urdfpost.verification.feeds`), and
the cone does not limit its first rotary axis' step there
(:func:`urdfpost.planning.strategies.cone._bend`)."""


@dataclass(frozen=True)
class Tolerances:
    """Thresholds for posting and verification.

    Attributes
    ----------
    tip : float
        Allowed tool-tip deviation from the CL path, mm. 0.01 mm is a common finishing chord
        tolerance and the issue's default; inch programs use 0.0004 in (0.01016 mm).
    orientation : float
        Allowed tool-axis deviation from the CL tool axis (slerp between CL points), rad.
        0.5 degree: well below what changes a ball-end cut, above the rounding of 0.0001 degree
        output on any realistic machine.
    interpolation_share : float
        Share of ``tip`` given to the interpolation between blocks when subdividing
        machine-coordinate moves; the rest is kept for the rounding of the written program
        (0.001 mm, 0.0001 in, 0.0001 degree at up to a metre from the rotary axis).
    pole : float
        Sine of the angle between the tool axis and the first rotary axis below which that
        axis' angle is taken as undetermined (the pole). 1e-9: a CL axis written with 9-10
        significant digits cannot be closer to the pole than this unless it is exactly on it.
    reach : float
        Slack, in the cosine domain of the tilt equation, for orientations at the edge of what
        the machine can reach (clipped onto the edge instead of rejected). 1e-9.
    branch_merge : float
        Two tilt solutions closer than this (rad) are one branch (the edge of the reachable
        set): the point is reported as an edge point with one branch. The tilt itself comes
        from a half-angle formula that does not cancel near the edge, so it is not moved.
    pole_crossing : float
        A feed block whose tool axis passes a pole closer than this (rad) crosses it: the
        crossing point is inserted with the axis on the pole, so the first rotary axis can turn
        there in place. 1e-6 rad changes the orientation by far less than any cut can show.
    four_axis_axis : float
        Angle (rad) by which a CL tool axis may miss the cone a single rotary axis can reach
        on a 4-axis machine. 1e-6 rad: CL files print 6-10 decimals.
    chord_share : float
        Share of ``tip`` allowed as chord error when CIRCLE records are interpolated into
        points: the program is verified against those points, so the deviation from the true
        arc is at most the verified deviation plus ``chord``. 0.1 keeps that within 1.1 times
        the tolerance at about three times the points of a full-tolerance chord.
    max_subdivision_depth : int
        Cap on recursive bisection of one block (2**depth pieces at most).
    samples_per_block : int
        Samples per block when measuring the deviation between two blocks (the maximum is
        refined around the worst sample by golden-section search).
    singular_sigma : float
        A CL point whose orientation Jacobian has a smallest singular value below this is
        singular (see :mod:`urdfpost.planning.singularity`). sin(2 deg) = 0.0349: for an
        orthogonal two-axis machine the tool axis lies within 2 degrees of the pole, where the
        first rotary axis turns at least 29 times faster than the tool axis does.
    swing_limit : float
        A step between neighbouring CL points that turns a rotary axis by more than this (rad)
        is flagged as a swing even where the conditioning is fine. 10 degrees: Fusion's
        singularity "angle" default; a proper finishing path turns a few degrees per point.
    singular_margin : int
        CL points added on each side of a singular span (within its feed run); the span's end
        points are where a strategy hands back to the exact inverse kinematics.
    spline_step : float
        Largest turn of the first rotary axis between rows the ``spline`` strategy inserts
        along its curve, rad. 2 degrees (ModuleWorks interpolates poles in 3-degree steps);
        the generic subdivision adds more where the nonlinear error needs them.
    rollover_turn : float
        Largest turn of a rollover axis in one block, rad (:mod:`urdfpost.posting.rollover`:
        longer turns are split). 179 degrees: less than the half turn at which a control that
        takes the shortest way could go either way, with room for the written rounding
        (0.0001 degree).
    feed_share : float
        How far the tip feed a feed block gives may differ from the CL feed, as a share of
        it (verification, :mod:`urdfpost.verification.feeds`). 1 %: well above the rounding
        of the written F words and positions, well below what a cut shows.
    """

    tip: float = 0.01
    orientation: float = 0.008726646259971648  # 0.5 degree
    interpolation_share: float = 0.8
    pole: float = 1e-9
    reach: float = 1e-9
    branch_merge: float = 2e-6
    pole_crossing: float = 1e-6
    four_axis_axis: float = 1e-6
    chord_share: float = 0.1
    max_subdivision_depth: int = 12
    samples_per_block: int = 9
    singular_sigma: float = 0.03489949670250097  # sin(2 deg)
    swing_limit: float = 0.17453292519943295  # 10 deg
    singular_margin: int = 1
    spline_step: float = 0.03490658503988659  # 2 deg
    rollover_turn: float = 3.12413936106985  # 179 deg
    feed_share: float = 0.01

    @property
    def chord(self) -> float:
        """Chord tolerance for arc interpolation, mm."""
        return self.tip * self.chord_share

    @classmethod
    def for_units(cls, units: str, tip: float | None = None) -> Tolerances:
        """Default tolerances for a program in ``units`` ("mm" or "inch").

        Parameters
        ----------
        units : str
            "mm" or "inch".
        tip : float, optional
            Tool-tip tolerance in ``units``; default 0.01 mm or 0.0004 in.

        Returns
        -------
        Tolerances
            With ``tip`` converted to mm.
        """
        scale = mm_per_unit(units)
        if tip is None:
            tip = 0.0004 if units == "inch" else 0.01
        return cls(tip=tip * scale)
