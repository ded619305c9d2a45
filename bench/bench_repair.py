"""The singularity repair's share of a post: ``urdfpost post`` in this process, the strategy timed.

Run::

    python bench/bench_repair.py 100000 heidenhain --no-tcp
    python bench/bench_repair.py 1000000 fanuc --tcp --piece-points 0
    PYTHONPATH=<old checkout>/src python bench/bench_repair.py 100000 heidenhain --no-tcp

The hemisphere job of ``bench/make_large_cl.py`` (written once) is posted for the dmu50 by
:func:`urdfpost.cli.main` with the arguments after the control (the command a user runs, in this
process). The strategy the post takes is wrapped in a timer, and so is the joint curve of each
plan it returns: the repair is the strategy's own work plus its curve's evaluations afterwards
(:func:`urdfpost.planning.realise.realise` and the subdivision's midpoints). Printed: wall and CPU
seconds of the repair and of the whole post (CPU of this process and of its finished children:
the verification worker of a post in pieces), and the SHA-256 of the program. Nothing here is a
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
    args, post_args = parser.parse_known_args(argv)

    from urdfpost.cli import main as urdfpost_main
    from urdfpost.planning.strategies import DEFAULT_STRATEGY, STRATEGIES

    cl = ensure_file(args.points)
    strategy = STRATEGIES[DEFAULT_STRATEGY]
    own, curve = Timer(), Timer()

    def timed_strategy(problem: Any) -> Any:
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
    print(json.dumps(record), flush=True)
    return code


if __name__ == "__main__":
    raise SystemExit(main())
