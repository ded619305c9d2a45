"""Shipped singular test paths: their closed-form facts, the APT round trip, and that they post."""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest

from urdfpost.analysis.testpaths import (
    PATHS,
    great_circle_sweep,
    hemisphere_raster,
    nutating_edge,
    to_apt,
)
from urdfpost.geometry import slerp
from urdfpost.machine import Machine, load_machine
from urdfpost.posting.options import PostOptions
from urdfpost.posting.whole import post
from urdfpost.readers import read_cl_text
from urdfpost.toolpath import Event, Motion, Toolpath

Z = np.array([0.0, 0.0, 1.0])


@functools.cache
def machine(name: str) -> Machine:
    return load_machine(name)


@functools.cache
def shipped(name: str) -> Toolpath:
    return PATHS[name]()


def passes(tp: Toolpath) -> list[np.ndarray]:
    """Indices of the feed points of each pass (runs between rapids)."""
    feed = np.flatnonzero(tp.motion == Motion.FEED)
    return np.split(feed, np.flatnonzero(np.diff(feed) > 1) + 1)


def angle_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle between unit vectors (rows), degrees."""
    return np.degrees(np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1), np.sum(a * b, axis=-1)))


# -- layout -----------------------------------------------------------------------------------


@pytest.mark.parametrize("name", sorted(PATHS))
def test_layout_tool_cutter_and_rapid_separated_passes(name: str) -> None:
    tp = shipped(name)
    assert tp.units == "mm" and tp.source.startswith("<") and tp.multiaxis
    kinds = [e.kind for e in tp.events]
    assert kinds[:3] == ["partno", "cutter", "tool"]
    tool = tp.events[2]
    assert tool.index == 0 and tool.data["number"] == 1
    cutter = tp.events[1].data
    assert cutter["corner_radius"] == pytest.approx(cutter["diameter"] / 2)  # ball end
    np.testing.assert_allclose(np.linalg.norm(tp.axis, axis=1), 1.0, atol=1e-12)
    for run in passes(tp):
        # a rapid before and after every pass; the first feed point is the plunge
        assert tp.motion[run[0] - 1] == Motion.RAPID and tp.motion[run[-1] + 1] == Motion.RAPID
        assert np.all(np.isfinite(tp.feed[run])) and np.all(tp.feed[run] > 0)
    assert np.all(np.isnan(tp.feed[tp.motion == Motion.RAPID]))
    assert np.all(np.diff(tp.line) > 0)


# -- closed-form facts ------------------------------------------------------------------------


def test_hemisphere_pole_distance_is_arcsin_of_offset() -> None:
    radius, offsets, center = 50.0, (0.0, 0.5, 2.0, 5.0), np.array([3.0, -2.0, 60.0])
    tp = hemisphere_raster(radius=radius, offsets=offsets, step=0.5, center=center)
    runs = passes(tp)
    assert len(runs) == len(offsets)
    for run, y0 in zip(runs, offsets, strict=True):
        tip, axis = tp.tip[run], tp.axis[run]
        np.testing.assert_allclose(tip[:, 1] - center[1], y0, atol=1e-12)
        np.testing.assert_allclose(np.linalg.norm(tip - center, axis=1), radius, rtol=1e-12)
        np.testing.assert_allclose(axis, (tip - center) / radius, atol=1e-12)  # surface normal
        tilt = angle_deg(axis, Z)
        assert tilt.min() == pytest.approx(math.degrees(math.asin(y0 / radius)), abs=1e-9)
        assert tilt.max() <= 60.0 + 1e-9
        assert tilt.max() > 58.0  # the x range is used up to the tilt limit
        np.testing.assert_allclose(np.abs(np.diff(tip[:, 0])), 0.5, atol=1e-12)
    # passes alternate direction; the y0 = 0 pass has a CL point exactly on the pole
    assert tp.tip[runs[0][1], 0] < 0 < tp.tip[runs[1][1], 0]
    assert np.any(np.all(tp.axis[runs[0]] == Z, axis=1))


def test_hemisphere_rejects_an_offset_beyond_the_tilt_limit() -> None:
    with pytest.raises(ValueError, match=r"expected offsets within 43.3\d* mm"):
        hemisphere_raster(offsets=(0.0, 45.0))


@pytest.mark.parametrize("offset", [0.0, 0.1, 1.0, 5.0])
def test_great_circle_sweep_passes_the_pole_at_its_offset(offset: float) -> None:
    half = 10.0
    tp = great_circle_sweep(offset, half_angle_deg=half, points=41, length=40.0)
    (run,) = passes(tp)
    axis = tp.axis[run]  # the feed points: the plunge ends on the first one
    assert len(axis) == 41
    # a great circle: every axis lies in one plane through the origin
    normal = np.cross(axis[0], axis[-1])
    np.testing.assert_allclose(axis @ (normal / np.linalg.norm(normal)), 0.0, atol=1e-12)
    # its closest approach to +Z, sampled densely between the points, is the offset
    t = np.tile(np.linspace(0.0, 1.0, 201), (len(axis) - 1, 1))
    dense = slerp(axis[:-1], axis[1:], t).reshape(-1, 3)
    assert angle_deg(dense, Z).min() == pytest.approx(offset, abs=1e-9)
    assert angle_deg(axis[20], Z) == pytest.approx(offset, abs=1e-9)
    h, o = math.radians(half), math.radians(offset)
    end_tilt = math.degrees(math.acos(math.cos(h) * math.cos(o)))
    np.testing.assert_allclose(angle_deg(axis[[0, -1]], Z), end_tilt, atol=1e-9)
    # the tip runs on a straight line of the given length at even spacing
    tip = tp.tip[run]
    assert np.linalg.norm(tip[-1] - tip[0]) == pytest.approx(40.0)
    np.testing.assert_allclose(np.linalg.norm(np.diff(tip, axis=0), axis=1), 1.0)


def test_nutating_edge_reaches_the_tilt_limit_and_returns() -> None:
    tp = nutating_edge(max_tilt_deg=90.0, points=61, min_tilt_deg=30.0, azimuth_span_deg=60.0)
    (run,) = passes(tp)
    tilt = angle_deg(tp.axis[run], Z)
    assert tilt.max() == pytest.approx(90.0, abs=1e-12)
    assert tilt[0] == pytest.approx(30.0) and tilt[-1] == pytest.approx(30.0)
    peak = int(np.argmax(tilt))
    assert np.all(np.diff(tilt[1 : peak + 1]) > 0) and np.all(np.diff(tilt[peak:]) < 0)
    azimuth = np.degrees(np.arctan2(tp.axis[run, 1], tp.axis[run, 0]))
    assert np.all(np.diff(azimuth) > 0) and azimuth[-1] - azimuth[0] == pytest.approx(60.0)
    assert nutating_edge(max_tilt_deg=80.0).axis[:, 2].min() == pytest.approx(
        math.cos(math.radians(80.0))
    )


# -- APT ---------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", sorted(PATHS))
def test_to_apt_reads_back_to_the_same_toolpath(name: str) -> None:
    tp = shipped(name)
    text = to_apt(tp)
    back = read_cl_text(text, source=tp.source)
    np.testing.assert_allclose(back.tip, tp.tip, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(back.axis, tp.axis, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(back.feed, tp.feed)  # NaN for rapids on both sides
    np.testing.assert_array_equal(back.motion, tp.motion)
    np.testing.assert_array_equal(back.line, tp.line)
    assert back.events == tp.events
    assert back.units == "mm" and back.warnings == () and back.multiaxis
    lines = text.splitlines()
    assert lines[0].startswith("PARTNO ") and lines[-1] == "FINI"
    assert all(lines[k - 1].startswith("GOTO/") for k in tp.line)


def test_to_apt_says_which_event_it_cannot_write() -> None:
    tp = great_circle_sweep(1.0)
    odd = Toolpath(
        tip=tp.tip,
        axis=tp.axis,
        feed=tp.feed,
        motion=tp.motion,
        line=tp.line,
        events=(*tp.events, Event(3, "coolant", 99, {"mode": "flood"})),
    )
    with pytest.raises(ValueError, match="got 'coolant' \\(line 99\\)"):
        to_apt(odd)


# -- every shipped path posts -----------------------------------------------------------------

POST_CASES = [
    (path, name)
    for path in ("hemisphere", "sweep-0", "sweep-0.1", "sweep-1", "sweep-5")
    for name in ("dmu50", "gantry-ca", "monoblock")
] + [("nutating-edge", "dmu50-nutating")]


@pytest.mark.parametrize("tcp", [True, False], ids=["tcp", "machine"])
@pytest.mark.parametrize(("path", "name"), POST_CASES)
def test_shipped_paths_post_and_verify(path: str, name: str, tcp: bool) -> None:
    tp = shipped(path)
    result = post(tp, machine(name), PostOptions(tcp=tcp))  # the default strategy
    check = result.verification
    assert check.ok and check.reached == len(tp)


def test_nutating_edge_runs_to_b_180_on_the_nutating_table() -> None:
    tp = shipped("nutating-edge")
    result = post(tp, machine("dmu50-nutating"), PostOptions(tcp=True, strategy="none"))
    b = [m.position[result.program.axes.index("B")] for m in result.program.moves()]
    assert max(b) == pytest.approx(180.0, abs=1e-3)
