"""The ``urdfpost`` command line: post, verify, machines, machine show; exit codes, messages,
atomic outputs. Most cases call ``main([...])`` in-process; a few run the real process."""

from __future__ import annotations

import json
import math
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import shared_cl

import urdfpost
from urdfpost.cli import main
from urdfpost.dialects import DIALECTS

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
GOLDEN = HERE / "golden" / "post"
JOB = GOLDEN / "short_job.apt"
DOME = ROOT / "examples" / "dome.apt"
MACHINE_NAMES = (
    "dmu50",
    "dmu50-nutating",
    "gantry-ca",
    "monoblock",
    "umc750",
    "vf2-4axis",
    "xyzac-trt",
)

TINY = """\
UNITS/MM
MULTAX/ON
LOADTL/1
SPINDL/10000,CLW
FEDRAT/MMPM,1000
GOTO/0,0,10,0,0.2588190,0.9659258
GOTO/20,0,10,0.2588190,0,0.9659258
FINI
"""

INCH_JOB = """\
UNITS/INCHES
MULTAX/ON
LOADTL/2
SPINDL/6000,CLW
RAPID
GOTO/1.0000,0.0000,1.0000,0.0000000,0.0000000,1.0000000
FEDRAT/IPM,20.0000
GOTO/1.0000,0.0000,0.5000
GOTO/0.5000,0.2500,0.5000,0.2588190,0.0000000,0.9659258
GOTO/-1.0000,-1.0000,0.5000,0.0000000,0.0000000,1.0000000
GOHOME
FINI
"""

#: A semicircle of radius 0.17 in, inch, for the umc750 (inch machine).
ARC_INCH = """\
UNITS/INCHES
MULTAX/ON
LOADTL/2
SPINDL/6000,CLW
RAPID
GOTO/0.1700,0.0000,1.0000,0.0000000,0.0000000,1.0000000
FEDRAT/IPM,20.0000
GOTO/0.1700,0.0000,0.5000
CIRCLE/0.0000,0.0000,0.5000,0.0000000,0.0000000,1.0000000,0.1700
GOTO/-0.1700,0.0000,0.5000
GOTO/-1.0000,-1.0000,0.5000
GOHOME
FINI
"""


def write(folder: Path, name: str, text: str) -> Path:
    path = folder / name
    path.write_text(text, encoding="utf-8")
    return path


def files(folder: Path) -> set[str]:
    """Names in a folder, hidden (temporary) files included."""
    return {p.name for p in folder.iterdir()}


# --------------------------------------------------------------------------------------------
# post


def test_post_writes_the_program_and_reports(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "job.h"
    report = tmp_path / "job.json"
    rc = main(
        [
            "post",
            "--strategy",
            "recursive",
            str(JOB),
            "--machine",
            "dmu50",
            "-o",
            str(out),
            "--report",
            str(report),
        ]
    )
    assert rc == 0
    # the same text as the library writes (the golden file)
    assert out.read_text() == (GOLDEN / "dmu50_heidenhain_tcp.h").read_text()
    stdout = capsys.readouterr().out.splitlines()
    assert stdout[0] == f"wrote {out} (heidenhain, TCP, mm) for machine dmu50"
    assert stdout[1] == "strategy recursive: 1 singular spans (pole at CL lines 19-25)"
    assert stdout[2].startswith("verification within tolerance: 16/16 CL points reached, 23 blocks")
    assert re.search(r"tool tip deviation max \d\.\d{4} mean \d\.\d{4} mm", stdout[2])
    assert "largest rotary step C 176.005, B 30.060 deg" in stdout[2]
    data = json.loads(report.read_text())
    for key in (
        "cl_points",
        "blocks",
        "max_tip_deviation",
        "max_orientation_deviation_deg",
        "max_rotary_step_deg",
        "units",
        "warnings",
    ):
        assert key in data, key
    assert data["cl_points"] == 16
    assert data["blocks"] == 23  # 19 on the path, 4 of the approach and the end
    assert data["units"] == "mm"
    # C would turn beyond its velocity limit at the pole: those blocks' feed is reduced
    feeds = data["feeds"]
    assert feeds["mode"] == "tip" and feeds["capped_blocks"] > 0
    assert data["warnings"] == [
        f"{JOB}: feed reduced on {feeds['capped_blocks']} blocks (axis velocity limits: C "
        f"{feeds['capped_blocks']}), worst at CL line {feeds['worst_cl_line']} (to "
        f"{feeds['worst_percent_of_programmed']:.1f}% of programmed)"
    ]
    assert data["feed_check"]["ok"] and data["feed_check"]["capped"] == feeds["capped_blocks"]
    assert set(data["max_rotary_step_deg"]) == {"B", "C"}
    assert data["max_rotary_step_deg"]["C"] == pytest.approx(176.0049)
    assert data["max_rotary_step_deg"]["B"] == pytest.approx(30.0604)
    assert 0 <= data["max_tip_deviation"] <= 0.01
    assert 0 <= data["max_orientation_deviation_deg"] <= 0.5
    assert files(tmp_path) == {"job.h", "job.json"}


def test_post_machine_coordinates_and_block_numbers(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "job.nc"
    rc = main(
        [
            "post",
            "--strategy",
            "recursive",
            str(JOB),
            "-m",
            "gantry-ca",
            "-o",
            str(out),
            "--no-tcp",
            "-q",
        ]
    )
    assert rc == 0
    assert out.read_text() == (GOLDEN / "gantry-ca_fanuc_mc.nc").read_text()
    assert "(fanuc, machine coordinates, mm) for machine gantry-ca" in capsys.readouterr().out
    numbered = tmp_path / "numbered.nc"
    assert (
        main(
            [
                "post",
                "--strategy",
                "recursive",
                str(JOB),
                "-m",
                "gantry-ca",
                "-o",
                str(numbered),
                "--block-numbers",
            ]
        )
        == 0
    )
    body = [x for x in numbered.read_text().splitlines() if x not in ("%",) and x.strip()]
    assert sum(bool(re.match(r"N\d+ ", x)) for x in body) >= 19


def test_post_default_output_name_and_controller(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.chdir(tmp_path)
    shutil.copy(JOB, tmp_path / "short_job.apt")
    # gantry-ca's control is siemens: CL name + .mpf in the current folder
    assert main(["post", "--strategy", "recursive", "short_job.apt", "-m", "gantry-ca", "-q"]) == 0
    assert files(tmp_path) == {"short_job.apt", "short_job.mpf"}
    assert (tmp_path / "short_job.mpf").read_text() == (
        GOLDEN / "gantry-ca_siemens_tcp.mpf"
    ).read_text()
    assert capsys.readouterr().out.startswith("wrote short_job.mpf (siemens, TCP, mm)")


@pytest.mark.parametrize(
    ("ext", "controller"),
    [(".h", "heidenhain"), (".mpf", "siemens"), (".nc", "fanuc"), (".ngc", "linuxcnc")],
)
def test_output_extension_picks_the_controller(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], ext: str, controller: str
) -> None:
    out = tmp_path / f"job{ext}"
    assert (
        main(["post", "--strategy", "recursive", str(JOB), "-m", "monoblock", "-o", str(out), "-q"])
        == 0
    )
    assert out.read_text() == (GOLDEN / f"monoblock_{controller}_tcp{ext}").read_text()
    assert f"({controller}, TCP, mm)" in capsys.readouterr().out


def test_controller_option_wins_over_the_extension(tmp_path: Path) -> None:
    out = tmp_path / "job.nc"
    assert (
        main(
            [
                "post",
                "--strategy",
                "recursive",
                str(JOB),
                "-m",
                "monoblock",
                "-o",
                str(out),
                "-c",
                "siemens",
                "-q",
            ]
        )
        == 0
    )
    assert out.read_text() == (GOLDEN / "monoblock_siemens_tcp.mpf").read_text()


def test_version(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0
    assert capsys.readouterr().out.strip() == f"urdfpost {urdfpost.__version__}"


@pytest.mark.parametrize(
    "args",
    [
        pytest.param(["post", "{cl}"], id="missing --machine"),
        pytest.param(["post", "{cl}", "-m", "dmu50", "--prefer", "Q+"], id="bad --prefer"),
        pytest.param(["post", "{cl}", "-m", "dmu50", "--prefer", "B"], id="--prefer no sign"),
        pytest.param(["post", "{cl}", "-m", "dmu50", "--tcp", "--no-tcp"], id="tcp and no-tcp"),
        pytest.param(["post", "{cl}", "-m", "dmu50", "--tool-length", "-5"], id="negative length"),
        pytest.param(["post", "{cl}", "-m", "dmu50", "--tolerance", "0"], id="zero tolerance"),
        pytest.param(["post", "{cl}", "-m", "dmu50", "-c", "haas"], id="unknown controller"),
        pytest.param(["post", "{cl}", "-m", "dmu50", "--units", "cm"], id="unknown units"),
        pytest.param(["verify", "{cl}", "-m", "dmu50"], id="verify without --cl"),
        pytest.param(
            ["verify", "{cl}", "-m", "dmu50", "--cl", "{cl}", "--angle-tolerance", "nan"],
            id="verify nan angle tolerance",
        ),
        pytest.param(
            ["verify", "{cl}", "-m", "dmu50", "--cl", "{cl}", "--angle-tolerance", "-5"],
            id="verify negative angle tolerance",
        ),
        pytest.param(
            ["post", "{cl}", "-m", "dmu50", "--angle-tolerance", "nan"], id="post nan angle"
        ),
        pytest.param(
            ["post", "{cl}", "-m", "dmu50", "--angle-tolerance", "-5"], id="post -5 angle"
        ),
        pytest.param(["frobnicate"], id="unknown command"),
        pytest.param([], id="no command"),
    ],
)
def test_usage_errors_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str]
) -> None:
    cl = write(tmp_path, "tiny.apt", TINY)
    with pytest.raises(SystemExit) as exc:
        main([a.format(cl=cl) for a in args])
    assert exc.value.code == 2
    assert "usage: urdfpost" in capsys.readouterr().err
    assert files(tmp_path) == {"tiny.apt"}


def _domain_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], cl_text: str, args: list[str]
) -> str:
    """Run a post that must fail: exit 1, one ``urdfpost: `` message, no file left behind."""
    cl = write(tmp_path, "part.apt", cl_text)
    out = tmp_path / "part.nc"
    report = tmp_path / "part.json"
    rc = main(
        [
            "post",
            "--strategy",
            "recursive",
            str(cl),
            "-o",
            str(out),
            "--report",
            str(report),
            "-q",
            *args,
        ]
    )
    captured = capsys.readouterr()
    assert rc == 1
    assert captured.out == ""
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1, captured.err
    assert lines[0].startswith("urdfpost: ")
    assert "Traceback" not in captured.err
    assert files(tmp_path) == {"part.apt"}  # no program, no report, no temporary file
    return lines[0]


def test_unknown_machine_exit_1(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    msg = _domain_error(tmp_path, capsys, TINY, ["-m", "nosuch"])
    assert "nosuch" in msg
    for name in MACHINE_NAMES:  # the message lists the known machines
        assert name in msg


def test_malformed_cl_exit_1(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    text = "UNITS/MM\nLOADTL/1\nGOTO/0,0,5,0,0,1\nGOTO/0,0,abc,0,0,1\n"
    msg = _domain_error(tmp_path, capsys, text, ["-m", "dmu50"])
    assert f"{tmp_path / 'part.apt'}:4:" in msg
    assert "GOTO" in msg and "'abc'" in msg


def test_unreachable_point_exit_1(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # the tool pointing down: beyond the B travel of the trunnion (-35..120 deg)
    text = (
        "UNITS/MM\nLOADTL/1\nSPINDL/8000,CLW\nFEDRAT/MMPM,500\nGOTO/0,0,5,0,0,1\n"
        "GOTO/0,0,0,0,0,-1\nGOTO/0,0,5,0,0,1\n"
    )
    msg = _domain_error(tmp_path, capsys, text, ["-m", "umc750"])
    assert f"{tmp_path / 'part.apt'}:6:" in msg
    assert "cannot be reached" in msg
    assert "umc750" in msg


def test_tolerance_failure_exit_1(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    msg = _domain_error(
        tmp_path, capsys, TINY, ["-m", "dmu50", "--no-tcp", "--tolerance", "0.0000001"]
    )
    assert "misses its tolerance" in msg
    assert "nothing written" in msg
    assert "BEYOND TOLERANCE" in msg


def test_unknown_extension_exit_1(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cl = write(tmp_path, "part.apt", TINY)
    rc = main(
        [
            "post",
            "--strategy",
            "recursive",
            str(cl),
            "-m",
            "dmu50",
            "-o",
            str(tmp_path / "part.txt"),
            "-q",
        ]
    )
    assert rc == 1
    err = capsys.readouterr().err
    assert err.startswith("urdfpost: ") and "'.txt'" in err
    assert files(tmp_path) == {"part.apt"}


def test_missing_cl_file_exit_1(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rc = main(
        [
            "post",
            "--strategy",
            "recursive",
            str(tmp_path / "none.apt"),
            "-m",
            "dmu50",
            "-o",
            str(tmp_path / "x.h"),
        ]
    )
    assert rc == 1
    err = capsys.readouterr().err
    assert err.startswith(f"urdfpost: {tmp_path / 'none.apt'}") and "cannot read" in err
    assert files(tmp_path) == set()


def test_failed_post_keeps_the_previous_program(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    cl = write(tmp_path, "part.apt", TINY)
    out = write(tmp_path, "part.h", "previous program\n")
    args = ["post", str(cl), "-m", "dmu50", "-o", str(out), "--no-tcp", "--tolerance", "1e-7"]
    assert main([*args, "-q"]) == 1
    capsys.readouterr()
    assert out.read_text() == "previous program\n"
    assert files(tmp_path) == {"part.apt", "part.h"}


def test_unknown_cl_record_warns_and_becomes_a_comment(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    text = TINY.replace("FEDRAT/MMPM,1000\n", "FEDRAT/MMPM,1000\nFROBNICATE/1,2\n")
    cl = write(tmp_path, "part.apt", text)
    out = tmp_path / "part.ngc"
    report = tmp_path / "part.json"
    assert (
        main(
            [
                "post",
                "--strategy",
                "recursive",
                str(cl),
                "-m",
                "dmu50",
                "-o",
                str(out),
                "--report",
                str(report),
            ]
        )
        == 0
    )
    err = capsys.readouterr().err
    assert re.search(rf"urdfpost: warning: {re.escape(str(cl))}:6: .*FROBNICATE/1,2", err)
    assert "(FROBNICATE/1,2)" in out.read_text().splitlines()
    assert any("FROBNICATE" in w and ":6:" in w for w in json.loads(report.read_text())["warnings"])


# --------------------------------------------------------------------------------------------
# units through the command line


def test_inch_cl_gives_inch_program_and_inch_report(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    cl = write(tmp_path, "inch.apt", INCH_JOB)
    expected_units = {".h": r"^0 BEGIN PGM \w+ INCH$", ".mpf": r"^G700$", ".nc": r"^G20$"}
    expected_units[".ngc"] = r"^G20$"
    for ext, pattern in expected_units.items():
        out = tmp_path / f"inch{ext}"
        report = tmp_path / f"inch{ext}.json"
        args = ["post", str(cl), "-m", "dmu50", "-o", str(out), "--report", str(report), "-q"]
        # dmu50 writes mm (its <urdfpost units="mm">): inch asked for; --tool-length in inch
        args += ["--units", "inch"]
        assert main([*args, "--tool-length", "4", "--no-tcp"]) == 0
        assert re.search(pattern, out.read_text(), re.M), ext
        data = json.loads(report.read_text())
        assert data["units"] == "inch"
        assert data["tip_tolerance"] == pytest.approx(0.0004)
        assert data["max_tip_deviation"] <= 0.0004
        assert data["tool_length_mm"] == pytest.approx(4 * 25.4)  # --tool-length in inch
    stdout = capsys.readouterr().out
    assert "(heidenhain, machine coordinates, inch)" in stdout
    assert re.search(
        r"tool tip deviation max 0\.\d{5} mean 0\.\d{5} inch \(tolerance 0\.00040\)", stdout
    )


def test_nx_ballmill_through_the_command_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    cl = shared_cl("nx_variable_axis_ballmill_inch.cls")
    out = tmp_path / "ballmill.nc"
    report = tmp_path / "ballmill.json"
    assert (
        main(
            [
                "post",
                "--strategy",
                "recursive",
                str(cl),
                "-m",
                "umc750",
                "-o",
                str(out),
                "--report",
                str(report),
                "--spindle",
                "8000",
            ]
        )
        == 0
    )
    captured = capsys.readouterr()
    assert "(fanuc, TCP, inch) for machine umc750" in captured.out
    # the file starts no spindle: --spindle's, said as a warning, before the approach
    assert "S8000 CW (--spindle) used" in captured.err
    assert "348/348 CL points reached" in captured.out
    assert "no tool change before the first move; tool 1 assumed" in captured.err
    text = out.read_text()
    assert re.search(r"^G20$", text, re.M)
    assert "\nX-4.2721 Y-3.0148 Z3.0000 B" in text  # the GOTO as written (MSYS moves nothing)
    assert text.index("S8000 M3") < text.index("G43.4")
    data = json.loads(report.read_text())
    assert data["units"] == "inch" and data["cl_points"] == data["cl_points_reached"] == 348
    assert data["max_tip_deviation"] <= 0.0004
    assert main(["verify", str(out), "-m", "umc750", "--cl", str(cl)]) == 0


# --------------------------------------------------------------------------------------------
# machines


def test_machines_lists_the_seven(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["machines"]) == 0
    rows = capsys.readouterr().out.strip().splitlines()
    assert [r.split()[0] for r in rows] == list(MACHINE_NAMES)
    families = {r.split()[0]: r.split()[1] for r in rows}
    assert families["dmu50"] == "table-table"
    assert families["gantry-ca"] == "head-head"
    assert families["monoblock"] == "head-table"
    assert families["vf2-4axis"] == "4-axis"
    assert "INVALID" not in "\n".join(rows)


def test_machine_show(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["machine", "show", "umc750"]) == 0
    out = capsys.readouterr().out
    assert re.search(r"^family\s+table-table$", out, re.M)
    assert re.search(r"^control\s+fanuc, units inch, tool length 152\.4 mm", out, re.M)
    for axis in "XYZ":
        assert re.search(
            rf"^  {axis}  prismatic .* travel -?\d+\.\d{{3}} \.\. -?\d+\.\d{{3}} mm", out, re.M
        )
    assert re.search(r"^  B  revolute .* travel -35\.000 \.\. 120\.000 deg", out, re.M)
    assert re.search(r"^  C  continuous .* travel continuous", out, re.M)
    assert "singular tool directions" in out
    up = r"\([-+]0\.0000, [-+]0\.0000, \+1\.0000\)"
    assert re.search(
        rf"^  pole  tool axis along {up}: C undetermined \(within travel\)$", out, re.M
    )
    assert re.search(
        r"^  pole  tool axis along .*-1\.0000\): C undetermined \(outside travel\)$", out, re.M
    )


def test_machine_show_unknown_exit_1(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["machine", "show", "nosuch"]) == 1
    assert capsys.readouterr().err.startswith("urdfpost: ")


# --------------------------------------------------------------------------------------------
# the real process


def test_subprocess_post_and_verify(tmp_path: Path) -> None:
    cl = write(tmp_path, "part.apt", TINY)
    out = tmp_path / "part.ngc"
    run = [sys.executable, "-m", "urdfpost.cli"]
    proc = subprocess.run(
        [*run, "post", str(cl), "-m", "dmu50", "-o", str(out), "--no-tcp", "-q"],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.startswith(f"wrote {out} (linuxcnc, machine coordinates, mm)")
    assert out.is_file()
    proc = subprocess.run(
        [*run, "verify", str(out), "-m", "dmu50", "--cl", str(cl)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr
    proc = subprocess.run(
        [*run, "post", str(cl)], capture_output=True, text=True, timeout=120, cwd=tmp_path
    )
    assert proc.returncode == 2
    assert "--machine" in proc.stderr
    proc = subprocess.run(
        [*run, "post", str(cl), "-m", "nosuch"], capture_output=True, text=True, timeout=120
    )
    assert proc.returncode == 1
    assert proc.stderr.startswith("urdfpost: ")
    assert files(tmp_path) == {"part.apt", "part.ngc"}


@pytest.mark.parametrize(
    "argv", [["machine", "show", "dmu50"], ["machines"], ["testpath", "sweep-0"]]
)
def test_output_into_a_closed_pipe_stops_quietly(tmp_path: Path, argv: list[str]) -> None:
    """``urdfpost machine show dmu50 | head -1``: the reader has gone, so the write fails with
    EPIPE; the command stops with the code of a tool killed by SIGPIPE, and no traceback."""
    import os

    read, write = os.pipe()
    os.close(read)  # the reader is gone before the first byte
    try:
        proc = subprocess.run(
            [sys.executable, "-m", "urdfpost", *argv],
            stdout=write,
            stderr=subprocess.PIPE,
            text=True,
            timeout=120,
            cwd=tmp_path,
        )
    finally:
        os.close(write)
    assert proc.stderr == ""
    assert proc.returncode == 141


def test_reports_are_strict_json(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """A path through the exact pole has an exactly singular span (condition number without
    bound): its ``max_kappa`` is written as null, never as the ``Infinity`` that strict JSON
    parsers refuse; ``verify`` and ``compare`` reports too."""
    monkeypatch.chdir(tmp_path)
    cl, out = tmp_path / "s0.apt", tmp_path / "s0.h"
    assert main(["testpath", "sweep-0", "-o", str(cl)]) == 0
    assert main(["post", str(cl), "-m", "dmu50", "-o", str(out), "--report", "p.json"]) == 0
    # the program's strategy bent the tool axis by up to 2.5 deg and widened the tip tolerance
    check = ["--angle-tolerance", "2.5", "--tolerance", "0.04", "--report", "v.json"]
    assert main(["verify", str(out), "-m", "dmu50", "--cl", str(cl), *check]) == 0
    assert main(["compare", str(cl), "-m", "dmu50", "--report", "c.json"]) == 0

    def refuse(token: str) -> None:
        raise AssertionError(f"non-standard JSON token {token}")

    reports = {
        name: json.loads(Path(name).read_text(), parse_constant=refuse)
        for name in ("p.json", "v.json", "c.json")
    }
    spans = reports["p.json"]["strategy"]["spans"]
    assert any(span["max_kappa"] is None for span in spans), spans
    assert any(span["max_kappa"] is None for span in reports["c.json"]["spans"])


def test_console_script_version() -> None:
    exe = shutil.which("urdfpost")
    if exe is None:
        pytest.skip("the urdfpost console script is not installed on PATH")
    proc = subprocess.run([exe, "--version"], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0
    assert proc.stdout.strip() == f"urdfpost {urdfpost.__version__}"


# --------------------------------------------------------------------------------------------
# regressions (bugs found while writing these tests, now fixed)


def test_verify_accepts_what_post_wrote_with_arcs(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    cl = write(tmp_path, "arc.apt", ARC_INCH)
    out = tmp_path / "arc.nc"
    assert (
        main(["post", "--strategy", "recursive", str(cl), "-m", "umc750", "-o", str(out), "-q"])
        == 0
    )
    assert main(["verify", str(out), "-m", "umc750", "--cl", str(cl)]) == 0
    capsys.readouterr()


def _arc_chord_errors(text: str, radius_in: float) -> np.ndarray:
    """Sagitta (inch) between consecutive program points on the arc of ``radius_in`` about
    the origin at Z 0.5 in (TCP Fanuc program)."""
    program = DIALECTS["fanuc"].read(text, path="arc.nc")
    pts = []
    last = [math.nan] * 3
    for mv in program.moves():
        last = [v if not math.isnan(v) else o for v, o in zip(mv.position[:3], last, strict=True)]
        p = np.array(last) / 25.4
        if abs(p[2] - 0.5) < 1e-4 and abs(math.hypot(p[0], p[1]) - radius_in) < 2e-4:
            pts.append(p[:2])
    pts_a = np.array(pts)
    half = np.arccos(np.clip(np.sum(pts_a[1:] * pts_a[:-1], 1) / radius_in**2, -1, 1)) / 2
    return radius_in * (1 - np.cos(half))


def test_tolerance_option_applies_to_arcs(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    cl = write(tmp_path, "arc.apt", ARC_INCH.replace("0.1700", "1.0000"))
    out = tmp_path / "arc.nc"
    assert (
        main(
            [
                "post",
                "--strategy",
                "recursive",
                str(cl),
                "-m",
                "umc750",
                "-o",
                str(out),
                "--tolerance",
                "0.0001",
                "--no-arcs",  # the interpolated points written: their chords are measured
            ]
        )
        == 0
    )
    capsys.readouterr()
    sagitta = _arc_chord_errors(out.read_text(), 1.0)
    assert len(sagitta) > 10
    assert sagitta.max() <= 0.0001 + 0.00005


def test_unwritable_output_is_a_domain_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    cl = write(tmp_path, "part.apt", TINY)
    rc = main(
        [
            "post",
            "--strategy",
            "recursive",
            str(cl),
            "-m",
            "dmu50",
            "-o",
            str(tmp_path / "missing" / "part.h"),
        ]
    )
    assert rc == 1
    assert capsys.readouterr().err.startswith("urdfpost: ")


@pytest.mark.parametrize("strategy", ["cone", "recursive", "none"])
def test_cl_file_without_motion_posts_an_empty_program_with_a_warning(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], strategy: str
) -> None:
    cl = tmp_path / "empty.apt"
    cl.write_text("PARTNO/EMPTY\nFEDRAT/1000\nFINI\n", encoding="ascii")
    out = tmp_path / "empty.h"
    assert (
        main(["post", str(cl), "--machine", "dmu50", "--strategy", strategy, "-o", str(out)]) == 0
    )
    err = capsys.readouterr().err
    assert "empty.apt: no motion records; the program has no moves" in err
    text = out.read_text(encoding="ascii")
    assert "BEGIN PGM EMPTY MM" in text and " L " not in text


# -- output paths: never an input, links followed, devices written, all outputs or none -------


@pytest.mark.parametrize("streamed", [False, True])
@pytest.mark.parametrize(
    ("output", "report", "fragment"),
    [
        ("part.apt", None, "the program (-o) would overwrite the CL file"),
        ("hard.apt", None, "the program (-o) would overwrite the CL file"),  # a hard link
        ("link.h", None, "the program (-o) would overwrite the CL file"),  # a symlink to it
        ("part.h", "part.apt", "the report (--report) would overwrite the CL file"),
        ("part.h", "part.h", "the report (--report) would overwrite the program (-o)"),
        ("part.h", "missing/part.json", "cannot write: no such folder"),
        ("part.h", "folder", "cannot write: it is a folder"),
        ("folder", None, "cannot write: it is a folder"),
    ],
)
def test_an_output_that_is_an_input_or_another_output_is_refused(
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    streamed: bool,
    output: str,
    report: str | None,
    fragment: str,
) -> None:
    monkeypatch.chdir(tmp_path)
    cl = write(tmp_path, "part.apt", TINY)
    (tmp_path / "hard.apt").hardlink_to(cl)
    (tmp_path / "link.h").symlink_to("part.apt")
    (tmp_path / "folder").mkdir()
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir() if p.is_file()}
    argv = ["post", "part.apt", "-m", "dmu50", "-c", "heidenhain", "-o", output, "-q"]
    argv += ["--report", report] if report else []
    argv += ["--piece-points", "2"] if streamed else []
    assert main(argv) == 1
    err = capsys.readouterr().err
    assert fragment in err and err.count("\n") == 1, err
    after = {p.name: p.read_bytes() for p in tmp_path.iterdir() if p.is_file()}
    assert after == before  # nothing written, nothing replaced, nothing left
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([*before, "folder"])


@pytest.mark.parametrize("streamed", [False, True])
def test_outputs_follow_links_and_write_devices_and_fifos(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], streamed: bool
) -> None:
    """``-o`` on a symlink writes its target (the link stays); ``-o /dev/null`` and a FIFO are
    written, never replaced by a regular file."""
    import os
    import stat
    import threading

    cl = write(tmp_path, "part.apt", TINY)
    more = ["--piece-points", "2"] if streamed else []
    target = tmp_path / "real.h"
    target.write_text("old program\n")
    link = tmp_path / "link.h"
    link.symlink_to(target.name)
    assert main(["post", str(cl), "-m", "dmu50", "-o", str(link), "-q", *more]) == 0
    assert link.is_symlink() and target.read_text().startswith("0 BEGIN PGM")

    devnull = os.stat(os.devnull)
    out = ["post", str(cl), "-m", "dmu50", "-c", "heidenhain", "-q", *more]
    assert main([*out, "-o", os.devnull, "--report", os.devnull]) == 0
    after = os.stat(os.devnull)
    assert stat.S_ISCHR(after.st_mode) and after.st_ino == devnull.st_ino

    fifo = tmp_path / "pipe.h"
    os.mkfifo(fifo)
    got: list[bytes] = []
    reader = threading.Thread(target=lambda: got.append(fifo.read_bytes()))
    reader.start()
    assert main([*out, "-o", str(fifo)]) == 0
    reader.join(timeout=60)
    assert stat.S_ISFIFO(os.stat(fifo).st_mode)
    assert got and got[0].decode() == target.read_text()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["link.h", "part.apt", "pipe.h", "real.h"]


@pytest.mark.parametrize("streamed", [False, True])
def test_a_full_disk_is_a_clear_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], streamed: bool
) -> None:
    """Writing to ``/dev/full`` fails with ENOSPC: one ``cannot write`` line, exit 1, nothing
    left behind, and the report that was to go with the program not written either."""
    if not Path("/dev/full").exists():
        pytest.skip("no /dev/full on this system")
    cl = write(tmp_path, "part.apt", TINY)
    argv = ["post", str(cl), "-m", "dmu50", "-c", "heidenhain", "-o", "/dev/full", "-q"]
    argv += ["--report", str(tmp_path / "r.json")]
    argv += ["--piece-points", "2"] if streamed else []
    assert main(argv) == 1
    err = capsys.readouterr().err
    assert err.startswith("urdfpost: /dev/full: cannot write: No space left on device"), err
    assert "Traceback" not in err
    assert files(tmp_path) == {"part.apt"}


@pytest.mark.parametrize("command", ["post", "compare"])
def test_prefer_of_an_axis_the_machine_lacks_is_a_usage_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], command: str
) -> None:
    """``--prefer A+`` on a B/C machine was silently ignored."""
    cl = write(tmp_path, "part.apt", TINY)
    argv = [command, str(cl), "-m", "dmu50", "--prefer", "A+"]
    argv += ["-o", str(tmp_path / "part.h")] if command == "post" else []
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "--prefer A: machine dmu50 has no rotary axis A; expected one of" in err, err
    assert files(tmp_path) == {"part.apt"}


def test_testpath_to_standard_output(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """``-o -`` is standard output (it wrote a file named ``-``)."""
    monkeypatch.chdir(tmp_path)
    assert main(["testpath", "sweep-1", "-o", "-"]) == 0
    text = capsys.readouterr().out
    assert main(["testpath", "sweep-1", "-o", "file.apt"]) == 0
    assert text == (tmp_path / "file.apt").read_text()
    assert files(tmp_path) == {"file.apt"}


@pytest.mark.parametrize("pieces", [[], ["--piece-points", "100"]])
def test_verify_says_how_to_verify_a_program_its_strategy_bent(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], pieces: list[str]
) -> None:
    """The dome posted as the README does (strategy cone, which bends the tool axis by up to
    2 deg near the pole): verified against the CL tool axis it is refused, and verify says
    what the header says, the --angle-tolerance to give; with it, it passes. A program whose
    header line is gone gets no such advice."""
    dome = DOME
    out = tmp_path / "dome.h"
    assert main(["post", str(dome), "-m", "dmu50", "-o", str(out), "-q"]) == 0
    capsys.readouterr()
    verify = ["verify", str(out), "-m", "dmu50", "--cl", str(dome), *pieces]
    assert main(verify) == 1
    printed = capsys.readouterr().out
    advice = re.search(
        r"dome\.h: the tool axis is off the CL data's by up to ([0-9.]+) deg, and the header says "
        r"the post's singularity strategy may bend it by up to 2 deg: verify it with "
        r"--angle-tolerance 2 ",
        printed,
    )
    assert advice and 0.5 < float(advice[1]) <= 2.5, printed
    assert main([*verify, "--angle-tolerance", "2"]) == 0
    capsys.readouterr()
    text = out.read_text()
    out.write_text(re.sub(r"^\d+ ; tool axis: .*\n", "", text, flags=re.M))
    assert main(verify) == 1
    assert "--angle-tolerance 2" not in capsys.readouterr().out
