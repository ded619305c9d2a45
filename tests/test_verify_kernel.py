"""The compiled first pass and refinement of verification's block deviation
(:mod:`urdfpost.verification._deviation_kernel`) against the numpy path they stand for: per
sample, per block (maxima, the samples they are at, the bounds, the refined maxima), and
through whole verifications of posted programs, good and damaged; and the numpy path when they
cannot run."""

from __future__ import annotations

import functools
import re
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest
from conftest import StandIn, Unloaded
from hypothesis import given, settings
from hypothesis import strategies as st

import urdfpost.verification.measure as measure
from urdfpost import load_machine
from urdfpost.dialects import dialect_for
from urdfpost.geometry import chunks, refine_max
from urdfpost.kinematics.forward import tip_and_axis
from urdfpost.linearize import RowPoses
from urdfpost.machine import Machine
from urdfpost.posting.check import bent_tolerances
from urdfpost.posting.options import PostOptions
from urdfpost.posting.whole import post
from urdfpost.readers import read_cl
from urdfpost.tolerances import Tolerances
from urdfpost.verification import verify
from urdfpost.verification.feeds import FeedRules, tip_lengths
from urdfpost.verification.match import _row_poses
from urdfpost.verification.measure import _Blocks, _Polyline

pytest.importorskip("numba")

from urdfpost.verification import _deviation_kernel
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
        polyline=_Polyline.of(cl_tip, cl_axis, pivot),
        tcp=tcp,
        tool_length=100.0,
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
    kernels = measure.KERNELS.load()
    assert kernels is not None
    kernel = kernels.block_deviation
    inputs = measure._KernelInputs.of(feed)
    assert inputs is not None
    for part in [*chunks(len(feed.start), 7 * len(T)), slice(0, len(feed.start))]:
        dist2, best, worst, bound, length = measure._first_pass_compiled(
            kernel, inputs, feed, part, T
        )
        want_dist2, want_chord2, tip_bound, chord_bound = _numpy_pass(feed, part)
        _agree(dist2, want_dist2)
        # the same operations on the same cosines and sines: the same numbers (at a pivot the
        # curve's cosines and sines are the C library's there and numpy's here, which may
        # differ in the last bit where numpy's are vectorised: within AGREE, above)
        if not feed.pivot:
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
    _compare(replace(feed, polyline=_Polyline.of(tips, np.column_stack(axes), pivot)))


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
        monkeypatch.setattr(measure.KERNELS, "start", 10**12)
        want = measure._row_deviation(*args)
        monkeypatch.setattr(measure.KERNELS, "start", 1)
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
    monkeypatch.setattr(measure.KERNELS, "start", 1)
    got = measure._row_deviation(rows, polyline, np.tile(ja, s), np.tile(jb, s), window)
    assert np.array_equal(got[0], dist2.ravel())
    _agree(got[1], chord2.ravel())


def test_compiled_bounds_hold() -> None:
    """The bounds the compiled pass gives are above the deviation anywhere in the block (dense
    samples of the numpy path): the refinement still finds what it must."""
    kernels = measure.KERNELS.load()
    assert kernels is not None
    kernel = kernels.block_deviation
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


def _refined(
    feed: _Blocks, rng: np.random.Generator
) -> tuple[measure._KernelInputs, np.ndarray, tuple, tuple, tuple]:
    """The compiled first pass over every block, and a random half of the compared blocks to
    refine by tip and four fifths by orientation: the inputs, the blocks refined, and the
    samples worst, the maxima sampled and the blocks wanted (of each of the two)."""
    kernels = measure.KERNELS.load()
    inputs = measure._KernelInputs.of(feed)
    assert kernels is not None and inputs is not None
    n = len(feed.start)
    _, best, worst, _, _ = measure._first_pass_compiled(
        kernels.block_deviation, inputs, feed, slice(0, n), T
    )
    assert feed.valid is not None
    wanted = (rng.random(n) < 0.5) & feed.valid, (rng.random(n) < 0.8) & feed.valid
    todo = np.flatnonzero(wanted[0] | wanted[1])
    return inputs, todo, (worst[0], worst[1]), (best[0], best[1]), wanted


def _kernel_errors(feed: _Blocks, inputs: measure._KernelInputs, blocks: np.ndarray):
    """``refine_max``'s function of the blocks, each point through the kernel's evaluation
    (``deviation_at``) on its own."""
    c = inputs.chain
    kinds = np.array([_deviation_kernel._kind(*w) for w in c.direction], dtype=np.int64)
    u, dist2, chord2 = np.empty(1), np.empty(1), np.empty(1)
    work, trig = np.empty((10, 1)), np.empty((2, len(c.column), 1))
    frames = np.empty((measure._LONG, _deviation_kernel._FRAME))

    def errors(idx: np.ndarray, tt: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        d2, c2 = np.empty(len(idx)), np.empty(len(idx))
        for m, (i, x) in enumerate(zip(idx, tt, strict=True)):
            b = blocks[i]
            span = max(inputs.jb[b] - inputs.ja[b], 1)
            _deviation_kernel._frames(
                inputs.ja[b], span, *feed.polyline.tip, *feed.polyline.axis, inputs.omega,
                feed.window, feed.pivot, frames,
            )  # fmt: skip
            u[0] = x
            _deviation_kernel.deviation_at(
                c.column, c.rotary, c.direction, c.pivot, kinds, inputs.linear, c.tool_point,
                c.home_axis, inputs.values, inputs.start[b], span, frames, feed.tcp, feed.pivot,
                feed.window, u, 1, dist2, chord2, work, trig,
            )  # fmt: skip
            d2[m], c2[m] = dist2[0], chord2[0]
        return d2, c2

    return errors


@pytest.mark.parametrize("name", MACHINES)
@pytest.mark.parametrize("tcp", [False, True])
@pytest.mark.parametrize("pivot", [0.0, 3.0])
def test_compiled_refinement_is_refine_max(name: str, tcp: bool, pivot: float) -> None:
    """The compiled refinement of blocks of every kind of machine: the maxima of
    ``refine_max`` with the kernel's evaluations, to the bit (the same brackets), and within
    AGREE of ``refine_max`` with numpy's; the blocks of long spans left to numpy, untouched."""
    rng = np.random.default_rng(hash((name, tcp, pivot, "refine")) % 2**32)
    for scale in (0.002, 0.05, 0.5):
        feed = _feed(machine(name), rng, 60, scale, tcp, pivot)
        inputs, todo, worst, best, wanted = _refined(feed, rng)
        kernels = measure.KERNELS.load()
        assert kernels is not None
        got = (best[0].copy(), best[1].copy())
        left = measure._refine_compiled(
            kernels.refine_deviation, inputs, feed, todo, T, worst, got, wanted
        )
        long = np.maximum(feed.jb - feed.ja, 1)[todo] > measure._LONG
        assert np.array_equal(left, todo[long])
        short = todo[~long]
        args = (
            T,
            (worst[0][short], worst[1][short]),
            (best[0][short], best[1][short]),
            (wanted[0][short], wanted[1][short]),
        )
        with_kernel = refine_max(_kernel_errors(feed, inputs, short), *args, measure._ITERATIONS)

        def numpy_errors(
            idx: np.ndarray, tt: np.ndarray, feed: _Blocks = feed, short: np.ndarray = short
        ) -> tuple[np.ndarray, np.ndarray]:
            dist2, chord2 = feed.errors(short[idx], tt[None, :])
            return dist2[0], chord2[0]

        with_numpy = refine_max(numpy_errors, *args, measure._ITERATIONS)
        for i in range(2):
            assert np.array_equal(got[i][short], with_kernel[i])
            _agree(got[i][short], with_numpy[i])
            assert np.array_equal(got[i][left], best[i][left])
            # refined where wanted: never below the sampled maximum
            assert np.all(got[i][short] >= best[i][short])


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
    """A posted program read back (and the same with a stretch of its Y words 0.05 mm off,
    beyond the tolerance between its CL points): verified with the compiled first pass, the
    same verification as with numpy, at the tip and at a pivot (with the tolerance the
    command line gives a pivot, :func:`bent_tolerances`); the damaged one fails."""
    text, tool_length = _posted(tcp)
    if damage:
        lines = text.splitlines(keepends=True)
        a = next(
            k for k in range(len(lines) // 3, len(lines)) if re.search(r"\bY-?[0-9]", lines[k])
        )
        b = a + 40  # (from a Y word on: the passes run along X, Y written at their starts)
        lines[a:b] = [re.sub(r"Y(-?[0-9.]+)", lambda w: f"Y{float(w[1]) + 0.05:.4f}", x)
                      for x in lines[a:b]]  # fmt: skip
        text = "".join(lines)
    program = dialect_for("fanuc").read(text, path="prog.nc")
    m = machine("dmu50")
    job = read_cl(DOME)
    rules = FeedRules.of(dialect_for("fanuc").spec, "mm")
    for pivot in (0.0, 3.0):
        tol = bent_tolerances(Tolerances.for_units("mm"), 0.0, pivot)
        kwargs = {"tol": tol, "pivot": pivot, "tool_length": tool_length, "feed_rules": rules}
        monkeypatch.setattr(measure.KERNELS, "start", 10**12)
        want = verify(program, m, job, **kwargs)  # type: ignore[arg-type]
        monkeypatch.setattr(measure.KERNELS, "start", 1)
        got = verify(program, m, job, **kwargs)  # type: ignore[arg-type]
        assert got == want
        assert want.feeds is not None  # the tip feed measured (on the kernel's tip paths)
        assert (want.max_tip_deviation <= tol.tip) is not damage


def test_block_deviation_falls_back_to_numpy_when_the_kernel_fails(
    monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture, stand_in: StandIn
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

    kernels = SimpleNamespace(
        block_deviation=broken, point_deviation=broken, refine_deviation=broken
    )
    monkeypatch.setattr(measure.KERNELS, "start", 1)
    stand_in(measure.KERNELS, kernels)
    with caplog.at_level("WARNING", logger="urdfpost.verification.measure"):
        assert verify(program, m, job, tool_length=tool_length) == want
    assert "compiled block deviation unavailable (cannot cache function" in caplog.text
    assert measure.KERNELS.failed
    assert verify(program, m, job, tool_length=tool_length) == want


def test_refinement_falls_back_to_numpy_when_its_kernel_fails(
    monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture, stand_in: StandIn
) -> None:
    """The first pass compiled, the refinement's kernel failing: a warning, and every block
    wanted refined by numpy (``refine_max``), within AGREE of the numpy path's maxima."""
    feed = _feed(machine("dmu50"), np.random.default_rng(11), 200, 0.05, False, 3.0)
    levels = [(0.0, 0.0)]
    monkeypatch.setattr(measure.KERNELS, "start", 10**12)
    (want,) = measure._block_deviation([feed], levels)
    real = measure.KERNELS.load()
    assert real is not None

    def broken(*args: object) -> None:
        raise RuntimeError("cannot cache function 'refine_deviation': no locator available")

    refined: list[int] = []

    def spy(*args: Any, **kwargs: Any) -> tuple[np.ndarray, np.ndarray]:
        wanted = args[4]
        refined.append(int(wanted[0].sum() + wanted[1].sum()))
        return refine_max(*args, **kwargs)

    kernels = SimpleNamespace(
        block_deviation=real.block_deviation,
        point_deviation=real.point_deviation,
        refine_deviation=broken,
    )
    monkeypatch.setattr(measure.KERNELS, "start", 1)
    stand_in(measure.KERNELS, kernels)
    monkeypatch.setattr(measure, "refine_max", spy)
    with caplog.at_level("WARNING", logger="urdfpost.verification.measure"):
        (got,) = measure._block_deviation([feed], levels)
    assert "compiled block deviation unavailable (cannot cache function" in caplog.text
    assert measure.KERNELS.failed
    assert sum(refined) > 0
    _agree(got.tip, want.tip)
    _agree(got.block_chord2, want.block_chord2)


def test_without_numba_the_numpy_path_runs(
    monkeypatch: pytest.MonkeyPatch, unloaded: Unloaded
) -> None:
    """No numba (the kernels' module cannot be imported): no kernels, whatever the size, and
    the verification the numpy path gives."""
    import builtins

    text, tool_length = _posted(False)
    program = dialect_for("fanuc").read(text, path="prog.nc")
    m = machine("dmu50")
    job = read_cl(DOME)
    monkeypatch.setattr(measure.KERNELS, "start", 10**12)
    want = verify(program, m, job, tool_length=tool_length)
    real_import = builtins.__import__

    def no_kernels(name: str, *args: object, **kwargs: object) -> object:
        if name == "urdfpost.verification" and "_deviation_kernel" in (args[2] or ()):  # type: ignore[operator]
            raise ImportError("no numba here")
        return real_import(name, *args, **kwargs)  # type: ignore[arg-type]

    def compiled(*args: object) -> None:
        raise AssertionError("a compiled pass ran")

    unloaded(measure.KERNELS)
    monkeypatch.setattr(builtins, "__import__", no_kernels)
    monkeypatch.setattr(measure.KERNELS, "start", 1)
    monkeypatch.setattr(measure, "_first_pass_compiled", compiled)
    monkeypatch.setattr(measure, "_refine_compiled", compiled)
    try:
        assert measure.KERNELS.get(10**9) is None
        assert verify(program, m, job, tool_length=tool_length) == want
    finally:
        monkeypatch.undo()
