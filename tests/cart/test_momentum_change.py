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


def _spike(mass: float = 20.0, spike_n: float = -200.0, noise: float = 0.005, seed: int = 0):
    """Forward speeds and the measured net force at 100 Hz over 0.5 s: a cart of ``mass`` kg at 0.8 m/s under a
    constant 4 N, with a ``spike_n`` N wrench over the period ending at 0.3 s (an arm at its limit)."""
    rng = np.random.default_rng(seed)
    t = DT * np.arange(1, 51)
    f = np.full(t.size, 4.0)
    f[np.abs(t - 0.3) < 1e-9] += spike_n
    v = 0.8 + np.cumsum(f) * DT / mass
    return t, v + noise * rng.standard_normal(t.size), f


def _run_measured(test: MomentumTest, t, v, omega, f, mass: float, dy: float, t_imp: float = 0.3):
    found = None
    for tk, vk, wk, fk in zip(t, v, omega, f):
        test.add(tk, vk, wk, fk)
        if abs(tk - t_imp) < 1e-9:
            test.arm(tk, mass, dy)
        found = test.check(tk) or found
    return found


def test_a_jump_the_measured_wrench_explains_is_no_load() -> None:
    """A 200 N spike over one period slows a 20 kg cart by 0.1 m/s (r = 1.14): with the measured force the
    jump is the wrench's (ratio 1 within its std); the speed alone reads it as a load put in."""
    t, v, f = _spike()
    zero = np.zeros(t.size)
    measured = MomentumTest(side_s=0.1)
    assert _run_measured(measured, t, v, zero, f, 20.0, 0.0) is None
    _, ratio, std = measured.tested[0]
    assert abs(ratio - 1.0) < 3.0 * std + 0.01
    assert _run(MomentumTest(side_s=0.1), t, v) is not None


def test_a_load_put_in_under_a_measured_wrench_is_weighed() -> None:
    """The load put in (20 -> 30 kg) while a -60 N wrench brakes the cart: the ratio is the masses' 1.5."""
    t, v, f = _spike(spike_n=0.0, noise=0.0)
    f = np.full(t.size, -60.0)
    v = np.empty(t.size)
    p, m = 20.0 * 0.8, 20.0
    for k in range(t.size):  # the momentum kept at the jump, the force's impulse on each side
        if abs(t[k] - 0.3) < 1e-9:
            m = 30.0
        p += f[k] * DT
        v[k] = p / m
    found = _run_measured(MomentumTest(side_s=0.1), t, v, np.zeros(t.size), f, 20.0, 0.0)
    assert found is not None
    assert found[1] == pytest.approx(1.5, rel=0.01)


def test_a_yaw_jump_moves_the_origin_not_the_centre_of_mass() -> None:
    """The yaw rate jumps by 0.6 rad/s with the CoM 0.15 m to the side: {b}'s origin speeds down by 0.09 m/s
    (r = 1.13) but the CoM's forward speed ``v - dy omega`` does not change: no load."""
    t, _, f = _spike(spike_n=0.0, noise=0.0)
    f = np.zeros(t.size)
    omega = np.where(t > 0.3 - 0.5 * DT, -0.6, 0.0)
    v = 0.8 + 0.15 * omega
    found = _run_measured(MomentumTest(side_s=0.1), t, v, omega, f, 20.0, 0.15)
    assert found is None
    assert _run_measured(MomentumTest(side_s=0.1), t, v, omega, f, 20.0, 0.0) is not None


def test_the_predicted_noise_bounds_the_ratio_std() -> None:
    """Noise-free speeds: the lines' residuals are zero, the std is the predicted one (motion capture 0.05 m/s):
    a 10 % slowing is then within 3 std and no load; with no predicted noise it is one."""
    t, v = _speeds(1.1, noise=0.0)
    quiet = MomentumTest(side_s=0.1, speed_std=0.05)
    assert _run(quiet, t, v) is None
    assert quiet.tested[0][2] > 0.05
    assert _run(MomentumTest(side_s=0.1), t, v) is not None


@pytest.mark.parametrize("bad", [{"side_s": 0.0}, {"min_change": -0.1}, {"speed_std": -1.0}, {"force_std": -1.0}])
def test_bad_settings_are_refused(bad: dict) -> None:
    with pytest.raises(ValueError, match="MomentumTest needs"):
        MomentumTest(**bad)


def test_a_misfitting_wrench_is_trusted_less() -> None:
    """The measured force claims a 200 N push over one period that the motion does not show (an arm at its
    limit): taken at its word, the cart that kept its speed reads as slowed (r = 1.13, a load); with the model's
    residual ratio (12) scaling the force's std the jump is within 3 std: no load."""
    t, _, f = _spike(spike_n=200.0)
    rng = np.random.default_rng(3)
    v = 0.8 + np.cumsum(np.full(t.size, 4.0)) * DT / 20.0 + 0.005 * rng.standard_normal(t.size)

    def run(misfit: float):
        test = MomentumTest(side_s=0.1, speed_std=0.005, force_std=3.0)
        found = None
        for tk, vk, fk in zip(t, v, f):
            test.add(tk, vk, 0.0, fk)
            if abs(tk - 0.3) < 1e-9:
                test.arm(tk, 20.0, 0.0, misfit)
            found = test.check(tk) or found
        return found, test.tested[0]

    assert run(1.0)[0] is not None
    found, (_, ratio, std) = run(12.0)
    assert found is None and ratio - 1.0 < 3.0 * std
