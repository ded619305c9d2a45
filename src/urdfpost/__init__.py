"""urdfpost: a five-axis CNC post-processor for any machine described by a URDF.

Library entry points::

    from urdfpost import load_machine, read_cl, post, PostOptions
    machine = load_machine("umc750")
    toolpath = read_cl("part.cls")
    result = post(toolpath, machine, PostOptions(controller="fanuc"))
    print(result.text)
"""

from __future__ import annotations

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("urdfpost")
except PackageNotFoundError:  # pragma: no cover - running from a source tree
    __version__ = "0.0.0"

from urdfpost.errors import (
    CLDataError,
    DialectError,
    MachineDefinitionError,
    ToleranceError,
    UnreachableError,
    UrdfpostError,
)
from urdfpost.machine import Machine, list_machines, load_machine


def __getattr__(name: str):
    if name in ("post", "PostResult"):
        from urdfpost.posting import whole

        return getattr(whole, name)
    if name == "PostOptions":
        from urdfpost.posting.options import PostOptions

        return PostOptions
    if name == "read_cl":
        from urdfpost.readers import read_cl

        return read_cl
    if name == "verify":
        from urdfpost.verification import verify

        return verify
    raise AttributeError(f"module 'urdfpost' has no attribute {name!r}")


__all__ = [
    "CLDataError",
    "DialectError",
    "Machine",
    "MachineDefinitionError",
    "PostOptions",
    "PostResult",
    "ToleranceError",
    "UnreachableError",
    "UrdfpostError",
    "list_machines",
    "load_machine",
    "post",
    "read_cl",
    "verify",
]
