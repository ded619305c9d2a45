"""CL reading benchmark: :func:`urdfpost.read_cl` and :func:`urdfpost.read_cl_chunks` of an APT
file against the numpy floor.

Run::

    python bench/make_large_cl.py 1000000 -o /tmp/h1m.apt
    python bench/bench_cl_read.py /tmp/h1m.apt                  # 5 rounds
    python bench/bench_cl_read.py /tmp/h1m.apt --rounds 3 --numpy --cold

Each round times, one after the other (the machine's other work spreads over all of them):
the floor (``np.loadtxt`` of the GOTO lines' numbers, ``floor_loadtxt`` of
``bench/bench_scale.py``), :func:`~urdfpost.readers.read_cl` of the file, and
:func:`~urdfpost.readers.read_cl_chunks` of it in pieces of
:data:`urdfpost.posting.PIECE_POINTS` points (every piece taken, as ``urdfpost post`` does).
Wall seconds (``time.perf_counter``) and this process's CPU seconds (``time.process_time``)
each; then the median ratios to the floor. A warm-up read comes first, so numba's import and
the loading of its cached machine code (the compiled GOTO scan,
:mod:`urdfpost.readers._goto_kernel`) are not in the rounds; ``--cold`` times them: one read
in a fresh interpreter, with and without the compiled scan. ``--numpy`` reads without the
compiled scan (the numpy path); ``--numba-imported`` imports numba first (then the compiled scan
runs from :data:`urdfpost.readers.apt.COMPILED_WARM_FROM` characters, else from
:data:`~urdfpost.readers.apt.COMPILED_FROM`). Nothing here is a test.
"""

from __future__ import annotations

import argparse
import logging
import statistics
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from bench_scale import floor_loadtxt  # noqa: E402

log = logging.getLogger("bench_read")

_COLD = """
import sys, time
t0 = time.perf_counter(); c0 = time.process_time()
import urdfpost.readers.apt as apt
from urdfpost.readers import read_cl
if sys.argv[2] == "numpy":
    apt.KERNELS.start = apt.KERNELS.warm_start = 1 << 62
tp = read_cl(sys.argv[1])
print(time.perf_counter() - t0, time.process_time() - c0, len(tp))
"""


def timed(fn: Callable[[], Any]) -> tuple[float, float]:
    """Wall and CPU seconds of one call of ``fn``."""
    t, c = time.perf_counter(), time.process_time()
    fn()
    return time.perf_counter() - t, time.process_time() - c


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("path", help="an APT file (bench/make_large_cl.py)")
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--numpy", action="store_true", help="without the compiled scan")
    parser.add_argument("--cold", action="store_true", help="also time a read in a new process")
    parser.add_argument(
        "--numba-imported",
        action="store_true",
        help="import numba first, as a post does (the compiled scan then runs from "
        "COMPILED_WARM_FROM characters, not COMPILED_FROM)",
    )
    args = parser.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(message)s")

    import urdfpost.readers.apt as apt
    from urdfpost.posting import PIECE_POINTS
    from urdfpost.readers import read_cl, read_cl_chunks

    if args.numpy:
        apt.KERNELS.start = apt.KERNELS.warm_start = 1 << 62
    if args.numba_imported:
        import numba  # noqa: F401

    def chunks() -> None:
        for piece in read_cl_chunks(args.path, max_points=PIECE_POINTS):
            del piece

    jobs: dict[str, Callable[[], Any]] = {
        "floor": lambda: floor_loadtxt(args.path),
        "read_cl": lambda: read_cl(args.path),
        "read_cl_chunks": chunks,
    }
    points = len(read_cl(args.path))  # warm-up: imports, numba's cache, the page cache
    log.info("%s: %d points, %s", args.path, points, "numpy" if args.numpy else "default")
    got: dict[str, list[tuple[float, float]]] = {name: [] for name in jobs}
    for _ in range(args.rounds):
        for name, fn in jobs.items():
            got[name].append(timed(fn))
    floor = statistics.median(w for w, _ in got["floor"])
    floor_cpu = statistics.median(c for _, c in got["floor"])
    for name, runs in got.items():
        wall = statistics.median(w for w, _ in runs)
        cpu = statistics.median(c for _, c in runs)
        log.info(
            "%-15s wall %s (median %.3f, %.2fx floor); CPU %s (median %.3f, %.2fx floor)",
            name,
            ", ".join(f"{w:.3f}" for w, _ in runs),
            wall,
            wall / floor,
            ", ".join(f"{c:.3f}" for _, c in runs),
            cpu,
            cpu / floor_cpu,
        )
    if args.cold:
        for how in ("numpy", "default"):
            out = subprocess.run(
                [sys.executable, "-c", _COLD, args.path, how],
                check=True,
                capture_output=True,
                text=True,
            ).stdout.split()
            log.info(
                "cold read_cl (%s, imports included): wall %.3f s, CPU %.3f s",
                how,
                *map(float, out[:2]),
            )


if __name__ == "__main__":
    main()
