"""Benchmark: wrench allocation solve time (median us) per QP backend, and contact-point search time.

Run: .venv/bin/python benchmarks/bench_allocation.py [--json]
Prints medians; never asserts a time. "closed-form" is the shortcut taken when
the equality-only optimum already satisfies every limit (the usual case in a
control loop); the backend rows force the QP (fast_path=False). Equality on the
motion rows (fx, tau) only; "limit binds" is a request where a grasp limit is active.
"""
from __future__ import annotations

import argparse
import builtins
import json
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


def main(argv=None) -> None:
    """Print the tables (or, with --json, one JSON object of the medians and ratios)."""
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--json", action="store_true", help="print one JSON object instead of the tables")
    args = ap.parse_args(argv)
    report = {"allocation_us": {}, "contact_points_ms": {}}
    _print = builtins.print
    print = (lambda *a, **k: None) if args.json else _print  # noqa: A001 - tables only without --json
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
            report["allocation_us"].setdefault(name, {})[solver] = {"easy": t_easy, "limit_binds": t_hard,
                                                                    "ratio_vs_proxqp": t_hard / base}
        fast = WrenchAllocator(pts, fast_path=True, only_motion_directions=True)
        assert fast.solve(easy).solver == "closed-form"
        t_closed = median_us(lambda: fast.solve(easy))
        print(f"{name:<8}{'closed-form':<13}{t_closed:>10.1f}{'-':>13}{'':>17}")
        t_build = median_us(lambda: WrenchAllocator(pts), repeat=100)
        print(f"{name:<8}{'(build)':<13}{t_build:>10.1f}")
        report["allocation_us"][name]["closed-form"] = {"easy": t_closed}
        report["allocation_us"][name]["build"] = t_build
    print()
    print("contact-point optimization (grid 1 cm + local refinement), median [ms]")
    for n_arms, gamma in ((1, [40.0, 0.0, -2.0]), (2, [60.0, 5.0, 3.0])):
        t = median_us(lambda: optimal_contact_points(gamma, h, n_arms=n_arms), repeat=5) / 1e3
        plan = optimal_contact_points(gamma, h, n_arms=n_arms)
        print(f"{n_arms} arm(s): {t:8.1f} ms   {plan.evaluations} allocations")
        report["contact_points_ms"][f"{n_arms}_arm"] = {"median_ms": t, "allocations": plan.evaluations}
    if args.json:
        _print(json.dumps(report))


if __name__ == "__main__":
    main()
