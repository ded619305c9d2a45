"""NC control dialects: write a controller-neutral :class:`~urdfpost.program.Program` as text for
a control, and read such text back.

>>> from urdfpost.dialects import dialect_for
>>> dialect = dialect_for(path="part.h")          # or dialect_for("heidenhain")
>>> text = dialect.write(program)                  # doctest: +SKIP
>>> dialect.read(text, path="part.h")              # doctest: +SKIP

Each control is a :class:`~urdfpost.dialects.spec.DialectSpec` in its own module
(:mod:`.heidenhain`, :mod:`.siemens`, :mod:`.fanuc`, :mod:`.linuxcnc`); the writer
(:mod:`.writer`) and reader (:mod:`.reader`) are shared.
"""

from __future__ import annotations

import os
from pathlib import PurePath

from urdfpost.dialects import fanuc, heidenhain, linuxcnc, siemens
from urdfpost.dialects.dialect import Dialect
from urdfpost.dialects.spec import DialectSpec, MotionLayout, NumberFormat
from urdfpost.errors import DialectError

__all__ = ["DIALECTS", "Dialect", "DialectSpec", "MotionLayout", "NumberFormat", "dialect_for"]

DIALECTS: dict[str, Dialect] = {
    spec.name: Dialect(spec) for spec in (heidenhain.SPEC, siemens.SPEC, fanuc.SPEC, linuxcnc.SPEC)
}


def _known() -> str:
    return ", ".join(f"{name} ({'/'.join(d.extensions)})" for name, d in sorted(DIALECTS.items()))


def dialect_for(name: str | None = None, path: str | os.PathLike[str] | None = None) -> Dialect:
    """The dialect named ``name``, else the one for the extension of ``path``.

    Parameters
    ----------
    name : str, optional
        Control name, case-insensitive: heidenhain, siemens, fanuc, linuxcnc.
    path : str or PathLike, optional
        Program file; its extension picks the control when no name is given
        (.h heidenhain, .mpf/.spf siemens, .nc fanuc, .ngc linuxcnc).

    Returns
    -------
    Dialect
        The control.

    Raises
    ------
    DialectError
        Unknown name, unknown extension, or neither given; the message lists the known ones.
    """
    if name is not None:
        dialect = DIALECTS.get(name.strip().lower())
        if dialect is None:
            raise DialectError(f"unknown control {name!r}; known controls: {_known()}")
        return dialect
    if path is None:
        raise DialectError(f"no control given; name one of: {_known()}")
    suffix = PurePath(os.fspath(path)).suffix.lower()
    for dialect in DIALECTS.values():
        if suffix in dialect.extensions:
            return dialect
    raise DialectError(
        f"cannot tell the control from the extension {suffix or '(none)'!r} of "
        f"{os.fspath(path)!r}; known controls and extensions: {_known()}; or name the control"
    )
