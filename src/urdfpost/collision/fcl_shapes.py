"""FCL geometry of single shapes: the machine's link shapes, the tool's sections, the stock.

Each becomes a :class:`Shape`: its FCL geometry, its placement in its link, and what the world
bounds it with (an enclosing sphere, hull points). The machine's shapes come as data from the
machine file (:attr:`urdfpost.machine.Machine.shapes`); only their mesh files are read here.
FCL is imported when a world is built (:func:`_import_fcl`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from urdfpost.collision.mesh import load_mesh
from urdfpost.collision.tool import ToolBody
from urdfpost.errors import GeometryError
from urdfpost.machine import Box, Cylinder, Machine, Sphere
from urdfpost.units import M_TO_MM

if TYPE_CHECKING:
    import trimesh

MACHINE, STOCK = "machine", "stock"
"""Kinds of the machine's shapes and of the stock (which is also the stock body's name)."""


def _import_fcl() -> Any:
    try:
        import fcl
    except ImportError as e:  # pragma: no cover - python-fcl is a dependency
        raise GeometryError("collision checking needs python-fcl: pip install python-fcl") from e
    return fcl


@dataclass(frozen=True, eq=False)
class Shape:
    """One rigid shape before it becomes a body of the world.

    Attributes
    ----------
    name : str or None
        ``<collision name>`` of a machine shape; the kind of a tool or stock shape.
    kind : str
        ``machine``, ``cutter``, ``shank``, ``holder`` or ``stock``.
    link : str
        URDF link it moves with.
    local : ndarray, shape (4, 4)
        Placement in the link frame, translation in mm.
    geometry : fcl.CollisionGeometry
    center : ndarray, shape (3,)
        Centre of an enclosing sphere, in the shape's own frame, mm.
    radius : float
        Radius of that sphere, mm.
    hull : ndarray, shape (k, 3)
        Points in the shape's own frame, mm: the shape lies within ``pad`` of their convex hull.
    pad : float
        mm.
    """

    name: str | None
    kind: str
    link: str
    local: np.ndarray
    geometry: Any
    center: np.ndarray
    radius: float
    hull: np.ndarray
    pad: float = 0.0


def bvh(fcl: Any, vertices: np.ndarray, faces: np.ndarray) -> Any:
    """FCL bounding-volume hierarchy of a triangle mesh (vertices (v, 3), faces (f, 3) int)."""
    model = fcl.BVHModel()
    model.beginModel(len(faces), len(vertices))
    model.addSubModel(np.asarray(vertices, dtype=float), np.asarray(faces, dtype=np.int64))
    model.endModel()
    return model


def sphere_of(vertices: np.ndarray) -> tuple[np.ndarray, float]:
    """A sphere enclosing points (v, 3): centre (the bounding box's) and radius."""
    lo, hi = vertices.min(axis=0), vertices.max(axis=0)
    center = (lo + hi) / 2
    return center, float(np.linalg.norm(vertices - center, axis=1).max())


def box_points(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """The 8 corners of a box, shape (8, 3)."""
    idx = np.array([[i >> 2 & 1, i >> 1 & 1, i & 1] for i in range(8)])
    return np.where(idx == 1, hi, lo)


def cylinder_points(r: float, z0: float, z1: float, sides: int = 16) -> np.ndarray:
    """Corners of a prism circumscribing a cylinder about Z, shape (2 * sides, 3)."""
    a = np.linspace(0.0, 2 * np.pi, sides, endpoint=False)
    ring = np.column_stack([np.cos(a), np.sin(a)]) * r / np.cos(np.pi / sides)
    return np.vstack([np.column_stack([ring, np.full(sides, z)]) for z in (z0, z1)])


def hull_points(vertices: np.ndarray) -> np.ndarray:
    """Vertices of the convex hull of a point set (its bounding box corners if that fails)."""
    try:
        from scipy.spatial import ConvexHull

        return vertices[ConvexHull(vertices).vertices]
    except Exception:  # degenerate (flat) point sets
        return box_points(vertices.min(axis=0), vertices.max(axis=0))


_TWIN_SIDES = 64  # a cylinder's twin prism is at most r (1 / cos(pi / 64) - 1) = 0.12 % r larger


def twin(fcl: Any, geometry: Any) -> Any:
    """Triangulated copy of a box or cylinder, enclosing it, for distances to meshes (or None).

    FCL computes the distance between two meshes with closed-form bounding-volume and triangle
    distances, but between a primitive and a mesh with GJK at every visited leaf: hundreds of
    times slower next to a large mesh.
    """
    if isinstance(geometry, fcl.Box):
        half = np.asarray(geometry.side, dtype=float) / 2
        vertices = box_points(-half, half)
        # corners are indexed by bits (x, y, z); two triangles per face, outward order
        faces = np.array(
            [
                [0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5],  # x = -, x = +
                [0, 4, 5], [0, 5, 1], [2, 3, 7], [2, 7, 6],  # y = -, y = +
                [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3],  # z = -, z = +
            ]
        )  # fmt: skip
        return bvh(fcl, vertices, faces)
    if isinstance(geometry, fcl.Cylinder):
        n = _TWIN_SIDES
        vertices = cylinder_points(geometry.radius, -geometry.lz / 2, geometry.lz / 2, n)
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
        return bvh(fcl, vertices, faces)
    return None


def machine_shapes(fcl: Any, machine: Machine) -> list[Shape]:
    """The ``<collision>`` shapes of every link (:attr:`Machine.shapes`) as FCL shapes, mm.

    Raises
    ------
    GeometryError
        A ``<collision>`` element that cannot be read, a mesh file that is missing, unreadable
        or empty.
    """
    shapes: list[Shape] = []
    zero = np.zeros(3)
    for s in machine.shapes:
        g = s.geometry
        if isinstance(g, Box):
            size = g.size
            geometry = fcl.Box(*size)
            center, radius = zero, float(np.linalg.norm(size) / 2)
            hull, pad = box_points(-size / 2, size / 2), 0.0
        elif isinstance(g, Cylinder):
            r, length = g.radius, g.length
            geometry = fcl.Cylinder(r, length)
            center, radius = zero, math.hypot(r, length / 2)
            hull, pad = cylinder_points(r, -length / 2, length / 2), 0.0
        elif isinstance(g, Sphere):
            geometry = fcl.Sphere(g.radius)
            center, radius = zero, g.radius
            hull, pad = zero[None, :], g.radius
        else:
            mesh = load_mesh(g.path, what=f"link {s.link!r} collision")
            vertices = np.asarray(mesh.vertices, dtype=float) * g.scale * M_TO_MM
            geometry = bvh(fcl, vertices, mesh.faces)
            center, radius = sphere_of(vertices)
            hull, pad = hull_points(vertices), 0.0
            if not radius > 0:
                raise GeometryError(f"{s.where}: <mesh> has zero size")
        shapes.append(Shape(s.name, MACHINE, s.link, s.origin, geometry, center, radius, hull, pad))
    return shapes


def tool_shapes(fcl: Any, tool: ToolBody, tool_length: float) -> list[Shape]:
    """The tool's sections (:meth:`ToolBody.sections`) as FCL shapes on the ``tool`` link.

    A ball-end cutter is a capsule whose lower hemisphere ends at the tip (a sphere when it is
    no longer than its diameter); every other section is a cylinder.
    """
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
            hull = cylinder_points(s.radius, -length / 2, length / 2)
        shapes.append(
            Shape(s.kind, s.kind, "tool", local, geometry, np.zeros(3), radius, hull, pad)
        )
    return shapes


def stock_shape(fcl: Any, mesh: trimesh.Trimesh) -> Shape:
    """The stock mesh (in the workpiece frame, mm) as an FCL shape on the ``workpiece`` link."""
    vertices = np.asarray(mesh.vertices, dtype=float)
    center, radius = sphere_of(vertices)
    geometry = bvh(fcl, vertices, mesh.faces)
    return Shape(
        STOCK, STOCK, "workpiece", np.eye(4), geometry, center, radius, hull_points(vertices)
    )
