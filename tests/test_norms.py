"""Row lengths and angles of 3-vectors by whole columns: numpy's reduction to the bit."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from urdfpost.geometry import angle_between, norms


def bits(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a).view(np.uint8)


@settings(max_examples=200, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    n=st.integers(1, 3000),
    scale=st.floats(-12, 8),
    unit=st.booleans(),
    near=st.sampled_from([0.0, 1e-12, 1e-6, 1.0]),
)
def test_norms_and_angles_are_numpys_to_the_bit(
    seed: int, n: int, scale: float, unit: bool, near: float
) -> None:
    """Vectors of every magnitude, unit ones nearly equal or opposite: ``norms`` is
    ``np.linalg.norm(x, axis=-1)`` and ``angle_between`` its ``2 atan2(|u - v|, |u + v|)``
    with it, to the bit, in rows, broadcast and in higher dimensions."""
    rng = np.random.default_rng(seed)
    u = rng.normal(size=(n, 3)) * 10.0 ** rng.uniform(scale - 2, scale + 2, (n, 1))
    if unit:
        u /= np.linalg.norm(u, axis=-1, keepdims=True)
    v = (u if rng.random() < 0.5 else -u) + near * rng.normal(size=(n, 3))
    assert np.array_equal(bits(norms(u)), bits(np.linalg.norm(u, axis=-1)))
    want = 2.0 * np.arctan2(np.linalg.norm(u - v, axis=-1), np.linalg.norm(u + v, axis=-1))
    assert np.array_equal(bits(angle_between(u, v)), bits(want))
    w = 2.0 * np.arctan2(np.linalg.norm(u[0] - v, axis=-1), np.linalg.norm(u[0] + v, axis=-1))
    assert np.array_equal(bits(angle_between(u[0], v)), bits(w))
    cube = u[: (n // 4) * 4].reshape(-1, 2, 2, 3)
    assert np.array_equal(bits(norms(cube)), bits(np.linalg.norm(cube, axis=-1)))
    assert float(angle_between(u[0], u[0])) == 0.0


@settings(max_examples=100, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    n=st.integers(1, 2000),
    axis=st.sampled_from(["x", "y", "z", "any"]),
    home=st.booleans(),
)
def test_rotating_one_vector_is_rotating_its_rows(seed: int, n: int, axis: str, home: bool) -> None:
    """``rotate`` of one vector (the tool axis at home, as ``tool_axis_of`` starts from) works
    its products with the joint axis out once: the same rows as rotating it repeated per row,
    to the bit."""
    from urdfpost.kinematics.forward import _rotate_about, rotate

    rng = np.random.default_rng(seed)
    k = {"x": np.eye(3)[0], "y": np.eye(3)[1], "z": np.eye(3)[2]}.get(axis)
    if k is None:
        k = rng.normal(size=3)
        k /= np.linalg.norm(k)
    v = np.eye(3)[2] if home else rng.normal(size=3)
    theta = rng.uniform(-7.0, 7.0, n)
    want = _rotate_about(k, theta, np.broadcast_to(v, (n, 3)).copy())
    assert np.array_equal(bits(rotate(k, theta, v)), bits(want))


@settings(max_examples=30, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    n=st.integers(1, 3 * 8192 + 5),
    machine_name=st.sampled_from(["dmu50", "gantry-ca", "dmu50-nutating", "vf2-4axis"]),
)
def test_the_tool_axes_in_chunks_are_those_of_one_pass(
    seed: int, n: int, machine_name: str
) -> None:
    """``tool_axis_of`` works a few thousand rows at a time: the bits of one pass of its
    rotations over all rows, and of each row alone (two- and one-rotary machines)."""
    from urdfpost.kinematics.forward import rotate
    from urdfpost.machine import load_machine
    from urdfpost.planning.problem import tool_axis_of

    m = load_machine(machine_name)
    rng = np.random.default_rng(seed)
    rotary = rng.uniform(-7.0, 7.0, (n, len(m.rotary)))
    rotary[rng.random(n) < 0.1] = 0.0
    got = tool_axis_of(m, rotary)
    rot = m.rotary
    want = rotate(rot[-1].direction, rotary[:, -1], m.home_tool_axis)
    for j in range(len(rot) - 2, -1, -1):
        want = rotate(rot[j].direction, rotary[:, j], want)
    assert np.array_equal(bits(got), bits(want))
    at = rng.choice(n, min(n, 20), replace=False)
    alone = np.concatenate([tool_axis_of(m, rotary[i : i + 1]) for i in at])
    assert np.array_equal(bits(got[at]), bits(alone))


@settings(max_examples=30, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    n=st.integers(1, 3 * 8192 + 5),
    machine_name=st.sampled_from(["dmu50", "gantry-ca", "dmu50-nutating", "monoblock"]),
)
def test_the_best_tilt_in_chunks_is_that_of_one_pass(seed: int, n: int, machine_name: str) -> None:
    """``best_tilt`` turns the target axes back a few thousand rows at a time: the bits of
    turning them all in one pass."""
    from urdfpost.kinematics.forward import rotate
    from urdfpost.machine import load_machine
    from urdfpost.planning.strategies._common import TWO_PI, best_tilt

    m = load_machine(machine_name)
    rng = np.random.default_rng(seed)
    axis = rng.normal(size=(n, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    theta1, near = rng.uniform(-7.0, 7.0, n), rng.uniform(-7.0, 7.0, n)
    k1, k2 = m.rotary[0].direction, m.rotary[1].direction
    v0 = m.home_tool_axis
    w = rotate(k1, -theta1, axis)
    t2 = np.arctan2(w @ np.cross(k2, v0), w @ (v0 - k2 * (k2 @ v0)))
    want = t2 + TWO_PI * np.round((near - t2) / TWO_PI)
    assert np.array_equal(bits(best_tilt(m, axis, theta1, near)), bits(want))
