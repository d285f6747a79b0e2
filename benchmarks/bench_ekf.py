"""Benchmark: one cart EKF step (model, Jacobians, predict, update) vs the same model through filterpy.

Prints the median microseconds per step of `cart.ekf.CartEKF.step` and of
filterpy's ExtendedKalmanFilter driven by the same model functions (the
analytic f and F of `cart.ekf.dynamics_jacobian`, Euler discretisation
Phi = I + F dt, the same Q, R and P0) through filterpy's own `predict()` (with
`predict_x` overridden by the nonlinear Euler step, as filterpy documents) and
`update()` (with the same wrapped heading residual). The two filters are timed
in interleaved blocks so that a change of machine load hits both; the ratio
is the median over blocks of (filterpy median / ours median). Both filters'
final mass estimates are printed as a check that they are the same filter.
Then the wall time of `cartpush reproduce` (11 tests x 2 runs). Never asserts a time.

Run: .venv/bin/python benchmarks/bench_ekf.py [--skip-reproduce]
"""
from __future__ import annotations

import argparse
import contextlib
import io
import math
import os
import statistics
import time

import numpy as np
from filterpy.kalman import ExtendedKalmanFilter

from studies import table1
from cart.ekf import CartEKF, EKFConfig, dynamics_jacobian
from cart.simulate import MeasurementNoise, simulate

H_SEL = np.hstack([np.eye(6), np.zeros((6, 4))])


def make_log(duration: float = 10.0):
    """Return (t, gamma, z) of a simulated push of the test-5 cart with 5 mm noise."""
    truth = table1.true_params(table1.TESTS[4])
    ctrl = lambda t, q, qd: np.array([15 * math.cos(q[2]), 15 * math.sin(q[2]), 2.0 * math.sin(t)])
    sim = simulate(truth, ctrl, duration, noise=MeasurementNoise.from_level(0.005), rng=np.random.default_rng(0))
    return sim.measured.t, sim.measured.gamma, np.hstack([sim.measured.q, sim.measured.qd])


class FilterpyTwin(ExtendedKalmanFilter):
    """filterpy's EKF with the cart model: predict_x is the Euler step of f and sets F = I + df/dx dt."""

    def __init__(self, ref: CartEKF) -> None:
        super().__init__(dim_x=10, dim_z=6)
        self.x = ref.x.copy()
        self.P = ref.P.copy()
        self.R = ref.R.copy()
        self.qc = ref.Qc.copy()
        self.sigma = ref.sigma
        self.dt = 0.01
        self.fbuf = np.zeros((10, 10))
        self.fbuf[0, 3] = self.fbuf[1, 4] = self.fbuf[2, 5] = 1.0

    def predict_x(self, u=0):
        """Euler step of the exact cart dynamics (paper eq. 16); F for the covariance (eq. 13/17)."""
        acc = dynamics_jacobian(self.x, u, self.sigma, self.fbuf, False)
        xdot = np.concatenate([self.x[3:6], acc, np.zeros(4)])
        self.F = np.eye(10) + self.fbuf * self.dt
        self.Q = self.qc * self.dt
        self.x = self.x + xdot * self.dt


def _h_jacobian(x):
    return H_SEL


def _hx(x):
    return x[:6]


def _residual(a, b):
    y = a - b
    y[2] = (y[2] + math.pi) % (2.0 * math.pi) - math.pi
    return y


def timed_steps(step, t, gamma, z, k0: int, k1: int) -> list:
    """Return the per-step seconds of ``step(gamma, dt, z)`` for samples k0..k1-1."""
    out = []
    pc = time.perf_counter
    for k in range(k0, k1):
        dt = t[k] - t[k - 1]
        g, zk = gamma[k - 1], z[k]
        t0 = pc()
        step(g, dt, zk)
        out.append(pc() - t0)
    return out


def bench_step(t, gamma, z, cfg: EKFConfig, phi0, sigma, block: int = 100, rounds: int = 3):
    """Return (ours samples, filterpy samples, per-block ratios, final masses) of interleaved runs."""
    ours_all, fp_all, ratios, masses = [], [], [], None
    for _ in range(rounds):
        ours = CartEKF(z[0, :3], z[0, 3:], phi0, sigma, cfg)
        twin = FilterpyTwin(ours)

        def fp_step(g, dt, zk):
            twin.dt = dt
            twin.predict(u=g)
            twin.update(zk, HJacobian=_h_jacobian, Hx=_hx, residual=_residual)

        for k0 in range(1, len(t), block):
            k1 = min(k0 + block, len(t))
            a = timed_steps(ours.step, t, gamma, z, k0, k1)
            b = timed_steps(fp_step, t, gamma, z, k0, k1)
            ours_all += a
            fp_all += b
            ratios.append(statistics.median(b) / statistics.median(a))
        masses = (float(ours.x[6]), float(twin.x[6]))
    return ours_all, fp_all, ratios, masses


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--skip-reproduce", action="store_true", help="skip timing `cartpush reproduce`")
    args = parser.parse_args()
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    t, gamma, z = make_log()
    guess = table1.guess_params(table1.TESTS[4])
    cfg = table1.ekf_config(0.005)
    ours, fp, ratios, masses = bench_step(t, gamma, z, cfg, guess.phi, guess.sigma)
    med_o, med_f = statistics.median(ours) * 1e6, statistics.median(fp) * 1e6
    print(f"load average (1 min) at start: {load:.2f} on {os.cpu_count()} CPUs")
    print(f"{'EKF step (10 states, 6 measurements)':40s} {'median us':>10s} {'ratio':>8s}")
    print(f"{'cart.ekf.CartEKF.step':40s} {med_o:10.1f} {1.0:8.2f}")
    print(f"{'filterpy ExtendedKalmanFilter':40s} {med_f:10.1f} {med_f / med_o:8.2f}")
    q1, q2, q3 = statistics.quantiles(ratios, n=4)
    print(f"ratio per block of 100 steps: median {q2:.2f} (quartiles {q1:.2f}-{q3:.2f}, {len(ratios)} blocks)")
    print(f"final mass estimate: ours {masses[0]:.4f} kg, filterpy {masses[1]:.4f} kg (true 20)")
    if not args.skip_reproduce:
        from wholebody.cli import main as cli_main

        argv = ["reproduce", "--json"]
        t0 = time.perf_counter()
        with contextlib.redirect_stdout(io.StringIO()):
            cli_main(argv)
        wall = time.perf_counter() - t0
        load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
        print(f"{'cartpush ' + ' '.join(argv):40s} {wall:10.1f} s  (load average after: {load:.2f})")


if __name__ == "__main__":
    main()
