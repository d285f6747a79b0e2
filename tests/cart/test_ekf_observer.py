"""The EKF as a state observer of a cart whose model is wrong: EKFConfig.adaptive_q_tau (innovation-mean adaptive Q).

A cart turning under a torque its observer's inertia (3x too large) under-predicts: the paper's filter (the option
off) gates the motion capture until ``gate_max_consecutive`` rejections and then snaps its yaw-rate estimate to it
(steps of ~12 measurement stds in one period); with the velocities' process noise scaled by the innovation-mean
test it follows the turn without a rejection or a step beyond a few stds, and a lone outlier is still gated.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from cart import table1
from cart.ekf import CartEKF, EKFConfig
from cart.errors import ParameterError
from cart.simulate import MeasurementNoise, simulate

LEVEL = 0.005  # motion-capture noise std (m, rad, m/s, rad/s)
TAU = 0.1  # adaptive_q_tau (s): ten 10 ms periods


def _turning_log(seed: int = 0):
    """(truth, true log, t, gamma, z) of a cart pushed at 15 N and turned by a 12 N m sine torque (|omega| to 1.1 rad/s)."""
    truth = table1.true_params(table1.TESTS[4])

    def ctrl(t, q, qd):
        return np.array([15.0 * math.cos(q[2]), 15.0 * math.sin(q[2]), 12.0 * math.sin(0.8 * t)])

    sim = simulate(truth, ctrl, 10.0, noise=MeasurementNoise.from_level(LEVEL), rng=np.random.default_rng(seed))
    m = sim.measured
    return truth, sim.true, m.t, m.gamma, np.hstack([m.q, m.qd])


def _observe(truth, t, gamma, z, inertia_factor: float, tau: float, outlier: int | None = None):
    """Run the observer (parameters frozen, inertia about {b} times ``inertia_factor``); return (ekf, omega_hat, accepted, b of omega)."""
    phi = truth.phi.copy()
    phi[3] *= inertia_factor
    cfg = EKFConfig.from_noise([LEVEL] * 6, estimate_params=False, adaptive_q_tau=tau)
    ekf = CartEKF(z[0, :3], z[0, 3:], phi, truth.sigma, cfg, sigma_yaw=truth.sigma_yaw)
    omega, accepted = [float(ekf.x[5])], [True]
    bias = [0.0]
    for k in range(1, len(t)):
        zk = z[k].copy()
        if k == outlier:
            zk[5] += 50.0 * LEVEL
        ekf.step(gamma[k - 1], t[k] - t[k - 1], zk)
        omega.append(float(ekf.x[5]))
        accepted.append(ekf.accepted)
        bias.append(ekf.velocity_bias[2])
    return ekf, np.array(omega), np.array(accepted), np.array(bias)


def _largest_step(omega_hat: np.ndarray, omega_true: np.ndarray) -> float:
    """Return the largest change of the yaw-rate estimate in one period beyond the true change, in measurement stds."""
    return float(np.max(np.abs(np.diff(omega_hat) - np.diff(omega_true)))) / LEVEL


@pytest.mark.parametrize("seed", [0, 1])
def test_paper_filter_snaps_on_a_model_error(seed):
    """The option off: the gate rejects the turn's samples and the forced acceptances step the estimate."""
    truth, true, t, g, z = _turning_log(seed)
    ekf, omega, _, _ = _observe(truth, t, g, z, 3.0, 0.0)
    assert ekf.forced_accepts >= 10
    assert _largest_step(omega, true.qd[:, 2]) > 8.0


@pytest.mark.parametrize("seed", [0, 1])
def test_adaptive_observer_follows_a_turn_without_steps(seed):
    truth, true, t, g, z = _turning_log(seed)
    ekf, omega, _, _ = _observe(truth, t, g, z, 3.0, TAU)
    assert ekf.forced_accepts == 0 and ekf.rejected_samples == 0
    assert _largest_step(omega, true.qd[:, 2]) < 3.0
    _, omega_off, _, _ = _observe(truth, t, g, z, 3.0, 0.0)
    err = np.sqrt(np.mean((omega - true.qd[:, 2]) ** 2))
    err_off = np.sqrt(np.mean((omega_off - true.qd[:, 2]) ** 2))
    assert err < 0.5 * err_off


def test_adaptive_observer_of_a_right_model_is_the_paper_filter_within_noise():
    """With the true inertia the innovations are unbiased: the yaw-rate error stays that of the option off."""
    truth, true, t, g, z = _turning_log(0)
    _, omega, _, _ = _observe(truth, t, g, z, 1.0, TAU)
    _, omega_off, _, _ = _observe(truth, t, g, z, 1.0, 0.0)
    err = np.sqrt(np.mean((omega - true.qd[:, 2]) ** 2))
    err_off = np.sqrt(np.mean((omega_off - true.qd[:, 2]) ** 2))
    assert err < 1.2 * err_off + 1e-4
    assert _largest_step(omega, true.qd[:, 2]) < 1.0


def test_adaptive_observer_still_gates_a_lone_outlier():
    """A 50-std yaw-rate glitch is rejected, moves the estimate by less than a std, and the Q scale it leaves is bounded."""
    truth, true, t, g, z = _turning_log(0)
    k = 300
    ekf, omega, accepted, bias = _observe(truth, t, g, z, 1.0, TAU, outlier=k)
    assert not accepted[k] and accepted[k + 1]
    assert abs((omega[k] - omega[k - 1]) - (true.qd[k, 2] - true.qd[k - 1, 2])) < LEVEL
    _, omega_clean, _, _ = _observe(truth, t, g, z, 1.0, TAU)
    assert np.max(np.abs(omega[k : k + 50] - omega_clean[k : k + 50])) < 2.0 * LEVEL
    beta = 0.01 / TAU  # the innovation clipped at the gate's sqrt: b <= (beta sqrt(gate))^2 (2 - beta) / beta
    assert bias[k] <= beta * (2.0 - beta) * ekf.gate_threshold * 1.01


def test_default_is_the_paper_filter_and_a_negative_tau_is_refused():
    assert EKFConfig().adaptive_q_tau == 0.0
    truth, _, t, g, z = _turning_log(0)
    ekf, _, _, _ = _observe(truth, t[:50], g[:50], z[:50], 3.0, 0.0)
    assert ekf.velocity_bias == [0.0, 0.0, 0.0]  # never updated
    with pytest.raises(ParameterError):
        CartEKF(z[0, :3], z[0, 3:], truth.phi, truth.sigma, EKFConfig(adaptive_q_tau=-1.0))


def test_online_estimator_passes_the_adaptive_option_to_its_observer():
    """`OnlineOptions.observer_adaptive_q_tau` reaches the state observer's `EKFConfig` (off by default)."""
    from cart.online_estimator import make_online_estimator
    from cart.params import CartParams

    std = MeasurementNoise().measurement_std()
    default = make_online_estimator(np.zeros(3), CartParams(m=20.0, dx=0.3, dy=0.0, I=1.5), std)
    adaptive = make_online_estimator(
        np.zeros(3), CartParams(m=20.0, dx=0.3, dy=0.0, I=1.5), std, observer_adaptive_q_tau=0.1
    )
    assert default.observer.config.adaptive_q_tau == 0.0
    assert adaptive.observer.config.adaptive_q_tau == pytest.approx(0.1)
