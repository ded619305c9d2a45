"""Numbers a CL reader must refuse at their record (issue 22): values that overflow, or grow
absurdly large, when converted to millimetres, and values that are not finite.

Every case is read whole (:func:`read_cl`) and in pieces (:func:`read_cl_chunks`), with every
warning an error: the message names the file, the line and what was expected, and no numpy
RuntimeWarning comes before it.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import urdfpost.readers.apt as apt_module
from urdfpost.errors import CLDataError
from urdfpost.readers import read_cl, read_cl_chunks, read_cl_text

ROOT = Path(__file__).resolve().parents[1]

#: The end of every message about a length beyond the bound.
LENGTH = "is beyond the largest length urdfpost accepts (1e9 mm)"
#: ... and about a feed beyond the bound.
FEED = "is beyond the fastest feed urdfpost accepts (1e9 mm/min)"
#: 39 plain GOTO lines (inch): a run read in bulk before and after a bad record.
RUN = "".join(f"GOTO/{k * 0.1:.4f},{-k:.3f},{k % 3},0.6,0,0.8\n" for k in range(1, 40))

# (name, format, units given to the reader, text, line, message after "name:line: ")
CASES = [
    (
        "goto-x-inch",
        "apt",
        None,
        "UNITS/INCHES\nGOTO/0,0,0,0,0,1\nGOTO/1e308,0,0,0,0,1\nGOTO/1,0,0,0,0,1\n",
        3,
        f"GOTO: x 1e308 inch {LENGTH}",
    ),
    (
        "goto-y-in-a-run",
        "apt",
        None,
        "UNITS/INCHES\nFEDRAT/IPM,10\n" + RUN + "GOTO/0,-1e308,0,0,0,1\n" + RUN,
        42,
        f"GOTO: y -1e308 inch {LENGTH}",
    ),
    (
        "goto-z-absurd-not-overflowing",  # 4e7 in = 1.016e9 mm: finite, and still absurd
        "apt",
        None,
        "UNITS/INCHES\n" + RUN + "GOTO/0,0,4e7\n" + RUN,
        41,
        f"GOTO: z 4e7 inch {LENGTH}",
    ),
    ("goto-mm", "apt", None, "UNITS/MM\nGOTO/0,2e9,0\n", 2, f"GOTO: y 2e9 mm {LENGTH}"),
    ("from", "apt", "inch", "FROM/0,0,1e308\n", 1, f"FROM: z 1e308 inch {LENGTH}"),
    (
        "circle-radius",
        "apt",
        None,
        "GOTO/0,0,0\nGOTO/1,0,0\nCIRCLE/0,0,0,0,0,1,1e300\nGOTO/-1,0,0\n",
        3,
        f"CIRCLE: radius 1e300 mm {LENGTH}",
    ),
    (
        "circle-radius-inch",
        "apt",
        None,
        "UNITS/INCHES\nGOTO/1,0,0\nCIRCLE/0,0,0,0,0,1,1e308\nGOTO/-1,0,0\n",
        3,
        f"CIRCLE: radius 1e308 inch {LENGTH}",
    ),
    (
        "circle-centre",
        "apt",
        None,
        "UNITS/INCHES\nGOTO/1,0,0\nCIRCLE/0,1e308,0,0,0,1,1\nGOTO/-1,0,0\n",
        3,
        f"CIRCLE: centre y 1e308 inch {LENGTH}",
    ),
    ("fedrat-ipm", "apt", None, "FEDRAT/IPM,1e308\n", 1, f"FEDRAT: feed 1e308 inch/min {FEED}"),
    (
        "fedrat-file-units",
        "apt",
        None,
        "UNITS/INCHES\nFEDRAT/1e308\n",
        2,
        f"FEDRAT: feed 1e308 inch/min {FEED}",
    ),
    (
        "fedrat-ipr",
        "apt",
        None,
        "FEDRAT/IPR,1e308\n",
        1,
        "FEDRAT: feed 1e308 inch/rev is beyond the largest feed per revolution urdfpost "
        "accepts (1e9 mm/rev)",
    ),
    (
        "fedrat-per-rev-at-speed",
        "apt",
        None,
        "SPINDL/1e6,CLW\nFEDRAT/MMPR,1e4\n",
        2,
        f"FEDRAT: feed 10000 mm/rev at 1e6 rpm {FEED}",
    ),
    (
        "spindle-speed-for-feed-per-rev",
        "apt",
        None,
        "FEDRAT/IPR,0.01\nSPINDL/1e300,CLW\n",
        2,
        f"SPINDL: feed 0.01 inch/rev at 1e300 rpm {FEED}",
    ),
    ("cutter", "apt", "inch", "CUTTER/1e308\n", 1, f"CUTTER: diameter 1e308 inch {LENGTH}"),
    (
        "cutter-corner",
        "apt",
        None,
        "UNITS/INCHES\nCUTTER/0.5,1e308\n",
        2,
        f"CUTTER: corner radius 1e308 inch {LENGTH}",
    ),
    (
        "cutter-length",
        "apt",
        None,
        "UNITS/INCHES\nCUTTER/0.5,0.1,0,0,0,0,1e308\n",
        2,
        f"CUTTER: length 1e308 inch {LENGTH}",
    ),
    (
        "tldata",
        "apt",
        None,
        "UNITS/INCHES\nTLDATA/MILL,0.5,0,1e308\n",
        2,
        f"TLDATA: length 1e308 inch {LENGTH}",
    ),
    (
        "loadtl-length",
        "apt",
        None,
        "UNITS/INCHES\nLOADTL/1,LENGTH,1e308\n",
        2,
        f"LOADTL: length 1e308 inch {LENGTH}",
    ),
    (
        "msys-origin",
        "apt",
        None,
        "UNITS/INCHES\nMSYS/0,0,1e308,1,0,0,0,1,0\n",
        2,
        f"MSYS: origin z 1e308 inch {LENGTH}",
    ),
    ("plain", "plain", "inch", "1 2 3\n1e308 0 0\n", 2, f"x 1e308 inch {LENGTH}"),
    ("plain-axis", "plain", "inch", "1 2 3\n0 -1e308 0 0 0 1\n", 2, f"y -1e308 inch {LENGTH}"),
    ("plain-mm", "plain", None, "# z\n0 0 -2e9\n", 2, f"z -2e9 mm {LENGTH}"),
]

# values that are not finite: errors already (LOADTL's LENGTH was not)
NOT_FINITE = [
    ("apt", "GOTO/nan,0,0\n", 1, "expected a finite number for the 1st value of GOTO, got 'nan'"),
    ("apt", "GOTO/0,inf,0\n", 1, "expected a finite number for the 2nd value of GOTO, got 'inf'"),
    ("apt", "GOTO/0,0,1e999\n", 1, "expected a finite number for the 3rd value of GOTO"),
    ("apt", "GOTO/1,0,0\nCIRCLE/0,0,0,0,0,1,inf\nGOTO/-1,0,0\n", 2, "expected a positive radius"),
    ("apt", "GOTO/1,0,0\nCIRCLE/nan,0,0,0,0,1,1\n", 2, "expected a finite number for the 1st"),
    ("apt", "FEDRAT/inf\n", 1, "expected a positive feed in FEDRAT, got inf"),
    ("apt", "SPINDL/nan\n", 1, "expected a spindle speed >= 0 in SPINDL, got nan"),
    ("apt", "CUTTER/6,nan\n", 1, "expected tool dimensions >= 0 in CUTTER, got nan"),
    ("apt", "TLDATA/MILL,inf\n", 1, "expected tool dimensions >= 0 in TLDATA, got inf"),
    (
        "apt",
        "LOADTL/1,LENGTH,nan\n",
        1,
        "expected a finite tool length for the 3rd value of LOADTL, got 'nan'",
    ),
    ("apt", "MSYS/0,0,nan,1,0,0,0,1,0\n", 1, "expected finite numbers in MSYS"),
    ("apt", "MSYS/0,0,0,1e300,0,0,0,1,0\n", 1, "expected two independent axis vectors in MSYS"),
    ("plain", "0 0 inf\n", 1, "expected a finite number for the 3rd value, got 'inf'"),
]


def _write(folder: Path, name: str, text: str) -> Path:
    path = folder / name
    path.write_text(text, encoding="utf-8")
    return path


def _whole_error(path: Path, fmt: str, units: str | None) -> CLDataError:
    with pytest.raises(CLDataError) as info:
        read_cl(path, format=fmt, units=units)
    return info.value


def _streamed_error(path: Path, fmt: str, units: str | None, **kwargs: int) -> CLDataError:
    with pytest.raises(CLDataError) as info:
        for _ in read_cl_chunks(path, format=fmt, units=units, **kwargs):
            pass
    return info.value


@pytest.mark.filterwarnings("error")
@pytest.mark.parametrize(
    ("name", "fmt", "units", "text", "line", "message"), CASES, ids=[c[0] for c in CASES]
)
def test_a_value_beyond_the_bound_is_an_error_at_its_record(
    tmp_path: Path, name: str, fmt: str, units: str | None, text: str, line: int, message: str
) -> None:
    path = _write(tmp_path, f"{name}.cl", text)
    expected = f"{path}:{line}: {message}"
    errors = [
        _whole_error(path, fmt, units),
        _streamed_error(path, fmt, units, max_points=2),
        _streamed_error(path, fmt, units, max_points=1, _text_piece=64),
    ]
    for error in errors:
        assert (str(error), error.path, error.line) == (expected, str(path), line)


@pytest.mark.filterwarnings("error")
@pytest.mark.parametrize(
    ("units", "text", "line", "message"),
    [c[2:] for c in CASES if c[1] == "apt"],
    ids=[c[0] for c in CASES if c[1] == "apt"],
)
def test_bulk_and_record_by_record_agree(
    monkeypatch: pytest.MonkeyPatch, units: str | None, text: str, line: int, message: str
) -> None:
    for least in (1, 10**9):  # every GOTO run read in bulk; none
        monkeypatch.setattr(apt_module, "BULK_MIN_RECORDS", least)
        with pytest.raises(CLDataError) as info:
            read_cl_text(text, source="src.apt", format="apt", units=units)
        assert (info.value.line, info.value.detail) == (line, message)


@pytest.mark.filterwarnings("error")
@pytest.mark.parametrize(("fmt", "text", "line", "message"), NOT_FINITE)
def test_a_value_that_is_not_finite_is_an_error(
    tmp_path: Path, fmt: str, text: str, line: int, message: str
) -> None:
    path = _write(tmp_path, "nan.cl", text)
    for error in (_whole_error(path, fmt, None), _streamed_error(path, fmt, None, max_points=1)):
        assert error.line == line
        assert error.detail.startswith(message), error.detail


@pytest.mark.filterwarnings("error")
@pytest.mark.parametrize("least", [1, 10**9])
def test_lengths_up_to_the_bound_are_read(monkeypatch: pytest.MonkeyPatch, least: int) -> None:
    monkeypatch.setattr(apt_module, "BULK_MIN_RECORDS", least)
    edge = "GOTO/1e9,-1e9,0\n" * 40
    arc = "GOTO/1e9,0,0\nCIRCLE/0,0,0,0,0,1,1e9\nGOTO/-1e9,0,0\n"
    text = "UNITS/MM\nCUTTER/1e9\nLOADTL/1,LENGTH,-1e9\nFEDRAT/1e9\n" + edge + arc
    tp = read_cl_text(text, format="apt", chord_tolerance=1e3)
    assert np.abs(tp.tip).max() <= 1e9 * (1 + 1e-12) and tp.feed.max() == 1e9
    assert tp.tip[:40].tolist() == [[1e9, -1e9, 0.0]] * 40
    plain = read_cl_text("1e9 -1e9 0\n", format="plain")
    assert plain.tip.tolist() == [[1e9, -1e9, 0.0]]


@pytest.mark.parametrize(
    ("text", "line", "message"),
    [
        (
            "UNITS/INCHES\nGOTO/0,0,0,0,0,1\nGOTO/1e308,0,0,0,0,1\nGOTO/1,0,0,0,0,1\nFINI\n",
            3,
            f"GOTO: x 1e308 inch {LENGTH}",
        ),
        (
            "GOTO/0,0,0\nGOTO/1,0,0\nCIRCLE/0,0,0,0,0,1,1e300\nGOTO/-1,0,0\nFINI\n",
            3,
            f"CIRCLE: radius 1e300 mm {LENGTH}",
        ),
    ],
    ids=["goto", "circle"],
)
@pytest.mark.parametrize("streamed", [[], ["--piece-points", "2"]], ids=["whole", "streamed"])
def test_the_command_line_names_the_record(
    tmp_path: Path, text: str, line: int, message: str, streamed: list[str]
) -> None:
    _write(tmp_path, "bad.apt", text)
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    argv = [sys.executable, "-W", "error", "-m", "urdfpost", "post", "bad.apt", "-m", "dmu50"]
    done = subprocess.run(
        [*argv, *streamed], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120
    )
    assert (done.returncode, done.stdout, done.stderr) == (
        1,
        "",
        f"urdfpost: bad.apt:{line}: {message}\n",
    )
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.apt"]  # nothing written
