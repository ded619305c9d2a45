"""The ``urdfpost`` command line.

``main(argv) -> int``: usage errors exit 2 (argparse), domain errors print ``urdfpost: <message>``
on stderr and exit 1. Files are read and written only here and in the readers; outputs are
written to a temporary file and renamed, so a failed run leaves no half-written file.
"""

from __future__ import annotations

import argparse
import logging
import os
import signal
import sys
import tempfile
import threading
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from urdfpost import __version__, _stops
from urdfpost._files import check_distinct, output_target, temp_file, write_texts
from urdfpost._memory import keep_freed_memory
from urdfpost._stops import Terminated
from urdfpost.errors import UrdfpostError
from urdfpost.posting import PIECE_POINTS
from urdfpost.posting.tools import read_tool_table
from urdfpost.strict_json import report_json
from urdfpost.units import UNITS, mm_per_unit, program_units

if TYPE_CHECKING:
    from urdfpost.posting.stream import StreamResult
    from urdfpost.posting.whole import PostResult

log = logging.getLogger("urdfpost")

MAX_WARNINGS_SHOWN = 20
_STREAM_BYTES = 16 << 20  # CL files larger than this are posted in pieces by default


def _given(inputs: dict[str, Any]) -> dict[str, Any]:
    """The inputs that were given (an option left out is None)."""
    return {role: path for role, path in inputs.items() if path is not None}


def _program_units(args: argparse.Namespace, machine: Any, cl_units: str) -> str:
    """The program units: ``--units``, else the machine file's setting, else ``cl_units``
    (``verify`` has no ``--units``: its program says)."""
    return program_units(getattr(args, "units", None), machine.settings.units, cl_units)


def _read_cl(args: argparse.Namespace, machine: Any) -> Any:
    """Read the CL file, interpolating arcs with the chord tolerance of the program units.

    The CL units are ``--cl-units`` when given (a file that says otherwise gets a warning),
    else the file's own, else mm (never the machine's); arcs are read again when the program
    units (:func:`_program_units`) turn out to differ from the guess.
    """
    from urdfpost.readers import read_cl
    from urdfpost.tolerances import Tolerances

    cl_units = args.cl_units
    guess = _program_units(args, machine, cl_units or "mm")
    chord = Tolerances.for_units(guess, args.tolerance).chord
    # a work offset per MCS: each MCS's points as its MSYS has them
    separate = getattr(args, "mcs_offsets", False)
    toolpath = read_cl(
        args.cl, format=args.format, units=cl_units, chord_tolerance=chord, separate_mcs=separate
    )
    units = _program_units(args, machine, toolpath.units)
    if units != guess:
        chord = Tolerances.for_units(units, args.tolerance).chord
        toolpath = read_cl(
            args.cl,
            format=args.format,
            units=cl_units,
            chord_tolerance=chord,
            separate_mcs=separate,
        )
    return toolpath


def _read_cl_pieces(
    args: argparse.Namespace, machine: Any, points: int
) -> tuple[Any, Iterator[Any]]:
    """The CL file as pieces of at most ``points`` points, read as they are needed.

    Returns the first piece (for the units) and an iterator over all of them, the first
    included; as :func:`_read_cl` for the units and the chord tolerance.
    """
    import itertools

    from urdfpost.readers import read_cl_chunks
    from urdfpost.tolerances import Tolerances

    cl_units = args.cl_units
    guess = _program_units(args, machine, cl_units or "mm")

    def pieces(chord: float) -> Iterator[Any]:
        return read_cl_chunks(
            args.cl, max_points=points, format=args.format, units=cl_units, chord_tolerance=chord
        )

    chunks = pieces(Tolerances.for_units(guess, args.tolerance).chord)
    first = next(chunks)
    units = _program_units(args, machine, first.units)
    if units != guess:
        chunks = pieces(Tolerances.for_units(units, args.tolerance).chord)
        first = next(chunks)
    return first, itertools.chain([first], chunks)


def _non_negative(value: str) -> float:
    try:
        v = float(value)
    except ValueError as e:
        raise argparse.ArgumentTypeError(f"expected a number, got {value!r}") from e
    if not np.isfinite(v) or v < 0:
        raise argparse.ArgumentTypeError(f"expected a non-negative number, got {value!r}")
    return v


def _positive(value: str) -> float:
    v = _non_negative(value)
    if v == 0:
        raise argparse.ArgumentTypeError("expected a positive number, got 0")
    return v


class UsageError(UrdfpostError):
    """An option that does not fit the machine named with it: a usage error (exit 2)."""


def _check_prefer(prefer: Any, machine: Any) -> Any:
    """``--prefer`` when it names a rotary axis of ``machine``."""
    names = [axis.name for axis in machine.rotary]
    if prefer is not None and prefer.axis not in names:
        raise UsageError(
            f"--prefer {prefer.axis}: machine {machine.name} has no rotary axis {prefer.axis}; "
            f"expected one of {', '.join(names)}"
        )
    return prefer


def _piece_points(value: str) -> int:
    try:
        n = int(value)
    except ValueError as e:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {value!r}") from e
    if n < 0 or n == 1:
        raise argparse.ArgumentTypeError(f"expected 0 or at least 2, got {n}")
    return n


def _prefer(value: str) -> Any:
    from urdfpost.planning.branches import Preference

    try:
        return Preference.parse(value)
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e)) from e


def _setup(value: str) -> Any:
    from urdfpost.machine import Setup

    try:
        return Setup.parse(value)
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e)) from e


def _setup_argument(p: argparse.ArgumentParser, units: str) -> None:
    """``--setup``: where the job puts the program zero on the machine."""
    p.add_argument(
        "--setup",
        type=_setup,
        metavar="X,Y,Z[,ROT]",
        help="where the program zero (the CL frame) sits for this job: X,Y,Z its origin in the "
        "frame of the link the URDF mounts the workpiece on (the parent link of the joint "
        f"whose child is 'workpiece', e.g. c_table), {units}; ROT degrees about that link's "
        "+Z, added to the URDF's orientation (default: the URDF's placement; "
        "docs/machines.md). Write --setup=-10,5,80 when it starts with a minus",
    )


def _job_machine(args: argparse.Namespace, machine: Any, scale: float) -> Any:
    """``machine`` with the ``--setup`` of the job (its offset in units of ``scale`` mm)."""
    from urdfpost.errors import MachineDefinitionError
    from urdfpost.machine import with_setup

    if args.setup is None:
        return machine
    try:
        return with_setup(machine, args.setup.scaled(scale))
    except MachineDefinitionError as e:
        raise UsageError(f"--setup: {e}") from e


def _strategy_arguments(p: argparse.ArgumentParser, single: bool) -> None:
    from urdfpost.planning.singularity import DEFAULT_DETECTOR, DETECTORS
    from urdfpost.planning.strategies import DEFAULT_STRATEGY
    from urdfpost.planning.strategies._registry import registered

    if single:
        # checked when the command runs (_checked_strategy), not here: the plug-ins load then,
        # with logging set up, and the strategies a script registered after import count
        p.add_argument(
            "--strategy",
            metavar="NAME",
            help=f"singularity strategy: {', '.join(registered())} or an installed plug-in's "
            f"(entry-point group urdfpost.strategies; default: the machine file's, else "
            f"{DEFAULT_STRATEGY})",
        )
    p.add_argument(
        "--detector",
        choices=DETECTORS,
        help="how singular spans are found: 'geometric' (tool axis near a pole or the tilt "
        "edge, large rotary steps) or 'rate' (a rotary axis faster than its velocity limit at "
        f"the programmed feed; geometric where a cut has no feed) (default {DEFAULT_DETECTOR})",
    )
    p.add_argument(
        "--angle-tolerance",
        type=_positive,
        default=2.0,
        metavar="DEG",
        help="how far a strategy may bend the tool axis, degrees (default 2)",
    )
    p.add_argument(
        "--planner",
        choices=("global", "local"),
        default="global",
        help="branch choice over the whole path (default) or point by point",
    )
    p.add_argument(
        "--lift",
        type=_non_negative,
        default=0.0,
        help="lift along the tool axis inside singular spans, program units (spline; default 0)",
    )


def _checked_strategy(name: str | None) -> str | None:
    """The ``--strategy`` name, checked against every strategy, plug-ins included.

    Raises
    ------
    UsageError
        No strategy has that name (the message lists them).
    UrdfpostError
        A plug-in's name clashes with another strategy's.
    """
    from urdfpost.planning.strategies import STRATEGIES

    if name is None or name in STRATEGIES:
        return name
    raise UsageError(f"--strategy: unknown {name!r}; expected one of {', '.join(STRATEGIES)}")


def _planning_arguments(p: argparse.ArgumentParser) -> None:
    """Collision and rewind options of ``post``."""
    p.add_argument(
        "--stock",
        metavar="MESH",
        help="stock or part mesh (STL, OBJ, ...) in the workpiece frame, program units; "
        "turns collision checks on",
    )
    p.add_argument(
        "--check-collisions",
        action="store_true",
        help="check tool, holder and machine for collisions with FCL (on with --stock)",
    )
    p.add_argument("--holder-diameter", type=_positive, help="tool holder diameter (default 40 mm)")
    p.add_argument("--holder-length", type=_positive, help="tool holder length (default 60 mm)")
    p.add_argument(
        "--retract",
        type=_positive,
        help="lift along the tool axis for a rewind, program units (default 50 mm)",
    )
    p.add_argument(
        "--rewind-feed",
        type=_positive,
        help="feed of a rewind's lift and turn, program units/min (default: rapid)",
    )


def _job_arguments(p: argparse.ArgumentParser) -> None:
    """Work offset, approach and process defaults of ``post``."""
    p.add_argument(
        "--work-offset",
        type=int,
        default=1,
        metavar="N",
        help="work offset the program selects: 1 for G54 (Heidenhain preset 1), 2 for G55, ... "
        "(default 1)",
    )
    p.add_argument(
        "--clearance",
        type=_positive,
        help="approach point above the first point of each tool's path, along its tool axis, "
        "program units (default 10 mm)",
    )
    p.add_argument(
        "--feed",
        type=_positive,
        help="feed for cutting moves the CL data gives none for, program units/min "
        "(default: such a move is an error)",
    )
    p.add_argument(
        "--feed-mode",
        choices=("auto", "tip", "inverse-time", "per-block"),
        help="how the F words are made: 'tip' the CL tip feed (right with TCP), "
        "'inverse-time' G93 (F = 1/block time), 'per-block' F per minute of each block's "
        "axis-space length; 'auto': tip with TCP, else inverse time where the control has "
        "it, else per block (default: the machine file's feed_mode, else auto). Every "
        "block's F is lowered where an axis would exceed its URDF velocity limit",
    )
    p.add_argument(
        "--spindle",
        type=_positive,
        metavar="RPM",
        help="spindle speed (clockwise) for cutting the CL data does not start the spindle "
        "for (default: such a move is an error)",
    )
    p.add_argument(
        "--no-arcs",
        dest="arcs",
        action="store_false",
        help="write the CL data's arcs (CIRCLE) as lines, as interpolated (default: as G2/G3, "
        "Heidenhain CC + C, where the control, the plane and a fixed tool axis allow it)",
    )
    p.add_argument(
        "--tilted-planes",
        dest="tilted_planes",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="write an operation at a fixed tilt (3+2) in a tilted working plane: PLANE "
        "SPATIAL (Heidenhain), CYCLE800 (Siemens), G68.2 (Fanuc), in TCP programs; LinuxCNC "
        "has none (default: the machine file's tilted_planes, else on)",
    )
    p.add_argument(
        "--expand-cycles",
        action="store_true",
        help="write the CL data's canned cycles (CYCLE/DRILL...) as the motion they make "
        "instead of the control's drilling cycles",
    )


def _tool_table_argument(p: argparse.ArgumentParser) -> None:
    """``--tool-table``: each tool's gauge length, for machine-coordinate programs."""
    p.add_argument(
        "--tool-table",
        metavar="FILE",
        help="machine-coordinate programs: each tool's gauge length from this LinuxCNC tool "
        "table (lines 'T1 P1 Z101.6 D12.7', lengths in program units); a tool not in it has "
        "the CL data's LOADTL LENGTH, else --tool-length",
    )


def _mcs_offsets_argument(p: argparse.ArgumentParser) -> None:
    """``--mcs-offsets``: one work offset per NX MCS."""
    p.add_argument(
        "--mcs-offsets",
        action="store_true",
        help="TCP programs: one work offset per MCS of an NX CL file (G54 for the first MCS, "
        "G55 for the next ..., from --work-offset), each MCS's points as its MSYS has them; "
        "default: every MCS transformed into the first (a job with it is posted whole)",
    )


def _cl_units_argument(p: argparse.ArgumentParser, *aliases: str) -> None:
    """``--cl-units``: the units the CL file is read in."""
    p.add_argument(
        "--cl-units",
        *aliases,
        dest="cl_units",
        choices=UNITS,
        help="units of the CL data, overriding what the file says (with a warning when it "
        "says otherwise); default the file's own units, else mm",
    )


def build_parser() -> argparse.ArgumentParser:
    """The argument parser (exposed for documentation and tests)."""
    from urdfpost.analysis import COLOR_BY as VIEW_COLORS
    from urdfpost.dialects import DIALECTS
    from urdfpost.readers import FORMATS

    controllers = sorted(DIALECTS)
    p = argparse.ArgumentParser(
        prog="urdfpost",
        description="Five-axis post-processor for any machine described by a URDF.",
    )
    p.add_argument("--version", action="version", version=f"urdfpost {__version__}")
    p.add_argument("-v", "--verbose", action="count", default=0, help="more detail (-vv: debug)")
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")

    po = sub.add_parser("post", help="post a CL file for a machine and control")
    po.add_argument("cl", help="CL file (APT, CATIA, Creo, NX CLSF, or plain 'x y z i j k')")
    po.add_argument("--machine", "-m", required=True, help="machine name or URDF file")
    po.add_argument("--controller", "-c", choices=controllers, help="control dialect")
    po.add_argument("-o", "--output", help="program file (default: CL name + control extension)")
    tcp = po.add_mutually_exclusive_group()
    tcp.add_argument(
        "--tcp",
        dest="tcp",
        action="store_true",
        default=True,
        help="tool tip in workpiece coordinates, TCP on (default)",
    )
    tcp.add_argument(
        "--no-tcp",
        dest="tcp",
        action="store_false",
        help="machine axis positions: the post does the kinematics",
    )
    po.add_argument(
        "--units",
        choices=UNITS,
        help="program units (default: the machine file's units setting, else the CL file's)",
    )
    _cl_units_argument(po)
    po.add_argument(
        "--tool-length",
        type=_non_negative,
        help="tool length, gauge point to tip, in program units",
    )
    _tool_table_argument(po)
    _mcs_offsets_argument(po)
    po.add_argument(
        "--tolerance",
        type=_positive,
        help="tool-tip tolerance in program units (default 0.01 mm / 0.0004 in)",
    )
    smoothing = po.add_mutually_exclusive_group()
    smoothing.add_argument(
        "--smoothing",
        nargs="?",
        const=True,
        type=_positive,
        metavar="TOL",
        help="write the control's path smoothing cycle (CYCL DEF 32, CYCLE832, G05.1 Q1, "
        "G64 P), with its path tolerance TOL in program units (default: the tool-tip "
        "tolerance); default: the machine file's smoothing setting, else on",
    )
    smoothing.add_argument(
        "--no-smoothing",
        dest="smoothing",
        action="store_const",
        const=False,
        help="write no path smoothing cycle (the control's own path mode)",
    )
    po.add_argument("--prefer", type=_prefer, help="preferred rotary branch, e.g. B+ or B-")
    _setup_argument(po, "program units")
    _strategy_arguments(po, single=True)
    po.add_argument("--format", choices=list(FORMATS), help="CL format (default: detected)")
    po.add_argument("--block-numbers", action="store_true", help="number the blocks")
    po.add_argument("--name", help="program name (default: PARTNO or URDFPOST)")
    po.add_argument("--report", help="write a JSON report here")
    po.add_argument(
        "--view",
        metavar="HTML",
        help="also write the 3-D view of the program (as 'urdfpost view' does)",
    )
    po.add_argument(
        "--view-color",
        choices=VIEW_COLORS,
        help="with --view: colour the tool-tip trace by deviation or by axis speed",
    )
    po.add_argument(
        "--piece-points",
        type=_piece_points,
        metavar="N",
        help="post in pieces of about N CL points, read, written and verified one at a time "
        "(bounded memory for long jobs; each piece verified in a second process while the next "
        "is planned); 0: never. Default: pieces of "
        f"{PIECE_POINTS} points when the CL file is over {_STREAM_BYTES >> 20} MB",
    )
    po.add_argument(
        "--single-process",
        action="store_true",
        help="with --piece-points: time, write and verify each piece in this process after it "
        "is planned (by default a second process does while the next is planned)",
    )
    _planning_arguments(po)
    _job_arguments(po)
    po.add_argument("--quiet", "-q", action="store_true", help="no progress bar")

    ve = sub.add_parser("verify", help="check an NC program against its CL data")
    ve.add_argument("program", help="NC program in any supported dialect")
    ve.add_argument("--machine", "-m", required=True, help="machine name or URDF file")
    ve.add_argument("--cl", required=True, help="the CL file the program was made from")
    ve.add_argument(
        "--controller",
        "-c",
        choices=controllers,
        help="dialect of the program (default: from its extension)",
    )
    _cl_units_argument(ve, "--units")
    ve.add_argument(
        "--tool-length",
        type=_non_negative,
        help="tool length in program units (machine-coordinate programs)",
    )
    _tool_table_argument(ve)
    _mcs_offsets_argument(ve)
    ve.add_argument("--tolerance", type=_positive, help="tool-tip tolerance in program units")
    _setup_argument(ve, "the program's units")
    ve.add_argument(
        "--angle-tolerance",
        type=_non_negative,
        default=0.0,
        metavar="DEG",
        help="tool-axis bending the program's strategy was allowed, degrees (default 0: the "
        "program must follow the CL tool axis; a post's program: the --angle-tolerance it was "
        "posted with, 2 by default); when given, a ball-end tool is measured at its ball "
        "centre, as the post checks a program it bent, against the curve the CL data moves "
        "the ball centre on (the tip straight, the tool axis on its slerp)",
    )
    ve.add_argument("--format", choices=list(FORMATS), help="CL format (default: detected)")
    ve.add_argument("--report", help="write a JSON report here")
    ve.add_argument(
        "--piece-points",
        type=_piece_points,
        metavar="N",
        help="read and check in pieces of about N CL points (bounded memory for long jobs; "
        "the same figures, but for the mean deviation; the pieces verified in worker processes, "
        "one per core, while the next are read); 0: never. Default: pieces of "
        f"{PIECE_POINTS} points when the CL file or the program is over {_STREAM_BYTES >> 20} MB",
    )
    ve.add_argument(
        "--single-process",
        action="store_true",
        help="with --piece-points: verify each piece in this process after it is read (by "
        "default worker processes verify them while the next are read)",
    )

    vw = sub.add_parser(
        "view",
        help="write a 3-D view of the machine running a program (one HTML file)",
        description="Write one self-contained HTML file that shows the machine from its URDF "
        "visuals, the stock, the tool, the CL path and the tool-tip trace, and plays the "
        "program (play/pause, timeline, speed, the current block and its NC line, the axis "
        "values; singular spans, rewinds and the worst deviation marked). It opens offline.",
    )
    vw.add_argument("program", help="NC program in any supported dialect")
    vw.add_argument("--machine", "-m", required=True, help="machine name or URDF file")
    vw.add_argument("--cl", help="the CL file the program was made from (drawn, and measured)")
    vw.add_argument(
        "--controller",
        "-c",
        choices=controllers,
        help="dialect of the program (default: from its extension)",
    )
    vw.add_argument(
        "--stock", help="stock or part mesh (STL, OBJ, ...), workpiece frame, program units"
    )
    vw.add_argument(
        "--color",
        choices=VIEW_COLORS,
        help="colour the tool-tip trace by its distance to the CL path (needs --cl) or by the "
        "largest axis speed as a fraction of its limit",
    )
    _cl_units_argument(vw, "--units")
    vw.add_argument(
        "--tool-length",
        type=_non_negative,
        help="tool length in program units (default: the machine file's)",
    )
    _tool_table_argument(vw)
    vw.add_argument("--tolerance", type=_positive, help=argparse.SUPPRESS)
    vw.add_argument("--format", choices=list(FORMATS), help="CL format (default: detected)")
    _setup_argument(vw, "the program's units")
    vw.add_argument("-o", "--output", required=True, help="the HTML file to write")

    co = sub.add_parser(
        "compare",
        help="post a CL file with several singularity strategies",
        description="Post a CL file with several singularity strategies and measure each "
        "program the same way. A strategy that makes no program, or one that misses its "
        "tolerance, is a row of the table with its reason; the report and the plot are "
        "written all the same. Exit status: 0 when at least one strategy makes a verified "
        "program, 1 when none does (nothing 'urdfpost post' would write) or on an error, 2 "
        "on a usage error.",
    )
    co.add_argument("cl", help="CL file")
    co.add_argument("--machine", "-m", required=True, help="machine name or URDF file")
    co.add_argument("--controller", "-c", choices=controllers, help="control dialect")
    co.add_argument(
        "--strategies",
        default="all",
        help="'all' or a comma-separated list of strategy names (default all)",
    )
    co.add_argument(
        "--no-tcp",
        dest="tcp",
        action="store_false",
        default=True,
        help="machine axis positions instead of TCP",
    )
    co.add_argument(
        "--units",
        choices=UNITS,
        help="program units (default: the machine file's units setting, else the CL file's)",
    )
    _cl_units_argument(co)
    co.add_argument("--tool-length", type=_non_negative, help="tool length in program units")
    co.add_argument("--tolerance", type=_positive, help="tool-tip tolerance in program units")
    co.add_argument("--prefer", type=_prefer, help="preferred rotary branch, e.g. B+")
    _setup_argument(co, "program units")
    _strategy_arguments(co, single=False)
    co.add_argument("--format", choices=list(FORMATS), help="CL format (default: detected)")
    co.add_argument("--report", help="write the figures as JSON here")
    co.add_argument(
        "--csv",
        help="write per-block data as CSV here: one row per program row per strategy (CL "
        "index, time, axis positions, velocities, accelerations, jerks, tip feed, deviations)",
    )
    co.add_argument(
        "--plot",
        help="write a PNG of rotary angles and speeds against CL index and time here "
        "(failing strategies marked)",
    )

    tp = sub.add_parser("testpath", help="write a shipped singular test path as APT")
    tp.add_argument("name", help="path name (see --list)", nargs="?")
    tp.add_argument("-o", "--output", help="APT file (default NAME.apt; - for standard output)")
    tp.add_argument("--list", action="store_true", help="list the shipped paths")

    sub.add_parser("machines", help="list the machines urdfpost knows by name")
    ma = sub.add_parser("machine", help="describe a machine")
    ma_sub = ma.add_subparsers(dest="machine_command", required=True, metavar="ACTION")
    show = ma_sub.add_parser("show", help="family, axes, travels, singular directions")
    show.add_argument("name", help="machine name or URDF file")
    return p


def _setup_logging(verbose: int) -> Callable[[], None]:
    """Send the library's log to stderr; returns what restores the logger as it was (so a
    caller running :func:`main` in-process keeps its own logging)."""
    level = logging.WARNING if verbose == 0 else logging.INFO if verbose == 1 else logging.DEBUG
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(logging.Formatter("urdfpost: %(levelname)s: %(message)s"))
    root = logging.getLogger("urdfpost")
    saved = (root.handlers[:], root.level, root.propagate)

    def restore() -> None:
        root.handlers[:], root.propagate = saved[0], saved[2]
        root.setLevel(saved[1])

    root.handlers[:] = [handler]
    root.setLevel(level)
    root.propagate = False
    return restore


def _show_warnings(warnings: Sequence[str]) -> None:
    for w in warnings[:MAX_WARNINGS_SHOWN]:
        print(f"urdfpost: warning: {w}", file=sys.stderr)
    if len(warnings) > MAX_WARNINGS_SHOWN:
        print(
            f"urdfpost: warning: ... and {len(warnings) - MAX_WARNINGS_SHOWN} more warnings "
            "(all are in the --report JSON)",
            file=sys.stderr,
        )


def _cmd_post(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from urdfpost.dialects import dialect_for
    from urdfpost.machine import load_machine
    from urdfpost.posting.options import PostOptions
    from urdfpost.posting.whole import post

    # no monitor thread: a streamed post forks its verification worker, best from one thread
    tqdm.monitor_interval = 0

    strategy = _checked_strategy(args.strategy)  # a usage error before any work
    machine = load_machine(args.machine)
    pieces = args.piece_points
    if args.mcs_offsets:
        if pieces:
            raise UsageError("--mcs-offsets posts the job whole; expected no --piece-points")
        pieces = 0
    if pieces is None:
        size = Path(args.cl).stat().st_size if Path(args.cl).is_file() else 0
        pieces = PIECE_POINTS if size > _STREAM_BYTES else 0
    if pieces:
        toolpath, chunks = _read_cl_pieces(args, machine, pieces)
    else:
        toolpath, chunks = _read_cl(args, machine), None
    units = _program_units(args, machine, toolpath.units)
    scale = mm_per_unit(units)
    machine = _job_machine(args, machine, scale)
    dialect = dialect_for(
        args.controller or (None if args.output else machine.settings.controller), args.output
    ).with_clamps(machine.settings.clamps)
    offsets = dialect.spec.work_offsets
    if not 1 <= args.work_offset <= offsets:
        raise UsageError(
            f"--work-offset {args.work_offset}: {dialect.name} has work offsets 1 to {offsets}"
        )
    options = PostOptions(
        controller=dialect.name,
        tcp=args.tcp,
        units=units,
        tool_length=None if args.tool_length is None else args.tool_length * scale,
        tolerance=args.tolerance,
        prefer=_check_prefer(args.prefer, machine),
        block_numbers=args.block_numbers,
        program_name=args.name,
        strategy=strategy,
        detector=args.detector,
        angle_tolerance=args.angle_tolerance,
        planner=args.planner,
        lift=args.lift,
        retract=args.retract,
        rewind_feed=args.rewind_feed,
        collisions=args.check_collisions,
        stock=args.stock,
        holder_diameter=args.holder_diameter,
        holder_length=args.holder_length,
        work_offset=args.work_offset,
        clearance=args.clearance,
        feed=args.feed,
        spindle=args.spindle,
        tool_table=None if args.tool_table is None else read_tool_table(args.tool_table, scale),
        mcs_offsets=args.mcs_offsets,
        expand_cycles=args.expand_cycles,
        smoothing=None if args.smoothing is None else args.smoothing is not False,
        smoothing_tolerance=args.smoothing if isinstance(args.smoothing, float) else None,
        feed_mode=args.feed_mode,
        arcs=args.arcs,
        tilted_planes=args.tilted_planes,
    )
    out = Path(args.output) if args.output else Path(Path(args.cl).stem + dialect.extensions[0])
    inputs = {
        "the CL file": args.cl,
        "the stock mesh": args.stock,
        "the machine file": machine.path,
    }
    outputs = _given(
        {
            "the program (-o)": out,
            "the report (--report)": args.report,
            "the view (--view)": args.view,
        }
    )
    check_distinct(outputs, _given(inputs))  # before any work: all or nothing
    targets = [output_target(path) for path in outputs.values()]
    roles = {Path(path): role for role, path in outputs.items()}
    staged: dict[Path, Path] = {}
    with tqdm(
        total=None if chunks is not None else len(toolpath),
        unit="pt",
        desc="posting",
        disable=args.quiet or None,
        file=sys.stderr,
        leave=False,
    ) as bar:
        files: dict[Path, str] = {}
        result: PostResult | StreamResult
        if chunks is not None:
            from urdfpost.posting.stream import post_stream

            # streamed into a hidden file beside the program (in the temporary folder for a
            # device), moved into place with the report
            target = targets[0]
            folder = target.real.parent if target.regular else Path(tempfile.gettempdir())
            fd, stage = temp_file(target.real, folder=folder)  # (stale ones removed)
            os.close(fd)
            staged[out] = Path(stage)
            try:
                result = post_stream(
                    chunks,
                    machine,
                    Path(stage),
                    options,
                    piece_points=pieces,
                    progress=bar.update,
                    parallel=False if args.single_process else None,
                )
            except BaseException as e:
                Path(stage).unlink(missing_ok=True)
                if isinstance(e, OSError):  # the disk filled up, the folder went away
                    raise UrdfpostError(f"{out}: cannot write: {e.strerror or e}") from e
                raise
        else:
            whole = post(toolpath, machine, options, progress=bar.update)
            files[out] = whole.text
            result = whole
    report = result.report
    view = None
    try:
        _show_warnings(list(report.warnings))
        if args.report:
            files[Path(args.report)] = report_json(report.as_json())
        if args.view:  # the program as written, read back
            text = files[out] if out in files else Path(staged[out]).read_text(encoding="utf-8")
            cl = toolpath if chunks is None else None  # (a streamed post holds no whole CL)
            files[Path(args.view)], view = _view_html(
                machine, dialect, text, str(out), cl, args.stock, report.tool_length_mm,
                args.view_color, tool_lengths=report.tool_lengths_mm,
            )  # fmt: skip
        write_texts(files, _given(inputs), roles, staged)
    except BaseException:  # Ctrl-C, SIGTERM before write_texts took the staged program
        for stage_path in staged.values():
            stage_path.unlink(missing_ok=True)
        raise
    mode = "TCP" if args.tcp else "machine coordinates"
    print(f"wrote {out} ({dialect.name}, {mode}, {units}) for machine {machine.name}")
    strat = report.strategy
    assert strat is not None
    spans = strat.spans
    kinds = ", ".join(f"{sp.kind} at CL lines {sp.first_line}-{sp.last_line}" for sp in spans[:5])
    more = f" and {len(spans) - 5} more" if len(spans) > 5 else ""
    found = f" ({kinds}{more})" if kinds else ""
    print(f"strategy {strat.name}: {len(spans)} singular spans{found}")
    for r in report.rewinds:
        print(f"rewind at CL line {r.cl_line}: {r.comment.split(': ', 1)[1]}")
    hits = report.collisions
    if hits.checked:
        clearance = (hits.min_clearance or 0.0) / scale
        print(
            f"collisions: none in {hits.moves} moves ({hits.samples} samples, "
            f"{hits.pairs_checked} body pairs); clearance {clearance:.3f} {units} "
            f"({' and '.join(hits.nearest or [])}) at CL line {hits.at_cl_line}"
        )
    print(result.verification.summary(units))
    if report.figures is not None and report.figures.feeds is not None:
        print(report.figures.feeds.duration())
    if view is not None:
        print(_view_summary(Path(args.view), view))
    return 0


def _cmd_verify(args: argparse.Namespace) -> int:
    import math

    from urdfpost.dialects import dialect_for
    from urdfpost.machine import load_machine
    from urdfpost.posting.process import SpindleState, checked_process
    from urdfpost.posting.report import Report
    from urdfpost.tolerances import Tolerances
    from urdfpost.verification import verify_matched
    from urdfpost.verification.process import (
        ProcessChecker,
        end_words,
        located,
        read_with_end,
        rounding_of,
    )

    machine = load_machine(args.machine)
    dialect = dialect_for(args.controller, None if args.controller else args.program)
    dialect = dialect.with_clamps(machine.settings.clamps)
    pieces = args.piece_points
    if args.mcs_offsets:
        if pieces:
            raise UsageError("--mcs-offsets verifies the program whole; expected no --piece-points")
        pieces = 0
    if pieces is None:
        sizes = [Path(f).stat().st_size for f in (args.cl, args.program) if Path(f).is_file()]
        pieces = PIECE_POINTS if max(sizes, default=0) > _STREAM_BYTES else 0
    text = ""
    ended = False
    if pieces:  # the program's header (units) from its first piece of text
        from urdfpost.posting.readback import CUT_MARGIN, program_texts

        head = next(program_texts(args.program, 1 << 16), "")
        program = dialect.read(head, path=args.program, rollover=machine.settings.rollover)
        # (one read per piece checked: verify_stream holds the points just past a piece)
        toolpath, chunks = _read_cl_pieces(args, machine, pieces + CUT_MARGIN)
    else:
        try:
            text = Path(args.program).read_text(encoding="utf-8", errors="replace")
        except OSError as e:
            raise UrdfpostError(f"{args.program}: cannot read: {e.strerror or e}") from e
        rollover = machine.settings.rollover
        program, ended = read_with_end(dialect, text, path=args.program, rollover=rollover)
        toolpath, chunks = _read_cl(args, machine), None
    from urdfpost.posting.header import bent_in_header

    stated_bend = bent_in_header(program)  # what the post's strategy may bend, as it says
    scale = mm_per_unit(program.units)
    machine = _job_machine(args, machine, scale)
    tol = Tolerances.for_units(program.units, args.tolerance)
    tool_length = (
        machine.settings.tool_length if args.tool_length is None else args.tool_length * scale
    )
    table = None if args.tool_table is None else read_tool_table(args.tool_table, scale)
    pivot = 0.0
    plain_tol = tol
    if args.angle_tolerance > 0:
        from urdfpost.posting.check import bent_tolerances
        from urdfpost.posting.tools import cutting_points

        pivot = cutting_points(toolpath)[0]  # (at the first CL point: the first piece has it)
        tol = bent_tolerances(tol, args.angle_tolerance, pivot)
    # the process the post makes of the CL data; NaN where the CL data has no feed or speed
    # (a post fills those from --feed and --spindle, which the program says nothing of)
    process = ProcessChecker(
        machine,
        tol=tol,
        tool_length=tool_length,
        pivot=pivot,
        rounding=rounding_of(dialect, program.units),
        end=end_words(dialect),
    )

    from urdfpost.verification.feeds import FeedRules

    # how the control times the blocks (the largest inverse-time F counts in G93 only)
    feed_rules = FeedRules.of(dialect.spec, program.units)

    def expected(cl: Any, state: Any = None) -> tuple[Any, Any]:
        cl, state, _ = checked_process(
            cl, feed=math.nan, spindle=math.nan, units=program.units, state=state
        )
        return cl, state

    if chunks is not None:
        from dataclasses import replace

        from urdfpost.posting.readback import program_texts, verify_stream

        warnings: list[str] = []

        def collected(pieces: Iterator[Any]) -> Iterator[Any]:
            state: SpindleState | None = None
            for piece in pieces:  # every piece's reader warnings, in order
                warnings.extend(piece.warnings)
                piece, state = expected(piece, state)
                yield piece

        check, program = verify_stream(
            args.program,
            collected(chunks),
            machine,
            dialect.name,
            tol=plain_tol if args.angle_tolerance > 0 else tol,
            tool_length=tool_length,
            pivot=pivot,
            bent=args.angle_tolerance if args.angle_tolerance > 0 else None,
            piece_points=pieces,
            process=process,
            table=table,
            feed_rules=feed_rules,
            parallel=False if args.single_process else None,
        )
        toolpath = replace(toolpath, warnings=tuple(warnings))
        process_check = process.result()
        faults = located(process_check, dialect, lambda: program_texts(args.program), args.program)
    else:
        from urdfpost.posting.readback import merge_verifications
        from urdfpost.posting.tools import (
            in_own_mcs,
            mcs_machine,
            mcs_shifts,
            paired_sections,
            transformed_mcs,
        )

        checks = []
        cl_data = expected(toolpath)[0]
        shifts = mcs_shifts(cl_data) if args.mcs_offsets else {}
        bent = args.angle_tolerance > 0  # measured at each tool's cutting point
        sections = paired_sections(
            program, cl_data, tool_length, table, by_mcs=args.mcs_offsets, by_pivot=bent
        )
        for k, (part, cl, section) in enumerate(sections):
            on = machine
            if section.mcs in shifts:  # its points as its MCS has them, on that machine
                on = mcs_machine(machine, shifts[section.mcs])
                cl = in_own_mcs(cl, shifts[section.mcs], transformed_mcs(cl_data))
            length = section.length
            point, section_tol = pivot, tol
            if bent:
                point = section.pivot
                section_tol = bent_tolerances(plain_tol, args.angle_tolerance, point)
            verified, match = verify_matched(
                part,
                on,
                cl,
                tool_length=length,
                tol=section_tol,
                pivot=point,
                feed_rules=feed_rules,
            )
            checks.append(verified)
            last = k == len(sections) - 1
            process.add(  # (the rows the verification matched)
                part,
                cl,
                ended=ended if last else None,
                fresh=k > 0,
                tool_length=length,
                machine=on,
                match=match,
            )
        check = merge_verifications(checks, [k > 0 for k in range(len(checks))])
        process_check = process.result()
        faults = located(process_check, dialect, lambda: [text], args.program)
    _show_warnings(toolpath.warnings)
    ok = check.ok and process_check.ok
    if args.report:
        report = Report(
            machine=machine.name,
            controller=dialect.name,
            tcp=program.tcp,
            units=program.units,
            verification=check,
            tool_length_mm=program.tool_length,
            warnings=tuple(toolpath.warnings),
        ).as_json()
        report["verified"] = ok
        report["process"] = process_check.as_dict() | {"faults": faults}
        inputs = {"the program": args.program, "the CL file": args.cl}
        roles = {Path(args.report): "the report (--report)"}
        write_texts({Path(args.report): report_json(report)}, _given(inputs), roles)
    print(f"{args.program}: {check.summary(program.units)}")
    if check.missed_lines:
        shown = ", ".join(str(x) for x in check.missed_lines[:10])
        print(f"missed CL lines: {shown}{' ...' if len(check.missed_lines) > 10 else ''}")
    feeds = check.feeds
    if feeds is not None and not feeds.ok:  # the geometry may be right: say where the feed is not
        at = feeds.worst_cl_line if feeds.max_axis_share <= 1.0 else feeds.max_axis_cl_line
        print(f"worst tip feed near CL line {at}")
    elif not check.ok and check.worst_cl_line:
        print(f"worst deviation near CL line {check.worst_cl_line}")
    off = check.max_orientation_deviation_deg  # (beyond the CL axis: as a bending strategy)
    if (
        not check.ok
        and args.angle_tolerance == 0
        and stated_bend
        and off > check.orientation_tolerance_deg
    ):
        print(
            f"{args.program}: the tool axis is off the CL data's by up to {off:.4f} deg, and "
            f"the header says the post's singularity strategy may bend it by up to "
            f"{stated_bend:g} deg: verify it with --angle-tolerance {stated_bend:g} (the ball "
            "centre of a ball-end tool is then measured, as the post checked it)"
        )
    print(f"{args.program}: {process_check.summary()}")
    for line in faults:
        print(line)
    for note in process_check.notes:
        print(f"{args.program}: note: {note}")
    from urdfpost.program import smoothing_summary

    # (a program checked in pieces: its header keeps the smoothing blocks)
    print(f"{args.program}: {smoothing_summary(program, program.units)}")
    return 0 if ok else 1


def _cmd_compare(args: argparse.Namespace) -> int:
    from urdfpost.analysis.compare import compare, table
    from urdfpost.machine import load_machine
    from urdfpost.planning.strategies import STRATEGIES
    from urdfpost.posting.options import PostOptions

    machine = load_machine(args.machine)
    names = list(STRATEGIES) if args.strategies == "all" else args.strategies.split(",")
    names = [n.strip() for n in names if n.strip()]
    unknown = [n for n in names if n not in STRATEGIES]
    if unknown:
        raise UsageError(
            f"--strategies: unknown {', '.join(unknown)}; expected 'all' or names from "
            f"{', '.join(STRATEGIES)}"
        )
    from urdfpost.analysis.timing import require_toppra

    require_toppra()  # before the comparison, which can take minutes
    if args.plot:
        from urdfpost.analysis.plot import require_matplotlib

        require_matplotlib()
    toolpath = _read_cl(args, machine)
    units = _program_units(args, machine, toolpath.units)
    scale = mm_per_unit(units)
    machine = _job_machine(args, machine, scale)
    options = PostOptions(
        controller=args.controller,
        tcp=args.tcp,
        units=units,
        tool_length=None if args.tool_length is None else args.tool_length * scale,
        tolerance=args.tolerance,
        prefer=_check_prefer(args.prefer, machine),
        detector=args.detector,
        angle_tolerance=args.angle_tolerance,
        planner=args.planner,
        lift=args.lift,
    )
    result = compare(
        toolpath,
        machine,
        names,
        options,
        progress=lambda n: logging.getLogger("urdfpost").info("strategy %s", n),
    )
    files: dict[Path, str] = {}
    inputs = {"the CL file": args.cl, "the machine file": machine.path}
    roles: dict[Path, str] = {}
    if args.report:
        files[Path(args.report)] = report_json(result.as_dict())
        roles[Path(args.report)] = "the report (--report)"
    if args.csv:
        from urdfpost.analysis.compare import per_block_csv

        if Path(args.csv) in files:
            raise UsageError("--csv and --report name the same file")
        files[Path(args.csv)] = per_block_csv(result)
        roles[Path(args.csv)] = "the per-block data (--csv)"
    if args.plot:
        output_target(args.plot)
        outputs = {"the plot (--plot)": args.plot} | {r: p for p, r in roles.items()}
        check_distinct(outputs, _given(inputs))
    write_texts(files, _given(inputs), roles)
    if args.plot:
        from urdfpost.analysis.plot import plot_comparison

        plot_comparison(result, args.plot, title=f"{Path(args.cl).name} on {machine.name}")
    print(table(result, units))
    for sp in result.spans:
        print(
            f"span {sp.kind:5s} CL lines {sp.first_line}-{sp.last_line} (CL index "
            f"{sp.first}-{sp.last}): min sigma {sp.min_sigma:.4f}, exact swing "
            f"{sp.swing_deg:.1f} deg, largest step {sp.max_step_deg:.1f} deg"
        )
    for o in result.outcomes:
        if not o.verified and o.error:
            print(f"{o.strategy}: {o.error}")
    if not result.posted:
        print(
            f"urdfpost: no strategy makes a verified program of {args.cl} on {machine.name} "
            f"({len(result.outcomes)} tried; the reasons are above)",
            file=sys.stderr,
        )
        return 1
    return 0


def _cmd_testpath(args: argparse.Namespace) -> int:
    from urdfpost.analysis.testpaths import PATHS, to_apt

    if args.list or not args.name:
        for name, make in PATHS.items():
            tp = make()
            print(f"{name:16s} {len(tp):5d} points  {tp.source}")
        return 0
    if args.name not in PATHS:
        raise UsageError(f"unknown test path {args.name!r}; expected one of {', '.join(PATHS)}")
    if args.output == "-":  # the usual name for standard output
        sys.stdout.write(to_apt(PATHS[args.name]()))
        return 0
    out = Path(args.output or f"{args.name}.apt")
    write_texts({out: to_apt(PATHS[args.name]())}, roles={out: "the CL file (-o)"})
    print(f"wrote {out}")
    return 0


def _cmd_machines(args: argparse.Namespace) -> int:
    from urdfpost.machine import list_machines, load_machine

    rows = []
    for name, path in sorted(list_machines().items()):
        try:
            m = load_machine(path)
        except UrdfpostError as e:
            rows.append((name, "INVALID", "", str(e)))
            continue
        rot = " ".join(a.name for a in m.rotary)
        rows.append((name, m.family, rot, m.settings.description))
    if not rows:
        print("no machines found")
        return 0
    width = max(len(r[0]) for r in rows)
    for name, family, rot, desc in rows:
        print(f"{name:<{width}}  {family:<11}  {rot:<4}  {desc}")
    return 0


def describe_machine(name: str) -> str:
    """Human-readable description of a machine (what ``urdfpost machine show`` prints)."""
    from urdfpost.kinematics.inverse import singular_sets
    from urdfpost.machine import load_machine

    m = load_machine(name)
    s = m.settings
    lines = [
        f"machine   {m.name}  ({m.path})",
        f"family    {m.family}",
    ]
    if s.description:
        lines.append(f"about     {s.description}")
    pref = f"{s.prefer[0]}{'+' if s.prefer[1] > 0 else '-'}" if s.prefer else "none"
    lines += [
        f"control   {s.controller}, units {s.units}, tool length {s.tool_length:g} mm, "
        f"preferred branch {pref}",
        "axes (workpiece frame at home; linear mm, rotary deg):",
    ]
    for a in m.axes:
        d = ", ".join(f"{x:+.4f}" for x in a.direction)
        if a.rotary:
            travel = (
                "continuous"
                if a.continuous
                else (f"{np.degrees(a.lower):.3f} .. {np.degrees(a.upper):.3f} deg")
            )
            vel = f"{np.degrees(a.velocity):.1f} deg/s" if np.isfinite(a.velocity) else "-"
            piv = ", ".join(f"{x:.3f}" for x in a.pivot)
            lines.append(
                f"  {a.name}  {a.kind:<10} {a.side:<5}  dir ({d})  through ({piv}) mm  "
                f"travel {travel}  max {vel}"
            )
        else:
            vel = f"{a.velocity * 60 / 1000:.1f} m/min" if np.isfinite(a.velocity) else "-"
            lines.append(
                f"  {a.name}  {a.kind:<10} {a.side:<5}  dir ({d})  "
                f"travel {a.lower:.3f} .. {a.upper:.3f} mm  max {vel}"
            )
    v0 = ", ".join(f"{x:+.4f}" for x in m.home_tool_axis)
    g0 = ", ".join(f"{x:.3f}" for x in m.home_tool_in_work[:3, 3])
    lines.append(f"home      tool axis ({v0}), gauge point ({g0}) mm at q = 0")
    if m.mount is not None:
        zero = ", ".join(f"{x:.3f}" for x in m.mount.origin)
        turn = ", ".join(f"{x:g}" for x in m.mount.rpy)
        lines.append(
            f"zero      program zero ({zero}) mm on link {m.mount.parent} (joint "
            f"{m.mount.joint}, rpy {turn} rad): the default of --setup"
        )
    lines.append("singular tool directions (workpiece frame at home):")
    for sing in singular_sets(m):
        d = ", ".join(f"{x:+.4f}" for x in sing.direction)
        reach = "within travel" if sing.within_travel else "outside travel"
        if sing.kind == "pole":
            lines.append(
                f"  pole  tool axis along ({d}): {m.rotary[0].name} undetermined ({reach})"
            )
        else:
            lines.append(
                f"  edge  tool axis {np.degrees(sing.cone_angle):.3f} deg from ({d}): branches "
                f"merge, limit of reachable tilt ({reach})"
            )
    return "\n".join(lines)


def _cmd_machine(args: argparse.Namespace) -> int:
    print(describe_machine(args.name))
    return 0


def _view_html(
    machine: Any,
    dialect: Any,
    text: str,
    path: str,
    cl: Any,
    stock: str | None,
    tool_length: float | None,
    color: str | None,
    program: Any = None,
    tool_lengths: Any = None,
) -> tuple[str, dict[str, Any]]:
    """The 3-D view of a program text, read back (unless ``program`` is that already) as
    ``verify`` reads it."""
    from urdfpost.analysis.view import view_data, view_html

    if program is None:
        program = dialect.read(text, path=path, rollover=machine.settings.rollover)
    data = view_data(
        machine,
        program,
        text,
        dialect,
        cl=cl,
        stock=stock,
        tool_length=tool_length,
        color=color,
        tool_lengths=tool_lengths,
    )
    return view_html(data), data


def _view_summary(path: Path, data: dict[str, Any]) -> str:
    kinds = [m["kind"] for m in data["marks"]]
    marks = ", ".join(
        f"{kinds.count(k)} {label}"
        for k, label in (("singular", "singular"), ("rewind", "rewind"), ("worst", "worst"))
        if k in kinds
    )
    return (
        f"wrote {path}: the 3-D view of {data['moves']} moves in {data['samples']} samples"
        f"{' (' + marks + ' marked)' if marks else ''}"
    )


def _cmd_view(args: argparse.Namespace) -> int:
    from urdfpost.dialects import dialect_for
    from urdfpost.machine import load_machine

    if args.color == "deviation" and not args.cl:
        raise UsageError("--color deviation measures the trace against the CL data: give --cl")
    machine = load_machine(args.machine)
    dialect = dialect_for(args.controller, None if args.controller else args.program)
    dialect = dialect.with_clamps(machine.settings.clamps)
    try:
        text = Path(args.program).read_text(encoding="utf-8", errors="replace")
    except OSError as e:
        raise UrdfpostError(f"{args.program}: cannot read: {e.strerror or e}") from e
    program = dialect.read(text, path=args.program, rollover=machine.settings.rollover)
    scale = mm_per_unit(program.units)
    machine = _job_machine(args, machine, scale)
    cl = _read_cl(args, machine) if args.cl else None
    tool_length = None if args.tool_length is None else args.tool_length * scale
    lengths = None
    if args.tool_table is not None or cl is not None:  # each tool's (machine coordinates)
        from urdfpost.posting.tools import gauge_lengths

        table = None if args.tool_table is None else read_tool_table(args.tool_table, scale)
        default = machine.settings.tool_length if tool_length is None else tool_length
        lengths = dict(table or {})
        if cl is not None:
            lengths = gauge_lengths(cl, default, table)
    out = Path(args.output)
    inputs = {
        "the program": args.program,
        "the CL file": args.cl,
        "the stock mesh": args.stock,
        "the machine file": machine.path,
    }
    check_distinct({"the view (-o)": out}, _given(inputs))
    output_target(out)
    page, data = _view_html(
        machine, dialect, text, args.program, cl, args.stock, tool_length, args.color, program,
        lengths,
    )  # fmt: skip
    write_texts({out: page}, _given(inputs), {out: "the view (-o)"})
    print(_view_summary(out, data))
    return 0


COMMANDS = {
    "view": _cmd_view,
    "post": _cmd_post,
    "verify": _cmd_verify,
    "machines": _cmd_machines,
    "compare": _cmd_compare,
    "testpath": _cmd_testpath,
    "machine": _cmd_machine,
}


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit code."""
    try:
        return _run(argv)
    except BrokenPipeError:
        # the reader went away (``urdfpost machine show dmu50 | head -1``): stop quietly with
        # the code of a Unix tool killed by SIGPIPE; output files are complete before anything
        # is printed. Python flushes stdout again at exit: point it at /dev/null first.
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
        return 128 + signal.SIGPIPE


def _run(argv: Sequence[str] | None) -> int:
    keep_freed_memory()
    parser = build_parser()
    args = parser.parse_args(argv)
    restore = _setup_logging(args.verbose)
    signals = _stops.install()  # Ctrl-C and SIGTERM: raised, and remembered (_stops.check)
    try:
        code = COMMANDS[args.command](args)
        _stops.check()  # (one lost after the last place that checks)
        sys.stdout.flush()  # a closed pipe shows here, not in the interpreter's exit
        return code
    except UsageError as e:
        print(f"urdfpost: error: {e}", file=sys.stderr)
        return 2
    except UrdfpostError as e:
        print(f"urdfpost: {e}", file=sys.stderr)
        return 1
    except KeyboardInterrupt as e:  # Ctrl-C or SIGTERM: the files are cleaned up by now
        _ignore_stops()  # a second one would interrupt the message
        if isinstance(e, Terminated):
            print("urdfpost: terminated", file=sys.stderr)
            return 128 + signal.SIGTERM
        print("urdfpost: interrupted", file=sys.stderr)
        return 128 + signal.SIGINT
    finally:
        signals()
        restore()


def _ignore_stops() -> None:
    """Ignore further Ctrl-C and ``SIGTERM`` (in the main thread) until :func:`_run` ends."""
    if threading.current_thread() is threading.main_thread():
        for s in (signal.SIGTERM, signal.SIGINT):
            signal.signal(s, signal.SIG_IGN)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
