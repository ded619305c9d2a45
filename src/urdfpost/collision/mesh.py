"""Triangle meshes: reading stock, part and link mesh files (trimesh), and point-in-mesh tests.

trimesh is imported when a mesh is first read, so urdfpost without collision checks never loads
it.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from urdfpost.errors import GeometryError

if TYPE_CHECKING:
    import trimesh


def _import_trimesh() -> Any:
    try:
        import trimesh
    except ImportError as e:  # pragma: no cover - a declared dependency
        raise GeometryError("reading meshes needs trimesh: pip install trimesh") from e
    return trimesh


def load_mesh(path: str | os.PathLike[str], what: str = "stock") -> trimesh.Trimesh:
    """Read a triangle mesh (STL, OBJ, PLY, ... through trimesh), units as in the file.

    Parameters
    ----------
    path : str or PathLike
        The mesh file.
    what : str
        What the mesh is, for messages ("stock", "link 'fixture' collision").

    Returns
    -------
    trimesh.Trimesh

    Raises
    ------
    GeometryError
        Naming the file, when it is missing, unreadable or holds no triangles.
    """
    tm = _import_trimesh()
    p = Path(path)
    if not p.is_file():
        raise GeometryError(f"{p}: {what} file not found")
    try:
        mesh = tm.load(p, force="mesh")
    except Exception as e:  # trimesh raises many kinds for broken or unknown files
        raise GeometryError(f"{p}: cannot read the {what} mesh: {e}") from e
    if not isinstance(mesh, tm.Trimesh) or len(mesh.faces) == 0:
        raise GeometryError(
            f"{p}: the {what} mesh has no triangles (expected an STL or OBJ file of a surface)"
        )
    return mesh


def points_inside(mesh: trimesh.Trimesh, points: np.ndarray) -> np.ndarray:
    """Which points lie inside a closed mesh.

    trimesh's ray test when it has a ray engine (embreex or rtree), else the generalised
    winding number (Jacobson et al. 2013): the solid angles of all triangles seen from the
    point sum to 4 pi inside and 0 outside.

    Parameters
    ----------
    mesh : trimesh.Trimesh
    points : ndarray, shape (n, 3)
        In the mesh's frame and units.

    Returns
    -------
    ndarray, shape (n,), bool
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
