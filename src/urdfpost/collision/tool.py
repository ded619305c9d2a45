"""The tool as collision bodies: sizes of cutter, shank and holder, and the solids they give.

:class:`ToolBody` holds the sizes (from a CL ``cutter`` or ``tool`` event with
:meth:`ToolBody.from_cutter`); :meth:`ToolBody.sections` places the solids of revolution
(:class:`ToolSection`) along the tool axis for a tool length. Plain data: FCL geometry is made
from the sections in :mod:`urdfpost.collision.fcl_shapes`.

Examples
--------
>>> [(s.kind, s.z0, s.z1) for s in ToolBody().sections(100.0)]
[('cutter', -100.0, -80.0), ('shank', -80.0, -60.0), ('holder', -60.0, 0.0)]
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from urdfpost.errors import GeometryError

log = logging.getLogger(__name__)

CUTTER, SHANK, HOLDER = "cutter", "shank", "holder"
"""Kinds of the tool's sections (and the names of the tool's bodies)."""

DEFAULT_FLUTES_PER_DIAMETER = 2.0
"""Cutting length of a tool whose flute length is unknown, in diameters."""

_BALL_TOL = 1e-6  # mm: a corner radius this close to half the diameter is a ball end


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

    Raises
    ------
    GeometryError
        For a size that is not a positive length, or a corner radius larger than half the
        diameter.

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
                raise GeometryError(f"tool: {what} {value!r} mm: expected a positive length")
        if not (np.isfinite(self.corner_radius) and self.corner_radius >= 0):
            raise GeometryError(
                f"tool: corner radius {self.corner_radius!r} mm: expected 0 or a positive length"
            )
        if self.corner_radius > self.diameter / 2 + _BALL_TOL:
            raise GeometryError(
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
