"""The one :class:`Dialect` class: a spec plus the shared writer and reader."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import replace
from types import MappingProxyType

import numpy as np

from urdfpost.dialects.reader import ProgramReader, read_program
from urdfpost.dialects.spec import ROTARY_ADDRESSES, DialectSpec
from urdfpost.dialects.writer import ProgramWriter, program_writer, write_program
from urdfpost.errors import DialectError
from urdfpost.program import Program
from urdfpost.units import mm_per_unit


class Dialect:
    """An NC control: writes a :class:`Program` as text and reads such text back.

    Parameters
    ----------
    spec : DialectSpec
        What this control writes and understands.
    """

    def __init__(self, spec: DialectSpec) -> None:
        self.spec = spec

    @property
    def name(self) -> str:
        """Control name (``"heidenhain"``)."""
        return self.spec.name

    @property
    def extensions(self) -> tuple[str, ...]:
        """Program file extensions, lower case with the dot; the first is the default."""
        return self.spec.extensions

    def __repr__(self) -> str:
        return f"Dialect({self.name!r})"

    def with_clamps(self, clamps: Sequence[tuple[str, int, int]]) -> Dialect:
        """This control with a machine's rotary clamp codes (``(axis, clamp M, release M)``,
        :attr:`~urdfpost.machine.model.Settings.clamps`) among its M codes, written for and
        read as :class:`~urdfpost.program.Clamp` blocks; itself when there are none.

        Raises
        ------
        DialectError
            A code that means something else on this control.
        """
        if not clamps:
            return self
        codes = dict(self.spec.m_codes)
        for axis, on, off in clamps:
            for code, action in ((on, f"clamp_on:{axis}"), (off, f"clamp_off:{axis}")):
                if code in codes:
                    raise DialectError(
                        f"clamp code M{code} for {axis}: {self.name} has M{code} for "
                        f"{codes[code].replace('_', ' ')}; expected a code of its own"
                    )
                codes[code] = action
        return Dialect(replace(self.spec, m_codes=MappingProxyType(codes)))

    def write(
        self,
        program: Program,
        *,
        block_numbers: bool | None = None,
        header: str | None = None,
        program_number: int | None = None,
        blank: np.ndarray | None = None,
    ) -> str:
        """The program as NC text.

        Parameters
        ----------
        program : Program
            Positions in mm and degrees; written in inch when ``program.units == "inch"``.
        block_numbers : bool, optional
            Number the blocks (default: the control's practice; Heidenhain always numbers).
        header : str, optional
            Text written as comments after the program start. Without it the output depends
            on ``program`` only (no dates).
        program_number : int, optional
            Fanuc ``O``-number (default: the program name if it is a number, else 1000).
        blank : ndarray, shape (2, 3), optional
            Lowest and highest corner of the stock's box in the workpiece frame, mm: written
            where the control describes its blank (Heidenhain ``BLK FORM``).

        Returns
        -------
        str
            The program, one block per line, ending with a newline.

        Raises
        ------
        DialectError
            The program cannot be written for this control (unknown axis, TCP without a tool
            for controls that need its offset number, ...).
        """
        return write_program(
            self.spec,
            program,
            block_numbers=block_numbers,
            header=header,
            program_number=program_number,
            blank=blank,
        )

    def writer(
        self,
        program: Program,
        *,
        block_numbers: bool | None = None,
        program_number: int | None = None,
    ) -> ProgramWriter:
        """A writer for a program written in pieces: ``open(header)``, then
        ``write_body(piece)`` for each piece, ``close()``; ``take()`` gives the text written so
        far. ``program`` (the first piece) gives the name, axes, units and TCP mode; the
        parameters are those of :meth:`write`."""
        return program_writer(self.spec, program, block_numbers, program_number)

    def reader(
        self, path: str = "<string>", *, rollover: frozenset[str] = frozenset()
    ) -> ProgramReader:
        """A reader for a program given in pieces (``feed(text, verbatim)``, ``take()``): the
        counterpart of :meth:`writer` (``rollover``: as for :meth:`read`)."""
        return ProgramReader(self.spec, path, rollover)

    def read(
        self,
        text: str,
        *,
        path: str = "<string>",
        verbatim: Iterable[str] = (),
        rollover: frozenset[str] = frozenset(),
    ) -> Program:
        """Read a program of this control.

        Parameters
        ----------
        text : str
            Program text (as written by :meth:`write`, or edited by hand).
        path : str
            File name for error messages.
        verbatim : iterable of str
            Texts of the :class:`~urdfpost.program.Insert` blocks the program was written with.
            Lines equal to one of their lines are read back as ``Insert`` blocks, unparsed and
            trusted; other inserted text must be readable like any other line.
        rollover : frozenset of str
            Rotary axes the control rolls over (the machine's ``rollover`` setting,
            :attr:`~urdfpost.machine.model.Settings.rollover`): read modulo 360 and unwound
            the way the control turns them, so their positions count turns.

        Returns
        -------
        Program
            Positions in mm and degrees whatever the file units; axes not yet programmed (or
            unknown after a home return) are NaN. See :mod:`urdfpost.dialects.reader`.

        Raises
        ------
        ProgramParseError
            A line that cannot be read, with path, line number and what was expected.
        """
        return read_program(self.spec, text, path, verbatim, rollover)

    def comment_text(self, text: str) -> str:
        """``text`` as a comment reads back after writing (case, replaced characters)."""
        return self.spec.comment_text(text)

    def resolution(self, address: str, units: str) -> float:
        """One unit of the last written decimal, in mm, degrees or mm/min.

        Parameters
        ----------
        address : str
            An axis letter, or ``"F"`` for the feed.
        units : str
            Program units, "mm" or "inch".

        Returns
        -------
        float
            Written values are within half of this of the program's values.
        """
        inch = units == "inch"
        if address == "F":
            fmt = self.spec.feed_inch if inch else self.spec.feed_mm
            return fmt.resolution * (self.spec.feed_inch_unit if inch else 1.0)
        if address in ROTARY_ADDRESSES:
            return self.spec.rotary.resolution
        fmt = self.spec.linear_inch if inch else self.spec.linear_mm
        return fmt.resolution * mm_per_unit("inch" if inch else "mm")
