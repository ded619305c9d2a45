"""A streamed post killed, terminated or interrupted (issues 22 and 23): no process of it is
left, the old program is intact and no temporary file remains (but the ones of ``SIGKILL``,
which nothing can remove and the next post of the same output does).

The posts run as real subprocesses in a session of their own (``start_new_session``), whose
processes are found in ``/proc``: Linux only, where the verification worker is forked.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
from jobs import write_hemisphere

from urdfpost._files import remove_stale_temps, temp_file

ROOT = Path(__file__).resolve().parent.parent
DOME = ROOT / "examples" / "dome.apt"
OLD = b"the program of the last post\n"
GONE = 5.0  # seconds within which every process of a post must be gone

linux = pytest.mark.skipif(
    not sys.platform.startswith("linux") or (os.cpu_count() or 1) < 2,
    reason="forked verification worker and /proc: Linux with more than one core",
)


@pytest.fixture(scope="module")
def long_cl(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The benchmark's hemisphere raster, 40000 points: a streamed post (in pieces of 50
    points) of several seconds, still running when the tests stop it."""
    return write_hemisphere(40000, tmp_path_factory.mktemp("cl") / "hemisphere.apt")


def session(sid: int) -> list[tuple[int, str]]:
    """The processes of session ``sid`` that have not exited: (pid, state) each (a zombie,
    which holds no file and no pipe, is left out)."""
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
        except OSError:  # exited meanwhile
            continue
        state, _ppid, _pgrp, session_id = stat.rpartition(")")[2].split()[:4]
        if int(session_id) == sid and state != "Z":
            found.append((int(entry.name), state))
    return found


def children(pid: int) -> list[int]:
    """The child processes of ``pid``."""
    kids = []
    for task in Path(f"/proc/{pid}/task").glob("*/children"):
        try:
            kids += [int(k) for k in task.read_text().split()]
        except OSError:
            pass
    return kids


def wait_for(what: str, done: Callable[[], bool], timeout: float) -> None:
    """Wait until ``done()``; fail naming ``what`` after ``timeout`` seconds."""
    end = time.monotonic() + timeout
    while not done():
        if time.monotonic() > end:
            pytest.fail(f"not within {timeout} s: {what}")
        time.sleep(0.02)


def hidden(folder: Path) -> list[str]:
    """The hidden files of ``folder`` (every temporary file of a post is one)."""
    return sorted(p.name for p in folder.iterdir() if p.name.startswith("."))


@pytest.fixture
def streamed(tmp_path: Path, long_cl: Path) -> Iterator[tuple[subprocess.Popen[bytes], Path]]:
    """A streamed post of the long job to ``tmp_path/x.h`` (which holds an old program), once
    its verification worker runs; every process of it killed at the end, whatever happened."""
    out = tmp_path / "x.h"
    out.write_bytes(OLD)
    args = [sys.executable, "-m", "urdfpost", "post", str(long_cl), "-m", "dmu50", "-o", str(out)]
    proc = subprocess.Popen(
        [*args, "--piece-points", "50"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        start_new_session=True,
        cwd=tmp_path,
    )
    try:

        def working() -> bool:
            if proc.poll() is not None:
                pytest.fail(f"the post ended before its worker started: {finished(proc)}")
            return bool(children(proc.pid)) and len(hidden(tmp_path)) == 2  # .part: staged, own

        wait_for("the verification worker starts", working, 20.0)
        yield proc, out
    finally:
        for pid, _ in session(proc.pid):
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
        if proc.poll() is None:
            proc.kill()
        proc.communicate()


def finished(proc: subprocess.Popen[bytes]) -> tuple[str, str]:
    """The post's stdout and stderr, read to their end: every process that holds the pipes
    (the post, its worker) has gone (within :data:`GONE` seconds)."""
    try:
        out, err = proc.communicate(timeout=GONE)
    except subprocess.TimeoutExpired:
        pytest.fail(f"the post's output pipes are still open {GONE} s after it was stopped")
    return out.decode(), err.decode()


@linux
def test_sigkill_leaves_no_worker_and_the_next_post_removes_its_files(
    streamed: tuple[subprocess.Popen[bytes], Path],
) -> None:
    """``SIGKILL`` of the post: its worker leaves at once (it does not hold the caller's
    pipes), the old program is intact, and what the post could not remove (its ``.part``
    files) the next post of the same output removes."""
    from urdfpost.cli import main

    proc, out = streamed
    worker = children(proc.pid)
    os.kill(proc.pid, signal.SIGKILL)
    finished(proc)
    assert proc.returncode == -signal.SIGKILL
    wait_for(f"the worker {worker} exits", lambda: not session(proc.pid), GONE)
    assert out.read_bytes() == OLD
    left = hidden(out.parent)
    assert left and all(n.startswith(".x.h.") and n.endswith(".part") for n in left), left
    assert main(["post", str(DOME), "-m", "dmu50", "-q", "-o", str(out)]) == 0
    assert out.read_bytes() != OLD
    assert hidden(out.parent) == []


@linux
@pytest.mark.parametrize(
    ("signum", "group", "line", "code"),
    [
        (signal.SIGTERM, False, "urdfpost: terminated", 143),
        (signal.SIGTERM, True, "urdfpost: terminated", 143),
        (signal.SIGINT, True, "urdfpost: interrupted", 130),  # Ctrl-C: the whole group
        (signal.SIGINT, False, "urdfpost: interrupted", 130),
    ],
    ids=["sigterm", "sigterm-group", "ctrl-c", "sigint"],
)
def test_sigterm_and_ctrl_c_stop_the_post_cleanly(
    streamed: tuple[subprocess.Popen[bytes], Path],
    signum: signal.Signals,
    group: bool,
    line: str,
    code: int,
) -> None:
    """``SIGTERM`` as Ctrl-C: one line on stderr (no traceback of the worker), exit 128 plus
    the signal, no process and no temporary file left, the old program intact."""
    proc, out = streamed
    if group:
        os.killpg(proc.pid, signum)
    else:
        os.kill(proc.pid, signum)
    stdout, stderr = finished(proc)
    assert stderr.splitlines() == [line], stderr
    assert proc.returncode == code
    assert stdout == ""
    wait_for("every process of the post exits", lambda: not session(proc.pid), GONE)
    assert out.read_bytes() == OLD
    assert hidden(out.parent) == []


@linux
def test_a_worker_whose_post_dies_leaves_without_the_kernel(tmp_path: Path) -> None:
    """Where the kernel does not kill the worker with the post (no ``PR_SET_PDEATHSIG``), the
    idle worker sees its post gone and leaves (within the poll interval)."""
    from urdfpost.posting import worker

    script = tmp_path / "post.py"
    script.write_text(
        textwrap.dedent(
            """
            import os, sys, time
            from urdfpost import load_machine
            from urdfpost.posting import worker
            from urdfpost.tolerances import Tolerances

            worker._die_with_parent = lambda parent: os.getppid() == parent  # no prctl
            checks = worker.Checks(
                load_machine("dmu50"), "heidenhain", "x.h", Tolerances.for_units("mm"), "mm",
                True,
            )
            print(checks.process.pid, flush=True)
            time.sleep(60)
            """
        )
    )
    proc = subprocess.Popen(
        [sys.executable, str(script)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        start_new_session=True,
        cwd=tmp_path,
    )
    try:
        assert proc.stdout is not None
        pid = int(proc.stdout.readline())
        assert pid in children(proc.pid)
        os.kill(proc.pid, signal.SIGKILL)
        _, err = proc.communicate(timeout=worker.PARENT_POLL + GONE)
        wait_for("the worker exits", lambda: not session(proc.pid), worker.PARENT_POLL + GONE)
        assert err == b""
    finally:
        for p, _ in session(proc.pid):
            os.kill(p, signal.SIGKILL)
        if proc.poll() is None:
            proc.kill()
        proc.communicate()


@linux
def test_an_interrupt_while_a_piece_is_handed_over_stops_the_worker(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Ctrl-C while the thread that hands a piece to the worker starts: closing stops the
    worker (and does not fail on the thread that never ran)."""
    from urdfpost import load_machine
    from urdfpost.posting.check import CheckTarget
    from urdfpost.posting.worker import Checks, PieceJob
    from urdfpost.readers import read_cl
    from urdfpost.tolerances import Tolerances
    from urdfpost.toolpath import toolpath_slice

    tol = Tolerances.for_units("mm")
    checks = Checks(load_machine("dmu50"), "heidenhain", "x.h", tol, "mm", parallel=True)
    assert checks.process is not None
    process = checks.process
    piece = toolpath_slice(read_cl(DOME), 0, 2)
    job = PieceJob(text="", inserts=[], target=CheckTarget(piece, None, 0, 0.0, 2.0, 0.0))

    def interrupted(self: threading.Thread) -> None:
        raise KeyboardInterrupt

    try:
        with monkeypatch.context() as patch:
            patch.setattr(threading.Thread, "start", interrupted)
            with pytest.raises(KeyboardInterrupt):
                checks.submit(job)
    finally:
        checks.close()
    assert not process.is_alive()


def dead_pid() -> int:
    """The id of a process that has exited (and been reaped)."""
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


@pytest.mark.skipif(os.name != "posix", reason="stale files are told by their process on POSIX")
def test_stale_temporary_files_of_the_output_only_are_removed(tmp_path: Path) -> None:
    """A new temporary file of ``x.h`` removes those of ``x.h`` whose process is gone, and
    keeps those of running processes, of other outputs and every other file."""
    dead, alive = dead_pid(), os.getppid()
    names = {
        f".x.h.{dead}-abcd1234.part": False,
        f".x.h.{dead}-abcd_234.tmp": False,
        f".x.h.{alive}-abcd1234.part": True,  # another post of x.h at work
        f".y.h.{dead}-abcd1234.part": True,  # another output
        f".x.h.{dead}-abcd1234.part.bak": True,
        ".x.h.abcd1234.part": True,  # no process in the name (older urdfpost): whose?
        "x.h": True,
    }
    for name in names:
        (tmp_path / name).write_text("x")
    fd, made = temp_file(tmp_path / "x.h")
    os.close(fd)
    assert made.name.startswith(f".x.h.{os.getpid()}-") and made.name.endswith(".part")
    kept = {p.name for p in tmp_path.iterdir()}
    assert kept == {n for n, keep in names.items() if keep} | {made.name}
    # the temporary file of a temporary file is one more of the same output
    fd, again = temp_file(made, ".tmp")
    os.close(fd)
    assert again.name.startswith(f".x.h.{os.getpid()}-") and again.name.endswith(".tmp")
    assert remove_stale_temps(tmp_path, "x.h") == []  # ours: this process runs


def interrupt(warnings: object) -> None:
    """Ctrl-C."""
    raise KeyboardInterrupt


def terminate(warnings: object) -> None:
    """``kill PID``: the handler raises where the signal is taken, after this call."""
    if signal.getsignal(signal.SIGTERM) in (signal.SIG_DFL, signal.SIG_IGN, None):
        pytest.fail("no handler of SIGTERM (the signal would end the tests)")
    os.kill(os.getpid(), signal.SIGTERM)
    time.sleep(0.5)  # (taken at once, in the main thread: this line is not finished)
    pytest.fail("SIGTERM was not taken")


@pytest.mark.parametrize("pieces", ["100", "0"])
@pytest.mark.parametrize(
    ("stop", "line", "code"),
    [
        (interrupt, "urdfpost: interrupted", 130),
        pytest.param(
            terminate,
            "urdfpost: terminated",
            143,
            marks=pytest.mark.skipif(os.name != "posix", reason="os.kill ends a Windows process"),
        ),
    ],
    ids=["ctrl-c", "sigterm"],
)
def test_a_stop_after_the_post_before_the_files_are_written(
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    pieces: str,
    stop: Callable[[object], None],
    line: str,
    code: int,
) -> None:
    """Ctrl-C or ``SIGTERM`` once the program is posted and verified, while the warnings are
    shown (in-process): one line, exit 128 plus the signal, the old program intact, nothing
    staged left; the caller's signal handlers are as they were."""
    from urdfpost import cli

    handlers = {s: signal.getsignal(s) for s in (signal.SIGTERM, signal.SIGINT)}
    out = tmp_path / "x.h"
    out.write_bytes(OLD)
    monkeypatch.setattr(cli, "_show_warnings", stop)
    args = ["post", str(DOME), "-m", "dmu50", "-q", "-o", str(out), "--piece-points", pieces]
    assert cli.main([*args, "--report", str(tmp_path / "x.json")]) == code
    assert capsys.readouterr().err.splitlines() == [line]
    assert out.read_bytes() == OLD
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.h"]
    assert {s: signal.getsignal(s) for s in handlers} == handlers
