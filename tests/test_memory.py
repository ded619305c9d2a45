"""The command line's allocator settings (``urdfpost._memory``)."""

from __future__ import annotations

import subprocess
import sys

import pytest

from urdfpost._memory import keep_freed_memory


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's mallopt")
def test_the_allocator_keeps_freed_memory_on_linux() -> None:
    """mallopt takes every setting on glibc (in a fresh process: once per process)."""
    code = "from urdfpost._memory import keep_freed_memory as k; print(k(), k())"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["True", "True"]


def test_keep_freed_memory_answers_once_per_process() -> None:
    assert keep_freed_memory() is keep_freed_memory()
