"""The rate-based singularity detector (issue 18): spans where a rotary axis would run faster
than its velocity limit at the programmed feed; the geometric detector as the default and the
fallback; the ``--detector`` option of ``post`` and ``compare``."""

from __future__ import annotations

import logging
from dataclasses import replace

import numpy as np
import pytest

from urdfpost.analysis.testpaths import great_circle_sweep, hemisphere_raster, to_apt
from urdfpost.cli import main
from urdfpost.errors import UrdfpostError
from urdfpost.machine import load_machine
from urdfpost.planning.singularity import (
    DEFAULT_DETECTOR,
    DetectorTolerances,
    demanded_rates,
    detect,
    detector_of,
    step_times,
    with_detector,
)
from urdfpost.planning.strategies import Problem, exact_selection
from urdfpost.posting.options import PostOptions, resolve
from urdfpost.tolerances import Tolerances
from urdfpost.toolpath import Motion, Toolpath

RADIUS, FEED = 50.0, 2000.0  # mm, mm/min: the research notes' hemisphere (section 7)


def exact_q(machine, tp: Toolpath) -> np.ndarray:
    """The exact joint path the strategies detect spans on."""
    return exact_selection(Problem(machine, tp, tool_length=100.0, tol=Tolerances()), tp).q


def pass_at(y0: float, feed: float = FEED) -> Toolpath:
    """One hemisphere raster pass at offset ``y0`` (mm) from the apex."""
    return hemisphere_raster(radius=RADIUS, offsets=(y0,), feed=feed)


def test_demanded_rate_of_a_hemisphere_pass_is_feed_over_offset() -> None:
    # closed form: C turns at F / y0 rad/s at the apex (F in mm/s); 5 mm: 382 deg/s
    m = load_machine("dmu50")
    tp = pass_at(5.0)
    rates = demanded_rates(m, tp, exact_q(m, tp))
    peak = np.degrees(np.nanmax(rates[:, 0]))
    assert peak == pytest.approx(np.degrees(FEED / 60.0 / 5.0), rel=0.01)
    assert peak > np.degrees(m.rotary[0].velocity)  # twice the DMU 50's 180 deg/s


def test_step_times_are_length_over_feed_and_nan_without_feed() -> None:
    tip = np.array([[0.0, 0, 0], [1.0, 0, 0], [1.0, 0, 0], [1.0, 3.0, 0]])
    axis = np.tile([0.0, 0, 1], (4, 1))
    tp = Toolpath.from_points(tip, axis, feed=np.array([np.nan, 600.0, 600.0, np.nan]))
    dt = step_times(tp)
    assert dt[0] == pytest.approx(0.1)  # 1 mm at 10 mm/s
    assert dt[1] == 0.0  # the tip stands still: no time from the feed
    assert np.isnan(dt[2])


def test_the_5mm_pass_the_geometric_detector_misses_is_a_rate_span() -> None:
    """Issue 18: sin 2 deg is blind to the feed; 381 deg/s of C against 180 deg/s."""
    m = load_machine("dmu50")
    tp = pass_at(5.0)
    q = exact_q(m, tp)
    assert detect(m, tp, q, Tolerances()) == []
    spans = detect(m, tp, q, with_detector(Tolerances(), "rate"))
    assert len(spans) == 1
    sp = spans[0]
    assert sp.kind == "rate"
    apex = int(np.argmin(np.abs(tp.tip[:, 0])))
    assert sp.first < apex < sp.last
    # the span is wide enough for its net turn at the limit in the time the feed gives it
    t = np.concatenate([[0.0], np.cumsum(step_times(tp))])
    col = m.rotary_columns[0]
    turn = abs(q[sp.last, col] - q[sp.first, col])
    assert turn <= m.rotary[0].velocity * (t[sp.last] - t[sp.first])
    # and no wider than it needs to be (plus the margin on each side)
    inner = sp.first + 1 + Tolerances().singular_margin, sp.last - 1 - Tolerances().singular_margin
    turn_in = abs(q[inner[1], col] - q[inner[0], col])
    assert turn_in > m.rotary[0].velocity * (t[inner[1]] - t[inner[0]])


def test_a_slower_feed_needs_no_rate_span() -> None:
    # 800 mm/min at 5 mm: 153 deg/s, within the limit
    m = load_machine("dmu50")
    tp = pass_at(5.0, feed=800.0)
    rates = demanded_rates(m, tp, exact_q(m, tp))
    assert np.nanmax(rates[:, 0]) < m.rotary[0].velocity
    assert detect(m, tp, exact_q(m, tp), with_detector(Tolerances(), "rate")) == []


def test_rate_share_scales_the_limit() -> None:
    m = load_machine("dmu50")
    tp = pass_at(5.0, feed=800.0)
    tol = replace(with_detector(Tolerances(), "rate"), rate_share=0.5)  # 90 deg/s
    assert [s.kind for s in detect(m, tp, exact_q(m, tp), tol)] == ["rate"]


def test_a_pole_crossing_is_a_pole_span_for_both_detectors() -> None:
    m = load_machine("dmu50")
    tp = great_circle_sweep(0.1)
    q = exact_q(m, tp)
    for detector in ("geometric", "rate"):
        spans = detect(m, tp, q, with_detector(Tolerances(), detector))
        assert [s.kind for s in spans] == ["pole"], detector


def test_a_cut_without_feed_falls_back_to_geometric_with_a_warning(caplog) -> None:
    m = load_machine("dmu50")
    tp = pass_at(0.5)
    feed = tp.feed.copy()
    feed[tp.motion == Motion.FEED] = np.nan  # no feed programmed
    tp = replace(tp, feed=feed)
    q = exact_q(m, tp)
    with caplog.at_level(logging.WARNING, logger="urdfpost.planning.singularity"):
        spans = detect(m, tp, q, with_detector(Tolerances(), "rate"))
    assert spans == detect(m, tp, q, Tolerances())
    assert spans  # the 0.5 mm pass is geometrically singular
    (record,) = caplog.records
    assert "no feed" in record.message and "geometric" in record.message
    assert f"CL line {int(tp.line[1])}" in record.message


def test_a_machine_without_velocity_limits_falls_back_with_a_warning(caplog) -> None:
    m = load_machine("dmu50")
    unlimited = replace(m, axes=tuple(replace(a, velocity=np.inf) for a in m.axes))
    assert not np.isfinite([a.velocity for a in unlimited.rotary]).any()
    tp = pass_at(0.5)
    q = exact_q(m, tp)
    with caplog.at_level(logging.WARNING, logger="urdfpost.planning.singularity"):
        spans = detect(unlimited, tp, q, with_detector(Tolerances(), "rate"))
    assert spans == detect(unlimited, tp, q, Tolerances())
    assert any("no velocity limit" in r.message for r in caplog.records)


def test_detector_tolerances_keep_every_threshold_and_check_the_name() -> None:
    tol = Tolerances.for_units("inch")
    rate = with_detector(tol, "rate")
    assert isinstance(rate, DetectorTolerances) and rate.tip == tol.tip
    assert detector_of(rate) == "rate" and detector_of(tol) == DEFAULT_DETECTOR == "geometric"
    assert with_detector(rate, "geometric").detector == "geometric"
    with pytest.raises(ValueError, match="unknown singularity detector 'fast'"):
        with_detector(tol, "fast")


def test_resolve_carries_the_detector_into_the_job() -> None:
    m = load_machine("dmu50")
    assert detector_of(resolve(PostOptions(), m, "mm").tol) == "geometric"
    assert detector_of(resolve(PostOptions(detector="rate"), m, "mm").tol) == "rate"
    with pytest.raises(UrdfpostError, match="unknown singularity detector 'x'; expected one of"):
        resolve(PostOptions(detector="x"), m, "mm")


@pytest.fixture
def five_mm_pass(tmp_path):
    path = tmp_path / "pass5.apt"
    path.write_text(to_apt(pass_at(5.0)))
    return path


def test_cli_compare_with_the_rate_detector_shows_the_rate_span(five_mm_pass, capsys) -> None:
    args = ["compare", str(five_mm_pass), "-m", "dmu50", "--strategies", "none,cone"]
    main(args)
    assert "span rate" not in capsys.readouterr().out
    main([*args, "--detector", "rate"])
    out = capsys.readouterr().out
    assert "1 singular spans" in out and "span rate" in out


def test_cli_post_takes_the_detector(five_mm_pass, tmp_path, capsys) -> None:
    out = tmp_path / "p.h"
    args = ["--strategy", "linear", "--detector", "rate", "-o", str(out)]
    code = main(["post", str(five_mm_pass), "-m", "dmu50", *args])
    assert code == 0 and out.is_file()
    assert "1 singular spans" in capsys.readouterr().out


def test_cli_rejects_an_unknown_detector(five_mm_pass, capsys) -> None:
    with pytest.raises(SystemExit) as e:
        main(["post", str(five_mm_pass), "-m", "dmu50", "--detector", "fast"])
    assert e.value.code == 2
    assert "invalid choice: 'fast'" in capsys.readouterr().err
