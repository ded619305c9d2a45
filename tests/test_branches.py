"""Branch selection: travel limits, preference, continuity, unwrapping, unreachable points."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from oracles import tip_and_axis_pin

from urdfpost import UnreachableError, load_machine
from urdfpost.kinematics import IKStatus, tip_and_axis
from urdfpost.planning.branches import TWO_PI, Preference, select
from urdfpost.planning.branches.rules import _wrap


def tilt_path(tilt_deg: np.ndarray, azimuth_deg: np.ndarray, z: float = 10.0) -> tuple:
    """CL points on a line with tool axes at the given tilt from +Z and azimuth about +Z."""
    t, a = np.radians(tilt_deg), np.radians(azimuth_deg)
    axis = np.stack([np.sin(t) * np.cos(a), np.sin(t) * np.sin(a), np.cos(t)], axis=1)
    tip = np.stack([np.linspace(-10, 10, len(t)), np.zeros(len(t)), np.full(len(t), z)], axis=1)
    return tip, axis


@pytest.fixture(scope="module")
def umc():
    return load_machine("umc750")


def test_preference_decides_the_branch_at_the_start(umc) -> None:
    tip, axis = tilt_path(np.full(5, 20.0), np.full(5, 30.0))
    b = umc.axis_names.index("B")
    plus = select(umc, tip, axis, tool_length=150.0, prefer=Preference("B", +1))
    minus = select(umc, tip, axis, tool_length=150.0, prefer=Preference("B", -1))
    assert np.all(plus.q[:, b] > 0)
    assert np.all(minus.q[:, b] < 0)
    for sel in (plus, minus):
        got_tip, got_axis = tip_and_axis_pin(umc, sel.q, 150.0)
        np.testing.assert_allclose(got_tip, tip, atol=1e-9)
        np.testing.assert_allclose(got_axis, axis, atol=1e-9)


def test_preference_yields_when_its_branch_runs_out_of_travel(umc) -> None:
    """B- is preferred, but the tilt grows to 60 deg where B- is beyond -35: starting on B+
    avoids a half-turn flip in the middle of the cut."""
    tip, axis = tilt_path(np.linspace(10, 60, 30), np.full(30, 0.0))
    sel = select(umc, tip, axis, tool_length=150.0, prefer=Preference("B", -1))
    b = umc.axis_names.index("B")
    assert np.all(sel.q[:, b] > 0)
    assert np.all(np.diff(sel.branch) == 0)


def test_travel_limits_are_never_exceeded(umc) -> None:
    tip, axis = tilt_path(np.linspace(0, 90, 40), np.linspace(0, 720, 40))
    sel = select(umc, tip, axis, tool_length=150.0)
    lo, hi = umc.lower - 1e-9, umc.upper + 1e-9
    assert np.all((sel.q >= lo) & (sel.q <= hi))


def test_continuous_axis_is_unwrapped_along_the_path(umc) -> None:
    """Three turns of the azimuth: C follows with small steps instead of jumping by 360."""
    az = np.linspace(0, 1080, 200)
    tip, axis = tilt_path(np.full(200, 30.0), az)
    sel = select(umc, tip, axis, tool_length=150.0)
    c = np.degrees(sel.q[:, umc.axis_names.index("C")])
    steps = np.abs(np.diff(c))
    assert steps.max() < 6.0
    assert abs(c[-1] - c[0]) == pytest.approx(1080.0, abs=1e-6)


def test_exact_pole_crossing_switches_branch_without_turning_c(umc) -> None:
    """A great circle through vertical: B changes sign (B travel allows -35) and C stands."""
    tilt = np.concatenate([np.linspace(20, 0, 11), np.linspace(2, 20, 10)])
    az = np.concatenate([np.full(11, 0.0), np.full(10, 180.0)])
    tip, axis = tilt_path(tilt, az)
    sel = select(umc, tip, axis, tool_length=150.0)
    c = np.degrees(sel.q[:, umc.axis_names.index("C")])
    assert sel.status[10] == IKStatus.POLE
    assert np.ptp(c) < 1e-9
    b = np.degrees(sel.q[:, umc.axis_names.index("B")])
    assert b[0] * b[-1] < 0


def test_pole_holds_the_previous_angle(umc) -> None:
    tip, axis = tilt_path(np.array([10.0, 0.0, 0.0, 0.0]), np.array([40.0, 0, 0, 0]))
    sel = select(umc, tip, axis, tool_length=150.0)
    c = sel.q[:, umc.axis_names.index("C")]
    assert np.all(sel.status[1:] == IKStatus.POLE)
    np.testing.assert_allclose(c[1:], c[0], atol=1e-12)


def test_unreachable_orientation_names_the_line(umc) -> None:
    tip, axis = tilt_path(np.array([10.0, 150.0]), np.array([0.0, 0.0]))
    with pytest.raises(UnreachableError, match=r"part\.cls:42: tool axis .* cannot be reached"):
        select(umc, tip, axis, tool_length=150.0, lines=np.array([41, 42]), source="part.cls")


def test_linear_travel_names_the_axis(umc) -> None:
    tip = np.array([[0.0, 0.0, 10.0], [5000.0, 0.0, 10.0]])
    axis = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 1.0]])
    with pytest.raises(UnreachableError, match=r"part\.cls:8: .*X would need"):
        select(umc, tip, axis, tool_length=150.0, lines=np.array([7, 8]), source="part.cls")


@pytest.mark.parametrize("text,axis,sign", [("B+", "B", 1), ("-c", "C", -1), ("A-", "A", -1)])
def test_preference_parse(text: str, axis: str, sign: int) -> None:
    assert Preference.parse(text) == Preference(axis, sign)


def test_preference_parse_rejects_garbage() -> None:
    with pytest.raises(ValueError, match="expected a preferred branch like B\\+"):
        Preference.parse("X+")


@settings(max_examples=25, deadline=None)
@given(
    name=st.sampled_from(["dmu50", "umc750", "dmu50-nutating", "gantry-ca", "monoblock"]),
    seed=st.integers(0, 2**31),
)
def test_selection_reproduces_reachable_paths(name: str, seed: int) -> None:
    """A random smooth joint path within travel: its poses are reached within travel, every
    selected point reproduces the pose, and the rotary motion is no larger than the path's."""
    m = load_machine(name)
    rng = np.random.default_rng(seed)
    lo = np.where(np.isfinite(m.lower), m.lower, -np.pi)
    hi = np.where(np.isfinite(m.upper), m.upper, np.pi)
    a, b = rng.uniform(lo + 0.25 * (hi - lo), hi - 0.25 * (hi - lo), (2, len(lo)))
    s = np.linspace(0, 1, 40)[:, None]
    q = a + s * (b - a)
    tip, axis = tip_and_axis(m, q, 100.0)
    sel = select(m, tip, axis, tool_length=100.0)
    assert np.all((sel.q >= m.lower - 1e-9) & (sel.q <= m.upper + 1e-9))
    got_tip, got_axis = tip_and_axis_pin(m, sel.q, 100.0)
    np.testing.assert_allclose(got_tip, tip, atol=1e-8)
    np.testing.assert_allclose(got_axis, axis, atol=1e-9)
    cols = list(m.rotary_columns)
    travel = np.abs(np.diff(sel.q[:, cols], axis=0)).sum()
    assert travel <= np.abs(np.diff(q[:, cols], axis=0)).sum() + np.pi + 1e-6


@pytest.mark.parametrize("scale", [1e-9, 1.0, 3.0, 2.0 * np.pi, 3.0 * np.pi, 50.0, 1e6])
def test_wrap_is_the_mod_formula_to_the_bit(scale: float) -> None:
    """The planner's wrap (turns added without branches, fmod skipped in range) gives what
    ``pi - mod(pi - a, 2 pi)`` gives, bit for bit: few angles, differences of wrapped angles
    (within range), anything else (fmod), the edges of the range, signed zeros and NaN."""
    rng = np.random.default_rng(int(scale * 1000) % 2**32)
    edges = np.array(
        [
            m
            for e in (-TWO_PI, 0.0, TWO_PI, 2 * TWO_PI, -np.pi, np.pi, 3 * np.pi)
            for m in (e, np.nextafter(e, np.inf), np.nextafter(e, -np.inf))
        ]
    )
    for a in (
        rng.uniform(-scale, scale, 5000),
        np.concatenate([rng.uniform(-scale, scale, 5000), np.pi - edges, edges, [0.0, -0.0]]),
        rng.uniform(-np.pi, np.pi, 5000) - rng.uniform(-np.pi, np.pi, 5000),
        np.array([scale, -scale, np.nan, -0.0]),
        np.concatenate([rng.uniform(-np.pi, np.pi, 100), [np.nan]]),
    ):
        want = np.pi - np.mod(np.pi - a, TWO_PI)
        got = _wrap(a)
        assert np.array_equal(np.isnan(got), np.isnan(want))
        keep = ~np.isnan(want)
        assert np.array_equal(got[keep].view(np.int64), want[keep].view(np.int64))
        out = a.copy()
        assert _wrap(out, out=out) is out
        assert np.array_equal(out[keep].view(np.int64), want[keep].view(np.int64))
