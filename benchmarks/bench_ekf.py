"""Benchmark: one cart EKF step (model, Jacobians, predict, update) vs the same model through filterpy.

Prints the median microseconds per step of `cart.ekf.CartEKF.step` and of
filterpy's ExtendedKalmanFilter driven by the same f, F, H, Q, R (Euler
discretisation, F_d = I + F dt), their ratio, and the wall time of
`cartpush reproduce` (all 11 tests x 2 runs). Never asserts a time.

Run: .venv/bin/python benchmarks/bench_ekf.py [--skip-reproduce]
"""
from __future__ import annotations

import argparse
import math
import statistics
import time

import numpy as np
from filterpy.kalman import ExtendedKalmanFilter

from cart import table1
from cart.ekf import CartEKF, EKFConfig, dynamics_jacobian
from cart.simulate import MeasurementNoise, simulate


def make_log(n_s: float = 10.0):
    """Return (t, gamma, z) of a simulated push with 5 mm noise."""
    truth = table1.true_params(table1.TESTS[4])
    ctrl = lambda t, q, qd: np.array([15 * math.cos(q[2]), 15 * math.sin(q[2]), 2.0 * math.sin(t)])
    sim = simulate(truth, ctrl, n_s, noise=MeasurementNoise.from_level(0.005), rng=np.random.default_rng(0))
    return sim.measured.t, sim.measured.gamma, np.hstack([sim.measured.q, sim.measured.qd])


def filterpy_twin(z0, phi0, sigma, cfg: EKFConfig) -> ExtendedKalmanFilter:
    """Return a filterpy EKF with the same state, P0, Q and R as CartEKF."""
    ref = CartEKF(z0[:3], z0[3:], phi0, sigma, cfg)
    kf = ExtendedKalmanFilter(dim_x=10, dim_z=6)
    kf.x = ref.x.copy()
    kf.P = ref.P.copy()
    kf.R = ref.R.copy()
    kf._qc = ref.Qc.copy()
    return kf


def time_cart(t, gamma, z, phi0, sigma, cfg) -> list[float]:
    ekf = CartEKF(z[0, :3], z[0, 3:], phi0, sigma, cfg)
    out = []
    for k in range(1, len(t)):
        dt = t[k] - t[k - 1]
        g, zk = gamma[k - 1], z[k]
        t0 = time.perf_counter()
        ekf.step(g, dt, zk)
        out.append(time.perf_counter() - t0)
    return out


def time_filterpy(t, gamma, z, phi0, sigma, cfg) -> list[float]:
    kf = filterpy_twin(z[0], phi0, sigma, cfg)
    hsel = np.hstack([np.eye(6), np.zeros((6, 4))])
    fbuf = np.zeros((10, 10))
    fbuf[0, 3] = fbuf[1, 4] = fbuf[2, 5] = 1.0
    out = []
    for k in range(1, len(t)):
        dt = t[k] - t[k - 1]
        g, zk = gamma[k - 1], z[k]
        t0 = time.perf_counter()
        acc = dynamics_jacobian(kf.x, g, sigma, fbuf, False)
        xdot = np.concatenate([kf.x[3:6], acc, np.zeros(4)])
        kf.F = np.eye(10) + fbuf * dt
        kf.Q = kf._qc * dt
        kf.x = kf.x + xdot * dt
        kf.P = kf.F @ kf.P @ kf.F.T + kf.Q  # filterpy's predict() would re-propagate x linearly
        kf.update(zk, HJacobian=lambda x: hsel, Hx=lambda x: hsel @ x)
        out.append(time.perf_counter() - t0)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--skip-reproduce", action="store_true", help="skip timing `cartpush reproduce`")
    args = parser.parse_args()
    t, gamma, z = make_log()
    guess = table1.guess_params(table1.TESTS[4])
    cfg = table1.ekf_config(0.005)
    rows = []
    for name, fn in (("cart.ekf.CartEKF.step", time_cart), ("filterpy ExtendedKalmanFilter", time_filterpy)):
        samples = []
        for _ in range(3):
            samples += fn(t, gamma, z, guess.phi, guess.sigma, cfg)
        rows.append((name, statistics.median(samples) * 1e6))
    print(f"{'EKF step (10 states, 6 measurements)':40s} {'median us':>10s} {'ratio':>8s}")
    for name, med in rows:
        print(f"{name:40s} {med:10.1f} {med / rows[0][1]:8.2f}")
    if not args.skip_reproduce:
        from wholebody.cli import main as cli_main
        import contextlib
        import io

        t0 = time.perf_counter()
        with contextlib.redirect_stdout(io.StringIO()):
            cli_main(["reproduce", "--json"])
        print(f"{'cartpush reproduce (11 tests x 2 runs)':40s} {time.perf_counter() - t0:10.1f} s")


if __name__ == "__main__":
    main()
