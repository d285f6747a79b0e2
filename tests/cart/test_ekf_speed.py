"""The EKF check's fast paths against the plain computations they stand for (bit for bit)."""

from __future__ import annotations

import numpy as np

from cart.ekf import CartEKF, EKFConfig, measurement_std_from_log, run_ekf
from cart.logs import local_polyfit, local_polyfits


def _jittered_log(n: int = 400, seed: int = 2) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    t = np.cumsum(0.005 + 0.0004 * rng.standard_normal(n))
    q = np.column_stack([np.sin(t), 0.5 * np.cos(0.7 * t), 0.3 * t]) + 1e-3 * rng.standard_normal((n, 3))
    qd = np.gradient(q, t, axis=0)
    gamma = np.column_stack([5.0 * np.sin(2.0 * t), 3.0 * np.cos(t), 0.4 * np.sin(t)])
    return t, np.hstack([q, qd]), gamma


def test_run_ekf_equals_stepping_the_filter_by_hand():
    """run_ekf's loop (Python-float time steps) gives the numbers of CartEKF.step on the log's own rows."""
    t, z, gamma = _jittered_log()
    phi0, cfg = [20.0, 0.1, 0.0, 3.0], EKFConfig(estimate_params=True)
    ekf, hist, nis = run_ekf(t, gamma, z, phi0=phi0, sigma=1.0, config=cfg, sigma_yaw=0.5)
    ref = CartEKF(z[0, :3], z[0, 3:], phi0, 1.0, cfg, sigma_yaw=0.5)
    for k in range(1, len(t)):
        assert nis[k] == ref.step(gamma[k - 1], t[k] - t[k - 1], z[k])
        assert np.array_equal(hist[k], ref.x)
    assert np.array_equal(ekf.P, ref.P)


def test_local_polyfits_of_several_arrays_equal_one_fit_each():
    t, z, _ = _jittered_log(300)
    smooth, slope, width = local_polyfits(t, [z[:, :3], z[:, 3:]])
    for k, arr in enumerate((z[:, :3], z[:, 3:])):
        ref_smooth, ref_slope, ref_width = local_polyfit(t, arr)
        assert np.array_equal(smooth[k], ref_smooth) and np.array_equal(slope[k], ref_slope) and width == ref_width


def test_measurement_std_uses_the_same_fits_as_one_fit_per_array():
    t, z, _ = _jittered_log(300)
    q, qd = z[:, :3], z[:, 3:]
    got = measurement_std_from_log(t, q, qd)
    (smooth, _, width), (vsmooth, _, _) = local_polyfit(t, q), local_polyfit(t, qd)
    scale = np.sqrt(width / max(width - 3, 1))
    pose = np.maximum(np.std(q - smooth, axis=0) * scale, 1e-4)
    vel = np.maximum(np.std(qd - vsmooth, axis=0) * scale, 1e-3)
    assert got[2] == pose[2] and got[5] == vel[2]
    assert got[0] == 0.5 * (pose[0] + pose[1]) and got[3] == 0.5 * (vel[0] + vel[1])
