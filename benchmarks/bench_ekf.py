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

Then the whole process `cartpush reproduce --json` (Table I, 11 tests x 2 runs of 30 s, start-up
included), with the default worker processes (one per CPU) and with `--workers 1` (its serial peer),
interleaved `--repeats` times; with `--baseline DIR` also the same command on another checkout of the
sources (run from DIR, DIR first on PYTHONPATH, e.g. the sources before a change), in the same rounds.
Medians, ratios and the CPU time (user + system of the process and its workers); never asserts a time.

Run: .venv/bin/python benchmarks/bench_ekf.py [--skip-reproduce] [--repeats 3] [--baseline DIR] [--json]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import subprocess
import sys
import time

import numpy as np
from filterpy.kalman import ExtendedKalmanFilter

from cart import table1
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


def time_reproduce(repeats: int, baseline: str | None = None) -> tuple[dict, dict]:
    """Return (wall s, CPU s) of `cartpush reproduce --json` runs, interleaved: each {label: [seconds]}.

    CPU is user + system time of the process and its workers (less sensitive to other load than the wall time).
    The baseline runs from its own directory, so that its sources come first on sys.path.
    """
    import resource

    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    cmd = [sys.executable, "-m", "cartpush.cli", "reproduce", "--json"]
    variants = {
        "reproduce (default workers)": (cmd, root, root),
        "reproduce --workers 1": (cmd + ["--workers", "1"], root, root),
    }
    if baseline:
        base = os.path.abspath(baseline)
        variants["reproduce, baseline checkout"] = (cmd, base, base + os.pathsep + root)
    wall: dict = {label: [] for label in variants}
    cpu: dict = {label: [] for label in variants}
    for _ in range(repeats):
        for label, (argv, cwd, path) in variants.items():
            env = dict(os.environ, PYTHONPATH=path)
            r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
            t0 = time.perf_counter()
            subprocess.run(argv, cwd=cwd, env=env, check=True, stdout=subprocess.DEVNULL)
            wall[label].append(time.perf_counter() - t0)
            r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
            cpu[label].append(r1.ru_utime - r0.ru_utime + r1.ru_stime - r0.ru_stime)
    return wall, cpu


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--skip-reproduce", action="store_true", help="skip timing `cartpush reproduce`")
    parser.add_argument("--repeats", type=int, default=3, help="rounds of the reproduce timings (default 3)")
    parser.add_argument("--baseline", metavar="DIR", help="also time reproduce on the sources in DIR (before/after)")
    parser.add_argument("--json", action="store_true", help="print one JSON object (medians, ratios)")
    args = parser.parse_args()
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    t, gamma, z = make_log()
    guess = table1.guess_params(table1.TESTS[4])
    cfg = table1.ekf_config(0.005)
    ours, fp, ratios, masses = bench_step(t, gamma, z, cfg, guess.phi, guess.sigma)
    med_o, med_f = statistics.median(ours) * 1e6, statistics.median(fp) * 1e6
    q1, q2, q3 = statistics.quantiles(ratios, n=4)
    out = {
        "load_average_start": load,
        "cpus": os.cpu_count(),
        "ekf_step_us": med_o,
        "filterpy_step_us": med_f,
        "filterpy_over_ours": med_f / med_o,
        "block_ratio_median": q2,
        "block_ratio_quartiles": [q1, q3],
        "final_mass_ours_kg": masses[0],
        "final_mass_filterpy_kg": masses[1],
    }
    if not args.skip_reproduce:
        times, cpu = time_reproduce(args.repeats, args.baseline)
        out["reproduce_s"] = {label: statistics.median(v) for label, v in times.items()}
        out["reproduce_cpu_s"] = {label: statistics.median(v) for label, v in cpu.items()}
        out["reproduce_all_s"] = times
        out["load_average_end"] = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    if args.json:
        print(json.dumps(out))
        return
    print(f"load average (1 min) at start: {load:.2f} on {os.cpu_count()} CPUs")
    print(f"{'EKF step (10 states, 6 measurements)':40s} {'median us':>10s} {'ratio':>8s}")
    print(f"{'cart.ekf.CartEKF.step':40s} {med_o:10.1f} {1.0:8.2f}")
    print(f"{'filterpy ExtendedKalmanFilter':40s} {med_f:10.1f} {med_f / med_o:8.2f}")
    print(f"ratio per block of 100 steps: median {q2:.2f} (quartiles {q1:.2f}-{q3:.2f}, {len(ratios)} blocks)")
    print(f"final mass estimate: ours {masses[0]:.4f} kg, filterpy {masses[1]:.4f} kg (true 20)")
    if "reproduce_s" in out:
        ref = out["reproduce_s"]["reproduce (default workers)"]
        print(f"{'whole process, Table I (22 x 30 s)':40s} {'median s':>10s} {'/ default':>9s} {'CPU s':>7s}  (runs)")
        for label, med in out["reproduce_s"].items():
            runs = ", ".join(f"{v:.1f}" for v in out["reproduce_all_s"][label])
            print(
                f"{'cartpush ' + label:40s} {med:10.2f} {med / ref:9.2f} {out['reproduce_cpu_s'][label]:7.1f}  ({runs})"
            )
        print(f"load average (1 min) after: {out['load_average_end']:.2f}")


if __name__ == "__main__":
    main()
