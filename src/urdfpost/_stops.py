"""Stops that are not lost: Ctrl-C and ``SIGTERM`` remembered as well as raised.

Python raises a stop (``KeyboardInterrupt``) in the main thread at the next instruction after
the signal arrives. Where that instruction is Python code that a C library called and whose
errors it clears, the stop is lost and the run goes on to its end. numpy does this: comparing
an array with an ``IntEnum`` member looks ``__array_ufunc__`` up on the enum's class (in
Python, ``EnumType.__getattr__``, up to Python 3.11) and clears any error of that lookup; a
streamed post interrupted there went on and replaced the program it had to leave alone.

The handlers of :func:`install` therefore also remember the stop, and :func:`check` raises it
again where the work can stop cleanly: between the pieces of a streamed post or verification,
between the runs a post subdivides, and before an output file is put into place.
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Callable
from types import FrameType


class Terminated(KeyboardInterrupt):
    """``SIGTERM`` received: raised in the main thread so that the run stops as at Ctrl-C,
    temporary files removed and the verification worker stopped (exit 143)."""


_received: int | None = None
"""The signal of the first stop since :func:`install` (None: none)."""


def _error(signum: int) -> KeyboardInterrupt:
    return Terminated() if signum == signal.SIGTERM else KeyboardInterrupt()


def _stop(signum: int, frame: FrameType | None) -> None:
    """The handler of Ctrl-C and ``SIGTERM``: remember the stop, then raise it (a second
    ``SIGTERM`` is ignored: the cleanup is not cut short)."""
    global _received
    if _received is None:
        _received = signum
    if signum == signal.SIGTERM:
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
    raise _error(signum)


def install() -> Callable[[], None]:
    """Handle Ctrl-C and ``SIGTERM`` with :func:`_stop`; returns what puts the handlers back as
    they were and forgets the stop received.

    Nothing changes when this does not run in the main thread (only the main thread may
    handle signals), and a signal whose handling is not Python's default (ignored by whoever
    started us, or a caller's own handler) is left alone.
    """
    global _received
    if threading.current_thread() is not threading.main_thread():
        return lambda: None
    _received = None
    saved = {s: signal.getsignal(s) for s in (signal.SIGTERM, signal.SIGINT)}
    if saved[signal.SIGTERM] is signal.SIG_DFL:
        signal.signal(signal.SIGTERM, _stop)
    if saved[signal.SIGINT] is signal.default_int_handler:
        signal.signal(signal.SIGINT, _stop)

    def restore() -> None:
        global _received
        for s, handler in saved.items():
            if handler is not None:  # (None: set outside Python, cannot be put back)
                signal.signal(s, handler)
        _received = None

    return restore


def check() -> None:
    """Raise the stop received since :func:`install` (:class:`Terminated` for ``SIGTERM``,
    ``KeyboardInterrupt`` for Ctrl-C), if any: a stop raised where it was lost is raised
    again here; without one, nothing happens.

    Raises
    ------
    KeyboardInterrupt
        The stop received.
    """
    if _received is not None:
        raise _error(_received)


def forget() -> None:
    """Forget the stop received (a forked worker, which ignores stops: the post stops it)."""
    global _received
    _received = None


__all__ = ["Terminated", "check", "forget", "install"]
