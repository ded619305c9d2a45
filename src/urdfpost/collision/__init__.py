"""Collision checking with FCL: the machine's ``<collision>`` shapes, the tool and the stock.

A :class:`CollisionWorld` is built once per machine, tool and stock, and then asked about many
joint vectors: :meth:`CollisionWorld.check` for configurations, :meth:`CollisionWorld.check_moves`
for the straight joint-space moves between them. Geometry is built once; per configuration only
the transforms of the bodies that move relative to the workpiece are updated.

Bodies, and the side of the kinematic chain each belongs to (derived from the URDF tree, no
machine names):

- every ``<collision>`` element of every link (box, cylinder, sphere, mesh). A link is on the
  **head** side when a moving joint of the chain that carries the tool lies between it and the
  root, on the **table** side when one that carries the workpiece does, and in the **static**
  frame when neither does (bed, column, trunnion housing);
- the tool on the head side (:class:`ToolBody`): the cutting part from the tip, the shank above
  it and the holder, which ends at the gauge point;
- the stock (or part) mesh in the workpiece frame, on the workpiece's side.

Pairs checked: every body against every body of another side, and the stock against bodies of
its own side that move relative to it, except the cutting part against the stock (that is
cutting) and machine shapes that already touch at the home pose. ``docs/collisions.md`` lists the
pairs and the limits.

Everything is placed in the workpiece frame, mm. Joint vectors ``q`` have one column per axis in
``machine.axis_names`` order (mm for linear axes, rad for rotary axes), as everywhere in urdfpost.

Examples
--------
>>> from urdfpost.machine import load_machine
>>> machine = load_machine("dmu50")
>>> world = CollisionWorld.build(machine, ToolBody(diameter=10.0), tool_length=100.0)
>>> bool(world.check(machine.home).hit[0])
False
"""

from __future__ import annotations

import logging
import math
import os
from collections.abc import Collection, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from urdfpost.errors import CollisionError
from urdfpost.machine import Machine
from urdfpost.units import M_TO_MM

if TYPE_CHECKING:
    import trimesh

log = logging.getLogger(__name__)

HEAD, TABLE, STATIC = "head", "table", "static"
"""Sides of the kinematic chain a body moves with."""

MACHINE, CUTTER, SHANK, HOLDER, STOCK = "machine", "cutter", "shank", "holder", "stock"
"""Kinds of bodies (and the names of the tool and stock bodies)."""

HOME_CONTACT_MM = 0.01
"""Machine shapes closer than this at the home pose (mm) are taken as touching by design (a slide
on its bed, a cradle in its trunnion) and not checked against each other. 0.01 mm: far below any
modelled clearance, above the rounding of FCL's distance between touching faces."""

JOB_BODIES = (CUTTER, SHANK, HOLDER, STOCK)
"""Kinds of the bodies that come with the job (``clearance_of=JOB_BODIES``)."""

DEFAULT_STEP_MM = 1.0
"""Default largest displacement (mm) of any body point between two samples of a move."""

DEFAULT_STEP_DEG = 1.0
"""Default largest rotary axis change (degrees) between two samples of a move."""

DEFAULT_FLUTES_PER_DIAMETER = 2.0
"""Cutting length of a tool whose flute length is unknown, in diameters."""

_CHUNK = 2048  # configurations whose transforms are computed at once (memory bound)
_BALL_TOL = 1e-6  # mm: a corner radius this close to half the diameter is a ball end


def _import_fcl() -> Any:
    try:
        import fcl
    except ImportError as e:  # pragma: no cover - python-fcl is a dependency
        raise CollisionError("collision checking needs python-fcl: pip install python-fcl") from e
    return fcl


def _import_trimesh() -> Any:
    try:
        import trimesh
    except ImportError as e:  # pragma: no cover - a declared dependency
        raise CollisionError("reading meshes needs trimesh: pip install trimesh") from e
    return trimesh


# -- the tool -----------------------------------------------------------------------------


@dataclass(frozen=True)
class ToolSection:
    """One solid of revolution of the tool, in the tool frame (+Z from the tip to the spindle).

    Attributes
    ----------
    kind : str
        ``"cutter"``, ``"shank"`` or ``"holder"``.
    z0, z1 : float
        Lower and upper end along the tool frame's Z, mm (negative: below the gauge point).
    radius : float
        mm.
    ball : bool
        Whether the lower end is a hemisphere of ``radius`` (ball-end cutter).
    """

    kind: str
    z0: float
    z1: float
    radius: float
    ball: bool = False


@dataclass(frozen=True)
class ToolBody:
    """Sizes of the tool and its holder, mm.

    The tool is modelled as three solids along the tool axis, from the tip up: the cutting part
    (``flute_length`` long, a capsule for a ball end, else a cylinder of the full diameter, which
    covers a corner radius), the shank (``shank_diameter``) and the holder (``holder_diameter``,
    ``holder_length`` long, ending at the gauge point). :meth:`sections` places them for a tool
    length.

    Attributes
    ----------
    diameter : float
        Cutter diameter, mm.
    corner_radius : float
        Corner radius, mm; ``diameter / 2`` for a ball end.
    flute_length : float or None
        Cutting length from the tip, mm; None: ``DEFAULT_FLUTES_PER_DIAMETER`` x diameter.
    shank_diameter : float or None
        mm; None: the cutter diameter.
    holder_diameter : float
        mm.
    holder_length : float
        From the gauge point toward the tip, mm.

    Examples
    --------
    >>> ToolBody.from_cutter({"diameter": 8.0, "corner_radius": 4.0}, tool_length=90.0).ball
    True
    """

    diameter: float = 10.0
    corner_radius: float = 0.0
    flute_length: float | None = None
    shank_diameter: float | None = None
    holder_diameter: float = 40.0
    holder_length: float = 60.0

    def __post_init__(self) -> None:
        sizes = {
            "diameter": self.diameter,
            "holder diameter": self.holder_diameter,
            "holder length": self.holder_length,
            "flute length": self.flute_length,
            "shank diameter": self.shank_diameter,
        }
        for what, value in sizes.items():
            if value is not None and not (np.isfinite(value) and value > 0):
                raise CollisionError(f"tool: {what} {value!r} mm: expected a positive length")
        if not (np.isfinite(self.corner_radius) and self.corner_radius >= 0):
            raise CollisionError(
                f"tool: corner radius {self.corner_radius!r} mm: expected 0 or a positive length"
            )
        if self.corner_radius > self.diameter / 2 + _BALL_TOL:
            raise CollisionError(
                f"tool: corner radius {self.corner_radius:g} mm is larger than half the "
                f"diameter {self.diameter:g} mm"
            )

    @property
    def ball(self) -> bool:
        """Whether the cutter is a ball end (corner radius = half the diameter)."""
        return self.corner_radius >= self.diameter / 2 - _BALL_TOL

    @classmethod
    def from_cutter(
        cls,
        data: Mapping[str, Any],
        tool_length: float,
        *,
        holder_diameter: float | None = None,
        holder_length: float | None = None,
        flute_length: float | None = None,
    ) -> ToolBody:
        """The tool of a CL ``cutter`` or ``tool`` event.

        Parameters
        ----------
        data : mapping
            The event's data: ``diameter``, ``corner_radius``, ``length`` (mm, each optional or
            None). ``length`` is the cutter's own length from the tip; a tool shorter than the
            distance from the gauge point to the tip sits in a longer holder (or extension), so
            the holder is lengthened to ``tool_length - length``, and the cutting length is at
            most ``length``.
        tool_length : float
            Gauge point to tip, mm.
        holder_diameter, holder_length, flute_length : float, optional
            mm; the class defaults when not given.

        Returns
        -------
        ToolBody
        """
        defaults = cls()
        diameter = data.get("diameter")
        diameter = defaults.diameter if diameter is None else float(diameter)
        corner = data.get("corner_radius")
        corner = 0.0 if corner is None else float(corner)
        h_len = defaults.holder_length if holder_length is None else float(holder_length)
        length = data.get("length")
        flute = flute_length
        if length is not None and float(length) > 0:
            length = float(length)
            if tool_length - length > h_len:
                log.debug(
                    "tool %g mm long at tool length %g mm: holder lengthened to %g mm",
                    length,
                    tool_length,
                    tool_length - length,
                )
                h_len = tool_length - length
            flute = min(DEFAULT_FLUTES_PER_DIAMETER * diameter if flute is None else flute, length)
        return cls(
            diameter=diameter,
            corner_radius=corner,
            flute_length=flute,
            holder_diameter=defaults.holder_diameter
            if holder_diameter is None
            else float(holder_diameter),
            holder_length=h_len,
        )

    def sections(self, tool_length: float) -> tuple[ToolSection, ...]:
        """The solids of the tool for a tool length, in the tool frame.

        The cutting part starts at the tip (``z = -tool_length``); the holder ends at the gauge
        point (``z = 0``) and is shortened when the tool would not stick out by its cutting
        length; the shank fills the rest. A tool length of 0 (the gauge point is programmed)
        gives no solids.

        Parameters
        ----------
        tool_length : float
            Gauge point to tip, mm.

        Returns
        -------
        tuple of ToolSection
            Cutter, shank, holder (those of non-zero length).
        """
        if not tool_length > 0:
            return ()
        tip = -float(tool_length)
        flute = DEFAULT_FLUTES_PER_DIAMETER * self.diameter
        flute = min(self.flute_length if self.flute_length is not None else flute, tool_length)
        holder = min(self.holder_length, tool_length - flute)
        if holder < self.holder_length:
            log.warning(
                "tool length %g mm leaves %g mm below a %g mm holder for a %g mm cutting "
                "length: holder shortened to %g mm",
                tool_length,
                tool_length - self.holder_length,
                self.holder_length,
                flute,
                holder,
            )
        out = [ToolSection(CUTTER, tip, tip + flute, self.diameter / 2, self.ball)]
        shank_r = (self.shank_diameter or self.diameter) / 2
        if -holder - (tip + flute) > 1e-9:
            out.append(ToolSection(SHANK, tip + flute, -holder, shank_r))
        if holder > 1e-9:
            out.append(ToolSection(HOLDER, -holder, 0.0, self.holder_diameter / 2))
        return tuple(out)


# -- bodies -------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class Body:
    """One rigid collision shape.

    Attributes
    ----------
    name : str
        The ``<collision name>`` (``link/name`` if the name is taken, the link name if there
        is none), or ``cutter``, ``shank``, ``holder``, ``stock``.
    kind : str
        ``machine``, ``cutter``, ``shank``, ``holder`` or ``stock``.
    link : str
        URDF link it moves with.
    side : str
        ``head``, ``table`` or ``static``.
    axes : frozenset of str
        Machine axes between the root link and ``link``: bodies with equal sets never move
        relative to each other.
    local : ndarray, shape (4, 4)
        Placement of the shape in the link frame, translation in mm.
    center : ndarray, shape (3,)
        Centre of a sphere enclosing the shape, in the shape's own frame, mm.
    radius : float
        Radius of that sphere, mm.
    hull : ndarray, shape (k, 3)
        Points in the shape's own frame, mm: the shape lies within ``pad`` of their convex hull.
    pad : float
        mm.
    """

    name: str
    kind: str
    link: str
    side: str
    axes: frozenset[str]
    local: np.ndarray
    center: np.ndarray
    radius: float
    hull: np.ndarray
    pad: float


@dataclass(frozen=True, eq=False)
class CollisionResult:
    """Collisions of single configurations.

    Attributes
    ----------
    hit : ndarray, shape (n,), bool
        Whether configuration i collides.
    pairs : list of (str, str) or None
        Body names of the first colliding pair found per configuration (tool and head first),
        None where clear.
    clearance : ndarray, shape (n,), mm, or None
        Smallest distance over the checked pairs, 0 where colliding; None unless asked for.
    nearest : list of (str, str) or None, or None
        The pair at that distance; None unless clearance was asked for.
    """

    hit: np.ndarray
    pairs: list[tuple[str, str] | None]
    clearance: np.ndarray | None = None
    nearest: list[tuple[str, str] | None] | None = None


@dataclass(frozen=True, eq=False)
class MoveCollisionResult:
    """Collisions of the straight joint-space moves between consecutive configurations.

    Attributes
    ----------
    hit : ndarray, shape (n - 1,), bool
        Whether move i (from configuration i to i + 1, both ends included) collides.
    pairs : list of (str, str) or None
        Body names of the first colliding pair along each move, None where clear.
    at : ndarray, shape (n - 1,)
        Fraction of the move (0 = start, 1 = end) of the first colliding sample, NaN where
        clear.
    samples : ndarray, shape (n - 1,), int
        Number of intervals each move was cut into (``samples + 1`` configurations checked,
        fewer when a collision ends the scan).
    """

    hit: np.ndarray
    pairs: list[tuple[str, str] | None]
    at: np.ndarray
    samples: np.ndarray


@dataclass
class _Query:
    """Mutable state handed to the FCL broad-phase callback."""

    fcl: Any
    index: dict[int, int]  # id of an FCL geometry -> body index
    excluded: set[tuple[int, int]]
    request: Any
    pair: tuple[int, int] | None = None


def _collide_callback(o1: Any, o2: Any, query: _Query) -> bool:
    """Narrow phase of one broad-phase candidate pair; True (stop) on a counted collision."""
    fcl = query.fcl
    result = fcl.CollisionResult()
    if not fcl.collide(o1, o2, query.request, result):
        return False
    c = result.contacts[0]
    i, j = query.index[id(c.o1)], query.index[id(c.o2)]
    key = (min(i, j), max(i, j))
    if key in query.excluded:
        return False
    query.pair = key
    return True


# -- reading geometry ---------------------------------------------------------------------


def _floats(text: str | None, n: int, default: tuple[float, ...], where: str) -> np.ndarray:
    if text is None:
        return np.array(default, dtype=float)
    try:
        values = np.array([float(v) for v in text.split()])
    except ValueError as e:
        raise CollisionError(f"{where}: {text!r}: expected {n} numbers") from e
    if values.shape != (n,):
        raise CollisionError(f"{where}: {text!r}: expected {n} numbers")
    return values


def _origin(el: Any, where: str) -> np.ndarray:
    """Placement of an ``<origin>`` element, shape (4, 4), translation in mm."""
    import pinocchio as pin

    t = np.eye(4)
    origin = el.find("origin")
    if origin is not None:
        xyz = _floats(origin.get("xyz"), 3, (0.0, 0.0, 0.0), f"{where}: <origin xyz>")
        rpy = _floats(origin.get("rpy"), 3, (0.0, 0.0, 0.0), f"{where}: <origin rpy>")
        t[:3, :3] = pin.rpy.rpyToMatrix(*rpy)
        t[:3, 3] = xyz * M_TO_MM
    return t


def resolve_mesh_path(filename: str, urdf_path: str | os.PathLike[str]) -> Path:
    """File of a URDF ``<mesh filename>``.

    ``package://name/rest`` is looked for as ``rest`` and ``name/rest`` next to the URDF file
    and in the folders above it, then under each folder of ``$ROS_PACKAGE_PATH``;
    ``file://`` paths are absolute; other relative paths are relative to the URDF file.

    Raises
    ------
    CollisionError
        Naming the mesh and the places looked in, when none exists.
    """
    urdf_file = Path(urdf_path)
    base = urdf_file.parent if urdf_file.is_file() else Path.cwd()
    if filename.startswith("file://"):
        candidates = [Path(filename[len("file://") :])]
    elif filename.startswith("package://"):
        package, _, rest = filename[len("package://") :].partition("/")
        folders = [base, *list(base.parents)[:3]]
        folders += [Path(p) for p in os.environ.get("ROS_PACKAGE_PATH", "").split(os.pathsep) if p]
        candidates = [base / rest]
        for folder in folders:
            candidates.append(folder / package / rest)
            if folder.name == package:
                candidates.append(folder / rest)
    else:
        p = Path(filename)
        candidates = [p if p.is_absolute() else base / p]
    for c in candidates:
        if c.is_file():
            return c
    tried = ", ".join(dict.fromkeys(str(c) for c in candidates))
    raise CollisionError(f"{urdf_path}: mesh {filename!r} not found (looked for {tried})")


def load_mesh(path: str | os.PathLike[str], what: str = "stock") -> trimesh.Trimesh:
    """Read a triangle mesh (STL, OBJ, PLY, ... through trimesh), units as in the file.

    Raises
    ------
    CollisionError
        Naming the file, when it is missing, unreadable or holds no triangles.
    """
    tm = _import_trimesh()
    p = Path(path)
    if not p.is_file():
        raise CollisionError(f"{p}: {what} file not found")
    try:
        mesh = tm.load(p, force="mesh")
    except Exception as e:  # trimesh raises many kinds for broken or unknown files
        raise CollisionError(f"{p}: cannot read the {what} mesh: {e}") from e
    if not isinstance(mesh, tm.Trimesh) or len(mesh.faces) == 0:
        raise CollisionError(
            f"{p}: the {what} mesh has no triangles (expected an STL or OBJ file of a surface)"
        )
    return mesh


def _bvh(fcl: Any, vertices: np.ndarray, faces: np.ndarray) -> Any:
    model = fcl.BVHModel()
    model.beginModel(len(faces), len(vertices))
    model.addSubModel(np.asarray(vertices, dtype=float), np.asarray(faces, dtype=np.int64))
    model.endModel()
    return model


def _sphere_of(vertices: np.ndarray) -> tuple[np.ndarray, float]:
    lo, hi = vertices.min(axis=0), vertices.max(axis=0)
    center = (lo + hi) / 2
    return center, float(np.linalg.norm(vertices - center, axis=1).max())


def _box_points(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """The 8 corners of a box, shape (8, 3)."""
    idx = np.array([[i >> 2 & 1, i >> 1 & 1, i & 1] for i in range(8)])
    return np.where(idx == 1, hi, lo)


def _cylinder_points(r: float, z0: float, z1: float, sides: int = 16) -> np.ndarray:
    """Corners of a prism circumscribing a cylinder about Z, shape (2 * sides, 3)."""
    a = np.linspace(0.0, 2 * np.pi, sides, endpoint=False)
    ring = np.column_stack([np.cos(a), np.sin(a)]) * r / np.cos(np.pi / sides)
    return np.vstack([np.column_stack([ring, np.full(sides, z)]) for z in (z0, z1)])


def _hull_points(vertices: np.ndarray) -> np.ndarray:
    """Vertices of the convex hull of a point set (its bounding box corners if that fails)."""
    try:
        from scipy.spatial import ConvexHull

        return vertices[ConvexHull(vertices).vertices]
    except Exception:  # degenerate (flat) point sets
        return _box_points(vertices.min(axis=0), vertices.max(axis=0))


_TWIN_SIDES = 64  # a cylinder's twin prism is at most r (1 / cos(pi / 64) - 1) = 0.12 % r larger


def _twin(fcl: Any, geometry: Any) -> Any:
    """Triangulated copy of a box or cylinder, enclosing it, for distances to meshes (or None).

    FCL computes the distance between two meshes with closed-form bounding-volume and triangle
    distances, but between a primitive and a mesh with GJK at every visited leaf: hundreds of
    times slower next to a large mesh.
    """
    if isinstance(geometry, fcl.Box):
        half = np.asarray(geometry.side, dtype=float) / 2
        vertices = _box_points(-half, half)
        # corners are indexed by bits (x, y, z); two triangles per face, outward order
        faces = np.array(
            [
                [0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5],  # x = -, x = +
                [0, 4, 5], [0, 5, 1], [2, 3, 7], [2, 7, 6],  # y = -, y = +
                [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3],  # z = -, z = +
            ]
        )  # fmt: skip
        return _bvh(fcl, vertices, faces)
    if isinstance(geometry, fcl.Cylinder):
        n = _TWIN_SIDES
        vertices = _cylinder_points(geometry.radius, -geometry.lz / 2, geometry.lz / 2, n)
        k = np.arange(n)
        nxt = (k + 1) % n
        faces = np.vstack(
            [
                np.column_stack([k, nxt, n + nxt]),
                np.column_stack([k, n + nxt, n + k]),
                np.column_stack([np.zeros(n - 2, int), k[2:], k[1:-1]]),
                np.column_stack([np.full(n - 2, n), n + k[1:-1], n + k[2:]]),
            ]
        )
        return _bvh(fcl, vertices, faces)
    return None


def _inside(mesh: trimesh.Trimesh, points: np.ndarray) -> np.ndarray:
    """Which points lie inside a closed mesh, shape (n,) bool.

    trimesh's ray test when it has a ray engine (embreex or rtree), else the generalised
    winding number (Jacobson et al. 2013): the solid angles of all triangles seen from the
    point sum to 4 pi inside and 0 outside.
    """
    try:
        return np.asarray(mesh.contains(points), dtype=bool)
    except ImportError:
        pass
    tri = np.asarray(mesh.triangles, dtype=float)
    out = np.empty(len(points), dtype=bool)
    for k, p in enumerate(np.asarray(points, dtype=float)):
        a, b, c = (tri[:, i] - p for i in range(3))
        la, lb, lc = (np.linalg.norm(v, axis=1) for v in (a, b, c))
        det = np.einsum("ij,ij->i", a, np.cross(b, c))
        den = (
            la * lb * lc
            + np.einsum("ij,ij->i", a, b) * lc
            + np.einsum("ij,ij->i", b, c) * la
            + np.einsum("ij,ij->i", c, a) * lb
        )
        out[k] = abs(np.arctan2(det, den).sum() / (2 * np.pi)) > 0.5
    return out


@dataclass
class _Shape:
    name: str | None
    kind: str
    link: str
    local: np.ndarray
    geometry: Any
    center: np.ndarray
    radius: float
    hull: np.ndarray
    pad: float = 0.0


def _link_shapes(fcl: Any, machine: Machine) -> list[_Shape]:
    """The ``<collision>`` elements of every link, in mm."""
    from lxml import etree

    root = etree.fromstring(
        machine.urdf_text.encode("utf-8"), parser=etree.XMLParser(remove_comments=True)
    )
    shapes: list[_Shape] = []
    for link in root.findall("link"):
        lname = link.get("name")
        for el in link.findall("collision"):
            where = f"{machine.path}:{el.sourceline}: link {lname!r} <collision>"
            local = _origin(el, where)
            geom_el = el.find("geometry")
            shape = None if geom_el is None or len(geom_el) == 0 else geom_el[0]
            if shape is None:
                raise CollisionError(f"{where}: no <geometry> shape")
            tag = shape.tag
            zero = np.zeros(3)
            if tag == "box":
                size = _floats(shape.get("size"), 3, (), f"{where}: <box size>") * M_TO_MM
                geometry = fcl.Box(*size)
                center, radius = zero, float(np.linalg.norm(size) / 2)
                hull, pad = _box_points(-size / 2, size / 2), 0.0
            elif tag == "cylinder":
                r = _floats(shape.get("radius"), 1, (), f"{where}: <cylinder radius>")[0]
                length = _floats(shape.get("length"), 1, (), f"{where}: <cylinder length>")[0]
                r, length = r * M_TO_MM, length * M_TO_MM
                geometry = fcl.Cylinder(r, length)
                center, radius = zero, math.hypot(r, length / 2)
                hull, pad = _cylinder_points(r, -length / 2, length / 2), 0.0
            elif tag == "sphere":
                r = _floats(shape.get("radius"), 1, (), f"{where}: <sphere radius>")[0] * M_TO_MM
                geometry = fcl.Sphere(r)
                center, radius = zero, r
                hull, pad = zero[None, :], r
            elif tag == "mesh":
                filename = shape.get("filename")
                if not filename:
                    raise CollisionError(f"{where}: <mesh> without filename")
                scale = _floats(shape.get("scale"), 3, (1.0, 1.0, 1.0), f"{where}: <mesh scale>")
                path = resolve_mesh_path(filename, machine.path)
                mesh = load_mesh(path, what=f"link {lname!r} collision")
                vertices = np.asarray(mesh.vertices, dtype=float) * scale * M_TO_MM
                geometry = _bvh(fcl, vertices, mesh.faces)
                center, radius = _sphere_of(vertices)
                hull, pad = _hull_points(vertices), 0.0
            else:
                raise CollisionError(
                    f"{where}: unknown shape <{tag}>: expected box, cylinder, sphere or mesh"
                )
            if not radius > 0:
                raise CollisionError(f"{where}: <{tag}> has zero size")
            shapes.append(
                _Shape(el.get("name"), MACHINE, lname, local, geometry, center, radius, hull, pad)
            )
    return shapes


def _tool_shapes(fcl: Any, tool: ToolBody, tool_length: float) -> list[_Shape]:
    shapes = []
    for s in tool.sections(tool_length):
        length = s.z1 - s.z0
        local = np.eye(4)
        if s.ball and length <= 2 * s.radius:
            geometry = fcl.Sphere(s.radius)
            local[2, 3] = s.z0 + s.radius
            radius, hull, pad = s.radius, np.zeros((1, 3)), s.radius
        elif s.ball:
            # capsule: segment from z0 + r to z1 - r, so the lower hemisphere ends at the tip
            half = length / 2 - s.radius
            geometry = fcl.Capsule(s.radius, 2 * half)
            local[2, 3] = (s.z0 + s.z1) / 2
            radius, hull, pad = length / 2, np.array([[0, 0, -half], [0, 0, half]]), s.radius
        else:
            geometry = fcl.Cylinder(s.radius, length)
            local[2, 3] = (s.z0 + s.z1) / 2
            radius, pad = math.hypot(s.radius, length / 2), 0.0
            hull = _cylinder_points(s.radius, -length / 2, length / 2)
        shapes.append(
            _Shape(s.kind, s.kind, "tool", local, geometry, np.zeros(3), radius, hull, pad)
        )
    return shapes


def _stock_shape(fcl: Any, mesh: trimesh.Trimesh) -> _Shape:
    vertices = np.asarray(mesh.vertices, dtype=float)
    center, radius = _sphere_of(vertices)
    geometry = _bvh(fcl, vertices, mesh.faces)
    return _Shape(
        STOCK, STOCK, "workpiece", np.eye(4), geometry, center, radius, _hull_points(vertices)
    )


def _axes_above(machine: Machine) -> dict[str, list[str]]:
    """Per link: the machine axes between the root and the link, from the root."""
    from urdfpost.machine import urdf

    doc = urdf.parse_urdf(machine.urdf_text, machine.path)
    by_child = {j.child: j for j in doc.joints.values()}
    names = set(machine.axis_names)
    paths = {}
    for link in doc.links:
        path, at = [], link
        while at in by_child:
            j = by_child[at]
            if j.name in names:
                path.append(j.name)
            at = j.parent
        paths[link] = path[::-1]
    return paths


def _side(machine: Machine, path: list[str]) -> str:
    """Side of a link with these machine axes above it."""
    sides = {machine.axis(a).side for a in path}
    return HEAD if HEAD in sides else TABLE if TABLE in sides else STATIC


def _bodies_of(
    machine: Machine, shapes: list[_Shape], paths: dict[str, list[str]]
) -> tuple[list[Body], list[Any]]:
    """Bodies in reporting order (tool, head, stock, table, static) and their FCL geometries.

    Machine shapes are named by their ``<collision name>``, by ``link/name`` when the name is
    used twice or by a tool or stock body, and by the link name when they have none.
    """
    rank = {CUTTER: 0, SHANK: 1, HOLDER: 2, HEAD: 3, STOCK: 4, TABLE: 5, STATIC: 6}
    shapes = sorted(
        shapes,
        key=lambda s: rank[s.kind if s.kind != MACHINE else _side(machine, paths[s.link])],
    )
    taken = {s.kind for s in shapes if s.kind != MACHINE}
    counts: dict[str, int] = {}
    for s in shapes:
        if s.kind == MACHINE:
            counts[s.name or s.link] = counts.get(s.name or s.link, 0) + 1
    bodies, seen = [], set()
    for s in shapes:
        name = s.kind
        if s.kind == MACHINE:
            name = s.name or s.link
            if name in taken or counts[name] > 1:
                name = f"{s.link}/{name}"
            base, k = name, 1
            while name in seen:
                k += 1
                name = f"{base}#{k}"
        seen.add(name)
        bodies.append(
            Body(
                name=name,
                kind=s.kind,
                link=s.link,
                side=_side(machine, paths[s.link]),
                axes=frozenset(paths[s.link]),
                local=s.local,
                center=s.center,
                radius=s.radius,
                hull=s.hull,
                pad=s.pad,
            )
        )
    return bodies, [s.geometry for s in shapes]


def _levers(machine: Machine, bodies: list[Body], paths: dict[str, list[str]]) -> np.ndarray:
    """Per axis: the largest distance of any body point from a rotary axis, mm (1 if linear).

    Bounded over every configuration within travel, at the neutral pose: for a body moved by
    the axis directly (no machine axis between them), the largest distance of its hull from
    the axis line; otherwise the distance from the axis line to the next axis' pivot, plus the
    distances between the pivots further down (rigid), plus the largest travel of every linear
    axis on the way, plus the largest distance of the hull from the last pivot.

    Returns
    -------
    ndarray, shape (m,)
        In ``machine.axis_names`` order.
    """
    import pinocchio as pin

    model = machine.model
    data = model.createData()  # type: ignore[attr-defined]
    pin.forwardKinematics(model, data, pin.neutral(model))
    pin.updateFramePlacements(model, data)
    pivot, direction = {}, {}
    for a in machine.axes:
        jid = model.getJointId(a.name)  # type: ignore[attr-defined]
        pivot[a.name] = np.asarray(data.oMi[jid].translation) * M_TO_MM
        motion = np.asarray(data.joints[jid].S).reshape(6)  # joint frame, linear part first
        direction[a.name] = data.oMi[jid].rotation @ motion[3:]

    def from_line(name: str, x: np.ndarray) -> np.ndarray:
        d = x - pivot[name]
        return np.linalg.norm(d - np.outer(d @ direction[name], direction[name]), axis=1)

    levers = {a.name: 1.0 for a in machine.axes}
    for b in bodies:
        t = data.oMf[model.getFrameId(b.link, pin.FrameType.BODY)].homogeneous.copy()  # type: ignore[attr-defined]
        t[:3, 3] *= M_TO_MM
        t = t @ b.local
        hull = b.hull @ t[:3, :3].T + t[:3, 3]
        path = paths[b.link]
        for k, name in enumerate(path):
            if not machine.axis(name).rotary:
                continue
            below = path[k + 1 :]
            if not below:
                reach = float(from_line(name, hull).max())
            else:
                p = pivot[below[0]]
                reach = float(from_line(name, p[None, :])[0])
                for nxt in below[1:]:
                    reach += float(np.linalg.norm(pivot[nxt] - p))
                    p = pivot[nxt]
                for nxt in below:
                    a = machine.axis(nxt)
                    if not a.rotary:
                        reach += max(abs(a.lower), abs(a.upper))
                reach += float(np.linalg.norm(hull - p, axis=1).max())
            levers[name] = max(levers[name], reach + b.pad)
    return np.array([levers[a.name] for a in machine.axes])


# -- the world ----------------------------------------------------------------------------


class CollisionWorld:
    """FCL scene of one machine, tool and stock; build it with :meth:`build`.

    The world holds FCL objects whose transforms it sets on every query, so one world serves
    one thread at a time. Geometry is never rebuilt after :meth:`build`.

    Attributes
    ----------
    machine : Machine
    tool_length : float
        Gauge point to tip, mm.
    stock_mesh : trimesh.Trimesh or None
        The stock in the workpiece frame, mm.
    """

    machine: Machine
    tool_length: float
    stock_mesh: trimesh.Trimesh | None

    # set by build() and the _setup_* helpers it calls; FCL and Pinocchio objects are untyped
    _fcl: Any  # the fcl module
    _geometries: list[Any]  # per body: its FCL geometry
    _bodies: tuple[Body, ...]
    _stock: int  # index of the stock body, -1 if none
    _objects: list[Any]  # per body: its fcl.CollisionObject
    _index: dict[int, int]  # id of an FCL geometry -> body index
    _crequest: Any  # fcl.CollisionRequest
    _drequest: Any  # fcl.DistanceRequest
    _box_center: np.ndarray  # (b, 3): per body, centre of its box in its own frame, mm
    _box_half: np.ndarray  # (b, 3): per body, half sizes of that box, mm
    _excluded: set[tuple[int, int]]  # body pairs (i < j) touching at home
    _pairs: np.ndarray  # (p, 2), int: body pairs checked
    _levers: np.ndarray  # (m,): per axis, see levers
    _pin: Any  # the pinocchio module
    _data: Any  # pinocchio.Data
    _neutral: np.ndarray  # (nq,)
    _pin_index: tuple[tuple[int, int], ...]  # per axis: (idx_q, nq)
    _moving: list[int]  # bodies that move relative to the workpiece
    _moving_pos: dict[int, int]  # body index -> position in _moving
    _frames: list[int]  # Pinocchio frame ids: the workpiece, then the moving bodies' links
    _moving_link: np.ndarray  # (k,), int: per moving body, its link among _frames[1:]
    _moving_local: np.ndarray  # (k, 4, 4): per moving body, its placement in its link
    _fixed_transform: dict[int, np.ndarray]  # bodies rigid with the workpiece: placement
    _manager_pairs: list[tuple[Any, Any]]  # broad-phase managers collided with each other
    _moving_managers: list[Any]  # managers holding a moving body
    _twins: dict[int, Any]  # primitive body -> fcl.CollisionObject of its triangulated twin

    @classmethod
    def build(
        cls,
        machine: Machine,
        tool: ToolBody | None = None,
        tool_length: float | None = None,
        stock: str | os.PathLike[str] | trimesh.Trimesh | None = None,
        *,
        home_contact: float = HOME_CONTACT_MM,
    ) -> CollisionWorld:
        """Build the bodies, the FCL objects and the broad-phase managers.

        Parameters
        ----------
        machine : Machine
        tool : ToolBody, optional
            Default ``ToolBody()`` (10 mm flat end mill in a 40 x 60 mm holder).
        tool_length : float, optional
            Gauge point to tip, mm; default the machine's ``tool_length`` setting. 0: no tool
            bodies (the gauge point is programmed).
        stock : path or trimesh.Trimesh, optional
            Stock or part mesh in the workpiece frame, mm (STL, OBJ, ... read by trimesh).
        home_contact : float
            Machine shapes closer than this at the home pose are not checked against each
            other, mm (see ``HOME_CONTACT_MM``).

        Returns
        -------
        CollisionWorld

        Raises
        ------
        CollisionError
            A stock or mesh file that is missing or unreadable, a ``<collision>`` element that
            cannot be read, nonsensical tool sizes.
        """
        fcl = _import_fcl()
        self = cls()
        self.machine = machine
        self._fcl = fcl
        self.tool_length = float(
            machine.settings.tool_length if tool_length is None else tool_length
        )
        if not self.tool_length > 0:
            log.info("tool length 0 (gauge point programmed): no tool bodies are checked")
        self.stock_mesh = None
        if stock is not None:
            mesh = load_mesh(stock) if isinstance(stock, str | os.PathLike) else stock
            if not mesh.is_watertight:
                log.warning(
                    "stock mesh is not closed: only contacts with its surface are found, not "
                    "a body entirely inside it"
                )
            self.stock_mesh = mesh

        shapes = _tool_shapes(fcl, tool or ToolBody(), self.tool_length)
        shapes += _link_shapes(fcl, machine)
        if self.stock_mesh is not None:
            shapes.append(_stock_shape(fcl, self.stock_mesh))
        paths = _axes_above(machine)
        bodies, self._geometries = _bodies_of(machine, shapes, paths)
        self._bodies = tuple(bodies)
        self._stock = next((i for i, b in enumerate(bodies) if b.kind == STOCK), -1)
        self._objects = [fcl.CollisionObject(g) for g in self._geometries]
        self._index = {id(g): i for i, g in enumerate(self._geometries)}
        self._crequest = fcl.CollisionRequest(num_max_contacts=1, enable_contact=False)
        self._drequest = fcl.DistanceRequest()
        lo = np.array([b.hull.min(axis=0) - b.pad for b in bodies])
        hi = np.array([b.hull.max(axis=0) + b.pad for b in bodies])
        self._box_center, self._box_half = (lo + hi) / 2, (hi - lo) / 2

        self._setup_kinematics(paths["workpiece"])
        self._setup_managers(frozenset(paths["workpiece"]))
        self._excluded = set()
        self._exclude_touching_at_home(home_contact)
        self._pairs = np.array(
            [
                (i, j)
                for i in range(len(bodies))
                for j in range(i + 1, len(bodies))
                if self._rule(bodies[i], bodies[j]) and (i, j) not in self._excluded
            ],
            dtype=int,
        ).reshape(-1, 2)
        self._setup_twins()
        self._levers = _levers(machine, bodies, paths)
        log.debug(
            "collision world for %s: %d bodies, %d pairs checked, %d excluded",
            machine.name,
            len(bodies),
            len(self._pairs),
            len(self._excluded),
        )
        return self

    def _setup_kinematics(self, work_path: list[str]) -> None:
        """Frames to place the bodies that move in the workpiece frame; place the others."""
        import pinocchio as pin

        model, bodies = self.machine.model, self._bodies
        self._pin = pin
        self._data = model.createData()  # type: ignore[attr-defined]
        self._neutral = pin.neutral(model)
        self._pin_index = self.machine._pin_index
        work_axes = frozenset(work_path)
        self._moving = [i for i, b in enumerate(bodies) if b.axes != work_axes]
        self._moving_pos = {i: k for k, i in enumerate(self._moving)}
        links = sorted({bodies[i].link for i in self._moving})
        frame = {
            lk: model.getFrameId(lk, pin.FrameType.BODY)  # type: ignore[attr-defined]
            for lk in {b.link for b in bodies} | {"workpiece"}
        }
        self._frames = [frame["workpiece"]] + [frame[lk] for lk in links]
        self._moving_link = np.array([links.index(bodies[i].link) for i in self._moving], int)
        self._moving_local = np.array([bodies[i].local for i in self._moving]).reshape(-1, 4, 4)
        # bodies rigid with the workpiece: placed once (at home; any pose gives the same)
        data = self._data
        pin.forwardKinematics(model, data, self._pin_q(self.machine.home[None, :])[0])
        w_inv = np.linalg.inv(pin.updateFramePlacement(model, data, frame["workpiece"]).homogeneous)
        self._fixed_transform = {}
        for i, b in enumerate(bodies):
            if i not in self._moving_pos:
                t = w_inv @ pin.updateFramePlacement(model, data, frame[b.link]).homogeneous
                t[:3, 3] *= M_TO_MM
                self._fixed_transform[i] = t @ b.local
                self._place(self._objects[i], t @ b.local)

    def _setup_managers(self, work_axes: frozenset[str]) -> None:
        """One broad-phase manager per class of bodies.

        Bodies of one class (side; cutter, stock or other; rigid with the workpiece or not)
        have the same partners under :meth:`_rule`, so colliding the right pairs of managers
        checks exactly the chosen pairs of bodies.
        """
        fcl, bodies = self._fcl, self._bodies
        classes: dict[tuple[str, str, bool], list[int]] = {}
        for i, b in enumerate(bodies):
            kind = b.kind if b.kind in (CUTTER, STOCK) else ""
            classes.setdefault((b.side, kind, b.axes == work_axes), []).append(i)
        managers = []
        for members in classes.values():
            m = fcl.DynamicAABBTreeCollisionManager()
            m.registerObjects([self._objects[i] for i in members])
            m.setup()
            managers.append((m, members))
        self._manager_pairs = [
            (ma, mb)
            for a, (ma, ia) in enumerate(managers)
            for mb, ib in managers[a + 1 :]
            if self._rule(bodies[ia[0]], bodies[ib[0]])
        ]
        self._moving_managers = [
            m for m, members in managers if any(i in self._moving_pos for i in members)
        ]

    def _exclude_touching_at_home(self, home_contact: float) -> None:
        """Leave out pairs of machine shapes that touch at the home pose; say which."""
        fcl, bodies = self._fcl, self._bodies
        self._set_moving(self._moving_transforms(self.machine.home[None, :])[0])
        for i in range(len(bodies)):
            for j in range(i + 1, len(bodies)):
                bi, bj = bodies[i], bodies[j]
                if bi.kind != MACHINE or bj.kind != MACHINE or not self._rule(bi, bj):
                    continue
                oi, oj = self._objects[i], self._objects[j]
                touching = fcl.collide(oi, oj, self._crequest, fcl.CollisionResult()) or (
                    fcl.distance(oi, oj, self._drequest) <= home_contact
                )
                if touching:
                    self._excluded.add((i, j))
                    # neighbours across one axis (a slide on its bed) are expected to touch
                    neighbours = len(bi.axes ^ bj.axes) == 1
                    (log.info if neighbours else log.warning)(
                        "%s: %s (%s) and %s (%s) touch at the home pose: not checked against "
                        "each other",
                        self.machine.name,
                        bi.name,
                        bi.link,
                        bj.name,
                        bj.link,
                    )

    def _setup_twins(self) -> None:
        """Triangulated twins of the primitives paired with a mesh, for distances."""
        fcl = self._fcl
        meshes = {i for i, g in enumerate(self._geometries) if isinstance(g, fcl.BVHModel)}
        self._twins = {}
        for pair in self._pairs:
            for a, b in (pair, pair[::-1]):
                a, b = int(a), int(b)
                if b in meshes and a not in meshes and a not in self._twins:
                    twin = _twin(fcl, self._geometries[a])
                    if twin is not None:
                        self._twins[a] = fcl.CollisionObject(twin)
                        if a in self._fixed_transform:
                            self._place(self._twins[a], self._fixed_transform[a])

    @staticmethod
    def _rule(a: Body, b: Body) -> bool:
        """Whether bodies a and b are checked against each other (before home exclusions)."""
        if a.axes == b.axes:
            return False  # rigidly connected
        kinds = {a.kind, b.kind}
        if kinds == {CUTTER, STOCK}:
            return False  # that is cutting
        return a.side != b.side or STOCK in kinds

    # -- description ---------------------------------------------------------------------

    @property
    def bodies(self) -> tuple[Body, ...]:
        """Every body, in reporting order (tool, head, stock, table, static)."""
        return self._bodies

    @property
    def excluded(self) -> tuple[tuple[str, str], ...]:
        """Pairs of machine shapes not checked because they touch at the home pose."""
        b = self._bodies
        return tuple((b[i].name, b[j].name) for i, j in sorted(self._excluded))

    @property
    def levers(self) -> dict[str, float]:
        """Per axis: largest distance of a body point from a rotary axis (mm), 1 for linear."""
        return dict(zip(self.machine.axis_names, self._levers.tolist(), strict=True))

    def checked_pairs(self) -> list[tuple[str, str]]:
        """Every pair of bodies checked against each other, by name."""
        b = self._bodies
        return [
            (b[i].name, b[j].name)
            for i in range(len(b))
            for j in range(i + 1, len(b))
            if self._rule(b[i], b[j]) and (i, j) not in self._excluded
        ]

    # -- kinematics ----------------------------------------------------------------------

    def _as_q(self, q: np.ndarray) -> np.ndarray:
        m = len(self.machine.axes)
        q = np.asarray(q, dtype=float)
        if q.ndim == 1:
            q = q[None, :]
        if q.ndim != 2 or q.shape[1] != m:
            raise ValueError(
                f"expected joint vectors of shape (n, {m}) ({' '.join(self.machine.axis_names)}),"
                f" got {q.shape}"
            )
        bad = ~np.isfinite(q).all(axis=1)
        if bad.any():
            raise ValueError(f"joint vectors with NaN or inf at rows {np.flatnonzero(bad)[:10]}")
        return q

    def _pin_q(self, q: np.ndarray) -> np.ndarray:
        """Pinocchio configurations, shape (n, nq)."""
        qp = np.tile(self._neutral, (q.shape[0], 1))
        for col, ((idx, nq), a) in enumerate(zip(self._pin_index, self.machine.axes, strict=True)):
            if nq == 2:
                qp[:, idx], qp[:, idx + 1] = np.cos(q[:, col]), np.sin(q[:, col])
            elif a.rotary:
                qp[:, idx] = q[:, col]
            else:
                qp[:, idx] = q[:, col] / M_TO_MM
        return qp

    def _moving_transforms(self, q: np.ndarray) -> np.ndarray:
        """Placements of the moving bodies in the workpiece frame, shape (n, k, 4, 4), mm."""
        pin, model, data = self._pin, self.machine.model, self._data
        qp = self._pin_q(q)
        frames = self._frames
        out = np.empty((q.shape[0], len(frames), 4, 4))
        for i in range(q.shape[0]):
            pin.forwardKinematics(model, data, qp[i])
            for k, f in enumerate(frames):
                out[i, k] = pin.updateFramePlacement(model, data, f).homogeneous
        rel = np.linalg.inv(out[:, :1]) @ out[:, 1:]
        rel[:, :, :3, 3] *= M_TO_MM
        return rel[:, self._moving_link] @ self._moving_local

    @staticmethod
    def _place(obj: Any, t: np.ndarray) -> None:
        obj.setRotation(t[:3, :3])
        obj.setTranslation(t[:3, 3])

    def _set_moving(self, transforms: np.ndarray) -> None:
        for k, i in enumerate(self._moving):
            self._place(self._objects[i], transforms[k])
        for m in self._moving_managers:
            m.update()

    # -- queries -------------------------------------------------------------------------

    def _first_pair(self) -> tuple[int, int] | None:
        query = _Query(self._fcl, self._index, self._excluded, self._crequest)
        for ma, mb in self._manager_pairs:
            ma.collide(mb, query, _collide_callback)
            if query.pair is not None:
                return query.pair
        return None

    def _lower_bounds(self, transforms: np.ndarray, pairs: np.ndarray) -> np.ndarray:
        """Lower bounds of the distance of each pair, shape (n, p), mm.

        Each body is enclosed in an oriented box (the bounding box of its hull points in its
        own frame); the bound is the largest gap between the two boxes along any of their six
        axes (a separating-axis test that measures the gap).
        """
        n, bodies = transforms.shape[0], self._bodies
        rot = np.empty((n, len(bodies), 3, 3))
        center = np.empty((n, len(bodies), 3))
        for i, t in self._fixed_transform.items():
            rot[:, i] = t[:3, :3]
            center[:, i] = t[:3, :3] @ self._box_center[i] + t[:3, 3]
        for k, i in enumerate(self._moving):
            t = transforms[:, k]
            rot[:, i] = t[:, :3, :3]
            center[:, i] = t[:, :3, :3] @ self._box_center[i] + t[:, :3, 3]
        ia, ib = pairs[:, 0], pairs[:, 1]
        r_a, r_b = rot[:, ia], rot[:, ib]  # (n, p, 3, 3), columns = box axes
        axes = np.concatenate([r_a, r_b], axis=3)  # (n, p, 3, 6)
        d = np.abs(np.einsum("npi,npik->npk", center[:, ib] - center[:, ia], axes))
        half_a = np.abs(np.einsum("npij,npik->npjk", r_a, axes))  # |a_j . u_k|
        half_b = np.abs(np.einsum("npij,npik->npjk", r_b, axes))
        reach = np.einsum("pj,npjk->npk", self._box_half[ia], half_a) + np.einsum(
            "pj,npjk->npk", self._box_half[ib], half_b
        )
        return np.maximum((d - reach).max(axis=2), 0.0)

    def _distance(self, i: int, j: int, transforms: np.ndarray) -> float:
        """Distance between bodies i and j placed by ``transforms`` (moving bodies), mm."""
        fcl = self._fcl
        objects = []
        for a, b in ((i, j), (j, i)):
            twin = self._twins.get(a)
            if twin is not None and isinstance(self._geometries[b], fcl.BVHModel):
                if a in self._moving_pos:
                    self._place(twin, transforms[self._moving_pos[a]])
                objects.append(twin)
            else:
                objects.append(self._objects[a])
        return float(fcl.distance(objects[0], objects[1], self._drequest))

    def _nearest(
        self, transforms: np.ndarray, pairs: np.ndarray, bounds: np.ndarray
    ) -> tuple[float, tuple[int, int] | None]:
        """Smallest distance over ``pairs``, visiting them by increasing lower bound."""
        best, arg = math.inf, None
        for p in np.argsort(bounds):
            if bounds[p] >= best:
                break
            i, j = int(pairs[p, 0]), int(pairs[p, 1])
            d = self._distance(i, j, transforms)
            if d < best:
                best, arg = max(d, 0.0), (i, j)
                if best <= 0.0:
                    break
        return best, arg

    def _inside_stock(self, transforms: np.ndarray, clear: np.ndarray) -> np.ndarray:
        """Index of a head-side body entirely inside the (closed) stock, -1 if none.

        Parameters
        ----------
        transforms : ndarray, shape (n, k, 4, 4)
            Moving body placements.
        clear : ndarray, shape (n,), bool
            Configurations to test.

        Returns
        -------
        ndarray, shape (n,), int
            Body index.
        """
        n = transforms.shape[0]
        out = np.full(n, -1)
        mesh = self.stock_mesh
        if mesh is None or not mesh.is_watertight or not clear.any():
            return out
        lo, hi = mesh.bounds
        for k, i in enumerate(self._moving):
            b = self._bodies[i]
            if b.side != HEAD or b.kind == CUTTER:
                continue
            c = transforms[:, k, :3, :3] @ b.center + transforms[:, k, :3, 3]
            within = clear & (out < 0) & np.all((c - b.radius > lo) & (c + b.radius < hi), axis=1)
            if within.any():
                rows = np.flatnonzero(within)
                out[rows[_inside(mesh, c[rows])]] = i
        return out

    def _names(self, pair: tuple[int, int] | None) -> tuple[str, str] | None:
        if pair is None:
            return None
        return (self._bodies[pair[0]].name, self._bodies[pair[1]].name)

    def _clearance_pairs(self, clearance_of: Collection[str] | None) -> np.ndarray:
        if clearance_of is None:
            return self._pairs
        wanted = set(clearance_of)
        b = self._bodies
        keep = [
            k
            for k, (i, j) in enumerate(self._pairs)
            if wanted & {b[i].name, b[i].kind, b[j].name, b[j].kind}
        ]
        return self._pairs[keep]

    def check(
        self,
        q: np.ndarray,
        clearance: bool = False,
        clearance_of: Collection[str] | None = None,
    ) -> CollisionResult:
        """Collisions of single configurations.

        Parameters
        ----------
        q : ndarray, shape (n, m) or (m,)
            Joint vectors, mm / rad, columns in ``machine.axis_names`` order.
        clearance : bool
            Also compute the smallest distance over the checked pairs (slower).
        clearance_of : collection of str, optional
            Count only pairs with a body of these names or kinds in the clearance, e.g.
            ``JOB_BODIES`` (tool and stock) to leave out gaps inside the machine.

        Returns
        -------
        CollisionResult

        Raises
        ------
        ValueError
            For joint vectors of the wrong shape or with NaN.
        """
        q = self._as_q(q)
        n = q.shape[0]
        hit = np.zeros(n, dtype=bool)
        pairs: list[tuple[int, int] | None] = [None] * n
        dist = np.full(n, np.nan)
        nearest: list[tuple[int, int] | None] = [None] * n
        near_pairs = self._clearance_pairs(clearance_of) if clearance else self._pairs[:0]
        for start in range(0, n, _CHUNK):
            rows = slice(start, min(start + _CHUNK, n))
            transforms = self._moving_transforms(q[rows])
            for k in range(transforms.shape[0]):
                self._set_moving(transforms[k])
                pairs[start + k] = self._first_pair()
                hit[start + k] = pairs[start + k] is not None
            inside = self._inside_stock(transforms, ~hit[rows])
            for k_in in np.flatnonzero(inside >= 0):
                hit[start + k_in], pairs[start + k_in] = True, (int(inside[k_in]), self._stock)
            if clearance:
                bounds = self._lower_bounds(transforms, near_pairs)
                for k in range(transforms.shape[0]):
                    if hit[start + k]:
                        dist[start + k], nearest[start + k] = 0.0, pairs[start + k]
                    else:
                        self._set_moving(transforms[k])
                        d, arg = self._nearest(transforms[k], near_pairs, bounds[k])
                        dist[start + k], nearest[start + k] = d, arg
        return CollisionResult(
            hit=hit,
            pairs=[self._names(p) for p in pairs],
            clearance=dist if clearance else None,
            nearest=[self._names(p) for p in nearest] if clearance else None,
        )

    def sample_counts(
        self, q: np.ndarray, step_mm: float = DEFAULT_STEP_MM, step_deg: float = DEFAULT_STEP_DEG
    ) -> np.ndarray:
        """Number of intervals :meth:`check_moves` cuts each move into.

        The sampling rule: along a straight joint-space move the points of two bodies move,
        relative to each other, along paths no longer than ``s = sum_j lever_j * |dq_j|``
        (``lever_j`` = 1 for a linear axis, and for a rotary axis the largest distance of any
        body point from it, see :attr:`levers`). The move is cut into ``max(ceil(s / step_mm),
        ceil(max_rotary |dq| / step_deg), 1)`` equal intervals, so between two samples no body
        point moves more than ``step_mm`` relative to another body, and no rotary axis turns
        more than ``step_deg``.

        Parameters
        ----------
        q : ndarray, shape (n, m)
            mm / rad.
        step_mm : float
            mm.
        step_deg : float
            Degrees.

        Returns
        -------
        ndarray, shape (n - 1,), int
        """
        if not (step_mm > 0 and step_deg > 0):
            raise ValueError(f"expected positive steps, got {step_mm!r} mm, {step_deg!r} deg")
        q = self._as_q(q)
        dq = np.abs(np.diff(q, axis=0))
        swept = dq @ self._levers
        rot = [i for i, a in enumerate(self.machine.axes) if a.rotary]
        turn = dq[:, rot].max(axis=1) if rot else np.zeros(len(dq))
        n = np.maximum(np.ceil(swept / step_mm), np.ceil(turn / math.radians(step_deg)))
        return np.maximum(n, 1).astype(int)

    def check_moves(
        self, q: np.ndarray, step_mm: float = DEFAULT_STEP_MM, step_deg: float = DEFAULT_STEP_DEG
    ) -> MoveCollisionResult:
        """Collisions along the straight joint-space moves between consecutive configurations.

        Each move is sampled as :meth:`sample_counts` says (both ends included) and scanned
        from its start; the scan of a move stops at its first collision. Anywhere on the move,
        the bodies are within ``step_mm / 2`` (relative displacement of any point) of where
        they are at the nearest sample, so an overlap that holds a ball of diameter
        ``step_mm / 2`` is always found; only shallower grazes can fall between samples.

        Parameters
        ----------
        q : ndarray, shape (n, m)
            Joint vectors, mm / rad.
        step_mm : float
            Largest displacement of a body point between samples, mm.
        step_deg : float
            Largest rotary axis change between samples, degrees.

        Returns
        -------
        MoveCollisionResult
        """
        q = self._as_q(q)
        counts = self.sample_counts(q, step_mm, step_deg)
        ends = self.check(q)
        n_moves = q.shape[0] - 1
        hit = np.zeros(n_moves, dtype=bool)
        at = np.full(n_moves, np.nan)
        pairs: list[tuple[str, str] | None] = [None] * n_moves
        start_hit = ends.hit[:-1]
        hit[start_hit] = True
        at[start_hit] = 0.0
        for i in np.flatnonzero(start_hit):
            pairs[i] = ends.pairs[i]
        # interior samples of the moves whose start is clear, in order along each move
        todo = np.flatnonzero(~start_hit & (counts > 1))
        inner = counts[todo] - 1
        move = np.repeat(todo, inner)
        offsets = np.cumsum(inner) - inner
        k = np.arange(len(move)) - np.repeat(offsets, inner) + 1
        t = k / counts[move]
        for lo in range(0, len(move), _CHUNK):
            sl = slice(lo, lo + _CHUNK)
            mv, tt = move[sl], t[sl]
            live = ~hit[mv]
            if not live.any():
                continue
            mv, tt = mv[live], tt[live]
            qs = q[mv] + tt[:, None] * (q[mv + 1] - q[mv])
            transforms = self._moving_transforms(qs)
            for r in range(len(mv)):
                if hit[mv[r]]:
                    continue
                self._set_moving(transforms[r])
                pair = self._first_pair()
                if pair is not None:
                    hit[mv[r]], at[mv[r]], pairs[mv[r]] = True, tt[r], self._names(pair)
            inside = self._inside_stock(transforms, np.ones(len(mv), dtype=bool))
            for r_in in np.flatnonzero(inside >= 0):
                m = mv[r_in]
                if not hit[m] or tt[r_in] < at[m]:
                    hit[m], at[m] = True, tt[r_in]
                    pairs[m] = self._names((int(inside[r_in]), self._stock))
        end_hit = ~hit & ends.hit[1:]
        hit[end_hit] = True
        at[end_hit] = 1.0
        for i in np.flatnonzero(end_hit):
            pairs[i] = ends.pairs[i + 1]
        return MoveCollisionResult(hit=hit, pairs=pairs, at=at, samples=counts)


__all__ = [
    "CUTTER",
    "DEFAULT_STEP_DEG",
    "DEFAULT_STEP_MM",
    "HEAD",
    "HOLDER",
    "HOME_CONTACT_MM",
    "JOB_BODIES",
    "MACHINE",
    "SHANK",
    "STATIC",
    "STOCK",
    "TABLE",
    "Body",
    "CollisionResult",
    "CollisionWorld",
    "MoveCollisionResult",
    "ToolBody",
    "ToolSection",
    "load_mesh",
    "resolve_mesh_path",
]
