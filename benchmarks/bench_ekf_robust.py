"""Benchmark: the cart EKF over 10^6 steps with 1 % gross outliers and occasional NaN measurements.

Simulates an open-loop push (varying force and torque, 5 mm / 5 mm/s noise,
100 Hz) of the Table I test-5 cart, corrupts 1 % of the measurements with
gross outliers (+-1..50 m, m/s or rad on one channel) and 0.1 % with a NaN,
runs `cart.ekf.run_ekf` from a 15 kg guess and prints: steps, time per step,
the counters (rejected, non-finite, forced accepts, covariance repairs), whether
P is symmetric positive definite, and the final estimate against the truth in
units of its std. Also times the clean run (no corruption) for the overhead of
the gate. Prints a table; never asserts a time.

Run: .venv/bin/python benchmarks/bench_ekf_robust.py [--steps 1000000] [--json]
"""

from __future__ import annotations

import argparse
import json
import math
import time

import numpy as np

from cart import table1
from cart.ekf import EKFConfig, run_ekf
from cart.simulate import MeasurementNoise, simulate


def make_log(steps: int, seed: int = 0):
    """Return (truth, t, gamma, z) of `steps` + 1 samples at 100 Hz."""
    truth = table1.true_params(table1.TESTS[4])

    def ctrl(t, q, qd):
        f = 15.0 + 10.0 * math.sin(0.7 * t)
        return np.array([f * math.cos(q[2]), f * math.sin(q[2]), 3.0 * math.sin(0.5 * t)])

    sim = simulate(
        truth, ctrl, steps * 0.01, noise=MeasurementNoise.from_level(0.005), rng=np.random.default_rng(seed), substeps=1
    )
    m = sim.measured
    return truth, m.t, m.gamma, np.hstack([m.q, m.qd])


def corrupt(z: np.ndarray, seed: int = 1, outlier_rate: float = 0.01, nan_rate: float = 0.001):
    """Return (corrupted copy of z, outlier rows, NaN rows)."""
    rng = np.random.default_rng(seed)
    z = z.copy()
    n = len(z)
    out = rng.choice(np.arange(1, n), size=int(n * outlier_rate), replace=False)
    z[out, rng.integers(0, 6, size=len(out))] += rng.choice([-1, 1], size=len(out)) * rng.uniform(1, 50, len(out))
    nan_rows = rng.choice(np.setdiff1d(np.arange(1, n), out), size=int(n * nan_rate), replace=False)
    z[nan_rows, rng.integers(0, 6, size=len(nan_rows))] = np.nan
    return z, out, nan_rows


def main() -> None:
    """Run the benchmark and print the table (or JSON)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=1_000_000)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    t0 = time.perf_counter()
    truth, t, g, z = make_log(args.steps)
    sim_s = time.perf_counter() - t0
    zc, out, nan_rows = corrupt(z)
    rows = {}
    for label, zz in (("clean", z), ("corrupted", zc)):
        t0 = time.perf_counter()
        ekf, hist, nis = run_ekf(t, g, zz, truth.with_mass(15.0).phi, truth.sigma, EKFConfig())
        wall = time.perf_counter() - t0
        del hist
        P = ekf.P
        eig = float(np.linalg.eigvalsh(P).min())
        est, std = ekf.params(), ekf.params_std()
        rows[label] = {
            "steps": len(t) - 1,
            "us_per_step": 1e6 * wall / (len(t) - 1),
            "outliers_injected": 0 if label == "clean" else len(out),
            "nan_injected": 0 if label == "clean" else len(nan_rows),
            "rejected_samples": ekf.rejected_samples,
            "nonfinite_samples": ekf.nonfinite_samples,
            "forced_accepts": ekf.forced_accepts,
            "covariance_repairs": ekf.covariance_repairs,
            "P_symmetric": bool(np.array_equal(P, P.T)),
            "P_min_eig": eig,
            "P_finite": bool(np.all(np.isfinite(P))),
            "mass": est.m,
            "mass_true": truth.m,
            "mass_err_std": (est.m - truth.m) / std["mass"],
            "dx_err_std": (est.dx - truth.dx) / std["com"][0],
            "dy_err_std": (est.dy - truth.dy) / std["com"][1],
        }
    if args.json:
        print(json.dumps({"simulation_s": sim_s, **rows}))
        return
    print(f"simulated {len(t) - 1} steps in {sim_s:.1f} s")
    keys = list(rows["clean"])
    print(f"{'':22}{'clean':>16}{'corrupted':>16}")
    for k in keys:
        a, b = rows["clean"][k], rows["corrupted"][k]
        fmt = (lambda v: f"{v:16.4g}") if isinstance(a, float) else (lambda v: f"{str(v):>16}")
        print(f"{k:22}{fmt(a)}{fmt(b)}")


if __name__ == "__main__":
    main()
