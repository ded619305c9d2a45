"""Geometry used while reading CL data: coordinate frames (NX ``MSYS``) and arc interpolation."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

Vec3 = tuple[float, float, float]


@dataclass(frozen=True)
class Frame:
    """A rigid frame in which CL points are written, expressed in the workpiece frame.

    A point ``p`` and a vector ``a`` given in the frame are, in the workpiece frame,
    ``origin + R @ p`` and ``R @ a`` where the columns of ``R`` are the frame's X, Y, Z axes.

    Attributes
    ----------
    origin : tuple of 3 floats, mm
    rotation : tuple of 3 tuples of 3 floats
        Rows of ``R`` (so ``rotation[r][c]``), orthonormal and right-handed.
    """

    origin: Vec3 = (0.0, 0.0, 0.0)
    rotation: tuple[Vec3, Vec3, Vec3] = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))

    def point(self, p: Sequence[float]) -> Vec3:
        """Workpiece coordinates (mm) of a point given in this frame (mm)."""
        x, y, z = p
        (a, b, c), (d, e, f), (g, h, i) = self.rotation
        ox, oy, oz = self.origin
        return (ox + a * x + b * y + c * z, oy + d * x + e * y + f * z, oz + g * x + h * y + i * z)

    def vector(self, v: Sequence[float]) -> Vec3:
        """Workpiece components of a direction given in this frame."""
        x, y, z = v
        (a, b, c), (d, e, f), (g, h, i) = self.rotation
        return (a * x + b * y + c * z, d * x + e * y + f * z, g * x + h * y + i * z)

    def in_frame(self, other: Frame) -> Frame:
        """This frame expressed in ``other``: ``other^-1 * self``.

        A point ``p`` given in this frame is ``R_o.T @ (o_s - o_o) + R_o.T @ R_s @ p`` in
        ``other`` (``o``, ``R``: origin and rotation of this frame ``s`` and of ``other``).
        """
        r_other = np.asarray(other.rotation)
        rotation = r_other.T @ np.asarray(self.rotation)
        origin = r_other.T @ (np.asarray(self.origin) - np.asarray(other.origin))
        (a, b, c), (d, e, f), (g, h, i) = rotation.tolist()
        ox, oy, oz = origin.tolist()
        return Frame(origin=(ox, oy, oz), rotation=((a, b, c), (d, e, f), (g, h, i)))

    def near(self, other: Frame, relative: float = 1e-9) -> bool:
        """Whether two frames are the same within ``relative``: the origins within ``relative``
        times the larger of their distances from zero and 1 mm, the rotations' entries within
        ``relative``."""
        o1, o2 = np.asarray(self.origin), np.asarray(other.origin)
        size = max(1.0, float(np.abs(o1).max()), float(np.abs(o2).max()))
        turn = np.abs(np.asarray(self.rotation) - np.asarray(other.rotation)).max()
        return bool(np.abs(o1 - o2).max() <= relative * size and turn <= relative)

    @classmethod
    def from_axes(
        cls, origin: Sequence[float], x_axis: Sequence[float], y_axis: Sequence[float]
    ) -> Frame:
        """Frame from its origin (mm) and X and Y axis directions, orthonormalised.

        X is normalised, Y is made orthogonal to X (Gram-Schmidt) and normalised, Z = X x Y.

        Raises
        ------
        ValueError
            When an axis has zero length or the two are parallel.
        """
        x = np.asarray(x_axis, dtype=float)
        y = np.asarray(y_axis, dtype=float)
        with np.errstate(over="ignore", invalid="ignore"):  # a huge axis: an inf norm, refused
            nx = float(np.linalg.norm(x))
            if not np.isfinite(nx) or nx < 1e-9:
                raise ValueError("X axis of zero length")
            x = x / nx
            y = y - (y @ x) * x
            ny = float(np.linalg.norm(y))
        if not np.isfinite(ny) or ny < 1e-9:
            raise ValueError("Y axis of zero length or parallel to the X axis")
        y = y / ny
        z = np.cross(x, y)
        rotation = np.column_stack([x, y, z])
        (a, b, c), (d, e, f), (g, h, i) = rotation.tolist()
        ox, oy, oz = (float(v) for v in origin)
        return cls(origin=(ox, oy, oz), rotation=((a, b, c), (d, e, f), (g, h, i)))


IDENTITY = Frame()


@dataclass(frozen=True)
class Arc:
    """Points interpolated on a circular (or helical) arc.

    Attributes
    ----------
    points : ndarray, shape (k, 3), mm
        Points after the start, the last one exactly the end point.
    sweep : float, rad
        Angle turned about the rotation axis (positive).
    radius_error : float, mm
        Largest difference between the programmed radius and the distance of the start or end
        point from the circle axis.
    start_tangent : ndarray, shape (3,)
        Unit direction of motion at the start, in the plane of the circle.
    end_tangent : ndarray, shape (3,)
        Unit direction of motion at the end, in the plane of the circle.
    """

    points: np.ndarray
    sweep: float
    radius_error: float
    start_tangent: np.ndarray
    end_tangent: np.ndarray


def max_arc_step(radius: float, chord_tolerance: float) -> float:
    """Largest angle step (rad) whose chord stays within ``chord_tolerance`` of the circle.

    The sagitta of a chord spanning ``dtheta`` is ``radius * (1 - cos(dtheta / 2))``. The step
    is capped at a quarter turn so that even coarse tolerances keep the shape of the arc.
    """
    if chord_tolerance >= radius:
        return math.pi / 2
    # 1 - cos(d / 2) = 2 sin(d / 4)^2: stable when the tolerance is tiny against the radius
    return min(4.0 * math.asin(math.sqrt(0.5 * chord_tolerance / radius)), math.pi / 2)


class ArcTooFineError(ValueError):
    """An arc would need more than :data:`MAX_ARC_POINTS` points."""


#: Most points one arc may be interpolated into; more means a radius no machine can cut.
MAX_ARC_POINTS = 10_000_000


def interpolate_arc(
    start: Sequence[float],
    end: Sequence[float],
    centre: Sequence[float],
    rotation_axis: Sequence[float],
    radius: float,
    *,
    turns: int = 1,
    chord_tolerance: float,
) -> Arc:
    """Interpolate an arc (or helix) from ``start`` to ``end`` within a chord tolerance.

    The motion turns by the right-hand rule about ``rotation_axis`` (counter-clockwise seen
    from its tip). The distance from the circle axis and the position along it vary linearly
    with the angle from the start point to the end point, so the arc always passes through both
    even when they are not exactly on the programmed circle (rounded data) or are at different
    heights (helix).

    Parameters
    ----------
    start, end : sequence of 3 floats, mm
        Start (the previous point) and end (the point of the GOTO after the CIRCLE).
    centre : sequence of 3 floats, mm
        A point of the circle axis.
    rotation_axis : sequence of 3 floats
        Unit vector; the motion is counter-clockwise seen from its tip.
    radius : float, mm
        Programmed radius (used for the step size and the radius error).
    turns : int
        APT ``TIMES``: the arc ends at its ``turns``-th arrival at the end angle, i.e. the
        sweep is the partial angle plus ``turns - 1`` full turns. Start == end (seen along the
        axis) is a full turn.
    chord_tolerance : float, mm
        Largest allowed distance between a chord and the arc.

    Returns
    -------
    Arc

    Raises
    ------
    ValueError
        When the start or end point lies on the circle axis.
    """
    c = np.asarray(centre, dtype=float)
    m = np.asarray(rotation_axis, dtype=float)
    s_rel = np.asarray(start, dtype=float) - c
    e_rel = np.asarray(end, dtype=float) - c
    h_s, h_e = float(s_rel @ m), float(e_rel @ m)
    u_s, u_e = s_rel - h_s * m, e_rel - h_e * m
    r_s, r_e = float(np.linalg.norm(u_s)), float(np.linalg.norm(u_e))
    tiny = 1e-9 * max(1.0, radius)
    if r_s < tiny or r_e < tiny:
        raise ValueError("start or end point on the circle axis")
    e1 = u_s / r_s
    e2 = np.cross(m, e1)
    if float(np.linalg.norm(u_e - u_s)) <= tiny:
        partial = 2.0 * math.pi
    else:
        partial = math.atan2(float(u_e @ e2), float(u_e @ e1)) % (2.0 * math.pi)
        if partial == 0.0:  # rounding of an end point a hair before the start
            partial = 2.0 * math.pi
    sweep = partial + 2.0 * math.pi * (turns - 1)
    step = max_arc_step(max(radius, r_s, r_e), chord_tolerance)
    pieces = sweep / step if step > 0 else math.inf
    if not pieces <= MAX_ARC_POINTS:
        raise ArcTooFineError(
            f"expected an arc a machine can cut, got radius {max(radius, r_s, r_e):.6g} mm, "
            f"which needs more than {MAX_ARC_POINTS} points at chord tolerance "
            f"{chord_tolerance:g} mm"
        )
    count = max(1, math.ceil(pieces - 1e-12))
    t = np.arange(1, count + 1, dtype=float) / count
    theta = sweep * t
    rho = r_s + (r_e - r_s) * t
    height = h_s + (h_e - h_s) * t
    points = (
        c
        + (rho * np.cos(theta))[:, None] * e1
        + (rho * np.sin(theta))[:, None] * e2
        + height[:, None] * m
    )
    points[-1] = np.asarray(end, dtype=float)
    return Arc(
        points=points,
        sweep=sweep,
        radius_error=max(abs(r_s - radius), abs(r_e - radius)),
        start_tangent=e2,
        end_tangent=np.cross(m, u_e / r_e),
    )
