"""Cutter-location (CL) data readers.

Two formats:

- ``"apt"``: APT-family records (generic APT, CATIA, Creo, Siemens NX CLSF listings), see
  :mod:`urdfpost.readers.apt` for the records understood and the events emitted;
- ``"plain"``: one ``x y z [i j k]`` point per line, see :mod:`urdfpost.readers.plain`.

Every reader returns a :class:`~urdfpost.toolpath.Toolpath` in millimetres in the workpiece frame
and remembers the file's units. Files are opened only here.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Callable

from urdfpost.errors import CLDataError
from urdfpost.toolpath import Toolpath

from .apt import detect_apt, read_apt_text
from .plain import read_plain_text

logger = logging.getLogger(__name__)

__all__ = [
    "READERS",
    "detect_format",
    "read_apt_text",
    "read_cl",
    "read_cl_text",
    "read_plain_text",
]

#: Reader of each format: ``reader(text, *, source, units, chord_tolerance) -> Toolpath``.
READERS: dict[str, Callable[..., Toolpath]] = {"apt": read_apt_text, "plain": read_plain_text}


def detect_format(text: str) -> str:
    """Guess the format of CL text.

    Returns
    -------
    str
        "apt" when any line looks like an APT/CLSF record (``WORD/...``, or a ``$$`` comment),
        else "plain".
    """
    return "apt" if detect_apt(text) else "plain"


def read_cl_text(
    text: str,
    *,
    source: str = "<string>",
    format: str | None = None,
    units: str | None = None,
    chord_tolerance: float = 0.001,
) -> Toolpath:
    """Read CL data from a string.

    Parameters
    ----------
    text : str
        File contents.
    source : str
        Name used in messages and warnings.
    format : str, optional
        A key of :data:`READERS`; detected with :func:`detect_format` when omitted.
    units : str, optional
        "mm" or "inch": the units of the values when the file does not say (default "mm").
        A file that says (``UNITS/``, ``IPM``/``MMPM``) wins.
    chord_tolerance : float, mm
        Largest chord error of points interpolated on arcs.

    Returns
    -------
    Toolpath

    Raises
    ------
    CLDataError
        For data that cannot be read.
    ValueError
        For an unknown format or units name, or a chord tolerance that is not positive.
    """
    if format is None:
        format = detect_format(text)
        logger.debug("%s: detected format %s", source, format)
    try:
        reader = READERS[format.lower()]
    except KeyError:
        raise ValueError(
            f"format: expected one of {', '.join(sorted(READERS))}, got {format!r}"
        ) from None
    return reader(text, source=source, units=units, chord_tolerance=chord_tolerance)


def read_cl(
    path: str | os.PathLike[str],
    *,
    format: str | None = None,
    units: str | None = None,
    chord_tolerance: float = 0.001,
) -> Toolpath:
    """Read a CL file (UTF-8; undecodable bytes are replaced).

    Parameters
    ----------
    path : str or path-like
        The file; its name is used in messages.
    format, units, chord_tolerance
        As for :func:`read_cl_text`.

    Raises
    ------
    CLDataError
        When the file cannot be read (line 0) or its data cannot.
    """
    source = os.fspath(path)
    try:
        with open(source, encoding="utf-8", errors="replace", newline="") as handle:
            text = handle.read()
    except OSError as exc:
        raise CLDataError(source, 0, f"cannot read: {exc.strerror or exc}") from exc
    return read_cl_text(
        text, source=source, format=format, units=units, chord_tolerance=chord_tolerance
    )
