"""Benchmark: wrench allocation solve time (median us) per QP backend, and contact-point search time.

Run: .venv/bin/python benchmarks/bench_allocation.py
Prints medians; never asserts a time. "closed-form" is the shortcut taken when
the equality-only optimum already satisfies every limit (the usual case in a
control loop); the backend rows force the QP (fast_path=False). Equality on the
motion rows (fx, tau) only; "limit binds" is a request where a grasp limit is active.
"""
from __future__ import annotations

import time
import warnings

import numpy as np
import qpsolvers

from wholebody.contacts.allocation import WrenchAllocator
from wholebody.contacts.handle import HandleSegment
from wholebody.contacts.placement import optimal_contact_points

warnings.filterwarnings("ignore")


def median_us(fn, repeat: int = 300) -> float:
    """Return the median wall time of fn() in microseconds."""
    fn()
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times) * 1e6)


def main() -> None:
    h = HandleSegment.default()
    cases = {
        "1 arm": ([h.point(0.35)], [30.0, 0.0, 0.0], [30.0, 0.0, 3.0]),
        "2 arms": ([h.point(0.05), h.point(0.45)], [60.0, 0.0, 2.0], [60.0, 0.0, 14.0]),
    }
    solvers = [s for s in ("proxqp", "osqp", "daqp") if s in qpsolvers.available_solvers]
    print("allocation solve time, median [us] (matrices cached in WrenchAllocator)")
    print(f"{'case':<8}{'solver':<13}{'easy':>10}{'limit binds':>13}{'ratio vs proxqp':>17}")
    for name, (pts, easy, hard) in cases.items():
        base = None
        for solver in solvers:
            alloc = WrenchAllocator(pts, solver=solver, fast_path=False, only_motion_directions=True)
            x = alloc.solve(hard).wrenches_ee.reshape(-1)[alloc.free]
            assert np.any(alloc.Gin @ x > alloc.hin - 1e-6), "the hard case must hit a limit"
            t_easy = median_us(lambda: alloc.solve(easy))
            t_hard = median_us(lambda: alloc.solve(hard))
            base = t_hard if base is None else base
            print(f"{name:<8}{solver:<13}{t_easy:>10.1f}{t_hard:>13.1f}{t_hard / base:>17.2f}")
        fast = WrenchAllocator(pts, fast_path=True, only_motion_directions=True)
        assert fast.solve(easy).solver == "closed-form"
        print(f"{name:<8}{'closed-form':<13}{median_us(lambda: fast.solve(easy)):>10.1f}{'-':>13}{'':>17}")
        t_build = median_us(lambda: WrenchAllocator(pts), repeat=100)
        print(f"{name:<8}{'(build)':<13}{t_build:>10.1f}")
    print()
    print("contact-point optimization (grid 1 cm + local refinement), median [ms]")
    for n_arms, gamma in ((1, [40.0, 0.0, -2.0]), (2, [60.0, 5.0, 3.0])):
        t = median_us(lambda: optimal_contact_points(gamma, h, n_arms=n_arms), repeat=5) / 1e3
        plan = optimal_contact_points(gamma, h, n_arms=n_arms)
        print(f"{n_arms} arm(s): {t:8.1f} ms   {plan.evaluations} allocations")


if __name__ == "__main__":
    main()
