"""The 3-D view: one self-contained HTML file that plays a program on the machine of its URDF.

The machine is drawn from the machine file's ``<visual>`` elements (boxes, cylinders and
spheres as three.js primitives, meshes read with trimesh), the stock or part mesh rides on the
workpiece frame, the tool is a cylinder from the tip up the tool axis, of the diameter of the
cutter of the tool loaded (:func:`_tool_sizes`).
The page plays the program: play/pause, a timeline, the speed, the current block with its line
of NC text and the axis values; singular spans, rewinds and the worst deviation are marked on
the timeline.

Where the poses come from
-------------------------
Everything is placed by Pinocchio's forward kinematics here, in Python, at samples of the
program's joint path; the page only interpolates between neighbouring samples. A
machine-coordinate program's joints are its axis words (joint-linear between blocks, as the
control moves them). A TCP program's linear words are the tool tip: at each sample the tip and
the rotary angles are interpolated linearly (as a TCP control moves them) and the linear axes
are solved for them (:func:`urdfpost.kinematics.inverse.solve_linear`): the same read back as
``urdfpost verify``. A block is sampled every 2 degrees of its largest rotary step (at most 32
samples a block), and the whole program at most :data:`MAX_SAMPLES` times (longer programs are
sampled at evenly spaced blocks, which the page says).

Time
----
Each block takes the longer of its tip path at the programmed feed and the largest of its axis
steps at the axis' velocity limit (URDF ``<limit velocity>``); a rapid moves every axis at its
limit. No acceleration is modelled: the timeline orders and spaces the blocks for playback, it
is not a machining-time prediction (``urdfpost compare`` reports those).

Why three.js
------------
The page uses three.js (r160, MIT licence), vendored in ``view_assets/`` and inlined into the
file, so it opens offline from disk with no server and no CDN. Pinocchio's
``MeshcatVisualizer`` was the other candidate: meshcat's static HTML export needs a running
meshcat server (a ZMQ and web server) to produce the file, its player shows animation clips but
not the NC text, block number or timeline marks this view needs, and its bundle is 2.5 times
the size of three.js' module build.
"""

from __future__ import annotations

import base64
import html
import json
import logging
import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from urdfpost.analysis import COLOR_BY
from urdfpost.collision.mesh import load_mesh
from urdfpost.errors import UrdfpostError
from urdfpost.kinematics.forward import tip_and_axis
from urdfpost.kinematics.inverse import assemble, solve_linear
from urdfpost.machine import Machine
from urdfpost.machine.shapes import Box, Cylinder, LinkShape, Mesh, Sphere, link_shapes
from urdfpost.planning.singularity import conditioning
from urdfpost.posting.tools import row_tool_values, tool_cutters
from urdfpost.program import (
    FEED_INVERSE_TIME,
    Arc,
    Move,
    MoveTable,
    Program,
    arcs_as_moves,
    rewind_moves,
)
from urdfpost.tolerances import Tolerances
from urdfpost.toolpath import Toolpath
from urdfpost.verification import program_joints
from urdfpost.verification.feeds import tip_feeds
from urdfpost.verification.planes import in_own_frame

log = logging.getLogger(__name__)

ASSETS = Path(__file__).with_name("view_assets")
"""The page's template, its script and the vendored three.js."""

THREE_VERSION = "0.160.0"
"""The vendored three.js build (``three.module.min.js``, ``OrbitControls.js`` of the npm
package ``three``)."""

MAX_SAMPLES = 60_000
"""Samples of the joint path a view holds at most (a few MB of HTML)."""

SAMPLE_STEP = math.radians(2.0)
"""Largest rotary step between samples of one block, rad."""

BLOCK_SAMPLES = 32
"""Samples of one block at most."""

MAX_TEXT_LINES = 200_000
"""NC text lines the page carries at most (the lines of the sampled blocks)."""

DEFAULT_CUTTER = 10.0
"""Tool diameter drawn when the CL data has none, mm."""

_RGBA: dict[str, tuple[float, ...]] = {"": (0.62, 0.64, 0.68, 1.0)}


@dataclass(frozen=True)
class Timeline:
    """The sampled joint path of a program and its times.

    Attributes
    ----------
    q : ndarray, shape (S, m)
        Joint values at the samples, mm / rad.
    t : ndarray, shape (S,)
        Time of each sample from the program start, s.
    move : ndarray, shape (S,), int
        The program move (row of :func:`program_joints`) each sample belongs to: the sample
        lies on the way to that move's end.
    speed : ndarray, shape (S,)
        The largest axis speed on the way to each sample as a fraction of that axis'
        velocity limit (0 where the axes have none).
    """

    q: np.ndarray
    t: np.ndarray
    move: np.ndarray
    speed: np.ndarray


def program_rows(
    machine: Machine, program: Program, tool_length: float, axis_feed_rule: str = "combined"
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Joint values, rapid flags and feeds of a program's moves.

    Parameters
    ----------
    machine : Machine
    program : Program
        As written or read back.
    tool_length : float, mm
        The tool a TCP program's linear axes are solved for.
    axis_feed_rule : str
        The control's rule for a feed per minute without TCP
        (:func:`urdfpost.verification.feeds.tip_feeds`).

    Returns
    -------
    q : ndarray, shape (N, m), mm / rad
        Machine joint values (a TCP program's linear axes solved for its tip).
    rapid : ndarray, shape (N,), bool
    feed : ndarray, shape (N,), mm/min
        The modal feed of each move (NaN before the first); the tip feed each block gives
        where the F words are no tip feeds (inverse time, machine coordinates).
    """
    values, rapid = program_joints(machine, program)
    feed = program.move_table().feed.copy()
    ok = ~np.isnan(feed)
    idx = np.maximum.accumulate(np.where(ok, np.arange(len(feed)), -1))
    feed = np.where(idx >= 0, feed[np.maximum(idx, 0)], np.nan)
    if not program.tcp or program.feed_mode == FEED_INVERSE_TIME:
        # F words that are no tip feeds: the tip feed each block gives, by the control's rule
        feed = np.where(rapid, feed, tip_feeds(machine, program, tool_length, axis_feed_rule))
    if program.tcp and len(values):
        values = _tcp_joints(machine, values, tool_length)
    return values, rapid, feed


def _tcp_joints(machine: Machine, values: np.ndarray, tool_length: float) -> np.ndarray:
    """Machine joints of TCP rows (linear values = the tool tip in the workpiece frame)."""
    rot = values[:, list(machine.rotary_columns)]
    tip = values[:, list(machine.linear_columns)]
    return assemble(machine, rot, solve_linear(machine, rot, tip, tool_length))


def _durations(
    machine: Machine, q: np.ndarray, rapid: np.ndarray, feed: np.ndarray, tip: np.ndarray
) -> np.ndarray:
    """Seconds of each move (the first: 0): tip path at the feed, axis steps at their limits."""
    n = len(q)
    out = np.zeros(n)
    if n < 2:
        return out
    v = np.array([a.velocity for a in machine.axes])
    steps = np.abs(np.diff(q, axis=0))
    limited = np.isfinite(v) & (v > 0)
    axis_time = np.zeros(n - 1)
    if limited.any():
        axis_time = (steps[:, limited] / v[limited]).max(axis=1)
    path = np.linalg.norm(np.diff(tip, axis=0), axis=1)
    f = feed[1:]
    feed_time = np.where(
        np.isfinite(f) & (f > 0) & ~rapid[1:], path / np.where(f > 0, f, 1.0) * 60.0, 0.0
    )
    # a rapid on axes with no limit, or a feed move without a feed: 10 m/min
    fallback = np.where(axis_time > 0, 0.0, path / 10_000.0 * 60.0)
    out[1:] = np.maximum(np.maximum(axis_time, feed_time), fallback)
    return out


def timeline(
    machine: Machine,
    program: Program,
    q: np.ndarray,
    rapid: np.ndarray,
    feed: np.ndarray,
    tool_length: float,
    max_samples: int = MAX_SAMPLES,
    lengths: np.ndarray | None = None,
) -> Timeline:
    """Samples of the program's joint path with their times (see the module docstring).

    Parameters
    ----------
    machine : Machine
    program : Program
    q, rapid, feed : ndarray
        From :func:`program_rows`, N rows.
    tool_length : float, mm
    max_samples : int
        Samples at most.
    lengths : ndarray, shape (N,), mm, optional
        A machine-coordinate program posted with each tool's gauge length: the length of
        each row (:func:`urdfpost.posting.tools.row_tool_values`); default ``tool_length``.

    Returns
    -------
    Timeline
    """
    n = len(q)
    if n == 0:
        raise UrdfpostError(f"{program.name}: the program has no moves to show")
    tip, _ = tips_and_axes(machine, q, tool_length, lengths)
    seconds = _durations(machine, q, rapid, feed, tip)
    rot = list(machine.rotary_columns)
    counts = np.ones(n, dtype=np.int64)
    if rot and n > 1:
        step = np.abs(np.diff(q[:, rot], axis=0)).max(axis=1)
        counts[1:] = np.clip(np.ceil(step / SAMPLE_STEP), 1, BLOCK_SAMPLES)
    if counts.sum() > max_samples:  # one sample a block, then every k-th block
        counts[:] = 1
        keep = np.unique(np.linspace(0, n - 1, min(n, max_samples)).round().astype(np.int64))
    else:
        keep = np.arange(n)
    moves, frac = [], []
    prev = -1
    for i in keep.tolist():
        k = int(counts[i]) if prev == i - 1 else 1
        moves.append(np.full(k, i))
        frac.append(np.arange(1, k + 1) / k)
        prev = i
    move = np.concatenate(moves)
    s = np.concatenate(frac)
    start = np.maximum(move - 1, 0)
    ends = np.cumsum(seconds)
    t = ends[start] + s * (ends[move] - ends[start])
    t[move == 0] = 0.0
    qa, qb = q[start], q[move]
    if program.tcp:
        ta, tb = tip[start], tip[move]
        rot_s = qa[:, rot] + s[:, None] * (qb[:, rot] - qa[:, rot])
        tip_s = ta + s[:, None] * (tb - ta)
        qs = assemble(machine, rot_s, solve_linear(machine, rot_s, tip_s, tool_length))
    else:
        qs = qa + s[:, None] * (qb - qa)
    v = np.array([a.velocity for a in machine.axes])
    limited = np.isfinite(v) & (v > 0)
    speed = np.zeros(len(qs))
    dt = np.diff(t)
    if limited.any() and len(qs) > 1:
        rate = np.abs(np.diff(qs[:, limited], axis=0)) / np.where(dt > 0, dt, np.inf)[:, None]
        speed[1:] = (rate / v[limited]).max(axis=1)
    return Timeline(qs, t, move, speed)


def tips_and_axes(
    machine: Machine, q: np.ndarray, tool_length: float, lengths: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Tool tip (mm) and axis of joint rows ``q`` (N, m), each with its own gauge length
    ``lengths`` (N,) mm where given, else ``tool_length``."""
    if lengths is None or len(np.unique(lengths)) <= 1:
        length = tool_length if lengths is None or not len(lengths) else float(lengths[0])
        return tip_and_axis(machine, q, length)
    tip, axis = np.empty((len(q), 3)), np.empty((len(q), 3))
    for length in np.unique(lengths):
        rows = lengths == length
        tip[rows], axis[rows] = tip_and_axis(machine, q[rows], float(length))
    return tip, axis


def _rgba_of(root: Any) -> dict[str, tuple[float, ...]]:
    """``<material name>`` colours defined at the top of the machine file."""
    colors: dict[str, tuple[float, ...]] = {}
    for m in root.findall("material"):
        c = m.find("color")
        if m.get("name") and c is not None and c.get("rgba"):
            try:
                colors[m.get("name")] = tuple(float(x) for x in c.get("rgba").split())
            except ValueError:
                continue
    return colors


def _visual_colors(root: Any) -> list[tuple[float, ...]]:
    """The colour of each ``<visual>`` in file order (its material's, or the default grey)."""
    named = _rgba_of(root)
    out: list[tuple[float, ...]] = []
    for link in root.findall("link"):
        for el in link.findall("visual"):
            rgba = _RGBA[""]
            m = el.find("material")
            if m is not None:
                c = m.find("color")
                if c is not None and c.get("rgba"):
                    try:
                        rgba = tuple(float(x) for x in c.get("rgba").split())
                    except ValueError:
                        pass
                elif m.get("name") in named:
                    rgba = named[m.get("name")]
            if len(rgba) != 4 or not all(math.isfinite(x) for x in rgba):
                rgba = _RGBA[""]
            out.append(rgba)
    return out


def _b64(a: np.ndarray, dtype: str) -> str:
    return base64.b64encode(np.ascontiguousarray(a, dtype=dtype).tobytes()).decode("ascii")


def _mesh_data(path: Path, scale: np.ndarray, what: str) -> dict[str, Any]:
    """Vertices (mm, the file's units times ``scale``) and faces of a mesh file, base64."""
    mesh = load_mesh(path, what)
    return {
        "kind": "mesh",
        "positions": _b64(np.asarray(mesh.vertices) * scale, "<f4"),
        "indices": _b64(np.asarray(mesh.faces).ravel(), "<u4"),
    }


def _shape_data(shape: LinkShape, rgba: tuple[float, ...]) -> dict[str, Any]:
    """One visual as the page draws it: kind, sizes in mm, placement in its link."""
    g = shape.geometry
    data: dict[str, Any]
    if isinstance(g, Box):
        data = {"kind": "box", "size": [float(x) for x in g.size]}
    elif isinstance(g, Cylinder):
        data = {"kind": "cylinder", "radius": g.radius, "length": g.length}
    elif isinstance(g, Sphere):
        data = {"kind": "sphere", "radius": g.radius}
    elif isinstance(g, Mesh):
        data = _mesh_data(g.path, np.asarray(g.scale) * 1000.0, f"{shape.where} mesh")
    else:  # pragma: no cover - Geometry is closed
        raise TypeError(g)
    data["origin"] = [float(x) for x in shape.origin.T.ravel()]  # column-major, as three.js
    data["color"] = list(rgba)
    data["name"] = shape.name or ""
    return data


def _poses(machine: Machine, q: np.ndarray, links: list[str]) -> np.ndarray:
    """Placements of ``links`` in the machine's root frame at each sample, shape (S, L, 7):
    position (mm) and quaternion (x, y, z, w)."""
    import pinocchio as pin

    model = machine.model
    data = model.createData()  # type: ignore[attr-defined]
    frames = [model.getFrameId(lk, pin.FrameType.BODY) for lk in links]  # type: ignore[attr-defined]
    out = np.empty((len(q), len(links), 7))
    for i, row in enumerate(q):
        pin.forwardKinematics(model, data, machine.pin_configuration(row))
        for k, f in enumerate(frames):
            m = pin.updateFramePlacement(model, data, f)
            out[i, k, :3] = m.translation * 1000.0
            out[i, k, 3:] = pin.Quaternion(m.rotation).coeffs()
    return out


def _runs(flags: np.ndarray) -> list[tuple[int, int]]:
    """First and last index of each run of True."""
    if not flags.any():
        return []
    d = np.diff(np.concatenate([[0], flags.astype(np.int8), [0]]))
    return list(
        zip(np.flatnonzero(d == 1).tolist(), (np.flatnonzero(d == -1) - 1).tolist(), strict=True)
    )


def _tip_deviation(tip: np.ndarray, cl: Toolpath) -> np.ndarray:
    """Distance of each tip sample to the CL polyline, mm.

    The candidates of each sample are the CL segments that touch one of its 16 nearest CL
    points (a k-d tree); the distance to each candidate segment is exact.
    """
    from scipy.spatial import cKDTree

    pts = cl.tip
    if len(pts) == 0:
        return np.zeros(len(tip))
    if len(pts) == 1:
        return np.linalg.norm(tip - pts[0], axis=1)
    k = min(16, len(pts))
    _, near = cKDTree(pts).query(tip, k=k)
    near = np.asarray(near).reshape(len(tip), k)
    best = np.full(len(tip), np.inf)
    for seg_start in (near - 1, near):
        a_idx = np.clip(seg_start, 0, len(pts) - 2)
        a, b = pts[a_idx], pts[a_idx + 1]
        ab = b - a
        denom = np.einsum("...i,...i", ab, ab)
        rel = tip[:, None, :] - a
        s = np.clip(np.einsum("...i,...i", rel, ab) / np.where(denom > 0, denom, 1.0), 0.0, 1.0)
        d = np.linalg.norm(rel - s[..., None] * ab, axis=-1).min(axis=1)
        best = np.minimum(best, d)
    return best


ARC_STEP = 0.1
"""Longest chord between the moves an arc block is shown as, mm."""


def _motion_lines(
    dialect: Any, text: str, path: str, inserts: list[str] | None = None
) -> tuple[np.ndarray, list[int]]:
    """The NC line of each move of a program (:func:`move_lines`) and of each arc."""
    lines = move_lines(dialect, text, path, inserts)
    reader = dialect.reader(path)
    reader.feed(text, list(inserts or ()))
    return lines, list(reader.builder.arc_lines)


def _lines_of_runs(
    written: Program, run: Program, lines: np.ndarray, arc_lines: list[int]
) -> np.ndarray:
    """The NC line of each move of ``run`` (``written`` with its arcs as moves): the moves'
    own lines, and the arc's line for each move along an arc; ``lines`` as they are when the
    lines of the arcs are not known (they are not the text's)."""
    arcs = [p for p in written.parts if isinstance(p, Arc)]
    if not arcs:
        return lines
    if len(arcs) != len(arc_lines) or len(lines) != len(written.move_table()):
        return lines
    out: list[np.ndarray] = []
    at, arc = 0, iter(arc_lines)
    for part, ran in zip(written.parts, run.parts, strict=True):
        if isinstance(part, Arc):
            assert isinstance(ran, MoveTable)
            out.append(np.full(len(ran), next(arc), dtype=np.int64))
        elif isinstance(part, MoveTable | Move):
            k = len(part) if isinstance(part, MoveTable) else 1
            out.append(lines[at : at + k])
            at += k
    return np.concatenate(out) if out else lines


def move_lines(dialect: Any, text: str, path: str, inserts: list[str] | None = None) -> np.ndarray:
    """The NC text line (1-based) of each move of a program, in the order of its moves.

    The program is read once by the control's reader, which notes the line of every move it
    reads (:attr:`urdfpost.dialects.reader.ProgramBuilder.move_lines`).

    Parameters
    ----------
    dialect : Dialect
        Of the program.
    text : str
        The program text.
    path : str
        For messages.
    inserts : list of str, optional
        Verbatim blocks, as :meth:`Dialect.read`.

    Returns
    -------
    ndarray, shape (N,), int
    """
    reader = dialect.reader(path)
    reader.feed(text, list(inserts or ()))
    moves = len(reader.take().move_table())
    noted = reader.builder.move_lines
    lines = np.concatenate([np.atleast_1d(x) for x in noted]) if noted else np.zeros(0)
    if len(lines) != moves:  # (every move is read by one of the two ways that note it)
        raise AssertionError(f"{path}: {len(lines)} move lines for {moves} moves")
    return lines.astype(np.int64)


def _tool_sizes(
    program: Program, cl: Toolpath | None, moves: np.ndarray, lengths: np.ndarray | float
) -> tuple[float, np.ndarray]:
    """The tool drawn at each sample: the diameter of the cutter the CL data gives the tool the
    program has loaded (:func:`~urdfpost.posting.tools.tool_cutters`; the first cutter's
    where it gives none, :data:`DEFAULT_CUTTER` without any), and a length of at least four
    diameters.

    Parameters
    ----------
    program : Program
    cl : Toolpath or None
    moves : ndarray, shape (n,), int
        The move of each sample.
    lengths : ndarray, shape (n,), or float, mm
        The tool length at each sample.

    Returns
    -------
    first : float, mm
        The first cutter's diameter.
    sizes : ndarray, shape (n, 2), mm
        Diameter and length at each sample.
    """
    first = _cutter(cl)
    by_tool: dict[int, float] = {}
    if cl is not None:
        for number, cutter in tool_cutters(cl)[1].items():
            d = cutter[0]
            if d is not None and d > 0 and math.isfinite(d):
                by_tool[number] = float(d)
    diameter = row_tool_values(program, by_tool, first)[moves] if len(moves) else np.zeros(0)
    length = np.maximum(np.broadcast_to(lengths, diameter.shape), 4.0 * diameter)
    return first, np.column_stack([diameter, length])


def _cutter(cl: Toolpath | None) -> float:
    """The first cutter diameter of the CL data, mm."""
    if cl is not None:
        for e in cl.events:
            d = e.data.get("diameter") if e.kind in ("tool", "cutter") else None
            if isinstance(d, int | float) and d > 0 and math.isfinite(d):
                return float(d)
    return DEFAULT_CUTTER


def _mark(kind: str, t0: float, t1: float, label: str) -> dict[str, Any]:
    return {"kind": kind, "t0": float(t0), "t1": float(t1), "label": label}


def _marks(
    machine: Machine,
    program: Program,
    line: Timeline,
    rapid: np.ndarray,
    deviation: np.ndarray | None,
    move_line: np.ndarray,
) -> list[dict[str, Any]]:
    """The timeline's marks: rewinds (between the program's rewind comments), singular spans
    (samples of feed moves where the orientation Jacobian's smallest singular value is below
    the detector's threshold, :func:`urdfpost.planning.singularity.conditioning`) and the
    worst tool-tip deviation from the CL path.

    ``rapid`` and ``deviation`` (mm, or None without CL data) are per sample.
    """
    marks: list[dict[str, Any]] = []
    rew = rewind_moves(program)
    if len(rew) == int(line.move.max()) + 1:
        for a, b in _runs(rew[line.move]):
            marks.append(_mark("rewind", line.t[a], line.t[b], "rewind"))
    if machine.rotary:
        sigma, _ = conditioning(machine, line.q)
        for a, b in _runs((sigma < Tolerances().singular_sigma) & ~rapid):
            marks.append(_mark("singular", line.t[a], line.t[b], "singular span"))
    if deviation is not None:
        w = int(np.argmax(deviation))
        label = f"worst tip deviation {deviation[w]:.4f} mm (NC line {int(move_line[w])})"
        marks.append(_mark("worst", line.t[w], line.t[w], label))
    return marks


def view_data(
    machine: Machine,
    program: Program,
    text: str,
    dialect: Any,
    *,
    cl: Toolpath | None = None,
    stock: str | Path | None = None,
    tool_length: float | None = None,
    color: str | None = None,
    inserts: list[str] | None = None,
    max_samples: int = MAX_SAMPLES,
    tool_lengths: Mapping[int, float] | None = None,
) -> dict[str, Any]:
    """Everything the page shows, as JSON-ready data.

    Parameters
    ----------
    machine : Machine
        The machine the program was posted for (with its job setup).
    program : Program
        The program read back from ``text`` (or as written).
    text : str
        The program's NC text.
    dialect : Dialect
        The program's control.
    cl : Toolpath, optional
        The CL data: drawn as the path, and the worst deviation and the trace's deviation
        colours measured against it.
    stock : path, optional
        A mesh file (STL, OBJ, ...) in the workpiece frame, in program units.
    tool_length : float, mm, optional
        Default: the program's (machine coordinates) or the machine file's.
    color : {"deviation", "speed"}, optional
        Colour the tool-tip trace by its distance to the CL path (needs ``cl``) or by the
        largest axis speed as a fraction of its limit.
    inserts : list of str, optional
        Verbatim blocks of the program text.
    max_samples : int
    tool_lengths : mapping of int to float, mm, optional
        A machine-coordinate program posted with each tool's gauge length
        (:mod:`urdfpost.posting.tools`): the length of each tool number; a tool not in it
        has ``tool_length``.

    Returns
    -------
    dict
    """
    from lxml import etree

    if color is not None and color not in COLOR_BY:
        raise ValueError(f"color must be one of {COLOR_BY}, not {color!r}")
    if color == "deviation" and cl is None:
        raise UrdfpostError("colouring by deviation needs the CL data (--cl)")
    if tool_length is None:
        tool_length = (
            program.tool_length
            if not program.tcp and program.tool_length > 0
            else machine.settings.tool_length
        )
    program = in_own_frame(program, machine)  # (tilted planes: the moves in the program's frame)
    written = program
    program = arcs_as_moves(program, ARC_STEP)  # the moves the control makes along its arcs
    q, rapid, feed = program_rows(machine, program, tool_length, dialect.spec.axis_feed_rule)
    lengths = None
    if tool_lengths and not program.tcp:
        lengths = row_tool_values(program, tool_lengths, tool_length)
    line = timeline(machine, program, q, rapid, feed, tool_length, max_samples, lengths)
    sample_lengths = None if lengths is None else lengths[line.move]
    tip, axis = tips_and_axes(machine, line.q, tool_length, sample_lengths)
    root = etree.fromstring(machine.urdf_text.encode("utf-8"))
    visuals = link_shapes(root, machine.path, "visual")
    colors = _visual_colors(root)
    bodies: dict[str, list[dict[str, Any]]] = {}
    for shape, rgba in zip(visuals, colors, strict=True):
        bodies.setdefault(shape.link, []).append(_shape_data(shape, rgba))
    links = sorted(set(bodies) | {"workpiece"})
    moving = [lk for lk in links if machine.link_axes.get(lk)]
    fixed = [lk for lk in links if lk not in moving]
    poses = _poses(machine, line.q, moving)
    still = _poses(machine, line.q[:1], fixed)[0]
    lines = _lines_of_runs(written, program, *_motion_lines(dialect, text, program.name, inserts))
    nc = text.splitlines()
    move_line = lines[line.move] if len(lines) == len(q) else np.zeros(len(line.move), np.int64)
    if len(lines) != len(q):
        log.warning("%s: the NC lines of the moves could not be told apart", program.name)
    shown = sorted(set(move_line.tolist()))[:MAX_TEXT_LINES]
    text_of = {n: nc[n - 1] if 0 < n <= len(nc) else "" for n in shown}
    deviation = None
    if cl is not None and len(cl):
        deviation = np.where(rapid[line.move], 0.0, _tip_deviation(tip, cl))
    marks = _marks(machine, program, line, rapid[line.move], deviation, move_line)
    first_cutter, tool_sizes = _tool_sizes(
        program, cl, line.move, tool_length if sample_lengths is None else sample_lengths
    )
    trace_color = None
    if color == "deviation" and deviation is not None:
        trace_color = {
            "by": "deviation",
            "values": _b64(deviation, "<f4"),
            "unit": "mm",
            "max": float(max(deviation.max(), 1e-9)),
        }
    elif color == "speed":
        trace_color = {
            "by": "speed",
            "values": _b64(line.speed, "<f4"),
            "unit": "of the axis limit",
            "max": float(max(line.speed.max(), 1e-9)),
        }
    stock_data = None
    if stock is not None:
        stock_data = _mesh_data(
            Path(stock), np.full(3, 25.4 if program.units == "inch" else 1.0), "stock"
        )
    axes = list(machine.axis_names)
    rotary = [a.rotary for a in machine.axes]
    shown_q = np.where(
        rotary, np.degrees(line.q), line.q / (25.4 if program.units == "inch" else 1.0)
    )
    return {
        "title": f"{program.name} on {machine.name}",
        "machine": machine.name,
        "units": program.units,
        "tcp": program.tcp,
        "three": THREE_VERSION,
        "bodies": bodies,
        "moving": moving,
        "fixed": {lk: [float(x) for x in still[k]] for k, lk in enumerate(fixed)},
        "samples": len(line.t),
        "moves": len(q),
        "sampled_every": 1 if len(line.t) >= len(q) else math.ceil(len(q) / len(line.t)),
        "t": _b64(line.t, "<f8"),
        "poses": _b64(poses, "<f4"),
        "tip": _b64(tip, "<f4"),
        "axis": _b64(axis, "<f4"),
        "q": _b64(shown_q, "<f4"),
        "axes": axes,
        "rotary": rotary,
        "move": _b64(line.move, "<i4"),
        "line": _b64(move_line, "<i4"),
        "text": {str(n): s for n, s in text_of.items()},
        "cl": _b64(cl.tip, "<f4") if cl is not None and len(cl) else None,
        "stock": stock_data,
        "tool": {
            "diameter": first_cutter,
            "length": max(tool_length, 4.0 * first_cutter),
            "sizes": _b64(tool_sizes, "<f4"),  # per sample: diameter, length (mm)
        },
        "marks": marks,
        "color": trace_color,
    }


def view_html(data: dict[str, Any]) -> str:
    """The page: the template with the data, the player script and three.js inlined.

    Parameters
    ----------
    data : dict
        From :func:`view_data`.

    Returns
    -------
    str
        A complete HTML document that needs nothing but a browser with WebGL.
    """
    template = (ASSETS / "view.html").read_text(encoding="utf-8")
    three = (ASSETS / "three.module.min.js").read_text(encoding="utf-8")
    orbit = (ASSETS / "OrbitControls.js").read_text(encoding="utf-8")
    player = (ASSETS / "player.js").read_text(encoding="utf-8")
    payload = json.dumps(data, separators=(",", ":")).replace("</", "<\\/")
    return (
        template.replace("{{TITLE}}", html.escape(str(data["title"])))
        .replace("{{THREE}}", _script_text(three))
        .replace("{{ORBIT}}", _script_text(orbit))
        .replace("{{DATA}}", payload)
        .replace("{{PLAYER}}", _script_text(player))
    )


def _script_text(js: str) -> str:
    """Source text safe inside a ``<script type="text/plain">`` element."""
    return js.replace("</script", "<\\/script")
