"""The CL path at a pivot (the ball centre that ``--angle-tolerance`` measures) is a curve, not
the chord between the CL points' ball centres.

A CL segment moves the tool tip straight and turns the tool axis on its slerp, so the ball
centre, r up the axis, moves on ``tip(u) + r slerp(u)``: off the chord between its ends by up
to ``r (1 - cos(omega / 2))``. Measured against the chord, a program that follows the CL data
exactly was refused by ``urdfpost verify --angle-tolerance`` once the axis turned by tens of
degrees in a block (10 mm moves turning 20-40 degrees with a 3 mm ball: 0.141 mm against a
tolerance of 0.0362 mm).
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import minimize_scalar

from urdfpost.cli import main
from urdfpost.geometry import Arcs, Segments, coords
from urdfpost.verification.measure import _FLAT, _curve_distance2, _Polyline

RADIUS = 3.0


def _turning_cl(path: Path, turn_deg: float, step: float = 10.0) -> Path:
    """A ball-end job whose tool axis turns ``turn_deg`` per move, back and forth between 15 and
    15 + 2 turn degrees off Z (away from the pole), while the tip moves ``step`` mm along X."""
    lines = ["PARTNO TURN", "UNITS/MM", "MULTAX/ON", "LOADTL/1"]
    lines += [f"CUTTER/{2 * RADIUS},{RADIUS}", "SPINDL/10000,CLW", "RAPID"]
    for k in range(8):
        tilt = math.radians(15 + turn_deg * (k % 3))
        spin = math.radians(30 * k / 8)
        i, j, kk = math.sin(tilt) * math.cos(spin), math.sin(tilt) * math.sin(spin), math.cos(tilt)
        lines.append(f"GOTO/{-30 + step * k:.4f},0.0000,5.0000,{i:.6f},{j:.6f},{kk:.6f}")
        if k == 0:
            lines.append("FEDRAT/MMPM,1000")
    lines.append("FINI")
    path.write_text("\n".join(lines) + "\n")
    return path


def _verify(program: Path, cl: Path, capsys: pytest.CaptureFixture[str]) -> tuple[int, float]:
    """``urdfpost verify --angle-tolerance 2``: exit code and the tip deviation reported."""
    args = ["verify", str(program), "-m", "dmu50", "--cl", str(cl), "--angle-tolerance", "2"]
    code = main(args)
    out = capsys.readouterr()
    found = re.search(r"tool tip deviation max ([0-9.]+)", out.out + out.err)
    assert found, out
    return code, float(found[1])


@pytest.mark.parametrize("tcp", [True, False])
@pytest.mark.parametrize("turn", [20.0, 40.0])
def test_a_program_turning_the_axis_by_tens_of_degrees_verifies_at_the_ball_centre(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], tcp: bool, turn: float
) -> None:
    """Posted, the job verifies at the ball centre within the tolerance the post gives it
    (the tip tolerance plus the ball radius times the orientation tolerance; less than the
    chord's sag), and a program moved 0.08 mm at one CL point, along the path or across it,
    is refused."""
    cl = _turning_cl(tmp_path / "turn.apt", turn)
    program = tmp_path / "turn.h"
    post = ["post", str(cl), "-m", "dmu50", "-c", "heidenhain", "-q", "-o", str(program)]
    assert main(post + ([] if tcp else ["--no-tcp"])) == 0
    capsys.readouterr()
    code, tip = _verify(program, cl, capsys)
    assert code == 0
    assert tip <= 0.01 + RADIUS * math.radians(0.5)  # the tolerance of the ball centre
    assert tip < RADIUS * (1 - math.cos(math.radians(turn) / 2))  # the chord's sag, at least

    text = program.read_text().splitlines(keepends=True)
    moves = [i for i, line in enumerate(text) if re.match(r"\d+ L X[-+][0-9.]+ .*", line)]
    at = moves[len(moves) // 2]
    along = text.copy()  # a CL point's row moved along the path: that point is missed
    along[at] = re.sub(r"X([-+][0-9.]+)", lambda w: f"X{float(w[1]) + 0.08:+.3f}", text[at])
    damaged = tmp_path / "damaged.h"
    damaged.write_text("".join(along))
    assert _verify(damaged, cl, capsys)[0] == 1
    if tcp:  # moved 0.08 mm across the path (Z, the same 5 mm all along, is modal)
        assert "Z" not in text[at] + text[at + 1]
        across = text.copy()
        across[at] = text[at].replace(" B", " Z+5.080 B", 1)
        across[at + 1] = text[at + 1].replace(" B", " Z+5.000 B", 1)
        damaged.write_text("".join(across))
        code, tip = _verify(damaged, cl, capsys)
        assert code == 1
        assert tip > 0.07


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    turn=st.one_of(st.floats(0.0, 170.0), st.sampled_from([0.0, 0.01, 0.03, 0.05, 0.2])),
    length=st.sampled_from([0.0, 0.01, 1.0, 10.0, 50.0]),
    radius=st.floats(0.5, 8.0),
    off=st.sampled_from([0.0, 1e-3, 0.05]),
)
def test_the_distance_from_the_curve_is_the_nearest_point_s(
    seed: int, turn: float, length: float, radius: float, off: float
) -> None:
    """``_curve_distance2`` against a dense scan refined by a bounded search: for a point
    within 0.05 mm of the curve the same distance (to 1e-8 mm; on a segment whose sag is at
    most ``_FLAT``, measured without Newton steps, to twice the sag), whatever the turn (up to
    170 degrees in one segment) and the tip's move (none: a turn in place); for any point never
    less (it is the distance to a point of the curve)."""
    rng = np.random.default_rng(seed)
    omega = math.radians(turn)
    a0 = rng.normal(size=3)
    a0 /= np.linalg.norm(a0)
    normal = rng.normal(size=3)
    normal -= (normal @ a0) * a0
    normal /= np.linalg.norm(normal)
    a1 = math.cos(omega) * a0 + math.sin(omega) * normal
    t0 = rng.normal(size=3) * 10.0
    t1 = t0 + rng.normal(size=3) * length

    def curve(u: np.ndarray) -> np.ndarray:
        u = np.asarray(u, dtype=float)[..., None]
        if omega < 1e-9:
            slerp = a0 + 0.0 * u
        else:
            slerp = (np.sin((1 - u) * omega) * a0 + np.sin(u * omega) * a1) / math.sin(omega)
        return t0 + u * (t1 - t0) + radius * slerp

    grid = np.linspace(0.0, 1.0, 20001)
    on = curve(grid)
    for far in (off, 0.5, 3.0):
        point = curve(rng.uniform()) + rng.normal(size=3) * far / math.sqrt(3)
        scan = np.sum((on - point) ** 2, axis=1)
        k = int(np.argmin(scan))
        found = minimize_scalar(
            lambda x, p=point: float(np.sum((curve(x) - p) ** 2)),
            bounds=(grid[max(k - 1, 0)], grid[min(k + 1, len(grid) - 1)]),
            method="bounded",
            options={"xatol": 1e-12},
        )
        true = math.sqrt(min(float(found.fun), float(scan[k])))
        seg = Segments.between((t0 + radius * a0)[None], (t1 + radius * a1)[None])
        arc = Arcs.between(a0[None], a1[None])
        pts = coords(point[None])
        s = seg.distance2(pts)[1]
        d2, u = _curve_distance2(seg, arc, pts, s, radius)
        got = math.sqrt(float(d2[0]))
        assert 0.0 <= u[0] <= 1.0
        assert math.isclose(got, float(np.linalg.norm(curve(u[0]) - point)), abs_tol=1e-9)
        assert got >= true - 1e-8
        sag = radius * (1.0 - math.cos(omega / 2.0))
        if far <= 0.05:
            assert got <= true + 1e-8 + (2.0 * sag if sag <= _FLAT else 0.0)


def test_the_curve_leaves_the_chord_by_its_sag_at_most() -> None:
    """``|slerp(u) - lerp(u)|`` of unit vectors omega apart is largest halfway, ``1 - cos(omega
    / 2)``: the bound the search of far segments and the axis window grow by
    (:meth:`_Polyline.sag`)."""
    u = np.linspace(0.0, 1.0, 40001)
    omega = np.linspace(1e-3, math.pi - 1e-3, 300)
    w = omega[:, None] * u
    off = np.hypot(
        np.cos(w) - (1 - u + u * np.cos(omega)[:, None]), np.sin(w) - u * np.sin(omega)[:, None]
    )
    tip = np.zeros((2, 3))
    axis = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 1.0]])
    for k, angle in enumerate(omega):
        axis[1] = [math.sin(angle), 0.0, math.cos(angle)]
        sag = _Polyline.of(tip + 2.0 * axis, axis, -2.0).sag()[0]
        assert math.isclose(sag, 2.0 * off[k].max(), rel_tol=1e-7)
        assert math.isclose(off[k].max(), off[k][20000], rel_tol=1e-12)  # halfway
