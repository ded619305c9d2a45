"""The compiled box culling (:mod:`urdfpost.collision._kernels`) against the numpy path.

The kernels lower every gap by ``KERNEL_SLACK_MM`` (1e-10 mm) so that they keep, for FCL, every
pair the numpy path keeps; otherwise they are the numpy formulas. Held here to the numpy path
figure by figure (box gaps, the stock tree's separations and culls) on four machines, and the
scans as a whole (first contact of every move, pairs and samples) on paths that cut into a
stock; and the numpy path without numba or after a compile failure, with the same results.
"""

from __future__ import annotations

import logging
from types import ModuleType, SimpleNamespace

import numpy as np
import pytest
import trimesh
from conftest import StandIn, Unloaded
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from urdfpost.collision import CollisionWorld, ToolBody
from urdfpost.collision import world as world_module
from urdfpost.collision.world import GAP_MM
from urdfpost.kinematics import inverse
from urdfpost.machine import load_machine

pytest.importorskip("fcl")

TOOL_LENGTH = 100.0  # mm
MACHINES = ["dmu50", "monoblock", "gantry-ca", "dmu50-nutating"]
TOL = 1e-9  # mm: the kernels' figures are the numpy ones less 1e-10 mm, give or take rounding


def _kernels() -> ModuleType:
    pytest.importorskip("numba")
    module = world_module.KERNELS.load()
    assert module is not None
    return module


def _stock() -> trimesh.Trimesh:
    """A dome of 5,120 triangles (an 11-level tree) on the table, 40 mm radius."""
    sphere = trimesh.creation.icosphere(subdivisions=4, radius=40.0)
    sphere.apply_translation((0.0, 0.0, 10.0))
    return sphere


@pytest.fixture(scope="module", params=MACHINES)
def world(request: pytest.FixtureRequest) -> CollisionWorld:
    machine = load_machine(request.param)
    return CollisionWorld.build(machine, ToolBody(diameter=10.0), TOOL_LENGTH, _stock())


def _configurations(world: CollisionWorld, n: int, seed: int) -> np.ndarray:
    """Joint vectors (n, m) with the tool around the dome, from inside it to 30 mm off it,
    axes tilted up to 50 degrees; plus a few anywhere within travel."""
    machine = world.machine
    rng = np.random.default_rng(seed)
    direction = rng.normal(size=(n, 3))
    direction[:, 2] = np.abs(direction[:, 2])
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    tips = direction * rng.uniform(20.0, 70.0, (n, 1)) + (0.0, 0.0, 10.0)
    tilt = rng.uniform(-0.9, 0.9, (n, 2))
    axes = np.column_stack([tilt, np.ones(n)])
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    q = inverse(machine, tips, axes, TOOL_LENGTH).q[:, 0]
    lo = np.where(np.isfinite(machine.lower), machine.lower, -7.0)
    hi = np.where(np.isfinite(machine.upper), machine.upper, 7.0)
    anywhere = lo + rng.random((n // 10, len(machine.axes))) * (hi - lo)
    q = np.vstack([q[~np.isnan(q).any(axis=1)], anywhere])
    assert len(q) > n // 2
    return q


@pytest.mark.parametrize("need", [np.inf, GAP_MM, 5.0, "per configuration"])
def test_pair_bounds_are_the_numpy_bounds_lowered(world: CollisionWorld, need: object) -> None:
    """Wherever the numpy bound is within ``need`` (then the oriented boxes answered), the
    compiled one is that bound less at most 1e-9 mm, never more; elsewhere it is beyond
    ``need`` too (less the slack)."""
    kernels = _kernels()
    q = _configurations(world, 400, 1)
    transforms = world._moving_transforms(q)
    boxes = world._boxes(transforms)
    pairs = world._pairs
    if need == "per configuration":
        need = np.random.default_rng(2).uniform(0.0, 30.0, len(q))
    assert isinstance(need, float | np.ndarray)
    plain = world._lower_bounds(transforms, pairs, need, boxes)
    fast = world._lower_bounds(transforms, pairs, need, boxes, kernels)
    assert fast.shape == plain.shape
    within = plain <= np.reshape(need, (-1, 1))
    assert within.any()
    assert (fast[within] <= plain[within]).all()
    np.testing.assert_allclose(fast[within], plain[within], rtol=0, atol=TOL)
    beyond = np.broadcast_to(np.reshape(need, (-1, 1)), plain.shape)[~within]
    assert (fast[~within] > beyond - TOL).all()
    # the decision the scans take from them: the same pairs near, within the slack
    assert ((fast <= GAP_MM) >= (plain <= GAP_MM)).all()
    assert (plain[(fast <= GAP_MM) & (plain > GAP_MM)] <= GAP_MM + TOL).all()
    # some pairs close, some apart, on every machine
    assert (plain <= GAP_MM).any() and (plain > 10.0).any()


def test_asked_bounds_compiled(world: CollisionWorld) -> None:
    """The pairs near among those allowed: the numpy answer, and nothing where not allowed."""
    kernels = _kernels()
    q = _configurations(world, 300, 3)
    boxes = world._boxes(world._moving_transforms(q))
    allowed = np.random.default_rng(4).random((len(q), len(world._pairs))) < 0.3
    plain = world._asked_bounds(boxes, allowed, GAP_MM)
    fast = world._asked_bounds(boxes, allowed, GAP_MM, kernels)
    assert plain.any()
    np.testing.assert_array_equal(fast, plain)


@pytest.mark.parametrize("turned", [False, True])
def test_stock_separations_compiled(
    world: CollisionWorld, monkeypatch: pytest.MonkeyPatch, turned: bool
) -> None:
    """The compiled descent's separation of every stock pair: at most the numpy one and
    within 1e-9 mm of it; +inf and -inf (crowded) where the numpy descent gives them. Also
    with the stock's tree turned and moved in the workpiece frame (the culling figures only:
    the FCL objects are not moved)."""
    kernels = _kernels()
    if turned:
        from scipy.spatial.transform import Rotation

        placement = np.eye(4)
        placement[:3, :3] = Rotation.from_euler(
            "xyz", [20.0, -35.0, 50.0], degrees=True
        ).as_matrix()
        placement[:3, 3] = (5.0, -8.0, 3.0)
        monkeypatch.setitem(world._fixed_transform, world._stock, placement)
    q = _configurations(world, 400, 5)
    transforms = world._moving_transforms(q)
    boxes = world._boxes(transforms)
    most = np.random.default_rng(6).uniform(0.0, 25.0, len(q))
    plain = world._stock_separations(transforms, most, boxes)
    fast = world._stock_separations(transforms, most, boxes, kernels)
    assert fast.shape == plain.shape == (len(q), len(world._stock_pairs))
    finite = np.isfinite(plain)
    assert finite.sum() > 50 and (plain == np.inf).any() and (plain == -np.inf).any()
    assert (fast <= plain).all()
    np.testing.assert_allclose(fast[finite], plain[finite], rtol=0, atol=TOL)
    np.testing.assert_array_equal(np.isneginf(fast), np.isneginf(plain))
    assert (
        fast[plain == np.inf] > most[:, None].repeat(plain.shape[1], 1)[plain == np.inf] - TOL
    ).all()


@pytest.mark.parametrize("gap", [GAP_MM, 2.0, "per configuration"])
def test_stock_culls_compiled(world: CollisionWorld, gap: object) -> None:
    """The stock pairs the tree's ``near`` keeps for FCL: the same compiled."""
    kernels = _kernels()
    q = _configurations(world, 400, 7)
    transforms = world._moving_transforms(q)
    boxes = world._boxes(transforms)
    if gap == "per configuration":
        gap = np.random.default_rng(8).uniform(0.0, 10.0, len(q))
    assert isinstance(gap, float | np.ndarray)
    start = np.random.default_rng(9).random((len(q), len(world._pairs))) < 0.8
    plain, fast = start.copy(), start.copy()
    world._cull_stock_pairs(transforms, plain, gap, boxes)
    world._cull_stock_pairs(transforms, fast, gap, boxes, kernels)
    sp = world._stock_pairs
    assert plain[:, sp].any() and (start[:, sp] & ~plain[:, sp]).any()
    np.testing.assert_array_equal(fast, plain)


def _compare_scans(world: CollisionWorld, q: np.ndarray, monkeypatch: pytest.MonkeyPatch) -> int:
    """check_moves and check of ``q`` by the numpy path and compiled: the same results, and
    the same move ends and moves kept (or a superset within the slack). Returns the hits."""
    kernels = _kernels()
    with monkeypatch.context() as m:
        m.setattr(world_module.KERNELS, "forced", False)
        plain, plain_check = world.check_moves(q), world.check(q)
    with monkeypatch.context() as m:
        m.setattr(world_module.KERNELS, "forced", True)
        assert world_module.KERNELS.get(1) is kernels
        fast, fast_check = world.check_moves(q), world.check(q)
    assert fast.pairs == plain.pairs
    np.testing.assert_array_equal(fast.at, plain.at)
    np.testing.assert_array_equal(fast.samples, plain.samples)
    assert fast_check.pairs == plain_check.pairs
    ends_plain, may_plain = world._ends_and_moves(q)
    ends_fast, may_fast = world._ends_and_moves(q, kernels)
    np.testing.assert_array_equal(ends_fast, ends_plain)
    assert (may_fast >= may_plain).all()
    return int(plain.hit.sum()) + int(plain_check.hit.sum())


def test_scans_compiled_find_what_the_numpy_path_finds(
    world: CollisionWorld, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Passes across the dome, over it and through it, the axis tilting: every move's first
    contact (pair and sample) and every point's, compiled and not."""
    t = np.linspace(-1.0, 1.0, 12)
    tips, axes = [], []
    for y, z in ((-25.0, 30.0), (0.0, 5.0), (20.0, 62.0)):
        tips.append(np.column_stack([70.0 * t, np.full_like(t, y), np.full_like(t, z)]))
        axes.append(np.column_stack([0.5 * t, np.full_like(t, 0.3), np.ones_like(t)]))
    a = np.vstack(axes)
    a /= np.linalg.norm(a, axis=1, keepdims=True)
    q = inverse(world.machine, np.vstack(tips), a, TOOL_LENGTH).q[:, 0]
    q = q[~np.isnan(q).any(axis=1)]
    assert len(q) > 20
    assert _compare_scans(world, q, monkeypatch) > 0


@pytest.fixture(scope="module")
def thin_wall_world() -> CollisionWorld:
    """A 0.4 mm thin wall, 60 mm long and 30 mm high, standing on the table (dmu50)."""
    wall = trimesh.creation.box(extents=(0.4, 60.0, 30.0))
    wall.apply_translation((0.0, 0.0, 15.0))
    return CollisionWorld.build(load_machine("dmu50"), ToolBody(diameter=10.0), TOOL_LENGTH, wall)


@settings(
    max_examples=30, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(st.floats(-3.0, 3.0), st.floats(0.0, 40.0), st.floats(-0.5, 0.5))
def test_grazing_the_thin_wall_compiled(
    thin_wall_world: CollisionWorld,
    monkeypatch: pytest.MonkeyPatch,
    x: float,
    z: float,
    tilt: float,
) -> None:
    """Sweeps across the wall top and flank at clearances from touching to a few mm."""
    tips = np.array([[x, -50.0, z], [x, 50.0, z + 5.0], [-x, 0.0, z]])
    axes = np.array([[tilt, 0.0, 1.0], [-tilt, 0.0, 1.0], [0.0, tilt, 1.0]])
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    q = inverse(thin_wall_world.machine, tips, axes, TOOL_LENGTH).q[:, 0]
    if np.isnan(q).any():
        return
    _compare_scans(thin_wall_world, q, monkeypatch)


def test_without_numba_the_numpy_path_runs(
    thin_wall_world: CollisionWorld, monkeypatch: pytest.MonkeyPatch, unloaded: Unloaded
) -> None:
    """No numba (the module cannot be imported): no kernels, whatever the size, and the scans
    give what checking every pair at every sample (Pinocchio placements) gives."""
    import builtins

    real_import = builtins.__import__

    def no_kernels(name: str, *args: object, **kwargs: object) -> object:
        if name == "urdfpost.collision" and "_kernels" in (args[2] or ()):  # type: ignore[operator]
            raise ImportError("no numba here")
        return real_import(name, *args, **kwargs)  # type: ignore[arg-type]

    unloaded(world_module.KERNELS)
    monkeypatch.setattr(builtins, "__import__", no_kernels)
    try:
        assert world_module.KERNELS.load() is None
        assert world_module.KERNELS.get(10**9) is None
        tips = np.array([[0.0, -50.0, 0.0], [0.0, 50.0, 5.0], [5.0, 0.0, 40.0]])
        q = inverse(thin_wall_world.machine, tips, np.tile([0.0, 0.0, 1.0], (3, 1)), TOOL_LENGTH).q[
            :, 0
        ]
        moves = thin_wall_world.check_moves(q)
        assert moves.hit[0]
        counts = thin_wall_world.sample_counts(q)
        for mv, c in enumerate(counts):
            qs = q[mv] + (np.arange(c + 1) / c)[:, None] * (q[mv + 1] - q[mv])
            first = thin_wall_world._first_pairs(qs, plain=True)
            hits = np.flatnonzero(first[:, 0] >= 0)
            assert moves.hit[mv] == bool(len(hits))
            if len(hits):
                assert moves.at[mv] == hits[0] / c
    finally:
        monkeypatch.undo()


def test_a_kernel_that_fails_leaves_the_numpy_path_with_a_warning(
    thin_wall_world: CollisionWorld,
    monkeypatch: pytest.MonkeyPatch,
    caplog: pytest.LogCaptureFixture,
    stand_in: StandIn,
) -> None:
    """numba present but unable to compile or load the kernels: one warning, then the numpy
    path for the rest of the process, the same results."""

    def broken(*args: object) -> None:
        raise RuntimeError("cannot compile here")

    fake = SimpleNamespace(pair_bounds=broken, stock_separations=broken, cull_stock_pairs=broken)
    tips = np.array([[0.0, -50.0, 0.0], [0.0, 50.0, 5.0], [5.0, 0.0, 40.0]])
    axes = np.tile([0.0, 0.0, 1.0], (3, 1))
    q = inverse(thin_wall_world.machine, tips, axes, TOOL_LENGTH).q[:, 0]
    monkeypatch.setattr(world_module.KERNELS, "forced", False)
    expected = thin_wall_world.check_moves(q)
    monkeypatch.setattr(world_module.KERNELS, "forced", True)
    stand_in(world_module.KERNELS, fake)
    with caplog.at_level(logging.WARNING, logger="urdfpost.collision.world"):
        got = thin_wall_world.check_moves(q)
    assert world_module.KERNELS.failed == "cannot compile here"
    assert len([r.message for r in caplog.records if "numpy path runs" in r.message]) == 1
    assert got.pairs == expected.pairs and expected.hit[0]
    np.testing.assert_array_equal(got.at, expected.at)
    # no kernels once one failed, whatever the size
    monkeypatch.setattr(world_module.KERNELS, "forced", None)
    assert world_module.KERNELS.get(10**9) is None


def test_compiled_from_a_query_size_then_for_every_query(unloaded: Unloaded) -> None:
    """Before the kernels are loaded, small queries run numpy (no numba import for them);
    from ``COMPILED_FROM`` configurations on, and after ``warm_kernels``, every query runs
    compiled."""
    kernels = _kernels()
    unloaded(world_module.KERNELS)
    assert world_module.KERNELS.get(world_module.COMPILED_FROM - 1) is None
    assert world_module.KERNELS.get(world_module.COMPILED_FROM) is kernels
    assert world_module.KERNELS.get(1) is kernels
    unloaded(world_module.KERNELS)
    assert world_module.warm_kernels()
    assert world_module.KERNELS.get(1) is kernels
