"""Verification's refinement of block deviations: compiled against numpy, inside a post.

Run::

    python bench/bench_refine.py post /tmp/urdfpost-bench/hemisphere_1000000.apt -m dmu50 \\
        -c heidenhain --no-tcp -q -o /tmp/h1m.h --single-process

The arguments are those of ``urdfpost`` (the command runs in this process; ``--single-process``
keeps the verification here too). Every refinement the verification runs compiled
(:func:`urdfpost.verification.measure._refine_compiled`, from ``COMPILED_FROM`` feed blocks with
numba) is run again on the same blocks by numpy's :func:`urdfpost.geometry.refine_max`, in
chunks as ``_block_deviation`` runs it. Printed: the blocks refined, the CPU seconds of each
(summed over the comparisons), and how many refined maxima differ and by how much (the
kernel's are kept). Nothing here is a test: speed is never checked in the suite.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable

import numpy as np

import urdfpost.verification.measure as measure
from urdfpost.cli import main
from urdfpost.geometry import chunks, refine_max

_compiled = measure._refine_compiled
spent = {"compiled": 0.0, "numpy": 0.0}
counts = {"blocks": 0, "differ": 0}
largest = [0.0]


Pair = tuple[np.ndarray, np.ndarray]


def _both(
    kernel: Callable[..., None],
    inputs: measure._KernelInputs,
    feed: measure._Blocks,
    todo: np.ndarray,
    t: np.ndarray,
    worst: Pair,
    best: Pair,
    wanted: Pair,
) -> np.ndarray:
    """The compiled refinement, timed, and numpy's on the same blocks, timed and compared."""
    sampled = (best[0].copy(), best[1].copy())
    c0 = time.process_time()
    left = _compiled(kernel, inputs, feed, todo, t, worst, best, wanted)
    c1 = time.process_time()
    numpy_best = (sampled[0].copy(), sampled[1].copy())
    for part in chunks(len(todo), 4):
        sub = todo[part]

        def errors(idx: np.ndarray, tt: np.ndarray, sub: np.ndarray = sub) -> Pair:
            dist2, chord2 = feed.errors(sub[idx], tt[None, :])
            return dist2[0], chord2[0]

        refined = refine_max(
            errors,
            t,
            (worst[0][sub], worst[1][sub]),
            (sampled[0][sub], sampled[1][sub]),
            (wanted[0][sub], wanted[1][sub]),
            iterations=measure._ITERATIONS,
        )
        numpy_best[0][sub], numpy_best[1][sub] = refined
    spent["compiled"] += c1 - c0
    spent["numpy"] += time.process_time() - c1
    counts["blocks"] += len(todo)
    for i in range(2):
        gap = np.abs(best[i][todo] - numpy_best[i][todo])
        counts["differ"] += int(np.count_nonzero(gap))
        largest[0] = max(largest[0], float(gap.max(initial=0.0)))
    return left


if __name__ == "__main__":
    measure._refine_compiled = _both
    code = main(sys.argv[1:])
    print(
        f"refined {counts['blocks']} blocks: compiled {spent['compiled']:.3f} s CPU, numpy "
        f"{spent['numpy']:.3f} s CPU; {counts['differ']} maxima differ, by at most "
        f"{largest[0]:.3g}"
    )
    sys.exit(code)
