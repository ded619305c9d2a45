"""Collision checking with FCL: the machine's ``<collision>`` shapes, the tool and the stock.

- :mod:`urdfpost.collision.world`: :class:`CollisionWorld` (bodies, pairs, queries), results;
- :mod:`urdfpost.collision.tool`: :class:`ToolBody` and its :class:`ToolSection` solids;
- :mod:`urdfpost.collision.fcl_shapes`: FCL geometry of link shapes, tool sections and stock;
- :mod:`urdfpost.collision.mesh`: reading mesh files (:func:`load_mesh`), point-in-mesh tests.

The machine's shapes are read with the machine file (:attr:`urdfpost.machine.Machine.shapes`);
``docs/collisions.md`` says which bodies are checked against which, and the limits.

An example is in :mod:`urdfpost.collision.world`.
"""

from __future__ import annotations

from urdfpost.collision.fcl_shapes import MACHINE, STOCK
from urdfpost.collision.mesh import load_mesh
from urdfpost.collision.tool import (
    CUTTER,
    DEFAULT_FLUTES_PER_DIAMETER,
    HOLDER,
    SHANK,
    ToolBody,
    ToolSection,
)
from urdfpost.collision.world import (
    DEFAULT_STEP_DEG,
    DEFAULT_STEP_MM,
    HEAD,
    HOME_CONTACT_MM,
    JOB_BODIES,
    STATIC,
    TABLE,
    Body,
    CollisionResult,
    CollisionWorld,
    MoveCollisionResult,
)
from urdfpost.machine.shapes import resolve_mesh_path

__all__ = [
    "CUTTER",
    "DEFAULT_FLUTES_PER_DIAMETER",
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
