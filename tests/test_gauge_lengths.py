"""The gauge length a machine-coordinate program is computed with: the tool table, else the
CL data's ``LOADTL LENGTH``, else the job's one length (docs/job.md). A CUTTER's or NX
TLDATA's length is the cutter's own length and never a gauge length.

Found in session 16: the cutter's length went into the tool event as its ``length`` and was
taken for the gauge length (the NX 15-operation job without a tool table was posted with T2 at
38.1 mm); a one-tool job's ``LOADTL LENGTH`` was ignored by the whole post (the streamed post
used it: the two programs 20 mm apart in Z); and a tool loaded again without LENGTH went back
to the job's length.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from conftest import SHARED_CL

from urdfpost.cli import main
from urdfpost.errors import CLDataError
from urdfpost.posting.tools import gauge_lengths, tool_cutters
from urdfpost.readers import read_cl, read_cl_text

DOME = Path(__file__).resolve().parents[1] / "examples" / "dome.apt"
NX = SHARED_CL / "nx_project2_15ops_inch.cls"


def _dome(tmp_path: Path, name: str, loads: list[str]) -> Path:
    """The dome's path once per tool change record of ``loads``."""
    skip = ("PARTNO", "LOADTL", "CUTTER", "FINI", "END", "GOHOME")
    body = [x for x in DOME.read_text().splitlines() if not x.startswith(skip)]
    lines = ["PARTNO GAUGE"]
    for load in loads:
        lines += [load, *body]
    path = tmp_path / f"{name}.apt"
    path.write_text("\n".join([*lines, "FINI"]) + "\n")
    return path


def _post(cl: Path, out: Path, *extra: str) -> str:
    argv = ["post", str(cl), "-m", "dmu50", "-c", "fanuc", "--no-tcp", "-o", str(out), "-q"]
    assert main([*argv, *extra]) == 0
    return out.read_text()


def _body(text: str) -> list[str]:
    """The program without its comments (the header names the source)."""
    return [line for line in text.splitlines() if not line.startswith("(")]


def test_a_cutter_length_is_no_gauge_length(tmp_path: Path) -> None:
    """Two tools whose CUTTER records give a length of 25 and 40 mm: both have the job's
    gauge length (one section), and the collision body keeps each cutter's length."""
    cl = _dome(
        tmp_path, "cutters", ["LOADTL/1\nCUTTER/6,3,0,0,0,0,25", "LOADTL/2\nCUTTER/6,3,0,0,0,0,40"]
    )
    tp = read_cl(cl)
    assert gauge_lengths(tp, 100.0) == {1: 100.0, 2: 100.0}
    assert tool_cutters(tp)[1] == {1: (6.0, 3.0, 25.0), 2: (6.0, 3.0, 40.0)}
    text = _post(cl, tmp_path / "cutters.nc")
    assert "WITH TOOL LENGTH 100.000 MM" in text


@pytest.mark.skipif(not NX.is_file(), reason="shared NX data not present")
def test_nx_tldata_lengths_are_no_gauge_lengths() -> None:
    """The 15-operation NX job's TLDATA lengths (4.0, 1.5 and 2.5 in) are its cutters' own:
    without a tool table every tool has the job's length."""
    tp = read_cl(NX)
    assert gauge_lengths(tp, 100.0) == {1: 100.0, 2: 100.0, 3: 100.0}
    assert [round(c[2], 3) for c in tool_cutters(tp)[1].values()] == [101.6, 38.1, 63.5]


@pytest.mark.parametrize("streamed", [False, True])
def test_one_tool_is_posted_with_its_loadtl_length(tmp_path: Path, streamed: bool) -> None:
    """``LOADTL/3,LENGTH,120``: the program is the one of ``--tool-length 120`` (it was the
    machine file's 100 mm in the whole post), whole and streamed."""
    cl = _dome(tmp_path, "given", ["LOADTL/3,LENGTH,120"])
    plain = _dome(tmp_path, "plain", ["LOADTL/3"])
    pieces = ["--piece-points", "100"] if streamed else []
    given = _post(cl, tmp_path / "given.nc", *pieces)
    wanted = _post(plain, tmp_path / "wanted.nc", "--tool-length", "120", *pieces)
    assert "WITH TOOL LENGTH 120.000 MM" in given
    assert _body(given) == _body(wanted)


def test_a_tool_loaded_again_keeps_its_length(tmp_path: Path) -> None:
    """Tool 1 with LENGTH 120, loaded again without it: 120 for both loads (it fell back to
    the job's length for the whole job), the program that of LENGTH on both."""
    once = _dome(tmp_path, "once", ["LOADTL/1,LENGTH,120", "LOADTL/1"])
    both = _dome(tmp_path, "both", ["LOADTL/1,LENGTH,120", "LOADTL/1,LENGTH,120"])
    assert gauge_lengths(read_cl(once), 100.0) == {1: 120.0}
    assert _body(_post(once, tmp_path / "once.nc")) == _body(_post(both, tmp_path / "both.nc"))


def test_a_length_given_after_none_is_refused() -> None:
    """Tool 1 first loaded without LENGTH (the job's length), then with LENGTH 120: two tools
    for one number, refused at the second load."""
    text = "UNITS/MM\nLOADTL/1\nFEDRAT/100\nGOTO/0,0,0\nLOADTL/1,LENGTH,120\nGOTO/1,0,0\nFINI\n"
    with pytest.raises(CLDataError, match=r"x\.apt:5: tool 1 is LENGTH 120 here but no LENGTH"):
        read_cl_text(text, source="x.apt")
