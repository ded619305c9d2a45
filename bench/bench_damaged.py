"""Verifying a damaged program: blocks compared with long CL spans.

Run::

    python bench/bench_damaged.py 20000            # bounded search, and every segment in turn
    python bench/bench_damaged.py 100000 --no-oracle

The hemisphere job of ``bench/make_large_cl.py`` (written once) is posted for the dmu50
(Fanuc, machine coordinates); every X word of a share of the program's lines (``--share``, a
fifth by default), in its middle, is put 0.5 mm off (a stretch run with a wrong offset: its CL
points are all missed), and the program is verified in this process with
:func:`urdfpost.verification.verify`. Every block between the last CL point reached and the
next is compared with that whole span of CL points. Printed: the missed CL points, the worst
deviation, the seconds of the verification with the far segments searched with bounds (the
default), and with every segment taken in turn (``--no-oracle`` skips it: it grows with the
blocks times the span), their ratio, and whether the figures are equal. Nothing here is a
test: speed is never checked in the suite.
"""

from __future__ import annotations

import argparse
import re
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from make_large_cl import ensure_file  # noqa: E402

from urdfpost import load_machine  # noqa: E402
from urdfpost.dialects import dialect_for  # noqa: E402
from urdfpost.posting.options import PostOptions  # noqa: E402
from urdfpost.posting.whole import post  # noqa: E402
from urdfpost.readers import read_cl  # noqa: E402
from urdfpost.tolerances import Tolerances  # noqa: E402
from urdfpost.verification import measure, verify  # noqa: E402


def _damaged(text: str, share: float) -> str:
    """The program with every X word of a stretch of ``share`` of its lines, in its middle,
    0.5 mm off (a stretch run with a wrong offset: its CL points are all missed)."""
    lines = text.splitlines(keepends=True)
    a = int(len(lines) * (0.5 - share / 2))
    b = int(len(lines) * (0.5 + share / 2))

    def shifted(word: re.Match[str]) -> str:
        return f"X{float(word.group(1)) + 0.5:.3f}"

    lines[a:b] = [re.sub(r"X(-?\d+\.?\d*)", shifted, line) for line in lines[a:b]]
    return "".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("points", type=int, nargs="?", default=20000)
    parser.add_argument("--share", type=float, default=0.2, help="share of lines damaged")
    parser.add_argument("--no-oracle", action="store_true", help="skip the one-by-one search")
    args = parser.parse_args()
    path = ensure_file(args.points)
    job = read_cl(path)
    machine = load_machine("dmu50")
    result = post(job, machine, PostOptions(controller="fanuc", tcp=False))
    program = dialect_for("fanuc").read(_damaged(result.text, args.share), path="damaged.nc")
    tol = Tolerances.for_units("mm")

    def timed() -> tuple[float, object]:
        t0 = time.perf_counter()
        v = verify(program, machine, job, tool_length=result.program.tool_length, tol=tol)
        return time.perf_counter() - t0, v

    bounded, v = timed()
    print(f"{args.points} CL points: {len(v.missed_lines)} missed, {v.blocks} blocks")
    print(f"max tip deviation {v.max_tip_deviation:.4f} mm at CL line {v.worst_cl_line}")
    print(f"bounded search: {bounded:.2f} s")
    if args.no_oracle:
        return
    measure._LONG = sys.maxsize  # every segment in turn
    each, w = timed()
    print(f"every segment in turn: {each:.2f} s; ratio {each / bounded:.1f}x")
    print(f"figures equal: {v == w}")


if __name__ == "__main__":
    main()
