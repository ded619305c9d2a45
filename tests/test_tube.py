"""The cone strategy's rate-limited tube against its plain point-by-point definition."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from urdfpost.planning.strategies.cone import _reachable, _rounding, _tube


def reachable_reference(lo: np.ndarray, hi: np.ndarray, step: np.ndarray):
    n = len(lo)
    r_lo, r_hi = lo.copy(), hi.copy()
    ok = True
    for i in range(1, n):
        a = max(lo[i], r_lo[i - 1] - step[i - 1])
        b = min(hi[i], r_hi[i - 1] + step[i - 1])
        if a > b:
            ok = False
            a = b = float(np.clip(0.5 * (r_lo[i - 1] + r_hi[i - 1]), lo[i], hi[i]))
        r_lo[i], r_hi[i] = a, b
    return r_lo, r_hi, ok


def tube_reference(exact: np.ndarray, half: np.ndarray, step: np.ndarray) -> np.ndarray:
    lo, hi = exact - half, exact + half
    r_lo, r_hi, ok = reachable_reference(lo, hi, step)
    if not ok:
        with np.errstate(divide="ignore", invalid="ignore"):
            need = np.abs(np.diff(exact)) / step
        k_lo, k_hi = 1.0, float(np.nanmax(np.where(np.isfinite(need), need, 1.0), initial=1.0))
        k_hi = max(k_hi, 1.0) * (1 + 1e-9)
        for _ in range(40):
            k = np.sqrt(k_lo * k_hi)
            if reachable_reference(lo, hi, step * k)[2]:
                k_hi = k
            else:
                k_lo = k
            if k_hi / k_lo < 1.001:
                break
        step = step * k_hi
        r_lo, r_hi, _ = reachable_reference(lo, hi, step)
    n = len(exact)
    out = np.empty(n)
    out[-1] = np.clip(exact[-1], r_lo[-1], r_hi[-1])
    for i in range(n - 2, -1, -1):
        a = max(r_lo[i], out[i + 1] - step[i])
        b = min(r_hi[i], out[i + 1] + step[i])
        if a <= b:
            out[i] = np.clip(exact[i], a, b)
        elif a <= b + _rounding(exact, half, step):  # closed by rounding alone: one value
            out[i] = 0.5 * (a + b)
        else:
            out[i] = np.clip(exact[i], r_lo[i], r_hi[i])
    return out


def pole_pass(rng: np.random.Generator, n: int, width: float, offset: float):
    """A first rotary angle swinging half a turn near the middle of a run (a pass beside the
    pole), a band that widens there, and step limits from a velocity limit."""
    x = np.linspace(-1.0, 1.0, n)
    exact = np.arctan2(x, offset) + 0.01 * rng.normal(size=n).cumsum() / np.sqrt(n)
    sin_phi = np.hypot(x, offset)
    half = np.arcsin(np.clip(np.radians(2.0) / np.maximum(sin_phi, 1e-12), 0.0, 1.0))
    half[[0, -1]] = 0.0
    step = np.full(n - 1, width) * rng.uniform(0.5, 1.5, n - 1)
    return exact, half, step


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    n=st.integers(2, 400),
    width=st.floats(0.001, 0.2),
    offset=st.floats(0.001, 0.3),
)
def test_tube_matches_the_point_by_point_definition(
    seed: int, n: int, width: float, offset: float
) -> None:
    exact, half, step = pole_pass(np.random.default_rng(seed), n, width, offset)
    got, want = _tube(exact, half, step), tube_reference(exact, half, step)
    # the forward intervals come from running sums, not one step at a time: the same to the
    # rounding of those sums
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-9)
    assert np.all(np.abs(got - exact) <= half + 1e-9)


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(2, 300), tight=st.booleans())
def test_reachable_matches_the_point_by_point_definition(seed: int, n: int, tight: bool) -> None:
    """Random bands and steps, feasible or not (intervals closing and restarting)."""
    rng = np.random.default_rng(seed)
    centre = rng.normal(0.0, 0.3, n).cumsum()
    width = rng.uniform(0.0, 0.05 if tight else 0.5, n)
    width[rng.random(n) < 0.1] = 0.0  # points pinned to one value
    lo, hi = centre - width, centre + width
    step = rng.uniform(0.0, 0.2 if tight else 1.0, n - 1)
    got, want = _reachable(lo, hi, step), reachable_reference(lo, hi, step)
    assert got[2] == want[2]
    np.testing.assert_allclose(got[0], want[0], rtol=0, atol=1e-9)
    np.testing.assert_allclose(got[1], want[1], rtol=0, atol=1e-9)
    if not want[2]:
        assert not _reachable(lo, hi, step, stop=True)[2]


def test_long_runs_are_exact_away_from_the_swing() -> None:
    """A long run with one swing: the tube equals the definition and is exact far from it."""
    rng = np.random.default_rng(7)
    exact, half, step = pole_pass(rng, 20_000, 0.002, 0.01)
    got = _tube(exact, half, step)
    np.testing.assert_allclose(got, tube_reference(exact, half, step), rtol=0, atol=1e-9)
    assert np.array_equal(got[:1000], exact[:1000]) and np.array_equal(got[-1000:], exact[-1000:])
    assert np.any(got != exact)
