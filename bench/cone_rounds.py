"""How the cone spends a post: its rounds per piece, on the whole piece and on windows, and the
splices of its last round (issue 21).

Run::

    python bench/cone_rounds.py post /tmp/urdfpost-bench/hemisphere_1000000.apt \\
        -m dmu50 -c heidenhain --no-tcp -q -o /tmp/x.h
    python bench/cone_rounds.py post <a 10M job's pole section> -m dmu50 ... -o /tmp/x.h

The arguments are those of ``urdfpost``; the command runs in this process with
``--single-process`` (so the counts are this process's). Printed on standard error after the
command's own output: per piece planned by the cone, its points, how many rounds were planned
on the whole piece and on windows, whether the last round was spliced (``cone._spliced``) or
refused, and the CPU seconds of the whole-piece rounds; then the totals, and the CPU of the
whole command for scale. Nothing here is a test.
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass, field
from typing import Any


@dataclass
class _Piece:
    problem: Any
    points: int
    whole: int = 0
    windows: int = 0
    whole_cpu: float = 0.0
    splice: list[str] = field(default_factory=list)


def main(argv: list[str]) -> int:
    from urdfpost.cli import main as urdfpost
    from urdfpost.planning import strategies
    from urdfpost.planning.strategies import cone

    pieces: list[_Piece] = []
    planned, spliced, strategy = cone._planned, cone._spliced, cone.strategy_cone

    def counted_planned(problem: Any, tp: Any, *rest: Any) -> Any:
        start = time.process_time()
        r = planned(problem, tp, *rest)
        if problem is pieces[-1].problem:  # (a window's round has a problem of its own)
            pieces[-1].whole += 1
            pieces[-1].whole_cpu += time.process_time() - start
        else:
            pieces[-1].windows += 1
        return r

    def counted_spliced(*args: Any) -> Any:
        r = spliced(*args)
        pieces[-1].splice.append("spliced" if r is not None else "refused")
        return r

    def counted_strategy(problem: Any) -> Any:
        pieces.append(_Piece(problem, len(problem.toolpath)))
        return strategy(problem)

    cone._planned = counted_planned  # type: ignore[assignment]
    cone._spliced = counted_spliced  # type: ignore[assignment]
    strategies.STRATEGIES["cone"] = counted_strategy  # (the registry every post looks in)
    start = time.process_time()
    code = urdfpost([*argv, "--single-process"])
    total = time.process_time() - start
    err = sys.stderr
    print("piece  points  whole rounds  window rounds  last round     whole-round CPU s", file=err)
    for i, p in enumerate(pieces, 1):
        last = ",".join(p.splice) or "-"
        print(
            f"{i:5d} {p.points:7d} {p.whole:13d} {p.windows:14d}  {last:13s} {p.whole_cpu:9.3f}",
            file=err,
        )
    whole_cpu = sum(p.whole_cpu for p in pieces)
    print(
        f"pieces {len(pieces)}, whole rounds {sum(p.whole for p in pieces)}, window rounds "
        f"{sum(p.windows for p in pieces)}, spliced "
        f"{sum(s == 'spliced' for p in pieces for s in p.splice)}, refused "
        f"{sum(s == 'refused' for p in pieces for s in p.splice)}; whole-round CPU "
        f"{whole_cpu:.2f} s of {total:.2f} s ({100 * whole_cpu / max(total, 1e-9):.0f}%)",
        file=err,
    )
    return int(code or 0)


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
