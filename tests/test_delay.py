"""APT ``DELAY`` (a dwell) is the control's dwell block, not a comment.

``DELAY/2.5`` (seconds; also ``DELAY/SEC,2.5``) and ``DELAY/REV,10`` (turns of the spindle at
the speed programmed) were carried into the program as comments with a warning: the control
did not dwell where the CAM system asked it to (a spot face, a hole's bottom, a chip break).
Now each is a :class:`~urdfpost.program.Dwell` (G4, Heidenhain cycle 9), read back as one, and
LinuxCNC's interpreter dwells for that long.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from rs274 import run_rs274

from urdfpost.cli import main
from urdfpost.dialects import DIALECTS
from urdfpost.errors import CLDataError
from urdfpost.program import Dwell, Move, MoveTable
from urdfpost.readers import read_cl_text

HEAD = "PARTNO DELAY\nUNITS/MM\nMULTAX/ON\nLOADTL/1\nCUTTER/10,0\nSPINDL/RPM,8000,CLW\n"
MOVES = "RAPID\nGOTO/0,0,50,0,0,1\nFEDRAT/MMPM,500\nGOTO/0,0,10,0,0,1\n"


def _job(delays: str, head: str = HEAD) -> str:
    return f"{head}{MOVES}{delays}\nGOTO/20,0,10,0,0,1\nFINI\n"


def _kind(part: object) -> str:
    """A program part as "feed" (a block of feed moves), "dwell", or "" (anything else)."""
    if isinstance(part, Dwell):
        return "dwell"
    if isinstance(part, MoveTable) and not part.rapid.all():
        return "feed"
    if isinstance(part, Move) and not part.rapid:
        return "feed"
    return ""


def _dwells(text: str) -> list[tuple[int, float]]:
    tp = read_cl_text(text, source="delay.apt")
    return [(e.line, e.data["seconds"]) for e in tp.events if e.kind == "dwell"]


def test_delay_in_seconds_and_in_spindle_turns() -> None:
    """Seconds with or without SEC, either order; turns at the spindle speed programmed (10
    turns at 8000/min: 0.075 s), in inch files too (a time has no unit)."""
    delays = "DELAY/2.5\nDELAY/SEC,1.5\nDELAY/0.5,SEC\nDELAY/REV,10\nDELAY/0"
    assert _dwells(_job(delays)) == [(11, 2.5), (12, 1.5), (13, 0.5), (14, 0.075), (15, 0.0)]
    inch = _job("DELAY/2", HEAD.replace("UNITS/MM", "UNITS/INCHES"))
    assert _dwells(inch) == [(11, 2.0)]


@pytest.mark.parametrize(
    ("record", "expected"),
    [
        ("DELAY/-1", "expected a dwell >= 0 in DELAY, got -1"),
        ("DELAY", "expected DELAY/seconds, DELAY/SEC,seconds or DELAY/REV,turns"),
        ("DELAY/1,2", "expected DELAY/seconds, DELAY/SEC,seconds or DELAY/REV,turns"),
        ("DELAY/MIN,1", "expected DELAY/seconds, DELAY/SEC,seconds or DELAY/REV,turns"),
        ("DELAY/REV,SEC,1", "expected DELAY/seconds, DELAY/SEC,seconds or DELAY/REV,turns"),
        ("DELAY/1.2.3", "the 1st value of DELAY"),
    ],
)
def test_a_bad_delay_is_refused_at_its_line(record: str, expected: str) -> None:
    with pytest.raises(CLDataError, match=r"delay\.apt:11: .*") as e:
        read_cl_text(_job(record), source="delay.apt")
    assert expected in str(e.value)


def test_turns_need_a_turning_spindle_with_a_speed() -> None:
    stopped = _job("SPINDL/OFF\nDELAY/REV,10")
    with pytest.raises(CLDataError, match=r"delay\.apt:12: DELAY/REV: .* spindle stopped"):
        read_cl_text(stopped, source="delay.apt")
    unknown = _job("DELAY/REV,10", HEAD.replace("SPINDL/RPM,8000,CLW", "SPINDL/ON"))
    with pytest.raises(CLDataError, match=r"delay\.apt:11: DELAY/REV: .* speed unknown"):
        read_cl_text(unknown, source="delay.apt")


@pytest.mark.parametrize("controller", sorted(DIALECTS))
@pytest.mark.parametrize("tcp", [True, False])
def test_each_control_dwells_and_reads_it_back(
    tmp_path: Path, controller: str, tcp: bool, capsys: pytest.CaptureFixture[str]
) -> None:
    """Posted with and without TCP: the control's dwell blocks, in order, where the CL data
    has them (after the first cut), read back as dwells of the same time; no warning."""
    cl = tmp_path / "delay.apt"
    cl.write_text(_job("DELAY/2.5\nDELAY/REV,10"))
    out = tmp_path / f"delay{DIALECTS[controller].extensions[0]}"
    argv = ["post", str(cl), "-m", "dmu50", "-c", controller, "-o", str(out), "-q"]
    assert main([*argv, "--tcp" if tcp else "--no-tcp"]) == 0
    assert "warning" not in capsys.readouterr().err
    back = DIALECTS[controller].read(out.read_text())
    dwells = [p.seconds for p in back.parts if isinstance(p, Dwell)]
    assert dwells == pytest.approx([2.5, 0.075])
    # between the cut down to Z10 and the cut along X (the program's feed rows)
    kinds = [_kind(p) for p in back.parts]
    kinds = [k for k in kinds if k]
    assert kinds[kinds.index("dwell") - 1 :] == ["feed", "dwell", "dwell", "feed"], kinds
    text = out.read_text()
    if controller == "linuxcnc":
        result = run_rs274(text, {1: 0.0 if not tcp else 100.0}, tmp_path / "rs274")
        assert [c.number(0) for c in result.named("DWELL")] == pytest.approx([2.5, 0.075])
