"""A reorientation in place through the pole (the tip held, the tool axis tilted from the
pole to 90 degrees and back): the cone does not limit the first rotary axis where the tip
does not move (no tip feed to keep), so it bends nothing there.

Limited by the zero time of those moves, the tube had no room at any point: it restarted its
forward pass at every point (quadratic: 8000 points took 64 s) and bent the whole turn, with
about 8 blocks per CL point and 2 degrees of axis deviation throughout.
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from urdfpost import load_machine
from urdfpost.planning.strategies import cone
from urdfpost.posting.options import PostOptions
from urdfpost.posting.whole import post
from urdfpost.readers import read_cl


def _goto(i: float, j: float, k: float) -> str:
    n = math.sqrt(i * i + j * j + k * k)
    return f"GOTO/0.000000,0.000000,10.000000,{i / n:.9f},{j / n:.9f},{k / n:.9f}"


def _turn_in_place(points: int, path: Path) -> Path:
    """The tip at (0, 0, 10); the axis from the pole to a 90 degree tilt (azimuth 30 degrees)
    and back, ``points`` + 1 GOTOs at a feed."""
    lines = ["PARTNO TURN", "UNITS/MM", "MULTAX/ON", "LOADTL/3", "CUTTER/6.0,3.0"]
    lines += ["SPINDL/12000,CLW", "RAPID", _goto(0.0, 0.0, 1.0), "FEDRAT/MMPM,1000"]
    half = points // 2
    az = math.radians(30.0)
    for p in range(points + 1):
        t = math.radians(90.0 * (p if p <= half else points - p) / half)
        lines.append(_goto(math.sin(t) * math.cos(az), math.sin(t) * math.sin(az), math.cos(t)))
    path.write_text("\n".join([*lines, "FINI"]) + "\n")
    return path


@pytest.mark.parametrize("compiled", [False, True], ids=["numpy", "compiled"])
def test_a_turn_in_place_through_the_pole_is_not_bent(
    compiled: bool, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    if not compiled:
        monkeypatch.setattr(cone.KERNELS, "start", 10**9)  # (the numpy tube)
    elif cone.KERNELS.load() is None:
        pytest.skip("numba is not installed")
    else:
        monkeypatch.setattr(cone.KERNELS, "start", 1)
    job = read_cl(_turn_in_place(600, tmp_path / "turn.apt"))
    result = post(job, load_machine("dmu50"), PostOptions(controller="heidenhain"))
    strategy = result.report.figures.strategy
    assert strategy.name == "cone"
    assert not strategy.bent  # nothing bent: the axis as programmed everywhere
    v = result.verification
    assert v.ok and v.reached == len(job)
    assert v.max_orientation_deviation_deg < 1e-6
    assert v.blocks < len(job) + 20  # (not ~8 blocks per CL point)
