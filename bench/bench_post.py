"""Benchmarks: prints figures and ratios (no pass/fail; speed is never checked in tests).

Run: ``python bench/bench_post.py`` (uses ../shared/testdata/cl when present, else the bundled
example only).
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))  # the Pinocchio reference: tests/oracles.py

from oracles import tip_and_axis_pin  # noqa: E402

from urdfpost import PostOptions, load_machine, post, read_cl  # noqa: E402
from urdfpost.kinematics import inverse, tip_and_axis  # noqa: E402

SHARED = ROOT.parent / "shared" / "testdata" / "cl"


def best_of(fn: Callable[[], object], repeat: int = 3) -> float:
    """Smallest wall time of ``repeat`` runs, s."""
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return min(times)


def bench_kinematics() -> None:
    machine = load_machine("dmu50-nutating")
    rng = np.random.default_rng(1)
    n = 20_000
    q = np.column_stack(
        [rng.uniform(-100, 100, (n, 3)), rng.uniform(0.1, 3.0, n), rng.uniform(-3, 3, n)]
    )
    tip, axis = tip_and_axis(machine, q, 100.0)
    t_vec = best_of(lambda: inverse(machine, tip, axis, 100.0))
    k = 500
    t_loop = best_of(
        lambda: [inverse(machine, tip[i : i + 1], axis[i : i + 1], 100.0) for i in range(k)]
    )
    per_vec, per_loop = t_vec / n * 1e6, t_loop / k * 1e6
    print(
        f"IK, all branches        {per_vec:8.2f} us/pose vectorised ({n} poses), "
        f"{per_loop:8.1f} us/pose one call per pose; ratio {per_loop / per_vec:6.1f}x"
    )
    t_poe = best_of(lambda: tip_and_axis(machine, q, 100.0))
    t_pin = best_of(lambda: tip_and_axis_pin(machine, q[:k], 100.0))
    print(
        f"FK product of exp.      {t_poe / n * 1e6:8.2f} us/pose; Pinocchio "
        f"{t_pin / k * 1e6:8.1f} us/pose; ratio {t_pin / k / (t_poe / n):6.1f}x"
    )


def bench_post(label: str, path: Path, machine_name: str) -> None:
    t_read = best_of(lambda: read_cl(path), repeat=1)
    toolpath = read_cl(path)
    machine = load_machine(machine_name)
    for tcp in (True, False):
        t = time.perf_counter()
        result = post(toolpath, machine, PostOptions(tcp=tcp))
        dt = time.perf_counter() - t
        v = result.verification
        print(
            f"{label:<28} {'TCP' if tcp else 'machine':<8} read {t_read:6.3f} s, post+verify "
            f"{dt:6.2f} s, {len(toolpath) / dt:8.0f} CL pts/s, {v.blocks} blocks "
            f"({v.blocks / max(len(toolpath), 1):.2f} per CL point), max dev "
            f"{v.max_tip_deviation:.4f} mm"
        )


def main() -> None:
    bench_kinematics()
    bench_post("examples/dome.apt (dmu50)", ROOT / "examples" / "dome.apt", "dmu50")
    for name in ("nx_variable_axis_ballmill_inch.cls", "nx_project2_15ops_inch.cls"):
        if (SHARED / name).is_file():
            bench_post(f"{name[:24]} (umc750)", SHARED / name, "umc750")
        else:
            print(f"{name}: not present, skipped")


if __name__ == "__main__":
    main()
