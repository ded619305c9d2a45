"""Verification: a program's motion, run through the machine, compared with the CL data.

Every block end of the program goes through the forward kinematics; between feed blocks the
axes are interpolated as the control does, sampled, and refined where it can matter. The result
is compared with the CL path: the tool-tip distance to the CL polyline, the tool-axis angle to
the CL orientation path near the tip (the slerp of the CL axes, within the tip tolerance of the
tip's place along the segment: ``docs/verification.md``), and which CL points the program
reaches, in order.

Modules
-------
:mod:`urdfpost.verification.match`
    Which program rows reach which CL points, the rows' joint values and poses.
:mod:`urdfpost.verification.measure`
    The deviation of the blocks from the CL path, and the figures of a :class:`Verification`.

The streamed verifier (:func:`urdfpost.posting.readback.verify_stream`) uses the matching on its
own (:func:`match_points`, :data:`REACH`) to find where a program can be checked in pieces.
"""

from __future__ import annotations

from urdfpost.verification.match import (
    REACH,
    at_pivot,
    match_points,
    program_joints,
    row_points,
    row_poses_at_tip,
)
from urdfpost.verification.measure import (
    Check,
    Verification,
    missed_note,
    rewind_note,
    verify,
    verify_checks,
    verify_matched,
)

__all__ = [
    "REACH",
    "Check",
    "Verification",
    "at_pivot",
    "match_points",
    "missed_note",
    "program_joints",
    "rewind_note",
    "row_points",
    "row_poses_at_tip",
    "verify",
    "verify_checks",
    "verify_matched",
]
