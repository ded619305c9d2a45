"""The public modules of a package, imported: how the registries (dialects, CL readers,
strategies) find their entries, so that a new one is one new file."""

from __future__ import annotations

import importlib
import pkgutil
from collections.abc import Iterable
from types import ModuleType


def public_modules(package: str, path: Iterable[str]) -> list[ModuleType]:
    """Every module of a package whose name does not start with ``_``, imported, by name.

    Parameters
    ----------
    package : str
        The package's name (its ``__name__``).
    path : iterable of str
        Its ``__path__``.
    """
    names = sorted(m.name for m in pkgutil.iter_modules(list(path)) if not m.name.startswith("_"))
    return [importlib.import_module(f"{package}.{name}") for name in names]
