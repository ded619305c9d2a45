"""The first pass and the refinement of :func:`urdfpost.verification.measure._block_deviation`,
compiled.

Per feed block, in one loop: the forward kinematics at the block's samples (the tool point and
axis carried through the chain's joints, as :func:`urdfpost.kinematics.forward.tip_and_axis_along`
carries them, the cosines and sines by angle addition along the samples), the measured point
(the pivot up the tool axis; in TCP programs the straight line plus the pivot), its deviation
from the block's short CL span (:func:`urdfpost.verification.measure._span_deviation`: the
squared distance from the nearest segment, or with a pivot from the nearest segment's curve,
and the squared chord to the CL orientation in the window), the largest of each and the
sample it is at, and the bounds over the whole block of
:meth:`urdfpost.verification.measure._Blocks.bounds` (with
:func:`urdfpost.kinematics.forward.interpolation_bounds`). Nothing of size samples times
blocks is made but the squared distances the mean is summed from.

The refinement (:func:`refine_deviation`) runs the golden-section searches of
:func:`urdfpost.geometry.refine_max` block by block, each iteration's two points as two
samples of the first pass's code (:func:`deviation_at`), their cosines and sines of the angle
itself as numpy takes them there.

Imported by ``_block_deviation`` when it first runs on enough blocks (numba's import takes a
third of a second); the machine code is cached on disk beside this module (``__pycache__``).
The numpy path stays the definition: the operations are those of the numpy path in the same
order, so the squared distances come out the same bit for bit where the cosines and sines do
(at a pivot, the curve's are the C library's here and numpy's there: the same on x86-64 with
numpy 2.4, within :data:`AGREE` where numpy's vectorised ones differ);
the chords differ by the last bits of ``arctan2`` (numpy's vectorised one is not libm's) and of
the Taylor polynomial of :func:`urdfpost.linearize._turn_chord2` (all its terms here, as many as
the largest turn of a chunk needs there). ``tests/test_verify_kernel.py`` holds the two to
:data:`AGREE` per sample and per refined maximum on generated jobs of several machines.

Blocks compared with more than ``long_span`` CL segments (a program that left the CL path) are
flagged and left to the numpy path, whose search with bounds (``_far_segments``) does not grow
with the span; nor are they handed to the refinement.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from urdfpost.geometry import GOLDEN

AGREE = 1e-12
"""How far a squared distance (mm^2) or squared chord of the kernel may be from the numpy
path's, relative to the larger and absolute (``|a - b| <= AGREE * max(1, |a|, |b|)``)."""

_SMALL_TURN2 = 0.1 * 0.1
"""Squared turns up to which :func:`_turn_chord2` uses its Taylor polynomial
(:data:`urdfpost.linearize._SMALL_TURN` squared)."""


@njit(cache=True, nogil=True, error_model="numpy")
def _turn_chord2(turn: float) -> float:
    """``4 sin^2(turn / 2)``: :func:`urdfpost.linearize._turn_chord2` of one turn (rad), with
    every term of its polynomial."""
    t2 = turn * turn
    if t2 > _SMALL_TURN2:
        s = np.sin(0.5 * turn)
        return 4.0 * (s * s)
    out = 1.0 / 1814400.0
    out = out * t2 + -1.0 / 20160.0
    out = out * t2 + 1.0 / 360.0
    out = out * t2 + -1.0 / 12.0
    out = out * t2 + 1.0
    return out * t2


@njit(cache=True, nogil=True, error_model="numpy")
def _one_minus_rho(z2: float) -> float:
    """``1 - sqrt(1 - z2)``: :func:`urdfpost.linearize._one_minus_rho` of one value."""
    if z2 > 1e-4:
        w = min(z2, 1.0)
        return w / (1.0 + np.sqrt(1.0 - w))
    out = z2 * (7.0 / 256.0)
    out += 5.0 / 128.0
    out *= z2
    out += 1.0 / 16.0
    out *= z2
    out += 1.0 / 8.0
    out *= z2
    out += 0.5
    return out * z2


@njit(cache=True, nogil=True, error_model="numpy")
def _clip(x: float, lo: float, hi: float) -> float:
    """``np.clip``: ``minimum(maximum(x, lo), hi)``."""
    return min(max(x, lo), hi)


@njit(cache=True, nogil=True, error_model="numpy")
def _turn(
    kind: int,
    w0: float,
    w1: float,
    w2: float,
    cos: float,
    sin: float,
    x0: float,
    x1: float,
    x2: float,
) -> tuple[float, float, float]:
    """``x`` turned about the unit direction ``w`` (Rodrigues), as
    :func:`urdfpost.kinematics.forward._turn` turns it: about a coordinate axis (``kind`` 0, 1,
    2: ``w`` is exactly +-1 along it) as a turn in the plane of the other two, else by the whole
    formula (``kind`` -1)."""
    if kind == 0:  # the plane (y, z)
        s = w0 * sin
        return x0, cos * x1 - s * x2, s * x1 + cos * x2
    if kind == 1:  # the plane (z, x)
        s = w1 * sin
        return s * x2 + cos * x0, x1, cos * x2 - s * x0
    if kind == 2:  # the plane (x, y)
        s = w2 * sin
        return cos * x0 - s * x1, s * x0 + cos * x1, x2
    along = w0 * x0 + w1 * x1 + w2 * x2
    e0, e1, e2 = x0 - w0 * along, x1 - w1 * along, x2 - w2 * along
    return (
        (w0 * along + cos * e0) + sin * (w1 * x2 - w2 * x1),
        (w1 * along + cos * e1) + sin * (w2 * x0 - w0 * x2),
        (w2 * along + cos * e2) + sin * (w0 * x1 - w1 * x0),
    )


@njit(cache=True, nogil=True, error_model="numpy")
def _kind(w0: float, w1: float, w2: float) -> int:
    """The coordinate axis a unit direction lies exactly along (0, 1, 2), else -1."""
    if abs(w0) == 1.0 and w1 == 0.0 and w2 == 0.0:
        return 0
    if abs(w1) == 1.0 and w2 == 0.0 and w0 == 0.0:
        return 1
    if abs(w2) == 1.0 and w0 == 0.0 and w1 == 0.0:
        return 2
    return -1


@njit(cache=True, nogil=True, error_model="numpy")
def _first_max(e: np.ndarray, s: int) -> tuple[int, float]:
    """``np.argmax`` of the first ``s`` values of ``e`` (the first maximum; the first NaN if
    any), and the value there."""
    arg, best = 0, e[0]
    if np.isnan(best):
        return 0, best
    for k in range(1, s):
        v = e[k]
        if np.isnan(v):
            return k, v
        if v > best:
            arg, best = k, v
    return arg, best


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _sampled(
    joint_column: np.ndarray,
    joint_rotary: np.ndarray,
    joint_direction: np.ndarray,
    joint_pivot: np.ndarray,
    kinds: np.ndarray,
    linear_columns: np.ndarray,
    tool_point: np.ndarray,
    home_axis: np.ndarray,
    values: np.ndarray,
    r0: int,
    t: np.ndarray,
    s: int,
    cos_j: np.ndarray,
    sin_j: np.ndarray,
    tcp: bool,
    pivot: float,
    qx: np.ndarray,
    qy: np.ndarray,
    qz: np.ndarray,
    vx: np.ndarray,
    vy: np.ndarray,
    vz: np.ndarray,
) -> float:
    """The measured point and the tool axis of the block from program row ``r0`` to the next
    at its first ``s`` parameters ``t`` (:meth:`urdfpost.verification.measure._Blocks.errors`,
    one sample as the others: the kinematics of
    :func:`urdfpost.kinematics.forward.tip_and_axis_along`, then the pivot up the tool axis; in
    TCP programs the straight line plus the pivot).

    Parameters
    ----------
    joint_column, joint_rotary, joint_direction, joint_pivot, linear_columns, tool_point,
    home_axis, values, tcp, pivot
        As :func:`block_deviation`.
    kinds : ndarray, shape (k,), int64
        :func:`_kind` of every joint's direction.
    r0 : int
    t : ndarray, shape (s,) or longer
    s : int
    cos_j, sin_j : ndarray, shape (k, s) or wider
        The cosine and sine of every rotary joint's angle at the samples (rows of linear
        joints not read).

    Returns
    -------
    float
        The length of the polyline of the tool tip through the samples, mm (0 in TCP
        programs: not measured). Written: ``qx, qy, qz`` (mm) and ``vx, vy, vz``, shape (s,)
        or longer, the measured point and unit tool axis at every sample.
    """
    r1 = r0 + 1
    for k in range(s):
        p0, p1, p2 = tool_point[0], tool_point[1], tool_point[2]
        a0, a1, a2 = home_axis[0], home_axis[1], home_axis[2]
        for j in range(joint_column.shape[0]):
            w0, w1, w2 = joint_direction[j, 0], joint_direction[j, 1], joint_direction[j, 2]
            if not joint_rotary[j]:
                if not tcp:
                    c = joint_column[j]
                    value = t[k] * (values[r1, c] - values[r0, c]) + values[r0, c]
                    p0, p1, p2 = p0 + w0 * value, p1 + w1 * value, p2 + w2 * value
                continue
            cos, sin = cos_j[j, k], sin_j[j, k]
            if not tcp:  # the point about the joint's line
                c0, c1, c2 = joint_pivot[j, 0], joint_pivot[j, 1], joint_pivot[j, 2]
                p0, p1, p2 = _turn(kinds[j], w0, w1, w2, cos, sin, p0 - c0, p1 - c1, p2 - c2)
                p0, p1, p2 = p0 + c0, p1 + c1, p2 + c2
            a0, a1, a2 = _turn(kinds[j], w0, w1, w2, cos, sin, a0, a1, a2)
        if tcp:  # the control moves the tip on the straight line
            lx, ly, lz = linear_columns[0], linear_columns[1], linear_columns[2]
            p0 = values[r0, lx] + t[k] * (values[r1, lx] - values[r0, lx]) + pivot * a0
            p1 = values[r0, ly] + t[k] * (values[r1, ly] - values[r0, ly]) + pivot * a1
            p2 = values[r0, lz] + t[k] * (values[r1, lz] - values[r0, lz]) + pivot * a2
        qx[k], qy[k], qz[k] = p0, p1, p2
        vx[k], vy[k], vz[k] = a0, a1, a2
    length = 0.0
    if tcp:
        return length
    for k in range(s - 1):  # the tip's polyline (feeds.tip_lengths), summed in numpy's order
        e0, e1, e2 = qx[k + 1] - qx[k], qy[k + 1] - qy[k], qz[k + 1] - qz[k]
        chord = np.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
        length = length + chord if k else chord
    if pivot != 0.0:  # the measured point
        for k in range(s):
            qx[k], qy[k], qz[k] = (
                qx[k] + pivot * vx[k],
                qy[k] + pivot * vy[k],
                qz[k] + pivot * vz[k],
            )
    return length


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _angles_along(
    joint_rotary: np.ndarray,
    trig: np.ndarray,
    b: int,
    s: int,
    cos_j: np.ndarray,
    sin_j: np.ndarray,
) -> None:
    """The cosine and sine of every rotary joint's angle at the ``s`` samples of block ``b``,
    by angle addition from those at the first sample (as
    :func:`urdfpost.kinematics.forward.cos_sin_along` adds them).

    Parameters
    ----------
    joint_rotary : ndarray, shape (k,), bool
    trig : ndarray, shape (k, 4, n)
        Per rotary joint and block, the cosine and sine of its angle at the first sample and
        of its change from one sample to the next (worked out by numpy).
    b, s : int

    Returns
    -------
    None
        Written: ``cos_j``, ``sin_j``, shape (k, s) or wider (rows of linear joints left).
    """
    for j in range(joint_rotary.shape[0]):
        if joint_rotary[j]:  # angle addition from the cosine and sine at t[0]
            cos_j[j, 0], sin_j[j, 0] = trig[j, 0, b], trig[j, 1, b]
            cd, sd = trig[j, 2, b], trig[j, 3, b]
            for k in range(1, s):
                cos_j[j, k] = cos_j[j, k - 1] * cd - sin_j[j, k - 1] * sd
                sin_j[j, k] = sin_j[j, k - 1] * cd + cos_j[j, k - 1] * sd


_FRAME = 22
"""Numbers per CL segment in the rows of :func:`_frames`."""

_NEWTON = 8
"""Newton steps to the nearest point of a CL segment's curve
(:data:`urdfpost.verification.measure._NEWTON`)."""

_SETTLED = 1e-12
""":data:`urdfpost.verification.measure._SETTLED`."""

_FLAT = 1e-6
""":data:`urdfpost.verification.measure._FLAT`, mm."""


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _frames(
    first: int,
    span: int,
    px: np.ndarray,
    py: np.ndarray,
    pz: np.ndarray,
    ax: np.ndarray,
    ay: np.ndarray,
    az: np.ndarray,
    omega_of: np.ndarray,
    window: float,
    pivot: float,
    frames: np.ndarray,
) -> None:
    """The CL segments ``first .. first + span - 1`` and their arcs as :func:`_span` compares
    samples with them, one row of ``frames`` (shape (span, :data:`_FRAME`) or larger) each:
    the start (mm) and the step to the next CL point (mm), the inverse squared length (0 for a
    point, 1/mm^2), the half window in the segment's parameter (inf for a point; with a pivot,
    of the window grown by the curve's sag, as
    :func:`urdfpost.verification.measure._segment_errors` grows it), the arc's frame (its
    start, the unit direction it turns towards and their cross product,
    :func:`urdfpost.linearize._frame`), its angle (rad), the pivot (mm), the cosine and
    sine of the angle and the curve's sag (mm; the CL segment's curve, :func:`_curve`)."""
    last = px.shape[0] - 1
    for off in range(span):
        a = min(first + off, last)
        nxt = min(a + 1, last)
        sx, sy, sz = px[a], py[a], pz[a]
        dx, dy, dz = px[nxt] - sx, py[nxt] - sy, pz[nxt] - sz
        dd = dx * dx + dy * dy + dz * dz
        inv_dd = 1.0 / dd if dd > 0 else 0.0
        omega = omega_of[a]
        reach = window
        sag = 0.0
        if pivot != 0.0:  # measure._sag
            quarter = np.sin(0.25 * omega)
            sag = 2.0 * abs(pivot) * (quarter * quarter)
            reach = window + sag
        half = reach * np.sqrt(inv_dd) if inv_dd > 0 else np.inf
        # the arc (Arcs.of_coords) and its frame (linearize._frame)
        u0, u1, u2 = ax[a], ay[a], az[a]
        dot = u0 * ax[nxt] + u1 * ay[nxt] + u2 * az[nxt]
        g0, g1, g2 = ax[nxt] - dot * u0, ay[nxt] - dot * u1, az[nxt] - dot * u2
        sine = np.sqrt(g0 * g0 + g1 * g1 + g2 * g2)
        inv = 1.0 / sine if sine > 0 else 0.0
        g0, g1, g2 = g0 * inv, g1 * inv, g2 * inv
        dot = g0 * u0 + g1 * u1 + g2 * u2
        m0, m1, m2 = g0 - dot * u0, g1 - dot * u1, g2 - dot * u2
        length = np.sqrt(m0 * m0 + m1 * m1 + m2 * m2)
        if length < 0.5:  # v0 x the coordinate axis least along it
            least = 0
            if abs(u1) < abs(u0):
                least = 1
            if abs(u2) < (abs(u1) if least == 1 else abs(u0)):
                least = 2
            o0 = 1.0 if least == 0 else 0.0
            o1 = 1.0 if least == 1 else 0.0
            o2 = 1.0 if least == 2 else 0.0
            m0, m1, m2 = u1 * o2 - u2 * o1, u2 * o0 - u0 * o2, u0 * o1 - u1 * o0
            length = np.sqrt(m0 * m0 + m1 * m1 + m2 * m2)
        m0, m1, m2 = m0 / length, m1 / length, m2 / length
        k0, k1, k2 = u1 * m2 - u2 * m1, u2 * m0 - u0 * m2, u0 * m1 - u1 * m0
        f = frames[off]
        f[0], f[1], f[2], f[3], f[4], f[5] = sx, sy, sz, dx, dy, dz
        f[6], f[7], f[8], f[9], f[10] = inv_dd, half, u0, u1, u2
        f[11], f[12], f[13], f[14], f[15], f[16] = m0, m1, m2, k0, k1, k2
        f[17] = omega
        f[18], f[19], f[20], f[21] = pivot, np.cos(omega), np.sin(omega), sag


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _curve(
    w0: float,
    w1: float,
    w2: float,
    u: float,
    f: np.ndarray,
) -> tuple[float, float]:
    """:func:`urdfpost.verification.measure._curve_distance2` of one point: the squared
    distance from the curve of the CL segment of the frame ``f`` (:func:`_frames`) of the
    point ``w`` from the segment's start (mm), from the chord's projection parameter ``u``,
    and the parameter it is measured at; the same operations in the same order."""
    dx, dy, dz = f[3], f[4], f[5]
    v0, v1, v2, n0, n1, n2 = f[8], f[9], f[10], f[11], f[12], f[13]
    omega, pivot, cos_w, sin_w = f[17], f[18], f[19], f[20]
    flat = f[21] <= _FLAT  # the first point of the curve is near enough: no steps
    best, best_u = np.inf, u
    for step in range(_NEWTON + 1):
        angle = u * omega
        cos_a, sin_a = np.cos(angle), np.sin(angle)
        alpha = (cos_a - 1.0) + u * (1.0 - cos_w)
        beta = sin_a - u * sin_w
        ra, rb = pivot * alpha, pivot * beta
        e0 = w0 - u * dx - (ra * v0 + rb * n0)
        e1 = w1 - u * dy - (ra * v1 + rb * n1)
        e2 = w2 - u * dz - (ra * v2 + rb * n2)
        d2 = e0 * e0 + e1 * e1 + e2 * e2
        if step == 0 or d2 < best:
            best, best_u = d2, u
        if step == _NEWTON or flat:
            break
        da = (1.0 - cos_w) - omega * sin_a
        db = omega * cos_a - sin_w
        c0 = dx + pivot * (da * v0 + db * n0)
        c1 = dy + pivot * (da * v1 + db * n1)
        c2 = dz + pivot * (da * v2 + db * n2)
        bend = pivot * (omega * omega)
        b0 = bend * (cos_a * v0 + sin_a * n0)
        b1 = bend * (cos_a * v1 + sin_a * n1)
        b2 = bend * (cos_a * v2 + sin_a * n2)
        grad = e0 * c0 + e1 * c1 + e2 * c2
        speed2 = c0 * c0 + c1 * c1 + c2 * c2
        curv = speed2 + (e0 * b0 + e1 * b1 + e2 * b2)
        den = curv if curv > 0.0 else speed2
        move = grad / den if den > 0.0 else 0.0
        if not abs(move) > _SETTLED:  # settled: the steps left would repeat this one
            break
        nxt = _clip(u + move, 0.0, 1.0)
        if nxt == u:
            break
        u = nxt
    return best, best_u


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _span(
    qx: np.ndarray,
    qy: np.ndarray,
    qz: np.ndarray,
    vx: np.ndarray,
    vy: np.ndarray,
    vz: np.ndarray,
    s: int,
    span: int,
    frames: np.ndarray,
    window: float,
    dist2: np.ndarray,
    chord2: np.ndarray,
    within: np.ndarray,
    outside0: np.ndarray,
    at0: np.ndarray,
    par0: np.ndarray,
) -> None:
    """:func:`urdfpost.verification.measure._span_deviation` of the first ``s`` points ``q``
    (mm) and unit axes ``v`` against the ``span`` CL segments of ``frames`` (:func:`_frames`).

    Writes the squared distance from the nearest segment (the first of equals) into
    ``dist2``, the squared chord to the CL orientation in the window (that of the nearest
    segment where no segment is within the window) into ``chord2``, and, of the first
    segment, how far the projection parameter falls outside [0, 1] and the chord at it into
    ``outside0`` and ``at0``, and with a pivot, the parameter on its curve the distance is
    measured at into ``par0`` (``within``: scratch); all shape (s,) or longer.
    """
    window2 = window * window
    for off in range(span):
        f = frames[off]
        sx, sy, sz, dx, dy, dz = f[0], f[1], f[2], f[3], f[4], f[5]
        inv_dd, half, u0, u1, u2 = f[6], f[7], f[8], f[9], f[10]
        m0, m1, m2, k0, k1, k2 = f[11], f[12], f[13], f[14], f[15], f[16]
        omega = f[17]
        for k in range(s):
            w0, w1, w2 = qx[k] - sx, qy[k] - sy, qz[k] - sz
            raw = w0 * dx + w1 * dy
            raw = (raw + w2 * dz) * inv_dd
            par = _clip(raw, 0.0, 1.0)
            out = abs(raw - par)
            e0, e1, e2 = w0 - par * dx, w1 - par * dy, w2 - par * dz
            d2 = e0 * e0 + e1 * e1 + e2 * e2
            if f[18] != 0.0:  # with a pivot: from the curve
                d2, on = _curve(w0, w1, w2, par, f)
                if off == 0:
                    par0[k] = on
            u = 1.0 + out if par >= 1.0 else par - out  # not clipped
            # orientation_path_chord2
            x = vx[k] * u0 + vy[k] * u1 + vz[k] * u2
            y = vx[k] * m0 + vy[k] * m1 + vz[k] * m2
            z = vx[k] * k0 + vy[k] * k1 + vz[k] * k2
            base = z * z
            gap = _one_minus_rho(base)
            rho = 1.0 - gap
            base = base + gap * gap
            nearest = np.arctan2(y, x)
            at = _turn_chord2(_clip(u, 0.0, 1.0) * omega - nearest) * rho + base
            lo = _clip(u - half, 0.0, 1.0) * omega
            hi = _clip(u + half, 0.0, 1.0) * omega
            if nearest < (lo + hi) * 0.5 - np.pi:
                nearest = nearest + 2.0 * np.pi
            turn = _clip(nearest, lo, hi) - nearest
            # in the window: the chord across the arc's plane (0 turns to 0, bit for bit)
            path = base if turn == 0.0 else _turn_chord2(turn) * rho + base
            c2 = min(path, at)
            near = c2 if d2 <= window2 else np.inf
            if off == 0:
                dist2[k], chord2[k], within[k] = d2, c2, near
                outside0[k], at0[k] = out, at
            else:
                if d2 < dist2[k]:
                    dist2[k], chord2[k] = d2, c2
                within[k] = min(within[k], near)
    for k in range(s):
        if np.isfinite(within[k]):
            chord2[k] = within[k]


@njit(cache=True, nogil=True, error_model="numpy")
def block_deviation(
    joint_column: np.ndarray,
    joint_rotary: np.ndarray,
    joint_direction: np.ndarray,
    joint_pivot: np.ndarray,
    rotary_index: np.ndarray,
    linear_columns: np.ndarray,
    tool_point: np.ndarray,
    home_axis: np.ndarray,
    values: np.ndarray,
    reach: np.ndarray,
    swing: np.ndarray,
    start: np.ndarray,
    ja: np.ndarray,
    jb: np.ndarray,
    valid: np.ndarray,
    px: np.ndarray,
    py: np.ndarray,
    pz: np.ndarray,
    ax: np.ndarray,
    ay: np.ndarray,
    az: np.ndarray,
    omega_of: np.ndarray,
    trig: np.ndarray,
    t: np.ndarray,
    tcp: bool,
    pivot: float,
    window: float,
    long_span: int,
    dist2: np.ndarray,
    best: np.ndarray,
    worst: np.ndarray,
    bound: np.ndarray,
    long: np.ndarray,
    length: np.ndarray,
) -> None:
    """Sample every block, compare it with its CL span, bound it (the first pass of
    ``_block_deviation`` for one comparison and one chunk of blocks).

    Parameters
    ----------
    joint_column, joint_rotary : ndarray, shape (k,), int64 and bool
        The chain's joints from the tool back (:attr:`urdfpost.kinematics.forward.PoeChain.joints`):
        column in ``values``, rotary or linear.
    joint_direction, joint_pivot : ndarray, shape (k, 3)
        Unit direction; a rotary joint's point of its line (mm; zeros for a linear joint).
    rotary_index : ndarray, shape (k,), int64
        Column of a rotary joint in ``reach`` and ``swing`` (-1 for a linear joint).
    linear_columns : ndarray, shape (3,), int64
        Columns of X, Y, Z (the tip of a TCP program).
    tool_point, home_axis : ndarray, shape (3,)
        Tool tip (mm) and axis at home.
    values : ndarray, shape (N, m)
        Program rows, mm / rad.
    reach, swing : ndarray, shape (N, r)
        At the rows, at the pivot (:class:`urdfpost.linearize.RowPoses`).
    start, ja, jb : ndarray, shape (n,), int64
        First row and CL span of each block.
    valid : ndarray, shape (n,), bool
        The blocks compared.
    px, py, pz, ax, ay, az : ndarray, shape (n_cl,)
        CL points at the pivot (mm) and CL tool axes.
    omega_of : ndarray, shape (n_cl,), rad
        Angle of the CL arc from each point to the next (:class:`urdfpost.geometry.Arcs`,
        worked out by numpy: its ``arctan2``).
    trig : ndarray, shape (k, 4, n)
        Per rotary joint and block, the cosine and sine of its angle at ``t[0]`` and of its
        change from one sample to the next (worked out by numpy, as
        :func:`urdfpost.kinematics.forward.cos_sin_along` works them out).
    t : ndarray, shape (s,)
        Evenly spaced sample parameters, ends included.
    tcp : bool
    pivot, window : float, mm
        The measured point's height up the tool axis (and that of the CL points, whose
        segments are then curves, :func:`_curve`); the window of the axis comparison.
    long_span : int
        Blocks compared with more CL segments than this are flagged in ``long`` and not
        measured.

    Returns
    -------
    None
        Written: ``dist2`` (s, n), squared tip distance of every sample (0 where not
        compared; mm^2); ``best`` (2, n), the largest squared distance and chord;
        ``worst`` (2, n), int64, the samples they are at; ``bound`` (2, n), the bounds on the
        tip deviation (mm) and axis chord (-inf where not compared, inf over more than one
        CL segment); ``long`` (n,), bool; ``length`` (n,), mm, the length of the polyline of
        the tool tip through the samples of every block, compared or not
        (:func:`urdfpost.verification.feeds.tip_lengths`; 0 in TCP programs).
    """
    n, s = start.shape[0], t.shape[0]
    n_joints = joint_column.shape[0]
    h = float(t[1] - t[0])
    kinds = np.empty(n_joints, dtype=np.int64)
    for j in range(n_joints):
        kinds[j] = _kind(joint_direction[j, 0], joint_direction[j, 1], joint_direction[j, 2])
    room = h * h / 8.0
    cos_j = np.empty((n_joints, s))
    sin_j = np.empty((n_joints, s))
    qx, qy, qz = np.empty(s), np.empty(s), np.empty(s)  # measured point
    vx, vy, vz = np.empty(s), np.empty(s), np.empty(s)  # tool axis
    chord2, d2s = np.empty(s), np.empty(s)
    within = np.empty(s)
    outside0 = np.empty(s)
    at0 = np.empty(s)
    par0 = np.empty(s)
    reach_j, swing_j = np.empty(n_joints), np.empty(n_joints)
    frames = np.empty((max(long_span, 1), _FRAME))
    for b in range(n):
        span = max(jb[b] - ja[b], 1)
        long[b] = valid[b] and span > long_span
        length[b] = 0.0
        if not valid[b]:
            for k in range(s):
                dist2[k, b] = 0.0
            best[0, b] = best[1, b] = 0.0
            worst[0, b] = worst[1, b] = 0
            bound[0, b] = bound[1, b] = -np.inf
        if tcp and (long[b] or not valid[b]):
            continue  # (no tip path wanted: the control moves the tip on the chord)
        r0, r1 = start[b], start[b] + 1
        # -- the kinematics along the block (tip_and_axis_along) --
        _angles_along(joint_rotary, trig, b, s, cos_j, sin_j)
        length[b] = _sampled(
            joint_column,
            joint_rotary,
            joint_direction,
            joint_pivot,
            kinds,
            linear_columns,
            tool_point,
            home_axis,
            values,
            r0,
            t,
            s,
            cos_j,
            sin_j,
            tcp,
            pivot,
            qx,
            qy,
            qz,
            vx,
            vy,
            vz,
        )
        if not valid[b] or long[b]:
            continue
        # -- the deviation from the CL span (_span_deviation, _segment_errors) --
        _frames(ja[b], span, px, py, pz, ax, ay, az, omega_of, window, pivot, frames)
        _span(
            qx, qy, qz, vx, vy, vz, s, span, frames, window, d2s, chord2, within, outside0, at0,
            par0,
        )  # fmt: skip
        inv_dd0, omega0 = frames[0, 6], frames[0, 17]
        for k in range(s):
            dist2[k, b] = d2s[k]
        worst[0, b], best[0, b] = _first_max(d2s, s)
        worst[1, b], best[1, b] = _first_max(chord2, s)
        if jb[b] - ja[b] > 1:
            bound[0, b] = bound[1, b] = np.inf
            continue
        # -- the bounds (interpolation_bounds, _Blocks.bounds) --
        tip_speed = axis_speed = 0.0
        for j in range(n_joints):  # from the tool back
            c = joint_column[j]
            d = abs(values[r1, c] - values[r0, c])
            if joint_rotary[j]:
                i = rotary_index[j]
                reach_j[j] = max(reach[r0, i], reach[r1, i]) + 0.5 * tip_speed
                swing_j[j] = min(1.0, max(swing[r0, i], swing[r1, i]) + 0.5 * axis_speed)
                axis_speed = axis_speed + d * swing_j[j]
            else:
                reach_j[j] = 1.0
            tip_speed = tip_speed + d * reach_j[j]
        tip_curv = axis_curv = turning = 0.0
        for j in range(n_joints - 1, -1, -1):  # from the workpiece
            c = joint_column[j]
            d = abs(values[r1, c] - values[r0, c])
            own = d if joint_rotary[j] else 0.0
            factor = d * (own + 2.0 * turning)
            tip_curv = tip_curv + factor * reach_j[j]
            if joint_rotary[j]:
                axis_curv = axis_curv + factor * swing_j[j]
                turning = turning + d
        if tcp:
            lx, ly, lz = linear_columns[0], linear_columns[1], linear_columns[2]
            cx = values[r1, lx] - values[r0, lx]
            cy = values[r1, ly] - values[r0, ly]
            cz = values[r1, lz] - values[r0, lz]
            tip_speed = np.sqrt(cx * cx + cy * cy + cz * cz) + abs(pivot) * axis_speed
            tip_curv = abs(pivot) * axis_curv
        inv_length = np.sqrt(inv_dd0)
        spin = omega0 * tip_speed * inv_length
        bound[0, b] = np.sqrt(best[0, b]) + tip_curv * room
        if pivot != 0.0:  # the curve's bend between the parameters measured to
            du2 = 0.0
            for k in range(1, s):
                du = par0[k] - par0[k - 1]
                du2 = max(du2, du * du)
            bound[0, b] = bound[0, b] + abs(pivot) * (omega0 * omega0) * du2 / 8.0
        pair = g_max = out_max = -np.inf
        g_prev = 0.0
        for k in range(s):
            g = np.sqrt(at0[k])
            if k:
                pair = max(pair, g + g_prev)
            g_prev = g
            g_max = max(g_max, g)
            out_max = max(out_max, outside0[k])
        first_order = 0.5 * pair + (axis_speed + spin) * (h / 2.0)
        curv = axis_curv + spin * spin + 2.0 * omega0 * tip_curv * inv_length
        second = g_max + 2.0 * omega0 * out_max + curv * room
        moves = axis_speed * (h / 2.0) + min(spin * (h / 2.0), omega0)
        third = np.sqrt(best[1, b]) + moves
        bound[1, b] = min(min(first_order, second), third)


@njit(cache=True, nogil=True, error_model="numpy")
def point_deviation(
    tx: np.ndarray,
    ty: np.ndarray,
    tz: np.ndarray,
    vx: np.ndarray,
    vy: np.ndarray,
    vz: np.ndarray,
    ja: np.ndarray,
    jb: np.ndarray,
    px: np.ndarray,
    py: np.ndarray,
    pz: np.ndarray,
    ax: np.ndarray,
    ay: np.ndarray,
    az: np.ndarray,
    omega_of: np.ndarray,
    pivot: float,
    window: float,
    long_span: int,
    dist2: np.ndarray,
    chord2: np.ndarray,
    long: np.ndarray,
) -> None:
    """:func:`urdfpost.verification.measure._span_deviation` of single points (the program's
    rows) against their CL spans.

    Parameters
    ----------
    tx, ty, tz, vx, vy, vz : ndarray, shape (N,)
        The points (mm) and their unit tool axes.
    ja, jb : ndarray, shape (N,), int64
        CL span of each.
    px, py, pz, ax, ay, az, omega_of, pivot, window, long_span
        As :func:`block_deviation` (the points are at the pivot).

    Returns
    -------
    None
        Written: ``dist2`` and ``chord2`` (N,), mm^2 and squared chord; ``long`` (N,), bool,
        the points of spans longer than ``long_span`` (not measured).
    """
    d2, c2, within, outside, at, par = (
        np.empty(1),
        np.empty(1),
        np.empty(1),
        np.empty(1),
        np.empty(1),
        np.empty(1),
    )
    frames = np.empty((max(long_span, 1), _FRAME))
    for r in range(tx.shape[0]):
        span = max(jb[r] - ja[r], 1)
        long[r] = span > long_span
        if long[r]:
            continue
        _frames(ja[r], span, px, py, pz, ax, ay, az, omega_of, window, pivot, frames)
        _span(
            tx[r : r + 1], ty[r : r + 1], tz[r : r + 1], vx[r : r + 1], vy[r : r + 1],
            vz[r : r + 1], 1, span, frames, window, d2, c2, within, outside, at, par,
        )  # fmt: skip
        dist2[r], chord2[r] = d2[0], c2[0]


@njit(cache=True, nogil=True, error_model="numpy")
def _maximum(x: float, y: float) -> float:
    """``np.maximum`` of two values: the larger, NaN if either is."""
    return x if x >= y or np.isnan(x) else y


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def deviation_at(
    joint_column: np.ndarray,
    joint_rotary: np.ndarray,
    joint_direction: np.ndarray,
    joint_pivot: np.ndarray,
    kinds: np.ndarray,
    linear_columns: np.ndarray,
    tool_point: np.ndarray,
    home_axis: np.ndarray,
    values: np.ndarray,
    r0: int,
    span: int,
    frames: np.ndarray,
    tcp: bool,
    pivot: float,
    window: float,
    u: np.ndarray,
    s: int,
    dist2: np.ndarray,
    chord2: np.ndarray,
    work: np.ndarray,
    trig: np.ndarray,
) -> None:
    """The squared distance and chord of one block at the parameters ``u`` against its CL
    span (:meth:`urdfpost.verification.measure._Blocks.errors` of one block at parameters of
    its own): the first pass's samples of :func:`block_deviation`, with the cosines and sines
    of the angles themselves (as :func:`urdfpost.kinematics.forward.tip_and_axis_along` takes
    them at parameters that are not one evenly spaced set).

    Parameters
    ----------
    joint_column, joint_rotary, joint_direction, joint_pivot, kinds, linear_columns,
    tool_point, home_axis, values, r0, tcp, pivot
        As :func:`_sampled`.
    span : int
        How many CL segments the block's span has.
    frames : ndarray, shape (span, _FRAME) or larger
        :func:`_frames` of them.
    window : float, mm
    u : ndarray, shape (s,) or longer
        The parameters, in [0, 1].
    s : int
    work : ndarray, shape (10, s) or wider
        Scratch.
    trig : ndarray, shape (2, k, s) or wider
        Scratch for the cosines and sines.

    Returns
    -------
    None
        Written: ``dist2`` (mm^2) and ``chord2``, shape (s,) or longer.
    """
    r1 = r0 + 1
    cos_j, sin_j = trig[0], trig[1]
    for j in range(joint_column.shape[0]):
        if joint_rotary[j]:
            c = joint_column[j]
            for k in range(s):  # q0 + t dq, as numpy sums the two terms
                angle = u[k] * (values[r1, c] - values[r0, c]) + values[r0, c]
                cos_j[j, k], sin_j[j, k] = np.cos(angle), np.sin(angle)
    _sampled(
        joint_column, joint_rotary, joint_direction, joint_pivot, kinds, linear_columns,
        tool_point, home_axis, values, r0, u, s, cos_j, sin_j, tcp, pivot, work[0], work[1],
        work[2], work[3], work[4], work[5],
    )  # fmt: skip
    _span(
        work[0], work[1], work[2], work[3], work[4], work[5], s, span, frames, window, dist2,
        chord2, work[6], work[7], work[8], work[9],
    )  # fmt: skip


@njit(cache=True, nogil=True, error_model="numpy")
def refine_deviation(
    joint_column: np.ndarray,
    joint_rotary: np.ndarray,
    joint_direction: np.ndarray,
    joint_pivot: np.ndarray,
    linear_columns: np.ndarray,
    tool_point: np.ndarray,
    home_axis: np.ndarray,
    values: np.ndarray,
    start: np.ndarray,
    ja: np.ndarray,
    jb: np.ndarray,
    px: np.ndarray,
    py: np.ndarray,
    pz: np.ndarray,
    ax: np.ndarray,
    ay: np.ndarray,
    az: np.ndarray,
    omega_of: np.ndarray,
    t: np.ndarray,
    tcp: bool,
    pivot: float,
    window: float,
    iterations: int,
    worst: np.ndarray,
    wanted: np.ndarray,
    best: np.ndarray,
) -> None:
    """The refinement of the first pass's maxima (the squared distance and the squared chord)
    of blocks: :func:`urdfpost.geometry.refine_max` of every block, both golden-section
    searches of a block in one loop, the two points of each iteration evaluated together by
    :func:`deviation_at` against the block's CL segments, worked out once (:func:`_frames`).

    A block's searches do not depend on other blocks, so the brackets, the points evaluated
    and the maxima are those of ``refine_max`` given the same evaluations.

    Parameters
    ----------
    joint_column, joint_rotary, joint_direction, joint_pivot, linear_columns, tool_point,
    home_axis, values
        As :func:`block_deviation`.
    start, ja, jb : ndarray, shape (n,), int64
        First row and CL span of each block refined.
    px, py, pz, ax, ay, az, omega_of, tcp, pivot, window
        As :func:`block_deviation`.
    t : ndarray, shape (s,)
        The first pass's sample parameters, evenly spaced.
    iterations : int
        Golden-section iterations.
    worst : ndarray, shape (2, n), int64
        The sample of each block's largest squared distance and chord.
    wanted : ndarray, shape (2, n), bool
        The blocks whose largest squared distance, and squared chord, are refined.
    best : ndarray, shape (2, n)
        The largest squared distance (mm^2) and chord sampled; updated in place to the
        largest seen.

    Returns
    -------
    None
    """
    n_joints = joint_column.shape[0]
    kinds = np.empty(n_joints, dtype=np.int64)
    for j in range(n_joints):
        kinds[j] = _kind(joint_direction[j, 0], joint_direction[j, 1], joint_direction[j, 2])
    h = t[1] - t[0] if t.shape[0] > 1 else 0.5
    u, work, trig = np.empty(2), np.empty((10, 2)), np.empty((2, n_joints, 2))
    dist2, chord2 = np.empty(2), np.empty(2)
    most = 1
    for b in range(start.shape[0]):
        most = max(most, jb[b] - ja[b])
    frames = np.empty((most, _FRAME))
    for b in range(start.shape[0]):
        span = max(jb[b] - ja[b], 1)
        if wanted[0, b] or wanted[1, b]:
            _frames(ja[b], span, px, py, pz, ax, ay, az, omega_of, window, pivot, frames)
        for i in range(2):
            if not wanted[i, b]:
                continue
            value = dist2 if i == 0 else chord2
            lo = _clip(t[worst[i, b]] - h, 0.0, 1.0)
            hi = _clip(t[worst[i, b]] + h, 0.0, 1.0)
            top = best[i, b]
            for _ in range(iterations):  # both points of an iteration as two samples
                u[0] = hi - GOLDEN * (hi - lo)
                u[1] = lo + GOLDEN * (hi - lo)
                deviation_at(
                    joint_column, joint_rotary, joint_direction, joint_pivot, kinds,
                    linear_columns, tool_point, home_axis, values, start[b], span, frames, tcp,
                    pivot, window, u, 2, dist2, chord2, work, trig,
                )  # fmt: skip
                top = _maximum(top, _maximum(value[0], value[1]))
                if value[0] > value[1]:  # on [lo, u[1]] from here
                    hi = u[1]
                else:
                    lo = u[0]
            best[i, b] = top
