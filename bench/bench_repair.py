"""The singularity repair's share of a post: ``urdfpost post`` in this process, the strategy timed.

Run::

    python bench/bench_repair.py 100000 heidenhain --no-tcp
    python bench/bench_repair.py 1000000 fanuc --tcp --piece-points 0
    python bench/bench_repair.py 1000000 heidenhain --no-tcp --again 3 [--numpy]
    PYTHONPATH=<old checkout>/src python bench/bench_repair.py 100000 heidenhain --no-tcp

The hemisphere job of ``bench/make_large_cl.py`` (written once) is posted for the dmu50 by
:func:`urdfpost.cli.main` with the arguments after the control (the command a user runs, in this
process). The strategy the post takes is wrapped in a timer, and so is the joint curve of each
plan it returns: the repair is the strategy's own work plus its curve's evaluations afterwards
(:func:`urdfpost.planning.realise.realise` and the subdivision's midpoints). Printed: wall and CPU
seconds of the repair and of the whole post (CPU of this process and of its finished children:
the verification worker of a post in pieces), and the SHA-256 of the program. ``--again N``
plans the post's problems N more times afterwards (numba, where used, loaded: the strategy's
steady cost, without the fixed cost of a process); ``--numpy`` turns the planning's compiled
kernels off. Nothing here is a
test: speed is never checked in the suite.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from make_large_cl import ensure_file  # noqa: E402

MACHINE = "dmu50"


def _cpu() -> float:
    """CPU seconds of this process and its finished children."""
    t = os.times()
    return t.user + t.system + t.children_user + t.children_system


class Timer:
    """Wall and CPU seconds spent inside the functions it wraps (not nested)."""

    def __init__(self) -> None:
        self.wall = 0.0
        self.cpu = 0.0
        self.calls = 0

    def wrap(self, fn: Callable[..., Any]) -> Callable[..., Any]:
        def timed(*args: Any, **kwargs: Any) -> Any:
            w, c = time.perf_counter(), time.process_time()
            try:
                return fn(*args, **kwargs)
            finally:
                self.wall += time.perf_counter() - w
                self.cpu += time.process_time() - c
                self.calls += 1

        return timed


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("points", type=int, help="CL points of the hemisphere job")
    parser.add_argument("control", help="control dialect")
    parser.add_argument(
        "--again",
        type=int,
        default=0,
        help="after the post, plan its problems again this many times (the strategy alone, "
        "numba loaded: its steady cost) and print the least CPU seconds of a pass",
    )
    parser.add_argument(
        "--numpy",
        action="store_true",
        help="the planning's numpy paths only (its compiled kernels off)",
    )
    args, post_args = parser.parse_known_args(argv)

    from urdfpost.cli import main as urdfpost_main
    from urdfpost.planning.strategies import DEFAULT_STRATEGY, STRATEGIES

    if args.numpy:
        from urdfpost.planning.branches import engine
        from urdfpost.planning.strategies import cone

        engine.KERNELS.forced = cone.KERNELS.forced = False
    cl = ensure_file(args.points)
    strategy = STRATEGIES[DEFAULT_STRATEGY]
    own, curve = Timer(), Timer()
    problems: list[Any] = []

    def timed_strategy(problem: Any) -> Any:
        if args.again:
            problems.append(problem)
        plan = own.wrap(strategy)(problem)
        return plan if plan.curve is None else replace(plan, curve=curve.wrap(plan.curve))

    STRATEGIES[DEFAULT_STRATEGY] = timed_strategy
    try:
        with tempfile.TemporaryDirectory() as tmp:
            out = Path(tmp) / "program.nc"
            cmd = ["post", str(cl), "-m", MACHINE, "-c", args.control, "-q", "-o", str(out)]
            w, c = time.perf_counter(), _cpu()
            code = urdfpost_main([*cmd, *post_args])
            wall, cpu = time.perf_counter() - w, _cpu() - c
            digest = hashlib.sha256(out.read_bytes()).hexdigest() if code == 0 else ""
    finally:
        STRATEGIES[DEFAULT_STRATEGY] = strategy
    again = []
    for _ in range(args.again):
        c = time.process_time()
        for problem in problems:
            strategy(problem)
        again.append(time.process_time() - c)
    record = {
        "points": args.points,
        "control": args.control,
        "args": post_args,
        "post_wall_s": round(wall, 3),
        "post_cpu_s": round(cpu, 3),
        "strategy_calls": own.calls,
        "strategy_wall_s": round(own.wall, 3),
        "strategy_cpu_s": round(own.cpu, 3),
        "curve_calls": curve.calls,
        "curve_wall_s": round(curve.wall, 3),
        "curve_cpu_s": round(curve.cpu, 3),
        "repair_wall_s": round(own.wall + curve.wall, 3),
        "repair_cpu_s": round(own.cpu + curve.cpu, 3),
        "sha256": digest,
    }
    if again:
        record["strategy_again_cpu_s"] = round(min(again), 3)
    print(json.dumps(record), flush=True)
    return code


if __name__ == "__main__":
    raise SystemExit(main())
