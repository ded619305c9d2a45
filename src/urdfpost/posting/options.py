"""What a post is asked for (:class:`PostOptions`) and the job's settings resolved from it.

:func:`resolve` is the one place where the options of a call (the command line's or a
script's), the machine file's ``<urdfpost>`` settings and the defaults meet: every stage after
it reads the :class:`Job` and never looks at the options or the machine settings again.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

from urdfpost.dialects import Dialect, dialect_for
from urdfpost.errors import MachineDefinitionError, UrdfpostError
from urdfpost.machine import Machine
from urdfpost.planning.branches import Preference
from urdfpost.planning.rewinds import DEFAULT_RETRACT
from urdfpost.planning.singularity import DEFAULT_DETECTOR, DETECTORS, with_detector
from urdfpost.planning.strategies import DEFAULT_STRATEGY, STRATEGIES
from urdfpost.posting.feeds import FEED_AUTO, FEED_INVERSE, FEED_MODES, FEED_PER_BLOCK, FEED_TIP
from urdfpost.posting.transitions import DEFAULT_CLEARANCE
from urdfpost.program import Smoothing
from urdfpost.tolerances import Tolerances
from urdfpost.units import mm_per_unit, program_units


@dataclass(frozen=True)
class PostOptions:
    """How to post.

    Attributes
    ----------
    controller : str or None
        Dialect name; default the machine file's controller.
    tcp : bool
        Write the tool tip in workpiece coordinates with TCP on (the control does the
        kinematics) instead of machine axis positions.
    units : str or None
        Program units ("mm" or "inch"); default the machine file's ``units`` setting, else
        the CL data's units (:func:`urdfpost.units.program_units`).
    tool_length : float or None
        Tool length in mm (gauge point to tip); default the machine file's.
    tolerance : float or None
        Tool-tip tolerance in program units; default 0.01 mm or 0.0004 in.
    prefer : Preference or None
        Preferred rotary branch; default the machine file's.
    block_numbers : bool
        Number the blocks (Heidenhain always does).
    program_name : str or None
        Default: the CL PARTNO, else "URDFPOST".
    strategy : str or None
        Singularity strategy (:data:`urdfpost.planning.strategies.STRATEGIES`); default the
        machine file's, else :data:`~urdfpost.planning.strategies.DEFAULT_STRATEGY`.
    detector : str or None
        Singularity detector (:data:`urdfpost.planning.singularity.DETECTORS`): "geometric"
        (conditioning and swing thresholds) or "rate" (axis speed at the programmed feed over
        the velocity limit); default
        :data:`~urdfpost.planning.singularity.DEFAULT_DETECTOR`.
    angle_tolerance : float
        How far a strategy may bend the tool axis from the programmed one, degrees.
    planner : str
        Branch choice over the whole path ("global") or point by point ("local").
    lift : float
        Lift along the tool axis inside singular spans (``spline`` strategy), program units;
        0 = off.
    retract : float or None
        Lift along the tool axis for a rewind, program units; default 50 mm (2 in).
    rewind_feed : float or None
        Feed of a rewind's lift and turn, program units per minute; None: rapid. The return
        to the part is at the feed of the cut.
    collisions : bool
        Check every branch candidate and the program's moves for collisions with FCL (always
        on when a stock is given).
    stock : str or None
        Stock or part mesh (STL, OBJ, ...) in the workpiece frame, program units.
    holder_diameter, holder_length : float or None
        Tool holder size, program units; default 40 x 60 mm.
    clearance : float or None
        The approach point above the first point of the path (at the start and after each
        tool change), along its tool axis, program units; default 10 mm (0.4 in).
    work_offset : int
        The work offset the program selects: 1 for G54 (Heidenhain preset 1), 2 for G55...
    feed : float or None
        Feed for cutting moves the CL data gives no feed for, program units per minute
        (reported as a warning); None: such a move is an error.
    spindle : float or None
        Spindle speed (rpm, clockwise) for cutting with the spindle off (reported as a
        warning); None: such a move is an error.
    tool_table : mapping of int to float, or None
        Gauge length of each tool number, mm (:func:`urdfpost.posting.tools.read_tool_table`):
        machine-coordinate programs compute each tool's moves with its own length, first
        from here, else the CL data's ``LOADTL LENGTH``, else ``tool_length``.
    mcs_offsets : bool
        A work offset per NX MCS (TCP programs): the points of each MCS written as its MSYS
        has them, in work offset ``work_offset + k`` for the file's MCS ``k``; default: every
        MCS transformed into the first, one work offset.
    expand_cycles : bool
        Write the CL data's canned cycles (``CYCLE/DRILL`` ...) as the motion they make
        instead of the control's cycles (``G81``, ``CYCLE81``, ``CYCL DEF 200``).
    smoothing : bool or None
        Write the control's path smoothing (tolerance) cycle before the cut and its cancel
        after it; None: the machine file's ``smoothing`` setting (default on).
    smoothing_tolerance : float or None
        Its path tolerance, program units; default the tool-tip tolerance
        (:attr:`tolerance`). The rotary axes' tolerance, where the control takes one, is the
        orientation tolerance.
    feed_mode : str or None
        How the F words are made (:data:`urdfpost.posting.feeds.FEED_MODES`): "tip" (the CL
        tip feed; right with TCP), "inverse-time" (G93: F = 1 / block time), "per-block" (F
        per minute, the block's axis-space length over its time); None or "auto": "tip" with
        TCP, else inverse time where the control has it, else per block (``docs/job.md``).
    arcs : bool
        Write the CL data's arcs (CIRCLE records) as arcs (G2/G3, Heidenhain C) where the
        control, the tool axis and the plane allow it (:mod:`urdfpost.posting.arcs`); False
        writes them as lines, as interpolated.
    tilted_planes : bool or None
        Write operations at a fixed tilt in a tilted working plane (PLANE SPATIAL, CYCLE800,
        G68.2) in TCP programs on controls that have one (:mod:`urdfpost.posting.planes`);
        None: the machine file's ``tilted_planes`` setting (default on).
    """

    controller: str | None = None
    tcp: bool = True
    units: str | None = None
    tool_length: float | None = None
    tolerance: float | None = None
    prefer: Preference | None = None
    block_numbers: bool = False
    program_name: str | None = None
    strategy: str | None = None
    detector: str | None = None
    angle_tolerance: float = 2.0
    planner: str = "global"
    lift: float = 0.0
    retract: float | None = None
    rewind_feed: float | None = None
    collisions: bool = False
    stock: str | None = None
    holder_diameter: float | None = None
    holder_length: float | None = None
    clearance: float | None = None
    work_offset: int = 1
    feed: float | None = None
    spindle: float | None = None
    tool_table: Mapping[int, float] | None = None
    mcs_offsets: bool = False
    expand_cycles: bool = False
    smoothing: bool | None = None
    smoothing_tolerance: float | None = None
    feed_mode: str | None = None
    arcs: bool = True
    tilted_planes: bool | None = None


@dataclass(frozen=True)
class Job:
    """The settings of one post, resolved: lengths in mm, every default applied.

    Attributes
    ----------
    machine : Machine
    dialect : Dialect
        The control the program is written for.
    units : str
        Program units ("mm" or "inch").
    tol : Tolerances
        In mm and radians; a
        :class:`~urdfpost.planning.singularity.DetectorTolerances` carrying the singularity
        detector.
    strategy : str
        Name of the singularity strategy.
    tcp : bool
    tool_length : float
        Gauge point to tip, mm.
    angle_tolerance_deg : float
    prefer : Preference or None
    planner : str
    lift : float
        mm.
    retract : float
        mm.
    rewind_feed : float or None
        mm/min; None: rapid.
    block_numbers : bool or None
        None: the dialect's default.
    program_name : str or None
        None: from the CL data.
    collisions : bool
        A collision world is built (asked for, or a stock given).
    stock : str or None
        Path of the stock mesh, in program units.
    holder_diameter, holder_length : float or None
        mm; None: the tool model's defaults.
    clearance : float
        mm.
    work_offset : int
    feed : float or None
        mm/min.
    spindle : float or None
        rpm.
    tool_table : mapping of int to float
        Gauge length of each tool number given for the job, mm (:mod:`urdfpost.posting.tools`).
    mcs_offsets : bool
        A work offset per MCS.
    expand_cycles : bool
        Canned cycles written as their motion.
    smoothing : Smoothing or None
        The path smoothing switched on before the cut (tolerance mm, rotary tolerance
        degrees); None: none written.
    rollover : frozenset of str
        The rotary axes the control rolls over (the machine file's ``rollover`` setting).
    feed_mode : str
        "tip", "inverse-time" or "per-block" (:func:`feed_mode_name`).
    arcs : bool
        Write arcs as arcs (:attr:`PostOptions.arcs`).
    tilted_planes : bool
        Write operations at a fixed tilt in tilted planes (:attr:`PostOptions.tilted_planes`
        resolved with the machine file's setting).
    pivot : float or None
        The cutting point of the tool section being posted, mm up the tool axis from the tip
        (:func:`urdfpost.posting.tools.cutting_points`); None: the CL data's at its first
        point.
    cutter : tuple or None
        The cutter of the tool section being posted (diameter, corner radius, length, mm;
        :func:`urdfpost.posting.tools.tool_cutters`), whose body the collisions are checked
        with; None: the CL data's at its first point.
    """

    machine: Machine
    dialect: Dialect
    units: str
    tol: Tolerances
    strategy: str
    tcp: bool
    tool_length: float
    angle_tolerance_deg: float
    prefer: Preference | None
    planner: str
    lift: float
    retract: float
    rewind_feed: float | None
    block_numbers: bool | None
    program_name: str | None
    collisions: bool
    stock: str | None
    holder_diameter: float | None
    holder_length: float | None
    clearance: float = DEFAULT_CLEARANCE
    work_offset: int = 1
    feed: float | None = None
    spindle: float | None = None
    tool_table: Mapping[int, float] = field(default_factory=dict)
    mcs_offsets: bool = False
    expand_cycles: bool = False
    smoothing: Smoothing | None = None
    rollover: frozenset[str] = frozenset()
    feed_mode: str = FEED_TIP
    arcs: bool = True
    tilted_planes: bool = True
    pivot: float | None = None
    cutter: tuple[float | None, float | None, float | None] | None = None


def feed_mode_name(name: str | None, tcp: bool, dialect: Dialect) -> str:
    """The feed mode of a post: ``name``, ``auto`` (or None) resolved for TCP and the control.

    ``auto``: the tip feed with TCP (the control applies F at the tip); without TCP inverse
    time where the control has it (G93), else F per block.

    Raises
    ------
    UrdfpostError
        An unknown mode, or inverse time on a control without it.
    """
    name = name or FEED_AUTO
    if name not in FEED_MODES:
        raise UrdfpostError(f"unknown feed mode {name!r}; expected one of {', '.join(FEED_MODES)}")
    has_inverse = dialect.spec.inverse_time is not None
    if name == FEED_AUTO:
        return FEED_TIP if tcp else (FEED_INVERSE if has_inverse else FEED_PER_BLOCK)
    if name == FEED_INVERSE and not has_inverse:
        raise UrdfpostError(
            f"feed mode inverse-time: {dialect.name} has no inverse-time feed; expected "
            f"{FEED_PER_BLOCK} or {FEED_TIP} (docs/job.md)"
        )
    return name


def _feed_mode(options: PostOptions, machine: Machine, dialect: Dialect) -> str:
    """The job's feed mode: the options', else the machine file's (an error names the file
    and line of its setting), else ``auto``."""
    settings = machine.settings
    if options.feed_mode is not None or settings.feed_mode is None:
        return feed_mode_name(options.feed_mode, options.tcp, dialect)
    try:
        return feed_mode_name(settings.feed_mode, options.tcp, dialect)
    except UrdfpostError as e:
        where = settings.where or str(machine.path)
        raise MachineDefinitionError(f"{where}: <urdfpost feed_mode=...>: {e}") from e


def smoothing_of(
    options: PostOptions, machine: Machine, dialect: Dialect, tol: Tolerances, units: str
) -> Smoothing | None:
    """The smoothing a post writes: asked for (else the machine file's setting), at the
    asked tolerance (in the program ``units``) or the tool-tip tolerance, with
    the orientation tolerance for the rotary axes where the control takes one.

    The default tolerance is at least one unit of the program's last linear decimal (0.001
    mm, 0.0001 in): a tool-tip tolerance below it cannot be written, and the control is told
    the smallest tolerance it can be.

    Raises
    ------
    UrdfpostError
        A tolerance that is not a positive number, or one asked for below the program's last
        decimal; smoothing asked for on a control that has no smoothing cycle.
    """
    on = machine.settings.smoothing if options.smoothing is None else options.smoothing
    spec = dialect.spec
    if not on:
        return None
    if not spec.smoothing_on:
        if options.smoothing:
            raise UrdfpostError(f"{dialect.name} has no path smoothing cycle; use --no-smoothing")
        return None
    scale = mm_per_unit(units)
    smallest = dialect.resolution("X", units)  # mm
    tolerance = max(tol.tip, smallest)
    if options.smoothing_tolerance is not None:
        tolerance = options.smoothing_tolerance * scale
        if not (math.isfinite(tolerance) and tolerance > 0.0):
            raise UrdfpostError(
                f"smoothing tolerance {options.smoothing_tolerance!r}: expected a positive "
                "length in program units"
            )
        if tolerance < smallest * (1.0 - 1e-9):
            raise UrdfpostError(
                f"smoothing tolerance {options.smoothing_tolerance!r}: below the program's "
                f"last decimal ({smallest / scale:g} {units}); expected at least that"
            )
    takes = any("{tol}" in t for t in spec.smoothing_on)
    angles = any("{angle}" in t for t in spec.smoothing_on)
    return Smoothing(
        True,
        tolerance if takes else None,
        math.degrees(tol.orientation) if angles else None,
    )


def strategy_name(machine: Machine, name: str | None = None) -> str:
    """The strategy a post uses: ``name``, else the machine file's, else the default.

    Raises
    ------
    UrdfpostError
        ``name`` is not a strategy.
    MachineDefinitionError
        The machine file names one that is not (the message names the file and line).
    """
    if name:
        if name not in STRATEGIES:
            raise UrdfpostError(
                f"unknown singularity strategy {name!r}; expected one of {', '.join(STRATEGIES)}"
            )
        return name
    settings = machine.settings
    if settings.strategy is None:
        return DEFAULT_STRATEGY
    if settings.strategy not in STRATEGIES:
        where = settings.where or str(machine.path)
        raise MachineDefinitionError(
            f"{where}: <urdfpost strategy={settings.strategy!r}>: expected one of "
            f"{', '.join(STRATEGIES)}"
        )
    return settings.strategy


def detector_name(name: str | None = None) -> str:
    """The singularity detector a post uses: ``name``, else the default.

    Raises
    ------
    UrdfpostError
        ``name`` is not a detector.
    """
    if name is None:
        return DEFAULT_DETECTOR
    if name not in DETECTORS:
        raise UrdfpostError(
            f"unknown singularity detector {name!r}; expected one of {', '.join(DETECTORS)}"
        )
    return name


def resolve(options: PostOptions | None, machine: Machine, cl_units: str) -> Job:
    """The settings of a post: ``options``, else the machine file's, else the defaults.

    Parameters
    ----------
    options : PostOptions or None
    machine : Machine
    cl_units : str
        Units of the CL data: the program's when neither the options nor the machine file
        name any (:func:`urdfpost.units.program_units`).

    Returns
    -------
    Job

    Raises
    ------
    DialectError
        An unknown control.
    UrdfpostError, MachineDefinitionError
        An unknown strategy (:func:`strategy_name`) or detector (:func:`detector_name`).
    """
    options = options or PostOptions()
    units = program_units(options.units, machine.settings.units, cl_units)
    scale = mm_per_unit(units)

    def mm(value: float | None) -> float | None:
        return None if value is None else value * scale

    settings = machine.settings
    dialect = dialect_for(options.controller or settings.controller).with_clamps(settings.clamps)
    offsets = dialect.spec.work_offsets
    if not 1 <= options.work_offset <= offsets:
        raise UrdfpostError(
            f"work offset {options.work_offset}: {dialect.name} has work offsets 1 to {offsets}"
        )
    if options.mcs_offsets and not options.tcp:
        raise UrdfpostError(
            "a work offset per MCS needs TCP: machine-coordinate positions hold where the part "
            "sits, and their work offset must be zero (post without --mcs-offsets)"
        )
    tol = with_detector(
        Tolerances.for_units(units, options.tolerance), detector_name(options.detector)
    )
    return Job(
        machine=machine,
        dialect=dialect,
        units=units,
        tol=tol,
        strategy=strategy_name(machine, options.strategy),
        tcp=options.tcp,
        tool_length=settings.tool_length if options.tool_length is None else options.tool_length,
        angle_tolerance_deg=options.angle_tolerance,
        prefer=options.prefer
        if options.prefer is not None
        else (Preference(*settings.prefer) if settings.prefer else None),
        planner=options.planner,
        lift=options.lift * scale,
        retract=DEFAULT_RETRACT if options.retract is None else options.retract * scale,
        rewind_feed=mm(options.rewind_feed),
        block_numbers=options.block_numbers or None,
        program_name=options.program_name,
        collisions=bool(options.collisions or options.stock),
        stock=options.stock,
        holder_diameter=mm(options.holder_diameter),
        holder_length=mm(options.holder_length),
        clearance=DEFAULT_CLEARANCE if options.clearance is None else options.clearance * scale,
        work_offset=options.work_offset,
        feed=mm(options.feed),
        spindle=options.spindle,
        tool_table=dict(options.tool_table or {}),
        mcs_offsets=options.mcs_offsets,
        expand_cycles=options.expand_cycles,
        smoothing=smoothing_of(options, machine, dialect, tol, units),
        rollover=settings.rollover,
        feed_mode=_feed_mode(options, machine, dialect),
        arcs=options.arcs,
        tilted_planes=settings.tilted_planes
        if options.tilted_planes is None
        else options.tilted_planes,
    )
