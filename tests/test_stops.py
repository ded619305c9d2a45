"""A stop (Ctrl-C, ``SIGTERM``) that Python raises where a C library clears it is not lost
(:mod:`urdfpost._stops`): the run still stops, before any output is replaced.

numpy clears every error of its ``__array_ufunc__`` lookup, which for an ``IntEnum`` operand
runs Python code (the enum class's ``__getattr__``, Python 3.11): a Ctrl-C that arrived there
vanished, and a streamed post ran on to its end and replaced the old program (about 1 in 40
interrupted posts).
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from urdfpost import _stops

ROOT = Path(__file__).resolve().parent.parent
DOME = ROOT / "examples" / "dome.apt"
OLD = b"the program of the last post\n"

posix = pytest.mark.skipif(not hasattr(signal, "SIGTERM") or os.name != "posix", reason="POSIX")


class _Sender(type):
    """A class whose attribute lookups run Python code that receives ``signum`` (the way an
    ``IntEnum``'s class looks up what numpy asks it for)."""

    signum = signal.SIGINT

    def __getattr__(cls, name: str) -> object:
        if name == "__array_ufunc__":
            os.kill(os.getpid(), cls.signum)
            for _ in range(3):  # Python handles the signal at the next instruction: here
                pass
        raise AttributeError(name)


class _Operand(int, metaclass=_Sender):
    pass


def _lost_in_numpy(signum: int) -> None:
    """Deliver ``signum`` while numpy compares an array with an operand whose class receives
    it in a lookup numpy makes (where numpy clears the error, the stop is lost)."""
    _Sender.signum = signum
    with contextlib.suppress(KeyboardInterrupt):  # (raised, where numpy lets it through)
        assert list(np.arange(3) == _Operand(1)) == [False, True, False]


@posix
@pytest.mark.parametrize(
    ("signum", "error"),
    [(signal.SIGINT, KeyboardInterrupt), (signal.SIGTERM, _stops.Terminated)],
    ids=["ctrl-c", "sigterm"],
)
def test_a_stop_lost_in_numpy_is_raised_at_the_next_check(
    signum: signal.Signals, error: type[KeyboardInterrupt]
) -> None:
    restore = _stops.install()
    try:
        _stops.check()  # nothing received: nothing raised
        _lost_in_numpy(signum)
        with pytest.raises(error) as raised:
            _stops.check()
        assert type(raised.value) is error
        with pytest.raises(error):  # (and again: it stays until the handlers are put back)
            _stops.check()
    finally:
        restore()
    _stops.check()  # forgotten with the handlers
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL


@posix
def test_a_handler_of_the_caller_is_left_alone() -> None:
    """Where the caller handles Ctrl-C itself, its handler stays (and nothing is remembered)."""
    seen: list[int] = []
    previous = signal.signal(signal.SIGINT, lambda s, f: seen.append(s))
    try:
        restore = _stops.install()
        try:
            assert signal.getsignal(signal.SIGINT) is not _stops._stop
            os.kill(os.getpid(), signal.SIGINT)
            for _ in range(3):
                pass
            assert seen == [signal.SIGINT]
            _stops.check()
        finally:
            restore()
    finally:
        signal.signal(signal.SIGINT, previous)


_SCRIPT = """
import contextlib, os, signal, sys
from urdfpost import cli
from urdfpost.posting import {module} as module

real, calls = module.post_piece, []

def lossy(*args, **kwargs):
    # the stop arrives where something clears it (as numpy does), in piece {at}
    calls.append(1)
    if len(calls) == {at}:
        with contextlib.suppress(KeyboardInterrupt):
            os.kill(os.getpid(), signal.{signal})
            for _ in range(3):
                pass
        print("lost", file=sys.stderr)
    return real(*args, **kwargs)

module.post_piece = lossy
sys.exit(cli.main(sys.argv[1:]))
"""


@posix
@pytest.mark.parametrize(
    ("module", "pieces", "at", "signame", "line", "code"),
    [
        ("stream", "50", 2, "SIGINT", "urdfpost: interrupted", 130),
        ("stream", "50", 2, "SIGTERM", "urdfpost: terminated", 143),
        ("whole", "0", 1, "SIGINT", "urdfpost: interrupted", 130),
    ],
    ids=["streamed-ctrl-c", "streamed-sigterm", "whole-ctrl-c"],
)
def test_a_post_whose_stop_is_lost_still_stops_and_keeps_the_old_program(
    tmp_path: Path, module: str, pieces: str, at: int, signame: str, line: str, code: int
) -> None:
    """A post whose stop is cleared where it was raised stops all the same: the message and
    exit code of the stop, the old program intact, no temporary file left."""
    script = tmp_path / "post.py"
    script.write_text(textwrap.dedent(_SCRIPT.format(module=module, at=at, signal=signame)))
    out = tmp_path / "x.h"
    out.write_bytes(OLD)
    args = ["post", str(DOME), "-m", "dmu50", "-q", "-o", str(out), "--piece-points", pieces]
    proc = subprocess.run(
        [sys.executable, str(script), *args], capture_output=True, text=True, cwd=tmp_path
    )
    assert proc.stderr.splitlines() == ["lost", line], proc.stderr
    assert proc.returncode == code
    assert out.read_bytes() == OLD
    assert sorted(p.name for p in tmp_path.iterdir()) == ["post.py", "x.h"]
