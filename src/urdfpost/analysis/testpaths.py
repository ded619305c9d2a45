"""Shipped singular test paths: generators used by the tests, the docs and the benchmarks.

Every generator returns a :class:`~urdfpost.toolpath.Toolpath` in millimetres in the workpiece
frame (tip = CL point, axis = unit tool axis from the tip toward the spindle), laid out the way
an APT file would carry it and numbered by the lines :func:`to_apt` writes for it: a part name,
a ball-end cutter (corner radius = diameter / 2), tool 1, and per pass a rapid to a clearance
point above the first CL point, a feed plunge onto it, the feed moves of the pass and a rapid
retract along the last tool axis. Each pass is therefore its own feed run.

The paths and their closed-form facts (``../shared/docs/singularity-research.md`` section 7):

- :func:`hemisphere_raster`: passes across a hemisphere at offsets ``y0`` from its apex with the
  tool normal to the surface. The tool axis comes within ``arcsin(y0 / R)`` of vertical, and
  without repair the first rotary axis (C) of a machine whose pole is vertical turns at up to
  ``F / y0`` rad/s (F in mm/s) at the apex.
- :func:`great_circle_sweep`: the tool axis sweeps a great circle that passes the pole at a
  chosen angular distance (0: through it).
- :func:`nutating_edge`: the tilt from vertical runs up to the edge of a 45-degree nutating
  table's reach (90 degrees on ``dmu50-nutating``) and back.
- :func:`micro_pole`: five CL points micrometres apart, coordinates rounded to 0.001 mm, the
  tool axis passing within a fraction of a degree of vertical (the pole of a C table) and
  turning by degrees between them: a stand-in for the seed paper's Table 1, whose rows we do
  not have.

:data:`PATHS` names the shipped variants.

Examples
--------
>>> from urdfpost.analysis.testpaths import PATHS, to_apt
>>> tp = PATHS["sweep-1"]()
>>> len(tp), tp.source
(43, '<great-circle sweep 1 deg>')
>>> to_apt(tp).splitlines()[0]
'PARTNO GREAT-CIRCLE SWEEP 1 DEG'
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Sequence
from dataclasses import replace

import numpy as np
from numpy.typing import ArrayLike

from urdfpost.toolpath import Event, Motion, Toolpath

log = logging.getLogger(__name__)

__all__ = [
    "PATHS",
    "great_circle_sweep",
    "hemisphere_raster",
    "micro_pole",
    "nutating_edge",
    "to_apt",
]

#: Ball-end cutter of every shipped path, mm.
CUTTER_DIAMETER = 6.0
#: Distance of the approach and retract points from the path along the tool axis, mm.
CLEARANCE = 10.0
#: Spindle speed of every shipped path (clockwise), rpm.
SPINDLE_RPM = 12000.0
_DIGITS = 10  # significant digits written to APT: round trip to ~1e-9 relative


def _assemble(
    passes: Sequence[tuple[np.ndarray, np.ndarray, str]],
    *,
    name: str,
    feed: float,
    clearance: float = CLEARANCE,
    cutter_diameter: float = CUTTER_DIAMETER,
) -> Toolpath:
    """A toolpath of feed passes joined by rapid retracts and approaches.

    Parameters
    ----------
    passes : sequence of (tip, axis, comment)
        ``tip`` and ``axis`` of shape (k, 3) (mm, unit), and a comment written before the pass.
    name : str
        Part name; the source is ``"<name>"``.
    feed : float, mm/min
        Feed of the plunge and of the pass.
    clearance : float, mm
        Approach and retract distance along the tool axis.
    cutter_diameter : float, mm
        Ball-end cutter diameter (corner radius half of it).

    Returns
    -------
    Toolpath
        Lines numbered as :func:`to_apt` writes them.
    """
    tips: list[ArrayLike] = []
    axes: list[ArrayLike] = []
    feeds: list[ArrayLike] = []
    kinds: list[ArrayLike] = []
    events = [Event(0, "partno", 0, {"text": name.upper()})]
    cutter = {"diameter": cutter_diameter, "corner_radius": cutter_diameter / 2.0}
    events.append(Event(0, "cutter", 0, dict(cutter)))
    events.append(Event(0, "tool", 0, {"number": 1, **cutter}))
    events.append(Event(0, "spindle", 0, {"rpm": SPINDLE_RPM, "direction": "cw"}))
    n = 0
    for tip, axis, comment in passes:
        tip = np.asarray(tip, dtype=float)
        axis = np.asarray(axis, dtype=float)
        axis = axis / np.linalg.norm(axis, axis=1, keepdims=True)
        events.append(Event(n, "comment", 0, {"text": comment}))
        k = len(tip)
        tips += [tip[:1] + clearance * axis[:1], tip, tip[-1:] + clearance * axis[-1:]]
        axes += [axis[:1], axis, axis[-1:]]
        feeds += [[math.nan], np.full(k, feed), [math.nan]]
        kinds += [[Motion.RAPID], np.full(k, Motion.FEED), [Motion.RAPID]]
        n += k + 2
    toolpath = Toolpath(
        tip=np.concatenate(tips),
        axis=np.concatenate(axes),
        feed=np.concatenate(feeds).astype(float),
        motion=np.concatenate(kinds).astype(np.int8),
        line=np.zeros(n, dtype=int),
        events=tuple(events),
        units="mm",
        source=f"<{name}>",
    )
    _, point_lines, event_lines = _apt_records(toolpath)
    return replace(
        toolpath,
        line=point_lines,
        events=tuple(
            replace(e, line=line) for e, line in zip(toolpath.events, event_lines, strict=True)
        ),
    )


def hemisphere_raster(
    radius: float = 50.0,
    offsets: Sequence[float] = (0.0, 0.5, 2.0, 5.0),
    feed: float = 2000.0,
    step: float = 0.5,
    max_tilt_deg: float = 60.0,
    center: Sequence[float] = (0.0, 0.0, 50.0),
) -> Toolpath:
    """Raster passes along X over a hemisphere, the tool normal to the surface.

    Pass ``k`` runs at ``y = y0_k`` (relative to the centre) over ``z = sqrt(R^2 - x^2 - y0^2)``
    with the tool axis ``(P - c) / R``; X is limited so that the tilt from +Z stays within
    ``max_tilt_deg``. Points are ``step`` apart in X, symmetric about the apex (x = 0 is a point,
    so the pass at ``y0 = 0`` has a CL point exactly on the pole). Passes alternate direction.

    Closed form: the smallest angle between the tool axis and +Z on a pass is
    ``arcsin(|y0| / R)``, reached at x = 0, where the azimuth of the tool axis, and with it a C
    axis whose pole is +Z, turns at ``F / |y0|`` rad/s for a feed F in mm/s.

    Parameters
    ----------
    radius : float, mm
    offsets : sequence of float, mm
        Pass offsets y0 from the apex; each ``|y0|`` must stay below ``R sin(max_tilt)``.
    feed : float, mm/min
    step : float, mm
        Distance between points along X.
    max_tilt_deg : float, degrees
        Largest tilt of the tool axis from +Z.
    center : sequence of 3 float, mm
        Centre of the sphere in the workpiece frame. The default raises it 50 mm above the
        workpiece origin: with the tool tilted 60 degrees, the lowest CL points of a sphere
        centred on the origin (z = 25 mm) lie below the Z travel of the ``gantry-ca`` head and
        the ``monoblock`` swivel head.

    Returns
    -------
    Toolpath
        Source ``"<hemisphere raster>"``.

    Raises
    ------
    ValueError
        For a non-positive radius, step or feed, or an offset beyond the tilt limit.
    """
    if radius <= 0 or step <= 0 or feed <= 0:
        raise ValueError(
            f"expected a positive radius, step and feed, got {radius:g}, {step:g}, {feed:g}"
        )
    c = np.asarray(center, dtype=float).reshape(3)
    reach = radius * math.sin(math.radians(max_tilt_deg))
    passes = []
    for k, y0 in enumerate(offsets):
        if abs(y0) >= reach:
            raise ValueError(
                f"expected offsets within {reach:g} mm of the apex (R sin(max tilt)), got {y0:g}"
            )
        half = math.sqrt(reach**2 - y0**2)
        count = math.floor(half / step * (1 + 1e-12))
        x = step * np.arange(-count, count + 1, dtype=float)
        if k % 2:
            x = x[::-1]
        normal = (
            np.stack(
                [x, np.full_like(x, y0), np.sqrt(np.maximum(radius**2 - x**2 - y0**2, 0.0))], axis=1
            )
            / radius
        )
        tip = c + radius * normal
        passes.append((tip, normal, f"PASS {k + 1} AT Y0 {y0:g} MM"))
    return _assemble(passes, name="hemisphere raster", feed=feed)


def great_circle_sweep(
    offset_deg: float = 0.0,
    half_angle_deg: float = 10.0,
    points: int = 41,
    feed: float = 1000.0,
    length: float = 40.0,
) -> Toolpath:
    """The tool axis sweeps a great circle through or past the pole +Z.

    The axis is ``cos(t) p + sin(t) x`` for ``t`` from ``-half_angle`` to ``+half_angle``, with
    ``p = (0, sin(offset), cos(offset))``: a great circle whose closest approach to +Z, at
    ``t = 0``, is ``offset`` (for an odd ``points`` that is a CL point). The tip moves on the
    straight line from ``(-length / 2, 0, 0)`` to ``(length / 2, 0, 0)`` at constant speed.

    Parameters
    ----------
    offset_deg : float, degrees
        Smallest angle between the tool axis and +Z.
    half_angle_deg : float, degrees
        Sweep on either side of the closest approach (the tilt from +Z at the ends is
        ``arccos(cos(half) cos(offset))``).
    points : int
        CL points of the sweep (at least 2).
    feed : float, mm/min
    length : float, mm
        Length of the tip's straight path.

    Returns
    -------
    Toolpath
        Source ``"<great-circle sweep OFFSET deg>"``.
    """
    if points < 2:
        raise ValueError(f"expected at least 2 points, got {points}")
    off = math.radians(offset_deg)
    t = np.radians(np.linspace(-half_angle_deg, half_angle_deg, points))
    p = np.array([0.0, math.sin(off), math.cos(off)])
    axis = np.cos(t)[:, None] * p + np.sin(t)[:, None] * np.array([1.0, 0.0, 0.0])
    tip = np.zeros((points, 3))
    tip[:, 0] = np.linspace(-length / 2.0, length / 2.0, points)
    name = f"great-circle sweep {offset_deg:g} deg"
    return _assemble([(tip, axis, f"SWEEP {offset_deg:g} DEG FROM THE POLE")], name=name, feed=feed)


def nutating_edge(
    max_tilt_deg: float = 90.0,
    points: int = 61,
    feed: float = 1000.0,
    min_tilt_deg: float = 30.0,
    azimuth_span_deg: float = 60.0,
    length: float = 40.0,
    center: Sequence[float] = (100.0, 0.0, 0.0),
) -> Toolpath:
    """A path whose tilt runs up to the edge of a nutating table's reach and back.

    The tilt from +Z is ``min + (max - min) sin(pi u)`` for ``u`` in [0, 1] (``max`` reached at
    ``u = 1/2``, a CL point for odd ``points``) while the azimuth turns evenly through
    ``azimuth_span_deg`` centred on +X; the tip moves on a straight line along Y through
    ``center``, as on a side wall facing +X. A 45-degree nutating table (``dmu50-nutating``)
    reaches 90 degrees of tilt only at B = 180, where its two inverse-kinematics branches merge.

    Parameters
    ----------
    max_tilt_deg, min_tilt_deg : float, degrees
    points : int
    feed : float, mm/min
    azimuth_span_deg : float, degrees
    length : float, mm
    center : sequence of 3 float, mm
        Middle of the tip's line. The default puts it 100 mm out along +X, the direction the
        tool axis points at the edge: there a nutating table turns the workpiece's +X up, and
        points near its centre would sit below the Z travel of ``dmu50-nutating``.

    Returns
    -------
    Toolpath
        Source ``"<nutating edge>"``.
    """
    if points < 2:
        raise ValueError(f"expected at least 2 points, got {points}")
    u = np.linspace(0.0, 1.0, points)
    tilt = np.radians(min_tilt_deg + (max_tilt_deg - min_tilt_deg) * np.sin(np.pi * u))
    if points % 2:
        tilt[points // 2] = math.radians(max_tilt_deg)  # exactly, not sin(pi/2) rounded
    azimuth = np.radians(azimuth_span_deg * (u - 0.5))
    axis = np.stack(
        [np.sin(tilt) * np.cos(azimuth), np.sin(tilt) * np.sin(azimuth), np.cos(tilt)], axis=1
    )
    tip = np.tile(np.asarray(center, dtype=float).reshape(1, 3), (points, 1))
    tip[:, 1] += np.linspace(-length / 2.0, length / 2.0, points)
    return _assemble(
        [(tip, axis, f"TILT {min_tilt_deg:g} TO {max_tilt_deg:g} DEG AND BACK")],
        name="nutating edge",
        feed=feed,
    )


def micro_pole(
    tilt_deg: Sequence[float] = (2.0, 1.2, 0.6, 1.2, 2.0),
    azimuth_deg: Sequence[float] = (-40.0, -20.0, 0.0, 20.0, 40.0),
    step: Sequence[float] = (0.003, 0.001, 0.0),
    start: Sequence[float] = (20.0, 10.0, 5.0),
    feed: float = 500.0,
    digits: int = 3,
) -> Toolpath:
    """A few CL points micrometres apart near the pole, the tool axis turning by degrees.

    A stand-in for the seed paper's Table 1 (five GOTO rows near vertical, posted on a
    45-degree B table), whose rows we do not have: it has the properties that made that
    example hard to verify. The tip steps are a few micrometres (``step``, rounded to
    ``digits`` decimals of a millimetre as a CL file writes them), far shorter than the tip
    tolerance, while the tool axis turns by a degree or more between points and passes within
    ``min(tilt_deg)`` of vertical, where the C table of ``dmu50-nutating`` turns by tens of
    degrees per point. On segments this short the tip's place on the segment is rounding
    noise: a verifier that compares the tool axis at the tip's projection parameter rejects
    the posts (machine coordinates), one that compares it with the CL orientation path near
    the tip does not (``docs/verification.md``).

    Parameters
    ----------
    tilt_deg, azimuth_deg : sequence of float, degrees
        Tool axis of each point: angle from +Z and azimuth from +X (the same length, at least
        2).
    step : sequence of 3 float, mm
        Tip step from one point to the next.
    start : sequence of 3 float, mm
        The first tip.
    feed : float, mm/min
    digits : int
        Decimals (of a millimetre) the tips are rounded to.

    Returns
    -------
    Toolpath
        Source ``"<micro pole>"``.

    Raises
    ------
    ValueError
        For tilts and azimuths of different lengths, fewer than 2 points, or a feed that is not
        positive.
    """
    tilt, azimuth = (
        np.radians(np.asarray(tilt_deg, float)),
        np.radians(np.asarray(azimuth_deg, float)),
    )
    if tilt.shape != azimuth.shape or tilt.ndim != 1 or len(tilt) < 2 or feed <= 0:
        raise ValueError(
            f"expected as many tilts as azimuths, at least 2, and a positive feed; got "
            f"{len(tilt)} tilts, {len(azimuth)} azimuths, feed {feed:g}"
        )
    axis = np.stack(
        [np.sin(tilt) * np.cos(azimuth), np.sin(tilt) * np.sin(azimuth), np.cos(tilt)], axis=1
    )
    offsets = np.arange(len(tilt))[:, None] * np.asarray(step, dtype=float).reshape(1, 3)
    tip = np.round(np.asarray(start, dtype=float).reshape(1, 3) + offsets, digits)
    return _assemble([(tip, axis, "MICROMETRE STEPS NEAR THE POLE")], name="micro pole", feed=feed)


#: The shipped variants by stable name.
PATHS: dict[str, Callable[[], Toolpath]] = {
    "hemisphere": hemisphere_raster,
    "sweep-0": lambda: great_circle_sweep(0.0),
    "sweep-0.1": lambda: great_circle_sweep(0.1),
    "sweep-1": lambda: great_circle_sweep(1.0),
    "sweep-5": lambda: great_circle_sweep(5.0),
    "nutating-edge": nutating_edge,
    "micro-pole": micro_pole,
}


def _num(x: float) -> str:
    """A number with :data:`_DIGITS` significant digits (no negative zero)."""
    text = f"{x:.{_DIGITS}g}"
    return "0" if float(text) == 0.0 else text


def _apt_records(toolpath: Toolpath) -> tuple[list[str], np.ndarray, list[int]]:
    """APT records of a toolpath and the line each point and event lands on.

    Returns
    -------
    records : list of str
        One record per line.
    point_lines : ndarray, shape (n,), int
        1-based line of the GOTO of each point.
    event_lines : list of int
        1-based line of each event, in :attr:`Toolpath.events` order.
    """
    n = len(toolpath)
    records: list[str] = []
    point_lines = np.zeros(n, dtype=int)
    event_lines = [0] * len(toolpath.events)
    by_index: dict[int, list[int]] = {}
    for k, e in enumerate(toolpath.events):
        by_index.setdefault(min(e.index, n), []).append(k)

    partno = [k for k in by_index.get(0, []) if toolpath.events[k].kind == "partno"][:1]
    for k in partno:
        records.append(f"PARTNO {toolpath.events[k].data.get('text', '')}".rstrip())
        event_lines[k] = len(records)
    records += ["UNITS/MM", "MULTAX/ON"]

    def emit(k: int) -> None:
        e = toolpath.events[k]
        if e.kind == "partno":
            records.append(f"PARTNO {e.data.get('text', '')}".rstrip())
        elif e.kind == "comment":
            records.append(f"PPRINT {e.data.get('text', '')}".rstrip())
        elif e.kind == "cutter":
            values = [e.data["diameter"], e.data.get("corner_radius", 0.0)]
            if e.data.get("length") is not None:
                values += [0.0] * 4 + [e.data["length"]]
            records.append("CUTTER/" + ",".join(_num(v) for v in values))
        elif e.kind == "tool":
            records.append(f"LOADTL/{int(e.data['number'])}")
        elif e.kind == "spindle":
            if e.data["direction"] == "off":
                records.append("SPINDL/OFF")
            else:
                word = "CLW" if e.data["direction"] == "cw" else "CCLW"
                records.append(f"SPINDL/RPM,{_num(e.data['rpm'])},{word}")
        else:
            raise ValueError(
                f"to_apt: expected events of kind partno, comment, cutter, tool or spindle, "
                f"got {e.kind!r} (line {e.line})"
            )
        event_lines[k] = len(records)

    feed = math.nan
    for i in range(n + 1):
        for k in by_index.get(i, []):
            if k not in partno:
                emit(k)
        if i == n:
            break
        if toolpath.motion[i] == Motion.RAPID:
            records.append("RAPID")
        else:
            f = float(toolpath.feed[i])
            if not math.isfinite(f):
                raise ValueError(f"to_apt: feed move {i} (line {toolpath.line[i]}) has no feed")
            if f != feed:
                records.append(f"FEDRAT/MMPM,{_num(f)}")
                feed = f
        values = (*toolpath.tip[i], *toolpath.axis[i])
        records.append("GOTO/" + ",".join(_num(float(v)) for v in values))
        point_lines[i] = len(records)
    records.append("FINI")
    return records, point_lines, event_lines


def to_apt(toolpath: Toolpath) -> str:
    """APT text of a toolpath, which :func:`urdfpost.readers.read_cl_text` reads back.

    Written in millimetres (``UNITS/MM``, ``FEDRAT/MMPM``) with 10 significant digits,
    ``MULTAX/ON`` and six-value ``GOTO`` records, ``RAPID`` before each rapid point; events of
    kind partno, comment (``PPRINT``), cutter (``CUTTER/d,r[,0,0,0,0,length]``), tool
    (``LOADTL/n``) and spindle (``SPINDL/RPM,n,CLW|CCLW``, ``SPINDL/OFF``) before the point
    they precede. A toolpath from this module's generators carries the line numbers of this
    text.

    Parameters
    ----------
    toolpath : Toolpath

    Returns
    -------
    str
        One record per line, ending in ``FINI`` and a newline.

    Raises
    ------
    ValueError
        For an event kind not listed above, or a feed point without a feed.
    """
    records, _, _ = _apt_records(toolpath)
    return "\n".join(records) + "\n"
