"""The compiled first pass of verification's block deviation
(:mod:`urdfpost.verification._deviation_kernel`) against the numpy path it stands for: per
sample, per block (maxima, the samples they are at, the bounds), and through whole
verifications of posted programs, good and damaged; and the numpy path when it cannot run."""

from __future__ import annotations

import functools
import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import urdfpost.verification.measure as measure
from urdfpost import load_machine
from urdfpost.dialects import dialect_for
from urdfpost.geometry import chunks
from urdfpost.kinematics.forward import tip_and_axis
from urdfpost.linearize import RowPoses
from urdfpost.machine import Machine
from urdfpost.posting.options import PostOptions
from urdfpost.posting.whole import post
from urdfpost.readers import read_cl
from urdfpost.tolerances import Tolerances
from urdfpost.verification import verify
from urdfpost.verification.feeds import FeedRules, tip_lengths
from urdfpost.verification.match import _row_poses
from urdfpost.verification.measure import _Blocks, _Polyline

pytest.importorskip("numba")

from urdfpost.verification._deviation_kernel import AGREE

DOME = Path(__file__).resolve().parents[1] / "examples" / "dome.apt"
MACHINES = ["dmu50", "monoblock", "gantry-ca", "dmu50-nutating", "umc750"]
T = np.linspace(0.0, 1.0, measure._SAMPLES + 2)


@functools.cache
def machine(name: str) -> Machine:
    return load_machine(name)


def _feed(
    m: Machine, rng: np.random.Generator, n: int, scale: float, tcp: bool, pivot: float
) -> _Blocks:
    """Blocks of a random walk through the machine's joints, compared with CL points near its
    rows: most with one CL segment, some with a few, some with a long span (more than
    ``_LONG`` segments: left to numpy), some with their projection outside the segment, a few
    not compared (``valid``), some CL segments of no length or no turn."""
    step = np.column_stack(
        [rng.uniform(-scale, scale, n) * (1.0 if a.rotary else 20.0) for a in m.axes]
    )
    q = np.cumsum(step, axis=0) + np.array([0.0 if a.rotary else 10.0 for a in m.axes])
    tip, axis = tip_and_axis(m, q, 100.0)
    cl_axis = axis + rng.normal(0.0, 0.2 * scale, axis.shape)
    cl_axis[rng.random(n) < 0.1] = axis[0]  # runs of one orientation: arcs of no angle
    cl_axis /= np.linalg.norm(cl_axis, axis=1, keepdims=True)
    along = np.gradient(tip, axis=0) * rng.uniform(-0.3, 0.3, (n, 1))
    cl_tip = tip + along + rng.normal(0.0, 0.01, tip.shape) + pivot * axis
    repeat = np.flatnonzero(rng.random(n) < 0.05)[1:]
    cl_tip[repeat] = cl_tip[repeat - 1]  # segments of no length
    values = q.copy()
    if tcp:
        values[:, list(m.linear_columns)] = tip
    blocks = n - 1
    ja = np.arange(blocks)
    span = rng.choice([1, 2, 4, measure._LONG + 5], size=blocks, p=[0.8, 0.1, 0.07, 0.03])
    span[rng.random(blocks) < 0.05] = 0  # a block within one CL point
    jb = np.minimum(ja + span, n - 1)
    return _Blocks(
        machine=m,
        values=values,
        rows=_row_poses(m, values, tcp, 100.0, pivot),
        start=np.arange(blocks),
        ja=ja,
        jb=jb,
        polyline=_Polyline.of(cl_tip, cl_axis),
        tcp=tcp,
        tool_length=100.0,
        pivot=pivot,
        window=0.01,
        valid=rng.random(blocks) > 0.05,
    )


def _numpy_pass(
    feed: _Blocks, part: slice
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The numpy path's first pass over the blocks of ``part`` (as ``_block_deviation`` runs
    it): squared distances and chords per sample, bounds per block."""
    blocks = np.arange(part.start, part.stop)
    first: list = []
    dist2, chord2 = feed.errors(blocks, T, first)
    assert feed.valid is not None
    valid = feed.valid[part]
    dist2[:, ~valid] = 0.0
    chord2[:, ~valid] = 0.0
    tip_bound, chord_bound = feed.bounds(blocks, dist2, chord2, first[0], float(T[1] - T[0]))
    tip_bound[~valid] = -np.inf
    chord_bound[~valid] = -np.inf
    return dist2, chord2, tip_bound, chord_bound


def _agree(a: np.ndarray, b: np.ndarray) -> None:
    """Within :data:`AGREE`, relative to the larger and absolute; infinities alike."""
    assert np.array_equal(np.isinf(a), np.isinf(b))
    finite = np.isfinite(a)
    a, b = a[finite], b[finite]
    slack = AGREE * np.maximum(1.0, np.maximum(np.abs(a), np.abs(b)))
    assert np.all(np.abs(a - b) <= slack), float(np.max(np.abs(a - b) - slack))


def _compare(feed: _Blocks) -> None:
    """The compiled pass against the numpy pass, chunk by chunk, on every count it reports."""
    kernels = measure._kernel()
    assert kernels is not None
    kernel = kernels.block
    inputs = measure._KernelInputs.of(feed)
    assert inputs is not None
    for part in [*chunks(len(feed.start), 7 * len(T)), slice(0, len(feed.start))]:
        dist2, best, worst, bound, length = measure._first_pass_compiled(
            kernel, inputs, feed, part, T
        )
        want_dist2, want_chord2, tip_bound, chord_bound = _numpy_pass(feed, part)
        _agree(dist2, want_dist2)
        # the same operations on the same cosines and sines: the same numbers
        assert np.array_equal(dist2, want_dist2)
        cols = np.arange(part.stop - part.start)
        for i, want in enumerate((want_dist2, want_chord2)):
            _agree(best[i], want.max(axis=0))
            # the sample named is a largest one (ties may go either way within AGREE)
            _agree(want[worst[i], cols], want.max(axis=0))
        _agree(bound[0], tip_bound)
        _agree(bound[1], chord_bound)
        if not feed.tcp:  # the tip's path through the samples of every block, as the feeds'
            rows = feed.start[part]
            q0, q1 = feed.values[rows], feed.values[rows + 1]
            want = tip_lengths(feed.machine, q0, q1, False, feed.tool_length)
            assert np.array_equal(length, want)


@pytest.mark.parametrize("name", MACHINES)
@pytest.mark.parametrize("tcp", [False, True])
@pytest.mark.parametrize("pivot", [0.0, 3.0])
def test_compiled_pass_is_the_numpy_pass(name: str, tcp: bool, pivot: float) -> None:
    """Per sample and per block, on generated blocks of every kind of machine: the squared
    tip distances and the largest chords within AGREE of numpy's, the same samples named
    worst, the same bounds."""
    m = machine(name)
    rng = np.random.default_rng(hash((name, tcp, pivot)) % 2**32)
    for scale in (0.002, 0.05, 0.5):
        _compare(_feed(m, rng, 80, scale, tcp, pivot))


@settings(max_examples=25, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    name=st.sampled_from(MACHINES),
    tcp=st.booleans(),
    pivot=st.sampled_from([0.0, 3.0, -2.0]),
    scale=st.sampled_from([1e-4, 0.01, 0.3, 1.5]),
    squeeze=st.sampled_from([1.0, 1e-4]),
)
def test_compiled_pass_is_the_numpy_pass_anywhere(
    seed: int, name: str, tcp: bool, pivot: float, scale: float, squeeze: float
) -> None:
    """Likewise for random walks of any size, CL points drawn together to micrometre segments
    (``squeeze``: the window wider than the segments)."""
    feed = _feed(machine(name), np.random.default_rng(seed), 40, scale, tcp, pivot)
    (px, py, pz), axes = feed.polyline.tip, feed.polyline.axis
    tips = np.column_stack([px, py, pz])
    tips = tips[0] + squeeze * (tips - tips[0])
    _compare(replace(feed, polyline=_Polyline.of(tips, np.column_stack(axes))))


@pytest.mark.parametrize("name", MACHINES)
@pytest.mark.parametrize("pivot", [0.0, 3.0])
def test_compiled_rows_are_the_numpy_rows(
    name: str, pivot: float, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The deviation at the program rows themselves (one sample each, spans of every length,
    long ones left to numpy): within AGREE of numpy's."""
    rng = np.random.default_rng(5)
    for scale in (0.002, 0.05, 0.5):
        feed = _feed(machine(name), rng, 120, scale, False, pivot)
        rows = feed.rows.take(slice(0, len(feed.start)))
        args = (rows, feed.polyline, feed.ja, feed.jb, feed.window)
        monkeypatch.setattr(measure, "COMPILED_FROM", 10**12)
        want = measure._row_deviation(*args)
        monkeypatch.setattr(measure, "COMPILED_FROM", 1)
        got = measure._row_deviation(*args)
        for g, w in zip(got, want, strict=True):
            _agree(g, w)
        assert np.array_equal(got[0], want[0])  # the squared distances bit for bit


@pytest.mark.parametrize("name", MACHINES)
@pytest.mark.parametrize("tcp", [False, True])
def test_compiled_chords_per_sample(name: str, tcp: bool, monkeypatch: pytest.MonkeyPatch) -> None:
    """Every sample's squared distance and chord: the points and axes the numpy path measured
    along the blocks, through the kernel's span loop one by one (``point_deviation``), within
    AGREE of numpy's (the distances bit for bit)."""
    feed = _feed(machine(name), np.random.default_rng(9), 150, 0.05, tcp, 3.0)
    seen: list = []
    numpy_span = measure._span_deviation

    def spy(*args: object, **kwargs: object) -> tuple[np.ndarray, np.ndarray]:
        out = numpy_span(*args, **kwargs)  # type: ignore[arg-type]
        seen.append((args, out))
        return out

    monkeypatch.setattr(measure, "_span_deviation", spy)
    feed.errors(np.arange(len(feed.start)), T)
    monkeypatch.setattr(measure, "_span_deviation", numpy_span)
    (points, axes, polyline, ja, jb, window, _), (dist2, chord2) = seen[0]
    s = len(T)
    rows = RowPoses(
        tip=np.column_stack([c.ravel() for c in points]),
        axis=np.column_stack([c.ravel() for c in axes]),
        reach=np.zeros((dist2.size, 0)),
        swing=np.zeros((dist2.size, 0)),
    )
    monkeypatch.setattr(measure, "COMPILED_FROM", 1)
    got = measure._row_deviation(rows, polyline, np.tile(ja, s), np.tile(jb, s), window)
    assert np.array_equal(got[0], dist2.ravel())
    _agree(got[1], chord2.ravel())


def test_compiled_bounds_hold() -> None:
    """The bounds the compiled pass gives are above the deviation anywhere in the block (dense
    samples of the numpy path): the refinement still finds what it must."""
    kernels = measure._kernel()
    assert kernels is not None
    kernel = kernels.block
    for name in MACHINES:
        for tcp in (False, True):
            feed = _feed(machine(name), np.random.default_rng(7), 60, 0.05, tcp, 3.0)
            inputs = measure._KernelInputs.of(feed)
            assert inputs is not None
            part = slice(0, len(feed.start))
            bound = measure._first_pass_compiled(kernel, inputs, feed, part, T)[3]
            dist2, chord2 = feed.errors(np.arange(len(feed.start)), np.linspace(0, 1, 2001))
            assert feed.valid is not None
            compared = feed.valid
            assert np.all(np.sqrt(dist2.max(axis=0))[compared] <= bound[0][compared] + 1e-12)
            assert np.all(np.sqrt(chord2.max(axis=0))[compared] <= bound[1][compared] + 1e-12)


@functools.cache
def _posted(tcp: bool) -> tuple[str, float]:
    """The dome job posted (fanuc), its text and tool length."""
    job = read_cl(DOME)
    result = post(
        job, machine("dmu50"), PostOptions(strategy="recursive", controller="fanuc", tcp=tcp)
    )
    return result.text, result.program.tool_length


@pytest.mark.parametrize("tcp", [False, True])
@pytest.mark.parametrize("damage", [False, True])
def test_compiled_verification_is_the_numpy_verification(
    tcp: bool, damage: bool, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A posted program read back (and the same with a stretch of its Y words 0.02 mm off,
    beyond the tolerance between its CL points): verified with the compiled first pass, the
    same verification as with numpy, at the tip and at a pivot; the damaged one fails."""
    text, tool_length = _posted(tcp)
    if damage:
        lines = text.splitlines(keepends=True)
        a, b = len(lines) // 3, len(lines) // 3 + 40
        lines[a:b] = [re.sub(r"Y(-?[0-9.]+)", lambda w: f"Y{float(w[1]) + 0.02:.4f}", x)
                      for x in lines[a:b]]  # fmt: skip
        text = "".join(lines)
    program = dialect_for("fanuc").read(text, path="prog.nc")
    m = machine("dmu50")
    job = read_cl(DOME)
    tol = Tolerances.for_units("mm")
    rules = FeedRules.of(dialect_for("fanuc").spec, "mm")
    for pivot in (0.0, 3.0):
        kwargs = {"tol": tol, "pivot": pivot, "tool_length": tool_length, "feed_rules": rules}
        monkeypatch.setattr(measure, "COMPILED_FROM", 10**12)
        want = verify(program, m, job, **kwargs)  # type: ignore[arg-type]
        monkeypatch.setattr(measure, "COMPILED_FROM", 1)
        got = verify(program, m, job, **kwargs)  # type: ignore[arg-type]
        assert got == want
        assert want.feeds is not None  # the tip feed measured (on the kernel's tip paths)
        assert (want.max_tip_deviation <= tol.tip) is not damage


def test_block_deviation_falls_back_to_numpy_when_the_kernel_fails(
    monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    """numba that cannot compile or cache the kernel on this machine: a warning, and the numpy
    path gives the verification (for the rest of the process too)."""
    text, tool_length = _posted(False)
    program = dialect_for("fanuc").read(text, path="prog.nc")
    m = machine("dmu50")
    job = read_cl(DOME)
    want = verify(program, m, job, tool_length=tool_length)

    def broken(*args: object) -> None:
        raise RuntimeError("cannot cache function 'block_deviation': no locator available")

    kernels = measure._Kernels(broken, broken)
    monkeypatch.setattr(measure, "COMPILED_FROM", 1)
    monkeypatch.setattr(measure, "_compiled", lambda: None if measure._KERNEL_FAILED else kernels)
    monkeypatch.setattr(measure, "_KERNEL_FAILED", [])
    with caplog.at_level("WARNING", logger="urdfpost.verification.measure"):
        assert verify(program, m, job, tool_length=tool_length) == want
    assert "compiled block deviation unavailable (cannot cache function" in caplog.text
    assert measure._KERNEL_FAILED
    assert verify(program, m, job, tool_length=tool_length) == want
