"""Reading programs back: the time of ``Dialect.read`` on large program files.

Run::

    python bench/bench_program_read.py /tmp/pr/h1m.h /tmp/pr/h1m.nc --repeat 2
    python bench/bench_program_read.py /tmp/pr/h1m.h --numpy      # the numpy path only
    PYTHONPATH=<old checkout>/src python bench/bench_program_read.py /tmp/pr/h1m.h

Each file is read (its control from its extension, or ``-c``) ``--repeat`` times in this
process, as :func:`urdfpost.dialects.reader.read_program` reads it (a :class:`ProgramReader`
fed the whole text). Printed per read: wall and CPU seconds (the first read of a process
includes numba's import and the loading of the compiled loop's machine code, when the reader
runs compiled), then a SHA-256 of what was read: every block and array of the program and the
text line of every move. Two runs (before and after a change, compiled and ``--numpy``) must
print the same digests. Nothing here is a test.
"""

from __future__ import annotations

import argparse
import hashlib
import time
from pathlib import Path

import numpy as np

import urdfpost.dialects.reader as reader_module
from urdfpost.dialects import dialect_for
from urdfpost.program import MoveTable, Program


def digest(program: Program, move_lines: list[int | np.ndarray]) -> str:
    """SHA-256 of a program read (blocks, arrays bit for bit, header) and its move lines."""
    h = hashlib.sha256()
    for name in ("name", "axes", "units", "tcp", "tool_length", "feed_mode"):
        h.update(repr(getattr(program, name)).encode())
    for name in ("rotary", "continuous", "rollover"):
        h.update(repr(sorted(getattr(program, name))).encode())
    for part in program.parts:
        if isinstance(part, MoveTable):
            for array in (part.position, part.rapid, part.feed):
                h.update(np.ascontiguousarray(array).tobytes())
        else:
            h.update(repr(part).encode())
    for lines in move_lines:
        h.update(np.asarray(lines, dtype=np.int64).tobytes())
    return h.hexdigest()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("programs", nargs="+", type=Path)
    parser.add_argument("-c", "--control", help="control (default: from the extension)")
    parser.add_argument("--repeat", type=int, default=2, help="reads of each file (default 2)")
    parser.add_argument("--numpy", action="store_true", help="never the compiled loop")
    args = parser.parse_args(argv)
    if args.numpy:
        reader_module.COMPILED_FROM = 1 << 62
    for path in args.programs:
        dialect = dialect_for(args.control, path)
        text = path.read_text()
        for k in range(args.repeat):
            wall, cpu = time.perf_counter(), time.process_time()
            reader = dialect.reader(str(path))
            reader.feed(text)
            reader.builder.flush_smoothing()
            program = reader.take()
            wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
            print(f"{path.name} {dialect.name} read {k + 1}: wall {wall:.3f} s, CPU {cpu:.3f} s")
        print(f"{path.name} sha256 {digest(program, reader.builder.move_lines)[:16]}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
