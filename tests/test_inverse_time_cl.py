"""APT ``FEDRAT/INVERS,f``: CL data at an inverse-time feed.

Each feed move after it takes ``1/f`` minutes, so its tool tip moves at ``f`` times the move's
length per minute. The record was carried into the program as a comment with a warning, and
the moves after it were cut at the feed before it (a 10 mm move meant to take 3 s ran at
1016 mm/min, five times too fast). Now each move's feed is its length times ``f``, which the
post times as every feed (and its own check measures the program against).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from urdfpost.cli import main
from urdfpost.errors import CLDataError
from urdfpost.readers import read_cl_text
from urdfpost.readers.apt import KERNELS

HEAD = "PARTNO INVERS\nUNITS/MM\nMULTAX/ON\nLOADTL/1\nCUTTER/10,0\nSPINDL/RPM,8000,CLW\n"
START = "RAPID\nGOTO/0,0,50,0,0,1\nFEDRAT/MMPM,500\nGOTO/0,0,10,0,0,1\n"


def _read(body: str, head: str = HEAD):
    return read_cl_text(f"{head}{START}{body}\nFINI\n", source="inv.apt")


def test_each_move_takes_one_over_f_minutes() -> None:
    """Lines, a GODLTA, a run of many GOTOs, then FEDRAT/MMPM again: each move's feed is its
    tip length times f; the moves before and after keep their feed per minute."""
    zigzag = [f"GOTO/{10 + 0.5 * k:.4f},{(k % 2) * 3.0:.4f},10,0,0,1" for k in range(400)]
    head = ["FEDRAT/INVERS,20", "GOTO/10,0,10,0,0,1", "GODLTA/0,0,2"]
    body = "\n".join([*head, *zigzag[1:], "FEDRAT/MMPM,600", "GOTO/0,0,12,0,0,1"])
    tp = _read(body)
    tips = np.asarray(tp.tip)
    lengths = np.linalg.norm(np.diff(tips, axis=0), axis=1)
    assert tp.feed[1] == 500.0
    np.testing.assert_allclose(tp.feed[2:-1], 20.0 * lengths[1:-1], rtol=1e-12)
    assert tp.feed[-1] == 600.0
    # the same read record by record (no compiled or numpy bulk reading of the runs)
    forced = KERNELS.forced
    try:
        KERNELS.forced = False
        again = _read(body)
    finally:
        KERNELS.forced = forced
    np.testing.assert_array_equal(again.feed, tp.feed)


@pytest.mark.parametrize("forced", [True, False])
def test_an_inverse_time_feed_before_every_move(forced: bool) -> None:
    """CL data with a FEDRAT/INVERS before every GOTO (each move its own time), long enough
    for the bulk readers (compiled and numpy): each move's feed is its own f times its
    length (an INVERS line is no feed line of a run)."""
    lines, fs = [], []
    for k in range(1, 3000):
        fs.append(5 + k % 7)
        lines += [f"FEDRAT/INVERS,{fs[-1]}", f"GOTO/{k * 0.5:.4f},{(k % 2) * 2:.4f},10,0,0,1"]
    previous = KERNELS.forced
    try:
        KERNELS.forced = forced
        tp = _read("\n".join(lines))
    finally:
        KERNELS.forced = previous
    length = np.linalg.norm(np.diff(np.asarray(tp.tip), axis=0), axis=1)
    np.testing.assert_allclose(tp.feed[2:], np.array(fs) * length[1:], rtol=1e-12)


def test_an_arc_takes_one_over_f_minutes() -> None:
    """A quarter circle of radius 10 at FEDRAT/INVERS,6: every point of it at 6 times its
    length (the chords' sum, within the chord tolerance of 15.708 mm) per minute."""
    body = "GOTO/10,0,10,0,0,1\nFEDRAT/INVERS,6\nCIRCLE/0,0,10,0,0,1,10\nGOTO/0,10,10,0,0,1"
    tp = _read(body)
    arc = tp.feed[3:]
    assert len(arc) > 3 and np.all(arc == arc[0])
    assert arc[0] == pytest.approx(6 * 10 * np.pi / 2, rel=1e-4)


@pytest.mark.parametrize(
    ("body", "expected"),
    [
        ("FEDRAT/INVERS,0", r"inv\.apt:11: expected a positive inverse-time feed .* got 0"),
        ("FEDRAT/INVERS", r"inv\.apt:11: expected one inverse-time feed in FEDRAT/INVERS"),
        ("FEDRAT/INVERS,1,2", r"inv\.apt:11: expected one inverse-time feed .* got 2"),
        (
            "FEDRAT/INVERS,5\nGOTO/0,0,10,1,0,0",
            r"inv\.apt:12: a move that does not move the tool tip at the inverse-time feed of "
            r"FEDRAT/INVERS,5 \(line 11\): the post times each move by its tip's feed",
        ),
        ("FEDRAT/INVERS,1e9\nGOTO/10,0,10", r"inv\.apt:12: GOTO: feed .* beyond the fastest"),
    ],
)
def test_what_cannot_be_timed_is_refused_at_its_line(body: str, expected: str) -> None:
    with pytest.raises(CLDataError, match=expected):
        _read(body)


def test_a_first_move_at_an_inverse_time_feed_is_refused() -> None:
    text = f"{HEAD}FEDRAT/INVERS,5\nGOTO/0,0,10,0,0,1\nFINI\n"
    with pytest.raises(CLDataError, match=r"inv\.apt:8: a first move at the inverse-time feed"):
        read_cl_text(text, source="inv.apt")


@pytest.mark.parametrize("args", [["--tcp"], ["--no-tcp"], ["--no-tcp", "--piece-points", "50"]])
def test_posted_at_the_moves_times(
    tmp_path: Path, args: list[str], capsys: pytest.CaptureFixture[str]
) -> None:
    """Posted (TCP, machine coordinates, in pieces) with no warning; the 10 mm move at
    FEDRAT/INVERS,20 is cut at 200 mm/min (LinuxCNC writes tip feeds per minute with TCP), and
    the post's check of the feeds passes."""
    zigzag = [f"GOTO/{10 + 0.5 * k:.4f},{(k % 2) * 3.0:.4f},10,0,0,1" for k in range(200)]
    cl = tmp_path / "inv.apt"
    cl.write_text(f"{HEAD}{START}FEDRAT/INVERS,20\nGOTO/10,0,10,0,0,1\n" + "\n".join(zigzag[1:]))
    out = tmp_path / "inv.ngc"
    assert main(["post", str(cl), "-m", "dmu50", "-c", "linuxcnc", "-o", str(out), *args]) == 0
    captured = capsys.readouterr()
    assert "warning" not in captured.err, captured.err
    assert "tip feed within tolerance" in captured.out
    if args == ["--tcp"]:
        assert "X10.000 F200" in out.read_text().replace(" Y0.000", "")
