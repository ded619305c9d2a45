"""What a CL format module declares: one :class:`Format` named ``FORMAT``.

:mod:`urdfpost.readers` finds the format modules of its package and builds
:data:`~urdfpost.readers.FORMATS` from their ``FORMAT`` entries (see its docstring for how to
add a format).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from typing import Protocol

from urdfpost.toolpath import Toolpath

__all__ = ["Detector", "Format", "StreamReader", "TextReader"]


class TextReader(Protocol):
    """Reads the whole text of a file:
    ``read_text(text, *, source, units, chord_tolerance[, separate_mcs])``.

    Parameters
    ----------
    text : str
        Whole file contents (any line breaks).
    source : str
        File name for messages.
    units : str or None
        "mm" or "inch": the units of the values, whatever the file says (a file that says
        otherwise gets a warning). None: the units the file declares, else "mm".
    chord_tolerance : float, mm
        Largest chord error of points interpolated on arcs (a format without arcs ignores it).
    separate_mcs : bool
        Passed only when true (so a format without coordinate systems may leave it out):
        points after a change of coordinate system (NX ``MSYS``) stay in theirs instead of
        being transformed into the first (see :mod:`urdfpost.readers.apt`).

    Returns
    -------
    Toolpath
        Tips in mm in the workpiece frame, unit tool axes, feeds in mm/min.

    Raises
    ------
    CLDataError
        For data that cannot be read, with the file and line.
    """

    def __call__(
        self,
        text: str,
        *,
        source: str,
        units: str | None,
        chord_tolerance: float,
        separate_mcs: bool = ...,
    ) -> Toolpath: ...


class StreamReader(Protocol):
    """Reads a file in pieces:
    ``read_stream(source, *, max_points, units, chord_tolerance, text_piece[, separate_mcs])``.

    Parameters
    ----------
    source : str
        The file (opened by the reader; :func:`~urdfpost.readers._stream.text_pieces` gives its
        text in pieces cut at line breaks, decoded as the whole-file reading decodes it).
    max_points : int
        Most points in a piece (at least 1).
    units, chord_tolerance, separate_mcs
        As for :class:`TextReader`.
    text_piece : int
        Bytes read from the file at a time.

    Yields
    ------
    Toolpath
        Consecutive pieces of what the format's :class:`TextReader` makes of the whole text,
        as :func:`~urdfpost.readers.read_cl_chunks` describes them.
    """

    def __call__(
        self,
        source: str,
        *,
        max_points: int,
        units: str | None,
        chord_tolerance: float,
        text_piece: int,
        separate_mcs: bool = ...,
    ) -> Iterator[Toolpath]: ...


class Detector(Protocol):
    """Whether text looks like the format: ``detect(text, line_start)``.

    Parameters
    ----------
    text : str
        The whole text, or a piece of it cut after a line break.
    line_start : bool
        False when ``text`` is a piece that follows a lone CR: a ``^`` of a multi-line regular
        expression does not match at its start in the whole text (it does after LF only).

    Returns
    -------
    bool
        True when a line of ``text`` marks the format.
    """

    def __call__(self, text: str, line_start: bool) -> bool: ...


@dataclass(frozen=True)
class Format:
    """One CL format: its name, readers and how it is recognised.

    Attributes
    ----------
    name : str
        The name users give (``--format``, ``read_cl(format=...)``), lower case.
    description : str
        One line for help texts.
    read_text : TextReader
        Reads the whole text at once.
    read_stream : StreamReader
        Reads a file in pieces; concatenated, the pieces are ``read_text``'s toolpath.
    detect : Detector, optional
        Recognises the format in text; None for a format chosen by name only (or the fallback).
    fallback : bool
        Whether this is the format of text that no detector recognises (exactly one format).
    arcs : bool
        Whether the format has arcs: then ``chord_tolerance`` is checked (a positive length)
        before a file is read.
    """

    name: str
    description: str
    read_text: TextReader
    read_stream: StreamReader
    detect: Detector | None = None
    fallback: bool = False
    arcs: bool = False
