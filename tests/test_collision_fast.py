"""The culled collision scan against the plain one: same first contact (pair and sample)."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from urdfpost.collision import CollisionWorld, ToolBody
from urdfpost.kinematics import inverse
from urdfpost.machine import Machine, load_machine

TOOL_LENGTH = 100.0  # mm

pytest.importorskip("fcl")


@pytest.fixture(scope="module")
def dmu50() -> Machine:
    return load_machine("dmu50")


@pytest.fixture(scope="module")
def thin_wall_world(dmu50: Machine) -> CollisionWorld:
    """A 0.4 mm thin wall, 60 mm long and 30 mm high, standing on the table."""
    wall = trimesh.creation.box(extents=(0.4, 60.0, 30.0))
    wall.apply_translation((0.0, 0.0, 15.0))
    return CollisionWorld.build(dmu50, ToolBody(diameter=10.0), TOOL_LENGTH, wall)


def _q(machine: Machine, tips: np.ndarray, axes: np.ndarray) -> np.ndarray:
    ik = inverse(machine, tips, axes / np.linalg.norm(axes, axis=1, keepdims=True), TOOL_LENGTH)
    return ik.q[:, 0]


def _plain_moves(world: CollisionWorld, q: np.ndarray) -> tuple[list, np.ndarray]:
    """First contact of every move by the plain scan: every sample, every pair, Pinocchio."""
    counts = world.sample_counts(q)
    pairs, at = [], np.full(len(counts), np.nan)
    for m, c in enumerate(counts):
        t = np.arange(c + 1) / c
        qs = q[m] + t[:, None] * (q[m + 1] - q[m])
        first = world._first_pairs(qs, plain=True)
        hits = np.flatnonzero(first[:, 0] >= 0)
        if len(hits):
            h = hits[0]
            pairs.append((world.bodies[first[h, 0]].name, world.bodies[first[h, 1]].name))
            at[m] = h / c
        else:
            pairs.append(None)
    return pairs, at


points = st.tuples(st.floats(-40.0, 40.0), st.floats(-40.0, 40.0), st.floats(-10.0, 80.0))
tilts = st.tuples(st.floats(-0.6, 0.6), st.floats(-0.6, 0.6))


@settings(
    max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(st.lists(st.tuples(points, tilts), min_size=2, max_size=6))
def test_fast_moves_find_the_plain_first_contact(
    thin_wall_world: CollisionWorld, dmu50: Machine, path: list
) -> None:
    tips = np.array([p for p, _ in path], dtype=float)
    axes = np.array([(a, b, 1.0) for _, (a, b) in path], dtype=float)
    q = _q(dmu50, tips, axes)
    if np.isnan(q).any():
        return
    fast = thin_wall_world.check_moves(q)
    pairs, at = _plain_moves(thin_wall_world, q)
    assert fast.pairs == pairs
    np.testing.assert_array_equal(fast.at, at)
    single = thin_wall_world.check(q)
    plain = thin_wall_world._first_pairs(q, plain=True)
    assert single.hit.tolist() == (plain[:, 0] >= 0).tolist()


@settings(
    max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(st.floats(-3.0, 3.0), st.floats(0.0, 40.0), st.floats(-0.5, 0.5))
def test_grazing_the_thin_wall(
    thin_wall_world: CollisionWorld, dmu50: Machine, x: float, z: float, tilt: float
) -> None:
    """Sweeps across the wall top and flank at clearances from touching to a few mm: a bound
    that culls too much misses these."""
    tips = np.array([[x, -50.0, z], [x, 50.0, z + 5.0], [-x, 0.0, z]])
    axes = np.array([[tilt, 0.0, 1.0], [-tilt, 0.0, 1.0], [0.0, tilt, 1.0]])
    q = _q(dmu50, tips, axes)
    if np.isnan(q).any():
        return
    fast = thin_wall_world.check_moves(q, step_mm=0.5)
    counts = thin_wall_world.sample_counts(q, step_mm=0.5)
    for m, c in enumerate(counts):
        qs = q[m] + (np.arange(c + 1) / c)[:, None] * (q[m + 1] - q[m])
        first = thin_wall_world._first_pairs(qs, plain=True)
        hits = np.flatnonzero(first[:, 0] >= 0)
        assert fast.hit[m] == bool(len(hits))
        if len(hits):
            assert fast.at[m] == hits[0] / c
            names = tuple(thin_wall_world.bodies[i].name for i in first[hits[0]])
            assert fast.pairs[m] == names


@pytest.mark.parametrize("name", ["dmu50", "monoblock", "gantry-ca", "umc750", "xyzac-trt"])
def test_array_placements_match_pinocchio(name: str) -> None:
    machine = load_machine(name)
    world = CollisionWorld.build(machine, ToolBody(), TOOL_LENGTH)
    rng = np.random.default_rng(7)
    lo = np.where(np.isfinite(machine.lower), machine.lower, -7.0)
    hi = np.where(np.isfinite(machine.upper), machine.upper, 7.0)
    q = lo + rng.random((50, len(machine.axes))) * (hi - lo)
    np.testing.assert_allclose(
        world._moving_transforms(q), world._moving_transforms(q, pinocchio=True), atol=1e-9
    )


@pytest.mark.parametrize("seed", range(3))
def test_one_descent_of_the_stock_tree_answers_every_gap(seed: int) -> None:
    """The separation of an oriented box from the stock's leaf boxes (one descent of the
    tree) is the smallest separating-axis gap over all leaves (every leaf taken in turn), +inf
    beyond the gap asked, -inf only where the descent met too many nodes; and where
    :meth:`near` at g clears a box (every leaf farther than g), the separation is above g:
    boxes inside the stock, touching it, beside and far above it, gaps from 0 to 20 mm."""
    from scipy.spatial.transform import Rotation

    from urdfpost.collision.world import _BoxTree

    rng = np.random.default_rng(seed)
    sphere = trimesh.creation.icosphere(subdivisions=3, radius=30.0)
    tree = _BoxTree.of(sphere.vertices[sphere.faces])
    k = 300
    center = rng.uniform(-60.0, 60.0, (k, 3))
    center[:40] = rng.uniform(-5.0, 5.0, (40, 3))  # inside: many leaves near, or crowded
    rot = Rotation.random(k, random_state=seed).as_matrix()
    half = rng.uniform(0.5, 20.0, (k, 3))
    most = 20.0
    sep = tree.separation(center, rot, half, np.full(k, most))
    # every leaf box in turn, the same gap
    lo, hi = tree.lo[-1], tree.hi[-1]
    leaf = np.all(lo <= hi, axis=1)
    mid, ext = (lo[leaf] + hi[leaf]) / 2, (hi[leaf] - lo[leaf]) / 2
    d = mid[None] - center[:, None]  # (k, leaves, 3)
    base = np.einsum("kij,kj->ki", np.abs(rot), half)[:, None]
    spread = np.abs(rot).sum(axis=2)[:, None]
    world = ((np.abs(d) - base - ext[None]) / spread).max(axis=2)
    d_box = np.abs(np.einsum("kij,kli->klj", rot, d))
    ext_box = np.einsum("kij,li->klj", np.abs(rot), ext)
    brute = np.maximum(world, (d_box - half[:, None] - ext_box).max(axis=2)).min(axis=1)
    exact = np.isfinite(sep)
    assert exact.sum() > 100 and (sep == np.inf).sum() > 10 and (sep == -np.inf).any()
    np.testing.assert_allclose(sep[exact], brute[exact], rtol=0, atol=1e-9)
    assert (brute[sep == np.inf] > most).all()
    for g in (0.0, 0.5, 3.0, 10.0, 20.0):
        cleared = ~tree.near(center, rot, half, g)
        assert (sep[cleared] > g - 1e-9).all()
