"""Closed-form inverse kinematics speed against per-point numerical IK.

Run::

    python bench/bench_ik.py                    # 100k and 1M points
    python bench/bench_ik.py --points 200000    # one size (several: comma-separated)
    python bench/bench_ik.py --machines dmu50,gantry-ca

The poses are the hemisphere finishing job of ``bench/make_large_cl.py`` (tool normal to a
40 mm hemisphere, axis up to 60 degrees from +Z, exact poles on the passes over the top),
read once per size with :func:`urdfpost.read_cl` (the file is written to the temporary
directory when absent). Every shipped machine reaches these orientations.

For each machine and size the table gives the best of three runs of
:func:`urdfpost.kinematics.inverse.inverse` (all branches, rotary and linear axes), in points
per second, and the share of points with each IK status. The numerical reference is the
per-point damped least squares IK of ``bench/bench_scale.py`` (:func:`bench_scale.numerical_ik`,
Pinocchio, warm-started from the previous point), timed on a sample of ``--sample`` points of
the same job, and the ratio is closed-form over numerical points per second. Nothing here is a
test: speed is never checked in the suite.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from bench_scale import numerical_ik  # noqa: E402
from make_large_cl import ensure_file  # noqa: E402

from urdfpost import load_machine, read_cl  # noqa: E402
from urdfpost.kinematics.inverse import IKStatus, inverse  # noqa: E402
from urdfpost.machine import Machine  # noqa: E402

MACHINES = ("dmu50", "dmu50-nutating", "gantry-ca", "monoblock", "xyzac-trt")
NUMERICAL_RUNS = 4  # the sample is this many runs of consecutive points


def best_seconds(machine: Machine, tip: np.ndarray, axis: np.ndarray, repeat: int = 3) -> float:
    """Smallest wall time of ``repeat`` calls of :func:`inverse` on all points, s."""
    tool_length = machine.settings.tool_length
    inverse(machine, tip[:1000], axis[:1000], tool_length)  # warm up
    best = np.inf
    for _ in range(repeat):
        t = time.perf_counter()
        result = inverse(machine, tip, axis, tool_length)
        best = min(best, time.perf_counter() - t)
        del result
    return best


def numerical_rate(machine: Machine, tip: np.ndarray, axis: np.ndarray, sample: int) -> float:
    """Points per second of the per-point numerical IK on ``sample`` points of the job."""
    n = len(tip)
    per_run = max(sample // NUMERICAL_RUNS, 1)
    firsts = np.linspace(0, n - per_run, NUMERICAL_RUNS).astype(int)
    index = np.concatenate([np.arange(s, s + per_run) for s in firsts])
    t = time.perf_counter()
    numerical_ik(
        str(machine.path), tip[index], axis[index], machine.settings.tool_length, NUMERICAL_RUNS
    )
    return len(index) / (time.perf_counter() - t)


def status_note(machine: Machine, tip: np.ndarray, axis: np.ndarray) -> str:
    """Share of points per IK status (on the first 100k points)."""
    k = min(len(tip), 100_000)
    status = inverse(machine, tip[:k], axis[:k], machine.settings.tool_length).status
    shares = [(s.name.lower(), np.mean(status == s)) for s in IKStatus]
    return ", ".join(f"{name} {100 * p:.3g}%" for name, p in shares if p > 0)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--points", default="100000,1000000", help="CL points, comma-separated (default 100k, 1M)"
    )
    parser.add_argument("--machines", default=",".join(MACHINES), help="comma-separated names")
    parser.add_argument(
        "--sample", type=int, default=400, help="points of the numerical IK sample (default 400)"
    )
    args = parser.parse_args(argv)
    sizes = [int(s) for s in args.points.split(",")]
    names = args.machines.split(",")
    machines = {name: load_machine(name) for name in names}
    print(
        f"python {sys.version.split()[0]}, numpy {np.__version__}, {os.cpu_count()} CPUs, "
        f"load average {os.getloadavg()[0]:.1f} at the start"
    )

    jobs = {}
    for n in sizes:
        t = time.perf_counter()
        toolpath = read_cl(ensure_file(n))
        jobs[n] = (np.ascontiguousarray(toolpath.tip), np.ascontiguousarray(toolpath.axis))
        print(f"hemisphere job, {n} points: read in {time.perf_counter() - t:.1f} s")

    tip0, axis0 = jobs[sizes[0]]
    header = f"{'machine':<16} {'family':<12} {'numerical':>11}"
    header += "".join(f" {f'{n:,} pts/s':>14} {'ratio':>6}" for n in sizes)
    print(f"\n{header}  statuses")
    for name, machine in machines.items():
        num = numerical_rate(machine, tip0, axis0, args.sample)
        row = f"{name:<16} {machine.family:<12} {num / 1e3:9.1f} k"
        for n in sizes:
            tip, axis = jobs[n]
            rate = n / best_seconds(machine, tip, axis)
            row += f" {rate / 1e6:12.2f} M {rate / num:5.0f}x"
        print(f"{row}  {status_note(machine, tip0, axis0)}", flush=True)
    print(
        f"\nnumerical: per-point Pinocchio DLS on {args.sample} points; ratio: closed-form "
        f"over numerical points/s. Load average {os.getloadavg()[0]:.1f} at the end."
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
