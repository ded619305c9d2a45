"""What a post is asked for (:class:`PostOptions`) and the job's settings resolved from it.

:func:`resolve` is the one place where the options of a call (the command line's or a
script's), the machine file's ``<urdfpost>`` settings and the defaults meet: every stage after
it reads the :class:`Job` and never looks at the options or the machine settings again.
"""

from __future__ import annotations

from dataclasses import dataclass

from urdfpost.dialects import Dialect, dialect_for
from urdfpost.errors import MachineDefinitionError, UrdfpostError
from urdfpost.machine import Machine
from urdfpost.planning.branches import Preference
from urdfpost.planning.rewinds import DEFAULT_RETRACT
from urdfpost.planning.singularity import DEFAULT_DETECTOR, DETECTORS, with_detector
from urdfpost.planning.strategies import DEFAULT_STRATEGY, STRATEGIES
from urdfpost.posting.transitions import DEFAULT_CLEARANCE
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
    arcs : bool
        Write the CL data's arcs (CIRCLE records) as arcs (G2/G3, Heidenhain C) where the
        control, the tool axis and the plane allow it (:mod:`urdfpost.posting.arcs`); False
        writes them as lines, as interpolated.
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
    arcs: bool = True


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
    arcs : bool
        Write arcs as arcs (:attr:`PostOptions.arcs`).
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
    arcs: bool = True


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
    dialect = dialect_for(options.controller or settings.controller)
    offsets = dialect.spec.work_offsets
    if not 1 <= options.work_offset <= offsets:
        raise UrdfpostError(
            f"work offset {options.work_offset}: {dialect.name} has work offsets 1 to {offsets}"
        )
    return Job(
        machine=machine,
        dialect=dialect,
        units=units,
        tol=with_detector(
            Tolerances.for_units(units, options.tolerance), detector_name(options.detector)
        ),
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
        arcs=options.arcs,
    )
