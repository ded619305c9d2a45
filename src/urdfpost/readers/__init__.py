"""Cutter-location (CL) data readers.

Two formats:

- ``"apt"``: APT-family records (generic APT, CATIA, Creo, Siemens NX CLSF listings), see
  :mod:`urdfpost.readers.apt` for the records understood and the events emitted;
- ``"plain"``: one ``x y z [i j k]`` point per line, see :mod:`urdfpost.readers.plain`.

Every reader returns a :class:`~urdfpost.toolpath.Toolpath` in millimetres in the workpiece frame
and remembers the file's units. Files are opened only here. :func:`read_cl` reads a whole file at
once; :func:`read_cl_chunks` reads it in pieces (for files too large to hold in memory) and
hands out the same toolpath as consecutive pieces.
"""

from __future__ import annotations

import logging
import operator
import os
from collections.abc import Callable, Iterator

from urdfpost.errors import CLDataError
from urdfpost.toolpath import Toolpath

from ._common import normalise_units
from ._encoding import HEAD_BYTES, check_text, encoding_of
from ._stream import STREAM_READERS, check_chord_tolerance, detect_file_format
from .apt import detect_apt, read_apt_text
from .plain import read_plain_text

logger = logging.getLogger(__name__)

__all__ = [
    "READERS",
    "detect_format",
    "read_apt_text",
    "read_cl",
    "read_cl_chunks",
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
    """Read a CL file (UTF-8, or UTF-16/32 with a byte-order mark; undecodable bytes are
    replaced, a NUL byte is an error).

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
        with open(source, "rb") as handle:
            data = handle.read()
    except OSError as exc:
        raise CLDataError(source, 0, f"cannot read: {exc.strerror or exc}") from exc
    codec, mark = encoding_of(data[:HEAD_BYTES])
    text = check_text(str(memoryview(data)[mark:], codec, "replace"), source)
    del data
    return read_cl_text(
        text, source=source, format=format, units=units, chord_tolerance=chord_tolerance
    )


def read_cl_chunks(
    path: str | os.PathLike[str],
    *,
    max_points: int,
    format: str | None = None,
    units: str | None = None,
    chord_tolerance: float = 0.001,
    _text_piece: int = 1 << 23,
) -> Iterator[Toolpath]:
    """Read a CL file in pieces: :func:`read_cl` for files too large to hold in memory.

    The file is read from disk in pieces of about ``_text_piece`` characters cut at line
    breaks; the reader's state (continued record, modal feed, units, tool, tool axis, frame,
    pending RAPID or CIRCLE, line number) goes on from one piece to the next, and points are
    handed out as soon as more than ``max_points`` are held. Memory is bounded by the two piece
    sizes, not by the file's size. An APT file is first scanned quickly for what applies to all
    of it (its units, the NX dialect, a record left open at the end of the file). The file is
    open while the pieces are taken (until the iterator ends or is closed).

    Parameters
    ----------
    path : str or path-like
        The file; its name is used in messages.
    max_points : int
        Most points in a piece (at least 1).
    format, units, chord_tolerance
        As for :func:`read_cl_text`. A detected format is detected on the whole file, as by
        :func:`read_cl` (reading stops at the first APT record).
    _text_piece : int
        Bytes read from the file at a time (characters, for ASCII text; for tests).

    Returns
    -------
    iterator of Toolpath
        Consecutive, disjoint pieces of ``read_cl(path, format=format, units=units,
        chord_tolerance=chord_tolerance)``, each of 1 to ``max_points`` points (every piece but
        the last has ``max_points``); a file with no motion gives one piece of 0 points.
        Concatenated, the pieces' ``tip``, ``axis``, ``feed``, ``motion`` and ``line`` are
        those of :func:`read_cl` bit for bit. An event is in the piece of the point it comes
        before, its ``index`` counted from the piece's first point (events after the last
        motion are in the last piece, at its length). Each warning is in the piece an event
        recorded with it would be in; in order, the pieces' warnings are :func:`read_cl`'s.
        ``units`` and ``source`` are :func:`read_cl`'s in every piece;
        ``multiaxis`` says whether a record up to the one that made the piece's last point
        carried a tool axis (``MULTAX``, six values; the points of an arc but its last are
        made by its CIRCLE record), and the last piece's is :func:`read_cl`'s.

    Raises
    ------
    ValueError
        At the call, before the file is read: ``max_points`` below 1, an unknown format or
        units name, a chord tolerance that is not positive (for an APT format given; for a
        detected one, at the first piece).
    CLDataError
        The error :func:`read_cl` raises, with the same file, line and message, when the
        iteration reaches it: pieces before the bad record may have been handed out already.
        (A continued record cut off by the end of an APT file, and a file that cannot be
        opened, are found before the first piece, as :func:`read_cl` finds them first.)

    Examples
    --------
    >>> import tempfile, pathlib
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "a.apt"
    >>> _ = path.write_text("FEDRAT/100\\nGOTO/0,0,0\\nGOTO/1,0,0\\n$$ end\\nGOTO/2,0,0\\n")
    >>> [(len(p), [e.index for e in p.events]) for p in read_cl_chunks(path, max_points=2)]
    [(2, []), (1, [0])]
    """
    max_points = _check_count(max_points, "max_points", "point")
    text_piece = _check_count(_text_piece, "_text_piece", "character")
    if format is not None:
        if format.lower() not in STREAM_READERS:
            raise ValueError(
                f"format: expected one of {', '.join(sorted(READERS))}, got {format!r}"
            )
        format = format.lower()
        if format == "apt":
            check_chord_tolerance(chord_tolerance)
    normalise_units(units)
    return _read_chunks(
        os.fspath(path),
        max_points=max_points,
        format=format,
        units=units,
        chord_tolerance=chord_tolerance,
        text_piece=text_piece,
    )


def _check_count(value: int, name: str, unit: str) -> int:
    """``value`` as an int of at least 1.

    Raises
    ------
    ValueError
        When it is not a whole number or is below 1.
    """
    try:
        count = operator.index(value)
    except TypeError:
        raise ValueError(f"{name}: expected a whole number of {unit}s, got {value!r}") from None
    if count < 1:
        raise ValueError(f"{name}: expected at least 1 {unit}, got {count}")
    return count


def _read_chunks(
    source: str,
    *,
    max_points: int,
    format: str | None,
    units: str | None,
    chord_tolerance: float,
    text_piece: int,
) -> Iterator[Toolpath]:
    """The pieces of :func:`read_cl_chunks` (its arguments checked)."""
    if format is None:
        format = detect_file_format(source, text_piece)
        logger.debug("%s: detected format %s", source, format)
    yield from STREAM_READERS[format](
        source,
        max_points=max_points,
        units=units,
        chord_tolerance=chord_tolerance,
        text_piece=text_piece,
    )
