"""The wrench noise's spectral model (cart.noise_model.fit_spectrum) and what identify makes of it.

Flicker (pink, 1 / f) F/T noise keeps its power at the cart's own frequencies, where an AR(1) model fitted at
short lags sees none of it: the model check called such effect-free logs a misfit. Dry friction (a step in
the wrench at every reversal) must still be one.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from cart.identify import identify
from cart.noise_model import fit_spectrum, lag_correlation


def _pink(n: int, dt: float, rng: np.random.Generator) -> np.ndarray:
    """Return unit-std 1 / f noise (white noise shaped by 1 / sqrt(f) in the frequency domain)."""
    f = np.fft.rfftfreq(n, dt)
    spec = np.fft.rfft(rng.standard_normal(n))
    spec[1:] /= np.sqrt(f[1:])
    spec[0] = 0.0
    e = np.fft.irfft(spec, n)
    return e / np.std(e)


def test_the_spectrum_of_flicker_noise_is_one_over_f_and_white_noise_is_flat():
    rng = np.random.default_rng(3)
    dt, n = 0.005, 12000
    pink = fit_spectrum(2.0 * _pink(n, dt, rng), dt, (4.0, 50.0), 1.0 / (n * dt))
    assert 0.7 <= pink.alpha <= 1.0 and pink.power > 0
    assert pink.sigma == pytest.approx(2.0, rel=0.3)
    white = fit_spectrum(2.0 * rng.standard_normal(n), dt, (4.0, 50.0), 1.0 / (n * dt))
    assert white.sigma == pytest.approx(2.0, rel=0.1)
    assert abs(lag_correlation(white, dt)) < 0.1 and lag_correlation(pink, dt) > 0.3


def _noise_free_wrench_log(seed: int):
    """A 45 s independent-simulator log at 250 Hz: motion-capture noise on the pose, the wrench exact."""
    from studies.testbeds import rigid_sim

    case = rigid_sim.random_case(seed, duration=45.0)
    clean = replace(
        case, rate_hz=250.0, jitter=0.0, pos_std=0.0, theta_std=0.0, force_std=0.0, torque_std=0.0, vel_std=None
    )
    log, truth = rigid_sim.simulate(clean)
    rng = np.random.default_rng(11)
    q = log.q + rng.standard_normal(log.q.shape) * [case.pos_std, case.pos_std, case.theta_std]
    return replace(log, q=q, qd=None), truth


@pytest.fixture(scope="module")
def clean_run():
    return _noise_free_wrench_log(7)


@pytest.mark.parametrize("seed", [1, 2])
def test_pink_force_noise_fits_the_model_and_its_std_covers_the_truth(clean_run, seed):
    log, truth = clean_run
    rng = np.random.default_rng(seed)
    dt = float(np.median(np.diff(log.t)))
    noise = np.column_stack([_pink(len(log.t), dt, rng) for _ in range(3)]) * [2.0, 2.0, 0.2] + [0.2, -0.1, 0.02]
    res = identify(replace(log, gamma=log.gamma + noise))
    assert res.model_fits, res.residual_ratio
    assert abs(res.params.m - truth["m"]) < 3.0 * res.std["mass"]
    assert res.std["mass"] < 0.1 * truth["m"]
    assert res.wrench_noise is not None and res.wrench_noise[0].alpha > 0.5


def test_dry_friction_is_still_a_misfit_and_not_coloured_noise():
    from studies.testbeds import hidden_effects

    rng = np.random.default_rng([3, 7])
    log = hidden_effects.random_case("coulomb_friction", rng).measured
    res = identify(log)
    assert not res.model_fits
    assert max(res.residual_ratio) > 2.0
    assert math.isfinite(res.std["mass"])


@pytest.fixture(scope="module")
def drift_case():
    return _noise_free_wrench_log(6200)


@pytest.mark.parametrize("seed", [1, 2])
def test_a_drifting_offset_is_slow_sensor_noise_not_a_misfit(drift_case, seed):
    from studies.testbeds.coloured_noise import slow_noise

    log, truth = drift_case
    dt = float(np.median(np.diff(log.t)))
    noise = slow_noise("drift", len(log.t), dt, 0.0, np.random.default_rng(seed))  # white + a random walk
    res = identify(replace(log, gamma=log.gamma + noise))
    assert max(res.residual_ratio) > 1.6  # the spectral model, fitted above the cut-off, misses the drift
    assert res.model_fits, res.residual_ratio
    assert any("slow sensor noise" in w for w in res.warnings)
    assert abs(res.params.m - truth["m"]) < 3.0 * res.std["mass"]


def test_a_time_delay_under_a_drifting_offset_is_still_a_misfit():
    from studies.testbeds import hidden_effects
    from studies.testbeds.coloured_noise import slow_noise

    rng = np.random.default_rng([5, 3])
    log = hidden_effects.random_case("time_delay", rng).measured
    dt = float(np.median(np.diff(log.t)))
    res = identify(replace(log, gamma=log.gamma + slow_noise("drift", len(log.t), dt, 0.0, rng)))
    assert not res.model_fits, res.residual_ratio
    assert not any("slow sensor noise" in w for w in res.warnings)
