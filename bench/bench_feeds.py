"""The post's feed timing: compiled tip path lengths against numpy, inside a post.

Run::

    python bench/bench_feeds.py post /tmp/urdfpost-bench/hemisphere_1000000.apt -m dmu50 \\
        -c heidenhain --no-tcp -q -o /tmp/h1m.h --single-process

The arguments are those of ``urdfpost`` (the command runs in this process; ``--single-process``
keeps the verification here too). Every :func:`urdfpost.posting.feeds.timed_program` the post
runs is run twice on the same program: with the compiled tip path lengths
(:data:`urdfpost.verification.feeds.KERNELS` forced off) and without (forced on); the two
programs' F words and figures must be the same. Printed: the CPU seconds of each, summed over
the pieces, and of the tip path lengths within them; and the CPU seconds of the verification's
:func:`~urdfpost.verification.feeds.measure_feeds` and of the rows' realisation
(:func:`urdfpost.planning.realise.realise`). Against a tree without the kernels (``PYTHONPATH``
to an older copy) the one path there is timed. Nothing here is a test: speed is never checked in
the suite.
"""

from __future__ import annotations

import sys
import time
from collections import defaultdict
from collections.abc import Callable
from typing import Any

import numpy as np

import urdfpost.posting.feeds as posting_feeds
import urdfpost.posting.piece as piece
import urdfpost.verification.feeds as feeds
import urdfpost.verification.measure as measure
from urdfpost.cli import main

spent: dict[str, float] = defaultdict(float)
counts: dict[str, int] = defaultdict(int)
mode = ["compiled"]
KERNELS = getattr(feeds, "KERNELS", None)  # (None: a tree from before the kernels)
LENGTHS = "tip_lengths_at" if hasattr(posting_feeds, "tip_lengths_at") else "tip_lengths"


def timed(key: str, fn: Callable[..., Any]) -> Callable[..., Any]:
    """``fn``, its CPU seconds added to ``spent[key]`` and its calls counted."""

    def run(*args: Any, **kwargs: Any) -> Any:
        c = time.process_time()
        out = fn(*args, **kwargs)
        spent[key] += time.process_time() - c
        counts[key] += 1
        return out

    return run


def _lengths(fn: Callable[..., Any]) -> Callable[..., Any]:
    """The tip path lengths of ``timed_program``, timed in the current mode."""

    def run(*args: Any, **kwargs: Any) -> Any:
        c = time.process_time()
        out = fn(*args, **kwargs)
        spent[f"lengths {mode[0]}"] += time.process_time() - c
        return out

    return run


def _both(fn: Callable[..., Any]) -> Callable[..., Any]:
    """``timed_program`` with the kernels and without, timed and compared."""

    def run(*args: Any, **kwargs: Any) -> Any:
        counts["pieces"] += 1
        counts["blocks"] += len(args[0].move_table())
        if KERNELS is None:
            mode[0] = "numpy"
            return timed("timed numpy", fn)(*args, **kwargs)
        KERNELS.forced = False
        mode[0] = "numpy"
        want = timed("timed numpy", fn)(*args, **kwargs)
        KERNELS.forced = None
        mode[0] = "compiled"
        got = timed("timed compiled", fn)(*args, **kwargs)
        same = got[1] == want[1] and np.array_equal(
            got[0].move_table().feed, want[0].move_table().feed, equal_nan=True
        )
        counts["differ"] += not same
        return got

    return run


def report() -> None:
    """The figures, one line each."""
    numpy_s, compiled_s = spent["timed numpy"], spent["timed compiled"]
    print(f"timed_program: {counts['pieces']} pieces, {counts['blocks']} moves")
    if KERNELS is None:
        print(f"  numpy only (no kernels in this tree): {numpy_s:.3f} s CPU")
        print(f"  of which tip lengths {spent['lengths numpy']:.3f} s")
    else:
        ratio = numpy_s / compiled_s if compiled_s else float("nan")
        print(
            f"  numpy {numpy_s:.3f} s CPU, compiled {compiled_s:.3f} s CPU, ratio {ratio:.2f}x; "
            f"{counts['differ']} pieces differ"
        )
        ln, lc = spent["lengths numpy"], spent["lengths compiled"]
        ratio = ln / lc if lc else float("nan")
        print(f"  tip lengths alone: numpy {ln:.3f} s, compiled {lc:.3f} s, ratio {ratio:.2f}x")
    print(f"measure_feeds: {counts['measure']} calls, {spent['measure']:.3f} s CPU")
    print(f"realise: {counts['realise']} calls, {spent['realise']:.3f} s CPU")


if __name__ == "__main__":
    setattr(posting_feeds, LENGTHS, _lengths(getattr(posting_feeds, LENGTHS)))
    piece.timed_program = _both(piece.timed_program)
    measure.measure_feeds = timed("measure", measure.measure_feeds)
    piece.realise = timed("realise", piece.realise)
    code = main(sys.argv[1:])
    report()
    sys.exit(code)
