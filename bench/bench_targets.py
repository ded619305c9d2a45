"""Issue 21's targets, measured as a user runs the commands: ``urdfpost post`` and ``urdfpost
verify`` of hemisphere jobs against the floor, and how the time grows with the job.

Run::

    python bench/bench_targets.py                          # 100k, 1M and 10M points
    python bench/bench_targets.py --sizes 100000,1000000 --runs 3
    PYTHONPATH=<old checkout>/src python bench/bench_targets.py --sizes 1000000

For each size the hemisphere job of ``bench/make_large_cl.py`` (written once) is posted for the
dmu50 (heidenhain, machine coordinates: the cone repair, subdivision, feed timing and the
read-back verification of every block; in pieces with a verification worker, the default for
files this large), and the program it writes is verified again with ``urdfpost verify`` (with
the cone's angle tolerance, 2.5 degrees, which the post used). Each command runs in its own
process; printed per run: wall seconds, CPU seconds (user + system of the command and its
worker), the peak resident memory of the larger of them, and the ratios to the floor: the
fastest of ``np.loadtxt`` of the file's GOTO lines and one regex with ``np.fromstring``
(``bench/bench_scale.py``'s), measured in this process, best of three. Then the growth of the
medians from one size to the next against the growth of the job. The SHA-256 of each program
shows that the runs (and two trees) wrote the same.

Targets (issue 21): the post within 4x the floor in wall time and 5x in CPU time, verify within
2.5x, 10M within the same ratio in under 500 MB, the growth linear. Nothing here is a test:
speed is never checked in the suite.
"""

from __future__ import annotations

import argparse
import hashlib
import itertools
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from bench_scale import floor_fromstring, floor_loadtxt  # noqa: E402
from make_large_cl import ensure_file  # noqa: E402

MACHINE = "dmu50"
CONTROL = "heidenhain"


def floor_seconds(path: Path) -> float:
    """The floor: the fastest of three reads of the GOTO numbers by each numpy method, s."""
    best = float("inf")
    for _ in range(3):
        for fn in (floor_fromstring, floor_loadtxt):
            t = time.perf_counter()
            fn(str(path))
            best = min(best, time.perf_counter() - t)
    return best


_WRAPPER = (
    "import json, resource, subprocess, sys\n"
    "proc = subprocess.run(sys.argv[1:], capture_output=True, text=True)\n"
    "use = resource.getrusage(resource.RUSAGE_CHILDREN)\n"
    "print(json.dumps([proc.returncode, proc.stderr, use.ru_utime + use.ru_stime, "
    "use.ru_maxrss]))\n"
)
"""Runs a command and prints its exit code, its errors, the CPU seconds of it and its worker,
and the peak resident memory of the largest of them, kB (its own ``RUSAGE_CHILDREN``: none of
the commands run before it)."""


def run(command: list[str]) -> dict[str, Any]:
    """One command in a subprocess: wall and CPU seconds, peak MB of its largest process."""
    t = time.perf_counter()
    proc = subprocess.run(
        [sys.executable, "-c", _WRAPPER, *command], capture_output=True, text=True, check=True
    )
    wall = time.perf_counter() - t
    code, errors, cpu, peak_kb = json.loads(proc.stdout)
    if code != 0:
        raise SystemExit(f"{' '.join(command)} failed ({code}):\n{errors}")
    return {"wall": wall, "cpu": cpu, "peak_mb": peak_kb / 1024.0}


def byte_compiled() -> Path:
    """Byte-compile the urdfpost that the commands run (the one this interpreter imports), as
    installing it does, and return its folder.

    An install (``pip install .``) writes the modules' bytecode; an editable one writes it on
    the first import, unless ``PYTHONDONTWRITEBYTECODE`` is set (as on the development
    machines), when every command would compile all of urdfpost from source again (about
    0.25 s of CPU per command): a cost of the checkout, not of the post, and one the
    commands of a user's install never pay.
    """
    import compileall

    import urdfpost

    folder = Path(urdfpost.__file__).resolve().parent
    compileall.compile_dir(str(folder), quiet=1)
    return folder


WARM_POINTS = 100_000
"""CL points of the post and verify run before the measured ones (:func:`warm_up`)."""


def warm_up(exe: list[str], folder: Path) -> int:
    """Run a post and a verify of the :data:`WARM_POINTS` job once, unmeasured: numba's cache
    of compiled kernels is kept per source file, so the first commands of a tree not run
    before (a fresh ``git archive`` of another revision) compile every kernel, about 15 s that
    an install pays once. Returns the points."""
    path = ensure_file(WARM_POINTS)
    program = folder / "warm.h"
    post = [*exe, "post", str(path), "-m", MACHINE, "-c", CONTROL, "--no-tcp", "-q"]
    subprocess.run([*post, "-o", str(program)], capture_output=True, check=True)
    verify = [*exe, "verify", str(program), "-m", MACHINE, "--cl", str(path)]
    subprocess.run([*verify, "--angle-tolerance", "2.5"], capture_output=True, check=True)
    return WARM_POINTS


def sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sizes", default="100000,1000000,10000000", help="CL points")
    parser.add_argument("--runs", type=int, default=1, help="runs of each command per size")
    parser.add_argument("--no-verify", action="store_true", help="the post only")
    args = parser.parse_args(argv)
    sizes = [int(s) for s in args.sizes.split(",")]
    exe = [sys.executable, "-m", "urdfpost"]
    print(
        f"python {sys.version.split()[0]}, {os.cpu_count()} CPUs, "
        f"load average {os.getloadavg()[0]:.1f} at the start"
    )
    print(f"byte-compiled {byte_compiled()} (as an install does)")
    medians: dict[str, dict[int, float]] = {"post": {}, "verify": {}}
    with tempfile.TemporaryDirectory() as tmp:
        warmed = warm_up(exe, Path(tmp))
        print(f"numba's cache warmed (a post and a verify of {warmed} points, not measured)")
        for n in sizes:
            path = ensure_file(n)
            floor = floor_seconds(path)
            print(f"\n{n} CL points ({path.name}); floor {floor:.3f} s")
            print(
                f"  {'command':<8} {'wall s':>8} {'CPU s':>8} {'peak MB':>8} "
                f"{'wall/floor':>11} {'CPU/floor':>10}  program SHA-256"
            )
            program = Path(tmp) / f"h{n}.h"
            for kind in ("post", "verify"):
                if kind == "verify" and args.no_verify:
                    continue
                walls = []
                for _ in range(args.runs):
                    if kind == "post":
                        command = [*exe, "post", str(path), "-m", MACHINE, "-c", CONTROL]
                        command += ["--no-tcp", "-q", "-o", str(program)]
                    else:
                        command = [*exe, "verify", str(program), "-m", MACHINE]
                        command += ["--cl", str(path), "--angle-tolerance", "2.5"]
                    r = run(command)
                    walls.append(r["wall"])
                    digest = sha256(program)[:16] if kind == "post" else ""
                    print(
                        f"  {kind:<8} {r['wall']:8.2f} {r['cpu']:8.2f} {r['peak_mb']:8.0f} "
                        f"{r['wall'] / floor:10.1f}x {r['cpu'] / floor:9.1f}x  {digest}",
                        flush=True,
                    )
                medians[kind][n] = statistics.median(walls)
    print(f"\nload average {os.getloadavg()[0]:.1f} at the end (other processes skew times)")
    for kind, by_size in medians.items():
        ordered = sorted(by_size)
        for a, b in itertools.pairwise(ordered):
            print(
                f"growth of {kind}: time({b}) / time({a}) = {by_size[b] / by_size[a]:.2f} "
                f"(points ratio {b / a:g})"
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
