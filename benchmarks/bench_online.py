"""Benchmark: one step of the online estimator vs the paper's EKF step vs filterpy's EKF, in the same run.

Prints the median microseconds per step of `cart.online_estimator.OnlineLSEstimator.step`,
`cart.ekf.CartEKF.step` and filterpy's ExtendedKalmanFilter with the same cart model
(`benchmarks.bench_ekf.FilterpyTwin`), on the same simulated push log, timed in interleaved
blocks of 100 steps so that a change of machine load hits all three. Never asserts a time.

The online estimator's window search for load changes (`cart.window_changes`) runs once every 2 s and takes
tenths of a second when it does: the median step does not show it. ``window_cpu`` replays a longer push
(``--window-log-s``, 30 s) with the search on and off in one process and reports the CPU time per step (mean),
the longest step and the number of searches.

Run: .venv/bin/python benchmarks/bench_online.py [--rounds 3] [--window-log-s 30] [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from bench_ekf import FilterpyTwin, _h_jacobian, _hx, _residual, make_log, timed_steps  # noqa: E402

from cart import table1  # noqa: E402
from cart.ekf import CartEKF  # noqa: E402
from cart.online_estimator import make_online_estimator  # noqa: E402


def window_cpu(duration: float) -> dict:
    """Return the online estimator's CPU per step (mean, max, us) on a ``duration`` s push, window search on / off."""
    t, gamma, z = make_log(duration)
    guess = table1.guess_params(table1.TESTS[4])
    cfg = table1.ekf_config(0.005)
    out: dict = {}
    for on in (True, False):
        est = make_online_estimator(z[0], guess, cfg.meas_std, window_changes=on)
        steps = []
        for k in range(1, len(t)):
            c0 = time.process_time()
            est.step(gamma[k - 1], t[k] - t[k - 1], z[k])
            steps.append(time.process_time() - c0)
        key = "window_on" if on else "window_off"
        out[key] = {"mean_us": 1e6 * sum(steps) / len(steps), "max_us": 1e6 * max(steps)}
        out[key]["searches"] = est.window.checks if est.window is not None else 0
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--window-log-s", type=float, default=30.0)
    args = parser.parse_args()
    t, gamma, z = make_log()
    guess = table1.guess_params(table1.TESTS[4])
    cfg = table1.ekf_config(0.005)
    times: dict[str, list[float]] = {"online": [], "paper_ekf": [], "filterpy_ekf": []}
    for _ in range(args.rounds):
        online = make_online_estimator(z[0], guess, cfg.meas_std)
        ekf = CartEKF(z[0, :3], z[0, 3:], guess.phi, guess.sigma, cfg)
        twin = FilterpyTwin(CartEKF(z[0, :3], z[0, 3:], guess.phi, guess.sigma, cfg))

        def fp_step(g, dt, zk):
            twin.dt = dt
            twin.predict(u=g)
            twin.update(zk, HJacobian=_h_jacobian, Hx=_hx, residual=_residual)

        for k0 in range(1, len(t), 100):
            k1 = min(k0 + 100, len(t))
            times["online"] += timed_steps(online.step, t, gamma, z, k0, k1)
            times["paper_ekf"] += timed_steps(ekf.step, t, gamma, z, k0, k1)
            times["filterpy_ekf"] += timed_steps(fp_step, t, gamma, z, k0, k1)
    med = {k: statistics.median(v) * 1e6 for k, v in times.items()}
    out = {
        "step_us": med,
        "load_average": os.getloadavg()[0],
        "final_mass_online": online.params().m,
        "final_mass_paper_ekf": float(ekf.x[6]),
        "window_cpu": window_cpu(args.window_log_s),
    }
    if args.json:
        print(json.dumps(out))
        return
    print(f"load average (1 min): {out['load_average']:.2f}")
    print(f"{'estimator step':40s} {'median us':>10s} {'/ paper EKF':>12s}")
    for k, v in med.items():
        print(f"{k:40s} {v:10.1f} {v / med['paper_ekf']:12.2f}")
    print(f"final mass (true 20): online {out['final_mass_online']:.2f}, paper EKF {out['final_mass_paper_ekf']:.2f}")
    for key, row in out["window_cpu"].items():
        print(
            f"online, {args.window_log_s:.0f} s push, {key}: CPU {row['mean_us']:.0f} us / step (mean), "
            f"longest step {row['max_us'] / 1000:.1f} ms, {row['searches']} window searches"
        )


if __name__ == "__main__":
    main()
