"""Compiled kernels, loaded lazily, with the numpy paths as the fallback.

Sequential loops (the planning's branch choice and cone tube, the verification's matching and
deviations, the readers' scans of CL and program text, the collision culling) have numba
versions in private modules next to their numpy code (``_*_kernel.py``), which compute the same
numbers. numba is an optional extra (``fast``): a :class:`Kernels` imports its module when a
large enough task asks for it first (numba's import and the loading of the cached machine code
cost about half a second per process); without numba, or after a kernel failed in this process
(a warning is logged once), the numpy paths run, with the same results.
"""

from __future__ import annotations

import logging
import sys
from collections.abc import Callable
from types import ModuleType

log = logging.getLogger(__name__)

COMPILED_FROM = 50_000
"""The default size of a task (CL points of a path for the planning) from which the kernels
are loaded (the fixed cost of numba's import is then a small share)."""


_BLAS_PROBE = "scipy.linalg"
"""What numba imports, the first time its CPU target is made ready in a process, to learn
whether a BLAS is there for its array functions (:func:`start_numba`)."""

_started = False


def start_numba() -> None:
    """Import numba and make its CPU target ready, without the import of :mod:`scipy.linalg`
    it makes on the way.

    The first kernel a process calls makes numba's CPU target ready: it imports numba's
    implementations of the numpy functions, one of which (``numba.np.arraymath``) imports
    ``scipy.linalg`` only to learn whether a BLAS is there for ``np.dot`` and the like (about a
    quarter of a second per process, on the critical path of a post and of a verification).
    No kernel of urdfpost calls a BLAS function, so the target is made ready here with that
    probe (``numba.np.linalg.ensure_blas``, which ``numba.np.arraymath`` takes in as it is
    imported) failing at once; it is put back right after, so numba's linear algebra and
    ``scipy.linalg`` work as ever later on. numba then notes that it has no BLAS, which
    changes only how a kernel that called ``np.dot`` on arrays would be compiled (a loop of its
    own). Where numba or scipy.linalg is imported already, or numba is missing (the ImportError
    is the caller's), nothing else is done. Once per process.

    Raises
    ------
    ImportError
        numba is not installed.
    """
    global _started
    if _started:
        return
    import numba  # noqa: F401  (ImportError: numba is missing)

    _started = True
    if _BLAS_PROBE in sys.modules or "numba.np.arraymath" in sys.modules:
        return
    import numba.np.linalg as linalg
    from numba.core.registry import cpu_target

    def no_probe() -> None:
        raise ImportError("no BLAS probe (urdfpost._compiled.start_numba)")

    probe = linalg.ensure_blas
    linalg.ensure_blas = no_probe  # what numba.np.arraymath takes for its probe
    try:
        cpu_target.target_context.refresh()
    finally:
        linalg.ensure_blas = probe


class Kernels:
    """A module of compiled kernels, imported on first use by a large enough task.

    Parameters
    ----------
    load : callable
        Imports and returns the module (raises ImportError without numba).
    what : str
        What the kernels do, for the warning when they fail.
    start : int
        Size of a task from which the kernels are used (:meth:`wanted`).
    warm_start : int, optional
        Size from which they are used once numba is imported in this process (by these kernels
        or others): then only their own cached code is loaded. None: ``start`` always.
    stays : bool
        Whether, once loaded, the kernels are used for tasks of any size; else only for tasks
        from ``start`` (or ``warm_start``) on.
    logger : logging.Logger
        Where the warning goes.
    warning : str
        The warning when a kernel fails, with ``what`` and the reason for its two ``%s``.
    first_line : bool
        Whether the warning gives the first line of the error only (the whole error is logged
        at debug level).
    """

    def __init__(
        self,
        load: Callable[[], ModuleType],
        what: str,
        *,
        start: int = COMPILED_FROM,
        warm_start: int | None = None,
        stays: bool = True,
        logger: logging.Logger = log,
        warning: str = "compiled %s unavailable (%s); the numpy path runs",
        first_line: bool = False,
    ) -> None:
        self._load = load
        self.what = what
        self.start = start
        self.warm_start = warm_start
        self.stays = stays
        self._log = logger
        self._warning = warning
        self._first_line = first_line
        self.module: ModuleType | None = None
        self.failed: str | None = None
        self._tried = False
        self.forced: bool | None = None  # tests: True to use at any size, False never

    def wanted(self, size: int) -> bool:
        """Whether a task of ``size`` uses the kernels (when they can be loaded): from
        ``start`` on (``warm_start`` once numba is imported), or at any size once loaded if
        they stay."""
        if self.forced is not None:
            return self.forced
        if self.stays and self.module is not None:
            return True
        start = self.start
        if self.warm_start is not None and "numba" in sys.modules:
            start = self.warm_start
        return size >= start

    def get(self, size: int) -> ModuleType | None:
        """The module for a task of ``size``, or None (:meth:`wanted` says no, numba is
        missing, or a kernel failed here)."""
        return self.load() if self.wanted(size) else None

    def load(self) -> ModuleType | None:
        """The module, imported on the first call whatever the size, or None (numba missing,
        a kernel failed here, or ``forced`` off)."""
        if self.failed is not None or self.forced is False:
            return None
        if self.module is None and not self._tried:
            try:  # (a thread asking meanwhile imports it too: the import lock gives it the same)
                start_numba()
                self.module = self._load()
            except ImportError:
                pass
            self._tried = True
        return self.module

    def loaded(self) -> ModuleType | None:
        """The module if it was loaded and has not failed, else None (never imports it)."""
        return None if self.failed is not None or self.forced is False else self.module

    def fail(self, error: BaseException) -> None:
        """A kernel failed (numba could not compile or cache it here): the numpy paths run
        from now on in this process."""
        self.failed = str(error)
        reason: object = error
        if self._first_line:
            reason = (str(error).strip().splitlines() or [type(error).__name__])[0]
        self._log.warning(self._warning, self.what, reason)
        if self._first_line:
            self._log.debug("compiled %s failed", self.what, exc_info=error)
