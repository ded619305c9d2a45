"""One ``urdfpost`` command run in this process, with the CPU time of this process (the post's
or verify's main process) and of its workers (the verification worker, verify's workers)
printed apart, and the wall time: which process is the critical path of a streamed job.

Run::

    python bench/process_cpu.py post /tmp/urdfpost-bench/hemisphere_1000000.apt \\
        -m dmu50 -c heidenhain --no-tcp -q -o /tmp/x.h
    python bench/process_cpu.py verify /tmp/x.h -m dmu50 \\
        --cl /tmp/urdfpost-bench/hemisphere_1000000.apt --angle-tolerance 2.5
    PYTHONPATH=<old checkout>/src python bench/process_cpu.py post ...

The arguments are those of ``urdfpost``. Printed on standard error, after the command's own
output: ``main cpu`` (user + system of this process, s), ``workers cpu`` (of the processes it
started and waited for), ``wall`` (s). On two cores the wall time cannot be less than half the
sum of the two, nor less than the main process's.
"""

from __future__ import annotations

import resource
import sys
import time


def main(argv: list[str]) -> int:
    from urdfpost.cli import main as urdfpost

    start = time.perf_counter()
    try:
        code = urdfpost(argv)
    finally:
        wall = time.perf_counter() - start
        own = resource.getrusage(resource.RUSAGE_SELF)
        workers = resource.getrusage(resource.RUSAGE_CHILDREN)
        print(
            f"main cpu {own.ru_utime + own.ru_stime:.2f}  "
            f"workers cpu {workers.ru_utime + workers.ru_stime:.2f}  wall {wall:.2f}",
            file=sys.stderr,
        )
    return int(code or 0)


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
