"""Cutter-location (CL) data readers.

Two formats, one module each:

- ``"apt"``: APT-family records (generic APT, CATIA, Creo, Siemens NX CLSF listings), see
  :mod:`urdfpost.readers.apt` for the records understood and the events emitted;
- ``"plain"``: one ``x y z [i j k]`` point per line, see :mod:`urdfpost.readers.plain`.

Every reader returns a :class:`~urdfpost.toolpath.Toolpath` in millimetres in the program's
coordinates (for NX CLSF: the first MCS, the GOTO values as written) and remembers the units it
read the file in: those given (``units=``, the command line's ``--cl-units``), else the file's
own, else mm. Files are opened only here. :func:`read_cl` reads a whole file at
once; :func:`read_cl_chunks` reads it in pieces (for files too large to hold in memory) and
hands out the same toolpath as consecutive pieces.

:data:`FORMATS` maps each format's name to its :class:`Format`: its whole-file reader, its
streaming reader and how it is detected. It is built when the package is imported from the
package's modules: every module whose name does not start with ``_`` is a format and declares
one ``FORMAT``; the formats are in the order of their names (the order of messages and of
detection).

Adding a format takes one new file, ``readers/<name>.py``, that declares ``FORMAT``::

    # src/urdfpost/readers/csv.py: comma-separated points, x,y,z,i,j,k per line
    from ._format import Format

    def read_csv_text(text, *, source="<string>", units=None, chord_tolerance=0.001):
        ...  # -> Toolpath (build it with _common.ToolpathBuilder)

    def read_csv_stream(source, *, max_points, units, chord_tolerance, text_piece):
        ...  # -> Iterator[Toolpath]: read_csv_text's toolpath in pieces (see _stream)

    FORMAT = Format(
        name="csv",
        description="comma-separated x,y,z,i,j,k points",
        read_text=read_csv_text,
        read_stream=read_csv_stream,
        detect=None,  # or detect(text, line_start) -> bool, to be recognised
    )

``read_cl(path, format="csv")`` then reads it, and ``read_cl_chunks`` too. A format with a
``detect`` function is chosen for text it recognises (detectors are tried in the order of
:data:`FORMATS`); text that none recognises is of the one format marked ``fallback`` (plain).
"""

from __future__ import annotations

import logging
import operator
import os
from collections.abc import Iterator, Mapping
from types import MappingProxyType

from urdfpost._modules import public_modules
from urdfpost.errors import CLDataError
from urdfpost.toolpath import Toolpath

from ._common import normalise_units
from ._encoding import HEAD_BYTES, check_text, encoding_of
from ._format import Format
from ._stream import check_chord_tolerance, text_pieces
from .apt import read_apt_text
from .plain import read_plain_text

logger = logging.getLogger(__name__)

__all__ = [
    "FORMATS",
    "Format",
    "detect_file_format",
    "detect_format",
    "read_apt_text",
    "read_cl",
    "read_cl_chunks",
    "read_cl_text",
    "read_plain_text",
]


def _discover(package: str, path: list[str]) -> Mapping[str, Format]:
    """The ``FORMAT`` of every public module of a package, by name.

    Parameters
    ----------
    package : str
        The package's name (``__name__``).
    path : list of str
        Its ``__path__``.

    Returns
    -------
    mapping of str to Format
        Read-only, in the order of the names.

    Raises
    ------
    TypeError
        A public module without a ``FORMAT``, two formats of one name, or not exactly one
        fallback format.
    """
    found: dict[str, Format] = {}
    for module in public_modules(package, path):
        entry = getattr(module, "FORMAT", None)
        if not isinstance(entry, Format):
            raise TypeError(
                f"{module.__name__}: expected a module-level FORMAT = Format(...) (a helper "
                f"module's name starts with '_'), got {entry!r}"
            )
        if entry.name in found:
            raise TypeError(f"{module.__name__}: format {entry.name!r} is declared twice")
        found[entry.name] = entry
    fallbacks = [name for name, entry in found.items() if entry.fallback]
    if len(fallbacks) != 1:
        raise TypeError(f"{package}: expected one fallback format, got {fallbacks}")
    return MappingProxyType(dict(sorted(found.items())))


#: Every CL format by name (sorted), found in this package's modules (see the docstring).
FORMATS: Mapping[str, Format] = _discover(__name__, __path__)

_FALLBACK = next(name for name, entry in FORMATS.items() if entry.fallback)


def _format_named(name: str) -> Format:
    """The format of a name given by a caller (any case).

    Raises
    ------
    ValueError
        For an unknown name; the message lists the known ones.
    """
    try:
        return FORMATS[name.lower()]
    except KeyError:
        raise ValueError(f"format: expected one of {', '.join(FORMATS)}, got {name!r}") from None


def detect_format(text: str) -> str:
    """Guess the format of CL text.

    Returns
    -------
    str
        The first format of :data:`FORMATS` whose detector recognises the text, else the
        fallback: "apt" when any line looks like an APT/CLSF record (``WORD/...``, or a ``$$``
        comment), else "plain".
    """
    for name, entry in FORMATS.items():
        if entry.detect is not None and entry.detect(text, True):
            return name
    return _FALLBACK


def detect_file_format(source: str, size: int = 1 << 23) -> str:
    """:func:`detect_format` of a file, read in pieces of about ``size`` bytes until it is known.

    A format is known when it is recognised in a piece and no format before it in
    :data:`FORMATS` can still be (an APT file is known at its first record); a file that only
    the fallback format fits is read to the end.

    Raises
    ------
    CLDataError
        When the file cannot be read.
    """
    detecting = [(name, entry.detect) for name, entry in FORMATS.items() if entry.detect]
    seen: set[str] = set()
    line_start = True  # whether the piece starts where the whole text has a "^" (after LF)
    for piece in text_pieces(source, size):
        # a line's match ends before its line's break, so it lies in one piece
        seen.update(name for name, detect in detecting if detect(piece, line_start))
        if detecting and detecting[0][0] in seen:  # no format before it to wait for
            return detecting[0][0]
        line_start = piece.endswith("\n")
    return next((name for name, _ in detecting if name in seen), _FALLBACK)


def read_cl_text(
    text: str,
    *,
    source: str = "<string>",
    format: str | None = None,
    units: str | None = None,
    chord_tolerance: float = 0.001,
    separate_mcs: bool = False,
) -> Toolpath:
    """Read CL data from a string.

    Parameters
    ----------
    text : str
        File contents.
    source : str
        Name used in messages and warnings.
    format : str, optional
        A key of :data:`FORMATS` (any case); detected with :func:`detect_format` when omitted.
    units : str, optional
        "mm" or "inch": the units of the values, whatever the file says (a file that says
        otherwise, ``UNITS/`` or ``IPM``/``MMPM``, gets the warning "CL file says inch at line
        L; read as mm (--cl-units)"). None: the units the file declares, else mm (never a
        machine's units).
    chord_tolerance : float, mm
        Largest chord error of points interpolated on arcs.
    separate_mcs : bool
        NX CLSF: leave the points after an ``MSYS`` of another MCS in that MCS (its ``msys``
        event's ``mcs`` index marks the change) instead of transforming them into the first
        MCS (see :mod:`urdfpost.readers.apt`).

    Returns
    -------
    Toolpath

    Raises
    ------
    CLDataError
        For data that cannot be read, among them a number that is not finite where a finite
        one is needed, and a length, once in mm, beyond
        :data:`~urdfpost.readers._common.MAX_LENGTH_MM` (a feed beyond
        :data:`~urdfpost.readers._common.MAX_FEED_MM_PER_MIN`): the message names the file,
        the record's line and the value.
    ValueError
        For an unknown format or units name, or a chord tolerance that is not positive.
    """
    if format is None:
        format = detect_format(text)
        logger.debug("%s: detected format %s", source, format)
    return _format_named(format).read_text(
        text,
        source=source,
        units=units,
        chord_tolerance=chord_tolerance,
        **_mcs_option(separate_mcs),
    )


def _mcs_option(separate_mcs: bool) -> dict[str, bool]:
    """``separate_mcs`` for a format's reader: given only when true (a format without
    coordinate systems need not take it)."""
    return {"separate_mcs": True} if separate_mcs else {}


def read_cl(
    path: str | os.PathLike[str],
    *,
    format: str | None = None,
    units: str | None = None,
    chord_tolerance: float = 0.001,
    separate_mcs: bool = False,
) -> Toolpath:
    """Read a CL file (UTF-8, or UTF-16/32 with a byte-order mark; undecodable bytes are
    replaced, a NUL byte is an error).

    Parameters
    ----------
    path : str or path-like
        The file; its name is used in messages.
    format, units, chord_tolerance, separate_mcs
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
        text,
        source=source,
        format=format,
        units=units,
        chord_tolerance=chord_tolerance,
        separate_mcs=separate_mcs,
    )


def read_cl_chunks(
    path: str | os.PathLike[str],
    *,
    max_points: int,
    format: str | None = None,
    units: str | None = None,
    chord_tolerance: float = 0.001,
    separate_mcs: bool = False,
    _text_piece: int = 1 << 23,
) -> Iterator[Toolpath]:
    """Read a CL file in pieces: :func:`read_cl` for files too large to hold in memory.

    The file is read from disk in pieces of about ``_text_piece`` characters cut at line
    breaks; the reader's state (continued record, modal feed, units, tool, tool axis, MCS,
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
    format, units, chord_tolerance, separate_mcs
        As for :func:`read_cl_text`. A detected format is detected on the whole file, as by
        :func:`read_cl` (reading stops at the first APT record).
    _text_piece : int
        Bytes read from the file at a time (characters, for ASCII text; for tests).

    Returns
    -------
    iterator of Toolpath
        Consecutive, disjoint pieces of ``read_cl(path, format=format, units=units,
        chord_tolerance=chord_tolerance, separate_mcs=separate_mcs)``, each of 1 to
        ``max_points`` points (every piece but the last has ``max_points``); a file with no
        motion gives one piece of 0 points.
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
        units name, a chord tolerance that is not positive (for a format given that has arcs,
        such as APT; for a detected one, at the first piece).
    CLDataError
        The error :func:`read_cl` raises, with the same file, line and message, when the
        iteration reaches it: pieces before the bad record may have been handed out already.
        (A continued record cut off by the end of an APT file, and a file that cannot be
        opened, are found before the first piece, as :func:`read_cl` finds them first; a NUL
        byte after the bad record is the error, as for :func:`read_cl`, which refuses it
        before reading any record; a file refused as not CL data, mostly unknown records, is
        refused at its end, see :mod:`urdfpost.readers.apt`.)

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
        entry = _format_named(format)
        format = entry.name
        if entry.arcs:
            check_chord_tolerance(chord_tolerance)
    normalise_units(units)
    return _read_chunks(
        os.fspath(path),
        max_points=max_points,
        format=format,
        units=units,
        chord_tolerance=chord_tolerance,
        text_piece=text_piece,
        separate_mcs=separate_mcs,
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
    separate_mcs: bool,
) -> Iterator[Toolpath]:
    """The pieces of :func:`read_cl_chunks` (its arguments checked)."""
    if format is None:
        format = detect_file_format(source, text_piece)
        logger.debug("%s: detected format %s", source, format)
    try:
        yield from FORMATS[format].read_stream(
            source,
            max_points=max_points,
            units=units,
            chord_tolerance=chord_tolerance,
            text_piece=text_piece,
            **_mcs_option(separate_mcs),
        )
    except CLDataError:
        # read_cl refuses a NUL anywhere in the file before it reads a record: so does this,
        # when a record before the NUL was at fault (the rest of the file is read only then)
        for _ in text_pieces(source, text_piece):
            pass
        raise
