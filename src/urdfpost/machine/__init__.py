"""The machine: a URDF file read once into an immutable model.

- :mod:`urdfpost.machine.model`: :class:`Machine`, :class:`Axis`, :class:`Settings` (data);
- :mod:`urdfpost.machine.urdf`: reading and checking the URDF and its ``<urdfpost>`` element;
- :mod:`urdfpost.machine.shapes`: the links' ``<collision>`` shapes as data;
- :mod:`urdfpost.machine.load`: finding machines by name and building a :class:`Machine`;
- :mod:`urdfpost.machine.setup`: the job setup (:class:`Setup`), where the program zero sits.

Examples
--------
>>> from urdfpost.machine import load_machine
>>> machine = load_machine("dmu50")
>>> machine.family, machine.axis_names
('table-table', ('X', 'Y', 'Z', 'B', 'C'))
"""

from __future__ import annotations

from urdfpost.machine.load import (
    check_geometry,
    list_machines,
    load_machine,
    machine_dirs,
    machine_from_urdf,
    resolve_machine,
    shipped_machine_dir,
    with_setup,
)
from urdfpost.machine.model import (
    MOVING_TYPES,
    NC_ADDRESSES,
    ROTARY_TYPES,
    Axis,
    Machine,
    Settings,
)
from urdfpost.machine.setup import Setup, WorkpieceMount
from urdfpost.machine.shapes import Box, Cylinder, LinkShape, Mesh, Sphere, resolve_mesh_path

__all__ = [
    "MOVING_TYPES",
    "NC_ADDRESSES",
    "ROTARY_TYPES",
    "Axis",
    "Box",
    "Cylinder",
    "LinkShape",
    "Machine",
    "Mesh",
    "Settings",
    "Setup",
    "Sphere",
    "WorkpieceMount",
    "check_geometry",
    "list_machines",
    "load_machine",
    "machine_dirs",
    "machine_from_urdf",
    "resolve_machine",
    "resolve_mesh_path",
    "shipped_machine_dir",
    "with_setup",
]
