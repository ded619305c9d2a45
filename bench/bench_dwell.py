"""A dwell: the dome example with two of its CL points repeated N times each (identical GOTO
records, one block each in the program), posted and verified as a user runs the commands, for
growing N. The time and memory must grow linearly with the job (until December 2026 the
matching made a dwell quadratic: 2 x 4000 repeats took 19.7 s, 2 x 8000 were killed at 24 GB).

Run::

    python bench/bench_dwell.py                      # N = 1000, 4000, 16000, 64000
    python bench/bench_dwell.py --repeats 1000,8000

Printed per N: CL points, the wall seconds and peak resident MB of ``urdfpost post`` (whole)
and of ``urdfpost verify`` of its program (with the post's angle tolerance, 2 degrees: verify
adds its own 0.5 as the post does), and the growth of each from the N before against
the growth of the job. Nothing here is a test.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
DOME = ROOT / "examples" / "dome.apt"
AT = "GOTO/-16.4973,"  # two CL points of the dome (Y -12 and Y 12)

_WRAPPER = (
    "import json, resource, subprocess, sys\n"
    "proc = subprocess.run(sys.argv[1:], capture_output=True, text=True)\n"
    "use = resource.getrusage(resource.RUSAGE_CHILDREN)\n"
    "print(json.dumps([proc.returncode, proc.stdout + proc.stderr, use.ru_maxrss]))\n"
)


def dwell_job(repeats: int, folder: Path) -> tuple[Path, int]:
    """The dome with its points :data:`AT` repeated ``repeats`` times each; its path and its
    number of CL points."""
    lines: list[str] = []
    for line in DOME.read_text().splitlines():
        lines += [line] * (1 + repeats * line.startswith(AT))
    path = folder / f"dwell_{repeats}.apt"
    path.write_text("\n".join(lines) + "\n")
    return path, sum(line.startswith("GOTO/") for line in lines)


def run(command: list[str]) -> tuple[float, float, str]:
    """One command in its own process: wall seconds, peak MB, the last line of its output."""
    start = time.perf_counter()
    proc = subprocess.run(
        [sys.executable, "-c", _WRAPPER, *command], capture_output=True, text=True, check=True
    )
    wall = time.perf_counter() - start
    code, output, peak_kb = json.loads(proc.stdout)
    if code != 0:
        raise SystemExit(f"{' '.join(command)} failed ({code}):\n{output}")
    verdict = next((x for x in output.splitlines() if "verification" in x), "")
    return wall, peak_kb / 1024, verdict[:70]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", default="1000,4000,16000,64000")
    args = parser.parse_args()
    exe = [sys.executable, "-m", "urdfpost"]
    before: tuple[int, float, float] | None = None
    print(f"{'N':>6} {'points':>7} {'post s':>7} {'MB':>5} {'verify s':>8} {'MB':>5}  growth")
    with tempfile.TemporaryDirectory() as tmp:
        for n in (int(x) for x in args.repeats.split(",")):
            cl, points = dwell_job(n, Path(tmp))
            program = Path(tmp) / f"dwell_{n}.h"
            post, post_mb, said = run([*exe, "post", str(cl), "-m", "dmu50", "-o", str(program)])
            assert "within tolerance" in said, said
            check = ["verify", str(program), "-m", "dmu50", "--cl", str(cl)]
            verify, verify_mb, said = run([*exe, *check, "--angle-tolerance", "2.0"])
            assert "within tolerance" in said, said
            growth = ""
            if before is not None:
                growth = (
                    f"job x{points / before[0]:.2f}: post x{post / before[1]:.2f}, "
                    f"verify x{verify / before[2]:.2f}"
                )
            print(
                f"{n:>6} {points:>7} {post:>7.2f} {post_mb:>5.0f} {verify:>8.2f} "
                f"{verify_mb:>5.0f}  {growth}"
            )
            before = (points, post, verify)


if __name__ == "__main__":
    main()
