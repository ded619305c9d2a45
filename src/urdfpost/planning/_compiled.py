"""Compiled kernels of the planning, loaded lazily, with the numpy paths as the fallback.

The planning's sequential loops (the branch choice's dynamic programme, the cone's tube) have
numba versions in private modules next to their numpy code (``_*_kernel.py``), which compute
the same numbers in the same order of operations. numba is an optional extra (``fast``): a
:class:`Kernels` imports its module when a large path is planned first (numba's import and
the loading of the cached machine code cost about half a second per process), and from then
on for any path; without numba, or after a kernel failed in this process (a warning is logged
once), the numpy paths run, with the same results.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from types import ModuleType

log = logging.getLogger(__name__)

COMPILED_FROM = 50_000
"""CL points of a path from which planning it loads the compiled kernels (the fixed cost of
numba's import is then a small share); once loaded, they run on paths of any size."""


class Kernels:
    """A module of compiled kernels, imported on first use by a large enough path.

    Parameters
    ----------
    load : callable
        Imports and returns the module (raises ImportError without numba).
    what : str
        What the kernels do, for the warning when they fail.
    """

    def __init__(self, load: Callable[[], ModuleType], what: str) -> None:
        self._load = load
        self.what = what
        self.module: ModuleType | None = None
        self.failed: str | None = None
        self._tried = False
        self.forced: bool | None = None  # tests: True to load at any size, False never

    def get(self, points: int) -> ModuleType | None:
        """The module, or None (numba missing, a kernel failed here, or ``points`` below
        :data:`COMPILED_FROM` before it was ever loaded)."""
        if self.failed is not None or self.forced is False:
            return None
        if self.module is not None:
            return self.module
        if self._tried or (points < COMPILED_FROM and not self.forced):
            return None
        self._tried = True
        try:
            self.module = self._load()
        except ImportError:
            return None
        return self.module

    def loaded(self) -> ModuleType | None:
        """The module if it was loaded (by :meth:`get`) and has not failed, else None."""
        return None if self.failed is not None or self.forced is False else self.module

    def fail(self, error: BaseException) -> None:
        """A kernel failed (numba could not compile or cache it here): the numpy paths run
        from now on in this process."""
        self.failed = str(error)
        log.warning("compiled %s unavailable (%s); the numpy path runs", self.what, error)
