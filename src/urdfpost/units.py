"""Units of length: every conversion between program units and millimetres is made here, and
the one rule for telling whether CL data read in one unit looks like the other.

Inside urdfpost lengths are millimetres (machine files are metres, converted once at load);
CL files, programs and reports are in their own units, ``"mm"`` or ``"inch"``.

Which units apply where (the command line and the posts follow it):

- **CL units**: those the CL file declares (``UNITS/``, else a feed keyword such as ``IPM``),
  else mm; units given to the reader (``--cl-units``, ``read_cl(units=...)``) override the
  file, with a warning when the file says otherwise.
- **Program units**: those asked for (``--units``, ``PostOptions.units``), else the machine
  file's ``<urdfpost units=...>`` when it sets one, else the CL units
  (:func:`program_units`).
"""

from __future__ import annotations

from collections.abc import Sequence

MM_PER_INCH = 25.4
"""Millimetres per inch."""

M_TO_MM = 1000.0
"""Millimetres per metre (URDF lengths are metres)."""

UNITS = ("mm", "inch")
"""The program units urdfpost reads and writes."""


def mm_per_unit(units: str) -> float:
    """Millimetres per unit of length of ``units`` (``"mm"`` or ``"inch"``)."""
    return MM_PER_INCH if units == "inch" else 1.0


def program_units(asked: str | None, machine_units: str | None, cl_units: str) -> str:
    """The units a program is written in: ``asked``, else the machine file's, else the CL data's.

    Parameters
    ----------
    asked : str or None
        ``--units`` / ``PostOptions.units``.
    machine_units : str or None
        The machine file's ``units`` setting; None when the file sets none.
    cl_units : str
        Units of the CL data.

    Examples
    --------
    >>> program_units(None, None, "inch"), program_units(None, "mm", "inch")
    ('inch', 'mm')
    >>> program_units("inch", "mm", "mm")
    'inch'
    """
    return asked or machine_units or cl_units


# -- is the declared unit plausible? ----------------------------------------------------------
#
# A CL file that declares the wrong unit (an mm job labelled UNITS/INCHES, inch data in a file
# that says nothing and is read in mm) is off by 25.4 everywhere, and each figure alone can be
# real: a 4 in face mill, a 6 m gantry part, a 0.1 mm micro tool. Together they cannot, so the
# warning needs two of the three figures to point to the other unit (fewer known: none).

#: in/min. Cutting feeds above this in an inch file look like mm/min: 1000 in/min is 25 m/min,
#: beyond the cutting feed of nearly every machine tool, while 1000 mm/min is an ordinary one.
INCH_FEED_TOO_FAST = 1000.0
#: in. A cutter wider than this in a five-axis inch job looks like mm: 3 in (76 mm) is the
#: size of a face mill, not of a five-axis tool; a 3 mm tool is common.
INCH_CUTTER_TOO_LARGE = 3.0
#: in. A path wider than this in an inch file looks like mm: 200 in is over 5 m, beyond the
#: travel of most machines, and 200 mm is a small part.
INCH_EXTENT_TOO_LARGE = 200.0
#: mm/min. Cutting feeds all below this in an mm file look like in/min: 5 mm/min is slow even
#: for micro-milling, and 5 in/min (127 mm/min) is an ordinary plunge.
MM_FEED_TOO_SLOW = 5.0
#: mm. A cutter narrower than this in an mm file looks like inch: 0.5 mm is a micro tool, 0.5 in
#: (12.7 mm) a common one.
MM_CUTTER_TOO_SMALL = 0.5
#: mm. A path smaller than this in every direction in an mm file looks like inch: 5 mm is a
#: tiny part, 5 in (127 mm) an ordinary one.
MM_EXTENT_TOO_SMALL = 5.0
#: How many of the three figures must point to the other unit for the warning.
SUSPECT_FIGURES = 2


def units_doubt(
    units: str,
    *,
    feed: float | None,
    cutter: float | None,
    extent: float | None,
) -> str | None:
    """Why CL data read in ``units`` look like the other unit, or None when they do not.

    Parameters
    ----------
    units : str
        The units the data were read in ("mm" or "inch").
    feed : float or None, units/min
        The fastest programmed cutting feed per minute; None when none was programmed.
    cutter : float or None, units
        The largest cutter diameter; None when no cutter was given.
    extent : float or None, units
        The largest side of the box around the tool tips; None for no points.

    Returns
    -------
    str or None
        The figures that point to the other unit, e.g. ``"feeds up to 1181 inch/min, a 10
        inch cutter"``, when at least :data:`SUSPECT_FIGURES` of them do.

    Examples
    --------
    >>> units_doubt("inch", feed=1200.0, cutter=10.0, extent=150.0)
    'feeds up to 1200 inch/min, a 10 inch cutter'
    >>> units_doubt("inch", feed=200.0, cutter=4.0, extent=30.0) is None
    True
    """
    figures: Sequence[tuple[float | None, bool, str]]
    if units == "inch":
        figures = (
            (feed, feed is not None and feed > INCH_FEED_TOO_FAST, "feeds up to {} inch/min"),
            (cutter, cutter is not None and cutter > INCH_CUTTER_TOO_LARGE, "a {} inch cutter"),
            (extent, extent is not None and extent > INCH_EXTENT_TOO_LARGE, "a {} inch path"),
        )
    else:
        figures = (
            (feed, feed is not None and feed < MM_FEED_TOO_SLOW, "feeds of at most {} mm/min"),
            (cutter, cutter is not None and cutter < MM_CUTTER_TOO_SMALL, "a {} mm cutter"),
            (extent, extent is not None and extent < MM_EXTENT_TOO_SMALL, "a path of {} mm"),
        )
    odd = [text.format(f"{value:.4g}") for value, suspect, text in figures if suspect]
    return ", ".join(odd) if len(odd) >= SUSPECT_FIGURES else None


def other_units(units: str) -> str:
    """The other of "mm" and "inch"."""
    return "mm" if units == "inch" else "inch"
