"""Units of length: every conversion between program units and millimetres is made here.

Inside urdfpost lengths are millimetres (machine files are metres, converted once at load);
programs, CL files and reports are in the job's units, ``"mm"`` or ``"inch"``.
"""

from __future__ import annotations

MM_PER_INCH = 25.4
"""Millimetres per inch."""

M_TO_MM = 1000.0
"""Millimetres per metre (URDF lengths are metres)."""

UNITS = ("mm", "inch")
"""The program units urdfpost reads and writes."""


def mm_per_unit(units: str) -> float:
    """Millimetres per unit of length of ``units`` (``"mm"`` or ``"inch"``)."""
    return MM_PER_INCH if units == "inch" else 1.0
