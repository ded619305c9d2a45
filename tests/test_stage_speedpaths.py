"""Speed paths of subdivision and singularity detection: the numbers of the code they replaced.

The forward kinematics work in chunks of rows and may take their temporaries from a
:class:`~urdfpost.kinematics.forward.Scratch`; the detector builds its Jacobians a chunk at a
time from shared cosines and sines; subdivision merges its few inserted rows into place instead
of sorting everything. Each must give what the straightforward code gave, bit for bit (kept here
as the ``reference_*`` functions), on every shipped machine and on generated ones.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from urdfgen import build, machines

import urdfpost.linearize as linearize
from urdfpost.kinematics import forward
from urdfpost.kinematics.forward import (
    ROWS,
    Scratch,
    chain_of,
    cross,
    rotate,
    tip_and_axis,
    tip_and_axis_along,
    tip_axis_and_reach,
)
from urdfpost.machine import Machine, list_machines, load_machine
from urdfpost.planning.singularity import (
    conditioning,
    detect,
    feed_runs,
    joined_runs,
    orientation_jacobian,
)
from urdfpost.tolerances import Tolerances
from urdfpost.toolpath import Motion, Toolpath

SHIPPED = sorted(list_machines())


def same(a: np.ndarray, b: np.ndarray) -> bool:
    """Equal shapes, dtypes and bits."""
    a, b = np.asarray(a), np.asarray(b)
    return a.shape == b.shape and a.dtype == b.dtype and a.tobytes() == b.tobytes()


def random_q(machine: Machine, rng: np.random.Generator, n: int) -> np.ndarray:
    """Joint vectors: linear in +/-400 mm, rotary in +/-2 pi, a few rows at the poles."""
    q = np.empty((n, len(machine.axes)))
    for j, a in enumerate(machine.axes):
        q[:, j] = rng.uniform(-2 * np.pi, 2 * np.pi, n) if a.rotary else rng.uniform(-400, 400, n)
    q[: min(n, 4), list(machine.rotary_columns)] = 0.0
    return q


def walk(machine: Machine, rng: np.random.Generator, n: int, step: float = 0.02) -> np.ndarray:
    """A path of joint vectors with small steps."""
    q = random_q(machine, rng, 1) + np.cumsum(rng.normal(0.0, step, (n, len(machine.axes))), 0)
    q[:, list(machine.linear_columns)] *= 100.0
    return q


# -- the references: the whole path at once, as first written ---------------------------------


def reference_tip_and_axis(machine: Machine, q: np.ndarray, tool_length: float) -> tuple:
    tip, (axis,), reach, swing = forward._tip_and_axis_carried(machine, q, tool_length, True)
    n = q.shape[0]
    cols = machine.rotary_columns
    reach_a, swing_a = np.empty((n, len(cols))), np.empty((n, len(cols)))
    for i, c in enumerate(cols):
        reach_a[:, i], swing_a[:, i] = reach[c], swing[c]
    return forward._rows(tip, n), forward._rows(axis, n), reach_a, swing_a


def reference_orientation_jacobian(machine: Machine, q: np.ndarray) -> np.ndarray:
    n = q.shape[0]
    _, v, _, _ = reference_tip_and_axis(machine, q, 0.0)
    chain = [a for a in sorted(machine.axes, key=lambda a: a.chain_index) if a.rotary]
    cols = []
    for j, a in enumerate(chain):
        w = np.broadcast_to(a.screw[:3], (n, 3))
        for b in chain[j - 1 :: -1] if j else ():
            w = rotate(b.screw[:3], q[:, machine.axis_names.index(b.name)], w)
        cols.append(cross(w, v))
    return np.stack(cols, axis=2)


def reference_conditioning(machine: Machine, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    j = reference_orientation_jacobian(machine, q)
    if j.shape[2] == 2:
        total = np.einsum("nij,nij->n", j, j)
        area = np.linalg.norm(cross(j[:, :, 0], j[:, :, 1]), axis=1)
        smax = np.sqrt(0.5 * (total + np.sqrt(np.maximum(total**2 - 4.0 * area**2, 0.0))))
        with np.errstate(divide="ignore", invalid="ignore"):
            smin = np.where(smax > 0, area / np.where(smax > 0, smax, 1.0), 0.0)
    else:
        s = np.linalg.svd(j, compute_uv=False)
        smin, smax = s[:, -1], s[:, 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        kappa = np.where(smin > 0, smax / np.where(smin > 0, smin, 1.0), np.inf)
    return smin, kappa


def reference_joined_runs(joined: np.ndarray) -> list[tuple[int, int]]:
    n = len(joined)
    runs = []
    i = 0
    while i < n - 1:
        if joined[i + 1]:
            j = i + 1
            while j + 1 < n and joined[j + 1]:
                j += 1
            runs.append((i, j))
            i = j
        else:
            i += 1
    return runs


def reference_spans(machine: Machine, toolpath: Toolpath, q: np.ndarray, tol: Tolerances) -> list:
    """The spans of :func:`detect` as first written, as dicts."""
    n = len(toolpath)
    runs = reference_joined_runs(toolpath.motion == Motion.FEED)
    sigma, kappa = reference_conditioning(machine, q)
    rot = q[:, list(machine.rotary_columns)]
    step = np.zeros((n, rot.shape[1]))
    step[1:] = np.abs(np.diff(rot, axis=0))
    _, v, _, _ = reference_tip_and_axis(machine, q, 0.0)
    near_pole = (
        np.sqrt(np.clip(1.0 - (v @ machine.rotary[0].direction) ** 2, 0.0, None))
        < tol.singular_sigma
    )
    spans = []
    for s, e in runs:
        low = sigma[s : e + 1] < tol.singular_sigma
        swing = np.zeros(e - s + 1, dtype=bool)
        big = (step[s + 1 : e + 1] > tol.swing_limit).any(axis=1)
        swing[1:] |= big
        swing[:-1] |= big
        mark = low | swing
        if not mark.any():
            continue
        idx = np.flatnonzero(mark) + s
        breaks = np.flatnonzero(np.diff(idx) > 1)
        starts = np.concatenate([[idx[0]], idx[breaks + 1]])
        ends = np.concatenate([idx[breaks], [idx[-1]]])
        merged: list[list[int]] = []
        for a, b in zip(starts, ends, strict=True):
            a = max(s, int(a) - tol.singular_margin)
            b = min(e, int(b) + tol.singular_margin)
            if merged and a <= merged[-1][1]:
                merged[-1][1] = max(merged[-1][1], b)
            else:
                merged.append([a, b])
        for a, b in merged:
            sl = slice(a, b + 1)
            if (sigma[sl] < tol.singular_sigma).any():
                kind = "pole" if near_pole[sl].any() else "edge"
            else:
                kind = "swing"
            spans.append(
                {
                    "first": a,
                    "last": b,
                    "first_line": int(toolpath.line[a]),
                    "last_line": int(toolpath.line[b]),
                    "kind": kind,
                    "min_sigma": float(sigma[sl].min()),
                    "max_kappa": float(kappa[sl].max()),
                    "swing_deg": float(np.degrees(step[a + 1 : b + 1, 0].sum())),
                    "max_step_deg": float(np.degrees(step[a + 1 : b + 1].max(initial=0.0))),
                }
            )
    return spans


# -- forward kinematics in chunks, with and without a scratch ---------------------------------


def check_forward(m: Machine, seed: int) -> None:
    rng = np.random.default_rng(seed)
    q = random_q(m, rng, ROWS + 37)  # two chunks of rows, the second short
    ref = reference_tip_and_axis(m, q, 31.5)
    got = tip_axis_and_reach(m, q, 31.5)
    assert all(same(a, b) for a, b in zip(ref, got, strict=True))
    tip, axis = tip_and_axis(chain_of(m), q, 31.5)
    assert same(tip, ref[0]) and same(axis, ref[1])

    q0, q1 = q[:300], q[1:301]
    scratch = Scratch()
    for t in (np.arange(1, 10) / 10, np.array([0.0, 0.3, 0.35, 1.0]), rng.uniform(0, 1, (3, 300))):
        for with_tip in (True, False):
            plain = tip_and_axis_along(m, q0, q1, t, 12.0, with_tip=with_tip)
            scratch.start((t.shape[0], 300))
            fast = tip_and_axis_along(
                chain_of(m), q0, q1, t, 12.0, with_tip=with_tip, scratch=scratch
            )
            for p, f in zip(plain, fast, strict=True):
                if p is None:
                    assert f is None
                else:
                    assert all(same(a, b) for a, b in zip(p, f, strict=True))


@pytest.mark.parametrize("name", SHIPPED)
def test_forward_speed_paths_shipped(name: str) -> None:
    check_forward(load_machine(name), 3)


@settings(max_examples=15, deadline=None)
@given(gen=machines(), seed=st.integers(0, 2**16))
def test_forward_speed_paths_generated(gen, seed):
    check_forward(build(gen), seed)


def test_scratch_hands_out_an_array_again_once_nothing_refers_to_it() -> None:
    work = Scratch().start((4, 5))
    a = work.take()
    first = a.ctypes.data
    row = a[1]
    del a
    b = work.take()
    assert b.ctypes.data != first  # a row of the first array is still alive
    del row
    c = work.take()
    assert c.ctypes.data == first  # nothing refers to it any more
    assert c.shape == (4, 5) and b.shape == (4, 5)
    with pytest.raises(ValueError, match="scratch started for shape"):
        tip_and_axis_along(
            load_machine("dmu50"),
            np.zeros((3, 5)),
            np.ones((3, 5)),
            np.arange(1, 10) / 10,
            scratch=work,
        )


# -- the detector -------------------------------------------------------------------------


def check_detector(m: Machine, seed: int) -> None:
    rng = np.random.default_rng(seed)
    q = random_q(m, rng, ROWS + 501)
    assert same(orientation_jacobian(m, q), reference_orientation_jacobian(m, q))
    assert same(orientation_jacobian(m, q[5]), reference_orientation_jacobian(m, q[5:6]))
    assert all(
        same(a, b) for a, b in zip(conditioning(m, q), reference_conditioning(m, q), strict=True)
    )
    assert all(same(x, np.zeros(0)) for x in conditioning(m, q[:0]))


@pytest.mark.parametrize("name", SHIPPED)
def test_detector_speed_paths_shipped(name: str) -> None:
    check_detector(load_machine(name), 5)


@settings(max_examples=15, deadline=None)
@given(gen=machines(), seed=st.integers(0, 2**16))
def test_detector_speed_paths_generated(gen, seed):
    check_detector(build(gen), seed)


@settings(max_examples=200, deadline=None)
@given(st.lists(st.booleans(), max_size=40))
def test_joined_runs_as_the_loop_found_them(joined):
    assert joined_runs(np.array(joined, dtype=bool)) == reference_joined_runs(joined)


@pytest.mark.parametrize("name", SHIPPED)
def test_detect_spans_as_first_found(name: str) -> None:
    m = load_machine(name)
    rng = np.random.default_rng(17)
    n = 3000
    q = walk(m, rng, n)
    rot = list(m.rotary_columns)
    q[1000:1003, rot[-1]] = 0.0  # through the pole or the edge
    q[2000:2002, rot[0]] += np.array([0.0, 0.5])  # a swing
    q[2500:2600, rot[-1]] = rng.normal(0.0, 1e-3, 100)
    motion = np.full(n, Motion.FEED, dtype=np.int8)
    motion[[0, 700, 701, 2200]] = Motion.RAPID
    toolpath = Toolpath(
        tip=np.zeros((n, 3)),
        axis=np.tile([0.0, 0.0, 1.0], (n, 1)),
        feed=np.full(n, 1000.0),
        motion=motion,
        line=np.arange(n) + 10,
    )
    tol = Tolerances()
    spans = detect(m, toolpath, q, tol)
    assert [s.as_dict() for s in spans] == reference_spans(m, toolpath, q, tol)
    assert spans  # the path has some
    assert feed_runs(toolpath) == reference_joined_runs(motion == Motion.FEED)


# -- subdivision -------------------------------------------------------------------------


@settings(max_examples=100, deadline=None)
@given(
    n=st.integers(0, 60),
    extra=st.lists(st.integers(-2, 62), max_size=30),
    few=st.booleans(),
)
def test_merged_rows_as_a_stable_sort_puts_them(n, extra, few):
    keys = np.arange(n, dtype=float)
    more = np.array(extra, dtype=float) + 0.5 * (np.arange(len(extra)) % 2)  # ties too
    rows = np.arange(n * 2, dtype=float).reshape(n, 2)
    added = -np.arange(1, 2 * len(extra) + 1, dtype=float).reshape(-1, 2)
    order = np.argsort(np.concatenate([keys, more]), kind="stable")
    expected = np.concatenate([rows, added])[order]
    at, sort = linearize._merge_positions(keys, more)
    saved = linearize._FEW_INSERTED
    try:
        linearize._FEW_INSERTED = 10**6 if few else -1
        assert same(linearize._inserted(rows, at, added[sort]), expected)
    finally:
        linearize._FEW_INSERTED = saved


def test_column_max_and_first_largest_as_argmax() -> None:
    rng = np.random.default_rng(2)
    values = rng.uniform(0, 1, (9, 50)).round(1)  # ties
    values[:, 3] = 0.0
    values[4, 7] = np.nan
    values[[2, 6], 9] = np.nan
    index = np.argmax(values, axis=0)
    expected = values[index, np.arange(50)]
    assert same(linearize._column_max(values), expected)
    assert same(linearize._column_max(values[:, :3]), expected[:3])  # no NaN, no zero
    wanted = rng.uniform(size=50) < 0.5
    assert same(linearize._first_largest(values, wanted), np.where(wanted, index, 0))


def test_block_errors_with_poses_given_or_worked_out() -> None:
    m = load_machine("umc750")
    rng = np.random.default_rng(4)
    q = walk(m, rng, 9000, step=0.003)
    tip, axis = tip_and_axis(m, q, 20.0)
    tol = Tolerances()
    targets = (0.004, 0.002)
    ends = linearize.RowPoses.of(m, q, 20.0)
    args = (m, q[:-1], q[1:], tip[:-1], tip[1:], axis[:-1], axis[1:])
    for tcp in (False, True):
        given_ = linearize._block_errors(
            *args, (ends.take(slice(0, -1)), ends.take(slice(1, None))), 20.0, tcp, tol, targets
        )
        worked = linearize._block_errors(*args, None, 20.0, tcp, tol, targets)
        assert same(given_.tip, worked.tip) and same(given_.orientation, worked.orientation)


@pytest.mark.parametrize("many", [False, True])
def test_subdivide_puts_rows_and_blocks_in_order(many: bool) -> None:
    """Bisected blocks land between their rows, whichever way the rows are merged in."""
    m = load_machine("dmu50")
    rng = np.random.default_rng(8)
    q = walk(m, rng, 400, step=0.01 if many else 0.001)
    tip, axis = tip_and_axis(m, q, 10.0)
    tol = Tolerances(max_subdivision_depth=3)
    out = {}
    saved = linearize._FEW_INSERTED
    try:
        for few in (10**6, -1):
            linearize._FEW_INSERTED = few
            out[few] = linearize.subdivide(m, q, tip, axis, tool_length=10.0, tol=tol)
    finally:
        linearize._FEW_INSERTED = saved
    a, b = out.values()
    for f in ("q", "tip", "axis", "source"):
        assert same(getattr(a, f), getattr(b, f))
    assert same(a.error.tip, b.error.tip) and same(a.error.orientation, b.error.orientation)
    inserted = int((a.source < 0).sum())
    assert (inserted > 300) if many else (0 < inserted < 300)
    kept = a.source[a.source >= 0]
    assert same(kept, np.arange(400))
    assert same(a.q[a.source >= 0], q)
    assert len(a.error.tip) == len(a.q) - 1
    # an inserted row is the midpoint solution between its neighbours: its tip is between them
    mid = np.flatnonzero(a.source < 0)
    off_centre = np.linalg.norm(a.tip[mid] - 0.5 * (a.tip[mid - 1] + a.tip[mid + 1]), axis=1)
    assert np.all(off_centre <= np.linalg.norm(a.tip[mid + 1] - a.tip[mid - 1], axis=1))
