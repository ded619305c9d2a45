"""The orientation floor of a check (``Check.orientation_floor``) and the streamed post's levels
(``posting.check.PieceLevels``): blocks below what the program reaches elsewhere are not refined,
and what verification reports stays that of refining them.

A cone-bent piece is checked against the path the cone intended, which the program follows to
micro-radians: the largest deviation sampled is tiny, and so most blocks' bounds reach it and
were refined, in every such piece of a streamed post.
"""

from __future__ import annotations

import logging
import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from jobs import write_hemisphere

from urdfpost import load_machine
from urdfpost.dialects import dialect_for
from urdfpost.posting import check as check_module
from urdfpost.posting.options import PostOptions, resolve
from urdfpost.posting.piece import post_piece
from urdfpost.posting.stream import post_stream
from urdfpost.program import Program
from urdfpost.readers import read_cl
from urdfpost.toolpath import Toolpath, toolpath_pieces
from urdfpost.verification import Check, Verification, verify_checks

_REFINED = re.compile(r"verify: \d+ blocks, tip refined in (\d+), orientation in (\d+)")


@pytest.fixture(scope="module")
def raster(tmp_path_factory: pytest.TempPathFactory) -> Toolpath:
    """The benchmark's hemisphere raster (passes over and beside the pole), 6000 points."""
    return read_cl(write_hemisphere(6000, tmp_path_factory.mktemp("floor") / "hemisphere.apt"))


@pytest.fixture(scope="module")
def bent(raster: Toolpath) -> tuple[Program, float, Check]:
    """The cone's program of the raster, read back, its tool length (mm) and the check of it
    against the path the cone intended."""
    m = load_machine("dmu50")
    job = resolve(PostOptions(controller="heidenhain", tcp=False), m, raster.units)
    posted = post_piece(raster, job)
    assert posted.target.intended is not None, "the cone bent nothing"
    dialect = dialect_for("heidenhain")
    readback = dialect.read(dialect.write(posted.program))
    return readback, posted.target.tool_length, Check(posted.target.intended, job.tol)


def refined(caplog: pytest.LogCaptureFixture) -> tuple[int, int]:
    """The blocks refined for the tip and the orientation, summed over the verifications
    logged since the last call."""
    found = [_REFINED.search(r.getMessage()) for r in caplog.records]
    caplog.clear()
    counts = [(int(x[1]), int(x[2])) for x in found if x is not None]
    assert counts, "no verification logged its refining"
    return sum(c[0] for c in counts), sum(c[1] for c in counts)


def checked(
    bent: tuple[Program, float, Check], caplog: pytest.LogCaptureFixture, **change: object
) -> tuple[Verification, tuple[int, int]]:
    program, length, check = bent
    with caplog.at_level(logging.DEBUG, logger="urdfpost"):
        (v,) = verify_checks(program, load_machine("dmu50"), [replace(check, **change)], length)
    return v, refined(caplog)


def test_a_floor_below_the_maximum_changes_nothing(
    bent: tuple[Program, float, Check], caplog: pytest.LogCaptureFixture
) -> None:
    exact, (_, many) = checked(bent, caplog)
    assert exact.ok and many > 0
    reached = float(np.radians(exact.max_orientation_deviation_deg))
    at, (_, same) = checked(bent, caplog, orientation_floor=reached * (1 - 1e-9))
    assert at == exact
    assert same == many  # the blocks that may reach the maximum: refined all the same


def test_a_floor_above_the_maximum_reports_no_more_and_refines_less(
    bent: tuple[Program, float, Check], caplog: pytest.LogCaptureFixture
) -> None:
    exact, (_, many) = checked(bent, caplog)
    reached = float(np.radians(exact.max_orientation_deviation_deg))
    above, (_, fewer) = checked(bent, caplog, orientation_floor=20 * reached)
    assert fewer < many
    assert above.max_orientation_deviation_deg <= exact.max_orientation_deviation_deg
    # what it does not touch: the tip, the verdict
    assert above.max_tip_deviation == exact.max_tip_deviation
    assert above.ok == exact.ok
    assert above.mean_tip_deviation == exact.mean_tip_deviation


def test_a_floor_never_hides_a_miss(
    bent: tuple[Program, float, Check], caplog: pytest.LogCaptureFixture
) -> None:
    """Below a tolerance the program misses, the floor is the tolerance: the blocks that miss
    it are refined, and the failed verification is the one refined everywhere."""
    check = bent[2]
    exact, _ = checked(bent, caplog)
    reached = float(np.radians(exact.max_orientation_deviation_deg))
    tight = replace(check.tol, orientation=0.5 * reached)
    failed, _ = checked(bent, caplog, tol=tight)
    assert not failed.ok
    floored, _ = checked(bent, caplog, tol=tight, orientation_floor=100 * reached)
    assert floored == failed


def test_streamed_levels_keep_every_figure(
    tmp_path: Path,
    raster: Toolpath,
    caplog: pytest.LogCaptureFixture,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A streamed post refines the later pieces' blocks only up to what the earlier pieces
    reached: its merged verifications, against the CL data and the intended path, are those
    of refining every piece as a whole post would, and it refines fewer blocks."""

    def post(name: str) -> tuple[object, tuple[int, int]]:
        out = tmp_path / name
        with caplog.at_level(logging.DEBUG, logger="urdfpost"):
            result = post_stream(
                toolpath_pieces(raster, 997),
                load_machine("dmu50"),
                out,
                PostOptions(controller="heidenhain", tcp=False),
                piece_points=700,
                lookahead=200,
                parallel=False,
            )
        return result, refined(caplog)

    levelled, (_, fewer) = post("levelled.nc")
    monkeypatch.setattr(check_module.PieceLevels, "floors", lambda *_: (0.0, 0.0))
    every, (_, many) = post("every.nc")
    assert (tmp_path / "levelled.nc").read_bytes() == (tmp_path / "every.nc").read_bytes()
    assert levelled.report.as_json()["streamed"]["pieces"] > 3
    assert levelled.verification == every.verification
    report = levelled.report.as_json()
    assert report["strategy"]["intended_path_check"], "no piece bent"
    assert report == every.report.as_json()
    assert fewer < many
