"""Write large five-axis APT CL files for the scaling benchmark.

The job is a finishing raster over a hemisphere with the tool normal to the surface (ball mill,
CL point = tool tip), so the tool axis varies continuously. The hemisphere sits on the
workpiece zero of the ``dmu50`` machine; the raster is cut in several layers, each turned about
the hemisphere's axis (0, 45, 90, 135 degrees for four layers), and every layer has a pass
through the top: the tool axis goes through vertical (an exact pole of the C table) once per
layer, and the passes beside it come within a fraction of a degree of the pole. Passes are
limited to ``max_tilt`` from the top, so the tool axis stays within that angle of +Z (the
dmu50 B axis tilts -5 to +110 degrees; C is continuous).

Within a layer the passes zigzag and are joined by feed moves; between layers the tool retracts
along its axis, rises to a safe height, moves across by RAPID, comes down to the approach point
and plunges at a lower feed. Points per pass are proportional to
the pass length (an even point spacing along every pass) and add up to the requested count.

Run: ``python bench/make_large_cl.py 1000000 [-o FILE]`` (default file in the system temporary
directory, ``urdfpost-bench/hemisphere_<n>.apt``). The file is written in chunks, so a
10M-point file needs no more memory than a 100k-point one.
"""

from __future__ import annotations

import argparse
import math
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

#: Default directory of generated files.
DATA_DIR = Path(tempfile.gettempdir()) / "urdfpost-bench"

GOTO = "GOTO/%.4f,%.4f,%.4f,%.6f,%.6f,%.6f"
CUT_FEED = 2000.0  # mm/min
PLUNGE_FEED = 800.0  # mm/min
RETRACT_FEED = 3000.0  # mm/min
CLEARANCE = 10.0  # mm along the tool axis, for the links between layers
LINK_POINTS = 4  # per layer: above the approach, approach, retract, up to the safe height


def default_path(points: int, feed_per_point: bool = False) -> Path:
    """Where :func:`write_hemisphere` puts a file of ``points`` points by default."""
    return DATA_DIR / f"hemisphere_{'fed_' if feed_per_point else ''}{points}.apt"


def _goto_lines(tip: np.ndarray, axis: np.ndarray, feeds: np.ndarray | None = None) -> str:
    """GOTO records of the rows of ``tip`` (mm) and ``axis``, shapes (k, 3), one per line; with
    ``feeds`` (mm/min, shape (k,)), a FEDRAT before each."""
    rows = np.hstack([tip, axis]).tolist()
    if feeds is None:
        return "\n".join([GOTO % tuple(r) for r in rows]) + "\n"
    lines = [f"FEDRAT/MMPM,{f:.1f}\n{GOTO % tuple(r)}" for f, r in zip(feeds, rows, strict=True)]
    return "\n".join(lines) + "\n"


def optimised_feeds(first: int, count: int) -> np.ndarray:
    """The feeds of cutting moves ``first`` to ``first + count`` of a feed-optimised job, as a
    feed optimiser writes one per move: 1500 to 2100 mm/min in steps of 100, changing at every
    move (mm/min, shape (count,))."""
    return 1500.0 + (np.arange(first, first + count) % 7) * 100.0


def pass_layout(points: int, layers: int, radius: float, max_tilt: float) -> list[np.ndarray]:
    """Points per pass, one array per layer.

    The passes of a layer are parallel chords of the disc the raster covers (radius
    ``radius * sin(max_tilt)`` seen from above), an odd number of them so that the middle one
    runs over the top. Counts are proportional to the chord lengths, at least 3, and odd on the
    middle pass so that it has a point exactly on the top.

    Returns
    -------
    list of ndarray of int, one of shape (passes,) per layer
        Motion points of each pass (the links between layers come on top:
        :data:`LINK_POINTS` per layer).
    """
    per_layer = max(points - LINK_POINTS * layers, 3 * layers) / layers
    # passes ~ sqrt of the points per layer, with the stepover about 4x the point spacing
    passes = max(3, int(math.sqrt(per_layer / 4.0 * math.pi / 4.0)) | 1)
    disc = radius * math.sin(max_tilt)
    offsets = np.linspace(-disc, disc, passes + 2)[1:-1]  # no zero-length pass on the rim
    lengths = 2.0 * np.sqrt(disc**2 - offsets**2)
    counts = []
    budget = points - LINK_POINTS * layers
    for layer in range(layers):
        share = budget // layers + (layer < budget % layers)
        c = np.maximum(3, np.floor(lengths / lengths.sum() * share).astype(int))
        c[np.argsort(-lengths)[: max(0, share - int(c.sum()))]] += 1  # hand out the remainder
        middle = passes // 2
        if c[middle] % 2 == 0:  # a point exactly on the top; take it from the next pass
            c[middle] += 1
            c[middle + 1] -= 1
        counts.append(c)
    return counts


def hemisphere_records(
    points: int,
    *,
    layers: int = 4,
    radius: float = 40.0,
    max_tilt_deg: float = 60.0,
    feed_per_point: bool = False,
) -> Iterator[str]:
    """Text of the job, in chunks (one per pass and some for the frame records).

    Parameters
    ----------
    points : int
        Motion points (GOTO records) in the file, >= 20.
    layers : int
        Raster directions, evenly spread over a half turn.
    radius : float, mm
        Radius of the hemisphere (CL points are on it: a ball-end tip follows the offset
        surface of the part).
    max_tilt_deg : float, degrees
        Largest angle of the tool axis from +Z.
    feed_per_point : bool
        A FEDRAT before every cutting move (:func:`optimised_feeds`), as feed-optimised CL
        data has, instead of one per layer.

    Yields
    ------
    str
        Lines of the file, each chunk ending with a newline.
    """
    if points < 20:
        raise ValueError(f"points: expected at least 20, got {points}")
    max_tilt = math.radians(max_tilt_deg)
    disc = radius * math.sin(max_tilt)
    cut = 0  # cutting moves so far
    yield (
        "PARTNO HEMISPHERE BENCHMARK\n"
        "UNITS/MM\n"
        "MULTAX/ON\n"
        f"$$ {points} CL points, {layers} raster layers over a {radius:g} mm hemisphere, "
        "tool normal to the surface\n"
        "LOADTL/1\n"
        "CUTTER/6.0,3.0\n"
        "SPINDL/12000,CLW\n"
        "COOLNT/FLOOD\n"
    )
    for layer, counts in enumerate(pass_layout(points, layers, radius, max_tilt)):
        angle = math.pi * layer / layers
        along = np.array([math.cos(angle), math.sin(angle), 0.0])
        across = np.array([-math.sin(angle), math.cos(angle), 0.0])
        offsets = np.linspace(-disc, disc, len(counts) + 2)[1:-1]
        offsets[len(counts) // 2] = 0.0  # exactly over the top
        yield f"PPRINT LAYER {layer + 1} AT {math.degrees(angle):.1f} DEG\n"
        for k, (v, count) in enumerate(zip(offsets, counts, strict=True)):
            half = math.sqrt(max(disc**2 - v**2, 0.0))
            u = np.linspace(-half, half, int(count))
            if k % 2:
                u = u[::-1]
            if count % 2:
                u[count // 2] = 0.0
            xy = u[:, None] * along + v * across
            z = np.sqrt(np.maximum(radius**2 - np.sum(xy**2, axis=1), 0.0))
            tip = np.column_stack([xy[:, :2], z])
            axis = tip / radius
            first = 1 if k == 0 else 0  # the plunge, at its own feed
            feeds = optimised_feeds(cut, len(tip) - first) if feed_per_point else None
            cut += len(tip) - first
            if k == 0:
                approach = tip[:1] + CLEARANCE * axis[:1]
                above = approach.copy()
                above[:, 2] = radius + 2.0 * CLEARANCE
                yield "RAPID\n" + _goto_lines(above, axis[:1])
                yield "RAPID\n" + _goto_lines(approach, axis[:1])
                yield f"FEDRAT/MMPM,{PLUNGE_FEED:.1f}\n" + _goto_lines(tip[:1], axis[:1])
                yield f"FEDRAT/MMPM,{CUT_FEED:.1f}\n" + _goto_lines(tip[1:], axis[1:], feeds)
            else:
                yield _goto_lines(tip, axis, feeds)
        retract = tip[-1:] + CLEARANCE * axis[-1:]
        yield f"FEDRAT/MMPM,{RETRACT_FEED:.1f}\n" + _goto_lines(retract, axis[-1:])
        retract[:, 2] = radius + 2.0 * CLEARANCE
        yield "RAPID\n" + _goto_lines(retract, axis[-1:])
    yield "COOLNT/OFF\nSPINDL/OFF\nEND\nFINI\n"


def write_hemisphere(points: int, path: Path | None = None, **kwargs: Any) -> Path:
    """Write the hemisphere job of ``points`` points to ``path`` (see :func:`default_path`).

    Returns
    -------
    Path
        The file written.
    """
    if path is None:
        path = default_path(points, bool(kwargs.get("feed_per_point")))
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(path.suffix + ".part")
    with open(tmp, "w", encoding="ascii", newline="\n") as handle:
        buffer: list[str] = []
        size = 0
        for chunk in hemisphere_records(points, **kwargs):
            buffer.append(chunk)
            size += len(chunk)
            if size > 1 << 22:
                handle.write("".join(buffer))
                buffer, size = [], 0
        handle.write("".join(buffer))
    tmp.replace(path)
    return path


def ensure_file(points: int, path: Path | None = None) -> Path:
    """The default file of ``points`` points, written when absent."""
    path = Path(path) if path is not None else default_path(points)
    if not path.is_file():
        write_hemisphere(points, path)
    return path


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("points", type=int, help="number of GOTO records (e.g. 1000000)")
    parser.add_argument("-o", "--output", type=Path, help="file to write")
    parser.add_argument("--layers", type=int, default=4, help="raster directions (default 4)")
    parser.add_argument("--radius", type=float, default=40.0, help="mm (default 40)")
    parser.add_argument(
        "--max-tilt", type=float, default=60.0, help="largest tool tilt from +Z, deg (default 60)"
    )
    parser.add_argument(
        "--feed-per-point",
        action="store_true",
        help="a FEDRAT before every cutting move, as feed-optimised CL data has "
        "(default file hemisphere_fed_<points>.apt)",
    )
    args = parser.parse_args(argv)
    t = time.perf_counter()
    path = write_hemisphere(
        args.points,
        args.output,
        layers=args.layers,
        radius=args.radius,
        max_tilt_deg=args.max_tilt,
        feed_per_point=args.feed_per_point,
    )
    dt = time.perf_counter() - t
    size = path.stat().st_size / 1e6
    print(f"wrote {path}: {args.points} points, {size:.1f} MB in {dt:.2f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
