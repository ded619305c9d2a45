"""Forward and inverse kinematics of the tool relative to the workpiece."""

from urdfpost.kinematics.forward import (
    linear_directions,
    rotate,
    rotation_about,
    tip_and_axis,
    tool_in_work,
)
from urdfpost.kinematics.inverse import (
    IKResult,
    IKStatus,
    RotarySolutions,
    assemble,
    inverse,
    solve_linear,
    solve_rotary,
)

__all__ = [
    "IKResult",
    "IKStatus",
    "RotarySolutions",
    "assemble",
    "inverse",
    "linear_directions",
    "rotate",
    "rotation_about",
    "solve_linear",
    "solve_rotary",
    "tip_and_axis",
    "tool_in_work",
]
