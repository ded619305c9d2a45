"""The check of a program's canned cycles against the CL data's holes.

A program's :class:`~urdfpost.program.Cycle` blocks are expanded into the motion the control
runs (:func:`urdfpost.program.expand_cycles`, the same expansion ``--expand-cycles`` writes),
and that motion goes through the machine like every other row. The CL data's holes (the points
of its ``cycle`` events, :func:`urdfpost.toolpath.cycle_holes`) are not matched as points of
the path: a hole is a hole top to drill from, which the control reaches on the feed into the
hole rather than at a block end (an ISO ``G81`` does not even name it). Each is checked here
instead, in order, against the rows of the expanded cycles that run on its axis (the first run
of consecutive cycle rows within the tip tolerance of the line through the hole top along its
tool axis, after the run of the hole before):

- the hole top lies on one of the feed blocks of the run (within the tip tolerance);
- the deepest point of the run is the hole bottom, the top plus the cycle's depth down the tool
  axis (within the tip tolerance);
- the tool axis of every row of the run is the hole's (within the orientation tolerance);
- the feed of the run's feed blocks is the cycle's (within :data:`FEED_TOLERANCE`).

The rest of the program is compared with the CL path without its holes; the moves of the
expanded cycles are compared there as rapids are (they leave the path on purpose).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from urdfpost.geometry import angle_between
from urdfpost.tolerances import Tolerances
from urdfpost.toolpath import Toolpath, cycle_holes

HOLES_NOTE = " holes of canned cycles: "
"""What the note of a :class:`HoleCheck` says after the number of holes (the verification's
summary repeats the note)."""

FEED_TOLERANCE = 0.005
"""Relative deviation of a cycle's feed from the CL's: 0.5 %, above the rounding of a feed
written with one decimal (Heidenhain tapping's pitch with four)."""


@dataclass(frozen=True)
class HoleCheck:
    """What :func:`check_holes` found.

    Attributes
    ----------
    holes : int
        CL holes checked.
    bad_lines : list of int
        CL lines of the holes beyond tolerance (or not drilled at all).
    bottom : float, mm
        Largest distance of a hole's deepest point from its CL bottom.
    top : float, mm
        Largest distance of a hole top from the feed into the hole.
    axis_deg : float
        Largest tool-axis angle from a hole's axis.
    feed : float
        Largest relative feed deviation.
    missing : list of int
        CL lines of the holes no rows drill.
    """

    holes: int
    bad_lines: list[int]
    bottom: float
    top: float
    axis_deg: float
    feed: float
    missing: list[int]

    @property
    def ok(self) -> bool:
        return not self.bad_lines

    def note(self, units: str = "mm") -> str:
        """One line for the verification's notes."""
        scale = 25.4 if units == "inch" else 1.0
        text = (
            f"{self.holes}{HOLES_NOTE}largest deviations: bottom {self.bottom / scale:.4f} "
            f"{units}, top from the feed into the hole {self.top / scale:.4f} {units}, tool "
            f"axis {self.axis_deg:.3f} deg, feed {100 * self.feed:.2f} %"
        )
        if self.missing:
            text += f"; not drilled: CL lines {' '.join(map(str, self.missing))}"
        elif self.bad_lines:
            text += f"; beyond tolerance: CL lines {' '.join(map(str, self.bad_lines))}"
        return text


def without_holes(toolpath: Toolpath) -> Toolpath:
    """``toolpath`` without the points of its canned cycles' holes (events re-indexed)."""
    holes = [i for i, _ in cycle_holes(toolpath)]
    if not holes:
        return toolpath
    keep = np.ones(len(toolpath), dtype=bool)
    keep[holes] = False
    before = np.concatenate([[0], np.cumsum(keep)])  # kept points before each index
    return replace(
        toolpath,
        tip=toolpath.tip[keep],
        axis=toolpath.axis[keep],
        feed=toolpath.feed[keep],
        motion=toolpath.motion[keep],
        line=toolpath.line[keep],
        events=tuple(replace(e, index=int(before[e.index])) for e in toolpath.events),
    )


def _segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance of point ``p`` (3,) from the segments ``a`` to ``b`` (k, 3), mm."""
    ab = b - a
    length2 = np.einsum("ij,ij->i", ab, ab)
    t = np.where(length2 > 0, np.einsum("ij,ij->i", p - a, ab) / np.maximum(length2, 1e-300), 0)
    nearest = a + np.clip(t, 0.0, 1.0)[:, None] * ab
    return np.linalg.norm(p - nearest, axis=1)


def check_holes(
    toolpath: Toolpath,
    tip: np.ndarray,
    axis: np.ndarray,
    rapid: np.ndarray,
    feed: np.ndarray,
    cycle: np.ndarray,
    tol: Tolerances,
) -> HoleCheck | None:
    """Check the CL data's holes against the program's expanded cycles.

    Parameters
    ----------
    toolpath : Toolpath
        The CL data (its ``cycle`` events and hole points).
    tip, axis : ndarray, shape (N, 3)
        Tool tip (mm) and axis of the program's rows, workpiece frame.
    rapid : ndarray, shape (N,), bool
        Rapid rows (as written: an expanded cycle's feeds are not rapid).
    feed : ndarray, shape (N,), mm/min
    cycle : ndarray, shape (N,), bool
        Rows of expanded cycles (:func:`urdfpost.program.cycle_moves`).
    tol : Tolerances

    Returns
    -------
    HoleCheck or None
        None when the CL data has no holes.
    """
    holes = cycle_holes(toolpath)
    if not holes:
        return None
    bad: list[int] = []
    missing: list[int] = []
    worst = {"bottom": 0.0, "top": 0.0, "axis": 0.0, "feed": 0.0}
    start = 0
    n = len(tip)
    for index, event in holes:
        line = int(toolpath.line[index])
        p, a = toolpath.tip[index], toolpath.axis[index]
        depth, rate = float(event.data["depth"]), float(event.data["feed"])
        rel = tip[start:] - p
        along = rel @ a
        radial = np.linalg.norm(rel - along[:, None] * a, axis=1)
        near = cycle[start:] & (radial <= tol.tip)
        first = int(np.argmax(near)) if near.any() else -1
        if first < 0:
            missing.append(line)
            bad.append(line)
            continue
        run_end = first
        while run_end < n - start and near[run_end]:
            run_end += 1
        lo, hi = start + first, start + run_end
        start = hi
        bottom = abs(-float(along[first:run_end].min()) - depth)
        feeds = [j for j in range(lo + 1, hi) if not rapid[j]]
        top = (
            float(_segment_distance(p, tip[[j - 1 for j in feeds]], tip[feeds]).min())
            if feeds
            else np.inf
        )
        angle = float(np.max(angle_between(axis[lo:hi], np.broadcast_to(a, (hi - lo, 3)))))
        deviation = (
            float(np.max(np.abs(feed[feeds] - rate))) / rate if feeds and rate > 0 else np.inf
        )
        worst["bottom"] = max(worst["bottom"], bottom)
        worst["top"] = max(worst["top"], top)
        worst["axis"] = max(worst["axis"], float(np.degrees(angle)))
        worst["feed"] = max(worst["feed"], deviation)
        if (
            bottom > tol.tip
            or top > tol.tip
            or angle > tol.orientation
            or not deviation <= FEED_TOLERANCE
        ):
            bad.append(line)
    return HoleCheck(
        holes=len(holes),
        bad_lines=bad,
        bottom=worst["bottom"],
        top=worst["top"],
        axis_deg=worst["axis"],
        feed=worst["feed"],
        missing=missing,
    )
