"""Per-step cost of the closed push loop (`wholebody.push.run_push`): where the 100 Hz period goes.

Times one 30 s Traj. 2 run (1 arm, EKF, optimal contact) and, inside it, the median cost of each
stage: the whole-body QP tracker (`WholeBodyQPTracker.step`, the QP of `wholebody.motion.control`), the arm
torques (Pinocchio RNEA + Jacobian), the wrench allocation QP, the EKF step and the contact re-plan.
Prints a table of medians and the share of the wall time. Never asserts a time.

    .venv/bin/python benchmarks/bench_push.py [--duration 30] [--arms 1] [--json]
"""

from __future__ import annotations

import argparse
import json
import time
from collections import defaultdict
from collections.abc import Callable

import numpy as np

import wholebody.push as push
from cart.ekf import CartEKF
from wholebody.contacts.allocation import WrenchAllocator


def _timed(cls: type, name: str, store: dict[str, list[float]], label: str) -> Callable[[], None]:
    """Wrap cls.name to record its wall time under `label`; return a function restoring the original."""
    original = getattr(cls, name)

    def wrapper(self, *args, **kwargs):
        t0 = time.perf_counter()
        out = original(self, *args, **kwargs)
        store[label].append(time.perf_counter() - t0)
        return out

    setattr(cls, name, wrapper)
    return lambda: setattr(cls, name, original)


def main(argv=None) -> None:
    """Print the table (or, with --json, one JSON object of the medians and shares)."""
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--duration", type=float, default=30.0)
    parser.add_argument("--arms", type=int, default=1)
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of the table")
    args = parser.parse_args(argv)
    store: dict[str, list[float]] = defaultdict(list)
    restore = [
        _timed(push.WholeBodyQPTracker, "step", store, "whole-body QP (tracker.step)"),
        _timed(push.MobileManipulator, "torques", store, "arm torques (rnea + J^T w)"),
        _timed(WrenchAllocator, "solve", store, "wrench allocation QP"),
        _timed(CartEKF, "step", store, "EKF step"),
        _timed(push.ContactScheduler, "update", store, "contact scheduler (incl. re-plans)"),
    ]
    config = push.PushConfig(duration=args.duration, n_arms=args.arms)
    t0 = time.perf_counter()
    res = push.run_push(config)
    wall = time.perf_counter() - t0
    for r in restore:
        r()
    n = len(res.t)
    if args.json:
        stages = {
            label: {
                "calls": len(ts),
                "median_us": 1e6 * float(np.median(ts)),
                "total_s": float(np.sum(ts)),
                "share": float(np.sum(ts)) / wall,
            }
            for label, ts in store.items()
        }
        print(
            json.dumps(
                {
                    "trajectory": config.trajectory,
                    "arms": config.n_arms,
                    "duration_s": args.duration,
                    "periods": n,
                    "wall_s": wall,
                    "ms_per_period": 1e3 * wall / n,
                    "stages": stages,
                    "grasp_error_max_mm": 1e3 * res.metrics.grasp_error_max_m,
                    "wheel_limit_ratio": res.metrics.base_wheel_limit_ratio,
                }
            )
        )
        return
    print(
        f"run_push: Traj.{config.trajectory}, {config.n_arms} arm(s), {args.duration:g} s = {n} periods: "
        f"{wall:.2f} s wall, {1e3 * wall / n:.3f} ms per period"
    )
    print(f"{'stage':<38}{'calls':>7}{'median [us]':>13}{'total [s]':>11}{'share':>8}")
    for label, times in store.items():
        ts = np.array(times)
        print(f"{label:<38}{len(ts):>7}{1e6 * np.median(ts):>13.0f}{ts.sum():>11.2f}{ts.sum() / wall:>8.1%}")
    print(
        f"grasp error max {1e3 * res.metrics.grasp_error_max_m:.2f} mm, "
        f"wheel-speed limit ratio {res.metrics.base_wheel_limit_ratio:.3f}"
    )


if __name__ == "__main__":
    main()
