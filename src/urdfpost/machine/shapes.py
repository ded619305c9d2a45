"""The links' collision shapes as plain data, read from the machine file's ``<collision>`` elements.

Every ``<collision>`` element of every link becomes one :class:`LinkShape`: the link, the
element's name, its ``<origin>`` as a transform in mm, and its geometry (:class:`Box`,
:class:`Cylinder`, :class:`Sphere` or :class:`Mesh`, sizes in mm; a mesh's file is found with
:func:`resolve_mesh_path`). Nothing here builds collision objects: :mod:`urdfpost.collision`
turns the shapes into FCL geometry and reads the mesh files.

Examples
--------
>>> from lxml import etree
>>> root = etree.fromstring(
...     '<robot><link name="bed"><collision name="bed"><origin xyz="0 0 -0.3"/>'
...     '<geometry><box size="1.4 1.2 0.6"/></geometry></collision></link></robot>'
... )
>>> shape = link_shapes(root, "my-machine.urdf")[0]
>>> shape.link, shape.name, shape.geometry.size.tolist(), float(shape.origin[2, 3])
('bed', 'bed', [1400.0, 1200.0, 600.0], -300.0)
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from urdfpost.errors import GeometryError
from urdfpost.units import M_TO_MM


@dataclass(frozen=True, eq=False)
class Box:
    """A box centred on its origin.

    Attributes
    ----------
    size : ndarray, shape (3,)
        Edge lengths along the origin's x, y, z, mm.
    """

    size: np.ndarray


@dataclass(frozen=True)
class Cylinder:
    """A cylinder about its origin's z axis, centred on the origin.

    Attributes
    ----------
    radius, length : float
        mm.
    """

    radius: float
    length: float


@dataclass(frozen=True)
class Sphere:
    """A sphere centred on its origin.

    Attributes
    ----------
    radius : float
        mm.
    """

    radius: float


@dataclass(frozen=True, eq=False)
class Mesh:
    """A triangle mesh file.

    Attributes
    ----------
    path : Path
        The file, found by :func:`resolve_mesh_path`.
    filename : str
        As the ``<mesh filename>`` attribute gives it.
    scale : ndarray, shape (3,)
        The ``<mesh scale>`` attribute: from the file's units to metres (URDF units).
    """

    path: Path
    filename: str
    scale: np.ndarray


Geometry = Box | Cylinder | Sphere | Mesh
"""The geometry of one ``<collision>`` element."""


@dataclass(frozen=True, eq=False)
class LinkShape:
    """One ``<collision>`` element of a link.

    Attributes
    ----------
    link : str
        Name of the link it belongs to.
    name : str or None
        The ``<collision name>`` attribute.
    origin : ndarray, shape (4, 4)
        Placement of the shape in the link frame (the ``<origin>`` element), translation in mm.
    geometry : Box, Cylinder, Sphere or Mesh
        Sizes in mm.
    where : str
        ``file:line: link 'name' <collision>``, the start of every message about the shape.
    """

    link: str
    name: str | None
    origin: np.ndarray
    geometry: Geometry
    where: str


def _floats(text: str | None, n: int, default: tuple[float, ...], where: str) -> np.ndarray:
    """``n`` finite numbers separated by spaces, shape (n,); ``default`` when the attribute is
    absent."""
    if text is None:
        return np.array(default, dtype=float)
    count = "a" if n == 1 else str(n)
    plural = "" if n == 1 else "s"
    try:
        values = np.array([float(v) for v in text.split()])
    except ValueError as e:
        raise GeometryError(f"{where}: {text!r}: expected {count} number{plural}") from e
    if values.shape != (n,):
        raise GeometryError(f"{where}: {text!r}: expected {count} number{plural}")
    if not np.all(np.isfinite(values)):
        raise GeometryError(f"{where}: {text!r}: expected {count} finite number{plural}")
    return values


def _lengths(text: str | None, n: int, where: str) -> np.ndarray:
    """``n`` finite lengths >= 0 (a shape's sizes), shape (n,), URDF metres."""
    values = _floats(text, n, (), where)
    if np.any(values < 0):
        raise GeometryError(f"{where}: {text!r}: expected sizes >= 0")
    return values


def _origin(el: Any, where: str) -> np.ndarray:
    """Placement of the ``<origin>`` child of ``el``, shape (4, 4), translation in mm."""
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

    Parameters
    ----------
    filename : str
        As the ``<mesh filename>`` attribute gives it.
    urdf_path : str or PathLike
        The URDF file (the working directory stands in for a URDF that is no file).

    Returns
    -------
    Path
        An existing file.

    Raises
    ------
    GeometryError
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
    raise GeometryError(f"{urdf_path}: mesh {filename!r} not found (looked for {tried})")


def _geometry(shape: Any, where: str, source: str) -> Geometry:
    """The geometry of a ``<box>``, ``<cylinder>``, ``<sphere>`` or ``<mesh>`` element."""
    tag = shape.tag
    if tag == "box":
        size = _lengths(shape.get("size"), 3, f"{where}: <box size>") * M_TO_MM
        size.setflags(write=False)
        extent = float(np.linalg.norm(size) / 2)
        geometry: Geometry = Box(size)
    elif tag == "cylinder":
        r = _lengths(shape.get("radius"), 1, f"{where}: <cylinder radius>")[0]
        length = _lengths(shape.get("length"), 1, f"{where}: <cylinder length>")[0]
        r, length = r * M_TO_MM, length * M_TO_MM
        extent = math.hypot(r, length / 2)
        geometry = Cylinder(float(r), float(length))
    elif tag == "sphere":
        r = _lengths(shape.get("radius"), 1, f"{where}: <sphere radius>")[0] * M_TO_MM
        extent = float(r)
        geometry = Sphere(float(r))
    elif tag == "mesh":
        filename = shape.get("filename")
        if not filename:
            raise GeometryError(f"{where}: <mesh> without filename")
        scale = _floats(shape.get("scale"), 3, (1.0, 1.0, 1.0), f"{where}: <mesh scale>")
        scale.setflags(write=False)
        return Mesh(resolve_mesh_path(filename, source), filename, scale)
    else:
        raise GeometryError(
            f"{where}: unknown shape <{tag}>: expected box, cylinder, sphere or mesh"
        )
    if not extent > 0:
        raise GeometryError(f"{where}: <{tag}> has zero size")
    return geometry


def link_shapes(root: Any, source: str, element: str = "collision") -> tuple[LinkShape, ...]:
    """The ``<collision>`` (or ``<visual>``) elements of every link, in file order.

    Parameters
    ----------
    root : lxml.etree._Element
        The ``<robot>`` element of the parsed machine file.
    source : str
        The file's name, for messages and for finding mesh files.
    element : str
        ``"collision"`` (what the collision checks use) or ``"visual"`` (what the 3-D view
        draws); both have the same ``<origin>`` and ``<geometry>``.

    Returns
    -------
    tuple of LinkShape

    Raises
    ------
    GeometryError
        For an element without geometry, an unknown shape, a size or origin that is not
        the right count of finite numbers, a negative or zero size, a mesh without a file name
        or whose file is not found. Each message names the file, the line and the link.
    """
    shapes: list[LinkShape] = []
    for link in root.findall("link"):
        lname = link.get("name")
        for el in link.findall(element):
            where = f"{source}:{el.sourceline}: link {lname!r} <{element}>"
            origin = _origin(el, where)
            origin.setflags(write=False)
            geom_el = el.find("geometry")
            shape = None if geom_el is None or len(geom_el) == 0 else geom_el[0]
            if shape is None:
                raise GeometryError(f"{where}: no <geometry> shape")
            geometry = _geometry(shape, where, source)
            shapes.append(LinkShape(lname, el.get("name"), origin, geometry, where))
    return tuple(shapes)
