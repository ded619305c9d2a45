"""Files written through a temporary file: the permissions of an ordinary file, not 0600."""

from __future__ import annotations

import os
import stat
from pathlib import Path

import pytest

from urdfpost.cli import main

ROOT = Path(__file__).resolve().parent.parent
DOME = str(ROOT / "examples" / "dome.apt")


def mode(path: Path) -> int:
    return stat.S_IMODE(path.stat().st_mode)


@pytest.fixture
def umask_022():
    old = os.umask(0o022)
    yield 0o644
    os.umask(old)


@pytest.mark.parametrize("pieces", ["0", "100"])
def test_new_files_get_the_umask_mode(tmp_path: Path, umask_022: int, pieces: str) -> None:
    """A program and report written whole or in pieces are readable by others, as a file the
    user created would be (a DNC server or a colleague reads them)."""
    out, report = tmp_path / "a.h", tmp_path / "a.json"
    args = ["post", DOME, "-m", "dmu50", "-q", "-o", str(out), "--report", str(report)]
    assert main([*args, "--piece-points", pieces]) == 0
    assert mode(out) == umask_022
    assert mode(report) == umask_022


@pytest.mark.parametrize("pieces", ["0", "100"])
def test_a_replaced_file_keeps_its_mode(tmp_path: Path, pieces: str) -> None:
    out = tmp_path / "a.h"
    out.write_text("old\n")
    out.chmod(0o640)
    assert main(["post", DOME, "-m", "dmu50", "-q", "-o", str(out), "--piece-points", pieces]) == 0
    assert mode(out) == 0o640 and out.read_text() != "old\n"


def test_python_dash_m_runs_the_command_line() -> None:
    """``python -m urdfpost`` is the ``urdfpost`` command (for environments without the
    script on the path, and for the benchmarks)."""
    import subprocess
    import sys

    from urdfpost import __version__

    done = subprocess.run(
        [sys.executable, "-m", "urdfpost", "--version"], capture_output=True, text=True, check=False
    )
    assert done.returncode == 0 and done.stdout.strip() == f"urdfpost {__version__}"
