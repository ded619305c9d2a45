"""A dwell: one CL point repeated thousands of times (more than the matching searches ahead,
``REACH``), posted and verified as a user runs them.

Such a job used to be refused by its own post (the path after the dwell missed), and the
verification of a program whose blocks left the path before a dwell compared every block
after them with every repeated point (memory growing with the square of the dwell: a job
with two 8000-point dwells took 24 GB and was killed).
"""

from __future__ import annotations

import resource
import subprocess
import sys
from pathlib import Path

import pytest

from urdfpost.cli import main
from urdfpost.verification.match import REACH

ROOT = Path(__file__).resolve().parent.parent
DOME = ROOT / "examples" / "dome.apt"
DWELL = REACH + 1000
AT = "GOTO/-16.4973,"  # a CL point of the dome's first pass (Y -12) and one of its last (Y 12)


@pytest.fixture(scope="module")
def dwell_cl(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The dome with its points ``AT`` repeated ``DWELL`` times each."""
    lines = []
    for line in DOME.read_text().splitlines():
        lines += [line] * (1 + DWELL * line.startswith(AT))
    path = tmp_path_factory.mktemp("dwell") / "dwell.apt"
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.fixture(scope="module")
def dwell_program(dwell_cl: Path) -> Path:
    """The post of the dwell job (a Heidenhain program)."""
    out = dwell_cl.with_suffix(".h")
    assert main(["post", str(dwell_cl), "-m", "dmu50", "-q", "-o", str(out)]) == 0
    return out


def _verify(program: Path, cl: Path) -> subprocess.CompletedProcess[str]:
    """``urdfpost verify`` of ``program`` against ``cl`` in a process of at most 3 GB of
    address space (a memory blow-up fails there, rather than on the machine)."""

    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (3 << 30, 3 << 30))

    args = ["verify", str(program), "-m", "dmu50", "--cl", str(cl), "--angle-tolerance", "2.0"]
    return subprocess.run(
        [sys.executable, "-m", "urdfpost", *args],
        capture_output=True,
        text=True,
        preexec_fn=limit,
    )


def test_a_dwell_longer_than_the_search_is_posted_and_verified(
    dwell_cl: Path, dwell_program: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The post writes one block per repeated point and its verification reaches every CL
    point; ``urdfpost verify`` of the program says the same."""
    text = dwell_program.read_text()
    # (the repeats in full: the first block of the point leaves out the Y it does not change)
    assert text.count("L X-16.497 Y-12.000 Z+21.996") == DWELL
    proc = _verify(dwell_program, dwell_cl)
    assert proc.returncode == 0, proc.stderr
    n = 301 + 2 * DWELL
    assert f"verification within tolerance: {n}/{n} CL points reached" in proc.stdout


def test_a_program_whose_dwell_is_off_the_path_is_refused_in_bounded_memory(
    dwell_cl: Path, dwell_program: Path, tmp_path: Path
) -> None:
    """The first dwell's blocks 0.05 mm off the CL point: refused with the verdict (beyond
    tolerance, the dwell's points missed), within 3 GB (the blocks after it, compared with
    the rest of the path, the other dwell included, used to take 24 GB)."""
    bad = tmp_path / "bad.h"
    bad.write_text(
        dwell_program.read_text().replace(
            "L X-16.497 Y-12.000 Z+21.996", "L X-16.547 Y-12.000 Z+21.996"
        )
    )
    proc = _verify(bad, dwell_cl)
    assert proc.returncode == 1, proc.stderr
    assert "verification BEYOND TOLERANCE" in proc.stdout
    assert "missed CL lines: " in proc.stdout
    assert "Error" not in proc.stderr, proc.stderr
