"""The feed timing's compiled tip path lengths (:mod:`urdfpost.verification._feeds_kernel`)
against the numpy path they stand for, bit for bit; the numpy path when they cannot run; and the
column-by-column forms of the feed measures (:func:`urdfpost.verification.feeds.limit_times`,
:func:`~urdfpost.verification.feeds.axis_lengths`, the fastest axis of
:func:`~urdfpost.verification.feeds.measure_feeds`) against the whole-array numpy they replace,
bit for bit too."""

from __future__ import annotations

import functools
from types import SimpleNamespace

import numpy as np
import pytest
from conftest import StandIn, Unloaded
from hypothesis import given, settings
from hypothesis import strategies as st
from jobs import rotary_sweep

import urdfpost.verification.feeds as feeds
from urdfpost import load_machine
from urdfpost.dialects import dialect_for
from urdfpost.machine import Machine
from urdfpost.posting.feeds import timed_program
from urdfpost.posting.options import PostOptions
from urdfpost.posting.whole import post
from urdfpost.readers import read_cl_text
from urdfpost.units import mm_per_unit
from urdfpost.verification.feeds import (
    _PER_MINUTE,
    _fastest,
    _tip_lengths_numpy,
    axis_lengths,
    limit_times,
    tip_lengths,
    tip_lengths_at,
)

MACHINES = ["dmu50", "monoblock", "gantry-ca", "dmu50-nutating", "umc750", "xyzac-trt"]


@functools.cache
def machine(name: str) -> Machine:
    return load_machine(name)


def _walk(m: Machine, rng: np.random.Generator, n: int, scale: float) -> np.ndarray:
    """Program rows of a random walk through the machine's joints (mm, rad), with rows
    repeated (blocks that do not move) and rows where only a rotary axis moves."""
    step = np.column_stack(
        [rng.uniform(-scale, scale, n) * (1.0 if a.rotary else 20.0) for a in m.axes]
    )
    step[rng.random(n) < 0.05] = 0.0
    still = rng.random(n) < 0.05
    step[np.ix_(still, list(m.linear_columns))] = 0.0
    return np.cumsum(step, axis=0) + np.array([0.0 if a.rotary else 10.0 for a in m.axes])


@pytest.fixture
def compiled(monkeypatch: pytest.MonkeyPatch) -> SimpleNamespace:
    """The kernels, used at any size in this test (skipped without numba)."""
    pytest.importorskip("numba")
    monkeypatch.setattr(feeds.KERNELS, "forced", True)
    module = feeds.KERNELS.load()
    assert module is not None
    return module


@pytest.mark.parametrize("name", MACHINES)
@pytest.mark.parametrize("tool_length", [0.0, 120.0])
def test_compiled_tip_lengths_are_numpy_s(
    name: str, tool_length: float, compiled: SimpleNamespace
) -> None:
    """On walks of every kind of machine, from micrometre steps to large turns: the same bits,
    taken at rows (the post's blocks, some rows skipped) or as pairs of rows."""
    m = machine(name)
    rng = np.random.default_rng(abs(hash((name, tool_length))) % 2**32)
    for scale in (1e-5, 0.002, 0.05, 0.5, 3.0):
        values = _walk(m, rng, 300, scale)
        start = np.flatnonzero(rng.random(len(values) - 1) < 0.9)
        q0, q1 = values[start], values[start + 1]
        want = _tip_lengths_numpy(m, q0, q1, tool_length)
        assert np.array_equal(tip_lengths_at(m, values, start, False, tool_length), want)
        assert np.array_equal(tip_lengths(m, q0, q1, False, tool_length), want)


@settings(max_examples=30, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    name=st.sampled_from(MACHINES),
    scale=st.sampled_from([1e-7, 1e-3, 0.3, 2.0, 7.0]),
    n=st.integers(2, 60),
)
def test_compiled_tip_lengths_are_numpy_s_anywhere(
    seed: int, name: str, scale: float, n: int
) -> None:
    """Likewise for walks of any length and step (the fixture cannot be used with hypothesis:
    the kernels are forced on by hand)."""
    pytest.importorskip("numba")
    m = machine(name)
    values = _walk(m, np.random.default_rng(seed), n, scale)
    start = np.arange(n - 1)
    want = _tip_lengths_numpy(m, values[:-1], values[1:], 100.0)
    before = feeds.KERNELS.forced
    feeds.KERNELS.forced = True
    try:
        got = tip_lengths_at(m, values, start, False, 100.0)
    finally:
        feeds.KERNELS.forced = before
    assert np.array_equal(got, want)


def test_tcp_lengths_are_chords(compiled: SimpleNamespace) -> None:
    """TCP programs: the chord of X, Y, Z (the kernel is not asked)."""
    m = machine("dmu50")
    values = _walk(m, np.random.default_rng(3), 50, 0.1)
    lin = list(m.linear_columns)
    want = np.linalg.norm(values[1:, lin] - values[:-1, lin], axis=1)
    assert np.array_equal(tip_lengths_at(m, values, np.arange(49), True, 100.0), want)


@pytest.mark.parametrize("controller", ["heidenhain", "fanuc"])
def test_timed_program_is_the_same_compiled(
    controller: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A post of large rotary moves, fast enough for the axes to cap it: the same F words and
    figures with the kernels as without."""
    pytest.importorskip("numba")
    m = machine("dmu50")
    job = read_cl_text(rotary_sweep(feed=6000.0, points=120), source="sweep.apt")
    result = post(job, m, PostOptions(controller=controller, tcp=False))
    program, spec = result.program, dialect_for(controller).spec
    mode = "per-block" if controller == "heidenhain" else "inverse-time"
    monkeypatch.setattr(feeds.KERNELS, "forced", False)
    want, want_figures = timed_program(program, m, mode, spec, program.tool_length)
    assert want_figures.capped_blocks
    monkeypatch.setattr(feeds.KERNELS, "forced", True)
    got, got_figures = timed_program(program, m, mode, spec, program.tool_length)
    assert got_figures == want_figures
    assert np.array_equal(got.move_table().feed, want.move_table().feed, equal_nan=True)


def test_tip_lengths_fall_back_to_numpy_when_the_kernel_fails(
    monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture, stand_in: StandIn
) -> None:
    """numba that cannot compile or cache the kernel here: a warning, once, and numpy's lengths
    (for the rest of the process too)."""
    m = machine("dmu50")
    values = _walk(m, np.random.default_rng(8), 40, 0.2)
    want = _tip_lengths_numpy(m, values[:-1], values[1:], 100.0)

    def broken(*args: object) -> None:
        raise RuntimeError("cannot cache function 'tip_lengths': no locator available")

    monkeypatch.setattr(feeds.KERNELS, "start", 1)
    stand_in(feeds.KERNELS, SimpleNamespace(tip_lengths=broken))
    with caplog.at_level("WARNING", logger="urdfpost.verification.feeds"):
        assert np.array_equal(tip_lengths_at(m, values, np.arange(39), False, 100.0), want)
        assert np.array_equal(tip_lengths(m, values[:-1], values[1:], False, 100.0), want)
    assert caplog.text.count("compiled tip lengths unavailable (cannot cache function") == 1
    assert feeds.KERNELS.failed


def test_without_numba_the_numpy_path_runs(
    monkeypatch: pytest.MonkeyPatch, unloaded: Unloaded
) -> None:
    """No numba (the kernels' module cannot be imported): numpy's lengths at any size."""
    import builtins

    m = machine("dmu50")
    values = _walk(m, np.random.default_rng(9), 40, 0.2)
    want = _tip_lengths_numpy(m, values[:-1], values[1:], 100.0)
    real_import = builtins.__import__

    def no_numba(name: str, *args: object, **kwargs: object) -> object:
        if name == "numba" or name.startswith("numba."):
            raise ImportError("No module named 'numba'")
        return real_import(name, *args, **kwargs)  # type: ignore[arg-type]

    unloaded(feeds.KERNELS)
    monkeypatch.setattr(feeds.KERNELS, "start", 1)
    monkeypatch.delitem(__import__("sys").modules, "urdfpost.verification._feeds_kernel", False)
    monkeypatch.setattr(builtins, "__import__", no_numba)
    assert np.array_equal(tip_lengths_at(m, values, np.arange(39), False, 100.0), want)
    assert feeds.KERNELS.module is None


def test_sizes_the_kernels_are_used_from(unloaded: Unloaded) -> None:
    """From COMPILED_FROM blocks, or a tenth of that once numba is imported here."""
    import sys

    unloaded(feeds.KERNELS)
    k = feeds.KERNELS
    assert k.wanted(k.start)
    assert k.warm_start is not None and k.warm_start < k.start
    assert k.wanted(k.warm_start) == ("numba" in sys.modules)
    assert not k.wanted(k.warm_start - 1)


# -- the column-by-column measures against the whole-array numpy they replace ----------------


def _limit_times_rows(machine: Machine, dq: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`limit_times` as it was written on whole rows."""
    velocity = np.array([a.velocity for a in machine.axes], dtype=float) * _PER_MINUTE
    finite = np.isfinite(velocity) & (velocity > 0.0)
    need = np.zeros_like(dq)
    need[:, finite] = np.abs(dq[:, finite]) / velocity[finite]
    axis = np.argmax(need, axis=1) if dq.shape[1] else np.zeros(len(dq), dtype=int)
    time = need[np.arange(len(dq)), axis] if dq.shape[1] else np.zeros(len(dq))
    return time, np.where(time > 0.0, axis, -1)


def _axis_lengths_rows(
    machine: Machine, q0: np.ndarray, q1: np.ndarray, rule: str, units: str
) -> np.ndarray:
    """:func:`axis_lengths` as it was written on whole rows."""
    lin, rot = list(machine.linear_columns), list(machine.rotary_columns)
    linear = np.linalg.norm(q1[:, lin] - q0[:, lin], axis=1) / mm_per_unit(units)
    rotary = np.degrees(np.linalg.norm(q1[:, rot] - q0[:, rot], axis=1))
    if rule == "combined":
        return np.hypot(linear, rotary)
    return np.where(linear > 0.0, linear, rotary)


def _fastest_rows(
    dq: np.ndarray, time: np.ndarray, velocity: np.ndarray, timed: np.ndarray
) -> tuple[int, int, float] | None:
    """The fastest axis as :func:`measure_feeds` took it on whole rows (None: not reported)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        share = np.where(timed[:, None], np.abs(dq) / time[:, None] / velocity, 0.0)
    share = np.nan_to_num(share, nan=0.0, posinf=np.inf)
    if timed.any() and share.size:
        row, col = divmod(int(np.argmax(share)), share.shape[1])
        if share[row, col] > 0.0:
            return row, col, float(share[row, col])
    return None


def _moves(rng: np.random.Generator, n: int, m: int) -> np.ndarray:
    """Axis travel with zeros, ties, repeated rows, NaN and infinities in places."""
    dq = rng.normal(size=(n, m)) * rng.choice([0.0, 1e-9, 1.0, 300.0], size=(n, m))
    if n:
        dq[rng.random(n) < 0.1] = dq[0]
    tie = rng.random(n) < 0.1  # two axes alike in a block
    dq[tie, -1] = -dq[tie, 0]
    odd = rng.random((n, m)) < 0.01
    dq[odd] = rng.choice([np.nan, np.inf, -np.inf], size=int(odd.sum()))
    return dq


@pytest.mark.parametrize("name", MACHINES)
@pytest.mark.parametrize("seed", range(4))
def test_column_measures_are_the_row_measures(name: str, seed: int) -> None:
    """limit_times, axis_lengths and the fastest axis, column by column: the same bits as on
    whole rows, ties, NaN and infinities included."""
    m = machine(name)
    rng = np.random.default_rng(seed)
    for n in (0, 1, 7, 2000):
        dq = _moves(rng, n, len(m.axes))
        time, axis = limit_times(m, dq)
        want_time, want_axis = _limit_times_rows(m, dq)
        assert np.array_equal(time, want_time, equal_nan=True)
        assert np.array_equal(axis, want_axis)
        q0 = rng.normal(size=(n, len(m.axes))) * 100.0
        q1 = q0 + dq
        for rule in ("combined", "linear-first"):
            for units in ("mm", "inch"):
                got = axis_lengths(m, q0, q1, rule, units)
                want = _axis_lengths_rows(m, q0, q1, rule, units)
                assert np.array_equal(got, want, equal_nan=True)
        velocity = np.array([a.velocity for a in m.axes], dtype=float) * _PER_MINUTE
        block_time = np.abs(rng.normal(size=n)) * rng.choice([0.0, 1e-6, 1.0], size=n)
        timed = rng.random(n) < 0.9
        want_fast = _fastest_rows(dq, block_time, velocity, timed)
        travel = [np.abs(dq[:, j]) for j in range(dq.shape[1])]
        row, col, top = _fastest(travel, block_time, velocity, timed)
        assert (None if not top > 0.0 else (row, col, top)) == want_fast


def test_fastest_axis_on_a_tie_is_the_first_in_row_order() -> None:
    """Two blocks at the same largest share: the first block, and in it the first axis."""
    travel = [np.array([1.0, 2.0, 2.0]), np.array([2.0, 1.0, 2.0])]
    time, velocity = np.ones(3), np.ones(2)
    assert _fastest(travel, time, velocity, np.ones(3, dtype=bool)) == (0, 1, 2.0)
    assert _fastest(travel, time, velocity, np.array([False, True, True])) == (1, 0, 2.0)
