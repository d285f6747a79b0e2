"""Issue 14, class 2: the EKF against bad measurements — NaN rows, gross outliers, gaps, a broken covariance."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cart import table1
from cart.ekf import CartEKF, EKFConfig, chi2_isf, run_ekf
from cart.errors import CartpushError, NumericalError
from cart.simulate import MeasurementNoise, simulate


def _log(duration: float, seed: int = 0):
    """(truth, t, gamma, z) of an open-loop push with a varying force and torque, 5 mm / 5 mm/s noise."""
    truth = table1.true_params(table1.TESTS[4])

    def ctrl(t, q, qd):
        f = 15.0 + 10.0 * math.sin(0.7 * t)
        return np.array([f * math.cos(q[2]), f * math.sin(q[2]), 3.0 * math.sin(0.5 * t)])

    sim = simulate(truth, ctrl, duration, noise=MeasurementNoise.from_level(0.005), rng=np.random.default_rng(seed))
    m = sim.measured
    return truth, m.t, m.gamma, np.hstack([m.q, m.qd])


def _assert_spd(P):
    assert np.all(np.isfinite(P))
    np.testing.assert_array_equal(P, P.T)
    assert np.linalg.eigvalsh(P).min() > 0.0


def test_chi2_quantile_matches_scipy():
    from scipy.stats import chi2

    for alpha in (0.5, 1e-3, 1e-6, 1e-12):
        assert chi2_isf(alpha, 6) == pytest.approx(chi2.isf(alpha, 6), rel=1e-9)
    assert chi2_isf(1e-3, 3) == pytest.approx(chi2.isf(1e-3, 3), rel=1e-9)


def test_nan_measurement_is_skipped_and_counted():
    truth, t, g, z = _log(5.0)
    z = z.copy()
    z[100, 3] = np.nan
    z[200] = np.inf
    ekf, hist, nis = run_ekf(t, g, z, truth.with_mass(15.0).phi, truth.sigma, EKFConfig(estimate_sigma=True))
    assert ekf.nonfinite_samples == 2 and math.isnan(nis[100]) and math.isnan(nis[200])
    assert np.all(np.isfinite(hist)) and np.all(np.isfinite(ekf.P))
    # a NaN in the first row: the filter starts at the first finite one
    z[0, 0] = np.nan
    ekf, hist, _ = run_ekf(t, g, z, truth.phi, truth.sigma)
    assert np.all(np.isfinite(hist)) and ekf.nonfinite_samples == 3


def test_gross_outlier_is_rejected_and_a_real_jump_is_accepted():
    truth, t, g, z = _log(10.0)
    cfg = EKFConfig(estimate_sigma=True)
    z_glitch = z.copy()
    z_glitch[500::1000, 3] += 50.0  # 50 m/s velocity glitches every 10 s
    ekf, hist, _ = run_ekf(t, g, z_glitch, truth.phi, truth.sigma, cfg)
    clean, hist0, _ = run_ekf(t, g, z, truth.phi, truth.sigma, cfg)
    assert ekf.rejected_samples >= 1 and ekf.forced_accepts == 0
    assert abs(hist[-1, 6] - hist0[-1, 6]) < 0.2 and abs(hist[-1, 8] / hist[-1, 6]) < 0.5
    # a persistent offset of 0.5 m (the motion capture re-zeroed): accepted after a few rejections
    z_jump = z.copy()
    z_jump[500:, 0] += 0.5
    ekf, hist, _ = run_ekf(t, g, z_jump, truth.phi, truth.sigma, cfg)
    assert 1 <= ekf.forced_accepts and ekf.rejected_samples <= 50
    assert abs(hist[-1, 0] - z_jump[-1, 0]) < 0.05


def test_long_gap_is_split_into_substeps():
    truth, t, g, z = _log(20.0)
    keep = np.ones(len(t), dtype=bool)
    keep[500:1500] = False  # a 10 s hole in a 100 Hz log
    ekf, hist, _ = run_ekf(
        t[keep], g[keep], z[keep], truth.with_mass(15.0).phi, truth.sigma, EKFConfig(estimate_sigma=True)
    )
    assert ekf.gaps == 1
    assert abs(hist[-1, 6] - truth.m) < 2.0  # one Euler step over 10 s gave 12 kg for a 31.5 kg cart before


def test_broken_covariance_is_repaired_not_a_linalg_error():
    truth, t, g, z = _log(2.0)
    ekf = CartEKF(z[0, :3], z[0, 3:], truth.phi, truth.sigma, EKFConfig())
    P = ekf.P
    P[0, 0] = -1.0  # not positive definite
    P[:6, :6] -= 10.0 * np.eye(6)
    ekf.step(g[0], t[1] - t[0], z[1])
    assert ekf.covariance_repairs >= 1
    _assert_spd(ekf.P)
    ekf.P = np.full_like(ekf.P, np.nan)
    with pytest.raises(NumericalError) as err:
        ekf.step(g[1], t[2] - t[1], z[2])
    assert isinstance(err.value, CartpushError)


def test_20k_steps_with_outliers_and_nans_stay_spd_and_within_3_std():
    """The test-suite version of benchmarks/bench_ekf_robust.py (10^6 steps): 1 % gross outliers, 0.1 % NaN."""
    truth, t, g, z = _log(200.0, seed=3)
    rng = np.random.default_rng(4)
    z = z.copy()
    n = len(t)
    out = rng.choice(np.arange(1, n), size=n // 100, replace=False)
    z[out, rng.integers(0, 6, size=len(out))] += rng.choice([-1, 1], size=len(out)) * rng.uniform(1, 50, len(out))
    nan_rows = rng.choice(np.setdiff1d(np.arange(1, n), out), size=n // 1000, replace=False)
    z[nan_rows, rng.integers(0, 6, size=len(nan_rows))] = np.nan
    ekf, hist, nis = run_ekf(t, g, z, truth.with_mass(15.0).phi, truth.sigma, EKFConfig(estimate_sigma=False))
    assert len(t) > 20_000
    assert ekf.nonfinite_samples == len(nan_rows)
    assert ekf.rejected_samples >= 0.9 * len(out)
    _assert_spd(ekf.P)
    est, std = ekf.params(), ekf.params_std()
    assert abs(est.m - truth.m) < 3 * std["mass"]
    assert abs(est.dx - truth.dx) < 3 * std["com"][0] and abs(est.dy - truth.dy) < 3 * std["com"][1]
