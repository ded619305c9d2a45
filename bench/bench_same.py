"""Same programs, same speed: the 1M-point bench job posted whole and in pieces.

Run::

    python bench/bench_same.py                         # 1M points, this checkout
    PYTHONPATH=<old checkout>/src python bench/bench_same.py --label before
    python bench/bench_same.py --points 200000 --label quick

Each post is ``urdfpost post`` in its own subprocess (the command a user runs) on the
hemisphere job of ``bench/make_large_cl.py``, for the dmu50: in machine coordinates for
heidenhain and with TCP for fanuc, each whole (``--piece-points 0``) and in pieces (the
default for a large file). Printed per post: wall time, CL points per second and the SHA-256 of
the program; the last line is a JSON record of the same figures, so that two runs (before and
after a change) can be compared: the digests must be equal and the times close. Nothing here is
a test: speed is never checked in the suite.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from make_large_cl import ensure_file  # noqa: E402

MACHINE = "dmu50"
POSTS = (
    ("heidenhain", False, True),
    ("heidenhain", False, False),
    ("fanuc", True, True),
    ("fanuc", True, False),
)
"""(control, TCP, whole) of each post."""


def run_post(cl: Path, control: str, tcp: bool, whole: bool, out: Path) -> float:
    """Wall seconds of one ``urdfpost post`` of ``cl`` to ``out``."""
    cmd = [sys.executable, "-m", "urdfpost", "post", str(cl), "-m", MACHINE, "-c", control]
    cmd += ["-q", "-o", str(out)]
    if not tcp:
        cmd.append("--no-tcp")
    if whole:
        cmd += ["--piece-points", "0"]
    t = time.perf_counter()
    subprocess.run(cmd, check=True, env=os.environ.copy(), stdout=subprocess.DEVNULL)
    return time.perf_counter() - t


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--points", type=int, default=1_000_000, help="CL points (default 1M)")
    parser.add_argument("--label", default="this checkout", help="name of the run")
    args = parser.parse_args(argv)
    cl = ensure_file(args.points)
    record: dict[str, object] = {"label": args.label, "points": args.points, "posts": {}}
    posts: dict[str, object] = {}
    print(f"{args.label}: {cl.name}, load average {os.getloadavg()[0]:.1f}")
    with tempfile.TemporaryDirectory() as tmp:
        for control, tcp, whole in POSTS:
            key = f"{control} {'tcp' if tcp else 'mc'} {'whole' if whole else 'pieces'}"
            out = Path(tmp) / "out.nc"
            seconds = run_post(cl, control, tcp, whole, out)
            digest = hashlib.sha256(out.read_bytes()).hexdigest()
            posts[key] = {"s": round(seconds, 2), "sha256": digest}
            print(
                f"  {key:<24} {seconds:8.1f} s {args.points / seconds / 1e3:7.1f} k pts/s  "
                f"{digest[:16]}",
                flush=True,
            )
    record["posts"] = posts
    print(json.dumps(record))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
