"""Regenerate the ranking tables of docs/singularity.md with timed kinematics, in one command.

Every shipped test path (``urdfpost testpath --list``) is compared on the machines of the docs'
tables with ``urdfpost compare`` (in process, the command line's own code), which writes the
JSON report, the per-block CSV and the plot of each case. From that output alone the script
then builds

- the block of docs/singularity.md between ``<!-- ranking:begin -->`` and
  ``<!-- ranking:end -->``: the axis limits used, the ranking by timed machining time against
  the velocity-only ranking, and the table ``urdfpost compare`` printed for every case;
- ``docs/img/fig-c-vs-cl-linear-spline.png``: C against the CL index, ``linear`` against
  ``spline`` (the style of Fig. 3/4 of the interpolation papers), read from the per-block CSV.

Usage::

    python bench/rank_tables.py                 # print the block, outputs in a temporary folder
    python bench/rank_tables.py --out runs --write-docs

``--write-docs`` replaces the block in docs/singularity.md and writes the figures into
docs/img/. Deterministic: the same code and machine files give the same text.
"""

from __future__ import annotations

import argparse
import contextlib
import csv
import io
import json
import logging
import sys
import tempfile
from pathlib import Path

from urdfpost.analysis.testpaths import PATHS, to_apt
from urdfpost.cli import main as urdfpost

log = logging.getLogger("rank_tables")

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "singularity.md"
IMG = ROOT / "docs" / "img"
BEGIN, END = "<!-- ranking:begin -->", "<!-- ranking:end -->"

#: The machines of the docs' tables: table-table, head-head, nutating.
MACHINES = ("dmu50", "gantry-ca", "dmu50-nutating")
#: The comparison plots the docs show: (machine, test path) -> file in docs/img.
PLOTS = {
    ("dmu50", "hemisphere"): "compare-hemisphere-dmu50.png",
    ("gantry-ca", "sweep-0.1"): "compare-sweep01-gantry-ca.png",
    ("dmu50-nutating", "nutating-edge"): "compare-nutating-edge.png",
}
#: The case of the Fig. 3/4-style plot (machine, test path) and its two strategies.
FIGURE = ("gantry-ca", "sweep-0.1", ("linear", "spline"))


def run_case(machine: str, path: str, out: Path, plot: bool) -> tuple[int, str, dict]:
    """``urdfpost compare`` of one test path on one machine: exit status, table, report."""
    apt = out / f"{path}.apt"
    if not apt.exists():
        apt.write_text(to_apt(PATHS[path]()), encoding="utf-8")
    stem = out / f"{path}-{machine}"
    argv = [
        "compare",
        str(apt),
        "-m",
        machine,
        "--report",
        f"{stem}.json",
        "--csv",
        f"{stem}.csv",
    ]
    if plot:
        argv += ["--plot", f"{stem}.png"]
    text = io.StringIO()
    with contextlib.redirect_stdout(text):
        status = urdfpost(argv)
    report = json.loads(Path(f"{stem}.json").read_text(encoding="utf-8"))
    # the table names the CL file: by its name, wherever the outputs went
    return status, text.getvalue().replace(f"{out}/", ""), report


def ranking(report: dict, key: str) -> str:
    """Verified strategies from fastest to slowest by metric ``key``."""
    rows = [
        (s["metrics"][key], s["strategy"])
        for s in report["strategies"]
        if s["metrics"] is not None and s["verified"]
    ]
    return " < ".join(f"{name} {value:.2f}" for value, name in sorted(rows))


def limits_table(reports: dict[str, dict]) -> list[str]:
    """Markdown table of the limits the timed kinematics used, per machine."""
    lines = [
        "| machine | axis | velocity | acceleration | jerk |",
        "|---|---|---|---|---|",
    ]
    for machine, report in reports.items():
        for axis, lim in report["limits"].items():
            unit = "deg" if axis in "ABC" else "mm"
            lines.append(
                f"| {machine} | {axis} | {lim['velocity']:.4g} {unit}/s | "
                f"{lim['acceleration']:.4g} {unit}/s^2 | {lim['jerk']:.4g} {unit}/s^3 |"
            )
    return lines


def figure(csv_path: Path, strategies: tuple[str, ...], target: Path, title: str) -> None:
    """C against the CL index for ``strategies``, from the per-block CSV alone."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    rows = list(csv.DictReader(csv_path.open(encoding="utf-8")))
    fig = Figure(figsize=(7.0, 5.0), layout="constrained")
    FigureCanvasAgg(fig)
    ax_q, ax_v = fig.subplots(2, 1, sharex=True)
    for name, style in zip(strategies, ("-", "--"), strict=False):
        mine = [r for r in rows if r["strategy"] == name and r["cl_index"]]
        x = [float(r["cl_index"]) for r in mine]
        ax_q.plot(x, [float(r["q_C"]) for r in mine], style, marker=".", ms=3, label=name)
        ax_v.plot(x, [abs(float(r["v_C"])) for r in mine], style, marker=".", ms=3, label=name)
    ax_q.set_ylabel("C (deg)")
    ax_v.set_ylabel("|C velocity| on the timed trajectory (deg/s)")
    ax_v.set_xlabel("CL index")
    for ax in (ax_q, ax_v):
        ax.grid(True, lw=0.3, alpha=0.5)
        ax.legend(fontsize="small")
    fig.suptitle(title)
    fig.savefig(target, format="png", dpi=110, metadata={"Software": None})


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, help="folder for the reports, CSVs and plots")
    parser.add_argument(
        "--write-docs", action="store_true", help="update docs/singularity.md and docs/img/"
    )
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    with tempfile.TemporaryDirectory() as tmp:
        out = args.out or Path(tmp)
        out.mkdir(parents=True, exist_ok=True)
        block = [
            BEGIN,
            "",
            "Produced by `python bench/rank_tables.py --write-docs` (`urdfpost compare`, TCP, "
            "default tolerances, the shipped machine files' limits below).",
            "",
        ]
        reports: dict[str, dict] = {}
        sections: list[str] = []
        for machine in MACHINES:
            for path in PATHS:
                log.info("compare %s on %s", path, machine)
                plot = args.write_docs and (machine, path) in PLOTS
                status, text, report = run_case(machine, path, out, plot=plot)
                reports.setdefault(machine, report)
                sections += [
                    f"**{path} on {machine}** (exit {status}; timed: "
                    f"{ranking(report, 'time_s') or 'no verified program'}; velocity only: "
                    f"{ranking(report, 'velocity_only_time_s') or '-'})",
                    "",
                    "```",
                    text.rstrip(),
                    "```",
                    "",
                ]
        block += ["Limits used:", "", *limits_table(reports), "", *sections, END]
        machine, path, pair = FIGURE
        if args.write_docs:
            IMG.mkdir(exist_ok=True)
            figure(
                out / f"{path}-{machine}.csv",
                pair,
                IMG / "fig-c-vs-cl-linear-spline.png",
                f"{path} on {machine}: C against CL index ({' against '.join(pair)})",
            )
            for (m, p), name in PLOTS.items():
                (IMG / name).write_bytes((out / f"{p}-{m}.png").read_bytes())
            doc = DOC.read_text(encoding="utf-8")
            head, rest = doc.split(BEGIN, 1)
            _, tail = rest.split(END, 1)
            DOC.write_text(head + "\n".join(block) + tail, encoding="utf-8")
            log.info("wrote %s", DOC)
        else:
            sys.stdout.write("\n".join(block) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
