"""NC control dialects: write a controller-neutral :class:`~urdfpost.program.Program` as text for
a control, and read such text back.

>>> from urdfpost.dialects import dialect_for
>>> dialect = dialect_for(path="part.h")          # or dialect_for("heidenhain")
>>> text = dialect.write(program)                  # doctest: +SKIP
>>> dialect.read(text, path="part.h")              # doctest: +SKIP

Each control is a :class:`~urdfpost.dialects.spec.DialectSpec` in its own module
(:mod:`.heidenhain`, :mod:`.siemens`, :mod:`.fanuc`, :mod:`.linuxcnc`); the writer
(:mod:`.writer`) and reader (:mod:`.reader`) are shared.

:data:`DIALECTS` is built when the package is imported: every module of the package whose name
does not start with ``_`` and that has a module-level ``SPEC`` (a ``DialectSpec``) is a control
(the shared modules :mod:`.dialect`, :mod:`.spec`, :mod:`.reader`, :mod:`.writer` have none).
The controls are in the order of their modules' ``RANK`` (an int; a module without one comes
after those with one), then of their names: heidenhain, siemens, fanuc, linuxcnc. The order is
the one of :data:`DIALECTS` (the first control whose extension matches wins in
:func:`dialect_for`); lists for people are sorted by name.

Adding a control takes one new file, ``dialects/<name>.py``, that declares ``SPEC``, for
instance a control that writes Fanuc's G-code in files of its own extension::

    # src/urdfpost/dialects/mazak.py: Mazak Smooth in EIA/ISO mode
    import dataclasses

    from urdfpost.dialects import fanuc

    RANK = 4  # optional: its place (without one: after the ranked controls, by name)

    SPEC = dataclasses.replace(fanuc.SPEC, name="mazak", extensions=(".eia",))

``dialect_for("mazak")`` and ``dialect_for(path="part.eia")`` then find it, and the command
line offers it. A control unlike the others fills a ``DialectSpec(...)`` of its own (every
field is described in :mod:`.spec`; :mod:`.fanuc` is a complete one), and syntax that is not
word-address G-code goes in the same module as the hooks its spec names (:mod:`.heidenhain`).
"""

from __future__ import annotations

import math
import os
from pathlib import PurePath

from urdfpost._modules import public_modules
from urdfpost.dialects.dialect import Dialect
from urdfpost.dialects.spec import DialectSpec, MotionLayout, NumberFormat
from urdfpost.errors import DialectError

__all__ = ["DIALECTS", "Dialect", "DialectSpec", "MotionLayout", "NumberFormat", "dialect_for"]


def _discover(package: str, path: list[str]) -> dict[str, Dialect]:
    """The dialect of every public module of a package that has a module-level ``SPEC``.

    Parameters
    ----------
    package : str
        The package's name (``__name__``).
    path : list of str
        Its ``__path__``.

    Returns
    -------
    dict of str to Dialect
        By control name, in the order of the modules' ``RANK`` (none: last), then of the names.

    Raises
    ------
    TypeError
        Two controls of one name, or a ``RANK`` that is not an int.
    """
    found: dict[str, tuple[float, Dialect]] = {}
    for module in public_modules(package, path):
        spec = getattr(module, "SPEC", None)
        if not isinstance(spec, DialectSpec):
            continue
        rank = getattr(module, "RANK", math.inf)
        if rank is not math.inf and (not isinstance(rank, int) or isinstance(rank, bool)):
            raise TypeError(f"{module.__name__}: expected an int RANK, got {rank!r}")
        if spec.name in found:
            raise TypeError(f"{module.__name__}: control {spec.name!r} is declared twice")
        found[spec.name] = (rank, Dialect(spec))
    ordered = sorted(found.items(), key=lambda item: (item[1][0], item[0]))
    return {name: dialect for name, (_, dialect) in ordered}


#: Every control by name, in the order described above (found in this package's modules).
DIALECTS: dict[str, Dialect] = _discover(__name__, __path__)


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
