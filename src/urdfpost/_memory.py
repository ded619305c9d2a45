"""The C allocator of a command's process, set for large numpy jobs.

A post or a verification of a million CL points makes and drops arrays of tens of megabytes
many times over. glibc's ``malloc`` gives such blocks back to the system as soon as they are
freed (``munmap``, or trimming the top of the heap), and the next array of that size is faulted
in page by page again: about a fifth of a 1M-point verify went to the kernel that way
(``bench/RESULTS.md``). :func:`keep_freed_memory` has the allocator keep what it freed for the
next array instead (``mallopt``); the peak memory is not raised, as the memory kept is what the
process held at its peak. That holds with one heap (arena) for the process: by default each
thread that allocates while another does gets an arena of its own, which keeps its own peak
(a streamed post writes in a thread while it plans: 50 to 70 MB more at its peak, measured on
the hemisphere jobs), so the threads share one. Only the command line calls it (the process is
the command's); on a C library other than glibc it does nothing.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import functools
import logging
import sys

log = logging.getLogger(__name__)

_M_TRIM_THRESHOLD = -1
_M_TOP_PAD = -2
_M_MMAP_THRESHOLD = -3
_M_ARENA_MAX = -8

MMAP_THRESHOLD = 32 * 2**20
"""Bytes from which a block is mapped on its own (glibc's largest dynamic threshold)."""

TRIM_THRESHOLD = 2**31 - 1
"""Free bytes at the top of the heap before it is given back (the largest ``mallopt`` takes)."""

TOP_PAD = 64 * 2**20
"""Bytes the heap grows by beyond each request (address space; resident only once used)."""

ARENAS = 1
"""Heaps of the process, shared by its threads (the numpy work holds the lock only while it
allocates, not while it computes)."""


@functools.cache
def keep_freed_memory() -> bool:
    """Set glibc's ``malloc`` to keep freed memory for reuse, in one heap for all threads
    (once per process, before the process starts threads).

    Returns
    -------
    bool
        Whether the settings took (False off Linux, or with another C library).
    """
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        mallopt = libc.mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes = [ctypes.c_int, ctypes.c_int]
    mallopt.restype = ctypes.c_int
    settings = (
        (_M_MMAP_THRESHOLD, MMAP_THRESHOLD),
        (_M_TRIM_THRESHOLD, TRIM_THRESHOLD),
        (_M_TOP_PAD, TOP_PAD),
        (_M_ARENA_MAX, ARENAS),
    )
    ok = all(mallopt(param, value) == 1 for param, value in settings)
    log.debug("allocator: freed memory kept for reuse: %s", ok)
    return ok
