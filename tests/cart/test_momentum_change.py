"""MomentumTest: a load put in at rest found by the forward speed's jump at an impulse (paper eq. 3-4)."""

from __future__ import annotations

import numpy as np
import pytest

from cart.change_detection import MomentumTest

DT = 0.01


def _speeds(ratio: float, v0: float = 0.8, accel: float = 0.2, noise: float = 0.01, seed: int = 0):
    """Forward speeds at 100 Hz over 0.5 s: ``v0 + accel t``, divided by ``ratio`` from the jump at 0.3 s on."""
    rng = np.random.default_rng(seed)
    t = DT * np.arange(1, 51)
    v = v0 + accel * t
    v[t > 0.3 - 0.5 * DT] /= ratio
    return t, v + noise * rng.standard_normal(t.size)


def _run(test: MomentumTest, t: np.ndarray, v: np.ndarray, t_imp: float = 0.3):
    found = None
    for tk, vk in zip(t, v):
        test.add(tk, vk)
        if abs(tk - t_imp) < 1e-9:
            test.arm(tk)
        found = test.check(tk) or found
    return found


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_load_put_in_gives_the_mass_ratio(seed: int) -> None:
    t, v = _speeds(1.5, seed=seed)
    found = _run(MomentumTest(side_s=0.1), t, v)
    assert found is not None
    t_imp, ratio, std = found
    assert t_imp == pytest.approx(0.3)
    assert 0.0 < std < 0.05
    assert abs(ratio - 1.5) < 3.0 * std + 0.01  # the lines take out the acceleration on each side


def test_the_jump_is_taken_at_the_period_before_the_impulse_sample() -> None:
    """Fast acceleration on each side: evaluating the lines at the impulse sample itself would bias the ratio."""
    t, v = _speeds(1.25, accel=2.0, noise=0.0)
    found = _run(MomentumTest(side_s=0.1), t, v)
    assert found is not None
    v_jump = 0.8 + 2.0 * (0.3 - 0.5 * DT)
    assert found[1] == pytest.approx(v_jump / (v_jump / 1.25), rel=1e-9)


@pytest.mark.parametrize("ratio", [1.0, 1.05, 1 / 1.5])
def test_no_load_put_in_without_a_slowing_jump_beyond_the_bar(ratio: float) -> None:
    """No jump, one below min_change, or a speed-up (a push, not a load at rest): nothing found, but tested."""
    test = MomentumTest(side_s=0.1, min_change=0.08)
    t, v = _speeds(ratio)
    assert _run(test, t, v) is None
    assert len(test.tested) == 1


def test_a_cart_at_rest_gives_nothing() -> None:
    """At rest the ratio of two noisy zeros is meaningless: its std (or the sign test) rejects it."""
    test = MomentumTest(side_s=0.1)
    t, v = _speeds(1.0, v0=0.0, accel=0.0, noise=0.002)
    assert _run(test, t, v) is None


def test_nothing_armed_nothing_tested() -> None:
    test = MomentumTest(side_s=0.1)
    t, v = _speeds(1.5)
    for tk, vk in zip(t, v):
        test.add(tk, vk)
        assert test.check(tk) is None
    assert test.tested == []
